# SPDX-License-Identifier: LGPL-2.1-or-later
"""Constant-scallop finishing of trimmed faces: passes that follow the selected faces, each
offset from the one before by the distance that leaves the asked scallop between them.

The work is done in the XY plane of the ball-centre positions, on a grid of spacing about a
third of the flat stepover over the selected faces' extent grown by R:

* **Region.**  A grid node belongs to the region when the certified drop-cutter
  (:meth:`FaceSet.drop_ball`, over ALL faces) touches a selected face there with a surface
  contact (the centre on the face's normal through the contact, as the faces' waterline asks:
  a ball hanging on a trim edge or a face's outer edge finishes nothing).  On every grid edge
  between a region node and one outside, the border is bisected with the same test to 1/1024
  of the edge: the region's border, to that precision, as polylines.
* **Stepover field.**  At each region node the contact's jet gives, for 36 across directions
  and the 32-neighbourhood's 16 axes, the XY distance s(n) between passes whose across
  direction is n leaving cusps of height h (:func:`.raster.cross_section_stepover`: the
  normal curvature of the face across the pass, the offset of the ball centres from the
  contacts, the slopes across and along the pass, a vertical cusp as the verification
  measures it), clamped to [0.02 s_flat, R].  The cost per mm along each axis a is the dual
  max_n |n . a| / s(n) (:func:`.scallop_metric.dual_costs`: the level sets of a field are
  s(n) apart across n only if moving along a costs at least that), then the largest within
  half a stepover along the axis (:func:`.scallop_metric.band_costs`: a cusp depends on the
  surface between its two contacts, as the raster's band rule has it).
* **Scallop distance.**  D, the distance from the border counted in stepovers: a least-cost
  path over the grid whose edges cost their XY length at those costs
  (:func:`.scallop_field.propagate`), started at the nodes within a cell of the border from
  the XY vector to it at the cost along it.  Where the faces allow wide steps D grows slowly,
  where they need close passes fast, so its level sets 1 apart are passes a stepover apart,
  measured across each pass at each point.  Loops that meet merge and open ones end at the
  border by construction (they are level sets).
* **Passes.**  The levels 0.05, 1.05, 2.05, ... (the first runs along the border, 0.05 of a
  stepover inside it); marching squares gives their polylines.  **Gaps**
  (:mod:`.scallop_gaps`): on a grid of surface points three times finer, E, the distance
  from the passes' contact lines counted so that 1/2 is where the ball's gap reaches h; where
  it passes the limit the tolerance leaves, the contour round that region moved to the ball
  centres is a pass (a thin one its midline); rounds until none is left.  Fronts that meet
  (ridges of D, the corners of nested loops) leave such regions, and so do slopes, where a
  pass's contacts run uphill of its centres and its cusp grows faster downhill.
* **Certified cutter locations.**  Each polyline is sampled every sqrt(8 R tol) mm (its
  vertices kept), the tip is the drop-cutter height over all faces, midpoints are added where
  the height departs from the chord by more than tol / 2 (unless the Hermite model of the
  height from the contacts' slopes keeps it well within that, as the faces' raster does), the
  pass is cut only where the contact lies on a selected face, thinned by Douglas-Peucker to
  tol / 2 (vertically and in XY), and its chords are sampled again and made one-sided by
  :func:`.chords.lift_chords`: no straight move dips below the exact drop-cutter height.
* **Order.**  Greedy nearest next pass from where the tool is (a closed loop is entered at its
  vertex nearest the tool, loops all run counter-clockwise), stay-down links
  (:func:`.links.stay_down_links`) where the next pass starts within 2 R.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..typing import FloatArray
from .chords import lift_chords, sample_chords
from .common import (
    Jet,
    Monitor,
    ProgressFn,
    ToolParameters,
    Toolpath,
    ToolpathStats,
    principal_curvatures,
    simplify,
)
from .faces_raster import FaceQuery
from .faces_waterline import SURFACE_TILT, _upward_signs
from .faceset import FaceSet
from .links import stay_down_links
from .raster import cross_section_stepover
from .scallop_field import (
    AXES,
    axis_vectors,
    contour_keys,
    contours,
    edge_ends,
    edge_points,
    near_vector,
    propagate,
)
from .scallop_gaps import SurfaceGrid, gap_limit, gap_passes
from .scallop_metric import (
    NormalCurvature,
    across_directions,
    band_costs,
    directional_cost,
    dual_costs,
)

#: Grid spacing as a share of the flat stepover (at most R / 4).
GRID_SHARE = 1.0 / 3.0
#: Most grid nodes; a finer grid is coarsened to this.
MAX_NODES = 2_000_000
#: Level of the first pass (stepovers inside the border).
FIRST_LEVEL = 0.05
#: A gap loop narrower than this share of the flat stepover is cut as its midline.
THIN = 0.5
#: Bisection steps of the region's border on a grid edge.
BORDER_STEPS = 10
#: Rounds of midpoint refinement along a pass.
REFINE_ROUNDS = 5
#: Steepest slope (tan) at which the Hermite model of the height may stand in for an exact
#: midpoint, and the share of the half tolerance its departure must stay within.
MODEL_SLOPE = 5.0
MODEL_SHARE = 0.25
#: Longest stay-down link between passes, in tool radii.
STAY_DOWN_LINK = 2.0


class _Grid:
    """The grid of ball-centre positions, the drop-cutter's answers on it and the region."""

    def __init__(self, faceset: FaceSet, tool: ToolParameters, query: FaceQuery,
                 signs: np.ndarray):
        R = tool.radius
        lo, hi = faceset.bounds(selected_only=True)
        g = min(GRID_SHARE * tool.flat_stepover, R / 4.0)
        span = (float(hi[0] - lo[0]) + 2 * R, float(hi[1] - lo[1]) + 2 * R)
        g = max(g, math.sqrt(span[0] * span[1] / MAX_NODES))
        self.xs = np.linspace(lo[0] - R, hi[0] + R, max(3, math.ceil(span[0] / g) + 1))
        self.ys = np.linspace(lo[1] - R, hi[1] + R, max(3, math.ceil(span[1] / g) + 1))
        self.dx, self.dy = self.xs[1] - self.xs[0], self.ys[1] - self.ys[0]
        self.shape = (len(self.xs), len(self.ys))
        X, Y = np.meshgrid(self.xs, self.ys, indexing="ij")
        self.xy = np.column_stack([X.ravel(), Y.ravel()])
        self.faceset, self.tool, self.query, self.signs = faceset, tool, query, signs
        tip, face, u, v, sel = query.heights(self.xy)
        self.inside, jets = surface_contacts(faceset, signs, self.xy, tip, face, u, v, sel, R)
        self.axes = axis_vectors(self.dx, self.dy)
        across = across_directions(self.axes)
        self.cost = np.full((len(AXES), len(self.xy)), np.inf)
        for idx, jet in jets:
            self.cost[:, idx] = dual_costs(stepovers(jet, tool, across), across, self.axes)
        self.inside = self.inside.reshape(self.shape)
        self.cost = band_costs(self.cost.reshape((len(AXES),) + self.shape), AXES, self.dx,
                               self.dy)

    def contacts(self, polylines: list) -> list[FloatArray]:
        """XY of the contacts (exact drop-cutter) along XY ``polylines`` of ball centres, split
        where a point has no surface contact on a selected face."""
        if not polylines:
            return []
        xy = np.concatenate([np.asarray(p, dtype=float)[:, :2] for p in polylines])
        tip, face, u, v, sel = self.query.heights(xy)
        ok, jets = surface_contacts(self.faceset, self.signs, xy, tip, face, u, v, sel,
                                    self.tool.radius)
        c = np.full((len(xy), 2), np.nan)
        for idx, jet in jets:
            c[idx] = jet.p[:, :2]
        out = []
        for piece, good in zip(np.split(c, np.cumsum([len(p) for p in polylines])[:-1]),
                               np.split(ok, np.cumsum([len(p) for p in polylines])[:-1])):
            out += [piece[run] for run in _true_runs(good, False)]
        return out

    def region(self, xy: FloatArray) -> np.ndarray:
        """Whether the ball centred over xy has a surface contact on a selected face."""
        tip, face, u, v, sel = self.query.heights(xy)
        return surface_contacts(self.faceset, self.signs, xy, tip, face, u, v, sel,
                                self.tool.radius)[0]

    def border(self) -> list[FloatArray]:
        """The region's border as XY polylines (mm), bisected on each grid edge it crosses."""
        mask = self.inside.astype(float)
        chains = contour_keys(mask, 0.5)
        if not chains:
            return []
        keys = np.unique(np.concatenate(chains))
        c = edge_ends(self.shape, keys)
        first_in = self.inside[c[:, 0, 0], c[:, 0, 1]]
        p0 = np.column_stack([self.xs[c[:, 0, 0]], self.ys[c[:, 0, 1]]])
        p1 = np.column_stack([self.xs[c[:, 1, 0]], self.ys[c[:, 1, 1]]])
        t_in = np.where(first_in, 0.0, 1.0)  # along the edge from its first corner
        t_out = 1.0 - t_in
        for _ in range(BORDER_STEPS):
            t = 0.5 * (t_in + t_out)
            ok = self.region(p0 + t[:, None] * (p1 - p0))
            t_in = np.where(ok, t, t_in)
            t_out = np.where(ok, t_out, t)
        t_of = dict(zip(keys.tolist(), (0.5 * (t_in + t_out)).tolist()))
        return [edge_points(mask, self.xs, self.ys, ch, 0.5,
                            np.array([t_of[k] for k in ch.tolist()])) for ch in chains]

    def distance(self, near: FloatArray, vec: FloatArray) -> FloatArray:
        """Least cost (stepovers) from polylines to every region node (inf where none),
        started at the nodes within a cell of them from the XY vector from their nearest
        point at the node's cost along it (further out the cost between falls short of the
        node's where it rises towards the polylines, as on a fillet that steepens); ``near``
        and ``vec`` are :func:`.scallop_field.near_vector` of the polylines on the grid."""
        ok = self.inside & (near <= max(self.dx, self.dy))
        start = np.full(self.shape, np.inf)
        start[ok] = directional_cost(self.cost[:, ok], self.axes, vec[ok])
        return propagate(start, self.cost, self.dx, self.dy, self.inside)


