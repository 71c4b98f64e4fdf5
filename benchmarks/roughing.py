# SPDX-License-Identifier: LGPL-2.1-or-later
"""BSplineCAM's roughing op against what a FreeCAD user roughs with today (issue 12, item 6).

On the case study, from the stock block our job makes (part box + 2 mm sideways and on top,
bottom at the part's), with the same 10 mm flat end mill, step-down 2 mm, stepover 40 % and
0.3 mm to leave where the op has such a setting:

* ``bsplinecam``: our Z-level roughing op (``pipeline.build_job(..., roughing=...)``);
* ``bsplinecam_fine2``, ``bsplinecam_fine4``: the same op at ``--deep-stepdown`` (8 mm) with
  a fine step-down (``FineStepDown``) of 2 and 4 mm: the bulk at the deep step, the terraces
  no thicker than the fine one (its bounded width of cut is what lets the flute go deeper);
* ``bsplinecam_fine4_ramp5``: 8 + 4 mm with the entries ramped at 5 degrees (``RampAngle``;
  FreeCAD's Adaptive op starts its helices at 5) instead of our default 3;
* ``bsplinecam_fine4_load``: 8 + 4 mm at a 25 % stepover, the fair load: 2.5 mm wide by 8 mm
  deep is the 20 mm^2 cross-section of cut of the 3D Pocket's full-width slot 2 mm deep;
* ``freecad_3d_pocket``: FreeCAD's 3D Pocket (0.20 ``PathScripts.PathPocket``) on the whole
  model with ``ProcessStockArea`` (it pockets the stock minus the part, level by level), its
  ``ExtraOffset`` as the sideways stock to leave (it has no vertical one; its FinishDepth is
  the depth of a last thin step, not an allowance) and ``FinalDepth`` = lowest design point
  + 0.3 mm;
* ``freecad_3d_surface_multipass``: FreeCAD's 3D Surface op (OpenCAMLib drop-cutter) on the
  whole model, ``LayerMode`` "Multi-pass" with StepDown 2 mm, ``DepthOffset`` 0.3 mm (its
  stock to leave), ``BoundBox`` "Stock" so the passes cover the block.

Each op is computed and posted (linuxcnc) alone, each in a child freecadcmd (one after the
other) bounded by ``--timeout`` seconds: a hang or a crash is reported, not dropped.  Every program is then
simulated from the block (:func:`BSplineCAM.core.simulation.verify.verify_job`) and measured: stock left
above the design over the part's footprint (snapshot after the tool minus design; a negative
minimum is a gouge), radial and axial engagement outside entries, rapid collisions, machining
time nominal and with acceleration (:mod:`BSplineCAM.core.simulation.machining_time`).

Run with FreeCAD 0.20's interpreter (the peers need its Path workbench, the Surface op
OpenCAMLib):

    freecadcmd -c "import runpy, sys; sys.argv=['x']; runpy.run_path('benchmarks/roughing.py',
                   run_name='__main__')"

Writes build/bench/roughing.json, the programs and pictures of the stock left per op there.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.app import cam, compat, pipeline  # noqa: E402
from BSplineCAM.core.program.gcode import MoveKind, read_gcode  # noqa: E402
from BSplineCAM.core.simulation.machining_time import machining_time  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify_job  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from toolpath import post_alone, timed_recompute  # noqa: E402  (benchmarks/toolpath.py)

FreeCAD = compat.ensure_freecad()
CASE_STUDY = ROOT / "examples" / "case-study.json"
OUT = ROOT / "build" / "bench"
OPS = ("bsplinecam", "bsplinecam_fine2", "bsplinecam_fine4", "bsplinecam_fine4_ramp5",
       "bsplinecam_fine4_load", "freecad_3d_pocket", "freecad_3d_surface_multipass")
OURS = OPS[:5]
PEERS = OPS[5:]
#: Fine step-down (mm) of our variants at the deep step-down.
FINE = {"bsplinecam_fine2": 2.0, "bsplinecam_fine4": 4.0, "bsplinecam_fine4_ramp5": 4.0,
        "bsplinecam_fine4_load": 4.0}
#: Stepover (% of the diameter) of a variant, if not --stepover: the fair load's 25 % x 8 mm
#: deep is the Pocket's full 10 mm width x 2 mm.
STEPOVER = {"bsplinecam_fine4_load": 25}
#: Ramp angle (degrees) of a variant, if not the default: 5 is the helix angle FreeCAD's
#: Adaptive op starts with.
RAMP = {"bsplinecam_fine4_ramp5": 5.0}
TITLES = {"bsplinecam": "BSplineCAM rough", "bsplinecam_fine2": "ours deep+fine 2",
          "bsplinecam_fine4": "ours deep+fine 4", "bsplinecam_fine4_ramp5": "ours 8+4, 5 deg",
          "bsplinecam_fine4_load": "ours 8+4, 25 %",
          "freecad_3d_pocket": "FC 3D Pocket",
          "freecad_3d_surface_multipass": "FC Surface multi"}
#: Table rows: (label, key in a result, format).
ROWS = (
    ("compute time (s)", "seconds", "{:.2f}"),
    ("program moves", "moves", "{:d}"),
    ("machining time (min)", "machining_time_min", "{:.2f}"),
    ("  with acceleration (min)", "machining_time_accel_min", "{:.2f}"),
    ("  of which rapids (min)", "rapid_time_min", "{:.2f}"),
    ("cutting length (mm)", "cutting_length_mm", "{:.0f}"),
    ("air (feed, no cut) (mm)", "air_length_mm", "{:.0f}"),
    ("removed volume (cm3)", "removed_volume_cm3", "{:.1f}"),
    ("stock left min (mm)", "stock_left_min_mm", "{:.3f}"),
    ("stock left max (mm)", "stock_left_max_mm", "{:.3f}"),
    ("stock left mean (mm)", "stock_left_mean_mm", "{:.3f}"),
    ("stock left p95 (mm)", "stock_left_p95_mm", "{:.3f}"),
    ("gouged cells (< -0.01 mm)", "gouged_cells", "{:d}"),
    ("share < allowance - 0.02", "below_allowance_fraction", "{:.3f}"),
    ("share > stepdown+allow.+0.02", "over_stepdown_fraction", "{:.4f}"),
    ("radial engagement max (mm)", "radial_engagement_max_mm", "{:.2f}"),
    ("radial engagement mean (mm)", "radial_engagement_mean_mm", "{:.2f}"),
    ("effective width (mm)", "effective_width_mm", "{:.2f}"),
    ("axial engagement max (mm)", "axial_engagement_max_mm", "{:.2f}"),
    ("axial engagement mean (mm)", "axial_engagement_mean_mm", "{:.2f}"),
    ("mean removal rate (cm3/min)", "mean_removal_rate_cm3_per_min", "{:.2f}"),
    ("entries", "entries", "{:d}"),
    ("entry radial max (mm)", "entry_radial_engagement_max_mm", "{:.2f}"),
    ("rapid collisions", "rapid_collisions", "{:d}"),
)
#: A cell this far below the design (mm) counts as gouged (the Z-map's own error is smaller).
GOUGE_MM = 0.01
#: Slack (mm) of the allowance and step-down fractions (the Z-map's error is smaller).
SLACK_MM = 0.02




def make_job(doc, surface: Surface, args: argparse.Namespace, name: str = "bsplinecam"):
    """Our job (roughing T1 flat, finishing T2 ball made inactive): (job, roughing op); for
    a fine variant at the deep step-down with its fine step-down."""
    fine = FINE.get(name, 0.0)
    roughing = pipeline.RoughingParameters(
        shape="flat", diameter=args.diameter,
        stepdown=args.deep_stepdown if fine else args.stepdown, fine_stepdown=fine,
        stepover_percent=STEPOVER.get(name, args.stepover), radial_allowance=args.allowance,
        axial_allowance=args.allowance, stock_margin=args.margin,
        ramp_angle=RAMP.get(name, pipeline.RoughingParameters.ramp_angle))
    finishing = pipeline.FinishingParameters(tool_diameter=6.0, scallop=0.01)
    _, job, finish = pipeline.build_job(surface, finishing, cam.Cutting(), doc, roughing=roughing)
    finish.Active = False  # not computed, not posted
    return job, job.Operations.Group[0]


def add_pocket(job, args: argparse.Namespace, zmin_design: float):
    """FreeCAD's 3D Pocket on the whole model and stock, set up as the module doc says."""
    op = _path_module("PathPocket").Create("Pocket3D", parentJob=job)
    op.ToolController = job.Tools.Group[0]
    op.Base = []
    op.ProcessStockArea = True
    op.StepOver = int(args.stepover)
    op.OffsetPattern = "ZigZag"
    op.ZigZagAngle = 0.0
    op.ExtraOffset = args.allowance
    op.setExpression("StepDown", None)
    op.StepDown = args.stepdown
    box = job.Stock.Shape.BoundBox
    for name, value in (("StartDepth", box.ZMax), ("FinalDepth", zmin_design + args.allowance)):
        op.setExpression(name, None)
        setattr(op, name, value)
    return op


