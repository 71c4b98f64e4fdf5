# SPDX-License-Identifier: LGPL-2.1-or-later
"""Verification: simulate a program on a Z-map and measure it against the design surface.

Definitions (all heights at cell centres, mm):

* deviation = machined - design; the design height comes from the exact footprint inversion
  (:func:`footprint.surface_height`), so no sampling error enters at the cell centres.
* gouge = design - machined where positive; scallop (material left) = machined - design.
  Both are taken over the *inner* footprint, the footprint shrunk by one tool diameter; the
  band along the edges, where a tool rolling off the part cannot finish, is reported apart.
* scallop evenness = mean over the inner cells of the largest scallop within a square of the
  flat stepover at the largest scallop around each (the local cusp peak), over the largest
  scallop (:mod:`.evenness`); ``scallop_mean_over_max`` the plain mean over the largest.
* coverage = fraction of all footprint cells machined to within ``coverage_tolerance`` of
  the design (machined - design <= tolerance): the share of the surface the tool finished.
* machining time = sum of feed-move lengths / their feeds + rapid lengths / the rapid rate.

:func:`verify_faces` measures against a model given as trimmed faces (a part from STEP): the
design is the top-most face above each cell (:mod:`.faces_height`), gouge is measured over
the whole model (check faces included), scallop and coverage on the selected faces away from
their borders by one tool radius.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from enum import Enum
from typing import TypeVar

import numpy as np

from ..errors import ParameterError
from ..geometry.distance import dilate_disk
from ..geometry.faces import Face
from ..geometry.faces_height import FacesHeight
from ..geometry.footprint import footprint_bounds, surface_height
from ..geometry.surface import Surface
from ..program.gcode import MoveKind, Program, linearise, simulation_chord_tolerance
from ..program.gcode_words import Segments
from ..program.tooltable import check_program_tools
from ..toolpath.common import check_tool_fits
from ..typing import FloatArray
from .evenness import scallop_evenness
from .gouge_normal import measure as measure_normal_gouge
from .job_simulation import JobSimulation, check_stock_form, simulate_job
from .load_limits import LoadCheck, LoadLimits, check_loads, default_limits
from .simulate import Grid, Simulation, Tool, simulate
from .stock import CylinderStock

T = TypeVar("T")

#: Design - machined above this (mm) counts a cell as gouged.
GOUGE_TOLERANCE_MM = 1e-3
DEFAULT_RAPID_RATE = 5000.0  # mm/min
DEFAULT_COVERAGE_TOLERANCE = 0.1  # mm
DEFAULT_STOCK_MARGIN = 1.0  # mm
#: Where the design height between two neighbouring cells rises more steeply than this, a
#: wall the selected faces meet stands there, though seen from above they touch (a boss's
#: side between its two fillets): the selection has a border there.  A smooth face ending
#: vertical rises less over its last cell (a 3 mm fillet: 76 degrees over 0.1 mm).
STEEP_BORDER_DEG = 85.0


class StockTop(str, Enum):
    """Where the stock block's top lies."""

    DESIGN = "design"  # the design surface's highest point plus a margin
    PROGRAM = "program"  # the highest end point of a feed move (G1/G2/G3)
    #: the design raised by the margin cell by cell, no stock off it: a part already
    #: roughed (or cast) to within the margin, which a finishing program starts from
    MODEL = "model"

    @classmethod
    def parse(cls, value: str | StockTop) -> StockTop:
        try:
            return cls(value)
        except ValueError:
            raise ParameterError(
                f"stock top must be 'design', 'program' or 'model', got {value!r}") from None


@dataclass(frozen=True)
class Verification:
    """Simulation, design heights and masks on the same grid, and the metrics (JSON-ready)."""

    simulation: Simulation
    design: FloatArray
    inside: np.ndarray
    inner: np.ndarray
    metrics: dict
    #: The whole-program simulation of :func:`verify_job` (None for one tool).
    job: JobSimulation | None = field(default=None, compare=False)
    #: Its moves checked against each tool's load limits (:func:`verify_job`; else None).
    loads: LoadCheck | None = field(default=None, compare=False)

    @property
    def deviation(self) -> FloatArray:
        """Machined - design (mm), NaN off the footprint."""
        return np.where(self.inside, self.simulation.height - self.design, np.nan)


