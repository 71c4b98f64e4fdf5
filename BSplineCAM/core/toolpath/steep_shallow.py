# SPDX-License-Identifier: LGPL-2.1-or-later
"""Steep / shallow finishing: raster passes on the shallow part of the design, waterline
contours on the steep part, each clipped to its region grown by a small overlap.

The slope is that of the part under the ball (:class:`SlopeSplit`): the angle between the
vertical and the surface normal at the contact of a ball whose tip is above each cell of a
Z-map grid.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..geometry.footprint import footprint_bounds
from ..simulation.simulate import Grid
from ..typing import FloatArray
from .common import (
    CancelFn,
    Monitor,
    ProgressFn,
    Strategy,
    ToolParameters,
    Toolpath,
    ToolpathStats,
    check_finite,
    check_positive,
)
from .dropcutter import DropCutter
from .faces_raster import STAY_DOWN_LINK as FACES_LINK
from .faces_raster import FaceQuery, raster_faces
from .faces_waterline import waterline_faces
from .generator import STAY_DOWN_LINK as RASTER_LINK
from .generator import generate_single, request_tool
from .links import stay_down_links
from .order import order_contours
from .rest import _cell_index, _dilate, _tool_radius


@dataclass(frozen=True)
class SlopeSplit:
    """Slope of the part under the ball on a Z-map grid: ``slope_deg`` (ny, nx) is the angle
    (degrees) between the vertical and the surface normal at the contact of a ball whose tip
    is above each cell centre (NaN where the ball meets no surface); ``shallow`` and ``steep``
    split the cells at ``threshold_deg``."""

    grid: Any
    slope_deg: FloatArray
    shallow: np.ndarray
    steep: np.ndarray
    threshold_deg: float

    def zone(self, which: str, grow: float) -> np.ndarray:
        """The ``'shallow'`` or ``'steep'`` mask grown by ``grow`` mm."""
        mask = self.shallow if which == "shallow" else self.steep
        return _dilate(mask, grow / self.grid.cell)


def _check_threshold(threshold_deg: Any) -> float:
    value = check_finite(threshold_deg, "threshold_deg", "degrees")
    if not 0.0 < value < 90.0:
        raise ParameterError(f"threshold_deg must lie in (0, 90) degrees, got {value:g}")
    return value


def split_by_slope(surface: Any, threshold_deg: float, tool_diameter: float,
                   cell: float | None = None) -> SlopeSplit:
    """Shallow (slope below ``threshold_deg``) and steep cells of a core Surface, judged at
    the contact point of the ball (``tool_diameter`` mm) whose tip is above each cell centre,
    so that a toolpath position can be classified by its XY.  ``cell`` (mm, default R/8) is
    the grid spacing over the footprint grown by the tool radius."""
    threshold = _check_threshold(threshold_deg)
    R = _tool_radius(tool_diameter)
    cell = 0.125 * R if cell is None else check_positive(cell, "cell", "mm")
    x0, x1, y0, y1 = footprint_bounds(surface)
    grid = Grid.covering(x0 - R, x1 + R, y0 - R, y1 + R, cell)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    dc = DropCutter(surface, R)
    tip, u, w = dc.heights(np.column_stack([X.ravel(), Y.ravel()]))
    slope = np.full(len(tip), np.nan)
    ok = np.isfinite(tip)
    if ok.any():
        n = surface.normals(np.clip(u[ok], 0.0, 1.0), np.clip(w[ok], 0.0, 1.0))
        slope[ok] = np.degrees(np.arccos(np.clip(np.abs(n[:, 2]), 0.0, 1.0)))
    slope = slope.reshape(X.shape)
    with np.errstate(invalid="ignore"):
        shallow = slope < threshold
        steep = slope >= threshold
    return SlopeSplit(grid, slope, shallow, steep, threshold)


def clip_polylines(polylines: list, grid: Any, mask: np.ndarray, step: float) -> list:
    """Pieces of the (n, 3) polylines whose points lie in cells where ``mask`` is True.

    Each chord is cut at ``step`` (mm) intervals; a piece keeps the original vertices inside
    it and ends at points on the chords, so it follows the same straight moves (and stays
    one-sided where they were)."""
    out = []
    for p in polylines:
        p = np.asarray(p, dtype=float)
        if len(p) < 2:
            continue
        seg = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)
        n = np.maximum(np.ceil(seg / step).astype(int), 1)
        chord = np.repeat(np.arange(len(seg)), n)
        frac = np.concatenate([np.arange(m) / m for m in n])
        pts = np.vstack([p[chord] + frac[:, None] * (p[chord + 1] - p[chord]), p[-1:]])
        vertex = np.concatenate([frac == 0.0, [True]])
        ix, iy, on = _cell_index(grid, pts[:, :2])
        keep = on & mask[iy, ix]
        edges = np.flatnonzero(np.diff(np.concatenate([[0], keep.astype(int), [0]])))
        for a, b in zip(edges[0::2], edges[1::2]):
            if b - a < 2:
                continue
            sel = vertex[a:b].copy()
            sel[0] = sel[-1] = True
            out.append(pts[a:b][sel])
    return out


def split_faces_by_slope(faceset: Any, threshold_deg: float, tool_diameter: float,
                         cell: float | None = None) -> SlopeSplit:
    """:func:`split_by_slope` for the trimmed faces of a FaceSet: the slope at each cell is
    that of the contact normal (c - p) / R of the certified drop-cutter over every face (check
    faces included, a trim edge too: there the ball rests on the edge and the normal is the
    edge contact's), so a position is classified by what the ball really touches.  ``cell``
    (mm, default R/4) spans the selected faces' extent grown by the tool radius."""
    threshold = _check_threshold(threshold_deg)
    R = _tool_radius(tool_diameter)
    cell = 0.25 * R if cell is None else check_positive(cell, "cell", "mm")
    lo, hi = faceset.bounds(selected_only=True)
    grid = Grid.covering(lo[0] - R, hi[0] + R, lo[1] - R, hi[1] + R, cell)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    q = np.column_stack([X.ravel(), Y.ravel()])
    tip, face, u, v, _ = faceset.drop_ball(q, R)
    slope = np.full(len(q), np.nan)
    idx = np.flatnonzero((face >= 0) & np.isfinite(tip))
    p = faceset.contact_points(face[idx], u[idx], v[idx])
    rise = tip[idx] + R - p[:, 2]  # the contact normal's vertical part, times R
    slope[idx] = np.degrees(np.arccos(np.clip(rise / R, 0.0, 1.0)))
    slope = slope.reshape(X.shape)
    with np.errstate(invalid="ignore"):
        shallow = slope < threshold
        steep = slope >= threshold
    return SlopeSplit(grid, slope, shallow, steep, threshold)


def _steep_shallow(raster: Toolpath, water: Toolpath, split: SlopeSplit, query: Any,
                   overlap: float, wall: float, max_link: float, started: float,
                   clearance_height: float | None) -> Toolpath:
    """Raster passes kept on the shallow zone and contours on the steep one, each grown by
    ``overlap`` mm; the contour pieces after the raster in the order of short moves
    (:func:`.order.order_contours`), every gap up to ``max_link`` mm a stay-down feed over
    the exact heights of ``query`` (a DropCutter or FaceQuery)."""
    step = 0.5 * split.grid.cell
    shallow = clip_polylines(raster.passes, split.grid, split.zone("shallow", overlap), step)
    steep = clip_polylines(water.passes, split.grid, split.zone("steep", overlap), step)
    steep = order_contours(steep, float(raster.parameters["tool_diameter"]),
                           start=shallow[-1][-1] if shallow else None, reversible=True)
    tol = float(raster.parameters["tolerance"])
    links = stay_down_links(query, shallow + steep, max_link, tol) if shallow or steep else []
    parameters = dict(raster.parameters)
    parameters.update({"strategy": "steep_shallow", "threshold_deg": split.threshold_deg,
                       "overlap": overlap, "waterline_min_slope": wall})
    extra = {"split": split, "raster_passes": len(shallow), "waterline_passes": len(steep)}
    toolpath = Toolpath("steep_shallow", shallow + steep, parameters,
                        list(raster.unreachable), ToolpathStats(notes=[]), extra=extra,
                        links=links)
    return toolpath.finish(started, clearance_height)


def _check_overlap(overlap: Any, radius: float) -> float:
    """The overlap of the two zones (mm), R/2 by default."""
    return 0.5 * radius if overlap is None else check_positive(overlap, "overlap", "mm")


def _steep_shallow_request(threshold_deg: Any, tool: ToolParameters, overlap: Any,
                           progress: ProgressFn, cancel: CancelFn) -> tuple:
    """(start time, threshold degrees, overlap mm (default R/2), monitor at 0) of a
    steep/shallow request with a validated ``tool``, its other arguments checked."""
    started = time.perf_counter()
    threshold = _check_threshold(threshold_deg)
    overlap = _check_overlap(overlap, tool.radius)
    monitor = Monitor(progress, cancel, "steep/shallow")
    monitor(0.0)
    return started, threshold, overlap, monitor


def _check_raw_request(threshold_deg: Any, tool_diameter: Any, overlap: Any) -> None:
    """The threshold, the diameter's range and the overlap of a steep/shallow request given
    by raw values, checked in that order before the tool is validated."""
    _check_threshold(threshold_deg)
    _check_overlap(overlap, _tool_radius(tool_diameter))


def generate_steep_shallow(surface: Any, tool_diameter: float, scallop: float,
                           tolerance: float, threshold_deg: float = 45.0, angle: float = 0.0,
                           overlap: float | None = None, cell: float | None = None,
                           clearance_height: float | None = None, progress: ProgressFn = None,
                           cancel: CancelFn = None) -> Toolpath:
    """:func:`steep_shallow` with the tool given by its diameter, scallop and tolerance (mm),
    validated here."""
    _check_raw_request(threshold_deg, tool_diameter, overlap)
    tool = request_tool(surface, Strategy.RASTER, tool_diameter, scallop, tolerance)
    return steep_shallow(surface, tool, threshold_deg, angle, overlap, cell, clearance_height,
                         progress, cancel)


def steep_shallow(surface: Any, tool: ToolParameters, threshold_deg: float = 45.0,
                  angle: float = 0.0, overlap: float | None = None, cell: float | None = None,
                  clearance_height: float | None = None, progress: ProgressFn = None,
                  cancel: CancelFn = None) -> Toolpath:
    """Raster passes (direction ``angle`` degrees) on the shallow part of a core Surface and
    waterline contours on the steep part, split at ``threshold_deg`` by
    :func:`split_by_slope`; each kept where its zone grown by ``overlap`` (mm, default R/2)
    holds, so the two overlap and leave no seam.  Passes and contours are linked by stay-down
    feeds where short (:func:`links.stay_down_links`).  ``extra`` holds
    the split and how many passes of each kind were kept.  ``tool`` is validated."""
    started, threshold, overlap, monitor = _steep_shallow_request(
        threshold_deg, tool, overlap, progress, cancel)
    R = tool.radius
    raster = generate_single(surface, Strategy.RASTER, tool, angle,
                             clearance_height=clearance_height)
    monitor(0.4)
    wall = max(threshold - 10.0, 1.0)
    water = generate_single(surface, Strategy.WATERLINE, tool,
                            clearance_height=clearance_height, min_slope=wall)
    monitor(0.8)
    split = split_by_slope(surface, threshold, tool.diameter, cell)
    toolpath = _steep_shallow(raster, water, split, DropCutter(surface, R), overlap, wall,
                              RASTER_LINK * R, started, clearance_height)
    monitor(1.0)
    return toolpath


def generate_faces_steep_shallow(faceset: Any, tool_diameter: float, scallop: float,
                                 tolerance: float, threshold_deg: float = 45.0,
                                 angle: float = 0.0, overlap: float | None = None,
                                 cell: float | None = None, progress: ProgressFn = None,
                                 cancel: CancelFn = None) -> Toolpath:
    """:func:`steep_shallow_faces` with the tool given by its diameter, scallop and tolerance
    (mm), validated here."""
    _check_raw_request(threshold_deg, tool_diameter, overlap)
    tool = ToolParameters.validate(tool_diameter, scallop, tolerance)
    return steep_shallow_faces(faceset, tool, threshold_deg, angle, overlap, cell, progress,
                               cancel)


def steep_shallow_faces(faceset: Any, tool: ToolParameters, threshold_deg: float = 45.0,
                        angle: float = 0.0, overlap: float | None = None,
                        cell: float | None = None, progress: ProgressFn = None,
                        cancel: CancelFn = None) -> Toolpath:
    """:func:`steep_shallow` on the selected faces of a FaceSet: raster passes
    (:func:`.faces_raster.raster_faces`) on the shallow zone, waterline contours
    (:func:`.faces_waterline.waterline_faces`, levels from the scallop on walls
    over ``threshold_deg`` - 10 degrees) on the steep one, split by
    :func:`split_faces_by_slope`; every height the certified drop-cutter over all faces.
    ``tool`` is validated."""
    started, threshold, overlap, monitor = _steep_shallow_request(
        threshold_deg, tool, overlap, progress, cancel)
    R = tool.radius
    raster = raster_faces(faceset, tool, angle, lambda f: monitor(0.3 * f))
    wall = max(threshold - 10.0, 1.0)
    water = waterline_faces(faceset, tool, lambda f: monitor(0.3 + 0.55 * f), min_slope=wall)
    split = split_faces_by_slope(faceset, threshold, tool.diameter, cell)
    monitor(0.95)
    toolpath = _steep_shallow(raster, water, split, FaceQuery(faceset, R), overlap, wall,
                              FACES_LINK * R, started, None)
    monitor(1.0)
    return toolpath


__all__ = ["SlopeSplit", "clip_polylines", "generate_faces_steep_shallow",
           "generate_steep_shallow", "split_by_slope", "split_faces_by_slope", "steep_shallow",
           "steep_shallow_faces"]
