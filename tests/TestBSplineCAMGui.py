# SPDX-License-Identifier: LGPL-2.1-or-later
"""GUI tests of the BSplineCAM workbench, run inside a real FreeCAD GUI (under Xvfb).

``tools/run_gui_test.sh`` starts FreeCAD with ``tests/gui_run_tests.py``, which runs these
classes in FreeCAD's event loop, writes a JSON result and exits with its status.  The last
class saves ``docs/view3d.png`` (3D view) and ``docs/workbench.png`` (main window);
``TestCamCommands`` runs the job, post-process and verify commands on the case study (coarse
scallop) and saves ``docs/verify3d.png`` (simulated part) and ``docs/job.png`` (job tree).
File dialogs are replaced by fixed paths; error boxes are closed by a timer and recorded.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import sys
import tempfile
import unittest
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

try:
    import FreeCAD
except ImportError:  # a plain Python (the core's pytest run)
    raise unittest.SkipTest("needs the FreeCAD GUI: run tools/run_gui_test.sh") from None
if not FreeCAD.GuiUp:
    raise unittest.SkipTest("needs the FreeCAD GUI: run tools/run_gui_test.sh")

import FreeCADGui  # noqa: E402
from PySide import QtCore, QtGui  # noqa: E402

from BSplineCAM.app import importers  # noqa: E402
from BSplineCAM.app import surface_feature as sf  # noqa: E402
from BSplineCAM.core import Surface  # noqa: E402

CASE_STUDY = ROOT / "examples" / "case-study.json"
DOCS = Path(os.environ.get("BSPLINECAM_DOCS", ROOT / "docs"))
WORKBENCH = "BSplineCAMWorkbench"
#: Commands that need a selected surface, and the one that needs nothing.
SELECTION_COMMANDS = ("BSplineCAM_EditNet", "BSplineCAM_ExportDat", "BSplineCAM_ExportStep",
                      "BSplineCAM_PaperRoute")


def process_events(rounds: int = 5) -> None:
    for _ in range(rounds):
        QtGui.QApplication.processEvents()


def wait(ms: int) -> None:
    """Let FreeCAD's event loop run for ``ms`` milliseconds (toolbar state updates on timers)."""
    loop = QtCore.QEventLoop()
    QtCore.QTimer.singleShot(ms, loop.quit)
    loop.exec_()


def is_active(name: str) -> bool:
    """The command's IsActive as FreeCAD sees it."""
    return bool(FreeCADGui.Command.get(name).isActive())


@contextlib.contextmanager
def message_boxes() -> Iterator[list[str]]:
    """Close every modal message box that appears meanwhile; yield the texts they showed."""
    seen: list[str] = []

    def close_modal() -> None:
        box = QtGui.QApplication.activeModalWidget()
        if isinstance(box, QtGui.QMessageBox):
            seen.append(f"{box.windowTitle()}: {box.text()}")
            box.done(0)

    timer = QtCore.QTimer()
    timer.timeout.connect(close_modal)
    timer.start(100)
    try:
        yield seen
    finally:
        timer.stop()


@contextlib.contextmanager
def dialogs_answer(open_path: str = "", save_path: str = "") -> Iterator[None]:
    """Make the commands' file dialogs return fixed paths."""
    from BSplineCAM.gui import commands

    saved = commands.ask_open_file, commands.ask_save_file
    commands.ask_open_file = lambda *args: open_path
    commands.ask_save_file = lambda *args: save_path
    try:
        yield
    finally:
        commands.ask_open_file, commands.ask_save_file = saved


