"""Where the shipped configuration lives: a module of its own, so that a light command (the health
probe) finds the default config without importing the service's schemas."""

from __future__ import annotations

from pathlib import Path

CONFIG_DIR = Path(__file__).resolve().parent.parent / "config"
DEFAULT_CONFIG = CONFIG_DIR / "default.yaml"
SHIPPED_REGISTER_MAP = CONFIG_DIR / "registers.yaml"
