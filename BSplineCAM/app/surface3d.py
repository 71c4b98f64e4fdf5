# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD's own 3D Surface op (OpenCAMLib drop-cutter) on a BSplineCAM job, for comparison.

:func:`add_freecad_surface_op` sets up 0.20's ``PathScripts.PathSurface`` (1.0's
``Path.Op.Surface``) so that it machines what the BSplineCAM raster op machines:

* the job's model, restricted to its top face (the B-spline surface) as Base geometry, so the
  side walls and the bottom are not cut;
* ``ScanType`` "Planar" (drop-cutter), ``LayerMode`` "Single-pass", ``CutPattern`` "ZigZag"
  (or "Line") with ``CutPatternAngle`` 0: passes along X, like the raster at angle 0;
* ``StepOver`` (a percentage of the tool diameter) giving the scallop height ``h`` on a flat:
  s = 2 sqrt(2Rh - h^2) (:func:`BSplineCAM.core.toolpath.common.flat_stepover`);
* ``SampleInterval`` by the raster's chordal rule: a cutter-location curve of radius >= R
  sampled every sqrt(8 R tol) mm sags at most tol between samples (capped at R/2), so both
  ops sample along a pass at the same density (FreeCAD's default is 1 mm);
* ``BoundaryEnforcement`` on and ``BoundaryAdjustment`` = R: PathSurface keeps the ball
  centre R inside the face's outline when enforcing, the adjustment pushes it back out to
  the outline (within LinearDeflection), where the BSplineCAM raster's ball centres end too;
* heights and depths from the job (its setup sheet's expressions), the job's tool controller.
"""

from __future__ import annotations

import math

from ..core.toolpath.common import check_positive, flat_stepover
from . import compat

FreeCAD = compat.ensure_freecad()

#: Cut patterns that raster along one direction, as the BSplineCAM raster does.
CUT_PATTERNS = ("ZigZag", "Line")


class OpenCAMLibMissing(RuntimeError):
    """FreeCAD's 3D Surface op cannot run: OpenCAMLib (``ocl``) is not importable."""


def stepover_percent(tool_diameter: float, scallop: float) -> float:
    """FreeCAD's StepOver (% of the tool diameter) leaving cusps of ``scallop`` mm on a flat."""
    check_positive(tool_diameter, "tool_diameter")
    check_positive(scallop, "scallop")
    if scallop >= tool_diameter / 2.0:
        raise ValueError(
            f"scallop must be < the tool radius {tool_diameter / 2:g} mm, got {scallop}"
        )
    return 100.0 * flat_stepover(tool_diameter / 2.0, scallop) / tool_diameter


def chordal_sample_interval(tool_diameter: float, tolerance: float) -> float:
    """Sampling step (mm) along a pass: sqrt(8 R tol), at most R/2 (the raster's rule)."""
    radius = check_positive(tool_diameter, "tool_diameter") / 2.0
    return min(math.sqrt(8.0 * radius * check_positive(tolerance, "tolerance")), radius / 2.0)


def top_face_name(model) -> str:
    """``FaceN`` of the model's B-spline face (else its highest face): the surface to machine."""
    faces = model.Shape.Faces
    if not faces:
        raise ValueError(f"{model.Label}: the model has no face")
    bspline = [i for i, f in enumerate(faces) if type(f.Surface).__name__ == "BSplineSurface"]
    index = bspline[0] if bspline else max(range(len(faces)), key=lambda i: faces[i].BoundBox.ZMax)
    return f"Face{index + 1}"


def job_tool_and_model(job, tool_diameter: float) -> tuple:
    """The job's first tool controller and model, checked: ValueError if either is missing or
    the tool's diameter is not ``tool_diameter`` (mm).  Makes the job's document the active one
    (CAM's op factories create in the active document)."""
    controllers = list(job.Tools.Group)
    if not controllers:
        raise ValueError(f"job {job.Label!r} has no tool controller")
    controller = controllers[0]
    if abs(float(controller.Tool.Diameter) - tool_diameter) > 1e-9:
        raise ValueError(
            f"tool_diameter {tool_diameter:g} mm differs from the job's tool "
            f"({float(controller.Tool.Diameter):g} mm)"
        )
    models = list(job.Model.Group)
    if not models:
        raise ValueError(f"job {job.Label!r} has no model")
    if FreeCAD.ActiveDocument is not job.Document:
        FreeCAD.setActiveDocument(job.Document.Name)
    return controller, models[0]


def add_freecad_surface_op(
    job,
    scallop: float,
    tool_diameter: float,
    *,
    tolerance: float = 0.002,
    sample_interval: float | None = None,
    pattern: str = "ZigZag",
    name: str = "Surface3D",
):
    """Add FreeCAD's 3D Surface op to ``job``, set up like the BSplineCAM raster (module doc).

    ``scallop`` and ``tolerance`` in mm fix StepOver and SampleInterval; ``sample_interval``
    (mm) overrides the latter.  ``tool_diameter`` (mm) must be the job's tool's.  Raises
    :class:`OpenCAMLibMissing` when OpenCAMLib is absent (it names the package to install) and
    ValueError on bad arguments.  The op is not recomputed.
    """
    if not compat.opencamlib_available():
        raise OpenCAMLibMissing(compat.opencamlib_missing_message())
    percent = stepover_percent(tool_diameter, scallop)
    if sample_interval is None:
        sample_interval = chordal_sample_interval(tool_diameter, tolerance)
    check_positive(sample_interval, "sample_interval")
    if pattern not in CUT_PATTERNS:
        raise ValueError(f"pattern must be one of {', '.join(CUT_PATTERNS)}, got {pattern!r}")
    controller, model = job_tool_and_model(job, tool_diameter)
    op = compat.cam_module("surface_op").Create(name, parentJob=job)
    op.ToolController = controller
    op.Base = [(model, [top_face_name(model)])]
    op.ScanType = "Planar"
    op.LayerMode = "Single-pass"
    op.CutPattern = pattern
    op.CutPatternAngle = 0.0
    op.BoundBox = "BaseBoundBox"
    op.BoundaryEnforcement = True
    op.BoundaryAdjustment = tool_diameter / 2.0
    op.StepOver = percent
    op.SampleInterval = sample_interval
    op.DepthOffset = 0.0
    return op
