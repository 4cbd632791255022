"""A model whose robot is read from URDF predicts and compensates exactly like the same model on the DH YAML."""

import numpy as np
import yaml

from service.compensation import FastPredictor
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT, random_dataset


def model_on(robot_file: str) -> StiffnessModel:
    data = yaml.safe_load((MODELS / "kr125_6dof.yaml").read_text())
    data["robot"] = str(ROOT / "config" / "robots" / robot_file)
    return StiffnessModel.from_dict(data, "kr125_6dof")


def test_urdf_robot_model_and_fast_path_equal_the_dh_robot():
    dh, urdf = model_on("kr125_masses.yaml"), model_on("kr125_urdf.yaml")
    data = random_dataset(dh.robot, 12, seed=7)
    np.testing.assert_allclose(urdf.predict(data), dh.predict(data), rtol=0, atol=1e-9)   # mm, deg
    fa, fb = FastPredictor(dh), FastPredictor(urdf)
    rng = np.random.default_rng(8)
    for q, w in zip(np.radians(data.q_deg[::7]), rng.normal(size=(12, 6)) * 300):
        fa.kinematics(q)
        fb.kinematics(q)
        np.testing.assert_allclose(fb.deflection(fb.wrench_base(w.tolist())),
                                   fa.deflection(fa.wrench_base(w.tolist())), rtol=0, atol=1e-12)   # m, rad
        np.testing.assert_allclose(fb.J, fa.J, rtol=0, atol=1e-9)
