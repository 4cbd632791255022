"""Where the shipped configuration lives, and the names of the service config's sections: a module of
its own, so that a light command (the health probe) finds the default config and refuses a misspelt
section without importing the service's schemas."""

from __future__ import annotations

from io_process.endpoints import SHIPPED_CONFIG

DEFAULT_CONFIG = SHIPPED_CONFIG / "default.yaml"

# the service config's top-level sections: `service.config.ServiceConfig`'s fields (a test holds them equal)
SECTIONS = ("cycle", "model", "source", "filter", "gravity", "limits", "faults", "tare", "dynamics", "accelerometer",
            "plc", "ads", "monitoring", "robot")
