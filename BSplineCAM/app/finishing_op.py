# SPDX-License-Identifier: LGPL-2.1-or-later
"""The "B-spline surface finish" operation: a Path/CAM op computed on the exact surface.

A subclass of FreeCAD's own ObjectOp (0.20 ``PathScripts.PathOp``, 1.0 ``Path.Op.Base``), so it
lives in a standard Job, takes its tool from a ToolController and its heights from the job's
setup sheet.  ``opExecute`` reads the properties, calls the numeric core
(:func:`BSplineCAM.core.toolpath.generate`) and turns the plain moves into Path commands.

Faces, like CAM's own ops (issue 11): ``Base`` = [(object, ["Face3", "Face8"])] from any
object with a Shape (Part, PartDesign, an imported STEP, the job's model clone), or, when
``Base`` is empty and the job's model is no BSplineCAM surface, every face of the job's models
a 3-axis tool reaches from above ("up").  The faces become core faces
(:mod:`BSplineCAM.app.faces`) and are machined by the certified drop-cutter over a
:class:`~BSplineCAM.core.toolpath.faceset.FaceSet` in which every other face of the job's
models is a check surface, never cut (:func:`job_faces`).

Linking: passes close together are joined by stay-down feeds; between the others the tool
climbs to the clearance height (``Retract`` full) or only as high as the model and the stock
the earlier ops left need (``Retract`` minimum, :mod:`BSplineCAM.app.retract`; or the model
raised by ``StockAllowance`` with ``StartStock`` model).  A rapid descends only to the safe
height (above the stock) or, with minimum retracts, to the margin over the stock around the
pass it enters; the rest of the approach is a feed at the vertical feed rate.
"""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np

from ..core import Surface
from ..core import toolpath as core_toolpath
from ..core.errors import BSplineCAMError
from ..core.geometry import faces as core_faces
from ..core.geometry.face_import import DEFAULT_CHORDAL_TOLERANCE
from ..core.geometry.faces import FaceError
from ..core.program.gcode import read_gcode
from ..core.simulation.machining_time import DEFAULT_RAPID_RATE, MachineLimits
from ..core.simulation.measures import program_measures, toolpath_lengths
from ..core.toolpath import common as toolpath_common
from ..core.toolpath import retracts
from ..core.toolpath.arcs import feed_length
from ..core.toolpath.arcs_moves import plain_gcode
from ..core.toolpath.common import RAPID_RANGE, CuttingParameters, ToolParameters
from ..core.toolpath.faceset import FaceSet
from ..core.toolpath.rest import faceset_cl_height, generate_rest, net_cl_height
from . import cam, compat
from .faces import faces_and_reach
from .load_limits import LOAD_PROPERTIES
from .part import Extent, surface_extent
from .progress import op_progress, previous_commands, report_cancelled
from .proxy import add_missing_properties
from .retract import PROPERTIES as RETRACT_PROPERTIES
from .retract import hops_report, op_hops
from .stock_left import stock_after_ops
from .surface_feature import is_surface

FreeCAD = compat.ensure_freecad()
import Path  # noqa: E402  (FreeCAD's Path module, 0.20 and 1.0)

OpBase = compat.cam_module("op")
OBJECT_VERSION = "1"
STRATEGIES = [s.value for s in toolpath_common.Strategy]
DIRECTIONS = [d.value for d in toolpath_common.Direction]
ISO_DIRECTIONS = [d.value for d in toolpath_common.IsoDirection]


