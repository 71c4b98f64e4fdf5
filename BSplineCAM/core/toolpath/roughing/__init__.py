# SPDX-License-Identifier: LGPL-2.1-or-later
"""3-axis Z-level roughing from a stock block or cylinder down to the part plus a stock to
leave.

The part is a height function sampled on a grid.  The lowest allowed tool-tip height T(x, y) is
the maximum over the tool's footprint of part + axial allowance - profile(|d|), the footprint
grown by the radial allowance and by GRID_GROWTH_CELLS cells (so that no point of a contour,
interpolated between cells and simplified, comes closer to the part than the allowance); it is
the inverse tool offset of a Z-map (Choi & Jerard, "Sculptured Surface Machining", 1998, ch. 5).

Each level z clears the allowed centres {T <= z} by distance fronts: Q_0 is air (centres whose
tool disk lies outside the stock) or an entry into a component not reaching air (a closed
pocket): a helix where one fits, else a zig-zag ramp along the component's longest straight
chord where that is at least a tool diameter long, else, for an end mill that cuts at its
centre, a straight plunge at the point farthest from the walls (:meth:`_Job.enter`); a
component none of these enters is left, and named in a note.  Q_{k+1} = (Q_k dilated by the
stepover s) intersected with {T <= z}.  The part of each front's boundary where it grew is a pass, so the
width of cut stays within s.  In a component entered by a helix the fronts are rings round it,
and an outward ring at the full stepover meets the material over a wider arc of the tool's edge
than a straight pass does: a ring grows by :func:`ring_step` of its radius instead, by half the
gap when that would leave it just short of a wall (a front running along a wall, crossing it
back and forth, would be cut in slivers, each entered anew), to the wall when the wall lies
within that step all round, and by s once it meets a wall on one side only.  The wall pieces
{T = z} a front reaches are cut right after it,
from the new front towards the old one, where the material left beside them reaches deeper than
WALL_SLIVER s into the tool's disk, and a last pass follows the level's walls and takes the
thinner slivers.  Contours come from marching squares on the distance field, at sub-cell
precision.  Along a shallow wall the tip height rises in one-cell plateaus and its contour
runs in stairs, each jog a short move sideways into the material: a pass takes the chords
across them that stay inside its contour (within STAIR_CELLS cells) and sweep no wider than
the moves they replace.

Two grids of the level follow the cut: the material still uncut (a cell is cut once a pass
comes within the tool radius, distances exact near that radius) decides which stretches cut
and which links may stay down; an estimate of the machined surface (level + profile at the
distance, never below the true floor) decides how low the tool may rapid and descend: rapids
between passes travel TRAVEL_GAP_MM above the highest material the estimate holds along the
way, the clearance height only where that is higher.  A pass that cannot be reached by a clear
link or a straight descent at its start is entered from the floor already cut when it can be:
a straight descent where the tool's disk is clear down to the level, within
LEAD_IN_REACH_RADII tool radii of the pass's start, and a feed to a vertex within
LEAD_IN_DIAMETERS tool diameters along the pass whose whole swath is no wider than the
stepover (the pass then runs back to its start and on).  Otherwise it is entered by a ramp
along the pass itself at the ramp angle from the surface down to the level: backwards along an
open pass to its start (so the pass does not go back over the ramp), round a closed one.  (A
ramp that reaches its depth at a wall ends in a slot the full diameter wide that the
simulation counts as entry; a lead-in that runs back to a start at a wall ends in the same
head-on cut as a pass into a wall, counted: below.)

With a fine step-down the levels at the step-down run top-down and after each one the band
above it gets levels the fine step apart, cut bottom-up (:func:`_cutting_order`): on such a
level only material above it is uncut, and Q_0 also holds the centres where the tool, by the
surface estimate below, meets no material (the floor already cut), so its fronts start there.

The stock is a block or a vertical cylinder (:mod:`..stock`, CAM's "CreateCylinder" stock):
material lies only over its footprint, so Q_0 is every allowed centre whose tool disk misses
that footprint (the corners of a cylinder's bounding box are air), the uncut grid and the
surface estimate start at the stock top only inside it, and the passes, cut only where they
meet uncut material, end at most a tool radius and a few cells past the rim; the first pass
of a level starts out there, by a straight descent in the air beside the stock.

A pass running head-on into a wall, or past the end of the previous pass along a wall that
slants across the fronts, ends with material on both sides; there the width of cut reaches
about R + s/2 (the crescent between two end disks s apart: 7.4 mm for a 10 mm mill at a 4 mm
stepover and a 2 mm stepdown on examples/case-study.json).  So each level is replayed on
its uncut grid, and where its fronts cut wider than ENGAGEMENT_LIMIT s it is cut again
with fronts that grow by less within WALL_LAYER_RADII tool radii of the walls: they bend
and come to the wall at a slant (:meth:`_Job.level_best`).  Bent fronts cut a little wider
than s where they bend and where two of them close in on each other beside a wall (on the
case study at 2 mm the widest cut went from 7.4 to 4.9 mm), so a level still over is cut
again with its bent fronts at shares of the stepover (STEPOVER_SCALES) until one keeps
within the limit: closer fronts leave thinner wedges.  The narrowest cut is kept.  On the
case study at 2 mm: widest cut 4.3 mm (no move over 1.1 s plus the simulation's cell, 12
before), five of its ten levels at 90 % or less of the stepover, 16 % more cutting length
and about 1.3 times the compute.  Rings round a helix are cut on their exact circle (the
radius their grid contour has) in chords within RING_CHORD_MM: the grid's contour wanders
by about a cell, and a chord of it pointing outwards cut up to 6.2 mm wide at a 4 mm
stepover.  A fine level's fronts round the floor cut below it (a pocket) grow as rings by
the ring step of the radius of a disc of the floor's area (:meth:`_Job.floor_rings`), and
by less where they bend more than that: by the ring step of the radius the front has there
(:func:`front_radius`, the curvature of the cleared region's smoothed signed distance).
That floor is round only roughly, so its rings are not put on a circle; they are cut as
smooth curves (:meth:`_Job.smoothed`) in chords within RING_CHORD_MM, since a long chord of
a bending front sweeps the material ahead of its end.  On the case study's pocket at 8 + 4
mm, moves over the stepover's 1.1: 71 before the rings, 29 with the disc's step in long
chords (up to 5.5 mm wide), 8 now (up to 4.75 mm).  Fronts round other round cleared
regions (the rest of a small closed pass after a ramp that covers only part of it) grow by
the full stepover.

Once a level is kept, its feed moves are replayed once more, and with a flat or bull-nose
end mill each one still wider than PEEL_OVER s is cut instead by a few feeds each within
PEEL_WIDTH s that take the same material (:meth:`_Job.peel`): a greedy walk over a lattice
round the move, each next point the one whose feed from the last cuts the most of that
material within the width, ending at the move's end; where it is stuck, a way to a point
from which a feed to the end takes what is left thin (a sliver beside a contour's corner,
which the tool reaches from the corner only: a feed along the wall takes it thin, one
across it wide).  The steps may stand out of the region as far as the move does (a
contour's corner some hundredths of a mm out, at most PEEL_SLACK_MM).  This takes the
slivers that fronts, bent or narrowed, still meet at a notch of a wall (a wall curving
round the tool, which a straight move into it touches on both flanks at once) and where
two fronts close in.  In that replay a descent (a ramp, a helix) takes only what it cuts
at the level: beside a ramp's start the material stands almost as high as before.  At the
fair load (8 + 4 mm at a 25 % stepover on the case study): moves over 1.1 s plus the
simulation's cell 11 -> 1, widest 3.79 -> 2.95 mm.

A closed pocket no helix enters gets, with a zig-zag ramp or a plunge, a lap round the
boundary of its allowed centres, ramped down to the level and lapped again at it: such a
pocket's centres lie within a few cells of the ramp's chord or the plunge's point, and the
level's wall pass would leave the ring between their reach and the wall as a sliver thinner
than its tolerance.  The lap runs half way between the component's cells and the others, the
same at every level of a straight-walled hole (a contour of T - z moves by up to a cell with
z).  The descents start from the material's top the surface estimate holds within the tool's
disk; beside such a pocket's walls that is the top of the material left there (the allowance
and the tip map's growth), so below the first levels they descend partly through air.

At a wall the passes of successive levels come to the same material within hundredths of a
millimetre (each level's contour is interpolated on the grid, and a pass counts as cutting
only material more than 1.25 cells deep in its tool's disk).  Where a pass of a lower level
reaches a few micrometres nearer than those above it, it takes the hairline column they left
over its whole height.  The job simulation's axial engagement, the deepest drop of any cell,
counts that height: on examples/part.step (10 mm flat, 2 mm down, 0.3 mm allowance, a block 2
mm larger) the largest outside the entries is 20 mm, at the cell 0.67 mm off the part's corner
(80, 0): the levels from Z 21.82 down to 5.82 pass its centre 5.000 to 5.03 mm away, the one
at Z 3.82 4.9987 mm away, so it takes a column 20 mm high and about a micrometre thick.  All
27 moves that go deeper than the step-down and the allowance there do so only at cells
within 0.06 mm of their tool's rim (TestBSplineCAMRoughingEntries bounds the depth of cut
outside the entries away from the rim).

The package: :mod:`.constants`; the tip-height map (:mod:`.tips`); fields and contours on the
grid (:mod:`.gridops`, :mod:`.contours`); round fronts (:mod:`.rings`); a run (:class:`_Job`,
:mod:`.job`) made of its grid state (:mod:`.state`), the widths of cut (:mod:`.engagement`),
the entries (:mod:`.entries`), the passes along the contours (:mod:`.passes`), the replay of
a level (:mod:`.replay`), the peel (:mod:`.peel`) and the levels (:mod:`.levels`).  This
module holds :func:`generate_roughing`, which hands the run ENGAGEMENT_LIMIT,
STEPOVER_SCALES and PEEL_OVER as this module holds them when it is called.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ...errors import ParameterError
from ...simulation.simulate import Grid, Tool
from ...simulation.stock import CylinderStock, Stock, StockShape
from ...typing import FloatArray
from ..common import (
    CancelFn,
    Monitor,
    ProgressFn,
    check_finite,
    check_positive,
    check_range,
)
from .constants import (
    BACK_RAMP_ROUNDS,
    BACK_RAMP_TOL_MM,
    CELL_HALF_DIAGONAL,
    DESCENT_BAND_MM,
    ENGAGEMENT_LIMIT,
    ENTRY_TRACK_MM,
    FILLET_MM,
    FLAT_SLOPE_DEG,
    FLAT_TOOL_AREAS,
    FRONT_SMOOTH_RADII,
    GRID_GROWTH_CELLS,
    HELIX_CHORD_MM,
    LEAD_IN_DIAMETERS,
    LEAD_IN_LATTICE,
    LEAD_IN_REACH_RADII,
    LEAD_IN_ROUTES,
    LEAD_IN_TRIES,
    MAX_CELLS,
    MAX_RAMP_ANGLE_DEG,
    MIN_FRONT_STEP,
    PEEL_APPROACHES,
    PEEL_LATTICE,
    PEEL_OVER,
    PEEL_SLACK_MM,
    PEEL_STEPS,
    PEEL_WIDTH,
    RAMP_ANGLE_DEG,
    RING_CHORD_MM,
    RING_MARGIN_CELLS,
    SMOOTH_ROUNDS,
    STAIR_CELLS,
    STEPOVER_SCALES,
    TRAVEL_GAP_MM,
    WALL_LAYER_RADII,
    WALL_LAYER_STEPS,
    WALL_SLIVER,
)
from .contours import marching_squares
from .entries import _ramp
from .gridops import _densify, _polyline_distance, capped_distance
from .job import _Job
from .levels import _cutting_order, _levels
from .replay import _split_descents
from .rings import front_radius, ring_step, ring_steps
from .tips import disk_max, tip_height

__all__ = [
    "BACK_RAMP_ROUNDS", "BACK_RAMP_TOL_MM", "CELL_HALF_DIAGONAL", "DESCENT_BAND_MM",
    "ENGAGEMENT_LIMIT", "ENTRY_TRACK_MM", "FILLET_MM", "FLAT_SLOPE_DEG", "FLAT_TOOL_AREAS",
    "FRONT_SMOOTH_RADII", "GRID_GROWTH_CELLS", "HELIX_CHORD_MM", "LEAD_IN_DIAMETERS",
    "LEAD_IN_LATTICE", "LEAD_IN_REACH_RADII", "LEAD_IN_ROUTES", "LEAD_IN_TRIES", "MAX_CELLS",
    "MAX_RAMP_ANGLE_DEG", "MIN_FRONT_STEP", "PEEL_APPROACHES", "PEEL_LATTICE", "PEEL_OVER",
    "PEEL_SLACK_MM", "PEEL_STEPS", "PEEL_WIDTH", "RAMP_ANGLE_DEG", "RING_CHORD_MM",
    "RING_MARGIN_CELLS", "SMOOTH_ROUNDS", "STAIR_CELLS", "STEPOVER_SCALES", "TRAVEL_GAP_MM",
    "WALL_LAYER_RADII", "WALL_LAYER_STEPS", "WALL_SLIVER",
    "CylinderStock", "HeightFn", "Roughing", "Stock", "TipHeight",
    "capped_distance", "check_fine_stepdown", "check_ramp_angle", "disk_max", "front_radius",
    "generate_roughing", "marching_squares", "ring_step", "ring_steps", "tip_height",
    # for the tests
    "_Job", "_densify", "_polyline_distance", "_ramp", "_split_descents",
]

HeightFn = Callable[[FloatArray, FloatArray], FloatArray]


@dataclass
class TipHeight:
    """Lowest allowed tool-tip Z (mm) per cell of ``grid`` (rows along y); ``z`` is (ny, nx)."""

    grid: Grid
    z: FloatArray


@dataclass
class Roughing:
    """Roughing moves (tool-tip positions, machine order) and what was done."""

    moves: list
    levels: list
    clearance_height: float
    stats: dict
    tip_height: TipHeight
    parameters: dict = field(default_factory=dict)


def _validate(height, stock, tool, stepdown, stepover, radial, axial, cell, clearance):
    if not callable(height):
        raise ParameterError(f"height must be a function (xs, ys) -> heights in mm, got "
                             f"{height!r}")
    if not isinstance(stock, (Stock, CylinderStock)):
        raise ParameterError(f"stock must be a Stock block or a CylinderStock (mm), got "
                             f"{stock!r}")
    if not isinstance(tool, Tool):
        raise ParameterError(f"tool must be a simulate.Tool, got {tool!r}")
    stepdown = check_positive(stepdown, "stepdown", "mm")
    stepover = check_positive(stepover, "stepover", "mm")
    if stepover > tool.diameter:
        raise ParameterError(
            f"stepover must not exceed the tool diameter ({tool.diameter:g} mm), "
            f"got {stepover:g} mm")
    size = min(stock.x_max - stock.x_min, stock.y_max - stock.y_min)
    radial = check_range(radial, "radial_allowance", "mm", 0.0, size)
    axial = check_range(axial, "axial_allowance", "mm", 0.0, stock.z_max - stock.z_min)
    if cell is not None:
        cell = check_positive(cell, "cell", "mm")
    if clearance is not None:
        clearance = check_finite(clearance, "clearance_height", "mm")
        if not clearance > stock.z_max:
            raise ParameterError(
                f"clearance_height must lie above the stock top ({stock.z_max:g} mm), "
                f"got {clearance:g} mm")
    return stepdown, stepover, radial, axial, cell, clearance


def generate_roughing(height: HeightFn, stock: StockShape, tool: Tool, stepdown: float,
                      stepover: float, radial_allowance: float = 0.0,
                      axial_allowance: float = 0.0, cell: float | None = None,
                      clearance_height: float | None = None, flat_levels: bool = True,
                      fine_stepdown: float | None = None,
                      ramp_angle: float = RAMP_ANGLE_DEG, centre_cutting: bool = False,
                      progress: ProgressFn = None, cancel: CancelFn = None) -> Roughing:
    """Z-level roughing of the part ``height`` (mm, NaN where no part) out of ``stock``, a
    :class:`~BSplineCAM.core.simulation.stock.Stock` block or a vertical
    :class:`~BSplineCAM.core.simulation.stock.CylinderStock` (material only inside its circle).

    ``stepdown`` (mm) between levels, ``stepover`` (mm, at most the diameter) the largest
    radial width of cut, allowances (mm) left on the walls and floors, ``cell`` (mm) the
    grid (default min(stepover/10, diameter/40) within [0.05, 0.5]), ``clearance_height``
    (mm, default stock top + 5).  With ``flat_levels`` flat areas get a level of their own.
    With ``fine_stepdown`` (mm, in (0, stepdown]) the band above each level gets levels that
    far apart, cut bottom-up after it (:func:`_cutting_order`); ``levels`` of the result are
    in cutting order.  Helical and ramped entries descend at ``ramp_angle`` (degrees, in
    (0, MAX_RAMP_ANGLE_DEG]).  ``centre_cutting`` says that the end mill cuts at its centre,
    so that it may plunge: a closed pocket that neither a helix nor a zig-zag ramp enters is
    then entered by a straight plunge at its point farthest from the walls (counted in the
    stats' ``entries`` as ``plunge``); without it such a pocket is left and named in a note.
    Moves are tool-tip positions; see the module docstring for the method.
    """
    started = time.perf_counter()
    monitor = Monitor(progress, cancel, "roughing")
    stepdown, s, ar, aa, cell, clearance = _validate(
        height, stock, tool, stepdown, stepover, radial_allowance, axial_allowance, cell,
        clearance_height)
    fine = None if fine_stepdown is None else check_range(
        fine_stepdown, "fine_stepdown", "mm", 0.0, stepdown, low_open=True)
    ramp_angle = check_ramp_angle(ramp_angle, "ramp_angle")
    if not isinstance(centre_cutting, (bool, np.bool_)):
        raise ParameterError(f"centre_cutting must be True or False (whether the end mill "
                             f"cuts at its centre), got {centre_cutting!r}")
    if fine is not None and fine >= stepdown - 1e-9:
        fine = None  # no level between two of the step-down
    notes: list[str] = []
    R = tool.radius
    if cell is None:
        cell = min(max(min(s / 10.0, tool.diameter / 40.0), 0.05), 0.5)
    margin = R + ar + s + 4.0 * cell
    width = stock.x_max - stock.x_min + 2 * margin
    depth = stock.y_max - stock.y_min + 2 * margin
    if (width / cell) * (depth / cell) > MAX_CELLS:
        coarse = math.sqrt(width * depth / MAX_CELLS)
        notes.append(f"grid cell coarsened from {cell:g} mm to {coarse:.3g} mm to stay within "
                     f"{MAX_CELLS / 1e6:g} million cells")
        cell = coarse
        margin = R + ar + s + 4.0 * cell
    grid = Grid.covering(stock.x_min - margin, stock.x_max + margin, stock.y_min - margin,
                         stock.y_max + margin, cell)
    xs, ys = grid.centres()
    part = np.asarray(height(xs, ys), dtype=float)
    if part.shape != (grid.ny, grid.nx):
        raise ParameterError(f"height must return an array of shape (len(ys), len(xs)) = "
                             f"{(grid.ny, grid.nx)}, got {part.shape}")
    has = np.isfinite(part)
    xg, yg = np.meshgrid(xs, ys)
    outside = stock.distance_xy(xg, yg)
    if has.any():
        out = has & (outside > cell)
        if out.any():
            raise ParameterError(
                "stock must contain the part's XY extent: part found at "
                f"x={xg[out][0]:.3f}, y={yg[out][0]:.3f} mm outside the stock "
                f"({stock.describe()})")
        top_part = float(part[has].max())
        if top_part > stock.z_max + 1e-9:
            raise ParameterError(
                f"stock top ({stock.z_max:g} mm) lies below the part's highest point "
                f"({top_part:.3f} mm)")
    clearance = stock.z_max + 5.0 if clearance is None else clearance
    ztol = min(0.01, stepdown / 50.0)
    T = tip_height(part, cell, tool, ar, aa, stock.z_min, ztol)
    monitor(0.05)

    # material only inside the stock's footprint (a block's rectangle or a cylinder's
    # circle): the fronts start from the air around it, where the tool's disk meets none
    in_stock = stock.contains_xy(xg, yg)
    air = outside >= R * (1 + 1e-9)
    levels, main = _levels(part, T, in_stock, stock, stepdown, aa, cell, R, flat_levels)
    order = _cutting_order(levels, main, stock.z_max, fine)
    Hp = np.where(has, part + aa, -np.inf)

    job = _Job(grid, T, Hp, tool, s, ar, cell, stock, clearance, notes, monitor)
    job.stepdown, job.in_stock, job.ztol, job.outside_mm = stepdown, in_stock, ztol, outside
    job.ramp_slope = math.tan(math.radians(ramp_angle))
    job.engagement_limit, job.stepover_scales = ENGAGEMENT_LIMIT, STEPOVER_SCALES
    job.peel_over = PEEL_OVER
    job.centre_cutting = bool(centre_cutting)
    for li, (z, z_above, up) in enumerate(order):
        job.level_best(z, z_above, in_stock, air, li, len(order), step_up=up)
    levels = [z for z, _, _ in order]
    job.writer.retract()
    job.report_leftover()

    moves = job.writer.moves
    cut = 0.0
    prev = None
    for m in moves:
        if prev is not None and m.kind == "feed":
            cut += math.dist(prev, m[1:])
        prev = m[1:]
    stats = {
        "seconds": time.perf_counter() - started,
        "levels": len(levels),
        "passes": job.passes,
        "cutting_length_mm": cut,
        "entries": {"helical": job.helical, "outside": job.outside, "ramp": job.ramps,
                    "lead_in": job.lead_ins, "zigzag": job.zigzags, "plunge": job.plunges},
        "bent_levels": job.bent_levels,
        "narrowed_levels": job.narrowed_levels,
        "peeled_moves": job.peeled_moves,
        "entry_spans": job.entry_spans,
        "link_moves": job.links,
        "retracts": job.writer.retracts,
        "lifts": job.lifts,
        "ramps": job.ramps,
        "cell_mm": cell,
        "notes": notes,
    }
    monitor(1.0)
    params = {"stepdown": stepdown, "stepover": s, "radial_allowance": ar,
              "axial_allowance": aa, "cell": cell, "flat_levels": bool(flat_levels),
              "ramp_angle": ramp_angle, "centre_cutting": bool(centre_cutting),
              "tool": {"diameter": tool.diameter, "shape": tool.shape.value,
                       "corner_radius": tool.corner_radius}}
    return Roughing(moves, [float(z) for z in levels], float(clearance), stats,
                    TipHeight(grid, T), params)


def check_ramp_angle(value, argument: str) -> float:
    """The entries' ramp angle (degrees) in (0, MAX_RAMP_ANGLE_DEG]; else ParameterError naming
    ``argument`` (the caller's name for it: the op's property, the CLI's option, the panel's
    field)."""
    return check_range(value, argument, "degrees", 0.0, MAX_RAMP_ANGLE_DEG, low_open=True)


def check_fine_stepdown(value, argument: str, stepdown: float) -> float | None:
    """The fine step-down (mm) in [0, stepdown], 0 meaning none (None); else ParameterError
    naming ``argument``."""
    fine = check_range(value, argument, "mm", 0.0, stepdown)
    return fine if fine > 0.0 else None
