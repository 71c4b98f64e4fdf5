# SPDX-License-Identifier: LGPL-2.1-or-later
"""Verification against a part's exact faces (issue 11): ``verify PART PROGRAM --faces ...``.

The part is made here by cadquery: a 40 x 30 x 10 mm block, its two long top edges rounded by
3 mm fillets (cylinders, converted by OCCT to rational NURBS) and an 8 mm through hole.  Its
design heights have a closed form (plane z = 10, fillets z = 7 + sqrt(9 - (3 - y)^2)), and the
programs are written here by a plain generator: a ball raster over the top, a pass plunged into
the top and a pass through a fillet.  Scallops, gouges and coverage are compared with the
closed forms at the cell centres; the faces' heights with the closed form and with the point
probe ``FaceSet.height``.  The command line runs on the same part (FreeCAD), refusals included.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess

import numpy as np
import pytest
from conftest import ROOT

from BSplineCAM.core.geometry.faces import face_from_dict
from BSplineCAM.core.geometry.faces_height import FacesHeight
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify_faces

BIN = ROOT / "bin" / "bsplinecam"
VENV_PYTHON = ROOT / ".venv" / "bin" / "python"
REQUIRE_ALL = os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1"
L, W, H, F, HOLE = 40.0, 30.0, 10.0, 3.0, (28.0, 15.0, 4.0)
R = 3.0  # ball radius

MAKE = """
import json, sys
sys.path.insert(0, {root!r})
import cadquery as cq
from BSplineCAM.core.geometry.faces import to_dict
from BSplineCAM.ocp.faces import faces_from_shape, read_part
L, W, H, F, (hx, hy, hr) = {L}, {W}, {H}, {F}, {HOLE}
block = cq.Workplane().box(L, W, H, centered=False)
block = block.cut(cq.Workplane().add(cq.Solid.makeCylinder(hr, 3 * H, cq.Vector(hx, hy, -H))))
block = block.edges("|X and >Z").fillet(F)
cq.exporters.export(block, sys.argv[1])
faces = faces_from_shape(read_part(sys.argv[1]), "up")
json.dump([to_dict(f) for f in faces], open(sys.argv[2], "w"))
"""


def have_freecadcmd() -> bool:
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()[0]
    return shutil.which(cmd) is not None


needs_freecad = pytest.mark.skipif(not have_freecadcmd() and not REQUIRE_ALL,
                                   reason="freecadcmd is not installed")


@pytest.fixture(scope="module")
def part(tmp_path_factory):
    """(STEP path, faces, number of the top face)."""
    if not VENV_PYTHON.exists() and not REQUIRE_ALL:
        pytest.skip("the project venv (cadquery) is not installed")
    folder = tmp_path_factory.mktemp("part")
    step, dump = folder / "block.step", folder / "faces.json"
    code = MAKE.format(root=str(ROOT), L=L, W=W, H=H, F=F, HOLE=HOLE)
    proc = subprocess.run([str(VENV_PYTHON), "-c", code, str(step), str(dump)],
                          capture_output=True, text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    faces = [face_from_dict(doc) for doc in json.loads(dump.read_text())]
    tops = [f for f in faces if f.source == "Plane"
            and np.allclose(np.asarray(f.surface.poles)[..., 2], H)]
    assert len(tops) == 1
    return step, faces, tops[0].index


def design_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Closed form of the part's top: NaN off the part and in the hole."""
    z = np.full(np.broadcast(x, y).shape, H)
    lo, hi = y < F, y > W - F
    z = np.where(lo, H - F + np.sqrt(np.maximum(F * F - (F - y) ** 2, 0.0)), z)
    z = np.where(hi, H - F + np.sqrt(np.maximum(F * F - (y - (W - F)) ** 2, 0.0)), z)
    off = (x < 0) | (x > L) | (y < 0) | (y > W) | (np.hypot(x - HOLE[0], y - HOLE[1]) < HOLE[2])
    return np.where(off, np.nan, z)


def select(faces, numbers):
    from dataclasses import replace

    return [replace(f, selected=f.index in numbers) for f in faces]


def raster(ys, z: float, extra=()) -> str:
    """Ball raster along X at tip height z, one pass per y, from x = -6 to 46."""
    lines = ["%", "G17 G21 G90 G54", "T1 M6", "S10000 M3", "G0 Z30"]
    for i, y in enumerate(ys):
        a, b = (-6.0, 46.0) if i % 2 == 0 else (46.0, -6.0)
        lines += [f"G0 X{a} Y{y:.4f}", f"G1 Z{z:.4f} F600", f"G1 X{b} F1200", "G0 Z30"]
    return "\n".join([*lines, *extra, "M5", "M2", "%"]) + "\n"


