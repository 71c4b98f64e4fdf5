# SPDX-License-Identifier: LGPL-2.1-or-later
"""The metric of the constant-scallop distance (:mod:`.faces_scallop`): what a step of the
field costs, per grid node and direction, so that its level sets one apart are passes that
leave the asked scallop.

* **Dual costs.**  Let s(n) be the XY distance allowed between passes whose across
  direction is the unit XY vector n (:func:`.faces_scallop.stepovers`).  A field D whose
  level sets are passes must satisfy |grad D| >= 1 / s(n) with n = grad D / |grad D|: the set
  of allowed gradients is bounded by the curve n / s(n).  A least-cost path field D solves
  F(grad D) = 1, F the dual (polar) norm of the path cost c(v); for grad D to lie on or
  outside that curve c(v) must be its support function, c(v) = max_n |n . v| / s(n)
  (Rockafellar, "Convex Analysis", section 15: the polar of a gauge).  The cost 1 / s(v)
  taken along v is smaller wherever s varies with the direction (a slope: s across it is
  narrower than along it), the more so the more oblique v is to the narrow direction, so a
  front runs obliquely at that lower cost and its level sets end up wider apart than s.
  :func:`dual_costs` takes the maximum over :data:`DIRECTIONS` across directions (and the
  axes themselves), a lower bound of the support function within 1 - cos(pi / (2 N)).
* **Cusp band.**  The cusp between two passes stands between their contacts and its height
  depends on the surface over that whole band, not only where the field's path is: a contact
  on a convex fillet allows a step that leaves too high a cusp on the flat next to it.
  :func:`band_costs` gives each node, per axis k, the largest cost c_k over the nodes along
  axis k within half its own stepover across it (1 / (2 c_k)): at the middle of two passes
  the cost is the band's largest, the step at most the band's least, as the raster's
  :func:`.raster.scallop_line_offsets` asks.
* :func:`directional_cost` evaluates the per-axis costs in any XY direction: the positive
  combination of the two axes that bracket it, an upper bound (c is convex and
  1-homogeneous).
"""

from __future__ import annotations

import math

import numpy as np

from .. import kernels
from ..kernels import scallop_kernels as _sk
from ..typing import FloatArray
from .common import (
    Jet,
    ToolParameters,
    curved_stepover,
)

#: Across directions sampled over a half turn for the dual costs.
DIRECTIONS = 36


def across_directions(axes: FloatArray, count: int = DIRECTIONS) -> FloatArray:
    """Unit XY vectors: ``count`` over a half turn and the rows of ``axes``."""
    t = np.arange(count) * math.pi / count
    return np.vstack([np.column_stack([np.cos(t), np.sin(t)]), axes])


def dual_costs(allowed: FloatArray, across: FloatArray, axes: FloatArray) -> FloatArray:
    """(len(axes), m) cost per mm along each unit XY vector of ``axes``: max over the across
    directions n of |n . a| / s(n), ``allowed`` (len(across), m) the stepovers s (mm)."""
    inv = 1.0 / allowed
    weight = np.abs(axes @ across.T)  # (axes, across)
    out = np.empty((len(axes), allowed.shape[1]))
    for k in range(len(axes)):
        out[k] = np.max(weight[k][:, None] * inv, axis=0)
    return out


