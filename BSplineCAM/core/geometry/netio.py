# SPDX-License-Identifier: LGPL-2.1-or-later
"""Control-net and point files: JSON (canonical), CSV, and the paper's .dat point format.

Every reader validates as it goes and raises :class:`NetError` naming the file and the line
or index at fault.  Time and memory stay linear in the input: the limits below (file size,
line length, nesting, digits per number, points per net, coordinates) are checked before the
work they bound, and the error names the limit and its value.  Writers go through
:func:`atomic_write` so a failure never leaves a half-written file behind.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import re
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import NetError
from ..typing import FloatArray
from .basis import DEGREE, KnotLayout

MIN_POINTS = DEGREE + 1

# Limits on what the readers accept.  Time and memory stay linear in the input below them, and
# the error that enforces one names it and its value.
#: Bytes in one net or point file (256 MiB).
MAX_FILE_BYTES = 256 * 2**20
#: Characters on one line of a CSV or .dat file.
MAX_LINE_CHARS = 4096
#: Depth of nested JSON arrays and objects (a net needs 4: document, net, row, point).
MAX_NESTING = 64
#: Digits in one number (integer, fraction and exponent together).
MAX_DIGITS = 100
#: Points in one net or point grid (rows x columns).
MAX_NET_POINTS = 4_000_000
#: Largest |x|, |y| or |z| of a point, mm (one kilometre).
MAX_COORDINATE_MM = 1e6
#: Characters of a net's name.
MAX_NAME_CHARS = 200

#: A plain decimal number, as C's printf, numpy and JSON write them (ASCII digits only; no
#: underscores, no nan/inf).
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_INTEGER = re.compile(r"[+-]?[0-9]+")
#: A .dat line of three such numbers, apart by white space and commas.
_D = _DECIMAL.pattern
_DAT_POINT = re.compile(rf"[\s,]*({_D})[\s,]+({_D})[\s,]+({_D})[\s,]*", re.ASCII)


@dataclass(frozen=True)
class ControlNet:
    """A validated rectangular net: rows follow u, columns follow w; units are millimetres."""

    points: FloatArray
    knots: KnotLayout = KnotLayout.UNIFORM
    name: str = "surface"
    units: str = "mm"
    extra: dict = field(default_factory=dict, compare=False)

    @property
    def shape(self) -> tuple[int, int]:
        return int(self.points.shape[0]), int(self.points.shape[1])

    def to_json_dict(self) -> dict:
        return {
            "name": self.name,
            "units": self.units,
            "knots": self.knots.value,
            "control_points": self.points.tolist(),
        }


def validate_net(data: object, source: str = "control net") -> FloatArray:
    """Turn nested lists (or an array) into a finite (rows, cols, 3) float array.

    Ragged rows, short points, non-numbers, NaN/inf and nets under 4x4 each raise a NetError
    that names ``source`` and the offending row/column index.
    """
    if isinstance(data, np.ndarray):
        array = data
        if array.ndim != 3 or array.shape[2] != 3:
            raise NetError(
                f"{source}: expected an array of shape (rows, columns, 3), got {array.shape}"
            )
        _check_net_size(array.shape[0], array.shape[1], source)
        try:
            array = array.astype(float)
        except (TypeError, ValueError, OverflowError):
            raise NetError(f"{source}: control points are not all finite numbers") from None
    else:
        if not isinstance(data, Sequence) or isinstance(data, (str, bytes)) or len(data) == 0:
            raise NetError(f"{source}: control_points must be a non-empty list of rows")
        rows: list[list[list[float]]] = []
        width = None
        if len(data) > MAX_NET_POINTS:
            _check_net_size(len(data), 1, source)
        for i, row in enumerate(data):
            if not isinstance(row, Sequence) or isinstance(row, (str, bytes)):
                raise NetError(f"{source}: row {i} is not a list of points")
            if width is None:
                width = len(row)
            elif len(row) != width:
                raise NetError(
                    f"{source}: ragged net: row {i} has {len(row)} points, row 0 has {width}"
                )
            if i == 0:
                _check_net_size(len(data), width, source)
            parsed_row = []
            for j, point in enumerate(row):
                if (not isinstance(point, Sequence) or isinstance(point, (str, bytes))
                        or len(point) != 3):
                    raise NetError(f"{source}: point [{i}][{j}] must be [x, y, z], got "
                                   f"{_excerpt(repr(point))}")
                coords = []
                for c, value in enumerate(point):
                    if isinstance(value, bool) or not isinstance(value, (int, float)):
                        raise NetError(
                            f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is not a number: "
                            f"{_excerpt(repr(value))}"
                        )
                    try:
                        coords.append(float(value))
                    except OverflowError:  # an integer beyond any float
                        raise NetError(
                            f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is beyond "
                            f"MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm"
                        ) from None
                parsed_row.append(coords)
            rows.append(parsed_row)
        array = np.array(rows, dtype=float)
    if array.shape[0] < MIN_POINTS or array.shape[1] < MIN_POINTS:
        raise NetError(
            f"{source}: a cubic surface needs at least {MIN_POINTS}x{MIN_POINTS} control points, "
            f"got {array.shape[0]}x{array.shape[1]}"
        )
    bad = np.argwhere(~np.isfinite(array))
    if len(bad):
        i, j, c = (int(v) for v in bad[0])
        raise NetError(
            f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is {array[i, j, c]} (not finite)"
        )
    far = np.argwhere(np.abs(array) > MAX_COORDINATE_MM)
    if len(far):
        i, j, c = (int(v) for v in far[0])
        raise NetError(
            f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is {array[i, j, c]:g} mm, beyond "
            f"MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm"
        )
    return array


def _check_net_size(rows: int, cols: int, source: str) -> None:
    if rows * cols > MAX_NET_POINTS:
        raise NetError(
            f"{source}: {rows}x{cols} points, more than MAX_NET_POINTS={MAX_NET_POINTS}"
        )


def _excerpt(text: str, limit: int = 60) -> str:
    """``text`` for an error message: repr, cut to about ``limit`` characters."""
    if len(text) <= limit:
        return repr(text)
    return repr(text[:limit]) + f"... ({len(text)} characters)"


def _line_of(text: str, offset: int) -> int:
    return text.count("\n", 0, max(offset, 0)) + 1


def parse_number(token: str, where: str, what: str = "coordinate") -> float:
    """A finite float from a decimal ``token`` of a line-based file (mm), or a NetError that
    names ``where`` (file and line) and the limit broken."""
    if _DECIMAL.fullmatch(token) is None:
        if token.strip("+-").lower() in ("nan", "inf", "infinity"):
            raise NetError(f"{where}: {what} {token!r} is not finite")
        raise NetError(f"{where}: not numeric: {_excerpt(token)}")
    if len(token) > MAX_DIGITS and sum(c.isdigit() for c in token) > MAX_DIGITS:
        raise NetError(f"{where}: a number has more than MAX_DIGITS={MAX_DIGITS} digits")
    value = float(token)
    if not math.isfinite(value):
        raise NetError(f"{where}: {what} {_excerpt(token)} is not finite (overflows)")
    return value


# ---------------------------------------------------------------------------------------------
# atomic writes


@contextlib.contextmanager
def atomic_write(path: str | os.PathLike, mode: str = "w") -> Iterator[io.IOBase]:
    """Write to a temporary file beside ``path`` and rename it into place only on success."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)
    try:
        with os.fdopen(fd, mode, encoding=None if "b" in mode else "utf-8", newline=None) as handle:
            yield handle
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def read_bytes(path: str | os.PathLike, limit: int, limit_name: str) -> bytes:
    """A file's bytes, read in pieces so that memory never exceeds ``limit`` (also for pipes);
    OSError or a larger file raise a NetError naming the file and ``limit_name``."""
    pieces = []
    size = 0
    try:
        with open(path, "rb") as handle:
            if os.fstat(handle.fileno()).st_size > limit:
                raise NetError(f"{path}: larger than {limit_name}={limit} bytes")
            while size <= limit:
                piece = handle.read(2**20)
                if not piece:
                    break
                pieces.append(piece)
                size += len(piece)
    except OSError as exc:
        raise NetError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if size > limit:
        raise NetError(f"{path}: larger than {limit_name}={limit} bytes")
    return b"".join(pieces)


