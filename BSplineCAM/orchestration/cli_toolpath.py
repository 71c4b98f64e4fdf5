# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam toolpath``: surface → FreeCAD job → finishing op → post-processed G-code.

Writes DIR/NAME.ngc (checked by LinuxCNC's rs274 when installed), DIR/toolpath.json and
DIR/NAME-job.FCStd.  Every argument is validated before any work, and the output folder
receives nothing unless all steps succeed.
"""

from __future__ import annotations

import argparse
import importlib.util
from pathlib import Path

from ..core import BSplineCAMError, Surface
from ..core.errors import ParameterError
from ..core.program import rs274
from ..core.toolpath import check_request
from ..core.toolpath.common import (
    CuttingParameters,
    Direction,
    IsoDirection,
    Strategy,
    ToolParameters,
    check_angle,
)
from . import parts
from .cli_common import (
    EXIT_CHECK_FAILED,
    _safe_name,
    add_retract_options,
    check_output,
    check_retract_options,
    emit,
    json_text,
    staged_output,
    with_engine,
)
from .pipeline_run import (
    DEFAULT_RAPID,
    check_posts,
    cutting_parameters,
    freecad_cutting,
    run_pipeline,
)

#: Option names, in the order the core's validators take them.
TOOL_OPTIONS = ("--tool-diameter", "--scallop", "--tolerance", "--angle")


def register(sub) -> None:
    p = sub.add_parser("toolpath", help="ball-end finishing toolpath on the exact surface, posted to G-code")
    p.add_argument("net", help="control net (.json, .csv, .dat) or part (.step, .stp, .brep, .FCStd)")
    p.add_argument("--knots", choices=["uniform", "clamped"], help="override the file's knot layout")
    p.add_argument("--faces", default=None,
                   help="faces of a part to machine: up (default) or numbers such as 3,8,20")
    p.add_argument("--tool-diameter", type=float, required=True, help="ball-end diameter (mm)")
    p.add_argument("--scallop", type=float, required=True, help="largest scallop height left (mm)")
    p.add_argument("--tolerance", type=float, default=0.002, help="chordal tolerance along passes (mm, default 0.002)")
    p.add_argument("--strategy", default="raster", choices=[s.value for s in Strategy])
    p.add_argument("--angle", type=float, default=0.0, help="raster direction from +X (degrees)")
    p.add_argument("--direction", default="zigzag", choices=[d.value for d in Direction])
    p.add_argument("--iso-direction", default="u", choices=[d.value for d in IsoDirection])
    p.add_argument("--arcs", default="on", choices=["on", "off"],
                   help="fit passes with one-sided G2/G3 arcs in their plane (default on)")
    add_retract_options(p, start_stock=True)
    p.add_argument("--post", default="linuxcnc", help="FreeCAD post-processor (linuxcnc, grbl, fanuc, mach3_mach4, ...)")
    p.add_argument("--feed", type=float, default=1200.0, help="cutting feed (mm/min)")
    p.add_argument("--plunge-feed", type=float, default=400.0, help="vertical feed (mm/min)")
    p.add_argument("--spindle", type=float, default=12000.0, help="spindle speed (rpm)")
    p.add_argument("--rapid", type=float, default=DEFAULT_RAPID, help="rapid rate for the time estimate (mm/min)")
    p.add_argument("--no-rs274", action="store_true", help="do not check the program with LinuxCNC's rs274")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_toolpath)


def cmd_toolpath(args: argparse.Namespace) -> int:
    # Everything the FreeCAD op would refuse is refused here first, with the core's own checks,
    # so that no refusal happens inside a recompute (whose traceback FreeCAD prints).
    cutting_params = cutting_parameters(args)
    check_retract_options(args)
    check_output(args.out)
    if parts.is_part(args.net):
        return cmd_toolpath_part(args, cutting_params)
    parts.refuse_faces_on_net(args.faces, args.net)
    surface = Surface.from_file(args.net, args.knots)
    strategy, tool, angle = check_request(surface, args.strategy, args.tool_diameter,
                                          args.scallop, args.tolerance, args.angle, TOOL_OPTIONS)
    from ..app import pipeline

    check_posts([args.post])
    params = pipeline.FinishingParameters(
        tool_diameter=tool.diameter, scallop=tool.scallop, tolerance=tool.tolerance,
        strategy=strategy.value, angle=angle, direction=args.direction,
        iso_direction=args.iso_direction, arcs=args.arcs == "on", retract=args.retract,
        retract_margin=args.retract_margin, start_stock=args.start_stock,
        stock_allowance=args.stock_allowance)
    cutting = freecad_cutting(cutting_params)
    name = _safe_name(surface.name)
    with staged_output(Path(args.out)) as stage:
        program = stage / f"{name}.ngc"
        report = run_pipeline(
            lambda: pipeline.machine(surface, params, program, args.post, cutting,
                                     stage / f"{name}-job.FCStd"),
            program, cutting_params.rapid)
        report["parameters"] = {
            "strategy": strategy.value, "angle_deg": angle, "direction": args.direction,
            "iso_direction": args.iso_direction, "arcs": args.arcs,
            "retract": args.retract, "retract_margin_mm": args.retract_margin,
            "start_stock": args.start_stock, "stock_allowance_mm": args.stock_allowance,
            "tool_diameter_mm": tool.diameter,
            "scallop_mm": tool.scallop, "tolerance_mm": tool.tolerance}
        report["angle_deg"] = angle
        if not args.no_rs274 and rs274.available():
            check = rs274.check(program, {1: tool.diameter})
            report["rs274"] = check.as_dict()
            if not check.ok:
                emit(report)
                raise BSplineCAMError(f"{program.name}: LinuxCNC's rs274 rejects the program: {check.message}")
        (stage / "toolpath.json").write_text(json_text(with_engine(report)))
    emit(report)
    return 0 if report.get("rs274", {"ok": True})["ok"] else EXIT_CHECK_FAILED


#: The multi-face raster generator (issue 11); parts are refused until it is present.
FACES_RASTER = "BSplineCAM.core.toolpath.faces_raster"


def faces_raster_available() -> bool:
    """True when the multi-face toolpath module can be imported."""
    try:
        return importlib.util.find_spec(FACES_RASTER) is not None
    except ImportError:
        return False


def cmd_toolpath_part(args: argparse.Namespace, cutting_params: CuttingParameters) -> int:
    """``toolpath PART --faces up|3,8,20``: the faces' raster, waterline or isoparametric
    passes over the multi-face drop-cutter."""
    if args.knots is not None:
        raise ParameterError(f"--knots applies to control nets, not to the part {args.net}")
    selection = parts.parse_faces(args.faces)
    if not faces_raster_available():
        raise ParameterError(f"{args.net}: toolpaths on parts need the multi-face raster "
                             f"({FACES_RASTER}), which this build does not have yet; "
                             "machine a control net (.json, .csv, .dat) instead")
    if args.strategy != Strategy.WATERLINE.value and args.direction != Direction.ZIGZAG.value:
        raise ParameterError(f"--direction {args.direction}: {args.strategy} on parts runs "
                             "zigzag only")
    tool = ToolParameters.validate(args.tool_diameter, args.scallop, args.tolerance,
                                   TOOL_OPTIONS[:3])
    angle = check_angle(args.angle, TOOL_OPTIONS[3])
    faces = parts.load_faces(args.net, parts._selection_text(selection),
                             chordal_tolerance=tool.tolerance)
    return parts.machine_faces(args, faces, tool, angle, cutting_params)
