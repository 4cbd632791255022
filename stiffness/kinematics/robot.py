"""The robot: a standard DH table, joint limits, the F/T sensor frame, the TCP and (optionally) the
links' masses and a gravity balancer, read from YAML.

Kinematics are built with pinocchio from the DH table (`Robot.pin_model`). For whole measurement
campaigns the same chain is evaluated batched in NumPy (`Robot.frames`), and the tests check the two
agree. A robot YAML may instead name a URDF (``urdf: {file: ...}``); `stiffness.kinematics.urdf` reads its
joints, limits and inertials with pinocchio's parser and turns them into the same DH table, so every
robot is a DH robot from here on (docs/model_format.md, "Robot").

Frames: 0 is the base, i = 1..6 the DH frames after joint i, 6 the flange. DH convention:
    T(i-1, i) = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i),   theta_i = q_i + offset_i
"""

from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import Field, field_validator

from ..errors import ConfigError, quote
from ..files.yaml_schema import Strict, deep_update, items_numbered, read_yaml, validate
from .spatial import rot_x, rot_z, rpy_matrix, trans_x, trans_z, transform

N_JOINTS = 6
BODIES = ("A1", "A2", "A3", "A4", "A5", "A6", "TCP")



def _six(v: list[float]) -> list[float]:
    if len(v) != N_JOINTS:
        raise ValueError(f"needs {N_JOINTS} values, one per joint (got {len(v)})")
    return v


class DHConfig(Strict):
    a_mm: list[float] = Field(json_schema_extra=items_numbered("joint"))
    alpha_deg: list[float] = Field(json_schema_extra=items_numbered("joint"))
    d_mm: list[float] = Field(json_schema_extra=items_numbered("joint"))
    offset_deg: list[float] = Field(default_factory=lambda: [0.0] * N_JOINTS, json_schema_extra=items_numbered("joint"))

    _check = field_validator("a_mm", "alpha_deg", "d_mm", "offset_deg")(_six)


class PoseConfig(Strict):
    xyz_mm: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)
    rpy_deg: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)

    def matrix(self) -> np.ndarray:
        return transform(rpy_matrix(np.radians(self.rpy_deg)), np.array(self.xyz_mm) / 1000.0)

    def flow_text(self) -> str:
        """The pose as a YAML flow mapping (a data file's ``# key: value`` header): the position to 0.1 um,
        the angles to 10 digits (six, 100.0625 deg written as 100.062, turned a point 60 mm away by 0.5 um)."""
        return (f"{{xyz_mm: [{', '.join(f'{v:.4f}' for v in self.xyz_mm)}], "
                f"rpy_deg: [{', '.join(f'{v:.10g}' for v in self.rpy_deg)}]}}")


class SensorConfig(PoseConfig):
    frame: int = Field(6, ge=0, le=6, description="DH frame the sensor is mounted on")


class LinkInertialConfig(Strict):
    """One link's mass and centre of mass, in its DH frame (link i is the body between joints i and i+1)."""
    mass_kg: float = Field(ge=0.0, le=1e5)
    com_mm: list[Annotated[float, Field(ge=-1e4, le=1e4)]] = Field(min_length=3, max_length=3)


class BalancerConfig(Strict):
    """A gravity balancer on ``joint`` that carries ``share`` of the arm's static torque there."""
    joint: int = Field(ge=1, le=N_JOINTS)
    share: float = Field(ge=0.0, le=1.0)


class InertialConfig(Strict):
    links: list[LinkInertialConfig] | None = Field(
        None, description="DH frames 1..6; required with dh, forbidden with urdf (the URDF has them)",
        json_schema_extra=items_numbered("link"))
    balancer: BalancerConfig | None = None

    @field_validator("links")
    @classmethod
    def _six_links(cls, v):
        return v if v is None else _six(v)


class UrdfConfig(Strict):
    file: str = Field(description="the URDF, relative to the robot YAML")
    flange: str = Field("flange", description="the URDF frame (link or fixed joint) that is DH frame 6")


