"""A CMM's QIF 3 results file (ANSI/DMSC QIF 3.0, ISO 23952) read as a part (docs/part_format.md, "QIF").

QIF results hold every measured feature of one or more parts: its points (a measured point set, referenced as
a whole or as a range), whether they are compensated for the probe's radius, and the file's units. What QIF
does not carry, the cutter's radius and the part frame, comes from the caller (`read_qif_part`).

A feature whose points cannot be read (`stiffness.data.qif_points`: a reference that does not resolve, a set
without points, a form not read) is left out, named with the reason (`QifLeftOut`); the file's other
features still read. What concerns the whole file (not XML, not QIF 3 results, an unknown unit) is refused.

The XML is parsed by defusedxml with DTDs forbidden: a document type declaration, an entity (a "billion
laughs" bomb) or an external reference is refused before anything is expanded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ..errors import DataError
from .qif_points import NS, Unreadable, feature_points, number, of_sets, point_sets
from .qif_points import local as _local
from .qif_points import q as _q
from .qif_points import text as _text

UNITS_MM = {"mm": 1.0, "millimeter": 1.0, "millimetre": 1.0, "inch": 25.4, "in": 25.4, "m": 1000.0,
            "meter": 1000.0, "metre": 1000.0}
CIRCULAR = ("Circle", "Cylinder")
RESULTS_PATH = "Results/MeasurementResultsSet/MeasurementResults"     # QIFResults.xsd: QIFDocument/Results


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


@dataclass(frozen=True)
class QifLeftOut:
    """A measured feature whose points cannot be read: its name, id and type, and why (naming the element as
    the file has it)."""

    name: str
    id: str
    type: str
    reason: str

    def describe(self) -> str:
        return f"feature {self.name} (id {self.id}, {self.type}) left out: {self.reason}"

    def text(self, source: str) -> str:
        return f"{source}: {self.describe()}"

    def to_dict(self, source: str | None = None) -> dict:
        out = {"name": self.name, "id": self.id, "type": self.type, "reason": self.reason}
        return out if source is None else {"part": source, **out}


@dataclass
class QifResults:
    path: Path
    unit: str
    results: int                        # which MeasurementResults (from 1)
    features: list[QifFeature] = field(default_factory=list)       # every measured feature whose points read
    left_out: list[QifLeftOut] = field(default_factory=list)       # every one whose points do not, and why


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


def _feature(fm, kind: str, fid: str, name: str, sets, scale: float, internal: bool | None) -> QifFeature:
    """One feature measurement with its points; Unreadable when they cannot be read."""
    pts, labels, used = feature_points(fm, sets)
    radius = of_sets("ProbeRadius", _text(fm, "ProbeRadius"), [s.probe_radius for s in used])
    compensated = of_sets("Compensated", _text(fm, "Compensated"), [s.compensated for s in used])
    diameter = _text(fm, "Diameter")
    return QifFeature(name, fid, kind, np.array(pts, dtype=float).reshape(-1, 3) * scale, labels,
                      _bool(compensated, True), number("ProbeRadius", radius) * scale if radius else 0.0,
                      number("Diameter", diameter) * scale if diameter else None, internal)


def read_qif(path: str | Path, results: int | None = None) -> QifResults:
    """Every measured feature of one MeasurementResults (``results``, from 1; needed when the file holds several),
    and those left out because their points cannot be read. DataError names the file and the element of every
    problem of the file as a whole."""
    path = Path(path)
    root = _parse(path)
    _check_root(path, root)
    unit, scale = _unit(path, root)
    all_results = root.findall("/".join(_q(t) for t in RESULTS_PATH.split("/")))
    if not all_results:
        raise DataError(f"{path}: no {RESULTS_PATH}: not a QIF results file")
    if results is None and len(all_results) > 1:
        listing = ", ".join(f"{k + 1} (id {r.get('id')})" for k, r in enumerate(all_results))
        raise DataError(f"{path}: {len(all_results)} MeasurementResults: pick one with --results N: {listing}")
    k = results or 1
    if not 1 <= k <= len(all_results):
        raise DataError(f"{path}: --results {k}: the file holds {len(all_results)} MeasurementResults")
    sets = point_sets(root)
    names, internal = _names(root)
    out = QifResults(path, unit, k)
    measured = all_results[k - 1].find(_q("MeasuredFeatures"))
    for fm in (measured if measured is not None else []):
        kind = _local(fm.tag).removesuffix("FeatureMeasurement")
        fid = fm.get("id", "")
        item = _text(fm, "FeatureItemId") or ""
        try:
            out.features.append(_feature(fm, kind, fid, names.get(item, fid), sets, scale, internal.get(item)))
        except Unreadable as e:
            out.left_out.append(QifLeftOut(names.get(item, fid), fid, kind, str(e)))
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
    if len(p) < 3:
        raise DataError(f"{where}: {len(p)} point(s); a circle needs at least 3")
    c, rc, n = fit_circle(p)
    internal, decided = feature.internal, ""
    if internal is None:
        internal = side_by_diameter(rc, feature.probe_radius_mm, feature.reported_diameter_mm)
        if internal is None:
            raise DataError(f"{where}: probe-centre points (Compensated false), but the file says neither whether "
                            "the feature is INTERNAL or EXTERNAL (InternalExternal of its definition) nor a Diameter "
                            "that tells: the points are not moved to the surface")
        decided = (f"; the file does not say INTERNAL or EXTERNAL, its reported diameter "
                   f"{feature.reported_diameter_mm:.4f} mm does")
    radial = (p - c) - np.outer((p - c) @ n, n)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    sign = 1.0 if internal else -1.0
    how = "outward (an internal feature)" if internal else "inward (an external feature)"
    return (p + sign * feature.probe_radius_mm * radial,
            f"feature {feature.name}: probe centres moved {feature.probe_radius_mm:g} mm {how} to the surface{decided}")


def side_by_diameter(centres_radius_mm: float, probe_radius_mm: float, reported_mm: float | None) -> bool | None:
    """Whether a circle of probe centres of radius ``centres_radius_mm`` is a hole (True) or a boss (False) by the
    diameter the CMM reported for its surface: a hole's surface lies the probe's radius outside its centres, a
    boss's inside, so the two readings differ by the probe's diameter. None when no diameter is reported, or it
    lies nearer neither reading by more than half the probe's radius."""
    if reported_mm is None or probe_radius_mm <= 0:
        return None
    hole = abs(reported_mm / 2 - (centres_radius_mm + probe_radius_mm))
    boss = abs(reported_mm / 2 - (centres_radius_mm - probe_radius_mm))
    if min(hole, boss) > probe_radius_mm / 2:
        return None
    return hole < boss


