# SPDX-License-Identifier: LGPL-2.1-or-later
"""BSplineCAM's raster op against FreeCAD's own 3D Surface op (OpenCAMLib) on the case study
(or ``--surface dome|saddle|waves|NET``).

Both ops sit in one job on the same model and tool (6 mm ball by default) and aim at the same
scallop height (0.01 mm by default): the raster by its curvature-aware stepover, the 3D
Surface op by the flat stepover 2 sqrt(2Rh - h^2) (see :mod:`BSplineCAM.app.surface3d`).
Each op's first recompute is timed; each is posted alone with linuxcnc, checked by rs274 and
simulated from its G-code text with :func:`BSplineCAM.core.simulation.verify.verify`.

The flat stepover leaves a larger scallop than requested on steep walls, so with
``--match-scallop`` the 3D Surface op is recomputed at other StepOvers (a power-law secant on
the measured scallop, kept inside the bracket of passing and failing trials) until the
simulation measures its largest scallop at most our op's measured one (``--match-target ours``)
or the requested one (``requested``): its moves and time at that stepover make a third column.

With ``--part PART.step [--faces up|3,8]`` the model is a part instead of a net: our op
machines the selected faces (default: every face a 3-axis tool reaches from above, as
``bsplinecam part`` picks them), the 3D Surface op gets the same faces as its Base, and both
programs are simulated against the part's exact faces (gouge over the whole model, scallop and
coverage on the selected faces away from their borders, as ``bsplinecam verify PART PROGRAM
--faces ...``; see :func:`BSplineCAM.core.simulation.verify.verify_faces`).  Our op on parts is slow
(drop-cutter queries at tangent joints): pass a scallop it finishes in (say 0.1 mm).

Needs a FreeCAD with OpenCAMLib (0.20 with the PyPI wheel, 1.0 and 1.1 with Debian's
python3-opencamlib); run inside freecadcmd (for 1.0 or 1.1: tools/freecad11.sh freecadcmd -c ...):

    freecadcmd -c "import runpy, sys; sys.argv=['x', '--scallop', '0.01', '--json', 'out.json'];
                   runpy.run_path('benchmarks/toolpath.py', run_name='__main__')"
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.app import cam, compat, pipeline, surface3d  # noqa: E402
from BSplineCAM.core.program import rs274  # noqa: E402
from BSplineCAM.core.program.gcode import MoveKind, read_gcode  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify, verify_faces  # noqa: E402
from BSplineCAM.orchestration import parts  # noqa: E402

FreeCAD = compat.ensure_freecad()
CASE_STUDY = ROOT / "examples" / "case-study.json"
#: Table rows: (label, key in a result, format).
ROWS = (
    ("time (s)", "seconds", "{:.2f}"),
    ("gouge max (mm)", "gouge_max_mm", "{:.4f}"),
    ("largest scallop (mm)", "scallop_max_mm", "{:.4f}"),
    ("scallop p99 (mm)", "scallop_p99_mm", "{:.4f}"),
    ("coverage", "coverage", "{:.4f}"),
    ("moves", "moves", "{:d}"),
    ("cutting length (mm)", "cutting_length_mm", "{:.0f}"),
    ("  of which vertical (mm)", "vertical_feed_mm", "{:.0f}"),
    ("rs274", "rs274", "{}"),
)

#: Rows that get a FreeCAD / BSplineCAM ratio.
RATIOS = ("seconds", "moves", "cutting_length_mm", "vertical_feed_mm")


def timed_recompute(doc, op) -> float:
    """Seconds of the document recompute that computes ``op`` (just added, so still touched)."""
    start = time.perf_counter()
    doc.recompute()
    seconds = time.perf_counter() - start
    if not op.Path.Commands:
        raise RuntimeError(f"{op.Label} produced no path")
    return seconds


def post_alone(job, op, path: Path) -> str:
    """Post ``op`` alone (the job's other ops made inactive meanwhile) with linuxcnc."""
    others = [o for o in job.Operations.Group if o is not op]
    states = [o.Active for o in others]
    try:
        for other in others:
            other.Active = False
        op.Active = True
        return cam.post_process(job, "linuxcnc", path)
    finally:
        for other, state in zip(others, states):
            other.Active = state


def measure(design, text: str, path: Path, diameter: float, cell: float) -> dict:
    """rs274's verdict and the simulation's metrics of one posted program against ``design``:
    a Surface, or a part's faces (a list of core Faces, the machined ones ``selected``)."""
    result = {}
    if rs274.available():
        check = rs274.check(path, {1: diameter})
        result["rs274"] = "ok" if check.ok else f"FAILED: {check.message}"
    else:
        result["rs274"] = "not installed"
    program = read_gcode(text)
    check = verify if isinstance(design, Surface) else verify_faces
    metrics = check(design, program, Tool(diameter), cell=cell).metrics
    keys = (
        "gouge_max_mm",
        "gouge_cells",
        "scallop_max_mm",
        "scallop_p99_mm",
        "scallop_mean_mm",
        "edge_scallop_max_mm",
        "edge_gouge_max_mm",
        "coverage",
        "cutting_length_mm",
        "rapid_length_mm",
        "machining_time_s",
    )
    result.update({k: metrics[k] for k in keys})
    result["rapid_collisions"] = len(metrics["rapid_collisions"])
    feeds = program.kind != MoveKind.RAPID
    lateral = np.hypot(*(program.end[:, :2] - program.start[:, :2]).T)
    result["vertical_feed_mm"] = float(program.lengths()[feeds & (lateral < 1e-9)].sum())
    result["moves"] = len(program)
    result["feed_moves"] = int((program.kind != MoveKind.RAPID).sum())
    return result


def benchmark_surface(name: str) -> Surface:
    """The surfaces of the benchmark: the case study, or one made here by name (a steep dome,
    a saddle, a field of waves), or a control-net file."""
    if name == "case-study":
        return Surface.from_json(CASE_STUDY)
    if name in SURFACES:
        n, size, height = SURFACES[name]
        x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n), indexing="ij")
        z = height(x / size, y / size)
        return Surface(np.stack([x, y, z], axis=-1), "clamped", name)
    return Surface.from_file(name)


