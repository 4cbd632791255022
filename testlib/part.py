"""A synthetic cut for the part tests: a trace and a measured part made by a truth model, without the HIL.

The tool follows the HIL's circle (its inverse kinematics, `hil.path.CirclePath`) uncompensated; the cutting
force turns with the feed (constant feed, normal and axial components). The arm deflects by the truth's
prediction over the whole cut in time order (so a history effect sees the whole load history), and each
measured point lies the tool radius beyond the deflected tool, along the contour's normal, plus probe noise.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from hil.path import CirclePath
from hil.scenario import CircleConfig
from stiffness.data.measurements import Dataset
from stiffness.data.part_points import write_part
from stiffness.data.trace_file import COLUMNS, TraceFile
from stiffness.kinematics.robot import PoseConfig
from stiffness.model.stiffness_model import StiffnessModel

CENTER_Q = [0.0, -60.0, 90.0, 0.0, 60.0, 0.0]
TOOL_RADIUS_MM = 4.0


@lru_cache(maxsize=8)
def _circle(robot, center_q: tuple, ik_points: int) -> CirclePath:
    return CirclePath(robot, CircleConfig(center_q_deg=list(center_q), points=ik_points))


@dataclass
class SyntheticCut:
    trace: Path
    part: Path
    deviation_mm: np.ndarray        # n . dX of the truth at each point, in the part's order
    points_base: np.ndarray         # (n, 3) m
    frame: PoseConfig


def synthetic_cut(truth: StiffnessModel, folder: Path, name: str = "cut", center_q=CENTER_Q, points: int = 180,
                  noise_um: float = 2.0, seed: int = 0, mask_deg: float = 10.0, force_N=(320.0, 450.0, 150.0),
                  dt: float = 0.002, ik_points: int = 720) -> SyntheticCut:
    """Write ``folder/name.csv`` (trace) and ``folder/name_part.csv`` (part); see the module docstring."""
    robot = truth.robot
    path = _circle(robot, tuple(center_q), ik_points)
    t = np.arange(-0.2, path.duration + 0.2, dt)
    q = np.array([path.q_ref_deg(x) for x in t])
    phi = path.angle(t)
    ramp = np.clip(t / 0.1, 0.0, 1.0) * np.clip((path.duration + 0.1 - t) / 0.1, 0.0, 1.0)
    Ff, Fn, Fa = force_N
    a = path.R_tool[:, 2]
    F = ramp[:, None] * (-Ff * path.tangent(phi) - Fn * path.outward(phi) - Fa * a)
    frames = robot.frames(np.radians(q))
    tcp, sensor = frames[:, 7, :3, 3], robot.sensor_pose(frames)
    w_base = np.concatenate([F, np.cross(tcp - sensor[:, :3, 3], F)], axis=1)
    R_s = sensor[:, :3, :3]
    w_sensor = np.concatenate([np.einsum("nji,nj->ni", R_s, w_base[:, :3]),
                               np.einsum("nji,nj->ni", R_s, w_base[:, 3:])], axis=1)
    data = Dataset(t, np.full(len(t), "cut"), q, w_sensor, np.full(len(t), 6), np.full((len(t), 6), np.nan))
    dX = truth.predict(truth.context(data))[:, :3] / 1000.0
    table = np.zeros((len(t), len(COLUMNS)))
    col = {c: k for k, c in enumerate(COLUMNS)}
    table[:, col["time_s"]] = t + 1.0
    table[:, col["cycle"]] = np.arange(len(t)) + 1
    table[:, col["q1_deg"]: col["q6_deg"] + 1] = q
    table[:, col["fx_N"]: col["mz_Nm"] + 1] = w_base
    table[:, col["status_word"]] = 1
    table[:, col["task_state"]] = 1
    folder = Path(folder)
    with TraceFile(folder / f"{name}.csv") as f:
        f.write(table)
    cut_rows = np.nonzero((phi > np.radians(mask_deg)) & (phi < 2 * np.pi - np.radians(mask_deg)))[0]
    pick = cut_rows[np.linspace(0, len(cut_rows) - 1, points).astype(int)]
    n = path.outward(phi[pick])
    rng = np.random.default_rng(seed)
    wall = tcp[pick] + dX[pick] + TOOL_RADIUS_MM / 1000.0 * n + noise_um * 1e-6 * rng.standard_normal((len(pick), 3))
    frame = PoseConfig(xyz_mm=(path.center * 1000.0).tolist(), rpy_deg=[0.0, 0.0, 30.0])
    T = frame.matrix()
    write_part(folder / f"{name}_part.csv", (wall - T[:3, 3]) @ T[:3, :3] * 1000.0, TOOL_RADIUS_MM, frame, name)
    return SyntheticCut(folder / f"{name}.csv", folder / f"{name}_part.csv",
                        np.einsum("na,na->n", dX[pick], n) * 1000.0, wall, frame)


STYLUS_RADIUS_MM = 1.5


def probe_touches(cut: SyntheticCut, robot, touches: int = 36, stylus_radius_mm: float = STYLUS_RADIUS_MM,
                  center_q=CENTER_Q, ik_points: int = 720) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The robot's own probe of ``cut``'s wall: ``touches`` of its points, each touched by a stylus of
    ``stylus_radius_mm`` moving along the wall's normal, the joints latched at the contact (no latency, no
    repeatability) by ``robot``'s inverse kinematics (the robot that cut it: its geometry is the truth's).
    Returns the latched joints (deg), the approach directions (base) and which of the part's points were touched."""
    import pinocchio as pin

    from hil.path import solve_ik

    path = _circle(robot, tuple(center_q), ik_points)
    pick = np.linspace(0, len(cut.points_base) - 1, touches).astype(int)
    wall = cut.points_base[pick]
    a = path.R_tool[:, 2]
    n = (wall - path.center) @ (np.eye(3) - np.outer(a, a))
    n /= np.linalg.norm(n, axis=1)[:, None]
    centre = wall - stylus_radius_mm / 1000.0 * n
    q, guess = [], np.radians(center_q)
    for x in centre:
        guess = solve_ik(robot, pin.SE3(path.R_tool, x), guess)
        q.append(np.degrees(guess))
    return np.array(q), n, pick
