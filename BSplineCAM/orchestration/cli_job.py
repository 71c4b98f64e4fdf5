# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam job NET --rough flat:10 --finish ball:6 --out DIR``: block to part.

One FreeCAD job: Z-level roughing (flat or bull-nose end mill, T1) from a stock block grown by
``--stock-margin`` around the part down to the part plus ``--allowance``, then the ball-end
finishing op (T2) on the exact surface; one program with tool changes, posted by FreeCAD's
post-processor and checked by LinuxCNC's rs274; then the whole program simulated from the block
(``core.verify.verify_job``): per tool removed volume, engagement, material removal rate, air
cutting and rapid collisions, and the final gouge, scallop and coverage.

Writes DIR/NAME.ngc, DIR/NAME-job.FCStd, DIR/job.json (per-op figures), DIR/verify.json and
pictures of the stock after each tool (DIR/stock-T1.png, DIR/stock-T2.png) with the final
deviation map (DIR/deviation.png), all or nothing.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from ..core import BSplineCAMError, Surface
from ..core.errors import ParameterError
from ..core.program import rs274
from ..core.program.gcode import read_gcode_file
from ..core.program.tooltable import MAX_LINE_CHARS, parse_tool_spec
from ..core.simulation.gouge_normal import gouge_gate_mm
from ..core.simulation.load_limits import (
    ENGAGEMENT_RATIO,
    LoadLimits,
    job_limits,
    parse_limit_fields,
    with_fields,
)
from ..core.simulation.verify import verify_job
from ..core.toolpath import check_request
from ..core.toolpath.common import Strategy, ToolParameters, check_angle, check_range
from ..core.toolpath.roughing import (
    MAX_RAMP_ANGLE_DEG,
    RAMP_ANGLE_DEG,
    check_fine_stepdown,
    check_ramp_angle,
)
from . import parts
from . import report as pictures
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
from .cli_verify import add_machine_options, check_machine_limits, machine_time_metrics
from .pipeline_run import (
    DEFAULT_RAPID,
    check_posts,
    cutting_parameters,
    freecad_cutting,
    run_pipeline,
)

#: Ranges of the roughing options (mm, percent).
STOCK_MARGIN_RANGE = (0.0, 1000.0)
STEPDOWN_RANGE = (0.01, 100.0)
STEPOVER_RANGE = (1.0, 100.0)
ALLOWANCE_RANGE = (0.0, 50.0)


