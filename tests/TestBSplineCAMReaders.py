# SPDX-License-Identifier: LGPL-2.1-or-later
"""Readers never crash, hang or lie: the inputs of issue 10 and their kin, one test each.

Every reader (JSON, CSV, .dat, G-code) answers bad input with the project's error naming the
file, the line (or index) and the limit broken; nothing non-finite comes out.  The expected
values come from the inputs themselves (closed forms, the chord-count formula), never from
saved output of the readers.  Memory is bounded with tracemalloc, not with timings.
"""

from __future__ import annotations

import json
import math
import tracemalloc

import numpy as np
import pytest

from BSplineCAM.core.errors import BSplineCAMError, NetError
from BSplineCAM.core.geometry import netio
from BSplineCAM.core.program import gcode
from BSplineCAM.core.program.gcode import (
    GcodeError,
    MoveKind,
    linearise,
    read_gcode,
    read_gcode_file,
)
from BSplineCAM.orchestration.cli import main as cli_main

GRID = np.arange(48.0).reshape(4, 4, 3)


def json_net(points) -> str:
    return json.dumps({"name": "t", "units": "mm", "control_points": points})


def csv_net(points: np.ndarray) -> str:
    rows = ["row,column,x,y,z"]
    rows += [f"{i},{j},{p[0]!r},{p[1]!r},{p[2]!r}" for (i, j), p in
             ((ij, points[ij].tolist()) for ij in np.ndindex(points.shape[:2]))]
    return "\n".join(rows) + "\n"


def dat_net(points: np.ndarray) -> str:
    return f"# rows={points.shape[0]}\n" + "".join(
        f"{x!r} {y!r} {z!r}\n" for x, y, z in points.reshape(-1, 3).tolist())


def raises_net(path, *patterns: str) -> str:
    with pytest.raises(NetError) as info:
        netio.read_net(path)
    message = str(info.value)
    assert str(path) in message and "\n" not in message
    for pattern in patterns:
        assert pattern in message, message
    return message


def peak_mib(call) -> float:
    """Peak memory (MiB) Python and numpy allocate while ``call`` runs (it may raise)."""
    tracemalloc.start()
    try:
        call()
    except BSplineCAMError:
        pass
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    return peak / 2**20


# ---------------------------------------------------------------------------------------------
# JSON


@pytest.mark.parametrize("depth", [1000, 100_000])
def test_json_nesting_limit(tmp_path, depth):
    path = tmp_path / "deep.json"
    path.write_text('{"control_points":\n' + "[" * depth + "]" * depth + "}")
    raises_net(path, "line 2", f"MAX_NESTING={netio.MAX_NESTING}")


def test_json_nesting_at_the_limit_is_parsed(tmp_path):
    inner = "[" * (netio.MAX_NESTING - 2) + "1" + "]" * (netio.MAX_NESTING - 2)
    path = tmp_path / "n.json"
    path.write_text(json.dumps({"control_points": GRID.tolist()})[:-1] + ', "x": ' + inner + "}")
    assert netio.read_json(path).extra["x"] is not None


@pytest.mark.parametrize("digits", [300, 4301, 20_000])
def test_json_integer_with_many_digits(tmp_path, digits):
    """Hundreds of digits overflowed float(); past 4300 Python's int() refused them itself."""
    path = tmp_path / "big.json"
    path.write_text(json_net(GRID.tolist()).replace("47.0", "\n" + "9" * digits))
    raises_net(path, "line 2", f"MAX_DIGITS={netio.MAX_DIGITS}")


def test_json_integer_beyond_reach(tmp_path):
    path = tmp_path / "far.json"
    path.write_text(json_net(GRID.tolist()).replace("47.0", "9" * 30))
    raises_net(path, "point [3][3] coordinate z", "MAX_COORDINATE_MM=1e+06 mm")


def test_python_integers_beyond_any_float_are_named():
    points = GRID.tolist()
    points[1][2][0] = 10**400
    with pytest.raises(NetError, match=r"point \[1\]\[2\] coordinate x is beyond"):
        netio.validate_net(points, "api")
    with pytest.raises(NetError, match="not all finite numbers"):
        netio.validate_net(np.array(points, dtype=object), "api")


