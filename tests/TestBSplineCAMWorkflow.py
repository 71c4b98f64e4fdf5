# SPDX-License-Identifier: LGPL-2.1-or-later
"""The job workflow a user lives in (issue 13): reopen, heights from the surface, first moves.

unittest classes run by ``freecadcmd`` (``tools/run_freecad_tests.sh TestBSplineCAMWorkflow``)
in FreeCAD 0.20, 1.0 and 1.1:

* a job with its op, simulated part and cross-check is saved, closed and loaded again (every
  proxy is then a fresh object made from the file), FreeCAD's console must show no error while
  it loads, and every app-level operation must work on it before anything is touched;
* heights, depths and stock follow the exact surface after a control point is raised (checked
  against the maximum of a dense grid of the core's evaluation) and do not move when the
  shape is meshed (as the 3D view does);
* every posted program (every post, every strategy, and every op after a tool change) first
  rises alone to the clearance height, checked on the G-code text.
"""

from __future__ import annotations

import json
import os
import re
import sys
import tempfile
import unittest
from pathlib import Path

import numpy as np
from bsplinecam_freecad import CASE_STUDY, ROUNDING, TOOL, FreeCAD

from BSplineCAM import Surface
from BSplineCAM.app import cam, compat, finishing_op, pipeline, surface_feature
from BSplineCAM.app import verify_feature as vf
from BSplineCAM.core.program import rs274


def hill() -> Surface:
    """A 60 x 60 mm net, flat at z = 10 mm with one interior control point raised to 40 mm:
    the surface's top stays far below that pole (OCCT's box of the face reaches it)."""
    x, y = np.meshgrid(np.linspace(0, 60, 7), np.linspace(0, 60, 7), indexing="ij")
    z = np.full_like(x, 10.0)
    z[3, 3] = 40.0
    return Surface(np.stack([x, y, z], axis=-1), "clamped", "hill")


def dense_z(surface: Surface, n: int = 401) -> tuple[float, float]:
    """(min z, max z) of an n x n grid of the core's evaluation: the independent reference."""
    g = np.linspace(0.0, 1.0, n)
    z = surface.evaluate_grid(g, g)[..., 2]
    return float(z.min()), float(z.max())


class ConsoleErrors:
    """What FreeCAD's console reports as errors while the context is open.

    With a Python console observer (``FreeCAD.Console.AddObserver``, where the FreeCAD has it)
    its error lines; otherwise the text the command-line console writes to the stderr file
    descriptor (errors and warnings; messages go to stdout), read for error marks.
    """

    #: What an error line written to stderr carries (FreeCAD's report of a Python exception
    #: reads like "<string>(16)<class 'AttributeError'>: setAttr failed.").
    ERROR_MARKS = re.compile(r"error|exception|traceback|failed|<class '", re.IGNORECASE)

    def __init__(self) -> None:
        self.errors: list[str] = []
        self._observer = hasattr(FreeCAD.Console, "AddObserver")

    def OnError(self, text):  # noqa: N802 - FreeCAD API
        self.errors.append(str(text))

    def OnWarning(self, text):  # noqa: N802 - FreeCAD API
        return None

    def OnMessage(self, text):  # noqa: N802 - FreeCAD API
        return None

    def OnLog(self, text):  # noqa: N802 - FreeCAD API
        return None

    def __enter__(self):
        if self._observer:
            FreeCAD.Console.AddObserver(self)
            return self
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc) -> None:
        if self._observer:
            FreeCAD.Console.RemoveObserver(self)
            return
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        text = self._file.read().decode("utf-8", "replace")
        self._file.close()
        sys.stderr.write(text)
        for line in re.split(r"[\r\n]+", text):
            if self.ERROR_MARKS.search(line):
                self.errors.append(line)


# --- the G-code text, read independently of the code under test ------------------------------
_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_NON_MOTION_G = {4, 10, 28, 30, 53, 92}