def register(sub) -> None:
    p = sub.add_parser("job", help="block to part: roughing end mill + ball finishing in one "
                       "program with tool changes, verified from the block")
    p.add_argument("net", help="control net (.json, .csv, .dat) or part (.step, .stp, .brep, "
                   ".FCStd)")
    p.add_argument("--knots", choices=["uniform", "clamped"], help="override the file's knot layout")
    p.add_argument("--faces", default=None,
                   help="faces of a part to finish: up (default) or numbers such as 3,8,20; "
                        "the roughing clears the whole part")
    p.add_argument("--stock-margin", type=float, default=2.0,
                   help="stock block around the part, sideways and above (mm, default 2)")
    p.add_argument("--rough", default="flat:10",
                   help="roughing tool SHAPE:DIAMETER[:CORNER], flat, bullnose or ball, mm "
                        "(default flat:10)")
    p.add_argument("--stepdown", type=float, default=2.0, help="roughing Z step (mm, default 2)")
    p.add_argument("--fine-stepdown", type=float, default=0.0,
                   help="terraces no thicker than this: after each --stepdown level, levels "
                        "this far apart in the band above it, cut bottom-up (mm, at most "
                        "--stepdown; default 0: off)")
    p.add_argument("--stepover", type=float, default=40.0,
                   help="roughing width of cut, percent of the roughing diameter (default 40)")
    p.add_argument("--ramp-angle", type=float, default=RAMP_ANGLE_DEG,
                   help="angle at which the roughing's helical and ramped entries descend "
                        f"(degrees, above 0, at most {MAX_RAMP_ANGLE_DEG:g}; default "
                        f"{RAMP_ANGLE_DEG:g})")
    p.add_argument("--allowance", type=float, default=0.3,
                   help="stock to leave after roughing, radial and axial (mm, default 0.3)")
    p.add_argument("--radial-allowance", type=float, default=None,
                   help="sideways stock to leave (mm, default --allowance)")
    p.add_argument("--axial-allowance", type=float, default=None,
                   help="vertical stock to leave (mm, default --allowance)")
    p.add_argument("--no-flat-levels", action="store_true",
                   help="no extra roughing levels at the part's flat areas")
    p.add_argument("--centre-cutting", action="store_true",
                   help="the roughing end mill cuts at its centre: closed pockets too narrow "
                        "for a helix are entered by a straight plunge")
    p.add_argument("--finish", default="ball:6", help="finishing tool ball:DIAMETER (mm)")
    p.add_argument("--rest-limit", type=float, default=1.0,
                   help="rest passes take the roughing's terraces down to this much above the "
                        "part, so the finishing passes over them cut about allowance + scallop "
                        "+ this deep (mm, default 1; 0: no rest passes)")
    p.add_argument("--scallop", type=float, default=0.01, help="largest scallop height (mm)")
    p.add_argument("--tolerance", type=float, default=0.002,
                   help="chordal tolerance along passes (mm, default 0.002)")
    p.add_argument("--strategy", default="raster", choices=[s.value for s in Strategy])
    p.add_argument("--angle", type=float, default=0.0, help="raster direction from +X (degrees)")
    p.add_argument("--arcs", default="on", choices=["on", "off"],
                   help="fit finishing passes with one-sided G2/G3 arcs (default on)")
    add_retract_options(p)
    p.add_argument("--post", default="linuxcnc",
                   help="FreeCAD post-processor(s), comma-separated: the first writes NAME.ngc "
                        "(verified), each other NAME-POST.ngc; every one checked by rs274")
    p.add_argument("--feed", type=float, default=1200.0, help="cutting feed (mm/min)")
    p.add_argument("--plunge-feed", type=float, default=400.0, help="vertical feed (mm/min)")
    p.add_argument("--spindle", type=float, default=12000.0, help="spindle speed (rpm)")
    p.add_argument("--rapid", type=float, default=DEFAULT_RAPID,
                   help="rapid rate for the time estimates (mm/min)")
    p.add_argument("--cell", type=float, default=0.1,
                   help="Z-map cell of the verification (mm, default 0.1)")
    p.add_argument("--rough-limits", default=None,
                   help="load limits of the roughing tool T1, overriding the job's: "
                        "axial=MM,radial=MM,rate=MM3_PER_MIN, any of them, none lifts one "
                        "(default: axial the step-down, radial 1.1 x the stepover)")
    p.add_argument("--finish-limits", default=None,
                   help="load limits of the finishing ball T2, overriding the job's (same "
                        "syntax; default: axial the ball's diameter, radial its width at the "
                        "planned stock (allowance + scallop + rest limit) or 0.9 x its "
                        "diameter if wider, on cuts deeper than that stock)")
    p.add_argument("--no-rs274", action="store_true", help="do not check with LinuxCNC's rs274")
    p.add_argument("--out", required=True, help="output folder")
    add_machine_options(p)
    p.set_defaults(func=cmd_job)


def parse_tool(text: str, option: str):
    """A core Tool from SHAPE:DIAMETER[:CORNER] (the --tools syntax of verify, one tool);
    errors name the option and its value."""
    if not isinstance(text, str) or len(text) > MAX_LINE_CHARS:
        raise ParameterError(f"{option}: expected <shape>:<diameter mm>[:<corner radius mm>]")
    return parse_tool_spec(text, f"{option} {text}")


