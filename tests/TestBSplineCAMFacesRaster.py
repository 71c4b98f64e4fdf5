# SPDX-License-Identifier: LGPL-2.1-or-later
"""Raster finishing of trimmed and several faces (core/toolpath/faces_raster.py), measured by
simulating the G-code text against the exact faces."""

from __future__ import annotations

import time

import numpy as np
from TestBSplineCAMFaceSet import gcode, two_faces

from BSplineCAM.core.gcode import read_gcode
from BSplineCAM.core.simulate import Grid, Tool, simulate_program
from BSplineCAM.core.toolpath.faces_raster import generate_faces_raster
from BSplineCAM.core.toolpath.faceset import FaceSet


def test_raster_of_trimmed_face_simulated():
    faces = two_faces()
    fs = FaceSet(faces)
    D, h, tol = 6.0, 0.05, 0.01
    t0 = time.perf_counter()
    tp = generate_faces_raster(fs, D, h, tol)
    print("raster", time.perf_counter() - t0, tp.extra["chord_lift"], tp.extra["dropcutter"])
    assert tp.passes
    # passes only where the contact lies on the selected face
    verts = np.concatenate(tp.passes)
    _t, _f, _u, _v, on_sel = fs.drop_ball(verts[:, :2], D / 2)
    assert on_sel.mean() > 0.99
    program = read_gcode(gcode(tp))
    grid = Grid.covering(0.0, 32.0, 0.0, 24.0, 0.2)
    sim = simulate_program(program, Tool(D), grid, top=5.0)
    xs, ys = grid.centres()
    X, Y = np.meshgrid(xs, ys)
    z, fidx, _u, _v, found = fs.height(np.column_stack([X.ravel(), Y.ravel()]), False)
    design = z.reshape(X.shape)
    found = found.reshape(X.shape)
    assert found.mean() > 0.9
    gouge = np.where(found, design - sim.height, -np.inf)
    assert gouge.max() <= 1e-3, gouge.max()
    # scallop on the selected face away from its borders (one tool radius)
    R = D / 2
    far = ((X > R) & (X < 24 - R) & (Y > R) & (Y < 24 - R)
           & (np.hypot(X - 12, Y - 12) > 0.12 * 24 + R))
    far &= found & (fidx.reshape(X.shape) == 0)
    assert far.sum() > 500
    scallop = (sim.height - design)[far]
    assert scallop.max() <= h + tol + 1e-3, scallop.max()
