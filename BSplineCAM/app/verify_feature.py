# SPDX-License-Identifier: LGPL-2.1-or-later
"""The "simulated part" document object: a verification's Z-map as a mesh, with its deviation.

:func:`make_verification` reads G-code *text* (what a controller would run), simulates it on a
Z-map against the exact design (:func:`BSplineCAM.core.simulation.verify.verify`) and stores the result
as a ``Mesh::FeaturePython``: the machined top surface triangulated at every ``Stride``-th
cell centre, closed by walls and a base into a block, plus per top vertex the deviation
(machined - design, mm) in ``Deviation`` and the metrics (JSON) in ``Metrics``.  The object is
a snapshot of one program: nothing is recomputed from its properties; the view provider
(gui layer) colours the mesh from ``Deviation``.

Vertex order of the mesh: the top grid first, row by row (``GridRows`` x ``GridColumns``,
rows along y), vertex ``r * GridColumns + c`` at the Z-map cell ``(r * Stride, c * Stride)``
(the last row and column are always included), then the base vertices.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core import Surface
from ..core.geometry.footprint import footprint_bounds
from ..core.program.gcode import read_gcode
from ..core.simulation.gouge_normal import gouge_gate_mm
from ..core.simulation.simulate import Simulation, Tool
from ..core.simulation.verify import Verification, verify, verify_faces
from ..core.simulation.verify import verify_job as verify_job_program
from . import cam, compat
from .finishing_op import ObjectSurfaceFinish, find_surface_object
from .load_limits import job_load_limits
from .progress import StatusProgress
from .proxy import StatelessProxy, add_missing_properties
from .roughing_op import ObjectSurfaceRough
from .stock_left import core_tool, job_stock
from .surface_feature import surface_of

FreeCAD = compat.ensure_freecad()

OBJECT_VERSION = "1"
TYPE_NAME = "BSplineCAM::Verification"
#: Largest number of top-grid vertices along one side of the mesh (the stride follows).
MAX_MESH_SIDE = 200
#: Depth of the mesh block's base below the lowest machined point (mm).
BASE_DEPTH_MM = 5.0
#: Default Z-map cells along the footprint's longer side (cell size = side / this).
DEFAULT_CELLS = 400
PROP_READONLY = 1
PROP_OUTPUT = 8

#: (type, name, group, tooltip) of the object's properties.
PROPERTIES: tuple[tuple[str, str, str, str], ...] = (
    ("App::PropertyLink", "Surface", "Verification", "Design surface the program was verified on"),
    ("App::PropertyLink", "Job", "Verification", "Job whose program was verified (if any)"),
    ("App::PropertyString", "Program", "Verification", "Source of the G-code (file or post)"),
    ("App::PropertyLength", "ToolDiameter", "Verification", "Ball-end diameter simulated"),
    ("App::PropertyLength", "Cell", "Verification", "Z-map cell size"),
    ("App::PropertyInteger", "Stride", "Mesh", "Z-map cells between mesh vertices"),
    ("App::PropertyInteger", "GridRows", "Mesh", "Top-grid vertex rows (along y)"),
    ("App::PropertyInteger", "GridColumns", "Mesh", "Top-grid vertex columns (along x)"),
    ("App::PropertyFloatList", "Deviation", "Mesh",
     "Machined - design per top vertex (mm; 1e9 off the footprint)"),
    ("App::PropertyString", "Metrics", "Verification",
     "Gouge, scallop, coverage, lengths and times of the program (JSON)"),
    ("App::PropertyLinkList", "StockAfter", "Verification",
     "The stock after each tool but the last (meshes, hidden at first), for a job with "
     "roughing"),
    ("App::PropertyString", "Version", "Base", "Version of the BSplineCAM verification object"),
)
#: Stored in ``Deviation`` for vertices off the design's footprint (a float list holds no NaN).
OFF_FOOTPRINT = 1e9


class VerificationFeature(StatelessProxy):
    """Proxy of the simulated-part mesh: properties only, no recomputation (a snapshot)."""

    Type = TYPE_NAME

    def __init__(self, obj) -> None:
        obj.Proxy = self
        self.ensure_properties(obj)

    @staticmethod
    def ensure_properties(obj) -> None:
        add_missing_properties(obj, [
            (kind, name, group, tip,
             0 if name in ("Surface", "Job", "StockAfter") else PROP_READONLY | PROP_OUTPUT, None)
            for kind, name, group, tip in PROPERTIES])
        for name in ("Deviation",):
            obj.setEditorMode(name, 2)  # hidden: thousands of numbers
        if obj.Version != OBJECT_VERSION:
            obj.Version = OBJECT_VERSION

    def execute(self, obj) -> None:
        """Nothing to do: the mesh and deviation are the stored result of one simulation."""

    def onDocumentRestored(self, obj) -> None:  # noqa: N802 - FreeCAD API
        self.ensure_properties(obj)


def is_verification(obj) -> bool:
    return getattr(getattr(obj, "Proxy", None), "Type", None) == TYPE_NAME


@dataclass(frozen=True)
class ZMapMesh:
    """Vertices (n, 3), triangles (m, 3) and the top grid's shape, stride and deviation."""

    points: np.ndarray
    facets: np.ndarray
    rows: int
    columns: int
    stride: int
    deviation: np.ndarray  # (rows * columns,), NaN off the footprint