def pass_at(y: float, z: float) -> list[str]:
    return [f"G0 X-6 Y{y:.4f}", f"G1 Z{z:.4f} F600", "G1 X46 F1200", "G0 Z30"]


# -- design heights -------------------------------------------------------------------------------
def test_heights_against_closed_form_and_point_probe(part):
    from BSplineCAM.core.toolpath.faceset import FaceSet

    _, faces, top = part
    cell = 0.1
    xs = np.arange(-1.05, L + 1.0, cell)
    ys = np.arange(-1.05, W + 1.0, cell)
    hm = FacesHeight(faces, cell).grid(xs, ys)
    expect = design_z(xs[None, :], ys[:, None])
    # cells within 1e-3 mm of an edge may go either way (trim polylines at 1e-3 mm)
    gx, gy = np.meshgrid(xs, ys)
    edge = ((np.abs(gx) < 2e-3) | (np.abs(gx - L) < 2e-3) | (np.abs(gy) < 2e-3)
            | (np.abs(gy - W) < 2e-3)
            | (np.abs(np.hypot(gx - HOLE[0], gy - HOLE[1]) - HOLE[2]) < 2e-3))
    sure = ~edge
    assert np.array_equal(hm.found[sure], np.isfinite(expect[sure]))
    ok = sure & np.isfinite(expect)
    np.testing.assert_allclose(hm.z[ok], expect[ok], atol=1e-6)
    on_top = ok & (gy > F + 1e-3) & (gy < W - F - 1e-3)
    assert np.all(hm.face[on_top] == top - 1)
    # the same points through the point probe (where it finds the top face)
    rng = np.random.default_rng(5)
    pick = rng.choice(np.flatnonzero(ok.ravel()), 3000, replace=False)
    z, face, _, _, found = FaceSet(faces).height(np.column_stack([gx.ravel()[pick],
                                                                   gy.ravel()[pick]]))
    agree = found & (face >= 0) & (face == hm.face.ravel()[pick])
    assert agree.mean() > 0.9
    np.testing.assert_allclose(z[agree], hm.z.ravel()[pick][agree], atol=1e-6)


# -- verification, core --------------------------------------------------------------------------
def test_raster_over_top_scallop_closed_form(part):
    """Top face selected: scallop at every measured cell is R - sqrt(R^2 - d^2), d the distance
    to the nearest pass; the raster at tip z = 10 stays above the fillets: no gouge."""
    _, faces, top = part
    step = 1.5
    ys = np.arange(-4.0, W + 4.0 + 1e-9, step)
    result = verify_faces(select(faces, {top}), read_gcode(raster(ys, H)), Tool(2 * R),
                          cell=0.1, coverage_tolerance=0.1)
    m = result.metrics
    assert m["faces"] == [top] and top not in m["check_faces"]
    assert m["gouge_max_mm"] < 1e-5 and m["gouge_cells"] == 0
    _, cy = result.simulation.grid.centres()
    d = np.abs(cy[:, None] - ys[None, :]).min(axis=1)
    expect = np.broadcast_to((R - np.sqrt(R * R - d * d))[:, None], result.inner.shape)
    inner = result.inner
    np.testing.assert_allclose(result.deviation[inner], expect[inner], atol=2e-5)
    assert m["scallop_max_mm"] == pytest.approx(expect[inner].max(), abs=2e-5)
    assert m["coverage"] == 1.0
    # measured cells: the top face at least one tool radius from its borders
    gx, gy = np.meshgrid(*result.simulation.grid.centres())
    assert np.all((gy[inner] > F + R - 0.15) & (gy[inner] < W - F - R + 0.15))
    assert np.all(np.hypot(gx[inner] - HOLE[0], gy[inner] - HOLE[1]) > HOLE[2] + R - 0.15)
    assert np.all((gx[inner] > R - 0.15) & (gx[inner] < L - R + 0.15))
    # and every cell that far inside is measured
    far = ((gy > F + R + 0.15) & (gy < W - F - R - 0.15) & (gx > R + 0.15) & (gx < L - R - 0.15)
           & (np.hypot(gx - HOLE[0], gy - HOLE[1]) > HOLE[2] + R + 0.15))
    assert np.all(inner[far])


