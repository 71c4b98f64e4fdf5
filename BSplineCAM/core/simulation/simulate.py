# SPDX-License-Identifier: LGPL-2.1-or-later
"""Stock simulation on a Z-map: the lower envelope of the tool swept along every move.

The stock is a grid of vertical dexels over the XY footprint; each keeps the height of its
top at the cell centre.  A move removes material down to the exact lower envelope of the
tool swept along the straight segment (arcs come here as chords, see ``gcode.linearise``).

Envelope of one segment, at a cell centre p (derivation in the docstring of
:func:`_envelope`): with the tool bottom z_tip + f(r) at radial distance r from its axis,
the height is min over the segment of z(s) + f(|p - c(s)|).  For the ball, flat and bull-nose
profiles f is convex and non-decreasing, so that function of s is convex and its minimum is
the unconstrained stationary point clamped to the segment: closed form for ball and flat
ends, a 1-D bisection for the bull-nose (Huang & Oliver, "NC milling error assessment and
tool path correction", SIGGRAPH 1994, use the same lower-envelope formulation).

Speed: segments with similar windows are stacked and evaluated as one (K, H, W) array, so
numpy's per-call overhead is paid per batch, not per move; only the final min into the
height map loops over moves, at a few microseconds each.
"""

from __future__ import annotations

import math
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from enum import Enum

import numpy as np

from .. import kernels
from ..errors import ParameterError
from ..kernels import zmap_kernels
from ..program.gcode import Program, Segments, linearise, simulation_chord_tolerance
from ..threads import numpy_threads
from ..typing import FloatArray

#: Cells evaluated per batch: (K, H, W) temporaries stay in the processor's cache.
BATCH_CELLS = 1 << 17
#: A rapid that removes more than this (mm) is a collision.
COLLISION_TOLERANCE_MM = 0.01
#: The tool's outermost RIM_MM (mm) cuts nothing in the Z-map.  A tool whose side only
#: touches a vertical wall (a waterline contour the radius from it, to the program's four
#: decimals) would drop the column of a cell centred on the wall (grids are aligned to round
#: coordinates, and so are a CAD part's walls) to the contact height: a gouge of the wall's
#: height where the tool removed nothing.
RIM_MM = 1e-4
_BISECTION_STEPS = 24


class ToolShape(str, Enum):
    """End of the cutter."""

    BALL = "ball"
    FLAT = "flat"
    BULLNOSE = "bullnose"

    @classmethod
    def parse(cls, value: str | ToolShape) -> ToolShape:
        try:
            return cls(value)
        except ValueError:
            raise ParameterError(
                f"tool shape must be one of {', '.join(s.value for s in cls)}, got {value!r}"
            ) from None


@dataclass(frozen=True)
class Tool:
    """A cutter; the programmed point is the tool tip (lowest point on the axis), in mm."""

    diameter: float
    shape: ToolShape = ToolShape.BALL
    corner_radius: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "shape", ToolShape.parse(self.shape))
        if not (isinstance(self.diameter, (int, float)) and math.isfinite(self.diameter)
                and self.diameter > 0):
            raise ParameterError(
                f"tool diameter must be a positive length (mm), got {self.diameter!r}")
        if self.shape is ToolShape.BULLNOSE:
            if not (math.isfinite(self.corner_radius) and 0 < self.corner_radius <= self.radius):
                raise ParameterError(
                    f"bull-nose corner radius must be in (0, {self.radius:g}] mm (half the "
                    f"diameter), got {self.corner_radius!r}"
                )
        elif self.corner_radius not in (0, 0.0):
            raise ParameterError(
                f"corner radius (mm) applies to a bull-nose tool, not {self.shape.value}")

    @property
    def radius(self) -> float:
        return self.diameter / 2.0

    def profile(self, r: FloatArray) -> FloatArray:
        """Height of the tool's bottom above its tip at radial distance r (mm); inf beyond."""
        r = np.abs(np.asarray(r, dtype=float))
        R = self.radius
        with np.errstate(invalid="ignore"):
            if self.shape is ToolShape.BALL:
                out = R - np.sqrt(np.maximum(R * R - r * r, 0.0))
            elif self.shape is ToolShape.FLAT:
                out = np.zeros_like(r)
            else:
                a, rc = R - self.corner_radius, self.corner_radius
                e = np.maximum(r - a, 0.0)
                out = rc - np.sqrt(np.maximum(rc * rc - e * e, 0.0))
        return np.where(r <= R * (1 + 1e-12), out, np.inf)