class RobotConfig(Strict):
    name: str = "robot"
    dh: DHConfig | None = None
    urdf: UrdfConfig | None = None
    joint_limits_deg: list[tuple[float, float]] | None = Field(None, json_schema_extra=items_numbered("joint"))
    sensor: SensorConfig = Field(default_factory=SensorConfig)
    tcp: PoseConfig = Field(default_factory=lambda: PoseConfig(xyz_mm=[0.0, 0.0, 250.0]))
    inertial: InertialConfig | None = None

    def check_sources(self, source: str) -> None:
        """The DH table or a URDF, each with what it needs and nothing it brings itself."""
        has_links = self.inertial is not None and self.inertial.links is not None
        problem = None
        if (self.dh is None) == (self.urdf is None):
            problem = "give either dh (with joint_limits_deg) or urdf (with its file), not both and not neither"
        elif self.dh is not None and self.joint_limits_deg is None:
            problem = "joint_limits_deg is missing (a dh robot needs them)"
        elif self.urdf is not None and self.joint_limits_deg is not None:
            problem = "joint_limits_deg is not allowed with urdf (the URDF gives the limits)"
        elif self.urdf is not None and has_links:
            problem = "inertial.links is not allowed with urdf (the URDF gives the masses)"
        elif self.dh is not None and self.inertial is not None and not has_links:
            problem = "inertial.links is missing (six entries, DH frames 1..6)"
        if problem:
            raise ConfigError(f"{source}: {problem}")

    @field_validator("joint_limits_deg")
    @classmethod
    def _limits(cls, v: list[tuple[float, float]] | None) -> list[tuple[float, float]] | None:
        if v is None:
            return v
        _six(v)
        for i, (lo, hi) in enumerate(v):
            if not lo < hi:
                raise ValueError(f"joint {i + 1}: min {lo} must be below max {hi}")
        return v


