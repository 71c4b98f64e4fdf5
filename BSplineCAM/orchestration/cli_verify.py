# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam verify NET|PART PROGRAM --tool-diameter D --out DIR``: simulate and measure G-code
(a part: ``--faces up|all|3,8``, measured against its exact faces).

Writes DIR/verify.json (metrics, see ``core/verify.py`` for the definitions), DIR/deviation.png
and DIR/simulated.png, all or nothing.

A program with tool changes (M6 to more than one tool) is simulated with each move's tool from
``--tools T1=flat:10,T2=ball:6`` or ``--tool-table FILE`` (a LinuxCNC tool table), which replace
--tool-diameter/--tool-shape; ``--stock x0,x1,y0,y1,z0,z1`` (mm) starts from that block.
Either adds a ``tools`` section to verify.json with the per-tool figures
(``core/job_simulation.py``).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..core import Surface
from ..core.errors import ParameterError
from ..core.geometry.faces_height import FacesHeight
from ..core.geometry.footprint import footprint_bounds
from ..core.geometry.netio import MAX_COORDINATE_MM
from ..core.program.gcode import read_gcode_file
from ..core.program.tooltable import check_program_tools, parse_tools_option, read_tool_table
from ..core.simulation.load_limits import (
    LoadLimits,
    default_limits,
    parse_limit_fields,
    parse_load_limits,
    with_fields,
)
from ..core.simulation.machining_time import (
    DEFAULT_ACCELERATION,
    DEFAULT_JUNCTION_DEVIATION,
    MachineLimits,
    machining_time,
    parse_axis_values,
)
from ..core.simulation.simulate import Tool, ToolShape, zmap_shape
from ..core.simulation.verify import (
    DEFAULT_COVERAGE_TOLERANCE,
    DEFAULT_RAPID_RATE,
    DEFAULT_STOCK_MARGIN,
    StockTop,
    verify,
    verify_faces,
    verify_job,
)
from ..core.toolpath.common import (
    MAX_TOOL_DIAMETER,
    MIN_TOOL_DIAMETER,
    RAPID_RANGE,
    check_range,
    check_tool_fits,
)
from . import parts, report
from .cli_common import (
    EXIT_CHECK_FAILED,
    check_interrupted,
    check_output,
    emit,
    json_text,
    staged_output,
    with_engine,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``verify`` subcommand."""
    p = subparsers.add_parser("verify", help="simulate G-code on a Z-map and measure gouge, "
                                             "scallop and coverage against the design")
    p.add_argument("net", help="control net: .json (canonical), .csv or .dat; or a part "
                               "(.step, .stp, .brep, .FCStd)")
    p.add_argument("program", help="G-code program (.ngc, .nc, .gcode)")
    p.add_argument("--faces", default=None,
                   help="faces of a part the program machines: up (default) or numbers "
                        "such as 3,8,20")
    p.add_argument("--knots", choices=["uniform", "clamped"],
                   help="override the file's knot layout")
    p.add_argument("--tool-diameter", type=float, default=None,
                   help="cutter diameter (mm); or --tools / --tool-table")
    p.add_argument("--tool-shape", choices=[s.value for s in ToolShape], default="ball",
                   help="cutter end (default ball)")
    p.add_argument("--corner-radius", type=float, default=0.0,
                   help="corner radius of a bull-nose cutter (mm)")
    p.add_argument("--tools", default=None,
                   help="tools by number for programs with tool changes: T1=flat:10,T2=ball:6,"
                        "T3=bullnose:10:1 (shape:diameter[:corner radius], mm)")
    p.add_argument("--tool-table", default=None,
                   help="LinuxCNC tool table giving the tools by number (D in mm; the comment "
                        "names the shape: ball, bullnose r1.5, else flat)")
    p.add_argument("--load-limit", action="append", default=None, metavar="N:LIMITS",
                   help="load limits of tool N: N:axial=MM,radial=MM,rate=MM3_PER_MIN, any of "
                        "them (the others keep the tool's defaults, none lifts one); "
                        "repeatable; a move over one fails the check (exit 1).  Simulates the "
                        "whole program (as --stock)")
    p.add_argument("--stock", default=None,
                   help="stock block x0,x1,y0,y1,z0,z1 (mm) to simulate from (default: the "
                        "grid's extent, top from --stock-top)")
    p.add_argument("--cell", type=float, default=0.1, help="Z-map cell size (mm, default 0.1)")
    p.add_argument("--stock-top", choices=[s.value for s in StockTop], default="design",
                   help="stock top: design maximum + --stock-margin (default), the program's "
                        "highest feed move, or model: the design raised by --stock-margin "
                        "cell by cell (a part roughed to within it; one finishing program)")
    p.add_argument("--stock-margin", type=float, default=DEFAULT_STOCK_MARGIN,
                   help=f"stock above the design's top, or above the design cell by cell with "
                        f"--stock-top model (mm, default {DEFAULT_STOCK_MARGIN:g})")
    p.add_argument("--rapid-rate", "--rapid", type=float, default=DEFAULT_RAPID_RATE,
                   help=f"rapid traverse rate for the time estimates, also each axis's "
                        f"velocity limit (mm/min, default {DEFAULT_RAPID_RATE:g})")
    add_machine_options(p)
    p.add_argument("--coverage-tolerance", type=float, default=DEFAULT_COVERAGE_TOLERANCE,
                   help="a cell counts as finished within this much of the design (mm, default "
                        f"{DEFAULT_COVERAGE_TOLERANCE:g})")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_verify)


#: Ranges of the numeric options: (option, unit, low, high, low excluded).
STOCK_MARGIN_RANGE = (0.0, 1000.0)
CELL_RANGE = (1e-3, 100.0)
COVERAGE_TOLERANCE_RANGE = (0.0, 100.0)


def add_machine_options(p: argparse.ArgumentParser) -> None:
    """Options of the machine model behind ``machining_time_with_acceleration_s``."""
    p.add_argument("--accel", default=str(DEFAULT_ACCELERATION),
                   help="axis acceleration for the machine time: one value or X,Y,Z "
                        f"(mm/s^2, default {DEFAULT_ACCELERATION:g})")
    p.add_argument("--junction-deviation", type=float, default=DEFAULT_JUNCTION_DEVIATION,
                   help="corner speed model as grbl's (mm, default "
                        f"{DEFAULT_JUNCTION_DEVIATION:g})")


def check_machine_limits(args: argparse.Namespace):
    """--accel, --rapid-rate and --junction-deviation as validated MachineLimits."""
    accel = parse_axis_values(args.accel, "--accel", "mm/s^2")
    return MachineLimits.checked(accel, args.rapid_rate, args.junction_deviation,
                                 names=("--accel", "--rapid-rate", "--junction-deviation",
                                        "--rapid-rate"))


def machine_time_metrics(args: argparse.Namespace, program) -> dict:
    """The program's time on the machine of the options, for verify.json."""
    return machining_time(program, check_machine_limits(args)).metrics()


def check_options(args: argparse.Namespace) -> Tool | None:
    """Every numeric option finite and in range, errors naming the option and its unit; the
    tool of --tool-diameter, or None when --tools or --tool-table gives the tools."""
    given = [o for o, v in (("--tools", getattr(args, "tools", None)),
                            ("--tool-table", getattr(args, "tool_table", None))) if v is not None]
    if len(given) > 1:
        raise ParameterError("--tools and --tool-table exclude each other: give one")
    if given:
        for option, value, default in (("--tool-diameter", args.tool_diameter, None),
                                       ("--tool-shape", args.tool_shape, "ball"),
                                       ("--corner-radius", args.corner_radius, 0.0)):
            if value != default:
                raise ParameterError(f"{given[0]} replaces {option}: give one of them")
    elif args.tool_diameter is None:
        raise ParameterError("--tool-diameter (mm), --tools or --tool-table is required")
    check_range(args.cell, "--cell", "mm", *CELL_RANGE)
    check_range(args.stock_margin, "--stock-margin", "mm", *STOCK_MARGIN_RANGE)
    check_range(args.rapid_rate, "--rapid-rate", "mm/min", *RAPID_RANGE)
    check_machine_limits(args)
    check_range(args.coverage_tolerance, "--coverage-tolerance", "mm",
                *COVERAGE_TOLERANCE_RANGE, low_open=True)
    if getattr(args, "stock", None) is not None:
        parse_stock(args.stock)
    load_limit_fields(args)
    if given:
        return None
    d = check_range(args.tool_diameter, "--tool-diameter", "mm", MIN_TOOL_DIAMETER,
                    MAX_TOOL_DIAMETER)
    corner = check_range(args.corner_radius, "--corner-radius", "mm", 0.0, d / 2.0)
    try:
        return Tool(d, ToolShape.parse(args.tool_shape), corner)
    except ParameterError as exc:
        raise ParameterError(f"--tool-shape {args.tool_shape} / --corner-radius: {exc}") from None


#: Stock values and their names, for --stock.
_STOCK_NAMES = ("x0", "x1", "y0", "y1", "z0", "z1")


def parse_stock(text: str) -> tuple[float, float, float, float, float, float]:
    """--stock x0,x1,y0,y1,z0,z1 (mm), finite, each pair increasing, within the machine's
    reach; ParameterError naming --stock otherwise."""
    items = text.split(",")
    if len(items) != 6:
        raise ParameterError(f"--stock must be six numbers x0,x1,y0,y1,z0,z1 (mm), got {text!r}")
    values = []
    for v, name in zip(items, _STOCK_NAMES):
        v = v.strip()
        if len(v) > 40:
            raise ParameterError(f"--stock {name}: {v[:20]!r}... is not a length (mm)")
        values.append(check_range(v, f"--stock {name}", "mm", -MAX_COORDINATE_MM,
                                  MAX_COORDINATE_MM))
    for a in (0, 2, 4):
        if not values[a] < values[a + 1]:
            raise ParameterError(f"--stock: {_STOCK_NAMES[a]} ({values[a]:g} mm) must be below "
                                 f"{_STOCK_NAMES[a + 1]} ({values[a + 1]:g} mm)")
    return tuple(values)


def load_limit_fields(args: argparse.Namespace) -> dict[int, dict]:
    """--load-limit N:axial=..,radial=..,rate=.. (repeatable) as {N: the LoadLimits fields
    given}; ParameterError naming --load-limit and the unit."""
    out: dict[int, dict] = {}
    for text in getattr(args, "load_limit", None) or []:
        number, _ = parse_load_limits(text, "--load-limit")
        if number in out:
            raise ParameterError(f"--load-limit {text}: T{number} is given twice")
        out[number] = parse_limit_fields(text.partition(":")[2], "--load-limit")
    return out


def load_limits_for(args: argparse.Namespace, tools: dict[int, Tool]) -> dict[int, LoadLimits]:
    """Each tool's default load limits with --load-limit's fields over them; a tool number
    the program's tools lack is a ParameterError naming --load-limit."""
    given = load_limit_fields(args)
    for number in given:
        if number not in tools:
            raise ParameterError(f"--load-limit: T{number} is not among the program's tools "
                                 f"(T{', T'.join(str(n) for n in sorted(tools))})")
    return {n: with_fields(default_limits(t), given.get(n, {})) for n, t in tools.items()}


def job_tools(args: argparse.Namespace, tool: Tool | None, program) -> dict[int, Tool] | None:
    """Tools by number for the program: from --tools / --tool-table, or --tool-diameter's tool
    for every tool of a program with at most one (None then, unless --stock asks for the
    whole-program simulation, or --load-limit); a program changing between tools needs
    --tools/--tool-table."""
    if args.tools is not None:
        tools = parse_tools_option(args.tools)
    elif args.tool_table is not None:
        tools = read_tool_table(args.tool_table)
    else:
        used = sorted({n for _, n in program.tool_changes if n > 0})
        if len(used) > 1:
            raise ParameterError(
                f"{program.source} changes tools ({', '.join(f'T{n}' for n in used)}): give "
                "them with --tools T1=flat:10,T2=ball:6 or --tool-table FILE instead of "
                "--tool-diameter")
        if args.stock is None and not getattr(args, "load_limit", None):
            return None
        tools = {n: tool for n in [0, *used]}
    check_program_tools(program, tools)
    return tools


def _tools_fit(model, tools: dict[int, Tool]) -> None:
    for n, t in sorted(tools.items()):
        check_tool_fits(model, t.diameter, f"tool T{n} diameter")


def cmd_verify(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    tool = check_options(args)
    check_output(args.out)
    if parts.is_part(args.net):
        return cmd_verify_part(args, tool)
    parts.refuse_faces_on_net(args.faces, args.net)
    surface = Surface.from_file(args.net, args.knots)
    if tool is not None:
        check_tool_fits(surface, tool.diameter, "--tool-diameter")
    x0, x1, y0, y1 = footprint_bounds(surface)
    stock = None if args.stock is None else parse_stock(args.stock)
    if stock is not None:
        x0, x1, y0, y1 = min(x0, stock[0]), max(x1, stock[1]), min(y0, stock[2]), max(y1, stock[3])
    zmap_shape(x1 - x0, y1 - y0, args.cell, "--cell")
    program = read_gcode_file(args.program)
    tools = job_tools(args, tool, program)
    if tools is None:
        result = verify(surface, program, tool, cell=args.cell, stock_top=args.stock_top,
                        stock_margin=args.stock_margin, rapid_rate=args.rapid_rate,
                        coverage_tolerance=args.coverage_tolerance)
    else:
        _tools_fit(surface, tools)
        result = verify_job(surface, program, tools, stock, cell=args.cell,
                            stock_top=args.stock_top, stock_margin=args.stock_margin,
                            rapid_rate=args.rapid_rate,
                            coverage_tolerance=args.coverage_tolerance,
                            load_limits=load_limits_for(args, tools))
    check_interrupted()
    metrics = {"net": str(Path(args.net)), "program": str(Path(args.program)), **result.metrics,
               **machine_time_metrics(args, program),
               "elapsed_s": round(time.perf_counter() - started, 3)}
    return write_results(args, result, metrics)


def cmd_verify_part(args: argparse.Namespace, tool: Tool | None) -> int:
    """``verify PART PROGRAM --faces up|all|3,8``: the program measured against the part's
    exact faces (``core.verify.verify_faces``): gouge over the whole model, scallop and
    coverage on the selected faces away from their borders; the same outputs as for a net,
    plus the selected and check faces."""
    started = time.perf_counter()
    if args.knots is not None:
        raise ParameterError(f"--knots applies to control nets, not to the part {args.net}")
    parts.parse_faces(args.faces, allow_all=True)
    faces = parts.load_faces(args.net, args.faces, allow_all=True)
    check_interrupted()
    program = read_gcode_file(args.program)
    result = verify_faces_checked(args, faces, program, tool)
    check_interrupted()
    metrics = {"part": str(Path(args.net)), "program": str(Path(args.program)),
               **result.metrics, **machine_time_metrics(args, program),
               "elapsed_s": round(time.perf_counter() - started, 3)}
    return write_results(args, result, metrics, ("faces", "check_faces"))


def _job_summary(metrics: dict) -> dict:
    """The per-tool lines of the stdout summary."""
    if "tools" not in metrics:
        return {}
    keys = ("removed_volume_mm3", "radial_engagement_max_mm", "axial_engagement_max_mm",
            "material_removal_rate_max_mm3_per_min", "rapid_collisions")
    return {"tools": {n: {k: t[k] for k in keys} for n, t in metrics["tools"].items()}}


#: The figures of verify.json the command prints on stdout.
SUMMARY = ("gouge_max_mm", "scallop_max_mm", "scallop_p99_mm", "scallop_mean_mm",
           "scallop_evenness", "scallop_mean_over_max", "edge_scallop_max_mm",
           "coverage", "rapid_collisions", "cutting_length_mm", "machining_time_s",
           "machining_time_with_acceleration_s")
#: Figures printed too where verify.json has them: the gouge along the design's normal
#: (parts measured with a ball; a net's gouge is the vertical one).
SUMMARY_WHEN_MEASURED = ("gouge_normal_max_mm", "gouge_normal_unmeasured_max_mm")


def write_results(args: argparse.Namespace, result, metrics: dict, extra: tuple = ()) -> int:
    """--out/verify.json, deviation.png and simulated.png (all or nothing), the warnings on
    stderr and the summary (``SUMMARY`` + ``extra``) on stdout; exit status 0, or
    EXIT_CHECK_FAILED with one "check failed" line per region of moves over their tool's load
    limits (a whole-program simulation)."""
    with staged_output(Path(args.out)) as stage:
        report.plot_deviation(result, stage / "deviation.png")
        report.plot_simulated(result, stage / "simulated.png")
        (stage / "verify.json").write_text(json_text(with_engine(metrics)), encoding="utf-8")
    for warning in metrics.get("warnings", []):
        print(f"bsplinecam verify: warning: {warning}", file=sys.stderr)
    summary = {k: metrics[k] for k in SUMMARY + tuple(extra)}
    if metrics.get("gouge_normal_measured"):
        summary.update({k: metrics[k] for k in SUMMARY_WHEN_MEASURED if k in metrics})
    summary.update(_job_summary(metrics))
    loads = getattr(result, "loads", None)
    if loads is not None:
        summary["loads_ok"] = loads.ok
        summary["overloaded_moves"] = loads.overloaded_moves
    emit({"out": str(Path(args.out).resolve()), **summary,
          "warnings": metrics.get("warnings", [])})
    if loads is not None and not loads.ok:
        tools = {n: figures.tool for n, figures in result.job.tools.items()}
        for line in loads.messages(tools):
            print(f"bsplinecam verify: check failed: {line}; see "
                  f"{Path(args.out) / 'verify.json'}", file=sys.stderr)
        return EXIT_CHECK_FAILED
    return 0


def verify_faces_checked(args: argparse.Namespace, faces, program, tool: Tool | None):
    """``core.verify.verify_faces`` (``verify_job`` with --tools, --tool-table or --stock)
    after the Z-map size check over the part's and the stock's extent."""
    x0, x1, y0, y1 = FacesHeight(faces, args.cell).bounds()
    x0, x1, y0, y1 = x0 - args.cell, x1 + args.cell, y0 - args.cell, y1 + args.cell
    stock = None if getattr(args, "stock", None) is None else parse_stock(args.stock)
    if stock is not None:
        x0, x1, y0, y1 = min(x0, stock[0]), max(x1, stock[1]), min(y0, stock[2]), max(y1, stock[3])
    zmap_shape(x1 - x0, y1 - y0, args.cell, "--cell")
    tools = job_tools(args, tool, program) if hasattr(args, "tools") else None
    if tools is not None:
        return verify_job(faces, program, tools, stock, cell=args.cell,
                          stock_top=args.stock_top, stock_margin=args.stock_margin,
                          rapid_rate=args.rapid_rate,
                          coverage_tolerance=args.coverage_tolerance,
                          load_limits=load_limits_for(args, tools))
    return verify_faces(faces, program, tool, cell=args.cell, stock_top=args.stock_top,
                        stock_margin=args.stock_margin, rapid_rate=args.rapid_rate,
                        coverage_tolerance=args.coverage_tolerance)
