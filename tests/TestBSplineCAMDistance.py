# SPDX-License-Identifier: LGPL-2.1-or-later
"""The exact distance transform and disk dilation against brute force and SciPy."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from BSplineCAM.core.geometry.distance import dilate_disk, squared_distance


def brute_squared(mask: np.ndarray) -> np.ndarray:
    """Every cell against every set cell: the definition, O(cells^2)."""
    ys, xs = np.nonzero(mask)
    gy, gx = np.mgrid[: mask.shape[0], : mask.shape[1]]
    d2 = (gy[..., None] - ys) ** 2 + (gx[..., None] - xs) ** 2
    return d2.min(axis=-1).astype(float)


def brute_dilate(mask: np.ndarray, radius: float) -> np.ndarray:
    """Outside the grid set: pad by the radius, test every offset of the disk."""
    k = int(np.floor(radius)) + 1
    padded = np.pad(mask, k, constant_values=True)
    return brute_squared(padded)[k:-k, k:-k] <= radius * radius + 1e-9


masks = st.integers(1, 24).flatmap(
    lambda ny: st.integers(1, 24).flatmap(
        lambda nx: arrays(bool, (ny, nx), elements=st.booleans())))


@settings(max_examples=150, deadline=None)
@given(masks)
def test_squared_distance_is_the_definition(mask):
    if not mask.any():
        assert (squared_distance(mask) >= (mask.shape[0] ** 2 + mask.shape[1] ** 2)).all()
        return
    np.testing.assert_array_equal(squared_distance(mask), brute_squared(mask))


@settings(max_examples=150, deadline=None)
@given(masks, st.floats(0.0, 12.0))
def test_disk_dilation_with_outside_set(mask, radius):
    np.testing.assert_array_equal(dilate_disk(mask, radius), brute_dilate(mask, radius))


def test_large_grid_against_scipy():
    ndimage = pytest.importorskip("scipy.ndimage")
    rng = np.random.default_rng(7)
    mask = rng.random((300, 420)) < 0.001
    mask[:, :3] = False
    np.testing.assert_allclose(squared_distance(mask),
                               ndimage.distance_transform_edt(~mask) ** 2, atol=1e-9)


def test_footprint_shrinks_by_a_disk():
    """A disc footprint of radius 100 cells shrunk by 30: the inner disc has radius 70."""
    gy, gx = np.mgrid[:241, :241]
    r = np.hypot(gy - 120, gx - 120)
    inside = r <= 100
    inner = inside & ~dilate_disk(~inside, 30.0)
    assert inner[r <= 69].all() and not inner[r > 70.5].any()


@pytest.mark.parametrize("radius", [24.0 - 4e-15, 24.0, 24.0 + 4e-15, 7.0 - 1e-12, 23.5])
@pytest.mark.parametrize("seed", [0, 1])
def test_dilation_at_a_radius_a_rounding_off_a_whole_number(radius, seed):
    """6 mm over 0.25000000000000006 mm cells is 23.999999999999996 cells, and the cap of the
    banded dilation's row distances, 24^2, lies inside r^2 + 1e-9: the dilation still equals
    thresholding the exact distance, on an empty mask (only the border counts, outside set)
    and on a sparse one, and takes no cell of the grid for within it that is not (taking every
    cell empties the part's footprint shrunk by the tool, as Verify G-code in FreeCAD 0.20
    showed)."""
    rng = np.random.default_rng(seed)
    mask = rng.random((90, 110)) < (0.0 if seed == 0 else 0.0005)
    got = dilate_disk(mask, radius, outside=True)
    k = int(np.floor(radius)) + 2
    padded = np.pad(mask, k, constant_values=True)
    want = (squared_distance(padded) <= radius * radius + 1e-9)[k:-k, k:-k]
    assert np.array_equal(got, want)
    assert not got.all()
