"""Compare a model with a machined part: the part's error, the arm's deflection that made it, and the model's
own account of both (`stiffcomp part compare`, docs/part.md).

Along the surface normal n at each point (`stiffness.part.rows`):

=================  ===============================================================================
part error         the point's deviation from the nominal contour, as the CMM reports it (Fig. 8b)
deflection e       how far the arm was deflected along n when the tool made the point
model              what the model predicts of e at the trace's joints and wrench (n . dX)
missed             e - model: the part error the model would leave with a perfect correction
correction         how far the service's correction moved the tool along n (from the trace)
=================  ===============================================================================

The part error is e plus the correction's move: the correction cancels what the model predicted, so the
part error is what the model missed plus what the correction did not deliver (its delay, its limits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.campaign import Context
from ..effects.axial import joint_torque
from ..model.stiffness_model import StiffnessModel
from .rows import PartRows
from .timing import when_made


@dataclass
class PartComparison:
    """A model against one part: arrays over the part's used points, in the part's point order."""

    rows: PartRows
    model: StiffnessModel
    model_mm: np.ndarray           # n . dX predicted by the model
    torque: np.ndarray             # (n, 6) the joints' external torques at the points, Nm
    ctx: Context

    @property
    def missed_mm(self) -> np.ndarray:
        return self.rows.deviation_mm - self.model_mm

    def summary(self) -> dict:
        r = self.rows
        return {"points": int(r.used.sum()), "left_out_count": len(r.left_out),
                "left_out": [x.to_dict() for x in r.left_out], "trace_gaps": [g.to_dict() for g in r.gaps],
                "part_error_mean_mm": _mean_abs(r.nominal_mm), "part_error_max_mm": _max_abs(r.nominal_mm),
                "deflection_mean_mm": float(np.mean(r.deviation_mm)),
                "model_missed_rms_mm": float(np.sqrt(np.mean(self.missed_mm ** 2))),
                "model_missed_max_mm": _max_abs(self.missed_mm),
                "correction_mean_mm": float(np.mean(r.correction_mm)),
                "notes": list(r.notes)}

    def lines(self) -> list[str]:
        s = self.summary()
        r = self.rows
        left = (f" of {len(r.used)} ({s['left_out_count']} left out, named below; every figure is over the "
                f"{s['points']} used)" if s["left_out_count"] else "")
        return [f"part {r.part.source} against the trace {r.trace.source}: {s['points']} points{left}",
                (f"part error against the nominal contour: mean {s['part_error_mean_mm']:.4f} mm, "
                f"max {s['part_error_max_mm']:.4f} mm"),
                (f"the arm's deflection along the normal when each point was cut: mean {s['deflection_mean_mm']:+.4f} mm "
                f"({r.deviation_mm.min():+.4f} to {r.deviation_mm.max():+.4f})"),
                (f"{self.model.name} predicts it to RMS {s['model_missed_rms_mm']:.4f} mm (max {s['model_missed_max_mm']:.4f} "
                "mm): what it misses is what a perfect correction would still leave on the part"),
                f"the service's correction moved the tool {s['correction_mean_mm']:+.4f} mm along the normal (mean)",
                *r.notes]


def compare_part(model: StiffnessModel, rows: PartRows) -> PartComparison:
    """The model's account of the part read against its trace (each point when the model says it was made)."""
    rows = when_made(rows, model)
    data = rows.dataset(model.robot, model.input_map())
    ctx = model.context(data)
    pred = model.predict(ctx)[:, 0]
    return PartComparison(rows, model, at_points(rows, data, pred), at_points(rows, data, np.stack(
        [joint_torque(ctx.frame_wrench, j)[ctx.row_reading] for j in range(1, 7)], axis=1)), ctx)


def at_points(rows: PartRows, data, values: np.ndarray) -> np.ndarray:
    """``values`` over the rows of ``rows.dataset(...)`` (``data``), taken at the points, in the part's order."""
    measured = np.nonzero(data.measured[:, 0])[0]
    out = np.empty((len(rows.t),) + values.shape[1:])
    out[np.argsort(rows.t, kind="stable")] = values[measured]
    return out


def _mean_abs(x: np.ndarray) -> float:
    return float(np.mean(np.abs(x)))


def _max_abs(x: np.ndarray) -> float:
    return float(np.max(np.abs(x)))
