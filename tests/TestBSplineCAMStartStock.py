# SPDX-License-Identifier: LGPL-2.1-or-later
"""A finishing program's declared starting stock (issue 44, item 3: lift only as high as the
stock and the model need): the model raised by an allowance (a part roughed elsewhere or cast
to within it).  Hops and entries clear the raised model by their margin, checked against the
closed form of a dome on a plate; the verification simulates from the same stock (``--stock-top
model``) and flags a rapid that cuts it."""

from __future__ import annotations

import json
import math
import subprocess

import numpy as np
import pytest
from bsplinecam_helpers import plane, rectangle, revolved_face
from conftest import ROOT, run_main

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.program.gcode import MoveKind, read_gcode
from BSplineCAM.core.simulation.simulate import Grid, Tool, linearise, simulate
from BSplineCAM.core.simulation.verify import StockTop, verify_faces, verify_job
from BSplineCAM.core.toolpath import to_moves
from BSplineCAM.core.toolpath.common import Toolpath, ToolpathStats
from BSplineCAM.core.toolpath.faceset import FaceSet
from BSplineCAM.core.toolpath.retracts import RaisedModel, StockMap, faces_hops

R = 3.0
RHO, CX, CY, BASE = 8.0, 30.0, 20.0, 2.0
ALLOWANCE, MARGIN = 1.5, 1.0


def exact_tip(xy: np.ndarray, radius: float = R) -> np.ndarray:
    """The ball's tip height over a hemisphere of radius RHO at (CX, CY, BASE) on a plate at
    BASE, in closed form."""
    d = np.hypot(xy[:, 0] - CX, xy[:, 1] - CY)
    over = np.sqrt(np.maximum((RHO + radius) ** 2 - d * d, 0.0)) - radius
    return BASE + np.where(d < RHO + radius, np.maximum(over, 0.0), 0.0)


@pytest.fixture(scope="module")
def dome():
    c = math.sqrt(0.5)
    sphere = revolved_face([(RHO, BASE), (RHO, BASE + RHO), (0.0, BASE + RHO)], [1.0, c, 1.0],
                           (CX, CY), 1, "Sphere")
    plate = plane(0.0, 60.0, 0.0, 40.0, BASE)
    return FaceSet([sphere, Face(plate, rectangle(plate), index=2, selected=False)])


def toolpath_of(passes, clearance=40.0):
    tp = Toolpath("raster", passes, {"tool_diameter": 2 * R, "tolerance": 0.01}, [],
                  ToolpathStats(), links=[None] * (len(passes) - 1))
    return tp.finish(0.0, clearance)


def three_passes():
    """Passes on the plate left of the dome, right of it, and on the dome's flank."""
    return [np.array([[5.0, 20.0, BASE], [12.0, 20.0, BASE]]),
            np.array([[48.0, 20.0, BASE], [55.0, 20.0, BASE]]),
            np.array([[CX + 3.0, CY, float(exact_tip(np.array([[CX + 3.0, CY]]))[0])],
                      [CX + 4.0, CY, float(exact_tip(np.array([[CX + 4.0, CY]]))[0])]])]


def test_hops_and_entries_clear_the_raised_model_by_the_margin(dome):
    tp = toolpath_of(three_passes())
    hops = faces_hops(tp, dome, tp.clearance_height, MARGIN, RaisedModel(ALLOWANCE))
    top = BASE + RHO
    # across the dome: its top raised by the allowance, plus the margin (and at most the
    # model bound's reach, a quarter of the radius, above that)
    assert top + ALLOWANCE + MARGIN <= hops.travel[0] <= top + ALLOWANCE + MARGIN + 0.8
    starts = np.array([p[0, 2] for p in tp.passes])
    assert hops.approach == pytest.approx(starts[1:] + ALLOWANCE + MARGIN)
    assert hops.entry == pytest.approx(starts + ALLOWANCE + MARGIN)
    moves = to_moves(tp, safe_height=35.0, hops=hops)
    xyz = np.array([[m.x, m.y, m.z] for m in moves])
    kinds = [m.kind for m in moves]
    # the first pass is entered from the clearance plane by a rapid down to its entry height,
    # not to the safe height, and fed the last ALLOWANCE + MARGIN mm
    assert kinds[:3] == ["rapid", "rapid", "feed"]
    assert xyz[1, 2] == pytest.approx(BASE + ALLOWANCE + MARGIN)
    # every rapid but the climbs out of a pass stays above the raised model along its whole
    # length; every feed down to a pass is at most the allowance and the margin long
    for k in range(1, len(moves)):
        p, q = xyz[k - 1], xyz[k]
        line = p + np.linspace(0, 1, 801)[:, None] * (q - p)
        vertical = np.allclose(p[:2], q[:2])
        if kinds[k] == "rapid" and not (vertical and q[2] > p[2]):
            assert np.all(line[:, 2] >= exact_tip(line[:, :2]) + ALLOWANCE + MARGIN - 1e-9)
        elif kinds[k] == "feed" and vertical and q[2] < p[2]:
            assert p[2] - q[2] <= ALLOWANCE + MARGIN + 1e-9


