"""The measured points of a QIF 3 results file (ANSI/DMSC QIF 3.0, ISO 23952): its point sets, and the points
each measured feature references (docs/part_format.md, "A CMM's QIF results file").

A ``MeasuredPointSet`` (QIF 3.0 schema, QIFLibrary/Features.xsd, ``MeasuredPointSetType``) holds ``count``
points as ``Points``, one list of x y z triples, or as ``BinaryPoints``; with them ``Compensated`` and
``ProbeRadius`` shared by all its points, or ``Compensations`` and ``ProbeRadii`` one per point; and optionally
a ``CoordinateSystemId`` or ``TranformId`` (the schema's spelling) when its points are not in the document's
common coordinate system. Some writers put ``Point/XYZ`` elements under ``Points`` or directly under the set;
those are read too.

A feature references its points through its ``PointList``: ``WholePointSetId`` (the whole set),
``RangePointSetId`` with ``range="START END"`` (inclusive, from 1) or ``SinglePointSetId`` with ``index``.

What cannot be read (a reference that does not resolve, a set without points, binary points, one value per
point, another coordinate system) is not an error of the file: it is `Unreadable`, whose text names the
element as the file has it, and leaves that feature out (`stiffness.data.qif_part`). A set is read only
for the features that use it, so a broken set never stops a feature that does not.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NS = "http://qifstandards.org/xsd/qif3"
BINARY = ("BinaryPoints", "CombinedPointsBinary", "PointsBinary")
PER_POINT = ("Compensations", "BinaryCompensated", "ProbeRadii", "BinaryProbeRadii")
OTHER_FRAME = ("CoordinateSystemId", "TranformId", "TransformId")     # QIF 3.0 spells it TranformId


class Unreadable(Exception):
    """A feature's points cannot be read; the text says why, naming the element as the file has it."""


def q(tag: str) -> str:
    return f"{{{NS}}}{tag}"


def local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


def text(el, tag: str) -> str | None:
    """The stripped text of the first ``tag`` under ``el`` (at any depth), or None."""
    x = el.find(f".//{q(tag)}")
    return x.text.strip() if x is not None and x.text else None


def number(where: str, value: str) -> float:
    """``value`` as a finite float; Unreadable names ``where`` otherwise."""
    try:
        v = float(value)
    except ValueError:
        raise Unreadable(f"{where}: {value!r} is not a number") from None
    if not np.isfinite(v):
        raise Unreadable(f"{where}: {value!r} is not finite")
    return v


@dataclass
class PointSet:
    """A MeasuredPointSet: its points in file units (None: not readable, ``problem`` says why) and what it says
    of them (the text of its Compensated and ProbeRadius)."""

    id: str
    points: list | None
    compensated: str | None
    probe_radius: str | None
    problem: str | None = None


def _triples(what: str, el) -> list[tuple]:
    vals = (el.text or "").split()
    if len(vals) % 3:
        raise Unreadable(f"{what}: Points holds {len(vals)} numbers, not x y z triples")
    nums = [number(f"{what} point {k // 3 + 1}", v) for k, v in enumerate(vals)]
    return [tuple(nums[k:k + 3]) for k in range(0, len(nums), 3)]


def _xyz_elements(what: str, xyzs) -> list[tuple]:
    pts = []
    for k, xyz in enumerate(xyzs):
        vals = (xyz.text or "").split()
        if len(vals) != 3:
            raise Unreadable(f"{what} point {k + 1}: XYZ {xyz.text!r} is not 'x y z'")
        pts.append(tuple(number(f"{what} point {k + 1}", v) for v in vals))
    return pts