def motions(text: str, labels: tuple[str, ...] = ()) -> list[tuple[int, str, dict]]:
    """(line number, "rapid"/"feed"/"arc", axis words) of every motion line in program order
    (modal G0/G1 carried over as a controller does), and (line number, "op", {}) for each
    comment line that names one of ``labels`` (an op's start: FreeCAD puts its label first)."""
    out: list[tuple[int, str, dict]] = []
    wanted = {label.upper() for label in labels}
    mode = None
    for number, raw in enumerate(text.splitlines(), start=1):
        upper = raw.upper()
        comments = [c.strip() for c in re.findall(r"\(([^)]*)\)", upper)]
        if wanted & set(comments):
            out.append((number, "op", {}))
        line = re.sub(r"\([^)]*\)", "", upper).split(";")[0]
        words = [(letter, float(value)) for letter, value in _WORD.findall(line)]
        gs = {int(v) for letter, v in words if letter == "G"}
        for g in gs & {0, 1, 2, 3}:
            mode = g
        axes = {letter: v for letter, v in words if letter in "XYZ"}
        if axes and not gs & _NON_MOTION_G and mode is not None:
            out.append((number, {0: "rapid", 1: "feed"}.get(mode, "arc"), axes))
    return out


class FirstMoves:
    def assert_rises_alone_first(self, text: str, ops: list, label: str) -> None:
        """The program's first motion, and the first motion of every op (of ``ops``), is
        ``G0 Z<that op's clearance>`` alone, the next a rapid in X and Y at that height."""
        moves = motions(text, tuple(op.Label for op in ops))
        clearances = [op.ClearanceHeight.Value for op in ops]
        starts = [k for k, m in enumerate(moves) if m[1] == "op"]
        self.assertEqual(len(starts), len(ops), f"{label}: op labels in the program")
        first_motion = next(k for k, m in enumerate(moves) if m[1] != "op")
        for s in sorted({first_motion - 1, *starts}):
            rest = [m for m in moves[s + 1:] if m[1] != "op"]
            (line, kind, axes), (line2, kind2, axes2) = rest[0], rest[1]
            self.assertEqual(kind, "rapid", f"{label}: line {line}")
            self.assertEqual(set(axes), {"Z"}, f"{label}: line {line} is not a lone Z rise")
            self.assertTrue(any(abs(axes["Z"] - c) <= ROUNDING for c in clearances),
                            f"{label}: line {line} rises to {axes['Z']}, not to {clearances}")
            self.assertEqual(kind2, "rapid", f"{label}: line {line2}")
            self.assertTrue({"X", "Y"} <= set(axes2), f"{label}: line {line2}")
            self.assertLessEqual(abs(axes2.get("Z", axes["Z"]) - axes["Z"]), ROUNDING,
                                 f"{label}: line {line2} moves in Z with X and Y")


