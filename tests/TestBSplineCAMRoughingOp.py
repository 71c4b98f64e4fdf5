# SPDX-License-Identifier: LGPL-2.1-or-later
"""Block to part inside FreeCAD (0.20, 1.0, 1.1): the roughing op before the finishing op.

unittest classes run by ``freecadcmd`` (tools/run_freecad_tests.sh).  The job's program, posted
by every post, is checked by LinuxCNC's rs274 and simulated from its *text*, from the job's
stock block, with both tools (core.verify.verify_job), against the exact design surface.
"""

from __future__ import annotations

import json
import sys
import tempfile
import unittest
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.app import cam, compat, pipeline  # noqa: E402
from BSplineCAM.core.program import rs274  # noqa: E402
from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify_job  # noqa: E402

FreeCAD = compat.ensure_freecad()
ROUGH = pipeline.RoughingParameters(shape="flat", diameter=8.0, stepdown=2.0,
                                    stepover_percent=40, radial_allowance=0.3,
                                    axial_allowance=0.3, stock_margin=2.0)
FINISH = pipeline.FinishingParameters(tool_diameter=6.0, scallop=0.05, tolerance=0.01,
                                      arcs=True)
CELL = 0.1


def bump() -> Surface:
    """A 50 x 50 mm net: a bump 9 mm high on a gentle slope (walls up to about 40 deg)."""
    x, y = np.meshgrid(np.linspace(0, 50, 8), np.linspace(0, 50, 8), indexing="ij")
    z = 10 + 0.05 * x + 9 * np.exp(-((x - 25) ** 2 + (y - 25) ** 2) / 120)
    return Surface(np.stack([x, y, z], axis=-1), "clamped", "bump")


