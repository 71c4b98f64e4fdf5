# SPDX-License-Identifier: LGPL-2.1-or-later
"""Machining time per part and finishing strategy: our op's strategies against FreeCAD's own
3D Surface op (OpenCAMLib) as it comes and retuned to our best strategy's scallop.

For each part (``--parts``; ``part`` is examples/part.step, ``step`` the plane-with-fillets
step of tests/TestBSplineCAMPartialPasses.py built here with FreeCAD's Part module and written
as STEP: a flat top, a 4 mm convex fillet, a 60 degree ramp, a 4 mm concave fillet and a flat
floor, 20 mm long), one job holds our finishing op on the faces reached from above and, after
it, FreeCAD's 3D Surface op on the same faces (both on the job's one ball-end tool controller:
the same HorizFeed, VertFeed and rapid rate).  Our op is recomputed with each strategy of
``--strategies`` (raster with partial passes, steep_shallow, scallop by default; minimum
retracts), then as the raster issue 44 measured (:func:`baseline_raster`: whole passes,
full retracts, at each of ``--baseline-angles``; the op has no property for whole passes, so
the core's raster is called with ``partial=False`` as benchmarks/machining_time.py calls it).
FreeCAD's op runs at the flat stepover 2 sqrt(2Rh - h^2) with BoundaryAdjustment R (as it
comes), then is retuned twice from there (:func:`retune`: the secant of
``benchmarks/toolpath.py`` on StepOver, then again with SampleInterval halved when no StepOver
gets there, ``--match-sample-halvings``):

* away from the borders: until its largest scallop away from the selection's border is at
  most our fastest strategy's;
* on the whole selection, the fair comparison: its BoundaryAdjustment first
  (:func:`adjust_boundary`, ``--boundary-adjustments``) so that its ball centres may leave the
  faces' outline as ours do, then StepOver and SampleInterval until its largest scallop away
  from the border and in the edge band are both at most ours.  As it comes, the op stops the
  ball centre on the outline and so leaves the edge band (fillets down to side walls)
  unfinished, which the first retune does not ask of it.

Each program is posted alone (linuxcnc), checked by rs274 and measured on its text: the time
with acceleration on the default machine (:func:`BSplineCAM.core.simulation.measures.
program_measures`: 500 mm/s^2 per axis, rapids 5000 mm/min, junction deviation 0.01 mm),
feed and rapid lengths, the vertical feeds among the feeds (plunges and retracts at the feed),
and the simulation against the part's exact faces (:func:`BSplineCAM.core.simulation.verify.
verify_faces`): gouge (along the faces' normal, the depth the ball and its shank enter them:
:func:`BSplineCAM.core.simulation.gouge_normal.gouge_gate_mm`; the Z-map's vertical depth
beside it), largest and mean scallop, evenness and coverage away from the faces'
borders, and the largest scallop in the edge band (within the tool radius of a border).  The
targets of issue 44 are checked per part: our fastest strategy (without gouge) no slower than
FreeCAD's retuned op, at least ``--raster-saving`` (30 %) faster than issue 44's raster at the
first of ``--baseline-angles`` (0, the command line's default), no gouge over
``--gouge-limit``, and an evenness of at least ``--evenness`` on the flat-and-fillet parts.

Every program is simulated from the raw block (the design's top plus 1 mm), or, with
``--start-stock-allowance A``, from the model raised by A mm (a part roughed to within A
before the finish): our op then declares that stock (``StartStock`` model), so its hops and
entries clear it rather than the block's top, and the simulation lists any rapid of any program
that cuts it.  ``--freecad off`` leaves FreeCAD's op out (our rows and issue 44's raster).

Run inside freecadcmd 0.20 with OpenCAMLib (as benchmarks/toolpath.py), one part per process
when parts are slow, then print the table of all the JSON files with ``--tables``:

    freecadcmd -c "import runpy, sys; sys.argv=['x', '--parts', 'part,step', '--json', 'out.json'];
                   runpy.run_path('benchmarks/machining_parts.py', run_name='__main__')"
    .venv/bin/python benchmarks/machining_parts.py --tables out1.json out2.json
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

#: Part names with a meaning here; any other name is a part file.
PART_NAMES = {"part": ROOT / "examples" / "part.step", "step": None}
DEFAULT_PARTS = "part,step,tests/parts/mal_vis.brep,tests/parts/MODERN_Exhaust_1.brep"
#: Parts made of flats and fillets, where the evenness target applies.
FLAT_AND_FILLET = ("part", "step")
DEFAULT_STRATEGIES = "raster,steep_shallow,scallop"
#: Keys of the op's report kept in the figures.
REPORT_KEYS = ("passes", "moves", "air_length_mm", "link_length_mm", "program_moves",
               "arc_moves", "unreachable", "notes")


def load_toolpath_benchmark():
    """benchmarks/toolpath.py as a module (its job, post and matching helpers)."""
    spec = importlib.util.spec_from_file_location(
        "bsplinecam_benchmark_toolpath", Path(__file__).resolve().parent / "toolpath.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def step_part(folder: Path) -> Path:
    """The plane-with-fillets step (module doc) as a STEP file in ``folder``: the profile in
    XZ (top at z = 10 from x = -40 to 0, fillets of radius 4 mm, ramp of 2 mm run at 60
    degrees, floor 40 mm wide), on a base at z = 0, extruded 20 mm along +Y."""
    import FreeCAD
    import Part

    rho, t, run, top, flat, length = 4.0, math.radians(60.0), 2.0, 10.0, 40.0, 20.0

    def v(x: float, z: float):
        return FreeCAD.Vector(x, 0.0, z)

    pa = (rho * math.sin(t), top - rho * (1 - math.cos(t)))
    pb = (pa[0] + run, pa[1] - run * math.tan(t))
    centre = (pb[0] + rho * math.sin(t), pb[1] + rho * math.cos(t))
    floor = centre[1] - rho
    convex_mid = (rho * math.cos(math.pi / 2 - t / 2),
                  top - rho + rho * math.sin(math.pi / 2 - t / 2))
    concave_mid = (centre[0] + rho * math.cos(1.5 * math.pi - t / 2),
                   centre[1] + rho * math.sin(1.5 * math.pi - t / 2))
    end = centre[0] + flat
    edges = [
        Part.LineSegment(v(-flat, 0.0), v(-flat, top)).toShape(),
        Part.LineSegment(v(-flat, top), v(0.0, top)).toShape(),
        Part.Arc(v(0.0, top), v(*convex_mid), v(*pa)).toShape(),
        Part.LineSegment(v(*pa), v(*pb)).toShape(),
        Part.Arc(v(*pb), v(*concave_mid), v(centre[0], floor)).toShape(),
        Part.LineSegment(v(centre[0], floor), v(end, floor)).toShape(),
        Part.LineSegment(v(end, floor), v(end, 0.0)).toShape(),
        Part.LineSegment(v(end, 0.0), v(-flat, 0.0)).toShape(),
    ]
    solid = Part.Face(Part.Wire(edges)).extrude(FreeCAD.Vector(0.0, length, 0.0))
    path = folder / "step.step"
    solid.exportStep(str(path))
    return path


def source_version() -> str:
    """``git describe --always --dirty`` of the checkout this file is in, or why not."""
    try:
        done = subprocess.run(["git", "-C", str(ROOT), "describe", "--always", "--dirty"],
                              capture_output=True, text=True, timeout=30, check=True)
    except (OSError, subprocess.SubprocessError):
        return "not a git checkout"
    return done.stdout.strip()


def part_file(name: str, folder: Path) -> Path:
    """The file of a ``--parts`` entry."""
    if name == "step":
        return step_part(folder)
    path = PART_NAMES.get(name) or Path(name)
    if not path.is_file():
        raise SystemExit(f"--parts: {name}: no such file")
    return path


def measure_program(faces, text: str, path: Path, args: argparse.Namespace) -> dict:
    """rs274's verdict, the machine figures and the simulation of one posted program."""
    from BSplineCAM.core.program import rs274
    from BSplineCAM.core.program.gcode import MoveKind, read_gcode
    from BSplineCAM.core.simulation.gouge_normal import gouge_gate_mm
    from BSplineCAM.core.simulation.measures import program_measures
    from BSplineCAM.core.simulation.simulate import Tool
    from BSplineCAM.core.simulation.verify import verify_faces

    out = {"program": str(path)}
    if rs274.available():
        check = rs274.check(path, {1: args.diameter})
        out["rs274"] = "ok" if check.ok else f"FAILED: {check.message}"
    else:
        out["rs274"] = "not installed"
    program = read_gcode(text)
    out.update(program_measures(program))
    feeds = program.kind != MoveKind.RAPID
    lateral = (program.end[:, :2] - program.start[:, :2]).T
    vertical = feeds & (abs(lateral[0]) < 1e-9) & (abs(lateral[1]) < 1e-9)
    out["vertical_feed_mm"] = float(program.lengths()[vertical].sum())
    out["moves"] = len(program)
    started = time.perf_counter()
    allowance = getattr(args, "start_stock_allowance", None)  # benchmarks/strategies.py: none
    stock = {} if allowance is None else {"stock_top": "model", "stock_margin": allowance}
    metrics = verify_faces(faces, program, Tool(args.diameter), cell=args.cell, **stock).metrics
    out["verify_seconds"] = time.perf_counter() - started
    for key in ("gouge_cells", "scallop_max_mm", "scallop_p99_mm",
                "scallop_mean_mm", "scallop_evenness", "scallop_mean_over_max", "coverage",
                "edge_scallop_max_mm", "edge_gouge_max_mm"):
        out[key] = float(metrics[key])
    # the gouge the targets gate on: the ball's and shank's depth into the faces along the
    # normal (the Z-map's vertical depth reads a wall's height beside a wall's top edge)
    out["gouge_max_mm"] = gouge_gate_mm(metrics)
    out["gouge_vertical_max_mm"] = float(metrics["gouge_max_mm"])
    out["rapid_collisions"] = len(metrics["rapid_collisions"])
    return out