class Robot:
    """A 6R serial robot from a DH table, with its sensor frame, TCP and optional link masses.

    Parameters
    ----------
    config : RobotConfig
        The validated robot description with its DH table (`from_yaml` turns a URDF into one).
    source : str
        Where the config came from, for error messages.
    """

    def __init__(self, config: RobotConfig, source: str = "<robot>"):
        if config.dh is None:
            raise ConfigError(f"{source}: no dh table (a urdf robot is read with Robot.from_yaml)")
        self.config = config
        self.source = source
        self.name = config.name
        self.a = np.array(config.dh.a_mm) / 1000.0
        self.alpha = np.radians(config.dh.alpha_deg)
        self.d = np.array(config.dh.d_mm) / 1000.0
        self.offset = np.radians(config.dh.offset_deg)
        self.limits_deg = np.array(config.joint_limits_deg, dtype=float)
        self.sensor_frame = config.sensor.frame
        self.T_frame_sensor = config.sensor.matrix()
        self.T_flange_tcp = config.tcp.matrix()
        links = config.inertial.links if config.inertial is not None else None
        self.link_mass = np.array([lk.mass_kg for lk in links]) if links else np.zeros(N_JOINTS)
        self.link_com = (np.array([lk.com_mm for lk in links]) / 1000.0 if links
                         else np.zeros((N_JOINTS, 3)))          # m, link i's centre in DH frame i
        self.balancer = config.inertial.balancer if config.inertial is not None else None

    @property
    def has_masses(self) -> bool:
        """Whether any link has a mass (else the arm's static torque is zero)."""
        return bool(self.link_mass.any())

    @classmethod
    def from_yaml(cls, path: str | Path) -> Robot:
        data = read_extended(Path(path))
        config = validate(RobotConfig, data, str(path))
        config.check_sources(str(path))
        if config.urdf is not None:
            from .urdf import read_urdf

            urdf_path = Path(path).parent / config.urdf.file
            dh, limits, links = read_urdf(urdf_path, config.urdf.flange, f"{path}: urdf.file")
            inertial = {"links": links} | ({"balancer": data["inertial"]["balancer"]}
                                           if config.inertial and config.inertial.balancer else {})
            config = validate(RobotConfig, data | {"dh": dh, "joint_limits_deg": limits, "inertial": inertial},
                              f"{urdf_path} (read for {path})")
        return cls(config, str(path))

    # -- batched kinematics -------------------------------------------------------------------
    def dh_transforms(self, q: np.ndarray) -> np.ndarray:
        """T(i-1, i) for each joint: (N, 6) joint angles in rad -> (N, 6, 4, 4)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        th = q + self.offset
        ct, st = np.cos(th), np.sin(th)
        ca, sa = np.cos(self.alpha), np.sin(self.alpha)
        A = np.zeros(q.shape + (4, 4))
        A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, self.a * ct
        A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, self.a * st
        A[..., 2, 1], A[..., 2, 2], A[..., 2, 3] = sa, ca, self.d
        A[..., 3, 3] = 1.0
        return A

    def frames(self, q: np.ndarray) -> np.ndarray:
        """Base poses of DH frames 0..6 and the TCP: (N, 6) rad -> (N, 8, 4, 4); index 7 is the TCP."""
        A = self.dh_transforms(q)
        n = A.shape[0]
        F = np.empty((n, 8, 4, 4))
        F[:, 0] = np.eye(4)
        for i in range(N_JOINTS):
            F[:, i + 1] = F[:, i] @ A[:, i]
        F[:, 7] = F[:, 6] @ self.T_flange_tcp
        return F

    def sensor_pose(self, F: np.ndarray) -> np.ndarray:
        """Base pose of the F/T sensor from the frames returned by `frames`."""
        return F[:, self.sensor_frame] @ self.T_frame_sensor

    def within_limits(self, q_deg: np.ndarray) -> np.ndarray:
        """Boolean mask (N, 6): True where the joint angle lies inside its limits."""
        q_deg = np.atleast_2d(q_deg)
        return (q_deg >= self.limits_deg[:, 0]) & (q_deg <= self.limits_deg[:, 1])

    # -- pinocchio ----------------------------------------------------------------------------
    @cached_property
    def pin_model(self):
        """A pinocchio model of the chain with operational frames A1..A6, 'sensor' and 'TCP'.

        Joint i's frame is DH frame i-1 turned by Rz(offset_i + q_i); frame A_i is joint i's frame
        moved by Tz(d_i) Tx(a_i) Rx(alpha_i). Link i's mass sits on joint i as a point mass at its
        centre of mass (zero without an ``inertial`` section); gravity is pinocchio's default
        (0, 0, -9.81) m/s^2 in the base.
        """
        import pinocchio as pin

        model = pin.Model()
        model.name = self.name
        parent = 0
        tail = np.eye(4)  # from the previous joint's frame to DH frame i-1
        for i in range(N_JOINTS):
            rz_off = rot_z(self.offset[i])
            placement = pin.SE3(tail @ rz_off)
            parent = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i + 1}")
            model.lowerPositionLimit[i] = np.radians(self.limits_deg[i, 0])
            model.upperPositionLimit[i] = np.radians(self.limits_deg[i, 1])
            tail = trans_z(self.d[i]) @ trans_x(self.a[i]) @ rot_x(self.alpha[i])
            com = (tail @ np.append(self.link_com[i], 1.0))[:3]
            model.appendBodyToJoint(parent, pin.Inertia(self.link_mass[i], com, np.zeros((3, 3))), pin.SE3.Identity())
            model.addFrame(pin.Frame(BODIES[i], parent, pin.SE3(tail), pin.FrameType.OP_FRAME))
        flange = pin.SE3(tail)
        model.addFrame(pin.Frame("TCP", parent, flange * pin.SE3(self.T_flange_tcp), pin.FrameType.OP_FRAME))
        if self.sensor_frame == 0:
            model.addFrame(pin.Frame("sensor", 0, pin.SE3(self.T_frame_sensor), pin.FrameType.OP_FRAME))
        else:
            j = self.sensor_frame
            sensor = model.frames[model.getFrameId(BODIES[j - 1])].placement * pin.SE3(self.T_frame_sensor)
            model.addFrame(pin.Frame("sensor", j, sensor, pin.FrameType.OP_FRAME))
        return model


def read_extended(path: Path, seen: tuple[Path, ...] = ()) -> dict:
    """A robot YAML's mapping; ``extends: OTHER.yaml`` (relative to it) starts from that robot's file
    and this one's keys merged in at every depth (e.g. the kinematic KR 125 plus its masses)."""
    data = read_yaml(path)
    base = data.pop("extends", None)
    if base is None:
        return data
    if not isinstance(base, str):
        raise ConfigError(f"{path}: extends = {quote(base)} must name a robot YAML file (relative to this one)")
    other = (path.parent / base).resolve()
    if other in seen or other == path.resolve():
        raise ConfigError(f"{path}: extends = {quote(base)} comes back to a file it extends")
    if not other.exists():
        raise ConfigError(f"{path}: extends = {quote(base)}: file {other} not found")
    return deep_update(read_extended(other, (*seen, path.resolve())), data)


def load_robot(path: str | Path) -> Robot:
    """Read a robot YAML; ConfigError names the file and key on failure."""
    if not Path(path).exists():
        raise ConfigError(f"{path}: robot file not found")
    return Robot.from_yaml(path)
