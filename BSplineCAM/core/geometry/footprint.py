# SPDX-License-Identifier: LGPL-2.1-or-later
"""Height of the design surface above points of its XY footprint: z where S_xy(u, w) = (x, y).

Vectorised Newton inversion of the footprint map (u, w) -> (x, y).  Seeds come from a dense
parameter grid splatted into an XY lookup raster (the top-most sample wins, as a Z-map sees
the top of an overhang), refined by one linear step with the sample's Jacobian; Newton then
converges in two or three steps.  Points whose clamped Newton iterate does not reach them
lie outside the footprint.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from ..threads import numpy_threads
from ..typing import ArrayLike, FloatArray
from .matrix import evaluate_patch_orders
from .surface import Surface

#: A point is on the footprint when Newton lands within this distance of it (mm).
INSIDE_TOLERANCE_MM = 1e-7
NEWTON_STEPS = 12
_LOOKUP = 256
_CHUNK = 1 << 17


def surface_height(surface: Surface, x: ArrayLike,
                   y: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray]:
    """Design height z (mm) and parameters (u, w) at points (x, y); x and y broadcast.

    Returns ``(z, u, w, inside)``; where ``inside`` is False (the point is off the footprint)
    z, u and w are NaN.
    """
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    shape = x.shape
    px, py = x.ravel(), y.ravel()
    seeds = _Seeds(surface)
    z = np.full(px.size, np.nan)
    u = np.full(px.size, np.nan)
    w = np.full(px.size, np.nan)
    inside = np.zeros(px.size, dtype=bool)
    surface.patch_form  # noqa: B018 - built once here, not raced for by the threads

    def run(lo: int) -> None:
        sl = slice(lo, lo + _CHUNK)
        z[sl], u[sl], w[sl], inside[sl] = _invert(surface, seeds, px[sl], py[sl])

    # chunks are independent and write disjoint slices; numpy releases the GIL in its loops
    starts = range(0, px.size, _CHUNK)
    threads = min(numpy_threads(), len(starts))
    if threads <= 1:
        for lo in starts:
            run(lo)
    else:
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(run, starts))
    return z.reshape(shape), u.reshape(shape), w.reshape(shape), inside.reshape(shape)


def footprint_bounds(surface: Surface, samples: int = 201) -> tuple[float, float, float, float]:
    """XY bounding box (x_min, x_max, y_min, y_max) of the surface, from a dense sample (mm)."""
    pts = surface.grid(samples, samples)
    return (float(pts[..., 0].min()), float(pts[..., 0].max()),
            float(pts[..., 1].min()), float(pts[..., 1].max()))


class _Seeds:
    """Lookup raster over the footprint's bounding box: sample parameters per XY cell."""

    def __init__(self, surface: Surface) -> None:
        rows, cols = surface.shape
        n = max(3 * _LOOKUP, 16 * max(rows, cols))
        pu = np.linspace(0.0, 1.0, n)
        pw = np.linspace(0.0, 1.0, n)
        p = surface.evaluate_grid(pu, pw)
        su = surface.evaluate_grid(pu, pw, 1, 0)
        sw = surface.evaluate_grid(pu, pw, 0, 1)
        self.lo = np.array([p[..., 0].min(), p[..., 1].min()])
        span = np.array([p[..., 0].max(), p[..., 1].max()]) - self.lo
        self.step = max(float(span.max()), 1e-9) / _LOOKUP
        self.shape = tuple(int(v) for v in np.ceil(np.maximum(span, 1e-9) / self.step) + 1)
        flat_p = p.reshape(-1, 3)
        cell = self._cell(flat_p[:, 0], flat_p[:, 1])
        order = np.argsort(flat_p[:, 2], kind="stable")  # later (higher) samples overwrite
        table = np.full(self.shape[0] * self.shape[1], -1, dtype=np.int64)
        table[cell[order]] = order
        table = fill_empty_cells(table.reshape(self.shape), 3)
        self.table = table
        self.u = np.repeat(pu, n)
        self.w = np.tile(pw, n)
        self.xy = flat_p[:, :2]
        self.jac = np.stack([su.reshape(-1, 3)[:, :2], sw.reshape(-1, 3)[:, :2]], axis=-1)

    def _cell(self, x: FloatArray, y: FloatArray) -> np.ndarray:
        i = np.clip(np.floor((x - self.lo[0]) / self.step).astype(np.int64), 0, self.shape[0] - 1)
        j = np.clip(np.floor((y - self.lo[1]) / self.step).astype(np.int64), 0, self.shape[1] - 1)
        return i * self.shape[1] + j

    def seed(self, x: FloatArray, y: FloatArray) -> tuple[FloatArray, FloatArray, np.ndarray]:
        """Seed parameters, and whether the point is near enough the footprint to try."""
        outside_box = ((x < self.lo[0] - 2 * self.step) | (y < self.lo[1] - 2 * self.step)
                       | (x > self.lo[0] + (self.shape[0] + 1) * self.step)
                       | (y > self.lo[1] + (self.shape[1] + 1) * self.step))
        k = self.table.ravel()[self._cell(x, y)]
        near = (k >= 0) & ~outside_box
        k = np.where(near, k, 0)
        delta = np.stack([x, y], axis=-1) - self.xy[k]
        jac = self.jac[k]
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        det = np.where(np.abs(det) > 1e-300, det, 1.0)
        du = (jac[:, 1, 1] * delta[:, 0] - jac[:, 0, 1] * delta[:, 1]) / det
        dw = (jac[:, 0, 0] * delta[:, 1] - jac[:, 1, 0] * delta[:, 0]) / det
        return (np.clip(self.u[k] + du, 0.0, 1.0), np.clip(self.w[k] + dw, 0.0, 1.0), near)


