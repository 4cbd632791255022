"""`stiffcomp modal-map MEASURED.csv`: the arm's first modes over the workspace, predicted from physics (the
stiffness model's springs and the arm's masses) and corrected by the modes measured at a few poses
(`stiffness.dynamics.modal_map`, docs/accelerometer.md "A modal map").

MEASURED is a CSV: q1_deg .. q6_deg (the pose), f1_hz and, where measured, f2_hz, f3_hz (the pose's lowest
modes, from `stiffcomp modes` on a tap test or a cut there). The stiffness comes from ``--config``'s model
(a service config; the tool is what its gravity section says the sensor carries) or ``--model``; the masses from ``--masses`` (a robot
description with an ``inertial`` section; default the model's robot). It prints the factors the measured
poses give, the prior's and the map's error at them and, with ``--at POSES.csv`` (q1_deg .. q6_deg), the
modes predicted there; ``-o`` writes those as CSV, ``--plot`` draws the measured poses.
"""

from __future__ import annotations

from .common import check_image_file, check_output_file, print_json


def register(sub) -> None:
    p = sub.add_parser("modal-map", help="the first modes over the workspace, from physics and a few measured poses")
    p.add_argument("measured", help="CSV: q1_deg .. q6_deg, f1_hz[, f2_hz, f3_hz]: the modes measured at a few poses")
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--config", metavar="SERVICE.yaml",
                     help="the service config: its model, and the bodies its gravity section says the sensor carries")
    src.add_argument("--model", metavar="MODEL.yaml", help="the stiffness model (with --tool-kg, --tool-cog-mm)")
    p.add_argument("--masses", metavar="ROBOT.yaml", help="a robot description with the link masses (default: "
                                                          "the model's robot)")
    p.add_argument("--tool-kg", type=float, default=None, help="with --model: the tool's mass (default the model's "
                                                                "payload, else 0)")
    p.add_argument("--tool-cog-mm", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="with --model: the tool's centre of gravity in the sensor frame (mm)")
    p.add_argument("--at", metavar="POSES.csv", help="CSV: q1_deg .. q6_deg: predict the modes at these poses")
    p.add_argument("-o", "--output", metavar="FILE.csv", help="write the --at poses' modes")
    p.add_argument("--plot", metavar="FILE.png", help="the measured modes beside the prior's and the map's")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def stiffness_and_tool(args):
    """(the stiffness model, the tool as a PayloadConfig) from --config or --model and the tool options."""
    from stiffness.errors import ConfigError
    from stiffness.kinematics.statics import PayloadConfig
    from stiffness.model.stiffness_model import StiffnessModel

    if args.config is not None:
        if args.tool_kg is not None or args.tool_cog_mm is not None:
            raise ConfigError("--tool-kg and --tool-cog-mm go with --model; with --config the tool is its "
                              "gravity section's")
        from service.config import load_config

        cfg = load_config(args.config)
        carried = cfg.gravity.payload_sets()[0]                  # all the sensor carries moves with the arm
        return (StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)),
                PayloadConfig(mass_kg=carried.mass_kg, cog_mm=carried.cog_mm))
    model = StiffnessModel.from_yaml(args.model)
    base = model.payload or PayloadConfig()
    if args.tool_kg is not None and not 0.0 <= args.tool_kg <= 1e4:
        raise ConfigError(f"--tool-kg {args.tool_kg:g}: the tool's mass in kg, 0 to 10000")
    return model, PayloadConfig(mass_kg=base.mass_kg if args.tool_kg is None else args.tool_kg,
                                cog_mm=list(base.cog_mm if args.tool_cog_mm is None else args.tool_cog_mm))


