"""A small campaign and context for the effect tests."""

import numpy as np
from stiffcomp_testlib import MODELS, random_dataset

from stiffness.model import StiffnessModel


def model_with(*entries, base="kr125_axial"):
    m = StiffnessModel.from_yaml(MODELS / f"{base}.yaml")
    d = m.to_dict()
    d["effects"] = d["effects"] + list(entries)
    return StiffnessModel.from_dict(d, "test", robot=m.robot)


def context(robot, n=40, seed=0):
    from stiffness.context import Context
    return Context(robot, random_dataset(robot, n, seed))


def only(tw: np.ndarray, site: int, comp: int) -> np.ndarray:
    """The twist at one site and component, after checking every other entry is zero."""
    rest = tw.copy()
    rest[:, site, comp] = 0.0
    assert np.abs(rest).max() == 0.0
    return tw[:, site, comp]