def test_gouges_on_selected_and_check_faces(part):
    """A pass plunged 0.2 mm into the top gouges it by 0.2 mm; a pass beside the part at
    (y, z) = (-1, 6.5) cuts the fillet, a check face when only the top is selected, by
    max over cell centres of fillet - ball (closed forms); both count in gouge_max_mm."""
    _, faces, top = part
    ys = np.arange(-4.0, W + 4.0 + 1e-9, 1.5)
    program = raster(ys, H, extra=pass_at(15.05, H - 0.2) + pass_at(-1.0, 6.5))
    result = verify_faces(select(faces, {top}), read_gcode(program), Tool(2 * R), cell=0.1)
    m = result.metrics
    assert m["gouge_selected_max_mm"] == pytest.approx(0.2, abs=1e-5)
    _, cy = result.simulation.grid.centres()
    yy = cy[(cy > 0) & (cy < F)]
    fillet = H - F + np.sqrt(F * F - (F - yy) ** 2)
    ball = 6.5 + R - np.sqrt(np.maximum(R * R - (yy + 1.0) ** 2, 0.0))
    ball = np.where(np.abs(yy + 1.0) <= R, ball, np.inf)
    expect = float((fillet - ball).max())
    assert expect > 0.3
    assert m["gouge_check_max_mm"] == pytest.approx(expect, abs=1e-5)
    assert m["gouge_max_mm"] == pytest.approx(max(expect, 0.2), abs=1e-5)
    assert m["gouge_cells"] > 100


def test_all_faces_selected_measures_fillets(part):
    """Every face selected (--faces all): with a 1 mm ball the fillets lie partly more than its
    radius from the model's border and are measured too; a raster at constant z leaves them
    uncut, so coverage drops and the scallop grows to the fillet's drop at y = 0.5 + cell."""
    _, faces, top = part
    ys = np.arange(-4.0, W + 4.0 + 1e-9, 0.5)
    prog = read_gcode(raster(ys, H))
    only_top = verify_faces(select(faces, {top}), prog, Tool(1.0), cell=0.1).metrics
    every = verify_faces(select(faces, {f.index for f in faces}), prog, Tool(1.0),
                         cell=0.1).metrics
    assert only_top["coverage"] == 1.0 and every["coverage"] < 0.95
    drop = H - (H - F + math.sqrt(F * F - (F - 0.5) ** 2))  # 1.34 mm
    assert drop - 0.1 < every["scallop_max_mm"] <= drop + 1e-6
    assert only_top["scallop_max_mm"] < 0.07
    assert every["gouge_max_mm"] < 1e-5


# -- the command line ------------------------------------------------------------------------------
def run_bin(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN), *args], capture_output=True, text=True, timeout=900,
                          cwd=ROOT, check=False)


