"""The static joint torque tau_s(q): the arm's own weight, the payload's weight and the balancer.

tau_s is written exactly like the external joint torque the model already uses (Eq. 4 and
`stiffness.effects.axial.joint_torque`): tau_i = W_i[rz], the moment about joint i's axis (z of DH
frame i-1) of the external loads on the links distal of joint i. Gravity on those links is such an
external load, so

    tau_s = tau_arm + tau_payload + tau_balancer,

    tau_arm     = -g(q)                      pinocchio's generalized gravity g (the torque the motors hold),
    tau_payload = J_c(q)^T (m_p g_vec)       the payload's weight at its centre c (sensor frame),
                                             the same as its wrench [m_p R_s^T g_vec; c x F] at the sensor
                                             transported to each joint (Eq. 4),
    tau_balancer_j = -share * tau_arm_j      at the balancer's joint j, zero elsewhere,

with g_vec the gravity vector in base axes (default (0, 0, -9.81) m/s^2) and J_c the Jacobian of the
payload's centre. All in Nm. A robot without masses gives tau_arm = tau_balancer = 0; with no payload,
tau_s = 0. The balancer carries a share of the arm's weight only: a spring set for the arm knows
nothing of the tool.

Backlash, nonlinear stiffness and hysteresis act at the joint's total torque tau_s + tau_ext
(docs/effects.md, "Static torque"): offline tau_s comes from the model's robot (masses, balancer) and
the model's ``payload`` (`PayloadConfig`, what the sensor carried while the campaign was measured); in
the service from the robot and the ``gravity`` section's payload, recomputed when the joints move.
"""

from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np
from pydantic import Field

from ..errors import quote
from ..files.yaml_schema import Strict
from .robot import Robot

PARTS = ("m", "mx", "my", "mz")          # pinocchio's dynamic parameters 0..3 of each link
N_COLUMNS = 6 * len(PARTS)
G_STANDARD = (0.0, 0.0, -9.81)   # m/s^2, base axes: a floor-mounted robot


class PayloadConfig(Strict):
    """A model's ``payload``: what the sensor carried while the campaign was measured (spindle, holder,
    tool), its mass and its centre of gravity in the sensor frame."""

    mass_kg: float = Field(0.0, ge=0.0, le=1e4)
    cog_mm: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)


class StaticTorques(NamedTuple):
    """Static joint torques per reading, each (N, 6) in Nm, signed like the external joint torque;
    ``identified`` is the correction the fit identified (`stiffness.model.preload_term`), zero without one."""

    arm: np.ndarray
    payload: np.ndarray
    balancer: np.ndarray
    identified: np.ndarray | float = 0.0

    @property
    def prior(self) -> np.ndarray:
        """arm + payload + balancer, (N, 6) Nm: what the masses give."""
        return self.arm + self.payload + self.balancer

    @property
    def total(self) -> np.ndarray:
        """tau_s = arm + payload + balancer + identified, (N, 6) Nm."""
        return self.prior + self.identified


