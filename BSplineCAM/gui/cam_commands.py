# SPDX-License-Identifier: LGPL-2.1-or-later
"""The machining commands: a job with the finishing op, post-processing, and verification.

* ``BSplineCAM_Job``: a task panel asks the tool, scallop, tolerance, strategy and feeds, then
  one transaction makes the surface solid, adds a Path/CAM Job with a ball-end tool controller
  and the finishing op, and computes it (progress in the status bar, Esc interrupts); any
  failure or interruption aborts the transaction, so the document is left as it was.  With
  faces of any object selected in the 3D view instead of a surface, the job is made on that
  object and the op machines those faces (its ``Base``; the panel's face list takes more
  faces from the selection, like CAM's Base geometry page).
* ``BSplineCAM_PostProcess``: a post (linuxcnc, grbl, fanuc, mach3_mach4) and a file; the
  program is checked by LinuxCNC's ``rs274`` when installed, the result in the report view.
* ``BSplineCAM_Verify``: the selected job's program (posted to a temporary linuxcnc file), or
  a chosen G-code file on the selected surface, simulated from its text; the simulated part
  appears coloured by deviation with a colour bar fixed to the screen, and the figures in a
  task panel (selectable, with a Copy button) and the report view.

Long computations show a progress bar with a Cancel button in the status bar (Esc cancels
too; :mod:`.progress_bar`); a cancelled op keeps its previous toolpath.

Like :mod:`.commands`, the work runs through ``FreeCADGui.doCommand`` inside a transaction;
dialogs go through replaceable ``ask_*`` functions (tests answer them).
"""

from __future__ import annotations

import contextlib
import io
import json
import os
from collections.abc import Iterator
from pathlib import Path

import FreeCAD
import FreeCADGui
from PySide import QtGui

from ..app import compat
from ..app.proxy import StatelessProxy
from ..app.surface_feature import is_surface
from ..core.toolpath.common import ToolpathCancelled
from . import commands, progress_bar, results_panel
from .commands import BaseCommand, obj_ref, transaction, wait_cursor
from .messages import report_error, show_info, task_buttons
from .resources import icon

GCODE_FILTER = "G-code (*.ngc *.nc *.gcode *.tap *.txt);;All files (*)"
#: File suffix suggested per post-processor.
POST_SUFFIX = {"linuxcnc": ".ngc", "grbl": ".nc", "fanuc": ".nc", "mach3_mach4": ".tap"}


# -- dialogs (tests replace these) -----------------------------------------------------------
def ask_post(posts: list[str]) -> str:
    """Post-processor chosen from ``posts`` ('' when cancelled)."""
    name, ok = QtGui.QInputDialog.getItem(FreeCADGui.getMainWindow(), "Post-process",
                                          "Post-processor:", posts, 0, False)
    return str(name) if ok else ""


def ask_tool_diameter() -> float:
    """Ball-end diameter (mm) of a program chosen from a file (0 when cancelled)."""
    value, ok = QtGui.QInputDialog.getDouble(FreeCADGui.getMainWindow(), "Verify G-code",
                                             "Ball-end tool diameter (mm):", 6.0, 0.01, 1000.0, 3)
    return float(value) if ok else 0.0


# -- selection -------------------------------------------------------------------------------
def is_job(obj) -> bool:
    return all(hasattr(obj, name) for name in ("Operations", "Tools", "Model", "Stock"))


def is_finishing_op(obj) -> bool:
    return type(getattr(obj, "Proxy", None)).__name__ == "ObjectSurfaceFinish"


def selected_job():
    """The job of the one selected job or finishing op (None otherwise; cheap)."""
    selection = FreeCADGui.Selection.getSelection()
    if len(selection) != 1:
        return None
    obj = selection[0]
    if is_job(obj):
        return obj
    if is_finishing_op(obj):
        from ..app.verify_feature import job_of

        return job_of(obj)
    return None


def selected_surface():
    selection = FreeCADGui.Selection.getSelection()
    return selection[0] if len(selection) == 1 and is_surface(selection[0]) else None


