"""Reload the service's YAML while it runs (SIGHUP, `stiffcomp reload`; docs/service.md, "Reload").

The main thread does all the work, the cycle only swaps (the cycle never waits on a reload):

1. `prepare` rereads the file the service started with and validates it as a start does: the config
   (`load_config`, with the checks across sections), the model (`load_model`: found, readable,
   physical), the register map, and the real-time predictor of the model. An invalid file changes
   nothing; the log line is the validation's own message (file, key, value, range).
2. It compares old and new by dotted key (`diff`), the model file's contents included
   (``model.file:robot.*``, ``model.file:effects``, ``model.file:<effect>.<parameter>``) and the
   register map's (``plc.register_map:registers``); a list of mappings by entry, a payload set by its
   ``index`` (``gravity.payloads[index 3].mass_kg``). A key that only a restart applies (`RESTART`: the
   cycle, the source, the PLC, ADS and monitoring settings, the model's structure, the register map)
   refuses the whole reload by name. ``gravity`` goes through `_apply_gravity`; a new table without the
   set the PLC's ``payload_index`` selects is refused, naming the set (`_payload_kept`).
3. It builds the new stages (filter, predictor) and the new parameters, and returns one function that
   puts them in place. `Service.work` takes it between two cycles (from a list it pops; one truth test
   per cycle while there is none); it
   assigns references and a few floats, carries the filter's state over (`SosLowPass.continue_from`)
   and starts the model ramp (`service.model_ramp.PredictorRamp`), and counts the reload
   (``reload_count`` in the contract).

Every reload writes exactly one log line that says ``reload``: accepted, with each changed key as
``old → new``, or refused, with why, in one wording: ``reload of FILE refused, nothing changed: WHY``.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, NamedTuple

from stiffness.errors import quote
from stiffness.model.stiffness_model import StiffnessModel

from .compensation import FastPredictor, load_model
from .config import ServiceConfig, load_config
from .errors import ServiceError
from .filters import SosLowPass, SpikeRejector
from .gravity import GravityConfig
from .limits import CorrectionLimiter
from .model_ramp import PredictorRamp
from .payloads import describe as describe_set
from .supervision import Supervisor

log = logging.getLogger("stiffcomp.service")

# what only a restart applies: the sections of sockets, the cycle's timing and thread, the opened sensor
# and the image laid out by the register map; the dynamic compensation's states, the accelerometer's
# supervision and bias; the model's structure
RESTART = ("cycle", "source", "plc", "ads", "monitoring", "dynamics", "accelerometer", "robot")
STRUCTURE = ("model.file:robot.", "model.file:effects")
RESTART_KEYS = {"gravity.g_mps2"}         # gravity's direction: the arm's static torque too, not a payload switch
LOWPASS = {"filter.type", "filter.order", "filter.cutoff_hz"}          # a new low-pass (the rest: parameters)
SHOWN = 8               # changed keys named in one log line; the rest are counted
HANDOVER_S = 5.0        # the cycle takes a prepared reload within a cycle; this bounds the wait on a stalled one

Swap = Callable[[Any, Any], None]        # (cycle, source) -> None, run between two cycles


class Outcome(NamedTuple):
    """What a reload did: accepted or not, and the one log line that says so."""

    accepted: bool
    message: str


class Prepared(NamedTuple):
    """A validated reload, ready to swap in: the new config and model, and the cycle's part."""

    cfg: ServiceConfig
    model: StiffnessModel
    changes: dict[str, tuple[Any, Any]]
    swap: Swap


def diff(old: Any, new: Any, prefix: str = "") -> dict[str, tuple[Any, Any]]:
    """{dotted key: (old, new)} for each value that differs (None where absent). Mappings are compared key
    by key; a list of mappings (a table) entry by entry, each named by its ``index`` if it has one
    (``gravity.payloads[index 3].mass_kg``), else by its number (``[entry 2]``), so an added or removed
    entry is one key; any other list is one value."""
    if isinstance(old, dict) or isinstance(new, dict):
        a, b = (x if isinstance(x, dict) else {} for x in (old, new))
        out: dict[str, tuple[Any, Any]] = {}
        for k in dict.fromkeys([*a, *b]):
            out.update(diff(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else str(k)))
        return out
    if _table(old) or _table(new):
        a, b = _entries(old), _entries(new)
        out = {}
        for k in dict.fromkeys([*a, *b]):
            if k in a and k in b:
                out.update(diff(a[k], b[k], f"{prefix}[{k}]"))
            else:
                out[f"{prefix}[{k}]"] = (a.get(k), b.get(k))
        return out
    return {prefix: (old, new)} if old != new else {}


def _table(value: Any) -> bool:
    return isinstance(value, list) and any(isinstance(v, dict) for v in value)


def _entries(value: Any) -> dict[str, Any]:
    """A table's entries by name: ``index N`` where an entry has an index, else ``entry N`` (from 1)."""
    rows = value if isinstance(value, list) else []
    return {(f"index {v['index']}" if isinstance(v, dict) and "index" in v else f"entry {k + 1}"): v
            for k, v in enumerate(rows)}


