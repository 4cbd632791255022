"""The modal map's figures (issue 52, item 5): the first two modes predicted over the circle's workspace from
physics and a few measured poses, against the truth's, beside the physics prior alone and a reach law.

The truth (the robot stub, ``robot.frequencies: physics``): the reference truth's stiffness, its own masses
(config/hil/truth_masses.yaml: the arm housing 20 % heavier and its centre moved, the forearm 25 % heavier,
the rocker 10 % lighter than the model's description says) and a tool ``--tool-error`` heavier than the
service's gravity section (12 kg). The model's side: the identified model (config/models/kr125_6dof.yaml),
the approximate masses (config/robots/kr125_masses.yaml), the gravity section's tool.

Measured: a tap test at each of ``--measured`` poses (the workspace box's corners), identified as `stiffcomp
modes` does. Held out: ``--held-out`` poses drawn uniformly in the box (seeded), where the map, the prior and
a reach law f_k = a_k r^-e_k (fitted to the same measured poses, r the TCP's distance from the base's axis)
are compared with the truth's own modes. Deterministic: one run is the figure.

    .venv/bin/python benchmarks/bench_modal_map.py [--measured 8] [--held-out 12] [--tool-error 0.2]
                                                   [--plot docs/img/modal_map.png] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.modal_survey import physics_scenario, service_map, tap_survey, true_modes, workspace_poses
from stiffness.model.stiffness_model import StiffnessModel


def reach(truth, poses):
    return np.hypot(*truth.robot.frames(np.radians(poses))[:, 7, :2, 3].T)


def reach_law(r_meas, f_meas, r_at):
    """f_k = a_k r^-e_k fitted in logs to the measured modes, evaluated at the reaches ``r_at``; NaN where the
    measured poses share one reach (the box's corners, 2 or 4 of them: the law is not determined)."""
    if np.ptp(r_meas) < 0.01:
        return np.full((len(r_at), f_meas.shape[1]), np.nan)
    out = []
    for k in range(f_meas.shape[1]):
        slope, icpt = np.polyfit(np.log(r_meas), np.log(f_meas[:, k]), 1)
        out.append(np.exp(icpt + slope * np.log(r_at)))
    return np.array(out).T


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--measured", type=int, default=8)
    ap.add_argument("--held-out", type=int, default=12)
    ap.add_argument("--tool-error", type=float, default=0.2)
    ap.add_argument("--plot", type=Path)
    ap.add_argument("--json", type=Path)
    args = ap.parse_args(argv)

    sc = physics_scenario(args.tool_error)
    truth = StiffnessModel.from_yaml(sc.resolve(sc.truth))
    measured_q = workspace_poses(sc, truth, args.measured, seed=0, corners=True)
    held_q = workspace_poses(sc, truth, args.held_out, seed=52)
    print(f"tap tests at {len(measured_q)} poses ...", flush=True)
    measured = tap_survey(sc, truth, measured_q, progress=lambda i, n: print(f"  {i}/{n}", flush=True))
    truth_hz = true_modes(sc, truth, held_q)

    mapped = service_map(sc)
    prior_hz = mapped.predict(held_q)[0][:, :2]
    factors = mapped.fit(measured_q, measured)
    map_hz = mapped.predict(held_q)[0][:, :2]
    law_hz = reach_law(reach(truth, measured_q), measured, reach(truth, held_q))

    meas_err = measured / true_modes(sc, truth, measured_q) - 1.0
    rows = {"physics prior": prior_hz, "modal map": map_hz, "reach law": law_hz}
    print(f"\ntruth's modes at the {len(held_q)} held-out poses: {truth_hz[:, 0].min():.2f}-{truth_hz[:, 0].max():.2f} Hz "
          f"and {truth_hz[:, 1].min():.2f}-{truth_hz[:, 1].max():.2f} Hz; the tap tests' own error at most "
          f"{100 * np.abs(meas_err).max():.2f} %")
    print(f"fitted factors: stiffness {factors.stiffness:.3f}, arm inertia {factors.arm:.3f}, "
          f"tool {factors.tool_kg:.2f} kg (the truth's {sc.payload.tool.mass_kg:.2f}, the prior's {mapped.prior.tool_kg:.2f})")
    print(f"\n{'':15s} {'mode 1 max |err| %':>19s} {'mode 2 max |err| %':>19s} {'RMS %':>7s}")
    out = {"measured_poses": len(measured_q), "held_out_poses": len(held_q), "factors": factors.__dict__, "rows": {}}
    for name, hz in rows.items():
        err = 100.0 * (hz / truth_hz - 1.0)
        out["rows"][name] = {"max_abs_pct": np.abs(err).max(0).tolist(), "rms_pct": float(np.sqrt((err ** 2).mean()))}
        print(f"{name:15s} {np.abs(err[:, 0]).max():19.2f} {np.abs(err[:, 1]).max():19.2f} "
              f"{np.sqrt((err ** 2).mean()):7.2f}")
    if args.plot:
        figure(truth_hz, rows, reach(truth, held_q), args.plot)
        print(f"wrote {args.plot}")
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


def figure(truth_hz, rows, r, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    order = np.argsort(r)
    for k, ax in enumerate(axes):
        for (name, hz), marker in zip(rows.items(), "sox"):
            ax.plot(r[order], 100 * (hz[order, k] / truth_hz[order, k] - 1), marker + "-", label=name)
        ax.axhspan(-5, 5, color="0.9", zorder=0, label="±5 %")
        ax.set_title(f"mode {k + 1} at the held-out poses")
        ax.set_xlabel("the TCP's reach from the base's axis (m)")
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel("predicted / true frequency − 1 (%)")
    axes[1].legend()
    fig.tight_layout()
    fig.savefig(path, dpi=90)


if __name__ == "__main__":
    sys.exit(main())
