# SPDX-License-Identifier: LGPL-2.1-or-later
"""Waterline finishing: constant-Z contours of the ball's cutter-location surface.

At tip height z the ball touches the surface without cutting exactly where the drop-cutter
height c(x, y) - R equals z, so each waterline is a level set of the exact drop-cutter field
(the offset surface S + R n with its folds resolved by the max).  Levels are found by
marching squares (Lorensen & Cline 1987) on a grid of exact heights, each crossing is
polished on its grid edge by regula falsi on the exact drop-cutter, points projected onto the
level are inserted between crossings until the contour follows it to tolerance / 4
(:func:`densify`), the result is thinned by Douglas–Peucker to tolerance / 2 in XY, and every
chord is checked against the exact drop-cutter: where the ball would dip below the level (a
chord across a convex contour) the vertices are pushed outwards (:func:`push_out`).  The push
is thus bounded by the chordal tolerance; on a wall of slope alpha it lifts the ball by about
push * tan(alpha), which the scallop budget h + tolerance absorbs.
The step-down follows the scallop on walls: adjacent contours a slope alpha apart along the
surface are dz / sin(alpha) apart, so dz = s sin(alpha) with s the curvature-adjusted
stepover; walls shallower than ``min_slope`` are left to a raster pass (reported in notes).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..typing import FloatArray
from .chords import (
    CLEARANCE,
    DIP_LIMIT,
    MAX_SLOPE,
    NEGLIGIBLE,
    chord_excess,
    sample_chords,
)
from .common import (
    NEAR_FIT,
    Monitor,
    ToolParameters,
    curved_stepover,
    normal_curvature,
    simplify,
)
from .dropcutter import DropCutter

#: Least share of the area flatter than the waterline's slope threshold that gets a note.
SHALLOW_NOTE = 0.005

#: Marching-squares segments per case (corner bits: 1 = (i, j), 2 = (i+1, j), 4 = (i+1, j+1),
#: 8 = (i, j+1)); edges 0 = bottom, 1 = right, 2 = top, 3 = left.  Saddles 5 and 10 are split
#: by the cell-centre value at run time.
CASES = {
    1: [(3, 0)], 2: [(0, 1)], 3: [(3, 1)], 4: [(1, 2)], 6: [(0, 2)], 7: [(3, 2)],
    8: [(2, 3)], 9: [(2, 0)], 11: [(2, 1)], 12: [(1, 3)], 13: [(1, 0)], 14: [(0, 3)],
}


def level_heights(dc: DropCutter, tool: ToolParameters, min_slope: float,
                  z_top: float, z_bottom: float) -> list[float]:
    """Tip heights of the waterlines, top down (mm), from scallop-limited step-downs."""
    uu, ww = np.meshgrid(dc.u, dc.w, indexing="ij")
    jet = dc.jet(uu.ravel(), ww.ravel())
    n = jet.normal
    sin_a = np.sqrt(np.clip(1.0 - n[:, 2] ** 2, 0.0, 1.0))
    steep = sin_a >= math.sin(min_slope)
    # Steepest-descent direction in the tangent plane: across the waterlines.
    down = np.column_stack([n[:, 0] * n[:, 2], n[:, 1] * n[:, 2], n[:, 2] ** 2 - 1.0])
    dz = level_steps(tool, n, normal_curvature(jet, down))
    z_off = jet.p[:, 2] + tool.radius * (n[:, 2] - 1.0)
    order = np.argsort(z_off[steep])
    return step_levels(z_off[steep][order], dz[steep][order], tool, min_slope, z_top, z_bottom,
                       gap=dc.margin ** 0.5)


def level_steps(tool: ToolParameters, n: FloatArray, kappa: FloatArray) -> FloatArray:
    """Step-down (mm) between waterlines that keeps the scallop within ``tool.scallop`` at
    surface samples with upward unit normals ``n`` (m, 3) and normal curvature ``kappa``
    (1/mm, concave > 0) down their slope; inf where the ball fits the hollow across the
    levels (a concave radius up to R / (1 - NEAR_FIT)) or cannot enter it.

    The scallop is held vertically (as the machined part is measured): h n_z along the normal.
    curved_stepover spaces the contact points; the levels space ball centres, which sit on a
    circle of radius rho - R sign about the centre of curvature: factor 1 - R kappa, which
    vanishes where the ball fits.  There every level's ball would touch the hollow only at
    its fitting height (its centre on the hollow's axis), so no step-down holds the scallop;
    such samples bound none, as in the raster's stepover (:data:`.common.NEAR_FIT`).  A
    filleted foot of a boss whose radius is the ball's had set 30 levels 0.04 mm apart, each
    cut round the boss's wall and dropped there (the contact on the wall, not the fillet).
    """
    R = tool.radius
    sin_a = np.sqrt(np.clip(1.0 - n[:, 2] ** 2, 0.0, 1.0))
    contact = curved_stepover(R, tool.scallop * np.clip(n[:, 2], 0.05, 1.0), kappa)
    dz = contact * np.clip(1.0 - R * kappa, 0.05, None) * sin_a
    return np.where(kappa * R >= 1.0 - NEAR_FIT, np.inf, dz)


def step_levels(zs: FloatArray, dzs: FloatArray, tool: ToolParameters, min_slope: float,
                z_top: float, z_bottom: float, gap: float) -> list[float]:
    """Tip heights of the waterlines from ``z_top`` down to above ``z_bottom`` (mm): each step
    the least step-down ``dzs`` (mm) of the steep samples whose tip heights ``zs`` (mm,
    ascending) lie in the band it spans, widened by ``gap`` (mm); the flat stepover where the
    band holds none, and never below 2 % of its vertical share at ``min_slope`` (rad).  One
    control net (here) and a model's faces (faces_waterline) step down alike."""
    floor = tool.flat_stepover * math.sin(min_slope)
    levels = []
    z = z_top
    while True:
        step = tool.flat_stepover
        for _ in range(6):
            lo, hi = np.searchsorted(zs, [z - step - gap, z + gap])
            need = max(float(dzs[lo:hi].min()), 0.02 * floor) if hi > lo else step
            if need >= 0.999 * step:
                break
            step = need
        z -= step
        if z <= z_bottom:
            break
        levels.append(z)
    return levels


def _crossings(Z: FloatArray, level: float) -> tuple[list, np.ndarray, np.ndarray]:
    """Marching squares: segments as pairs of edge keys, and per key its two grid corners."""
    above = np.nan_to_num(Z, nan=-np.inf) > level
    a00, a10 = above[:-1, :-1], above[1:, :-1]
    a11, a01 = above[1:, 1:], above[:-1, 1:]
    case = a00 * 1 + a10 * 2 + a11 * 4 + a01 * 8
    segments = []
    ci, cj = np.nonzero((case != 0) & (case != 15))
    cases = case[ci, cj]
    nx, ny = Z.shape
    for c, ii, jj in zip(cases.tolist(), ci.tolist(), cj.tolist()):
        if c in (5, 10):
            centre = np.nanmean(Z[ii:ii + 2, jj:jj + 2]) > level
            pairs = {(5, True): [(3, 2), (1, 0)], (5, False): [(3, 0), (1, 2)],
                     (10, True): [(0, 3), (2, 1)], (10, False): [(0, 1), (2, 3)]}[(c, centre)]
        else:
            pairs = CASES[c]
        for e0, e1 in pairs:
            segments.append((_edge_key(ii, jj, e0, nx, ny), _edge_key(ii, jj, e1, nx, ny)))
    return segments, above, case


def _edge_key(i: int, j: int, edge: int, nx: int, ny: int) -> int:
    """Horizontal edges (i, j)-(i+1, j) are keys i*ny + j; vertical ones get offset nx*ny."""
    if edge == 0:
        return i * ny + j
    if edge == 2:
        return i * ny + j + 1
    if edge == 3:
        return nx * ny + i * ny + j
    return nx * ny + (i + 1) * ny + j


def _chain(segments: list) -> list[list[int]]:
    """Link segments sharing edge keys into polylines (closed loops repeat their first key)."""
    links: dict[int, list[int]] = {}
    for s, (a, b) in enumerate(segments):
        links.setdefault(a, []).append(s)
        links.setdefault(b, []).append(s)
    used = [False] * len(segments)
    chains = []
    ends = [k for k, v in links.items() if len(v) == 1]
    for start in ends + [k for k in links if len(links[k]) != 1]:
        for s0 in links[start]:
            if used[s0]:
                continue
            chain = [start]
            key, seg = start, s0
            while True:
                used[seg] = True
                a, b = segments[seg]
                key = b if a == key else a
                chain.append(key)
                nxt = [s for s in links[key] if not used[s]]
                if not nxt:
                    break
                seg = nxt[0]
            chains.append(chain)
    return chains


def waterline(surface: Any, tool: ToolParameters, min_slope: float, monitor: Monitor,
              dc: DropCutter) -> tuple[list, dict]:
    """Closed or open contours (lists of (n, 3) tip positions), top level first."""
    g = tool.radius / 4.0
    lo, hi = dc.lo, dc.hi
    xs = np.linspace(lo[0], hi[0], max(3, math.ceil((hi[0] - lo[0]) / g) + 1))
    ys = np.linspace(lo[1], hi[1], max(3, math.ceil((hi[1] - lo[1]) / g) + 1))
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    Z = dc.heights(np.column_stack([X.ravel(), Y.ravel()]))[0].reshape(X.shape)
    monitor(0.3)
    levels = level_heights(dc, tool, min_slope, float(np.nanmax(Z)), float(np.nanmin(Z)))
    nx, ny = Z.shape
    corners = np.empty((2 * nx * ny, 2, 2), dtype=np.intp)  # edge key -> two grid corners
    ii, jj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    flat_i, flat_j = ii.ravel(), jj.ravel()
    corners[: nx * ny, 0] = np.column_stack([flat_i, flat_j])  # (i, j)-(i+1, j)
    corners[: nx * ny, 1] = np.column_stack([np.minimum(flat_i + 1, nx - 1), flat_j])
    corners[nx * ny:, 0] = np.column_stack([flat_i, flat_j])  # (i, j)-(i, j+1)
    corners[nx * ny:, 1] = np.column_stack([flat_i, np.minimum(flat_j + 1, ny - 1)])
    polylines, heights = [], []
    for k, level in enumerate(levels):
        segments, _, _ = _crossings(Z, level)
        for chain in _chain(segments):
            polylines.append(np.asarray(chain))
            heights.append(level)
        monitor(0.3 + 0.3 * (k + 1) / max(len(levels), 1))
    if not polylines:
        return [], {"levels": levels, "notes": ["no waterline levels"]}
    keys = np.concatenate(polylines)
    zl = np.concatenate([np.full(len(p), h) for p, h in zip(polylines, heights)])
    c0, c1 = corners[keys, 0], corners[keys, 1]
    p0 = np.column_stack([xs[c0[:, 0]], ys[c0[:, 1]]])
    p1 = np.column_stack([xs[c1[:, 0]], ys[c1[:, 1]]])
    z0 = np.nan_to_num(Z[c0[:, 0], c0[:, 1]], nan=-1e9)
    z1 = np.nan_to_num(Z[c1[:, 0], c1[:, 1]], nan=-1e9)
    # Regula falsi on each edge against the exact drop-cutter (Illinois variant).
    t0, t1 = np.zeros(len(keys)), np.ones(len(keys))
    f0, f1 = z0 - zl, z1 - zl
    for _ in range(12):
        t = np.clip((t0 * f1 - t1 * f0) / np.where(f1 != f0, f1 - f0, 1.0), 0.0, 1.0)
        ft = np.nan_to_num(dc.heights(p0 + t[:, None] * (p1 - p0))[0], nan=-1e9) - zl
        same = np.sign(ft) == np.sign(f0)
        t0, f0, t1, f1 = (np.where(same, t, t0), np.where(same, ft, 0.5 * f0),
                          np.where(same, t1, t), np.where(same, 0.5 * f1, ft))
    t = np.where(np.abs(f0) < np.abs(f1), t0, t1)
    xy = p0 + t[:, None] * (p1 - p0)
    pts = np.column_stack([xy, zl])
    starts = np.cumsum([0] + [len(p) for p in polylines])
    pts, starts = densify(dc, pts, starts, 0.25 * tool.tolerance)
    monitor(0.8)
    keep = simplify(pts, starts, 0.5 * tool.tolerance, "planar")
    passes = [pts[a:b][keep[a:b]] for a, b in zip(starts[:-1], starts[1:])]
    step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)
    passes, push_stats = push_out(dc, passes, step)
    monitor(0.95)
    steps = -np.diff(levels) if len(levels) > 1 else np.array([np.nan])
    return passes, {
        "levels": levels, "stepover_min_mm": float(np.nanmin(steps)),
        "stepover_max_mm": float(np.nanmax(steps)), "chord_push": push_stats,
        "notes": shallow_notes(*_surface_normals(dc), min_slope, "the surface's"),
    }


