"""Write a synthetic ATI CAN log: a milling load as the sensor would report it, for the replay source.

The shipped config/replay/demo_milling.blf is made by::

    python -m hil.demo_log config/replay/demo_milling.blf

The wrench (sensor axes) is a cut that ramps in and out: a static feed force, the tooth-pass
oscillation of a 4-flute cutter at 6000 rpm (400 Hz, which the low-pass removes), the weight of the
default payload at the default pose, a sensor bias, white noise and a few single-sample spikes.
"""

from __future__ import annotations

import argparse

import numpy as np

from service.sources.replay import write_log


def milling_wrench(t: np.ndarray, gravity_bias: np.ndarray | None = None, seed: int = 1,
                   spikes: bool = True) -> np.ndarray:
    """(N, 6) wrench in N, Nm at times ``t`` (s); ``spikes`` adds a few single-sample spikes on Fz."""
    rng = np.random.default_rng(seed)
    period = 8.0
    phase = np.mod(t, period)
    envelope = np.clip(np.minimum(phase - 1.0, period - 1.0 - phase) / 0.5, 0.0, 1.0)
    tooth = np.sin(2 * np.pi * 400.0 * t)
    w = np.zeros((len(t), 6))
    w[:, 0] = envelope * (250.0 + 120.0 * tooth)
    w[:, 1] = envelope * (-180.0 + 90.0 * tooth)
    w[:, 2] = envelope * 120.0
    w[:, 3] = envelope * (6.0 + 3.0 * tooth)
    w[:, 4] = envelope * (9.0 - 2.0 * tooth)
    w[:, 5] = envelope * 4.0
    w += rng.normal(0.0, [1.5, 1.5, 1.5, 0.05, 0.05, 0.05], size=w.shape)
    if spikes:
        w[rng.choice(len(t), size=max(1, len(t) // 4000), replace=False), 2] += 900.0
    if gravity_bias is not None:
        w += gravity_bias
    return w


def default_gravity_bias() -> np.ndarray:
    """Payload weight and bias of config/default.yaml at its initial pose, as the sensor reads them."""
    from service.config import load_config
    from stiffness.model.stiffness_model import StiffnessModel

    from .payload import TruePayload

    cfg = load_config()
    robot = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)).robot
    F = robot.frames(np.radians(cfg.plc.initial_q_deg)[None])
    R_s = robot.sensor_pose(F)[0, :3, :3]
    payload = TruePayload(cfg.gravity)
    return payload.wrench(R_s) + payload.bias


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--seconds", type=float, default=16.0)
    args = ap.parse_args(argv)
    t = np.arange(int(args.seconds * 1000)) / 1000.0
    write_log(args.out, milling_wrench(t, default_gravity_bias()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
