"""A comparison (`stiffness.compare.comparison`) as an HTML page: verdict first, the overall table, the tables by
body, configuration, load direction and component, RMS bars and the Fig. 4 grids (docs/compare.md).

The group tables are long, not wide: one row per group and model, one column per `METRICS` entry, so
their width does not grow with the number of models or the length of their names.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.measurements import COMPONENTS
from ..report.html import Report
from .comparison import METRICS, Comparison

GROUPS = (("by_body", "body"), ("by_config", "configuration"), ("by_load_direction", "load direction"))
COMPONENT_STATS = (("rms", "RMS"), ("max", "max |error|"), ("r2", "R²"))


def build_report(comp: Comparison, command: str = "", plots: bool = True) -> Report:
    """The HTML report: verdict, overall table, tables by group, RMS bars and Fig. 4 grids."""
    from ..report import plots as P

    names = [m.name for m in comp.models]
    title = "Model against measurement: " + " vs ".join(names)
    rep = Report(title, f"{comp.data.source}: {len(comp.data)} rows, {len(comp.data.configs)} configurations; "
                        "predicted without fitting")
    text, kind = comp.verdict()
    rep.verdict(text, kind)
    rep.heading("Overall")
    header = ["metric", *names] + (["change"] if len(names) > 1 else [])
    ch = comp.change()
    rows = []
    for metric in METRICS:
        row = [metric.label, *(m.metrics[metric.key] for m in comp.models)]
        if ch:
            row.append(change_text(metric.key, ch[metric.key]))
        rows.append(row)
    rep.table(header, rows, "RMS per component; max |error| over rows and components; R² per kind")
    for group, what in GROUPS:
        rep.heading(f"By {what}")
        rep.table(*group_table(comp, group, what))
        if plots:
            noise = comp.models[-1].noise
            rep.figure(P.rms_bars([(m.name, m.metrics[group]) for m in comp.models], what,
                                  (noise["position_mm"], noise["rotation_deg"])),
                       f"rms_{group}", f"RMS error per {what}")
    rep.heading("By component")
    rep.table(*component_table(comp))
    if plots:
        rep.heading("Deflection against load (Fig. 4)")
        rep.paragraph("Each grid shows one component for every measured body (rows) and load axis "
                      f"(columns): measured readings as dots, the model{'s' if len(names) > 1 else ''} as "
                      "lines in the order the readings were taken, coloured by configuration. "
                      f"Readings with |F| below {comp.threshold_N:.3g} N count as unloaded and appear in "
                      "every column.")
        preds = [(m.name, m.predicted) for m in comp.models]
        for c in COMPONENTS:
            rep.figure(P.deflection_vs_load(comp.data, comp.direction, preds, c), f"load_{c}",
                       f"{c} [{'mm' if c.startswith('d') else 'deg'}] against load", dpi=80)
    if command:
        rep.heading("Reproduce")
        rep.preformatted(command)
    return rep


def change_text(key: str, ch: dict[str, float]) -> str | None:
    """Relative change for errors, absolute change for R² (a fraction already)."""
    if key.startswith("r2_"):
        return f"{ch['change']:+.3f}" if np.isfinite(ch["change"]) else None
    return f"{ch['relative']:+.1%}" if np.isfinite(ch["relative"]) else None


def _model_column(comp: Comparison) -> list[str]:
    """The model column, when there is more than one model to tell apart."""
    return ["model"] if len(comp.models) > 1 else []


def group_table(comp: Comparison, group: str, what: str) -> tuple[list[str], list[list[Any]], str]:
    """One row per group and model: the rows of the group and every metric."""
    header = [what, *_model_column(comp), "rows", *(m.column for m in METRICS)]
    rows = []
    for k in comp.models[0].metrics[group]:
        for m in comp.models:
            g = m.metrics[group][k]
            rows.append([k, *([m.name] if len(comp.models) > 1 else []), g["n_rows"],
                         *(g[metric.key] for metric in METRICS)])
    return header, rows, f"Error by {what}"


def component_table(comp: Comparison) -> tuple[list[str], list[list[Any]]]:
    """One row per component and model: its unit, RMS, max |error| and R²."""
    header = ["component", "unit", *_model_column(comp), *(label for _, label in COMPONENT_STATS)]
    rows = []
    for c in COMPONENTS:
        for m in comp.models:
            g = m.metrics["by_component"][c]
            rows.append([c, g["unit"], *([m.name] if len(comp.models) > 1 else []),
                         *(g[s] for s, _ in COMPONENT_STATS)])
    return header, rows