def add_surface(job, args: argparse.Namespace):
    """FreeCAD's 3D Surface op, multi-pass, on the whole model, over the stock's box."""
    if not compat.opencamlib_available():
        raise RuntimeError(compat.opencamlib_missing_message())
    op = compat.cam_module("surface_op").Create("Surface3DMulti", parentJob=job)
    op.ToolController = job.Tools.Group[0]
    op.Base = []
    op.ScanType = "Planar"
    op.LayerMode = "Multi-pass"
    op.CutPattern = "ZigZag"
    op.CutPatternAngle = 0.0
    op.BoundBox = "Stock"
    op.StepOver = int(args.stepover)
    op.DepthOffset = args.allowance
    op.setExpression("StepDown", None)
    op.StepDown = args.stepdown
    box = job.Stock.Shape.BoundBox
    op.setExpression("StartDepth", None)
    op.StartDepth = box.ZMax
    return op


def _path_module(name: str):
    import importlib

    return importlib.import_module(f"PathScripts.{name}")


def op_settings(op) -> dict:
    """The op's settings that the comparison depends on, JSON-ready."""
    names = ("StepDown", "StepOver", "StartDepth", "FinalDepth", "ExtraOffset", "OffsetPattern",
             "ZigZagAngle", "ProcessStockArea", "FinishDepth", "LayerMode", "ScanType",
             "CutPattern", "BoundBox", "DepthOffset", "SampleInterval", "RadialAllowance",
             "AxialAllowance", "FlatLevels")
    out = {}
    for name in names:
        if hasattr(op, name):
            value = getattr(op, name)
            out[name] = value.Value if hasattr(value, "Value") else value
    return out


