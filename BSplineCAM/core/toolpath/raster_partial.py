# SPDX-License-Identifier: LGPL-2.1-or-later
"""Partial raster passes: main passes spaced by what most of the surface allows, and between
two of them extra passes over the stretches that need a closer neighbour only.

The input is the stepover field of the faces' raster (:func:`.faces_raster._stepover_samples`):
per surface sample the across- and along-coordinates of the ball centre touching it (mm) and
the largest XY distance between the two passes on either side of it that keeps the scallop
there <= h (mm).

* **Pieces.**  A piece is a stretch [a0, a1] of a line at across-offset b.  Main pieces span
  the whole along-range; several pieces may share one offset.
* **Filling a band.**  Between two lines at lo and hi (a gap g = hi - lo) that both exist over
  an along-stretch S, the samples in S whose centres lie within ``widen`` of [lo, hi] and
  whose allowance is below g need a line between them: a piece at (lo + hi) / 2 over each
  cluster of their along-coordinates, grown by :data:`MARGIN` tool radii at each end, merged
  with its neighbour where the two are closer than :data:`MERGE` tool radii, and clipped to S.
  Both halves are filled the same way over each new piece's stretch, so the gap halves until
  every sample's allowance is met (the pieces nest: a deeper piece lies within the one above
  it, where both its bounding lines exist).
* **Main step.**  From each main line the next one is placed at the step of least estimated
  length per mm of width: the main pass (the along-extent of the samples in its band), the
  pieces that filling the band would add, and :data:`PIECE_COST` tool radii per piece (its
  links, its stops).  The candidates are the step of the whole-pass rule
  (:func:`.raster.scallop_line_offsets`: the least allowance in the band) and steps from the
  widest allowance down to it, :data:`LADDER` per halving; a wider one is taken only if it
  saves more than 1 - :data:`GAIN` of that length.  Where the allowance is the same along the
  whole band (a plane, a cylinder with passes along its axis), no wider step saves anything and the
  lines are those of the whole-pass rule.
* **Order** (:func:`order_pieces`): the main passes zig-zag (even ranks forward, along the
  pass direction).  Every forward main pass takes the pieces of the bands below and above it
  as detours: where their stretch starts the tool leaves the main pass, cuts the band below's
  pieces (offsets descending), the main pass's part over the stretch, then the band above's
  (ascending), each from its end nearer the tool, and goes on along the main pass from the
  stretch's far end.  With an odd number of pieces each side (a halving gives 2^k - 1) the
  crossings add up to an odd number, so the detour ends at that far end and every link in it
  is about a stepover long (within a stay-down link's reach).  The main passes are split at
  the stretches' ends by a point on their chord (the chords are unchanged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..typing import FloatArray
from .common import ToolParameters

#: Along-distance (tool radii) a piece runs beyond the samples that need it, at each end.
MARGIN = 1.0
#: Two stretches of one offset closer than this (tool radii) are cut as one piece.
MERGE = 2.0
#: Length (tool radii) charged per piece when the main step is chosen: its links and stops.
PIECE_COST = 2.0
#: A main step wider than the whole-pass rule's is taken only if its estimated length per mm
#: of width is below this share of that rule's.
GAIN = 0.95
#: Candidate main steps per halving, from the widest allowance down to the whole-pass rule's.
LADDER = 4
#: Deepest halving of a band (a gap of 1/2^12 of the main step is far below any allowance).
MAX_DEPTH = 12


@dataclass(frozen=True)
class Piece:
    """A stretch [a0, a1] (mm along) of the line at across-offset ``b`` (mm).  ``band`` is the
    main line's rank for a main piece, else the rank of the main line below its band;
    ``depth`` is 0 for main pieces, k for the k-th halving."""

    b: float
    a0: float
    a1: float
    band: int
    depth: int

    @property
    def main(self) -> bool:
        return self.depth == 0


class StepoverSamples:
    """The stepover field sorted by across-offset: ``b`` and ``a`` the centre's across- and
    along-coordinates (mm), ``allowed`` the largest stepover there (mm)."""

    def __init__(self, b: FloatArray, a: FloatArray, allowed: FloatArray):
        order = np.argsort(b, kind="stable")
        self.b = np.asarray(b, float)[order]
        self.a = np.asarray(a, float)[order]
        self.allowed = np.asarray(allowed, float)[order]

    def window(self, lo: float, hi: float) -> slice:
        i0, i1 = np.searchsorted(self.b, [lo, hi])
        return slice(int(i0), int(i1))


def stretches(a: FloatArray, lo: float, hi: float, margin: float,
              merge: float) -> list[tuple[float, float]]:
    """The along-stretches of samples ``a`` (mm): each grown by ``margin`` at both ends,
    merged where less than ``merge`` apart, clipped to [lo, hi] (empty ones dropped)."""
    if len(a) == 0:
        return []
    a = np.sort(a)
    cut = np.flatnonzero(np.diff(a) > 2.0 * margin + merge)
    starts = np.concatenate([[a[0]], a[cut + 1]]) - margin
    ends = np.concatenate([a[cut], [a[-1]]]) + margin
    out = []
    for s, e in zip(np.maximum(starts, lo), np.minimum(ends, hi)):
        if e > s:
            out.append((float(s), float(e)))
    return out


def fill_band(samples: StepoverSamples, lo: float, hi: float, stretch: tuple[float, float],
              band: int, widen: float, radius: float, depth: int = 1,
              out: list | None = None) -> list[Piece]:
    """The partial pieces between the lines at ``lo`` and ``hi`` (mm), both existing over
    ``stretch`` (mm along), that meet every sample's allowance there (module docstring)."""
    out = [] if out is None else out
    gap = hi - lo
    if depth > MAX_DEPTH or gap <= 1e-6:
        return out
    w = samples.window(lo - widen, hi + widen)
    a = samples.a[w]
    need = (samples.allowed[w] < gap * (1.0 - 1e-9)) & (a >= stretch[0]) & (a <= stretch[1])
    if not need.any():
        return out
    mid = 0.5 * (lo + hi)
    for s0, s1 in stretches(a[need], stretch[0], stretch[1], MARGIN * radius, MERGE * radius):
        out.append(Piece(mid, s0, s1, band, depth))
        fill_band(samples, lo, mid, (s0, s1), band, widen, radius, depth + 1, out)
        fill_band(samples, mid, hi, (s0, s1), band, widen, radius, depth + 1, out)
    return out