class GuiTestCase(unittest.TestCase):
    @classmethod
    def setUpClass(cls) -> None:
        FreeCADGui.activateWorkbench(WORKBENCH)
        process_events()

    def setUp(self) -> None:
        self.tmp = Path(tempfile.mkdtemp(prefix="bsplinecam-gui-"))
        self.doc = FreeCAD.newDocument(f"GuiTest{abs(hash(self.id())) % 100000}")
        self.doc_name = self.doc.Name
        FreeCAD.setActiveDocument(self.doc.Name)
        FreeCADGui.Selection.clearSelection()

    def tearDown(self) -> None:
        if FreeCADGui.Control.activeDialog():
            FreeCADGui.Control.closeDialog()
        FreeCADGui.Selection.clearSelection()
        if self.doc_name in FreeCAD.listDocuments():
            FreeCAD.closeDocument(self.doc_name)
        process_events()
        shutil.rmtree(self.tmp, ignore_errors=True)

    def new_surface(self):
        """Run BSplineCAM_NewSurface on the case study; the object it made."""
        before = {o.Name for o in self.doc.Objects}
        with dialogs_answer(open_path=str(CASE_STUDY)):
            FreeCADGui.runCommand("BSplineCAM_NewSurface")
        made = [o for o in self.doc.Objects if o.Name not in before]
        self.assertEqual(len(made), 1)
        return made[0]


class TestWorkbench(GuiTestCase):
    def test_start_up_imports_nothing(self) -> None:
        """InitGui registers the workbench without importing the package (fast start)."""
        startup = os.environ.get("BSPLINECAM_STARTUP_MODULES")
        if startup is None:
            self.skipTest("not started by tests/gui_run_tests.py")
        self.assertEqual(json.loads(startup), [])

    def test_workbench_commands_toolbar_menu(self) -> None:
        from BSplineCAM.gui import layout

        self.assertIn(WORKBENCH, FreeCADGui.listWorkbenches())
        self.assertEqual(FreeCADGui.activeWorkbench().name(), WORKBENCH)
        icon = FreeCADGui.listWorkbenches()[WORKBENCH].Icon
        self.assertTrue(os.path.isfile(icon), icon)
        registered = set(FreeCADGui.listCommands())
        for name in layout.SURFACE_COMMANDS + layout.TOOLPATH_COMMANDS + layout.VERIFY_COMMANDS:
            self.assertIn(name, registered)
            info = FreeCADGui.Command.get(name).getInfo()
            self.assertTrue(info["menuText"] and info["toolTip"], info)
            pixmap = FreeCADGui.Command.get(name).getInfo()["pixmap"]
            self.assertTrue(os.path.isfile(pixmap) and pixmap.endswith(".svg"), pixmap)
        bars = FreeCADGui.getMainWindow().findChildren(QtGui.QToolBar)
        toolbars = {tb.windowTitle() for tb in bars if tb.isVisible()}
        for title in ("BSplineCAM surface", "BSplineCAM toolpath", "BSplineCAM verify"):
            self.assertIn(title, toolbars)
        menus = [a.text() for a in FreeCADGui.getMainWindow().menuBar().actions()]
        self.assertIn("&BSplineCAM", menus)
        self.assertEqual(layout.TOOLPATH_COMMANDS, ["BSplineCAM_Job", "BSplineCAM_PostProcess"])
        self.assertEqual(layout.VERIFY_COMMANDS, ["BSplineCAM_Verify"])

    def test_is_active(self) -> None:
        self.assertTrue(is_active("BSplineCAM_NewSurface"))
        for name in (*SELECTION_COMMANDS, "BSplineCAM_CrossCheck"):
            self.assertFalse(is_active(name), f"{name} active in an empty document")
        obj = self.new_surface()
        FreeCADGui.Selection.clearSelection()
        self.assertTrue(is_active("BSplineCAM_CrossCheck"))  # all surfaces of the document
        for name in SELECTION_COMMANDS:
            self.assertFalse(is_active(name), f"{name} active without a selection")
        FreeCADGui.Selection.addSelection(obj)
        for name in (*SELECTION_COMMANDS, "BSplineCAM_CrossCheck", "BSplineCAM_NewSurface"):
            self.assertTrue(is_active(name), f"{name} inactive with a surface selected")
        FreeCAD.closeDocument(self.doc.Name)
        process_events()
        self.assertTrue(is_active("BSplineCAM_NewSurface"))
        for name in SELECTION_COMMANDS:
            self.assertFalse(is_active(name), f"{name} active without a document")


