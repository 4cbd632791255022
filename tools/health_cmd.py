"""`stiffcomp health`: ask the running service whether it is healthy (Docker HEALTHCHECK, systemd, k8s).

Asks the service's I/O process over HTTP (``GET /health`` at ``monitoring.host:monitoring.port``),
not the PLC registers, and gives up after 1 s in total. The endpoint answers JSON::

    {"healthy": true, "reason": "running, no fault, 0.2 % of cycles exceeded over 10 s", ...}

Exit code 0 when healthy, 1 otherwise (also when nothing answers); the reason is printed in one line.

From the config it reads only the sections it needs (`service.config.read_sections`): a site config
copied out of the container names a model and a replay inside the image, which this command never
opens, so it works from the host as docs/deploy.md shows it.
"""

from __future__ import annotations

import http.client

from plc_interface.monitoring import read_health
from service.config import DEFAULT_CONFIG, read_sections

TIMEOUT_S = 1.0
ANY_ADDRESS = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}


def register(sub) -> None:
    p = sub.add_parser("health", help="exit 0 if the running service is healthy, 1 (with the reason) if not")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (its monitoring section)")
    p.add_argument("--host", default=None, help="override monitoring.host")
    p.add_argument("--port", type=int, default=None, help="override monitoring.port")
    p.set_defaults(func=run)


def run(args) -> int:
    mon = read_sections(args.config, "monitoring").monitoring
    host = args.host or ANY_ADDRESS.get(mon.host, mon.host)   # a service bound to all interfaces
    port = args.port or mon.port
    healthy, reason = check(host, port)
    print(f"{'healthy' if healthy else 'unhealthy'}: {reason}")
    return 0 if healthy else 1


def check(host: str, port: int, timeout_s: float = TIMEOUT_S) -> tuple[bool, str]:
    """(healthy, reason) from ``GET http://host:port/health``, within ``timeout_s`` in total."""
    try:
        answer = read_health(host, port, timeout_s)
    except (OSError, http.client.HTTPException):
        return False, f"no answer from the service's I/O process at {host}:{port}"
    except ValueError as e:
        return False, str(e)
    reason = " ".join(str(answer.get("reason") or "no reason given").split())   # one line, always
    return answer["healthy"] is True, reason
