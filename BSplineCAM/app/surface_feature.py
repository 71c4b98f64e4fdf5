# SPDX-License-Identifier: LGPL-2.1-or-later
"""The parametric "B-spline surface" document object (Part::FeaturePython).

All state lives in properties (the net as a flat vector list with its row and column counts);
the proxy keeps nothing, so documents pickle as plain data and reopen identically in 0.20 and
1.0.  ``execute`` reads the properties, builds the core Surface, assigns the exact face.
"""

from __future__ import annotations

import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from ..core import Surface
from ..core.errors import NetError
from ..core.geometry.basis import KnotLayout
from . import part
from .compat import ensure_freecad
from .crosscheck import crosscheck
from .proxy import StatelessProxy, add_missing_properties

FreeCAD = ensure_freecad()

#: Stored in the read-only ``Version`` property; bump it when properties change meaning.
OBJECT_VERSION = "1"
#: Marks our objects (Proxy.Type), so commands can recognise them without isinstance checks.
TYPE_NAME = "BSplineCAM::Surface"
KNOT_LAYOUTS = [layout.value for layout in KnotLayout]
#: Property type flags (App::PropertyType): ReadOnly in the editor, Output (no recompute).
PROP_READONLY = 1
PROP_OUTPUT = 8

#: (type, name, group, tooltip, flags, default) of every property the object carries.
PROPERTIES: tuple[tuple[str, str, str, str, int, object], ...] = (
    ("App::PropertyVectorList", "ControlPoints", "Control net",
     "Control points (mm), row by row (rows follow u)", 0, None),
    ("App::PropertyInteger", "Rows", "Control net",
     "Number of control-point rows (u direction)", 0, None),
    ("App::PropertyInteger", "Columns", "Control net",
     "Number of control-point columns (w direction)", 0, None),
    ("App::PropertyEnumeration", "Knots", "Control net",
     "uniform: the paper's unclamped knots; clamped: the surface reaches the corner points",
     0, KNOT_LAYOUTS),
    ("App::PropertyBool", "MakeSolid", "Shape",
     "Close the surface down to a base plane (the model of a CAM job)", 0, False),
    ("App::PropertyDistance", "BaseOffset", "Shape",
     "Depth of the base plane below the surface's lowest point (mm)", 0, 5.0),
    ("App::PropertyString", "CrossCheck", "Verification",
     "Deviation of OCCT's evaluation from the matrix form (JSON report)",
     PROP_READONLY | PROP_OUTPUT, ""),
    ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM object",
     PROP_READONLY | PROP_OUTPUT, None),
)


class SurfaceFeature(StatelessProxy):
    """Proxy of the B-spline surface object: properties in, exact Part shape out."""

    Type = TYPE_NAME

    def __init__(self, obj) -> None:
        obj.Proxy = self
        self.ensure_properties(obj)

    @staticmethod
    def ensure_properties(obj) -> None:
        """Add any property missing (new objects, and documents from older versions)."""
        add_missing_properties(obj, PROPERTIES)
        for name in ("Version", "CrossCheck"):
            obj.setEditorMode(name, 1)  # read-only in the property editor
        if obj.Version != OBJECT_VERSION:
            obj.Version = OBJECT_VERSION

    @staticmethod
    def surface(obj) -> Surface:
        """The core Surface the properties describe (raises NetError on an invalid net)."""
        return surface_of(obj)

    def execute(self, obj) -> None:
        """Read properties, evaluate by core, assign the exact shape (placement kept)."""
        surface = surface_of(obj)
        if obj.MakeSolid:
            shape = part.to_solid(surface, margin=float(obj.BaseOffset))
        else:
            shape = part.to_face(surface)
        shape.Placement = obj.Placement
        obj.Shape = shape

    def onDocumentRestored(self, obj) -> None:  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)


def is_surface(obj) -> bool:
    """True for a BSplineCAM surface object (cheap: used by commands' IsActive)."""
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TYPE_NAME


def surface_of(obj) -> Surface:
    """The core Surface of a surface object's properties (NetError names the object)."""
    rows, cols = int(obj.Rows), int(obj.Columns)
    flat = np.array([tuple(v) for v in obj.ControlPoints], dtype=float).reshape(-1, 3)
    if rows * cols != len(flat):
        raise NetError(
            f"{obj.Label}: Rows x Columns = {rows}x{cols} but {len(flat)} control points"
        )
    return Surface(flat.reshape(rows, cols, 3), obj.Knots, obj.Label)


def set_net(obj, surface: Surface) -> None:
    """Write a core Surface's net and knot layout into the object's properties."""
    rows, cols = surface.shape
    obj.Rows = rows
    obj.Columns = cols
    points = surface.control_points.reshape(-1, 3)
    obj.ControlPoints = [FreeCAD.Vector(*map(float, p)) for p in points]
    obj.Knots = surface.knots.value