def verify(surface: Surface, program: Program, tool: Tool, cell: float = 0.1,
           stock_top: str | StockTop = StockTop.DESIGN, stock_margin: float = DEFAULT_STOCK_MARGIN,
           rapid_rate: float = DEFAULT_RAPID_RATE,
           coverage_tolerance: float = DEFAULT_COVERAGE_TOLERANCE,
           chord_tolerance: float | None = None,
           progress: Callable[[float], None] | None = None) -> Verification:
    """Simulate ``program`` with ``tool`` over the surface's footprint and measure it.

    ``progress(fraction)``, if given, is called at least every 50 ms while the simulation runs
    (so a GUI stays responsive) and may raise to abandon it (see :func:`run_reporting`).
    """
    def run(grid: Grid, top: float) -> tuple[Simulation, Segments, None]:
        return (*_simulate(program, tool, grid, top, chord_tolerance, progress), None)

    return _verify_surface(surface, program, tool, cell, stock_top, stock_margin, rapid_rate,
                           coverage_tolerance, progress, run)


def _verify_surface(surface: Surface, program: Program, tool: Tool, cell: float,
                    stock_top: str | StockTop, stock_margin: float, rapid_rate: float,
                    coverage_tolerance: float, progress: Callable[[float], None] | None,
                    run: Callable, stock_xy: tuple | None = None) -> Verification:
    """:func:`verify` with the simulation ``run(grid, top) -> (Simulation, segments, job)``
    and the grid grown to cover ``stock_xy`` = (x0, x1, y0, y1) mm if given."""
    _check_arguments(cell, rapid_rate, coverage_tolerance, stock_margin, program)
    stock_top = StockTop.parse(stock_top)
    x0, x1, y0, y1 = footprint_bounds(surface)
    check_tool_fits(surface, tool.diameter, "tool diameter")
    grid = _covering((x0, x1, y0, y1), stock_xy, cell)
    design, inside = _design_heights(surface, grid)
    if not np.any(inside):
        raise ParameterError("no cell centre lies on the surface's footprint: cell too large")
    top = _stock_top(program, stock_top, design, inside, stock_margin)
    sim, segments, job = run(grid, top)
    inner = inside & ~_dilate(~inside, tool.diameter / cell)
    if not np.any(inner):
        raise ParameterError(
            f"the footprint shrunk by the tool diameter ({tool.diameter:g} mm) is empty: "
            "tool too large for the part"
        )
    metrics = _metrics(program, sim, design, inside, inner, inner, inside & ~inner, inside, tool,
                       rapid_rate, coverage_tolerance)
    metrics["gouge_normal_measured"] = False  # a surface, not faces: the gouge is vertical
    _describe(metrics, program, sim, segments, tool, stock_top, (x0, x1, y0, y1))
    _describe_job(metrics, job, inside)
    if progress is not None:
        progress(1.0)
    return Verification(sim, design, inside, inner, metrics, job)  # NaN off the footprint


def _design_heights(surface: Surface, grid: Grid) -> tuple[FloatArray, np.ndarray]:
    """The design height at each cell centre (NaN off the footprint) and the footprint's
    mask (:func:`.footprint.surface_height`; its parameter arrays are dropped at once)."""
    xs, ys = grid.centres()
    found = surface_height(surface, xs[None, :], ys[:, None])
    return found[0], found[3]