class TestSurfaceCommands(GuiTestCase):
    def test_new_surface_view_provider_and_undo(self) -> None:
        obj = self.new_surface()
        self.assertTrue(sf.is_surface(obj))
        self.assertTrue(obj.isValid())
        vobj = obj.ViewObject
        self.assertEqual(type(vobj.Proxy).__name__, "SurfaceViewProvider")
        self.assertTrue(vobj.ShowControlNet)
        self.assertEqual(vobj.Proxy.switch.whichChild.getValue(), 0)
        self.assertEqual(vobj.Proxy.coords.point.getNum(), 100)
        vobj.ShowControlNet = False
        self.assertEqual(vobj.Proxy.switch.whichChild.getValue(), -1)
        vobj.ShowControlNet = True
        self.assertEqual(FreeCADGui.Selection.getSelection(), [obj])
        name = obj.Name
        self.doc.undo()
        self.assertIsNone(self.doc.getObject(name), "undo did not remove the new surface")
        self.doc.redo()
        self.assertIsNotNone(self.doc.getObject(name))

    def test_save_reopen_restores_view_provider(self) -> None:
        obj = self.new_surface()
        obj.ViewObject.ShowControlNet = False
        obj.ViewObject.ControlNetColor = (0.0, 0.5, 0.0)
        name = obj.Name
        path = self.tmp / "gui.FCStd"
        self.doc.saveAs(str(path))
        FreeCAD.closeDocument(self.doc.Name)
        process_events()
        self.doc = FreeCAD.openDocument(str(path))
        self.doc_name = self.doc.Name
        obj = self.doc.getObject(name)
        vobj = obj.ViewObject
        self.assertEqual(type(vobj.Proxy).__name__, "SurfaceViewProvider")
        self.assertFalse(vobj.ShowControlNet)
        self.assertEqual(vobj.Proxy.switch.whichChild.getValue(), -1)
        self.assertAlmostEqual(vobj.ControlNetColor[1], 0.5, places=2)
        self.assertEqual(vobj.Proxy.coords.point.getNum(), 100)
        vobj.ShowControlNet = True
        self.assertEqual(vobj.Proxy.switch.whichChild.getValue(), 0)

    def test_bad_file_gives_message_and_no_change(self) -> None:
        bad = self.tmp / "ragged.json"
        bad.write_text('{"control_points": [[[0, 0, 0], [1, 0, 0]]]}', encoding="utf-8")
        self.new_surface()
        names = [o.Name for o in self.doc.Objects]
        undo = self.doc.UndoCount
        with message_boxes() as boxes, dialogs_answer(open_path=str(bad)):
            FreeCADGui.runCommand("BSplineCAM_NewSurface")
            process_events()
        self.assertEqual(len(boxes), 1, boxes)
        self.assertIn("ragged.json", boxes[0])
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        self.assertEqual(self.doc.UndoCount, undo)
        # FreeCAD's own import route (FreeCAD.loadFile → module.insert, as the Import dialog;
        # .csv is ours alone, .json/.dat are shared with Fem and Draft, so name the module)
        bad_csv = self.tmp / "words.csv"
        bad_csv.write_text("row,col,x,y,z\n0,0,a,b,c\n", encoding="utf-8")
        for module_call in (lambda: FreeCAD.loadFile(str(bad_csv), self.doc.Name),
                            lambda: FreeCAD.loadFile(str(bad), self.doc.Name, importers.__name__)):
            with message_boxes() as boxes:
                module_call()
                process_events()
            self.assertEqual(len(boxes), 1, boxes)
            self.assertEqual([o.Name for o in self.doc.Objects], names)

    def test_import_routes(self) -> None:
        self.assertIn("BSplineCAM.app.importers", FreeCAD.getImportType("json"))
        self.assertIn("BSplineCAM.app.importers", FreeCAD.getImportType("dat"))
        self.assertIn("BSplineCAM.app.importers", FreeCAD.getExportType("csv"))
        csv = self.tmp / "case.csv"
        importers.write_surface(Surface.from_json(CASE_STUDY), csv)
        FreeCAD.loadFile(str(csv), self.doc.Name)
        FreeCAD.loadFile(str(CASE_STUDY), self.doc.Name, importers.__name__)
        surfaces = sf.surfaces_in(self.doc.Objects)
        self.assertEqual(len(surfaces), 2)
        for obj in surfaces:
            self.assertEqual(type(obj.ViewObject.Proxy).__name__, "SurfaceViewProvider")
            self.assertTrue(obj.isValid())

    def test_edit_net_cancel_restores_ok_keeps(self) -> None:
        obj = self.new_surface()
        original = [tuple(v) for v in obj.ControlPoints]
        top = obj.Shape.BoundBox.ZMax
        FreeCADGui.Selection.addSelection(obj)
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        process_events()
        self.assertTrue(FreeCADGui.Control.activeDialog())
        self.assertFalse(is_active("BSplineCAM_EditNet"))
        panel = obj.ViewObject.Proxy.panel
        panel.set_cell(4, 4, 2, 80.0)  # live preview: the object follows the table
        self.assertEqual(obj.ControlPoints[44].z, 80.0)
        self.assertGreater(obj.Shape.BoundBox.ZMax, top + 10)
        panel.reject()
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())
        self.assertEqual([tuple(v) for v in obj.ControlPoints], original)
        self.assertAlmostEqual(obj.Shape.BoundBox.ZMax, top, places=9)

        FreeCADGui.Selection.addSelection(obj)
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        panel = obj.ViewObject.Proxy.panel
        panel.set_cell(4, 4, 2, 80.0)
        panel.knots.setCurrentIndex(panel.knots.findText("uniform"))
        panel.accept()
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())
        self.assertEqual(obj.ControlPoints[44].z, 80.0)
        self.assertEqual(obj.Knots, "uniform")
        self.assertTrue(obj.isValid())
        self.assertNotIn("Touched", obj.State)

    def test_crosscheck_exports_paper_route(self) -> None:
        obj = self.new_surface()
        FreeCADGui.Selection.addSelection(obj)
        FreeCADGui.runCommand("BSplineCAM_CrossCheck")
        report = json.loads(obj.CrossCheck)
        self.assertTrue(report["exact_route_ok"], report)
        dat = self.tmp / "points.dat"
        step = self.tmp / "surface.step"
        with dialogs_answer(save_path=str(dat)):
            FreeCADGui.runCommand("BSplineCAM_ExportDat")
        self.assertTrue(dat.is_file())
        with dialogs_answer(save_path=str(step)):
            FreeCADGui.runCommand("BSplineCAM_ExportStep")
        import Part

        self.assertEqual(len(Part.read(str(step)).Faces), 1)
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(obj)
        with dialogs_answer(open_path=str(dat)):
            FreeCADGui.runCommand("BSplineCAM_PaperRoute")
        routes = [o for o in self.doc.Objects if hasattr(o, "MaxDeviation")]
        self.assertEqual(len(routes), 1)
        self.assertTrue(1e-4 < float(routes[0].MaxDeviation) < 1.0, routes[0].MaxDeviation)