def pick(qif: QifResults, name: str | None) -> QifFeature:
    """The feature named ``name`` (FeatureName or id), or the only one with points. A feature left out is
    refused with its reason when named, and named when nothing else has points."""
    with_points = [f for f in qif.features if len(f.points_mm)]
    listing = ", ".join([f"{f.name} (id {f.id}, {len(f.points_mm)} points)" for f in qif.features]
                        + [f"{x.name} (id {x.id}, left out)" for x in qif.left_out]) or "none"
    if name is None:
        if len(with_points) == 1:
            return with_points[0]
        if not with_points:
            why = "".join(f"; {x.describe()}" for x in qif.left_out)
            that_reads = " that reads" if qif.left_out else ""
            raise DataError(f"{qif.path}: no measured points (PointList) in any measured feature{that_reads}: "
                            f"{listing}{why}")
        raise DataError(f"{qif.path}: {len(with_points)} measured features with points: pick one with --feature "
                        f"NAME: {listing}")
    hits = [f for f in qif.features if name in (f.name, f.id)]
    if not hits:
        left = [x for x in qif.left_out if name in (x.name, x.id)]
        if left:
            raise DataError(f"{qif.path}: --feature {name}: {left[0].describe()}")
        raise DataError(f"{qif.path}: --feature {name}: no measured feature of that name or id; the file has: "
                        f"{listing}")
    if not len(hits[0].points_mm):
        raise DataError(f"{qif.path}: feature {name}: no measured points (PointList) to read as a part")
    return hits[0]


class QifPart(NamedTuple):
    """A QIF feature read as a part: the points, a line on the probe compensation, and the file's features left
    out (their points cannot be read)."""

    part: object                        # stiffness.data.part_points.PartMeasurement
    note: str
    left_out: list[QifLeftOut]


def read_qif_part(path: str | Path, tool_radius_mm: float, frame: np.ndarray | None, feature: str | None = None,
                  results: int | None = None) -> QifPart:
    """A QIF feature's surface points as a `PartMeasurement`, a note on the probe compensation, and the features
    left out."""
    from .part_points import PartMeasurement

    qif = read_qif(path, results)
    f = pick(qif, feature)
    if len(f.points_mm) < 3:
        raise DataError(f"{qif.path}: feature {f.name}: {len(f.points_mm)} point(s); a contour needs at least 3")
    pts, note = surface_points(f, str(qif.path))
    part = PartMeasurement(str(qif.path), pts, f.labels, np.arange(1, len(pts) + 1), tool_radius_mm, frame,
                           f"QIF feature {f.name}")
    return QifPart(part, note, list(qif.left_out))


def feature_rows(qif: QifResults) -> list[dict]:
    """One dict per measured feature, for `stiffcomp part features`."""
    rows = []
    for f in qif.features:
        row = {"name": f.name, "id": f.id, "type": f.type, "points": len(f.points_mm), "compensated": f.compensated,
               "units": qif.unit}
        if f.type in CIRCULAR:
            d, note = None, None
            if len(f.points_mm) >= 3:
                try:
                    d = 2.0 * fit_circle(surface_points(f, str(qif.path))[0])[1]
                except DataError as e:
                    note = str(e).split(": ", 2)[-1]          # why there is no diameter, without the file's name
            else:
                note = f"{len(f.points_mm)} point(s); a circle needs at least 3"
            row.update(diameter_mm=d, reported_diameter_mm=f.reported_diameter_mm)
            if note:
                row["note"] = note
        rows.append(row)
    return rows
