"""Where the shipped configuration lives: a module of its own, so that a light command (the health
probe) finds the default config without importing the service's schemas."""

from __future__ import annotations

from plc_interface.endpoints import SHIPPED_CONFIG

DEFAULT_CONFIG = SHIPPED_CONFIG / "default.yaml"
