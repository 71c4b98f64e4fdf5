# SPDX-License-Identifier: LGPL-2.1-or-later
"""Load limits per tool, checked move by move on a whole-program simulation.

A tool's :class:`LoadLimits` bound three figures of every cutting feed move (a linearised
move that engages material, see :mod:`.job_simulation` for their definitions): the axial
engagement (mm, the deepest cut), the radial engagement (mm, the width of cut across the
direction of travel) and the material removal rate (mm^3/min, over windows of a tool radius).
Entries of a flat or bull-nose end mill (plunges, ramps, helices and their closing turns,
``JobSimulation.entry``) cut at full width by nature: their axial engagement and removal rate
are checked, their radial engagement is not.  A ball's moves are all checked in full: the
moves the simulation takes as entries (every feed move that descends) are, for a finishing
ball, its passes going down a slope.  A figure over its limit is an :class:`Overload`; the overloaded moves of one tool
whose deepest cuts lie within about a tool diameter of each other form an
:class:`OverloadRegion`, with the thickness of the stock the tool met there.

Default limits (:func:`default_limits`), from the tool's kind and diameter D alone:

* a ball end mill is a finishing tool, which takes a scallop-sized cut, not a slot: axial
  engagement at most BALL_AXIAL_RATIO x D, radial engagement at most the ball's width at that
  depth, 2 sqrt(a (D - a)) for the axial limit a (0.87 D);
* a flat or bull-nose end mill is a roughing tool: axial engagement at most
  END_MILL_AXIAL_RATIO x D, radial engagement not limited (a slot at full width is a fair cut
  for it at that depth);
* the removal rate is not limited by default: a move within its radial and axial limits
  removes at most radial x axial x feed, so the rate adds a bound only when the machinist
  gives one for the tool, material and spindle (``rate=``).

A job's limits (:func:`job_limits`) come from its parameters, set by measurement on the case
study (examples/case-study.json) and examples/part.step with the 10 mm flat end mill at a 2 mm
step-down and 40 % stepover, 0.3 mm allowances, and the 6 mm ball:

* the roughing tool (T1), a flat or bull-nose end mill, cuts at most ENGAGEMENT_RATIO x the
  stepover wide outside its entries (measured: 4.30 and 4.11 mm against 4.5); a ball roughing
  tool's passes over the cusps of the pass before are wider, so its width is not limited.  Its
  depth is limited to the step-down: its levels, helices, ramps and plunges each cut one
  step-down (measured 2.00 mm on both parts, with and without plunges; the slivers thinner
  than a cell that a level's rim shaves beside the part's corners are no depth of cut, see
  :mod:`.job_simulation`);
* the finishing ball (T2) cuts at most as wide as the ball is at the depth of the stock the
  job plans for it, the axial allowance + the scallop + the rest limit (the step-down without
  rest passes), or FINISH_WIDTH_RATIO x D if wider, where it cuts deeper than that planned
  stock (``radial_from_depth_mm``): a rest pass taking its limit's depth across a column left
  in a round-bottomed hole at full width is the planned load, the same width through a plug
  of stock is not.  The rest passes leave the terraces within
  about their limit, not exactly (measured: 3.3 mm at most on both parts; 5.13 and 5.36 mm
  over 1.6 to 2.0 mm of stock after rest passes of 1 mm under a waterline finish of a bump,
  against 5.4 mm; the 6 mm ball over the stock left in examples/part.step's hole: 5.9 mm).
  Every move is checked, its descending ones too (a finishing pass descending a slope is no
  entry into a pocket).  Its depth is limited to that planned stock or, if larger, its
  diameter: the radial allowance stands as a skin on the part's walls, which the ball rolling
  over a wall's top edge and down its side cuts from its top down a radius or more at a light
  width (measured: 3.17 mm deep, at most 0.8 mm wide, along examples/part.step's sides, 3.50
  mm at its corner, 3.93 mm down the side of a block with rounded edges; 1.1 mm on the case
  study); a cut that deep and wide is caught by the width;
* neither rate is limited (measured: the ball 2200 mm^3/min at most on honest passes, 10277
  over the hole's stock; the end mill 12600 outside and 15700 in its entries).

Each limit has the simulation's resolution added: the engagement threshold (a tenth of a cell,
at least ENGAGEMENT_DEPTH_MM) for a depth, one cell for a width.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

import numpy as np

from ..errors import ParameterError
from .job_simulation import JobSimulation, engagement_threshold, initial_height
from .simulate import Tool, ToolShape

#: Default axial limit of a ball end mill (a finishing tool), times its diameter.
BALL_AXIAL_RATIO = 0.25
#: Default axial limit of a flat or bull-nose end mill (a roughing tool), times its diameter.
END_MILL_AXIAL_RATIO = 1.0
#: Width of cut a finishing ball may take in a job at least, times its diameter (its width a
#: little over a quarter of its diameter deep).
FINISH_WIDTH_RATIO = 0.9
#: A roughing end mill's width of cut outside its entries, times the stepover.
ENGAGEMENT_RATIO = 1.1
#: Range of a length limit (mm) and of a removal rate limit (mm^3/min), low end excluded.
LENGTH_LIMIT_RANGE_MM = (0.0, 1000.0)
RATE_LIMIT_RANGE = (0.0, 1e9)
#: Overloads listed in :meth:`LoadCheck.to_dict` (all are counted), and message lines per
#: tool in :meth:`LoadCheck.messages` (the rest summed up in one line).
MAX_LISTED_OVERLOADS = 1000
MAX_REGION_MESSAGES = 8

#: The option keys of :func:`parse_load_limits`, their field and unit.
_KEYS = {"axial": ("axial_mm", "mm"), "radial": ("radial_mm", "mm"),
         "rate": ("removal_rate_mm3_per_min", "mm^3/min")}
_QUANTITIES = {"axial": ("axial_mm", "axial engagement", "mm"),
               "radial": ("radial_mm", "radial engagement", "mm"),
               "removal_rate": ("removal_rate_mm3_per_min", "removal rate", "mm^3/min")}


@dataclass(frozen=True)
class LoadLimits:
    """Largest axial and radial engagement (mm) and removal rate (mm^3/min) one tool may take
    in a move; None: not limited.  With ``radial_from_depth_mm`` the width limit holds for the
    cuts deeper than that only (a finishing ball may take the stock planned for it at any
    width, a slot through a plug not)."""

    axial_mm: float | None = None
    radial_mm: float | None = None
    removal_rate_mm3_per_min: float | None = None
    radial_from_depth_mm: float | None = None

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is not None and not (isinstance(value, (int, float))
                                          and math.isfinite(value) and value > 0):
                unit = "mm^3/min" if f.name.startswith("removal") else "mm"
                raise ParameterError(f"load limit {f.name} must be positive ({unit}) or None, "
                                     f"got {value!r}")

    def to_dict(self) -> dict:
        """JSON-ready: the three limits, null where not limited."""
        return {f.name: None if getattr(self, f.name) is None
                else round(float(getattr(self, f.name)), 6) for f in fields(self)}


def ball_width(diameter: float, depth: float) -> float:
    """Width (mm) of a ball of ``diameter`` mm at ``depth`` mm above its tip (the diameter from
    the equator up)."""
    a = min(max(depth, 0.0), diameter / 2.0)
    return 2.0 * math.sqrt(a * (diameter - a))


def default_limits(tool: Tool) -> LoadLimits:
    """The limits of ``tool`` from its kind and diameter (see the module docstring)."""
    if tool.shape is ToolShape.BALL:
        axial = BALL_AXIAL_RATIO * tool.diameter
        return LoadLimits(axial_mm=axial, radial_mm=ball_width(tool.diameter, axial))
    return LoadLimits(axial_mm=END_MILL_AXIAL_RATIO * tool.diameter)


def job_limits(rough: Tool, finish: Tool, *, stepdown: float, stepover: float,
               axial_allowance: float, radial_allowance: float, scallop: float,
               rest_limit: float, cell: float) -> dict[int, LoadLimits]:
    """{1: the roughing tool's limits, 2: the finishing ball's} from the job's parameters (mm:
    ``stepover`` is the roughing's width of cut in mm, ``rest_limit`` 0 means no rest passes;
    ``cell`` the simulation's Z-map cell); see the module docstring."""
    for name, value in (("stepdown", stepdown), ("stepover", stepover), ("cell", cell),
                        ("scallop", scallop)):
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive (mm), got {value!r}")
    for name, value in (("axial allowance", axial_allowance),
                        ("radial allowance", radial_allowance), ("rest limit", rest_limit)):
        if not (math.isfinite(value) and value >= 0):
            raise ParameterError(f"{name} must be >= 0 (mm), got {value!r}")
    slack = engagement_threshold(cell)
    rough_radial = None
    if rough.shape is not ToolShape.BALL:
        rough_radial = ENGAGEMENT_RATIO * stepover + cell
        rough_radial = None if rough_radial >= rough.diameter else rough_radial
    rough_axial = stepdown + slack
    planned = axial_allowance + scallop + (rest_limit if rest_limit > 0 else stepdown)
    finish_axial = max(planned, finish.diameter) + slack
    finish_radial = max(ball_width(finish.diameter, planned),
                        FINISH_WIDTH_RATIO * finish.diameter) + cell \
        if finish.shape is ToolShape.BALL else None
    if finish_radial is not None and finish_radial >= finish.diameter:
        finish_radial = None
    return {1: LoadLimits(axial_mm=rough_axial, radial_mm=rough_radial),
            2: LoadLimits(axial_mm=finish_axial, radial_mm=finish_radial,
                          radial_from_depth_mm=planned + slack if finish_radial else None)}


