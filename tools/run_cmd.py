"""`stiffcomp run`: the cyclic compensation service (docs/service.md).

Validates the whole config before anything starts (a bad config exits with code 2), then runs
until --duration elapses, Ctrl-C or SIGTERM (``--check`` stops after the validation and the checks of this machine a start needs, `service.preflight`:
nothing started, no port kept open); both stop it cleanly (the correction ramps to zero) with
exit code 0. SIGHUP reloads the config file (`Service.on_hangup`, docs/service.md): the run file
(`tools.run_file`) tells `stiffcomp reload` this process's pid and each reload's outcome. Between its
waits the main thread watches the I/O process (`Service.watch_io`); exit code 1 when the service failed
(the cycle died, or the I/O process died beyond faults.io_restarts), and --stats-json says why
(``failure``, ``io_process``).
"""

from __future__ import annotations

import logging
import signal
import threading
import time

from io_base.log_format import FORMATTERS, configure_logging
from service.config import DEFAULT_CONFIG, load_config

from .run_file import RunFile


def register(sub) -> None:
    p = sub.add_parser("run", help="run the cyclic compensation service")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (default: config/default.yaml)")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="stop after S seconds of cycles (counted from the first cycle)")
    p.add_argument("--check", action="store_true",
                   help="validate the config and everything it names as a start does (model, register map, "
                        "source), then exit 0 without starting anything or opening a port")
    p.add_argument("--stats-json", default=None, metavar="FILE", help="write the task statistics on exit")
    p.add_argument("--log-level", default="INFO", choices=["DEBUG", "INFO", "WARNING", "ERROR"])
    p.add_argument("--log-format", default="text", choices=sorted(FORMATTERS),
                   help="text (default) or json: one JSON object per line, for a log collector")
    add_trace_options(p)
    p.set_defaults(func=run)


def add_trace_options(p) -> None:
    """--trace FILE and its size limit: every cycle recorded outside the cycle (docs/part_format.md)."""
    from stiffness.data.trace_file import DEFAULT_KEEP, DEFAULT_MAX_MB

    p.add_argument("--trace", default=None, metavar="FILE",
                   help="record every cycle to FILE, .csv or .parquet (off by default), one row a cycle with the "
                        "columns: time_s, unix_time_s, cycle, q1_deg..q6_deg (the joints the PLC reported), "
                        "fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm (the wrench the cycle used, base axes), "
                        "c1_deg..c6_deg (the correction sent), acc_x_mps2, acc_y_mps2, acc_z_mps2 (the arm's acceleration "
                        "at the tool, base axes, with an accelerometer), box_x_mps2, box_y_mps2, box_z_mps2 (its "
                        "reading as the box gave it), status_word, fault_word, task_state, box_samples (readings "
                        "taken, mod 65536; accelerometer.replay reads them back). The "
                        "predicted deflection is not recorded: stiffcomp part recomputes it from its model "
                        "(docs/part_format.md)")
    p.add_argument("--trace-max-mb", type=float, default=DEFAULT_MAX_MB, metavar="MB",
                   help=f"rotate the trace at this size (default {DEFAULT_MAX_MB:g})")
    p.add_argument("--trace-keep", type=int, default=DEFAULT_KEEP, metavar="N",
                   help=f"rotated trace files kept, FILE.1 the newest (default {DEFAULT_KEEP})")


def trace_options(args):
    """The TraceOptions of --trace, or None."""
    if args.trace is None:
        return None
    from pathlib import Path

    from service.trace import TraceOptions

    return TraceOptions(Path(args.trace), args.trace_max_mb * 1e6, args.trace_keep)


WATCH_S = 0.1          # the main thread's longest wait: the I/O process is checked this often


def run(args) -> int:
    configure_logging("WARNING" if args.check else args.log_level, args.log_format)
    from service.app import Service

    cfg = load_config(args.config)
    service = Service(cfg, trace_options(args))   # everything validated and opened, nothing started yet
    if args.check:
        return check(args, cfg, service)
    stop = threading.Event()
    hangup = threading.Event()
    run_file = RunFile(args.config)
    previous = {s: signal.signal(s, lambda *_: stop.set()) for s in (signal.SIGINT, signal.SIGTERM)}
    previous[signal.SIGHUP] = signal.signal(signal.SIGHUP, lambda *_: hangup.set())
    started = False
    try:
        service.start()                 # inside: a port in use still frees the image and the handlers
        started = True
        if run_file.claim():
            run_file.write(service)
        else:
            logging.getLogger("stiffcomp.service").warning(
                "no run file for stiffcomp reload at %s (another service runs with %s, or the folder is not "
                "writable): SIGHUP still reloads", run_file.path, args.config)
        if args.duration is not None:
            _first_cycle(service, stop)     # --duration counts cycling time, not a slow start's
        t_end = None if args.duration is None else time.monotonic() + args.duration
        interval = cfg.cycle.stats_log_interval_s or None
        next_log = time.monotonic() + (interval or 0)
        while not stop.is_set() and service.watch_io() and not service.failed.is_set():
            if hangup.is_set():
                hangup.clear()
                service.on_hangup()
                run_file.write(service)
            now = time.monotonic()
            if t_end is not None and now >= t_end:
                break
            wait = min(x for x in (t_end, next_log if interval else None, now + WATCH_S) if x is not None) - now
            stop.wait(max(wait, 0.0))
            if interval and time.monotonic() >= next_log:
                service.log_stats()
                next_log += interval
    finally:
        service.stop()
        run_file.release()
        for s, h in previous.items():
            signal.signal(s, h)
        if started:                     # a start that failed ran nothing: no statistics that read like a run
            service.log_stats()
        if args.stats_json:
            service.write_stats(args.stats_json)
    return 1 if service.failed.is_set() else 0


def check(args, cfg, service) -> int:
    """``--check``: the service was built (config, model, map, source); close it, then ask this machine what the
    start needs (`service.preflight`): a refusal exits 2 naming the keys, what run would warn about is said."""
    from service.preflight import check_start

    service.stop()                      # closes what the constructor opened; nothing ran
    found = check_start(cfg)
    print(f"{args.config}: ok, the service would start: model {cfg.resolve(cfg.model.file)}, register map "
          f"{cfg.resolve(cfg.plc.register_map)}, source {cfg.source.type} (nothing started)")
    if found.checked:
        print("  listens: " + ", ".join(found.checked))
    for note in found.notes:
        print(f"  note: {note}")
    return 0


def _first_cycle(service, stop, timeout_s: float = 30.0) -> None:
    """Wait until the cycle has run once (a loaded machine starts the task's thread late), a stop, a failure,
    or ``timeout_s``."""
    end = time.monotonic() + timeout_s
    while (service.info.cycle_count == 0 and not stop.is_set() and not service.failed.is_set()
           and time.monotonic() < end and service.watch_io()):
        stop.wait(0.005)
