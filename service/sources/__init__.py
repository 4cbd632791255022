"""F/T sources: name -> backend, each with its section schema beside it; `SourceConfig` is the ``source``
section. python-can loads a bus interface only when a CAN source opens it."""

from __future__ import annotations

import importlib
from typing import Literal

from pydantic import Field, model_validator

from stiffness.files.yaml_schema import Strict

from ..ati import AtiConfig
from .base import FtSource
from .can_source import CanConfig
from .replay import ReplayConfig

# name -> the backend's class, imported only when used; the config's ``source.type`` takes these names
SOURCES = {
    "replay": "service.sources.replay:ReplaySource",
    "can": "service.sources.can_source:CanSource",
}


def source_class(name: str) -> type[FtSource]:
    module, cls = SOURCES[name].split(":")
    return getattr(importlib.import_module(module), cls)


class SourceConfig(Strict):
    """``source``: which backend, its section, the sensor's protocol and its measuring range."""

    type: Literal[tuple(SOURCES)] = "replay"
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


def make_source(cfg) -> FtSource:
    """The source named by ``cfg.source.type``, from its section (the service config composes them)."""
    return source_class(cfg.source.type).from_config(cfg.source, cfg.faults.sensor_timeout_ms / 1000.0, cfg.resolve)


__all__ = ["SOURCES", "FtSource", "SourceConfig", "make_source", "source_class"]
