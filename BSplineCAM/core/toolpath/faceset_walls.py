# SPDX-License-Identifier: LGPL-2.1-or-later
"""Vertical check faces (walls) of the drop-cutter (:mod:`.faceset`), met by the 3-D chords of
their trimmed borders in closed form instead of by branch and bound."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .. import kernels
from ..geometry.faces import Face
from ..kernels import faceset_wall_kernels as wk
from ..numeric import clamp
from ..typing import FloatArray
from .faceset_params import TOUCH

#: Chords per run of the compiled drop's skip test (:attr:`_Walls.block_lo`).
WALL_BLOCK = 16


def _vertical(s) -> bool:
    """Whether the surface is ruled by vertical lines: along one parameter direction every
    row of poles shares its xy (and its weight), so each (u or v) iso-line is a vertical
    segment: a wall, a vertical cylinder, any extrusion along Z."""
    P = s.poles
    W = s.weights if s.weights is not None else np.ones(P.shape[:2])
    size = float(np.ptp(P.reshape(-1, 3), axis=0).max()) or 1.0
    for axis in (0, 1):
        dev = np.abs(P[..., :2] - np.take(P[..., :2], [0], axis=axis)).max()
        wdev = np.abs(W - np.take(W, [0], axis=axis)).max()
        if dev <= 1e-12 * size and wdev <= 1e-12 * float(W.max()) and P.shape[axis] > 1:
            return True
    return False


class _Walls:
    """Vertical check faces by their borders.

    On a face ruled by vertical lines, f = p_z + sqrt(R^2 - |p_xy - q|^2) grows with p_z along
    each ruling (xy fixed), so its maximum over the material lies where a ruling leaves it: on
    the trim loops.  Each loop segment maps to a 3-D chord of the border (exact for planar
    walls, within the trim tolerance on curved ones, as everywhere else trims are met), and
    along a chord f(t) is concave (f is concave in p, p affine in t): its maximum over the
    reachable part of [0, 1] is the stationary point of f' = 0 in closed form, clipped.  So a
    wall costs a few array operations per segment instead of a branch and bound whose best
    contacts tie with the neighbouring face's along their shared edge."""

    def __init__(self, faces: Sequence[Face], index: Sequence[int]):
        segs, owner, uv = [], [], []
        self.boxes = []
        for f, k in zip(faces, index):
            e = f._edges
            a = f.surface.evaluate(e[:, 0], e[:, 1])
            b = f.surface.evaluate(e[:, 2], e[:, 3])
            segs.append(np.stack([a, b], axis=1))
            owner.append(np.full(len(e), k))
            uv.append(e)
            pts = np.concatenate([a, b])
            self.boxes.append((pts.min(axis=0), pts.max(axis=0)))
        self.seg = np.concatenate(segs) if segs else np.zeros((0, 2, 3))
        self.owner = np.concatenate(owner) if owner else np.zeros(0, int)
        self.uv = np.concatenate(uv) if uv else np.zeros((0, 4))
        self.boxes_of_chords()

    def boxes_of_chords(self) -> None:
        """The chords' xy boxes (``lo``, ``hi``) and those of runs of WALL_BLOCK chords
        (``block_lo``, ``block_hi``; NaN boxes left out): the compiled drop passes over a run
        out of reach whole."""
        self.lo = self.seg[:, :, :2].min(axis=1)
        self.hi = self.seg[:, :, :2].max(axis=1)
        self.block = WALL_BLOCK
        starts = np.arange(0, len(self.seg), self.block)
        if len(starts):
            self.block_lo = np.fmin.reduceat(self.lo, starts, axis=0)
            self.block_hi = np.fmax.reduceat(self.hi, starts, axis=0)
        else:
            self.block_lo = self.block_hi = np.zeros((0, 2))

    def drop(self, q: FloatArray, R: float):
        """(best centre height, face, u, v) over the walls' borders for queries q (m, 2)."""
        m = len(q)
        best = np.full(m, -np.inf)
        face = np.full(m, -1)
        bu = np.zeros(m)
        bv = np.zeros(m)
        if len(self.seg) == 0:
            return best, face, bu, bv
        if kernels.use_numba():
            try:
                return wk.drop(np.ascontiguousarray(q, dtype=float), float(R), self.lo,
                               self.hi, self.seg, self.owner, self.uv, TOUCH, self.block_lo,
                               self.block_hi, self.block)
            except kernels.KernelUnavailable:
                pass
        dx = np.maximum(np.maximum(self.lo[None, :, 0] - q[:, :1], q[:, :1] - self.hi[None, :, 0]), 0)
        dy = np.maximum(np.maximum(self.lo[None, :, 1] - q[:, 1:], q[:, 1:] - self.hi[None, :, 1]), 0)
        qi, si = np.nonzero(dx * dx + dy * dy <= R * R)
        if len(qi) == 0:
            return best, face, bu, bv
        a = self.seg[si, 0]
        d = self.seg[si, 1] - a
        e = a[:, :2] - q[qi]
        L = (d[:, :2] ** 2).sum(axis=1)
        ed = (e * d[:, :2]).sum(axis=1)
        ee = (e * e).sum(axis=1)
        R2 = R * R
        # reachable t: L t^2 + 2 ed t + ee - R^2 <= 0
        flat = L <= 1e-300
        Ls = np.where(flat, 1.0, L)
        disc = ed * ed - L * (ee - R2)
        root = np.sqrt(np.maximum(disc, 0.0))
        t1 = np.where(flat, 0.0, (-ed - root) / Ls)
        t2 = np.where(flat, 1.0, (-ed + root) / Ls)
        ok = np.where(flat, ee <= R2, disc >= 0)
        lo_t = np.maximum(t1, 0.0)
        hi_t = np.minimum(t2, 1.0)
        ok &= lo_t <= hi_t
        # stationary point of f(t): tau = t + ed / L, L tau^2 (L + dz^2) = dz^2 (R^2 - e_perp^2)
        dz = d[:, 2]
        perp = np.maximum(ee - ed * ed / Ls, 0.0)
        tau = np.sign(dz) * np.abs(dz) * np.sqrt(np.maximum(R2 - perp, 0.0)
                                                 / (Ls * (Ls + dz * dz)))
        t = np.where(flat, np.where(dz >= 0, hi_t, lo_t), tau - ed / Ls)
        t = clamp(t, lo_t, hi_t)

        def f_at(tt):
            p = a + tt[:, None] * d
            r2 = ((p[:, :2] - q[qi]) ** 2).sum(axis=1)
            return np.where(ok & (r2 <= R2 * TOUCH), p[:, 2] + np.sqrt(np.maximum(R2 - r2, 0)),
                            -np.inf)

        # the clipped stationary point is the maximum of the concave f; the ends of the
        # reachable interval are checked too, against rounding
        cands = [t, lo_t, hi_t]
        vals = np.stack([f_at(c) for c in cands])
        k = np.argmax(vals, axis=0)
        fv = vals[k, np.arange(len(qi))]
        tb = np.choose(k, cands)
        order = np.argsort(fv, kind="stable")  # later (larger) assignments win
        qi, si, fv, tb = qi[order], si[order], fv[order], tb[order]
        good = np.isfinite(fv)
        qi, si, fv, tb = qi[good], si[good], fv[good], tb[good]
        best[qi] = fv
        face[qi] = self.owner[si]
        uvs = self.uv[si]
        bu[qi] = uvs[:, 0] + tb * (uvs[:, 2] - uvs[:, 0])
        bv[qi] = uvs[:, 1] + tb * (uvs[:, 3] - uvs[:, 1])
        return best, face, bu, bv

    def points(self, k: int, u: FloatArray, v: FloatArray) -> FloatArray:
        """The 3-D contact (m, 3) that :meth:`drop` measured for contacts (u, v) on wall ``k``:
        the point of the border chord whose trim segment holds (u, v), at the same fraction
        along it.  On a curved wall it differs from the surface at (u, v) by up to the trim
        tolerance, and the height's slope (envelope theorem) must come from the chord's
        point, the one the height was measured at."""
        mine = np.flatnonzero(self.owner == k)
        uv = np.column_stack([u, v]).astype(float)
        out = np.full((len(uv), 3), np.nan)
        if len(mine) == 0 or len(uv) == 0:
            return out
        e = self.uv[mine]
        a, dd = e[:, :2], e[:, 2:] - e[:, :2]
        L2 = (dd * dd).sum(axis=1)
        L2s = np.where(L2 > 0, L2, 1.0)
        step = max(1, 2 ** 20 // len(mine))  # bounded memory: queries x segments per block
        for start in range(0, len(uv), step):
            w = uv[start:start + step]
            rel = w[:, None, :] - a[None]
            t = np.clip((rel * dd[None]).sum(axis=2) / L2s[None], 0.0, 1.0)
            off = rel - t[..., None] * dd[None]
            j = np.argmin((off * off).sum(axis=2), axis=1)
            rows = np.arange(len(w))
            seg = self.seg[mine[j]]
            tj = t[rows, j]
            out[start:start + step] = seg[:, 0] + tj[:, None] * (seg[:, 1] - seg[:, 0])
        return out