def run_part(name: str, bench, args: argparse.Namespace, out: Path) -> dict:
    """Our op with each strategy and FreeCAD's op (flat and matched) on one part."""
    from BSplineCAM.app import pipeline, surface3d

    FreeCAD = bench.FreeCAD
    stem = Path(name).stem
    out = out / stem
    out.mkdir(parents=True, exist_ok=True)
    part = part_file(name, out)
    params = pipeline.FinishingParameters(
        tool_diameter=args.diameter, scallop=args.scallop, tolerance=args.tolerance,
        strategy=args.strategies[0], angle=args.angle)
    ns = argparse.Namespace(part=str(part), faces=args.faces)
    doc = FreeCAD.newDocument("BSplineCAMMachiningParts")
    figures = {"part": name, "file": str(part), "ours": {}}
    try:
        faces, job, ours = bench.part_job(ns, params, doc)
        figures["faces"] = list(ours.Base[0][1])
        if args.start_stock_allowance is not None:
            ours.StartStock, ours.StockAllowance = "model", args.start_stock_allowance
        for strategy in args.strategies:
            ours.Strategy = strategy
            print(f"{name}: {strategy} ...", flush=True)
            try:
                seconds = bench.timed_recompute(doc, ours)
                report = json.loads(ours.Report or "{}")
                if report.get("error"):
                    raise RuntimeError(report["error"])
            except Exception as exc:  # a failing strategy is a row of the table
                figures["ours"][strategy] = {"error": str(exc)}
                print(f"{name}: {strategy} FAILED: {exc}", flush=True)
                continue
            path = out / f"{stem}-{strategy}.ngc"
            text = bench.post_alone(job, ours, path)
            result = {"seconds": seconds, **measure_program(faces, text, path, args)}
            result["report"] = {k: report[k] for k in REPORT_KEYS if k in report}
            figures["ours"][strategy] = result
            print(f"{name}: {strategy}: {summary(result)}", flush=True)
        figures["baseline"] = {}
        for angle in args.baseline_angles:
            label = f"raster {angle:g} deg, whole passes, full retracts"
            print(f"{name}: {label} ...", flush=True)
            figures["baseline"][label] = baseline_raster(bench, job, ours, doc, faces, args, out,
                                                         angle)
            print(f"{name}: {label}: {summary(figures['baseline'][label])}", flush=True)
        if args.freecad == "off":
            return figures
        # Our op leaves the job: posting FreeCAD's op alone toggles the others' Active, which
        # would recompute ours again with each of FreeCAD's timed recomputes.
        doc.removeObject(ours.Name)
        doc.recompute()
        theirs = surface3d.add_freecad_surface_op(
            job, args.scallop, args.diameter, tolerance=args.tolerance, pattern=args.pattern)
        theirs.Base = [(job.Model.Group[0], figures["faces"])]
        print(f"{name}: FreeCAD 3D Surface ...", flush=True)
        flat = freecad_run(bench, job, theirs, doc, faces, args,
                           out / f"{stem}-freecad_3d_surface.ngc")
        figures["freecad_flat"] = flat
        figures["freecad_op"] = {"StepOver_percent": theirs.StepOver,
                                 "SampleInterval_mm": theirs.SampleInterval.Value,
                                 "CutPattern": theirs.CutPattern}
        print(f"{name}: FreeCAD flat: {summary(flat)}", flush=True)
        best = best_strategy(figures["ours"], args.gouge_limit)
        if best is None:
            figures["freecad_matched"] = {"matched": False, "reason": "no strategy of ours"}
            return figures
        inner = figures["ours"][best]["scallop_max_mm"]
        edge = figures["ours"][best]["edge_scallop_max_mm"]
        stepover, interval = theirs.StepOver, theirs.SampleInterval.Value
        matched = retune(bench, job, theirs, doc, faces, args, out / "inner", flat,
                         {"scallop_max_mm": inner}, name)
        figures["freecad_matched"] = matched
        # the whole selection: the edge band too, from the flat run's StepOver and interval
        theirs.StepOver, theirs.SampleInterval = stepover, interval
        boundary = adjust_boundary(bench, job, theirs, doc, faces, args, out / "boundary",
                                   flat, edge, name)
        figures["freecad_boundary"] = boundary
        figures["freecad_whole"] = retune(
            bench, job, theirs, doc, faces, args, out / "whole", boundary["chosen"],
            {"scallop_max_mm": inner, "edge_scallop_max_mm": edge}, name)
        return figures
    finally:
        FreeCAD.closeDocument(doc.Name)


