# SPDX-License-Identifier: LGPL-2.1-or-later
"""GUI tests of the BSplineCAM workbench, run inside a real FreeCAD GUI (under Xvfb).

``tools/run_gui_test.sh`` starts FreeCAD with ``tests/gui_run_tests.py``, which runs these
classes in FreeCAD's event loop, writes a JSON result and exits with its status.  The last
class saves ``view3d.png`` (3D view) and ``workbench.png`` (main window);
``TestCamCommands`` runs the job, post-process and verify commands on the case study (coarse
scallop) and saves ``verify3d.png`` (simulated part) and ``job.png`` (job tree), all in
:data:`bsplinecam_gui.DOCS` (build/screenshots; ``make screenshots`` refreshes docs/).
File dialogs are replaced by fixed paths; error boxes are closed by a timer and recorded.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
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
from bsplinecam_gui import (  # noqa: E402
    CASE_STUDY,
    COARSE_SCALLOP,
    DOCS,
    PICTURE,
    TOOL,
    WORKBENCH,
    CamTestCase,
    GuiTestCase,
    PictureChecks,
    bench_window,
    box_corners,
    clear_report,
    dialogs_answer,
    drawn_boxes,
    in_scene,
    is_active,
    isometric_view,
    message_boxes,
    process_events,
    report_text,
    scene_box,
    wait,
)
from PySide import QtCore, QtGui  # noqa: E402

from BSplineCAM.app import importers  # noqa: E402
from BSplineCAM.app import surface_feature as sf  # noqa: E402
from BSplineCAM.core import Surface  # noqa: E402

#: Commands that need a selected surface, and the one that needs nothing.
SELECTION_COMMANDS = ("BSplineCAM_EditNet", "BSplineCAM_ExportDat", "BSplineCAM_ExportStep",
                      "BSplineCAM_PaperRoute")


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
        self.assertEqual(layout.TOOLPATH_COMMANDS, ["BSplineCAM_Job", "BSplineCAM_Rough", "BSplineCAM_PostProcess"])
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
        (obj,) = self.reopen("gui.FCStd", obj)
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


#: A fine scallop takes seconds (to cancel); COARSE_SCALLOP keeps the GUI test fast (mm).
FINE_SCALLOP = 0.005


@contextlib.contextmanager
def timed_during_computation(action, after: float = 0.05) -> Iterator[list]:
    """A timer ticking every 10 ms meanwhile; yield its ticks as (computing, fraction).

    Once a computation (a status-bar progress bar) has passed ``after`` of its work,
    ``action(bar)`` runs once, from the timer, as a user's click would.
    """
    from BSplineCAM.gui import progress_bar

    ticks: list = []
    done: list = []

    def tick() -> None:
        bar = progress_bar.ProgressBar.active
        ticks.append((bar is not None, bar.fraction if bar is not None else None))
        if bar is not None and bar.fraction > after and not done:
            done.append(bar.fraction)
            action(bar)

    timer = QtCore.QTimer()
    timer.timeout.connect(tick)
    timer.start(10)
    try:
        yield ticks
    finally:
        timer.stop()


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


def drawn_of_type(root, type_name: str) -> int:
    """How many nodes of a Coin type are drawn under ``root`` (switches followed)."""
    from pivy import coin

    search = coin.SoSearchAction()
    search.setType(coin.SoType.fromName(type_name))
    search.setInterest(coin.SoSearchAction.ALL)
    search.apply(root)
    return search.getPaths().getLength()


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
        from BSplineCAM.gui import progress_bar

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

        # the user clicks Cancel in the status bar while the toolpath computes (a fine
        # scallop: seconds of work): everything is undone
        panel.scallop.setValue(FINE_SCALLOP)
        with timed_during_computation(lambda bar: progress_bar.StatusWidgets.button.click()) \
                as ticks:
            self.assertFalse(panel.accept())
        process_events()
        self.assertTrue(any(computing for computing, _ in ticks), ticks)  # fired meanwhile
        last = progress_bar.ProgressBar.last
        self.assertTrue(last.cancelled)
        self.assertLess(last.fraction, 1.0)
        self.assertLessEqual(last.calls - last.calls_at_cancel, 1)  # its next report stopped it
        self.assertIsNone(progress_bar.ProgressBar.active)
        self.assertFalse(progress_bar.StatusWidgets.bar.isVisible())
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
        import numpy as np
        from pivy import coin

        from BSplineCAM.app import verify_feature as vf
        from BSplineCAM.core.program import rs274
        from BSplineCAM.gui import cam_commands, verify_view

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
        # the Coin nodes draw those colours, one per vertex, and each as the deviation says
        proxy = vobj.Proxy
        drawn = np.array([c.getValue() for c in proxy.material.diffuseColor.getValues()])
        np.testing.assert_allclose(drawn, colours, atol=1e-6)
        self.assertEqual(proxy.binding.value.getValue(),
                         coin.SoMaterialBinding.PER_VERTEX_INDEXED)
        self.assertEqual(list(proxy.faces.materialIndex.getValues()),
                         list(proxy.faces.coordIndex.getValues()))
        band, scallop, gouge = proxy.scale
        self.assertAlmostEqual(band, vobj.Band)
        self.assertAlmostEqual(scallop, max(metrics["scallop_p99_mm"], 2 * band))
        self.assertAlmostEqual(gouge, max(metrics["gouge_max_mm"], 2 * band))
        deviation = vf.deviation_of(result)
        self.assertEqual(len(deviation), len(top))
        on_design = np.abs(deviation) <= band
        left = deviation >= scallop
        gouged = deviation < -band
        between = (deviation > band) & (deviation < scallop)
        self.assertGreater(on_design.mean(), 0.2)
        self.assertTrue(left.any())
        np.testing.assert_allclose(top[on_design], np.broadcast_to(verify_view.GREEN,
                                                                    top[on_design].shape))
        np.testing.assert_allclose(top[left], np.broadcast_to(verify_view.BLUE,
                                                               top[left].shape))
        self.assertTrue(np.all(top[between, 2] > verify_view.GREEN[2]))  # towards blue
        self.assertTrue(np.all(top[gouged, 0] > verify_view.GREEN[0]))  # towards red
        self.assertFalse(op.ViewObject.Visibility)  # paths hidden: the part shows
        self.assertTrue(vobj.Visibility)
        # the status bar's progress bar went away with the computation
        from BSplineCAM.gui import progress_bar, results_panel

        self.assertFalse(progress_bar.StatusWidgets.bar.isVisible())
        self.assertIsNone(progress_bar.ProgressBar.active)
        # the figures in a task panel, selectable and copyable

        panel = results_panel.ResultsPanel.last
        self.assertIsNotNone(panel)
        self.assertTrue(FreeCADGui.Control.activeDialog())
        text = panel.figures.toPlainText()
        for figure in (f"{metrics['gouge_max_mm']:.4f} mm", f"{metrics['scallop_max_mm']:.4f}",
                       f"{metrics['scallop_p99_mm']:.4f} mm", f"{100 * metrics['coverage']:.2f} %",
                       "machining time"):
            self.assertIn(figure, text)
        self.assertTrue(panel.figures.isReadOnly())
        self.assertTrue(panel.figures.textInteractionFlags() & QtCore.Qt.TextSelectableByMouse)
        # no chatter of FreeCAD's post scripts in the report view
        for noise in ("Show editor", "postprocessing"):
            self.assertNotIn(noise, report_text())

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
        self.screenshots(job, op, result, hidden=made[0])

    def assert_screen_space_legend(self, view, proxy) -> None:
        """The colour bar hangs under an orthographic camera of its own (LEAVE_ALONE), in an
        annotation inside a group fitAll skips: zooming the view moves the part on screen,
        not the bar."""
        from pivy import coin

        search = coin.SoSearchAction()
        search.setNode(proxy.legend_coords)
        search.apply(view.getSceneGraph())
        path = search.getPath()
        self.assertIsNotNone(path)
        chain = [path.getNode(i) for i in range(path.getLength())]
        names = [n.getTypeId().getName() for n in chain]
        self.assertIn("SoSkipBoundingGroup", names)
        annotations = [n for n in chain if n.isOfType(coin.SoAnnotation.getClassTypeId())]
        self.assertEqual(len(annotations), 1, names)
        camera = annotations[0].getChild(0)
        self.assertTrue(camera.isOfType(coin.SoOrthographicCamera.getClassTypeId()))
        self.assertEqual(camera.viewportMapping.getValue(), coin.SoCamera.LEAVE_ALONE)
        self.assertNotEqual(camera, view.getCameraNode())
        width, height = view.getSize()

        def on_screen(points, volume) -> list:
            return [tuple(round(c * s, 3) for c, s in zip(
                volume.projectToScreen(coin.SbVec3f(*p)).getValue()[:2], (width, height)))
                for p in points]

        bar = [p.getValue() for p in proxy.legend_coords.point.getValues()]
        corners = box_corners(*scene_box(view, proxy.root))
        main = view.getCameraNode()
        hud_before = on_screen(bar, camera.getViewVolume(0.0))
        part_before = on_screen(corners, main.getViewVolume(width / height))
        xs = [x for x, _ in hud_before]
        ys = [y for _, y in hud_before]
        for x, y in hud_before:  # the bar within the view, at its left
            self.assertTrue(0 < x < 0.5 * width and 0 < y < height, (x, y))
        self.assertGreater(max(ys) - min(ys), 0.3 * height)
        view.zoomIn()
        view.zoomIn()
        process_events()
        hud_after = on_screen(bar, camera.getViewVolume(0.0))
        part_after = on_screen(corners, main.getViewVolume(width / height))
        self.assertEqual(hud_after, hud_before)  # same pixels after zooming
        self.assertNotEqual(part_after, part_before)  # while the part grew on screen
        self.assertGreater(max(x for x, _ in part_after) - min(x for x, _ in part_after),
                           max(x for x, _ in part_before) - min(x for x, _ in part_before))
        self.assertEqual(len(xs), 8)
        view.fitAll()
        process_events()

    def screenshots(self, job, op, result, hidden) -> None:
        """docs/verify3d.png (the coloured part) and docs/job.png (the bench with the job).

        What the 3D view shows is checked on the scene graph and the camera: the part's
        Deviation nodes are drawn and no other object draws anything (but CAM's job axes), the
        legend is fixed to the screen, fitAll frames the part; the picture only where renderers
        agree.
        """
        mw, mdi = bench_window()
        view = isometric_view(mdi)
        vobj, proxy = result.ViewObject, result.ViewObject.Proxy
        # drawn: the object's root, its display-mode switch on the Deviation node, the legend
        self.assertTrue(in_scene(view, vobj.RootNode))
        switch = vobj.SwitchNode
        self.assertEqual(switch.whichChild.getValue(), switch.findChild(proxy.root))
        for node in (proxy.root, proxy.faces, proxy.side_faces, proxy.legend):
            self.assertTrue(in_scene(view, node), node)
        # the file route's verification is hidden: in the scene graph, not drawn
        self.assertTrue(in_scene(view, hidden.ViewObject.Proxy.root, drawn_only=False))
        self.assertFalse(in_scene(view, hidden.ViewObject.Proxy.root))
        # with the legend off, only the part's mesh is drawn: the verify command hid the
        # design, the model, the stock and the paths.  (FreeCAD 1.0's CAM draws a job's origin
        # axes while the job is visible: not ours, at the origin, and allowed for.)
        mesh_box = result.Mesh.BoundBox
        vobj.ShowLegend = False
        process_events()
        self.assertFalse(in_scene(view, proxy.legend))
        boxes = drawn_boxes(view, self.doc)
        job_axes = boxes.pop(job.Name, None)
        if job_axes is not None:
            self.assertTrue(all(lo <= 0 <= hi for lo, hi in zip(*job_axes)), job_axes)
        self.assertEqual(list(boxes), [result.Name])
        # the mesh spans the design's x/y (its vertices stand on Z-map cells, at most a cell
        # and a stride in from the design's edges)
        low, high = boxes[result.Name]
        self.assert_box_close(low, high, mesh_box, tol=1e-3)
        self.assert_box_close(low, high, result.Surface.Shape.BoundBox,
                              tol=float(result.Cell) * max(int(result.Stride), 1), axes="xy")
        # with the legend: a colour bar fixed to the screen, left out of the part's box
        vobj.ShowLegend = True
        process_events()
        self.assertTrue(in_scene(view, proxy.legend))
        self.assert_screen_space_legend(view, proxy)
        self.assert_box_close(*scene_box(view, vobj.RootNode), mesh_box, tol=1e-3)
        # the camera frames all the scene draws (the part, its legend and any job axes)
        low, high = scene_box(view)
        self.assert_framed(view, low, high)  # fitted by isometric_view
        verify3d = DOCS / "verify3d.png"
        view.saveImage(str(verify3d), *PICTURE, "White")
        # points inside the block, just above its base and away from its walls: the part
        # covers them wherever the camera looks from
        inner = [(mesh_box.XMin + fx * mesh_box.XLength, mesh_box.YMin + fy * mesh_box.YLength,
                  mesh_box.ZMin + 0.01 * mesh_box.ZLength)
                 for fx in (0.25, 0.5, 0.75) for fy in (0.25, 0.5, 0.75)]
        self.assert_picture(view, verify3d, inner)
        # the bench with the part, its legend and the figures' task panel
        screen = QtGui.QApplication.primaryScreen()
        from BSplineCAM.gui import results_panel

        self.assertTrue(results_panel.show(results_panel.verification_panel(result)))
        view.viewIsometric()
        view.fitAll()
        wait(1500)
        results_png = DOCS / "verify_results.png"
        self.assertTrue(screen.grabWindow(mw.winId()).save(str(results_png), "PNG"))
        results_panel.close_results()
        process_events()
        self.assertFalse(FreeCADGui.Control.activeDialog())

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
        self.assertTrue(screen.grabWindow(mw.winId()).save(str(job_png), "PNG"))
        for path in (verify3d, job_png, results_png):
            self.assertTrue(path.is_file() and path.stat().st_size > 10000, path)


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


class TestZScreenshots(PictureChecks, GuiTestCase):
    """Last: the documentation pictures, with checks of what the 3D view draws."""

    def test_screenshots(self) -> None:
        mw, mdi = bench_window()
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
        self.check_surface_view(view, obj)
        view3d = DOCS / "view3d.png"
        view.saveImage(str(view3d), *PICTURE, "White")
        # on the picture: points of the surface and the control points (a 6-pixel dot, or the
        # surface in front of it)
        face = obj.Shape.Faces[0]
        u0, u1, v0, v1 = face.ParameterRange
        on_surface = [tuple(face.valueAt(u0 + fu * (u1 - u0), v0 + fv * (v1 - v0)))
                      for fu in (0.25, 0.5, 0.75) for fv in (0.25, 0.5, 0.75)]
        self.assert_picture(view, view3d, on_surface + [tuple(v) for v in obj.ControlPoints])
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

    def check_surface_view(self, view, obj) -> None:
        """The 3D view draws the surface's faces and its control net, and frames them."""
        from BSplineCAM.gui.surface_view import net_line_indices

        vobj, proxy = obj.ViewObject, obj.ViewObject.Proxy
        self.assertTrue(vobj.Visibility)
        self.assertTrue(in_scene(view, vobj.RootNode))
        # a display mode showing Part's faces, in the colour the view provider gave
        self.assertIn(vobj.DisplayMode, ("Flat Lines", "Shaded"))
        self.assertGreaterEqual(vobj.SwitchNode.whichChild.getValue(), 0)
        self.assertGreater(drawn_of_type(vobj.RootNode, "SoBrepFaceSet"), 0)
        for got, want in zip(vobj.ShapeColor[:3], (0.45, 0.62, 0.85)):
            self.assertAlmostEqual(got, want, places=2)
        # the control net: drawn, every row and column of the object's points, in its colour
        self.assertTrue(vobj.ShowControlNet)
        self.assertEqual(proxy.switch.whichChild.getValue(), 0)
        for node in (proxy.switch, proxy.coords, proxy.lines, proxy.points):
            self.assertTrue(in_scene(view, node), node)
        rows, cols = int(obj.Rows), int(obj.Columns)
        net = [tuple(v) for v in obj.ControlPoints]
        self.assertEqual(len(net), rows * cols)
        drawn = [tuple(p.getValue()) for p in proxy.coords.point.getValues()]
        self.assertEqual(len(drawn), len(net))
        for got, want in zip(drawn, net):
            for a, b in zip(got, want):
                self.assertAlmostEqual(a, b, places=3)
        self.assertEqual(list(proxy.lines.coordIndex.getValues()), net_line_indices(rows, cols))
        self.assertEqual(proxy.points.numPoints.getValue(), rows * cols)
        for got, want in zip(proxy.color.rgb[0].getValue(), vobj.ControlNetColor[:3]):
            self.assertAlmostEqual(got, want, places=3)
        # the scene's box is the surface's and the net's, nothing else; the camera frames it
        box = obj.Shape.BoundBox
        for point in net:
            box.add(FreeCAD.Vector(*point))
        low, high = scene_box(view)
        self.assert_box_close(low, high, box, tol=0.01 * box.DiagonalLength)
        self.assert_framed(view, low, high)
