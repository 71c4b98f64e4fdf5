# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the drop-cutter on one net (:class:`~BSplineCAM.core.toolpath.
dropcutter.DropCutter`): one call answers a block of queries, each on its own, where the
numpy engine makes a few hundred array operations per block (:func:`centre_heights`), and one
gives their slopes from the contacts (:func:`slopes`).

Per query, as the numpy engine: the seeds (the best sample of the 5 x 5 hash cells around the
query, and the best sampled peak outside its neighbourhood, ``DropCutter.seeds`` and
``_sampled_peak``), each moved to its parabola's vertex (``_vertex_seed``), the projected
Newton ascent with backtracking from each (``DropCutter.refine`` and ``_indefinite_step``),
the higher of the two.  The candidates are scanned in the numpy engine's order and the first
of equal maxima is taken, as ``np.argmax`` takes it; the surface jets are the paper's matrix
form per patch (:func:`~BSplineCAM.core.geometry.matrix.evaluate_patch_orders`), its
4-term sums added in order.  Where numpy leaves the last bit to its library (``h ** 3``, the
einsum's summation order, ``arctan2``), the two engines may differ by a rounding, so they
agree to far below 1e-12 mm and take the same decisions but for ties within a rounding.

Every value is f at a real surface point, as in the numpy engine, so a height never exceeds
the true one.  The kernels take contiguous float64 and int64 arrays only.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper


@helper
def unit(t):
    """t clamped to [0, 1] (NaN stays NaN, as ``np.minimum(np.maximum(t, 0), 1)``)."""
    if t < 0.0:
        return 0.0
    if t > 1.0:
        return 1.0
    return t


@helper
def power_row(s, derivative, spans, row):
    """[s^3, s^2, s, 1] or its ``derivative`` in the normalised parameter into ``row`` (4,)
    (``matrix.power_rows``)."""
    if derivative == 0:
        row[0], row[1], row[2], row[3] = s * s * s, s * s, s, 1.0
        return
    scale = float(spans) ** derivative
    if derivative == 1:
        row[0], row[1], row[2], row[3] = 3.0 * s * s * scale, 2.0 * s * scale, scale, 0.0
    else:
        row[0], row[1], row[2], row[3] = 6.0 * s * scale, 2.0 * scale, 0.0, 0.0


@helper
def locate(t, spans):
    """Patch index and local parameter of t in [0, 1] (``matrix.locate``)."""
    scaled = t * spans
    index = int(math.floor(scaled))
    index = min(max(index, 0), spans - 1)
    return index, scaled - index


@helper
def jet_at(coef, p_u, p_w, u, w, orders, out, rows, planes):
    """Point (``orders`` 1) or point, Su, Sw, Suu, Suw, Sww (``orders`` 6) at (u, w) in [0, 1]
    into ``out`` (6, 3); ``rows`` (4,) and ``planes`` (3, 4, 3) are scratch."""
    iu, su = locate(u, p_u)
    iw, sw = locate(w, p_w)
    patch = iu * p_w + iw
    top = 1 if orders == 1 else 3
    for dq in range(top):
        power_row(sw, dq, p_w, rows)
        for k in range(12):
            acc = 0.0
            for b in range(4):
                acc += rows[b] * coef[patch, b, k]
            planes[dq, k // 3, k % 3] = acc
    for o in range(orders):
        dp = (0, 1, 0, 2, 1, 0)[o]
        dq = (0, 0, 1, 0, 1, 2)[o]
        power_row(su, dp, p_u, rows)
        for c in range(3):
            acc = 0.0
            for a in range(4):
                acc += rows[a] * planes[dq, a, c]
            out[o, c] = acc


@helper
def maximand(qx, qy, px, py, pz, R2):
    """f = p_z + sqrt(R^2 - |p_xy - q|^2), -inf outside the ball (``DropCutter._maximand``)."""
    d2 = (px - qx) ** 2 + (py - qy) ** 2
    if d2 < R2:
        return pz + math.sqrt(max(R2 - d2, 0.0))
    return -math.inf


@helper
def sampled_value(qx, qy, px, py, pz, R2):
    """The seeds' f of a sample: -inf beyond the ball, inclusive of its rim."""
    d2 = (px - qx) ** 2 + (py - qy) ** 2
    if d2 <= R2:
        return pz + math.sqrt(max(R2 - d2, 0.0))
    return -math.inf


@helper
def indefinite_step(gu, gw, Huu, Huw, Hww, tu, tw):
    """Ascent step (du, dw) where the Hessian is not negative definite
    (``dropcutter._indefinite_step``)."""
    a, b, c = Huu * tu * tu, Huw * tu * tw, Hww * tw * tw
    ga, gb = gu * tu, gw * tw
    half = 0.5 * (a - c)
    radius = math.hypot(half, b)
    mean = 0.5 * (a + c)
    theta = 0.5 * math.atan2(b, half)
    cos, sin = math.cos(theta), math.sin(theta)
    step_a = 0.0
    step_b = 0.0
    for k in range(2):
        lam = mean + radius if k == 0 else mean - radius
        va = cos if k == 0 else -sin
        vb = sin if k == 0 else cos
        g = ga * va + gb * vb
        if lam < 0.0:
            t = -g / lam
            t = -1.0 if t < -1.0 else (1.0 if t > 1.0 else t)
        else:
            t = -1.0 if g < 0.0 else 1.0
        step_a += t * va
        step_b += t * vb
    return step_a * tu, step_b * tw


@helper
def refine_one(coef, p_u, p_w, qx, qy, u, w, R2, tu, tw, ps_u, ps_w, iterations, converged,
               jet, trial, rows, planes):
    """Projected Newton ascent of f from (u, w) (``DropCutter.refine`` for one query):
    (centre z, u, w); ``jet``, ``trial`` (6, 3), ``rows`` and ``planes`` are scratch."""
    u, w = unit(u), unit(w)
    jet_at(coef, p_u, p_w, u, w, 6, jet, rows, planes)
    fval = maximand(qx, qy, jet[0, 0], jet[0, 1], jet[0, 2], R2)
    if not math.isfinite(fval):
        return fval, u, w
    for _ in range(iterations):
        Dx = jet[0, 0] - qx
        Dy = jet[0, 1] - qy
        h = math.sqrt(max(R2 - (Dx * Dx + Dy * Dy), 1e-300))
        Dux, Duy, Dwx, Dwy = jet[1, 0], jet[1, 1], jet[2, 0], jet[2, 1]
        dDu = Dx * Dux + Dy * Duy
        dDw = Dx * Dwx + Dy * Dwy
        gu = jet[1, 2] - dDu / h
        gw = jet[2, 2] - dDw / h
        h3 = math.pow(h, 3.0)
        Huu = jet[3, 2] - ((Dux * Dux + Duy * Duy) + (Dx * jet[3, 0] + Dy * jet[3, 1])) / h \
            - dDu * dDu / h3
        Hww = jet[5, 2] - ((Dwx * Dwx + Dwy * Dwy) + (Dx * jet[5, 0] + Dy * jet[5, 1])) / h \
            - dDw * dDw / h3
        Huw = jet[4, 2] - ((Dux * Dwx + Duy * Dwy) + (Dx * jet[4, 0] + Dy * jet[4, 1])) / h \
            - dDu * dDw / h3
        fix_u = (u <= 0.0 and gu < 0) or (u >= 1.0 and gu > 0)
        fix_w = (w <= 0.0 and gw < 0) or (w >= 1.0 and gw > 0)
        if fix_u:
            gu = 0.0
            Huu = -1.0
        if fix_w:
            gw = 0.0
            Hww = -1.0
        if fix_u or fix_w:
            Huw = 0.0
        det = Huu * Hww - Huw * Huw
        concave = Huu < 0 and det > 0
        if concave:
            du = -(Hww * gu - Huw * gw) / det
            dw = -(Huu * gw - Huw * gu) / det
        else:
            du, dw = indefinite_step(gu, gw, Huu, Huw, Hww, tu, tw)
        ratio = max(abs(du) / tu, abs(dw) / tw)
        shrink = 1.0 / max(ratio, 1e-300) if ratio > 1.0 else 1.0
        du *= shrink
        dw *= shrink
        model_gain = gu * du + gw * dw
        model_gain += 0.5 * (Huu * du * du + 2.0 * Huw * du * dw + Hww * dw * dw)
        if concave and shrink == 1.0 and model_gain < converged:
            return fval, unit(u + du), unit(w + dw)
        f0 = fval
        cu, cw = unit(u + du), unit(w + dw)
        jet_at(coef, p_u, p_w, cu, cw, 6, trial, rows, planes)
        fc = maximand(qx, qy, trial[0, 0], trial[0, 1], trial[0, 2], R2)
        full = fc >= f0
        halved = False
        if full:
            nu, nw, fnew = cu, cw, fc
        else:
            nu, nw, fnew = u, w, f0
            step = 0.5
            for _halving in range(7):
                hu, hw = unit(u + step * du), unit(w + step * dw)
                jet_at(coef, p_u, p_w, hu, hw, 1, trial, rows, planes)
                fh = maximand(qx, qy, trial[0, 0], trial[0, 1], trial[0, 2], R2)
                if fh >= f0:
                    nu, nw, fnew = hu, hw, fh
                    halved = True
                    break
                step *= 0.5
        moved = math.hypot((nu - u) / ps_u, (nw - w) / ps_w)
        u, w, fval = nu, nw, fnew
        still = (full or halved) and moved > 1e-9 and fnew - f0 > 1e-13
        if full:
            jet[:, :] = trial
        elif halved:
            jet_at(coef, p_u, p_w, nu, nw, 6, jet, rows, planes)
        if not still:
            break
    return fval, u, w


@helper
def vertex_seed(qx, qy, i, j, samples, n_u, n_w, gu, gw, R2):
    """(u, w) of sample (i, j) moved to the vertex of the parabola through f at it and its
    grid neighbours along u and along w, at most one grid step (``DropCutter._vertex_seed``)."""
    out_u = 0.0
    out_w = 0.0
    for axis in range(2):
        n = n_u if axis == 0 else n_w
        k = i if axis == 0 else j
        inner = 0 < k < n - 1
        down = k - 1 if inner else k
        up = k + 1 if inner else k
        if axis == 0:
            a0, a1, a2 = down * n_w + j, i * n_w + j, up * n_w + j
        else:
            a0, a1, a2 = i * n_w + down, i * n_w + j, i * n_w + up
        f0 = maximand(qx, qy, samples[a0, 0], samples[a0, 1], samples[a0, 2], R2)
        f1 = maximand(qx, qy, samples[a1, 0], samples[a1, 1], samples[a1, 2], R2)
        f2 = maximand(qx, qy, samples[a2, 0], samples[a2, 1], samples[a2, 2], R2)
        shift = 0.0
        if inner and math.isfinite(f0) and math.isfinite(f2):
            curv = f0 - 2.0 * f1 + f2
            if curv < 0:
                shift = 0.5 * (f0 - f2) / curv
        shift = -1.0 if shift < -1.0 else (1.0 if shift > 1.0 else shift)
        step = 1.0 / (n - 1)
        if axis == 0:
            out_u = unit(gu[k] + shift * step)
        else:
            out_w = unit(gw[k] + shift * step)
    return out_u, out_w


@helper
def sampled_peak(qx, qy, i, j, value, samples, n_u, n_w, R2):
    """True where no grid neighbour of sample (i, j) has a higher f
    (``DropCutter._sampled_peak``)."""
    for di in range(-1, 2):
        for dj in range(-1, 2):
            if di == 0 and dj == 0:
                continue
            ni = min(max(i + di, 0), n_u - 1)
            nj = min(max(j + dj, 0), n_w - 1)
            a = ni * n_w + nj
            if sampled_value(qx, qy, samples[a, 0], samples[a, 1], samples[a, 2], R2) > value:
                return False
    return True


def _centre_heights_loops(q, sx, sy, sz, si, sj, starts, samples, gu, gw, lo_x, lo_y, cell,
                          ncx, ncy, n_u, n_w, window, R, margin, neighbourhood, coef, p_u,
                          p_w, iterations, converged, z, u, w):
    """Ball-centre heights (``DropCutter._centre_heights``) of the queries ``q`` (m, 2) into
    ``z`` (-inf where no surface lies within R), contacts into ``u``, ``w``.  ``sx``, ``sy``,
    ``sz``, ``si``, ``sj`` are the samples in hash order, ``starts`` the hash cells' first
    samples (at most ``window`` in 5 x 5 cells), ``samples`` (n_u * n_w, 3) the grid, ``gu``, ``gw`` its parameters, ``coef``
    the patches' power-basis coefficients (P, 4, 12) of ``p_u`` x ``p_w`` patches; the
    constants are the drop-cutter's (the basin's ``neighbourhood`` in grid steps, the
    Newton ``iterations`` and the gain ``converged`` (mm) that ends them)."""
    R2 = R * R
    ps_u = 1.0 / (n_u - 1)
    ps_w = 1.0 / (n_w - 1)
    tu = 3.0 * ps_u
    tw = 3.0 * ps_w
    jet = np.empty((6, 3))
    trial = np.empty((6, 3))
    rows = np.empty(4)
    planes = np.empty((3, 4, 3))
    cand_k = np.empty(window, np.int64)
    cand_f = np.empty(window)
    for m in range(q.shape[0]):
        qx = q[m, 0]
        qy = q[m, 1]
        cx = int(math.floor((qx - lo_x) / cell)) + 2
        cy = int(math.floor((qy - lo_y) / cell)) + 2
        cx = min(max(cx, 0), ncx - 1)
        cy = min(max(cy, 0), ncy - 1)
        c0 = min(max(cx - 2, 0), ncx - 1)
        c1 = min(max(cx + 2, 0), ncx - 1)
        # The best candidate, the first of equal maxima in the numpy engine's order.  A
        # candidate whose f is surely below the running best less the margin can be neither
        # the best nor a second basin (``has2`` needs value2 >= value - margin): its square
        # root is skipped.  The test leaves 1e-6 of the gap, at least 1e-12 (1 + |z|) mm, far
        # above the rounding of f, so no candidate that numpy could choose is skipped.
        value = -math.inf
        best = -1
        listed = 0
        for r in range(-2, 3):
            row = min(max(cy + r, 0), ncy - 1)
            for k in range(starts[row * ncx + c0], starts[row * ncx + c1 + 1]):
                d2 = (sx[k] - qx) ** 2 + (sy[k] - qy) ** 2
                if not d2 <= R2:
                    continue
                rest = R2 - d2
                t = (value - margin) - sz[k]
                if t > 1e-6 * (1.0 + abs(sz[k])) and rest < t * t * (1.0 - 1e-6):
                    continue
                f = sz[k] + math.sqrt(max(rest, 0.0))
                cand_k[listed] = k
                cand_f[listed] = f
                listed += 1
                if f > value:
                    value = f
                    best = k
        if best < 0:
            z[m] = -math.inf
            u[m] = 0.0
            w[m] = 0.0
            continue
        bi = si[best]
        bj = sj[best]
        # the best candidate outside the best's neighbourhood, among those that could count
        floor = value - margin
        value2 = -math.inf
        second = -1
        for c in range(listed):
            f = cand_f[c]
            if f < floor or f <= value2:
                continue
            k = cand_k[c]
            if abs(si[k] - bi) <= neighbourhood and abs(sj[k] - bj) <= neighbourhood:
                continue
            value2 = f
            second = k
        has2 = second >= 0 and value2 >= value - margin
        if has2:
            has2 = sampled_peak(qx, qy, si[second], sj[second], value2, samples, n_u, n_w, R2)
        su, sw = vertex_seed(qx, qy, bi, bj, samples, n_u, n_w, gu, gw, R2)
        fz, fu, fw = refine_one(coef, p_u, p_w, qx, qy, su, sw, R2, tu, tw, ps_u, ps_w,
                                iterations, converged, jet, trial, rows, planes)
        if has2:
            su, sw = vertex_seed(qx, qy, si[second], sj[second], samples, n_u, n_w, gu, gw, R2)
            fz2, fu2, fw2 = refine_one(coef, p_u, p_w, qx, qy, su, sw, R2, tu, tw, ps_u, ps_w,
                                       iterations, converged, jet, trial, rows, planes)
            if fz2 > fz:
                fz, fu, fw = fz2, fu2, fw2
        z[m] = fz
        u[m] = fu
        w[m] = fw


def _slopes_loops(q, u, w, coef, p_u, p_w, R, out):
    """Gradients (dz/dx, dz/dy) of the tip height at the queries ``q`` (m, 2) from their
    contacts (``u``, ``w`` in [0, 1]) into ``out`` (m, 2) (``DropCutter.slopes``)."""
    R2 = R * R
    point = np.empty((6, 3))
    rows = np.empty(4)
    planes = np.empty((3, 4, 3))
    for m in range(q.shape[0]):
        jet_at(coef, p_u, p_w, unit(u[m]), unit(w[m]), 1, point, rows, planes)
        dx = point[0, 0] - q[m, 0]
        dy = point[0, 1] - q[m, 1]
        h = math.sqrt(max(R2 - (dx * dx + dy * dy), 0.0))
        out[m, 0] = dx / h
        out[m, 1] = dy / h


centre_heights = Kernel(_centre_heights_loops)
slopes = Kernel(_slopes_loops)

__all__ = ["centre_heights", "slopes"]
