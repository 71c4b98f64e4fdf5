# SPDX-License-Identifier: LGPL-2.1-or-later
"""Design heights of a model's faces on a Z-map grid: the top-most face point above each cell.

The same answer as the point probe :meth:`~BSplineCAM.core.toolpath.faceset.FaceSet.height`
(z, face, u, v where S_xy(u, v) = (x, y) inside the face's trim, the highest face winning),
at a cost linear in the cells, for the millions of cells of a verification:

* per face, a coarse-to-fine inversion: the surface is sampled span by span (each knot span
  gets enough samples that neighbours lie within the lookup step in XY), the samples near the
  trimmed material are splatted into an XY lookup raster of that step (the top-most sample
  wins, as a Z-map sees the top of an overhang), and each cell starts from its raster cell's
  sample moved by one linear step with the sample's Jacobian; vectorised Newton on
  S_xy(u, v) = (x, y) then converges in two or three steps (as :mod:`.footprint` does for a
  control net's surface);
* faces are visited from the highest to the lowest (by the top of their control nets, which
  bounds the surface), and a cell whose height is already above a face's top skips that face;
* a converged point counts when it lies within the trim (even-odd rule of
  :func:`.faces.inside`, evaluated with the trim's segments filed by bands of v);
* row bands of the grid are independent and run on the machine's cores (numpy releases the GIL
  inside its loops).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..errors import BSplineCAMError
from ..threads import numpy_threads
from ..typing import FloatArray
from .faces import Face
from .footprint import fill_empty_cells

#: A point is on a face when Newton lands within this distance of it (mm), or within
#: 1e-10 of the model's size when that is larger.
INSIDE_TOLERANCE_MM = 1e-7
NEWTON_STEPS = 12
#: Cells handled together by one thread.
CHUNK_CELLS = 1 << 16
#: A point this many trim tolerances outside a face's trim polyline still counts as on it.
SEAM_FACTOR = 2.0
#: Lookup raster step, at least this many cells of the grid and this fraction of the model.
LOOKUP_CELLS = 4.0
LOOKUP_FRACTION = 1.0 / 1500.0
#: Samples per knot span: at least, at most.
SPAN_SAMPLES = (4, 512)
#: Most samples of one face (the lookup step grows to keep within it).
MAX_FACE_SAMPLES = 4_000_000


@dataclass(frozen=True)
class HeightMap:
    """Top-most face above each cell centre of a (ny, nx) grid.

    ``z`` mm (NaN where no face lies above), ``face`` the 0-based index in the face list
    (-1 where none), ``u`` and ``v`` the face's parameters there (NaN where none).
    """

    z: FloatArray
    face: np.ndarray
    u: FloatArray
    v: FloatArray

    @property
    def found(self) -> np.ndarray:
        return self.face >= 0


class _Trim:
    """Even-odd point-in-trim test (the half-open crossing rule of :func:`.faces.inside`, so
    the same answer) with the trim segments filed by bands of v."""

    def __init__(self, face: Face, bands: int | None = None):
        e = face._edges
        e = e[e[:, 1] != e[:, 3]]  # horizontal edges never straddle the ray
        lo = np.minimum(e[:, 1], e[:, 3])
        hi = np.maximum(e[:, 1], e[:, 3])
        n = bands or int(min(4096, max(1, len(e) // 2)))
        self.v0 = float(lo.min()) if len(e) else 0.0
        span = float(hi.max()) - self.v0 if len(e) else 1.0
        self.n = n
        self.h = span / n if span > 0 else 1.0
        first, last = self._band(lo), self._band(hi)
        counts = np.zeros(n + 1, np.int64)
        np.add.at(counts, first, 1)
        np.add.at(counts, last + 1, -1)
        width = max(1, int(np.cumsum(counts)[:n].max(initial=1)))
        table = np.full((n, width, 4), np.nan)
        fill = np.zeros(n, np.int64)
        for k in np.argsort(first, kind="stable"):
            for b in range(first[k], last[k] + 1):
                table[b, fill[b]] = e[k]
                fill[b] += 1
        self.table = table

    def _band(self, v: FloatArray) -> np.ndarray:
        return np.clip(np.floor((v - self.v0) / self.h), 0, self.n - 1).astype(np.intp)

    def __call__(self, u: FloatArray, v: FloatArray) -> np.ndarray:
        seg = self.table[self._band(v)]
        u0, v0, u1, v1 = seg[..., 0], seg[..., 1], seg[..., 2], seg[..., 3]
        qv = v[:, None]
        straddle = (v0 > qv) != (v1 > qv)
        with np.errstate(invalid="ignore", divide="ignore"):
            cross = u0 + (qv - v0) * ((u1 - u0) / (v1 - v0))
        hits = straddle & (u[:, None] < cross)
        return (np.count_nonzero(hits, axis=1) % 2) == 1


def _span_parameters(knots: FloatArray, domain: tuple[float, float], samples: np.ndarray
                     ) -> FloatArray:
    """Parameters with ``samples[i]`` intervals in each knot span of the domain."""
    lo, hi = domain
    breaks = np.unique(np.clip(np.asarray(knots, dtype=float), lo, hi))
    parts = [np.linspace(a, b, int(n) + 1)[:-1] for a, b, n in
             zip(breaks[:-1], breaks[1:], samples)]
    return np.concatenate([*parts, [hi]])


def _spans(knots: FloatArray, domain: tuple[float, float]) -> int:
    lo, hi = domain
    return max(1, len(np.unique(np.clip(np.asarray(knots, dtype=float), lo, hi))) - 1)


def _orders(surface, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Point, S_u and S_v at scattered parameters (one pass over each point's patch)."""
    if hasattr(surface, "_evaluate_orders"):
        p, su, sv = surface._evaluate_orders(u, v, ((0, 0), (1, 0), (0, 1)))
        return p, su, sv
    return surface.evaluate(u, v), surface.evaluate(u, v, du=1), surface.evaluate(u, v, dw=1)


