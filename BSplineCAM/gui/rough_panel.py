# SPDX-License-Identifier: LGPL-2.1-or-later
"""``BSplineCAM_Rough``: Z-level roughing added to the selected job, before its finishing.

A task panel asks the end mill (flat, bull-nose or ball; diameter, corner radius), step-down,
stepover, stock to leave and the stock block's margin; one transaction adds the tool
controller (T1; the job's other tools move up one number), grows the job's stock, adds the
roughing op (:mod:`BSplineCAM.app.roughing_op`) first in the job and computes it (progress
and Cancel in the status bar).  Any failure or cancel aborts the transaction: the document is
left as it was.  Double-clicking the op (or "Edit roughing" in its context menu) opens the
same panel filled from the op to change it, again in one transaction; the tool is then its
controller's bit, shown but not edited there.
"""

from __future__ import annotations

import json

import FreeCADGui
from PySide import QtGui

from ..app import compat
from ..core.toolpath.roughing import (
    MAX_RAMP_ANGLE_DEG,
    RAMP_ANGLE_DEG,
    check_fine_stepdown,
    check_ramp_angle,
)
from . import progress_bar, results_panel
from .cam_commands import (
    FinishOpViewProvider,
    PanelBase,
    _cutting_source,
    app_toolbit_factory,
    attach_job_view_providers,
    check_op,
    is_job,
    selected_job,
    spin,
)
from .commands import BaseCommand, obj_ref, transaction, wait_cursor
from .messages import show_info
from .resources import icon

SHAPES = ["flat", "bullnose", "ball"]


def is_roughing_op(obj) -> bool:
    from ..app.roughing_op import ObjectSurfaceRough

    return isinstance(getattr(obj, "Proxy", None), ObjectSurfaceRough)


def add_roughing(job, roughing, cutting):
    """One transaction: tool controller, stock margin, roughing op, computed; returns the op.
    Raises (and aborts, leaving the document as it was) if the op fails or is cancelled."""
    doc = job.Document
    before = {o.Name for o in doc.Objects}
    with wait_cursor(), app_toolbit_factory(), compat.toolbits_keep_transaction(), \
            transaction("BSplineCAM roughing", doc):
        FreeCADGui.doCommand("from BSplineCAM.app import cam, pipeline")
        FreeCADGui.doCommand(f"job = {obj_ref(job)}")
        FreeCADGui.doCommand(f"rough = pipeline.add_roughing(job, pipeline.{roughing!r}, "
                             f"{_cutting_source(cutting)})")
        op = next(o for o in doc.Objects if o.Name not in before and is_roughing_op(o))
        attach_job_view_providers(job, op, RoughOpViewProvider)
        _recompute_and_check(op)
    return op


def edit_roughing(op, roughing, cutting) -> None:
    """One transaction: the op's parameters, feeds and stock margin changed, recomputed.
    Raises (and aborts, leaving the op as it was) if the op fails or is cancelled."""
    doc = op.Document
    with wait_cursor(), transaction("BSplineCAM edit roughing", doc):
        FreeCADGui.doCommand("from BSplineCAM.app import cam, pipeline")
        FreeCADGui.doCommand(f"pipeline.edit_roughing({obj_ref(op)}, pipeline.{roughing!r}, "
                             f"{_cutting_source(cutting)})")
        _recompute_and_check(op)


def _recompute_and_check(op) -> None:
    try:
        FreeCADGui.doCommand(f"App.getDocument({op.Document.Name!r}).recompute()")
    finally:
        progress_bar.finish()
    check_op(op)


class RoughOpViewProvider(FinishOpViewProvider):
    """The roughing op in the job's tree: double-click (or its context menu) edits it in the
    roughing task panel."""

    def setEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        """Mode 0 opens the roughing panel on the op; other modes fall back to FreeCAD's."""
        if mode != 0:
            return None
        op = vobj.Object
        job = op.Proxy.job_of(op)
        if job is None:
            return None
        FreeCADGui.Control.showDialog(RoughPanel(job, op))
        return True

    def unsetEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        if mode != 0:
            return None
        FreeCADGui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj) -> bool:  # noqa: N802 - FreeCAD API
        if results_panel.editing_dialog():
            return False
        results_panel.close_results()
        FreeCADGui.getDocument(vobj.Object.Document.Name).setEdit(vobj.Object.Name, 0)
        return True

    def setupContextMenu(self, vobj, menu) -> None:  # noqa: N802 - FreeCAD API
        from PySide import QtGui as Widgets

        action = Widgets.QAction(Widgets.QIcon(icon("job")), "Edit roughing", menu)
        action.triggered.connect(lambda: self.doubleClicked(vobj))
        menu.addAction(action)


