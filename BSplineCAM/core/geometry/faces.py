# SPDX-License-Identifier: LGPL-2.1-or-later
"""Faces: a NURBS surface and its trim, the unit that toolpaths take (numpy only).

A face of a solid is its surface bounded by wires.  Here the wires are closed polylines in
the surface's parameter space (u, v): ``outer`` bounds the material, each of ``holes`` cuts
some away.  A parameter point is on the material when it lies inside an odd number of loops
(even-odd rule over outer + holes), so the orientation of a loop does not matter.

The polylines come from the wires' exact parameter curves (pcurves) by :func:`densify_edge`:
the image on the surface of every straight parameter segment stays within ``tolerance`` mm of
the true edge (chord error measured in 3-D, model units mm), so a toolpath clipped by the
polyline is clipped at most ``tolerance`` from the true boundary.

The surface's normal ``Su × Sv`` is the outward normal of the solid (the machined side): the
app layer reverses v for a face that OCCT holds as Reversed and records it in ``flipped_v``,
with OCCT's v = v0 + v1 - v.

Faces cross process boundaries (FreeCAD → venv worker) as plain JSON data:
:func:`to_dict` and :func:`face_from_dict`, the latter strict about every key and value.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Union

import numpy as np

from ..errors import BSplineCAMError
from ..typing import ArrayLike, FloatArray
from .nurbs import NurbsSurface

#: Name and version written into every face's plain-data form.
FORMAT = "bsplinecam-face"
VERSION = 1

#: Default chord tolerance of the trim polylines in mm.
DEFAULT_TOLERANCE = 1e-3

#: A normal's z below -UP_TOLERANCE points down; above +UP_TOLERANCE, up (see :func:`reach`).
UP_TOLERANCE = 1e-9
#: The smallest model tolerance (mm) :func:`reach` assumes: OCCT's Precision::Confusion().
MODEL_TOLERANCE_FLOOR = 1e-7
#: Sample rows per side of a face in :func:`reach`'s height estimate (``sample_points``).
REACH_SAMPLES = 15


class FaceError(BSplineCAMError):
    """A face that cannot be machined as given: bad trim, bad data, failed conversion."""


@dataclass(frozen=True, eq=False)
class Face:
    """A trimmed NURBS face of a model.

    ``surface``  the NurbsSurface (mm), normal ``Su × Sv`` outward.
    ``outer``    (k, 2) closed polyline in (u, v), first point repeated last.
    ``holes``    tuple of (k, 2) closed polylines.
    ``index``    1-based number of the face in its source shape (``name`` is "Face<index>").
    ``selected`` True: machined; False: a check surface, never cut.
    ``flipped_v`` the surface's v was reversed against OCCT's (a Reversed face).
    ``source``   what the surface was before conversion ("BSplineSurface", "Cylinder", ...).
    ``deviation`` max distance (mm) of the NURBS from OCCT's evaluation of the original.
    ``tolerance`` chord tolerance (mm) of the trim polylines.
    """

    surface: object
    outer: FloatArray
    holes: tuple[FloatArray, ...] = ()
    index: int = 1
    name: str = ""
    selected: bool = True
    flipped_v: bool = False
    source: str = "BSplineSurface"
    deviation: float = 0.0
    tolerance: float = DEFAULT_TOLERANCE
    _edges: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", f"Face{self.index}")
        outer = np.array(self.outer, dtype=float)
        holes = tuple(np.array(h, dtype=float) for h in self.holes)
        object.__setattr__(self, "outer", outer)
        object.__setattr__(self, "holes", holes)
        validate_trim(outer, holes, self.name)
        edges = [np.concatenate([loop[:-1], loop[1:]], axis=1) for loop in (outer, *holes)]
        object.__setattr__(self, "_edges", np.concatenate(edges))

    @property
    def loops(self) -> tuple[FloatArray, ...]:
        return (self.outer, *self.holes)

    def bounds(self) -> tuple[float, float, float, float]:
        """(u0, u1, v0, v1) of the outer loop: the trimmed face's parameter box."""
        lo, hi = self.outer.min(axis=0), self.outer.max(axis=0)
        return float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])


