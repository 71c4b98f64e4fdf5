# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the drop-cutter's walls (:class:`~BSplineCAM.core.toolpath.
faceset_walls._Walls`): the ball's highest rest on the walls' border chords, one query and
chord at a time where the numpy engine broadcasts every query against every chord.

The arithmetic is the numpy engine's, operation by operation (``np.maximum`` and
``np.minimum`` with their NaN rule, ``np.sign``'s zero, ``np.argmax``'s first of equals), and
so are the choices: each query takes its largest finite value, the last chord of equals.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .scalars import nan_max, nan_min


@helper
def _rest(a0, a1, a2, d0, d1, d2, qx, qy, R2, touch_R2, ok, tt):
    """The centre height of the ball above (qx, qy) resting on the chord's point a + tt d
    (-inf unless ``ok`` and within reach: ``faceset_walls._Walls.drop``'s ``f_at``)."""
    p0 = a0 + tt * d0
    p1 = a1 + tt * d1
    p2 = a2 + tt * d2
    r2 = (p0 - qx) ** 2 + (p1 - qy) ** 2
    if ok and r2 <= touch_R2:
        return p2 + math.sqrt(nan_max(R2 - r2, 0.0))
    return -np.inf


def _drop_loops(q, R, lo, hi, seg, owner, uv, touch, block_lo, block_hi, block):
    """(best centre height, face, u, v) over the chords ``seg`` (S, 2, 3) (xy boxes ``lo``,
    ``hi`` (S, 2), wall ``owner`` (S,), trim segment ``uv`` (S, 4)) for queries q (m, 2)
    and a ball of radius R (``faceset_walls._Walls.drop``).  The chords come in runs of
    ``block``, run b's xy box (``block_lo``, ``block_hi`` (B, 2)) holding its chords' boxes:
    a run out of the ball's reach is passed over whole (each of its chords fails the same
    test, rounding being monotonic), the others chord by chord in order."""
    m = q.shape[0]
    S = seg.shape[0]
    B = block_lo.shape[0]
    best = np.full(m, -np.inf)
    face = np.full(m, -1, np.int64)
    bu = np.zeros(m)
    bv = np.zeros(m)
    R2 = R * R
    touch_R2 = R2 * touch
    cand = np.empty(3)
    for i in range(m):
        qx = q[i, 0]
        qy = q[i, 1]
        for b in range(B):
            dx = nan_max(nan_max(block_lo[b, 0] - qx, qx - block_hi[b, 0]), 0.0)
            dy = nan_max(nan_max(block_lo[b, 1] - qy, qy - block_hi[b, 1]), 0.0)
            if not dx * dx + dy * dy <= R * R:
                continue
            for s in range(b * block, min(S, (b + 1) * block)):
                dx = nan_max(nan_max(lo[s, 0] - qx, qx - hi[s, 0]), 0.0)
                dy = nan_max(nan_max(lo[s, 1] - qy, qy - hi[s, 1]), 0.0)
                if dx * dx + dy * dy <= R * R:
                    _chord(R2, touch_R2, seg, owner, uv, cand, i, qx, qy, s, best, face, bu,
                           bv)
    return best, face, bu, bv


@helper
def _chord(R2, touch_R2, seg, owner, uv, cand, i, qx, qy, s, best, face, bu, bv):
    """Query ``i``'s best rest on chord ``s`` (whose xy box is within its reach:
    :func:`_drop_loops`), into ``best``, ``face``, ``bu``, ``bv`` where it is at least the
    best so far."""
    a0 = seg[s, 0, 0]
    a1 = seg[s, 0, 1]
    a2 = seg[s, 0, 2]
    d0 = seg[s, 1, 0] - a0
    d1 = seg[s, 1, 1] - a1
    d2 = seg[s, 1, 2] - a2
    e0 = a0 - qx
    e1 = a1 - qy
    L = d0 ** 2 + d1 ** 2
    ed = e0 * d0 + e1 * d1
    ee = e0 * e0 + e1 * e1
    # reachable t: L t^2 + 2 ed t + ee - R^2 <= 0
    flat = L <= 1e-300
    Ls = 1.0 if flat else L
    disc = ed * ed - L * (ee - R2)
    root = math.sqrt(nan_max(disc, 0.0))
    t1 = 0.0 if flat else (-ed - root) / Ls
    t2 = 1.0 if flat else (-ed + root) / Ls
    ok = (ee <= R2) if flat else (disc >= 0)
    lo_t = nan_max(t1, 0.0)
    hi_t = nan_min(t2, 1.0)
    ok = ok and lo_t <= hi_t
    # the stationary point of the concave f(t)
    perp = nan_max(ee - ed * ed / Ls, 0.0)
    sign = 1.0 if d2 > 0 else (-1.0 if d2 < 0 else (d2 if d2 != d2 else 0.0))
    tau = sign * abs(d2) * math.sqrt(nan_max(R2 - perp, 0.0) / (Ls * (Ls + d2 * d2)))
    t = (hi_t if d2 >= 0 else lo_t) if flat else tau - ed / Ls
    cand[0] = nan_min(nan_max(t, lo_t), hi_t)
    cand[1] = lo_t
    cand[2] = hi_t
    fv = -np.inf
    k = 0
    for c in range(3):
        x = _rest(a0, a1, a2, d0, d1, d2, qx, qy, R2, touch_R2, ok, cand[c])
        if c == 0:
            fv = x
        elif fv == fv and (x > fv or x != x):
            fv = x
            k = c
    if math.isfinite(fv) and fv >= best[i]:
        tb = cand[k]
        best[i] = fv
        face[i] = owner[s]
        bu[i] = uv[s, 0] + tb * (uv[s, 2] - uv[s, 0])
        bv[i] = uv[s, 1] + tb * (uv[s, 3] - uv[s, 1])


drop = Kernel(_drop_loops)
