"""A POU's statements translated once into the source of a Python function over its variables (`Translator`);
its expressions are `expressions.Expressions`'. A construct outside the subset, or a typing rule broken, is an
`StError` naming the POU and line, never a silent no-op."""

from __future__ import annotations

from typing import Any

from blark import transform as tf

from .expressions import Expressions
from .values import (
    ANY_INT,
    BITS,
    INTS,
    Arr,
    StError,
    Str,
    StructType,
    common,
    limit,
    maximum,
    minimum,
    real_div,
    real_to_int,
    widens,
)

# what the translated code calls besides `Machine.namespace`: the PLC's results for every value (`values`)
HELPERS = {"real_to_int": real_to_int, "limit": limit, "minimum": minimum, "maximum": maximum, "real_div": real_div}


class Translator(Expressions):
    """One POU's statements as the source of a Python function ``body(self)``."""

    def __init__(self, machine, name: str, cls):
        self.m, self.name, self.cls = machine, name, cls
        self.vars = {n.lower(): (n, t) for n, t in {**cls.INPUTS, **cls.OUTPUTS, **cls.LOCALS}.items()}
        self.lines: list[str] = []
        self.temps = 0

    def fail(self, node, why: str):
        line = getattr(getattr(node, "meta", None), "line", "?")
        raise StError(f"{self.name}: line {line}: {why}")

    def function(self, statements) -> Any:
        self.lines = ["def body(self):", "    rt = M.runtime"]
        self.block(statements, 1)
        self.lines.append("    return None")
        namespace = {**self.m.namespace, **HELPERS, "M": self.m}
        exec("\n".join(self.lines), namespace)     # noqa: S102 (our own translation of the parsed source)
        body = namespace["body"]
        body.source = "\n".join(self.lines)
        return body

    def emit(self, depth: int, text: str) -> None:
        self.lines.append("    " * depth + text)

    def block(self, statements, depth: int) -> None:
        items = statements.statements if statements is not None else []
        if not items:
            self.emit(depth, "pass")
        for s in items:
            self.statement(s, depth)

    # -- statements ------------------------------------------------------------------------------------
    def statement(self, s, depth: int) -> None:
        if isinstance(s, tf.AssignmentStatement):
            value, vt = self.expr(s.expression)
            for target in s.variables:
                code, tt = self.access(target, store=True)
                self.store(depth, code, tt, value, vt, s)
        elif isinstance(s, tf.FunctionCallStatement):
            self.call_block(s, depth)
        elif isinstance(s, tf.IfStatement):
            self.emit(depth, f"if {self.condition(s.if_expression)}:")
            self.block(s.statements, depth + 1)
            for clause in s.else_ifs:
                self.emit(depth, f"elif {self.condition(clause.if_expression)}:")
                self.block(clause.statements, depth + 1)
            if s.else_clause is not None:
                self.emit(depth, "else:")
                self.block(s.else_clause.statements, depth + 1)
        elif isinstance(s, tf.CaseStatement):
            code, t = self.expr(s.expression)
            if t not in INTS and t != ANY_INT:
                self.fail(s, f"CASE on {t}: IEC takes an integer (or an enum's own values)")
            temp = self.temp()
            self.emit(depth, f"{temp} = {code}")
            word = "if"
            for case in s.cases:
                labels = []
                for match in case.matches:
                    label, lt = self.expr(match)
                    if common(lt, t) is None:
                        self.fail(case, f"CASE label of {lt} for a selector of {t}")
                    labels.append(label)
                self.emit(depth, f"{word} {temp} in ({', '.join(labels)},):")
                self.block(case.statements, depth + 1)
                word = "elif"
            if s.else_clause is not None:
                self.emit(depth, "else:" if word == "elif" else "if True:")
                self.block(s.else_clause.statements, depth + 1)
        elif isinstance(s, tf.ForStatement):
            var, vt = self.access(s.control, store=True)
            start, st = self.expr(s.from_)
            end, et = self.expr(s.to)
            step, pt = self.expr(s.step) if s.step is not None else ("1", ANY_INT)
            if vt not in INTS or any(common(x, vt) is None for x in (st, et, pt)):
                self.fail(s, "FOR takes an integer variable and integer bounds")
            self.emit(depth, f"{var} = {start}")
            self.emit(depth, f"while ({var} <= {end}) if ({step}) > 0 else ({var} >= {end}):")
            self.block(s.statements, depth + 1)
            self.emit(depth + 1, f"{var} = W_{vt}({var} + ({step}))")
        else:
            self.fail(s, f"{type(s).__name__} is outside the subset this machine runs")

    def temp(self) -> str:
        self.temps += 1
        return f"_t{self.temps}"

    def condition(self, node) -> str:
        code, t = self.expr(node)
        if t != "BOOL":
            self.fail(node, f"a condition of {t}: IEC takes BOOL")
        return code

    def store(self, depth: int, target: str, tt, value: str, vt, node) -> None:
        if not self.assignable(vt, tt):
            self.fail(node, f"{vt} assigned to {tt}: IEC 61131-3 converts it only explicitly")
        kind = self.m.types.get(tt.lower()) if isinstance(tt, str) else None
        if isinstance(kind, StructType):
            self.emit(depth, f"{target}.assign({value})")
        elif isinstance(tt, Arr):
            self.emit(depth, f"{target}[:] = {value}")
        elif tt in INTS or tt in BITS or tt == "TIME":
            self.emit(depth, f"{target} = W_{tt}({value})")
        elif tt == "REAL":
            self.emit(depth, f"{target} = f32({value})")
        elif tt == "LREAL":
            self.emit(depth, f"{target} = float({value})")
        elif isinstance(tt, Str):
            self.emit(depth, f"{target} = ({value})[:{tt.length}]")
        else:
            self.emit(depth, f"{target} = {value}")

    def assignable(self, src, dst) -> bool:
        if src == dst or (isinstance(src, str) and isinstance(dst, str) and widens(src, dst)):
            return True
        return isinstance(src, Str) and isinstance(dst, Str)

    def call_block(self, s, depth: int) -> None:
        code, t = self.access(s.name)
        cls = self.m.blocks.get(t.lower()) if isinstance(t, str) else None
        if cls is None:
            self.fail(s, f"{t} called as a statement: only function block instances are")
        pins = {n.lower(): (n, pt) for n, pt in cls.INPUTS.items()}
        obj = self.temp()
        self.emit(depth, f"{obj} = {code}")
        for p in s.parameters:
            if not isinstance(p, tf.InputParameterAssignment) or p.name is None:
                self.fail(s, "a block is called with named inputs (pin := value) only")
            pin = str(p.name.name).lower()
            if pin not in pins:
                self.fail(s, f"{t} has no input {p.name.name}")
            name, pt = pins[pin]
            value, vt = self.expr(p.value)
            self.store(depth, f"{obj}.{name}", pt, value, vt, s)
        self.emit(depth, f"{obj}.body()")

    # -- expressions -----------------------------------------------------------------------------------
