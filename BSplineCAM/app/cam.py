# SPDX-License-Identifier: LGPL-2.1-or-later
"""A standard Path/CAM Job around a B-spline surface, its ball-end tool, and post-processing.

Job, ToolBit and ToolController are FreeCAD's own (through :mod:`compat`), so the job is one a
FreeCAD user can open, edit and post like any other.  Feeds and spindle speed are always set:
FreeCAD's default tool controller has zero feed, which a real controller refuses.
"""

from __future__ import annotations

import functools
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..core import Surface
from . import compat
from .part import surface_extent
from .surface_feature import is_surface

FreeCAD = compat.ensure_freecad()

#: The post-processor of new jobs and of the pipeline when the user names none.
DEFAULT_POST = "linuxcnc"


@dataclass(frozen=True)
class Cutting:
    """Feeds (mm/min) and spindle speed (rpm) of the ball-end tool controller."""

    horizontal_feed: float = 1200.0
    vertical_feed: float = 400.0
    spindle_speed: float = 12000.0
    rapid: float = 5000.0

    def validate(self) -> None:
        for name in ("horizontal_feed", "vertical_feed", "spindle_speed", "rapid"):
            value = getattr(self, name)
            if not value > 0:
                unit = "rpm" if name == "spindle_speed" else "mm/min"
                raise ValueError(f"{name.replace('_', ' ')} must be > 0 {unit}, got {value}")


def make_ballend_controller(diameter: float, cutting: Cutting = Cutting(), number: int = 1, doc=None):
    """A ToolController holding a ball-end ToolBit of ``diameter`` mm, feeds and speed set."""
    return make_controller("ball", diameter, cutting=cutting, number=number, doc=doc)


def make_controller(shape: str, diameter: float, corner_radius: float = 0.0,
                    cutting: Cutting = Cutting(), number: int = 1, doc=None):
    """A ToolController (tool ``number``) holding a ToolBit of a core shape ('ball', 'flat',
    'bullnose' with ``corner_radius``), sizes in mm, feeds and speed set."""
    if not diameter > 0:
        raise ValueError(f"tool diameter must be > 0 mm, got {diameter}")
    cutting.validate()
    doc = doc or FreeCAD.ActiveDocument
    _activate(doc)
    bit = compat.make_tool_bit(doc, shape, diameter, corner_radius)
    tc = compat.cam_module("controller").Create(f"TC: {bit.Label}", bit, number)
    compat.make_proxy_restorable(tc)
    set_cutting(tc, cutting)
    tc.recompute()
    settle_tool_bit(bit)
    return tc


def settle_tool_bit(bit) -> None:
    """Recompute the bit and the body that draws it until none of them is touched: FreeCAD
    1.1's bit sets its sketch's sizes while it recomputes, touching the sketch, revolution
    and body again, which would make the next recompute (CAM's Post Process) redo the job;
    a sketch that cannot be built at the bit's sizes is a ValueError naming the bit."""
    doc = bit.Document
    for _ in range(3):
        objects = [bit, *bit.OutListRecursive]
        stale = [o for o in objects if "Touched" in o.State]
        if not stale:
            break
        doc.recompute(stale)
    broken = [o.Label for o in [bit, *bit.OutListRecursive] if "Invalid" in o.State]
    if broken:
        raise ValueError(f"{bit.Label}: FreeCAD cannot build the tool's shape at these sizes "
                         f"({', '.join(broken)} failed)")


def set_cutting(tc, cutting: Cutting) -> None:
    """Feeds, rapids and spindle speed (forward) of the tool controller ``tc``."""
    cutting.validate()
    tc.HorizFeed = f"{cutting.horizontal_feed} mm/min"
    tc.VertFeed = f"{cutting.vertical_feed} mm/min"
    tc.HorizRapid = f"{cutting.rapid} mm/min"
    tc.VertRapid = f"{cutting.rapid} mm/min"
    tc.SpindleSpeed = float(cutting.spindle_speed)
    tc.SpindleDir = "Forward"


def controller_cutting(tc) -> Cutting:
    """The tool controller's feeds (mm/min) and spindle speed (rpm) as a :class:`Cutting`."""
    def mm_min(quantity) -> float:  # a speed quantity (mm/s internally) or a plain number
        return float(quantity.getValueAs("mm/min")) if hasattr(quantity, "getValueAs") \
            else float(quantity)
    return Cutting(horizontal_feed=mm_min(tc.HorizFeed), vertical_feed=mm_min(tc.VertFeed),
                   spindle_speed=float(tc.SpindleSpeed), rapid=mm_min(tc.HorizRapid))


def add_controller(job, shape: str, diameter: float, corner_radius: float = 0.0,
                   cutting: Cutting = Cutting(), number: int | None = None):
    """Add a tool controller to ``job`` (number: the next free one) and return it."""
    if number is None:
        number = 1 + max((int(tc.ToolNumber) for tc in job.Tools.Group), default=0)
    tc = make_controller(shape, diameter, corner_radius, cutting, number, job.Document)
    job.Tools.addObject(tc)
    return tc