def read_text(path: str | os.PathLike, limit: int | None = None,
              limit_name: str = "MAX_FILE_BYTES", error: type[Exception] = NetError) -> str:
    """A file's UTF-8 text (a leading byte-order mark dropped); ``error`` names the file, and
    the line where it can (lines end at LF, CR LF or CR), when it is missing, larger than
    ``limit`` bytes (``limit_name``; default MAX_FILE_BYTES), not UTF-8 or holds NUL bytes.
    Every reader of a text file (nets, programs, tool tables) goes through here."""
    if limit is None:
        limit = MAX_FILE_BYTES
    try:
        data = read_bytes(path, limit, limit_name)
    except NetError as exc:
        if error is NetError:
            raise
        raise error(str(exc)) from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise error(f"{path}: line {_line_at(data, exc.start)}: not a text file (invalid UTF-8 "
                    f"byte 0x{data[exc.start]:02x})") from None
    nul = text.find("\x00")
    if nul >= 0:
        raise error(f"{path}: line {_line_at(text, nul)}: not a text file (contains NUL bytes)")
    return text


def _line_at(text: str | bytes, offset: int) -> int:
    """The line (from 1) holding ``offset``, lines ended by LF, CR LF or CR."""
    lf, cr = ("\n", "\r") if isinstance(text, str) else (b"\n", b"\r")
    return (text.count(lf, 0, offset) + text.count(cr, 0, offset)
            - text.count(cr + lf, 0, offset) + 1)


