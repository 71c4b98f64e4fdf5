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
from . import cam, compat

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


def build_job(surface: Surface, params: FinishingParameters, cutting: cam.Cutting, doc,
              post: str = cam.DEFAULT_POST):
    """The surface object (solid), a job with a ball-end tool controller and ``post`` as its
    PostProcessor, and the finishing op."""
    from .finishing_op import Create
    from .surface_feature import make_surface

    model = make_surface(surface, doc=doc, solid=True)
    doc.recompute()
    job = cam.make_job(model, params.tool_diameter, cutting, post=post)
    op = Create("SurfaceFinish", parentJob=job)
    op.Surface = model
    op.Strategy = params.strategy
    op.ScallopHeight = params.scallop
    op.Tolerance = params.tolerance
    op.Angle = params.angle
    op.Direction = params.direction
    op.IsoDirection = params.iso_direction
    op.Arcs = bool(params.arcs)
    return model, job, op


def build_faces_job(model, params: FinishingParameters, cutting: cam.Cutting = cam.Cutting(),
                    faces=None, post: str = cam.DEFAULT_POST):
    """A job around ``model`` (any object with a Shape: Part, PartDesign, an imported STEP)
    with a ball-end tool controller and the finishing op on its faces.

    ``faces``: face names or numbers of ``model`` ("Face3" or 3) for the op's ``Base`` (on the
    job's model clone), or None for the default: every face a 3-axis tool reaches from above.
    Returns (job, op); the document is not recomputed.
    """
    from .finishing_op import Create

    job = cam.make_job(model, params.tool_diameter, cutting, post=post)
    op = Create("SurfaceFinish", parentJob=job)
    if faces is not None:
        names = [f if isinstance(f, str) else f"Face{int(f)}" for f in faces]
        op.Base = [(job.Model.Group[0], names)]
    for prop, value in (("Strategy", params.strategy), ("ScallopHeight", params.scallop),
                        ("Tolerance", params.tolerance), ("Angle", params.angle),
                        ("Direction", params.direction), ("IsoDirection", params.iso_direction),
                        ("Arcs", bool(params.arcs))):
        setattr(op, prop, value)
    return job, op


def machine(
    surface: Surface,
    params: FinishingParameters,
    gcode_path: str | os.PathLike,
    post: str = "linuxcnc",
    cutting: cam.Cutting = cam.Cutting(),
    document_path: str | os.PathLike | None = None,
) -> dict:
    """Compute, post and write the program; return the op's report plus timings.

    The document is temporary and closed at the end (saved first to ``document_path`` if
    given).  Errors in the op (bad parameters, unreachable tolerance) raise ValueError.
    """
    compat.post_module(post)  # an unknown post-processor fails before any work
    doc = FreeCAD.newDocument("BSplineCAMJob")
    try:
        started = time.perf_counter()
        _, job, op = build_job(surface, params, cutting, doc, post)
        doc.recompute()
        report = json.loads(op.Report or "{}")
        if "error" in report or not op.Path.Commands:
            raise ValueError(report.get("error") or f"{op.Label}: no toolpath was produced")
        compute_seconds = time.perf_counter() - started
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
