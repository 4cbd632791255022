"""The misreadings of a probe log to try when its touches do not lie on the wall its trace cut: each plausible
misreading undone on a copy of the log (`misreadings`). Each copy is read against the cut as the log is
(`probe_geometry.readings`), and those that put the touches on the wall are named with their evidence, likeliest
first (`probe_checks.explain`), as `suspects` does for a CMM's radius and frame. The misreadings:

* joints in radians (every |q| below 2 pi, read as degrees);
* one joint's sign flipped, or one joint offset from the cut's (by the difference of the medians of the
  touches' and the cut's joints rounded to OFFSET_DEG, when that is over OFFSET_DEG: a joint zero of another
  convention is a round angle, and the touches' joints differ from the cut's medians by a little);
* a probe_frame in metres, or its length along another axis of the flange (the flange's frame for the stylus's);
* every approach reversed (named only where the approaches point straight back along the wall's normal, to a
  wall on the near side of the stylus centre, which a stylus smaller than the tool cannot touch).

A stylus radius that is off is not among them: `probe_checks` names it from the touches' common distance.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple

import numpy as np

from ..data.probe_log import ProbeLog
from ..kinematics.robot import PoseConfig
from .contour import TracedCut

OFFSET_DEG = 5.0     # a joint whose touches sit this far from the cut's (median) is tried shifted back


class Misreading(NamedTuple):
    """A misreading of a probe log: its words, the log with it undone, and whether it reverses every approach."""

    text: str
    log: ProbeLog
    reverses: bool = False


def misreadings(probe: ProbeLog, cut: TracedCut) -> list[Misreading]:
    """Each misreading of the module's docstring that ``probe`` may hold, undone; ``cut``: the trace's cut, whose
    median joints a joint's offset is measured from."""
    return list(_undone(probe, cut))


def _undone(probe: ProbeLog, cut: TracedCut):
    q = probe.q_deg
    if np.abs(q).max() <= 2 * np.pi:
        yield Misreading("the joints are in radians (the columns are q1_deg .. q6_deg, degrees)",
                         replace(probe, q_deg=np.degrees(q)))
    for j in range(6):
        if np.abs(q[:, j]).max() > 0:
            flipped = q.copy()
            flipped[:, j] *= -1.0
            yield Misreading(f"q{j + 1}_deg has the wrong sign", replace(probe, q_deg=flipped))
        off = float(cut.q_deg[j] - np.median(q[:, j]))
        off = float(np.round(off / OFFSET_DEG) * OFFSET_DEG)     # a convention's zero is a round angle (90, 180)
        if abs(off) > OFFSET_DEG:
            shifted = q.copy()
            shifted[:, j] += off
            yield Misreading(f"q{j + 1}_deg is {-off:+.1f} deg off the cut's joint {j + 1} (a zero of another "
                             "convention?)", replace(probe, q_deg=shifted))
    xyz = np.array(probe.probe_frame.xyz_mm, dtype=float)
    length = float(np.linalg.norm(xyz))
    rpy = list(probe.probe_frame.rpy_deg)
    if 0 < length < 5.0:
        yield Misreading(f"probe_frame's xyz_mm {_v(xyz)} is in metres: {_v(1000 * xyz)} mm",
                         replace(probe, probe_frame=PoseConfig(xyz_mm=list(1000 * xyz), rpy_deg=rpy)))
    for axis in range(3):
        for sign in (1.0, -1.0):
            along = np.zeros(3)
            along[axis] = sign * length
            if length > 0 and not np.allclose(along, xyz):
                yield Misreading(f"probe_frame's xyz_mm {_v(xyz)} puts the stylus off the flange's {'xyz'[axis]} "
                                 f"axis: {_v(along)} (the stylus centre in the flange frame, DH frame 6)",
                                 replace(probe, probe_frame=PoseConfig(xyz_mm=list(along), rpy_deg=rpy)))
    yield Misreading("every approach is reversed (it points from the wall to the stylus)",
                     replace(probe, approach=-probe.approach), reverses=True)


def _v(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:g}" for v in x) + "]"
