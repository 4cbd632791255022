"""The virtual CMM: the contour the robot stub really cut, measured as a CMM measures a part.

The tool's edge makes the wall: at each path angle phi the surface lies the tool radius r from the tool's
actual centre p(phi) (the stub's true TCP, `hil.report.evaluate`), on the wall's side (outside the circle
when the milling force pushes the tool towards the centre, ``normal_toward_center``):

    w(phi) = p(phi) + s r u(phi) - depth a + noise,       s = +1 wall outside, -1 inside

u(phi) the circle's outward direction o(phi) made perpendicular to the tool axis a (the wall is parallel
to the tool: a tilted tool cuts a tilted wall), ``points`` angles equally spaced, seeded Gaussian probe noise of
``noise_um`` (1 sigma) on each axis. Points within ``entry_exit_mask_deg`` of the start are left out, as
the paper leaves out the entry and exit (the tool passes there twice). The points are written in the part
frame of the scenario's ``cmm.part_frame`` (default: at the circle's nominal centre, the base's axes), in
the part format (`stiffness.data.part_points`), or, to a ``.qif`` file, as a CMM's QIF 3 results: the measured
circle ``CONTOUR`` with the nominal one it should be (`stiffness.data.qif_write`).

The part's error is each point's normal deviation from the nominal wall, the nominal path offset the same
way (Fig. 8b): ``part_error_mm`` is its mean absolute value.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from stiffness.data.part_points import write_part
from stiffness.data.qif_write import NominalCircle, write_qif_circle
from stiffness.kinematics.robot import PoseConfig

from .iso9283 import cut_by_angle
from .scenario import Scenario
from .world import World

if TYPE_CHECKING:
    from .report import Evaluation


@dataclass
class CmmResult:
    """The measured points (base, m), their angles (rad), their normal deviations (mm), the part frame and the
    nominal wall (part frame, mm)."""

    points: np.ndarray
    angle: np.ndarray
    error_mm: np.ndarray
    frame: PoseConfig
    tool_radius_mm: float
    nominal: NominalCircle | None = None

    @property
    def part_error_mm(self) -> float:
        return float(np.mean(np.abs(self.error_mm)))

    @property
    def qif_options(self) -> str:
        """What a QIF file does not carry, as `stiffcomp part`'s options (the values a part CSV writes)."""
        return (f"--tool-radius-mm {self.tool_radius_mm:g} --part-frame "
                + " ".join([f"{v:.4f}" for v in self.frame.xyz_mm] + [f"{v:.6g}" for v in self.frame.rpy_deg]))

    def write(self, path: str | Path, title: str = "virtual CMM of a HIL cut") -> Path:
        """The points in the part format, or as QIF 3 results to a ``.qif`` file (any case)."""
        T = self.frame.matrix()
        local = (self.points - T[:3, 3]) @ T[:3, :3] * 1000.0
        if str(path).lower().endswith(".qif"):
            return write_qif_circle(path, local, self.nominal)
        return write_part(path, local, self.tool_radius_mm, self.frame, title)


def measure(scenario: Scenario, world: World, evaluation: Evaluation) -> CmmResult:
    """The virtual CMM's points of one pass (``evaluation``: `hil.report.evaluate`'s)."""
    cfg = scenario.cmm
    path = world.path
    r = scenario.milling.tool_diameter_mm / 2000.0
    side = 1.0 if scenario.milling.normal_toward_center else -1.0
    ang, p = cut_by_angle(evaluation)
    mask = np.radians(cfg.entry_exit_mask_deg)
    phi = np.linspace(0.0, 2 * np.pi, cfg.points, endpoint=False)
    phi = phi[(phi >= mask) & (phi <= 2 * np.pi - mask)]
    inside = (phi >= ang.min()) & (phi <= ang.max())
    phi = phi[inside]
    tool = np.column_stack([np.interp(phi, ang, p[:, k]) for k in range(3)])
    a = path.R_tool[:, 2]
    u = path.outward(phi) @ (np.eye(3) - np.outer(a, a))
    u /= np.linalg.norm(u, axis=1)[:, None]
    rng = np.random.default_rng(cfg.seed)
    w = tool + side * r * u + (cfg.depth_mm / 1000.0) * a + cfg.noise_um * 1e-6 * rng.standard_normal(tool.shape)
    nominal = path.point(phi) + side * r * u + (cfg.depth_mm / 1000.0) * a
    error_mm = side * np.einsum("na,na->n", w - nominal, u) * 1000.0
    frame = cfg.part_frame or PoseConfig(xyz_mm=(path.center * 1000.0).tolist(), rpy_deg=[0.0, 0.0, 0.0])
    T = frame.matrix()
    center = (path.center + (cfg.depth_mm / 1000.0) * a - T[:3, 3]) @ T[:3, :3] * 1000.0
    wall = NominalCircle(center, np.array([0.0, 0.0, 1.0]) @ T[:3, :3], 2000.0 * (path.radius + side * r),
                         internal=side > 0)             # the wall outside the tool's path: a pocket's
    return CmmResult(w, phi, error_mm, frame, r * 1000.0, wall)
