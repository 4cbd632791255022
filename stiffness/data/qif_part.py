"""A CMM's QIF 3 results file (ANSI/DMSC QIF 3.0, ISO 23952) read as a part (docs/part_format.md, "QIF").

QIF results hold every measured feature of one or more parts: its points (a measured point set, referenced as
a whole or as a range), whether they are compensated for the probe's radius, and the file's units. What QIF
does not carry, the cutter's radius and the part frame, comes from the caller (`read_qif_part`).

The XML is parsed by defusedxml with DTDs forbidden: a document type declaration, an entity (a "billion
laughs" bomb) or an external reference is refused before anything is expanded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataError

NS = "http://qifstandards.org/xsd/qif3"
UNITS_MM = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "inch": 25.4, "in": 25.4, "m": 1000.0,
            "meter": 1000.0, "metre": 1000.0}
CIRCULAR = ("Circle", "Cylinder")


def _q(tag: str) -> str:
    return f"{{{NS}}}{tag}"


def _local(tag: str) -> str:
    return tag.rsplit("}", 1)[-1]


@dataclass
class QifFeature:
    """One measured feature: its points as the file gives them (mm), and what the file says of them."""

    name: str
    id: str
    type: str                           # "Circle", "Cylinder", "Plane", ...
    points_mm: np.ndarray               # (N, 3), mm, as measured (probe centres when not compensated)
    labels: list[str]
    compensated: bool
    probe_radius_mm: float
    reported_diameter_mm: float | None
    internal: bool | None               # a hole (True), a boss (False), not said (None)


@dataclass
class QifResults:
    path: Path
    unit: str
    results: int                        # which MeasurementResults (from 1)
    features: list[QifFeature] = field(default_factory=list)


def _parse(path: Path):
    from xml.etree.ElementTree import ParseError

    import defusedxml.ElementTree as DET
    from defusedxml import DefusedXmlException

    if not path.exists():
        raise DataError(f"{path}: QIF file not found")
    try:
        return DET.parse(str(path), forbid_dtd=True, forbid_entities=True, forbid_external=True).getroot()
    except DefusedXmlException as e:
        raise DataError(f"{path}: refused: the XML declares a DTD, an entity or an external reference "
                        f"({type(e).__name__}); a QIF file needs none") from None
    except ParseError as e:
        line = e.position[0] if getattr(e, "position", None) else "?"
        raise DataError(f"{path}: line {line}: not QIF: not well-formed XML ({e})") from None


def _unit(path: Path, root) -> tuple[str, float]:
    el = root.find(f"{_q('FileUnits')}/{_q('PrimaryUnits')}/{_q('LinearUnit')}/{_q('UnitName')}")
    if el is None:
        return "mm", 1.0        # QIF's default linear unit
    name = (el.text or "").strip()
    if name.lower() not in UNITS_MM:
        raise DataError(f"{path}: FileUnits/PrimaryUnits/LinearUnit/UnitName {name!r}: a unit this reader does "
                        f"not know (it reads {', '.join(UNITS_MM)})")
    return name, UNITS_MM[name.lower()]


def _check_root(path: Path, root) -> None:
    if _local(root.tag) != "QIFDocument" or not root.tag.startswith(f"{{{NS}}}"):
        raise DataError(f"{path}: not QIF: the root element is {_local(root.tag)!r}, not QIFDocument in {NS}")
    version = root.get("versionQIF", "")
    if not version.startswith("3."):
        raise DataError(f"{path}: QIFDocument versionQIF {version!r}: only QIF 3.x results are read")


def _text(el, tag: str) -> str | None:
    x = el.find(f".//{_q(tag)}")
    return x.text.strip() if x is not None and x.text else None


def _number(path: Path, where: str, text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise DataError(f"{path}: {where}: {text!r} is not a number") from None
    if not np.isfinite(v):
        raise DataError(f"{path}: {where}: {text!r} is not finite")
    return v


@dataclass
class _PointSet:
    """A MeasuredPointSet: its points in file units (None: binary, not read) and what it says of them."""

    points: list | None
    compensated: str | None
    probe_radius: str | None


def _xyz_triples(path: Path, sid: str, el) -> list[tuple[float, float, float]]:
    """The set's points: QIF 3's ``Points`` list of x y z triples, or Point/XYZ elements."""
    if el is not None and el.find(_q("Point")) is None:
        vals = (el.text or "").split()
        if len(vals) % 3:
            raise DataError(f"{path}: MeasuredPointSet {sid}: Points holds {len(vals)} numbers, not x y z triples")
        nums = [_number(path, f"MeasuredPointSet {sid} point {k // 3 + 1}", v) for k, v in enumerate(vals)]
        return [tuple(nums[k:k + 3]) for k in range(0, len(nums), 3)]
    pts = []
    for k, xyz in enumerate((el if el is not None else []).iter(_q("XYZ"))):
        vals = (xyz.text or "").split()
        if len(vals) != 3:
            raise DataError(f"{path}: MeasuredPointSet {sid} point {k + 1}: XYZ {xyz.text!r} is not 'x y z'")
        pts.append(tuple(_number(path, f"MeasuredPointSet {sid} point {k + 1}", v) for v in vals))
    return pts


def _point_sets(path: Path, root) -> dict[str, _PointSet]:
    sets = {}
    for ps in root.iter(_q("MeasuredPointSet")):
        sid = ps.get("id", "")
        binary = any(ps.find(f".//{_q(t)}") is not None for t in ("CombinedPointsBinary", "PointsBinary",
                                                                   "BinaryPoints"))
        pts = None if binary else _xyz_triples(path, sid, ps.find(_q("Points")))   # binary: refused when used
        count = ps.get("count")
        if pts is not None and count is not None and count.strip() != str(len(pts)):
            raise DataError(f"{path}: MeasuredPointSet {sid}: count {count!r} but {len(pts)} points")
        sets[sid] = _PointSet(pts, _text(ps, "Compensated"), _text(ps, "ProbeRadius"))
    return sets


def _feature_points(path: Path, fm, fid: str, sets) -> tuple[list, list[str], list[_PointSet]]:
    pts, labels, used = [], [], []
    refs = [(r, None) for r in fm.iter(_q("WholePointSetId"))] + \
           [(r, r.get("range", "")) for r in fm.iter(_q("RangePointSetId"))] + \
           [(r, f"{r.get('index', '')} {r.get('index', '')}") for r in fm.iter(_q("SinglePointSetId"))]
    for ref, rng in refs:
        sid = (ref.text or "").strip()
        if sid not in sets:
            raise DataError(f"{path}: feature {fid}: point set id {sid!r} does not resolve to a MeasuredPointSet")
        points = sets[sid].points
        if points is None:
            raise DataError(f"{path}: MeasuredPointSet {sid}: binary points (CombinedPointsBinary, BinaryPoints) "
                            "are not read; export the points as text (Points)")
        lo, hi = 1, len(points)
        if rng is not None:
            try:
                lo, hi = (int(v) for v in rng.split())
            except ValueError:
                raise DataError(f"{path}: feature {fid}: RangePointSetId range {rng!r} is not 'start end'") from None
            if not 1 <= lo <= hi <= len(points):
                raise DataError(f"{path}: feature {fid}: RangePointSetId range {rng!r} is outside point set {sid}'s "
                                f"{len(points)} points (from 1)")
        pts += points[lo - 1: hi]
        labels += [f"{sid}:{k}" for k in range(lo, hi + 1)]
        used.append(sets[sid])
    return pts, labels, used


def _of_sets(path: Path, fid: str, tag: str, own: str | None, of_sets: list[str | None]) -> str | None:
    """The feature's own ``tag`` (Compensated, ProbeRadius), else what its point sets say (QIF 3 puts it
    there), which must agree."""
    if own is not None:
        return own
    said = set(of_sets) - {None}
    if len(said) > 1:
        raise DataError(f"{path}: feature {fid}: its point sets differ in {tag} ({', '.join(sorted(said))}); "
                        "export them as one set")
    return said.pop() if said else None


def _names(root) -> tuple[dict[str, str], dict[str, bool]]:
    """FeatureItem id -> FeatureName, and -> internal (through its nominal and definition, where given)."""
    by_id = {el.get("id"): el for el in root.iter() if el.get("id") is not None}
    names, internal = {}, {}
    items = root.find(f"{_q('Features')}/{_q('FeatureItems')}")
    for item in (items if items is not None else []):
        iid = item.get("id")
        names[iid] = _text(item, "FeatureName") or iid
        nominal = by_id.get(_text(item, "FeatureNominalId") or "")
        definition = by_id.get(_text(nominal, "FeatureDefinitionId") or "") if nominal is not None else None
        ie = (_text(definition, "InternalExternal") or "").upper() if definition is not None else ""
        if ie in ("INTERNAL", "EXTERNAL"):             # NOT_APPLICABLE says no more than an absent one
            internal[iid] = ie == "INTERNAL"
    return names, internal


def _bool(text: str | None, default: bool) -> bool:
    return default if text is None else text.lower() in ("true", "1")


def read_qif(path: str | Path, results: int | None = None) -> QifResults:
    """Every measured feature with points of one MeasurementResults (``results``, from 1; needed when the file
    holds several). DataError names the file and the element of every problem."""
    path = Path(path)
    root = _parse(path)
    _check_root(path, root)
    unit, scale = _unit(path, root)
    all_results = list(root.iter(_q("MeasurementResults")))
    if not all_results:
        raise DataError(f"{path}: no MeasurementsResults/MeasurementResultsSet/MeasurementResults: not a QIF "
                        "results file")
    if results is None and len(all_results) > 1:
        listing = ", ".join(f"{k + 1} (id {r.get('id')})" for k, r in enumerate(all_results))
        raise DataError(f"{path}: {len(all_results)} MeasurementResults: pick one with --results N: {listing}")
    k = results or 1
    if not 1 <= k <= len(all_results):
        raise DataError(f"{path}: --results {k}: the file holds {len(all_results)} MeasurementResults")
    chosen = all_results[k - 1]
    sets = _point_sets(path, root)
    names, internal = _names(root)
    out = QifResults(path, unit, k)
    measured = chosen.find(_q("MeasuredFeatures"))
    for fm in (measured if measured is not None else []):
        kind = _local(fm.tag).removesuffix("FeatureMeasurement")
        fid = fm.get("id", "")
        item = _text(fm, "FeatureItemId") or ""
        pts, labels, used = _feature_points(path, fm, fid, sets)
        radius = _of_sets(path, fid, "ProbeRadius", _text(fm, "ProbeRadius"), [s.probe_radius for s in used])
        diameter = _text(fm, "Diameter")
        out.features.append(QifFeature(
            names.get(item, fid), fid, kind, np.array(pts, dtype=float).reshape(-1, 3) * scale, labels,
            _bool(_of_sets(path, fid, "Compensated", _text(fm, "Compensated"), [s.compensated for s in used]),
                  True),
            _number(path, f"feature {fid} ProbeRadius", radius) * scale if radius else 0.0,
            _number(path, f"feature {fid} Diameter", diameter) * scale if diameter else None,
            internal.get(item)))
    return out


def fit_circle(points: np.ndarray) -> tuple[np.ndarray, float, np.ndarray]:
    """The circle through points (N, 3): centre, radius and the normal of its plane (least squares)."""
    from scipy.optimize import least_squares

    c0 = points.mean(axis=0)
    _, _, vt = np.linalg.svd(points - c0)
    e1, e2, n = vt
    xy = np.column_stack([(points - c0) @ e1, (points - c0) @ e2])
    A = np.column_stack([2 * xy, np.ones(len(xy))])           # algebraic fit, then geometric refinement
    sol = np.linalg.lstsq(A, (xy ** 2).sum(axis=1), rcond=None)[0]
    start = np.array([sol[0], sol[1], np.sqrt(max(sol[2] + sol[0] ** 2 + sol[1] ** 2, 0.0))])
    fit = least_squares(lambda v: np.hypot(xy[:, 0] - v[0], xy[:, 1] - v[1]) - v[2], start)
    a, b, r = fit.x
    return c0 + a * e1 + b * e2, float(abs(r)), n


def surface_points(feature: QifFeature, source: str = "") -> tuple[np.ndarray, str]:
    """The feature's points on the surface (mm) and a line saying what was done to them. Probe centres of a
    circle or cylinder move by the probe's radius along the fitted circle's radial direction in its plane:
    outward in a hole, inward on a boss."""
    p = feature.points_mm
    if feature.compensated:
        return p, f"feature {feature.name}: points as measured (compensated for the probe)"
    if feature.probe_radius_mm == 0.0:
        return p, f"feature {feature.name}: points as measured (not compensated, but no ProbeRadius to move them by)"
    where = f"{source}: feature {feature.name}"
    if feature.type not in CIRCULAR:
        raise DataError(f"{where}: probe-centre points (Compensated false) on a {feature.type} are not moved to "
                        "the surface; export compensated points")
    if feature.internal is None:
        raise DataError(f"{where}: probe-centre points (Compensated false), but the file does not say whether the "
                        "feature is INTERNAL or EXTERNAL (InternalExternal of its definition)")
    if len(p) < 3:
        raise DataError(f"{where}: {len(p)} point(s); a circle needs at least 3")
    c, _, n = fit_circle(p)
    radial = (p - c) - np.outer((p - c) @ n, n)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    sign = 1.0 if feature.internal else -1.0
    how = "outward (an internal feature)" if feature.internal else "inward (an external feature)"
    return (p + sign * feature.probe_radius_mm * radial,
            f"feature {feature.name}: probe centres moved {feature.probe_radius_mm:g} mm {how} to the surface")


def pick(qif: QifResults, name: str | None) -> QifFeature:
    """The feature named ``name`` (FeatureName or id), or the only one with points."""
    with_points = [f for f in qif.features if len(f.points_mm)]
    listing = ", ".join(f"{f.name} (id {f.id}, {len(f.points_mm)} points)" for f in qif.features) or "none"
    if name is None:
        if len(with_points) == 1:
            return with_points[0]
        if not with_points:
            raise DataError(f"{qif.path}: no measured points (PointList) in any measured feature: {listing}")
        raise DataError(f"{qif.path}: {len(with_points)} measured features with points: pick one with --feature "
                        f"NAME: {listing}")
    hits = [f for f in qif.features if name in (f.name, f.id)]
    if not hits:
        raise DataError(f"{qif.path}: --feature {name}: no measured feature of that name or id; the file has: "
                        f"{listing}")
    if not len(hits[0].points_mm):
        raise DataError(f"{qif.path}: feature {name}: no measured points (PointList) to read as a part")
    return hits[0]


def read_qif_part(path: str | Path, tool_radius_mm: float, frame: np.ndarray | None, feature: str | None = None,
                  results: int | None = None):
    """A QIF feature's surface points as a `PartMeasurement`, and a note on the probe compensation."""
    from .part_points import PartMeasurement

    qif = read_qif(path, results)
    f = pick(qif, feature)
    if len(f.points_mm) < 3:
        raise DataError(f"{qif.path}: feature {f.name}: {len(f.points_mm)} point(s); a contour needs at least 3")
    pts, note = surface_points(f, str(qif.path))
    part = PartMeasurement(str(qif.path), pts, f.labels, np.arange(1, len(pts) + 1), tool_radius_mm, frame,
                           f"QIF feature {f.name}")
    return part, note


def feature_rows(qif: QifResults) -> list[dict]:
    """One dict per measured feature, for `stiffcomp part features`."""
    rows = []
    for f in qif.features:
        row = {"name": f.name, "id": f.id, "type": f.type, "points": len(f.points_mm), "compensated": f.compensated,
               "units": qif.unit}
        if f.type in CIRCULAR:
            d = None
            if len(f.points_mm) >= 3:
                try:
                    d = 2.0 * fit_circle(surface_points(f, str(qif.path))[0])[1]
                except DataError:
                    d = None
            row.update(diameter_mm=d, reported_diameter_mm=f.reported_diameter_mm)
        rows.append(row)
    return rows
