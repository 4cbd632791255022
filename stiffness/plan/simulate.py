"""Synthetic measurement campaigns like the paper's (Sec. III-B), made from a truth model.

A campaign file (docs/simulate.md) names a truth model YAML, the configurations and the load
protocol. For every configuration and every tool axis a in the campaign's ``loads.axes``, the load
is ramped

    0 -> +s -> ... -> +max -> ... -> +s -> 0 -> -s -> ... -> -max -> ... -> -s -> 0      (N)

along axis a of the flange frame (DH frame 6), applied at the load point p (flange frame, mm). The
sensor measures that wrench as force and moment about its own origin in its own axes (Eq. 4):

    W_s = A(T_0s, T_0p) [F; 0],     F = f e_a  (flange axes)

Each load state is read ``readings.repeats`` times; only the ``components`` the device measures are
written (a laser tracker: dx, dy, dz of the TCP). The deflection of each measured body is the
truth model's prediction for the *true* wrench (`StiffnessModel.predict`, with the campaign's time
order, so time- and history-dependent effects see the readings as they were taken); then the
optical system's noise (mm, deg per component) is added to the deflection and the F/T sensor's
noise (N, Nm per component) to the wrench that is written. The result is a `Dataset` in the
measurement format (docs/measurement_format.md).

Time (s) runs in the order readings are taken: a state's readings are ``interval_s`` apart,
the first one ``interval_s`` after the state began; the next state begins ``settle_s`` after the
previous state's last reading, and ``move_s`` more is added between configurations.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, field_validator

from ..data.measurements import COMPONENTS, Dataset
from ..errors import ConfigError, quote
from ..files.yaml_schema import Strict, read_yaml, validate
from ..kinematics.robot import BODIES, N_JOINTS, Robot
from ..kinematics.spatial import transform, transport_wrench
from ..model.stiffness_model import StiffnessModel

AXES = ("x", "y", "z")
MAX_ROWS = 5_000_000  # refuse campaigns that would not fit in memory comfortably



class ConfigurationSpec(Strict):
    name: str = Field(min_length=1)
    q_deg: list[float] = Field(min_length=N_JOINTS, max_length=N_JOINTS)


class RandomConfigurations(Strict):
    count: int = Field(ge=1, le=10_000)
    seed: int | None = Field(None, description="defaults to the campaign's seed")
    margin_deg: float = Field(5.0, ge=0.0, description="stay this far inside every joint limit")
    prefix: str = Field("C", min_length=1)


class LoadSpec(Strict):
    axes: list[Literal["x", "y", "z"]] = Field(default_factory=lambda: list(AXES), min_length=1)
    max_N: float = Field(1200.0, gt=0.0, le=1e6)
    step_N: float = Field(300.0, gt=0.0)
    point_mm: list[float] = Field(default_factory=lambda: [100.0, 0.0, 250.0], min_length=3, max_length=3)

    @field_validator("axes")
    @classmethod
    def _unique_axes(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError("each axis may appear once")
        return v

    def levels(self) -> np.ndarray:
        """The load magnitudes of one ramp: 0, +s .. +max .. +s, 0, -s .. -max .. -s, 0 (N)."""
        up = np.arange(1, int(np.floor(self.max_N / self.step_N + 1e-9)) + 1) * self.step_N
        if up[-1] < self.max_N - 1e-9:
            up = np.append(up, self.max_N)
        half = np.concatenate([up, up[-2::-1]])
        return np.concatenate([[0.0], half, [0.0], -half, [0.0]])


class ReadingSpec(Strict):
    repeats: int = Field(3, ge=1, le=1000)
    interval_s: float = Field(4.0, gt=0.0)
    settle_s: float = Field(8.0, ge=0.0)
    move_s: float = Field(0.0, ge=0.0)
    start_s: float = 0.0


class NoiseSpec(Strict):
    position_mm: float = Field(0.03, ge=0.0, le=10.0)
    rotation_deg: float = Field(0.002, ge=0.0, le=1.0)
    force_N: float = Field(2.0, ge=0.0, le=1000.0)
    moment_Nm: float = Field(0.5, ge=0.0, le=1000.0)


class CampaignSpec(Strict):
    """The campaign YAML, validated; unknown keys are rejected."""

    name: str = "campaign"
    description: str = ""
    truth: str = Field(min_length=1, description="truth model YAML, relative to the campaign file")
    seed: int = 0
    configurations: list[ConfigurationSpec] = Field(default_factory=list)
    random_configurations: RandomConfigurations | None = None
    loads: LoadSpec = Field(default_factory=LoadSpec)
    readings: ReadingSpec = Field(default_factory=ReadingSpec)
    noise: NoiseSpec = Field(default_factory=NoiseSpec)
    bodies: list[Literal["A1", "A2", "A3", "A4", "A5", "A6", "TCP"]] = Field(
        default_factory=lambda: list(BODIES), min_length=1)
    components: list[Literal["dx", "dy", "dz", "rx", "ry", "rz"]] = Field(
        default_factory=lambda: list(COMPONENTS), min_length=1,
        description="the deflection components the device measures (a laser tracker: dx, dy, dz)")

    @field_validator("bodies", "components")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError("each entry may appear once")
        return v


class Campaign:
    """A validated campaign: truth model, joint angles per configuration, protocol and noise.

    Parameters
    ----------
    spec : CampaignSpec
    truth : StiffnessModel
        The model that makes the deflections.
    source : str
        The campaign file, for error messages and the dataset's ``source``.
    """

    def __init__(self, spec: CampaignSpec, truth: StiffnessModel, source: str = "<campaign>"):
        check_spec(spec, source)
        self.source = source
        self.name = spec.name
        self.truth = truth
        self.seed = spec.seed
        self.axes = [AXES.index(a) for a in spec.loads.axes]
        self.levels_N = spec.loads.levels()
        self.point_mm = np.array(spec.loads.point_mm, dtype=float)
        rs = spec.readings
        self.repeats, self.interval_s, self.settle_s = rs.repeats, rs.interval_s, rs.settle_s
        self.move_s, self.start_s = rs.move_s, rs.start_s
        self.noise = spec.noise.model_dump()
        self.bodies = np.array([BODIES.index(b) for b in spec.bodies])
        self.components = np.isin(COMPONENTS, spec.components)
        names = [c.name for c in spec.configurations]
        q = [c.q_deg for c in spec.configurations]
        _check_limits(truth.robot, np.array(q).reshape(-1, N_JOINTS), "configurations", source)
        if spec.random_configurations is not None:
            r = spec.random_configurations
            seed = spec.seed if r.seed is None else r.seed
            q_rand = random_configurations(truth.robot, r.count, seed, r.margin_deg, source)
            width = len(str(r.count))
            names += [f"{r.prefix}{i + 1:0{width}d}" for i in range(r.count)]
            q += q_rand.tolist()
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ConfigError(f"{source}: configurations: name = {quote(dup[0])} is used twice; names must be unique")
        self.config_names = names
        self.q_deg = np.array(q, dtype=float)
        n_rows = len(names) * len(self.axes) * len(self.levels_N) * self.repeats * len(self.bodies)
        if n_rows > MAX_ROWS:
            raise ConfigError(f"{source}: the campaign would have {n_rows} rows; at most {MAX_ROWS} allowed")

    @classmethod
    def from_yaml(cls, path: str | Path) -> Campaign:
        path = Path(path)
        if not path.exists():
            raise ConfigError(f"{path}: campaign file not found")
        spec = validate(CampaignSpec, read_yaml(path), str(path))
        truth_path = path.parent / spec.truth
        if not truth_path.exists():
            raise ConfigError(f"{path}: truth = {quote(spec.truth)}: model file {truth_path} not found "
                              "(the path is relative to the campaign file)")
        return cls(spec, StiffnessModel.from_yaml(truth_path), str(path))

    # -- the protocol ---------------------------------------------------------------------------
    def plan(self) -> Dataset:
        """The readings in the order they are taken, with the true (noise-free) sensor wrench.

        Deflections are zero: the skeleton that `run` fills in.
        """
        times, cfg, q_rows, forces = [], [], [], []
        t = self.start_s
        for c, (name, q) in enumerate(zip(self.config_names, self.q_deg)):
            if c:
                t += self.move_s
            for axis in self.axes:
                e = np.eye(3)[axis]
                for f in self.levels_N:
                    for _ in range(self.repeats):
                        t += self.interval_s
                        times.append(t)
                        cfg.append(name)
                        q_rows.append(q)
                        forces.append(f * e)
                    t += self.settle_s
        q_deg = np.array(q_rows)
        W = sensor_wrench(self.truth.robot, q_deg, np.array(forces), self.point_mm)
        nb = len(self.bodies)
        rep = np.repeat(np.arange(len(times)), nb)
        return Dataset(np.array(times)[rep], np.array(cfg)[rep], q_deg[rep], W[rep],
                       np.tile(self.bodies, len(times)), np.zeros((len(rep), 6)), source=self.source)

    def run(self, noise: bool = True) -> Dataset:
        """Simulate the campaign: the truth model's deflections, then measurement noise (if ``noise``)."""
        data = self.plan()
        data.deflection = self.truth.predict(data)
        if noise:
            add_noise(data, self.noise, np.random.default_rng(self.seed))
        data.deflection[:, ~self.components] = np.nan        # not measured by the device
        return data