def test_without_an_allowance_the_hops_are_those_of_the_model(dome):
    tp = toolpath_of(three_passes())
    raised = faces_hops(tp, dome, tp.clearance_height, MARGIN, RaisedModel(0.0))
    bare = faces_hops(tp, dome, tp.clearance_height, MARGIN)
    assert np.array_equal(raised.travel, bare.travel)
    assert np.array_equal(raised.approach, bare.approach)
    assert bare.entry is None  # no stock known: entries stop at the safe height
    plain = to_moves(tp, safe_height=35.0, hops=bare)
    assert [round(m.z, 9) for m in plain[:2]] == [tp.clearance_height, 35.0]


def test_entries_over_a_stock_map_land_above_its_columns(dome):
    tp = toolpath_of(three_passes())
    height = np.full((40, 60), BASE + 0.5)
    height[18:22, 3:6] = 7.0  # stock beside the first pass's start
    hops = faces_hops(tp, dome, tp.clearance_height, MARGIN, StockMap(0.0, 0.0, 1.0, height))
    assert hops.entry[0] == pytest.approx(7.0 + MARGIN)
    assert hops.entry[1] == pytest.approx(BASE + 0.5 + MARGIN)
    moves = to_moves(tp, safe_height=35.0, hops=hops)
    assert moves[1].kind == "rapid" and moves[1].z == pytest.approx(7.0 + MARGIN)
    # an entry is never raised above the safe height
    low = to_moves(tp, safe_height=3.0, hops=hops)
    assert low[1].z == pytest.approx(3.0)
    # over the whole raw block the descent stops at the safe height, as CAM's ops do
    block = StockMap(0.0, 0.0, 60.0, np.array([[20.0]]), whole_block=True)
    hops = faces_hops(tp, dome, tp.clearance_height, MARGIN, block)
    assert hops.entry is None
    assert to_moves(tp, safe_height=35.0, hops=hops)[1].z == pytest.approx(35.0)


def flat_faces():
    top = plane(0.0, 40.0, 0.0, 30.0, 10.0)
    return [Face(top, rectangle(top), index=1, selected=True)]


def program(text: str):
    return read_gcode("G21 G90 G17\nF1000\n" + text + "\nM2\n")


def test_verify_from_the_model_raised_flags_a_rapid_into_it_and_not_above_it():
    tool = Tool(6.0)
    cut = ("G0 X5 Y15 Z20\nG0 Z12.5\nG1 Z10\nG1 X35 Y15 Z10\nG0 Z20\n")
    # a rapid at 11.2 mm over the uncut plate: the stock reaches 10 + 2 = 12 mm
    into = program(cut + "G0 X5 Y25 Z20\nG0 Z11.2\nG0 X35 Y25 Z11.2\n")
    above = program(cut + "G0 X5 Y25 Z20\nG0 Z12.3\nG0 X35 Y25 Z12.3\n")
    hit = verify_faces(flat_faces(), into, tool, cell=0.5, stock_top="model", stock_margin=2.0)
    clear = verify_faces(flat_faces(), above, tool, cell=0.5, stock_top=StockTop.MODEL,
                         stock_margin=2.0)
    lines = [c["line"] for c in hit.metrics["rapid_collisions"]]
    assert lines and all(line >= 9 for line in lines)
    # 0.8 mm, less the ball's rise over the nearest cell centre (0.35 mm off its axis: 0.02)
    deepest = max(c["depth_mm"] for c in hit.metrics["rapid_collisions"])
    assert deepest == pytest.approx(0.8, abs=0.03)
    assert clear.metrics["rapid_collisions"] == []
    assert clear.metrics["stock_top"] == "model"
    start = clear.simulation.start_heights()
    on = clear.inside
    assert np.allclose(start[on], 12.0) and np.all(np.isneginf(start[~on]))
    # the feed at 10 mm ploughed 30 mm through 2 mm of stock: a circular segment of height 2
    # of the ball's section along it, a spherical cap of height 2 at its ends
    h = 2.0
    segment = R * R * math.acos((R - h) / R) - (R - h) * math.sqrt(2 * R * h - h * h)
    caps = math.pi * h * h * (3 * R - h) / 3
    assert clear.simulation.removed_volume() == pytest.approx(30.0 * segment + caps, rel=0.02)


