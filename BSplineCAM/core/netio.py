# SPDX-License-Identifier: LGPL-2.1-or-later
"""Control-net and point files: JSON (canonical), CSV, and the paper's .dat point format.

Every reader validates as it goes and raises :class:`NetError` naming the file and the line
or index at fault.  Writers go through :func:`atomic_write` so a failure never leaves a
half-written file behind.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .basis import DEGREE, KnotLayout
from .errors import NetError
from .typing import FloatArray

MIN_POINTS = DEGREE + 1


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
            raise NetError(f"{source}: expected an array of shape (rows, columns, 3), got {array.shape}")
        try:
            array = array.astype(float)
        except (TypeError, ValueError):
            raise NetError(f"{source}: control points are not all numbers") from None
    else:
        if not isinstance(data, Sequence) or isinstance(data, (str, bytes)) or len(data) == 0:
            raise NetError(f"{source}: control_points must be a non-empty list of rows")
        rows: list[list[list[float]]] = []
        width = None
        for i, row in enumerate(data):
            if not isinstance(row, Sequence) or isinstance(row, (str, bytes)):
                raise NetError(f"{source}: row {i} is not a list of points")
            if width is None:
                width = len(row)
            elif len(row) != width:
                raise NetError(
                    f"{source}: ragged net: row {i} has {len(row)} points, row 0 has {width}"
                )
            parsed_row = []
            for j, point in enumerate(row):
                if not isinstance(point, Sequence) or isinstance(point, (str, bytes)) or len(point) != 3:
                    raise NetError(f"{source}: point [{i}][{j}] must be [x, y, z], got {point!r}")
                coords = []
                for c, value in enumerate(point):
                    if isinstance(value, bool) or not isinstance(value, (int, float)):
                        raise NetError(
                            f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is not a number: {value!r}"
                        )
                    coords.append(float(value))
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
        raise NetError(f"{source}: point [{i}][{j}] coordinate {'xyz'[c]} is {array[i, j, c]} (not finite)")
    return array


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


def read_text(path: Path) -> str:
    """A file's UTF-8 text; a NetError names the file when it is missing or binary."""
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise NetError(f"{path}: cannot read: {exc.strerror}") from None
    except UnicodeDecodeError:
        raise NetError(f"{path}: not a text file (invalid UTF-8)") from None


# ---------------------------------------------------------------------------------------------
# JSON


def read_json(path: str | os.PathLike) -> ControlNet:
    """Read the canonical control-net JSON (see README): name, units, knots, control_points."""
    path = Path(path)
    text = read_text(path)
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as exc:
        raise NetError(f"{path}: line {exc.lineno}, column {exc.colno}: invalid JSON: {exc.msg}") from None
    return net_from_dict(doc, str(path))


def net_from_dict(doc: object, source: str = "control net") -> ControlNet:
    """Validate a parsed JSON document into a ControlNet."""
    if not isinstance(doc, dict):
        raise NetError(f"{source}: expected a JSON object with 'control_points'")
    if "control_points" not in doc:
        raise NetError(f"{source}: missing 'control_points'")
    units = str(doc.get("units", "mm"))
    if units not in ("mm", "in", "inch"):
        raise NetError(f"{source}: unknown units {units!r}: expected 'mm' or 'in'")
    points = validate_net(doc["control_points"], source)
    if units != "mm":
        points = points * 25.4
    try:
        layout = KnotLayout.parse(doc.get("knots", "uniform"))
    except NetError as exc:
        raise NetError(f"{source}: {exc}") from None
    name = str(doc.get("name") or Path(source).stem or "surface")
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
    """Read a CSV control net: header ``row,column,x,y,z``, one point per line, any order."""
    path = Path(path)
    text = read_text(path)
    entries: dict[tuple[int, int], list[float]] = {}
    reader = csv.reader(io.StringIO(text))
    saw_header = False
    for lineno, record in enumerate(reader, start=1):
        cells = [c.strip() for c in record]
        if not cells or all(not c for c in cells) or cells[0].startswith("#"):
            continue
        if not saw_header and [c.lower() for c in cells] == CSV_HEADER:
            saw_header = True
            continue
        if len(cells) != 5:
            raise NetError(f"{path}: line {lineno}: expected 5 fields row,column,x,y,z, got {len(cells)}")
        try:
            i, j = int(cells[0]), int(cells[1])
            xyz = [float(c) for c in cells[2:]]
        except ValueError:
            raise NetError(f"{path}: line {lineno}: not numeric: {','.join(cells)}") from None
        if i < 0 or j < 0:
            raise NetError(f"{path}: line {lineno}: negative row/column index")
        if not all(math.isfinite(v) for v in xyz):
            raise NetError(f"{path}: line {lineno}: coordinate is not finite")
        if (i, j) in entries:
            raise NetError(f"{path}: line {lineno}: point ({i}, {j}) given twice")
        entries[(i, j)] = xyz
    if not entries:
        raise NetError(f"{path}: no control points")
    rows = 1 + max(i for i, _ in entries)
    cols = 1 + max(j for _, j in entries)
    missing = [(i, j) for i in range(rows) for j in range(cols) if (i, j) not in entries]
    if missing:
        raise NetError(f"{path}: the net is not rectangular: point {missing[0]} is missing")
    points = [[entries[(i, j)] for j in range(cols)] for i in range(rows)]
    return ControlNet(points=validate_net(points, str(path)), knots=KnotLayout.parse(knots), name=path.stem)


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
    lines = read_text(path).splitlines()
    values: list[list[float]] = []
    header_rows = None
    for lineno, line in enumerate(lines, start=1):
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            for token in stripped[1:].split():
                if token.startswith("rows="):
                    with contextlib.suppress(ValueError):
                        header_rows = int(token[5:])
            continue
        fields = stripped.replace(",", " ").split()
        if len(fields) != 3:
            raise NetError(f"{path}: line {lineno}: expected 'X Y Z', got {len(fields)} fields")
        try:
            xyz = [float(f) for f in fields]
        except ValueError:
            raise NetError(f"{path}: line {lineno}: not numeric: {stripped!r}") from None
        if not all(math.isfinite(v) for v in xyz):
            raise NetError(f"{path}: line {lineno}: coordinate is not finite")
        values.append(xyz)
    flat = np.array(values, dtype=float).reshape(-1, 3)
    count = len(flat)
    if count < MIN_POINTS * MIN_POINTS:
        raise NetError(f"{path}: {count} points: a surface needs a grid of at least 4x4")
    rows = rows if rows is not None else header_rows
    if rows is not None:
        if rows < MIN_POINTS or count % rows or count // rows < MIN_POINTS:
            raise NetError(f"{path}: {count} points do not form a grid of {rows} rows (of at least 4)")
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


def read_net(path: str | os.PathLike, knots: str | KnotLayout | None = None, rows: int | None = None) -> ControlNet:
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
        return ControlNet(validate_net(grid, str(path)), KnotLayout.parse(knots or "uniform"), path.stem)
    raise NetError(f"{path}: unknown control-net format {suffix!r}: expected .json, .csv or .dat")
