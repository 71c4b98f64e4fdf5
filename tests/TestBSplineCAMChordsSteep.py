# SPDX-License-Identifier: LGPL-2.1-or-later
"""One-sided chords across steep bands and vertical jumps of the cutter-location (CL) height
(:mod:`BSplineCAM.core.toolpath.chords`), against a closed-form drop-cutter.

The reference is a ball of radius R dropped on an extruded polyline profile: the centre height
is the largest of the segments' offsets (contact inside a segment) and the vertices' caps
(contact on an edge), each in closed form; the gradient is the active contact's (envelope
theorem).  A vertical step makes the CL jump where the ball's side meets the wall; a drafted
wall steeper than ``MAX_SLOPE`` makes a smooth steep band.  Chords must clear the exact CL
height everywhere by ``DIP_LIMIT``, except within ``MIN_SPLIT`` (mm, sideways) of a jump.
"""

from __future__ import annotations

import numpy as np
import pytest

from BSplineCAM.core.toolpath import chords
from BSplineCAM.core.toolpath.chords import (
    DIP_LIMIT,
    MIN_SPLIT,
    ROUNDS,
    chord_excess,
    lift_chords,
    sample_chords,
)

R = 3.0
HEIGHT = 6.0  # wall height (mm), more than R: the CL jumps at the wall's foot
STEEP = 40.0  # drafted wall's slope, steeper than MAX_SLOPE
#: x (mm) where the CL of either profile jumps or changes its contact.
FEATURES = [-R, 0.0, R, HEIGHT / STEEP, HEIGHT / STEEP + R]


def _profile(kind: str) -> np.ndarray:
    """Profile (x, z) vertices (mm): a flat top for x < 0, a wall, a floor at -HEIGHT."""
    if kind == "step":
        return np.array([[-30.0, 0.0], [0.0, 0.0], [0.0, -HEIGHT], [30.0, -HEIGHT]])
    return np.array([[-30.0, 0.0], [0.0, 0.0], [HEIGHT / STEEP, -HEIGHT], [30.0, -HEIGHT]])