def selected_faces() -> list[tuple[object, list[str]]]:
    """(object, face names) of the faces picked in the 3D view, in selection order (other
    sub-elements are left out: :func:`selected_non_faces` names them; cheap)."""
    out = []
    for sel in FreeCADGui.Selection.getSelectionEx():
        names = [n for n in sel.SubElementNames if n.startswith("Face")]
        if names:
            out.append((sel.Object, names))
    return out


def selected_non_faces() -> list[str]:
    """"Label.Edge12"-style names of the picked sub-elements that are not faces, and of whole
    objects picked beside faces (a job is made on faces only)."""
    selection = FreeCADGui.Selection.getSelectionEx()
    if not any(n.startswith("Face") for sel in selection for n in sel.SubElementNames):
        return []
    out = []
    for sel in selection:
        if not sel.SubElementNames:
            out.append(sel.Object.Label)
        out += [f"{sel.Object.Label}.{n}" for n in sel.SubElementNames if not n.startswith("Face")]
    return out


def non_faces_text(names: list[str]) -> str:
    """The panel's word on a selection with edges or vertices in it."""
    def kind(name: str) -> str:
        element = name.rsplit(".", 1)[-1]
        word = next((w for w in ("Edge", "Vertex") if element.startswith(w)), "")
        return f"{name} is {'an edge' if word == 'Edge' else 'a vertex' if word else 'an object'}"
    shown = ", ".join(kind(n) for n in names[:3]) + (", ..." if len(names) > 3 else "")
    return f"select faces only: {shown}; left out of the job"


def faces_extent(faces) -> tuple[float, float]:
    """(x, y) mm of the box around the faces (their objects' placements applied)."""
    box = None
    for obj, names in faces:
        for name in names:
            b = obj.Shape.getElement(name).BoundBox
            if box is None:
                box = b
            else:
                box = FreeCAD.BoundBox(box)
                box.add(b)
    return (0.0, 0.0) if box is None else (float(box.XLength), float(box.YLength))


def check_tool_fits(diameter: float, faces) -> None:
    """ValueError when a ball of ``diameter`` mm is wider than every side of the faces' box."""
    x, y = faces_extent(faces)
    if diameter > max(x, y) > 0:
        raise ValueError(f"the {diameter:g} mm ball is larger than the selected faces "
                         f"({x:.1f} x {y:.1f} mm): choose a tool of at most {max(x, y):.1f} mm")


def faces_text(faces) -> str:
    return "; ".join(f"{obj.Label}: {', '.join(names)}" for obj, names in faces)


def gui_ref(obj) -> str:
    return f"Gui.getDocument({obj.Document.Name!r}).getObject({obj.Name!r})"


class FinishOpViewProvider(StatelessProxy):
    """Icon of the finishing op in the job's tree; the op is edited in the property view."""

    def __init__(self, vobj) -> None:
        vobj.Proxy = self

    def attach(self, vobj) -> None:
        self.ViewObject = vobj

    def getIcon(self) -> str:  # noqa: N802 - FreeCAD API
        return icon("job")


def attach_job_view_providers(job, op, provider=None) -> None:
    """What CAM's own job command does in the GUI: the job's tree and icons, tool bit hidden."""
    if job.ViewObject is not None and job.ViewObject.Proxy is None:
        job.ViewObject.Proxy = compat.cam_module("job_gui").ViewProvider(job.ViewObject)
        job.ViewObject.addExtension("Gui::ViewProviderGroupExtensionPython")
        job.ViewObject.Proxy.deleteOnReject = False
    for tc in job.Tools.Group:
        bit = getattr(tc, "Tool", None)
        if bit is not None and bit.ViewObject is not None:
            if bit.ViewObject.Proxy is None:
                compat.cam_module("icon_gui").Attach(bit.ViewObject, "ToolBit")
            bit.ViewObject.Visibility = False
    if op.ViewObject is not None:
        (provider or FinishOpViewProvider)(op.ViewObject)


