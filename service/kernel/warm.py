"""Compile the cycle for the shipped models into numba's disk cache: `make install` and the container
build run it, so that no service start, test or benchmark compiles what the project ships.

    python -m service.kernel.warm        # prints each model and how long it took

The models: the springs alone, each library effect's examples alone, and every effect together, on the
KR 125 without and with its masses, and with an identified preload (each a different set of laws, or of
the static torque's paths). A model of a user's with other laws compiles at its first start (seconds)
and is cached from then on.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def models():
    """(label, model) of every shipped combination."""
    from stiffness.effects import EFFECTS
    from stiffness.kinematics.robot import load_robot
    from stiffness.model.stiffness_model import StiffnessModel

    springs = StiffnessModel.from_yaml(ROOT / "config" / "models" / "kr125_6dof.yaml")

    def model_with(*entries):
        d = springs.to_dict()
        d["effects"] = d["effects"] + list(entries)
        return StiffnessModel.from_dict(d, " + ".join(["springs", *(e["effect"] for e in entries)]), robot=springs.robot)

    examples = [entry for cls in EFFECTS.values() for entry in cls.examples]
    yield "springs only", springs
    for e in examples:
        yield f"+ {e['effect']}", model_with(e)
    every = model_with(*examples)
    yield "every effect", every
    yield "every effect, masses", StiffnessModel.from_dict(
        every.to_dict(), "every effect, masses", robot=load_robot(ROOT / "config" / "robots" / "kr125_masses.yaml"))


def main() -> int:
    import logging

    from service.config import load_config
    from service.pipeline import Cycle

    logging.disable(logging.WARNING)         # the example models' drift line, once per model
    cfg = load_config(ROOT / "config" / "default.yaml")
    t_all = time.perf_counter()
    for label, model in models():
        t0 = time.perf_counter()
        Cycle.from_config(cfg, model).compensator.compile()
        print(f"compiled cycle: {label}: {time.perf_counter() - t0:.1f} s", flush=True)
    print(f"compiled cycle cache ready in {time.perf_counter() - t_all:.0f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