#: name -> (net points per side, footprint side mm, z(u, w) mm on [0, 1]^2).
SURFACES = {
    "dome": (9, 60.0, lambda u, w: 10 + 40 * np.exp(-((u - 0.5) ** 2 + (w - 0.5) ** 2) / 0.05)),
    "saddle": (8, 80.0, lambda u, w: 20 + 30 * (u - 0.5) ** 2 - 30 * (w - 0.5) ** 2),
    "waves": (14, 100.0, lambda u, w: 15 + 4 * np.sin(6 * u) * np.cos(5 * w) + 3 * u),
}


#: Keys of a matching trial kept in the figures.
TRIAL_KEYS = ("seconds", "moves", "scallop_max_mm", "scallop_p99_mm", "gouge_max_mm", "coverage")


def next_stepover(trials: list[dict], target: float, aim: float) -> float:
    """The next stepover (mm) to try so that the measured scallop comes to ``aim * target``.

    The scallop is modelled as c * stepover^p, p fitted through the last two trials (2, the
    flat's exponent, with one trial; clamped to [0.5, 4]); the step stays inside the bracket of
    the largest stepover that met ``target`` and the smallest that did not (geometric
    bisection when the model steps out of it)."""
    last = trials[-1]
    power = 2.0
    if len(trials) > 1:
        a, b = trials[-2], trials[-1]
        ds = np.log(b["stepover_mm"] / a["stepover_mm"])
        dh = np.log(b["scallop_max_mm"] / a["scallop_max_mm"])
        if abs(ds) > 1e-9 and dh / ds > 0:
            power = float(np.clip(dh / ds, 0.5, 4.0))
    step = last["stepover_mm"] * (aim * target / last["scallop_max_mm"]) ** (1.0 / power)
    passing = [t["stepover_mm"] for t in trials if t["scallop_max_mm"] <= target]
    failing = [t["stepover_mm"] for t in trials if t["scallop_max_mm"] > target]
    low = max(passing, default=0.0)
    high = min(failing, default=np.inf)
    if not low < step < high:
        if low > 0 and np.isfinite(high):
            step = np.sqrt(low * high)
        else:
            step = 0.7 * high if np.isfinite(high) else 1.3 * low
    return float(step)


def match_scallop(job, op, doc, surface, args, out: Path, first: dict, target: float) -> dict:
    """Reduce FreeCAD's StepOver until its measured largest scallop is <= ``target`` (mm).

    ``first`` is the op's measured run at its flat stepover.  Each trial recomputes the op
    (timed), posts it alone and simulates it as the first run was.  Stops at the first trial
    within [(1 - args.match_rtol) target, target] or after ``args.match_steps`` new trials; the
    result is the matching trial with the largest stepover (``matched`` false when none met
    the target), with the list of all trials."""
    diameter = args.diameter
    flat = op.StepOver
    results = [{**first, "stepover_mm": diameter * flat / 100.0}]
    trials = [{k: results[0][k] for k in ("stepover_mm", *TRIAL_KEYS)}]
    try:
        trials_loop(job, op, doc, surface, args, out, target, results, trials)
    finally:
        op.StepOver = flat  # the op's properties in the figures are those of its first run
    passing = [r for r in results if r["scallop_max_mm"] <= target]
    if not passing:
        return {"matched": False, "target_scallop_mm": target, "trials": trials}
    best = max(passing, key=lambda r: r["stepover_mm"])
    return {**best, "matched": True, "target_scallop_mm": target, "trials": trials}


