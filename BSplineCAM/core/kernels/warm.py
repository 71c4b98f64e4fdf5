# SPDX-License-Identifier: LGPL-2.1-or-later
"""Compile the kernels before the first real job: a small drop-cutter over two faces (a
rational quarter cylinder trimmed by a hole and a bicubic bump), one beside a wall and one on a
net, the
scattered NURBS evaluation with derivatives, short Z-map simulations (one tool, and a job with two), the roughing of a small pocketed
plate, the constant-scallop strategy's grid fields and the arc fitting of a sine, all run through
the public paths
so that every kernel they reach is compiled (or loaded from the cache folder) with the
argument types real jobs pass.

``warm_up(progress)`` calls ``progress(fraction)`` between its steps: the GUI shows a bar (and
its Cancel raises between steps) while a first start compiles; with the cache filled it takes
a fraction of a second.  Under the numpy engine it does nothing.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..geometry.faces import Face
from ..geometry.nurbs import NurbsSurface
from ..geometry.surface import Surface
from ..program.gcode import read_gcode
from ..program.gcode_words import Segments
from ..simulation import simulate as sim
from ..simulation.job_simulation import simulate_job
from ..toolpath import scallop_field, scallop_metric
from ..toolpath.arcs import fit_polyline
from ..toolpath.dropcutter import DropCutter
from ..toolpath.faceset import FaceSet
from ..toolpath.roughing import Stock, generate_roughing
from . import engine, use_numba


def _faces():
    c = math.sqrt(0.5)
    arc = [(0.0, 10.0), (10.0, 10.0), (10.0, 0.0)]
    poles = np.array([[[x, y, z] for y in (0.0, 30.0)] for x, z in arc])
    weights = np.array([[1.0, 1.0], [c, c], [1.0, 1.0]])
    cylinder = NurbsSurface(poles, [0, 0, 0, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights=weights)
    t = np.linspace(0.0, 2.0 * np.pi, 65)
    hole = np.column_stack([0.5 + 0.2 * np.cos(t), 0.5 + 0.2 * np.sin(t)])
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
    g = np.linspace(0.0, 20.0, 5)
    xx, yy = np.meshgrid(g + 12.0, g, indexing="ij")
    zz = 2.0 * np.exp(-((xx - 22.0) ** 2 + (yy - 10.0) ** 2) / 40.0)
    knots = [0, 0, 0, 0, 0.5, 1, 1, 1, 1]
    bump = NurbsSurface(np.stack([xx, yy, zz], axis=-1), knots, knots, 3, 3)
    return [Face(cylinder, square, holes=(hole[::-1],), index=1),
            Face(bump, square, index=2)]


def _steps() -> list[tuple[str, Callable[[], None]]]:
    faces = _faces()

    def evaluate():
        for f in faces:
            u = np.linspace(0.0, 1.0, 7)
            f.surface.derivatives(u, u[::-1])
            f.surface.evaluate(u, u)

    def drop():
        fs = FaceSet(faces)
        x = np.linspace(-2.0, 30.0, 9)
        q = np.column_stack([x, np.full(len(x), 14.0)])
        fs.drop_ball(q, 3.0)
        fs.drop_ball(q[:2] + 0.5, 3.0)
        fs.drop_ball(np.array([[34.95, 10.0]]), 3.0)  # the rim grazes the bump: rim bound
        x, y = np.meshgrid(np.linspace(0.0, 30.0, 5), np.linspace(0.0, 28.0, 5), indexing="ij")
        DropCutter(Surface(np.stack([x, y, np.sin(x / 5.0)], axis=-1)), 3.0).heights_and_slopes(q)

    def walls():
        # a plate beside a vertical check face: the walls' drop
        plate = NurbsSurface(np.array([[[0.0, 0.0, 1.0], [0.0, 10.0, 1.0]],
                                       [[10.0, 0.0, 1.0], [10.0, 10.0, 1.0]]]),
                             [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
        wall = NurbsSurface(np.array([[[10.0, 0.0, 0.0], [10.0, 10.0, 0.0]],
                                      [[10.0, 0.0, 5.0], [10.0, 10.0, 5.0]]]),
                            [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
        square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0], [0.0, 0.0]])
        fs = FaceSet([Face(plate, square, index=1),
                      Face(wall, square, index=2, selected=False)])
        fs.drop_ball(np.array([[5.0, 5.0], [9.0, 5.0]]), 3.0)

    def simulate():
        grid = sim.Grid.covering(-5.0, 25.0, -5.0, 25.0, 0.5)
        pts = np.array([[0.0, 0.0, 5.0], [20.0, 0.0, 4.0], [20.0, 20.0, 3.0]])
        segs = Segments(pts[:-1], pts[1:], np.zeros(2, bool), np.arange(1, 3), np.arange(2))
        for shape, corner in (("ball", 0.0), ("flat", 0.0), ("bullnose", 1.0)):
            sim.simulate(segs, sim.Tool(6.0, shape, corner), grid, 6.0)
        # a job: an end mill's pass, a tool change, a ball's pass
        job = read_gcode("G21 G90\nT1 M6\nS8000 M3\nG0 X0 Y5 Z8\nG1 Z4 F600\n"
                         "G1 X20 F1200\nT2 M6\nS9000 M3\nG0 X0 Y12 Z8\nG1 Z4.5 F600\n"
                         "G1 X20 Y14 F1200\nG0 Z10\nM2\n")
        simulate_job(job, {1: sim.Tool(6.0, "flat"), 2: sim.Tool(6.0, "ball")}, grid,
                     (-5.0, 25.0, -5.0, 25.0, 0.0, 6.0))

    def rough():
        def plate(xs, ys):  # a plate with a round pocket, NaN off it
            X, Y = np.meshgrid(np.asarray(xs, float), np.asarray(ys, float))
            h = np.where((np.abs(X) <= 12.0) & (np.abs(Y) <= 12.0), 6.0, np.nan)
            h[np.hypot(X, Y) <= 7.0] = 2.0
            return h

        generate_roughing(plate, Stock(-14.0, 14.0, -14.0, 14.0, 0.0, 8.0),
                          sim.Tool(6.0, "flat"), 3.0, 2.4, 0.2, 0.2, cell=0.5)

    def scallop():
        xs, ys = np.linspace(0.0, 10.0, 21), np.linspace(0.0, 8.0, 17)
        t = np.linspace(0.0, 2.0 * np.pi, 33)
        ring = np.column_stack([5.0 + 3.0 * np.cos(t), 4.0 + 2.0 * np.sin(t)])
        near = scallop_field.NearField(xs, ys, 3)
        near.add([ring])
        free = near.out < 1.0
        axes = scallop_field.AXES
        cost = scallop_metric.band_costs(np.ones((len(axes),) + free.shape), axes, 0.5, 0.5)
        scallop_field.propagate(np.where(near.out < 0.3, 0.0, np.inf), cost, 0.5, 0.5, free)
        cover = np.ones((16,) + free.shape, np.float32)
        scallop_metric.directional_cost_on(cover, cover, scallop_field.axis_vectors(0.5, 0.5),
                                           free, near.vec[free])

    def arcs():  # a sine in G18: single arcs and biarcs
        x = np.linspace(0.0, 20.0, 81)
        fit_polyline(np.column_stack([x, np.zeros_like(x), np.sin(x / 2.0)]), 0.001, 18)

    return [("NURBS evaluation", evaluate), ("drop-cutter", drop), ("walls", walls),
            ("Z-map simulation", simulate), ("roughing", rough), ("constant scallop", scallop),
            ("arc fitting", arcs)]


def warm_up(progress: Callable[[float], None] | None = None) -> dict:
    """Compile (or load) the kernels; returns the engine's report (``Engine.to_dict``)."""
    if not use_numba():
        return engine().to_dict()
    steps = _steps()
    for k, (_name, step) in enumerate(steps):
        if progress is not None:
            progress(k / len(steps))
        step()
    if progress is not None:
        progress(1.0)
    return engine().to_dict()


__all__ = ["warm_up"]
