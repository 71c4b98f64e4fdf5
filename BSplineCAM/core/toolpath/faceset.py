# SPDX-License-Identifier: LGPL-2.1-or-later
"""A certified ball drop-cutter over several trimmed NURBS faces (issue 11, item 3).

For a ball of radius R above q = (x, y), the lowest centre height that cuts no face is

    c(q) = max over face points p inside their trims with |p_xy - q| <= R of
           f(p) = p_z + sqrt(R^2 - |p_xy - q|^2)

(Chuang, Chen & Yau 2002; see :mod:`.dropcutter`).  Here c(q) is found by branch and bound over
the Bezier patches of every face ("The NURBS Book" A5.7 decomposition, :meth:`NurbsSurface.
bezier_patches`), split by de Casteljau's algorithm (A5.4-style halving of the homogeneous
control nets, so rational patches split exactly), and the returned height is within
``CERTIFY`` (1e-4 mm) of the true maximum *by a bound*, not by sample density:

* Upper bound of f over a sub-patch.  f is concave in the 3-D point p on the cylinder
  |p_xy - q| <= R (a linear term plus a hemisphere), so its tangent plane at any p0 lies above
  it: f(p) <= f(p0) + g . (p - p0), g = grad f(p0).  On the patch, g . (S(u, v) - p0) is a
  scalar Bezier patch with coefficients g . (P_k - p0) (a convex combination for rational
  patches, weights > 0); writing them as an affine function a(s, t) of the Greville abscissae
  plus a residual r_k, the bound is f(p0) + max over the patch's material of a + max r_k, and an
  affine function is largest at a vertex of the material: the corners of an untrimmed
  sub-patch, or, where a trim loop crosses it, the corners inside the trim and the points where
  the trim polyline's segments enter and leave the sub-patch (Liang-Barsky clipping).  With p0
  the control net's centroid the gap to the true maximum shrinks as the square of the
  sub-patch size.  It is combined (the smaller wins) with the box bound
  z_max + sqrt(R^2 - dist(q, box_xy)^2), which also prunes sub-patches out of reach.  Near
  the ball's rim f's slope across it grows as R / sqrt(R^2 - r^2) and both converge only
  linearly (the tangent plane is not used there, the box reaches past a trim towards the
  query): deep sub-patches there are also bounded by the material's own z and xy distance,
  from the affine part's values at the material's vertices and the residual
  (:func:`_material_reach`), which converge as the square of the sub-patch.
* Lower bound: f at actual surface points inside the trim (the corner control points of a
  Bezier patch lie on the surface; trim vertices are evaluated; on shallow sub-patches also the
  point at the control point nearest the query), so the answer never exceeds the true height.
* Local certificates, one per face (:meth:`FaceSet._face_regions`): around each face's best
  contact (Newton-polished, on a trim edge too) a box in (u, v) on which f cannot exceed the
  contact's value plus a proved excess, from the hemisphere's strong concavity and Taylor
  bounds on the hodographs; a contact on a domain side or a trim segment counts only the
  directions into the material (the polygon of the material in the box).  Sub-patches of that
  face inside the box are dropped once the bound is within ``CERTIFY`` of the query's best, and
  a sub-patch overlapping the box is split along the box's side.  So neither the face holding
  the maximum nor a tangent (G1) neighbour, whose own maximum lies on the shared edge nearly
  tied with it (a fillet and a top), is halved down to CERTIFY there.
* Level by level, every (query, sub-patch) pair whose upper bound exceeds its query's best lower
  bound by more than ``CERTIFY`` is halved along its longer side; the rest are dropped.  When
  none remain the best lower bound is certified.  Trim-edge contacts are the vertices on the
  trim polylines (exact edge contacts on the polyline, which is within the face's trim
  tolerance of the true edge).

Everything is vectorised over queries (chunks of ``QUERY_CHUNK``) and sub-patches.  The queries
of a pass meet the same sub-patches (the halving does not depend on the query), so a level's
pairs index a table of distinct sub-patches (:class:`.faceset_trims._Items`): each is split once and its
query-free bound terms computed once, and the trim classification and material vertices of a
sub-patch are remembered across levels and calls (:class:`.faceset_trims._RowCache`).

:class:`FaceSet` is the front; the pieces live in sibling modules, each one idea:
:mod:`.faceset_params` (tolerances and limits), :mod:`.faceset_bezier` (Bernstein bases, de
Casteljau splits, hulls and affine bounds), :mod:`.faceset_trims` (point-in-trim, trim
classification and material vertices per face), :mod:`.faceset_walls` (vertical check faces by
their borders), :mod:`.faceset_contacts` (Newton polish of contacts), :mod:`.faceset_regions`
(local certificates), :mod:`.faceset_bounds` (bounds over sub-patches),
:mod:`.faceset_subdivide` (splitting sub-patches), :mod:`.faceset_branch` (the branch and bound
over a chunk of queries), :mod:`.faceset_extent` (the faces' box) and :mod:`.faceset_probe`
(the point probe).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import kernels
from ..errors import BSplineCAMError, ParameterError
from ..geometry.faces import Face
from ..typing import FloatArray
from . import parallel
from .faceset_bezier import _bernstein as _bernstein
from .faceset_bezier import _bernstein_grid as _bernstein_grid
from .faceset_bezier import _material_reach as _material_reach
from .faceset_bezier import _rational_drift as _rational_drift
from .faceset_bezier import _sub_net as _sub_net
from .faceset_branch import drop_chunk
from .faceset_extent import extent
from .faceset_params import (
    CERTIFY,
    CHUNKS_PER_THREAD,
    MAX_CROWDED,
    PARALLEL_CHUNK,
    PARALLEL_CHUNK_NUMPY,
    QUERY_CHUNK,
)
from .faceset_params import CLASSIFY_CACHE as CLASSIFY_CACHE
from .faceset_params import CORNERS as CORNERS
from .faceset_params import CUT_MARGIN as CUT_MARGIN
from .faceset_params import HEIGHT_GRID as HEIGHT_GRID
from .faceset_params import HEIGHT_SEEDS as HEIGHT_SEEDS
from .faceset_params import HEIGHT_STEPS as HEIGHT_STEPS
from .faceset_params import MAX_DEPTH as MAX_DEPTH
from .faceset_params import MAX_OPEN as MAX_OPEN
from .faceset_params import MAX_SEGMENTS as MAX_SEGMENTS
from .faceset_params import POLISH_LEVELS as POLISH_LEVELS
from .faceset_params import POLISH_STEPS as POLISH_STEPS
from .faceset_params import REGION_EVERY as REGION_EVERY
from .faceset_params import REGION_SIZES as REGION_SIZES
from .faceset_params import REGION_TIE as REGION_TIE
from .faceset_params import RIM_DEPTH as RIM_DEPTH
from .faceset_params import RIM_FRACTION as RIM_FRACTION
from .faceset_params import RIM_ROUNDING_MM as RIM_ROUNDING_MM
from .faceset_params import SEED_DEPTH as SEED_DEPTH
from .faceset_params import TOUCH as TOUCH
from .faceset_probe import probe_heights
from .faceset_regions import face_regions
from .faceset_trims import _FaceData
from .faceset_walls import _vertical, _Walls

#: Counters of ``FaceSet.stats`` that keep the largest of the chunks' values (the others add).
_PEAK_STATS = frozenset({"levels"})
#: Holds "numba" once a drop-cutter of this process has run under the numba engine (its
#: kernels compiled).
_WARM: set = set()
#: Guards the sets' counters and box memos against callers on several threads of their own.
_STATS_LOCK = threading.Lock()
_BOX_LOCK = threading.Lock()


def spread(m: int, threads: int, least: int) -> int:
    """The threads a call of ``m`` queries runs on: ``threads`` if it holds at least two
    chunks of ``least`` queries, else 1."""
    return threads if m >= 2 * least else 1


def chunk_size(m: int, threads: int, least: int) -> int:
    """Queries per chunk of a call of ``m`` queries on ``threads`` threads: QUERY_CHUNK on one
    thread.  On more, the call is cut into equal chunks of at most QUERY_CHUNK, at least
    CHUNKS_PER_THREAD per thread where each still holds ``least`` queries (a call of a few
    thousand queries keeps the threads busy; each chunk has a fixed cost, and the queries of
    a chunk share their sub-patches), their number a multiple of the threads where that holds
    too."""
    if threads <= 1:
        return QUERY_CHUNK
    n = max(-(-m // QUERY_CHUNK), min(CHUNKS_PER_THREAD * threads, m // least), 1)
    even = -(-n // threads) * threads
    if m // even >= least:
        n = even
    return -(-m // n)


@dataclass
class DropResult:
    """Ball-centre heights and contacts of :meth:`FaceSet.drop_ball` (mm, parameters)."""

    centre: FloatArray
    face: np.ndarray
    u: FloatArray
    v: FloatArray
    gap: FloatArray


class FaceSet:
    """The faces a job sees: ``selected`` ones are machined, the others are check surfaces.

    >>> fs = FaceSet(faces)
    >>> tip, face, u, v, on_selected = fs.drop_ball(xy, radius=3.0)
    """

    def __init__(self, faces: Sequence[Face]):
        faces = list(faces)
        if not faces:
            raise BSplineCAMError("the face set is empty: select at least one face")
        self.faces = faces
        # Unselected vertical faces (walls) enter by their borders only (see _Walls)
        walls = [k for k, f in enumerate(faces) if not f.selected and _vertical(f.surface)]
        self.walls = _Walls([faces[k] for k in walls], walls)
        self.data = [_FaceData(f, k) for k, f in enumerate(faces) if k not in set(walls)]
        boxes = [(d.lo.min(axis=0), d.hi.max(axis=0)) for d in self.data] + self.walls.boxes
        lo = np.min([b[0] for b in boxes], axis=0)
        hi = np.max([b[1] for b in boxes], axis=0)
        self.size = float(np.linalg.norm(hi - lo))
        self.stats = {"pairs": 0, "levels": 0, "uncertified": 0}
        self._box_memo: dict = {}  # bounds() per selected_only: the faces never change

    def trim_test(self, k: int):
        """The inside test (u, v) -> bool array of face ``k`` (its index in ``faces``, not
        in ``data``: unselected walls have no entry there).  A wall has none."""
        for d in self.data:
            if d.index == k:
                return d.inside
        raise IndexError(f"face {k} is a wall or out of range: no trim test")

    def contact_points(self, face: np.ndarray, u: FloatArray, v: FloatArray) -> FloatArray:
        """The 3-D points (m, 3) where :meth:`drop_ball`'s contacts (face, u, v) touch the
        ball (NaN where face is -1): the surface at (u, v), or on a wall the point of its
        border chord the height was measured at (:meth:`_Walls.points`)."""
        face = np.asarray(face)
        u = np.asarray(u, dtype=float)
        v = np.asarray(v, dtype=float)
        out = np.full((len(face), 3), np.nan)
        walls = set(self.walls.owner.tolist())
        for k in np.unique(face[face >= 0]).tolist():
            idx = np.flatnonzero(face == k)
            if k in walls:
                out[idx] = self.walls.points(k, u[idx], v[idx])
            else:
                out[idx] = self.faces[k].surface.evaluate(u[idx], v[idx])
        return out

    # -- drop-cutter ---------------------------------------------------------------------------
    def drop_ball(self, xy, radius: float, selected_only: bool = False,
                  certify: float = CERTIFY, hint: tuple | None = None):
        """Tip heights (m,) (mm; NaN where the ball meets no face), contact face index (-1
        none), contact (u, v) and whether the contact lies on a selected face.

        The centre height c = tip + R is within ``certify`` mm (default ``CERTIFY``) below
        the true maximum of f over all faces (only the selected ones if ``selected_only``),
        by the bound of the module docstring.  A looser ``certify`` stops the branch and
        bound sooner (callers that add it back get a height never below the true one).
        ``hint`` (face, u, v), (m,) each, offers a contact near each query (a neighbour's
        answer; face -1 none) that starts its branch and bound (:mod:`.faceset_hints`):
        the height keeps its certificate whatever the hint.
        """
        R = float(radius)
        if not (math.isfinite(R) and R > 0):
            raise ParameterError(f"radius must be a finite number > 0 mm, got {radius!r}")
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        if not np.all(np.isfinite(q)):
            bad = int(np.flatnonzero(~np.isfinite(q).all(axis=1))[0])
            raise ParameterError(f"query point {bad} is not finite (mm): {q[bad].tolist()}")
        res = self.centre_heights(q, R, selected_only, certify, hint)
        tip = res.centre - R
        tip[~np.isfinite(tip)] = np.nan
        on_sel = np.zeros(len(q), bool)
        found = res.face >= 0
        sel = np.array([f.selected for f in self.faces])
        on_sel[found] = sel[res.face[found]]
        return tip, res.face, res.u, res.v, on_sel

    def centre_heights(self, q: FloatArray, R: float, selected_only: bool = False,
                       certify: float = CERTIFY, hint: tuple | None = None) -> DropResult:
        """Certified ball-centre heights (see :meth:`drop_ball`), chunk by chunk.

        A query's branch and bound meets only its own pairs, so the chunks are independent:
        with more than one thread (:mod:`.parallel`) they run on the shared pool, each
        writing its own slice and counting into its own counters, added to ``stats`` in the
        chunks' order afterwards; the answers and counters are those of one thread, bit for
        bit, whatever the chunk size (:func:`spread`, :func:`chunk_size`)."""
        m = len(q)
        if m == 0:
            e = np.zeros(0)
            return DropResult(e, np.zeros(0, int), e, e, e)
        if hint is not None:
            hint = tuple(np.asarray(a).reshape(-1) for a in hint)
            if len(hint) != 3 or any(len(a) != m for a in hint):
                raise ParameterError(f"hint must be (face, u, v) of {m} entries each, got "
                                     f"{[len(a) for a in hint]}")
        out = DropResult(np.full(m, -np.inf), np.full(m, -1), np.zeros(m), np.zeros(m),
                         np.zeros(m))
        data = [d for d in self.data if d.selected or not selected_only]
        # the numpy engine's small array operations hold the GIL: only large calls gain
        least = PARALLEL_CHUNK if kernels.engine().name == "numba" else PARALLEL_CHUNK_NUMPY
        threads = spread(m, parallel.threads(), least)
        size = chunk_size(m, threads, least)
        starts = range(0, m, size)

        def one(k: int) -> dict:
            sl = slice(starts[k], min(m, starts[k] + size))
            stats = dict.fromkeys(self.stats, 0)
            h = None if hint is None else tuple(a[sl] for a in hint)
            r = self._chunk(q[sl], R, data, not selected_only, certify, stats, h)
            out.centre[sl], out.face[sl], out.u[sl], out.v[sl], out.gap[sl] = r
            return stats

        # the process's first drop under the numba engine compiles its kernels: on one
        # thread, before the others start
        cold = kernels.engine().name == "numba" and not _WARM
        counts = parallel.run(one, len(starts), first_here=cold, alone=threads <= 1)
        if cold:
            _WARM.add("numba")
        with _STATS_LOCK:
            for stats in counts:
                for key, value in stats.items():
                    self.stats[key] = (max(self.stats[key], value) if key in _PEAK_STATS
                                       else self.stats[key] + value)
        return out

    def _chunk(self, q: FloatArray, R: float, data: list, walls: bool = True,
               certify: float = CERTIFY, stats: dict | None = None,
               hint: tuple | None = None) -> tuple:
        """Certified heights of one chunk of queries (:func:`.faceset_branch.drop_chunk`),
        counted into ``stats`` (default: the set's), with this module's MAX_CROWDED read at
        each call."""
        return drop_chunk(self.data, self.walls, self.stats if stats is None else stats, q, R,
                          data, walls, certify, MAX_CROWDED, hint)

    #: The local certificate of a face around contacts (:func:`.faceset_regions.face_regions`):
    #: ``(d, qq, R, u, v, limit) -> (found, box, excess)``.
    _face_regions = staticmethod(face_regions)

    # -- point probe ---------------------------------------------------------------------------
    def height(self, xy, selected_only: bool = False):
        """Top-most face point above each xy (a point probe): (z, face, u, v, inside).

        Per face, the xy map S_xy(u, v) = q is inverted by Newton's method from the
        HEIGHT_SEEDS nearest (in xy) of a HEIGHT_GRID x HEIGHT_GRID sample of every patch whose
        box holds q (several: near a vertical bit the map folds); a root counts when it lies in
        the patch's domain (to 1e-9) within the trim and reproduces q to 1e-9 of the set's size.
        z is NaN and ``inside`` False where no face lies above.
        """
        return probe_heights(self.data, self.size, xy, selected_only)

    # -- bounds --------------------------------------------------------------------------------
    def bounds(self, selected_only: bool = True) -> tuple[FloatArray, FloatArray]:
        """(lo, hi) 3-vectors (mm): a box enclosing the faces (inside their trims), each side
        found by branch and bound on the Bezier boxes to within 1e-6 of the set's size
        (computed once per ``selected_only``: the op's extent and its passes both ask)."""
        key = bool(selected_only)
        with _BOX_LOCK:
            if key not in self._box_memo:
                self._box_memo[key] = extent(self.data, self.walls, self.size, key)
            lo, hi = self._box_memo[key]
        return lo.copy(), hi.copy()


__all__ = ["CERTIFY", "DropResult", "FaceSet"]
