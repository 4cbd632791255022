"""The effect interface: each physical effect is a small class with its equation and parameters.

An effect is one named entry in a model YAML (``effect: NAME`` plus its parameters). It acts in one
of two places:

* ``input`` effects change the sensor wrench before it is transported (e.g. sensor misalignment);
* ``site`` effects add twists at the sites of `stiffness.data.campaign` (springs, backlash, bending ...).

Parameters are held in SI units in ``theta``; ``Param.unit``/``Param.yaml_factor`` convert to the
units a person reads in the YAML. A site effect that is linear in its parameters provides
``basis(ctx, W)`` so that identification is a linear least-squares problem.

Everything else about an effect lives in its own module too, so that a new effect is one file (and
its test) plus its line in the registry (`stiffness.effects.EFFECTS`):

* ``realtime(robot)``: the terms it adds to the service's 1 ms path (`stiffness.effects.terms`);
* ``candidates(model, ctx)``: where the diagnosis tries it, with its trial grid of shapes;
* ``size_text(estimate, std_error, model)``: its estimated size in plain words;
* ``evidence_plot``: how the diagnosis shows its evidence (``EVIDENCE_PLOTS``);
* ``examples``: model entries at the sizes a KR 125 shows (the HIL, the start-up test, benchmarks);
* a runnable example in its module's docstring, which the tests execute.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ..data.campaign import N_SITES, Context
from ..errors import ConfigError, quote
from .terms import InputTerm, Term

# "predicted": the residual against the deflection the effect predicts (points on the diagonal: explained);
# "axial": joint i's unexplained axial rotation against its torque tau_i, with the fitted curve;
# "axial_branches": the same, each reading coloured by the effect's ``loading(ctx, W, theta)`` in [-1, 1]
EVIDENCE_PLOTS = ("predicted", "axial", "axial_branches")


@dataclass(frozen=True)
class Param:
    """One parameter: its YAML key (unit in the name), SI scale for fitting, and whether it is fitted.

    ``yaml_factor`` converts SI to the YAML unit (value_yaml = value_si * yaml_factor).
    ``compliance`` marks a compliance: physically >= 0 (a negative one is a spring that pushes back
    the wrong way), refused by `StiffnessModel.require_physical`, bounded by ``fit(nonnegative=True)``.
    """

    key: str
    unit: str
    scale: float
    yaml_factor: float = 1.0
    nonlinear: bool = False
    bounds: tuple[float, float] = (-np.inf, np.inf)
    compliance: bool = False


class Effect(ABC):
    """Base of all effects. Subclasses set ``name``, ``kind``, ``equation`` and build ``params``."""

    name: ClassVar[str]
    kind: ClassVar[str] = "site"          # "site" or "input"
    equation: ClassVar[str] = ""
    per_joint: ClassVar[bool] = True       # located at a joint (or link) number
    joints: ClassVar[tuple[int, ...]] = (1, 2, 3, 4, 5, 6)
    evidence_plot: ClassVar[str] = "predicted"    # one of EVIDENCE_PLOTS
    examples: ClassVar[tuple[dict[str, Any], ...]] = ()   # model entries at sizes a KR 125 shows

    def __init__(self, params: list[Param], theta: np.ndarray, joint: int | None = None):
        self.params = params
        self.theta = np.asarray(theta, dtype=float)
        self.joint = joint
        self.std_error = np.full(len(params), np.nan)

    # -- construction from / to YAML ----------------------------------------------------------
    @classmethod
    @abstractmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Effect:
        """Build from a YAML entry; raise ConfigError naming ``where`` and the key on bad values."""

    def to_config(self) -> dict[str, Any]:
        out: dict[str, Any] = {"effect": self.name}
        if self.joint is not None:
            out[self.location_key] = self.joint
        for p, v in zip(self.params, self.theta):
            out[p.key] = float(f"{v * p.yaml_factor:.6g}")
        return out

    location_key: ClassVar[str] = "joint"

    @property
    def label(self) -> str:
        return f"{self.name}" + (f"@{self.location_key}{self.joint}" if self.joint is not None else "")

    @property
    def linear(self) -> bool:
        """True when every parameter enters linearly (no nonlinear shape parameter, not an input)."""
        return not any(p.nonlinear for p in self.params) and self.kind == "site"

    @property
    def linear_mask(self) -> np.ndarray:
        return np.array([not p.nonlinear for p in self.params], dtype=bool)

    # -- evaluation ---------------------------------------------------------------------------
    def twists(self, ctx: Context, theta: np.ndarray, W: np.ndarray) -> np.ndarray:
        """Twists (R, 12, 6) in m, rad at the sites, given the frame wrenches W (R, 7, 6)."""
        return np.einsum("p,rpsc->rsc", theta[self.linear_mask], self.basis(ctx, W, theta))

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """(R, P_linear, 12, 6): the twists per unit of each linear parameter, for the nonlinear
        parameters' values in ``theta``."""
        raise NotImplementedError(f"{self.name} does not define its basis")

    def wrench(self, ctx: Context, theta: np.ndarray, wrench_sensor: np.ndarray) -> np.ndarray:
        """For input effects: the corrected sensor wrench (R, 6)."""
        return wrench_sensor

    @staticmethod
    def zeros(ctx: Context, n_params: int) -> np.ndarray:
        return np.zeros((ctx.n_readings, n_params, N_SITES, 6))

    # -- the service, the diagnosis, the words ---------------------------------------------------
    def realtime(self, robot: Any) -> list[Term] | None:
        """The terms this effect adds to the service's 1 ms path, its parameters frozen
        (`stiffness.effects.terms`); None when it has none, and the service refuses the model.
        An input effect is taken from `StiffnessModel.input_map`, with every other input effect."""
        return [InputTerm(self.label)] if self.kind == "input" else None

    @classmethod
    def candidates(cls, model: Any, ctx: Context) -> list[list[Effect]]:
        """Where the diagnosis tries this effect on ``model`` (which lacks it there): one list per place,
        each holding the shape variants to try (the best is kept). None tried by default."""
        return []

    def size_text(self, estimate: np.ndarray, std_error: np.ndarray, model: Any) -> str:
        """The size of this effect with parameters ``estimate`` (SI), in the units a person reads."""
        return ", ".join(f"{p.key} = {v * p.yaml_factor:.4g}" for p, v in zip(self.params, estimate))


