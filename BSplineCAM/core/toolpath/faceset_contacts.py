# SPDX-License-Identifier: LGPL-2.1-or-later
"""Contacts of the drop-cutter (:mod:`.faceset`) polished by Newton's method: the gradient
and Hessian of f(u, v) = S_z + sqrt(R^2 - |S_xy - q|^2), projected Newton ascent in (u, v)
and along the trim segments that hold a contact.  A step counts only where it raises f at a
real surface point inside the trim, so the polished values stay lower bounds.  The queries'
best heights are raised to their faces' best contacts by :func:`merge`."""

from __future__ import annotations

import numpy as np

from .. import kernels
from ..kernels import regions_kernels
from ..numeric import clamp
from ..typing import FloatArray
from .faceset_params import POLISH_STEPS
from .faceset_trims import _FaceData


def grad_hess(s, u: FloatArray, v: FloatArray, qq: FloatArray, R2: float):
    """Gradient (gu, gw) and Hessian (Huu, Huw, Hww) of f(u, v) = S_z + sqrt(R^2 -
    |S_xy - q|^2)."""
    j = s.derivatives(u, v)
    D = j.point[:, :2] - qq
    h = np.sqrt(np.maximum(R2 - (D * D).sum(axis=1), 1e-300))
    Du, Dw = j.su[:, :2], j.sw[:, :2]
    dDu = (D * Du).sum(1)
    dDw = (D * Dw).sum(1)
    gu = j.su[:, 2] - dDu / h
    gw = j.sw[:, 2] - dDw / h
    h3 = h ** 3
    Huu = j.suu[:, 2] - ((Du * Du).sum(1) + (D * j.suu[:, :2]).sum(1)) / h - dDu ** 2 / h3
    Hww = j.sww[:, 2] - ((Dw * Dw).sum(1) + (D * j.sww[:, :2]).sum(1)) / h - dDw ** 2 / h3
    Huw = (j.suw[:, 2] - ((Du * Dw).sum(1) + (D * j.suw[:, :2]).sum(1)) / h
           - dDu * dDw / h3)
    return gu, gw, Huu, Huw, Hww


def newton_step(s, u: FloatArray, v: FloatArray, qq: FloatArray, R2: float):
    """Newton step of f(u, v) (gradient and Hessian as in :meth:`DropCutter.refine`):
    (concave here, new u, new v)."""
    gu, gw, Huu, Huw, Hww = grad_hess(s, u, v, qq, R2)
    det = Huu * Hww - Huw * Huw
    concave = (Huu < 0) & (det > 0)
    safe = np.where(concave, det, 1.0)
    du = np.where(concave, -(Hww * gu - Huw * gw) / safe, 0.0)
    dw = np.where(concave, -(Huu * gw - Huw * gu) / safe, 0.0)
    # on a side of the domain with the ascent pointing out: Newton along the side only
    (u0, u1), (v0, v1) = s.domain
    pin_u = ((u <= u0) & (gu < 0)) | ((u >= u1) & (gu > 0))
    pin_v = ((v <= v0) & (gw < 0)) | ((v >= v1) & (gw > 0))
    side_u = pin_u & ~pin_v & (Hww < 0)
    side_v = pin_v & ~pin_u & (Huu < 0)
    du = np.where(side_u, 0.0, np.where(side_v, -gu / np.where(side_v, Huu, 1.0), du))
    dw = np.where(side_v, 0.0, np.where(side_u, -gw / np.where(side_u, Hww, 1.0), dw))
    ok = (concave | side_u | side_v) & np.isfinite(du) & np.isfinite(dw)
    return ok, u + np.where(ok, du, 0.0), v + np.where(ok, dw, 0.0)