# -- the job ---------------------------------------------------------------------------------
@contextlib.contextmanager
def app_toolbit_factory() -> Iterator[None]:
    """CAM's GUI tool-bit factory opens and *commits* a transaction of its own, which would
    commit half of ours; the app factory it wraps makes the same bit without that.  The GUI
    module installs its factory when first imported (FreeCAD 1.0 imports it lazily, while
    the job is being made), so it is imported before the swap."""
    compat.cam_module("toolbit_gui")
    toolbit = compat.cam_module("toolbit")
    saved = getattr(toolbit, "Factory", None)
    plain = getattr(toolbit, "ToolBitFactory", None)
    if saved is None or plain is None or type(saved) is plain:
        yield
        return
    toolbit.Factory = plain()
    try:
        yield
    finally:
        toolbit.Factory = saved


def _cutting_source(cutting) -> str:
    """The console line's cam.Cutting(...) for ``cutting``."""
    return (f"cam.Cutting(horizontal_feed={cutting.horizontal_feed!r}, "
            f"vertical_feed={cutting.vertical_feed!r}, "
            f"spindle_speed={cutting.spindle_speed!r}, rapid={cutting.rapid!r})")


def _finish_op(params, doc, before: set) -> tuple:
    """Set the new op's parameters from ``params`` (on the console), find the job and op made
    since ``before``, recompute and check; returns (job, op)."""
    for prop, value in (("Strategy", params.strategy), ("ScallopHeight", params.scallop),
                        ("Tolerance", params.tolerance), ("Angle", params.angle),
                        ("Direction", params.direction),
                        ("IsoDirection", params.iso_direction), ("Arcs", params.arcs)):
        FreeCADGui.doCommand(f"op.{prop} = {value!r}")
    made = [o for o in doc.Objects if o.Name not in before]
    job = next(o for o in made if is_job(o))
    op = next(o for o in made if is_finishing_op(o))
    attach_job_view_providers(job, op)
    try:
        FreeCADGui.doCommand(f"App.getDocument({doc.Name!r}).recompute()")
    finally:
        progress_bar.finish()
    check_op(op)
    return job, op


def create_job(surface, params, cutting) -> tuple:
    """One transaction: solid model, job, ball-end controller, finishing op, computed.

    Raises (and aborts, leaving the document as it was) if the op fails or is interrupted.
    """
    doc = surface.Document
    before = {o.Name for o in doc.Objects}
    with wait_cursor(), app_toolbit_factory(), compat.toolbits_keep_transaction(), \
            transaction("BSplineCAM job", doc):
        cut = _cutting_source(cutting)
        FreeCADGui.doCommand("from BSplineCAM.app import cam, finishing_op")
        FreeCADGui.doCommand(f"surface = {obj_ref(surface)}")
        if not surface.MakeSolid:
            FreeCADGui.doCommand("surface.MakeSolid = True")
            FreeCADGui.doCommand("surface.recompute()")
        FreeCADGui.doCommand(f"job = cam.make_job(surface, {params.tool_diameter!r}, {cut})")
        FreeCADGui.doCommand("op = finishing_op.Create('SurfaceFinish', parentJob=job)")
        FreeCADGui.doCommand("op.Surface = surface")
        set_output_file(next(o for o in doc.Objects if o.Name not in before and is_job(o)))
        job, op = _finish_op(params, doc, before)
    FreeCADGui.doCommand(f"{gui_ref(surface)}.Visibility = False")  # the job's clone shows it
    return job, op


def create_faces_job(faces, params, cutting) -> tuple:
    """:func:`create_job` for faces of any object: the job's model is the first face's object,
    the op's ``Base`` the faces (one transaction, aborted on any failure)."""
    model = faces[0][0]
    doc = model.Document
    before = {o.Name for o in doc.Objects}
    with wait_cursor(), app_toolbit_factory(), compat.toolbits_keep_transaction(), \
            transaction("BSplineCAM job", doc):
        cut = _cutting_source(cutting)
        FreeCADGui.doCommand("from BSplineCAM.app import cam, finishing_op")
        FreeCADGui.doCommand(f"model = {obj_ref(model)}")
        FreeCADGui.doCommand(f"job = cam.make_job(model, {params.tool_diameter!r}, {cut})")
        FreeCADGui.doCommand("op = finishing_op.Create('SurfaceFinish', parentJob=job)")
        base = ", ".join(f"({obj_ref(obj)}, {list(names)!r})" for obj, names in faces)
        FreeCADGui.doCommand(f"op.Base = [{base}]")
        set_output_file(next(o for o in doc.Objects if o.Name not in before and is_job(o)))
        job, op = _finish_op(params, doc, before)
    if model.ViewObject is not None and model.ViewObject.Visibility:
        FreeCADGui.doCommand(f"{gui_ref(model)}.Visibility = False")  # the job's clone shows it
    return job, op