def read_values(cls_name: str, section: dict[str, Any], params: list[Param], where: str,
                allowed_extra: tuple[str, ...] = ()) -> np.ndarray:
    """Read parameter values (YAML units) from an effect entry, rejecting unknown keys."""
    known = {p.key for p in params} | {"effect", "fit", *allowed_extra}
    unknown = sorted(set(section) - known)
    if unknown:
        raise ConfigError(f"{where}: {unknown[0]} is not a key of effect '{cls_name}' "
                          f"(known: {', '.join(sorted(known - {'effect', 'fit'}))})")
    theta = np.zeros(len(params))
    for k, p in enumerate(params):
        raw = section.get(p.key, 0.0)
        try:
            v = float(raw)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: {p.key} = {quote(raw)} is not a number ({p.unit})") from None
        if not np.isfinite(v):
            raise ConfigError(f"{where}: {p.key} = {quote(raw)} must be finite ({p.unit})")
        lo, hi = p.bounds
        si = v / p.yaml_factor
        if not lo <= si <= hi:
            raise ConfigError(f"{where}: {p.key} = {quote(raw)} is outside [{lo * p.yaml_factor:g}, "
                              f"{hi * p.yaml_factor:g}] {p.unit}")
        theta[k] = si
    return theta


def read_location(section: dict[str, Any], key: str, allowed: tuple[int, ...], where: str) -> int:
    """Read the joint or link number of an effect entry, naming the allowed values on error."""
    if key not in section:
        raise ConfigError(f"{where}: {key} is missing (one of {', '.join(map(str, allowed))})")
    v = section[key]
    if not isinstance(v, int) or isinstance(v, bool) or v not in allowed:
        raise ConfigError(f"{where}: {key} = {quote(v)} must be one of {', '.join(map(str, allowed))}")
    return v
