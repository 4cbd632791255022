"""The service config (config/default.yaml): a pydantic schema that rejects unknown keys.

Every section maps to one class through its ``from_config`` factory; the classes read what they
need in their constructor and keep no reference to the config. Errors name the file, the key, the
value and the allowed range, e.g.::

    config/default.yaml: filter.cutoff_hz = 900 must be below half the cycle rate (500 Hz)

Paths in the file (model, replay log, register map, DBC) are relative to the config file.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError, field_validator, model_validator

from plc_interface.ads.settings import AdsSettings
from plc_interface.settings import MonitoringSettings, PlcSettings
from stiffness.errors import StiffnessError
from stiffness.yamlio import Strict, format_validation_error, read_yaml

from .errors import ServiceConfigError

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "config" / "default.yaml"



def _six_or_one(v: float | list[float]) -> list[float]:
    vals = [float(v)] * 6 if isinstance(v, (int, float)) else [float(x) for x in v]
    if len(vals) != 6:
        raise ValueError(f"needs one value or six (one per joint), got {len(vals)}")
    if any(not x > 0 for x in vals):
        raise ValueError("every value must be > 0")
    return vals


class CycleConfig(Strict):
    period_ms: float = Field(1.0, ge=0.1, le=100.0)
    stats_log_interval_s: float = Field(10.0, ge=0.0)
    history: int = Field(600_000, ge=1000, le=10_000_000)
    realtime_priority: int = Field(0, ge=0, le=99)
    cpu: int | None = Field(None, ge=0, le=1023)
    spin_us: float = Field(0.0, ge=0.0, le=1000.0)


class ModelConfig(Strict):
    file: str
    refinement_iterations: int = Field(0, ge=0, le=10)
    damping: float = Field(1e-3, ge=0.0, le=1.0)


class AtiConfig(Strict):
    base_id: int = Field(0x020, ge=0, le=0x7F0)
    counts_per_force: float = Field(10.0, gt=0)
    counts_per_torque: float = Field(100.0, gt=0)
    foreign_frames: Literal["fault", "ignore"] = "fault"
    dbc: str = "ati_netft_can.dbc"


class CanConfig(Strict):
    interface: str = "virtual"
    channel: str = "ati0"
    bitrate: int | None = Field(1_000_000, gt=0)
    request_each_cycle: bool = True
    options: dict[str, str | int | float | bool] = Field(default_factory=dict)


class ReplayConfig(Strict):
    file: str
    pacing: Literal["realtime", "fast"] = "realtime"
    loop: bool = True


class SourceConfig(Strict):
    type: Literal["replay", "can"] = "replay"
    ati: AtiConfig = Field(default_factory=AtiConfig)
    can: CanConfig = Field(default_factory=CanConfig)
    replay: ReplayConfig | None = None
    max_force_N: float = Field(2500.0, gt=0)
    max_torque_Nm: float = Field(250.0, gt=0)

    @model_validator(mode="after")
    def _replay_needs_file(self) -> SourceConfig:
        if self.type == "replay" and self.replay is None:
            raise ValueError("type = 'replay' needs a replay section with a file")
        return self


class SpikeConfig(Strict):
    max_step_N: float = Field(300.0, gt=0)
    max_step_Nm: float = Field(30.0, gt=0)
    max_held: int = Field(3, ge=0, le=100)


class FilterConfig(Strict):
    type: Literal["butterworth", "bessel", "none"] = "butterworth"
    order: int = Field(2, ge=1, le=8)
    cutoff_hz: float = Field(100.0, gt=0)
    spike: SpikeConfig = Field(default_factory=SpikeConfig)


class BodyConfig(Strict):
    mass_kg: float = Field(0.0, ge=0.0, le=1000.0)
    cog_mm: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)


class GravityConfig(Strict):
    g_mps2: list[float] = Field(default_factory=lambda: [0.0, 0.0, -9.81], min_length=3, max_length=3)
    sensor: BodyConfig = Field(default_factory=BodyConfig)
    tool: BodyConfig = Field(default_factory=BodyConfig)
    fixture: BodyConfig = Field(default_factory=BodyConfig)
    workpiece: BodyConfig = Field(default_factory=BodyConfig)
    bias: list[float] = Field(default_factory=lambda: [0.0] * 6, min_length=6, max_length=6)


class LimitsConfig(Strict):
    max_correction_deg: float | list[float] = 0.5
    max_rate_deg_s: float | list[float] = 5.0
    fault_ramp_s: float = Field(0.2, gt=0.0, le=10.0)

    _check = field_validator("max_correction_deg", "max_rate_deg_s")(_six_or_one)


class FaultsConfig(Strict):
    sensor_timeout_ms: float = Field(10.0, gt=0)
    plc_heartbeat_timeout_ms: float = Field(200.0, ge=0)
    overrun_trip_count: int = Field(10, ge=1, le=1000)
    io_restarts: int = Field(3, ge=0, le=100)


class TareConfig(Strict):
    max_force_N: float = Field(200.0, gt=0)




class ServiceConfig(Strict):
    cycle: CycleConfig = Field(default_factory=CycleConfig)
    model: ModelConfig
    source: SourceConfig
    filter: FilterConfig = Field(default_factory=FilterConfig)
    gravity: GravityConfig = Field(default_factory=GravityConfig)
    limits: LimitsConfig = Field(default_factory=LimitsConfig)
    faults: FaultsConfig = Field(default_factory=FaultsConfig)
    tare: TareConfig = Field(default_factory=TareConfig)
    plc: PlcSettings = Field(default_factory=PlcSettings)
    ads: AdsSettings = Field(default_factory=AdsSettings)
    monitoring: MonitoringSettings = Field(default_factory=MonitoringSettings)

    # set by load_config: where the file was, for relative paths and messages
    path: Path = Field(default=Path("<config>"), exclude=True)

    def resolve(self, relative: str) -> Path:
        """A path written in the config, relative to the config file's folder."""
        p = Path(relative)
        return p if p.is_absolute() else self.path.parent / p


