# SPDX-License-Identifier: LGPL-2.1-or-later
"""A whole program simulated from a stock block, with tool changes and per-tool engagement.

The Z-map is that of :mod:`.simulate` (one dexel per cell, its top at the cell centre, each
move cut to the exact lower envelope of the tool swept along it, arcs as chords), but the
moves are cut one after the other, each with the tool the program loaded last (M6, see
``Program.tool``), starting from the block ``stock`` = (x0, x1, y0, y1, z0, z1) mm or a
vertical cylinder (:class:`.stock.CylinderStock`, CAM's "CreateCylinder" stock).  Cells
whose centre lies outside the block's XY (the cylinder's circle) have no material (their
height is z0) and are never counted; the height never goes below z0 (no material there to
remove).

Definitions, per linearised move (a line, or one chord of an arc); "removed" at a cell means
the height drop that move causes there, and a cell counts as *engaged* when that drop exceeds
the depth threshold ``max(ENGAGEMENT_DEPTH_MM, cell / 10)``:

* axial engagement = the largest drop (mm) at the cells whose centres lie within
  R - max(cell, RIM_FRACTION x D) of the move's XY path (at least R / 2): how deep the tool
  cut into material.  A column in the outer RIM_FRACTION of the diameter that the rim shaves
  beside a wall, up to the whole height of the levels above (a level's wall contour a little
  inside the one above), is a side cut under RIM_FRACTION x D wide, a light load at any depth
  the flutes reach: it counts for the cutting length, not for the depth.
* radial engagement = the extent of the engaged cells across the direction of travel (in XY,
  perpendicular to it: max - min of their centres' cross coordinate, plus one cell for the
  cells' own width), clipped to the tool diameter.  A full-width slot gives the diameter, a
  pass beside a cleared region at stepover s gives s (both within a cell).  For a move
  without XY travel it is the larger XY extent of the engaged cells.  With a bull-nose or a
  ball only the engaged cells whose material stood above the tool's corner count (the
  corner radius, or the ball's radius, above the tip; at most half the move's axial
  engagement: :func:`corner_height`), if any does: material lower than that is the fillet or
  cusp the previous pass's corner left, which a pass beside it shaves (counted, a 10 mm
  bull-nose of 2 mm corner radius at a 4 mm stepover measured 5.8 mm).
* cutting length = feed moves with at least one engaged cell; air length = the other feed
  moves (mm).
* entry = a feed move whose program move descends by more than ENTRY_DESCENT_MM (plunge,
  ramp, helix), and the level feed moves after such a run, up to the next descent, lift or
  rapid, that lie on its XY path (end and midpoint within ENTRY_REACH_MM of it, plus the
  chord tolerance of arcs): the closing turn of a helix, the way back along a ramp, or the
  end of a pass round which a ramp descended, which clear the wedge the descent left
  (:func:`entry_moves`).  A move off the path, even inside the descent's XY box, is no
  entry.  Entries are counted and their largest engagement reported apart; the radial
  maximum and the means leave them out (a roughing strategy bounds engagement outside its
  entries only).  Means are weighted by the moves' lengths, over cutting non-entry moves.
* material removal rate = removed volume / time (feed), over windows of consecutive cutting
  feed moves of the same tool at least one tool radius long (a shorter run: the whole run),
  so that short moves do not spike it; the largest over the tool's moves, mm^3/min.
* collision = a rapid that removes more than COLLISION_TOLERANCE_MM somewhere: its source
  line, deepest drop (mm) and the cell where it happened; rapids cut the stock like feeds.

Cost: each move is cut in windows of its tool's reach (moves longer than twice the radius,
or 32 cells, are cut in pieces so that a diagonal move does not cost its whole bounding
box); envelopes are computed in batches as in :mod:`.simulate`, the merge per move.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .. import kernels
from ..errors import ParameterError
from ..geometry.netio import MAX_COORDINATE_MM
from ..kernels import job_kernels, zmap_kernels
from ..program.gcode import Program, Segments, linearise, simulation_chord_tolerance
from ..program.tooltable import check_program_tools
from ..typing import FloatArray
from .simulate import (
    BATCH_CELLS,
    COLLISION_TOLERANCE_MM,
    RIM_MM,
    Collision,
    Grid,
    Simulation,
    Tool,
    ToolShape,
    _envelope,
    _merge,
    _round_up,
    corner_height,
)
from .stock import CylinderStock, Stock

#: A program move that descends more than this (mm) is an entry (plunge, ramp, helix).
ENTRY_DESCENT_MM = 1e-3
#: Slack (mm) of an entry's footprint, the path of its descent (plus the chord tolerance
#: when arcs are linearised: a closing turn's chords and the helix's cut their circle apart).
ENTRY_REACH_MM = 0.02
#: Smallest height drop (mm) that engages a cell (the threshold is at least a tenth of a cell).
ENGAGEMENT_DEPTH_MM = 0.01
#: The outer band of the tool's disk (times its diameter) whose cuts count for the cutting
#: length but not for the depth of cut: light side cuts, such as slivers beside a wall.
RIM_FRACTION = 0.05
#: Pieces a move is cut in are at most this many cells long (or two tool radii if longer).
PIECE_CELLS = 32
#: Whether a Python float added to a numpy float32 scalar stays float32 (numpy 2's rule):
#: the compiled engine rounds the radial measure's corner height as numpy does.
_WEAK_SCALARS = isinstance(1.0 + np.float32(1.0), np.float32)


def entry_moves(program: Program, segments: Segments | None = None,
                slack: float = ENTRY_REACH_MM) -> np.ndarray:
    """Per program move: True for the moves of an entry (see the module docstring).
    ``segments`` (the program linearised) give the path of arcs (helices) by their chords;
    without them, by their end points.  A level move after a descending run, before the next
    descent, lift or rapid, is part of the entry if its end and its midpoint lie within
    ``slack`` (mm) of the run's XY path: it goes back over the ramp, round the helix or
    round the rest of a closed pass to the ramp's start, clearing the wedge the descent
    left."""
    feed = np.asarray(program.kind) != 0
    start = np.asarray(program.start, dtype=float)
    end = np.asarray(program.end, dtype=float)
    out = feed & (end[:, 2] < start[:, 2] - ENTRY_DESCENT_MM)
    n = len(out)
    runs = np.flatnonzero(np.diff(np.concatenate([[0], out.view(np.int8), [0]])))
    for a, b in zip(runs[::2].tolist(), runs[1::2].tolist()):
        if segments is not None:
            lo, hi = np.searchsorted(segments.move, [a, b])
            p0, p1 = segments.start[lo:hi, :2], segments.end[lo:hi, :2]
        else:
            p0, p1 = start[a:b, :2], end[a:b, :2]
        level = end[b - 1, 2]
        j = b
        while j < n and feed[j] and not out[j] and abs(end[j, 2] - level) <= ENTRY_DESCENT_MM:
            j += 1
        if j > b:
            # the level moves that follow, up to the next descent, lift or rapid: those
            # on the run's path are the way back or the closing lap of a closed pass
            mid = 0.5 * (start[b:j, :2] + end[b:j, :2])
            probe = np.concatenate([end[b:j, :2], mid])
            far = _distance_to_segments(probe, p0, p1).reshape(2, -1).max(axis=0) > slack
            out[b:j] = ~far
    return out


def _distance_to_segments(q: FloatArray, p0: FloatArray, p1: FloatArray) -> FloatArray:
    """Distance (mm) of each point q (k, 2) to the nearest of the segments p0 -> p1 (m, 2)."""
    d = p1 - p0
    dd = np.einsum("ij,ij->i", d, d)
    rel = q[:, None, :] - p0[None, :, :]
    t = np.einsum("kij,ij->ki", rel, d) / np.where(dd > 0, dd, 1.0)
    t = np.minimum(np.maximum(t, 0.0), 1.0)
    gap = rel - t[:, :, None] * d[None, :, :]
    return np.sqrt(np.einsum("kij,kij->ki", gap, gap).min(axis=1))


def engagement_threshold(cell: float) -> float:
    """Height drop (mm) above which a cell counts as engaged on a grid of ``cell`` mm."""
    return max(ENGAGEMENT_DEPTH_MM, cell / 10.0)


@dataclass(frozen=True)
class ToolReport:
    """What one tool (by number) did over the program; lengths mm, volumes mm^3."""

    number: int
    tool: Tool
    removed_volume_mm3: float
    cutting_length_mm: float
    air_length_mm: float
    rapid_length_mm: float
    radial_engagement_max_mm: float
    radial_engagement_mean_mm: float
    axial_engagement_max_mm: float
    axial_engagement_mean_mm: float
    max_radial_line: int | None
    max_radial_move: int | None
    material_removal_rate_max_mm3_per_min: float
    entries: int
    entry_radial_engagement_max_mm: float
    entry_axial_engagement_max_mm: float
    collisions: tuple[Collision, ...]

    def to_dict(self) -> dict:
        """JSON-ready figures."""
        def r(v: float) -> float | None:
            return None if v is None or not math.isfinite(v) else round(float(v), 6)

        return {
            "tool": {"shape": self.tool.shape.value, "diameter_mm": self.tool.diameter,
                     "corner_radius_mm": self.tool.corner_radius},
            "removed_volume_mm3": r(self.removed_volume_mm3),
            "cutting_length_mm": r(self.cutting_length_mm),
            "air_length_mm": r(self.air_length_mm),
            "rapid_length_mm": r(self.rapid_length_mm),
            "radial_engagement_max_mm": r(self.radial_engagement_max_mm),
            "radial_engagement_mean_mm": r(self.radial_engagement_mean_mm),
            "axial_engagement_max_mm": r(self.axial_engagement_max_mm),
            "axial_engagement_mean_mm": r(self.axial_engagement_mean_mm),
            "max_radial_line": self.max_radial_line,
            "max_radial_move": self.max_radial_move,
            "material_removal_rate_max_mm3_per_min": r(
                self.material_removal_rate_max_mm3_per_min),
            "entries": self.entries,
            "entry_radial_engagement_max_mm": r(self.entry_radial_engagement_max_mm),
            "entry_axial_engagement_max_mm": r(self.entry_axial_engagement_max_mm),
            "rapid_collisions": [c.to_dict() for c in self.collisions],
        }


@dataclass(frozen=True)
class JobSimulation:
    """The machined block and the per-tool figures.

    ``height`` (ny, nx) mm is the final Z-map (z0 where the block has no material),
    ``stock`` the block (x0, x1, y0, y1, z0, z1) mm or, for a cylinder (``cylinder``), its
    bounding box, ``in_stock`` the cells inside the block's XY (the cylinder's circle),
    ``snapshots[n]`` the Z-map after the last
    move of tool n.  Per linearised move (``segments``): ``tool`` number, ``volume`` removed
    (mm^3), ``axial`` and ``radial`` engagement (mm), ``entry``, and ``rate``, the largest
    material removal rate (mm^3/min) of the windows ending in it (NaN for a move that cuts
    nothing; see the module docstring), and ``deepest`` (n, 2), the XY (mm) of the cell centre
    where a cutting feed move cut deepest (NaN for the others).
    """

    grid: Grid
    stock: tuple[float, float, float, float, float, float]
    height: FloatArray
    in_stock: np.ndarray
    tools: dict[int, ToolReport]
    snapshots: dict[int, FloatArray]
    segments: Segments
    tool: np.ndarray
    volume: FloatArray
    axial: FloatArray
    radial: FloatArray
    entry: np.ndarray
    collisions: tuple[Collision, ...]
    unsimulated_rapids: int = 0
    threshold_mm: float = field(default=ENGAGEMENT_DEPTH_MM)
    cylinder: CylinderStock | None = None
    rate: FloatArray | None = field(default=None, compare=False)
    deepest: FloatArray | None = field(default=None, compare=False)

    def removed_volume(self) -> float:
        """Volume cut from the block (mm^3), all tools."""
        return float(self.volume.sum())

    def simulation(self) -> Simulation:
        """The final Z-map as a :class:`.simulate.Simulation` (top = the block's top)."""
        return Simulation(self.grid, self.height, float(self.stock[5]), self.collisions)

    def metrics(self) -> dict:
        """JSON-ready per-tool figures, keyed by the tool number as text."""
        return {str(n): report.to_dict() for n, report in sorted(self.tools.items())}


def check_stock(stock, argument: str = "stock") -> tuple[float, float, float, float, float,
                                                          float]:
    """(x0, x1, y0, y1, z0, z1) mm with x0 < x1, y0 < y1, z0 < z1, all finite except z0 may be
    -inf (a block without bottom); else ParameterError naming ``argument``."""
    try:
        values = tuple(float(v) for v in stock)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{argument} must be six numbers x0,x1,y0,y1,z0,z1 (mm), got "
                             f"{stock!r}") from None
    if len(values) != 6:
        raise ParameterError(f"{argument} must be six numbers x0,x1,y0,y1,z0,z1 (mm), got "
                             f"{len(values)}")
    x0, x1, y0, y1, z0, z1 = values
    finite = all(abs(v) <= MAX_COORDINATE_MM for v in (x0, x1, y0, y1, z1)) \
        and (z0 == -math.inf or abs(z0) <= MAX_COORDINATE_MM)
    if not finite or not (x0 < x1 and y0 < y1 and z0 < z1):
        raise ParameterError(f"{argument} must lie within MAX_COORDINATE_MM="
                             f"{MAX_COORDINATE_MM:g} mm with x0 < x1, y0 < y1, z0 < z1 (mm), "
                             f"got {','.join(f'{v:g}' for v in values)}")
    return values