def retune(bench, job, theirs, doc, faces, args, out: Path, flat: dict, targets: dict,
           name: str) -> dict:
    """FreeCAD's op retuned until each measure of ``targets`` (key -> mm: ``scallop_max_mm``
    away from the borders, ``edge_scallop_max_mm`` in the edge band) is at most its target:
    its StepOver by ``benchmarks/toolpath.py``'s secant (:func:`next_stepover`) on the worst
    ratio of measure to target, from its ``flat`` run; when no StepOver gets there (the
    samples along the passes, SampleInterval apart, cut chords across concave fillets), the
    search again from the flat StepOver with SampleInterval halved, up to
    ``--match-sample-halvings`` times.  The result is the matching run with the largest
    StepOver (measured as the others, ``matched`` false and the run nearest the targets when
    none matched) with every stage's trials."""
    stages = []
    interval = theirs.SampleInterval.Value
    stepover = theirs.StepOver
    first = flat
    found = None
    nearest = flat
    for stage in range(args.match_sample_halvings + 1):
        folder = out / f"sample{stage}"
        folder.mkdir(parents=True, exist_ok=True)
        if stage:
            interval /= 2.0
            theirs.StepOver, theirs.SampleInterval = stepover, interval
            first = freecad_run(bench, job, theirs, doc, faces, args,
                                folder / "freecad_3d_surface.ngc")
            print(f"{name}: FreeCAD flat, SampleInterval {interval:.3f} mm: {summary(first)}",
                  flush=True)
        runs = search_stepover(bench, job, theirs, doc, faces, args, folder, first, targets,
                               name)
        stages.append({"sample_interval_mm": interval,
                       "trials": [{"stepover_mm": r["stepover_mm"],
                                   **{k: r[k] for k in targets}} for r in runs]})
        nearest = min([nearest, *runs], key=lambda r: worst_ratio(r, targets))
        passing = [r for r in runs if worst_ratio(r, targets) <= 1.0]
        if passing:
            found = max(passing, key=lambda r: r["stepover_mm"])
            break
    theirs.StepOver, theirs.SampleInterval = stepover, flat.get("sample_interval_mm",
                                                                interval)
    result = dict(found or nearest)
    result.update(matched=found is not None, targets_mm=targets, stages=stages,
                  target_scallop_mm=targets["scallop_max_mm"])
    print(f"{name}: FreeCAD retuned to {targets}: "
          f"{'matched' if found else 'NOT matched, nearest'}: {summary(result)}", flush=True)
    return result