def _lines(text: str, path: Path) -> list[str]:
    """Lines ended by LF, CR LF or CR, each at most MAX_LINE_CHARS long."""
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    longest = max(map(len, lines), default=0)
    if longest > MAX_LINE_CHARS:
        lineno = next(n for n, line in enumerate(lines, 1) if len(line) > MAX_LINE_CHARS)
        raise NetError(f"{path}: line {lineno}: longer than MAX_LINE_CHARS={MAX_LINE_CHARS} "
                       "characters")
    return lines


# ---------------------------------------------------------------------------------------------
# JSON


class _JsonLimit(Exception):
    """Raised by the parser's hooks; read_json turns it into a NetError with the line."""

    def __init__(self, pattern: str, message: str, occurrence: int = 0) -> None:
        super().__init__(message)
        self.pattern = pattern
        self.message = message
        self.occurrence = occurrence

    def where(self, text: str) -> str:
        """``line N: `` of the offending text, or nothing if it cannot be found."""
        found = [m.start() for m, _ in zip(re.finditer(self.pattern, text),
                                          range(self.occurrence + 1))]
        return f"line {_line_of(text, found[-1])}: " if found else ""


#: A JSON string (escapes included), replaced by "" before the brackets are counted.  An
#: unterminated one runs to the end of the text, so that the scan stays linear (the parser
#: refuses it afterwards).
_JSON_STRING = re.compile(r'"[^"\\]*(?:\\.[^"\\]*)*"?', re.DOTALL)


def _long_number(token: str) -> str:
    if sum(c.isdigit() for c in token) > MAX_DIGITS:
        raise _JsonLimit(re.escape(token), f"a number has more than MAX_DIGITS={MAX_DIGITS} "
                         "digits")
    return token


def _json_float(token: str) -> float:
    return float(token if len(token) <= MAX_DIGITS else _long_number(token))


def _json_int(token: str) -> int:
    return int(token if len(token) <= MAX_DIGITS else _long_number(token))


def _json_object(pairs: list[tuple[str, object]]) -> dict:
    doc = dict(pairs)
    if len(doc) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _JsonLimit(re.escape(json.dumps(key)) + r"\s*:",
                                 f"key {_excerpt(key)} appears twice in an object", 1)
            seen.add(key)
    return doc


