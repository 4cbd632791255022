"""The service config (config/default.yaml): the sections composed into one schema that rejects unknown keys.

Each section's schema lives beside the class that reads it (``cycle`` in `service.task`, ``model`` in
`service.compensation`, ``source`` in `service.sources` with each backend's and the sensor protocol's
beside them, ``filter`` in `service.filters`, ``gravity`` in `service.gravity`, ``limits`` in
`service.limits`, ``faults`` in `service.supervision`, and the PLC, ADS and monitoring settings in
`plc_interface`). Each class's ``from_config`` factory receives its own section, reads what it needs
in its constructor and keeps no reference to the config. Here are only the composition and the checks
that involve more than one section. Errors name the file, the key, the value and the allowed range, e.g.::

    config/default.yaml: filter.cutoff_hz = 900 must be below half the cycle rate (500 Hz)

Paths in the file (model, replay log, register map, DBC) are relative to the config file; a relative
path with nothing there names the shipped config/ folder's file (`SHIPPED`), so a copy of
config/default.yaml in a site folder still finds the shipped model, register map, DBC and replay, and a
file put beside the copy takes precedence (docs/config.md, "Paths").
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from pydantic import Field, ValidationError

from io_process.endpoints import SHIPPED_CONFIG, load_register_map, resolve_path
from io_process.settings import MonitoringSettings
from plc_link.ads.settings import AdsSettings
from plc_link.errors import RegisterMapError
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings
from robot_road.settings import RobotSettings
from stiffness.errors import StiffnessError, quote
from stiffness.files.kinds import looks_like
from stiffness.files.yaml_schema import Strict, format_validation_error, read_yaml

from .accelerometer import AccelerometerConfig
from .compensation import ModelConfig
from .dynamics import DynamicsConfig
from .errors import ServiceConfigError
from .filters import FilterConfig
from .gravity import GravityConfig
from .limits import LimitsConfig
from .paths import DEFAULT_CONFIG
from .pipeline import TareConfig
from .sources import SourceConfig
from .supervision import FaultsConfig
from .task import CycleConfig

SHIPPED = SHIPPED_CONFIG                # the shipped config/ folder: where a relative path not beside the file goes


class ServiceConfig(Strict):
    cycle: CycleConfig = Field(default_factory=CycleConfig)
    model: ModelConfig
    source: SourceConfig
    filter: FilterConfig = Field(default_factory=FilterConfig)
    gravity: GravityConfig = Field(default_factory=GravityConfig)
    limits: LimitsConfig = Field(default_factory=LimitsConfig)
    faults: FaultsConfig = Field(default_factory=FaultsConfig)
    tare: TareConfig = Field(default_factory=TareConfig)
    dynamics: DynamicsConfig = Field(default_factory=DynamicsConfig)
    accelerometer: AccelerometerConfig = Field(default_factory=AccelerometerConfig)
    plc: PlcSettings = Field(default_factory=PlcSettings)
    ads: AdsSettings = Field(default_factory=AdsSettings)
    monitoring: MonitoringSettings = Field(default_factory=MonitoringSettings)
    robot: RobotSettings = Field(default_factory=RobotSettings)

    # set by load_config: where the file was, for relative paths and messages
    path: Path = Field(default=Path("<config>"), exclude=True)

    def resolve(self, relative: str) -> Path:
        """A path written in the config: relative to the config file's folder, else to the shipped
        config/ folder where only that has the file (module docstring)."""
        return _resolve(self.path, relative)

    def files(self) -> dict[str, str]:
        """Every file the config names and uses, by dotted key, as written (`resolve` finds it)."""
        files = {"model.file": self.model.file, "plc.register_map": self.plc.register_map,
                 "source.ati.dbc": self.source.ati.dbc}
        if self.source.type == "replay" and self.source.replay is not None:
            files["source.replay.file"] = self.source.replay.file
        if self.accelerometer.replay:                  # (given only with enabled)
            files["accelerometer.replay"] = self.accelerometer.replay
        ff = self.dynamics.feedforward
        if self.dynamics.enabled and ff is not None and ff.file is not None:
            files["dynamics.feedforward.file"] = ff.file
        files |= {f"plc.tls.{k}": v for k, v in self.plc.tls.files().items()}
        return files

    @property
    def cycle_enables_on_start(self) -> bool:
        """Whether the cycle acts as if the enable bit were set: ``plc.enable_on_start``, except where the robot
        road writes the command word (``plc.role: none`` with a robot interface). There the road sets the enable
        bit itself, the robot's own where it sends a command element, so that a robot program's 0 switches the
        correction off (docs/robot.md)."""
        return self.plc.enable_on_start and not (self.robot.enabled and self.plc.role == "none")

    @property
    def commander(self) -> str:
        """Who writes the command word and the heartbeat, as messages name it: the PLC, or (``plc.role: none`` with
        a robot interface) the robot, whose packets are the heartbeat."""
        if self.robot.enabled and self.plc.role == "none":
            return f"the robot ({self.robot.declaration.title} packets)"
        return "the PLC"

    def register_map(self) -> RegisterMap:
        """The register map ``plc.register_map`` names; a bad or missing map raises ServiceConfigError
        naming this config file, the key and its value, then what is wrong in the map."""
        return _register_map(self.path, self.plc.register_map)


def _resolve(config_path: Path, relative: str) -> Path:
    return resolve_path(config_path, relative)


def _register_map(config_path: Path, relative: str) -> RegisterMap:
    try:
        return load_register_map(config_path, relative)
    except RegisterMapError as e:
        raise ServiceConfigError(f"{config_path}: plc.register_map = {quote(relative)}: {e}") from e


class ConfigSections(SimpleNamespace):
    """Some top-level sections of a service config (`read_sections`), with ``path``, ``resolve`` and
    ``register_map`` as `ServiceConfig` has them."""

    def resolve(self, relative: str) -> Path:
        return _resolve(self.path, relative)

    def register_map(self) -> RegisterMap:
        return _register_map(self.path, self.plc.register_map)


def _read(path: Path) -> dict:
    """The config file's mapping through the one YAML loader; ServiceConfigError names the file, and what the
    file looks like when it is another of the project's files (a register map passed as the config)."""
    if not path.exists():
        raise ServiceConfigError(f"{path}: config file not found")
    try:
        data = read_yaml(path)
    except StiffnessError as e:
        raise ServiceConfigError(str(e)) from e
    check_kind(path, data)
    return data


