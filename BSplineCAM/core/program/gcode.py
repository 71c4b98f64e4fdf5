# SPDX-License-Identifier: LGPL-2.1-or-later
"""Read the G-code that FreeCAD's post-processors emit into arrays of moves (mm, mm/min).

Covers what the linuxcnc, grbl, fanuc and mach3_mach4 posts write: G0/G1/G2/G3 (arcs by
I/J/K offsets or R), G17/G18/G19, G20/G21, G90/G91, G90.1/G91.1, F, S, T, M3/M4/M5, M6,
M7/M8/M9, G43 H, G54..G59, G40/G49/G80/G94/G98/G99/G61/G64, G4 dwell, G28/G30 (return to the
machine's home through an intermediate point), N numbers, ( ) and ; comments, % and M2/M30.
The semantics follow LinuxCNC's RS274NGC interpreter (Kramer, Proctor & Messina, "The NIST
RS274NGC Interpreter - Version 3", NISTIR 6556, 2000): words on one line are executed in the
order of section 3.8, not in the order written.  Anything else raises
:class:`GcodeError` naming the line, so a program is never half-understood.

A program in inches (G20) is converted to millimetres word by word;
``Program.converted_from_inches`` records that it happened.  The machine position is unknown
until the program sets every axis: no move is recorded from an unknown start (rs274 would
assume the origin, which lies inside the stock of most parts).  The same holds after G28/G30
(the home position is the machine's, not the program's) and after an axis word whose value is
a parameter expression, such as the tool-length line of FreeCAD 1.0's fanuc post,
``G91 G0 G43 G54 Z-[#[2000+#4120]] H#4120``: that axis is unknown until the program sets it
again, and ``Program.warnings`` says so.  Parameter assignments (``#1=...``) and expressions
in other words are refused.

Nothing non-finite comes out, and time and memory stay linear in the text: a line longer than
MAX_LINE_CHARS, a number with more than MAX_DIGITS digits, brackets nested deeper than
MAX_NESTING, a position, arc centre or radius beyond MAX_COORDINATE_MM (the machine's reach), a
character outside ASCII that is not in a comment, and an arc that :func:`linearise` would cut
into more than MAX_ARC_SEGMENTS chords (or a program into more than MAX_SEGMENTS pieces) raise
:class:`GcodeError` naming the line and the limit.  Lines end at LF, CR LF or CR only.

The moves (:class:`Program`, :class:`Segments`, :class:`MoveKind`) and the lexer of lines and
words live in :mod:`.gcode_words`; callers import them from here.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..geometry.netio import (  # noqa: F401  (MAX_NESTING re-exported, a limit of the reader)
    MAX_COORDINATE_MM,
    MAX_DIGITS,
    MAX_NESTING,
    read_text,
)
from ..typing import FloatArray
from .gcode_words import (
    _NUMBER,
    PLANE_AXES,
    GcodeError,
    MoveKind,
    Program,
    Segments,
    _arc_geometry,
    _excerpt,
    _parse_line,
    split_lines,
)

MM_PER_INCH = 25.4

# Limits on what the reader accepts (with MAX_DIGITS per number, MAX_NESTING of brackets and
# MAX_COORDINATE_MM, the machine's reach, shared with the net readers).  Time and memory stay
# linear in the program below them; the error that enforces one names it and its value.
#: Bytes in one program file (512 MiB).
MAX_PROGRAM_BYTES = 512 * 2**20
#: Characters on one line, comments included.
MAX_LINE_CHARS = 4096
#: Chords one arc may be cut into by :func:`linearise`.
MAX_ARC_SEGMENTS = 100_000
#: Straight pieces :func:`linearise` may return for a whole program.
MAX_SEGMENTS = 10_000_000
#: LinuxCNC's arc end-radius tolerance (mm absolute, and relative), rs274ngc interp_arc.cc.
ARC_RADIUS_TOLERANCE_MM = 0.05
ARC_RADIUS_TOLERANCE_REL = 0.001


# ---------------------------------------------------------------------------------------------
# reading

#: G codes accepted without effect on the geometry (cutter compensation off, tool length,
#: work offsets, canned cycle cancel, path control, feed mode per minute, return modes).
_G_IGNORED = {40.0, 43.0, 49.0, 54.0, 55.0, 56.0, 57.0, 58.0, 59.0, 61.0, 61.1, 64.0, 80.0,
              94.0, 98.0, 99.0}
_M_IGNORED = {0, 1, 3, 4, 5, 7, 8, 9}
_AXES = "XYZ"
_NO_CENTRE = (math.nan, math.nan, math.nan)
#: The line most programs are made of: [N..] [G0|G1] [X..] [Y..] [Z..] [F..], upper case, in
#: this order; read by :meth:`_State.simple_move` without the general word handling.
_SIMPLE_MOVE = re.compile(
    rf"\s*(?:N\d+\s*)?(?:G0?([01])(?![\d.])\s*)?(?:X({_NUMBER})\s*)?(?:Y({_NUMBER})\s*)?"
    rf"(?:Z({_NUMBER})\s*)?(?:F({_NUMBER})\s*)?",
    re.ASCII,
)


def read_gcode(text: str, source: str = "program", require_end: bool = True) -> Program:
    """Parse the text of a program into a :class:`Program` (mm).

    ``require_end``: a program that stops without M2/M30 or a closing % is taken as truncated.
    """
    state = _State(source)
    lines = split_lines(text[1:] if text.startswith("\ufeff") else text)
    percent_open = False
    simple = _SIMPLE_MOVE.fullmatch
    for lineno, raw in enumerate(lines, start=1):
        if len(raw) <= MAX_DIGITS:  # no number can be too long: the plain-move path is safe
            match = simple(raw)
            if match is not None and state.simple_move(match.groups(), lineno):
                continue
        elif len(raw) > MAX_LINE_CHARS:
            raise GcodeError(f"{source}: line {lineno}: longer than MAX_LINE_CHARS="
                             f"{MAX_LINE_CHARS} characters")
        stripped = raw.strip()
        if stripped.startswith("%"):
            if stripped.strip("% \t"):
                raise GcodeError(f"{source}: line {lineno}: text after '%': {_excerpt(stripped)}")
            if percent_open or state.moves_seen:
                state.ended = True
                break
            percent_open = True
            continue
        state.lineno = lineno
        state.execute(_parse_line(raw, source, lineno))
        if state.ended:
            break
    if require_end and not state.ended:
        raise GcodeError(
            f"{source}: the program ends at line {len(lines)} without M2, M30 or a closing %: "
            "truncated?"
        )
    return state.program()


def read_gcode_file(path: str, require_end: bool = True) -> Program:
    """Read a program file (UTF-8, a byte-order mark allowed); unreadable, undecodable or
    binary files and files over MAX_PROGRAM_BYTES raise GcodeError."""
    text = read_text(path, MAX_PROGRAM_BYTES, "MAX_PROGRAM_BYTES", GcodeError)
    return read_gcode(text, path, require_end)


class _State:
    """The interpreter's modal state while reading, and the moves so far."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.lineno = 0
        self.position: list[float | None] = [None, None, None]
        self.motion: int | None = None
        self.plane = 17
        self.scale = 1.0  # mm per program unit
        self.absolute = True
        self.arc_absolute = False
        self.feed = math.nan
        self.inches_seen = False
        self.ended = False
        self.moves_seen = False
        self.tools: list[int] = []
        self.selected_tool: int | None = None
        #: (index of the first move after the change, source line, tool) per M6
        self.changes: list[tuple[int, int, int]] = []
        self.moves: list[tuple] = []
        self.warnings: list[str] = []

    def error(self, message: str) -> GcodeError:
        return GcodeError(f"{self.source}: line {self.lineno}: {message}")

    def execute(self, words: list[tuple[str, float]]) -> None:
        if not words:
            return
        self.moves_seen = True
        values: dict[str, float] = {}
        g_codes: list[float] = []
        m_codes: list[int] = []
        for letter, value in words:
            if letter in "GM" and math.isnan(value):
                raise self.error(f"parameters and expressions are not supported in {letter}")
            if letter == "G":
                g = round(value, 1)
                if abs(value - g) > 1e-6:  # G1.00001 is no G1
                    raise self.error(f"unknown G code G{value!r}")
                g_codes.append(g)
            elif letter == "M":
                if value != int(value):
                    raise self.error(f"unknown M code M{value:g}")
                m_codes.append(int(value))
            elif letter == "N":
                continue
            elif letter in "XYZIJKRFSTPHDLQ":
                if letter in values:
                    raise self.error(f"word {letter} appears twice")
                if math.isnan(value) and letter not in "XYZHD":
                    raise self.error(f"parameters and expressions are not supported in {letter}")
                values[letter] = value
            elif letter in "ABCUVW":
                raise self.error(f"axis word {letter} not supported (3-axis programs only)")
            elif letter == "O":
                raise self.error("O-word subroutines and program numbers are not supported")
            else:
                raise self.error(f"unknown word {letter}{value:g}")
        motion = None
        home = None
        for g in g_codes:
            if g in (28.0, 30.0):
                home = int(g)
            elif g in (0.0, 1.0, 2.0, 3.0):
                if motion is not None:
                    raise self.error("two motion codes on one line")
                motion = int(g)
            elif g in (17.0, 18.0, 19.0):
                self.plane = int(g)
            elif g == 20.0:
                self.scale = MM_PER_INCH
                self.inches_seen = True
            elif g == 21.0:
                self.scale = 1.0
            elif g == 90.0:
                self.absolute = True
            elif g == 91.0:
                self.absolute = False
            elif g == 90.1:
                self.arc_absolute = True
            elif g == 91.1:
                self.arc_absolute = False
            elif g == 4.0:
                if "P" not in values:
                    raise self.error("G4 dwell without P")
            elif g in _G_IGNORED:
                continue
            elif g == 93.0:
                raise self.error("G93 inverse-time feed is not supported")
            elif 81.0 <= g <= 89.0:
                raise self.error(f"canned cycle G{g:g} is not supported")
            else:
                raise self.error(f"unknown or unsupported G code G{g:g}")
        for m in m_codes:
            if m not in _M_IGNORED and m not in (2, 6, 30):
                raise self.error(f"unknown or unsupported M code M{m}")
        if "F" in values:
            if values["F"] <= 0:
                raise self.error(f"feed F{values['F']:g} must be positive")
            self.feed = values["F"] * self.scale
        if "T" in values:
            tool = values["T"]
            if tool < 0 or tool != int(tool):
                raise self.error(f"tool number T{tool:g} is not a whole number >= 0")
            self.selected_tool = int(tool)
        if 6 in m_codes and self.selected_tool is not None:
            if self.selected_tool > 0:
                self.tools.append(self.selected_tool)
            self.changes.append((len(self.moves), self.lineno, self.selected_tool))
        if motion is not None:
            self.motion = motion
        if "P" in values and self.motion in (2, 3) and 4.0 not in g_codes and values["P"] != 1:
            raise self.error(f"G{self.motion} with P{values['P']:g}: multi-turn arcs are not "
                             "supported")
        has_axes = any(a in values for a in _AXES)
        if home is not None:
            if motion is not None:
                raise self.error(f"G{home} and a motion code on one line")
            self._home(home, values)
        elif motion is not None or (has_axes and 4.0 not in g_codes):
            if 4.0 in g_codes and motion is not None:
                raise self.error("G4 and a motion on one line")
            if self.motion is None:
                if has_axes:
                    raise self.error("axis words without a motion mode (G0/G1/G2/G3)")
            elif has_axes:
                self._move(values)
            elif self.motion in (2, 3):
                raise self.error(f"G{self.motion} without an end point (X/Y/Z)")
        elif any(k in values for k in "IJKR"):
            raise self.error("arc words I/J/K/R without G2/G3")
        if 2 in m_codes or 30 in m_codes:
            self.ended = True

    def simple_move(self, words: tuple[str | None, ...], lineno: int) -> bool:
        """Execute a plain G0/G1 line from its (G, X, Y, Z, F) words, when nothing about it
        needs the general path (absolute mode, known position, a feed for G1); returns
        whether it did.  The result is the same as :meth:`execute` would give."""
        g, x, y, z, f = words
        motion = self.motion if g is None else int(g)
        position = self.position
        if (not self.absolute or motion not in (0, 1) or (x is None and y is None and z is None)
                or None in position):
            return False
        feed = self.feed
        if f is not None:
            feed = float(f) * self.scale
            if not feed > 0:
                return False
        if motion == 1 and not math.isfinite(feed):
            return False
        scale = self.scale
        target = [position[0] if x is None else float(x) * scale,
                  position[1] if y is None else float(y) * scale,
                  position[2] if z is None else float(z) * scale]
        self.lineno = lineno
        self.moves_seen = True
        self.motion = motion
        self.feed = feed
        self.position = target
        if target != position:
            self.moves.append((motion, tuple(position), tuple(target), _NO_CENTRE, self.plane,
                               math.nan if motion == 0 else feed, lineno))
        return True

    def _home(self, code: int, values: dict[str, float]) -> None:
        """G28/G30: a rapid to the intermediate point the axis words give (if any), then the
        named axes (all, if none is named) go to the machine's home, unknown to the program."""
        if any(k in values for k in "IJKR"):
            raise self.error(f"arc words I/J/K/R with G{code}")
        named = [a for a, letter in enumerate(_AXES) if letter in values]
        # An incremental intermediate point from an unknown position is unknown too; the axis
        # goes home from there all the same.
        if named and (self.absolute or all(self.position[a] is not None for a in named)):
            target = self._target(values)
            start = self.position
            if None not in start and None not in target and target != start:
                self.moves.append((0, tuple(start), tuple(target), _NO_CENTRE, self.plane,
                                   math.nan, self.lineno))
            self.position = target
        homed = named or [0, 1, 2]
        for axis in homed:
            self.position[axis] = None
        self.warn(f"G{code} sends {''.join(_AXES[a] for a in homed)} to the machine's home; "
                  "moves are simulated again once the program sets every axis")

    def warn(self, message: str) -> None:
        text = f"{self.source}: line {self.lineno}: {message}"
        if len(self.warnings) < 20 and text not in self.warnings:
            self.warnings.append(text)

    def _target(self, values: dict[str, float]) -> list[float | None]:
        target = list(self.position)
        for axis, letter in enumerate(_AXES):
            if letter not in values:
                continue
            if math.isnan(values[letter]):
                target[axis] = None
                self.warn(f"{letter} is set by an expression; moves are simulated again once "
                          "the program sets every axis")
                continue
            value = values[letter] * self.scale
            if self.absolute:
                target[axis] = value
            elif self.position[axis] is None:
                raise self.error(f"incremental {letter} move (G91) from an unknown position")
            else:
                target[axis] = self.position[axis] + value
        return target

    def _move(self, values: dict[str, float]) -> None:
        target = self._target(values)
        start = self.position
        kind = self.motion
        arc = kind in (2, 3)
        if not arc and any(k in values for k in "IJKR"):
            raise self.error(f"arc words I/J/K/R with G{kind}")
        if kind != 0 and not math.isfinite(self.feed):
            raise self.error(f"G{kind} with no feed rate set (F)")
        known = all(v is not None for v in start)
        if arc and not known:
            raise self.error("arc from an unknown position: set X, Y and Z first")
        self.position = target
        if not known or any(v is None for v in target):
            return
        if arc:
            centre = tuple(self._arc_centre(values, np.array(start, dtype=float),
                                            np.array(target, dtype=float), kind))
        elif start == target:
            return
        else:
            centre = _NO_CENTRE
        feed = math.nan if kind == 0 else self.feed
        self.moves.append((kind, tuple(start), tuple(target), centre, self.plane, feed,
                           self.lineno))

    def _arc_centre(self, values: dict[str, float], start: FloatArray, end: FloatArray,
                    kind: int) -> FloatArray:
        a1, a2, normal = PLANE_AXES[self.plane]
        offset_letters = {17: "IJ", 18: "KI", 19: "JK"}[self.plane]
        s = np.array([start[a1], start[a2]])
        e = np.array([end[a1], end[a2]])
        centre = np.empty(3)
        centre[normal] = start[normal]
        if "R" in values:
            if any(k in values for k in "IJK"):
                raise self.error("arc with both R and I/J/K")
            radius = values["R"] * self.scale
            if abs(radius) > MAX_COORDINATE_MM:
                raise self.error(f"arc radius R{values['R']:g} is beyond the machine's reach "
                                 f"(MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm)")
            chord = e - s
            d = float(np.hypot(*chord))
            if d < 1e-9:
                raise self.error("R-form arc with the same start and end point (use I/J/K)")
            if d > 2 * abs(radius) + ARC_RADIUS_TOLERANCE_MM:
                raise self.error(
                    f"arc radius R{values['R']:g} is smaller than half the chord ({d / 2:.4f} mm)"
                )
            h = math.sqrt(max(radius * radius - d * d / 4.0, 0.0))
            left = np.array([-chord[1], chord[0]]) / d
            # the short arc (R > 0) has its centre left of the chord when counter-clockwise
            side = 1.0 if (kind == 3) == (radius > 0) else -1.0
            c = (s + e) / 2.0 + side * h * left
        else:
            if not any(k in values for k in offset_letters):
                raise self.error(
                    f"G{kind} in G{self.plane} needs {offset_letters[0]}/{offset_letters[1]} "
                    "or R"
                )
            off = np.array([values.get(k, 0.0) for k in offset_letters]) * self.scale
            c = off if self.arc_absolute else s + off
            r1 = float(np.hypot(*(s - c)))
            r2 = float(np.hypot(*(e - c)))
            if r1 < 1e-9:
                raise self.error("arc of zero radius")
            miss = abs(r1 - r2)
            if miss > ARC_RADIUS_TOLERANCE_MM and miss > ARC_RADIUS_TOLERANCE_REL * r1:
                raise self.error(
                    f"radius to the arc's end ({r2:.4f} mm) differs from radius to its start "
                    f"({r1:.4f} mm)"
                )
        centre[a1], centre[a2] = c
        return centre

    def program(self) -> Program:
        tool = np.zeros(len(self.moves), dtype=np.intp)
        for first, _, number in self.changes:
            tool[first:] = number
        if self.moves:
            kind, start, end, centre, plane, feed, line = zip(*self.moves)
        else:
            kind = start = end = centre = plane = feed = line = ()
        starts = np.array(start, dtype=float).reshape(-1, 3)
        ends = np.array(end, dtype=float).reshape(-1, 3)
        centres = np.array(centre, dtype=float).reshape(-1, 3)
        # a move's start is the previous end or a position read without a move: check all three
        for name, points in (("start point", starts), ("end point", ends),
                             ("arc centre", centres)):
            far = np.flatnonzero(np.any(np.abs(points) > MAX_COORDINATE_MM, axis=1))
            if len(far):
                self.lineno = line[far[0]]
                raise self.error(
                    f"{name} ({', '.join(f'{v:.6g}' for v in points[far[0]])}) mm is beyond the "
                    f"machine's reach (MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm)"
                )
        return Program(
            kind=np.array(kind, dtype=np.intp),
            start=starts,
            end=ends,
            centre=centres,
            plane=np.array(plane, dtype=np.intp),
            feed=np.array(feed, dtype=float),
            line=np.array(line, dtype=np.intp),
            source_units="in" if self.inches_seen else "mm",
            converted_from_inches=self.inches_seen,
            tools=tuple(self.tools),
            warnings=tuple(self.warnings),
            source=self.source,
            tool=tool,
            tool_changes=tuple((line, number) for _, line, number in self.changes),
        )