def roughing_parameters(args: argparse.Namespace):
    """(roughing tool, the checked roughing options as pipeline.RoughingParameters' fields);
    errors name the option.  No FreeCAD needed."""
    tool = parse_tool(args.rough, "--rough")
    margin = check_range(args.stock_margin, "--stock-margin", "mm", *STOCK_MARGIN_RANGE)
    stepdown = check_range(args.stepdown, "--stepdown", "mm", *STEPDOWN_RANGE)
    fine = check_fine_stepdown(args.fine_stepdown, "--fine-stepdown (at most --stepdown)",
                               stepdown) or 0.0
    stepover = check_range(args.stepover, "--stepover", "%", *STEPOVER_RANGE)
    ramp = check_ramp_angle(args.ramp_angle, "--ramp-angle")
    allowance = check_range(args.allowance, "--allowance", "mm", *ALLOWANCE_RANGE)
    radial = allowance if args.radial_allowance is None else check_range(
        args.radial_allowance, "--radial-allowance", "mm", *ALLOWANCE_RANGE)
    axial = allowance if args.axial_allowance is None else check_range(
        args.axial_allowance, "--axial-allowance", "mm", *ALLOWANCE_RANGE)
    return tool, dict(
        shape=tool.shape.value, diameter=tool.diameter,
        corner_radius=tool.corner_radius if tool.shape.value == "bullnose" else 0.0,
        stepdown=stepdown, stepover_percent=int(round(stepover)), radial_allowance=radial,
        axial_allowance=axial, stock_margin=margin, flat_levels=not args.no_flat_levels,
        fine_stepdown=fine, ramp_angle=ramp, centre_cutting=bool(args.centre_cutting))


