"""The arm's first modes at any pose: predicted from physics, corrected by a few measured poses (a modal map).

The physics (the prior). The arm's first modes are its main axes swinging the wrist and the tool on the
joints' springs; the wrist's own modes lie far above them, so the wrist is taken as locked. At the pose q,
in base axes and for the TCP's translation:

    Lambda(q) = J(q)^-T M(q) J(q)^-1      the arm's inertia at the TCP: M the joints 1-3 block of the joint
                                          space mass matrix (pinocchio's `crba`, the wrist, flange and tool
                                          carried rigidly), J the TCP's translational Jacobian of joints 1-3
    K(q) = C(q)^-1                        the stiffness at the TCP: C the stiffness model's compliance there
                                          (`stiffness.model.cartesian.tcp_compliance`, its 3 x 3 force block)
    K phi_k = w_k^2 Lambda phi_k          mode k: frequency f_k = w_k / 2 pi, direction phi_k

M is linear in the masses, so Lambda = Lambda_arm + m_tool Lambda_1 (the tool at its centre of gravity, one
kg in Lambda_1). The masses are the robot description's ``inertial`` links (the arm-weight effect's) and
the tool's, as the service's gravity section gives it.

The correction. Three physical factors, theta = (ln c_K, ln c_M, m_tool): K -> c_K K, Lambda -> c_M
Lambda_arm + m_tool Lambda_1, found by least squares from the modes measured at a few poses (a tap test's or
a cut's, `stiffcomp modes`), each frequency weighted by `MEASURED_SIGMA`, and pulled toward the prior
(c_K = c_M = 1 by `PRIOR_SIGMA`; the tool's mass by `TOOL_SIGMA` of its own): a pose or two corrects the
whole workspace as far as those factors explain it, and no measurement leaves the prior as it is.

The HIL's robot stub computes its true modes the same way from its own stiffness, masses and tool
(`hil.structure`, ``frequencies: physics``); docs/accelerometer.md has the map's figures.

Example: a point mass on a spring at the TCP rings at sqrt(k / m) / 2 pi.

>>> import numpy as np
>>> f, phi = modes(np.eye(3) * 2e6, np.eye(3) * 500.0)
>>> print(np.round(f, 2))
[10.07 10.07 10.07]
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy import linalg, optimize

from ..errors import DataError
from ..kinematics.robot import Robot
from ..kinematics.statics import PayloadConfig

ARM_JOINTS = 3              # the joints whose springs and inertia make the first modes (the wrist locked)
MEASURED_SIGMA = 0.01       # a measured mode's frequency, 1 sigma (a tap test's identification: < 1 %)
PRIOR_SIGMA = 0.2           # c_K and c_M about 1: the masses are estimates, the springs identified
TOOL_SIGMA = 0.3            # the tool's mass about what the gravity section says, as a share of it
MIN_TOOL_SIGMA_KG = 2.0
MAX_CONDITION = 1e6         # the TCP's translational Jacobian of joints 1-3, and its compliance: beyond, singular


def modes(K: np.ndarray, Lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The modes of a stiffness ``K`` (3, 3) on an inertia ``Lam`` (3, 3): frequencies (3,) in Hz, lowest
    first, and directions (3, 3), column k mode k's, unit length (they are Lam-orthogonal, not orthogonal)."""
    w2, V = linalg.eigh((K + K.T) / 2, (Lam + Lam.T) / 2)
    V = V / np.linalg.norm(V, axis=0)
    V = V * np.where(V[np.argmax(np.abs(V), axis=0), range(3)] < 0, -1.0, 1.0)   # largest component positive
    return np.sqrt(np.maximum(w2, 0.0)) / (2 * np.pi), V


