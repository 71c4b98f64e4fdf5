# SPDX-License-Identifier: LGPL-2.1-or-later
"""3-axis Z-level roughing from a stock block or cylinder down to the part plus a stock to
leave.

The part is a height function sampled on a grid.  The lowest allowed tool-tip height T(x, y) is
the maximum over the tool's footprint of part + axial allowance - profile(|d|), the footprint
grown by the radial allowance and by GRID_GROWTH_CELLS cells (so that no point of a contour,
interpolated between cells and simplified, comes closer to the part than the allowance); it is
the inverse tool offset of a Z-map (Choi & Jerard, "Sculptured Surface Machining", 1998, ch. 5).

Each level z clears the allowed centres {T <= z} by distance fronts: Q_0 is air (centres whose
tool disk lies outside the stock) or a helical entry, and Q_{k+1} = (Q_k dilated by the stepover
s) intersected with {T <= z}.  The part of each front's boundary where it grew is a pass, so the
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
"""

from __future__ import annotations

import copy
import math
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from ..distance import squared_distance
from ..errors import ParameterError
from ..simulate import Grid, Tool, ToolShape, corner_height
from ..stock import CylinderStock, Stock, StockShape
from ..typing import FloatArray
from .common import (
    CancelFn,
    Monitor,
    Move,
    ProgressFn,
    check_finite,
    check_positive,
    check_range,
    label_regions,
    simplify,
)

HeightFn = Callable[[FloatArray, FloatArray], FloatArray]

#: Default angle (degrees) at which helical and ramped entries descend.
RAMP_ANGLE_DEG = 3.0
#: Steepest ramp angle accepted (degrees): steeper is a plunge, which roughing never makes.
MAX_RAMP_ANGLE_DEG = 30.0
#: A wall piece a front reaches is cut right after it when the material left beside it
#: reaches deeper than this share of the stepover into the tool's disk; thinner slivers wait
#: for the level's last pass along the wall.
WALL_SLIVER = 0.5
#: A ring round a helix that would stop this close (cells) short of a wall goes half way to it.
RING_MARGIN_CELLS = 3
#: A stay-down lead-in may join a pass this many tool diameters along it from its start.
LEAD_IN_DIAMETERS = 3.0
#: A lead-in from the floor already cut (a straight descent in the cleared region, then a
#: feed to a vertex of the pass within LEAD_IN_DIAMETERS) starts within this many tool radii
#: of the pass's start, on a lattice this share of the radius apart, and at most
#: LEAD_IN_TRIES such feeds are measured (:meth:`_Job.cleared_lead_in`).
LEAD_IN_REACH_RADII = 2.5
LEAD_IN_LATTICE = 0.25
LEAD_IN_TRIES = 40
#: At most this many lead-ins whose route is measured (:meth:`_Job.runs_within`) per pass.
LEAD_IN_ROUTES = 8
#: Fronts bent towards the walls (:meth:`_Job.level` with ``layer``): within this many tool
#: radii of a wall a front grows by less, down to a share of the stepover at the wall (one of
#: WALL_LAYER_STEPS; the share rises quadratically with the distance, so that the front
#: bends smoothly), and so comes to the wall at a slant instead of head-on.  A level is cut
#: so only when its plain fronts cut wider than ENGAGEMENT_LIMIT stepovers, and kept only
#: if that cuts narrower (:meth:`_Job.level_best`).
WALL_LAYER_RADII = 2.0
WALL_LAYER_STEPS = (0.8, 0.65)
#: Shares of the stepover by which a level's bent fronts grow when at the full stepover
#: they still cut wider than ENGAGEMENT_LIMIT (:meth:`_Job.level_best`): closer fronts
#: leave thinner wedges where they meet the walls and each other.
STEPOVER_SCALES = (0.9, 0.8, 0.7)
#: A floor ring's front grows by :func:`ring_steps` of the radius it has there
#: (:func:`front_radius`, smoothed by box means reaching FRONT_SMOOTH_RADII tool radii to each
#: side), by at least MIN_FRONT_STEP stepovers.
FRONT_SMOOTH_RADII = 0.5
MIN_FRONT_STEP = 0.25
#: Widest cut accepted (times the stepover; :meth:`_Job.engaged_width`, which counts a grid
#: cell for the cells' own width) before a level's bent fronts are tried: the bound the
#: clearing keeps.
ENGAGEMENT_LIMIT = 1.1
#: The replay marks a descent in pieces each spanning at most this much height (mm), the
#: surface estimate dropping to the piece's highest tip height (:meth:`_Job.replay`).
DESCENT_BAND_MM = 0.05
#: A level's feed moves (outside its entries) still wider than PEEL_OVER stepovers when the
#: level is kept are cut instead by a few feeds each no wider than PEEL_WIDTH stepovers
#: (:meth:`_Job.peel`): at most PEEL_STEPS, to points on a lattice PEEL_LATTICE tool radii
#: apart within R of the move.
PEEL_OVER = 1.0
PEEL_WIDTH = 1.0
PEEL_STEPS = 24
PEEL_LATTICE = 0.25
#: Where a peel is stuck, it tries ways to at most PEEL_APPROACHES points whose feed to the
#: move's end takes what is left within the width (:meth:`_Job.peel_approach`).
PEEL_APPROACHES = 4
#: A peel's steps may stand out of the region as far as the move it replaces does (a
#: contour's corner some hundredths of a mm out; 0.064 mm at most on the case study), at
#: most PEEL_SLACK_MM.
PEEL_SLACK_MM = 0.1
#: A level move after an entry's descent whose end and midpoint lie this close (mm) to the
#: descent's track is part of the entry in a level's replay (the job simulation's
#: ENTRY_REACH_MM).
ENTRY_TRACK_MM = 0.02
#: A ramp backwards into an open pass starts where the material's top lies at most
#: BACK_RAMP_TOL_MM above the ramp's top, found in at most BACK_RAMP_ROUNDS rounds
#: (:meth:`_Job.back_ramp`).
BACK_RAMP_ROUNDS = 8
BACK_RAMP_TOL_MM = 1e-4
#: Gap (mm) kept above the material by rapids that travel below the clearance height.
TRAVEL_GAP_MM = 1.0
#: Chord error of the helices (mm).
HELIX_CHORD_MM = 0.01
#: Largest number of grid cells; a finer cell is coarsened with a note.
MAX_CELLS = 4_000_000
#: Largest gap (mm) between a ring round a helix and the chords it is cut in: a chord of a
#: ring sweeps across more of the material than the tangent move ring_step assumes (1.8 mm
#: chords on a 6.5 mm ring cut 4.7 mm wide at a 4 mm stepover; 0.7 mm chords 4.3 mm).
RING_CHORD_MM = 0.02
#: Rounds of corner cutting that smooth a floor ring's fronts (:meth:`_Job.smoothed`).
SMOOTH_ROUNDS = 3
#: Largest distance (cells) by which a pass may run inside its contour where that straightens
#: out the contour's stairs (:meth:`_Job.inner_chords`).
STAIR_CELLS = 1.0
#: Slope below which an area counts as flat (degrees) for the extra levels.
FLAT_SLOPE_DEG = 1.0
#: Flat areas smaller than this many tool areas get no level of their own.
FLAT_TOOL_AREAS = 2.0
#: Height (mm) of the material under a bull-nose's or ball's corner, left by a pass beside,
#: from which a move counts it in its width of cut (:meth:`_Job.engaged_widths`): the job
#: simulation's engagement threshold at its 0.1 mm cells.
FILLET_MM = 0.01
_EPS = 1e-6
#: Half a cell's diagonal, in cells.
CELL_HALF_DIAGONAL = 0.5 * math.sqrt(2.0)
#: Footprint growth against the grid (cells): a contour point lies on a cell edge, up to one
#: cell from the allowed centre it was interpolated from, and simplification moves it by a
#: quarter cell more; T at a centre then bounds the true T within 1.5 cells of it.
GRID_GROWTH_CELLS = 1.5


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


# -- validation ---------------------------------------------------------------------------------
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


# -- the tip-height map -------------------------------------------------------------------------
def _sparse_table(P: FloatArray, widest: int) -> list:
    """Row-wise running maxima over 1, 2, 4, ... columns (Bentley's sparse table)."""
    table = [P]
    span = 1
    while 2 * span <= widest:
        prev = table[-1]
        table.append(np.maximum(prev[:, :-span], prev[:, span:]))
        span *= 2
    return table


def _window_max(table: list, r0: int, r1: int, c0: int, c1: int, nx: int) -> FloatArray:
    """max over columns x + c0 .. x + c1 (padded indices) of rows r0:r1, for x in 0..nx-1."""
    n = c1 - c0 + 1
    p = n.bit_length() - 1
    t = table[p]
    a = t[r0:r1, c0:c0 + nx]
    b0 = c1 - (1 << p) + 1
    return np.maximum(a, t[r0:r1, b0:b0 + nx])


def tip_height(part: FloatArray, cell: float, tool: Tool, radial: float, axial: float,
               floor: float, ztol: float) -> FloatArray:
    """Lowest tool-tip Z per cell: max over the grown footprint of part + axial - profile.

    ``part`` is (ny, nx) with NaN where no part lies.  The footprint radius is
    R + radial + cell/sqrt(2); the profile is the tool's shifted out by radial + cell/sqrt(2).
    Per row of offsets the columns are grouped into runs where the profile varies by at most
    ``ztol`` (mm) and each run costs two look-ups in a sparse table of row maxima (van Herk /
    Gil-Werman style max filter); the run's lowest profile value is used, so the result is
    high by at most ``ztol``, never low.  Clamped below by ``floor``.
    """
    ny, nx = part.shape
    grow = radial + GRID_GROWTH_CELLS * cell
    Rg = tool.radius + grow
    k = int(math.floor(Rg / cell + 1e-9))
    H = np.where(np.isfinite(part), part + axial, -np.inf)
    P = np.pad(H, k, constant_values=-np.inf)
    table = _sparse_table(P, 2 * k + 1)

    def fe(d: float, dy: int) -> float:
        r = cell * math.hypot(d, dy)
        return float(tool.profile(min(max(r - grow, 0.0), tool.radius)))

    out = np.full((ny, nx), -np.inf)
    lim = (Rg / cell) ** 2 + 1e-9
    for dy in range(-k, k + 1):
        w = int(math.floor(math.sqrt(max(lim - dy * dy, 0.0))))
        r0 = dy + k
        d0 = 0
        while d0 <= w:
            f0 = fe(d0, dy)
            d1 = d0
            while d1 + 1 <= w and fe(d1 + 1, dy) - f0 <= ztol:
                d1 += 1
            if d0 == 0:
                m = _window_max(table, r0, r0 + ny, k - d1, k + d1, nx)
            else:
                m = np.maximum(_window_max(table, r0, r0 + ny, k - d1, k - d0, nx),
                               _window_max(table, r0, r0 + ny, k + d0, k + d1, nx))
            np.maximum(out, m - f0, out=out)
            d0 = d1 + 1
    return np.maximum(out, floor)


def disk_max(values: FloatArray, radius: float) -> FloatArray:
    """max of ``values`` over a disk of ``radius`` cells around each cell (-inf beyond)."""
    k = int(math.floor(radius + 1e-9))
    ny, nx = values.shape
    table = _sparse_table(np.pad(values, k, constant_values=-np.inf), 2 * k + 1)
    out = np.full(values.shape, -np.inf)
    for dy in range(-k, k + 1):
        w = int(math.floor(math.sqrt(max(radius * radius + 1e-9 - dy * dy, 0.0))))
        np.maximum(out, _window_max(table, dy + k, dy + k + ny, k - w, k + w, nx), out=out)
    return out


# -- grid helpers -------------------------------------------------------------------------------
def _bilinear(field_: FloatArray, fx: FloatArray, fy: FloatArray) -> FloatArray:
    """Bilinear value at fractional cell indices (column fx, row fy), clamped to the grid."""
    ny, nx = field_.shape
    fx = np.clip(fx, 0.0, nx - 1.0)
    fy = np.clip(fy, 0.0, ny - 1.0)
    j = np.minimum(np.floor(fx).astype(int), max(nx - 2, 0))
    i = np.minimum(np.floor(fy).astype(int), max(ny - 2, 0))
    u, v = fx - j, fy - i
    j1, i1 = np.minimum(j + 1, nx - 1), np.minimum(i + 1, ny - 1)
    return ((1 - u) * (1 - v) * field_[i, j] + u * (1 - v) * field_[i, j1]
            + (1 - u) * v * field_[i1, j] + u * v * field_[i1, j1])


