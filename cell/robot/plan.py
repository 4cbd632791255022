"""The plans the robot programs are written from: the probe's (the HIL scenario's probe section, the circle's radius
and the cutter's, the robot YAML's tcp) and the road's (the service config's ``robot`` and ``limits`` sections).

The scenario and the robot are read as YAML here, not through the HIL (which stands above this package): the keys
read are the ones config/hil/circle.yaml documents, and every value is checked for the range a program can take."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import yaml

from stiffness.errors import ConfigError

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "config" / "hil" / "circle.yaml"
ROBOT = ROOT / "config" / "robots" / "kr125.yaml"
CONFIGS = (ROOT / "config" / "robot_kuka_rsi.yaml", ROOT / "config" / "robot_abb_egm.yaml")


@dataclass(frozen=True)
class ProbePlan:
    """What the probe programs do: the touches along the contour, the probe's geometry and its frame in DH frame 6."""

    touches: int = 120
    mask_deg: float = 10.0
    path_radius_mm: float = 35.0
    tool_radius_mm: float = 4.0
    stylus_radius_mm: float = 1.5
    speed_mm_s: float = 5.0
    latency_ms: float = 1.0
    depth_mm: float = 2.0
    clearance_mm: float = 2.0
    overrun_mm: float = 4.0
    probe_xyz_mm: tuple[float, float, float] = (0.0, 0.0, 250.0)
    probe_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self):
        checks = [("touches", 2 <= self.touches <= 999), ("mask_deg", 0 <= self.mask_deg < 180),
                  ("path_radius_mm", 0 < self.path_radius_mm <= 5000), ("tool_radius_mm", 0 < self.tool_radius_mm <= 500),
                  ("stylus_radius_mm", 0 < self.stylus_radius_mm <= 50), ("speed_mm_s", 0 < self.speed_mm_s <= 1000),
                  ("latency_ms", 0 <= self.latency_ms <= 100), ("depth_mm", 0 <= self.depth_mm <= 1000),
                  ("clearance_mm", 0 < self.clearance_mm <= 100), ("overrun_mm", 0 < self.overrun_mm <= 100),
                  ("probe_xyz_mm", all(abs(v) <= 5000 for v in self.probe_xyz_mm)),
                  ("probe_rpy_deg", all(abs(v) <= 180 for v in self.probe_rpy_deg))]
        values = [self.mask_deg, self.path_radius_mm, self.tool_radius_mm, self.stylus_radius_mm, self.speed_mm_s,
                  self.latency_ms, self.depth_mm, *self.probe_xyz_mm, *self.probe_rpy_deg]
        bad = [name for name, ok in checks if not ok]
        if bad or not all(math.isfinite(v) for v in values):
            raise ConfigError(f"probe plan: {', '.join(bad) or 'a value is not finite'} out of range: {self}")
        if self.path_radius_mm + self.tool_radius_mm - self.stylus_radius_mm <= self.clearance_mm:
            raise ConfigError("probe plan: the stylus cannot start clearance_mm short of the wall: the contour is "
                              "smaller than the stylus and the clearance")

    @property
    def reach_mm(self) -> float:
        """The stylus ball's centre at the nominal wall, from the contour's centre."""
        return self.path_radius_mm + self.tool_radius_mm - self.stylus_radius_mm


# each value of the plan a program states: its KRL name, its RAPID name, the ProbePlan field and what it is
PLAN_ROWS = (
    ("nTouches", "nTouches", "touches", "touches, equally spaced along the contour (probe.touches)"),
    ("maskDeg", "maskDeg", "mask_deg", "none within this of the contour's start (probe.entry_exit_mask_deg)"),
    ("rPath", "rPath", "path_radius_mm",
     "the cutter centre's nominal path about the contour's centre, mm (circle.radius_mm)"),
    ("rTool", "rTool", "tool_radius_mm", "the cutter's radius, mm (milling.tool_diameter_mm / 2)"),
    ("rStylus", "rStylus", "stylus_radius_mm",
     "the stylus ball's effective radius, mm, from a ring gauge (probe.stylus_radius_mm)"),
    ("vProbe", "vProbe", "speed_mm_s", "the probing speed along the normal, mm/s (probe.speed_mm_s)"),
    ("latencyMs", "latencyMs", "latency_ms", "trigger to latch on this controller, ms, as measured (probe.latency_ms)"),
    ("depth", "depth", "depth_mm", "the touches this far below the path's plane, mm (probe.depth_mm)"),
    ("clearance", "CLEARANCE", "clearance_mm", "each search starts this far short of the nominal wall, mm"),
    ("overrun", "OVERRUN", "overrun_mm", "... and gives up this far beyond it, mm"),
)


def _yaml(path: Path) -> dict:
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as e:
        raise ConfigError(f"{path}: cannot be read: {e}") from e
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: not a YAML mapping")
    return data


def _key(data: dict, path: Path, *keys: str):
    value = data
    for key in keys:
        if not isinstance(value, dict) or key not in value:
            raise ConfigError(f"{path}: no {'.'.join(keys)}")
        value = value[key]
    return value


def load_probe_plan(scenario: Path = SCENARIO, robot: Path = ROBOT) -> ProbePlan:
    """The probe plan of a HIL scenario (its probe section, circle.radius_mm, milling.tool_diameter_mm) with the
    robot YAML's tcp as the probe's frame."""
    sc, rb = _yaml(scenario), _yaml(robot)
    probe = _key(sc, scenario, "probe")
    try:
        return ProbePlan(
            touches=int(_key(probe, scenario, "touches")), mask_deg=float(probe.get("entry_exit_mask_deg", 10.0)),
            path_radius_mm=float(_key(sc, scenario, "circle", "radius_mm")),
            tool_radius_mm=float(_key(sc, scenario, "milling", "tool_diameter_mm")) / 2.0,
            stylus_radius_mm=float(_key(probe, scenario, "stylus_radius_mm")),
            speed_mm_s=float(_key(probe, scenario, "speed_mm_s")),
            latency_ms=float(probe.get("latency_ms", 0.0)), depth_mm=float(probe.get("depth_mm", 0.0)),
            probe_xyz_mm=tuple(float(v) for v in _key(rb, robot, "tcp", "xyz_mm")),
            probe_rpy_deg=tuple(float(v) for v in _key(rb, robot, "tcp", "rpy_deg")))
    except (TypeError, ValueError) as e:
        raise ConfigError(f"{scenario}, {robot}: a probe value is not a number: {e}") from e
