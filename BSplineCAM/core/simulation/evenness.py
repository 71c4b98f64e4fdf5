# SPDX-License-Identifier: LGPL-2.1-or-later
"""How evenly a finishing program leaves its scallop: the local cusp peak against the largest.

A pattern that leaves the asked scallop h everywhere has a cusp of height about h within one
stepover of every point; a pattern whose passes are spaced for its steepest point leaves
cusps far below h over most of the surface.  The measure:

* the window w is the flat stepover of the tool's corner at the largest scallop s_max,
  w = 2 sqrt(2 r s_max - s_max^2) (r the ball's radius, a bull nose's corner radius; at
  least two cells): the distance between passes that leave s_max on a plane;
* for each measured cell, its local cusp peak is the largest scallop among the measured cells
  in the square of side w centred on it (a moving maximum, separable: a square of side w
  holds the disk of diameter w, so it reaches the nearest cusp of passes w apart whatever
  their direction);
* ``scallop_evenness`` = mean of the local peaks / s_max: near 1 where the cusps everywhere
  stand near the largest (an even pattern at the asked scallop), low where most of the
  surface is machined far finer than its worst spot asks.  1 when no scallop is left.

``scallop_mean_over_max`` is the plain ratio of the mean (machined - design over the measured
cells, as ``scallop_mean_mm``) to s_max: about 1/3 for an even pattern of circular cusps on a
plane (a parabola's mean over its span is a third of its rise).
"""

from __future__ import annotations

import math

import numpy as np

from ..typing import FloatArray
from .simulate import Tool, ToolShape


def evenness_window(tool: Tool, scallop_max: float, cell: float) -> float:
    """The moving maximum's window (mm): the flat stepover of the tool's corner at
    ``scallop_max`` (mm), at least two cells of ``cell`` mm."""
    r = tool.radius if tool.shape is ToolShape.BALL else tool.corner_radius
    h = min(max(scallop_max, 0.0), r)
    return max(2.0 * math.sqrt(max(2.0 * r * h - h * h, 0.0)), 2.0 * cell)


def running_max(x: FloatArray, half: int, axis: int) -> FloatArray:
    """Largest value of ``x`` within ``half`` cells each side along ``axis`` (the window
    clipped at the array's ends), in O(log window) passes (a sparse table)."""
    if half <= 0:
        return x.copy()
    x = np.moveaxis(x, axis, 0)
    n = x.shape[0]
    width = 2 * half + 1
    pad = np.full((half,) + x.shape[1:], -np.inf)
    table = np.concatenate([pad, x, pad])
    span = 1
    while 2 * span <= width:
        table = np.maximum(table[:-span], table[span:])
        span *= 2
    out = np.maximum(table[:n], table[width - span:width - span + n])
    return np.moveaxis(out, 0, axis)


def scallop_evenness(scallop: FloatArray, measured: np.ndarray, cell: float,
                     tool: Tool) -> dict:
    """``scallop_evenness``, ``scallop_mean_over_max`` and the window
    (``scallop_evenness_window_mm``) of the scallop grid (machined - design, mm) over the
    ``measured`` cells of a grid of ``cell`` mm (module docstring)."""
    values = np.where(measured, np.maximum(scallop, 0.0), -np.inf)
    inner = values[measured]
    top = float(inner.max()) if inner.size else 0.0
    window = evenness_window(tool, top, cell)
    if top <= 0.0:
        return {"scallop_evenness": 1.0, "scallop_mean_over_max": 1.0,
                "scallop_evenness_window_mm": window}
    half = math.ceil(0.5 * window / cell - 1e-9)
    peak = running_max(running_max(values, half, 0), half, 1)
    return {"scallop_evenness": float(peak[measured].mean() / top),
            "scallop_mean_over_max": float(max(0.0, scallop[measured].mean()) / top),
            "scallop_evenness_window_mm": window}


__all__ = ["evenness_window", "running_max", "scallop_evenness"]
