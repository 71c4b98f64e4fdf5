# SPDX-License-Identifier: LGPL-2.1-or-later
"""Gap passes of the constant-scallop finish (:mod:`.faces_scallop`).

The cusp over a surface point is set by the passes whose contacts run near it: a ball stands
above the surface by a gap that grows with the distance from its contact.  So the scallop is
kept wherever E, the distance of the surface point from the passes' contact lines counted so
that it is 1/2 where the gap reaches the asked scallop (:func:`.scallop_metric.cover_costs`),
is at most 1/2.  It is measured on the surface from the contacts, not between ball centres:
on a slope of angle t a ball's contact lies R sin t uphill of its centre and the surface
under the centre lies R (sec t - 1) below its tip, so downhill of a pass the scallop grows
faster than uphill, and where passes cross a slope obliquely their contacts bunch up or
spread.  The level sets of the scallop distance D keep the scallop between two loops from
the same side; where fronts from different sides meet (a ridge of D, the corners of nested
loops, the strip between a hole's rings and a border's) and on such slopes they can stand
too far apart.

E is taken on a grid of surface points :data:`FINE` times finer than the field's (the
top-most face above each node, :class:`.geometry.faces_height.FacesHeight`), on the
selected faces where a ball centred along the normal R above the point lies in the field's
region: from the XY vector to the nearest contact segment of the passes (exact drop-cutter
contacts) at the point's cost along it.  Each region where E exceeds 1/2 and somewhere
:func:`gap_limit` gets the contour E = 1/2 round it, moved to the ball centres R along the
normals, as a pass: its contacts half a stepover from the passes outside, every point inside
within half a stepover of them while the region's largest E is at most 1.  Rounds repeat
with the added passes until no such region is left or :data:`ROUNDS` have run.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from .. import kernels
from ..geometry.faces_height import FacesHeight
from ..kernels import scallop_kernels as _sk
from ..typing import FloatArray
from .common import Jet, ToolParameters
from .scallop_field import NearField, bilinear, contour_keys, edge_points
from .scallop_metric import band_costs, cover_costs, directional_cost_on

#: Beyond reach of every pass (stepovers).
FAR = 1.0
#: The surface grid is this many times finer than the field's, less where that would pass
#: MAX_SURFACE_NODES (each holds 2 COVER_DIRECTIONS costs).
FINE = 3
MAX_SURFACE_NODES = 1_000_000
#: Rounds of gap passes at most.
ROUNDS = 5
#: E is measured out to this many times the widest half stepover (the
#: ``REACH_PERCENTILE``-th percentile of the surface points' widest).
REACH_SHARE = 1.2
REACH_PERCENTILE = 99.0
#: Directions over a half turn along which the cover costs are evaluated (the cost along
#: another is interpolated from the two that bracket it, an upper bound within about
#: 1 - cos(pi / (2 COVER_DIRECTIONS)) where the metric is near isotropic).
COVER_DIRECTIONS = 16


class SurfaceGrid:
    """Surface points under a grid :data:`FINE` times finer than the field's (xs, ys), the
    cover costs about each along :data:`COVER_DIRECTIONS` directions and the upward
    normals."""

    def __init__(self, faces: list, signs: FloatArray, tool: ToolParameters, xs: FloatArray,
                 ys: FloatArray, inside: np.ndarray):
        fine = FINE
        while fine > 1 and (fine * (len(xs) - 1) + 1) * (fine * (len(ys) - 1) + 1) \
                > MAX_SURFACE_NODES:
            fine -= 1
        self.xs = np.linspace(xs[0], xs[-1], fine * (len(xs) - 1) + 1)
        self.ys = np.linspace(ys[0], ys[-1], fine * (len(ys) - 1) + 1)
        self.dx, self.dy = self.xs[1] - self.xs[0], self.ys[1] - self.ys[0]
        self.shape = (len(self.xs), len(self.ys))
        t = np.arange(COVER_DIRECTIONS) * np.pi / COVER_DIRECTIONS
        self.axes = axes = np.column_stack([np.cos(t), np.sin(t)])
        cell = min(self.dx, self.dy)
        hm = FacesHeight(faces, cell).grid(self.xs, self.ys)
        face = hm.face.T
        chosen = np.array([f.selected for f in faces] + [False])
        on = chosen[face] & np.isfinite(hm.z.T)
        u, v = hm.u.T, hm.v.T
        self.cover = np.full((len(axes),) + self.shape, np.inf)
        self.normal = np.zeros(self.shape + (3,))
        for k in np.unique(face[on]).tolist():
            m = on & (face == k)
            jet = Jet.at(faces[k].surface, u[m], v[m], float(signs[k]))
            self.cover[:, m] = cover_costs(jet, tool, axes)
            self.normal[m] = jet.normal
        # the gap at a point depends on the surface between it and the contact: moving
        # along an axis, the largest cost over the half stepover behind the point, against
        # it over the half stepover ahead
        steps = axes * cell / np.array([self.dx, self.dy])
        self.against = band_costs(self.cover, steps, self.dx, self.dy,
                                  sides=(1,)).astype(np.float32)
        self.cover = band_costs(self.cover, steps, self.dx, self.dy,
                                sides=(-1,)).astype(np.float32)
        X, Y = np.meshgrid(self.xs, self.ys, indexing="ij")
        centre = np.column_stack([(X + tool.radius * self.normal[..., 0]).ravel(),
                                  (Y + tool.radius * self.normal[..., 1]).ravel()])
        reach = bilinear(inside.astype(float), xs, ys, centre).reshape(self.shape) > 0.999
        self.on = on & reach
        self.radius = tool.radius
        # reach: 1.2 times the widest half stepover but over hollows the ball nearly fits
        # (where E is small at any distance that matters); a point beyond it from every
        # contact line counts as far only where its own half stepover is within reach
        half = 0.5 / np.min(np.minimum(self.cover, self.against)[:, self.on], axis=0) \
            if self.on.any() else [cell]
        self.reach_mm = REACH_SHARE * float(np.percentile(half, REACH_PERCENTILE))
        self.reach = int(np.ceil(self.reach_mm / cell)) + 1
        self.half = np.full(self.shape, np.inf)
        self.half[self.on] = half
        # E where no contact line is within reach: far where the point's half stepover is
        self.beyond = np.full(self.shape, np.nan)
        self.beyond[self.on] = np.where(self.half[self.on] * REACH_SHARE <= self.reach_mm,
                                        FAR, 0.0)

    def near_field(self) -> NearField:
        """An empty :class:`.scallop_field.NearField` over the surface points, out to the
        reach: the contact lines for :meth:`distance`."""
        return NearField(self.xs, self.ys, self.reach)

    def distance(self, contact_lines: NearField) -> FloatArray:
        """E (nx, ny) at the surface points from the contact lines taken into
        ``contact_lines`` (NaN off them; :data:`FAR` beyond reach), each
        raised to the largest E between it and a neighbour along x or y: across a band
        between two contact lines E is a tent whose ridge mostly lies between the nodes.
        From a node E grows along its vector from the nearest contact v at the cost along
        v per mm, so along the edge to its neighbour at that cost times the cosine; where
        both grow towards each other, the tent's top lies where the two lines meet."""
        near, vec = contact_lines.out, contact_lines.vec
        on = self.on & np.isfinite(near)
        length = np.hypot(vec[..., 0], vec[..., 1])
        unit = vec / np.where(length > 0, length, 1.0)[..., None]
        rate = np.zeros(self.shape)
        rate[on] = directional_cost_on(self.cover, self.against, self.axes, on, unit[on])
        e = self.beyond.copy()
        e[on] = rate[on] * length[on]
        return tents(e, rate, unit, on, self.dx, self.dy)

    def centres(self, p: FloatArray) -> FloatArray:
        """XY of the ball centres R along the (interpolated) normals above surface points p."""
        nx = bilinear(self.normal[..., 0], self.xs, self.ys, p)
        ny = bilinear(self.normal[..., 1], self.xs, self.ys, p)
        return p + self.radius * np.column_stack([nx, ny])


