"""A `FastPredictor`'s compiled form: its model packed into arrays once, then one call per cycle
(`service.kernel.template`, the kinematics in it when the joints moved), no allocation in it.

`pack` reads pinocchio's model once (joint placements and axes, the DH frames, the sensor and the TCP)
and `Statics` (masses, balancer, payload, identified preloads); the terms' parameters are stacked per
kind, each term's law named by its index among the model's laws of that kind. A history term's state
becomes a view of the stacked state, so `HistoryTerm.reset` (Python) restarts the compiled state too.
"""

from __future__ import annotations

import numpy as np

from .build import NotCompilable, module_for
from .template import FLOATS, INTS, STATE_SIZE

_REVOLUTE = {"JointModelRX": (1.0, 0.0, 0.0), "JointModelRY": (0.0, 1.0, 0.0), "JointModelRZ": (0.0, 0.0, 1.0)}


def _axis(joint) -> tuple[float, float, float]:
    name = joint.shortname()
    if name in _REVOLUTE:
        return _REVOLUTE[name]
    if name == "JointModelRevoluteUnaligned":
        return tuple(float(v) for v in joint.axis)
    raise NotCompilable(f"joint type {name} (the compiled chain has revolute joints only)")


def _stack(rows, width_min: int = 1) -> np.ndarray:
    width = max([width_min, *(len(r) for r in rows)])
    out = np.zeros((len(rows), width))
    for n, r in enumerate(rows):
        out[n, :len(r)] = r
    return out