def check_stock_form(stock, argument: str = "stock") -> tuple[float, float, float, float, float,
                                                               float] | CylinderStock:
    """The stock as the job simulation takes it: a :class:`.stock.CylinderStock` as it is, a
    :class:`.stock.Stock` block or six numbers as :func:`check_stock`'s (x0, x1, y0, y1, z0,
    z1) mm; else ParameterError naming ``argument``."""
    if isinstance(stock, CylinderStock):
        if not all(abs(v) <= MAX_COORDINATE_MM for v in stock.bounds):
            raise ParameterError(f"{argument} must lie within MAX_COORDINATE_MM="
                                 f"{MAX_COORDINATE_MM:g} mm, got the {stock.describe()}")
        return stock
    if isinstance(stock, Stock):
        stock = stock.bounds
    return check_stock(stock, argument)


def initial_height(grid: Grid, stock) -> tuple[FloatArray, np.ndarray]:
    """(Z-map (ny, nx) float32 mm, cells with material) of the uncut ``stock`` (any form
    :func:`check_stock_form` takes): its top z1 over the cells whose centre lies in its XY
    footprint (a block's rectangle, a cylinder's circle, rims included), z0 (the bottom,
    -inf for a block without one) elsewhere."""
    form = check_stock_form(stock)
    xs, ys = grid.centres()
    if isinstance(form, CylinderStock):
        in_stock = form.contains_xy(xs[None, :], ys[:, None])
        z0, z1 = form.z_min, form.z_max
    else:
        x0, x1, y0, y1, z0, z1 = form
        in_stock = ((xs[None, :] >= x0) & (xs[None, :] <= x1)
                    & (ys[:, None] >= y0) & (ys[:, None] <= y1))
    height = np.where(in_stock, np.float32(z1), np.float32(z0) if math.isfinite(z0)
                      else np.float32(-np.inf)).astype(np.float32)
    return height, in_stock


