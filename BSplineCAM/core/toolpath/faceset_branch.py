# SPDX-License-Identifier: LGPL-2.1-or-later
"""The branch and bound of the certified drop-cutter (:mod:`.faceset`) over a chunk of
queries: level by level every (query, sub-patch) pair is bounded
(:func:`.faceset_bounds.sub_patch_bounds`), the faces' best contacts raise the queries' lower
bounds, contacts are polished and local certificates sought (:mod:`.faceset_regions`), and the
pairs still open above their query's best are split (:mod:`.faceset_subdivide`).

Under the numba engine a face's level runs in three compiled calls
(:mod:`..kernels.faceset_round_kernels`): its bounds, its contacts, and its open pairs' cuts and
halves; the numpy engine takes the same steps as array operations, to the same answers."""

from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels import faceset_round_kernels as rk
from ..typing import FloatArray
from .faceset_bounds import sub_patch_bounds
from .faceset_contacts import merge, polish
from .faceset_hints import seed_hints
from .faceset_params import (
    CERTIFY,
    MAX_CROWDED,
    MAX_DEPTH,
    MAX_OPEN,
    POLISH_LEVELS,
    POLISH_STEPS,
    REGION_EVERY,
)
from .faceset_regions import certify_faces
from .faceset_subdivide import children, open_children, region_cuts
from .faceset_trims import _Items
from .faceset_walls import _Walls


def drop_chunk(all_data: list, walls: _Walls, stats: dict, q: FloatArray, R: float,
               data: list, use_walls: bool = True, certify: float = CERTIFY,
               max_crowded: int = MAX_CROWDED, hint: tuple | None = None) -> tuple:
    """Certified ball-centre heights of queries ``q`` (m, 2) over faces ``data`` (and the
    ``walls``' borders if ``use_walls``): (centre, face, u, v, gap).  ``all_data`` are all
    of the set's non-wall faces (the final polish), ``stats`` its counters (updated), and
    ``max_crowded`` the levels a query crowded with open sub-patches is kept.  ``hint``
    (face, u, v) (m,) each: a contact near each query's (a neighbour's; face -1 none) that
    starts its face's best lower bound (:func:`.faceset_hints.seed_hints`)."""
    m = len(q)
    best = np.full(m, -np.inf)
    face = np.full(m, -1)
    bu = np.zeros(m)
    bv = np.zeros(m)
    gap = np.zeros(m)
    if use_walls:
        best, face, bu, bv = walls.drop(q, R)
    groups = _root_pairs(data, q, R)
    # per face (rows follow ``data``): its best lower bound and contact, and the certified
    # region around that contact (box in (u, v), the bound of f on it; inf: none)
    nf = len(data)
    fb = np.full((nf, m), -np.inf)
    fu = np.zeros((nf, m))
    fv = np.zeros((nf, m))
    reg_box = np.zeros((nf, m, 4))
    reg_val = np.full((nf, m), np.inf)
    sought = np.full((nf, m), np.nan)  # fb when a region was last sought
    crowded_levels = np.zeros(m, int)
    fused = kernels.use_numba()
    touched = np.zeros(m, bool)  # scratch of the compiled _record_contacts
    if hint is not None:
        seed_hints(data, q, R, hint, fb, fu, fv)
        merge(data, fb, fu, fv, best, face, bu, bv)
    level = 0
    while groups:
        level += 1
        given_up = crowded_levels >= max_crowded
        crowded_now = np.zeros(m, bool)
        evaluated = []
        for j, d, it in groups:
            ub, lb, lu, lv = sub_patch_bounds(d, it, q, R, best[it.query] + certify)
            evaluated.append((j, d, it, ub))
            if fused:
                try:
                    rk.record_contacts(j, it.query, lb, lu, lv, fb, fu, fv, touched)
                    continue
                except kernels.KernelUnavailable:
                    fused = False
            _record_contacts(j, it, lb, lu, lv, fb, fu, fv)
        merge(data, fb, fu, fv, best, face, bu, bv)
        if level in POLISH_LEVELS[1:] or (level > POLISH_LEVELS[-1]
                                          and level % REGION_EVERY == 0):
            certify_faces(data, q, R, evaluated, fb, fu, fv, best, face, bu, bv,
                          certify, reg_box, reg_val, sought)
        groups = []
        for j, d, it, ub in evaluated:
            stats["pairs"] += len(it.query)
            if fused:
                try:
                    halves, unc = open_children(j, d, it, ub, best, gap, reg_box, reg_val,
                                                given_up, certify, crowded_now)
                    stats["uncertified"] += unc
                    if len(halves.query):
                        groups.append((j, d, halves))
                    continue
                except kernels.KernelUnavailable:
                    fused = False
            open_, rb, inreg, crowded = _open_pairs(j, it, ub, best, gap, reg_box, reg_val,
                                                    given_up, certify, stats, m)
            crowded_now |= crowded
            if open_.any():
                halves = children(d, it, open_, region_cuts(it, open_, rb, inreg))
                if len(halves.query):
                    groups.append((j, d, halves))
        crowded_levels += crowded_now
    stats["levels"] = max(stats["levels"], level)
    # a final polish: smooth maxima to machine precision, so that neighbouring heights are
    # consistent to far better than CERTIFY (the chord checks compare them)
    polish(all_data, q, R, best, face, bu, bv, steps=2 * POLISH_STEPS)
    return best, face, bu, bv, gap


