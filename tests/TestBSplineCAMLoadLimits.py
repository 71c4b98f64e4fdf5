# SPDX-License-Identifier: LGPL-2.1-or-later
"""Load limits per tool: closed-form programs cut from a block (a full-width slot, a side pass
at a known width, plunges, a ball ramp), checked against limits, with the overload's line,
value and region; the option syntax; the defaults; and ``bsplinecam verify --load-limit``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import plane_net, run_main

from BSplineCAM.core.errors import ParameterError
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.job_simulation import simulate_job
from BSplineCAM.core.simulation.load_limits import (
    LoadLimits,
    check_loads,
    default_limits,
    job_limits,
    parse_load_limits,
)
from BSplineCAM.core.simulation.simulate import Grid, Tool
from BSplineCAM.orchestration.cli_common import EXIT_CHECK_FAILED, EXIT_INPUT_ERROR

CELL = 0.2
FLAT10 = Tool(10.0, "flat")
BALL6 = Tool(6.0, "ball")
BLOCK = (0.0, 50.0, -20.0, 20.0, -10.0, 0.0)


def program(*lines: str) -> str:
    """Line 1 the modes, line 2 a comment, then ``lines`` from line 3 (the tool change)."""
    return "\n".join(["G21 G90 G17", "(header)", *lines, "M2"]) + "\n"


def grid() -> Grid:
    return Grid(-20.0, -30.0, CELL, round(90 / CELL), round(60 / CELL))


def run(text: str, tool: Tool = FLAT10):
    return simulate_job(read_gcode(text), {1: tool}, grid(), BLOCK)


def slot(y: float, depth: float, feed: float = 600.0) -> list[str]:
    """Five lines: rapid over, rapid down, plunge beside the block, the cut (the 4th: line 7
    after the tool change), lift."""
    return [f"G0 X-10 Y{y} Z5", "G0 Z1", f"G1 Z{-depth} F{feed}", f"G1 X60 F{feed}", "G0 Z5"]


def test_full_width_slot_over_radial_limit() -> None:
    """A 10 mm flat slotting 2 mm deep cuts 10 mm wide (the diameter): over a 6 mm radial
    limit at the slot's line (7), within an 11 mm one."""
    job = run(program("T1 M6", *slot(0.0, 2.0)))
    check = check_loads(job, {1: LoadLimits(axial_mm=3.0, radial_mm=6.0)})
    assert not check.ok
    assert [(o.line, o.quantity) for o in check.overloads] == [(7, "radial")]
    assert check.overloads[0].value == pytest.approx(10.0, abs=CELL)
    assert check.overloads[0].limit == 6.0
    assert check.overloads[0].z == pytest.approx(-2.0)
    assert check_loads(job, {1: LoadLimits(axial_mm=3.0, radial_mm=10.5)}).ok
    # the depth: 2 mm against a 1.5 mm limit
    deep = check_loads(job, {1: LoadLimits(axial_mm=1.5)})
    assert [(o.line, o.quantity) for o in deep.overloads] == [(7, "axial")]
    assert deep.overloads[0].value == pytest.approx(2.0, abs=1e-5)


def test_width_limit_from_a_depth() -> None:
    """With radial_from_depth_mm the width limit holds for deeper cuts only: the 10 mm flat's
    full-width slot 2 mm deep passes a 6 mm width limit from 2.5 mm, fails it from 1.5 mm."""
    job = run(program("T1 M6", *slot(0.0, 2.0)))
    assert check_loads(job, {1: LoadLimits(radial_mm=6.0, radial_from_depth_mm=2.5)}).ok
    over = check_loads(job, {1: LoadLimits(radial_mm=6.0, radial_from_depth_mm=1.5)})
    assert [(o.line, o.quantity) for o in over.overloads] == [(7, "radial")]