def surface_contacts(faceset: FaceSet, signs: np.ndarray, xy: FloatArray, tip: FloatArray,
                     face: np.ndarray, u: FloatArray, v: FloatArray, sel: np.ndarray,
                     radius: float) -> tuple[np.ndarray, list]:
    """Whether each contact is a surface contact on a selected face (|(c - p) / R - n| <=
    ``SURFACE_TILT``, c the ball centre, p the contact, n the upward normal), and per face
    (indices into xy, :class:`Jet` at its contacts) for those."""
    good = sel & np.isfinite(tip)
    jets = []
    for k in np.unique(face[good]).tolist():
        idx = np.flatnonzero(good & (face == k))
        d = faceset.faces[k].surface.derivatives(u[idx], v[idx])
        jet = Jet(u[idx], v[idx], d.point, d.su, d.sw, d.suu, d.suw, d.sww, signs[k])
        c = np.column_stack([xy[idx], tip[idx] + radius])
        ok = np.linalg.norm((c - d.point) / radius - jet.normal, axis=1) <= SURFACE_TILT
        good[idx] = ok
        if ok.any():
            keep = np.flatnonzero(ok)
            jets.append((idx[keep], Jet(*(a[keep] for a in (
                jet.u, jet.w, jet.p, jet.su, jet.sw, jet.suu, jet.suw, jet.sww)), signs[k])))
    return good, jets


