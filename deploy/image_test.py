"""`make image-test`: start the built image and check it from the host as a plant would use it.

Checks, one line each: the container starts with a site config from a mounted volume; Docker reports
it healthy (its HEALTHCHECK runs `stiffcomp health --live`); the probe, run inside the container
(3 runs), answers within `PROBE_MAX_S`; ``/health/live`` answers live; ``/health/ready`` answers its
checks consistently and its PLC check turns true once a PLC's heartbeat arrives over Modbus; the cycle
counter rises when read over Modbus and over ADS (pyads, Beckhoff's AdsLib); the metrics endpoint
answers text that prometheus-client's parser reads; `docker stop` (SIGTERM) ends it with exit code
0; the service in it ran the compiled cycle from the kernels the build warmed, its cycle work is as
fast as the same service's on this host, and the real-time options docs/deploy.md gives take
(`image_cycle`; SKIP where this Docker daemon cannot apply them, which fails nothing); the image
carries none of the build's CA certificates, no pip, setuptools, test tools or egg-info, and its size
is printed with the largest packages. Every check runs even when an earlier
one failed, so one run shows everything that is missing. Exit code 0 only if all pass.

The container runs with ``--network host`` (an engine started with ``--bridge=none`` offers nothing
else), so the test picks free ports for Modbus, ADS and HTTP.
"""

from __future__ import annotations

import argparse
import json
import logging
import re
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request
from datetime import datetime
from pathlib import Path

import yaml
from image_cycle import check_compiled, check_cycle, check_realtime, docker

from hil.testing import ROOT, free_port
from io_process.endpoints import PROBES
from io_process.health import READY_CHECKS
from plc_link.register_map import RegisterMap
from tools.block_reader import BlockReader
from tools.pyads_connection import ADS_TCP_PORT, CYCLE_SYMBOL, open_ads, read_cycle_count

SITE = "/etc/stiffcomp"
PROBE_MAX_S = 1.0          # the probe's wall time in the container, median of 3 (the HEALTHCHECK allows 3 s)


class Checks:
    """Prints one line per check and remembers whether all passed."""

    def __init__(self) -> None:
        self.failed: list[str] = []

    def report(self, name: str, ok: bool | None, detail: str) -> bool:
        """``ok`` None: the check cannot run here (SKIP, with why in ``detail``), which fails nothing."""
        print(f"{'SKIP' if ok is None else 'PASS' if ok else 'FAIL'}  {name:<8} {detail}", flush=True)
        if ok is False:
            self.failed.append(name)
        return bool(ok)


def site_config(image: str, folder: Path) -> dict:
    """The image's own starting config with free ports and metrics on, written to ``folder``."""
    cfg = yaml.safe_load(docker("run", "--rm", "--entrypoint", "cat", image, f"{SITE}/service.yaml"))
    cfg["plc"]["host"] = "127.0.0.1"
    cfg["plc"]["port"] = free_port()
    cfg["monitoring"].update(host="127.0.0.1", port=free_port(), metrics=True)
    cfg["ads"].update(host="127.0.0.1", port=free_port())
    cfg["cycle"]["stats_log_interval_s"] = 0
    path = folder / "service.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    folder.chmod(0o755)                      # read by the image's non-root user
    path.chmod(0o644)
    return cfg


def wait_healthy(name: str, timeout_s: float) -> tuple[bool, str]:
    t0 = time.monotonic()
    deadline = t0 + timeout_s
    while True:
        state = json.loads(docker("inspect", "--format", "{{json .State}}", name))
        health = state.get("Health") or {}
        status = health.get("Status", "no healthcheck")
        if not state.get("Running"):
            return False, f"the container stopped (exit code {state.get('ExitCode')})"
        last = (health.get("Log") or [{}])[-1]
        if status == "healthy":
            return True, (f"Docker reports healthy after {time.monotonic() - t0:.0f} s (stiffcomp health --live "
                          f"exit 0; that check took {_took(last):.2f} s with docker's exec)")
        if status == "unhealthy" or time.monotonic() > deadline:
            out = (last.get("Output") or "no health check ran").strip().splitlines()
            return False, f"Docker reports {status} after {timeout_s:g} s at most: {out[-1] if out else ''}"
        time.sleep(0.5)