def corner_height(tool: Tool, axial):
    """Height (mm) above the tip from which a cut's material counts for its radial engagement:
    the top of the tool's corner (a bull-nose's corner radius, a ball's radius; 0 for a flat
    end), at most half the cut's depth ``axial``, so that a cut shallower than the corner is
    measured at half its depth.  A bull-nose pass s beside the previous one also shaves the
    fillet the previous pass's corner left, lower than the corner: counted, two passes 4 mm
    apart with a 10 mm tool of 2 mm corner radius would measure 5.8 mm.  ``axial`` may be an
    array (one height per cut)."""
    if tool.shape is ToolShape.FLAT:
        corner = 0.0
    else:
        corner = tool.radius if tool.shape is ToolShape.BALL else tool.corner_radius
    return np.minimum(corner, 0.5 * np.asarray(axial, dtype=float))


#: Most cells of a Z-map: about 100 bytes each while verifying (1.6 GB), and the time to
#: simulate a program grows with them.
MAX_ZMAP_CELLS = 16_000_000


def zmap_shape(width: float, height: float, cell: float,
               argument: str = "cell size") -> tuple[int, int]:
    """Columns and rows of whole ``cell``-sized cells covering width x height (mm); a
    ParameterError naming ``argument`` if there would be more than ``MAX_ZMAP_CELLS``."""
    fx = max(width, 0.0) / cell - 1e-9
    fy = max(height, 0.0) / cell - 1e-9
    if not (math.isfinite(fx) and math.isfinite(fy)) or \
            max(fx, 1.0) * max(fy, 1.0) > 2.0 * MAX_ZMAP_CELLS:
        raise ParameterError(
            f"{argument} {cell:g} mm gives more than {MAX_ZMAP_CELLS / 1e6:g} million Z-map cells "
            f"over {width:.6g} x {height:.6g} mm: use a larger cell")
    nx = max(1, math.ceil(fx))
    ny = max(1, math.ceil(fy))
    if nx * ny > MAX_ZMAP_CELLS:
        raise ParameterError(
            f"{argument} {cell:g} mm gives {nx} x {ny} Z-map cells (at most "
            f"{MAX_ZMAP_CELLS / 1e6:g} million) over {width:.6g} x {height:.6g} mm: use a "
            "larger cell")
    return nx, ny


@dataclass(frozen=True)
class Grid:
    """Cells of size ``cell`` (mm) from (x0, y0); arrays on it are (ny, nx), rows along y."""

    x0: float
    y0: float
    cell: float
    nx: int
    ny: int

    @classmethod
    def covering(cls, x_min: float, x_max: float, y_min: float, y_max: float,
                 cell: float) -> Grid:
        """The grid of whole cells covering the rectangle, centred on it."""
        if not (math.isfinite(cell) and cell > 0):
            raise ParameterError(f"cell size must be a positive length (mm), got {cell!r}")
        nx, ny = zmap_shape(x_max - x_min, y_max - y_min, cell)
        x0 = (x_min + x_max) / 2.0 - nx * cell / 2.0
        y0 = (y_min + y_max) / 2.0 - ny * cell / 2.0
        return cls(float(x0), float(y0), float(cell), nx, ny)

    def centres(self) -> tuple[FloatArray, FloatArray]:
        """Cell-centre coordinates (x of each column, y of each row), mm."""
        return (self.x0 + (np.arange(self.nx) + 0.5) * self.cell,
                self.y0 + (np.arange(self.ny) + 0.5) * self.cell)


@dataclass(frozen=True)
class Collision:
    """A rapid move that cut stock: source line, deepest cut (mm) and where."""

    line: int
    depth_mm: float
    x: float
    y: float

    def to_dict(self) -> dict:
        return {"line": self.line, "depth_mm": round(self.depth_mm, 6),
                "x": round(self.x, 4), "y": round(self.y, 4)}