def test_json_net_scaled_to_1e307(tmp_path, capsys):
    """``check`` printed Infinity/NaN and exited 1 with no message."""
    path = tmp_path / "huge.json"
    path.write_text(json_net((GRID / 47.0 * 1e307).tolist()))
    raises_net(path, "beyond MAX_COORDINATE_MM=1e+06 mm")
    assert cli_main(["check", str(path)]) == 2
    captured = capsys.readouterr()
    assert "Infinity" not in captured.out and "NaN" not in captured.out
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and "huge.json" in err[0] and "MAX_COORDINATE_MM" in err[0]


def test_json_inches_beyond_reach(tmp_path):
    path = tmp_path / "in.json"
    points = GRID.copy()
    points[0, 0, 1] = 50_000.0  # 1.27 km
    path.write_text(json.dumps({"units": "in", "control_points": points.tolist()}))
    raises_net(path, "point [0][0] coordinate y is 1.27e+06 mm")


@pytest.mark.parametrize("literal, shown", [("NaN", "nan"), ("Infinity", "inf"),
                                            ("-Infinity", "-inf"), ("1e400", "inf")])
def test_json_non_finite_literals_name_the_point(tmp_path, literal, shown):
    path = tmp_path / "nan.json"
    path.write_text(json_net(GRID.tolist()).replace("20.0", literal))
    raises_net(path, f"point [1][2] coordinate z is {shown}")


def test_json_duplicate_keys(tmp_path):
    path = tmp_path / "dup.json"
    text = json_net(GRID.tolist())
    path.write_text(text[:-1] + ',\n"control_points": []}')
    raises_net(path, "line 2", "'control_points' appears twice")


@pytest.mark.parametrize("key, value", [("name", ["a"]), ("units", 1), ("knots", {"a": 1}),
                                        ("units", None), ("knots", None),
                                        ("name", "x" * 300), ("name", "a\nb")])
def test_json_header_fields(tmp_path, key, value):
    path = tmp_path / "h.json"
    path.write_text(json.dumps({key: value, "control_points": GRID.tolist()}))
    raises_net(path, repr(key) if key != "name" or isinstance(value, list) else "MAX_NAME_CHARS")


def test_json_bom_and_crlf(tmp_path):
    path = tmp_path / "bom.json"
    path.write_bytes(b"\xef\xbb\xbf" + json.dumps({"control_points": GRID.tolist()}, indent=1)
                     .replace("\n", "\r\n").encode())
    np.testing.assert_array_equal(netio.read_json(path).points, GRID)


@pytest.mark.parametrize("suffix", [".json", ".csv", ".dat"])
def test_nul_and_invalid_utf8_name_the_line(tmp_path, suffix):
    path = tmp_path / f"b{suffix}"
    path.write_bytes(b"\n\n1 \x00 2\n")
    raises_net(path, "line 3", "NUL")
    path.write_bytes(b"\n1 2 3\n\n\xc3\x28\n")
    raises_net(path, "line 4", "invalid UTF-8 byte 0xc3")


def test_file_size_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(netio, "MAX_FILE_BYTES", 1000)
    path = tmp_path / "big.dat"
    path.write_text("1 2 3\n" * 200)
    raises_net(path, "MAX_FILE_BYTES=1000")


def test_net_size_limit(monkeypatch):
    monkeypatch.setattr(netio, "MAX_NET_POINTS", 20)
    with pytest.raises(NetError, match="5x5 points, more than MAX_NET_POINTS=20"):
        netio.validate_net(np.zeros((5, 5, 3)).tolist(), "api")
    with pytest.raises(NetError, match="MAX_NET_POINTS=20"):
        netio.validate_net(np.zeros((5, 5, 3)), "api")


# ---------------------------------------------------------------------------------------------
# CSV


def test_csv_far_index_fails_before_any_grid(tmp_path):
    """A row index of 100000 built the whole grid and ran out of memory."""
    path = tmp_path / "far.csv"
    path.write_text(csv_net(GRID) + "100000,0,1,2,3\n")
    raises_net(path, "line 18", "row index 100000 is beyond the file's 18 lines")
    path.write_text(csv_net(GRID) + "3,99999999999999999999,1,2,3\n")
    raises_net(path, "line 18", "column index")
    assert peak_mib(lambda: netio.read_net(path)) < 5


