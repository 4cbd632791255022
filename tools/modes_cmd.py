"""`stiffcomp modes DATA`: the structure's modes identified from a recorded force and path (commissioning), or
from a cut's trace with the accelerometer.

DATA is a CSV: t_s, fx_N, fy_N, fz_N (the force at the tool, base axes) and dx_mm, dy_mm, dz_mm (the TCP's
deflection from its path, base axes): a tap test, a dynamometer and a laser tracker on a test cut, or the
HIL's (`stiffcomp hil circle --dynamic-compensation --modes-data FILE`). Or DATA is the trace of a cut
(`stiffcomp run --trace`, CSV or Parquet) whose service read the flange accelerometer: no path measured, the
deflection seen through the accelerometer's band (`stiffness.dynamics.from_cut`); ``--config`` then names the
service config the cut ran with: its model's robot turns the joints into the tool's path, its
``dynamics.observer`` gives the band (else the observer's default), and its ``dynamics.structure.lag_ms`` is
kept (a trace's lag is not the arm's: its wrench is filtered, its acceleration late). ``--compare FILE`` holds
the modes of a file's ``dynamics.structure`` against the record's and names what is missing or off
(`stiffness.dynamics.compare`). It prints which force directions the
record excites, the modes (a mode the record does not show is refused, `stiffness.dynamics.excitation`), the
arm's own lag and how much of the deflection they explain against a static fit alone; ``-o`` writes the
``dynamics`` section for the service config, ``--plot`` the identified response over the measured one
(docs/dynamics.md, "Commissioning").
"""

from __future__ import annotations

from pathlib import Path

from .common import check_image_file, check_number, check_output_file, print_json


def register(sub) -> None:
    p = sub.add_parser("modes", help="identify the structure's modes from a recorded force and path")
    p.add_argument("data", help="CSV: t_s, fx_N, fy_N, fz_N, dx_mm, dy_mm, dz_mm (base axes); or a cut's trace "
                                "with the accelerometer's columns (give --config)")
    p.add_argument("--config", default=None, metavar="SERVICE.yaml",
                   help="a trace's: the service config the cut ran with (its robot, band and lag)")
    p.add_argument("--modes", type=int, default=2, choices=(1, 2, 3), help="how many modes (default 2)")
    p.add_argument("--max-lag-ms", type=float, default=30.0,
                   help="the longest lag of the arm tried, ms (above 0, at most the config's 100)")
    p.add_argument("--compare", default=None, metavar="FILE.yaml",
                   help="the modes of this file's dynamics.structure (a service config, or what -o wrote) against "
                        "the record's: which is missing, which is off (the record's modes: one more than it holds "
                        "where the record shows one)")
    p.add_argument("-o", "--output", default=None, metavar="FILE.yaml",
                   help="write the dynamics section (the modes, their lag) for the service config")
    p.add_argument("--plot", default=None, metavar="FILE.png", help="the identified response over the measured one")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def section(found) -> dict:
    """The service config's ``dynamics`` with the identified structure and the predictor on."""
    return {"dynamics": {"enabled": True, "predictor": {}, "structure": found.to_config()}}


def check_options(args) -> None:
    """Each option's value, refused naming it before the record is read: --max-lag-ms within what the
    service's ``dynamics.structure.lag_ms`` takes, -o and --plot into folders that exist, --plot with a
    suffix matplotlib writes."""
    from stiffness.dynamics.structure import MAX_LAG_MS

    check_number("--max-lag-ms", args.max_lag_ms, "ms: the arm's lag is fitted from 0 to it, and "
                 f"dynamics.structure.lag_ms takes at most {MAX_LAG_MS:g}", above=0.0, at_most=MAX_LAG_MS)
    if args.output is not None:
        check_output_file("-o", args.output)
    if args.plot is not None:
        check_image_file("--plot", args.plot)