#: Where a job's programs go when its document has a file: beside it, named after the job
#: (CAM's own substitutions: %D the document's folder, %j the job's label).
OUTPUT_BESIDE_DOCUMENT = "%D/%j.ngc"


def output_file_for(job) -> str:
    """The PostProcessorOutputFile a new job gets: beside its saved document, or (a document
    never saved) in the folder of FreeCAD's last file dialog, else the home folder."""
    doc = job.Document
    if doc.FileName:
        return OUTPUT_BESIDE_DOCUMENT
    general = FreeCAD.ParamGet("User parameter:BaseApp/Preferences/General")
    folder = general.GetString("FileOpenSavePath", "") or os.path.expanduser("~")
    if not os.path.isdir(folder):
        folder = os.path.expanduser("~")
    return os.path.join(folder, f"{doc.Label}-{job.Label}.ngc")


def set_output_file(job) -> None:
    """Give a new job its output file (:func:`output_file_for`; one it has is kept), on the
    console like the rest of the job, and say where programs go."""
    if getattr(job, "PostProcessorOutputFile", "") or not hasattr(job, "PostProcessorOutputFile"):
        return
    path = output_file_for(job)
    FreeCADGui.doCommand(f"job.PostProcessorOutputFile = {path!r}")
    FreeCAD.Console.PrintMessage(f"BSplineCAM: {job.Label} posts its program to {path} (the "
                                 "job's PostProcessorOutputFile)\n")


def check_op(op) -> None:
    """Raise if the op's computation failed or was interrupted (its toolpath is unusable)."""
    if progress_bar.cancelled(op):
        raise ToolpathCancelled(f"{op.Label}: cancelled by the user; nothing was changed")
    status = op.getStatusString() if hasattr(op, "getStatusString") else ""
    if "interrupted" in status:
        raise ToolpathCancelled(f"{op.Label}: {status}; nothing was changed")
    report = json.loads(op.Report or "{}")
    if not op.isValid() or "error" in report or not op.Path.Commands:
        why = report.get("error") or status or "no toolpath was produced"
        raise ValueError(f"{op.Label}: {why}")


def spin(value: float, low: float, high: float, decimals: int, suffix: str, step: float):
    """A double spin box of a task panel."""
    box = QtGui.QDoubleSpinBox()
    box.setRange(low, high)
    box.setDecimals(decimals)
    box.setSingleStep(step)
    box.setSuffix(suffix)
    box.setValue(value)
    return box


