# SPDX-License-Identifier: LGPL-2.1-or-later
"""Tools by number: the --tools option, LinuxCNC tool tables (good, bad, fuzzed), tool
changes in the G-code reader, and ``bsplinecam verify`` with --tools/--tool-table/--stock."""

from __future__ import annotations

import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from conftest import FUZZ, hang_guard, plane_net, run_main
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core.errors import BSplineCAMError, ParameterError
from BSplineCAM.core.program import rs274
from BSplineCAM.core.program.gcode import read_canonical, read_gcode
from BSplineCAM.core.program.tooltable import (
    MAX_TABLE_BYTES,
    ToolTableError,
    check_program_tools,
    parse_tools_option,
    read_tool_table,
)
from BSplineCAM.core.simulation.simulate import Tool, ToolShape
from BSplineCAM.orchestration.cli_common import EXIT_CHECK_FAILED

# -- --tools -----------------------------------------------------------------------------------


def test_tools_option() -> None:
    tools = parse_tools_option("T1=flat:10,T2=ball:6, T3=bullnose:10:1,7=bull:4.5:0.5")
    assert tools == {1: Tool(10.0, ToolShape.FLAT), 2: Tool(6.0, ToolShape.BALL),
                     3: Tool(10.0, ToolShape.BULLNOSE, 1.0), 7: Tool(4.5, ToolShape.BULLNOSE, 0.5)}


@pytest.mark.parametrize("text, fragment", [
    ("", "expected T<n>"),
    ("T1", "expected T<n>"),
    ("T1=flat", "expected T<n>"),
    ("T1=flat:10:1:2", "expected T<n>"),
    ("Tx=flat:10", "expected T<n>"),
    ("T1=cone:10", "tool shape"),
    ("T1=flat:ten", "diameter 'ten' is not a number"),
    ("T1=flat:0", "diameter must lie in"),
    ("T1=flat:1e400", "diameter '1e400' is not a number"),
    ("T1=flat:99999999", "beyond MAX_COORDINATE_MM"),
    ("T1=flat:10,T1=ball:6", "T1 is given twice"),
    ("T1=bullnose:10", "needs its corner radius"),
    ("T1=bullnose:10:6", "corner radius"),
    ("T1=flat:10:1", "corner radius (mm) applies to a bull-nose"),
    ("T1000000=flat:10", "expected T<n>"),
    ("T1=flat:" + "1" * 200, "MAX_DIGITS"),
])
def test_tools_option_refused(text: str, fragment: str) -> None:
    with pytest.raises(ToolTableError, match="--tools") as info:
        parse_tools_option(text)
    assert fragment in str(info.value)
    assert isinstance(info.value, ParameterError)


# -- tool tables -------------------------------------------------------------------------------

TABLE = """\ufeff; BSplineCAM job tools
T1 P1 D10.0 Z+0.0 ;flat end mill
P2 D6 T2 Z-1.5  ; Ball nose 6 mm

t3 p3 d10 ;BULL NOSE R1.5 carbide\r
T4 P4 X0 Y0 Z0 A0 B0 C0 U0 V0 W0 D8 I0 J0 Q0 ; bullnose r=0.8
T5 P5 D3.175 ;  1/8in. flat\r
"""


def test_tool_table(tmp_path: Path) -> None:
    path = tmp_path / "tool.tbl"
    path.write_bytes(TABLE.encode("utf-8"))
    tools = read_tool_table(path)
    assert tools == {1: Tool(10.0, ToolShape.FLAT), 2: Tool(6.0, ToolShape.BALL),
                     3: Tool(10.0, ToolShape.BULLNOSE, 1.5), 4: Tool(8.0, ToolShape.BULLNOSE, 0.8),
                     5: Tool(3.175, ToolShape.FLAT)}


