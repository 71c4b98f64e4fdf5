# SPDX-License-Identifier: LGPL-2.1-or-later
"""G-code reader: FreeCAD post-processor output, arcs, units, errors, and LinuxCNC's rs274."""

from __future__ import annotations

import math
import os
import re
import shutil
from unittest import mock

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core.program import gcode, rs274
from BSplineCAM.core.program.gcode import (
    GcodeError,
    MoveKind,
    linearise,
    read_canonical,
    read_gcode,
)

RS274 = shutil.which("rs274")

# What FreeCAD 0.20's linuxcnc/fanuc/mach3 posts write, with line numbers and comments.
FREECAD_STYLE = """%
(Exported by FreeCAD)
(Post Processor: linuxcnc_post)
N100 (begin preamble)
N110 G17 G54 G40 G49 G80 G90
N120 G21
N130 (begin operation: Surface)
N140 (machine units: mm/min)
N150 M6 T1
N160 G43 H1
N170 M3 S10000
N180 G0 Z15.000
N190 G0 X10.000 Y5.000
N200 G1 X10.000 Y5.000 Z-1.000 F300.000 ; plunge
N210 G1 X30.000 Y5.000 Z-1.000 F600.000
N220 G2 X40.000 Y15.000 I0.000 J10.000 F600.000
N230 G3 X30.000 Y25.000 R10.000
N240 G1 X20 Y25
N250 G0 Z15.000
N260 M9
N270 M5
N280 G17 G54 G90 G80 G40
N290 M2
%
"""


def test_freecad_style_program() -> None:
    prog = read_gcode(FREECAD_STYLE)
    # the first two rapids only set the (unknown) start position, so no move is recorded
    assert list(prog.kind) == [MoveKind.LINE, MoveKind.LINE, MoveKind.ARC_CW,
                               MoveKind.ARC_CCW, MoveKind.LINE, MoveKind.RAPID]
    np.testing.assert_allclose(prog.start[0], [10, 5, 15])
    np.testing.assert_allclose(prog.end[2], [40, 15, -1])
    np.testing.assert_allclose(prog.centre[2], [30, 15, -1])
    np.testing.assert_allclose(prog.centre[3], [30, 15, -1], atol=1e-12)  # R form, same circle
    assert prog.feed[0] == 300 and prog.feed[3] == 600 and math.isnan(prog.feed[5])
    assert prog.line[2] == 16  # source line of N220
    assert prog.tools == (1,)
    assert not prog.converted_from_inches
    lengths = prog.lengths()
    assert lengths[2] == pytest.approx(1.5 * math.pi * 10)  # clockwise: the long way round
    assert lengths[3] == pytest.approx(math.pi / 2 * 10)


@pytest.mark.parametrize("plane, words, centre", [
    ("G17", "G2 X10 Y0 I5 J0", [5, 0, 0]),
    ("G18", "G2 X10 Z0 I5 K0", [5, 0, 0]),
    ("G19", "G2 Y10 Z0 J5 K0", [0, 5, 0]),
])
def test_arc_planes(plane: str, words: str, centre: list[float]) -> None:
    prog = read_gcode(f"G21 G90 F100\nG0 X0 Y0 Z0\n{plane}\n{words}\nM2\n")
    np.testing.assert_allclose(prog.centre[0], centre)
    assert prog.lengths()[0] == pytest.approx(5 * math.pi)


@pytest.mark.parametrize("kind, r, centre", [
    ("G2", 5, [5, 0]),       # half circle: both sides agree
    ("G2", 10, [5, -8.660254]),  # short clockwise arc from (0,0) to (10,0): centre below
    ("G3", 10, [5, 8.660254]),
    ("G2", -10, [5, 8.660254]),  # R < 0: the long arc
])
def test_r_form_centre(kind: str, r: float, centre: list[float]) -> None:
    prog = read_gcode(f"G21 G90 F100\nG0 X0 Y0 Z0\n{kind} X10 Y0 R{r}\nM2\n")
    np.testing.assert_allclose(prog.centre[0, :2], centre, atol=1e-6)


def test_incremental_and_absolute_arc_centre() -> None:
    prog = read_gcode("G21 G90 F100\nG0 X1 Y1 Z0\nG91 G1 X2 Y3\nG90.1 G90 G2 X13 Y4 I8 J4\nM30\n")
    np.testing.assert_allclose(prog.end[0], [3, 4, 0])
    np.testing.assert_allclose(prog.centre[1, :2], [8, 4])


