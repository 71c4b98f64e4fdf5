# SPDX-License-Identifier: LGPL-2.1-or-later
"""Machining time per part and finishing strategy: our op's strategies against FreeCAD's own
3D Surface op (OpenCAMLib) at its flat stepover and retuned to our best strategy's scallop.

For each part (``--parts``; ``part`` is examples/part.step, ``step`` the plane-with-fillets
step of tests/TestBSplineCAMPartialPasses.py built here with FreeCAD's Part module and written
as STEP: a flat top, a 4 mm convex fillet, a 60 degree ramp, a 4 mm concave fillet and a flat
floor, 20 mm long), one job holds our finishing op on the faces reached from above and, after
it, FreeCAD's 3D Surface op on the same faces (both on the job's one ball-end tool controller:
the same HorizFeed, VertFeed and rapid rate).  Our op is recomputed with each strategy of
``--strategies`` (raster with partial passes, steep_shallow, scallop by default), then
FreeCAD's op at the flat stepover 2 sqrt(2Rh - h^2) and, with the secant search of
``benchmarks/toolpath.py`` (``--match-scallop``), at the stepover where its simulated largest
scallop is at most the one of our fastest strategy; when no stepover gets there (its samples
along the passes, SampleInterval apart, cut chords across concave fillets), the search runs
again with SampleInterval halved (``--match-sample-halvings``).

Each program is posted alone (linuxcnc), checked by rs274 and measured on its text: the time
with acceleration on the default machine (:func:`BSplineCAM.core.simulation.measures.
program_measures`: 500 mm/s^2 per axis, rapids 5000 mm/min, junction deviation 0.01 mm),
feed and rapid lengths, the vertical feeds among the feeds (plunges and retracts at the feed),
and the simulation against the part's exact faces (:func:`BSplineCAM.core.simulation.verify.
verify_faces`): gouge, largest and mean scallop, evenness and coverage away from the faces'
borders, and the largest scallop in the edge band (within the tool radius of a border).  The targets of issue 44
are checked per part: our fastest strategy (without gouge) no slower than FreeCAD's retuned
op, at least ``--raster-saving`` (30 %) faster than the raster, no gouge over
``--gouge-limit``, and an evenness of at least ``--evenness`` on the flat-and-fillet parts.

Run inside freecadcmd 0.20 with OpenCAMLib (as benchmarks/toolpath.py), one part per process
when parts are slow, then print the table of all the JSON files with ``--tables``:

    freecadcmd -c "import runpy, sys; sys.argv=['x', '--parts', 'part,step', '--json', 'out.json'];
                   runpy.run_path('benchmarks/machining_parts.py', run_name='__main__')"
    .venv/bin/python benchmarks/machining_parts.py --tables out1.json out2.json
"""

from __future__ import annotations

import argparse
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
    metrics = verify_faces(faces, program, Tool(args.diameter), cell=args.cell).metrics
    out["verify_seconds"] = time.perf_counter() - started
    for key in ("gouge_max_mm", "gouge_cells", "scallop_max_mm", "scallop_p99_mm",
                "scallop_mean_mm", "scallop_evenness", "scallop_mean_over_max", "coverage",
                "edge_scallop_max_mm", "edge_gouge_max_mm"):
        out[key] = float(metrics[key])
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
    ns = argparse.Namespace(part=str(part), faces=args.faces, diameter=args.diameter,
                            cell=args.cell, match_steps=args.match_steps,
                            match_rtol=args.match_rtol)
    doc = FreeCAD.newDocument("BSplineCAMMachiningParts")
    figures = {"part": name, "file": str(part), "ours": {}}
    try:
        faces, job, ours = bench.part_job(ns, params, doc)
        figures["faces"] = list(ours.Base[0][1])
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
        # Our op leaves the job: posting FreeCAD's op alone toggles the others' Active, which
        # would recompute ours again with each of FreeCAD's timed recomputes.
        doc.removeObject(ours.Name)
        doc.recompute()
        theirs = surface3d.add_freecad_surface_op(
            job, args.scallop, args.diameter, tolerance=args.tolerance, pattern=args.pattern)
        theirs.Base = [(job.Model.Group[0], figures["faces"])]
        print(f"{name}: FreeCAD 3D Surface ...", flush=True)
        seconds = bench.timed_recompute(doc, theirs)
        path = out / f"{stem}-freecad_3d_surface.ngc"
        text = bench.post_alone(job, theirs, path)
        flat = {"seconds": seconds, **measure_program(faces, text, path, args),
                "stepover_mm": args.diameter * theirs.StepOver / 100.0}
        figures["freecad_flat"] = flat
        figures["freecad_op"] = {"StepOver_percent": theirs.StepOver,
                                 "SampleInterval_mm": theirs.SampleInterval.Value,
                                 "CutPattern": theirs.CutPattern}
        print(f"{name}: FreeCAD flat: {summary(flat)}", flush=True)
        best = best_strategy(figures["ours"], args.gouge_limit)
        if best is None:
            figures["freecad_matched"] = {"matched": False, "reason": "no strategy of ours"}
            return figures
        target = figures["ours"][best]["scallop_max_mm"]
        matched = retune(bench, job, theirs, doc, faces, ns, args, out, flat, target, name)
        figures["freecad_matched"] = matched
        return figures
    finally:
        FreeCAD.closeDocument(doc.Name)


