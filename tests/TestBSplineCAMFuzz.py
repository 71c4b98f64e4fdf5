# SPDX-License-Identifier: LGPL-2.1-or-later
"""Fuzz the readers: any input gives finite data or the project's error, never a hang.

Hypothesis mutates valid JSON, CSV and .dat nets and G-code programs (inserted separators,
BOMs, NUL and invalid UTF-8 bytes, NaN/Infinity literals, numbers of hundreds or thousands of
digits, deep nesting, long lines, duplicated and cut text) and builds G-code from a grammar of
words and extreme numbers.  The property for every reader: it returns finite data inside the
limits (points within MAX_COORDINATE_MM, a net of at least 4x4; moves, centres and feeds
finite, arcs linearised into finite chords that join end to end) or raises BSplineCAMError
with a one-line message naming the source.  Anything else (another exception, a non-finite
value) fails, and so does a call that runs longer than HANG_S: a hang guard for inputs of at
most a few hundred kilobytes, generous enough never to trip on a slow machine (a quadratic
reader needs minutes on the inputs drawn here).  The examples are derandomised so that CI
runs the same cases each time; the suite is sized to about 30 s per interpreter.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import FUZZ, hang_guard
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core.errors import BSplineCAMError
from BSplineCAM.core.geometry import netio
from BSplineCAM.core.program.gcode import (
    MoveKind,
    Program,
    linearise,
    read_gcode,
    read_gcode_file,
)

# ---------------------------------------------------------------------------------------------
# mutations

PAYLOADS = [
    "\x00", "\ufeff", "\r", "\r\n", "\n", "\x0c", "\x0b", "\x1c", "\u2028", "\x85", "\t", " ",
    "\u00e9", "\u0663", "\u0131", "\u00df", "\uff11", "\ud800",
    "[", "]", "{", "}", "#", "(", ")", ";", '"', "\\", ",", ":", ".", "-", "+", "e", "E", "%",
    "NaN", "Infinity", "-Infinity", "nan", "inf", "-inf", "1e400", "-1e400", "1e-400", "1e308",
    "1e6", "1e12", "9" * 101, "9" * 400, "9" * 5000, "0." + "0" * 150 + "1", "1_0", "0x1F",
    "[" * 100, "]" * 100, '{"a":' * 70, "null", "true", '"x"',
    "G0", "G1", "G2", "G3", "G91", "G20", "G18", "G28", "R", "I", "J", "K", "P3", "T", "M6",
    "F", "X", "Y", "Z", "N", "S", "#1", "[#2]", "M2", "%",
    '"control_points":', '"name":', "100000", "99999999", "-1", "# rows=", "row,column,x,y,z",
    "X1" * 3000, " " * 5000, "#" * 3000, "(x" * 100, "1" * 40_000,
]
BYTES = [b"\xff", b"\xc3", b"\xed\xa0\x80", b"\x80", b"\xef\xbb\xbf", b"\x00"]

_OPS = st.tuples(
    st.sampled_from(["insert", "replace", "delete", "duplicate", "truncate", "repeat"]),
    st.floats(0.0, 1.0),
    st.integers(0, 40),
    st.one_of(st.sampled_from(PAYLOADS), st.text(max_size=6)),
)
MUTATIONS = st.lists(_OPS, min_size=1, max_size=6)
BYTE_MUTATIONS = st.lists(st.tuples(st.floats(0.0, 1.0), st.sampled_from(BYTES)), max_size=2)


def mutate(text: str, ops) -> str:
    for op, where, length, payload in ops:
        at = int(where * len(text))
        if op == "insert":
            text = text[:at] + payload + text[at:]
        elif op == "replace":
            text = text[:at] + payload + text[at + max(length, 1):]
        elif op == "delete":
            text = text[:at] + text[at + length:]
        elif op == "duplicate":
            text = text[:at] + text[at:at + 64 * length] + text[at:]
        elif op == "truncate":
            text = text[:at]
        else:  # repeat a short piece many times: long lines, deep nesting, many points
            piece = text[at:at + max(length // 4, 1)]
            text = text[:at] + piece * 2000 + text[at:]
    return text


def encode(text: str, byte_ops) -> bytes:
    data = text.encode("utf-8", "surrogatepass")
    for where, piece in byte_ops:
        at = int(where * len(data))
        data = data[:at] + piece + data[at:]
    return data


# ---------------------------------------------------------------------------------------------
# properties


def assert_project_error(exc: BSplineCAMError, source: str) -> None:
    message = str(exc)
    assert "\n" not in message and source in message, message
    assert len(message) < 2000, message[:200]


def check_net(path) -> None:
    """read_net gives a finite net inside the limits, or the project's error naming the file."""
    try:
        with hang_guard():
            net = netio.read_net(path)
    except BSplineCAMError as exc:
        assert_project_error(exc, str(path))
        return
    points = net.points
    assert points.ndim == 3 and points.shape[2] == 3
    assert points.shape[0] >= netio.MIN_POINTS and points.shape[1] >= netio.MIN_POINTS
    assert np.all(np.isfinite(points)) and np.abs(points).max() <= netio.MAX_COORDINATE_MM
    assert isinstance(net.name, str)