def capped_distance(mask: np.ndarray, cap: float) -> FloatArray:
    """Euclidean distance (cells) from each cell centre to the nearest set cell, exact up to
    ``cap`` and ceil(cap) + 1 beyond: min over |dy| <= cap of dy^2 + g(y + dy)^2, g the
    distance along the row (the separable form of Felzenszwalb & Huttenlocher, 2012).  The
    squares are integers: they are kept in the narrowest integer type that holds them (the
    column pass runs over the whole grid cap times)."""
    k = int(math.ceil(cap))
    big = k + 1
    ny, nx = mask.shape
    # only cells within big of both a set and an unset cell need the passes: beyond the set
    # cells' box grown by big every cell is big away, beyond the unset cells' one it is set
    rows, cols_ = mask.any(axis=1), mask.any(axis=0)
    if not rows.any():
        return np.full(mask.shape, float(big))
    unset_rows, unset_cols = ~mask.all(axis=1), ~mask.all(axis=0)
    if not unset_rows.any():
        return np.zeros(mask.shape)
    i0, i1 = _grown_span(rows, unset_rows, big)
    j0, j1 = _grown_span(cols_, unset_cols, big)
    if (i1 - i0) * (j1 - j0) < 0.75 * ny * nx:  # worth a crop
        out = np.where(mask, 0.0, float(big))
        out[i0:i1, j0:j1] = capped_distance(mask[i0:i1, j0:j1], cap)
        return out
    top = big * big + k * k
    kind = np.int16 if top < 2 ** 15 else (np.int32 if top < 2 ** 31 else np.int64)
    far = 10 * (nx + big)
    cols = np.arange(nx, dtype=np.int32 if far < 2 ** 30 else np.int64)
    left = np.where(mask, cols, -far)
    np.maximum.accumulate(left, axis=1, out=left)
    right = np.minimum.accumulate(np.where(mask, cols, far)[:, ::-1], axis=1)[:, ::-1]
    g = np.minimum(np.minimum(cols - left, right - cols), big).astype(kind)
    f = g * g
    best = f.copy()
    shifted = np.empty_like(f)
    for dy in range(1, min(k, ny - 1) + 1):
        c = kind(dy * dy)
        t = shifted[:ny - dy]
        np.add(f[:-dy], c, out=t)
        np.minimum(best[dy:], t, out=best[dy:])
        np.add(f[dy:], c, out=t)
        np.minimum(best[:-dy], t, out=best[:-dy])
    np.minimum(best, kind(big * big), out=best)
    return np.sqrt(best, dtype=float)


def _grown_span(a: np.ndarray, b: np.ndarray, grow: int) -> tuple[int, int]:
    """[start, stop) of the overlap of the spans of the true entries of a and of b, each
    grown by ``grow`` (within 0 .. len)."""
    n = len(a)
    ia, ib = np.flatnonzero(a), np.flatnonzero(b)
    lo = max(int(ia[0]) - grow, int(ib[0]) - grow, 0)
    hi = min(int(ia[-1]) + grow + 1, int(ib[-1]) + grow + 1, n)
    return lo, max(hi, lo)


def _polyline_distance(pts: FloatArray, path: FloatArray) -> FloatArray:
    """Distance (mm) from each point (k, 2) to the polyline ``path`` (n, 2)."""
    if len(path) == 1:
        return np.hypot(*(pts - path[0]).T)
    ax, ay = path[:-1, 0], path[:-1, 1]
    abx, aby = path[1:, 0] - ax, path[1:, 1] - ay
    L2 = np.maximum(abx * abx + aby * aby, 1e-300)
    out = np.full(len(pts), np.inf)
    step = max(1, 2_000_000 // max(len(ax), 1))
    for k in range(0, len(pts), step):
        rx = pts[k:k + step, :1] - ax
        ry = pts[k:k + step, 1:] - ay
        t = np.clip((rx * abx + ry * aby) / L2, 0.0, 1.0)
        out[k:k + step] = np.hypot(rx - t * abx, ry - t * aby).min(axis=1)
    return out


def _corner_min(field_: FloatArray, fx: FloatArray, fy: FloatArray) -> FloatArray:
    """Smallest value among the (up to) four cell centres around fractional indices."""
    ny, nx = field_.shape
    j = np.clip(np.floor(fx).astype(int), 0, nx - 1)
    i = np.clip(np.floor(fy).astype(int), 0, ny - 1)
    j1, i1 = np.minimum(j + 1, nx - 1), np.minimum(i + 1, ny - 1)
    return np.minimum(np.minimum(field_[i, j], field_[i, j1]),
                      np.minimum(field_[i1, j], field_[i1, j1]))


def _densify(pts: FloatArray, step: float) -> FloatArray:
    """Points along a polyline (k, 2) no farther apart than ``step``: each segment cut in
    equal pieces."""
    if len(pts) < 2:
        return pts.copy()
    if len(pts) == 2:  # one segment (most calls): no gathers
        d = pts[1] - pts[0]
        n = max(1, int(math.ceil(float(np.hypot(d[0], d[1])) / step)))
        t = (np.arange(1, n + 1) / n)[:, None]
        return np.concatenate([pts[:1], pts[0] + t * d])
    seg = pts[1:] - pts[:-1]
    owner, t = _pieces(seg, step)
    return np.concatenate([pts[:1], pts[:-1][owner] + t[:, None] * seg[owner]])


def _pieces(seg: FloatArray, step: float) -> tuple[np.ndarray, FloatArray]:
    """Segments (k, 2) cut in equal pieces no longer than ``step``: the segment of each
    piece's end and its fraction along it (1/n .. 1)."""
    n = np.maximum(np.ceil(np.hypot(seg[:, 0], seg[:, 1]) / step).astype(np.intp), 1)
    owner = np.repeat(np.arange(len(seg)), n)
    return owner, (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n) + 1) / n[owner]


