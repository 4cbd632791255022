"""`stiffcomp health`: ask the running service whether it is healthy (Docker HEALTHCHECK, systemd, k8s).

Asks the service's I/O process over HTTP (``GET /health`` at ``monitoring.host:monitoring.port``),
not the PLC registers, and gives up after 1 s in total. The endpoint answers JSON::

    {"healthy": true, "reason": "running, no fault, 0.2 % of cycles exceeded over 10 s", ...}

Exit code 0 when healthy, 1 otherwise (also when nothing answers); the reason is printed in one line.

From the config it reads only the sections it needs (`read_sections`): a site config copied out of the
container names a model and a replay inside the image, which this command never opens, so it works
from the host as docs/deploy.md shows it.
"""

from __future__ import annotations

import http.client
import json
import time
from pathlib import Path
from types import SimpleNamespace

from pydantic import ValidationError

from service.config import DEFAULT_CONFIG, ServiceConfig
from service.errors import ServiceConfigError
from stiffness.errors import StiffnessError
from stiffness.yamlio import format_validation_error, read_yaml

TIMEOUT_S = 1.0
ANY_ADDRESS = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}


def register(sub) -> None:
    p = sub.add_parser("health", help="exit 0 if the running service is healthy, 1 (with the reason) if not")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (its monitoring section)")
    p.add_argument("--host", default=None, help="override monitoring.host")
    p.add_argument("--port", type=int, default=None, help="override monitoring.port")
    p.set_defaults(func=run)


def read_sections(path: str | Path, *names: str) -> SimpleNamespace:
    """Only the named top-level sections of a service config (``plc``, ``ads``, ``monitoring``), validated
    as the service validates them; nothing else in the file is read or checked, no file it names is opened.

    Returns a namespace with those sections, ``path`` and ``resolve(relative)`` (relative to the file);
    ServiceConfigError names the file, key and value."""
    path = Path(path)
    if not path.exists():
        raise ServiceConfigError(f"{path}: config file not found")
    try:
        data = read_yaml(path)
    except StiffnessError as e:
        raise ServiceConfigError(str(e)) from e
    out = SimpleNamespace(path=path, resolve=lambda rel: Path(rel) if Path(rel).is_absolute() else path.parent / rel)
    for name in names:
        model = ServiceConfig.model_fields[name].annotation
        try:
            setattr(out, name, model.model_validate(data.get(name) or {}))
        except ValidationError as e:
            raise ServiceConfigError(format_validation_error(str(path), e, prefix=name)) from e
    return out


def run(args) -> int:
    mon = read_sections(args.config, "monitoring").monitoring
    host = args.host or ANY_ADDRESS.get(mon.host, mon.host)   # a service bound to all interfaces
    port = args.port or mon.port
    healthy, reason = check(host, port)
    print(f"{'healthy' if healthy else 'unhealthy'}: {reason}")
    return 0 if healthy else 1


def check(host: str, port: int, timeout_s: float = TIMEOUT_S) -> tuple[bool, str]:
    """(healthy, reason) from ``GET http://host:port/health``, within ``timeout_s`` in total."""
    deadline = time.monotonic() + timeout_s
    conn = http.client.HTTPConnection(host, port, timeout=timeout_s)
    try:
        conn.connect()
        conn.sock.settimeout(max(deadline - time.monotonic(), 0.01))
        conn.request("GET", "/health", headers={"Accept": "application/json"})
        resp = conn.getresponse()
        body = resp.read(64 * 1024)
        if time.monotonic() > deadline:
            raise TimeoutError
    except (OSError, http.client.HTTPException):
        return False, f"no answer from the service's I/O process at {host}:{port}"
    finally:
        conn.close()
    try:
        answer = json.loads(body)
        healthy = answer["healthy"]
    except (ValueError, KeyError, TypeError):
        return False, f"{host}:{port}/health answered HTTP {resp.status} without the health JSON"
    reason = " ".join(str(answer.get("reason") or "no reason given").split())   # one line, always
    return healthy is True, reason