def _whole_pass_step(samples: StepoverSamples, b: float, widest: float, widen: float) -> float:
    """The step from ``b`` of :func:`.raster.scallop_line_offsets`: the least allowance in the
    band it spans (widened by ``widen``)."""
    step = widest
    for _ in range(8):
        w = samples.window(b - widen, b + step + widen)
        need = float(samples.allowed[w].min()) if w.stop > w.start else step
        if need >= step * 0.999:
            break
        step = need
    return step


def _band_length(samples: StepoverSamples, lo: float, hi: float, along: tuple[float, float],
                 band: int, widen: float, radius: float) -> tuple[float, list[Piece]]:
    """Estimated cut length (mm) of the band [lo, hi]: its main pass over the along-extent of
    its samples, the pieces filling it, :data:`PIECE_COST` radii per pass; and the pieces."""
    w = samples.window(lo - widen, hi + widen)
    if w.stop <= w.start:
        return PIECE_COST * radius, []
    a = samples.a[w]
    main = min(float(a.max()), along[1]) - max(float(a.min()), along[0])
    pieces = fill_band(samples, lo, hi, along, band, widen, radius)
    extra = sum(p.a1 - p.a0 for p in pieces)
    return max(main, 0.0) + extra + PIECE_COST * radius * (1 + len(pieces)), pieces


def partial_offsets(samples: StepoverSamples, b0: float, b1: float, along: tuple[float, float],
                    tool: ToolParameters, widen: float) -> tuple[list[float], list[Piece]]:
    """Main line offsets from ``b0`` to ``b1`` (mm) and the partial pieces between them
    (module docstring), the lines spanning ``along`` (mm)."""
    R = tool.radius
    widest = min(float(samples.allowed.max(initial=tool.flat_stepover)), R)
    lines = [b0]
    pieces: list[Piece] = []
    b = b0
    while b < b1 - 1e-9:
        band = len(lines) - 1
        base = _whole_pass_step(samples, b, widest, widen)
        candidates = [base]
        k = 0
        while True:
            s = widest * 2.0 ** (-k / LADDER)
            if s <= base * 1.001:
                break
            candidates.append(s)
            k += 1
        best = None
        for i, s in enumerate(candidates):
            hi = min(b + s, b1)
            length, found = _band_length(samples, b, hi, along, band, widen, R)
            rate = length / (hi - b) * (1.0 if i == 0 else 1.0 / GAIN)
            if best is None or rate < best[0]:
                best = (rate, hi, found)
        _, hi, found = best
        lines.append(hi)
        pieces.extend(found)
        b = hi
    return lines, pieces


def order_pieces(runs: list[tuple[int, FloatArray]], pieces: list[Piece],
                 along: FloatArray) -> list[FloatArray]:
    """The cut runs ``[(piece index, (n, 3) tip positions)]`` (each piece's runs in
    along-order, ``along`` the passes' unit direction in XY) in cutting order, as the module
    docstring says."""
    by_piece: dict[int, list[FloatArray]] = {}
    for k, run in runs:
        by_piece.setdefault(k, []).append(run)
    per_band: dict[int, list[int]] = {}
    for k, p in enumerate(pieces):
        if not p.main and k in by_piece:
            per_band.setdefault(p.band, []).append(k)
    ordered: list[FloatArray] = []
    for rank, k in sorted((p.band, k) for k, p in enumerate(pieces) if p.main):
        main = by_piece.get(k, [])
        if rank % 2:
            ordered.extend(r[::-1] for r in main[::-1])
            continue
        below, above = per_band.pop(rank - 1, []), per_band.pop(rank, [])
        _detours(main, below, above, pieces, by_piece, along, ordered)
    rest = [k for keys in per_band.values() for k in keys]
    while rest:
        j = _nearest(rest, by_piece, ordered)
        rest.remove(j)
        ordered.extend(_oriented(by_piece[j], ordered))
    return ordered