def marching_squares(F: FloatArray) -> list:
    """Polylines (k, 2) in fractional cell indices (column, row) of the level set F = 0.

    Inside is F <= 0; each polyline is oriented with the inside on its right (climb milling
    with a clockwise spindle leaves the material on the left).  Saddles are resolved by the
    cell's mean.  Closed loops repeat their first point at the end.
    """
    ny, nx = F.shape
    if ny < 2 or nx < 2:
        return []
    ins = F <= 0.0
    a, b = F[:-1, :-1], F[:-1, 1:]
    d, c = F[1:, :-1], F[1:, 1:]
    ia, ib, id_, ic = ins[:-1, :-1], ins[:-1, 1:], ins[1:, :-1], ins[1:, 1:]
    code = ia.astype(np.int8) + 2 * ib + 4 * ic + 8 * id_
    cells = np.flatnonzero((code != 0) & (code != 15))
    if not len(cells):
        return []
    ci, cj = np.divmod(cells, nx - 1)
    nh = ny * (nx - 1)

    def hid(i, j):
        return i * (nx - 1) + j

    def vid(i, j):
        return nh + i * nx + j

    def cross_h(i, j):  # between (i, j) and (i, j+1)
        f0, f1 = F[i, j], F[i, j + 1]
        return np.stack([j + f0 / (f0 - f1), i + 0.0 * f0], axis=-1)

    def cross_v(i, j):  # between (i, j) and (i+1, j)
        f0, f1 = F[i, j], F[i + 1, j]
        return np.stack([j + 0.0 * f0, i + f0 / (f0 - f1)], axis=-1)

    e_id = np.stack([hid(ci, cj), vid(ci, cj + 1), hid(ci + 1, cj), vid(ci, cj)], axis=1)
    crossed = np.stack([ia.ravel()[cells] != ib.ravel()[cells],
                        ib.ravel()[cells] != ic.ravel()[cells],
                        id_.ravel()[cells] != ic.ravel()[cells],
                        ia.ravel()[cells] != id_.ravel()[cells]], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        pts = np.stack([cross_h(ci, cj), cross_v(ci, cj + 1), cross_h(ci + 1, cj),
                        cross_v(ci, cj)], axis=1)
    saddle = crossed.sum(axis=1) == 4
    seg_cell, seg_e0, seg_e1 = [], [], []
    two = np.flatnonzero(~saddle)
    order = np.argsort(~crossed[two], axis=1, kind="stable")[:, :2]
    seg_cell.append(two)
    seg_e0.append(order[:, 0])
    seg_e1.append(order[:, 1])
    sad = np.flatnonzero(saddle)
    if len(sad):
        fl = cells[sad]
        mean = (a.ravel()[fl] + b.ravel()[fl] + c.ravel()[fl] + d.ravel()[fl]) / 4.0
        centre_as_a = (mean <= 0.0) == ia.ravel()[fl]
        # centre joins a and c: cut off b (edges 0, 1) and d (2, 3); else a (3, 0) and c (1, 2)
        e0a = np.where(centre_as_a, 0, 3)
        e1a = np.where(centre_as_a, 1, 0)
        e0b = np.where(centre_as_a, 2, 1)
        e1b = np.where(centre_as_a, 3, 2)
        seg_cell += [sad, sad]
        seg_e0 += [e0a, e0b]
        seg_e1 += [e1a, e1b]
    sc = np.concatenate(seg_cell)
    s0 = np.concatenate(seg_e0)
    s1 = np.concatenate(seg_e1)
    p0 = pts[sc, s0]
    p1 = pts[sc, s1]
    k0 = e_id[sc, s0]
    k1 = e_id[sc, s1]
    # orientation: inside (F decreasing) on the right of p0 -> p1
    mid = 0.5 * (p0 + p1)
    i0, j0 = ci[sc], cj[sc]
    u, v = mid[:, 0] - j0, mid[:, 1] - i0
    fa, fb = a.ravel()[cells[sc]], b.ravel()[cells[sc]]
    fc, fd = c.ravel()[cells[sc]], d.ravel()[cells[sc]]
    gx = (1 - v) * (fb - fa) + v * (fc - fd)
    gy = (1 - u) * (fd - fa) + u * (fc - fb)
    t = p1 - p0
    good = (t[:, 1] * gx - t[:, 0] * gy) < 0
    # chain the segments through shared edge crossings (undirected, then orient by majority)
    ends: dict = {}
    for s, (e0, e1) in enumerate(zip(k0.tolist(), k1.tolist())):
        ends.setdefault(e0, []).append(s)
        ends.setdefault(e1, []).append(s)
    used = np.zeros(len(sc), bool)
    k0l, k1l = k0.tolist(), k1.tolist()
    lines = []

    def walk(s: int, key: int) -> tuple[list, list]:
        """Follow from segment s leaving through crossing ``key``; keys and segments."""
        keys, segs = [], []
        while True:
            nxt = [q for q in ends.get(key, []) if not used[q]]
            if not nxt:
                return keys, segs
            q = nxt[0]
            used[q] = True
            segs.append(q)
            key = k1l[q] if k0l[q] == key else k0l[q]
            keys.append(key)

    # each crossing's point where it first occurs (p0 then p1 of each segment, in order)
    key_seq = np.stack([k0, k1], axis=1).ravel()
    point_seq = np.stack([p0, p1], axis=1).reshape(-1, 2)
    crossing, first_at = np.unique(key_seq, return_index=True)
    for s in range(len(sc)):
        if used[s]:
            continue
        used[s] = True
        fwd_keys, fwd_segs = walk(s, k1l[s])
        closed = bool(fwd_keys) and fwd_keys[-1] == k0l[s]
        if closed:
            keys = [k0l[s], k1l[s], *fwd_keys]
            segs = [s, *fwd_segs]
        else:
            back_keys, back_segs = walk(s, k0l[s])
            keys = [*back_keys[::-1], k0l[s], k1l[s], *fwd_keys]
            segs = [*back_segs[::-1], s, *fwd_segs]
        keys_a = np.array(keys)
        poly = point_seq[first_at[np.searchsorted(crossing, keys_a)]]
        # majority vote of the segments' orientation tests along the chain's direction
        segs_a = np.array(segs)
        agree = int(np.count_nonzero((k0[segs_a] == keys_a[:len(segs)]) == good[segs_a]))
        vote = 2 * agree - len(segs)
        if vote < 0:
            poly = poly[::-1]
        lines.append(poly)
    return lines


# -- the generator ------------------------------------------------------------------------------
class _Writer:
    """Moves with the tool's position, counts and the uncut-material grid of the level."""

    def __init__(self, clearance: float):
        self.moves: list[Move] = []
        self.clear = clearance
        self.pos = None  # (x, y, z) or None before the first move
        self.retracts = 0

    def add(self, kind: str, x: float, y: float, z: float) -> None:
        p = (float(x), float(y), float(z))
        if self.pos is not None and all(a == b or abs(a - b) <= 1e-9
                                        for a, b in zip(p, self.pos)):
            return
        self.moves.append(Move(kind, *p))
        self.pos = p

    def retract(self) -> None:
        if self.pos is not None and self.pos[2] < self.clear:
            self.add("rapid", self.pos[0], self.pos[1], self.clear)
            self.retracts += 1


def generate_roughing(height: HeightFn, stock: StockShape, tool: Tool, stepdown: float,
                      stepover: float, radial_allowance: float = 0.0,
                      axial_allowance: float = 0.0, cell: float | None = None,
                      clearance_height: float | None = None, flat_levels: bool = True,
                      fine_stepdown: float | None = None,
                      ramp_angle: float = RAMP_ANGLE_DEG,
                      progress: ProgressFn = None, cancel: CancelFn = None) -> Roughing:
    """Z-level roughing of the part ``height`` (mm, NaN where no part) out of ``stock``, a
    :class:`~BSplineCAM.core.stock.Stock` block or a vertical
    :class:`~BSplineCAM.core.stock.CylinderStock` (material only inside its circle).

    ``stepdown`` (mm) between levels, ``stepover`` (mm, at most the diameter) the largest
    radial width of cut, allowances (mm) left on the walls and floors, ``cell`` (mm) the
    grid (default min(stepover/10, diameter/40) within [0.05, 0.5]), ``clearance_height``
    (mm, default stock top + 5).  With ``flat_levels`` flat areas get a level of their own.
    With ``fine_stepdown`` (mm, in (0, stepdown]) the band above each level gets levels that
    far apart, cut bottom-up after it (:func:`_cutting_order`); ``levels`` of the result are
    in cutting order.  Helical and ramped entries descend at ``ramp_angle`` (degrees, in
    (0, MAX_RAMP_ANGLE_DEG]).
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
                    "lead_in": job.lead_ins},
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
              "ramp_angle": ramp_angle,
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


def _levels(part, T, in_stock, stock, stepdown, aa, cell, R, flat_levels) -> tuple:
    """(levels, main): stock top - k stepdown down to the lowest level needed (``main``,
    top-down) plus the flat-area heights (``levels``, all of them, top-down)."""
    reach = T[in_stock]
    low = max(float(reach.min()) if reach.size else stock.z_min, stock.z_min)
    top = stock.z_max
    levels = []
    k = 1
    while top - k * stepdown > low + 1e-6:
        levels.append(top - k * stepdown)
        k += 1
    if low < top - 1e-6:
        levels.append(low)
    main = list(levels)
    if flat_levels:
        finite = np.isfinite(part)
        filled = np.where(finite, part, 0.0)
        gy, gx = np.gradient(filled, cell)
        flat = finite & in_stock & (np.hypot(gx, gy) < math.tan(math.radians(FLAT_SLOPE_DEG)))
        flat[1:-1, 1:-1] &= finite[:-2, 1:-1] & finite[2:, 1:-1] & finite[1:-1, :-2] & \
            finite[1:-1, 2:]
        if flat.any():
            labels, n = label_regions(flat)
            counts = np.bincount(labels[flat], minlength=n)
            big = np.flatnonzero(counts * cell * cell >= FLAT_TOOL_AREAS * math.pi * R * R)
            for comp in big.tolist():
                h = float(np.median(part[labels == comp])) + aa
                if low + 1e-3 < h < top - 1e-3 and all(abs(h - z) > 1e-3 for z in levels):
                    levels.append(h)
    return sorted(levels, reverse=True), main


def _cutting_order(levels: list, main: list, top: float, fine: float | None) -> list:
    """(z, z_above, step_up) per level in cutting order.  Without ``fine`` the levels run
    top-down, each below the one above.  With it the ``main`` levels (at the step-down from
    the top, and the lowest) run top-down, and after each the band between it and the one above
    gets levels every ``fine`` mm (and the flat-area levels in it), cut from the bottom up
    (step_up True): each clears, beside the floor already cut, the terrace left there up to
    the band's top, so a terrace is never thicker than ``fine`` and its material is cut once."""
    if fine is None:
        return [(z, top if i == 0 else levels[i - 1], False) for i, z in enumerate(levels)]
    extra = [z for z in levels if z not in main]
    out = []
    above = top
    for z in main:
        band = {round(z + k * fine, 9) for k in range(1, int((above - z) / fine) + 1)
                if z + k * fine < above - 1e-3}
        band |= {e for e in extra if z < e < above}
        band = sorted(band)
        band = [b for i, b in enumerate(band) if b in extra or
                all(abs(b - e) > 1e-3 for e in extra)]
        out.append((z, above, False))
        out.extend((b, above, True) for b in band)
        above = z
    return out


@dataclass
class _Ring:
    """Fronts round a helical entry: its component, its centre (x, y mm), the radius of its
    last front (mm; None once it met a wall and grows by the stepover) and the component's
    cells within a stepover of the rim (where a front nears a wall)."""

    mask: np.ndarray
    centre: tuple
    radius: float | None
    near_rim: np.ndarray
    exact: bool = True  # a helix's circle; False: a floor already cut, round only roughly


class _Job:
    """State of one roughing run: the grids, the writer and the running counts."""

    def __init__(self, grid, T, Hp, tool, s, ar, cell, stock, clearance, notes, monitor):
        self.grid, self.T, self.Hp, self.tool = grid, T, Hp, tool
        self.s, self.ar, self.cell, self.stock = s, ar, cell, stock
        self.notes, self.monitor = notes, monitor
        self.R = tool.radius
        self.Rc = tool.radius / cell
        self.writer = _Writer(clearance)
        self.passes = 0
        self.helical = 0
        self.outside = 0
        self.ramps = 0
        self.lead_ins = 0  # straight descents on the floor already cut, then a lead-in
        self.bent_levels: list = []  # levels (z) cut with the fronts bent towards the walls
        self.narrowed_levels: list = []  # [z, share of the stepover] of those cut narrower
        self.lifts = 0
        self.entry_spans: list = []
        self.peeled_moves = 0
        self.links: list[int] = []
        self.floor = np.full(T.shape, stock.z_max)  # lowest level cut at each cell
        self.skipped: list = []

    # coordinates
    def xy(self, f: FloatArray) -> FloatArray:
        g = self.grid
        return np.column_stack([g.x0 + (f[:, 0] + 0.5) * g.cell, g.y0 + (f[:, 1] + 0.5) * g.cell])

    def idx(self, p: FloatArray) -> FloatArray:
        g = self.grid
        p = np.atleast_2d(np.asarray(p, dtype=float))
        return np.column_stack([(p[:, 0] - g.x0) / g.cell - 0.5, (p[:, 1] - g.y0) / g.cell - 0.5])

    def window(self, f: FloatArray, pad: float) -> tuple[int, int, int, int]:
        ny, nx = self.T.shape
        j0 = max(int(math.floor(f[:, 0].min() - pad)), 0)
        j1 = min(int(math.ceil(f[:, 0].max() + pad)) + 1, nx)
        i0 = max(int(math.floor(f[:, 1].min() - pad)), 0)
        i1 = min(int(math.ceil(f[:, 1].max() + pad)) + 1, ny)
        return i0, i1, j0, j1

    # the uncut-material grid
    def mark(self, path_xy: FloatArray, only: np.ndarray | None = None,
             heights: tuple | None = None) -> None:
        """Record the cut of the tool along a path at the level: cells within R of it leave
        the uncut grid, and cells the tool covers whole (their centre within R less half a
        diagonal) drop in the surface estimate to the level plus the profile at their
        farthest point, so that the estimate bounds the material over the whole cell; its
        lower bound ``surface_lo`` drops wherever the tool reaches the cell, to the level plus
        the profile at the cell's nearest point.
        Distances come from the path's samples rounded to cells (good to 3/4 cell), exact to
        the path's segments in the band where that rounding could decide either; a path of
        one segment (most calls) has them exact over its whole window, at less cost.  With
        ``only``, the cells leave that grid of uncut cells and nothing else changes.  With
        ``heights`` (low, high) the path is not at the level but between those tip heights
        (a descent's): the estimate drops to the high one plus the profile, its lower bound
        and the floor to the low one."""
        path_xy = np.asarray(path_xy, dtype=float)
        if len(path_xy) == 2:
            i0, i1, j0, j1 = self.window(self.idx(path_xy), self.Rc + 2)
            g = self.grid
            px = (g.x0 + (np.arange(j0, j1) + 0.5) * g.cell)[None, :] - path_xy[0, 0]
            py = (g.y0 + (np.arange(i0, i1) + 0.5) * g.cell)[:, None] - path_xy[0, 1]
            ab = path_xy[1] - path_xy[0]
            t = np.clip((px * ab[0] + py * ab[1]) / max(float(ab @ ab), 1e-300), 0.0, 1.0)
            dist = np.hypot(px - t * ab[0], py - t * ab[1])
            dist_lo = dist
        else:
            f = self.idx(_densify(path_xy, 0.5 * self.cell))
            i0, i1, j0, j1 = self.window(f, self.Rc + 2)
            m = np.zeros((i1 - i0, j1 - j0), bool)
            ii = np.clip(np.rint(f[:, 1]).astype(int) - i0, 0, i1 - i0 - 1)
            jj = np.clip(np.rint(f[:, 0]).astype(int) - j0, 0, j1 - j0 - 1)
            m[ii, jj] = True
            d = capped_distance(m, self.Rc + 1)
            dist = np.minimum(d + 0.75, self.Rc + 1.0) * self.cell  # >= the true distance
            dist_lo = np.maximum(d - 0.75, 0.0) * self.cell  # <= it
            band = np.flatnonzero((d > self.Rc - 3.0) & (d <= self.Rc + 1.0))
            if len(band):
                by, bx = np.divmod(band, j1 - j0)
                pts = self.xy(np.column_stack([bx + j0, by + i0]).astype(float))
                dist.flat[band] = dist_lo.flat[band] = _polyline_distance(pts, path_xy)
        cut = dist <= self.R
        if only is not None:  # that grid of uncut cells only
            only[i0:i1, j0:j1] &= ~cut
            return
        z_lo, z_hi = (self.z, self.z) if heights is None else heights
        self.uncut[i0:i1, j0:j1] &= ~cut
        fl = self.floor[i0:i1, j0:j1]
        fl[cut] = np.minimum(fl[cut], z_lo)
        # the estimate bounds the material's top over the whole cell: a cell drops only where
        # its farthest point (half a diagonal out) lies within the tool, to the profile there
        far = dist + CELL_HALF_DIAGONAL * self.cell
        whole = far <= self.R
        sf = self.surface[i0:i1, j0:j1]
        sf[whole] = np.minimum(sf[whole], z_hi + self.tool.profile(far[whole]))
        # and its lower bound: the tool's lowest point over the cell, where it reaches any
        near = dist_lo - CELL_HALF_DIAGONAL * self.cell
        some = near <= self.R
        lo = self.surface_lo[i0:i1, j0:j1]
        lo[some] = np.minimum(lo[some], z_lo + self.tool.profile(np.maximum(near[some], 0.0)))

    def safe_at(self, q: FloatArray, z: float) -> float:
        """Lowest tip height (>= z) at q (xy) where the tool meets none of the material the
        surface estimate holds (:meth:`safe_heights` of one point)."""
        return float(self.safe_heights(np.asarray(q, dtype=float)[None, :], z)[0])

    def safe_heights(self, qs: FloatArray, z: float) -> FloatArray:
        """:meth:`safe_at` of each point of qs (n, 2): the highest cell of the surface estimate
        within the tool's disk less the tool's profile there, the cells taken 3/4 cell nearer
        for their size (the profile of a bull-nose or ball rises steeply at its rim), at
        least z."""
        f = self.idx(np.asarray(qs, dtype=float))
        base = np.floor(f).astype(int)
        k = int(math.ceil(self.Rc + 0.75)) + 1
        o = np.arange(-k, k + 2)
        oj, oi = (a.ravel() for a in np.meshgrid(o, o))
        # only offsets that can reach the disk (the point lies within 1.5 cells of its base)
        reach = np.hypot(oj, oi) <= self.Rc + 0.75 + 1.5
        oj, oi = oj[reach], oi[reach]
        jj = base[:, 0:1] + oj[None, :]
        ii = base[:, 1:2] + oi[None, :]
        r = np.hypot(jj - f[:, 0:1], ii - f[:, 1:2]) * self.cell - 0.75 * self.cell
        ny, nx = self.surface.shape
        inside = (r <= self.R) & (jj >= 0) & (jj < nx) & (ii >= 0) & (ii < ny)
        top = np.full(r.shape, -np.inf)
        top[inside] = self.surface[ii[inside], jj[inside]] - self.tool.profile(
            np.maximum(r[inside], 0.0))
        return np.maximum(top.max(axis=1), z)

    def clear_at(self, qs: FloatArray, z: float) -> np.ndarray:
        """Which points of qs (n, 2) the tool may descend straight to z at: :meth:`safe_heights`
        within 0.01 mm of z, measured only where the nearest cell of the estimate above that
        (its distance on the grid, give or take the point's offset from its cell's centre)
        lies neither beyond the tool's reach (clear) nor under its flat bottom (not)."""
        qs = np.asarray(qs, dtype=float)
        f = self.idx(qs)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        high = self.surface[i0:i1, j0:j1] > z + 0.01
        ok = np.ones(len(qs), bool)
        if not high.any():
            return ok
        d = capped_distance(high, self.Rc + 3)
        jr = np.rint(f[:, 0]).astype(int) - j0
        ir = np.rint(f[:, 1]).astype(int) - i0
        # a point off the grid has no cell of its own there: measured
        on = (jr >= 0) & (jr < j1 - j0) & (ir >= 0) & (ir < i1 - i0)
        dq = np.where(on, d[np.clip(ir, 0, i1 - i0 - 1), np.clip(jr, 0, j1 - j0 - 1)], np.nan)
        far = (dq - CELL_HALF_DIAGONAL - 0.75) * self.cell > self.R
        # such a cell within the tool's flat bottom (where its profile is 0) blocks it
        tool = self.tool
        flat = {"flat": self.R, "bullnose": self.R - tool.corner_radius}.get(tool.shape.value,
                                                                             0.0)
        blocked = (dq + CELL_HALF_DIAGONAL - 0.75) * self.cell <= flat
        ok[blocked] = False
        near = ~(far | blocked)  # NaN (off the grid) is neither
        if near.any():
            ok[near] = self.safe_heights(qs[near], z) <= z + 0.01
        return ok

    def link_ok(self, p: tuple, q: tuple, z: float) -> bool:
        """A feed from p to q at level z stays in {T <= z} and its tool meets no uncut
        material (within the grid's rounding of the cut region)."""
        if not self.in_region(p, q, z):
            return False
        f = self.along(p, q)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        sub = self.uncut[i0:i1, j0:j1]
        if not sub.any():
            return True
        d = capped_distance(sub, self.Rc + 2)
        return bool(np.all(_bilinear(d, f[:, 0] - j0, f[:, 1] - i0) >= self.Rc - 1.25))

    def along(self, a, b) -> FloatArray:
        """Fractional grid indices of points half a cell apart along the segment a-b (xy)."""
        return self.idx(_densify(np.array([a[:2], b[:2]], dtype=float), 0.5 * self.cell))

    def in_region(self, a, b, z) -> bool:
        """The straight feed from a to b (xy) stays in {T <= z}."""
        return bool(self.in_region_many(np.asarray(a, dtype=float)[None, :2],
                                        np.asarray(b, dtype=float)[None, :2], z)[0])

    def in_region_many(self, A: FloatArray, B: FloatArray, z: float) -> np.ndarray:
        """:meth:`in_region` of the feeds from A[i] to B[i] (n, 2), sampled at once: the
        points of :func:`_densify` of each, half a cell apart."""
        D = B - A
        owner, t = _pieces(D, 0.5 * self.cell)
        pts = np.concatenate([A, A[owner] + t[:, None] * D[owner]])
        f = self.idx(pts)
        high = _bilinear(self.T, f[:, 0], f[:, 1]) > z + 1e-3
        out = ~high[:len(A)]
        out &= np.bincount(owner, weights=high[len(A):], minlength=len(A)) == 0
        return out

    def path_in_region(self, path: FloatArray, z: float) -> bool:
        """Every feed along the polyline ``path`` (xy) stays in {T <= z} (:meth:`in_region`
        of each, sampled at once)."""
        p = np.asarray(path, dtype=float)[:, :2]
        a, b = (p[:-1], p[1:]) if len(p) > 1 else (p, p)
        return bool(self.in_region_many(a, b, z).all())

    def engaged_width(self, a, b) -> float:
        """Width of cut (mm) of a feed from a to b (xy) at the level, by the uncut grid, as the
        job simulation measures a move: the extent across the move of all the uncut cells it
        sweeps (within R of it, ahead of its start), plus a cell.  A move entering a band at a
        slant cuts a swath wider than the width at any one of its positions."""
        return float(self.engaged_widths(np.asarray(a, dtype=float)[None, :2],
                                         np.asarray(b, dtype=float)[None, :2])[0])

    def engaged_widths(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """:meth:`engaged_width` of the feeds from A[i] to B[i] (n, 2), over the uncut cells
        of the window round all of them at once."""
        return self.engaged(A, B)[0]

    def engaged(self, A: FloatArray, B: FloatArray, task: np.ndarray | None = None,
                material: np.ndarray | None = None) -> tuple:
        """(widths, counts): :meth:`engaged_widths` of the feeds from A[i] to B[i], and how
        many of the cells of ``task`` (a grid of the level's shape; None: the uncut cells)
        each sweeps within R (ahead of its start, as the widths count)."""
        out = np.zeros(len(A))
        counts = np.zeros(len(A), int)
        length = np.array([math.dist(a, b) for a, b in zip(A.tolist(), B.tolist())])
        live = np.flatnonzero(length >= 1e-9)
        if not len(live):
            return out, counts
        A, B, length = A[live], B[live], length[live]
        i0, i1, j0, j1 = self.window(self.idx(np.concatenate([A, B])), self.Rc + 2)
        uncut = base = (self.uncut if material is None else material)[i0:i1, j0:j1]
        work = uncut if task is None else task[i0:i1, j0:j1]
        flat = self.tool.shape is ToolShape.FLAT
        if not flat:
            # a bull-nose's or ball's passes leave fillets under their corners, which the
            # surface estimate holds: material there counts as the simulation counts it
            above = self.surface[i0:i1, j0:j1] - self.z
            above_lo = self.surface_lo[i0:i1, j0:j1] - self.z
            uncut = uncut | (above > FILLET_MM)
        iy, ix = np.nonzero(uncut | work)
        if not len(iy):
            return out, counts
        cells = self.xy(np.column_stack([ix + j0, iy + i0]).astype(float))
        d = (B - A) / length[:, None]
        rx = cells[None, :, 0] - A[:, :1]
        ry = cells[None, :, 1] - A[:, 1:]
        along = rx * d[:, :1] + ry * d[:, 1:]
        across = ry * d[:, :1] - rx * d[:, 1:]
        L = length[:, None]
        swept = (along > 0) & (np.abs(across) <= self.R) & (along <= L) | (
            (along > L) & ((along - L) ** 2 + across * across <= self.R * self.R))
        counts[live] = (swept & work[iy, ix][None, :]).sum(axis=1)
        swept &= uncut[iy, ix][None, :]
        if not flat:
            # material left under a corner counts where the move's tool, over the whole cell,
            # passes below it (a pass over the same line leaves the same fillet), and only
            # what stands above corner_height of the move's deepest cut, as the simulation
            # counts it (fresh material: the uncut cells, at the level's top)
            h = above[iy, ix]  # the estimate bounds the material's top, uncut cells' too
            fresh = base[iy, ix]
            dist = np.where(along > L, np.hypot(along - L, across), np.abs(across))
            bottom = self.tool.profile(dist + CELL_HALF_DIAGONAL * self.cell)
            # the move's deepest cut, as the simulation takes it: the most the tool drops
            # any cell by, not the highest material it passes (a fillet's crest beside it
            # under the corner would lift the corner's height over the toes it does skim);
            # from the estimate's lower bound less the tool's highest point over each cell,
            # so that it is never deeper than the simulation's and sets the corner no higher
            axial = np.where(swept, above_lo[iy, ix][None, :] - bottom, 0.0).max(axis=1)
            corner = corner_height(self.tool, np.maximum(axial, 0.0))
            swept &= fresh[None, :] | ((h[None, :] > corner[:, None] + FILLET_MM)
                                       & (h[None, :] > bottom + FILLET_MM))
        hi = np.where(swept, across, -np.inf).max(axis=1)
        lo = np.where(swept, across, np.inf).min(axis=1)
        out[live] = np.where(swept.any(axis=1), hi - lo + self.cell, 0.0)
        return out, counts

    def lead_in(self, p: FloatArray, z: float) -> int | None:
        """Index k of a vertex of pass p (xy) that the tool, at level z nearby, may reach by
        a straight feed cutting no wider than the stepover and staying
        in {T <= z}: the first such vertex within LEAD_IN_DIAMETERS tool diameters along p."""
        w = self.writer
        if w.pos is None or abs(w.pos[2] - z) > 1e-9:
            return None
        here = np.array(w.pos[:2])
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        for k in range(1, len(p)):
            if arc[k] > LEAD_IN_DIAMETERS * self.tool.diameter:
                break
            q = p[k]
            if math.dist(here, q) > 10 * self.tool.diameter:
                continue
            if self.in_region(here, q, z) and self.engaged_width(here, q) <= self.s:
                return k
        return None

    def cleared_lead_in(self, p: FloatArray, z: float) -> tuple | None:
        """A straight descent and a lead-in into pass p (xy) on level z from the floor already
        cut: a point c within LEAD_IN_REACH_RADII tool radii of the pass's start and a tool
        diameter of the stock's footprint, where the surface estimate leaves the tool's disk
        clear down to z, and the index k of a vertex within LEAD_IN_DIAMETERS tool diameters
        along p, such that the feed from c to p[k] stays in {T <= z} and its whole swath is no
        wider than the stepover (:meth:`engaged_width`), and the route's first moves after it
        (for k > 0 back to the start and on), up to a diameter past p[k], within 1.1 stepover
        (:meth:`runs_within`, at most LEAD_IN_ROUTES routes).  The start is tried first, then
        the vertices along; in each, the shortest feeds first, at most LEAD_IN_TRIES of them;
        (c, k) or None."""
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        ks = np.flatnonzero(arc <= LEAD_IN_DIAMETERS * self.tool.diameter)
        ks = ks[:: max(1, len(ks) // 8)]
        step = max(self.cell, LEAD_IN_LATTICE * self.R)
        reach = LEAD_IN_REACH_RADII * self.R
        n = int(reach / step)
        g = np.arange(-n, n + 1) * step
        off = np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
        off = off[np.hypot(off[:, 0], off[:, 1]) <= reach]
        C = p[0] + off
        # by the stock, not farther out in the air than a tool diameter beyond its rim
        f = np.rint(self.idx(C)).astype(int)
        ny, nx = self.T.shape
        inside = (f[:, 0] >= 0) & (f[:, 0] < nx) & (f[:, 1] >= 0) & (f[:, 1] < ny)
        f = f[inside]
        C = C[inside][self.outside_mm[f[:, 1], f[:, 0]] <= 2 * self.R]
        C = C[self.clear_at(C, z)] if len(C) else C
        if not len(C):
            return None
        dist = np.hypot(C[:, None, 0] - p[ks][None, :, 0], C[:, None, 1] - p[ks][None, :, 1])
        # the start first, then further along (whence the route runs back to the start); the
        # route's first moves, up to a diameter past where the lead-in joined it, must cut
        # within 1.1 stepover too (a start at a wall could be met head-on)
        checked = 0
        for group in (ks == 0, ks > 0):
            sub = np.where(group[None, :], dist, np.inf)
            tries = np.argsort(sub, axis=None, kind="stable")[:LEAD_IN_TRIES]
            tries = tries[np.isfinite(sub.flat[tries])]
            # the feeds of the tries in one go: long enough, in the region, narrow enough
            ci_all, kj_all = np.divmod(tries, len(ks))
            good = dist[ci_all, kj_all] > 1e-9
            good[good] = self.in_region_many(C[ci_all[good]], p[ks[kj_all[good]]], z)
            good[good] = self.engaged_widths(C[ci_all[good]], p[ks[kj_all[good]]]) <= self.s
            for ci, kj in zip(ci_all[good].tolist(), kj_all[good].tolist()):
                c, k = C[ci], int(ks[kj])
                route = _lead_route(p, k)
                length = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(route, axis=0).T))])
                m = int(np.searchsorted(length, 2.0 * arc[k] + self.tool.diameter))
                if self.runs_within(np.vstack([c, route[:m + 1]])):
                    return c, k
                checked += 1
                if checked >= LEAD_IN_ROUTES:
                    return None
        return None

    def runs_within(self, path: FloatArray) -> bool:
        """Every feed of path (xy) after its first cuts no wider than 1.1 stepover, the bound
        the passes keep (:meth:`engaged_width` of its whole swath, a cell over the width
        along a pass), each measured after the feeds before it have cut (a trial on the
        grids, undone)."""
        f = self.idx(path)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        saved = [(g, g[i0:i1, j0:j1].copy())
                 for g in (self.uncut, self.floor, self.surface, self.surface_lo)]
        try:
            self.mark(path[:2])
            for a, b in zip(path[1:-1], path[2:]):
                if self.engaged_width(a, b) > 1.1 * self.s:
                    return False
                self.mark(np.array([a, b]))
            return True
        finally:
            for g, view in saved:
                g[i0:i1, j0:j1] = view

    def travel_height(self, a: FloatArray, b: FloatArray) -> float:
        """Height (mm) at which a rapid from a to b (xy) meets no material: the highest
        surface estimate within the tool radius plus two cells of the segment, plus
        TRAVEL_GAP_MM."""
        path = np.array([a, b], dtype=float)
        f = self.idx(path)
        i0, i1, j0, j1 = self.window(f, self.Rc + 3)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        sub = self.surface[i0:i1, j0:j1]
        high = sub > -np.inf
        if not high.any():
            return -np.inf
        pts = self.xy(np.column_stack([jj[high], ii[high]]).astype(float))
        near = _polyline_distance(pts, path) <= self.R + 2 * self.cell
        return float(sub[high][near].max(initial=-np.inf)) + TRAVEL_GAP_MM

    def descend(self, q: FloatArray, z: float, over: float) -> None:
        """Lift, rapid over q, rapid down to ``over`` and feed down to z.  The lift goes to
        the clearance height, or only as high as the material along the way needs
        (:meth:`travel_height`) when that is lower."""
        w = self.writer
        h = w.clear
        if w.pos is not None and w.pos[2] < w.clear:
            h = max(self.travel_height(np.array(w.pos[:2]), np.asarray(q, dtype=float)),
                    over, w.pos[2])
            if h < w.clear - 1e-9:
                w.add("rapid", w.pos[0], w.pos[1], h)
                self.lifts += 1
            else:
                h = w.clear
                w.retract()
        w.add("rapid", q[0], q[1], h)
        if over < h:
            w.add("rapid", q[0], q[1], over)
        w.add("feed", q[0], q[1], z)

    def link(self, q: tuple) -> None:
        """A stay-down feed to q (x, y, z) between passes, its index kept in ``links``."""
        n = len(self.writer.moves)
        self.writer.add("feed", *q)
        if len(self.writer.moves) > n:
            self.links.append(n)

    def back_ramp(self, p: FloatArray, z: float, top: float,
                  slope: float) -> tuple | None:
        """A ramp into the open pass p (xy) that reaches level z at its start, so that the pass
        follows without going back over the ramp: the walk of length L = (h - z) / ``slope``
        (dz/dxy) from the start along p (back and forth along a shorter p, as
        :func:`_ramp`), taken from its far end backwards, h the height there that clears the
        material (:meth:`safe_at`, at least ``top``).  Returns the ramp's top (x, y, h) and
        its points (k, 3) down to the start, or None if no such height is found."""
        height = top
        for _ in range(BACK_RAMP_ROUNDS):
            fwd, _ = _ramp(p, False, height - z, slope)
            walk = np.vstack([p[:1], fwd[:, :2]])
            h = self.safe_at(walk[-1], z)
            # the far end moves with the height: where the material's top slopes along the
            # pass (beside a stock's rim under a ball) the heights converge geometrically
            if h <= height + BACK_RAMP_TOL_MM:
                break
            height = h
        else:
            return None
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(walk, axis=0).T))])
        ramp = np.column_stack([walk[:-1][::-1], z + slope * arc[:-1][::-1]])
        return (float(walk[-1, 0]), float(walk[-1, 1]), height), ramp

    def cut_path(self, p: FloatArray, z: float, z_above: float) -> None:
        """Reach the start of pass p (xy) on level z and cut it: a straight stay-down link if
        it meets no uncut material, or a stay-down lead-in to a vertex a few diameters along
        the pass that cuts within the stepover (:meth:`lead_in`); else lift (:meth:`descend`)
        and descend straight at the start where the surface estimate leaves the tool's disk
        clear down to z, or on the floor already cut near it, followed by a lead-in to the
        start or a vertex along the pass (:meth:`cleared_lead_in`); else ramp down along the
        pass itself at the ramp angle from the surface: along an open pass backwards to its
        start (:meth:`back_ramp`), round a closed one from its start."""
        w = self.writer
        closed = len(p) > 2 and bool(np.allclose(p[0], p[-1]))
        q = (float(p[0, 0]), float(p[0, 1]), z)
        route = p
        if w.pos is not None and abs(w.pos[2] - z) < 1e-9 and \
                math.dist(w.pos[:2], q[:2]) <= 10 * self.tool.diameter and \
                self.link_ok(w.pos, q, z):
            self.link(q)
        elif (k := self.lead_in(p, z)) is not None:
            # a stay-down feed into the pass at k within the stepover, then the pass: round a
            # closed one back to k, an open one back to its start and then all along it
            here = np.array(w.pos[:2])
            self.link((float(p[k, 0]), float(p[k, 1]), z))
            self.mark(np.array([here, p[k]]))
            route = _lead_route(p, k)
        elif (top := self.safe_at(p[0], z)) <= z + 0.01:
            self.descend(p[0], z, z + 1.0)
        elif (lead := self.cleared_lead_in(p, z)) is not None:
            c, k = lead
            self.descend(c, z, z + 1.0)
            self.link((float(p[k, 0]), float(p[k, 1]), z))
            self.mark(np.array([c, p[k]]))
            self.lead_ins += 1
            route = _lead_route(p, k)
        else:
            slope = self.ramp_slope
            back = None if closed else self.back_ramp(p, z, top, slope)
            if back is not None:
                # down along the pass backwards to its start, then the whole pass
                start, ramp = back
                self.descend(start[:2], start[2], start[2] + 1.0)
                first = len(w.moves)
                route = p
            else:
                self.descend(p[0], top, top + 1.0)
                first = len(w.moves)
                ramp, route = _ramp(p, closed, top - z, slope)
                ramp[:, 2] += z
            for x, y, zz in ramp:
                w.add("feed", x, y, zz)
            self.entry_spans.append([first, len(w.moves)])
            self.ramps += 1
        for x, y in route[1:]:
            w.add("feed", x, y, z)
        self.passes += 1
        self.mark(p)

    # one level
    def level_best(self, z, z_above, in_stock, air, li, nlevels, step_up=False) -> None:
        """Cut level z by :meth:`level`; where its widest cut (:meth:`widest_cut`, every move
        outside the entries) passes ENGAGEMENT_LIMIT stepovers, cut it again with the fronts
        bent towards the walls, at each of WALL_LAYER_STEPS, and if none keeps within the
        limit, again so with the fronts grown by each of STEPOVER_SCALES of the stepover in
        turn (not for a ball), until one does.  The narrowest cut is kept."""
        before = self.snapshot()
        self.level(z, z_above, in_stock, air, li, nlevels, step_up)
        limit = ENGAGEMENT_LIMIT * self.s
        best = self.widest_cut(z)
        if best <= limit:
            self.peel_level(z)
            return
        kept, used = self.snapshot(), None
        # a ball's cut at the level is not the grid's flat swath: closer fronts shave more
        # of the previous passes' cusps (a sloped plane at 2.4 mm: 80 -> 114 moves over)
        scales = (1.0,) if self.tool.shape is ToolShape.BALL else (1.0,) + STEPOVER_SCALES
        for scale in scales:
            for step in WALL_LAYER_STEPS:
                self.restore(self.copied(before))
                self.level(z, z_above, in_stock, air, li, nlevels, step_up, layer=step,
                           scale=scale)
                width = self.widest_cut(z)
                if width < best:
                    best, kept, used = width, self.snapshot(), scale
                if best <= limit:
                    break
            if best <= limit:
                break
        self.restore(kept)
        self.peel_level(z)
        if used is not None:
            self.bent_levels.append(float(z))
        if used is not None and used < 1.0:
            self.narrowed_levels.append([float(z), used])

    def peel_level(self, z: float) -> None:
        """Replay the level's feed moves at z outside its entries in order, as
        :meth:`widest_cut` does, and cut each one wider than PEEL_OVER stepovers by
        :meth:`peel` instead, where that finds a way; then mark the new moves on the run's
        state too.  The entry spans and links after a peeled move shift with it.  For flat
        and bull-nose end mills (a bull-nose's width counts the fillets its corner shaves, as
        :meth:`engaged` measures them); not for a ball, whose passes' cusps the flat
        replay does not hold."""
        if self.tool.shape is ToolShape.BALL:
            return
        over = PEEL_OVER * self.s
        moves = self.writer.moves
        first = self.level_first
        out = list(moves[:max(first, 1)])
        added = np.zeros(len(moves) + 1, int)  # moves added before each old index
        extra = 0
        peeled: list = []

        def visit(i: int, m: Move, ab: tuple | None) -> None:
            nonlocal extra
            added[i] = extra
            way = None
            if ab is not None and self.level_width(*ab) > over:
                way = self.peel(np.array(ab[0]), np.array(ab[1]), z)
            if way is None:
                if ab is not None:
                    self.mark_both(np.array(ab))
                out.append(m)
            else:
                out.extend(Move("feed", float(x), float(y), z) for x, y in way[1:])
                extra += len(way) - 2
                peeled.append(way)

        self.replay(z, visit)
        if not peeled:
            return
        added[len(moves)] = extra
        self.entry_spans = [[a + added[min(a, len(moves))], b + added[min(b, len(moves))]]
                            if b > first else [a, b] for a, b in self.entry_spans]
        self.links = [k + added[min(k, len(moves))] if k >= first else k for k in self.links]
        self.writer.moves = out
        for way in peeled:
            self.mark(way)
        self.peeled_moves += len(peeled)

    def peel(self, a: FloatArray, b: FloatArray, z: float, slack: float | None = None,
             approach: bool = True) -> FloatArray | None:
        """A way (xy points from a to b at level z, in {T <= z}) that cuts the material the
        feed a-b would cut (its swept uncut cells) in feeds each no wider than PEEL_WIDTH
        stepovers (:meth:`engaged`): greedily, each next point the one, on a lattice
        PEEL_LATTICE tool radii apart within R of the feed, whose feed from the last point
        cuts the most of that material within the width, until the feed to b cuts all that
        is left of it within the width; where no step takes any of it within the width, a
        step to the point whose feed to b is the narrowest (:meth:`peel_detour`: a
        bull-nose's corner shaving the fillets beside); and where none is narrower, a way
        (a peel of its own, without this fallback) to a lattice point whose feed to b takes
        what is left within the width (:meth:`peel_approach`: the material left lies where
        the tool reaches it from b's end only, as a sliver along a wall, which a feed along
        the wall takes thin and one across it wide); at most PEEL_STEPS feeds and
        approaches.  The material is that of the replay's ``uncut_level`` grid, where the
        descents of entries did not cut (a ramp cuts less than the level beside its start).
        The region {T <= z} holds the way up to ``slack`` (mm; None: as high as the feed
        a-b rises over it, :meth:`region_slack`, at most PEEL_SLACK_MM: a contour's corner
        may stand some hundredths of a mm out, and its feed ends there).  None where no way
        is found (the replay's grids are then as they were)."""
        R, width = self.R, PEEL_WIDTH * self.s
        feed = np.array([a, b])
        if slack is None:
            slack = min(self.region_slack(a, b, z), PEEL_SLACK_MM)
        zr = z + slack
        task = np.zeros(self.uncut.shape, bool)
        i0, i1, j0, j1 = self.window(self.idx(feed), self.Rc + 2)
        jj, ii = np.meshgrid(np.arange(j0, j1), np.arange(i0, i1))
        cells = self.xy(np.column_stack([jj.ravel(), ii.ravel()]).astype(float))
        near = (_polyline_distance(cells, feed) <= R).reshape(jj.shape)
        task[i0:i1, j0:j1] = near & self.uncut_level[i0:i1, j0:j1]
        # the lattice: points within R of the feed, not at its start
        h = max(min(PEEL_LATTICE * R, 0.25 * math.dist(a, b)), 2.0 * self.cell)
        n = int(math.ceil((math.dist(a, b) + 2 * R) / h)) + 1
        ox = np.arange(n) * h + min(a[0], b[0]) - R
        oy = np.arange(n) * h + min(a[1], b[1]) - R
        lx, ly = np.meshgrid(ox, oy)
        lat = np.column_stack([lx.ravel(), ly.ravel()])
        lat = lat[_polyline_distance(lat, feed) <= R]
        saved = (self.uncut.copy(), self.floor.copy(), self.surface.copy(),
                 self.surface_lo.copy(), self.uncut_level.copy())
        way = [a]
        here = a
        for _ in range(PEEL_STEPS):
            if math.dist(here, b) < 1e-9 and not task.any():
                return np.array(way)  # a step to b itself took the last of it
            w_b, c_b = self.engaged(here[None, :], b[None, :], task,
                                    material=self.uncut_level)
            if w_b[0] <= width and c_b[0] >= task.sum() and self.in_region(here, b, zr) and \
                    math.dist(here, b) >= 1e-9:
                way.append(b)
                self.mark_both(np.array([here, b]))
                return np.array(way)
            cand = lat[np.hypot(*(lat - here).T) > 0.5 * h]
            cand = cand[self.in_region_many(np.broadcast_to(here, cand.shape).copy(), cand, zr)]
            if not len(cand):
                break
            widths, counts = self.engaged(np.broadcast_to(here, cand.shape).copy(), cand, task,
                                          material=self.uncut_level)
            ok = (widths <= width) & (counts > 0)
            if ok.any():
                q = cand[int(np.flatnonzero(ok)[np.argmax(counts[ok])])]
            else:
                # no step takes the task within the width: what makes the feed to b too
                # wide is material outside it (a bull-nose's corner shaving the fillets of
                # the passes beside): a step within the width to the point whose own feed
                # to b is the narrowest, if narrower than the one from here by a cell
                q = self.peel_detour(cand[widths <= width], b, zr, w_b[0])
                if q is None:
                    sub = self.peel_approach(here, b, z, slack, lat, task) if approach \
                        else None
                    if sub is None:
                        break
                    way.extend(sub[1:])
                    here = sub[-1]
                    task &= self.uncut_level
                    continue
            self.mark_both(np.array([here, q]))
            task &= self.uncut_level
            way.append(q)
            here = q
        self.uncut, self.floor, self.surface, self.surface_lo, self.uncut_level = saved
        return None

    def peel_approach(self, here: FloatArray, b: FloatArray, z: float, slack: float,
                      lat: FloatArray, task: np.ndarray) -> FloatArray | None:
        """For :meth:`peel`: a way from here to one of the lattice points ``lat`` whose feed
        to b stays in the region (up to ``slack``) and takes all of ``task`` within the
        width, by a peel of the feed here-q (:meth:`peel` without this fallback), the
        nearest of PEEL_APPROACHES such points first.  The grids hold the way's cut.  None
        if there is none."""
        to_b = np.broadcast_to(b, lat.shape).copy()
        w, c = self.engaged(lat, to_b, task, material=self.uncut_level)
        good = (w <= PEEL_WIDTH * self.s) & (c >= task.sum()) & \
            (np.hypot(*(lat - here).T) > 1e-9)
        good[good] = self.in_region_many(lat[good], to_b[good], z + slack)
        order = np.flatnonzero(good)
        order = order[np.argsort(np.hypot(*(lat[order] - here).T), kind="stable")]
        for k in order[:PEEL_APPROACHES]:
            sub = self.peel(here, lat[k], z, slack, approach=False)
            if sub is not None:
                return sub
        return None

    def region_slack(self, a: FloatArray, b: FloatArray, z: float) -> float:
        """How far (mm, >= 0) the feed a-b at level z rises over the region {T <= z}: the
        most T (bilinear, as :meth:`in_region` samples it) stands over z along it."""
        f = self.along(a, b)
        return max(0.0, float((_bilinear(self.T, f[:, 0], f[:, 1]) - z).max()))

    def peel_detour(self, cand: FloatArray, b: FloatArray, z: float,
                    now: float) -> FloatArray | None:
        """For :meth:`peel`: of the points ``cand`` (reached within the width), the one whose
        feed to b stays in {T <= z} and is the narrowest (:meth:`engaged`, on
        ``uncut_level``), if narrower than ``now`` (the feed to b from where the peel is) by
        a cell; ties to the nearest to b.  None if there is none."""
        if not len(cand):
            return None
        to_b = np.broadcast_to(b, cand.shape).copy()
        fits = self.in_region_many(cand, to_b, z)
        if not fits.any():
            return None
        cand, to_b = cand[fits], to_b[fits]
        w, _ = self.engaged(cand, to_b, material=self.uncut_level)
        k = int(np.lexsort((np.hypot(*(cand - b).T), w))[0])
        return cand[k] if w[k] <= now - self.cell else None

    def mark_level(self, path_xy: FloatArray) -> None:
        """:meth:`mark` on the replay's grid of the material cut at the level only
        (``uncut_level``; the descents of entries cut less)."""
        self.mark(path_xy, only=self.uncut_level)

    def snapshot(self) -> dict:
        """A copy of the run's state (:meth:`copied`)."""
        return self.copied(self.__dict__)

    def copied(self, state: dict) -> dict:
        """A deep copy of a state, the grids and objects that never change shared."""
        shared = [self.grid, self.T, self.Hp, self.tool, self.stock, self.monitor, self.notes,
                  getattr(self, "in_stock", None), getattr(self, "outside_mm", None)]
        writer = state.get("writer")
        if writer is not None:
            shared += writer.moves  # immutable: the copy's list holds the same moves
        return copy.deepcopy(dict(state), {id(v): v for v in shared})

    def restore(self, state: dict) -> None:
        """Back to a :meth:`snapshot` (attributes set since then go too: the first level
        makes the surface estimate)."""
        self.__dict__.clear()
        self.__dict__.update(state)

    def replay_start(self) -> tuple:
        """Set the uncut grid and the surface estimate back to the level's start for a replay
        of its moves: (moves, index of the level's first, which are entries (per index), the
        run's (uncut, floor, surface, surface_lo) to put back after)."""
        moves = self.writer.moves
        first = self.level_first
        entry = np.zeros(len(moves) + 1, bool)
        for a, b in self.entry_spans:
            if b > first:
                entry[max(a, first):b] = True
                # the level moves that follow on the descent's track (the way back over a
                # ramp, a helix's closing turn) clear the wedge it left: entry too, as the
                # job simulation counts them (a peel of one strayed off the track)
                track = np.array([(m.x, m.y) for m in moves[max(a - 1, 0):b]])
                z = moves[b - 1].z
                j = b
                while j < len(moves) and moves[j].kind == "feed" and \
                        abs(moves[j].z - z) < 1e-6:
                    p, q = moves[j - 1], moves[j]
                    probe = np.array([(q.x, q.y), (0.5 * (p.x + q.x), 0.5 * (p.y + q.y))])
                    if float(_polyline_distance(probe, track).max()) > ENTRY_TRACK_MM:
                        break
                    entry[j] = True
                    j += 1
        saved = self.uncut, self.floor, self.surface, self.surface_lo
        self.uncut = self.level_uncut.copy()
        self.floor, self.surface = self.floor.copy(), self.level_surface.copy()
        self.surface_lo = self.level_surface_lo.copy()
        return moves, first, entry, saved

    def replay(self, z: float, visit: Callable) -> None:
        """Replay the level's moves in order from its start (:meth:`replay_start`), with the
        grid ``uncut_level`` of the material cut at the level only beside them (entries'
        descents and ramps cut less than the level: they leave it uncut there), and call
        ``visit(i, move, ab)`` for each move i after the level's first: ab the (a, b) xy ends
        of a feed at z outside the entries, which ``visit`` measures (:meth:`level_width`)
        and marks (:meth:`mark_both`), else None (the replay has marked the other feeds).
        The run's grids are put back after."""
        moves, first, entry, saved = self.replay_start()
        run: list = []  # consecutive feeds not measured, marked at once
        levels: list = []  # whether each of run's feeds lies at the level (not a descent)
        heights: list = []  # the tip's height at each of run's points

        def flush() -> None:
            # (a flat end mill's width counts the uncut grid only: no pieces for it)
            band = math.inf if self.tool.shape is ToolShape.FLAT else DESCENT_BAND_MM
            path, zs, at = _split_descents(np.array(run), np.array(heights), levels, band)
            k = 1
            while k < len(path):
                # the feeds at the level at once; a descent's in pieces each within
                # DESCENT_BAND_MM of height, marked at theirs (as at the level, a ramp's
                # fillets beside it were taken 0.28 mm lower than it left them, and a peel
                # step by them measured 3.71 mm where the simulation found 4.75)
                j = k
                if at[k]:
                    while j + 1 < len(path) and at[j + 1]:
                        j += 1
                    self.mark(path[k - 1:j + 1])
                    for q in range(k, j + 1):  # a descent cuts less than the level
                        self.mark_level(path[q - 1:q + 1])
                else:
                    while j + 1 < len(path) and not at[j + 1] and \
                            np.ptp(zs[k - 1:j + 2]) <= band:
                        j += 1
                    piece, xy = zs[k - 1:j + 1], path[k - 1:j + 1]
                    # a plunge (no move across) leaves what its lowest point does
                    top = piece.min() if np.ptp(xy, axis=0).max() < 1e-9 else piece.max()
                    self.mark(xy, heights=(float(piece.min()), float(top)))
                k = j + 1
            run.clear()
            levels.clear()
            heights.clear()

        self.uncut_level = self.level_uncut.copy()
        try:
            for i in range(max(first, 1), len(moves)):
                p, m = moves[i - 1], moves[i]
                if m.kind != "feed":
                    flush()
                    visit(i, m, None)
                    continue
                a, b = (p.x, p.y), (m.x, m.y)
                at_level = abs(p.z - z) < 1e-6 and abs(m.z - z) < 1e-6
                if not entry[i] and at_level:
                    flush()
                    visit(i, m, (a, b))
                else:
                    if not run or run[-1] != a:
                        flush()
                        run.append(a)
                        levels.append(False)
                        heights.append(p.z)
                    run.append(b)
                    levels.append(at_level)
                    heights.append(m.z)
                    visit(i, m, None)
            flush()
        finally:
            self.uncut, self.floor, self.surface, self.surface_lo = saved
            del self.uncut_level

    def level_width(self, a, b) -> float:
        """Width of cut (mm) of the feed a-b in a replay (:meth:`engaged`), the material that
        of ``uncut_level``: beside an entry's ramp the wedge it left above the level counts
        (the uncut grid takes the ramp's track as cut: a pass beside one measured 0.29 mm
        where the job simulation found 2.95)."""
        return float(self.engaged(np.asarray(a, dtype=float)[None, :2],
                                  np.asarray(b, dtype=float)[None, :2],
                                  material=self.uncut_level)[0][0])

    def mark_both(self, path_xy: FloatArray) -> None:
        """:meth:`mark` and :meth:`mark_level` of a feed at the level in a replay."""
        self.mark(path_xy)
        self.mark_level(path_xy)

    def widest_cut(self, z: float) -> float:
        """Widest cut (mm, :meth:`level_width`) of the level's feed moves at z outside its
        entries, replayed in order (:meth:`replay`) on the level's grids as they were at its
        start (every feed move, entries included, cuts its swath; the wedge an entry's
        descent leaves above the level stays material for the width)."""
        worst = 0.0

        def visit(i: int, m: Move, ab: tuple | None) -> None:
            nonlocal worst
            if ab is not None:
                worst = max(worst, self.level_width(*ab))
                self.mark_both(np.array(ab))

        self.replay(z, visit)
        return worst

    def level(self, z, z_above, in_stock, air, li, nlevels, step_up=False,
              layer: float | None = None, scale: float = 1.0) -> None:
        tip, cell = self.T, self.cell
        if not hasattr(self, "surface"):
            self.surface = np.where(in_stock, self.stock.z_max, -np.inf)
            self.surface_lo = self.surface.copy()
        A = tip <= z + _EPS
        self.uncut = in_stock & (self.Hp < z_above - _EPS)
        self.z = z
        labels, n = label_regions(A)
        Q = A & air
        if step_up:
            # a level above one already cut: only material above z is uncut, and the fronts
            # start from the centres where the tool meets none (the floor cut below)
            self.uncut &= self.surface > z + _EPS
            clear = tip_height(np.where(np.isfinite(self.surface), self.surface, np.nan),
                               cell, self.tool, 0.0, 0.0, -math.inf, self.ztol)
            Q |= A & (clear <= z + _EPS)
        self.level_first = len(self.writer.moves)
        self.level_uncut = self.uncut.copy()
        self.level_surface = self.surface.copy()
        self.level_surface_lo = self.surface_lo.copy()
        floor_rings = self.floor_rings(A & ~air, Q) if step_up else []
        entered = np.zeros(n + 1, bool)  # index -1 -> the last slot stays False
        entered[np.unique(labels[Q])] = True
        self.outside += int(entered.sum())
        self.allowed = A & entered[labels]
        rings: list[_Ring] = []  # the components entered by a helix
        for comp in range(n):
            if entered[comp]:
                continue
            mask = labels == comp
            centre = self.helix(mask, z, z_above)
            if centre is None:
                continue
            entered[comp] = True
            self.allowed |= mask
            cx, cy, rh = centre
            Q |= mask & ((self.X - cx) ** 2 + (self.Y - cy) ** 2 <= rh * rh)
            rings.append(_Ring(mask, (cx, cy), rh,
                               capped_distance(mask, self.s / cell + 2) * cell <= self.s))
        rings += floor_rings
        frac0 = (li + 0.05) / nlevels
        # growing fronts.  On a level at a flat floor T - z is 0 over whole areas, where a
        # front's contour would run through the cells' centres (stairs of cell-long moves
        # across the round fronts of a cylinder stock, each stair a burst of engagement):
        # inside {T <= z} the wall term is taken a cell lower, so that there the distance
        # places the contour.  It still crosses only cell edges from an allowed centre, which
        # GRID_GROWTH_CELLS covers.
        wall = np.where(A, tip - z - cell, tip - z)
        # allowed cells beside a disallowed one: the rim the rings grow towards
        rim = (capped_distance(~A, 2.0) <= 1.0) & A if rings else None
        base = np.full(A.shape, self.s * scale)
        if layer is not None:
            # fronts grow by less near the walls, so that they bend and meet them at a slant
            width = WALL_LAYER_RADII * self.R
            near = np.clip(1.0 - capped_distance(~A, width / cell + 1) * cell / width, 0.0, 1.0)
            base *= 1.0 - (1.0 - layer) * near * near
        k = 0
        while True:
            self.monitor(0.05 + 0.9 * (frac0 + min(k, 50) / 60.0 / nlevels))
            dQ = capped_distance(Q, self.s / cell + 2) * cell
            step = base.copy()
            rho = None
            for ring in rings:
                # a ring round a helix grows by the step that keeps the arc of the tool's
                # edge in the material that of a straight pass (see the module docstring
                # for the rings that near a wall)
                if ring.radius is not None:
                    ds = ring_step(ring.radius, self.R, self.s * scale)
                    near = ~A & ring.near_rim
                    if near.any():
                        # nearest wall, and the farthest point of the component's rim
                        gap = float(dQ[near].min())
                        far = float(dQ[rim & ring.mask].max(initial=math.inf))
                    else:
                        gap = far = math.inf
                    margin = RING_MARGIN_CELLS * cell
                    if far <= ds or gap <= ds - margin:
                        # the ring reaches the wall all round by no more than ds, or it
                        # meets the wall on one side (a long pocket) and grows by the
                        # stepover on
                        ring.radius = None
                    else:
                        if gap <= ds + margin:
                            ds = 0.5 * gap  # not along the wall: half way there first
                        step[ring.mask] = ds
                        ring.radius += ds
                if not ring.exact:
                    # a floor cut below is round only roughly: where its front bends more
                    # than the ring's radius says, it grows by the ring step of the radius
                    # it has there (:func:`front_radius`)
                    if rho is None:
                        rho = front_radius(Q, cell, self.R)
                    step[ring.mask] = np.minimum(step[ring.mask],
                                                 ring_steps(rho[ring.mask], self.R, self.s * scale))
            F = np.maximum(dQ - step, wall)
            F[A & ~self.allowed] = 1.0
            Qn = F <= 0.0
            if Qn.sum() <= Q.sum():
                break
            k += 1
            # the rings still round: their front pieces go on the exact circle
            circles = [r for r in rings if r.radius is not None and r.exact]
            zones = [r.mask for r in rings if not r.exact]  # the floor rings' fronts
            self.cut_contours(F, z, z_above, front=dQ - step, reached=dQ, circles=circles,
                              smooth=np.logical_or.reduce(zones) if zones else None)
            Q = Qn
        # walls
        F = tip - z
        F[A & ~self.allowed] = 1.0
        self.cut_contours(F, z, z_above, front=None)

    def floor_rings(self, A: np.ndarray, Q: np.ndarray) -> list:
        """Rings round the parts of the floor already cut away from the air (a fine level's
        fronts grow outwards from a pocket cut below it), grown by :func:`ring_step` of the
        radius of a disc of the same area, as round a helix but not put on a circle; each
        with the cells of A nearer to it than to the rest of Q as its component."""
        labels, n = label_regions(Q & A)
        out = []
        cell = self.cell
        for comp in range(n):
            mask = labels == comp
            count = int(mask.sum())
            if count < 16:
                continue
            rest = Q & ~mask
            mine = np.sqrt(squared_distance(mask))
            zone = A & (mine < np.sqrt(squared_distance(rest))) if rest.any() else A.copy()
            ci, cj = np.argwhere(mask).mean(axis=0)
            centre = self.xy(np.array([[cj, ci]], dtype=float))[0]
            out.append(_Ring(zone, (float(centre[0]), float(centre[1])),
                             math.sqrt(count / math.pi) * cell,
                             capped_distance(zone, self.s / cell + 2) * cell <= self.s,
                             exact=False))
        return out

    @property
    def X(self):
        xs, ys = self.grid.centres()
        return xs[None, :]

    @property
    def Y(self):
        xs, ys = self.grid.centres()
        return ys[:, None]

    def helix(self, mask, z, z_above):
        """Helical entry into a component not reaching air; (cx, cy, radius) or None."""
        idx = np.argwhere(mask)
        i0, j0 = idx.min(axis=0) - 1
        i1, j1 = idx.max(axis=0) + 2
        i0, j0 = max(i0, 0), max(j0, 0)
        sub = mask[i0:i1, j0:j1]
        d = np.sqrt(squared_distance(~sub))
        d[~sub] = 0.0
        at = int(np.argmax(d))
        ci, cj = divmod(at, sub.shape[1])
        r_fit = (float(d.flat[at]) - 1.5) * self.cell
        r_min = max(2 * self.cell, 0.05 * self.tool.diameter)
        cx, cy = self.xy(np.array([[cj + j0, ci + i0]], dtype=float))[0]
        if r_fit < r_min:
            self.skipped.append((z, float(cx), float(cy), mask.sum() * self.cell ** 2))
            return None
        rh = min(0.4 * self.tool.diameter, 0.8 * self.R, r_fit)
        w = self.writer
        w.retract()
        first = len(w.moves)
        sx, sy = cx + rh, cy
        w.add("rapid", sx, sy, w.clear)
        z_above = self.safe_at(np.array([sx, sy]), z)
        if z_above + 1.0 < w.clear:
            w.add("rapid", sx, sy, z_above + 1.0)
        w.add("feed", sx, sy, z_above)
        dth = _chord_angle(rh, HELIX_CHORD_MM)
        per_turn = 2 * math.pi * rh * self.ramp_slope
        # at least one turn down, so that the helix ends where it began and its last flat
        # turn only trims the wedge the descent left (a shallow drop goes down more gently)
        turns = max((z_above - z) / per_turn, 1.0 if z_above > z + _EPS else 0.0)
        total = 2 * math.pi * (turns + 1.0)
        n = max(8, int(math.ceil(total / dth)))
        th = np.linspace(0.0, total, n + 1)[1:]
        zz = np.maximum(z_above - (z_above - z) * th / max(2 * math.pi * turns, 1e-12), z)
        # clockwise: the material outside stays on the left (climb)
        px, py = cx + rh * np.cos(-th), cy + rh * np.sin(-th)
        for x, y, zh in zip(px, py, zz):
            w.add("feed", x, y, zh)
        self.entry_spans.append([first, len(w.moves)])
        self.helical += 1
        self.passes += 1
        ring = np.column_stack([px, py])
        self.mark(ring)
        # the core within R - rh of the centre
        self.mark(np.array([[cx, cy], [cx, cy]]))
        return float(cx), float(cy), rh

    def cut_contours(self, F, z, z_above, front, reached=None, circles=(),
                     smooth: np.ndarray | None = None) -> None:
        """Cut the contour F = 0 where the tool meets uncut material.

        With ``front`` (distance to the cleared centres less the step, mm) and ``reached``
        (that distance) the contour is a new front: its front pieces are cut first (climb),
        then the pieces on the walls {T = z} that the front newly reached, each from its end
        nearer the new front towards the old one, so that the strip beside it is already cut.
        Without, the contour is the level's final wall pass.  ``circles``: (component mask,
        the rings round a helix still round (:class:`_Ring`); front pieces of a ring within a
        cell of its circle (the grid's contour of it) are put on it (:meth:`on_circles`) and
        cut in chords within RING_CHORD_MM of it.  ``smooth``: the floor rings' zones
        (:meth:`emit`).
        """
        lines = marching_squares(F)
        if not lines:
            return
        # distance (cells) to uncut material, only around the contour (values beyond the
        # window are not needed: a vertex's window reaches past the tool radius)
        every = np.concatenate(lines)
        i0, i1, j0, j1 = self.window(every, self.Rc + 4)
        du = np.full(F.shape, 1e9)
        sub = self.uncut[i0:i1, j0:j1]
        if sub.any():
            du[i0:i1, j0:j1] = capped_distance(sub, self.Rc + 2)
        back = int(2 * self.Rc) + 2
        fronts, walls = [], []
        for line in lines:
            dv = _bilinear(du, line[:, 0], line[:, 1])
            cuts = dv < self.Rc - 1.25
            if not cuts.any():
                continue
            closed = len(line) > 2 and bool(np.allclose(line[0], line[-1]))
            free, clear = dv >= self.Rc - 1.25, dv >= self.Rc + 1.0
            if front is None:
                for piece in _stretches(line, cuts, free, clear, closed, back):
                    ends = _bilinear(du, piece[[0, -1], 0], piece[[0, -1], 1]) >= self.Rc + 1.0
                    fronts.append(piece[::-1] if ends[1] and not ends[0] else piece)
                continue
            tz = _bilinear(self.T - z, line[:, 0], line[:, 1])
            fr = _bilinear(front, line[:, 0], line[:, 1])
            # front where the front's distance decides the contour; on a flat floor both are
            # about 0 and rounding would cut the front into slivers, each with its own ramp
            is_front = fr >= tz - 0.25 * self.cell
            for piece in _stretches(line, cuts & is_front, free, clear, closed, back):
                # climb, unless only the end is out of the material (saves a ramp)
                ends = _bilinear(du, piece[[0, -1], 0], piece[[0, -1], 1]) >= self.Rc + 1.0
                fronts.append(piece[::-1] if ends[1] and not ends[0] else piece)
            # wall pieces away from the old boundary (distance to it above 1.5 cells)
            new = _bilinear(reached, line[:, 0], line[:, 1]) > 1.5 * self.cell
            for piece in _stretches(line, cuts & ~is_front & new, free, clear, closed, back):
                d = _bilinear(front, piece[:, 0], piece[:, 1])
                closed_piece = len(piece) > 2 and bool(np.allclose(piece[0], piece[-1]))
                walls.append(piece if closed_piece or d[0] >= d[-1] else piece[::-1])
        if circles and fronts:
            fronts, circles = self.on_circles(fronts, circles)
        self.emit(fronts, z, z_above, circles, field=F, smooth=smooth)
        self.emit(self.deep_walls(walls), z, z_above, field=F)

    def on_circles(self, pieces: list, rings: list) -> tuple:
        """The front pieces (fractional indices) with those of each ring put on its circle,
        and the circles ((centre (x, y), radius) mm).  The circle's radius is the one the
        ring's contour has: the median distance from the centre of its points within three
        cells of the ring's radius (the grid's distance fronts fall short of it by up to
        about 0.1 mm a ring); its points within a cell of it are moved onto it radially."""
        every = np.concatenate(pieces)
        ny, nx = self.T.shape
        inside = [ring.mask[np.clip(np.rint(every[:, 1]).astype(int), 0, ny - 1),
                            np.clip(np.rint(every[:, 0]).astype(int), 0, nx - 1)]
                  for ring in rings]
        starts = np.cumsum([0] + [len(p) for p in pieces])
        circles = []
        for ring, mine in zip(rings, inside):
            c = self.idx(np.array([ring.centre]))[0]
            rel = every - c
            dist = np.hypot(rel[:, 0], rel[:, 1])
            near = (np.abs(dist * self.cell - ring.radius) <= 3 * self.cell) & mine
            if not near.any():
                continue
            rc = float(np.median(dist[near]))
            snap = (np.abs(dist - rc) <= 1.0) & mine & (dist > 0)
            every[snap] = c + rel[snap] * (rc / dist[snap])[:, None]
            circles.append((ring.centre, rc * self.cell))
        return [every[a:b] for a, b in zip(starts[:-1], starts[1:])], circles

    def deep_walls(self, walls: list) -> list:
        """The wall pieces (fractional indices) along which the material still uncut after the
        front reaches deeper than WALL_SLIVER of the stepover into the tool's disk; the thinner
        slivers are left to the level's last pass, which follows the whole wall."""
        if not walls:
            return walls
        i0, i1, j0, j1 = self.window(np.concatenate(walls), self.Rc + 4)
        sub = self.uncut[i0:i1, j0:j1]
        if not sub.any():
            return []
        du = capped_distance(sub, self.Rc + 2)
        keep = []
        for piece in walls:
            dv = _bilinear(du, piece[:, 0] - j0, piece[:, 1] - i0)
            if (self.Rc - float(dv.min())) * self.cell >= WALL_SLIVER * self.s:
                keep.append(piece)
        return keep

    def emit(self, stretches: list, z: float, z_above: float, circles=(),
             field: FloatArray | None = None, smooth: np.ndarray | None = None) -> None:
        """Simplify the stretches (fractional indices) within cell/4, and with ``field`` (the
        F whose contour they are) straighten them inwards (:meth:`inner_chords`), and cut
        them, nearest next first; an open stretch is cut in its own direction, a closed one
        from its vertex nearest the tool.  A chord between two points on one of the
        ``circles`` (see :meth:`on_circles`, (centre, radius) mm) is cut as an arc in chords
        within RING_CHORD_MM of it.  With ``smooth`` (cells: the floor rings' zones) a
        stretch wholly inside it is cut as a smooth curve (:meth:`smoothed`) instead of
        straightened."""
        if not stretches:
            return
        pts = [self.xy(p) for p in stretches]
        starts = np.cumsum([0] + [len(p) for p in pts])
        allp = np.concatenate(pts)
        keep = simplify(np.column_stack([allp, np.full(len(allp), z)]), starts,
                        0.25 * self.cell, "planar")
        paths = [allp[a:b][keep[a:b]] for a, b in zip(starts[:-1], starts[1:])]
        if field is not None:
            ny, nx = self.T.shape
            for i, st in enumerate(stretches):
                jj = np.clip(np.rint(st[:, 0]).astype(int), 0, nx - 1)
                ii = np.clip(np.rint(st[:, 1]).astype(int), 0, ny - 1)
                if smooth is not None and smooth[ii, jj].all():
                    paths[i] = self.smoothed(paths[i], z)  # a floor ring's front
                else:
                    paths[i] = self.inner_chords(paths[i], field)
        if circles:
            paths = [_arc_fill(q, circles, RING_CHORD_MM) for q in paths]
        # a stretch that simplification left as one point (two equal ones) would only plunge
        paths = [q for q in paths if len(q) > 1 and np.hypot(*np.diff(q, axis=0).T).sum() > 1e-9]
        remaining = list(range(len(paths)))
        while remaining:
            here = np.array(self.writer.pos[:2]) if self.writer.pos is not None else \
                paths[remaining[0]][0]
            best, best_d, best_i = None, math.inf, 0
            for r in remaining:
                p = paths[r]
                if len(p) > 2 and np.allclose(p[0], p[-1]):
                    dd = np.hypot(*(p - here).T)
                    i = int(np.argmin(dd))
                    d0 = float(dd[i])
                else:
                    i, d0 = 0, math.dist(here, p[0])
                if d0 < best_d:
                    best, best_d, best_i = r, d0, i
            remaining.remove(best)
            p = paths[best]
            if len(p) > 2 and np.allclose(p[0], p[-1]) and best_i:
                p = np.concatenate([p[best_i:-1], p[:best_i + 1]])
            self.cut_path(p, z, z_above)

    def smoothed(self, path: FloatArray, z: float) -> FloatArray:
        """A floor ring's front (xy) as a smooth curve in short chords: SMOOTH_ROUNDS rounds
        of Chaikin's corner cutting (1974; the limit is the quadratic B-spline of the
        vertices, inside their polygon's corners), simplified within RING_CHORD_MM; the path
        itself where that leaves {T <= z}.  A chord of a curved front sweeps across more of
        the material ahead of its end than the tangent move the ring step assumes (3 mm
        chords on a 17 mm ring: about 0.5 mm wider)."""
        if len(path) < 3:
            return path
        closed = bool(np.allclose(path[0], path[-1]))
        q = path[:-1] if closed else path
        for _ in range(SMOOTH_ROUNDS):
            nxt = np.roll(q, -1, axis=0)
            cut = np.empty((2 * len(q), 2))
            cut[0::2] = 0.75 * q + 0.25 * nxt
            cut[1::2] = 0.25 * q + 0.75 * nxt
            q = cut if closed else np.vstack([path[:1], cut[1:-2], path[-1:]])
        q = np.vstack([q, q[:1]]) if closed else q
        keep = simplify(np.column_stack([q, np.full(len(q), z)]), np.array([0, len(q)]),
                        RING_CHORD_MM, "planar")
        q = q[keep]
        return q if self.path_in_region(q, z) else path

    def inner_chords(self, path: FloatArray, field: FloatArray) -> FloatArray:
        """Path (xy) with the vertices dropped that a chord between two others passes on the
        inner side of, within STAIR_CELLS cells: the chord stays where ``field`` (the F of
        the contour: distance to the cleared centres less the step, or the wall term) is at
        most 0, so it cuts no wider than the contour and keeps as far from the walls, and its
        whole swath (:meth:`engaged_width`) is no wider than the stepover or the widest of the
        moves it replaces.  The contour of a tip height that rises in one-cell plateaus along
        a shallow wall runs in stairs of a cell; each stair's jog is a short move sideways
        into the material (4.5 mm wide at a 3.2 mm stepover on a 3 degree slope)."""
        n = len(path)
        if n < 3:
            return path
        if not np.allclose(path[0], path[-1]) and n > 4:
            # an open path keeps its first and last moves: where it ends at a wall the last
            # one is the head-on cut, which a long move running into it would only widen
            # (the job simulation measures the whole swath of a move)
            return np.vstack([path[:1], self._chords_within(path[1:-1], field), path[-1:]])
        return self._chords_within(path, field)

    def _chords_within(self, path: FloatArray, field: FloatArray) -> FloatArray:
        """:meth:`inner_chords` of the whole path, its ends kept."""
        n = len(path)
        if n < 3:
            return path
        limit = STAIR_CELLS * self.cell
        out = [path[0]]
        i = 0
        while i < n - 1:
            j = i + 1
            while j + 1 < n:
                a, b = path[i], path[j + 1]
                ab = b - a
                L2 = float(ab @ ab)
                if L2 < 1e-18:
                    break
                mid = path[i + 1:j + 1]
                t = np.clip((mid - a) @ ab / L2, 0.0, 1.0)
                dev = np.hypot(*(mid - a - t[:, None] * ab).T)
                if dev.max() > limit:
                    break
                f = self.along(a, b)
                if np.any(_bilinear(field, f[:, 0], f[:, 1]) > 1e-3):
                    break
                j += 1
            # a chord that would sweep wider than the moves it replaces (a run along a wall
            # taken into the head-on cut at its end) gives back vertices
            while j > i + 1 and self.engaged_width(path[i], path[j]) > max(
                    self.s, *(self.engaged_width(path[k], path[k + 1])
                              for k in range(i, j))):
                j -= 1
            out.append(path[j])
            i = j
        return np.array(out)

    def report_leftover(self) -> None:
        cell = self.cell
        if self.skipped:
            # one entry per place (levels of one pocket lie within a tool radius)
            groups: list = []
            for z, x, y, _ in self.skipped:
                for g in groups:
                    if math.hypot(g[0] - x, g[1] - y) <= self.R:
                        g[2], g[3] = max(g[2], z), min(g[3], z)
                        break
                else:
                    groups.append([x, y, z, z])
            parts = ", ".join(
                f"({x:.1f}, {y:.1f}) at Z {hi:.2f}" + (f" to {lo:.2f}" if lo < hi else "")
                for x, y, hi, lo in groups[:6])
            more = f" and {len(groups) - 6} more" if len(groups) > 6 else ""
            self.notes.append(
                f"{len(groups)} pocket(s) where no helical entry fits the tool were skipped, "
                f"left for a smaller tool: {parts}{more}")
        # material more than a stepdown above the part, away from every wall that explains it
        gap = self.ar + GRID_GROWTH_CELLS * cell + max(2 * cell, 0.45 * self.R)
        base = np.where(np.isfinite(self.Hp), self.Hp, self.stock.z_min)
        near = disk_max(base, gap / cell)
        left = (self.floor - base > self.stepdown + 0.1) & (near < self.floor - self.stepdown) \
            & self.in_stock
        if not left.any():
            return
        labels, n = label_regions(left)
        counts = np.bincount(labels[left], minlength=n)
        xs, ys = self.grid.centres()
        area_min = 0.05 * math.pi * self.R ** 2
        for comp in np.flatnonzero(counts * cell * cell >= area_min).tolist():
            m = labels == comp
            iy, ix = np.nonzero(m)
            self.notes.append(
                f"material the tool cannot reach left for a smaller tool: about "
                f"{counts[comp] * cell * cell:.1f} mm^2 around x={xs[ix].mean():.1f}, "
                f"y={ys[iy].mean():.1f} mm, up to {float(self.floor[m].max()):.2f} mm high "
                f"over a part down to {float(base[m].min()):.2f} mm")


