# SPDX-License-Identifier: LGPL-2.1-or-later
"""Helpers of the GUI tests (TestBSplineCAMGui*.py), which run inside a real
FreeCAD GUI: the base test cases (the workbench active, a fresh document per test), FreeCAD's
event loop, message boxes and file dialogs answered, the report view, the bench window and its
3D view, and checks of what a view shows.

Not a test module (no ``TestBSplineCAM`` prefix).  It imports FreeCADGui and PySide, so only
the GUI run loads it: the GUI test modules raise unittest.SkipTest before importing it where
FreeCAD's GUI is not up, and so does this module.
"""

from __future__ import annotations

import contextlib
import itertools
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

CASE_STUDY = ROOT / "examples" / "case-study.json"
#: Where the screenshots go (tools/run_gui_test.sh: build/screenshots, or docs/ on purpose).
DOCS = Path(os.environ.get("BSPLINECAM_DOCS", ROOT / "build" / "screenshots"))
WORKBENCH = "BSplineCAMWorkbench"


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

    def reopen(self, name: str, *objects):
        """Save the document as ``name`` in the test's folder, close it and open it again
        (fresh proxies); the same objects, by name, from the reopened document, which loaded
        with nothing red in the report view."""
        names = [o.Name for o in objects]
        path = self.tmp / name
        self.doc.saveAs(str(path))
        FreeCAD.closeDocument(self.doc.Name)
        process_events()
        clear_report()
        self.doc = FreeCAD.openDocument(str(path))
        self.doc_name = self.doc.Name
        process_events()
        self.assertNotIn("Error", report_text())
        return [self.doc.getObject(n) for n in names]

    def new_surface(self):
        """Run BSplineCAM_NewSurface on the case study; the object it made."""
        before = {o.Name for o in self.doc.Objects}
        with dialogs_answer(open_path=str(CASE_STUDY)):
            FreeCADGui.runCommand("BSplineCAM_NewSurface")
        made = [o for o in self.doc.Objects if o.Name not in before]
        self.assertEqual(len(made), 1)
        return made[0]


#: A coarse scallop keeps the GUI test fast (mm); FINE_SCALLOP (below) takes
#: seconds (to cancel).  TOOL: the ball's diameter (mm).
COARSE_SCALLOP = 0.1
TOOL = 6.0


def report_text() -> str:
    """What FreeCAD's report view shows."""
    dock = FreeCADGui.getMainWindow().findChild(QtGui.QDockWidget, "Report view")
    edit = dock.findChild(QtGui.QTextEdit) if dock is not None else None
    return edit.toPlainText() if edit is not None else ""


def clear_report() -> None:
    dock = FreeCADGui.getMainWindow().findChild(QtGui.QDockWidget, "Report view")
    edit = dock.findChild(QtGui.QTextEdit) if dock is not None else None
    if edit is not None:
        edit.clear()


def bench_window():
    """The main window at 1600 x 1000 without FreeCAD's start page: (main window, MDI area)."""
    mw = FreeCADGui.getMainWindow()
    mw.showNormal()
    mw.setGeometry(0, 0, 1600, 1000)
    mdi = mw.findChild(QtGui.QMdiArea)
    for sub in mdi.subWindowList():
        if sub.windowTitle().startswith("Start page"):
            sub.close()
    return mw, mdi


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

#: Size of the saved 3D pictures (pixels).
PICTURE = (1600, 1000)


def in_scene(view, node, drawn_only: bool = True) -> bool:
    """Whether ``node`` hangs in the view's Coin scene graph.

    With ``drawn_only`` the search follows what is drawn: a switch leads only into the child it
    shows (a hidden object, another display mode or ShowLegend off are not found).
    """
    from pivy import coin

    search = coin.SoSearchAction()
    search.setNode(node)
    search.setInterest(coin.SoSearchAction.FIRST)
    search.setSearchingAll(not drawn_only)
    search.apply(view.getSceneGraph())
    return search.getPath() is not None


def scene_box(view, node=None) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
    """(min, max) corners of what ``node`` (default: the view's whole scene graph, the box
    fitAll frames) draws, as Coin's bounding-box action sees it; None if nothing."""
    from pivy import coin

    region = coin.SbViewportRegion(*view.getSize())
    if node is None:
        # FreeCAD's own overlays sit in SoSkipBoundingGroups, which fitAll leaves out (FreeCAD
        # 1.1 keeps a zero-size marker at the origin there): leave them out too
        root = view.getSceneGraph()
        nodes = [root.getChild(i) for i in range(root.getNumChildren())]
        nodes = [n for n in nodes if n.getTypeId().getName() != "SoSkipBoundingGroup"]
    else:
        nodes = [node]
    box = coin.SbBox3f()
    for part in nodes:
        # as FreeCAD's fitAll: SoSkipBoundingGroups (screen overlays) excluded meanwhile
        search = coin.SoSearchAction()
        search.setType(coin.SoType.fromName("SoSkipBoundingGroup"))
        search.setInterest(coin.SoSearchAction.ALL)
        search.setSearchingAll(True)
        search.apply(part)
        paths = search.getPaths()
        skips = [paths[i].getTail() for i in range(paths.getLength())]
        modes = [skip.getField("mode").getValue() for skip in skips]
        for skip in skips:
            skip.getField("mode").setValue(1)  # EXCLUDE_BBOX
        action = coin.SoGetBoundingBoxAction(region)
        action.apply(part)
        for skip, mode in zip(skips, modes):
            skip.getField("mode").setValue(mode)
        if not action.getBoundingBox().isEmpty():
            box.extendBy(action.getBoundingBox())
    if box.isEmpty():
        return None
    return tuple(box.getMin().getValue()), tuple(box.getMax().getValue())