def worst_ratio(run: dict, targets: dict) -> float:
    """The largest of a run's measures over their targets (1 or less: every target met)."""
    return max(run[k] / max(v, 1e-9) for k, v in targets.items())


def search_stepover(bench, job, theirs, doc, faces, args, folder: Path, first: dict,
                    targets: dict, name: str) -> list[dict]:
    """FreeCAD's op rerun at other StepOvers from ``first`` (its run at the op's StepOver)
    until :func:`worst_ratio` is within [1 - ``--match-rtol``, 1], after ``--match-steps``
    reruns or when the StepOver stops changing (``--match-min-stepover``, or the op's
    least): ``benchmarks/toolpath.py``'s :func:`next_stepover` on the worst ratio.  Returns
    every run (``first`` first), measured; the op keeps the last run's StepOver."""
    runs = [first]
    for index in range(1, args.match_steps + 1):
        ratio = worst_ratio(runs[-1], targets)
        if 1.0 - args.match_rtol <= ratio <= 1.0:
            break
        trials = [{"stepover_mm": r["stepover_mm"], "scallop_max_mm": worst_ratio(r, targets)}
                  for r in runs]
        step = max(bench.next_stepover(trials, 1.0, 1.0 - args.match_rtol / 2.0),
                   args.match_min_stepover)
        theirs.StepOver = 100.0 * step / args.diameter
        run = freecad_run(bench, job, theirs, doc, faces, args,
                          folder / f"freecad_3d_surface-match{index}.ngc")
        runs.append(run)
        repeated = abs(run["stepover_mm"] - runs[-2]["stepover_mm"]) < 1e-6
        print(f"{name}: match {index}: stepover {run['stepover_mm']:.4f} mm, "
              + ", ".join(f"{k} {run[k]:.4f} (target {v:.4f})" for k, v in targets.items()),
              flush=True)
        if repeated:  # --match-min-stepover or the op's least (1 %): no other run
            break
    return runs


def freecad_run(bench, job, theirs, doc, faces, args, path: Path) -> dict:
    """FreeCAD's op recomputed (timed), posted alone to ``path`` and measured, with its
    StepOver (mm), SampleInterval and BoundaryAdjustment."""
    seconds = bench.timed_recompute(doc, theirs)
    text = bench.post_alone(job, theirs, path)
    return {"seconds": seconds, **measure_program(faces, text, path, args),
            "stepover_mm": args.diameter * theirs.StepOver / 100.0,
            "sample_interval_mm": theirs.SampleInterval.Value,
            "boundary_adjustment_mm": theirs.BoundaryAdjustment.Value,
            "final_depth_mm": theirs.FinalDepth.Value}