def stepovers(jet: Jet, tool: ToolParameters, across: FloatArray) -> FloatArray:
    """(len(across), m) XY distance between passes (mm) that run perpendicular to each unit XY
    vector ``across``, leaving vertical cusps of ``tool.scallop`` at the jet's points
    (:func:`.raster.cross_section_stepover`), clamped to [0.02 s_flat, R]."""
    curvature = NormalCurvature(jet)
    n = curvature.normal
    kappa_max = principal_curvatures(jet)[1]
    nz = np.clip(n[:, 2], 1e-3, 1.0)
    out = np.empty((len(across), len(n)))
    for a, c in enumerate(across):
        along = np.array([-c[1], c[0]])
        t = np.column_stack([np.full(len(n), c[0]), np.full(len(n), c[1]),
                             -(n[:, :2] @ c) / nz])
        s = cross_section_stepover(tool.radius, tool.scallop, curvature(t), n, c,
                                   along, kappa_max)
        out[a] = np.clip(s, 0.02 * tool.flat_stepover, tool.radius)
    return out


def generate_faces_scallop(faceset: FaceSet, tool_diameter: float, scallop: float,
                           tolerance: float, progress: ProgressFn = None) -> Toolpath:
    """:func:`scallop_faces` with the tool given by its diameter, scallop (cusp height) and
    tolerance (one-sided chordal), all mm, validated here."""
    return scallop_faces(faceset, ToolParameters.validate(tool_diameter, scallop, tolerance),
                         progress)