def _surface_normals(dc: DropCutter) -> tuple[FloatArray, FloatArray]:
    """Upward normals' z and area weights (mm^2) at the drop-cutter's sample grid."""
    uu, ww = np.meshgrid(dc.u, dc.w, indexing="ij")
    jet = dc.jet(uu.ravel(), ww.ravel())
    du = np.gradient(np.asarray(dc.u, float))
    dw = np.gradient(np.asarray(dc.w, float))
    cross = np.cross(jet.su, jet.sw)
    return jet.normal[:, 2], np.linalg.norm(cross, axis=1) * np.outer(du, dw).ravel()


def shallow_share(nz: FloatArray, area: FloatArray, min_slope: float) -> float:
    """Share of the area (weights ``area`` at samples whose upward unit normal has z ``nz``)
    flatter than ``min_slope`` (rad)."""
    total = float(np.sum(area))
    return float(np.sum(area[np.asarray(nz) > math.cos(min_slope)])) / total if total else 0.0


def shallow_notes(nz: FloatArray, area: FloatArray, min_slope: float, whose: str) -> list[str]:
    """The waterline's note on what it leaves: the :func:`shallow_share` of the area, which no
    level finishes (none if under SHALLOW_NOTE of it)."""
    share = shallow_share(nz, area, min_slope)
    if share < SHALLOW_NOTE:
        return []
    return [f"{100.0 * share:.0f} % of {whose} area is flatter than "
            f"{math.degrees(min_slope):g} degrees and is not finished by waterline: pair it "
            "with a raster pass, or use the steep_shallow strategy"]


