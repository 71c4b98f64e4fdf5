# SPDX-License-Identifier: LGPL-2.1-or-later
"""User-facing messages: errors go to the report view and to a dialog, never a traceback."""

from __future__ import annotations

import FreeCAD
import FreeCADGui


def show_error(title: str, message: str) -> None:
    """A modal error box over FreeCAD's main window (the report view has the text too)."""
    from PySide import QtGui

    QtGui.QMessageBox.critical(FreeCADGui.getMainWindow(), title, message)


def report_error(title: str, message: str) -> None:
    """Report view and dialog: the one way commands tell the user that input was bad."""
    FreeCAD.Console.PrintError(f"{title}: {message}\n")
    show_error(title, message)


def show_info(title: str, message: str) -> None:
    """Report view, plus the status bar so a long result does not need a dialog."""
    FreeCAD.Console.PrintMessage(f"{title}: {message}\n")
    FreeCADGui.getMainWindow().statusBar().showMessage(f"{title}: {message}", 15000)


def task_buttons(*buttons) -> int:
    """The int a task panel's ``getStandardButtons`` returns for QDialogButtonBox buttons.

    PySide2 (FreeCAD 0.20, 1.0) turns its enums into ints with ``int()``; PySide6 (FreeCAD
    1.1) has Python enums whose ``value`` is the int (``int()`` on them raises).
    """
    flags = 0
    for button in buttons:
        flags |= int(getattr(button, "value", button))
    return flags
