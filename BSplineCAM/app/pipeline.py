# SPDX-License-Identifier: LGPL-2.1-or-later
"""Surface → Job → finishing op → post-processed program, headless, in one FreeCAD document.

What the ``toolpath`` command and the main job run; the GUI commands build the same objects
one by one.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass

from ..core import Surface
from ..core.toolpath.roughing import RAMP_ANGLE_DEG
from . import cam, compat, finishing_op, roughing_op
from .faces import read_part
from .surface_feature import make_surface

FreeCAD = compat.ensure_freecad()


@dataclass(frozen=True)
class FinishingParameters:
    """What the user chooses: tool (mm), scallop and tolerance (mm), angle (deg), strategy."""

    tool_diameter: float
    scallop: float
    tolerance: float = 0.002
    strategy: str = "raster"
    angle: float = 0.0
    direction: str = "zigzag"
    iso_direction: str = "u"
    arcs: bool = True  # fit passes with one-sided G2/G3 arcs (core.toolpath.arcs)
    rest_limit: float = 1.0  # after roughing: rest passes down to this above the part (mm)
    retract: str = "minimum"  # between passes: "minimum" (model and stock left) or "full"
    retract_margin: float = 1.0  # how far a minimum retract clears them (mm)
    start_stock: str = "job"  # the stock retracts clear: "job" or "model" (raised by:)
    stock_allowance: float = 1.0  # with "model": the stock's height above the model (mm)


@dataclass(frozen=True)
class RoughingParameters:
    """Roughing before the finish: the end mill (shape 'flat', 'bullnose' or 'ball',
    diameter and corner radius mm), step-down (mm), stepover (percent of the diameter), stock
    to leave (mm), the stock block's margin around the part (mm), flat-area levels and the
    fine step-down (mm, 0: off) of the terraces between levels, the entries' ramp angle
    (degrees), and whether the end mill cuts at its centre (closed pockets too narrow for a
    helix are then entered by a plunge)."""

    shape: str = "flat"
    diameter: float = 10.0
    corner_radius: float = 0.0
    stepdown: float = 2.0
    stepover_percent: int = 40
    radial_allowance: float = 0.3
    axial_allowance: float = 0.3
    stock_margin: float = 2.0
    flat_levels: bool = True
    fine_stepdown: float = 0.0
    ramp_angle: float = RAMP_ANGLE_DEG
    centre_cutting: bool = False


def build_job(surface: Surface, params: FinishingParameters, cutting: cam.Cutting, doc,
              post: str = cam.DEFAULT_POST, roughing: RoughingParameters | None = None):
    """The surface object (solid), a job with a ball-end tool controller and ``post`` as its
    PostProcessor, and the finishing op; with ``roughing``, first a roughing op with its own
    tool controller (T1, the ball becomes T2) from a stock block grown by its margin.
    Returns (model, job, op) with op the finishing op; ``job.Operations.Group`` holds both."""
    model = make_surface(surface, doc=doc, solid=True)
    doc.recompute()
    job = cam.make_job(model, params.tool_diameter, cutting, post=post)
    op = finishing_op.Create("SurfaceFinish", parentJob=job)
    if roughing is not None:
        add_roughing(job, roughing, cutting)
    op.Surface = model
    op.Strategy = params.strategy
    op.ScallopHeight = params.scallop
    op.Tolerance = params.tolerance
    op.Angle = params.angle
    op.Direction = params.direction
    op.IsoDirection = params.iso_direction
    op.Arcs = bool(params.arcs)
    op.RestLimit = params.rest_limit
    op.Retract = params.retract
    op.RetractMargin = params.retract_margin
    op.StartStock = params.start_stock
    op.StockAllowance = params.stock_allowance
    return model, job, op


def add_roughing(job, roughing: RoughingParameters, cutting: cam.Cutting):
    """The roughing op (first in the job) with its tool controller T1; the job's other
    controllers move up one number (the ball-end becomes T2) and the stock block grows by
    ``roughing.stock_margin`` on every side but the bottom.  Returns the op (not computed)."""
    # the op first: CAM's ops pick their controller when made, and a job's first op with
    # several controllers to choose from fails headless (FreeCAD 0.20-1.1 PathUtils)
    op = roughing_op.Create("SurfaceRough", parentJob=job)
    # inactive until it is set up, and the job's other ops with it: making the new
    # controller's tool bit recomputes the document (FreeCAD 0.20's ToolBit copies its
    # shape, headless too), which would otherwise rough the whole stock with the finishing
    # ball and the op's defaults, and compute the finishing ops once without the roughed
    # stock, all thrown away at the next recompute
    others = [o for o in job.Operations.Group if o is not op and getattr(o, "Active", False)]
    for other in (op, *others):
        other.Active = False
    try:
        _set_up_roughing(job, op, roughing, cutting)
    finally:
        for other in others:
            other.Active = True
    op.Active = True
    return op


def _set_up_roughing(job, op, roughing: RoughingParameters, cutting: cam.Cutting) -> None:
    """:func:`add_roughing`'s work on the new op ``op``, the job's ops inactive meanwhile."""
    for tc in job.Tools.Group:
        tc.ToolNumber = int(tc.ToolNumber) + 1
    tc = cam.add_controller(job, roughing.shape, roughing.diameter, roughing.corner_radius,
                            cutting, number=1)
    set_stock_margin(job, roughing.stock_margin)
    group = list(job.Operations.Group)
    if group and group[0] is not op:  # roughing goes first, before the finishing ops
        job.Operations.Group = [op, *(o for o in group if o is not op)]
    op.ToolController = tc
    for other in job.Operations.Group:  # the finishing ops start from the roughed stock
        if other is not op and hasattr(other, "RestFrom"):
            other.RestFrom = [*other.RestFrom, op]
    set_roughing(op, roughing)


#: The stock block's extensions beyond the part that the margin sets (not the bottom).
MARGIN_EXTENSIONS = ("ExtXneg", "ExtXpos", "ExtYneg", "ExtYpos", "ExtZpos")


def set_stock_margin(job, margin: float) -> None:
    """Grow the job's stock block by ``margin`` mm on every side but the bottom."""
    if not margin >= 0:
        raise ValueError(f"stock margin must be >= 0 mm, got {margin}")
    stock = job.Stock
    for name in MARGIN_EXTENSIONS:
        if hasattr(stock, name):
            setattr(stock, name, margin)
    if hasattr(stock, "ExtZneg"):
        stock.ExtZneg = 0.0


