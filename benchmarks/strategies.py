# SPDX-License-Identifier: LGPL-2.1-or-later
"""Every finishing strategy on every part against FreeCAD's own op for it, at one scallop.

For each part of ``--parts`` and each strategy of ``--strategies`` a fresh document holds the
part, a job (6 mm ball by default) and our finishing op on the faces a 3-axis tool reaches
from above (as ``bsplinecam part`` picks them, :func:`benchmarks.toolpath.part_job`).  Our op
is recomputed twice: *cold* (the op's first recompute: its faces read and prepared; in the
first row of a process also the compiled kernels loaded) and *warm* (the op touched and
recomputed again: faces cached).  Then, in the same job, FreeCAD's op for the strategy on the
same faces is recomputed once (timed):

* raster, isoparametric, steep_shallow: the 3D Surface op (OpenCAMLib drop-cutter, ZigZag
  along X) at the flat stepover 2 sqrt(2Rh - h^2) for the scallop h, set up by
  :func:`BSplineCAM.app.surface3d.add_freecad_surface_op`.  Its program does not depend on our
  strategy, so it runs once per part and its figures serve the three rows;
* waterline: the Waterline op ("OCL Dropcutter", multi-pass) at the step-down that leaves h on
  a vertical wall, set up by :func:`BSplineCAM.app.waterline3d.add_freecad_waterline_op`, the
  job's stock widened to a tool diameter round the model so that its scan reaches round the
  model's outline.  0.20's op ignores the face selection and contours the whole model from the
  stock's top down to the selected faces' lowest point.

Both programs are posted alone with linuxcnc, checked by rs274 and simulated against the
part's exact faces (:func:`benchmarks.machining_parts.measure_program`: gouge over the whole
model, scallop away from the selection's border and in the edge band).  The ratio is FreeCAD's
time over our warm time.

Parts: ``part`` (examples/part.step) and the test parts, made here with FreeCAD's Part module
and written as STEP (:data:`PARTS`): ``boss``, ``dome``, ``box`` (the filleted box of
tests/TestBSplineCAMFaces.py), ``dimples``, ``loft``; any other entry is a part file.

Run inside freecadcmd 0.20 with OpenCAMLib (as benchmarks/toolpath.py):

    freecadcmd -c "import runpy, sys; sys.argv=['x', '--parts', 'part,boss', '--json', 'out.json'];
                   runpy.run_path('benchmarks/strategies.py', run_name='__main__')"
    python3 benchmarks/strategies.py --table out.json

Coverage and scallop are measured on the selected faces away from their border: with the
default selection (faces seen from above, vertical walls left out) waterline leaves the flats
of a part unfinished, so its largest scallop there is the height of a flat above the lowest
level, for both ops.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
for folder in (ROOT, HERE):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import machining_parts  # noqa: E402

#: Strategies compared, and FreeCAD's op for each.
FREECAD_OP = {"raster": "3d_surface", "isoparametric": "3d_surface",
              "steep_shallow": "3d_surface", "waterline": "waterline"}
DEFAULT_PARTS = "part,boss,dome,box,dimples,loft"
#: Keys of a measured program kept in the table's JSON rows.
KEYS = ("seconds", "moves", "rs274", "gouge_max_mm", "scallop_max_mm", "scallop_p99_mm",
        "edge_scallop_max_mm", "coverage", "machining_time_s", "program")


def _v(x: float, y: float, z: float):
    import FreeCAD

    return FreeCAD.Vector(x, y, z)


def boss():
    """An 80 x 60 x 10 mm plate with a round boss (radius 12 mm, 14 mm high) at its centre,
    3 mm fillet round its foot and 4 mm round its top edge."""
    import Part

    plate = Part.makeBox(80, 60, 10)
    solid = plate.fuse(Part.makeCylinder(12, 14, _v(40, 30, 10))).removeSplitter()
    solid = solid.makeFillet(3.0, [e for e in solid.Edges if _circle_at(e, 10.0, 12.0)])
    return solid.makeFillet(4.0, [e for e in solid.Edges if _circle_at(e, 24.0, 12.0)])


def _circle_at(edge, z: float, radius: float) -> bool:
    box = edge.BoundBox
    return (abs(box.ZMin - z) < 1e-6 and abs(box.ZMax - z) < 1e-6
            and abs(box.XLength - 2 * radius) < 1e-6)


def dome():
    """A revolved dome: the profile z = 5 + 25 exp(-r^2 / 300) (a B-spline through 13
    points, 0 <= r <= 35 mm) over a 5 mm base of radius 35 mm, revolved about Z."""
    import Part

    points = [_v(r, 0.0, 5.0 + 25.0 * math.exp(-r * r / 300.0)) for r in
              (35.0 * i / 12.0 for i in range(12, -1, -1))]
    curve = Part.BSplineCurve()
    curve.interpolate(points)
    edges = [Part.LineSegment(_v(0, 0, 0), _v(35, 0, 0)).toShape(),
             Part.LineSegment(_v(35, 0, 0), points[0]).toShape(),
             curve.toShape(),
             Part.LineSegment(points[-1], _v(0, 0, 0)).toShape()]
    face = Part.Face(Part.Wire(edges))
    return Part.Solid(Part.Shell(face.revolve(_v(0, 0, 0), _v(0, 0, 1), 360).Faces))


def box():
    """tests/TestBSplineCAMFaces.py's filleted box: 40 x 30 x 20 mm, its top edges 4 mm."""
    import Part

    solid = Part.makeBox(40, 30, 20)
    top = [e for e in solid.Edges
           if abs(e.BoundBox.ZMin - 20) < 1e-9 and abs(e.BoundBox.ZMax - 20) < 1e-9]
    return solid.makeFillet(4.0, top)