def ring_step(rho: float, R: float, s: float) -> float:
    """Step (mm) from a round front of radius ``rho`` (tool centres, mm) cleared all round to
    the next one, so that a tool of radius R on it meets the material over the same arc as
    on a straight pass at stepover s.

    On a straight pass the tool's edge is in the material over the angle phi0 = acos(1 - s/R)
    from the normal to the pass; the simulation's width of cut, the extent of the engaged
    cells across the travel, is R (1 - cos phi0) = s.  Round a cleared disc of radius
    rho + R the edge of a tool at radius rho' = rho + ds is in the material where
    rho'^2 + 2 rho' R cos(phi) + R^2 >= (rho + R)^2: over a wider arc than phi0 if ds = s
    (a 10 mm mill 4 mm out of a 4 mm helix: 96 degrees instead of 78, a width of 5.5 mm).
    The ds that gives phi0 solves rho'^2 + 2 c R rho' - ((rho + R)^2 - R^2) = 0 with
    c = 1 - s/R; it tends to s as rho grows."""
    return float(min(max(float(_ring_growth(rho, R, s)), 0.0), s))


def _ring_growth(rho, R: float, s: float):
    """rho' - rho of :func:`ring_step` (unclipped), for a radius or an array of them."""
    c = 1.0 - s / R
    return -c * R + np.sqrt(c * c * R * R + (rho + R) ** 2 - R * R) - rho


