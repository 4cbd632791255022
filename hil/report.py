"""Path errors of a pass and the Fig. 8 plot (machined circle and point-to-point error).

The path error of a cycle is the point-to-point error of Fig. 8b: the actual TCP's distance from the
circle's centre in the circle's plane minus the radius (mm; + outside). The cutter's edge, not its
tangential position, makes the machined contour, so this is the error a CMM would measure. Only
cycles of the cut (0 <= t <= one circle) count.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from stiffness.report.plots import legend_below

from .device_log import Track
from .robot_stub import RobotStub
from .world import World

if TYPE_CHECKING:
    from stiffness.model.stiffness_model import StiffnessModel

    from .run import PassResult
    from .scenario import Scenario


@dataclass(frozen=True, eq=False)
class Evaluation:
    """A pass as the robot stub cut it, per cycle: its time (s), the actual TCP (base, m, (n, 3)), its angle about
    the circle's centre (rad), its radial path error (mm, + outside), whether the cycle is of the cut
    (0 <= t <= one circle) and the process force at the tool (N, base, (n, 3))."""

    t: np.ndarray
    p: np.ndarray
    angle: np.ndarray
    err_mm: np.ndarray
    cut: np.ndarray
    force: np.ndarray


def evaluate(world: World, stub: RobotStub, track: Track) -> Evaluation:
    """Actual TCP, path angle and radial error (mm) of every cycle of a pass's ``track`` (its device's log)."""
    t = np.asarray(track.t)
    p, F_t = stub.actual(t, np.asarray(track.q_cmd), world.force, world.t_start, world.t_end)
    angle, err = world.path.radial_error(p)
    cut = (t >= 0.0) & (t <= world.path.duration)
    return Evaluation(t=t, p=p, angle=angle, err_mm=err * 1000.0, cut=cut, force=F_t)


def evaluate_pass(scenario: Scenario, truth: StiffnessModel, result: PassResult) -> tuple[World, Evaluation]:
    """The world of ``scenario`` and `evaluate` of a pass's ``result`` (real time or lock step: its ``log``) on
    the robot stub of ``truth``."""
    world = World(scenario, truth.robot)
    return world, evaluate(world, RobotStub(truth, scenario.robot, scenario.payload), result.log)


def evaluate_uncompensated(world: World, stub: RobotStub, period_s: float) -> Evaluation:
    """`evaluate` for a pass without compensation, from the world and the stub alone: the PLC would
    command q_ref at every cycle (``period_s`` apart), which nothing in the service changes, so the
    path error needs no process. The same figure as an uncompensated pass, without its jitter."""
    t = np.arange(world.t_start, world.t_end, period_s)
    q = np.array([world.path.q_ref_deg(x) for x in t])
    return evaluate(world, stub, Track(t=t, q_ref=q, q_cmd=q))


WINDOW_S = 0.1          # the entry and exit windows: this long after the force starts and after the circle closes
LAGS_S = np.arange(0.0, 0.0605, 0.0005)      # the delays the end-to-end estimate tries


def windows(world: World) -> dict[str, tuple[float, float]]:
    """The entry and exit windows (s since the cut started): the 100 ms after the tool meets the material,
    and the 100 ms after the circle closes (when the cutter leaves it)."""
    end = world.path.duration
    return {"entry": (0.0, WINDOW_S), "exit": (end, end + WINDOW_S)}


def window_errors(world: World, ev: Evaluation) -> dict[str, float]:
    """Peak and mean |path error| (mm) in the entry and exit windows and over the steady part of the cut (the
    cut without the windows): ``entry_peak_mm``, ``entry_mean_mm``, ``exit_…``, ``steady_peak_mm``, ``steady_mean_mm``."""
    t, e = ev.t, np.abs(ev.err_mm)
    out, inside = {}, np.zeros(len(t), dtype=bool)
    for name, (a, b) in windows(world).items():
        m = (t >= a) & (t <= b)
        inside |= m
        out[f"{name}_peak_mm"] = float(e[m].max()) if m.any() else float("nan")
        out[f"{name}_mean_mm"] = float(e[m].mean()) if m.any() else float("nan")
    steady = ev.cut & ~inside
    out["steady_peak_mm"], out["steady_mean_mm"] = float(e[steady].max()), float(e[steady].mean())
    return out


TOOTH_SAMPLES = 10     # the force averaged over one tooth period at this many points (the mean of a sinusoid
                       # and of its harmonics below the tenth over one period is zero)
ALIAS_MS = 4.0          # samples further apart than this: the force averaged over each one's interval


def end_to_end_delay(world: World, log: Track) -> float | None:
    """The delay (s) from the force at the tool to the correction the PLC applied: the lag at which the
    applied correction's TCP displacement, FK(q_cmd) - FK(q_ref), is best explained as a linear function of
    the process force (least squares over `LAGS_S`, refined on a parabola); None without a correction, and
    None when the best lag is an end of `LAGS_S`: then no delay in the range explains it (a truth with an
    effect far from linear in the force, e.g. a hysteresis that flips twice per circle, pulled the fit to 0).

    The raw force's tooth-passing content times the fit finely but gives it a minimum every tooth period (the
    400 Hz teeth sampled by a 2 ms PLC: minima 1-2.5 ms apart), and the lowest of them can be the wrong one: on
    a quiet host the best lag read 6.0 ms in one run, below what the filters alone hold back, and 8.0 or 10.0
    in others. So the force averaged over one tooth period, centred (no lag of its own, no tooth content: one
    minimum), picks the basin first, and the raw force's lowest minimum within half a tooth period of it is the
    delay. Where the log's samples lie further apart than `ALIAS_MS` (a robot road at 12 ms or more), the force
    is averaged over the interval each sample stands for instead (a millisecond grid over several tooth
    periods): RSI at 12 ms read 5.5 ms on the raw force, for a chain whose filters alone hold back 6.5 (with the
    average: 7.6-8.1 ms, as at 4 ms)."""
    t = np.asarray(log.t)
    use = (t >= 0.0) & (t <= world.t_end)
    if use.sum() < 50:
        return None
    step_s = float(np.median(np.diff(t[use])))
    half = int(step_s * 1000.0 / 2.0) if step_s * 1000.0 > ALIAS_MS else 0
    if half:
        return _best(delay_cost(world, log, np.arange(-half, half + 1) * 1e-3))
    tooth_s = 1.0 / world.milling.f_tooth
    basin = _best(delay_cost(world, log, (np.arange(TOOTH_SAMPLES) + 0.5) / TOOTH_SAMPLES * tooth_s - tooth_s / 2))
    if basin is None:
        return None
    raw = delay_cost(world, log, np.zeros(1))
    return _best(raw, np.abs(LAGS_S - basin) <= tooth_s / 2)


def _best(cost: np.ndarray | None, within: np.ndarray | None = None) -> float | None:
    """The lag of the lowest ``cost`` (among the lags ``within``, default all), refined on the parabola through
    it and its neighbours; None at an end of `LAGS_S`."""
    if cost is None:
        return None
    k = int(np.argmin(np.where(within, cost, np.inf) if within is not None else cost))
    if not 0 < k < len(cost) - 1:
        return None
    c0, c1, c2 = cost[k - 1: k + 2]
    den = c0 - 2 * c1 + c2
    return float(LAGS_S[k] + (0.5 * (c0 - c2) / den if den > 0 else 0.0) * (LAGS_S[1] - LAGS_S[0]))


def delay_cost(world: World, log: Track, window: np.ndarray) -> np.ndarray | None:
    """The least-squares misfit of the applied correction's TCP displacement by the force averaged over
    ``window`` (s, offsets about each sample) at each lag of `LAGS_S` (`end_to_end_delay`); None without a
    correction."""
    t = np.asarray(log.t)
    use = (t >= 0.0) & (t <= world.t_end)
    robot = world.robot
    moved = (robot.frames(np.radians(np.asarray(log.q_cmd)[use]))[:, 7, :3, 3]
             - robot.frames(np.radians(np.asarray(log.q_ref)[use]))[:, 7, :3, 3])
    if np.abs(moved).max() < 1e-7:
        return None
    moved = moved - moved.mean(axis=0)
    cost = []
    for lag in LAGS_S:
        f = np.mean([world.force(t[use] - lag + w) for w in window], axis=0)
        X = np.column_stack([f, np.ones(len(f))])
        cost.append(float(np.sum((moved - X @ np.linalg.lstsq(X, moved, rcond=None)[0]) ** 2)))
    return np.array(cost)


STYLES = {"uncompensated": ("tab:red", "-"), "compensated": ("tab:blue", "-"), "dynamic": ("tab:green", "-")}


def label(name: str, passes: dict) -> str:
    """A pass's name in a legend: with a dynamic pass beside it, the compensated one is the static one."""
    if "dynamic" in passes:
        return {"compensated": "static compensation", "dynamic": "dynamic compensation"}.get(name, name)
    return name