class RoughingFixture(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMRoughingOp")
        cls.surface = bump()
        cls.model, cls.job, cls.finish = pipeline.build_job(
            cls.surface, FINISH, cam.Cutting(), cls.doc, roughing=ROUGH)
        cls.doc.recompute()
        cls.rough = cls.job.Operations.Group[0]
        cls.tmp = tempfile.TemporaryDirectory()
        cls.programs = {}

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def program(self, post: str = "linuxcnc") -> Path:
        if post not in self.programs:
            path = Path(self.tmp.name) / f"{post}.ngc"
            cam.post_process(self.job, post, path, remember=False)
            self.programs[post] = path
        return self.programs[post]

    def stock(self) -> tuple:
        b = self.job.Stock.Shape.BoundBox
        return (b.XMin, b.XMax, b.YMin, b.YMax, b.ZMin, b.ZMax)


class TestRoughingJob(RoughingFixture):
    def test_ops_tools_and_stock(self):
        self.assertEqual([o.Name for o in self.job.Operations.Group],
                         [self.rough.Name, self.finish.Name])
        tcs = {int(tc.ToolNumber): compat.core_tool_shape(tc.Tool) for tc in self.job.Tools.Group}
        self.assertEqual(tcs, {1: ("flat", 8.0, 0.0), 2: ("ball", 6.0, 3.0)})
        self.assertIs(self.rough.ToolController.Tool, next(
            tc.Tool for tc in self.job.Tools.Group if int(tc.ToolNumber) == 1))
        x0, x1, y0, y1, z0, z1 = self.stock()
        self.assertAlmostEqual(x0, -2.0, places=6)
        self.assertAlmostEqual(x1, 52.0, places=6)
        self.assertAlmostEqual(y1, 52.0, places=6)
        top = float(np.max(self.surface.grid(101, 101)[..., 2]))
        self.assertAlmostEqual(z1, top + 2.0, delta=0.01)
        for op in (self.rough, self.finish):
            report = json.loads(op.Report)
            self.assertNotIn("error", report, op.Label)
            self.assertTrue(op.Path.Commands, op.Label)
        levels = json.loads(self.rough.Report)["levels"]
        self.assertEqual(levels, sorted(levels, reverse=True))
        entries = json.loads(self.rough.Report)["entries"]
        self.assertEqual(set(entries), {"helical", "outside", "ramp", "lead_in", "zigzag",
                                        "plunge"})
        self.assertEqual((entries["zigzag"], entries["plunge"]), (0, 0))  # no closed pocket
        self.assertGreater(entries["outside"] + entries["helical"], 0)
        self.assertIn("rest", json.loads(self.finish.Report))

    def test_every_post_passes_rs274_with_two_tool_changes(self):
        if not rs274.available():
            self.skipTest("LinuxCNC's rs274 is not installed")
        for post in compat.POST_PROCESSORS:
            with self.subTest(post=post):
                path = self.program(post)
                text = path.read_text()
                program = read_gcode(text, post, require_end=False)
                changes = [t for _, t in program.tool_changes]
                if post == "grbl":  # grbl has no tool changer: the post writes them as comments
                    self.assertEqual(changes, [])
                    self.assertLess(text.index("( M6 T1 )"), text.index("( M6 T2 )"))
                else:  # fanuc's footer unloads the spindle (M6 T0)
                    self.assertEqual(changes[:2], [1, 2], post)
                    self.assertIn(changes[2:], ([], [0]), post)
                check = rs274.check(path, {1: 8.0, 2: 6.0})
                self.assertTrue(check.ok, f"{post}: {check.message}")

    def test_whole_program_from_the_block(self):
        """Simulated from the stock block with both tools: no gouge, no rapid collision, the
        roughing leaves the allowance (never less) and never engages more than the stepover
        by 10 % outside its entries, and the finishing tool never cuts deeper than
        allowance + scallop + rest limit (the rest passes took the terraces)."""
        program = read_gcode(self.program().read_text(), "linuxcnc")
        result = verify_job(self.surface, program, {1: Tool(8.0, "flat"), 2: Tool(6.0)},
                            stock=self.stock(), cell=CELL)
        m = result.metrics
        self.assertLessEqual(m["gouge_max_mm"], 1e-3)
        self.assertEqual(m["rapid_collisions"], [])
        self.assertLessEqual(m["scallop_max_mm"], FINISH.scallop + FINISH.tolerance + 1e-3)
        t1, t2 = m["tools"]["1"], m["tools"]["2"]
        stepover = 0.4 * 8.0
        self.assertLessEqual(t1["radial_engagement_max_mm"], 1.1 * stepover + CELL)
        self.assertLessEqual(t1["axial_engagement_max_mm"], ROUGH.stepdown + 1e-3)
        limit = self.finish.RestLimit.Value
        deepest = ROUGH.axial_allowance + FINISH.scallop + limit
        self.assertLessEqual(t2["axial_engagement_max_mm"], deepest + CELL)
        # the stock after roughing, against the exact design inside the footprint
        after = result.job.snapshots[1]
        design = result.design
        inside = np.isfinite(design)
        left = after[inside] - design[inside]
        # a flat end over a slope leaves at least the allowance (the grid: within a cell's
        # height change on the steepest wall, 0.1 mm * tan 40 deg)
        self.assertGreaterEqual(float(left.min()), min(ROUGH.axial_allowance,
                                                       ROUGH.radial_allowance) - 0.09)
        self.assertLessEqual(float(np.percentile(left, 50)), ROUGH.stepdown + 0.3)

    def test_finishing_hops_over_the_stock_the_roughing_left(self):
        """Retract minimum (a new op's): gaps between the finishing op's passes hop, below
        the clearance height and above the stock the roughing left (the job simulation of the
        roughing: no rapid of the whole program touches the stock, see
        test_whole_program_from_the_block), and the program takes less time than with full
        retracts."""
        report = json.loads(self.finish.Report)
        self.assertEqual(self.finish.Retract, "minimum")
        self.assertGreater(report["retract_hops"], 0)
        clearance = self.finish.ClearanceHeight.Value
        rapids = [c for c in self.finish.Path.Commands if c.Name in ("G0", "G00")
                  and "Z" in c.Parameters]
        low = [c for c in rapids if c.Parameters["Z"] < clearance - 1e-6]
        self.assertGreaterEqual(len(low), report["retract_hops"])
        self.finish.Retract = "full"
        try:
            self.doc.recompute()
            full = json.loads(self.finish.Report)
            self.assertEqual(full["retract_hops"], 0)
            self.assertLess(report["machining_time_with_acceleration_s"],
                            full["machining_time_with_acceleration_s"])
            self.assertLess(report["rapid_length_mm"], full["rapid_length_mm"])
        finally:
            self.finish.Retract = "minimum"
            self.doc.recompute()
            self.programs.clear()

    def test_verify_feature_follows_the_tool_changes(self):
        """The workbench's Verify on a job with roughing: both tools from the stock block, the
        per-tool figures in Metrics and the stock after T1 as a mesh of its own."""
        from BSplineCAM.app import verify_feature

        before = {o.Name for o in self.doc.Objects}
        result = verify_feature.verify_job(self.job, cell=0.25)
        try:
            metrics = json.loads(result.Metrics)
            self.assertEqual(sorted(metrics["tools"]), ["1", "2"])
            self.assertEqual(metrics["tools"]["1"]["tool"]["shape"], "flat")
            self.assertLessEqual(metrics["gouge_max_mm"], 2e-3)
            stages = list(result.StockAfter)
            self.assertEqual(len(stages), 1)
            self.assertEqual(stages[0].Label, "Stock after T1 (flat 8 mm)")
            self.assertEqual(stages[0].Mesh.CountPoints, result.Mesh.CountPoints)
            # the roughed stock lies above the finished part everywhere, by the allowance
            # on average over the part
            top = result.GridRows * result.GridColumns
            rough = np.array([p.z for p in stages[0].Mesh.Points[:top]])
            final = np.array([p.z for p in result.Mesh.Points[:top]])
            self.assertTrue(np.all(rough >= final - 1e-6))
            self.assertGreater(float(np.mean(rough - final)), ROUGH.axial_allowance)
        finally:
            for name in {o.Name for o in self.doc.Objects} - before:
                self.doc.removeObject(name)

    def test_verify_checks_the_ops_load_limits(self):
        """Verify holds each tool to its op's load limits: the job's own (from the roughing's
        step-down and stepover, the ball's stock to take) pass on this honest job; a finishing
        op's MaxAxialEngagement below the stock it is left fails it, naming T2 and lines."""
        from BSplineCAM.app import verify_feature

        self.assertEqual(self.finish.MaxAxialEngagement.Value, 0.0)  # 0: the job's limit
        self.assertFalse(self.rough.CentreCutting)
        before = {o.Name for o in self.doc.Objects}
        try:
            honest = json.loads(verify_feature.verify_job(self.job, cell=0.25).Metrics)["loads"]
            self.assertTrue(honest["ok"], honest)
            limits = honest["limits"]
            self.assertEqual(sorted(limits), ["1", "2"])
            # the ball's depth: the stock planned for it (allowance + scallop + rest limit),
            # or its diameter when larger (the skin of radial stock on a wall's edge), plus
            # the simulation's resolution (a tenth of a cell)
            planned = ROUGH.axial_allowance + FINISH.scallop + self.finish.RestLimit.Value
            self.assertAlmostEqual(limits["2"]["axial_mm"], max(planned, 6.0) + 0.025)
            # the end mill: a step-down deep, 1.1 stepover wide
            self.assertAlmostEqual(limits["1"]["axial_mm"], ROUGH.stepdown + 0.025)
            self.assertAlmostEqual(limits["1"]["radial_mm"], 1.1 * 0.4 * 8.0 + 0.25)
            self.finish.MaxAxialEngagement = 0.05
            metrics = json.loads(verify_feature.verify_job(self.job, cell=0.25).Metrics)
            loaded = metrics["loads"]
            self.assertFalse(loaded["ok"])
            self.assertAlmostEqual(loaded["limits"]["2"]["axial_mm"], 0.05)
            over = [o for o in loaded["overloads"] if o["tool"] == 2]
            self.assertTrue(over and all(o["quantity"] == "axial" and o["value"] > 0.05
                                         and o["line"] > 0 for o in over), over)
            self.assertTrue(any(m.startswith("T2 ") for m in loaded["messages"]),
                            loaded["messages"])
            self.assertIn("EXCEEDED", verify_feature.format_metrics("job", metrics))
        finally:
            self.finish.MaxAxialEngagement = 0.0
            self.finish.purgeTouched()
            for name in {o.Name for o in self.doc.Objects} - before:
                self.doc.removeObject(name)

    def test_saved_and_reopened(self):
        path = str(Path(self.tmp.name) / "rough.FCStd")
        self.doc.saveCopy(path)
        doc = FreeCAD.openDocument(path)
        try:
            rough = doc.getObject(self.rough.Name)
            before = len(rough.Path.Commands)
            rough.touch()
            doc.recompute()
            self.assertEqual(len(rough.Path.Commands), before)
            self.assertNotIn("error", json.loads(rough.Report))
        finally:
            FreeCAD.closeDocument(doc.Name)


class TestRoughingBadInput(RoughingFixture):
    def recompute_error(self) -> str:
        self.rough.touch()
        self.doc.recompute()
        return json.loads(self.rough.Report or "{}").get("error", "")

    def test_stepdown_deeper_than_the_cutting_edge(self):
        bit = self.rough.ToolController.Tool
        edge = float(getattr(bit.CuttingEdgeHeight, "Value", bit.CuttingEdgeHeight))
        saved = self.rough.StepDown.Value
        try:
            self.rough.StepDown = edge + 1.0
            self.assertIn("StepDown", self.recompute_error())
        finally:
            self.rough.StepDown = saved
            self.doc.recompute()

    def assert_refused(self, name: str, value: float, restore: float, unit: str) -> None:
        """Property ``name`` set to ``value``: the op's error names it and ``unit``; set
        back to ``restore``, the op computes again."""
        try:
            setattr(self.rough, name, value)
            error = self.recompute_error()
            self.assertIn(name, error)
            self.assertIn(unit, error)
        finally:
            setattr(self.rough, name, restore)
            self.doc.recompute()
        self.assertNotIn("error", json.loads(self.rough.Report))

    def test_fine_stepdown_deeper_than_the_stepdown(self):
        self.assert_refused("FineStepDown", self.rough.StepDown.Value + 0.5, 0.0, "mm")

    def test_ramp_angle_sets_the_ramps(self):
        """RampAngle 6 degrees: the report says so and the posted program's roughing ramps
        (T1's straight descending feeds over 0.5 mm in XY) are at most 6 degrees steep, the
        steepest within 10 % of it (at the default 3 none is steeper than 3.15)."""
        import math

        def steepest() -> float:
            program = read_gcode(self.program_now().read_text(), "linuxcnc")
            d = program.end - program.start
            xy = np.hypot(d[:, 0], d[:, 1])
            # moves over 0.5 mm: the post's 4 decimals leave a shorter one's slope inexact
            ramp = (program.tool == 1) & (program.kind == 1) & (d[:, 2] < -1e-4) & (xy > 0.5)
            self.assertTrue(ramp.any())
            return float(np.degrees(np.arctan(-d[ramp, 2] / xy[ramp])).max())

        self.assertLessEqual(steepest(), 3.0 * 1.05)
        try:
            self.rough.RampAngle = 6.0
            self.rough.touch()
            self.doc.recompute()
            self.assertEqual(json.loads(self.rough.Report)["ramp_angle_deg"], 6.0)
            self.assertTrue(6.0 * 0.9 <= steepest() <= 6.0 * 1.05)
        finally:
            self.rough.RampAngle = 3.0
            self.rough.touch()
            self.doc.recompute()
        self.assertTrue(math.isclose(json.loads(self.rough.Report)["ramp_angle_deg"], 3.0))

    def program_now(self) -> Path:
        """The job posted afresh (linuxcnc), after a change to an op."""
        path = Path(self.tmp.name) / "now.ngc"
        cam.post_process(self.job, "linuxcnc", path, remember=False)
        return path

    def test_document_saved_before_ramp_angle_opens(self):
        """A document saved before the op had RampAngle opens with it at the default 3
        degrees (ensure_properties on restore) and recomputes to the same program."""
        path = Path(self.tmp.name) / "before-ramp-angle.FCStd"
        before = [(c.Name, dict(c.Parameters)) for c in self.rough.Path.Commands]
        self.rough.removeProperty("RampAngle")
        try:
            self.doc.saveCopy(str(path))
        finally:
            self.rough.Proxy.ensure_properties(self.rough)
            self.rough.RampAngle = 3.0
        older = FreeCAD.openDocument(str(path))
        try:
            op = older.getObject(self.rough.Name)
            self.assertAlmostEqual(float(op.RampAngle.Value), 3.0)
            op.touch()
            older.recompute()
            report = json.loads(op.Report)
            self.assertNotIn("error", report)
            self.assertEqual(report["ramp_angle_deg"], 3.0)
            after = [(c.Name, dict(c.Parameters)) for c in op.Path.Commands]
            self.assertEqual([n for n, _ in after], [n for n, _ in before])
            worst = max(abs(a[k] - b[k]) for (_, a), (_, b) in zip(after, before) for k in a)
            self.assertLess(worst, 1e-6)
        finally:
            FreeCAD.closeDocument(older.Name)

    def test_document_saved_before_retract_opens_with_full_retracts(self):
        """A finishing op saved before Retract existed opens with Retract full (its program
        unchanged: climbs to the clearance height) and RetractMargin at 1 mm."""
        path = Path(self.tmp.name) / "before-retract.FCStd"
        for name in ("Retract", "RetractMargin"):
            self.finish.removeProperty(name)
        try:
            self.doc.saveCopy(str(path))
        finally:
            self.finish.Proxy.ensure_properties(self.finish)
            self.finish.Retract = "minimum"
        older = FreeCAD.openDocument(str(path))
        try:
            op = older.getObject(self.finish.Name)
            self.assertEqual(op.Retract, "full")
            self.assertAlmostEqual(float(op.RetractMargin.Value), 1.0)
        finally:
            FreeCAD.closeDocument(older.Name)

    def test_retract_margin_out_of_range_is_the_ops_error(self):
        before = [(c.Name, dict(c.Parameters)) for c in self.finish.Path.Commands]
        self.finish.RetractMargin = 0.01
        try:
            self.doc.recompute()
            report = json.loads(self.finish.Report)
            self.assertIn("RetractMargin", report["error"])
            self.assertIn("mm", report["error"])
            self.assertEqual([(c.Name, dict(c.Parameters)) for c in self.finish.Path.Commands],
                             before)
        finally:
            self.finish.RetractMargin = 1.0
            self.doc.recompute()

    def test_start_stock_model_enters_and_hops_over_the_model_raised(self):
        """StartStock model (a part roughed elsewhere to within StockAllowance): the finish
        ignores the roughing's stock; every feed down to a pass, the first one included, is
        at most StockAllowance + RetractMargin long, and every rapid descent ends at least
        that far above the pass it enters.  StockAllowance over 100 mm is the op's error."""
        self.assertEqual(self.finish.StartStock, "job")
        allowance, margin = 0.5, float(self.finish.RetractMargin.Value)
        self.finish.StartStock = "model"
        self.finish.StockAllowance = allowance
        try:
            self.doc.recompute()
            report = json.loads(self.finish.Report)
            self.assertNotIn("error", report)
            self.assertGreater(report["retract_hops"], 0)
            z = x = y = None
            descents = []
            for c in self.finish.Path.Commands:
                p = c.Parameters
                nx, ny, nz = p.get("X", x), p.get("Y", y), p.get("Z", z)
                if c.Name in ("G1", "G01") and z is not None and nx == x and ny == y \
                        and nz < z:
                    descents.append(z - nz)
                x, y, z = nx, ny, nz
            self.assertGreater(len(descents), report["retract_hops"])
            self.assertLessEqual(max(descents), allowance + margin + 1e-6)
            self.assertGreater(max(descents), allowance + margin - 1e-6)
            self.finish.StockAllowance = 200.0
            self.doc.recompute()
            error = json.loads(self.finish.Report)["error"]
            self.assertIn("StockAllowance", error)
            self.assertIn("mm", error)
        finally:
            self.finish.StartStock = "job"
            self.finish.StockAllowance = 1.0
            self.doc.recompute()
            self.programs.clear()

    def test_ramp_angle_out_of_range(self):
        for bad in (0.0, 45.0):
            self.assert_refused("RampAngle", bad, 3.0, "degrees")

    def test_fine_stepdown_levels_and_program(self):
        """StepDown 6 mm with FineStepDown 2 mm: levels every 6 mm from the stock top, each
        followed by the levels of the band above it, bottom-up, 2 mm apart at most; the
        program, posted and simulated from the block, leaves no more than the plain 2 mm
        levels do, gouges nothing, no rapid touches the stock, and cuts less."""
        plain = json.loads(self.rough.Report)
        left_plain = self.stock_left()
        saved = self.rough.StepDown.Value
        try:
            self.rough.StepDown = 6.0
            self.rough.FineStepDown = 2.0
            self.rough.touch()
            self.doc.recompute()
            report = json.loads(self.rough.Report)
            self.assertNotIn("error", report)
            levels = report["levels"]
            top = self.stock()[5]
            main = [i for i, z in enumerate(levels)
                    if abs((top - z) / 6.0 - round((top - z) / 6.0)) < 1e-6 or z == min(levels)]
            self.assertGreaterEqual(len(main), 2)
            above = top
            for a, b in zip(main, main[1:] + [len(levels)]):
                band = levels[a + 1:b]
                self.assertEqual(band, sorted(band))
                steps = np.diff([levels[a], *band, above])
                self.assertTrue(np.all(steps <= 2.0 + 1e-6), (levels[a], band, above))
                above = levels[a]
            self.assertLess(report["cutting_length_mm"], plain["cutting_length_mm"])
            left = self.stock_left()
            self.assertLessEqual(left["max"], left_plain["max"] + 0.1)
            self.assertGreaterEqual(left["min"], 0.3 - 0.05)
            self.assertEqual(left["collisions"], 0)
        finally:
            self.rough.StepDown = saved
            self.rough.FineStepDown = 0.0
            self.rough.touch()
            self.doc.recompute()

    def stock_left(self) -> dict:
        """The roughing's program (linuxcnc post, written afresh) simulated from the block:
        stock left above the design (min, max) and the rapids touching the stock."""
        self.finish.Active = False
        try:
            path = Path(self.tmp.name) / "rough-only.ngc"
            cam.post_process(self.job, "linuxcnc", path, remember=False)
        finally:
            self.finish.Active = True
        program = read_gcode(path.read_text())
        result = verify_job(self.surface, program, {1: Tool(8.0, "flat")}, stock=self.stock(),
                            cell=0.2)
        left = result.job.snapshots[1] - result.design
        left = left[result.inside & np.isfinite(left)]
        return {"min": float(left.min()), "max": float(left.max()),
                "collisions": len(result.metrics["rapid_collisions"])}

    def test_allowance_larger_than_the_stock(self):
        saved = self.rough.AxialAllowance.Value
        try:
            self.rough.AxialAllowance = 500.0
            self.assertIn("allowance", self.recompute_error().lower())
        finally:
            self.rough.AxialAllowance = saved
            self.doc.recompute()
        self.assertNotIn("error", json.loads(self.rough.Report))


class TestCylinderStock(unittest.TestCase):
    """A job whose stock is CAM's cylinder (``CreateCylinder``, r 37 mm round the bump's
    middle): the op roughs from the cylinder, not from its box, and its program, simulated
    from the cylinder, cuts nothing with its rapids and clears nothing out in the box's
    corners (up to 52 mm from the axis, where the cylinder holds no material)."""

    RADIUS = 37.0
    BOTTOM = 8.0

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("TestBSplineCAMCylinderStock")
        cls.surface = bump()
        cls.model, cls.job, cls.finish = pipeline.build_job(
            cls.surface, FINISH, cam.Cutting(), cls.doc, roughing=ROUGH)
        cls.top = float(np.max(cls.surface.grid(101, 101)[..., 2])) + 2.0
        old = cls.job.Stock
        placement = FreeCAD.Placement(FreeCAD.Vector(25, 25, cls.BOTTOM), FreeCAD.Rotation())
        cls.job.Stock = compat.cam_module("stock").CreateCylinder(
            cls.job, radius=cls.RADIUS, height=cls.top - cls.BOTTOM, placement=placement)
        cls.doc.removeObject(old.Name)
        cls.doc.recompute()
        cls.rough = cls.job.Operations.Group[0]

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)

    def test_the_ops_stock_is_the_cylinder(self):
        from BSplineCAM.core.simulation.stock import CylinderStock

        self.assertEqual(compat.cam_stock_type(self.job.Stock), "CreateCylinder")
        stock = self.rough.Proxy.stock_block(self.rough)
        self.assertIsInstance(stock, CylinderStock)
        self.assertAlmostEqual(stock.x, 25.0, places=6)
        self.assertAlmostEqual(stock.y, 25.0, places=6)
        self.assertAlmostEqual(stock.radius, self.RADIUS, places=6)
        self.assertAlmostEqual(stock.z_min, self.BOTTOM, places=6)
        self.assertAlmostEqual(stock.z_max, self.top, places=6)
        from BSplineCAM.app.stock_left import job_stock

        self.assertEqual(job_stock(self.job), stock)

    def test_roughs_within_the_cylinder(self):
        from BSplineCAM.core.simulation.job_simulation import simulate_job
        from BSplineCAM.core.simulation.simulate import Grid

        report = json.loads(self.rough.Report)
        self.assertNotIn("error", report)
        self.assertTrue(self.rough.Path.Commands)
        stock = self.rough.Proxy.stock_block(self.rough)
        # every feed ends within two tool radii of the cylinder: passes end within the tool's
        # reach (links join such ends, inside the same disk), a lead-in descends at most a
        # diameter out in the air; nothing clears the box's corners
        reach = stock.radius + 8.0 + 0.5
        far = [c for c in self.rough.Path.Commands if c.Name in ("G1", "G2", "G3")
               and "X" in c.Parameters and "Y" in c.Parameters
               and np.hypot(c.Parameters["X"] - stock.x, c.Parameters["Y"] - stock.y) > reach]
        self.assertEqual(far, [])
        # the op's program simulated from the cylinder: no rapid cuts, material removed, the
        # width of cut outside entries within 1.1 stepover (the round fronts on the level at
        # the cylinder's bottom made it 5.5 mm while they ran in stairs through the cells)
        program = read_gcode(f"T1 M6\n{self.rough.Path.toGCode()}\nM2\n", "rough")
        grid = Grid.covering(stock.x_min, stock.x_max, stock.y_min, stock.y_max, CELL)
        job = simulate_job(program, {1: Tool(8.0, "flat")}, grid, stock)
        self.assertEqual(job.collisions, ())
        self.assertGreater(job.removed_volume(), 0.0)
        self.assertEqual(job.cylinder, stock)
        stepover = 0.01 * ROUGH.stepover_percent * 8.0
        radial = job.tools[1].radial_engagement_max_mm
        self.assertGreaterEqual(radial, 0.9 * stepover)
        self.assertLessEqual(radial, 1.1 * stepover + CELL)

    def test_verify_follows_the_cylinder(self):
        """The workbench's Verify of the job starts the whole program from the cylinder."""
        from BSplineCAM.app import verify_feature

        before = {o.Name for o in self.doc.Objects}
        result = verify_feature.verify_job(self.job, cell=0.5)
        try:
            metrics = json.loads(result.Metrics)
            self.assertAlmostEqual(metrics["stock_cylinder_mm"]["radius"], self.RADIUS,
                                   places=6)
            self.assertEqual(metrics["rapid_collisions"], [])
            self.assertEqual(sorted(metrics["tools"]), ["1", "2"])
        finally:
            for name in {o.Name for o in self.doc.Objects} - before:
                self.doc.removeObject(name)