def band_costs(cost: FloatArray, steps: FloatArray, dx: float, dy: float,
               share: float = 0.5, sides: tuple = (1, -1)) -> FloatArray:
    """Per direction k the largest finite ``cost[k]`` over the nodes at t ``steps[k]`` (t a
    whole number of either sign in ``sides``, ``steps[k]`` = (di, dj) in nodes, rounded to
    the nearest node) within ``share`` / cost[k] mm of the node; non-finite entries stay as
    they are."""
    out = cost.copy()
    _, nx, ny = cost.shape
    for k, (di, dj) in enumerate(steps):
        c = cost[k]
        finite = np.isfinite(c) & (c > 0)
        if not finite.any():
            continue
        step = math.hypot(di * dx, dj * dy)
        reach = np.where(finite, share / np.where(finite, c, 1.0), 0.0)
        tmax = int(math.floor(float(reach.max()) / step))
        src = np.where(finite, c, -np.inf)
        best = src.copy()
        if kernels.use_numba() and src.dtype == reach.dtype == np.float64:
            offsets = {}  # (oi, oj): the least distance that reaches it
            for t in range(1, tmax + 1):
                for sign in sides:
                    offsets.setdefault((int(round(sign * t * di)), int(round(sign * t * dj))),
                                       t * step)
            try:
                _sk.band(src, reach, np.array([o[0] for o in offsets], dtype=np.int64),
                         np.array([o[1] for o in offsets], dtype=np.int64),
                         np.array(list(offsets.values()), dtype=float), best)
                out[k] = np.where(finite, best, c)
                continue
            except kernels.KernelUnavailable:
                pass
        seen = set()
        for t in range(1, tmax + 1):
            within = reach >= t * step
            for sign in sides:
                oi, oj = int(round(sign * t * di)), int(round(sign * t * dj))
                if (oi, oj) in seen:
                    continue
                seen.add((oi, oj))
                shifted = np.full((nx, ny), -np.inf)
                a0, a1 = max(0, -oi), min(nx, nx - oi)
                b0, b1 = max(0, -oj), min(ny, ny - oj)
                if a0 >= a1 or b0 >= b1:
                    continue
                shifted[a0:a1, b0:b1] = src[a0 + oi:a1 + oi, b0 + oj:b1 + oj]
                best = np.where(within, np.maximum(best, shifted), best)
        out[k] = np.where(finite, best, c)
    return out


class NormalCurvature:
    """:func:`.common.normal_curvature` at one jet's points in direction after direction:
    the normal and the fundamental forms are taken once, the rest as there, so the values
    are the same to the bit."""

    def __init__(self, jet: Jet):
        self.normal = n = jet.normal
        self.su, self.sw = jet.su, jet.sw
        self.E = np.einsum("ij,ij->i", jet.su, jet.su)
        self.F = np.einsum("ij,ij->i", jet.su, jet.sw)
        self.G = np.einsum("ij,ij->i", jet.sw, jet.sw)
        det = self.E * self.G - self.F * self.F
        self.det = np.where(np.abs(det) > 0, det, 1.0)
        self.L = np.einsum("ij,ij->i", jet.suu, n)
        self.M = np.einsum("ij,ij->i", jet.suw, n)
        self.N = np.einsum("ij,ij->i", jet.sww, n)

    def __call__(self, direction: FloatArray) -> FloatArray:
        """Normal curvature (1/mm, positive concave) in the tangent direction nearest each
        row of ``direction`` (3-vectors)."""
        n, E, F, G, det = self.normal, self.E, self.F, self.G, self.det
        d = np.asarray(direction, dtype=float)
        d = d - np.einsum("ij,ij->i", d, n)[:, None] * n
        bu = np.einsum("ij,ij->i", d, self.su)
        bw = np.einsum("ij,ij->i", d, self.sw)
        a = (G * bu - F * bw) / det
        b = (E * bw - F * bu) / det
        first = E * a * a + 2 * F * a * b + G * b * b
        second = self.L * a * a + 2 * self.M * a * b + self.N * b * b
        return second / np.where(first > 0, first, 1.0)


def cover_costs(jet: Jet, tool: ToolParameters, axes: FloatArray) -> FloatArray:
    """(len(axes), m) cost per XY mm, along each unit XY vector a of ``axes``, of moving away
    from a ball's contact at the jet's point across a pass that runs perpendicular to a:
    1/2 where the swept ball's vertical gap over the surface grows to ``tool.scallop``.  The
    gap test's metric, measured from the passes' contact lines, not their centres (on a
    slope of angle t a ball's contact lies R sin t uphill of its centre, and the surface
    under the centre lies R (sec t - 1) below its tip).

    In the vertical plane along a, scaled by cos(beta) (beta the slope along the pass) as in
    :func:`.raster.cross_section_stepover`, half the contact arc between two passes leaving
    that cusp (:func:`.common.curved_stepover`), over sec of the scaled slope: the XY
    distance from the contact to the cusp (a hollow tighter than the ball: the flat one).
    Unlike the stepover, a hollow the ball nearly fits bounds it: its contacts do not crowd."""
    R, h = tool.radius, tool.scallop
    curvature = NormalCurvature(jet)
    n = curvature.normal
    nz = np.clip(n[:, 2], 1e-3, 1.0)
    out = np.empty((len(axes), len(n)))
    for k, a in enumerate(axes):
        along = np.array([-a[1], a[0]])
        na = n[:, :2] @ a
        p = -na / nz
        ta = -(n[:, :2] @ along) / nz
        cos_b = 1.0 / np.sqrt(1.0 + ta * ta)
        sec = np.sqrt(1.0 + p * p)
        t = np.column_stack([np.full(len(n), a[0]), np.full(len(n), a[1]), p])
        cos_phi = np.clip((nz - p * na) / sec, 1e-3, 1.0)
        z2 = curvature(t) * sec ** 3 / cos_phi * cos_b
        p2 = p * cos_b
        sec2 = np.sqrt(1.0 + p2 * p2)
        kappa2 = z2 / sec2 ** 3
        half = 0.5 * curved_stepover(R, h * cos_b / sec2, kappa2) / sec2
        out[k] = 0.5 / np.clip(half, 0.01 * tool.flat_stepover, R)
    return out


