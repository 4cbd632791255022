"""`stiffcomp part compare|learn|diagnose`: the machined part and the trace of its cut (docs/part.md).

    stiffcomp part compare  MODEL TRACE PART [--report DIR] [--json]
    stiffcomp part learn    MODEL TRACE PART [--part TRACE PART]... -o NEW.yaml [--campaign DATA]
    stiffcomp part diagnose MODEL TRACE PART [--part TRACE PART]... [--report DIR] [--json]
    stiffcomp part features FILE.qif [--json]

PART may be a CMM's QIF 3 results file (.qif; `tools.part_qif`: --feature, --results, --tool-radius-mm,
--part-frame), or the robot's own probe log (`stiffness.data.probe_log`: its header names the latched joints;
no part frame, so --part-frame and --best-fit are refused with it).

TRACE is `stiffcomp run --trace` (or `hil circle --trace`); PART a CMM's or a probe's points in the part
format (docs/part_format.md).
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from . import part_qif
from .common import Progress, check_number, check_output_file, print_json, write_output


def register(sub) -> None:
    p = sub.add_parser("part", help="compare, learn and diagnose from a machined part and the trace of its cut")
    ps = p.add_subparsers(dest="part_command", metavar="ACTION", required=True)
    c = ps.add_parser("compare", help="the part's error beside the model's account of it (Fig. 8)")
    _common(c)
    c.add_argument("--report", metavar="DIR", help="write the plots and an HTML page into DIR")
    c.set_defaults(func=run_compare)
    ln = ps.add_parser("learn", help="update the model from parts: each is one more measurement of it")
    _common(ln, more=True)
    _prior_options(ln)
    ln.add_argument("-o", "--output", required=True, help="where to write the learned model YAML")
    ln.add_argument("--report", metavar="DIR", help="write what the model misses before and after into DIR")
    ln.add_argument("--force", action="store_true",
                    help="write the model even when the parts do not fit it (a misplaced part, a wrong tool radius), "
                         "nothing was learned, or the input held negative compliances (docs/part.md)")
    ln.set_defaults(func=run_learn)
    d = ps.add_parser("diagnose", help="name the effect the model misses, from parts (as `diagnose` does from a campaign)")
    _common(d, more=True)
    _prior_options(d)
    d.add_argument("--report", metavar="DIR", help="write the evidence into DIR")
    d.set_defaults(func=run_diagnose)
    part_qif.register_features(ps)


def _common(p, more: bool = False) -> None:
    from stiffness.part.rows import NEAR_MM, SMOOTH_HZ

    p.add_argument("model", help="model YAML")
    p.add_argument("trace", help="the trace of the cut (`stiffcomp run --trace FILE`, .csv or .parquet)")
    p.add_argument("part", help="the part's measured points, or the robot's own probe log (docs/part_format.md)")
    if more:
        p.add_argument("--part", dest="more", nargs=2, action="append", default=[], metavar=("TRACE", "PART"),
                       help="another part and the trace of its cut (repeat for more)")
    p.add_argument("--best-fit", action="store_true",
                   help="place the part by a best fit to the traced path (no datum); hides a constant offset")
    p.add_argument("--near-mm", type=float, default=NEAR_MM, metavar="MM",
                   help=f"a point farther than this off where the tool passed is not on the contour (default {NEAR_MM:g})")
    p.add_argument("--smooth-hz", type=float, default=SMOOTH_HZ, metavar="HZ",
                   help=f"low-pass the trace's wrench without lag at HZ (default {SMOOTH_HZ:g}; 0: none)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    part_qif.add_options(p)


def _prior_options(p) -> None:
    p.add_argument("--campaign", metavar="DATA",
                   help="the campaign the model was identified from, given again: its fit is the prior "
                        "(default: the covariance the model's YAML carries from `stiffcomp fit`)")
    p.add_argument("--prior-relative", type=float, default=0.5, metavar="F",
                   help="for a model without a covariance or a campaign: each parameter within F of its value "
                        "(1 sigma; default 0.5)")


def _check_options(args) -> None:
    """Refuse a bad option before anything is read: one line naming it (exit 2), nothing written."""
    check_number("--near-mm", args.near_mm, "mm", above=0.0)
    check_number("--smooth-hz", args.smooth_hz, "Hz; 0: the wrench as traced", at_least=0.0)
    if getattr(args, "prior_relative", None) is not None:
        check_number("--prior-relative", args.prior_relative, "a fraction of each value", above=0.0)
    if getattr(args, "output", None):
        check_output_file("-o", args.output)
    parts = [args.part] + [x[1] for x in getattr(args, "more", [])]
    _check_order(args)
    _check_probe_options(args, parts)
    part_qif.check_options(args, parts)


def _check_order(args) -> None:
    """MODEL TRACE PART, each file what its place says, and no part given twice: a file in the wrong place is
    named as swapped before it is read as what it is not."""
    from stiffness.data.part_points import is_cmm_part
    from stiffness.data.probe_log import is_probe_log
    from stiffness.errors import ConfigError

    pairs = [(args.trace, args.part)] + [tuple(x) for x in getattr(args, "more", [])]
    order = "the order is MODEL TRACE PART (--part TRACE PART)"
    if Path(args.model).suffix.lower() not in (".yaml", ".yml"):
        raise ConfigError(f"{args.model}: given as the model, but a model is a YAML file: {order}")
    for trace, part in pairs:
        if Path(part).suffix.lower() in (".yaml", ".yml"):
            raise ConfigError(f"{part}: given as the part, but it is a YAML file (a model?): {order}")
        if is_probe_log(trace) or is_cmm_part(trace):
            raise ConfigError(f"{trace}: given as the trace, but it is a {'probe log' if is_probe_log(trace) else 'part'}"
                              f" (swapped with {part}?): {order}")
    seen: dict[str, str] = {}
    for _, part in pairs:
        key = str(Path(part).resolve())
        if key in seen:
            raise ConfigError(f"{part}: the same part is given twice: each counts as one more part, so the model "
                              "would learn it twice as surely as it should")
        seen[key] = part


def _check_probe_options(args, parts: list[str]) -> None:
    """A probe log is in the robot's base already: a part frame or a best fit given with one is refused."""
    from stiffness.data.probe_log import PART_FRAME_MEANINGLESS, is_probe_log
    from stiffness.errors import ConfigError

    probes = [p for p in parts if is_probe_log(p)]
    if not probes:
        return
    if args.part_frame is not None:
        raise ConfigError(f"--part-frame is meaningless with the probe log {probes[0]}: {PART_FRAME_MEANINGLESS}")
    if args.best_fit:
        raise ConfigError(f"--best-fit is meaningless with the probe log {probes[0]}: {PART_FRAME_MEANINGLESS}, so "
                          "there is no placement to fit")