def make_job(model, tool_diameter: float, cutting: Cutting = Cutting(), name: str = "Job",
             post: str = DEFAULT_POST):
    """A Job whose model is ``model`` (a solid B-spline surface object) and whose only tool
    controller is a ball end of ``tool_diameter`` mm with ``cutting`` feeds; its stock is
    sized from the exact surface, or a part's optimal box (:class:`SurfaceStock`), and its
    PostProcessor is ``post``."""
    if model is None or not hasattr(model, "Shape") or model.Shape.isNull():
        raise ValueError("a job needs a model with a shape: create the B-spline surface first")
    compat.post_module(post)  # an unknown post-processor is named before the document changes
    doc = model.Document
    _activate(doc)
    job = compat.cam_module("job").Create(name, [model])
    use_surface_stock(job, any_model=True)
    set_post_processor(job, post)
    tc = make_ballend_controller(tool_diameter, cutting, doc=doc)
    for old in list(job.Tools.Group):
        job.Tools.removeObject(old)
        for child in old.OutList:
            if child.isDerivedFrom("Part::FeaturePython") and not child.InList[1:]:
                _remove_tool_bit(doc, child)
        doc.removeObject(old.Name)
    job.Tools.addObject(tc)
    doc.recompute()
    return job


def _remove_tool_bit(doc, bit) -> None:
    """Remove a ToolBit and the body that draws it (``BitBody``: a PartDesign body with its
    sketch, revolution and origin, which FreeCAD 1.1 leaves behind when only the bit goes)."""
    body = getattr(bit, "BitBody", None)
    name = bit.Name
    if body is not None and body.Document is doc and not [o for o in body.InList if o is not bit]:
        bit.BitBody = None
        body.removeObjectsFromDocument()
        doc.removeObject(body.Name)
    if doc.getObject(name) is not None:
        doc.removeObject(name)


def set_post_processor(job, post: str) -> None:
    """Make ``post`` the job's PostProcessor (what CAM's own post command runs), if it differs."""
    if getattr(job, "PostProcessor", post) != post:
        compat.set_enumeration(job, "PostProcessor", post)


# --- the stock and the heights from the exact surface ---------------------------------------
def _is_surface(obj) -> bool:
    return is_surface(obj)


def model_surfaces(models) -> list[tuple]:
    """(surface object, model clone or None) per BSplineCAM surface behind ``models``."""
    found = []
    for model in models:
        if _is_surface(model):
            found.append((model, None))
            continue
        for candidate in [*getattr(model, "Objects", []), *getattr(model, "OutList", [])]:
            if _is_surface(candidate):
                found.append((candidate, model))
                break
    return found


def surface_in_job(source, clone=None):
    """The core Surface of a surface object in job coordinates: its global placement and
    the job's model clone's placement applied to the control points (exact for affine maps)."""
    import numpy as np

    surface = source.Proxy.surface(source)
    matrix = source.getGlobalPlacement().toMatrix()
    if clone is not None:
        matrix = clone.Placement.toMatrix().multiply(matrix)
    affine = np.array([[matrix.A[4 * r + c] for c in range(4)] for r in range(3)])
    if not np.allclose(affine, np.eye(4)[:3]):
        points = surface.control_points @ affine[:, :3].T + affine[:, 3]
        surface = Surface(points, surface.knots, surface.name)
    return surface


def model_extent(models):
    """A FreeCAD.BoundBox of ``models``: exact for BSplineCAM surfaces (the core's evaluation
    of the surface, down to the solid's base plane), OCCT's optimal box for any other model
    (``optimalBoundingBox``: evaluated on the geometry); None when there is nothing.  Never
    OCCT's quick box of a B-spline face (``Shape.BoundBox`` encloses the poles: 12 mm above
    examples/part.step's top)."""
    box = None
    exact = model_surfaces(models)
    covered = {id(clone or source) for source, clone in exact}
    for source, clone in exact:
        e = surface_extent(surface_in_job(source, clone))
        z_min = e.z_min - float(source.BaseOffset) if getattr(source, "MakeSolid", False) else e.z_min
        part = FreeCAD.BoundBox(e.x_min, e.y_min, z_min, e.x_max, e.y_max, e.z_max)
        box = part if box is None else box.united(part)
    for model in models:
        if id(model) in covered or not hasattr(model, "Shape") or model.Shape.isNull():
            continue
        own = model.Shape.optimalBoundingBox(False)  # not from a view's mesh
        box = own if box is None else box.united(own)
    return box


