# SPDX-License-Identifier: LGPL-2.1-or-later
"""The cubic B-spline surface of a control net: the object every later stage takes.

Parameters u and w are normalised to [0, 1] over the whole surface for both knot layouts;
the knots handed to OCCT use the same scale, so OCCT's (u, v) equals ours.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import ParameterError
from ..typing import ArrayLike, FloatArray
from . import matrix, netio
from .basis import DEGREE, KnotLayout, knot_vector, unique_knots
from .matrix import DEGENERATE_NORMAL

#: Partial derivatives (du, dw) in the order of :class:`Derivatives`' fields.
SECOND_ORDER = ((0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2))


@dataclass(frozen=True)
class Derivatives:
    """Point and partial derivatives at the same parameters (mm, mm per unit parameter)."""

    point: FloatArray
    su: FloatArray
    sw: FloatArray
    suu: FloatArray
    suw: FloatArray
    sww: FloatArray


class Surface:
    """A cubic tensor-product B-spline surface evaluated by the paper's matrix form.

    >>> s = Surface(points, knots="clamped")      # points: (rows, cols, 3), rows follow u
    >>> s.evaluate(0.5, 0.5)                      # -> array([x, y, z])
    >>> s.grid(101, 101).shape                    # -> (101, 101, 3)

    The net is read-only, so the per-patch power-basis coefficients used by the scattered
    evaluations (``evaluate``, ``derivatives``, ``normals``) are computed once and cached.
    """

    degree = DEGREE

    def __init__(self, control_points: ArrayLike, knots: str | KnotLayout = "uniform", name: str = "surface"):
        self.knots = KnotLayout.parse(knots)
        self.control_points = netio.validate_net(control_points, f"surface {name!r}")
        self.control_points.setflags(write=False)
        self.name = name

    # -- construction ------------------------------------------------------------------------
    @classmethod
    def from_net(cls, net: netio.ControlNet) -> Surface:
        return cls(net.points, net.knots, net.name)

    @classmethod
    def from_json(cls, path: str | os.PathLike) -> Surface:
        return cls.from_net(netio.read_json(path))

    @classmethod
    def from_file(cls, path: str | os.PathLike, knots: str | None = None) -> Surface:
        """Read .json, .csv or a .dat grid (its points taken as control points)."""
        return cls.from_net(netio.read_net(path, knots))

    def to_net(self) -> netio.ControlNet:
        return netio.ControlNet(np.array(self.control_points), self.knots, self.name)

    def __repr__(self) -> str:
        rows, cols = self.shape
        return f"Surface({self.name!r}, {rows}x{cols} control points, knots={self.knots.value!r})"

    # -- description -------------------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return int(self.control_points.shape[0]), int(self.control_points.shape[1])

    @property
    def patches(self) -> tuple[int, int]:
        rows, cols = self.shape
        return rows - DEGREE, cols - DEGREE

    def knot_vectors(self) -> tuple[FloatArray, FloatArray]:
        """Flat knot vectors in u and w (domain [0, 1])."""
        rows, cols = self.shape
        return knot_vector(rows, self.knots), knot_vector(cols, self.knots)

    def occt_knots(self) -> dict:
        """Distinct knots and multiplicities in u and w, the form OCCT's constructors take."""
        ku, kw = self.knot_vectors()
        uk, um = unique_knots(ku)
        wk, wm = unique_knots(kw)
        return {"u_knots": uk, "u_mults": um, "w_knots": wk, "w_mults": wm}

    def size(self) -> float:
        """Diagonal of the control net's bounding box (mm): the scale for relative tolerances."""
        pts = self.control_points.reshape(-1, 3)
        return float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))

    # -- evaluation --------------------------------------------------------------------------
    @staticmethod
    def _check_params(u: ArrayLike, w: ArrayLike) -> tuple[FloatArray, FloatArray]:
        try:
            u = np.asarray(u, dtype=float)
            w = np.asarray(w, dtype=float)
        except (TypeError, ValueError):
            raise ParameterError("parameters u and w must be numbers in [0, 1]") from None
        for name, values in (("u", u), ("w", w)):
            if values.size and (not np.all(np.isfinite(values)) or values.min() < -1e-12 or values.max() > 1 + 1e-12):
                raise ParameterError(f"parameter {name} must lie in [0, 1] (normalised), got {values.min()}..{values.max()}")
        return np.clip(u, 0.0, 1.0), np.clip(w, 0.0, 1.0)

    @cached_property
    def normal_scale(self) -> float:
        """|Su x Sw| of a surface this size (mm^2 per unit parameter^2): the reference for
        degenerate normals at scattered points."""
        spans = np.subtract(self.control_points.shape[:2], DEGREE)
        return self.size() ** 2 * float(spans[0] * spans[1])

    @cached_property
    def patch_form(self) -> matrix.PatchCoefficients:
        """Power-basis coefficients of every patch (:func:`matrix.patch_form`), built once."""
        return matrix.patch_form(self.control_points, self.knots)

    @cached_property
    def normal_form(self) -> matrix.NormalCoefficients:
        """Bezier coefficients of Su x Sw on every patch (:func:`matrix.normal_form`), built
        once: grid normals evaluate them like points, with no per-point cross product."""
        return matrix.normal_form(self.patch_form)

    def evaluate(self, u: ArrayLike, w: ArrayLike, du: int = 0, dw: int = 0) -> FloatArray:
        """Points (or the (du, dw) partial derivative) at parameters u, w (broadcast): (..., 3)."""
        u, w = self._check_params(u, w)
        return matrix.evaluate_patches(self.patch_form, u, w, du, dw)

    def evaluate_grid(self, u: ArrayLike, w: ArrayLike, du: int = 0, dw: int = 0) -> FloatArray:
        """Points (or a partial derivative) on the tensor grid u x w: (len(u), len(w), 3)."""
        u, w = self._check_params(np.atleast_1d(u), np.atleast_1d(w))
        return matrix.evaluate_grid(self.control_points, self.knots, u, w, du, dw)

    def grid(self, nu: int, nw: int) -> FloatArray:
        """Points sampled uniformly over the parameter domain: (nu, nw, 3)."""
        if int(nu) < 2 or int(nw) < 2:
            raise ParameterError(f"grid needs at least 2 samples each way, got {nu}x{nw}")
        return self.evaluate_grid(np.linspace(0.0, 1.0, int(nu)), np.linspace(0.0, 1.0, int(nw)))

    def derivatives(self, u: ArrayLike, w: ArrayLike, grid: bool = False) -> Derivatives:
        """Point, first and second partial derivatives from derivatives of [U] and [W]."""
        if grid:
            ev = self.evaluate_grid
            return Derivatives(
                point=ev(u, w), su=ev(u, w, 1, 0), sw=ev(u, w, 0, 1),
                suu=ev(u, w, 2, 0), suw=ev(u, w, 1, 1), sww=ev(u, w, 0, 2),
            )
        u, w = self._check_params(u, w)
        return Derivatives(*matrix.evaluate_patch_orders(self.patch_form, u, w, SECOND_ORDER))

    def normals(self, u: ArrayLike, w: ArrayLike, grid: bool = False) -> FloatArray:
        """Unit normals Su x Sw / |Su x Sw|.

        Where that cross product vanishes (a degenerate edge or a collapsed net), the normal is
        taken from a nearby interior parameter, so no NaN reaches a toolpath.
        """
        fallback = lambda: self._nudged_normals(u, w, grid)  # noqa: E731
        if grid:
            u, w = self._check_params(np.atleast_1d(u), np.atleast_1d(w))
            normal, degenerate = matrix.grid_unit_normals(self.patch_form, self.normal_form,
                                                          u, w)
            if np.any(degenerate):
                normal[degenerate] = fallback()[degenerate]
            return normal
        cu, cw = self._check_params(u, w)
        su, sw = matrix.evaluate_patch_orders(self.patch_form, cu, cw, ((1, 0), (0, 1)))
        return unit_normals(su, sw, fallback, self.normal_scale)

    def _nudged_normals(self, u: ArrayLike, w: ArrayLike, grid: bool) -> FloatArray:
        u, w = self._check_params(u, w)
        shift = 1e-6
        u2 = np.where(u > 0.5, u - shift, u + shift)
        w2 = np.where(w > 0.5, w - shift, w + shift)
        ev = self.evaluate_grid if grid else self.evaluate
        return unit_normals(ev(u2, w2, 1, 0), ev(u2, w2, 0, 1), None)

    def grid_with_normals(self, nu: int, nw: int) -> tuple[FloatArray, FloatArray]:
        """Points and unit normals on a uniform nu x nw parameter grid."""
        u = np.linspace(0.0, 1.0, int(nu))
        w = np.linspace(0.0, 1.0, int(nw))
        return self.evaluate_grid(u, w), self.normals(u, w, grid=True)


def unit_normals(su: FloatArray, sw: FloatArray, fallback, scale: float = 0.0) -> FloatArray:
    """Normalised cross product; degenerate entries (length at most DEGENERATE_NORMAL of the
    longest, or of ``scale``: the surface's, so that a batch of points all on a collapsed
    edge is seen as such) replaced by ``fallback()``."""
    normal = np.cross(su, sw)
    length = np.sqrt(np.einsum("...c,...c->...", normal, normal))
    degenerate = length <= DEGENERATE_NORMAL * max(1.0, float(length.max(initial=0.0)), scale)
    np.divide(normal, np.where(degenerate, 1.0, length)[..., None], out=normal)
    if np.any(degenerate):
        if fallback is None:
            normal[degenerate] = (0.0, 0.0, 1.0)
        else:
            normal[degenerate] = fallback()[degenerate]
    return normal