class ArmInertia:
    """Lambda_arm(q) and Lambda_1(q) (module docstring) of a robot with link masses and its tool's centre.

    ``robot`` must have an ``inertial`` section (DataError otherwise: the masses are what the modes hang on)
    and, given ``arm`` (the stiffness model's robot), its kinematics; ``tool`` gives the tool's centre of
    gravity in the sensor frame and its mass (the prior of the map's tool factor)."""

    def __init__(self, robot: Robot, tool: PayloadConfig, arm: Robot | None = None):
        import pinocchio as pin

        if not robot.has_masses:
            raise DataError(f"{robot.source}: no link masses (an inertial section): the modes need the arm's "
                            "inertia; give a robot description with them (e.g. config/robots/kr125_masses.yaml)")
        if arm is not None and not same_arm(robot, arm):
            raise DataError(f"{robot.source}: its DH table or TCP is not {arm.source}'s; the masses must hang on "
                            "the arm whose stiffness is modelled")
        self.robot, self.pin = robot, pin
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.cog = np.asarray(tool.cog_mm, dtype=float) / 1000.0            # sensor frame, m
        self.tool_kg = float(tool.mass_kg)                                   # the prior of the map's tool factor
        self.tcp = self.model.getFrameId("TCP")
        self.sensor = self.model.getFrameId("sensor")

    def at(self, q_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(Lambda_arm, Lambda_1), each (3, 3) kg, at the joints ``q_deg`` (6,). The tool is a point mass:
        its share of M is J_c^T J_c, J_c its centre's translational Jacobian (J_v - [r]x J_w about the TCP)."""
        pin, model, data = self.pin, self.model, self.data
        q = np.radians(np.asarray(q_deg, dtype=float))
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        pin.computeJointJacobians(model, data, q)
        pin.updateFramePlacements(model, data)
        J6 = pin.getFrameJacobian(model, data, self.tcp, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:, :ARM_JOINTS]
        r = data.oMf[self.sensor].act(self.cog) - data.oMf[self.tcp].translation
        Jc = J6[:3] - np.cross(r[:, None], J6[3:], axis=0)
        if np.linalg.cond(J6[:3]) > MAX_CONDITION:
            raise DataError(f"q = {np.round(np.degrees(q), 3).tolist()} deg: joints 1-3 cannot move the TCP in "
                            "every direction there (the arm stretched or folded, or the TCP on the base's axis), "
                            "so the arm's inertia at the TCP is unbounded: no modes at a singular pose")
        Ji = np.linalg.inv(J6[:3])
        return Ji.T @ M[:ARM_JOINTS, :ARM_JOINTS] @ Ji, Ji.T @ (Jc.T @ Jc) @ Ji


def same_arm(a: Robot, b: Robot) -> bool:
    """Whether two robot descriptions have the same kinematics (DH table and TCP)."""
    return (all(np.allclose(getattr(a, k), getattr(b, k)) for k in ("a", "d", "alpha", "offset"))
            and np.allclose(a.T_flange_tcp, b.T_flange_tcp))


@dataclass(frozen=True)
class Factors:
    """The correction theta (module docstring): K -> stiffness K, Lambda -> arm Lambda_arm + tool_kg Lambda_1."""

    stiffness: float = 1.0
    arm: float = 1.0
    tool_kg: float = 0.0


class ModalMap:
    """The first modes at any pose: `predict` from physics with the `factors`, `fit` to measured poses.

    ``compliance(q_deg)`` gives the stiffness model's 3 x 3 TCP compliance (m/N, base axes) at a pose; the
    prior's tool is ``inertia``'s."""

    def __init__(self, compliance: Callable[[np.ndarray], np.ndarray], inertia: ArmInertia):
        self.compliance, self.inertia = compliance, inertia
        self.prior = Factors(tool_kg=inertia.tool_kg)
        self.factors = self.prior
        self._cache: dict[tuple, tuple] = {}

    def _parts(self, q_deg) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        key = tuple(np.round(np.asarray(q_deg, dtype=float), 6))
        if key not in self._cache:
            C = np.asarray(self.compliance(np.asarray(q_deg, dtype=float)))[:3, :3]
            if not np.isfinite(C).all() or np.linalg.cond(C) > MAX_CONDITION:
                raise DataError(f"q = {np.round(np.asarray(q_deg, dtype=float), 3).tolist()} deg: the model's "
                                "compliance at the TCP is singular there (a direction its springs cannot deflect): "
                                "no modes")
            self._cache[key] = (np.linalg.inv(C), *self.inertia.at(q_deg))
        return self._cache[key]

    def predict(self, q_deg: np.ndarray, factors: Factors | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Frequencies (N, 3) Hz, lowest first, and directions (N, 3, 3) (column k mode k's) at poses (N, 6)."""
        f = factors or self.factors
        hz, phi = [], []
        for q in np.atleast_2d(q_deg):
            K, arm, one = self._parts(q)
            h, v = modes(f.stiffness * K, f.arm * arm + f.tool_kg * one)
            hz.append(h)
            phi.append(v)
        return np.array(hz), np.array(phi)

    def fit(self, q_deg: np.ndarray, measured_hz: np.ndarray) -> Factors:
        """The factors from the modes measured at poses ``q_deg`` (N, 6): ``measured_hz`` (N, k), each row the
        pose's k lowest modes (NaN: not measured); sets and returns `factors`."""
        q = np.atleast_2d(np.asarray(q_deg, dtype=float))
        meas = np.atleast_2d(np.asarray(measured_hz, dtype=float))
        if meas.shape[0] != len(q) or not 1 <= meas.shape[1] <= 3:
            raise DataError(f"{len(q)} poses and {meas.shape[0]} rows of measured modes ({meas.shape[1]} each): "
                            "give one row of 1-3 frequencies per pose")
        seen = np.isfinite(meas)
        if not seen.any() or (meas[seen] <= 0).any():
            raise DataError("the measured modes need at least one frequency, each > 0 Hz")
        p0 = self.prior
        tool_sigma = max(TOOL_SIGMA * p0.tool_kg, MIN_TOOL_SIGMA_KG)

        def factors(x):
            return Factors(float(np.exp(x[0])), float(np.exp(x[1])), float(x[2]))

        def residuals(x):
            hz = self.predict(q, factors(x))[0][:, :meas.shape[1]]
            r = (hz[seen] / meas[seen] - 1.0) / MEASURED_SIGMA
            return np.r_[r, x[0] / PRIOR_SIGMA, x[1] / PRIOR_SIGMA, (x[2] - p0.tool_kg) / tool_sigma]

        sol = optimize.least_squares(residuals, [0.0, 0.0, p0.tool_kg], bounds=([-2, -2, 0], [2, 2, np.inf]))
        self.factors = factors(sol.x)
        return self.factors


JOINTS = tuple(f"q{i}_deg" for i in range(1, 7))
MODES = ("f1_hz", "f2_hz", "f3_hz")


def read_poses(path, measured: bool) -> tuple[np.ndarray, np.ndarray]:
    """A CSV of poses: q1_deg .. q6_deg (the joints), and, ``measured``, f1_hz and, where measured, f2_hz,
    f3_hz (the pose's lowest modes, e.g. what `stiffcomp modes` found there; empty or NaN: not measured).
    (poses (N, 6), modes (N, k); k = 0 without ``measured``); DataError naming the file, line and column."""
    import math

    from ..errors import Problems, quote
    from ..files.csv_table import read_table

    problems = Problems()
    table = read_table(path, problems, ", ".join(JOINTS + MODES[:1] if measured else JOINTS))
    need = JOINTS + (MODES[:1] if measured else ())
    missing = [c for c in need if c not in table.cols]
    if missing:
        raise DataError(f"{path}: line {table.header_line}: missing column(s) {', '.join(missing)}; the poses need "
                        f"{', '.join(need)}" + (" (f2_hz, f3_hz where measured)" if measured else ""))
    names = [*JOINTS, *([c for c in MODES if c in table.cols] if measured else [])]
    rows = []
    for line, row in table.rows:
        values = []
        for c in names:
            text = row[table.cols.index(c)].strip()
            try:
                v = float(text) if text or c in JOINTS else math.nan
            except ValueError:
                problems.add(f"{path}: line {line}: {c} = {quote(text)} is not a number")
                break
            if c in JOINTS and not math.isfinite(v) or c not in JOINTS and not (math.isnan(v) or 0 < v < 1000):
                problems.add(f"{path}: line {line}: {c} = {quote(text)} " + ("is not finite" if c in JOINTS else
                             "is not a frequency in Hz (above 0, below 1000; empty: not measured)"))
                break
            values.append(v)
        else:
            rows.append(values)
    if problems:
        raise DataError(f"{path}: {problems.count} problem(s); nothing was loaded", problems)
    if not rows:
        raise DataError(f"{path}: no pose in it")
    data = np.array(rows)
    return data[:, :6], data[:, 6:]