def drawn_boxes(view, doc) -> dict[str, tuple[tuple[float, ...], tuple[float, ...]]]:
    """Per object of ``doc`` that the view draws something of, the box of what it draws."""
    boxes = {}
    for obj in doc.Objects:
        vobj = obj.ViewObject
        if vobj is not None and in_scene(view, vobj.RootNode):
            box = scene_box(view, vobj.RootNode)
            if box is not None:
                boxes[obj.Name] = box
    return boxes


def box_corners(low, high) -> list[tuple[float, float, float]]:
    return list(itertools.product(*zip(low, high)))


def picture_point(view, point, size=PICTURE) -> tuple[float, float]:
    """Where the camera puts ``point`` in a picture of ``size`` saved from the view (pixels from
    the top left): the camera's view volume at the picture's aspect (wider than high, so
    Coin's ADJUST_CAMERA widens the volume and keeps its height)."""
    from pivy import coin

    volume = view.getCameraNode().getViewVolume(size[0] / size[1])
    u, v, _ = volume.projectToScreen(coin.SbVec3f(*map(float, point))).getValue()
    return u * size[0], (1.0 - v) * size[1]


class PictureChecks:
    """Assertions on what a 3D view shows, told from the camera and the scene graph (which the
    code controls) rather than from rendered pixels (which move with the renderer)."""

    def assert_box_close(self, low, high, expected, tol: float, axes: str = "xyz") -> None:
        """The box (low, high) matches a FreeCAD BoundBox on the given axes within ``tol``."""
        for i, axis in enumerate("xyz"):
            if axis not in axes:
                continue
            want = [getattr(expected, f"{axis.upper()}{end}") for end in ("Min", "Max")]
            self.assertAlmostEqual(low[i], want[0], delta=tol, msg=f"{axis} min of {low}, {high}")
            self.assertAlmostEqual(high[i], want[1], delta=tol, msg=f"{axis} max of {low}, {high}")

    def assert_framed(self, view, low, high, fill: float = 0.4) -> None:
        """The camera sees the whole box, in the view and in a saved picture, and the box fills
        at least ``fill`` of their width or height (fitted, not a speck)."""
        width, height = view.getSize()
        corners = box_corners(low, high)
        on_view = [view.getPointOnScreen(*corner) for corner in corners]
        on_picture = [picture_point(view, corner) for corner in corners]
        for points, (w, h), where in ((on_view, (width, height), "view"),
                                      (on_picture, PICTURE, "picture")):
            for corner, (x, y) in zip(corners, points):
                self.assertTrue(0 <= x < w and 0 <= y < h,
                                f"{corner} is at {(x, y)}, outside the {where} {(w, h)}")
            xs, ys = [x for x, _ in points], [y for _, y in points]
            self.assertGreater(max((max(xs) - min(xs)) / w, (max(ys) - min(ys)) / h), fill,
                               f"the box covers little of the {where}: {points}")

    def assert_picture(self, view, path: Path, covered) -> None:
        """The picture just saved from the view on white: its size, its background and where
        the scene is drawn.

        A twin of the picture saved on black tells the background from the scene, pixel by
        pixel, whatever the renderer's lights, shading and anti-aliasing (only the background
        changes with the requested colour).  Its corners must be background (assert_framed
        keeps the scene off them) and the pixels where the camera puts ``covered``, points on
        or inside the drawn surfaces, must not.
        """
        twin = self.tmp / f"{path.stem}-on-black.png"
        view.saveImage(str(twin), *PICTURE, "Black")
        white, black = QtGui.QImage(str(path)), QtGui.QImage(str(twin))
        for image in (white, black):
            self.assertEqual((image.width(), image.height()), PICTURE, path)

        def background(x: float, y: float) -> bool:
            on_white = QtGui.QColor(white.pixel(int(x), int(y)))
            on_black = QtGui.QColor(black.pixel(int(x), int(y)))
            return (min(on_white.red(), on_white.green(), on_white.blue()) >= 250
                    and max(on_black.red(), on_black.green(), on_black.blue()) <= 5)

        w, h = PICTURE
        for x, y in ((2, 2), (w - 3, 2), (2, h - 3), (w - 3, h - 3)):
            self.assertTrue(background(x, y), f"{path.name}: corner {(x, y)} is drawn")
        for point in covered:
            x, y = picture_point(view, point)
            self.assertFalse(background(x, y),
                             f"{path.name}: background at {(x, y)}, where {point} is")


class CamTestCase(PictureChecks, GuiTestCase):
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