#: A coarse scallop keeps the GUI test fast (mm).
COARSE_SCALLOP = 0.1
TOOL = 6.0


@contextlib.contextmanager
def cam_dialogs(post: str = "", save_path: str = "", open_path: str = "",
                tool: float = TOOL) -> Iterator[None]:
    """Make the machining commands' dialogs answer fixed values."""
    from BSplineCAM.gui import cam_commands

    saved = cam_commands.ask_post, cam_commands.ask_tool_diameter
    cam_commands.ask_post = lambda posts: post
    cam_commands.ask_tool_diameter = lambda: tool
    try:
        with dialogs_answer(open_path=open_path, save_path=save_path):
            yield
    finally:
        cam_commands.ask_post, cam_commands.ask_tool_diameter = saved


def isometric_view(mdi):
    """The active 3D view maximised, nothing selected, isometric and fitted (and DOCS made)."""
    FreeCADGui.Selection.clearSelection()
    mdi.activeSubWindow().showMaximized()
    process_events(20)
    view = FreeCADGui.activeDocument().activeView()
    view.viewIsometric()
    view.fitAll()
    process_events(20)
    DOCS.mkdir(parents=True, exist_ok=True)
    return view


def tree_dock(mw):
    """The dock showing the document tree, brought to the front: "Combo View" in FreeCAD 0.20,
    a "Model" dock tabbed with "Tasks" in 1.0."""
    docks = [mw.findChild(QtGui.QDockWidget, name) for name in ("Combo View", "Model")]
    docks += [d for d in mw.findChildren(QtGui.QDockWidget) if d.findChildren(QtGui.QTreeWidget)]
    for dock in docks:
        if dock is not None and dock.findChildren(QtGui.QTreeWidget):
            dock.show()
            dock.raise_()
            return dock
    return None


