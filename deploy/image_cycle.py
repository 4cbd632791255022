"""`make image-test`'s checks of the compiled cycle: the service in the image runs it, from the kernels the
build warmed, and its cycle work is as fast as the same service's on this host.

* ``compiled``: the container started as shipped logged "compiled signal path ready", never "the cycle
  runs on the Python path", and wrote no compiled kernel while it ran (``docker diff``: no numba cache
  file, no generated module), so it loaded what the build compiled.
* ``cycle``: the same short service (the image's starting config, ports and paths aside) runs
  alternately on this host and in the image, `RUNS` times each for `RUN_S` s, and writes its
  ``--stats-json``; neither side asks for a real-time priority or locked memory (`SAME`), which the
  image's user may lack where this host's root has them. The image's cycle work p50 over the host's, the
  lower of each side's runs (the least disturbed on a shared machine), must stay under `RATIO_MAX`: the
  Python path costs some 3 times the compiled cycle's work, the same compiled code on the same machine
  about 1; and the image's log must show the compiled path.
* ``realtime``: the service in the image started with the options docs/deploy.md gives for real time
  (`REALTIME`) runs its cycle thread with SCHED_FIFO and its memory locked. Docker grants ``--cap-add``
  to root only, so the image's user gets both from resource limits. Skipped (one line saying why) where
  the Docker daemon may not raise those limits.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

import yaml

from hil.testing import ROOT, write_config

RATIO_MAX = 2.0          # image p50 / host p50 of the cycle work
RUN_S = 6.0              # each short service's run
RUNS = 2                 # per side, alternating host and image
PYTHON_PATH = "the cycle runs on the Python path"
READY = re.compile(r"compiled signal path ready in ([0-9.]+) s")
# what a compile writes: numba's index and data files, build.py's generated module
COMPILED_FILE = re.compile(r"\.nb[ic]$|stiffcomp_cycle_[0-9a-f]+\.py$")
SAME = {"realtime_priority": 0, "lock_memory": False}       # the cycle section of both sides' short runs
REALTIME = ("--ulimit", "rtprio=50", "--ulimit", "memlock=-1")


def docker(*args: str, check: bool = True, timeout: float = 60) -> str:
    r = subprocess.run(["docker", *args], check=False, capture_output=True, text=True, timeout=timeout)
    if check and r.returncode != 0:
        raise RuntimeError(f"docker {' '.join(args)}: {r.stderr.strip()}")
    return r.stdout.strip()


def log_verdict(log: str) -> str:
    """'' when the log shows the compiled cycle ready; else what it shows instead, in one line."""
    python = [line[line.index(PYTHON_PATH):] for line in log.splitlines() if PYTHON_PATH in line]
    if python:
        return python[0]
    return "" if READY.search(log) else "no 'compiled signal path ready' line in the log"


def check_compiled(name: str) -> tuple[bool, str]:
    """The stopped container ``name`` ran the compiled cycle from the build's kernels."""
    r = subprocess.run(["docker", "logs", name], capture_output=True, text=True, timeout=30, check=False)
    log = r.stdout + r.stderr
    why = log_verdict(log)
    written = [line.split()[-1] for line in docker("diff", name, timeout=30).splitlines()
               if line[:1] in "AC" and COMPILED_FILE.search(line)]
    compiled = f"it compiled at its start: {len(written)} file(s) written, e.g. {written[0]}" if written else ""
    if why:
        return False, "; ".join(filter(None, [why, compiled]))
    ready = f"compiled signal path ready in {READY.search(log).group(1)} s"
    return not written, f"{ready}; " + (compiled or "nothing compiled at its start (docker diff: no kernel file "
                                                   "written), so the build's kernels were loaded")


def _configs(folder: Path, cfg: dict) -> tuple[Path, Path]:
    """(the image's site folder, the host's config) for the short runs: the image's starting config as the
    site config ``cfg`` has it, and as this host's service reads it (config/default.yaml, its paths
    absolute, written so by the image's build too) with the same servers and ports; both with `SAME`."""
    site = folder / "site"
    site.mkdir(mode=0o755)
    (site / "service.yaml").write_text(yaml.safe_dump({**cfg, "cycle": {**cfg["cycle"], **SAME}}, sort_keys=False))
    (site / "service.yaml").chmod(0o644)
    pick = {"plc": ("host", "port"), "ads": ("host", "port"), "monitoring": ("host", "port", "metrics"),
            "cycle": ("stats_log_interval_s",)}
    overrides = {s: {k: cfg[s][k] for k in keys} for s, keys in pick.items()}
    overrides["cycle"].update(SAME)
    return site, write_config(folder, overrides, name="host.yaml")


