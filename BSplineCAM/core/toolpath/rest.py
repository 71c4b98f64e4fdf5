# SPDX-License-Identifier: LGPL-2.1-or-later
"""Rest finishing from the roughed stock (issue 12): ball-end passes at decreasing offsets.

A roughing program leaves the part under an allowance plus terraces: on shallow ground the
flat end mill's Z levels leave steps up to the step-down.  A single finishing pass would cut
those in one go.  :func:`generate_rest` removes them first with raster passes of the same
ball on the part's offset surfaces o_m = m * limit (m = M-1 .. 1, M = ceil(max excess /
limit)), each clipped to where the stock still stands above that offset, so that every
pass, and the finishing pass after them, cuts at most about ``limit`` below what the one
before left.

Geometry: a ball of radius R whose tip sits o above the offset-o surface is the ball of
radius R + o lowered by o, so the tip height of offset o is ``cl_height(R + o)(xy) + o``
(inverse tool offset, Kim & Chu).  ``cl_height(R)`` on the Z-map gives the excess
e = stock - CL_0, and CL_o >= CL_0 + o (the ball of radius R + o centred o above the ball
of radius R contains it), so the tip of offset o is in material only where e > o.

"""

from __future__ import annotations

import math
import time
from typing import Any, Callable

import numpy as np

from ..errors import ParameterError
from ..program.gcode import Segments
from ..simulation.simulate import Grid, Tool, simulate
from ..typing import FloatArray
from .chords import ChordSamples, lift_chords, sample_chords
from .common import (
    MAX_TOOL_DIAMETER,
    MIN_TOOL_DIAMETER,
    TOLERANCE_RANGE,
    CancelFn,
    Monitor,
    ProgressFn,
    Toolpath,
    ToolpathStats,
    check_angle,
    check_finite,
    check_positive,
    check_range,
    simplify,
)
from .dropcutter import DropCutter
from .faces_raster import FaceQuery

#: cl_height(radius) -> heights(xy): ball tip heights (mm, NaN off the part) at (n, 2) points.
HeightFn = Callable[[FloatArray], FloatArray]
ClHeightFn = Callable[[float], HeightFn]
#: Longest stay-down link between rest passes, in tool radii; longer gaps retract.
STAY_DOWN_LINK = 2.0
#: Non-cutting stretch inside a pass (in tool radii) beyond which the pass is split in two.
SPLIT_GAP = 2.0
#: Samples handled per chunk of the "does the ball cut the stock here" test.
CUT_CHUNK = 256


class OffsetHeights:
    """Tip heights and gradients of a ball of radius R on the part's offset surface at o (mm).

    ``heights(xy) = cl_height(R + o)(xy) + o``.  The gradient comes from the height function's
    own ``heights_and_slopes`` when it has one (a DropCutter does, by the envelope theorem),
    else from central differences; the chords use it only to place their exact checks.
    """

    def __init__(self, cl_height: ClHeightFn, radius: float, offset: float):
        self.radius = float(radius)
        self.offset = float(offset)
        self.fn = cl_height(self.radius + self.offset)
        self.step = 1e-4 * self.radius

    def heights(self, xy: FloatArray) -> FloatArray:
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        if len(q) == 0:
            return np.zeros(0)
        z = np.asarray(self.fn(q), dtype=float).reshape(-1)
        return z + self.offset

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        if len(q) == 0:
            return np.zeros(0), np.zeros((0, 2))
        both = getattr(self.fn, "heights_and_slopes", None)
        if both is not None:
            z, grad = both(q)
            return np.asarray(z, float) + self.offset, np.asarray(grad, float)
        h = self.step
        shifts = np.array([[0, 0], [h, 0], [-h, 0], [0, h], [0, -h]])
        z = self.heights((q[None, :, :] + shifts[:, None, :]).reshape(-1, 2)).reshape(5, -1)
        grad = np.column_stack([(z[1] - z[2]) / (2 * h), (z[3] - z[4]) / (2 * h)])
        grad[~np.isfinite(z[0])] = np.nan
        return z[0], grad


