# SPDX-License-Identifier: LGPL-2.1-or-later
"""Every difference between FreeCAD 0.20, 1.0 and 1.1 lives here, and nowhere else.

0.20 calls its machining module "Path" with Python code under ``PathScripts``; 1.0 calls it
"CAM" with the code under ``Path.Main``, ``Path.Op``, ``Path.Tool`` and ``Path.Post``.  1.1
keeps 1.0's layout but rewrote the tool bits as assets: ``Path.Tool.toolbit`` holds one class
per shape, made with ``ToolBit.from_shape_id("ballend.fcstd")`` and put in a document with
``attach_to_doc``; the ``Factory`` of 0.20/1.0 and ``findToolShape`` are gone.  1.1 also reads
addons from a versioned user folder (``getUserAppDataDir()`` ends in ``v1-1``).
"""

from __future__ import annotations

import contextlib
import glob
import importlib
import importlib.util
import os
import sys
from collections.abc import Iterator

#: Where Debian's FreeCAD packages put FreeCAD.so, tried in order when FreeCAD is not importable.
FREECAD_LIB_DIRS = (
    "/usr/lib/freecad-python3/lib",
    "/usr/lib/freecad/lib",
    "/usr/lib/freecad-daily-python3/lib",
)


def ensure_freecad() -> object:
    """Import FreeCAD, adding Debian's library folder to sys.path from a plain python3."""
    try:
        return importlib.import_module("FreeCAD")
    except ImportError:
        pass
    extra = os.environ.get("BSPLINECAM_FREECAD_LIB")
    for folder in ([extra] if extra else []) + list(FREECAD_LIB_DIRS):
        if folder and glob.glob(os.path.join(folder, "FreeCAD*.so")):
            if folder not in sys.path:
                sys.path.append(folder)
            freecad = importlib.import_module("FreeCAD")
            _add_module_folders(freecad)
            return freecad
    raise ImportError(
        "FreeCAD is not importable: install Debian's 'freecad' package "
        "(or set BSPLINECAM_FREECAD_LIB to the folder holding FreeCAD.so)"
    )


def _add_module_folders(freecad) -> None:
    """FreeCAD imported as a library (not by freecadcmd) leaves its Mod folders off sys.path:
    add them, as freecadcmd does, so Path/CAM's Python modules import."""
    roots = [freecad.getResourceDir(), freecad.getHomePath()]
    folders = []
    for root in roots:
        folders += sorted(glob.glob(os.path.join(root, "Mod", "*")))
        folders += [os.path.join(root, "Mod"), os.path.join(root, "Ext")]  # Ext: the PySide shim
    for folder in folders:
        if os.path.isdir(folder) and folder not in sys.path:
            sys.path.append(folder)


def freecad_version() -> tuple[int, int, int]:
    """(major, minor, patch) of the running FreeCAD."""
    fc = ensure_freecad()
    parts = list(fc.Version()[:3])
    numbers = []
    for p in parts:
        digits = "".join(ch for ch in str(p) if ch.isdigit())
        numbers.append(int(digits) if digits else 0)
    return tuple(numbers)  # type: ignore[return-value]


#: The FreeCAD series BSplineCAM supports, oldest first; each newer FreeCAD counts as the
#: newest series it has reached (a 1.2 runs the 1.1 code paths).
SERIES = ("0.20", "1.0", "1.1")


def cam_series() -> str:
    """"0.20", "1.0" or "1.1": which of the supported FreeCAD series is running."""
    version = freecad_version()
    if version >= (1, 1, 0):
        return "1.1"
    if version >= (0, 22, 0):  # 0.22 was 1.0's development version
        return "1.0"
    return "0.20"


def is_freecad_1() -> bool:
    """FreeCAD 1.0 or newer (the CAM layout of ``Path.Main``, ``Path.Op``, ...)."""
    return cam_series() != "0.20"


def _pick(choices: tuple):
    """The entry of ``choices`` (one per :data:`SERIES`) for the running FreeCAD."""
    return choices[SERIES.index(cam_series())]


