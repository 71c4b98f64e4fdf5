# SPDX-License-Identifier: LGPL-2.1-or-later
"""The arc fitting's compiled kernels (BSplineCAM.core.kernels.arcs_kernels) against the numpy
engine of ``arcs_fit._fit_runs`` and ``_fit_biarcs``: the same fits to the last bit on
batches of random runs (noisy, smooth, kinked, vertical and flat frames, tolerances from
1e-4 to 0.1 mm), the same moves from ``fit_polyline`` and ``fit_arcs`` on random polylines in
every plane, and the same moves on the case study's raster at 0.01 mm.

The kernels' loop functions also run as plain Python against the numpy engine, so the
algorithm is checked where numba is missing; the compiled half is skipped there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bsplinecam_helpers import numba_ready, same, under_both

from BSplineCAM.core import Surface, kernels
from BSplineCAM.core.kernels import arcs_kernels
from BSplineCAM.core.toolpath import arcs_fit, generate, to_moves
from BSplineCAM.core.toolpath.arcs import fit_arcs, fit_polyline
from BSplineCAM.core.toolpath.common import Move

CASE_STUDY = Path(__file__).resolve().parent.parent / "examples" / "case-study.json"
needs_numba = pytest.mark.skipif(not numba_ready(), reason="numba does not import")
SEEDS = range(12)


def random_runs(seed: int) -> tuple[list, np.ndarray]:
    """2-D runs along +x of 2..40 points: arcs of random circles with noise, noisy sines,
    random walks and straight lines; half of them flagged vertical."""
    rng = np.random.default_rng(seed)
    runs = []
    for _ in range(60):
        n = int(rng.integers(2, 41))
        x = np.cumsum(rng.uniform(0.005, 0.3, n))
        kind = rng.integers(4)
        if kind == 0:
            r = rng.uniform(0.5, 50.0)
            xc = x.mean() + rng.normal(0.0, 0.2 * r)
            z = np.sqrt(np.maximum(r * r - (x - xc) ** 2, 0.0)) * rng.choice([-1.0, 1.0])
        elif kind == 1:
            z = rng.uniform(0.1, 3.0) * np.sin(x / rng.uniform(0.2, 5.0))
        elif kind == 2:
            z = np.cumsum(rng.normal(0.0, 0.02, n))
        else:
            z = rng.uniform(-1.0, 1.0) * x
        z = z + rng.normal(0.0, 10.0 ** rng.uniform(-7, -3), n)
        pts = np.column_stack([x, z])
        if rng.uniform() < 0.3:  # a rotated frame (a contour's)
            a = rng.uniform(0.0, 2.0 * np.pi)
            pts = pts @ np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
        runs.append(pts)
    return runs, rng.uniform(size=len(runs)) < 0.5


def fits_of(runs, tolerance, vertical):
    """Per run (line flag, centre, radius) or None, as plain data."""
    return [None if f is None else (f.line, np.asarray(f.centre), f.radius)
            for f in arcs_fit._fit_runs(runs, tolerance, vertical)]


def biarcs_of(runs, tolerance, vertical):
    ta = np.array([arcs_fit._tangents(r)[0] for r in runs])
    tb = np.array([arcs_fit._tangents(r)[-1] for r in runs])
    return [None if f is None else (f.joint, f.centres, f.radii)
            for f in arcs_fit._fit_biarcs(runs, ta, tb, tolerance, vertical)]


def polyline(seed: int) -> tuple[np.ndarray, int, float]:
    """A random polyline in G18, G19 or G17 (either way along its axis), with its plane and
    side."""
    rng = np.random.default_rng(100 + seed)
    n = int(rng.integers(3, 300))
    s = np.cumsum(rng.uniform(0.01, 0.2, n)) * rng.choice([-1.0, 1.0])
    h = rng.uniform(0.5, 4.0) * np.sin(s / rng.uniform(0.5, 4.0)) \
        + rng.normal(0.0, 10.0 ** rng.uniform(-6, -3), n)
    plane = int(rng.choice([17, 18, 19]))
    c = rng.uniform(-5.0, 5.0)
    if plane == 18:
        pts = np.column_stack([s, np.full(n, c), h])
    elif plane == 19:
        pts = np.column_stack([np.full(n, c), s, h])
    else:
        pts = np.column_stack([s, h, np.full(n, c)])
    return pts, plane, float(rng.choice([-1.0, 1.0]))


def moves_data(moves) -> list[tuple]:
    return [tuple(m) for m in moves]


@pytest.fixture
def plain_loops(monkeypatch):
    """The kernels' loop functions run as plain Python where the kernels would run."""
    monkeypatch.setattr(arcs_fit.kernels, "use_numba", lambda: True)
    monkeypatch.setattr(arcs_kernels, "fit_runs", arcs_kernels.fit_runs.py)
    monkeypatch.setattr(arcs_kernels, "biarc_checks", arcs_kernels.biarc_checks.py)