def adjust_boundary(bench, job, theirs, doc, faces, args, out: Path, flat: dict, edge: float,
                    name: str) -> dict:
    """FreeCAD's op with its boundary moved out until its edge band's largest scallop is at
    most ``edge`` (mm, ours), at its flat StepOver and SampleInterval.

    PathSurface (0.20, ``PathSurfaceSupport._calculateOffsetValue``) offsets the faces'
    outline by BoundaryAdjustment - R - LinearDeflection for the ball centre when
    BoundaryEnforcement is on: BoundaryAdjustment = R (:mod:`BSplineCAM.app.surface3d`)
    keeps the centre on the outline, where a ball cannot finish a fillet down to a side wall
    (its contact at the fillet's foot lies R outside the outline); its passes lie at
    multiples of StepOver from the middle of the bound box, the boundary only decides which
    of them run.  FinalDepth goes R lower than the op's own: with BoundaryAdjustment > 0
    PathSurfaceSupport cuts its model of the stock's waste back by the faces' envelope down
    to FinalDepth, and on examples/part.step at 2 R the fillets' feet keep 1.04 mm with the
    op's FinalDepth, 0.27 mm with it R lower (measured; the cause not traced further).
    The trials are ``--boundary-adjustments`` (mm; by default 1.5 R and 2 R), in order,
    stopping at the first that meets ``edge``;
    the chosen one is that, or else the one with the least edge band scallop (the first
    within 2 % of it), the op as it comes among them.  The op keeps the chosen adjustment
    and FinalDepth."""
    radius = args.diameter / 2.0
    out.mkdir(parents=True, exist_ok=True)
    trials = [flat]
    depth = theirs.FinalDepth.Value
    theirs.setExpression("FinalDepth", None)
    theirs.FinalDepth = depth - radius
    adjustments = args.boundary_adjustments or [1.5 * radius, 2.0 * radius]
    for adjustment in adjustments:
        if trials[-1]["edge_scallop_max_mm"] <= edge:
            break
        theirs.BoundaryAdjustment = adjustment
        run = freecad_run(bench, job, theirs, doc, faces, args,
                          out / f"freecad_3d_surface-boundary{adjustment:g}.ngc")
        trials.append(run)
        print(f"{name}: FreeCAD BoundaryAdjustment {adjustment:g} mm: {summary(run)}, edge band "
              f"{run['edge_scallop_max_mm']:.4f} mm (ours {edge:.4f})", flush=True)
    meeting = [t for t in trials if t["edge_scallop_max_mm"] <= edge]
    if meeting:
        chosen = meeting[0]
    else:
        least = min(t["edge_scallop_max_mm"] for t in trials)
        chosen = next(t for t in trials if t["edge_scallop_max_mm"] <= 1.02 * least)
    theirs.BoundaryAdjustment = chosen["boundary_adjustment_mm"]
    theirs.FinalDepth = chosen["final_depth_mm"]
    return {"target_edge_scallop_mm": edge, "met": bool(meeting),
            "chosen": chosen,
            "trials": [{k: t[k] for k in ("boundary_adjustment_mm", "edge_scallop_max_mm",
                                          "scallop_max_mm", "gouge_max_mm",
                                          "machining_time_with_acceleration_s",
                                          "cutting_length_mm")} for t in trials]}


@contextlib.contextmanager
def whole_passes():
    """Our op's raster with every pass over the whole extent while inside: the op has no
    property for it, so the core's ``raster_faces``, as the op's strategy dispatch
    (:func:`BSplineCAM.core.toolpath.generate_faces`) calls it, gets ``partial=False`` (the
    call of benchmarks/machining_time.py's whole-passes rows)."""
    from BSplineCAM.core import toolpath as core_toolpath

    original = core_toolpath.raster_faces

    def raster_whole(*args, **kwargs):
        kwargs["partial"] = False
        return original(*args, **kwargs)

    core_toolpath.raster_faces = raster_whole
    try:
        yield
    finally:
        core_toolpath.raster_faces = original


def baseline_raster(bench, job, ours, doc, faces, args, out: Path, angle: float) -> dict:
    """Our raster as issue 44 measured it: the op (arcs on) at ``angle`` degrees with whole
    passes (:func:`whole_passes`) and full retracts, posted and measured as the strategies
    are; the op's Strategy, Angle and Retract are restored after."""
    saved = (ours.Strategy, ours.Angle.Value, ours.Retract)
    ours.Strategy, ours.Angle, ours.Retract = "raster", angle, "full"
    try:
        with whole_passes():
            seconds = bench.timed_recompute(doc, ours)
        report = json.loads(ours.Report or "{}")
        if report.get("error"):
            return {"error": report["error"]}
        stem = Path(out).name
        path = out / f"{stem}-raster-whole-{angle:g}.ngc"
        text = bench.post_alone(job, ours, path)
        result = {"seconds": seconds, **measure_program(faces, text, path, args),
                  "angle_deg": angle}
        result["report"] = {k: report[k] for k in REPORT_KEYS if k in report}
        return result
    finally:
        ours.Strategy, ours.Angle, ours.Retract = saved


