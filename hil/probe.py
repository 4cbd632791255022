"""The virtual probe: after the cut the robot, unloaded, probes the contour it machined with a touch probe in
its spindle, as the robot-side programs do (cell/robot/generated/probe/, docs/part.md "The robot probes its own part").

The machined wall is what the cut left: the tool's actual centre p (the stub's true TCP over the cut,
`hil.report.evaluate`) offset by the tool radius r toward the wall. For each touch at a nominal path angle phi
the program starts the stylus centre at the nominal path's point (at the touch's height) and moves it along
the contour's nominal normal d toward the wall at the probing speed v. The controller moves the arm through
the truth robot's own kinematics (the program was taught on it, as the cut's was: `hil.world.World` solves the
circle with the truth's robot), so the stylus centre follows

    x(s) = P0 + s d + eps,          eps ~ N(0, (repeatability / 3)^2) per axis, one draw per touch

eps the robot's repeatability (ISO 9283's RP, about +-0.03 mm for a KR 125 class arm, taken as 3 sigma). The
ball touches the wall when its centre lies r - r_s from the tool's actual path on the wall's side (the wall is
the cutter's envelope, r off its centre's path); the controller latches the joints tau later, the probe
having moved on v tau:

    q_trigger = IK(P0 + (s* + v tau) d),      tau = latency + U(-jitter, +jitter)

solved on the truth robot. The log states the probing speed and the nominal latency (what the maker's manual
gives), so the reader takes v * latency back and only the jitter and the repeatability stay in the touch.

The stiffness model's robot lacks what the truth's DH table holds; the probe log is read through the model's
kinematics, as the trace is, and there the two cancel (`stiffness.part.probe`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin

from stiffness.data.probe_log import write_probe
from stiffness.kinematics.robot import PoseConfig, Robot
from stiffness.part.contour import ToolPath

from .iso9283 import cut_by_angle
from .path import solve_ik
from .report import Evaluation
from .scenario import Scenario
from .world import World


@dataclass
class ProbeResult:
    """The touches of one probing: latched joints (deg), approach directions (base), the true contact points
    (base, m, for tests), the probe's geometry and what the log states."""

    q_deg: np.ndarray
    approach: np.ndarray
    contact: np.ndarray
    tool_radius_mm: float
    stylus_radius_mm: float
    probe_frame: PoseConfig
    speed_mm_s: float
    latency_ms: float

    def write(self, path: str | Path, title: str = "virtual probe of a HIL cut") -> Path:
        return write_probe(path, self.q_deg, self.approach, self.tool_radius_mm, self.stylus_radius_mm,
                           self.probe_frame, title, self.speed_mm_s, self.latency_ms)


def probe(scenario: Scenario, world: World, robot: Robot, evaluation: Evaluation, touches: int | None = None,
          seed: int | None = None) -> ProbeResult:
    """The virtual probe's touches of one pass (``evaluation``: `hil.report.evaluate`'s record) by the truth
    ``robot``; ``touches`` and ``seed`` override the scenario's ``probe`` section."""
    cfg = scenario.probe
    path = world.path
    n_touch = touches or cfg.touches
    r = scenario.milling.tool_diameter_mm / 2000.0
    rs = cfg.stylus_radius_mm / 1000.0
    side = 1.0 if scenario.milling.normal_toward_center else -1.0     # the wall outside the path: a pocket
    a = path.R_tool[:, 2]
    P = np.eye(3) - np.outer(a, a)
    ang, p = cut_by_angle(evaluation)
    actual = ToolPath(p, a)                                         # the tool's actual path, seen along its axis
    centre = actual.c2.mean(axis=0)
    mask = np.radians(cfg.entry_exit_mask_deg)
    phi = np.linspace(mask, 2 * np.pi - mask, n_touch)
    phi = phi[(phi >= ang.min()) & (phi <= ang.max())]
    rng = np.random.default_rng(cfg.seed if seed is None else seed)
    sigma = cfg.repeatability_mm / 3000.0
    q_out, d_out, contact = [], [], []
    guess_of = path.q_table_deg
    for f in phi:
        d = side * (path.outward(f) @ P)
        d /= np.linalg.norm(d)
        P0 = path.point(f) - (cfg.depth_mm / 1000.0) * a
        eps = sigma * rng.standard_normal(3)
        s = _touch(actual, centre, P0 + eps, d, side, r - rs)
        tau = (cfg.latency_ms + rng.uniform(-cfg.latency_jitter_ms, cfg.latency_jitter_ms)) / 1000.0
        x_latch = P0 + (s + cfg.speed_mm_s / 1000.0 * tau) * d
        k = round(f / (2 * np.pi) * (len(guess_of) - 1))
        q = solve_ik(robot, pin.SE3(path.R_tool, x_latch), np.radians(guess_of[k]))
        q_out.append(np.degrees(q))
        d_out.append(d)
        contact.append(P0 + eps + s * d + rs * d)
    tcp = robot.config.tcp
    return ProbeResult(np.array(q_out), np.array(d_out), np.array(contact), r * 1000.0, cfg.stylus_radius_mm,
                       PoseConfig(xyz_mm=list(tcp.xyz_mm), rpy_deg=list(tcp.rpy_deg)), cfg.speed_mm_s,
                       cfg.latency_ms)


def _touch(actual: ToolPath, centre: np.ndarray, start: np.ndarray, d: np.ndarray, side: float, at: float,
           iterations: int = 8) -> float:
    """How far along ``d`` from ``start`` the stylus centre lies ``at`` (r - r_s) from the tool's ``actual`` path
    on the wall's side: Newton on the signed distance in the plane across the tool axis."""
    s = 0.0
    for _ in range(iterations):
        x = start + s * d
        signed = _signed(actual, centre, x, side)
        step = at - signed
        s += step
        if abs(step) < 1e-10:
            break
    return s


def _signed(actual: ToolPath, centre: np.ndarray, x: np.ndarray, side: float) -> float:
    """The signed distance (m) of ``x`` from the ``actual`` path across the tool axis: positive on the wall's side,
    away from the path's ``centre`` (in the plane) for a pocket (side +1), toward it for a boss. The foot of the
    perpendicular on the polyline beside the nearest sample, every chord of it the path (the samples a cycle
    apart)."""
    x2 = actual.in_plane(x[None])
    dist, foot = actual.feet(x2, chord_steps=np.inf)
    out = side * (x2[0] - foot[0])
    return float(dist[0]) if np.dot(out, foot[0] - centre) >= 0 else -float(dist[0])
