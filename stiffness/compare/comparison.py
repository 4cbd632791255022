"""Model against measurement without fitting: error metrics overall and by body, component,
configuration and load direction, for one model or two side by side (docs/compare.md). The HTML
report of a comparison is `stiffness.compare.report`.

Metrics, for a set of rows and one kind (position: dx, dy, dz in mm; rotation: rx, ry, rz in deg),
with e = measured - predicted:

    RMS  = sqrt(mean over rows and the 3 components of e^2)    (per component, as `identify.rms`)
    max  = max over rows and components of |e|
    R^2  = 1 - sum e^2 / sum (y - ybar)^2,   ybar the mean of each component over the rows

R^2 is 1 when the set has no spread and no error, and undefined (NaN, null in JSON) when it has no
spread but some error. Per component, the same formulas use that one column. Only measured entries
count (a laser tracker measures no rotation: its rotation metrics are NaN, null in JSON).

The load direction of a reading is the dominant axis of the measured sensor force with its sign
("+x", "-x", ..., "-z"), or "none" when |F| is below 5 % of the campaign's largest |F|.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data.measurements import COMPONENTS, Dataset
from ..fit.result import rms
from ..kinematics.robot import BODIES
from ..model.stiffness_model import StiffnessModel

DIRECTIONS = ("+x", "-x", "+y", "-y", "+z", "-z", "none")
NONE_FRACTION = 0.05
NOISE_LEVEL = 1.5   # RMS below this many times the model's expected noise: "at the noise level"
NOISE_FAR = 3.0


def r2(y: np.ndarray, yhat: np.ndarray) -> float:
    """Coefficient of determination over all entries, each column centred on its own mean."""
    y = np.asarray(y, dtype=float).reshape(len(y), -1)
    ok = np.isfinite(y)
    if not ok.any():
        return float("nan")
    ss_res = float(np.nansum(np.square(y - np.asarray(yhat).reshape(y.shape))))
    mean = np.array([np.nanmean(c) if np.isfinite(c).any() else 0.0 for c in y.T])
    ss_tot = float(np.nansum(np.square(y - mean)))
    if ss_tot == 0.0:
        return 1.0 if ss_res == 0.0 else float("nan")
    return 1.0 - ss_res / ss_tot


def _rms_error(y: np.ndarray, yhat: np.ndarray) -> float:
    return rms(y - yhat)


def _max_error(y: np.ndarray, yhat: np.ndarray) -> float:
    return _max_abs(y - yhat)


def _r2_of_rows(y: np.ndarray, yhat: np.ndarray) -> float:
    return r2(y, yhat) if len(y) else float("nan")


@dataclass(frozen=True)
class Metric:
    """One error metric of a set of rows: its key in the metrics (and the JSON), its words in the
    reports, the kind of deflection it measures and how."""

    key: str                                              # e.g. "rms_position_mm"
    label: str                                            # the overall table's row: "RMS position [mm]"
    column: str                                           # a group table's column: "RMS mm"
    kind: str                                             # "position" (dx, dy, dz) or "rotation" (rx, ry, rz)
    stat: Callable[[np.ndarray, np.ndarray], float]       # (measured, predicted) of that kind -> value

    def of(self, y: np.ndarray, yhat: np.ndarray) -> float:
        sl = KIND_COLUMNS[self.kind]
        return self.stat(y[:, sl], yhat[:, sl])


KIND_COLUMNS = {"position": slice(0, 3), "rotation": slice(3, 6)}
METRICS = (
    Metric("rms_position_mm", "RMS position [mm]", "RMS mm", "position", _rms_error),
    Metric("rms_rotation_deg", "RMS rotation [deg]", "RMS deg", "rotation", _rms_error),
    Metric("max_position_mm", "max |error| position [mm]", "max mm", "position", _max_error),
    Metric("max_rotation_deg", "max |error| rotation [deg]", "max deg", "rotation", _max_error),
    Metric("r2_position", "R² position", "R² pos", "position", _r2_of_rows),
    Metric("r2_rotation", "R² rotation", "R² rot", "rotation", _r2_of_rows),
)


def summary(y: np.ndarray, yhat: np.ndarray) -> dict[str, Any]:
    """Every `METRICS` entry (RMS, max |error| and R² of position in mm and rotation in deg) and the
    number of rows, for rows y, yhat (n, 6)."""
    out: dict[str, Any] = {m.key: m.of(y, yhat) for m in METRICS}
    out["n_rows"] = len(y)
    return out


def by_component(y: np.ndarray, yhat: np.ndarray) -> dict[str, dict[str, Any]]:
    """Per component dx .. rz: RMS, max |error|, R^2 and the unit (mm or deg)."""
    out = {}
    for k, c in enumerate(COMPONENTS):
        e = y[:, k] - yhat[:, k]
        out[c] = {"rms": rms(e), "max": _max_abs(e),
                  "r2": r2(y[:, k], yhat[:, k]), "unit": "mm" if k < 3 else "deg"}
    return out


def _max_abs(e: np.ndarray) -> float:
    """max |e| over the measured (finite) entries; NaN when there are none."""
    e = np.abs(e[np.isfinite(e)])
    return float(e.max()) if e.size else float("nan")


def _noise_score(*terms: float) -> float:
    """Sum of squared noise ratios over the kinds that were measured (NaN terms left out)."""
    return float(sum(t**2 for t in terms if not np.isnan(t)))


def load_direction(data: Dataset, fraction: float = NONE_FRACTION) -> tuple[np.ndarray, float]:
    """Each row's load direction and the |F| threshold (N) below which it is "none"."""
    f = data.wrench[:, :3]
    mag = np.linalg.norm(f, axis=1)
    threshold = fraction * float(mag.max()) if len(mag) else 0.0
    axis = np.argmax(np.abs(f), axis=1)
    sign = np.sign(f[np.arange(len(f)), axis])
    labels = np.array([f"{'+' if s >= 0 else '-'}{'xyz'[a]}" for a, s in zip(axis, sign)], dtype=object)
    labels[mag <= threshold] = "none"
    return labels.astype(str), threshold


