# SPDX-License-Identifier: LGPL-2.1-or-later
"""The part job walked through the GUI's commands and panels, as a user would: import a STEP
part, pick faces (with an edge by mistake), the job panel (a tool too large first), the
roughing panel, Verify, CAM's own Post Process, save, close, reopen, Verify again.

Runs in the real FreeCAD GUI under Xvfb (``tools/run_gui_test.sh TestBSplineCAMGuiPart``).
Proves: every command leaves no object touched (so CAM's post never recomputes the
toolpaths), Verify measures a part job against the part's exact faces, the results show
unselected, the program lands where the job's output file says, and the report view holds no
traceback.
"""

from __future__ import annotations

import json
import os
import sys
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
# bsplinecam_gui puts the repository on sys.path and skips the module without FreeCAD's GUI
import bsplinecam_gui  # noqa: E402, F401, I001
import FreeCADGui  # noqa: E402
from bsplinecam_gui import (  # noqa: E402
    ROOT,
    COARSE_SCALLOP,
    TOOL,
    CamTestCase,
    clear_report,
    is_active,
    message_boxes,
    process_events,
    report_text,
)
from PySide import QtGui  # noqa: E402

PART = ROOT / "examples" / "part.step"


def touched(doc) -> list[str]:
    """Labels of the document's objects left touched or invalid."""
    return [f"{o.Label} ({', '.join(o.State)})" for o in doc.Objects
            if "Touched" in o.State or "Invalid" in o.State]


def up_faces(obj) -> list[str]:
    """Names of the B-spline faces of ``obj`` whose normal points up at their middle."""
    names = []
    for k, face in enumerate(obj.Shape.Faces, start=1):
        u0, u1, v0, v1 = face.ParameterRange
        if face.Surface.__class__.__name__ == "BSplineSurface" and \
                face.normalAt(0.5 * (u0 + u1), 0.5 * (v0 + v1)).z > 0.3:
            names.append(f"Face{k}")
    return names


def cam_post_command() -> str:
    """CAM's own post command: Path_Post in 0.20, CAM_Post in 1.0 and later."""
    names = FreeCADGui.listCommands()
    return "CAM_Post" if "CAM_Post" in names else "Path_Post"