def grid_indices(n: int, stride: int) -> np.ndarray:
    """0, stride, 2 stride, ... and always n - 1 (the Z-map's far edge)."""
    index = np.arange(0, n, stride)
    if index[-1] != n - 1:
        index = np.append(index, n - 1)
    return index


def auto_stride(shape: tuple[int, int], max_side: int = MAX_MESH_SIDE) -> int:
    return max(1, math.ceil((max(shape) - 1) / max(1, max_side - 1)))


def zmap_mesh(result: Verification, stride: int | None = None,
              base_depth: float = BASE_DEPTH_MM) -> ZMapMesh:
    """Triangulate the machined Z-map at every ``stride``-th cell centre, closed into a block.

    Each grid quad is split along its diagonal into two triangles (normals up); walls along
    the four sides reach a flat base ``base_depth`` mm below the lowest machined point, closed
    by a fan around the base's centre (the last vertex).
    """
    sim = result.simulation
    height = np.asarray(sim.height, dtype=float)
    ny, nx = height.shape
    stride = auto_stride((ny, nx)) if stride is None else int(stride)
    if stride < 1:
        raise ValueError(f"stride must be >= 1 cell, got {stride}")
    rows, cols = grid_indices(ny, stride), grid_indices(nx, stride)
    if len(rows) < 2 or len(cols) < 2:
        raise ValueError(f"the Z-map ({ny} x {nx} cells) is too small to triangulate")
    xs, ys = sim.grid.centres()
    gx, gy = np.meshgrid(xs[cols], ys[rows])
    top = np.column_stack([gx.ravel(), gy.ravel(), height[np.ix_(rows, cols)].ravel()])
    nr, nc = len(rows), len(cols)
    idx = np.arange(nr * nc).reshape(nr, nc)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    facets = [np.column_stack([a, b, c]), np.column_stack([a, c, d])]
    # the boundary loop counter-clockwise seen from above, and one base vertex under each
    ring = np.concatenate([idx[0, :], idx[1:, -1], idx[-1, -2::-1], idx[-2:0:-1, 0]])
    base_z = float(np.min(height)) - base_depth
    base = top[ring].copy()
    base[:, 2] = base_z
    first = len(top)
    nb = len(ring)
    bi = first + np.arange(nb)
    nxt = np.roll(np.arange(nb), -1)
    # walls: outward normals for a counter-clockwise ring
    facets.append(np.column_stack([ring, bi, bi[nxt]]))
    facets.append(np.column_stack([ring, bi[nxt], ring[nxt]]))
    # base: a fan around its centre, normals down
    centre = np.array([[*base[:, :2].mean(axis=0), base_z]])
    facets.append(np.column_stack([np.full(nb, first + nb), bi[nxt], bi]))
    deviation = (height - np.where(result.inside, result.design, np.nan))[np.ix_(rows, cols)]
    return ZMapMesh(np.vstack([top, base, centre]), np.vstack(facets).astype(np.int64), nr, nc,
                    stride, deviation.ravel())


def to_mesh(data: ZMapMesh):
    """A FreeCAD ``Mesh.Mesh`` with the vertices in the given order (topological build)."""
    import Mesh

    points = [FreeCAD.Vector(*map(float, p)) for p in data.points]
    facets = [tuple(map(int, f)) for f in data.facets]
    return Mesh.Mesh((points, facets))


def default_cell(surface: Surface) -> float:
    """A Z-map cell (mm) giving about DEFAULT_CELLS cells along the footprint's longer side."""
    x0, x1, y0, y1 = footprint_bounds(surface)
    return max(x1 - x0, y1 - y0) / DEFAULT_CELLS