def load_config(path: str | Path | None = None) -> ServiceConfig:
    """Read and validate the service config; ServiceConfigError names file, key, value and range."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    if not path.exists():
        raise ServiceConfigError(f"{path}: config file not found")
    try:
        data = read_yaml(path)
    except StiffnessError as e:
        raise ServiceConfigError(str(e)) from e
    if "path" in data:
        raise ServiceConfigError(f"{path}: path is not a known key")
    try:
        cfg = ServiceConfig.model_validate(data)
    except ValidationError as e:
        raise ServiceConfigError(format_validation_error(str(path), e)) from e
    cfg.path = path
    check_consistency(cfg)
    return cfg


def check_consistency(cfg: ServiceConfig) -> None:
    """Checks that involve more than one key, and that the files the config names exist."""
    src = str(cfg.path)
    import os

    if cfg.cycle.cpu is not None and cfg.cycle.cpu >= (os.cpu_count() or 1):
        raise ServiceConfigError(f"{src}: cycle.cpu = {cfg.cycle.cpu} must be below the number of CPUs "
                                 f"({os.cpu_count()})")
    if cfg.cycle.spin_us >= cfg.cycle.period_ms * 1000.0:
        raise ServiceConfigError(f"{src}: cycle.spin_us = {cfg.cycle.spin_us:g} must be below the period "
                                 f"({cfg.cycle.period_ms * 1000:g} us)")
    nyquist = 500.0 / cfg.cycle.period_ms
    if cfg.filter.type != "none" and not cfg.filter.cutoff_hz < nyquist:
        raise ServiceConfigError(f"{src}: filter.cutoff_hz = {cfg.filter.cutoff_hz:g} must be below half "
                                 f"the cycle rate ({nyquist:g} Hz)")
    if cfg.faults.sensor_timeout_ms <= cfg.cycle.period_ms:
        raise ServiceConfigError(f"{src}: faults.sensor_timeout_ms = {cfg.faults.sensor_timeout_ms:g} must be "
                                 f"longer than cycle.period_ms ({cfg.cycle.period_ms:g})")
    hb = cfg.faults.plc_heartbeat_timeout_ms
    if 0 < hb <= cfg.cycle.period_ms:
        raise ServiceConfigError(f"{src}: faults.plc_heartbeat_timeout_ms = {hb:g} must be 0 (off) or longer "
                                 f"than cycle.period_ms ({cfg.cycle.period_ms:g})")
    files = [("model.file", cfg.model.file), ("plc.register_map", cfg.plc.register_map),
             ("source.ati.dbc", cfg.source.ati.dbc)]
    if cfg.source.type == "replay" and cfg.source.replay is not None:
        files.append(("source.replay.file", cfg.source.replay.file))
    for key, rel in files:
        if not cfg.resolve(rel).exists():
            raise ServiceConfigError(f"{src}: {key} = {rel!r}: file {cfg.resolve(rel)} not found")
