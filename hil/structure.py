"""The arm's dynamics in the robot stub: how the deflection follows the load in time (docs/hil.md).

Two structures, the scenario's ``robot.model``:

``modal`` (the default): the arm rings. The load reaches the joints through a critically damped low-pass
at ``residual_hz`` (the arm does not follow the 400 Hz tooth passing), the truth model turns it into the
static deflection x_s(t), and each mode k (frequency f_k, damping zeta_k, unit direction phi_k) carries its
share of it as a second-order oscillator of unit static gain:

    a_k'' + 2 zeta_k w_k a_k' + w_k^2 a_k = w_k^2 (phi_k . x_s),       w_k = 2 pi f_k(q)
    x = sum_k phi_k a_k + (I - sum_k phi_k phi_k^T) x_s

The directions are in the arm's frame (x away from the base's axis, y across it, z up: the base turned by
q1), so a mode turns with the arm. Its frequency moves across the workspace with the reach r (the TCP's
distance from the base's axis): f_k(q) = f_k (r_ref / r)^exponent; a farther TCP hangs on a softer, heavier
arm. Defaults: 10 Hz and 16 Hz at 3 % damping (published modal maps of milling robots: first modes at
about 7, 10 and 16 Hz, 2-4 % damping, moving by up to 40 % over the workspace; docs/hil.md cites them).

``frequencies: physics`` computes the modes instead from the truth's own stiffness and inertia, as the
modal map predicts them (`stiffness.dynamics.modal_map`): the truth model's compliance at the TCP, the link
masses of the robot description ``masses`` (its ``inertial`` section; the same kinematics as the truth's)
and the tool the scenario's ``payload`` carries. Mode k is then the k-th lowest, its direction phi_k and
frequency the pose's (both moving along the path), its damping ``modes[k].damping`` (their ``hz`` and
``direction`` unused); its share is psi_k . x_s with psi_k the dual of the directions (they are orthogonal
in the arm's inertia, not in space), the modes left out static.

``lowpass``: the arm's first mode as a critically damped second-order low-pass at ``structure_hz`` on the
load (the stub before the modes; 0: static).

Both act on a uniform time grid (`GRID_S`); the servos hold the commanded joints between PLC cycles.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field, field_validator
from scipy import signal

from stiffness.dynamics.modal_map import ArmInertia, ModalMap
from stiffness.dynamics.structure import ModeConfig, orthogonal
from stiffness.errors import ConfigError, DataError
from stiffness.files.yaml_schema import Strict
from stiffness.kinematics.robot import load_robot
from stiffness.kinematics.statics import PayloadConfig
from stiffness.model.cartesian import tcp_compliance
from stiffness.model.stiffness_model import StiffnessModel

GRID_S = 5e-4            # the structure's time step
PHYSICS_EVERY_S = 0.02   # physics: `respond` computes the modes at poses this far apart, linear in between


def _default_modes() -> list[ModeConfig]:
    return [ModeConfig(hz=10.0, damping=0.03, direction=[1.0, 0.0, 0.0]),
            ModeConfig(hz=16.0, damping=0.03, direction=[0.0, 1.0, 0.0])]


class StructureConfig(Strict):
    """``robot``: the robot stub's structure (module docstring)."""

    model: Literal["modal", "lowpass"] = "modal"
    structure_hz: float = Field(20.0, ge=0.0, le=1000.0)
    modes: list[ModeConfig] = Field(default_factory=_default_modes)
    residual_hz: float = Field(40.0, gt=0.0, le=1000.0)
    reach_ref_m: float = Field(1.8, gt=0.1, le=10.0)
    reach_exponent: float = Field(1.0, ge=0.0, le=4.0)
    frequencies: Literal["reach", "physics"] = "reach"
    masses: str | None = None                      # physics: a robot description with the link masses

    _orthogonal = field_validator("modes")(classmethod(lambda cls, v: orthogonal(v)))


def physical_modes(cfg: StructureConfig, truth: StiffnessModel, tool: PayloadConfig) -> ModalMap:
    """The modal map of the truth's own stiffness, the masses of ``cfg.masses`` and the ``tool`` it carries
    (``frequencies: physics``); ConfigError for a description without masses or with other kinematics."""
    if len(cfg.modes) > 3:
        raise ConfigError(f"robot.modes: {len(cfg.modes)} modes with frequencies: physics, which gives the TCP's "
                          "three (translation): give at most 3")
    if cfg.masses is None:
        raise ConfigError("robot.frequencies: physics needs robot.masses: a robot description with the link "
                          "masses (an inertial section), e.g. config/robots/kr125_masses.yaml")
    try:
        inertia = ArmInertia(load_robot(cfg.masses), tool, arm=truth.robot)
    except DataError as e:
        raise ConfigError(f"robot.masses: {e}") from e
    return ModalMap(lambda q: tcp_compliance(truth, q), inertia)


