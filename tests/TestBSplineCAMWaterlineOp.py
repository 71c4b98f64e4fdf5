# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD's own Waterline op (OpenCAMLib) set up on a BSplineCAM job, for comparison.

unittest classes run by ``freecadcmd`` (tools/run_freecad_tests.sh TestBSplineCAMWaterlineOp).
The part is the filleted box of TestBSplineCAMFaces (40 x 30 x 20 mm, top edges 4 mm), its top
and fillets the selected faces; at a coarse scallop the op's levels are StepDown apart down to
the fillets' foot, its lowest contour runs about the ball radius off the box's walls (the stock
widened so that the scan reaches there), and its program passes rs274.  Without OpenCAMLib
setting it up raises OpenCAMLibMissing; tools/test.sh (BSPLINECAM_REQUIRE_ALL=1) makes a
missing OpenCAMLib an error, not a skip.
"""

from __future__ import annotations

import math
import os
import tempfile
import unittest
from pathlib import Path

import numpy as np
from bsplinecam_freecad import TOOL, FreeCAD, rs274_or_skip

from BSplineCAM.app import cam, compat, waterline3d
from BSplineCAM.core.program import rs274
from BSplineCAM.core.program.gcode import MoveKind, read_gcode

#: Step-down 2 sqrt(2 R h - h^2) = 3.3 mm on a wall; a coarse scan grid (mm), for speed.
SCALLOP = 0.5
SAMPLE_INTERVAL = 0.5
#: The box's top edges' fillet radius and the box (mm).
FILLET = 4.0
SIZE = (40.0, 30.0, 20.0)


def filleted_box():
    import Part

    box = Part.makeBox(*SIZE)
    top = [e for e in box.Edges
           if abs(e.BoundBox.ZMin - SIZE[2]) < 1e-9 and abs(e.BoundBox.ZMax - SIZE[2]) < 1e-9]
    return box.makeFillet(FILLET, top)


class TestSettings(unittest.TestCase):
    def test_stepdown_gives_the_scallop_on_a_vertical_wall(self):
        radius = TOOL / 2.0
        for h in (0.01, 0.2, 0.5):
            d = waterline3d.wall_stepdown(TOOL, h)
            self.assertAlmostEqual(radius - math.sqrt(radius**2 - (d / 2.0) ** 2), h, places=12)

    def test_bad_arguments_are_named(self):
        with self.assertRaisesRegex(ValueError, "scallop"):
            waterline3d.wall_stepdown(TOOL, 3.0)
        with self.assertRaisesRegex(ValueError, "tool_diameter"):
            waterline3d.wall_stepdown(0.0, 0.1)


@unittest.skipUnless(compat.opencamlib_available()
                     or os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1",
                     "OpenCAMLib is not installed")
class TestWaterlineOp(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMWaterlineOp")
        cls.model = cls.doc.addObject("Part::Feature", "Box")
        cls.model.Shape = filleted_box()
        cls.doc.recompute()
        cls.job = cam.make_job(cls.model, TOOL)
        model = cls.job.Model.Group[0]
        cls.faces = [f"Face{i + 1}" for i, f in enumerate(model.Shape.Faces)
                     if f.BoundBox.ZMax > SIZE[2] - FILLET - 1e-6
                     and f.BoundBox.ZMin > SIZE[2] - FILLET - 1e-6]
        waterline3d.widen_stock(cls.job, TOOL)
        cls.op = waterline3d.add_freecad_waterline_op(cls.job, cls.faces, SCALLOP, TOOL,
                                                      sample_interval=SAMPLE_INTERVAL)
        cls.doc.recompute()
        cls.tmp = tempfile.TemporaryDirectory()

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def feeds(self) -> np.ndarray:
        """End points (mm) of the op's G1 moves, the axes a command omits kept from before."""
        here = {"X": math.nan, "Y": math.nan, "Z": math.nan}
        ends = []
        for command in self.op.Path.Commands:
            here.update({k: v for k, v in command.Parameters.items() if k in here})
            if command.Name in ("G1", "G01"):
                ends.append([here[k] for k in "XYZ"])
        return np.array(ends).reshape(-1, 3)

    def test_configuration(self):
        op = self.op
        self.assertEqual(len(self.faces), 5)  # the top and its four fillets
        self.assertEqual((op.Algorithm, op.LayerMode, op.BoundBox),
                         ("OCL Dropcutter", "Multi-pass", "Stock"))
        self.assertAlmostEqual(op.StepDown.Value, waterline3d.wall_stepdown(TOOL, SCALLOP))
        self.assertAlmostEqual(op.SampleInterval.Value, SAMPLE_INTERVAL)
        self.assertAlmostEqual(op.FinalDepth.Value, SIZE[2] - FILLET)
        stock = self.job.Stock.Shape.BoundBox
        self.assertLessEqual(stock.XMin, -TOOL + 1e-9)
        self.assertGreaterEqual(stock.YMax, SIZE[1] + TOOL - 1e-9)

    def test_levels_are_stepdown_apart_down_to_the_faces_foot(self):
        levels = np.unique(np.round(self.feeds()[:, 2], 4))
        self.assertAlmostEqual(levels.min(), SIZE[2] - FILLET, places=3)
        steps = np.diff(levels)
        self.assertTrue(np.all(steps <= self.op.StepDown.Value + 1e-3), levels)

    def test_lowest_contour_runs_the_radius_off_the_walls(self):
        feeds = self.feeds()
        low = feeds[np.abs(feeds[:, 2] - (SIZE[2] - FILLET)) < 1e-3]
        self.assertGreater(len(low), 20)
        radius = TOOL / 2.0
        # outside the box, within two scan cells of the offset outline: the contour is drawn
        # through the scan's grid, whose cells it cuts across (inside the offset at corners)
        dx = np.maximum(np.maximum(-low[:, 0], low[:, 0] - SIZE[0]), 0.0)
        dy = np.maximum(np.maximum(-low[:, 1], low[:, 1] - SIZE[1]), 0.0)
        off = np.hypot(dx, dy)
        self.assertTrue(np.all(np.abs(off - radius) < 2.0 * SAMPLE_INTERVAL),
                        (off.min(), off.max()))

    def test_program_passes_rs274(self):
        path = Path(self.tmp.name) / "waterline3d.ngc"
        text = cam.post_process(self.job, "linuxcnc", path)
        moves = read_gcode(text)
        self.assertGreater(int(np.sum(moves.kind == MoveKind.LINE)), 20)
        rs274_or_skip(self)
        check = rs274.check(path, {1: TOOL})
        self.assertTrue(check.ok, check.message)

    def test_mismatched_tool_and_no_faces_are_refused(self):
        with self.assertRaisesRegex(ValueError, "tool_diameter 8 mm differs"):
            waterline3d.add_freecad_waterline_op(self.job, self.faces, SCALLOP, 8.0)
        with self.assertRaisesRegex(ValueError, "faces"):
            waterline3d.add_freecad_waterline_op(self.job, [], SCALLOP, TOOL)


if __name__ == "__main__":
    unittest.main()