def test_simulate_from_heights_per_cell_matches_the_block_where_they_agree():
    grid = Grid(0.0, 0.0, 0.5, 40, 30)
    moves = program("G0 X3 Y7 Z20\nG0 Z12\nG1 Z9\nG1 X17 Y8 Z9.5\nG0 Z20\n")
    segments = linearise(moves, 0.01)
    block = simulate(segments, Tool(6.0), grid, 11.0)
    per_cell = simulate(segments, Tool(6.0), grid, np.full((30, 40), 11.0))
    assert np.array_equal(block.height, per_cell.height)
    assert per_cell.top == 11.0 and per_cell.removed_volume() == block.removed_volume()
    with pytest.raises(ValueError, match="30 x 40"):
        simulate(segments, Tool(6.0), grid, np.full((3, 4), 11.0))


def test_a_whole_job_refuses_the_model_stock():
    with pytest.raises(ParameterError, match="stock top 'model'"):
        verify_job(flat_faces(), program("T1 M6\nG0 X5 Y5 Z20\nG1 Z10\n"), {1: Tool(6.0)},
                   stock_top="model")
    with pytest.raises(ParameterError, match="'design', 'program' or 'model'"):
        StockTop.parse("raised")


def test_cli_refuses_an_allowance_out_of_range_before_any_work(capsys, tmp_path):
    out = tmp_path / "out"
    status, _, err = run_main(capsys, "toolpath", str(ROOT / "examples" / "part.step"),
                              "--tool-diameter", "6", "--scallop", "0.05", "--start-stock",
                              "model", "--stock-allowance", "150", "--out", str(out))
    assert status == 2
    assert "--stock-allowance must lie in [0, 100] mm, got 150 mm" in err
    assert "Traceback" not in err and not out.exists()


@pytest.mark.venv_only
def test_cli_part_from_the_model_raised_verified_from_it(tmp_path):
    """``toolpath --start-stock model`` on examples/part.step, verified from the same stock:
    no rapid cuts it, and no feed down to a pass is longer than the allowance and margin."""
    part = ROOT / "examples" / "part.step"
    out = tmp_path / "tp"
    run = [str(ROOT / "bin" / "bsplinecam"), "toolpath", str(part), "--tool-diameter", "6",
           "--scallop", "0.2", "--start-stock", "model", "--stock-allowance", "0.5",
           "--out", str(out)]
    proc = subprocess.run(run, capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads((out / "toolpath.json").read_text())
    assert report["parameters"]["start_stock"] == "model"
    text = (out / "part.ngc").read_text()
    program = read_gcode(text)
    d = program.end - program.start
    down = (program.kind != MoveKind.RAPID) & (np.hypot(d[:, 0], d[:, 1]) < 1e-9) & (d[:, 2] < 0)
    assert down.sum() > 1 and -d[down, 2].min() <= 0.5 + 1.0 + 1e-3
    proc = subprocess.run(
        [str(ROOT / "bin" / "bsplinecam"), "verify", str(part), str(out / "part.ngc"),
         "--tool-diameter", "6", "--stock-top", "model", "--stock-margin", "0.5", "--cell",
         "0.25", "--out", str(tmp_path / "v")], capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stderr[-2000:]
    metrics = json.loads((tmp_path / "v" / "verify.json").read_text())
    assert metrics["stock_top"] == "model" and metrics["rapid_collisions"] == []
    assert metrics["gouge_normal_max_mm"] <= 1e-3