def densify(dc: DropCutter, pts: FloatArray, starts: np.ndarray, gap: float,
            rounds: int = 12) -> tuple[FloatArray, np.ndarray]:
    """Insert level-set points between contour vertices until every chord's midpoint lies
    within ``gap`` (XY, mm) of the level set.

    Marching squares leaves one vertex per grid edge (up to ~R/4 * sqrt 2 apart); across a
    convex contour such a chord sags by L^2 / (8 r) in XY, which :func:`push_out` would have
    to make good by moving the vertices outwards just as far, and on a wall of slope alpha
    that lifts the ball, and the scallop, by the sag times tan alpha.  Each round projects
    the midpoints of the chords still too far off onto the level by Newton steps along the
    exact drop-cutter gradient (clipped to half the chord) and inserts them; only the two
    halves of a split chord are examined again.
    """
    line = np.repeat(np.arange(len(starts) - 1), np.diff(starts))
    active = line[:-1] == line[1:]  # per chord (i, i + 1)
    for _ in range(rounds):
        idx = np.flatnonzero(active)
        if len(idx) == 0:
            break
        a, b = pts[idx], pts[idx + 1]
        level = a[:, 2]
        m = 0.5 * (a[:, :2] + b[:, :2])
        half = 0.5 * np.hypot(*(b[:, :2] - a[:, :2]).T)
        q = m.copy()
        good = np.ones(len(idx), bool)
        norm = np.full(len(idx), np.inf)
        for k in range(3):
            # a point whose last step was already below the insertion bound has converged
            # (Newton's next step is smaller still): it is not asked about again
            go = np.flatnonzero(~(norm < 1e-3 * gap))
            if len(go) == 0:
                break
            z, g = dc.heights_and_slopes(q[go])
            with np.errstate(divide="ignore", invalid="ignore"):
                step = ((level[go] - z) / np.einsum("ij,ij->i", g, g))[:, None] * g
            norm[go] = np.hypot(step[:, 0], step[:, 1])
            good[go] &= np.isfinite(norm[go])  # off the surface, or no gradient to follow
            if k == 0:
                # Midpoints already within the gap (or off the surface) end their chord.
                keep = good & (norm > gap)
                idx, level, m, half, q, step, norm, good = (
                    v[keep] for v in (idx, level, m, half, q, step, norm, good))
                go = np.arange(len(idx))
            step = np.where(good[go, None], step, 0.0)
            step *= np.minimum(1.0, half[go] / np.maximum(norm[go], 1e-300))[:, None]
            q[go] = q[go] + step
        # Inserted only where Newton converged (last step tiny) and the point is off the chord.
        ok = good & (norm < 1e-3 * gap) & (np.hypot(*(q - m).T) > gap)
        active[:] = False
        if not ok.any():
            break
        at = idx[ok] + 1
        pts = np.insert(pts, at, np.column_stack([q[ok], level[ok]]), axis=0)
        line = np.insert(line, at, line[at - 1])
        active = np.insert(active, at, False)
        new = at + np.arange(len(at))  # positions of the inserted points
        active[new - 1] = True
        active[new] = True
    starts = np.searchsorted(line, np.arange(line[-1] + 2)) if len(line) else starts
    return pts, starts


