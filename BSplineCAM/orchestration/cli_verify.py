# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam verify NET PROGRAM --tool-diameter D --out DIR``: simulate and measure G-code.

Writes DIR/verify.json (metrics, see ``core/verify.py`` for the definitions), DIR/deviation.png
and DIR/simulated.png, all or nothing.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from ..core import Surface
from ..core.gcode import read_gcode_file
from ..core.simulate import Tool, ToolShape
from ..core.verify import (
    DEFAULT_COVERAGE_TOLERANCE,
    DEFAULT_RAPID_RATE,
    DEFAULT_STOCK_MARGIN,
    StockTop,
    verify,
)


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``verify`` subcommand."""
    p = subparsers.add_parser("verify", help="simulate G-code on a Z-map and measure gouge, "
                                             "scallop and coverage against the design")
    p.add_argument("net", help="control net: .json (canonical), .csv or .dat")
    p.add_argument("program", help="G-code program (.ngc, .nc, .gcode)")
    p.add_argument("--knots", choices=["uniform", "clamped"],
                   help="override the file's knot layout")
    p.add_argument("--tool-diameter", type=float, required=True, help="cutter diameter (mm)")
    p.add_argument("--tool-shape", choices=[s.value for s in ToolShape], default="ball",
                   help="cutter end (default ball)")
    p.add_argument("--corner-radius", type=float, default=0.0,
                   help="corner radius of a bull-nose cutter (mm)")
    p.add_argument("--cell", type=float, default=0.1, help="Z-map cell size (mm, default 0.1)")
    p.add_argument("--stock-top", choices=[s.value for s in StockTop], default="design",
                   help="stock top: design maximum + --stock-margin (default), or the program's "
                        "highest feed move")
    p.add_argument("--stock-margin", type=float, default=DEFAULT_STOCK_MARGIN,
                   help=f"stock above the design's top (mm, default {DEFAULT_STOCK_MARGIN:g})")
    p.add_argument("--rapid-rate", type=float, default=DEFAULT_RAPID_RATE,
                   help=f"rapid traverse rate for the time estimate (mm/min, default "
                        f"{DEFAULT_RAPID_RATE:g})")
    p.add_argument("--coverage-tolerance", type=float, default=DEFAULT_COVERAGE_TOLERANCE,
                   help="a cell counts as finished within this much of the design (mm, default "
                        f"{DEFAULT_COVERAGE_TOLERANCE:g})")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_verify)


def cmd_verify(args: argparse.Namespace) -> int:
    from . import report
    from .cli import emit, staged_output

    started = time.perf_counter()
    surface = Surface.from_file(args.net, args.knots)
    program = read_gcode_file(args.program)
    tool = Tool(args.tool_diameter, ToolShape.parse(args.tool_shape), args.corner_radius)
    result = verify(surface, program, tool, cell=args.cell, stock_top=args.stock_top,
                    stock_margin=args.stock_margin, rapid_rate=args.rapid_rate,
                    coverage_tolerance=args.coverage_tolerance)
    metrics = {"net": str(Path(args.net)), "program": str(Path(args.program)), **result.metrics,
               "elapsed_s": round(time.perf_counter() - started, 3)}
    with staged_output(Path(args.out)) as stage:
        report.plot_deviation(result, stage / "deviation.png")
        report.plot_simulated(result, stage / "simulated.png")
        (stage / "verify.json").write_text(json.dumps(metrics, indent=1) + "\n", encoding="utf-8")
    summary = {k: metrics[k] for k in ("gouge_max_mm", "scallop_max_mm", "scallop_p99_mm",
                                       "edge_scallop_max_mm", "coverage", "rapid_collisions",
                                       "cutting_length_mm", "machining_time_s")}
    emit({"out": str(Path(args.out).resolve()), **summary})
    return 0
