# SPDX-License-Identifier: LGPL-2.1-or-later
"""The "B-spline surface finish" operation: a Path/CAM op computed on the exact surface.

A subclass of FreeCAD's own ObjectOp (0.20 ``PathScripts.PathOp``, 1.0 ``Path.Op.Base``), so it
lives in a standard Job, takes its tool from a ToolController and its heights from the job's
setup sheet.  ``opExecute`` reads the properties, calls the numeric core
(:func:`BSplineCAM.core.toolpath.generate`) and turns the plain moves into Path commands.

Linking: lateral rapids run at the clearance height; a rapid descends only to the safe height
(above the stock), the rest of the approach is a feed at the vertical feed rate.
"""

from __future__ import annotations

import json

import numpy as np

from ..core import Surface
from ..core.toolpath import common as toolpath_common
from . import compat
from .proxy import add_missing_properties

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
    ("App::PropertyEnumeration", "Strategy", "Surface", "raster (drop-cutter), waterline (constant Z) or isoparametric", 0, STRATEGIES),
    ("App::PropertyLength", "ScallopHeight", "Surface", "Largest scallop left between passes; the stepover follows the curvature", 0, 0.01),
    ("App::PropertyLength", "Tolerance", "Surface", "Chordal tolerance along a pass", 0, 0.002),
    ("App::PropertyAngle", "Angle", "Surface", "Raster direction in the XY plane", 0, None),
    ("App::PropertyEnumeration", "Direction", "Surface", "zigzag or one-way raster passes", 0, DIRECTIONS),
    ("App::PropertyEnumeration", "IsoDirection", "Surface", "Parameter followed by iso-parametric passes", 0, ISO_DIRECTIONS),
    ("App::PropertyBool", "Arcs", "Surface", "Fit passes with G2/G3 arcs (one-sided, within the tolerance) in the plane holding them", 0, True),
    ("App::PropertyString", "Report", "Surface", "Statistics of the last computation (JSON)", 0, None),
    ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM operation", 0, None),
)