def parse_limit_fields(text: str, option: str) -> dict:
    """``axial=1.5,radial=4,rate=8000`` (mm, mm, mm^3/min; ``none`` lifts a limit) as the
    LoadLimits fields it gives; ParameterError naming ``option`` and the unit otherwise."""
    if not isinstance(text, str) or not text.strip() or len(text) > 200:
        raise ParameterError(f"{option}: expected axial=MM,radial=MM,rate=MM3_PER_MIN (any of "
                             f"them), got {str(text)[:40]!r}")
    out: dict = {}
    for item in text.split(","):
        key, sep, value = (part.strip() for part in item.partition("="))
        if not sep or key.lower() not in _KEYS:
            raise ParameterError(f"{option} {text}: {item.strip()!r} is not one of axial=MM, "
                                 "radial=MM, rate=MM3_PER_MIN (axial and radial engagement in "
                                 "mm, removal rate in mm^3/min)")
        name, unit = _KEYS[key.lower()]
        if name in out:
            raise ParameterError(f"{option} {text}: {key} given twice")
        if value.lower() == "none":
            out[name] = None
            continue
        lo, hi = RATE_LIMIT_RANGE if unit != "mm" else LENGTH_LIMIT_RANGE_MM
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not (math.isfinite(number) and lo < number <= hi):
            raise ParameterError(f"{option} {text}: {key} must be a number above {lo:g} and at "
                                 f"most {hi:g} ({unit}), or none; got {value[:20]!r}")
        out[name] = number
    return out