#: (type, name, group, tooltip, flags, default) of the operation's own properties.
PROPERTIES = (
    ("App::PropertyLink", "Surface", "Surface", "BSplineCAM surface to machine (default: the job's model)", 0, None),
    ("App::PropertyLinkSubListGlobal", "Base", "Surface",
     "Faces to machine, e.g. (Part, ['Face3']); empty: the BSplineCAM surface, or else every "
     "face of the job's model a 3-axis tool reaches from above", 0, None),
    ("App::PropertyEnumeration", "Strategy", "Surface", "raster (drop-cutter), waterline (constant Z), isoparametric, steep_shallow (waterline on walls over 45 degrees, raster on the rest), or scallop (faces: passes offset inwards from the faces' border, spaced by the scallop they leave)", 0, STRATEGIES),
    ("App::PropertyLength", "ScallopHeight", "Surface", "Largest scallop left between passes; the stepover follows the curvature", 0, 0.01),
    ("App::PropertyLength", "Tolerance", "Surface", "Chordal tolerance along a pass", 0, 0.002),
    ("App::PropertyAngle", "Angle", "Surface", "Raster direction in the XY plane", 0, None),
    ("App::PropertyEnumeration", "Direction", "Surface", "zigzag or one-way raster passes; waterline: every contour climbs (material on the right), zigzag lets open ones run back and forth", 0, DIRECTIONS),
    ("App::PropertyEnumeration", "IsoDirection", "Surface", "Parameter followed by iso-parametric passes", 0, ISO_DIRECTIONS),
    ("App::PropertyBool", "Arcs", "Surface", "Fit passes with G2/G3 arcs (one-sided, within the tolerance) in the plane holding them", 0, True),
    ("App::PropertyLength", "RestLimit", "Surface",
     "After earlier ops (roughing): rest passes first take the terraces they left down to this "
     "much above the part, so the finishing passes over them cut about the stock left + "
     "scallop + this deep; 0: no rest passes", 0, 1.0),
    ("App::PropertyLinkList", "RestFrom", "Surface",
     "Ops whose cuts the rest passes start from (the job's roughing, set when it is added); "
     "the finishing op is recomputed after them", 0, None),
    ("App::PropertyString", "Report", "Surface", "Statistics of the last computation (JSON)", 0, None),
    ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM operation", 0, None),
    *RETRACT_PROPERTIES,
    *LOAD_PROPERTIES,
)


class OpError(BSplineCAMError):
    """A user error of the op (its input cannot be machined as set); reported in one line."""


def _labelled(obj, exc: Exception) -> str:
    """The error's text, prefixed by the op's label unless it already names the op."""
    text = str(exc)
    return text if text.startswith(f"{obj.Label}:") else f"{obj.Label}: {text}"