@pytest.mark.parametrize("text, fragment", [
    ("T1 P1 D10\nT2 P2 ;no diameter\n", "line 2: tool T2 has no diameter (D word"),
    ("P1 D10\n", "line 1: no tool number (T word)"),
    ("T1 D10 K3\n", "line 1: unknown word 'K3'"),
    ("T1 D10 D11\n", "line 1: word D appears twice"),
    ("T1 D10\nT1 D6\n", "line 2: tool T1 appears twice"),
    ("T1.5 D10\n", "line 1: T1.5: tool number must be a whole number"),
    ("T-1 D10\n", "tool number must be a whole number"),
    ("T1 D-10\n", "line 1: D-10: diameter must lie in"),
    ("T1 D0\n", "D0: diameter must lie in"),
    ("T1 D1e3\n", "line 1: unknown word 'E3'"),
    ("T1 D" + "9" * 150 + "\n", "more than MAX_DIGITS"),
    ("T1 D10 Z99999999\n", "beyond MAX_COORDINATE_MM"),
    ("T1 D10 ;bull nose\n", "needs its corner radius"),
    ("T1 D10 ;bull nose r6\n", "corner radius must be in"),
    ("T1 D\u00e910\n", "outside the comment"),
    ("T1 D10 " + " " * 5000 + "\n", "MAX_LINE_CHARS"),
    ("T1 D10 X\n", "word 'X' has no number"),
    ("T1 D10 #5\n", "cannot read '#5'"),
])
def test_tool_table_refused(tmp_path: Path, text: str, fragment: str) -> None:
    path = tmp_path / "bad.tbl"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(ToolTableError) as info:
        read_tool_table(path)
    message = str(info.value)
    assert message.startswith(f"{path}: ") and fragment in message, message
    assert "\n" not in message


