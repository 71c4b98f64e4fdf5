# SPDX-License-Identifier: LGPL-2.1-or-later
"""The stock an op starts from: the job's stock block cut by earlier ops (issue 12).

The earlier ops' Path commands, each after a tool change to its controller's number, are
read as one program (:func:`BSplineCAM.core.gcode.read_gcode`) and simulated from the job's
stock box with each controller's tool (:func:`BSplineCAM.core.job_simulation.simulate_job`),
the same simulation ``verify`` runs on the posted program.
"""

from __future__ import annotations

from . import compat

FreeCAD = compat.ensure_freecad()


def cutting_ops(ops) -> list:
    """Those of ``ops`` that are active and have a path and a tool controller."""
    return [o for o in ops if getattr(o, "Active", True)
            and getattr(o, "ToolController", None) is not None
            and getattr(o, "Path", None) is not None and o.Path.Commands]


def core_tool(tc):
    """The core Tool of a tool controller's bit (flat, bull-nose or ball)."""
    from ..core.simulate import Tool

    shape, diameter, corner = compat.core_tool_shape(tc.Tool)
    return Tool(diameter, shape, corner if shape == "bullnose" else 0.0)


def program_of(ops, source: str):
    """(core Program, {tool number: Tool}) of ``ops`` in order, each after its tool change."""
    from ..core.gcode import read_gcode

    tools = {}
    parts = []
    for other in ops:
        number = int(other.ToolController.ToolNumber)
        tools[number] = core_tool(other.ToolController)
        parts.append(f"T{number} M6\n{other.Path.toGCode()}\n")
    parts.append("M2\n")
    return read_gcode("".join(parts), source), tools


def stock_box(job) -> tuple[float, float, float, float, float, float]:
    """The job's stock as (x0, x1, y0, y1, z0, z1) mm (its shape's box)."""
    stock = getattr(job, "Stock", None)
    if stock is None or stock.Shape.isNull():
        raise ValueError(f"{job.Label}: the job has no stock")
    b = stock.Shape.BoundBox
    return (b.XMin, b.XMax, b.YMin, b.YMax, b.ZMin, b.ZMax)


def stock_after_ops(job, op, ops, cell: float, progress=None):
    """The job's stock block cut by ``ops`` (in the job's order) on cells of ``cell`` mm, as
    a core JobSimulation; None when none of them cuts."""
    from ..core.job_simulation import simulate_job
    from ..core.simulate import Grid

    order = {o.Name: k for k, o in enumerate(job.Operations.Group)}
    ops = sorted(cutting_ops(ops), key=lambda o: order.get(o.Name, -1))
    if not ops:
        return None
    program, tools = program_of(ops, f"{job.Label}: ops before {op.Label}")
    box = stock_box(job)
    grid = Grid.covering(box[0], box[1], box[2], box[3], cell)
    return simulate_job(program, tools, grid, box, progress=progress)