def test_side_pass_within_limits() -> None:
    """The tool's edge 4 mm inside the block's side (y = 20): a 4 mm wide cut, within 4.5 mm;
    the same pass at 3 mm over a 3.5 mm limit."""
    job = run(program("T1 M6", *slot(20.0 + 5.0 - 4.0, 2.0)))
    assert check_loads(job, {1: LoadLimits(axial_mm=2.1, radial_mm=4.5)}).ok
    check = check_loads(job, {1: LoadLimits(radial_mm=3.5)})
    assert [(o.line, o.quantity) for o in check.overloads] == [(7, "radial")]
    assert check.overloads[0].value == pytest.approx(4.0, abs=CELL)


def test_removal_rate_over_limit() -> None:
    """The full-width slot removes D x depth x feed = 10 x 2 x 600 mm^3/min."""
    job = run(program("T1 M6", *slot(0.0, 2.0)))
    check = check_loads(job, {1: LoadLimits(removal_rate_mm3_per_min=10000.0)})
    assert [(o.line, o.quantity) for o in check.overloads] == [(7, "removal_rate")]
    assert check.overloads[0].value == pytest.approx(10 * 2 * 600, rel=1e-3)
    assert check_loads(job, {1: LoadLimits(removal_rate_mm3_per_min=12100.0)}).ok
    assert np.nanmax(job.rate) == pytest.approx(job.tools[1].material_removal_rate_max_mm3_per_min)


def plunges(*points: tuple[float, float], depth: float = 5.0) -> list[str]:
    out = []
    for x, y in points:
        out += [f"G0 X{x} Y{y} Z5", "G0 Z1", f"G1 Z{-depth} F300", "G0 Z5"]
    return out


def test_plunges_axial_found_at_their_lines_and_grouped() -> None:
    """Plunges 5 mm deep against a 3 mm axial limit: each found at its line (5, 9, 13) with
    its depth; entries, so a flat's radial (full width, 10 mm) is not held against a 4 mm
    limit.  The two plunges 2 mm apart form one region, the far one another; the stock they
    meet is the block's whole height (10 mm), or above a design 4 mm under the top, 4 mm."""
    job = run(program("T1 M6", *plunges((10.0, 0.0), (12.0, 0.0), (40.0, 0.0))))
    check = check_loads(job, {1: LoadLimits(axial_mm=3.0, radial_mm=4.0)})
    assert [(o.line, o.quantity) for o in check.overloads] == [
        (6, "axial"), (10, "axial"), (14, "axial")]
    for o in check.overloads:
        assert o.value == pytest.approx(5.0, abs=1e-5) and o.z == pytest.approx(-5.0)
    near, far = check.regions
    assert (near.first_line, near.last_line, near.moves) == (6, 10, 2)
    assert (far.first_line, far.last_line, far.moves) == (14, 14, 1)
    assert far.x0 >= 40.0 - 5.0 and far.x1 <= 40.0 + 5.0
    assert near.x1 <= 12.0 + 5.0 and near.x0 >= 10.0 - 5.0
    assert (near.z_min, near.z_max) == (pytest.approx(-5.0), pytest.approx(-5.0))
    assert near.stock_mm == pytest.approx(10.0, abs=1e-5)
    design = np.full((job.grid.ny, job.grid.nx), -4.0)
    assert check_loads(job, {1: LoadLimits(axial_mm=3.0)}, design).regions[0].stock_mm == \
        pytest.approx(4.0, abs=1e-5)
    lines = check.messages({1: FLAT10})
    assert len(lines) == 2
    assert lines[0].startswith("T1 (flat 10 mm) line 6: axial engagement 5.00 mm over its "
                               "limit 3.00 mm; 2 moves over their limits meet stock up to "
                               "10.0 mm thick at x ")
    assert "(lines 6..10)" in lines[0] and "(lines 14..14)" in lines[1]
    data = check.to_dict()
    assert data["ok"] is False and data["overloaded_moves"] == 3
    assert data["limits"]["1"] == {"axial_mm": 3.0, "radial_mm": 4.0,
                                   "removal_rate_mm3_per_min": None,
                                   "radial_from_depth_mm": None}
    assert [r["moves"] for r in data["regions"]] == [2, 1]
    json.dumps(data, allow_nan=False)