def retune(bench, job, theirs, doc, faces, ns, args, out: Path, flat: dict, target: float,
           name: str) -> dict:
    """FreeCAD's op retuned to ``target`` (mm): its StepOver by ``benchmarks/toolpath.py``'s
    search from its ``flat`` run; when no StepOver reaches the target (the samples along the
    passes, SampleInterval apart, cut chords across concave fillets), the search again from
    the flat StepOver with SampleInterval halved, up to ``--match-sample-halvings`` times.
    The result is the matching run (measured as the others) with every stage's trials."""
    stages = []
    interval = theirs.SampleInterval.Value
    first = flat
    for stage in range(args.match_sample_halvings + 1):
        folder = out / f"sample{stage}"
        folder.mkdir(exist_ok=True)
        if stage:
            interval /= 2.0
            theirs.SampleInterval = interval
            seconds = bench.timed_recompute(doc, theirs)
            path = folder / "freecad_3d_surface.ngc"
            text = bench.post_alone(job, theirs, path)
            first = {"seconds": seconds, **measure_program(faces, text, path, args),
                     "stepover_mm": args.diameter * theirs.StepOver / 100.0}
            print(f"{name}: FreeCAD flat, SampleInterval {interval:.3f} mm: {summary(first)}",
                  flush=True)
        matched = bench.match_scallop(job, theirs, doc, faces, ns, folder, first, target)
        stages.append({"sample_interval_mm": interval, "trials": matched["trials"]})
        if matched["matched"]:
            program = Path(matched["program"])
            matched.update(measure_program(faces, program.read_text(), program, args))
            matched["sample_interval_mm"] = interval
            print(f"{name}: FreeCAD matched: {summary(matched)}", flush=True)
            break
    matched["stages"] = stages
    return matched


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


def targets(figures: dict, settings: dict) -> list[str]:
    """Issue 44's targets on one part, each met or not and by how much."""
    ours = figures["ours"]
    best = best_strategy(ours, settings["gouge_limit_mm"])
    if best is None:
        return ["no strategy of ours ran"]
    b = ours[best]
    t = b["machining_time_with_acceleration_s"]
    lines = [f"fastest of ours: {best}, {t:.0f} s"]
    matched = figures.get("freecad_matched", {})
    if matched.get("matched"):
        fc = matched["machining_time_with_acceleration_s"]
        verdict = "met" if t <= fc else "NOT met"
        lines.append(f"no slower than FreeCAD's op retuned to {matched['target_scallop_mm']:.4f}"
                     f" mm ({fc:.0f} s): {verdict}, ours {100 * (t / fc - 1):+.0f} %")
    else:
        lines.append("FreeCAD's op retuned: no stepover reached our scallop "
                     f"({matched.get('reason', 'trials exhausted')})")
    raster = ours.get("raster", {})
    if "error" not in raster and raster:
        r = raster["machining_time_with_acceleration_s"]
        saving = 1.0 - t / r
        need = settings["raster_saving"]
        verdict = "met" if saving >= need else "NOT met"
        lines.append(f"at least {100 * need:.0f} % less than the raster ({r:.0f} s): {verdict}, "
                     f"{100 * saving:.0f} % less")
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
            f"{1000 * r['gouge_max_mm']:.2f} | "
            f"{100 * r['coverage']:.1f} % | {r['rs274']} |")


def table(results: list[dict]) -> str:
    lines = []
    for figures in results:
        s = figures["settings"]
        lines += [
            f"**{figures['part']}** ({figures['file']}, faces {', '.join(figures['faces'])}; "
            f"ball {s['diameter_mm']:g} mm, scallop {s['scallop_mm']:g} mm, tolerance "
            f"{s['tolerance_mm']:g} mm)",
            "",
            "| program | compute s | feed m | of which vertical m | rapid m | time with "
            "acceleration s | largest / mean scallop mm | evenness | edge band scallop mm "
            "| gouge um | coverage | rs274 |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        lines += [row(k, v) for k, v in figures["ours"].items()]
        flat = figures.get("freecad_flat")
        if flat:
            lines.append(row(f"FreeCAD 3D Surface, flat stepover {flat['stepover_mm']:.3f} mm, "
                             f"SampleInterval {figures['freecad_op']['SampleInterval_mm']:.3f}"
                             " mm", flat))
        matched = figures.get("freecad_matched", {})
        if matched.get("matched"):
            lines.append(row(f"FreeCAD 3D Surface, retuned stepover "
                             f"{matched['stepover_mm']:.3f} mm, SampleInterval "
                             f"{matched['sample_interval_mm']:.3f} mm", matched))
        for stage in matched.get("stages", []):
            lines.append("")
            lines.append(f"FreeCAD's retuning at SampleInterval {stage['sample_interval_mm']:.3f}"
                         " mm (stepover -> largest scallop): " + "; ".join(
                             f"{t['stepover_mm']:.3f} -> {t['scallop_max_mm']:.4f} mm"
                             for t in stage["trials"]))
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
    if not args.strategies:
        parser.error("--strategies: give at least one")
    if args.match_steps < 1:
        parser.error(f"--match-steps must be at least 1, got {args.match_steps}")
    if not 0.0 < args.match_rtol < 1.0:
        parser.error(f"--match-rtol must be in (0, 1), got {args.match_rtol}")
    bench = load_toolpath_benchmark()
    from BSplineCAM.app import compat

    if not compat.opencamlib_available():
        raise SystemExit(f"this benchmark: {compat.opencamlib_missing_message()}")
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bsplinecam-parts-"))
    out.mkdir(parents=True, exist_ok=True)
    settings = {"diameter_mm": args.diameter, "scallop_mm": args.scallop,
                "tolerance_mm": args.tolerance, "cell_mm": args.cell,
                "gouge_limit_mm": args.gouge_limit, "raster_saving": args.raster_saving,
                "evenness": args.evenness,
                "freecad": ".".join(map(str, compat.freecad_version())),
                "source": source_version(), "date": time.strftime("%Y-%m-%d %H:%M UTC",
                                                                  time.gmtime())}
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
