# SPDX-License-Identifier: LGPL-2.1-or-later
"""A lift is accounted for without the drop-cutter
(:func:`BSplineCAM.core.toolpath.chords.lift_chords`): raising a chord's end vertices by
l_a, l_b >= 0 raises the chord by at least min(l_a, l_b) all along it, so its excess bound falls
by that much (:func:`BSplineCAM.core.toolpath.chords._lowered`) and only chords left unresolved
are examined again.

The reference is the closed-form cutter-location (CL) height of a ball of radius R on a
cylinder of radius RC (axis along y, top at z = 0), beside flat ground where the ball leaves
the cylinder: after the lift a fresh check of every chord (what re-examining them would find)
finds no excess above ``NEGLIGIBLE``, and no chord dips below the closed form on a dense
sample.
"""

from __future__ import annotations

import numpy as np
import pytest

from BSplineCAM.core.toolpath.chords import (
    CLEARANCE,
    DIP_LIMIT,
    NEGLIGIBLE,
    ChordSamples,
    _lowered,
    chord_excess,
    lift_chords,
    sample_chords,
)

R = 3.0
RC = 10.0


def _cl(x: np.ndarray) -> np.ndarray:
    """CL tip height (mm): on the cylinder's offset where |x| < RC + R, else the ground."""
    inside = np.abs(x) < RC + R
    return np.where(inside, np.sqrt(np.maximum((RC + R) ** 2 - x * x, 0.0)) - RC - R, -RC - R)


def _query(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = xy[:, 0]
    inside = np.abs(x) < RC + R
    with np.errstate(divide="ignore", invalid="ignore"):
        gx = np.where(inside, -x / np.sqrt((RC + R) ** 2 - x * x), 0.0)
    return _cl(x), np.column_stack([gx, np.zeros(len(x))])


def _lines(seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    lines = []
    for k in range(10):  # crowns and shoulders of the cylinder, a few inner vertices each
        x0 = rng.uniform(-12.0, 4.0)
        xs = np.sort(np.concatenate([[x0, x0 + rng.uniform(1.0, 8.0)],
                                     rng.uniform(x0, x0 + 1.0, rng.integers(0, 4))]))
        lines.append(np.column_stack([np.minimum(xs, 12.5), np.full(len(xs), float(k))]))
    return lines


def _dips(s: ChordSamples) -> np.ndarray:
    """Per final chord, its lowest point relative to the closed-form CL height (mm)."""
    v = np.flatnonzero(s.vertex)
    same = s.line[v[1:]] == s.line[v[:-1]]
    a, b = v[:-1][same], v[1:][same]
    t = np.linspace(0.0, 1.0, 4001)
    x = s.xy[a, 0][:, None] + t * (s.xy[b, 0] - s.xy[a, 0])[:, None]
    chord = s.zv[a][:, None] + t * (s.zv[b] - s.zv[a])[:, None]
    return (chord - _cl(x)).min(axis=1)


def test_lowered_bound_falls_by_the_lesser_end_lift():
    excess = np.array([0.3, 0.1, -np.inf, 0.05, -np.inf])
    lift = np.array([0.2, 0.5, 0.1, 0.0, 0.4])
    same = np.array([True, False, True, True])  # vertex 1 ends a line, vertex 2 starts one
    out = _lowered(excess, lift, same)
    assert out[0] == pytest.approx(0.3 - 0.2)
    assert out[1] == pytest.approx(0.1)  # its end vertex is on another line: no bound change
    assert out[2] == -np.inf  # a chord ending its line stays so
    assert out[3] == pytest.approx(0.05)  # one end did not rise: min lift 0
    assert out[4] == -np.inf


@pytest.mark.parametrize("seed", [1, 2, 3])
@pytest.mark.parametrize("max_lift", [0.01, 0.001])
def test_a_fresh_check_after_the_lift_finds_nothing_to_lift(seed, max_lift):
    lines = _lines(seed)
    s = sample_chords(_query, lines, [_cl(p[:, 0]) for p in lines], 0.2)
    stats = lift_chords(_query, s, max_lift)
    assert stats["iterations"] >= 2 and stats["max_lift_mm"] > 0.0  # lifts happened
    assert stats["worst_dip_mm"] <= NEGLIGIBLE
    assert stats["unresolved_chords"] == 0
    check = chord_excess(_query, s)
    assert check.unresolved == 0
    assert np.max(check.excess) <= NEGLIGIBLE
    assert _dips(s).min() >= -DIP_LIMIT


def test_the_lift_asks_the_drop_cutter_nothing_more():
    """Once the chords are checked (and split where a lift would exceed max_lift), lifting
    them costs no query: the only calls are the checks', none after the last lift."""
    lines = _lines(4)
    s = sample_chords(_query, lines, [_cl(p[:, 0]) for p in lines], 0.2)
    calls: list[tuple[int, float]] = []

    def counted(xy):
        calls.append((len(xy), float(np.max(s.zv[s.vertex] - s.z[s.vertex]))))
        return _query(xy)

    lift_chords(counted, s, 0.01)
    v = s.vertex
    assert calls and np.max(s.zv[v] - s.z[v]) > CLEARANCE
    assert all(lifted == 0.0 for _n, lifted in calls)  # every query came before any lift
