# SPDX-License-Identifier: LGPL-2.1-or-later
"""Jet.at on surfaces whose parameters are not [0, 1]: the clip follows the surface's domain.

A bilinear NURBS plane z = 0.1 x + 0.2 y over x, y in [0, 10] mm with knots on [2, 5] x [-3, 7]
has the closed form x = 10 (u - 2) / 3, y = (w + 3); a jet there must be that point with those
derivatives, and parameters beyond the domain land on its border, not on [0, 1].
"""

from __future__ import annotations

import numpy as np
import pytest

from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.geometry.surface import Surface
from BSplineCAM.core.toolpath.primitives import Jet


def plane() -> NurbsSurface:
    poles = np.array([[[x, y, 0.1 * x + 0.2 * y] for y in (0.0, 10.0)] for x in (0.0, 10.0)])
    return NurbsSurface(poles, [2.0, 2.0, 5.0, 5.0], [-3.0, -3.0, 7.0, 7.0], 1, 1)


def closed_form(u, w):
    x, y = 10.0 * (u - 2.0) / 3.0, w + 3.0
    return np.stack([x, y, 0.1 * x + 0.2 * y], axis=-1)


def test_jet_inside_a_shifted_domain_is_the_closed_form():
    u = np.array([2.0, 3.1, 4.7, 5.0])
    w = np.array([-3.0, 0.5, 6.2, 7.0])
    jet = Jet.at(plane(), u, w)
    np.testing.assert_allclose(jet.u, u)
    np.testing.assert_allclose(jet.w, w)
    np.testing.assert_allclose(jet.p, closed_form(u, w), atol=1e-12)
    np.testing.assert_allclose(jet.su, np.tile([10.0 / 3.0, 0.0, 1.0 / 3.0], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(jet.sw, np.tile([0.0, 1.0, 0.2], (4, 1)), atol=1e-12)
    n = np.array([-0.1, -0.2, 1.0]) / np.linalg.norm([-0.1, -0.2, 1.0])
    np.testing.assert_allclose(jet.normal, np.tile(n, (4, 1)), atol=1e-12)


def test_jet_clips_to_the_surface_domain_not_the_unit_square():
    jet = Jet.at(plane(), [0.5, 9.0], [-10.0, 0.5])
    np.testing.assert_allclose(jet.u, [2.0, 5.0])
    np.testing.assert_allclose(jet.w, [-3.0, 0.5])
    np.testing.assert_allclose(jet.p, closed_form(jet.u, jet.w), atol=1e-12)


def test_jet_on_a_net_clips_to_the_unit_square():
    poles = np.array([[[x, y, 0.0] for y in np.linspace(0, 30, 4)] for x in np.linspace(0, 30, 4)])
    jet = Jet.at(Surface(poles), [-0.5, 0.25, 1.5], [0.5, 2.0, -1.0])
    np.testing.assert_allclose(jet.u, [0.0, 0.25, 1.0])
    np.testing.assert_allclose(jet.w, [0.5, 1.0, 0.0])
    assert jet.p[:, 2] == pytest.approx([0.0, 0.0, 0.0])