class _DropCutterHeights:
    """Callable tip heights of one DropCutter, with ``heights_and_slopes``."""

    def __init__(self, dc: Any):
        self.dc = dc

    def __call__(self, xy: FloatArray) -> FloatArray:
        return self.dc.heights(xy)[0]

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        return self.dc.heights_and_slopes(xy)


#: Certification of the rest passes' drop-cutter over faces (mm): the branch and bound stops
#: once within this of the maximum, and this is added back, so a rest pass lies at most this
#: above its offset surface and never below it (the passes clear terraces, not the part).
REST_CERTIFY = 0.005


class _FaceHeights:
    """Callable tip heights of a ball over a FaceSet, with ``heights_and_slopes``: upper
    bounds within ``REST_CERTIFY`` of the true tip height."""

    def __init__(self, faceset: Any, radius: float):
        self.query = FaceQuery(faceset, radius)

    def _heights(self, xy: FloatArray):
        tip, face, u, v, _ = self.query.faceset.drop_ball(xy, self.query.radius,
                                                         certify=REST_CERTIFY)
        return tip + REST_CERTIFY, face, u, v

    def __call__(self, xy: FloatArray) -> FloatArray:
        return self._heights(xy)[0]

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        tip, face, u, v = self._heights(xy)
        grad = self.query.slopes(xy, face, u, v)
        grad[~np.isfinite(tip)] = np.nan
        return tip, grad


def net_cl_height(surface: Any) -> ClHeightFn:
    """``cl_height`` of a core Surface: the exact ball drop-cutter (:class:`DropCutter`),
    one per radius (mm)."""
    cache: dict = {}

    def make(radius: float) -> HeightFn:
        key = round(float(radius), 12)
        if key not in cache:
            cache[key] = _DropCutterHeights(DropCutter(surface, float(radius)))
        return cache[key]

    return make


def faceset_cl_height(faceset: Any) -> ClHeightFn:
    """``cl_height`` of a FaceSet (trimmed faces): :meth:`FaceSet.drop_ball` per radius (mm)."""
    return lambda radius: _FaceHeights(faceset, float(radius))


# -- Z-map helpers ----------------------------------------------------------------------------
def _stock_arrays(stock: Any) -> tuple[Any, FloatArray]:
    """(Grid, heights (ny, nx)) from a Simulation or a (grid, heights) pair."""
    if hasattr(stock, "grid") and hasattr(stock, "height"):
        grid, height = stock.grid, stock.height
    else:
        try:
            grid, height = stock
        except (TypeError, ValueError):
            raise ParameterError(
                "stock must be a Simulation or a (Grid, heights (ny, nx) mm) pair, got "
                f"{type(stock).__name__}") from None
    if not all(hasattr(grid, a) for a in ("x0", "y0", "cell", "nx", "ny")):
        raise ParameterError(f"stock grid must be a simulate.Grid, got {type(grid).__name__}")
    height = np.asarray(height, dtype=float)
    if height.shape != (grid.ny, grid.nx):
        raise ParameterError(
            f"stock heights must have the grid's shape ({grid.ny}, {grid.nx}), got "
            f"{height.shape}")
    return grid, height


def _refine_stock(grid: Any, height: FloatArray, cell: float) -> tuple[Any, FloatArray]:
    """The Z-map on cells of at most ``cell`` mm; a fine cell takes the highest of the coarse
    cell centres around it (never less material than the Z-map holds)."""
    k = max(1, math.ceil(grid.cell / cell - 1e-9))
    if k == 1:
        return grid, height
    fine = Grid(grid.x0, grid.y0, grid.cell / k, grid.nx * k, grid.ny * k)
    pad = np.pad(height, 1, mode="edge")
    xs, ys = fine.centres()
    # fractional coarse index of each fine centre, and the two coarse centres around it
    fx = (xs - grid.x0) / grid.cell - 0.5
    fy = (ys - grid.y0) / grid.cell - 0.5
    ix = np.clip(np.floor(fx).astype(int), -1, grid.nx - 1) + 1
    iy = np.clip(np.floor(fy).astype(int), -1, grid.ny - 1) + 1
    out = np.maximum(np.maximum(pad[np.ix_(iy, ix)], pad[np.ix_(iy, ix + 1)]),
                     np.maximum(pad[np.ix_(iy + 1, ix)], pad[np.ix_(iy + 1, ix + 1)]))
    return fine, out