class PanelBase:
    """OK and Cancel of the machining task panels; ``attempt`` runs the work of OK."""

    def new_form(self, title: str):
        """The panel's widget with a form layout (narrow docks put labels above fields)."""
        self.form = QtGui.QWidget()
        self.form.setWindowTitle(title)  # short: the task box is as wide as its title
        self.form.setWindowIcon(QtGui.QIcon(icon("job")))
        layout = QtGui.QFormLayout(self.form)
        layout.setRowWrapPolicy(QtGui.QFormLayout.WrapLongRows)
        layout.setFieldGrowthPolicy(QtGui.QFormLayout.AllNonFixedFieldsGrow)
        self.layout = layout
        return layout

    def make_cutting_fields(self) -> None:
        """The feed and spindle boxes (laid out by :meth:`cutting_rows`, read by
        :meth:`cutting`), from the defaults of :class:`~BSplineCAM.app.cam.Cutting`."""
        from ..app.cam import Cutting

        self.horizontal_feed = spin(Cutting.horizontal_feed, 0.0, 100000.0, 0, " mm/min", 100.0)
        self.vertical_feed = spin(Cutting.vertical_feed, 0.0, 100000.0, 0, " mm/min", 50.0)
        self.spindle = spin(Cutting.spindle_speed, 0.0, 100000.0, 0, " rpm", 500.0)
        self.rapid = Cutting.rapid

    def cutting_rows(self) -> tuple:
        """(label, widget, tooltip) rows of the feed and spindle fields."""
        return (("Horizontal feed", self.horizontal_feed, "Cutting feed"),
                ("Vertical feed", self.vertical_feed, "Plunge feed"),
                ("Spindle speed", self.spindle, "Spindle speed (forward)"))

    def set_cutting(self, cutting) -> None:
        self.horizontal_feed.setValue(cutting.horizontal_feed)
        self.vertical_feed.setValue(cutting.vertical_feed)
        self.spindle.setValue(cutting.spindle_speed)
        self.rapid = cutting.rapid

    def cutting(self):
        """The fields' :class:`~BSplineCAM.app.cam.Cutting`; ValueError names a bad one."""
        from ..app.cam import Cutting

        cutting = Cutting(horizontal_feed=self.horizontal_feed.value(),
                          vertical_feed=self.vertical_feed.value(),
                          spindle_speed=self.spindle.value(), rapid=self.rapid)
        cutting.validate()
        return cutting

    def add_message(self) -> None:
        """The red line under the fields where a refusal is explained."""
        self.message = QtGui.QLabel("")
        self.message.setWordWrap(True)
        self.message.setStyleSheet("color: #b00000")
        self.layout.addRow(self.message)

    def attempt(self, title: str, work) -> bool:
        """Run ``work()``; on failure or interruption say why in the panel (and a dialog for
        a failure) and return False, the panel staying open for a retry."""
        try:
            work()
        except ToolpathCancelled as exc:
            self.message.setText(f"Interrupted: {exc}")
            FreeCAD.Console.PrintWarning(f"BSplineCAM {title.lower()}: {exc}\n")
            return False
        except Exception as exc:  # noqa: BLE001 - a message, the panel stays for a retry
            text = str(exc) if isinstance(exc, ValueError) else f"{type(exc).__name__}: {exc}"
            self.message.setText(text)
            report_error(title, text)
            return False
        return True

    def getStandardButtons(self) -> int:  # noqa: N802 - FreeCAD API
        return task_buttons(QtGui.QDialogButtonBox.Ok, QtGui.QDialogButtonBox.Cancel)

    def reject(self) -> bool:
        FreeCADGui.Control.closeDialog()
        return True