# --- Path (0.20) / CAM (1.0, 1.1) -----------------------------------------------------------
#: Module names of the machining workbench's pieces: (FreeCAD 0.20, 1.0, 1.1).
_CAM_MODULES = {
    "job": ("PathScripts.PathJob", "Path.Main.Job", "Path.Main.Job"),
    "op": ("PathScripts.PathOp", "Path.Op.Base", "Path.Op.Base"),
    "toolbit": ("PathScripts.PathToolBit", "Path.Tool.Bit", "Path.Tool.toolbit"),
    "controller": ("PathScripts.PathToolController", "Path.Tool.Controller", "Path.Tool.Controller"),
    "surface_op": ("PathScripts.PathSurface", "Path.Op.Surface", "Path.Op.Surface"),
    "waterline_op": ("PathScripts.PathWaterline", "Path.Op.Waterline", "Path.Op.Waterline"),
    "utils": ("PathScripts.PathUtils", "PathScripts.PathUtils", "PathScripts.PathUtils"),
    "stock": ("PathScripts.PathStock", "Path.Main.Stock", "Path.Main.Stock"),
    "setup_sheet": ("PathScripts.PathSetupSheet", "Path.Base.SetupSheet", "Path.Base.SetupSheet"),
    # GUI layer only (view providers); imported by gui/ when FreeCAD.GuiUp
    "toolbit_gui": ("PathScripts.PathToolBitGui", "Path.Tool.Gui.Bit", "Path.Tool.toolbit.ui.view"),
    "job_gui": ("PathScripts.PathJobGui", "Path.Main.Gui.Job", "Path.Main.Gui.Job"),
    "icon_gui": ("PathScripts.PathIconViewProvider", "Path.Base.Gui.IconViewProvider",
                 "Path.Base.Gui.IconViewProvider"),
}
#: Where post-processor scripts live: (FreeCAD 0.20, 1.0, 1.1).
_POST_PACKAGES = ("PathScripts.post", "Path.Post.scripts", "Path.Post.scripts")
#: Decimals of coordinates in posted programs: 0.1 µm, so rounding stays far below the 1 µm
#: gouge budget (FreeCAD's default of 3 decimals alone can move a point by 0.5 µm).
POST_PRECISION = 4
#: The post-processors BSplineCAM supports and tests.
POST_PROCESSORS = ("linuxcnc", "grbl", "fanuc", "mach3_mach4")


# The old module names under which FreeCAD 0.20 saved CAM objects live in legacy_cam (standard
# library only, so the addon's Init.py installs them at start-up without importing BSplineCAM).
from .legacy_cam import LEGACY_CAM_MODULES, install_legacy_cam_modules  # noqa: E402,F401


def cam_module(role: str):
    """The machining module playing ``role`` (job, op, toolbit, controller, surface_op,
    waterline_op, utils; in the GUI also toolbit_gui, job_gui, icon_gui).

    A FreeCAD built without its CAM (Path) workbench raises an ImportError that says so.
    """
    ensure_freecad()
    if role not in _CAM_MODULES:
        raise KeyError(f"unknown CAM module role {role!r}")
    name = _pick(_CAM_MODULES[role])
    try:
        return importlib.import_module(name)
    except ImportError as exc:
        if "Path" in str(exc) or "PathScripts" in str(exc):
            raise ImportError(
                f"this FreeCAD {'.'.join(map(str, freecad_version()))} has no CAM (Path) "
                f"workbench ({name} is missing): install the full FreeCAD (Debian: "
                "apt-get install freecad)") from exc
        raise


def post_module(name: str):
    """The post-processor script module ``NAME_post`` (a ValueError names the known ones)."""
    ensure_freecad()
    package = _pick(_POST_PACKAGES)
    known = available_posts()
    if name not in known:
        raise ValueError(f"unknown post-processor {name!r}: available are {', '.join(sorted(known))}")
    return importlib.import_module(f"{package}.{name}_post")


