"""`stiffcomp health [--live | --ready]`: ask the running service (Docker HEALTHCHECK, systemd, k8s).

Three questions, one verdict each (`io_process.health` defines them; ready implies healthy
implies live):

* ``--live``: is the task alive (the cycle count rises, the I/O process answers)? The image's
  HEALTHCHECK asks this: only a dead or stuck task is worth a restart.
* no option: ``/health``: running, no fault, deadlines within the bound.
* ``--ready``: healthy, and the sensor fresh and the PLC's heartbeat seen: rely on the correction.

It asks the service's I/O process over HTTP (``GET /health``, ``/health/live`` or ``/health/ready`` at
``monitoring.host:monitoring.port``), and gives up after 1 s in total. Where the config switches HTTP
off (``monitoring.enabled: false``), it reads the to_plc block twice instead, by what the service
serves: plain Modbus TCP; else Modbus/TCP Security with the client certificate ``plc.tls.probe_cert``
names; else ADS; and judges it as the I/O process would. Exit code 0 when the verdict passes, 1 when
not (also when nothing answers), 2 when the config is bad or offers no way to ask; the reason is
printed in one line.

A probe runs every few seconds, so this command stays light: it reads the ``monitoring``, ``plc`` and
``ads`` sections with the service's own schemas (`io_process.endpoints.read_endpoints`), so it
refuses what the service refuses there, and a top-level key the service does not know, and never
imports NumPy, scipy or the model (tests/tools/test_health_cmd.py holds its import set). A config it has
validated, unchanged since (its bytes and the code the validation imported), is not validated again:
`tools.health_memo` keeps the monitoring address, and that probe imports neither pydantic nor pyyaml. A
site config copied out of the container names a model and a replay inside the image, which this command
never opens, so it works from the host as docs/deploy.md shows it.
"""

from __future__ import annotations

import sys
import time

from io_process.endpoints import PROBES, Endpoints, read_endpoints, read_health
from service.paths import DEFAULT_CONFIG, SECTIONS
from stiffness.errors import ConfigError

from .health_memo import digest, recall, remember

TIMEOUT_S = 1.0
MODBUS_GAP_S = 0.2          # between the two readings of the Modbus block: the count must rise in it
ANY_ADDRESS = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}
WORDS = {"health": ("healthy", "unhealthy"), "live": ("live", "not live"), "ready": ("ready", "not ready")}


def register(sub) -> None:
    p = sub.add_parser("health", help="exit 0 if the running service is healthy (--live: alive, --ready: "
                       "ready), 1 with the reason if not")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (its monitoring, plc and ads keys)")
    which = p.add_mutually_exclusive_group()
    which.add_argument("--live", dest="probe", action="store_const", const="live",
                       help="liveness: the cycle count rises (what a restart could fix)")
    which.add_argument("--ready", dest="probe", action="store_const", const="ready",
                       help="readiness: healthy, the sensor fresh and the PLC's heartbeat seen")
    p.add_argument("--host", default=None, help="override monitoring.host (without HTTP: the host of the "
                   "Modbus, Modbus/TCP Security or ADS server it asks)")
    p.add_argument("--port", type=int, default=None, help="override monitoring.port (without HTTP: the "
                   "port of the Modbus, Modbus/TCP Security or ADS server it asks)")
    p.set_defaults(func=run, probe="health")


def run(args) -> int:
    try:
        check_options(args)
        http = recall(args.config)          # a config validated before and unchanged since: no schema import
        if http is None:
            before = digest(args.config)
            ep = read_endpoints(args.config, SECTIONS)
            if ep.monitoring.enabled:
                http = ep.monitoring.host, ep.monitoring.port
                if before is not None:
                    remember(args.config, before, *http)
        if http is not None:
            passed, reason = check(*address(*http, args), probe=args.probe)
        else:
            passed, reason = check_block(ep, reader_for(ep, args), probe=args.probe)
    except ConfigError as e:
        print(f"stiffcomp health: error: {e}", file=sys.stderr)
        return 2
    print(f"{WORDS[args.probe][0 if passed else 1]}: {reason}")
    return 0 if passed else 1


def check_options(args) -> None:
    """``--host`` and ``--port`` checked as the config's keys are, by the schema of the section they stand
    for (a port 1 to 65535); ConfigError naming the option."""
    given = {k: v for k, v in (("host", args.host), ("port", args.port)) if v is not None}
    if not given:                   # nothing to check: the probe of every few seconds imports no schema for it
        return
    from pydantic import ValidationError

    from io_process.settings import MonitoringSettings

    try:
        MonitoringSettings.model_validate(given)
    except ValidationError as e:
        key = e.errors()[0]["loc"][0]
        raise ConfigError(f"--{key} {given[key]}: {e.errors()[0]['msg']}") from e


