"""`stiffcomp modes DATA`: the structure's modes identified from a recorded force and path (commissioning).

DATA is a CSV: t_s, fx_N, fy_N, fz_N (the force at the tool, base axes) and dx_mm, dy_mm, dz_mm (the TCP's
deflection from its path, base axes): a tap test, a dynamometer and a laser tracker on a test cut, or the
HIL's (`stiffcomp hil circle --dynamic-compensation --modes-data FILE`). It prints the modes, the arm's own
lag and how much of the deflection they explain against a static fit alone; ``-o`` writes the
``dynamics`` section for the service config, ``--plot`` the identified response over the measured one
(docs/dynamics.md, "Commissioning").
"""

from __future__ import annotations

from pathlib import Path

from .common import print_json


def register(sub) -> None:
    p = sub.add_parser("modes", help="identify the structure's modes from a recorded force and path")
    p.add_argument("data", help="CSV: t_s, fx_N, fy_N, fz_N, dx_mm, dy_mm, dz_mm (base axes)")
    p.add_argument("--modes", type=int, default=2, choices=(1, 2, 3), help="how many modes (default 2)")
    p.add_argument("--max-lag-ms", type=float, default=30.0, help="the longest lag of the arm tried, ms")
    p.add_argument("-o", "--output", default=None, metavar="FILE.yaml",
                   help="write the dynamics section (the modes, their lag) for the service config")
    p.add_argument("--plot", default=None, metavar="FILE.png", help="the identified response over the measured one")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def section(found) -> dict:
    """The service config's ``dynamics`` with the identified structure and the predictor on."""
    return {"dynamics": {"enabled": True, "predictor": {}, "structure": found.to_config()}}


def run(args) -> int:
    from stiffness.dynamics.identify import figure, identify, read_record
    from stiffness.errors import OutputError
    from stiffness.yamlio import dump_yaml

    rec = read_record(args.data)
    found = identify(rec, args.modes, args.max_lag_ms)
    out = {"modes": found.to_config()["modes"], "lag_ms": found.to_config()["lag_ms"],
           "explained": round(found.explained, 5), "explained_static": round(found.explained_static, 5),
           "residual_rms_mm": round(found.rms_mm, 5), "config": section(found)}
    if args.output:
        try:
            Path(args.output).write_text("# the structure identified by `stiffcomp modes " + str(args.data)
                                         + "`; merge into the service config (set dynamics.delay_ms)\n"
                                         + dump_yaml(section(found), sort_keys=False))
        except OSError as e:
            raise OutputError(f"-o {args.output}: cannot write: {e}") from e
        out["written"] = str(args.output)
    if args.plot:
        try:
            figure(found, rec).savefig(args.plot, dpi=110)
        except OSError as e:
            raise OutputError(f"--plot {args.plot}: cannot write: {e}") from e
        out["plot"] = str(args.plot)
    if args.json:
        print_json(out)
        return 0
    for k, m in enumerate(out["modes"]):
        print(f"mode {k + 1}: {m['hz']:.3f} Hz, damping {100 * m['damping']:.2f} %, direction "
              f"[{', '.join(f'{x:+.3f}' for x in m['direction'])}] (base axes)")
    print(f"the arm's own lag: {out['lag_ms']:.2f} ms")
    print(f"explains {100 * found.explained:.2f} % of the deflection (a static fit alone: "
          f"{100 * found.explained_static:.2f} %); residual RMS {found.rms_mm:.4f} mm")
    if args.output:
        print(f"next: merge {args.output} into the service config, set dynamics.delay_ms to the measured "
              "end-to-end delay, and restart the service")
    if args.plot:
        print(f"plot: {args.plot}")
    return 0
