"""Planning a campaign: the configurations that best determine a model for a measuring device.

Information. For a configuration q measured with the campaign protocol (load ramps along the flange
axes, `simulate.Campaign`), the linearised deflections are y = J(q) theta + e, with e the device's
noise (sigma per measured component, the model's ``noise`` section). In relative parameters
u_k = theta_k / |theta_k^0| the Fisher information of the configuration is

    F(q) = repeats * sum over its rows of J_u^T diag(m / sigma^2) J_u,      J_u = J diag(|theta^0|)

(m: 1 for a component the device measures, 0 otherwise), and a set S of configurations predicts
Cov(u) = (sum_{q in S} F(q))^-1: the relative standard error of parameter k is sqrt(Cov_kk).

Criterion. The plan minimises the worst relative standard error over the parameters of interest,
max_k sqrt(Cov_kk) (a minimax, or "G"-type, criterion on the parameters rather than on
predictions). Unlike D-optimality, which may leave one compliance poorly determined while
shrinking the volume of the confidence ellipsoid, it states directly what a person wants: no
compliance worse than the number printed. The parameters of interest are those the device can
determine at all (`identifiability`) and that an average set of N candidates determines to better
than MAX_RELATIVE; the others (e.g. translational compliances below the noise) are named.

Search. A candidate set of uniformly drawn configurations inside the joint limits less a margin;
a greedy start; Fedorov exchange over the candidates until no swap improves the criterion; then a
continuous refinement that perturbs each chosen configuration by shrinking steps and keeps what
improves. Wrench noise (errors in the variables) is neglected: it is small against the loads.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..fit.identifiability import unidentifiable_information
from ..fit.identify import jacobian
from ..kinematics.robot import BODIES
from ..model.stiffness_model import StiffnessModel
from .simulate import Campaign, CampaignSpec, LoadSpec, random_configurations

DEVICES = {
    # name: (bodies measured by default, components measured)
    "optical6d": (tuple(BODIES), (True,) * 6),
    "tracker": (("TCP",), (True, True, True, False, False, False)),
}
MAX_RELATIVE = 0.5      # parameters an average plan determines worse than this are not of interest
CANDIDATES = 160
STEPS_DEG = (12.0, 5.0, 2.0)
PERTURBATIONS = 6
CHUNK = 16


@dataclass
class Device:
    """What a measuring device sees: which bodies, which of the six components, with what noise."""

    name: str
    bodies: list[str]
    components: np.ndarray          # (6,) bool
    sigma: np.ndarray               # (6,) mm, deg

    @classmethod
    def named(cls, name: str, model: StiffnessModel, bodies: list[str] | None = None) -> Device:
        default, comps = DEVICES[name]
        sigma = np.array([model.noise["position_mm"]] * 3 + [model.noise["rotation_deg"]] * 3)
        return cls(name, list(bodies or default), np.array(comps), sigma)


@dataclass
class Plan:
    """The chosen configurations and what they predict."""

    q_deg: np.ndarray               # (N, 6)
    labels: list[str]               # parameter labels
    std_error: np.ndarray           # (P,) predicted, SI (inf where not identifiable)
    relative: np.ndarray            # (P,) predicted std error / |value|
    interest: np.ndarray            # (P,) bool: the parameters the criterion covers
    unidentifiable: list[str]
    criterion: float                # worst relative std error over the parameters of interest
    random_median: float            # the same for the median of random sets of N candidates


class Designer:
    """Information of configurations for one model, device and protocol (see the module docstring)."""

    def __init__(self, model: StiffnessModel, device: Device, loads: LoadSpec | None = None,
                 repeats: int = 3, margin_deg: float = 10.0):
        self.model, self.device = model, device
        self.loads = loads or LoadSpec()
        self.repeats, self.margin_deg = repeats, margin_deg
        theta = np.abs(model.theta)
        scale = np.array([p.scale for e in model.effects for p in e.params])
        self.unit = np.where(theta > 0, theta, scale)          # SI per relative unit
        self.lo = model.robot.limits_deg[:, 0] + margin_deg
        self.hi = model.robot.limits_deg[:, 1] - margin_deg

    def information(self, q_deg: np.ndarray) -> np.ndarray:
        """(M, P, P) Fisher information of each configuration, in relative parameters."""
        out = []
        w = self.device.components / self.device.sigma
        for start in range(0, len(q_deg), CHUNK):
            q = q_deg[start:start + CHUNK]
            spec = CampaignSpec(truth="-", configurations=[{"name": f"c{i}", "q_deg": list(v)} for i, v in enumerate(q)],
                                loads=self.loads, readings={"repeats": 1}, bodies=self.device.bodies)
            data = Campaign(spec, self.model, "<plan>").plan()
            J = jacobian(self.model, self.model.context(data)) * w[None, :, None] * self.unit
            for i in range(len(q)):
                Jc = J[data.config == f"c{i}"].reshape(-1, J.shape[2])
                out.append(self.repeats * (Jc.T @ Jc))
        return np.array(out)

    def clip(self, q_deg: np.ndarray) -> np.ndarray:
        return np.round(np.clip(q_deg, self.lo, self.hi), 3)


def relative_std_error(F: np.ndarray, ridge: float = 0.0) -> np.ndarray:
    """sqrt(diag((F + ridge I)^-1)): the predicted relative standard errors (inf if singular)."""
    try:
        cov = np.linalg.inv(F + ridge * np.eye(len(F)))
    except np.linalg.LinAlgError:
        return np.full(len(F), np.inf)
    return np.sqrt(np.clip(np.diag(cov), 0.0, None))


def plan(model: StiffnessModel, device: Device, n: int, seed: int = 0, progress: Callable[[str], None] | None = None,
         candidates: int = CANDIDATES, loads: LoadSpec | None = None, repeats: int = 3,
         margin_deg: float = 10.0) -> Plan:
    """Choose ``n`` configurations that minimise the worst predicted relative standard error."""
    say = progress or (lambda msg: None)
    des = Designer(model, device, loads, repeats, margin_deg)
    rng = np.random.default_rng([seed, 7])
    say(f"information of {candidates} candidate configurations")
    Q = random_configurations(model.robot, candidates, seed, margin_deg)
    Fc = des.information(Q)
    pool = Fc.mean(axis=0) * n
    hidden = unidentifiable_information(pool)
    ridge = 1e-10 * np.trace(pool) / len(pool)
    interest = ~hidden & (relative_std_error(pool, ridge) < MAX_RELATIVE)
    if not interest.any():
        interest = ~hidden

    def crit(F: np.ndarray) -> float:
        return float(relative_std_error(F, ridge)[interest].max())

    chosen: list[int] = []
    for k in range(n):                                  # greedy start
        say(f"greedy start {k + 1}/{n}")
        base = Fc[chosen].sum(axis=0)
        scores = [crit(base + Fc[c]) if c not in chosen else np.inf for c in range(len(Q))]
        chosen.append(int(np.argmin(scores)))
    q, F = Q[chosen].copy(), Fc[chosen].copy()
    best = crit(F.sum(axis=0))
    for sweep in range(10):                              # Fedorov exchange over the candidates
        say(f"exchange sweep {sweep + 1}: worst relative std error {best:.3g}")
        improved = False
        for i in range(n):
            rest = F.sum(axis=0) - F[i]
            scores = np.array([crit(rest + f) for f in Fc])
            c = int(np.argmin(scores))
            if scores[c] < best * (1 - 1e-9):
                q[i], F[i], best, improved = Q[c], Fc[c], float(scores[c]), True
        if not improved:
            break
    for step in STEPS_DEG:                               # continuous refinement around the choice
        say(f"refining with steps of {step:g} deg: worst relative std error {best:.3g}")
        trial = des.clip(np.repeat(q, PERTURBATIONS, axis=0)
                         + rng.normal(0.0, step, size=(n * PERTURBATIONS, 6)))
        Ft = des.information(trial).reshape(n, PERTURBATIONS, *F.shape[1:])
        for i in range(n):
            rest = F.sum(axis=0) - F[i]
            for t in range(PERTURBATIONS):
                s = crit(rest + Ft[i, t])
                if s < best:
                    q[i], F[i], best = trial[i * PERTURBATIONS + t], Ft[i, t], s
    subsets = [rng.choice(len(Q), n, replace=False) for _ in range(50)]
    random_median = float(np.median([crit(Fc[s].sum(axis=0)) for s in subsets]))
    rel = relative_std_error(F.sum(axis=0), ridge)
    rel[hidden] = np.inf
    labels = model.param_labels()
    return Plan(q, labels, rel * des.unit, rel, interest, [lab for lab, h in zip(labels, hidden) if h], best,
                random_median)


def worst_relative(model: StiffnessModel, device: Device, q_deg: np.ndarray, interest: np.ndarray,
                   repeats: int = 3) -> float:
    """The criterion of a given set of configurations (to compare a plan with other choices)."""
    F = Designer(model, device, repeats=repeats).information(np.asarray(q_deg, dtype=float)).sum(axis=0)
    return float(relative_std_error(F)[interest].max())