class RoughPanel(PanelBase):
    """Task panel of the roughing parameters; OK validates, computes, and closes on success."""

    #: The panel last opened (for scripting and tests; not saved).
    last: RoughPanel | None = None

    def __init__(self, job, op=None) -> None:
        """A panel adding roughing to ``job``, or editing its roughing ``op``."""
        self.job = job
        self.op = op
        self.editing = op is not None
        layout = self.new_form("Edit roughing" if self.editing else "Roughing")
        self.shape = QtGui.QComboBox()
        self.shape.addItems(SHAPES)
        self.diameter = spin(10.0, 0.0, 100.0, 3, " mm", 1.0)
        self.corner = spin(1.0, 0.0, 50.0, 3, " mm", 0.5)
        self.stepdown = spin(2.0, 0.0, 100.0, 3, " mm", 0.5)
        self.fine = spin(0.0, 0.0, 100.0, 3, " mm", 0.5)
        self.fine.setSpecialValueText("off")
        self.stepover = spin(40.0, 0.0, 100.0, 0, " %", 5.0)
        self.ramp = spin(RAMP_ANGLE_DEG, 0.0, 90.0, 1, " °", 0.5)
        self.radial = spin(0.3, 0.0, 50.0, 3, " mm", 0.1)
        self.axial = spin(0.3, 0.0, 50.0, 3, " mm", 0.1)
        self.margin = spin(2.0, 0.0, 1000.0, 2, " mm", 1.0)
        self.flat_levels = QtGui.QCheckBox("Extra levels at flat areas")
        self.flat_levels.setChecked(True)
        self.centre_cutting = QtGui.QCheckBox("Centre-cutting end mill (may plunge)")
        self.centre_cutting.setChecked(False)
        self.make_cutting_fields()
        target = QtGui.QLabel(job.Label)
        layout.addRow("Job", target)
        for label, widget, tip in (
            ("End mill", self.shape, "flat, bull-nose or ball end mill"),
            ("Diameter", self.diameter, "Diameter of the end mill"),
            ("Corner radius", self.corner, "Corner radius of the bull-nose end mill"),
            ("Step-down", self.stepdown, "Depth of each Z level"),
            ("Fine step-down", self.fine, "Terraces no thicker than this: after each level, "
             "levels this far apart in the band above it, cut from the bottom up (off: none)"),
            ("Stepover", self.stepover, "Width of cut, percent of the diameter; the radial "
             "engagement never exceeds it"),
            ("Ramp angle", self.ramp, "Helical and ramped entries descend at this angle "
             f"(above 0, at most {MAX_RAMP_ANGLE_DEG:g} degrees)"),
            ("Radial stock to leave", self.radial, "Material left on the part sideways"),
            ("Axial stock to leave", self.axial, "Material left on the part vertically"),
            ("Stock margin", self.margin, "The job's stock block around the part, sideways "
             "and above"),
            ("", self.flat_levels, "Extra Z levels at the part's flat areas"),
            ("", self.centre_cutting, "The end mill cuts at its centre: closed pockets too "
             "narrow for a helix are entered by a straight plunge (off: such a pocket is "
             "left, and the report names it and the tool that would enter it)"),
            *self.cutting_rows(),
        ):
            widget.setToolTip(tip)
            layout.addRow(label, widget)
        self.add_message()
        if self.editing:
            self.fill_from_op()
        self.shape.currentIndexChanged.connect(self.show_corner)
        self.show_corner()
        RoughPanel.last = self

    def fill_from_op(self) -> None:
        """The fields from the op, its controller and its job's stock; the tool is the
        controller's bit and is changed there, so its fields are read-only."""
        from ..app import cam, pipeline

        params = pipeline.roughing_of(self.op)
        self.set_cutting(cam.controller_cutting(self.op.ToolController))
        self.shape.setCurrentIndex(SHAPES.index(params.shape))
        for box, value in ((self.diameter, params.diameter), (self.corner, params.corner_radius),
                           (self.stepdown, params.stepdown), (self.fine, params.fine_stepdown),
                           (self.stepover, params.stepover_percent),
                           (self.ramp, params.ramp_angle),
                           (self.radial, params.radial_allowance),
                           (self.axial, params.axial_allowance), (self.margin, params.stock_margin)):
            box.setValue(value)
        self.flat_levels.setChecked(params.flat_levels)
        self.centre_cutting.setChecked(params.centre_cutting)
        tip = f"The bit of {self.op.ToolController.Label}: change it in the tool controller"
        for widget in (self.shape, self.diameter, self.corner):
            widget.setEnabled(False)
            widget.setToolTip(tip)

    def reject(self) -> bool:
        self.close()
        return True

    def close(self) -> None:
        """Close the panel, leaving the op's edit mode when it was opened by editing."""
        gui_doc = FreeCADGui.getDocument(self.job.Document.Name)
        if self.editing and gui_doc is not None and gui_doc.getInEdit() is not None:
            gui_doc.resetEdit()
        else:
            FreeCADGui.Control.closeDialog()

    def show_corner(self, *_args) -> None:
        shown = self.shape.currentText() == "bullnose"
        self.corner.setVisible(shown)
        label = self.layout.labelForField(self.corner)
        if label is not None:
            label.setVisible(shown)

    def parameters(self) -> tuple:
        """(RoughingParameters, Cutting) from the form; ValueError names a bad field."""
        from ..app.pipeline import RoughingParameters
        from ..core.simulation.simulate import Tool

        shape = self.shape.currentText()
        corner = self.corner.value() if shape == "bullnose" else 0.0
        Tool(self.diameter.value(), shape, corner)  # ParameterError names the bad size
        if not self.stepdown.value() > 0:
            raise ValueError("Step-down must be above 0 mm")
        check_fine_stepdown(self.fine.value(), "Fine step-down (at most the step-down)",
                            self.stepdown.value())
        if not self.stepover.value() >= 1:
            raise ValueError("Stepover must be at least 1 % of the diameter")
        check_ramp_angle(self.ramp.value(), "Ramp angle")
        params = RoughingParameters(
            shape=shape, diameter=self.diameter.value(), corner_radius=corner,
            stepdown=self.stepdown.value(), stepover_percent=int(self.stepover.value()),
            radial_allowance=self.radial.value(), axial_allowance=self.axial.value(),
            stock_margin=self.margin.value(), flat_levels=self.flat_levels.isChecked(),
            fine_stepdown=self.fine.value(), ramp_angle=self.ramp.value(),
            centre_cutting=self.centre_cutting.isChecked())
        return params, self.cutting()

    def accept(self) -> bool:
        def work() -> None:
            params, cutting = self.parameters()
            if self.editing:
                edit_roughing(self.op, params, cutting)
            else:
                self.op = add_roughing(self.job, params, cutting)

        if not self.attempt("Roughing", work):
            return False
        self.close()
        report = json.loads(self.op.Report or "{}")
        notes = report.get("notes", [])
        warned = f"; {len(notes)} warning(s) in the report view: {notes[0]}" if notes else ""
        show_info("Roughing", f"{self.op.Label}: {len(report.get('levels', []))} levels, "
                  f"{report.get('cutting_length_mm', 0):.0f} mm of cutting{warned}")
        return True


class AddRoughing(BaseCommand):
    name = "BSplineCAM_Rough"
    pixmap = "job"
    menu_text = "Roughing..."
    tool_tip = ("Add Z-level roughing from the stock block to the selected job, before its "
                "finishing: end mill, step-down, stepover and stock to leave in a task panel")

    def active(self) -> bool:
        return selected_job() is not None and not results_panel.editing_dialog()

    def run(self) -> None:
        job = selected_job()
        if job is None or not is_job(job):
            raise ValueError("select a machining job first")
        results_panel.close_results()
        FreeCADGui.Control.showDialog(RoughPanel(job))


def register() -> list[str]:
    """Register the roughing command with FreeCAD (idempotent); return its name."""
    FreeCADGui.addCommand(AddRoughing.name, AddRoughing())
    return [AddRoughing.name]
