# SPDX-License-Identifier: LGPL-2.1-or-later
"""Waterline levels and what the waterline leaves (core/toolpath/waterline.py level_steps,
shallow_share; faces_waterline): a hollow the ball fits bounds no step-down, and the share of
the faces too flat for waterline is measured and said.  Against closed forms on a plate with a
3 mm fillet round a boss's foot (a torus quarter, rational quadratic both ways)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from bsplinecam_helpers import fillet_ring, plate_with_hole

from BSplineCAM.core.toolpath import faces_waterline
from BSplineCAM.core.toolpath.common import ToolParameters
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.waterline import level_steps, shallow_share

RHO, WALL, BASE, HOLE, SIZE = 3.0, 12.0, 10.0, 15.0, 40.0  # mm, as fillet_ring, plate_with_hole
TOP = 25.0  # mm, the boss's top


def _boss_top(height: float = TOP, centre=(20.0, 20.0)):
    """The boss's flat top: a plane at ``height`` trimmed to the disc of radius WALL."""
    from BSplineCAM.core.geometry.faces import Face
    from BSplineCAM.core.geometry.nurbs import NurbsSurface

    lo, hi = np.subtract(centre, WALL), np.add(centre, WALL)
    poles = np.array([[[lo[0], lo[1], height], [lo[0], hi[1], height]],
                      [[hi[0], lo[1], height], [hi[0], hi[1], height]]], dtype=float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name="Face3")
    t = np.linspace(0.0, 2 * np.pi, 241)
    disc = 0.5 + 0.5 * np.column_stack([np.cos(t), np.sin(t)])
    disc[-1] = disc[0]
    return Face(s, disc, index=3, source="Plane")


def _levels(diameter: float) -> list[float]:
    """The levels of a boss's fillet and top on the plate (the boss's wall left out: only the
    selected faces' samples set them)."""
    fs = FaceSet([plate_with_hole(), fillet_ring(), _boss_top()])
    tool = ToolParameters.validate(diameter, 0.1, 0.002)
    signs = faces_waterline._upward_signs(fs)
    slope = math.radians(30.0)
    zs, dzs, z_low, z_high = faces_waterline._steep_samples(fs, tool, signs, slope)
    return faces_waterline.level_heights(zs, dzs, tool, slope, z_high, z_low)


def test_a_fillet_the_ball_fits_sets_no_levels():
    """A 6 mm ball in the 3 mm fillet touches it only with its centre on the fillet's axis (a
    single tip height, the plate's): no level in between finishes anything of it, so it
    bounds no step (its 0.02 of the flat one would give a boss's foot 30 levels 0.04 mm apart,
    each bisected round the boss's wall); the levels keep the flat stepover's vertical
    share.  A 5 mm ball (a 2.5 mm radius in the 3 mm hollow) still has its levels set by the
    fillet's curvature."""
    six = _levels(6.0)
    flat = ToolParameters.validate(6.0, 0.1, 0.002).flat_stepover
    assert len(six) <= math.ceil((TOP - BASE) / flat), six  # 76 with the fillet's steps
    assert np.all(-np.diff(six) >= 0.999 * flat), np.diff(six)
    five = _levels(5.0)
    in_fillet = [z for z in five if z < BASE + 1.0]  # where the fillet (tips 10-10.5 mm) sets them
    assert len(in_fillet) >= 5 and np.all(-np.diff(in_fillet) < 0.5 * flat), five
    # the bound itself: inf where the ball fits (radius R or up to 5 % wider), else finite
    tool = ToolParameters.validate(6.0, 0.1, 0.002)
    n = np.tile([math.sin(math.radians(45)), 0.0, math.cos(math.radians(45))], (3, 1))
    dz = level_steps(tool, n, np.array([1 / 3.0, 1 / 3.1, 1 / 3.6]))
    assert np.isinf(dz[:2]).all() and 0 < dz[2] < flat


def test_share_too_flat_for_waterline_is_measured_and_said():
    """The plate and the fillet's part flatter than 30 degrees, against the closed form: a
    point of the fillet at angle phi from its plate-side end has slope phi and lies at radius
    WALL + RHO - RHO sin(phi) from the boss's axis, so the torus strip up to phi has area
    2 pi RHO [(WALL + RHO) phi + RHO (cos phi - 1)]."""
    fs = FaceSet([plate_with_hole(), fillet_ring()])
    signs = faces_waterline._upward_signs(fs)

    def strip(phi):
        return 2 * math.pi * RHO * ((WALL + RHO) * phi + RHO * (math.cos(phi) - 1.0))

    plate = SIZE * SIZE - math.pi * HOLE * HOLE
    for deg in (30.0, 60.0):
        want = (plate + strip(math.radians(deg))) / (plate + strip(math.pi / 2))
        got = shallow_share(*faces_waterline._face_normals(fs, signs), math.radians(deg))
        assert got == pytest.approx(want, abs=0.01), (deg, got, want)
    tp = faces_waterline.generate_faces_waterline(fs, 6.0, 0.3, 0.01)
    share = 100 * (plate + strip(math.pi / 6)) / (plate + strip(math.pi / 2))
    said = [n for n in tp.stats.notes if "flatter than 30 degrees" in n]
    assert said and said[0].startswith(f"{share:.0f} %"), (tp.stats.notes, share)