def verify_faces(faces: Sequence[Face], program: Program, tool: Tool, cell: float = 0.1,
                 stock_top: str | StockTop = StockTop.DESIGN,
                 stock_margin: float = DEFAULT_STOCK_MARGIN,
                 rapid_rate: float = DEFAULT_RAPID_RATE,
                 coverage_tolerance: float = DEFAULT_COVERAGE_TOLERANCE,
                 chord_tolerance: float | None = None,
                 progress: Callable[[float], None] | None = None) -> Verification:
    """Simulate ``program`` over a model given as faces and measure it against them.

    The design at each cell centre is the top-most face point above it
    (:class:`.faces_height.FacesHeight`, exact to 1e-7 mm in XY); cells with no face above
    (holes, outside the model) are not measured.  Definitions as for a surface except where:

    * gouge (``gouge_max_mm``, ``gouge_cells``) is taken over the whole model, every face,
      selected or not, edges included (an unselected face is a check surface: it must not be
      cut anywhere); ``gouge_selected_max_mm`` and ``gouge_check_max_mm`` split it;
    * scallop and coverage are taken on the selected faces away from their borders: the cells
      of selected faces whose distance from any cell not on a selected face is more than the
      tool radius (the selection's union, so a seam between two selected faces is no border);
      the band within the radius is the edge band (``edge_*``);
    * the gouged cells (over GOUGE_TOLERANCE_MM) are measured again along the design's
      normal, as the depth the ball and its shank enter the faces (:mod:`.gouge_normal`:
      ``gouge_normal_max_mm``, where and by which move in ``gouge_normal_at``, cells left at
      their vertical depth in ``gouge_normal_unmeasured_*``).

    ``verification.inside`` is the model's mask, ``inner`` the measured part of the selection.
    """
    def run(grid: Grid, top: float) -> tuple[Simulation, Segments, None]:
        return (*_simulate(program, tool, grid, top, chord_tolerance, progress), None)

    return _verify_faces(faces, program, tool, cell, stock_top, stock_margin, rapid_rate,
                         coverage_tolerance, progress, run)


def _verify_faces(faces: Sequence[Face], program: Program, tool: Tool, cell: float,
                  stock_top: str | StockTop, stock_margin: float, rapid_rate: float,
                  coverage_tolerance: float, progress: Callable[[float], None] | None,
                  run: Callable, stock_xy: tuple | None = None,
                  tools: dict[int, Tool] | None = None) -> Verification:
    """:func:`verify_faces` with the simulation ``run`` (see :func:`_verify_surface`) and
    the tools of a whole program (``tools``, by number; else ``tool`` for every move)."""
    _check_arguments(cell, rapid_rate, coverage_tolerance, stock_margin, program)
    stock_top = StockTop.parse(stock_top)
    faces = list(faces)
    if not any(f.selected for f in faces):
        raise ParameterError("no face is selected: select the faces the program machines")
    heights = FacesHeight(faces, cell)
    x0, x1, y0, y1 = heights.bounds()
    grid = _covering((x0 - cell, x1 + cell, y0 - cell, y1 + cell), stock_xy, cell)
    xs, ys = grid.centres()
    hm = heights.grid(xs, ys)
    model = hm.found
    chosen = np.array([f.selected for f in faces] + [False])  # face -1: none
    selected = chosen[hm.face]
    if not np.any(selected):
        names = ", ".join(f.name for f in faces if f.selected)
        raise ParameterError(f"no cell centre of the {cell:g} mm grid lies on the selected "
                             f"faces ({names}) seen from above: nothing to measure")
    design = hm.z
    top = _stock_top(program, stock_top, design, model, stock_margin)
    sim, segments, job = run(grid, top)
    # the selection closed over gaps of a cell or two (cell centres on a seam between faces
    # that both fall outside their trim polylines), then shrunk by the tool radius
    closing = 1.5
    closed = ~dilate_disk(dilate_disk(selected, closing, outside=False) == 0, closing,
                          outside=True)
    inner = selected & closed & ~_dilate(~closed | _steep_steps(design, model, cell),
                                         tool.radius / cell)
    if not np.any(inner):
        raise ParameterError(
            f"the selected faces shrunk by the tool radius ({tool.radius:g} mm) are empty: "
            "tool too large for the selection, or cell too large")
    metrics = _metrics(program, sim, design, model, model, inner, selected & ~inner, inner, tool,
                       rapid_rate, coverage_tolerance)
    dev = sim.height - np.where(model, design, 0.0)
    for key, mask in (("gouge_selected_max_mm", selected), ("gouge_check_max_mm",
                                                             model & ~selected)):
        metrics[key] = float(max(0.0, -dev[mask].min())) if mask.any() else 0.0
    metrics.update(
        faces=[f.index for f in faces if f.selected],
        check_faces=[f.index for f in faces if not f.selected],
        model_cells=int(model.sum()), selected_cells=int(selected.sum()),
        face_cells={f.name: int(n) for f, n in
                    zip(faces, np.bincount(hm.face[model], minlength=len(faces)))},
    )
    metrics.pop("footprint_cells", None)
    numbers = [] if job is None else sorted(tools)
    tool_of = None if job is None else np.where(np.isin(job.tool, numbers),
                                                np.searchsorted(numbers, job.tool), -1)
    metrics.update(gouge_normal_measured=True, **measure_normal_gouge(
        faces, segments, [tools[n] for n in numbers] or [tool], grid, design, sim.height,
        model, GOUGE_TOLERANCE_MM, tool_of=tool_of).metrics())
    _describe(metrics, program, sim, segments, tool, stock_top, (x0, x1, y0, y1))
    _describe_job(metrics, job, model)
    if progress is not None:
        progress(1.0)
    return Verification(sim, np.where(model, design, np.nan), model, inner, metrics, job)