def directional_cost(cost: FloatArray, axes: FloatArray, v: FloatArray,
                     against: FloatArray | None = None, bound: bool = True) -> FloatArray:
    """Cost (m,) of the XY vectors ``v`` (m, 2) from per-axis costs per mm ``cost``
    (len(axes), m) at the same points, ``against`` for travel against each axis (default
    ``cost``).  With ``bound``: v as a positive combination of the two of the axes and their
    opposites that bracket it, the costs combined alike (an upper bound where the cost is
    convex, within 1 / cos(half the angle between the axes) - 1); else the cost per mm
    interpolated linearly in the angle between them (exact where it is isotropic, second
    order in the angle elsewhere), times |v|."""
    dirs = np.vstack([axes, -axes])
    c = np.vstack([cost, cost if against is None else against])
    ang = np.mod(np.arctan2(dirs[:, 1], dirs[:, 0]), 2.0 * math.pi)
    order = np.argsort(ang)
    ang, dirs, c = ang[order], dirs[order], c[order]
    theta = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * math.pi)
    lo = np.searchsorted(ang, theta, side="right") - 1  # ang[0] = 0: lo >= 0
    hi = (lo + 1) % len(ang)
    m = np.arange(len(theta))
    if not bound:
        span = np.where(hi == 0, 2.0 * math.pi, ang[hi]) - ang[lo]
        w = (theta - ang[lo]) / span
        return ((1.0 - w) * c[lo, m] + w * c[hi, m]) * np.hypot(v[:, 0], v[:, 1])
    a, b = dirs[lo], dirs[hi]
    det = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    alpha = (v[:, 0] * b[:, 1] - v[:, 1] * b[:, 0]) / det
    beta = (a[:, 0] * v[:, 1] - a[:, 1] * v[:, 0]) / det
    return np.abs(alpha) * c[lo, m] + np.abs(beta) * c[hi, m]


def directional_cost_on(cost: FloatArray, against: FloatArray, axes: FloatArray,
                        on: np.ndarray, v: FloatArray) -> FloatArray:
    """:func:`directional_cost` without ``bound`` at the nodes ``on`` (nx, ny) of per-axis
    cost grids ``cost`` and ``against`` (len(axes), nx, ny), ``v`` (m, 2) the vectors at
    those nodes in row-major order: ``directional_cost(cost[:, on], axes, v, against[:, on],
    bound=False)``, the costs read in place."""
    if kernels.use_numba():
        dirs = np.vstack([axes, -axes])
        ang = np.mod(np.arctan2(dirs[:, 1], dirs[:, 0]), 2.0 * math.pi)
        order = np.argsort(ang)
        theta = np.mod(np.arctan2(v[:, 1], v[:, 0]), 2.0 * math.pi)
        ii, jj = np.nonzero(on)
        try:
            return _sk.interpolated_cost(cost, against, order.astype(np.int64), ang[order],
                                         ii.astype(np.int64), jj.astype(np.int64), theta,
                                         np.ascontiguousarray(v[:, 0]),
                                         np.ascontiguousarray(v[:, 1]))
        except kernels.KernelUnavailable:
            pass
    return directional_cost(cost[:, on], axes, v, against[:, on], bound=False)


__all__ = ["DIRECTIONS", "NormalCurvature", "across_directions", "band_costs", "cover_costs", "directional_cost",
           "directional_cost_on", "dual_costs"]
