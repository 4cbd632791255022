"""A `Compensator`'s compiled signal path: the state of its stages in one array, the cycle in one call.

The stages keep their Python objects (`SpikeRejector`, `SosLowPass`, `GravityCompensator`,
`CorrectionLimiter`): a reload replaces them or their parameters, tests and the status read them, and the
Python path runs on them. The compiled path works on arrays `bind` copies from them, and `unbind` copies
its state back before the Python path takes a cycle (a model reload's ramp) or a reload reads them. A stage
replaced by a reload is noticed by identity at the next cycle and bound again; a reload that changes a stage's
parameters releases the stages first (`Compensator.release_stages`).
"""

from __future__ import annotations

import numpy as np

from .build import NotCompilable
from .signal import HAVE_LAST, HELD, MAX_DT, MAX_HELD, RAMP_S, RATE, REJECTED, SAFE_BEFORE, condition
from .template import SECTIONS, STATE, STATE_SIZE


class CompiledSignal:
    """The arrays of the compiled signal path of one `Compensator`, all in ``S`` (`template.STATE`: the sample
    x, the filtered y, the spike rejector's, the low-pass's and the limiter's state and parameters, the
    payload's weight and the bias, the joints), each part also an attribute."""

    def __init__(self):
        self.S = np.zeros(STATE_SIZE)
        for name, o, n in STATE:
            setattr(self, name, self.S[o:o + n])
        self.out = self.lout                    # the limiter's output, deg
        self.x_in = memoryview(self.x).cast("B").cast("d")      # a sample in, six stores
        self.coef, self.z = self.coefs[:5].reshape(1, 5), self.zs[:12].reshape(1, 2, 6)
        self.bound: tuple = ()
        self._condition = condition


    def bind(self, comp) -> None:
        """Copy the stages' state and parameters into the arrays; the gravity compensator's parameters (its
        ``gp``) live in S from now on."""
        s, f, lim, g = comp.spikes, comp.filter, comp.limiter, comp.gravity
        self.sp[HAVE_LAST], self.sp[HELD] = s.last is not None, s.held
        self.sp[MAX_HELD], self.sp[REJECTED] = s.max_held, s.rejected
        if s.last is not None:
            self.last[:] = s.last
        self.max_step[:] = s.max_step
        if f.last_output is not None:
            self.y[:] = f.last_output
        n = len(f._coef)
        if n > SECTIONS:
            raise NotCompilable(f"a low-pass of {n} second-order sections (the compiled one has room for {SECTIONS})")
        self.sections[0] = n
        self.coef, self.z = self.coefs[:5 * n].reshape(n, 5), self.zs[:12 * n].reshape(n, 2, 6)
        self.coef[:] = f._coef
        self.z[:] = f.state
        self.q[:] = comp.q_rad
        if g.gp is not self.gp:
            self.gp[:] = g.gp
            g.gp = self.gp
        self.lim[:RATE], self.lim[RATE:RAMP_S] = lim.max, lim.rate
        self.lim[RAMP_S], self.lim[MAX_DT], self.lim[SAFE_BEFORE] = lim.ramp_s, lim.max_dt, float(lim.safe)
        self.out[:] = lim.out
        self.ramp_rate[:] = lim._ramp_rate
        self.bound = (s, f, lim)               # the stages bound (`Compensator.cycle` checks them)

    def rebind(self, comp) -> None:
        """Bind again (after a stage changed), the state carried through the stages."""
        if self.bound:
            self.unbind(comp)
        self.bind(comp)

    def unbind(self, comp) -> None:
        """Copy the state back into the stages it was bound to (the Python path takes the next cycle, or a
        reload reads or replaces a stage: the replaced one keeps its state, the new one is bound next)."""
        s, f, lim = self.bound
        if self.sp[HAVE_LAST]:
            s.last = self.last.tolist()
        s.held, s.rejected = int(self.sp[HELD]), int(self.sp[REJECTED])
        f.state = self.z.tolist()
        if f.last_output is not None:           # the filter has seen a sample
            f.last_output = comp.filtered = self.y.tolist()
        lim.out, lim.safe, lim._ramp_rate = self.out.tolist(), bool(self.lim[SAFE_BEFORE]), self.ramp_rate.tolist()
        self.bound = ()

    def condition(self, wrench) -> list[float]:
        """Spikes and the low-pass for one sample (six floats); the filtered sample."""
        self.x[:] = wrench
        self._condition(self.x, self.sp, self.last, self.max_step, self.coef, self.z, self.y)
        return self.y.tolist()