def run(args) -> int:
    import numpy as np

    from stiffness.dynamics.modal_map import JOINTS, MODES, ArmInertia, ModalMap, read_poses
    from stiffness.errors import ConfigError, OutputError
    from stiffness.kinematics.robot import load_robot
    from stiffness.model.cartesian import tcp_compliance

    if args.output is not None and args.at is None:
        raise ConfigError(f"-o {args.output}: it writes the modes at the --at poses; give --at POSES.csv")
    if args.output is not None:
        check_output_file("-o", args.output)
    if args.plot is not None:
        check_image_file("--plot", args.plot)
    model, tool = stiffness_and_tool(args)
    masses = load_robot(args.masses) if args.masses else model.robot
    q, measured = read_poses(args.measured, measured=True)
    at = read_poses(args.at, measured=False)[0] if args.at else None
    mapped = ModalMap(lambda x: tcp_compliance(model, x), ArmInertia(masses, tool, arm=model.robot))
    k = measured.shape[1]
    prior = mapped.predict(q)[0][:, :k]
    factors = mapped.fit(q, measured)
    fitted = mapped.predict(q)[0][:, :k]
    err = {"prior": 100 * (prior / measured - 1), "map": 100 * (fitted / measured - 1)}
    out = {"factors": {"stiffness": factors.stiffness, "arm_inertia": factors.arm, "tool_kg": factors.tool_kg,
                       "tool_kg_prior": tool.mass_kg},
           "measured_poses": len(q),
           "error_pct": {name: {"max_abs": np.nanmax(np.abs(e), axis=0).tolist(),
                                "rms": float(np.sqrt(np.nanmean(e ** 2)))} for name, e in err.items()}}
    if at is not None:
        hz, phi = mapped.predict(at)
        out["at"] = [{"q_deg": p.tolist(), "hz": h.tolist(), "directions": v.T.tolist()} for p, h, v in zip(at, hz, phi)]
        if args.output:
            header = ",".join([*JOINTS, *MODES, *(f"phi{m}_{a}" for m in (1, 2, 3) for a in "xyz")])
            rows = np.column_stack([at, hz, np.swapaxes(phi, 1, 2).reshape(len(at), 9)])
            try:
                np.savetxt(args.output, rows, delimiter=",", header=header, comments="", fmt="%.6g")
            except OSError as e:
                raise OutputError(f"-o {args.output}: cannot write: {e}") from e
            out["written"] = str(args.output)
    if args.plot:
        figure(measured, prior, fitted).savefig(args.plot, dpi=100)
        out["plot"] = str(args.plot)
    if args.json:
        print_json(out)
        return 0
    print(f"{len(q)} measured pose(s), {k} mode(s) each; the factors they give: stiffness x{factors.stiffness:.3f}, "
          f"arm inertia x{factors.arm:.3f}, tool {factors.tool_kg:.2f} kg (given {tool.mass_kg:.2f})")
    for name, e in err.items():
        print(f"  {name:5s} at the measured poses: max |error| "
              + ", ".join(f"mode {j + 1} {np.nanmax(np.abs(e[:, j])):.2f} %" for j in range(k))
              + f"; RMS {np.sqrt(np.nanmean(e ** 2)):.2f} %")
    for row in out.get("at", []):
        print(f"  at [{', '.join(f'{x:.1f}' for x in row['q_deg'])}] deg: "
              + ", ".join(f"{h:.2f} Hz" for h in row["hz"]))
    for key in ("written", "plot"):
        if key in out:
            print(f"{key}: {out[key]}")
    return 0


def figure(measured, prior, fitted):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, ax = plt.subplots(figsize=(7, 3.5))
    x = np.arange(1, len(measured) + 1)
    for j in range(measured.shape[1]):
        ax.plot(x, measured[:, j], "ko", label="measured" if j == 0 else None)
        ax.plot(x, prior[:, j], "s", mfc="none", color="C0", label="physics prior" if j == 0 else None)
        ax.plot(x, fitted[:, j], "x", color="C1", label="modal map" if j == 0 else None)
    ax.set_xlabel("measured pose")
    ax.set_ylabel("mode frequency (Hz)")
    ax.set_xticks(x)
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    return fig