def inside(face: Face, u: ArrayLike, v: ArrayLike) -> np.ndarray:
    """True where (u, v) lies on the face's material: even-odd rule over outer and holes.

    Vectorised over points (any matching shapes); a point exactly on a loop may go either
    way.  Crossing test after W. R. Franklin's pnpoly (half-open in v).
    """
    u = np.asarray(u, dtype=float)
    v = np.asarray(v, dtype=float)
    shape = np.broadcast(u, v).shape
    pu, pv = (np.broadcast_to(a, shape).ravel() for a in (u, v))
    e = face._edges
    u0, v0, u1, v1 = e[:, 0], e[:, 1], e[:, 2], e[:, 3]
    # Drop horizontal edges, they never straddle the ray.
    keep = v0 != v1
    u0, v0, u1, v1 = u0[keep], v0[keep], u1[keep], v1[keep]
    slope = (u1 - u0) / (v1 - v0)
    result = np.zeros(pu.size, dtype=bool)
    chunk = max(1, 2_000_000 // max(1, u0.size))
    for start in range(0, pu.size, chunk):
        qu = pu[start:start + chunk, None]
        qv = pv[start:start + chunk, None]
        straddle = (v0 > qv) != (v1 > qv)
        cross_u = u0 + (qv - v0) * slope
        hits = straddle & (qu < cross_u)
        result[start:start + chunk] = (np.count_nonzero(hits, axis=1) % 2) == 1
    return result.reshape(shape)


def grid_points(face: Face, count: int = 15) -> tuple[FloatArray, float]:
    """(N, 2) cell centres of a ``count`` x ``count`` grid over the face's parameter box that
    lie inside its trim (a 4x finer grid if fewer than 10 do), and the parameter area of one
    cell: sum |Su x Sv| over the points times it estimates the face's area (mm^2)."""
    u0, u1, v0, v1 = face.bounds()
    for n in (count, 4 * count):
        t = (np.arange(n) + 0.5) / n
        uu, vv = np.meshgrid(u0 + (u1 - u0) * t, v0 + (v1 - v0) * t, indexing="ij")
        keep = inside(face, uu, vv)
        if np.count_nonzero(keep) >= 10:
            break
    return np.stack([uu[keep], vv[keep]], axis=1), (u1 - u0) * (v1 - v0) / (n * n)


def sample_points(face: Face, count: int = 15, boundary: int = 400) -> FloatArray:
    """(N, 2) parameter points of a face: its :func:`grid_points` and up to ``boundary``
    points of its trim polylines."""
    grid, _cell = grid_points(face, count)
    edge = np.concatenate(face.loops)
    if len(edge) > boundary:
        edge = edge[np.linspace(0, len(edge) - 1, boundary).astype(int)]
    return np.concatenate([grid, edge])


# --------------------------------------------------------------------------- validation


def _loop_scale(loop: FloatArray) -> float:
    return float(max(np.ptp(loop[:, 0]), np.ptp(loop[:, 1]), 1e-300))


def validate_trim(outer: FloatArray, holes: Sequence[FloatArray], name: str) -> None:
    """Raise :class:`FaceError` naming the face for an empty, open or self-crossing loop."""
    for which, loop in [("outer loop", outer)] + [
        (f"hole {i}", h) for i, h in enumerate(holes, start=1)
    ]:
        where = f"{name}: {which}"
        if loop.ndim != 2 or loop.shape[1] != 2:
            raise FaceError(f"{where} must be a (k, 2) array of (u, v) points, got shape "
                            f"{loop.shape}")
        if not np.all(np.isfinite(loop)):
            raise FaceError(f"{where} has a non-finite (u, v) point")
        if len(loop) < 4:
            raise FaceError(f"{where} is empty: {len(loop)} points, a closed loop needs at "
                            "least 3 distinct points and the first repeated last")
        scale = _loop_scale(loop)
        gap = float(np.hypot(*(loop[-1] - loop[0])))
        if gap > 1e-9 * scale:
            raise FaceError(f"{where} is not closed: its last point is {gap:.3g} from its "
                            "first in (u, v)")
        crossing = _self_crossing(loop)
        if crossing is not None:
            i, j = crossing
            raise FaceError(f"{where} crosses itself: segment {i} (from u={loop[i, 0]:.6g}, "
                            f"v={loop[i, 1]:.6g}) crosses segment {j} (from u={loop[j, 0]:.6g}, "
                            f"v={loop[j, 1]:.6g})")
        area = 0.5 * float(np.sum(loop[:-1, 0] * loop[1:, 1] - loop[1:, 0] * loop[:-1, 1]))
        if abs(area) <= 1e-12 * scale * scale:
            raise FaceError(f"{where} is empty: it encloses no area in (u, v)")


def _orient(ax, ay, bx, by, cx, cy):
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def _self_crossing(loop: FloatArray) -> tuple[int, int] | None:
    """The first pair of non-adjacent segments that properly cross, or None (O(k²), chunked)."""
    a, b = loop[:-1], loop[1:]
    k = len(a)
    if k < 4:
        return None
    eps = 1e-12 * _loop_scale(loop) ** 2
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    chunk = max(1, 4_000_000 // k)
    idx = np.arange(k)
    for start in range(0, k, chunk):
        i = idx[start:start + chunk, None]
        j = idx[None, :]
        # Bounding boxes first, then strict orientation tests (proper crossings only).
        cand = (j > i + 1) & ~((i == 0) & (j == k - 1))
        cand &= (lo[i, 0] <= hi[j, 0]) & (lo[j, 0] <= hi[i, 0])
        cand &= (lo[i, 1] <= hi[j, 1]) & (lo[j, 1] <= hi[i, 1])
        ii, jj = np.nonzero(cand)
        if ii.size == 0:
            continue
        ii = ii + start
        p, q, r, s = a[ii], b[ii], a[jj], b[jj]
        d1 = _orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], r[:, 0], r[:, 1])
        d2 = _orient(p[:, 0], p[:, 1], q[:, 0], q[:, 1], s[:, 0], s[:, 1])
        d3 = _orient(r[:, 0], r[:, 1], s[:, 0], s[:, 1], p[:, 0], p[:, 1])
        d4 = _orient(r[:, 0], r[:, 1], s[:, 0], s[:, 1], q[:, 0], q[:, 1])
        proper = (((d1 > eps) & (d2 < -eps)) | ((d1 < -eps) & (d2 > eps))) & (
            ((d3 > eps) & (d4 < -eps)) | ((d3 < -eps) & (d4 > eps))
        )
        hit = np.flatnonzero(proper)
        if hit.size:
            return int(ii[hit[0]]), int(jj[hit[0]])
    return None


