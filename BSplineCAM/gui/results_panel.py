# SPDX-License-Identifier: LGPL-2.1-or-later
"""A task panel showing figures a user reads and copies: a verification's, a cross-check's.

The text is the report view's summary (gouge, scallop max / p99, coverage, cutting length,
machining time; or the evaluators' deviations), in a read-only text box whose text can be
selected, plus a button copying it all to the clipboard.  Only Close: the panel changes nothing.
A results panel replaces another one; it does not push aside a panel that edits something.
"""

from __future__ import annotations

import re

import FreeCAD
import FreeCADGui
from PySide import QtGui

from ..core.simulation.gouge_normal import gouge_gate_mm
from .messages import task_buttons
from .resources import icon


class ResultsPanel:
    """FreeCAD task dialog (``form``) with a title, a verdict line and the copyable figures."""

    #: The panel last made, and the one last put in the task view (scripting, tests; not saved).
    last: ResultsPanel | None = None
    current: ResultsPanel | None = None

    def __init__(self, title: str, text: str, verdict: str = "", ok: bool = True,
                 pixmap: str = "verify") -> None:
        self.title, self.text, self.ok = title, compact(text), ok
        self.form = QtGui.QWidget()
        self.form.setWindowTitle(title)
        self.form.setWindowIcon(QtGui.QIcon(icon(pixmap)))
        layout = QtGui.QVBoxLayout(self.form)
        self.verdict = QtGui.QLabel(verdict)
        self.verdict.setWordWrap(True)
        self.verdict.setStyleSheet("font-weight: bold; color: %s" % ("#006000" if ok
                                                                     else "#b00000"))
        self.verdict.setVisible(bool(verdict))
        layout.addWidget(self.verdict)
        self.figures = QtGui.QPlainTextEdit()
        self.figures.setReadOnly(True)  # selectable and copyable, not editable
        self.figures.setLineWrapMode(QtGui.QPlainTextEdit.WidgetWidth)  # narrow docks
        self.figures.setPlainText(self.text)
        self.figures.setMinimumHeight(180)
        self.figures.setMinimumWidth(120)
        layout.addWidget(self.figures)
        self.copy = QtGui.QPushButton("Copy figures")
        self.copy.setToolTip("Copy the figures to the clipboard")
        self.copy.clicked.connect(self.copy_text)
        layout.addWidget(self.copy)
        ResultsPanel.last = self

    def copy_text(self) -> None:
        QtGui.QApplication.clipboard().setText(self.text)

    # -- task dialog API -----------------------------------------------------------------------
    def getStandardButtons(self) -> int:  # noqa: N802 - FreeCAD API
        return task_buttons(QtGui.QDialogButtonBox.Close)

    def reject(self) -> bool:
        FreeCADGui.Control.closeDialog()
        return True

    def accept(self) -> bool:
        return self.reject()


def compact(text: str) -> str:
    """The report view's column layout as "name: value" lines, readable in a narrow dock."""
    return "\n".join(re.sub(r"\s{2,}", ": ", line.strip()) for line in text.splitlines()) + "\n"


def show(panel: ResultsPanel) -> bool:
    """Show ``panel`` in the task view, replacing a results panel; False (and nothing shown)
    while another task panel is open, so that no edit is pushed aside."""
    if editing_dialog():
        FreeCAD.Console.PrintLog("BSplineCAM: a task panel is open; results not shown\n")
        return False
    close_results()
    FreeCADGui.Control.showDialog(panel)
    ResultsPanel.current = panel
    return True


def _shown(panel: ResultsPanel) -> bool:
    try:
        return panel.form.isVisible()
    except RuntimeError:  # its widget was deleted with the dialog
        return False


def editing_dialog() -> bool:
    """Whether a task panel other than a results panel is open (cheap, for IsActive)."""
    if not FreeCADGui.Control.activeDialog():
        return False
    return ResultsPanel.current is None or not _shown(ResultsPanel.current)


def close_results() -> None:
    """Close a results panel if it is the open task panel (before a command opens another)."""
    if FreeCADGui.Control.activeDialog() and ResultsPanel.current is not None \
            and _shown(ResultsPanel.current):
        FreeCADGui.Control.closeDialog()


def verification_panel(obj) -> ResultsPanel:
    """The figures of a verification object (its Metrics)."""
    import json

    from ..app.verify_feature import format_metrics, loads_ok

    metrics = json.loads(obj.Metrics or "{}")
    text = format_metrics(obj.Label, metrics) if metrics else "No metrics (not computed)\n"
    # the gouge job's gate reads: along the design's normal where measured, else vertical
    gouge = gouge_gate_mm(metrics) if metrics else 0.0
    tolerance = float(metrics.get("gouge_tolerance_mm", 0.0))
    safe = bool(metrics) and gouge <= tolerance and not metrics.get("rapid_collisions")
    loaded = bool(metrics) and loads_ok(metrics)
    ok = safe and loaded
    if not metrics:
        verdict = obj.Label
    elif not safe:
        verdict = f"{obj.Label}: gouge {gouge:.4f} mm or rapid collisions, see below"
    elif not loaded:
        verdict = f"{obj.Label}: a tool is loaded over its limits, see below"
    else:
        verdict = f"{obj.Label}: no gouge beyond {tolerance:g} mm" + (
            ", loads within limits" if metrics.get("loads") else "")
    # a short title: FreeCAD's task box does not shrink below its title
    return ResultsPanel("Verification", text, verdict, ok, "verify")


def crosscheck_panel(objs_reports: list) -> ResultsPanel:
    """The cross-check reports of surfaces: [(object, report dict)]."""
    from ..app.surface_feature import format_crosscheck

    text = "".join(format_crosscheck(obj.Label, report) for obj, report in objs_reports)
    ok = all(report.get("exact_route_ok", False) for _, report in objs_reports)
    names = ", ".join(obj.Label for obj, _ in objs_reports)
    verdict = (f"Exact route within tolerance: {names}" if ok else
               "Exact route outside tolerance or a backend unavailable")
    return ResultsPanel("Cross-check", text, verdict, ok, "crosscheck")
