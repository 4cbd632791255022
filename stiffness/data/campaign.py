"""Everything about a campaign that does not depend on the model's parameters.

The model is evaluated per *reading* (one load state), then gathered to rows (one measured body).

Twist sites. A structural effect contributes small twists [x, y, z, rx, ry, rz] (m, rad) at sites:
  * spring site j (j = 0..5): in DH frame j, applied before joint j+1's rotation (Eq. 5): joint
    j+1's spring; it moves frames j+1.. and the TCP.
  * tip site m (m = 1..6, stored at index 5 + m): in DH frame m, applied right after T(m-1, m): the
    distal end of link m; it moves frame m itself and everything beyond.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from ..kinematics.robot import Robot
from ..kinematics.spatial import skew, transport_wrench
from ..units import M_TO_MM, RAD_TO_DEG
from .measurements import Dataset

N_SITES = 12


def site_frame(site: int) -> int:
    """DH frame index of a twist site."""
    return site if site < 6 else site - 5


def site_affects(site: int, chain_frame: int) -> bool:
    """Whether a twist at ``site`` moves a body on DH frame ``chain_frame`` (the TCP is on frame 6)."""
    return site < chain_frame if site < 6 else site - 5 <= chain_frame


class Context:
    """Per-reading kinematics, wrenches and the linear map from site twists to row deflections.

    Parameters
    ----------
    robot : Robot
    data : Dataset
    statics : Statics, optional
        tau_s(q) of the robot's weight and the payload (`stiffness.kinematics.statics`); None: tau_s = 0.
    """

    def __init__(self, robot: Robot, data: Dataset, statics=None):
        self.robot = robot
        self.statics = statics
        self.data = data
        first, self.row_reading = data.readings()
        self.first_row = first
        self.n_readings = len(first)
        q = np.radians(data.q_deg[first])
        self.q = q
        self.A = robot.dh_transforms(q)                      # (R, 6, 4, 4)
        self.F = robot.frames(q)                             # (R, 8, 4, 4), 7 = TCP
        self.T_sensor = robot.sensor_pose(self.F)            # (R, 4, 4)
        self.wrench_sensor = data.wrench[first].copy()       # (R, 6) N, Nm
        self.time = data.time_s[first]
        self.config_labels = data.configs
        lookup = {c: i for i, c in enumerate(self.config_labels)}
        self.config = np.array([lookup[c] for c in data.config[first]])
        self.t_rel = self._time_in_config()
        self.body = data.body                                # (N,) 0..6
        self.chain_frame = np.minimum(data.body + 1, 6)      # A_k on frame k, TCP on frame 6
        self.frame_wrench = self.wrenches_at_frames(self.wrench_sensor)
        self.cache: dict = {}                                # per-campaign values effects reuse
        self.preload_torque: np.ndarray | None = None        # (R, 6) identified part of tau_s (model.bind_preload)

    @cached_property
    def static_prior(self) -> np.ndarray:
        """(R, 6) Nm: the static joint torque of the robot's masses, its balancer and the payload, signed
        like the external joint torque W_i[rz]; zeros without ``statics``."""
        if self.statics is None:
            return np.zeros((self.n_readings, 6))
        return self.statics(self.q).prior

    @property
    def static_torque(self) -> np.ndarray:
        """tau_s (R, 6) Nm: each reading's static joint torque, `static_prior` plus the identified
        correction ``preload_torque`` the model binds for its current parameters (`stiffness.model.preload_term`)."""
        return self.static_prior if self.preload_torque is None else self.static_prior + self.preload_torque

    def _time_in_config(self) -> np.ndarray:
        t0 = np.full(len(self.config_labels), np.inf)
        np.minimum.at(t0, self.config, self.time)
        return self.time - t0[self.config]

    def wrenches_at_frames(self, wrench_sensor: np.ndarray) -> np.ndarray:
        """The sensor wrench transported to DH frames 0..6 (Eq. 4): (R, 6) -> (R, 7, 6).

        Each is the force and the moment about the frame's origin, in the frame's axes, with the
        unloaded geometry.
        """
        R = len(wrench_sensor)
        out = np.empty((R, 7, 6))
        for f in range(7):
            out[:, f] = transport_wrench(wrench_sensor, self.T_sensor, self.F[:, f])
        return out

    @cached_property
    def G(self) -> np.ndarray:
        """(N, 12, 6, 6): G[n, s]: row n's deflection [mm, deg] per unit twist [m, rad] at site s (linearised chain)."""
        N = len(self.body)
        rr = self.row_reading
        P_body = self.F[rr, np.minimum(self.body + 1, 7), :3, 3]          # TCP is frame index 7
        G = np.zeros((N, N_SITES, 6, 6))
        for s in range(N_SITES):
            mask = np.array([site_affects(s, c) for c in range(7)])[self.chain_frame]
            if not mask.any():
                continue
            Fs = self.F[rr, site_frame(s)]
            Rs, ps = Fs[:, :3, :3], Fs[:, :3, 3]
            g = np.zeros((N, 6, 6))
            g[:, :3, :3] = Rs * M_TO_MM
            g[:, :3, 3:] = -skew(P_body - ps) @ Rs * M_TO_MM
            g[:, 3:, 3:] = Rs * RAD_TO_DEG
            G[:, s] = g * mask[:, None, None]
        if self.axes is not None:      # the components are G's axis 2
            G = np.swapaxes(self.in_row_axes(np.swapaxes(G, 1, 2)), 1, 2)
        return G

    @property
    def axes(self) -> np.ndarray | None:
        """(N, 3, 3) each row's measurement axes (`Dataset.axes`), or None for base axes."""
        return self.data.axes

    def in_row_axes(self, x: np.ndarray) -> np.ndarray:
        """Deflections in base axes, (N, 6, ...) with the components on axis 1, in each row's own axes
        (`Dataset.axes`): position and rotation each turned by the row's axes; unchanged without axes."""
        A = self.axes
        if A is None:
            return x
        out = np.empty_like(x)
        out[:, :3] = np.einsum("nij,nj...->ni...", A, x[:, :3])
        out[:, 3:] = np.einsum("nij,nj...->ni...", A, x[:, 3:])
        return out

    def rows(self, per_reading: np.ndarray) -> np.ndarray:
        """Gather a per-reading array to rows."""
        return per_reading[self.row_reading]