def check_kind(path: Path, data: dict) -> None:
    """ServiceConfigError naming the first key that is not a section and what the file looks like, when its
    top-level keys are more another kind's (`stiffness.files.kinds`) than a service config's."""
    like = looks_like(data, ServiceConfig.model_fields)
    if like is not None:
        key = next(k for k in data if k not in ServiceConfig.model_fields)
        raise ServiceConfigError(f"{path}: {key} is not a known key of a service config: this file looks like "
                                 f"{like} (docs/config.md)")


def read_sections(path: str | Path, *names: str) -> ConfigSections:
    """Only the named top-level sections of a service config (e.g. ``plc``, ``ads``, ``monitoring``),
    validated as the service validates them; nothing else in the file is read or checked and no file
    it names is opened. So a site config copied out of the container, whose model and replay are
    paths inside the image, serves the host-side `health` and `status` (docs/deploy.md).
    ServiceConfigError names the file, key and value."""
    path = Path(path)
    data = _read(path)
    out = ConfigSections(path=path)
    for name in names:
        section = ServiceConfig.model_fields[name].annotation
        try:
            setattr(out, name, section.model_validate(data.get(name) or {}))
        except ValidationError as e:
            raise ServiceConfigError(format_validation_error(str(path), e, name, section, data.get(name))) from e
    return out


def load_config(path: str | Path | None = None) -> ServiceConfig:
    """Read and validate the service config; ServiceConfigError names file, key, value and range."""
    path = Path(path) if path is not None else DEFAULT_CONFIG
    data = _read(path)
    if "path" in data:
        raise ServiceConfigError(f"{path}: path is not a known key")
    try:
        cfg = ServiceConfig.model_validate(data)
    except ValidationError as e:
        raise ServiceConfigError(format_validation_error(str(path), e, schema=ServiceConfig, data=data)) from e
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
    r = cfg.robot
    rt = cfg.cycle.realtime_priority
    if r.enabled and r.realtime_priority > 0 and rt > 0 and r.realtime_priority >= rt:
        raise ServiceConfigError(f"{src}: robot.realtime_priority = {r.realtime_priority} must be below "
                                 f"cycle.realtime_priority ({rt}): the 1 ms cycle comes first")
    if r.enabled and 0 < hb <= 2 * r.cycle_ms:
        raise ServiceConfigError(f"{src}: faults.plc_heartbeat_timeout_ms = {hb:g} must be 0 (off) or longer than two "
                                 f"of the robot's cycles ({r.interface} cycle_ms = {r.cycle_ms}): the robot's silence "
                                 "is what it counts")
    missing = [f"{key} = {quote(rel)}" for key, rel in cfg.files().items() if not cfg.resolve(rel).exists()]
    if missing:
        raise ServiceConfigError(
            f"{src}: {len(missing)} file(s) it names not found (a relative path is looked up beside it, in "
            f"{cfg.path.parent}/, then in the shipped {SHIPPED}/; an absolute path as written):\n  "
            + "\n  ".join(missing))
