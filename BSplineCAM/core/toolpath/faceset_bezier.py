# SPDX-License-Identifier: LGPL-2.1-or-later
"""Bezier nets of the drop-cutter over trimmed faces (:mod:`.faceset`): Bernstein bases and
Greville design matrices, de Casteljau splits of homogeneous nets ("The NURBS Book" A1.5),
hodograph (second-difference) hulls, and the bounds an affine part plus residual gives on a
sub-patch's coordinates (rational drift, the material's reach)."""

from __future__ import annotations

import math

import numpy as np

from ..typing import FloatArray
from .faceset_params import RIM_ROUNDING_MM


def _bernstein_grid(p: int, q: int) -> FloatArray:
    """Design matrix [1, i/p, j/q] of the (p+1)(q+1) Greville abscissae of a Bezier patch."""
    s, t = np.meshgrid(np.arange(p + 1) / p, np.arange(q + 1) / q, indexing="ij")
    return np.column_stack([np.ones(s.size), s.ravel(), t.ravel()])


def _bernstein(p: int, t: FloatArray) -> FloatArray:
    """Bernstein polynomials of degree p at t (n,): (n, p+1)."""
    i = np.arange(p + 1)
    c = np.array([math.comb(p, k) for k in i], float)
    return c * t[:, None] ** i * (1.0 - t[:, None]) ** (p - i)


def _corner_index(p: int, q: int) -> np.ndarray:
    """Flat indices of the corner control points (0,0), (p,0), (0,q), (p,q) of a (p+1)(q+1) net."""
    return np.array([0, p * (q + 1), q, p * (q + 1) + q])


def _split_into(work: FloatArray, axis: int, left: FloatArray, right: FloatArray) -> None:
    """de Casteljau halving at 1/2 of nets ``work`` (n, d, p+1, q+1; overwritten) along
    ``axis`` (2: u, 3: v), written into ``left`` and ``right`` ("The NURBS Book" A1.5)."""
    w = np.moveaxis(work, axis, 0)
    lv = np.moveaxis(left, axis, 0)
    rv = np.moveaxis(right, axis, 0)
    k = w.shape[0]
    lv[0] = w[0]
    rv[k - 1] = w[k - 1]
    for r in range(1, k):
        w[: k - r] += w[1 : k - r + 1]
        w[: k - r] *= 0.5
        lv[r] = w[0]
        rv[k - 1 - r] = w[k - 1 - r]


def _split_at(net: FloatArray, axis: int, t: FloatArray, keep_left: bool) -> FloatArray:
    """One side of de Casteljau's split of nets (n, d, p+1, q+1) at per-net parameters t (n,)
    along ``axis`` (2: u, 3: v) ("The NURBS Book" A1.5)."""
    w = np.moveaxis(net, axis, 0).copy()
    out = np.empty_like(w)
    k = w.shape[0]
    tt = t.reshape((1, -1) + (1,) * (w.ndim - 2))
    if keep_left:
        out[0] = w[0]
    else:
        out[k - 1] = w[k - 1]
    for r in range(1, k):
        w[: k - r] += tt[0] * (w[1 : k - r + 1] - w[: k - r])
        if keep_left:
            out[r] = w[0]
        else:
            out[k - 1 - r] = w[k - 1 - r]
    return np.moveaxis(out, 0, axis)


def _sub_net(net: FloatArray, s0: FloatArray, s1: FloatArray, t0: FloatArray,
             t1: FloatArray) -> FloatArray:
    """Nets of the sub-boxes [s0, s1] x [t0, t1] (local parameters in [0, 1], s0 < s1, t0 < t1)
    of Bezier nets (n, d, p+1, q+1)."""
    out = _split_at(net, 2, s1, True)
    out = _split_at(out, 2, s0 / s1, False)
    out = _split_at(out, 3, t1, True)
    return _split_at(out, 3, t0 / t1, False)


def _quadratic_bound(a: FloatArray, b: FloatArray, c: FloatArray) -> FloatArray:
    """Largest eigenvalue of [[a, b], [b, c]]: d^T H d <= it * |d|^2 whenever H's diagonal is
    at most (a, c) and its off-diagonal at most b in magnitude."""
    return 0.5 * (a + c) + np.sqrt(0.25 * (a - c) ** 2 + b * b)


def _second_differences(net: FloatArray, p: int, q: int) -> tuple:
    """Bezier coefficients of the second partial derivatives (ss, st, tt) of scalar nets
    (..., p+1, q+1) on the unit box (hodographs; zeros where the degree is 1)."""
    z = np.zeros(net.shape[:-2] + (1, 1))
    ss = (p * (p - 1) * (net[..., 2:, :] - 2 * net[..., 1:-1, :] + net[..., :-2, :])
          if p >= 2 else z)
    tt = (q * (q - 1) * (net[..., :, 2:] - 2 * net[..., :, 1:-1] + net[..., :, :-2])
          if q >= 2 else z)
    st = p * q * (net[..., 1:, 1:] - net[..., :-1, 1:] - net[..., 1:, :-1] + net[..., :-1, :-1])
    return ss, st, tt


