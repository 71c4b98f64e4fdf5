# SPDX-License-Identifier: LGPL-2.1-or-later
"""Verification: simulate a program on a Z-map and measure it against the design surface.

Definitions (all heights at cell centres, mm):

* deviation = machined - design; the design height comes from the exact footprint inversion
  (:func:`footprint.surface_height`), so no sampling error enters at the cell centres.
* gouge = design - machined where positive; scallop (material left) = machined - design.
  Both are taken over the *inner* footprint, the footprint shrunk by one tool diameter; the
  band along the edges, where a tool rolling off the part cannot finish, is reported apart.
* coverage = fraction of all footprint cells machined to within ``coverage_tolerance`` of
  the design (machined - design <= tolerance): the share of the surface the tool finished.
* machining time = sum of feed-move lengths / their feeds + rapid lengths / the rapid rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from .distance import dilate_disk
from .errors import ParameterError
from .footprint import footprint_bounds, surface_height
from .gcode import MoveKind, Program, linearise
from .simulate import Grid, Simulation, Tool, simulate
from .surface import Surface
from .typing import FloatArray

#: Design - machined above this (mm) counts a cell as gouged.
GOUGE_TOLERANCE_MM = 1e-3
DEFAULT_RAPID_RATE = 5000.0  # mm/min
DEFAULT_COVERAGE_TOLERANCE = 0.1  # mm
DEFAULT_STOCK_MARGIN = 1.0  # mm


class StockTop(str, Enum):
    """Where the stock block's top lies."""

    DESIGN = "design"  # the design surface's highest point plus a margin
    PROGRAM = "program"  # the highest end point of a feed move (G1/G2/G3)

    @classmethod
    def parse(cls, value: str | StockTop) -> StockTop:
        try:
            return cls(value)
        except ValueError:
            raise ParameterError(
                f"stock top must be 'design' or 'program', got {value!r}") from None


@dataclass(frozen=True)
class Verification:
    """Simulation, design heights and masks on the same grid, and the metrics (JSON-ready)."""

    simulation: Simulation
    design: FloatArray
    inside: np.ndarray
    inner: np.ndarray
    metrics: dict

    @property
    def deviation(self) -> FloatArray:
        """Machined - design (mm), NaN off the footprint."""
        return np.where(self.inside, self.simulation.height - self.design, np.nan)


def verify(surface: Surface, program: Program, tool: Tool, cell: float = 0.1,
           stock_top: str | StockTop = StockTop.DESIGN, stock_margin: float = DEFAULT_STOCK_MARGIN,
           rapid_rate: float = DEFAULT_RAPID_RATE,
           coverage_tolerance: float = DEFAULT_COVERAGE_TOLERANCE,
           chord_tolerance: float | None = None) -> Verification:
    """Simulate ``program`` with ``tool`` over the surface's footprint and measure it."""
    for name, value, unit in (("cell", cell, "mm"), ("rapid rate", rapid_rate, "mm/min"),
                              ("coverage tolerance", coverage_tolerance, "mm")):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive ({unit}), got {value!r}")
    if not (math.isfinite(stock_margin) and stock_margin >= 0):
        raise ParameterError(f"stock margin must be >= 0 (mm), got {stock_margin!r}")
    stock_top = StockTop.parse(stock_top)
    if len(program) == 0:
        raise ParameterError("the program has no moves")
    x0, x1, y0, y1 = footprint_bounds(surface)
    if tool.diameter >= min(x1 - x0, y1 - y0):
        raise ParameterError(
            f"tool diameter {tool.diameter:g} mm is not smaller than the part "
            f"({x1 - x0:.3g} x {y1 - y0:.3g} mm footprint)"
        )
    grid = Grid.covering(x0, x1, y0, y1, cell)
    xs, ys = grid.centres()
    design, _, _, inside = surface_height(surface, xs[None, :], ys[:, None])
    if not np.any(inside):
        raise ParameterError("no cell centre lies on the surface's footprint: cell too large")
    feeds = program.kind != MoveKind.RAPID
    if stock_top is StockTop.PROGRAM:
        if not np.any(feeds):
            raise ParameterError("stock top 'program' needs feed moves (G1/G2/G3)")
        top = float(program.end[feeds, 2].max())
    else:
        top = float(np.nanmax(design)) + stock_margin
    segments = linearise(program, grid.cell / 10.0 if chord_tolerance is None else chord_tolerance)
    sim = simulate(segments, tool, grid, top)
    inner = inside & ~_dilate(~inside, tool.diameter / cell)
    if not np.any(inner):
        raise ParameterError(
            f"the footprint shrunk by the tool diameter ({tool.diameter:g} mm) is empty: "
            "tool too large for the part"
        )
    metrics = _metrics(program, sim, design, inside, inner, tool, rapid_rate, coverage_tolerance)
    metrics.update(
        cell_mm=grid.cell, grid_cells=[grid.ny, grid.nx], stock_top_mm=top,
        stock_top=stock_top.value, moves=len(program), segments=len(segments),
        source_units=program.source_units, converted_from_inches=program.converted_from_inches,
        tool={"shape": tool.shape.value, "diameter_mm": tool.diameter,
              "corner_radius_mm": tool.corner_radius},
        program_tools=list(program.tools), program_warnings=list(program.warnings),
    )
    return Verification(sim, np.where(inside, design, np.nan), inside, inner, metrics)


def _metrics(program: Program, sim: Simulation, design: FloatArray, inside: np.ndarray,
             inner: np.ndarray, tool: Tool, rapid_rate: float, coverage_tolerance: float) -> dict:
    dev = sim.height - np.where(inside, design, 0.0)
    inner_dev = dev[inner]
    edge = inside & ~inner
    edge_dev = dev[edge]
    lengths = program.lengths()
    rapid = program.kind == MoveKind.RAPID
    cutting = float(lengths[~rapid].sum())
    feed_time = float(np.sum(lengths[~rapid] / program.feed[~rapid]) * 60.0)
    rapid_time = float(lengths[rapid].sum() / rapid_rate * 60.0)
    gouged = inner_dev < -GOUGE_TOLERANCE_MM
    return {
        "gouge_max_mm": float(max(0.0, -inner_dev.min())),
        "gouge_cells": int(gouged.sum()),
        "gouge_tolerance_mm": GOUGE_TOLERANCE_MM,
        "scallop_max_mm": float(max(0.0, inner_dev.max())),
        "scallop_p99_mm": float(max(0.0, np.percentile(inner_dev, 99))),
        "scallop_mean_mm": float(max(0.0, inner_dev.mean())),
        "edge_scallop_max_mm": float(max(0.0, edge_dev.max())) if edge_dev.size else 0.0,
        "edge_gouge_max_mm": float(max(0.0, -edge_dev.min())) if edge_dev.size else 0.0,
        "coverage": float(np.mean(dev[inside] <= coverage_tolerance)),
        "coverage_tolerance_mm": coverage_tolerance,
        "uncut_fraction": float(np.mean(sim.height[inside] >= sim.top - 1e-6)),
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


def _dilate(mask: np.ndarray, radius: float) -> np.ndarray:
    """Dilate a boolean (ny, nx) mask by a disk of ``radius`` cells; outside the grid is set.

    By the exact distance transform (:mod:`.distance`): linear in cells, whatever the radius.
    """
    return dilate_disk(mask, radius, outside=True)