def _parts(args, model) -> tuple[list, list[dict]]:
    """Each part read against its trace, and the features of its QIF file left out (their points cannot be
    read): named in the part's notes (the text) and returned for the JSON's ``left_out_features``."""
    from stiffness.data.probe_log import is_probe_log, read_probe
    from stiffness.data.trace_file import read_trace
    from stiffness.part import coverage
    from stiffness.part.probe import read_probe_against
    from stiffness.part.rows import read_against

    pairs = [(args.trace, args.part)] + [tuple(x) for x in getattr(args, "more", [])]
    out, features_left_out = [], []
    for k, (trace, part) in enumerate(pairs):
        if is_probe_log(part):
            rows = read_probe_against(read_probe(part), read_trace(trace), model.robot, f"part {k + 1}",
                                      near_mm=args.near_mm, smooth_hz=args.smooth_hz)
        else:
            measurement, left_out = part_qif.read_any(part, args)
            rows = read_against(measurement, read_trace(trace), model.robot, f"part {k + 1}",
                                best_fit=args.best_fit, near_mm=args.near_mm, smooth_hz=args.smooth_hz)
            rows.notes += [x.text(part) for x in left_out]
            features_left_out += [x.to_dict(part) for x in left_out]
        rows.notes += [n for n in [coverage.note(rows)] if n]
        out.append(rows)
    return out, features_left_out


def _prior(args, model, say):
    """The prior and the model to start from: the YAML's covariance, a campaign's fit, or the catalogue's."""
    from stiffness.data.measurements import read_measurements
    from stiffness.fit.identify import fit
    from stiffness.model.prior import Prior

    if args.campaign:
        say(f"fitting the campaign {args.campaign} for the prior")
        result = fit(model, read_measurements(args.campaign, model.robot))
        return Prior.from_fit(result, f"the fit of {args.campaign}"), result.model
    prior = Prior.from_model(model)
    if prior is not None:
        return prior, model
    return Prior.catalogue(model, args.prior_relative), model


def _command() -> str:
    return "stiffcomp " + " ".join(shlex.quote(a) for a in sys.argv[1:])


def run_compare(args) -> int:
    from stiffness.model.stiffness_model import StiffnessModel
    from stiffness.part.compare import compare_part

    _check_options(args)
    model = StiffnessModel.from_yaml(args.model)
    parts, features_left_out = _parts(args, model)
    comp = compare_part(model, parts[0])
    if args.report:
        from stiffness.part.report import compare_report

        rep = compare_report(comp, _command())
        path = write_output(Path(args.report) / "index.html", lambda p: rep.write(p.parent))
        print(f"report: {path}", file=sys.stderr)
    if args.json:
        print_json({**comp.summary(), "left_out_features": features_left_out})
        return 0
    print("\n".join(comp.lines()))
    return 0


def _setup(args, command: str):
    """Progress, the prior, the model to start from, the parts and the QIF features left out, for learn and
    diagnose."""
    from stiffness.model.stiffness_model import StiffnessModel

    _check_options(args)
    progress = Progress(command)
    prior, start = _prior(args, StiffnessModel.from_yaml(args.model), progress)
    return progress, prior, start, *_parts(args, start)