def tents(e: FloatArray, rate: FloatArray, unit: FloatArray, on: np.ndarray, dx: float,
          dy: float) -> FloatArray:
    """E (nx, ny) raised at each node to the top of the tent between it and its neighbour
    along x or y (:meth:`SurfaceGrid.distance`), E growing from both nodes (``on``) at
    ``rate`` per mm along their unit vectors ``unit`` (nx, ny, 2) from the contacts."""
    out = np.array(e, dtype=float)
    if kernels.use_numba():
        try:
            f64 = np.float64
            _sk.tent(np.ascontiguousarray(e, f64), np.ascontiguousarray(rate, f64),
                     np.ascontiguousarray(unit, f64), np.ascontiguousarray(on, bool),
                     float(dx), float(dy), out, np.empty(e.shape))
            return out
        except kernels.KernelUnavailable:
            pass
    for axis, step in ((0, dx), (1, dy)):
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[axis], hi[axis] = slice(None, -1), slice(1, None)
        lo, hi = tuple(lo), tuple(hi)
        both = on[lo] & on[hi]
        s1 = rate[lo] * unit[lo][..., axis]  # growth from the lower node towards the upper
        s2 = -rate[hi] * unit[hi][..., axis]
        up = both & (s1 > 0) & (s2 > 0)
        with np.errstate(invalid="ignore", divide="ignore"):
            t = (e[hi] - e[lo] + s2 * step) / (s1 + s2)
            top = np.where(up & (t > 0) & (t < step), e[lo] + s1 * t, -np.inf)
        out[lo] = np.fmax(out[lo], top)
        out[hi] = np.fmax(out[hi], top)
    return out