def grouped(keys: np.ndarray, order: list[str], y: np.ndarray, yhat: np.ndarray) -> dict[str, dict]:
    """`summary` for each group of rows with the same key, in ``order`` (absent keys skipped)."""
    return {k: summary(y[keys == k], yhat[keys == k]) for k in order if np.any(keys == k)}


@dataclass
class ModelResult:
    """One model's predictions and metrics on the data."""

    name: str
    source: str
    noise: dict[str, float]
    predicted: np.ndarray                 # (N, 6) mm, deg
    metrics: dict[str, Any] = field(default_factory=dict)


@dataclass
class Comparison:
    """Models against one dataset. ``models[1]`` (if any) is compared with ``models[0]``."""

    data: Dataset
    direction: np.ndarray
    threshold_N: float
    models: list[ModelResult]

    def change(self) -> dict[str, dict[str, float]] | None:
        """Overall metrics of the second model against the first: from, to, change, relative."""
        if len(self.models) < 2:
            return None
        a, b = self.models[0].metrics, self.models[1].metrics
        out = {}
        for key in (m.key for m in METRICS):
            rel = (b[key] - a[key]) / a[key] if a[key] else float("nan")
            out[key] = {"from": a[key], "to": b[key], "change": b[key] - a[key], "relative": rel}
        return out

    def better(self) -> str:
        """Name of the model with the smallest error, position and rotation each scaled by its noise."""
        def score(m: ModelResult) -> float:
            return _noise_score(m.metrics["rms_position_mm"] / m.noise["position_mm"],
                                m.metrics["rms_rotation_deg"] / m.noise["rotation_deg"])
        return min(self.models, key=score).name

    def verdict(self) -> tuple[str, str]:
        """A one-paragraph conclusion and its kind (good, warn, bad) for the report's top."""
        if len(self.models) == 1:
            return _single_verdict(self, self.models[0])
        ch = self.change()
        a, b = self.models[0], self.models[1]
        p, r = ch["rms_position_mm"], ch["rms_rotation_deg"]
        text = (f"{b.name} against {a.name}: RMS error {_verb(p['relative'])} from {p['from']:.4g} to "
                f"{p['to']:.4g} mm ({p['relative']:+.0%}) in position and {_verb(r['relative'])} from "
                f"{r['from']:.4g} to {r['to']:.4g} deg ({r['relative']:+.0%}) in rotation. "
                f"Better overall: {self.better()}.")
        detail, _ = _single_verdict(self, b)
        worse = [x for x in (p["relative"], r["relative"]) if x > 0.02]
        better = [x for x in (p["relative"], r["relative"]) if x < -0.02]
        kind = "good" if better and not worse else ("bad" if worse and not better else "warn")
        return text + "\n" + detail, kind

    def to_dict(self) -> dict[str, Any]:
        """The JSON structure documented in docs/compare.md."""
        out: dict[str, Any] = {
            "data": self.data.source, "rows": len(self.data), "configurations": self.data.configs,
            "load_threshold_N": self.threshold_N,
            "models": [{"name": m.name, "source": m.source, **m.metrics} for m in self.models],
        }
        if len(self.models) > 1:
            out["change"] = self.change()
            out["better"] = self.better()
        out["verdict"], out["verdict_kind"] = self.verdict()
        return out


