# SPDX-License-Identifier: LGPL-2.1-or-later
"""The "B-spline surface rough" operation: Z-level roughing from the job's stock to the part
plus a stock to leave, with a flat or bull-nose end mill (issue 12).

A Path/CAM op like the finishing op (:mod:`finishing_op`, whose surface, faces and depths
handling it shares): ``opExecute`` reads the properties, calls the numeric core
(:func:`BSplineCAM.core.toolpath.roughing.generate_roughing`) with the part's exact heights
(the BSplineCAM surface, or every face of the job's model) and the job's stock (a block, or
CAM's cylinder stock as a cylinder), and turns the moves into Path commands.  The tool comes from the op's ToolController (flat, bull-nose or
ball ToolBit).
"""

from __future__ import annotations

import json

import numpy as np

from ..core.errors import ParameterError
from ..core.geometry.faces_height import FacesHeight
from ..core.geometry.footprint import surface_height
from ..core.simulation.simulate import Tool
from ..core.toolpath.arcs import feed_length, fit_arcs
from ..core.toolpath.common import RAPID_RANGE, CuttingParameters
from ..core.toolpath.roughing import (
    MAX_RAMP_ANGLE_DEG,
    RAMP_ANGLE_DEG,
    check_fine_stepdown,
    check_ramp_angle,
    generate_roughing,
)
from . import cam, compat
from .finishing_op import (
    FreeCAD,
    ObjectSurfaceFinish,
    OpError,
    find_surface_object,
    moves_to_commands,
    new_op,
    progress_reporter,
)
from .load_limits import LOAD_PROPERTIES
from .stock_left import job_stock

OBJECT_VERSION = "1"
#: Chordal tolerance (mm) of the helical arcs fitted to the entries: the roughing's own
#: polylines lie within 0.01 mm of their helices, far inside the stock to leave.
ARC_TOLERANCE = 0.02

#: (type, name, group, tooltip, flags, default) of the operation's own properties.
PROPERTIES = (
    ("App::PropertyLink", "Surface", "Surface",
     "BSplineCAM surface to rough (default: the job's model)", 0, None),
    ("App::PropertyLinkSubListGlobal", "Base", "Surface",
     "Unused by roughing (every face of the job's model bounds the tool); kept so faces "
     "chosen for finishing can be shared", 0, None),
    ("App::PropertyLength", "StepDown", "Roughing", "Depth of each Z level", 0, 2.0),
    ("App::PropertyLength", "FineStepDown", "Roughing",
     "Terraces no thicker than this: after each StepDown level, levels this far apart in the "
     "band above it, cut from the bottom up (0: off)", 0, 0.0),
    ("App::PropertyAngle", "RampAngle", "Roughing",
     f"Angle (degrees, above 0, at most {MAX_RAMP_ANGLE_DEG:g}) at which helical and ramped "
     "entries descend into the material", 0, RAMP_ANGLE_DEG),
    ("App::PropertyPercent", "StepOver", "Roughing",
     "Width of cut, percent of the tool diameter (the radial engagement never exceeds it)",
     0, 40),
    ("App::PropertyLength", "RadialAllowance", "Roughing",
     "Stock to leave on the part, sideways (mm)", 0, 0.3),
    ("App::PropertyLength", "AxialAllowance", "Roughing",
     "Stock to leave on the part, vertically (mm)", 0, 0.3),
    ("App::PropertyBool", "CentreCutting", "Roughing",
     "The end mill cuts at its centre: closed pockets too narrow for a helix are entered by a "
     "straight plunge (off: such a pocket is left, and named in the report)", 0, False),
    ("App::PropertyBool", "FlatLevels", "Roughing",
     "Extra levels at the part's flat areas, so the terraces left there stay thin", 0, True),
    ("App::PropertyLength", "Cell", "Roughing",
     "Grid spacing of the level computation (0: automatic, a tenth of the stepover)", 0, 0.0),
    ("App::PropertyString", "Report", "Roughing", "Statistics of the last computation (JSON)",
     0, None),
    ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM operation", 0, None),
    *LOAD_PROPERTIES,
)