def verify_job(model: Surface | Sequence[Face], program: Program, tools: dict[int, Tool],
               stock: tuple | CylinderStock | None = None, cell: float = 0.1,
               stock_top: str | StockTop = StockTop.DESIGN,
               stock_margin: float = DEFAULT_STOCK_MARGIN,
               rapid_rate: float = DEFAULT_RAPID_RATE,
               coverage_tolerance: float = DEFAULT_COVERAGE_TOLERANCE,
               chord_tolerance: float | None = None, feed_default: float | None = None,
               progress: Callable[[float], None] | None = None,
               load_limits: dict[int, LoadLimits] | None = None) -> Verification:
    """Simulate a program with tool changes (:func:`.job_simulation.simulate_job`) from the
    block ``stock`` = (x0, x1, y0, y1, z0, z1) mm (or a vertical
    :class:`.stock.CylinderStock`) and measure the result as :func:`verify` (``model`` a
    Surface) or :func:`verify_faces` (a sequence of faces) do.

    Without ``stock`` the block is that of :func:`verify`: the grid's extent, no bottom, its
    top from ``stock_top``.  The grid covers the model and the block's XY.  The finishing tool,
    the one of the last feed move, stands for "the tool" of the single-tool metrics (the edge
    band's width, ``tool`` in the metrics); ``metrics["tools"]`` holds the per-tool figures
    (:meth:`.job_simulation.JobSimulation.metrics`), keyed by tool number, and
    ``removed_volume_mm3`` the volume cut from the block.

    Every tool's moves are checked against its load limits (:mod:`.load_limits`):
    ``load_limits[n]`` for tool n, :func:`.load_limits.default_limits` for a tool the dict
    lacks; ``metrics["loads"]`` holds the check (:meth:`.load_limits.LoadCheck.to_dict`) and
    ``verification.loads`` the :class:`.load_limits.LoadCheck`.
    """
    if len(program) == 0:
        raise ParameterError("the program has no moves")
    check_program_tools(program, tools)
    if StockTop.parse(stock_top) is StockTop.MODEL:
        raise ParameterError("stock top 'model' is for one finishing program: a program with "
                             "tool changes is simulated from its stock block")
    block = None if stock is None else check_stock_form(stock)
    feeds = np.flatnonzero(program.kind != MoveKind.RAPID)
    last = int(program.tool[feeds[-1]]) if len(feeds) else min(tools, default=0)
    if last not in tools:
        raise ParameterError(f"{program.source}: no tool T{last} given for the last feed move")
    finishing = tools[last]

    def run(grid: Grid, top: float) -> tuple[Simulation, Segments, JobSimulation]:
        box = block or (grid.x0, grid.x0 + grid.nx * grid.cell, grid.y0,
                        grid.y0 + grid.ny * grid.cell, -math.inf, top)
        report = None if progress is None else (lambda f: progress(0.1 + 0.85 * f))
        if progress is not None:
            progress(0.1)
        job = simulate_job(program, tools, grid, box, feed_default=feed_default,
                           progress=report, chord_tolerance=chord_tolerance)
        return job.simulation(), job.segments, job

    limits = dict(load_limits or {})
    for n in limits:
        if n not in tools:
            raise ParameterError(f"load limits given for T{n}, which the tools lack "
                                 f"(T{', T'.join(str(k) for k in sorted(tools))})")
    limits = {n: limits.get(n) or default_limits(t) for n, t in sorted(tools.items())}
    xy = None if block is None else tuple(
        block.bounds if isinstance(block, CylinderStock) else block)[:4]
    if isinstance(model, Surface):
        result = _verify_surface(model, program, finishing, cell, stock_top, stock_margin,
                                 rapid_rate, coverage_tolerance, progress, run, xy)
    else:
        result = _verify_faces(model, program, finishing, cell, stock_top, stock_margin,
                               rapid_rate, coverage_tolerance, progress, run, xy, tools)
    loads = check_loads(result.job, limits, result.design)
    result.metrics["loads"] = loads.to_dict()
    return replace(result, loads=loads)


