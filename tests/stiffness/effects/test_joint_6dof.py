"""joint_6dof: the off-axis springs added to an axial spring give the full 6-DoF spring."""

import numpy as np

from hil.testing import model_with
from testlib.common import random_dataset


def test_axial_plus_6dof_equals_the_full_spring(robot, model6):
    data = random_dataset(robot, 20, 4)
    entry = next(e for e in model6.to_dict()["effects"] if e["joint"] == 4)
    extra = {k: v for k, v in entry.items() if k not in ("rz_rad_per_Nm", "fit")}
    extra["effect"] = "joint_6dof"
    m = model_with(extra)                                      # axial model + joint 4's off-axis springs
    mine = m.copy()
    ref = model_with(base="kr125_axial")
    d = ref.to_dict()
    d["effects"] = [entry if e["joint"] == 4 else e for e in d["effects"]]
    from stiffness.model.stiffness_model import StiffnessModel
    full = StiffnessModel.from_dict(d, "full", robot=robot)
    # same axial compliances everywhere
    np.testing.assert_allclose(mine.predict(data), full.predict(data), atol=1e-12)
