"""`stiffcomp run`: the cyclic compensation service (not built yet)."""

from __future__ import annotations

import sys


def register(sub) -> None:
    p = sub.add_parser("run", help="run the cyclic compensation service")
    p.set_defaults(func=run)


def run(args) -> int:
    print("stiffcomp run: the cyclic service is not built yet (issue 4); "
          "the model tools work: stiffcomp fit, stiffcomp kcart", file=sys.stderr)
    return 1
