# SPDX-License-Identifier: LGPL-2.1-or-later
"""Ball-end finishing toolpaths on the exact B-spline surface (issue 4).

One entry point in the manner of CAM's ``Path/Base/Generator/helix.py``: :func:`generate`
validates its arguments (ParameterError, a ValueError, naming argument and unit) and
returns a :class:`Toolpath` of plain data; :func:`to_moves` links its passes with retracts.

>>> tp = generate(surface, strategy="raster", tool_diameter=6.0, scallop=0.01)
>>> moves = to_moves(tp)            # [Move('rapid', x, y, z), Move('feed', ...), ...]
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
    Move,
    ProgressFn,
    Region,
    Strategy,
    ToolParameters,
    Toolpath,
    ToolpathCancelled,
    ToolpathStats,
    check_finite,
    curved_stepover,
    flat_stepover,
    parse_enum,
    to_moves,
    unreachable_regions,
)
from .dropcutter import DropCutter

#: Longest stay-down link between zig-zag passes, in tool radii; longer gaps retract.
STAY_DOWN_LINK = 2.0
#: Most cutter locations a toolpath may need (about a quarter of an hour and a few GB): a
#: scallop or tolerance asking for more is refused up front instead of running for hours.
MAX_CUTTER_LOCATIONS = 50_000_000


def estimated_cutter_locations(surface: Any, tool: ToolParameters) -> float:
    """Exact cutter locations a finish of the whole surface samples: its area over the flat
    stepover times the point spacing along a pass, sqrt(8 R tol)."""
    grid = surface.grid(33, 33)
    cross = np.cross(np.diff(grid, axis=0)[:, :-1], np.diff(grid, axis=1)[:-1, :])
    area = float(np.linalg.norm(cross, axis=-1).sum())
    step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)
    return area / (tool.flat_stepover * step)


def generate(
    surface: Any,
    strategy: str | Strategy = Strategy.RASTER,
    tool_diameter: float = 6.0,
    scallop: float = 0.01,
    tolerance: float = 0.002,
    angle: float = 0.0,
    direction: str | Direction = Direction.ZIGZAG,
    iso_direction: str | IsoDirection = IsoDirection.U,
    clearance_height: float | None = None,
    progress: ProgressFn = None,
    cancel: CancelFn = None,
    min_slope: float = 30.0,
) -> Toolpath:
    """Ball-end finishing toolpath of ``surface`` (a core Surface).

    tool_diameter, scallop (cusp height h), tolerance (chordal, in [1e-5, 1]) and
    clearance_height are in mm; angle (raster pass direction from +X) and min_slope
    (waterline: walls below this slope are left to a raster pass) in degrees.
    ``progress(fraction)`` is called as work proceeds; ``cancel()`` returning True aborts with
    :class:`ToolpathCancelled`.  Regions whose concave radius is below the tool radius are
    listed in ``Toolpath.unreachable`` and left uncut, never gouged.
    """
    started = time.perf_counter()
    if not (hasattr(surface, "control_points") and hasattr(surface, "knots")):
        raise ParameterError(f"surface must be a BSplineCAM Surface, got {type(surface).__name__}")
    strategy = parse_enum(Strategy, strategy, "strategy")
    tool = ToolParameters.validate(tool_diameter, scallop, tolerance)
    angle = check_finite(angle, "angle", "degrees")
    direction = parse_enum(Direction, direction, "direction")
    iso_direction = parse_enum(IsoDirection, iso_direction, "iso_direction")
    min_slope = check_finite(min_slope, "min_slope", "degrees")
    if not 0.0 < min_slope < 90.0:
        raise ParameterError(f"min_slope must lie in (0, 90) degrees, got {min_slope:g}")
    if clearance_height is not None:
        check_finite(clearance_height, "clearance_height", "mm")
    needed = estimated_cutter_locations(surface, tool)
    if needed > MAX_CUTTER_LOCATIONS:
        raise ParameterError(
            f"scallop {tool.scallop:g} mm with tolerance {tool.tolerance:g} mm needs about "
            f"{needed / 1e6:.0f} million cutter locations on this surface (at most "
            f"{MAX_CUTTER_LOCATIONS / 1e6:.0f} million): raise the scallop height or the tolerance"
        )
    monitor = Monitor(progress, cancel, strategy.value)
    monitor(0.0)
    dc = DropCutter(surface, tool.radius)
    if strategy is Strategy.RASTER:
        from .raster import raster

        passes, extra = raster(surface, tool, angle, direction, monitor, dc)
    elif strategy is Strategy.WATERLINE:
        from .waterline import waterline

        passes, extra = waterline(surface, tool, math.radians(min_slope), monitor, dc)
    else:
        from .isoparametric import isoparametric

        passes, extra = isoparametric(surface, tool, iso_direction, direction, monitor, dc)
    parameters = {
        "strategy": strategy.value, "tool_diameter": 2.0 * tool.radius, "scallop": tool.scallop,
        "tolerance": tool.tolerance, "angle": angle, "direction": direction.value,
        "iso_direction": iso_direction.value, "min_slope": min_slope,
    }
    stats = ToolpathStats(
        stepover_min_mm=extra.pop("stepover_min_mm", float("nan")),
        stepover_max_mm=extra.pop("stepover_max_mm", float("nan")),
        notes=extra.pop("notes", []),
    )
    toolpath = Toolpath(strategy.value, passes, parameters,
                        unreachable_regions(surface, tool.radius, dc.sign), stats, extra=extra)
    toolpath.finish(started, clearance_height)
    if direction is Direction.ZIGZAG and strategy is not Strategy.WATERLINE:
        from .links import stay_down_links

        toolpath.links = stay_down_links(dc, toolpath.passes, STAY_DOWN_LINK * tool.radius, tool.tolerance)
        toolpath.finish(started, clearance_height)
    return toolpath


__all__ = [
    "Direction", "DropCutter", "IsoDirection", "Move", "Region", "Strategy", "Toolpath",
    "ToolpathCancelled", "ToolpathStats", "curved_stepover", "flat_stepover", "generate",
    "to_moves",
]
