"""A small campaign and context for the effect tests."""

import numpy as np

from testlib.common import random_dataset


def context(robot, n=40, seed=0):
    from stiffness.data.campaign import Context
    return Context(robot, random_dataset(robot, n, seed))


def only(tw: np.ndarray, site: int, comp: int) -> np.ndarray:
    """The twist at one site and component, after checking every other entry is zero."""
    rest = tw.copy()
    rest[:, site, comp] = 0.0
    assert np.abs(rest).max() == 0.0
    return tw[:, site, comp]