class TestReopenedJob(unittest.TestCase):
    """Make job + op + simulated part + cross-check, save, close, load again, use it all."""

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        doc = FreeCAD.newDocument("TestBSplineCAMWorkflow")
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.1)
        model, job, op = pipeline.build_job(Surface.from_json(CASE_STUDY), params, cam.Cutting(), doc)
        doc.recompute()
        vf.verify_job(job, cell=1.0)
        surface_feature.run_crosscheck(model)
        cls.names = {"model": model.Name, "job": job.Name, "op": op.Name}
        cls.commands = [c.toGCode() for c in op.Path.Commands]
        cls.heights = {p: getattr(op, p).Value for p in
                       ("ClearanceHeight", "SafeHeight", "StartDepth", "FinalDepth")}
        cls.path = str(Path(cls.tmp.name) / "workflow.FCStd")
        doc.saveAs(cls.path)
        FreeCAD.closeDocument(doc.Name)
        with ConsoleErrors() as console:
            cls.doc = FreeCAD.openDocument(cls.path)
        cls.console = console

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def obj(self, key: str):
        return self.doc.getObject(self.names[key])

    def test_console_observer_sees_errors(self):
        """The observer the reopen is checked with does catch an error line."""
        with ConsoleErrors() as console:
            FreeCAD.Console.PrintError("TestBSplineCAMWorkflow: expected error line\n")
        self.assertEqual(len(console.errors), 1)

    def test_open_shows_no_error(self):
        self.assertEqual(self.console.errors, [])

    def test_every_proxy_is_rebuilt(self):
        for obj in self.doc.Objects:
            if "Proxy" in obj.PropertiesList:
                with self.subTest(obj=obj.Name):
                    self.assertIsNotNone(obj.Proxy)
        job = self.obj("job")
        self.assertEqual(type(job.Stock.Proxy).__name__, "SurfaceStock")
        self.assertIsInstance(self.obj("op").Proxy, finishing_op.ObjectSurfaceFinish)
        self.assertTrue(surface_feature.is_surface(self.obj("model")))
        self.assertGreaterEqual(len([o for o in self.doc.Objects if vf.is_verification(o)]), 1)

    def test_every_operation_on_the_reopened_job(self):
        """In the order a user would: verify (before anything is recomputed), post with every
        post, cross-check, recompute the op; all as before saving."""
        job, op, model = self.obj("job"), self.obj("op"), self.obj("model")
        self.assertIs(vf.job_of(op), job)
        result = vf.verify_job(job, cell=1.0)
        metrics = json.loads(result.Metrics)
        self.assertLess(metrics["gouge_max_mm"], 1e-3 + 2 * ROUNDING)
        # one cutting length: the op's (its Path's feeds) and Verify's (the posted text's feeds)
        report = json.loads(op.Report)
        self.assertAlmostEqual(report["cutting_length_mm"], metrics["cutting_length_mm"],
                               delta=1e-6 * metrics["cutting_length_mm"] + 0.01)
        for post in compat.POST_PROCESSORS:
            with self.subTest(post=post):
                path = Path(self.tmp.name) / f"{post}.ngc"
                text = cam.post_process(job, post, path)
                self.assertIn("M6", text.replace(" ", "").upper())
                if rs274.available():
                    check = rs274.check(path, {1: TOOL})
                    self.assertTrue(check.ok, f"{post}: {check.message}")
        self.assertEqual(job.PostProcessor, compat.POST_PROCESSORS[-1])
        report = surface_feature.run_crosscheck(model)
        self.assertTrue(report["exact_route_ok"], report)
        op.touch()
        self.doc.recompute()
        self.assertTrue(op.isValid(), op.getStatusString())
        self.assertEqual([c.toGCode() for c in op.Path.Commands], self.commands)
        for name, value in self.heights.items():
            self.assertAlmostEqual(getattr(op, name).Value, value, places=9, msg=name)