class Statics:
    """tau_s(q) for one robot, payload and gravity direction.

    Parameters
    ----------
    robot : Robot
        With or without link masses and a balancer.
    payload_kg : float
        Mass carried at the sensor (spindle, tool, fixture), kg, >= 0.
    payload_cog_mm : (3,)
        Its centre of gravity in the sensor frame, mm.
    g_mps2 : (3,)
        Gravity in base axes, m/s^2.
    preloads : list of (joint, columns, beta)
        The identified corrections (`stiffness.model.preload_term`): joint j's static torque gains
        ``static_regressor(q)[j - 1, columns] @ beta``.

    Holds its own pinocchio model (a copy of ``robot.pin_model`` with this gravity and a frame at the
    payload's centre) and data, so calls are independent of anyone else's use of the robot's model.
    """

    def __init__(self, robot: Robot, payload_kg: float = 0.0, payload_cog_mm=(0.0, 0.0, 0.0),
                 g_mps2=G_STANDARD, preloads=()):
        import pinocchio as pin

        self.payload_kg = float(payload_kg)
        cog = np.asarray(payload_cog_mm, dtype=float)
        g = np.asarray(g_mps2, dtype=float)
        if not (np.isfinite(self.payload_kg) and self.payload_kg >= 0):
            raise ValueError(f"payload mass = {quote(payload_kg)} kg must be a finite number >= 0")
        if cog.shape != (3,) or not np.isfinite(cog).all():
            raise ValueError(f"payload centre of gravity = {quote(payload_cog_mm)} mm must be three finite numbers")
        if g.shape != (3,) or not np.isfinite(g).all():
            raise ValueError(f"gravity = {quote(g_mps2)} m/s^2 must be three finite numbers")
        self.g = g
        self.arm_loaded = robot.has_masses
        self.balancer = robot.balancer
        self._balancer_gain = np.zeros(6)           # tau_balancer = gain * tau_arm: -share at its joint
        if robot.balancer is not None:
            self._balancer_gain[robot.balancer.joint - 1] = -robot.balancer.share
        self._with_balancer = 1.0 + self._balancer_gain
        self.pm = pin.Model(robot.pin_model)
        self.pm.gravity = pin.Motion(np.concatenate([g, np.zeros(3)]))
        sensor = self.pm.frames[self.pm.getFrameId("sensor")]
        self._at_sensor = pin.SE3(sensor.placement)      # a copy: addFrame below moves the frames
        at_cog = sensor.placement * pin.SE3(np.eye(3), cog / 1000.0)
        self.cog_id = self.pm.addFrame(pin.Frame("payload_cog", sensor.parentJoint, at_cog, pin.FrameType.OP_FRAME))
        self.pd = self.pm.createData()
        self._weight = self.payload_kg * g
        self._pin = pin
        self.preloads = [(int(j), np.asarray(c, dtype=int), np.asarray(b, dtype=float)) for j, c, b in preloads]
        # each preload as weights on pinocchio's 10 dynamic parameters per link: its torque is one row of
        # the regressor times them (one regressor pass and one small product per call)
        self._pre_rows = np.array([j - 1 for j, _, _ in self.preloads], dtype=int)
        self._pre_w = np.zeros((len(self.preloads), 6 * 10))
        for n, (_, cols, beta) in enumerate(self.preloads):
            self._pre_w[n, _pin_index(cols)] = -beta          # minus: the arm's torque is -Y pi
        self._zero_v = np.zeros(self.pm.nv)
        self._g = g.tolist()
        self._offset = pin.SE3.Identity()         # sensor -> centre of gravity (`carry`)
        self._frames = self.pm.frames

    def carry(self, payload_kg: float, mc_kgm) -> None:
        """Change the payload in place: mass m (kg, >= 0) and m c (kg m, sensor frame), for the next call.

        No new pinocchio model (a service blending two payloads does this every cycle of the ramp): the
        weight and the frame at the centre move. tau_payload is linear in m and m c (it is the weight's
        wrench at the sensor carried to the joints, [m R_s^T g; (m c) x R_s^T g]), so carrying a blend of
        two payloads gives the blend of their torques."""
        m = self.payload_kg = float(payload_kg)
        gx, gy, gz = self._g
        self._weight = np.array([m * gx, m * gy, m * gz])
        if m > 0:
            cx, cy, cz = mc_kgm
            self._offset.translation = np.array([cx / m, cy / m, cz / m])
            self._frames[self.cog_id].placement = self._at_sensor * self._offset

    def __call__(self, q_rad: np.ndarray) -> StaticTorques:
        """The static torques at joint angles ``q_rad`` ((N, 6) or (6,), rad): each part (N, 6) Nm."""
        q = np.atleast_2d(np.asarray(q_rad, dtype=float))
        arm, payload = np.zeros((len(q), 6)), np.zeros((len(q), 6))
        identified = np.zeros((len(q), 6))
        for k in range(len(q)):
            arm[k], payload[k] = self._parts(q[k])
            identified[k] = self._identified(q[k])
        return StaticTorques(arm, payload, arm * self._balancer_gain, identified)

    def total_at(self, q_rad: np.ndarray) -> np.ndarray:
        """tau_s (6,) Nm at one configuration (6,) rad: the call to make when the joints move."""
        arm, payload = self._parts(q_rad)
        out = arm * self._with_balancer + payload
        return out + self._identified(q_rad) if self.preloads else out

    def regressor_rows(self, q_rad: np.ndarray, joint: int) -> np.ndarray:
        """(N, 24) row ``joint`` of the arm's static regressor (`static_regressor`) at
        each configuration of ``q_rad`` (N, 6)."""
        q = np.atleast_2d(np.asarray(q_rad, dtype=float))
        return np.array([static_regressor(self.pm, self.pd, qk)[joint - 1] for qk in q])

    def _identified(self, q: np.ndarray) -> np.ndarray:
        out = np.zeros(6)
        if self.preloads:
            z = self._zero_v
            Y = self._pin.computeJointTorqueRegressor(self.pm, self.pd, np.asarray(q, dtype=float), z, z)
            out[self._pre_rows] = (Y[self._pre_rows] * self._pre_w).sum(1)     # one preload per joint
        return out

    def _parts(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(arm, payload) torques (6,) at one configuration."""
        pin, pm, pd = self._pin, self.pm, self.pd
        arm = -pin.computeGeneralizedGravity(pm, pd, q) if self.arm_loaded else _ZERO
        if self.payload_kg > 0:
            payload = pin.computeFrameJacobian(pm, pd, q, self.cog_id, pin.LOCAL_WORLD_ALIGNED)[:3].T @ self._weight
        else:
            payload = _ZERO
        return arm, payload


_ZERO = np.zeros(6)
_ZERO.flags.writeable = False


def models_static_load(robot: Robot, preloads=()) -> bool:
    """Whether a model on ``robot`` with the identified ``preloads`` has a static torque at all: a robot
    without masses and without an identified preload models none, its payload's included (`statics_for`)."""
    return bool(robot.has_masses or len(preloads))


def statics_for(robot: Robot, payload: PayloadConfig | None = None, g_mps2=G_STANDARD,
                preloads=()) -> Statics | None:
    """The `Statics` of ``robot`` carrying ``payload``, with the model's identified ``preloads``
    ((joint, columns, beta), `stiffness.model.preload_term`), for the effects at the total torque.

    None (tau_s = 0, every effect at the external torque as before robots had masses) for a robot
    without masses and without an identified preload: a robot description without an ``inertial``
    section models no static load, its payload's included, so a model and a service on the same robot
    always agree on tau_s. With an identified preload the payload counts (the identified part is the
    arm's, fitted with the campaign's payload known).
    """
    if not models_static_load(robot, preloads):
        return None
    kg = payload.mass_kg if payload is not None else 0.0
    return Statics(robot, kg, payload.cog_mm if payload is not None else (0.0, 0.0, 0.0), g_mps2, preloads)


def static_regressor(pm, pd, q: np.ndarray) -> np.ndarray:
    """(6, 24): the arm's static torque (signed like the external joint torque) per unit of each link's
    m, m c_x, m c_y, m c_z, at configuration ``q`` (rad), for the gravity of ``pm``."""
    import pinocchio as pin

    zero = np.zeros(pm.nv)
    Y = pin.computeJointTorqueRegressor(pm, pd, np.asarray(q, dtype=float), zero, zero)
    return -Y.reshape(6, 6, 10)[:, :, :4].reshape(6, N_COLUMNS)


def _pin_index(columns) -> np.ndarray:
    """The index in pinocchio's (6 * 10) dynamic parameters of each `static_regressor` column."""
    link, part = np.divmod(np.asarray(columns, dtype=int), len(PARTS))
    return link * 10 + part


def column_key(k: int) -> str:
    link, part = divmod(k, len(PARTS))
    return f"{PARTS[part]}{link + 1}_{'kg' if part == 0 else 'kgm'}"


@lru_cache(maxsize=32)
def _base_columns(robot_id: int, joint: int, pm) -> tuple[int, ...]:
    rng = np.random.default_rng(0)
    lo = np.asarray(pm.lowerPositionLimit)
    hi = np.asarray(pm.upperPositionLimit)
    pd = pm.createData()
    Y = np.array([static_regressor(pm, pd, rng.uniform(lo, hi))[joint - 1] for _ in range(120)])
    return independent_columns(Y)


def independent_columns(Y: np.ndarray, tol: float = 1e-6) -> tuple[int, ...]:
    """The columns of ``Y`` taken in their order, each kept when it adds a direction the kept ones do not
    span (its part outside their span above ``tol``, in Y's units: Nm per kg or kg m, so a vertical joint
    1 keeps none). Among columns that depend on each other the first in key order is kept, whatever the
    linear algebra library's rounding: the keys a model file holds stay valid from one numpy to the next
    (QR with pivoting chose between equal columns by rounding).

    >>> independent_columns(np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 1.0]]))
    (0, 2)
    """
    basis = np.zeros((Y.shape[0], 0))
    kept = []
    for k in range(Y.shape[1]):
        r = Y[:, k] - basis @ (basis.T @ Y[:, k])
        r = r - basis @ (basis.T @ r)               # twice: Gram-Schmidt keeps the basis orthogonal
        norm = float(np.linalg.norm(r))
        if norm > tol:
            basis = np.column_stack([basis, r / norm])
            kept.append(k)
    return tuple(kept)


def base_columns(robot, joint: int) -> tuple[int, ...]:
    """The columns of the static regressor's row ``joint`` that the configurations tell apart."""
    return _base_columns(id(robot.pin_model), joint, robot.pin_model)
