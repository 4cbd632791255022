"""What is known of a model's parameters before new data: the prior of a fit (`identify.fit`).

A prior is a Gaussian over named parameters (the labels of `StiffnessModel.param_labels`): a mean and a
covariance. In a fit it adds, beside the data's rows, rows that hold the parameters near the mean,

    R (theta - theta_0),   R^T R = I_prior = pinv(covariance),

whitened like the data's rows (``(y - f(theta)) / sigma``), so the fit minimises both by the same least
squares. A direction the prior says nothing of (infinite variance: zero information) is free, and one the
new data do not see either stays where it starts (the fit's minimum-norm step).

Where a prior comes from:

* ``covariance`` in a model's YAML: `stiffcomp fit` stores what its campaign told of every parameter
  (standard errors and correlations, docs/model_format.md); `from_model` reads it back;
* a fit of a campaign given again: `from_fit`;
* a catalogue model with neither: `catalogue`, each parameter within a stated fraction of its value.

`stiffcomp part learn` fits a part's points with the model's prior, so the part moves only the
combinations of parameters it determines better than the prior did (`determined`).

Example: a prior of two compliances, the second unknown (no information).

>>> import numpy as np
>>> p = Prior(["a", "b"], np.array([1.0, 2.0]), np.diag([0.25, np.inf]), "example")
>>> R, c = p.rows(["a", "b"])
>>> R.round(6).tolist(), c.round(6).tolist()
([[2.0, 0.0]], [2.0])
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError, quote

RANK_TOL = 1e-10        # eigenvalues of the information below this share of the largest: no information


@dataclass
class Prior:
    """A Gaussian over named parameters (SI units).

    Parameters
    ----------
    labels : parameter labels (`StiffnessModel.param_labels`)
    mean : (P,) SI
    covariance : (P, P) SI^2; ``inf`` on the diagonal: nothing is known of that parameter
    source : what the prior came from, in words
    """

    labels: list[str]
    mean: np.ndarray
    covariance: np.ndarray
    source: str

    def information(self) -> np.ndarray:
        """I = pinv(covariance) over the labels (P, P); a parameter of infinite variance has none."""
        var = np.diag(self.covariance)
        known = np.isfinite(var) & (var > 0)
        info = np.zeros_like(self.covariance, dtype=float)
        if known.any():
            sub = self.covariance[np.ix_(known, known)]
            d = np.sqrt(np.diag(sub))
            lam, V = np.linalg.eigh(sub / np.outer(d, d))       # a correlation matrix: well scaled
            keep = lam > RANK_TOL * lam.max()
            inv = (V[:, keep] / lam[keep]) @ V[:, keep].T
            info[np.ix_(known, known)] = inv / np.outer(d, d)
        return info

    def rows(self, labels: list[str]) -> tuple[np.ndarray, np.ndarray]:
        """(R, c) for parameters ``labels`` (a model's, in its order): the prior's residual is
        R theta - c (k rows, in standard deviations); parameters the prior does not name are free."""
        where = {lab: k for k, lab in enumerate(self.labels)}
        idx = [where.get(lab, -1) for lab in labels]
        info = np.zeros((len(labels), len(labels)))
        mean = np.zeros(len(labels))
        own = self.information()
        have = np.array([k >= 0 for k in idx])
        src = np.array([k for k in idx if k >= 0], dtype=int)
        info[np.ix_(have, have)] = own[np.ix_(src, src)]
        mean[have] = self.mean[src]
        d = np.sqrt(np.clip(np.diag(info), 0.0, None))
        live = d > 0
        R = np.zeros((0, len(labels)))
        if live.any():
            sub = info[np.ix_(live, live)] / np.outer(d[live], d[live])
            lam, V = np.linalg.eigh(sub)
            keep = lam > RANK_TOL * lam.max()
            R = np.zeros((int(keep.sum()), len(labels)))
            R[:, live] = (np.sqrt(lam[keep])[:, None] * V[:, keep].T) * d[live]
        return R, R @ mean

    def std(self, labels: list[str]) -> np.ndarray:
        """The prior's standard deviation of each of ``labels`` (inf where it knows nothing)."""
        where = {lab: k for k, lab in enumerate(self.labels)}
        var = np.diag(self.covariance)
        return np.array([np.sqrt(var[where[lab]]) if lab in where and np.isfinite(var[where[lab]]) else np.inf
                         for lab in labels])

    def with_more(self, labels: list[str], std: np.ndarray) -> Prior:
        """This prior and, independent of it, parameters ``labels`` at 0 within ``std`` (SI): a weak prior keeps
        a nuisance parameter the data cannot see (a part's placement) where it is in a bounded fit."""
        n, k = len(self.labels), len(labels)
        cov = np.zeros((n + k, n + k))
        cov[:n, :n] = self.covariance
        cov[n:, n:] = np.diag(np.asarray(std, dtype=float) ** 2)
        return Prior(self.labels + list(labels), np.concatenate([self.mean, np.zeros(k)]), cov, self.source)

    # -- where priors come from -----------------------------------------------------------------------
    @classmethod
    def catalogue(cls, model, relative: float) -> Prior:
        """Each parameter independent, within ``relative`` of its value (1 sigma); a parameter at 0
        within ``relative`` of its fitting scale. For a model no campaign identified (a datasheet's)."""
        if not 0 < relative:
            raise ConfigError(f"the prior's relative uncertainty = {quote(relative)} must be > 0")
        theta = model.theta
        scale = np.array([p.scale for e in model.effects for p in e.params])
        sd = relative * np.where(theta != 0, np.abs(theta), scale)
        return cls(model.param_labels(), theta.copy(), np.diag(sd**2),
                   f"the model's values within {100 * relative:g} % each (no campaign covariance)")

    @classmethod
    def from_fit(cls, result, what: str) -> Prior:
        """The prior a fit leaves: its estimate and covariance (``FitResult.covariance``)."""
        m = result.model
        return cls(m.param_labels(), m.theta.copy(), result.covariance.copy(), what)

    @classmethod
    def from_model(cls, model) -> Prior | None:
        """The prior the model's YAML carries (``covariance``, written by `stiffcomp fit`), or None."""
        entry = getattr(model, "covariance", None)
        if entry is None:
            return None
        labels = model.param_labels()
        where = {lab: k for k, lab in enumerate(labels)}
        params = entry["params"]
        missing = [p for p in params if p not in where]
        if missing:
            raise ConfigError(f"{model.source}: covariance.params names {missing[0]}, which the model does not "
                              "hold (an effect was removed after the fit): fit the model again")
        factor = np.array([_param(model, where[p]).yaml_factor for p in params])
        sd = np.array([np.inf if s is None else float(s) for s in entry["std_error"]]) / factor
        corr = np.asarray(entry["correlation"], dtype=float)
        finite = np.isfinite(sd)
        cov = np.diag(np.where(finite, sd**2, np.inf))
        fin = np.nonzero(finite)[0]
        cov[np.ix_(fin, fin)] = corr[np.ix_(fin, fin)] * np.outer(sd[fin], sd[fin])
        mean = model.theta[[where[p] for p in params]]
        return cls(list(params), mean, cov, f"the covariance of {entry.get('source', 'the campaign')} "
                                            f"stored in {model.source}")


class PriorRows:
    """A prior's rows for one model: residual R theta - c (in standard deviations), empty without one."""

    def __init__(self, prior: Prior | None, model):
        P = len(model.theta)
        self.R, self.c = prior.rows(model.param_labels()) if prior is not None else (np.zeros((0, P)), np.zeros(0))

    def residual(self, theta: np.ndarray) -> np.ndarray:
        return self.R @ theta - self.c

    def information(self, scale: np.ndarray) -> np.ndarray:
        """R^T R in the parameters divided by ``scale`` (the fit's scaled units)."""
        Rs = self.R * scale
        return Rs.T @ Rs


def covariance_entry(model, covariance: np.ndarray, source: str) -> dict[str, Any]:
    """The model YAML's ``covariance`` section for ``covariance`` (P, P, SI) of its parameters:
    standard errors in the YAML's units (null: not determined) and correlations."""
    sd = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    finite = np.isfinite(sd) & (sd > 0)
    corr = np.eye(len(sd))
    fin = np.nonzero(finite)[0]
    corr[np.ix_(fin, fin)] = covariance[np.ix_(fin, fin)] / np.outer(sd[fin], sd[fin])
    factors = [p.yaml_factor for e in model.effects for p in e.params]
    return {"source": source, "params": model.param_labels(),
            "std_error": [float(f"{s * f:.6g}") if ok else None for s, f, ok in zip(sd, factors, finite)],
            "correlation": [[float(f"{c:.9g}") for c in row] for row in np.clip(corr, -1.0, 1.0)]}


def read_covariance(entry: Any, source: str) -> dict[str, Any] | None:
    """Validate a model YAML's ``covariance`` section (None when absent)."""
    if entry is None:
        return None
    where = f"{source}: covariance"
    if not isinstance(entry, dict) or not {"params", "std_error", "correlation"} <= set(entry):
        raise ConfigError(f"{where} must be a mapping with params, std_error and correlation (written by "
                          "`stiffcomp fit`, docs/model_format.md)")
    unknown = sorted(set(entry) - {"source", "params", "std_error", "correlation"})
    if unknown:
        raise ConfigError(f"{where}.{unknown[0]} is not a known key (known: source, params, std_error, correlation)")
    params, sd, corr = entry["params"], entry["std_error"], entry["correlation"]
    n = len(params) if isinstance(params, list) else -1
    if n < 1 or not all(isinstance(p, str) for p in params):
        raise ConfigError(f"{where}.params must be a list of parameter labels")
    if not isinstance(sd, list) or len(sd) != n or not all(
            s is None or (isinstance(s, (int, float)) and not isinstance(s, bool) and s >= 0) for s in sd):
        raise ConfigError(f"{where}.std_error must list {n} numbers >= 0 (null: not determined)")
    try:
        c = np.asarray(corr, dtype=float)
    except (TypeError, ValueError):
        c = np.zeros(0)
    if c.shape != (n, n) or not np.all(np.isfinite(c)) or np.any(np.abs(c) > 1.0 + 1e-9) \
            or not np.allclose(c, c.T, atol=1e-6):
        raise ConfigError(f"{where}.correlation must be a symmetric {n} x {n} matrix of numbers in [-1, 1]")
    return {"source": str(entry.get("source", "")), "params": list(params), "std_error": list(sd),
            "correlation": c.tolist()}


def _param(model, k: int):
    return [p for e in model.effects for p in e.params][k]
