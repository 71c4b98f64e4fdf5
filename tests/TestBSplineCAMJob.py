# SPDX-License-Identifier: LGPL-2.1-or-later
"""The Path/CAM job inside FreeCAD (0.20 and 1.0): op, heights, feeds, posts, rs274, simulation.

unittest classes run by ``freecadcmd`` (tools/run_freecad_tests.sh).  Every program is checked
by LinuxCNC's rs274 and simulated from its *text* against the exact design surface.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path
from unittest import mock

import numpy as np
from bsplinecam_freecad import CASE_STUDY, ROOT, ROUNDING, TOOL, FreeCAD, rs274_or_skip

from BSplineCAM import Surface
from BSplineCAM.app import cam, compat, pipeline
from BSplineCAM.core.program import rs274
from BSplineCAM.core.program.gcode import MoveKind, read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify


def case_study() -> Surface:
    return Surface.from_json(CASE_STUDY)


def steep_dome() -> Surface:
    """A 60 x 60 mm net with a dome whose walls reach about 60°: work for waterline passes."""
    x, y = np.meshgrid(np.linspace(0, 60, 9), np.linspace(0, 60, 9), indexing="ij")
    z = 10 + 40 * np.exp(-((x - 30) ** 2 + (y - 30) ** 2) / 180)
    return Surface(np.stack([x, y, z], axis=-1), "clamped", "dome")


class JobFixture(unittest.TestCase):
    """One document with the case study, a job and an op; programs posted per test."""

    params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.05, strategy="raster")

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMJob")
        cls.model, cls.job, cls.op = pipeline.build_job(case_study(), cls.params, cam.Cutting(), cls.doc)
        cls.doc.recompute()
        cls.tmp = tempfile.TemporaryDirectory()

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def post(self, post: str = "linuxcnc") -> tuple[str, Path]:
        path = Path(self.tmp.name) / f"{post}.ngc"
        return cam.post_process(self.job, post, path), path


class TestJob(JobFixture):
    def test_job_holds_model_ballend_and_feeds(self):
        self.assertEqual(len(self.job.Model.Group), 1)
        tcs = self.job.Tools.Group
        self.assertEqual(len(tcs), 1)
        tc = tcs[0]
        self.assertIn("ball", compat.tool_shape_name(tc.Tool).lower())
        # nothing left over from the default tool controller CAM makes (1.1's bit body included)
        loose = [o.Label for o in self.doc.Objects if not o.InList and o not in (self.job, self.model)]
        self.assertEqual(loose, [])
        self.assertFalse([o.Label for o in self.doc.Objects if "Endmill" in o.Label])
        self.assertAlmostEqual(float(tc.Tool.Diameter), TOOL)
        self.assertGreater(tc.HorizFeed.Value, 0)
        self.assertGreater(tc.VertFeed.Value, 0)
        self.assertGreater(float(tc.SpindleSpeed), 0)
        self.assertIs(self.op.ToolController, tc)
        self.assertIn(self.op, self.job.Operations.Group)

    def test_op_report_and_heights(self):
        report = json.loads(self.op.Report)
        self.assertEqual(report["strategy"], "raster")
        self.assertGreater(report["passes"], 10)
        # the machine figures: air beyond the rapids (plunges, links), acceleration's cost
        self.assertGreaterEqual(report["air_length_mm"], report["rapid_length_mm"])
        self.assertGreater(report["link_length_mm"], 0.0)
        self.assertGreater(report["machining_time_s"], 0.0)
        self.assertGreater(report["machining_time_with_acceleration_s"],
                           report["machining_time_s"])
        stock_top = self.job.Stock.Shape.BoundBox.ZMax
        self.assertGreater(self.op.SafeHeight.Value, stock_top)
        self.assertGreater(self.op.ClearanceHeight.Value, self.op.SafeHeight.Value)

    def test_rapids_stay_above_clearance_or_descend_to_safe_height(self):
        text, _ = self.post()
        program = read_gcode(text)
        clearance = self.op.ClearanceHeight.Value
        safe = self.op.SafeHeight.Value
        rapid = np.flatnonzero(program.kind == MoveKind.RAPID)
        self.assertGreater(len(rapid), 0)
        for i in rapid:
            start, end = program.start[i], program.end[i]
            lateral = np.hypot(*(end[:2] - start[:2]))
            if lateral > ROUNDING:
                self.assertGreaterEqual(min(start[2], end[2]), clearance - ROUNDING, f"lateral rapid at line {program.line[i]}")
            else:
                self.assertGreaterEqual(end[2], safe - ROUNDING, f"rapid descent below safe height at line {program.line[i]}")
        feeds = program.feed[program.kind != MoveKind.RAPID]
        self.assertTrue(np.all(feeds > 0))
        self.assertIn("S12000", text.replace(" ", ""))
        self.assertRegex(text, r"M6\s*T1")

    def test_every_post_passes_rs274(self):
        rs274_or_skip(self)
        for post in compat.POST_PROCESSORS:
            with self.subTest(post=post):
                text, path = self.post(post)
                check = rs274.check(path, {1: TOOL})
                self.assertTrue(check.ok, f"{post}: {check.message}")
                self.assertGreater(check.feeds, 100)
                moves = read_gcode(text)
                self.assertEqual(int(np.sum(moves.kind == MoveKind.LINE)), check.feeds, post)
                # the op fits arcs (G18 along X): every post writes them, rs274 counts them
                self.assertGreater(check.arcs, 100, post)
                self.assertEqual(int(np.sum(moves.kind >= MoveKind.ARC_CW)), check.arcs, post)

    def test_post_processor_is_the_users_choice(self):
        """The job's PostProcessor (what CAM's own post command runs) is the post chosen."""
        self.assertEqual(self.job.PostProcessor, "linuxcnc")
        try:
            self.post("grbl")
            self.assertEqual(self.job.PostProcessor, "grbl")
            cam.post_process(self.job, "fanuc", remember=False)
            self.assertEqual(self.job.PostProcessor, "grbl")
        finally:
            cam.set_post_processor(self.job, "linuxcnc")

    def test_one_cutting_length(self):
        """The op's cutting length is the feed length of the posted program's text."""
        text, _ = self.post()
        program = read_gcode(text)
        feeds = program.kind != MoveKind.RAPID
        measured = float(program.lengths()[feeds].sum())
        report = json.loads(self.op.Report)
        self.assertAlmostEqual(report["cutting_length_mm"], measured, delta=1e-6 * measured + 0.01)
        self.assertLess(report["pass_length_mm"], report["cutting_length_mm"])

    def test_unknown_post_is_named(self):
        with self.assertRaisesRegex(ValueError, "unknown post-processor 'nosuch'.*linuxcnc"):
            cam.post_process(self.job, "nosuch")

    def test_faces_apply_to_parts_only(self):
        """pipeline.machine takes ``faces`` on part files only: on a control net it refuses
        them before any document is made or program written."""
        path = Path(self.tmp.name) / "faces.ngc"
        documents = set(FreeCAD.listDocuments())
        with self.assertRaisesRegex(ValueError, "faces .*part files"):
            pipeline.machine(case_study(), self.params, path, faces=[1])
        self.assertFalse(path.exists())
        self.assertEqual(set(FreeCAD.listDocuments()), documents)

    def test_job_saves_and_reopens(self):
        path = Path(self.tmp.name) / "job.FCStd"
        self.doc.saveCopy(str(path))
        before = [c.toGCode() for c in self.op.Path.Commands]
        doc = FreeCAD.openDocument(str(path))
        try:
            op = doc.getObject(self.op.Name)
            op.touch()
            doc.recompute()
            self.assertEqual(op.Version, "1")
            self.assertEqual([c.toGCode() for c in op.Path.Commands], before)
        finally:
            FreeCAD.closeDocument(doc.Name)
            FreeCAD.setActiveDocument(self.doc.Name)


class TestMachinedPart(unittest.TestCase):
    """Simulate the posted G-code of each strategy and measure it against the design."""

    def machine(self, strategy: str, scallop: float, surface: Surface | None = None, **extra):
        """Post ``strategy`` with linuxcnc, check it with rs274, simulate the text; return
        (op report, verification)."""
        surface = surface or case_study()
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=scallop, strategy=strategy, **extra)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "p.ngc"
            report = pipeline.machine(surface, params, path)
            if rs274.available():
                check = rs274.check(path, {1: TOOL})
                self.assertTrue(check.ok, check.message)
            program = read_gcode(path.read_text())
        return report, verify(surface, program, Tool(TOOL), cell=0.1)

    def assert_machined(self, metrics: dict, scallop: float, tolerance: float = 0.002):
        self.assertEqual(metrics["rapid_collisions"], [])
        self.assertLessEqual(metrics["gouge_max_mm"], 1e-3 + 2 * ROUNDING, metrics)
        self.assertLessEqual(metrics["scallop_max_mm"], scallop + tolerance, metrics)
        self.assertGreaterEqual(metrics["coverage"], 0.99, metrics)

    def test_raster(self):
        report, result = self.machine("raster", 0.02, angle=30.0)
        self.assert_machined(result.metrics, 0.02)
        self.assertGreater(report["passes"], 20)

    def test_waterline_finishes_steep_walls(self):
        """On a steep dome, constant-Z passes finish walls steeper than 40° (flatter areas are a
        raster pass's job) to the scallop plus the chordal tolerance, measured vertically."""
        scallop, tolerance = 0.02, 0.002
        _, result = self.machine("waterline", scallop, surface=steep_dome())
        metrics = result.metrics
        self.assertEqual(metrics["rapid_collisions"], [])
        self.assertLessEqual(metrics["gouge_max_mm"], 1e-3 + 2 * ROUNDING, metrics)
        cell = metrics["cell_mm"]
        gy, gx = np.gradient(result.design, cell)
        steep = result.inner & (np.degrees(np.arctan(np.hypot(gx, gy))) >= 40.0)
        self.assertGreater(int(steep.sum()), 1000)
        self.assertLessEqual(float(np.nanmax(result.deviation[steep])), scallop + tolerance)

    def test_isoparametric(self):
        _, result = self.machine("isoparametric", 0.02)
        self.assert_machined(result.metrics, 0.02)


class TestBadInput(unittest.TestCase):
    def run_cli(self, *args) -> tuple[int, str, list]:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out"
            proc = subprocess.run([str(ROOT / "bin" / "bsplinecam"), "toolpath", str(CASE_STUDY), "--out", str(out), *args],
                                  capture_output=True, text=True, check=False, env={**os.environ})
            files = sorted(p.name for p in out.iterdir()) if out.exists() else []
        return proc.returncode, proc.stderr, files

    def test_bad_parameters_write_nothing(self):
        cases = [
            (["--tool-diameter", "0", "--scallop", "0.01"], "tool[_-]diameter"),
            (["--tool-diameter", "-6", "--scallop", "0.01"], "tool[_-]diameter"),
            (["--tool-diameter", "6", "--scallop", "0"], "scallop"),
            (["--tool-diameter", "6", "--scallop", "4"], "scallop"),
            (["--tool-diameter", "6", "--scallop", "0.01", "--tolerance", "5"], "tolerance"),
            (["--tool-diameter", "6", "--scallop", "0.01", "--post", "nosuch"], "nosuch"),
            (["--tool-diameter", "6", "--scallop", "0.01", "--feed", "0"], "feed"),
        ]
        for args, word in cases:
            with self.subTest(args=args):
                code, err, files = self.run_cli(*args)
                self.assertEqual(code, 2, err)
                self.assertRegex(err, word)
                self.assertNotIn("Traceback", err.split("bsplinecam toolpath: error")[-1])
                self.assertEqual(files, [])

    def test_making_an_op_is_quiet(self):
        """No "SetupSheet has no support for SurfaceFinish" (the op is registered with it)."""
        doc = FreeCAD.newDocument("TestBSplineCAMJobQuiet")
        sys.stdout.flush()
        sys.stderr.flush()
        saved = os.dup(1), os.dup(2)
        with tempfile.TemporaryFile() as log:
            os.dup2(log.fileno(), 1)
            os.dup2(log.fileno(), 2)
            try:
                pipeline.build_job(case_study(), pipeline.FinishingParameters(TOOL, 0.05),
                                   cam.Cutting(), doc)
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
                for fd in saved:
                    os.close(fd)
                FreeCAD.closeDocument(doc.Name)
            log.seek(0)
            text = log.read().decode("utf-8", "replace")
        self.assertNotIn("has no support", text)

    def test_op_refuses_feeds_and_spindle_out_of_range(self):
        """The op applies the command line's ranges: an infinite or absurd value is named."""
        doc = FreeCAD.newDocument("TestBSplineCAMJobBadFeeds")
        try:
            params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.05)
            _, job, op = pipeline.build_job(case_study(), params, cam.Cutting(), doc)
            doc.recompute()
            good = op.Path.toGCode()
            tc = op.ToolController
            for prop, value, word in (("SpindleSpeed", float("inf"), "SpindleSpeed"),
                                      ("SpindleSpeed", 1e9, "SpindleSpeed"),
                                      ("HorizFeed", 1e-6, "HorizFeed")):
                with self.subTest(prop=prop, value=value):
                    saved = getattr(tc, prop)
                    setattr(tc, prop, value)
                    op.touch()
                    doc.recompute()
                    self.assertIn(word, json.loads(op.Report).get("error", ""))
                    self.assertIn("rpm" if prop == "SpindleSpeed" else "mm/min",
                                  json.loads(op.Report)["error"])
                    setattr(tc, prop, saved)
            op.touch()
            doc.recompute()
            self.assertEqual(op.Path.toGCode(), good)
        finally:
            FreeCAD.closeDocument(doc.Name)

    def test_job_without_model(self):
        with self.assertRaisesRegex(ValueError, "needs a model"):
            cam.make_job(None, TOOL)

    def test_freecad_without_cam_is_named(self):
        """A FreeCAD built without its CAM workbench: one message saying what to install."""
        name = compat._pick(compat._CAM_MODULES["surface_op"])
        with mock.patch.dict(sys.modules, {name: None}), \
                self.assertRaisesRegex(ImportError, r"has no CAM \(Path\) workbench.*apt-get install freecad"):
            compat.cam_module("surface_op")


if __name__ == "__main__":
    unittest.main()
