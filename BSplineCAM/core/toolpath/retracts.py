# SPDX-License-Identifier: LGPL-2.1-or-later
"""Minimum retracts: between two passes the tool climbs only as high as the model and the
stock need, not to the clearance plane.

Where no stay-down link joins two passes (:mod:`.links`), a full retract climbs to the
clearance plane, travels there and comes back down: on a part 40 mm tall every such gap costs
80 mm of vertical rapid and a plunge from the safe height at the plunge feed.  A *hop* climbs
at the end of one pass to the travel height, moves straight across at that height and comes
down at the next pass's start to its approach height, from where the tool feeds to the pass:

* the **travel height** of a hop clears, by ``margin`` mm, the model under the ball along the
  straight line between the two points and the stock left there (when known);
* its **approach height** is ``margin`` mm above the pass start or above the stock around it,
  whichever is higher.

The model's bound is a certificate, not a sample.  A ball of radius R whose centre lies
within r of q lies inside the ball of radius R + r centred on q, so wherever that larger
ball can sit the smaller one can too: the tip of the tool anywhere within r of q is at most
``tip'(q) + r`` high, tip' the drop-cutter's tip height of the ball R + r at q.  Drops of the
larger ball at points at most 2r apart along the travel line bound the model under the whole
line, at most about r above its true top (on a flat exactly r); r is a quarter of the
ball's radius or half the margin, whichever is smaller.  The certified drop-cutter's own
tolerance is added.

The stock is a Z-map (the job simulation of the operations before this one): a tip at height
z clears every column whose centre lies within the ball's radius of its path when z is above
them.  The columns within R plus a whole cell's diagonal of the line are taken: the stock
between two cell centres, which the map does not hold (a terrace's edge inside a cell whose
centre was cut), lies next to a centre within that reach.

The stock may instead be declared as the model raised by an allowance
(:class:`RaisedModel`: a part roughed by another program, or a near-net casting, to within
that much of the model): the model's bound and the pass start, raised by the allowance, stand
for the stock's.  A ball's drop onto a surface moved up by a distance is its drop onto the
surface moved up by that distance, so the bound stays a certificate.  Without a stock the hop
clears only the model: that is for programs run on a part already roughed to within
``margin`` of the model.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..typing import FloatArray
from .dropcutter import DropCutter
from .faceset_params import CERTIFY

#: drop(xy (m, 2) mm, ball radius mm) -> tool-tip heights (m,) mm, NaN where no face is under
#: the ball; an upper bound of the true height to within ``DropFn`` callers' ``slack``.
DropFn = Callable[[FloatArray, float], FloatArray]

#: Default clearance (mm) of a hop above the model and the stock.
DEFAULT_MARGIN = 1.0
#: Smallest and largest margin (mm).
MARGIN_RANGE = (0.1, 100.0)
#: Smallest and largest allowance of a :class:`RaisedModel` stock (mm).
ALLOWANCE_RANGE = (0.0, 100.0)


@dataclass(frozen=True)
class StockMap:
    """The stock's top as a Z-map: cells of ``cell`` mm from (x0, y0), heights (ny, nx) mm at
    the cell centres (rows along y), NaN or -inf where no stock is left.  ``whole_block``:
    the raw block, uncut (entries then stop at the safe height, which lies above it)."""

    x0: float
    y0: float
    cell: float
    height: FloatArray
    whole_block: bool = False

    def top_near(self, a: FloatArray, b: FloatArray, reach: float) -> FloatArray:
        """Per row, the highest stock column whose centre lies within ``reach`` mm of the
        segment from ``a[i]`` to ``b[i]`` (XY, mm); -inf where none."""
        ny, nx = self.height.shape
        out = np.full(len(a), -np.inf)
        h = np.where(np.isfinite(self.height), self.height, -np.inf)
        for i, (p, q) in enumerate(zip(np.asarray(a, float), np.asarray(b, float))):
            lo = np.minimum(p, q) - reach
            hi = np.maximum(p, q) + reach
            c0 = max(int(np.floor((lo[0] - self.x0) / self.cell - 0.5)), 0)
            c1 = min(int(np.ceil((hi[0] - self.x0) / self.cell - 0.5)), nx - 1)
            r0 = max(int(np.floor((lo[1] - self.y0) / self.cell - 0.5)), 0)
            r1 = min(int(np.ceil((hi[1] - self.y0) / self.cell - 0.5)), ny - 1)
            if c1 < c0 or r1 < r0:
                continue
            xs = self.x0 + (np.arange(c0, c1 + 1) + 0.5) * self.cell
            ys = self.y0 + (np.arange(r0, r1 + 1) + 0.5) * self.cell
            px, py = np.meshgrid(xs, ys)
            d = q - p
            dd = float(d @ d)
            t = np.zeros_like(px) if dd == 0.0 else np.clip(
                ((px - p[0]) * d[0] + (py - p[1]) * d[1]) / dd, 0.0, 1.0)
            near = np.hypot(px - (p[0] + t * d[0]), py - (p[1] + t * d[1])) <= reach
            if near.any():
                out[i] = float(h[r0:r1 + 1, c0:c1 + 1][near].max())
        return out


@dataclass(frozen=True)
class RaisedModel:
    """The stock declared as the model raised by ``allowance`` mm, measured vertically: the
    part was roughed (or cast) to within that of the model before this program."""

    allowance: float


@dataclass(frozen=True)
class Hops:
    """Per gap between consecutive passes: the tip height (mm) of the rapid across and of the
    rapid descent's end, NaN where a stay-down link joins the passes or the tool retracts to
    the clearance plane (a hop would reach it anyway).  ``entry``, when the stock is known:
    per pass, how low the rapid descent from the clearance plane may end above its start
    (``margin`` over the stock there), NaN or None where it stops at the safe height."""

    travel: FloatArray
    approach: FloatArray
    entry: FloatArray | None = None


def model_bound(drop: DropFn, a: FloatArray, b: FloatArray, radius: float, reach: float,
                slack: float) -> FloatArray:
    """Per row, a height (mm) no tool-tip position of the ball ``radius`` on the segment from
    ``a[i]`` to ``b[i]`` (XY) lies below when resting on the model: drops of the ball of radius
    ``radius + reach`` at most 2 ``reach`` apart (see the module docstring), plus ``reach``
    and the drop-cutter's ``slack``; -inf where no face lies under any of them."""
    a = np.asarray(a, float).reshape(-1, 2)
    b = np.asarray(b, float).reshape(-1, 2)
    r = float(reach)
    length = np.hypot(*(b - a).T)
    n = np.maximum(np.ceil(length / (2.0 * r)).astype(int), 1)
    row = np.repeat(np.arange(len(a)), n + 1)
    frac = np.concatenate([np.arange(k + 1) / k for k in n])
    pts = a[row] + frac[:, None] * (b - a)[row]
    tip = np.asarray(drop(pts, float(radius) + r), dtype=float)
    out = np.full(len(a), -np.inf)
    ok = np.isfinite(tip)
    np.maximum.at(out, row[ok], tip[ok] + r + slack)
    return out


