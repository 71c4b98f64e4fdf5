# SPDX-License-Identifier: LGPL-2.1-or-later
"""Set-up shared by the test modules that run inside FreeCAD (freecadcmd, not pytest).

Imported first by each of them: puts the repository on sys.path (when a module is loaded from
elsewhere than tools/run_freecad_tests.sh), makes FreeCAD importable, and holds the design
surface and the ball-end size their jobs use.  Not a test module (no ``TestBSplineCAM``
prefix), and free of pytest so that FreeCAD's own Python can load it.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM.app import compat  # noqa: E402

FreeCAD = compat.ensure_freecad()
#: The README's case-study control net.
CASE_STUDY = ROOT / "examples" / "case-study.json"
#: Ball-end diameter of the test jobs (mm).
TOOL = 6.0
#: Posted coordinates carry 4 decimals: up to 0.05 µm of rounding per axis (mm).
ROUNDING = 1e-4