# --------------------------------------------------------------------------- densification


def densify_edge(
    pcurve: Callable[[FloatArray], FloatArray],
    surface_point: Callable[[FloatArray], FloatArray],
    t0: float,
    t1: float,
    tolerance: float,
    min_segments: int = 8,
    max_points: int = 100_000,
    name: str = "face",
) -> FloatArray:
    """Polyline (k, 2) in (u, v) of a parameter curve from ``t0`` to ``t1`` (both included).

    ``pcurve(t)`` gives (N, 2) parameter points, ``surface_point(uv)`` (N, 3) points in mm.
    A segment [ta, tb] is split in half until, at its quarter, half and three-quarter
    parameters, the surface point of the curve is within ``tolerance`` mm of the surface point
    of the straight (u, v) chord at the same fraction: the 3-D chord error of the trim.
    ``t1 < t0`` walks the curve backwards (a reversed edge).
    """
    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise FaceError(f"{name}: trim tolerance must be a positive length in mm, got {tolerance}")
    ts = list(np.linspace(t0, t1, min_segments + 1))
    uvs = list(np.asarray(pcurve(np.array(ts)), dtype=float))
    fractions = np.array([0.25, 0.5, 0.75])
    pending = list(range(len(ts) - 1))  # indices of segments still to check
    while pending:
        if len(ts) > max_points:
            raise FaceError(f"{name}: a trim edge needs more than {max_points} points for a "
                            f"chord tolerance of {tolerance} mm")
        a = np.array([ts[i] for i in pending])
        b = np.array([ts[i + 1] for i in pending])
        ua = np.array([uvs[i] for i in pending])
        ub = np.array([uvs[i + 1] for i in pending])
        tm = a[:, None] + (b - a)[:, None] * fractions[None, :]
        true_uv = np.asarray(pcurve(tm.ravel()), dtype=float)
        chord_uv = (ua[:, None, :] + (ub - ua)[:, None, :] * fractions[None, :, None]).reshape(-1, 2)
        err = np.linalg.norm(np.asarray(surface_point(true_uv)) - np.asarray(
            surface_point(chord_uv)), axis=1).reshape(-1, 3).max(axis=1)
        split = [seg for seg, e in zip(pending, err) if e > tolerance]
        if not split:
            break
        mids = {seg: true_uv.reshape(-1, 3, 2)[pending.index(seg), 1] for seg in split}
        new_ts, new_uvs, new_pending = [], [], []
        for i in range(len(ts) - 1):
            new_ts.append(ts[i])
            new_uvs.append(uvs[i])
            if i in mids:
                new_pending += [len(new_ts) - 1, len(new_ts)]
                new_ts.append(0.5 * (ts[i] + ts[i + 1]))
                new_uvs.append(mids[i])
        new_ts.append(ts[-1])
        new_uvs.append(uvs[-1])
        ts, uvs, pending = new_ts, new_uvs, new_pending
    return np.array(uvs, dtype=float)


