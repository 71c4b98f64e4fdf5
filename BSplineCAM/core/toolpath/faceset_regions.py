# SPDX-License-Identifier: LGPL-2.1-or-later
"""Local certificates of the drop-cutter (:mod:`.faceset`): around a face's best contact a box
in (u, v) on whose material f cannot exceed the contact's value plus a proved excess
(:func:`face_regions`), sought for the faces still open at a level (:func:`certify_faces`).
The branch and bound drops a face's sub-patches inside its region."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..kernels import regions_kernels
from ..numeric import clamp
from ..typing import FloatArray
from .faceset_bezier import _bernstein, _quadratic_bound, _second_differences, _sub_net
from .faceset_contacts import merge, polish
from .faceset_params import CORNERS, MAX_SEGMENTS, POLISH_STEPS, REGION_SIZES, REGION_TIE
from .faceset_trims import _FaceData, _Items


def face_regions(d: _FaceData, qq: FloatArray, R: float, u: FloatArray, v: FloatArray,
                 limit: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
    """Boxes in (u, v) of face ``d`` around contacts x* = (u, v) of queries ``qq`` on whose
    material f <= f(x*) + excess is proved, excess <= ``limit`` (a local certificate):
    (found, box (n, 4), excess).

    f(p) = p_z + sqrt(R^2 - |p_xy - q|^2) is concave in p with the hemisphere's Hessian at
    most -I/R in xy, so for p0 = S(x*) and g = grad f(p0):

        f(S(x)) - f(p0) <= g . (S(x) - p0) - |S_xy(x) - p0_xy|^2 / (2R)
                         = [N(x) w(x) - |E(x)|^2 / (2R)] / w(x)^2

    with the homogeneous net (A, w) of S, N = g . (A - w p0) and E = A_xy - w p0_xy, both
    polynomial patches vanishing at x*.  Taylor's theorem with the Bezier hulls of their
    second derivatives over the box (hodographs) bounds N <= n1 . d + lam |d|^2 / 2 and
    |E| >= (sigma - M2 rho / 2) |d|, d = x - x* (rho the box's largest |d|, sigma the least
    singular value of E's Jacobian at x*, n1 = grad N(x*)), so with
    k = (sigma - M2 rho / 2)+^2 / (2R) - lam w_max / 2 > 0 the bracket is at most
    w_max (n1 . d)+ - k |d|^2.  The same per direction: |E|^2 >= d^T J^T J d - M2 rho
    sigma_max |d|^2 (J = E's Jacobian at x*) and the hulls of N_ss, |N_st|, N_tt bound
    the Taylor term in (|ds|, |dt|), so the least eigenvalue of the 2x2 matrix they make
    is a k as well; the larger of the two is used.  Where a face turns steep its xy map
    nears singular across the slope (sigma -> 0: the first k fails), while N, concave
    across the slope, and J along it keep the second positive.  For any unit vector nu
    with alpha = n1 . nu >= 0 and beta = |n1 x nu|, n1 . d <= alpha delta + beta |d|
    where delta = max nu . d over the material in the box (a polygon: its largest value is
    at a vertex, the box corners in the material and the trim segments' ends clipped to
    the box), hence

        bracket <= w_max alpha delta + (w_max beta)^2 / (4 k).

    nu = n1 / |n1| and the axes cover an interior maximum and one on a side of the domain;
    the normals of the trim segments in the box cover a maximum on a trim edge (the
    material lies on one side of a straight edge: delta = 0, and beta, the slope along
    the edge, vanishes at the edge's maximum).  The least bound over these, divided by
    w_min^2, is the excess.  Boxes are tried largest first (REGION_SIZES: the first alone,
    then the rest in one pass, each query keeping the largest that holds) and stay inside
    the Bezier patch that holds x*."""
    n = len(u)
    found = np.zeros(n, bool)
    out_box = np.zeros((n, 4))
    out_ex = np.full(n, np.inf)
    if n == 0:
        return found, out_box, out_ex
    c = _contact_frames(d, qq, R, u, v, limit)
    if kernels.use_numba():
        try:
            return _regions_compiled(d, c, R, limit)
        except kernels.KernelUnavailable:
            pass
    todo = c.valid.copy()
    # trim segments crossing each box: those of the (nested) box tried before it
    segs = d.root_segs[c.root]
    stat = d.root_status[c.root]
    # the largest box first; where it fails, all the smaller ones in one pass (a call's
    # cost is in its array operations, not its rows), each query taking the largest
    # that holds.  A nested box's trim segments are among its first box's.
    for sizes in (REGION_SIZES[:1], REGION_SIZES[1:]):
        if not todo.any() or not sizes:
            break
        asked = np.flatnonzero(todo)
        k_ = np.repeat(asked, len(sizes))
        rho = np.tile(np.asarray(sizes, float), len(asked))
        bx = _region_boxes(c, k_, rho)
        kk, n1, wmax, wmin = _concavity(d, c, k_, bx, R)
        rbox, status, segs_k, st, okv, whole = _material_polygon(d, c, k_, bx, segs, stat)
        excess = _excess(d, bx, n1, kk, wmax, wmin, st, okv, segs_k)
        usable = (status > 0) | whole
        # k > 0 is all the bound needs: where the face turns steep its xy map nears
        # singular (s_eff <= 0, no concavity from the hemisphere), but a convex face's own
        # curvature (lam < 0) still makes f strongly concave along it
        ok = np.flatnonzero((kk > 0) & (wmin > 0) & usable & (excess <= limit[k_]))
        # rows run query by query, largest box first: each query's first good row
        first = ok[np.unique(k_[ok], return_index=True)[1]]
        hit = k_[first]
        found[hit] = True
        out_box[hit] = rbox[first]
        out_ex[hit] = excess[first]
        todo[hit] = False
    return found, out_box, out_ex


def _regions_compiled(d: _FaceData, c: _ContactFrames, R: float,
                      limit: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
    """:func:`face_regions` after its contact frames, by the compiled kernel (the same boxes,
    bounds and choices, one call)."""
    f64 = np.float64
    (u0, u1), (v0, v1) = d.face.surface.domain
    edges = d.edges if len(d.edges) else np.zeros((0, 4))
    bands = d._bands
    return regions_kernels.regions(
        d.nets, c.root.astype(np.int64), d.boxes, c.cs, c.ct, c.wu, c.wv,
        np.ascontiguousarray(c.g, f64), np.ascontiguousarray(c.gp, f64),
        np.ascontiguousarray(c.p0, f64), np.ascontiguousarray(c.j.su, f64),
        np.ascontiguousarray(c.j.sw, f64), np.ascontiguousarray(c.wstar, f64),
        np.ascontiguousarray(c.valid), np.ascontiguousarray(limit, f64),
        np.asarray(REGION_SIZES, f64), 1, float(R), d.p, d.q,
        np.ascontiguousarray(d.root_segs[c.root], np.int64),
        d.root_status[c.root].astype(np.int64), np.ascontiguousarray(edges, f64),
        np.ascontiguousarray(d._elo.reshape(-1, 2), f64),
        np.ascontiguousarray(d._ehi.reshape(-1, 2), f64), float(d._pad),
        bands.table, float(bands.v0), float(bands.h),
        np.array([u0, u1, v0, v1], f64))


@dataclass
class _ContactFrames:
    """The contacts x* of :func:`face_regions` in the Bezier patches that hold them."""

    #: index of the patch (n,), its parameter box (n, 4) and the box's widths (n,)
    root: np.ndarray
    box: FloatArray
    wu: FloatArray
    wv: FloatArray
    #: local parameters of x* in its patch (n,)
    cs: FloatArray
    ct: FloatArray
    #: the surface's derivatives at x*, the point p0 = S(x*) (n, 3)
    j: object
    p0: FloatArray
    #: x* well inside the ball's reach, with a positive limit
    valid: np.ndarray
    #: g = grad f(p0) (n, 3) and g . p0 (n,)
    g: FloatArray
    gp: FloatArray
    #: the patch's homogeneous net (n, 4, p+1, q+1) and its weight at x* (n,)
    nets: FloatArray
    wstar: FloatArray


def _contact_frames(d: _FaceData, qq: FloatArray, R: float, u: FloatArray, v: FloatArray,
                    limit: FloatArray) -> _ContactFrames:
    """The patch, local parameters, point, gradient of f and weight of each contact."""
    n = len(u)
    R2 = R * R
    s = d.face.surface
    iu = clamp(np.searchsorted(d.u_ends, u, side="left"), 0, d.nu - 1)
    iv = clamp(np.searchsorted(d.v_ends, v, side="left"), 0, d.nv - 1)
    root = iu * d.nv + iv
    box = d.boxes[root]
    wu, wv = box[:, 1] - box[:, 0], box[:, 3] - box[:, 2]
    cs = clamp((u - box[:, 0]) / wu, 0.0, 1.0)
    ct = clamp((v - box[:, 2]) / wv, 0.0, 1.0)
    j = s.derivatives(u, v)
    p0 = j.point
    D = p0[:, :2] - qq
    dd = (D * D).sum(axis=1)
    valid = (dd < R2 * (1.0 - 1e-9)) & (limit > 0)
    h0 = np.sqrt(np.maximum(R2 - dd, 1e-300))
    g = np.column_stack([-D / h0[:, None], np.ones(n)])
    gp = (g * p0).sum(axis=1)
    nets = d.nets[root]
    if s.rational:
        bs = _bernstein(d.p, cs)
        bt = _bernstein(d.q, ct)
        wstar = np.einsum("ni,nij,nj->n", bs, nets[:, 3], bt)
    else:
        wstar = np.ones(n)
    return _ContactFrames(root, box, wu, wv, cs, ct, j, p0, valid, g, gp, nets, wstar)


@dataclass
class _RegionBoxes:
    """Boxes [s0, s1] x [t0, t1] (local parameters of the patch) around the contacts ``k_``
    of :func:`face_regions`, one row per (contact, size)."""

    s0: FloatArray
    s1: FloatArray
    t0: FloatArray
    t1: FloatArray
    #: the box's net (n, 4, p+1, q+1)
    sub: FloatArray
    #: x*'s local parameters in the box
    ls: FloatArray
    lt: FloatArray
    #: the box's widths in (u, v)
    du: FloatArray
    dv: FloatArray


def _region_boxes(c: _ContactFrames, k_: np.ndarray, rho: FloatArray) -> _RegionBoxes:
    """The boxes of half-width ``rho`` around contacts ``k_``, clipped to their patch."""
    s0, s1 = np.maximum(c.cs[k_] - rho, 0.0), np.minimum(c.cs[k_] + rho, 1.0)
    t0, t1 = np.maximum(c.ct[k_] - rho, 0.0), np.minimum(c.ct[k_] + rho, 1.0)
    sub = _sub_net(c.nets[k_], s0, s1, t0, t1)
    ls, lt = (c.cs[k_] - s0) / (s1 - s0), (c.ct[k_] - t0) / (t1 - t0)
    du, dv = (s1 - s0) * c.wu[k_], (t1 - t0) * c.wv[k_]
    return _RegionBoxes(s0, s1, t0, t1, sub, ls, lt, du, dv)


def _concavity(d: _FaceData, c: _ContactFrames, k_: np.ndarray, bx: _RegionBoxes,
               R: float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The concavity k of the bracket on each box (the larger of the isotropic bound and
    the least eigenvalue of the per-direction one), n1 = grad N(x*), and the box net's
    largest and least weights: (k, n1, w_max, w_min)."""
    sub, ls, lt, du, dv = bx.sub, bx.ls, bx.lt, bx.du, bx.dv
    gk, pk = c.g[k_], c.p0[k_]
    hw = sub[:, 3]
    N = np.einsum("nc,ncij->nij", gk, sub[:, :3]) - hw * c.gp[k_, None, None]
    E = sub[:, :2] - hw[:, None] * pk[:, :2, None, None]
    nss, nst, ntt = _second_differences(N, d.p, d.q)
    h_ss, h_st, h_tt = (nss.max(axis=(-2, -1)), np.abs(nst).max(axis=(-2, -1)),
                        ntt.max(axis=(-2, -1)))
    lam = _quadratic_bound(h_ss, h_st, h_tt)
    ess, est, ett = _second_differences(E, d.p, d.q)
    mc = _quadratic_bound(np.abs(ess).max(axis=(-2, -1)),
                          np.abs(est).max(axis=(-2, -1)),
                          np.abs(ett).max(axis=(-2, -1)))
    m2 = np.hypot(mc[:, 0], mc[:, 1])
    wmax, wmin = hw.max(axis=(1, 2)), hw.min(axis=(1, 2))
    ws = c.wstar[k_]
    js = c.j.su[k_] * du[:, None]
    jt = c.j.sw[k_] * dv[:, None]
    n1 = np.column_stack([ws * (gk * js).sum(axis=1), ws * (gk * jt).sum(axis=1)])
    a11, a12, a21, a22 = ws * js[:, 0], ws * jt[:, 0], ws * js[:, 1], ws * jt[:, 1]
    fro = a11 * a11 + a12 * a12 + a21 * a21 + a22 * a22
    det = np.abs(a11 * a22 - a12 * a21)
    smax = np.sqrt(0.5 * (fro + np.sqrt(np.maximum(fro * fro - 4 * det * det, 0.0))))
    sigma = np.where(smax > 0, det / np.where(smax > 0, smax, 1.0), 0.0)
    rmax = np.hypot(np.maximum(ls, 1 - ls), np.maximum(lt, 1 - lt))
    s_eff = sigma - 0.5 * m2 * rmax
    lam_w = np.where(lam >= 0, lam * wmax, lam * wmin)
    kk = np.where(s_eff > 0, s_eff, 0.0) ** 2 / (2.0 * R) - 0.5 * lam_w
    # the same per direction (where the face turns steep, its xy map is nearly
    # singular across the slope, where N is strongly concave, and not along it):
    # |E|^2 >= |J d|^2 - 2 e |d| |J d| >= d^T (J^T J) d - 2 e smax |d|^2 with
    # e = M2 rho / 2, and w d^T H_N d <= (a, 2b, c) . (ds^2, |ds dt|, dt^2) with the
    # hulls' a, b, c (times w_max or w_min by sign), so the bracket is at most
    # w_max (n1 . d)+ - d'^T K d' for d' = (|ds|, |dt|) (|d'| = |d|): the least
    # eigenvalue of K serves as k too
    e_s = 0.5 * m2 * rmax * smax / R
    g_ss, g_tt = a11 * a11 + a21 * a21, a12 * a12 + a22 * a22
    g_st = np.abs(a11 * a12 + a21 * a22)
    k11 = g_ss / (2.0 * R) - e_s - 0.5 * np.where(h_ss >= 0, h_ss * wmax, h_ss * wmin)
    k22 = g_tt / (2.0 * R) - e_s - 0.5 * np.where(h_tt >= 0, h_tt * wmax, h_tt * wmin)
    k12 = g_st / (2.0 * R) + 0.5 * h_st * wmax
    k_dir = 0.5 * (k11 + k22) - np.sqrt(0.25 * (k11 - k22) ** 2 + k12 * k12)
    kk = np.maximum(kk, k_dir)
    return kk, n1, wmax, wmin


def _material_polygon(d: _FaceData, c: _ContactFrames, k_: np.ndarray, bx: _RegionBoxes,
                      segs: np.ndarray, stat: np.ndarray) -> tuple:
    """The material's polygon in each box: (box in (u, v) (n, 4), status, its trim segments,
    its vertices in the box's local (s, t) (n, 4 + 2K, 2), their validity, and whether the
    whole box's corners stand in for it).  ``segs`` and ``stat`` (per contact: the segments
    and status of the box tried before) are updated to each contact's latest box."""
    s0, s1, t0, t1, sub = bx.s0, bx.s1, bx.t0, bx.t1, bx.sub
    wu, wv = c.wu, c.wv
    b = c.box[k_]
    rbox = np.column_stack([b[:, 0] + s0 * wu[k_], b[:, 0] + s1 * wu[k_],
                            b[:, 2] + t0 * wv[k_], b[:, 2] + t1 * wv[k_]])
    # inside a box wholly in the material (status 1) the nested box is too: the
    # material is the box; the others are classified against their box's segments
    status = np.ones(len(k_), np.int8)
    segs_k = np.full((len(k_), MAX_SEGMENTS), -1, dtype=np.int64)
    st = np.zeros((len(k_), 4 + 2 * MAX_SEGMENTS, 2))
    st[:, :4] = CORNERS
    okv = np.zeros((len(k_), 4 + 2 * MAX_SEGMENTS), bool)
    okv[:, :4] = True
    cut = np.flatnonzero(stat[k_] == 2)
    if len(cut) and len(d.edges):
        status[cut], segs_k[cut] = d.classify(rbox[cut], segs[k_[cut]])
        segs[k_[cut]] = segs_k[cut]
        stat[k_[cut]] = status[cut]
        st[cut], okv[cut] = d.vertices(_Items(np.zeros(len(cut), int),
                                              np.arange(len(cut)), sub[cut],
                                              rbox[cut], np.zeros(len(cut), int),
                                              status[cut], segs_k[cut]))
    # too many segments to list: the whole box's corners bound the polygon
    whole = (segs_k[:, 0] == -2) | ~okv.any(axis=1)
    okv[whole] = False
    okv[whole, :4] = True
    return rbox, status, segs_k, st, okv, whole


def _excess(d: _FaceData, bx: _RegionBoxes, n1: FloatArray, kk: FloatArray, wmax: FloatArray,
            wmin: FloatArray, st: FloatArray, okv: np.ndarray, segs_k: np.ndarray) -> FloatArray:
    """The excess on each box: the least of w_max alpha delta + (w_max beta)^2 / (4 k) over
    the candidate directions nu (n1's own, the axes, the box's trim segments' normals),
    divided by w_min^2."""
    ls, lt, du, dv = bx.ls, bx.lt, bx.du, bx.dv
    rel = st - np.column_stack([ls, lt])[:, None, :]  # (n, V, 2): d of each vertex
    # candidate directions nu (n, C, 2): n1's own, the axes, the segments' normals
    n1n = np.hypot(n1[:, 0], n1[:, 1])
    unit = n1 / np.where(n1n > 0, n1n, 1.0)[:, None]
    eye = np.broadcast_to(np.eye(2), (len(st), 2, 2))
    valid_seg = segs_k >= 0
    e = (d.edges if len(d.edges) else np.zeros((1, 4)))[np.maximum(segs_k, 0)]
    tan = np.stack([(e[..., 2] - e[..., 0]) / du[:, None],
                    (e[..., 3] - e[..., 1]) / dv[:, None]], axis=-1)
    nrm = np.stack([-tan[..., 1], tan[..., 0]], axis=-1)
    nl = np.hypot(nrm[..., 0], nrm[..., 1])
    valid_seg &= nl > 0
    nrm = nrm / np.where(nl > 0, nl, 1.0)[..., None]
    nu = np.concatenate([unit[:, None], eye, nrm], axis=1)
    cok = np.concatenate([np.ones((len(st), 3), bool), valid_seg], axis=1)
    alpha = np.einsum("nc,nkc->nk", n1, nu)
    nu = nu * np.where(alpha < 0, -1.0, 1.0)[..., None]  # orient: alpha >= 0
    alpha = np.abs(alpha)
    beta = np.sqrt(np.maximum(n1n[:, None] ** 2 - alpha ** 2, 0.0))
    proj = np.einsum("nkc,nvc->nkv", nu, rel)
    delta = np.maximum(np.where(okv[:, None, :], proj, -np.inf).max(axis=2), 0.0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        cand = wmax[:, None] * alpha * delta + (wmax[:, None] * beta) ** 2 / (
            4.0 * kk[:, None])
        cand = np.where(cok, cand, np.inf)
        return cand.min(axis=1) / (wmin * wmin)


def certify_faces(data: list, q: FloatArray, R: float, evaluated: list, fb: FloatArray,
                  fu: FloatArray, fv: FloatArray, best: FloatArray, face: np.ndarray,
                  bu: FloatArray, bv: FloatArray, certify: float, reg_box: FloatArray,
                  reg_val: FloatArray, sought: FloatArray) -> None:
    """Polish each face's best contact of the queries with sub-patches of that face still
    open, then seek a certified region around it (:func:`face_regions`).

    A region of face F proves f <= reg_val on the material of F inside reg_box; F's
    sub-patches inside it are dropped once reg_val <= best + certify.  So the face that
    holds the maximum, and a tangent neighbour whose own maximum lies on the shared edge
    (a trim or domain side of it, nearly tied with the first), both stop halving there."""
    todo = []
    for j, d, it, ub in evaluated:
        qs = np.unique(it.query[ub > best[it.query] + certify])
        if len(qs) == 0:
            continue
        # contacts whose value rose since the last attempt (a better contact: a tighter
        # certificate, a larger region)
        fj, sj = fb[j, qs], sought[j, qs]
        qs = qs[np.isfinite(fj) & ~(fj <= sj) & (fj >= best[qs] - REGION_TIE)]
        if len(qs) == 0:
            continue
        fcs = np.full(len(qs), d.index)
        b, u, v = fb[j, qs].copy(), fu[j, qs].copy(), fv[j, qs].copy()
        polish([d], q[qs], R, b, fcs, u, v, steps=2 * POLISH_STEPS)
        fb[j, qs], fu[j, qs], fv[j, qs] = b, u, v
        todo.append((j, d, qs))
    if not todo:
        return
    merge(data, fb, fu, fv, best, face, bu, bv)
    for j, d, qs in todo:
        limit = best[qs] + certify - fb[j, qs]
        found, box, excess = face_regions(d, q[qs], R, fu[j, qs], fv[j, qs], limit)
        sought[j, qs] = fb[j, qs]
        hit = qs[found]
        reg_box[j, hit] = box[found]
        reg_val[j, hit] = fb[j, hit] + excess[found]