def parse_load_limits(text: str, option: str) -> tuple[int, LoadLimits]:
    """``N:axial=1.5,radial=4,rate=8000``: tool number N and its limits (mm, mm, mm^3/min;
    the ones not given, or given as ``none``, are None); ParameterError naming ``option``."""
    if not isinstance(text, str) or ":" not in text:
        raise ParameterError(f"{option}: expected TOOL:axial=MM,radial=MM,rate=MM3_PER_MIN "
                             f"(tool number, then any of the limits), got {str(text)[:40]!r}")
    number, _, rest = text.partition(":")
    number = number.strip().upper().removeprefix("T")
    if not number.isdigit() or len(number) > 6:
        raise ParameterError(f"{option} {text[:60]}: the tool number before ':' must be a "
                             "whole number such as 2")
    return int(number), LoadLimits(**parse_limit_fields(rest, option))


def with_fields(limits: LoadLimits, given: dict) -> LoadLimits:
    """``limits`` with the fields of :func:`parse_limit_fields` replaced."""
    return replace(limits, **given)


@dataclass(frozen=True)
class Overload:
    """One program move of ``tool`` over one limit: ``quantity`` ('axial', 'radial' or
    'removal_rate') at ``value`` against ``limit`` (mm or mm^3/min), at source ``line``;
    x, y (mm) where the move cut deepest, z its tool tip's lowest Z (mm)."""

    tool: int
    line: int
    move: int
    quantity: str
    value: float
    limit: float
    x: float
    y: float
    z: float

    @property
    def ratio(self) -> float:
        return self.value / self.limit

    def describe(self) -> str:
        """``axial engagement 3.02 mm over its limit 1.31 mm``."""
        _, name, unit = _QUANTITIES[self.quantity]
        digits = 0 if unit != "mm" else 2
        return (f"{name} {self.value:.{digits}f} {unit} over its limit "
                f"{self.limit:.{digits}f} {unit}")

    def to_dict(self) -> dict:
        return {"tool": self.tool, "line": self.line, "move": self.move,
                "quantity": self.quantity, "value": round(self.value, 6),
                "limit": round(self.limit, 6), "x": round(self.x, 4), "y": round(self.y, 4),
                "z": round(self.z, 4)}