def cmd_job(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    args.rapid_rate = args.rapid  # one rapid rate for the time estimates
    cutting_params = cutting_parameters(args)
    rough_tool, roughing = roughing_parameters(args)
    finish_tool = parse_tool(args.finish, "--finish")
    if finish_tool.shape.value != "ball":
        raise ParameterError(f"--finish {args.finish}: the finishing tool must be a ball end "
                             "(ball:DIAMETER)")
    check_range(args.cell, "--cell", "mm", 0.01, 5.0)
    rest_limit = check_range(args.rest_limit, "--rest-limit", "mm", 0.0, 50.0)
    for option, text in (("--rough-limits", args.rough_limits),
                         ("--finish-limits", args.finish_limits)):
        if text is not None:
            parse_limit_fields(text, option)
    check_machine_limits(args)
    check_retract_options(args)
    posts = [p.strip() for p in args.post.split(",")]
    if not all(posts) or len(set(posts)) != len(posts):
        raise ParameterError(f"--post {args.post}: give post-processor names once each, "
                             "separated by commas")
    check_output(args.out)
    names = ("--finish", "--scallop", "--tolerance", "--angle")
    if parts.is_part(args.net):
        if args.knots is not None:
            raise ParameterError(f"--knots applies to control nets, not to the part {args.net}")
        tool = ToolParameters.validate(finish_tool.diameter, args.scallop, args.tolerance,
                                       names[:3])
        angle = check_angle(args.angle, names[3])
        strategy = Strategy(args.strategy)
        selection = parts.parse_faces(args.faces)
        model = parts.load_faces(args.net, parts._selection_text(selection),
                                 chordal_tolerance=tool.tolerance)
        name = _safe_name(Path(args.net).stem)
        target, faces = args.net, None if selection == "up" else selection
    else:
        parts.refuse_faces_on_net(args.faces, args.net)
        model = Surface.from_file(args.net, args.knots)
        strategy, tool, angle = check_request(model, args.strategy, finish_tool.diameter,
                                              args.scallop, args.tolerance, args.angle, names)
        name = _safe_name(model.name)
        target, faces = model, None
    loads = load_limits_of(args, rough_tool, finish_tool, roughing, rest_limit, tool.scallop)
    from ..app import pipeline

    roughing = pipeline.RoughingParameters(**roughing)
    check_posts(posts)
    params = pipeline.FinishingParameters(
        tool_diameter=tool.diameter, scallop=tool.scallop, tolerance=tool.tolerance,
        strategy=strategy.value, angle=angle, arcs=args.arcs == "on", rest_limit=rest_limit,
        retract=args.retract, retract_margin=args.retract_margin)
    cutting = freecad_cutting(cutting_params)
    with staged_output(Path(args.out)) as stage:
        program = stage / f"{name}.ngc"
        others = {post: stage / f"{name}-{post}.ngc" for post in posts[1:]}
        report = run_pipeline(
            lambda: pipeline.machine(target, params, program, posts[0], cutting,
                                     stage / f"{name}-job.FCStd", roughing=roughing,
                                     more_posts=others, faces=faces),
            program, cutting_params.rapid)
        tools = {1: rough_tool, 2: finish_tool}
        report["programs"] = {post: path.name for post, path in
                              [(posts[0], program), *others.items()]}
        if parts.is_part(args.net):
            report["conversion_deviation_mm"], report["conversion_notes"] = \
                parts.conversion_report(model, args.tolerance)
        if not args.no_rs274 and rs274.available():
            checks = {}
            for post, path in [(posts[0], program), *others.items()]:
                check = rs274.check(path, {n: t.diameter for n, t in tools.items()})
                checks[post] = check.as_dict()
                if not check.ok:
                    emit(report)
                    raise BSplineCAMError(f"{path.name} ({post} post): LinuxCNC's rs274 "
                                          f"rejects the program: {check.message}")
            report["rs274"] = checks[posts[0]]
            report["rs274_by_post"] = checks
        verified = verify_program(args, model, program, tools, report["stock_mm"], stage,
                                  loads)
        report["verify"] = {k: verified[k] for k in SUMMARY if k in verified}
        report["elapsed_s"] = round(time.perf_counter() - started, 3)
        (stage / "verify.json").write_text(json_text(with_engine(verified)))
        (stage / "job.json").write_text(json_text(with_engine(report)))
    for note in report.get("roughing", {}).get("notes", []):
        print(f"bsplinecam job: warning: roughing: {note}", file=sys.stderr)
    for warning in verified.get("warnings", []):
        print(f"bsplinecam job: warning: {warning}", file=sys.stderr)
    emit({"out": str(Path(args.out).resolve()), **report["verify"],
          "notes": report.get("roughing", {}).get("notes", []),
          "rs274": report.get("rs274", {}).get("ok")})
    for line in verified.get("load_messages", []):
        print(f"bsplinecam job: check failed: {line}", file=sys.stderr)
    for name, check in verified.get("checks", {}).items():
        if name == "load_limits":
            continue
        if not check["ok"]:
            hint = ""
            if name == "scallop_max_mm" and args.strategy == Strategy.WATERLINE.value:
                hint = (" (waterline finishes the walls steeper than 30 degrees only; "
                        "--strategy steep_shallow adds a raster over the rest)")
            print(f"bsplinecam job: check failed: {name} {check['value']:.6g} over its limit "
                  f"{check['limit']:.6g}{hint}; see {Path(args.out) / 'verify.json'}",
                  file=sys.stderr)
    ok = report.get("rs274", {"ok": True})["ok"] and verified.get("ok", True)
    return 0 if ok else EXIT_CHECK_FAILED


#: Figures of verify.json repeated in job.json and printed on stdout.
SUMMARY = ("ok", "checks", "targets", "gouge_max_mm", "scallop_max_mm", "scallop_p99_mm",
           "scallop_evenness", "coverage",
           "rapid_collisions", "machining_time_s", "machining_time_with_acceleration_s",
           "tools")


#: Largest gouge (mm) the job accepts: on a part's faces the intrusion along the normal of
#: the cells the Z-map flags (those left unmeasured at their vertical depth), on a surface
#: the vertical depth (:func:`core.simulation.gouge_normal.gouge_gate_mm`).
GOUGE_LIMIT_MM = 0.001


def load_limits_of(args: argparse.Namespace, rough, finish, roughing: dict,
                   rest_limit: float, scallop: float) -> dict[int, LoadLimits]:
    """The job's load limits ({1: T1, 2: T2}, :func:`core.simulation.load_limits.job_limits`)
    with --rough-limits and --finish-limits over them; errors name the option and unit."""
    limits = job_limits(
        rough, finish, stepdown=roughing["stepdown"],
        stepover=0.01 * roughing["stepover_percent"] * rough.diameter,
        axial_allowance=roughing["axial_allowance"],
        radial_allowance=roughing["radial_allowance"], scallop=scallop,
        rest_limit=rest_limit, cell=args.cell)
    for number, option, text in ((1, "--rough-limits", args.rough_limits),
                                 (2, "--finish-limits", args.finish_limits)):
        if text is not None:
            limits[number] = with_fields(limits[number], parse_limit_fields(text, option))
    return limits


def engagement_targets(rough: dict, stepover: float, cell: float) -> dict:
    """The roughing tool's (T1) widest cut outside entries against ENGAGEMENT_RATIO times
    the stepover (mm), plus one cell of the simulation, whose width is the extent of the
    engaged cells plus a cell (a pass at the stepover measures it within a cell): {name:
    [value, limit, ok]}.  Reported, not enforced (see the README's known limits)."""
    radial = rough["radial_engagement_max_mm"] or 0.0
    limit = ENGAGEMENT_RATIO * stepover + cell
    return {"roughing_radial_engagement_max_mm": [radial, round(limit, 6),
                                                  radial <= limit + 1e-9]}


def engagement_warnings(targets: dict, rough: dict, stepover: float, cell: float) -> list:
    """A warning for a missed engagement target, naming the widest cut, its program line and
    the limit (mm)."""
    target = targets.get("roughing_radial_engagement_max_mm")
    if target is None or target["ok"]:
        return []
    line = rough.get("max_radial_line")
    where = f" at line {line}" if line is not None else ""
    return [f"roughing: widest cut {target['value']:.2f} mm{where} is over "
            f"{ENGAGEMENT_RATIO:g} x the stepover {stepover:g} mm plus the simulation's "
            f"{cell:g} mm cell ({target['limit']:g} mm): the tool is loaded more there than "
            "the stepover sets"]


def verify_program(args, model, program_path, tools, stock, stage,
                   loads: dict[int, LoadLimits] | None = None) -> dict:
    """The whole program simulated from the stock block and measured against the model (a
    core Surface, or a part's core faces), each tool's moves checked against ``loads`` (its
    defaults where not given);
    writes the stock pictures and the deviation map into ``stage``; returns verify.json with
    ``checks`` (gouge, scallop, rapid collisions, load limits (the number of overloaded
    moves): each limit, its value and whether it holds; ``ok`` when all hold), ``targets``
    (the roughing's engagement, reported), ``loads`` (the overloads and their regions) and
    ``load_messages`` (one line per region)."""
    program = read_gcode_file(str(program_path))
    result = verify_job(model, program, tools, stock=tuple(stock), cell=args.cell,
                        rapid_rate=args.rapid, load_limits=loads)
    metrics = {"model": str(Path(args.net)), "program": Path(program_path).name,
               **result.metrics, **machine_time_metrics(args, program)}
    rough = metrics["tools"]["1"]
    stepover = 0.01 * args.stepover * tools[1].diameter
    gouge = gouge_gate_mm(metrics)
    checks = {  # the program is safe and meets the design: these decide the exit status
        "gouge_max_mm": [gouge, GOUGE_LIMIT_MM, gouge <= GOUGE_LIMIT_MM],
        "scallop_max_mm": [metrics["scallop_max_mm"], args.scallop + args.tolerance,
                           metrics["scallop_max_mm"] <= args.scallop + args.tolerance],
        "rapid_collisions": [len(metrics["rapid_collisions"]), 0,
                             not metrics["rapid_collisions"]],
        "load_limits": [result.loads.overloaded_moves, 0, result.loads.ok],
    }
    metrics["load_messages"] = result.loads.messages(tools)
    targets = engagement_targets(rough, stepover, args.cell)
    metrics["checks"] = {k: {"value": v, "limit": lim, "ok": bool(ok)}
                         for k, (v, lim, ok) in checks.items()}
    metrics["targets"] = {k: {"value": v, "limit": lim, "ok": bool(ok)}
                          for k, (v, lim, ok) in targets.items()}
    metrics["ok"] = all(ok for _, _, ok in checks.values())
    metrics["warnings"] = [*metrics.get("warnings", []),
                           *engagement_warnings(metrics["targets"], rough, stepover, args.cell)]
    pictures.plot_deviation(result, stage / "deviation.png")
    for number in sorted(result.job.snapshots):
        pictures.plot_stock(result, number, stage / f"stock-T{number}.png")
    return metrics
