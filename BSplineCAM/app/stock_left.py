# SPDX-License-Identifier: LGPL-2.1-or-later
"""The stock an op starts from: the job's stock cut by earlier ops (issue 12).

The job's stock is read as core data (:func:`job_stock`): CAM's cylinder stock
("CreateCylinder") with a vertical axis as a :class:`BSplineCAM.core.simulation.stock.CylinderStock`,
every other stock as the block of its shape's box.  The earlier ops' Path commands, each
after a tool change to its controller's number, are read as one program
(:func:`BSplineCAM.core.program.gcode.read_gcode`) and simulated from that stock with each
controller's tool (:func:`BSplineCAM.core.simulation.job_simulation.simulate_job`), the same simulation
``verify`` runs on the posted program.
"""

from __future__ import annotations

from ..core.program.gcode import read_gcode
from ..core.simulation.job_simulation import simulate_job
from ..core.simulation.simulate import Grid, Tool
from ..core.simulation.stock import CylinderStock, Stock
from . import compat

FreeCAD = compat.ensure_freecad()


def cutting_ops(ops) -> list:
    """Those of ``ops`` that are active and have a path and a tool controller."""
    return [o for o in ops if getattr(o, "Active", True)
            and getattr(o, "ToolController", None) is not None
            and getattr(o, "Path", None) is not None and o.Path.Commands]


def core_tool(tc):
    """The core Tool of a tool controller's bit (flat, bull-nose or ball)."""
    shape, diameter, corner = compat.core_tool_shape(tc.Tool)
    return Tool(diameter, shape, corner if shape == "bullnose" else 0.0)


def program_of(ops, source: str):
    """(core Program, {tool number: Tool}) of ``ops`` in order, each after its tool change."""
    tools = {}
    parts = []
    for other in ops:
        number = int(other.ToolController.ToolNumber)
        tools[number] = core_tool(other.ToolController)
        parts.append(f"T{number} M6\n{other.Path.toGCode()}\n")
    parts.append("M2\n")
    return read_gcode("".join(parts), source), tools


#: Largest sine (of the angle between a cylinder stock's axis and Z) for which the cylinder
#: counts as vertical; a tilted cylinder is taken as its box (the roughing cuts Z levels).
VERTICAL_AXIS_TOLERANCE = 1e-9


def job_stock(job):
    """The job's stock as a core :class:`~BSplineCAM.core.simulation.stock.CylinderStock` when it is
    CAM's cylinder stock with its axis along Z (centre and height from its shape, which
    carries the Placement, radius from its Radius property), else as the
    :class:`~BSplineCAM.core.simulation.stock.Stock` block of its shape's box (mm, job coordinates).
    ValueError naming the job when it has no stock."""
    stock = getattr(job, "Stock", None)
    if stock is None or stock.Shape.isNull():
        raise ValueError(f"{job.Label}: the job has no stock")
    b = stock.Shape.BoundBox
    if compat.cam_stock_type(stock) == "CreateCylinder" and hasattr(stock, "Radius"):
        axis = stock.Placement.Rotation.multVec(FreeCAD.Vector(0, 0, 1))
        if abs(axis.x) <= VERTICAL_AXIS_TOLERANCE and abs(axis.y) <= VERTICAL_AXIS_TOLERANCE:
            radius = float(getattr(stock.Radius, "Value", stock.Radius))
            return CylinderStock(0.5 * (b.XMin + b.XMax), 0.5 * (b.YMin + b.YMax), radius,
                                 b.ZMin, b.ZMax)
    return Stock(b.XMin, b.XMax, b.YMin, b.YMax, b.ZMin, b.ZMax)


def stock_after_ops(job, op, ops, cell: float, progress=None):
    """The job's stock (:func:`job_stock`, a block or a cylinder) cut by ``ops`` (in the job's
    order) on cells of ``cell`` mm, as a core JobSimulation; None when none of them cuts."""
    order = {o.Name: k for k, o in enumerate(job.Operations.Group)}
    ops = sorted(cutting_ops(ops), key=lambda o: order.get(o.Name, -1))
    if not ops:
        return None
    program, tools = program_of(ops, f"{job.Label}: ops before {op.Label}")
    stock = job_stock(job)
    grid = Grid.covering(stock.x_min, stock.x_max, stock.y_min, stock.y_max, cell)
    return simulate_job(program, tools, grid, stock, progress=progress)
