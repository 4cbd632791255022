"""A robot from URDF: pinocchio's parser reads the joints, limits and inertials; they become a DH table.

Every robot in stiffcomp is a DH robot: the model's twist sites, the measured bodies A1..A6 and the
external joint torques are all defined in DH frames (docs/robot_format.md). A URDF is read with
``pin.buildModelFromUrdf`` and accepted when its chain *is* a DH chain:

* six revolute joints in one chain, each turning about +z of its own frame (``<axis xyz="0 0 1"/>``);
* the first joint's origin is a turn about z and a lift along z at most (Rz Tz commutes with the joint's
  own turn, so DH frame 0 is the URDF's root frame);
* each later joint's origin, and the flange frame's placement on link 6, has the DH form
  Rz(offset) Tz(d) Tx(a) Rx(alpha) (its x axis meets the previous joint's axis at a right angle).

With X_i the origin of joint i (in its parent link's frame) and X_7 the flange frame on link 6, the
chain X_1 Rz(q_1) X_2 Rz(q_2) ... X_6 Rz(q_6) X_7 equals the DH chain prod Rz(q_i) L_i with
L_1 = X_1 X_2 and L_i = X_{i+1}; DH frame i is URDF joint i's frame moved by X_{i+1}. A link's mass
and centre of mass are pinocchio's inertia of joint i (the links fixed to it merged in, as the parser
does), the centre moved into DH frame i. Rotational inertia is not kept: the statics do not need it.

`urdf_text` writes a DH robot as such a URDF (point masses); config/robots/kr125.urdf was made by it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..errors import ConfigError, quote
from ..units import M_TO_MM
from .spatial import rot_x, rot_z, trans_x, trans_z

TOLERANCE = 1e-9      # m and rad: how close a placement must be to its DH form


def _dh_from_placement(L: np.ndarray) -> tuple[dict[str, float], float]:
    """(offset, d, a, alpha) with Rz(offset) Tz(d) Tx(a) Rx(alpha) closest to L, and the misfit."""

    R, p = L[:3, :3], L[:3, 3]
    theta = np.arctan2(R[1, 0], R[0, 0])
    alpha = np.arctan2(R[2, 1], R[2, 2])
    a = p[0] * np.cos(theta) + p[1] * np.sin(theta)
    rebuilt = rot_z(theta) @ trans_z(p[2]) @ trans_x(a) @ rot_x(alpha)
    dh = {"offset_deg": float(np.degrees(theta)), "d_mm": float(p[2] * M_TO_MM),
          "a_mm": float(a * M_TO_MM), "alpha_deg": float(np.degrees(alpha))}
    return dh, float(np.abs(rebuilt - L).max())


def read_urdf(path: str | Path, flange: str, where: str) -> tuple[dict, list, list]:
    """The DH table, joint limits and link inertials of a URDF whose chain is a DH chain.

    Parameters
    ----------
    path : the URDF file
    flange : the URDF frame (a link or a fixed joint) that is DH frame 6
    where : how the caller names the reference, for error messages (``robot.yaml: urdf.file``)

    Returns
    -------
    dh : dict of a_mm, alpha_deg, d_mm, offset_deg (six each), for `stiffness.kinematics.robot.DHConfig`
    limits : six [min, max] in deg
    links : six dicts of mass_kg and com_mm (DH frame i), for `stiffness.kinematics.robot.LinkInertialConfig`
    """
    import pinocchio as pin

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"{where} = {quote(str(path))}: file not found")
    check_masses(path)
    try:
        model = pin.buildModelFromUrdf(str(path))
    except (ValueError, RuntimeError) as e:
        raise ConfigError(f"{path}: pinocchio cannot read this URDF: {e}") from e
    names = list(model.names)[1:]
    kinds = [model.joints[j].shortname() for j in range(1, model.njoints)]
    if model.njoints != 7 or model.nq != 6 or any(model.parents[j] != j - 1 for j in range(1, 7)):
        raise ConfigError(f"{path}: needs six revolute joints in one chain, has {quote(list(names))} "
                          f"of kinds {quote(list(kinds))}")
    for name, kind in zip(names, kinds):
        if kind != "JointModelRZ":
            raise ConfigError(f"{path}: joint {quote(name)} ({kind}) must be revolute about its frame's z axis "
                              "(axis xyz=\"0 0 1\"), as DH joints are")
    if not model.existFrame(flange):
        raise ConfigError(f"{path}: flange = {quote(flange)} is not a frame of the URDF (links and fixed joints: "
                          f"{quote([f.name for f in model.frames if f.parentJoint == 6])})")
    frame = model.frames[model.getFrameId(flange)]
    if frame.parentJoint != 6:
        raise ConfigError(f"{path}: flange = {quote(flange)} is not on the last joint's link")
    X = [model.jointPlacements[j].homogeneous for j in range(1, 7)] + [frame.placement.homogeneous]
    X1 = X[0]
    if np.abs(X1[2, :3] - [0, 0, 1]).max() > TOLERANCE or np.abs(X1[:2, 3]).max() > TOLERANCE:
        raise ConfigError(f"{path}: joint {quote(names[0])}: its origin may only turn about z and lift along z "
                          "(DH frame 0 is the URDF's root frame)")
    L = [X1 @ X[1]] + X[2:]
    table = {"a_mm": [], "alpha_deg": [], "d_mm": [], "offset_deg": []}
    for i, Li in enumerate(L):
        dh, misfit = _dh_from_placement(Li)
        if misfit > TOLERANCE:
            what = f"joint {quote(names[i + 1])}'s origin" if i < 5 else f"the flange frame {quote(flange)}"
            raise ConfigError(f"{path}: {what} is not a DH transform from DH frame {i} (misfit {misfit:.3g}; "
                              "its x axis must meet the previous joint's axis at a right angle)")
        for k, v in dh.items():
            table[k].append(v)
    limits = [[float(np.degrees(lo)), float(np.degrees(hi))]
              for lo, hi in zip(model.lowerPositionLimit, model.upperPositionLimit)]
    links = []
    for j in range(1, 7):
        inertia = model.inertias[j]
        com = np.linalg.solve(X[j], np.append(inertia.lever, 1.0))[:3]   # joint j's frame -> DH frame j
        links.append({"mass_kg": float(inertia.mass), "com_mm": (com * M_TO_MM).tolist()})
    return table, limits, links


def check_masses(path: Path) -> None:
    """Refuse a link whose ``<inertial>`` has no valid ``<mass value="KG"/>`` (a finite number >= 0).

    urdfdom drops such an inertial with a line on stderr only, so the link would become massless and
    every static torque distal of it wrong (an effect at the total torque placed wrongly) with exit 0.
    A link without ``<inertial>`` is massless on purpose and stays accepted. The file is read with the
    standard library's XML parser first; pinocchio's parser names any other error afterwards."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as e:
        raise ConfigError(f"{path}: not a readable URDF (XML): {e}") from e
    for link in root.iter("link"):
        inertial = link.find("inertial")
        if inertial is None:
            continue
        where = f"{path}: link {quote(link.get('name'))}: its <inertial>"
        mass = inertial.find("mass")
        if mass is None:
            raise ConfigError(f"{where} has no <mass> (write <mass value=\"KG\"/>, or remove the <inertial> "
                              "of a massless link)")
        value = mass.get("value")
        if value is None:
            raise ConfigError(f"{where} has <mass> without its value attribute (write <mass value=\"KG\"/>)")
        try:
            kg = float(value)
        except ValueError:
            kg = float("nan")
        if not (np.isfinite(kg) and kg >= 0.0):
            raise ConfigError(f"{where} has <mass value={quote(value)}>: the mass must be a finite number "
                              ">= 0 (kg)")