class Structure:
    """The structure of one robot stub: `load` filters the process force, `respond` the static deflection.
    ``physics``: the modal map the modes come from with ``frequencies: physics`` (`physical_modes`)."""

    def __init__(self, cfg: StructureConfig | float, physics: ModalMap | None = None):
        if not isinstance(cfg, StructureConfig):          # a number: the critically damped low-pass at that frequency
            cfg = StructureConfig(model="lowpass", structure_hz=float(cfg))
        self.cfg = cfg
        self.modal = cfg.model == "modal"
        self.directions = np.array([m.direction for m in cfg.modes]).reshape(-1, 3) if self.modal else np.zeros((0, 3))
        if self.modal and cfg.frequencies == "physics" and physics is None:
            raise ConfigError("robot.frequencies: physics: the structure needs the truth's modal map")
        self.physics = physics if self.modal and cfg.frequencies == "physics" else None

    @property
    def load_hz(self) -> float:
        return self.cfg.residual_hz if self.modal else self.cfg.structure_hz

    def load(self, t: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The force (N, 3) the joints feel at uniformly spaced times ``t`` for the process force."""
        hz = self.load_hz
        if hz <= 0 or len(t) < 2:
            return np.asarray(force, dtype=float)
        w = 2 * np.pi * hz
        b, a = signal.bilinear([w * w], [1.0, 2 * w, w * w], 1.0 / float(t[1] - t[0]))    # critically damped
        return signal.lfilter(b, a, force, axis=0)

    def frequencies(self, q_deg: np.ndarray, tcp: np.ndarray) -> np.ndarray:
        """(N, K) the modes' frequencies (Hz) at the poses ``q_deg`` (N, 6) with TCP positions ``tcp`` (N, 3)."""
        return self.shapes(q_deg, tcp)[0]

    def shapes(self, q_deg: np.ndarray, tcp: np.ndarray, every: int = 1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The modes at each pose: frequencies (N, K) Hz, directions phi (N, K, 3) and their duals psi (N, K,
        3), base axes (module docstring); physics: computed at every ``every``-th pose, linear in between."""
        q_deg = np.atleast_2d(q_deg)
        if self.physics is not None:
            return self._physics(q_deg, every)
        reach = np.maximum(np.hypot(tcp[:, 0], tcp[:, 1]), 0.05)
        scale = (self.cfg.reach_ref_m / reach) ** self.cfg.reach_exponent
        c, s = np.cos(np.radians(q_deg[:, 0])), np.sin(np.radians(q_deg[:, 0]))
        arm = np.stack([np.stack([c, -s, np.zeros_like(c)], 1), np.stack([s, c, np.zeros_like(c)], 1),
                        np.tile([0.0, 0.0, 1.0], (len(c), 1))], axis=1)          # base <- the arm's frame
        phi = np.einsum("nij,kj->nki", arm, self.directions)                       # (N, K, 3) in base axes
        return scale[:, None] * np.array([m.hz for m in self.cfg.modes])[None, :], phi, phi

    def _physics(self, q_deg: np.ndarray, every: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """`shapes` from the modal map, each mode's sign kept from one computed pose to the next."""
        n, k = len(q_deg), len(self.cfg.modes)
        at = np.unique(np.r_[np.arange(0, n, max(every, 1)), n - 1])
        hz, V = self.physics.predict(q_deg[at])
        W = np.linalg.inv(V)                                     # rows: the duals (x = V a, a = V^-1 x)
        phi, psi = np.swapaxes(V, 1, 2)[:, :k], W[:, :k]
        for i in range(1, len(at)):
            flip = np.where(np.einsum("kj,kj->k", phi[i], phi[i - 1]) < 0, -1.0, 1.0)[:, None]
            phi[i], psi[i] = phi[i] * flip, psi[i] * flip
        idx = np.arange(n)

        def along(v):
            flat = v.reshape(len(at), -1)
            return np.stack([np.interp(idx, at, flat[:, j]) for j in range(flat.shape[1])], 1).reshape((n, *v.shape[1:]))

        return along(hz[:, :k]), along(phi), along(psi)

    def respond(self, t: np.ndarray, q_deg: np.ndarray, tcp: np.ndarray, x_static: np.ndarray) -> np.ndarray:
        """The dynamic deflection (N, 3) at uniformly spaced times ``t`` for the static one ``x_static`` (N, 3,
        base axes), the joints ``q_deg`` and TCP positions ``tcp`` (for the modes' directions and frequencies)."""
        if not self.modal or not len(self.cfg.modes) or len(t) < 2:
            return np.asarray(x_static, dtype=float)
        dt = float(t[1] - t[0])
        f, phi, psi = self.shapes(q_deg, tcp, every=max(round(PHYSICS_EVERY_S / dt), 1))
        share = np.einsum("nki,ni->nk", psi, x_static)                              # psi_k . x_s
        zeta = np.array([m.damping for m in self.cfg.modes])
        moved = oscillate(share, 2 * np.pi * f, zeta, dt)
        return x_static + np.einsum("nki,nk->ni", phi, moved - share)


def oscillate(u: np.ndarray, w: np.ndarray, zeta: np.ndarray, dt: float) -> np.ndarray:
    """a (N, K) of a'' + 2 zeta w a' + w^2 a = w^2 u, each column its own oscillator, w (N, K) rad/s varying
    slowly; starting at rest at u[0]. The trapezoidal rule (stable, no numerical damping) with the frequency
    prewarped at each step."""
    n, k = u.shape
    a = np.empty_like(u)
    x, v = u[0].astype(float).copy(), np.zeros(k)
    h = dt / 2.0
    u_prev = u[0]
    for i in range(n):
        wi = 2.0 / dt * np.tan(w[i] * h)                        # prewarped: the discrete resonance where it belongs
        w2, c = wi * wi, 2.0 * zeta * wi
        # [x1, v1] = [x, v] + h ([v, f(x, v, u0)] + [v1, f(x1, v1, u1)]), f(x, v, u) = w2 (u - x) - c v
        ui = u[i]
        f0 = w2 * (u_prev - x) - c * v
        rhs_x = x + h * v
        rhs_v = v + h * f0 + h * w2 * ui
        u_prev = ui
        # x1 = rhs_x + h v1;  v1 (1 + h c) + h w2 x1 = rhs_v  ->  v1 (1 + h c + h^2 w2) = rhs_v - h w2 rhs_x
        v = (rhs_v - h * w2 * rhs_x) / (1.0 + h * c + h * h * w2)
        x = rhs_x + h * v
        a[i] = x
    return a