def trials_loop(job, op, doc, surface, args, out: Path, target: float, results: list,
                trials: list) -> None:
    """:func:`match_scallop`'s reruns, appended to ``results`` (measured runs) and ``trials``."""
    diameter = args.diameter
    for index in range(1, args.match_steps + 1):
        last = trials[-1]["scallop_max_mm"]
        if (1.0 - args.match_rtol) * target <= last <= target:
            break
        op.StepOver = 100.0 * next_stepover(trials, target, 1.0 - args.match_rtol / 2.0) / diameter
        stepover = diameter * op.StepOver / 100.0  # as the property stored it
        seconds = timed_recompute(doc, op)
        path = out / f"freecad_3d_surface-match{index}.ngc"
        text = post_alone(job, op, path)
        result = {"seconds": seconds, **measure(surface, text, path, diameter, args.cell)}
        result.update(program=str(path), stepover_mm=stepover)
        results.append(result)
        trials.append({k: result[k] for k in ("stepover_mm", *TRIAL_KEYS)})
        print(
            f"match {index}: stepover {stepover:.4f} mm, scallop {result['scallop_max_mm']:.4f}"
            f" mm (target {target:.4f}), {result['moves']} moves, {seconds:.1f} s",
            flush=True,
        )


def part_job(args: argparse.Namespace, params, doc):
    """The part's faces (core Faces, the selection ``selected``) and (job, our op) on its
    model, the op's Base those faces."""
    from BSplineCAM.app.faces import read_part

    faces = parts.load_faces(args.part, args.faces)
    chosen = [f.index for f in faces if f.selected]
    if not chosen:
        raise SystemExit(f"--faces {args.faces}: no face of {args.part} selected")
    model = doc.addObject("Part::Feature", "Part")
    model.Shape = read_part(args.part)
    model.Label = Path(args.part).stem
    doc.recompute()
    job, ours = pipeline.build_faces_job(model, params, cam.Cutting(), chosen)
    return faces, job, ours


def run(args: argparse.Namespace) -> dict:
    if not compat.opencamlib_available():
        raise SystemExit(f"this benchmark: {compat.opencamlib_missing_message()}")
    params = pipeline.FinishingParameters(
        tool_diameter=args.diameter,
        scallop=args.scallop,
        tolerance=args.tolerance,
        strategy="raster",
    )
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bsplinecam-bench-"))
    out.mkdir(parents=True, exist_ok=True)
    doc = FreeCAD.newDocument("BSplineCAMBenchmark")
    try:
        if args.part:
            surface, job, ours = part_job(args, params, doc)
        else:
            surface = benchmark_surface(args.surface)
            _, job, ours = pipeline.build_job(surface, params, cam.Cutting(), doc)
        results = {"bsplinecam": {"seconds": timed_recompute(doc, ours)}}
        theirs = surface3d.add_freecad_surface_op(
            job,
            args.scallop,
            args.diameter,
            tolerance=args.tolerance,
            pattern=args.pattern,
            sample_interval=args.sample_interval,
        )
        if args.part:  # the same faces as ours (the helper picks the net's one face)
            theirs.Base = [(job.Model.Group[0], list(ours.Base[0][1]))]
        results["freecad_3d_surface"] = {"seconds": timed_recompute(doc, theirs)}
        if json.loads(ours.Report or "{}").get("error"):
            raise RuntimeError(ours.Report)
        for key, op in (("bsplinecam", ours), ("freecad_3d_surface", theirs)):
            path = out / f"{key}.ngc"
            text = post_alone(job, op, path)
            results[key].update(measure(surface, text, path, args.diameter, args.cell))
            results[key]["program"] = str(path)
        if args.match_scallop:
            target = (
                results["bsplinecam"]["scallop_max_mm"]
                if args.match_target == "ours"
                else args.scallop
            )
            results["freecad_matched"] = match_scallop(
                job, theirs, doc, surface, args, out, results["freecad_3d_surface"], target
            )
        return {
            "surface": f"{args.part} faces {args.faces or 'up'} "
                       f"({', '.join(ours.Base[0][1])})" if args.part else args.surface,
            "freecad": ".".join(map(str, compat.freecad_version())),
            "tool_diameter_mm": args.diameter,
            "scallop_mm": args.scallop,
            "tolerance_mm": args.tolerance,
            "cell_mm": args.cell,
            "freecad_op": {
                "ScanType": theirs.ScanType,
                "LayerMode": theirs.LayerMode,
                "CutPattern": theirs.CutPattern,
                "CutPatternAngle": theirs.CutPatternAngle,
                "StepOver_percent": theirs.StepOver,
                "stepover_mm": args.diameter * theirs.StepOver / 100.0,
                "SampleInterval_mm": theirs.SampleInterval.Value,
                "LinearDeflection_mm": theirs.LinearDeflection.Value,
                "BoundaryAdjustment_mm": theirs.BoundaryAdjustment.Value,
                "Base": [f"{o.Label}.{s}" for o, subs in theirs.Base for s in subs],
            },
            "bsplinecam_report": json.loads(ours.Report),
            "speedup": results["freecad_3d_surface"]["seconds"] / results["bsplinecam"]["seconds"],
            **results,
        }
    finally:
        FreeCAD.closeDocument(doc.Name)


