"""The static torque identified from the data: where each configuration crosses a joint's nonlinearity.

A gearbox's play or soft zone sits at zero *total* torque tau_s(q) + tau_ext (`stiffness.kinematics.statics`). When
the robot's masses are approximate or missing, tau_s is wrong, and the fit identifies it:

    tau_s_j(q) = prior_j(q) + sum_k phi_jk(q) beta_k,

prior_j   the static torque of the robot's masses, balancer and payload (zero without masses);
phi_jk    column k of row j of the arm's static regressor: tau_arm = -Y(q) pi, Y pinocchio's joint torque
          regressor at rest (`computeJointTorqueRegressor` with v = a = 0), pi the links' masses and
          first moments (m, m c_x, m c_y, m c_z of link i in joint i's frame: DH frame i-1 turned with
          the joint); only the columns that row j can tell apart are kept (the base columns over random
          configurations, the first in key order of those that depend on each other);
beta_k    the correction of those base parameters *as joint j feels them*: a balancer's share on joint j
          scales its whole row, so it folds into beta (one joint's crossings cannot separate it from the
          masses).

The model holds one `PreloadTerm` per joint (YAML: the model's ``preload`` list, keys such as
``mx3_kgm``), identified by `identify.fit` as nonlinear parameters; `StiffnessModel.statics` adds it to
tau_s, so the offline prediction and the 1 ms service use it unchanged. A campaign sees tau_s only at
its configurations, and only where the external load crosses the nonlinearity: the directions of beta
the data cannot see stay at their start (named by the fit), and a configuration whose crossing lies
beyond its load range bounds tau_s there without fixing it (`crossings`).

Example: joint 2 of the KR 125 sees a few base columns of the 24 (m, mc of six links).

>>> from pathlib import Path
>>> import stiffness
>>> from stiffness.kinematics.robot import load_robot
>>> robot = load_robot(Path(stiffness.__file__).parents[1] / "config" / "robots" / "kr125.yaml")
>>> t = PreloadTerm(robot, 2)
>>> len(t.params) < 24 and all(p.key.endswith(("_kg", "_kgm")) for p in t.params)
True
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..effects.base import Effect, Param, read_location, read_values
from ..kinematics.statics import Statics, base_columns, column_key

BEYOND = 1.3                             # a start puts an unseen crossing this far beyond the load range
RIDGE = 1e-3                             # the start's pull toward the prior, relative to the data
STEP_NM = 10.0          # the fit's unit of change of an identified static torque (a backlash's width is tens of Nm)


class PreloadTerm(Effect):
    """The identified correction of joint ``joint``'s static torque (module docstring). It adds no twist:
    it moves where the joint's axial nonlinearity sits (`Context.static_torque`)."""

    name = "preload"
    kind = "static"
    equation = "tau_s,j(q) = prior_j(q) + phi_j(q) beta"

    def __init__(self, robot: Any, joint: int, theta: np.ndarray | None = None):
        self.columns = np.array(base_columns(robot, joint), dtype=int)
        params = [Param(column_key(k), "kg" if k % 4 == 0 else "kg m", 10.0, nonlinear=True)
                  for k in self.columns]
        super().__init__(params, np.zeros(len(params)) if theta is None else theta, joint)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> PreloadTerm:
        joint = read_location(section, "joint", cls.joints, where)
        probe = cls(robot, joint)
        return cls(robot, joint, read_values(cls.name, section, probe.params, where, ("joint",)))

    def to_config(self) -> dict[str, Any]:
        out = super().to_config()
        del out["effect"]
        return out

    def realtime(self, robot: Any) -> list:
        return []            # the service takes it through `StiffnessModel.statics`

    def phi(self, ctx) -> np.ndarray:
        """(R, K): the base columns at each reading of ``ctx``."""
        key = ("preload_phi", self.joint, tuple(self.columns))
        if key not in ctx.cache:
            statics = ctx.statics if ctx.statics is not None else Statics(ctx.robot)   # a robot without masses
            ctx.cache[key] = statics.regressor_rows(ctx.q, self.joint)[:, self.columns]
        return ctx.cache[key]

    def correction(self, ctx, theta: np.ndarray) -> np.ndarray:
        """(R,) Nm: what this term adds to joint j's static torque at each reading."""
        return self.phi(ctx) @ theta

    def size_text(self, estimate, std_error, model) -> str:
        return ", ".join(f"{p.key} {v:+.3g} (± {s:.2g})" for p, v, s in zip(self.params, estimate, std_error))