# ---------------------------------------------------------------------------------------------
# LinuxCNC canonical output, the independent reference

_CANON = re.compile(r"(STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED|SET_FEED_RATE|SELECT_PLANE|"
                    r"USE_LENGTH_UNITS|SELECT_TOOL|CHANGE_TOOL)\(([^)]*)\)")


def read_canonical(text: str) -> Program:
    """Moves from ``rs274 -g`` output (LinuxCNC's canonical machining functions).

    Used to check :func:`read_gcode` against LinuxCNC's own interpreter.  The first traverse
    starts from rs274's assumed origin, so like :func:`read_gcode` it only sets the position.
    ``CHANGE_TOOL`` loads the tool of the last ``SELECT_TOOL`` (its own argument, the pocket,
    if none was selected); the numbers are those of ``Program.tool``.
    """
    moves = []
    changes: list[tuple[int, int, int]] = []
    selected: int | None = None
    position: FloatArray | None = None
    plane = 17
    scale = 1.0
    feed = math.nan
    for lineno, raw in enumerate(text.splitlines(), start=1):
        match = _CANON.search(raw)
        if not match:
            continue
        name, args = match.group(1), match.group(2)
        if name == "USE_LENGTH_UNITS":
            scale = MM_PER_INCH if "INCHES" in args else 1.0
            continue
        if name == "SELECT_PLANE":
            plane = {"CANON_PLANE_XY": 17, "CANON_PLANE_XZ": 18, "CANON_PLANE_YZ": 19}[args.strip()]
            continue
        if name in ("SELECT_TOOL", "CHANGE_TOOL"):
            number = int(float(args.split(",")[0]))
            if name == "SELECT_TOOL":
                selected = number
            else:
                changes.append((len(moves), lineno, number if selected is None else selected))
            continue
        numbers = [float(v) for v in args.replace(",", " ").split()]
        if name == "SET_FEED_RATE":
            feed = numbers[0] * scale
            continue
        centre = np.full(3, np.nan)
        if name == "ARC_FEED":
            first_end, second_end, first_c, second_c, rotation, axis_end = numbers[:6]
            if abs(rotation) != 1:
                raise GcodeError(f"canonical line {lineno}: multi-turn arcs not supported")
            a1, a2, normal = PLANE_AXES[plane]
            end = np.empty(3)
            end[a1], end[a2], end[normal] = first_end, second_end, axis_end
            end *= scale
            centre[a1], centre[a2] = first_c * scale, second_c * scale
            kind = MoveKind.ARC_CCW if rotation > 0 else MoveKind.ARC_CW
        else:
            end = np.array(numbers[:3]) * scale
            kind = MoveKind.RAPID if name == "STRAIGHT_TRAVERSE" else MoveKind.LINE
        if position is not None and not (kind < 2 and np.array_equal(position, end)):
            if kind >= 2:
                centre[PLANE_AXES[plane][2]] = position[PLANE_AXES[plane][2]]
            f = math.nan if kind == MoveKind.RAPID else feed
            moves.append((int(kind), position, end, centre, plane, f, lineno))
        position = end
    state = _State("canonical")
    state.moves = moves
    state.changes = changes
    state.tools = [number for _, _, number in changes if number > 0]
    return state.program()