def sensor_wrench(robot: Robot, q_deg: np.ndarray, force_flange: np.ndarray,
                  point_mm: np.ndarray) -> np.ndarray:
    """The sensor wrench (N, Nm; sensor axes, about the sensor origin) of forces at a load point.

    Parameters
    ----------
    q_deg : (R, 6) joint angles, deg
    force_flange : (R, 3) force in flange (DH frame 6) axes, N
    point_mm : (3,) the load point in the flange frame, mm
    """
    F = robot.frames(np.radians(q_deg))
    T_0p = F[:, 6] @ transform(np.eye(3), np.asarray(point_mm, dtype=float) / 1000.0)
    W_p = np.concatenate([force_flange, np.zeros_like(force_flange)], axis=1)
    return transport_wrench(W_p, T_0p, robot.sensor_pose(F))


def add_noise(data: Dataset, noise: dict[str, float], rng: np.random.Generator) -> None:
    """Add Gaussian noise in place: per reading to the wrench, per row to the deflection.

    ``noise`` holds 1-sigma values per component: position_mm, rotation_deg, force_N, moment_Nm.
    """
    first, reading = data.readings()
    n_read = len(first)
    sw = np.array([noise["force_N"]] * 3 + [noise["moment_Nm"]] * 3)
    sd = np.array([noise["position_mm"]] * 3 + [noise["rotation_deg"]] * 3)
    w_noise = rng.standard_normal((n_read, 6)) * sw
    data.wrench = data.wrench + w_noise[reading]
    data.deflection = data.deflection + rng.standard_normal(data.deflection.shape) * sd


