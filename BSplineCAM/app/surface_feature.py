# SPDX-License-Identifier: LGPL-2.1-or-later
"""The parametric "B-spline surface" document object (Part::FeaturePython).

All state lives in properties (the net as a flat vector list with its row and column counts);
the proxy keeps nothing, so documents pickle as plain data and reopen identically in 0.20 and
1.0.  ``execute`` reads the properties, builds the core Surface, assigns the exact face.
"""

from __future__ import annotations

import os

import numpy as np

from ..core import Surface
from ..core.basis import KnotLayout
from .compat import ensure_freecad

FreeCAD = ensure_freecad()

OBJECT_VERSION = "1"
KNOT_LAYOUTS = [layout.value for layout in KnotLayout]


class SurfaceFeature:
    """Proxy of the B-spline surface object: properties in, exact Part shape out."""

    def __init__(self, obj):
        obj.Proxy = self
        self.ensure_properties(obj)

    @staticmethod
    def ensure_properties(obj) -> None:
        """Add any property missing (new objects, and documents from older versions)."""
        spec = [
            ("App::PropertyVectorList", "ControlPoints", "Control net", "Control points, row by row (rows follow u)"),
            ("App::PropertyInteger", "Rows", "Control net", "Number of control-point rows (u direction)"),
            ("App::PropertyInteger", "Columns", "Control net", "Number of control-point columns (w direction)"),
            ("App::PropertyEnumeration", "Knots", "Control net", "uniform: the paper's unclamped knots; clamped: the surface reaches the corner points"),
            ("App::PropertyBool", "MakeSolid", "Shape", "Close the surface down to a base plane (the model of a CAM job)"),
            ("App::PropertyDistance", "BaseOffset", "Shape", "Depth of the base plane below the surface's lowest point"),
            ("App::PropertyString", "CrossCheck", "Verification", "Deviation of OCCT's evaluation from the matrix form (JSON)"),
            ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM object"),
        ]
        for kind, name, group, tip in spec:
            if not hasattr(obj, name):
                obj.addProperty(kind, name, group, tip)
                if name == "Knots":
                    obj.Knots = KNOT_LAYOUTS
                elif name == "BaseOffset":
                    obj.BaseOffset = 5.0
        for name in ("Version", "CrossCheck"):
            obj.setEditorMode(name, 1)  # read-only
        obj.Version = OBJECT_VERSION

    def surface(self, obj) -> Surface:
        """The core Surface the properties describe (raises NetError on an invalid net)."""
        rows, cols = int(obj.Rows), int(obj.Columns)
        flat = np.array([tuple(v) for v in obj.ControlPoints], dtype=float).reshape(-1, 3)
        if rows * cols != len(flat):
            from ..core.errors import NetError

            raise NetError(f"{obj.Label}: Rows x Columns = {rows}x{cols} but {len(flat)} control points")
        return Surface(flat.reshape(rows, cols, 3), obj.Knots, obj.Label)

    def execute(self, obj) -> None:
        from . import part

        surface = self.surface(obj)
        if obj.MakeSolid:
            obj.Shape = part.to_solid(surface, margin=float(obj.BaseOffset))
        else:
            obj.Shape = part.to_face(surface)

    def onDocumentRestored(self, obj) -> None:  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)

    # proxies hold no state: both pickling protocols return None (0.20 and 1.0)
    def __getstate__(self):
        return None

    def __setstate__(self, state):
        return None

    def dumps(self):
        return None

    def loads(self, state):
        return None


def set_net(obj, surface: Surface) -> None:
    """Write a core Surface's net and knot layout into the object's properties."""
    rows, cols = surface.shape
    obj.Rows = rows
    obj.Columns = cols
    obj.ControlPoints = [FreeCAD.Vector(*map(float, p)) for p in surface.control_points.reshape(-1, 3)]
    obj.Knots = surface.knots.value


def make_surface(source, doc=None, name: str | None = None, knots: str | None = None, solid: bool = False):
    """Create a parametric B-spline surface object in ``doc`` (default: the active document).

    ``source`` is a control-net file (.json, .csv, .dat), a core Surface, or a (rows, cols, 3)
    array of control points.  Works headless; the view provider is attached when the GUI is up.
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
    SurfaceFeature(obj)
    obj.Label = name or surface.name
    set_net(obj, surface)
    obj.MakeSolid = bool(solid)
    if FreeCAD.GuiUp:
        from ..gui.surface_view import attach_view_provider

        attach_view_provider(obj)
    obj.recompute()
    return obj


def _object_name(label: str) -> str:
    clean = "".join(ch if ch.isalnum() else "_" for ch in label)
    return clean if clean and not clean[0].isdigit() else "BSplineSurface"