def summary(result: dict) -> str:
    return (f"{result['machining_time_with_acceleration_s']:.0f} s on the machine, "
            f"{result['cutting_length_mm'] / 1000:.2f} m cutting, scallop "
            f"{result['scallop_max_mm']:.4f} mm, gouge {1000 * result['gouge_max_mm']:.2f} um, "
            f"computed in {result['seconds']:.1f} s")


def best_strategy(ours: dict, gouge_limit: float) -> str | None:
    """Our strategy with the least time with acceleration among those without gouge (all of
    them when every one gouges), or None when none ran."""
    ran = {k: v for k, v in ours.items() if "error" not in v}
    clean = {k: v for k, v in ran.items() if v["gouge_max_mm"] <= gouge_limit} or ran
    if not clean:
        return None
    return min(clean, key=lambda k: clean[k]["machining_time_with_acceleration_s"])


def freecad_verdict(t: float, run: dict, what: str) -> str:
    """Our time ``t`` (s) against one of FreeCAD's retuned runs."""
    fc = run["machining_time_with_acceleration_s"]
    verdict = "met" if t <= fc else "NOT met"
    reached = "" if run.get("matched") else " (NOT reached: its nearest run)"
    return (f"no slower than FreeCAD's op retuned {what}{reached} ({fc:.0f} s): {verdict}, "
            f"ours {100 * (t / fc - 1):+.0f} %")


def change(saving: float) -> str:
    """A saving (fraction of the other's time) said as "N % less" or "N % more"."""
    return f"{100 * saving:.0f} % less" if saving >= 0 else f"{-100 * saving:.0f} % more"


def targets(figures: dict, settings: dict) -> list[str]:
    """Issue 44's targets on one part, each met or not and by how much.  The fair FreeCAD
    row is the one retuned on the whole selection (edge band included) when there is one."""
    ours = figures["ours"]
    best = best_strategy(ours, settings["gouge_limit_mm"])
    if best is None:
        return ["no strategy of ours ran"]
    b = ours[best]
    t = b["machining_time_with_acceleration_s"]
    lines = [f"fastest of ours: {best}, {t:.0f} s"]
    whole = figures.get("freecad_whole")
    if whole:
        edge = whole["targets_mm"]["edge_scallop_max_mm"]
        lines.append(freecad_verdict(
            t, whole, f"on the whole selection (scallop <= {whole['target_scallop_mm']:.4f} "
            f"mm away from the borders and <= {edge:.4f} mm in the edge band; the fair "
            "comparison)"))
    matched = figures.get("freecad_matched", {})
    if "machining_time_with_acceleration_s" in matched:
        lines.append(freecad_verdict(
            t, matched, f"away from the borders only ({matched['target_scallop_mm']:.4f} mm)"))
    elif matched:
        lines.append("FreeCAD's op retuned: no stepover reached our scallop "
                     f"({matched.get('reason', 'trials exhausted')})")
    baselines = {k: v for k, v in figures.get("baseline", {}).items() if "error" not in v}
    raster = ours.get("raster", {})
    need = settings["raster_saving"]
    if baselines:
        for index, (label, r) in enumerate(baselines.items()):
            base = r["machining_time_with_acceleration_s"]
            saving = 1.0 - t / base
            verdict = "met" if saving >= need else "NOT met"
            role = "the target" if index == 0 else "also"
            lines.append(f"at least {100 * need:.0f} % less than our raster of issue 44, "
                         f"{label} ({role}, {base:.0f} s): {verdict}, {change(saving)}")
    if "error" not in raster and raster:
        r = raster["machining_time_with_acceleration_s"]
        lines.append(f"against today's raster (partial passes, minimum retracts, {r:.0f} s): "
                     f"{change(1.0 - t / r)}")
    hits = b.get("rapid_collisions")
    if hits is not None:
        allowance = settings.get("start_stock_allowance_mm")
        stock = ("the raw block" if allowance is None
                 else f"the model raised by {allowance:g} mm")
        lines.append(f"no rapid into the stock ({stock}): "
                     f"{'met' if hits == 0 else 'NOT met'}, {hits} rapid(s) cut it")
    gouge = b["gouge_max_mm"]
    verdict = "met" if gouge <= settings["gouge_limit_mm"] else "NOT met"
    lines.append(f"no gouge (<= {1000 * settings['gouge_limit_mm']:g} um): {verdict}, "
                 f"{1000 * gouge:.2f} um")
    if figures["part"] in FLAT_AND_FILLET:
        e = b["scallop_evenness"]
        verdict = "met" if e >= settings["evenness"] else "NOT met"
        lines.append(f"evenness >= {settings['evenness']:g}: {verdict}, {e:.2f}")
    return lines