def read_data(args):
    """(the record, the lag to keep: None for a tap test's record, the config's for a trace's)."""
    from stiffness.data.trace_file import looks_like_trace
    from stiffness.dynamics.modes import read_record

    if not looks_like_trace(args.data):
        return read_record(args.data), None
    from service.config import load_config
    from stiffness.data.trace_file import read_trace
    from stiffness.dynamics.from_cut import BAND_HZ, BOX_LOWPASS_HZ, record_from_trace
    from stiffness.errors import DataError
    from stiffness.model.stiffness_model import StiffnessModel

    if args.config is None:
        raise DataError(f"{args.data}: a cut's trace: give --config SERVICE.yaml, the service config the cut ran "
                        "with (its model's robot turns the joints into the tool's path)")
    cfg = load_config(args.config)
    robot = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)).robot
    obs, st = cfg.dynamics.observer, cfg.dynamics.structure
    band = (obs.band_hz, obs.box_lowpass_hz) if obs is not None else (BAND_HZ, BOX_LOWPASS_HZ)
    rec = record_from_trace(read_trace(args.data), robot, *band)
    return rec, (st.lag_ms if st is not None else 0.0)


def run(args) -> int:
    from stiffness.dynamics.modes import figure, identify
    from stiffness.errors import OutputError
    from stiffness.files.yaml_schema import dump_yaml

    check_options(args)
    rec, kept_lag = read_data(args)
    verdict = None
    if args.compare is not None:
        from stiffness.dynamics.compare import compare
        from stiffness.dynamics.structure import read_structure

        verdict = compare(rec, read_structure(args.compare, "--compare"), args.max_lag_ms)
        found = verdict.found
    else:
        found = identify(rec, args.modes, args.max_lag_ms)
    if kept_lag is not None:
        found.structure.cfg.lag_ms = kept_lag
    out = {"modes": found.to_config()["modes"], "lag_ms": found.to_config()["lag_ms"],
           "explained": round(found.explained, 5), "explained_static": round(found.explained_static, 5),
           "residual_rms_mm": round(found.rms_mm, 5),
           "excitation": {**found.excitation.to_json(), "modes": [round(e, 1) for e in found.evidence]},
           "config": section(found)}
    if verdict is not None:
        out["compare"] = {"file": str(args.compare), "findings": [{"kind": f.kind, "text": f.text} for f in verdict.findings],
                          "rms_model_mm": round(verdict.rms_model_mm, 5), "rms_found_mm": round(verdict.rms_found_mm, 5)}
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
            figure(found, rec, predicted=None if verdict is None else verdict.response_model).savefig(args.plot, dpi=110)
        except OSError as e:
            raise OutputError(f"--plot {args.plot}: cannot write: {e}") from e
        out["plot"] = str(args.plot)
    if args.json:
        print_json(out)
        return 0
    print(f"the force {found.excitation.describe()} ({found.excitation.floor()})")
    for k, m in enumerate(out["modes"]):
        print(f"mode {k + 1}: {m['hz']:.3f} Hz, damping {100 * m['damping']:.2f} %, direction "
              f"[{', '.join(f'{x:+.3f}' for x in m['direction'])}] (base axes); explains {found.evidence[k]:.3g} P")
    print(f"the arm's own lag: {out['lag_ms']:.2f} ms" + (" (kept from --config: a trace's lag is not the arm's)"
                                                          if kept_lag is not None else ""))
    print(f"explains {100 * found.explained:.2f} % of the deflection (a static fit alone: "
          f"{100 * found.explained_static:.2f} %); residual RMS {found.rms_mm:.4f} mm")
    if verdict is not None:
        print(f"against {args.compare}:")
        for line in verdict.lines():
            print(f"  {line}")
    if args.output:
        print(f"next: merge {args.output} into the service config, set dynamics.delay_ms to the measured "
              "end-to-end delay, and restart the service")
    if args.plot:
        print(f"plot: {args.plot}")
    return 0
