"""Where the running service answers and how to ask it, for the light commands (the health probe).

A probe that an orchestrator runs every few seconds must cost milliseconds, so this module imports
the standard library, pyyaml (through `stiffness.yamlread`) and nothing else: no pydantic, no NumPy,
no model code. It owns

* the reading of the keys a probe reads, whose defaults `MonitoringEndpoint` and `PlcEndpoint` hold
  (`plc_interface.defaults`; the schemas in `plc_interface.settings` take theirs from there too);
* the probes of the I/O process's HTTP endpoint, `PROBES` (served by `plc_interface.monitoring`);
* `read_endpoints`, the light reader of those keys, and `read_probe`, the HTTP client.

`read_endpoints` reads only ``monitoring.enabled``, ``.host``, ``.port``, ``.health_max_exceed_rate``
and ``plc.role``, ``.host``, ``.port``, ``.register_map``. A plain value (an integer port in range, a
boolean, a string) is taken as it is; any other value is handed to the service's own schema, so the
probe accepts exactly what the service accepts, with the same message naming the file, the key and
the value. Every other key is left to the service, which refuses the whole file at its start when
anything in it is wrong.
"""

from __future__ import annotations

import http.client
import json
import math
import time
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

from stiffness.errors import ConfigError, quote
from stiffness.yamlread import read_yaml

from .defaults import PLC_ROLES, PORT_MAX, PORT_MIN, MonitoringEndpoint, PlcEndpoint

# probe -> (HTTP path, the verdict's key in its JSON); `plc_interface.health` explains each verdict
PROBES: dict[str, tuple[str, str]] = {
    "health": ("/health", "healthy"),
    "live": ("/health/live", "live"),
    "ready": ("/health/ready", "ready"),
}


def _number(v: Any) -> bool:
    return type(v) in (int, float) and math.isfinite(v)


# key -> the values the schema takes exactly as they are: the fast path; any other value is decided by
# the schema itself (pydantic, imported only then), so the probe accepts what the service accepts
_PLAIN = {
    "enabled": lambda v: type(v) is bool,
    "host": lambda v: type(v) is str,
    "port": lambda v: type(v) is int and PORT_MIN <= v <= PORT_MAX,
    "health_max_exceed_rate": lambda v: _number(v) and 0.0 <= v <= 1.0,
    "role": lambda v: v in PLC_ROLES and type(v) is str,
    "register_map": lambda v: type(v) is str,
}


SHIPPED_CONFIG = Path(__file__).resolve().parent.parent / "config"   # the shipped config/ folder


def resolve_path(config_path: Path, relative: str) -> Path:
    """A path written in a service config: as written when absolute; else beside the config file, or, where
    only the shipped config/ folder has the file, there (so a copy of config/default.yaml in a site folder
    still finds the shipped model, map, DBC and replay; a file put beside the copy takes precedence). The
    one rule the service (`service.config`) and the health probe share."""
    p = Path(relative)
    if p.is_absolute():
        return p
    beside = Path(config_path).parent / p
    if beside.exists() or ".." in p.parts:
        return beside
    shipped = SHIPPED_CONFIG / p
    return shipped if shipped.exists() else beside


def load_register_map(config_path: Path, relative: str):
    """The register map a service config at ``config_path`` names (``plc.register_map`` = ``relative``);
    RegisterMapError on a bad map. The one place the config's map is read (the service's config and the
    probe call it)."""
    from .register_map import RegisterMap

    return RegisterMap.from_yaml(resolve_path(config_path, relative))


@dataclass(frozen=True)
class Endpoints:
    """What `read_endpoints` found: the config file, and its ``monitoring`` and ``plc`` keys."""

    path: Path
    monitoring: MonitoringEndpoint
    plc: PlcEndpoint

    def register_map(self):
        """The register map ``plc.register_map`` names (`load_register_map`)."""
        return load_register_map(self.path, self.plc.register_map)


def read_endpoints(path: str | Path) -> Endpoints:
    """The probe's keys of the service config at ``path``; ConfigError names the file, key and value."""
    return endpoints_from(read_yaml(path), Path(path))


def endpoints_from(data: dict, path: Path) -> Endpoints:
    """The probe's keys of a config's mapping ``data``, read from ``path`` (for the messages)."""
    return Endpoints(path, _section(path, data, "monitoring", MonitoringEndpoint),
                     _section(path, data, "plc", PlcEndpoint))


def _section(path: Path, data: dict, name: str, cls):
    section = data.get(name)
    if section is None:
        section = {}
    if not isinstance(section, dict):
        raise ConfigError(f"{path}: {name} = {quote(section)}: expected a mapping")
    values = {k: section[k] for k in (f.name for f in fields(cls)) if k in section}
    odd = {k: v for k, v in values.items() if not _PLAIN[k](v)}
    if odd:
        values.update(_validated(path, name, odd))
    return cls(**{k: float(v) if k == "health_max_exceed_rate" else v for k, v in values.items()})


def _validated(path: Path, name: str, values: dict) -> dict:
    """``values`` as the service's schema reads them; ConfigError with the schema's message if it refuses."""
    from pydantic import ValidationError

    from stiffness.yamlio import format_validation_error

    from .settings import MonitoringSettings, PlcSettings

    schema = {"monitoring": MonitoringSettings, "plc": PlcSettings}[name]
    try:
        parsed = schema.model_validate(values)
    except ValidationError as e:
        raise ConfigError(format_validation_error(str(path), e, prefix=name)) from e
    return {k: getattr(parsed, k) for k in values}


def read_probe(host: str, port: int, probe: str = "health", timeout_s: float = 1.0) -> dict:
    """The JSON of ``probe`` (a key of `PROBES`) from the service's I/O process at ``host:port``, within
    ``timeout_s`` in total.

    Raises OSError (or http.client.HTTPException) when nothing answers in time, ValueError naming the
    address and the HTTP status when the answer is not the probe's JSON (a dict with its verdict key).
    """
    path, key = PROBES[probe]
    deadline = time.monotonic() + timeout_s
    conn = http.client.HTTPConnection(host, port, timeout=timeout_s)
    try:
        conn.connect()
        conn.sock.settimeout(max(deadline - time.monotonic(), 0.01))
        conn.request("GET", path, headers={"Accept": "application/json"})
        resp = conn.getresponse()
        body = resp.read(64 * 1024)
        if time.monotonic() > deadline:
            raise TimeoutError(f"{host}:{port}{path} took longer than {timeout_s:g} s")
    finally:
        conn.close()
    try:
        answer = json.loads(body)
    except ValueError:
        answer = None
    if not isinstance(answer, dict) or key not in answer:
        raise ValueError(f"{host}:{port}{path} answered HTTP {resp.status} without the {probe} JSON")
    return answer