def _check_json_nesting(text: str, path: Path) -> None:
    """Refuse arrays and objects nested deeper than MAX_NESTING before the parser recurses."""
    skeleton = _JSON_STRING.sub('""', text) if '"' in text else text
    raw = np.frombuffer(skeleton.encode("utf-8", "replace"), dtype=np.uint8)
    opens = (raw == ord("[")) | (raw == ord("{"))
    brackets = np.flatnonzero(opens | (raw == ord("]")) | (raw == ord("}")))
    if not len(brackets):
        return
    depth = np.cumsum(np.where(opens[brackets], 1, -1))
    deep = np.flatnonzero(depth > MAX_NESTING)
    if len(deep):
        offset = int(brackets[deep[0]])
        line = int(np.count_nonzero(raw[:offset] == ord("\n"))) + 1
        raise NetError(f"{path}: line {line}: arrays and objects nested deeper than "
                       f"MAX_NESTING={MAX_NESTING}")


def read_json(path: str | os.PathLike) -> ControlNet:
    """Read the canonical control-net JSON (see README): name, units, knots, control_points.

    Refused with a NetError naming the line: nesting deeper than MAX_NESTING, a number with more
    than MAX_DIGITS digits, a key given twice in one object; NaN and Infinity are named by their
    point's index (see :func:`validate_net`).
    """
    path = Path(path)
    text = read_text(path)
    _check_json_nesting(text, path)
    try:
        doc = json.loads(text, parse_int=_json_int, parse_float=_json_float,
                         object_pairs_hook=_json_object)
    except json.JSONDecodeError as exc:
        raise NetError(
            f"{path}: line {exc.lineno}, column {exc.colno}: invalid JSON: {exc.msg}"
        ) from None
    except _JsonLimit as exc:
        raise NetError(f"{path}: {exc.where(text)}{exc.message}") from None
    except RecursionError:  # a stack smaller than MAX_NESTING levels needs
        raise NetError(f"{path}: nested too deeply (MAX_NESTING={MAX_NESTING})") from None
    return net_from_dict(doc, str(path))


def net_from_dict(doc: object, source: str = "control net") -> ControlNet:
    """Validate a parsed JSON document into a ControlNet."""
    if not isinstance(doc, dict):
        raise NetError(f"{source}: expected a JSON object with 'control_points'")
    if "control_points" not in doc:
        raise NetError(f"{source}: missing 'control_points'")
    for key in ("name", "units", "knots"):
        value = doc.get(key)
        if key in doc and not isinstance(value, str) and not (key == "name" and value is None):
            raise NetError(f"{source}: {key!r} must be a string, got {_excerpt(repr(value))}")
    units = doc.get("units", "mm")
    if units not in ("mm", "in", "inch"):
        raise NetError(f"{source}: unknown units {_excerpt(units)}: expected 'mm' or 'in'")
    name = doc.get("name") or Path(source).stem or "surface"
    if len(name) > MAX_NAME_CHARS or not name.isprintable():
        raise NetError(f"{source}: 'name' must be printable text of at most "
                       f"MAX_NAME_CHARS={MAX_NAME_CHARS} characters, got {_excerpt(name)}")
    points = validate_net(doc["control_points"], source)
    if units != "mm":
        points = points * 25.4
        far = np.abs(points) > MAX_COORDINATE_MM
        if far.any():
            i, j, c = (int(v) for v in np.argwhere(far)[0])
            raise NetError(f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is "
                           f"{points[i, j, c]:g} mm, beyond MAX_COORDINATE_MM="
                           f"{MAX_COORDINATE_MM:g} mm")
    try:
        layout = KnotLayout.parse(doc.get("knots", "uniform"))
    except NetError as exc:
        raise NetError(f"{source}: {exc}") from None
    extra = {k: v for k, v in doc.items() if k not in ("name", "units", "knots", "control_points")}
    return ControlNet(points=points, knots=layout, name=name, units="mm", extra=extra)


def write_json(net: ControlNet, path: str | os.PathLike) -> None:
    with atomic_write(path) as handle:
        json.dump(net.to_json_dict(), handle, indent=1)
        handle.write("\n")


# ---------------------------------------------------------------------------------------------
# CSV: one control point per line, "row,column,x,y,z" with that header


CSV_HEADER = ["row", "column", "x", "y", "z"]


