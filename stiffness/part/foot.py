"""The foot of the perpendicular from a point on a traced path: the polyline through the tool centre's samples, in
the plane across the tool axis. The part reader finds where the tool passed abeam of a measured point by it
(`stiffness.part.rows`), the probe check the wall's normal at a touch (`stiffness.part.probe`), the HIL's virtual
probe where its stylus meets the wall the cut left (`hil.probe`).

Example: the chord from (0, 0) to (2, 0) passes abeam of (1.5, 1) at 1.5, a distance 1 from it.

>>> import numpy as np
>>> foot_on_path(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]), np.array([1.5, 1.0]), 0)
(1.0, 0, 0.75)
"""

from __future__ import annotations

import numpy as np


def foot_on_path(c2: np.ndarray, p: np.ndarray, j: int, chord=lambda s: True) -> tuple[float, int, float]:
    """The foot of the perpendicular from ``p`` on the polyline ``c2`` (samples in time order) beside its
    sample ``j``, on the chords s -> s + 1 (s = j - 1, j) that ``chord(s)`` takes for the path: its distance
    from p, the chord s and the fraction along it; the sample j itself (fraction 0) where none is nearer."""
    best = (float(np.linalg.norm(c2[j] - p)), j, 0.0)
    for s in (j - 1, j):
        if s < 0 or s + 1 >= len(c2) or not chord(s):
            continue
        seg = c2[s + 1] - c2[s]
        L2 = float(seg @ seg)
        f = 0.0 if L2 == 0 else float(np.clip((p - c2[s]) @ seg / L2, 0.0, 1.0))
        dist = float(np.linalg.norm(c2[s] + f * seg - p))
        if dist < best[0]:
            best = (dist, s, f)
    return best