def _took(entry: dict) -> float:
    """Seconds between a health log entry's Start and End (RFC 3339 with nanoseconds)."""
    def parse(stamp: str) -> datetime:          # Python reads at most microseconds
        return datetime.fromisoformat(re.sub(r"(\.\d{6})\d*", r"\1", stamp))

    try:
        return (parse(entry["End"]) - parse(entry["Start"])).total_seconds()
    except (KeyError, ValueError):
        return float("nan")


# run inside the container: the probe's wall time, 3 runs
_PROBE = r"""
import json, subprocess, sys, time
walls, runs = [], []
for _ in range(3):
    t = time.perf_counter()
    r = subprocess.run(sys.argv[1:], capture_output=True, text=True)
    walls.append(time.perf_counter() - t)
    runs.append((r.returncode, (r.stdout + r.stderr).strip()))
print(json.dumps({"walls": sorted(walls), "runs": runs}))
"""


def check_probe(name: str) -> tuple[bool, str]:
    """`stiffcomp health --live` as the HEALTHCHECK runs it, timed inside the container."""
    got = json.loads(docker("exec", name, "python3", "-c", _PROBE, "stiffcomp", "health", "--live",
                            "--config", f"{SITE}/service.yaml", timeout=60))
    walls, codes = got["walls"], [c for c, _ in got["runs"]]
    median = walls[1]
    ok = median < PROBE_MAX_S and codes == [0, 0, 0]
    return ok, (f"stiffcomp health --live in the container: median {median:.3f} s of 3 (max {walls[-1]:.3f} s, "
                f"bound {PROBE_MAX_S:g} s), exit codes {codes}: {got['runs'][-1][1]}")


def get_json(port: int, path: str) -> tuple[int, dict | None]:
    """(HTTP status, JSON body or None) of ``GET http://127.0.0.1:port/path``."""
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=2.0) as r:
            code, body = r.status, r.read()
    except urllib.error.HTTPError as e:
        code, body = e.code, e.read()
    except OSError:
        return 0, None
    try:
        return code, json.loads(body)
    except ValueError:
        return code, None


def check_live(cfg: dict) -> tuple[bool, str]:
    path = PROBES["live"][0]
    code, body = get_json(cfg["monitoring"]["port"], path)
    ok = code == 200 and body is not None and body.get("live") is True
    return ok, f"{path}: HTTP {code}, {json.dumps(body)}"


def check_ready(cfg: dict) -> tuple[bool, str]:
    """/health/ready names every check and agrees with itself; its PLC check is false until a PLC's
    heartbeat arrives (none has yet), then true once this test writes one over Modbus as a PLC does.
    The deadlines check follows the host's load, so its value is reported, not required."""
    from pymodbus.client import ModbusTcpClient

    path, port = PROBES["ready"][0], cfg["monitoring"]["port"]

    def consistent(code: int, body: dict | None) -> str:
        if body is None or set(body.get("checks", {})) != set(READY_CHECKS):
            return f"HTTP {code} without the checks {', '.join(READY_CHECKS)}: {body}"
        if body["ready"] is not all(body["checks"].values()) or (code == 200) is not body["ready"]:
            return f"HTTP {code} disagrees with its own checks: {body}"
        return ""

    code, before = get_json(port, path)
    if consistent(code, before):
        return False, f"{path}: {consistent(code, before)}"
    if before["checks"]["plc"]:
        return False, f"{path}: the PLC check passed before any PLC wrote a heartbeat: {before}"
    reg = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml").by_name["plc_heartbeat"]
    client = ModbusTcpClient("127.0.0.1", port=cfg["plc"]["port"], timeout=1.0, retries=0)
    deadline, beat, after = time.monotonic() + 10.0, 0, before
    try:
        while not after["checks"]["plc"] and time.monotonic() < deadline:
            beat = (beat + 1) % 65536
            client.write_register(reg.address, beat)
            time.sleep(0.1)
            code, after = get_json(port, path)
            if consistent(code, after):
                return False, f"{path}: {consistent(code, after)}"
    finally:
        client.close()
    ok = after["checks"]["plc"] is True
    return ok, (f"{path}: plc {before['checks']['plc']} -> {after['checks']['plc']} after {beat} heartbeat "
                f"writes; HTTP {code}, ready {after['ready']}: {after['reason']}")


