# SPDX-License-Identifier: LGPL-2.1-or-later
"""The moves a G-code program is read into, and the lexer of its text.

:class:`Program` (moves in machine order, mm and mm/min), :class:`Segments` (straight pieces
to simulate), :class:`MoveKind`, ``PLANE_AXES`` and :class:`GcodeError`; :func:`split_lines`
cuts a program into lines as LinuxCNC does and ``_parse_line`` a line into (letter, value)
words, comments removed and parameter expressions masked as unknown values.  The reader that
executes the words, :func:`BSplineCAM.core.program.gcode.read_gcode`, builds on them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from ..errors import BSplineCAMError
from ..geometry.netio import MAX_DIGITS, MAX_NESTING
from ..typing import FloatArray, IntArray


class GcodeError(BSplineCAMError):
    """A program that cannot be read; the message names the line."""


class MoveKind(IntEnum):
    """Motion of one move; the arcs' sense is that of the active plane's (first, second) axes."""

    RAPID = 0
    LINE = 1
    ARC_CW = 2
    ARC_CCW = 3


#: Plane code -> (first axis, second axis, normal axis) as indices into (x, y, z); right-handed.
PLANE_AXES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}


@dataclass(frozen=True)
class Program:
    """Moves of a program in machine order; all lengths mm, feeds mm/min (NaN for rapids).

    ``centre`` holds arc centres (NaN rows for straight moves); ``plane`` the plane code of
    each arc (17, 18 or 19); ``line`` the 1-based source line of each move.  ``tool`` is the
    number of the tool loaded by the last tool change (M6) before each move, 0 before the
    first; ``tool_changes`` lists each change as (source line, tool number).
    """

    kind: IntArray
    start: FloatArray
    end: FloatArray
    centre: FloatArray
    plane: IntArray
    feed: FloatArray
    line: IntArray
    source_units: str = "mm"
    converted_from_inches: bool = False
    tools: tuple[int, ...] = ()
    warnings: tuple[str, ...] = field(default=(), compare=False)
    #: The file (or name) the program was read from, for error messages.
    source: str = field(default="program", compare=False)
    tool: IntArray | None = field(default=None, compare=False)
    tool_changes: tuple[tuple[int, int], ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        if self.tool is None:
            object.__setattr__(self, "tool", np.zeros(len(self.kind), dtype=np.intp))

    def __len__(self) -> int:
        return int(len(self.kind))

    def lengths(self) -> FloatArray:
        """Path length of each move (mm): chord for lines, helix length for arcs."""
        length = np.linalg.norm(self.end - self.start, axis=1)
        arcs = np.flatnonzero(self.kind >= MoveKind.ARC_CW)
        if len(arcs):
            sweep, radius, axial = _arc_geometry(self, arcs)
            length[arcs] = np.hypot(np.abs(sweep) * radius, axial)
        return length


@dataclass(frozen=True)
class Segments:
    """Straight pieces to simulate: arcs replaced by chords; ``move`` indexes the Program."""

    start: FloatArray
    end: FloatArray
    rapid: np.ndarray
    line: IntArray
    move: IntArray

    def __len__(self) -> int:
        return int(len(self.move))


# ---------------------------------------------------------------------------------------------
# lexing

#: Stands for the value of a parameter expression (unknown to the reader) once it is masked.
_UNKNOWN_MARK = "?"
#: A number as G-code writes it; one way only to match each (no backtracking blow-up).
_NUMBER = r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)"
_WORD = re.compile(rf"([A-Z])({_NUMBER}|[+-]?\?)|(.)", re.ASCII | re.DOTALL)
_DIGITS = re.compile(r"[\d.]+", re.ASCII)
_COMMENT = re.compile(r"\([^()]*\)")
_FAST_WORD = re.compile(rf"([A-Z])({_NUMBER})", re.ASCII)


def _excerpt(text: str, limit: int = 60) -> str:
    """``text`` for an error message: repr, cut to about ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"... ({len(text)} characters)"


def split_lines(text: str) -> list[str]:
    """Lines of a program as LinuxCNC reads them: ended by LF, CR LF or CR only, so that a form
    feed or a Unicode line separator inside a comment stays in its line."""
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines[-1] == "":
        lines.pop()
    return lines


def _strip_comments(raw: str, source: str, lineno: int) -> str:
    """The line without its ( ) comments and what follows a ';' outside them."""
    text = _COMMENT.sub(" ", raw) if "(" in raw else raw
    text = text.split(";", 1)[0]
    if "(" in text or ")" in text:
        _comment_error(raw, source, lineno)
    return text


def _comment_error(raw: str, source: str, lineno: int) -> None:
    """Raise the error of a line whose comments do not close, or nest (left to right, as
    LinuxCNC reads them)."""
    pos = 0
    while True:
        opening = raw.find("(", pos)
        semicolon = raw.find(";", pos)
        closing = raw.find(")", pos)
        stop = min(i for i in (opening, semicolon, len(raw)) if i >= 0)
        if 0 <= closing < stop:
            raise GcodeError(f"{source}: line {lineno}: unbalanced comment parenthesis")
        if stop != opening:
            break
        end = raw.find(")", opening + 1)
        if end < 0:
            raise GcodeError(f"{source}: line {lineno}: unbalanced comment parenthesis")
        if "(" in raw[opening + 1:end]:
            raise GcodeError(f"{source}: line {lineno}: nested comment parenthesis")
        pos = end + 1
    raise GcodeError(f"{source}: line {lineno}: unbalanced comment parenthesis")


