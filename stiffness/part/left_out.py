"""The points of a part that no figure holds, and why: every part command names them, in its text and its
JSON, and says which figures hold them (docs/part.md).

A point is left out when the tool passed it twice (which pass made it cannot be told), when the trace is
blind to the moment it was made, or when a robust fit judged it a gross error (`stiffness.fit.gross_errors`). A trace
is blind where it lost rows (`stiffness.data.trace_file.Trace.gaps`) and where the joints it holds jumped: the tool
moved JUMP_FACTOR times its typical step and JUMP_MM or more between two rows, most often after the joints
stood still for a while (a stalled PLC or host). Either way where the arm was and what loaded it then is not
known, and the path across is a chord.

Example: two points of one file left out for one reason make one line.

>>> text = left_out_lines([LeftOut("p.csv", 12, "10", TWICE), LeftOut("p.csv", 13, "11", TWICE)])
>>> len(text), text[0].startswith("2 point(s) left out: the tool passed them twice"), text[0].endswith("p.csv line(s) 12-13")
(1, True, True)
>>> line_ranges([5, 6, 7, 9, 12, 13])
'5-7, 9, 12-13'
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

GAP_MARGIN_MM = 3.0      # a point this close along the path to rows the trace lost may have been made then: the
                         # deflected tool passes a point up to its deflection along the path from the commanded
                         # one, and the path's curve is read over 2 mm either side
JUMP_FACTOR = 10.0       # a step between two rows this many times the typical one, and JUMP_MM or more, is a jump
JUMP_MM = 3.0            # the trace did not see; a shorter chord stays within 0.03 mm of a 35 mm circle's arc
TWICE, IN_GAP, JUMP, GROSS = "passed_twice", "trace_gap", "trace_jump", "gross_error"      # why, in the JSON
REASONS = {TWICE: "the tool passed them twice (a closed contour's entry and exit overlap), so which pass made "
                  "them cannot be told",
           IN_GAP: f"the trace lost the rows of the moment they were made (or within {GAP_MARGIN_MM:g} mm of the "
                   "path of them): where the arm was and what loaded it then is not known",
           JUMP: f"the joints the trace holds jumped across the moment they were made (or within {GAP_MARGIN_MM:g} "
                 "mm of the path of it): where the arm was and what loaded it then is not known",
           GROSS: "the robust fit judged them gross errors"}
SHOWN_LINES = 40         # file lines named per reason in the text (the JSON has all)


@dataclass(frozen=True)
class Jump:
    """The tool moved ``moved_mm`` between table rows ``row`` and ``row + 1`` of a trace, ``moved_mm /
    typical_mm`` times its typical step, after the joints stood still for ``still`` rows."""

    row: int
    after_cycle: int
    moved_mm: float
    typical_mm: float
    from_s: float
    to_s: float
    still: int

    def text(self, source: str) -> str:
        before = f" after standing still for {self.still} cycle(s)" if self.still else ""
        return (f"{source}: the joints jumped between cycles {self.after_cycle} and {self.after_cycle + 1} (t = "
                f"{self.from_s:.3f} to {self.to_s:.3f} s){before}: the tool moved {self.moved_mm:.2f} mm, "
                f"{self.moved_mm / self.typical_mm:.0f} x its typical step, and the trace did not see it pass (a "
                "stalled PLC or host)")

    def to_dict(self) -> dict:
        return {"kind": "joints_jumped", "after_cycle": self.after_cycle, "moved_mm": self.moved_mm,
                "typical_step_mm": self.typical_mm, "still_rows": self.still, "from_s": self.from_s, "to_s": self.to_s}


def jumps(trace, tool: np.ndarray, run: np.ndarray) -> list[Jump]:
    """Where ``trace``'s tool centre (``tool``, m, per row) moves JUMP_FACTOR times its typical step (the median
    of the steps it moves in rows ``run``) and JUMP_MM or more between two rows that ``run`` and follow each other
    (rows lost between two are a gap, `Trace.gaps`)."""
    step = np.linalg.norm(np.diff(tool, axis=0), axis=1)
    both = run[:-1] & run[1:] & (np.diff(trace.cycle) == 1)
    moves = step[both & (step > 1e-9)]
    if not len(moves):
        return []
    typical = float(np.median(moves))
    still = np.zeros(len(step), dtype=int)            # rows the joints stood still before each step
    for k in range(1, len(step)):
        still[k] = still[k - 1] + 1 if step[k - 1] <= 1e-9 else 0
    c, t = trace.cycle, trace.time_s
    return [Jump(int(k), int(c[k]), 1000 * float(step[k]), 1000 * typical, float(t[k]), float(t[k + 1]), int(still[k]))
            for k in np.nonzero(both & (step > max(JUMP_FACTOR * typical, JUMP_MM / 1000.0)))[0]]


@dataclass(frozen=True)
class LeftOut:
    """A point of a part file that the figures leave out: its file, line and label, and why."""

    source: str
    line: int
    label: str
    why: str                              # a key of REASONS
    residual_mm: float | None = None      # a gross error's residual along the normal, after the fit

    def to_dict(self) -> dict:
        out = {"part": self.source, "line": self.line, "point": self.label, "why": self.why,
               "reason": REASONS[self.why]}
        if self.residual_mm is not None:
            out["residual_mm"] = self.residual_mm
        return out


def left_out_lines(items: list[LeftOut]) -> list[str]:
    """One line per file and reason: how many points, why, and their file lines."""
    groups: dict[tuple[str, str], list[LeftOut]] = {}
    for x in items:
        groups.setdefault((x.why, x.source), []).append(x)
    out = []
    for (why, source), xs in groups.items():
        lines = sorted(x.line for x in xs)
        more = f" and {len(lines) - SHOWN_LINES} more" if len(lines) > SHOWN_LINES else ""
        sizes = [f"{x.residual_mm:+.3f}" for x in sorted(xs, key=lambda x: x.line) if x.residual_mm is not None]
        size = f" (residual {', '.join(sizes[:SHOWN_LINES])} mm)" if sizes else ""
        out.append(f"{len(xs)} point(s) left out: {REASONS[why]}: {source} line(s) {line_ranges(lines[:SHOWN_LINES])}"
                   f"{more}{size}")
    return out


def line_ranges(lines: list[int]) -> str:
    """Sorted line numbers as runs: '5-7, 9'."""
    runs: list[list[int]] = []
    for v in lines:
        if runs and v == runs[-1][1] + 1:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return ", ".join(f"{a}-{b}" if b > a else f"{a}" for a, b in runs)


def gross_errors(parts: list, data, outlier: np.ndarray, residual: np.ndarray) -> list[LeftOut]:
    """The points a robust fit judged gross errors: ``outlier`` and ``residual`` (mm, after the fit) over the
    rows of ``data``, the ``parts``' (`PartRows`) datasets concatenated; named by part file and line."""
    by_label = {p.label: p.part for p in parts}
    out = []
    for r in np.nonzero(outlier & data.measured[:, 0])[0]:
        part = by_label[data.config[r]]
        k = int(np.nonzero(part.lines == data.line[r])[0][0])
        out.append(LeftOut(part.source, int(part.lines[k]), part.labels[k], GROSS, float(residual[r, 0])))
    return out


def rms_kept_and_all(residual_mm: np.ndarray, measured: np.ndarray, outlier: np.ndarray) -> tuple[float, float]:
    """The RMS of the measured ``residual_mm`` over the points kept (not ``outlier``), and over all of them."""
    def rms(m):
        return float(np.sqrt(np.mean(residual_mm[m] ** 2))) if m.any() else float("nan")

    return rms(measured & ~outlier), rms(measured)


def fit_account(parts: list, data, fit) -> tuple[list[LeftOut], float, float]:
    """Every point left out of a fit (`identify.FitResult`) of the ``parts``' rows ``data``: the parts' own and
    the fit's gross errors; and the fit's RMS along the normal over the points kept, and with its gross errors."""
    left = [x for p in parts for x in p.left_out] + gross_errors(parts, data, fit.outlier, fit.residual)
    return left, *rms_kept_and_all(fit.residual[:, 0], data.measured[:, 0], fit.outlier)
