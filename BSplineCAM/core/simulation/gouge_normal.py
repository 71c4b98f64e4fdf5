# SPDX-License-Identifier: LGPL-2.1-or-later
"""Gouge measured along the design's normal: how deep a ball end mill enters the model.

The Z-map (:mod:`.verify`) measures gouge vertically, design height - machined height at each
cell centre.  At the top edge of a steep wall that depth is the wall's height wherever the
tool reaches a cell's column by a hair: a ball passing low beside a 100 mm wall whose axis
comes 2.998 mm from a cell centre on the wall's top edge reads as a 100 mm "gouge".  This
module measures, for the cells the Z-map flags (design - machined over the tolerance, at most
``max_cells`` of them, the deepest first), how deep the tool really enters the model:

* the moves: the linearised segments (those the Z-map simulated) whose ball sweeps the cell's
  column below the design height there (the lowest point of the ball over the column, convex
  along a straight segment, found by golden-section search), each over the part of its path
  where the ball's axis lies within R of the cell centre;
* the ball: intrusion = R - signed distance from the ball's centre to the model's faces,
  maximised along that part of the path: centres every ``path_step`` mm, then every local
  maximum of those samples within half a step of the move's best (at most REFINED_MAXIMA,
  the deepest first) refined by golden-section search over its two neighbouring intervals.
  The distance is 1-Lipschitz in the centre, so a maximum no sample comes near exceeds its
  nearest sample by at most half a step;
* the shank above the ball (a cylinder of radius R from the centre up): intrusion = R -
  horizontal distance from the axis to the faces' points above the centre, at the same
  centres (not refined).

Distance to trimmed faces (:class:`FaceDistance`): per face, samples on a grid over its trim's
parameter box kept inside the trim (:func:`.faces.inside`) and the trim polylines' vertices;
the nearest samples seed Newton's iteration for the foot point (The NURBS Book, section 6.1,
point projection: the gradient of |S(u, v) - p|^2 zero, with the surface's second
derivatives; Gauss-Newton where the Hessian is not positive definite, the step halved until
the distance does not grow); a foot outside the trim gives way to the nearest point of the
trim polyline's image on the surface (golden-section search along each of the trim segments
nearest the point).  The sign: outside (positive) where (p - foot) . n > 0 with the face's
outward normal n at an interior foot; at a foot on a trim edge, outside when any face with a
point within twice the trims' tolerance of the nearest distance sees p on its outer side
(right at a convex edge; inside a concave edge every face there sees p inside).

What is exact and what is measured:

* every distance is that of a true point of a face as core holds it (on the surface, inside
  its trim polygon), so it never lies below the true distance to that face: the distance
  never over-states an intrusion; Newton's foot is exact to round-off at an interior minimum;
* a minimum the seeds miss (a face folded so that Newton from the nearest samples reaches
  another local minimum) under-states the intrusion by up to the samples' spacing (about
  ``sample_spacing``, 1 mm, at most 161 samples a side);
* trims are the polylines core holds, within each face's ``tolerance`` (1 µm by default) of
  the true edges: at a foot on a trim edge the intrusion is known to that tolerance (exactly
  where the edge is an iso-parameter line of the face, as a cylinder's rim is);
* the path is the linearised program (arcs as chords within the simulation's chord
  tolerance, 0.01 µm at a 0.1 mm cell);
* the shank: from the samples above the centre's height and damped Gauss-Newton on the
  horizontal distance (exact at an interior minimum, the samples' spacing otherwise), unsigned
  (a shank axis inside the material is not told apart), as tall as the faces reach (no
  holder, no flute length); the tool's own length and the holder are not measured.

Only ball end mills are measured: a cell swept by a flat or bull-nose move, a cell beyond
the cap, and a cell whose sweeping moves have no face within reach keep their vertical gouge
(``unmeasured``; :func:`gouge_gate_mm` counts them at that depth).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..geometry.faces import Face, inside
from ..program.gcode_words import Segments
from ..typing import FloatArray
from .simulate import Grid, Tool

#: Flagged cells measured at most (the worst first); the others keep their vertical gouge.
MAX_CELLS = 200
#: Spacing (mm) of the ball's centres along a move before refinement.
PATH_STEP_MM = 0.05
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
#: Design - machined above this (mm) flags a cell (the Z-map's gouge tolerance).
GOUGE_TOLERANCE_MM = 1e-3


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


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
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
        tangent = np.maximum(np.abs(_dot(r, d.su)) / np.maximum(np.linalg.norm(d.su, axis=-1),
                                                                 1e-300),
                             np.abs(_dot(r, d.sw)) / np.maximum(np.linalg.norm(d.sw, axis=-1),
                                                                1e-300))
        converged = tangent <= 1e-7 + 1e-9 * np.linalg.norm(r, axis=-1)
        normal = np.cross(d.su, d.sw)
        yield (qi[on], np.linalg.norm(r[on], axis=-1), _dot(r[on], normal[on]),
               ~converged[on], d.point[on])
        # the nearest samples themselves (true face points)
        first = near[:, 0]
        pts = smp.xyz[first]
        ds = s.derivatives(smp.uv[first, 0], smp.uv[first, 1])
        rs = p - pts
        yield (np.arange(n), np.linalg.norm(rs, axis=-1), _dot(rs, np.cross(ds.su, ds.sw)),
               np.ones(n, bool), pts)

    @staticmethod
    def _edge_candidates(face: Face, smp: _Samples, p: FloatArray):
        """The nearest point of the images of the trim segments nearest each point (their
        3-D chords ranked), by golden-section search along each."""
        s = face.surface
        a, b = smp.seg_xyz[:, 0], smp.seg_xyz[:, 1]
        ab = b - a
        ll = np.maximum(_dot(ab, ab), 1e-300)
        count = min(EDGE_SEGMENTS, len(a))
        best = np.empty((len(p), count), dtype=np.intp)
        chunk = max(1, 4_000_000 // max(1, len(a)))
        for i in range(0, len(p), chunk):
            pp = p[i:i + chunk, None, :]
            t = np.clip(_dot(pp - a[None], ab[None]) / ll[None], 0.0, 1.0)
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
        return (qi, np.linalg.norm(r, axis=-1), _dot(r, np.cross(d.su, d.sw)),
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


def _newton_foot(s, u: FloatArray, v: FloatArray, p: FloatArray,
                 steps: int = NEWTON_STEPS) -> tuple[FloatArray, FloatArray]:
    """Parameters of a local minimum of |S(u, v) - p| from (u, v): Newton on the gradient
    with the full Hessian where it is positive definite, Gauss-Newton (damped) elsewhere,
    step halving until the distance does not grow, clamped to the domain."""
    (u0, u1), (v0, v1) = s.domain
    for _ in range(steps):
        d = s.derivatives(u, v)
        r = d.point - p
        gu, gv = _dot(d.su, r), _dot(d.sw, r)
        juu, juv, jvv = _dot(d.su, d.su), _dot(d.su, d.sw), _dot(d.sw, d.sw)
        huu, huv, hvv = juu + _dot(d.suu, r), juv + _dot(d.suw, r), jvv + _dot(d.sww, r)
        det = huu * hvv - huv * huv
        newton = (det > 1e-14 * (juu * jvv + 1e-300)) & (huu > 0)
        mu = 1e-9 * (juu + jvv) + 1e-300
        huu = np.where(newton, huu, juu + mu)
        huv = np.where(newton, huv, juv)
        hvv = np.where(newton, hvv, jvv + mu)
        det = huu * hvv - huv * huv
        du = -(hvv * gu - huv * gv) / det
        dv = -(huu * gv - huv * gu) / det
        before = _dot(r, r)
        scale = np.ones_like(u)
        for _half in range(8):
            nu = np.clip(u + scale * du, u0, u1)
            nv = np.clip(v + scale * dv, v0, v1)
            e = s.evaluate(nu, nv) - p
            worse = _dot(e, e) > before * (1 + 1e-15)
            if not worse.any():
                break
            scale = np.where(worse, 0.5 * scale, scale)
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
    (u0, u1), (v0, v1) = s.domain
    for _ in range(steps):
        d = s.derivatives(u, v)
        r = (d.point - p)[:, :2]
        a, b = d.su[:, :2], d.sw[:, :2]
        gu, gv = _dot(a, r), _dot(b, r)
        juu, juv, jvv = _dot(a, a), _dot(a, b), _dot(b, b)
        mu = 1e-6 * (juu + jvv) + 1e-300
        juu, jvv = juu + mu, jvv + mu
        det = juu * jvv - juv * juv
        du = -(jvv * gu - juv * gv) / det
        dv = -(juu * gv - juv * gu) / det
        before = _dot(r, r)
        scale = np.ones_like(u)
        for _half in range(8):
            nu = np.clip(u + scale * du, u0, u1)
            nv = np.clip(v + scale * dv, v0, v1)
            e = (s.evaluate(nu, nv) - p)[:, :2]
            worse = _dot(e, e) > before * (1 + 1e-15)
            if not worse.any():
                break
            scale = np.where(worse, 0.5 * scale, scale)
        u, v = np.where(worse, u, nu), np.where(worse, v, nv)
    return u, v


# --------------------------------------------------------------------------- the measure


@dataclass(frozen=True)
class CellGouge:
    """One flagged cell measured along the normal (mm): ``depth`` = max(``ball``,
    ``shank``), the deepest intrusion of the moves sweeping its column; where (``line`` and
    ``move`` of the program, the ball's ``centre``, the ``face`` and its ``foot`` point)."""

    x: float
    y: float
    design: float
    vertical: float
    depth: float
    ball: float
    shank: float
    part: str
    line: int
    move: int
    centre: tuple[float, float, float]
    face: str
    foot: tuple[float, float, float]
    on_trim_edge: bool

    def to_dict(self) -> dict:
        """JSON-ready; an intrusion with no face within reach (no face above the centre
        for the shank) is None."""
        def r6(v: float) -> float:
            return round(float(v), 6)

        def depth(v: float) -> float | None:
            return float(v) if math.isfinite(v) else None

        return {"x_mm": r6(self.x), "y_mm": r6(self.y), "design_z_mm": r6(self.design),
                "vertical_mm": r6(self.vertical), "depth_mm": depth(self.depth),
                "ball_mm": depth(self.ball), "shank_mm": depth(self.shank), "part": self.part,
                "line": self.line, "move": self.move,
                "centre_mm": [r6(c) for c in self.centre], "face": self.face,
                "foot_mm": [r6(c) for c in self.foot], "on_trim_edge": self.on_trim_edge}


@dataclass(frozen=True)
class NormalGouge:
    """The flagged cells' measure: ``cells`` measured (deepest first), ``unmeasured`` (x, y,
    vertical gouge mm, why) for the others, ``flagged`` their total."""

    cells: tuple[CellGouge, ...]
    unmeasured: tuple[tuple[float, float, float, str], ...]
    flagged: int
    path_step: float

    @property
    def max_mm(self) -> float:
        """Deepest intrusion over the measured cells (0 for none)."""
        return max([0.0, *(c.depth for c in self.cells)])

    @property
    def unmeasured_max_mm(self) -> float:
        """Largest vertical gouge of the flagged cells not measured (0 for none)."""
        return max([0.0, *(u[2] for u in self.unmeasured)])

    def metrics(self) -> dict:
        """JSON-ready figures (``gouge_normal_*``)."""
        reasons: dict[str, int] = {}
        for u in self.unmeasured:
            reasons[u[3]] = reasons.get(u[3], 0) + 1
        return {
            "gouge_normal_max_mm": self.max_mm,
            "gouge_normal_cells_flagged": self.flagged,
            "gouge_normal_cells_checked": len(self.cells),
            "gouge_normal_cells_over_tolerance": sum(c.depth > GOUGE_TOLERANCE_MM
                                                     for c in self.cells),
            "gouge_normal_unmeasured_cells": reasons,
            "gouge_normal_unmeasured_max_mm": self.unmeasured_max_mm,
            "gouge_normal_path_step_mm": self.path_step,
            "gouge_normal_at": self.cells[0].to_dict() if self.cells else None,
            "gouge_normal_worst": [c.to_dict() for c in self.cells[:10]],
        }




def measure(faces: Sequence[Face], segments: Segments, tools: Sequence[Tool],
            grid: Grid, design: FloatArray, machined: FloatArray, mask: np.ndarray,
            tolerance: float = GOUGE_TOLERANCE_MM, max_cells: int = MAX_CELLS,
            path_step: float = PATH_STEP_MM, distance: FaceDistance | None = None
            ) -> NormalGouge:
    """Measure the cells of ``mask`` where ``design - machined > tolerance`` (mm) along the
    normal (module docstring): at most ``max_cells`` of them, the deepest first.

    ``segments`` are the linearised moves the Z-map ``machined`` came from, ``tools`` the
    tool of each segment (one Tool for all, or one per segment), ``design`` the top-most
    face height of each cell of ``grid``."""
    gouge = np.where(mask, design - machined, -np.inf)
    flagged = np.flatnonzero(gouge.ravel() > tolerance)
    order = flagged[np.argsort(-gouge.ravel()[flagged], kind="stable")]
    xs, ys = grid.centres()
    iy, ix = np.unravel_index(order, gouge.shape)
    cx, cy, cz, cg = xs[ix], ys[iy], design[iy, ix], gouge[iy, ix]
    unmeasured = [(float(x), float(y), float(g), "beyond the cap")
                  for x, y, g in zip(cx[max_cells:], cy[max_cells:], cg[max_cells:])]
    cx, cy, cz, cg = cx[:max_cells], cy[:max_cells], cz[:max_cells], cg[:max_cells]
    start = np.asarray(segments.start, dtype=float)
    end = np.asarray(segments.end, dtype=float)
    if len(tools) == 1 and len(start) != 1:
        tools = list(tools) * len(start)
    radius = np.array([t.radius for t in tools], dtype=float)
    ball = np.array([t.shape.value == "ball" for t in tools], dtype=bool)
    lo = np.minimum(start, end)
    hi = np.maximum(start, end)
    pairs: list[tuple[int, int, float, float]] = []  # (cell, segment, ta, tb)
    for c in range(len(cx)):
        q = np.array([cx[c], cy[c]])
        near = np.flatnonzero((lo[:, 0] - radius <= q[0]) & (hi[:, 0] + radius >= q[0])
                              & (lo[:, 1] - radius <= q[1]) & (hi[:, 1] + radius >= q[1])
                              & (lo[:, 2] < cz[c] - tolerance))
        ta, tb, hit = _column_interval(start[near], end[near], radius[near], q)
        near, ta, tb = near[hit], ta[hit], tb[hit]
        if np.any(~ball[near]):
            unmeasured.append((float(cx[c]), float(cy[c]), float(cg[c]),
                               "swept by a flat or bull-nose tool"))
            continue
        sweeps = _lowest_over(start[near], end[near], radius[near], q, ta, tb) \
            < cz[c] - tolerance
        if not sweeps.any():
            unmeasured.append((float(cx[c]), float(cy[c]), float(cg[c]),
                               "no move found sweeping the column"))
            continue
        pairs += [(c, int(s), float(a), float(b)) for s, a, b in
                  zip(near[sweeps], ta[sweeps], tb[sweeps])]
    dist = distance or FaceDistance(faces)
    cells = _measure_pairs(dist, pairs, start, end, radius, segments, (cx, cy, cz, cg),
                           path_step, unmeasured)
    cells.sort(key=lambda g: -g.depth)
    return NormalGouge(tuple(cells), tuple(unmeasured), len(flagged), path_step)


def _column_interval(p0: FloatArray, p1: FloatArray, radius: FloatArray, q: FloatArray):
    """[ta, tb] of each segment where its axis lies within its radius of ``q`` (XY), and
    whether that is not empty."""
    a = p0[:, :2] - q
    b = p1[:, :2] - p0[:, :2]
    bb, ab, aa = _dot(b, b), _dot(a, b), _dot(a, a) - radius * radius
    flat = bb <= 1e-24
    disc = ab * ab - bb * aa
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        ta = np.where(flat, 0.0, (-ab - root) / bb)
        tb = np.where(flat, 1.0, (-ab + root) / bb)
    hit = np.where(flat, aa <= 0.0, (disc >= 0.0) & (tb >= 0.0) & (ta <= 1.0))
    ta, tb = np.clip(ta, 0.0, 1.0), np.clip(tb, 0.0, 1.0)
    return ta, tb, hit


def _lowest_over(p0: FloatArray, p1: FloatArray, radius: FloatArray, q: FloatArray,
                 ta: FloatArray, tb: FloatArray) -> FloatArray:
    """The lowest point (mm) of a ball (tip at p0 + t (p1 - p0)) over the column at q for t
    in [ta, tb]: centre z - sqrt(R^2 - r(t)^2) is convex in t (golden section)."""
    def bottom(t: FloatArray) -> FloatArray:
        c = p0 + t[:, None] * (p1 - p0)
        r2 = np.sum((c[:, :2] - q) ** 2, axis=1)
        return c[:, 2] + radius - np.sqrt(np.maximum(radius * radius - r2, 0.0))

    if not len(p0):
        return np.zeros(0)
    t = golden_min(bottom, ta, tb)
    return np.minimum(bottom(t), np.minimum(bottom(ta), bottom(tb)))


#: Cells measured together: those within one square of this side (mm).
TILE_MM = 10.0


def _measure_pairs(dist: FaceDistance, pairs, start, end, radius, segments, cells,
                   path_step: float, unmeasured: list) -> list[CellGouge]:
    """Each cell's deepest ball and shank intrusion over the (cell, segment, ta, tb) pairs
    sweeping its column; cells within a tile of TILE_MM go to the distance together."""
    if not pairs:
        return []
    cx, cy, cz, cg = cells
    cell = np.array([p[0] for p in pairs])
    seg = np.array([p[1] for p in pairs])
    ta = np.array([p[2] for p in pairs])
    tb = np.array([p[3] for p in pairs])
    # the centre's distance to the face point over the cell bounds the nearest face's
    reach = radius[seg] + np.maximum(cg[cell], 0.0) + 0.01
    tile = np.floor(cx[cell] / TILE_MM) * 1e6 + np.floor(cy[cell] / TILE_MM)
    results = [None] * len(pairs)
    for key in np.unique(tile):
        group = np.flatnonzero(tile == key)
        ball, shank = _along(dist, start[seg[group]], end[seg[group]], radius[seg[group]],
                             ta[group], tb[group], reach[group], path_step)
        for n, g in enumerate(group):
            results[g] = (ball[0][n], ball[1][n], ball[2][n], shank[0][n], shank[1][n],
                          shank[2][n])
    out = []
    for k in np.unique(cell):
        mine = np.flatnonzero(cell == k)
        b = np.array([results[m][0] for m in mine])
        sh = np.array([results[m][3] for m in mine])
        if not np.isfinite(b).any() and not np.isfinite(sh).any():
            unmeasured.append((float(cx[k]), float(cy[k]), float(cg[k]),
                               "no face within reach of the sweeping moves"))
            continue
        i, j = int(np.argmax(b)), int(np.argmax(sh))
        if sh[j] > b[i]:
            part, w, (centre, near) = "shank", mine[j], results[mine[j]][4:6]
        else:
            part, w, (centre, near) = "ball", mine[i], results[mine[i]][1:3]
        face, foot, edge = near
        out.append(CellGouge(
            float(cx[k]), float(cy[k]), float(cz[k]), float(cg[k]), float(max(b[i], sh[j])),
            float(b[i]), float(sh[j]), part, int(segments.line[seg[w]]),
            int(segments.move[seg[w]]), tuple(float(v) for v in centre),
            dist.faces[face].name if face >= 0 else "", tuple(float(v) for v in foot),
            bool(edge)))
    return out


#: Local maxima refined per move and cell, the deepest first, by this many golden steps
#: (the bracket of two path steps shrinks to 0.618^14 of itself: 0.03 µm at 0.05 mm).
REFINED_MAXIMA = 6
REFINE_STEPS = 14


def _along(dist: FaceDistance, p0: FloatArray, p1: FloatArray, rad: FloatArray,
           ta: FloatArray, tb: FloatArray, reach: FloatArray, path_step: float):
    """The deepest ball and shank intrusion of each move (tip from p0 to p1) over t in
    [ta, tb]: ((depth, centre, (face, foot, edge)) for the ball, the same for the shank).

    The centres every ``path_step`` mm; the ball's distance is 1-Lipschitz in the centre, so
    a maximum between samples exceeds its nearest sample by at most half a step: every local
    maximum of the samples within half a step of the move's best is refined by golden
    section over its two neighbouring intervals (at most REFINED_MAXIMA per move)."""
    n_pairs = len(p0)
    length = np.linalg.norm(p1 - p0, axis=1)
    count = np.maximum(3, np.ceil((tb - ta) * length / path_step).astype(int) + 1)
    owner = np.repeat(np.arange(n_pairs), count)
    first = np.r_[0, np.cumsum(count)[:-1]]
    index = np.arange(owner.size) - first[owner]
    t = ta[owner] + (tb - ta)[owner] * index / (count[owner] - 1)
    up = np.zeros((n_pairs, 3))
    up[:, 2] = rad

    def centres(k: np.ndarray, tt: FloatArray) -> FloatArray:
        return p0[k] + tt[:, None] * (p1 - p0)[k] + up[k]

    c = centres(owner, t)
    near = dist.signed(c, reach[owner])
    depth = np.where(np.isnan(near.distance), -np.inf, rad[owner] - near.distance)
    best = np.full(n_pairs, -np.inf)
    np.maximum.at(best, owner, depth)
    # local maxima of each move's samples within half a step of its best
    prev = np.r_[-np.inf, depth[:-1]]
    nxt = np.r_[depth[1:], -np.inf]
    prev[first] = -np.inf
    nxt[first + count - 1] = -np.inf
    half = 0.5 * path_step
    peak = np.flatnonzero((depth >= prev) & (depth >= nxt) & np.isfinite(depth)
                          & (depth >= best[owner] - half))
    peak = peak[np.lexsort((-depth[peak], owner[peak]))]
    rank = np.arange(len(peak)) - np.searchsorted(owner[peak], owner[peak])
    peak = peak[rank < REFINED_MAXIMA]
    ball_t = np.full(n_pairs, np.nan)
    arg = np.full(n_pairs, -1)
    hit = np.flatnonzero(depth == best[owner])
    arg[owner[hit]] = hit
    ok = arg >= 0
    ball_t[ok] = t[arg[ok]]
    if len(peak):
        k = owner[peak]
        dt = ((tb - ta) / (count - 1))[k]
        lo_t, hi_t = np.maximum(t[peak] - dt, ta[k]), np.minimum(t[peak] + dt, tb[k])

        def negative_depth(tt: FloatArray) -> FloatArray:
            d = dist.signed(centres(k, tt), reach[k]).distance
            return np.where(np.isnan(d), np.inf, d - rad[k])

        t_star = golden_min(negative_depth, lo_t, hi_t, steps=REFINE_STEPS)
        d_star = rad[k] - dist.signed(centres(k, t_star), reach[k]).distance
        for kk, tt, dd in zip(k, t_star, d_star):
            if np.isfinite(dd) and dd > best[kk]:
                best[kk], ball_t[kk] = dd, tt
    ok = np.isfinite(ball_t)
    final = dist.signed(centres(np.flatnonzero(ok), ball_t[ok]), reach[ok])
    ball_depth = np.full(n_pairs, -np.inf)
    ball_depth[ok] = np.where(np.isnan(final.distance), -np.inf, rad[ok] - final.distance)
    ball_centre = np.full((n_pairs, 3), np.nan)
    ball_centre[ok] = centres(np.flatnonzero(ok), ball_t[ok])
    ball_near = [(-1, (np.nan,) * 3, False)] * n_pairs
    for i, w in enumerate(np.flatnonzero(ok)):
        ball_near[w] = (int(final.face[i]), final.foot[i], bool(final.edge[i]))
    # the shank at the same centres
    h = dist.horizontal(c, float(rad.max()))
    sdepth = rad[owner] - h.distance
    shank = np.full(n_pairs, -np.inf)
    np.maximum.at(shank, owner, sdepth)
    s_arg = np.full(n_pairs, -1)
    hit = np.flatnonzero(sdepth == shank[owner])
    s_arg[owner[hit]] = hit
    s_centre = np.full((n_pairs, 3), np.nan)
    s_near = [(-1, (np.nan,) * 3, False)] * n_pairs
    for w in np.flatnonzero(s_arg >= 0):
        a = s_arg[w]
        s_centre[w] = c[a]
        s_near[w] = (int(h.face[a]), h.foot[a], False)
    return (ball_depth, ball_centre, ball_near), (shank, s_centre, s_near)


def gouge_gate_mm(metrics: dict) -> float:
    """The gouge (mm) a gate compares with its limit, from verification ``metrics``: where
    the gouge was measured along the normal (``gouge_normal_measured``), the deeper of the
    measured cells' intrusion and the vertical gouge of the flagged cells left unmeasured;
    else the vertical gouge ``gouge_max_mm``."""
    if not metrics.get("gouge_normal_measured"):
        return float(metrics["gouge_max_mm"])
    return max(float(metrics["gouge_normal_max_mm"]),
               float(metrics["gouge_normal_unmeasured_max_mm"]))
