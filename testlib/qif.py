"""A small writer of QIF 3 results files for the tests, built with xml.etree after the standard's structure:
units, a feature's definition (internal or external), nominal and item (its name), and a MeasurementResults
whose measured feature references a measured point set as a whole or as a range. And the QIF 3.0 schema
(tests/data/qif3) to validate a file against."""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

NS = "http://qifstandards.org/xsd/qif3"
QIF3_XSD = Path(__file__).resolve().parents[1] / "tests" / "data" / "qif3" / "QIFApplications" / "QIFDocument.xsd"


@functools.cache
def qif3_schema():
    """The QIF 3.0 schema, loaded once (a few seconds). xmlschema ties an identity constraint whose selector
    ends in a wildcard (``t:Features/t:FeatureItems/t:*``) to the head of the substitution group there (the
    abstract FeatureItem) but not to its members (CircleFeatureItem, ...), so it would collect no key from
    them and refuse every valid reference to one; each member is given its head's constraints, as the schema
    means (libxml2 validates the same files as valid)."""
    import xmlschema

    schema = xmlschema.XMLSchema(QIF3_XSD)
    for head in schema.maps.elements.values():
        for member in head.iter_substitutes():
            member.selected_by.update(head.selected_by)
    return schema


def _sub(parent, tag, text=None, **attrs):
    el = ET.SubElement(parent, f"{{{NS}}}{tag}", {k: str(v) for k, v in attrs.items()})
    if text is not None:
        el.text = str(text)
    return el


OTHER_FORMS = ("unresolved", "no points", "point/xyz", "binary", "compensations", "coordinate system")


def _other(features, fs, pss, k: int, name: str, form: str, points) -> None:
    """Another measured feature ``name`` (a circle) whose point set is in ``form`` (OTHER_FORMS): its item in
    ``features``, its measurement in ``fs`` (MeasuredFeatures), its set in ``pss`` (MeasuredPointSets)."""
    iid, fid, sid = 50 + k, 60 + k, 70 + k
    item = _sub(features.find(f"{{{NS}}}FeatureItems"), "CircleFeatureItem", id=iid)
    _sub(item, "FeatureName", name)
    _sub(item, "FeatureNominalId", 2)
    fm = _sub(fs, "CircleFeatureMeasurement", id=fid)
    _sub(fm, "FeatureItemId", iid)
    _sub(_sub(fm, "PointList"), "WholePointSetId", 99 if form == "unresolved" else sid)
    ps = _sub(pss, "MeasuredPointSet", id=sid)
    if form == "point/xyz":                       # Point/XYZ directly under the set, no Points
        for p in np.asarray(points, dtype=float):
            _sub(_sub(ps, "Point"), "XYZ", " ".join(f"{v:.10g}" for v in p))
    elif form == "binary":
        _sub(ps, "BinaryPoints", "AAAA")
    elif form in ("compensations", "coordinate system"):
        _sub(ps, "Points", " ".join(f"{v:.10g}" for v in np.asarray(points, dtype=float).ravel()))
    if form == "coordinate system":
        ps.insert(0, ET.Element(f"{{{NS}}}CoordinateSystemId"))
        ps[0].text = "3"
    if form == "compensations":
        _sub(ps, "Compensations", " ".join(["true"] * len(points)))
    else:
        _sub(ps, "Compensated", "true")


def write_qif(path, points, *, name="HOLE", kind="Circle", unit="mm", compensated=True, probe_radius=None,
              diameter=None, internal=True, version="3.0.0", results=1, point_set_ref="20", point_range=None,
              binary=False, flat=False, count=None, others=()) -> Path:
    """Write ``points`` (N, 3, in ``unit``) as the measured feature ``name`` of ``results`` MeasurementResults.
    ``flat``: as the QIF 3.0 schema has a measured point set, its ``Points`` one list of x y z triples (of
    ``count`` points, default N) and ``Compensated`` and ``ProbeRadius`` on the set, not on the feature;
    ``internal`` None writes InternalExternal NOT_APPLICABLE. ``others``: (name, form) of more circles in the
    first MeasurementResults, each with the same points in one of OTHER_FORMS."""
    ET.register_namespace("", NS)
    root = ET.Element(f"{{{NS}}}QIFDocument", {"versionQIF": version, "idMax": "99"})
    lin = _sub(_sub(_sub(root, "FileUnits"), "PrimaryUnits"), "LinearUnit")
    _sub(lin, "SIUnitName", "meter")
    _sub(lin, "UnitName", unit)
    features = _sub(root, "Features")
    d = _sub(_sub(features, "FeatureDefinitions", n=1), f"{kind}FeatureDefinition", id=1)
    _sub(d, "InternalExternal", "NOT_APPLICABLE" if internal is None else "INTERNAL" if internal else "EXTERNAL")
    _sub(_sub(_sub(features, "FeatureNominals", n=1), f"{kind}FeatureNominal", id=2), "FeatureDefinitionId", 1)
    item = _sub(_sub(features, "FeatureItems", n=1), f"{kind}FeatureItem", id=3)
    _sub(item, "FeatureName", name)
    _sub(item, "FeatureNominalId", 2)
    rs = _sub(_sub(root, "Results"), "MeasurementResultsSet", n=results)
    for r in range(results):
        mr = _sub(rs, "MeasurementResults", id=10 + 20 * r)
        fs = _sub(mr, "MeasuredFeatures", n=1)
        fm = _sub(fs, f"{kind}FeatureMeasurement", id=11 + 20 * r)
        _sub(fm, "FeatureItemId", 3)
        if diameter is not None:
            _sub(fm, "Diameter", f"{diameter:.9g}")
        pl = _sub(fm, "PointList")
        if point_set_ref is not None:
            if point_range is None:
                _sub(pl, "WholePointSetId", point_set_ref)
            elif point_range[0] == point_range[1]:
                _sub(pl, "SinglePointSetId", point_set_ref, index=point_range[0])
            else:
                _sub(pl, "RangePointSetId", point_set_ref, range=f"{point_range[0]} {point_range[1]}")
        where = fm
        pss = _sub(mr, "MeasuredPointSets", n=1)
        ps = _sub(pss, "MeasuredPointSet", id=20 + 20 * r)
        for k, (other, form) in enumerate(others if r == 0 else ()):
            _other(features, fs, pss, k, other, form, points)
        if flat:
            ps.set("count", str(len(points) if count is None else count))
            _sub(ps, "Points", " ".join(f"{v:.10g}" for v in np.asarray(points, dtype=float).ravel()))
            where = ps
        _sub(where, "Compensated", "true" if compensated else "false")
        if probe_radius is not None:
            _sub(where, "ProbeRadius", f"{probe_radius:.9g}")
        if flat:
            continue
        if binary:
            _sub(ps, "CombinedPointsBinary", "AAAA")
            continue
        pts = _sub(ps, "Points", n=len(points))
        for p in np.asarray(points, dtype=float):
            _sub(_sub(pts, "Point"), "XYZ", " ".join(f"{v:.10g}" for v in p))
    ET.ElementTree(root).write(path, xml_declaration=True, encoding="utf-8")
    return Path(path)