@dataclass(frozen=True)
class OverloadRegion:
    """Overloaded moves of one tool close together: the XY box (mm) of the points where they
    cut deepest, their tool tips' Z range (mm), the thickness of the stock the tool met there
    (``stock_mm``: the largest, over those points, of the stock the tools before it left
    (the block for the first) above the part's design, or off the part above the block's
    bottom), their first and last source line and their number."""

    tool: int
    x0: float
    x1: float
    y0: float
    y1: float
    z_min: float
    z_max: float
    stock_mm: float
    first_line: int
    last_line: int
    moves: int

    def to_dict(self) -> dict:
        return {k: (round(v, 4) if isinstance(v, float) else v)
                for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class LoadCheck:
    """The limits checked, every overload (one per move and quantity, in program order) and
    their regions."""

    limits: dict[int, LoadLimits]
    overloads: tuple[Overload, ...]
    regions: tuple[OverloadRegion, ...]

    @property
    def ok(self) -> bool:
        return not self.overloads

    @property
    def overloaded_moves(self) -> int:
        """Program moves with at least one figure over its limit."""
        return len({(o.tool, o.move) for o in self.overloads})

    def to_dict(self) -> dict:
        """JSON-ready: ``ok``, the limits by tool number, the number of overloaded moves, the
        first MAX_LISTED_OVERLOADS overloads and every region."""
        return {
            "ok": self.ok,
            "limits": {str(n): lim.to_dict() for n, lim in sorted(self.limits.items())},
            "overloaded_moves": self.overloaded_moves,
            "overloads": [o.to_dict() for o in self.overloads[:MAX_LISTED_OVERLOADS]],
            "overloads_listed": min(len(self.overloads), MAX_LISTED_OVERLOADS),
            "overloads_total": len(self.overloads),
            "regions": [r.to_dict() for r in self.regions],
        }

    def messages(self, tools: dict[int, Tool]) -> list[str]:
        """One line per region: the tool, the line of its worst overload (largest value over
        limit) and that load, then how many moves, the stock they meet and where; at most
        MAX_REGION_MESSAGES per tool, then one line for the rest."""
        out = []
        for number in sorted({r.tool for r in self.regions}):
            name = describe_tool(number, tools.get(number))
            regions = [r for r in self.regions if r.tool == number]
            for region in regions[:MAX_REGION_MESSAGES]:
                inside = [o for o in self.overloads if o.tool == number
                          and region.first_line <= o.line <= region.last_line
                          and region.x0 <= o.x <= region.x1 and region.y0 <= o.y <= region.y1]
                worst = max(inside, key=lambda o: o.ratio)
                many = "move" if region.moves == 1 else f"{region.moves} moves"
                verb = "meets" if region.moves == 1 else "meet"
                out.append(
                    f"{name} line {worst.line}: {worst.describe()}; {many} over their limits "
                    f"{verb} stock up to {region.stock_mm:.1f} mm thick at "
                    f"x {region.x0:.1f}..{region.x1:.1f}, y {region.y0:.1f}..{region.y1:.1f} "
                    f"mm, Z {region.z_min:.1f} to {region.z_max:.1f} (lines "
                    f"{region.first_line}..{region.last_line})")
            if len(regions) > MAX_REGION_MESSAGES:
                rest = regions[MAX_REGION_MESSAGES:]
                out.append(f"{name}: {len(rest)} more regions of overloaded moves, "
                           f"{sum(r.moves for r in rest)} moves (lines {rest[0].first_line}"
                           f"..{max(r.last_line for r in rest)}; see verify.json's loads)")
        return out


def describe_tool(number: int, tool: Tool | None) -> str:
    """``T2 (ball 6 mm)``."""
    if tool is None:
        return f"T{number}"
    corner = f" r{tool.corner_radius:g}" if tool.shape is ToolShape.BULLNOSE else ""
    return f"T{number} ({tool.shape.value} {tool.diameter:g} mm{corner})"


def check_loads(job: JobSimulation, limits: dict[int, LoadLimits],
                design: np.ndarray | None = None) -> LoadCheck:
    """Every cutting feed move of a tool in ``limits`` against that tool's limits (an end
    mill's entries: axial and rate only), one :class:`Overload` per program move and quantity
    (the largest of its linearised pieces), grouped into regions (see the module docstring).
    ``design`` (the Z-map's shape, mm, NaN off the model) is the floor under the stock a
    region's moves meet; without it, or off the model, the block's bottom (if it has one,
    else the moves' tips)."""
    seg = job.segments
    n = len(seg)
    rapid = np.asarray(seg.rapid, bool)
    cutting = ~rapid & (job.axial > job.threshold_mm)
    rate = job.rate if job.rate is not None else np.full(n, np.nan)
    deepest = job.deepest if job.deepest is not None else \
        0.5 * (seg.start[:, :2] + seg.end[:, :2])
    low = np.minimum(seg.start[:, 2], seg.end[:, 2]) if n else np.zeros(0)
    found: dict[tuple[int, str], tuple[int, float, float]] = {}  # (move, qty) -> (seg, v, lim)
    for number, lim in sorted(limits.items()):
        mine = cutting & (job.tool == number)
        tool = job.tools[number].tool if number in job.tools else None
        exempt = job.entry if tool is not None and tool.shape is not ToolShape.BALL \
            else np.zeros(n, bool)
        wide = mine & ~exempt
        if lim.radial_from_depth_mm is not None:
            wide &= job.axial > lim.radial_from_depth_mm
        for quantity, values, mask in (("axial", job.axial, mine),
                                       ("radial", job.radial, wide),
                                       ("removal_rate", rate, mine)):
            limit = getattr(lim, _QUANTITIES[quantity][0])
            if limit is None:
                continue
            with np.errstate(invalid="ignore"):
                over = np.flatnonzero(mask & (values > limit))
            for s in over.tolist():
                key = (int(seg.move[s]), quantity)
                if key not in found or values[s] > found[key][1]:
                    found[key] = (s, float(values[s]), float(limit))
    overloads = []
    for (move, quantity), (s, value, limit) in found.items():
        overloads.append(Overload(int(job.tool[s]), int(seg.line[s]), move, quantity, value,
                                  limit, float(deepest[s, 0]), float(deepest[s, 1]),
                                  float(low[s])))
    overloads.sort(key=lambda o: (o.move, o.quantity))
    regions = _regions(job, overloads, design)
    return LoadCheck(dict(limits), tuple(overloads), regions)


def _regions(job: JobSimulation, overloads: list[Overload],
             design: np.ndarray | None) -> tuple[OverloadRegion, ...]:
    """The overloads of each tool grouped by the coarse cells (a tool diameter wide) of their
    deepest points, 8-connected; per group its box, Z range, stock thickness and lines."""
    out = []
    before = _stock_before(job)
    grid = job.grid
    floor = np.full((grid.ny, grid.nx), float(job.stock[4]))
    if design is not None:
        floor = np.where(np.isfinite(design), design, floor)
    for number in sorted({o.tool for o in overloads}):
        mine = [o for o in overloads if o.tool == number]
        size = max(job.tools[number].tool.diameter if number in job.tools else 1.0, grid.cell)
        xy = np.array([(o.x, o.y) for o in mine])
        keys = np.floor((xy - xy.min(axis=0)) / size).astype(np.int64)
        label = _components(keys)
        heights = before.get(number)
        for group in range(int(label.max()) + 1):
            members = [o for o, g in zip(mine, label.tolist()) if g == group]
            pts = xy[label == group]
            z = np.array([o.z for o in members])
            stock = 0.0
            if heights is not None:
                ix = np.clip(((pts[:, 0] - grid.x0) / grid.cell).astype(int), 0, grid.nx - 1)
                iy = np.clip(((pts[:, 1] - grid.y0) / grid.cell).astype(int), 0, grid.ny - 1)
                met = heights[iy, ix] - np.where(np.isfinite(floor[iy, ix]), floor[iy, ix], z)
                met = met[np.isfinite(met)]
                stock = float(max(met.max(), 0.0)) if len(met) else 0.0
            lines = [o.line for o in members]
            out.append(OverloadRegion(
                number, float(pts[:, 0].min()), float(pts[:, 0].max()), float(pts[:, 1].min()),
                float(pts[:, 1].max()), float(z.min()), float(z.max()), stock, min(lines),
                max(lines), len({o.move for o in members})))
    out.sort(key=lambda r: (r.tool, r.first_line))
    return tuple(out)


def _stock_before(job: JobSimulation) -> dict[int, np.ndarray]:
    """Per tool, the Z-map it started from: the snapshot of the tool whose moves came before
    its first move (tools in the order of their first moves), the block for the first."""
    order = []
    for number in job.tool.tolist():
        if number not in order:
            order.append(number)
    first, _ = initial_height(job.grid, job.cylinder if job.cylinder is not None
                              else job.stock)
    out = {}
    previous = np.asarray(first, dtype=float)
    for number in order:
        out[number] = previous
        if number in job.snapshots:
            previous = job.snapshots[number]
    return out


def _components(keys: np.ndarray) -> np.ndarray:
    """Labels 0..k-1 of the 8-connected components of the integer cells ``keys`` (m, 2),
    numbered in the order of their first member."""
    cells = {}
    for i, (a, b) in enumerate(map(tuple, keys.tolist())):
        cells.setdefault((a, b), []).append(i)
    parent = {c: c for c in cells}

    def root(c):
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    for a, b in cells:
        for da in (-1, 0, 1):
            for db in (-1, 0, 1):
                other = (a + da, b + db)
                if other in cells:
                    ra, rb = root((a, b)), root(other)
                    if ra != rb:
                        parent[rb] = ra
    label = np.empty(len(keys), np.intp)
    names: dict = {}
    for i, key in enumerate(map(tuple, keys.tolist())):
        label[i] = names.setdefault(root(key), len(names))
    return label
