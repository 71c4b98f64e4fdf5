# SPDX-License-Identifier: LGPL-2.1-or-later
"""The surface commands of the BSplineCAM workbench.

Each command does its work through ``FreeCADGui.doCommand`` so the macro recorder shows the
Python a user could type, inside a document transaction that is aborted on error.  Bad input
(an unreadable net, a failed export) is reported in the report view and a dialog.
File dialogs go through :func:`ask_open_file` / :func:`ask_save_file`, which tests replace.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from ..app.surface_feature import is_surface
from ..core import BSplineCAMError
from .messages import report_error
from .resources import icon

NET_FILTER = "Control nets (*.json *.csv *.dat);;JSON (*.json);;CSV (*.csv);;Points (*.dat)"
DAT_FILTER = "Point grid (*.dat)"
STEP_FILTER = "STEP (*.step *.stp)"


def ask_open_file(title: str, filters: str) -> str:
    """Path chosen in an open-file dialog ('' when cancelled)."""
    path, _ = QtGui.QFileDialog.getOpenFileName(FreeCADGui.getMainWindow(), title, "", filters)
    return path


def ask_save_file(title: str, filters: str, suggestion: str = "") -> str:
    """Path chosen in a save-file dialog ('' when cancelled)."""
    path, _ = QtGui.QFileDialog.getSaveFileName(
        FreeCADGui.getMainWindow(), title, suggestion, filters
    )
    return path


def selected_surfaces() -> list:
    """Surface objects in the selection (cheap enough for IsActive)."""
    return [obj for obj in FreeCADGui.Selection.getSelection() if is_surface(obj)]


def target_surfaces() -> list:
    """Selected surfaces, or every surface of the active document when nothing is selected."""
    chosen = selected_surfaces()
    if chosen or FreeCADGui.Selection.getSelection():
        return chosen
    doc = FreeCAD.ActiveDocument
    return [obj for obj in doc.Objects if is_surface(obj)] if doc else []


def obj_ref(obj) -> str:
    """Python expression for ``obj`` as the macro recorder should show it."""
    return f"App.getDocument({obj.Document.Name!r}).getObject({obj.Name!r})"


@contextlib.contextmanager
def transaction(title: str, doc=None) -> Iterator[object]:
    """Open a transaction on ``doc``; commit on success, abort (undo) and re-raise on error."""
    doc = doc or FreeCAD.ActiveDocument
    doc.openTransaction(title)
    try:
        yield doc
    except BaseException:
        doc.abortTransaction()
        raise
    doc.commitTransaction()


@contextlib.contextmanager
def wait_cursor() -> Iterator[None]:
    QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
    try:
        yield
    finally:
        QtGui.QApplication.restoreOverrideCursor()


class BaseCommand:
    """GetResources from class attributes; IsActive that never raises; errors reported."""

    name = ""
    pixmap = ""
    menu_text = ""
    tool_tip = ""

    def GetResources(self) -> dict:  # noqa: N802 - FreeCAD API
        return {"Pixmap": icon(self.pixmap), "MenuText": self.menu_text, "ToolTip": self.tool_tip}

    def IsActive(self) -> bool:  # noqa: N802 - FreeCAD API
        try:
            return bool(self.active())
        except Exception:  # noqa: BLE001 - IsActive must never raise
            return False

    def active(self) -> bool:
        return FreeCAD.ActiveDocument is not None

    def Activated(self) -> None:  # noqa: N802 - FreeCAD API
        try:
            self.run()
        except (BSplineCAMError, OSError, ValueError) as exc:
            report_error(self.menu_text, str(exc))
        except Exception as exc:  # noqa: BLE001 - a dialog, not a traceback, for the user
            report_error(self.menu_text, f"{type(exc).__name__}: {exc}")

    def run(self) -> None:
        raise NotImplementedError


class NewSurface(BaseCommand):
    name = "BSplineCAM_NewSurface"
    pixmap = "new_surface"
    menu_text = "New surface from control net..."
    tool_tip = ("Create a parametric cubic B-spline surface from a control-net file "
                "(.json .csv .dat)")

    def active(self) -> bool:
        return True

    def run(self, path: str | None = None) -> None:
        path = path or ask_open_file("Open a control net", NET_FILTER)
        if not path:
            return
        from ..app.importers import read_surface

        read_surface(path)  # validate before the document changes (NetError names the line)
        if FreeCAD.ActiveDocument is None:
            FreeCADGui.doCommand("App.newDocument()")
        with transaction("New B-spline surface"):
            FreeCADGui.doCommand("import BSplineCAM")
            FreeCADGui.doCommand(f"obj = BSplineCAM.make_surface({os.fspath(path)!r})")
            FreeCADGui.doCommand("App.ActiveDocument.recompute()")
        FreeCADGui.doCommand("Gui.Selection.clearSelection()")
        FreeCADGui.doCommand("Gui.Selection.addSelection(obj)")
        # isometric: hill and hollow show (from the top they are invisible)
        FreeCADGui.doCommand("Gui.activeDocument().activeView().viewIsometric()")
        FreeCADGui.doCommand("Gui.SendMsgToActiveView('ViewFit')")


class EditNet(BaseCommand):
    name = "BSplineCAM_EditNet"
    pixmap = "edit_net"
    menu_text = "Edit control net"
    tool_tip = "Edit the selected surface's control points in a table, with live preview"

    def active(self) -> bool:
        from .results_panel import editing_dialog

        return len(selected_surfaces()) == 1 and not editing_dialog()

    def run(self) -> None:
        from .results_panel import close_results

        obj = selected_surfaces()[0]
        close_results()
        # the panel opens (and commits or aborts) its own transaction
        FreeCADGui.doCommand(
            f"Gui.getDocument({obj.Document.Name!r}).setEdit({obj.Name!r}, 0)"
        )


class CrossCheck(BaseCommand):
    name = "BSplineCAM_CrossCheck"
    pixmap = "crosscheck"
    menu_text = "Cross-check against OCCT"
    tool_tip = ("Evaluate the surface by the paper's matrix form, Cox-de Boor and OCCT on a "
                "dense grid; report the deviations and store them in CrossCheck")

    def active(self) -> bool:
        return bool(target_surfaces())

    def run(self) -> None:
        import json

        from . import results_panel

        targets = target_surfaces()
        with wait_cursor(), transaction("Cross-check"):
            FreeCADGui.doCommand("from BSplineCAM.app.surface_feature import run_crosscheck")
            for obj in targets:
                FreeCADGui.doCommand(f"report = run_crosscheck({obj_ref(obj)})")
        reports = [(obj, json.loads(obj.CrossCheck or "{}")) for obj in targets]
        results_panel.show(results_panel.crosscheck_panel(reports))


class ExportDat(BaseCommand):
    name = "BSplineCAM_ExportDat"
    pixmap = "export_dat"
    menu_text = "Export .dat points..."
    tool_tip = "Write points sampled on the selected surface as the paper's .dat file"

    def active(self) -> bool:
        return len(selected_surfaces()) == 1

    def run(self, path: str | None = None) -> None:
        obj = selected_surfaces()[0]
        path = path or ask_save_file("Export .dat points", DAT_FILTER, f"{obj.Label}.dat")
        if not path:
            return
        if not path.lower().endswith(".dat"):
            path += ".dat"
        with transaction("Export .dat"):
            FreeCADGui.doCommand("from BSplineCAM.app import importers")
            FreeCADGui.doCommand(f"importers.export([{obj_ref(obj)}], {path!r})")
        if not os.path.isfile(path):
            raise OSError(f"{path}: nothing was written")


class ExportStep(BaseCommand):
    name = "BSplineCAM_ExportStep"
    pixmap = "export_step"
    menu_text = "Export STEP..."
    tool_tip = "Write the selected surface (face or solid) as STEP, exactly as OCCT holds it"

    def active(self) -> bool:
        return len(selected_surfaces()) == 1

    def run(self, path: str | None = None) -> None:
        obj = selected_surfaces()[0]
        path = path or ask_save_file("Export STEP", STEP_FILTER, f"{obj.Label}.step")
        if not path:
            return
        if not path.lower().endswith((".step", ".stp")):
            path += ".step"
        with transaction("Export STEP"):
            FreeCADGui.doCommand("from BSplineCAM.app import part")
            FreeCADGui.doCommand(f"part.export_shape({obj_ref(obj)}.Shape, {path!r})")
        FreeCAD.Console.PrintMessage(f"BSplineCAM: exported {obj.Label} to {path}\n")


class PaperRoute(BaseCommand):
    name = "BSplineCAM_PaperRoute"
    pixmap = "paper_route"
    menu_text = "Paper's import route (.dat to loft)..."
    tool_tip = ("Rebuild a surface the paper's way (.dat points, a spline per row, a loft) "
                "and measure its deviation from the selected exact surface (mm)")

    def active(self) -> bool:
        return len(selected_surfaces()) == 1

    def run(self, path: str | None = None) -> None:
        obj = selected_surfaces()[0]
        path = path or ask_open_file("Points of the paper's route", DAT_FILTER)
        if not path:
            return
        from ..core import read_dat

        read_dat(path)  # validate before the document changes
        with wait_cursor(), transaction("Paper route"):
            FreeCADGui.doCommand("from BSplineCAM.app import importers")
            FreeCADGui.doCommand(
                f"route = importers.import_paper_route({path!r}, design={obj_ref(obj)})"
            )


#: Every surface command, in toolbar order.
COMMANDS = (NewSurface, EditNet, CrossCheck, ExportDat, ExportStep, PaperRoute)


def register() -> list[str]:
    """Register the commands with FreeCAD (idempotent); return their names."""
    for command in COMMANDS:
        FreeCADGui.addCommand(command.name, command())
    return [command.name for command in COMMANDS]
