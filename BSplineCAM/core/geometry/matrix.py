# SPDX-License-Identifier: LGPL-2.1-or-later
"""The paper's matrix evaluator: P(u, w) = [U][MB][P][MB]^T[W] (appendix A, eq. A.2).

Each patch is written in the power basis [s^3, s^2, s, 1] of its local parameter s in [0, 1].
For the paper's uniform knots every patch uses the same matrix MB; for clamped (open uniform)
knots the patches near the ends have their own 4x4 matrices, found here by expanding the
Cox–de Boor basis of each span in the power basis.  Derivatives come from differentiating [U].

Scattered points use the same matrix form pre-multiplied per patch, A_ij = M_i P_ij M_j^T
(:func:`patch_form`), grouped by patch.  Evaluation never loops over points.  A grid is evaluated as two matrix products over whole
rows of patches: the sparse u-basis rows (4 non-zeros each, from [U][MB]) meet the net, then
one BLAS product with the w-basis gives all three coordinate planes at once.  Grid normals
(:func:`grid_unit_normals`) evaluate the normal Su x Sw of each patch, one Bernstein polynomial
of degree (5, 5) built once per net (:func:`normal_form`), by the same two stages.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import lru_cache
from itertools import count
from math import comb

import numpy as np

from ..threads import numpy_threads
from ..typing import ArrayLike, FloatArray, IntArray
from .basis import DEGREE, KnotLayout, cox_de_boor, knot_vector

#: The paper's uniform cubic B-spline basis matrix, appendix A (A.2).
MB: FloatArray = np.array(
    [[-1.0, 3.0, -3.0, 1.0], [3.0, -6.0, 3.0, 0.0], [-3.0, 0.0, 3.0, 0.0], [1.0, 4.0, 1.0, 0.0]]
) / 6.0
MB.setflags(write=False)

#: Chunk of scattered points evaluated at once: bounds the (m, 4, 12) gather temporary.
SCATTER_CHUNK = 1 << 15


def span_matrices(count: int, layout: str | KnotLayout) -> FloatArray:
    """Per-patch basis matrices, shape (count - 3, 4, 4), rows indexed like MB's.

    Row k of a matrix holds the power-basis coefficients of s^(3-k); column l the weight of
    control point j + l.  For the uniform layout every matrix equals MB exactly (the paper's
    derivation); for the clamped layout each span's Cox–de Boor cubics are expanded in the
    power basis by solving a 4x4 Vandermonde system at four interior sample points.
    """
    layout = KnotLayout.parse(layout)
    spans = count - DEGREE
    if layout is KnotLayout.UNIFORM:
        return np.broadcast_to(MB, (spans, 4, 4)).copy()
    return _clamped_span_matrices(count).copy()


@lru_cache(maxsize=64)
def _clamped_span_matrices(count: int) -> FloatArray:
    knots = knot_vector(count, KnotLayout.CLAMPED)
    spans = count - DEGREE
    samples = np.array([0.125, 0.375, 0.625, 0.875])
    vandermonde = np.vander(samples, 4)  # rows [s^3, s^2, s, 1]
    out = np.empty((spans, 4, 4))
    for j in range(spans):
        u = (j + samples) / spans
        values = cox_de_boor(knots, DEGREE, u)[:, j : j + 4]
        out[j] = np.linalg.solve(vandermonde, values)
    out.setflags(write=False)
    return out


def locate(t: ArrayLike, count: int) -> tuple[IntArray, FloatArray]:
    """Patch index and local parameter s in [0, 1] for normalised parameters t in [0, 1]."""
    spans = count - DEGREE
    scaled = np.asarray(t, dtype=float) * spans
    index = np.clip(np.floor(scaled).astype(np.intp), 0, spans - 1)
    return index, scaled - index


def power_rows(s: FloatArray, derivative: int, spans: int) -> FloatArray:
    """[U] = [s^3, s^2, s, 1] or its derivative with respect to the normalised parameter.

    d/dt = spans * d/ds, because t = (j + s) / spans.
    """
    s = np.asarray(s, dtype=float)
    one = np.ones_like(s)
    zero = np.zeros_like(s)
    if derivative == 0:
        rows = (s * s * s, s * s, s, one)
    elif derivative == 1:
        rows = (3.0 * s * s, 2.0 * s, one, zero)
    elif derivative == 2:
        rows = (6.0 * s, 2.0 * one, zero, zero)
    elif derivative == 3:
        rows = (6.0 * one, zero, zero, zero)
    else:
        rows = (zero, zero, zero, zero)
    return np.stack(rows, axis=-1) * float(spans) ** derivative


def local_weights(
    t: ArrayLike, count: int, layout: str | KnotLayout, derivative: int = 0
) -> tuple[IntArray, FloatArray]:
    """[U][M_j] for each parameter: first control index j and the 4 weights, shape (m, 4)."""
    index, s = locate(np.atleast_1d(t), count)
    matrices = span_matrices_cached(count, KnotLayout.parse(layout))
    rows = power_rows(s, derivative, count - DEGREE)
    if KnotLayout.parse(layout) is KnotLayout.UNIFORM:
        return index, rows @ MB
    return index, np.einsum("mk,mkl->ml", rows, matrices[index])


@lru_cache(maxsize=64)
def span_matrices_cached(count: int, layout: KnotLayout) -> FloatArray:
    mats = span_matrices(count, layout)
    mats.setflags(write=False)
    return mats


def basis_rows(
    t: ArrayLike, count: int, layout: str | KnotLayout, derivative: int = 0
) -> FloatArray:
    """Dense basis matrix (m, count) whose row holds [U][M_j] at columns j .. j+3."""
    index, weights = local_weights(t, count, layout, derivative)
    dense = np.zeros((len(index), count))
    rows = np.arange(len(index))[:, None]
    dense[rows, index[:, None] + np.arange(4)] = weights
    return dense


def _contract_rows(index: IntArray, weights: FloatArray, net: FloatArray) -> FloatArray:
    """Sum_k weights[a, k] * net[index[a] + k]: the u-basis applied row block by row block."""
    expand = (slice(None),) + (None,) * (net.ndim - 1)
    out = weights[:, 0][expand] * net[index]
    for k in range(1, 4):
        out += weights[:, k][expand] * net[index + k]
    return out


#: Threads that share the products of a large grid (:func:`grid_planes`,
#: :func:`grid_unit_normals`; numpy and BLAS release the GIL), and the grid points per thread
#: below which one thread does it all.  None: :func:`..threads.numpy_threads`, at most 2.
GRID_THREADS: int | None = None
GRID_THREAD_POINTS = 1 << 17

#: Multiply-adds of one BLAS product below which OpenBLAS computes it in the calling thread
#: (65536 x 4: its interface/gemm.c).  Our grid products stay below it and our threads share
#: them: a product OpenBLAS threads itself leaves its workers spinning for a while after it
#: returns, and they then take the cores from the next threaded stage (measured: the normals
#: took 9.6 ms instead of 5.6 ms right after BLAS-threaded points).
BLAS_ONE_THREAD_MACS = 65536 * 4


def _grid_threads(points: int, blocks: int) -> int:
    """Threads for a grid of ``points`` cut into ``blocks`` blocks."""
    cap = min(2, numpy_threads()) if GRID_THREADS is None else GRID_THREADS
    return max(1, min(cap, points // GRID_THREAD_POINTS, blocks))


def _shared_stages(stages: Sequence, threads: int) -> None:
    """Run each stage in ``threads`` threads at once, one stage after the other.

    A stage takes its blocks from a shared counter (``next()`` on an ``itertools.count`` holds
    the GIL), so a thread the machine holds back takes fewer."""
    if threads <= 1:
        for stage in stages:
            stage()
        return
    with ThreadPoolExecutor(threads - 1) as pool:
        for stage in stages:
            others = [pool.submit(stage) for _ in range(1, threads)]
            stage()
            for other in others:
                other.result()


def _blocks(order: Iterator[int], total: int) -> Iterator[int]:
    """Block numbers from the shared counter ``order`` until ``total`` are handed out."""
    for k in order:
        if k >= total:
            return
        yield k


def _stage1(net: FloatArray, layout: str | KnotLayout, u: FloatArray, du: int) -> FloatArray:
    """[U][M_i] applied along u: shape (n_w, 3·len(u)), coordinate-major within a row."""
    iu, wu = local_weights(u, net.shape[0], layout, du)
    stage1 = _contract_rows(iu, wu, net)  # (len(u), n_w, 3)
    return np.ascontiguousarray(stage1.transpose(1, 2, 0)).reshape(net.shape[1], 3 * len(u))


def grid_planes(
    net: FloatArray,
    layout: str | KnotLayout,
    u: ArrayLike,
    w: ArrayLike,
    du: int = 0,
    dw: int = 0,
) -> FloatArray:
    """The grid u x w as coordinate planes laid out (len(w), 3, len(u)), C-contiguous.

    Stage 1 applies [U][M_i] along u: four net rows per sample, giving a (n_w, 3·len(u)) block.
    Stage 2 applies ([W][M_j])^T patch column by patch column: the samples of w-span j need only
    net columns j..j+3, so each span is one small BLAS product writing a contiguous block of
    output rows.  That is a quarter of the work of a dense product and no temporary as large
    as the result.  The products are cut into blocks of rows below ``BLAS_ONE_THREAD_MACS``,
    shared among ``GRID_THREADS`` threads on large grids.
    """
    net = np.asarray(net, dtype=float)
    n_w = net.shape[1]
    u = np.atleast_1d(np.asarray(u, dtype=float))
    w = np.atleast_1d(np.asarray(w, dtype=float))
    stage1 = _stage1(net, layout, u, du)
    iw, ww = local_weights(w, n_w, layout, dw)
    out = np.empty((len(w), 3 * len(u)))
    if len(w) > 1 and np.any(np.diff(iw) < 0):  # unsorted w: one dense product
        np.matmul(basis_rows(w, n_w, layout, dw), stage1, out=out)
    else:
        runs = _runs(iw, max(1, BLAS_ONE_THREAD_MACS // (4 * stage1.shape[1] + 1)))
        order = count()

        def products() -> None:
            for k in _blocks(order, len(runs)):
                lo, hi, j = runs[k]
                np.matmul(ww[lo:hi], stage1[j : j + 4], out=out[lo:hi])

        _shared_stages([products], _grid_threads(out.size // 3, len(runs)))
    return out.reshape(len(w), 3, len(u))


def evaluate_grid(
    net: FloatArray,
    layout: str | KnotLayout,
    u: ArrayLike,
    w: ArrayLike,
    du: int = 0,
    dw: int = 0,
) -> FloatArray:
    """Points (or partial derivatives) on the tensor grid u x w: shape (len(u), len(w), 3).

    Returned as a transposed view of :func:`grid_planes`, so no (nu, nw, 3) copy is made.
    """
    return grid_planes(net, layout, u, w, du, dw).transpose(2, 0, 1)


#: Normals shorter than this fraction of the grid's longest count as degenerate (replaced by
#: the caller from a nearby interior parameter).  Where an edge of the net collapses to a
#: point, rounding leaves normals about 1e-14 of the longest there, pointing anywhere (even
#: downwards); legitimate ones that short lie within about 1e-11 of the edge in parameter,
#: where the nudged normal is the same to that order.
DEGENERATE_NORMAL = 1e-11

#: Rows of w per block in :func:`grid_normals`: small enough that a block's tangents stay in cache.
NORMAL_BLOCK_ROWS = 16


def grid_normals(
    net: FloatArray, layout: str | KnotLayout, u: ArrayLike, w: ArrayLike
) -> tuple[FloatArray, np.ndarray]:
    """Unit normals Su x Sw / |Su x Sw| on the grid, and the mask of degenerate ones.

    Tangents are made and crossed a few w-rows at a time, so they never leave the cache and
    the only large array written is the result.  Degenerate normals (zero cross product) are
    left as zero for the caller to replace.
    """
    net = np.asarray(net, dtype=float)
    n_w = net.shape[1]
    u = np.atleast_1d(np.asarray(u, dtype=float))
    w = np.atleast_1d(np.asarray(w, dtype=float))
    nu = len(u)
    stage_du = _stage1(net, layout, u, 1)
    stage_0 = _stage1(net, layout, u, 0)
    iw, w0 = local_weights(w, n_w, layout, 0)
    _, w1 = local_weights(w, n_w, layout, 1)
    out = np.empty((len(w), 3, nu))
    length = np.empty((len(w), nu))
    start = 0
    while start < len(w):
        j = iw[start]
        stop = start + 1
        while stop < len(w) and stop - start < NORMAL_BLOCK_ROWS and iw[stop] == j:
            stop += 1
        su = (w0[start:stop] @ stage_du[j : j + 4]).reshape(-1, 3, nu)
        sw = (w1[start:stop] @ stage_0[j : j + 4]).reshape(-1, 3, nu)
        block = out[start:stop]
        for c, (a, b) in enumerate(((1, 2), (2, 0), (0, 1))):
            np.multiply(su[:, a], sw[:, b], out=block[:, c])
            block[:, c] -= su[:, b] * sw[:, a]
        lengths = np.sqrt(np.einsum("mcn,mcn->mn", block, block))
        length[start:stop] = lengths
        lengths[lengths == 0] = np.inf
        block /= lengths[:, None, :]
        start = stop
    degenerate = length <= DEGENERATE_NORMAL * max(1.0, float(length.max(initial=0.0)))
    out.transpose(0, 2, 1)[degenerate] = 0.0
    return out.transpose(2, 0, 1), degenerate.T


@dataclass(frozen=True)
class PatchCoefficients:
    """Power-basis coefficients of every patch: A_ij = M_i P_ij M_j^T (appendix A, eq. A.2).

    ``coef[i * spans_w + j]`` is patch (i, j) as a (4, 12) matrix: row b holds the t^(3-b) term
    (t along w), column 3a + c coordinate c of the s^(3-a) term (s along u), so a point of the
    patch is sum_a [U]_a ([W] @ coef)[3a + c].  Built once per net; read-only.
    """

    coef: FloatArray
    counts: tuple[int, int]

    @property
    def spans(self) -> tuple[int, int]:
        """Patches along u and along w."""
        return self.counts[0] - DEGREE, self.counts[1] - DEGREE


def patch_form(net: FloatArray, layout: str | KnotLayout) -> PatchCoefficients:
    """Pre-multiply each 4x4 block of the net by its span matrices: [M_i][P_ij][M_j]^T."""
    net = np.asarray(net, dtype=float)
    n_u, n_w = net.shape[:2]
    layout = KnotLayout.parse(layout)
    mu = span_matrices_cached(n_u, layout)  # (pu, 4 = a, 4 = k)
    mw = span_matrices_cached(n_w, layout)  # (pw, 4 = b, 4 = l)
    blocks = np.lib.stride_tricks.sliding_window_view(net, (4, 4), axis=(0, 1))  # (pu,pw,3,k,l)
    coef = np.einsum("iak,ijckl,jbl->ijbac", mu, blocks, mw, optimize=True)
    coef = np.ascontiguousarray(coef.reshape((n_u - DEGREE) * (n_w - DEGREE), 4, 12))
    coef.setflags(write=False)
    return PatchCoefficients(coef, (n_u, n_w))


def evaluate_patches(
    form: PatchCoefficients, u: ArrayLike, w: ArrayLike, du: int = 0, dw: int = 0
) -> FloatArray:
    """Points (or the (du, dw) partial derivative) at scattered (u, w): broadcast shape + (3,)."""
    return evaluate_patch_orders(form, u, w, ((du, dw),))[0]


def evaluate_patch_orders(
    form: PatchCoefficients, u: ArrayLike, w: ArrayLike, orders: Sequence[tuple[int, int]]
) -> list[FloatArray]:
    """Several partial derivatives (du, dw) at the same scattered parameters, in one pass.

    Each point gathers its patch's coefficients; per w-order a 4-term sum with [W] gives the
    12 u-power planes, then each u-order is a 4-term sum with [U].  No loop runs over points
    or patches; work is done in chunks of ``SCATTER_CHUNK`` points, element by element, so the
    result does not depend on the chunking.  Returns arrays of shape broadcast(u, w) + (3,).
    """
    u, w = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(w, dtype=float))
    shape = u.shape
    u, w = u.ravel(), w.ravel()
    outs = [np.empty((len(u), 3)) for _ in orders]
    for start in range(0, len(u), SCATTER_CHUNK):
        sl = slice(start, start + SCATTER_CHUNK)
        for out, value in zip(outs, _patch_chunk(form, u[sl], w[sl], orders)):
            out[sl] = value
    return [out.reshape(shape + (3,)) for out in outs]


def _patch_chunk(form: PatchCoefficients, u: FloatArray, w: FloatArray,
                 orders: Sequence[tuple[int, int]]) -> list[FloatArray]:
    n_u, n_w = form.counts
    p_u, p_w = form.spans
    iu, su = locate(u, n_u)
    iw, sw = locate(w, n_w)
    coef = form.coef[iu * p_w + iw]  # (m, 4 = b, 12 = (a, c)): each point's own patch
    planes = {q: np.einsum("mb,mbk->mk", power_rows(sw, q, p_w), coef).reshape(-1, 4, 3)
              for q in sorted({q for _, q in orders})}  # (m, 4 = a, 3 = c)
    return [np.einsum("ma,mac->mc", power_rows(su, p, p_u), planes[q]) for p, q in orders]


def evaluate_points(
    net: FloatArray,
    layout: str | KnotLayout,
    u: ArrayLike,
    w: ArrayLike,
    du: int = 0,
    dw: int = 0,
) -> FloatArray:
    """Points (or partial derivatives) at scattered parameter pairs: shape broadcast(u, w) + (3,).

    Per point [U] · A_ij · [W]^T with the patch's power-basis coefficients
    (:func:`patch_form`); a :class:`~BSplineCAM.core.geometry.surface.Surface` caches those, so prefer
    its ``evaluate`` when evaluating one net repeatedly.
    """
    return evaluate_patches(patch_form(net, layout), u, w, du, dw)


def evaluate_curve(
    points: FloatArray, layout: str | KnotLayout, t: ArrayLike, derivative: int = 0
) -> FloatArray:
    """A cubic B-spline curve P(t) = [T][MB][P] for control points of shape (n, dim)."""
    points = np.asarray(points, dtype=float)
    t = np.atleast_1d(np.asarray(t, dtype=float))
    index, weights = local_weights(t, len(points), layout, derivative)
    return _contract_rows(index, weights, points)


# -- normals as one polynomial per patch ------------------------------------------------------
#: Grid points per block of w-rows in :func:`grid_unit_normals`: a block's coordinate planes
#: stay in cache between the product that makes them and their normalisation, each numpy call
#: works on enough points that its fixed cost does not show, and each product (6 multiply-adds
#: per point and coordinate: 196608) stays below ``BLAS_ONE_THREAD_MACS``.
NORMAL_BLOCK_POINTS = 1 << 15

#: Normals shorter than this fraction of the grid's longest are recomputed from the tangents
#: (:func:`grid_unit_normals`): there the product polynomial's rounding, relative to its
#: length, could exceed 1e-13.
NORMAL_GUARD = 1e-3


@dataclass(frozen=True)
class NormalCoefficients:
    """Bezier (Bernstein) coefficients of the unnormalised normal Su x Sw of every patch.

    Su is of degree (2, 3) and Sw of degree (3, 2) in the local (s, t) of a patch, so their
    cross product is one polynomial of degree (5, 5): ``coef[i, k, j * 18 + 6 c + l]`` is
    coordinate c of the B5_k(s) B5_l(t) term of patch (i, j), the layout stage 1 of
    :func:`grid_unit_normals` multiplies by [B5_0(s) ... B5_5(s)] (each coordinate's six
    t-coefficients together, so that stage 2 gives coordinate planes).  Derivatives are with
    respect to the normalised parameters (mm per unit), as :func:`evaluate_grid` gives them.
    """

    coef: FloatArray
    counts: tuple[int, int]
    #: Per patch (spans_u, spans_w): a lower bound of |Su x Sw| over the patch (the least
    #: projection of its coefficients on their mean direction, since the normal is a convex
    #: combination of them; zero where that proves nothing) and an upper bound (the longest
    #: coefficient).  NaN where a coefficient is not finite.
    least: FloatArray
    greatest: FloatArray
    #: Per patch (spans_u, spans_w): a lower bound of |Su x Sw| over the patch (the least
    #: projection of its coefficients on their mean direction, since the normal is a convex
    #: combination of them; zero where that proves nothing) and an upper bound (the longest
    #: coefficient).  NaN where a coefficient is not finite.
    least: FloatArray
    greatest: FloatArray

    @property
    def spans(self) -> tuple[int, int]:
        return self.counts[0] - DEGREE, self.counts[1] - DEGREE


def _power_to_bezier(degree: int) -> FloatArray:
    """B with b = B @ a: Bezier coefficients of sum_r a_r s^r on [0, 1]
    (b_i = sum_{r<=i} C(i, r) / C(p, r) a_r; "The NURBS Book" sec. 6.6)."""
    return np.array([[comb(i, r) / comb(degree, r) if r <= i else 0.0
                      for r in range(degree + 1)] for i in range(degree + 1)])


def normal_form(form: PatchCoefficients) -> NormalCoefficients:
    """Su x Sw patch by patch in Bernstein form ("The NURBS Book" sec. 1.4, 3.3 and 6.6).

    The patch's Bezier points Q come from its power-basis coefficients A_ij; Su has the Bezier
    coefficients 3 spans_u (Q[a+1, b] - Q[a, b]) and Sw 3 spans_w (Q[a, b+1] - Q[a, b]); the
    product of Bernstein polynomials of degrees m and n has the coefficient
    C(m, i1) C(n, i2) / C(m+n, i1+i2) on B_(i1+i2).  All weights are positive, so the form is
    as well conditioned as the tangents themselves.
    """
    pu, pw = form.spans
    # coef rows: t^(3-b); columns (a, c): s^(3-a)  ->  ascending a[i, j, p, q, c] for s^p t^q
    a = form.coef.reshape(pu, pw, 4, 4, 3)[:, :, ::-1, ::-1, :].transpose(0, 1, 3, 2, 4)
    to_bezier = _power_to_bezier(DEGREE)
    q = np.einsum("kp,ijpqc,lq->ijklc", to_bezier, a, to_bezier)
    su = 3.0 * pu * (q[:, :, 1:] - q[:, :, :-1])  # (pu, pw, 3, 4, 3): degree (2, 3)
    sw = 3.0 * pw * (q[:, :, :, 1:] - q[:, :, :, :-1])  # (pu, pw, 4, 3, 3): degree (3, 2)
    out = np.zeros((pu, pw, 6, 6, 3))
    ws = np.array([[comb(2, i1) * comb(3, i2) for i2 in range(4)] for i1 in range(3)])
    wt = np.array([[comb(3, j1) * comb(2, j2) for j2 in range(3)] for j1 in range(4)])
    for i1 in range(3):
        for j1 in range(4):
            weight = ws[i1][:, None, None] * wt[j1][None, :, None]  # (4, 3, 1)
            out[:, :, i1 : i1 + 4, j1 : j1 + 3] += weight * np.cross(
                su[:, :, None, None, i1, j1], sw)
    five = np.array([comb(5, k) for k in range(6)], dtype=float)
    out /= five[:, None, None] * five[None, :, None]
    points = out.reshape(pu, pw, 36, 3)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        mean = points.sum(axis=2)
        mean /= np.linalg.norm(mean, axis=-1, keepdims=True)
        least = np.einsum("ijkc,ijc->ijk", points, mean).min(axis=2)
        greatest = np.linalg.norm(points, axis=-1).max(axis=2)
    finite = np.isfinite(points).all(axis=(2, 3))
    least = np.where(finite, np.where(least > 0, least, 0.0), np.nan)  # zero mean: nothing
    greatest = np.where(finite, greatest, np.nan)
    for bound in (least, greatest):
        bound.setflags(write=False)
    # (i, j, k, l, c) -> (i, k, j, c, l)
    coef = np.ascontiguousarray(out.transpose(0, 2, 1, 4, 3)).reshape(pu, 6, pw * 18)
    coef.setflags(write=False)
    return NormalCoefficients(coef, form.counts, least, greatest)


def _bernstein_rows(s: FloatArray, degree: int) -> FloatArray:
    """[B_0(s) ... B_degree(s)], B_k = C(degree, k) s^k (1 - s)^(degree - k): (m, degree + 1)."""
    up = np.empty((len(s), degree + 1))
    down = np.empty((len(s), degree + 1))
    up[:, 0] = down[:, degree] = 1.0
    r = 1.0 - s
    for k in range(1, degree + 1):
        np.multiply(up[:, k - 1], s, out=up[:, k])
        np.multiply(down[:, degree - k + 1], r, out=down[:, degree - k])
    up *= down
    up *= np.array([comb(degree, k) for k in range(degree + 1)], dtype=float)
    return up


def _runs(index: IntArray, limit: int) -> list[tuple[int, int, int]]:
    """(lo, hi, value) of runs of equal consecutive values, at most ``limit`` long."""
    cuts = np.flatnonzero(np.diff(index)) + 1
    bounds = np.concatenate(([0], cuts, [len(index)]))
    runs = []
    for lo, hi in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        runs.extend((k, min(k + limit, hi), int(index[lo])) for k in range(lo, hi, limit))
    return runs


def _square_lengths(block: FloatArray, out: FloatArray) -> FloatArray:
    """x^2 + y^2 + z^2 of the coordinate planes ``block`` (3, m, n), written to ``out``."""
    return np.einsum("cij,cij->ij", block, block, out=out)


def _normalised_blocks(runs: list[tuple[int, int, int]], basis_w: FloatArray,
                       stage1: FloatArray, out: FloatArray, order: Iterator[int]) -> None:
    """Stage 2 of :func:`grid_unit_normals` for the blocks of w-rows whose numbers ``order``
    (shared among threads) hands out: each block's three coordinate planes are made by BLAS
    in ``out`` (3, len(w), len(u)) and normalised there while in cache, one 1/sqrt per point
    multiplied into the planes: five numpy calls per block."""
    nu = out.shape[2]
    rows = max((hi - lo for lo, hi, _ in runs), default=0)
    square = np.empty((rows, nu))
    with np.errstate(divide="ignore", invalid="ignore"):  # per thread: zeros are redone
        for k in order:
            lo, hi, j = runs[k]
            block = out[:, lo:hi]
            q = square[: hi - lo]
            np.matmul(basis_w[lo:hi], stage1[j], out=block)
            _square_lengths(block, q)
            np.sqrt(q, out=q)
            np.divide(1.0, q, out=q)
            block *= q


def grid_unit_normals(
    form: PatchCoefficients, nform: NormalCoefficients, u: ArrayLike, w: ArrayLike
) -> tuple[FloatArray, np.ndarray]:
    """Unit normals Su x Sw / |Su x Sw| on the grid u x w, and the mask of degenerate ones.

    The normal polynomial of each patch (:func:`normal_form`) is evaluated like points are by
    :func:`grid_planes`: stage 1 applies the quintic Bernstein rows [B_0(s) ... B_5(s)] along
    u, stage 2 BLAS products with [B_0(t) ... B_5(t)] per block of a few w-rows, written as
    coordinate planes (3, len(w), len(u)) and normalised while in cache (on large grids each
    stage is shared among ``GRID_THREADS`` threads).  No tangent is formed and no cross
    product taken per point: the work per point is 18 multiply-adds (the points' 12), 5 flops
    for the squared length, one square root, one division and 3 multiplies.  The planes
    layout keeps every elementwise step on contiguous memory.
    Normals shorter than ``NORMAL_GUARD`` of the longest (near a collapsed edge, where the
    product's rounding could show) are recomputed from Su and Sw
    (:func:`evaluate_patch_orders`), so the result agrees with :func:`grid_normals` within
    1e-12; only the blocks of w-rows whose patches' coefficients allow such a normal
    (:class:`NormalCoefficients` bounds) are searched for them.  Shapes:
    (len(u), len(w), 3), a view of the planes, and (len(u), len(w)); degenerate normals are
    zero.
    """
    u = np.atleast_1d(np.asarray(u, dtype=float))
    w = np.atleast_1d(np.asarray(w, dtype=float))
    nu, nw = len(u), len(w)
    n_u, n_w = nform.counts
    iu, su = locate(u, n_u)
    iw, sw = locate(w, n_w)
    basis_u = _bernstein_rows(su, 5)
    basis_w = _bernstein_rows(sw, 5)
    stage1 = np.empty((nform.coef.shape[2], nu))  # rows (w-span j, coordinate c, index l)
    out = np.empty((3, nw, nu))
    runs = _runs(iw, max(1, NORMAL_BLOCK_POINTS // max(nu, 1)))
    threads = _grid_threads(nw * nu, len(runs))
    runs_u = _runs(iu, max(1, -(-nu // (4 * threads))))
    order_u, order_w = count(), count()

    def first() -> None:  # stage 1 of bands of u
        for k in _blocks(order_u, len(runs_u)):
            lo, hi, i = runs_u[k]
            np.matmul(nform.coef[i].T, basis_u[lo:hi].T, out=stage1[:, lo:hi])

    def second() -> None:  # stage 2 of blocks of w-rows
        _normalised_blocks(runs, basis_w, stage1.reshape(-1, 3, 6, nu), out,
                           _blocks(order_w, len(runs)))

    _shared_stages([first, second], threads)
    stage1 = stage1.reshape(-1, 3, 6, nu)
    normals = out.transpose(2, 1, 0)
    degenerate = np.zeros((nu, nw), dtype=bool)
    # the patches the grid touches bound its normals' lengths from their coefficients
    spans_u = np.unique(iu)
    least = nform.least[spans_u].min(axis=0, initial=np.inf)  # per w-span
    longest = float(nform.greatest[spans_u][:, np.unique(iw)].max(initial=0.0))
    # every normal that may be degenerate (DEGENERATE_NORMAL of the longest) is a suspect too
    limit = max(NORMAL_GUARD * longest, DEGENERATE_NORMAL * max(1.0, longest))
    suspect_runs = [k for k, (_, _, j) in enumerate(runs) if not least[j] > limit]
    if not suspect_runs:  # no short, zero or non-finite normal is possible
        return normals, degenerate
    picks_u, picks_w = [], []
    for k in suspect_runs:  # the block's lengths again, to find its suspects
        lo, hi, j = runs[k]
        block = np.matmul(basis_w[lo:hi], stage1[j])
        q = _square_lengths(block, np.empty((hi - lo, nu)))
        rows, cols = np.nonzero(~(q > limit * limit))
        picks_w.append(rows + lo)
        picks_u.append(cols)
    if not any(len(pick) for pick in picks_u):
        return normals, degenerate
    suspect_u, suspect_w = np.concatenate(picks_u), np.concatenate(picks_w)
    tu, tw = evaluate_patch_orders(form, u[suspect_u], w[suspect_w], ((1, 0), (0, 1)))
    exact = np.cross(tu, tw)
    exact_length = np.sqrt(np.einsum("mc,mc->m", exact, exact))
    exact /= np.where(exact_length > 0, exact_length, 1.0)[:, None]
    zero = exact_length <= DEGENERATE_NORMAL * max(1.0, longest)
    exact[zero] = 0.0
    normals[suspect_u, suspect_w] = exact
    degenerate[suspect_u, suspect_w] = zero
    return normals, degenerate