def _set_points(ps, what: str) -> list[tuple]:
    """The set's points (file units), or Unreadable: a form this reader does not read, or no points at all."""
    for tag in BINARY:
        if ps.find(f".//{q(tag)}") is not None:
            raise Unreadable(f"{what}: binary points ({tag}) are not read; export the points as text (Points)")
    for tag in PER_POINT:
        if ps.find(q(tag)) is not None:
            raise Unreadable(f"{what}: {tag} (one value per point) is not read; export one Compensated and one "
                             "ProbeRadius for the set")
    for tag in OTHER_FRAME:
        ref = ps.find(q(tag))
        if ref is not None:
            raise Unreadable(f"{what}: its points are in another coordinate system ({tag} {(ref.text or '').strip()}),"
                             " which this reader does not apply; export them in the file's coordinate system")
    el = ps.find(q("Points"))
    if el is not None and el.find(q("Point")) is None:
        pts = _triples(what, el)
    else:
        xyzs = (el if el is not None else ps).findall(f"{q('Point')}/{q('XYZ')}")
        if el is None and not xyzs:
            raise Unreadable(f"{what}: no points: neither Points nor Point/XYZ")
        pts = _xyz_elements(what, xyzs)
    count = ps.get("count")
    if count is not None and count.strip() != str(len(pts)):
        raise Unreadable(f"{what}: count {count!r} but {len(pts)} points")
    return pts


def point_sets(root) -> dict[str, PointSet]:
    """Every MeasuredPointSet of the document by id; one that cannot be read carries its ``problem``."""
    sets = {}
    for ps in root.iter(q("MeasuredPointSet")):
        sid = ps.get("id", "")
        try:
            pts, problem = _set_points(ps, f"MeasuredPointSet {sid}"), None
        except Unreadable as e:
            pts, problem = None, str(e)
        sets[sid] = PointSet(sid, pts, text(ps, "Compensated"), text(ps, "ProbeRadius"), problem)
    return sets


def _bounds(tag: str, ref, sid: str, n: int) -> tuple[int, int]:
    """The first and last point (from 1) a reference takes of a set of ``n`` points."""
    if tag == "WholePointSetId":
        return 1, n
    attr = "range" if tag == "RangePointSetId" else "index"
    given = ref.get(attr)
    where = f"{tag} {sid!r} {attr} {given!r}"
    try:
        lo, hi = ((int(v) for v in given.split()) if tag == "RangePointSetId" else (int(given),) * 2)
    except (AttributeError, ValueError):
        form = "'start end'" if tag == "RangePointSetId" else "a whole number"
        raise Unreadable(f"{where} is not {form}") from None
    if not 1 <= lo <= hi <= n:
        raise Unreadable(f"{where} is outside MeasuredPointSet {sid}'s {n} points (from 1)")
    return lo, hi


def feature_points(fm, sets: dict[str, PointSet]) -> tuple[list, list[str], list[PointSet]]:
    """The points a feature measurement references (file units, in the order of its PointList), their labels
    (``SET:INDEX``) and the sets they come from; Unreadable when one reference cannot be read."""
    pts, labels, used = [], [], []
    for ref in fm.iter():
        tag = local(ref.tag)
        if tag not in ("WholePointSetId", "RangePointSetId", "SinglePointSetId"):
            continue
        sid = (ref.text or "").strip()
        if sid not in sets:
            raise Unreadable(f"{tag} {sid!r} does not resolve to a MeasuredPointSet")
        s = sets[sid]
        if s.points is None:
            raise Unreadable(s.problem)
        lo, hi = _bounds(tag, ref, sid, len(s.points))
        pts += s.points[lo - 1: hi]
        labels += [f"{sid}:{k}" for k in range(lo, hi + 1)]
        used.append(s)
    return pts, labels, used


def of_sets(tag: str, own: str | None, said_by_sets: list[str | None]) -> str | None:
    """The feature's own ``tag`` (Compensated, ProbeRadius), else what its point sets say (QIF 3 puts it
    there), which must agree."""
    if own is not None:
        return own
    said = set(said_by_sets) - {None}
    if len(said) > 1:
        raise Unreadable(f"its point sets differ in {tag} ({', '.join(sorted(said))}); export them as one set")
    return said.pop() if said else None
