# SPDX-License-Identifier: LGPL-2.1-or-later
"""Contours of a field on the grid: the level set F = 0 by marching squares, and the stretches
of a contour a pass cuts along."""

from __future__ import annotations

import numpy as np

from ... import kernels
from ...kernels import roughing_contour_kernels as _ck
from ...typing import FloatArray


def marching_squares(F: FloatArray) -> list:
    """Polylines (k, 2) in fractional cell indices (column, row) of the level set F = 0.

    Inside is F <= 0; each polyline is oriented with the inside on its right (climb milling
    with a clockwise spindle leaves the material on the left).  Saddles are resolved by the
    cell's mean.  Closed loops repeat their first point at the end.
    """
    ny, nx = F.shape
    if ny < 2 or nx < 2:
        return []
    if kernels.use_numba():
        try:
            points, starts = _ck.marching_squares(np.ascontiguousarray(F, dtype=float))
            return [points[a:b] for a, b in zip(starts[:-1].tolist(), starts[1:].tolist())]
        except kernels.KernelUnavailable:
            pass
    ins = F <= 0.0
    a, b = F[:-1, :-1], F[:-1, 1:]
    d, c = F[1:, :-1], F[1:, 1:]
    ia, ib, id_, ic = ins[:-1, :-1], ins[:-1, 1:], ins[1:, :-1], ins[1:, 1:]
    code = ia.astype(np.int8) + 2 * ib + 4 * ic + 8 * id_
    cells = np.flatnonzero((code != 0) & (code != 15))
    if not len(cells):
        return []
    ci, cj = np.divmod(cells, nx - 1)
    nh = ny * (nx - 1)

    def hid(i, j):
        return i * (nx - 1) + j

    def vid(i, j):
        return nh + i * nx + j

    def cross_h(i, j):  # between (i, j) and (i, j+1)
        f0, f1 = F[i, j], F[i, j + 1]
        return np.stack([j + f0 / (f0 - f1), i + 0.0 * f0], axis=-1)

    def cross_v(i, j):  # between (i, j) and (i+1, j)
        f0, f1 = F[i, j], F[i + 1, j]
        return np.stack([j + 0.0 * f0, i + f0 / (f0 - f1)], axis=-1)

    e_id = np.stack([hid(ci, cj), vid(ci, cj + 1), hid(ci + 1, cj), vid(ci, cj)], axis=1)
    crossed = np.stack([ia.ravel()[cells] != ib.ravel()[cells],
                        ib.ravel()[cells] != ic.ravel()[cells],
                        id_.ravel()[cells] != ic.ravel()[cells],
                        ia.ravel()[cells] != id_.ravel()[cells]], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        pts = np.stack([cross_h(ci, cj), cross_v(ci, cj + 1), cross_h(ci + 1, cj),
                        cross_v(ci, cj)], axis=1)
    saddle = crossed.sum(axis=1) == 4
    seg_cell, seg_e0, seg_e1 = [], [], []
    two = np.flatnonzero(~saddle)
    order = np.argsort(~crossed[two], axis=1, kind="stable")[:, :2]
    seg_cell.append(two)
    seg_e0.append(order[:, 0])
    seg_e1.append(order[:, 1])
    sad = np.flatnonzero(saddle)
    if len(sad):
        fl = cells[sad]
        mean = (a.ravel()[fl] + b.ravel()[fl] + c.ravel()[fl] + d.ravel()[fl]) / 4.0
        centre_as_a = (mean <= 0.0) == ia.ravel()[fl]
        # centre joins a and c: cut off b (edges 0, 1) and d (2, 3); else a (3, 0) and c (1, 2)
        e0a = np.where(centre_as_a, 0, 3)
        e1a = np.where(centre_as_a, 1, 0)
        e0b = np.where(centre_as_a, 2, 1)
        e1b = np.where(centre_as_a, 3, 2)
        seg_cell += [sad, sad]
        seg_e0 += [e0a, e0b]
        seg_e1 += [e1a, e1b]
    sc = np.concatenate(seg_cell)
    s0 = np.concatenate(seg_e0)
    s1 = np.concatenate(seg_e1)
    p0 = pts[sc, s0]
    p1 = pts[sc, s1]
    k0 = e_id[sc, s0]
    k1 = e_id[sc, s1]
    # orientation: inside (F decreasing) on the right of p0 -> p1
    mid = 0.5 * (p0 + p1)
    i0, j0 = ci[sc], cj[sc]
    u, v = mid[:, 0] - j0, mid[:, 1] - i0
    fa, fb = a.ravel()[cells[sc]], b.ravel()[cells[sc]]
    fc, fd = c.ravel()[cells[sc]], d.ravel()[cells[sc]]
    gx = (1 - v) * (fb - fa) + v * (fc - fd)
    gy = (1 - u) * (fd - fa) + u * (fc - fb)
    t = p1 - p0
    good = (t[:, 1] * gx - t[:, 0] * gy) < 0
    # chain the segments through shared edge crossings (undirected, then orient by majority)
    ends: dict = {}
    for s, (e0, e1) in enumerate(zip(k0.tolist(), k1.tolist())):
        ends.setdefault(e0, []).append(s)
        ends.setdefault(e1, []).append(s)
    used = np.zeros(len(sc), bool)
    k0l, k1l = k0.tolist(), k1.tolist()
    lines = []

    def walk(s: int, key: int) -> tuple[list, list]:
        """Follow from segment s leaving through crossing ``key``; keys and segments."""
        keys, segs = [], []
        while True:
            nxt = [q for q in ends.get(key, []) if not used[q]]
            if not nxt:
                return keys, segs
            q = nxt[0]
            used[q] = True
            segs.append(q)
            key = k1l[q] if k0l[q] == key else k0l[q]
            keys.append(key)

    # each crossing's point where it first occurs (p0 then p1 of each segment, in order)
    key_seq = np.stack([k0, k1], axis=1).ravel()
    point_seq = np.stack([p0, p1], axis=1).reshape(-1, 2)
    crossing, first_at = np.unique(key_seq, return_index=True)
    for s in range(len(sc)):
        if used[s]:
            continue
        used[s] = True
        fwd_keys, fwd_segs = walk(s, k1l[s])
        closed = bool(fwd_keys) and fwd_keys[-1] == k0l[s]
        if closed:
            keys = [k0l[s], k1l[s], *fwd_keys]
            segs = [s, *fwd_segs]
        else:
            back_keys, back_segs = walk(s, k0l[s])
            keys = [*back_keys[::-1], k0l[s], k1l[s], *fwd_keys]
            segs = [*back_segs[::-1], s, *fwd_segs]
        keys_a = np.array(keys)
        poly = point_seq[first_at[np.searchsorted(crossing, keys_a)]]
        # majority vote of the segments' orientation tests along the chain's direction
        segs_a = np.array(segs)
        agree = int(np.count_nonzero((k0[segs_a] == keys_a[:len(segs)]) == good[segs_a]))
        vote = 2 * agree - len(segs)
        if vote < 0:
            poly = poly[::-1]
        lines.append(poly)
    return lines


def _stretches(line: FloatArray, cuts: np.ndarray, free: np.ndarray, clear: np.ndarray,
               closed: bool, back: int) -> list:
    """Runs of cutting vertices, each grown by one vertex at both ends and further over
    ``free`` vertices (where the tool cuts nothing) to one where the tool's disk is
    ``clear`` (at most ``back`` vertices), so that a pass can start and end out of the
    material; a closed line that cuts everywhere stays closed."""
    if closed:
        c = cuts[:-1]
        m = len(c)
        grown = c | np.roll(c, 1) | np.roll(c, -1)
        if grown.all():
            return [line]
        first = int(np.flatnonzero(~grown)[0])
        body = np.roll(line[:-1], -first, axis=0)
        c = np.roll(c, -first)
        cl = np.roll(clear[:-1], -first)
        fr = np.roll(free[:-1], -first)
    else:
        body, c, cl, fr, m = line, cuts, clear, free, len(line)
    runs = []
    i = 0
    while i < m:
        if not c[i]:
            i += 1
            continue
        j = i
        while j + 1 < m and c[j + 1]:
            j += 1
        runs.append([i, j])
        i = j + 1
    taken = np.zeros(m, bool)
    for r in runs:
        taken[r[0]:r[1] + 1] = True
    out = []
    for i, j in runs:
        a = max(i - 1, 0) if i > 0 and not taken[i - 1] else i
        while a > 0 and a > i - back and not taken[a - 1] and fr[a - 1] and not cl[a]:
            a -= 1
        b = min(j + 1, m - 1) if j + 1 < m and not taken[j + 1] else j
        while b < m - 1 and b < j + back and not taken[b + 1] and fr[b + 1] and not cl[b]:
            b += 1
        taken[a:b + 1] = True
        out.append(body[a:b + 1])
    return [o for o in out if len(o) >= 2]
