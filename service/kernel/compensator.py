"""A `Compensator`'s compiled signal path: the conditioning call and the rest of the cycle in one more call.

The stages keep their Python objects (`SpikeRejector`, `SosLowPass`, `GravityCompensator`,
`CorrectionLimiter`): a reload replaces them or their parameters, tests and the status read them, and the
Python path runs on them. The compiled path works on arrays `bind` copies from them, and `unbind` copies
its state back before the Python path takes a cycle (a model reload's ramp). A stage replaced or
re-parametrised by a reload is noticed by identity at the next cycle and bound again.
"""

from __future__ import annotations

import numpy as np

from .signal import condition


class CompiledSignal:
    """The arrays of the compiled signal path of one `Compensator`."""

    def __init__(self):
        self.x, self.y = np.zeros(6), np.zeros(6)
        self.sp, self.last, self.max_step = np.zeros(4), np.zeros(6), np.zeros(6)
        self.coef, self.z = np.zeros((1, 5)), np.zeros((1, 2, 6))
        self.lim, self.out, self.ramp_rate = np.zeros(15), np.zeros(6), np.zeros(6)
        self.dq_deg, self.deflection = np.zeros(6), np.zeros(6)
        self.bound: tuple = ()
        self.args: tuple = (None,)             # the predictor's arrays for the signal path (Compensator)
        self._condition = condition

    def key(self, comp) -> tuple:
        """What the binding depends on: the stage objects and the parameter lists a reload replaces."""
        s, f, lim = comp.spikes, comp.filter, comp.limiter
        return (s, s.max_step, s.max_held, f, lim, lim.max, lim.rate, lim.ramp_s)

    def bind(self, comp) -> None:
        """Copy the stages' state and parameters into the arrays."""
        s, f, lim = comp.spikes, comp.filter, comp.limiter
        self.sp[:] = (s.last is not None, s.held, s.max_held, s.rejected)
        if s.last is not None:
            self.last[:] = s.last
        self.max_step[:] = s.max_step
        if self.coef.shape[0] != len(f._coef):
            self.coef, self.z = np.zeros((len(f._coef), 5)), np.zeros((len(f._coef), 2, 6))
        self.coef[:] = f._coef
        self.z[:] = f.state
        self.lim[:6], self.lim[6:12] = lim.max, lim.rate
        self.lim[12], self.lim[13], self.lim[14] = lim.ramp_s, lim.max_dt, float(lim.safe)
        self.out[:] = lim.out
        self.ramp_rate[:] = lim._ramp_rate
        self.bound = self.key(comp)

    def rebind(self, comp) -> None:
        """Bind again (after a stage changed), the state carried through the stages."""
        if self.bound:
            self.unbind(comp)
        self.bind(comp)

    def unbind(self, comp) -> None:
        """Copy the state back into the stages it was bound to (the Python path takes the next cycle, or a
        reload has replaced a stage: the replaced one keeps its state, the new one is bound next)."""
        s, f, lim = self.bound[0], self.bound[3], self.bound[4]
        if self.sp[0]:
            s.last = self.last.tolist()
        s.held, s.rejected = int(self.sp[1]), int(self.sp[3])
        f.state = self.z.tolist()
        lim.out, lim.safe, lim._ramp_rate = self.out.tolist(), bool(self.lim[14]), self.ramp_rate.tolist()
        self.bound = ()

    def condition(self, wrench) -> list[float]:
        """Spikes and the low-pass for one sample (six floats); the filtered sample."""
        self.x[:] = wrench
        self._condition(self.x, self.sp, self.last, self.max_step, self.coef, self.z, self.y)
        return self.y.tolist()
