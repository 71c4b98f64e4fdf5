# SPDX-License-Identifier: LGPL-2.1-or-later
"""benchmarks/ideal_length.py: the least cutting length for a scallop, against closed forms on
planes (surface area over the stepover that leaves the vertical scallop)."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from ideal_length import ideal_length  # noqa: E402
from TestBSplineCAMPartialPasses import strip  # noqa: E402

from BSplineCAM.core.toolpath.common import ToolParameters, flat_stepover  # noqa: E402

R, H = 3.0, 0.05


@pytest.mark.parametrize("slope_deg", [0.0, 30.0, 50.0])
def test_plane_needs_its_area_over_the_stepover(slope_deg):
    """A plane 40 x 20 mm at ``slope_deg``: the vertical scallop H is H cos(slope) along the
    normal, every direction allows the surface stepover w for it, so the least length in
    space is the surface's area over w, and in XY the XY area over the widest XY spacing
    (passes down the slope: w)."""
    t = math.radians(slope_deg)
    face = strip(0.0, 5.0, 40.0, 5.0 + 40.0 * math.tan(t), 20.0, 1)
    row = ideal_length([face], ToolParameters.validate(2 * R, H, 0.01), 0.1, 72)
    w = flat_stepover(R, H * math.cos(t))
    assert row["area_mm2"] == pytest.approx(800.0, rel=0.01)
    assert row["stepover_max_mm"] == pytest.approx(w, rel=1e-6)
    assert row["length_mm"] == pytest.approx(row["area_mm2"] / w, rel=1e-6)
    assert row["length_3d_mm"] == pytest.approx(row["area_mm2"] / math.cos(t) / w, rel=1e-3)