def table(figures: dict) -> str:
    ours, theirs = figures["bsplinecam"], figures["freecad_3d_surface"]
    matched = figures.get("freecad_matched")
    columns = [ours, theirs]
    header = f"{'':24}{'BSplineCAM raster':>20}{'FreeCAD 3D Surface':>20}{'FC/ours':>10}"
    if matched and matched["matched"]:
        columns.append(matched)
        header += f"{'FC matched':>14}{'FCm/ours':>10}"
    lines = [
        f"{figures['surface']}, {figures['tool_diameter_mm']:g} mm ball, scallop "
        f"{figures['scallop_mm']:g} mm, FreeCAD {figures['freecad']}",
        header,
    ]
    rows = ROWS
    if matched:
        rows = (("stepover (mm)", "stepover_mm", "{:.4f}"), *ROWS)
        theirs = {**theirs, "stepover_mm": figures["freecad_op"]["stepover_mm"]}
        columns[1] = theirs
        ours = {**ours, "stepover_mm": float("nan")}
        columns[0] = ours
    for label, key, fmt in rows:
        line = f"{label:24}"
        for index, column in enumerate(columns):
            value = column[key]
            width = 20 if index < 2 else 14
            line += f"{fmt.format(value) if value == value else 'curvature':>{width}}"
            if index and key in RATIOS and ours[key]:
                line += f"{value / ours[key]:>10.2f}"
            elif index:
                line += f"{'':>10}"
        lines.append(line.rstrip())
    if matched:
        lines.append(
            f"matching FreeCAD's largest scallop to {matched['target_scallop_mm']:.4f} mm: "
            + ("" if matched["matched"] else "NOT reached; ")
            + "; ".join(
                f"{t['stepover_mm']:.4f} mm -> {t['scallop_max_mm']:.4f} mm, {t['moves']} moves"
                for t in matched["trials"]
            )
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--surface", default="case-study",
                        help="case-study, dome, saddle, waves, or a control-net file")
    parser.add_argument("--part", help="machine this part (.step, .brep, .FCStd) instead of "
                        "a net")
    parser.add_argument("--faces", help="with --part: up (default) or face numbers such as 3,8")
    parser.add_argument("--diameter", type=float, default=6.0, help="ball diameter (mm)")
    parser.add_argument("--scallop", type=float, default=0.01, help="scallop height (mm)")
    parser.add_argument("--tolerance", type=float, default=0.002, help="chordal tolerance (mm)")
    parser.add_argument("--cell", type=float, default=0.1, help="simulation cell (mm)")
    parser.add_argument(
        "--pattern",
        choices=surface3d.CUT_PATTERNS,
        default="ZigZag",
        help="the 3D Surface op's CutPattern",
    )
    parser.add_argument(
        "--sample-interval",
        type=float,
        default=None,
        help="the 3D Surface op's SampleInterval (mm; default sqrt(8 R tol))",
    )
    parser.add_argument(
        "--match-scallop",
        action="store_true",
        help="also rerun the 3D Surface op at smaller (or larger) StepOver until its measured "
        "largest scallop is at most the target (--match-target), each run simulated",
    )
    parser.add_argument(
        "--match-target",
        choices=("ours", "requested"),
        default="ours",
        help="the scallop to match: our op's measured largest scallop or --scallop",
    )
    parser.add_argument("--match-steps", type=int, default=5,
                        help="most reruns of the 3D Surface op with --match-scallop")
    parser.add_argument("--match-rtol", type=float, default=0.1,
                        help="stop once the measured scallop is within this fraction below "
                        "the target")
    parser.add_argument("--out", help="folder for the two programs (default: a temporary one)")
    parser.add_argument("--json", help="write the figures to this JSON file")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.match_steps < 1:
        parser.error(f"--match-steps must be at least 1, got {args.match_steps}")
    if not 0.0 < args.match_rtol < 1.0:
        parser.error(f"--match-rtol must be in (0, 1), got {args.match_rtol}")
    if args.faces is not None and not args.part:
        parser.error("--faces applies to --part")
    if args.part and not Path(args.part).is_file():
        parser.error(f"--part {args.part}: no such file")
    figures = run(args)
    print(table(figures))
    if args.json:
        Path(args.json).write_text(json.dumps(figures, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
