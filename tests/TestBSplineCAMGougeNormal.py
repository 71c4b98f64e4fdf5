# SPDX-License-Identifier: LGPL-2.1-or-later
"""Gouge along the design's normal (:mod:`BSplineCAM.core.simulation.gouge_normal`) against
closed forms, on faces made here as exact NURBS: a box (six planes), a half cylinder (a
rational quadratic arc swept along y) and a plate with a round hole (its trim a polygon with
a vertex where the ball comes nearest).

* distances: the box's signed distance field and |r - Rc| for the cylinder, at random points;
* a ball beside the box's wall at R - d intrudes d (the Z-map shows the wall's height); at
  R + d it intrudes nothing, while a Z-map cell whose centre lies within the faces' seam
  tolerance outside the wall shows the wall's height;
* a pass over the cylinder lowered by a known depth along the normal measures that depth;
* a ball dipping into the hole grazes its rim: intrusion R - distance to the rim circle;
* a ball clear of a post under an overhanging lip: its shank runs through the lip;
* the gate (:func:`gouge_gate_mm`): a pass lowered 0.05 mm into the top or a wall fails it,
  cells beyond the cap and cells swept by a flat end mill keep their vertical gouge.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from BSplineCAM.core.geometry.face_distance import FaceDistance, golden_min
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.faces_height import FacesHeight
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.program.gcode import linearise, read_gcode
from BSplineCAM.core.simulation import gouge_normal as gn
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate
from BSplineCAM.core.simulation.verify import verify_faces, verify_job

SQUARE = np.array([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0)], float)
R = 3.0
BOX = (0.0, 20.0, 0.0, 20.0, 0.0, 10.0)


def plane(origin, eu, ev, index: int, holes=(), selected: bool = True, outer=SQUARE) -> Face:
    """A planar face over the parallelogram origin + [0, 1] eu + [0, 1] ev, trimmed by
    ``outer`` and ``holes`` in (u, v); its normal eu x ev is the outward one."""
    o, eu, ev = (np.asarray(a, float) for a in (origin, eu, ev))
    poles = np.array([[o, o + ev], [o + eu, o + eu + ev]])
    surface = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1)
    return Face(surface, outer, holes=tuple(holes), index=index, selected=selected)


def box(x0, x1, y0, y1, z0, z1) -> list[Face]:
    """Six planar faces; the top's surface reaches 5 mm beyond its trim all round (as a
    CAD system's trimmed plane does)."""
    lx, ly, lz = x1 - x0, y1 - y0, z1 - z0
    a, b = 5.0 / (lx + 10.0), 5.0 / (ly + 10.0)
    trim = np.array([(a, b), (1 - a, b), (1 - a, 1 - b), (a, 1 - b), (a, b)])
    return [plane((x0 - 5, y0 - 5, z1), (lx + 10, 0, 0), (0, ly + 10, 0), 1, outer=trim),
            plane((x0, y0, z0), (0, ly, 0), (lx, 0, 0), 2, selected=False),
            plane((x1, y0, z0), (0, ly, 0), (0, 0, lz), 3, selected=False),
            plane((x0, y0, z0), (0, 0, lz), (0, ly, 0), 4, selected=False),
            plane((x0, y0, z0), (lx, 0, 0), (0, 0, lz), 5, selected=False),
            plane((x0, y1, z0), (0, 0, lz), (lx, 0, 0), 6, selected=False)]


def half_cylinder(radius: float, length: float) -> Face:
    """z = sqrt(radius^2 - x^2), y in [0, length]: two rational quadratic quarter arcs (The
    NURBS Book, section 7.5) along u from x = -radius to +radius, a line along v."""
    w = math.sqrt(0.5)
    arc = np.array([(-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0)], float) * radius
    poles = np.array([[(x, y, z) for y in (0.0, length)] for x, z in arc])
    weights = np.array([[a, a] for a in (1, w, 1, w, 1)])
    surface = NurbsSurface(poles, [0, 0, 0, 0.5, 0.5, 1, 1, 1], [0, 0, 1, 1], 2, 1, weights)
    return Face(surface, SQUARE, index=1)


def program(*passes: list[str]) -> str:
    lines = ["%", "G21 G90", "T1 M6", "G0 Z40"]
    for p in passes:
        lines += p
    return "\n".join([*lines, "M2", "%"]) + "\n"


