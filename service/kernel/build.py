"""Build the per-model part of the compiled cycle: the laws the model's terms use, written into the
template (`service.kernel.template`), cached on disk, imported, and their functions set as its globals.

The file is named by a hash of everything the compiled code depends on: the generated text, each law's
source, the kernel's own modules and the numba and Python versions. A changed law or kernel is therefore a
new file and a new compile; the same model in the next process (or the next test, or another service on
the machine) finds numba's cache beside the file and loads in milliseconds.

Where: ``$STIFFCOMP_KERNEL_CACHE``, else ``$XDG_CACHE_HOME/stiffcomp/kernels``, else
``~/.cache/stiffcomp/kernels`` (a temporary folder when none can be written).
"""

from __future__ import annotations

import hashlib
import importlib.util
import inspect
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType

from stiffness.units import M_TO_MM, RAD_TO_DEG

from ..signals import VECTOR_AT
from . import template

KINDS = ("axial", "history", "wrench", "twist")
# what the generated module runs (its key): these files, the glue's formulas and the process image's protocol
COMPILED_FILES = ("chain.py", "signal.py", "pack.py", "../cycle_rules.py", "../../plc_link/image.py", "steady_cycle.py",
                  "template.py", "build.py")
_HEAD = {"axial": "(tau, p)", "history": "(s, p, tau, dt)", "wrench": "(s, p, w, dt)", "twist": "(s, p, dX, dt)"}
_MODULES: dict[str, ModuleType] = {}


class NotCompilable(Exception):
    """A law (or a term) that has no compiled form; the message says which and why."""


def cache_dir() -> Path:
    env = os.environ.get("STIFFCOMP_KERNEL_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "stiffcomp" / "kernels"


def _source_of(fn) -> str:
    if not inspect.isfunction(fn) or fn.__name__ == "<lambda>" or fn.__closure__:
        raise NotCompilable(f"{getattr(fn, '__qualname__', fn)!r} is not a plain module-level function")
    try:
        return inspect.getsource(fn)
    except (OSError, TypeError) as e:
        raise NotCompilable(f"the source of {fn.__qualname__} cannot be read ({e})") from None


def generate(laws: dict[str, list]) -> tuple[str, dict[str, str], dict[str, object]]:
    """The globals' lines, the dispatch bodies by kind, and the globals (name -> law function)."""
    bodies, names = {}, {}
    for kind in KINDS:
        lines = []
        for k, fn in enumerate(laws.get(kind, [])):
            name = f"law_{kind[0]}{k}"
            names[name] = fn
            lines.append(f"    if k == {k}:\n        {'return ' if kind in ('axial', 'history') else ''}"
                         f"{name}{_HEAD[kind]}" + ("" if kind in ("axial", "history") else "\n        return"))
        bodies[kind] = "\n".join(lines) if lines else "    pass"
    glob = "\n".join(f"{n} = None  # {fn.__module__}.{fn.__qualname__}, set by service.kernel.build"
                     for n, fn in names.items())
    return glob, bodies, names


def module_for(laws: dict[str, list]) -> ModuleType:
    """The compiled cycle's module for these laws (kind -> list of functions, in the order of their index)."""
    import numba

    glob, bodies, names = generate(laws)
    here = Path(__file__).parent
    h = hashlib.sha256()
    for part in [glob, *bodies.values(), *(_source_of(fn) for fn in names.values()),
                 *((here / f).read_text() for f in COMPILED_FILES), repr(VECTOR_AT), numba.__version__, sys.version]:
        h.update(part.encode())
    key = h.hexdigest()[:20]
    if key in _MODULES:
        return _MODULES[key]
    at = {f"at_{name}": VECTOR_AT[name] for name in ("wrench_base", "wrench_sensor", "deflection")}
    text = template.TEMPLATE.format(key=key, globals=glob, rad_to_deg=RAD_TO_DEG, m_to_mm=M_TO_MM,
                                    views=template.views(), state=template.state(), at_dq=VECTOR_AT["dq_deg"],
                                    **at, **bodies)
    path = _write(f"stiffcomp_cycle_{key}.py", text)
    spec = importlib.util.spec_from_file_location(f"stiffcomp_cycle_{key}", path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod                # numba's cache finds the module's globals by its name
    spec.loader.exec_module(mod)
    for n, fn in names.items():
        setattr(mod, n, numba.njit(fn))
    _MODULES[key] = mod
    return mod


def _write(name: str, text: str) -> Path:
    """The file ``name`` holding ``text`` in the cache folder, written once (never rewritten: numba's cache
    beside it is valid while the file's time stamp stays)."""
    for folder in (cache_dir(), Path(tempfile.gettempdir()) / "stiffcomp-kernels"):
        path = folder / name
        if path.exists():
            return path
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
            with os.fdopen(fd, "w") as f:
                f.write(text)
            try:
                os.link(tmp, path)          # fails if another process was first: its file stays
            except FileExistsError:
                pass
            os.unlink(tmp)
            return path
        except OSError:
            continue
    raise NotCompilable("no folder to write the compiled cycle into (STIFFCOMP_KERNEL_CACHE)")