def read_csv(path: str | os.PathLike, knots: str | KnotLayout = "uniform") -> ControlNet:
    """Read a CSV control net: header ``row,column,x,y,z``, one point per line, any order.

    Each index must be below the number of lines in the file (a net of R x C points has R x C
    lines), so a far index is refused before any grid is built.
    """
    path = Path(path)
    text = read_text(path)
    lines = _lines(text, path)
    entries: dict[tuple[int, int], list[float]] = {}
    reader = csv.reader(lines)
    saw_header = False
    lineno = 0
    try:
        for record in reader:
            lineno = reader.line_num
            cells = [c.strip() for c in record]
            if not cells or all(not c for c in cells) or cells[0].startswith("#"):
                continue
            if not saw_header and [c.lower() for c in cells] == CSV_HEADER:
                saw_header = True
                continue
            where = f"{path}: line {lineno}"
            if len(cells) != 5:
                raise NetError(f"{where}: expected 5 fields row,column,x,y,z, got {len(cells)}")
            index = []
            for label, cell in (("row", cells[0]), ("column", cells[1])):
                if _INTEGER.fullmatch(cell) is None:
                    raise NetError(f"{where}: not numeric: {label} index {_excerpt(cell)}")
                if len(cell) > MAX_DIGITS:
                    raise NetError(f"{where}: a number has more than MAX_DIGITS={MAX_DIGITS} "
                                   "digits")
                value = int(cell)
                if value < 0:
                    raise NetError(f"{where}: negative row/column index")
                if value >= len(lines):
                    raise NetError(
                        f"{where}: {label} index {value} is beyond the file's {len(lines)} "
                        "lines (a net of R x C points has R x C lines)"
                    )
                index.append(value)
            xyz = [parse_number(c, where) for c in cells[2:]]
            far = [v for v in xyz if abs(v) > MAX_COORDINATE_MM]
            if far:
                raise NetError(f"{where}: coordinate {far[0]:g} mm is beyond "
                               f"MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm")
            i, j = index
            if (i, j) in entries:
                raise NetError(f"{where}: point ({i}, {j}) given twice")
            entries[(i, j)] = xyz
    except csv.Error as exc:
        raise NetError(f"{path}: line {reader.line_num or lineno}: unreadable CSV: {exc}") from None
    if not entries:
        raise NetError(f"{path}: no control points")
    if len(entries) > MAX_NET_POINTS:
        raise NetError(f"{path}: {len(entries)} points, more than MAX_NET_POINTS={MAX_NET_POINTS}")
    rows = 1 + max(i for i, _ in entries)
    cols = 1 + max(j for _, j in entries)
    if rows * cols != len(entries):
        # more cells than points: one of the first len(entries) + 1 cells is missing
        missing = next((i, j) for i in range(rows) for j in range(cols) if (i, j) not in entries)
        raise NetError(f"{path}: the net is not rectangular: point {missing} is missing")
    points = np.empty((rows, cols, 3))
    for (i, j), xyz in entries.items():
        points[i, j] = xyz
    return ControlNet(points=validate_net(points, str(path)), knots=KnotLayout.parse(knots),
                      name=path.stem)


def write_csv(net: ControlNet, path: str | os.PathLike) -> None:
    with atomic_write(path) as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(CSV_HEADER)
        for i in range(net.shape[0]):
            for j in range(net.shape[1]):
                writer.writerow([i, j, *(repr(float(v)) for v in net.points[i, j])])


# ---------------------------------------------------------------------------------------------
# .dat: the paper's point file, one "X Y Z" per line


def write_dat(points: FloatArray, path: str | os.PathLike, comment: str = "") -> None:
    """Write a (rows, cols, 3) grid of surface points row by row, one "X Y Z" per line.

    A leading comment records the grid shape so that :func:`read_dat` need not guess it.
    """
    grid = np.asarray(points, dtype=float)
    rows, cols = grid.shape[:2]
    with atomic_write(path) as handle:
        if comment:
            handle.write(f"# {comment}\n")
        handle.write(f"# rows={rows} columns={cols}\n")
        np.savetxt(handle, grid.reshape(-1, 3), fmt="%.12g")


