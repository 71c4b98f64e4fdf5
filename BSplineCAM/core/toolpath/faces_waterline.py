# SPDX-License-Identifier: LGPL-2.1-or-later
"""Waterline finishing of trimmed faces: constant-Z contours of the ball over a whole
:class:`FaceSet` (issue 11, item 3).

As :mod:`.waterline` does for one control net: at tip height z the ball touches the model
without cutting exactly where the certified drop-cutter height c(x, y) - R over ALL faces
(:meth:`FaceSet.drop_ball`, check surfaces included) equals z, so each waterline is a level set
of that field.

* Levels, top down, are spaced by the scallop on the steep parts of the selected faces
  (slope at least ``min_slope``): dz = s (1 - R kappa) sin(alpha) with s the curvature-adjusted
  stepover for a vertical cusp h n_z (:func:`.common.curved_stepover`), the smallest of the
  band each step spans, sampled over each selected face inside its trim
  (:func:`faces.sample_points`).
* The field is sampled on a grid of R / 4 over the selected faces' extent grown by R (a ball
  beside a wall still touches it); marching squares (Lorensen & Cline 1987,
  :func:`.waterline._crossings`) gives each level's contours, every crossing is polished on
  its grid edge by safeguarded Newton steps (the height's slope from the ball's contact),
  regula falsi (Illinois) and bisection on the exact drop height to ``tolerance`` / 1000
  (:func:`polish_crossings`; "no face under the ball" stays NaN, never a stand-in number),
  level points are inserted until the contour follows the level to tolerance / 4
  (:func:`.waterline.densify`), Douglas-Peucker thins it to tolerance / 2 in XY and every chord
  is checked against the exact drop-cutter, vertices pushed outwards where the ball would dip
  below the level (:func:`.waterline.push_out`): the tool stays on the free side, never below
  the drop height.
* Where the height jumps past a level (the ball leaving the model over an edge: its side on
  a wall or an edge, the contact on its rim) the crossing is bracketed to tolerance / 8 and
  the point kept on the air side (at or below the level, or no face); it counts as a contour
  point when the contact just above the jump is a selected surface contact (tilted by up to
  the bracket's sqrt(2 width / R)) and its face reaches down to the ball's centre below it
  (:func:`_wall_on_face`: a tube's side under its rim; not a check face's side under a fillet
  that ends vertical, which such a contour would only rub).  Between such points the contour
  is carried along the jump to tolerance / 2 (:func:`_densify_jumps`), and push_out finds its
  shifts there by searching for the free side rather than from the meaningless gradient.
* A contour is kept only where the ball's contact lies on a selected face AND is a surface
  contact, the centre on the face's normal through it (|(c - p) / R - n| <= ``SURFACE_TILT``):
  a ball hanging on a trim edge (a hole's rim, a face's outer edge) touches only the edge and
  finishes nothing of the face.  Where a contour leaves the selected faces between two grid
  crossings, its end is carried on along the level (midpoints projected onto the level set by
  Newton steps on the exact height) by bisection to 1/128 of the grid edge.
* Every contour runs climb, the material on the tool's right (:func:`.order.orient_climb`);
  the contours are cut in the order of short moves, upper levels first where they lie over
  lower ones (:func:`.order.order_contours`; zigzag lets open ones run either way), joined by
  stay-down feeds (:func:`.links.stay_down_links`) where the next one starts within
  ``STAY_DOWN_LINK`` radii.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import ParameterError
from ..geometry.faces import grid_points, inside, sample_points
from ..typing import FloatArray
from .common import (
    Jet,
    Monitor,
    ProgressFn,
    ToolParameters,
    Toolpath,
    ToolpathStats,
    check_finite,
    normal_curvature,
    simplify,
)
from .faces_raster import STAY_DOWN_LINK, FaceQuery
from .faceset import FaceSet
from .faceset_hints import ContactMemo
from .links import stay_down_links
from .order import order_contours, orient_climb
from .waterline import (
    _chain,
    _crossings,
    densify,
    level_steps,
    push_out,
    shallow_notes,
    step_levels,
)

#: Largest |(c - p) / R - n| of a surface contact (c the ball centre, p the contact, n the
#: upward unit normal there); more is an edge contact (a trim edge, a face's border).
SURFACE_TILT = 1e-3
#: Largest number of drop-cutter queries per grid edge while polishing its crossing (regula
#: falsi converges in about 6 where the height is smooth; a jump takes about 12 bisections).
FALSI_STEPS = 32
#: A level point lies within this fraction of the tolerance of its level (mm) in height.
LEVEL_EPS = 1e-3
#: A jump of the drop height past a level is bracketed to this fraction of the tolerance (mm):
#: the point kept, on the air side, lies at most that far from where the ball leaves the model.
JUMP_WIDTH = 0.125
#: A bracket that narrow whose ends differ by more than this slope (dz / dxy; a wall within
#: 0.06 degrees of vertical) holds a jump; else it goes on to the tolerance / 1000 in z.
JUMP_SLOPE = 1000.0


class _MemoQuery(FaceQuery):
    """:class:`FaceQuery` that remembers the drop result of every point it was asked about.

    The waterline asks about many points again: the contact check after regula falsi repeats
    each edge's last iterate (or a grid corner), every :func:`.waterline.push_out` iteration
    re-samples the chords its pushes left where they were, and the final contact check
    repeats push_out's last vertices.  :meth:`FaceSet.drop_ball` answers each point on its
    own (the same bits whatever else shares its batch), so the remembered answer is certified
    as a new query's would be; only points not seen before (by their exact coordinates) are
    dropped, in one call, each with the contact of a point answered near it as its hint
    (:class:`.faceset_hints.ContactMemo`)."""

    def __init__(self, faceset: FaceSet, radius: float):
        super().__init__(faceset, radius)
        self._row: dict[bytes, int] = {}  # exact (x, y) bytes -> row of the arrays below
        self._tip, self._u, self._v = np.zeros(0), np.zeros(0), np.zeros(0)
        self._face, self._sel = np.zeros(0, int), np.zeros(0, bool)
        self._near = ContactMemo.for_radius(radius)

    def heights(self, xy: FloatArray):
        q = np.ascontiguousarray(np.asarray(xy, dtype=float).reshape(-1, 2))
        keys = _xy_keys(q)
        row = self._row
        new: dict[bytes, int] = {}
        for i, k in enumerate(keys):
            if k not in row and k not in new:
                new[k] = i
        if new:
            at = np.fromiter(new.values(), dtype=np.intp, count=len(new))
            tip, face, u, v, sel = self.faceset.drop_ball(q[at], self.radius,
                                                          hint=self._near.hints(q[at]))
            self._near.add(q[at], face, u, v)
            base = len(self._tip)
            row.update(zip(new, range(base, base + len(at))))
            self._tip = np.concatenate([self._tip, tip])
            self._face = np.concatenate([self._face, face])
            self._u = np.concatenate([self._u, u])
            self._v = np.concatenate([self._v, v])
            self._sel = np.concatenate([self._sel, sel])
        r = np.fromiter((row[k] for k in keys), dtype=np.intp, count=len(keys))
        return self._tip[r], self._face[r], self._u[r], self._v[r], self._sel[r]


class _FiniteQuery:
    """:class:`FaceQuery` that answers NaN for non-finite query points instead of refusing
    them (:func:`.waterline.densify`'s Newton steps turn a point whose gradient is undefined,
    a contact on the ball's rim, into NaN and leave it out afterwards)."""

    def __init__(self, query: FaceQuery):
        self.query = query
        self.radius = query.radius

    def heights_and_slopes(self, xy: FloatArray) -> tuple[FloatArray, FloatArray]:
        q = np.asarray(xy, dtype=float).reshape(-1, 2)
        ok = np.isfinite(q).all(axis=1)
        z = np.full(len(q), np.nan)
        g = np.full((len(q), 2), np.nan)
        if ok.any():
            z[ok], g[ok] = self.query.heights_and_slopes(q[ok])
        return z, g


def _upward_signs(faceset: FaceSet) -> np.ndarray:
    """Per face +1 or -1: the sign that turns Su x Sv up on average over its trim box."""
    signs = []
    for f in faceset.faces:
        u0, u1, v0, v1 = f.bounds()
        gu, gv = np.meshgrid(np.linspace(u0, u1, 9), np.linspace(v0, v1, 9), indexing="ij")
        d = f.surface.derivatives(gu.ravel(), gv.ravel())
        signs.append(1.0 if float(np.cross(d.su, d.sw)[:, 2].sum()) >= 0 else -1.0)
    return np.asarray(signs)


def _steep_samples(faceset: FaceSet, tool: ToolParameters, signs: np.ndarray,
                   min_slope: float) -> tuple[FloatArray, FloatArray, float, float]:
    """Tip heights of ball contacts at samples of the steep parts of the selected faces and
    the step-down each allows, sorted by height; the range of contact tip heights."""
    zs, dzs, lo, hi = [], [], math.inf, -math.inf
    for f, sign in zip(faceset.faces, signs):
        if not f.selected:
            continue
        uv = sample_points(f, count=60, boundary=400)
        d = f.surface.derivatives(uv[:, 0], uv[:, 1])
        jet = Jet(uv[:, 0], uv[:, 1], d.point, d.su, d.sw, d.suu, d.suw, d.sww, sign)
        n = jet.normal
        sin_a = np.sqrt(np.clip(1.0 - n[:, 2] ** 2, 0.0, 1.0))
        steep = (sin_a >= math.sin(min_slope)) & (n[:, 2] > 0)
        # steepest descent in the tangent plane: across the waterlines
        down = np.column_stack([n[:, 0] * n[:, 2], n[:, 1] * n[:, 2], n[:, 2] ** 2 - 1.0])
        dz = level_steps(tool, n, normal_curvature(jet, down))
        z_off = jet.p[:, 2] + tool.radius * (n[:, 2] - 1.0)
        lo, hi = min(lo, float(z_off.min())), max(hi, float(z_off.max()))
        zs.append(z_off[steep])
        dzs.append(dz[steep])
    z, dz = np.concatenate(zs), np.concatenate(dzs)
    order = np.argsort(z)
    return z[order], dz[order], lo, hi


def _face_normals(faceset: FaceSet, signs: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """Upward normals' z and area weights (mm^2) at grid points of the selected faces."""
    nz, area = [], []
    for f, sign in zip(faceset.faces, signs):
        if not f.selected:
            continue
        uv, cell = grid_points(f, count=60)
        d = f.surface.derivatives(uv[:, 0], uv[:, 1])
        c = sign * np.cross(d.su, d.sw)
        a = np.linalg.norm(c, axis=1)
        nz.append(c[:, 2] / np.maximum(a, 1e-300))
        area.append(a * cell)
    return np.concatenate(nz), np.concatenate(area)


def level_heights(zs: FloatArray, dzs: FloatArray, tool: ToolParameters, min_slope: float,
                  z_top: float, z_bottom: float) -> list[float]:
    """Tip heights of the waterlines, top down (mm): each step the least step-down allowed
    by the steep samples in the band it spans (as :func:`.waterline.level_heights`)."""
    return step_levels(zs, dzs, tool, min_slope, z_top, z_bottom, gap=1e-3 * tool.radius)


def _contacts(faceset: FaceSet, query: FaceQuery, signs: np.ndarray, xy: FloatArray,
              tilt_max: float = SURFACE_TILT) -> tuple[FloatArray, np.ndarray]:
    """Tip heights at xy and whether the ball's contact there is a surface contact on a
    selected face (|(c - p) / R - n| <= ``tilt_max``)."""
    tip, face, u, v, on_sel = query.heights(xy)
    R = query.radius
    good = on_sel & np.isfinite(tip)
    for k, f in enumerate(faceset.faces):
        idx = np.flatnonzero(good & (face == k))
        if len(idx) == 0:
            continue
        d = f.surface.derivatives(u[idx], v[idx])
        n = signs[k] * np.cross(d.su, d.sw)
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        c = np.column_stack([xy[idx], tip[idx] + R])
        tilt = np.linalg.norm((c - d.point) / R - n, axis=1)
        good[idx] = tilt <= tilt_max
    return tip, good


def _wall_on_face(faceset: FaceSet, query: FaceQuery, xy: FloatArray, z: FloatArray,
                  tol: float, steps: int = 12) -> np.ndarray:
    """Whether the face of the ball's contact at xy (just above a jump) reaches down to the
    height z (mm) at that contact's xy, within ``tol``: the wall a ball's side meets below a
    rim is then that face (a tube's side under its rim) and not another one (a check face's
    side under a fillet that ends vertical, which a contour there would only rub).  The point
    below the contact is projected onto the face by Gauss-Newton steps from the contact's
    parameters, kept in the face's domain and material."""
    _tip, face, u, v, _sel = query.heights(xy)
    out = np.zeros(len(xy), bool)
    for k in np.unique(face[face >= 0]).tolist():
        idx = np.flatnonzero(face == k)
        f = faceset.faces[k]
        (u0, u1), (v0, v1) = f.surface.domain
        uu, vv = u[idx].copy(), v[idx].copy()
        target = np.column_stack([f.surface.evaluate(uu, vv)[:, :2], z[idx]])
        for _ in range(steps):
            d = f.surface.derivatives(uu, vv)
            r = d.point - target
            a11 = np.einsum("ij,ij->i", d.su, d.su)
            a12 = np.einsum("ij,ij->i", d.su, d.sw)
            a22 = np.einsum("ij,ij->i", d.sw, d.sw)
            b1 = np.einsum("ij,ij->i", d.su, r)
            b2 = np.einsum("ij,ij->i", d.sw, r)
            det = a11 * a22 - a12 * a12
            safe = np.where(np.abs(det) > 1e-300, det, 1.0)
            uu = np.clip(uu - np.where(np.abs(det) > 1e-300, (a22 * b1 - a12 * b2) / safe, 0.0),
                         u0, u1)
            vv = np.clip(vv - np.where(np.abs(det) > 1e-300, (a11 * b2 - a12 * b1) / safe, 0.0),
                         v0, v1)
        gap = np.linalg.norm(f.surface.evaluate(uu, vv) - target, axis=1)
        out[idx] = (gap <= tol) & inside(f, uu, vv)
    return out


def _project(query: FaceQuery, q: FloatArray, level: FloatArray, steps: int = 2) -> FloatArray:
    """Points moved towards the level set by Newton steps along the exact height gradient."""
    q = q.copy()
    for _ in range(steps):
        z, g = query.heights_and_slopes(q)
        with np.errstate(divide="ignore", invalid="ignore"):
            step = ((level - z) / np.einsum("ij,ij->i", g, g))[:, None] * g
        q = q + np.where(np.isfinite(step), step, 0.0)
    return q


def _refine_ends(faceset: FaceSet, query: FaceQuery, signs: np.ndarray, kept: FloatArray,
                 dropped: FloatArray, level: FloatArray, rounds: int = 7) -> FloatArray:
    """Bisection along the level set between a kept contour point and its dropped neighbour:
    the last point found on the level (to 1e-7 mm) whose contact is a selected surface
    contact."""
    a, b = kept.copy(), dropped.copy()
    for _ in range(rounds):
        m = _project(query, 0.5 * (a + b), level)
        tip, good = _contacts(faceset, query, signs, m)
        good &= np.abs(tip - level) <= 1e-7
        a = np.where(good[:, None], m, a)
        b = np.where(good[:, None], b, m)
    return a


def _runs(keep: np.ndarray, closed: bool) -> list[np.ndarray]:
    """Index arrays of the runs of True in ``keep`` (a closed loop's first and last entries
    are the same point: a run may wrap round)."""
    n = len(keep)
    if closed:
        body = keep[:-1]
        if body.all():
            return [np.arange(n)]
        shift = int(np.flatnonzero(~body)[0])
        order = np.roll(np.arange(n - 1), -shift)
        runs = []
        for a, b in _true_runs(body[order]):
            runs.append(order[a:b])
        return runs
    return [np.arange(a, b) for a, b in _true_runs(keep)]


def _true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    v = np.concatenate([[False], mask, [False]])
    e = np.flatnonzero(v[1:] != v[:-1])
    return [(a, b) for a, b in zip(e[0::2], e[1::2]) if b - a >= 2]


def polish_crossings(heights, p0: FloatArray, p1: FloatArray, z0: FloatArray, z1: FloatArray,
                     level: FloatArray, eps: float, width: float, steps: int = FALSI_STEPS,
                     progress=None, slopes=None,
                     ) -> tuple[FloatArray, np.ndarray, FloatArray, np.ndarray]:
    """Where the drop height crosses ``level`` (mm) on each grid edge p0-p1.

    ``heights(xy)`` gives the certified tip heights (mm) at points (n, 2), NaN where no face
    lies under the ball: the tool falls through, below every level.  z0, z1 are those at the
    ends, one above the level, the other at or below it (the air side) or NaN.  Regula falsi
    with the Illinois modification (Dowell & Jarratt 1971: the value of an end kept twice in a
    row is halved) on the exact height, bisection instead while the air end has no face (no
    value to follow), while its ends differ by more than JUMP_SLOPE per mm (a jump to a face
    far below: the secant would land next to the air end step after step), or when three
    steps did not halve the bracket (Brent's safeguard: a discontinuity stalls the secant
    next to one end).  "No face" stays NaN throughout: a
    stand-in number would be changed by the halving and pull the secant onto that end.

    An edge stops at a point within ``eps`` of the level, or when its bracket is ``width`` mm
    wide with no face at its air end or a rise steeper than ``JUMP_SLOPE`` across it (at most
    ``width`` / 10^6 wide in any case): the height jumps past the level there (the ball
    leaving the model over an edge, its rim on a vertical tangent) and the point kept is the
    air end, the ball never above the exact drop height.  Returns the edge parameter t in
    [0, 1] of each point, whether it ends a jump, the parameter of the bracket's end above
    the level (the material it follows), and whether the edge settled within ``steps``
    queries (else t is its air end).  ``progress(fraction)``, if given, hears the share of
    the edges settled after each round of queries.

    ``slopes(xy)``, if given, is the gradient (n, 2) of the height at points ``heights`` was
    asked about (the contact's, free of a new drop: :meth:`FaceQuery.slopes`) or at the edge
    ends; each step then is a Newton step from the edge's latest point with a finite value
    and slope (the grid end nearer the level at first) wherever it lands strictly inside the
    bracket and no bisection is due: quadratic where the height is smooth, and it needs no
    value at the air end.  Safeguarded as in "Numerical Recipes" rtsafe (sec. 9.4): an edge
    whose Newton step stayed on its point's side and removed less than half its distance to
    the level (the ball's rim over a jump, where the level is never reached) is bisected
    from then on.  A bisection takes the dyadic point of the bracket with the fewest binary
    digits (its midpoint once the bracket is a dyadic interval): the levels a jump crosses on
    one grid edge then ask the same points, whatever steps came before.
    """
    n = len(p0)
    length = np.hypot(*(p1 - p0).T)
    f0, f1 = np.asarray(z0, float) - level, np.asarray(z1, float) - level
    up0 = np.nan_to_num(f0, nan=-np.inf) > 0.0
    tu, ta = np.where(up0, 0.0, 1.0), np.where(up0, 1.0, 0.0)  # above / air end
    gu, ga = np.where(up0, f0, f1), np.where(up0, f1, f0)  # their values for the secant
    gu_true, ga_true = gu.copy(), ga.copy()  # their exact values (NaN: no face)
    t_hit = np.full(n, np.nan)
    jump = np.zeros(n, bool)
    last = np.zeros(n, np.int8)  # +1: the step before replaced the above end, -1: the air end
    w_ago = np.full((3, n), np.inf)  # bracket widths 3, 2 and 1 steps ago
    done = np.zeros(n, bool)
    if slopes is not None:
        d = p1 - p0
        along = lambda g, i: np.einsum("ij,ij->i", np.asarray(g, float), d[i])  # noqa: E731
        s0, s1 = along(slopes(p0), slice(None)), along(slopes(p1), slice(None))
        # the Newton point: the grid end nearer the level with a value and a slope, then the
        # latest point asked (t, its value and its slope along the edge, dz per unit t)
        near0 = np.abs(np.nan_to_num(f0, nan=np.inf)) <= np.abs(np.nan_to_num(f1, nan=np.inf))
        tn = np.where(near0, 0.0, 1.0)
        fn, sn = np.where(near0, f0, f1), np.where(near0, s0, s1)
        newton = np.ones(n, bool)  # off once a step crept (a jump: no root to converge on)
    for k in range(steps + 1):
        w = np.abs(tu - ta)
        # a jump: narrow, and nothing under the ball at the air end or a rise steeper than
        # JUMP_SLOPE across the bracket (a steep but continuous height goes on to eps)
        with np.errstate(invalid="ignore", divide="ignore"):
            rise = (gu_true - ga_true) / (w * length)
        narrow = ~done & (w * length <= width) & (np.isnan(ga_true) | ~(rise <= JUMP_SLOPE))
        narrow |= ~done & (w * length <= 1e-6 * width)
        jump |= narrow
        done |= narrow
        act = np.flatnonzero(~done)
        if progress is not None:
            progress(1.0 - len(act) / max(n, 1))
        if len(act) == 0 or k == steps:
            break
        a_u, a_a, b_u, b_a = tu[act], ta[act], gu[act], ga[act]
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (a_a * b_u - a_u * b_a) / (b_u - b_a)
        lo, hi = np.minimum(a_u, a_a), np.maximum(a_u, a_a)
        bisect = ~np.isfinite(t) | (t <= lo) | (t >= hi) | (w[act] > 0.5 * w_ago[0, act])
        # a bracket whose ends differ more steeply than JUMP_SLOPE holds a jump (or a wall
        # within 0.06 degrees of vertical): the secant lands next to its air end time and
        # again, while bisection narrows it to ``width`` in log2 steps
        bisect |= rise[act] > JUMP_SLOPE
        if slopes is None:
            t = np.where(bisect, 0.5 * (a_u + a_a), t)
        else:
            with np.errstate(invalid="ignore", divide="ignore"):
                t_n = tn[act] - fn[act] / sn[act]
            use = ~bisect & newton[act] & (t_n > lo) & (t_n < hi)
            t = np.where(bisect | ~np.isfinite(t), _dyadic(lo, hi), t)
            t = np.where(use, t_n, t)
        w_ago[:, act] = np.vstack([w_ago[1:, act], w[act]])
        xy_t = p0[act] + t[:, None] * (p1[act] - p0[act])
        ft = np.asarray(heights(xy_t), float) - level[act]
        if slopes is not None:
            # a Newton step that stayed on its side without halving its distance crept
            crept = use & (np.sign(ft) == np.sign(fn[act])) & ~(np.abs(ft) <= 0.5 * np.abs(fn[act]))
            newton[act[crept]] = False
            st = along(slopes(xy_t), act)
            fresh = np.isfinite(ft) & np.isfinite(st)
            tn[act] = np.where(fresh, t, tn[act])
            fn[act] = np.where(fresh, ft, fn[act])
            sn[act] = np.where(fresh, st, sn[act])
        hit = np.abs(np.nan_to_num(ft, nan=np.inf)) <= eps
        above = np.nan_to_num(ft, nan=-np.inf) > 0.0
        # Illinois: the end kept for the second time in a row has its value halved
        keep_air = above & (last[act] == 1)
        keep_up = ~above & (last[act] == -1)
        tu[act] = np.where(above, t, a_u)
        gu_true[act] = np.where(above, ft, gu_true[act])
        ga_true[act] = np.where(above, ga_true[act], ft)
        gu[act] = np.where(above, ft, np.where(keep_up, 0.5 * b_u, b_u))
        ta[act] = np.where(above, a_a, t)
        ga[act] = np.where(above, np.where(keep_air, 0.5 * b_a, b_a), ft)
        last[act] = np.where(above, 1, -1)
        t_hit[act[hit]] = t[hit]
        done[act[hit]] = True
    converged = np.isfinite(t_hit)
    return np.where(converged, t_hit, ta), jump & ~converged, tu, converged | jump


def _dyadic(lo: FloatArray, hi: FloatArray) -> FloatArray:
    """The point j / 2^k strictly inside each interval (lo, hi) of [0, 1] with the least k
    (the midpoint where the interval is lo..hi = i / 2^k..(i + 1) / 2^k): it splits the
    interval into parts no wider than its dyadic cell's half."""
    out = 0.5 * (lo + hi)
    todo = hi > lo
    scale = 1.0
    for _ in range(60):
        if not todo.any():
            break
        scale *= 2.0
        j = np.floor(lo * scale) + 1.0
        found = todo & (j < hi * scale)
        out = np.where(found, j / scale, out)
        todo &= ~found
    return out


def _jump_near(query: FaceQuery, m: FloatArray, normal: FloatArray, level: FloatArray,
               reach: FloatArray, width: float,
               halvings: int = 12) -> tuple[FloatArray, np.ndarray]:
    """The air-side end (mm) of the nearest change between "above the level" and "air" (at or
    below it, or no face) from each point m along +-normal within ``reach``, bracketed to
    ``width`` mm, and whether one was found.  Candidates at reach / 2^i on both sides in one
    query (the nearest that differs from m is taken), then bisection."""
    n = len(m)
    sides = np.array([1.0, -1.0])
    dist = reach[:, None] * 0.5 ** np.arange(halvings)  # (n, K), decreasing
    q = m[:, None, None, :] + (sides[None, :, None, None] * dist[:, None, :, None]) * normal[
        :, None, None, :]
    z = query.heights(np.concatenate([m, q.reshape(-1, 2)]))[0]
    above = np.nan_to_num(z, nan=-np.inf) > np.concatenate([level, np.repeat(level, 2 * halvings)])
    free = ~above
    free_m, free_q = free[:n], free[n:].reshape(n, 2, halvings)
    change = free_q != free_m[:, None, None]
    # the nearest candidate that differs: the last (smallest distance) one with a change
    j = halvings - 1 - np.argmax(change[..., ::-1], axis=2)
    has = change.any(axis=2)
    far = np.where(has, np.take_along_axis(dist[:, None, :].repeat(2, 1), j[..., None], 2)[..., 0],
                   np.inf)
    pick = np.argmin(far, axis=1)
    rows = np.arange(n)
    found = np.isfinite(far[rows, pick])
    jj = j[rows, pick]
    hi = np.where(found, far[rows, pick], 0.0)  # differs from m
    lo = np.where(jj + 1 < halvings, dist[rows, np.minimum(jj + 1, halvings - 1)], 0.0)
    lo = np.where(found, lo, 0.0)  # same as m (every nearer candidate is)
    side = sides[pick]
    for _ in range(64):
        act = np.flatnonzero(found & (hi - lo > width))
        if len(act) == 0:
            break
        mid = 0.5 * (lo[act] + hi[act])
        zq = query.heights(m[act] + (side[act] * mid)[:, None] * normal[act])[0]
        same = ~(np.nan_to_num(zq, nan=-np.inf) > level[act]) == free_m[act]
        lo[act] = np.where(same, mid, lo[act])
        hi[act] = np.where(same, hi[act], mid)
    at = np.where(free_m, lo, hi)
    return m + (side * at)[:, None] * normal, found


def _densify_jumps(query: FaceQuery, pts: FloatArray, starts: np.ndarray, gap: float,
                   width: float, rounds: int = 6) -> tuple[FloatArray, np.ndarray]:
    """Insert points on the air side of the jump between consecutive jump points (flag in
    the fourth column) until every chord's midpoint lies within ``gap`` (XY, mm) of the
    jump: beside a jump :func:`.waterline.densify` finds no level to project onto, and a
    chord across a convex jump would cut into the model by its sag (the grid's chords of up
    to R / 4 sqrt 2 on an offset of radius R or more: up to R / 64), which push_out would
    make good by pushing the contour off the wall as far.  Each round looks along every
    open chord's normal from its midpoint for the jump (:func:`_jump_near`)."""
    line = np.repeat(np.arange(len(starts) - 1), np.diff(starts))
    jump = pts[:, 3] > 0.0
    active = (line[:-1] == line[1:]) & jump[:-1] & jump[1:]
    for _ in range(rounds):
        idx = np.flatnonzero(active)
        if len(idx):
            d = pts[idx + 1, :2] - pts[idx, :2]
            length = np.hypot(d[:, 0], d[:, 1])
            idx, d, length = idx[length > gap], d[length > gap], length[length > gap]
        if len(idx) == 0:
            break
        m = 0.5 * (pts[idx, :2] + pts[idx + 1, :2])
        normal = np.column_stack([-d[:, 1], d[:, 0]]) / length[:, None]
        level = pts[idx, 2]
        q, found = _jump_near(query, m, normal, level, 0.5 * length, width)
        add = found & (np.hypot(*(q - m).T) > gap)
        active[:] = False
        if not add.any():
            break
        at = idx[add] + 1
        pts = np.insert(pts, at, np.column_stack([q[add], level[add], np.ones(len(at))]), axis=0)
        line = np.insert(line, at, line[at - 1])
        active = np.insert(active, at, False)
        new = at + np.arange(len(at))
        active[new - 1] = True
        active[new] = True
    return pts, np.searchsorted(line, np.arange(line[-1] + 2))


def generate_faces_waterline(faceset: FaceSet, tool_diameter: float, scallop: float,
                             tolerance: float, progress: ProgressFn = None,
                             min_slope: float = 30.0) -> Toolpath:
    """:func:`waterline_faces` with the tool given by its diameter, scallop (cusp height) and
    tolerance (chordal), all mm, validated here."""
    return waterline_faces(faceset, ToolParameters.validate(tool_diameter, scallop, tolerance),
                           progress, min_slope)


def waterline_faces(faceset: FaceSet, tool: ToolParameters, progress: ProgressFn = None,
                    min_slope: float = 30.0, direction: str = "zigzag") -> Toolpath:
    """Waterline toolpath (tool-tip positions, mm) of the selected faces of ``faceset``.

    ``tool`` is validated (:meth:`ToolParameters.validate`); ``min_slope`` in degrees: walls
    shallower than this are spaced by the flat stepover only (pair the waterline with a
    raster pass there).  Contours are closed or open polylines at constant Z, never below
    the certified drop-cutter height over every face, each after the contours above it, each
    climb (the material on the tool's right); ``direction`` "zigzag" lets an open contour run
    the other way when that shortens the move to it, "oneway" keeps every one climb.
    """
    started = time.perf_counter()
    slope_deg = check_finite(min_slope, "min_slope", "degrees")
    if not 0.0 < slope_deg < 90.0:
        raise ParameterError(f"min_slope must lie in (0, 90) degrees, got {slope_deg:g}")
    if not isinstance(faceset, FaceSet):
        raise ParameterError(f"faceset must be a FaceSet, got {type(faceset).__name__}")
    monitor = Monitor(progress, None, "waterline")
    monitor(0.0)
    R = tool.radius
    slope = math.radians(slope_deg)
    query = _MemoQuery(faceset, R)
    signs = _upward_signs(faceset)
    lo, hi = faceset.bounds(selected_only=True)
    g = R / 4.0
    xs = np.linspace(lo[0] - R, hi[0] + R, max(3, math.ceil((hi[0] - lo[0] + 2 * R) / g) + 1))
    ys = np.linspace(lo[1] - R, hi[1] + R, max(3, math.ceil((hi[1] - lo[1] + 2 * R) / g) + 1))
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = query.heights(np.column_stack([X.ravel(), Y.ravel()]))[0].reshape(X.shape)
    monitor(0.3)
    zs, dzs, z_low, z_high = _steep_samples(faceset, tool, signs, slope)
    levels = level_heights(zs, dzs, tool, slope, z_high, z_low)
    nx, ny = Z.shape
    corners = np.empty((2 * nx * ny, 2, 2), dtype=np.intp)  # edge key -> two grid corners
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    fi, fj = ii.ravel(), jj.ravel()
    corners[: nx * ny, 0] = np.column_stack([fi, fj])
    corners[: nx * ny, 1] = np.column_stack([np.minimum(fi + 1, nx - 1), fj])
    corners[nx * ny:, 0] = np.column_stack([fi, fj])
    corners[nx * ny:, 1] = np.column_stack([fi, np.minimum(fj + 1, ny - 1)])
    polylines, heights = [], []
    for level in levels:
        segments, _, _ = _crossings(Z, level)
        for chain in _chain(segments):
            polylines.append(np.asarray(chain))
            heights.append(level)
    notes = shallow_notes(*_face_normals(faceset, signs), slope, "the selected faces'")
    parameters = {"strategy": "waterline", "tool_diameter": tool.diameter, "scallop": tool.scallop,
                  "tolerance": tool.tolerance, "min_slope": slope_deg,
                  "faces": [f.name for f in faceset.faces if f.selected]}
    steps = -np.diff(levels)
    stats = ToolpathStats(stepover_min_mm=float(steps.min()) if len(steps) else math.nan,
                          stepover_max_mm=float(steps.max()) if len(steps) else math.nan,
                          notes=notes)
    extra: dict = {"levels": levels}
    passes: list = []
    if polylines:
        passes, more = _contours(faceset, query, signs, tool, Z, xs, ys, corners, polylines,
                                 heights, monitor)
        extra.update(more)
    if not passes:
        notes.append("no waterline touches a selected face")
    # contours in the order of short moves (upper levels first over lower ones, open ones
    # either way), joined by stay-down feeds where the next starts within STAY_DOWN_LINK R
    if direction not in ("zigzag", "oneway"):
        raise ParameterError(f"direction must be zigzag or oneway, got {direction!r}")
    passes = orient_climb(passes, lambda xy: query.heights(xy)[0],
                          max(0.05 * R, 4.0 * tool.tolerance))
    passes = order_contours(passes, tool.diameter, reversible=direction == "zigzag")
    links = stay_down_links(query, passes, STAY_DOWN_LINK * R, tool.tolerance) if passes else []
    extra["dropcutter"] = dict(faceset.stats)
    toolpath = Toolpath("waterline", passes, parameters, [], stats, extra=extra, links=links)
    toolpath.finish(started, None)
    monitor(1.0)
    return toolpath


def _contours(faceset: FaceSet, query: FaceQuery, signs: np.ndarray, tool: ToolParameters,
              Z: FloatArray, xs: FloatArray, ys: FloatArray, corners: np.ndarray,
              polylines: list, heights: list, monitor: Monitor) -> tuple[list, dict]:
    """Level points on the grid edges of the chained contours, polished, split to the
    selected surface contacts, densified, thinned and pushed out (see the module docstring)."""
    keys = np.concatenate(polylines)
    zl = np.concatenate([np.full(len(p), h) for p, h in zip(polylines, heights)])
    c0, c1 = corners[keys, 0], corners[keys, 1]
    p0 = np.column_stack([xs[c0[:, 0]], ys[c0[:, 1]]])
    p1 = np.column_stack([xs[c1[:, 0]], ys[c1[:, 1]]])
    z0, z1 = Z[c0[:, 0], c0[:, 1]], Z[c1[:, 0], c1[:, 1]]
    width = JUMP_WIDTH * tool.tolerance
    # the crossings take most of the time: the progress bar moves with the edges settled
    t, jump, t_up, settled = polish_crossings(lambda q: query.heights(q)[0], p0, p1, z0, z1, zl,
                                              LEVEL_EPS * tool.tolerance, width,
                                              progress=lambda f: monitor(0.3 + 0.2 * f),
                                              slopes=lambda q: query.heights_and_slopes(q)[1])
    xy = p0 + t[:, None] * (p1 - p0)
    _tip, good = _contacts(faceset, query, signs, xy)
    if jump.any():
        # the ball beside a jump touches what it follows on its rim: the contact that counts
        # is the one just above the level, tilted by up to sqrt(2 width / R) from the normal,
        # with the wall the ball's side meets at the level on that face too
        up = p0[jump] + t_up[jump, None] * (p1[jump] - p0[jump])
        tilt = SURFACE_TILT + 2.0 * math.sqrt(2.0 * width / tool.radius)
        ok = _contacts(faceset, query, signs, up, tilt)[1]
        ok[ok] = _wall_on_face(faceset, query, up[ok], zl[jump][ok] + tool.radius,
                               tool.tolerance)
        good[jump] = ok
    monitor(0.5)
    # split each contour to its runs on selected surface contacts; each run end next to a
    # dropped point is carried on along the level to where the contact leaves the face
    starts = np.cumsum([0] + [len(p) for p in polylines])
    runs, ends = [], []  # ends: (run, at_start, kept index, dropped index)
    for a, b, poly in zip(starts[:-1], starts[1:], polylines):
        closed = len(poly) > 2 and poly[0] == poly[-1]
        m = b - a
        for run in _runs(good[a:b], closed):
            r = len(runs)
            runs.append(a + run)
            if len(run) == m:
                continue
            before = run[0] - 1 if run[0] > 0 else (m - 2 if closed else -1)
            after = run[-1] + 1 if run[-1] < m - 1 else (1 if closed else -1)
            if before >= 0:
                ends.append((r, True, a + run[0], a + before))
            if after >= 0:
                ends.append((r, False, a + run[-1], a + after))
    if not runs:
        return [], {}
    extended = {}
    if ends:
        e = np.array([(k, d) for _r, _s, k, d in ends])
        tips = _refine_ends(faceset, query, signs, xy[e[:, 0]], xy[e[:, 1]], zl[e[:, 0]])
        for (r, at_start, _k, _d), q in zip(ends, tips):
            extended[(r, at_start)] = q
    pieces = []
    for r, run in enumerate(runs):
        p = np.column_stack([xy[run], zl[run]])
        head, tail = extended.get((r, True)), extended.get((r, False))
        level = zl[run[0]]
        if head is not None:
            p = np.vstack([[head[0], head[1], level], p])
        if tail is not None:
            p = np.vstack([p, [tail[0], tail[1], level]])
        pieces.append(p)
    pts = np.concatenate(pieces)
    starts = np.cumsum([0] + [len(p) for p in pieces])
    pts, starts = densify(_FiniteQuery(query), pts, starts, 0.25 * tool.tolerance)
    monitor(0.7)
    # the kept jump points (found by their exact XY, which densify and simplify leave alone)
    # ride along in a fourth column: beside a jump the ball's contact is on its rim, which
    # the final check below cannot see at the air side
    beside = {k for k, j in zip(_xy_keys(xy), jump & good) if j}
    pts = np.column_stack([pts, [k in beside for k in _xy_keys(pts[:, :2])]])
    if beside:
        pts, starts = _densify_jumps(query, pts, starts, 0.5 * tool.tolerance, width)
    keep = simplify(pts, starts, 0.5 * tool.tolerance, "planar")
    passes = [pts[a:b][keep[a:b]] for a, b in zip(starts[:-1], starts[1:])]
    step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)
    passes, push_stats = push_out(_FiniteQuery(query), passes, step, drop_dips=True,
                                  follow_jumps=True, off_level=LEVEL_EPS * tool.tolerance)
    monitor(0.9)
    # vertices pushed off the selected faces' surface contacts end their run
    out = []
    if not passes:
        return [], {"chord_push": push_stats}
    allv = np.concatenate(passes)
    _tip, good = _contacts(faceset, query, signs, allv[:, :2])
    good |= allv[:, 3] > 0.0
    starts = np.cumsum([0] + [len(p) for p in passes])
    for a, b, p in zip(starts[:-1], starts[1:], passes):
        closed = len(p) > 2 and bool(np.all(p[0] == p[-1]))
        out.extend(p[run, :3] for run in _runs(good[a:b], closed))
    crossings = {"crossings": len(t), "jumps": int(jump.sum()),
                 "unsettled": int(np.count_nonzero(~settled))}
    return out, {"chord_push": push_stats, "crossings": crossings}


def _xy_keys(xy: FloatArray) -> list:
    """Exact (x, y) of each row as bytes (rows equal bit for bit share a key)."""
    q = np.ascontiguousarray(np.asarray(xy, dtype=float)[:, :2])
    return q.view(np.dtype((np.void, q.itemsize * 2))).ravel().tolist()


__all__ = ["FALSI_STEPS", "JUMP_WIDTH", "SURFACE_TILT", "generate_faces_waterline",
           "level_heights", "polish_crossings", "waterline_faces"]
