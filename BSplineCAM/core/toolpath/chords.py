# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided chords: straight moves between cutter locations that never dip below the exact
cutter-location (CL) height.

On a convex stretch the chord between two points of the CL curve lies below the curve, so a
straight move would let the ball cut into the part by up to the sag.  Each chord is checked
against the exact drop-cutter: along it the CL height z is known exactly at samples, with its
slope from the contact point (envelope theorem, :meth:`DropCutter.slopes`).  Between samples
the cubic Hermite interpolant (error O(d^4 z'''') / 384, de Boor, "A Practical Guide to
Splines", ch. IV) locates each chord's largest excess z - chord; that point is evaluated with
the exact drop-cutter and, where Hermite and exact values disagree by more than
``MODEL_ERROR``, inserted as a sample and the chord examined again; for :func:`lift_chords`
the exact slope there must agree too (a kink between two samples, where the contact leaves a
face for its border, can match a model through both ends at one point).  Intervals whose slopes
cannot be trusted (a wall steeper than ``MAX_SLOPE``, a contact on the ball's rim, a secant
steeper than that: a jump where the ball's side meets a wall) are cut into up to ``KSECT``
pieces per round with exact samples instead, down to ``MIN_SPLIT`` (at most ``ROUGH_PER_CHORD``
of a chord's intervals a round, the highest first, so a chord that is rough all along grows
by a bounded number of samples a round).  A steep interval whose
end data fit a smooth monotone height (up to ``MAX_SMOOTH_SLOPE``) keeps the Hermite model
until the model fails there once: a drafted wall is not cut into MIN_SPLIT pieces.  Every
round asks the drop-cutter once (a call costs far more than its points).

:func:`lift_chords` (raster, iso-parametric) then lifts each chord's end vertices by its
excess plus ``CLEARANCE`` (a vertex shared by two chords takes the larger lift).  A lift needs
no second check: the chord rises at least by the lesser of its end lifts all along, so its
excess bound falls by that much; only chords the check left unresolved are examined again,
until no chord dips more than ``DIP_LIMIT``.  Waterlines keep their Z and push their
vertices outwards instead (:mod:`waterline`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Callable

import numpy as np

from ..typing import FloatArray
from .primitives import max_into

#: A chord may dip below the exact CL height by at most this (mm): numerically zero.
DIP_LIMIT = 1e-7
#: Excess (mm) below which a chord is left alone: rounding of exact coincidence (planes).
NEGLIGIBLE = 1e-9
#: Each lift clears a chord's worst point by this much (mm), covering the model error.
CLEARANCE = 5e-8
#: Largest disagreement (mm) between the Hermite model and the exact height at a chord's
#: worst point before the point becomes a sample and the chord is examined again.
MODEL_ERROR = 2e-8
#: Largest |grad z| at which the Hermite model of the CL height is trusted.
MAX_SLOPE = 20.0
#: Largest |grad z| at which the Hermite model is trusted on an interval whose end data fit a
#: smooth monotone height (:func:`_one_signed_curvature`); the envelope-theorem slope of a
#: contact near the ball's rim is still accurate there.
MAX_SMOOTH_SLOPE = 200.0
#: Intervals whose modelled maximum lies within this (mm) of the chord's best are evaluated.
NEAR = 1e-5
#: Intervals shorter than this (mm) are not split further.
MIN_SPLIT = 1e-5
#: Rounds of sample insertion per check.
ROUNDS = 10
#: At most this many pieces per rough interval and round (k-section).
KSECT = 16
#: At most this many rough intervals of one chord are cut per round: those with the highest
#: exact ends (a jump's top).  A chord running along a vertical tangent (a contour at a
#: fillet's vertical end, a pass on the ball's own rim) is rough everywhere; cutting all its
#: intervals grew the samples 16-fold a round (140 000 drop-cutter queries in one round).
ROUGH_PER_CHORD = 4

#: query(xy) -> (tip heights (m,), gradients (m, 2)), NaN where the ball meets no surface.
QueryFn = Callable[[FloatArray], "tuple[FloatArray, FloatArray]"]


@dataclass
class ChordSamples:
    """Exact CL samples of polylines, back to back.

    ``pos`` (mm) increases along each line and is linear in XY along every chord; ``vertex``
    marks the polyline's vertices (first and last sample of each line included); ``zv`` holds
    the chord height at the vertices (z plus any lift; ignored elsewhere).
    """

    pos: FloatArray
    xy: FloatArray
    z: FloatArray
    grad: FloatArray
    line: np.ndarray
    vertex: np.ndarray
    zv: FloatArray

    def insert(self, after: np.ndarray, pos: FloatArray, xy: FloatArray, z: FloatArray,
               grad: FloatArray) -> tuple[np.ndarray, np.ndarray]:
        """Add exact non-vertex samples, each inside the interval from sample ``after[i]`` to
        ``after[i] + 1``, keeping the order by (line, pos).  Returns the new index of every
        old sample and of every added one (in the order given)."""
        if len(pos) == 0:
            return np.arange(len(self.pos)), np.empty(0, np.intp)
        order = np.lexsort((pos, after))
        at = after[order] + 1
        n, m = len(self.pos), len(at)
        # One merge for all arrays (as np.insert would place them, without redoing it 7 times).
        new_at = at + np.arange(m)
        old_at = np.arange(n) + np.searchsorted(at, np.arange(n), side="right")

        def merged(old: np.ndarray, added) -> np.ndarray:
            out = np.empty((n + m,) + old.shape[1:], old.dtype)
            out[old_at] = old
            out[new_at] = added
            return out

        self.pos = merged(self.pos, pos[order])
        self.xy = merged(self.xy, xy[order])
        self.z = merged(self.z, z[order])
        self.grad = merged(self.grad, grad[order])
        self.line = merged(self.line, self.line[after[order]])
        self.vertex = merged(self.vertex, False)
        self.zv = merged(self.zv, z[order])
        added = np.empty(m, np.intp)
        added[order] = new_at
        return old_at, added

    def vertices(self) -> tuple[FloatArray, FloatArray, np.ndarray]:
        """XY, chord heights and line of the vertices, in order."""
        v = self.vertex
        return self.xy[v], self.zv[v], self.line[v]


@dataclass
class ChordCheck:
    """Per vertex rank r (the chord from vertex r to r + 1): the largest excess of the exact
    CL height over the chord (mm; -inf where r ends its line) and, where that point had to be
    evaluated between samples, its XY and height gradient (NaN where it is a sample)."""

    excess: FloatArray
    where: FloatArray
    grad: FloatArray
    unresolved: int
    #: per vertex rank, the chords left unresolved after the last round (None: none)
    unresolved_at: np.ndarray | None = None


def _hermite_max(z0, z1, m0, m1, c0, c1):
    """Max over tau in [0, 1] of H(tau) - (c0 + tau (c1 - c0)) and its tau, H the cubic
    Hermite interpolant of values z0, z1 and end slopes m0, m1 (per unit tau)."""
    a3 = 2.0 * z0 + m0 - 2.0 * z1 + m1
    a2 = -3.0 * z0 - 2.0 * m0 + 3.0 * z1 - m1
    a1 = m0 - (c1 - c0)
    a0 = z0 - c0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        disc = np.sqrt(np.maximum(a2 * a2 - 3.0 * a3 * a1, 0.0))
        cubic = np.abs(a3) > 1e-14 * (np.abs(a2) + np.abs(a1) + 1e-300)
        r1 = np.where(cubic, (-a2 + disc) / (3.0 * a3), -a1 / (2.0 * a2))
        r2 = np.where(cubic, (-a2 - disc) / (3.0 * a3), np.nan)
    tau = np.column_stack([np.zeros_like(z0), np.ones_like(z0), r1, r2])
    tau = np.where((tau >= 0.0) & (tau <= 1.0), tau, np.nan)
    tau[:, :2] = (0.0, 1.0)
    g = ((a3[:, None] * tau + a2[:, None]) * tau + a1[:, None]) * tau + a0[:, None]
    g = np.where(np.isnan(g), -np.inf, g)
    best = np.argmax(g, axis=1)
    rows = np.arange(len(z0))
    return g[rows, best], tau[rows, best]


def _one_signed_curvature(dz: FloatArray, m0: FloatArray, m1: FloatArray) -> np.ndarray:
    """Whether end values and slopes (per unit of the interval) fit a monotone height of
    one-signed curvature: both slopes on the side of the rise ``dz`` and the secant between
    them (the mean value theorem for a monotone derivative).  A jump (a ball's side on a wall)
    rises more than either end slope explains and fails this."""
    lo, hi = np.minimum(m0, m1), np.maximum(m0, m1)
    up = (dz > 0) & (lo >= 0) & (lo <= dz) & (dz <= hi)
    down = (dz < 0) & (hi <= 0) & (hi >= dz) & (dz >= lo)
    return up | down


def _cap_rough(split: np.ndarray, cid: np.ndarray, ends: FloatArray,
               pos: FloatArray) -> np.ndarray:
    """``split`` keeping, per chord (``cid``), the ROUGH_PER_CHORD intervals with the
    highest exact ends (then the first along the chord); the others wait for a later round."""
    idx = np.flatnonzero(split)
    if len(idx) <= ROUGH_PER_CHORD:
        return split
    c = cid[idx]
    order = idx[np.lexsort((pos[idx], -np.nan_to_num(ends[idx], nan=-np.inf), c))]
    co = cid[order]
    first = np.searchsorted(co, co)
    out = np.zeros_like(split)
    out[order[np.arange(len(order)) - first < ROUGH_PER_CHORD]] = True
    return out


def chord_excess(query: QueryFn, s: ChordSamples, rounds: int = ROUNDS,
                 active: np.ndarray | None = None, kinks: bool = False) -> ChordCheck:
    """Largest exact CL height above each chord (see the module docstring); inserts into
    ``s`` the samples it had to evaluate.  With ``active`` (bool per vertex rank) only those
    chords are examined; the others report -inf.  With ``kinks`` a point evaluated at the
    model's maximum also checks its exact slope: the excess's tangent there, followed to the
    interval's end it rises towards, adds to the model error (per unit of the interval,
    ``reach``), so a kink between the samples, which a model through both ends can match at
    one point, fails the check and is examined again."""
    nvert = int(s.vertex.sum())
    done_excess = np.full(nvert, -np.inf)
    done_where = np.full((nvert, 2), np.nan)
    done_grad = np.full((nvert, 2), np.nan)
    resolved = np.zeros(nvert, bool) if active is None else ~np.asarray(active, bool)
    unresolved = 0
    unresolved_at = np.zeros(nvert, bool)
    # Samples where the Hermite model of a steep interval failed: their intervals are cut
    # like rough ones from then on (the model converges slowly near a vertical tangent).
    failed_steep = np.zeros(len(s.pos), bool)
    for r in range(rounds + 1):
        n = len(s.pos)
        idx = np.arange(n)
        va = np.maximum.accumulate(np.where(s.vertex, idx, 0))
        vb = np.minimum.accumulate(np.where(s.vertex, idx, n - 1)[::-1])[::-1]
        rank = np.cumsum(s.vertex) - 1
        k = np.flatnonzero(s.line[:-1] == s.line[1:])
        k = k[~resolved[rank[va[k]]]]  # intervals of chords still open
        a, b = va[k], vb[k + 1]
        cid = rank[a]
        span = s.pos[b] - s.pos[a]
        span = np.where(span > 0, span, 1.0)
        c0 = s.zv[a] + (s.pos[k] - s.pos[a]) / span * (s.zv[b] - s.zv[a])
        c1 = s.zv[a] + (s.pos[k + 1] - s.pos[a]) / span * (s.zv[b] - s.zv[a])
        z0, z1 = s.z[k], s.z[k + 1]
        d = s.xy[k + 1] - s.xy[k]
        g0, g1 = s.grad[k], s.grad[k + 1]
        m0 = np.einsum("ij,ij->i", g0, d)
        m1 = np.einsum("ij,ij->i", g1, d)
        finite = np.isfinite(z0) & np.isfinite(z1)
        length = np.hypot(d[:, 0], d[:, 1])
        # A secant steeper than both end slopes hides a jump (a ball's side on a wall).
        with np.errstate(divide="ignore", invalid="ignore"):
            secant = np.where(finite, np.abs(z1 - z0) / length, 0.0)
        steep = np.fmax(np.maximum(np.abs(g0).max(axis=1), np.abs(g1).max(axis=1)), secant)
        reliable = finite & np.isfinite(m0) & np.isfinite(m1)
        reliable &= (steep <= MAX_SLOPE) | ((steep <= MAX_SMOOTH_SLOPE)
                                            & _one_signed_curvature(z1 - z0, m0, m1))
        gh = np.full(len(k), -np.inf)
        tau = np.full(len(k), np.nan)
        if reliable.any():
            gh[reliable], tau[reliable] = _hermite_max(z0[reliable], z1[reliable], m0[reliable],
                                                       m1[reliable], c0[reliable], c1[reliable])
        ends = np.fmax(np.where(np.isfinite(z0), z0 - c0, -np.inf),
                       np.where(np.isfinite(z1), z1 - c1, -np.inf))
        # Unreliable intervals: bounded by their exact ends once too short to split.
        rough = finite & ~reliable
        gh[rough] = ends[rough]
        todo = ~resolved[cid]
        recut = reliable & (steep > MAX_SLOPE) & (failed_steep[k] | failed_steep[k + 1])
        split = (rough | recut) & todo & (length > MIN_SPLIT)
        split = _cap_rough(split, cid, ends, s.pos[k])
        # Best interval of every chord still open.
        best_excess = np.full(nvert, -np.inf)
        max_into(best_excess, cid, np.fmax(gh, ends))
        # Query every interval whose modelled maximum lies inside it, above its exact ends,
        # and near the chord's best: a second bump may hide a larger model error.
        cand = reliable & todo & ~split & (gh > ends + 0.5 * MODEL_ERROR)
        cand &= gh >= best_excess[cid] - NEAR
        cand_idx = np.flatnonzero(cand)
        # Rough intervals are cut into up to KSECT pieces at once (k-section): MIN_SPLIT is
        # reached in a few rounds, and those points share the round's one query call with
        # the candidates (a drop-cutter call costs far more than a few extra points).
        ks = k[split] if r < rounds else k[:0]
        pieces = np.clip(np.ceil((length[split] if r < rounds else length[:0]) / MIN_SPLIT),
                         2, KSECT).astype(np.intp)
        ks_after = np.repeat(ks, pieces - 1)
        first = np.repeat(np.cumsum(pieces - 1) - (pieces - 1), pieces - 1)
        frac = (np.arange(len(ks_after)) - first + 1) / np.repeat(pieces, pieces - 1)
        split_xy = s.xy[ks_after] + frac[:, None] * (s.xy[ks_after + 1] - s.xy[ks_after])
        split_pos = s.pos[ks_after] + frac * (s.pos[ks_after + 1] - s.pos[ks_after])
        if r < rounds and len(cand_idx):
            kk = k[cand_idx]
            t = tau[cand_idx]
            q = s.xy[kk] + t[:, None] * d[cand_idx]
        else:
            q = np.empty((0, 2))
        nq = len(q)
        if nq + len(ks_after):
            zall, gall = query(np.concatenate([q, split_xy]))
        else:
            zall, gall = np.empty(0), np.empty((0, 2))
        zs, gs = zall[nq:], gall[nq:]
        new_after, new_pos, new_xy = [], [], []
        if nq:
            zq, gq = zall[:nq], gall[:nq]
            cq = c0[cand_idx] + t * (c1[cand_idx] - c0[cand_idx])
            exact = np.where(np.isfinite(zq), zq - cq, -np.inf)
            err = np.abs(gh[cand_idx] - exact)
            if kinks:
                # A smooth maximum has no slope; an exact slope there that would carry the
                # excess beyond the point along its tangent (a kink between the samples: the
                # contact leaves a face for its border) counts as model error.
                sq = np.einsum("ij,ij->i", gq, d[cand_idx]) - (c1[cand_idx] - c0[cand_idx])
                reach = np.where(sq > 0, sq * (1.0 - t), -sq * t)
                err = np.fmax(err, np.where(np.isfinite(reach), reach, 0.0))
            ok = (err <= MODEL_ERROR) | (length[cand_idx] * np.minimum(t, 1 - t) <= MIN_SPLIT)
            # A point clearly below the chord settles it even where the model is off by more
            # than MODEL_ERROR (the drop-cutter's own noise on tiny intervals): four times the
            # disagreement still leaves the chord NEAR above the CL height there.
            ok |= exact + 4.0 * err < -NEAR
            ch = cid[cand_idx]
            # A chord is resolved when all its candidates matched the model.
            failed = np.zeros(nvert, bool)
            failed[ch[~ok]] = True
            bound = np.full(nvert, -np.inf)
            max_into(bound, ch, exact + err)
            order = np.lexsort((-exact, ch))
            head = order[np.r_[True, ch[order][1:] != ch[order][:-1]]]
            okc = np.unique(ch[~failed[ch]])
            done_excess[okc] = np.fmax(best_excess[okc], bound[okc])
            done_where[ch[head]] = q[head]
            done_grad[ch[head]] = gq[head]
            resolved[okc] = True
            # Every evaluated point becomes a sample: the next check starts from it.
            inside = length[cand_idx] * np.minimum(t, 1 - t) > MIN_SPLIT
            new_after.append(kk[inside])
            new_pos.append(s.pos[kk[inside]]
                           + t[inside] * (s.pos[kk[inside] + 1] - s.pos[kk[inside]]))
            new_xy.append(q[inside])
            s_insert = (zq[inside], gq[inside])
            mark = (~ok & (steep[cand_idx] > MAX_SLOPE))[inside]
        else:
            s_insert = (np.empty(0), np.empty((0, 2)))
            mark = np.zeros(0, bool)
        # Chords with no candidate (their worst point is a sample or a rough end) are done
        # once no rough interval is left to split.
        has_split = np.zeros(nvert, bool)
        has_split[cid[split]] = True
        has_cand = np.zeros(nvert, bool)
        has_cand[cid[cand_idx]] = True
        chords = np.zeros(nvert, bool)
        chords[cid] = True
        finish = chords & ~resolved & ~has_cand & ~has_split
        if r == rounds:
            unresolved_at = chords & ~resolved & ~finish
            unresolved = int(unresolved_at.sum())
            finish = chords & ~resolved
        done_excess[finish] = best_excess[finish]
        resolved[finish] = True
        old_at, added = s.insert(np.concatenate(new_after + [ks_after]).astype(np.intp),
                 np.concatenate(new_pos + [split_pos]),
                 np.concatenate(new_xy + [split_xy]).reshape(-1, 2),
                 np.concatenate([s_insert[0], zs]),
                 np.concatenate([s_insert[1], gs]).reshape(-1, 2))
        marks = np.zeros(len(s.pos), bool)
        marks[old_at] = failed_steep
        marks[added[:len(mark)]] = mark
        failed_steep = marks
        if resolved[chords].all():
            break
    return ChordCheck(done_excess, done_where, done_grad, unresolved, unresolved_at)


def _split_worst(s: ChordSamples, chords: np.ndarray, target: float) -> int:
    """Make exact samples vertices until no sample of the chords in ``chords`` (vertex ranks)
    lies more than ``target`` (mm) above the chord now over it: the highest sample of each
    such chord first, then of the pieces it leaves, and so on (Douglas & Peucker 1973, one
    sided, on the samples only: no drop-cutter query).  Returns how many were added.

    Inserting vertices keeps the sample indices, so the chords' samples stay marked while
    their chord is split."""
    n = len(s.pos)
    idx = np.arange(n)
    rank = np.cumsum(s.vertex) - 1
    va = np.maximum.accumulate(np.where(s.vertex, idx, 0))
    vb = np.minimum.accumulate(np.where(s.vertex, idx, n - 1)[::-1])[::-1]
    mine = np.zeros(int(s.vertex.sum()), bool)
    mine[chords] = True
    inner = np.flatnonzero(~s.vertex & (va < idx) & (vb > idx) & np.isfinite(s.z))
    inner = inner[mine[rank[va[inner]]]]
    added = 0
    while len(inner):
        va = np.maximum.accumulate(np.where(s.vertex, idx, 0))
        vb = np.minimum.accumulate(np.where(s.vertex, idx, n - 1)[::-1])[::-1]
        inner = inner[~s.vertex[inner]]
        a, b = va[inner], vb[inner]
        span = np.where(s.pos[b] > s.pos[a], s.pos[b] - s.pos[a], 1.0)
        chord = s.zv[a] + (s.pos[inner] - s.pos[a]) / span * (s.zv[b] - s.zv[a])
        g = s.z[inner] - chord
        sel = g > target
        inner, a, g = inner[sel], a[sel], g[sel]
        if len(inner) == 0:
            break
        order = np.lexsort((-g, a))  # the highest sample of each chord (by its first vertex)
        pick = inner[order[np.r_[True, a[order][1:] != a[order][:-1]]]]
        s.vertex[pick] = True
        s.zv[pick] = s.z[pick]
        added += len(pick)
    return added


def _check_lines(query: QueryFn, s: ChordSamples, active: np.ndarray | None) -> ChordCheck:
    """:func:`chord_excess` (with its kink check) of the ``active`` chords (bool per vertex
    rank; None: all), run on the lines that hold one only: each round of the check passes over
    all samples it is given, so a few chords left of a large job are not checked at the cost
    of all of it.
    The samples it adds go back into ``s``; chords of other lines report -inf."""
    if active is None:
        return chord_excess(query, s, kinks=True)
    line_v = s.line[s.vertex]
    mask = np.isin(s.line, np.unique(line_v[active]))
    if mask.all():
        return chord_excess(query, s, active=active, kinks=True)
    names = [f.name for f in fields(ChordSamples)]
    sub = ChordSamples(*(getattr(s, n)[mask] for n in names))
    mine = mask[s.vertex]
    check = chord_excess(query, sub, active=active[mine], kinks=True)
    keep = ~mask
    order = np.argsort(np.concatenate([s.line[keep], sub.line]), kind="stable")
    for n in names:
        setattr(s, n, np.concatenate([getattr(s, n)[keep], getattr(sub, n)])[order])
    nvert = len(line_v)
    excess = np.full(nvert, -np.inf)
    where = np.full((nvert, 2), np.nan)
    grad = np.full((nvert, 2), np.nan)
    excess[mine], where[mine], grad[mine] = check.excess, check.where, check.grad
    unresolved_at = np.zeros(nvert, bool)
    unresolved_at[mine] = check.unresolved_at
    return ChordCheck(excess, where, grad, check.unresolved, unresolved_at)


def _lowered(excess: FloatArray, vertex_lift: FloatArray, same: np.ndarray) -> FloatArray:
    """Bounds of the chords' excess (per vertex rank, mm) after their end vertices rose by
    ``vertex_lift`` (mm, >= 0; ``same``: vertex r + 1 is on vertex r's line).  The chord over
    a point rises by the linear blend of its ends' lifts, at least their minimum, so the
    excess there falls by at least that much; a chord ending its line (-inf) stays so."""
    low = np.zeros_like(vertex_lift)
    low[:-1] = np.where(same, np.minimum(vertex_lift[:-1], vertex_lift[1:]), 0.0)
    return np.where(np.isfinite(excess), excess - low, excess)


def lift_chords(query: QueryFn, s: ChordSamples, max_lift: float | None = None,
                iterations: int = 8) -> dict:
    """Raise the vertices in ``s.zv`` until every chord clears the exact CL height.

    Each chord's end vertices are lifted by its excess plus ``CLEARANCE`` (shared vertices take
    the larger lift, which only raises the neighbouring chord) and the chords' excess bounds
    fall by the lesser lift of their ends (:func:`_lowered`); chords left unresolved are checked
    again, until no chord dips more than ``DIP_LIMIT``.  A chord that would need more than ``max_lift`` (mm)
    first gets exact samples as new vertices, until none of its samples lies more than
    ``max_lift`` / 2 above the chord over it (:func:`_split_worst`), so the lift, and with it
    the height of the move above the CL curve, stays bounded.  Returns statistics (largest lift in mm,
    iterations, vertices added).
    """
    worst = np.inf
    it = 0
    unresolved = 0
    added = 0
    # After the first check a lift is accounted for without the drop-cutter: raising a
    # chord's end vertices by l_a, l_b >= 0 lowers the chord by at least min(l_a, l_b) all
    # along it, so a chord whose excess was bounded by e is bounded by e - min(l_a, l_b)
    # (:func:`_lowered`).  Only the chords left unresolved are examined again, on their lines
    # alone (:func:`_check_lines`); the others keep their (lowered) verdict.
    active = None
    for it in range(1, iterations + 1):
        if active is None:
            check = _check_lines(query, s, active)
            exc, stuck = check.excess.copy(), check.unresolved_at.copy()
        elif active.any():  # the chords not examined keep their last verdict
            check = _check_lines(query, s, active)
            exc[active], stuck[active] = check.excess[active], check.unresolved_at[active]
        unresolved = int(stuck.sum())
        worst = float(np.max(exc, initial=-np.inf))
        if worst <= NEGLIGIBLE or (worst <= DIP_LIMIT and it == iterations):
            break
        if max_lift is not None and it < iterations:
            big = np.flatnonzero(np.isfinite(exc) & (exc > max_lift))
            if len(big):
                new = _split_worst(s, big, 0.75 * max_lift)
                added += new
                if new:
                    active = None  # new vertices: the ranks moved, examine every chord
                    continue
        lift = np.where(np.isfinite(exc) & (exc > NEGLIGIBLE), exc + CLEARANCE, 0.0)
        vertex_lift = lift.copy()
        line_v = s.line[s.vertex]
        same = line_v[1:] == line_v[:-1]
        vertex_lift[1:] = np.maximum(vertex_lift[1:], np.where(same, lift[:-1], 0.0))
        if not vertex_lift.any():
            break
        s.zv[s.vertex] += vertex_lift
        exc = _lowered(exc, vertex_lift, same)
        active = stuck.copy()  # a chord left unresolved is examined again
    v = s.vertex & np.isfinite(s.z)
    return {"max_lift_mm": float(np.max(s.zv[v] - s.z[v], initial=0.0)),
            "worst_dip_mm": worst, "iterations": it, "unresolved_chords": unresolved,
            "vertices_added": added}


def sample_chords(query: QueryFn, polylines: list, zv: list, step: float) -> ChordSamples:
    """Exact CL samples along the chords of ``polylines`` ((n, 2+) XY arrays), at most
    ``step`` mm apart, vertices included; ``zv`` gives each polyline's vertex heights."""
    pos, xy, line, vertex, zvs = [], [], [], [], []
    for k, (p, zp) in enumerate(zip(polylines, zv)):
        p = np.asarray(p, dtype=float)[:, :2]
        seg = np.hypot(*np.diff(p, axis=0).T)
        n = np.maximum(np.ceil(seg / step).astype(int), 1)
        chord = np.repeat(np.arange(len(seg)), n)
        frac = np.concatenate([np.arange(m) / m for m in n])
        start = np.concatenate([[0.0], np.cumsum(seg)])
        pos.append(np.concatenate([start[chord] + frac * seg[chord], start[-1:]]))
        xy.append(np.concatenate([p[chord] + frac[:, None] * (p[chord + 1] - p[chord]), p[-1:]]))
        line.append(np.full(len(chord) + 1, k))
        vertex.append(np.concatenate([frac == 0.0, [True]]))
        zfull = np.full(len(chord) + 1, np.nan)
        zfull[vertex[-1]] = zp
        zvs.append(zfull)
    xy_all = np.concatenate(xy)
    z, grad = query(xy_all)
    return ChordSamples(np.concatenate(pos), xy_all, z, grad, np.concatenate(line),
                        np.concatenate(vertex), np.concatenate(zvs))