def available_posts() -> list[str]:
    """Names of the post-processors installed with this FreeCAD."""
    ensure_freecad()
    package = importlib.import_module(_pick(_POST_PACKAGES))
    names = []
    for folder in package.__path__:
        for path in glob.glob(os.path.join(folder, "*_post.py")):
            names.append(os.path.basename(path)[: -len("_post.py")])
    return sorted(set(names))


#: ToolBit shape file of each core tool shape (FreeCAD's Tools/Shape, the same in 0.20-1.1).
SHAPE_FILES = {"ball": "ballend.fcstd", "flat": "endmill.fcstd", "bullnose": "bullnose.fcstd"}
_SHAPE_LABELS = {"ball": "Ball end", "flat": "End mill", "bullnose": "Bull nose"}


def ballend_shape_file() -> str:
    """The ball-end ToolBit shape shipped with FreeCAD 0.20/1.0 (Tools/Shape/ballend.fcstd)."""
    return tool_shape_file("ball")


def tool_shape_file(shape: str) -> str:
    """The ToolBit shape file of a core tool shape ('ball', 'flat', 'bullnose') in 0.20/1.0."""
    name = SHAPE_FILES[shape]
    path = cam_module("toolbit").findToolShape(name)
    if not path:
        raise FileNotFoundError(f"FreeCAD's {name} tool shape was not found")
    return path


def make_ballend_bit(doc, diameter: float):
    """A ball-end ToolBit object of ``diameter`` mm in ``doc`` (which must be the active
    document: CAM's factories create objects there), made by FreeCAD's own tool-bit API."""
    return make_tool_bit(doc, "ball", diameter)


def tool_label(shape: str, diameter: float, corner_radius: float = 0.0) -> str:
    """How a tool is named in the document: "Ball end 6 mm", "Bull nose 10 mm r1"."""
    label = f"{_SHAPE_LABELS[shape]} {diameter:g} mm"
    return f"{label} r{corner_radius:g}" if shape == "bullnose" else label


def make_tool_bit(doc, shape: str, diameter: float, corner_radius: float = 0.0):
    """A ToolBit of a core tool shape ('ball', 'flat' or 'bullnose' with ``corner_radius``,
    mm) in ``doc`` (the active document), made by FreeCAD's own tool-bit API.  The bull
    nose's corner is ``CornerRadius`` in 1.1 and ``FlatRadius`` (the flat bottom's radius,
    diameter/2 - corner) in 0.20 and 1.0."""
    toolbit = cam_module("toolbit")
    label = tool_label(shape, diameter, corner_radius)
    if cam_series() == "1.1":
        asset = toolbit.ToolBit.from_shape_id(SHAPE_FILES[shape], label)
        bit = asset.attach_to_doc(doc)
    else:
        bit = toolbit.Factory.Create(label.replace(" ", ""), tool_shape_file(shape))
    bit.Label = label
    bit.Diameter = diameter
    if shape == "bullnose":
        if hasattr(bit, "CornerRadius"):
            bit.CornerRadius = corner_radius
        else:
            bit.FlatRadius = 0.5 * diameter - corner_radius
    # a long enough flute and body for the shape's sketch to close at any diameter
    if hasattr(bit, "CuttingEdgeHeight"):
        bit.CuttingEdgeHeight = max(float(bit.CuttingEdgeHeight), 30.0, diameter)
    if hasattr(bit, "Length"):
        edge = float(getattr(bit, "CuttingEdgeHeight", 0.0))
        bit.Length = max(float(bit.Length), 50.0, edge + 0.5 * diameter)
    if hasattr(bit, "ShankDiameter") and float(bit.ShankDiameter) < diameter / 4:
        bit.ShankDiameter = diameter / 2
    return bit