def along_y(x: float, z: float, y0: float, y1: float) -> list[str]:
    return [f"G0 X{x:.6f} Y{y0:.6f}", f"G1 Z{z:.6f} F500", f"G1 Y{y1:.6f}", "G0 Z40"]


def box_sdf(p: np.ndarray) -> np.ndarray:
    lo = np.array(BOX[0::2])
    hi = np.array(BOX[1::2])
    gap = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    outside = np.linalg.norm(gap, axis=1)
    depth = np.minimum(p - lo, hi - p).min(axis=1)
    return np.where(outside > 0, outside, -depth)


# -- distances -----------------------------------------------------------------------------------
def test_signed_distance_to_box_closed_form():
    rng = np.random.default_rng(3)
    p = rng.uniform([-4, -4, -4], [24, 24, 14], (400, 3))
    near = FaceDistance(box(*BOX)).signed(p, 40.0)
    np.testing.assert_allclose(near.distance, box_sdf(p), atol=1e-9)


def test_signed_distance_to_cylinder_closed_form():
    rng = np.random.default_rng(5)
    angle = rng.uniform(0.05, math.pi - 0.05, 200)  # within the face's arc
    r = rng.uniform(6.0, 14.0, 200)
    p = np.stack([r * np.cos(angle), rng.uniform(1.0, 19.0, 200), r * np.sin(angle)], axis=1)
    near = FaceDistance([half_cylinder(10.0, 20.0)]).signed(p, 10.0)
    np.testing.assert_allclose(near.distance, r - 10.0, atol=1e-9)
    assert not near.edge.any()


def test_golden_min_closed_form():
    t = golden_min(lambda x: (x - 0.3) ** 2, np.zeros(3), np.array([1.0, 0.5, 2.0]))
    np.testing.assert_allclose(t, 0.3, atol=1e-6)


# -- verify_faces on the box ---------------------------------------------------------------------
@pytest.mark.parametrize("d", [0.2, 0.05])
def test_ball_into_wall_measures_the_intrusion(d):
    """Tip 2 mm above the floor, the ball's side d into the wall x = 20: the Z-map's cells
    inside the wall within d of it lose the wall's height above the ball; along the normal
    the intrusion is d (the wall is a plane: exact to round-off)."""
    faces = box(*BOX)
    text = program(along_y(20.0 + R - d, 2.0, -10.0, 30.0))
    m = verify_faces(faces, read_gcode(text), Tool(2 * R), cell=0.1).metrics
    assert m["gouge_normal_measured"]
    if d < 0.1:  # no cell centre within 0.05 mm of the wall: the Z-map sees nothing
        assert m["gouge_cells"] == 0 and m["gouge_normal_cells_checked"] == 0
        return
    assert m["gouge_max_mm"] > 5.0
    assert m["gouge_normal_max_mm"] == pytest.approx(d, abs=1e-9)
    at = m["gouge_normal_at"]
    assert at["face"] == "Face3" and not at["on_trim_edge"]
    assert at["ball_mm"] == pytest.approx(d, abs=1e-9)
    assert at["shank_mm"] == pytest.approx(d, abs=1e-6)  # the shank beside the same wall
    assert gn.gouge_gate_mm(m) >= d - 1e-9


def seam_grid(offset: float) -> Grid:
    """A 0.1 mm grid with a column of cell centres ``offset`` mm beyond the wall x = 20."""
    cell = 0.1
    return Grid(20.0 + offset - 0.05 - 100 * cell, 5.0, cell, 150, 100)