#: push_out's default accuracy (mm) of the level points in height: a vertex farther than this
#: from its level, beyond what push_out's own smooth shifts explain, lies beside a jump of the
#: height (on its air side), where the gradients of its chords mean nothing (:func:`_beside_jump`).
OFF_LEVEL = 1e-6
#: Deepest dip (mm) of a chord beside a jump that its samples may miss (:func:`_jump_chord_excess`).
UNSEEN_DIP = 1e-4


def push_out(dc: DropCutter, passes: list, step: float, iterations: int = 6,
             drop_dips: bool = False, follow_jumps: bool = False,
             off_level: float = OFF_LEVEL) -> tuple[list, dict]:
    """Move waterline vertices outwards (downhill, in XY) until no chord at the level has the
    exact drop-cutter height above it: a chord across a convex contour lies inside the offset.

    A chord whose worst point is ``e`` above the level, where the height falls at rate
    |grad . m| across the chord (m its unit XY normal, pointing downhill), is shifted by
    (e + CLEARANCE) / |grad . m|; a shared vertex moves along the bisector of its chords'
    normals far enough for both.  Repeated until no chord dips more than ``DIP_LIMIT``.

    With ``follow_jumps`` (the faces' waterline, whose contours follow jumps of the height),
    where that shift would exceed a quarter of the chord (no smooth sag is that deep), the
    height is steeper than ``MAX_SLOPE`` at the worst point or an end lies beside a jump (no
    face, a jump shift of an earlier round, or off its level by more than ``off_level``, the
    level points' accuracy, plus what the smooth shifts explain: :func:`_beside_jump`), the
    height may jump inside the chord (the ball's
    rim on a wall, the model's edge: e is the jump's height and the gradient means nothing):
    the shift is found instead by searching along both normals from the worst point for the
    nearest point on the free side (height at most the level, or no face), halving from half
    the chord's length (:func:`_free_distance`), and the chords beside a jump are checked by
    samples spaced for ``UNSEEN_DIP`` (:func:`_jump_chord_excess`).  Every shift is thus at
    most half its chord, and the point count stays bounded.  Without it (one net's
    waterline) every chord is certified by :func:`chord_excess` alone, to ``DIP_LIMIT``.
    With ``drop_dips`` the chords still dipping after the last iteration are cut out of
    their passes (the tool is never left below the drop height); the stats count them.
    """
    passes = [np.array(p, dtype=float) for p in passes]
    moved_max = 0.0
    worst = np.inf
    it = 0
    jumps = 0
    check = None
    # per vertex (their count never changes here): the level deviation (mm) the smooth shifts
    # so far explain, and whether a jump shift moved it
    nv = sum(len(p) for p in passes)
    explained = np.zeros(nv)
    jumped = np.zeros(nv, bool)
    off = jumped
    for it in range(1, iterations + 2):
        s = sample_chords(dc.heights_and_slopes, passes, [p[:, 2] for p in passes], step)
        if follow_jumps:
            off = _beside_jump(s, explained, jumped, off_level)
            _hide_jump_chords(s, off)
        check = chord_excess(dc.heights_and_slopes, s)
        if follow_jumps:
            _jump_chord_excess(dc, s, check, off)
        worst = float(np.max(check.excess, initial=-np.inf))
        if worst <= NEGLIGIBLE or it > iterations:
            break
        vxy, vzv, vline = s.vertices()
        gv = s.grad[s.vertex]
        same = np.append(vline[1:] == vline[:-1], False)
        nxt = np.minimum(np.arange(len(vxy)) + 1, len(vxy) - 1)
        d = vxy[nxt] - vxy
        length = np.hypot(d[:, 0], d[:, 1])
        normal = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(length, 1e-300)[:, None]
        # halves first: an infinite slope's stand-in (the largest float) must not overflow
        grad = np.where(np.isfinite(check.grad), check.grad,
                        0.5 * np.nan_to_num(gv) + 0.5 * np.nan_to_num(gv[nxt]))
        rate = np.einsum("ij,ij->i", grad, normal)
        normal *= -np.sign(np.where(rate == 0, 1.0, rate))[:, None]  # downhill
        rate = np.maximum(np.abs(rate), 1e-3)
        need = same & np.isfinite(check.excess) & (check.excess > NEGLIGIBLE)
        shift = np.where(need, (np.maximum(check.excess, 0.0) + CLEARANCE) / rate, 0.0)
        cand = np.flatnonzero(need)
        where, gw = _worst_points(s, check, cand)
        # a vertex beside a jump (no face, or far below) makes its chords jump
        steep = ~(np.abs(gw).max(axis=1, initial=0.0) <= MAX_SLOPE)
        steep |= off[cand] | off[nxt[cand]] | (shift[cand] > 0.25 * length[cand])
        if not follow_jumps:
            steep[:] = False
        jump = cand[steep]
        where = where[steep]
        if len(jump):
            jumps += len(jump)
            dist, side = _free_distance(dc, where, normal[jump], vzv[jump], 0.5 * length[jump])
            shift[jump] = np.where(np.isfinite(dist), dist + CLEARANCE, 0.5 * length[jump])
            normal[jump] *= np.where(np.isfinite(dist), side, 1.0)[:, None]
        # Vertex r takes chord r (r -> r+1) and chord r-1 (r-1 -> r) of the same line.
        prev = np.append(False, same[:-1])
        m1 = np.where(need[:, None], normal, 0.0)
        m0 = np.zeros_like(m1)
        s0 = np.zeros(len(vxy))
        m0[1:] = np.where(prev[1:, None] & need[:-1, None], normal[:-1], 0.0)
        s0[1:] = np.where(prev[1:], shift[:-1], 0.0)
        both = m0 + m1
        norm = np.hypot(both[:, 0], both[:, 1])
        direction = both / np.where(norm > 0, norm, 1.0)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            c1 = np.einsum("ij,ij->i", direction, m1)
            c0 = np.einsum("ij,ij->i", direction, m0)
            amount = np.fmax(np.where(c1 > 0.1, shift / c1, 0.0),
                             np.where(c0 > 0.1, s0 / c0, 0.0))
        amount = np.where(norm > 0, amount, 0.0)
        move = direction * amount[:, None]
        # Closed contours repeat their first vertex at the end: move both copies alike.
        firsts = np.flatnonzero(np.append(True, vline[1:] != vline[:-1]))
        lasts = np.append(firsts[1:] - 1, len(vline) - 1)
        closed = np.hypot(*(vxy[firsts] - vxy[lasts]).T) < 1e-9
        fc, lc = firsts[closed], lasts[closed]
        joint = move[fc] + move[lc]
        move[fc] = joint
        move[lc] = joint
        moved_max = max(moved_max, float(np.hypot(move[:, 0], move[:, 1]).max(initial=0.0)))
        if follow_jumps:
            # a smooth shift lowers the vertex's height by about |grad| times its length (twice
            # that is allowed, and the clearance); a vertex a jump shift moved, or one without a
            # gradient, stays beside a jump
            jumped[jump] = True
            jumped[nxt[jump]] = True
            with np.errstate(over="ignore"):  # a jump's stand-in slope: inf, as meant
                slope = np.maximum(np.hypot(gv[:, 0], gv[:, 1]),
                                   np.hypot(grad[:, 0], grad[:, 1]))
            slope[1:] = np.maximum(slope[1:], np.where(prev[1:], slope[:-1], 0.0))
            moved = amount > 0
            jumped |= moved & ~np.isfinite(slope)
            explained += np.where(moved & np.isfinite(slope),
                                  2.0 * amount * slope + CLEARANCE, 0.0)
        new = vxy + move
        cuts = np.flatnonzero(np.diff(vline)) + 1
        passes = [np.column_stack([q, p[:, 2:]]) for q, p in zip(np.split(new, cuts), passes)]
    dipping = 0
    if check is not None and worst > NEGLIGIBLE:
        bad = np.isfinite(check.excess) & (check.excess > DIP_LIMIT)
        dipping = int(bad.sum())
        if drop_dips and dipping:
            passes = _cut_chords(passes, bad)
    return passes, {"max_push_mm": moved_max, "worst_dip_mm": worst,
                    "iterations": min(it, iterations), "jump_chords": jumps,
                    "dipping_chords": dipping}