def row(label: str, r: dict) -> str:
    if "error" in r:
        return f"| {label} | failed: {r['error'][:120]} |" + " |" * 10
    return (f"| {label} | {r['seconds']:.1f} | {r['cutting_length_mm'] / 1000:.2f} | "
            f"{r['vertical_feed_mm'] / 1000:.2f} | {r['rapid_length_mm'] / 1000:.2f} | "
            f"{r['machining_time_with_acceleration_s']:.0f} | "
            f"{r['scallop_max_mm']:.3f} / {r['scallop_mean_mm']:.4f} | "
            f"{r['scallop_evenness']:.2f} | {r['edge_scallop_max_mm']:.3f} | "
            f"{1000 * r['gouge_max_mm']:.2f} ({_vertical_um(r)}) | "
            f"{100 * r['coverage']:.1f} % | {r['rs274']} |")


def _vertical_um(r: dict) -> str:
    """The Z-map's vertical gouge (um) of a row, or "-" in a run before it was kept."""
    v = r.get("gouge_vertical_max_mm")
    return "-" if v is None else f"{1000 * v:.2f}"


def freecad_label(what: str, r: dict) -> str:
    """A FreeCAD row's label: what it is and the op's StepOver, SampleInterval and
    BoundaryAdjustment (mm)."""
    interval = r.get("sample_interval_mm")
    boundary = r.get("boundary_adjustment_mm")
    return (f"FreeCAD 3D Surface, {what}: stepover {r['stepover_mm']:.3f} mm"
            + (f", SampleInterval {interval:.3f} mm" if interval is not None else "")
            + (f", BoundaryAdjustment {boundary:.2f} mm" if boundary is not None else "")
            + (f", FinalDepth {r['final_depth_mm']:.2f} mm" if "final_depth_mm" in r else ""))


def trials_line(what: str, matched: dict) -> list[str]:
    """The retuning's trials, stage by stage."""
    lines = []
    for stage in matched.get("stages", []):
        lines.append("")
        lines.append(f"FreeCAD's retuning {what} at SampleInterval "
                     f"{stage['sample_interval_mm']:.3f} mm (stepover -> largest scallop, "
                     "edge band): " + "; ".join(
                         f"{t['stepover_mm']:.3f} -> {t['scallop_max_mm']:.4f}"
                         + (f", {t['edge_scallop_max_mm']:.4f}"
                            if "edge_scallop_max_mm" in t else "") + " mm"
                         for t in stage["trials"]))
    return lines