def run_op(name: str, args: argparse.Namespace, result_path: Path) -> None:
    """Child process: compute and post one op alone, write {seconds, program, settings, stock}.

    For a peer, our two ops and the ball's controller leave the job first (so that they are
    not computed, and the peer's op picks the flat end mill, the job's only controller)."""
    surface = Surface.from_json(CASE_STUDY)
    doc = FreeCAD.newDocument("RoughingBench")
    try:
        job, ours = make_job(doc, surface, args, name)
        if name in OURS:
            op = ours
            op.touch()  # timed from scratch, whatever the job's set-up computed already
        else:
            flat = ours.ToolController
            for other in list(job.Operations.Group)[::-1]:
                job.Operations.removeObject(other)
                doc.removeObject(other.Name)
            for tc in list(job.Tools.Group):
                if tc is not flat:
                    job.Tools.removeObject(tc)
                    doc.removeObject(tc.Name)
            doc.recompute()
            zmin = float(surface.grid(201, 201)[..., 2].min())
            op = add_pocket(job, args, zmin) if name == "freecad_3d_pocket" else add_surface(
                job, args)
        seconds = timed_recompute(doc, op)
        box = job.Stock.Shape.BoundBox  # grown by the margin (after a recompute)
        stock = [box.XMin, box.XMax, box.YMin, box.YMax, box.ZMin, box.ZMax]
        report = json.loads(getattr(op, "Report", "") or "{}")
        if report.get("error"):
            raise RuntimeError(op.Report)
        path = Path(args.out) / f"{name}.ngc"
        post_alone(job, op, path)
        result_path.write_text(json.dumps({
            "seconds": seconds, "program": str(path), "settings": op_settings(op),
            "stock_mm": stock, "report": {k: v for k, v in report.items() if k != "levels"}},
            default=str))
    finally:
        FreeCAD.closeDocument(doc.Name)