def start_from_centres(model, ctx, term: PreloadTerm, tau_s_per_config: np.ndarray,
                       determined: np.ndarray) -> np.ndarray:
    """beta that puts joint j's static torque at ``tau_s_per_config`` in the ``determined``
    configurations and beyond the load range (by BEYOND) in the others, on the side a first fit to the
    determined ones gives: ridge regression toward the prior (beta = 0), in closed form."""
    C = len(ctx.config_labels)
    prior = np.full(C, np.nan)
    prior[ctx.config] = ctx.static_prior[:, term.joint - 1]
    phi = np.full((C, len(term.columns)), np.nan)
    phi[ctx.config] = term.phi(ctx)
    ok = determined & np.isfinite(tau_s_per_config)
    if not ok.any():
        return np.zeros(len(term.columns))
    beta = _ridge(phi[ok], tau_s_per_config[ok] - prior[ok])
    tau = np.abs(ctx.frame_wrench[:, term.joint - 1, 5])
    reach = np.zeros(C)
    np.maximum.at(reach, ctx.config, tau)
    guess = prior + phi @ beta
    target = np.where(ok, tau_s_per_config, np.where(guess >= 0, 1.0, -1.0) * np.maximum(np.abs(guess),
                                                                                            BEYOND * reach))
    seen = np.isfinite(target) & np.isfinite(prior)
    return _ridge(phi[seen], target[seen] - prior[seen])


def _ridge(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(A, axis=0)
    norms[norms <= 0] = 1.0
    An = A / norms
    lam = RIDGE * max(float(np.linalg.norm(An, 2)) ** 2, 1e-300)
    return np.linalg.solve(An.T @ An + lam * np.eye(An.shape[1]), An.T @ b) / norms


def directions(model, ctx, nl: np.ndarray, scale: np.ndarray) -> np.ndarray | None:
    """(len(nl), Z), or None for a model without an identified preload: the directions the fit moves the nonlinear parameters ``nl`` in (scaled units).

    Every parameter moves alone, except an identified preload's: the campaign sees joint j's static
    torque only at its configurations, so its beta moves only in the row space of the base columns at
    those configurations; the rest of beta stays at its start (the prior)."""
    if not any(isinstance(e, PreloadTerm) for e in model.effects):
        return None
    labels = {}
    for e, sl in zip(model.effects, model.param_slices()):
        for k in range(sl.start, sl.stop):
            labels[k] = (e, sl)
    cols = []
    done = set()
    for i, k in enumerate(nl):
        e, sl = labels[int(k)]
        if not isinstance(e, PreloadTerm):
            col = np.zeros(len(nl))
            col[i] = 1.0
            cols.append(col)
            continue
        if id(e) in done:
            continue
        done.add(id(e))
        first = np.unique(ctx.config, return_index=True)[1]
        phi = e.phi(ctx)[first] * scale[sl]
        _, S, Vt = np.linalg.svd(phi, full_matrices=False)
        r = int(np.sum(S > 1e-6 * max(S[0], 1e-300))) if len(S) else 0
        pos = [i2 for i2, k2 in enumerate(nl) if sl.start <= k2 < sl.stop]
        for v, sv in zip(Vt[:r], S[:r]):         # one unit moves the configurations' tau_s by STEP_NM
            col = np.zeros(len(nl))
            col[pos] = v * STEP_NM / sv
            cols.append(col)
    return np.array(cols).T.reshape(len(nl), len(cols))


def held_preload(model) -> np.ndarray:
    """Boolean (P,): the model's parameters that belong to an identified preload."""
    return np.concatenate([np.full(len(e.params), isinstance(e, PreloadTerm)) for e in model.effects]) \
        if model.effects else np.zeros(0, dtype=bool)
