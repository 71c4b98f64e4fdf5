# SPDX-License-Identifier: LGPL-2.1-or-later
"""What ``bsplinecam toolpath`` and ``bsplinecam job`` share around ``app.pipeline.machine``.

Both check the feeds and the post-processors before any work (so that no refusal happens
inside a FreeCAD recompute, whose traceback FreeCAD prints), run the pipeline with FreeCAD's
console held, turn the op's refusal (ValueError) into the command's ParameterError, and add
the program's cutting length and machining time, measured on its own text, to the report.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Iterable
from pathlib import Path

from ..app import compat
from ..core.errors import ParameterError
from ..core.program.gcode import MoveKind, read_gcode
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


def machining_time(gcode: str, rapid: float = DEFAULT_RAPID) -> tuple[float, float]:
    """(cutting length mm, machining time s) of a program, from its own text and feeds."""
    program = read_gcode(gcode, "program", require_end=False)
    lengths = program.lengths()
    rapid_mask = program.kind == MoveKind.RAPID
    cutting = float(lengths[~rapid_mask].sum())
    minutes = float((lengths[~rapid_mask] / program.feed[~rapid_mask]).sum()) + float(lengths[rapid_mask].sum()) / rapid
    return cutting, 60.0 * minutes


def run_pipeline(run: Callable[[], dict], program: Path, rapid: float) -> dict:
    """``run()`` (app.pipeline.machine writing ``program``) with FreeCAD's console held; the
    op's ValueError becomes a ParameterError, an interruption stops here.  Returns its report
    with the program's name, cutting length (mm) and machining time (s) at ``rapid``
    (mm/min)."""
    try:
        with captured_console():
            report = run()
    except ValueError as exc:
        check_interrupted()
        raise ParameterError(str(exc)) from None
    check_interrupted()
    report["cutting_length_mm"], report["machining_time_s"] = (
        round(v, 3) for v in machining_time(program.read_text(), rapid))
    report["program"] = program.name
    return report