def ring_steps(rho: FloatArray, R: float, s: float) -> FloatArray:
    """:func:`ring_step` of each radius (mm; inf: a straight front), at least
    MIN_FRONT_STEP of the stepover."""
    r = np.minimum(np.asarray(rho, dtype=float), 1e6)
    return np.clip(_ring_growth(r, R, s), MIN_FRONT_STEP * s, s)


def front_radius(Q: np.ndarray, cell: float, R: float) -> FloatArray:
    """Radius (mm) of the boundary of the cleared centres Q nearest each cell (inf where it
    is straight or bends away): 1 / (the Laplacian of Q's signed distance, smoothed by two
    box means reaching FRONT_SMOOTH_RADII tool radii to each side) less the cell's distance,
    at least two cells.  The signed distance is smooth across the boundary, and the Laplacian
    of a distance is the curvature of its level sets, 1 / (rho + d) at a distance d from a
    round boundary of radius rho."""
    out = np.sqrt(squared_distance(Q)) * cell
    sd = out - np.sqrt(squared_distance(~Q)) * cell
    h = max(2, int(round(FRONT_SMOOTH_RADII * R / cell)))
    sm = _box_mean(_box_mean(sd, h), h)
    lap = np.zeros_like(sm)
    lap[1:-1, 1:-1] = (sm[1:-1, 2:] + sm[1:-1, :-2] + sm[2:, 1:-1] + sm[:-2, 1:-1]
                       - 4.0 * sm[1:-1, 1:-1]) / (cell * cell)
    with np.errstate(divide="ignore"):
        return np.where(lap > 1e-9, np.maximum(1.0 / lap - out, 2.0 * cell), np.inf)