def set_control_point(obj, row: int, col: int, point: Sequence[float]) -> None:
    """Move one control point (mm); the one-liner the net editor records in macros."""
    rows, cols = int(obj.Rows), int(obj.Columns)
    if not (0 <= row < rows and 0 <= col < cols):
        raise IndexError(f"{obj.Label}: control point [{row}][{col}] outside {rows}x{cols} net")
    points = list(obj.ControlPoints)
    points[row * cols + col] = FreeCAD.Vector(*map(float, point))
    obj.ControlPoints = points


def make_surface(
    source,
    doc=None,
    name: str | None = None,
    knots: str | None = None,
    solid: bool = False,
):
    """Create a parametric B-spline surface object in ``doc`` (default: the active document).

    ``source`` is a control-net file (.json, .csv, .dat), a core Surface, or a (rows, cols, 3)
    array of control points.  Works headless; the view provider is attached when the GUI is up.
    The file is read and validated before the document is touched, and the object is removed
    again if building it fails, so a bad input leaves the document as it was.
    """
    if isinstance(source, Surface):
        surface = source if knots is None else Surface(source.control_points, knots, source.name)
    elif isinstance(source, (str, os.PathLike)):
        surface = Surface.from_file(source, knots)
    else:
        surface = Surface(source, knots or "uniform", name or "surface")
    if doc is None:
        doc = FreeCAD.ActiveDocument or FreeCAD.newDocument()
    obj = doc.addObject("Part::FeaturePython", name or _object_name(surface.name))
    try:
        SurfaceFeature(obj)
        obj.Label = name or surface.name
        set_net(obj, surface)
        obj.MakeSolid = bool(solid)
        if FreeCAD.GuiUp:
            from ..gui.surface_view import attach_view_provider

            attach_view_provider(obj)
        obj.recompute()
        if not obj.isValid():
            raise NetError(f"{obj.Label}: the shape could not be built: {obj.getStatusString()}")
        obj.purgeTouched()  # the shape is current: a document recompute need not redo it
    except BaseException:
        doc.removeObject(obj.Name)
        raise
    return obj


def surfaces_in(objects: Iterable) -> list:
    """The BSplineCAM surface objects among ``objects``."""
    return [obj for obj in objects if is_surface(obj)]


def run_crosscheck(obj, **options) -> dict:
    """Cross-check a surface object against OCCT; store the report in ``obj.CrossCheck``.

    The report (max deviations in mm, see :func:`BSplineCAM.app.crosscheck.crosscheck`) is also
    printed to the report view, a warning when the exact route misses its tolerance.
    """
    report = crosscheck(surface_of(obj), **options)
    obj.CrossCheck = json.dumps(report, sort_keys=True)
    FreeCAD.Console.PrintMessage(format_crosscheck(obj.Label, report))
    if not report.get("exact_route_ok", False):
        FreeCAD.Console.PrintWarning(
            f"{obj.Label}: exact route outside tolerance or a backend was unavailable\n"
        )
    return report


def format_crosscheck(label: str, report: dict) -> str:
    """Human-readable lines of a cross-check report for the report view."""
    rows, cols = report["control_net"]
    head = (
        f"BSplineCAM cross-check of {label} ({rows}x{cols} net, {report['knots']} knots, "
        f"size {report['size_mm']:.3f} mm, {report['samples'][0]}^2 samples):"
    )
    lines = [head]
    for key, value in report["max_deviation_mm"].items():
        shown = "unavailable" if value is None else f"{value:.3e} mm"
        lines.append(f"  {key:<14} {shown}")
    paper = report.get("paper_route")
    if paper:
        lines.append(f"  paper route    {paper['max_deviation_mm']:.3e} mm "
                     f"(from {paper['points'][0]}x{paper['points'][1]} .dat points)")
    verdict = "OK" if report.get("exact_route_ok") else "NOT OK"
    lines.append(f"  exact route {verdict} (tolerance {report['tolerance_relative']:g} x size)")
    return "\n".join(lines) + "\n"


def _object_name(label: str) -> str:
    clean = "".join(ch if ch.isalnum() else "_" for ch in label)
    return clean if clean and not clean[0].isdigit() else "BSplineSurface"


def save_document(surface: Surface, path: str | os.PathLike, solid: bool = True) -> None:
    """A FreeCAD document holding the surface as a parametric object, saved atomically."""
    path = Path(path)
    doc = FreeCAD.newDocument(_unique_doc_name(path.stem))
    try:
        make_surface(surface, doc=doc, solid=solid)
        doc.recompute()
        tmp = path.with_name(f".{path.stem}.part.FCStd")
        doc.saveAs(str(tmp))
        os.replace(tmp, path)
    finally:
        FreeCAD.closeDocument(doc.Name)


def _unique_doc_name(stem: str) -> str:
    base = "".join(ch if ch.isalnum() else "_" for ch in stem) or "BSplineCAM"
    name, n = base, 1
    while name in FreeCAD.listDocuments():
        n += 1
        name = f"{base}{n}"
    return name
