# SPDX-License-Identifier: LGPL-2.1-or-later
"""What ``bsplinecam toolpath`` and ``bsplinecam job`` share around ``app.pipeline.machine``.

Both check the feeds and the post-processors before any work (so that no refusal happens
inside a FreeCAD recompute, whose traceback FreeCAD prints), run the pipeline with FreeCAD's
console held, turn the op's refusal (ValueError) into the command's ParameterError, and add
the program's cutting, rapid and air length and machining time (nominal and with
acceleration), measured on its own text, to the report.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from pathlib import Path

from ..app import compat
from ..core.errors import ParameterError
from ..core.program.gcode import read_gcode
from ..core.simulation.machining_time import MachineLimits
from ..core.simulation.measures import program_measures
from ..core.toolpath.common import CuttingParameters
from .cli_common import captured_console, check_interrupted

#: Option names, in the order CuttingParameters.validate takes them.
CUTTING_OPTIONS = ("--feed", "--plunge-feed", "--spindle", "--rapid")

#: Rapid rate of the time estimates when none is given (mm/min).
DEFAULT_RAPID = 5000.0


def cutting_parameters(args: argparse.Namespace) -> CuttingParameters:
    """--feed, --plunge-feed (mm/min), --spindle (rpm) and --rapid (mm/min), checked; errors
    name the option and its unit.  No FreeCAD needed."""
    return CuttingParameters.validate(args.feed, args.plunge_feed, args.spindle, args.rapid,
                                      CUTTING_OPTIONS)


def check_posts(posts: Iterable[str], option: str = "--post") -> None:
    """Refuse, before any work, a post-processor name that FreeCAD does not have (the
    ParameterError names ``option``).  Needs FreeCAD."""
    for post in posts:
        try:
            compat.post_module(post)
        except ValueError as exc:
            raise ParameterError(f"{option}: {' '.join(str(exc).split())}") from None


def freecad_cutting(cutting: CuttingParameters):
    """The checked feeds (mm/min) and spindle speed (rpm) as the app layer's cam.Cutting."""
    from ..app import cam

    return cam.Cutting(cutting.feed, cutting.plunge_feed, cutting.spindle, cutting.rapid)


def program_figures(gcode: str, rapid: float = DEFAULT_RAPID,
                    along_passes_mm: float | None = None) -> dict:
    """The program's figures of :mod:`BSplineCAM.core.simulation.measures`, measured on its
    own text (mm, s, rounded to 3 decimals): cutting and rapid length, machining time nominal
    and with acceleration (the default machine, rapids at ``rapid`` mm/min), and the air
    length when ``along_passes_mm``, the length along its passes, is known."""
    program = read_gcode(gcode, "program", require_end=False)
    limits = MachineLimits(rapid_rate=float(rapid))
    figures = program_measures(program, along_passes_mm, limits)
    return {k: round(v, 3) for k, v in figures.items()}


def run_pipeline(run: Callable[[], dict], program: Path, rapid: float) -> dict:
    """``run()`` (app.pipeline.machine writing ``program``) with FreeCAD's console held; the
    op's ValueError becomes a ParameterError, an interruption stops here.  Returns its report
    with the program's name and :func:`program_figures` at ``rapid`` (mm/min); the air length
    when the report tells the length along the passes (a finishing op's alone)."""
    try:
        with captured_console():
            report = run()
    except ValueError as exc:
        check_interrupted()
        raise ParameterError(str(exc)) from None
    check_interrupted()
    along = None
    if "roughing" not in report and "link_length_mm" in report:
        along = report["pass_length_mm"] - report["link_length_mm"] + report.get(
            "rest", {}).get("pass_length_mm", 0.0)
    report.update(program_figures(program.read_text(), rapid, along))
    report["program"] = program.name
    return report