def hop_heights(passes: list, links: list, drop: DropFn, radius: float, clearance: float,
                margin: float = DEFAULT_MARGIN, slack: float = 0.0,
                stock: StockMap | RaisedModel | None = None) -> Hops:
    """The :class:`Hops` of ``passes`` (tip positions (n, 3), in machining order) whose gaps
    have no stay-down link in ``links`` (None entries; an empty list: none).  ``drop`` is the
    drop-cutter over every face the tool may meet (check surfaces included), ``slack`` (mm) how
    far its heights may lie below the true ones, ``stock`` the stock left (a Z-map, or the
    model raised by an allowance), if known.  A hop
    whose travel height would not stay ``margin`` below ``clearance`` is left to the full
    retract (NaN)."""
    gaps = max(len(passes) - 1, 0)
    links = list(links) if links else [None] * gaps
    travel = np.full(gaps, np.nan)
    approach = np.full(gaps, np.nan)
    entry = _entries(passes, radius, margin, stock)
    todo = [k for k in range(gaps) if links[k] is None]
    if not todo:
        return Hops(travel, approach, entry)
    end = np.array([passes[k][-1] for k in todo], float)
    start = np.array([passes[k + 1][0] for k in todo], float)
    raised = float(stock.allowance) if isinstance(stock, RaisedModel) else 0.0
    top = np.maximum(end[:, 2], start[:, 2]) + raised
    reach = min(0.25 * float(radius), 0.5 * float(margin))
    top = np.fmax(top, model_bound(drop, end[:, :2], start[:, :2], radius, reach, slack) + raised)
    land = start[:, 2] + raised
    if isinstance(stock, StockMap):
        reach = float(radius) + np.sqrt(2.0) * stock.cell
        top = np.fmax(top, stock.top_near(end[:, :2], start[:, :2], reach))
        land = np.fmax(land, stock.top_near(start[:, :2], start[:, :2], reach))
    hop = top + margin
    ok = hop < clearance - margin
    idx = np.asarray(todo)[ok]
    travel[idx] = hop[ok]
    approach[idx] = np.minimum(land[ok] + margin, hop[ok])
    return Hops(travel, approach, entry)