def period_shift(bounds: Sequence[float], requested: Sequence[float],
                 periods: Sequence[float]) -> tuple[float, float]:
    """(du, dv): whole periods by which a segmented periodic surface's domain start
    (``bounds`` = u0, u1, v0, v1) moved from the ``requested`` (u0, v0); subtracting them from
    the knots puts the surface back on the trim's (OCCT's) parameters.  ``periods`` holds 0
    for a non-periodic direction."""
    out = []
    for got, want, period in zip((bounds[0], bounds[2]), requested, periods):
        if period <= 0:
            out.append(0.0)
            continue
        turns = round((got - want) / period)
        out.append(turns * period)
    return out[0], out[1]


def join_edges(pieces: Sequence[FloatArray], name: str, which: str, gap_tol: float,
               gap_measure: Callable[[FloatArray, FloatArray], float] | None = None,
               gap_unit: str = "in (u, v)") -> FloatArray:
    """One closed loop from edge polylines in wire order, each walked whichever way meets the
    previous one (so an edge's orientation need not be known); the joints must meet within
    ``gap_tol``, else :class:`FaceError` naming the face, loop and edge.

    Gaps are measured in (u, v) unless ``gap_measure(a, b)`` is given (e.g. the 3-D distance
    of the two parameter points on the surface, in mm, against the wire's vertex tolerance:
    OCCT leaves the parameter curves of edges meeting at a vertex apart by up to that much).
    """
    pieces = [np.asarray(p, dtype=float) for p in pieces if len(p)]
    if not pieces:
        raise FaceError(f"{name}: {which} is empty: no edges")

    def dist(a: FloatArray, b: FloatArray) -> float:
        return float(np.hypot(*(a - b)))

    measure = gap_measure or dist

    first = pieces[0]
    if len(pieces) > 1:
        nxt = pieces[1]
        if min(dist(first[0], nxt[0]), dist(first[0], nxt[-1])) < min(
            dist(first[-1], nxt[0]), dist(first[-1], nxt[-1])
        ):
            first = first[::-1]
    out = [first]
    for n, piece in enumerate(pieces[1:], start=2):
        end = out[-1][-1]
        if dist(piece[-1], end) < dist(piece[0], end):
            piece = piece[::-1]
        gap = measure(piece[0], end)
        if gap > gap_tol:
            raise FaceError(f"{name}: {which} is not closed: edge {n} starts {gap:.3g} from "
                            f"where the previous edge ends {gap_unit}")
        out.append(piece[1:])
    loop = np.concatenate(out)
    gap = measure(loop[-1], loop[0])
    if gap > gap_tol:
        raise FaceError(f"{name}: {which} is not closed: it ends {gap:.3g} from its start "
                        f"{gap_unit}")
    loop[-1] = loop[0]
    # Drop repeated points (a degenerate edge at a pole gives a zero-length piece).
    keep = np.ones(len(loop), dtype=bool)
    keep[1:] = np.any(np.diff(loop, axis=0) != 0, axis=1)
    keep[-1] = True
    return loop[keep]


