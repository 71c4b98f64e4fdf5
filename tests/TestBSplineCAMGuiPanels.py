# SPDX-License-Identifier: LGPL-2.1-or-later
"""GUI tests of progress and cancel, task panels, a reopened document and the roughing command,
run inside a real FreeCAD GUI (under Xvfb, ``tools/run_gui_test.sh``); their pictures go to
:data:`bsplinecam_gui.DOCS`.  File dialogs are replaced by fixed paths; error boxes are closed
by a timer and recorded.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
# bsplinecam_gui puts the repository on sys.path and skips the module without FreeCAD's GUI
import bsplinecam_gui  # noqa: E402, F401, I001
import FreeCAD  # noqa: E402
import FreeCADGui  # noqa: E402
from bsplinecam_gui import (  # noqa: E402
    COARSE_SCALLOP,
    DOCS,
    FINE_SCALLOP,
    PICTURE,
    CamTestCase,
    bench_window,
    cam_dialogs,
    clear_report,
    dialogs_answer,
    in_scene,
    is_active,
    isometric_view,
    message_boxes,
    process_events,
    report_text,
    scene_box,
    timed_during_computation,
    wait,
)
from PySide import QtCore, QtGui  # noqa: E402


def default_dock_width() -> int:
    """Width (pixels) of the dock holding the task panels, as a fresh FreeCAD lays it out."""
    mw = FreeCADGui.getMainWindow()
    for name in ("Combo View", "Tasks"):
        dock = mw.findChild(QtGui.QDockWidget, name)
        if dock is not None and dock.isVisible():
            return dock.width()
    return 0


class TestProgressAndPanels(CamTestCase):
    """Issue 13: progress and cancel, panels that fit and show what applies, the results."""

    def test_op_progress_esc_cancel_keeps_path(self) -> None:
        from BSplineCAM.gui import progress_bar

        surface, job, op = self.make_job()
        before = op.Path.toGCode()
        report = op.Report
        self.assertGreater(len(op.Path.Commands), 100)
        # a long recompute (fine scallop): timers fire meanwhile, Esc cancels it
        op.ScallopHeight = FINE_SCALLOP
        clear_report()
        mw = FreeCADGui.getMainWindow()

        def press_esc(bar) -> None:
            event = QtGui.QKeyEvent(QtCore.QEvent.KeyPress, QtCore.Qt.Key_Escape,
                                    QtCore.Qt.NoModifier)
            QtGui.QApplication.sendEvent(mw, event)

        with message_boxes() as boxes, timed_during_computation(press_esc) as ticks:
            self.doc.recompute()
            process_events()
        self.assertEqual(boxes, [])  # no "Do you really want to abort?"
        computing = [fraction for running, fraction in ticks if running]
        self.assertGreater(len(computing), 1, ticks)  # the event loop ran during the work
        last = progress_bar.ProgressBar.last
        self.assertEqual(last.target, (self.doc.Name, op.Name))
        self.assertTrue(last.cancelled)
        self.assertLess(last.fraction, 1.0)
        self.assertLessEqual(last.calls - last.calls_at_cancel, 1)  # stopped at its next report
        self.assertGreater(last.events, 1)
        # the op as it was: its previous program and report, valid, still to be recomputed
        self.assertEqual(op.Path.toGCode(), before)
        self.assertEqual(op.Report, report)
        self.assertTrue(op.isValid(), op.State)
        self.assertNotIn("Invalid", op.State)
        # touched again by a timer once the recompute has ended (retried every 50 ms)
        for _ in range(40):
            if "Touched" in op.State:
                break
            wait(50)
        self.assertIn("Touched", op.State)
        lines = [ln for ln in report_text().splitlines() if "cancelled by the user" in ln]
        self.assertEqual(len(lines), 1, report_text())
        self.assertFalse(progress_bar.StatusWidgets.bar.isVisible())
        # the next recompute is not marked aborted; the coarse scallop gives the same program
        op.ScallopHeight = COARSE_SCALLOP
        with message_boxes() as boxes:
            self.doc.recompute()
        self.assertEqual(boxes, [])
        self.assertTrue(op.isValid(), op.State)
        self.assertNotIn("Touched", op.State)
        self.assertEqual(op.Path.toGCode(), before)
        self.assertNotIn("aborted", report_text().lower())

        # Verify: the simulation reports while it runs, the Cancel button stops it, nothing made
        names = [o.Name for o in self.doc.Objects]
        undo = self.doc.UndoCount
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        clear_report()
        with message_boxes() as boxes, timed_during_computation(
                lambda bar: progress_bar.StatusWidgets.button.click(), after=0.3) as ticks:
            FreeCADGui.runCommand("BSplineCAM_Verify")
            process_events()
        self.assertEqual(boxes, [])
        computing = [fraction for running, fraction in ticks if running]
        self.assertTrue(any(0.15 < f < 0.8 for f in computing), ticks)  # during the simulation
        last = progress_bar.ProgressBar.last
        self.assertTrue(last.cancelled)
        self.assertLess(last.fraction, 1.0)
        self.assertLessEqual(last.calls - last.calls_at_cancel, 1)
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        self.assertEqual(self.doc.UndoCount, undo)
        lines = [ln for ln in report_text().splitlines() if "cancelled by the user" in ln]
        self.assertEqual(len(lines), 1, report_text())
        self.assertFalse(progress_bar.StatusWidgets.bar.isVisible())

    def test_job_panel_fields_and_width(self) -> None:
        surface = self.new_surface()
        panel = self.open_job_panel(surface)
        shown = {"raster": {"angle", "direction"}, "waterline": set(),
                 "isoparametric": {"iso_direction", "direction"}}
        for strategy, fields in shown.items():
            panel.strategy.setCurrentIndex(panel.strategy.findText(strategy))
            process_events()
            for name in ("angle", "direction", "iso_direction"):
                widget = getattr(panel, name)
                label = panel.layout.labelForField(widget)
                visible = name in fields
                self.assertEqual(widget.isVisibleTo(panel.form), visible, (strategy, name))
                self.assertEqual(label.isVisibleTo(panel.form), visible, (strategy, name))
        # Qt's QDialogButtonBox values: Ok 0x400, Cancel 0x400000, Close 0x200000 (FreeCAD 1.1's
        # PySide6 refuses int() on its enums: the panel's buttons must still come as an int)
        self.assertEqual(panel.getStandardButtons(), 0x400 | 0x400000)
        width = default_dock_width()
        self.assertGreater(width, 100)
        wait(500)
        DOCS.mkdir(parents=True, exist_ok=True)
        mw = FreeCADGui.getMainWindow()
        self.assertTrue(QtGui.QApplication.primaryScreen().grabWindow(mw.winId()).save(
            str(DOCS / "job_panel.png"), "PNG"))
        # the panel sits in a task box inside the dock (margins of a few pixels each side)
        self.assertLessEqual(panel.form.minimumSizeHint().width() + 40, width,
                             f"job panel needs {panel.form.minimumSizeHint().width()} px")
        panel.reject()
        process_events()
        # the net editor too, and a bad entry is explained beside the table
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        process_events()
        net = surface.ViewObject.Proxy.panel
        self.assertEqual(net.getStandardButtons(), 0x400 | 0x400000)
        self.assertLessEqual(net.form.minimumSizeHint().width() + 40, width,
                             f"net panel needs {net.form.minimumSizeHint().width()} px")
        z = surface.ControlPoints[12].z
        self.assertFalse(net.message.isVisibleTo(net.form))
        net.table.item(12, 2).setText("twelve")
        process_events()
        self.assertTrue(net.message.isVisibleTo(net.form))
        self.assertIn("'twelve' is not a number", net.message.text())
        self.assertIn("1,2 Z", net.message.text())
        self.assertEqual(float(net.table.item(12, 2).text()), z)
        self.assertEqual(surface.ControlPoints[12].z, z)
        net.set_cell(1, 2, 2, z + 1.0)
        self.assertFalse(net.message.isVisibleTo(net.form))
        self.assertAlmostEqual(surface.ControlPoints[12].z, z + 1.0)
        net.reject()
        process_events()

    def test_new_surface_isometric_net_on_top(self) -> None:
        import math
        import time

        from pivy import coin

        obj = self.new_surface()
        process_events()
        view = FreeCADGui.activeDocument().activeView()

        def view_direction():
            rotation = view.getCameraNode().orientation.getValue()
            return rotation.multVec(coin.SbVec3f(0, 0, -1)).getValue()

        # FreeCAD may animate the turn to the isometric view: wait (up to 5 s) for it to settle
        direction, deadline = view_direction(), time.monotonic() + 5.0
        while time.monotonic() < deadline:
            time.sleep(0.05)
            process_events()
            latest = view_direction()
            if max(abs(a - b) for a, b in zip(latest, direction)) < 1e-7:
                break
            direction = latest
        # isometric: the view direction makes the same angle with the three axes, looking down
        for component in direction:
            self.assertAlmostEqual(abs(component), 1 / math.sqrt(3), places=4, msg=direction)
        self.assertLess(direction[2], 0)
        # the net in an annotation: drawn over the surface, control points under it show
        proxy = obj.ViewObject.Proxy
        self.assertTrue(proxy.net_root.isOfType(coin.SoAnnotation.getClassTypeId()))
        for node in (proxy.lines, proxy.points):
            self.assertTrue(in_scene(view, node))
            self.assertGreaterEqual(proxy.net_root.findChild(node), 0)

    def test_crosscheck_results_panel(self) -> None:
        from BSplineCAM.gui import results_panel

        obj = self.new_surface()
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(obj)
        results_panel.ResultsPanel.last = None
        FreeCADGui.runCommand("BSplineCAM_CrossCheck")
        process_events()
        panel = results_panel.ResultsPanel.last
        self.assertIsNotNone(panel)
        self.assertTrue(FreeCADGui.Control.activeDialog())
        report = json.loads(obj.CrossCheck)
        text = panel.figures.toPlainText()
        for key, value in report["max_deviation_mm"].items():
            self.assertIn(key, text)
            if value is not None:
                self.assertIn(f"{value:.3e} mm", text)
        self.assertIn("exact route OK", text)
        self.assertEqual(panel.getStandardButtons(), 0x200000)
        self.assertTrue(panel.figures.isReadOnly())
        flags = panel.figures.textInteractionFlags()
        self.assertTrue(flags & QtCore.Qt.TextSelectableByMouse)
        panel.copy.click()
        self.assertEqual(QtGui.QApplication.clipboard().text(), text)
        # a results panel does not keep the net editor away
        self.assertTrue(is_active("BSplineCAM_EditNet"))
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        process_events()
        self.assertIsNotNone(obj.ViewObject.Proxy.panel)
        obj.ViewObject.Proxy.panel.reject()
        process_events()


class TestReopenedDocument(CamTestCase):
    """Every command on a job document saved, closed and opened again (fresh proxies)."""

    def test_every_command_after_reopen(self) -> None:
        from BSplineCAM.core.program import rs274
        from BSplineCAM.gui import cam_commands, results_panel

        surface, job, op = self.reopen("job.FCStd", *self.make_job())
        self.assertEqual(type(op.ViewObject.Proxy).__name__, "FinishOpViewProvider")
        before = op.Path.toGCode()
        # post-process the reopened job (the op stands for it), checked by rs274
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(op)
        self.assertTrue(is_active("BSplineCAM_PostProcess"))
        program = self.tmp / "reopened.ngc"
        cam_commands.PostProcess.last_check = None
        with cam_dialogs(post="linuxcnc", save_path=str(program)), message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_PostProcess")
        self.assertEqual(boxes, [])
        self.assertTrue(program.is_file())
        if rs274.available():
            self.assertTrue(cam_commands.PostProcess.last_check["ok"])
        # verify it: a simulated part and its figures
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        self.assertTrue(is_active("BSplineCAM_Verify"))
        count = len(self.doc.Objects)
        with message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_Verify")
            process_events()
        self.assertEqual(boxes, [])
        self.assertEqual(len(self.doc.Objects), count + 1)
        self.assertIsNotNone(results_panel.ResultsPanel.current)
        # the op recomputes after an edit, with progress, to the same program
        op.ScallopHeight = float(op.ScallopHeight.Value)
        op.touch()
        with message_boxes() as boxes:
            self.doc.recompute()
        self.assertEqual(boxes, [])
        self.assertTrue(op.isValid(), op.State)
        self.assertEqual(op.Path.toGCode(), before)
        # the surface commands on the reopened surface
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        with message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_CrossCheck")
            process_events()
        self.assertEqual(boxes, [])
        self.assertTrue(json.loads(surface.CrossCheck)["exact_route_ok"])
        for name, answer in (("BSplineCAM_ExportDat", self.tmp / "reopened.dat"),
                             ("BSplineCAM_ExportStep", self.tmp / "reopened.step")):
            FreeCADGui.Selection.clearSelection()
            FreeCADGui.Selection.addSelection(surface)
            with dialogs_answer(save_path=str(answer)), message_boxes() as boxes:
                FreeCADGui.runCommand(name)
            self.assertEqual(boxes, [])
            self.assertTrue(answer.is_file(), name)
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        process_events()
        panel = surface.ViewObject.Proxy.panel
        self.assertIsNotNone(panel)
        panel.reject()
        process_events()
        # a second job on the reopened surface
        panel = self.open_job_panel(surface)
        with message_boxes() as boxes:
            accepted = panel.accept()
        if not accepted:
            self.fail(f"the job panel refused: {panel.message.text()} {boxes}")
        self.assertEqual(len([o for o in self.doc.Objects if cam_commands.is_job(o)]), 2)
        self.assertNotIn("Error", report_text())


class TestRoughingCommand(CamTestCase):
    def open_rough_panel(self, job):
        from BSplineCAM.gui import rough_panel

        FreeCADGui.Selection.clearSelection()
        self.assertFalse(is_active("BSplineCAM_Rough"))  # no job selected
        FreeCADGui.Selection.addSelection(job)
        self.assertTrue(is_active("BSplineCAM_Rough"))
        rough_panel.RoughPanel.last = None
        FreeCADGui.runCommand("BSplineCAM_Rough")
        process_events()
        panel = rough_panel.RoughPanel.last
        self.assertIsNotNone(panel, "the roughing command opened no task panel")
        self.assertTrue(FreeCADGui.Control.activeDialog())
        return panel

    def test_roughing_added_before_the_finish_in_one_transaction(self) -> None:
        from BSplineCAM.app import compat
        from BSplineCAM.gui import rough_panel

        surface, job, op = self.make_job()
        op.RestLimit = 0  # the rest passes have tests of their own; keep the GUI run short
        self.doc.recompute()
        panel = self.open_rough_panel(job)
        names = [o.Name for o in self.doc.Objects]
        undo = self.doc.UndoCount
        # the corner radius field shows for the bull-nose only
        self.assertFalse(panel.corner.isVisible())
        panel.shape.setCurrentIndex(rough_panel.SHAPES.index("bullnose"))
        process_events()
        self.assertTrue(panel.corner.isVisible())
        panel.shape.setCurrentIndex(rough_panel.SHAPES.index("flat"))
        # a bad field: refused with its name, nothing changed
        panel.stepdown.setValue(0.0)
        with message_boxes() as boxes:
            self.assertFalse(panel.accept())
            process_events()
        self.assertIn("Step-down", panel.message.text())
        self.assertEqual(len(boxes), 1, boxes)
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        self.assertEqual(self.doc.UndoCount, undo)
        # a coarse roughing: computed, first in the job, T1; the ball moved to T2
        panel.stepdown.setValue(4.0)
        panel.stepover.setValue(50.0)
        panel.diameter.setValue(12.0)
        self.accept_panel(panel, undo + 1)
        rough = job.Operations.Group[0]
        self.assertTrue(rough_panel.is_roughing_op(rough))
        self.assertTrue(rough.FlatLevels)  # the panel's default
        self.assertIs(job.Operations.Group[1], op)
        self.assertEqual(list(op.RestFrom), [rough])
        self.assertTrue(rough.Path.Commands)
        self.assertNotIn("error", json.loads(rough.Report))
        shapes = {int(tc.ToolNumber): compat.core_tool_shape(tc.Tool)[0] for tc in job.Tools.Group}
        self.assertEqual(shapes, {1: "flat", 2: "ball"})
        self.edit_roughing(rough, undo + 1)
        # undo takes it all back
        self.doc.undo()
        self.doc.undo()
        process_events()
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        self.assertEqual([o.Name for o in job.Operations.Group], [op.Name])

    def test_roughing_from_a_cylinder_stock(self) -> None:
        """A job whose stock was changed to CAM's cylinder (CreateCylinder round the part):
        the Roughing command's op roughs from the cylinder (no feed beyond its reach, the
        box's corners hold no material) and the view shows the cylinder with the paths
        (docs/rough_cylinder.png)."""
        from BSplineCAM.app import compat
        from BSplineCAM.core.simulation.stock import CylinderStock

        surface, job, op = self.make_job()
        op.RestLimit = 0
        box = surface.Shape.BoundBox
        radius = 0.5 * math.hypot(box.XLength, box.YLength) + 2.0
        bottom, top = box.ZMin - 1.0, box.ZMax + 2.0
        old = job.Stock
        job.Stock = compat.cam_module("stock").CreateCylinder(
            job, radius=radius, height=top - bottom,
            placement=FreeCAD.Placement(FreeCAD.Vector(box.Center.x, box.Center.y, bottom),
                                        FreeCAD.Rotation()))
        self.doc.removeObject(old.Name)
        self.doc.recompute()
        panel = self.open_rough_panel(job)
        panel.stepdown.setValue(4.0)
        panel.stepover.setValue(50.0)
        panel.diameter.setValue(12.0)
        self.accept_panel(panel, self.doc.UndoCount + 1)
        rough = job.Operations.Group[0]
        self.assertNotIn("error", json.loads(rough.Report))
        stock = rough.Proxy.stock_block(rough)
        self.assertIsInstance(stock, CylinderStock)
        self.assertAlmostEqual(stock.radius, radius, places=6)
        feeds = [(c.Parameters["X"], c.Parameters["Y"]) for c in rough.Path.Commands
                 if c.Name in ("G1", "G2", "G3") and "X" in c.Parameters
                 and "Y" in c.Parameters]
        self.assertTrue(feeds)
        far = [xy for xy in feeds
               if math.hypot(xy[0] - stock.x, xy[1] - stock.y) > radius + 6.0 + 0.5]
        self.assertEqual(far, [])
        mw, mdi = bench_window()
        # the part in the cylinder (shaded, see-through) with the roughing's paths
        op.ViewObject.Visibility = False
        for model in job.Model.Group:
            model.ViewObject.Visibility = True
        job.Stock.ViewObject.Visibility = True
        job.Stock.ViewObject.DisplayMode = "Flat Lines"
        job.Stock.ViewObject.Transparency = 80
        view = isometric_view(mdi)
        self.assert_framed(view, *scene_box(view))
        picture = DOCS / "rough_cylinder.png"
        view.saveImage(str(picture), *PICTURE, "White")
        # points inside the part's solid, just above its base: covered from any side
        self.assert_picture(view, picture, [
            (box.XMin + fx * box.XLength, box.YMin + fy * box.YLength, box.ZMin + 0.5)
            for fx in (0.3, 0.5, 0.7) for fy in (0.3, 0.5, 0.7)])
        # saved, closed and opened again: the stock is still the cylinder, the op recomputes
        # to the same path with nothing red in the report view
        before = rough.Path.toGCode()
        job, rough = self.reopen("cylinder.FCStd", job, rough)
        self.assertEqual(type(rough.ViewObject.Proxy).__name__, "RoughOpViewProvider")
        self.assertEqual(rough.Path.toGCode(), before)
        rough.touch()
        self.doc.recompute()
        process_events()
        self.assertNotIn("Error", report_text())
        self.assertFalse(rough.State and "Invalid" in rough.State, rough.State)
        stock = rough.Proxy.stock_block(rough)
        self.assertIsInstance(stock, CylinderStock)
        self.assertAlmostEqual(stock.radius, radius, places=6)
        self.assertEqual(rough.Path.toGCode(), before)

    def accept_panel(self, panel, undo: int) -> None:
        """OK on ``panel``: accepted, closed, one more undo step (``undo`` in all)."""
        with message_boxes() as boxes:
            accepted = panel.accept()
        if not accepted:
            self.fail(f"the roughing panel refused: {panel.message.text()} {boxes}")
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())
        self.assertEqual(self.doc.UndoCount, undo)

    def edit_roughing(self, rough, undo: int) -> None:
        """Double-click opens the panel filled from the op; a bad field changes nothing; OK
        changes the op in one transaction and recomputes it."""
        from BSplineCAM.gui import rough_panel

        rough_panel.RoughPanel.last = None
        vobj = rough.ViewObject
        self.assertIsInstance(vobj.Proxy, rough_panel.RoughOpViewProvider)
        self.assertTrue(vobj.Proxy.doubleClicked(vobj))
        process_events()
        panel = rough_panel.RoughPanel.last
        self.assertIsNotNone(panel, "double-clicking the roughing op opened no panel")
        self.assertTrue(panel.editing)
        self.assertEqual((panel.stepdown.value(), panel.stepover.value(), panel.diameter.value()),
                         (4.0, 50.0, 12.0))
        self.assertEqual(panel.shape.currentText(), "flat")
        self.assertFalse(panel.diameter.isEnabled())  # the controller's bit
        wait(500)
        DOCS.mkdir(parents=True, exist_ok=True)
        self.assertTrue(QtGui.QApplication.primaryScreen().grabWindow(
            FreeCADGui.getMainWindow().winId()).save(str(DOCS / "rough_panel.png"), "PNG"))
        self.assertAlmostEqual(panel.horizontal_feed.value(),
                               float(rough.ToolController.HorizFeed.getValueAs("mm/min")))
        levels = json.loads(rough.Report)["levels"]
        panel.stepdown.setValue(100.0)  # deeper than the cutting edge: refused, nothing changes
        with message_boxes() as boxes:
            self.assertFalse(panel.accept())
            process_events()
        self.assertTrue(panel.message.text(), "no reason shown for the refusal")
        self.assertEqual(len(boxes), 1, boxes)
        self.assertEqual(self.doc.UndoCount, undo)
        self.assertIn("StepDown", panel.message.text())
        self.assertAlmostEqual(rough.StepDown.Value, 4.0)
        self.assertEqual(json.loads(rough.Report)["levels"], levels)
        self.assertEqual((panel.fine.value(), panel.fine.text()), (0.0, "off"))
        self.assertEqual(panel.flat_levels.isChecked(), bool(rough.FlatLevels))
        panel.stepdown.setValue(3.0)
        panel.fine.setValue(5.0)  # thicker than the step-down: refused, nothing changes
        with message_boxes():
            self.assertFalse(panel.accept())
            process_events()
        self.assertIn("Fine step-down", panel.message.text())
        self.assertEqual(self.doc.UndoCount, undo)
        self.assertAlmostEqual(rough.FineStepDown.Value, 0.0)
        panel.fine.setValue(1.5)
        self.assertAlmostEqual(panel.ramp.value(), float(rough.RampAngle.Value))
        panel.ramp.setValue(40.0)  # steeper than any ramp: refused, nothing changes
        with message_boxes():
            self.assertFalse(panel.accept())
            process_events()
        self.assertIn("Ramp angle", panel.message.text())
        self.assertIn("degrees", panel.message.text())
        self.assertEqual(self.doc.UndoCount, undo)
        panel.ramp.setValue(5.0)
        panel.horizontal_feed.setValue(900.0)
        self.accept_panel(panel, undo + 1)
        self.assertAlmostEqual(rough.StepDown.Value, 3.0)
        self.assertAlmostEqual(rough.FineStepDown.Value, 1.5)
        self.assertAlmostEqual(rough.RampAngle.Value, 5.0)
        self.assertEqual(json.loads(rough.Report)["ramp_angle_deg"], 5.0)
        self.assertAlmostEqual(float(rough.ToolController.HorizFeed.getValueAs("mm/min")), 900.0)
        self.assertNotEqual(json.loads(rough.Report)["levels"], levels)
        feed = rough.ToolController.HorizFeed.Value  # Path commands hold mm/s
        self.assertAlmostEqual(feed, 15.0)
        self.assertTrue(any(abs(c.Parameters.get("F", 0) - feed) < 1e-9
                            for c in rough.Path.Commands if c.Name == "G1"),
                        "the new feed is not in the recomputed path")
