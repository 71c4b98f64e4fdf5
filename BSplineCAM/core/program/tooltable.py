# SPDX-License-Identifier: LGPL-2.1-or-later
"""Tools by number (mm) for simulating a program with tool changes (M6).

Two sources: the ``--tools`` option (``T1=flat:10,T2=ball:6,T3=bullnose:10:1``, shape, diameter
and for a bull-nose the corner radius, mm) and a LinuxCNC tool table, one tool a line
(``T1 P1 D10.0 Z+0.0 ;flat end mill``): words in any order, a letter and a number each, what
follows ``;`` a comment (LinuxCNC Integrator Manual, "Tool Table Format").  The shape comes from
the comment: ``ball`` (or ``ballnose``), ``bull`` / ``bullnose`` with the corner radius as
``r1.5`` or ``R1.5``; anything else is a flat end mill.  D is read as mm.

The table reader is bounded like the net and G-code readers: files over MAX_TABLE_BYTES,
lines over MAX_LINE_CHARS, numbers over MAX_DIGITS digits or beyond MAX_COORDINATE_MM, tool
numbers over MAX_TOOL_NUMBER and more than MAX_TOOLS tools raise a :class:`ToolTableError`
naming the file, the line and the word.
"""

from __future__ import annotations

import math
import os
import re

import numpy as np

from ..errors import ParameterError
from ..geometry.netio import MAX_COORDINATE_MM, MAX_DIGITS, read_text
from ..simulation.simulate import Tool, ToolShape
from ..toolpath.common import MAX_TOOL_DIAMETER, MIN_TOOL_DIAMETER
from .gcode import MoveKind, Program

#: Bytes in one tool-table file (1 MiB).
MAX_TABLE_BYTES = 2**20
#: Characters in one line of a table, comment included, or in a ``--tools`` option.
MAX_LINE_CHARS = 4096
#: Largest tool number (LinuxCNC's tool numbers are 32-bit; no shop has more than this).
MAX_TOOL_NUMBER = 99_999
#: Tools in one table or option.
MAX_TOOLS = 10_000
#: Word letters of a LinuxCNC tool-table line: tool, pocket, offsets, diameter, angles,
#: orientation.
_TABLE_LETTERS = "TPXYZABCUVWDIJQ"
_NUMBER = re.compile(r"[+-]?(?:\d+(?:\.\d*)?|\.\d+)", re.ASCII)
_WORD = re.compile(r"\s*([A-Za-z])\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+))?", re.ASCII)
_BALL = re.compile(r"(?<![a-z])ball(?:[- _]?nose)?(?![a-z])")
_BULL = re.compile(r"(?<![a-z])bull(?:[- _]?nose)?(?![a-z])")
_CORNER = re.compile(r"(?<![a-z])r\s*=?\s*(\d+(?:\.\d*)?|\.\d+)")


class ToolTableError(ParameterError):
    """A tool table or ``--tools`` option that cannot be read; the message names the place."""


def _number(text: str, where: str, word: str) -> float:
    digits = sum(c.isdigit() for c in text)
    if digits > MAX_DIGITS:
        raise ToolTableError(f"{where}: {word}: a number has more than MAX_DIGITS={MAX_DIGITS} "
                             "digits")
    value = float(text)
    if not (math.isfinite(value) and abs(value) <= MAX_COORDINATE_MM):
        raise ToolTableError(f"{where}: {word}: {value:g} is beyond MAX_COORDINATE_MM="
                             f"{MAX_COORDINATE_MM:g} mm")
    return value


def _tool_number(value: float, where: str, word: str) -> int:
    if value != int(value) or not 0 <= value <= MAX_TOOL_NUMBER:
        raise ToolTableError(f"{where}: {word}: tool number must be a whole number in "
                             f"[0, {MAX_TOOL_NUMBER}]")
    return int(value)