@pytest.mark.venv_only
@needs_freecad
def test_cli_verify_part(part, tmp_path):
    step, faces, top = part
    ngc = tmp_path / "top.ngc"
    ngc.write_text(raster(np.arange(-4.0, W + 4.0 + 1e-9, 1.5), H,
                          extra=pass_at(15.05, H - 0.2)))
    out = tmp_path / "out"
    proc = run_bin("verify", str(step), str(ngc), "--faces", str(top), "--tool-diameter", "6",
                   "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    summary = json.loads(proc.stdout)
    assert summary["faces"] == [top]
    assert summary["gouge_max_mm"] == pytest.approx(0.2, abs=1e-5)
    report = json.loads((out / "verify.json").read_text())
    assert report["part"] == str(step) and report["gouge_selected_max_mm"] == pytest.approx(
        0.2, abs=1e-5)
    assert (out / "deviation.png").is_file() and (out / "simulated.png").is_file()


@pytest.mark.venv_only
@needs_freecad
@pytest.mark.parametrize("faces, fragments", [
    ("20", ["block.step: face 20 of"]),
    ("x", ["--faces", "'x'"]),
    (",", ["--faces", "empty"]),
    ("WALL", ["not reachable from above"]),
])
def test_cli_verify_part_refused(part, tmp_path, faces, fragments):
    step, all_faces, _ = part
    if faces == "WALL":
        faces = str(next(f.index for f in all_faces if f.source == "Plane"
                         and np.ptp(np.asarray(f.surface.poles)[..., 2]) > 1.0))
    ngc = tmp_path / "p.ngc"
    ngc.write_text(raster([15.0], H))
    out = tmp_path / "out"
    proc = run_bin("verify", str(step), str(ngc), "--faces", faces, "--tool-diameter", "6",
                   "--out", str(out))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bsplinecam "), proc.stderr
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert proc.stdout == "" and not out.exists()


def test_no_selected_face_refused(part):
    from BSplineCAM.core import ParameterError

    _, faces, _ = part
    with pytest.raises(ParameterError, match="no face is selected"):
        verify_faces(select(faces, set()), read_gcode(raster([15.0], H)), Tool(6.0))


# -- simulation at scale: trimmed windows, the direct disk dilation ----------------------------------
@pytest.mark.parametrize("shape, corner", [("ball", 0.0), ("flat", 0.0), ("bullnose", 1.0)])
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_trimmed_windows_lose_nothing(monkeypatch, shape, corner, seed):
    """Chains of short feed moves continuing one another in XY (raster passes along X, along a
    diagonal, and one that turns) with random slopes: the simulation with each move's window
    cut to where it can be the lowest equals the one with every move's whole reach, and both
    equal a dense sampling of tool positions along the path (an independent reference)."""
    from BSplineCAM.core.program.gcode import linearise
    from BSplineCAM.core.simulation import simulate as sim_mod

    rng = np.random.default_rng(seed)
    lines = ["G21 G90", "G0 X0 Y0 Z20"]
    paths = []
    for y0, direction in ((3.0, (1.0, 0.0)), (9.0, (0.6, 0.8)), (14.0, (1.0, 0.0))):
        start = np.array([1.0, y0])
        points = [np.append(start, 5.0)]
        for k in range(40):
            d = np.array(direction) if k < 25 or y0 != 14.0 else np.array([0.0, 1.0])
            step = rng.uniform(0.05, 0.6)
            xy = points[-1][:2] + step * d
            points.append(np.append(xy, points[-1][2] + rng.normal(0.0, 0.4) * step * 2))
        lines.append(f"G0 X{points[0][0]:.4f} Y{points[0][1]:.4f}")
        lines += [f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f} F900" for p in points]
        lines.append("G0 Z20")
        paths.append(points)
    program = read_gcode("\n".join(lines) + "\nM2\n")
    tool = Tool(4.0, shape, corner)
    grid = sim_mod.Grid.covering(-2.0, 30.0, 0.0, 30.0, 0.1)
    segments = linearise(program, 0.01)
    trimmed = sim_mod.simulate(segments, tool, grid, 12.0).height
    monkeypatch.setattr(sim_mod, "_along_ranges", lambda start, end, tool, feed: (
        np.full(len(start), -tool.radius),
        np.hypot(*(end[:, :2] - start[:, :2]).T) + tool.radius))
    whole = sim_mod.simulate(segments, tool, grid, 12.0).height
    assert np.abs(trimmed - whole).max() <= 4e-6
    # dense reference at random cells: tool positions every 2 um along each path
    xs, ys = grid.centres()
    pick_y = rng.integers(0, grid.ny, 400)
    pick_x = rng.integers(0, grid.nx, 400)
    ref = np.full(400, 12.0)
    for points in paths:
        pts = np.array(points)
        for a, b in zip(pts[:-1], pts[1:]):
            n = max(2, int(np.linalg.norm(b - a) / 0.002) + 1)
            c = a + np.linspace(0, 1, n)[:, None] * (b - a)
            r = np.hypot(xs[pick_x][:, None] - c[:, 0], ys[pick_y][:, None] - c[:, 1])
            h = c[:, 2] + tool.profile(r)
            ref = np.minimum(ref, h.min(axis=1))
    # sampling over-estimates by at most the slope times 1 um; the float32 envelope is good
    # to ~1e-6 mm, more on the swept rim where the profile turns vertical (simulate.py)
    got = trimmed[pick_y, pick_x]
    assert np.all(got <= ref + 2e-4)
    assert np.all(got >= ref - 2e-3)


@pytest.mark.parametrize("radius", [0.5, 1.0, 2.5, 7.0, 30.0])
def test_direct_dilation_equals_distance_transform(radius):
    """The banded dilation of ``distance.dilate_disk`` against thresholding the exact
    distance transform (itself tested against brute force in TestBSplineCAMDistance), on
    footprints with holes and islands, with and without the grid's outside set."""
    from BSplineCAM.core.geometry import distance

    rng = np.random.default_rng(int(radius * 10))
    yy, xx = np.mgrid[:160, :230]
    mask = (((xx - 60) ** 2 + (yy - 70) ** 2 < 30 ** 2) | ((xx - 170) ** 2 + (yy - 40) ** 2 < 9)
            | (rng.random(xx.shape) < 0.0005))
    for outside in (False, True):
        k = int(np.floor(radius)) + 1
        padded = np.pad(mask, k, constant_values=True) if outside else mask
        expect = distance.squared_distance(padded) <= radius * radius + 1e-9
        if outside:
            expect = expect[k:-k, k:-k]
        direct = distance._dilate_direct(padded, radius)
        if direct is not None:
            direct = direct[k:-k, k:-k] if outside else direct
            np.testing.assert_array_equal(direct, expect)
        np.testing.assert_array_equal(distance.dilate_disk(mask, radius, outside), expect)


# -- a wall between two selected faces -----------------------------------------------------------
def _plane_face(x0: float, x1: float, z: float, index: int):
    """A selected horizontal face over [x0, x1] x [0, 10] at height z (degree-1 NURBS)."""
    from BSplineCAM.core.geometry.faces import Face
    from BSplineCAM.core.geometry.nurbs import NurbsSurface

    poles = np.array([[[x0, 0, z], [x0, 10, z]], [[x1, 0, z], [x1, 10, z]]], dtype=float)
    surface = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name=f"Face{index}")
    loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    return Face(surface, loop, index=index, source="Plane")


