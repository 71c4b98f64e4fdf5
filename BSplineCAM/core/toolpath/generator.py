# SPDX-License-Identifier: LGPL-2.1-or-later
"""The checks of a toolpath request and the single-strategy generators on a net (raster,
waterline, isoparametric) behind :func:`BSplineCAM.core.toolpath.generate`.

Below :mod:`~BSplineCAM.core.toolpath.rest`, whose steep/shallow strategy runs a raster and a
waterline through :func:`generate_single`, and below the package, which adds steep/shallow and
re-exports everything here: no module of the toolpath package imports the package itself.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np

from ..errors import ParameterError
from .common import (
    CancelFn,
    Direction,
    IsoDirection,
    Monitor,
    ProgressFn,
    Strategy,
    ToolParameters,
    Toolpath,
    ToolpathStats,
    check_angle,
    check_finite,
    check_tool_fits,
    parse_enum,
    unreachable_regions,
)
from .dropcutter import DropCutter
from .isoparametric import isoparametric
from .links import stay_down_links
from .order import order_contours, orient_climb
from .raster import raster
from .waterline import waterline

#: Longest stay-down link between zig-zag passes, in tool radii; longer gaps retract.
STAY_DOWN_LINK = 2.0
#: Most cutter locations a toolpath may need: about 2 minutes and 3.5 GB on a 2-core machine
#: (measured: 1.4 million took 35 s and 1 GB).  A request for more is refused up front.
MAX_CUTTER_LOCATIONS = 5_000_000


def estimated_cutter_locations(surface: Any, tool: ToolParameters,
                               strategy: str | Strategy | None = None) -> float:
    """Upper estimate of the exact cutter locations a finish of the whole surface samples.

    The largest of: the surface's area over the flat stepover times the point spacing along a
    pass, sqrt(8 R tol) (every strategy); at least two points on each of the passes the flat
    stepover puts across the footprint's diagonal (raster); whole iso-curves of points along
    the longer parameter direction (isoparametric); the R/4 height grid over the footprint
    (waterline).  Only a 33 x 33 sample is evaluated, so the estimate itself is cheap.
    """
    grid = surface.grid(33, 33)
    cross = np.cross(np.diff(grid, axis=0)[:, :-1], np.diff(grid, axis=1)[:-1, :])
    area = float(np.linalg.norm(cross, axis=-1).sum())
    step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)
    flat = tool.flat_stepover
    estimate = area / (flat * step)
    ex = float(np.ptp(grid[..., 0]))
    ey = float(np.ptp(grid[..., 1]))
    strategy = None if strategy is None else parse_enum(Strategy, strategy, "strategy")
    if strategy is Strategy.STEEP_SHALLOW:  # a raster and a waterline of the whole surface
        strategy = None
    if strategy in (None, Strategy.RASTER):
        estimate = max(estimate, 2.0 * (math.hypot(ex, ey) / flat + 1.0))
    if strategy in (None, Strategy.ISOPARAMETRIC):
        lengths = [float(np.linalg.norm(np.diff(grid, axis=k), axis=-1).sum(axis=k).max())
                   for k in (0, 1)]
        estimate = max(estimate, (max(lengths) / step + 1.0) * (min(lengths) / flat + 1.0))
    if strategy in (None, Strategy.WATERLINE):
        g = tool.radius / 4.0
        estimate = max(estimate, (ex / g + 1.0) * (ey / g + 1.0))
    return estimate


def request_tool(surface: Any, strategy: str | Strategy, tool_diameter: Any, scallop: Any,
                 tolerance: Any,
                 names: tuple[str, str, str] = ("tool_diameter", "scallop", "tolerance"),
                 ) -> ToolParameters:
    """The tool of a request given by its raw values: the surface and the strategy checked
    first, then the tool (:meth:`ToolParameters.validate`, errors naming ``names``)."""
    _check_surface(surface)
    parse_enum(Strategy, strategy, "strategy")
    return ToolParameters.validate(tool_diameter, scallop, tolerance, names)


def _check_surface(surface: Any) -> None:
    if not (hasattr(surface, "control_points") and hasattr(surface, "knots")):
        raise ParameterError(f"surface must be a BSplineCAM Surface, got {type(surface).__name__}")


def check_request(surface: Any, strategy: str | Strategy, tool_diameter: Any, scallop: Any,
                  tolerance: Any, angle: Any = 0.0,
                  names: tuple[str, str, str, str] = ("tool_diameter", "scallop", "tolerance",
                                                      "angle"),
                  ) -> tuple[Strategy, ToolParameters, float]:
    """Every check :func:`generate` makes before any work, for callers that must refuse a
    request before starting (the command line validates with it before FreeCAD recomputes).

    Tool, scallop and tolerance (mm, :meth:`ToolParameters.validate`), then
    :func:`check_tool_request`.  ParameterError names the argument (``names``) and its unit.
    """
    tool = request_tool(surface, strategy, tool_diameter, scallop, tolerance, names[:3])
    return check_tool_request(surface, strategy, tool, angle, names)


def check_tool_request(surface: Any, strategy: str | Strategy, tool: ToolParameters,
                       angle: Any = 0.0,
                       names: tuple[str, str, str, str] = ("tool_diameter", "scallop",
                                                           "tolerance", "angle"),
                       ) -> tuple[Strategy, ToolParameters, float]:
    """The checks of a request whose ``tool`` is validated: the angle (degrees, [-360, 360]),
    a tool smaller than the part's footprint, and at most ``MAX_CUTTER_LOCATIONS`` estimated
    cutter locations.  Returns (strategy, tool, angle); ParameterError names the argument
    (``names``) and its unit."""
    _check_surface(surface)
    strategy = parse_enum(Strategy, strategy, "strategy")
    angle = check_angle(angle, names[3])
    check_tool_fits(surface, tool.diameter, names[0])
    needed = estimated_cutter_locations(surface, tool, strategy)
    if not needed <= MAX_CUTTER_LOCATIONS:
        raise ParameterError(
            f"{names[1]} {tool.scallop:g} mm with {names[2]} {tool.tolerance:g} mm and a "
            f"{tool.diameter:g} mm tool needs about {needed / 1e6:.3g} million cutter "
            f"locations on this surface (at most {MAX_CUTTER_LOCATIONS / 1e6:g} million): "
            "raise the scallop height or the tolerance"
        )
    return strategy, tool, angle


def check_generate(surface: Any, strategy: str | Strategy, tool: ToolParameters, angle: Any,
                   direction: str | Direction, iso_direction: str | IsoDirection,
                   clearance_height: float | None, min_slope: Any,
                   ) -> tuple[Strategy, float, Direction, IsoDirection, float]:
    """Every check :func:`~BSplineCAM.core.toolpath.generate` makes after the tool's, in its
    order: (strategy, angle, direction, iso_direction, min_slope), checked."""
    strategy, tool, angle = check_tool_request(surface, strategy, tool, angle)
    direction = parse_enum(Direction, direction, "direction")
    iso_direction = parse_enum(IsoDirection, iso_direction, "iso_direction")
    min_slope = check_finite(min_slope, "min_slope", "degrees")
    if not 0.0 < min_slope < 90.0:
        raise ParameterError(f"min_slope must lie in (0, 90) degrees, got {min_slope:g}")
    if clearance_height is not None:
        check_finite(clearance_height, "clearance_height", "mm")
    return strategy, angle, direction, iso_direction, min_slope


def run_strategy(started: float, surface: Any, strategy: Strategy, tool: ToolParameters,
                 angle: float, direction: Direction, iso_direction: IsoDirection,
                 min_slope: float, clearance_height: float | None, progress: ProgressFn,
                 cancel: CancelFn) -> Toolpath:
    """The raster, waterline or isoparametric toolpath of a checked request
    (:func:`check_generate`); ``started`` is when the request came in (perf_counter)."""
    monitor = Monitor(progress, cancel, strategy.value)
    monitor(0.0)
    dc = DropCutter(surface, tool.radius)
    if strategy is Strategy.RASTER:
        passes, extra = raster(surface, tool, angle, direction, monitor, dc)
    elif strategy is Strategy.WATERLINE:
        passes, extra = waterline(surface, tool, math.radians(min_slope), monitor, dc)
    else:
        passes, extra = isoparametric(surface, tool, iso_direction, direction, monitor, dc)
    parameters = {
        "strategy": strategy.value, "tool_diameter": tool.diameter, "scallop": tool.scallop,
        "tolerance": tool.tolerance, "angle": angle, "direction": direction.value,
        "iso_direction": iso_direction.value, "min_slope": min_slope,
    }
    stats = ToolpathStats(
        stepover_min_mm=extra.pop("stepover_min_mm", float("nan")),
        stepover_max_mm=extra.pop("stepover_max_mm", float("nan")),
        notes=extra.pop("notes", []),
    )
    if strategy is Strategy.WATERLINE:
        # every contour climb (material on the right), then in the order of short moves,
        # upper levels first over lower ones; zigzag lets an open contour run either way
        passes = orient_climb(passes, lambda xy: dc.heights(xy)[0],
                              max(0.05 * tool.radius, 4.0 * tool.tolerance))
        passes = order_contours(passes, tool.diameter,
                                reversible=direction is Direction.ZIGZAG)
    toolpath = Toolpath(strategy.value, passes, parameters,
                        unreachable_regions(surface, tool.radius, dc.sign), stats, extra=extra)
    toolpath.finish(started, clearance_height)
    if direction is Direction.ZIGZAG or strategy is Strategy.WATERLINE:
        toolpath.links = stay_down_links(dc, toolpath.passes, STAY_DOWN_LINK * tool.radius, tool.tolerance)
        toolpath.finish(started, clearance_height)
    return toolpath


def generate_single(
    surface: Any,
    strategy: str | Strategy,
    tool: ToolParameters,
    angle: float = 0.0,
    direction: str | Direction = Direction.ZIGZAG,
    iso_direction: str | IsoDirection = IsoDirection.U,
    clearance_height: float | None = None,
    progress: ProgressFn = None,
    cancel: CancelFn = None,
    min_slope: float = 30.0,
) -> Toolpath:
    """:func:`~BSplineCAM.core.toolpath.generate` for one strategy (raster, waterline or
    isoparametric) and a validated ``tool``; steep_shallow, which combines two, and scallop,
    which faces have, are refused."""
    started = time.perf_counter()
    strategy, angle, direction, iso_direction, min_slope = check_generate(
        surface, strategy, tool, angle, direction, iso_direction, clearance_height, min_slope)
    if strategy is Strategy.STEEP_SHALLOW:
        raise ParameterError("strategy 'steep_shallow' combines two strategies: "
                             "use BSplineCAM.core.toolpath.generate")
    if strategy is Strategy.SCALLOP:
        raise ParameterError("strategy 'scallop' is available on faces only: "
                             "use BSplineCAM.core.toolpath.generate_faces")
    return run_strategy(started, surface, strategy, tool, angle, direction, iso_direction,
                        min_slope, clearance_height, progress, cancel)
