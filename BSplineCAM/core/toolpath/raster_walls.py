# SPDX-License-Identifier: LGPL-2.1-or-later
"""Raster passes at a wall's foot: a piece halfway to the neighbour a wall holds up.

A raster's stepover assumes that the two lines on either side of a surface point both rest on
the surface round it.  Where a wall rises between two lines (a boss standing on a plate, the
side of a pocket), the line beyond the wall's foot rides on the wall or on the top: the strip
between the lower line and the wall's foot is cut from one side only and keeps up to about
twice the scallop, a staircase of pass ends along the foot.

Here a line's sample is *held up* on one side when the neighbouring line's tip, at the same
along-coordinate, stands more than :data:`WALL_RISE` tool radii above the height the sample's
own slope across the passes predicts there.  On a smooth face the neighbour departs from that
prediction by its curvature only: at most s^2 / (2 R) for a concave face the ball reaches
(curvature at most 1 / R) at a stepover s <= R, so R / 2; convex faces fall away.  Over the
along-stretches of held-up samples at least :data:`ALONG` stepovers long (samples less than a
stepover apart in one stretch, then grown by :data:`.raster_partial.MARGIN` radii) a piece
runs halfway between the two lines, cut where its own ball is not held up more than its line
(:func:`climbing`): every
point between the lower line and the wall's foot then lies within half a stepover of a cut
line, where the scallop is about a quarter of the asked one.  Where the wall crosses the
lines (shorter stretches: the steps of the staircase are shorter than the stepover) the ends
of the two lines close the strip between them.  A wall lower than
:data:`WALL_RISE` radii is not told from curvature and keeps its staircase.
"""

from __future__ import annotations

import numpy as np

from ..typing import FloatArray
from .raster_partial import MARGIN, Piece, stretches

#: Rise (tool radii) above the across-slope's prediction that marks a wall between two lines.
WALL_RISE = 0.5
#: Shortest held-up stretch (in stepovers of its band) that gets a piece.
ALONG = 1.0


def wall_pieces(pieces: list[Piece], line: np.ndarray, a: FloatArray, z: FloatArray,
                cut: np.ndarray, slope: FloatArray, radius: float
                ) -> tuple[list[Piece], list[int], list[float]]:
    """Pieces halfway between adjacent main lines over the stretches where a wall holds one of
    them up (module docstring), for each the index of the line it was made for (the one at
    the wall's foot) and the foot's height (mm: that line's highest held-up sample).  ``line`` (piece index), ``a`` (mm along), ``z`` (tip, mm; NaN where
    no face is under the ball), ``cut`` (the sample is cut) and ``slope`` (the tip height's
    slope across the passes) are the lines' samples, sorted by line then ``a``.  Stretches
    already covered by a depth-1 piece of the same band are left out."""
    mains = sorted((p.b, k) for k, p in enumerate(pieces) if p.main)
    out: list[Piece] = []
    refs: list[int] = []
    feet: list[float] = []
    if len(mains) < 2:
        return out, refs, feet
    bounds = np.searchsorted(line, np.arange(len(pieces) + 1))
    for rank in range(len(mains) - 1):
        (b0, k0), (b1, k1) = mains[rank], mains[rank + 1]
        band = pieces[k0].band
        lo = max(pieces[k0].a0, pieces[k1].a0)
        hi = min(pieces[k0].a1, pieces[k1].a1)
        mid = 0.5 * (b0 + b1)
        covered = [(p.a0, p.a1) for p in pieces
                   if p.depth == 1 and p.band == band and abs(p.b - mid) < 1e-9]
        for k, other in ((k0, k1), (k1, k0)):
            mine = slice(bounds[k], bounds[k + 1])
            ok = cut[mine] & np.isfinite(z[mine]) & np.isfinite(slope[mine])
            am = a[mine][ok]
            there = _height(bounds, other, a, z, am)
            rise = there - (z[mine][ok] + (pieces[other].b - pieces[k].b) * slope[mine][ok])
            up = np.isfinite(rise) & (rise > WALL_RISE * radius)
            held, zh = am[up], z[mine][ok][up]
            for s0, s1 in stretches(held, lo, hi, 0.0, b1 - b0):
                if s1 - s0 < ALONG * (b1 - b0):
                    continue  # a wall crossing the lines: their ends close the strip
                foot = float(zh[(held >= s0) & (held <= s1)].max())
                s0, s1 = max(s0 - MARGIN * radius, lo), min(s1 + MARGIN * radius, hi)
                for t0, t1 in _minus((s0, s1), covered):
                    out.append(Piece(mid, t0, t1, band, 1))
                    refs.append(k)
                    feet.append(foot)
    return out, refs, feet


