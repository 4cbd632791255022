"""`stiffcomp reload`: make the running service reread its config file, and say what happened.

Finds the service that `stiffcomp run --config FILE` started through its run file (`tools.run_file`;
no pid to know), sends it SIGHUP and waits until the run file reports the outcome of that reload:
its one log line, printed here. Exit code 0 when the reload was accepted, 1 when it was refused (the
service runs on unchanged) or no outcome came within ``--timeout``, 2 when no service runs with FILE.
"""

from __future__ import annotations

import os
import signal
import sys
import time

from service.config import DEFAULT_CONFIG

from .run_file import read_run_file, run_file_for


def register(sub) -> None:
    p = sub.add_parser("reload", help="make the running service reread its config (as SIGHUP does) and report")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="the config the service was started with")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S", help="wait this long for the outcome")
    p.set_defaults(func=run)


def run(args) -> int:
    state = read_run_file(args.config)
    if state is None:
        print(f"stiffcomp reload: no service runs with {args.config} (stiffcomp run --config {args.config} "
              f"writes {run_file_for(args.config)})", file=sys.stderr)
        return 2
    before = state["reloads"]["attempts"]
    os.kill(state["pid"], signal.SIGHUP)
    deadline = time.monotonic() + args.timeout
    while time.monotonic() < deadline:
        time.sleep(0.05)
        now = read_run_file(args.config)
        if now is None:
            print(f"stiffcomp reload: the service (pid {state['pid']}) ended before it answered", file=sys.stderr)
            return 1
        if now["reloads"]["attempts"] > before:
            last = now["reloads"]["last"]
            print(last["message"])
            return 0 if last["accepted"] else 1
    print(f"stiffcomp reload: the service (pid {state['pid']}) did not answer within {args.timeout:g} s",
          file=sys.stderr)
    return 1