def random_configurations(robot: Robot, count: int, seed: int, margin_deg: float = 5.0,
                          source: str = "<campaign>") -> np.ndarray:
    """``count`` joint-angle sets (deg) drawn uniformly inside the limits less ``margin_deg``."""
    lo = robot.limits_deg[:, 0] + margin_deg
    hi = robot.limits_deg[:, 1] - margin_deg
    bad = np.nonzero(lo >= hi)[0]
    if len(bad):
        j = bad[0]
        raise ConfigError(f"{source}: random_configurations.margin_deg = {margin_deg:g} leaves no room in "
                          f"joint {j + 1}'s limits {robot.limits_deg[j].tolist()} "
                          f"(must be below {np.diff(robot.limits_deg[j])[0] / 2:g})")
    rng = np.random.default_rng([seed, 1])  # a stream apart from the noise's
    return np.round(rng.uniform(lo, hi, size=(count, N_JOINTS)), 3)


def check_spec(spec: CampaignSpec, source: str) -> None:
    """The checks that span several keys; ConfigError names the keys, values and allowed range."""
    if not spec.configurations and spec.random_configurations is None:
        raise ConfigError(f"{source}: no configurations: give configurations (a list of name + q_deg), "
                          "random_configurations (count), or both")
    ld = spec.loads
    if ld.step_N > ld.max_N:
        raise ConfigError(f"{source}: loads.step_N = {ld.step_N:g} must not exceed loads.max_N = {ld.max_N:g}")
    if ld.max_N / ld.step_N > 1000:
        raise ConfigError(f"{source}: loads.step_N = {ld.step_N:g} makes {ld.max_N / ld.step_N:.0f} steps up to "
                          f"loads.max_N = {ld.max_N:g}; at most 1000 are allowed")


def _check_limits(robot: Robot, q_deg: np.ndarray, key: str, source: str) -> None:
    ok = robot.within_limits(q_deg) if len(q_deg) else np.ones((0, N_JOINTS), bool)
    problems = []
    for i, j in zip(*np.nonzero(~ok)):
        lo, hi = robot.limits_deg[j]
        problems.append(f"{source}: {key}.{i}.q_deg.{j} = {q_deg[i, j]:g} is outside joint {j + 1}'s "
                        f"limits [{lo:g}, {hi:g}] of {robot.source}")
    if problems:
        raise ConfigError("\n".join(problems))


def simulate(campaign: str | Path | Campaign, noise: bool = True) -> Dataset:
    """Read a campaign file (or take a Campaign) and simulate it."""
    c = campaign if isinstance(campaign, Campaign) else Campaign.from_yaml(campaign)
    return c.run(noise)