def _verb(relative: float) -> str:
    return "falls" if relative < 0 else "rises"


def _single_verdict(comp: Comparison, m: ModelResult) -> tuple[str, str]:
    mt = m.metrics
    ratios = (mt["rms_position_mm"] / m.noise["position_mm"], mt["rms_rotation_deg"] / m.noise["rotation_deg"])
    worst = {g: _worst(mt[g], m.noise) for g in ("by_body", "by_config", "by_load_direction")}
    text = (f"{m.name}: RMS error {mt['rms_position_mm']:.4g} mm and {mt['rms_rotation_deg']:.4g} deg per "
            f"component ({ratios[0]:.1f}x and {ratios[1]:.1f}x the expected noise of {m.noise['position_mm']:g} mm "
            f"and {m.noise['rotation_deg']:g} deg), R² {mt['r2_position']:.3f} and {mt['r2_rotation']:.3f}. ")
    ratios = tuple(r for r in ratios if not np.isnan(r)) or (float("nan"),)
    if max(ratios) < NOISE_LEVEL:
        return text + "The model explains the data to the noise level.", "good"
    text += (f"Largest error at body {worst['by_body']}, configuration {worst['by_config']}, "
             f"load direction {worst['by_load_direction']}.")
    return text, ("warn" if max(ratios) < NOISE_FAR else "bad")


def _worst(groups: dict[str, dict], noise: dict[str, float]) -> str:
    """The group with the largest error, position and rotation RMS each scaled by its noise."""
    def score(k: str) -> float:
        g = groups[k]
        return _noise_score(g["rms_position_mm"] / noise["position_mm"], g["rms_rotation_deg"] / noise["rotation_deg"])
    return max(groups, key=score) if groups else "-"


def evaluate(model: StiffnessModel, data: Dataset, direction: np.ndarray, name: str | None = None) -> ModelResult:
    """Predict with ``model`` (no fitting) and compute all metrics."""
    yhat = model.predict(data)
    y = data.deflection
    metrics = summary(y, yhat)
    metrics["by_body"] = grouped(np.array(BODIES)[data.body], list(BODIES), y, yhat)
    metrics["by_component"] = by_component(y, yhat)
    metrics["by_config"] = grouped(data.config, data.configs, y, yhat)
    metrics["by_load_direction"] = grouped(direction, list(DIRECTIONS), y, yhat)
    return ModelResult(name or model.name, model.source, dict(model.noise), yhat, metrics)


def compare(models: list[StiffnessModel], data: Dataset) -> Comparison:
    """Evaluate one or two models on the same data. Equal names get a suffix so they stay apart."""
    direction, threshold = load_direction(data)
    names = [m.name for m in models]
    if len(set(names)) < len(names):
        names = [f"{n} ({k + 1})" for k, n in enumerate(names)]
    results = [evaluate(m, data, direction, n) for m, n in zip(models, names)]
    return Comparison(data, direction, threshold, results)