class JobPanel(PanelBase):
    """Task panel of the job's parameters; OK validates, computes, and closes on success."""

    #: The panel last opened (for scripting and tests; not saved).
    last: JobPanel | None = None

    def __init__(self, surface, faces=None) -> None:
        from ..app.finishing_op import DIRECTIONS, ISO_DIRECTIONS, STRATEGIES

        self.surface = surface
        self.faces = [(obj, list(names)) for obj, names in (faces or [])]
        self.job = self.op = None
        layout = self.new_form("Machining job")

        def combo(items, current):
            box = QtGui.QComboBox()
            box.addItems(items)
            box.setCurrentIndex(items.index(current))
            return box

        self.tool = spin(6.0, 0.0, 100.0, 3, " mm", 0.5)
        self.scallop = spin(0.01, 0.0, 10.0, 4, " mm", 0.005)
        self.tolerance = spin(0.002, 0.0, 1.0, 4, " mm", 0.001)
        self.strategy = combo(STRATEGIES, "raster")
        self.angle = spin(0.0, -360.0, 360.0, 2, " °", 15.0)
        self.direction = combo(DIRECTIONS, "zigzag")
        self.iso_direction = combo(ISO_DIRECTIONS, "u")
        self.make_cutting_fields()
        if surface is not None:
            target = QtGui.QLabel(surface.Label)
            target.setWordWrap(True)
            layout.addRow("Surface", target)
        else:
            self.add_face_list(layout)
        for label, widget, tip in (
            ("Ball-end diameter", self.tool, "Diameter of the ball-end cutter"),
            ("Scallop height", self.scallop, "Largest cusp left between passes"),
            ("Tolerance", self.tolerance, "Chordal tolerance along a pass"),
            ("Strategy", self.strategy, "raster (drop-cutter), waterline or isoparametric"),
            ("Raster angle", self.angle, "Direction of raster passes in the XY plane"),
            ("Direction", self.direction, "zigzag or one-way raster passes"),
            ("Iso direction", self.iso_direction, "Parameter followed by isoparametric passes"),
            *self.cutting_rows(),
        ):
            widget.setToolTip(tip)
            widget.setMinimumWidth(60)
            layout.addRow(label, widget)
        self.add_message()
        self.strategy.currentIndexChanged.connect(self.show_strategy_fields)
        self.show_strategy_fields()
        JobPanel.last = self

    def add_face_list(self, layout) -> None:
        """The faces to machine, with "Add selected faces" and "Remove" (CAM's Base page)."""
        self.face_list = QtGui.QListWidget()
        self.face_list.setSelectionMode(QtGui.QAbstractItemView.ExtendedSelection)
        self.face_list.setMaximumHeight(120)
        self.face_list.setToolTip("Faces the op machines; every other face of the model is "
                                  "a check surface, never cut")
        add = QtGui.QPushButton("Add selected faces")
        add.setToolTip("Add the faces selected in the 3D view")
        remove = QtGui.QPushButton("Remove")
        remove.setToolTip("Remove the faces selected in this list")
        add.clicked.connect(self.add_selected_faces)
        remove.clicked.connect(self.remove_faces)
        buttons = QtGui.QHBoxLayout()
        buttons.addWidget(add)
        buttons.addWidget(remove)
        layout.addRow("Faces", self.face_list)
        layout.addRow(buttons)
        self.fill_face_list()

    def fill_face_list(self) -> None:
        self.face_list.clear()
        for obj, names in self.faces:
            for name in names:
                self.face_list.addItem(f"{obj.Label}.{name}")

    def add_selected_faces(self, *_args) -> None:
        for obj, names in selected_faces():
            for known, chosen in self.faces:
                if known is obj:
                    chosen.extend(n for n in names if n not in chosen)
                    break
            else:
                self.faces.append((obj, list(names)))
        self.fill_face_list()

    def remove_faces(self, *_args) -> None:
        gone = {item.text() for item in self.face_list.selectedItems()}
        self.faces = [(obj, kept) for obj, names in self.faces
                      if (kept := [n for n in names if f"{obj.Label}.{n}" not in gone])]
        self.fill_face_list()

    #: The fields each strategy reads (the others are hidden).
    STRATEGY_FIELDS = {"raster": ("angle", "direction"), "waterline": (),
                       "isoparametric": ("iso_direction", "direction"),
                       "steep_shallow": ("angle",), "scallop": ()}

    def show_strategy_fields(self, *_args) -> None:
        """Show the raster angle, direction and iso direction only where they apply."""
        wanted = self.STRATEGY_FIELDS.get(self.strategy.currentText(), ())
        for name in ("angle", "direction", "iso_direction"):
            widget = getattr(self, name)
            shown = name in wanted
            widget.setVisible(shown)
            label = self.layout.labelForField(widget)
            if label is not None:
                label.setVisible(shown)

    def parameters(self) -> tuple:
        """(FinishingParameters, Cutting) from the form; ValueError names a bad field."""
        from ..app.pipeline import FinishingParameters
        from ..core.toolpath.common import ToolParameters

        tool = ToolParameters.validate(self.tool.value(), self.scallop.value(),
                                       self.tolerance.value(),
                                       ("Ball-end diameter", "Scallop height", "Tolerance"))
        params = FinishingParameters(
            tool_diameter=tool.diameter, scallop=tool.scallop,
            tolerance=tool.tolerance, strategy=self.strategy.currentText(),
            angle=self.angle.value(), direction=self.direction.currentText(),
            iso_direction=self.iso_direction.currentText(),
            # FreeCAD's path view cannot draw the R-form G18/G19 arcs the posts need: a job
            # made here shows whole passes; the op's Arcs property turns arcs on
            arcs=False)
        return params, self.cutting()

    def accept(self) -> bool:
        """Validate, compute; the panel stays open (with the reason) when anything fails."""
        def work() -> None:
            params, cutting = self.parameters()
            if self.surface is not None:
                self.job, self.op = create_job(self.surface, params, cutting)
            elif not self.faces:
                raise ValueError("no face to machine: select faces in the 3D view and press "
                                 "Add selected faces")
            else:
                check_tool_fits(params.tool_diameter, self.faces)
                self.job, self.op = create_faces_job(self.faces, params, cutting)

        if not self.attempt("Machining job", work):
            return False
        FreeCADGui.Control.closeDialog()
        report = json.loads(self.op.Report or "{}")
        show_info("Machining job", f"{self.job.Label}: {report.get('passes', '?')} passes, "
                  f"{report.get('cutting_length_mm', 0):.0f} mm of cutting")
        FreeCADGui.Selection.clearSelection()
        FreeCADGui.Selection.addSelection(self.job)
        return True


