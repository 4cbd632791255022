"""Helpers for tests and the benchmark: service configs in a temporary folder, logs, free ports, leaks.

Shipped with the package (like python-can's virtual bus) so that tests, HIL tests and the benchmark
build their set-ups the same way.
"""

from __future__ import annotations

import os
import random
import socket
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from service.ati import AtiProtocol
from service.config import load_config
from service.sources.replay import write_log
from stiffness.effects import EFFECTS
from stiffness.effects.joint_spring import JointSpring
from stiffness.files.yaml_schema import deep_update, dump_yaml, read_yaml
from stiffness.model.stiffness_model import StiffnessModel

ROOT = Path(__file__).resolve().parent.parent
CONFIG = ROOT / "config"
TRUTH = ROOT / "examples" / "truth_reference.yaml"
# One entry of every library effect beyond the springs, at sizes a KR 125 shows (each effect's own
# `examples`): the service's every-effect start-up test, the HIL circle of the CLI test and the benchmark.
BEYOND_SPRINGS = [entry for cls in EFFECTS.values() for entry in cls.examples]
ROTATIONAL = ("rx_rad_per_Nm", "ry_rad_per_Nm", "rz_rad_per_Nm")      # a joint spring's rotational compliances


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port nothing listens on now, for a server a test is about to start, taken below the kernel's
    ephemeral range: a port the kernel hands out (bind to 0) is also what it gives the next client's
    outgoing connection, which may take it before the server binds (seen as "Address already in use"
    under load). ``kind``: socket.SOCK_STREAM (TCP) or socket.SOCK_DGRAM (UDP)."""
    low = _ephemeral_low()
    for _ in range(200):
        port = random.randint(max(1024, low - 12000), low - 1)
        with socket.socket(socket.AF_INET, kind) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
            return port
    with socket.socket(socket.AF_INET, kind) as s:       # the range is crowded: let the kernel choose
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ephemeral_low() -> int:
    """The first port of the kernel's ephemeral range (32768 where it cannot be read)."""
    try:
        return int(Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()[0])
    except (OSError, ValueError, IndexError):
        return 32768


def wait_for_port(port: int, proc: subprocess.Popen | None = None, timeout_s: float = 40.0,
                  host: str = "127.0.0.1") -> None:
    """Wait until something accepts TCP connections on ``port`` (a service starting in ``proc``).

    RuntimeError when ``proc`` exits first or ``timeout_s`` passes.
    """
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc is not None and proc.poll() is not None:
            raise RuntimeError(f"the process exited with code {proc.returncode} before it served port {port}")
        with socket.socket() as s:
            if s.connect_ex((host, port)) == 0:
                return
        time.sleep(0.1)
    raise RuntimeError(f"nothing served {host}:{port} within {timeout_s:g} s")


def write_config(folder: Path, overrides: dict[str, Any] | None = None, name: str = "service.yaml",
                 source: Path = CONFIG / "default.yaml") -> Path:
    """The service config ``source`` (config/default.yaml) with ``overrides`` merged in, written to
    ``folder``: the files it names made absolute by the config itself (`ServiceConfig.files`), so the copy
    names the same files. ADS and monitoring listen on free ports (not 48898 and 9020), so services of
    parallel tests and HIL runs never collide."""
    cfg = load_config(source)
    data = read_yaml(source)            # the one loader: aliases refused, errors name the file
    for key, rel in cfg.files().items():
        deep_update(data, _nested(key, str(cfg.resolve(rel).resolve())))
    deep_update(data, {"ads": {"port": free_port()}, "monitoring": {"port": free_port()}})
    deep_update(data, overrides or {})
    path = Path(folder) / name
    path.write_text(dump_yaml(data, sort_keys=False))
    return path


def _nested(key: str, value: Any) -> dict[str, Any]:
    """``{"a": {"b": value}}`` for the dotted key ``"a.b"``."""
    for part in reversed(key.split(".")):
        value = {part: value}
    return value


