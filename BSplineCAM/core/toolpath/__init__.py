# SPDX-License-Identifier: LGPL-2.1-or-later
"""Ball-end finishing toolpaths on the exact B-spline surface (issue 4).

One entry point in the manner of CAM's ``Path/Base/Generator/helix.py``: :func:`generate`
validates its arguments (ParameterError, a ValueError, naming argument and unit) and
returns a :class:`Toolpath` of plain data; :func:`to_moves` links its passes with retracts.

>>> tp = generate(surface, strategy="raster", tool_diameter=6.0, scallop=0.01)
>>> moves = to_moves(tp)            # [Move('rapid', x, y, z), Move('feed', ...), ...]
"""

from __future__ import annotations

import time
from typing import Any

from ..errors import ParameterError
from .arcs import contour_side, fit_arcs
from .common import (  # noqa: F401  (the package's names for its callers)
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
from .faces_iso import iso_faces
from .faces_raster import raster_faces
from .faces_scallop import scallop_faces
from .faces_waterline import waterline_faces
from .generator import (  # noqa: F401  (re-exported: the package's request checks)
    MAX_CUTTER_LOCATIONS,
    STAY_DOWN_LINK,
    check_generate,
    check_request,
    check_tool_request,
    estimated_cutter_locations,
    request_tool,
    run_strategy,
)
from .reach import unreachable_corners
from .steep_shallow import steep_shallow, steep_shallow_faces


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
    :func:`steep_shallow.generate_steep_shallow`) in degrees.
    ``progress(fraction)`` is called as work proceeds; ``cancel()`` returning True aborts with
    :class:`ToolpathCancelled`.  Regions whose concave radius is below the tool radius are
    listed in ``Toolpath.unreachable`` and left uncut, never gouged.
    """
    tool = request_tool(surface, strategy, tool_diameter, scallop, tolerance)
    return generate_for_tool(surface, tool, strategy, angle, direction, iso_direction,
                             clearance_height, progress, cancel, min_slope, threshold)


def generate_for_tool(
    surface: Any,
    tool: ToolParameters,
    strategy: str | Strategy = Strategy.RASTER,
    angle: float = 0.0,
    direction: str | Direction = Direction.ZIGZAG,
    iso_direction: str | IsoDirection = IsoDirection.U,
    clearance_height: float | None = None,
    progress: ProgressFn = None,
    cancel: CancelFn = None,
    min_slope: float = 30.0,
    threshold: float = 45.0,
) -> Toolpath:
    """:func:`generate` for a ``tool`` validated where the request came in
    (:meth:`ToolParameters.validate`); every other argument is checked here."""
    started = time.perf_counter()
    strategy, angle, direction, iso_direction, min_slope = check_generate(
        surface, strategy, tool, angle, direction, iso_direction, clearance_height, min_slope)
    if strategy is Strategy.STEEP_SHALLOW:
        return steep_shallow(surface, tool, threshold, angle, clearance_height=clearance_height,
                             progress=progress, cancel=cancel)
    if strategy is Strategy.SCALLOP:
        raise ParameterError("strategy 'scallop' is available on faces only: select the "
                             "part's faces (or use raster, waterline, isoparametric or "
                             "steep_shallow on a BSplineCAM surface)")
    return run_strategy(started, surface, strategy, tool, angle, direction, iso_direction,
                        min_slope, clearance_height, progress, cancel)


def program_moves(toolpath: Toolpath, clearance_height: float | None = None,
                  safe_height: float | None = None, arcs: bool = False,
                  surface: Any = None, hops: Any = None) -> list:
    """:func:`to_moves`, with every pass and link fitted by one-sided G2/G3 arcs when
    ``arcs`` (:func:`arcs.fit_arcs`, within half the toolpath's chordal tolerance of the
    polyline, which lies within the other half of the exact cutter-location curve).
    Waterline contours (G17) are fitted only with ``surface`` (a core Surface), whose
    drop-cutter tells their free side; without it they stay lines.  ``hops``
    (:func:`.retracts.surface_hops`) lifts the tool between passes only as high as needed."""
    moves = to_moves(toolpath, clearance_height, safe_height, hops)
    if not arcs:
        return moves
    side17 = None
    if surface is not None and toolpath.strategy == Strategy.WATERLINE.value:
        dc = DropCutter(surface, 0.5 * float(toolpath.parameters["tool_diameter"]))
        side17 = contour_side(lambda xy: dc.heights(xy)[0])
    return fit_arcs(moves, 0.5 * float(toolpath.parameters["tolerance"]), side17)


__all__ = [
    "MAX_CUTTER_LOCATIONS", "Direction", "DropCutter", "IsoDirection", "Move", "Region",
    "Strategy", "Toolpath", "ToolpathCancelled", "ToolpathStats", "check_request",
    "curved_stepover", "estimated_cutter_locations", "flat_stepover", "generate",
    "generate_for_tool", "program_moves", "to_moves",
]


#: Strategies on faces (every one nets have).
FACE_STRATEGIES = (Strategy.RASTER.value,
                   Strategy.WATERLINE.value,
                   Strategy.ISOPARAMETRIC.value,
                   Strategy.STEEP_SHALLOW.value,
                   Strategy.SCALLOP.value)


def generate_faces(faceset, strategy: str, tool_diameter: float | None = None,
                   scallop: float | None = None, tolerance: float | None = None,
                   angle: float = 0.0, direction: str = "zigzag", iso_direction: str = "u",
                   progress=None, where: str = "op",
                   names: tuple[str, str] = ("Strategy", "Direction"), threshold: float = 45.0,
                   *, tool: ToolParameters | None = None):
    """The toolpath of the selected faces of ``faceset`` (a core FaceSet) by ``strategy``:
    raster (:func:`~BSplineCAM.core.toolpath.faces_raster.raster_faces`, zigzag at
    ``angle`` degrees), waterline (:mod:`~BSplineCAM.core.toolpath.faces_waterline`, levels
    from the scallop on walls over 30 degrees), isoparametric
    (:mod:`~BSplineCAM.core.toolpath.faces_iso`, zigzag along ``iso_direction``) or
    steep_shallow (:func:`~BSplineCAM.core.toolpath.steep_shallow.steep_shallow_faces`:
    contours on walls steeper than ``threshold`` degrees, raster at ``angle`` on the rest) or
    scallop (:func:`~BSplineCAM.core.toolpath.faces_scallop.scallop_faces`: passes offset
    inwards from the selected faces' border, each by the stepover that leaves the scallop).
    The ball is ``tool``, validated where the request came in, or else tool_diameter,
    scallop and tolerance (mm), validated here (:meth:`ToolParameters.validate`).
    ``unreachable`` lists the regions of the
    selected faces the ball cannot reach (:func:`.reach.unreachable_corners`: inside corners
    and hollows tighter than it), whatever the strategy.  A strategy or direction faces do not have
    raises :class:`~BSplineCAM.core.errors.ParameterError` naming ``where`` and the property or option (``names``)."""
    _check_faces_request(strategy, direction, where, names)
    if tool is None:
        tool = ToolParameters.validate(tool_diameter, scallop, tolerance)
    elif (tool_diameter, scallop, tolerance) != (None, None, None):
        raise ParameterError("generate_faces: give the tool or its tool_diameter, scallop and "
                             "tolerance, not both")
    toolpath = _faces_toolpath(faceset, strategy, tool, angle, direction, iso_direction,
                               progress, where, names, threshold)
    lo, hi = faceset.bounds(selected_only=True)
    toolpath.unreachable = unreachable_corners(
        faceset.faces, [f.selected for f in faceset.faces],
        (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])), tool.radius)
    return toolpath


def _check_faces_request(strategy: str, direction: str, where: str,
                         names: tuple[str, str]) -> None:
    """A strategy faces have, and zigzag passes unless it is waterline; the ParameterError
    names ``where`` and the property or option (``names``)."""
    strategy_name, direction_name = names
    if strategy not in FACE_STRATEGIES:
        raise ParameterError(f"{where}: {strategy_name} {strategy!r} is not available on faces: use "
                      f"{', '.join(FACE_STRATEGIES)} (or a BSplineCAM surface)")
    if strategy != Strategy.WATERLINE.value and \
            direction != Direction.ZIGZAG.value:
        raise ParameterError(f"{where}: {direction_name} {direction!r} is not available on faces "
                      f"with {strategy}: use zigzag")


def _faces_toolpath(faceset, strategy: str, tool: ToolParameters, angle: float,
                    direction: str, iso_direction: str, progress, where: str,
                    names: tuple[str, str], threshold: float):
    """:func:`generate_faces` without the unreachable regions, its request checked."""
    if strategy == Strategy.STEEP_SHALLOW.value:
        return steep_shallow_faces(faceset, tool, threshold, angle, progress=progress)
    if strategy == Strategy.WATERLINE.value:
        return waterline_faces(faceset, tool, progress, direction=direction)
    if strategy == Strategy.ISOPARAMETRIC.value:
        return iso_faces(faceset, tool, iso_direction, progress)
    if strategy == Strategy.SCALLOP.value:
        return scallop_faces(faceset, tool, progress)
    return raster_faces(faceset, tool, angle, progress)


def no_pass_hint(toolpath) -> str:
    """Why a faces toolpath has no pass, from its notes (waterline: no steep wall)."""
    if toolpath.strategy == Strategy.WATERLINE.value:
        return (f" ({'; '.join(toolpath.stats.notes)})" if toolpath.stats.notes else "")
    return ""


def faces_program_moves(toolpath, faceset, clearance_height: float,
                        safe_height: float | None = None, arcs: bool = False,
                        hops: Any = None) -> list:
    """Program moves (:func:`to_moves`) of a toolpath on faces; with
    ``arcs``, fitted by one-sided G2/G3 arcs within half the toolpath's tolerance, as for
    nets (:func:`program_moves`): waterline contours in G17, their
    free side told by the certified drop-cutter over all of ``faceset``'s faces.  ``hops``
    (:func:`.retracts.faces_hops`) lifts the tool between passes only as high as needed."""
    moves = to_moves(toolpath, clearance_height, safe_height, hops)
    if not arcs:
        return moves
    side17 = None
    if toolpath.strategy == Strategy.WATERLINE.value:
        radius = 0.5 * float(toolpath.parameters["tool_diameter"])
        side17 = contour_side(lambda xy: faceset.drop_ball(xy, radius)[0])
    return fit_arcs(moves, 0.5 * float(toolpath.parameters["tolerance"]), side17)
