"""The HIL scenario file (config/hil/circle.yaml): a pydantic schema that rejects unknown keys."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field

from service.gravity import GravityConfig
from stiffness.files.yaml_schema import Strict, read_yaml, validate
from stiffness.kinematics.robot import PoseConfig

from .accelerometer import AccelerometerConfig
from .structure import StructureConfig

ROOT = Path(__file__).resolve().parent.parent
DEFAULT_SCENARIO = ROOT / "config" / "hil" / "circle.yaml"


class CircleConfig(Strict):
    center_q_deg: list[float] = Field(min_length=6, max_length=6)
    radius_mm: float = Field(35.0, gt=0.0, le=500.0)
    feed_mm_s: float = Field(50.0, gt=0.0, le=1000.0)
    direction: Literal["ccw", "cw"] = "ccw"
    points: int = Field(720, ge=36, le=100_000)
    lead_s: float = Field(0.4, ge=0.0, le=10.0)
    tail_s: float = Field(0.3, ge=0.0, le=10.0)


class MillingConfig(Strict):
    tool_diameter_mm: float = Field(8.0, gt=0.0)
    teeth: int = Field(4, ge=1, le=20)
    spindle_rpm: float = Field(6000.0, gt=0.0)
    feed_force_N: float = Field(320.0, ge=0.0, le=2000.0)
    normal_force_N: float = Field(450.0, ge=0.0, le=2000.0)
    normal_toward_center: bool = True
    axial_force_N: float = Field(150.0, ge=-2000.0, le=2000.0)
    tooth_amplitude: float = Field(0.3, ge=0.0, le=1.0)
    entry_overshoot: float = Field(0.4, ge=0.0, le=5.0)
    entry_tau_s: float = Field(0.05, gt=0.0, le=5.0)
    exit_s: float = Field(0.12, gt=0.0, le=5.0)
    variation: float = Field(0.03, ge=0.0, le=0.5)
    seed: int = 7


class SensorConfig(Strict):
    noise_N: float = Field(1.5, ge=0.0)
    noise_Nm: float = Field(0.05, ge=0.0)
    seed: int = 11
    rate_hz: float = Field(7000.0, ge=100.0, le=100_000.0)
    lowpass_hz: float = Field(52.0, ge=0.0, le=5000.0)


class PlcConfig(Strict):
    period_ms: float = Field(2.0, ge=1.0, le=4.0)
    # None: the program's own settings; a value is written into the program before its first cycle, as an
    # online change of GVL_StiffCompSettings.tServiceTimeout and MAIN.fMaxRateDegPerS would be
    service_timeout_ms: float | None = Field(None, gt=0.0)
    max_rate_deg_s: float | None = Field(None, gt=0.0, le=100.0)
    extra_delay_ms: float = Field(0.0, ge=0.0, le=100.0)     # the PLC applies each correction this much later


class CmmConfig(Strict):
    """The virtual CMM that measures the machined contour (`hil.cmm`)."""

    points: int = Field(360, ge=12, le=100_000)
    noise_um: float = Field(2.0, ge=0.0, le=1000.0)
    seed: int = 13
    entry_exit_mask_deg: float = Field(10.0, ge=0.0, le=180.0)
    depth_mm: float = Field(2.0, ge=0.0, le=100.0)
    part_frame: PoseConfig | None = None


class ProbeConfig(Strict):
    """The virtual probe: the robot touches the contour it machined (`hil.probe`, `stiffcomp hil circle --probe`)."""

    touches: int = Field(120, ge=3, le=10_000)          # 84 or more: `part diagnose` of a 36-parameter model
    stylus_radius_mm: float = Field(1.5, gt=0.0, le=50.0)
    speed_mm_s: float = Field(5.0, gt=0.0, le=500.0)            # the probing speed along the normal
    latency_ms: float = Field(1.0, ge=0.0, le=100.0)             # from the trigger to the latch, stated in the log
    latency_jitter_ms: float = Field(0.5, ge=0.0, le=100.0)      # +- around it, uniform: what the log cannot state
    repeatability_mm: float = Field(0.03, ge=0.0, le=5.0)        # ISO 9283 RP, taken as 3 sigma per axis
    seed: int = 17
    entry_exit_mask_deg: float = Field(10.0, ge=0.0, le=180.0)
    depth_mm: float = Field(2.0, ge=0.0, le=100.0)


class Scenario(Strict):
    truth: str
    model: str
    service: str = "service.yaml"
    circle: CircleConfig
    milling: MillingConfig = Field(default_factory=MillingConfig)
    sensor: SensorConfig = Field(default_factory=SensorConfig)
    robot: StructureConfig = Field(default_factory=StructureConfig)
    plc: PlcConfig = Field(default_factory=PlcConfig)
    payload: GravityConfig = Field(default_factory=GravityConfig)     # the truth: what the sensor carries
    cmm: CmmConfig = Field(default_factory=CmmConfig)
    probe: ProbeConfig = Field(default_factory=ProbeConfig)
    accelerometer: AccelerometerConfig = Field(default_factory=AccelerometerConfig)

    path: Path = Field(default=Path("<scenario>"), exclude=True)

    def resolve(self, relative: str | Path) -> Path:
        p = Path(relative)
        return p if p.is_absolute() else self.path.parent / p


def load_scenario(path: str | Path | None = None) -> Scenario:
    """Read and validate a scenario; ConfigError names the file, the key, the value and the range."""
    path = Path(path) if path is not None else DEFAULT_SCENARIO
    data = read_yaml(path)
    sc = validate(Scenario, data, str(path))
    sc.path = path
    if sc.robot.masses is not None:                          # relative to the scenario, as truth and model are
        sc.robot = sc.robot.model_copy(update={"masses": str(sc.resolve(sc.robot.masses))})
    return sc