def simulate_job(program: Program, tools: dict[int, Tool], grid: Grid, stock,
                 feed_default: float | None = None,
                 progress: Callable[[float], None] | None = None,
                 chord_tolerance: float | None = None,
                 threshold: float | None = None) -> JobSimulation:
    """Cut the block ``stock`` = (x0, x1, y0, y1, z0, z1) mm (or a :class:`.stock.Stock`,
    or a vertical :class:`.stock.CylinderStock`) on ``grid`` with ``program``, each move with
    the tool ``tools[program.tool[move]]`` (see the module docstring).

    ``feed_default`` (mm/min) stands for feed moves without a feed in the removal rate.
    ``progress(fraction)`` is called about every 50 ms and at the end (1.0); it may raise to
    abandon the run.
    A tool change to a number ``tools`` lacks raises ParameterError naming it and its line;
    rapids before the first tool change are not simulated if there is no tool 0.
    """
    form = check_stock_form(stock)
    cylinder = form if isinstance(form, CylinderStock) else None
    x0, x1, y0, y1, z0, z1 = form.bounds if cylinder is not None else form
    if feed_default is not None and not (math.isfinite(feed_default) and feed_default > 0):
        raise ParameterError(f"default feed must be positive (mm/min), got {feed_default!r}")
    check_program_tools(program, tools)
    thr = engagement_threshold(grid.cell) if threshold is None else float(threshold)
    if not (math.isfinite(thr) and thr > 0):
        raise ParameterError(f"engagement threshold must be positive (mm), got {threshold!r}")
    tol = simulation_chord_tolerance(grid.cell) if chord_tolerance is None else chord_tolerance
    seg = linearise(program, tol)
    n = len(seg)
    height, in_stock = initial_height(grid, form)
    number = program.tool[seg.move] if n else np.zeros(0, np.intp)
    rapid = np.asarray(seg.rapid, bool)
    entry = entry_moves(program, seg, ENTRY_REACH_MM + tol)[seg.move] & ~rapid if n \
        else np.zeros(0, bool)
    numbers = np.array(sorted(tools), dtype=np.intp)
    known = np.isin(number, numbers)
    radius = np.zeros(n)
    for t in np.unique(number[known]).tolist():
        radius[number == t] = tools[t].radius
    volume = np.zeros(n)
    axial = np.zeros(n)
    radial = np.zeros(n)
    hit: list[tuple[int, int, Collision]] = []  # (segment, tool, collision)
    snapshots: dict[int, FloatArray] = {}
    state = _Cutter(height, grid, z0, thr)
    low = np.minimum(seg.start[:, 2], seg.end[:, 2])
    live = known & (low < z1)
    pieces = _pieces(seg, radius, grid, live)
    state.piece_volume = np.zeros(len(pieces.segment))
    state.deepest = np.full((n, 2), np.nan)
    state.drop = np.zeros(n)
    last_report = time.monotonic()
    order = np.arange(n)
    # runs of one tool, cut in chunks of about BATCH_CELLS window cells
    run_bounds = np.flatnonzero(np.diff(number)) + 1 if n else np.zeros(0, np.intp)
    for run in np.split(order, run_bounds) if n else []:
        t = int(number[run[0]])
        if t not in tools:
            continue
        tool = tools[t]
        for chunk in _chunks(run, pieces):
            state.cut_chunk(chunk, seg, pieces, tool, rapid, live, volume, axial, radial, hit, t)
            if progress is not None and time.monotonic() - last_report > 0.05:
                progress(float(chunk[-1] + 1) / max(n, 1))
                last_report = time.monotonic()
        snapshots[t] = height.astype(float)
    if progress is not None:
        progress(1.0)
    lengths = np.linalg.norm(seg.end - seg.start, axis=1)
    feed = program.feed[seg.move].astype(float) if n else np.zeros(0)
    if feed_default is not None:
        feed = np.where(np.isfinite(feed) & (feed > 0), feed, feed_default)
    reports = {}
    rates = np.full(n, np.nan)
    for t in sorted(set(number.tolist()) & set(tools)):
        cutting = (number == t) & ~rapid & (state.drop > thr)
        _removal_rates(cutting, pieces, feed, state.piece_volume, tools[t].radius, rates)
        reports[t] = _report(t, tools[t], number == t, seg, rapid, entry, lengths, volume,
                             axial, radial, thr, [c for _, tt, c in hit if tt == t], rates,
                             state.drop)
    collisions = _merge([c for _, _, c in hit])
    return JobSimulation(
        grid=grid, stock=(x0, x1, y0, y1, z0, z1), height=height.astype(float),
        in_stock=in_stock, tools=reports, snapshots=snapshots, segments=seg, tool=number,
        volume=volume, axial=axial, radial=radial, entry=entry, collisions=collisions,
        unsimulated_rapids=int(np.sum(rapid & ~known)), threshold_mm=thr, cylinder=cylinder,
        rate=rates, deepest=state.deepest)