@pytest.mark.parametrize("data, fragment", [
    (b"T1 D10\n\xff\n", "line 2: not a text file"),
    (b"T1 D10\nT2 \x00D6\n", "line 2: not a text file (contains NUL"),
    (b"T1 D10\n" * (MAX_TABLE_BYTES // 7 + 1), "MAX_TABLE_BYTES"),
])
def test_tool_table_not_a_table(tmp_path: Path, data: bytes, fragment: str) -> None:
    path = tmp_path / "bad.tbl"
    path.write_bytes(data)
    with pytest.raises(ToolTableError, match=str(path)) as info:
        read_tool_table(path)
    assert fragment in str(info.value)


def test_missing_table_file(tmp_path: Path) -> None:
    with pytest.raises(ToolTableError, match="cannot read"):
        read_tool_table(tmp_path / "none.tbl")


# -- tool changes in programs --------------------------------------------------------------------

TWO_TOOLS = """%
(program with two tools)
G21 G90 G17
G0 Z20
(T1: flat)
T1 M6
G0 X0 Y0 Z5
G1 Z-1 F300
M6 T2 (ball)
G1 X10
T3
G1 Y10
T0 M6
G0 Z20
M30
%
"""


def test_tool_numbers_of_the_moves() -> None:
    """Each move has the tool of the last M6 (T alone only selects), 0 before the first."""
    prog = read_gcode(TWO_TOOLS)
    assert prog.tools == (1, 2)
    # the moves from line 8 on (X and Y are unknown before line 7)
    assert prog.line.tolist() == [8, 10, 12, 14]
    assert prog.tool.tolist() == [1, 2, 2, 0]
    assert prog.tool_changes == ((6, 1), (9, 2), (13, 0))
    check_program_tools(prog, {1: Tool(10, "flat"), 2: Tool(6)})
    with pytest.raises(ParameterError, match=r"line 9: tool change to T2, which the tool table "
                                             r"lacks \(tools given: T1\)"):
        check_program_tools(prog, {1: Tool(10, "flat")})
    before = read_gcode("G21 G90\nG0 X0 Y0 Z5\nG1 Z-1 F100\nM2\n")
    assert before.tool.tolist() == [0]
    with pytest.raises(ParameterError, match="line 3: feed move before any tool change"):
        check_program_tools(before, {1: Tool(6)})


@pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC rs274 not installed")
def test_tool_numbers_as_linuxcnc(tmp_path: Path) -> None:
    """The tool of each move is the one LinuxCNC's interpreter has loaded (CHANGE_TOOL)."""
    text = TWO_TOOLS.replace("G0 Z20\n(T1", "G0 X0 Y0 Z20\n(T1")
    path = tmp_path / "two.ngc"
    path.write_text(text)
    check = rs274.check(path, {1: 10.0, 2: 6.0, 3: 4.0}, timeout=60)
    assert check.ok, check.message
    canon = read_canonical(check.canonical)
    prog = read_gcode(text)
    assert np.allclose(canon.end, prog.end)
    assert canon.tool.tolist() == prog.tool.tolist() == [1, 1, 2, 2, 0]
    assert [n for _, n in canon.tool_changes] == [n for _, n in prog.tool_changes] == [1, 2, 0]


# -- fuzz ----------------------------------------------------------------------------------------

TABLE_FUZZ = settings(FUZZ, max_examples=300)


_PIECES = st.sampled_from([
    "T", "P", "D", "X", "Z", "Q", "K", ";", " ", "\t", "\n", "\r", "\r\n", "1", "0", "-", "+",
    ".", "e", "9" * 120, "1" * 20, "ball", "bull r", "R1.5", "nan", "inf", "\x00", "\ufeff",
    "\u00e9", "#", "(", "T1 D10", "T2 P2 D6 ;ball", "T3 D10 ;bull r1", " " * 300,
])


@st.composite
def mutated_tables(draw) -> bytes:
    text = draw(st.sampled_from([TABLE, "T1 P1 D10 ;flat\n", "T9 D0.5 ;ball\n" * 20]))
    for _ in range(draw(st.integers(0, 6))):
        at = draw(st.integers(0, len(text)))
        action = draw(st.integers(0, 3))
        if action == 0:
            text = text[:at] + draw(_PIECES) + text[at:]
        elif action == 1:
            text = text[:at] + text[at + draw(st.integers(1, 20)):]
        elif action == 2:
            text = text[:at] + draw(_PIECES) * draw(st.integers(1, 400)) + text[at:]
        else:
            text = text[:at] + text[at:] * draw(st.integers(1, 3))
    data = text.encode("utf-8")
    if draw(st.booleans()):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(max_size=8)) + data[at:]
    return data


@TABLE_FUZZ
@given(data=mutated_tables())
def test_fuzz_tool_table(tmp_path_factory, data: bytes) -> None:
    """Any file gives tools with finite sizes or a one-line ToolTableError naming the file."""
    path = tmp_path_factory.mktemp("fuzz") / "t.tbl"
    path.write_bytes(data)
    with hang_guard(what="read_tool_table"):
        try:
            tools = read_tool_table(path)
        except BSplineCAMError as exc:
            message = str(exc)
            assert isinstance(exc, ToolTableError)
            assert message.startswith(str(path)) and "\n" not in message, message
            return
    for number, tool in tools.items():
        assert isinstance(number, int) and number >= 0
        assert math.isfinite(tool.diameter) and tool.diameter > 0
        assert 0 <= tool.corner_radius <= tool.radius


@TABLE_FUZZ
@given(text=st.text(st.sampled_from("T=,:0123456789.flatbulnose-e+ "), max_size=60))
def test_fuzz_tools_option(text: str) -> None:
    try:
        tools = parse_tools_option(text)
    except BSplineCAMError as exc:
        assert str(exc).startswith("--tools") and "\n" not in str(exc)
        return
    assert tools and all(math.isfinite(t.diameter) and t.diameter > 0 for t in tools.values())


# -- bsplinecam verify ---------------------------------------------------------------------------


def job_text(finish_tool: int = 2) -> str:
    """T1 (flat 10) faces the 60 x 40 x 14 block to z 11; then a ball raster at z 10."""
    lines = ["G21 G90 G17", "(T1 flat 10 mm)", "T1 M6", "S8000 M3"]
    for k, y in enumerate(np.arange(0.0, 40.01, 5.0)):
        x0, x1 = (-6.0, 66.0) if k % 2 == 0 else (66.0, -6.0)
        lines += [f"G0 X{x0} Y{y} Z16", "G1 Z11 F800", f"G1 X{x1}", "G0 Z16"]
    lines += ["(finishing)", f"M6 T{finish_tool}", "S12000 M3"]
    for k, y in enumerate(np.arange(0.0, 40.01, 2.0)):
        x0, x1 = (0.0, 60.0) if k % 2 == 0 else (60.0, 0.0)
        lines += [f"G0 X{x0} Y{y} Z16", "G1 Z10 F600", f"G1 X{x1}", "G0 Z16"]
    return "\n".join([*lines, "M5", "M2"]) + "\n"


@pytest.mark.parametrize("how", ["tools", "table"])
def test_cli_verify_job(capsys, tmp_path: Path, how: str) -> None:
    program = tmp_path / "job.ngc"
    program.write_text(job_text())
    if how == "tools":
        spec = ["--tools", "T1=flat:10,T2=ball:6"]
    else:
        table = tmp_path / "tool.tbl"
        table.write_text("T1 P1 D10 Z0 ;flat\nT2 P2 D6 Z0 ;ball\n")
        spec = ["--tool-table", str(table)]
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, "verify", str(plane_net(tmp_path)), str(program),
                                   *spec, "--stock", "0,60,0,40,0,14", "--cell", "0.5",
                                   "--out", str(out))
    assert status == 0, err
    report = json.loads((out / "verify.json").read_text())
    tools = report["tools"]
    assert set(tools) == {"1", "2"}
    assert tools["1"]["removed_volume_mm3"] == pytest.approx(60 * 40 * 3, rel=1e-4)
    assert tools["1"]["axial_engagement_max_mm"] == pytest.approx(3.0, abs=1e-4)
    # passes 5 mm apart, the first half off the block: 5 mm radial engagement each
    assert tools["1"]["radial_engagement_max_mm"] == pytest.approx(5.0, abs=0.5)
    assert tools["1"]["tool"] == {"shape": "flat", "diameter_mm": 10.0, "corner_radius_mm": 0.0}
    # the ball leaves scallops between passes and half a ball at the block's x ends
    assert 0.9 * 60 * 40 < tools["2"]["removed_volume_mm3"] < 60 * 40
    assert report["removed_volume_mm3"] == pytest.approx(
        tools["1"]["removed_volume_mm3"] + tools["2"]["removed_volume_mm3"], rel=1e-6)
    assert report["stock_mm"] == [0, 60, 0, 40, 0, 14]
    assert report["gouge_max_mm"] < 1e-3
    assert report["rapid_collisions"] == []
    assert report["tool"]["shape"] == "ball"  # the finishing tool
    assert json.loads(stdout)["tools"]["2"]["removed_volume_mm3"] > 0