def _drop(profile: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact tip height (mm) and dz/dx of a ball of radius R dropped at ``x`` on the profile."""
    best = np.full(len(x), -np.inf)
    slope = np.zeros(len(x))
    for (x0, z0), (x1, z1) in zip(profile[:-1], profile[1:]):
        t = np.array([x1 - x0, z1 - z0]) / np.hypot(x1 - x0, z1 - z0)
        n = np.array([-t[1], t[0]])  # upward normal (profile runs in +x)
        if n[1] <= 0:
            continue  # a vertical wall touches only with its edges
        foot = x - R * n[0]  # contact's x for a centre over the segment's offset line
        inside = (foot >= min(x0, x1)) & (foot <= max(x0, x1))
        c = z0 + (foot - x0) * (z1 - z0) / (x1 - x0) + R * n[1]
        better = inside & (c > best)
        best = np.where(better, c, best)
        slope = np.where(better, (z1 - z0) / (x1 - x0), slope)
    for vx, vz in profile:
        dx = vx - x
        h = np.sqrt(np.maximum(R * R - dx * dx, 0.0))
        ok = np.abs(dx) < R
        c = vz + h
        better = ok & (c > best)
        best = np.where(better, c, best)
        with np.errstate(divide="ignore", invalid="ignore"):
            slope = np.where(better, dx / h, slope)
    return best - R, slope


class Counted:
    """Query along x only (the profile is extruded along y), counting calls and points."""

    def __init__(self, kind: str):
        self.profile = _profile(kind)
        self.calls = 0
        self.points = 0

    def __call__(self, xy):
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        self.calls += 1
        self.points += len(xy)
        z, dzdx = _drop(self.profile, xy[:, 0])
        return z, np.column_stack([dzdx, np.zeros(len(xy))])


def _lines(angle_deg: float, count: int = 5, spacing: float = 0.37):
    """Polylines crossing the wall at ``angle_deg`` from x, vertices every ``spacing`` mm
    (so the wall falls anywhere between vertices)."""
    a = np.radians(angle_deg)
    u = np.array([np.cos(a), np.sin(a)])
    out = []
    for k in range(count):
        s = np.arange(-6.0, 9.0, spacing) + 0.071 * k
        out.append(np.outer(s / u[0], u) + np.array([0.0, 1.3 * k]))
    return out


def _dense_dip(query: Counted, s, jumps: list[float]) -> float:
    """Largest dip (mm) of the chords of ``s`` below the exact CL height on a dense sampling
    of every chord, points within MIN_SPLIT (in x) of a jump excepted."""
    vxy, vz, vline = s.vertices()
    same = vline[1:] == vline[:-1]
    a, b = vxy[:-1][same], vxy[1:][same]
    za, zb = vz[:-1][same], vz[1:][same]
    worst = -np.inf
    t = np.linspace(0.0, 1.0, 4001)
    for k in range(len(a)):
        x = a[k, 0] + t * (b[k, 0] - a[k, 0])
        # and points close to the jumps, where a coarse grid would miss the worst dip
        near = np.concatenate(
            [j + np.geomspace(1e-9, 1e-2, 400) * sgn for j in FEATURES for sgn in (-1.0, 1.0)]
        )
        lo, hi = sorted((a[k, 0], b[k, 0]))
        x = np.concatenate([x, near[(near > lo) & (near < hi)]])
        tt = (x - a[k, 0]) / (b[k, 0] - a[k, 0]) if b[k, 0] != a[k, 0] else np.zeros(len(x))
        chord = za[k] + tt * (zb[k] - za[k])
        exact, _ = _drop(query.profile, x)
        keep = np.ones(len(x), bool)
        for j in jumps:
            keep &= np.abs(x - j) > MIN_SPLIT
        if keep.any():
            worst = max(worst, float(np.max(exact[keep] - chord[keep])))
    return worst


@pytest.mark.parametrize("kind", ["step", "draft"])
@pytest.mark.parametrize("angle", [0.0, 23.0, 180.0 - 61.0])
def test_lifted_chords_clear_exact_cl_across_walls(kind, angle):
    """Vertices on the exact CL, chords lifted: no point of any chord lies below the exact CL
    height by more than DIP_LIMIT, beside a jump's MIN_SPLIT-wide sideways tolerance; the
    lift stays within ``max_lift`` and the walls needed lifting at all (the test can fail)."""
    q = Counted(kind)
    lines = _lines(angle)
    zv = [q(p)[0] for p in lines]
    q.calls = q.points = 0
    s = sample_chords(q, lines, zv, 0.05)
    max_lift = 0.05
    stats = lift_chords(q, s, max_lift)
    jumps = [R] if kind == "step" else []
    assert _dense_dip(q, s, jumps) <= DIP_LIMIT
    v = s.vertex
    lift = s.zv[v] - s.z[v]
    assert np.all(lift >= -1e-12)  # vertices never below the exact CL
    assert stats["max_lift_mm"] <= max_lift + 1e-9
    assert stats["max_lift_mm"] > 1e-4  # the walls' chords did need lifting


@pytest.mark.parametrize("kind", ["step", "draft"])
def test_unlifted_chords_would_dip(kind):
    """The dense check finds the dips of chords between exact vertices across the wall (so a
    chord check that missed the steep band would fail the test above)."""
    q = Counted(kind)
    lines = _lines(0.0)
    zv = [q(p)[0] for p in lines]
    s = sample_chords(q, lines, zv, 0.05)
    assert _dense_dip(q, s, [R] if kind == "step" else []) > 1e-3


@pytest.mark.parametrize("kind", ["step", "draft"])
def test_steep_band_resolved_in_one_check_one_call_per_round(kind):
    """One chord check settles every chord across the wall (no chord left unresolved after
    ROUNDS rounds) with at most one drop-cutter call per round, and its excesses match the
    exact worst dips of the chords up to the jump's sideways tolerance."""
    q = Counted(kind)
    lines = _lines(17.0)
    zv = [q(p)[0] for p in lines]
    s = sample_chords(q, lines, zv, 0.05)
    q.calls = 0
    check = chord_excess(q, s)
    assert check.unresolved == 0
    assert q.calls <= ROUNDS
    # every chord's excess is an upper bound of its dense worst dip (sideways tolerance aside)
    vxy, vz, vline = s.vertices()
    same = np.flatnonzero(vline[1:] == vline[:-1])
    t = np.linspace(0.0, 1.0, 20001)
    for r in same:
        x = vxy[r, 0] + t * (vxy[r + 1, 0] - vxy[r, 0])
        chord = vz[r] + t * (vz[r + 1] - vz[r])
        exact, _ = _drop(q.profile, x)
        keep = np.abs(x - R) > MIN_SPLIT if kind == "step" else np.ones(len(x), bool)
        assert np.max((exact - chord)[keep]) <= check.excess[r] + 2 * chords.MODEL_ERROR


def test_one_signed_curvature_separates_smooth_bands_from_jumps():
    """End data of smooth monotone convex/concave heights pass; a jump or a turning point
    fails (closed forms: z = x^2 on [1, 2], a unit step, z = -(x - 1/2)^2 on [0, 1])."""
    f = chords._one_signed_curvature
    # convex rising: z = x^2 on [1, 2]: dz = 3, slopes 2 and 4 (per unit interval)
    assert f(np.array([3.0]), np.array([2.0]), np.array([4.0]))[0]
    # concave falling, mirrored: z = -x^2 on [1, 2]
    assert f(np.array([-3.0]), np.array([-2.0]), np.array([-4.0]))[0]
    # a step of 1 with flat ends and a rim slope of 0.5: rises more than its slopes explain
    assert not f(np.array([1.0]), np.array([0.0]), np.array([0.5]))[0]
    # a bump: z = -(x - 1/2)^2 on [0, 1]: slopes 1 and -1, no rise
    assert not f(np.array([0.0]), np.array([1.0]), np.array([-1.0]))[0]


def test_chord_along_a_walls_rim_grows_by_a_bounded_number_of_samples(monkeypatch):
    """A chord along the step's top edge, 1e-4 mm inside the ball's reach of it: the ball
    touches the edge with its rim all along, so the height is constant along the chord but
    its slope across is about 120 and every interval is too steep for the Hermite model.
    At most ROUGH_PER_CHORD of them are cut a round (all of them cut into 16 pieces cost a
    contour at a fillet's vertical end 140 000 drop-cutter queries in one round), and the
    chord is still found level with the exact height."""
    x = R - 1e-4
    z = float(_drop(_profile("step"), np.array([x]))[0][0])
    grad_x = float(_drop(_profile("step"), np.array([x]))[1][0])
    assert 20.0 < abs(grad_x) < 200.0  # steeper than MAX_SLOPE, a smooth band's slope

    def run():
        q = Counted("step")
        s = sample_chords(q, [np.array([[x, 0.0], [x, 10.0]])], [np.array([z, z])], 0.2)
        check = chord_excess(q, s)
        return q.points, check

    points, check = run()
    assert points < 51 + ROUNDS * chords.ROUGH_PER_CHORD * (chords.KSECT - 1), points
    assert abs(check.excess[0]) <= 1e-9, check.excess
    monkeypatch.setattr(chords, "ROUGH_PER_CHORD", 10 ** 9)
    uncapped, _ = run()
    assert uncapped > 100_000, uncapped