class TestAddRoughing(unittest.TestCase):
    def test_adding_roughing_computes_no_op(self):
        """Adding the roughing to a job whose finishing op is set up computes no op: the
        roughing's tool bit recomputes the document (FreeCAD 0.20), which computed the
        finishing op once from the bare block (a part's whole finish, thrown away at the
        job's recompute).  Then one recompute computes both, the finish from the roughed
        stock (its rest passes)."""
        doc = FreeCAD.newDocument("TestBSplineCAMAddRoughing")
        try:
            _, job, finish = pipeline.build_job(bump(), FINISH, cam.Cutting(), doc)
            pipeline.add_roughing(job, ROUGH, cam.Cutting())
            rough = job.Operations.Group[0]
            self.assertEqual(finish.Report, "")
            self.assertEqual(rough.Report, "")
            self.assertTrue(finish.Active and rough.Active)
            doc.recompute()
            report = json.loads(finish.Report)
            self.assertNotIn("error", report)
            self.assertGreater(report["rest"]["passes"], 0)
            self.assertNotIn("error", json.loads(rough.Report))
        finally:
            FreeCAD.closeDocument(doc.Name)


class TestJobCommand(unittest.TestCase):
    """``bsplinecam job`` in this FreeCAD: block to part on the bump, every output checked."""

    def run_job(self, out: Path, *extra: str) -> int:
        from BSplineCAM.orchestration import cli

        net = out.parent / "bump.json"
        net.write_text(json.dumps({"name": "bump", "knots": "clamped",
                                   "control_points": np.asarray(bump().control_points).tolist()}))
        return cli.main(["job", str(net), "--rough", "flat:8", "--stepdown", "2",
                         "--stepover", "40", "--allowance", "0.3", "--finish", "ball:6",
                         "--scallop", "0.05", "--tolerance", "0.01", *extra,
                         "--out", str(out)])

    def test_block_to_part_outputs(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "job"
            status = self.run_job(out, "--post", "linuxcnc,grbl")
            names = sorted(p.name for p in out.iterdir())
            self.assertEqual(status, 0, names)
            for name in ("bump.ngc", "bump-grbl.ngc", "bump-job.FCStd", "job.json",
                         "verify.json", "deviation.png", "stock-T1.png", "stock-T2.png"):
                self.assertIn(name, names)
            job = json.loads((out / "job.json").read_text())
            verified = json.loads((out / "verify.json").read_text())
            self.assertTrue(verified["ok"], verified["checks"])
            self.assertEqual(set(verified["checks"]), {"gouge_max_mm", "scallop_max_mm",
                                                       "rapid_collisions", "load_limits"})
            # every move within its tool's limits: the end mill a step-down deep
            self.assertEqual(verified["checks"]["load_limits"]["value"], 0)
            self.assertLessEqual(verified["tools"]["1"]["axial_engagement_max_mm"],
                                 ROUGH.stepdown + 0.01 + 1e-9)
            self.assertIn("roughing_radial_engagement_max_mm", verified["targets"])
            self.assertEqual(sorted(verified["tools"]), ["1", "2"])
            self.assertEqual(verified["tools"]["1"]["tool"]["shape"], "flat")
            self.assertGreater(verified["tools"]["1"]["removed_volume_mm3"],
                               verified["tools"]["2"]["removed_volume_mm3"])
            self.assertEqual(job["roughing"]["levels"], sorted(job["roughing"]["levels"],
                                                              reverse=True))
            if rs274.available():
                self.assertEqual(set(job["rs274_by_post"]), {"linuxcnc", "grbl"})
                self.assertTrue(all(r["ok"] for r in job["rs274_by_post"].values()))

    def test_finish_past_the_stock_margin(self):
        """A part (a block with rounded top edges, as BREP) finished with a 6 mm ball down
        its rounded sides, where the ball's centre runs out to its radius beyond the part,
        past a 1 mm stock margin: the rest passes clear what is left within the stock (the
        stock grid covers the passes, so none is refused) and the job verifies."""
        import Part

        from BSplineCAM.orchestration import cli

        box = Part.makeBox(30, 20, 8)
        top = [e for e in box.Edges if e.BoundBox.ZMin > 8 - 1e-9]
        shape = box.makeFillet(3.0, top)
        with tempfile.TemporaryDirectory() as tmp:
            brep = Path(tmp) / "block.brep"
            shape.exportBrep(str(brep))
            out = Path(tmp) / "job"
            status = cli.main(["job", str(brep), "--stock-margin", "1", "--rough", "flat:8",
                               "--stepdown", "4", "--allowance", "0.3", "--finish", "ball:6",
                               "--scallop", "0.2", "--tolerance", "0.01", "--no-rs274",
                               "--out", str(out)])
            self.assertEqual(status, 0)
            verified = json.loads((out / "verify.json").read_text())
            self.assertTrue(verified["ok"], verified["checks"])
            program = read_gcode((out / "block.ngc").read_text(), "block.ngc")
            t2 = program.end[program.tool == 2]
            self.assertLess(float(t2[:, 1].min()), -2.5)  # the finish past the 1 mm margin
            job = json.loads((out / "job.json").read_text())
            self.assertGreater(job["rest"]["passes"], 0, job["rest"])

    def test_failed_check_is_said(self):
        """A job whose finish leaves the scallop over its limit (waterline on the mostly
        shallow bump) ends with status 1 and a line per failed check on stderr, with the
        strategy's hint, besides verify.json."""
        import contextlib
        import io

        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "job"
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                status = self.run_job(out, "--strategy", "waterline", "--no-rs274")
            self.assertEqual(status, 1)
            verified = json.loads((out / "verify.json").read_text())
            self.assertFalse(verified["checks"]["scallop_max_mm"]["ok"])
            lines = [ln for ln in err.getvalue().splitlines() if "check failed" in ln]
            self.assertEqual(len(lines), 1, err.getvalue())
            self.assertIn("scallop_max_mm", lines[0])
            self.assertIn("steep_shallow", lines[0])

    def test_stepdown_beyond_the_cutting_edge_writes_nothing(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "job"
            status = self.run_job(out, "--stepdown", "45")
            self.assertEqual(status, 2)
            self.assertFalse(out.exists())


if __name__ == "__main__":
    unittest.main()