def scallop_faces(faceset: FaceSet, tool: ToolParameters,
                  progress: ProgressFn = None) -> Toolpath:
    """Constant-scallop toolpath (tool-tip positions, mm) of the selected faces of ``faceset``
    (see the module docstring); ``tool`` is validated (:meth:`ToolParameters.validate`).
    Heights are the certified drop-cutter over every face of the set."""
    started = time.perf_counter()
    monitor = Monitor(progress, None, "scallop")
    monitor(0.0)
    R = tool.radius
    query = FaceQuery(faceset, R)
    grid = _Grid(faceset, tool, query, _upward_signs(faceset))
    monitor(0.3)
    border = grid.border()
    near, vec = near_vector(border, grid.xs, grid.ys)
    d = grid.distance(near, vec)
    monitor(0.4)
    # outside the region the field falls below zero (the XY distance to the border in flat
    # stepovers): the first level's contour runs along the border, not the grid's staircase
    field = np.where(grid.inside, d, -np.where(np.isfinite(near), near, grid.dx)
                     / tool.flat_stepover)
    field[~np.isfinite(field)] = np.nan  # region nodes no path reaches (none expected)
    top = float(np.nanmax(np.where(grid.inside, field, np.nan), initial=-1.0)) \
        if grid.inside.any() else -1.0
    levels = [FIRST_LEVEL + k for k in range(int(math.floor(top - FIRST_LEVEL)) + 1)] \
        if top >= FIRST_LEVEL else []
    polylines = [(lv, p) for lv in levels for p in contours(field, grid.xs, grid.ys, lv)]
    monitor(0.5)
    surface = SurfaceGrid(faceset.faces, grid.signs, tool, grid.xs, grid.ys, grid.inside)
    gap_fill, gaps = gap_passes(surface, [p for _, p in polylines], grid.contacts,
                                gap_limit(tool), THIN * tool.flat_stepover)
    polylines += [(math.inf, p) for p in gap_fill]
    monitor(0.55)
    passes, lift_stats = _cut_passes(query, tool, polylines, monitor)
    ordered = _order(passes)
    monitor(0.95)
    inside = grid.inside
    steps = 1.0 / grid.cost[:, inside] if inside.any() else np.full((1, 1), np.nan)
    parameters = {"strategy": "scallop", "tool_diameter": tool.diameter,
                  "scallop": tool.scallop, "tolerance": tool.tolerance, "direction": "zigzag",
                  "faces": [f.name for f in faceset.faces if f.selected]}
    stats = ToolpathStats(stepover_min_mm=float(np.min(steps)),
                          stepover_max_mm=float(np.max(steps)))
    if not levels:
        stats.notes.append("the ball has no surface contact on the selected faces")
    extra = {"levels": len(levels), "gap_passes": len(gap_fill),
             "gap_area_mm2": gaps, "grid_mm": float(max(grid.dx, grid.dy)),
             "chord_lift": lift_stats, "dropcutter": dict(faceset.stats)}
    toolpath = Toolpath("scallop", ordered, parameters, [], stats, extra=extra)
    toolpath.finish(started, None)
    toolpath.links = stay_down_links(query, toolpath.passes, STAY_DOWN_LINK * R, tool.tolerance)
    toolpath.finish(started, None)
    monitor(1.0)
    return toolpath


