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

Distances to the faces: :mod:`..geometry.face_distance`.

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

from ..geometry.face_distance import FaceDistance, dot, golden_min
from ..geometry.faces import Face
from ..program.gcode_words import Segments
from ..typing import FloatArray
from .simulate import Grid, Tool, ToolShape

#: Flagged cells measured at most (the worst first); the others keep their vertical gouge.
MAX_CELLS = 200
#: Spacing (mm) of the ball's centres along a move before refinement.
PATH_STEP_MM = 0.05
#: Design - machined above this (mm) flags a cell (verify's GOUGE_TOLERANCE_MM).
GOUGE_TOLERANCE_MM = 1e-3


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
            path_step: float = PATH_STEP_MM, distance: FaceDistance | None = None,
            tool_of: np.ndarray | None = None) -> NormalGouge:
    """Measure the cells of ``mask`` where ``design - machined > tolerance`` (mm) along the
    normal (module docstring): at most ``max_cells`` of them, the deepest first.

    ``segments`` are the linearised moves the Z-map ``machined`` came from, cut by
    ``tools[tool_of[i]]`` (``tools[0]`` for every segment without ``tool_of``; -1: a move
    that cuts nothing, of a tool the simulation did not have); ``design`` is the top-most
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
    if not len(cx):
        return NormalGouge((), tuple(unmeasured), len(flagged), path_step)
    start = np.asarray(segments.start, dtype=float)
    end = np.asarray(segments.end, dtype=float)
    which = np.zeros(len(start), np.intp) if tool_of is None else np.asarray(tool_of, np.intp)
    # index -1 picks the last entry: no reach
    radius = np.array([*(t.radius for t in tools), -np.inf])[which]
    ball = np.array([*(t.shape is ToolShape.BALL for t in tools), True])[which]
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
    bb, ab, aa = dot(b, b), dot(a, b), dot(a, a) - radius * radius
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
