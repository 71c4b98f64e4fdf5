# SPDX-License-Identifier: LGPL-2.1-or-later
"""GUI tests of the BSplineCAM workbench, run inside a real FreeCAD GUI (under Xvfb).

``tools/run_gui_test.sh`` starts FreeCAD with ``tests/gui_run_tests.py``, which runs these
classes in FreeCAD's event loop, writes a JSON result and exits with its status.  The last
class saves ``view3d.png`` (3D view) and ``workbench.png`` (main window);
all in :data:`bsplinecam_gui.DOCS` (build/screenshots; ``make screenshots`` refreshes docs/).
The machining commands are tested in ``TestBSplineCAMGuiCam`` and ``TestBSplineCAMGuiPanels``.
File dialogs are replaced by fixed paths; error boxes are closed by a timer and recorded.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
# bsplinecam_gui puts the repository on sys.path and skips the module without FreeCAD's GUI
import bsplinecam_gui  # noqa: E402, F401, I001
import FreeCAD  # noqa: E402
import FreeCADGui  # noqa: E402
from bsplinecam_gui import (  # noqa: E402
    CASE_STUDY,
    DOCS,
    PICTURE,
    WORKBENCH,
    GuiTestCase,
    PictureChecks,
    bench_window,
    dialogs_answer,
    drawn_of_type,
    in_scene,
    is_active,
    isometric_view,
    message_boxes,
    process_events,
    scene_box,
    tree_dock,
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
