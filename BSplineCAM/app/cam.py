# SPDX-License-Identifier: LGPL-2.1-or-later
"""A standard Path/CAM Job around a B-spline surface, its ball-end tool, and post-processing.

Job, ToolBit and ToolController are FreeCAD's own (through :mod:`compat`), so the job is one a
FreeCAD user can open, edit and post like any other.  Feeds and spindle speed are always set:
FreeCAD's default tool controller has zero feed, which a real controller refuses.
"""

from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from . import compat

FreeCAD = compat.ensure_freecad()


@dataclass(frozen=True)
class Cutting:
    """Feeds (mm/min) and spindle speed (rpm) of the ball-end tool controller."""

    horizontal_feed: float = 1200.0
    vertical_feed: float = 400.0
    spindle_speed: float = 12000.0
    rapid: float = 5000.0

    def validate(self) -> None:
        for name in ("horizontal_feed", "vertical_feed", "spindle_speed", "rapid"):
            value = getattr(self, name)
            if not value > 0:
                unit = "rpm" if name == "spindle_speed" else "mm/min"
                raise ValueError(f"{name.replace('_', ' ')} must be > 0 {unit}, got {value}")


def make_ballend_controller(diameter: float, cutting: Cutting = Cutting(), number: int = 1, doc=None):
    """A ToolController holding a ball-end ToolBit of ``diameter`` mm, feeds and speed set."""
    if not diameter > 0:
        raise ValueError(f"tool diameter must be > 0 mm, got {diameter}")
    cutting.validate()
    doc = doc or FreeCAD.ActiveDocument
    _activate(doc)
    bit = compat.make_ballend_bit(doc, diameter)
    tc = compat.cam_module("controller").Create(f"TC: Ball end {diameter:g} mm", bit, number)
    tc.HorizFeed = f"{cutting.horizontal_feed} mm/min"
    tc.VertFeed = f"{cutting.vertical_feed} mm/min"
    tc.HorizRapid = f"{cutting.rapid} mm/min"
    tc.VertRapid = f"{cutting.rapid} mm/min"
    tc.SpindleSpeed = float(cutting.spindle_speed)
    tc.SpindleDir = "Forward"
    tc.recompute()
    return tc


def make_job(model, tool_diameter: float, cutting: Cutting = Cutting(), name: str = "Job"):
    """A Job whose model is ``model`` (a solid B-spline surface object) and whose only tool
    controller is a ball end of ``tool_diameter`` mm with ``cutting`` feeds."""
    if model is None or not hasattr(model, "Shape") or model.Shape.isNull():
        raise ValueError("a job needs a model with a shape: create the B-spline surface first")
    doc = model.Document
    _activate(doc)
    job = compat.cam_module("job").Create(name, [model])
    tc = make_ballend_controller(tool_diameter, cutting, doc=doc)
    for old in list(job.Tools.Group):
        job.Tools.removeObject(old)
        for child in old.OutList:
            if child.isDerivedFrom("Part::FeaturePython") and not child.InList[1:]:
                _remove_tool_bit(doc, child)
        doc.removeObject(old.Name)
    job.Tools.addObject(tc)
    doc.recompute()
    return job


def _remove_tool_bit(doc, bit) -> None:
    """Remove a ToolBit and the body that draws it (``BitBody``: a PartDesign body with its
    sketch, revolution and origin, which FreeCAD 1.1 leaves behind when only the bit goes)."""
    body = getattr(bit, "BitBody", None)
    name = bit.Name
    if body is not None and body.Document is doc and not [o for o in body.InList if o is not bit]:
        bit.BitBody = None
        body.removeObjectsFromDocument()
        doc.removeObject(body.Name)
    if doc.getObject(name) is not None:
        doc.removeObject(name)


def post_objects(job) -> list:
    """Objects in posting order: per operation its tool controller (on change) and the op."""
    objects = []
    current = None
    for op in job.Operations.Group:
        if hasattr(op, "Active") and not op.Active:
            continue
        tc = getattr(op, "ToolController", None)
        if tc is not None and tc is not current:
            objects.append(tc)
            current = tc
        objects.append(op)
    return objects


def post_process(job, post: str = "linuxcnc", path: str | os.PathLike | None = None, header: bool = False) -> str:
    """G-code of ``job`` by FreeCAD's post-processor ``post`` (linuxcnc, grbl, fanuc, ...).

    The program is written to ``path`` only when complete (through a temporary file beside
    it).  Header and editor are off by default, for deterministic output.
    """
    objects = post_objects(job)
    if not objects:
        raise ValueError(f"job {job.Label!r} has no active operation to post")
    folder = Path(path).parent if path is not None else Path(tempfile.gettempdir())
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".post-", suffix=".ngc", dir=folder)
    os.close(fd)
    try:
        gcode = compat.post_export(post, objects, tmp, header)
        if not gcode.strip():
            raise RuntimeError(f"post-processor {post!r} produced no G-code")
        if not gcode.endswith("\n"):
            gcode += "\n"
        if path is not None:
            Path(tmp).write_text(gcode)
            os.replace(tmp, path)
        return gcode
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _activate(doc) -> None:
    """Path's factories create objects in the *active* document."""
    if FreeCAD.ActiveDocument is not doc:
        FreeCAD.setActiveDocument(doc.Name)
