# SPDX-License-Identifier: LGPL-2.1-or-later
"""Task panel editing a surface's control net: a point table with live preview.

Edits go straight into the object's properties (and a recompute) so the 3D view follows;
OK records them as ``set_control_point`` lines in the macro recorder and commits the
transaction, Cancel puts the original net back and aborts it.
"""

from __future__ import annotations

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from ..app.surface_feature import KNOT_LAYOUTS, set_control_point
from .messages import task_buttons
from .resources import icon

AXES = ("X", "Y", "Z")


class NetEditPanel:
    """FreeCAD task dialog (``form``, ``accept``, ``reject``) for one surface object."""

    def __init__(self, obj) -> None:
        self.obj = obj
        self.doc = obj.Document
        self.original_points = [FreeCAD.Vector(v) for v in obj.ControlPoints]
        self.original_knots = str(obj.Knots)
        self.rows, self.cols = int(obj.Rows), int(obj.Columns)
        self.doc.openTransaction("Edit control net")
        self.form = self._build_form()
        self._fill_table()

    # -- the form ------------------------------------------------------------------------------
    def _build_form(self) -> QtGui.QWidget:
        form = QtGui.QWidget()
        form.setWindowTitle("Control net")  # short: FreeCAD's task box is as wide as its title
        form.setWindowIcon(QtGui.QIcon(icon("edit_net")))
        layout = QtGui.QVBoxLayout(form)
        top = QtGui.QFormLayout()
        top.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)  # narrow docks: labels above
        self.knots = QtGui.QComboBox()
        self.knots.addItems(KNOT_LAYOUTS)
        self.knots.setCurrentIndex(KNOT_LAYOUTS.index(self.original_knots))
        self.knots.currentIndexChanged.connect(self._knots_changed)
        top.addRow("Knots", self.knots)
        size = QtGui.QLabel(f"{self.obj.Label}: {self.rows} x {self.cols} points (rows u, "
                            "columns w)")
        size.setWordWrap(True)
        top.addRow("Net", size)
        self.live = QtGui.QCheckBox("Live preview")
        self.live.setChecked(True)
        self.live.toggled.connect(self._live_toggled)
        top.addRow(self.live)
        layout.addLayout(top)
        self.table = QtGui.QTableWidget(self.rows * self.cols, len(AXES))
        self.table.setHorizontalHeaderLabels([f"{axis} (mm)" for axis in AXES])
        self.table.horizontalHeader().setSectionResizeMode(QtGui.QHeaderView.Stretch)
        self.table.setVerticalHeaderLabels(
            [f"{i},{j}" for i in range(self.rows) for j in range(self.cols)]
        )
        self.table.itemChanged.connect(self._item_changed)
        self.table.setMinimumHeight(300)
        layout.addWidget(self.table)
        # bad entries are explained here, beside the table, not only in the report view
        self.message = QtGui.QLabel("")
        self.message.setObjectName("validation")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b00000")
        self.message.hide()
        layout.addWidget(self.message)
        return form

    def _fill_table(self) -> None:
        self.table.blockSignals(True)
        for index, point in enumerate(self.obj.ControlPoints):
            for axis in range(3):
                self.table.setItem(index, axis, QtGui.QTableWidgetItem(f"{point[axis]:.6g}"))
        self.table.blockSignals(False)

    # -- edits ---------------------------------------------------------------------------------
    def table_points(self) -> list[tuple[float, float, float]]:
        """The table's points (mm); a cell that is not a number keeps the object's value."""
        current = list(self.obj.ControlPoints)
        points = []
        for index in range(self.rows * self.cols):
            xyz = []
            for axis in range(3):
                item = self.table.item(index, axis)
                try:
                    xyz.append(float(item.text()))
                except (AttributeError, ValueError):
                    xyz.append(float(current[index][axis]))
            points.append(tuple(xyz))
        return points

    def set_cell(self, row: int, col: int, axis: int, value: float) -> None:
        """Type a value into the table (what a user does; tests drive the panel with it)."""
        self.table.item(row * self.cols + col, axis).setText(repr(float(value)))

    def _item_changed(self, item) -> None:
        try:
            value = float(item.text())
            if value != value or value in (float("inf"), float("-inf")):
                raise ValueError(item.text())
        except ValueError:
            old = self.obj.ControlPoints[item.row()][item.column()]
            i, j = divmod(item.row(), self.cols)
            self.show_message(f"Point {i},{j} {AXES[item.column()]}: {item.text()!r} is not a "
                              f"number (mm); it keeps {old:.6g} mm")
            self.table.blockSignals(True)
            item.setText(f"{old:.6g}")
            self.table.blockSignals(False)
            return
        self.show_message("")
        if self.live.isChecked():
            index = item.row()
            point = list(self.obj.ControlPoints[index])
            point[item.column()] = value
            set_control_point(self.obj, index // self.cols, index % self.cols, point)
            self._preview()

    def show_message(self, text: str) -> None:
        """The inline validation message under the table ('' hides it)."""
        self.message.setText(text)
        self.message.setVisible(bool(text))

    def _knots_changed(self, _index: int) -> None:
        if self.live.isChecked():
            self.obj.Knots = self.knots.currentText()
            self._preview()

    def _live_toggled(self, on: bool) -> None:
        if on:
            self._apply_all()
            self._preview()

    def _apply_all(self) -> None:
        for index, point in enumerate(self.table_points()):
            if tuple(self.obj.ControlPoints[index]) != point:
                set_control_point(self.obj, index // self.cols, index % self.cols, point)
        if self.obj.Knots != self.knots.currentText():
            self.obj.Knots = self.knots.currentText()

    def _preview(self) -> None:
        QtGui.QApplication.setOverrideCursor(QtCore.Qt.WaitCursor)
        try:
            self.doc.recompute()
        finally:
            QtGui.QApplication.restoreOverrideCursor()

    # -- task dialog API -----------------------------------------------------------------------
    def getStandardButtons(self) -> int:  # noqa: N802 - FreeCAD API
        return task_buttons(QtGui.QDialogButtonBox.Ok, QtGui.QDialogButtonBox.Cancel)

    def accept(self) -> bool:
        """Record the edits as Python in the macro recorder, recompute, commit."""
        self._apply_all()
        final = [tuple(v) for v in self.obj.ControlPoints]
        ref = f"App.getDocument({self.doc.Name!r}).getObject({self.obj.Name!r})"
        try:
            FreeCADGui.doCommand("from BSplineCAM.app.surface_feature import set_control_point")
            for index, point in enumerate(final):
                if tuple(self.original_points[index]) != point:
                    i, j = divmod(index, self.cols)
                    FreeCADGui.doCommand(f"set_control_point({ref}, {i}, {j}, {point!r})")
            if self.obj.Knots != self.original_knots:
                FreeCADGui.doCommand(f"{ref}.Knots = {str(self.obj.Knots)!r}")
            FreeCADGui.doCommand(f"App.getDocument({self.doc.Name!r}).recompute()")
        except Exception as exc:  # noqa: BLE001 - reported; the net is restored
            FreeCAD.Console.PrintError(f"BSplineCAM: editing the net failed: {exc}\n")
            return self.reject()
        self.doc.commitTransaction()
        self._close()
        return True

    def reject(self) -> bool:
        """Put the original net back and abort the transaction."""
        self.obj.ControlPoints = self.original_points
        self.obj.Knots = self.original_knots
        self.doc.abortTransaction()
        self.doc.recompute()
        self._close()
        return True

    def _close(self) -> None:
        gui_doc = FreeCADGui.getDocument(self.doc.Name)
        if gui_doc is not None and gui_doc.getInEdit() is not None:
            gui_doc.resetEdit()
        else:
            FreeCADGui.Control.closeDialog()