@pytest.mark.parametrize("clearance", [5e-4, -0.02])
def test_wall_top_cell_beyond_the_wall(clearance):
    """A cell centre 1.5 um beyond the wall x = 20 lies within the faces' seam tolerance
    (2 um) and takes the top's height; the ball passing low beside the wall at R +
    ``clearance`` from it reaches that column: the Z-map reads the wall's height as gouge.
    Along the normal the ball clears the wall by ``clearance`` (no gouge), or, negative,
    intrudes by it."""
    faces = box(*BOX)
    grid = seam_grid(1.5e-3)
    xs, ys = grid.centres()
    hm = FacesHeight(faces, grid.cell).grid(xs, ys)
    col = int(np.argmin(np.abs(xs - 20.0015)))
    assert np.all(hm.z[:, col] == 10.0)  # the seam rule puts the centre on the top
    segments = linearise(read_gcode(program(along_y(20.0 + R + clearance, 2.0, 0.0, 20.0))),
                         0.01)
    tool = Tool(2 * R)
    machined = simulate(segments, tool, grid, 11.0).height
    assert (hm.z - machined)[:, col].max() > 5.0  # the vertical "gouge"
    result = gn.measure(faces, segments, [tool], grid, hm.z, machined, hm.found)
    metrics = {"gouge_normal_measured": True, **result.metrics()}
    assert result.flagged > 0 and result.cells and not result.unmeasured
    depth = max(c.depth for c in result.cells)
    assert depth == pytest.approx(-clearance, abs=1e-9)
    assert gn.gouge_gate_mm(metrics) == pytest.approx(max(0.0, -clearance), abs=1e-9)


# -- a cylinder and a plate with a hole ----------------------------------------------------------
@pytest.mark.parametrize("angle_deg, depth", [(90.0, 0.03), (60.0, 0.03), (40.0, 0.01)])
def test_pass_lowered_along_the_cylinders_normal(angle_deg, depth):
    """A pass along the half cylinder's axis with the ball's centre at Rc + R - depth from
    the axis, at ``angle_deg`` from the horizontal: intrusion = depth; the Z-map reads at
    least that much."""
    rc, a = 10.0, math.radians(angle_deg)
    rho = rc + R - depth
    x, zc = round(rho * math.cos(a), 6), round(rho * math.sin(a), 6)  # as the program says
    text = program(along_y(x, zc - R, 2.0, 18.0))
    m = verify_faces([half_cylinder(rc, 20.0)], read_gcode(text), Tool(2 * R), cell=0.05).metrics
    assert m["gouge_normal_max_mm"] == pytest.approx(rc + R - math.hypot(x, zc), abs=1e-9)
    assert m["gouge_normal_max_mm"] == pytest.approx(depth, abs=1e-6)
    assert m["gouge_max_mm"] >= 0.9 * depth  # at cell centres, off the deepest line
    assert m["gouge_normal_at"]["face"] == "Face1"


def test_ball_grazing_a_holes_rim():
    """A plate z = 0 with a hole of radius 4 (a 360-gon with a vertex at (0, 4)); a ball of
    R = 3.5 moving along y over the hole's centre from y = -1 to 1 with its centre at
    height zc: its nearest rim point is (0, +-4, 0), at sqrt(3^2 + zc^2) from the end
    points: intrusion R - that, to the polygon's sagitta (1.5e-4 mm: its chords pass nearer
    than the circle).  The vertical depth over the cells beside the rim is larger."""
    r_ball, hole, d = 3.5, 4.0, 0.1
    zc = math.sqrt((r_ball - d) ** 2 - 9.0)
    k = np.arange(361) * 2 * math.pi / 360 + math.pi / 2
    loop = np.stack([0.5 + hole / 20.0 * np.cos(k), 0.5 + hole / 20.0 * np.sin(k)], axis=1)
    loop[-1] = loop[0]
    plate = plane((-10, -10, 0), (20, 0, 0), (0, 20, 0), 1, holes=[loop])
    text = program(along_y(0.0, zc - r_ball, -1.0, 1.0))
    m = verify_faces([plate], read_gcode(text), Tool(2 * r_ball), cell=0.02).metrics
    sagitta = hole * (1.0 - math.cos(math.radians(0.5)))
    assert d - 1e-9 <= m["gouge_normal_max_mm"] <= d + sagitta
    assert m["gouge_normal_at"]["on_trim_edge"]
    assert m["gouge_max_mm"] > 1.5 * d


# -- the gate ------------------------------------------------------------------------------------
def test_gate_fails_a_pass_lowered_into_the_top():
    """A raster over the box's top, one pass 0.05 mm low: along the normal 0.05 mm."""
    passes = [along_y(x, 10.0, -5.0, 25.0) for x in np.arange(-2.0, 22.01, 1.0)]
    passes.append(along_y(10.3, 9.95, -5.0, 25.0))
    m = verify_faces(box(*BOX), read_gcode(program(*passes)), Tool(2 * R), cell=0.1).metrics
    assert m["gouge_normal_max_mm"] == pytest.approx(0.05, abs=1e-9)
    assert gn.gouge_gate_mm(m) > 1e-3


