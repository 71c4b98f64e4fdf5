# SPDX-License-Identifier: LGPL-2.1-or-later
"""Trims of the drop-cutter's faces (:mod:`.faceset`): point-in-trim tests, trim segments
filed by band and by grid cell, Liang-Barsky clipping, and per face its Bezier patches with
each sub-patch's trim classification (outside, inside, straddling) and the vertices of its
material, remembered per distinct sub-patch.  Under the numba engine (:mod:`..kernels`) the
clipping, the classification, the vertices and the point-in-trim test run as compiled loops
(:mod:`..kernels.faceset_trim_kernels`), the same arithmetic and the same answers."""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..geometry.faces import Face
from ..geometry.surface import SECOND_ORDER
from ..kernels import faceset_trim_kernels as tk
from ..numeric import clamp
from ..typing import FloatArray
from .faceset_bezier import _bernstein_grid
from .faceset_params import CLASSIFY_CACHE, CORNERS, MAX_SEGMENTS

_clip_kernel = kernels.Kernel(tk.clip)
_listed_kernel = kernels.Kernel(tk.classify_listed)
_all_kernel = kernels.Kernel(tk.classify_all)
_inside_kernel = kernels.Kernel(tk.inside)
_vertices_kernel = kernels.Kernel(tk.vertices)
#: no clamping of the points of :meth:`_Bands.__call__`
_ANYWHERE = np.array([-np.inf, np.inf, -np.inf, np.inf])


