# SPDX-License-Identifier: LGPL-2.1-or-later
"""Set-up shared by the test modules that run inside FreeCAD (freecadcmd, not pytest).

Imported first by each of them: puts the repository on sys.path (when a module is loaded from
elsewhere than tools/run_freecad_tests.sh), makes FreeCAD importable, and holds the design
surface and the ball-end size their jobs use, and the block with a B-spline top of the op on
faces (which TestBSplineCAMParts also exports as STEP from a freecadcmd script).  Not a test
module (no ``TestBSplineCAM`` prefix), and free of pytest so that FreeCAD's own Python can load
it.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM.app import compat  # noqa: E402
from BSplineCAM.core.program import rs274  # noqa: E402

FreeCAD = compat.ensure_freecad()
#: The README's case-study control net.
CASE_STUDY = ROOT / "examples" / "case-study.json"
#: Ball-end diameter of the test jobs (mm).
TOOL = 6.0
#: Posted coordinates carry 4 decimals: up to 0.05 µm of rounding per axis (mm).
ROUNDING = 1e-4


def bspline_block():
    """30 x 20 mm block, z from -5 to about 10, its top a degree (3, 2) B-spline face: a
    Part.Shape (Part is imported here, not by the modules that need no shape)."""
    import Part

    V = FreeCAD.Vector
    nu, nv = 5, 4
    x, y = np.meshgrid(np.linspace(-2, 32, nu), np.linspace(-2, 22, nv), indexing="ij")
    z = 10 + 1.5 * np.sin(x / 7) * np.cos(y / 6)
    poles = [[V(float(x[i, j]), float(y[i, j]), float(z[i, j])) for j in range(nv)]
             for i in range(nu)]
    surface = Part.BSplineSurface()
    surface.buildFromPolesMultsKnots(poles, [4, 1, 4], [3, 1, 3], [0, 0.5, 1], [0, 0.5, 1],
                                     False, False, 3, 2)
    prism = Part.Face(surface).extrude(V(0, 0, -30))
    return prism.common(Part.makeBox(30, 20, 30, V(0, 0, -5))).Solids[0]


def rs274_or_skip(case) -> None:
    """In a test case: return if LinuxCNC's rs274 is installed, else skip it, or fail it when
    BSPLINECAM_REQUIRE_ALL=1 (CI, where every check must run)."""
    if rs274.available():
        return
    if os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1":
        case.fail("rs274 (linuxcnc-uspace) is required here (BSPLINECAM_REQUIRE_ALL=1)")
    case.skipTest("rs274 (linuxcnc-uspace) not installed")