def test_a_wall_between_selected_faces_is_a_border():
    """Two selected faces one above the other's side (z 10 on x < 10, z 14 beyond, the wall
    between them not in the model): seen from above they touch, but no ball reaches the foot
    of the wall, so the cells within a radius of it belong to the edge band.  A raster at the
    exact tip heights (the ball resting on the upper face's edge beside the wall) leaves the
    wall's foot as much as the closed form says, in the edge band; the scallop inside is the
    raster's own."""
    r = 1.0
    faces = [_plane_face(0.0, 10.0, 10.0, 1), _plane_face(10.0, 20.0, 14.0, 2)]
    xs = np.arange(-1.0, 21.0 + 1e-9, 0.25)
    tip = np.where(xs >= 10.0, 14.0,
                   np.where(xs > 10.0 - r, 14.0 - r + np.sqrt(np.maximum(
                       r * r - (10.0 - xs) ** 2, 0.0)), 10.0))
    lines = ["%", "G17 G21 G90 G54", "T1 M6", "S10000 M3", "G0 Z30"]
    for i, (x, z) in enumerate(zip(xs, tip)):
        a, b = (-2.0, 12.0) if i % 2 == 0 else (12.0, -2.0)
        lines += [f"G0 X{x:.4f} Y{a}", f"G1 Z{z:.4f} F600", f"G1 Y{b} F1200", "G0 Z30"]
    program = read_gcode("\n".join([*lines, "M5", "M2", "%"]) + "\n")
    m = verify_faces(faces, program, Tool(2 * r), cell=0.1).metrics
    assert m["gouge_max_mm"] < 1e-4
    assert m["scallop_max_mm"] < 0.07  # passes 0.25 mm apart: 0.0078 mm cusps, and rounding
    # the wall's foot: at each cell centre in front of it the lowest ball over it
    cx = np.arange(9.0, 10.0, 0.1) + 0.05
    d = np.abs(cx[:, None] - xs[None, :])
    ball = np.where(d <= r, tip[None, :] + r - np.sqrt(np.maximum(r * r - d * d, 0.0)), np.inf)
    left = float((ball.min(axis=1) - 10.0).max())
    assert left > 0.5
    assert m["edge_scallop_max_mm"] == pytest.approx(left, abs=0.02)
    assert m["coverage"] == pytest.approx(1.0)


def _cone_ring(r0: float = 5.0, r1: float = 10.0, z0: float = 0.0, z1: float = 2.0):
    """A conical ring about the z axis, radius r0 at z0 to r1 at z1: u the angle (its seam
    along +x), v the profile."""
    from bsplinecam_helpers import revolved_face

    return revolved_face([(r0, z0), (r1, z1)], index=1, source="Cone")


def test_heights_across_a_closed_face_seam():
    """A ring closed on itself (a cone's or torus's seam along +x): the cells on either side of
    the seam are found on it, with the cone's height, whichever side their seed lies on."""
    ring = _cone_ring()
    angles = np.radians(np.r_[np.linspace(-3.0, 3.0, 61), np.arange(0.0, 360.0, 7.0)])
    radius = np.r_[np.full(61, 7.3), np.linspace(5.2, 9.8, 52)]
    x, y = radius * np.cos(angles), radius * np.sin(angles)
    hm = FacesHeight([ring], 0.1).points(x, y)
    assert hm.found.all()
    np.testing.assert_allclose(hm.z, 2.0 * (radius - 5.0) / 5.0, atol=1e-6)