class ObjectSurfaceFinish(OpBase.ObjectOp):
    """Ball-end finishing of a BSplineCAM surface: raster, waterline or iso-parametric."""

    def opFeatures(self, obj):  # noqa: N802 - FreeCAD API
        return OpBase.FeatureTool | OpBase.FeatureDepths | OpBase.FeatureHeights | OpBase.FeatureCoolant

    def initOperation(self, obj):  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)

    @staticmethod
    def ensure_properties(obj) -> None:
        add_missing_properties(obj, PROPERTIES)
        for name in ("Report", "Version"):
            obj.setEditorMode(name, 1)
        obj.Version = OBJECT_VERSION

    def opOnDocumentRestored(self, obj):  # noqa: N802 - FreeCAD API
        """Rebuild what the proxy needs from properties (a restored proxy has only its class):
        missing properties, the job's exact-surface stock, a restorable tool controller.
        Documents saved before arcs existed keep their straight moves (Arcs off)."""
        had_arcs = hasattr(obj, "Arcs")
        self.ensure_properties(obj)
        if not had_arcs:
            obj.Arcs = False
        from . import cam

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

    def surface(self, obj) -> Surface:
        """The exact surface in job coordinates (the model clone's placement applied)."""
        from . import cam

        job = self.job_of(obj)
        source = obj.Surface or find_surface_object(job)
        if source is None:
            raise ValueError(f"{obj.Label}: the job has no BSplineCAM surface to machine")
        return cam.surface_in_job(source, _model_clone_of(job, source))

    def opUpdateDepths(self, obj):  # noqa: N802 - FreeCAD API
        """Depths and the stock top from the exact surface, not OCCT's box of the model.

        CAM's updateDepths takes the final depth from OCCT's box of the model (a B-spline
        face's box encloses its poles) and the stock top from the stock object (which may not
        be recomputed yet after an edit); here Final Depth is the surface's lowest point and
        Start Depth and OpStockZMax (the clearance and safe heights' base) the top of the
        stock computed from the exact surface (:func:`cam.stock_box`), so they move with the
        surface and are the same on every recompute.
        """
        from . import cam
        from .part import surface_extent

        job = self.job_of(obj)
        try:
            extent = surface_extent(self.surface(obj))
        except (ValueError, RuntimeError):
            return  # no surface: opExecute names the problem
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
        """Record a failure in ``Report`` (for headless callers) before FreeCAD marks the op."""
        try:
            self._execute(obj)
        except (ValueError, RuntimeError) as exc:
            obj.Report = json.dumps({"error": str(exc)})
            FreeCAD.Console.PrintError(f"{obj.Label}: {exc}\n")
            raise

    def _execute(self, obj) -> None:
        from ..core.toolpath import generate
        from ..core.toolpath.common import RAPID_RANGE, CuttingParameters

        # the command line's ranges (finite, a controller accepts them), named as in the panel
        tc = obj.ToolController.Label
        CuttingParameters.validate(
            self.horizFeed, self.vertFeed, float(obj.ToolController.SpindleSpeed), RAPID_RANGE[0],
            names=(f"{tc}: HorizFeed", f"{tc}: VertFeed", f"{tc}: SpindleSpeed", "rapid"))
        shape_name = compat.tool_shape_name(self.tool)
        if "ball" not in shape_name.lower():
            raise ValueError(f"{obj.Label}: a ball-end tool is required, the tool controller holds {shape_name!r}")
        surface = self.surface(obj)
        try:
            toolpath = generate(
                surface,
                strategy=obj.Strategy,
                tool_diameter=2.0 * self.radius,
                scallop=obj.ScallopHeight.Value,
                tolerance=obj.Tolerance.Value,
                angle=obj.Angle.Value,
                direction=obj.Direction,
                iso_direction=obj.IsoDirection,
                clearance_height=obj.ClearanceHeight.Value,
                progress=progress_reporter(obj),
            )
        except toolpath_common.ToolpathCancelled as exc:  # the user cancelled: keep the past
            from .progress import previous_commands, report_cancelled

            self.commandlist[:] = previous_commands(obj)
            report_cancelled(obj, exc)
            return
        if not toolpath.passes:
            raise ValueError(f"{obj.Label}: the strategy produced no pass")
        lowest = min(float(p[:, 2].min()) for p in toolpath.passes)
        clearance = obj.ClearanceHeight.Value
        from ..core.toolpath import program_moves

        moves = program_moves(toolpath, clearance, max(obj.SafeHeight.Value, lowest),
                              arcs=bool(getattr(obj, "Arcs", False)), surface=surface)
        commands = moves_to_commands(moves, self.horizFeed, self.vertFeed, clearance)
        self.commandlist.extend(commands)
        obj.Report = json.dumps(report(toolpath, commands), sort_keys=True)
        for region in toolpath.unreachable:
            FreeCAD.Console.PrintWarning(f"{obj.Label}: unreachable by the ball: {region}\n")


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


def _arc_length(name: str, params: dict, start, end, plane: int) -> float:
    """Length (mm) of a G2/G3 Path command from ``start`` to ``end``: R form (short arc) or
    I/J centre offsets, helical travel along the plane's normal included."""
    axes = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[plane]
    a1, a2, normal = axes
    s = np.array([start[a1], start[a2]])
    e = np.array([end[a1], end[a2]])
    if "R" in params:
        r = abs(float(params["R"]))
        half = min(1.0, float(np.linalg.norm(e - s)) / (2.0 * r)) if r > 0 else 0.0
        sweep = 2.0 * np.arcsin(half)
    else:
        offsets = {17: "IJ", 18: "KI", 19: "JK"}[plane]
        c = s + np.array([float(params.get(k, 0.0)) for k in offsets])
        r = float(np.linalg.norm(s - c))
        t0 = np.arctan2(*(s - c)[::-1])
        t1 = np.arctan2(*(e - c)[::-1])
        sweep = (t1 - t0) % (2 * np.pi) if name in ("G3", "G03") else (t0 - t1) % (2 * np.pi)
    return float(np.hypot(r * sweep, end[normal] - start[normal]))


