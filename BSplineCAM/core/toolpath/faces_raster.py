# SPDX-License-Identifier: LGPL-2.1-or-later
"""Raster finishing of trimmed faces: the certified drop-cutter over a whole :class:`FaceSet`.

Like :mod:`.raster` (one surface), passes are vertical planes at ``angle`` from +X, spaced by
the scallop height from the curvature and slope of the selected faces
(:func:`.raster.cross_section_stepover`).  By default (``partial``) main passes are spaced by
what most of the faces allow and, where a stretch of a pass needs a closer neighbour, partial
passes between two main passes cover that stretch only, the gap halved until every sample's
allowance is met (:mod:`.raster_partial`); without ``partial`` every pass spans the whole
extent at the smallest allowance of the band its step spans.
Along a pass the tool tip is the certified :meth:`FaceSet.drop_ball` height over ALL faces
(check surfaces included, so nothing on the model is gouged), sampled every sqrt(8 R tol) mm,
refined where a midpoint departs more than tol/2 from the chord (the exact midpoint is asked
for only where the height's Hermite model, from the contacts' slopes, does not already keep
the departure well within that: :func:`_hermite_departure`), thinned by Douglas-Peucker to
tol/2 and made one-sided by :func:`.chords.lift_chords`.  A pass is cut only where the ball's
contact lies on a selected face; elsewhere it is split and the tool rises between the pieces
(stay-down links by :func:`.links.stay_down_links`, or a retract).
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..geometry.faces import sample_points
from ..typing import FloatArray
from .common import (
    Jet,
    Monitor,
    ProgressFn,
    ToolParameters,
    Toolpath,
    ToolpathStats,
    check_angle,
    normal_curvature,
    principal_curvatures,
)
from .faceset import FaceSet
from .links import stay_down_links
from .raster import (
    cross_section_stepover,
    lifted_line_runs,
    scallop_line_offsets,
    zigzag_by_line,
)
from .raster_partial import Piece, StepoverSamples, order_pieces, partial_offsets
from .raster_walls import climbing, insert_runs, wall_pieces

#: Rounds of midpoint refinement along a pass.
REFINE_ROUNDS = 5
#: Steepest slope (tan) at which the Hermite model of the height along a pass may stand in
#: for an exact midpoint, and the share of the tolerance its departure must stay within.
MODEL_SLOPE = 5.0
MODEL_SHARE = 0.25
#: Longest stay-down link between passes, in tool radii.
STAY_DOWN_LINK = 2.0
#: Steepest slope (degrees) of a selected face whose contact sets how far passes reach beyond
#: the faces' XY box: the centre lies R sin(slope) beyond its contact.  Steeper (up to a
#: vertical tangent joint) the ball's lower side nears the joint's edge, where the certified
#: drop-cutter's near-ties make it slow; the part of the face steeper than this is left.
STEEPEST_REACHED = 75.0


class FaceQuery:
    """Tip heights and their gradients over a face set for one ball (for chords and links)."""

    def __init__(self, faceset: FaceSet, radius: float):
        self.faceset = faceset
        self.radius = float(radius)

    def heights(self, xy: FloatArray):
        """(tip z, face, u, v, on selected) from :meth:`FaceSet.drop_ball` (mm)."""
        return self.faceset.drop_ball(xy, self.radius)

    def slopes(self, xy: FloatArray, face: np.ndarray, u: FloatArray, v: FloatArray) -> FloatArray:
        """Gradient of the tip height (envelope theorem, see :meth:`DropCutter.slopes`)."""
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        p = self.faceset.contact_points(face, u, v)
        d = p[:, :2] - q
        h = np.sqrt(np.maximum(self.radius ** 2 - (d * d).sum(axis=1), 0.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            return d / h[:, None]

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        tip, face, u, v, _ = self.heights(xy)
        grad = self.slopes(xy, face, u, v)
        grad[~np.isfinite(tip)] = np.nan
        return tip, grad


def _along(grad: FloatArray, along: FloatArray) -> FloatArray:
    """Slope of the tip height along the pass direction (NaN where no face is met)."""
    return grad[:, 0] * along[0] + grad[:, 1] * along[1]


def _hermite_departure(a: FloatArray, z: FloatArray, slope: FloatArray, sel: np.ndarray,
                       idx: np.ndarray) -> tuple[np.ndarray, FloatArray]:
    """For the intervals ``idx`` (from sample i to i + 1 of a pass): whether the height's
    Hermite model may stand in for exact midpoints there, and its departure from the chord
    (mm).

    The midpoint test only keeps the pass within the tolerance of the exact height (that no
    chord dips below it is proved afterwards by :func:`.chords.lift_chords`).  Between two
    samples the cubic Hermite interpolant H of their heights and slopes m0, m1 (from the
    contacts) departs from the chord by tau (1 - tau) [(m0 - k)(1 - tau) - (m1 - k) tau] L,
    k the chord's slope, so by at most 4/27 (|m0 - k| + |m1 - k|) L.  That bound also covers
    a concave corner's kink between the samples (a V of slopes m0 < m1 departs by at most
    (m1 - m0) L / 4 <= 1.7 times it) and flags a wall hidden between them (k far from both
    slopes).  The model stands where both slopes are gentle (at most MODEL_SLOPE) and both
    ends are cut or both are not; there the exact midpoint, which would be dropped anyway
    (within MODEL_SHARE of the half tolerance), is not asked for.
    """
    i = idx
    L = a[i + 1] - a[i]
    m0, m1 = slope[i], slope[i + 1]
    with np.errstate(invalid="ignore", divide="ignore"):
        k = (z[i + 1] - z[i]) / L
        departure = 4.0 / 27.0 * (np.abs(m0 - k) + np.abs(m1 - k)) * L
        gentle = ((sel[i] == sel[i + 1]) & (np.abs(m0) <= MODEL_SLOPE)
                  & (np.abs(m1) <= MODEL_SLOPE) & np.isfinite(departure))
    return gentle, departure


def _stepover_field(faceset: FaceSet, tool: ToolParameters, along: FloatArray,
                    across: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Across-coordinate of the ball centre and the allowed XY stepover (mm) at samples of the
    selected faces, sorted by the former (as :meth:`RasterPlanner.stepover_field`), and the
    (along, across) extent of the centres that touch them (mm, [[a0, b0], [a1, b1]]): the
    centre's XY offset from its contact, R sin slope, capped at R sin :data:`STEEPEST_REACHED`,
    and none where a centre over the contact leaves no more than the tolerance."""
    b, _a, allowed, reach = _stepover_samples(faceset, tool, along, across)
    order = np.argsort(b)
    return b[order], allowed[order], reach