def _box_mean(a: FloatArray, h: int) -> FloatArray:
    """Mean of ``a`` over the (2h + 1)^2 window round each cell (edges replicated)."""
    p = np.pad(a, h, mode="edge")
    c = np.zeros((p.shape[0] + 1, p.shape[1] + 1))
    np.cumsum(np.cumsum(p, axis=0), axis=1, out=c[1:, 1:])
    n = 2 * h + 1
    return (c[n:, n:] - c[:-n, n:] - c[n:, :-n] + c[:-n, :-n]) / (n * n)


def _split_descents(path: FloatArray, zs: FloatArray, at_level: list,
                    band: float) -> tuple:
    """A polyline (xy ``path``, tip heights ``zs``; ``at_level[k]`` whether the feed to point
    k lies at the level) with every other feed but a plunge cut into pieces each descending
    at most ``band`` (mm): (path, zs, at_level) with the points added."""
    if len(path) < 2:
        return path, zs, list(at_level)
    P, Z, A = [path[0]], [zs[0]], [False]
    for k in range(1, len(path)):
        plunge = float(np.abs(path[k] - path[k - 1]).max()) < 1e-9  # its lowest point rules
        n = 1 if at_level[k] or plunge else max(1, int(math.ceil(abs(zs[k] - zs[k - 1]) / band)))
        for t in np.arange(1, n + 1) / n:
            P.append(path[k - 1] + t * (path[k] - path[k - 1]))
            Z.append(zs[k - 1] + t * (zs[k] - zs[k - 1]))
            A.append(bool(at_level[k]))
    return np.array(P), np.array(Z), A