def fill_empty_cells(table: np.ndarray, passes: int) -> np.ndarray:
    """Give empty lookup cells (index -1) a neighbour's sample, ``passes`` cells deep: the seed
    tables of one surface (here) and of a model's faces (faces_height) fill their gaps alike."""
    for _ in range(passes):
        empty = table < 0
        if not np.any(empty):
            break
        source = table.copy()
        for axis in (0, 1):
            for shift in (1, -1):
                rolled = np.roll(table, shift, axis=axis)
                edge = [slice(None)] * 2
                edge[axis] = 0 if shift == 1 else -1
                rolled[tuple(edge)] = -1
                take = (source < 0) & (rolled >= 0)
                source[take] = rolled[take]
        table = source
    return table


def _invert(surface: Surface, seeds: _Seeds, x: FloatArray,
            y: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray]:
    """Newton on S_xy(u, w) = (x, y) from the seeds, clamped to [0, 1]^2, active set only."""
    u, w, near = seeds.seed(x, y)
    z = np.full(x.size, np.nan)
    inside = np.zeros(x.size, dtype=bool)
    active = np.flatnonzero(near)
    for step in range(NEWTON_STEPS):
        if not len(active):
            break
        ua, wa = u[active], w[active]
        # the point first: most seeds land within the tolerance at once and need no
        # derivatives (a third of the work of point and both derivatives)
        (p,) = evaluate_patch_orders(surface.patch_form, ua, wa, ((0, 0),))
        rx = x[active] - p[:, 0]
        ry = y[active] - p[:, 1]
        ok = np.hypot(rx, ry) <= INSIDE_TOLERANCE_MM
        z[active[ok]] = p[ok, 2]
        inside[active[ok]] = True
        rest = ~ok
        active, ua, wa, rx, ry = active[rest], ua[rest], wa[rest], rx[rest], ry[rest]
        if not len(active):
            break
        su, sw = evaluate_patch_orders(surface.patch_form, ua, wa, ((1, 0), (0, 1)))
        ok = np.zeros(len(active), dtype=bool)
        det = su[:, 0] * sw[:, 1] - sw[:, 0] * su[:, 1]
        det = np.where(np.abs(det) > 1e-300, det, 1e-300)
        du = (sw[:, 1] * rx - sw[:, 0] * ry) / det
        dw = (su[:, 0] * ry - su[:, 1] * rx) / det
        scale = np.minimum(1.0, 0.25 / np.maximum(np.hypot(du, dw), 1e-300))  # damp wild steps
        tu = ua + scale * du
        tw = wa + scale * dw
        # an iterate held on the domain's edge by a step that leaves it: the point is outside
        leaving = (((ua == 0.0) & (tu < 0.0)) | ((ua == 1.0) & (tu > 1.0))
                   | ((wa == 0.0) & (tw < 0.0)) | ((wa == 1.0) & (tw > 1.0)))
        leaving &= step >= 2
        keep = ~ok & ~leaving
        u[active[keep]] = np.clip(tu[keep], 0.0, 1.0)
        w[active[keep]] = np.clip(tw[keep], 0.0, 1.0)
        active = active[keep]
    u = np.where(inside, u, np.nan)
    w = np.where(inside, w, np.nan)
    return z, u, w, inside