class TestHeightsFollowTheSurface(unittest.TestCase, FirstMoves):
    """Stock, depths and heights from the exact surface, after an edit and in every recompute."""

    def setUp(self):
        self.doc = FreeCAD.newDocument("TestBSplineCAMHeights")
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.2, tolerance=0.01)
        self.model, self.job, self.op = pipeline.build_job(hill(), params, cam.Cutting(), self.doc)
        self.doc.recompute()

    def tearDown(self):
        FreeCAD.closeDocument(self.doc.Name)

    def heights(self) -> dict:
        op, stock = self.op, self.job.Stock
        return {"clearance": op.ClearanceHeight.Value, "safe": op.SafeHeight.Value,
                "start": op.StartDepth.Value, "final": op.FinalDepth.Value,
                "stock_top": stock.Shape.BoundBox.ZMax, "stock_bottom": stock.Shape.BoundBox.ZMin,
                "stock_x": (stock.Shape.BoundBox.XMin, stock.Shape.BoundBox.XMax)}

    def assert_follow(self, surface: Surface) -> dict:
        low, high = dense_z(surface)
        h = self.heights()
        stock, sheet = self.job.Stock, self.job.SetupSheet
        top = high + stock.ExtZpos.Value
        self.assertLess(abs(h["stock_top"] - top), 1e-3, h)
        self.assertGreaterEqual(h["stock_top"], top - 1e-9, "stock below the surface's top")
        self.assertLess(abs(h["final"] - low), 1e-3, h)
        self.assertLess(abs(h["start"] - h["stock_top"]), 1e-9, h)
        self.assertAlmostEqual(h["clearance"], h["stock_top"] + sheet.ClearanceHeightOffset.Value, 9)
        self.assertAlmostEqual(h["safe"], h["stock_top"] + sheet.SafeHeightOffset.Value, 9)
        base = low - self.model.BaseOffset.Value - stock.ExtZneg.Value
        self.assertLess(abs(h["stock_bottom"] - base), 1e-3, h)
        self.assertAlmostEqual(h["stock_x"][0], -stock.ExtXneg.Value, 6)
        self.assertAlmostEqual(h["stock_x"][1], 60.0 + stock.ExtXpos.Value, 6)
        return h

    def test_heights_from_the_surface_not_its_poles(self):
        h = self.assert_follow(hill())
        pole_top = float(hill().control_points[..., 2].max())
        self.assertLess(h["stock_top"], pole_top - 10.0)

    def test_raising_a_control_point_moves_them(self):
        before = self.heights()
        surface_feature.set_control_point(self.model, 3, 3, (30.0, 30.0, 60.0))
        self.doc.recompute()
        surface = surface_feature.surface_of(self.model)
        h = self.assert_follow(surface)
        self.assertGreater(h["stock_top"], before["stock_top"] + 1.0)
        # the program: lone rise to clearance, rapid down to the safe height, then feed
        text = cam.post_process(self.job, "linuxcnc", remember=False)
        self.assert_rises_alone_first(text, [self.op], "after the edit")
        moves = motions(text)
        above, descent, plunge = moves[1], moves[2], moves[3]
        self.assertEqual(descent[1], "rapid")
        for axis in "XY":
            self.assertAlmostEqual(descent[2].get(axis, above[2][axis]), above[2][axis],
                                   delta=ROUNDING)
        self.assertAlmostEqual(descent[2]["Z"], h["safe"], delta=ROUNDING)
        self.assertEqual(plunge[1], "feed")
        self.assertLess(plunge[2]["Z"], h["safe"])

    def test_same_values_on_every_recompute_and_after_meshing(self):
        first = self.heights()
        for _ in range(2):
            self.model.Shape.tessellate(0.05)  # what the 3D view does to the shape
            self.op.touch()
            self.job.Stock.touch()
            self.doc.recompute()
            self.assertEqual(self.heights(), first)


class TestFirstMove(unittest.TestCase, FirstMoves):
    """Every post, every strategy, and the op after a second tool change."""

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMFirstMove")
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=0.2, tolerance=0.01)
        _, cls.job, cls.op = pipeline.build_job(hill(), params, cam.Cutting(), cls.doc)
        cls.doc.recompute()

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)

    def test_every_post_and_strategy(self):
        for strategy in finishing_op.STRATEGIES:
            self.op.Strategy = strategy
            self.doc.recompute()
            self.assertTrue(self.op.Path.Commands, strategy)
            for post in compat.POST_PROCESSORS:
                with self.subTest(strategy=strategy, post=post):
                    text = cam.post_process(self.job, post, remember=False)
                    self.assert_rises_alone_first(text, [self.op], f"{strategy}/{post}")

    def test_op_after_a_tool_change(self):
        tc = cam.make_ballend_controller(4.0, number=2, doc=self.doc)
        self.job.Tools.addObject(tc)
        op2 = finishing_op.Create("SurfaceFinish2", parentJob=self.job)
        op2.ToolController = tc
        op2.Strategy = "isoparametric"
        op2.ScallopHeight = 0.2
        op2.Tolerance = 0.01
        try:
            self.doc.recompute()
            for post in compat.POST_PROCESSORS:
                with self.subTest(post=post):
                    text = cam.post_process(self.job, post, remember=False)
                    self.assertIn("T2", text.replace(" ", "").upper(), post)
                    self.assert_rises_alone_first(text, [self.op, op2], post)
        finally:
            self.job.Operations.removeObject(op2)
            self.doc.removeObject(op2.Name)
            self.job.Tools.removeObject(tc)


if __name__ == "__main__":
    unittest.main()
