"""The ``monitoring:`` section of the config: the I/O process's HTTP endpoint."""

from __future__ import annotations

from pydantic import Field

from io_base.settings import PORT_MAX, PORT_MIN
from stiffness.files.yaml_schema import Strict


class MonitoringSettings(Strict):
    """The I/O process's HTTP endpoint: /health, /health/live and /health/ready always, /metrics
    (Prometheus) when ``metrics``."""

    enabled: bool = True
    host: str = "127.0.0.1"
    port: int = Field(9020, ge=PORT_MIN, le=PORT_MAX)
    metrics: bool = False
    health_max_exceed_rate: float = Field(0.05, ge=0.0, le=1.0)