class ObjectSurfaceFinish(OpBase.ObjectOp):
    """Ball-end finishing of a BSplineCAM surface: raster, waterline or iso-parametric."""

    def opFeatures(self, obj):  # noqa: N802 - FreeCAD API
        return OpBase.FeatureTool | OpBase.FeatureDepths | OpBase.FeatureHeights | OpBase.FeatureCoolant

    def initOperation(self, obj):  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)

    #: The op's own properties and version (a subclass names its own).
    properties = PROPERTIES
    version = OBJECT_VERSION

    @classmethod
    def ensure_properties(cls, obj) -> None:
        add_missing_properties(obj, cls.properties)
        for name in ("Report", "Version"):
            obj.setEditorMode(name, 1)
        obj.Version = cls.version

    def opOnDocumentRestored(self, obj):  # noqa: N802 - FreeCAD API
        """Rebuild what the proxy needs from properties (a restored proxy has only its class):
        missing properties, the job's exact-surface stock, a restorable tool controller.
        Documents saved before arcs existed keep their straight moves (Arcs off), those saved
        before minimum retracts their climbs to the clearance height (Retract full)."""
        had_arcs = hasattr(obj, "Arcs")
        had_retract = hasattr(obj, "Retract")
        self.ensure_properties(obj)
        if not had_arcs:
            obj.Arcs = False
        if not had_retract:
            obj.Retract = "full"
        job = self.job_of(obj)
        if job is not None:
            cam.use_surface_stock(job)
        if getattr(obj, "ToolController", None) is not None:
            compat.make_proxy_restorable(obj.ToolController)

    def opSetDefaultValues(self, obj, job):  # noqa: N802 - FreeCAD API
        if obj.Surface is None:
            obj.Surface = find_surface_object(job)

    def job_of(self, obj):
        """The op's job, found from the document (never from state a restored proxy lacks)."""
        return compat.cam_module("utils").findParentJob(obj)

    def uses_faces(self, obj) -> bool:
        """True when the op machines faces (``Base`` set, or no BSplineCAM surface to take)."""
        if getattr(obj, "Base", None):
            return True
        return obj.Surface is None and find_surface_object(self.job_of(obj)) is None

    def faces(self, obj) -> list:
        """The op's faces (:func:`job_faces`), cached while the shapes and Base stay the same
        (the proxy's cache is rebuilt from the document after a restore)."""
        job = self.job_of(obj)
        key = _faces_key(obj, job)
        cached = getattr(self, "_faces_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        faces = job_faces(obj, job)
        self._faces_cache = (key, faces)
        return faces

    def faceset(self, obj):
        key = _faces_key(obj, self.job_of(obj))
        cached = getattr(self, "_faceset_cache", None)
        if cached is not None and cached[0] == key:
            return cached[1]
        faceset = FaceSet(self.faces(obj))
        self._faceset_cache = (key, faceset)
        return faceset

    def surface(self, obj) -> Surface:
        """The exact surface in job coordinates (the model clone's placement applied)."""
        job = self.job_of(obj)
        source = obj.Surface or find_surface_object(job)
        if source is None:
            raise OpError(f"{obj.Label}: the job has no BSplineCAM surface to machine")
        return cam.surface_in_job(source, _model_clone_of(job, source))

    def rest_toolpath(self, obj, cl_height, toolpath, tool: ToolParameters):
        """Rest passes of the op's ball ``tool`` over the stock the ops of ``RestFrom`` left
        (:mod:`.stock_left`), or None: RestLimit 0, no such op with a path, or nothing above
        the limit."""
        limit = float(getattr(obj, "RestLimit", 0.0).Value) if hasattr(obj, "RestLimit") else 0.0
        if not limit > 0:
            return None
        job = self.job_of(obj)
        if job is None or not getattr(obj, "RestFrom", None):
            return None
        progress = progress_reporter(obj)
        stock = stock_after_ops(job, obj, obj.RestFrom, max(0.25 * limit, 0.05), progress)
        if stock is None:
            return None
        # the finishing passes' box, within the stock's grid: a ball on a part's side runs up
        # to its radius beyond the part, past a stock margin narrower than that, where no
        # stock is left to clear
        points = np.concatenate(toolpath.passes)
        g = stock.grid
        extent = (max(float(points[:, 0].min()), g.x0),
                  min(float(points[:, 0].max()), g.x0 + g.nx * g.cell),
                  max(float(points[:, 1].min()), g.y0),
                  min(float(points[:, 1].max()), g.y0 + g.ny * g.cell))
        if not (extent[1] > extent[0] and extent[3] > extent[2]):
            return None
        diameter = tool.diameter
        rest = generate_rest(cl_height, (stock.grid, stock.height), diameter, limit,
                             0.25 * diameter, extent, angle=float(obj.Angle.Value),
                             tolerance=max(obj.Tolerance.Value, 0.005), progress=progress,
                             clearance_height=obj.ClearanceHeight.Value)
        return rest if rest.passes else None

    def opUpdateDepths(self, obj):  # noqa: N802 - FreeCAD API
        """Depths and the stock top from the exact surface, not OCCT's box of the model.

        CAM's updateDepths takes the final depth from OCCT's box of the model (a B-spline
        face's box encloses its poles) and the stock top from the stock object (which may not
        be recomputed yet after an edit); here Final Depth is the surface's lowest point and
        Start Depth and OpStockZMax (the clearance and safe heights' base) the top of the
        stock computed from the exact surface (:func:`cam.stock_box`), so they move with the
        surface and are the same on every recompute.
        """
        job = self.job_of(obj)
        try:
            if self.uses_faces(obj):
                extent = _faces_extent(self.faceset(obj))
            else:
                extent = surface_extent(self.surface(obj))
        except (ValueError, RuntimeError):
            return  # no surface or bad faces: opExecute names the problem
        stock = getattr(job, "Stock", None) if job is not None else None
        if stock is not None and hasattr(stock, "ExtZpos"):
            box = cam.stock_box(stock)  # a stock "from base": around the exact surface
        elif stock is not None and not stock.Shape.isNull():
            box = stock.Shape.BoundBox  # the user's box or cylinder: its own exact box
        else:
            box = None
        top = max(box.ZMax, extent.z_max) if box is not None else extent.z_max
        bottom = box.ZMin if box is not None else extent.z_min
        _set_length(obj, "OpStockZMax", top)
        _set_length(obj, "OpStockZMin", bottom)
        _set_length(obj, "OpFinalDepth", extent.z_min)
        _set_length(obj, "OpStartDepth", top)

    def opExecute(self, obj):  # noqa: N802 - FreeCAD API
        """Record a failure in ``Report`` (for headless callers and the panel).

        A user error (:class:`~BSplineCAM.core.errors.BSplineCAMError`: a bad Base, a face no
        tool reaches, a parameter out of range) is reported as CAM's own ops report theirs
        (``Path.Log.error`` and return, e.g. "No Tool Controller is selected"): one line on
        the console naming the op and the face or property, the previous path kept.  Raising
        it would make FreeCAD print the whole traceback (PathUtils.waiting_effects re-raises,
        FeaturePython reports the Python stack).  Anything else is a bug: it is recorded and
        raised, traceback and all.
        """
        try:
            self._execute(obj)
        except toolpath_common.ToolpathCancelled as exc:  # the user cancelled: keep the past
            self.commandlist[:] = previous_commands(obj)
            report_cancelled(obj, exc)
        except BSplineCAMError as exc:
            self.commandlist[:] = previous_commands(obj)
            obj.Report = json.dumps({"error": str(exc)})
            FreeCAD.Console.PrintError(f"{_labelled(obj, exc)}\n")
        except (ValueError, RuntimeError) as exc:
            obj.Report = json.dumps({"error": str(exc)})
            FreeCAD.Console.PrintError(f"{_labelled(obj, exc)}\n")
            raise

    def ball(self, obj) -> ToolParameters:
        """The op's ball: its tool controller's bit diameter, ``ScallopHeight`` and
        ``Tolerance`` (mm), validated (:meth:`ToolParameters.validate`)."""
        return ToolParameters.validate(float(self.tool.Diameter), obj.ScallopHeight.Value,
                                       obj.Tolerance.Value)

    def _execute(self, obj) -> None:
        # the command line's ranges (finite, a controller accepts them), named as in the panel
        tc = obj.ToolController.Label
        CuttingParameters.validate(
            self.horizFeed, self.vertFeed, float(obj.ToolController.SpindleSpeed), RAPID_RANGE[0],
            names=(f"{tc}: HorizFeed", f"{tc}: VertFeed", f"{tc}: SpindleSpeed", "rapid"))
        shape_name = compat.tool_shape_name(self.tool)
        if "ball" not in shape_name.lower():
            raise OpError(f"{obj.Label}: a ball-end tool is required, the tool controller holds {shape_name!r}")
        if self.uses_faces(obj):
            self._execute_faces(obj)
            return
        surface = self.surface(obj)
        tool = self.ball(obj)
        toolpath = core_toolpath.generate_for_tool(
            surface,
            tool,
            strategy=obj.Strategy,
            angle=obj.Angle.Value,
            direction=obj.Direction,
            iso_direction=obj.IsoDirection,
            clearance_height=obj.ClearanceHeight.Value,
            progress=progress_reporter(obj),
        )
        if not toolpath.passes:
            raise OpError(f"{obj.Label}: the strategy produced no pass")
        lowest = min(float(p[:, 2].min()) for p in toolpath.passes)
        clearance = obj.ClearanceHeight.Value
        rest = self.rest_toolpath(obj, net_cl_height(surface), toolpath, tool)
        hops = op_hops(obj, self.job_of(obj), [rest, toolpath],
                       lambda t, c, m, s: retracts.surface_hops(t, surface, c, m, s),
                       progress_reporter(obj))
        moves = []
        if rest is not None:
            lowest = min(lowest, *(float(p[:, 2].min()) for p in rest.passes))
            moves = core_toolpath.program_moves(rest, clearance, max(obj.SafeHeight.Value, lowest),
                                  arcs=bool(getattr(obj, "Arcs", False)), surface=surface,
                                  hops=hops[0])
        moves += core_toolpath.program_moves(toolpath, clearance, max(obj.SafeHeight.Value, lowest),
                               arcs=bool(getattr(obj, "Arcs", False)), surface=surface,
                               hops=hops[1])
        commands = moves_to_commands(moves, self.horizFeed, self.vertFeed, clearance)
        self.commandlist.extend(commands)
        out = report(toolpath, commands, moves)
        out.update(machine_figures(obj, moves, toolpath, rest))
        out.update(hops_report(hops))
        if rest is not None:
            out["rest"] = rest_report(rest)
        out.update(stock_left_uncut(obj))
        obj.Report = json.dumps(out, sort_keys=True)
        warn_left(obj, toolpath)

    def _execute_faces(self, obj) -> None:
        """Finishing of the op's faces (:func:`job_faces`) by raster, waterline or
        iso-parametric passes (:func:`BSplineCAM.core.toolpath.generate_faces`), heights from
        the certified drop-cutter over all of the job's faces."""
        faceset = self.faceset(obj)
        tool = self.ball(obj)
        toolpath = core_toolpath.generate_faces(
            faceset, obj.Strategy, angle=obj.Angle.Value, direction=obj.Direction,
            iso_direction=obj.IsoDirection, progress=progress_reporter(obj),
            where=obj.Label, tool=tool)
        if not toolpath.passes:
            raise OpError(f"{obj.Label}: the {obj.Strategy} strategy produced no pass on the "
                          "selected faces" + core_toolpath.no_pass_hint(toolpath))
        lowest = min(float(p[:, 2].min()) for p in toolpath.passes)
        clearance = obj.ClearanceHeight.Value
        rest = self.rest_toolpath(obj, faceset_cl_height(faceset), toolpath, tool)
        arcs = bool(getattr(obj, "Arcs", False))
        hops = op_hops(obj, self.job_of(obj), [rest, toolpath],
                       lambda t, c, m, s: retracts.faces_hops(t, faceset, c, m, s),
                       progress_reporter(obj))
        moves = []
        if rest is not None:
            lowest = min(lowest, *(float(p[:, 2].min()) for p in rest.passes))
            moves = core_toolpath.faces_program_moves(rest, faceset, clearance,
                                        max(obj.SafeHeight.Value, lowest), arcs, hops[0])
        moves += core_toolpath.faces_program_moves(toolpath, faceset, clearance,
                                     max(obj.SafeHeight.Value, lowest), arcs, hops[1])
        commands = moves_to_commands(moves, self.horizFeed, self.vertFeed, clearance)
        self.commandlist.extend(commands)
        out = report(toolpath, commands, moves)
        out.update(machine_figures(obj, moves, toolpath, rest))
        out.update(hops_report(hops))
        if rest is not None:
            out["rest"] = rest_report(rest)
        out["faces"] = [f.name for f in faceset.faces if f.selected]
        out["check_faces"] = sum(not f.selected for f in faceset.faces)
        out.update(stock_left_uncut(obj))
        obj.Report = json.dumps(out, sort_keys=True)
        warn_left(obj, toolpath)


def stock_left_uncut(obj) -> dict:
    """The stock the ops of ``RestFrom`` (the roughing) left uncut, which this op's ball may
    meet, from their reports' notes: {"stock_left_uncut": [{"op", "note"}]}, said in the
    report view; {} when there is none.  Verify checks every move against the ball's load
    limits there."""
    found = []
    for other in getattr(obj, "RestFrom", None) or []:
        try:
            notes = json.loads(getattr(other, "Report", "") or "{}").get("notes", [])
        except ValueError:
            continue
        found += [{"op": other.Label, "note": n} for n in notes if "left uncut" in n]
    for item in found:
        FreeCAD.Console.PrintWarning(
            f"{obj.Label}: the ball may meet stock {item['op']} left: {item['note']}; Verify "
            "checks every move against the ball's load limits\n")
    return {"stock_left_uncut": found} if found else {}


def warn_left(obj, toolpath) -> None:
    """Say in the report view what the op leaves: regions the ball cannot reach and the
    toolpath's notes (a waterline's share of the faces too flat for it)."""
    for region in toolpath.unreachable:
        FreeCAD.Console.PrintWarning(f"{obj.Label}: unreachable by the ball: {region}\n")
    for note in toolpath.stats.notes:
        FreeCAD.Console.PrintWarning(f"{obj.Label}: {note}\n")


def moves_to_commands(moves, horizontal_feed: float, vertical_feed: float,
                      clearance: float | None = None) -> list:
    """Path commands for core moves; plunges (pure -Z feeds) use the vertical feed (mm/min).

    With ``clearance`` (absolute Z, mm) the program starts as FreeCAD's own ops do: a lone
    rise ``G0 Z<clearance>`` from wherever the tool stands (after a tool change, or jogged
    low), then the rapid in XY alone to above the first pass, then the descent.
    FreeCAD's Path stores feeds in mm/s; post-processors convert to the machine's units.
    """
    commands = []
    last = None
    moves = list(moves)
    if clearance is not None and moves:
        commands.append(Path.Command("G0", {"Z": float(clearance)}))
        first = moves[0]
        if first.kind == "rapid" and abs(first.z - clearance) < 1e-9:
            commands.append(Path.Command("G0", {"X": first.x, "Y": first.y}))
            last = (first.x, first.y, first.z)
            moves = moves[1:]
    arcs = ArcWords()
    for move in moves:
        target = {"X": move.x, "Y": move.y, "Z": move.z}
        if move.kind in ("cw", "ccw"):
            commands.extend(arcs.commands(move, last, horizontal_feed))
            last = (move.x, move.y, move.z)
            continue
        commands.extend(arcs.restore())
        if move.kind == "rapid":
            commands.append(Path.Command("G0", target))
        else:
            vertical = last is not None and abs(move.x - last[0]) < 1e-9 and abs(move.y - last[1]) < 1e-9
            feed = vertical_feed if vertical else horizontal_feed
            commands.append(Path.Command("G1", {**target, "F": feed}))
        last = (move.x, move.y, move.z)
    commands.extend(arcs.restore())
    return commands


#: Least difference (mm) between successive R, I or J words (see :class:`ArcWords`).
WORD_STEP = 1e-5


class ArcWords:
    """Path commands of core arcs (:class:`BSplineCAM.core.toolpath.arcs.Arc`) that every
    tested post writes correctly in FreeCAD 0.20, 1.0 and 1.1.

    The plane word (G18, G19) goes before a run of arcs in another plane and G17 is restored
    after it.  G17 arcs carry I/J (centre offsets, FreeCAD's own form, which its path view
    draws); G18/G19 arcs carry R instead of I/K or J/K, because the linuxcnc, fanuc and
    mach3_mach4 posts drop K from every command.  Posts that suppress a word equal to the
    last one written (fanuc: OUTPUT_DOUBLES off, which compares every letter with its last
    value in any command) would drop a repeated R, I or J, which are not modal: a value
    within WORD_STEP of the last one is moved WORD_STEP away from it, so that it still differs
    once the document stores the path with 6 decimals (an arc moves by at most that much,
    0.01 um, two orders below the 1 um gouge bound; in practice R repeats where arcs are
    clamped to the largest radius, and R changes a flat arc's height by far less).
    """

    def __init__(self) -> None:
        self.plane = 17
        self.last_words: dict[str, float] = {}

    def _distinct(self, letter: str, value: float) -> float:
        last = self.last_words.get(letter)
        if last is not None and abs(value - last) < WORD_STEP:
            value = last + WORD_STEP
        self.last_words[letter] = value
        return value

    def restore(self) -> list:
        if self.plane == 17:
            return []
        self.plane = 17
        return [Path.Command("G17")]

    def commands(self, arc, start, feed: float) -> list:
        out = []
        if arc.plane != self.plane:
            out.append(Path.Command(f"G{arc.plane}"))
            self.plane = arc.plane
        words = {"X": arc.x, "Y": arc.y, "Z": arc.z}
        if arc.plane == 17:
            words["I"] = self._distinct("I", arc.cx - start[0])
            words["J"] = self._distinct("J", arc.cy - start[1])
        else:
            words["R"] = self._distinct("R", arc.radius)
        words["F"] = feed
        out.append(Path.Command("G2" if arc.kind == "cw" else "G3", words))
        return out


def report(toolpath, commands=None, moves=None) -> dict:
    """The op's statistics.  ``cutting_length_mm`` is the length of the feed moves of the
    program's ``moves`` (core moves and arcs, approach feeds included; the commands are made
    of them), one definition with Verify's (:func:`BSplineCAM.core.toolpath.arcs.feed_length`);
    ``pass_length_mm`` is the length along the passes and stay-down links alone (the core's
    figure, also the cutting length without ``moves``); with ``commands``, also
    ``program_moves`` (G0-G3) and ``arc_moves`` (G2/G3)."""
    stats = toolpath.stats
    cutting = stats.cutting_length_mm if moves is None else feed_length(moves)
    out = {
        "strategy": toolpath.strategy,
        "passes": stats.passes,
        "moves": stats.moves,
        "cutting_length_mm": round(cutting, 6),
        "pass_length_mm": round(stats.cutting_length_mm, 6),
        "seconds": round(stats.seconds, 4),
        "unreachable": [getattr(r, "as_dict", lambda r=r: str(r))() for r in toolpath.unreachable],
        "notes": list(stats.notes),
    }
    if commands is not None:
        out["arc_moves"] = sum(c.Name in ("G2", "G3") for c in commands)
        out["program_moves"] = sum(c.Name in ("G0", "G1", "G2", "G3") for c in commands)
    return out


def machine_figures(obj, moves, *toolpaths) -> dict:
    """The op's program measured as :mod:`BSplineCAM.core.simulation.measures` says (rapid,
    air and link lengths, nominal machining time and the time with acceleration on the
    default machine), from its ``moves`` at its tool controller's feeds and rapid rate (the
    default machine's when the controller has none); ``toolpaths`` are the core toolpaths
    the moves follow (the rest passes and the finishing ones)."""
    cutting = cam.controller_cutting(obj.ToolController)
    rapid = cutting.rapid if RAPID_RANGE[0] <= cutting.rapid <= RAPID_RANGE[1] \
        else DEFAULT_RAPID_RATE
    text = plain_gcode(moves, cutting.horizontal_feed, plunge_feed=cutting.vertical_feed)
    program = read_gcode(text, obj.Label, require_end=False)
    lengths = toolpath_lengths(*toolpaths)
    figures = program_measures(program, lengths["along_passes_mm"],
                               MachineLimits(rapid_rate=rapid))
    figures.pop("cutting_length_mm")  # the report's own, from the moves
    figures["link_length_mm"] = lengths["link_length_mm"]
    return {k: round(v, 6) for k, v in figures.items()}


def rest_report(rest) -> dict:
    """The rest passes' figures in the finishing op's report."""
    return {"passes": rest.stats.passes, "moves": rest.stats.moves,
            "pass_length_mm": round(rest.stats.cutting_length_mm, 6),
            "seconds": round(rest.stats.seconds, 4),
            "offsets_mm": [round(float(o), 6) for o in rest.extra.get("offsets_mm", [])],
            "max_excess_mm": round(float(rest.extra.get("max_excess_mm", 0.0)), 6)}


def progress_reporter(obj):
    """The GUI's progress reporter (status-bar bar, Cancel and Esc raise ToolpathCancelled);
    None headless.  See :mod:`BSplineCAM.app.progress`."""
    if not FreeCAD.GuiUp:
        return None
    return op_progress(obj)


def find_surface_object(job):
    """The BSplineCAM surface behind the job's model (its clone's original), or None."""
    if job is None:
        return None
    for model in job.Model.Group:
        for candidate in [model, *getattr(model, "Objects", []), *getattr(model, "OutList", [])]:
            if is_surface(candidate):
                return candidate
    return None


#: A face's sub-element name in ``Base``.
FACE_NAME = re.compile(r"Face([1-9][0-9]*)")


def _model_of(job, obj):
    """The job's model (its clone) that ``obj`` is or stands behind, or None."""
    if job is None:
        return None
    for model in job.Model.Group:
        if obj is model or obj in [*getattr(model, "Objects", []), *getattr(model, "OutList", [])]:
            return model
    return None


def _shape_key(target) -> tuple:
    shape = target.Shape
    try:
        code = shape.hashCode()
    except Exception:  # noqa: BLE001 - no hashCode: compare by the box alone
        code = None
    return (target.Name, code, str(shape.BoundBox), str(shape.Placement), len(shape.Faces))


def _faces_key(obj, job) -> tuple:
    """What the op's faces depend on: Base, the trim tolerance and the shapes involved."""
    base = tuple((o.Name, tuple(subs)) for o, subs in (getattr(obj, "Base", None) or []))
    models = list(job.Model.Group) if job is not None else []
    others = [o for o, _ in (getattr(obj, "Base", None) or [])]
    return (base, tuple(_shape_key(t) for t in [*models, *others] if hasattr(t, "Shape")))


def _chordal_tolerance(obj) -> float:
    """The op's chordal tolerance (mm) that faces are accepted for (``core.face_import``): its
    ``Tolerance`` property, or the default when it has none."""
    value = getattr(getattr(obj, "Tolerance", None), "Value", None)
    if isinstance(value, (int, float)) and value > 0:
        return float(value)
    return DEFAULT_CHORDAL_TOLERANCE


def _requested_faces(obj, job) -> list[tuple[object, list[int]]]:
    """(target object, 1-based face numbers) per object of ``Base``; a Base object that is the
    original behind a job model becomes that model (the clone, in job coordinates).  Errors
    name the op, the object and the sub-element."""
    requested: list[tuple[object, list[int]]] = []
    for source, subs in obj.Base:
        names = [s for s in subs if s]
        if not names:
            raise FaceError(f"{obj.Label}: Base names {source.Label} but no face of it: the "
                            "selection is empty (select faces, e.g. Face3)")
        shape = getattr(source, "Shape", None)
        if shape is None or shape.isNull():
            raise FaceError(f"{obj.Label}: Base object {source.Label} has no shape")
        numbers = []
        for name in names:
            match = FACE_NAME.fullmatch(name)
            if match is None:
                raise FaceError(f"{obj.Label}: Base {source.Label}.{name} is not a face: the "
                                "op machines faces (Face1, Face2, ...)")
            number = int(match.group(1))
            if number > len(shape.Faces):
                raise FaceError(f"{obj.Label}: Base {source.Label}.{name}: no such face "
                                f"({source.Label} has {len(shape.Faces)} faces)")
            numbers.append(number)
        target = _model_of(job, source) or source
        for known, chosen in requested:
            if known is target:
                chosen.extend(n for n in numbers if n not in chosen)
                break
        else:
            requested.append((target, list(dict.fromkeys(numbers))))
    return requested


def job_faces(obj, job) -> list:
    """Core faces (mm, job coordinates) of the op: selected per ``Base`` (or every face of the
    job's models a 3-axis tool reaches from above when ``Base`` is empty); every other face of
    the job's models, and of the Base objects, is a check surface (``selected=False``).  Face
    names are "<object label>.Face<n>".  FaceError names the op, object and face at fault: a
    sub-element that is no face, an empty selection, a face seen from below, no upward face.
    """
    models = [m for m in (job.Model.Group if job is not None else [])
              if getattr(m, "Shape", None) is not None and not m.Shape.isNull()]
    base = list(getattr(obj, "Base", None) or [])
    requested = _requested_faces(obj, job) if base else []
    chosen = {id(target): numbers for target, numbers in requested}
    targets = [*models, *[t for t, _ in requested if all(t is not m for m in models)]]
    if not targets:
        raise FaceError(f"{obj.Label}: the job has no model with faces to machine")
    out = []
    for target in targets:
        where = f"{obj.Label}: {target.Label}"
        faces, reach = faces_and_reach(target.Shape, where=where,
                                       chordal_tolerance=_chordal_tolerance(obj))
        numbers = chosen.get(id(target))
        if numbers is not None:
            faces = core_faces.apply_selection(faces, reach, numbers, where)
        elif not base:
            faces = [dataclasses.replace(f, selected=up) for f, (up, _) in zip(faces, reach)]
        hidden = hidden_faces(target.Shape)
        out.extend(dataclasses.replace(f, name=f"{target.Label}.{f.name}") for f in faces
                   if f.selected or f.index not in hidden)
    if not any(f.selected for f in out):
        raise FaceError(f"{obj.Label}: no face of the job's model is reachable from above by a "
                        "3-axis tool: select faces in Base")
    return out


def hidden_faces(shape) -> set[int]:
    """1-based numbers of the faces of a closed solid that no ball dropped from above can
    touch first: planes whose outward normal is horizontal or points down, and cylinders
    with a vertical axis.  Leaving them out of the check surfaces changes no height.

    Why: the ball's lowest centre over a solid S is max f over S, f(p) = p_z +
    sqrt(R^2 - |p_xy - q|^2), which grows with p_z.  At a point inside such a face (or on an
    edge between two of them, a vertical line or a downward one) S holds p + t·z for small
    t > 0 (the material lies above a downward face; a vertical face holds the vertical line),
    so f is larger there and the maximum is never inside them: it lies on the other faces,
    which hold every edge that bounds these from above (a closed shell: each edge has two
    faces).  Exact for these surface types, so only they are left out; none for a shape
    that is not made of closed shells.
    """
    import Part

    if not shape.Solids or not shape.Shells or not all(sh.isClosed() for sh in shape.Shells):
        return set()
    out = set()
    for number, face in enumerate(shape.Faces, start=1):
        surface = face.Surface
        try:
            if isinstance(surface, Part.Plane):
                u0, u1, v0, v1 = face.ParameterRange
                if face.normalAt(0.5 * (u0 + u1), 0.5 * (v0 + v1)).z <= 1e-12:
                    out.add(number)
            elif isinstance(surface, Part.Cylinder) and abs(abs(surface.Axis.z) - 1.0) < 1e-12:
                out.add(number)
        except Exception:  # noqa: BLE001 - no normal there: keep the face as a check surface
            continue
    return out


def _faces_extent(faceset):
    """The selected faces' box (FaceSet.bounds, within 1e-6 of their size) as an Extent."""
    lo, hi = faceset.bounds(selected_only=True)
    return Extent(*(float(v) for v in (lo[0], hi[0], lo[1], hi[1], lo[2], hi[2])))


def _model_clone_of(job, source):
    if job is None:
        return None
    for found, clone in cam.model_surfaces(job.Model.Group):
        if found is source:
            return clone
    return None


def _set_length(obj, name: str, value: float) -> None:
    """Set a length property only when it changes (no needless touch)."""
    if abs(getattr(obj, name).Value - value) > 1e-9:
        setattr(obj, name, value)


def new_op(proxy_class, type_name: str, factory, name: str, obj=None, parentJob=None):  # noqa: N803
    """A new op of ``proxy_class`` in ``parentJob`` (default: the active job), like CAM's
    ops' Create; CAM's setup sheet is told the op type exists (it keeps none of its
    properties), so making one does not log "SetupSheet has no support for ..."."""
    compat.cam_module("setup_sheet").RegisterOperation(type_name, factory, lambda: [])
    if obj is None:
        obj = FreeCAD.ActiveDocument.addObject("Path::FeaturePython", name)
    obj.Proxy = proxy_class(obj, name, parentJob)
    return obj


def Create(name: str = "SurfaceFinish", obj=None, parentJob=None):  # noqa: N802, N803 - FreeCAD factory convention
    """A new finishing op in ``parentJob`` (default: the active job), like CAM's ops' Create."""
    return new_op(ObjectSurfaceFinish, "SurfaceFinish", Create, name, obj, parentJob)
