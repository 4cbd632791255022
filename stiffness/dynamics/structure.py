"""The structure's modes in the correction: the deflection the arm will show, not only the static one (the
paper's open problem 3).

The arm carries its static deflection x_s (the stiffness model's dX, m, base axes) through lightly damped
modes: mode k, frequency f_k, damping zeta_k, unit direction phi_k (base axes), moves the TCP along phi_k as

    a_k = H_k(s) (phi_k . x_s),     H_k(s) = (w_k^2 + c_k s) / (s^2 + 2 zeta'_k w_k s + w_k^2),   w_k = 2 pi f_k
    dX <- dX + sum_k phi_k (a_k - phi_k . x_s)

With zeta' = zeta and c = 0, H_k is the mode itself: the correction rings as the arm does and cancels its
ringing, if f_k is right. ``added_damping`` (YAML) sets zeta' = zeta + added and c = 2 (zeta' - zeta) w_k:
H_k then agrees with the mode to second order in s (the lag 2 zeta / w and the inertia -s^2 / w^2 of a
slow load), but rings far less, so a mode frequency that is off does not inject ringing of its own; the
price is that the arm's own ringing stays (docs/dynamics.md has both, and the case of a frequency 20 %
off). The rotation part of dX is left as it is (the modes move the TCP).

lag_ms (YAML) is the arm's own lag behind the force beyond its modes (what `stiffcomp modes` identifies:
the joints' low-pass): the predictor's horizon is the delay less this lag (`DynamicsContext`).

The modes are those identified where the robot cuts (`stiffcomp modes`, `stiffness.dynamics.modes`);
they move across the workspace (published: up to 40 %), so identify them again for another working area.

Real-time term: a `TwistTerm` whose law is `structure_law`, each mode's H_k as a biquad (bilinear at the
cycle's period, prewarped at f_k), on the Python and the compiled path; it starts in the steady state of
the first deflection (no ringing assumed). `Structure.respond` runs the same biquads over a whole record
(the identification and its plot).

Example: a step of 1 mm along a 10 Hz mode with 3 % damping overshoots to nearly 2 mm half a period later.

>>> import numpy as np
>>> from stiffness.dynamics.base import DynamicsContext
>>> part = Structure(Structure.Config(modes=[{"hz": 10.0, "damping": 0.03, "direction": [1, 0, 0]}]))
>>> x = np.zeros((200, 3)); x[1:, 0] = 1e-3
>>> a = part.respond(x, 0.001)
>>> print(f"{1000 * a[1:].max():.2f} mm at {np.argmax(a[:, 0])} ms")
1.91 mm at 51 ms
"""

from __future__ import annotations

import numpy as np
from pydantic import Field, field_validator
from scipy import signal

from ..effects.terms import TwistTerm
from ..files.yaml_schema import Strict
from .base import DynamicsContext, Stage, biquad

PER_MODE = 8             # phi (3), b0 b1 b2 a1 a2
MAX_LAG_MS = 100.0       # the most lag_ms takes


class ModeConfig(Strict):
    """One mode: frequency (Hz), damping ratio and the direction it moves the TCP ([x, y, z], made unit)."""

    hz: float = Field(gt=0.0, le=500.0)
    damping: float = Field(ge=1e-3, le=2.0)
    direction: list[float] = Field(min_length=3, max_length=3)

    @field_validator("direction")
    @classmethod
    def _unit(cls, v: list[float]) -> list[float]:
        n = float(np.linalg.norm(v))
        if n < 1e-9:
            raise ValueError("must not be zero: the direction the mode moves the TCP, [x, y, z]")
        return [float(x) / n for x in v]


def orthogonal(modes: list[ModeConfig]) -> list[ModeConfig]:
    """``modes`` if their directions are orthogonal (a modal basis in Cartesian space), else ValueError."""
    d = np.array([m.direction for m in modes]).reshape(-1, 3)
    if len(d) and not np.allclose(d @ d.T, np.eye(len(d)), atol=1e-3):      # YAML rounds them
        raise ValueError("the modes' directions must be orthogonal (a modal basis in Cartesian space)")
    return modes


def mode_biquad(hz: float, damping: float, period_s: float, added_damping: float = 0.0) -> np.ndarray:
    """[b0, b1, b2, a1, a2] of one mode's H (module docstring) at ``period_s``, prewarped at ``hz``."""
    w, zf = 2.0 * np.pi * hz, damping + added_damping
    return biquad([0.0, 2.0 * added_damping * w, w * w], [1.0, 2.0 * zf * w, w * w], period_s, hz)