def _beside_jump(s, explained: FloatArray, jumped: np.ndarray, off_level: float) -> np.ndarray:
    """Whether each vertex lies beside a jump of the height: no face under the ball, moved by
    a jump shift (``jumped``), off its level by more than ``off_level`` (mm, the level
    points' own accuracy) plus what push_out's smooth shifts explain (``explained``, mm):
    a vertex shifted downhill stands below its level by about its chord's excess, and its
    chords are smooth ones still; or near the ball's rim, the height steeper there than
    ``MAX_SLOPE`` (a face turning vertical: a fillet's end over a wall).  A contour there runs
    along the steep slope, and every interval of its chords is too steep for
    :func:`chord_excess`'s model (its ends level, the height between them no monotone rise).
    chord_excess now cuts only ROUGH_PER_CHORD such intervals of a chord a round (it had cut
    them all, 140 000 queries in one round round a box's filleted edge), so a long chord there
    would end unresolved, bounded by its samples; its chords are sampled as a jump's instead
    (:func:`_jump_chord_excess`, spaced for ``UNSEEN_DIP``)."""
    dev = np.abs(s.z[s.vertex] - s.zv[s.vertex])
    g = s.grad[s.vertex]
    with np.errstate(over="ignore", invalid="ignore"):
        rim = ~(np.hypot(g[:, 0], g[:, 1]) <= MAX_SLOPE)
    return jumped | ~(dev <= off_level + explained) | rim