def count_colours(image, step: int = 4) -> dict[str, int]:
    """Pixels (every ``step``-th) that are white, green, blue or red in a QImage.

    Colours are told by hue, so the shading of a FreeCAD version's lights (1.0 renders darker
    than 0.20) does not change the class; grey and near-black pixels count as none.
    """
    counts = {"white": 0, "green": 0, "blue": 0, "red": 0}
    for x in range(0, image.width(), step):
        for y in range(0, image.height(), step):
            c = QtGui.QColor(image.pixel(x, y))
            if c.red() > 245 and c.green() > 245 and c.blue() > 245:
                counts["white"] += 1
                continue
            hue, sat, val = c.hsvHue(), c.hsvSaturation(), c.value()
            if sat < 90 or val < 40 or hue < 0:
                continue
            if 75 <= hue <= 165:
                counts["green"] += 1
            elif 195 <= hue <= 260:
                counts["blue"] += 1
            elif hue <= 15 or hue >= 345:
                counts["red"] += 1
    return counts


class CamTestCase(GuiTestCase):
    def open_job_panel(self, surface):
        from BSplineCAM.gui import cam_commands

        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        cam_commands.JobPanel.last = None
        FreeCADGui.runCommand("BSplineCAM_Job")
        process_events()
        panel = cam_commands.JobPanel.last
        self.assertIsNotNone(panel, "the job command opened no task panel")
        self.assertTrue(FreeCADGui.Control.activeDialog())
        self.assertFalse(is_active("BSplineCAM_Job"))  # one task panel at a time
        panel.tool.setValue(TOOL)
        panel.scallop.setValue(COARSE_SCALLOP)
        return panel

    def make_job(self):
        """Surface, then the job command with a coarse scallop; (surface, job, op)."""
        from BSplineCAM.gui import cam_commands

        surface = self.new_surface()
        panel = self.open_job_panel(surface)
        undo = self.doc.UndoCount
        with message_boxes() as boxes:
            accepted = panel.accept()
        if not accepted:
            self.fail(f"the job panel refused: {panel.message.text()} {boxes}")
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())
        self.assertEqual(self.doc.UndoCount, undo + 1)  # one transaction
        jobs = [o for o in self.doc.Objects if cam_commands.is_job(o)]
        ops = [o for o in self.doc.Objects if cam_commands.is_finishing_op(o)]
        self.assertEqual((len(jobs), len(ops)), (1, 1))
        return surface, jobs[0], ops[0]