def _covering(bounds: tuple[float, float, float, float], stock_xy: tuple | None,
              cell: float) -> Grid:
    """The grid over ``bounds`` (x0, x1, y0, y1) mm, grown to cover ``stock_xy`` if given."""
    x0, x1, y0, y1 = bounds
    if stock_xy is not None:
        x0, x1 = min(x0, stock_xy[0]), max(x1, stock_xy[1])
        y0, y1 = min(y0, stock_xy[2]), max(y1, stock_xy[3])
    return Grid.covering(x0, x1, y0, y1, cell)


def _describe_job(metrics: dict, job: JobSimulation | None, model: np.ndarray) -> None:
    """The per-tool figures and the block of a whole-program simulation; a warning if the
    block does not cover the model (``model`` mask) in XY."""
    if job is None:
        return
    outside = int(np.sum(model & ~job.in_stock))
    if outside:
        metrics["warnings"].append(
            f"the stock block leaves {outside} of the model's {int(model.sum())} cells "
            "uncovered in XY: they have no material (gouge there means missing stock)")
    metrics.update(
        tools=job.metrics(), removed_volume_mm3=job.removed_volume(),
        stock_mm=[None if not math.isfinite(v) else v for v in job.stock],
        stock_top_mm=job.stock[5], engagement_threshold_mm=job.threshold_mm,
        unsimulated_rapids=job.unsimulated_rapids,
    )
    if job.cylinder is not None:
        c = job.cylinder
        metrics["stock_cylinder_mm"] = {"x": c.x, "y": c.y, "radius": c.radius,
                                        "z_min": c.z_min, "z_max": c.z_max}


def _check_arguments(cell: float, rapid_rate: float, coverage_tolerance: float,
                     stock_margin: float, program: Program) -> None:
    for name, value, unit in (("cell", cell, "mm"), ("rapid rate", rapid_rate, "mm/min"),
                              ("coverage tolerance", coverage_tolerance, "mm")):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive ({unit}), got {value!r}")
    if not (math.isfinite(stock_margin) and stock_margin >= 0):
        raise ParameterError(f"stock margin must be >= 0 (mm), got {stock_margin!r}")
    if len(program) == 0:
        raise ParameterError("the program has no moves")


def _stock_top(program: Program, stock_top: StockTop, design: FloatArray, model: np.ndarray,
               margin: float) -> float | FloatArray:
    """The stock's top (mm): one height for a block, per cell for ``model`` (-inf off it)."""
    if stock_top is StockTop.PROGRAM:
        feeds = program.kind != MoveKind.RAPID
        if not np.any(feeds):
            raise ParameterError("stock top 'program' needs feed moves (G1/G2/G3)")
        return float(program.end[feeds, 2].max())
    if stock_top is StockTop.MODEL:
        return np.where(model, design + margin, -np.inf)
    return float(np.nanmax(design)) + margin


def _simulate(program: Program, tool: Tool, grid: Grid, top: float,
              chord_tolerance: float | None,
              progress: Callable[[float], None] | None) -> tuple[Simulation, Segments]:
    segments = linearise(program, simulation_chord_tolerance(grid.cell)
                         if chord_tolerance is None else chord_tolerance)
    if progress is None:
        sim = simulate(segments, tool, grid, top)
    else:
        progress(0.1)
        sim = run_reporting(lambda: simulate(segments, tool, grid, top), progress, 0.1, 0.95)
    return sim, segments