def address(host: str, port: int, args) -> tuple[str, int]:
    """(host, port) to ask: the overrides, else the config's, a bind to all interfaces meaning here."""
    return args.host or ANY_ADDRESS.get(host, host), args.port or port


def check(host: str, port: int, timeout_s: float = TIMEOUT_S, probe: str = "health") -> tuple[bool, str]:
    """(passed, reason) of ``probe`` (a key of `PROBES`) over HTTP, within ``timeout_s`` in total."""
    try:
        answer = read_health(host, port, probe, timeout_s)
    except OSError:
        return False, f"no answer from the service's I/O process at {host}:{port}"
    except ValueError as e:
        return False, str(e)
    return answer[PROBES[probe][1]] is True, one_line(answer.get("reason"))


def reader_for(ep: Endpoints, args):
    """The reader of the to_plc block by what the service serves without HTTP: plain Modbus TCP, else
    Modbus/TCP Security with the client certificate ``plc.tls.probe_cert`` names, else ADS (imported here:
    pymodbus, pyads and the register map cost more than the HTTP path, which most configs use).
    ConfigError naming the keys when the service serves none of them to this probe."""
    import logging

    from .block_reader import AdsReader, BlockReader

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)     # the reason says it in one line
    plc, tls, ads = ep.plc, ep.plc.tls, ep.ads
    if plc.role == "server" and (not tls.enabled or tls.plain):
        return BlockReader(ep.register_map(), *address(plc.host, plc.port, args), timeout_s=TIMEOUT_S / 2)
    if plc.role == "server" and tls.probe_cert is not None:
        return BlockReader(ep.register_map(), *address(plc.host, tls.port, args), timeout_s=TIMEOUT_S / 2,
                           sslctx=probe_context(ep))
    served = (f"plc.role is {plc.role}" if plc.role != "server" else
              "plc.tls serves Modbus/TCP Security alone (plain: false) and names no probe_cert")
    if not ads.enabled:
        hint = ", or name a client certificate in plc.tls.probe_cert and probe_key" if plc.role == "server" else ""
        raise ConfigError(f"{ep.path}: monitoring.enabled is false, {served}, and ads.enabled is false: the "
                          f"service answers no probe (switch monitoring on{hint}; docs/deploy.md#health)")
    try:
        return AdsReader(ep.register_map(), *address(ads.host, ads.port, args), ads.net_id, ads.ams_port)
    except ValueError as e:
        raise ConfigError(f"{ep.path}: monitoring.enabled is false and {served}: only ADS is left to ask, "
                          f"and {e}") from None


def probe_context(ep: Endpoints):
    """The TLS context of the probe's client certificate (``plc.tls.probe_cert``, ``probe_key``), checking
    the server against ``plc.tls.ca``; ConfigError naming the keys when the files do not load."""
    from io_base.tls import client_context

    tls = ep.plc.tls
    files = {k: str(ep.resolve(getattr(tls, k))) for k in ("ca", "probe_cert", "probe_key")}
    try:
        return client_context(files["ca"], files["probe_cert"], files["probe_key"], check_hostname=False)
    except OSError as e:            # ssl.SSLError among them
        why = f"{e.strerror}: {e.filename}" if e.filename else str(e)
        raise ConfigError(f"{ep.path}: plc.tls.probe_cert = {files['probe_cert']}, probe_key = "
                          f"{files['probe_key']}, ca = {files['ca']}: not a client certificate, its key and "
                          f"a CA that load ({why})") from e


def check_block(ep: Endpoints, reader, probe: str = "health", gap_s: float = MODBUS_GAP_S) -> tuple[bool, str]:
    """(passed, reason) of ``probe`` from two readings of the to_plc block ``gap_s`` apart by ``reader``
    (`reader_for`), judged by the I/O process's own `HealthMonitor`."""
    from io_process.health import HealthMonitor

    # a count that rose between the two readings is live; one that did not has stalled for gap_s
    monitor = HealthMonitor(ep.monitoring.health_max_exceed_rate, stall_s=gap_s / 2)
    try:
        monitor.update(time.monotonic(), reader.read())
        time.sleep(gap_s)
        t = time.monotonic()
        monitor.update(t, reader.read())
    except ConnectionError as e:
        return False, one_line(e)
    finally:
        reader.close()
    verdict = monitor.verdicts(t)[probe]
    return verdict[PROBES[probe][1]] is True, one_line(verdict["reason"]) + f" ({reader.what} {reader.where})"


def one_line(reason) -> str:
    return " ".join(str(reason or "no reason given").split())
