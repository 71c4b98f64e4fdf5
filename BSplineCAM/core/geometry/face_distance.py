# SPDX-License-Identifier: LGPL-2.1-or-later
"""Distances from points to a model's trimmed NURBS faces (numpy only).

:class:`FaceDistance`: per face, samples on a grid over its trim's parameter box kept inside
the trim (:func:`.faces.inside`) and the trim polylines' vertices;
the nearest samples seed Newton's iteration for the foot point (The NURBS Book, section 6.1,
point projection: the gradient of |S(u, v) - p|^2 zero, with the surface's second
derivatives; Gauss-Newton where the Hessian is not positive definite, the step halved until
the distance does not grow); a foot outside the trim gives way to the nearest point of the
trim polyline's image on the surface (golden-section search along each of the trim segments
nearest the point).  The sign: outside (positive) where (p - foot) . n > 0 with the face's
outward normal n at an interior foot; at a foot on a trim edge, outside when any face with a
point within twice the trims' tolerance of the nearest distance sees p on its outer side
(right at a convex edge; inside a concave edge every face there sees p inside).

What is exact: every distance is that of a true point of a face as core holds it (on the
surface, inside its trim polygon), so it never lies below the true distance to that face;
Newton's foot is exact to round-off at an interior minimum.  What is measured: a minimum the
seeds miss (a face folded so that Newton from the nearest samples reaches another local
minimum) is missed by up to the samples' spacing (about ``sample_spacing``, 1 mm, at most
161 samples a side); trims are the polylines core holds, within each face's ``tolerance`` of
the true edges.

:meth:`FaceDistance.horizontal` gives the horizontal distance from a vertical half-line (a
shank's axis) to the face points above its foot: damped Gauss-Newton on |S_xy(u, v) -
p_xy| from the nearest samples above, exact at an interior minimum, the samples' spacing
otherwise.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..typing import FloatArray
from .faces import Face, inside

#: Target spacing (mm) of a face's samples (21 to 161 per side of its parameter box).
SAMPLE_SPACING_MM = 1.0
SAMPLES_PER_SIDE = (21, 161)
#: Newton seeds per query and face; Newton steps.
SEEDS = 3
NEWTON_STEPS = 30
#: Golden-section steps (the bracket shrinks by 0.618 per step).
GOLDEN_STEPS = 30
#: Trim segments searched per query and face.
EDGE_SEGMENTS = 3
_GOLD = 0.5 * (math.sqrt(5.0) - 1.0)


def golden_min(f, lo: FloatArray, hi: FloatArray, steps: int = GOLDEN_STEPS) -> FloatArray:
    """Argmin of ``f`` over each bracket [lo, hi] by golden-section search, vectorised over
    the brackets (``f`` maps an array of t to an array of values); exact for a unimodal f to
    0.618^steps of the bracket."""
    a = np.asarray(lo, dtype=float).copy()
    b = np.asarray(hi, dtype=float).copy()
    c, d = b - _GOLD * (b - a), a + _GOLD * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(steps):
        left = fc < fd  # the minimum lies in [a, d]
        a, b = np.where(left, a, c), np.where(left, d, b)
        new = np.where(left, b - _GOLD * (b - a), a + _GOLD * (b - a))
        fn = f(new)
        c, d, fc, fd = (np.where(left, new, d), np.where(left, c, new),
                        np.where(left, fn, fd), np.where(left, fc, fn))
    return np.where(fc < fd, c, d)


def _box_distance(points: FloatArray, lo: FloatArray, hi: FloatArray) -> FloatArray:
    """Distance (mm) from each point to the axis-aligned box [lo, hi] (0 inside)."""
    gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
    return np.sqrt(np.sum(gap * gap, axis=-1))


def dot(a: FloatArray, b: FloatArray) -> FloatArray:
    """Row-wise dot products of (..., 3) arrays."""
    return np.einsum("...i,...i->...", a, b)


@dataclass(frozen=True)
class _Samples:
    """One face's samples: (N, 2) parameters and (N, 3) points, its trim segments (K, 4) in
    (u, v) and their end points (K, 2, 3), and ``step``, the largest distance (mm) between
    neighbouring grid samples."""

    uv: FloatArray
    xyz: FloatArray
    seg_uv: FloatArray
    seg_xyz: FloatArray
    step: float


@dataclass(frozen=True)
class Nearest:
    """The nearest face point to each query: ``distance`` mm (signed for
    :meth:`FaceDistance.signed`: negative inside the model; NaN where no face lies within
    the reach), ``face`` the index in the face list (-1 none), ``foot`` (Q, 3) mm, ``edge``
    True where the foot lies on a trim polyline (or Newton stopped short of a minimum)."""

    distance: FloatArray
    face: np.ndarray
    foot: FloatArray
    edge: np.ndarray


class FaceDistance:
    """Distances from points to a model's trimmed faces (see the module docstring)."""

    def __init__(self, faces: Sequence[Face], sample_spacing: float = SAMPLE_SPACING_MM):
        self.faces = list(faces)
        self.spacing = float(sample_spacing)
        boxes = []
        for f in self.faces:
            poles = np.asarray(f.surface.poles, dtype=float).reshape(-1, 3)
            boxes.append((poles.min(axis=0), poles.max(axis=0)))  # convex hull (weights > 0)
        self.lo = np.array([b[0] for b in boxes]).reshape(-1, 3)
        self.hi = np.array([b[1] for b in boxes]).reshape(-1, 3)
        self.slack = 2.0 * max((f.tolerance for f in self.faces), default=0.0) + 1e-6
        self._samples: dict[int, _Samples] = {}

    def samples(self, k: int) -> _Samples:
        """Face k's samples, made on first use."""
        if k not in self._samples:
            self._samples[k] = self._make_samples(self.faces[k], self.lo[k], self.hi[k])
        return self._samples[k]

    def _make_samples(self, face: Face, lo: FloatArray, hi: FloatArray) -> _Samples:
        s = face.surface
        (du0, du1), (dv0, dv1) = s.domain
        u0, u1, v0, v1 = face.bounds()
        u0, u1, v0, v1 = max(u0, du0), min(u1, du1), max(v0, dv0), min(v1, dv1)
        n = int(np.clip(math.ceil(float(np.linalg.norm(hi - lo)) / self.spacing),
                        *SAMPLES_PER_SIDE))
        t = (np.arange(n) + 0.5) / n
        uu, vv = np.meshgrid(u0 + (u1 - u0) * t, v0 + (v1 - v0) * t, indexing="ij")
        grid = s.evaluate(uu, vv)
        step = max(float(np.linalg.norm(np.diff(grid, axis=a), axis=-1).max(initial=0.0))
                   for a in (0, 1))
        keep = inside(face, uu, vv)
        seg = face._edges
        ends = self._clamp(face, np.concatenate([seg[:, :2], seg[:, 2:]]))
        corners = self._clamp(face, seg[:, :2])
        uv = np.concatenate([np.stack([uu[keep], vv[keep]], axis=1), corners])
        pts = s.evaluate(ends[:, 0], ends[:, 1])
        k = len(seg)
        xyz = np.concatenate([grid[keep], pts[:k]])
        return _Samples(uv, xyz, np.concatenate([ends[:k], ends[k:]], axis=1),
                        np.stack([pts[:k], pts[k:]], axis=1), step)

    @staticmethod
    def _clamp(face: Face, uv: FloatArray) -> FloatArray:
        (u0, u1), (v0, v1) = face.surface.domain
        return np.stack([np.clip(uv[:, 0], u0, u1), np.clip(uv[:, 1], v0, v1)], axis=1)

    # -- signed distance ---------------------------------------------------------------------
    def signed(self, points: FloatArray, reach: float | FloatArray) -> Nearest:
        """Signed distance (mm, negative inside the model) from each of ``points`` (Q, 3) to
        the faces within ``reach`` mm of it (a number or one per point); NaN where none."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        q = len(points)
        reach = np.broadcast_to(np.asarray(reach, dtype=float), (q,))
        box = np.stack([_box_distance(points, self.lo[k], self.hi[k])
                        for k in range(len(self.faces))], axis=1) if self.faces else \
            np.zeros((q, 0))
        best = np.full(q, np.inf)
        found: list[tuple] = []
        for k in np.argsort(box.min(axis=0) if q else []):
            sel = np.flatnonzero((box[:, k] <= reach) & (box[:, k] <= best + self.slack))
            if not len(sel):
                continue
            for qi, d, dot, edge, foot in self._face_candidates(int(k), points[sel],
                                                                float(reach[sel].max())):
                found.append((sel[qi], d, dot, edge, np.full(len(qi), k), foot))
                np.minimum.at(best, sel[qi], d)
        return self._combine(q, found)

    def _face_candidates(self, k: int, p: FloatArray, reach: float):
        """(query index, distance, (p - foot) . n, on an edge, foot) of face k's candidates
        within ``reach`` mm of the points: the nearest sample, Newton from the nearest
        samples, the nearest trim segments."""
        face, full = self.faces[k], self.samples(k)
        s = face.surface
        n = len(p)
        # the samples and trim segments near the points (a face point within the reach lies
        # within a sample step of a sample)
        lo, hi = p.min(axis=0) - reach - full.step, p.max(axis=0) + reach + full.step
        keep = np.all((full.xyz >= lo) & (full.xyz <= hi), axis=1)
        seg_lo, seg_hi = full.seg_xyz.min(axis=1), full.seg_xyz.max(axis=1)
        near_seg = np.all((seg_hi >= lo) & (seg_lo <= hi), axis=1)
        smp = _Samples(full.uv[keep], full.xyz[keep], full.seg_uv[near_seg],
                       full.seg_xyz[near_seg], full.step)
        if len(smp.seg_uv):
            yield self._edge_candidates(face, smp, p)
        if not len(smp.uv):
            return
        seeds = min(SEEDS, len(smp.uv))
        near = np.empty((n, seeds), dtype=np.intp)
        chunk = max(1, 4_000_000 // max(1, len(smp.xyz)))
        for a in range(0, n, chunk):
            d2 = np.sum((p[a:a + chunk, None, :] - smp.xyz[None]) ** 2, axis=-1)
            near[a:a + chunk] = np.argpartition(d2, seeds - 1, axis=1)[:, :seeds] \
                if seeds < d2.shape[1] else np.arange(seeds)
        qi = np.repeat(np.arange(n), seeds)
        uv = smp.uv[near.ravel()]
        u, v = _newton_foot(s, uv[:, 0], uv[:, 1], p[qi])
        on = inside(face, u, v)
        d = s.derivatives(u, v)
        r = p[qi] - d.point
        tangent = np.maximum(np.abs(dot(r, d.su)) / np.maximum(np.linalg.norm(d.su, axis=-1),
                                                                 1e-300),
                             np.abs(dot(r, d.sw)) / np.maximum(np.linalg.norm(d.sw, axis=-1),
                                                                1e-300))
        converged = tangent <= 1e-7 + 1e-9 * np.linalg.norm(r, axis=-1)
        normal = np.cross(d.su, d.sw)
        yield (qi[on], np.linalg.norm(r[on], axis=-1), dot(r[on], normal[on]),
               ~converged[on], d.point[on])
        # the nearest samples themselves (true face points)
        first = near[:, 0]
        pts = smp.xyz[first]
        ds = s.derivatives(smp.uv[first, 0], smp.uv[first, 1])
        rs = p - pts
        yield (np.arange(n), np.linalg.norm(rs, axis=-1), dot(rs, np.cross(ds.su, ds.sw)),
               np.ones(n, bool), pts)

    @staticmethod
    def _edge_candidates(face: Face, smp: _Samples, p: FloatArray):
        """The nearest point of the images of the trim segments nearest each point (their
        3-D chords ranked), by golden-section search along each."""
        s = face.surface
        a, b = smp.seg_xyz[:, 0], smp.seg_xyz[:, 1]
        ab = b - a
        ll = np.maximum(dot(ab, ab), 1e-300)
        count = min(EDGE_SEGMENTS, len(a))
        best = np.empty((len(p), count), dtype=np.intp)
        chunk = max(1, 4_000_000 // max(1, len(a)))
        for i in range(0, len(p), chunk):
            pp = p[i:i + chunk, None, :]
            t = np.clip(dot(pp - a[None], ab[None]) / ll[None], 0.0, 1.0)
            d2 = np.sum((a[None] + t[..., None] * ab[None] - pp) ** 2, axis=-1)
            best[i:i + chunk] = np.argpartition(d2, count - 1, axis=1)[:, :count] \
                if count < d2.shape[1] else np.arange(count)
        qi = np.repeat(np.arange(len(p)), count)
        seg = smp.seg_uv[best.ravel()]
        q = p[qi]

        def at(t: FloatArray) -> FloatArray:
            return seg[:, :2] + t[:, None] * (seg[:, 2:] - seg[:, :2])

        def dist(t: FloatArray) -> FloatArray:
            uv = at(t)
            return np.sum((s.evaluate(uv[:, 0], uv[:, 1]) - q) ** 2, axis=-1)

        t = golden_min(dist, np.zeros(len(q)), np.ones(len(q)))
        uv = at(t)
        d = s.derivatives(uv[:, 0], uv[:, 1])
        r = q - d.point
        return (qi, np.linalg.norm(r, axis=-1), dot(r, np.cross(d.su, d.sw)),
                np.ones(len(q), bool), d.point)

    def _combine(self, q: int, found: list[tuple]) -> Nearest:
        dist = np.full(q, np.nan)
        face = np.full(q, -1)
        foot = np.full((q, 3), np.nan)
        edge = np.zeros(q, bool)
        if not found:
            return Nearest(dist, face, foot, edge)
        qi, d, dot, ed, fk, ft = (np.concatenate(x) for x in zip(*found))
        order = np.lexsort((d, qi))
        qi, d, dot, ed, fk, ft = qi[order], d[order], dot[order], ed[order], fk[order], \
            ft[order]
        first = np.r_[True, qi[1:] != qi[:-1]]
        lead = np.flatnonzero(first)
        owner = np.repeat(np.arange(len(lead)), np.diff(np.r_[lead, len(qi)]))
        near = d <= d[lead][owner] + self.slack
        vote = np.zeros(len(lead), bool)
        np.logical_or.at(vote, owner[near], dot[near] > 0.0)
        outside = np.where(ed[lead], vote, dot[lead] > 0.0)
        rows = qi[lead]
        dist[rows] = np.where(outside, d[lead], -d[lead])
        face[rows], foot[rows], edge[rows] = fk[lead], ft[lead], ed[lead]
        return Nearest(dist, face, foot, edge)

    # -- horizontal distance (the shank) -----------------------------------------------------
    def horizontal(self, points: FloatArray, reach: float) -> Nearest:
        """Horizontal distance (mm) from the vertical half-line above each point to the face
        points above it, within ``reach`` mm; inf where none (unsigned)."""
        points = np.asarray(points, dtype=float).reshape(-1, 3)
        q = len(points)
        dist = np.full(q, np.inf)
        face = np.full(q, -1)
        foot = np.full((q, 3), np.nan)
        for k in range(len(self.faces)):
            lo, hi = self.lo[k], self.hi[k]
            gap = np.maximum(np.maximum(lo[:2] - points[:, :2], points[:, :2] - hi[:2]), 0.0)
            sel = np.flatnonzero((np.hypot(gap[:, 0], gap[:, 1]) < np.minimum(dist, reach))
                                 & (hi[2] >= points[:, 2]))
            if not len(sel):
                continue
            d, ft = self._face_horizontal(k, points[sel], reach)
            better = d < dist[sel]
            dist[sel[better]], face[sel[better]], foot[sel[better]] = d[better], k, ft[better]
        return Nearest(dist, face, foot, np.zeros(q, bool))

    def _face_horizontal(self, k: int, p: FloatArray,
                         reach: float) -> tuple[FloatArray, FloatArray]:
        face, full = self.faces[k], self.samples(k)
        n = len(p)
        out = np.full(n, np.inf)
        foot = np.full((n, 3), np.nan)
        lo = p[:, :2].min(axis=0) - reach - full.step
        hi = p[:, :2].max(axis=0) + reach + full.step
        keep = np.all((full.xyz[:, :2] >= lo) & (full.xyz[:, :2] <= hi), axis=1) & \
            (full.xyz[:, 2] >= p[:, 2].min() - full.step)
        if not keep.any():
            return out, foot
        smp = _Samples(full.uv[keep], full.xyz[keep], full.seg_uv, full.seg_xyz, full.step)
        seeds = min(SEEDS, len(smp.uv))
        chunk = max(1, 4_000_000 // max(1, len(smp.xyz)))
        near = np.empty((n, seeds), dtype=np.intp)
        for a in range(0, n, chunk):
            pp = p[a:a + chunk]
            d2 = np.sum((pp[:, None, :2] - smp.xyz[None, :, :2]) ** 2, axis=-1)
            d2[smp.xyz[None, :, 2] < pp[:, None, 2]] = np.inf
            near[a:a + chunk] = np.argpartition(d2, seeds - 1, axis=1)[:, :seeds] \
                if seeds < d2.shape[1] else np.arange(seeds)
            dmin = np.sqrt(d2.min(axis=1))
            arg = d2.argmin(axis=1)
            ok = np.isfinite(dmin)
            out[a:a + chunk] = dmin
            foot[a:a + chunk][ok] = smp.xyz[arg[ok]]
        valid = smp.xyz[near.ravel(), 2] >= np.repeat(p[:, 2], seeds)
        qi = np.repeat(np.arange(n), seeds)[valid]
        if len(qi):
            uv = smp.uv[near.ravel()[valid]]
            u, v = _newton_horizontal(face.surface, uv[:, 0], uv[:, 1], p[qi])
            pts = face.surface.evaluate(u, v)
            ok = inside(face, u, v) & (pts[:, 2] >= p[qi, 2])
            d = np.hypot(*(pts[:, :2] - p[qi, :2]).T)
            for i, dd, pt in zip(qi[ok], d[ok], pts[ok]):
                if dd < out[i]:
                    out[i], foot[i] = dd, pt
        return out, foot


def _halved_step(s, u: FloatArray, v: FloatArray, du: FloatArray, dv: FloatArray,
                 p: FloatArray, before: FloatArray, dims: int) -> tuple:
    """(u, v) + scale (du, dv) clamped to the domain, each scale halved (at most 8 times)
    until the squared distance over the first ``dims`` coordinates does not grow past
    ``before``; the new parameters and where it still grew."""
    (u0, u1), (v0, v1) = s.domain
    scale = np.ones_like(u)
    for _half in range(8):
        nu = np.clip(u + scale * du, u0, u1)
        nv = np.clip(v + scale * dv, v0, v1)
        e = (s.evaluate(nu, nv) - p)[:, :dims]
        worse = dot(e, e) > before * (1 + 1e-15)
        if not worse.any():
            break
        scale = np.where(worse, 0.5 * scale, scale)
    return nu, nv, worse


def _newton_foot(s, u: FloatArray, v: FloatArray, p: FloatArray,
                 steps: int = NEWTON_STEPS) -> tuple[FloatArray, FloatArray]:
    """Parameters of a local minimum of |S(u, v) - p| from (u, v): Newton on the gradient
    with the full Hessian where it is positive definite, Gauss-Newton (damped) elsewhere,
    step halving until the distance does not grow, clamped to the domain."""
    (u0, u1), (v0, v1) = s.domain
    for _ in range(steps):
        d = s.derivatives(u, v)
        r = d.point - p
        gu, gv = dot(d.su, r), dot(d.sw, r)
        juu, juv, jvv = dot(d.su, d.su), dot(d.su, d.sw), dot(d.sw, d.sw)
        huu, huv, hvv = juu + dot(d.suu, r), juv + dot(d.suw, r), jvv + dot(d.sww, r)
        det = huu * hvv - huv * huv
        newton = (det > 1e-14 * (juu * jvv + 1e-300)) & (huu > 0)
        mu = 1e-9 * (juu + jvv) + 1e-300
        huu = np.where(newton, huu, juu + mu)
        huv = np.where(newton, huv, juv)
        hvv = np.where(newton, hvv, jvv + mu)
        det = huu * hvv - huv * huv
        du = -(hvv * gu - huv * gv) / det
        dv = -(huu * gv - huv * gu) / det
        nu, nv, worse = _halved_step(s, u, v, du, dv, p, dot(r, r), 3)
        moved = ~worse
        step = np.abs(np.where(moved, nu - u, 0.0)) + np.abs(np.where(moved, nv - v, 0.0))
        u, v = np.where(moved, nu, u), np.where(moved, nv, v)
        if float(step.max(initial=0.0)) <= 1e-15 * max(u1 - u0, v1 - v0):
            break
    return u, v


def _newton_horizontal(s, u: FloatArray, v: FloatArray, p: FloatArray,
                       steps: int = NEWTON_STEPS) -> tuple[FloatArray, FloatArray]:
    """Parameters of a local minimum of the horizontal distance |S_xy(u, v) - p_xy| from
    (u, v): damped Gauss-Newton (a vertical wall's S_xy is singular along its height)."""
    for _ in range(steps):
        d = s.derivatives(u, v)
        r = (d.point - p)[:, :2]
        a, b = d.su[:, :2], d.sw[:, :2]
        gu, gv = dot(a, r), dot(b, r)
        juu, juv, jvv = dot(a, a), dot(a, b), dot(b, b)
        mu = 1e-6 * (juu + jvv) + 1e-300
        juu, jvv = juu + mu, jvv + mu
        det = juu * jvv - juv * juv
        du = -(jvv * gu - juv * gv) / det
        dv = -(juu * gv - juv * gu) / det
        nu, nv, worse = _halved_step(s, u, v, du, dv, p, dot(r, r), 2)
        u, v = np.where(worse, u, nu), np.where(worse, v, nv)
    return u, v