def _dilate(mask: np.ndarray, radius_cells: float) -> np.ndarray:
    """Cells within ``radius_cells`` (cell units, centre to centre) of a True cell."""
    r = int(math.floor(radius_cells))
    if r <= 0 or not mask.any():
        return mask.copy()
    ny, nx = mask.shape
    csum = np.concatenate([np.zeros((ny, 1), int), np.cumsum(mask, axis=1)], axis=1)
    rows: dict = {}
    out = np.zeros_like(mask)
    for dy in range(-r, r + 1):
        w = int(math.floor(math.sqrt(max(radius_cells ** 2 - dy * dy, 0.0))))
        if w not in rows:
            lo = np.clip(np.arange(nx) - w, 0, nx)
            hi = np.clip(np.arange(nx) + w + 1, 0, nx)
            rows[w] = (csum[:, hi] - csum[:, lo]) > 0
        h = rows[w]
        if dy >= 0:
            out[dy:] |= h[:ny - dy] if dy else h
        else:
            out[:dy] |= h[-dy:]
    return out


def _cell_index(grid: Any, xy: FloatArray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Column, row of the cell holding each point, and whether it lies on the grid."""
    ix = np.floor((xy[:, 0] - grid.x0) / grid.cell).astype(np.int64)
    iy = np.floor((xy[:, 1] - grid.y0) / grid.cell).astype(np.int64)
    inside = (ix >= 0) & (ix < grid.nx) & (iy >= 0) & (iy < grid.ny)
    return np.clip(ix, 0, grid.nx - 1), np.clip(iy, 0, grid.ny - 1), inside


def _ball_cuts(grid: Any, stock: FloatArray, xy: FloatArray, tip: FloatArray, radius: float,
               margin: float) -> np.ndarray:
    """Whether the ball (tip at ``tip`` above ``xy``) lies more than ``margin`` below the stock
    at some cell centre within its radius."""
    r = int(math.ceil(radius / grid.cell)) + 1
    off = np.arange(-r, r + 1)
    oy, ox = (a.ravel() for a in np.meshgrid(off, off, indexing="ij"))
    xs, ys = grid.centres()
    out = np.zeros(len(xy), bool)
    R2 = radius * radius
    for start in range(0, len(xy), CUT_CHUNK):
        q = xy[start:start + CUT_CHUNK]
        z = tip[start:start + CUT_CHUNK]
        ix, iy, _ = _cell_index(grid, q)
        cx = ix[:, None] + ox
        cy = iy[:, None] + oy
        ok = (cx >= 0) & (cx < grid.nx) & (cy >= 0) & (cy < grid.ny)
        cx, cy = np.clip(cx, 0, grid.nx - 1), np.clip(cy, 0, grid.ny - 1)
        dx = xs[cx] - q[:, :1]
        dy = ys[cy] - q[:, 1:]
        d2 = dx * dx + dy * dy
        ok &= d2 < R2
        ball = z[:, None] + radius - np.sqrt(np.maximum(R2 - d2, 0.0))
        hit = ok & (stock[cy, cx] > ball + margin)
        out[start:start + CUT_CHUNK] = hit.any(axis=1)
    return out


# -- validation -------------------------------------------------------------------------------
def _check_extent(extent: Any, grid: Any) -> tuple[float, float, float, float]:
    try:
        x0, x1, y0, y1 = (float(v) for v in extent)
    except (TypeError, ValueError):
        raise ParameterError(
            f"extent must be (x_min, x_max, y_min, y_max) in mm, got {extent!r}") from None
    if not all(math.isfinite(v) for v in (x0, x1, y0, y1)) or not (x1 > x0 and y1 > y0):
        raise ParameterError(
            f"extent must be finite with x_min < x_max and y_min < y_max (mm), got {extent!r}")
    gx1 = grid.x0 + grid.nx * grid.cell
    gy1 = grid.y0 + grid.ny * grid.cell
    eps = 1e-9 * max(1.0, abs(gx1), abs(gy1))
    if x0 < grid.x0 - eps or x1 > gx1 + eps or y0 < grid.y0 - eps or y1 > gy1 + eps:
        raise ParameterError(
            f"stock grid ({grid.x0:g}..{gx1:g} x {grid.y0:g}..{gy1:g} mm) does not cover the "
            f"extent ({x0:g}..{x1:g} x {y0:g}..{y1:g} mm)")
    return x0, x1, y0, y1


def _tool_radius(tool_diameter: Any) -> float:
    return 0.5 * check_range(tool_diameter, "tool_diameter", "mm", MIN_TOOL_DIAMETER,
                             MAX_TOOL_DIAMETER)


# -- passes -----------------------------------------------------------------------------------
class _Frame:
    """Raster lines across a rectangle: direction ``along`` at angle, spacing ``stepover``."""

    def __init__(self, extent: tuple[float, float, float, float], angle_deg: float,
                 stepover: float, step: float):
        theta = math.radians(angle_deg)
        self.along = np.array([math.cos(theta), math.sin(theta)])
        self.across = np.array([-math.sin(theta), math.cos(theta)])
        x0, x1, y0, y1 = extent
        self.extent = extent
        corners = np.array([[x0, y0], [x1, y0], [x0, y1], [x1, y1]])
        a, b = corners @ self.along, corners @ self.across
        nb = max(1, math.ceil((b.max() - b.min()) / stepover - 1e-9))
        self.b = np.linspace(b.min(), b.max(), nb + 1)
        na = max(1, math.ceil((a.max() - a.min()) / step - 1e-9))
        self.a = np.linspace(a.min(), a.max(), na + 1)

    def points(self) -> tuple[FloatArray, np.ndarray, np.ndarray]:
        """XY of every (line, position) sample, the line and position indices, flat."""
        li, pj = (g.ravel() for g in np.meshgrid(np.arange(len(self.b)), np.arange(len(self.a)),
                                                  indexing="ij"))
        xy = self.a[pj, None] * self.along + self.b[li, None] * self.across
        return xy, li, pj

    def inside(self, xy: FloatArray) -> np.ndarray:
        x0, x1, y0, y1 = self.extent
        e = 1e-9
        return ((xy[:, 0] >= x0 - e) & (xy[:, 0] <= x1 + e)
                & (xy[:, 1] >= y0 - e) & (xy[:, 1] <= y1 + e))


def _pieces(li: np.ndarray, pj: np.ndarray, ok: np.ndarray, cuts: np.ndarray,
            gap: int) -> list[np.ndarray]:
    """Index arrays (into the flat samples) of the passes: runs of consecutive usable samples
    on one line, trimmed to one sample beyond the first and last that cut, and split where
    more than ``gap`` samples in a row cut nothing."""
    out = []
    idx = np.flatnonzero(ok)
    if len(idx) == 0:
        return out
    brk = np.flatnonzero((li[idx][1:] != li[idx][:-1]) | (pj[idx][1:] != pj[idx][:-1] + 1)) + 1
    for run in np.split(idx, brk):
        c = np.flatnonzero(cuts[run])
        if len(c) == 0:
            continue
        groups = np.split(c, np.flatnonzero(np.diff(c) > gap) + 1)
        for g in groups:
            lo = max(int(g[0]) - 1, 0)
            hi = min(int(g[-1]) + 1, len(run) - 1)
            if hi > lo:
                out.append(run[lo:hi + 1])
    return out


def _level_passes(query: OffsetHeights, frame: _Frame, grid: Any, stock: FloatArray,
                  region: np.ndarray, margin: float, tolerance: float,
                  ) -> tuple[list, list, dict]:
    """Passes of one offset: (line index, (n, 3) tip polyline) in line order, and stats."""
    R = query.radius
    xy, li, pj = frame.points()
    ix, iy, on_grid = _cell_index(grid, xy)
    use = frame.inside(xy) & on_grid
    use[use] = region[iy[use], ix[use]]
    z = np.full(len(xy), np.nan)
    grad_all = np.full((len(xy), 2), np.nan)
    sel = np.flatnonzero(use)
    z[sel], grad_all[sel] = query.heights_and_slopes(xy[sel])
    ok = use & np.isfinite(z)
    cuts = np.zeros(len(xy), bool)
    sel = np.flatnonzero(ok)
    cuts[sel] = _ball_cuts(grid, stock, xy[sel], z[sel], R, margin)
    step = float(frame.a[1] - frame.a[0]) if len(frame.a) > 1 else R
    pieces = _pieces(li, pj, ok, cuts, max(1, int(SPLIT_GAP * R / step)))
    if not pieces:
        return [], [], {"samples": int(ok.sum()), "cutting_samples": int(cuts.sum())}
    idx = np.concatenate(pieces)
    starts = np.concatenate([[0], np.cumsum([len(p) for p in pieces])])
    pts = np.column_stack([xy[idx], z[idx]])
    keep = simplify(pts, starts, 0.5 * tolerance, "vertical")
    grad = grad_all[idx]
    run_id = np.repeat(np.arange(len(pieces)), np.diff(starts))
    pos = frame.a[pj[idx]]
    samples = ChordSamples(pos, xy[idx], z[idx], grad, run_id, keep, z[idx].copy())
    lift = lift_chords(query.heights_and_slopes, samples, 0.5 * tolerance)
    vxy, vz, vline = samples.vertices()
    cut_at = np.flatnonzero(np.diff(vline)) + 1
    passes = [np.column_stack([p, q]) for p, q in zip(np.split(vxy, cut_at), np.split(vz, cut_at))]
    lines = [int(li[p[0]]) for p in pieces]
    return lines, passes, {"samples": int(ok.sum()), "cutting_samples": int(cuts.sum()),
                           "max_lift_mm": lift["max_lift_mm"]}


class _Sweeper:
    """The remaining stock on the analysis Z-map, lowered move by move by core.simulate."""

    def __init__(self, grid: Any, height: FloatArray, radius: float):
        self.grid = grid
        self.height = height.copy()
        self.tool = Tool(2.0 * radius)
        self.radius = radius

    def envelope(self, poly: FloatArray) -> tuple[tuple[slice, slice], FloatArray] | None:
        """Window of cells the ball reaches along ``poly`` ((n, 3) tips) and the lower
        envelope of the sweep there (mm; the window's stock top where untouched)."""
        g, R = self.grid, self.radius
        lo = np.floor((poly[:, :2].min(axis=0) - R - np.array([g.x0, g.y0])) / g.cell) - 1
        hi = np.ceil((poly[:, :2].max(axis=0) + R - np.array([g.x0, g.y0])) / g.cell) + 1
        i0, j0 = max(int(lo[0]), 0), max(int(lo[1]), 0)
        i1, j1 = min(int(hi[0]), g.nx), min(int(hi[1]), g.ny)
        if i1 <= i0 or j1 <= j0:
            return None
        sub = Grid(g.x0 + i0 * g.cell, g.y0 + j0 * g.cell, g.cell, i1 - i0, j1 - j0)
        window = (slice(j0, j1), slice(i0, i1))
        top = float(self.height[window].max()) + 1.0
        n = len(poly) - 1
        segs = Segments(poly[:-1], poly[1:], np.zeros(n, bool), np.arange(n), np.arange(n))
        return window, simulate(segs, self.tool, sub, top).height

    def depth(self, poly: FloatArray) -> tuple[float, Any]:
        """Deepest cut (mm) of the ball along ``poly`` into the remaining stock, and the
        envelope to :meth:`apply`."""
        env = self.envelope(poly)
        if env is None:
            return -math.inf, None
        window, low = env
        return float(np.max(self.height[window] - low)), env

    def apply(self, env: Any) -> None:
        if env is not None:
            window, low = env
            np.minimum(self.height[window], low, out=self.height[window])


def _link(query: OffsetHeights, a: FloatArray, b: FloatArray, tolerance: float,
          step: float) -> FloatArray | None:
    """One-sided straight link (tip polyline) on the offset CL surface from ``a`` to ``b``,
    None where the ball meets no part on the way."""
    samples = sample_chords(query.heights_and_slopes, [np.array([a[:2], b[:2]])],
                            [np.array([a[2], b[2]])], step)
    if not np.isfinite(samples.z).all():
        return None
    lift_chords(query.heights_and_slopes, samples, 0.5 * tolerance)
    xy, z, _ = samples.vertices()
    return np.column_stack([xy, z])


def _sequence(query: OffsetHeights, passes: list, sweeper: _Sweeper, margin: float,
              tolerance: float) -> tuple[list, list, int]:
    """Cut the passes in order on the remaining stock: drop those that remove nothing (not
    more than margin / 4), and link a pass to the one before by a stay-down feed where the
    link is short and the ball along it cuts at most ``margin`` into what is left (cleared or
    lower ground); None (retract) elsewhere.  Returns passes, links, dropped count."""
    R = query.radius
    kept: list = []
    links: list = []
    dropped = 0
    step = max(min(0.5 * sweeper.grid.cell, 0.25 * math.sqrt(8.0 * R * tolerance)), 1e-3)
    for p in passes:
        depth, env = sweeper.depth(p)
        if not depth > 0.25 * margin:
            dropped += 1
            continue
        if kept:
            link = None
            if float(np.hypot(*(p[0, :2] - kept[-1][-1, :2]))) <= STAY_DOWN_LINK * R:
                link = _link(query, kept[-1][-1], p[0], tolerance, step)
            if link is not None:
                link_depth, link_env = sweeper.depth(link)
                if link_depth <= margin:
                    sweeper.apply(link_env)
                else:
                    link = None
            links.append(link)
        sweeper.apply(env)
        kept.append(p)
    return kept, links, dropped


def generate_rest(cl_height: ClHeightFn, stock: Any, tool_diameter: float, limit: float,
                  stepover: float, extent: Any, angle: float = 0.0, tolerance: float = 0.005,
                  progress: ProgressFn = None, cancel: CancelFn = None,
                  margin: float | None = None, clearance_height: float | None = None,
                  ) -> Toolpath:
    """Ball-end rest passes clearing the roughed stock down to ``limit`` above the part.

    ``cl_height(radius)`` returns the exact ball tip height function (xy (n, 2) mm -> (n,)
    mm, NaN off the part) of a ball of that radius (mm): :func:`net_cl_height` for a core
    Surface, :func:`faceset_cl_height` for a FaceSet.  ``stock`` is the remaining stock as a
    Z-map: a :class:`simulate.Simulation` or a (Grid, heights (ny, nx) mm) pair covering
    ``extent`` = (x_min, x_max, y_min, y_max) mm, the rectangle machined.  Per offset
    o_m = m * limit (m = M-1 .. 1, M = ceil(max excess / limit), excess = stock - CL_0 on the
    Z-map, on cells of at most limit / 4 mm), raster lines ``stepover`` mm apart in direction
    ``angle`` (degrees from +X) are sampled at sqrt(8 R tolerance) mm, kept where the excess
    exceeds o_m + ``margin`` (default limit / 20 mm) grown by the tool radius, trimmed to
    where the ball cuts the stock, thinned within ``tolerance``/2 and made one-sided
    (:func:`chords.lift_chords`).  Passes run in zig-zag order, top offset first; links stay
    down (``Toolpath.links``) where the ball would cut only what the pass before swept.
    """
    started = time.perf_counter()
    R = _tool_radius(tool_diameter)
    limit = check_positive(limit, "limit", "mm")
    stepover = check_positive(stepover, "stepover", "mm")
    if stepover > 2.0 * R:
        raise ParameterError(
            f"stepover must not exceed the tool diameter ({2 * R:g} mm), got {stepover:g} mm")
    tolerance = check_range(tolerance, "tolerance", "mm", *TOLERANCE_RANGE)
    angle = check_angle(angle)
    margin = 0.05 * limit if margin is None else check_finite(margin, "margin", "mm")
    if margin < 0.0 or margin >= limit:
        raise ParameterError(f"margin must lie in [0, limit) mm, got {margin:g} mm")
    if not callable(cl_height):
        raise ParameterError(f"cl_height must be callable (radius -> heights), got "
                             f"{type(cl_height).__name__}")
    grid, height = _stock_arrays(stock)
    box = _check_extent(extent, grid)
    if clearance_height is not None:
        check_finite(clearance_height, "clearance_height", "mm")
    monitor = Monitor(progress, cancel, "rest")
    monitor(0.0)

    grid, height = _refine_stock(grid, height, 0.25 * limit)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    cxy = np.column_stack([X.ravel(), Y.ravel()])
    in_box = ((cxy[:, 0] >= box[0] - R) & (cxy[:, 0] <= box[1] + R)
              & (cxy[:, 1] >= box[2] - R) & (cxy[:, 1] <= box[3] + R))
    cl0 = np.full(len(cxy), np.nan)
    cl0[in_box] = np.asarray(cl_height(R)(cxy[in_box]), dtype=float).reshape(-1)
    excess = (height.ravel() - cl0).reshape(height.shape)
    excess = np.where(np.isfinite(excess), excess, -np.inf)
    top = float(excess.max(initial=-np.inf))
    levels = max(int(math.ceil(top / limit - 1e-9)), 0) if math.isfinite(top) else 0
    monitor(0.1)

    step = min(math.sqrt(8.0 * R * tolerance), 0.5 * R, 2.0 * grid.cell)
    frame = _Frame(box, angle, stepover, step)
    sweeper = _Sweeper(grid, height, R)
    cl0_map = cl0.reshape(height.shape)
    passes: list = []
    links: list = []
    per_level: list = []
    flip = False
    offsets = [m * limit for m in range(levels - 1, 0, -1)]
    for n, o in enumerate(offsets):
        # excess of what the levels above left
        left = np.where(np.isfinite(cl0_map), sweeper.height - cl0_map, -np.inf)
        region = _dilate(left > o + margin, (R + 2.0 * step) / grid.cell)
        if not region.any():
            per_level.append({"offset_mm": o, "passes": 0})
            continue
        query = OffsetHeights(cl_height, R, o)
        lines, level, stats = _level_passes(query, frame, grid, sweeper.height, region,
                                            margin, tolerance)
        # zig-zag: alternate the sense from one line to the next
        ordered = []
        for k in sorted(set(lines)):
            group = [p for kk, p in zip(lines, level) if kk == k]
            if flip:
                group = [p[::-1] for p in group[::-1]]
            flip = not flip
            ordered.extend(group)
        ordered, level_links, dropped = _sequence(query, ordered, sweeper, margin, tolerance)
        if passes and ordered:
            links.append(None)  # down to the next offset: retract
        passes.extend(ordered)
        links.extend(level_links)
        per_level.append({"offset_mm": o, "passes": len(ordered), "dropped": dropped, **stats})
        monitor(0.1 + 0.9 * (n + 1) / len(offsets))
    monitor(1.0)
    parameters = {
        "strategy": "rest", "tool_diameter": 2.0 * R, "limit": limit, "stepover": stepover,
        "tolerance": tolerance, "angle": angle, "margin": margin, "extent": list(box),
    }
    extra = {"offsets_mm": offsets, "levels": per_level, "max_excess_mm": top,
             "zmap_cell_mm": grid.cell}
    toolpath = Toolpath("rest", passes, parameters, [], ToolpathStats(
        stepover_min_mm=stepover, stepover_max_mm=stepover), extra=extra, links=links)
    return toolpath.finish(started, clearance_height)


__all__ = ["OffsetHeights", "faceset_cl_height", "generate_rest", "net_cl_height"]