def _hide_jump_chords(s, off: np.ndarray) -> None:
    """Blank (NaN) the inner samples of the chords with an end beside a jump (``off``, per
    vertex): there :func:`chord_excess` would cut every interval across it down to
    ``MIN_SPLIT`` and learn nothing (its model needs a height at both ends);
    :func:`_jump_chord_excess` checks them."""
    vxy, vzv, vline = s.vertices()
    jump = np.append((vline[1:] == vline[:-1]) & (off[:-1] | off[1:]), False)
    rank = np.cumsum(s.vertex) - 1
    blank = ~s.vertex & jump[rank]
    s.z[blank] = np.nan
    s.grad[blank] = np.nan


def _jump_chord_excess(dc: DropCutter, s, check, off: np.ndarray) -> None:
    """Exact samples along the chords with an end off its level (beside a jump), raising
    their excess in ``check`` where one stands higher than the chord (and making it the
    chord's worst point).  :func:`chord_excess` examines only intervals with a height at both
    ends: between two samples with no face under the ball (the air side of a jump) it sees
    nothing, yet a chord across a convex jump dips into the model between them.  Beside a
    jump the ball's side meets a wall or an edge, whose offset curves by 1 / R at most: a
    dip between samples h apart is at most h^2 / (8 R) deep, so they are spaced for
    ``UNSEEN_DIP``."""
    vxy, vzv, vline = s.vertices()
    if len(vxy) < 2:
        return
    same = vline[1:] == vline[:-1]
    chords = np.flatnonzero(same & (off[:-1] | off[1:]))
    if len(chords) == 0:
        return
    a, b = vxy[chords], vxy[chords + 1]
    h = math.sqrt(8.0 * dc.radius * UNSEEN_DIP)
    n = np.ceil(np.hypot(*(b - a).T) / h).astype(np.intp)
    keep = n >= 2
    chords, a, b, n = chords[keep], a[keep], b[keep], n[keep]
    if len(chords) == 0:
        return
    owner = np.repeat(np.arange(len(chords)), n - 1)
    first = np.repeat(np.cumsum(n - 1) - (n - 1), n - 1)
    frac = (np.arange(len(owner)) - first + 1) / n[owner]
    q = a[owner] + frac[:, None] * (b[owner] - a[owner])
    z, g = dc.heights_and_slopes(q)
    ex = np.where(np.isfinite(z), z - vzv[chords][owner], -np.inf)
    order = np.lexsort((-ex, owner))
    head = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]
    r = chords[owner[head]]
    up = ex[head] > np.where(np.isfinite(check.excess[r]), check.excess[r], -np.inf)
    r, at = r[up], head[up]
    check.excess[r] = ex[at]
    check.where[r] = q[at]
    check.grad[r] = g[at]