class TestPartJobWalk(CamTestCase):
    def import_part(self):
        """File > Import of the example STEP; the object that holds the faces."""
        import ImportGui

        before = {o.Name for o in self.doc.Objects}
        ImportGui.insert(str(PART), self.doc.Name)
        self.doc.recompute()
        process_events()
        made = [o for o in self.doc.Objects if o.Name not in before
                and hasattr(o, "Shape") and len(o.Shape.Faces) > 6]
        self.assertTrue(made, "the STEP import made no solid")
        return made[-1]

    def test_part_job_walk(self) -> None:
        from BSplineCAM.app import verify_feature as vf
        from BSplineCAM.gui import cam_commands, results_panel, rough_panel

        part = self.import_part()
        faces = up_faces(part)
        self.assertEqual(len(faces), 3, faces)  # the B-spline top and its two fillets

        # an edge picked with the faces: the job is offered, the panel says what is left out
        edge = "Edge1"
        FreeCADGui.Selection.clearSelection()
        for name in (*faces, edge):
            FreeCADGui.Selection.addSelection(part, name)
        self.assertTrue(is_active("BSplineCAM_Job"))
        cam_commands.JobPanel.last = None
        FreeCADGui.runCommand("BSplineCAM_Job")
        process_events()
        panel = cam_commands.JobPanel.last
        self.assertIsNotNone(panel)
        self.assertIn("select faces only", panel.message.text())
        self.assertIn(f"{edge} is an edge", panel.message.text())
        self.assertEqual([panel.face_list.item(k).text() for k in range(panel.face_list.count())],
                         [f"{part.Label}.{n}" for n in faces])

        # a ball larger than the faces: refused in the panel before anything is made
        names = [o.Name for o in self.doc.Objects]
        panel.tool.setValue(100.0)
        panel.scallop.setValue(COARSE_SCALLOP)
        with message_boxes() as boxes:
            self.assertFalse(panel.accept())
            process_events()
        self.assertIn("larger than the selected faces", panel.message.text())
        self.assertEqual(len(boxes), 1, boxes)
        self.assertEqual([o.Name for o in self.doc.Objects], names)

        # the job: computed in one step, its output file set, nothing left touched
        panel.tool.setValue(TOOL)
        clear_report()
        with message_boxes() as boxes, self.bars_seen() as seen:
            accepted = panel.accept()
        if not accepted:
            self.fail(f"the job panel refused: {panel.message.text()} {boxes}")
        process_events()
        job = next(o for o in self.doc.Objects if cam_commands.is_job(o))
        op = next(o for o in self.doc.Objects if cam_commands.is_finishing_op(o))
        self.assertEqual([n for _, subs in op.Base for n in subs], faces)
        self.assertTrue(seen, "no progress shown while the toolpath computed")
        self.assertEqual(max(seen), 0, "FreeCAD's progress bar showed beside ours")
        output = job.PostProcessorOutputFile
        self.assertTrue(os.path.isabs(output), output)  # an unsaved document: a named folder
        self.assertIn(str(output), report_text())
        self.assertEqual(touched(self.doc), [])

        # roughing with a flat end mill
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        rough_panel.RoughPanel.last = None
        FreeCADGui.runCommand("BSplineCAM_Rough")
        process_events()
        rpanel = rough_panel.RoughPanel.last
        self.assertIsNotNone(rpanel)
        rpanel.stepdown.setValue(4.0)
        rpanel.stepover.setValue(50.0)
        rpanel.diameter.setValue(10.0)
        with message_boxes() as boxes:
            accepted = rpanel.accept()
        if not accepted:
            self.fail(f"the roughing panel refused: {rpanel.message.text()} {boxes}")
        process_events()
        self.assertEqual(touched(self.doc), [])

        # Verify: the 10 mm end mill could not enter the part's hole, so the finishing ball
        # meets the plug left there; the panel says so in red, naming the tool and the place
        rough = next(o for o in job.Operations.Group if o.Name.startswith("SurfaceRough"))
        notes = json.loads(rough.Report).get("notes", [])
        self.assertTrue(any("too narrow for a helical entry" in n for n in notes), notes)
        self.assertIn("too narrow for a helical entry", report_text())
        # the finishing op says it may meet that stock, and Verify checks it
        left = json.loads(op.Report).get("stock_left_uncut", [])
        self.assertEqual([item["op"] for item in left], [rough.Label], op.Report)
        self.assertIn(f"{op.Label}: the ball may meet stock {rough.Label} left", report_text())
        plugged = self.verify(job)
        loads = json.loads(plugged.Metrics)["loads"]
        self.assertFalse(loads["ok"], loads)
        ball = int(op.ToolController.ToolNumber)
        self.assertIn(ball, {o["tool"] for o in loads["overloads"]})
        rpanel = results_panel.verification_panel(plugged)
        self.assertFalse(rpanel.ok)
        self.assertIn("over its limits", rpanel.verdict.text())
        self.assertIn(f"T{ball}", rpanel.figures.toPlainText())
        self.assertIn("line", rpanel.figures.toPlainText())
        self.assertIn("#b00000", rpanel.verdict.styleSheet())  # red
        for name in [plugged.Name, *(stage.Name for stage in plugged.StockAfter)]:
            self.doc.removeObject(name)

        # the end mill cuts at its centre: edited in the roughing panel, the hole is plunged
        rough_panel.RoughPanel.last = None
        vobj = rough.ViewObject
        self.assertTrue(vobj.Proxy.doubleClicked(vobj))
        process_events()
        epanel = rough_panel.RoughPanel.last
        self.assertTrue(epanel is not None and epanel.editing)
        self.assertFalse(epanel.centre_cutting.isChecked())
        epanel.centre_cutting.setChecked(True)
        with message_boxes() as boxes:
            accepted = epanel.accept()
        if not accepted:
            self.fail(f"the roughing panel refused: {epanel.message.text()} {boxes}")
        process_events()
        self.assertTrue(rough.CentreCutting)
        self.assertNotIn("stock_left_uncut", json.loads(op.Report))  # recomputed after it
        self.assertGreater(json.loads(rough.Report)["entries"].get("plunge", 0), 0,
                         rough.Report)
        self.assertEqual(touched(self.doc), [])

        # Verify: the part's exact faces, whole program from the stock, every load in limits
        result = self.verify(job)
        metrics = json.loads(result.Metrics)
        self.assertTrue(metrics["loads"]["ok"], metrics["loads"])
        self.assertTrue(results_panel.verification_panel(result).ok)
        self.assertLess(metrics["gouge_max_mm"], 0.01)
        # a part: the gouge along the normal too, in the report the panel shows
        self.assertTrue(metrics["gouge_normal_measured"])
        self.assertIn("along the normal", results_panel.verification_panel(result).text)
        self.assertEqual(sorted(metrics["faces"]), sorted(int(n[4:]) for n in faces))
        self.assertLess(metrics["scallop_p99_mm"], 1.5 * COARSE_SCALLOP)
        self.assertEqual(sorted(metrics["tools"]), ["1", "2"])
        self.assertEqual(len(result.StockAfter), 1)
        self.assertEqual(FreeCADGui.Selection.getSelection(), [])  # the colours show
        # named for the part (FreeCAD 1.1 makes labels unique by their trailing number: the
        # first verification's "... 1" stays taken after its removal, so "... 001")
        self.assertTrue(result.Label.startswith(f"Simulated {part.Label.rstrip('0123456789')}"),
                        result.Label)
        self.assertEqual(vf.finishing_op_of(job), op)
        self.assertEqual(touched(self.doc), [])
        self.picture(result)

        # CAM's own Post Process: the program goes to the job's output file, toolpaths are
        # not recomputed (nothing touched)
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        cwd_before = set(os.listdir(os.getcwd()))
        executed = []
        for o in job.Operations.Group:
            o.Proxy.opExecute = (lambda obj, run=o.Proxy.opExecute:
                                 (executed.append(obj.Name), run(obj))[1])
        try:
            with message_boxes() as boxes, self.modal_dialogs_accepted():
                FreeCADGui.runCommand(cam_post_command())
                process_events()
        finally:
            for o in job.Operations.Group:
                del o.Proxy.opExecute
        self.assertEqual(executed, [])  # no toolpath computed again
        self.assertTrue(Path(output).is_file(), (output, boxes, report_text()))
        self.assertIn("G1", Path(output).read_text())
        from BSplineCAM.core.program import rs274

        if rs274.available() or os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1":
            tools = {int(tc.ToolNumber): float(tc.Tool.Diameter) for tc in job.Tools.Group}
            check = rs274.check(output, tools)
            self.assertTrue(check.ok, check.message)  # the program a controller would run
        self.assertEqual(set(os.listdir(os.getcwd())) - cwd_before, set())
        Path(output).unlink()

        # save, close, reopen, Verify again
        job, = self.reopen("part-job.FCStd", job)
        self.assertEqual(touched(self.doc), [])
        again = self.verify(job)
        self.assertAlmostEqual(json.loads(again.Metrics)["gouge_max_mm"], metrics["gouge_max_mm"],
                               places=6)
        text = report_text()
        for bad in ("Traceback", "Touched", "Error"):
            self.assertNotIn(bad, text)

    def verify(self, job):
        """Verify G-code... on the selected job; the simulated part it made."""
        from BSplineCAM.app import verify_feature as vf

        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        self.assertTrue(is_active("BSplineCAM_Verify"))
        before = {o.Name for o in self.doc.Objects}
        clear_report()
        with message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_Verify")
            process_events()
        self.assertEqual(boxes, [])
        made = [o for o in self.doc.Objects if o.Name not in before and vf.is_verification(o)]
        self.assertEqual(len(made), 1, (made, report_text()))
        self.assertNotIn("Traceback", report_text())
        if FreeCADGui.Control.activeDialog():
            FreeCADGui.Control.closeDialog()
        process_events()
        return made[0]

    def picture(self, result) -> None:
        """part_verify.png: the bench with the simulated part coloured by deviation and the
        stock after roughing hidden; only the part's mesh is drawn (no selection colour)."""
        from bsplinecam_gui import DOCS, bench_window, drawn_boxes, isometric_view, wait

        mw, mdi = bench_window()
        view = isometric_view(mdi)
        boxes = drawn_boxes(view, self.doc)
        boxes = {name: box for name, box in boxes.items()
                 if not self.doc.getObject(name).TypeId.startswith("App::")}
        job_axes = [n for n in boxes if hasattr(self.doc.getObject(n), "Operations")]
        for name in job_axes:
            boxes.pop(name)
        self.assertEqual(list(boxes), [result.Name])
        self.assertFalse(FreeCADGui.Selection.isSelected(result))
        view.viewIsometric()
        view.fitAll()
        wait(1000)
        DOCS.mkdir(parents=True, exist_ok=True)
        path = DOCS / "part_verify.png"
        self.assertTrue(QtGui.QApplication.primaryScreen().grabWindow(mw.winId())
                        .save(str(path), "PNG"))

    def bars_seen(self):
        """Every 10 ms while the workbench's progress bar runs: how many other progress bars
        the status bar shows (yields the list)."""
        import contextlib

        from PySide import QtCore

        from BSplineCAM.gui import progress_bar

        @contextlib.contextmanager
        def watching():
            seen: list = []

            def tick() -> None:
                if progress_bar.ProgressBar.active is not None:
                    seen.append(len(progress_bar.other_bars()))

            timer = QtCore.QTimer()
            timer.timeout.connect(tick)
            timer.start(10)
            try:
                yield seen
            finally:
                timer.stop()

        return watching()

    def modal_dialogs_accepted(self):
        """Accept any modal dialog (0.20's G-code editor) that a post opens meanwhile."""
        import contextlib

        from PySide import QtCore

        @contextlib.contextmanager
        def accepting():
            def accept() -> None:
                box = QtGui.QApplication.activeModalWidget()
                if isinstance(box, QtGui.QDialog) and not isinstance(box, QtGui.QMessageBox):
                    box.accept()

            timer = QtCore.QTimer()
            timer.timeout.connect(accept)
            timer.start(200)
            try:
                yield
            finally:
                timer.stop()

        return accepting()


if __name__ == "__main__":
    unittest.main()