def test_inches_converted() -> None:
    prog = read_gcode("G20 G90\nG0 X0 Y0 Z1\nG1 X1 Y2 Z-0.1 F10\nG2 X3 Y2 R1\nM2\n")
    assert prog.converted_from_inches and prog.source_units == "in"
    np.testing.assert_allclose(prog.end[0], [25.4, 50.8, -2.54])
    assert prog.feed[0] == pytest.approx(254.0)
    np.testing.assert_allclose(prog.centre[1, :2], [50.8, 50.8])


@pytest.mark.parametrize("text, message", [
    ("G21\nG0 X0 Y0 Z0\nG1 X1 E5 F100\nM2\n", "line 3: unknown word E5"),
    ("G21\nG0 X0 Y0 Z0\nG1 X1 F100\nG7\nM2\n", "line 4: unknown or unsupported G code G7"),
    ("G21\nG0 X0 Y0 Z0\nM66\nM2\n", "line 3: unknown or unsupported M code M66"),
    ("G21\nG0 X0 Y0 Z0\nG1 X1 Y\n", "line 3: word 'Y' has no number"),
    ("G21\nG0 X0 Y0 Z0\nG1 X1 Y2 F100\n", "without M2, M30 or a closing %: truncated"),
    ("%\nG21\nG0 X0 Y0 Z0\nG1 X1 F100\n", "truncated"),
    ("G21\nG0 X0 Y0 Z0 (open comment\nM2\n", "line 2: unbalanced comment"),
    ("G21\nG0 X0 Y0 Z0\nG1 X1\nM2\n", "line 3: G1 with no feed rate"),
    ("G21\nG0 X0 Y0 Z0\nG2 X10 Y0 I4 J0 F100\nM2\n", "line 3: radius to the arc's end"),
    ("G21\nG0 X0 Y0 Z0\nG2 X10 Y0 R2 F100\nM2\n", "line 3: arc radius R2 is smaller"),
    ("G21\nG0 X0 Y0 Z0\nG1 X1 F#1\nM2\n", "line 3: parameters and expressions are not supported in F"),
    ("G21\n#1=5\nM2\n", "line 2: parameters and expressions are not supported"),
    ("G21\nG0 X0 Y0 Z0\nG0 X[1\nM2\n", "line 3: parameters and expressions are not supported"),
    ("G21\nG0 X0 Y0 Z0\nG28 G1 X1\nM2\n", "line 3: G28 and a motion code on one line"),
    ("G21\nG0 X0 Y0 Z0\nG1 X? F100\nM2\n", "line 3: cannot read"),
    ("G21\nG0 X0 Y0 Z0\nG81 X1 Y1 Z-1 R1 F100\nM2\n", "line 3: canned cycle G81"),
    ("G21\nG0 X0 Y0 Z0 A5\nM2\n", "line 2: axis word A"),
    ("G21\nX1\nM2\n", "line 2: axis words without a motion mode"),
    ("G21\nG91 G0 X1\nM2\n", "line 2: incremental X move (G91) from an unknown position"),
    ("\x01\x02garbage\x7f\n", "line 1: cannot read"),
])
def test_errors_name_the_line(text: str, message: str) -> None:
    with pytest.raises(GcodeError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_gcode(text, "prog.ngc")


def linuxcnc_moves(tmp_path, text: str):
    """The moves LinuxCNC's rs274 makes of ``text`` (6 mm tool 1), which it must accept."""
    ngc = tmp_path / "program.ngc"
    ngc.write_text(text)
    check = rs274.check(ngc, {1: 6.0}, timeout=60)
    assert check.ok, check.message
    return read_canonical(check.canonical)


# FreeCAD 1.0's fanuc post around a tool change: home Z, then a tool-length offset whose
# value lives in the controller's parameters.
FANUC_TOOL_CHANGE = """G17 G54 G40 G49 G80 G90
G21
G28 G91 Z0
G90 G0 X0 Y0 Z20
M05
G28 G91 Z0
M6 T1
G91 G0 G43 G54 Z-[#[2000+#4120]] H#4120
G90
M3 S10000
G0 X10 Y10
G0 Z5
G1 Z0 F100
G1 X20 F300
G28 X15 Y10
G0 X1 Y1 Z30
M2
"""


def test_home_and_parameter_axes_make_the_position_unknown() -> None:
    """G28 sends axes to the machine's home, an expression sets an axis to a value only the
    controller knows: no move is simulated from there until every axis is set again."""
    prog = read_gcode(FANUC_TOOL_CHANGE)
    assert list(prog.kind) == [MoveKind.LINE, MoveKind.LINE, MoveKind.RAPID]
    np.testing.assert_allclose(prog.start[0], [10, 10, 5])
    np.testing.assert_allclose(prog.end[1], [20, 10, 0])
    np.testing.assert_allclose(prog.end[2], [15, 10, 0])  # the intermediate point of G28
    assert list(prog.line) == [13, 14, 15]
    assert any("line 6: G28 sends Z" in w for w in prog.warnings), prog.warnings
    assert any("line 8: Z is set by an expression" in w for w in prog.warnings), prog.warnings


@pytest.mark.skipif(RS274 is None, reason="LinuxCNC rs274 not installed")
def test_fanuc_tool_change_is_a_valid_program(tmp_path) -> None:
    """LinuxCNC accepts the block, so refusing it would be the reader's fault."""
    theirs = linuxcnc_moves(tmp_path, FANUC_TOOL_CHANGE)
    ours = read_gcode(FANUC_TOOL_CHANGE)
    # the feeds, which start from a position set by the program, agree exactly
    np.testing.assert_allclose(ours.end[ours.kind == MoveKind.LINE],
                               theirs.end[theirs.kind == MoveKind.LINE], atol=1e-4)


@pytest.mark.skipif(RS274 is None, reason="LinuxCNC rs274 not installed")
def test_checks_at_once_do_not_collide(tmp_path) -> None:
    """rs274 maps its tool table at $HOME/.tool.mmap: checks run together (pytest-xdist, the CLI
    beside a test, two verifications) must each get their own, or one dies of SIGBUS."""
    from concurrent.futures import ThreadPoolExecutor

    lines = ["G21 G90 G17", "T1 M6", "M3 S10000", "G0 Z10", "G0 X0 Y0"]
    lines += [f"G1 X{i % 40:.3f} Y{i / 7:.3f} Z{-(i % 5) / 10:.3f} F800" for i in range(400)]
    lines += ["G0 Z10", "M5", "M2"]
    ngc = tmp_path / "zigzag.ngc"
    ngc.write_text("\n".join(lines) + "\n")
    with ThreadPoolExecutor(4) as pool:
        results = list(pool.map(lambda _: rs274.check(ngc, {1: 6.0}, timeout=60), range(24)))
    assert [r.message for r in results if not r.ok] == []
    assert {r.feeds for r in results} == {400}


def test_killed_rs274_named_as_a_crash(tmp_path, monkeypatch) -> None:
    """An rs274 killed by a signal is reported as that, not as a bare negative exit status."""
    fake = tmp_path / "bin" / "rs274"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nkill -BUS $$\n")
    fake.chmod(0o755)
    monkeypatch.setenv("PATH", f"{fake.parent}:{os.environ['PATH']}")
    ngc = tmp_path / "p.ngc"
    ngc.write_text("G0 X0\nM2\n")
    result = rs274.check(ngc, {1: 6.0}, timeout=60)
    assert not result.ok
    assert result.message == "rs274 was killed by SIGBUS"


def test_unknown_start_not_a_move() -> None:
    prog = read_gcode("G21 G90\nG0 Z10\nG0 X5 Y5\nG1 Z0 F100\nM2\n")
    assert len(prog) == 1
    np.testing.assert_allclose(prog.start[0], [5, 5, 10])


_COORD = st.floats(-200, 200, allow_nan=False).map(lambda v: f"{v:.4f}")
_SIMPLE_LINE = st.tuples(
    st.sampled_from(["", "G0", "G00", "G1", "G01", "g1"]),
    st.lists(st.tuples(st.sampled_from("XYZ"), _COORD), max_size=3, unique_by=lambda t: t[0]),
    st.sampled_from(["", "F250", "F1200.5"]),
    st.sampled_from(["", "N10 ", "N20"]),
    st.sampled_from(["", " (note)", " ; plunge", "  "]),
).map(lambda t: f"{t[3]}{t[0]} {' '.join(a + v for a, v in sorted(t[1]))} {t[2]}{t[4]}")
_MODE_LINE = st.sampled_from(["G90", "G91", "G20", "G21", "F300", "G17", ""])


@settings(max_examples=150, deadline=None)
@given(st.lists(st.one_of(_SIMPLE_LINE, _MODE_LINE), min_size=1, max_size=40),
       st.sampled_from([None, "G1 X1 F0", "G10 X1", "G1 X1 E2", "G0 X1 X2"]), st.integers(0, 40),
       st.sampled_from(["G21", "G20"]))
def test_plain_move_lines_read_as_by_the_general_path(lines: list[str], bad: str | None,
                                                       where: int, units: str) -> None:
    """The shortcut for plain G0/G1 lines gives the same program (or the same error) as the
    general word-by-word interpreter, which it bypasses."""
    if bad is not None:
        lines.insert(where, bad)
    text = f"{units} G90 F100\nG0 X0 Y0 Z5\n" + "\n".join(lines) + "\nM2\n"

    def read() -> object:
        try:
            return read_gcode(text)
        except GcodeError as exc:
            return str(exc)

    fast = read()
    with mock.patch.object(gcode, "_SIMPLE_MOVE", re.compile(r"(?!)")):
        general = read()
    if isinstance(general, str) or isinstance(fast, str):
        assert fast == general
        return
    for name in ("kind", "start", "end", "feed", "line", "plane"):
        np.testing.assert_array_equal(getattr(fast, name), getattr(general, name), err_msg=name)
    assert fast.converted_from_inches == general.converted_from_inches


@settings(max_examples=60, deadline=None)
@given(st.floats(0.5, 50), st.floats(-math.pi, math.pi), st.floats(0.05, 2 * math.pi - 0.05),
       st.booleans(), st.floats(1e-4, 0.05), st.floats(-3, 3))
def test_linearise_chords(radius: float, a0: float, sweep: float, ccw: bool, tol: float,
                          dz: float) -> None:
    """Chord vertices lie on the helix, sagitta <= tolerance, chords chain end to end."""
    a1 = a0 + (sweep if ccw else -sweep)
    s = (radius * math.cos(a0), radius * math.sin(a0))
    e = (radius * math.cos(a1), radius * math.sin(a1))
    code = "G3" if ccw else "G2"
    prog = read_gcode(f"G21 G90 F100\nG0 X{s[0]:.12f} Y{s[1]:.12f} Z0\n"
                      f"{code} X{e[0]:.12f} Y{e[1]:.12f} Z{dz:.12f} "
                      f"I{-s[0]:.12f} J{-s[1]:.12f}\nM2\n")
    seg = linearise(prog, tol)
    pts = np.vstack([seg.start, seg.end[-1:]])
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), radius, rtol=1e-9)
    np.testing.assert_allclose(seg.start[1:], seg.end[:-1], atol=1e-9)
    np.testing.assert_allclose(pts[-1], [e[0], e[1], dz], atol=1e-9)
    mid = (seg.start[:, :2] + seg.end[:, :2]) / 2
    sagitta = radius - np.hypot(mid[:, 0], mid[:, 1])
    assert sagitta.max() <= tol * (1 + 1e-9)
    turned = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    assert (turned[-1] - turned[0]) == pytest.approx(sweep if ccw else -sweep, abs=1e-9)