def core_tool_shape(bit) -> tuple[str, float, float]:
    """(core shape, diameter mm, corner radius mm) of a ToolBit: 'ball', 'flat' or
    'bullnose'; a ValueError naming the shape for any other bit (drill, v-bit, chamfer...)."""
    name = tool_shape_name(bit).lower()
    diameter = float(getattr(bit.Diameter, "Value", bit.Diameter))
    if "ball" in name:
        return "ball", diameter, 0.5 * diameter
    if "bull" in name:
        if hasattr(bit, "CornerRadius"):
            corner = float(getattr(bit.CornerRadius, "Value", bit.CornerRadius))
        else:
            flat = float(getattr(bit.FlatRadius, "Value", bit.FlatRadius))
            corner = 0.5 * diameter - flat
        return "bullnose", diameter, corner
    if "endmill" in name or "end mill" in name or name.startswith("flat"):
        return "flat", diameter, 0.0
    raise ValueError(f"tool shape {tool_shape_name(bit)!r} is not a ball, flat or bull-nose "
                     "end mill")


def opencamlib_missing_message() -> str:
    """What to install for FreeCAD's own 3D Surface op on the running FreeCAD, in one line."""
    version = ".".join(map(str, freecad_version()))
    how = _pick((
        "pip install opencamlib for Debian's python3 (tools/setup.sh does it, with an 'ocl' alias)",
        "apt-get install python3-opencamlib",
        "apt-get install python3-opencamlib",
    ))
    return (f"FreeCAD's 3D Surface op needs OpenCAMLib (Python module 'ocl' or 'opencamlib.ocl'), "
            f"which this FreeCAD {version} cannot import: {how}")


@contextlib.contextmanager
def toolbits_keep_transaction() -> Iterator[None]:
    """Tool bits made inside this context leave the caller's open transaction open.

    FreeCAD 1.1 builds a tool bit's body by opening the shape's file as a hidden document,
    copying the body into the job's document and closing the hidden one; in the GUI that close
    commits the job document's open transaction, so a command that makes a job would become
    several undo steps, and aborting it would leave half a job behind.  Here the hidden
    documents are closed only when the context ends (after the caller's transaction is
    committed or aborted).  FreeCAD 0.20 and 1.0 need nothing.
    """
    if cam_series() != "1.1":
        yield
        return
    shape_doc = importlib.import_module("Path.Tool.shape.doc")
    opener = shape_doc.ShapeDocFromBytes
    original_exit = opener.__exit__
    kept: list[str] = []

    def keep_open(self, exc_type, exc_value, traceback) -> None:
        if self._doc:
            kept.append(self._doc.Name)
            self._doc = None
        shape_doc.restore_doc_state(self._old_state)

    opener.__exit__ = keep_open
    try:
        yield
    finally:
        opener.__exit__ = original_exit
        fc = ensure_freecad()
        active = fc.ActiveDocument.Name if fc.ActiveDocument else None
        for name in kept:
            if name in fc.listDocuments():
                fc.closeDocument(name)
        if active and active in fc.listDocuments():
            fc.setActiveDocument(active)


def tool_shape_name(bit) -> str:
    """The shape a ToolBit was made from, as FreeCAD names it: ``ShapeType`` ("Ballend") or
    ``ShapeID`` in 1.1, ``ShapeName`` in 1.0, the ``BitShape`` file (ballend.fcstd) in 0.20;
    "" when the object is no ToolBit."""
    for prop in ("ShapeType", "ShapeID", "ShapeName", "BitShape"):
        value = str(getattr(bit, prop, "") or "")
        if value:
            return value
    return ""


def opencamlib_available() -> bool:
    """FreeCAD's own 3D Surface op needs OpenCAMLib, imported as ``ocl`` (0.20: the PyPI wheel
    with an alias module) or ``opencamlib.ocl`` (1.0 and 1.1: Debian's python3-opencamlib)."""
    for name in ("ocl", "opencamlib.ocl"):
        try:
            importlib.import_module(name)
            return True
        except ImportError:
            continue
    return False