def make_verification(surface_obj, gcode: str, tool_diameter: float, cell: float | None = None,
                      stride: int | None = None, program: str = "program", job=None,
                      surface: Surface | list | None = None, doc=None, progress=None,
                      tools: dict | None = None, stock: tuple | None = None,
                      load_limits: dict | None = None):
    """Simulate G-code text against a design; return the new simulated-part object.

    ``surface_obj`` is the design object (a BSplineCAM surface object, or the part whose faces
    are machined); ``surface`` overrides its geometry: a core Surface (e.g. in job
    coordinates) or a part's core faces (:func:`BSplineCAM.core.simulation.verify.verify_faces`: gouge on
    the whole model, scallop and coverage on the selected faces); ``tool_diameter`` is the ball end's (mm); ``cell``
    the Z-map cell (mm, default: :func:`default_cell`).  With ``tools`` ({number: core Tool})
    the program's tool changes are followed from the block ``stock`` (x0, x1, y0, y1, z0, z1
    mm, a core Stock, or a core CylinderStock; :func:`BSplineCAM.core.simulation.verify.verify_job`), the per-tool figures join the metrics and
    the stock after each tool but the last becomes a mesh of its own (``StockAfter``), and
    every move is checked against ``load_limits`` ({number: core LoadLimits}; the tools'
    defaults where missing), the overloads joining the metrics (``loads``).
    ``progress(fraction)`` is told of each stage (default: FreeCAD's progress bar when the
    GUI is up) and may raise to cancel; the document is touched only after the simulation.
    The metrics are also printed.
    """
    progress = progress or _progress_reporter(f"Verifying {program}")
    try:
        if surface is None:
            surface = surface_of(surface_obj)
        cell = default_cell(surface) if cell is None else float(cell)
        progress(0.05)
        parsed = read_gcode(gcode, source=program)
        progress(0.15)
        if tools:
            result = verify_job_program(surface, parsed, tools, stock, cell,
                                        progress=lambda f: progress(0.15 + 0.65 * f),
                                        load_limits=load_limits)
        elif isinstance(surface, Surface):
            result = verify(surface, parsed, Tool(float(tool_diameter)), cell,
                            progress=lambda f: progress(0.15 + 0.65 * f))
        else:
            result = verify_faces(surface, parsed, Tool(float(tool_diameter)), cell,
                                  progress=lambda f: progress(0.15 + 0.65 * f))
        progress(0.8)
        data = zmap_mesh(result, stride)
        mesh = to_mesh(data)
        stages = stage_meshes(result, data.stride)
        progress(0.95)
    finally:
        close = getattr(progress, "close", None)
        if close is not None:
            close()
    doc = doc or (surface_obj.Document if surface_obj is not None else FreeCAD.ActiveDocument)
    obj = doc.addObject("Mesh::FeaturePython", "Verification")
    try:
        VerificationFeature(obj)
        obj.Label = f"Simulated {surface_obj.Label if surface_obj is not None else 'part'}"
        obj.Surface = surface_obj
        obj.Job = job
        obj.Program = program
        obj.ToolDiameter = float(tool_diameter)
        obj.Cell = float(result.simulation.grid.cell)
        obj.Stride = data.stride
        obj.GridRows, obj.GridColumns = data.rows, data.columns
        obj.Deviation = [float(v) for v in np.where(np.isnan(data.deviation), OFF_FOOTPRINT,
                                                    data.deviation)]
        metrics = {"program": program, **result.metrics}
        if getattr(result, "loads", None) is not None:  # the overloads in words, per tool
            metrics["loads"] = {**metrics["loads"], "messages": result.loads.messages(tools)}
        obj.Metrics = json.dumps(metrics, sort_keys=True)
        obj.Mesh = mesh
        made = []
        for number, label, stage in stages:
            part = doc.addObject("Mesh::Feature", f"StockAfterT{number}")
            made.append(part)
            part.Label = f"Stock after T{number} ({label})"
            part.Mesh = stage
            if part.ViewObject is not None:
                part.ViewObject.Visibility = False
            part.purgeTouched()
        obj.StockAfter = made
        if FreeCAD.GuiUp:
            from ..gui.verify_view import attach_view_provider

            attach_view_provider(obj)
        obj.purgeTouched()
    except BaseException:
        for part in locals().get("made", []):
            doc.removeObject(part.Name)
        doc.removeObject(obj.Name)
        raise
    FreeCAD.Console.PrintMessage(format_metrics(obj.Label, metrics))
    return obj


