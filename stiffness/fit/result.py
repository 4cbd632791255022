"""The outcome of a fit (`FitResult`) and the residual helpers every command reports with: the RMS over the
measured entries, its sentence, and the weights of a row's residual entries."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model.stiffness_model import StiffnessModel


@dataclass
class FitResult:
    """The outcome of a fit. ``converged`` is False when the optimiser stopped without converging.

    The RMS properties are over the rows used (not the gross errors) and the measured components.
    """

    model: StiffnessModel
    residual: np.ndarray                   # (N, 6) measured - predicted, mm / deg; NaN where not measured
    sigma: np.ndarray                      # (6,) noise used as weights
    std_error: np.ndarray                  # (P,) SI
    t_value: np.ndarray                    # (P,)
    undetermined: list[str]
    converged: bool = True
    message: str = ""
    warnings: list[str] = field(default_factory=list)
    unidentifiable: list[str] = field(default_factory=list)   # the data cannot determine these at all
    outlier: np.ndarray | None = None      # (N,) bool: rows judged gross errors, weight zero
    lines: np.ndarray | None = None        # (N,) the file line of each row
    preload: list[str] = field(default_factory=list)   # per identified static torque: what the data determine
    preload_evidence: list = field(default_factory=list)   # per identified static torque: `preload_fit.Evidence`
    covariance: np.ndarray | None = None   # (P, P) SI: the estimate's covariance (inf where not determined)

    def __post_init__(self) -> None:
        if self.outlier is None:
            self.outlier = np.zeros(len(self.residual), dtype=bool)

    @property
    def inlier(self) -> np.ndarray:
        return ~self.outlier

    @property
    def weights(self) -> np.ndarray:
        """(N, 6) the weight of each residual entry: 1 / sigma where measured and not a gross error."""
        return weights(np.isfinite(self.residual), self.inlier, self.sigma)

    @property
    def outlier_lines(self) -> list[int]:
        rows = np.nonzero(self.outlier)[0]
        return [int(v) for v in (self.lines[rows] if self.lines is not None else rows + 2)]

    def outliers(self) -> dict:
        """The rows judged gross errors by file line: ``{"count": N, "lines": [...]}`` (the JSON form)."""
        return {"count": int(self.outlier.sum()), "lines": self.outlier_lines}

    def outlier_text(self, limit: int = 30) -> str:
        """One line naming the rows judged gross errors by file line."""
        o = self.outliers()
        if not o["count"]:
            return "outliers: none"
        more = f" and {o['count'] - limit} more" if o["count"] > limit else ""
        return (f"outliers: {o['count']} row(s) judged gross errors and left out, at line(s) "
                + ", ".join(map(str, o["lines"][:limit])) + more)

    def rms_text(self) -> str:
        """'0.0301 mm, 0.00201 deg' (a kind not measured: 'rotation not measured')."""
        return rms_text(self.rms_position_mm, self.rms_rotation_deg)

    @property
    def rms_position_mm(self) -> float:
        return rms(self.residual[self.inlier, :3])

    @property
    def rms_rotation_deg(self) -> float:
        return rms(self.residual[self.inlier, 3:])


def rms(x: np.ndarray) -> float:
    """Root mean square over the measured (finite) entries (per component, not of the 3-D norm)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(np.square(x)))) if x.size else float("nan")


def rms_text(mm: float, deg: float) -> str:
    """Position and rotation RMS for a sentence; a kind not measured (NaN) says so."""
    pos = "position not measured" if np.isnan(mm) else f"{mm:.4f} mm"
    rot = "rotation not measured" if np.isnan(deg) else f"{deg:.5f} deg"
    return f"{pos}, {rot}"


def weights(measured: np.ndarray, inlier: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """(N, 6) residual weights: 1 / sigma for measured entries of rows in use, else 0."""
    return (measured & inlier[:, None]) / np.asarray(sigma, dtype=float)[None, :]