class ObjectSurfaceRough(ObjectSurfaceFinish):
    """Z-level roughing of a BSplineCAM surface or a model's faces, from the job's stock."""

    properties = PROPERTIES
    version = OBJECT_VERSION

    def opOnDocumentRestored(self, obj):  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)
        job = self.job_of(obj)
        if job is not None:
            cam.use_surface_stock(job)
        if getattr(obj, "ToolController", None) is not None:
            compat.make_proxy_restorable(obj.ToolController)

    def uses_faces(self, obj) -> bool:
        """Roughing stays clear of every face of the model: faces unless a surface is given."""
        return obj.Surface is None and find_surface(self.job_of(obj)) is None

    def stock_block(self, obj):
        """The job's stock as core data (mm): a CylinderStock for CAM's cylinder stock (its
        axis along Z), so that the roughing cuts no air in the corners of its box, else the
        Stock block of its shape's box (:func:`.stock_left.job_stock`)."""
        job = self.job_of(obj)
        if job is None or getattr(job, "Stock", None) is None or job.Stock.Shape.isNull():
            raise OpError(f"{obj.Label}: the job has no stock to rough from")
        return job_stock(job)

    def height_function(self, obj):
        """height(xs, ys) -> (len(ys), len(xs)) top of the part (NaN off it), exact: the
        surface's footprint inversion, or the top-most face of the job's model."""
        if self.uses_faces(obj):
            faces = self.faces(obj)

            def height(xs, ys):
                cell = float(xs[1] - xs[0]) if len(xs) > 1 else 0.1
                return FacesHeight(faces, cell).grid(np.asarray(xs), np.asarray(ys)).z
            return height
        surface = self.surface(obj)

        def height(xs, ys):
            return surface_height(surface, np.asarray(xs)[None, :], np.asarray(ys)[:, None])[0]
        return height

    def tool_of(self, obj):
        """The ToolController's bit as a core Tool (flat, bull-nose or ball)."""
        shape, diameter, corner = compat.core_tool_shape(self.tool)
        return Tool(diameter, shape, corner if shape == "bullnose" else 0.0)

    def _execute(self, obj) -> None:
        tc = obj.ToolController.Label
        CuttingParameters.validate(
            self.horizFeed, self.vertFeed, float(obj.ToolController.SpindleSpeed), RAPID_RANGE[0],
            names=(f"{tc}: HorizFeed", f"{tc}: VertFeed", f"{tc}: SpindleSpeed", "rapid"))
        try:
            tool = self.tool_of(obj)
        except ValueError as exc:
            raise OpError(f"{obj.Label}: {exc}") from None
        edge = getattr(self.tool, "CuttingEdgeHeight", None)
        edge = float(getattr(edge, "Value", edge)) if edge is not None else None
        if edge is not None and edge > 0 and obj.StepDown.Value > edge:
            raise OpError(f"{obj.Label}: StepDown {obj.StepDown.Value:g} mm is deeper than "
                             f"the tool's cutting edge ({edge:g} mm, {tc})")
        try:
            fine = check_fine_stepdown(float(obj.FineStepDown.Value),
                                       "FineStepDown (at most StepDown)",
                                       float(obj.StepDown.Value))
            ramp = check_ramp_angle(float(obj.RampAngle.Value), "RampAngle")
        except ParameterError as exc:
            raise OpError(f"{obj.Label}: {exc}") from None
        stepover = 0.01 * int(obj.StepOver) * tool.diameter
        if not stepover > 0:
            raise OpError(f"{obj.Label}: StepOver must be above 0 % of the tool diameter")
        clearance = obj.ClearanceHeight.Value
        rough = generate_roughing(
            self.height_function(obj), self.stock_block(obj), tool, obj.StepDown.Value, stepover,
            radial_allowance=obj.RadialAllowance.Value,
            axial_allowance=obj.AxialAllowance.Value,
            cell=obj.Cell.Value or None, clearance_height=clearance,
            flat_levels=bool(obj.FlatLevels), fine_stepdown=fine, ramp_angle=ramp,
            centre_cutting=bool(getattr(obj, "CentreCutting", False)),
            progress=progress_reporter(obj))
        if not rough.moves:
            raise OpError(f"{obj.Label}: there is no stock to remove above the part")
        # helical entries become G17 helices; level contours stay lines (no surface to tell
        # their free side), see core.toolpath.arcs
        moves = fit_arcs(rough.moves, ARC_TOLERANCE)
        commands = moves_to_commands(moves, self.horizFeed, self.vertFeed,
                                     rough.clearance_height)
        self.commandlist.extend(commands)
        obj.Report = json.dumps(rough_report(rough, commands, moves, tool), sort_keys=True,
                                default=float)
        for note in rough.stats.get("notes", []):
            FreeCAD.Console.PrintWarning(f"{obj.Label}: {note}\n")


def rough_report(rough, commands, moves, tool) -> dict:
    """The op's statistics: the core's figures plus the program's moves and the feed length
    of the moves the commands are made of."""
    out = {k: v for k, v in rough.stats.items() if isinstance(v, (int, float, str, list))}
    out.update({
        "strategy": "roughing",
        "levels": [round(float(z), 6) for z in rough.levels],
        "ramp_angle_deg": float(rough.parameters["ramp_angle"]),
        # how the passes were entered: from the air, by helices, by ramps, or by a straight
        # descent on the floor already cut and a lead-in
        "entries": dict(rough.stats.get("entries", {})),
        "tool": {"shape": tool.shape.value, "diameter_mm": tool.diameter,
                 "corner_radius_mm": tool.corner_radius},
        "cutting_length_mm": round(feed_length(moves), 6),
        "program_moves": sum(c.Name in ("G0", "G1", "G2", "G3") for c in commands),
        "clearance_height_mm": rough.clearance_height,
    })
    return out


def find_surface(job):
    return find_surface_object(job)


def Create(name: str = "SurfaceRough", obj=None, parentJob=None):  # noqa: N802, N803 - FreeCAD factory convention
    """A new roughing op in ``parentJob`` (default: the active job), like CAM's ops' Create."""
    return new_op(ObjectSurfaceRough, "SurfaceRough", Create, name, obj, parentJob)
