# SPDX-License-Identifier: LGPL-2.1-or-later
"""The point probe of the drop-cutter's faces (:meth:`.faceset.FaceSet.height`): the top-most
face point above each xy, by Newton inversion of each face's xy map from samples of its
Bezier patches."""

from __future__ import annotations

import numpy as np

from ..numeric import clamp
from .faceset_params import HEIGHT_GRID, HEIGHT_SEEDS, HEIGHT_STEPS


def probe_heights(all_data: list, size: float, xy, selected_only: bool = False):
    """:meth:`.faceset.FaceSet.height` over the set's non-wall faces ``all_data``; ``size`` is
    the diagonal of the set's box (walls included): (z, face, u, v, inside)."""
    q = np.asarray(xy, dtype=float).reshape(-1, 2)
    m = len(q)
    z = np.full(m, -np.inf)
    face = np.full(m, -1)
    uo = np.zeros(m)
    vo = np.zeros(m)
    tol = 1e-9 * max(size, 1.0)
    grid = np.linspace(0.0, 1.0, HEIGHT_GRID)
    for d in all_data:
        if selected_only and not d.selected:
            continue
        s = d.face.surface
        roots = d.roots
        eps = 1e-9 * max(size, 1.0)
        hit = ((q[:, None, 0] >= d.lo[roots, 0] - eps) & (q[:, None, 0] <= d.hi[roots, 0] + eps)
               & (q[:, None, 1] >= d.lo[roots, 1] - eps)
               & (q[:, None, 1] <= d.hi[roots, 1] + eps))
        qi, ri = np.nonzero(hit)
        if len(qi) == 0:
            continue
        box = d.boxes[roots[ri]]
        su = box[:, :1] + grid[None] * (box[:, 1:2] - box[:, :1])
        sv = box[:, 2:3] + grid[None] * (box[:, 3:4] - box[:, 2:3])
        uu = np.repeat(su, HEIGHT_GRID, axis=1)
        vv = np.tile(sv, (1, HEIGHT_GRID))
        pts = s.evaluate(uu, vv)
        dist = ((pts[..., :2] - q[qi, None]) ** 2).sum(axis=-1)
        # several seeds: where the face turns vertical the xy map folds, and the nearest
        # sample may lie on the far side of the fold from the root
        k = np.argsort(dist, axis=1)[:, :HEIGHT_SEEDS]
        rows = np.repeat(np.arange(len(qi)), k.shape[1])
        u, v = uu[rows, k.ravel()], vv[rows, k.ravel()]
        qi, box = qi[rows], box[rows]
        (u0, u1), (v0, v1) = s.domain
        for _ in range(HEIGHT_STEPS):
            p = s.evaluate(u, v)
            su_ = s.evaluate(u, v, du=1)
            sv_ = s.evaluate(u, v, dw=1)
            r = q[qi] - p[:, :2]
            det = su_[:, 0] * sv_[:, 1] - su_[:, 1] * sv_[:, 0]
            det = np.where(np.abs(det) > 1e-300, det, 1e-300)
            du = (r[:, 0] * sv_[:, 1] - r[:, 1] * sv_[:, 0]) / det
            dv = (su_[:, 0] * r[:, 1] - su_[:, 1] * r[:, 0]) / det
            lim_u = box[:, 1] - box[:, 0]
            lim_v = box[:, 3] - box[:, 2]
            du = clamp(du, -lim_u, lim_u)
            dv = clamp(dv, -lim_v, lim_v)
            u = clamp(u + du, u0, u1)
            v = clamp(v + dv, v0, v1)
            if np.all(np.abs(r).max(axis=1) < 1e-3 * tol):
                break
        p = s.evaluate(u, v)
        ok = np.hypot(*(p[:, :2] - q[qi]).T) <= tol
        ok &= d.inside(u, v)
        ok &= p[:, 2] > z[qi]
        idx = np.flatnonzero(ok)
        order = idx[np.argsort(p[idx, 2], kind="stable")]
        z[qi[order]] = p[order, 2]
        face[qi[order]] = d.index
        uo[qi[order]], vo[qi[order]] = u[order], v[order]
    found = face >= 0
    z[~found] = np.nan
    return z, face, uo, vo, found