def dimples():
    """A 120 x 40 x 20 mm block with two spherical dimples of radius 15 mm (centres 10 mm
    above the top, as tests/TestBSplineCAMFacesPasses.py's one): the left one plain, the right
    one with its rim filleted 3 mm (as tests/TestBSplineCAMFacesCore.py's)."""
    import Part

    block = Part.makeBox(120, 40, 20)
    solid = block.cut(Part.makeSphere(15, _v(30, 20, 30))).cut(Part.makeSphere(15, _v(90, 20, 30)))
    rim = [e for e in solid.Edges
           if abs(e.BoundBox.ZMax - 20) < 1e-6 and abs(e.BoundBox.ZMin - 20) < 1e-6
           and e.BoundBox.XMin > 60 and e.BoundBox.XLength < 40]
    return solid.makeFillet(3.0, rim)


def loft():
    """A loft through four sections across Y (y = 0, 20, 40, 60 mm), each a 70 mm wide
    profile on z = 0 whose top is a B-spline through five heights: a wavy roof."""
    import Part

    tops = ((12, 18, 14, 20, 15), (16, 22, 25, 19, 13), (14, 26, 20, 24, 18),
            (18, 15, 21, 16, 12))
    wires = []
    for y, heights in zip((0.0, 20.0, 40.0, 60.0), tops):
        points = [_v(70.0 * i / 4, y, z) for i, z in enumerate(heights)]
        curve = Part.BSplineCurve()
        curve.interpolate(points)
        wires.append(Part.Wire([
            Part.LineSegment(_v(0, y, 0), _v(70, y, 0)).toShape(),
            Part.LineSegment(_v(70, y, 0), points[-1]).toShape(),
            curve.toShape().reversed(),
            Part.LineSegment(points[0], _v(0, y, 0)).toShape(),
        ]))
    return Part.makeLoft(wires, True, False)


#: Test parts made here: name -> builder of a Part.Shape.
PARTS = {"boss": boss, "dome": dome, "box": box, "dimples": dimples, "loft": loft}


def part_file(name: str, folder: Path) -> Path:
    """The STEP file of a ``--parts`` entry (a test part is built and written to ``folder``)."""
    if name in PARTS:
        shape = PARTS[name]()
        if not shape.isValid():
            raise RuntimeError(f"{name}: the built shape is not valid")
        path = folder / f"{name}.step"
        shape.exportStep(str(path))
        return path
    return machining_parts.part_file(name, folder)