def errors(ev: Evaluation) -> tuple[float, float]:
    """(mean, max) absolute path error over the cut, mm."""
    e = np.abs(ev.err_mm[ev.cut])
    return float(e.mean()), float(e.max())


def plot(world: World, passes: dict[str, Evaluation], path: str | Path, exaggerate: float = 20.0) -> Path:
    """`circle_figure` written to ``path`` (PNG)."""
    path = Path(path)
    circle_figure(world, passes, exaggerate).savefig(path, dpi=130)
    return path


def circle_figure(world: World, passes: dict[str, Evaluation], exaggerate: float = 20.0) -> Figure:
    """Fig. 8: (a) nominal, uncompensated and compensated paths (radial error exaggerated), (b) the error
    around the circle; the legend below both, off the data."""
    r_mm = world.path.radius * 1000.0
    fig = Figure(figsize=(12, 5.6), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, aspect="equal")
    th = np.linspace(0, 2 * np.pi, 721)
    ax.plot(r_mm * np.cos(th), r_mm * np.sin(th), "k-", lw=1.2, label="nominal")
    styles = STYLES
    for name, ev in passes.items():
        c = ev.cut
        rr = r_mm + exaggerate * ev.err_mm[c]
        ax.plot(rr * np.cos(ev.angle[c]), rr * np.sin(ev.angle[c]), color=styles[name][0], lw=0.9,
                label=f"{label(name, passes)} (error x{exaggerate:g})")
    ax.set_xlabel("x in the circle's plane, mm")
    ax.set_ylabel("y, mm")
    ax.set_title(f"a) milled circle, r = {r_mm:g} mm")
    bx = fig.add_subplot(1, 2, 2)
    for name, ev in passes.items():
        c = ev.cut
        mean = np.abs(ev.err_mm[c]).mean()
        bx.plot(np.degrees(ev.angle[c]), ev.err_mm[c], color=styles[name][0], lw=0.8,
                label=f"{label(name, passes)}: mean |e| {mean:.3f} mm")
    bx.axhline(0.0, color="k", lw=0.6)
    bx.set_xlabel("angle along the circle, deg")
    bx.set_ylabel("point-to-point (radial) error, mm")
    bx.set_title("b) point-to-point error")
    bx.grid(alpha=0.3)
    legend_below(fig, ax, bx, ncols=3)
    return fig


def windows_figure(world: World, passes: dict[str, Evaluation]) -> Figure:
    """The path error in the entry and the exit windows (and 50 ms either side), each pass a line."""
    fig = Figure(figsize=(12, 4.4), layout="constrained")
    axes = []
    for k, (name, (a, b)) in enumerate(windows(world).items()):
        ax = fig.add_subplot(1, 2, k + 1)
        for pname, ev in passes.items():
            m = (ev.t >= a - 0.05) & (ev.t <= b + 0.05)
            ax.plot(1000 * (ev.t[m] - a), ev.err_mm[m], color=STYLES[pname][0], lw=0.9,
                    label=label(pname, passes))
        ax.axvspan(0, 1000 * (b - a), color="0.9")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_xlabel(f"ms after the {name} (shaded: the {name} window)")
        ax.set_ylabel("path error, mm")
        ax.set_title(f"{name}")
        ax.grid(alpha=0.3)
        axes.append(ax)
    legend_below(fig, *axes, ncols=3)
    return fig