def _stepover_samples(faceset: FaceSet, tool: ToolParameters, along: FloatArray,
                      across: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                                   FloatArray]:
    """:func:`_stepover_field` unsorted, with the along-coordinate of each sample's ball
    centre (mm) after its across-coordinate."""
    offs, alongs, allowed, reach = [], [], [], []
    for f in faceset.faces:
        if not f.selected:
            continue
        uv = sample_points(f, count=60, boundary=400)
        s = f.surface
        d = s.derivatives(uv[:, 0], uv[:, 1])
        nz = np.cross(d.su, d.sw)[:, 2]
        sign = 1.0 if float(nz.sum()) >= 0 else -1.0
        jet = Jet(uv[:, 0], uv[:, 1], d.point, d.su, d.sw, d.suu, d.suw, d.sww, sign)
        n = jet.normal
        nzc = np.clip(n[:, 2], 1e-3, 1.0)
        tz = -(n[:, 0] * across[0] + n[:, 1] * across[1]) / nzc
        t = np.column_stack([np.full(len(tz), across[0]), np.full(len(tz), across[1]), tz])
        kappa = normal_curvature(jet, t)
        xy = cross_section_stepover(tool.radius, tool.scallop, kappa, n, across, along,
                                    principal_curvatures(jet)[1])
        sin_slope = np.hypot(n[:, 0], n[:, 1])
        cap = math.sin(math.radians(STEEPEST_REACHED))
        # steeper samples are not reached by the passes: their allowance does not count
        kept = sin_slope <= cap
        allowed.append(np.maximum(xy, 0.02 * tool.flat_stepover)[kept])
        centre = d.point[:, :2] + tool.radius * n[:, :2]
        offs.append((centre @ across)[kept])
        alongs.append((centre @ along)[kept])
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = np.where(kept, 1.0, cap / sin_slope)
            # a ball centred over a contact this gentle leaves at most the tolerance (its
            # height above the face there, R (1 / cos slope - 1)): no reach beyond it
            gentle = tool.radius * (1.0 / np.abs(n[:, 2]) - 1.0) <= tool.tolerance
        scale[gentle] = 0.0
        centre = d.point[:, :2] + tool.radius * scale[:, None] * n[:, :2]
        reach.append(centre @ np.column_stack([along, across]))
    ab = np.concatenate(reach)
    return (np.concatenate(offs), np.concatenate(alongs), np.concatenate(allowed),
            np.array([ab.min(axis=0), ab.max(axis=0)]))


