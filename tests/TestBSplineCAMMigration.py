# SPDX-License-Identifier: LGPL-2.1-or-later
"""A document saved by an older FreeCAD opens and recomputes in the newer ones (0.20 -> 1.0 -> 1.1).

Runs inside each FreeCAD (tools/run_freecad_tests.sh); tools/test.sh runs the versions oldest
first and empties the exchange folder before, so that:
- every version saves its own job document (surface object, CAM job, ball-end tool bit and
  finishing op) as ``job-<series>.FCStd`` in ``$BSPLINECAM_MIGRATION_DIR`` (default
  build/migration);
- every version opens the documents of the *older* series found there, recomputes them, and
  checks what a user relies on: the surface has the design's poles and knots, the tool bit is
  still a ball end of the same size with the same feeds, the op recomputes to the program the
  older version computed (saved beside it as text), the program posts and passes rs274.
In 0.20 (the oldest) there is nothing older to open: that test skips, saying so.
"""

from __future__ import annotations

import json
import os
import tempfile
import unittest
from pathlib import Path

import numpy as np
from bsplinecam_freecad import CASE_STUDY, ROOT, TOOL, FreeCAD

from BSplineCAM import Surface
from BSplineCAM.app import cam, compat, pipeline
from BSplineCAM.core.program import rs274
from BSplineCAM.core.program.gcode import read_gcode

CUTTING = cam.Cutting(horizontal_feed=1100.0, vertical_feed=350.0, spindle_speed=11000.0)
PARAMS = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.08, strategy="raster", angle=30.0)


def exchange_dir() -> Path:
    return Path(os.environ.get("BSPLINECAM_MIGRATION_DIR", str(ROOT / "build" / "migration")))


def series() -> str:
    return compat.cam_series()


def commands(op) -> list:
    """The op's path as [name, {axis: value}] (JSON-friendly, compared to 1e-6 mm)."""
    return [[c.Name, {k: float(v) for k, v in c.Parameters.items()}] for c in op.Path.Commands]


def max_difference(a: list, b: list) -> float:
    """Largest difference of a parameter between two paths of the same commands (inf if the
    commands or their words differ)."""
    if len(a) != len(b):
        return float("inf")
    worst = 0.0
    for (name_a, par_a), (name_b, par_b) in zip(a, b):
        if name_a != name_b or sorted(par_a) != sorted(par_b):
            return float("inf")
        for key, value in par_a.items():
            worst = max(worst, abs(value - par_b[key]))
    return worst


def find_one(doc, predicate, what: str):
    found = [o for o in doc.Objects if predicate(o)]
    if len(found) != 1:
        raise AssertionError(f"{doc.FileName}: expected one {what}, found {[o.Label for o in found]}")
    return found[0]


class TestSaveForNewer(unittest.TestCase):
    def test_save_job_document(self):
        """This version's job, saved for the newer versions to open (with what it computed)."""
        folder = exchange_dir()
        folder.mkdir(parents=True, exist_ok=True)
        doc = FreeCAD.newDocument("MigrationJob")
        try:
            surface = Surface.from_json(CASE_STUDY)
            model, job, op = pipeline.build_job(surface, PARAMS, CUTTING, doc)
            doc.recompute()
            self.assertGreater(len(op.Path.Commands), 100)
            target = folder / f"job-{series()}.FCStd"
            doc.saveAs(str(target))
            facts = {"freecad": ".".join(map(str, compat.freecad_version())), "model": model.Name,
                     "job": job.Name, "op": op.Name, "commands": commands(op)}
            (folder / f"job-{series()}.json").write_text(json.dumps(facts))
            self.assertTrue(target.is_file() and target.stat().st_size > 1000)
        finally:
            FreeCAD.closeDocument(doc.Name)