def stage_meshes(result: Verification, stride: int) -> list:
    """(tool number, tool label, Mesh) of the stock after each tool but the last of a
    whole-program verification; [] for one tool."""
    job = getattr(result, "job", None)
    if job is None or len(job.snapshots) < 2:
        return []
    import dataclasses

    out = []
    order = list(job.snapshots)  # in the order the program used them
    for number in order[:-1]:
        tool = job.tools[number].tool
        sim = Simulation(job.grid, np.asarray(job.snapshots[number], dtype=float),
                         float(job.stock[5]), ())
        stage = dataclasses.replace(result, simulation=sim)
        label = f"{tool.shape.value} {tool.diameter:g} mm"
        out.append((number, label, to_mesh(zmap_mesh(stage, stride))))
    return out


def job_tools(job) -> dict:
    """{tool number: core Tool} of the job's tool controllers (flat, bull-nose, ball)."""
    return {int(tc.ToolNumber): core_tool(tc) for tc in job.Tools.Group}


def deviation_of(obj) -> np.ndarray:
    """Per top vertex machined - design (mm), NaN off the footprint."""
    values = np.array(obj.Deviation, dtype=float)
    return np.where(values >= OFF_FOOTPRINT / 2, np.nan, values)


def job_program(job, post: str = "linuxcnc") -> str:
    """The job's program posted (header off) to a temporary file and read back as text."""
    with tempfile.TemporaryDirectory(prefix="bsplinecam-verify-") as tmp:
        return cam.post_process(job, post, Path(tmp) / "job.ngc", remember=False)


def finishing_ops(job) -> list:
    """The job's BSplineCAM ops (finishing and roughing, whose class derives from it)."""
    return [op for op in job.Operations.Group
            if isinstance(getattr(op, "Proxy", None), ObjectSurfaceFinish)]


def finishing_op_of(job):
    """The op that finishes the part: the last active BSplineCAM op that is not a roughing
    (a roughing op when the job has nothing else); None when the job has no BSplineCAM op."""
    ops = [op for op in finishing_ops(job) if getattr(op, "Active", True)]
    finishing = [op for op in ops if not isinstance(op.Proxy, ObjectSurfaceRough)]
    return (finishing or ops or [None])[-1]


def design_of(op):
    """(design object, exact model) an op is verified against: its surface object and the
    exact surface in job coordinates, or for an op on faces the part it machines and its
    faces (selected ones machined, every other face of the job's models a check surface)."""
    if op.Proxy.uses_faces(op):
        job = op.Proxy.job_of(op)
        base = list(getattr(op, "Base", None) or [])
        source = base[0][0] if base else (job.Model.Group[0] if job.Model.Group else None)
        originals = list(getattr(source, "Objects", None) or [])  # the job's model clone
        return (originals[0] if len(originals) == 1 else source), list(op.Proxy.faces(op))
    return op.Surface or find_surface_object(op.Proxy.job_of(op)), op.Proxy.surface(op)


def job_of(obj):
    """The job of a job or of an operation in one (None otherwise)."""
    if obj is None:
        return None
    if hasattr(obj, "Operations") and hasattr(obj, "Tools"):
        return obj
    if isinstance(getattr(obj, "Proxy", None), ObjectSurfaceFinish):
        return obj.Proxy.job_of(obj) or _parent_job(obj)
    return _parent_job(obj)


def _parent_job(obj):
    for parent in getattr(obj, "InList", []):
        for grand in getattr(parent, "InList", []):
            if hasattr(grand, "Operations") and grand.Operations is parent:
                return grand
    return None