def gap_limit(tool: ToolParameters) -> float:
    """E above which a region gets a gap pass: the cusp grows as the square of the distance
    from the contact, so E = 1/2 sqrt(1 + tol / (2 h)) leaves it within half the chordal
    tolerance over the scallop (the other half is the chords' lift, :func:`.chords.
    lift_chords`)."""
    return 0.5 * math.sqrt(1.0 + tool.tolerance / tool.scallop)


def thin_midline(loop: FloatArray, width: float) -> FloatArray:
    """A closed polyline narrower than ``width`` (mm; twice its area over its length) as its
    midline: split at its two points furthest apart, the two sides resampled alike by arc
    length and averaged; others as they are.  Round a sliver (a ridge of E that passes the
    limit by little) one pass along it covers it: both sides would cut the band twice."""
    if len(loop) < 5 or not np.allclose(loop[0], loop[-1]):
        return loop
    x, y = loop[:, 0], loop[:, 1]
    area = 0.5 * abs(float(np.dot(x[:-1], y[1:]) - np.dot(x[1:], y[:-1])))
    seg = np.hypot(*np.diff(loop, axis=0).T)
    if 2.0 * area / max(float(seg.sum()), 1e-12) >= width:
        return loop
    ring = loop[:-1]
    a = int(np.argmax(np.hypot(*(ring - ring[0]).T)))
    b = int(np.argmax(np.hypot(*(ring - ring[a]).T)))
    ring = np.roll(ring, -a, axis=0)
    b = (b - a) % len(ring)
    one = ring[:b + 1]
    other = np.vstack([ring[b:], ring[:1]])[::-1]

    def resample(p: FloatArray, m: int) -> FloatArray:
        t = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(p, axis=0).T))])
        u = np.linspace(0.0, t[-1], m)
        return np.column_stack([np.interp(u, t, p[:, 0]), np.interp(u, t, p[:, 1])])

    m = max(len(one), len(other), 2)
    return 0.5 * (resample(one, m) + resample(other, m))


def gap_passes(surface: SurfaceGrid, polylines: list, contacts: Callable[[list], list],
               limit: float, thin: float) -> tuple[list, float]:
    """XY polylines (mm, ball centres) that close the gaps of ``polylines`` (see the module
    docstring), ``contacts`` giving the contact lines of centre polylines, ``limit`` the E
    above which a region gets one (:func:`gap_limit`), a loop narrower than ``thin`` (mm)
    made its midline (:func:`thin_midline`); and the area (mm^2, XY of surface points) still
    further than ``limit`` from every pass after them."""
    added: list = []
    lines = surface.near_field()
    lines.add(contacts(polylines))
    e = None
    for _ in range(ROUNDS):
        e = surface.distance(lines)
        filled = np.nan_to_num(e, nan=0.0)  # off the surface: below all
        if not (filled > limit).any():
            break
        new = [surface.centres(thin_midline(edge_points(filled, surface.xs, surface.ys,
                                                        chain, limit), thin))
               for chain in contour_keys(filled, limit)]
        if not new:
            break
        added += new
        lines.add(contacts(new))
        e = None
    if e is None:  # passes were added since the last E
        e = surface.distance(lines)
    left = np.count_nonzero(np.nan_to_num(e, nan=0.0) > limit)
    return added, float(left) * surface.dx * surface.dy


__all__ = ["COVER_DIRECTIONS", "FAR", "FINE", "MAX_SURFACE_NODES", "ROUNDS", "SurfaceGrid", "gap_limit",
           "gap_passes", "tents", "thin_midline"]
