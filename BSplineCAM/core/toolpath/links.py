# SPDX-License-Identifier: LGPL-2.1-or-later
"""Stay-down links: the tool feeds from the end of one pass to the start of the next.

A zig-zag pass ends next to where the next one starts (one stepover away).  Retracting,
travelling and plunging there costs a climb to the safe height and a feed back down for
every pass; instead the link is cut as a short feed move along the surface, made one-sided
like every chord (:mod:`chords`): its vertices are exact cutter locations and no straight
piece of it dips below the exact drop-cutter height.  Links longer than ``max_link`` (or over
a gap where no surface lies under the ball) still retract.
"""

from __future__ import annotations

import numpy as np

from ..typing import FloatArray
from .chords import lift_chords, sample_chords
from .dropcutter import DropCutter


def stay_down_links(dc: DropCutter, passes: list, max_link: float, tolerance: float) -> list:
    """Per gap between consecutive passes, an (n, 3) polyline of tip positions from the end of
    one pass to the start of the next (both included), or None where the tool must retract.

    Each link starts as one straight move; where that would dip below the exact cutter-location
    height, :func:`chords.lift_chords` lifts its ends by at most ``tolerance``/2 (mm) or adds the
    highest exact cutter locations as vertices, so no piece of it cuts into the part.
    """
    links: list = [None] * max(len(passes) - 1, 0)
    gaps = [k for k in range(len(passes) - 1)
            if float(np.hypot(*(passes[k + 1][0][:2] - passes[k][-1][:2]))) <= max_link]
    if not gaps:
        return links
    polylines = [np.array([passes[k][-1][:2], passes[k + 1][0][:2]]) for k in gaps]
    zv = [np.array([passes[k][-1][2], passes[k + 1][0][2]]) for k in gaps]
    step = max(0.25 * min(np.sqrt(8.0 * dc.radius * tolerance), dc.radius), 1e-3)
    samples = sample_chords(dc.heights_and_slopes, polylines, zv, step)
    on_surface = np.ones(len(gaps), dtype=bool)
    on_surface[np.unique(samples.line[~np.isfinite(samples.z)])] = False
    lift_chords(dc.heights_and_slopes, samples, 0.5 * tolerance)
    xy_v, z_v, line_v = samples.vertices()
    for j, k in enumerate(gaps):
        if not on_surface[j]:
            continue  # no surface under part of the link: retract there
        mine = line_v == j
        links[k] = np.column_stack([xy_v[mine], z_v[mine]])
    return links


def link_length(links: list) -> FloatArray:
    """Cutting length (mm) of each link (0 where the tool retracts)."""
    return np.array([0.0 if lk is None else float(np.linalg.norm(np.diff(lk, axis=0), axis=1).sum())
                     for lk in links])


def join_links(passes: list, links: list) -> None:
    """Give a pass's end and the stay-down link leaving it one height, and the same for the
    link's end and the next pass's start: the higher of the two.

    :func:`stay_down_links` may lift a link's end vertices to keep its chords above the exact
    CL height, and :func:`.common.to_moves` cuts a link from the pass's last point: it calls
    this on copies, so the move from there is the lifted chord.  Raising a vertex of a
    one-sided chord keeps it one-sided, so the passes stay so.
    """
    for k, link in enumerate(links):
        if link is None:
            continue
        z0 = max(float(passes[k][-1, 2]), float(link[0, 2]))
        z1 = max(float(passes[k + 1][0, 2]), float(link[-1, 2]))
        passes[k][-1, 2] = link[0, 2] = z0
        passes[k + 1][0, 2] = link[-1, 2] = z1
