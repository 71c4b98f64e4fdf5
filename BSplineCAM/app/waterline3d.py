# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD's own Waterline op (OpenCAMLib) on a BSplineCAM job, for comparison.

:func:`add_freecad_waterline_op` sets up 0.20's ``PathScripts.PathWaterline`` (1.0's and 1.1's
``Path.Op.Waterline``) so that it machines what the BSplineCAM waterline strategy machines:

* the given faces of the job's model as Base geometry: the op's FinalDepth follows their
  lowest point (``opUpdateDepths``), but with either algorithm 0.20's op then machines the whole
  model ("Face selection is unavailable", ``PathSurfaceSupport.ProcessSelectedFaces``);
* ``BoundBox`` "Stock": the drop-cutter scan covers that box only, so a contour round a wall
  on the model's outline needs the stock R wider than the model (:func:`widen_stock`);
* ``Algorithm`` "OCL Dropcutter" (a drop-cutter scan of the model's mesh on a grid
  SampleInterval apart, contoured at each level), ``LayerMode`` "Multi-pass",
  ``CutPattern`` and ``ClearLastLayer`` "None"/"Off" (contours only, no clearing of flats);
* ``StepDown`` (its setup sheet expression cleared) giving the scallop height ``h`` on a vertical wall, where the levels play the
  part of a raster's passes: s = 2 sqrt(2Rh - h^2)
  (:func:`BSplineCAM.core.toolpath.common.flat_stepover`); on gentler walls the same step
  down leaves larger scallops, as any constant step-down does;
* ``SampleInterval`` by the raster's chordal rule (:func:`.surface3d.chordal_sample_interval`),
  the grid of the scan both ways;
* heights and StartDepth from the job (its setup sheet's expressions), the job's tool
  controller.
"""

from __future__ import annotations

from ..core.toolpath.common import check_positive, flat_stepover
from . import compat
from .surface3d import OpenCAMLibMissing, chordal_sample_interval, job_tool_and_model

FreeCAD = compat.ensure_freecad()

def waterline_module():
    """The module of FreeCAD's Waterline op for the running FreeCAD."""
    return compat.cam_module("waterline_op")


def wall_stepdown(tool_diameter: float, scallop: float) -> float:
    """Step-down (mm) between levels that leaves cusps of ``scallop`` mm on a vertical wall."""
    radius = check_positive(tool_diameter, "tool_diameter") / 2.0
    if check_positive(scallop, "scallop") >= radius:
        raise ValueError(f"scallop must be < the tool radius {radius:g} mm, got {scallop}")
    return flat_stepover(radius, scallop)


def widen_stock(job, margin: float) -> None:
    """Make the job's stock-from-base reach at least ``margin`` mm beyond the model in X and Y
    (its ExtXneg, ExtXpos, ExtYneg, ExtYpos); other stocks are left as they are."""
    check_positive(margin, "margin")
    stock = job.Stock
    for name in ("ExtXneg", "ExtXpos", "ExtYneg", "ExtYpos"):
        if hasattr(stock, name) and getattr(stock, name).Value < margin:
            setattr(stock, name, margin)
    stock.recompute()


def add_freecad_waterline_op(
    job,
    faces: list[str],
    scallop: float,
    tool_diameter: float,
    *,
    tolerance: float = 0.002,
    sample_interval: float | None = None,
    name: str = "Waterline3D",
):
    """Add FreeCAD's Waterline op to ``job`` on ``faces`` ("FaceN" of the job's first model),
    set up as the module doc says.

    ``scallop`` (mm) fixes StepDown, ``tolerance`` (mm) SampleInterval; ``sample_interval``
    (mm) overrides the latter.  ``tool_diameter`` (mm) must be the job's tool's.  Raises
    :class:`OpenCAMLibMissing` when OpenCAMLib is absent and ValueError on bad arguments.  The
    op is not recomputed.
    """
    if not compat.opencamlib_available():
        raise OpenCAMLibMissing(compat.opencamlib_missing_message())
    stepdown = wall_stepdown(tool_diameter, scallop)
    if sample_interval is None:
        sample_interval = chordal_sample_interval(tool_diameter, tolerance)
    check_positive(sample_interval, "sample_interval")
    if not faces:
        raise ValueError("faces must name at least one face of the job's model")
    controller, model = job_tool_and_model(job, tool_diameter)
    op = waterline_module().Create(name, parentJob=job)
    op.ToolController = controller
    op.Base = [(model, list(faces))]
    op.Algorithm = "OCL Dropcutter"
    op.BoundBox = "Stock"
    op.LayerMode = "Multi-pass"
    op.CutPattern = "None"
    op.ClearLastLayer = "Off"
    op.setExpression("StepDown", None)
    op.StepDown = stepdown
    op.SampleInterval = sample_interval
    op.DepthOffset = 0.0
    return op