def add_freecad_op(kind: str, job, faces: list[str], args: argparse.Namespace):
    """FreeCAD's op of ``kind`` ("3d_surface" or "waterline") on ``faces`` of the job."""
    from BSplineCAM.app import surface3d, waterline3d

    if kind == "waterline":
        waterline3d.widen_stock(job, args.diameter)  # contours round the model's outline
        return waterline3d.add_freecad_waterline_op(job, faces, args.scallop, args.diameter,
                                                    tolerance=args.tolerance)
    op = surface3d.add_freecad_surface_op(job, args.scallop, args.diameter,
                                          tolerance=args.tolerance)
    op.Base = [(job.Model.Group[0], faces)]
    return op


def freecad_settings(op) -> dict:
    """The settings of FreeCAD's op that fix its program (mm, %)."""
    out = {"op": op.Proxy.__class__.__name__, "SampleInterval_mm": op.SampleInterval.Value}
    for name in ("StepOver", "CutPattern", "LayerMode", "Algorithm"):
        if hasattr(op, name):
            out[name] = getattr(op, name)
    if op.Proxy.__class__.__name__ == "ObjectWaterline":
        out["StepDown_mm"] = op.StepDown.Value
    out["FinalDepth_mm"] = op.FinalDepth.Value
    return out


def run_row(bench, name: str, part: Path, strategy: str, args, out: Path,
            shared: dict) -> dict:
    """One part and strategy: our op cold and warm, FreeCAD's op (or its figures from
    ``shared``, keyed by FreeCAD op kind, when this part already ran it)."""
    from BSplineCAM.app import pipeline

    FreeCAD = bench.FreeCAD
    params = pipeline.FinishingParameters(tool_diameter=args.diameter, scallop=args.scallop,
                                          tolerance=args.tolerance, strategy=strategy)
    doc = FreeCAD.newDocument("BSplineCAMStrategies")
    row = {"part": name, "strategy": strategy, "freecad_op": FREECAD_OP[strategy]}
    stem = f"{Path(name).stem}-{strategy}"
    try:
        faces, job, ours = bench.part_job(argparse.Namespace(part=str(part), faces=None),
                                          params, doc)
        selected = list(ours.Base[0][1])
        row["faces"] = selected
        print(f"{name} {strategy}: ours cold ...", flush=True)
        cold = bench.timed_recompute(doc, ours)
        report = json.loads(ours.Report or "{}")
        if report.get("error"):
            raise RuntimeError(report["error"])
        ours.touch()
        warm = bench.timed_recompute(doc, ours)
        path = out / f"{stem}-ours.ngc"
        text = bench.post_alone(job, ours, path)
        row["ours"] = {"cold_s": cold, "warm_s": warm,
                       **machining_parts.measure_program(faces, text, path, args)}
        row["ours"]["notes"] = report.get("notes", [])
        print(f"{name} {strategy}: ours {cold:.2f} / {warm:.2f} s, "
              f"gouge {row['ours']['gouge_max_mm']:.4f}, "
              f"scallop {row['ours']['scallop_max_mm']:.4f} mm", flush=True)
        kind = FREECAD_OP[strategy]
        if kind in shared:
            row["freecad"] = {**shared[kind], "shared": True}
        else:
            # our op leaves the job: posting FreeCAD's op alone toggles the others' Active,
            # which would recompute ours with FreeCAD's timed recompute
            doc.removeObject(ours.Name)
            doc.recompute()
            theirs = add_freecad_op(kind, job, selected, args)
            print(f"{name} {strategy}: FreeCAD {kind} ...", flush=True)
            seconds = bench.timed_recompute(doc, theirs)
            path = out / f"{Path(name).stem}-freecad_{kind}.ngc"
            text = bench.post_alone(job, theirs, path)
            shared[kind] = {"seconds": seconds, "settings": freecad_settings(theirs),
                            **machining_parts.measure_program(faces, text, path, args)}
            row["freecad"] = shared[kind]
        row["ratio"] = row["freecad"]["seconds"] / warm
        print(f"{name} {strategy}: FreeCAD {row['freecad']['seconds']:.2f} s, "
              f"ratio {row['ratio']:.1f}x", flush=True)
    except Exception as exc:  # a failing row is a row of the table
        row["error"] = f"{type(exc).__name__}: {exc}"
        print(f"{name} {strategy}: FAILED: {row['error']}", flush=True)
    finally:
        FreeCAD.closeDocument(doc.Name)
    return row