def check_program(program: Program, tolerance: float) -> None:
    """Moves finite; arcs linearised into finite chords joining each move's ends, or the
    project's error."""
    arcs = program.kind >= MoveKind.ARC_CW
    for array in (program.start, program.end, program.centre[arcs]):
        assert np.all(np.isfinite(array))
        assert array.size == 0 or np.abs(array).max() <= netio.MAX_COORDINATE_MM
    feeds = program.feed[program.kind != MoveKind.RAPID]
    assert np.all(np.isfinite(feeds)) and np.all(feeds > 0)
    try:
        with hang_guard():
            segments = linearise(program, tolerance)
    except BSplineCAMError as exc:
        assert_project_error(exc, program.source)
        return
    assert np.all(np.isfinite(segments.start)) and np.all(np.isfinite(segments.end))
    if len(segments):
        first = np.r_[True, segments.move[1:] != segments.move[:-1]]
        last = np.r_[segments.move[1:] != segments.move[:-1], True]
        np.testing.assert_array_equal(segments.start[first], program.start[segments.move[first]])
        np.testing.assert_array_equal(segments.end[last], program.end[segments.move[last]])
        inner = ~last[:-1]
        scale = 1.0 + np.abs(segments.end[:-1][inner]).max(initial=0.0)
        assert np.abs(segments.end[:-1][inner] - segments.start[1:][inner]).max(
            initial=0.0) <= 1e-9 * scale


def check_gcode_text(text: str, tolerance: float = 0.01) -> None:
    try:
        with hang_guard():
            program = read_gcode(text, "fuzz.ngc")
    except BSplineCAMError as exc:
        assert_project_error(exc, "fuzz.ngc")
        return
    check_program(program, tolerance)


# ---------------------------------------------------------------------------------------------
# seeds

_rng = np.random.default_rng(20261201)
SEED_NET = np.round(_rng.normal(scale=30.0, size=(4, 5, 3)), 3)
SEED_JSON = json.dumps({"name": "seed", "units": "mm", "knots": "clamped",
                        "control_points": SEED_NET.tolist()}, indent=1)
SEED_CSV = "row,column,x,y,z\n" + "".join(
    f"{i},{j},{x!r},{y!r},{z!r}\n" for (i, j) in np.ndindex(4, 5)
    for x, y, z in [SEED_NET[i, j].tolist()])
SEED_DAT = "# seed\n# rows=4 columns=5\n" + "".join(
    f"{x:.12g} {y:.12g} {z:.12g}\n" for x, y, z in SEED_NET.reshape(-1, 3).tolist())
SEED_GCODE = """%
(Exported by FreeCAD; post: linuxcnc)
N100 G17 G54 G40 G49 G80 G90
N110 G21
N120 M6 T1
N130 G43 H1
N140 M3 S10000
N150 G0 Z15.000
N160 G0 X10.000 Y5.000
N170 G1 X10.000 Y5.000 Z-1.000 F300.000 ; plunge
N180 G1 X30.000 Y5.000 Z-1.000 F600.000
N190 G2 X40.000 Y15.000 I0.000 J10.000
N200 G3 X30.000 Y25.000 R10.000
N210 G18 G2 X20 Z-1 I-5 K0
N220 G17 G91 G1 X-5 Y-5
N230 G90 G20 G1 X0.5 Y0.5
N240 G21 G0 Z15.000
N250 G28
N260 M5
N270 M2
%
"""


@pytest.mark.parametrize("suffix, seed", [(".json", SEED_JSON), (".csv", SEED_CSV),
                                          (".dat", SEED_DAT)], ids=["json", "csv", "dat"])
def test_seeds_are_read(tmp_path, suffix, seed):
    """The unmutated seeds are valid: the fuzzing starts from inputs the readers accept."""
    path = tmp_path / f"seed{suffix}"
    path.write_text(seed)
    np.testing.assert_allclose(netio.read_net(path).points, SEED_NET, atol=1e-9)
    program = read_gcode(SEED_GCODE)
    assert len(program) >= 7 and program.converted_from_inches


@pytest.mark.parametrize("suffix, seed", [(".json", SEED_JSON), (".csv", SEED_CSV),
                                          (".dat", SEED_DAT)], ids=["json", "csv", "dat"])
