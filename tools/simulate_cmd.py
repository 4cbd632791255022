"""`stiffcomp simulate CAMPAIGN.yaml -o DATA.csv`: a synthetic campaign from a truth model."""

from __future__ import annotations

from pathlib import Path

from stiffness.errors import ConfigError
from stiffness.plan.simulate import Campaign

from .common import print_json


def register(sub) -> None:
    p = sub.add_parser("simulate", help="make a synthetic measurement campaign from a truth model",
                       description="Simulate a campaign (docs/simulate.md): configurations, load ramps along "
                                   "the flange axes, repeated readings, optical and F/T sensor noise. Writes "
                                   "the measurement format (docs/measurement_format.md).")
    p.add_argument("campaign", help="campaign YAML (e.g. examples/campaign_reference.yaml)")
    p.add_argument("-o", "--output", required=True, help="write the campaign CSV here")
    p.add_argument("--seed", type=int, help="override the campaign's seed")
    p.add_argument("--no-noise", action="store_true", help="write the truth model's exact deflections")
    p.add_argument("--json", action="store_true", help="print a summary as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    campaign = Campaign.from_yaml(args.campaign)
    if args.seed is not None:
        campaign.seed = args.seed
    data = campaign.run(noise=not args.no_noise)
    out = Path(args.output)
    if out.suffix.lower() in (".parquet", ".pq"):
        raise ConfigError(f"{out}: simulate writes CSV; give an output name ending in .csv")
    if out.parent and not out.parent.exists():
        out.parent.mkdir(parents=True)
    data.to_csv(out)
    summary = {
        "output": str(out),
        "rows": len(data),
        "readings": len(data.readings()[0]),
        "configurations": data.configs,
        "bodies": len(campaign.bodies),
        "time_s": [float(data.time_s.min()), float(data.time_s.max())],
        "truth": campaign.truth.source,
        "seed": campaign.seed,
        "noise": None if args.no_noise else campaign.noise,
    }
    if args.json:
        print_json(summary)
    else:
        noise = "no noise" if args.no_noise else (
            "noise " + ", ".join(f"{k} {v:g}" for k, v in campaign.noise.items()))
        print(f"wrote {out}: {summary['rows']} rows, {summary['readings']} readings, "
              f"{len(data.configs)} configurations, t = {summary['time_s'][0]:g}..{summary['time_s'][1]:g} s")
        print(f"  truth {campaign.truth.source}, seed {campaign.seed}, {noise}")
    return 0