def op_in_child(name: str, args: argparse.Namespace) -> dict:
    """Compute ``name`` in a child freecadcmd bounded by ``args.timeout``: its figures or why
    not (a hang or a crash of one op does not stop the others)."""
    result_path = Path(args.out) / f"{name}.result.json"
    result_path.unlink(missing_ok=True)
    argv = [sys.argv[0] if sys.argv else "roughing.py", "--op", name, *child_options(args)]
    code = (f"import runpy, sys; sys.argv={argv!r}; "
            f"runpy.run_path({str(Path(__file__).resolve())!r}, run_name='__main__')")
    log = Path(args.out) / f"{name}.log"
    started = time.perf_counter()
    with log.open("w") as out:
        try:
            proc = subprocess.run([args.freecadcmd, "-c", code], stdout=out,
                                  stderr=subprocess.STDOUT, timeout=args.timeout,
                                  env={**os.environ, "PYTHONPATH": str(ROOT)})
        except subprocess.TimeoutExpired:
            return {"failed": f"no result within the {args.timeout:g} s timeout (killed)",
                    "log": str(log)}
    if not result_path.exists():
        tail = log.read_text(errors="replace").strip().splitlines()[-5:]
        return {"failed": f"exit status {proc.returncode} after "
                          f"{time.perf_counter() - started:.0f} s: {' | '.join(tail)}",
                "log": str(log)}
    return {**json.loads(result_path.read_text()), "log": str(log)}


def child_options(args: argparse.Namespace) -> list[str]:
    return ["--diameter", str(args.diameter), "--stepdown", str(args.stepdown),
            "--deep-stepdown", str(args.deep_stepdown),
            "--stepover", str(args.stepover), "--allowance", str(args.allowance),
            "--margin", str(args.margin), "--out", str(args.out)]


def measure(surface: Surface, text: str, stock: tuple, args: argparse.Namespace,
            picture: Path) -> dict:
    """The program simulated from ``stock`` with the flat end mill, measured (module doc)."""
    program = read_gcode(text)
    numbers = sorted({int(t) for t in np.unique(program.tool)} | {1})
    tools = {n: Tool(args.diameter, "flat") for n in numbers if n > 0} or {1: Tool(args.diameter,
                                                                                     "flat")}
    feeds = program.kind != MoveKind.RAPID
    if not feeds.any():  # an op whose recompute failed posts its frame only
        return {"failed": "its program has no feed move (see its log)"}
    number = int(program.tool[np.flatnonzero(feeds)[-1]])
    result = verify_job(surface, program, tools, stock=stock, cell=args.cell)
    left = result.job.snapshots[number] - result.design
    left = left[result.inside & np.isfinite(left)]
    tool = result.metrics["tools"][str(number)]
    timing = machining_time(program)
    figures = {
        "moves": len(program),
        "machining_time_min": timing.nominal / 60.0,
        "machining_time_accel_min": timing.total / 60.0,
        "rapid_time_min": float(timing.nominal_time[timing.rapid].sum()) / 60.0,
        "stock_left_min_mm": float(left.min()),
        "stock_left_max_mm": float(left.max()),
        "stock_left_mean_mm": float(left.mean()),
        "stock_left_p05_mm": float(np.percentile(left, 5)),
        "stock_left_p95_mm": float(np.percentile(left, 95)),
        "gouged_cells": int(np.sum(left < -GOUGE_MM)),
        "below_allowance_fraction": float(np.mean(left < args.allowance - SLACK_MM)),
        "over_stepdown_fraction": float(np.mean(left > args.stepdown + args.allowance + SLACK_MM)),
        "footprint_cells": int(left.size),
        "removed_volume_cm3": tool["removed_volume_mm3"] / 1000.0,
        "rapid_collisions": len(result.metrics["rapid_collisions"]),
    }
    for key in ("cutting_length_mm", "air_length_mm", "rapid_length_mm",
                "radial_engagement_max_mm", "radial_engagement_mean_mm",
                "axial_engagement_max_mm", "axial_engagement_mean_mm", "entries",
                "entry_radial_engagement_max_mm", "entry_axial_engagement_max_mm",
                "material_removal_rate_max_mm3_per_min"):
        figures[key] = tool[key]
    feed_min = float(timing.nominal_time[~timing.rapid].sum()) / 60.0
    figures["mean_removal_rate_cm3_per_min"] = figures["removed_volume_cm3"] / feed_min
    # the width a cut of the mean depth along the cutting length would need for the removed
    # volume: a bulk measure, unlike the radial maximum free of zigzag line-end corners
    figures["effective_width_mm"] = tool["removed_volume_mm3"] / (
        tool["cutting_length_mm"] * tool["axial_engagement_mean_mm"])
    try:
        from BSplineCAM.orchestration import report

        report.plot_stock(result, number, picture)
        figures["picture"] = str(picture)
    except ImportError as exc:  # no matplotlib in this interpreter
        figures["picture"] = f"not drawn: {exc}"
    return figures