class TestCamCommands(CamTestCase):
    def test_is_active(self) -> None:
        names = ("BSplineCAM_Job", "BSplineCAM_PostProcess", "BSplineCAM_Verify")
        for name in names:
            self.assertFalse(is_active(name), f"{name} active in an empty document")
        surface = self.new_surface()
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        self.assertTrue(is_active("BSplineCAM_Job"))
        self.assertTrue(is_active("BSplineCAM_Verify"))  # a G-code file on the surface
        self.assertFalse(is_active("BSplineCAM_PostProcess"))

    def test_job_panel_validation_and_interruption(self) -> None:
        from BSplineCAM.app import progress
        from BSplineCAM.core.toolpath.common import ToolpathCancelled

        surface = self.new_surface()
        names = [o.Name for o in self.doc.Objects]
        undo = self.doc.UndoCount
        panel = self.open_job_panel(surface)
        panel.scallop.setValue(0.0)
        with message_boxes() as boxes:
            self.assertFalse(panel.accept())
            process_events()
        self.assertIn("scallop", panel.message.text().lower())
        self.assertEqual(len(boxes), 1, boxes)
        panel.scallop.setValue(COARSE_SCALLOP)
        panel.spindle.setValue(0.0)
        with message_boxes() as boxes:
            self.assertFalse(panel.accept())
        self.assertIn("spindle speed", panel.message.text())
        panel.spindle.setValue(12000.0)
        self.assertEqual([o.Name for o in self.doc.Objects], names)

        # the user interrupts the computation at 30 %: everything is undone
        def interrupting(obj):
            def report(fraction: float) -> None:
                if fraction > 0.3:
                    raise ToolpathCancelled("interrupted by the user at 30%")
            return report

        saved = progress.op_progress
        progress.op_progress = interrupting
        try:
            self.assertFalse(panel.accept())
        finally:
            progress.op_progress = saved
        process_events()
        self.assertIn("nterrupted", panel.message.text())
        self.assertTrue(FreeCADGui.Control.activeDialog())  # the panel stays for a retry
        self.assertEqual([o.Name for o in self.doc.Objects], names)
        self.assertEqual(self.doc.UndoCount, undo)
        self.assertFalse(surface.MakeSolid)
        self.assertTrue(surface.isValid())
        panel.reject()
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())

    def test_job_post_verify(self) -> None:
        from BSplineCAM import rs274
        from BSplineCAM.app import verify_feature as vf
        from BSplineCAM.gui import cam_commands

        surface, job, op = self.make_job()
        self.assertTrue(surface.MakeSolid)
        self.assertEqual(type(job.ViewObject.Proxy).__name__, "ViewProvider")
        self.assertIn(op, job.Operations.Group)
        self.assertTrue(op.isValid())
        report = json.loads(op.Report)
        self.assertEqual(report["strategy"], "raster")
        self.assertGreater(len(op.Path.Commands), 100)
        tc = job.Tools.Group[0]
        self.assertAlmostEqual(float(tc.Tool.Diameter), TOOL)
        self.assertAlmostEqual(tc.HorizFeed.getValueAs("mm/min").Value, 1200.0, places=3)
        self.assertAlmostEqual(float(tc.SpindleSpeed), 12000.0)

        # post-processing, checked by rs274
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(op)  # the op stands for its job
        self.assertTrue(is_active("BSplineCAM_PostProcess"))
        programs = {}
        for post in ("linuxcnc", "grbl"):
            path = self.tmp / f"job-{post}.ngc"
            cam_commands.PostProcess.last_check = None
            with cam_dialogs(post=post, save_path=str(path)), message_boxes() as boxes:
                FreeCADGui.runCommand("BSplineCAM_PostProcess")
            self.assertEqual(boxes, [])
            self.assertTrue(path.is_file(), path)
            self.assertIn("G1", path.read_text())
            programs[post] = path
            if rs274.available():
                check = cam_commands.PostProcess.last_check
                self.assertTrue(check and check["ok"], check)
                self.assertGreater(check["straight_feeds"], 100)
        self.assertTrue(rs274.available() or os.environ.get("BSPLINECAM_NO_RS274"),
                        "rs274 is not installed (set BSPLINECAM_NO_RS274=1 to allow)")

        # verification of the job: a simulated part coloured by deviation
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(job)
        before = {o.Name for o in self.doc.Objects}
        with message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_Verify")
        self.assertEqual(boxes, [])
        made = [o for o in self.doc.Objects if o.Name not in before]
        self.assertEqual(len(made), 1, made)
        result = made[0]
        self.assertTrue(vf.is_verification(result))
        self.assertIs(result.Job, job)
        metrics = json.loads(result.Metrics)
        self.assertLess(metrics["gouge_max_mm"], 0.01)
        self.assertLess(metrics["scallop_p99_mm"], 1.5 * COARSE_SCALLOP)
        self.assertGreater(metrics["coverage"], 0.95)
        self.assertGreater(metrics["machining_time_s"], 0)
        vobj = result.ViewObject
        self.assertEqual(type(vobj.Proxy).__name__, "VerificationViewProvider")
        self.assertEqual(vobj.DisplayMode, "Deviation")
        count = result.Mesh.CountPoints
        self.assertEqual(vobj.Proxy.material.diffuseColor.getNum(), count)
        self.assertEqual(vobj.Proxy.coords.point.getNum(), count)
        colours = vobj.Proxy.colours
        top = colours[:result.GridRows * result.GridColumns]
        green = (top[:, 1] > 0.5) & (top[:, 2] < 0.5)
        blue = top[:, 2] > 0.6
        self.assertGreater(green.mean(), 0.2)  # passes touch the design
        self.assertGreater(blue.mean(), 0.02)  # scallops left between passes
        self.assertFalse(op.ViewObject.Visibility)  # paths hidden: the part shows
        self.assertTrue(vobj.Visibility)

        # the file route: a program on the selected surface
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(surface)
        before = {o.Name for o in self.doc.Objects}
        with cam_dialogs(open_path=str(programs["grbl"])), message_boxes() as boxes:
            FreeCADGui.runCommand("BSplineCAM_Verify")
        self.assertEqual(boxes, [])
        made = [o for o in self.doc.Objects if o.Name not in before]
        self.assertEqual(len(made), 1, made)
        self.assertEqual(made[0].Program, str(programs["grbl"]))
        other = json.loads(made[0].Metrics)
        self.assertAlmostEqual(other["cutting_length_mm"], metrics["cutting_length_mm"], places=2)
        made[0].ViewObject.Visibility = False
        # the surface's control net is drawn outside its display modes: hiding the surface
        # does not hide the net (surface_view), so switch it off for the pictures
        surface.ViewObject.ShowControlNet = False
        self.screenshots(job, op, result)

    def screenshots(self, job, op, result) -> None:
        """docs/verify3d.png (the coloured part) and docs/job.png (the bench with the job)."""
        mw = FreeCADGui.getMainWindow()
        mw.showNormal()
        mw.setGeometry(0, 0, 1600, 1000)
        mdi = mw.findChild(QtGui.QMdiArea)
        for sub in mdi.subWindowList():
            if sub.windowTitle().startswith("Start page"):
                sub.close()
        view = isometric_view(mdi)
        verify3d = DOCS / "verify3d.png"
        view.saveImage(str(verify3d), 1600, 1000, "White")
        counts = count_colours(QtGui.QImage(str(verify3d)))
        total = sum(1 for _ in range(0, 1600, 4)) * sum(1 for _ in range(0, 1000, 4))
        self.assertGreater(counts["green"], total * 0.05, counts)
        self.assertGreater(counts["blue"], total * 0.003, counts)  # scallop crests
        self.assertGreater(counts["white"], total * 0.2, counts)

        # the workbench with the job's tree open, the op's paths shown and selected
        result.ViewObject.Visibility = False
        op.ViewObject.Visibility = True
        for model in job.Model.Group:
            model.ViewObject.Visibility = True
            model.ViewObject.Transparency = 40  # CAM's 80 % leaves it invisible in a picture
        combo = tree_dock(mw)
        if combo is not None:
            mw.resizeDocks([combo], [430], QtCore.Qt.Horizontal)
            for tree in combo.findChildren(QtGui.QTreeWidget):
                tree.expandToDepth(3)  # the job and its groups, not the bit's body
        report = mw.findChild(QtGui.QDockWidget, "Report view")
        if report is not None:
            report.show()
        FreeCADGui.Selection.addSelection(op)
        view.viewIsometric()
        view.fitAll()
        wait(1500)
        job_png = DOCS / "job.png"
        screen = QtGui.QApplication.primaryScreen()
        self.assertTrue(screen.grabWindow(mw.winId()).save(str(job_png), "PNG"))
        for path in (verify3d, job_png):
            self.assertTrue(path.is_file() and path.stat().st_size > 10000, path)


