"""The HIL's flange accelerometer: a virtual Beckhoff EP3751 at the robot stub's force sensor, whose process data
the virtual PLC's MAIN reads as the I/O configuration would link them (docs/accelerometer.md).

What it measures is the stub's true motion at the tool: the actual TCP P(t) = FK(q(t)) + x(t), with x the
stub's deflection (its modes, its static deflection, `hil.robot_stub.RobotStub.actual`) and q(t) the joints the
drives move through (the PLC's commands, each reached by the next cycle in a straight line, as a drive's fine
interpolation does: the truth's path error holds each command, and the two differ by a cycle's lag), so the
path's own acceleration and the correction's motion are in it too. The
reference path's part, FK(q_ref) + x, is computed once for the pass on the stub's grid; the correction's part,
FK(q_cmd) - FK(q_ref), each PLC cycle from the command. The box then does what its documentation says
(Beckhoff, EP3751-0160 and EP3751-0260 documentation):

* it samples at its "Sampling rate" (CoE F800:0D): 4000, 2000, 1000, 200 or 100 Hz, through an integrated
  low-pass that cannot be disabled, whose 3 dB cut-off the rate sets (EP3751-0260, "Sampling rate (ODR)":
  1000, 500, 62.5, 100 and 100 Hz; modelled as a second-order Butterworth, an assumption: the order is not
  documented); ``auto`` takes the fastest rate whose recommended maximum EtherCAT cycle (0.25, 0.5, 1, 5, 10
  ms) the PLC's period keeps, as the box's own "Auto" adapts it to the cycle (4000 Hz is not offered: it is
  finer than the stub's 0.5 ms grid);
* it reads the specific force along its axes, f = R^T (a - g), plus its bias, plus noise (``noise_mg`` RMS a
  sample: the documentation gives no figure, so the default is an assumption, a MEMS box's order of
  magnitude), as an INT16 ``Value`` in mg per LSB (the factory setting);
* at each new value its TxPDO Toggle inverts; its TxPDO State stays clear (no self test here).

``VirtualAccelerometer.sample`` is called once per PLC cycle, before MAIN's body, with the joints the servos
hold; it returns MAIN's inputs (``nAccX`` .. ``bAccStateZ``, `cell.plc.blocks.ACC_INPUTS`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field
from scipy import signal

from stiffness.files.yaml_schema import Strict

from .structure import GRID_S

G0 = 9.80665                     # m/s^2 per g: the box's mg
# the box's sampling rate (Hz) -> (its low-pass's 3 dB cut-off, Hz; the recommended maximum EtherCAT cycle, s):
# EP3751-0260 documentation, "Sampling rate (ODR)"
RATES = {4000: (1000.0, 0.00025), 2000: (500.0, 0.0005), 1000: (62.5, 0.001), 200: (100.0, 0.005),
         100: (100.0, 0.01)}


class AccelerometerConfig(Strict):
    """The scenario's ``accelerometer``: the virtual box (module docstring)."""

    enabled: bool = False
    sampling_hz: Literal["auto", 2000, 1000, 200, 100] = "auto"     # 4000 Hz is finer than the stub's grid
    noise_mg: float = Field(1.0, ge=0.0, le=1000.0)
    bias_mg: list[float] = Field(default_factory=lambda: [15.0, -10.0, 25.0], min_length=3, max_length=3)
    mount_rpy_deg: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)
    seed: int = 19


def sampling_rate(cfg: AccelerometerConfig, plc_period_s: float) -> int:
    """The box's rate: the configured one, or (``auto``) the fastest of the stub's grid whose EtherCAT cycle the
    PLC keeps."""
    if cfg.sampling_hz != "auto":
        return int(cfg.sampling_hz)
    return max(hz for hz, (_, cycle) in RATES.items()
               if hz * GRID_S <= 1.0 + 1e-9 and (cycle >= plc_period_s - 1e-9 or hz == 100))


