# SPDX-License-Identifier: LGPL-2.1-or-later
"""The roughing's distance transforms taken down the columns and then along the rows
(core.kernels.roughing_kernels: a row's lower envelope of parabolas over the cells with a
farther neighbour only, each within the cap's reach) against SciPy's exact Euclidean
distance transform and against the numpy engine, on masks made to hit the row pass's cases:
plateaus of equal column distances, rows with no set cell within the cap, set cells on the
grid's border, one-cell-wide grids and caps wider than the grid.  And the widths of cut of a
batch of feeds in one window (each feed visits its own box) against each feed alone."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_helpers import numba_ready, under_both
from bsplinecam_roughing import bare_job

from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.toolpath.roughing import gridops

needs_numba = pytest.mark.skipif(not numba_ready(), reason="numba does not import")


def _masks() -> list:
    rng = np.random.default_rng(23)
    out = []
    for shape in [(1, 1), (1, 31), (29, 1), (2, 2), (17, 43), (61, 24)]:
        ny, nx = shape
        yy, xx = np.mgrid[0:ny, 0:nx]
        out.append(np.zeros(shape, bool))
        out.append(np.ones(shape, bool))
        corner = np.zeros(shape, bool)
        corner[0, 0] = corner[-1, -1] = True
        out.append(corner)
        rows = np.zeros(shape, bool)
        rows[::7] = True  # equal column distances along each row: plateaus
        out.append(rows)
        out.append(~rows)
        cols = np.zeros(shape, bool)
        cols[:, ::5] = True
        out.append(cols)
        out.append((xx + yy) % 2 == 0)  # checkerboard
        out.append((xx - nx / 3) ** 2 + (yy - ny / 2) ** 2 <= (min(shape) / 3) ** 2)
        for density in (0.01, 0.1, 0.5, 0.95):
            out.append(rng.random(shape) < density)
    return out


CAPS = [0.5, 1.0, 2.0, 3.7, 8.0, 22.0, 100.0]


@pytest.mark.parametrize("cap", CAPS)
def test_capped_distance_is_scipy_s_within_the_cap(cap):
    """Exact up to the cap (SciPy's transform, to the bit: both are square roots of the same
    integers) and ceil(cap) + 1 beyond, under the engine this process runs."""
    from scipy import ndimage

    big = float(int(np.ceil(cap)) + 1)
    for mask in _masks():
        got = gridops.capped_distance(mask, cap)
        if not mask.any():
            assert np.all(got == big)
            continue
        ref = ndimage.distance_transform_edt(~mask)
        assert np.array_equal(got, np.minimum(ref, big))


def test_squared_distance_is_scipy_s():
    """The squared distance is the square of SciPy's exact transform (integers, exact), and
    (ny + nx + 2)^2 everywhere on a mask with no set cell."""
    from scipy import ndimage

    for mask in _masks():
        got = gridops.squared_distance(mask)
        ny, nx = mask.shape
        if not mask.any():
            assert np.all(got == float((ny + nx + 2) ** 2))
            continue
        _, (iy, ix) = ndimage.distance_transform_edt(~mask, return_indices=True)
        yy, xx = np.mgrid[0:ny, 0:nx]
        assert np.array_equal(got, ((yy - iy) ** 2 + (xx - ix) ** 2).astype(float))


@needs_numba
@pytest.mark.parametrize("cap", CAPS)
def test_distances_engines_agree_on_row_cases(cap):
    for mask in _masks():
        a, b = under_both(lambda m=mask: gridops.capped_distance(m, cap))
        assert np.array_equal(a, b)
        a, b = under_both(lambda m=mask: gridops.squared_distance(m))
        assert np.array_equal(a, b)


def _batch_and_alone() -> list:
    """(widths, counts) of a batch of long feeds spread over a grid, in one window, and of
    each feed alone, against the uncut grid and a task grid."""
    job, xs, ys = bare_job(0.25, 30.0, Tool(10.0, "flat"))
    rng = np.random.default_rng(9)
    shape = job.T.shape
    job.z = 1.0
    job.uncut = rng.random(shape) < 0.7
    task = rng.random(shape) < 0.4
    A = rng.uniform(-29.0, 29.0, (12, 2))
    B = np.clip(A + rng.uniform(-12.0, 12.0, A.shape), -31.0, 31.0)  # some beyond the grid
    B[4] = A[4]  # a feed of no length
    out = []
    for kw in ({}, {"task": task}):
        batch = job.engaged(A, B, **kw)
        alone = [job.engaged(A[k:k + 1], B[k:k + 1], **kw) for k in range(len(A))]
        out.append((batch, alone))
    return out


def _check_batch(results) -> None:
    for (widths, counts), alone in results:
        assert np.array_equal(widths, np.concatenate([w for w, _ in alone]))
        assert np.array_equal(counts, np.concatenate([c for _, c in alone]))
        assert widths.max() > 0 and counts.max() > 0


def test_widths_of_a_batch_are_each_feed_s_alone():
    """A feed's width of cut and count of swept cells do not depend on the other feeds of the
    batch (their common window), under the engine this process runs."""
    _check_batch(_batch_and_alone())


@needs_numba
def test_widths_of_a_batch_engines_agree():
    a, b = under_both(_batch_and_alone)
    _check_batch(a)
    _check_batch(b)
    for (batch_a, _), (batch_b, _) in zip(a, b):
        assert np.array_equal(batch_a[0], batch_b[0])
        assert np.array_equal(batch_a[1], batch_b[1])


def test_same_point_is_allclose():
    """Whether a polyline closes: ``same_point`` answers as ``np.allclose`` (its default
    tolerances) on points near and at its tolerance, at zero, and not finite."""
    rng = np.random.default_rng(4)
    cases = [(np.array([np.inf, 1.0]), np.array([np.inf, 1.0])),
             (np.array([np.nan, 1.0]), np.array([np.nan, 1.0])),
             (np.array([1e-9, 0.0]), np.array([0.0, 0.0])),
             (np.array([1.0, 2.0, 3.0]), np.array([1.0, 2.0, 3.0 + 3e-5]))]
    for k in range(20000):
        a = rng.uniform(-500.0, 500.0, 2)
        scale = np.abs(a) if k % 2 else np.ones(2)
        b = a + rng.choice([-1.0, 1.0], 2) * 10.0 ** rng.uniform(-10, -3) * scale
        cases.append((a, b if k % 5 else a.copy()))
    answers = [gridops.same_point(a, b) for a, b in cases]
    assert answers == [bool(np.allclose(a, b)) for a, b in cases]
    assert 0 < sum(answers) < len(answers)