def structure_law(s, p, dX, dt):
    """dX (6,) <- the modes' response, in place; p = [K, K x (phi (3), b0, b1, b2, a1, a2)];
    s = [K x (z0, z1), started, K x u] (u: this cycle's phi_k . x_s, what the follower compares the arm with,
    `stiffness.dynamics.follower`)."""
    n = int(p[0])
    first = s[2 * n] == 0.0
    for k in range(n):
        o = 1 + 8 * k
        u = p[o] * dX[0] + p[o + 1] * dX[1] + p[o + 2] * dX[2]
        s[2 * n + 1 + k] = u
        b0, b1, b2, a1, a2 = p[o + 3], p[o + 4], p[o + 5], p[o + 6], p[o + 7]
        if first:                          # the steady state of the first deflection: H(0) = 1
            s[2 * k + 1] = (b2 - a2) * u
            s[2 * k] = (b1 - a1) * u + s[2 * k + 1]
        y = b0 * u + s[2 * k]
        s[2 * k] = b1 * u - a1 * y + s[2 * k + 1]
        s[2 * k + 1] = b2 * u - a2 * y
        for i in range(3):
            dX[i] += p[o + i] * (y - u)
    s[2 * n] = 1.0


class Structure(Stage):
    """``dynamics.structure``: the arm's modes (module docstring)."""

    name = "structure"

    class Config(Strict):
        modes: list[ModeConfig] = Field(min_length=1, max_length=6)
        lag_ms: float = Field(0.0, ge=0.0, le=MAX_LAG_MS)
        added_damping: float = Field(0.0, ge=0.0, le=2.0)

        _orthogonal = field_validator("modes")(classmethod(lambda cls, v: orthogonal(v)))

    def coefficients(self, period_s: float) -> np.ndarray:
        """(K, 5) each mode's biquad [b0, b1, b2, a1, a2] at ``period_s``."""
        return np.array([mode_biquad(m.hz, m.damping, period_s, self.cfg.added_damping) for m in self.cfg.modes])

    def params(self, period_s: float) -> np.ndarray:
        rows = [[*m.direction, *c] for m, c in zip(self.cfg.modes, self.coefficients(period_s))]
        return np.array([len(rows), *np.ravel(rows)])

    def terms(self, ctx: DynamicsContext) -> list[TwistTerm]:
        return [TwistTerm(structure_law, self.params(ctx.period_s), [0.0] * (3 * len(self.cfg.modes) + 1))]

    def lag_s(self) -> float:
        return self.cfg.lag_ms / 1000.0

    @staticmethod
    def inputs(term: TwistTerm) -> np.ndarray:
        """The last cycle's u = phi_k . x_s of each mode, from the term's state (`structure_law`)."""
        n = int(term.params[0])
        return term.state[2 * n + 1:3 * n + 1]

    def with_frequencies(self, hz) -> Structure:
        """This structure with the modes at ``hz`` (one each; the follower's, `stiffness.dynamics.follower`)."""
        modes = [m.model_copy(update={"hz": float(f)}) for m, f in zip(self.cfg.modes, hz)]
        return Structure(self.cfg.model_copy(update={"modes": modes}))

    def respond(self, x_static: np.ndarray, period_s: float) -> np.ndarray:
        """The modes' response (N, 3) to a static deflection (N, 3) sampled every ``period_s`` (s), from its
        steady state: the biquads of `structure_law` run over the record (scipy.signal.lfilter)."""
        x = np.asarray(x_static, dtype=float)
        out = x.copy()
        for m, c in zip(self.cfg.modes, self.coefficients(period_s)):
            phi = np.array(m.direction)
            u = x @ phi
            b, a = c[:3], np.array([1.0, c[3], c[4]])
            y = signal.lfilter(b, a, u, zi=signal.lfilter_zi(b, a) * u[0])[0]
            out += np.outer(y - u, phi)
        return out

    def describe(self) -> str:
        modes = ", ".join(f"{m.hz:g} Hz {100 * m.damping:.1f} %" for m in self.cfg.modes)
        extra = f", damping + {self.cfg.added_damping:g}" if self.cfg.added_damping else ""
        return f"structure ({modes}{extra}; lag {self.cfg.lag_ms:g} ms)"


def read_structure(path, option: str) -> Structure:
    """The ``dynamics.structure`` of a YAML file (a service config, or what `stiffcomp modes -o` writes);
    DataError naming ``option`` and the file when it holds none, or one the service does not take."""
    from pydantic import ValidationError

    from ..errors import DataError
    from ..files.yaml_schema import format_validation_error, read_yaml

    data = read_yaml(path)
    section = (data.get("dynamics") or {}).get("structure") if isinstance(data, dict) else None
    if not isinstance(section, dict):
        raise DataError(f"{option} {path}: no dynamics.structure in it (a service config's, or what "
                        "`stiffcomp modes -o` writes)")
    try:
        return Structure(Structure.Config.model_validate(section))
    except ValidationError as e:
        raise DataError(format_validation_error(str(path), e, prefix="dynamics.structure")) from e