def _sampled_lines(query: FaceQuery, pieces: list[Piece], first: int, step: float, xy_of,
                   along: FloatArray, half: float, monitor: Monitor | None) -> tuple:
    """The pieces' dense cutter locations: (line index (``first`` + the piece's), along mm,
    tip z, face, u, v, on selected, tip gradient), sorted by line then along.  Sampled every
    ``step`` mm and refined at midpoints that depart more than ``half`` mm from their chord
    (module docstring)."""
    counts = [max(2, math.ceil((p.a1 - p.a0) / step) + 1) for p in pieces]
    line = first + np.repeat(np.arange(len(pieces)), counts)
    a = np.concatenate([np.linspace(p.a0, p.a1, n) for p, n in zip(pieces, counts)])
    z, face, u, v, sel = query.heights(xy_of(a, line))
    # every sample's height gradient, from its contact: the midpoint model below and the
    # chord checks after it
    grad = query.slopes(xy_of(a, line), face, u, v)
    if monitor is not None:
        monitor(0.5)
    fresh = np.ones(len(z), bool)  # an interval is tested once: when an end of it is new
    for r in range(REFINE_ROUNDS):
        ok = np.isfinite(z[:-1]) & np.isfinite(z[1:]) & (line[:-1] == line[1:])
        idx = np.flatnonzero(ok & (np.diff(a) > 1e-4) & (fresh[:-1] | fresh[1:]))
        gentle, departure = _hermite_departure(a, z, _along(grad, along), sel, idx)
        idx = idx[~(gentle & (departure <= MODEL_SHARE * half))]  # else modelled within tol
        if len(idx) == 0:
            break
        am = 0.5 * (a[idx] + a[idx + 1])
        lm = line[idx]
        zm, fm, um, vm, sm = query.heights(xy_of(am, lm))
        bad = np.isfinite(zm) & (np.abs(zm - 0.5 * (z[idx] + z[idx + 1])) > half)
        # keep also where the contact changes between selected and not (sharper split)
        bad |= (sel[idx] != sel[idx + 1]) & np.isfinite(zm)
        if not bad.any():
            break
        gm = query.slopes(xy_of(am[bad], lm[bad]), fm[bad], um[bad], vm[bad])
        # every sample keeps its contact (face, u, v), for the slopes below
        kept = [(line, lm), (a, am), (z, zm), (sel, sm), (face, fm), (u, um), (v, vm)]
        line, a, z, sel, face, u, v = (np.concatenate([old, new[bad]]) for old, new in kept)
        grad = np.concatenate([grad, gm])
        fresh = np.concatenate([np.zeros(len(fresh), bool), np.ones(int(bad.sum()), bool)])
        order = np.lexsort((a, line))
        line, a, z, sel, face, u, v, fresh, grad = (
            x[order] for x in (line, a, z, sel, face, u, v, fresh, grad))
        if monitor is not None:
            monitor(0.5 + 0.05 * (r + 1))
    return line, a, z, face, u, v, sel, grad


def generate_faces_raster(faceset: FaceSet, tool_diameter: float, scallop: float,
                          tolerance: float, angle: float = 0.0,
                          progress: ProgressFn = None, partial: bool = True) -> Toolpath:
    """:func:`raster_faces` with the tool given by its diameter, scallop (cusp height) and
    tolerance (one-sided chordal), all mm, validated here."""
    return raster_faces(faceset, ToolParameters.validate(tool_diameter, scallop, tolerance),
                        angle, progress, partial)