@settings(FUZZ, max_examples=120)
@given(ops=MUTATIONS, byte_ops=BYTE_MUTATIONS)
def test_fuzz_net_readers(tmp_path, suffix, seed, ops, byte_ops):
    path = tmp_path / f"fuzz{suffix}"
    path.write_bytes(encode(mutate(seed, ops), byte_ops))
    check_net(path)


_JSON_NUMBERS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(10**400), max_value=10**400),
    st.sampled_from([0, -0.0, 1e-320, 1e6, 1e6 + 1, -1e6, 5e307]),
)
_JSON_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), _JSON_NUMBERS, st.text(max_size=5)),
    lambda inner: st.one_of(st.lists(inner, max_size=6),
                            st.dictionaries(st.text(max_size=4), inner, max_size=4)),
    max_leaves=40,
)
_POINTS = st.lists(st.lists(st.lists(_JSON_NUMBERS, min_size=3, max_size=3), min_size=4,
                            max_size=5), min_size=4, max_size=5)


@settings(FUZZ, max_examples=80)
@given(points=st.one_of(_POINTS, _JSON_VALUES),
       header=st.dictionaries(st.sampled_from(["name", "units", "knots", "extra"]), _JSON_VALUES,
                              max_size=3))
def test_fuzz_json_documents(tmp_path, points, header):
    path = tmp_path / "doc.json"
    path.write_text(json.dumps({**header, "control_points": points}))
    check_net(path)


@settings(FUZZ, max_examples=200)
@given(ops=MUTATIONS)
def test_fuzz_gcode_text(ops):
    check_gcode_text(mutate(SEED_GCODE, ops))


@settings(FUZZ, max_examples=80)
@given(ops=MUTATIONS, byte_ops=BYTE_MUTATIONS)
def test_fuzz_gcode_file(tmp_path, ops, byte_ops):
    path = tmp_path / "fuzz.ngc"
    path.write_bytes(encode(mutate(SEED_GCODE, ops), byte_ops))
    try:
        with hang_guard():
            program = read_gcode_file(str(path))
    except BSplineCAMError as exc:
        assert_project_error(exc, str(path))
        return
    check_program(program, 0.01)


# A grammar of G-code lines: modal codes, motions and words with ordinary and extreme numbers.
_NUMBER_TEXT = st.one_of(
    st.floats(-200.0, 200.0, allow_nan=False).map(lambda v: f"{v:.4f}"),
    st.integers(-200, 200).map(str),
    st.sampled_from(["0", "-0", ".5", "1.", "+3", "999999", "-999999.9", "1000001",
                     "0.0000001", "9" * 100, "9" * 101, "1" + "0" * 30, "00000000000001"]),
)
_WORDS = st.tuples(st.sampled_from("XYZIJKRFPTSN"), _NUMBER_TEXT).map("".join)
_MODES = st.sampled_from(["G0", "G1", "G2", "G3", "G17", "G18", "G19", "G20", "G21", "G90",
                          "G91", "G90.1", "G91.1", "G28", "G4 P1", "M3", "M6", "T1", ""])
_LINES = st.lists(st.tuples(_MODES, st.lists(_WORDS, max_size=5)).map(
    lambda t: " ".join([t[0], *t[1]])), max_size=15)


@settings(FUZZ, max_examples=150)
@given(lines=_LINES, tolerance=st.sampled_from([1e-4, 0.001, 0.01, 0.1, 10.0]))
def test_fuzz_gcode_grammar(lines, tolerance):
    text = "G21 G90 G17 F500\nG0 X0 Y0 Z10\n" + "\n".join(lines) + "\nM2\n"
    check_gcode_text(text, tolerance)


@settings(FUZZ, max_examples=80)
@given(x=st.floats(-1e6, 1e6), y=st.floats(-1e6, 1e6), i=st.floats(-1e6, 1e6),
       j=st.floats(-1e6, 1e6), r=st.floats(-2e6, 2e6), z=st.floats(-100, 100),
       tolerance=st.sampled_from([1e-4, 0.01, 1.0]), ccw=st.booleans())
def test_fuzz_arc_linearisation(x, y, i, j, r, z, tolerance, ccw):
    """Arcs anywhere within the machine's reach, by I/J and by R: finite chords, or the
    project's error (unreachable end point, too many chords)."""
    code = "G3" if ccw else "G2"
    for words in (f"I{i:.6f} J{j:.6f}", f"R{r:.6f}"):
        text = f"G21 G90\nG0 X0 Y0 Z0\n{code} X{x:.6f} Y{y:.6f} Z{z:.4f} {words} F100\nM2\n"
        check_gcode_text(text, tolerance)
    radius = math.hypot(i, j)
    if radius > 1e-3:  # a full circle of that radius: the chord count of the closed form
        text = f"G21 G90\nG0 X0 Y0 Z0\n{code} X0 Y0 I{i:.6f} J{j:.6f} F100\nM2\n"
        check_gcode_text(text, tolerance)