class TestZScreenshots(GuiTestCase):
    """Last: the documentation pictures, with a check that the view is not empty."""

    def test_screenshots(self) -> None:
        mw = FreeCADGui.getMainWindow()
        mw.showNormal()
        mw.setGeometry(0, 0, 1600, 1000)
        mdi = mw.findChild(QtGui.QMdiArea)
        for sub in mdi.subWindowList():
            if sub.windowTitle().startswith("Start page"):
                sub.close()
        combo = tree_dock(mw)
        if combo is not None:
            mw.resizeDocks([combo], [430], QtCore.Qt.Horizontal)
        report = mw.findChild(QtGui.QDockWidget, "Report view")
        if report is not None:
            report.show()
            report.findChild(QtGui.QTextEdit).clear()  # start-up warnings are not ours
        obj = self.new_surface()
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(obj)
        FreeCADGui.runCommand("BSplineCAM_CrossCheck")  # its report in the report view
        view = isometric_view(mdi)
        view3d = DOCS / "view3d.png"
        view.saveImage(str(view3d), 1600, 1000, "White")
        # the main window, grabbed from the X screen because QWidget.grab() leaves OpenGL
        # views empty: first with the surface selected (all commands enabled, its properties
        # shown), then with the net editor open
        screen = QtGui.QApplication.primaryScreen()
        FreeCADGui.Selection.addSelection(obj)
        wait(1500)
        workbench = DOCS / "workbench.png"
        self.assertTrue(screen.grabWindow(mw.winId()).save(str(workbench), "PNG"))
        FreeCADGui.runCommand("BSplineCAM_EditNet")
        FreeCADGui.Selection.clearSelection()
        view.viewIsometric()
        view.fitAll()
        wait(1500)
        editor = DOCS / "net_editor.png"
        self.assertTrue(screen.grabWindow(mw.winId()).save(str(editor), "PNG"))
        obj.ViewObject.Proxy.panel.reject()
        process_events()
        for path in (view3d, workbench, editor):
            self.assertTrue(path.is_file() and path.stat().st_size > 10000, path)
        image = QtGui.QImage(str(view3d))
        self.assertEqual((image.width(), image.height()), (1600, 1000))
        counts = {"white": 0, "net": 0, "surface": 0}
        for x in range(0, 1600, 8):
            for y in range(0, 1000, 8):
                c = QtGui.QColor(image.pixel(x, y))
                r, g, b = c.red(), c.green(), c.blue()
                if r > 245 and g > 245 and b > 245:
                    counts["white"] += 1
                elif r > 150 and g < 100 and b < 100:
                    counts["net"] += 1
                elif b > r + 30:
                    counts["surface"] += 1
        total = (1600 // 8) * (1000 // 8)
        self.assertGreater(counts["surface"], total * 0.05, counts)  # surface visible
        self.assertGreater(counts["net"], 20, counts)  # control net drawn
        self.assertGreater(counts["white"], total * 0.2, counts)  # fitted, not clipped