def test_ball_descending_move_radial_is_checked() -> None:
    """A ramp 2 mm down over 20 mm in X (line 7): an entry.  The 6 mm ball ends 2 mm deep, as
    wide there as 2 sqrt(2 (6 - 2)) = 5.66 mm: over a 4 mm radial limit (a ball's descending
    moves are its finishing passes); a flat end mill's same ramp is an entry, its width not
    held against the limit."""
    text = program("T1 M6", "G0 X5 Y0 Z5", "G0 Z1", "G1 Z0 F300", "G1 X25 Z-2", "G0 Z5")
    ball = run(text, BALL6)
    assert ball.entry[ball.segments.line == 7].all()
    check = check_loads(ball, {1: LoadLimits(radial_mm=4.0)})
    assert [(o.line, o.quantity) for o in check.overloads] == [(7, "radial")]
    assert check.overloads[0].value == pytest.approx(2 * math.sqrt(2 * 4), abs=2 * CELL)
    flat = run(text, FLAT10)
    assert check_loads(flat, {1: LoadLimits(radial_mm=4.0)}).ok


def test_default_limits_by_kind() -> None:
    ball = default_limits(BALL6)
    assert ball.axial_mm == pytest.approx(1.5)
    assert ball.radial_mm == pytest.approx(2 * math.sqrt(1.5 * 4.5))
    assert ball.removal_rate_mm3_per_min is None
    assert default_limits(FLAT10) == LoadLimits(axial_mm=10.0)
    assert default_limits(Tool(10.0, "bullnose", 2.0)) == LoadLimits(axial_mm=10.0)


def test_job_limits_from_parameters() -> None:
    """The case study's job: step-down 2, stepover 4 mm, 0.3 mm allowances, scallop 0.01, rest
    limit 1, cell 0.1 (threshold 0.01)."""
    limits = job_limits(FLAT10, BALL6, stepdown=2.0, stepover=4.0, axial_allowance=0.3,
                        radial_allowance=0.3, scallop=0.01, rest_limit=1.0, cell=0.1)
    assert limits[1].axial_mm == pytest.approx(2.0 + 0.01)  # a step-down
    assert limits[1].radial_mm == pytest.approx(1.1 * 4.0 + 0.1)
    assert limits[2].axial_mm == pytest.approx(6.0 + 0.01)  # the ball's diameter
    # the ball's width at the planned stock (1.31 mm deep: 5.01 mm) is under 0.9 D
    planned = 0.3 + 0.01 + 1.0
    assert 2 * math.sqrt(planned * (6 - planned)) < 5.4
    assert limits[2].radial_mm == pytest.approx(0.9 * 6.0 + 0.1)
    # no rest passes: the ball meets the terraces, a step-down thick; a ball roughing tool's
    # width is not limited, its depth the step-down
    limits = job_limits(Tool(8.0), BALL6, stepdown=1.9, stepover=3.0, axial_allowance=0.3,
                        radial_allowance=0.3, scallop=0.01, rest_limit=0.0, cell=0.1)
    planned = 0.3 + 0.01 + 1.9
    assert 2 * math.sqrt(planned * (6 - planned)) > 5.4
    assert limits[2].radial_mm == pytest.approx(2 * math.sqrt(planned * (6 - planned)) + 0.1)
    assert limits[1].radial_mm is None
    assert limits[1].axial_mm == pytest.approx(1.9 + 0.01)
    # terraces 2.5 mm thick: the ball's width there and a cell reach its diameter: unlimited
    limits = job_limits(FLAT10, BALL6, stepdown=2.5, stepover=4.0, axial_allowance=0.3,
                        radial_allowance=0.3, scallop=0.01, rest_limit=0.0, cell=0.1)
    assert limits[2].radial_mm is None
    with pytest.raises(ParameterError, match="stepdown"):
        job_limits(FLAT10, BALL6, stepdown=0.0, stepover=4.0, axial_allowance=0.3,
                   radial_allowance=0.3, scallop=0.01, rest_limit=1.0, cell=0.1)