def climbing(line: np.ndarray, a: FloatArray, z: FloatArray, slope: FloatArray,
             pieces: list[Piece], walls: list[Piece], refs: list[int], feet: list[float],
             radius: float) -> np.ndarray:
    """Per sample (sorted by line then along; ``walls[k]`` is line ``len(pieces) + k``, made
    for line ``refs[k]`` of ``pieces`` at a foot ``feet[k]`` mm high), whether a wall piece's
    ball stands more than WALL_RISE radii above what its line's across-slope predicts there or
    above its foot: the piece on the wall or its top, which it is not made to cut."""
    out = np.zeros(len(line), bool)
    first = len(pieces)
    bounds = np.searchsorted(line, np.arange(first + len(walls) + 1))
    for k, ref in enumerate(refs):
        mine = slice(bounds[first + k], bounds[first + k + 1])
        at = a[mine]
        r0, r1 = bounds[ref], bounds[ref + 1]
        zr = _height(bounds, ref, a, z, at)
        sr = np.interp(at, a[r0:r1], slope[r0:r1]) if r1 > r0 else np.full(len(at), np.nan)
        with np.errstate(invalid="ignore"):
            rise = z[mine] - (zr + (walls[k].b - pieces[ref].b) * sr)
            above = (rise > WALL_RISE * radius) | (z[mine] > feet[k] + WALL_RISE * radius)
        out[mine] = above
    return out


def insert_runs(ordered: list[FloatArray], walls: list[tuple[float, FloatArray]],
                along: FloatArray, across: FloatArray) -> list[FloatArray]:
    """The passes ``ordered`` (tip positions (n, 3), in cutting order) with each wall run
    ``(b, run)`` (``b`` the across-offset of the line it was made for) cut beside that line:
    the line's pass runs on to the far end of the run's stretch, the tool steps across (half
    a stepover) and cuts the run back to the stretch's near end, steps back and goes over
    the stretch again on its way on.  A run whose line has no pass beside it is cut last."""
    out = [p for p in ordered]
    rest = []
    for b, run in walls:
        ra = run[:, :2] @ along
        s0, s1 = float(ra.min()), float(ra.max())
        k = _beside(out, b, s0, s1, along, across)
        if k is None:
            rest.append(run)
            continue
        p = out[k]
        pa = p[:, :2] @ along
        forward = pa[-1] >= pa[0]
        near, far = (s0, s1) if forward else (s1, s0)
        head = _part(p, far, along, before=True)
        tail = _part(p, near, along, before=False)
        back = run if (ra[0] >= ra[-1]) == forward else run[::-1]
        out[k:k + 1] = [q for q in (head, back, tail) if len(q) >= 2]
    return out + rest


def _beside(passes: list[FloatArray], b: float, s0: float, s1: float, along: FloatArray,
            across: FloatArray) -> int | None:
    """Index of the pass on the line at across-offset ``b`` overlapping [s0, s1] (mm along)
    the most, or None."""
    best, found = 0.0, None
    for k, p in enumerate(passes):
        if abs(float(p[0, :2] @ across) - b) > 1e-6 or abs(float(p[-1, :2] @ across) - b) > 1e-6:
            continue
        pa = p[:, :2] @ along
        overlap = min(float(pa.max()), s1) - max(float(pa.min()), s0)
        if overlap > best:
            best, found = overlap, k
    return found


def _part(p: FloatArray, c: float, along: FloatArray, before: bool) -> FloatArray:
    """The part of pass ``p`` before (or after) it reaches the along-coordinate ``c`` (mm),
    ended (or started) by the point on its chord there: the chords are unchanged, so they
    stay one-sided; the whole pass where it does not reach ``c``."""
    a = p[:, :2] @ along
    sign = 1.0 if a[-1] >= a[0] else -1.0
    t = sign * (a - c)
    i = int(np.searchsorted(t, 0.0))  # first point at or past c (t increases along p)
    if i == 0:
        return p[:1] if before else p
    if i == len(p):
        return p if before else p[-1:]
    f = (0.0 - t[i - 1]) / (t[i] - t[i - 1]) if t[i] > t[i - 1] else 0.0
    q = p[i - 1] + f * (p[i] - p[i - 1])
    return np.vstack([p[:i], q]) if before else np.vstack([q, p[i:]])


def _height(bounds: np.ndarray, k: int, a: FloatArray, z: FloatArray,
            where: FloatArray) -> FloatArray:
    """Line ``k``'s tip height at the along-coordinates ``where``: linear between its samples,
    NaN where either bracketing sample has no face under the ball or outside its samples."""
    at = a[bounds[k]:bounds[k + 1]]
    zt = z[bounds[k]:bounds[k + 1]]
    if len(at) < 2 or len(where) == 0:
        return np.full(len(where), np.nan)
    j = np.clip(np.searchsorted(at, where), 1, len(at) - 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.clip((where - at[j - 1]) / (at[j] - at[j - 1]), 0.0, 1.0)
        out = zt[j - 1] + t * (zt[j] - zt[j - 1])
    out[(where < at[0]) | (where > at[-1])] = np.nan
    return out


def _minus(span: tuple[float, float], covered: list[tuple[float, float]]
           ) -> list[tuple[float, float]]:
    """The parts of ``span`` outside every stretch of ``covered`` (mm along)."""
    parts = [span]
    for c0, c1 in covered:
        nxt = []
        for s0, s1 in parts:
            if c1 <= s0 or c0 >= s1:
                nxt.append((s0, s1))
                continue
            if c0 > s0:
                nxt.append((s0, c0))
            if c1 < s1:
                nxt.append((c1, s1))
        parts = nxt
    return [(s0, s1) for s0, s1 in parts if s1 - s0 > 1e-6]


__all__ = ["ALONG", "WALL_RISE", "climbing", "insert_runs", "wall_pieces"]