class VirtualAccelerometer:
    """The box at the stub's force sensor for one pass.

    The box's low-pass acts before it samples, on the stub's grid (`hil.structure.GRID_S`): the reference's
    acceleration (its second derivative on the grid) is filtered once for the pass, the correction's as the
    PLC's commands come (the servos hold each, so its position is a staircase on the grid); the box takes
    their sum at its own rate.

    Parameters
    ----------
    cfg : AccelerometerConfig
    robot : the stub's robot (its forward kinematics and sensor pose)
    t : (N,) the stub's grid over the pass (uniform)
    p_ref : (N, 3) the actual TCP along the reference path on that grid (m, base)
    q_ref : callable t -> the reference joints (deg)
    g_mps2 : gravity in base axes
    plc_period_s : the PLC's (and EtherCAT's) cycle
    """

    def __init__(self, cfg: AccelerometerConfig, robot, t: np.ndarray, p_ref: np.ndarray, q_ref, g_mps2,
                 plc_period_s: float):
        from stiffness.kinematics.spatial import rpy_matrix

        self.robot, self.q_ref = robot, q_ref
        self.rate = sampling_rate(cfg, plc_period_s)
        self.t0, self.dt = float(t[0]), float(t[1] - t[0])
        self.every = max(1, round(1.0 / (self.rate * self.dt)))     # grid steps between the box's values
        self.sos = signal.butter(2, RATES[self.rate][0], fs=1.0 / self.dt, output="sos")
        acc = np.gradient(np.gradient(p_ref, self.dt, axis=0), self.dt, axis=0)        # (N, 3), m/s^2
        zi = signal.sosfilt_zi(self.sos)[:, :, None] * acc[:1][None, :, :]
        self.acc_ref = signal.sosfilt(self.sos, acc, axis=0, zi=zi)[0]
        self.zc = np.zeros((len(self.sos), 2, 3))                  # the correction's part: from rest
        self.g = np.asarray(g_mps2, dtype=float)
        self.R_mount = rpy_matrix(np.radians(cfg.mount_rpy_deg))
        self.bias = np.array(cfg.bias_mg) * 1e-3 * G0
        self.noise = cfg.noise_mg * 1e-3 * G0
        self.rng = np.random.default_rng(cfg.seed)
        self.k = 0                                   # the next grid step
        self.c: list[np.ndarray] | None = None       # the correction's TCP offset: the last two grid steps
        self.held = self.target = np.zeros(3)        # ... the one the drives left at the last cycle, and the next
        self.t_held = 0.0
        self.R = np.eye(3)
        self.toggle = False
        self.counts = [0, 0, 0]
        self.true: list[tuple[float, np.ndarray]] = []    # (t, the low-passed acceleration, base) of each value

    def sample(self, t: float, q_held_deg) -> dict:
        """The box's process data as MAIN reads them at the PLC's cycle at ``t`` (s); ``q_held_deg``: the joints
        the PLC commanded, which the drives reach by the next cycle, moving there in a straight line (their fine
        interpolation: a servo does not jump a setpoint's step)."""
        q = np.radians(np.array([np.asarray(q_held_deg, dtype=float), np.asarray(self.q_ref(t), dtype=float)]))
        F = self.robot.frames(q)
        offset = F[0, 7, :3, 3] - F[1, 7, :3, 3]                 # the correction's (and the servo's) TCP offset
        if self.c is None:
            self.c, self.held, self.target, self.t_held = [offset, offset], offset, offset, t
            self.k = max(0, int(np.ceil((t - self.t0) / self.dt - 1e-9)))
        span = max(t - self.t_held, 1e-9)
        steps, k = [], self.k
        while self.t0 + k * self.dt < t - 1e-9 and k < len(self.acc_ref):
            w = min(1.0, (self.t0 + k * self.dt - self.t_held) / span)
            steps.append(self.held + w * (self.target - self.held))
            k += 1
        if steps:
            self._steps(np.array(steps))
        self.held, self.target, self.t_held = self.target, offset, t
        self.R = self.robot.sensor_pose(F[:1])[0, :3, :3] @ self.R_mount
        return {"nAccX": self.counts[0], "nAccY": self.counts[1], "nAccZ": self.counts[2], "bAccToggle": self.toggle,
                "bAccStateX": False, "bAccStateY": False, "bAccStateZ": False}

    def _steps(self, c: np.ndarray) -> None:
        """Grid steps with the servos at TCP offsets ``c`` (n, 3), low-passed as one block (the filter's state
        carried: the same as step by step); the box takes a value every ``every`` steps."""
        path = np.vstack([self.c[0], self.c[1], c])
        a = (path[2:] - 2.0 * path[1:-1] + path[:-2]) / (self.dt * self.dt)
        self.c = [path[-2], path[-1]]
        y, self.zc = signal.sosfilt(self.sos, a, axis=0, zi=self.zc)
        for i in range(len(c)):
            if self.k % self.every == 0:
                a_lp = self.acc_ref[self.k] + y[i]
                self.true.append((self.t0 + self.k * self.dt, a_lp))
                f = self.R.T @ (a_lp - self.g) + self.bias + self.rng.normal(0.0, self.noise, 3)
                self.counts = [int(np.clip(np.rint(x / (1e-3 * G0)), -32768, 32767)) for x in f]
                self.toggle = not self.toggle
            self.k += 1


def reference_motion(scenario, truth, world) -> tuple[np.ndarray, np.ndarray]:
    """(t, p): the stub's actual TCP along the reference path over the pass, on its grid (m, base): what the box
    measures but for the correction's motion (module docstring)."""
    from .robot_stub import RobotStub

    stub = RobotStub(truth, scenario.robot, scenario.payload)
    t = np.arange(world.t_start - 2 * GRID_S, world.t_end + 4 * GRID_S, GRID_S)
    q = np.array([world.path.q_ref_deg(x) for x in t])
    return t, stub.actual(t, q, world.force, float(t[0]), float(t[-1]))[0]


def register_map_with_accelerometer(cfg, folder: Path) -> Path:
    """The register map of the service config ``cfg`` with the accelerometer's four values bound after its last
    from_plc register (no gap: the PLC writes its block whole; docs/register_map.md, "The accelerometer")."""
    from plc_link.contract import ACCELEROMETER
    from stiffness.files.yaml_schema import dump_yaml

    source = cfg.resolve(cfg.plc.register_map)
    data = cfg.register_map().extended(ACCELEROMETER)
    path = folder / f"{source.stem}_accelerometer.yaml"
    path.write_text(dump_yaml(data, sort_keys=False))
    return path
