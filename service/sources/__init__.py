"""F/T sources: name -> backend, imported lazily (a CAN backend needs python-can's interface only when used)."""

from __future__ import annotations

import importlib

from .base import FtSource

SOURCES = {
    "can": "service.sources.can_source:CanSource",
    "replay": "service.sources.replay:ReplaySource",
}


def source_class(name: str) -> type[FtSource]:
    module, cls = SOURCES[name].split(":")
    return getattr(importlib.import_module(module), cls)


def make_source(cfg) -> FtSource:
    """Build the source named by ``cfg.source.type`` from the whole service config."""
    return source_class(cfg.source.type).from_config(cfg)


__all__ = ["SOURCES", "FtSource", "make_source", "source_class"]