def verify_job(job, cell: float | None = None, stride: int | None = None, progress=None):
    """Post ``job`` (linuxcnc) and verify the program against what its finishing op machines
    (:func:`design_of`: a surface, or a part's exact faces with gouge over the whole model),
    with that op's tool; a job with several tools is simulated whole from the job's stock.
    The simulated part is added to the job's document."""
    op = finishing_op_of(job)
    if op is None:
        raise ValueError(f"{job.Label}: the job has no BSplineCAM operation to verify")
    source, model = design_of(op)
    diameter = float(op.ToolController.Tool.Diameter)
    gcode = job_program(job)
    used = {int(o.ToolController.ToolNumber) for o in job.Operations.Group
            if getattr(o, "Active", True) and getattr(o, "ToolController", None) is not None}
    tools = stock = None
    if len(used) > 1:  # roughing and finishing: the whole program from the job's stock
        tools, stock = job_tools(job), job_stock(job)  # a block, or a cylinder as one
    elif job_tools(job).get(int(op.ToolController.ToolNumber), Tool(diameter)).shape.value != "ball":
        tools = job_tools(job)  # one end mill: simulated with its own shape
    if cell is None and not isinstance(model, Surface):
        b = job.Stock.Shape.BoundBox
        cell = max(b.XLength, b.YLength) / DEFAULT_CELLS
    limits = None
    if tools:
        ops = [o for o in finishing_ops(job) if getattr(o, "Active", True)]
        limits = job_load_limits(job, ops, tools, cell if cell is not None
                                 else default_cell(model))
    return make_verification(source, gcode, diameter, cell, stride, program=f"{job.Label} (linuxcnc)",
                             job=job, surface=model, doc=job.Document, progress=progress,
                             tools=tools, stock=stock, load_limits=limits)


def verify_file(surface_obj, path: str | os.PathLike, tool_diameter: float,
                cell: float | None = None, stride: int | None = None, progress=None):
    """Verify a G-code file (its text) on a surface object with a ball end (mm)."""
    text = Path(path).read_text(encoding="utf-8", errors="replace")
    return make_verification(surface_obj, text, tool_diameter, cell, stride,
                             program=os.fspath(path), progress=progress)


def format_metrics(label: str, m: dict) -> str:
    """The report-view summary of a verification's metrics."""
    minutes, seconds = divmod(float(m["machining_time_s"]), 60.0)
    collisions = m.get("rapid_collisions") or []
    lines = [
        f"BSplineCAM verification of {label} ({m.get('program', 'program')}):",
        f"  gouge max          {m['gouge_max_mm']:.4f} mm ({m['gouge_cells']} cells beyond "
        f"{m['gouge_tolerance_mm']:g} mm)",
        *([f"  along the normal   {gouge_gate_mm(m):.4f} mm (the ball and its shank into the "
           f"faces, at the cells above)"] if m.get("gouge_normal_measured") else []),
        f"  scallop max / p99  {m['scallop_max_mm']:.4f} / {m['scallop_p99_mm']:.4f} mm "
        f"(edge band max {m['edge_scallop_max_mm']:.3f} mm)",
        f"  scallop evenness   {m.get('scallop_evenness', float('nan')):.2f} (local cusp "
        f"peak / max; mean / max {m.get('scallop_mean_over_max', float('nan')):.2f})",
        f"  coverage           {100 * m['coverage']:.2f} % within "
        f"{m['coverage_tolerance_mm']:g} mm",
        f"  cutting length     {m['cutting_length_mm']:.1f} mm (rapids "
        f"{m['rapid_length_mm']:.1f} mm)",
        f"  machining time     {int(minutes)} min {seconds:.1f} s",
        f"  rapid collisions   {len(collisions)}",
        f"  Z-map              {m['grid_cells'][1]} x {m['grid_cells'][0]} cells of "
        f"{m['cell_mm']:.3g} mm",
    ]
    lines.extend(load_lines(m))
    for number, t in sorted((m.get("tools") or {}).items()):
        tool = t["tool"]
        lines.append(
            f"  T{number} {tool['shape']} {tool['diameter_mm']:g} mm: removed "
            f"{t['removed_volume_mm3'] / 1000:.1f} cm3, radial engagement max "
            f"{t['radial_engagement_max_mm']:.3f} mm, axial max "
            f"{t['axial_engagement_max_mm']:.3f} mm, "
            f"{len(t['rapid_collisions'])} rapid collisions")
    return "\n".join(lines) + "\n"


def load_lines(m: dict) -> list[str]:
    """The report-view lines of a verification's load check (none without one)."""
    loads = m.get("loads")
    if not loads:
        return []
    if loads.get("ok", True):
        return ["  load limits        every move within its tool's limits"]
    return ["  load limits        EXCEEDED:",
            *(f"    {text}" for text in loads.get("messages", []))]


def loads_ok(m: dict) -> bool:
    """False when a verification's load check found a move over its tool's limits."""
    return bool((m.get("loads") or {}).get("ok", True))


def _progress_reporter(message: str):
    """FreeCAD's progress bar when the GUI is up (cancellable); a no-op headless."""
    if not FreeCAD.GuiUp:
        return _no_progress
    return StatusProgress(message)


def _no_progress(fraction: float) -> None:
    return None
