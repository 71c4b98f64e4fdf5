# SPDX-License-Identifier: LGPL-2.1-or-later
"""The stock a job starts from, as plain data (mm): a block, or a vertical cylinder (issue 12).

FreeCAD CAM's job stock is a box ("FromBase", "CreateBox") or a cylinder ("CreateCylinder",
``Path/Main/Stock.py``: Radius, Height and a Placement whose axis is the cylinder's).  A
cylinder is not its bounding box: the four corners between the circle and the box hold no
material, so a roughing that clears them cuts air and a simulation that starts from them
counts volume that was never there.  Both forms answer the same questions, so the roughing
(:mod:`.toolpath.roughing`) and the job simulation (:mod:`.job_simulation`) take either:
``bounds`` (the XYZ box), ``contains_xy`` (the footprint as a mask of points) and
``distance_xy`` (how far a point lies outside the footprint).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..typing import FloatArray
from ..validation import check_finite


def _finite(value: Any, argument: str) -> float:
    return check_finite(value, argument, "mm")


@dataclass(frozen=True)
class Stock:
    """A block of stock (mm)."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    z_min: float
    z_max: float

    def __post_init__(self) -> None:
        for name in ("x_min", "x_max", "y_min", "y_max", "z_min", "z_max"):
            object.__setattr__(self, name, _finite(getattr(self, name), f"stock {name}"))
        for axis in "xyz":
            lo, hi = getattr(self, f"{axis}_min"), getattr(self, f"{axis}_max")
            if not hi > lo:
                raise ParameterError(
                    f"stock {axis}_max ({hi:g} mm) must lie above {axis}_min ({lo:g} mm)")

    @classmethod
    def around(cls, bounds: tuple[float, float, float, float, float, float], margin: float,
               top_margin: float | None = None) -> Stock:
        """The part box (x0, x1, y0, y1, z0, z1) grown by ``margin`` sideways and
        ``top_margin`` (default ``margin``) above; the bottom is the part's bottom (mm)."""
        margin = _nonnegative(margin, "margin")
        top = margin if top_margin is None else _nonnegative(top_margin, "top_margin")
        x0, x1, y0, y1, z0, z1 = (float(v) for v in bounds)
        return cls(x0 - margin, x1 + margin, y0 - margin, y1 + margin, z0, z1 + top)

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """(x_min, x_max, y_min, y_max, z_min, z_max) mm."""
        return (self.x_min, self.x_max, self.y_min, self.y_max, self.z_min, self.z_max)

    def contains_xy(self, xs: FloatArray, ys: FloatArray) -> np.ndarray:
        """True where the points (broadcast xs, ys, mm) lie in the block's XY (edges in)."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        return (xs >= self.x_min) & (xs <= self.x_max) & (ys >= self.y_min) & (ys <= self.y_max)

    def distance_xy(self, xs: FloatArray, ys: FloatArray) -> FloatArray:
        """Distance (mm) from the points (broadcast) to the block's XY rectangle, 0 inside."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        dx = np.maximum(np.maximum(self.x_min - xs, xs - self.x_max), 0.0)
        dy = np.maximum(np.maximum(self.y_min - ys, ys - self.y_max), 0.0)
        return np.hypot(dx, dy)

    def describe(self) -> str:
        """The block for messages (mm)."""
        return (f"block x {self.x_min:g}..{self.x_max:g}, y {self.y_min:g}..{self.y_max:g}, "
                f"z {self.z_min:g}..{self.z_max:g} mm")


@dataclass(frozen=True)
class CylinderStock:
    """A cylinder of stock with its axis along Z (mm): centre (x, y), ``radius``, from
    ``z_min`` to ``z_max``; CAM's "CreateCylinder" stock when its axis is vertical."""

    x: float
    y: float
    radius: float
    z_min: float
    z_max: float

    def __post_init__(self) -> None:
        for name in ("x", "y", "radius", "z_min", "z_max"):
            object.__setattr__(self, name, _finite(getattr(self, name), f"stock cylinder {name}"))
        if not self.radius > 0:
            raise ParameterError(
                f"stock cylinder radius must be above 0 mm, got {self.radius:g} mm")
        if not self.z_max > self.z_min:
            raise ParameterError(f"stock cylinder z_max ({self.z_max:g} mm) must lie above "
                                 f"z_min ({self.z_min:g} mm)")

    @property
    def x_min(self) -> float:
        return self.x - self.radius

    @property
    def x_max(self) -> float:
        return self.x + self.radius

    @property
    def y_min(self) -> float:
        return self.y - self.radius

    @property
    def y_max(self) -> float:
        return self.y + self.radius

    @property
    def bounds(self) -> tuple[float, float, float, float, float, float]:
        """The bounding box (x_min, x_max, y_min, y_max, z_min, z_max) mm."""
        return (self.x_min, self.x_max, self.y_min, self.y_max, self.z_min, self.z_max)

    def contains_xy(self, xs: FloatArray, ys: FloatArray) -> np.ndarray:
        """True where the points (broadcast xs, ys, mm) lie in the circle (rim in)."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        return (xs - self.x) ** 2 + (ys - self.y) ** 2 <= self.radius ** 2

    def distance_xy(self, xs: FloatArray, ys: FloatArray) -> FloatArray:
        """Distance (mm) from the points (broadcast) to the circle's disk, 0 inside."""
        xs, ys = np.asarray(xs, dtype=float), np.asarray(ys, dtype=float)
        return np.maximum(np.hypot(xs - self.x, ys - self.y) - self.radius, 0.0)

    def describe(self) -> str:
        """The cylinder for messages (mm)."""
        return (f"cylinder centre ({self.x:g}, {self.y:g}), radius {self.radius:g}, "
                f"z {self.z_min:g}..{self.z_max:g} mm")


#: Either form of stock.
StockShape = Stock | CylinderStock


def _nonnegative(value: Any, argument: str) -> float:
    number = _finite(value, argument)
    if number < 0:
        raise ParameterError(f"{argument} must be at least 0 mm, got {number:g} mm")
    return number
