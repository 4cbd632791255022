"""The dynamic compensation in the service: the ``dynamics`` section, its parts' terms and the plan's feed.

Off by default. With ``enabled: true`` each part the section holds (`stiffness.dynamics.STAGES`: the
predictor, the feedforward, the structure's modes; docs/dynamics.md) is built from its own sub-section and
returns its per-cycle terms of the real-time kinds, which the predictor (`FastPredictor`) runs with the
model's own: a `WrenchTerm` on the external wrench before the springs, a `TwistTerm` on the deflection
before the correction, on the Python and the compiled path alike. The correction they change goes through
the same limiter as the static one (its ramps and the fault ramp), and every state restarts at the first
sample, after a tare and after a fault reset.

``delay_ms`` is the end-to-end delay from the force at the tool to the correction at the joints (what
`stiffcomp hil circle` reports as delay_ms, or a commissioning measurement); the predictor's horizon is
that less the structure's own lag (`stiffness.dynamics.base.DynamicsContext`).
"""

from __future__ import annotations

import logging

from pydantic import Field, create_model, model_validator

from stiffness.dynamics import STAGES, DynamicsContext, Stage
from stiffness.dynamics.observer import MAX_SAMPLE_MS, Observer
from stiffness.dynamics.structure import Structure
from stiffness.effects.terms import Term
from stiffness.errors import StiffnessError
from stiffness.files.yaml_schema import Strict

from .errors import ServiceConfigError

log = logging.getLogger("stiffcomp.service")

def _follower_has_its_structure(section):
    """``observer.follow`` hands the modes' frequencies to ``structure``: it must hold the observer's modes."""
    obs, st = section.observer, section.structure
    if obs is not None and obs.follow and (
            st is None or len(st.modes) != len(obs.modes)
            or any(abs(sum(a * b for a, b in zip(m.direction, n.direction))) < 0.99 for m, n in zip(st.modes, obs.modes))):
        raise ValueError("observer.follow: the follower hands the modes' frequencies to dynamics.structure, which "
                         "must hold the observer's modes (as many, in the same order and directions)")
    return section


DynamicsConfig = create_model(
    "DynamicsConfig", __base__=Strict, __doc__="``dynamics``: the dynamic compensation (module docstring).",
    __validators__={"_follower": model_validator(mode="after")(_follower_has_its_structure)},
    enabled=(bool, False),
    delay_ms=(float, Field(8.0, ge=0.0, le=200.0)),
    **{name: (cls.Config | None, None) for name, cls in STAGES.items()})


class Dynamics:
    """The parts of one ``dynamics`` section, and the terms they gave to the predictors that run them.

    Parameters
    ----------
    section : DynamicsConfig
    period_s : float
        The cycle's period.
    resolve : callable (str) -> Path
        A path written in the config, found (the plan file).
    """

    def __init__(self, section, period_s: float, resolve=None):
        self.section = section
        self.period_s = float(period_s)
        self.stages: list[Stage] = []
        self._resolve = resolve
        self.follower = None            # `stiffness.dynamics.follower`, with ``dynamics.observer.follow``
        self._live: dict[str, Term] = {}    # the terms the cycle runs now, by part
        if section.enabled:
            self.stages = [self._stage(name, cls, getattr(section, name)) for name, cls in STAGES.items()
                          if getattr(section, name) is not None]

    def part(self, name: str) -> Stage | None:
        """The part ``name`` (`stiffness.dynamics.STAGES`), or None when the section has none."""
        return next((p for p in self.stages if p.name == name), None)

    def _stage(self, name: str, cls: type[Stage], cfg) -> Stage:
        try:
            return cls.from_config(cfg, self._resolve)
        except StiffnessError as e:
            raise ServiceConfigError(f"dynamics.{name}: {e}") from e

    @property
    def active(self) -> bool:
        return bool(self.stages)

    def terms(self) -> list[Term]:
        """Fresh terms of every part (their states at the start), in the registry's order."""
        lag = sum(p.lag_s() for p in self.stages)
        ctx = DynamicsContext(self.period_s, self.section.delay_ms / 1000.0, lag)
        out: list[Term] = []
        for part in self.stages:
            try:
                terms = part.terms(ctx)
            except ValueError as e:
                raise ServiceConfigError(f"dynamics.{part.name}: {e}") from e
            self._live[part.name] = terms[0] if terms else None
            out += terms
            ctx = part.context(ctx)
        obs = self.part("observer")
        self.follower = None if obs is None else obs.follower(self.period_s, self.retune)
        return out

    def retune(self, hz) -> None:
        """The structure's and the observer's modes at ``hz`` (the follower's), in the terms the cycle runs:
        their parameters rewritten in place (the compiled cycle reads the same memory)."""
        for name in ("structure", "observer"):
            part, term = self.part(name), self._live.get(name)
            p = part.with_frequencies(hz).params(self.period_s)
            term.params[:len(p)] = p
        configured = ", ".join(f"{m.hz:g}" for m in self.part("observer").cfg.modes)
        log.info("dynamics: the modes follow the arm's ringing: %s Hz (configured %s Hz)",
                 ", ".join(f"{f:.2f}" for f in hz), configured)

    def plc_values(self) -> list[str]:
        """The contract values the parts read from the PLC every cycle (`feed`)."""
        return [v for p in self.stages if (v := p.plc_value()) is not None]

    def feed(self, t: float, inputs, p_tcp) -> None:
        """This cycle's values from the PLC (``inputs``: the `FromPlc` record) into the parts that read one."""
        for p in self.stages:
            name = p.plc_value()
            if name is not None:
                p.feed(t, float(getattr(inputs, name)), p_tcp)

    @property
    def reads_motion(self) -> bool:
        """A part reads the accelerometer (`feed_motion`)."""
        return any(p.reads_motion for p in self.stages)

    def feed_motion(self, acceleration, ok: bool, p_tcp, sample_period_s: float) -> None:
        """The accelerometer's acceleration and state, the nominal TCP and the time between the accelerometer's
        values, into the parts that read them; a part held off by values too far apart says so once."""
        for p in self.stages:
            if p.reads_motion:
                was = getattr(p, "too_slow", False)
                p.feed_motion(acceleration, ok, p_tcp, sample_period_s)
                if getattr(p, "too_slow", False) and not was and ok:
                    log.warning("dynamics.%s: the accelerometer's values come every %.1f ms; it needs one every "
                                "%.1f ms at most (the box at 1000 Hz or more, the PLC's task at 1 ms): off, the "
                                "correction goes on from the force alone (docs/accelerometer.md)", p.name,
                                1000.0 * sample_period_s, MAX_SAMPLE_MS)
        if self.follower is not None:
            self._follow()

    def _follow(self) -> None:
        """The follower's cycle, on the states the cycle just left: the structure's inputs and the observer's
        band deflection; it starts afresh while the observer is not running or its band is settling."""
        obs = self._live["observer"]
        if not Observer.settled(obs):
            self.follower.restart()
            return
        self.follower.step(Structure.inputs(self._live["structure"]), Observer.measured(obs))

    def describe(self) -> str:
        if not self.stages:
            return "dynamic compensation off"
        return f"dynamic compensation (delay {self.section.delay_ms:g} ms): " + "; ".join(p.describe() for p in self.stages)