def test_csv_sparse_net_is_not_rectangular(tmp_path):
    """Indices within the line count but a sparse grid: the missing point is found at once."""
    lines = ["row,column,x,y,z"] + [f"{i},{i},0,0,0" for i in range(2000)]
    path = tmp_path / "diag.csv"
    path.write_text("\n".join(lines) + "\n")
    raises_net(path, "point (0, 1) is missing")
    assert peak_mib(lambda: netio.read_net(path)) < 20


def test_csv_long_field(tmp_path):
    """A field over 131072 characters raised _csv.Error."""
    path = tmp_path / "long.csv"
    path.write_text(csv_net(GRID) + "0,0," + "1" * 200_000 + ",2,3\n")
    raises_net(path, "line 18", f"MAX_LINE_CHARS={netio.MAX_LINE_CHARS}")
    # a quoted field over many lines reaches csv's own limit: still the project's error
    path.write_text(csv_net(GRID) + '0,0,"' + ("1" * 4000 + "\n") * 40 + '",2,3\n')
    raises_net(path, "unreadable CSV")


@pytest.mark.parametrize("field", ["nan", "inf", "-Infinity", "1_000", "\u0663", "0x10", "1e400",
                                   "1" * 101, "", "1,5"])
def test_csv_numbers_are_plain_decimals(tmp_path, field):
    path = tmp_path / "n.csv"
    path.write_text(csv_net(GRID) .replace("3,3,45.0", f'3,3,"{field}"'))
    raises_net(path, "line 17")


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_csv_bom_crlf_quotes(tmp_path, newline):
    path = tmp_path / "ok.csv"
    text = csv_net(GRID).replace("0,0,0.0", '"0","0","0.0"').replace("\n", newline)
    path.write_bytes(b"\xef\xbb\xbf" + text.encode())
    np.testing.assert_array_equal(netio.read_net(path).points, GRID)


# ---------------------------------------------------------------------------------------------
# .dat


@pytest.mark.parametrize("line, message", [
    ("1 2 1e400", "is not finite"), ("1 2 nan", "'nan' is not finite"),
    ("1 2 " + "9" * 200, "MAX_DIGITS=100"), ("1 2 3e6", "beyond MAX_COORDINATE_MM"),
    ("1 2 \u0663", "not numeric"), ("1 2 1_0", "not numeric"),
])
def test_dat_numbers(tmp_path, line, message):
    path = tmp_path / "d.dat"
    path.write_text(dat_net(GRID) + line + "\n")
    raises_net(path, "line 18", message)


def test_dat_row_header_with_many_digits(tmp_path):
    path = tmp_path / "r.dat"
    path.write_text("# rows=" + "1" * 200 + "\n" + dat_net(GRID))
    raises_net(path, "line 1", "not numeric")


@pytest.mark.parametrize("newline", ["\r\n", "\r"])
def test_dat_crlf_and_bom(tmp_path, newline):
    path = tmp_path / "ok.dat"
    path.write_bytes(b"\xef\xbb\xbf" + dat_net(GRID).replace("\n", newline).encode())
    np.testing.assert_array_equal(netio.read_dat(path), GRID)


# ---------------------------------------------------------------------------------------------
# G-code

HEAD = "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X1 F100\n"


def raises_gcode(line: str, *patterns: str, tolerance: float | None = None) -> str:
    with pytest.raises(GcodeError) as info:
        program = read_gcode(HEAD + line + "\nM2\n", "p.ngc")
        if tolerance is not None:
            linearise(program, tolerance)
    message = str(info.value)
    assert message.startswith("p.ngc: ") and "\n" not in message
    for pattern in patterns:
        assert pattern in message, message
    return message


@pytest.mark.parametrize("word", ["T", "M", "N", "S", "G", "X", "F", "R", "I", "P"])
def test_gcode_word_with_400_digits(word):
    """400 digits after any word are refused on their line by MAX_DIGITS, not read: T/M would
    overflow int(), an axis become inf, F be reported as 'no feed rate set'."""
    message = raises_gcode(f"G2 X2 Y0 I0.5 J0 {word}{'9' * 400}", "line 4",
                           f"MAX_DIGITS={gcode.MAX_DIGITS}")
    assert "feed" not in message