def post_export(name: str, objects: list, filename: str, header: bool = False) -> str:
    """Run FreeCAD's post-processor ``name`` on ``objects``, writing ``filename``; return the text.

    Every post takes ``(objects, filename, argstring)``, but they differ: some return the text,
    some only write the file (0.20's grbl), and each parses its own options, so only those it
    knows are passed.  0.20's fanuc reads ``Tool.ToolType``, which ToolBits lack; it gets a
    stand-in tool controller that answers it.
    """
    module = post_module(name)
    wanted = ["--no-show-editor", f"--precision={POST_PRECISION}"] + ([] if header else ["--no-header"])
    parser = getattr(module, "parser", None)
    known = getattr(parser, "_option_string_actions", None)
    args = [a for a in wanted if known is None or a.split("=")[0] in known]
    objects = [_PostView(o) if hasattr(o, "Path") and not hasattr(o, "ToolNumber") else o for o in objects]
    if name == "fanuc" and not is_freecad_1():
        objects = [_LegacyToolController(o) if hasattr(o, "ToolNumber") else o for o in objects]
    text = module.export(objects, filename, " ".join(args))
    if not text and os.path.exists(filename):
        with open(filename, encoding="utf-8") as handle:
            text = handle.read()
    return text or ""


class _PathView:
    """A Path whose ``Commands`` list is built once.  ``Path.Commands`` copies every command
    out of C++ on each access, and posts such as 0.20's fanuc read it once per command, which
    makes posting quadratic (minutes for a finishing program)."""

    def __init__(self, path):
        self._path = path
        self.Commands = path.Commands

    def __getattr__(self, name):
        return getattr(self._path, name)


class _PostView:
    """An operation seen by a post-processor: everything delegated, its Path cached."""

    def __init__(self, obj):
        self._obj = obj
        self.Path = _PathView(obj.Path)

    def __getattr__(self, name):
        return getattr(self._obj, name)


class _LegacyTool:
    """A ToolBit seen through the legacy Tool API that 0.20's fanuc post reads."""

    ToolType = "BallEndMill"

    def __init__(self, bit):
        self._bit = bit

    def __getattr__(self, name):
        return getattr(self._bit, name)


class _LegacyToolController:
    def __init__(self, controller):
        self._controller = controller
        self.Tool = _LegacyTool(controller.Tool)

    def __getattr__(self, name):
        return getattr(self._controller, name)


def set_enumeration(obj, name: str, value: str) -> None:
    """Set an enumeration property, adding ``value`` to its choices when missing (0.20 lists
    only the post-processors enabled in the preferences in a job's ``PostProcessor``)."""
    choices = list(obj.getEnumerationsOfProperty(name) or [])
    if value not in choices:
        current = getattr(obj, name)
        setattr(obj, name, [*choices, value])
        if current in choices:
            setattr(obj, name, current)
    setattr(obj, name, value)


def make_proxy_restorable(obj) -> bool:
    """Keep a CAM object's Python proxy from failing to restore ("setAttr failed" in red).

    FreeCAD saves a proxy without ``dumps``/``__getstate__`` of its own through Python's
    ``object.__getstate__`` (3.11+), which gives None for an empty ``__dict__``; on reading,
    a proxy without ``loads``/``__setstate__`` then has None assigned to its ``__dict__``,
    which fails.  CAM's ToolController (0.20, 1.0 and 1.1) is such a proxy.  One attribute in
    its ``__dict__`` makes it save a dict, which restores.  True if the proxy was changed.
    """
    proxy = getattr(obj, "Proxy", None)
    if proxy is None or not hasattr(proxy, "__dict__"):
        return False
    own = {name for klass in type(proxy).__mro__[:-1] for name in vars(klass)}
    if own & {"dumps", "__getstate__", "loads", "__setstate__"} or proxy.__dict__:
        return False
    proxy.__dict__["restorable"] = True
    return True


def cam_stock_type(stock) -> str:
    """CAM's own name for the kind of a job's stock ("FromBase", "CreateBox",
    "CreateCylinder", "None" or "Unknown"), by CAM's ``StockType.FromStock`` (the same in
    0.20, 1.0 and 1.1): the hidden ``StockType`` property a GUI session adds, else the
    properties each kind carries (a cylinder's Radius and Height)."""
    return str(cam_module("stock").StockType.FromStock(stock))
