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
    check_angle,
    check_finite,
    check_tool_fits,
    curved_stepover,
    flat_stepover,
    parse_enum,
    to_moves,
    unreachable_regions,
)
from .dropcutter import DropCutter

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


def check_request(surface: Any, strategy: str | Strategy, tool_diameter: Any, scallop: Any,
                  tolerance: Any, angle: Any = 0.0,
                  names: tuple[str, str, str, str] = ("tool_diameter", "scallop", "tolerance",
                                                      "angle"),
                  ) -> tuple[Strategy, ToolParameters, float]:
    """Every check :func:`generate` makes before any work, for callers that must refuse a
    request before starting (the command line validates with it before FreeCAD recomputes).

    Tool, scallop and tolerance (mm, :meth:`ToolParameters.validate`), the angle (degrees,
    [-360, 360]), a tool smaller than the part's footprint, and at most
    ``MAX_CUTTER_LOCATIONS`` estimated cutter locations.  ParameterError names the argument
    (``names``) and its unit.
    """
    if not (hasattr(surface, "control_points") and hasattr(surface, "knots")):
        raise ParameterError(f"surface must be a BSplineCAM Surface, got {type(surface).__name__}")
    strategy = parse_enum(Strategy, strategy, "strategy")
    tool = ToolParameters.validate(tool_diameter, scallop, tolerance, names[:3])
    angle = check_angle(angle, names[3])
    check_tool_fits(surface, 2.0 * tool.radius, names[0])
    needed = estimated_cutter_locations(surface, tool, strategy)
    if not needed <= MAX_CUTTER_LOCATIONS:
        raise ParameterError(
            f"{names[1]} {tool.scallop:g} mm with {names[2]} {tool.tolerance:g} mm and a "
            f"{2.0 * tool.radius:g} mm tool needs about {needed / 1e6:.3g} million cutter "
            f"locations on this surface (at most {MAX_CUTTER_LOCATIONS / 1e6:g} million): "
            "raise the scallop height or the tolerance"
        )
    return strategy, tool, angle


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
    threshold: float = 45.0,
) -> Toolpath:
    """Ball-end finishing toolpath of ``surface`` (a core Surface).

    tool_diameter, scallop (cusp height h), tolerance (chordal, in [1e-5, 1]) and
    clearance_height are in mm; angle (raster pass direction from +X), min_slope
    (waterline: walls below this slope are left to a raster pass) and threshold
    (steep_shallow: the slope above which waterline takes over from raster,
    :func:`rest.generate_steep_shallow`) in degrees.
    ``progress(fraction)`` is called as work proceeds; ``cancel()`` returning True aborts with
    :class:`ToolpathCancelled`.  Regions whose concave radius is below the tool radius are
    listed in ``Toolpath.unreachable`` and left uncut, never gouged.
    """
    started = time.perf_counter()
    strategy, tool, angle = check_request(surface, strategy, tool_diameter, scallop, tolerance,
                                          angle)
    direction = parse_enum(Direction, direction, "direction")
    iso_direction = parse_enum(IsoDirection, iso_direction, "iso_direction")
    min_slope = check_finite(min_slope, "min_slope", "degrees")
    if not 0.0 < min_slope < 90.0:
        raise ParameterError(f"min_slope must lie in (0, 90) degrees, got {min_slope:g}")
    if clearance_height is not None:
        check_finite(clearance_height, "clearance_height", "mm")
    if strategy is Strategy.STEEP_SHALLOW:
        from .rest import generate_steep_shallow

        return generate_steep_shallow(surface, 2.0 * tool.radius, tool.scallop, tool.tolerance,
                                      threshold, angle, clearance_height=clearance_height,
                                      progress=progress, cancel=cancel)
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


def program_moves(toolpath: Toolpath, clearance_height: float | None = None,
                  safe_height: float | None = None, arcs: bool = False,
                  surface: Any = None) -> list:
    """:func:`to_moves`, with every pass and link fitted by one-sided G2/G3 arcs when
    ``arcs`` (:func:`arcs.fit_arcs`, within half the toolpath's chordal tolerance of the
    polyline, which lies within the other half of the exact cutter-location curve).
    Waterline contours (G17) are fitted only with ``surface`` (a core Surface), whose
    drop-cutter tells their free side; without it they stay lines."""
    moves = to_moves(toolpath, clearance_height, safe_height)
    if not arcs:
        return moves
    from .arcs import contour_side, fit_arcs

    side17 = None
    if surface is not None and toolpath.strategy == Strategy.WATERLINE.value:
        dc = DropCutter(surface, 0.5 * float(toolpath.parameters["tool_diameter"]))
        side17 = contour_side(lambda xy: dc.heights(xy)[0])
    return fit_arcs(moves, 0.5 * float(toolpath.parameters["tolerance"]), side17)


__all__ = [
    "MAX_CUTTER_LOCATIONS", "Direction", "DropCutter", "IsoDirection", "Move", "Region",
    "Strategy", "Toolpath", "ToolpathCancelled", "ToolpathStats", "check_request",
    "curved_stepover", "estimated_cutter_locations", "flat_stepover", "generate", "program_moves",
    "to_moves",
]