def stock_margin(job) -> float | None:
    """The margin :func:`set_stock_margin` gave, or None when the stock is not such a block."""
    stock = getattr(job, "Stock", None)
    values = {float(getattr(getattr(stock, n, None), "Value", getattr(stock, n, float("nan"))))
              for n in MARGIN_EXTENSIONS}
    return values.pop() if len(values) == 1 and all(v == v for v in values) else None


def set_roughing(op, roughing: RoughingParameters) -> None:
    """The roughing op's step-down, stepover, stock to leave, flat levels, fine step-down and
    ramp angle (not its tool)."""
    op.StepDown = roughing.stepdown
    op.FineStepDown = roughing.fine_stepdown
    op.StepOver = int(roughing.stepover_percent)
    op.RadialAllowance = roughing.radial_allowance
    op.AxialAllowance = roughing.axial_allowance
    op.FlatLevels = bool(roughing.flat_levels)
    op.RampAngle = roughing.ramp_angle
    op.CentreCutting = bool(roughing.centre_cutting)


def roughing_of(op) -> RoughingParameters:
    """The op's parameters as a :class:`RoughingParameters` (tool from its controller's bit,
    margin from its job's stock: the defaults where they cannot be read)."""
    shape, diameter, corner = compat.core_tool_shape(op.ToolController.Tool)
    job = op.Proxy.job_of(op)
    margin = stock_margin(job) if job is not None else None
    return RoughingParameters(
        shape=shape, diameter=float(diameter),
        corner_radius=float(corner) if shape == "bullnose" else 0.0,
        stepdown=float(op.StepDown.Value), stepover_percent=int(op.StepOver),
        radial_allowance=float(op.RadialAllowance.Value),
        axial_allowance=float(op.AxialAllowance.Value),
        stock_margin=RoughingParameters.stock_margin if margin is None else margin,
        flat_levels=bool(op.FlatLevels), fine_stepdown=float(op.FineStepDown.Value),
        ramp_angle=float(op.RampAngle.Value),
        centre_cutting=bool(getattr(op, "CentreCutting", False)))


def edit_roughing(op, roughing: RoughingParameters, cutting: cam.Cutting) -> None:
    """Change a roughing op in place: its parameters, its controller's feeds and speed and
    the stock margin (the tool itself is its controller's bit).  Not recomputed."""
    cutting.validate()
    job = op.Proxy.job_of(op)
    cam.set_cutting(op.ToolController, cutting)
    if job is not None:
        set_stock_margin(job, roughing.stock_margin)
    set_roughing(op, roughing)


def build_faces_job(model, params: FinishingParameters, cutting: cam.Cutting = cam.Cutting(),
                    faces=None, post: str = cam.DEFAULT_POST):
    """A job around ``model`` (any object with a Shape: Part, PartDesign, an imported STEP)
    with a ball-end tool controller and the finishing op on its faces.

    ``faces``: face names or numbers of ``model`` ("Face3" or 3) for the op's ``Base`` (on the
    job's model clone), or None for the default: every face a 3-axis tool reaches from above.
    Returns (job, op); the document is not recomputed.
    """
    job = cam.make_job(model, params.tool_diameter, cutting, post=post)
    op = finishing_op.Create("SurfaceFinish", parentJob=job)
    if faces is not None:
        names = [f if isinstance(f, str) else f"Face{int(f)}" for f in faces]
        op.Base = [(job.Model.Group[0], names)]
    for prop, value in (("Strategy", params.strategy), ("ScallopHeight", params.scallop),
                        ("Tolerance", params.tolerance), ("Angle", params.angle),
                        ("Direction", params.direction), ("IsoDirection", params.iso_direction),
                        ("Arcs", bool(params.arcs)), ("RestLimit", params.rest_limit),
                        ("Retract", params.retract), ("RetractMargin", params.retract_margin),
                        ("StartStock", params.start_stock),
                        ("StockAllowance", params.stock_allowance)):
        setattr(op, prop, value)
    return job, op