def _lead_route(p: FloatArray, k: int) -> FloatArray:
    """The route that cuts pass p (xy) from its vertex k, where a lead-in joins it: round a
    closed pass back to k, along an open one back to its start and then all along it."""
    closed = len(p) > 2 and bool(np.allclose(p[0], p[-1]))
    return np.vstack([p[k:-1], p[:k + 1]]) if closed else np.vstack([p[k::-1], p[1:]])


def _chord_angle(radius: float, sag: float) -> float:
    """Angle (radians) of the chords of a circle of ``radius`` that lie within ``sag`` of it
    (mm)."""
    return 2.0 * math.acos(max(1.0 - sag / radius, -1.0))


def _arc_fill(path: FloatArray, circles: list, sag: float) -> FloatArray:
    """The path (xy, mm) with each chord whose two ends lie on one of ``circles`` ((centre,
    radius), mm) replaced by the shorter arc between them in chords within ``sag`` of it."""
    if len(path) < 2:
        return path
    out = [path[0]]
    for a, b in zip(path[:-1], path[1:]):
        for (cx, cy), r in circles:
            ra, rb = math.hypot(a[0] - cx, a[1] - cy), math.hypot(b[0] - cx, b[1] - cy)
            if abs(ra - r) > 1e-6 * max(r, 1.0) or abs(rb - r) > 1e-6 * max(r, 1.0):
                continue
            ta, tb = math.atan2(a[1] - cy, a[0] - cx), math.atan2(b[1] - cy, b[0] - cx)
            d = (tb - ta + math.pi) % (2 * math.pi) - math.pi
            step = _chord_angle(r, sag)
            n = int(math.ceil(abs(d) / step)) if step > 0 else 1
            for t in np.arange(1, n) / n:
                out.append(np.array([cx + r * math.cos(ta + t * d), cy + r * math.sin(ta + t * d)]))
            break
        out.append(b)
    return np.array(out)


