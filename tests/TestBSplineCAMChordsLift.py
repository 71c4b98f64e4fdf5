# SPDX-License-Identifier: LGPL-2.1-or-later
"""Bounded lifts of one-sided chords (:func:`BSplineCAM.core.toolpath.chords.lift_chords`)
against a closed-form cutter-location (CL) height: a ball of radius R on a cylinder of radius
RC (axis along y, top at z = 0), whose CL height is z(x) = sqrt((RC + R)^2 - x^2) - RC - R
with its exact slope.

A long chord across the crown dips far below the CL curve; with ``max_lift`` the chord is
split at exact samples first, so no vertex is lifted by more than ``max_lift`` and no chord
dips below the CL height anywhere (checked on a dense sample of the closed form, not on the
samples the code saw).
"""

from __future__ import annotations

import numpy as np
import pytest

from BSplineCAM.core.toolpath.chords import (
    CLEARANCE,
    DIP_LIMIT,
    _split_worst,
    lift_chords,
    sample_chords,
)

R = 3.0
RC = 10.0


def _cl(x: np.ndarray) -> np.ndarray:
    return np.sqrt((RC + R) ** 2 - x * x) - RC - R


def _query(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = xy[:, 0]
    z = _cl(x)
    grad = np.column_stack([-x / np.sqrt((RC + R) ** 2 - x * x), np.zeros(len(x))])
    return z, grad


def _chords(s):
    """Each final chord as (x0, z0, x1, z1) (mm)."""
    v = np.flatnonzero(s.vertex)
    same = s.line[v[1:]] == s.line[v[:-1]]
    a, b = v[:-1][same], v[1:][same]
    return s.xy[a, 0], s.zv[a], s.xy[b, 0], s.zv[b]


@pytest.mark.parametrize("max_lift", [0.1, 0.01, 0.001])
def test_lift_is_bounded_and_every_chord_clears_the_cl(max_lift):
    lines = [np.array([[-6.0, 0.0], [6.0, 0.0]]), np.array([[-2.0, 1.0], [7.5, 1.0]])]
    s = sample_chords(_query, lines, [_cl(p[:, 0]) for p in lines], 0.05)
    stats = lift_chords(_query, s, max_lift)
    v = s.vertex
    lift = s.zv[v] - s.z[v]
    assert lift.min() >= -1e-12  # vertices only rise
    assert lift.max() <= max_lift + 2 * CLEARANCE
    x0, z0, x1, z1 = _chords(s)
    t = np.linspace(0.0, 1.0, 2001)
    x = x0[:, None] + t * (x1 - x0)[:, None]
    chord = z0[:, None] + t * (z1 - z0)[:, None]
    assert (chord - _cl(x)).min() >= -DIP_LIMIT
    assert stats["worst_dip_mm"] <= DIP_LIMIT
    # the sag of a chord between vertices a distance d apart is about d^2 / (8 (RC + R)):
    # the split keeps it near max_lift, no finer than needed
    widths = x1 - x0
    assert widths.max() >= 0.5 * np.sqrt(8 * (RC + R) * max_lift)


def test_split_at_once_needs_one_split_round():
    """The samples alone decide every vertex needed (one-sided Douglas-Peucker on them): the
    split is followed by one lift and its check, where one vertex per chord and round took a
    round for every halving of the excess."""
    line = np.array([[-6.0, 0.0], [6.0, 0.0]])
    s = sample_chords(_query, [line], [_cl(line[:, 0])], 0.05)
    stats = lift_chords(_query, s, 0.001)
    assert stats["iterations"] <= 3
    assert stats["vertices_added"] > 10


def test_split_worst_leaves_no_sample_above_its_target():
    line = np.array([[-6.0, 0.0], [6.0, 0.0]])
    s = sample_chords(_query, [line], [_cl(line[:, 0])], 0.05)
    added = _split_worst(s, np.array([0]), 0.002)
    assert added > 0
    v = np.flatnonzero(s.vertex)
    for a, b in zip(v[:-1], v[1:]):
        inner = np.arange(a + 1, b)
        chord = s.zv[a] + (s.pos[inner] - s.pos[a]) / (s.pos[b] - s.pos[a]) * (s.zv[b] - s.zv[a])
        assert np.all(s.z[inner] - chord <= 0.002)
    # nothing else was touched: a chord not asked for keeps its vertices
    s2 = sample_chords(_query, [line, line + [0, 1]], [_cl(line[:, 0])] * 2, 0.05)
    _split_worst(s2, np.array([1]), 0.002)
    assert s2.vertex[s2.line == 0].sum() == 2


def test_checking_only_the_lifted_chords_lines_gives_the_full_checks_answer(monkeypatch):
    """After the first check lift_chords examines only the lines holding a chord left
    unresolved (a lift lowers the others' bounds without a check); every vertex height, sample
    and statistic equals what checking every chord at each of its checks gives."""
    from BSplineCAM.core.toolpath import chords

    rng = np.random.default_rng(11)
    lines = []
    for k in range(12):  # crowns, shoulders, flat stretches off the cylinder's top
        x0 = rng.uniform(-9.0, 4.0)
        xs = np.sort(np.concatenate([[x0, x0 + rng.uniform(2.0, 8.0)],
                                     rng.uniform(x0, x0 + 2.0, rng.integers(0, 3))]))
        lines.append(np.column_stack([xs, np.full(len(xs), float(k))]))
    for k in range(4):  # vertices 0.2 um apart: no chord sags, no lift
        xs = rng.uniform(-8.0, 8.0) + 2e-4 * np.arange(11)
        lines.append(np.column_stack([xs, np.full(len(xs), 20.0 + k)]))
    results = []
    for full in (False, True):
        if full:
            monkeypatch.setattr(chords, "_check_lines",
                                lambda query, s, active: chords.chord_excess(query, s, kinks=True))
        s = sample_chords(_query, lines, [_cl(p[:, 0]) for p in lines], 0.2)
        stats = lift_chords(_query, s, 0.01)
        results.append((s, stats))
    (a, sa), (b, sb) = results
    assert sa["iterations"] > 2  # lifts happened
    for name in ("pos", "xy", "z", "zv", "line", "vertex"):
        assert np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True), name
    assert sa == sb