def rises(read, what: str) -> tuple[bool, str]:
    a = read()
    time.sleep(0.5)
    b = read()
    return b > a, f"{what}: cycle count {a} -> {b} in 0.5 s" + ("" if b > a else " (not rising)")


def check_modbus(cfg: dict) -> tuple[bool, str]:
    rmap = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
    reader = BlockReader(rmap, "127.0.0.1", cfg["plc"]["port"], timeout_s=1.0)
    try:
        return rises(lambda: int(reader.read()["cycle_count"]), f"Modbus 127.0.0.1:{cfg['plc']['port']}")
    except ConnectionError as e:
        return False, str(e)
    finally:
        reader.close()


def check_ads(cfg: dict) -> tuple[bool, str]:
    ads = cfg.get("ads") or {}
    port = int(ads.get("port", ADS_TCP_PORT))
    conn, why = open_ads("127.0.0.1", ads.get("net_id", "127.0.0.1.1.1"), int(ads.get("ams_port", 851)), port)
    if conn is None:
        return False, why
    import pyads

    try:
        return rises(lambda: read_cycle_count(conn), f"ADS 127.0.0.1:{port} {CYCLE_SYMBOL}")
    except pyads.ADSError as e:
        return False, f"ADS 127.0.0.1:{port}: {e}"
    finally:
        conn.close()


def check_metrics(cfg: dict) -> tuple[bool, str]:
    from prometheus_client.parser import text_string_to_metric_families

    url = f"http://127.0.0.1:{cfg['monitoring']['port']}/metrics"
    try:
        with urllib.request.urlopen(url, timeout=2.0) as r:
            text = r.read().decode()
    except OSError as e:
        return False, f"no answer at {url} (the I/O process's metrics endpoint): {e}"
    try:
        families = {f.name: f for f in text_string_to_metric_families(text)}
    except ValueError as e:
        return False, f"{url}: prometheus-client's parser refused the text: {e}"
    cycles = families.get("stiffcomp_cycles")
    if cycles is None or not cycles.samples or cycles.samples[0].value <= 0:
        return False, f"{url}: {len(families)} families, but no stiffcomp_cycles_total above 0"
    return True, f"{url}: {len(families)} families, stiffcomp_cycles_total = {cycles.samples[0].value:.0f}"


def check_stop(name: str) -> tuple[bool, str]:
    t0 = time.monotonic()
    docker("stop", "--time", "20", name, timeout=40)
    code = int(docker("inspect", "--format", "{{.State.ExitCode}}", name))
    return code == 0, f"docker stop (SIGTERM): exit code {code} after {time.monotonic() - t0:.1f} s"


# run inside the image: what the build must not have left there, and the largest installed packages
_INSPECT = r"""
import glob, importlib.util, json, os, subprocess, sys
site = glob.glob("/opt/venv/lib/python3*/site-packages")[0]
def du(p):
    return sum(os.path.getsize(os.path.join(d, f)) for d, _, fs in os.walk(p) for f in fs
               if not os.path.islink(os.path.join(d, f)))
sizes = sorted(((du(os.path.join(site, n)), n) for n in os.listdir(site)), reverse=True)
print(json.dumps({
    "site_ca_dir": os.path.exists("/usr/local/share/ca-certificates/stiffcomp"),
    "bundle": open("/etc/ssl/certs/ca-certificates.crt").read() if os.path.exists("/etc/ssl/certs/ca-certificates.crt") else "",
    "modules": [m for m in ("pip", "setuptools", "wheel", "pytest", "hypothesis", "ruff", "pyte")
                if importlib.util.find_spec(m)],
    "base_modules": subprocess.run([sys._base_executable, "-c", "import importlib.util as u; print(' '.join(m for m in "
        "('pip', 'setuptools', 'wheel') if u.find_spec(m)))"], capture_output=True, text=True).stdout.split(),
    "egg_info": glob.glob("/opt/stiffcomp/*.egg-info"),
    "tests_dirs": len(glob.glob(site + "/*/tests")),
    "venv_mb": du("/opt/venv") / 1e6, "largest": [(n, round(b / 1e6)) for b, n in sizes[:6]]}))
"""


