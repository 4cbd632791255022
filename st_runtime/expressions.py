"""Expressions: each parsed expression as Python source and its IEC type, with IEC 61131-3's typing rules (AND,
OR, XOR and NOT take BOOL or bit strings; arithmetic on one type after the implicit widenings; X_TO_Y takes an
X) and the PLC's arithmetic (integers wrap on store, REAL results rounded to float32). What a PLC computes from
any value never raises: REAL_TO_<int> of NaN or an infinity, LIMIT, MIN and MAX of a NaN, a REAL divided by
zero each give the value `values` documents (`real_to_int`, `limit`, `minimum`, `maximum`, `real_div`)."""

from __future__ import annotations

import re
from typing import Any

from blark import transform as tf

from .values import ANY_INT, ANY_REAL, BITS, INTS, POINTER, REALS, Arr, EnumType, Str, StructType, common


class Expressions:
    """The expression half of `translate.Translator` (``self.m`` the machine, ``self.vars`` the POU's
    variables, ``self.fail`` the error naming the line)."""

    def expr(self, node) -> tuple[str, Any]:
        if isinstance(node, tf.Boolean):
            return ("True" if str(node.value).upper() == "TRUE" else "False"), "BOOL"
        if isinstance(node, tf.BitString):
            value = int(str(node.value).replace("_", ""), node.base)
            return str(value), (str(node.type_name).upper() if node.type_name else ANY_INT)
        if isinstance(node, tf.Integer):
            value = int(str(node.value).replace("_", ""), node.base)
            return str(value), (str(node.type_name).upper() if node.type_name else ANY_INT)
        if isinstance(node, tf.Real):
            return repr(float(str(node.value).replace("_", ""))), (str(node.type_name).upper() if node.type_name
                                                                   else ANY_REAL)
        if isinstance(node, tf.Duration):
            ms = sum(float(str(getattr(node, f) or 0)) * k for f, k in (("days", 86_400_000), ("hours", 3_600_000),
                                                                       ("minutes", 60_000), ("seconds", 1000),
                                                                       ("milliseconds", 1)))
            return str(int(-ms if node.negative else ms)), "TIME"
        if isinstance(node, tf.String):
            text = str(node.value)[1:-1]
            return repr(text), Str(len(text))
        if isinstance(node, tf.ParenthesizedExpression):
            code, t = self.expr(node.expr)
            return f"({code})", t
        if isinstance(node, tf.UnaryOperation):
            return self.unary(node)
        if isinstance(node, tf.BinaryOperation):
            return self.binary(node)
        if isinstance(node, tf.FunctionCall):
            return self.function_call(node)
        if isinstance(node, (tf.SimpleVariable, tf.MultiElementVariable)):
            return self.access(node)
        self.fail(node, f"{type(node).__name__} is outside the subset this machine runs")

    def unary(self, node) -> tuple[str, Any]:
        code, t = self.expr(node.expr)
        op = str(node.op).upper()
        if op == "NOT":
            if t == "BOOL":
                return f"(not {code})", t
            if t in BITS:
                return f"(~{code} & {(1 << BITS[t]) - 1})", t
            self.fail(node, f"NOT on {t}: IEC takes BOOL or a bit string (BYTE, WORD, DWORD, LWORD)")
        if op == "-":
            if t in INTS or t in REALS or t in (ANY_INT, ANY_REAL, "TIME"):
                return f"(-{code})", t
            self.fail(node, f"- on {t}")
        self.fail(node, f"unary {op}")

    def binary(self, node) -> tuple[str, Any]:
        a, at = self.expr(node.left)
        b, bt = self.expr(node.right)
        op = str(node.op).upper()
        if op in ("AND", "OR", "XOR", "AND_THEN", "OR_ELSE"):
            t = common(at, bt)
            if t == "BOOL":
                py = {"AND": "and", "AND_THEN": "and", "OR": "or", "OR_ELSE": "or", "XOR": "!="}[op]
                return f"({a} {py} {b})", t
            if t in BITS or (t == ANY_INT and {at, bt} & set(BITS)):
                py = {"AND": "&", "OR": "|", "XOR": "^"}[op]
                return f"({a} {py} {b})", t
            self.fail(node, f"{op} on {at} and {bt}: IEC takes BOOL or bit strings (BYTE, WORD, DWORD, LWORD)")
        if op in ("=", "<>", "<", ">", "<=", ">="):
            t = common(at, bt)
            enum = at == bt and isinstance(self.m.types.get(str(at).lower()), EnumType)
            if t is None and not enum:
                self.fail(node, f"{at} {op} {bt}: the operands' types differ")
            py = {"=": "==", "<>": "!="}.get(op, op)
            return f"({a} {py} {b})", "BOOL"
        if op in ("+", "-", "*", "/", "MOD"):
            t = common(at, bt)
            if t == "TIME" or (op in ("*", "/") and at == "TIME" and bt in (*INTS, ANY_INT)):
                t = "TIME"
            elif t is None or not (t in INTS or t in REALS or t in (ANY_INT, ANY_REAL)):
                self.fail(node, f"{at} {op} {bt}: arithmetic on different or non-numeric types")
            if op == "MOD" and not (t in INTS or t == ANY_INT):
                self.fail(node, f"MOD on {t}: IEC takes integers (ANY_INT)")
            if op == "/":
                expr = f"idiv({a}, {b})" if (t in INTS or t in (ANY_INT, "TIME")) else f"real_div({a}, {b})"
            elif op == "MOD":
                expr = f"({a} - idiv({a}, {b}) * {b})"
            else:
                expr = f"({a} {op} {b})"
            return (f"f32{expr}" if expr.startswith("(") else f"f32({expr})") if t == "REAL" else expr, t
        if op == "**":
            self.fail(node, "** is outside the subset")
        self.fail(node, f"operator {op}")

    def function_call(self, node) -> tuple[str, Any]:
        name = str(node.name.name) if isinstance(node.name, tf.SimpleVariable) else str(node.name)
        args = []
        for p in node.parameters:
            if not isinstance(p, tf.InputParameterAssignment) or p.name is not None:
                self.fail(node, f"{name}: a function takes its inputs by position here")
            args.append(p.value)
        upper = name.upper()
        m = re.fullmatch(r"([A-Z]+)_TO_([A-Z]+)", upper)
        if m:
            src, dst = m.groups()
            (code, t), = [self.expr(a) for a in args]
            if not (t == src or (t == ANY_INT and src in INTS | BITS) or (t == ANY_REAL and src in REALS)):
                self.fail(node, f"{name} of {t}: it takes {src}")
            if src in REALS and (dst in INTS or dst in BITS):
                return f"W_{dst}(real_to_int({code}))", dst
            if dst in INTS or dst in BITS:
                return f"W_{dst}({code})", dst
            if dst == "REAL":
                return f"f32(float({code}))", dst
            if dst == "LREAL":
                return f"float({code})", dst
            self.fail(node, f"{name} is outside the subset")
        if upper in ("LIMIT", "MIN", "MAX"):
            got = [self.expr(a) for a in args]
            t = got[0][1]
            for _, at in got[1:]:
                t = common(t, at)
                if t is None:
                    self.fail(node, f"{name} of {[g[1] for g in got]}: the inputs' types differ")
            codes = [c for c, _ in got]
            if upper == "LIMIT":
                if len(codes) != 3:
                    self.fail(node, "LIMIT takes three inputs: MN, IN, MX")
                return f"limit({', '.join(codes)})", t
            return f"{'minimum' if upper == 'MIN' else 'maximum'}({', '.join(codes)})", t
        if upper == "ABS":
            (code, t), = [self.expr(a) for a in args]
            return f"abs({code})", t
        if upper == "ADR":
            code, t = self.access(args[0])
            return f"Pointer({code}, {t!r})", POINTER
        if upper == "GETCURTASKINDEXEX":
            return "1", "BYTE"
        self.fail(node, f"function {name} is outside the subset")

    def access(self, node, store: bool = False) -> tuple[str, Any]:
        """The Python code and the type of a variable (``x``, ``a[i]``, ``st.f``, ``GVL.c``, ``E.VALUE``)."""
        if isinstance(node, tf.SimpleVariable):
            base, elements = str(node.name), []
        elif isinstance(node, tf.MultiElementVariable):
            base, elements = str(node.name.name), list(node.elements)
        else:
            self.fail(node, f"{type(node).__name__} where a variable is expected")
        key = base.lower()
        if key in self.vars:
            name, t = self.vars[key]
            code = f"self.{name}"
        elif key in self.m.globals and elements and isinstance(elements[0], tf.FieldSelector):
            gvl, types, constants = self.m.globals[key]
            field = str(elements.pop(0).field.name)
            match = {n.lower(): n for n in types}.get(field.lower())
            if match is None:
                self.fail(node, f"{gvl} has no {field}")
            if store and match in constants:
                self.fail(node, f"{gvl}.{match} is a constant")
            code, t = f"G_{gvl}.{match}", types[match]
        elif isinstance(self.m.types.get(key), EnumType) and elements:
            enum = self.m.types[key]
            value = str(elements.pop(0).field.name)
            if value not in enum.values or store:
                self.fail(node, f"{enum.name}.{value}")
            code, t = str(enum.values[value]), enum.name
        else:
            self.fail(node, f"{base} is not declared (qualified_only lists are read as LIST.name)")
        for e in elements:
            if isinstance(e, tf.SubscriptList):
                if not isinstance(t, Arr) or len(e.subscripts) != 1:
                    self.fail(node, f"{base}: an index on {t}")
                index, it = self.expr(e.subscripts[0])
                if not (it in INTS or it in BITS or it == ANY_INT):
                    self.fail(node, f"{base}: an index of {it}")
                code, t = f"{code}[({index}) - {t.lower}]", t.base
            else:
                field = str(e.field.name)
                kind = self.m.types.get(t.lower()) if isinstance(t, str) else None
                if isinstance(kind, StructType):
                    fields = {n.lower(): n for n in kind.fields}
                    if field.lower() not in fields:
                        self.fail(node, f"{kind.name} has no field {field}")
                    name = fields[field.lower()]
                    code, t = f"{code}.{name}", kind.fields[name]
                elif isinstance(t, str) and t.lower() in self.m.blocks:
                    cls = self.m.blocks[t.lower()]
                    pins = {n.lower(): (n, pt) for n, pt in {**cls.INPUTS, **cls.OUTPUTS}.items()}
                    if field.lower() not in pins or (store and field.lower() not in
                                                     {n.lower() for n in cls.INPUTS}):
                        self.fail(node, f"{t}.{field}: not an input or output (or written from outside)")
                    name, pt = pins[field.lower()]
                    code, t = f"{code}.{name}", pt
                else:
                    self.fail(node, f"{base}: .{field} on {t}")
        return code, t