class MakeJob(BaseCommand):
    name = "BSplineCAM_Job"
    pixmap = "job"
    menu_text = "Machining job..."
    tool_tip = ("Make a Path/CAM job finishing the selected surface, or the faces selected "
                "in the 3D view, with a ball end: tool, scallop height, tolerance, strategy "
                "and feeds in a task panel")

    def active(self) -> bool:
        return ((selected_surface() is not None or bool(selected_faces()))
                and not results_panel.editing_dialog())

    def run(self) -> None:
        surface = selected_surface()
        faces = [] if surface is not None else selected_faces()
        left_out = [] if surface is not None else selected_non_faces()
        results_panel.close_results()
        panel = JobPanel(surface, faces)
        if left_out:
            panel.message.setText(non_faces_text(left_out))
        FreeCADGui.Control.showDialog(panel)


# -- post-processing -------------------------------------------------------------------------
@contextlib.contextmanager
def quiet_posts() -> Iterator[None]:
    """FreeCAD's post scripts print chatter ("Show editor = 0", "postprocessing...") to
    stdout, which the GUI shows in the report view: keep it in FreeCAD's log instead."""
    chatter = io.StringIO()
    try:
        with contextlib.redirect_stdout(chatter):
            yield
    finally:
        for line in chatter.getvalue().splitlines():
            if line.strip():
                FreeCAD.Console.PrintLog(f"post-processor: {line}\n")


def tool_table(job) -> dict[int, float]:
    return {int(tc.ToolNumber): float(tc.Tool.Diameter) for tc in job.Tools.Group}


class PostProcess(BaseCommand):
    name = "BSplineCAM_PostProcess"
    pixmap = "post"
    menu_text = "Post-process..."
    tool_tip = ("Write the selected job's G-code with a post-processor (linuxcnc, grbl, fanuc, "
                "mach3_mach4) and check it with LinuxCNC's rs274")

    #: rs274's verdict on the last program written (dict, for scripting and tests).
    last_check: dict | None = None

    def active(self) -> bool:
        return selected_job() is not None

    def run(self) -> None:
        from ..core.program import rs274

        job = selected_job()
        available = set(compat.available_posts())
        posts = [p for p in compat.POST_PROCESSORS if p in available]
        post = ask_post(posts)
        if not post:
            return
        path = commands.ask_save_file(f"G-code ({post})", GCODE_FILTER,
                                      f"{job.Label}{POST_SUFFIX.get(post, '.nc')}")
        if not path:
            return
        with wait_cursor(), transaction("Post-process", job.Document), quiet_posts():
            FreeCADGui.doCommand("from BSplineCAM.app import cam")
            FreeCADGui.doCommand(f"cam.post_process({obj_ref(job)}, {post!r}, {path!r})")
        if not os.path.isfile(path):
            raise OSError(f"{path}: nothing was written")
        lines = len(Path(path).read_text(encoding="utf-8").splitlines())
        FreeCAD.Console.PrintMessage(f"BSplineCAM: {job.Label} posted by {post} to {path} "
                                     f"({lines} lines)\n")
        if not rs274.available():
            PostProcess.last_check = None
            FreeCAD.Console.PrintWarning("BSplineCAM: rs274 (LinuxCNC) is not installed; the "
                                         "program was not checked\n")
            return
        with wait_cursor():
            result = rs274.check(path, tool_table(job))
        PostProcess.last_check = result.as_dict()
        if result.ok:
            show_info("rs274", f"{os.path.basename(path)} OK: {result.feeds} feeds, "
                      f"{result.traverses} rapids, {result.arcs} arcs")
        else:
            FreeCAD.Console.PrintError(f"rs274 rejects {path}: {result.message}\n")