# --------------------------------------------------------------------------- selection

#: "up" or 1-based face numbers (3 or "Face3"), as a list or a comma-separated string.
Selection = Union[str, Sequence[Union[int, str]]]


def parse_selection(selection: Selection, count: int, where: str = "shape"):
    """"up", or the distinct 1-based face numbers of ``selection`` checked against ``count``
    faces; FaceError for an empty selection, a bad item or a number out of range."""
    if isinstance(selection, str):
        text = selection.strip()
        if text.lower() == "up":
            return "up"
        selection = [s for s in text.split(",") if s.strip()]
    items = list(selection)
    if not items:
        raise FaceError(f"{where}: the face selection is empty")
    out: list[int] = []
    for item in items:
        if isinstance(item, (bool, float)):
            raise FaceError(f"{where}: face selection item {item!r} is not a face number")
        label = str(item).strip()
        digits = label[4:] if label.lower().startswith("face") else label
        try:
            number = int(digits)
        except ValueError:
            raise FaceError(f"{where}: face selection item {label!r} is neither a face number "
                            "(3 or Face3) nor 'up'") from None
        if not 1 <= number <= count:
            raise FaceError(f"{where}: face {number} of {count}: no such face (faces are "
                            f"numbered 1 to {count})")
        if number not in out:
            out.append(number)
    return out


def reach(nz: ArrayLike, z: ArrayLike, model_tolerance: float,
          spacing: float) -> tuple[bool, str]:
    """Whether a 3-axis tool reaches a face from above, and why not, from its outward unit
    normals' z ``nz`` and heights ``z`` (mm) at sample points about ``spacing`` (mm) apart.

    The rule: where the normal points down (z < -UP_TOLERANCE) the face leans over the
    material below it.  Going down through that part, the face moves sideways by
    ``tan(tilt)`` per unit of height, the tilt being the normal's angle below the horizontal;
    its overhang is the integral of that over the part's height, estimated from the samples
    sorted by height (each step of height at the larger tilt of its two ends, plus half a
    sample spacing beyond the highest and the lowest).  When the overhang is within
    ``model_tolerance`` (mm: the model's own tolerance at the face, at least
    MODEL_TOLERANCE_FLOOR), the face is vertical there up to what the model can tell -- the
    foot of a blend tangent to a wall -- and is reachable; otherwise it is undercut.  A face
    whose normal is nowhere up (z <= UP_TOLERANCE everywhere) is a wall, not reached from
    above.
    """
    nz = np.asarray(nz, dtype=float).ravel()
    z = np.asarray(z, dtype=float).ravel()
    if not len(nz):
        return False, "its normal is defined nowhere"
    tolerance = max(float(model_tolerance), MODEL_TOLERANCE_FLOOR)
    down = nz < -UP_TOLERANCE
    if np.any(down):
        low = float(nz[down].min())
        if low <= -0.5:  # 30 degrees or more below the horizontal: no question of tolerance
            return False, f"its outward normal points down (normal z = {low:.3g})"
        order = np.argsort(z[down], kind="stable")
        heights = z[down][order]
        tilt = nz[down][order]
        slope = -tilt / np.sqrt(1.0 - tilt * tilt)
        steps = np.maximum(slope[1:], slope[:-1]) * np.diff(heights)
        overhang = float(steps.sum()) + 0.5 * float(spacing) * (float(slope[0])
                                                                 + float(slope[-1]))
        if not overhang <= tolerance:
            return False, (f"its outward normal points down (normal z = {low:.3g}) and it "
                           f"overhangs by about {overhang:.3g} mm over "
                           f"{float(np.ptp(heights)) + float(spacing):.3g} mm of height, more "
                           f"than the model's tolerance {tolerance:.3g} mm")
    if float(nz.max()) <= UP_TOLERANCE:
        return False, "it is vertical (outward normal z = 0 everywhere)"
    return True, ""