def _detours(main: list[FloatArray], below: list[int], above: list[int], pieces: list[Piece],
             by_piece: dict, along: FloatArray, ordered: list[FloatArray]) -> None:
    """A forward main pass's runs with its detours appended to ``ordered``: over each stretch
    where the bands below and above it have pieces, the tool leaves the main pass at the
    stretch's start, cuts the band below's pieces (offsets descending), the main pass's part
    over the stretch, then the band above's (ascending), and goes on along the main pass from
    where it left off (an odd number of crossings each side: it ends at the stretch's far
    end)."""
    spans = _merged([(pieces[j].a0, pieces[j].a1) for j in below + above
                     if pieces[j].depth == 1])
    if not spans:
        ordered.extend(main)
        return
    cuts = sorted({a for span in spans for a in span})
    parts = [q for run in main for q in _split_run(run, cuts, along)]
    starts = np.array([s for s, _ in spans])

    def span_of(lo: float, hi: float) -> int:
        i = int(np.searchsorted(starts, 0.5 * (lo + hi), side="right")) - 1
        return i if i >= 0 and 0.5 * (lo + hi) <= spans[i][1] else -1

    inside: dict[int, list[FloatArray]] = {}
    events = []
    for q in parts:
        a = q[:, :2] @ along
        i = span_of(float(a[0]), float(a[-1]))
        if i < 0:
            events.append((float(a[0]), 1, q))
        else:
            inside.setdefault(i, []).append(q)
    events += [(s, 0, i) for i, (s, _) in enumerate(spans)]
    owner = {j: max(span_of(pieces[j].a0, pieces[j].a1), 0) for j in below + above}
    for _, kind, item in sorted(events, key=lambda e: (e[0], e[1])):
        if kind == 1:
            ordered.append(item)
            continue
        for keys, descending in (([j for j in below if owner[j] == item], True), (None, None),
                                 ([j for j in above if owner[j] == item], False)):
            if keys is None:
                if item in inside:
                    ordered.extend(_oriented(inside[item], ordered))
                continue
            _cut_by_offset(keys, descending, pieces, by_piece, ordered)


def _cut_by_offset(keys: list[int], descending: bool, pieces: list[Piece], by_piece: dict,
                   ordered: list[FloatArray]) -> None:
    """The pieces ``keys`` by offset, those of one offset nearest first, each from its end
    nearer the tool."""
    keys = sorted(keys, key=lambda j: pieces[j].b, reverse=descending)
    i = 0
    while i < len(keys):
        same = [j for j in keys[i:] if pieces[j].b == pieces[keys[i]].b]
        i += len(same)
        while same:
            j = _nearest(same, by_piece, ordered)
            same.remove(j)
            ordered.extend(_oriented(by_piece[j], ordered))


def _merged(spans: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Overlapping along-stretches (mm) merged, in order."""
    out: list[list[float]] = []
    for s, e in sorted(spans):
        if out and s <= out[-1][1]:
            out[-1][1] = max(out[-1][1], e)
        else:
            out.append([s, e])
    return [(s, e) for s, e in out]


def _split_run(run: FloatArray, cuts: list[float], along: FloatArray) -> list[FloatArray]:
    """A run (tip positions, along-coordinate increasing) split at the along-coordinates
    ``cuts`` (mm): a point on the chord there ends one part and starts the next (the chords
    are unchanged, so they stay one-sided)."""
    a = run[:, :2] @ along
    out = []
    for c in cuts:
        if not a[0] < c < a[-1]:
            continue
        i = int(np.searchsorted(a, c))
        t = (c - a[i - 1]) / (a[i] - a[i - 1]) if a[i] > a[i - 1] else 0.0
        p = run[i - 1] + t * (run[i] - run[i - 1])
        head = np.vstack([run[:i], p])
        if len(head) >= 2:
            out.append(head)
        run = np.vstack([p, run[i:]])
        a = run[:, :2] @ along
    out.append(run)
    return [q for q in out if len(q) >= 2 and np.abs(np.diff(q, axis=0)).max() > 1e-9]


def _ends(group: list[FloatArray]) -> tuple[FloatArray, FloatArray]:
    return group[0][0, :2], group[-1][-1, :2]


def _nearest(keys: list[int], by_piece: dict, ordered: list[FloatArray]) -> int:
    """The piece of ``keys`` with an end nearest the tool (the last run's end)."""
    if not ordered:
        return keys[0]
    at = ordered[-1][-1, :2]
    return min(keys, key=lambda j: min(float(np.hypot(*(e - at))) for e in _ends(by_piece[j])))


def _oriented(group: list[FloatArray], ordered: list[FloatArray]) -> list[FloatArray]:
    """A piece's runs from its end nearer the tool."""
    if not ordered:
        return group
    at = ordered[-1][-1, :2]
    first, last = _ends(group)
    if np.hypot(*(last - at)) < np.hypot(*(first - at)):
        return [r[::-1] for r in group[::-1]]
    return group


__all__ = ["Piece", "StepoverSamples", "fill_band", "order_pieces", "partial_offsets",
           "stretches"]