def machine(
    model: Surface | str | os.PathLike,
    params: FinishingParameters,
    gcode_path: str | os.PathLike,
    post: str = "linuxcnc",
    cutting: cam.Cutting = cam.Cutting(),
    document_path: str | os.PathLike | None = None,
    roughing: RoughingParameters | None = None,
    more_posts: dict | None = None,
    faces=None,
) -> dict:
    """Compute, post and write the program; return the op's report plus timings.

    ``model`` is a core Surface (a control net) or a part file (STEP, BREP, FCStd): on a
    part the finishing op takes its ``faces`` (numbers, or None for every face reached from
    above; a surface has no faces to choose), the roughing a block around the whole part.
    With ``roughing``, the job roughs first (T1) and finishes with the ball (T2); the
    roughing op's report is under ``roughing``, with its tool and stock box.
    The document is temporary and closed at the end (saved first to ``document_path`` if
    given).  ``more_posts`` ({post: path}) posts the same job by other post-processors too.
    Errors in the op (bad parameters, unreachable tolerance) raise ValueError.
    """
    if isinstance(model, (str, os.PathLike)):
        build = _part_builder(model, params, cutting, post, roughing, faces)
    else:
        if faces is not None:
            raise ValueError(f"faces {faces!r}: a surface has no faces to choose; "
                             "faces apply to part files")

        def build(doc):
            _, job, op = build_job(model, params, cutting, doc, post, roughing)
            return job, op

    return _machine(build, params, gcode_path, post, cutting, document_path, roughing,
                    more_posts)


def _part_builder(part_path, params: FinishingParameters, cutting: cam.Cutting, post: str,
                  roughing: RoughingParameters | None, faces):
    """``build(doc) -> (job, finishing op)`` for a part file, read once here so that an
    unreadable file fails before any document is made."""
    from pathlib import Path

    shape = read_part(str(part_path))

    def build(doc):
        model = doc.addObject("Part::Feature", "Part")
        model.Shape = shape
        model.Label = Path(part_path).stem
        doc.recompute()
        job, op = build_faces_job(model, params, cutting, faces, post)
        if roughing is not None:
            add_roughing(job, roughing, cutting)
        return job, op

    return build


def _machine(build, params, gcode_path, post, cutting, document_path, roughing,
             more_posts) -> dict:
    """The work of :func:`machine` on a surface or a part: a temporary document,
    ``build(doc) -> (job, finishing op)``, recompute, every op checked, posts, reports."""
    compat.post_module(post)  # an unknown post-processor fails before any work
    for other in more_posts or {}:
        compat.post_module(other)
    doc = FreeCAD.newDocument("BSplineCAMJob")
    try:
        started = time.perf_counter()
        job, op = build(doc)
        doc.recompute()
        reports = {}
        for each in job.Operations.Group:
            got = json.loads(getattr(each, "Report", "") or "{}")
            if "error" in got or not each.Path.Commands:
                raise ValueError(got.get("error") or f"{each.Label}: no toolpath was produced")
            reports[each.Name] = got
        report = reports[op.Name]
        if roughing is not None:
            rough_op = job.Operations.Group[0]
            report["roughing"] = reports[rough_op.Name]
            box = job.Stock.Shape.BoundBox
            report["stock_mm"] = [box.XMin, box.XMax, box.YMin, box.YMax, box.ZMin, box.ZMax]
            report["tools"] = {
                str(int(tc.ToolNumber)): dict(zip(("shape", "diameter_mm", "corner_radius_mm"),
                                                  compat.core_tool_shape(tc.Tool)))
                for tc in job.Tools.Group}
        compute_seconds = time.perf_counter() - started
        for other, path in (more_posts or {}).items():
            cam.post_process(job, other, path, remember=False)
        cam.post_process(job, post, gcode_path)
        if document_path is not None:
            doc.saveAs(str(document_path))
        report["post"] = post
        report["tool_diameter_mm"] = params.tool_diameter
        report["scallop_mm"] = params.scallop
        report["tolerance_mm"] = params.tolerance
        report["clearance_height_mm"] = op.ClearanceHeight.Value
        report["safe_height_mm"] = op.SafeHeight.Value
        report["feeds_mm_per_min"] = {"horizontal": cutting.horizontal_feed, "vertical": cutting.vertical_feed,
                                      "rapid": cutting.rapid}
        report["spindle_rpm"] = cutting.spindle_speed
        report["job_seconds"] = round(compute_seconds, 4)
        report["freecad"] = ".".join(map(str, compat.freecad_version()))
        return report
    finally:
        FreeCAD.closeDocument(doc.Name)
