# SPDX-License-Identifier: LGPL-2.1-or-later
"""Subdivision of the drop-cutter's sub-patches (:mod:`.faceset`): each open sub-patch is
halved along its longer side by de Casteljau's algorithm, or split along a side of its face's
certified region, and its halves classified against the trim.  Under the numba engine
(:mod:`..kernels`) the halving and the splits run as compiled loops
(:mod:`..kernels.faceset_kernels`), the same arithmetic."""

from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels import faceset_kernels as fk
from ..kernels import faceset_round_kernels as rk
from ..typing import FloatArray
from .faceset_bezier import _split_at, _split_into
from .faceset_params import CUT_MARGIN, MAX_DEPTH, MAX_OPEN, MAX_SEGMENTS
from .faceset_trims import _FaceData, _Items


def children(d: _FaceData, it: _Items, mask: np.ndarray | None = None,
             cut: tuple | None = None) -> _Items:
    """Halve each sub-patch (those in ``mask``) along its longer side (corner distances);
    with ``cut`` = (t, along_u) (n,) each, a sub-patch whose t is finite is split at its
    local parameter t along u (along_u) or v instead.

    Halving depends on the sub-patch alone, and the queries of a pass share their shallow
    sub-patches: each node of the table is halved once, its halves shared (the pieces of
    a split at a region's side, which depends on the query, are the pair's own)."""
    idx_all = np.arange(len(it.query)) if mask is None else np.flatnonzero(mask)
    free = np.ones(len(idx_all), bool)
    if cut is not None:
        t_all = cut[0][idx_all]
        free = ~np.isfinite(t_all)
    nets, boxes, parents, nodes = [], [], [], []
    count = 0
    fi = idx_all[free]
    if len(fi):
        un, inv = np.unique(it.node[fi], return_inverse=True)
        inv = inv.ravel()
        along_u, left, right = _halve(d, it.nets[un])
        b = it.box[fi]
        au = along_u[inv]
        mu = 0.5 * (b[:, 0] + b[:, 1])
        mv = 0.5 * (b[:, 2] + b[:, 3])
        bl, br = b.copy(), b.copy()
        bl[:, 1] = np.where(au, mu, b[:, 1])
        br[:, 0] = np.where(au, mu, b[:, 0])
        bl[:, 3] = np.where(au, b[:, 3], mv)
        br[:, 2] = np.where(au, b[:, 2], mv)
        nets += [left, right]
        boxes += [bl, br]
        parents += [fi, fi]
        nodes += [inv, len(un) + inv]
        count = 2 * len(un)
    ci = idx_all[~free]
    if len(ci):
        t = t_all[~free]
        along = cut[1][ci]
        b = it.box[ci]
        for axis, sel in ((2, along), (3, ~along)):
            idx = ci[sel]
            m = len(idx)
            if m == 0:
                continue
            lo, hi = (0, 1) if axis == 2 else (2, 3)
            tt = t[sel]
            bb = b[sel]
            mid = bb[:, lo] + tt * (bb[:, hi] - bb[:, lo])
            b0, b1 = bb.copy(), bb.copy()
            b0[:, hi] = mid
            b1[:, lo] = mid
            nets += list(_split_both(it.nets[it.node[idx]], axis, tt))
            boxes += [b0, b1]
            parents += [idx, idx]
            nodes += [count + np.arange(m), count + m + np.arange(m)]
            count += 2 * m
    if not parents:
        return it.take(np.zeros(0, np.intp))
    out = np.concatenate(nets)
    box = np.concatenate(boxes)
    parent = np.concatenate(parents)
    node = np.concatenate(nodes)
    n2 = len(parent)
    status = np.ones(n2, np.int8)
    segs = np.full((n2, MAX_SEGMENTS), -1, dtype=np.int64)
    strad = np.flatnonzero(it.status[parent] == 2)
    if len(strad):
        status[strad], segs[strad] = d.classify(box[strad], it.segs[parent[strad]])
    pieces = _Items(it.query[parent], node, out, box, it.depth[parent] + 1, status, segs)
    keep = status > 0
    return pieces if keep.all() else pieces.take(keep)


