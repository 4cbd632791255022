"""Fixtures shared by the model-core tests: the KR 125 robot and the 36-parameter model."""

from __future__ import annotations

import pytest

from stiffness.kinematics.robot import Robot
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT


@pytest.fixture(scope="session")
def robot() -> Robot:
    return Robot.from_yaml(ROOT / "config" / "robots" / "kr125.yaml")


@pytest.fixture(scope="session")
def model6() -> StiffnessModel:
    return StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
