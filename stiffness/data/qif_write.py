"""A measured circle written as a QIF 3 results file (ANSI/DMSC QIF 3.0, ISO 23952): what a CMM would hand
over, in the form `stiffness.data.qif_part` reads back (docs/part_format.md, "QIF").

The document holds what the QIF 3.0 schema asks of a results file, and no more:

- ``QPId``, derived from the rest of the document (a name-based UUID, RFC 4122 version 5, of its bytes), so
  the same cut gives the same file, byte for byte, and another cut another id; and ``FileUnits`` (linear
  unit mm);
- the feature's ``CircleFeatureDefinition`` (INTERNAL for a hole, EXTERNAL for a boss, the nominal diameter),
  ``CircleFeatureNominal`` (nominal centre and normal) and ``CircleFeatureItem`` (its ``FeatureName``);
- one ``MeasurementResults`` whose ``CircleFeatureMeasurement`` references its ``MeasuredPointSet`` as a
  whole (``WholePointSetId``), with the circle fitted to the points as the measured ``Location``, ``Normal``
  and ``Diameter``; the set's ``Points`` are x y z triples, ``Compensated`` true (the points lie on the
  surface, not at the probe's centre).

Coordinates are written in mm with 4 decimals (0.1 um), as the part CSV writes them, so the same cut read from
either file gives the same points.
"""

from __future__ import annotations

import uuid
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .qif_part import NS, fit_circle

QPID_NAMESPACE = uuid.uuid5(uuid.NAMESPACE_URL, NS)     # the QPIds this writer derives, under the QIF namespace


@dataclass
class NominalCircle:
    """The circle the feature should be (part frame, mm): centre, unit normal, diameter, hole or boss."""

    center_mm: np.ndarray
    normal: np.ndarray
    diameter_mm: float
    internal: bool


def _sub(parent, tag: str, text: str | None = None, **attrs) -> ET.Element:
    el = ET.SubElement(parent, f"{{{NS}}}{tag}", {k: str(v) for k, v in attrs.items()})
    if text is not None:
        el.text = text
    return el


def _xyz(v) -> str:
    return " ".join(f"{x:.4f}" for x in np.asarray(v, dtype=float))


def _unit(v) -> str:
    v = np.asarray(v, dtype=float)
    return " ".join(f"{x:.9f}" for x in v / np.linalg.norm(v))


def _features(root, name: str, nominal: NominalCircle) -> None:
    features = _sub(root, "Features")
    d = _sub(_sub(features, "FeatureDefinitions", n=1), "CircleFeatureDefinition", id=1)
    _sub(d, "InternalExternal", "INTERNAL" if nominal.internal else "EXTERNAL")
    _sub(d, "Diameter", f"{nominal.diameter_mm:.4f}")
    n = _sub(_sub(features, "FeatureNominals", n=1), "CircleFeatureNominal", id=2)
    _sub(n, "FeatureDefinitionId", "1")
    _sub(n, "Location", _xyz(nominal.center_mm))
    _sub(n, "Normal", _unit(nominal.normal))
    item = _sub(_sub(features, "FeatureItems", n=1), "CircleFeatureItem", id=3)
    _sub(item, "FeatureNominalId", "2")
    _sub(item, "FeatureName", name)
    _sub(_sub(_sub(_sub(item, "DeterminationMode"), "Checked"), "CheckDetails"), "Measured")


def write_qif_circle(path: str | Path, points_mm: np.ndarray, nominal: NominalCircle,
                     name: str = "CONTOUR") -> Path:
    """Write the points (N, 3; part frame, mm; on the surface) as the measured circle ``name``."""
    path = Path(path)
    pts = np.round(np.asarray(points_mm, dtype=float).reshape(-1, 3), 4)
    center, radius, normal = fit_circle(pts)
    if float(normal @ np.asarray(nominal.normal, dtype=float)) < 0.0:
        normal = -normal                                    # the fitted plane's normal, on the nominal's side
    ET.register_namespace("", NS)
    root = ET.Element(f"{{{NS}}}QIFDocument", {"versionQIF": "3.0.0", "idMax": "6"})
    lin = _sub(_sub(_sub(root, "FileUnits"), "PrimaryUnits"), "LinearUnit")
    _sub(lin, "SIUnitName", "meter")
    _sub(lin, "UnitName", "mm")
    _sub(_sub(lin, "UnitConversion"), "Factor", "0.001")
    _features(root, name, nominal)
    results = _sub(_sub(_sub(root, "Results"), "MeasurementResultsSet", n=1), "MeasurementResults", id=4)
    fm = _sub(_sub(results, "MeasuredFeatures", n=1), "CircleFeatureMeasurement", id=5)
    _sub(fm, "FeatureItemId", "3")
    _sub(_sub(fm, "PointList", n=1), "WholePointSetId", "6")
    _sub(fm, "Location", _xyz(center))
    _sub(fm, "Normal", _unit(normal))
    _sub(fm, "Diameter", f"{2.0 * radius:.4f}")
    ps = _sub(_sub(results, "MeasuredPointSets", n=1), "MeasuredPointSet", id=6, count=len(pts))
    _sub(ps, "Points", "\n" + "\n".join(_xyz(p) for p in pts) + "\n")
    _sub(ps, "Compensated", "true")
    _sub(_sub(results, "InspectionStatus"), "InspectionStatusEnum", "NOT_CALCULATED")
    qpid = ET.Element(f"{{{NS}}}QPId")
    qpid.text = str(uuid.uuid5(QPID_NAMESPACE, ET.tostring(root, encoding="unicode")))
    root.insert(0, qpid)                                    # the schema's first child of QIFDocument
    ET.indent(root)
    ET.ElementTree(root).write(path, xml_declaration=True, encoding="utf-8")
    return path