def raster_faces(faceset: FaceSet, tool: ToolParameters, angle: float = 0.0,
                 progress: ProgressFn = None, partial: bool = True) -> Toolpath:
    """Zig-zag raster toolpath (tool-tip positions, mm) of the selected faces of ``faceset``.

    ``tool`` is validated (:meth:`ToolParameters.validate`); angle in degrees from +X.
    Heights are the certified drop-cutter over every face of the set.  With ``partial`` the
    main passes are spaced by what most of the faces allow and partial passes fill the
    stretches that need closer ones (:mod:`.raster_partial`); without it every pass spans the
    whole extent, spaced by the least allowance of its band.
    """
    started = time.perf_counter()
    angle = check_angle(angle)
    monitor = Monitor(progress, None, "raster")
    monitor(0.0)
    R = tool.radius
    query = FaceQuery(faceset, R)
    theta = math.radians(angle)
    along = np.array([math.cos(theta), math.sin(theta)])
    across = np.array([-math.sin(theta), math.cos(theta)])
    lo, hi = faceset.bounds(selected_only=True)
    corners = np.array([[lo[0], lo[1]], [hi[0], lo[1]], [lo[0], hi[1]], [hi[0], hi[1]]])
    # ball centres over the selected faces' extent, as the net raster keeps them over the
    # surface's (further out the ball only grazes a flat border with its equator), and beyond
    # it as far as the centres touching a steep border lie (R sin slope past the contact)
    b_off, a_off, allowed, reach = _stepover_samples(faceset, tool, along, across)
    a0 = min(float((corners @ along).min()), float(reach[0, 0]))
    a1 = max(float((corners @ along).max()), float(reach[1, 0]))
    b0 = min(float((corners @ across).min()), float(reach[0, 1]))
    b1 = max(float((corners @ across).max()), float(reach[1, 1]))
    step = min(math.sqrt(8.0 * R * tool.tolerance), R / 2.0)
    if partial:
        samples = StepoverSamples(b_off, a_off, allowed)
        offsets, partials = partial_offsets(samples, b0, b1, (a0, a1), tool,
                                            0.5 * tool.flat_stepover)
        pieces = [Piece(b, a0, a1, k, 0) for k, b in enumerate(offsets)] + partials
    else:
        offsets = scallop_line_offsets(np.sort(b_off), allowed[np.argsort(b_off)], b0, b1, tool,
                                       0.5 * tool.flat_stepover)
        pieces = [Piece(b, a0, a1, k, 0) for k, b in enumerate(offsets)]
    # a line index per piece: pieces may share an across-offset, each sampled over its stretch
    bvals = np.array([p.b for p in pieces])

    def xy_of(a_, line_):
        return a_[:, None] * along + bvals[line_][:, None] * across

    half = 0.5 * tool.tolerance
    samples = _sampled_lines(query, pieces, 0, step, xy_of, along, half, monitor)
    # a wall between two lines: a piece halfway to the one it holds up (:mod:`.raster_walls`)
    line, a, z, face, u, v, sel, grad = samples
    extra, refs, feet = wall_pieces(pieces, line, a, z, np.isfinite(z) & sel, grad @ across, R)
    if extra:
        bvals = np.concatenate([bvals, [p.b for p in extra]])
        more = _sampled_lines(query, extra, len(pieces), step, xy_of, along, half, None)
        line, a, z, face, u, v, sel, grad = (np.concatenate([x, y]) for x, y in
                                             zip(samples, more))
        order = np.lexsort((a, line))
        line, a, z, face, u, v, sel, grad = (
            x[order] for x in (line, a, z, face, u, v, sel, grad))
        # a wall piece is cut at the wall's foot, not up the wall
        sel = sel & ~climbing(line, a, z, grad @ across, pieces, extra, refs, feet, R)
        pieces = pieces + extra
    cut = np.isfinite(z) & sel
    brk = np.flatnonzero((line[1:] != line[:-1]) | (cut[1:] != cut[:-1]))
    bounds = np.concatenate([[0], brk + 1, [len(z)]])
    runs = [(s, e) for s, e in zip(bounds[:-1], bounds[1:]) if e - s >= 2 and cut[s]]
    passes: list = []
    lift_stats: dict = {}
    if runs:
        idx = np.concatenate([np.arange(s, e) for s, e in runs])
        xy = xy_of(a[idx], line[idx])
        passes, lift_stats = lifted_line_runs(query.heights_and_slopes, runs, line, a[idx], xy,
                                              z[idx], grad[idx], half, monitor)
    first = len(pieces) - len(extra)
    walls = [(pieces[refs[k - first]].b, run) for k, run in passes if k >= first]
    passes = [(k, run) for k, run in passes if k < first]
    ordered = order_pieces(passes, pieces, along) if partial else zigzag_by_line(passes)
    if walls:
        # each wall run beside the pass of the line it was made for
        ordered = insert_runs(ordered, walls, along, across)
    monitor(0.95)
    steps = np.diff(np.unique(bvals))
    parameters = {"strategy": "raster", "tool_diameter": tool.diameter, "scallop": tool.scallop,
                  "tolerance": tool.tolerance, "angle": angle, "direction": "zigzag",
                  "faces": [f.name for f in faceset.faces if f.selected]}
    stats = ToolpathStats(stepover_min_mm=float(steps.min()) if len(steps) else float("nan"),
                          stepover_max_mm=float(steps.max()) if len(steps) else float("nan"))
    parameters["partial"] = bool(partial)
    extra = {"line_offsets_mm": list(map(float, offsets)),
             "partial_passes_mm": [[p.b, p.a0, p.a1] for p in pieces if not p.main],
             "chord_lift": lift_stats,
             "angle_frame": (along.tolist(), across.tolist()),
             "dropcutter": dict(faceset.stats)}
    toolpath = Toolpath("raster", ordered, parameters, [], stats, extra=extra)
    toolpath.finish(started, None)
    toolpath.links = stay_down_links(query, toolpath.passes, STAY_DOWN_LINK * R, tool.tolerance)
    toolpath.finish(started, None)
    monitor(1.0)
    return toolpath


__all__ = ["FaceQuery", "generate_faces_raster", "raster_faces"]
