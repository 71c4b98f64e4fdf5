# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD's own 3D Surface op (OpenCAMLib) set up on a BSplineCAM job, for comparison.

unittest classes run by ``freecadcmd`` (tools/run_freecad_tests.sh TestBSplineCAMSurfaceOp).
With OpenCAMLib (0.20: the PyPI wheel; 1.0 and 1.1: Debian's python3-opencamlib) the op is
computed at a coarse scallop, posted and checked by rs274; without it setting it up raises
OpenCAMLibMissing.  tools/test.sh sets BSPLINECAM_REQUIRE_ALL=1: there a missing OpenCAMLib is
an error, not a skip.
"""

from __future__ import annotations

import math
import os
import re
import tempfile
import unittest
from pathlib import Path
from unittest import mock

import numpy as np
from bsplinecam_freecad import CASE_STUDY, ROUNDING, TOOL, FreeCAD, rs274_or_skip

from BSplineCAM import Surface
from BSplineCAM.app import cam, compat, surface3d
from BSplineCAM.app.surface_feature import make_surface
from BSplineCAM.core.program import rs274
from BSplineCAM.core.program.gcode import MoveKind, read_gcode

#: Coarse enough for a quick test: stepover 2 sqrt(2 R h - h^2) = 3.3 mm (55 % of the tool).
SCALLOP = 0.5
#: FreeCAD's default sampling along a pass (mm), and a coarse tessellation (mm), for speed.
SAMPLE_INTERVAL = 1.0
LINEAR_DEFLECTION = 0.02


class JobFixture(unittest.TestCase):
    """A document with the case study as a solid and a job with a 6 mm ball-end tool."""

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMSurfaceOp")
        cls.model = make_surface(Surface.from_json(CASE_STUDY), doc=cls.doc, solid=True)
        cls.doc.recompute()
        cls.job = cam.make_job(cls.model, TOOL)
        cls.tmp = tempfile.TemporaryDirectory()

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()


class TestSettings(unittest.TestCase):
    def test_stepover_gives_the_scallop_on_a_flat(self):
        for h in (0.01, 0.05, 0.5):
            percent = surface3d.stepover_percent(TOOL, h)
            s = TOOL * percent / 100.0
            radius = TOOL / 2.0
            self.assertAlmostEqual(radius - math.sqrt(radius**2 - (s / 2.0) ** 2), h, places=12)
        self.assertAlmostEqual(surface3d.stepover_percent(6.0, 0.01), 8.1582, places=3)

    def test_sample_interval_follows_the_chordal_rule(self):
        self.assertAlmostEqual(surface3d.chordal_sample_interval(6.0, 0.002), math.sqrt(0.048))
        self.assertAlmostEqual(surface3d.chordal_sample_interval(6.0, 1.0), 1.5)

    def test_bad_arguments_are_named(self):
        with self.assertRaisesRegex(ValueError, "scallop"):
            surface3d.stepover_percent(TOOL, 0.0)
        with self.assertRaisesRegex(ValueError, "scallop"):
            surface3d.stepover_percent(TOOL, 3.0)
        with self.assertRaisesRegex(ValueError, "tool_diameter"):
            surface3d.stepover_percent(-1.0, 0.01)


class TestMissingOpenCAMLib(JobFixture):
    def test_clear_error_without_opencamlib(self):
        """Pretended absent where it is installed; really absent in a FreeCAD without it."""
        # what is missing, and how to get it on this FreeCAD
        how = {"0.20": "pip install opencamlib", "1.0": "apt-get install python3-opencamlib",
               "1.1": "apt-get install python3-opencamlib"}[compat.cam_series()]
        missing = r"OpenCAMLib \(Python module 'ocl' or 'opencamlib\.ocl'\).*" + re.escape(how)
        with (
            mock.patch.object(compat, "opencamlib_available", return_value=False),
            self.assertRaisesRegex(surface3d.OpenCAMLibMissing, missing),
        ):
            surface3d.add_freecad_surface_op(self.job, SCALLOP, TOOL)
        if not compat.opencamlib_available():
            with self.assertRaisesRegex(RuntimeError, "needs OpenCAMLib"):
                surface3d.add_freecad_surface_op(self.job, SCALLOP, TOOL)
        self.assertEqual(len(self.job.Operations.Group), 0)


@unittest.skipUnless(compat.opencamlib_available() or os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1",
                     "OpenCAMLib (ocl) is not importable")
class TestFreeCADSurfaceOp(JobFixture):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.op = surface3d.add_freecad_surface_op(
            cls.job, SCALLOP, TOOL, sample_interval=SAMPLE_INTERVAL
        )
        cls.op.LinearDeflection = LINEAR_DEFLECTION
        cls.doc.recompute()

    def test_configuration(self):
        op = self.op
        self.assertEqual(op.ScanType, "Planar")
        self.assertEqual(op.LayerMode, "Single-pass")
        self.assertEqual(op.CutPattern, "ZigZag")
        self.assertAlmostEqual(op.StepOver, surface3d.stepover_percent(TOOL, SCALLOP))
        self.assertAlmostEqual(op.SampleInterval.Value, SAMPLE_INTERVAL)
        ((base, subs),) = op.Base
        self.assertIs(base, self.job.Model.Group[0])
        face = base.Shape.getElement(subs[0])
        self.assertEqual(type(face.Surface).__name__, "BSplineSurface")
        self.assertIs(op.ToolController, self.job.Tools.Group[0])
        self.assertGreater(op.ClearanceHeight.Value, self.job.Stock.Shape.BoundBox.ZMax)

    def test_path_stays_on_the_top_surface(self):
        feeds = np.array(
            [
                [c.Parameters[k] for k in "XYZ"]
                for c in self.op.Path.Commands
                if c.Name == "G1" and all(k in c.Parameters for k in "XYZ")
            ]
        )
        self.assertGreater(len(feeds), 100)
        box = self.model.Shape.BoundBox
        top = self.model.Shape.getElement(self.op.Base[0][1][0]).BoundBox
        self.assertGreaterEqual(feeds[:, 0].min(), box.XMin - ROUNDING)
        self.assertLessEqual(feeds[:, 0].max(), box.XMax + ROUNDING)
        self.assertGreaterEqual(feeds[:, 1].min(), box.YMin - ROUNDING)
        self.assertLessEqual(feeds[:, 1].max(), box.YMax + ROUNDING)
        # no feed below the top face: the side walls are not followed down
        self.assertGreaterEqual(feeds[:, 2].min(), top.ZMin - ROUNDING)
        # passes along X, about one stepover apart
        rows = np.unique(np.round(feeds[:, 1], 3))
        stepover = TOOL * self.op.StepOver / 100.0
        self.assertTrue(np.allclose(np.diff(rows), stepover, atol=1e-3), rows)

    def test_program_passes_rs274(self):
        path = Path(self.tmp.name) / "surface3d.ngc"
        text = cam.post_process(self.job, "linuxcnc", path)
        moves = read_gcode(text)
        self.assertGreater(int(np.sum(moves.kind == MoveKind.LINE)), 100)
        rs274_or_skip(self)
        check = rs274.check(path, {1: TOOL})
        self.assertTrue(check.ok, check.message)
        self.assertEqual(int(np.sum(moves.kind == MoveKind.LINE)), check.feeds)

    def test_mismatched_tool_and_pattern_are_refused(self):
        with self.assertRaisesRegex(ValueError, "tool_diameter 8 mm differs"):
            surface3d.add_freecad_surface_op(self.job, SCALLOP, 8.0)
        with self.assertRaisesRegex(ValueError, "pattern"):
            surface3d.add_freecad_surface_op(self.job, SCALLOP, TOOL, pattern="Spiral")


if __name__ == "__main__":
    unittest.main()