def read_dat(path: str | os.PathLike, rows: int | None = None) -> FloatArray:
    """Read a .dat grid of points as (rows, cols, 3).

    The row count is taken from ``rows``, else from a ``# rows=R`` comment, else detected: of
    all factorisations of the point count, the one whose grid is smoothest (smallest second
    differences along both directions) is the row layout.
    """
    path = Path(path)
    lines = _lines(read_text(path), path)
    values: list[list[float]] = []
    header_rows = None
    for lineno, line in enumerate(lines, start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            for token in stripped[1:].split():
                if token.startswith("rows="):
                    if _INTEGER.fullmatch(token[5:]) is None or len(token) > 5 + MAX_DIGITS:
                        raise NetError(f"{path}: line {lineno}: not numeric: {_excerpt(token)}")
                    header_rows = int(token[5:])
            continue
        match = _DAT_POINT.fullmatch(stripped) if len(stripped) <= MAX_DIGITS else None
        if match is not None:
            xyz = [float(v) for v in match.groups()]
            if max(map(abs, xyz)) <= MAX_COORDINATE_MM:  # finite and within reach
                values.append(xyz)
                if len(values) > MAX_NET_POINTS:
                    raise NetError(f"{path}: line {lineno}: more than "
                                   f"MAX_NET_POINTS={MAX_NET_POINTS} points")
                continue
        where = f"{path}: line {lineno}"  # the slow path, naming what is wrong
        fields = stripped.replace(",", " ").split()
        if len(fields) != 3:
            raise NetError(f"{where}: expected 'X Y Z', got {len(fields)} fields")
        xyz = [parse_number(f, where) for f in fields]
        far = [v for v in xyz if abs(v) > MAX_COORDINATE_MM]
        if far:
            raise NetError(f"{where}: coordinate {far[0]:g} mm is beyond "
                           f"MAX_COORDINATE_MM={MAX_COORDINATE_MM:g} mm")
        values.append(xyz)
        if len(values) > MAX_NET_POINTS:
            raise NetError(f"{where}: more than MAX_NET_POINTS={MAX_NET_POINTS} points")
    flat = np.array(values, dtype=float).reshape(-1, 3)
    count = len(flat)
    if count < MIN_POINTS * MIN_POINTS:
        raise NetError(f"{path}: {count} points: a surface needs a grid of at least 4x4")
    rows = rows if rows is not None else header_rows
    if rows is not None:
        if rows < MIN_POINTS or count % rows or count // rows < MIN_POINTS:
            raise NetError(
                f"{path}: {count} points do not form a grid of {rows} rows (of at least 4)"
            )
        return flat.reshape(rows, count // rows, 3)
    return flat.reshape(detect_rows(flat, str(path)), -1, 3)


def detect_rows(flat: FloatArray, source: str = "points") -> int:
    """Row count of a row-major point grid, by the smoothness of each candidate layout."""
    count = len(flat)
    candidates = [r for r in range(MIN_POINTS, count // MIN_POINTS + 1) if count % r == 0]
    if not candidates:
        raise NetError(f"{source}: {count} points do not form a grid of at least 4x4")
    scale = float(np.ptp(flat, axis=0).max()) or 1.0
    best, best_score = None, math.inf
    for r in candidates:
        grid = flat.reshape(r, count // r, 3) / scale
        along_rows = np.abs(np.diff(grid, 2, axis=1)).max()
        along_cols = np.abs(np.diff(grid, 2, axis=0)).max()
        score = max(along_rows, along_cols)
        if score < best_score - 1e-12:
            best, best_score = r, score
    return int(best)


def read_net(path: str | os.PathLike, knots: str | KnotLayout | None = None,
             rows: int | None = None) -> ControlNet:
    """Read a control net by extension: .json, .csv, or a .dat grid used as control points."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".json":
        net = read_json(path)
        if knots is not None:
            net = ControlNet(net.points, KnotLayout.parse(knots), net.name, net.units, net.extra)
        return net
    if suffix == ".csv":
        return read_csv(path, knots or "uniform")
    if suffix in (".dat", ".txt", ".xyz"):
        grid = read_dat(path, rows)
        return ControlNet(validate_net(grid, str(path)), KnotLayout.parse(knots or "uniform"),
                          path.stem)
    raise NetError(f"{path}: unknown control-net format {suffix!r}: expected .json, .csv or .dat")