@pytest.mark.parametrize("line, what", [
    ("G1 X" + "9" * 99, "end point (1e+99, 0, 0) mm"),
    ("G91 G1 Y-2000000", "end point (1, -2e+06, 0) mm"),
    ("G20 G1 Z40000", "end point (1, 0, 1.016e+06) mm"),
    ("G2 X1 Y0 I-1000000000000 J0", "arc centre (-1e+12, 0, 0) mm"),
    ("G2 X2 Y0 R1" + "0" * 90, "arc radius R1e+90"),
])
def test_gcode_beyond_the_machines_reach(line, what):
    """End points, arc centres and radii beyond MAX_COORDINATE_MM are refused on their line:
    an axis overflowing to inf would reach verify.json as Infinity, R1e200 give a NaN centre,
    an arc of radius 1e12 mm be cut into 22 million pieces."""
    raises_gcode(line, "line 4", what, "MAX_COORDINATE_MM=1e+06 mm")


def test_gcode_arc_segment_limit():
    """The chord count ceil(phi / (2 acos(1 - tol / r))) of a full circle of 900 m."""
    r, tol = 900_000.0, 1e-4
    chords = math.ceil(2 * math.pi / (2 * math.acos(1 - tol / r)))
    assert chords > gcode.MAX_ARC_SEGMENTS
    raises_gcode(f"G2 X1 Y0 I-{r - 1:.0f} J0", "line 4", f"needs {chords} chords",
                 f"MAX_ARC_SEGMENTS={gcode.MAX_ARC_SEGMENTS}", tolerance=tol)


def test_gcode_large_arc_within_limits_keeps_its_sagitta():
    """A 2 m radius half circle at 0.01 mm: sagitta of every chord within tolerance."""
    r, tol = 2000.0, 0.01
    program = read_gcode(f"G21 G90\nG0 X{r} Y0 Z0\nG3 X-{r} Y0 I-{r} J0 F100\nM2\n")
    seg = linearise(program, tol)
    assert len(seg) == math.ceil(math.pi / (2 * math.acos(1 - tol / r)))
    mid = (seg.start + seg.end) / 2
    sagitta = r - np.hypot(mid[:, 0], mid[:, 1])
    assert np.all(np.isfinite(seg.start)) and sagitta.max() <= tol * (1 + 1e-9)


def test_gcode_total_segment_limit(monkeypatch):
    monkeypatch.setattr(gcode, "MAX_SEGMENTS", 50)
    program = read_gcode("G21 G90\nG0 X10 Y0 Z0\nG3 X10 Y0 I-10 J0 F100\nM2\n", "c.ngc")
    with pytest.raises(GcodeError, match="c.ngc: the program needs .* MAX_SEGMENTS=50"):
        linearise(program, 1e-4)


@pytest.mark.parametrize("line", [
    "G1 X" + "1" * 40_000 + "Q",       # over a minute for a plain-move pattern quadratic in it
    "(" + "x" * 40_000 + ")",
])
def test_gcode_long_line(line):
    raises_gcode(line, "line 4", f"MAX_LINE_CHARS={gcode.MAX_LINE_CHARS}")


@pytest.mark.parametrize("line, message", [
    ("G1 X" + "1" * 4000 + "Q", "MAX_DIGITS"),
    ("G1 X" + "1." * 2000, "MAX_DIGITS"),
    ("G1 X" + "[" * 2000 + "1" + "]" * 2000, f"MAX_NESTING={gcode.MAX_NESTING}"),
    ("G1 X1" + " " * 4000 + "Q", "word 'Q' has no number"),
])
def test_gcode_long_lines_within_the_limit(line, message):
    raises_gcode(line, "line 4", message)


@pytest.mark.parametrize("separator", ["\x0c", "\x0b", "\x1c", "\x1d", "\x1e", "\x85",
                                       "\u2028", "\u2029"])
def test_gcode_line_separators_inside_comments(separator):
    """str.splitlines() split the line there: 'unbalanced comment parenthesis'."""
    program = read_gcode(f"{HEAD}(a{separator}b) G1 X2 ; c{separator}d\nG1 X3\nM2\n")
    np.testing.assert_array_equal(program.end[:, 0], [1, 2, 3])
    np.testing.assert_array_equal(program.line, [3, 4, 5])


def test_gcode_semicolon_inside_a_comment():
    program = read_gcode(f"{HEAD}(a;b) G1 X2 (c) ; (d\nM2\n")
    np.testing.assert_array_equal(program.end[:, 0], [1, 2])
    raises_gcode("(a (b) c) G1 X2", "line 4", "nested comment")