def test_gate_keeps_the_vertical_gouge_of_unmeasured_cells():
    """Beyond the cap, and under a flat end mill, a cell keeps its vertical gouge."""
    faces = box(*BOX)
    text = program(along_y(20.0 + R - 0.2, 2.0, -10.0, 30.0))
    segments = linearise(read_gcode(text), 0.01)
    grid = seam_grid(-0.05)
    xs, ys = grid.centres()
    hm = FacesHeight(faces, grid.cell).grid(xs, ys)
    for tool, cap, why in ((Tool(2 * R), 3, "beyond the cap"),
                           (Tool(2 * R, "flat"), 50, "swept by a flat or bull-nose tool")):
        machined = simulate(segments, tool, grid, 11.0).height
        result = gn.measure(faces, segments, [tool], grid, hm.z, machined, hm.found,
                            max_cells=cap)
        metrics = {"gouge_normal_measured": True, **result.metrics()}
        assert why in metrics["gouge_normal_unmeasured_cells"]
        vertical = float(np.nanmax(np.where(hm.found, hm.z - machined, np.nan)))
        assert vertical > 5.0
        assert gn.gouge_gate_mm(metrics) == pytest.approx(vertical, abs=1e-6)
    assert gn.gouge_gate_mm({"gouge_normal_measured": False, "gouge_max_mm": 0.5}) == 0.5


@pytest.mark.parametrize("wall", [False, True])
def test_job_gate_fails_a_finishing_pass_into_a_face(wall):
    """A whole program (verify_job): T1, a 10 mm flat end mill, clears above the box; T2,
    the ball, makes one pass 0.05 mm into the top (or into the wall x = 20): the gate reads
    0.05 mm, measured along the normal on the ball's cells."""
    pass_ = (along_y(20.0 + R - 0.05, 2.0, -10.0, 30.0) if wall
             else along_y(10.3, 9.95, -5.0, 25.0))
    text = "\n".join(["%", "G21 G90", "T1 M6", "G0 Z40", *along_y(10.0, 12.0, -8.0, 28.0),
                      "T2 M6", *pass_, "M2", "%"]) + "\n"
    tools = {1: Tool(10.0, "flat"), 2: Tool(2 * R)}
    result = verify_job(box(*BOX), read_gcode(text), tools, stock=(-8, 28, -8, 28, 0, 12),
                        cell=0.02)
    m = result.metrics
    assert m["gouge_normal_measured"] and m["gouge_normal_cells_checked"] > 0
    assert m["gouge_normal_max_mm"] == pytest.approx(0.05, abs=1e-9)
    assert gn.gouge_gate_mm(m) > 1e-3


def test_shank_under_an_overhang():
    """A post 8 mm tall and, 2 mm above it, a lip reaching 6 mm beyond its side x = 20; the
    ball passes beside the post 0.5 mm clear of it, under the lip: the Z-map reads the lip's
    height over the ball; the ball clears every face, its shank (axis at x = 23.5) runs
    through the lip: intrusion R (unsigned, from the lip's underside above the centre)."""
    post = box(0.0, 20.0, 0.0, 20.0, 0.0, 8.0)
    lip = [replace(f, index=f.index + 6) for f in box(0.0, 26.0, 0.0, 20.0, 10.0, 12.0)]
    text = program(along_y(20.0 + R + 0.5, 2.0, -10.0, 30.0))
    m = verify_faces(post + lip, read_gcode(text), Tool(2 * R), cell=0.1).metrics
    at = m["gouge_normal_at"]
    assert m["gouge_max_mm"] > 5.0
    assert at["ball_mm"] == pytest.approx(-0.5, abs=1e-9)
    assert at["part"] == "shank" and at["shank_mm"] == pytest.approx(R, abs=1e-9)
    # 11000 cells under the lip: those beyond the cap count at their vertical depth
    assert m["gouge_normal_unmeasured_cells"]["beyond the cap"] > 0
    assert gn.gouge_gate_mm(m) == pytest.approx(m["gouge_normal_unmeasured_max_mm"], abs=1e-12)
    assert gn.gouge_gate_mm(m) >= R