def test_parse_load_limits() -> None:
    assert parse_load_limits("2:axial=1.5,radial=4,rate=8000", "--load-limit") == (
        2, LoadLimits(1.5, 4.0, 8000.0))
    assert parse_load_limits("T1: radial = none , axial=2", "--load-limit") == (
        1, LoadLimits(axial_mm=2.0))


@pytest.mark.parametrize("text, fragments", [
    ("2:axial=abc", ["--load-limit", "axial", "(mm)"]),
    ("2:axial=0", ["--load-limit", "axial", "(mm)"]),
    ("2:radial=inf", ["--load-limit", "radial", "(mm)"]),
    ("2:rate=-5", ["--load-limit", "rate", "(mm^3/min)"]),
    ("2:speed=3", ["--load-limit", "'speed=3'", "mm^3/min"]),
    ("2:axial=1,axial=2", ["--load-limit", "axial given twice"]),
    ("x:axial=1", ["--load-limit", "tool number"]),
    ("axial=1", ["--load-limit", "TOOL:"]),
    ("2:", ["--load-limit", "axial=MM"]),
])
def test_parse_errors_name_the_option_and_unit(text: str, fragments: list[str]) -> None:
    with pytest.raises(ParameterError) as info:
        parse_load_limits(text, "--load-limit")
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message, message


# -- bsplinecam verify --load-limit ------------------------------------------------------------
def forced_program() -> tuple[str, int]:
    """T1 (flat 10) faces the 60 x 40 x 14 block to z 11; T2 (ball 6) then cuts one pass 1 mm
    deep along y = 20, 2 sqrt(1 x 5) = 4.47 mm wide; the pass's line."""
    lines = ["G21 G90 G17", "(T1 flat 10 mm)", "T1 M6", "S8000 M3"]
    for k, y in enumerate(np.arange(0.0, 40.01, 5.0)):
        x0, x1 = (-6.0, 66.0) if k % 2 == 0 else (66.0, -6.0)
        lines += [f"G0 X{x0} Y{y} Z16", "G1 Z11 F800", f"G1 X{x1}", "G0 Z16"]
    lines += ["(finishing)", "M6 T2", "S12000 M3", "G0 X-4 Y20 Z16", "G1 Z10 F600", "G1 X64"]
    line = len(lines)
    return "\n".join([*lines, "G0 Z16", "M5", "M2"]) + "\n", line


def test_cli_verify_reports_the_overload(capsys, tmp_path: Path) -> None:
    text, line = forced_program()
    path = tmp_path / "job.ngc"
    path.write_text(text)
    net = str(plane_net(tmp_path))
    base = ["verify", net, str(path), "--tools", "T1=flat:10,T2=ball:6", "--stock",
            "0,60,0,40,0,14", "--cell", "0.5"]
    status, stdout, err = run_main(capsys, *base, "--load-limit", "2:radial=3",
                                   "--out", str(tmp_path / "over"))
    assert status == EXIT_CHECK_FAILED, err
    failed = [s for s in err.splitlines() if "check failed" in s]
    assert len(failed) == 1
    assert failed[0].startswith(f"bsplinecam verify: check failed: T2 (ball 6 mm) line {line}: "
                                "radial engagement ")
    report = json.loads((tmp_path / "over" / "verify.json").read_text())
    loads = report["loads"]
    assert loads["ok"] is False and loads["overloaded_moves"] == 1
    (over,) = loads["overloads"]
    assert (over["tool"], over["line"], over["quantity"]) == (2, line, "radial")
    assert over["value"] == pytest.approx(2 * math.sqrt(5.0), abs=0.5)
    # T2's other limits keep the ball's defaults; T1 its own
    assert loads["limits"]["2"]["axial_mm"] == pytest.approx(1.5)
    assert loads["limits"]["1"] == {"axial_mm": 10.0, "radial_mm": None,
                                    "removal_rate_mm3_per_min": None,
                                    "radial_from_depth_mm": None}
    assert json.loads(stdout)["overloaded_moves"] == 1
    # within the defaults (1 mm deep, 4.47 mm wide against 1.5 and 5.2 mm): exit 0
    status, stdout, err = run_main(capsys, *base, "--out", str(tmp_path / "ok"))
    assert status == 0, err
    assert json.loads((tmp_path / "ok" / "verify.json").read_text())["loads"]["ok"] is True


