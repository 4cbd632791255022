"""A probe log: the robot probes its own machined contour with a touch probe in the spindle
(docs/part_format.md, "A probe log").

A CSV file: a few ``# key: value`` lines (YAML), then a header row and one row per touch:

    # stiffcomp probe: the paper's circle, probed by the robot after the cut
    # tool_radius_mm: 4.0
    # stylus_radius_mm: 1.5
    # probe_frame: {xyz_mm: [0.0, 0.0, 250.0], rpy_deg: [0.0, 0.0, 0.0]}
    touch,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,approach_x,approach_y,approach_z
    1,0.5303,-59.6431,89.7312,0.0000,59.9119,0.5303,0.984808,0.173648,0.000000

q1_deg .. q6_deg         the joints the controller latched at the probe's trigger, deg (KUKA's $AXIS_INT after a
                         fast measurement input, ABB's SearchL hit through CalcJointT)
approach_x, _y, _z       the nominal direction the probe moved in when it touched, robot base axes (made unit)
touch                    a label per touch (optional; the line number names a touch otherwise)
tool_radius_mm           the cutter's radius (required): the wall lies that far from the cutter's axis
stylus_radius_mm         the stylus ball's radius (required; its effective radius, from a ring gauge)
probe_frame              the stylus ball's centre in the flange (DH frame 6): xyz_mm and rpy_deg as the robot
                         YAML's ``tcp`` (required)
probing_speed_mm_s,      optional, together: the probe moved on at the probing speed for the trigger's
trigger_latency_ms       latency before the joints were latched; the reader takes that distance back along the
                         approach

The touched point, in the robot's base, through the model's own (nominal) kinematics
(`stiffness.part.probe_geometry`):

    p = FK_probe(q_trigger) + (r_s - v tau) d        d the approach direction, r_s the stylus radius

and the cut's commanded tool centre is FK(q_commanded + correction) through the same kinematics, at nearly
the same joints: the robot's geometric errors (its DH table's, its encoders' offsets) cancel to first order
between the two, and no part frame is needed (both are in the robot's base). A ``part_frame`` key is refused
by name: it would mean nothing here.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
from pydantic import Field

from ..errors import DataError, Problems
from ..files.csv_table import given_twice, peek, read_table
from ..files.yaml_schema import Strict
from ..kinematics.robot import PoseConfig

JOINT_COLS = tuple(f"q{i}_deg" for i in range(1, 7))
APPROACH_COLS = ("approach_x", "approach_y", "approach_z")
HEADER = "touch," + ",".join(JOINT_COLS + APPROACH_COLS)
PART_FRAME_MEANINGLESS = ("a probe log needs no part frame: its touches are the robot's own joints, read through "
                          "the same kinematics as the trace, in the robot's base")


class ProbeHeader(Strict):
    """The ``# key: value`` lines of a probe log."""

    stiffcomp_probe: str | None = None
    tool_radius_mm: float = Field(gt=0.0, le=500.0)
    stylus_radius_mm: float = Field(gt=0.0, le=50.0)
    probe_frame: PoseConfig
    probing_speed_mm_s: float | None = Field(None, gt=0.0, le=1000.0)
    trigger_latency_ms: float | None = Field(None, ge=0.0, le=100.0)


@dataclass
class ProbeLog:
    """The touches of a probe log: latched joints, approach directions and the probe's geometry."""

    source: str
    q_deg: np.ndarray              # (N, 6) latched at each trigger
    approach: np.ndarray           # (N, 3) unit, base axes
    labels: list[str]
    lines: np.ndarray              # (N,) the file line of each touch
    tool_radius_mm: float
    stylus_radius_mm: float
    probe_frame: PoseConfig
    probing_speed_mm_s: float | None = None
    trigger_latency_ms: float | None = None
    title: str = ""

    def __len__(self) -> int:
        return len(self.q_deg)

    @property
    def overtravel_mm(self) -> float:
        """How far the probe moved on between the contact and the latch: v tau (mm; 0 when not given)."""
        if self.probing_speed_mm_s is None or self.trigger_latency_ms is None:
            return 0.0
        return self.probing_speed_mm_s * self.trigger_latency_ms / 1000.0

    def where(self, k: int) -> str:
        return f"{self.source}: line {self.lines[k]}"


