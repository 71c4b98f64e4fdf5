# SPDX-License-Identifier: LGPL-2.1-or-later
"""Where a ball end mill cannot reach the selected faces: inside corners and hollows.

A ball of radius R touches the design surface z(p) only where a ball resting on the part from
above reaches down to it.  Its centre rests at c(q) = max over |p - q| <= R of
z(p) + sqrt(R^2 - |p - q|^2) over each XY position q (the grey-scale dilation of z by the
hemisphere), and the lowest any ball reaches at p is

    reach(p) = min over |q - p| <= R of  c(q) - sqrt(R^2 - |q - p|^2)

(the erosion of c: together the morphological opening of z by the ball; Serra, "Image
Analysis and Mathematical Morphology", 1982, ch. XII; the "inverse offset" of CAM).  Where
reach(p) - z(p) is large the material stays, whatever the passes: an inside corner between
faces (a dome standing on a plate), or a hollow tighter than the ball.  Both are computed on
a grid of the faces' design heights (:class:`~BSplineCAM.core.geometry.faces_height.FacesHeight`),
every face of the model counting (check faces bear the ball too), and the cells of the
selected faces left deeper than a threshold are grouped into regions, which the faces
toolpaths report as ``unreachable`` (the net's own report lists hollows tighter than the
ball by their curvature: :func:`.common.unreachable_regions`).

On the grid a ball centred between cell centres rests on the nearest ones: on a smooth face
the opening then stands above the face by about (cell / 2 / cos slope)^2 / 2R, 0.1 mm on
75 degree slopes at a tenth of the radius, and beside a steep side the depth left comes out
up to about a third of a cell too deep (a cone's foot: 0.707 against 0.641 mm; a dome's on a
plate, 1.12 mm, 1.02 on a grid twice as fine at ten times the cost).  So only cells flatter
than REACH_SLOPE_DEG (by the grid's own slope) and left deeper than MIN_DEPTH_MM count, and
the depths are reported as "up to".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..geometry.faces_height import FacesHeight
from ..typing import FloatArray
from .common import label_regions

#: Grid cell as a share of the ball's radius, and the most cells of a grid (the cell grows).
CELL_SHARE = 0.1
MAX_CELLS = 1_500_000
#: Material left deeper than this (mm) counts as unreachable.
MIN_DEPTH_MM = 0.2
#: Only cells whose design slope (over the grid's neighbours) is at most this count.
REACH_SLOPE_DEG = 75.0
#: Regions of fewer cells are dropped (the grid's noise on a single cell).
MIN_CELLS = 3


@dataclass(frozen=True)
class CornerRegion:
    """A connected patch of the selected faces the ball cannot reach: XY box (mm), the
    deepest material left there (mm, above the design) and its area (mm^2)."""

    x_range: tuple[float, float]
    y_range: tuple[float, float]
    depth_mm: float
    area_mm2: float

    def as_dict(self) -> dict:
        return {"x_range": list(self.x_range), "y_range": list(self.y_range),
                "depth_mm": self.depth_mm, "area_mm2": self.area_mm2}

    def __str__(self) -> str:
        (x0, x1), (y0, y1) = self.x_range, self.y_range
        return (f"x {x0:.2f}..{x1:.2f} mm, y {y0:.2f}..{y1:.2f} mm: up to "
                f"{self.depth_mm:.3f} mm left over {self.area_mm2:.3g} mm^2")


def _disk(radius_cells: float) -> tuple[np.ndarray, np.ndarray, FloatArray]:
    k = int(math.floor(radius_cells))
    di, dj = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    d2 = (di * di + dj * dj).astype(float)
    keep = d2 <= radius_cells * radius_cells
    return di[keep], dj[keep], d2[keep]


def _shifted(a: FloatArray, di: int, dj: int, fill: float) -> FloatArray:
    """a[i + di, j + dj] (``fill`` beyond the grid)."""
    out = np.full(a.shape, fill)
    ny, nx = a.shape
    if abs(di) >= ny or abs(dj) >= nx:
        return out
    out[max(0, -di):ny - max(0, di), max(0, -dj):nx - max(0, dj)] = \
        a[max(0, di):ny - max(0, -di), max(0, dj):nx - max(0, -dj)]
    return out


def opening(z: FloatArray, radius: float, cell: float) -> FloatArray:
    """The lowest height (mm) a ball of ``radius`` reaches over each cell of the height grid
    ``z`` (cells ``cell`` mm; -inf where nothing lies): the dilation of z by the hemisphere,
    then its erosion (module docstring).  -inf where no ball rests nearby."""
    rc = radius / cell
    di, dj, d2 = _disk(rc)
    cap = np.sqrt(np.maximum(radius * radius - d2 * cell * cell, 0.0))
    centre = np.full(z.shape, -np.inf)
    for a, b, h in zip(di.tolist(), dj.tolist(), cap.tolist()):
        np.maximum(centre, _shifted(z, a, b, -np.inf) + h, out=centre)
    reach = np.full(z.shape, np.inf)
    with np.errstate(invalid="ignore"):
        for a, b, h in zip(di.tolist(), dj.tolist(), cap.tolist()):
            np.minimum(reach, _shifted(centre, a, b, np.inf) - h, out=reach)
    return np.where(np.isfinite(reach), reach, -np.inf)


def unreachable_corners(faces, selected: list[bool], bounds: tuple[float, float, float, float],
                        radius: float, min_depth: float = MIN_DEPTH_MM) -> list[CornerRegion]:
    """Regions of the selected faces (core Faces ``faces``, ``selected`` per face; ``bounds``
    (x0, x1, y0, y1) mm their extent) that a ball of ``radius`` mm cannot reach by more than
    ``min_depth`` mm (module docstring), deepest first."""
    x0, x1, y0, y1 = bounds
    pad = 2.0 * radius
    cell = CELL_SHARE * radius
    area = (x1 - x0 + 2 * pad) * (y1 - y0 + 2 * pad)
    cell = max(cell, math.sqrt(area / MAX_CELLS))
    xs = np.arange(x0 - pad, x1 + pad + cell, cell)
    ys = np.arange(y0 - pad, y1 + pad + cell, cell)
    hm = FacesHeight(list(faces), cell).grid(xs, ys)
    z = np.where(hm.found, hm.z, -np.inf)
    reach = opening(z, radius, cell)
    chosen = np.array(list(selected) + [False])[hm.face]
    with np.errstate(invalid="ignore"):
        gy, gx = np.gradient(np.where(hm.found, hm.z, np.nan), cell)
        gentle = np.hypot(gx, gy) <= math.tan(math.radians(REACH_SLOPE_DEG))
        left = np.where(chosen & gentle, reach - z, 0.0)
    mask = left > min_depth
    if not mask.any():
        return []
    labels, count = label_regions(mask)
    regions = []
    for k in range(count):
        iy, ix = np.nonzero(labels == k)
        if len(iy) < MIN_CELLS:
            continue
        regions.append(CornerRegion(
            (float(xs[ix].min() - cell / 2), float(xs[ix].max() + cell / 2)),
            (float(ys[iy].min() - cell / 2), float(ys[iy].max() + cell / 2)),
            float(left[iy, ix].max()), float(len(iy) * cell * cell)))
    return sorted(regions, key=lambda r: -r.depth_mm)