@dataclass
class _Pieces:
    """Pieces of the live segments, in order: segment index, ends and window."""

    segment: np.ndarray
    start: FloatArray
    end: FloatArray
    ix0: np.ndarray
    iy0: np.ndarray
    h: np.ndarray
    w: np.ndarray
    first: np.ndarray  # per segment: index of its first piece (count in ``count``)
    count: np.ndarray


def _pieces(seg: Segments, radius: FloatArray, grid: Grid, live: np.ndarray) -> _Pieces:
    """Each live segment cut into pieces of XY length at most max(2 R, PIECE_CELLS cells), with
    the padded window of cells each piece's tool can reach (empty windows dropped)."""
    n = len(seg)
    d = np.hypot(*(seg.end[:, :2] - seg.start[:, :2]).T) if n else np.zeros(0)
    step = np.maximum(2.0 * radius, PIECE_CELLS * grid.cell)
    count = np.where(live, np.maximum(1, np.ceil(d / step - 1e-9)), 0).astype(np.intp)
    owner = np.repeat(np.arange(n), count)
    first = np.cumsum(count) - count
    k = np.arange(len(owner)) - first[owner]
    f0 = (k / count[owner])[:, None]
    f1 = ((k + 1) / count[owner])[:, None]
    delta = seg.end[owner] - seg.start[owner]
    p0 = seg.start[owner] + f0 * delta
    p1 = seg.start[owner] + f1 * delta
    last = first + count - 1
    p0[first[count > 0]] = seg.start[count > 0]
    p1[last[count > 0]] = seg.end[count > 0]
    r = radius[owner][:, None]
    lo = np.minimum(p0[:, :2], p1[:, :2]) - r
    hi = np.maximum(p0[:, :2], p1[:, :2]) + r
    origin = np.array([grid.x0, grid.y0])
    a = np.maximum(np.ceil((lo - origin) / grid.cell - 0.5).astype(np.int64), 0)
    b = np.minimum(np.floor((hi - origin) / grid.cell - 0.5).astype(np.int64),
                   np.array([grid.nx - 1, grid.ny - 1]))
    size = b - a + 1
    keep = np.all(size > 0, axis=1)
    w = np.minimum(_round_up(size[:, 0]), grid.nx)
    h = np.minimum(_round_up(size[:, 1]), grid.ny)
    ix0 = np.minimum(a[:, 0], grid.nx - w)
    iy0 = np.minimum(a[:, 1], grid.ny - h)
    owner, p0, p1, ix0, iy0, h, w = (v[keep] for v in (owner, p0, p1, ix0, iy0, h, w))
    count = np.bincount(owner, minlength=n).astype(np.intp)
    first = np.cumsum(count) - count
    return _Pieces(owner, p0, p1, ix0, iy0, h, w, first, count)