def table(results: list[dict]) -> str:
    lines = []
    for figures in results:
        s = figures["settings"]
        lines += [
            f"**{figures['part']}** ({figures['file']}, faces {', '.join(figures['faces'])}; "
            f"ball {s['diameter_mm']:g} mm, scallop {s['scallop_mm']:g} mm, tolerance "
            f"{s['tolerance_mm']:g} mm; {s['date']}, {s['source']})",
            "",
            "| program | compute s | feed m | of which vertical m | rapid m | time with "
            "acceleration s | largest / mean scallop mm | evenness | edge band scallop mm "
            "| gouge um, along the normal (vertical) | coverage | rs274 |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        lines += [row(k, v) for k, v in figures["ours"].items()]
        lines += [row(f"{k} (issue 44's raster)", v)
                  for k, v in figures.get("baseline", {}).items()]
        flat = figures.get("freecad_flat")
        if flat:
            lines.append(row(freecad_label("as it comes (flat stepover)", flat), flat))
        matched = figures.get("freecad_matched", {})
        if "machining_time_with_acceleration_s" in matched:
            lines.append(row(freecad_label(
                "retuned away from the borders" + ("" if matched["matched"] else
                                                    " (NOT reached)"), matched), matched))
        whole = figures.get("freecad_whole", {})
        if whole:
            lines.append(row(freecad_label(
                "retuned on the whole selection, the fair comparison"
                + ("" if whole["matched"] else " (NOT reached: nearest run)"), whole), whole))
        lines += trials_line("away from the borders", matched)
        boundary = figures.get("freecad_boundary")
        if boundary:
            lines.append("")
            lines.append(
                f"FreeCAD's boundary at the flat stepover (BoundaryAdjustment -> edge band "
                f"scallop, time; ours {boundary['target_edge_scallop_mm']:.4f} mm, "
                f"{'met' if boundary['met'] else 'NOT met'}): " + "; ".join(
                    f"{t['boundary_adjustment_mm']:.2f} mm -> {t['edge_scallop_max_mm']:.4f} "
                    f"mm, {t['machining_time_with_acceleration_s']:.0f} s"
                    for t in boundary["trials"]))
        lines += trials_line("on the whole selection", whole)
        lines.append("")
        lines += [f"- {line}" for line in targets(figures, s)]
        lines.append("")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default=DEFAULT_PARTS,
                        help="comma-separated: part (examples/part.step), step (the "
                        "plane-with-fillets step), or part files")
    parser.add_argument("--faces", default=None, help="up (default) or face numbers")
    parser.add_argument("--strategies", default=DEFAULT_STRATEGIES,
                        help="our op's strategies, comma-separated")
    parser.add_argument("--angle", type=float, default=0.0, help="raster angle (deg)")
    parser.add_argument("--diameter", type=float, default=6.0, help="ball diameter (mm)")
    parser.add_argument("--scallop", type=float, default=0.05, help="scallop height (mm)")
    parser.add_argument("--tolerance", type=float, default=0.01, help="chordal tolerance (mm)")
    parser.add_argument("--cell", type=float, default=0.1, help="simulation cell (mm)")
    parser.add_argument("--pattern", default="ZigZag", help="the 3D Surface op's CutPattern")
    parser.add_argument("--match-steps", type=int, default=5,
                        help="most reruns of the 3D Surface op when retuning it")
    parser.add_argument("--match-rtol", type=float, default=0.1,
                        help="retuning stops within this fraction below the target scallop")
    parser.add_argument("--match-sample-halvings", type=int, default=2,
                        help="when no StepOver reaches the target, halve the 3D Surface op's "
                        "SampleInterval and search again, at most this many times")
    parser.add_argument("--boundary-adjustments", default="",
                        help="the 3D Surface op's BoundaryAdjustment trials on the whole "
                        "selection (mm, comma-separated; default 1.5 R, 2 R)")
    parser.add_argument("--match-min-stepover", type=float, default=0.3,
                        help="the least StepOver (mm) the retuning tries")
    parser.add_argument("--baseline-angles", default="0,90",
                        help="angles (deg) of issue 44's raster (whole passes, full "
                        "retracts); the first one is the raster-saving target's")
    parser.add_argument("--start-stock-allowance", type=float, default=None,
                        help="the part comes roughed to within this of the model (mm): our "
                        "op's StartStock model with this StockAllowance, and every program "
                        "simulated from the model raised by it (verify's stock top 'model'); "
                        "default: the raw block")
    parser.add_argument("--freecad", default="on", choices=["on", "off"],
                        help="off: our strategies and issue 44's raster only, no FreeCAD op")
    parser.add_argument("--source", default=None,
                        help="the source's version for the figures (default: git describe)")
    parser.add_argument("--gouge-limit", type=float, default=0.001,
                        help="deepest cut into the part that counts as no gouge (mm)")
    parser.add_argument("--raster-saving", type=float, default=0.3,
                        help="the target's saving on the raster's time (fraction)")
    parser.add_argument("--evenness", type=float, default=0.5,
                        help="the target's evenness on the flat-and-fillet parts")
    parser.add_argument("--out", help="folder for the programs (default: a temporary one)")
    parser.add_argument("--json", help="write the figures to this JSON file")
    parser.add_argument("--tables", nargs="+", metavar="JSON",
                        help="print the table of these JSON files and stop (no FreeCAD)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.tables:
        results = [r for f in args.tables for r in json.loads(Path(f).read_text())]
        print(table(results))
        return
    args.strategies = [s for s in args.strategies.split(",") if s]
    try:
        args.boundary_adjustments = [float(v) for v in args.boundary_adjustments.split(",")
                                     if v]
        args.baseline_angles = [float(v) for v in args.baseline_angles.split(",") if v]
    except ValueError as exc:
        parser.error(f"--boundary-adjustments, --baseline-angles: {exc}")
    if not args.strategies:
        parser.error("--strategies: give at least one")
    if args.match_steps < 1:
        parser.error(f"--match-steps must be at least 1, got {args.match_steps}")
    if not 0.0 < args.match_rtol < 1.0:
        parser.error(f"--match-rtol must be in (0, 1), got {args.match_rtol}")
    bench = load_toolpath_benchmark()
    from BSplineCAM.app import compat

    if args.freecad == "on" and not compat.opencamlib_available():
        raise SystemExit(f"this benchmark: {compat.opencamlib_missing_message()}")
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bsplinecam-parts-"))
    out.mkdir(parents=True, exist_ok=True)
    settings = {"diameter_mm": args.diameter, "scallop_mm": args.scallop,
                "tolerance_mm": args.tolerance, "cell_mm": args.cell,
                "gouge_limit_mm": args.gouge_limit, "raster_saving": args.raster_saving,
                "evenness": args.evenness,
                "start_stock_allowance_mm": args.start_stock_allowance,
                "freecad": ".".join(map(str, compat.freecad_version())),
                "source": args.source or source_version(),
                "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    results = []
    for name in (p for p in args.parts.split(",") if p):
        started = time.perf_counter()
        figures = run_part(name, bench, args, out)
        figures["settings"] = settings
        figures["wall_seconds"] = time.perf_counter() - started
        results.append(figures)
        if args.json:  # after each part, so that a stopped run keeps the parts done
            Path(args.json).write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
    print(table(results))


if __name__ == "__main__":
    main()