def polish(data: list, q: FloatArray, R: float, best: FloatArray, face: np.ndarray,
           bu: FloatArray, bv: FloatArray, steps: int = POLISH_STEPS) -> None:
    """Raise the lower bounds in place by projected Newton ascent of f(u, v) from the best
    contacts (Nocedal & Wright 16.7); a step counts only at a real surface point inside
    its face's trim that raises f, so ``best`` stays a lower bound."""
    R2 = R * R
    for d in data:
        idx = np.flatnonzero(face == d.index)
        if len(idx) == 0:
            continue
        s = d.face.surface
        if kernels.use_numba():
            try:
                best[idx], bu[idx], bv[idx] = _polish_compiled(d, q[idx], R2, best[idx],
                                                               bu[idx], bv[idx], steps)
                if len(d.edges):
                    edge_polish(d, q, R, idx, best, bu, bv)
                continue
            except kernels.KernelUnavailable:
                pass
        (u0, u1), (v0, v1) = s.domain
        u, v = bu[idx].copy(), bv[idx].copy()
        qq = q[idx]
        fbest = best[idx].copy()
        # a contact whose step was refused would take the same step again: only the
        # contacts that moved go on
        live = np.arange(len(idx))
        for _ in range(steps):
            ul, vl, ql = u[live], v[live], qq[live]
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
                ok_, nu_, nv_ = newton_step(s, ul, vl, ql, R2)
            nu_ = clamp(nu_, u0, u1)
            nv_ = clamp(nv_, v0, v1)
            p = s.evaluate(nu_, nv_)
            pd = ((p[:, :2] - ql) ** 2).sum(axis=1)
            fv = np.where(pd <= R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)), -np.inf)
            good = (fv > fbest[live]) & ok_ & (np.abs(nu_ - ul) + np.abs(nv_ - vl) > 0)
            if good.any():
                good[good] = d.inside(nu_[good], nv_[good])
            if not good.any():
                break
            live = live[good]
            u[live], v[live], fbest[live] = nu_[good], nv_[good], fv[good]
        best[idx], bu[idx], bv[idx] = fbest, u, v
        if len(d.edges):
            edge_polish(d, q, R, idx, best, bu, bv)


def edge_polish(d: _FaceData, q: FloatArray, R: float, idx: np.ndarray, best: FloatArray,
                bu: FloatArray, bv: FloatArray) -> None:
    """Newton's method along the trim segments that hold a contact (a maximum on the trim
    edge, where the ball rests on the face's boundary): the contacts the halving finds
    there (trim vertices, clipped segment ends) are polished to machine precision, so that
    neighbouring heights along a pass agree to far better than CERTIFY."""
    (u0, u1), (v0, v1) = d.face.surface.domain
    eps = 1e-10 * max(u1 - u0, v1 - v0)
    qi, si = d.segments_at(bu[idx], bv[idx], eps)
    if len(qi) == 0:
        return
    rows = idx[qi]
    e = d.edges[si]
    a = e[:, :2]
    dd = e[:, 2:] - a
    L2 = (dd * dd).sum(axis=1)
    t = clamp(((np.column_stack([bu[rows], bv[rows]]) - a) * dd).sum(axis=1)
              / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
    qq = q[rows]
    R2 = R * R
    t, ft = _edge_newton(d, a, dd, t, qq, R2)
    uu, vv = a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1]
    order = np.argsort(ft, kind="stable")  # later (larger) assignments win
    rows, ft, uu, vv = rows[order], ft[order], uu[order], vv[order]
    up = ft > best[rows]
    best[rows[up]] = ft[up]
    bu[rows[up]], bv[rows[up]] = uu[up], vv[up]


def _edge_newton(d: _FaceData, a: FloatArray, dd: FloatArray, t: FloatArray, qq: FloatArray,
                 R2: float) -> tuple[FloatArray, FloatArray]:
    """Newton's method for the largest f along segments a + t dd (t in [0, 1]) of face
    ``d`` from ``t``: the parameters reached and their values f (-inf where no step raised
    f)."""
    if kernels.use_numba():
        try:
            return _edge_newton_compiled(d, a, dd, t, qq, R2)
        except kernels.KernelUnavailable:
            pass
    s = d.face.surface
    ft = np.full(len(t), -np.inf)
    for _ in range(2 * POLISH_STEPS):
        uu, vv = a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            gu, gw, huu, huw, hww = grad_hess(s, uu, vv, qq, R2)
            f1 = gu * dd[:, 0] + gw * dd[:, 1]
            f2 = huu * dd[:, 0] ** 2 + 2 * huw * dd[:, 0] * dd[:, 1] + hww * dd[:, 1] ** 2
            step = np.where(f2 < 0, -f1 / f2, np.sign(f1))
        nt = clamp(t + np.nan_to_num(step), 0.0, 1.0)
        p = s.evaluate(a[:, 0] + nt * dd[:, 0], a[:, 1] + nt * dd[:, 1])
        pd = ((p[:, :2] - qq) ** 2).sum(axis=1)
        fv = np.where(pd <= R2, p[:, 2] + np.sqrt(np.maximum(R2 - pd, 0.0)), -np.inf)
        better = fv > ft
        t = np.where(better, nt, t)
        ft = np.where(better, fv, ft)
        if not better.any():
            break
    return t, ft