@dataclass(frozen=True)
class Simulation:
    """The machined Z-map (mm) and what the simulation noticed on the way."""

    grid: Grid
    height: FloatArray
    top: float
    collisions: tuple[Collision, ...]
    #: The stock's heights before the first move (mm) when they differ from cell to cell
    #: (-inf: no stock); None: a block with its top at ``top``.
    start: FloatArray | None = None

    def start_heights(self) -> FloatArray:
        """The stock's heights before the first move (mm), per cell."""
        if self.start is not None:
            return self.start
        return np.full(self.height.shape, self.top)

    def removed_volume(self) -> float:
        """Volume cut from the stock (mm^3), cell area times removed depth."""
        start = self.start_heights()
        cut = np.isfinite(start)
        return float(np.sum(start[cut] - self.height[cut]) * self.grid.cell ** 2)


def simulate_program(program: Program, tool: Tool, grid: Grid, top: float,
                     chord_tolerance: float | None = None) -> Simulation:
    """Simulate a program; arcs become chords within ``chord_tolerance`` (default cell/10)."""
    tol = simulation_chord_tolerance(grid.cell) if chord_tolerance is None else chord_tolerance
    return simulate(linearise(program, tol), tool, grid, top)


def simulate(segments: Segments, tool: Tool, grid: Grid, top: float | FloatArray,
             collision_tolerance: float = COLLISION_TOLERANCE_MM) -> Simulation:
    """Cut a block of stock with top at ``top`` (mm) along the segments, in program order;
    ``top`` may also be the stock's height per cell, (ny, nx) mm, -inf where there is none.

    Feed segments between two rapids commute (the Z-map keeps a minimum), so they are batched
    in any order; a rapid that can reach the stock is checked against the stock as the moves
    before it left it, and reported as a :class:`Collision` if it cuts deeper than
    ``collision_tolerance``.
    """
    initial = None
    if np.ndim(top) == 0:
        height = np.full((grid.ny, grid.nx), float(top), dtype=np.float32)
    else:
        initial = np.asarray(top, dtype=float)
        if initial.shape != (grid.ny, grid.nx) or np.isnan(initial).any() or \
                not np.isfinite(initial).any():
            raise ValueError(f"simulate: the stock's heights must be finite or -inf on the "
                             f"{grid.ny} x {grid.nx} grid, got shape {initial.shape}")
        height = initial.astype(np.float32)
        top = float(initial[np.isfinite(initial)].max())
    start = np.asarray(segments.start, dtype=float)
    end = np.asarray(segments.end, dtype=float)
    low = np.minimum(start[:, 2], end[:, 2])
    full = _windows(start, end, tool.radius, grid)
    live = (full[:, 1] >= full[:, 0]) & (full[:, 3] >= full[:, 2]) & (low < top)
    window = _windows(start, end, tool.radius, grid,
                      _along_ranges(start, end, tool, live & ~segments.rapid))
    collisions: list[Collision] = []
    risky = np.flatnonzero(live & segments.rapid)
    begin = 0
    for r in [*risky.tolist(), len(start)]:
        feed = np.arange(begin, r)
        feed = feed[live[feed] & ~segments.rapid[feed]]
        if len(feed):
            _cut(height, feed, start, end, window, tool, grid, None)
        if r < len(start):
            depth = _cut(height, np.array([r]), start, end, window, tool, grid, collision_tolerance)
            if depth is not None:
                collisions.append(Collision(int(segments.line[r]), *depth))
        begin = r + 1
    out = height.astype(float)
    out += 0.0  # a zero height as +0 (the merge's minimum may keep either zero's sign)
    return Simulation(grid, out, float(top), _merge(collisions), initial)


def _merge(collisions: list[Collision]) -> tuple[Collision, ...]:
    """One collision per source line (its deepest cut)."""
    best: dict[int, Collision] = {}
    for c in collisions:
        if c.line not in best or c.depth_mm > best[c.line].depth_mm:
            best[c.line] = c
    return tuple(best[k] for k in sorted(best))