def _worst_points(s, check, chords: np.ndarray) -> tuple[FloatArray, FloatArray]:
    """XY (mm) of the highest point above each chord (vertex ranks) and the height's gradient
    there: the evaluated point where :func:`chord_excess` gives one, else its highest exact
    sample (a rough interval's)."""
    n = len(s.pos)
    idx = np.arange(n)
    va = np.maximum.accumulate(np.where(s.vertex, idx, 0))
    rank = np.cumsum(s.vertex) - 1
    ex = np.where(np.isfinite(s.z), s.z - s.zv[va], -np.inf)
    order = np.lexsort((-ex, rank))
    head = order[np.r_[True, rank[order][1:] != rank[order][:-1]]]
    best = np.full((int(s.vertex.sum()), 2), np.nan)
    best[rank[head]] = s.xy[head]
    grad = np.full_like(best, np.nan)
    grad[rank[head]] = s.grad[head]
    out, g = best[chords], grad[chords]
    given = np.isfinite(check.where[chords]).all(axis=1)
    out[given] = check.where[chords][given]
    g[given] = check.grad[chords][given]
    return out, g


def _free_distance(dc: DropCutter, where: FloatArray, normal: FloatArray, level: FloatArray,
                   reach: FloatArray, halvings: int = 12,
                   bisections: int = 8) -> tuple[FloatArray, FloatArray]:
    """Distance (mm) from each point along +-normal to the nearest point on the free side
    (drop height at most level + NEGLIGIBLE, or no face), and the side (+1 / -1); inf where
    neither side is free at ``reach``.  Candidates at reach / 2^i on both sides in one query,
    the nearest free one whose farther candidates are all free taken, then bisected."""
    m = len(where)
    frac = 0.5 ** np.arange(halvings)
    sides = np.array([1.0, -1.0])
    d = reach[:, None, None] * frac[None, None, :] * np.ones((1, 2, 1))  # (m, side, i)
    q = where[:, None, None, :] + (sides[None, :, None, None] * d[..., None]) * normal[:, None,
                                                                                       None, :]
    z = dc.heights_and_slopes(q.reshape(-1, 2))[0].reshape(m, 2, halvings)
    free = ~(np.nan_to_num(z, nan=-np.inf) > level[:, None, None] + NEGLIGIBLE)
    run = np.cumprod(free, axis=2).sum(axis=2)  # free candidates from the far end inwards
    hi = np.where(run > 0, reach[:, None] * 0.5 ** np.maximum(run - 1, 0), np.inf)
    lo = np.where(run < halvings, hi * 0.5, 0.0)
    pick = np.argmin(hi, axis=1)
    rows = np.arange(m)
    hi, lo = hi[rows, pick], lo[rows, pick]
    side = sides[pick]
    ok = np.isfinite(hi)
    for _ in range(bisections):
        if not ok.any():
            break
        mid = 0.5 * (lo[ok] + hi[ok])
        zq = dc.heights_and_slopes(where[ok] + (side[ok] * mid)[:, None] * normal[ok])[0]
        f = ~(np.nan_to_num(zq, nan=-np.inf) > level[ok] + NEGLIGIBLE)
        hi[ok] = np.where(f, mid, hi[ok])
        lo[ok] = np.where(f, lo[ok], mid)
    return hi, side


def _cut_chords(passes: list, bad: np.ndarray) -> list:
    """The passes without the chords flagged in ``bad`` (per vertex rank: the chord from it to
    the next vertex of its pass); a pass is split where one goes, single points dropped."""
    out = []
    at = 0
    for p in passes:
        b = bad[at:at + len(p) - 1]
        at += len(p)
        if not b.any():
            out.append(p)
            continue
        cuts = np.flatnonzero(b) + 1
        for piece in np.split(np.arange(len(p)), cuts):
            # piece runs from a vertex after a cut chord to the start of the next cut chord
            if len(piece) >= 2:
                out.append(p[piece])
    return out