@pytest.mark.parametrize("extra, fragments", [
    ([], ["--tool-diameter (mm), --tools or --tool-table is required"]),
    (["--tool-diameter", "6"], ["changes tools (T1, T2)", "--tool-table"]),
    (["--tools", "T1=flat:10"], ["line 42: tool change to T2, which the tool table lacks"]),
    (["--tools", "T1=flat:10,T2=ball:6", "--tool-diameter", "6"],
     ["--tools replaces --tool-diameter"]),
    (["--tools", "T1=flat:10,T2=ball:6", "--tool-table", "x.tbl"], ["exclude each other"]),
    (["--tools", "T1=flat:10,T2=cone:6"], ["--tools", "tool shape"]),
    (["--tool-table", "nowhere.tbl"], ["nowhere.tbl", "cannot read"]),
    (["--tools", "T1=flat:10,T2=ball:6", "--stock", "0,60,0,40,14,0"], ["--stock", "z0"]),
    (["--tools", "T1=flat:10,T2=ball:6", "--stock", "0,60,0,40,0"], ["--stock", "six"]),
    (["--tools", "T1=flat:10,T2=ball:6", "--stock", "0,60,0,nan,0,14"], ["--stock y1"]),
])
def test_cli_verify_job_refused(capsys, tmp_path: Path, extra, fragments) -> None:
    """Exit status 2, one line naming the problem, nothing written."""
    program = tmp_path / "job.ngc"
    program.write_text(job_text())
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, "verify", str(plane_net(tmp_path)), str(program),
                                   *extra, "--cell", "0.5", "--out", str(out))
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert stdout == "" and not out.exists()


def test_cli_verify_one_tool_with_stock(capsys, tmp_path: Path) -> None:
    """One tool change (as FreeCAD's posts write) and --stock: --tool-diameter suffices and
    verify.json gains the per-tool section."""
    program = tmp_path / "job.ngc"
    program.write_text(job_text(finish_tool=1).replace("M6 T1", "(no change)"))
    out = tmp_path / "out"
    status, _, err = run_main(capsys, "verify", str(plane_net(tmp_path)), str(program),
                              "--tool-diameter", "6", "--stock=-5,65,-5,45,0,14",
                              "--cell", "0.5", "--out", str(out))
    # the 6 mm ball faces the block 3 mm deep: over a ball's default axial limit (1.5 mm)
    assert status == EXIT_CHECK_FAILED, err
    assert "check failed: T1 (ball 6 mm) line 7: axial engagement " in err
    report = json.loads((out / "verify.json").read_text())
    assert set(report["tools"]) == {"1"}
    assert report["grid_cells"][0] * 0.5 >= 50 and report["grid_cells"][1] * 0.5 >= 70
