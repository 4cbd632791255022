"""The probe log as each controller writes it, from the program's own text: the statements that write the log are
run as the controller runs them (KRL: StrClear, SWRITE, krl_fprintf, krl_fwriteln; RAPID: Write with its \\Num and
\\NoNewLine), with no escape processing anywhere (neither language has escape sequences in its literals)."""

from __future__ import annotations

import re

import numpy as np

from cell.robot.krl import code_of as krl_code_of
from cell.robot.rapid import code_of as rapid_code_of


def krl_defs(src: str) -> dict[str, list[str]]:
    """Each DEF's code lines, by name."""
    out, name = {}, None
    for raw in src.splitlines():
        code = krl_code_of(raw)
        head = re.match(r"^DEF\s+(\w+)\s*\(", code)
        if head:
            name = head.group(1)
            out[name] = []
        elif name is not None and code:
            out[name].append(code)
            if code == "END":
                name = None
    return out


def _args(text: str) -> list[str]:
    return [a.strip() for a in re.findall(r'\s*("[^"]*"|[^,]+)', text)]


def _value(arg: str, env: dict):
    return arg[1:-1] if arg.startswith('"') else env[arg] if arg in env else float(arg)


def krl_run_log(lines: list[str], env: dict) -> str:
    """What the DEF's ``lines`` write to the log (KRL's formats are C's; a literal is written as it stands)."""
    text, buf = [], ""
    for code in lines:
        if re.match(r"\w+\s*=\s*StrClear\(logLine\[\]\)", code):
            buf = ""
        elif m := re.match(r'SWRITE\(logLine\[\],\s*\w+,\s*\w+,\s*(.*)\)$', code):
            fmt, *args = _args(m.group(1))
            buf += _value(fmt, env) % tuple(_value(a, env) for a in args)
        elif m := re.search(r'"krl_fprintf",\s*logHandle,\s*(.*)\)$', code):
            fmt, *args = _args(m.group(1))
            text.append(_value(fmt, env) % tuple(_value(a, env) for a in args))
        elif m := re.search(r'"krl_fwriteln",\s*logHandle,\s*(.*)\)$', code):
            arg = m.group(1).strip()
            text.append((buf if arg == "logLine[]" else _value(arg, env)) + "\n")
    return "".join(text)


def kuka_rotation(a: float, b: float, c: float) -> np.ndarray:
    """A KUKA frame's rotation: A about Z, then B about the new Y, then C about the new X (deg)."""
    a, b, c = np.radians([a, b, c])
    rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rx = np.array([[1, 0, 0], [0, np.cos(c), -np.sin(c)], [0, np.sin(c), np.cos(c)]])
    return rz @ ry @ rx


def krl_log(src: str, data: dict, touches: list[tuple[np.ndarray, float, float]], base_abc=(0.0, 0.0, 0.0)) -> str:
    """The log StiffCompProbe.src writes: LOG_HEADER, then LOG_TOUCH for each (joints, dx, dy), the base turned by
    ``base_abc`` in the robot's root (what ``tip = toRoot : tip`` gives)."""
    defs = krl_defs(src)
    env = {n: v for n, v in data.items() if not isinstance(v, dict)}
    env.update({f"probeFrame.{c}": v for c, v in data.get("probeFrame", {}).items()})
    text = krl_run_log(defs.get("LOG_HEADER", []), env)
    rot = kuka_rotation(*base_abc)
    for k, (q, dx, dy) in enumerate(touches, 1):
        ax, ay, az = rot @ np.array([dx, dy, 0.0])
        env.update({f"hit.A{i + 1}": float(v) for i, v in enumerate(q)})
        env.update(k=k, dx=dx, dy=dy, ax=float(ax), ay=float(ay), az=float(az))
        text += krl_run_log(defs.get("LOG_TOUCH", []), env)
    return text


# -- RAPID ----------------------------------------------------------------------------------------------------
def rapid_procs(mod: str) -> dict[str, list[str]]:
    """Each PROC's statements (to their ``;``), by name."""
    out, name, part = {}, None, ""
    for raw in mod.splitlines():
        code = rapid_code_of(raw).strip()
        if m := re.match(r"PROC\s+(\w+)", code):
            name = m.group(1)
            out[name] = []
        elif code.startswith("ENDPROC"):
            name = None
        elif name is not None and code:
            part = f"{part} {code}".strip()
            if part.endswith(";"):
                out[name].append(part)
                part = ""
    return out


def _numtostr(value: float, decimals: int) -> str:
    return f"{round(value, decimals):.{decimals}f}" if decimals else str(round(value))


def rapid_string(expr: str, env: dict) -> str:
    """The string a chain of literals and NumToStr calls builds at run time."""
    out = ""
    for term in re.findall(r'"[^"]*"|NumToStr\([^()]*\)', expr):
        if term.startswith('"'):
            out += term[1:-1]
        else:
            value, decimals = (a.strip() for a in term[len("NumToStr("):-1].rsplit(",", 1))
            out += _numtostr(float(env[value]), int(decimals))
    return out


def rapid_run_log(statements: list[str], env: dict, strings: list[str]) -> str:
    """What ``Write log, ..`` statements write; every string they build goes to ``strings`` as well."""
    text = ""
    for s in statements:
        m = re.match(r"Write\s+log\s*,\s*(.*?)\s*((?:\\\w+(?::=\w+)?\s*)*);$", s)
        if m is None:
            continue
        built = rapid_string(m.group(1), env)
        strings.append(built)
        text += built
        num = re.search(r"\\Num:=(\w+)", m.group(2))
        if num:
            text += f"{float(env[num.group(1)]):g}"
        if "\\NoNewLine" not in m.group(2):
            text += "\n"
    return text


def rapid_log(mod: str, consts: dict, touches: list[tuple[np.ndarray, np.ndarray]], strings: list[str]) -> str:
    """The log StiffCompProbe.modx writes: LogHeader, then LogTouch for each (joints, approach in the base)."""
    procs = rapid_procs(mod)
    env = dict(consts)
    text = rapid_run_log(procs.get("LogHeader", []), env, strings)
    for k, (q, d) in enumerate(touches, 1):
        env.update({f"jHit.robax.rax_{i + 1}": float(v) for i, v in enumerate(q)})
        env.update({"k": k, "dBase.x": float(d[0]), "dBase.y": float(d[1]), "dBase.z": float(d[2])})
        text += rapid_run_log(procs.get("LogTouch", []), env, strings)
    return text
