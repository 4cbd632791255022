"""A machined part's measurement: points on its surface from a CMM or an on-machine probe
(docs/part_format.md).

A CSV file: a few ``# key: value`` lines (YAML), then a header row and one row per point:

    # stiffcomp part: the paper's circle, CMM of 2026-11-24
    # tool_radius_mm: 4.0
    # part_frame: {xyz_mm: [1524.1, 0.0, 1020.5], rpy_deg: [0.0, 0.0, 0.0]}
    point,x_mm,y_mm,z_mm
    1,39.0012,0.0000,-2.0000
    2,38.9953,0.6803,-2.0000

x_mm, y_mm, z_mm   the point on the machined surface, mm, in the part's frame (required)
point              a label per point (optional; the line number names a point otherwise)
tool_radius_mm     the cutter's radius (required): the surface lies that far from the tool's axis
part_frame         the part frame in the robot's base (xyz_mm, rpy_deg as the robot YAML's poses: URDF
                   roll-pitch-yaw), from the fixture's calibration; without it the part has no datum and
                   only ``--best-fit`` can place it (which hides a constant offset, `stiffness.part.rows`)

Errors name the file and the line. Units: the format is millimetres; a file whose points sit where the
trace says the tool went only after scaling by 25.4 or 1000 is named as inches or metres
(`stiffness.part.rows`).
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

POINT_COLS = ("x_mm", "y_mm", "z_mm")


class PartHeader(Strict):
    """The ``# key: value`` lines of a part file."""

    stiffcomp_part: str | None = None
    tool_radius_mm: float = Field(gt=0.0, le=500.0)
    part_frame: PoseConfig | None = None


@dataclass
class PartMeasurement:
    """Points on a machined surface (part frame, mm), where they came from, and the cut's geometry."""

    source: str
    points_mm: np.ndarray          # (N, 3) in the part frame
    labels: list[str]
    lines: np.ndarray              # (N,) the file line of each point
    tool_radius_mm: float
    frame: np.ndarray | None       # (4, 4) base <- part (m), or None: no datum
    title: str = ""
    stylus_radius_mm: float | None = None   # touched by the robot's own probe (`probe_log`): placed by this
                                            # radius and probe_frame, not by a part_frame; None: a CMM's points

    @property
    def probed(self) -> bool:
        return self.stylus_radius_mm is not None

    def __len__(self) -> int:
        return len(self.points_mm)

    def in_base(self, frame: np.ndarray | None = None) -> np.ndarray:
        """The points in the robot's base (m), through ``frame`` (default: the file's part frame)."""
        T = self.frame if frame is None else frame
        if T is None:
            raise DataError(f"{self.source}: no part_frame: the points cannot be placed in the robot's base "
                            "(give the fixture's calibration as part_frame, or --best-fit)")
        return self.points_mm / 1000.0 @ T[:3, :3].T + T[:3, 3]

    def where(self, k: int) -> str:
        """``FILE: line N`` of point ``k``."""
        return f"{self.source}: line {self.lines[k]}"


def read_part(path: str | Path) -> PartMeasurement:
    """Read and check a part file; DataError names the file and the line of every problem."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: part file not found")
    problems = Problems()
    table = read_table(path, problems, "point,x_mm,y_mm,z_mm")
    header = table.header(path, PartHeader, "tool_radius_mm, part_frame", partial(_refuse, path))
    cols = table.cols
    missing = [c for c in POINT_COLS if c not in cols]
    if missing:
        unit = next((c for c in cols if c.lower() in ("x_in", "x_inch", "x_m")), None)
        hint = f" ({unit} is not millimetres: the format is mm)" if unit else ""
        raise DataError(f"{path}: line {table.header_line}: missing column(s) {', '.join(missing)}{hint}; "
                        f"the format needs {', '.join(POINT_COLS)} (docs/part_format.md)")
    label_col = cols.index("point") if "point" in cols else None
    pts, labels, where = [], [], []
    for line, row, p in table.numbers(path, POINT_COLS, problems, "x_mm, y_mm and z_mm", "coordinate"):
        pts.append(p)
        labels.append(row[label_col].strip() if label_col is not None else str(line))
        where.append(line)
    given_twice(path, labels, where, "point", problems)
    if problems:
        raise DataError(f"{path}: {problems.count} problem(s); nothing was loaded", problems)
    if len(pts) < 3:
        raise DataError(f"{path}: {len(pts)} point(s); a contour needs at least 3")
    frame = header.part_frame.matrix() if header.part_frame is not None else None
    return PartMeasurement(str(path), np.array(pts), labels, np.array(where), header.tool_radius_mm, frame,
                           header.stiffcomp_part or "")


def is_cmm_part(path: str | Path) -> bool:
    """Whether ``path`` reads as a CMM's points: the first row after its '#' lines names x_mm, y_mm and z_mm."""
    return {"x_mm", "y_mm", "z_mm"} <= peek(path)[1]


def _refuse(path: Path, data: dict) -> None:
    """What a part file's '#' lines lack, in the format's words (`Table.header`)."""
    if "tool_radius_mm" not in data:
        raise DataError(f"{path}: '# tool_radius_mm: R' is missing: the surface lies the cutter's radius from "
                        "the tool's axis (docs/part_format.md)")


def write_part(path: str | Path, points_mm: np.ndarray, tool_radius_mm: float, frame: PoseConfig | None,
               title: str = "", labels: list[str] | None = None) -> Path:
    """Write points (N, 3, part frame, mm) in the part format."""
    path = Path(path)
    lines = [f"# stiffcomp part: {title or 'points on a machined surface'}",
             f"# tool_radius_mm: {tool_radius_mm:g}"]
    if frame is not None:
        lines.append(f"# part_frame: {frame.flow_text()}")
    lines.append("point," + ",".join(POINT_COLS))
    labels = labels or [str(k + 1) for k in range(len(points_mm))]
    lines += [f"{lab}," + ",".join(f"{v:.4f}" for v in p) for lab, p in zip(labels, points_mm)]
    path.write_text("\n".join(lines) + "\n")
    return path