def stock_box(stock):
    """The box (FreeCAD.BoundBox, job coordinates) of a stock made from the job's models:
    their exact extent plus the stock's Ext* allowances (mm); None without models."""
    group = getattr(getattr(stock, "Base", None), "Group", None)
    box = model_extent(group) if group else None
    if box is None:
        return None
    return FreeCAD.BoundBox(
        box.XMin - stock.ExtXneg.Value, box.YMin - stock.ExtYneg.Value, box.ZMin - stock.ExtZneg.Value,
        box.XMax + stock.ExtXpos.Value, box.YMax + stock.ExtYpos.Value, box.ZMax + stock.ExtZpos.Value)


@functools.cache
def _surface_stock_class():
    """:class:`SurfaceStock`, made on first use: its base is CAM's StockFromBase, whose module
    differs between the series and is imported only when a job needs it."""

    class SurfaceStock(compat.cam_module("stock").StockFromBase):
        """CAM's stock "from base" (same properties and panel), sized from the exact surface.

        CAM's own stock takes OCCT's box of the model (a B-spline face's poles, or its mesh
        once the view draws it, so the box moves with the view) and keeps the placement it had
        when it was made; this one takes :func:`stock_box` and follows the model when its
        surface changes (the stock depends on the job's model group, so a recompute updates it).
        """

        def execute(self, obj) -> None:
            box = stock_box(obj)
            if box is None:
                super().execute(obj)
                return
            import Part

            corner = FreeCAD.Vector(box.XMin, box.YMin, box.ZMin)
            placement = FreeCAD.Placement(corner, FreeCAD.Rotation())
            current = obj.Placement
            if (current.Base - corner).Length > 1e-12 or abs(current.Rotation.Angle) > 1e-12:
                obj.Placement = placement
            self.origin = FreeCAD.Vector()
            self.length, self.width, self.height = box.XLength, box.YLength, box.ZLength
            shape = Part.makeBox(box.XLength, box.YLength, box.ZLength)
            shape.Placement = placement
            obj.Shape = shape

    SurfaceStock.__module__ = __name__
    SurfaceStock.__qualname__ = "SurfaceStock"
    return SurfaceStock


def __getattr__(name: str):
    """``cam.SurfaceStock`` (what documents name as the stock's proxy class), made lazily."""
    if name == "SurfaceStock":
        return _surface_stock_class()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def use_surface_stock(job, any_model: bool = False) -> bool:
    """Give a job's stock "from base" the :class:`SurfaceStock` proxy (new jobs, and jobs
    saved before it existed) when the job machines a BSplineCAM surface, or (``any_model``:
    the jobs :func:`make_job` makes, STEP parts included) whatever its models; True if
    changed."""
    stock = getattr(job, "Stock", None)
    proxy = getattr(stock, "Proxy", None)
    base_class = compat.cam_module("stock").StockFromBase
    if stock is None or type(proxy) is not base_class or not hasattr(stock, "ExtZpos"):
        return False
    if not any_model and not model_surfaces(getattr(stock.Base, "Group", [])):
        return False
    surface_stock = _surface_stock_class()
    new = surface_stock.__new__(surface_stock)
    new.__dict__.update(getattr(proxy, "__dict__", {}))
    stock.Proxy = new
    stock.touch()
    return True


def post_objects(job) -> list:
    """Objects in posting order: per operation its tool controller (on change) and the op."""
    objects = []
    current = None
    for op in job.Operations.Group:
        if hasattr(op, "Active") and not op.Active:
            continue
        tc = getattr(op, "ToolController", None)
        if tc is not None and tc is not current:
            objects.append(tc)
            current = tc
        objects.append(op)
    return objects


def post_process(job, post: str = "linuxcnc", path: str | os.PathLike | None = None, header: bool = False,
                 remember: bool = True) -> str:
    """G-code of ``job`` by FreeCAD's post-processor ``post`` (linuxcnc, grbl, fanuc, ...).

    ``remember`` makes ``post`` the job's PostProcessor (the user's choice, which CAM's own
    post command then uses); a check that only reads the program passes False.

    The program is written to ``path`` only when complete (through a temporary file beside
    it).  Header and editor are off by default, for deterministic output.
    """
    objects = post_objects(job)
    if not objects:
        raise ValueError(f"job {job.Label!r} has no active operation to post")
    compat.post_module(post)  # an unknown post is named before anything changes
    if remember:
        set_post_processor(job, post)
    folder = Path(path).parent if path is not None else Path(tempfile.gettempdir())
    folder.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".post-", suffix=".ngc", dir=folder)
    os.close(fd)
    try:
        gcode = compat.post_export(post, objects, tmp, header)
        if not gcode.strip():
            raise RuntimeError(f"post-processor {post!r} produced no G-code")
        if not gcode.endswith("\n"):
            gcode += "\n"
        if path is not None:
            Path(tmp).write_text(gcode)
            os.replace(tmp, path)
        return gcode
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _activate(doc) -> None:
    """Path's factories create objects in the *active* document."""
    if FreeCAD.ActiveDocument is not doc:
        FreeCAD.setActiveDocument(doc.Name)
