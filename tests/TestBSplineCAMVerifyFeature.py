# SPDX-License-Identifier: LGPL-2.1-or-later
"""The simulated-part object (app layer, headless): its mesh is the verification's Z-map.

unittest run by ``freecadcmd`` (``tools/run_freecad_tests.sh TestBSplineCAMVerifyFeature``).
The Z-map is recomputed independently by the core from the same G-code text, and the mesh's
vertices, deviation and metrics are compared with it.
"""

from __future__ import annotations

import json
import tempfile
import unittest
from pathlib import Path

import numpy as np
from bsplinecam_freecad import CASE_STUDY, TOOL, FreeCAD

from BSplineCAM import Surface
from BSplineCAM.app import cam, pipeline
from BSplineCAM.app import verify_feature as vf
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify

CELL = 0.5


class TestVerificationFeature(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.doc = FreeCAD.newDocument("TestBSplineCAMVerifyFeature")
        cls.surface = Surface.from_json(CASE_STUDY)
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.1)
        cls.model, cls.job, cls.op = pipeline.build_job(cls.surface, params, cam.Cutting(),
                                                        cls.doc)
        cls.doc.recompute()
        cls.obj = vf.verify_job(cls.job, cell=CELL, stride=3)
        # the reference: the same program text, simulated by the core alone
        cls.gcode = vf.job_program(cls.job)
        cls.reference = verify(cls.surface, read_gcode(cls.gcode), Tool(TOOL), CELL)

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def test_object_and_properties(self):
        obj = self.obj
        self.assertTrue(vf.is_verification(obj))
        self.assertEqual(obj.TypeId, "Mesh::FeaturePython")
        self.assertIs(obj.Job, self.job)
        self.assertIs(obj.Surface, self.model)
        self.assertAlmostEqual(obj.ToolDiameter.Value, TOOL)
        self.assertAlmostEqual(obj.Cell.Value, CELL)
        self.assertEqual(obj.Stride, 3)
        self.assertEqual(obj.Version, vf.OBJECT_VERSION)
        metrics = json.loads(obj.Metrics)
        for key in ("gouge_max_mm", "scallop_max_mm", "scallop_p99_mm", "coverage",
                    "cutting_length_mm", "machining_time_s"):
            self.assertAlmostEqual(metrics[key], self.reference.metrics[key], places=9, msg=key)
        self.assertLess(metrics["gouge_max_mm"], 0.01)
        self.assertGreater(metrics["coverage"], 0.95)

    def test_mesh_heights_equal_the_zmap(self):
        obj = self.obj
        height = self.reference.simulation.height
        ny, nx = height.shape
        rows, cols = vf.grid_indices(ny, 3), vf.grid_indices(nx, 3)
        self.assertEqual((obj.GridRows, obj.GridColumns), (len(rows), len(cols)))
        self.assertEqual(rows[-1], ny - 1)
        self.assertEqual(cols[-1], nx - 1)
        points = np.array([tuple(p.Vector) for p in obj.Mesh.Points])
        top = obj.GridRows * obj.GridColumns
        ring = 2 * (obj.GridRows + obj.GridColumns) - 4
        self.assertEqual(len(points), top + ring + 1)
        xs, ys = self.reference.simulation.grid.centres()
        rng = np.random.default_rng(5)
        for k in rng.integers(0, top, 300):
            r, c = divmod(int(k), obj.GridColumns)
            i, j = rows[r], cols[c]
            np.testing.assert_allclose(points[k], [xs[j], ys[i], height[i, j]], atol=1e-9)
        # every top vertex, not just the sample
        np.testing.assert_allclose(points[:top, 2], height[np.ix_(rows, cols)].ravel(),
                                   atol=1e-9)
        # the base is flat and below everything
        self.assertTrue(np.all(points[top:, 2] < height.min()))
        self.assertAlmostEqual(float(np.ptp(points[top:, 2])), 0.0)

    def test_deviation_per_vertex(self):
        dev = vf.deviation_of(self.obj)
        ref = self.reference.deviation
        ny, nx = ref.shape
        expected = ref[np.ix_(vf.grid_indices(ny, 3), vf.grid_indices(nx, 3))].ravel()
        self.assertEqual(len(dev), len(expected))
        np.testing.assert_array_equal(np.isnan(dev), np.isnan(expected))
        ok = ~np.isnan(dev)
        np.testing.assert_allclose(dev[ok], expected[ok], atol=1e-12)

    def test_mesh_is_a_closed_solid(self):
        mesh = self.obj.Mesh
        self.assertTrue(mesh.isSolid())
        self.assertFalse(mesh.hasNonManifolds())
        box = self.obj.Mesh.BoundBox
        self.assertGreater(mesh.Volume, 0.0)
        self.assertLess(box.XMin, 1.0)
        self.assertGreater(box.XMax, 99.0)

    def test_file_route_and_reopen(self):
        program = Path(self.tmp.name) / "job.ngc"
        program.write_text(self.gcode, encoding="utf-8")
        obj = vf.verify_file(self.model, program, TOOL, cell=1.0)
        self.assertEqual(obj.Program, str(program))
        self.assertEqual(obj.Stride, 1)  # 100 x 100 cells need no thinning
        self.assertIsNone(obj.Job)
        name, count = obj.Name, obj.Mesh.CountPoints
        metrics = obj.Metrics
        path = Path(self.tmp.name) / "verify.FCStd"
        self.doc.saveCopy(str(path))
        other = FreeCAD.openDocument(str(path))
        try:
            again = other.getObject(name)
            self.assertTrue(vf.is_verification(again))
            self.assertEqual(again.Mesh.CountPoints, count)
            self.assertEqual(again.Metrics, metrics)
            np.testing.assert_array_equal(vf.deviation_of(again), vf.deviation_of(obj))
        finally:
            FreeCAD.closeDocument(other.Name)
        self.doc.removeObject(name)

    def test_bad_input_leaves_document_alone(self):
        names = [o.Name for o in self.doc.Objects]
        with self.assertRaises(Exception):
            vf.make_verification(self.model, "G0 X0 Y0 Z50\nM2\n", 200.0)  # tool too large
        with self.assertRaises(Exception):
            vf.make_verification(self.model, "G1 X0 Y0 Z0 Q\nM2\n", TOOL)
        self.assertEqual([o.Name for o in self.doc.Objects], names)


if __name__ == "__main__":
    unittest.main()