def _ramp(p: FloatArray, closed: bool, drop: float, slope: float) -> tuple:
    """Points (x, y, height above the level) descending ``drop`` (mm) at ``slope``
    (dz/dxy) along pass p from its start (round a closed pass, back and forth along an open
    one), and the route (xy) at the level from where the ramp ends through the whole pass."""
    need = drop / slope
    n = len(p)
    if n < 2 or need <= 0 or not np.hypot(*np.diff(p, axis=0).T).sum() > 1e-12:
        return np.empty((0, 3)), p  # nothing to ramp along (the walk would never end)
    out = []
    length = 0.0
    i, step = 0, 1
    while True:
        j = i + step
        if closed and j == n:
            i, j = 0, 1
        elif not closed and not 0 <= j < n:
            step = -step
            j = i + step
        seg = float(np.hypot(*(p[j] - p[i])))
        if length + seg >= need:
            t = (need - length) / seg if seg > 0 else 1.0
            end = p[i] + t * (p[j] - p[i])
            out.append((end[0], end[1], 0.0))
            break
        length += seg
        out.append((p[j][0], p[j][1], drop - length * slope))
        i = j
    ramp = np.array(out, dtype=float)
    end = ramp[-1, :2]
    if closed:
        # from the end point forwards round the loop back to it (segment i -> j, j = i + 1)
        route = np.vstack([end, p[j:-1], p[:j], end])
    else:
        # back along the pass to its start, then the whole pass
        k = min(i, j)
        route = np.vstack([end, p[k::-1], p[1:]])
    return ramp, route


def _stretches(line: FloatArray, cuts: np.ndarray, free: np.ndarray, clear: np.ndarray,
               closed: bool, back: int) -> list:
    """Runs of cutting vertices, each grown by one vertex at both ends and further over
    ``free`` vertices (where the tool cuts nothing) to one where the tool's disk is
    ``clear`` (at most ``back`` vertices), so that a pass can start and end out of the
    material; a closed line that cuts everywhere stays closed."""
    if closed:
        c = cuts[:-1]
        m = len(c)
        grown = c | np.roll(c, 1) | np.roll(c, -1)
        if grown.all():
            return [line]
        first = int(np.flatnonzero(~grown)[0])
        body = np.roll(line[:-1], -first, axis=0)
        c = np.roll(c, -first)
        cl = np.roll(clear[:-1], -first)
        fr = np.roll(free[:-1], -first)
    else:
        body, c, cl, fr, m = line, cuts, clear, free, len(line)
    runs = []
    i = 0
    while i < m:
        if not c[i]:
            i += 1
            continue
        j = i
        while j + 1 < m and c[j + 1]:
            j += 1
        runs.append([i, j])
        i = j + 1
    taken = np.zeros(m, bool)
    for r in runs:
        taken[r[0]:r[1] + 1] = True
    out = []
    for i, j in runs:
        a = max(i - 1, 0) if i > 0 and not taken[i - 1] else i
        while a > 0 and a > i - back and not taken[a - 1] and fr[a - 1] and not cl[a]:
            a -= 1
        b = min(j + 1, m - 1) if j + 1 < m and not taken[j + 1] else j
        while b < m - 1 and b < j + back and not taken[b + 1] and fr[b + 1] and not cl[b]:
            b += 1
        taken[a:b + 1] = True
        out.append(body[a:b + 1])
    return [o for o in out if len(o) >= 2]