class TestOpenOlder(unittest.TestCase):
    def older_documents(self) -> list[Path]:
        mine = compat.SERIES.index(series())
        found = [exchange_dir() / f"job-{s}.FCStd" for s in compat.SERIES[:mine]]
        return [p for p in found if p.is_file() and p.with_suffix(".json").is_file()]

    def test_older_documents_open_and_recompute(self):
        older = self.older_documents()
        if series() == compat.SERIES[0]:
            self.skipTest(f"FreeCAD {series()} is the oldest supported series: nothing older to open")
        if not older:
            self.skipTest(f"no older job documents in {exchange_dir()}: tools/test.sh makes them "
                          "(run the older FreeCADs' suites first)")
        design = Surface.from_json(CASE_STUDY)
        for path in older:
            with self.subTest(saved_by=path.stem):
                self.check_document(path, design)

    def check_document(self, path: Path, design: Surface) -> None:
        # what the addon's Init.py does at FreeCAD start-up (here the addon may not be installed)
        compat.install_legacy_cam_modules()
        facts = json.loads(path.with_suffix(".json").read_text())
        with tempfile.TemporaryDirectory() as tmp:
            copy = Path(tmp) / path.name  # never write over the older version's file
            copy.write_bytes(path.read_bytes())
            doc = FreeCAD.openDocument(str(copy))
            try:
                FreeCAD.setActiveDocument(doc.Name)
                model = doc.getObject(facts["model"])
                job = doc.getObject(facts["job"])
                op = doc.getObject(facts["op"])
                self.assertIsNotNone(model, facts)
                self.assertIsNotNone(job, facts)
                self.assertIsNotNone(op, facts)
                # every object got its behaviour back: no proxy lost to a moved module
                lost = [o.Label for o in doc.Objects
                        if o.TypeId.endswith("Python") and getattr(o, "Proxy", None) is None]
                self.assertEqual(lost, [], "objects whose Python class did not restore")
                self.assertEqual(type(job.Proxy).__name__, "ObjectJob")
                # the surface: recomputed from its properties, the design's poles and knots
                model.touch()
                doc.recompute()
                faces = [f for f in model.Shape.Faces if f.Surface.TypeId == "Part::GeomBSplineSurface"]
                self.assertEqual(len(faces), 1, [f.Surface.TypeId for f in model.Shape.Faces])
                poles = np.array([[tuple(p) for p in row] for row in faces[0].Surface.getPoles()])
                np.testing.assert_allclose(poles, design.control_points, atol=1e-9)
                # the tool: still a ball end of the same size, with the same feeds and speed
                tc = find_one(doc, lambda o: hasattr(o, "ToolNumber") and hasattr(o, "Tool"),
                              "tool controller")
                self.assertIn("ball", compat.tool_shape_name(tc.Tool).lower())
                self.assertAlmostEqual(float(tc.Tool.Diameter), TOOL)
                self.assertAlmostEqual(tc.HorizFeed.getValueAs("mm/min").Value, CUTTING.horizontal_feed)
                self.assertAlmostEqual(tc.VertFeed.getValueAs("mm/min").Value, CUTTING.vertical_feed)
                self.assertAlmostEqual(float(tc.SpindleSpeed), CUTTING.spindle_speed)
                # the op: recomputed here, the same program as the older version computed
                op.touch()
                doc.recompute()
                bad = [o.Label for o in doc.Objects if "Invalid" in o.State or "Error" in o.State]
                self.assertEqual(bad, [], "objects in error after recompute")
                self.assertEqual(op.Strategy, PARAMS.strategy)
                self.assertAlmostEqual(op.Angle.Value, PARAMS.angle)
                # the same program up to the last bits of float arithmetic (each FreeCAD has its
                # own numpy: 1.24, 2.2, 2.4), far below the 0.1 µm that the posts write
                self.assertLess(max_difference(commands(op), facts["commands"]), 1e-6)
                # and it posts, and a controller takes it
                program = Path(tmp) / "migrated.ngc"
                text = cam.post_process(job, "linuxcnc", program)
                self.assertGreater(len(read_gcode(text).kind), 100)
                if rs274.available():
                    check = rs274.check(program, {1: TOOL})
                    self.assertTrue(check.ok, check.message)
                else:
                    self.assertNotEqual(os.environ.get("BSPLINECAM_REQUIRE_ALL"), "1",
                                        "rs274 (linuxcnc-uspace) is required here")
            finally:
                FreeCAD.closeDocument(doc.Name)


if __name__ == "__main__":
    unittest.main()
