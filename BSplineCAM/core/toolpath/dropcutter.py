# SPDX-License-Identifier: LGPL-2.1-or-later
"""Exact drop-cutter for a ball end mill on the B-spline surface itself (no mesh).

For a ball of radius R whose centre is above (x, y), the lowest centre height that does not
cut the surface is

    c(x, y) = max over surface points p with |p_xy - q| <= R of  p_z + sqrt(R^2 - |p_xy - q|^2)

and the tool tip sits at c - R (Chuang, Chen & Yau 2002, "A reverse engineering approach to
ball-end drop cutting"; the inverse-tool-offset view of Kim & Chu).  The maximand

    f(u, w) = S_z + sqrt(R^2 - |S_xy - q|^2)

is maximised over the parameter square [0, 1]^2: an interior maximum is exactly the point
where the offset surface S + R n passes over q; maxima on the square's sides and corners are
the ball resting on the surface's boundary edges and corners.  A dense parameter sample
gives global seeds (the best one, and the best sampled peak outside its neighbourhood, so a
ball resting in a concave valley on two walls finds both contacts), and projected Newton with
backtracking (Nocedal & Wright, section 3.1 and 16.7) polishes each to machine precision,
stopping on the Newton decrement.  Where f is not concave (a seed on a saddle or in a valley of
f, as where the ball nearly fits a hollow) the step is still Newton's across the contact and a
trust step uphill along it, so the ascent reaches the maximum instead of stalling on its flank.
Every value is evaluated at a real surface point, so it never exceeds the true height; the
maximum over the polished seeds is taken.  A feature narrower than the sample spacing (about
R/4) whose basin no sample lies in is not seen.

The numpy code here is the reference and the fallback engine; under the numba engine each
query's seeds, vertex seeds and Newton ascent run in one compiled call per block of queries
(:mod:`~BSplineCAM.core.kernels.net_drop_kernels`), the same algorithm and decisions.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import kernels
from ..geometry import matrix
from ..kernels import net_drop_kernels
from ..threads import numpy_threads
from ..typing import FloatArray
from . import parallel
from .primitives import Jet, upward_sign

#: Queries handled per chunk: bounds the (queries x candidates) temporaries.
QUERY_CHUNK = 1024
#: Derivative orders of a jet: point, Su, Sw, Suu, Suw, Sww.
JET_ORDERS = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))
#: Predicted gain (mm) of a Newton step below which a maximum counts as found.
CONVERGED = 1e-14
#: Samples within this many grid steps of the best seed belong to its basin.
NEIGHBOURHOOD = 2
#: Newton iterations of :meth:`DropCutter.refine` at most.
REFINE_ITERATIONS = 30
#: Queries per worker thread: a call with fewer runs on the caller's thread alone.
THREAD_QUERIES = 4096


class DropCutter:
    """Ball drop-cutter on one surface; build once per (surface, radius), query many times.

    >>> dc = DropCutter(surface, radius=3.0)
    >>> tip_z, u, w = dc.heights(xy)          # xy: (m, 2) mm -> tip heights (mm), contacts
    """

    def __init__(self, surface: Any, radius: float, spacing: float | None = None):
        self.surface = surface
        self.radius = float(radius)
        self.sign = upward_sign(surface)
        self.form = surface.patch_form
        # Dense sample: about R/4 between samples, so a seed lies within the basin of the
        # maximum that Newton then converges to (and cells hold a bounded number of samples).
        spacing = self.radius / 4.0 if spacing is None else float(spacing)
        coarse = surface.grid(33, 33)
        len_u = np.linalg.norm(np.diff(coarse, axis=0), axis=-1).sum(axis=0).max()
        len_w = np.linalg.norm(np.diff(coarse, axis=1), axis=-1).sum(axis=1).max()
        self.n_u = int(np.clip(math.ceil(len_u / spacing) + 1, 16, 1200))
        self.n_w = int(np.clip(math.ceil(len_w / spacing) + 1, 16, 1200))
        self.u = np.linspace(0.0, 1.0, self.n_u)
        self.w = np.linspace(0.0, 1.0, self.n_w)
        pts = np.ascontiguousarray(surface.evaluate_grid(self.u, self.w)).reshape(-1, 3)
        self.samples = pts
        self.lo = pts[:, :2].min(axis=0)
        self.hi = pts[:, :2].max(axis=0)
        # Spatial hash: cells of size R/2, samples sorted by (row, column) of their cell; a
        # query scans the 5 x 5 cells around its own.
        self.cell = self.radius / 2.0
        self.ncx = int((self.hi[0] - self.lo[0]) // self.cell) + 5
        self.ncy = int((self.hi[1] - self.lo[1]) // self.cell) + 5
        cx, cy = self._cells(pts[:, :2])
        key = cy * self.ncx + cx
        self.order = np.argsort(key, kind="stable")
        self.starts = np.searchsorted(key[self.order], np.arange(self.ncx * self.ncy + 1))
        self.sx, self.sy, self.sz = (np.ascontiguousarray(pts[self.order, k]) for k in range(3))
        gi, gj = np.divmod(self.order, self.n_w)
        self.si, self.sj = gi.astype(np.int32), gj.astype(np.int32)
        self._si64, self._sj64 = gi.astype(np.int64), gj.astype(np.int64)
        self._starts64 = self.starts.astype(np.int64)
        # most samples a query's 5 x 5 cells hold (the compiled seeds' scratch)
        self._window = 25 * int(np.diff(self.starts).max(initial=0))
        self.param_step = (1.0 / (self.n_u - 1), 1.0 / (self.n_w - 1))
        gap = max(np.linalg.norm(np.diff(coarse, axis=0), axis=-1).max() * 32 / (self.n_u - 1),
                  np.linalg.norm(np.diff(coarse, axis=1), axis=-1).max() * 32 / (self.n_w - 1))
        self.margin = gap * gap / self.radius

    def jet(self, u: FloatArray, w: FloatArray) -> Jet:
        """Surface jet at (u, w) (clipped to [0, 1]) with the normal oriented upwards."""
        return Jet.at(self.surface, u, w, self.sign)

    def points(self, u: FloatArray, w: FloatArray) -> FloatArray:
        """Surface points at (u, w), clipped to [0, 1] (mm)."""
        return self.surface.evaluate(np.clip(u, 0.0, 1.0), np.clip(w, 0.0, 1.0))

    def _cells(self, xy: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        c = np.floor((xy - self.lo) / self.cell).astype(np.intp) + 2
        return (np.clip(c[:, 0], 0, self.ncx - 1), np.clip(c[:, 1], 0, self.ncy - 1))

    # -- seeds ------------------------------------------------------------------------------
    def seeds(self, q: FloatArray) -> tuple[np.ndarray, np.ndarray, FloatArray]:
        """Best sample index and the best sampled peak outside its neighbourhood (-1 if
        none), and the best sampled centre height (-inf where no surface lies within R)."""
        m = len(q)
        best = np.full(m, -1)
        second = np.full(m, -1)
        value = np.full(m, -np.inf)
        R2 = self.radius * self.radius
        cx, cy = self._cells(q)
        rows = np.clip(cy[:, None] + np.arange(-2, 3), 0, self.ncy - 1)  # (m, 5)
        k0 = rows * self.ncx + np.clip(cx - 2, 0, self.ncx - 1)[:, None]
        k1 = rows * self.ncx + np.clip(cx + 2, 0, self.ncx - 1)[:, None]
        lo_all = self.starts[k0]
        hi_all = self.starts[k1 + 1]
        # Chunks of queries with alike candidate counts: a chunk is padded to its widest row.
        sequence = np.argsort((hi_all - lo_all).max(axis=1), kind="stable")
        for start in range(0, m, QUERY_CHUNK):
            sl = sequence[start:start + QUERY_CHUNK]
            qq = q[sl]
            lo = lo_all[sl]
            hi = hi_all[sl]
            width = int((hi - lo).max(initial=0))
            if width == 0:
                continue
            idx = lo[:, :, None] + np.arange(width)
            ok = idx < hi[:, :, None]
            idx = np.where(ok, idx, 0).reshape(len(qq), -1)
            ok = ok.reshape(len(qq), -1)
            d2 = (self.sx[idx] - qq[:, :1]) ** 2
            d2 += (self.sy[idx] - qq[:, 1:]) ** 2
            ok &= d2 <= R2
            np.subtract(R2, d2, out=d2)
            np.maximum(d2, 0.0, out=d2)
            f = np.sqrt(d2, out=d2)
            f += self.sz[idx]
            f[~ok] = -np.inf
            rows_ = np.arange(len(qq))
            a = np.argmax(f, axis=1)
            value[sl] = f[rows_, a]
            ci, cj = self.si[idx], self.sj[idx]
            bi, bj = ci[rows_, a], cj[rows_, a]
            near = np.abs(ci - bi[:, None]) <= NEIGHBOURHOOD
            near &= np.abs(cj - bj[:, None]) <= NEIGHBOURHOOD
            f[near] = -np.inf
            a2 = np.argmax(f, axis=1)
            value2 = f[rows_, a2]
            # A second basin is worth polishing only if its sample could beat the best after
            # refinement (sampling error of a maximum is below ~ spacing^2 / R) and is a peak
            # of the sampled maximand: a sample with a higher grid neighbour lies on the flank
            # of the best's basin (every higher sample is within the best's neighbourhood).
            has2 = value2 >= value[sl] - self.margin
            i2, j2 = ci[rows_, a2], cj[rows_, a2]
            has2[has2] = self._sampled_peak(qq[has2], i2[has2], j2[has2], value2[has2])
            found = np.isfinite(value[sl])
            best[sl] = np.where(found, bi * self.n_w + bj, -1)
            second[sl] = np.where(has2, i2 * self.n_w + j2, -1)
        return best, second, value

    def _sampled_peak(self, q: FloatArray, i: np.ndarray, j: np.ndarray,
                      value: FloatArray) -> np.ndarray:
        """True where no grid neighbour of sample (i, j) has a higher maximand for query q."""
        di = np.array([-1, -1, -1, 0, 0, 1, 1, 1])
        dj = np.array([-1, 0, 1, -1, 1, -1, 0, 1])
        ni = np.clip(i[:, None] + di, 0, self.n_u - 1)
        nj = np.clip(j[:, None] + dj, 0, self.n_w - 1)
        p = self.samples[ni * self.n_w + nj]  # (m, 8, 3)
        d2 = (p[..., 0] - q[:, :1]) ** 2 + (p[..., 1] - q[:, 1:]) ** 2
        R2 = self.radius * self.radius
        f = np.where(d2 <= R2, p[..., 2] + np.sqrt(np.maximum(R2 - d2, 0.0)), -np.inf)
        return ~(f > value[:, None]).any(axis=1)

    def _vertex_seed(self, q: FloatArray, i: np.ndarray, j: np.ndarray) -> tuple[FloatArray,
                                                                                  FloatArray]:
        """(u, w) of sample (i, j) moved to the vertex of the parabola through the maximand
        at it and its two grid neighbours, along u and along w (at most one grid step), so
        that Newton starts closer to the maximum; a sample on the grid's border, or whose
        neighbours lie outside the ball, stays where it is."""
        out = []
        for axis, (n, t) in enumerate(((self.n_u, self.u), (self.n_w, self.w))):
            k = (i, j)[axis]
            inner = (k > 0) & (k < n - 1)
            down, up = np.where(inner, k - 1, k), np.where(inner, k + 1, k)
            f0, f1, f2 = (self._maximand(q, self.samples[a * self.n_w + b])
                          for a, b in (((down, j), (i, j), (up, j)) if axis == 0
                                       else ((i, down), (i, j), (i, up))))
            with np.errstate(invalid="ignore"):  # -inf - -inf: a neighbour outside the ball
                curv = f0 - 2.0 * f1 + f2
                good = inner & np.isfinite(f0) & np.isfinite(f2) & (curv < 0)
                shift = np.where(good, 0.5 * (f0 - f2) / np.where(good, curv, -1.0), 0.0)
            step = 1.0 / (n - 1)
            out.append(_unit(t[k] + np.clip(shift, -1.0, 1.0) * step))
        return out[0], out[1]

    # -- refinement -------------------------------------------------------------------------
    def _jets(self, u: FloatArray, w: FloatArray) -> list[FloatArray]:
        """Point, Su, Sw, Suu, Suw, Sww at (u, w) already in [0, 1], each (m, 3)."""
        return matrix.evaluate_patch_orders(self.form, u, w, JET_ORDERS)

    def _maximand(self, q: FloatArray, p: FloatArray) -> FloatArray:
        """f = p_z + sqrt(R^2 - |p_xy - q|^2) for surface points p (-inf outside the ball)."""
        d2 = (p[:, 0] - q[:, 0]) ** 2 + (p[:, 1] - q[:, 1]) ** 2
        R2 = self.radius ** 2
        return np.where(d2 < R2, p[:, 2] + np.sqrt(np.maximum(R2 - d2, 0.0)), -np.inf)

    def refine(self, q: FloatArray, u: FloatArray, w: FloatArray,
               iterations: int = REFINE_ITERATIONS) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Projected Newton ascent of f(u, w) from (u, w); returns (centre z, u, w).

        The jet is evaluated at each trial point, so an accepted full step carries its
        derivatives into the next iteration; a point stops once the quadratic model predicts
        no gain above ``CONVERGED`` (mm), after that last step, or once a step gains nothing.
        """
        R2 = self.radius ** 2
        u, w = _unit(u), _unit(w)
        jet = self._jets(u, w)
        fval = self._maximand(q, jet[0])
        active = np.flatnonzero(np.isfinite(fval))
        jet = [a[active] for a in jet]
        trust = 3.0 * np.array(self.param_step)
        for _ in range(iterations):
            if len(active) == 0:
                break
            qa = q[active]
            p, su, sw, suu, suw, sww = jet
            D = p[:, :2] - qa
            h = np.sqrt(np.maximum(R2 - (D * D).sum(axis=1), 1e-300))
            Du, Dw = su[:, :2], sw[:, :2]
            dDu = (D * Du).sum(1)
            dDw = (D * Dw).sum(1)
            gu = su[:, 2] - dDu / h
            gw = sw[:, 2] - dDw / h
            h3 = h ** 3
            Huu = suu[:, 2] - ((Du * Du).sum(1) + (D * suu[:, :2]).sum(1)) / h - dDu * dDu / h3
            Hww = sww[:, 2] - ((Dw * Dw).sum(1) + (D * sww[:, :2]).sum(1)) / h - dDw * dDw / h3
            Huw = suw[:, 2] - ((Du * Dw).sum(1) + (D * suw[:, :2]).sum(1)) / h - dDu * dDw / h3
            ua, wa = u[active], w[active]
            fix_u = ((ua <= 0.0) & (gu < 0)) | ((ua >= 1.0) & (gu > 0))
            fix_w = ((wa <= 0.0) & (gw < 0)) | ((wa >= 1.0) & (gw > 0))
            gu = np.where(fix_u, 0.0, gu)
            gw = np.where(fix_w, 0.0, gw)
            Huw = np.where(fix_u | fix_w, 0.0, Huw)
            Huu = np.where(fix_u, -1.0, Huu)
            Hww = np.where(fix_w, -1.0, Hww)
            det = Huu * Hww - Huw * Huw
            concave = (Huu < 0) & (det > 0)
            safe = np.where(concave, det, 1.0)
            du = np.where(concave, -(Hww * gu - Huw * gw) / safe, 0.0)
            dw = np.where(concave, -(Huu * gw - Huw * gu) / safe, 0.0)
            # Not concave here (a saddle or a valley of f): Newton along the concave principal
            # direction, the trust step uphill along the other (see _indefinite_step).
            bent = np.flatnonzero(~concave)
            if len(bent):
                du[bent], dw[bent] = _indefinite_step(
                    gu[bent], gw[bent], Huu[bent], Huw[bent], Hww[bent], trust)
            # Limit the step to the trust region (stay in the seed's basin).
            ratio = np.maximum(np.abs(du) / trust[0], np.abs(dw) / trust[1])
            shrink = np.where(ratio > 1.0, 1.0 / np.maximum(ratio, 1e-300), 1.0)
            du *= shrink
            dw *= shrink
            # Newton decrement: at a concave maximum the model's gain is the step's gain.
            model_gain = gu * du + gw * dw
            model_gain += 0.5 * (Huu * du * du + 2.0 * Huw * du * dw + Hww * dw * dw)
            go = ~(concave & (shrink == 1.0) & (model_gain < CONVERGED))
            if not go.all():
                # Converged: take the last Newton step without evaluating it, so the contact
                # (and the slope it gives) is exact too; the value may lag by < CONVERGED.
                done = active[~go]
                u[done], w[done] = _unit(ua[~go] + du[~go]), _unit(wa[~go] + dw[~go])
                active, ua, wa, du, dw, qa = (a[go] for a in (active, ua, wa, du, dw, qa))
                jet = [a[go] for a in jet]
                if len(active) == 0:
                    break
            f0 = fval[active]
            cu, cw = _unit(ua + du), _unit(wa + dw)
            trial = self._jets(cu, cw)
            fc = self._maximand(qa, trial[0])
            full = fc >= f0
            nu_, nw_ = np.where(full, cu, ua), np.where(full, cw, wa)
            fnew = np.where(full, fc, f0)
            # Backtracking for the rest, on points alone.
            halved = np.zeros(len(active), bool)
            todo = np.flatnonzero(~full)
            step = 0.5
            for _halving in range(7):
                if len(todo) == 0:
                    break
                hu, hw = _unit(ua[todo] + step * du[todo]), _unit(wa[todo] + step * dw[todo])
                fh = self._maximand(qa[todo], matrix.evaluate_patches(self.form, hu, hw))
                good = fh >= f0[todo]
                sel = todo[good]
                nu_[sel], nw_[sel], fnew[sel] = hu[good], hw[good], fh[good]
                halved[sel] = True
                todo = todo[~good]
                step *= 0.5
            moved = np.hypot((nu_ - ua) / self.param_step[0], (nw_ - wa) / self.param_step[1])
            u[active], w[active], fval[active] = nu_, nw_, fnew
            # Converged: no accepted step, or a step below 1e-9 of the sample spacing.
            still = (full | halved) & (moved > 1e-9) & (fnew - f0 > 1e-13)
            jet = [np.where(full[:, None], t, j) for t, j in zip(trial, jet)]
            if halved.any():
                for j, fresh in zip(jet, self._jets(nu_[halved], nw_[halved])):
                    j[halved] = fresh
            active = active[still]
            jet = [a[still] for a in jet]
        return fval, u, w

    def centre_heights(self, xy: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Ball-centre heights c(x, y) (mm; -inf where no surface within R) and contact (u, w).

        Each query is answered on its own, so a large call is split into consecutive parts
        answered on the shared pool (:mod:`.parallel`), up to ``threads.numpy_threads()`` at
        once (numpy releases the GIL in its loops): the same values as on one thread, bit for
        bit."""
        q = np.ascontiguousarray(np.asarray(xy, dtype=float).reshape(-1, 2))
        threads = max(1, min(numpy_threads(), len(q) // THREAD_QUERIES))
        if threads == 1:
            return self._centre_heights(q)
        chunks = np.array_split(q, threads)
        parts = parallel.run(lambda k: self._centre_heights(chunks[k]), threads)
        return tuple(np.concatenate(column) for column in zip(*parts))

    def _centre_heights(self, q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        if kernels.use_numba():
            try:
                return self._centre_heights_compiled(q)
            except kernels.KernelUnavailable:
                pass
        best, second, _ = self.seeds(q)
        m = len(q)
        two = np.concatenate([best, second])
        ok = two >= 0
        su = np.zeros(2 * m)
        sw = np.zeros(2 * m)
        gi, gj = np.divmod(two[ok], self.n_w)
        qq = np.concatenate([q, q])
        su[ok], sw[ok] = self._vertex_seed(qq[ok], gi, gj)
        z = np.full(2 * m, -np.inf)
        u = np.zeros(2 * m)
        w = np.zeros(2 * m)
        idx = np.flatnonzero(ok)
        z[idx], u[idx], w[idx] = self.refine(qq[idx], su[idx], sw[idx])
        pick = np.where(z[m:] > z[:m], np.arange(m) + m, np.arange(m))
        return z[pick], u[pick], w[pick]

    def _centre_heights_compiled(self, q: FloatArray) -> tuple[FloatArray, FloatArray,
                                                                FloatArray]:
        """:meth:`_centre_heights` by the numba engine
        (:func:`~BSplineCAM.core.kernels.net_drop_kernels.centre_heights`)."""
        args = self.kernel_arguments(q)
        net_drop_kernels.centre_heights(*args)
        return args[-3:]

    def kernel_arguments(self, q: FloatArray) -> tuple:
        """The arguments of :func:`~BSplineCAM.core.kernels.net_drop_kernels.centre_heights`
        for the queries ``q`` (m, 2), ending with the three outputs (z, u, w) it fills."""
        m = len(q)
        p_u, p_w = self.form.spans
        return (np.ascontiguousarray(q, dtype=float), self.sx, self.sy, self.sz, self._si64,
                self._sj64, self._starts64, self.samples, self.u, self.w, float(self.lo[0]),
                float(self.lo[1]), float(self.cell), self.ncx, self.ncy, self.n_u, self.n_w,
                self._window, self.radius, float(self.margin), NEIGHBOURHOOD, self.form.coef,
                p_u, p_w, REFINE_ITERATIONS, CONVERGED, np.empty(m), np.empty(m), np.empty(m))

    def heights(self, xy: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Tool-tip heights c(x, y) - R (mm; NaN where the ball meets no surface) and contacts."""
        c, u, w = self.centre_heights(xy)
        tip = c - self.radius
        tip[~np.isfinite(tip)] = np.nan
        return tip, u, w

    def slopes(self, xy: FloatArray, u: FloatArray, w: FloatArray) -> FloatArray:
        """Gradient (dz/dx, dz/dy) of the tip height at ``xy`` from its contacts (u, w).

        By the envelope theorem the derivative of max_p f(p, q) is that of f at the maximiser:
        grad c = (p_xy - q) / sqrt(R^2 - |p_xy - q|^2) with p the contact point.  Exact where
        the contact is unique; at a crease (two contacts) it is one of the one-sided values.
        """
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        u, w = np.asarray(u, dtype=float), np.asarray(w, dtype=float)
        if kernels.use_numba() and len(u) == len(q) == len(w) and _in_unit(u) and _in_unit(w):
            try:
                out = np.empty((len(q), 2))
                net_drop_kernels.slopes(np.ascontiguousarray(q), np.ascontiguousarray(u),
                                        np.ascontiguousarray(w), self.form.coef,
                                        *self.form.spans, self.radius, out)
                return out
            except kernels.KernelUnavailable:
                pass
        d = self.points(u, w)[:, :2] - q
        h = np.sqrt(np.maximum(self.radius ** 2 - np.einsum("ij,ij->i", d, d), 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            return d / h[:, None]

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Tip heights (mm; NaN off the surface) and their gradients (NaN there too)."""
        tip, u, w = self.heights(xy)
        grad = self.slopes(xy, u, w)
        grad[~np.isfinite(tip)] = np.nan
        return tip, grad


def _indefinite_step(gu: FloatArray, gw: FloatArray, Huu: FloatArray, Huw: FloatArray,
                     Hww: FloatArray, trust: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Ascent step (du, dw) of f where its Hessian is not negative definite.

    In coordinates scaled by the trust step, the Hessian's principal directions split the step:
    along a direction of negative curvature the Newton step (the model's maximum there), along
    one of zero or positive curvature a full trust step uphill (the model rises without bound;
    from a stationary saddle, either way).  Steepest ascent (used here before) is badly scaled
    where f is much more curved across the contact than along it (the ball nearly fitting a
    hollow or a valley): its trust-sized step overshoots across the contact, backtracking runs
    out, and the search stops on the flank, short of the maximum (Nocedal & Wright, 3.4, 4.3).
    """
    tu, tw = trust
    a, b, c = Huu * tu * tu, Huw * tu * tw, Hww * tw * tw
    ga, gb = gu * tu, gw * tw
    half = 0.5 * (a - c)
    radius = np.hypot(half, b)
    mean = 0.5 * (a + c)
    theta = 0.5 * np.arctan2(b, half)
    cos, sin = np.cos(theta), np.sin(theta)
    step_a = np.zeros_like(ga)
    step_b = np.zeros_like(gb)
    # (cos, sin) belongs to the larger eigenvalue, (-sin, cos) to the smaller.
    for lam, va, vb in ((mean + radius, cos, sin), (mean - radius, -sin, cos)):
        g = ga * va + gb * vb
        curved = lam < 0.0
        t = np.where(curved, np.clip(-g / np.where(curved, lam, -1.0), -1.0, 1.0),
                     np.where(g < 0.0, -1.0, 1.0))
        step_a += t * va
        step_b += t * vb
    return step_a * tu, step_b * tw


def _in_unit(t: np.ndarray) -> bool:
    """Whether every parameter lies in [0, 1] (the compiled slopes take no others: the numpy
    path refuses them)."""
    return t.ndim == 1 and (t.size == 0 or (float(t.min()) >= 0.0 and float(t.max()) <= 1.0))


def _unit(t: FloatArray) -> FloatArray:
    """t clamped to [0, 1] (a new array; cheaper than np.clip on small arrays)."""
    return np.minimum(np.maximum(t, 0.0), 1.0)


def brute_force_heights(surface: Any, radius: float, xy: FloatArray, samples: int = 801,
                        zoom: int = 41) -> FloatArray:
    """Reference tip heights by brute force (slow; for tests): the best of a dense uniform
    parameter sample, then of a ``zoom`` x ``zoom`` sample around each of the best few."""
    u = np.linspace(0.0, 1.0, samples)
    pts = np.asarray(surface.evaluate_grid(u, u)).reshape(-1, 3)
    out = np.empty(len(xy))
    R2 = radius * radius
    step = 1.0 / (samples - 1)
    for k, q in enumerate(np.asarray(xy, dtype=float)):
        d2 = ((pts[:, :2] - q) ** 2).sum(axis=1)
        f = np.where(d2 <= R2, pts[:, 2] + np.sqrt(np.maximum(R2 - d2, 0.0)), -np.inf)
        if not np.isfinite(f.max()):
            out[k] = np.nan
            continue
        best = f.max()
        for g in np.argsort(f)[-3:]:
            i, j = divmod(int(g), samples)
            lu = np.clip(np.linspace(u[i] - 2 * step, u[i] + 2 * step, zoom), 0.0, 1.0)
            lw = np.clip(np.linspace(u[j] - 2 * step, u[j] + 2 * step, zoom), 0.0, 1.0)
            local = np.asarray(surface.evaluate_grid(lu, lw)).reshape(-1, 3)
            dl = ((local[:, :2] - q) ** 2).sum(axis=1)
            ok = dl <= R2
            if ok.any():
                best = max(best, float((local[ok, 2] + np.sqrt(R2 - dl[ok])).max()))
        out[k] = best - radius
    return out