def _run_host(config: Path, out: Path) -> tuple[dict | None, str]:
    r = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--config", str(config), "--duration", str(RUN_S),
                        "--stats-json", str(out)], cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    return (json.loads(out.read_text()) if r.returncode == 0 and out.exists() else None), r.stderr


def _run_image(image: str, site: Path, out: Path, site_mount: str, *options: str,
               duration_s: float = RUN_S) -> tuple[dict | None, str]:
    r = subprocess.run(["docker", "run", "--rm", "--network", "host", *options, "-v", f"{site}:{site_mount}:ro",
                        "-v", f"{out.parent}:/out", image, "run", "--config", f"{site_mount}/service.yaml",
                        "--duration", str(duration_s), "--stats-json", f"/out/{out.name}"],
                       capture_output=True, text=True, timeout=180, check=False)
    return (json.loads(out.read_text()) if r.returncode == 0 and out.exists() else None), r.stderr


def _last(log: str) -> str:
    lines = log.strip().splitlines()
    return lines[-1] if lines else "(no output)"


def check_cycle(image: str, cfg: dict, site_mount: str) -> tuple[bool, str]:
    """The image's cycle work p50 against this host's, as the module's docstring says."""
    p50, why = {"image": [], "host": []}, ""
    with tempfile.TemporaryDirectory(prefix="stiffcomp-cycle-") as tmp:
        folder = Path(tmp)
        folder.chmod(0o777)                  # the image's user writes its statistics here
        site, host_cfg = _configs(folder, cfg)
        for k in range(RUNS):
            stats, log = _run_host(host_cfg, folder / f"host{k}.json")
            if stats is None:
                return False, f"the host's service failed: {_last(log)}"
            p50["host"].append(stats["exec_us"]["p50"])
            stats, log = _run_image(image, site, folder / f"image{k}.json", site_mount)
            if stats is None:
                return False, f"the service in the image failed: {_last(log)}"
            p50["image"].append(stats["exec_us"]["p50"])
            why = why or log_verdict(log)
    ratio = min(p50["image"]) / min(p50["host"])
    listed = {side: "/".join(f"{v:.1f}" for v in values) for side, values in p50.items()}
    return ratio <= RATIO_MAX and not why, (
        (f"{why}; " if why else "") + f"cycle work p50: image {listed['image']} us, host {listed['host']} us "
        f"({RUNS} runs of {RUN_S:g} s each, alternating); image/host {ratio:.2f} (bound {RATIO_MAX:g}, the lower "
        "p50 of each side)")


def check_realtime(image: str, cfg: dict, site_mount: str) -> tuple[bool | None, str]:
    """The service in the image with `REALTIME`: SCHED_FIFO and its memory locked (None: not checkable)."""
    with tempfile.TemporaryDirectory(prefix="stiffcomp-rt-") as tmp:
        folder = Path(tmp)
        folder.chmod(0o777)
        site = folder / "site"
        site.mkdir(mode=0o755)
        (site / "service.yaml").write_text(yaml.safe_dump(cfg, sort_keys=False))
        (site / "service.yaml").chmod(0o644)
        stats, log = _run_image(image, site, folder / "rt.json", site_mount, *REALTIME, duration_s=1.0)
    flags = " ".join(REALTIME)
    refused = re.search(r"error setting rlimit.*?: operation not permitted", log)
    if stats is None and refused:
        return None, f"not checked: this Docker daemon may not raise the limits of {flags} ({refused.group(0)})"
    lines = [line for line in log.splitlines() if "SCHED_FIFO" in line or "mlockall" in line]
    ok = stats is not None and any("runs with SCHED_FIFO" in line for line in lines) and \
        not any("cannot" in line for line in lines)
    return ok, f"{flags}: " + ("; ".join(line.split(": ", 1)[-1] for line in lines) or _last(log))