def truth_with(hidden: list[dict], axial_except: int | None = None, robot: Path | None = None) -> StiffnessModel:
    """examples/truth_reference.yaml (read from its file, to the digit) plus the ``hidden`` effect
    entries; with ``axial_except``, every joint but that one keeps only its axial spring (to hide a
    joint_6dof); with ``robot``, on that robot file (e.g. config/robots/kr125_masses.yaml: the same
    kinematics with masses) instead of its own."""
    d = yaml.safe_load(TRUTH.read_text())
    if robot is not None:
        d["robot"] = str(Path(robot).resolve())
    if axial_except is not None:
        d["effects"] = [e if e["joint"] == axial_except else
                        {"effect": JointSpring.name, "joint": e["joint"], "rz_rad_per_Nm": e["rz_rad_per_Nm"]}
                        for e in d["effects"]]
    d["effects"] = d["effects"] + list(hidden)
    label = " + ".join(["truth_reference", *(e["effect"] for e in hidden)])
    return StiffnessModel.from_dict(d, label, TRUTH.parent)


def model_with(*entries: dict, base: str | Path = "kr125_axial") -> StiffnessModel:
    """A model of config/models (``base`` a name there, or a model file) plus the effect ``entries``,
    on the same robot."""
    m = StiffnessModel.from_yaml(base if isinstance(base, Path) else CONFIG / "models" / f"{base}.yaml")
    d = m.to_dict()
    d["effects"] = d["effects"] + list(entries)
    label = " + ".join([m.name, *(e["effect"] for e in entries)])
    return StiffnessModel.from_dict(d, label, robot=m.robot)


def constant_log(path: Path, wrench, seconds: float = 1.0, rate_hz: float = 1000.0,
                 protocol: AtiProtocol | None = None, **kw) -> Path:
    """A log of a constant wrench (N, Nm), ``seconds`` long."""
    w = np.tile(np.asarray(wrench, dtype=float), (int(seconds * rate_hz), 1))
    write_log(path, w, rate_hz, protocol, **kw)
    return path


def sockets_open() -> set[str]:
    """The sockets this process holds (Linux /proc)."""
    out = set()
    for fd in os.listdir("/proc/self/fd"):
        try:
            target = os.readlink(f"/proc/self/fd/{fd}")
        except OSError:
            continue
        if target.startswith("socket:"):
            out.add(target)
    return out


def leaked_threads(before: set[threading.Thread], wait_s: float = 3.0) -> list[str]:
    """Threads started since ``before`` that are still alive after waiting up to ``wait_s``."""
    deadline = time.monotonic() + wait_s
    while True:
        extra = [t for t in threading.enumerate() if t not in before and t.is_alive()]
        if not extra or time.monotonic() > deadline:
            return [t.name for t in extra]
        time.sleep(0.02)


def scaled_model_file(source: Path, factor: float, dest: Path, extra: list | None = None,
                      keys: tuple[str, ...] = ("_per_N", "_per_Nm")) -> Path:
    """A copy of the model file ``source`` at ``dest`` with every compliance whose key ends with one of ``keys``
    (by default all: ``*_per_N``, ``*_per_Nm``) times ``factor`` and the ``extra`` effect entries appended (a
    same-structure reload, another structure, or with `ROTATIONAL` a catalogue model that is too stiff about
    its axes); its robot path is made absolute so the copy can live anywhere."""
    data = read_yaml(source)
    data["robot"] = str((Path(source).parent / data["robot"]).resolve())
    for e in data["effects"]:
        for k, v in e.items():
            if k.endswith(keys):
                e[k] = float(v) * factor          # YAML 1.1 reads 4e-07 (no point) as a string
    data["effects"] += extra or []
    Path(dest).write_text(dump_yaml(data, sort_keys=False))
    return Path(dest)


def box_scenario():
    """The default HIL scenario with the PLC's task at 1 ms and the virtual accelerometer on (what the
    accelerometer's HIL tests cut with: the EP3751 at 1000 Hz for a 1 ms task, docs/accelerometer.md)."""
    from .scenario import load_scenario

    sc = load_scenario()
    sc.plc.period_ms = 1.0
    sc.accelerometer.enabled = True
    return sc