def _along_ranges(start: FloatArray, end: FloatArray, tool: Tool,
                  feed: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """Along each segment's XY direction (mm from its start): the stretch of cells where its
    envelope can be the lowest of the program's, (lo, hi); the full reach is (-R, L + R).

    The envelope at a cell is min over t in [0, L] of g(t), g convex (see :func:`_envelope`);
    its minimiser t* = qa - tau*(qp) lies inside (0, L) only for qa in [tau_min, L + tau_max],
    tau* between 0 and R s, s = m / sqrt(1 + m^2) for the ball, sign(m) for the others.  Where
    t* is clamped to an end, the value is the tool standing at that end, which is no lower
    than the interior minimum of the neighbouring segment wherever that one's t* is inside.
    So for a chain of feed segments that continue one another in the same XY direction
    (raster passes), segment i needs the cells where it is interior plus the wedge beyond its
    end where both it and the next clamp to the shared point: qa up to L + max(tau_max of
    both).  A chain's first segment keeps its start's whole ball (-R), its last its end's
    (L + R); every other segment keeps its whole reach.
    """
    n = len(start)
    R = tool.radius
    d = end[:, :2] - start[:, :2]
    L = np.hypot(d[:, 0], d[:, 1])
    lo = np.full(n, -R)
    hi = L + R
    if n < 2:
        return lo, hi
    moving = L > 1e-9
    safe = np.where(moving, L, 1.0)
    ux, uy = d[:, 0] / safe, d[:, 1] / safe
    m = (end[:, 2] - start[:, 2]) / safe
    s = m / np.sqrt(1.0 + m * m) if tool.shape is ToolShape.BALL else np.sign(m)
    tau_lo = np.minimum(0.0, R * s)
    tau_hi = np.maximum(0.0, R * s)
    ok = feed & moving
    link = (ok[:-1] & ok[1:]
            & np.all(end[:-1] == start[1:], axis=1)
            & (np.abs(ux[:-1] - ux[1:]) <= 1e-12) & (np.abs(uy[:-1] - uy[1:]) <= 1e-12))
    after = np.zeros(n, bool)  # linked to the next segment
    after[:-1] = link
    before = np.zeros(n, bool)  # linked to the previous one
    before[1:] = link
    next_hi = np.zeros(n)
    next_hi[:-1] = tau_hi[1:]
    lo = np.where(before, tau_lo, lo)
    hi = np.where(after, L + np.maximum(tau_hi, next_hi), hi)
    return lo, hi


def _windows(start: FloatArray, end: FloatArray, radius: float, grid: Grid,
             along: tuple[FloatArray, FloatArray] | None = None) -> np.ndarray:
    """Inclusive cell ranges (ix_lo, ix_hi, iy_lo, iy_hi) each segment's tool can reach, or
    with ``along`` = (lo, hi) the cells within ``radius`` across the segment's XY line and
    from lo to hi mm along it (its direction from start to end)."""
    if along is not None:
        d = end[:, :2] - start[:, :2]
        L = np.hypot(d[:, 0], d[:, 1])
        moving = L > 1e-9
        safe = np.where(moving, L, 1.0)
        u = np.where(moving[:, None], d / safe[:, None], np.array([1.0, 0.0]))
        a, b = along
        # the rectangle [a, b] x [-R, R] in the segment's frame: its corners' XY box
        ext = np.abs(u) * ((b - a) / 2.0)[:, None] + np.abs(u[:, ::-1]) * radius
        mid = start[:, :2] + u * ((a + b) / 2.0)[:, None]
        lo, hi = mid - ext, mid + ext
    else:
        lo = np.minimum(start[:, :2], end[:, :2]) - radius
        hi = np.maximum(start[:, :2], end[:, :2]) + radius
    origin = np.array([grid.x0, grid.y0])
    first = np.ceil((lo - origin) / grid.cell - 0.5).astype(np.int64)
    last = np.floor((hi - origin) / grid.cell - 0.5).astype(np.int64)
    first = np.maximum(first, 0)
    last = np.minimum(last, np.array([grid.nx - 1, grid.ny - 1]))
    return np.stack([first[:, 0], last[:, 0], first[:, 1], last[:, 1]], axis=1)


def _cut(height: FloatArray, index: np.ndarray, start: FloatArray, end: FloatArray,
         window: np.ndarray, tool: Tool, grid: Grid,
         collision_tolerance: float | None) -> tuple[float, float, float] | None:
    """Lower ``height`` by the envelopes of segments ``index``; for a rapid, report its cut.

    Batches run on up to ``threads.numpy_threads()`` threads: numpy releases the GIL inside its loops, and the
    merge into ``height`` (a minimum, so order-free) is serialised by a lock.
    """
    w = window[index, 1] - window[index, 0] + 1
    h = window[index, 3] - window[index, 2] + 1
    # pad window sizes to a few shapes so that many segments share one batch
    wb = np.minimum(_round_up(w), grid.nx)
    hb = np.minimum(_round_up(h), grid.ny)
    ix0 = np.minimum(window[index, 0], grid.nx - wb)
    iy0 = np.minimum(window[index, 2], grid.ny - hb)
    key = hb * (grid.nx + 1) + wb
    order = np.argsort(key, kind="stable")
    bounds = np.flatnonzero(np.diff(key[order])) + 1
    batches = []
    for group in np.split(order, bounds):
        per_batch = max(1, BATCH_CELLS // int(hb[group[0]] * wb[group[0]]))
        batches.extend(group[b:b + per_batch] for b in range(0, len(group), per_batch))
    if kernels.use_numba():
        try:
            return _cut_compiled(height, index, start, end, ix0, iy0, hb, wb, batches, tool,
                                 grid, collision_tolerance)
        except kernels.KernelUnavailable:
            pass
    result: list[tuple[float, float, float]] = []
    lock = threading.Lock()

    def run(mine: list[np.ndarray]) -> None:
        scratch = _Scratch()
        for sel in mine:
            H, W = int(hb[sel[0]]), int(wb[sel[0]])
            seg = index[sel]
            env = _envelope(start[seg], end[seg], ix0[sel], iy0[sel], H, W, tool, grid, scratch)
            with lock:
                for k in range(len(sel)):
                    y, x = int(iy0[sel[k]]), int(ix0[sel[k]])
                    view = height[y:y + H, x:x + W]
                    if collision_tolerance is not None:
                        depth = np.nan_to_num(view - env[k], nan=-np.inf)
                        at = int(np.argmax(depth))
                        if depth.flat[at] > collision_tolerance:
                            cy, cx = divmod(at, W)
                            result.append((float(depth.flat[at]),
                                           grid.x0 + (x + cx + 0.5) * grid.cell,
                                           grid.y0 + (y + cy + 0.5) * grid.cell))
                    np.fmin(view, env[k], out=view)

    threads = min(numpy_threads(), len(batches))
    if threads <= 1:
        run(batches)
    else:
        with ThreadPoolExecutor(threads) as pool:
            for future in [pool.submit(run, batches[i::threads]) for i in range(threads)]:
                future.result()
    return max(result) if result else None


#: Cells a call stamps before it is split over threads (numba engine).
THREADED_CELLS = 1 << 16


def segment_frame(p0: FloatArray, p1: FloatArray) -> tuple[FloatArray, ...]:
    """Each segment's frame for its envelope: XY length L (0 for a vertical one), unit XY
    direction (ux, uy) ((1, 0) when vertical), slope m = dz / L (0 when vertical) and the
    start height z0 (the lower end's when vertical).  Shared by both engines' envelopes."""
    d = p1[:, :2] - p0[:, :2]
    L = np.hypot(d[:, 0], d[:, 1])
    flat = L < 1e-9
    safe = np.where(flat, 1.0, L)
    ux = np.where(flat, 1.0, d[:, 0] / safe)
    uy = np.where(flat, 0.0, d[:, 1] / safe)
    m = np.where(flat, 0.0, (p1[:, 2] - p0[:, 2]) / safe)
    z0 = np.where(flat, np.minimum(p0[:, 2], p1[:, 2]), p0[:, 2])
    return np.where(flat, 0.0, L), ux, uy, m, z0


def window_reach(p0: FloatArray, ix0, iy0, hb, wb, x0: float, y0: float,
                 cell: float) -> FloatArray:
    """The largest |dx| or |dy| (mm) from each segment's start to a cell centre of its window
    (monotone along a row or column: at the window's first or last cell), which decides
    :func:`_envelope`'s ``wide`` choice."""
    def extreme(origin, first, size, p):
        lo = origin + (first + 0.5) * cell - p
        hi = origin + (first + size - 1 + 0.5) * cell - p
        return np.maximum(np.abs(lo), np.abs(hi))

    return np.maximum(extreme(x0, ix0, wb, p0[:, 0]), extreme(y0, iy0, hb, p0[:, 1]))


def _cut_compiled(height: FloatArray, index: np.ndarray, start: FloatArray, end: FloatArray,
                  ix0: np.ndarray, iy0: np.ndarray, hb: np.ndarray, wb: np.ndarray,
                  batches: list[np.ndarray], tool: Tool, grid: Grid,
                  collision_tolerance: float | None) -> tuple[float, float, float] | None:
    """:func:`_cut` by the compiled :func:`.zmap_kernels.stamp`, segment by segment into
    ``height``, with the numpy engine's windows, per-segment float32 constants and per-batch
    ``wide`` choice (see :func:`_envelope`), so that the height map is bit-identical.  Threads
    (the kernel runs without the GIL) take interleaved 4-row blocks, so none writes another's
    cells."""
    R = tool.radius
    p0, p1 = start[index], end[index]
    L, ux, uy, m, z0 = segment_frame(p0, p1)
    # the numpy engine's wide choice: per batch, from the largest |dx|, |dy| of its cells
    # (monotone along a row or column: at the window's first or last cell)
    reach = window_reach(p0, ix0, iy0, hb, wb, grid.x0, grid.y0, grid.cell)
    wide = np.zeros(len(index), bool)
    for sel in batches:
        wide[sel] = bool(reach[sel].max() > 2 * R)
    f32 = np.float32
    bisect = np.zeros(len(index), f32)
    if tool.shape is ToolShape.BALL:
        shape, slope, zf = zmap_kernels.BALL, m / np.sqrt(1.0 + m * m), z0 + R
    elif tool.shape is ToolShape.FLAT:
        shape, slope, zf = zmap_kernels.FLAT, np.sign(m), z0
    else:
        shape, slope, zf = zmap_kernels.BULLNOSE, np.sign(m), z0 + tool.corner_radius
        bisect = np.abs(m).astype(f32)
    consts = zmap_kernels.constants(R, tool.corner_radius, RIM_MM)
    args = [height, float(grid.x0), float(grid.y0), float(grid.cell),
            *(np.ascontiguousarray(v, dtype=np.int64) for v in (ix0, iy0, hb, wb)),
            *(np.ascontiguousarray(v, dtype=float) for v in (p0[:, 0], p0[:, 1], ux, uy)),
            wide, np.ascontiguousarray(L, dtype=float),
            *(np.ascontiguousarray(v).astype(f32) for v in (L, m, slope, zf)), bisect,
            int(shape), consts, collision_tolerance is not None]
    threads = 1 if collision_tolerance is not None else min(numpy_threads(), max(
        1, int(np.sum(hb * wb.astype(np.int64))) // THREADED_CELLS))
    depth = np.zeros((threads, 3))
    if threads <= 1:
        zmap_kernels.stamp(*args, 0, 1, depth[0])
    else:
        with ThreadPoolExecutor(threads) as pool:
            for future in [pool.submit(zmap_kernels.stamp, *args, t, threads, depth[t])
                           for t in range(threads)]:
                future.result()
    if collision_tolerance is None or not depth[0, 0] > collision_tolerance:
        return None
    y, x = int(depth[0, 1]), int(depth[0, 2])
    return (float(depth[0, 0]), grid.x0 + (x + 0.5) * grid.cell, grid.y0 + (y + 0.5) * grid.cell)


def _round_up(n: np.ndarray) -> np.ndarray:
    """Window sizes rounded up to 1/16 steps of their power of two (at most 6.25% padding)."""
    n = np.maximum(n, 1)
    step = np.maximum(1, 2 ** np.floor(np.log2(n)).astype(np.int64) // 16)
    return -(-n // step) * step


class _Scratch:
    """Work arrays that one thread reuses from batch to batch: fresh ones of a batch's size
    are page-faulted in on first touch, at a cost comparable to the arithmetic on them."""

    def __init__(self) -> None:
        self.pool = np.empty((0, 0), np.float32)

    def arrays(self, count: int, shape: tuple[int, ...]) -> list[FloatArray]:
        size = math.prod(shape)
        if self.pool.shape[0] < count or self.pool.shape[1] < size:
            self.pool = np.empty((count, size), np.float32)
        return [self.pool[i, :size].reshape(shape) for i in range(count)]


def _envelope(p0: FloatArray, p1: FloatArray, ix0: np.ndarray, iy0: np.ndarray, H: int, W: int,
              tool: Tool, grid: Grid, scratch: _Scratch | None = None) -> FloatArray:
    """Lower envelope (K, H, W) of the tool swept from p0 to p1 over each segment's window.

    With ``scratch`` the result lives in its arrays, valid until the next call with it.

    In the segment's frame, a cell centre lies at qa along and qp across the XY direction
    (length L, slope m = dz/L).  With the tool axis at distance t = s L along the segment, the
    envelope is min over t in [0, L] of
        g(t) = z0 + m t + f(sqrt(qp^2 + (qa - t)^2)),
    convex in t.  Its stationary point solves f'(r) (qa - t) / r = m; with
    rho^2 = R^2 - qp^2 and tau = qa - t: ball tau* = rho m / sqrt(1 + m^2), flat
    tau* = rho sign(m), bull-nose by bisection.  Clamping t* = qa - tau* to [0, L] gives the
    minimum.  Cells out of the tool's reach come out NaN (the caller merges with fmin).
    A vertical segment (L = 0) has t = 0 and the lower end's z.

    float32 throughout, since the arrays are the simulation's whole cost, but at the tool's
    scale: qa is taken from both ends, every coordinate is rounded once, and R^2 - r^2 is
    rho^2 - tau^2.  A cell's offset from the tool's axis is then good to 1e-6 R whatever the
    move's length (its place along the move to 6e-8 of that length, where the envelope rises
    at the move's own slope), and its height to that error times the envelope's slope:
    ~1e-6 mm mostly, more on the swept rim (where the profile turns vertical) and along short
    steep moves.
    """
    R = tool.radius
    L, ux, uy, m, z0 = segment_frame(p0, p1)
    dx = (grid.x0 + (ix0[:, None] + np.arange(W) + 0.5) * grid.cell - p0[:, 0, None])[:, None, :]
    dy = (grid.y0 + (iy0[:, None] + np.arange(H) + 0.5) * grid.cell - p0[:, 1, None])[:, :, None]
    e = (slice(None), None, None)
    f32 = np.float32
    # The (K, H, W) coordinates are each a per-row plus a per-column term.  Where those exceed
    # 2 R (long moves) they are summed in float64 and rounded once, which costs about one
    # float32 pass more per array; else in float32, with errors of a few ulp of 2 R, and qa1
    # is qa - L.
    wide = max(np.abs(dx).max(initial=0.0), np.abs(dy).max(initial=0.0)) > 2 * R
    terms = (lambda v: v) if wide else (lambda v: v.astype(f32))
    qa, qa1, qp2, rho, beyond = (scratch or _Scratch()).arrays(5, (len(L), H, W))
    np.add(terms(dy * uy[e]), terms(dx * ux[e]), out=qa)  # from p0
    if wide:
        np.add(terms(dy * uy[e]), terms(dx * ux[e] - L[e]), out=qa1)  # from p1
    else:
        np.subtract(qa, L.astype(f32)[e], out=qa1)
    np.subtract(terms(dy * ux[e]), terms(dx * uy[e]), out=qp2)
    np.square(qp2, out=qp2)
    # cells farther than R - RIM_MM from the swept axis (across, or beyond an end) are left
    # (float32 puts them within ~1e-6 R)
    np.negative(qa, out=beyond)
    np.maximum(beyond, qa1, out=beyond)
    np.maximum(beyond, f32(0.0), out=beyond)
    np.square(beyond, out=beyond)
    beyond += qp2
    np.subtract(f32(R * R), qp2, out=rho)
    with np.errstate(invalid="ignore"):
        np.sqrt(rho, out=rho)  # NaN beyond the tool's reach across the path
        if tool.shape is ToolShape.BALL:
            tau = np.multiply(rho, (m / np.sqrt(1.0 + m * m)).astype(f32)[e], out=qp2)
        elif tool.shape is ToolShape.FLAT:
            tau = np.multiply(rho, np.sign(m).astype(f32)[e], out=qp2)
        else:
            tau = _bullnose_tau(qp2, rho, np.abs(m).astype(f32)[e], tool)
            tau *= np.sign(m).astype(f32)[e]
        # t* = qa - tau* clamped to [0, L] is tau* clamped to [qa1, qa]; both are clamped,
        # t so that the ends' heights are exact, tau so that r is exact at both ends
        np.minimum(tau, qa, out=tau)  # NaN stays NaN
        np.maximum(tau, qa1, out=qa1)
        t = np.subtract(qa, tau, out=tau)  # >= 0
        tau = qa1
        np.minimum(t, L.astype(f32)[e], out=t)
        t *= m.astype(f32)[e]  # height of the tip above z0
        # R^2 - r^2 = rho^2 - tau^2, which keeps its precision where r^2 is close to R^2
        # (steep moves have their minimum there); negative beyond the ends' reach
        gap = np.subtract(rho, tau, out=qa)
        gap *= np.add(rho, tau, out=rho)
        if tool.shape is ToolShape.BALL:
            t += (z0 + R).astype(f32)[e]
            np.sqrt(gap, out=gap)
            t -= gap
        elif tool.shape is ToolShape.FLAT:
            t += z0.astype(f32)[e]
            t[gap < f32(-1e-6 * R * R)] = np.nan
        else:
            # corner: f = rc - sqrt(rc^2 - (r - a)^2), a = R - rc, with rc - (r - a) = R - r =
            # gap / (R + r) carried to the end for the same precision; 0 on the flat (R - r >= rc)
            rc = tool.corner_radius
            r = np.subtract(f32(R * R), gap, out=tau)
            np.sqrt(r, out=r)
            r += f32(R)
            np.divide(gap, r, out=gap)  # R - r
            np.minimum(gap, f32(rc), out=gap)  # NaN stays NaN
            np.subtract(f32(2 * rc), gap, out=r)
            gap *= r  # rc^2 - (r - a)^2
            np.sqrt(gap, out=gap)
            t += (z0 + rc).astype(f32)[e]
            t -= gap
        t[beyond > f32((R - RIM_MM) ** 2)] = np.nan
    return t


def _bullnose_tau(qp2: FloatArray, rho: FloatArray, m: FloatArray, tool: Tool) -> FloatArray:
    """tau >= 0 solving f'(r) tau / r = m for the bull-nose profile, by bisection on [0, rho].

    f'(r) = (r - a) / sqrt(rc^2 - (r - a)^2) beyond the flat of radius a, zero within; the
    left side grows with tau, so bisection is safe.
    """
    a, rc = tool.radius - tool.corner_radius, tool.corner_radius
    slopes = m.reshape(len(m), -1)[:, 0]
    rows = np.flatnonzero(slopes > 0)
    if len(rows) < len(slopes):  # level moves: tau = 0 exactly, no bisection
        out = rho * rho.dtype.type(0)  # NaN stays NaN
        if len(rows):
            out[rows] = _bullnose_tau(qp2[rows], rho[rows], m[rows], tool)
        return out
    lo = np.zeros_like(rho)
    hi = rho.copy()
    for _ in range(_BISECTION_STEPS):
        mid = 0.5 * (lo + hi)
        r = np.sqrt(qp2 + mid * mid)
        e = np.clip(r - a, 0.0, rc * (1 - 1e-12))
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = e / np.sqrt(rc * rc - e * e) * np.where(r > 0, mid / np.maximum(r, 1e-300), 0.0)
        grow = slope < m
        lo = np.where(grow, mid, lo)
        hi = np.where(grow, hi, mid)
    return 0.5 * (lo + hi)