def _true_runs(mask: np.ndarray, closed: bool) -> list[np.ndarray]:
    """Index arrays of the runs of True (at least 2 long); a closed polyline's (first and last
    points the same) may wrap round."""
    n = len(mask)
    if n < 2:
        return []
    if closed and mask.all():
        return [np.arange(n)]
    v = np.concatenate([[False], mask, [False]])
    e = np.flatnonzero(v[1:] != v[:-1])
    runs = [np.arange(a, b) for a, b in zip(e[0::2], e[1::2])]
    if closed and len(runs) > 1 and runs[0][0] == 0 and runs[-1][-1] == n - 1:
        runs = [np.concatenate([runs[-1], runs[0][1:]])] + runs[1:-1]
    return [r for r in runs if len(r) >= 2]


def _samples(polylines: list, step: float) -> tuple[np.ndarray, FloatArray, FloatArray,
                                                   np.ndarray]:
    """Points every ``step`` mm at most along each XY polyline, its vertices included: line
    index, arc length (mm), XY, and per line whether it is closed."""
    line, pos, xy, closed = [], [], [], []
    for k, (_lv, p) in enumerate(polylines):
        p = np.asarray(p, dtype=float)[:, :2]
        keep = np.concatenate([[True], np.hypot(*np.diff(p, axis=0).T) > 1e-9])
        p = p[keep]
        closed.append(len(p) > 3 and bool(np.allclose(p[0], p[-1], atol=1e-9)))
        if len(p) < 2:
            p = np.vstack([p, p])
        seg = np.hypot(*np.diff(p, axis=0).T)
        n = np.maximum(np.ceil(seg / step).astype(int), 1)
        chord = np.repeat(np.arange(len(seg)), n)
        frac = np.concatenate([np.arange(m) / m for m in n])
        start = np.concatenate([[0.0], np.cumsum(seg)])
        pos.append(np.concatenate([start[chord] + frac * seg[chord], start[-1:]]))
        xy.append(np.concatenate([p[chord] + frac[:, None] * (p[chord + 1] - p[chord]),
                                  p[-1:]]))
        line.append(np.full(len(chord) + 1, k))
    return (np.concatenate(line), np.concatenate(pos), np.concatenate(xy),
            np.asarray(closed, bool))


