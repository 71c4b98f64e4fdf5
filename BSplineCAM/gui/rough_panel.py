# SPDX-License-Identifier: LGPL-2.1-or-later
"""``BSplineCAM_Rough``: Z-level roughing added to the selected job, before its finishing.

A task panel asks the end mill (flat, bull-nose or ball; diameter, corner radius), step-down,
stepover, stock to leave and the stock block's margin; one transaction adds the tool
controller (T1; the job's other tools move up one number), grows the job's stock, adds the
roughing op (:mod:`BSplineCAM.app.roughing_op`) first in the job and computes it (progress
and Cancel in the status bar).  Any failure or cancel aborts the transaction: the document is
left as it was.  The op's properties stay editable in the property view afterwards.
"""

from __future__ import annotations

import json

import FreeCADGui
from PySide import QtGui

from ..app import compat
from . import progress_bar, results_panel
from .cam_commands import (
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
        attach_job_view_providers(job, op)
        try:
            FreeCADGui.doCommand(f"App.getDocument({doc.Name!r}).recompute()")
        finally:
            progress_bar.finish()
        check_op(op)
    return op


class RoughPanel(PanelBase):
    """Task panel of the roughing parameters; OK validates, computes, and closes on success."""

    #: The panel last opened (for scripting and tests; not saved).
    last: RoughPanel | None = None

    def __init__(self, job) -> None:
        self.job = job
        self.op = None
        layout = self.new_form("Roughing")
        self.shape = QtGui.QComboBox()
        self.shape.addItems(SHAPES)
        self.diameter = spin(10.0, 0.0, 100.0, 3, " mm", 1.0)
        self.corner = spin(1.0, 0.0, 50.0, 3, " mm", 0.5)
        self.stepdown = spin(2.0, 0.0, 100.0, 3, " mm", 0.5)
        self.stepover = spin(40.0, 0.0, 100.0, 0, " %", 5.0)
        self.radial = spin(0.3, 0.0, 50.0, 3, " mm", 0.1)
        self.axial = spin(0.3, 0.0, 50.0, 3, " mm", 0.1)
        self.margin = spin(2.0, 0.0, 1000.0, 2, " mm", 1.0)
        self.flat_levels = QtGui.QCheckBox("Extra levels at flat areas")
        self.flat_levels.setChecked(True)
        self.horizontal_feed = spin(1200.0, 0.0, 100000.0, 0, " mm/min", 100.0)
        self.vertical_feed = spin(400.0, 0.0, 100000.0, 0, " mm/min", 50.0)
        self.spindle = spin(12000.0, 0.0, 100000.0, 0, " rpm", 500.0)
        target = QtGui.QLabel(job.Label)
        layout.addRow("Job", target)
        for label, widget, tip in (
            ("End mill", self.shape, "flat, bull-nose or ball end mill"),
            ("Diameter", self.diameter, "Diameter of the end mill"),
            ("Corner radius", self.corner, "Corner radius of the bull-nose end mill"),
            ("Step-down", self.stepdown, "Depth of each Z level"),
            ("Stepover", self.stepover, "Width of cut, percent of the diameter; the radial "
             "engagement never exceeds it"),
            ("Radial stock to leave", self.radial, "Material left on the part sideways"),
            ("Axial stock to leave", self.axial, "Material left on the part vertically"),
            ("Stock margin", self.margin, "The job's stock block around the part, sideways "
             "and above"),
            ("", self.flat_levels, "Extra Z levels at the part's flat areas"),
            ("Horizontal feed", self.horizontal_feed, "Cutting feed"),
            ("Vertical feed", self.vertical_feed, "Plunge feed"),
            ("Spindle speed", self.spindle, "Spindle speed (forward)"),
        ):
            widget.setToolTip(tip)
            layout.addRow(label, widget)
        self.add_message()
        self.shape.currentIndexChanged.connect(self.show_corner)
        self.show_corner()
        RoughPanel.last = self

    def show_corner(self, *_args) -> None:
        shown = self.shape.currentText() == "bullnose"
        self.corner.setVisible(shown)
        label = self.layout.labelForField(self.corner)
        if label is not None:
            label.setVisible(shown)

    def parameters(self) -> tuple:
        """(RoughingParameters, Cutting) from the form; ValueError names a bad field."""
        from ..app.cam import Cutting
        from ..app.pipeline import RoughingParameters
        from ..core.simulate import Tool

        shape = self.shape.currentText()
        corner = self.corner.value() if shape == "bullnose" else 0.0
        Tool(self.diameter.value(), shape, corner)  # ParameterError names the bad size
        if not self.stepdown.value() > 0:
            raise ValueError("Step-down must be above 0 mm")
        if not self.stepover.value() >= 1:
            raise ValueError("Stepover must be at least 1 % of the diameter")
        params = RoughingParameters(
            shape=shape, diameter=self.diameter.value(), corner_radius=corner,
            stepdown=self.stepdown.value(), stepover_percent=int(self.stepover.value()),
            radial_allowance=self.radial.value(), axial_allowance=self.axial.value(),
            stock_margin=self.margin.value(), flat_levels=self.flat_levels.isChecked())
        cutting = Cutting(horizontal_feed=self.horizontal_feed.value(),
                          vertical_feed=self.vertical_feed.value(),
                          spindle_speed=self.spindle.value())
        cutting.validate()
        return params, cutting

    def accept(self) -> bool:
        def work() -> None:
            params, cutting = self.parameters()
            self.op = add_roughing(self.job, params, cutting)

        if not self.attempt("Roughing", work):
            return False
        FreeCADGui.Control.closeDialog()
        report = json.loads(self.op.Report or "{}")
        show_info("Roughing", f"{self.op.Label}: {len(report.get('levels', []))} levels, "
                  f"{report.get('cutting_length_mm', 0):.0f} mm of cutting")
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
