# SPDX-License-Identifier: LGPL-2.1-or-later
"""The tool-tip height map: the lowest tip height the part allows at each cell (an inverse
tool offset of a Z-map), and the disk maximum of a grid, by running maxima in a sparse table."""

from __future__ import annotations

import math

import numpy as np

from ...simulation.simulate import Tool
from ...typing import FloatArray
from .constants import GRID_GROWTH_CELLS


def _sparse_table(P: FloatArray, widest: int) -> list:
    """Row-wise running maxima over 1, 2, 4, ... columns (Bentley's sparse table)."""
    table = [P]
    span = 1
    while 2 * span <= widest:
        prev = table[-1]
        table.append(np.maximum(prev[:, :-span], prev[:, span:]))
        span *= 2
    return table


def _window_max(table: list, r0: int, r1: int, c0: int, c1: int, nx: int) -> FloatArray:
    """max over columns x + c0 .. x + c1 (padded indices) of rows r0:r1, for x in 0..nx-1."""
    n = c1 - c0 + 1
    p = n.bit_length() - 1
    t = table[p]
    a = t[r0:r1, c0:c0 + nx]
    b0 = c1 - (1 << p) + 1
    return np.maximum(a, t[r0:r1, b0:b0 + nx])


def tip_height(part: FloatArray, cell: float, tool: Tool, radial: float, axial: float,
               floor: float, ztol: float) -> FloatArray:
    """Lowest tool-tip Z per cell: max over the grown footprint of part + axial - profile.

    ``part`` is (ny, nx) with NaN where no part lies.  The footprint radius is
    R + radial + cell/sqrt(2); the profile is the tool's shifted out by radial + cell/sqrt(2).
    Per row of offsets the columns are grouped into runs where the profile varies by at most
    ``ztol`` (mm) and each run costs two look-ups in a sparse table of row maxima (van Herk /
    Gil-Werman style max filter); the run's lowest profile value is used, so the result is
    high by at most ``ztol``, never low.  Clamped below by ``floor``.
    """
    ny, nx = part.shape
    grow = radial + GRID_GROWTH_CELLS * cell
    Rg = tool.radius + grow
    k = int(math.floor(Rg / cell + 1e-9))
    H = np.where(np.isfinite(part), part + axial, -np.inf)
    P = np.pad(H, k, constant_values=-np.inf)
    table = _sparse_table(P, 2 * k + 1)

    def fe(d: float, dy: int) -> float:
        r = cell * math.hypot(d, dy)
        return float(tool.profile(min(max(r - grow, 0.0), tool.radius)))

    out = np.full((ny, nx), -np.inf)
    lim = (Rg / cell) ** 2 + 1e-9
    for dy in range(-k, k + 1):
        w = int(math.floor(math.sqrt(max(lim - dy * dy, 0.0))))
        r0 = dy + k
        d0 = 0
        while d0 <= w:
            f0 = fe(d0, dy)
            d1 = d0
            while d1 + 1 <= w and fe(d1 + 1, dy) - f0 <= ztol:
                d1 += 1
            if d0 == 0:
                m = _window_max(table, r0, r0 + ny, k - d1, k + d1, nx)
            else:
                m = np.maximum(_window_max(table, r0, r0 + ny, k - d1, k - d0, nx),
                               _window_max(table, r0, r0 + ny, k + d0, k + d1, nx))
            np.maximum(out, m - f0, out=out)
            d0 = d1 + 1
    return np.maximum(out, floor)


def disk_max(values: FloatArray, radius: float) -> FloatArray:
    """max of ``values`` over a disk of ``radius`` cells around each cell (-inf beyond)."""
    k = int(math.floor(radius + 1e-9))
    ny, nx = values.shape
    table = _sparse_table(np.pad(values, k, constant_values=-np.inf), 2 * k + 1)
    out = np.full(values.shape, -np.inf)
    for dy in range(-k, k + 1):
        w = int(math.floor(math.sqrt(max(radius * radius + 1e-9 - dy * dy, 0.0))))
        np.maximum(out, _window_max(table, dy + k, dy + k + ny, k - w, k + w, nx), out=out)
    return out