def _describe(metrics: dict, program: Program, sim: Simulation, segments: Segments, tool: Tool,
              stock_top: StockTop, footprint: tuple[float, float, float, float]) -> None:
    grid = sim.grid
    metrics.update(
        cell_mm=grid.cell, grid_cells=[grid.ny, grid.nx], stock_top_mm=sim.top,
        stock_top=stock_top.value, moves=len(program), segments=len(segments),
        source_units=program.source_units, converted_from_inches=program.converted_from_inches,
        tool={"shape": tool.shape.value, "diameter_mm": tool.diameter,
              "corner_radius_mm": tool.corner_radius},
        program_tools=list(program.tools), program_warnings=list(program.warnings),
        warnings=extent_warnings(program, footprint, tool.radius),
    )


def run_reporting(work: Callable[[], T], progress: Callable[[float], None], f0: float,
                  f1: float, interval: float = 0.05) -> T:
    """``work()`` in a worker thread while this thread calls ``progress`` every ``interval``
    seconds with a fraction creeping from f0 towards f1 (the total is not known).

    If ``progress`` raises (a cancel), the exception propagates at once; the worker, which
    cannot be interrupted, finishes in the background and its result is dropped.
    """
    outcome: dict = {}

    def run() -> None:
        try:
            outcome["value"] = work()
        except BaseException as exc:  # noqa: BLE001 - handed to the calling thread
            outcome["error"] = exc

    worker = threading.Thread(target=run, name="bsplinecam-simulate", daemon=True)
    worker.start()
    step = 0
    while worker.is_alive():
        worker.join(interval)
        step += 1
        progress(f0 + (f1 - f0) * (1.0 - 0.97 ** step))
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


#: Program extent over part extent that suggests inches read as mm or mm read as inches.
INCH_RATIO = 25.4
_UNIT_RATIO_BAND = (12.0, 50.0)


def extent_warnings(program: Program, footprint: tuple[float, float, float, float],
                    radius: float) -> list[str]:
    """Warnings when the program cannot have machined the part: the XY extent of its feed
    moves (rapids if it has none) misses the footprint grown by the tool radius, or the ratio
    of the two extents is near 25.4 or 1/25.4 (mm numbers under G20, or inch numbers under
    G21).  ``footprint`` is (x_min, x_max, y_min, y_max) in mm."""
    feeds = program.kind != MoveKind.RAPID
    moves = feeds if np.any(feeds) else np.ones(len(program), bool)
    points = np.concatenate([program.start[moves, :2], program.end[moves, :2]])
    points = points[np.all(np.isfinite(points), axis=1)]
    if len(points) == 0:
        return []
    px0, py0 = points.min(axis=0)
    px1, py1 = points.max(axis=0)
    fx0, fx1, fy0, fy1 = footprint

    def mm(v: float) -> str:
        return f"{round(float(v), 4) + 0.0:.6g}"

    span = (f"the program's {'feed ' if np.any(feeds) else ''}moves span X {mm(px0)} to "
            f"{mm(px1)}, Y {mm(py0)} to {mm(py1)} mm")
    part = f"the part's footprint X {mm(fx0)} to {mm(fx1)}, Y {mm(fy0)} to {mm(fy1)} mm"
    warnings = []
    if px1 < fx0 - radius or px0 > fx1 + radius or py1 < fy0 - radius or py0 > fy1 + radius:
        warnings.append(f"{span}: that does not overlap {part}")
    size = max(px1 - px0, py1 - py0)
    part_size = max(fx1 - fx0, fy1 - fy0)
    if size > 0 and part_size > 0:
        ratio = size / part_size
        lo, hi = _UNIT_RATIO_BAND
        if lo <= ratio <= hi:
            said = "G20 (inches)" if program.converted_from_inches else "mm"
            warnings.append(f"{span}, {ratio:.3g} times the part's size: the units look "
                            f"wrong (the program is read as {said}; are its numbers mm?)")
        elif lo <= 1.0 / ratio <= hi:
            said = "G20 (inches)" if program.converted_from_inches else "G21 (mm)"
            warnings.append(f"{span}, 1/{1.0 / ratio:.3g} of the part's size: the units look "
                            f"wrong (the program is read as {said}; are its numbers inches?)")
    return warnings