def urdf_text(robot) -> str:
    """The robot (a `stiffness.kinematics.robot.Robot`) as a URDF in the form `read_urdf` accepts.

    Links ``base_link``, ``link1`` .. ``link6`` and ``flange`` (DH frame 6, a fixed joint); each link's
    mass is a point mass at its centre; effort and velocity limits are 0 (stiffcomp does not use them).
    """

    L = [rot_z(o) @ trans_z(d) @ trans_x(a) @ rot_x(al) for o, d, a, al in zip(robot.offset, robot.d, robot.a, robot.alpha)]
    lines = ['<?xml version="1.0"?>',
             (f"<!-- {robot.name}: written by stiffness.kinematics.urdf.urdf_text from {Path(robot.source).name}; "
              "DH frame i is joint i's frame moved by the next joint's origin (docs/robot_format.md) -->"),
             f'<robot name="{robot.name.replace(" ", "_")}">', '  <link name="base_link"/>']
    for i in range(6):
        com = (L[i] @ np.append(robot.link_com[i], 1.0))[:3]
        origin = _origin(np.eye(4) if i == 0 else L[i - 1])
        lo, hi = np.radians(robot.limits_deg[i])
        lines += [f'  <link name="link{i + 1}">',
                  f'    <inertial><origin xyz="{_num(com)}" rpy="0 0 0"/><mass value="{_num(robot.link_mass[i])}"/>',
                  '      <inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>',
                  '  </link>',
                  f'  <joint name="joint{i + 1}" type="revolute">',
                  f'    <parent link="{"base_link" if i == 0 else f"link{i}"}"/><child link="link{i + 1}"/>',
                  f'    {origin}<axis xyz="0 0 1"/>',
                  f'    <limit lower="{_num(lo)}" upper="{_num(hi)}" effort="0" velocity="0"/>',
                  '  </joint>']
    lines += ['  <link name="flange"/>',
              '  <joint name="flange_joint" type="fixed">',
              f'    <parent link="link6"/><child link="flange"/>{_origin(L[5])}',
              '  </joint>', '</robot>', '']
    return "\n".join(lines)


def _num(v) -> str:
    """Numbers rounded to 1e-15 (m, rad, kg): round-off residue such as 1e-17 reads as 0."""
    return " ".join(repr(float(np.round(x, 15)) + 0.0) for x in np.atleast_1d(v))


def _origin(T: np.ndarray) -> str:
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")      # URDF rpy: R = Rz(y) Ry(p) Rx(r)
    return f'<origin xyz="{_num(T[:3, 3])}" rpy="{_num(rpy)}"/>'
