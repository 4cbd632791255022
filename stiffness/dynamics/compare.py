"""The modes a model holds against the modes a record shows (`stiffcomp modes DATA --compare FILE`), as
`diagnose` does for a static effect: where the model fails and what is missing.

The record's modes are identified with one more than the model holds (`stiffness.dynamics.modes.identify`:
three at most, along orthogonal directions; a mode the record does not show is not made up, and then as many
as the model holds). Each of the model's modes is matched to the record's mode along the nearest direction
(|phi . phi'| at least MATCH_COS). What follows, largest first:

* a mode of the record with no match in the model is **missing**, with its frequency, damping, direction and
  evidence (in units of the record's noise floor, `stiffness.dynamics.excitation`);
* a matched mode whose frequency differs by more than FREQUENCY_OFF is **off in frequency**; by more than
  DAMPING_OFF (relative), **off in damping**;
* a mode of the model that matches none of the record's is **not seen** (the record may not excite it).

Before and after: the RMS of what each leaves of the record's deflection, the model's modes with the
compliance and lag the record gives (its best case: a trace's lag is not the arm's), against the record's own
modes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import DataError
from ..units import M_TO_MM
from .modes import Identified, Record, identify, response
from .structure import Structure

MATCH_COS = 0.7            # directions within 45 deg are the same mode's
FREQUENCY_OFF = 0.05       # a frequency off by more than 5 % is named
DAMPING_OFF = 0.5          # a damping off by more than half of it is named


@dataclass
class Finding:
    kind: str                 # missing, frequency, damping, unseen
    text: str
    size: float               # for the order: how far off (relative), or the evidence of a missing mode


@dataclass
class ModesVerdict:
    found: Identified
    findings: list[Finding]
    rms_model_mm: float       # what the model's modes leave (the compliance solved for the record)
    rms_found_mm: float       # what the record's own modes leave
    response_model: np.ndarray     # the model's response to the record (N, 3), m

    def lines(self) -> list[str]:
        if not self.findings:
            return [(f"the model's modes are the record's: it leaves {self.rms_model_mm:.4f} mm RMS, the record's own "
                     f"{self.rms_found_mm:.4f} mm")]
        out = [f"({k}) {f.text}" for k, f in enumerate(self.findings, 1)]
        out.append(f"the model's modes leave {self.rms_model_mm:.4f} mm RMS of the record's deflection; with these, "
                   f"{self.rms_found_mm:.4f} mm")
        return out


def _describe(m) -> str:
    return (f"{m.hz:.2f} Hz, damping {100 * m.damping:.1f} %, along [{', '.join(f'{x:+.2f}' for x in m.direction)}]")


def compare(rec: Record, model: Structure, max_lag_ms: float = 30.0) -> ModesVerdict:
    """The record's modes against ``model``'s (module docstring); DataError as `identify` raises it."""
    n = len(model.cfg.modes)
    found = None
    if n < 3:
        try:
            found = identify(rec, n + 1, max_lag_ms)
        except DataError as e:
            if "is not in the record" not in str(e):
                raise
    if found is None:
        found = identify(rec, n, max_lag_ms)
    evidence = dict(zip(map(id, found.structure.cfg.modes), found.evidence))
    findings, taken = [], set()
    for m in model.cfg.modes:
        cos = [abs(float(np.dot(m.direction, f.direction))) for f in found.structure.cfg.modes]
        k = int(np.argmax(cos))
        if cos[k] < MATCH_COS or k in taken:
            findings.append(Finding("unseen", f"the model's mode at {_describe(m)} is not in the record (nothing "
                                    "along its direction: the record may not excite it)", 0.0))
            continue
        taken.add(k)
        f = found.structure.cfg.modes[k]
        df = (f.hz - m.hz) / m.hz
        if abs(df) > FREQUENCY_OFF:
            findings.append(Finding("frequency", f"the model's mode at {m.hz:.2f} Hz is off in frequency: the record "
                                    f"rings at {f.hz:.2f} Hz along it ({100 * df:+.0f} %)", abs(df)))
        dz = (f.damping - m.damping) / m.damping
        if abs(dz) > DAMPING_OFF:
            findings.append(Finding("damping", f"the model's mode at {m.hz:.2f} Hz is off in damping: "
                                    f"{100 * m.damping:.1f} %, the record's {100 * f.damping:.1f} %", abs(dz)))
    for k, f in enumerate(found.structure.cfg.modes):
        if k not in taken:
            findings.append(Finding("missing", f"a mode missing from the model: {_describe(f)}; it explains "
                                    f"{evidence[id(f)]:.3g} P of the record", float("inf")))
    findings.sort(key=lambda x: -x.size)
    modes = Structure(Structure.Config(modes=model.cfg.modes, lag_ms=found.structure.cfg.lag_ms))
    predicted = response(rec, modes)
    rms = float(np.sqrt(np.mean(np.sum((rec.deflection - predicted) ** 2, axis=1)))) * M_TO_MM
    return ModesVerdict(found, findings, rms, found.rms_mm, predicted)