def feed_length(commands) -> float:
    """Length (mm) of the feed moves (G1) of Path commands, each from the previous position:
    the cutting length Verify measures on the posted program's text."""
    total = 0.0
    position = None
    plane = 17
    for command in commands:
        params = command.Parameters
        if command.Name in ("G17", "G18", "G19"):
            plane = int(command.Name[1:])
            continue
        if command.Name not in ("G0", "G00", "G1", "G01", "G2", "G02", "G3", "G03") or not params:
            continue
        target = [params.get(axis, position[i] if position else 0.0) for i, axis in enumerate("XYZ")]
        if command.Name in ("G1", "G01") and position is not None:
            total += float(np.linalg.norm(np.subtract(target, position)))
        elif command.Name not in ("G0", "G00") and position is not None:
            total += _arc_length(command.Name, params, position, target, plane)
        position = target
    return total


def report(toolpath, commands=None) -> dict:
    """The op's statistics.  ``cutting_length_mm`` is the length of the program's feed moves
    (approach feeds included), one definition with Verify's; ``pass_length_mm`` is the length
    along the passes and stay-down links alone (the core's figure); with ``commands``, also
    ``program_moves`` (G0-G3) and ``arc_moves`` (G2/G3)."""
    stats = toolpath.stats
    cutting = stats.cutting_length_mm if commands is None else feed_length(commands)
    out = {
        "strategy": toolpath.strategy,
        "passes": stats.passes,
        "moves": stats.moves,
        "cutting_length_mm": round(cutting, 6),
        "pass_length_mm": round(stats.cutting_length_mm, 6),
        "seconds": round(stats.seconds, 4),
        "unreachable": [getattr(r, "as_dict", lambda r=r: str(r))() for r in toolpath.unreachable],
    }
    if commands is not None:
        out["arc_moves"] = sum(c.Name in ("G2", "G3") for c in commands)
        out["program_moves"] = sum(c.Name in ("G0", "G1", "G2", "G3") for c in commands)
    return out


def progress_reporter(obj):
    """The GUI's progress reporter (status-bar bar, Cancel and Esc raise ToolpathCancelled);
    None headless.  See :mod:`BSplineCAM.app.progress`."""
    if not FreeCAD.GuiUp:
        return None
    from .progress import op_progress

    return op_progress(obj)


def find_surface_object(job):
    """The BSplineCAM surface behind the job's model (its clone's original), or None."""
    if job is None:
        return None
    for model in job.Model.Group:
        for candidate in [model, *getattr(model, "Objects", []), *getattr(model, "OutList", [])]:
            if _is_surface(candidate):
                return candidate
    return None


def _model_clone_of(job, source):
    if job is None:
        return None
    from .cam import model_surfaces

    for found, clone in model_surfaces(job.Model.Group):
        if found is source:
            return clone
    return None


def _set_length(obj, name: str, value: float) -> None:
    """Set a length property only when it changes (no needless touch)."""
    if abs(getattr(obj, name).Value - value) > 1e-9:
        setattr(obj, name, value)


def _is_surface(obj) -> bool:
    from .surface_feature import is_surface

    return is_surface(obj)


def register_with_setup_sheet() -> None:
    """Tell CAM's setup sheet the op exists (it keeps none of its properties), so making an op
    does not log "SetupSheet has no support for SurfaceFinish"."""
    compat.cam_module("setup_sheet").RegisterOperation("SurfaceFinish", Create, lambda: [])


def Create(name: str = "SurfaceFinish", obj=None, parentJob=None):  # noqa: N802, N803 - FreeCAD factory convention
    """A new finishing op in ``parentJob`` (default: the active job), like CAM's ops' Create."""
    register_with_setup_sheet()
    if obj is None:
        obj = FreeCAD.ActiveDocument.addObject("Path::FeaturePython", name)
    obj.Proxy = ObjectSurfaceFinish(obj, name, parentJob)
    return obj