def _grad_hess_compiled(s, u: FloatArray, v: FloatArray, qq: FloatArray, R2: float) -> FloatArray:
    """:func:`grad_hess` by the compiled kernels: (5, n) rows gu, gw, Huu, Huw, Hww.  h ** 3
    is numpy's (its last bit may come from a vector math library)."""
    j = s.derivatives(u, v)
    f64 = np.float64
    point = np.ascontiguousarray(j.point, f64)
    h = regions_kernels.ball_depth(point, qq, R2)
    h3 = h ** 3
    return regions_kernels.grad_hess(point, np.ascontiguousarray(j.su, f64),
                                     np.ascontiguousarray(j.sw, f64),
                                     np.ascontiguousarray(j.suu, f64),
                                     np.ascontiguousarray(j.suw, f64),
                                     np.ascontiguousarray(j.sww, f64), qq, h, h3)


def _polish_compiled(d: _FaceData, qq: FloatArray, R2: float, fbest: FloatArray, u: FloatArray,
                     v: FloatArray, steps: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    """:func:`polish`'s Newton ascent on face ``d`` by the compiled kernels (the same steps
    and choices): the contacts' values and (u, v), from theirs (copies are changed)."""
    s = d.face.surface
    (u0, u1), (v0, v1) = s.domain
    dom = np.array([u0, u1, v0, v1], np.float64)
    bands = d._bands
    qq = np.ascontiguousarray(qq, np.float64)
    u, v, fbest = u.copy(), v.copy(), fbest.copy()
    rows, *ders_pack = d.derivative_pack()
    rational = bool(s.rational)
    *point_pack, point_index, tol = d.point_pack()
    live = np.arange(len(u))
    for _ in range(steps):
        ul, vl, ql = u[live], v[live], qq[live]
        # two compiled calls a step, h ** 3 numpy's between them (see regions_kernels)
        ders, h, inside = regions_kernels.polish_ders(ul, vl, ql, R2, rows, rational,
                                                      *ders_pack)
        if not inside:
            s.derivatives(ul, vl)  # outside the surface's domain: its evaluation says so
        fv, good, nu_, nv_, inside = regions_kernels.polish_step(
            ders, rows, h, h ** 3, ql, R2, ul, vl, fbest[live], dom, bands.table,
            float(bands.v0), float(bands.h), rational, *point_pack, point_index, tol)
        if not inside:
            s.evaluate(nu_, nv_)
        if not good.any():
            break
        live = live[good]
        u[live], v[live], fbest[live] = nu_[good], nv_[good], fv[good]
    return fbest, u, v


def _edge_newton_compiled(d: _FaceData, a: FloatArray, dd: FloatArray, t: FloatArray,
                          qq: FloatArray, R2: float) -> tuple[FloatArray, FloatArray]:
    """:func:`_edge_newton` by the compiled kernels (the same steps and choices), two calls
    a step (h ** 3 numpy's between them, see ``regions_kernels``)."""
    f64 = np.float64
    s = d.face.surface
    a = np.ascontiguousarray(a, f64)
    dd = np.ascontiguousarray(dd, f64)
    qq = np.ascontiguousarray(qq, f64)
    t = np.array(t, f64)
    ft = np.full(len(t), -np.inf)
    rows, *ders_pack = d.derivative_pack()
    rational = bool(s.rational)
    *point_pack, point_index, tol = d.point_pack()
    for _ in range(2 * POLISH_STEPS):
        uu, vv = a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1]
        ders, h, inside = regions_kernels.polish_ders(uu, vv, qq, R2, rows, rational,
                                                      *ders_pack)
        if not inside:
            s.derivatives(uu, vv)  # outside the surface's domain: its evaluation says so
        moved, inside = regions_kernels.edge_polish_step(ders, rows, h, h ** 3, qq, R2, a, dd,
                                                         t, ft, rational, *point_pack,
                                                         point_index, tol)
        if not inside:
            s.evaluate(a[:, 0] + t * dd[:, 0], a[:, 1] + t * dd[:, 1])
        if moved == 0:
            break
    return t, ft


def merge(data: list, fb: FloatArray, fu: FloatArray, fv: FloatArray, best: FloatArray,
          face: np.ndarray, bu: FloatArray, bv: FloatArray) -> None:
    """Raise each query's best (and its contact) to its faces' best lower bounds."""
    if len(fb) == 0:
        return
    k = np.argmax(fb, axis=0)
    cols = np.arange(fb.shape[1])
    top = fb[k, cols]
    up = np.flatnonzero(top > best)
    if len(up):
        best[up] = top[up]
        face[up] = np.array([d.index for d in data])[k[up]]
        bu[up], bv[up] = fu[k[up], up], fv[k[up], up]
