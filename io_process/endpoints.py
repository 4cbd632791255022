"""Where the running service answers and how to ask it, for the light commands (the health probe).

A probe that an orchestrator runs every few seconds must cost little, so this module imports the
standard library, pyyaml (through `stiffness.files.yaml_syntax`), and, to read a config, pydantic and the I/O
process's own schemas; never NumPy, the model code or the cycle's schemas. It owns

* the probes of the I/O process's HTTP endpoint, `PROBES` (served by `io_process.monitoring`);
* `read_endpoints`, the reader of the sections a probe asks by, and `read_health`, the HTTP client.

`read_endpoints` validates ``monitoring``, ``plc`` and ``ads`` with the very schemas the service
composes into its config (`MonitoringSettings`, `PlcSettings`, `AdsSettings`, through
`stiffness.files.yaml_schema.validate`), so each refusal is the service's, word for word, and refuses a top-level
key outside the service config's sections as the service does. The other sections' values and the
files the config names (the model, the replay: paths inside an image) are the service's to check at
its start; the probe reads none of them.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import TYPE_CHECKING

from stiffness.errors import ConfigError

if TYPE_CHECKING:
    from collections.abc import Collection

MAX_ANSWER = 64 * 1024      # bytes of an answer read at most: the probes' JSON is a few hundred
# probe -> (HTTP path, the verdict's key in its JSON); `io_process.health` explains each verdict
PROBES: dict[str, tuple[str, str]] = {
    "health": ("/health", "healthy"),
    "live": ("/health/live", "live"),
    "ready": ("/health/ready", "ready"),
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
    from plc_link.register_map import RegisterMap

    return RegisterMap.from_yaml(resolve_path(config_path, relative))


class Endpoints:
    """What `read_endpoints` found: the config file, and its ``monitoring`` (`MonitoringSettings`),
    ``plc`` (`PlcSettings`) and ``ads`` (`AdsSettings`) sections as the service reads them. (A plain class,
    not a dataclass: the probe imports neither dataclasses nor inspect.)"""

    __slots__ = ("ads", "monitoring", "path", "plc")

    def __init__(self, path: Path, monitoring, plc, ads):
        self.path, self.monitoring, self.plc, self.ads = path, monitoring, plc, ads

    def resolve(self, relative: str) -> Path:
        """A path written in the config, found as the service finds it (`resolve_path`)."""
        return resolve_path(self.path, relative)

    def register_map(self):
        """The register map ``plc.register_map`` names (`load_register_map`)."""
        return load_register_map(self.path, self.plc.register_map)


def read_endpoints(path: str | Path, sections: Collection[str] = ()) -> Endpoints:
    """The probe's sections of the service config at ``path`` (`endpoints_from`); ConfigError names the
    file, the key and the value."""
    from stiffness.files.yaml_syntax import read_yaml  # here: a probe that remembers the config reads no YAML

    return endpoints_from(read_yaml(path), Path(path), sections)


def endpoints_from(data: dict, path: Path, sections: Collection[str] = ()) -> Endpoints:
    """``monitoring``, ``plc`` and ``ads`` of a config's mapping ``data`` (read from ``path``, for the
    messages), validated by the service's own schemas; with ``sections``, the service config's top-level
    names, a top-level key outside them is refused in the words the service refuses it with."""
    from plc_link.ads.settings import AdsSettings
    from plc_link.settings import PlcSettings
    from stiffness.files.yaml_schema import validate

    from .settings import MonitoringSettings

    unknown = [k for k in data if sections and k not in sections]
    if unknown:
        from stiffness.files.kinds import looks_like

        like = looks_like(data, sections)
        raise ConfigError(f"{path}: {unknown[0]} is not a known key" + (
            f" of a service config: this file looks like {like} (docs/config.md)" if like else ""))
    schemas = {"monitoring": MonitoringSettings, "plc": PlcSettings, "ads": AdsSettings}
    return Endpoints(path, **{name: validate(schema, data[name], str(path), name) if name in data else schema()
                              for name, schema in schemas.items()})


def read_health(host: str, port: int, probe: str = "health", timeout_s: float = 1.0) -> dict:
    """The JSON of ``probe`` (a key of `PROBES`) from the service's I/O process at ``host:port``, within
    ``timeout_s`` in total.

    One HTTP/1.0 GET on a socket, the whole answer read until the server closes (HTTP/1.0: no chunks, no
    keep-alive; the I/O process serves with wsgiref, `io_process.monitoring`). Not http.client: it imports
    the email package and ssl, some 20 to 40 ms of a probe that an orchestrator runs every few seconds and that
    otherwise costs the interpreter's start and this one request (docs/deploy.md#the-probes-cost).

    Raises OSError when nothing answers in time, ValueError naming the address and the HTTP status when the
    answer is not the probe's JSON (a dict with its verdict key).
    """
    import socket

    path, key = PROBES[probe]
    deadline = time.monotonic() + timeout_s
    request = f"GET {path} HTTP/1.0\r\nHost: {host}:{port}\r\nAccept: application/json\r\n\r\n".encode()
    chunks, size = [], 0
    with socket.create_connection((host, port), timeout=timeout_s) as sock:
        sock.sendall(request)
        while size < MAX_ANSWER:
            sock.settimeout(max(deadline - time.monotonic(), 0.01))
            chunk = sock.recv(MAX_ANSWER - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        if time.monotonic() > deadline:
            raise TimeoutError(f"{host}:{port}{path} took longer than {timeout_s:g} s")
    head, _, body = b"".join(chunks).partition(b"\r\n\r\n")
    status = head.split(b"\r\n", 1)[0].decode("latin-1", "replace").split(" ")
    code = status[1] if len(status) > 1 and status[0].startswith("HTTP/") else "?"
    try:
        answer = json.loads(body)
    except ValueError:
        answer = None
    if not isinstance(answer, dict) or key not in answer:
        raise ValueError(f"{host}:{port}{path} answered HTTP {code} without the {probe} JSON")
    return answer


