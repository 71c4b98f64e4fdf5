# SPDX-License-Identifier: LGPL-2.1-or-later
"""GUI tests of the machining commands on the case study, run inside a real FreeCAD GUI (under
Xvfb, ``tools/run_gui_test.sh``): job, post-process and verify (coarse scallop), saving
``verify3d.png`` (simulated part) and ``job.png`` (job tree) in :data:`bsplinecam_gui.DOCS`.
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
import FreeCADGui  # noqa: E402
from bsplinecam_gui import (  # noqa: E402
    COARSE_SCALLOP,
    DOCS,
    FINE_SCALLOP,
    PICTURE,
    TOOL,
    CamTestCase,
    bench_window,
    box_corners,
    cam_dialogs,
    drawn_boxes,
    in_scene,
    is_active,
    isometric_view,
    message_boxes,
    process_events,
    report_text,
    scene_box,
    timed_during_computation,
    tree_dock,
    wait,
)
from PySide import QtCore, QtGui  # noqa: E402


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

    def test_a_kernels_first_use_is_said_on_the_running_bar(self) -> None:
        """While a compiled kernel loads or compiles on its first use, the op's own bar says
        which (the bar stands still meanwhile); the next report restores its message."""
        from BSplineCAM.core import kernels
        from BSplineCAM.gui import progress_bar

        self.assertIs(kernels._first_use_listener, progress_bar.first_use)
        label = progress_bar.StatusWidgets.get()[0]
        bar = progress_bar.ProgressBar("SurfaceFinish: computing the toolpath")
        try:
            bar(0.3)
            kernels._tell_first_use("halve")
            noted = label.text()
            mw = FreeCADGui.getMainWindow()
            picture = DOCS / "first_use_bar.png"
            if DOCS.name != "docs":  # a check picture, not one of the user guide's
                QtGui.QApplication.primaryScreen().grabWindow(mw.winId()).save(
                    str(picture), "PNG")
            bar(0.4)
            after = label.text()
        finally:
            bar.close()
        self.assertEqual(noted, "SurfaceFinish: computing the toolpath (preparing the "
                                "compiled kernel halve, first use this session)")
        self.assertEqual(after, "SurfaceFinish: computing the toolpath")

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