@pytest.mark.parametrize("extra, fragments", [
    (["--load-limit", "3:axial=1"], ["--load-limit", "T3"]),
    (["--load-limit", "2:axial=x"], ["--load-limit", "(mm)"]),
    (["--load-limit", "2:axial=1", "--load-limit", "2:radial=2"], ["--load-limit", "twice"]),
])
def test_cli_verify_load_limit_errors(capsys, tmp_path: Path, extra, fragments) -> None:
    text, _ = forced_program()
    path = tmp_path / "job.ngc"
    path.write_text(text)
    status, stdout, err = run_main(capsys, "verify", str(plane_net(tmp_path)), str(path),
                                   "--tools", "T1=flat:10,T2=ball:6", "--stock",
                                   "0,60,0,40,0,14", "--cell", "0.5", *extra,
                                   "--out", str(tmp_path / "out"))
    assert status == EXIT_INPUT_ERROR
    assert stdout == ""
    (message,) = err.strip().splitlines()
    for fragment in fragments:
        assert fragment in message, message
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("extra, fragments", [
    (["--rough-limits", "axial=none,radial=x"], ["--rough-limits", "radial", "(mm)"]),
    (["--finish-limits", "rate=0"], ["--finish-limits", "rate", "(mm^3/min)"]),
    (["--finish-limits", "depth=1"], ["--finish-limits", "'depth=1'"]),
])
def test_cli_job_limit_options_refused(capsys, tmp_path: Path, extra, fragments) -> None:
    status, stdout, err = run_main(capsys, "job", str(plane_net(tmp_path)), *extra,
                                   "--out", str(tmp_path / "out"))
    assert status == EXIT_INPUT_ERROR
    (message,) = err.strip().splitlines()
    for fragment in fragments:
        assert fragment in message, message
    assert not (tmp_path / "out").exists()


def test_job_limit_options_override_the_jobs() -> None:
    """--rough-limits and --finish-limits replace the fields they name, keep the others."""
    from types import SimpleNamespace

    from BSplineCAM.orchestration.cli_job import load_limits_of, roughing_parameters

    args = SimpleNamespace(
        rough="flat:10", stock_margin=2.0, stepdown=2.0, fine_stepdown=0.0, stepover=40.0,
        ramp_angle=3.0, allowance=0.3, radial_allowance=None, axial_allowance=None,
        no_flat_levels=False, centre_cutting=False, cell=0.1, rough_limits=None,
        finish_limits=None)
    rough, roughing = roughing_parameters(args)
    plain = load_limits_of(args, rough, BALL6, roughing, 1.0, 0.01)
    assert plain == job_limits(FLAT10, BALL6, stepdown=2.0, stepover=4.0, axial_allowance=0.3,
                               radial_allowance=0.3, scallop=0.01, rest_limit=1.0, cell=0.1)
    args.rough_limits = "rate=9000"
    args.finish_limits = "radial=none,axial=2"
    over = load_limits_of(args, rough, BALL6, roughing, 1.0, 0.01)
    assert over[1] == LoadLimits(plain[1].axial_mm, plain[1].radial_mm, 9000.0)
    # radial=none lifts the width limit (the depth it held from stays, unused)
    assert over[2] == LoadLimits(axial_mm=2.0, radial_from_depth_mm=plain[2].radial_from_depth_mm)
