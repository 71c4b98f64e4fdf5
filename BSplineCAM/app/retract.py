# SPDX-License-Identifier: LGPL-2.1-or-later
"""The finishing op's retracts: how high the tool climbs between passes no stay-down feed
joins (:mod:`BSplineCAM.core.toolpath.retracts`).

``Retract`` "minimum" (the default of a new op) climbs only as high as the model under the
ball and the stock left by the job's earlier ops need, plus ``RetractMargin``: the stock is
the job's stock block cut by every active op before this one, simulated from their Path
commands (:func:`.stock_left.stock_after_ops`, the simulation Verify runs), or the whole
block when no earlier op cuts.  A job without a stock, or "full", climbs to the clearance
height as CAM's own ops do.

``StartStock`` "model" declares the stock instead: the model raised by ``StockAllowance``
(a part roughed by another program, or a near-net casting), whatever the job's stock block and
earlier ops (:class:`~BSplineCAM.core.toolpath.retracts.RaisedModel`).  A finishing op alone in
a job would otherwise take the raw block as its stock and feed every entry down from the
block's top.
"""

from __future__ import annotations

import numpy as np

from ..core.simulation.stock import CylinderStock
from ..core.toolpath import retracts
from ..core.validation import check_range
from .stock_left import job_stock, stock_after_ops

RETRACTS = ["minimum", "full"]
START_STOCKS = ["job", "model"]
DEFAULT_ALLOWANCE = 1.0

#: (type, name, group, tooltip, flags, default) of the retract's properties.
PROPERTIES = (
    ("App::PropertyEnumeration", "Retract", "Surface",
     "Between passes no stay-down feed joins: minimum climbs only as high as the model and "
     "the stock the earlier ops left need (plus RetractMargin); full climbs to the clearance "
     "height", 0, RETRACTS),
    ("App::PropertyLength", "RetractMargin", "Surface",
     "How far a minimum retract's rapids clear the model and the stock left", 0,
     retracts.DEFAULT_MARGIN),
    ("App::PropertyEnumeration", "StartStock", "Surface",
     "The stock a minimum retract clears: job (the job's stock block cut by the ops before "
     "this one) or model (the model raised by StockAllowance: a part roughed elsewhere or "
     "cast to within it)", 0, START_STOCKS),
    ("App::PropertyLength", "StockAllowance", "Surface",
     "With StartStock model: how far above the model the stock reaches, measured vertically",
     0, DEFAULT_ALLOWANCE),
)


def stock_cell(radius: float) -> float:
    """Z-map cell (mm) of the stock a minimum retract clears: a quarter of the ball's
    radius, within 0.25 to 1 mm (the hop takes the columns a cell's diagonal beyond the
    ball's reach, :mod:`BSplineCAM.core.toolpath.retracts`)."""
    return float(min(max(0.25 * radius, 0.25), 1.0))


def _block_map(stock) -> retracts.StockMap:
    """The whole stock as one column at its top: conservative over its box."""
    x0, x1, y0, y1, _z0, z1 = stock.bounds
    size = max(x1 - x0, y1 - y0)
    if isinstance(stock, CylinderStock):
        size = max(size, 2.0 * stock.radius)
    return retracts.StockMap(0.5 * (x0 + x1) - 0.5 * size, 0.5 * (y0 + y1) - 0.5 * size,
                             size, np.array([[z1]], dtype=float), whole_block=True)


def job_stock_map(job, op, radius: float, progress=None):
    """The stock the op starts from as a :class:`~BSplineCAM.core.toolpath.retracts.StockMap`
    (see the module docstring), or None when the job has no stock."""
    try:
        stock = job_stock(job)
    except ValueError:
        return None
    group = list(job.Operations.Group)
    earlier = group[:group.index(op)] if op in group else []
    sim = stock_after_ops(job, op, earlier, stock_cell(radius), progress) if earlier else None
    if sim is None:
        return _block_map(stock)
    g = sim.grid
    height = np.where(sim.in_stock, sim.height, -np.inf)
    return retracts.StockMap(g.x0, g.y0, g.cell, height)


def op_hops(obj, job, toolpaths: list, hops_of, progress=None) -> list:
    """Per toolpath of the op (None entries skipped), its
    :class:`~BSplineCAM.core.toolpath.retracts.Hops` (None: full retracts).
    ``hops_of(toolpath, clearance, margin, stock)`` is
    :func:`~BSplineCAM.core.toolpath.retracts.surface_hops` or ``faces_hops`` bound to the
    op's model; the stock map is computed once for all of them."""
    none = [None] * len(toolpaths)
    if getattr(obj, "Retract", "full") != "minimum" or job is None:
        return none
    margin = check_range(obj.RetractMargin.Value, f"{obj.Label}: RetractMargin", "mm",
                         *retracts.MARGIN_RANGE)
    first = next((t for t in toolpaths if t is not None and t.passes), None)
    if first is None:
        return none
    if getattr(obj, "StartStock", "job") == "model":
        stock = retracts.RaisedModel(check_range(
            obj.StockAllowance.Value, f"{obj.Label}: StockAllowance", "mm",
            *retracts.ALLOWANCE_RANGE))
    else:
        stock = job_stock_map(job, obj, 0.5 * float(first.parameters["tool_diameter"]),
                              progress)
    if stock is None:
        return none
    clearance = float(obj.ClearanceHeight.Value)
    return [None if t is None or not t.passes else hops_of(t, clearance, margin, stock)
            for t in toolpaths]


def hops_report(hops: list) -> dict:
    """``retract_hops``: how many gaps between passes hop instead of climbing to the
    clearance height."""
    return {"retract_hops": sum(int(np.isfinite(h.travel).sum()) for h in hops
                                if h is not None)}