def _chunks(run: np.ndarray, pieces: _Pieces):
    """Consecutive segments of ``run`` whose pieces hold about BATCH_CELLS cells together."""
    has = pieces.count[run] > 0
    if not np.any(has):
        return
    run = run[has]
    area = np.concatenate([[0], np.cumsum(pieces.h * pieces.w)])
    per_segment = area[pieces.first[run] + pieces.count[run]] - area[pieces.first[run]]
    cumulative = np.cumsum(per_segment)
    start = 0
    while start < len(run):
        base = cumulative[start - 1] if start else 0.0
        stop = int(np.searchsorted(cumulative, base + BATCH_CELLS, side="right"))
        stop = max(stop, start + 1)
        yield run[start:stop]
        start = stop


class _Cutter:
    """The Z-map being cut, and the per-segment measurement."""

    def __init__(self, height: FloatArray, grid: Grid, z0: float, threshold: float) -> None:
        self.height = height
        self.grid = grid
        self.z0 = np.float32(z0) if math.isfinite(z0) else None
        self.threshold = np.float32(threshold)
        self.piece_volume = np.zeros(0)
        self.deepest = np.zeros((0, 2))
        self.drop = np.zeros(0)  # per segment: the deepest drop at any cell (mm)

    def envelopes(self, index: np.ndarray, pieces: _Pieces, tool: Tool) -> dict[int, FloatArray]:
        """Envelope (H, W) of each piece in ``index``, batched by window shape."""
        out: dict[int, FloatArray] = {}
        key = pieces.h[index] * (self.grid.nx + 1) + pieces.w[index]
        order = np.argsort(key, kind="stable")
        bounds = np.flatnonzero(np.diff(key[order])) + 1
        for group in np.split(order, bounds):
            sel = index[group]
            H, W = int(pieces.h[sel[0]]), int(pieces.w[sel[0]])
            env = _envelope(pieces.start[sel], pieces.end[sel], pieces.ix0[sel],
                            pieces.iy0[sel], H, W, tool, self.grid)
            for k, p in enumerate(sel.tolist()):
                out[p] = env[k]
        return out

    def cut_chunk(self, chunk: np.ndarray, seg: Segments, pieces: _Pieces, tool: Tool,
                  rapid: np.ndarray, live: np.ndarray, volume: FloatArray, axial: FloatArray,
                  radial: FloatArray, hit: list, number: int) -> None:
        index = np.concatenate([np.arange(pieces.first[s], pieces.first[s] + pieces.count[s])
                                for s in chunk.tolist()])
        if kernels.use_numba():
            try:
                self._cut_chunk_compiled(chunk, index, seg, pieces, tool, rapid, volume, axial,
                                         radial, hit, number)
                return
            except kernels.KernelUnavailable:
                pass
        envs = self.envelopes(index, pieces, tool)
        for s in chunk.tolist():
            ks = range(int(pieces.first[s]), int(pieces.first[s] + pieces.count[s]))
            self.cut_segment(s, ks, envs, seg, pieces, tool, bool(rapid[s]), volume, axial,
                             radial, hit, number)

    def _cut_chunk_compiled(self, chunk: np.ndarray, index: np.ndarray, seg: Segments,
                            pieces: _Pieces, tool: Tool, rapid: np.ndarray, volume: FloatArray,
                            axial: FloatArray, radial: FloatArray, hit: list,
                            number: int) -> None:
        """:meth:`cut_chunk` by the compiled :func:`.job_kernels.cut_chunk`, with the numpy
        engine's per-piece envelope constants and per-shape ``wide`` choice (see
        :func:`.simulate._envelope`), so that heights and figures are bit-identical."""
        grid = self.grid
        ix0, iy0, hb, wb = (np.ascontiguousarray(v[index], dtype=np.int64)
                            for v in (pieces.ix0, pieces.iy0, pieces.h, pieces.w))
        shape = {ToolShape.BALL: zmap_kernels.BALL, ToolShape.FLAT: zmap_kernels.FLAT,
                 ToolShape.BULLNOSE: zmap_kernels.BULLNOSE}[tool.shape]
        envelope = job_kernels.envelope_arrays(
            pieces.start[index], pieces.end[index], ix0, iy0, hb, wb, hb * (grid.nx + 1) + wb,
            tool.radius, tool.corner_radius, shape, grid.x0, grid.y0, grid.cell)
        count = np.ascontiguousarray(pieces.count[chunk], dtype=np.int64)
        first = np.cumsum(count) - count
        start = np.ascontiguousarray(seg.start[chunk], dtype=float)
        end = np.ascontiguousarray(seg.end[chunk], dtype=float)
        length = np.array([math.hypot(a, b) for a, b in (end[:, :2] - start[:, :2]).tolist()])
        is_rapid = np.ascontiguousarray(rapid[chunk], dtype=bool)
        reach = max(tool.radius - max(grid.cell, RIM_FRACTION * tool.diameter),
                    0.5 * tool.radius)
        k = len(chunk)
        drop, deep, across, volume_out = (np.zeros(k) for _ in range(4))
        xy = np.zeros((k, 2))
        piece_volume = np.zeros(len(index))
        job_kernels.cut_chunk(
            self.height, float(grid.x0), float(grid.y0), float(grid.cell),
            np.float32(0.0 if self.z0 is None else self.z0), self.z0 is not None,
            self.threshold, ix0, iy0, hb, wb, *envelope, int(shape),
            zmap_kernels.constants(tool.radius, tool.corner_radius, RIM_MM), first, count,
            start, end, length, is_rapid, reach * reach,
            float(corner_height(tool, math.inf)), float(tool.diameter), grid.cell ** 2,
            _WEAK_SCALARS, drop, deep, across, xy, piece_volume, volume_out)
        self.drop[chunk] = drop
        axial[chunk] = deep
        radial[chunk] = across
        volume[chunk] = volume_out
        self.piece_volume[index] = piece_volume
        cutting = (drop > self.threshold) & ~is_rapid
        self.deepest[chunk[cutting]] = xy[cutting]
        for j in np.flatnonzero(is_rapid & (drop > COLLISION_TOLERANCE_MM)).tolist():
            s = int(chunk[j])
            hit.append((s, number, Collision(int(seg.line[s]), float(drop[j]),
                                             float(xy[j, 0]), float(xy[j, 1]))))

    def cut_segment(self, s: int, ks: range, envs: dict, seg: Segments, pieces: _Pieces,
                    tool: Tool, is_rapid: bool, volume: FloatArray, axial: FloatArray,
                    radial: FloatArray, hit: list, number: int) -> None:
        grid = self.grid
        height = self.height
        # the drops measured against the Z-map before the segment (pieces overlap), then cut
        drops = []
        for k in ks:
            y, x = int(pieces.iy0[k]), int(pieces.ix0[k])
            H, W = int(pieces.h[k]), int(pieces.w[k])
            view = height[y:y + H, x:x + W]
            new = np.fmin(view, envs[k])
            if self.z0 is not None:
                np.maximum(new, self.z0, out=new)
            drops.append((view, new, view - new, x, y))
        at = [int(np.argmax(d)) for _, _, d, _, _ in drops]
        k_max = max(range(len(drops)), key=lambda k: float(drops[k][2].flat[at[k]]))
        _, _, d, x, y = drops[k_max]
        deepest = float(d.flat[at[k_max]])
        cy, cx = divmod(at[k_max], d.shape[1])
        px, py = grid.x0 + (x + cx + 0.5) * grid.cell, grid.y0 + (y + cy + 0.5) * grid.cell
        self.drop[s] = deepest
        axial[s] = deepest
        if deepest > self.threshold and not is_rapid:
            axial[s] = self._inner_depth(drops, seg.start[s], seg.end[s], tool)
            radial[s] = self._radial(drops, seg.start[s], seg.end[s], tool, deepest)
            self.deepest[s] = (px, py)
        if is_rapid and deepest > COLLISION_TOLERANCE_MM:
            hit.append((s, number, Collision(int(seg.line[s]), deepest, px, py)))
        area = grid.cell ** 2
        if len(drops) == 1:
            view, new, d, _, _ = drops[0]
            if deepest > 0:
                self.piece_volume[ks[0]] = float(d.sum(dtype=np.float64)) * area
                view[...] = new
        else:
            for k, (view, new, _, _, _) in zip(ks, drops):
                after = np.fmin(view, new)
                self.piece_volume[k] = float((view - after).sum(dtype=np.float64)) * area
                view[...] = after
        volume[s] = float(self.piece_volume[ks[0]:ks[-1] + 1].sum())

    def _inner_depth(self, drops: list, p0: FloatArray, p1: FloatArray, tool: Tool) -> float:
        """The largest drop (mm) at the engaged cells whose centres lie within R - max(cell,
        RIM_FRACTION x D) (at least R / 2) of the segment's XY path: the depth of cut, without
        the slivers the rim shaves (see the module docstring)."""
        grid = self.grid
        reach = max(tool.radius - max(grid.cell, RIM_FRACTION * tool.diameter),
                    0.5 * tool.radius)
        a = np.asarray(p0[:2], dtype=float)
        d = np.asarray(p1[:2], dtype=float) - a
        dd = float(d[0] * d[0] + d[1] * d[1])
        best = 0.0
        for _, _, drop, x, y in drops:
            iy, ix = np.nonzero(drop > self.threshold)
            if not len(ix):
                continue
            q = np.column_stack([grid.x0 + (ix + x + 0.5) * grid.cell - a[0],
                                 grid.y0 + (iy + y + 0.5) * grid.cell - a[1]])
            # elementwise (no BLAS dot, which may fuse): the compiled engine's arithmetic
            t = (np.clip((q[:, 0] * d[0] + q[:, 1] * d[1]) / dd, 0.0, 1.0) if dd > 0
                 else np.zeros(len(q)))
            gx = q[:, 0] - t * d[0]
            gy = q[:, 1] - t * d[1]
            inner = gx * gx + gy * gy <= reach * reach
            if np.any(inner):
                best = max(best, float(drop[iy[inner], ix[inner]].max()))
        return best

    def _radial(self, drops: list, p0: FloatArray, p1: FloatArray, tool: Tool,
                deepest: float) -> float:
        """Extent of the engaged cells across the segment's XY direction, plus a cell, at most
        the tool diameter (mm).  Only cells whose material stood higher than
        :func:`corner_height` above the tip count, if any does: lower material under a
        bull-nose's or a ball's corner is the fillet or cusp a previous pass left."""
        grid = self.grid
        d = p1[:2] - p0[:2]
        L = math.hypot(d[0], d[1])
        above = (min(float(p0[2]), float(p1[2])) + float(corner_height(tool, deepest))
                 + self.threshold)
        for upper in (True, False):  # the cells above the corner, else all
            lo, hi = math.inf, -math.inf
            lo2, hi2 = math.inf, -math.inf
            for before, _, drop, x, y in drops:
                engaged = drop > self.threshold
                if upper:
                    engaged &= before > above
                iy, ix = np.nonzero(engaged)
                if not len(ix):
                    continue
                cx = grid.x0 + (ix + x + 0.5) * grid.cell - p0[0]
                cy = grid.y0 + (iy + y + 0.5) * grid.cell - p0[1]
                if L > 1e-9:
                    q = (cy * d[0] - cx * d[1]) / L
                    lo, hi = min(lo, float(q.min())), max(hi, float(q.max()))
                else:
                    lo, hi = min(lo, float(cx.min())), max(hi, float(cx.max()))
                    lo2, hi2 = min(lo2, float(cy.min())), max(hi2, float(cy.max()))
            if hi >= lo:
                extent = hi - lo if L > 1e-9 else max(hi - lo, hi2 - lo2)
                return min(tool.diameter, extent + grid.cell)
        return 0.0