# ---------------------------------------------------------------------------------------------
# geometry


#: Largest sagitta (mm) of the chords that stand for arcs in a simulation: a chord inside a
#: convex arc lowers the tool by its sagitta, which verification would report as a gouge.
SIMULATION_ARC_SAGITTA_MM = 1e-4


def simulation_chord_tolerance(cell: float) -> float:
    """Chord tolerance (mm) for simulating arcs on a Z-map of ``cell`` mm: a tenth of the cell
    (the scallop's resolution), at most SIMULATION_ARC_SAGITTA_MM (well below the 1 um gouge
    bound), so one-sided arcs above the cutter-location curve simulate without fake gouges."""
    return min(cell / 10.0, SIMULATION_ARC_SAGITTA_MM)


def linearise(program: Program, tolerance: float) -> Segments:
    """Replace arcs by chords whose sagitta is at most ``tolerance`` (mm); lines pass through.

    The chord count of an arc of radius r and sweep phi is ceil(phi / (2 acos(1 - tol/r))).
    Radius and axial position vary linearly with the angle (LinuxCNC's helix and spiral).
    """
    if not tolerance > 0:
        raise ValueError(f"tolerance must be positive (mm), got {tolerance}")
    n = len(program)
    pieces = np.ones(n, dtype=np.intp)
    arcs = np.flatnonzero(program.kind >= MoveKind.ARC_CW)
    if len(arcs):
        sweep, radius, _ = _arc_geometry(program, arcs)
        half = np.arccos(np.clip(1.0 - tolerance / np.maximum(radius, 1e-12), -1.0, 1.0))
        wanted = np.maximum(1, np.ceil(np.abs(sweep) / (2 * np.maximum(half, 1e-9))))
        over = np.flatnonzero(~(wanted <= MAX_ARC_SEGMENTS))
        if len(over):
            a = arcs[over[0]]
            raise GcodeError(
                f"{program.source}: line {program.line[a]}: an arc of radius "
                f"{radius[over[0]]:.6g} mm needs "
                f"{wanted[over[0]]:.6g} chords for a sagitta of {tolerance:g} mm, more than "
                f"MAX_ARC_SEGMENTS={MAX_ARC_SEGMENTS}"
            )
        pieces[arcs] = wanted
    total = int(pieces.sum())
    if total > MAX_SEGMENTS:
        raise GcodeError(f"{program.source}: the program needs {total} straight pieces for a "
                         "chord tolerance of "
                         f"{tolerance:g} mm, more than MAX_SEGMENTS={MAX_SEGMENTS}")
    move = np.repeat(np.arange(n), pieces)
    first = np.cumsum(pieces) - pieces
    k = np.arange(len(move)) - first[move]
    frac0 = k / pieces[move]
    frac1 = (k + 1) / pieces[move]
    start = program.start[move] + frac0[:, None] * (program.end - program.start)[move]
    end = program.start[move] + frac1[:, None] * (program.end - program.start)[move]
    if len(arcs):
        is_arc = np.zeros(n, dtype=bool)
        is_arc[arcs] = True
        sel = is_arc[move]
        sweep_all = np.zeros(n)
        sweep_all[arcs] = sweep
        for code, (a1, a2, normal) in PLANE_AXES.items():
            rows = np.flatnonzero(sel & (program.plane[move] == code))
            if not len(rows):
                continue
            m = move[rows]
            c = program.centre[m]
            s = program.start[m]
            e = program.end[m]
            t0 = np.arctan2(s[:, a2] - c[:, a2], s[:, a1] - c[:, a1])
            r0 = np.hypot(s[:, a1] - c[:, a1], s[:, a2] - c[:, a2])
            r1 = np.hypot(e[:, a1] - c[:, a1], e[:, a2] - c[:, a2])
            for frac, out in ((frac0, start), (frac1, end)):
                f = frac[rows]
                t = t0 + f * sweep_all[m]
                r = r0 + f * (r1 - r0)
                out[rows, a1] = c[:, a1] + r * np.cos(t)
                out[rows, a2] = c[:, a2] + r * np.sin(t)
                out[rows, normal] = s[:, normal] + f * (e[:, normal] - s[:, normal])
    # the first piece of every move starts, and its last ends, exactly where the move does
    start[first] = program.start
    end[first + pieces - 1] = program.end
    return Segments(start=start, end=end, rapid=program.kind[move] == MoveKind.RAPID,
                    line=program.line[move], move=move)