def _parse_line(raw: str, source: str, lineno: int) -> list[tuple[str, float]]:
    """Words of one line as (letter, value), comments and block delete removed."""
    text = _strip_comments(raw, source, lineno) if "(" in raw or ";" in raw or ")" in raw else raw
    if not text.isascii():  # before white space goes: X1\u30000 is no X10
        bad = next(c for c in text if not c.isascii())
        raise GcodeError(f"{source}: line {lineno}: character {bad!r} outside a comment "
                         f"(G-code is ASCII): {_excerpt(text.strip())}")
    text = "".join(text.split()).upper()
    if text.startswith("/"):
        text = text[1:]
    if _UNKNOWN_MARK in text:  # the marker of masked expressions is no G-code character
        raise GcodeError(f"{source}: line {lineno}: cannot read {_excerpt(text)}")
    if len(text) > MAX_DIGITS:
        longest = max((len(d) - d.count(".") for d in _DIGITS.findall(text)), default=0)
        if longest > MAX_DIGITS:
            raise GcodeError(f"{source}: line {lineno}: a number has more than MAX_DIGITS="
                             f"{MAX_DIGITS} digits")
    if any(c in text for c in "#[]<>"):
        text = _mask_expressions(text, source, lineno)
    words = _FAST_WORD.findall(text)
    if sum(len(a) + len(b) for a, b in words) == len(text):
        return [(a, float(b)) for a, b in words]
    words = []
    for match in _WORD.finditer(text):
        if match.group(3) is not None:
            rest = _excerpt(text[match.start():])
            bad = match.group(3)
            if bad.isalpha():
                raise GcodeError(f"{source}: line {lineno}: word {bad!r} has no number: {rest}")
            raise GcodeError(f"{source}: line {lineno}: cannot read {rest}")
        value = match.group(2)
        unknown = value.lstrip("+-") == _UNKNOWN_MARK
        words.append((match.group(1), math.nan if unknown else float(value)))
    return words


def _mask_expressions(text: str, source: str, lineno: int) -> str:
    """Replace each parameter expression used as a word's value (``#4120``, ``[#[2000+#1]]``)
    by a marker read as an unknown value; anything else with ``#``, brackets or ``<>`` (an
    assignment, a named parameter, a stray bracket) is refused."""
    # One pass, innermost first as the NIST grammar nests them: ``#`` + digits, ``#`` + an
    # unknown and a bracket holding no bracket each become the marker; linear in the line.
    out: list[str] = []
    opened: list[int] = []
    pos, size = 0, len(text)
    while pos < size:
        c = text[pos]
        pos += 1
        if c == "[":
            if len(opened) >= MAX_NESTING:
                raise GcodeError(f"{source}: line {lineno}: brackets nested deeper than "
                                 f"MAX_NESTING={MAX_NESTING}")
            opened.append(len(out))
            out.append(c)
            continue
        if c == "]" and opened:
            del out[opened.pop():]
        elif c.isdigit() and out and out[-1] == "#":
            while pos < size and text[pos].isdigit():
                pos += 1
            out.pop()
        else:
            out.append(c)
            continue
        while out and out[-1] == "#":  # a parameter numbered by an expression
            out.pop()
        out.append(_UNKNOWN_MARK)
    masked = "".join(out)
    stray_mark = re.search(r"(?<![A-Z+-])" + re.escape(_UNKNOWN_MARK), masked)
    if any(c in masked for c in "#[]<>=") or stray_mark:
        raise GcodeError(
            f"{source}: line {lineno}: parameters and expressions are not supported: "
            f"{_excerpt(text)}"
        )
    return masked


# ---------------------------------------------------------------------------------------------
# geometry


def _arc_geometry(program: Program, index: IntArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Signed sweep (rad, + counter-clockwise), start radius (mm) and axial travel of arcs."""
    sweep = np.empty(len(index))
    radius = np.empty(len(index))
    axial = np.empty(len(index))
    for code, (a1, a2, normal) in PLANE_AXES.items():
        sel = program.plane[index] == code
        if not np.any(sel):
            continue
        i = index[sel]
        c = program.centre[i]
        s = program.start[i]
        e = program.end[i]
        t0 = np.arctan2(s[:, a2] - c[:, a2], s[:, a1] - c[:, a1])
        t1 = np.arctan2(e[:, a2] - c[:, a2], e[:, a1] - c[:, a1])
        ccw = np.mod(t1 - t0, 2 * np.pi)
        cw = np.mod(t0 - t1, 2 * np.pi)
        ccw = np.where(ccw < 1e-12, 2 * np.pi, ccw)
        cw = np.where(cw < 1e-12, 2 * np.pi, cw)
        sweep[sel] = np.where(program.kind[i] == MoveKind.ARC_CCW, ccw, -cw)
        radius[sel] = np.hypot(s[:, a1] - c[:, a1], s[:, a2] - c[:, a2])
        axial[sel] = e[:, normal] - s[:, normal]
    return sweep, radius, axial