def _report(number: int, tool: Tool, mine: np.ndarray, seg: Segments, rapid: np.ndarray,
            entry: np.ndarray, lengths: FloatArray, volume: FloatArray,
            axial: FloatArray, radial: FloatArray, threshold: float,
            collisions: list[Collision], rates: FloatArray, drop: FloatArray) -> ToolReport:
    feeds = mine & ~rapid
    cutting = feeds & (drop > threshold)
    normal = cutting & ~entry
    entries = cutting & entry
    weight = lengths[normal]
    total = float(weight.sum())

    def mean(v: FloatArray) -> float:
        if not np.any(normal):
            return 0.0
        return float(np.sum(v[normal] * weight) / total) if total > 0 else float(v[normal].mean())

    at = int(np.flatnonzero(normal)[np.argmax(radial[normal])]) if np.any(normal) else None
    return ToolReport(
        number=number, tool=tool,
        removed_volume_mm3=float(volume[mine].sum()),
        cutting_length_mm=float(lengths[cutting].sum()),
        air_length_mm=float(lengths[feeds & ~cutting].sum()),
        rapid_length_mm=float(lengths[mine & rapid].sum()),
        radial_engagement_max_mm=float(radial[normal].max()) if np.any(normal) else 0.0,
        radial_engagement_mean_mm=mean(radial),
        axial_engagement_max_mm=float(axial[cutting].max()) if np.any(cutting) else 0.0,
        axial_engagement_mean_mm=mean(axial),
        max_radial_line=None if at is None else int(seg.line[at]),
        max_radial_move=None if at is None else int(seg.move[at]),
        material_removal_rate_max_mm3_per_min=float(np.nanmax(rates[cutting]))
        if np.any(cutting & np.isfinite(rates)) else math.nan,
        entries=int(len(np.unique(seg.move[entries]))),
        entry_radial_engagement_max_mm=float(radial[entries].max()) if np.any(entries) else 0.0,
        entry_axial_engagement_max_mm=float(axial[entries].max()) if np.any(entries) else 0.0,
        collisions=_merge(collisions),
    )