def apply_selection(faces: Sequence[Face], reach: Sequence[tuple[bool, str]], chosen,
                    where: str = "shape") -> list[Face]:
    """The faces with ``selected`` set: "up" picks every face a 3-axis tool reaches from above
    (``reach[i] = (reachable, why not)``); numbers must name such faces.  FaceError naming the
    face otherwise, or when "up" finds none."""
    if chosen == "up":
        chosen = [face.index for face, (up, _) in zip(faces, reach) if up]
        if not chosen:
            raise FaceError(f"{where}: no face is reachable from above by a 3-axis tool")
    else:
        for number in chosen:
            up, why = reach[number - 1]
            if not up:
                raise FaceError(f"{where}: Face{number} is not reachable from above by a "
                                f"3-axis tool: {why}")
    return [replace(face, selected=face.index in chosen) for face in faces]


# --------------------------------------------------------------------------- plain data

_SURFACE_KEYS = ("poles", "weights", "knots_u", "knots_v", "degree_u", "degree_v",
                 "periodic_u", "periodic_v", "name")
_FACE_KEYS = ("format", "version", "index", "name", "selected", "flipped_v", "source",
              "deviation", "tolerance", "outer", "holes", "surface")


def surface_to_dict(surface) -> dict:
    """Plain JSON data of a NurbsSurface (its constructor's arguments, non-periodic form)."""
    weights = getattr(surface, "weights", None)
    return {
        "poles": np.asarray(surface.poles, dtype=float).tolist(),
        "weights": None if weights is None else np.asarray(weights, dtype=float).tolist(),
        "knots_u": np.asarray(surface.knots_u, dtype=float).tolist(),
        "knots_v": np.asarray(surface.knots_v, dtype=float).tolist(),
        "degree_u": int(surface.degree_u),
        "degree_v": int(surface.degree_v),
        # NurbsSurface holds a periodic direction already unwrapped (OCCT's SetUNotPeriodic):
        # its poles and knots are those of the non-periodic form.
        "periodic_u": False,
        "periodic_v": False,
        "name": str(getattr(surface, "name", "face")),
    }


def make_surface(poles, knots_u, knots_v, degree_u, degree_v, weights=None,
                 periodic_u=False, periodic_v=False, name="face"):
    """The core NurbsSurface (BSplineCAM.core.geometry.nurbs) from plain arrays."""
    return NurbsSurface(poles, knots_u, knots_v, degree_u, degree_v, weights=weights,
                        periodic_u=periodic_u, periodic_v=periodic_v, name=name)