# -- verification ----------------------------------------------------------------------------
class Verify(BaseCommand):
    name = "BSplineCAM_Verify"
    pixmap = "verify"
    menu_text = "Verify G-code..."
    tool_tip = ("Simulate the selected job's program (or a G-code file on the selected "
                "surface) on a Z-map and show the part coloured by deviation: blue material "
                "left, green on design, red gouge; the figures in a task panel")

    def active(self) -> bool:
        return selected_job() is not None or selected_surface() is not None

    def run(self) -> None:
        job = selected_job()
        surface = None if job is not None else selected_surface()
        if job is None and surface is None:
            raise ValueError("select a job, a finishing op, or a surface and a G-code file")
        doc = (job or surface).Document
        before = {o.Name for o in doc.Objects}
        if job is not None:
            call = f"verify_feature.verify_job({obj_ref(job)})"
        else:
            path = commands.ask_open_file("G-code to verify", GCODE_FILTER)
            if not path:
                return
            diameter = ask_tool_diameter()
            if not diameter > 0:
                return
            call = f"verify_feature.verify_file({obj_ref(surface)}, {path!r}, {diameter!r})"
        earlier = progress_bar.ProgressBar.last
        try:
            with wait_cursor(), transaction("Verify G-code", doc), quiet_posts():
                FreeCADGui.doCommand("from BSplineCAM.app import verify_feature")
                FreeCADGui.doCommand(f"verification = {call}")
        except Exception as exc:
            # doCommand may hand the core's ToolpathCancelled on as another exception type
            last = progress_bar.ProgressBar.last
            if not (isinstance(exc, ToolpathCancelled)
                    or (last is not earlier and last is not None and last.cancelled)):
                raise
            done = 100 * last.fraction if last is not None else 0.0
            FreeCAD.Console.PrintMessage(f"Verify G-code: cancelled by the user at {done:.0f} % "
                                         "of the work; nothing was changed\n")
            return
        finally:
            progress_bar.finish()
        made = [o for o in doc.Objects if o.Name not in before]
        for obj in hidden_by_verification(job, surface):
            FreeCADGui.doCommand(f"{gui_ref(obj)}.Visibility = False")
        result = next((o for o in made if o.TypeId == "Mesh::FeaturePython"), None)
        if result is not None:
            metrics = json.loads(result.Metrics)
            show_info("Verification", f"gouge max {metrics['gouge_max_mm']:.4f} mm, scallop "
                      f"max {metrics['scallop_max_mm']:.4f} mm, coverage "
                      f"{100 * metrics['coverage']:.1f} %")
            # unselected: the selection colour would hide the deviation map
            FreeCADGui.Selection.clearSelection()
            results_panel.show(results_panel.verification_panel(result))


def hidden_by_verification(job, surface) -> list:
    """What would hide the simulated part: the design, the job's model, stock and paths."""
    hide = []
    if job is not None:
        hide += list(job.Model.Group) + [job.Stock] + list(job.Operations.Group)
        hide += [o.Surface for o in job.Operations.Group if getattr(o, "Surface", None)]
    if surface is not None:
        hide.append(surface)
    return [o for o in hide if o is not None and o.ViewObject is not None
            and o.ViewObject.Visibility]


#: The machining commands by toolbar: (toolpath commands, verify commands).
TOOLPATH = (MakeJob, PostProcess)
VERIFY = (Verify,)


def register() -> list[str]:
    """Register the commands with FreeCAD (idempotent); return their names."""
    for command in (*TOOLPATH, *VERIFY):
        FreeCADGui.addCommand(command.name, command())
    return [command.name for command in (*TOOLPATH, *VERIFY)]