def _clip(seg: FloatArray, box: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
    """Liang-Barsky clipping of segments (n, K, 4) (u0, v0, u1, v1) by boxes (n, 4)
    (u0, u1, v0, v1): hit mask (n, K) and the clipped end points (n, K, 2) each."""
    if kernels.use_numba():
        try:
            return _clip_kernel(np.ascontiguousarray(seg, dtype=float),
                                np.ascontiguousarray(box, dtype=float))
        except kernels.KernelUnavailable:
            pass
    a = seg[..., :2]
    d = seg[..., 2:] - a
    t0 = np.zeros(seg.shape[:2])
    t1 = np.ones(seg.shape[:2])
    hit = np.isfinite(seg[..., 0])
    with np.errstate(divide="ignore", invalid="ignore"):
        for c, lo, hi in ((0, box[:, 0], box[:, 1]), (1, box[:, 2], box[:, 3])):
            dc = d[..., c]
            ac = a[..., c]
            flat = dc == 0
            hit &= ~(flat & ((ac < lo[:, None]) | (ac > hi[:, None])))
            ta = (lo[:, None] - ac) / dc
            tb = (hi[:, None] - ac) / dc
            tlo = np.where(flat, -np.inf, np.minimum(ta, tb))
            thi = np.where(flat, np.inf, np.maximum(ta, tb))
            t0 = np.maximum(t0, tlo)
            t1 = np.minimum(t1, thi)
    hit &= t0 <= t1
    return hit, a + t0[..., None] * d, a + t1[..., None] * d


class _Bands:
    """Point-in-trim test of :func:`faces.inside` (even-odd, pnpoly's half-open crossing rule,
    so the same answer) with the trim segments filed by horizontal bands of v: a point meets
    only the segments of its band, which holds every segment that can straddle its v."""

    def __init__(self, edges: FloatArray, bands: int = 256):
        keep = edges[:, 1] != edges[:, 3]  # horizontal edges never straddle the ray
        e = edges[keep]
        lo = np.minimum(e[:, 1], e[:, 3])
        hi = np.maximum(e[:, 1], e[:, 3])
        self.v0 = float(lo.min()) if len(e) else 0.0
        span = float(hi.max()) - self.v0 if len(e) else 1.0
        self.n = bands
        self.h = span / bands if span > 0 else 1.0
        first = self._band(lo)
        last = self._band(hi)
        rows = [[] for _ in range(bands)]
        for k, (f, g) in enumerate(zip(first, last)):
            for b in range(f, g + 1):
                rows[b].append(k)
        width = max(1, max(len(r) for r in rows))
        table = np.full((bands, width, 4), np.nan)
        for b, r in enumerate(rows):
            table[b, : len(r)] = e[r]
        self.table = table

    def _band(self, v: FloatArray) -> np.ndarray:
        return clamp(np.floor((v - self.v0) / self.h), 0, self.n - 1).astype(np.intp)

    def __call__(self, u: FloatArray, v: FloatArray, dom: FloatArray = _ANYWHERE) -> np.ndarray:
        """Whether each (u, v) lies inside (the points clamped into ``dom``, (u lo, u hi,
        v lo, v hi), first)."""
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        if kernels.use_numba():
            try:
                return self._compiled(u, v, dom)
            except kernels.KernelUnavailable:
                pass
        if dom is not _ANYWHERE:
            u = clamp(u, dom[0], dom[1])
            v = clamp(v, dom[2], dom[3])
        shape = np.broadcast(u, v).shape
        pu, pv = (np.broadcast_to(a, shape).ravel() for a in (u, v))
        seg = self.table[self._band(pv)]  # (m, width, 4); NaN rows never straddle
        u0, v0, u1, v1 = seg[..., 0], seg[..., 1], seg[..., 2], seg[..., 3]
        qv = pv[:, None]
        straddle = (v0 > qv) != (v1 > qv)
        with np.errstate(invalid="ignore", divide="ignore"):
            cross = u0 + (qv - v0) * ((u1 - u0) / (v1 - v0))
        hits = straddle & (pu[:, None] < cross)
        return ((np.count_nonzero(hits, axis=1) % 2) == 1).reshape(shape)

    def _compiled(self, u: FloatArray, v: FloatArray, dom: FloatArray) -> np.ndarray:
        shape = np.broadcast(u, v).shape
        pu, pv = (np.ascontiguousarray(np.broadcast_to(a, shape).ravel()) for a in (u, v))
        return _inside_kernel(self.table, self.v0, self.h, self.n, pu, pv,
                              np.asarray(dom, dtype=float)).reshape(shape)


class _SegmentGrid:
    """Trim segments filed by the cells of a G x G grid over the domain that their boxes
    meet: the segments near a point are found among its cell's few."""

    def __init__(self, edges: FloatArray, domain, cells: int = 64):
        (u0, u1), (v0, v1) = domain
        self.edges = edges
        self.o = np.array([u0, v0])
        self.h = np.array([(u1 - u0) / cells or 1.0, (v1 - v0) / cells or 1.0])
        self.g = cells
        rows: dict = {}
        if len(edges):
            lo = self._cell(np.minimum(edges[:, :2], edges[:, 2:]) - 1e-9 * self.h * cells)
            hi = self._cell(np.maximum(edges[:, :2], edges[:, 2:]) + 1e-9 * self.h * cells)
            for k in range(len(edges)):
                for i in range(lo[k, 0], hi[k, 0] + 1):
                    for j in range(lo[k, 1], hi[k, 1] + 1):
                        rows.setdefault(i * cells + j, []).append(k)
        width = max([len(r) for r in rows.values()] + [1])
        self.table = np.full((cells * cells, width), -1, dtype=np.intp)
        for c, r in rows.items():
            self.table[c, : len(r)] = r

    def _cell(self, pts: FloatArray) -> np.ndarray:
        return clamp(np.floor((pts - self.o) / self.h), 0, self.g - 1).astype(np.intp)

    def near(self, u: FloatArray, v: FloatArray, eps: float):
        pts = np.column_stack([u, v])
        c = self._cell(pts)
        cand = self.table[c[:, 0] * self.g + c[:, 1]]  # (n, width)
        qi, slot = np.nonzero(cand >= 0)
        si = cand[qi, slot]
        if len(si) == 0:
            return qi, si
        e = self.edges[si]
        a, d = e[:, :2], e[:, 2:] - e[:, :2]
        L2 = (d * d).sum(axis=1)
        t = clamp(((pts[qi] - a) * d).sum(axis=1) / np.where(L2 > 0, L2, 1.0), 0.0, 1.0)
        r = pts[qi] - (a + t[:, None] * d)
        keep = (r * r).sum(axis=1) <= eps * eps
        return qi[keep], si[keep]


class _RowCache:
    """Answers of a function of a row alone, remembered by the row's bytes: ``cache(keys,
    compute)`` returns ``compute(rows)`` (a tuple of arrays, one row per index of ``rows``)
    for every row of ``keys`` (n, w), computing each distinct row not seen before once.  At
    most CLASSIFY_CACHE rows are kept (then it starts afresh).

    The drop-cutter's chunks share a face's caches from several threads (:mod:`.parallel`):
    a lock guards the table, and ``compute`` runs outside it (two threads may then compute
    the same new row; its answer is the same, so either is kept)."""

    def __init__(self):
        self.index: dict = {}
        self.store: list = []
        self.size = 0
        self._lock = threading.Lock()

    def __call__(self, keys: FloatArray, compute) -> tuple:
        keys = np.ascontiguousarray(keys, dtype=float)
        rows = keys.view(np.dtype((np.void, keys.itemsize * keys.shape[1]))).ravel()
        uniq, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
        ukeys = uniq.tolist()
        inverse = inverse.ravel()
        with self._lock:
            get = self.index.get
            pos = np.fromiter((get(k, -1) for k in ukeys), np.intp, len(ukeys))
            todo = np.flatnonzero(pos < 0)
            if len(todo) == 0:
                at = pos[inverse]
                return tuple(g[at] for g in self.store)
            known = np.flatnonzero(pos >= 0)
            seen = [g[pos[known]] for g in self.store] if len(known) else []
        done = compute(first[todo])
        answers = []
        for k, a in enumerate(done):
            each = np.empty((len(ukeys),) + a.shape[1:], a.dtype)
            each[todo] = a
            if len(known):
                each[known] = seen[k]
            answers.append(each)
        with self._lock:
            self._remember(ukeys, answers)
        return tuple(a[inverse] for a in answers)

    def _remember(self, ukeys: list, answers: list) -> None:
        """File the rows ``ukeys`` not yet known with their ``answers`` (caller holds the lock)."""
        get = self.index.get
        todo = [k for k, key in enumerate(ukeys) if get(key, -1) < 0]
        if not todo:
            return
        if self.size + len(todo) > CLASSIFY_CACHE:
            self.index, self.store, self.size = {}, [], 0
            todo = list(range(len(ukeys)))
        need = self.size + len(todo)
        if not self.store or need > len(self.store[0]):
            cap = max(2 * need, 1024)
            grown = [np.empty((cap,) + a.shape[1:], a.dtype) for a in answers]
            for g, old in zip(grown, self.store):
                g[: self.size] = old[: self.size]
            self.store = grown
        for g, a in zip(self.store, answers):
            g[self.size:need] = a[todo]
        self.index.update(zip([ukeys[k] for k in todo], range(self.size, need)))
        self.size = need


@dataclass
class _Items:
    """(query, sub-patch) pairs of one face: homogeneous nets, parameter boxes, trim state.

    The nets live in a table ``nets`` (N, 4, p+1, q+1) that the pairs index by ``node``: the
    queries of a pass share their sub-patches, so each is split and bounded (its query-free
    part) once, not once per query.  ``status`` 1: wholly inside the trim, 2: straddling it.
    ``segs`` (n, K) indices of the trim segments crossing a straddling sub-patch (-1 padding;
    row all -2: more than K, test all).
    """

    query: np.ndarray
    node: np.ndarray
    nets: FloatArray
    box: FloatArray
    depth: np.ndarray
    status: np.ndarray
    segs: np.ndarray

    @property
    def net(self) -> FloatArray:
        """Each pair's net (n, 4, p+1, q+1)."""
        return self.nets[self.node]

    def take(self, keep: np.ndarray) -> _Items:
        return _Items(self.query[keep], self.node[keep], self.nets, self.box[keep],
                      self.depth[keep], self.status[keep], self.segs[keep])


class _FaceData:
    """Per face: Bezier nets of its patches, their boxes and trim classification."""

    def __init__(self, face: Face, index: int):
        self.face = face
        self.index = index
        s = face.surface
        bez = s.bezier_patches()
        self.p, self.q = s.degree_u, s.degree_v
        nu, nv = bez.points.shape[:2]
        hom = np.concatenate([bez.points * bez.weights[..., None], bez.weights[..., None]], -1)
        # coordinate planes (n, 4, p+1, q+1): reductions run over contiguous memory
        self.nets = np.ascontiguousarray(
            hom.reshape(nu * nv, self.p + 1, self.q + 1, 4).transpose(0, 3, 1, 2))
        self.nu, self.nv = nu, nv
        self.u_ends, self.v_ends = bez.u[:, 1].copy(), bez.v[:, 1].copy()
        uu, vv = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        self.boxes = np.column_stack([bez.u[uu.ravel(), 0], bez.u[uu.ravel(), 1],
                                      bez.v[vv.ravel(), 0], bez.v[vv.ravel(), 1]])
        pts = bez.points.reshape(nu * nv, -1, 3)
        self.lo, self.hi = pts.min(axis=1), pts.max(axis=1)
        self._bands = _Bands(face._edges)
        (u0, u1), (v0, v1) = s.domain
        eu, ev = 1e-12 * (u1 - u0), 1e-12 * (v1 - v0)
        self._inner = np.array([u0 + eu, u1 - eu, v0 + ev, v1 - ev])
        # Segments (u0, v0, u1, v1) that bound the material inside the domain: those lying on
        # the domain's own sides bound nothing more than the surface's edge does (an untrimmed
        # face has none left, so none of its sub-patches straddles).
        (du0, du1), (dv0, dv1) = s.domain
        e = face._edges
        eps = 1e-12 * max(du1 - du0, dv1 - dv0)
        on_side = np.zeros(len(e), bool)
        for c, side in ((0, du0), (0, du1), (1, dv0), (1, dv1)):
            on_side |= (np.abs(e[:, c] - side) <= eps) & (np.abs(e[:, c + 2] - side) <= eps)
        self.edges = np.ascontiguousarray(e[~on_side], dtype=float)
        self._elo = np.minimum(self.edges[:, :2], self.edges[:, 2:])
        self._ehi = np.maximum(self.edges[:, :2], self.edges[:, 2:])
        self._pad = 1e-9 * max(du1 - du0, dv1 - dv0)
        self._grid = _SegmentGrid(self.edges, face.surface.domain)
        self._known = _RowCache()  # classify's answers by row
        self._known_vertices = _RowCache()  # vertices' answers by row
        self._point_pack = None  # see point_pack
        self._derivative_pack = None  # see derivative_pack
        self.design = _bernstein_grid(self.p, self.q)
        self.pinv = np.linalg.pinv(self.design)  # (3, K)
        # the same, contiguous, and the corner control points' flat indices, for the kernels
        self._pinv = np.ascontiguousarray(self.pinv)
        self._design = np.ascontiguousarray(self.design)
        self._corners = np.array([0, self.p * (self.q + 1), self.q,
                                  self.p * (self.q + 1) + self.q], dtype=np.int64)
        status, segs = self.classify(self.boxes, np.full((len(self.boxes), 1), -2))
        self.root_status, self.root_segs = status, segs
        keep = status > 0
        self.roots = np.flatnonzero(keep)

    def point_pack(self) -> tuple:
        """The compiled point evaluation's arguments for this face's surface (its scattered
        kernel's pack of order (0, 0), the quotient rule's index, the domain and its
        tolerances: :mod:`..kernels.nurbs_eval`), for kernels that evaluate points."""
        if self._point_pack is None:
            s = self.face.surface
            self._point_pack = (*s._pack(((0, 0),)), np.zeros((1, 1), dtype=np.int64),
                                np.array(s._tolerances, dtype=float))
        return self._point_pack

    def derivative_pack(self) -> tuple:
        """The compiled derivatives' arguments for this face's surface: the rows of the
        point, Su, Sw, Suu, Suw, Sww among the orders the surface's kernels compute (with the
        quotient rule's lower ones for a rational surface), then the scattered kernel's pack of
        those orders, the quotient rule's index and the domain and its tolerances
        (:mod:`..kernels.nurbs_eval`)."""
        if self._derivative_pack is None:
            s = self.face.surface
            if s.rational:
                needed = tuple(sorted({(a, b) for du, dw in SECOND_ORDER
                                       for a in range(du + 1) for b in range(dw + 1)}))
            else:
                needed = SECOND_ORDER
            top = max(max(a, b) for a, b in needed)
            index = np.zeros((top + 1, top + 1), dtype=np.int64)
            for k, (a, b) in enumerate(needed):
                index[a, b] = k
            rows = np.array([needed.index(o) for o in SECOND_ORDER], dtype=np.int64)
            self._derivative_pack = (rows, *s._pack(needed), index,
                                     np.array(s._tolerances, dtype=float))
        return self._derivative_pack

    def inside(self, u: FloatArray, v: FloatArray) -> np.ndarray:
        """Whether (u, v) lies in the material: the trim test of :func:`faces.inside`, with points
        on the domain's own sides (where pnpoly's half-open rule would put the right and top
        sides outside) moved a hair into the domain first."""
        return self._bands(u, v, self._inner)

    def segments_at(self, u: FloatArray, v: FloatArray, eps: float):
        """(point index, segment index) of the trim segments within ``eps`` of each (u, v)."""
        return self._grid.near(u, v, eps)

    @property
    def selected(self) -> bool:
        return bool(self.face.selected)

    def classify(self, box: FloatArray, parent_segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Status (0 outside, 1 inside, 2 straddling) and crossing segments of boxes (n, 4)
        whose parents were crossed by ``parent_segs`` (rows of -2: by any segment).

        A row's answer depends on the row alone, and the queries of a pass meet the same
        sub-patches (halving is the same for every query): rows are classified once each
        (duplicates within a call share the answer, earlier calls' answers are remembered:
        :class:`_RowCache`), so the trim test, which at shallow depth clips every one of the
        face's segments, runs per sub-patch, not per query."""
        if len(box) == 0:
            return np.zeros(0, np.int8), np.full((0, MAX_SEGMENTS), -1, dtype=np.int64)
        if kernels.use_numba() and not (parent_segs[:, 0] == -2).any():
            # compiled, a row crossed by listed segments costs less than finding it among
            # the known ones
            return self._classify(box, parent_segs)
        return self._known(np.column_stack([box, parent_segs]),
                           lambda rows: self._classify(box[rows], parent_segs[rows]))

    def _classify(self, box: FloatArray, parent_segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`classify` of every row (no sharing)."""
        n = len(box)
        status = np.zeros(n, np.int8)
        segs = np.full((n, MAX_SEGMENTS), -1, dtype=np.int64)
        if n == 0:
            return status, segs
        every = parent_segs[:, 0] == -2
        E = len(self.edges)
        if kernels.use_numba():
            try:
                return self._compiled_classify(box, parent_segs, every, status, segs)
            except kernels.KernelUnavailable:
                pass
        counts = np.zeros(n, int)
        # sub-patches whose parent was crossed by many segments: test all of them, those whose
        # boxes (padded against rounding) meet the sub-patch's by Liang-Barsky
        idx_all = np.flatnonzero(every)
        chunk = max(1, 4_000_000 // max(E, 1))
        for start in range(0, len(idx_all), chunk):
            rows = idx_all[start:start + chunk]
            b = box[rows]
            pad = self._pad
            near = ((self._elo[None, :, 0] <= b[:, 1:2] + pad)
                    & (self._ehi[None, :, 0] >= b[:, 0:1] - pad)
                    & (self._elo[None, :, 1] <= b[:, 3:4] + pad)
                    & (self._ehi[None, :, 1] >= b[:, 2:3] - pad))
            ri, ei = np.nonzero(near)  # row-major: each row's segments in ascending order
            hit, _, _ = _clip(self.edges[ei][:, None, :], b[ri])
            hr, he = ri[hit[:, 0]], ei[hit[:, 0]]
            cnt = np.bincount(hr, minlength=len(rows))
            counts[rows] = cnt
            rank = np.arange(len(hr)) - np.searchsorted(hr, hr)
            # each row's first MAX_SEGMENTS hit segment ids (-1 padding), -2 rows for more
            small = rank < MAX_SEGMENTS
            segs[rows[hr[small]], rank[small]] = he[small]
            segs[rows[cnt > MAX_SEGMENTS]] = -2
        rest = np.flatnonzero(~every)
        if len(rest) and E:
            ps = parent_segs[rest]
            valid = ps >= 0
            seg = np.where(valid[..., None], self.edges[np.maximum(ps, 0)], np.nan)
            hit, _, _ = _clip(seg, box[rest])
            counts[rest] = hit.sum(axis=1)
            # compact the surviving ids to the front of each row
            order = np.argsort(~hit, axis=1, kind="stable")
            kept = np.take_along_axis(np.where(hit, ps, -1), order, axis=1)
            segs[rest, : kept.shape[1]] = kept
        return self._status(box, counts, status, segs)

    def _compiled_classify(self, box: FloatArray, parent_segs: np.ndarray, every: np.ndarray,
                           status: np.ndarray, segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_classify` with the clipping loops compiled."""
        counts = np.zeros(len(box), np.int64)
        box = np.ascontiguousarray(box, dtype=float)
        idx_all = np.flatnonzero(every)
        if len(idx_all):
            counts[idx_all], segs[idx_all] = _all_kernel(self.edges, self._elo, self._ehi,
                                                         self._pad, box[idx_all], MAX_SEGMENTS)
        rest = np.flatnonzero(~every)
        if len(rest) and len(self.edges):
            ps = np.ascontiguousarray(parent_segs[rest], dtype=np.int64)
            counts[rest], segs[rest, : ps.shape[1]] = _listed_kernel(self.edges, ps, box[rest])
        return self._status(box, counts, status, segs)

    def _status(self, box: FloatArray, counts: np.ndarray, status: np.ndarray,
                segs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Status 2 where ``counts`` of crossing segments, else 1 or 0 by the trim test at the
        box's middle, in place; and ``segs``."""
        crossed = counts > 0
        status[crossed] = 2
        clear = np.flatnonzero(~crossed)
        if len(clear):
            b = box[clear]
            mid = self.inside(0.5 * (b[:, 0] + b[:, 1]), 0.5 * (b[:, 2] + b[:, 3]))
            status[clear] = np.where(mid, 1, 0)
        return status, segs

    def vertices(self, items: _Items) -> tuple[FloatArray, np.ndarray]:
        """Local (s, t) in [0, 1]^2 of the candidate vertices of the material in straddling
        sub-patches (n, 4 + 2K, 2) and their validity (n, 4 + 2K): the 4 corners (valid when
        inside the trim), then the clipped trim segment end points.  They depend on the box
        and its segments alone: computed once per distinct sub-patch (see :class:`_RowCache`)."""
        if len(items.query) == 0 or kernels.use_numba():
            # compiled, a row's vertices cost less than finding it among the known ones
            return self._vertices(items.box, items.segs)
        return self._known_vertices(np.column_stack([items.box, items.segs]),
                                    lambda rows: self._vertices(items.box[rows], items.segs[rows]))

    def _vertices(self, box: FloatArray, ps: np.ndarray) -> tuple[FloatArray, np.ndarray]:
        """:meth:`vertices` of every row (no sharing)."""
        if kernels.use_numba():
            try:
                st, oks = _vertices_kernel(self.edges, np.ascontiguousarray(box, dtype=float),
                                           np.ascontiguousarray(ps, dtype=np.int64))
                corners = self.inside(box[:, [0, 1, 0, 1]], box[:, [2, 2, 3, 3]])
                return st, np.concatenate([corners, oks], axis=1)
            except kernels.KernelUnavailable:
                pass
        n = len(box)
        st = np.zeros((n, 4 + 2 * MAX_SEGMENTS, 2))
        ok = np.zeros((n, 4 + 2 * MAX_SEGMENTS), bool)
        st[:, :4] = CORNERS
        du = box[:, 1] - box[:, 0]
        dv = box[:, 3] - box[:, 2]
        ok[:, :4] = self.inside(box[:, [0, 1, 0, 1]], box[:, [2, 2, 3, 3]])
        valid = ps >= 0
        seg = np.where(valid[..., None], self.edges[np.maximum(ps, 0)], np.nan)
        hit, e0, e1 = _clip(seg, box)
        pts = np.concatenate([e0, e1], axis=1)  # (n, 2K, 2)
        loc = np.empty_like(pts)
        loc[..., 0] = (pts[..., 0] - box[:, :1]) / du[:, None]
        loc[..., 1] = (pts[..., 1] - box[:, 2:3]) / dv[:, None]
        st[:, 4:] = clamp(np.nan_to_num(loc), 0.0, 1.0)
        ok[:, 4:] = np.concatenate([hit, hit], axis=1)
        return st, ok