def _removal_rates(cutting: np.ndarray, pieces: _Pieces, feed: FloatArray,
                   piece_volume: FloatArray, radius: float, out: FloatArray) -> None:
    """Into ``out`` (per segment): the largest removed volume / feed time (mm^3/min) over the
    windows that end in one of the segment's pieces, windows of consecutive pieces of
    ``cutting`` segments at least ``radius`` long (a run shorter than that: one window, the
    whole run, which ends in its last piece).  A piece's volume is what it removed beyond the
    pieces before it, so long moves are resolved too."""
    idx = np.flatnonzero(cutting[pieces.segment])
    if not len(idx):
        return
    owner = pieces.segment[idx]
    # runs: consecutive pieces of the same or consecutive segments
    new_run = np.ones(len(idx), bool)
    new_run[1:] = (np.diff(idx) > 1) | (np.diff(owner) > 1)
    run_id = np.cumsum(new_run) - 1
    run_first = np.flatnonzero(new_run)
    length = np.linalg.norm(pieces.end[idx] - pieces.start[idx], axis=1)
    minutes = length / feed[owner]
    c_len = np.concatenate([[0.0], np.cumsum(length)])
    c_vol = np.concatenate([[0.0], np.cumsum(piece_volume[idx])])
    c_min = np.concatenate([[0.0], np.cumsum(minutes)])
    end = np.arange(1, len(idx) + 1)
    start = np.searchsorted(c_len, c_len[end] - radius, side="right") - 1
    begin = run_first[run_id]
    full = start >= begin  # a window of at least one radius inside the run
    run_last = np.append(run_first[1:], len(idx)) - 1
    short_run = (c_len[run_last + 1] - c_len[run_first]) < radius
    # a run shorter than the radius: one window, the whole run
    whole = short_run[run_id] & (end - 1 == run_last[run_id])
    start = np.where(full, start, begin)
    use = full | whole
    with np.errstate(divide="ignore", invalid="ignore"):
        rate = (c_vol[end] - c_vol[start]) / (c_min[end] - c_min[start])
    use &= np.isfinite(rate)
    np.fmax.at(out, owner[use], rate[use])