def _make_tool(diameter: float, shape: ToolShape, corner: float, where: str) -> Tool:
    if not MIN_TOOL_DIAMETER <= diameter <= MAX_TOOL_DIAMETER:
        raise ToolTableError(f"{where}: diameter must lie in [{MIN_TOOL_DIAMETER:g}, "
                             f"{MAX_TOOL_DIAMETER:g}] mm, got {diameter:g} mm")
    try:
        return Tool(float(diameter), shape, float(corner))
    except ParameterError as exc:
        raise ToolTableError(f"{where}: {exc}") from None


def parse_tools_option(text: str, option: str = "--tools") -> dict[int, Tool]:
    """Tools from ``T1=flat:10,T2=ball:6,T3=bullnose:10:1`` (shape:diameter[:corner radius],
    mm; ``T`` optional, ``bull`` for bullnose); a ToolTableError names ``option`` and the item."""
    if not isinstance(text, str) or not text.strip():
        raise ToolTableError(f"{option}: expected T<n>=<shape>:<diameter mm>[:<corner radius "
                             f"mm>], ... got {text!r}")
    if len(text) > MAX_LINE_CHARS:
        raise ToolTableError(f"{option}: longer than MAX_LINE_CHARS={MAX_LINE_CHARS} characters")
    tools: dict[int, Tool] = {}
    for item in text.split(","):
        item = item.strip()
        where = f"{option} {item!r}"
        number, sep, spec = item.partition("=")
        number = number.strip()
        if number[:1] in "Tt":
            number = number[1:]
        parts = [p.strip() for p in spec.split(":")]
        if not sep or not re.fullmatch(r"\d{1,6}", number, re.ASCII) or not 2 <= len(parts) <= 3:
            raise ToolTableError(f"{where}: expected T<n>=<shape>:<diameter mm>[:<corner radius "
                                 "mm>], e.g. T1=flat:10 or T3=bullnose:10:1")
        n = _tool_number(float(number), where, "T")
        if n in tools:
            raise ToolTableError(f"{where}: tool T{n} is given twice")
        if len(tools) >= MAX_TOOLS:
            raise ToolTableError(f"{option}: more than MAX_TOOLS={MAX_TOOLS} tools")
        tools[n] = parse_tool_spec(spec, where)
    return tools


def parse_tool_spec(spec: str, where: str) -> Tool:
    """A tool from ``shape:diameter[:corner radius]`` (mm; ``bull`` for bullnose); a
    ToolTableError starts with ``where`` (the option and the item)."""
    parts = [p.strip() for p in spec.split(":")]
    if not 2 <= len(parts) <= 3:
        raise ToolTableError(f"{where}: expected <shape>:<diameter mm>[:<corner radius mm>], "
                             "e.g. flat:10 or bullnose:10:1")
    shape_name = parts[0].lower()
    shape_name = "bullnose" if shape_name in ("bull", "bull-nose") else shape_name
    try:
        shape = ToolShape.parse(shape_name)
    except ParameterError as exc:
        raise ToolTableError(f"{where}: {exc}") from None
    values = []
    for p, name in zip(parts[1:], ("diameter", "corner radius")):
        if not _NUMBER.fullmatch(p):
            raise ToolTableError(f"{where}: {name} {p!r} is not a number (mm)")
        values.append(_number(p, where, name))
    corner = values[1] if len(values) > 1 else 0.0
    if shape is ToolShape.BULLNOSE and len(values) < 2:
        raise ToolTableError(f"{where}: a bull-nose tool needs its corner radius: "
                             "bullnose:<diameter mm>:<corner radius mm>")
    return _make_tool(values[0], shape, corner, where)


def _shape_from_comment(comment: str, where: str) -> tuple[ToolShape, float]:
    text = comment.lower()
    if _BULL.search(text):
        match = _CORNER.search(text)
        if match is None:
            raise ToolTableError(f"{where}: comment {comment.strip()[:60]!r}: a bull-nose tool "
                                 "needs its corner radius in the comment, e.g. 'bullnose r1.5'")
        return ToolShape.BULLNOSE, _number(match.group(1), where, "corner radius")
    if _BALL.search(text):
        return ToolShape.BALL, 0.0
    return ToolShape.FLAT, 0.0


