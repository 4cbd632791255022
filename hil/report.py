"""Path errors of a pass and the Fig. 8 plot (machined circle and point-to-point error).

The path error of a cycle is the point-to-point error of Fig. 8b: the actual TCP's distance from the
circle's centre in the circle's plane minus the radius (mm; + outside). The cutter's edge, not its
tangential position, makes the machined contour, so this is the error a CMM would measure. Only
cycles of the cut (0 <= t <= one circle) count.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from stiffness.plots import legend_below

from .robot_stub import RobotStub
from .world import World

GRID_S = 2.5e-4          # the structural filter runs on this uniform grid


def evaluate(world: World, stub: RobotStub, log: dict) -> dict[str, np.ndarray]:
    """Actual TCP, path angle and radial error (mm) of every cycle of a pass; ``cut`` marks the cut."""
    t = np.asarray(log["t"])
    grid = np.arange(world.t_start, world.t_end + GRID_S, GRID_S)
    F = stub.structural_load(grid, world.force(grid))
    F_t = np.stack([np.interp(t, grid, F[:, k]) for k in range(3)], axis=1)
    p = stub.tcp(log["q_cmd"], F_t, t)
    angle, err = world.path.radial_error(p)
    cut = (t >= 0.0) & (t <= world.path.duration)
    return {"t": t, "p": p, "angle": angle, "err_mm": err * 1000.0, "cut": cut, "force": F_t}


def evaluate_uncompensated(world: World, stub: RobotStub, period_s: float) -> dict[str, np.ndarray]:
    """`evaluate` for a pass without compensation, from the world and the stub alone: the PLC would
    command q_ref at every cycle (``period_s`` apart), which nothing in the service changes, so the
    path error needs no process. The same figure as an uncompensated pass, without its jitter."""
    t = np.arange(world.t_start, world.t_end, period_s)
    q = np.array([world.path.q_ref_deg(x) for x in t])
    return evaluate(world, stub, {"t": t, "q_cmd": q})


def errors(ev: dict) -> tuple[float, float]:
    """(mean, max) absolute path error over the cut, mm."""
    e = np.abs(ev["err_mm"][ev["cut"]])
    return float(e.mean()), float(e.max())


def plot(world: World, passes: dict[str, dict], path: str | Path, exaggerate: float = 20.0) -> Path:
    """`circle_figure` written to ``path`` (PNG)."""
    path = Path(path)
    circle_figure(world, passes, exaggerate).savefig(path, dpi=130)
    return path


def circle_figure(world: World, passes: dict[str, dict], exaggerate: float = 20.0) -> Figure:
    """Fig. 8: (a) nominal, uncompensated and compensated paths (radial error exaggerated), (b) the error
    around the circle; the legend below both, off the data."""
    r_mm = world.path.radius * 1000.0
    fig = Figure(figsize=(12, 5.6), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, aspect="equal")
    th = np.linspace(0, 2 * np.pi, 721)
    ax.plot(r_mm * np.cos(th), r_mm * np.sin(th), "k-", lw=1.2, label="nominal")
    styles = {"uncompensated": ("tab:red", "-"), "compensated": ("tab:blue", "-")}
    for name, ev in passes.items():
        c = ev["cut"]
        rr = r_mm + exaggerate * ev["err_mm"][c]
        ax.plot(rr * np.cos(ev["angle"][c]), rr * np.sin(ev["angle"][c]), color=styles[name][0], lw=0.9,
                label=f"{name} (error x{exaggerate:g})")
    ax.set_xlabel("x in the circle's plane, mm")
    ax.set_ylabel("y, mm")
    ax.set_title(f"a) milled circle, r = {r_mm:g} mm")
    bx = fig.add_subplot(1, 2, 2)
    for name, ev in passes.items():
        c = ev["cut"]
        mean = np.abs(ev["err_mm"][c]).mean()
        bx.plot(np.degrees(ev["angle"][c]), ev["err_mm"][c], color=styles[name][0], lw=0.8,
                label=f"{name}: mean |e| {mean:.3f} mm")
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_xlabel("angle along the circle, deg")
    bx.set_ylabel("point-to-point (radial) error, mm")
    bx.set_title("b) point-to-point error")
    bx.grid(alpha=0.3)
    legend_below(fig, ax, bx, ncols=3)
    return fig