ARC_PROGRAM = """%
G17 G21 G90 G54 G40 G49 G80
T1 M6
S12000 M3
G0 X5 Y5 Z20
G1 Z8 F200
G1 X25 Y5 Z7.5 F800
G2 X35 Y15 I0 J10
G3 X25 Y25 R10
G1 X15 Y25
G3 X5 Y15 I0 J-10
G2 X15 Y5 R-10
G91 G1 X3 Y1 Z-0.5
G90 G18 G2 X24 Z7 I3 K0
G17 G0 Z20
M5
M2
%
"""


@pytest.mark.skipif(RS274 is None, reason="LinuxCNC rs274 not installed")
def test_same_moves_as_linuxcnc(tmp_path) -> None:
    """Our reader and LinuxCNC's interpreter agree on every end point and arc centre."""
    ours = read_gcode(ARC_PROGRAM)
    theirs = linuxcnc_moves(tmp_path, ARC_PROGRAM)
    assert len(ours) == len(theirs)
    np.testing.assert_array_equal(ours.kind, theirs.kind)
    np.testing.assert_allclose(ours.end, theirs.end, atol=1e-4)
    np.testing.assert_allclose(ours.start, theirs.start, atol=1e-4)
    arcs = ours.kind >= MoveKind.ARC_CW
    np.testing.assert_allclose(ours.centre[arcs], theirs.centre[arcs], atol=1e-4)
    np.testing.assert_allclose(ours.feed[~arcs & (ours.kind == 1)],
                               theirs.feed[~arcs & (theirs.kind == 1)])