def _root_pairs(data: list, q: FloatArray, R: float) -> list:
    """(row in ``data``, face, pairs) of the faces' root Bezier patches whose boxes come
    within R of a query in xy."""
    R2 = R * R
    groups = []
    for j, d in enumerate(data):
        roots = d.roots
        if len(roots) == 0:
            continue
        dx = np.maximum(np.maximum(d.lo[roots, 0][None] - q[:, :1],
                                   q[:, :1] - d.hi[roots, 0][None]), 0.0)
        dy = np.maximum(np.maximum(d.lo[roots, 1][None] - q[:, 1:],
                                   q[:, 1:] - d.hi[roots, 1][None]), 0.0)
        qi, ri = np.nonzero(dx * dx + dy * dy <= R2)
        if len(qi) == 0:
            continue
        r = roots[ri]
        groups.append((j, d, _Items(qi, r, d.nets, d.boxes[r], np.zeros(len(r), int),
                                    d.root_status[r], d.root_segs[r])))
    return groups


def _record_contacts(j: int, it: _Items, lb: FloatArray, lu: FloatArray, lv: FloatArray,
                     fb: FloatArray, fu: FloatArray, fv: FloatArray) -> None:
    """Raise face row ``j``'s best lower bounds ``fb`` (and contacts ``fu``, ``fv``) of each
    query to its pairs' lower bounds ``lb`` at (``lu``, ``lv``), in place."""
    good = np.isfinite(lb)
    if good.any():
        gi = np.flatnonzero(good)
        order = gi[np.argsort(lb[gi], kind="stable")]
        qq = it.query[order]
        better = lb[order] > fb[j, qq]
        qq, order = qq[better], order[better]
        # later (larger) assignments win
        fb[j, qq] = lb[order]
        fu[j, qq], fv[j, qq] = lu[order], lv[order]


def _open_pairs(j: int, it: _Items, ub: FloatArray, best: FloatArray, gap: FloatArray,
                reg_box: FloatArray, reg_val: FloatArray, given_up: np.ndarray,
                certify: float, stats: dict, m: int) -> tuple:
    """The pairs of face row ``j`` still open: upper bound above their query's best by more
    than ``certify``, outside their face's certified region, above MAX_DEPTH, of a query not
    given up, and among its MAX_OPEN best of the face.  The bounds of the pairs left open
    otherwise go to their query's ``gap`` (and ``stats``), in place.  Returns (open, each
    pair's region box, whether the region holds, which of the ``m`` queries are crowded)."""
    qs = it.query
    open_ = ub > best[qs] + certify
    # sub-patches inside their face's certified region
    rb = reg_box[j, qs]
    inreg = reg_val[j, qs] <= best[qs] + certify
    open_ &= ~(inreg & (it.box[:, 0] >= rb[:, 0]) & (it.box[:, 1] <= rb[:, 1])
               & (it.box[:, 2] >= rb[:, 2]) & (it.box[:, 3] <= rb[:, 3]))
    deep = open_ & (it.depth >= MAX_DEPTH)
    if deep.any():
        np.maximum.at(gap, qs[deep], ub[deep] - best[qs[deep]])
        stats["uncertified"] += int(deep.sum())
    open_ &= ~deep
    stop = open_ & given_up[qs]
    if stop.any():
        # crowded for the most levels: its bounds no longer close in
        np.maximum.at(gap, qs[stop], ub[stop] - best[qs[stop]])
        stats["uncertified"] += int(stop.sum())
        open_ &= ~stop
    crowded = np.bincount(qs[open_], minlength=m) > MAX_OPEN
    if crowded.any():
        # a query whose maximum is (nearly) tied along a curve: keep its MAX_OPEN
        # best sub-patches; the rest's bounds are reported as its gap
        idx = np.flatnonzero(open_ & crowded[qs])
        order = idx[np.lexsort((-ub[idx], qs[idx]))]
        qo = qs[order]
        first = np.searchsorted(qo, qo)
        drop = order[np.arange(len(order)) - first >= MAX_OPEN]
        np.maximum.at(gap, qs[drop], ub[drop] - best[qs[drop]])
        stats["uncertified"] += len(drop)
        open_[drop] = False
    return open_, rb, inreg, crowded