def parse_tool_table(text: str, source: str = "tool table") -> dict[int, Tool]:
    """Tools of a LinuxCNC tool table's text (see the module docstring)."""
    tools: dict[int, Tool] = {}
    lines = text.replace("\r\n", "\n").replace("\r", "\n").split("\n")
    for lineno, raw in enumerate(lines, start=1):
        where = f"{source}: line {lineno}"
        if len(raw) > MAX_LINE_CHARS:
            raise ToolTableError(f"{where}: longer than MAX_LINE_CHARS={MAX_LINE_CHARS} "
                                 "characters")
        body, _, comment = raw.partition(";")
        if not body.strip():
            continue
        if not body.isascii():
            bad = next(c for c in body if not c.isascii())
            raise ToolTableError(f"{where}: character {bad!r} outside the comment")
        words: dict[str, float] = {}
        pos = 0
        stripped = body.rstrip()
        while pos < len(stripped):
            match = _WORD.match(stripped, pos)
            if match is None:
                raise ToolTableError(f"{where}: cannot read {stripped[pos:].strip()[:40]!r}")
            letter = match.group(1).upper()
            word = f"{letter}{match.group(2) or ''}"
            if letter not in _TABLE_LETTERS:
                raise ToolTableError(f"{where}: unknown word {word[:40]!r}")
            if match.group(2) is None:
                raise ToolTableError(f"{where}: word {letter!r} has no number")
            if letter in words:
                raise ToolTableError(f"{where}: word {letter} appears twice")
            words[letter] = _number(match.group(2), where, word[:40])
            pos = match.end()
        if "T" not in words:
            raise ToolTableError(f"{where}: no tool number (T word)")
        number = _tool_number(words["T"], where, f"T{words['T']:g}")
        if "D" not in words:
            raise ToolTableError(f"{where}: tool T{number} has no diameter (D word, mm)")
        if number in tools:
            raise ToolTableError(f"{where}: tool T{number} appears twice")
        if len(tools) >= MAX_TOOLS:
            raise ToolTableError(f"{where}: more than MAX_TOOLS={MAX_TOOLS} tools")
        shape, corner = _shape_from_comment(comment, where)
        tools[number] = _make_tool(words["D"], shape, corner, f"{where}: D{words['D']:g}")
    return tools


def read_tool_table(path: str | os.PathLike) -> dict[int, Tool]:
    """Tools of a LinuxCNC tool-table file (UTF-8, see the module docstring); errors name the
    file, the line and the word."""
    text = read_text(path, MAX_TABLE_BYTES, "MAX_TABLE_BYTES", ToolTableError)
    return parse_tool_table(text, str(path))


def check_program_tools(program: Program, tools: dict[int, Tool]) -> None:
    """ParameterError if a move of ``program`` that may cut (a feed, or a rapid after a tool
    change) uses a tool number ``tools`` lacks; the message names the tool and the line of
    its tool change (M6), or of the first feed move before any change (tool 0)."""
    known = ", ".join(f"T{n}" for n in sorted(tools)) or "none"
    for line, number in program.tool_changes:
        if number != 0 and number not in tools:
            raise ParameterError(
                f"{program.source}: line {line}: tool change to T{number}, which the tool table "
                f"lacks (tools given: {known})")
    if 0 not in tools:
        feeds = (program.tool == 0) & (program.kind != MoveKind.RAPID)
        if np.any(feeds):
            first = int(program.line[np.flatnonzero(feeds)[0]])
            raise ParameterError(
                f"{program.source}: line {first}: feed move before any tool change (M6), with "
                f"no tool T0 given (tools given: {known})")