def _closed_directions(surface, domain: tuple[float, float, float, float]) -> tuple[bool, bool]:
    """Whether the surface closes on itself along u and along v: its points at the two ends of
    the direction's domain agree to 1e-9 of its size at 17 parameters across (a periodic
    surface, or a cylinder, cone, sphere or torus converted by OCCT)."""
    u0, u1, v0, v1 = domain
    t = np.linspace(0.0, 1.0, 17)
    size = float(np.ptp(np.asarray(surface.poles, dtype=float).reshape(-1, 3), axis=0).max())
    out = []
    for ends, across in (((u0, u1), v0 + (v1 - v0) * t), ((v0, v1), u0 + (u1 - u0) * t)):
        pts = []
        for end in ends:
            e = np.full(len(across), end)
            pts.append(surface.evaluate(e, across) if len(out) == 0
                       else surface.evaluate(across, e))
        out.append(bool(np.abs(pts[0] - pts[1]).max() <= 1e-9 * max(size, 1e-300)))
    return out[0], out[1]


class _FaceSeeds:
    """One face's lookup raster of samples (parameters, XY and Jacobian) and its trim."""

    def __init__(self, face: Face, index: int, step: float):
        s = face.surface
        self.face, self.index, self.surface = face, index, s
        (u0, u1), (v0, v1) = s.domain
        self.domain = (u0, u1, v0, v1)
        poles = np.asarray(s.poles, dtype=float).reshape(-1, 3)
        self.zmax = float(poles[:, 2].max())  # the convex hull bounds the surface
        self.trim = _Trim(face)
        self.closed = _closed_directions(s, (u0, u1, v0, v1))
        k0 = SPAN_SAMPLES[0]
        nu, nv = _spans(s.knots_u, (u0, u1)), _spans(s.knots_v, (v0, v1))
        # coarse pass: the largest XY chord between neighbouring samples of each span
        pu = _span_parameters(s.knots_u, (u0, u1), np.full(nu, k0))
        pv = _span_parameters(s.knots_v, (v0, v1), np.full(nv, k0))
        coarse = s.evaluate_grid(pu, pv)[..., :2]
        chord_u = np.hypot(*np.moveaxis(np.diff(coarse, axis=0), -1, 0)).max(axis=1)
        chord_v = np.hypot(*np.moveaxis(np.diff(coarse, axis=1), -1, 0)).max(axis=0)
        cu = chord_u.reshape(nu, k0).max(axis=1)
        cv = chord_v.reshape(nv, k0).max(axis=1)
        lo_n, hi_n = SPAN_SAMPLES
        while True:
            mu = np.clip(np.ceil(k0 * cu / step), lo_n, hi_n)
            mv = np.clip(np.ceil(k0 * cv / step), lo_n, hi_n)
            if mu.sum() * mv.sum() <= MAX_FACE_SAMPLES:
                break
            step *= 1.5
        self.step = step
        pu = _span_parameters(s.knots_u, (u0, u1), mu)
        pv = _span_parameters(s.knots_v, (v0, v1), mv)
        if hasattr(s, "_grid_orders"):
            p, su, sv = s._grid_orders(pu, pv, ((0, 0), (1, 0), (0, 1)))
        else:
            p, su, sv = (s.evaluate_grid(pu, pv, a, b) for a, b in ((0, 0), (1, 0), (0, 1)))
        uu, vv = np.meshgrid(pu, pv, indexing="ij")
        # samples on the material or next to it (two samples deep) seed the cells
        on = self.trim(uu.ravel(), vv.ravel()).reshape(uu.shape)
        near = on.copy()
        for _ in range(2):
            grown = near.copy()
            grown[1:] |= near[:-1]
            grown[:-1] |= near[1:]
            grown[:, 1:] |= near[:, :-1]
            grown[:, :-1] |= near[:, 1:]
            near = grown
        keep = np.flatnonzero(near.ravel())
        self.empty = len(keep) == 0
        pts = p.reshape(-1, 3)[keep]
        on_pts = p.reshape(-1, 3)[on.ravel()]
        self.bounds = ((float(on_pts[:, 0].min()), float(on_pts[:, 0].max()),
                        float(on_pts[:, 1].min()), float(on_pts[:, 1].max()))
                       if len(on_pts) else None)
        if self.empty:
            return
        self.u = uu.ravel()[keep]
        self.v = vv.ravel()[keep]
        self.xy = pts[:, :2].copy()
        jac = np.stack([su.reshape(-1, 3)[keep, :2], sv.reshape(-1, 3)[keep, :2]], axis=-1)
        det = jac[:, 0, 0] * jac[:, 1, 1] - jac[:, 0, 1] * jac[:, 1, 0]
        ok = np.abs(det) > 1e-300
        safe = np.where(ok, det, 1.0)
        # inverse Jacobian per sample (zero where the face is vertical there)
        self.inv = np.where(ok[:, None, None], np.stack(
            [np.stack([jac[:, 1, 1], -jac[:, 0, 1]], -1),
             np.stack([-jac[:, 1, 0], jac[:, 0, 0]], -1)], 1) / safe[:, None, None], 0.0)
        self.lo = self.xy.min(axis=0) - step
        span = self.xy.max(axis=0) + step - self.lo
        self.shape = tuple(int(n) for n in np.ceil(span / step) + 1)
        cell = self._cell(self.xy[:, 0], self.xy[:, 1])
        order = np.argsort(pts[:, 2], kind="stable")  # higher samples written last win
        table = np.full(self.shape[0] * self.shape[1], -1, dtype=np.int64)
        table[cell[order]] = order
        self.table = fill_empty_cells(table.reshape(self.shape), 2).ravel()
        self.box = (self.lo[0], self.lo[0] + span[0], self.lo[1], self.lo[1] + span[1])

    def _cell(self, x: FloatArray, y: FloatArray) -> np.ndarray:
        i = np.clip(np.floor((x - self.lo[0]) / self.step).astype(np.int64), 0, self.shape[0] - 1)
        j = np.clip(np.floor((y - self.lo[1]) / self.step).astype(np.int64), 0, self.shape[1] - 1)
        return i * self.shape[1] + j

    def _wrapped(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(u, v) with a step past a closed direction's end carried round to its start (a
        cylinder's or torus's seam: the seed may lie on the other side of it)."""
        u0, u1, v0, v1 = self.domain
        if self.closed[0]:
            u = np.where(u > u1, u - (u1 - u0), np.where(u < u0, u + (u1 - u0), u))
        if self.closed[1]:
            v = np.where(v > v1, v - (v1 - v0), np.where(v < v0, v + (v1 - v0), v))
        return u, v

    def _into_domain(self, u: FloatArray, v: FloatArray) -> tuple[FloatArray, FloatArray]:
        u0, u1, v0, v1 = self.domain
        u, v = self._wrapped(u, v)
        return np.clip(u, u0, u1), np.clip(v, v0, v1)

    def invert(self, x: FloatArray, y: FloatArray, tol: float
               ) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray]:
        """Newton on S_xy(u, v) = (x, y) from the lookup seeds: (indices of the points found on
        the face's material, their z, u and v)."""
        k = self.table[self._cell(x, y)]
        active = np.flatnonzero(k >= 0)
        if not len(active):
            return active, np.empty(0), np.empty(0), np.empty(0)
        k = k[active]
        dx = x[active] - self.xy[k, 0]
        dy = y[active] - self.xy[k, 1]
        inv = self.inv[k]
        u0, u1, v0, v1 = self.domain
        u, v = self._into_domain(self.u[k] + inv[:, 0, 0] * dx + inv[:, 0, 1] * dy,
                                 self.v[k] + inv[:, 1, 0] * dx + inv[:, 1, 1] * dy)
        max_step = 0.25 * max(u1 - u0, v1 - v0)
        hit_i, hit_z, hit_u, hit_v, hit_su, hit_sv = [], [], [], [], [], []
        pos = np.arange(len(active))
        xs, ys = x[active], y[active]
        for step in range(NEWTON_STEPS):
            if not len(pos):
                break
            p, su, sv = _orders(self.surface, u, v)
            rx = xs - p[:, 0]
            ry = ys - p[:, 1]
            ok = np.hypot(rx, ry) <= tol
            if ok.any():
                hit_i.append(pos[ok])
                hit_z.append(p[ok, 2])
                hit_u.append(u[ok])
                hit_v.append(v[ok])
                hit_su.append(np.linalg.norm(su[ok], axis=1))
                hit_sv.append(np.linalg.norm(sv[ok], axis=1))
            det = su[:, 0] * sv[:, 1] - sv[:, 0] * su[:, 1]
            det = np.where(np.abs(det) > 1e-300, det, 1e-300)
            du = (sv[:, 1] * rx - sv[:, 0] * ry) / det
            dv = (su[:, 0] * ry - su[:, 1] * rx) / det
            scale = np.minimum(1.0, max_step / np.maximum(np.hypot(du, dv), 1e-300))
            tu, tv = self._wrapped(u + scale * du, v + scale * dv)
            # held on the domain's edge by a step that leaves it: not on this face
            leaving = (((u == u0) & (tu < u0)) | ((u == u1) & (tu > u1))
                       | ((v == v0) & (tv < v0)) | ((v == v1) & (tv > v1)))
            keep = ~ok & ~(leaving & (step >= 2)) & np.isfinite(tu) & np.isfinite(tv)
            pos, xs, ys = pos[keep], xs[keep], ys[keep]
            u = np.clip(tu[keep], u0, u1)
            v = np.clip(tv[keep], v0, v1)
        if not hit_i:
            return np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0)
        idx = np.concatenate(hit_i)
        hz, hu, hv, nu, nv = (np.concatenate(a) for a in (hit_z, hit_u, hit_v, hit_su, hit_sv))
        inside = self.trim(hu, hv)
        # Within SEAM_FACTOR trim tolerances of the trim polyline (probed along u and v): the
        # polylines of two faces sharing an edge each lie within their tolerance of it, so a
        # cell centre can fall between them; it belongs to both faces' surfaces there.
        out = np.flatnonzero(~inside)
        if len(out):
            reach = SEAM_FACTOR * self.face.tolerance
            du = reach / np.maximum(nu[out], 1e-300)
            dv = reach / np.maximum(nv[out], 1e-300)
            u0, u1, v0, v1 = self.domain
            near = np.zeros(len(out), bool)
            for a, b in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                near |= self.trim(np.clip(hu[out] + a * du, u0, u1),
                                  np.clip(hv[out] + b * dv, v0, v1))
            inside[out[near]] = True
        return active[idx[inside]], hz[inside], hu[inside], hv[inside]