def run(args: argparse.Namespace) -> dict:
    from BSplineCAM.app import compat

    if not compat.opencamlib_available():
        raise SystemExit(f"this benchmark: {compat.opencamlib_missing_message()}")
    bench = machining_parts.load_toolpath_benchmark()
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="bsplinecam-strat-"))
    out.mkdir(parents=True, exist_ok=True)
    started = time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime())
    rows = []
    for name in args.parts:
        part = part_file(name, out)
        shared: dict = {}
        for strategy in args.strategies:
            rows.append(run_row(bench, name, part, strategy, args, out, shared))
            if args.json:  # keep what is measured if a later row takes too long
                write_json(args, started, rows)
    return figures(args, started, rows)


def figures(args: argparse.Namespace, started: str, rows: list) -> dict:
    from BSplineCAM.app import compat

    return {"started": started, "freecad": ".".join(map(str, compat.freecad_version())),
            "source": machining_parts.source_version(), "tool_diameter_mm": args.diameter,
            "scallop_mm": args.scallop, "tolerance_mm": args.tolerance, "cell_mm": args.cell,
            "rows": rows}


def write_json(args: argparse.Namespace, started: str, rows: list) -> None:
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(figures(args, started, rows), indent=1,
                                          sort_keys=True, default=str) + "\n")


def table(result: dict) -> str:
    """The markdown table of ``result`` (:func:`run`)."""
    lines = [
        f"{result['tool_diameter_mm']:g} mm ball, scallop {result['scallop_mm']:g} mm, "
        f"FreeCAD {result['freecad']}, {result['started']}, {result['source']}",
        "",
        "| part | strategy | ours cold / warm (s) | FreeCAD op (s) | ratio | gouge ours / FreeCAD "
        "(mm) | largest scallop ours / FreeCAD (mm) | coverage ours / FreeCAD | rs274 |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for row in result["rows"]:
        if "error" in row and "freecad" not in row:
            lines.append(f"| {row['part']} | {row['strategy']} | {row['error']} ||||||")
            continue
        ours, theirs = row["ours"], row["freecad"]
        op = "3D Surface" if row["freecad_op"] == "3d_surface" else "Waterline"
        lines.append(
            f"| {row['part']} | {row['strategy']} | {ours['cold_s']:.2f} / {ours['warm_s']:.2f} "
            f"| {op} {theirs['seconds']:.2f} | {row['ratio']:.1f}x "
            f"| {ours['gouge_max_mm']:.4f} / {theirs['gouge_max_mm']:.4f} "
            f"| {ours['scallop_max_mm']:.3f} / {theirs['scallop_max_mm']:.3f} "
            f"| {ours['coverage']:.2f} / {theirs['coverage']:.2f} "
            f"| {ours['rs274']} / {theirs['rs274']} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--parts", default=DEFAULT_PARTS,
                        help=f"comma-separated: {', '.join(['part', *PARTS])} or part files")
    parser.add_argument("--strategies", default=",".join(FREECAD_OP),
                        help=f"comma-separated, of {', '.join(FREECAD_OP)}")
    parser.add_argument("--scallop", type=float, default=0.2, help="scallop height (mm)")
    parser.add_argument("--diameter", type=float, default=6.0, help="ball diameter (mm)")
    parser.add_argument("--tolerance", type=float, default=0.002, help="chordal tolerance (mm)")
    parser.add_argument("--cell", type=float, default=0.1, help="simulation cell (mm)")
    parser.add_argument("--out", help="folder for the parts and programs (default: temporary)")
    parser.add_argument("--json", help="write the figures to this JSON file (after each row)")
    parser.add_argument("--table", metavar="JSON", help="print the table of a JSON file written "
                        "by --json and exit (no FreeCAD needed)")
    args = parser.parse_args(sys.argv[1:] if argv is None else argv)
    if args.table:
        print(table(json.loads(Path(args.table).read_text())))
        return
    args.parts = [p.strip() for p in args.parts.split(",") if p.strip()]
    args.strategies = [s.strip() for s in args.strategies.split(",") if s.strip()]
    unknown = [s for s in args.strategies if s not in FREECAD_OP]
    if unknown:
        parser.error(f"--strategies: unknown {', '.join(unknown)}")
    result = run(args)
    print(table(result))
    if args.json:
        write_json(args, result["started"], result["rows"])


if __name__ == "__main__":
    main()