def _cut_passes(query: FaceQuery, tool: ToolParameters, polylines: list,
                monitor: Monitor) -> tuple[list, dict]:
    """The XY ``polylines`` [(level, (n, 2))] made into certified passes [(level, (n, 3),
    whole closed loop)] cut where the contact lies on a selected face (see the module
    docstring), and the chord lift's statistics."""
    if not polylines:
        return [], {}
    R, half = tool.radius, 0.5 * tool.tolerance
    step = min(math.sqrt(8.0 * R * tool.tolerance), R / 2.0)
    line, pos, xy, closed = _samples(polylines, step)
    z, face, u, v, sel = query.heights(xy)
    grad = query.slopes(xy, face, u, v)
    monitor(0.65)
    fresh = np.ones(len(z), bool)  # an interval is tested once: when an end of it is new
    for r in range(REFINE_ROUNDS):
        ok = (np.isfinite(z[:-1]) & np.isfinite(z[1:]) & (line[:-1] == line[1:])
              & (np.diff(pos) > 1e-4) & (fresh[:-1] | fresh[1:]))
        idx = np.flatnonzero(ok)
        d = xy[idx + 1] - xy[idx]
        L = np.hypot(d[:, 0], d[:, 1])
        d /= L[:, None]
        m0 = np.einsum("ij,ij->i", grad[idx], d)
        m1 = np.einsum("ij,ij->i", grad[idx + 1], d)
        with np.errstate(invalid="ignore"):
            k = (z[idx + 1] - z[idx]) / L
            departure = 4.0 / 27.0 * (np.abs(m0 - k) + np.abs(m1 - k)) * L
            gentle = ((sel[idx] == sel[idx + 1]) & (np.abs(m0) <= MODEL_SLOPE)
                      & (np.abs(m1) <= MODEL_SLOPE) & (departure <= MODEL_SHARE * half))
        idx = idx[~gentle]
        if len(idx) == 0:
            break
        mxy = 0.5 * (xy[idx] + xy[idx + 1])
        zm, fm, um, vm, sm = query.heights(mxy)
        bad = np.isfinite(zm) & (np.abs(zm - 0.5 * (z[idx] + z[idx + 1])) > half)
        bad |= (sel[idx] != sel[idx + 1]) & np.isfinite(zm)
        if not bad.any():
            break
        gm = query.slopes(mxy[bad], fm[bad], um[bad], vm[bad])
        new = (line[idx][bad], 0.5 * (pos[idx] + pos[idx + 1])[bad], mxy[bad], zm[bad],
               sm[bad], gm)
        line, pos, xy, z, sel, grad = (np.concatenate([old, add]) for old, add in
                                       zip((line, pos, xy, z, sel, grad), new))
        fresh = np.concatenate([np.zeros(len(fresh), bool), np.ones(int(bad.sum()), bool)])
        order = np.lexsort((pos, line))
        line, pos, xy, z, sel, grad, fresh = (a[order] for a in
                                              (line, pos, xy, z, sel, grad, fresh))
        monitor(0.65 + 0.03 * (r + 1))
    cut = np.isfinite(z) & sel
    starts = np.searchsorted(line, np.arange(len(polylines) + 1))
    runs = []  # (level, sample indices, whole closed loop)
    for k, (lv, _p) in enumerate(polylines):
        a, b = starts[k], starts[k + 1]
        for run in _true_runs(cut[a:b], bool(closed[k])):
            runs.append((lv, a + run, bool(closed[k]) and len(run) == b - a))
    if not runs:
        return [], {}
    pts = np.concatenate([np.column_stack([xy[i], z[i]]) for _lv, i, _c in runs])
    bounds = np.cumsum([0] + [len(i) for _lv, i, _c in runs])
    keep = (simplify(pts, bounds, half, "vertical")
            | simplify(pts, bounds, tool.tolerance, "planar"))
    verts = [pts[a:b][keep[a:b]] for a, b in zip(bounds[:-1], bounds[1:])]
    monitor(0.8)
    samples = sample_chords(query.heights_and_slopes, [p[:, :2] for p in verts],
                            [p[:, 2] for p in verts], step)
    stats = lift_chords(query.heights_and_slopes, samples, half)
    vxy, vz, vline = samples.vertices()
    cuts = np.flatnonzero(np.diff(vline)) + 1
    out = [(lv, np.column_stack([pxy, pz]), whole) for (lv, _i, whole), pxy, pz in
           zip(runs, np.split(vxy, cuts), np.split(vz, cuts))]
    return out, stats


def _order(passes: list) -> list[FloatArray]:
    """Passes [(level, (n, 3), whole closed loop)] in cutting order: from the outermost loop,
    each next the one whose entry (a closed loop's nearest vertex, an open pass's nearer end)
    is nearest the tool; closed loops run counter-clockwise, entered where the tool is."""
    if not passes:
        return []
    items = []
    for _lv, p, whole in passes:
        p = p.copy()
        if whole:
            p[0, 2] = p[-1, 2] = max(p[0, 2], p[-1, 2])  # one height at the seam
            x, y = p[:, 0], p[:, 1]
            if float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1])) < 0.0:
                p = p[::-1].copy()
        items.append((p, whole))
    owner = np.concatenate([np.full(len(p), k) for k, (p, _w) in enumerate(items)])
    index = np.concatenate([np.arange(len(p)) for p, _w in items])
    allv = np.concatenate([p[:, :2] for p, _w in items])
    entry = np.concatenate([np.ones(len(p), bool) if w else
                            np.isin(np.arange(len(p)), [0, len(p) - 1]) for p, w in items])
    alive = np.ones(len(items), bool)
    first = int(np.argmin([lv for lv, _p, _w in passes]))
    out = []
    k, at = first, 0
    while True:
        p, whole = items[k]
        if whole and at:
            p = np.vstack([p[at:-1], p[:at + 1]])
        elif not whole and at:
            p = p[::-1]
        out.append(p)
        alive[k] = False
        if not alive.any():
            break
        cand = np.flatnonzero(alive[owner] & entry)
        dist = np.hypot(*(allv[cand] - p[-1, :2]).T)
        j = cand[int(np.argmin(dist))]
        k, at = int(owner[j]), int(index[j])
    return out


__all__ = ["generate_faces_scallop", "scallop_faces", "stepovers", "surface_contacts"]
