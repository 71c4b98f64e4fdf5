# SPDX-License-Identifier: LGPL-2.1-or-later
"""A chord over a kink of the cutter-location (CL) height (the contact leaves the surface for
its border between two samples) clears the exact CL height after
:func:`BSplineCAM.core.toolpath.chords.lift_chords`.

The chord is the case-study raster's last stay-down link (examples/case-study.json, ball
6 mm, tolerance 0.002 mm): along x = 100 mm from y = 99.37 to the net's border at y = 100,
where the height's slope drops from 0.025 to 0.018 between two samples 0.023 mm apart.  The
Hermite model of that interval matches the exact height at its maximum, yet the true excess
peaks about 1 um higher further on; the exact slope at that point gives the kink away
(:func:`chord_excess` with ``kinks``).  Had the lift trusted the model there, the link would
dip 0.98 um below the CL height; the dense exact sample here sees such a dip.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from BSplineCAM.core.geometry.netio import read_net
from BSplineCAM.core.geometry.surface import Surface
from BSplineCAM.core.toolpath.chords import (
    DIP_LIMIT,
    MODEL_ERROR,
    chord_excess,
    lift_chords,
    sample_chords,
)
from BSplineCAM.core.toolpath.dropcutter import DropCutter

NET = Path(__file__).resolve().parent.parent / "examples" / "case-study.json"
RADIUS = 3.0
TOLERANCE = 0.002


ENDS = np.array([[100.0, 99.36744669], [100.0, 100.0]])
STEP = max(0.25 * min(np.sqrt(8.0 * RADIUS * TOLERANCE), RADIUS), 1e-3)  # links.py's


def _link():
    net = read_net(NET)
    dc = DropCutter(Surface(net.points, knots=net.knots.value), RADIUS)
    z, _ = dc.heights_and_slopes(ENDS)
    return dc, z, sample_chords(dc.heights_and_slopes, [ENDS], [z], STEP)


def test_the_kink_check_bounds_the_chords_excess():
    dc, z, s = _link()
    t = np.linspace(0.0, 1.0, 2001)
    cl, _ = dc.heights_and_slopes(ENDS[0] + t[:, None] * (ENDS[1] - ENDS[0]))
    true = float(np.nanmax(cl - (z[0] + t * (z[1] - z[0]))))
    check = chord_excess(dc.heights_and_slopes, s, kinks=True)
    assert check.unresolved == 0
    assert check.excess[0] >= true - MODEL_ERROR


def test_link_over_the_nets_border_kink_clears_the_exact_cl_height():
    dc, _z, s = _link()
    stats = lift_chords(dc.heights_and_slopes, s, 0.5 * TOLERANCE)
    assert stats["unresolved_chords"] == 0
    v = np.flatnonzero(s.vertex)
    t = np.linspace(0.0, 1.0, 2001)
    lowest = np.inf
    for a, b in zip(v[:-1], v[1:]):
        xy = s.xy[a] + t[:, None] * (s.xy[b] - s.xy[a])
        cl, _ = dc.heights_and_slopes(xy)
        chord = s.zv[a] + t * (s.zv[b] - s.zv[a])
        lowest = min(lowest, float(np.nanmin(chord - cl)))
    assert lowest >= -DIP_LIMIT
