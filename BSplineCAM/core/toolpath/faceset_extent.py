# SPDX-License-Identifier: LGPL-2.1-or-later
"""The extent of the drop-cutter's faces (:mod:`.faceset`): each side of a box enclosing the
faces inside their trims, found by branch and bound over their Bezier sub-patches (the
coordinate's hull, tightened on straddling sub-patches by its affine part at the material's
vertices)."""

from __future__ import annotations

import numpy as np

from ..errors import BSplineCAMError
from ..typing import FloatArray
from .faceset_bezier import _corner_index, _rational_drift
from .faceset_params import MAX_DEPTH
from .faceset_subdivide import children
from .faceset_trims import _FaceData, _Items
from .faceset_walls import _Walls


def extent(all_data: list, walls: _Walls, size: float,
           selected_only: bool) -> tuple[FloatArray, FloatArray]:
    """(lo, hi) 3-vectors (mm): a box enclosing the faces ``all_data`` (only the selected
    ones if ``selected_only``, else with the ``walls`` too) inside their trims, each side
    found by branch and bound on the Bezier boxes to within 1e-6 of ``size``."""
    data = [d for d in all_data if d.selected or not selected_only]
    if not data and (selected_only or not walls.boxes):
        raise BSplineCAMError("no selected face: the selection is empty")
    tol = 1e-6 * max(size, 1e-9)
    lo = np.empty(3)
    hi = np.empty(3)
    for c in range(3):
        for sign, out in ((1.0, hi), (-1.0, lo)):
            best = -np.inf
            for d in data:
                best = max(best, _extreme(d, c, sign, tol, best))
            out[c] = sign * best
    if not selected_only:
        for wlo, whi in walls.boxes:  # a wall's extremes lie on its border
            lo, hi = np.minimum(lo, wlo), np.maximum(hi, whi)
    return lo, hi


def _extreme(d: _FaceData, c: int, sign: float, tol: float, best: float) -> float:
    """max of sign * coordinate c over the face's material (branch and bound)."""
    r = d.roots
    it = _Items(np.zeros(len(r), int), r, d.nets, d.boxes[r], np.zeros(len(r), int),
                d.root_status[r], d.root_segs[r])
    cap = -np.inf
    for level in range(MAX_DEPTH):
        if len(it.query) == 0:
            break
        flat = it.net.reshape(len(it.query), 4, -1)
        vals = sign * flat[:, c] / flat[:, 3]
        ub = vals.max(axis=1)
        coef = vals @ d.pinv.T
        resid = (vals - coef @ d.design.T).max(axis=1)
        cidx = _corner_index(d.p, d.q)
        cok = np.ones((len(vals), 4), bool)
        strad = np.flatnonzero(it.status == 2)
        if len(strad):
            st, ok = d.vertices(it.take(strad))
            cok[strad] = ok[:, :4]
            listed = it.segs[strad, 0] != -2
            if listed.any():
                # the coordinate is a scalar Bezier patch: affine part at the material's
                # vertices plus the largest residual of its coefficients (a rational
                # patch: plus the affine part's drift, :func:`_rational_drift`)
                strad, st, ok = strad[listed], st[listed], ok[listed]
                cs = coef[strad]
                aval = cs[:, :1] + cs[:, 1:2] * st[..., 0] + cs[:, 2:3] * st[..., 1]
                extra = resid[strad]
                if d.face.surface.rational:
                    extra = extra + _rational_drift(flat[strad, 3], cs)
                ub[strad] = np.minimum(ub[strad],
                                       np.where(ok, aval, -np.inf).max(axis=1) + extra)
            loc = st[:, 4:]
            good = ok[:, 4:]
            if good.any():
                b = it.box[strad]
                uu = b[:, :1] + loc[..., 0] * (b[:, 1:2] - b[:, :1])
                vv = b[:, 2:3] + loc[..., 1] * (b[:, 3:4] - b[:, 2:3])
                p = d.face.surface.evaluate(uu[good], vv[good])
                best = max(best, float((sign * p[:, c]).max()))
        cv = np.where(cok, vals[:, cidx], -np.inf)
        best = max(best, float(cv.max(initial=-np.inf)))
        keep = ub > best + tol
        # what is dropped is bounded by its upper bounds: the result encloses the face
        cap = max(cap, float(ub[~keep].max(initial=-np.inf)))
        if not keep.any():
            break
        if level == MAX_DEPTH - 1:
            cap = max(cap, float(ub.max()))
        it = children(d, it, keep)
    return max(best, cap)