def test_limits_agree():
    assert arcs_kernels.MIN_RADIUS == arcs_fit.MIN_RADIUS
    assert arcs_kernels.MARGIN == arcs_fit.MARGIN
    assert arcs_kernels.ROUNDING == arcs_fit.ROUNDING
    assert arcs_kernels.BISECTIONS == arcs_fit.BISECTIONS


@pytest.mark.parametrize("seed", SEEDS[:4])
@pytest.mark.parametrize("tolerance", [1e-3, 0.05])
def test_loops_as_python_match_numpy(seed, tolerance, plain_loops):
    runs, vertical = random_runs(seed)
    with kernels.forced("numpy"):
        want = (fits_of(runs, tolerance, vertical), biarcs_of(runs, tolerance, vertical))
    got = (fits_of(runs, tolerance, vertical), biarcs_of(runs, tolerance, vertical))
    assert [f is None for f in got[0]] == [f is None for f in want[0]]
    assert [f is None for f in got[1]] == [f is None for f in want[1]]
    same([x for f in got[0] if f for x in f], [x for f in want[0] if f for x in f])
    same([x for f in got[1] if f for x in f], [x for f in want[1] if f for x in f])


@needs_numba
@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("tolerance", [1e-4, 1e-3, 0.01, 0.1])
def test_fits_same_in_both_engines(seed, tolerance):
    runs, vertical = random_runs(seed)
    a, b = under_both(lambda: (fits_of(runs, tolerance, vertical),
                               biarcs_of(runs, tolerance, vertical)))
    for want, got in zip(a, b):
        assert [f is None for f in got] == [f is None for f in want]
        same([x for f in got if f for x in f], [x for f in want if f for x in f])


def test_batches_cover_every_branch():
    """The random batches hold lines, arcs, refusals and biarcs (numpy engine)."""
    seen = {"line": 0, "arc": 0, "none": 0, "biarc": 0, "no biarc": 0}
    with kernels.forced("numpy"):
        for seed in SEEDS[:3]:
            runs, vertical = random_runs(seed)
            for tolerance in (1e-3, 0.1):
                for f in fits_of(runs, tolerance, vertical):
                    seen["none" if f is None else "line" if f[0] else "arc"] += 1
                for f in biarcs_of(runs, tolerance, vertical):
                    seen["no biarc" if f is None else "biarc"] += 1
    assert min(seen.values()) > 0, seen


@needs_numba
@pytest.mark.parametrize("seed", SEEDS)
def test_polylines_same_in_both_engines(seed):
    pts, plane, side = polyline(seed)
    a, b = under_both(lambda: moves_data(fit_polyline(pts, 0.002, plane, side)))
    assert a == b
    moves = [Move("rapid", *pts[0])] + [Move("feed", *p) for p in pts[1:]]
    a, b = under_both(lambda: moves_data(fit_arcs(moves, 0.002, lambda _: side)))
    assert a == b


@needs_numba
def test_case_study_raster_same_in_both_engines():
    toolpath = generate(Surface.from_json(CASE_STUDY), "raster", 6.0, 0.01)
    moves = to_moves(toolpath)
    tolerance = 0.5 * float(toolpath.parameters["tolerance"])
    a, b = under_both(lambda: moves_data(fit_arcs(moves, tolerance)))
    assert a == b
    assert sum(len(m) == 9 for m in a) > 1000  # arcs, thousands of them