def open_children(j: int, d: _FaceData, it: _Items, ub: FloatArray, best: FloatArray,
                  gap: FloatArray, reg_box: FloatArray, reg_val: FloatArray,
                  given_up: np.ndarray, certify: float, crowded: np.ndarray) -> tuple:
    """The compiled level's end for face row ``j`` (:func:`..kernels.faceset_round_kernels.
    open_split`): the pairs still open (``faceset_branch._open_pairs``; ``gap`` and
    ``crowded`` updated in place) cut along their regions' sides (:func:`region_cuts`) or
    halved, as :func:`children` of them: (halves, pairs left uncertified).  Raises
    :class:`..kernels.KernelUnavailable` where the kernel cannot run."""
    bands = d._bands
    unc, parent, query, node, nets, box, depth, status, segs, done = rk.open_split(
        j, np.ascontiguousarray(it.query, dtype=np.int64),
        np.ascontiguousarray(it.node, dtype=np.int64), np.ascontiguousarray(it.nets),
        np.ascontiguousarray(it.box, dtype=float), np.ascontiguousarray(it.depth, np.int64),
        np.ascontiguousarray(it.status, dtype=np.int8),
        np.ascontiguousarray(it.segs, dtype=np.int64), ub, best, gap, reg_box, reg_val,
        given_up, float(certify), MAX_DEPTH, MAX_OPEN, CUT_MARGIN,
        bool(d.face.surface.rational), d.edges, bands.table, float(bands.v0), float(bands.h),
        d._inner, crowded)
    pieces = _Items(query, node, nets, box, depth, status, segs)
    if done:
        return pieces, int(unc)
    # parents crossed by more trim segments than listed: classified against all
    todo = np.flatnonzero(status < 0)
    status[todo], segs[todo] = d.classify(box[todo], it.segs[parent[todo]])
    keep = status > 0
    return (pieces if keep.all() else pieces.take(keep)), int(unc)


_halve_kernel = kernels.Kernel(fk.halve)
_split_at_kernel = kernels.Kernel(fk.split_at)


def _halve(d: _FaceData, pn: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
    """Whether each net (U, 4, p+1, q+1) is halved along u (its longer side) and its left and
    right halves (de Casteljau at 1/2)."""
    if kernels.use_numba():
        try:
            return _halve_kernel(np.ascontiguousarray(pn, dtype=float),
                                 bool(d.face.surface.rational))
        except kernels.KernelUnavailable:
            pass
    along_u = _longer_u(d, pn)
    left = np.empty_like(pn)
    right = np.empty_like(pn)
    for axis, sel in ((2, along_u), (3, ~along_u)):
        if sel.any():
            k = np.flatnonzero(sel)
            lk = np.empty_like(pn[k])
            rk = np.empty_like(lk)
            _split_into(pn[k], axis, lk, rk)
            left[k], right[k] = lk, rk
    return along_u, left, right


def _split_both(pn: FloatArray, axis: int, t: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Both sides of de Casteljau's split of nets ``pn`` at local parameters ``t`` along
    ``axis`` (2: u, 3: v)."""
    if kernels.use_numba():
        try:
            return _split_at_kernel(np.ascontiguousarray(pn, dtype=float),
                                    np.full(len(pn), axis == 2),
                                    np.ascontiguousarray(t, dtype=float))
        except kernels.KernelUnavailable:
            pass
    return _split_at(pn, axis, t, True), _split_at(pn, axis, t, False)


def _longer_u(d: _FaceData, net: FloatArray) -> np.ndarray:
    """Whether each net's u side is the longer (the sum of its corners' xy distances)."""
    k2, k3 = net.shape[2] - 1, net.shape[3] - 1
    corner = net[:, :, ::k2, ::k3]  # (n, 4, 2, 2)
    if d.face.surface.rational:
        corner = corner[:, :2] / corner[:, 3:]
    len_u = np.abs(corner[:, :2, 1] - corner[:, :2, 0]).sum(axis=(1, 2))
    len_v = np.abs(corner[:, :2, :, 1] - corner[:, :2, :, 0]).sum(axis=(1, 2))
    return len_u >= len_v


def region_cuts(it: _Items, open_: np.ndarray, rb: FloatArray,
                inreg: np.ndarray) -> tuple[FloatArray, np.ndarray]:
    """Where an open sub-patch overlaps its face's certified region, split it along a side
    of the region instead of at its middle (the side cutting it most evenly, if it cuts it
    between CUT_MARGIN and 1 - CUT_MARGIN), so that the piece inside the region is dropped
    after a few splits instead of being halved down to the region's scale."""
    b = it.box
    over = (open_ & inreg & (b[:, 0] < rb[:, 1]) & (b[:, 1] > rb[:, 0])
            & (b[:, 2] < rb[:, 3]) & (b[:, 3] > rb[:, 2]))
    t = np.full(len(b), np.nan)
    along_u = np.zeros(len(b), bool)
    if not over.any():
        return t, along_u
    wu = b[:, 1] - b[:, 0]
    wv = b[:, 3] - b[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        cand = np.column_stack([(rb[:, 0] - b[:, 0]) / wu, (rb[:, 1] - b[:, 0]) / wu,
                                (rb[:, 2] - b[:, 2]) / wv, (rb[:, 3] - b[:, 2]) / wv])
    ok = (cand > CUT_MARGIN) & (cand < 1.0 - CUT_MARGIN) & over[:, None]
    score = np.where(ok, np.abs(cand - 0.5), np.inf)
    k = np.argmin(score, axis=1)
    rows = np.flatnonzero(np.isfinite(score[np.arange(len(b)), k]))
    t[rows] = cand[rows, k[rows]]
    along_u[rows] = k[rows] < 2
    return t, along_u