class FacesHeight:
    """The faces of a model prepared for height queries on Z-map grids of cell ``cell`` mm.

    >>> heights = FacesHeight(faces, cell=0.1)
    >>> hm = heights.grid(xs, ys)       # HeightMap of shape (len(ys), len(xs))
    """

    def __init__(self, faces: Sequence[Face], cell: float):
        faces = list(faces)
        if not faces:
            raise BSplineCAMError("the model has no faces")
        if not (math.isfinite(cell) and cell > 0):
            raise BSplineCAMError(f"cell size must be a positive length (mm), got {cell!r}")
        poles = np.concatenate([np.asarray(f.surface.poles, dtype=float).reshape(-1, 3)
                                for f in faces])
        self.size = float(np.linalg.norm(poles.max(axis=0) - poles.min(axis=0)))
        step = max(LOOKUP_CELLS * cell, LOOKUP_FRACTION * self.size)
        self.faces = faces
        seeds = [_FaceSeeds(f, k, step) for k, f in enumerate(faces)]
        # highest first: a cell above a face's top skips it
        self.seeds = sorted((s for s in seeds if not s.empty), key=lambda s: -s.zmax)
        self.tol = max(INSIDE_TOLERANCE_MM, 1e-10 * self.size)

    def bounds(self, selected_only: bool = False) -> tuple[float, float, float, float]:
        """(x_min, x_max, y_min, y_max) mm of the samples on the faces' material (within the
        lookup step of the true extent); a BSplineCAMError when there are none."""
        boxes = [s.bounds for s in self.seeds
                 if s.bounds is not None and (s.face.selected or not selected_only)]
        if not boxes:
            raise BSplineCAMError("no face of the model has material to measure")
        b = np.array(boxes)
        return (float(b[:, 0].min()), float(b[:, 1].max()), float(b[:, 2].min()),
                float(b[:, 3].max()))

    def points(self, x: FloatArray, y: FloatArray) -> HeightMap:
        """Top-most face above scattered points (flat arrays, mm)."""
        x = np.asarray(x, dtype=float).ravel()
        y = np.asarray(y, dtype=float).ravel()
        z = np.full(x.size, -np.inf)
        face = np.full(x.size, -1, dtype=np.int32)
        u = np.full(x.size, np.nan)
        v = np.full(x.size, np.nan)
        for s in self.seeds:
            x0, x1, y0, y1 = s.box
            cand = np.flatnonzero((x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
                                  & (z < s.zmax + self.tol))
            if not len(cand):
                continue
            idx, hz, hu, hv = s.invert(x[cand], y[cand], self.tol)
            better = hz > z[cand[idx]]
            at = cand[idx[better]]
            z[at], face[at], u[at], v[at] = hz[better], s.index, hu[better], hv[better]
        z[face < 0] = np.nan
        return HeightMap(z, face, u, v)

    def grid(self, xs: FloatArray, ys: FloatArray, threads: int | None = None) -> HeightMap:
        """Top-most face above each point (xs[j], ys[i]): arrays (len(ys), len(xs)).

        Bands of rows go to ``threads`` worker threads (``threads.numpy_threads()`` if None)."""
        xs = np.asarray(xs, dtype=float)
        ys = np.asarray(ys, dtype=float)
        ny, nx = len(ys), len(xs)
        z = np.empty((ny, nx))
        face = np.empty((ny, nx), dtype=np.int32)
        u = np.empty((ny, nx))
        v = np.empty((ny, nx))
        rows = max(1, CHUNK_CELLS // max(nx, 1))
        starts = range(0, ny, rows)

        def run(i0: int) -> None:
            sl = slice(i0, min(ny, i0 + rows))
            gx, gy = np.meshgrid(xs, ys[sl])
            hm = self.points(gx, gy)
            shape = gx.shape
            z[sl], face[sl] = hm.z.reshape(shape), hm.face.reshape(shape)
            u[sl], v[sl] = hm.u.reshape(shape), hm.v.reshape(shape)

        workers = max(1, min(numpy_threads() if threads is None else threads, len(starts)))
        if workers == 1:
            for i0 in starts:
                run(i0)
        else:
            with ThreadPoolExecutor(workers) as pool:
                list(pool.map(run, starts))
        return HeightMap(z, face, u, v)


__all__ = ["FacesHeight", "HeightMap"]