class CompiledPredictor:
    """The arrays and the compiled functions of one `FastPredictor` (``fp``)."""

    def __init__(self, fp):
        pm = fp.pm
        if pm.nq != 6 or pm.nv != 6 or list(pm.parents) != [0, 0, 1, 2, 3, 4, 5]:
            raise NotCompilable("the robot is not a serial chain of six joints")
        if any(b for b in fp.slow_frame_terms):
            raise NotCompilable("a frame compliance that changes with q (its update is Python)")
        self.jR = np.array([pm.jointPlacements[j].rotation for j in range(1, 7)])
        self.jp = np.array([pm.jointPlacements[j].translation for j in range(1, 7)])
        self.axis = np.array([_axis(pm.joints[j]) for j in range(1, 7)])
        fids = [*fp.frame_ids[:5], fp.sensor_id, fp.tcp_id]
        self.fR = np.array([pm.frames[f].placement.rotation for f in fids])
        self.fp = np.array([pm.frames[f].placement.translation for f in fids])
        self.fj = np.array([pm.frames[f].parentJoint for f in fids], dtype=np.int64)
        self.ch = np.array([fp.lam, fp.iterations])     # λ, and the Newton steps after the linear one
        self.iterations = fp.iterations
        self.oR = np.zeros((7, 3, 3))
        self.oR[0] = np.eye(3)
        self.op = np.zeros((7, 3))
        self.tmp, self.A6, self.pw = np.zeros((3, 3, 3)), np.zeros((6, 6)), np.zeros((6, 6))
        self.Ad = np.zeros((6, 6, 6))
        self.Ad[0] = np.eye(6)
        self.J, self.Jp = np.zeros((6, 6)), np.zeros((6, 6))
        self.Rs, self.ps, self.Rin = np.eye(3), np.zeros(3), np.ascontiguousarray(fp.R_in, dtype=float)
        self.Ttcp = np.eye(4)
        self.st, self.lever, self.c_pay = np.zeros(18), np.zeros((6, 3)), np.zeros(3)
        self.pre_rows, self.pre_w = np.zeros(0, dtype=np.int64), np.zeros((0, 60))
        self.tau_s = np.zeros(6)
        laws: dict[str, list] = {k: [] for k in ("axial", "history", "wrench", "twist")}

        def law_index(kind, term):
            if term.law is None:
                raise NotCompilable(f"joint {term.joint}'s axial term is a Python callable without a law")
            if term.law not in laws[kind]:
                laws[kind].append(term.law)
            return laws[kind].index(term.law)

        self.comp = np.ascontiguousarray(fp.compliance, dtype=float)
        self.axj = np.array([t.joint - 1 for t in fp.axial], dtype=np.int64)
        self.axl = np.array([law_index("axial", t) for t in fp.axial], dtype=np.int64)
        self.axp = _stack([t.params for t in fp.axial])
        self.at_rest = np.zeros(len(fp.axial))
        self.hj = np.array([h.joint - 1 for h in fp.history], dtype=np.int64)
        self.hl = np.array([law_index("history", h) for h in fp.history], dtype=np.int64)
        self.hp, self.hg = _stack([h.params for h in fp.history]), np.array([h.gain for h in fp.history])
        self.hs = self._states(fp.history)
        self.wl = np.array([law_index("wrench", t) for t in fp.wrench_terms], dtype=np.int64)
        self.wp, self.wst = _stack([t.params for t in fp.wrench_terms]), self._states(fp.wrench_terms)
        self.tl = np.array([law_index("twist", t) for t in fp.twist_terms], dtype=np.int64)
        self.tp, self.tst = _stack([t.params for t in fp.twist_terms]), self._states(fp.twist_terms)
        self.fm = np.array([b.frame for b in fp.frame_terms], dtype=np.int64)
        self.fC = np.array([b.C for b in fp.frame_terms], dtype=float).reshape(-1, 6, 6)
        self.wb, self.w0, self.dX, self.dq = np.zeros(6), np.zeros(6), np.zeros(6), np.zeros(6)
        self.ws = np.zeros(6)                   # the wrench in sensor axes (the compensator's signal path)
        self.local, self.delta = np.zeros((6, 6)), np.zeros((6, 6))
        self.r3, self.rA, self.rv, self.Jk = np.zeros((5, 3, 3)), np.zeros((6, 6)), np.zeros((6, 6)), np.zeros((6, 6))
        self.rR, self.rp = np.zeros((7, 3, 3)), np.zeros((7, 3))
        self.rR[0] = np.eye(3)
        self.statics(fp.statics)
        self._stateful = [(fp.history, "hs"), (fp.wrench_terms, "wst"), (fp.twist_terms, "tst")]
        self._parametered = [(fp.wrench_terms, "wp"), (fp.twist_terms, "tp")]
        self._carve()
        self.mod = module_for(laws)
        self._kin = self.mod.kinematics
        self._settle = self.mod.settle
        self._predict = self.mod.predict
        self._cycle = self.mod.cycle
        # the entries a service calls from Python, loaded now (numba's cache) rather than in a cycle: a steady
        # call that finds nothing armed (V zero) does nothing; the cycle's own arrays are restored by its caller
        self.mod.steady(self.F, self.I, np.zeros(STATE_SIZE), np.zeros(128), np.zeros((0, 5), dtype=np.int64),
                        np.zeros(1, dtype=np.uint8), np.zeros(1, dtype=np.uint8), np.zeros((1, 2), dtype=np.float32), 0)

    @staticmethod
    def _states(terms) -> np.ndarray:
        S = _stack([t.state for t in terms])
        for n, t in enumerate(terms):           # the term's state is now the compiled state
            S[n, :len(t.state)] = t.state
            t.state = S[n, :len(t.state)]
        return S

    def _carve(self) -> None:
        """Move the arrays of `template.FLOATS` and `template.INTS` into one buffer per dtype, ``F`` and ``I`` (led
        by four ints per array: its offset and shape), each attribute then a view of its part: `cycle` takes the
        two. The terms' states follow their stacked array."""
        rows = [*((n, float) for n, _ in FLOATS), *((n, np.int64) for n, _ in INTS)]
        arrays = [np.ascontiguousarray(getattr(self, n), dtype=t) for n, t in rows]
        n_f = sum(a.size for a, (_, t) in zip(arrays, rows) if t is float)
        n_i = sum(a.size for a, (_, t) in zip(arrays, rows) if t is np.int64)
        bufs = {float: np.zeros(n_f), np.int64: np.zeros(4 * len(rows) + n_i, dtype=np.int64)}
        at = {float: 0, np.int64: 4 * len(rows)}
        for k, ((name, t), a) in enumerate(zip(rows, arrays)):
            o = at[t]
            view = bufs[t][o:o + a.size].reshape(a.shape)
            view[...] = a
            setattr(self, name, view)
            bufs[np.int64][4 * k:4 * k + 4] = (o, *a.shape, *(1,) * (3 - a.ndim))
            at[t] = o + a.size
        self.F, self.I = bufs[float], bufs[np.int64]
        for terms, name in self._stateful:
            S = getattr(self, name)
            for n, term in enumerate(terms):
                term.state = S[n, :len(term.state)]
        for terms, name in self._parametered:
            P = getattr(self, name)             # a term's parameters too: written in place, the cycle reads
            for n, term in enumerate(terms):    # them (`stiffness.dynamics.follower` retunes the modes)
                term.params = P[n, :len(term.params)]

    def statics(self, statics) -> None:
        """Take `Statics` (or None: tau_s = 0) into the arrays, in place."""
        st = self.st
        st[:] = 0.0
        if statics is None:
            return
        if statics.pm.frames[statics.cog_id].parentJoint != 6:
            raise NotCompilable("the payload's centre is not on the last joint")
        st[0], st[1] = 1.0, float(statics.arm_loaded)
        st[2:5] = statics.g
        st[6:12] = [statics.pm.inertias[k].mass for k in range(1, 7)]
        st[12:18] = statics._balancer_gain
        self.lever[:] = [statics.pm.inertias[k].lever for k in range(1, 7)]
        rows = np.ascontiguousarray(statics._pre_rows, dtype=np.int64)
        w = np.ascontiguousarray(statics._pre_w, dtype=float).reshape(len(rows), 60)
        if hasattr(self, "F") and self.pre_w.shape == w.shape:     # carved: in place
            self.pre_rows[:], self.pre_w[:] = rows, w
        else:
            self.pre_rows, self.pre_w = rows, w
            if hasattr(self, "F"):
                self._carve()
        self.payload(statics)

    def payload(self, statics) -> None:
        """The payload's mass and centre from `Statics` (after `Statics.carry`), in place."""
        self.st[5] = statics.payload_kg
        self.c_pay[:] = statics._frames[statics.cog_id].placement.translation

    def kinematics(self, q: np.ndarray) -> None:
        self._kin(q, self.ch, self.jR, self.jp, self.axis, self.fR, self.fp, self.fj, self.oR, self.op, self.tmp,
                  self.A6, self.Ad, self.J, self.Jp, self.Rs, self.ps, self.Rin, self.Ttcp, self.pw, self.st,
                  self.lever, self.c_pay, self.pre_rows, self.pre_w, self.tau_s, self.axj, self.axl, self.axp,
                  self.at_rest)

    def settle(self) -> None:
        self._settle(self.axis, self.oR, self.op, self.tmp, self.pw, self.st, self.lever, self.c_pay,
                     self.pre_rows, self.pre_w, self.tau_s, self.axj, self.axl, self.axp, self.at_rest)

    def cycle(self, S: np.ndarray, out: np.ndarray, flags: int, dt: float) -> int:
        """One cycle's arithmetic in one call (`template.cycle`: its arguments and the bits it returns)."""
        return self._cycle(self.F, self.I, S, out, flags, dt)

    def predict(self, dt: float) -> None:
        """From ``wb`` (the wrench in base axes, about the sensor origin): ``dX`` and ``dq`` (without the
        refinement)."""
        self._predict(self.wb, self.ps, self.Ad, self.comp, self.tau_s, self.axj, self.axl, self.axp,
                      self.at_rest, self.hj, self.hl, self.hp, self.hs, self.hg, self.fm, self.fC, self.wl, self.wp,
                      self.wst, self.tl, self.tp, self.tst, dt, self.Ttcp, self.Jp, self.w0, self.local,
                      self.delta, self.dX, self.dq)