def to_dict(face: Face) -> dict:
    """Plain JSON data of a face: read back by :func:`face_from_dict`."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "index": int(face.index),
        "name": face.name,
        "selected": bool(face.selected),
        "flipped_v": bool(face.flipped_v),
        "source": face.source,
        "deviation": float(face.deviation),
        "tolerance": float(face.tolerance),
        "outer": face.outer.tolist(),
        "holes": [h.tolist() for h in face.holes],
        "surface": surface_to_dict(face.surface),
    }


def _exact_keys(doc: object, keys: Sequence[str], where: str) -> dict:
    if not isinstance(doc, dict):
        raise FaceError(f"{where}: expected an object, got {type(doc).__name__}")
    missing = [k for k in keys if k not in doc]
    extra = sorted(set(doc) - set(keys))
    if missing:
        raise FaceError(f"{where}: missing key(s) {', '.join(missing)}")
    if extra:
        raise FaceError(f"{where}: unknown key(s) {', '.join(map(str, extra))}")
    return doc


def _typed(value: object, kind: type, where: str):
    ok = isinstance(value, kind) and not (kind is int and isinstance(value, bool))
    if kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    if not ok:
        raise FaceError(f"{where} must be {kind.__name__}, got {value!r}")
    return value


def _array(value: object, ndim: int, where: str, last: int | None = None) -> FloatArray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as exc:
        raise FaceError(f"{where} must be a {ndim}-D array of numbers ({exc})") from None
    if arr.ndim != ndim or (last is not None and arr.shape[-1] != last) or arr.size == 0:
        raise FaceError(f"{where} must be a non-empty {ndim}-D array"
                        + (f" with {last} columns" if last else "") + f", got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise FaceError(f"{where} holds a non-finite number")
    return arr


def face_from_dict(doc: object, source: str = "face") -> Face:
    """A :class:`Face` from :func:`to_dict`'s data; any missing, unknown or ill-typed key is a
    :class:`FaceError` naming ``source``, the face and the key."""
    doc = _exact_keys(doc, _FACE_KEYS, source)
    if doc["format"] != FORMAT or doc["version"] != VERSION:
        raise FaceError(f"{source}: not a {FORMAT} version {VERSION} record "
                        f"(format {doc['format']!r}, version {doc['version']!r})")
    index = _typed(doc["index"], int, f"{source}: index")
    if index < 1:
        raise FaceError(f"{source}: index is 1-based, got {index}")
    name = _typed(doc["name"], str, f"{source}: name")
    where = f"{source}: {name}"
    selected = _typed(doc["selected"], bool, f"{where}: selected")
    flipped = _typed(doc["flipped_v"], bool, f"{where}: flipped_v")
    kind = _typed(doc["source"], str, f"{where}: source")
    deviation = float(_typed(doc["deviation"], float, f"{where}: deviation (mm)"))
    tolerance = float(_typed(doc["tolerance"], float, f"{where}: tolerance (mm)"))
    outer = _array(doc["outer"], 2, f"{where}: outer", 2)
    holes_doc = doc["holes"]
    if not isinstance(holes_doc, list):
        raise FaceError(f"{where}: holes must be a list of loops")
    holes = tuple(_array(h, 2, f"{where}: hole {i}", 2) for i, h in enumerate(holes_doc, 1))
    sdoc = _exact_keys(doc["surface"], _SURFACE_KEYS, f"{where}: surface")
    poles = _array(sdoc["poles"], 3, f"{where}: surface poles (mm)", 3)
    weights = None
    if sdoc["weights"] is not None:
        weights = _array(sdoc["weights"], 2, f"{where}: surface weights")
        if weights.shape != poles.shape[:2]:
            raise FaceError(f"{where}: surface weights have shape {weights.shape}, the poles "
                            f"{poles.shape[:2]}")
        if np.any(weights <= 0):
            raise FaceError(f"{where}: surface weights must be positive")
    knots_u = _array(sdoc["knots_u"], 1, f"{where}: surface knots_u")
    knots_v = _array(sdoc["knots_v"], 1, f"{where}: surface knots_v")
    degree_u = _typed(sdoc["degree_u"], int, f"{where}: surface degree_u")
    degree_v = _typed(sdoc["degree_v"], int, f"{where}: surface degree_v")
    periodic_u = _typed(sdoc["periodic_u"], bool, f"{where}: surface periodic_u")
    periodic_v = _typed(sdoc["periodic_v"], bool, f"{where}: surface periodic_v")
    sname = _typed(sdoc["name"], str, f"{where}: surface name")
    try:
        surface = make_surface(poles, knots_u, knots_v, degree_u, degree_v, weights=weights,
                               periodic_u=periodic_u, periodic_v=periodic_v, name=sname)
    except BSplineCAMError as exc:
        raise FaceError(f"{where}: surface: {exc}") from None
    return Face(surface, outer, holes, index=index, name=name, selected=selected,
                flipped_v=flipped, source=kind, deviation=deviation, tolerance=tolerance)


def flip_v(poles: FloatArray, weights: FloatArray | None, knots_v: FloatArray):
    """Poles, weights and full knot vector of the same surface with v reversed:
    S'(u, v) = S(u, v0 + v1 - v) over the same interval [v0, v1] = [knots_v[0], knots_v[-1]]."""
    knots_v = np.asarray(knots_v, dtype=float)
    flipped = (knots_v[0] + knots_v[-1]) - knots_v[::-1]
    return (np.asarray(poles)[:, ::-1].copy(),
            None if weights is None else np.asarray(weights)[:, ::-1].copy(), flipped)


__all__ = [
    "DEFAULT_TOLERANCE", "FORMAT", "MODEL_TOLERANCE_FLOOR", "UP_TOLERANCE", "VERSION", "Face",
    "FaceError", "Selection", "reach",
    "apply_selection", "densify_edge", "parse_selection",
    "face_from_dict", "flip_v", "inside", "join_edges", "make_surface", "period_shift",
    "sample_points",
    "surface_to_dict",
    "to_dict", "validate_trim",
]
