# SPDX-License-Identifier: LGPL-2.1-or-later
"""Raster passes at a wall's foot (core/toolpath/raster_walls.py).

The end-to-end case machines a floor and a top 10 mm higher joined by a vertical wall along
the passes, and simulates the program from its G-code text against the exact faces: without
the pieces at the wall's foot the last floor pass stands about a stepover from the foot and
the strip between keeps more than twice the scallop."""

from __future__ import annotations

import numpy as np
import pytest
from bsplinecam_helpers import assert_above_drop, gcode, plane, rectangle

from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify_faces
from BSplineCAM.core.toolpath import raster_walls
from BSplineCAM.core.toolpath.faces_raster import generate_faces_raster
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.raster_partial import Piece
from BSplineCAM.core.toolpath.raster_walls import insert_runs, wall_pieces

D, H, TOL = 6.0, 0.05, 0.01
R = D / 2
#: The wall's y (mm): the last floor line lies about a stepover (1.06 mm) from the foot.
WALL_Y = 10.6


def wall_faces(y: float = WALL_Y) -> list[Face]:
    """A 30 mm floor (z = 0, y < ``y``), a top 10 mm up (y > ``y``) and the vertical wall
    between them (a check face), all along X."""
    floor = plane(0.0, 30.0, 0.0, y, 0.0)
    top = plane(0.0, 30.0, y, 20.0, 10.0)
    wall = NurbsSurface(np.array([[[0, y, 0], [0, y, 10]], [[30, y, 0], [30, y, 10]]], float),
                        [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return [Face(floor, rectangle(floor), index=1), Face(top, rectangle(top), index=2),
            Face(wall, rectangle(wall), index=3, selected=False)]


def machined(faces):
    fs = FaceSet(faces)
    tp = generate_faces_raster(fs, D, H, TOL)
    metrics = verify_faces(faces, read_gcode(gcode(tp)), Tool(D), cell=0.1).metrics
    return fs, tp, metrics


@pytest.mark.venv_only
def test_a_wall_along_the_passes_keeps_the_scallop(monkeypatch):
    faces = wall_faces()
    fs, tp, metrics = machined(faces)
    assert metrics["scallop_max_mm"] <= H + TOL
    assert metrics["gouge_max_mm"] <= 1e-3
    assert metrics["coverage"] == 1.0
    assert_above_drop(fs, tp)
    # the piece runs halfway between the last floor line and the one the wall holds up, on
    # the floor, over the whole length
    offsets = np.array(tp.extra["line_offsets_mm"])
    foot = WALL_Y - R
    below, above = offsets[offsets < foot].max(), offsets[offsets > foot].min()
    mid = [p for p in tp.passes if np.allclose(p[:, 1], 0.5 * (below + above))]
    assert mid and all(np.allclose(p[:, 2], 0.0, atol=1e-6) for p in mid)
    assert sum(float(np.ptp(p[:, 0])) for p in mid) > 25.0
    # without it the strip at the foot keeps more than twice the scallop
    monkeypatch.setattr(raster_walls, "WALL_RISE", np.inf)
    _, bare, without = machined(faces)
    assert without["scallop_max_mm"] > 2 * H
    assert len(bare.passes) < len(tp.passes)


def lines(b_values, a: np.ndarray, heights, slopes=None):
    """Samples of main lines at across-offsets ``b_values`` over along-coordinates ``a``:
    (pieces, line, a, z, cut, slope) as :func:`wall_pieces` takes them."""
    pieces = [Piece(b, float(a[0]), float(a[-1]), k, 0) for k, b in enumerate(b_values)]
    n = len(a)
    line = np.repeat(np.arange(len(pieces)), n)
    z = np.concatenate(heights)
    slope = np.zeros(len(z)) if slopes is None else np.concatenate(slopes)
    return pieces, line, np.tile(a, len(pieces)), z, np.isfinite(z), slope


def test_a_step_gets_a_piece_over_its_stretch_and_curvature_none():
    a = np.linspace(0.0, 30.0, 61)
    step = np.where((a >= 10.0) & (a <= 20.0), 2.0, 0.0)  # held up 2 mm over [10, 20]
    pieces, line, aa, z, cut, slope = lines([0.0, 1.0], a, [np.zeros_like(a), step])
    out, refs, feet = wall_pieces(pieces, line, aa, z, cut, slope, R)
    assert len(out) == 1 and refs == [0] and feet == [0.0]
    p = out[0]
    assert p.b == 0.5 and p.depth == 1 and p.band == 0
    assert p.a0 == pytest.approx(10.0 - R) and p.a1 == pytest.approx(20.0 + R)
    # a concave cylinder of radius R across the lines (1 mm apart): the neighbour rises by
    # its curvature, (s^2 / 2R), well under WALL_RISE radii
    y = np.array([0.0, 1.0])
    zc = R - np.sqrt(R * R - y * y)
    dz = y / np.sqrt(R * R - y * y)
    pieces, line, aa, z, cut, slope = lines(
        y, a, [np.full_like(a, zc[0]), np.full_like(a, zc[1])],
        [np.full_like(a, dz[0]), np.full_like(a, dz[1])])
    assert wall_pieces(pieces, line, aa, z, cut, slope, R)[0] == []
    # a step across a short stretch (a wall crossing the lines) gets none either
    short = np.where((a >= 10.0) & (a <= 10.5), 2.0, 0.0)
    pieces, line, aa, z, cut, slope = lines([0.0, 1.0], a, [np.zeros_like(a), short])
    assert wall_pieces(pieces, line, aa, z, cut, slope, R)[0] == []


@pytest.mark.parametrize("forward", [True, False])
def test_a_wall_run_goes_in_beside_its_line(forward):
    along, across = np.array([1.0, 0.0]), np.array([0.0, 1.0])
    x = np.linspace(0.0, 30.0, 7)  # vertices every 5 mm
    main = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
    other = np.column_stack([x, np.full_like(x, 2.0), np.zeros_like(x)])
    run = np.array([[12.0, 0.5, 0.0], [18.0, 0.5, 0.0]])
    ordered = [main if forward else main[::-1], other]
    out = insert_runs(ordered, [(0.0, run)], along, across)
    assert len(out) == 4 and out[3] is other
    head, back, tail = out[:3]
    if forward:
        # on to the run's far end, the run back, the line again from the near end
        assert head[0, 0] == 0.0 and head[-1, 0] == pytest.approx(18.0)
        assert back[0, 0] == 18.0 and back[-1, 0] == 12.0
        assert tail[0, 0] == pytest.approx(12.0) and tail[-1, 0] == 30.0
    else:
        assert head[0, 0] == 30.0 and head[-1, 0] == pytest.approx(12.0)
        assert back[0, 0] == 12.0 and back[-1, 0] == 18.0
        assert tail[0, 0] == pytest.approx(18.0) and tail[-1, 0] == 0.0
    # the split points lie on the line's chords
    assert np.allclose(head[:, 1:], 0.0) and np.allclose(tail[:, 1:], 0.0)
    # a run whose line has no pass is cut last
    lone = insert_runs([other], [(0.0, run)], along, across)
    assert len(lone) == 2 and lone[1] is run