def model_diff(old: StiffnessModel, new: StiffnessModel) -> dict[str, tuple[Any, Any]]:
    """The model file's contents by key: ``model.file:robot.<key>`` (the robot), ``model.file:effects``
    (the structure: which parameters of which effects) and ``model.file:<effect>.<key>`` (values, in the
    YAML's units), ``model.file:payload.<key>``."""
    out = diff(old.robot.config.model_dump(), new.robot.config.model_dump(), "model.file:robot")
    labels_old, labels_new = old.param_labels(), new.param_labels()
    if labels_old != labels_new:
        out["model.file:effects"] = (_effects(old), _effects(new))
        return out
    factors = [p.yaml_factor for e in new.effects for p in e.params]
    for label, f, a, b in zip(labels_new, factors, old.theta, new.theta):
        if a != b:
            out[f"model.file:{label}"] = (float(a * f), float(b * f))
    pay = [None if m.payload is None else m.payload.model_dump() for m in (old, new)]
    out.update(diff(pay[0] or {}, pay[1] or {}, "model.file:payload"))
    return out


def _effects(model: StiffnessModel) -> str:
    return ", ".join(e.label for e in model.effects)


def _map_rows(rmap) -> tuple:
    return (rmap.as_list(), {d: b.model_dump(exclude={"registers"}) for d, b in rmap.blocks.items()})


def describe(changes: dict[str, tuple[Any, Any]]) -> str:
    """``key old → new`` for each change (the first `SHOWN`, then how many more); a table's entry that
    came or went as ``key added`` or ``key removed``, never as a dump of its values."""
    items = [f"{k} added" if a is None and isinstance(b, dict) else f"{k} removed" if b is None and isinstance(a, dict)
             else f"{k} {quote(a)} → {quote(b)}" for k, (a, b) in changes.items()]
    more = len(items) - SHOWN
    return ", ".join(items[:SHOWN]) + (f" and {more} more" if more > 0 else "")


def _apply_gravity(old: GravityConfig, new: GravityConfig) -> Swap | None:
    """The one place a reload changes the ``gravity`` section: its payload table and bodies go to the
    payload switch (`service.payloads.PayloadSelector.reload`), so the set in use ramps to its new values
    over ``gravity.switch_ramp_s`` and a set that is gone is refused as a PLC's missing index is.
    ``gravity.g_mps2`` is in `RESTART_KEYS` (it changes the arm's own static torque). None: unchanged."""
    if old == new:
        return None
    return lambda cycle, source: cycle.compensator.payloads.reload(new)


def _payload_kept(cycle, new: GravityConfig) -> str | None:
    """Why a new ``gravity`` section cannot be taken: its table has no set for the index the PLC selects,
    which the current table has (the reload would latch ``payload_invalid`` and ramp the correction to
    zero). None when it can (the PLC has moved to a set that stays, or selects none the table had)."""
    selector = cycle.compensator.payloads
    index = selector.requested
    if index in new.payload_sets() or index not in selector.sets:
        return None
    return (f"gravity.payloads[index {index}] removed, but the PLC's payload_index = {index} selects it (set "
            f"{describe_set(selector.sets[index])}): switch the PLC to a set that stays, then reload")


def refused(path, why: str) -> Outcome:
    """The one wording of a refusal: ``reload of FILE refused, nothing changed: WHY`` (a WHY that names
    FILE first, as a validation error does, loses that repetition)."""
    why = why.removeprefix(f"{path}: ")
    return Outcome(False, f"reload of {path} refused, nothing changed: {why}")


def prepare(old: ServiceConfig, old_model: StiffnessModel, old_rmap, cycle) -> Prepared | Outcome:
    """Reread ``old.path`` and validate it completely; a `Prepared` reload, or the refusal (`Outcome`).

    Runs in the main thread: it reads files, designs filters and builds a predictor, which the cycle
    never waits for. ``cycle`` is read only (the current gravity, joints, period)."""
    path = old.path
    try:
        new = load_config(path)
        model = load_model(new)
        rmap = new.register_map()
    except ServiceError as e:
        return refused(path, str(e))
    changes = diff(old.model_dump(), new.model_dump())
    changes.update(model_diff(old_model, model))
    if _map_rows(old_rmap) != _map_rows(rmap):
        changes["plc.register_map:registers"] = (old_rmap.source, rmap.source)
    restart = [k for k in changes if k.split(".")[0] in RESTART or k.startswith(STRUCTURE) or k in RESTART_KEYS]
    if restart:
        return refused(path, f"{describe({k: changes[k] for k in restart})}: "
                             f"{'this needs' if len(restart) == 1 else 'these need'} a restart of the service")
    gone = _payload_kept(cycle, new.gravity)
    if gone:
        return refused(path, gone)
    gravity_swap = _apply_gravity(old.gravity, new.gravity)
    try:
        swap = _stages(new, model, changes, cycle, gravity_swap)
    except ServiceError as e:
        return refused(path, str(e))
    return Prepared(new, model, changes, swap)


