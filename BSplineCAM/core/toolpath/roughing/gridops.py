# SPDX-License-Identifier: LGPL-2.1-or-later
"""Fields and polylines on the grid: bilinear sampling at fractional cell indices, capped
distance transforms, distances to a polyline, polylines cut into short pieces and whether
two of their points coincide."""

from __future__ import annotations

import math

import numpy as np

from ... import kernels
from ...geometry.distance import squared_distance as _squared_distance_numpy
from ...kernels import roughing_kernels as _rk
from ...kernels import roughing_sample_kernels as _sk
from ...typing import FloatArray


def _bilinear(field_: FloatArray, fx: FloatArray, fy: FloatArray) -> FloatArray:
    """Bilinear value at fractional cell indices (column fx, row fy), clamped to the grid."""
    if kernels.use_numba() and field_.dtype == np.float64 and np.ndim(fx) == 1 and \
            np.ndim(fy) == 1:
        try:
            return _sk.bilinear(np.ascontiguousarray(field_),
                                np.ascontiguousarray(fx, dtype=float),
                                np.ascontiguousarray(fy, dtype=float))
        except kernels.KernelUnavailable:
            pass
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
    if kernels.use_numba():
        try:
            return _rk.capped_distance(np.ascontiguousarray(mask, dtype=bool), k, big)
        except kernels.KernelUnavailable:
            pass
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


def grown_capped_distance(dist: FloatArray, added: np.ndarray, cap: float) -> FloatArray:
    """:func:`capped_distance` of a set grown by the cells ``added``, given ``dist``, that of
    the set (the same ``cap``): the smaller of ``dist`` and the capped distance to the added
    cells.  Both are sqrt(min((ceil(cap) + 1)^2, the squared distance to the nearest set
    cell)), so the minimum is the union's to the bit; the distance to the added cells is
    taken over their box grown by the cap only (:func:`capped_distance` crops), which is
    small where a front grows in a pocket."""
    return np.minimum(dist, capped_distance(added, cap))


def squared_distance(mask: np.ndarray) -> FloatArray:
    """Squared Euclidean distance (cells^2) from each cell centre to the nearest set cell
    (:func:`~BSplineCAM.core.geometry.distance.squared_distance`)."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim == 2 and mask.size and kernels.use_numba():
        try:
            return _rk.squared_distance(np.ascontiguousarray(mask))
        except kernels.KernelUnavailable:
            pass
    return _squared_distance_numpy(mask)


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
    if kernels.use_numba():
        try:
            return _rk.polyline_distance(np.ascontiguousarray(pts, dtype=float),
                                         np.ascontiguousarray(path, dtype=float))
        except kernels.KernelUnavailable:
            pass
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


def same_point(a, b) -> bool:
    """``np.allclose(a, b)`` of two points (its tolerances: |a - b| <= 1e-8 + 1e-5 |b| in
    each coordinate, the same float operations), without its array machinery (a polyline's
    closure is asked thousands of times per run); points with a coordinate not finite go to
    ``np.allclose`` itself."""
    xs = np.asarray(a, dtype=float).ravel().tolist()
    ys = np.asarray(b, dtype=float).ravel().tolist()
    if len(xs) != len(ys):
        return bool(np.allclose(a, b))
    for x, y in zip(xs, ys):
        if not (math.isfinite(x) and math.isfinite(y)):
            return bool(np.allclose(a, b))
        if not abs(x - y) <= 1e-08 + 1e-05 * abs(y):
            return False
    return True