def test_gcode_long_parameter_chain_is_an_unknown_value():
    """``X####...#1`` is X set by a parameter of a parameter ...: unknown to the reader, and a
    chain of 4000 is read in no time (a masking quadratic in the chain's length is not)."""
    program = read_gcode(f"{HEAD}G1 X{'#' * 4000}1\nG1 X5 Y1\nG1 X6\nM2\n")
    np.testing.assert_array_equal(program.end[:, 0], [1, 6])  # no move from the unknown X
    np.testing.assert_array_equal(program.start[-1], [5, 1, 0])
    assert program.line[-1] == 6
    assert any("X is set by an expression" in w for w in program.warnings)


@pytest.mark.parametrize("line, char", [
    ("G1 X\u0663", "\u0663"),      # Arabic-Indic three: float() read it as 3
    ("G2 X2 Y0 \u0131-1 J0", "\u0131"),  # dotless i: upper() made it I
    ("G1 X\uff11", "\uff11"),       # full-width one
    ("G1 X\u00df", "\u00df"),       # sharp s: upper() made it SS
    ("G1 X1\u30000", "\u3000"),     # ideographic space: split() made it X10
    ("G1 X1 \u2028 Y2", "\u2028"),  # a line separator outside a comment
])
def test_gcode_non_ascii_outside_comments(line, char):
    raises_gcode(line, "line 4", repr(char), "ASCII")


@pytest.mark.parametrize("line, message", [
    ("G1.00001 X2", "unknown G code G1.00001"),
    ("G2 X1 Y0 I-1 J0 P3", "multi-turn arcs"),
    ("T1.5 M6", "tool number T1.5"),
    ("T-2 M6", "tool number T-2"),
])
def test_gcode_words_never_truncated(line, message):
    raises_gcode(line, "line 4", message)


def test_gcode_one_turn_p_and_whole_tools_pass():
    program = read_gcode(f"{HEAD}T2 M6\nG2 X1 Y0 I-1 J0 P1\nM2\n")
    assert program.tools == (2,) and program.kind[-1] == MoveKind.ARC_CW


def test_gcode_file_bom_crlf_cr(tmp_path):
    plain = f"{HEAD}G2 X3 Y2 R2\nG1 Y5\nM2\n"
    reference = read_gcode(plain)
    for text in (plain.replace("\n", "\r\n"), plain.replace("\n", "\r")):
        path = tmp_path / "p.ngc"
        path.write_bytes(b"\xef\xbb\xbf" + text.encode())
        program = read_gcode_file(str(path))
        np.testing.assert_array_equal(program.end, reference.end)
        np.testing.assert_array_equal(program.line, reference.line)


@pytest.mark.parametrize("data, message", [
    (b"G21\nG0 X0\n(\xe9)\nM2\n", "line 3: not a text file (invalid UTF-8 byte 0xe9)"),
    (b"G21\r\nG0 X0\r\n\r\nG1 \x00\r\nM2\r\n", "line 4: not a text file (contains NUL"),
])
def test_gcode_file_binary_names_the_line(tmp_path, data, message):
    path = tmp_path / "b.ngc"
    path.write_bytes(data)
    with pytest.raises(GcodeError, match=message.replace("(", r"\(").replace(")", r"\)")):
        read_gcode_file(str(path))


def test_gcode_file_size_limit(tmp_path, monkeypatch):
    monkeypatch.setattr(gcode, "MAX_PROGRAM_BYTES", 100)
    path = tmp_path / "big.ngc"
    path.write_text(HEAD * 20 + "M2\n")
    with pytest.raises(GcodeError, match="MAX_PROGRAM_BYTES=100"):
        read_gcode_file(str(path))


def test_gcode_arrays_stay_finite_at_the_limits():
    """Values just inside every limit: finite positions, centres and feeds (mm, mm/min)."""
    big = "9" * 6  # 999999 mm, inside the reach
    program = read_gcode(f"G21 G90\nG0 X0 Y0 Z0\nG1 X{big} F{'9' * 100}\nG1 Y{big}\n"
                         f"G2 X0 Y{big} I-{int(big) // 2} J0\nG20 G1 Z39370\nM2\n")
    for array in (program.start, program.end, program.feed[program.kind > 0],
                  program.centre[program.kind >= 2]):
        assert np.all(np.isfinite(array))
    segments = linearise(program, 0.01)
    assert np.all(np.isfinite(segments.start)) and np.all(np.isfinite(segments.end))
