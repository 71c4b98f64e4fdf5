# SPDX-License-Identifier: LGPL-2.1-or-later
"""Where the ball cannot reach the selected faces (core/toolpath/reach.py), against closed
forms: the corner at the foot of a cone standing on a plate, a fillet the ball fits."""

from __future__ import annotations

import math

import numpy as np
from bsplinecam_helpers import fillet_ring, plate_with_hole, revolved_face

from BSplineCAM.core.toolpath.reach import opening, unreachable_corners


def _frustum(centre=(20.0, 20.0), r0=10.0, z0=10.0, r1=5.0, z1=20.0):
    """The side of a cone frustum standing on the plate: radius r0 at z0 to r1 at z1 (its
    normal points out)."""
    return revolved_face([(r0, z0), (r1, z1)], centre=centre, index=2, source="Cone")


def test_opening_of_a_v_groove_against_its_closed_form():
    """z = |x| (a 90 degree groove): a ball of radius R rests on both flanks, its centre
    R sqrt(2) above the apex, so it reaches R (sqrt(2) - 1) above it; off the apex by more
    than R / sqrt(2) it touches the flank itself."""
    R, cell = 3.0, 0.05
    x = np.arange(-10.0, 10.0 + 1e-9, cell)
    z = np.tile(np.abs(x), (9, 1))
    reach = opening(z, R, cell)[4]
    inner = np.abs(x) < 6.0
    expect = np.where(np.abs(x) <= R / math.sqrt(2),
                      R * math.sqrt(2) - np.sqrt(np.maximum(R * R - x * x, 0.0)), np.abs(x))
    np.testing.assert_allclose(reach[inner], expect[inner], atol=0.02)
    assert np.all(reach[inner] >= np.abs(x)[inner] - 1e-12)  # never below the design


def test_the_corner_at_a_cone_foot_is_unreachable():
    """A frustum (63.4 degree side) on a plate: the ball resting on both leaves a ring of
    material at the foot, 0.641 mm deep at the corner (the ball touching the plate and the
    side: centre 1.854 mm out from the foot, 3 mm up).  A 3 mm fillet there instead, which
    the 6 mm ball fits, leaves nothing."""
    R = 3.0
    faces = [plate_with_hole(hole=10.0), _frustum()]
    regions = unreachable_corners(faces, [True, True], (0.0, 40.0, 0.0, 40.0), R)
    assert len(regions) == 1, [str(r) for r in regions]
    ring = regions[0]
    rc = 10.0 + (R * math.sqrt(125.0) - 5.0 * R) / 10.0
    depth = R + 10.0 - math.sqrt(R * R - (10.0 - rc) ** 2) - 10.0
    assert abs(depth - 0.641) < 1e-3
    # the grid's ball rests on cell centres: beside the steep side it stands up to about a
    # third of a cell (0.1 mm here) too high
    assert depth - 0.05 < ring.depth_mm <= depth + 0.1
    # all round the foot, within the ball's reach of it
    for lo, hi in (ring.x_range, ring.y_range):
        assert 20.0 - rc - 0.5 < lo < 20.0 - 10.0 + 0.1 and 20.0 + 10.0 - 0.1 < hi < 20.0 + rc + 0.5
    assert "left over" in str(ring) and ring.as_dict()["depth_mm"] == ring.depth_mm
    fillet = [plate_with_hole(), fillet_ring()]
    assert unreachable_corners(fillet, [True, True], (0.0, 40.0, 0.0, 40.0), R) == []