def _metrics(program: Program, sim: Simulation, design: FloatArray, inside: np.ndarray,
             gouge: np.ndarray, inner: np.ndarray, edge: np.ndarray, coverage: np.ndarray,
             tool: Tool, rapid_rate: float, coverage_tolerance: float) -> dict:
    """Metrics over masks of the grid: ``inside`` where the design is defined, ``gouge`` where
    gouge is measured, ``inner`` where scallop is, ``edge`` the band reported apart and
    ``coverage`` where coverage and the uncut fraction are."""
    dev = np.where(inside, design, 0.0)
    np.subtract(sim.height, dev, out=dev)
    lengths = program.lengths()
    rapid = program.kind == MoveKind.RAPID
    cutting = float(lengths[~rapid].sum())
    feed_time = float(np.sum(lengths[~rapid] / program.feed[~rapid]) * 60.0)
    rapid_time = float(lengths[rapid].sum() / rapid_rate * 60.0)
    # one masked copy alive at a time
    gouge_dev = dev[gouge]
    gouged = {"gouge_max_mm": float(max(0.0, -gouge_dev.min())) if gouge_dev.size else 0.0,
              "gouge_cells": int(np.count_nonzero(gouge_dev < -GOUGE_TOLERANCE_MM))}
    del gouge_dev
    inner_dev = dev[inner]
    scallop = {"scallop_max_mm": float(max(0.0, inner_dev.max())),
               "scallop_p99_mm": float(max(0.0, np.percentile(inner_dev, 99))),
               "scallop_mean_mm": float(max(0.0, inner_dev.mean()))}
    del inner_dev
    edge_dev = dev[edge]
    return {
        **gouged,
        "gouge_tolerance_mm": GOUGE_TOLERANCE_MM,
        **scallop,
        **scallop_evenness(dev, inner, sim.grid.cell, tool),
        "edge_scallop_max_mm": float(max(0.0, edge_dev.max())) if edge_dev.size else 0.0,
        "edge_gouge_max_mm": float(max(0.0, -edge_dev.min())) if edge_dev.size else 0.0,
        "coverage": float(np.mean(dev[coverage] <= coverage_tolerance)),
        "coverage_tolerance_mm": coverage_tolerance,
        "uncut_fraction": float(np.mean(sim.height[coverage]
                                        >= sim.start_heights()[coverage] - 1e-6)),
        "rapid_collisions": [c.to_dict() for c in sim.collisions],
        "cutting_length_mm": cutting,
        "rapid_length_mm": float(lengths[rapid].sum()),
        "machining_time_s": feed_time + rapid_time,
        "feed_time_s": feed_time,
        "rapid_time_s": rapid_time,
        "rapid_rate_mm_per_min": rapid_rate,
        "removed_volume_mm3": sim.removed_volume(),
        "footprint_cells": int(inside.sum()),
        "inner_cells": int(inner.sum()),
    }


def _steep_steps(design: FloatArray, model: np.ndarray, cell: float) -> np.ndarray:
    """Cells of the model whose design height differs from a neighbour's (along x or y, both
    on the model) by more than one cell at STEEP_BORDER_DEG."""
    rise = cell * math.tan(math.radians(STEEP_BORDER_DEG))
    z = np.where(model, design, np.nan)
    out = np.zeros(z.shape, bool)
    for axis in (0, 1):
        with np.errstate(invalid="ignore"):
            step = np.abs(np.diff(z, axis=axis)) > rise  # NaN (off the model): False
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        out[tuple(lo)] |= step
        out[tuple(hi)] |= step
    return out


def _dilate(mask: np.ndarray, radius: float) -> np.ndarray:
    """Dilate a boolean (ny, nx) mask by a disk of ``radius`` cells; outside the grid is set.

    By the exact distance transform (:mod:`.distance`): linear in cells, whatever the radius.
    """
    return dilate_disk(mask, radius, outside=True)