def _entries(passes: list, radius: float, margin: float,
             stock: StockMap | RaisedModel | None) -> FloatArray | None:
    """Per pass, ``margin`` above its start or above the stock around it (a hop's approach
    height, :func:`hop_heights`); None without a stock or on the whole raw block.  Straight
    above a pass's start the ball clears the model: the start is the drop-cutter's height
    there."""
    if stock is None or not passes or getattr(stock, "whole_block", False):
        return None
    start = np.array([p[0] for p in passes], float)
    if isinstance(stock, RaisedModel):
        return start[:, 2] + float(stock.allowance) + margin
    reach = float(radius) + np.sqrt(2.0) * stock.cell
    return np.fmax(start[:, 2], stock.top_near(start[:, :2], start[:, :2], reach)) + margin


def surface_hops(toolpath, surface, clearance: float, margin: float = DEFAULT_MARGIN,
                 stock: StockMap | RaisedModel | None = None) -> Hops:
    """:func:`hop_heights` of a toolpath on a core Surface (a net), its model bound from the
    net's drop-cutter (:class:`.dropcutter.DropCutter`, whose heights are those of real
    surface points polished from a dense sample of seeds)."""
    def drop(xy: FloatArray, r: float) -> FloatArray:
        return DropCutter(surface, r).heights(xy)[0]

    radius = 0.5 * float(toolpath.parameters["tool_diameter"])
    return hop_heights(toolpath.passes, toolpath.links, drop, radius, clearance, margin,
                       0.0, stock)


def faces_hops(toolpath, faceset, clearance: float, margin: float = DEFAULT_MARGIN,
               stock: StockMap | RaisedModel | None = None) -> Hops:
    """:func:`hop_heights` of a toolpath on faces, its model bound from the certified
    drop-cutter over every face of ``faceset`` (selected and check faces), plus its
    certificate's tolerance."""
    def drop(xy: FloatArray, r: float) -> FloatArray:
        return faceset.drop_ball(xy, r)[0]

    radius = 0.5 * float(toolpath.parameters["tool_diameter"])
    return hop_heights(toolpath.passes, toolpath.links, drop, radius, clearance, margin,
                       CERTIFY, stock)


__all__ = ["ALLOWANCE_RANGE", "DEFAULT_MARGIN", "Hops", "MARGIN_RANGE", "RaisedModel",
           "StockMap", "faces_hops", "hop_heights", "model_bound", "surface_hops"]