def pem_bodies(folder: Path) -> list[str]:
    """The base64 body of each certificate in the build's CA folder (what must not be in the image)."""
    out = []
    for crt in sorted(folder.glob("*.crt")):
        text = crt.read_text(errors="replace")
        for block in text.split("-----BEGIN CERTIFICATE-----")[1:]:
            out.append("".join(block.split("-----END CERTIFICATE-----")[0].split()))
    return out


def check_contents(image: str) -> tuple[bool, str]:
    """No site CA certificate, build tool, test extra or egg-info in the runtime image; its size."""
    got = json.loads(docker("run", "--rm", "--entrypoint", "python3", image, "-c", _INSPECT, timeout=120))
    bundle = "".join(got.pop("bundle").split())
    leaked = [b[:16] for b in pem_bodies(ROOT / "deploy" / "ca-certificates") if b and b in bundle]
    problems = ([f"{len(leaked)} build CA certificate(s) in the trust store"] if leaked else []) \
        + (["/usr/local/share/ca-certificates/stiffcomp exists"] if got["site_ca_dir"] else []) \
        + [f"{m} is installed" for m in got["modules"]] + [f"{e} left" for e in got["egg_info"]] \
        + [f"{m} is installed in the base's Python" for m in got["base_modules"]] \
        + ([f"{got['tests_dirs']} packages keep their tests/"] if got["tests_dirs"] else [])
    size_mb = int(docker("image", "inspect", "--format", "{{.Size}}", image)) / 1e6
    largest = ", ".join(f"{n} {mb} MB" for n, mb in got["largest"])
    detail = f"image {size_mb:.0f} MB, venv {got['venv_mb']:.0f} MB (largest: {largest})"
    return not problems, "; ".join(problems + [detail])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--image", default="stiffcomp")
    ap.add_argument("--healthy-timeout", type=float, default=60.0, metavar="S")
    args = ap.parse_args(argv)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)    # a refused connection is reported once, below
    checks = Checks()
    name = f"stiffcomp-image-test-{int(time.time())}"
    with tempfile.TemporaryDirectory(prefix="stiffcomp-site-") as tmp:
        cfg = site_config(args.image, Path(tmp))
        try:
            cid = docker("run", "-d", "--name", name, "--network", "host", "-v", f"{tmp}:{SITE}:ro", args.image)
            checks.report("start", True, f"container {cid[:12]} from {args.image}, config {SITE}/service.yaml "
                          f"(Modbus {cfg['plc']['port']}, HTTP {cfg['monitoring']['port']})")
            checks.report("healthy", *wait_healthy(name, args.healthy_timeout))
            checks.report("probe", *check_probe(name))
            checks.report("live", *check_live(cfg))
            checks.report("ready", *check_ready(cfg))
            checks.report("modbus", *check_modbus(cfg))
            checks.report("ads", *check_ads(cfg))
            checks.report("metrics", *check_metrics(cfg))
            checks.report("stop", *check_stop(name))
            checks.report("compiled", *check_compiled(name))
            checks.report("cycle", *check_cycle(args.image, cfg, SITE))
            checks.report("realtime", *check_realtime(args.image, cfg, SITE))
            checks.report("contents", *check_contents(args.image))
        finally:
            if checks.failed:
                logs = subprocess.run(["docker", "logs", "--tail", "15", name], check=False, capture_output=True,
                                      text=True)
                print("---- last lines of the container's log ----\n" + (logs.stdout + logs.stderr).strip())
            docker("rm", "-f", name, check=False)
    print("image-test: " + ("all checks passed" if not checks.failed else f"FAILED: {', '.join(checks.failed)}"))
    return 1 if checks.failed else 0


if __name__ == "__main__":
    sys.exit(main())