def run(args: argparse.Namespace) -> dict:
    surface = Surface.from_json(CASE_STUDY)
    Path(args.out).mkdir(parents=True, exist_ok=True)
    # one FreeCAD at a time: the children run one after the other
    results = {name: op_in_child(name, args) for name in OPS}
    stock = next((tuple(r["stock_mm"]) for r in results.values() if "stock_mm" in r), None)
    if stock is None:
        raise SystemExit("no op produced a program: " + json.dumps(results, indent=1))
    for name in OPS:
        if "program" in results[name]:
            text = Path(results[name]["program"]).read_text()
            picture = Path(args.out) / f"{name}-stock.png"
            results[name].update(measure(surface, text, stock, args, picture))
    ratios = {}
    for ours in OURS:
        for name in PEERS:
            if "machining_time_min" in results[name] and "machining_time_min" in results[ours]:
                ratios[f"{name}/{ours}"] = {
                    key: results[name][key] / results[ours][key]
                    for key in ("machining_time_min", "machining_time_accel_min", "seconds")}
    return {
        "surface": CASE_STUDY.name,
        "freecad": ".".join(map(str, compat.freecad_version())),
        "tool": {"shape": "flat", "diameter_mm": args.diameter},
        "stepdown_mm": args.stepdown,
        "deep_stepdown_mm": args.deep_stepdown,
        "fine_stepdown_mm": FINE,
        "ramp_angle_deg": RAMP,
        "stepover_percent_of_variant": STEPOVER,
        "stepover_percent": args.stepover,
        "allowance_mm": args.allowance,
        "stock_mm": list(stock),
        "cell_mm": args.cell,
        "timeout_s": args.timeout,
        "ratios_peer_over_ours": ratios,
        **results,
    }


def table(figures: dict) -> str:
    lines = [
        f"case study, flat {figures['tool']['diameter_mm']:g} mm, step-down "
        f"{figures['stepdown_mm']:g} mm, stepover {figures['stepover_percent']} %, "
        f"allowance {figures['allowance_mm']:g} mm, FreeCAD {figures['freecad']}",
        f"{'':28}" + "".join(f"{TITLES[n]:>19}" for n in OPS),
    ]
    for label, key, fmt in ROWS:
        cells = []
        for name in OPS:
            value = figures[name].get(key)
            cells.append("-" if value is None else fmt.format(value))
        lines.append(f"{label:28}" + "".join(f"{c:>19}" for c in cells))
    for name in OPS:
        if "failed" in figures[name]:
            lines.append(f"{TITLES[name]}: FAILED: {figures[name]['failed']}")
    for key, r in figures["ratios_peer_over_ours"].items():
        peer, ours = key.split("/")
        lines.append(f"{TITLES[peer]} / {TITLES[ours]}: machining time "
                     f"{r['machining_time_min']:.2f}x (with acceleration "
                     f"{r['machining_time_accel_min']:.2f}x), compute {r['seconds']:.2f}x")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--diameter", type=float, default=10.0, help="flat end mill (mm)")
    parser.add_argument("--stepdown", type=float, default=2.0, help="step-down (mm)")
    parser.add_argument("--deep-stepdown", type=float, default=8.0,
                        help="step-down of our fine variants (mm)")
    parser.add_argument("--stepover", type=int, default=40, help="stepover (%% of diameter)")
    parser.add_argument("--allowance", type=float, default=0.3, help="stock to leave (mm)")
    parser.add_argument("--margin", type=float, default=2.0, help="stock block margin (mm)")
    parser.add_argument("--cell", type=float, default=0.1, help="simulation cell (mm)")
    parser.add_argument("--timeout", type=float, default=900.0,
                        help="seconds each op may take (each computed in a child freecadcmd)")
    parser.add_argument("--freecadcmd", default="freecadcmd", help="FreeCAD's interpreter")
    parser.add_argument("--out", default=str(OUT), help="folder for programs and pictures")
    parser.add_argument("--json", default=str(OUT / "roughing.json"), help="figures (JSON)")
    parser.add_argument("--op", choices=OPS, help=argparse.SUPPRESS)  # child mode
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.op:
        run_op(args.op, args, Path(args.out) / f"{args.op}.result.json")
        return
    figures = run(args)
    print(table(figures))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(figures, indent=1, sort_keys=True, default=str) + "\n")


if __name__ == "__main__":
    main()
