# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the drop-cutter's local certificates and contact polish
(:mod:`~BSplineCAM.core.toolpath.faceset_regions`, :mod:`~BSplineCAM.core.toolpath.
faceset_contacts`): loop-style functions over plain contiguous arrays, one call per face and
step where the numpy engine makes dozens of array operations.

The arithmetic is the numpy engine's, operation by operation: the same sub-net splits (de
Casteljau at the same parameters, in the same order), the same sums in the same order (the
numpy engine's sums here have two or three terms, which numpy adds left to right), the same
NaN-propagating minimum and maximum (``np.minimum``, ``np.maximum``, ``.min()``, ``.max()``),
the same even-odd trim test over the same bands of segments and the same Liang-Barsky
clipping.  Where numpy calls a function whose last bit depends on its library (``h ** 3``,
which numpy may take from a vector math library), the caller computes it with numpy and
passes it in.  So both engines take the same decisions and return the same bits.

The trim test and the clipping of a segment are :mod:`.faceset_trim_kernels`' helpers
(:func:`~BSplineCAM.core.kernels.helper`), the sub-net split one here: compiled once, called
by the kernels.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .faceset_trim_kernels import clip_one, inside_one
from .nurbs_eval import _check_loops, _rational_loops, _scattered_loops

#: ``np.nan_to_num``'s replacement for +inf
_BIG = 1.7976931348623157e308


@helper
def _split_side(A, B, work, tt, left, along_u):
    """One side of de Casteljau's split of the net ``A`` (4, P, Q) at ``tt`` along u
    (``along_u``) or v into ``B``: the left side (``left``) or the right one (the sub-net
    splits of ``faceset_bezier._sub_net``)."""
    P = A.shape[1]
    Q = A.shape[2]
    k_ = P if along_u else Q
    other = Q if along_u else P
    for c in range(4):
        for o in range(other):
            for a in range(k_):
                work[a] = A[c, a, o] if along_u else A[c, o, a]
            first_out = work[0] if left else work[k_ - 1]
            if along_u:
                B[c, 0 if left else k_ - 1, o] = first_out
            else:
                B[c, o, 0 if left else k_ - 1] = first_out
            for rr in range(1, k_):
                for a in range(k_ - rr):
                    work[a] = work[a] + tt * (work[a + 1] - work[a])
                at = rr if left else k_ - 1 - rr
                val = work[0] if left else work[k_ - 1 - rr]
                if along_u:
                    B[c, at, o] = val
                else:
                    B[c, o, at] = val


def _regions_loops(nets, root, boxes, cs, ct, wu, wv, g, gp, p0, su, sw, wstar, valid, limit,
                   sizes, first, R, p, q, segs0, stat0, edges, elo, ehi, pad, bands, band_v0,
                   band_h, dom):
    """:func:`~BSplineCAM.core.toolpath.faceset_regions.face_regions` after its contact
    frames: for each valid contact, the boxes of half-widths ``sizes`` (largest first) in its
    Bezier patch ``root`` (of the face's ``nets``, ``boxes``), each with its concavity k, its
    material polygon and its excess, the first that holds kept: (found (n,), box (n, 4),
    excess (n,)).

    The contact's trim segments and status start as its patch's (``segs0``, ``stat0``); after
    the box of index ``first - 1`` (the numpy engine's first pass) they become that box's, and
    the later boxes are classified against them.  ``edges`` (E, 4) are the face's trim
    segments inside the domain, ``elo``, ``ehi`` their boxes, ``pad`` the box padding of the
    classification, ``bands`` (B, W, 4), ``band_v0``, ``band_h`` the band table of the
    point-in-trim test and ``dom`` the domain (u0, u1, v0, v1)."""
    n = cs.shape[0]
    P = p + 1
    Q = q + 1
    K = segs0.shape[1]
    E = edges.shape[0]
    V = 4 + 2 * K
    found = np.zeros(n, dtype=np.bool_)
    out_box = np.zeros((n, 4))
    out_ex = np.full(n, np.inf)
    A = np.empty((4, P, Q))
    B = np.empty((4, P, Q))
    work = np.empty(max(P, Q))
    N = np.empty((P, Q))
    Ex = np.empty((2, P, Q))
    segs_cur = np.empty(K, dtype=np.int64)
    segs_k = np.empty(K, dtype=np.int64)
    st = np.zeros((V, 2))
    okv = np.zeros(V, dtype=np.bool_)
    pts = np.empty((5, 2))
    ins = np.zeros(5, dtype=np.bool_)
    nus = np.empty((3 + K, 2))
    cok = np.zeros(3 + K, dtype=np.bool_)
    m_ss = np.empty(2)
    m_tt = np.empty(2)
    m_st = np.empty(2)
    eu = 1e-12 * (dom[1] - dom[0])
    ev = 1e-12 * (dom[3] - dom[2])
    iu0 = dom[0] + eu
    iu1 = dom[1] - eu
    iv0 = dom[2] + ev
    iv1 = dom[3] - ev
    two_r = 2.0 * R
    for i in range(n):
        if not valid[i]:
            continue
        r = root[i]
        for k in range(K):
            segs_cur[k] = segs0[i, k]
        stat_cur = stat0[i]
        bu0 = boxes[r, 0]
        bv0 = boxes[r, 2]
        for si in range(sizes.shape[0]):
            rho = sizes[si]
            # -- the box and its net (_region_boxes, _sub_net) ---------------------------------
            s0 = cs[i] - rho
            s0 = s0 if (s0 >= 0.0 or s0 != s0) else 0.0
            s1 = cs[i] + rho
            s1 = s1 if (s1 <= 1.0 or s1 != s1) else 1.0
            t0 = ct[i] - rho
            t0 = t0 if (t0 >= 0.0 or t0 != t0) else 0.0
            t1 = ct[i] + rho
            t1 = t1 if (t1 <= 1.0 or t1 != t1) else 1.0
            for c in range(4):
                for a in range(P):
                    for b in range(Q):
                        A[c, a, b] = nets[r, c, a, b]
            # u at s1 left, u at s0/s1 right, v at t1 left, v at t0/t1 right: A -> B -> A ...
            _split_side(A, B, work, s1, True, True)
            _split_side(B, A, work, s0 / s1, False, True)
            _split_side(A, B, work, t1, True, False)
            _split_side(B, A, work, t0 / t1, False, False)
            ls = (cs[i] - s0) / (s1 - s0)
            lt = (ct[i] - t0) / (t1 - t0)
            du = (s1 - s0) * wu[i]
            dv = (t1 - t0) * wv[i]
            # -- concavity (_concavity) ---------------------------------------------------------
            g0 = g[i, 0]
            g1 = g[i, 1]
            g2 = g[i, 2]
            wmax = -np.inf
            wmin = np.inf
            for a in range(P):
                for b in range(Q):
                    hw = A[3, a, b]
                    N[a, b] = ((g0 * A[0, a, b] + g1 * A[1, a, b]) + g2 * A[2, a, b]) - hw * gp[i]
                    Ex[0, a, b] = A[0, a, b] - hw * p0[i, 0]
                    Ex[1, a, b] = A[1, a, b] - hw * p0[i, 1]
                    if wmax == wmax and not (hw <= wmax):
                        wmax = hw
                    if wmin == wmin and not (hw >= wmin):
                        wmin = hw
            # hull maxima of the second differences: N's (ss, |st|, tt), E's |.| per coordinate
            fp = float(p * (p - 1))
            fq = float(q * (q - 1))
            fpq = float(p * q)
            h_ss = 0.0 if p < 2 else -np.inf
            h_tt = 0.0 if q < 2 else -np.inf
            h_st = -np.inf
            for c in range(2):
                m_ss[c] = 0.0 if p < 2 else -np.inf
                m_tt[c] = 0.0 if q < 2 else -np.inf
                m_st[c] = -np.inf
            for a in range(P - 2):
                for b in range(Q):
                    x = fp * ((N[a + 2, b] - 2.0 * N[a + 1, b]) + N[a, b])
                    if h_ss == h_ss and not (x <= h_ss):
                        h_ss = x
                    for c in range(2):
                        x = abs(fp * ((Ex[c, a + 2, b] - 2.0 * Ex[c, a + 1, b]) + Ex[c, a, b]))
                        if m_ss[c] == m_ss[c] and not (x <= m_ss[c]):
                            m_ss[c] = x
            for a in range(P):
                for b in range(Q - 2):
                    x = fq * ((N[a, b + 2] - 2.0 * N[a, b + 1]) + N[a, b])
                    if h_tt == h_tt and not (x <= h_tt):
                        h_tt = x
                    for c in range(2):
                        x = abs(fq * ((Ex[c, a, b + 2] - 2.0 * Ex[c, a, b + 1]) + Ex[c, a, b]))
                        if m_tt[c] == m_tt[c] and not (x <= m_tt[c]):
                            m_tt[c] = x
            for a in range(P - 1):
                for b in range(Q - 1):
                    x = abs(fpq * (((N[a + 1, b + 1] - N[a, b + 1]) - N[a + 1, b]) + N[a, b]))
                    if h_st == h_st and not (x <= h_st):
                        h_st = x
                    for c in range(2):
                        x = abs(fpq * (((Ex[c, a + 1, b + 1] - Ex[c, a, b + 1])
                                        - Ex[c, a + 1, b]) + Ex[c, a, b]))
                        if m_st[c] == m_st[c] and not (x <= m_st[c]):
                            m_st[c] = x
            d_ = h_ss - h_tt
            lam = 0.5 * (h_ss + h_tt) + math.sqrt(0.25 * (d_ * d_) + h_st * h_st)
            d_ = m_ss[0] - m_tt[0]
            mc0 = 0.5 * (m_ss[0] + m_tt[0]) + math.sqrt(0.25 * (d_ * d_) + m_st[0] * m_st[0])
            d_ = m_ss[1] - m_tt[1]
            mc1 = 0.5 * (m_ss[1] + m_tt[1]) + math.sqrt(0.25 * (d_ * d_) + m_st[1] * m_st[1])
            m2 = math.hypot(mc0, mc1)
            ws = wstar[i]
            js0 = su[i, 0] * du
            js1 = su[i, 1] * du
            js2 = su[i, 2] * du
            jt0 = sw[i, 0] * dv
            jt1 = sw[i, 1] * dv
            jt2 = sw[i, 2] * dv
            n10 = ws * ((g0 * js0 + g1 * js1) + g2 * js2)
            n11 = ws * ((g0 * jt0 + g1 * jt1) + g2 * jt2)
            a11 = ws * js0
            a12 = ws * jt0
            a21 = ws * js1
            a22 = ws * jt1
            fro = ((a11 * a11 + a12 * a12) + a21 * a21) + a22 * a22
            det = abs(a11 * a22 - a12 * a21)
            x = fro * fro - 4.0 * det * det
            x = x if (x >= 0.0 or x != x) else 0.0
            smax = math.sqrt(0.5 * (fro + math.sqrt(x)))
            sigma = det / smax if smax > 0 else 0.0
            x = 1.0 - ls
            ml = ls if (ls >= x or ls != ls) else x
            x = 1.0 - lt
            mt = lt if (lt >= x or lt != lt) else x
            rmax = math.hypot(ml, mt)
            s_eff = sigma - 0.5 * m2 * rmax
            lam_w = lam * wmax if lam >= 0 else lam * wmin
            x = s_eff if s_eff > 0 else 0.0
            kk = (x * x) / two_r - 0.5 * lam_w
            e_s = 0.5 * m2 * rmax * smax / R
            g_ss = a11 * a11 + a21 * a21
            g_tt = a12 * a12 + a22 * a22
            g_st = abs(a11 * a12 + a21 * a22)
            k11 = g_ss / two_r - e_s - 0.5 * (h_ss * wmax if h_ss >= 0 else h_ss * wmin)
            k22 = g_tt / two_r - e_s - 0.5 * (h_tt * wmax if h_tt >= 0 else h_tt * wmin)
            k12 = g_st / two_r + 0.5 * h_st * wmax
            d_ = k11 - k22
            k_dir = 0.5 * (k11 + k22) - math.sqrt(0.25 * (d_ * d_) + k12 * k12)
            kk = kk if (kk >= k_dir or kk != kk) else k_dir
            # -- the material polygon (_material_polygon, classify, vertices) -------------------
            rb0 = bu0 + s0 * wu[i]
            rb1 = bu0 + s1 * wu[i]
            rb2 = bv0 + t0 * wv[i]
            rb3 = bv0 + t1 * wv[i]
            status = 1
            for k in range(K):
                segs_k[k] = -1
            for v in range(V):
                st[v, 0] = 0.0
                st[v, 1] = 0.0
                okv[v] = v < 4
            st[1, 0] = 1.0
            st[2, 1] = 1.0
            st[3, 0] = 1.0
            st[3, 1] = 1.0
            if stat_cur == 2 and E > 0:
                every = segs_cur[0] == -2
                count = 0
                ncand = E if every else K
                rdu = rb1 - rb0
                rdv = rb3 - rb2
                for m in range(ncand):
                    if every:
                        e = m
                        if not ((elo[e, 0] <= rb1 + pad) and (ehi[e, 0] >= rb0 - pad)
                                and (elo[e, 1] <= rb3 + pad) and (ehi[e, 1] >= rb2 - pad)):
                            continue
                    else:
                        e = segs_cur[m]
                        if e < 0:
                            continue
                    # Liang-Barsky (_clip)
                    a0 = edges[e, 0]
                    a1 = edges[e, 1]
                    d0 = edges[e, 2] - a0
                    d1 = edges[e, 3] - a1
                    hit, c0, c1 = clip_one(a0, a1, d0, d1, rb0, rb1, rb2, rb3)
                    if not hit:
                        continue
                    count += 1
                    if count <= K:
                        segs_k[count - 1] = e
                        for end in range(2):
                            tc = c0 if end == 0 else c1
                            row = 4 + (count - 1) + end * K
                            for c in range(2):
                                x = (a0 + tc * d0) if c == 0 else (a1 + tc * d1)
                                x = (x - rb0) / rdu if c == 0 else (x - rb2) / rdv
                                if x != x:
                                    x = 0.0
                                elif x == np.inf:
                                    x = _BIG
                                elif x == -np.inf:
                                    x = -_BIG
                                x = x if (x >= 0.0 or x != x) else 0.0
                                x = x if (x <= 1.0 or x != x) else 1.0
                                st[row, c] = x
                            okv[row] = True
                if count > K:
                    for k in range(K):
                        segs_k[k] = -2
                    for v in range(4, V):
                        okv[v] = False
                        st[v, 0] = 0.0
                        st[v, 1] = 0.0
                # the trim test (_FaceData.inside, _Bands) at the box's middle and corners
                pts[0, 0] = 0.5 * (rb0 + rb1)
                pts[0, 1] = 0.5 * (rb2 + rb3)
                pts[1, 0] = rb0
                pts[1, 1] = rb2
                pts[2, 0] = rb1
                pts[2, 1] = rb2
                pts[3, 0] = rb0
                pts[3, 1] = rb3
                pts[4, 0] = rb1
                pts[4, 1] = rb3
                for m in range(5):
                    ins[m] = inside_one(bands, band_v0, band_h, pts[m, 0], pts[m, 1], iu0, iu1,
                                        iv0, iv1)
                status = 2 if count > 0 else (1 if ins[0] else 0)
                for m in range(4):
                    okv[m] = ins[m + 1]
                if si == first - 1:
                    for k in range(K):
                        segs_cur[k] = segs_k[k]
                    stat_cur = status
            any_ok = False
            for v in range(V):
                any_ok = any_ok or okv[v]
            whole = segs_k[0] == -2 or not any_ok
            if whole:
                for v in range(V):
                    okv[v] = v < 4
            # -- the excess (_excess) -----------------------------------------------------------
            n1n = math.hypot(n10, n11)
            nn = n1n if n1n > 0 else 1.0
            nus[0, 0] = n10 / nn
            nus[0, 1] = n11 / nn
            nus[1, 0] = 1.0
            nus[1, 1] = 0.0
            nus[2, 0] = 0.0
            nus[2, 1] = 1.0
            cok[0] = True
            cok[1] = True
            cok[2] = True
            for k in range(K):
                sk = segs_k[k]
                e = sk if sk > 0 else 0
                if E > 0:
                    tn0 = (edges[e, 2] - edges[e, 0]) / du
                    tn1 = (edges[e, 3] - edges[e, 1]) / dv
                else:
                    tn0 = 0.0 / du
                    tn1 = 0.0 / dv
                x0 = -tn1
                x1 = tn0
                nl = math.hypot(x0, x1)
                cok[3 + k] = sk >= 0 and nl > 0
                nd = nl if nl > 0 else 1.0
                nus[3 + k, 0] = x0 / nd
                nus[3 + k, 1] = x1 / nd
            best = np.inf
            nan = False
            for c in range(3 + K):
                alpha = n10 * nus[c, 0] + n11 * nus[c, 1]
                sgn = -1.0 if alpha < 0 else 1.0
                v0_ = nus[c, 0] * sgn
                v1_ = nus[c, 1] * sgn
                alpha = abs(alpha)
                x = n1n * n1n - alpha * alpha
                x = x if (x >= 0.0 or x != x) else 0.0
                beta = math.sqrt(x)
                top = -np.inf
                for v in range(V):
                    if okv[v]:
                        pr = v0_ * (st[v, 0] - ls) + v1_ * (st[v, 1] - lt)
                        top = top if (top >= pr or top != top) else pr
                delta = top if (top >= 0.0 or top != top) else 0.0
                if cok[c]:
                    x = wmax * beta
                    cand = wmax * alpha * delta + (x * x) / (4.0 * kk)
                else:
                    cand = np.inf
                if cand != cand:
                    nan = True
                elif cand < best:
                    best = cand
            excess = (np.nan if nan else best) / (wmin * wmin)
            usable = status > 0 or whole
            if kk > 0 and wmin > 0 and usable and excess <= limit[i]:
                found[i] = True
                out_box[i, 0] = rb0
                out_box[i, 1] = rb1
                out_box[i, 2] = rb2
                out_box[i, 3] = rb3
                out_ex[i] = excess
                break
    return found, out_box, out_ex


regions = Kernel(_regions_loops)


@helper
def _ball_depth_loops(point, qq, R2):
    """h = sqrt(R^2 - |S_xy - q|^2) (at least 1e-300 under the root) of
    :func:`~BSplineCAM.core.toolpath.faceset_contacts.grad_hess`: (n,)."""
    n = point.shape[0]
    h = np.empty(n)
    for i in range(n):
        d0 = point[i, 0] - qq[i, 0]
        d1 = point[i, 1] - qq[i, 1]
        x = R2 - (d0 * d0 + d1 * d1)
        x = x if (x >= 1e-300 or x != x) else 1e-300
        h[i] = math.sqrt(x)
    return h


@helper
def _grad_hess_loops(point, su, sw, suu, suw, sww, qq, h, h3):
    """Gradient and Hessian (gu, gw, Huu, Huw, Hww) (5, n) of f(u, v) = S_z + sqrt(R^2 -
    |S_xy - q|^2) as :func:`~BSplineCAM.core.toolpath.faceset_contacts.grad_hess`, from the
    surface's derivatives, h (:func:`_ball_depth_loops`) and h ** 3."""
    n = point.shape[0]
    out = np.empty((5, n))
    for i in range(n):
        D0 = point[i, 0] - qq[i, 0]
        D1 = point[i, 1] - qq[i, 1]
        u0 = su[i, 0]
        u1 = su[i, 1]
        w0 = sw[i, 0]
        w1 = sw[i, 1]
        dDu = D0 * u0 + D1 * u1
        dDw = D0 * w0 + D1 * w1
        hi = h[i]
        h3i = h3[i]
        out[0, i] = su[i, 2] - dDu / hi
        out[1, i] = sw[i, 2] - dDw / hi
        out[2, i] = (suu[i, 2] - ((u0 * u0 + u1 * u1) + (D0 * suu[i, 0] + D1 * suu[i, 1])) / hi
                     - dDu * dDu / h3i)
        out[3, i] = (suw[i, 2] - ((u0 * w0 + u1 * w1) + (D0 * suw[i, 0] + D1 * suw[i, 1])) / hi
                     - dDu * dDw / h3i)
        out[4, i] = (sww[i, 2] - ((w0 * w0 + w1 * w1) + (D0 * sww[i, 0] + D1 * sww[i, 1])) / hi
                     - dDw * dDw / h3i)
    return out


@helper
def _newton_loops(gh, u, v, dom):
    """Projected Newton step of :func:`~BSplineCAM.core.toolpath.faceset_contacts.newton_step`
    from the gradient and Hessian ``gh`` (5, n), its new (u, v) clamped to the domain ``dom``
    (u0, u1, v0, v1) as :func:`~BSplineCAM.core.toolpath.faceset_contacts.polish` does:
    (ok, new u, new v)."""
    n = u.shape[0]
    ok = np.empty(n, dtype=np.bool_)
    nu = np.empty(n)
    nv = np.empty(n)
    u0, u1, v0, v1 = dom[0], dom[1], dom[2], dom[3]
    for i in range(n):
        gu = gh[0, i]
        gw = gh[1, i]
        huu = gh[2, i]
        huw = gh[3, i]
        hww = gh[4, i]
        det = huu * hww - huw * huw
        concave = huu < 0 and det > 0
        safe = det if concave else 1.0
        du = -(hww * gu - huw * gw) / safe if concave else 0.0
        dw = -(huu * gw - huw * gu) / safe if concave else 0.0
        ui = u[i]
        vi = v[i]
        pin_u = (ui <= u0 and gu < 0) or (ui >= u1 and gu > 0)
        pin_v = (vi <= v0 and gw < 0) or (vi >= v1 and gw > 0)
        side_u = pin_u and not pin_v and hww < 0
        side_v = pin_v and not pin_u and huu < 0
        if side_u:
            du = 0.0
        elif side_v:
            du = -gu / huu
        if side_v:
            dw = 0.0
        elif side_u:
            dw = -gw / hww
        good = (concave or side_u or side_v) and np.isfinite(du) and np.isfinite(dw)
        ok[i] = good
        x = ui + (du if good else 0.0)
        x = x if (x >= u0 or x != x) else u0
        nu[i] = x if (x <= u1 or x != x) else u1
        x = vi + (dw if good else 0.0)
        x = x if (x >= v0 or x != x) else v0
        nv[i] = x if (x <= v1 or x != x) else v1
    return ok, nu, nv


@helper
def _newton_accept_loops(p, qq, R2, fbest, ok, nu, nv, u, v, bands, band_v0, band_h, dom):
    """The values f at the stepped points ``p`` (n, 3) and whether each step counts (ok, moved,
    raises f above ``fbest``, inside the trim: the even-odd test of
    :meth:`~BSplineCAM.core.toolpath.faceset_trims._FaceData.inside` over the band table),
    as :func:`~BSplineCAM.core.toolpath.faceset_contacts.polish`: (f (n,), good (n,))."""
    n = p.shape[0]
    fv = np.empty(n)
    good = np.zeros(n, dtype=np.bool_)
    eu = 1e-12 * (dom[1] - dom[0])
    ev = 1e-12 * (dom[3] - dom[2])
    for i in range(n):
        d0 = p[i, 0] - qq[i, 0]
        d1 = p[i, 1] - qq[i, 1]
        pd = d0 * d0 + d1 * d1
        x = R2 - pd
        x = x if (x >= 0.0 or x != x) else 0.0
        f = p[i, 2] + math.sqrt(x) if pd <= R2 else -np.inf
        fv[i] = f
        if not (f > fbest[i] and ok[i] and abs(nu[i] - u[i]) + abs(nv[i] - v[i]) > 0):
            continue
        good[i] = inside_one(bands, band_v0, band_h, nu[i], nv[i], dom[0] + eu, dom[1] - eu,
                             dom[2] + ev, dom[3] - ev)
    return fv, good


@helper
def _edge_step_loops(gh, dd, t):
    """Newton's step along the trim segments of
    :func:`~BSplineCAM.core.toolpath.faceset_contacts.edge_polish`: the new parameters
    (n,) on the segments (directions ``dd`` (n, 2)) from the gradient and Hessian ``gh``
    (5, n) at ``t``, clamped to [0, 1]."""
    n = t.shape[0]
    nt = np.empty(n)
    for i in range(n):
        e0 = dd[i, 0]
        e1 = dd[i, 1]
        f1 = gh[0, i] * e0 + gh[1, i] * e1
        f2 = gh[2, i] * (e0 * e0) + 2.0 * gh[3, i] * e0 * e1 + gh[4, i] * (e1 * e1)
        if f2 < 0:
            step = -f1 / f2
        elif f1 > 0:
            step = 1.0
        elif f1 < 0:
            step = -1.0
        elif f1 == 0:
            step = 0.0
        else:
            step = f1  # NaN, as np.sign's
        if step != step:
            step = 0.0
        elif step == np.inf:
            step = _BIG
        elif step == -np.inf:
            step = -_BIG
        x = t[i] + step
        x = x if (x >= 0.0 or x != x) else 0.0
        nt[i] = x if (x <= 1.0 or x != x) else 1.0
    return nt


@helper
def _edge_accept_loops(p, qq, R2, nt, t, ft):
    """f at the points ``p`` (n, 3) of the stepped parameters ``nt``; where it beats ``ft``
    the parameter and value move there (``t``, ``ft`` in place), as
    :func:`~BSplineCAM.core.toolpath.faceset_contacts.edge_polish`: how many moved."""
    n = p.shape[0]
    moved = 0
    for i in range(n):
        d0 = p[i, 0] - qq[i, 0]
        d1 = p[i, 1] - qq[i, 1]
        pd = d0 * d0 + d1 * d1
        x = R2 - pd
        x = x if (x >= 0.0 or x != x) else 0.0
        f = p[i, 2] + math.sqrt(x) if pd <= R2 else -np.inf
        if f > ft[i]:
            t[i] = nt[i]
            ft[i] = f
            moved += 1
    return moved


def _polish_ders_loops(u, v, qq, R2, rows, rational, knots_u, p, first_u, last_u, knots_v, q,
                       first_v, last_v, spans_v, orders, offsets, tables, dim, index, dom):
    """The first step of a polish step (:func:`~BSplineCAM.core.toolpath.faceset_contacts.
    polish`): the surface's point and derivatives at (u, v) (:mod:`.nurbs_eval`'s loops over
    its pack of the orders the quotient rule needs, ``rows`` (6,) of point, Su, Sw, Suu, Suw,
    Sww among them; ``dom`` the domain and its tolerances) and h
    (:func:`_ball_depth_loops`): (derivatives (k, n, 3), h (n,), whether (u, v) lay in the
    domain).  The caller takes h ** 3 with numpy (see the module docstring)."""
    cu, cv, ok = _check_loops(u, v, dom[0], dom[1], dom[2], dom[3], dom[4], dom[5])
    ders, _, _ = _scattered_loops(knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                                  spans_v, orders, offsets, tables, dim, cu, cv)
    if rational:
        ders = _rational_loops(ders, orders, index)
    return ders, _ball_depth_loops(ders[rows[0]], qq, R2), ok


def _polish_step_loops(ders, rows, h, h3, qq, R2, u, v, fbest, dom, bands, band_v0, band_h,
                       rational, knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                       spans_v, orders, offsets, tables, dim, index, tol):
    """The rest of a polish step: the gradient and Hessian (:func:`_grad_hess_loops`), the
    projected Newton step (:func:`_newton_loops`), the surface's point there (the pack of
    order (0, 0), ``tol`` the domain and its tolerances) and the step's value and acceptance
    (:func:`_newton_accept_loops`): (f (n,), good (n,), new u, new v, whether the new
    (u, v) lay in the domain)."""
    gh = _grad_hess_loops(ders[rows[0]], ders[rows[1]], ders[rows[2]], ders[rows[3]],
                          ders[rows[4]], ders[rows[5]], qq, h, h3)
    ok, nu, nv = _newton_loops(gh, u, v, dom)
    cu, cv, inside = _check_loops(nu, nv, tol[0], tol[1], tol[2], tol[3], tol[4], tol[5])
    pts, _, _ = _scattered_loops(knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                                 spans_v, orders, offsets, tables, dim, cu, cv)
    if rational:
        pts = _rational_loops(pts, orders, index)
    fv, good = _newton_accept_loops(pts[0], qq, R2, fbest, ok, nu, nv, u, v, bands, band_v0,
                                    band_h, dom)
    return fv, good, nu, nv, inside


def _edge_polish_step_loops(ders, rows, h, h3, qq, R2, a, dd, t, ft, rational, knots_u, p,
                            first_u, last_u, knots_v, q, first_v, last_v, spans_v, orders,
                            offsets, tables, dim, index, tol):
    """The rest of a Newton step along trim segments a + t dd
    (:func:`~BSplineCAM.core.toolpath.faceset_contacts.edge_polish`), after
    :func:`_polish_ders_loops` at a + t dd: the gradient and Hessian, the step
    (:func:`_edge_step_loops`), the surface's points there (the pack of order (0, 0)) and
    the moves that raise f (:func:`_edge_accept_loops`; ``t``, ``ft`` in place): (how many
    moved, whether the new points lay in the domain)."""
    gh = _grad_hess_loops(ders[rows[0]], ders[rows[1]], ders[rows[2]], ders[rows[3]],
                          ders[rows[4]], ders[rows[5]], qq, h, h3)
    nt = _edge_step_loops(gh, dd, t)
    n = t.shape[0]
    nu = np.empty(n)
    nv = np.empty(n)
    for i in range(n):
        nu[i] = a[i, 0] + nt[i] * dd[i, 0]
        nv[i] = a[i, 1] + nt[i] * dd[i, 1]
    cu, cv, inside = _check_loops(nu, nv, tol[0], tol[1], tol[2], tol[3], tol[4], tol[5])
    pts, _, _ = _scattered_loops(knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                                 spans_v, orders, offsets, tables, dim, cu, cv)
    if rational:
        pts = _rational_loops(pts, orders, index)
    return _edge_accept_loops(pts[0], qq, R2, nt, t, ft), inside


polish_ders = Kernel(_polish_ders_loops)
edge_polish_step = Kernel(_edge_polish_step_loops)
polish_step = Kernel(_polish_step_loops)
ball_depth = Kernel(_ball_depth_loops)
grad_hess = Kernel(_grad_hess_loops)
newton = Kernel(_newton_loops)
newton_accept = Kernel(_newton_accept_loops)
edge_step = Kernel(_edge_step_loops)
edge_accept = Kernel(_edge_accept_loops)