def _stages(new: ServiceConfig, model: StiffnessModel, changes: dict, cycle, gravity_swap: Swap | None) -> Swap:
    """Everything the cycle needs from ``new``, built here, and the swap that puts it in place."""
    period = new.cycle.period_ms / 1000.0
    comp = cycle.compensator
    filt = SosLowPass.from_config(new.filter, period) if LOWPASS.intersection(changes) else None
    spikes = SpikeRejector.from_config(new.filter.spike)
    limiter = CorrectionLimiter.from_config(new.limits, period)
    sup = Supervisor.from_config(new.faults, cycle.faults, model.robot.limits_deg, new.cycle_enables_on_start)
    timeout_s, tare_max = new.faults.sensor_timeout_ms / 1000.0, new.tare.max_force_N
    pred = None
    if any(k.startswith("model.") for k in changes):
        pred = FastPredictor.from_config(new.model, model, comp.dynamics)   # ModelUnsupportedError: refused
        g = comp.gravity
        pred.carry(g.mass, g.cog, g.g_mps2)      # the payload now; the swap takes the switch's blend of then
        q_prep = comp.q_rad
        pred.kinematics(q_prep)
        if comp.kernel is not None:
            pred.compile()                       # the same laws as the running model: loaded, not compiled
    ramp_cycles = round(new.limits.fault_ramp_s / period)

    def swap(cycle, source) -> None:
        c = cycle.compensator
        c.release_stages()                      # the compiled path's state into the stages read and replaced here
        if filt is not None:
            filt.continue_from(c.filter)
            c.filter = filt
        s = c.spikes
        s.max_step, s.max_held = spikes.max_step, spikes.max_held
        lim = c.limiter
        lim.max, lim.rate, lim.ramp_s = limiter.max, limiter.rate, limiter.ramp_s
        v = cycle.supervisor
        v.hb_timeout, v.overrun_trip = sup.hb_timeout, sup.overrun_trip
        source.timeout_s = timeout_s
        c.tare_max = tare_max
        if pred is not None:
            pred.carry_payload(c.gravity.mass, c.gravity.mc)     # a payload switch may be ramping
            if c.q_rad is not q_prep:          # the joints moved since: one more kinematics pass
                pred.kinematics(c.q_rad)
            ramp = PredictorRamp(c.predictor, pred, ramp_cycles, lambda: _finish(c, ramp, pred))
            c.predictor = c.payloads.predictor = ramp
        if gravity_swap is not None:
            gravity_swap(cycle, source)
        cycle.reloads += 1

    return swap


def _finish(comp, ramp: PredictorRamp, pred: FastPredictor) -> None:
    """The ramp's end: the new predictor alone (unless a later reload has started a ramp of its own)."""
    if comp.predictor is ramp:
        comp.predictor = comp.payloads.predictor = pred


def _hand_over(service, prepared: Prepared) -> Outcome:
    """Give ``prepared`` to the cycle and wait until it is applied (or take it back: refused)."""
    task, cycle = service.task, service.cycle
    before = cycle.reloads
    service.pending.append(prepared.swap)
    deadline = time.monotonic() + HANDOVER_S
    while service.pending and task is not None and task.running and time.monotonic() < deadline:
        time.sleep(0.001)
    try:
        service.pending.pop()
        return refused(service.cfg.path, f"the cycle did not take it within {HANDOVER_S:g} s (is it running?)")
    except IndexError:
        pass                            # taken: the swap counts the reload as its last step
    while cycle.reloads == before and time.monotonic() < deadline + HANDOVER_S:
        time.sleep(0.0005)
    if cycle.reloads == before:         # the swap raised: the cycle's error policy stops the service
        return Outcome(False, f"reload of {service.cfg.path} failed while the cycle applied it ({service.failure})")
    service.cfg, service.model = prepared.cfg, prepared.model
    return Outcome(True, f"reload {cycle.reloads} of {prepared.cfg.path} accepted: "
                   f"{describe(prepared.changes) if prepared.changes else 'no change'}")


def reload(service) -> Outcome:
    """Reload ``service`` (a running `service.app.Service`) from its config file; one log line, the outcome.

    Main thread only. The prepared swap is handed to the cycle in ``service.pending``, a list which the
    cycle pops between two cycles; the wait for that is bounded (`HANDOVER_S`), and a swap not taken by
    then is popped back here. A pop is atomic, so exactly one side gets it: never applied and refused."""
    try:
        got = prepare(service.cfg, service.model, service.rmap, service.cycle)
    except Exception as e:  # noqa: BLE001 - a reload must never take the running service down
        got = refused(service.cfg.path, f"an unexpected {type(e).__name__}: {e}")
    if isinstance(got, Prepared):
        got = _hand_over(service, got)
    (log.info if got.accepted else log.warning)("%s", got.message)       # refused: the service runs on
    return got