def _rational_drift(w: FloatArray, coef: FloatArray) -> FloatArray:
    """Bound on how far a rational patch's coordinate can exceed its control values' affine
    part a(s, t) = c0 + c1 s + c2 t taken at (s, t) (n,), from the weights w (n, K) and coef
    (n, 3).  The coordinate is sum lam_k x_k with lam_k = w_k B_k / sum w_j B_j, so its affine
    part is a at g = sum lam_k g_k (g_k the Greville abscissae, in the unit box), not at
    (s, t) = sum B_k g_k: |g - (s, t)| <= sum |lam_k - B_k| |g_k - (s, t)| <= sqrt(2) eps with
    eps = (w_max - w_min) / w_min (|lam_k - B_k| <= B_k eps), so the coordinate is at most
    a(s, t) + |(c1, c2)| sqrt(2) eps + the residual.  Subdivision evens the weights out, so
    the drift shrinks as the square of the sub-patch (a polynomial patch has none)."""
    wmin = w.min(axis=1)
    eps = (w.max(axis=1) - wmin) / wmin
    return math.sqrt(2.0) * eps * np.hypot(coef[:, 1], coef[:, 2])


def _material_reach(st: FloatArray, ok: np.ndarray, k: int, node: np.ndarray, q: FloatArray,
                    centroid: tuple, C: FloatArray, RS: FloatArray,
                    w: FloatArray | None) -> tuple[FloatArray, FloatArray]:
    """Upper bound of z and lower bound of the xy distance from q (m, 2) over the material
    of sub-patches ``node`` (m,) whose material polygon has its vertices among ``st``
    (m, 4 + 2k, 2), local (s, t), where ``ok`` (m, 4 + 2k): the corners, then the first and
    the second ends of k clipped trim segments (as :meth:`.faceset_trims._FaceData.vertices`).

    Each coordinate is its control values' affine part a(s, t) (``C``, about the net's
    ``centroid``) plus at most its largest residual (``RS``; for a rational patch plus the
    drift of :func:`_rational_drift`, from the weights ``w``), and an affine map takes the
    polygon into the hull of its vertices' images.  So z is at most the largest a_z at a
    vertex plus its residual, and the xy distance at least the hull's distance from q, less
    the xy residual: the hull lies beyond the line of any unit normal nu at min_v nu . (a(v)
    - q), tried along the images of the box's sides and of the trim segments (the material's
    edges) and towards the nearest vertex.  Both converge as the square of the sub-patch,
    where the box of the net converges linearly, and near the ball's rim f's slope across it
    grows as R / sqrt(R^2 - r^2)."""
    cx, cy, cz = (c[node] for c in centroid)
    s_, t_ = st[..., 0], st[..., 1]
    cX, cY, cZ = C[1, node], C[2, node], C[0, node]
    ax = (cx + cX[:, 0])[:, None] + cX[:, 1:2] * s_ + cX[:, 2:3] * t_ - q[:, :1]
    ay = (cy + cY[:, 0])[:, None] + cY[:, 1:2] * s_ + cY[:, 2:3] * t_ - q[:, 1:]
    az = (cz + cZ[:, 0])[:, None] + cZ[:, 1:2] * s_ + cZ[:, 2:3] * t_
    rx, ry, rz = (np.abs(RS[j, node]).max(axis=1) for j in (1, 2, 0))
    if w is not None:
        rx = rx + _rational_drift(w, cX)
        ry = ry + _rational_drift(w, cY)
        rz = rz + _rational_drift(w, cZ)
    z_top = np.where(ok, az, -np.inf).max(axis=1) + rz
    # candidate normals (m, D): the images of the box's sides (s and t), of the trim
    # segments, and the direction of the nearest vertex
    tx = [cX[:, 1], cX[:, 2]]
    ty = [cY[:, 1], cY[:, 2]]
    if k:
        ds = st[:, 4 + k:, 0] - st[:, 4:4 + k, 0]
        dt = st[:, 4 + k:, 1] - st[:, 4:4 + k, 1]
        tx.append(cX[:, 1:2] * ds + cX[:, 2:3] * dt)
        ty.append(cY[:, 1:2] * ds + cY[:, 2:3] * dt)
    dist2 = np.where(ok, ax * ax + ay * ay, np.inf)
    j = np.argmin(dist2, axis=1)
    rows = np.arange(len(node))
    nx = np.column_stack(tuple(-v for v in ty) + (ax[rows, j],))
    ny = np.column_stack(tuple(tx) + (ay[rows, j],))
    length = np.hypot(nx, ny)
    usable = length > 0
    nx = nx / np.where(usable, length, 1.0)
    ny = ny / np.where(usable, length, 1.0)
    gap = np.zeros(len(node))
    for c in range(nx.shape[1]):
        proj = nx[:, c:c + 1] * ax + ny[:, c:c + 1] * ay  # (m, V)
        lo = np.where(ok, proj, np.inf).min(axis=1)
        hi = np.where(ok, proj, -np.inf).max(axis=1)
        gap = np.maximum(gap, np.where(usable[:, c], np.maximum(lo, -hi), 0.0))
    # less the residual, and a margin for rounding (coordinates of order 1e2 mm)
    r = np.maximum(gap - np.hypot(rx, ry) - RIM_ROUNDING_MM, 0.0)
    return z_top, r