def run_learn(args) -> int:
    from stiffness.part.learn import learn

    progress, prior, start, parts, features_left_out = _setup(args, "part learn")
    result = learn(start, parts, prior, args.best_fit, progress)
    progress.done()
    written = not result.problems or args.force      # a learning that fails its checks only when asked
    if written:
        _write_learned(args, result)
    if args.json:
        print_json({"output": args.output if written else None, "problems": result.problems,
                    "prior": prior.source, "points": result.points_kept,
                    "rms_before_mm": result.before_mm, "rms_after_mm": result.after_mm,       # over the points kept
                    "rms_before_with_left_out_mm": result.before_all_mm,           # the fit's gross errors too
                    "rms_after_with_left_out_mm": result.after_all_mm,
                    "left_out": [x.to_dict() for x in result.left_out], "left_out_features": features_left_out,
                    "trace_gaps": [g.to_dict() for p in parts for g in p.gaps],
                    "parameters": result.n_params,
                    "determined": [{"weights": c.weights, "information_ratio": c.ratio, "moved_prior_sigma": c.moved_sigma}
                                   for c in result.determined],
                    "changes": [{"parameter": lab, "before": b0, "after": b1} for lab, b0, b1 in result.changes],
                    "notes": result.notes})
        return _refuse_unless(written, args, result)
    print("\n".join(result.lines()))
    if written:
        print(f"written: {args.output}" + (" (--force: despite the problem(s) above)" if result.problems else ""))
    return _refuse_unless(written, args, result)


def _write_learned(args, result) -> None:
    """The learned model to -o, and the report to --report."""
    header = (f"# {args.model} learned from {len(result.parts)} part(s) by `stiffcomp part learn`; its covariance "
              "is the prior of the next")
    write_output(args.output, lambda p: result.model.to_yaml(p, header))
    if args.report:
        from stiffness.part.report import learn_report

        rep = learn_report(result, _command())
        path = write_output(Path(args.report) / "index.html", lambda p: rep.write(p.parent))
        print(f"report: {path}", file=sys.stderr)


def _refuse_unless(written: bool, args, result) -> int:
    """0 once the model is written; a learning that failed its checks (`stiffness.part.sanity`) and was not
    forced is refused in one line naming the output and the first problem (the text lists them all)."""
    if written:
        return 0
    from stiffness.errors import DataError

    more = f" ({len(result.problems) - 1} more listed)" if len(result.problems) > 1 else ""
    raise DataError(f"{args.output}: not written: {result.problems[0]}{more}; --force writes it")


def run_diagnose(args) -> int:
    from stiffness.diagnose.report import VERDICT_KIND, to_dict
    from stiffness.part.diagnose import diagnose_parts
    from stiffness.part.left_out import GROSS, fit_account, left_out_lines

    progress, prior, start, parts, features_left_out = _setup(args, "part diagnose")
    pd = diagnose_parts(start, parts, prior, progress, args.best_fit)
    progress.done()
    d = pd.diagnosis
    left_out, rms_kept, rms_all = fit_account(pd.parts, pd.data, d.fit)
    gross = [x for x in left_out if x.why == GROSS]
    if args.report:
        from stiffness.part.compare import compare_part
        from stiffness.part.report import diagnose_report

        rep = diagnose_report(pd.message, VERDICT_KIND[d.verdict], compare_part(d.fit.model, parts[0]), pd,
                              _command())
        path = write_output(Path(args.report) / "index.html", lambda p: rep.write(p.parent))
        print(f"report: {path}", file=sys.stderr)
    if args.json:
        out = to_dict(d)
        out["message"] = pd.message
        out["where"] = pd.where
        out["marks_deg"] = pd.marks_deg or []
        out.update(rms_kept_mm=rms_kept, rms_with_left_out_mm=rms_all, left_out=[x.to_dict() for x in left_out],
                   left_out_features=features_left_out,
                   trace_gaps=[g.to_dict() for p in pd.parts for g in p.gaps], notes=[n for p in pd.parts for n in p.notes])
        print_json(out)
        return 0
    print(f"verdict: {d.verdict}")
    print(f"  {pd.message}")
    with_gross = f" ({rms_all:.4f} mm with the {len(gross)} the fit left out)" if gross else ""
    print(f"  the parts' residual RMS {rms_kept:.4f} mm along the normal over the "
          f"{sum(len(p.used) for p in pd.parts) - len(left_out)} points kept{with_gross}; prior: {prior.source}")
    print("  candidates (best first):")
    for c in d.candidates[:8]:
        where = f"{c.effect.location_key} {c.joint}" if c.joint is not None else "global"
        print(f"    {'*' if c.named else ' '} {c.name:20s} {where:8s} CV {100 * c.cv_improvement:5.1f} %  "
              f"dBIC {c.delta_bic:10.1f}  after {c.rms_position_mm_after:.4f} mm")
    if d.best is not None:
        b = d.best
        loc = f" --joint {b.joint}" if b.joint is not None else ""
        print(f"  next: stiffcomp model add {args.model} {b.name}{loc} -o with_{b.name}.yaml")
    for line in [n for p in pd.parts for n in p.notes] + left_out_lines(gross):
        print(f"  {line}")
    return 0