PROBE_KEYS = ("stiffcomp_probe", "stylus_radius_mm", "probe_frame", "probing_speed_mm_s", "trigger_latency_ms")


def is_probe_log(path: str | Path) -> bool:
    """Whether ``path`` is a probe log rather than a CMM's points: a '#' line names a key only a probe log has
    (the stylus, its frame, its speed and latency: so a log whose header row is misspelt, or that has none, is
    still read and refused as one), or its header row names the latched joints and the approach (a trace names
    joints too)."""
    keys, cols = peek(path)
    return bool(keys & set(PROBE_KEYS)) or {"q1_deg", "approach_x"} <= cols     # a trace names joints too


def read_probe(path: str | Path) -> ProbeLog:
    """Read and check a probe log; DataError names the file and the line of every problem."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: probe log not found")
    problems = Problems()
    table = read_table(path, problems, HEADER)
    header = table.header(path, ProbeHeader, "tool_radius_mm, stylus_radius_mm, probe_frame",
                          partial(_refuse, path))
    cols = table.cols
    missing = [c for c in JOINT_COLS + APPROACH_COLS if c not in cols]
    if missing:
        raise DataError(f"{path}: line {table.header_line}: missing column(s) {', '.join(missing)}; a probe log "
                        f"needs {HEADER} (docs/part_format.md)")
    label_col = cols.index("touch") if "touch" in cols else None
    q, d, labels, where = [], [], [], []
    for line, row, v in table.numbers(path, JOINT_COLS + APPROACH_COLS, problems, "the joints and the approach",
                                      "value"):
        n = float(np.linalg.norm(v[6:]))
        if n < 1e-6:
            problems.add(f"{path}: line {line}: the approach direction is zero: give the direction the probe "
                         "moved in when it touched")
            continue
        q.append(v[:6])
        d.append(np.array(v[6:]) / n)
        labels.append(row[label_col].strip() if label_col is not None else str(line))
        where.append(line)
    given_twice(path, labels, where, "touch", problems)
    if problems:
        raise DataError(f"{path}: {problems.count} problem(s); nothing was loaded", problems)
    if len(q) < 3:
        raise DataError(f"{path}: {len(q)} touch(es); a contour needs at least 3")
    return ProbeLog(str(path), np.array(q), np.array(d), labels, np.array(where), header.tool_radius_mm,
                    header.stylus_radius_mm, header.probe_frame, header.probing_speed_mm_s,
                    header.trigger_latency_ms, header.stiffcomp_probe or "")


def _refuse(path: Path, data: dict) -> None:
    """What a probe log's '#' lines hold that the format refuses, in its words (`Table.header`)."""
    if "part_frame" in data:
        raise DataError(f"{path}: part_frame: {PART_FRAME_MEANINGLESS}; remove the key")
    if (data.get("probing_speed_mm_s") is None) != (data.get("trigger_latency_ms") is None):
        raise DataError(f"{path}: probing_speed_mm_s and trigger_latency_ms go together (the probe moves on v tau "
                        "between the contact and the latch); give both or neither")


def write_probe(path: str | Path, q_deg: np.ndarray, approach: np.ndarray, tool_radius_mm: float,
                stylus_radius_mm: float, probe_frame: PoseConfig, title: str = "",
                probing_speed_mm_s: float | None = None, trigger_latency_ms: float | None = None) -> Path:
    """Write touches (latched joints (N, 6) deg, approach directions (N, 3) base) as a probe log."""
    path = Path(path)
    lines = [f"# stiffcomp probe: {title or 'the robot probes its own part'}",
             f"# tool_radius_mm: {tool_radius_mm:g}",
             f"# stylus_radius_mm: {stylus_radius_mm:g}",
             f"# probe_frame: {probe_frame.flow_text()}"]
    if probing_speed_mm_s is not None and trigger_latency_ms is not None:
        lines += [f"# probing_speed_mm_s: {probing_speed_mm_s:g}", f"# trigger_latency_ms: {trigger_latency_ms:g}"]
    lines.append(HEADER)
    # joints to 1e-6 deg: 0.03 um at 2 m of reach, below any probe's resolution
    lines += [f"{k + 1}," + ",".join(f"{v:.6f}" for v in q) + "," + ",".join(f"{v:.6f}" for v in d)
              for k, (q, d) in enumerate(zip(q_deg, approach))]
    path.write_text("\n".join(lines) + "\n")
    return path