#: Strategies on faces (every one nets have).
FACE_STRATEGIES = (Strategy.RASTER.value,
                   Strategy.WATERLINE.value,
                   Strategy.ISOPARAMETRIC.value,
                   Strategy.STEEP_SHALLOW.value)


def generate_faces(faceset, strategy: str, tool_diameter: float, scallop: float,
                   tolerance: float, angle: float = 0.0, direction: str = "zigzag",
                   iso_direction: str = "u", progress=None, where: str = "op",
                   names: tuple[str, str] = ("Strategy", "Direction"), threshold: float = 45.0):
    """The toolpath of the selected faces of ``faceset`` (a core FaceSet) by ``strategy``:
    raster (:func:`~BSplineCAM.core.toolpath.faces_raster.generate_faces_raster`, zigzag at
    ``angle`` degrees), waterline (:mod:`~BSplineCAM.core.toolpath.faces_waterline`, levels
    from the scallop on walls over 30 degrees), isoparametric
    (:mod:`~BSplineCAM.core.toolpath.faces_iso`, zigzag along ``iso_direction``) or
    steep_shallow (:func:`~BSplineCAM.core.toolpath.rest.generate_faces_steep_shallow`:
    contours on walls steeper than ``threshold`` degrees, raster at ``angle`` on the rest).
    tool_diameter, scallop and tolerance in mm.  ``unreachable`` lists the regions of the
    selected faces the ball cannot reach (:func:`.reach.unreachable_corners`: inside corners
    and hollows tighter than it), whatever the strategy.  A strategy or direction faces do not have
    raises :class:`~BSplineCAM.core.errors.ParameterError` naming ``where`` and the property or option (``names``)."""
    toolpath = _faces_toolpath(faceset, strategy, tool_diameter, scallop, tolerance, angle,
                               direction, iso_direction, progress, where, names, threshold)
    from .reach import unreachable_corners

    lo, hi = faceset.bounds(selected_only=True)
    toolpath.unreachable = unreachable_corners(
        faceset.faces, [f.selected for f in faceset.faces],
        (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])), 0.5 * float(tool_diameter))
    return toolpath


def _faces_toolpath(faceset, strategy: str, tool_diameter: float, scallop: float,
                    tolerance: float, angle: float, direction: str, iso_direction: str,
                    progress, where: str, names: tuple[str, str], threshold: float):
    """:func:`generate_faces` without the unreachable regions."""
    strategy_name, direction_name = names
    if strategy not in FACE_STRATEGIES:
        raise ParameterError(f"{where}: {strategy_name} {strategy!r} is not available on faces: use "
                      f"{', '.join(FACE_STRATEGIES)} (or a BSplineCAM surface)")
    if strategy != Strategy.WATERLINE.value and \
            direction != Direction.ZIGZAG.value:
        raise ParameterError(f"{where}: {direction_name} {direction!r} is not available on faces "
                      f"with {strategy}: use zigzag")
    if strategy == Strategy.STEEP_SHALLOW.value:
        from .rest import generate_faces_steep_shallow

        return generate_faces_steep_shallow(faceset, tool_diameter, scallop, tolerance,
                                            threshold, angle, progress=progress)
    if strategy == Strategy.WATERLINE.value:
        from .faces_waterline import generate_faces_waterline

        return generate_faces_waterline(faceset, tool_diameter, scallop, tolerance, progress)
    if strategy == Strategy.ISOPARAMETRIC.value:
        from .faces_iso import generate_faces_iso

        return generate_faces_iso(faceset, tool_diameter, scallop, tolerance, iso_direction,
                                  progress)
    from .faces_raster import generate_faces_raster

    return generate_faces_raster(faceset, tool_diameter, scallop, tolerance, angle, progress)


def no_pass_hint(toolpath) -> str:
    """Why a faces toolpath has no pass, from its notes (waterline: no steep wall)."""
    if toolpath.strategy == Strategy.WATERLINE.value:
        return (f" ({'; '.join(toolpath.stats.notes)})" if toolpath.stats.notes else "")
    return ""


def faces_program_moves(toolpath, faceset, clearance_height: float,
                        safe_height: float | None = None, arcs: bool = False) -> list:
    """Program moves (:func:`to_moves`) of a toolpath on faces; with
    ``arcs``, fitted by one-sided G2/G3 arcs within half the toolpath's tolerance, as for
    nets (:func:`program_moves`): waterline contours in G17, their
    free side told by the certified drop-cutter over all of ``faceset``'s faces."""
    from .arcs import contour_side, fit_arcs

    moves = to_moves(toolpath, clearance_height, safe_height)
    if not arcs:
        return moves
    side17 = None
    if toolpath.strategy == Strategy.WATERLINE.value:
        radius = 0.5 * float(toolpath.parameters["tool_diameter"])
        side17 = contour_side(lambda xy: faceset.drop_ball(xy, radius)[0])
    return fit_arcs(moves, 0.5 * float(toolpath.parameters["tolerance"]), side17)
