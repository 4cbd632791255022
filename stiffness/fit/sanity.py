"""Sanity checks on a loaded campaign that a reader cannot make row by row, said in words.

* Duplicates. A row may repeat an earlier one exactly (every column, as a copy-paste or a merged
  export makes), or measure a body a second time in one reading (same configuration, time, joint
  angles and wrench) with other values. Either would count as a repeated reading and lower the noise
  estimate, so both are named, then left out (the first copy kept) or kept as the user chooses.
* Units. The noise seen between repeated readings (`residuals.pure_error`) is compared with the
  model's ``noise``; more than NOISE_RATIO apart in either direction most often means a unit slip
  (millimetres written as metres, degrees as radians).
"""

from __future__ import annotations

import numpy as np

from ..data.campaign import Context
from ..data.measurements import Dataset
from ..data.residuals import pure_error
from ..kinematics.robot import BODIES
from ..model.stiffness_model import StiffnessModel

NOISE_RATIO = 10.0
SHOW_LINES = 20


def duplicate_rows(data: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(exact, same_body): boolean (N,) masks of the rows that repeat an earlier row of the file.

    ``exact`` repeats an earlier row in every column; ``same_body`` measures a body of a reading
    (same config, time, joint angles and wrench) again, with other deflection values. The first row
    of each is in neither mask.
    """
    n = len(data)
    if n == 0:
        return np.zeros(0, bool), np.zeros(0, bool)
    _, reading = data.readings()
    key = reading * len(BODIES) + data.body
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    earlier = first[inv.reshape(-1)]
    later = earlier != np.arange(n)
    a, b = data.deflection, data.deflection[earlier]
    same = np.all((a == b) | (np.isnan(a) & np.isnan(b)), axis=1)
    return later & same, later & ~same


def resolve_duplicates(data: Dataset, keep: bool = False) -> tuple[Dataset, list[str]]:
    """The campaign without its duplicate rows (or with them, ``keep``) and a warning per kind found."""
    exact, same_body = duplicate_rows(data)
    what = "kept (as asked)" if keep else "left out, the first copy kept (--keep-duplicates keeps them)"
    warnings = []
    for mask, text in ((exact, "repeat an earlier row exactly"),
                       (same_body, ("measure a body again in one reading (same config, time, joint angles "
                                   "and wrench) with other values"))):
        if mask.any():
            warnings.append(f"{data.source}: {int(mask.sum())} row(s) {text}, at line(s) "
                            f"{_lines(data, mask)}; {what}. A copy counts as a repeated reading and lowers "
                            "the noise estimate")
    if keep or not (exact.any() or same_body.any()):
        return data, warnings
    return data.subset(~(exact | same_body)), warnings


def noise_warning(model: StiffnessModel, ctx: Context, y: np.ndarray) -> str | None:
    """A warning when the noise between repeated readings is more than NOISE_RATIO from the model's
    ``noise`` (per kind, position and rotation), naming the likely unit slip; None otherwise or when
    the data hold too few repeats to tell."""
    seen = pure_error(ctx, y)
    if seen is None:
        return None
    out = []
    for kind, unit, slip in (("position_mm", "mm", "millimetres given as metres (1000x)"),
                             ("rotation_deg", "deg", "degrees given as radians (57x) or as mdeg")):
        measured, stated = seen[kind], model.noise[kind]
        if not np.isfinite(measured) or measured <= 0:
            continue
        ratio = measured / stated
        if ratio > NOISE_RATIO or ratio < 1 / NOISE_RATIO:
            side = f"{ratio:.3g}x" if ratio > 1 else f"1/{1 / ratio:.3g}"
            out.append(f"{kind.split('_')[0]} {measured:.3g} {unit} is {side} of the model's noise.{kind} "
                       f"({stated:g} {unit}); likely a unit slip in the data, e.g. {slip}, or a wrong noise "
                       "section in the model")
    if not out:
        return None
    return (f"{ctx.data.source}: the noise between repeated readings differs from the model's by more than "
            f"{NOISE_RATIO:g}x: " + "; ".join(out) + ". Check the deflection columns' units "
            "(docs/measurement_format.md)")


def _lines(data: Dataset, mask: np.ndarray) -> str:
    lines = data.line[mask]
    more = f" and {len(lines) - SHOW_LINES} more" if len(lines) > SHOW_LINES else ""
    return ", ".join(map(str, lines[:SHOW_LINES])) + more
