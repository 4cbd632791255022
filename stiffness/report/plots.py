"""Report plots: pure functions returning matplotlib Figures (object API, no display needed).

`deflection_vs_load` is the paper's Fig. 4: a deflection component against the load, measured
(dots) and modelled (lines), for every measured body, coloured by configuration.
"""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ..data.measurements import COMPONENTS, Dataset
from ..kinematics.robot import BODIES

UNITS = {c: ("mm" if k < 3 else "deg") for k, c in enumerate(COMPONENTS)}
LINESTYLES = ("--", "-", ":", "-.")
MAX_LEGEND_CONFIGS = 12
BAR_COLOURS = ("#9e9e9e", "#1f77b4", "#ff7f0e", "#2ca02c")   # first model grey: "before"


def config_colours(configs: list[str]) -> dict[str, tuple]:
    """A distinct colour per configuration (tab10 up to 10, then a continuous map)."""
    cmap = colormaps["tab10"] if len(configs) <= 10 else colormaps["viridis"]
    n = max(len(configs) - 1, 1)
    return {c: cmap(k if len(configs) <= 10 else k / n) for k, c in enumerate(configs)}


def deflection_vs_load(data: Dataset, direction: np.ndarray, predictions: list[tuple[str, np.ndarray]],
                       component: str) -> Figure:
    """One component's deflection against the load along each tool axis, per body (Fig. 4).

    Parameters
    ----------
    data : Dataset
        The measurements; x is the sensor force along the column's axis (N).
    direction : (N,) str
        Each row's load direction ("+x" .. "-z", "none"; `stiffness.compare.comparison.load_direction`).
        A column holds the readings loaded along its axis and the unloaded ones.
    predictions : list of (name, (N, 6) array)
        Modelled deflections (mm, deg); each model is drawn as lines in the order readings were
        taken, one line style per model.
    component : str
        One of dx, dy, dz (mm), rx, ry, rz (deg).
    """
    k = COMPONENTS.index(component)
    bodies = [b for b in range(len(BODIES)) if np.any(data.body == b)]
    axes_present = [a for a in range(3) if np.any(np.char.endswith(direction.astype(str), "xyz"[a]))]
    axes_present = axes_present or [0]
    configs = data.configs
    colours = config_colours(configs)
    nr, nc = len(bodies), len(axes_present)
    # fixed margins (inches): a layout engine would cost seconds per figure on a 21-panel grid
    w, h = 3.4 * nc + 1.0, 1.9 * nr + 1.3
    fig = Figure(figsize=(w, h))
    fig.subplots_adjust(left=0.85 / w, right=1 - 0.15 / w, bottom=0.95 / h, top=1 - 0.75 / h,
                        wspace=0.28, hspace=0.12)
    grid = fig.subplots(nr, nc, squeeze=False, sharex="col")
    styles = ("-",) if len(predictions) == 1 else LINESTYLES
    for i, b in enumerate(bodies):
        for j, a in enumerate(axes_present):
            ax = grid[i, j]
            axis = "xyz"[a]
            on = (data.body == b) & np.isin(direction, [f"+{axis}", f"-{axis}", "none"])
            for cfg in configs:
                rows = np.nonzero(on & (data.config == cfg))[0]
                if not len(rows):
                    continue
                rows = rows[np.argsort(data.time_s[rows], kind="stable")]
                x = data.wrench[rows, a]
                ax.plot(x, data.deflection[rows, k], ".", ms=3.5, color=colours[cfg], alpha=0.75)
                for (_, yhat), ls in zip(predictions, styles):
                    ax.plot(x, yhat[rows, k], ls, lw=1.1, color=colours[cfg])
            ax.grid(True, lw=0.4, alpha=0.5)
            ax.tick_params(labelsize=7)
            if i == nr - 1:
                ax.set_xlabel(f"F{axis} at the sensor [N]", fontsize=8)
            if j == 0:
                ax.set_ylabel(f"{BODIES[b]}\n{component} [{UNITS[component]}]", fontsize=8)
            if i == 0:
                ax.set_title(f"load along {axis}", fontsize=9)
    _legend(fig, configs, colours, [n for n, _ in predictions], styles)
    fig.suptitle(f"{component}: measured (dots) and modelled (lines) against load", fontsize=11,
                 y=1 - 0.15 / h)
    return fig


def legend_below(fig: Figure, *axes, ncols: int | None = None, markerscale: float = 1.0) -> None:
    """The legend entries of ``axes`` as one legend below them, off the data (the figure must use
    the constrained layout, which makes room). The one place plots put a legend."""
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(handles, labels, loc="outside lower center", ncols=ncols or min(len(handles), 6), fontsize=8,
               frameon=False, markerscale=markerscale)


def _legend(fig: Figure, configs: list[str], colours: dict, models: list[str], styles) -> None:
    handles = [Line2D([], [], ls="none", marker=".", ms=8, color="0.3", label="measured")]
    handles += [Line2D([], [], ls=ls, color="0.3", label=name) for name, ls in zip(models, styles)]
    if len(configs) <= MAX_LEGEND_CONFIGS:
        handles += [Line2D([], [], ls="-", lw=4, color=colours[c], label=c) for c in configs]
    else:
        handles.append(Line2D([], [], ls="none", label=f"colour: {len(configs)} configurations"))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 8), fontsize=8, frameon=False)


def rms_bars(groups: list[tuple[str, dict[str, dict]]], what: str,
             noise: tuple[float, float] | None = None) -> Figure:
    """RMS error per group (body, configuration, ...) side by side for each model.

    Parameters
    ----------
    groups : list of (model name, {group: metrics})
        Metrics as `stiffness.compare.comparison.summary` returns them.
    what : str
        The grouping, for the title ("body", "configuration", "load direction").
    noise : (position_mm, rotation_deg), optional
        The expected measurement noise, drawn as a dashed line: the floor no model can go below.
    """
    keys = list(dict.fromkeys(k for _, g in groups for k in g))
    fig = Figure(figsize=(max(6.0, 0.55 * len(keys) * max(len(groups), 1) + 2), 3.4), layout="constrained")
    axes = fig.subplots(1, 2)
    width = 0.8 / max(len(groups), 1)
    x = np.arange(len(keys))
    for n, (ax, metric, label) in enumerate(zip(axes, ("rms_position_mm", "rms_rotation_deg"),
                                                ("RMS position error [mm]", "RMS rotation error [deg]"))):
        if noise is not None:
            ax.axhline(noise[n], ls="--", lw=1, color="k", label="expected noise")
        for m, (name, g) in enumerate(groups):
            vals = [g[k][metric] if k in g else np.nan for k in keys]
            ax.bar(x + (m - (len(groups) - 1) / 2) * width, vals, width, label=name,
                   color=BAR_COLOURS[(m + (len(groups) == 1)) % 4])
        ax.set_xticks(x, keys, rotation=45 if len(keys) > 8 else 0, fontsize=8)
        ax.set_ylabel(label, fontsize=9)
        ax.tick_params(axis="y", labelsize=8)
        ax.grid(True, axis="y", lw=0.4, alpha=0.5)
    legend_below(fig, axes[0])
    fig.suptitle(f"RMS error per {what}", fontsize=11)
    return fig
