"""Unit factors, named by direction: multiply a value in the first unit to get the second.

One module for the whole project, so that a factor never means its own inverse somewhere else::

    angle_deg = angle_rad * RAD_TO_DEG
    length_mm = length_m * M_TO_MM
"""

from __future__ import annotations

import math

RAD_TO_DEG = 180.0 / math.pi
DEG_TO_RAD = math.pi / 180.0
M_TO_MM = 1000.0
MM_TO_M = 1.0 / 1000.0
