"""Test helpers shared across directories: paths and a small synthetic-campaign generator.

Imported as ``testlib.common``; conftest files only hold fixtures."""

from __future__ import annotations

import contextlib
import io
import subprocess
from pathlib import Path

import numpy as np

from stiffness.data.measurements import Dataset
from stiffness.kinematics.robot import Robot

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MODELS = ROOT / "config" / "models"


def run_cli(*args, cwd: Path = ROOT) -> subprocess.CompletedProcess:
    """``stiffcomp ARGS`` run in this process (`tools.cli.main`, what the console script calls), from ``cwd``,
    its standard output and error captured: what a subprocess would give, less its 1.7 s of imports. The
    tests of what only a process shows (a signal, an exit status without main, a traceback on stderr) start one.
    """
    from tools.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main([str(a) for a in args])
        except SystemExit as e:                          # argparse's usage errors and --help
            code = e.code if isinstance(e.code, int) else (0 if e.code is None else 1)
    return subprocess.CompletedProcess(["stiffcomp", *map(str, args)], code, out.getvalue(), err.getvalue())


def random_dataset(robot: Robot, n_readings: int, seed: int, max_force: float = 1200.0,
                   bodies=range(7)) -> Dataset:
    """Random configurations inside the limits and random wrenches; deflections zero (to be predicted)."""
    rng = np.random.default_rng(seed)
    lo, hi = robot.limits_deg[:, 0] * 0.7, robot.limits_deg[:, 1] * 0.7
    q = rng.uniform(lo, hi, size=(n_readings, 6))
    f = rng.uniform(-max_force, max_force, size=(n_readings, 3))
    lever = rng.uniform(-0.3, 0.3, size=(n_readings, 3))
    m = np.cross(lever, f)
    bodies = list(bodies)
    nb = len(bodies)
    rows = n_readings * nb
    rep = np.repeat(np.arange(n_readings), nb)
    return Dataset(time_s=rep.astype(float), config=np.array([f"C{i}" for i in rep]), q_deg=q[rep],
                   wrench=np.concatenate([f, m], axis=1)[rep], body=np.tile(bodies, n_readings),
                   deflection=np.zeros((rows, 6)))


def with_deflection(data: Dataset, deflection: np.ndarray) -> Dataset:
    out = data.subset(np.arange(len(data)))
    out.deflection = np.asarray(deflection, dtype=float)
    return out



def pose_error(fp, q_rad: np.ndarray, dq: np.ndarray, dX: np.ndarray) -> float:
    """Distance (m + rad) of the TCP at q + δq from the unloaded TCP at q moved by -dX, for a
    `service.compensation.FastPredictor` ``fp`` (its pinocchio model and data)."""
    import pinocchio as pin

    def tcp(q):
        pin.framesForwardKinematics(fp.pm, fp.pd, q)
        return fp.pd.oMf[fp.tcp_id].homogeneous.copy()

    T0, Tk = tcp(q_rad), tcp(q_rad + dq)
    dp = Tk[:3, 3] - (T0[:3, 3] - dX[:3])
    dr = pin.log3(Tk[:3, :3] @ (pin.exp3(-dX[3:]) @ T0[:3, :3]).T)
    return float(np.linalg.norm(dp) + np.linalg.norm(dr))


def wait_for(pred, timeout: float = 20.0, every: float = 0.01) -> bool:
    """Poll ``pred`` until it is true (True) or ``timeout`` seconds have passed (False): tests wait on
    an event, never on a fixed window."""
    import time

    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(every)
    return bool(pred())
