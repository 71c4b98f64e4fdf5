# SPDX-License-Identifier: LGPL-2.1-or-later
"""Machine time of the faces' raster with and without partial passes and of the
constant-scallop passes, on a STEP part.

The part's faces are read with cadquery's OCCT (``BSplineCAM.ocp``, no FreeCAD), the faces
reached from above selected, as ``bsplinecam toolpath PART.step`` does.  For each angle the
raster (:func:`BSplineCAM.core.toolpath.faces_raster.raster_faces`) is computed with
``partial=False`` (every pass over the whole extent, spaced by its band's least allowance)
and ``partial=True`` (main passes and partial ones), then the constant-scallop passes
(:func:`BSplineCAM.core.toolpath.faces_scallop.scallop_faces`, unless ``--no-scallop``); each
program (lines, feed --feed,
plunges at --plunge-feed, the core's moves) is measured from its G-code text: cutting and air
length, machining time with acceleration (:mod:`BSplineCAM.core.simulation.machining_time`,
the default machine), and simulated against the exact faces (:func:`BSplineCAM.core.
simulation.verify.verify_faces`): gouge, largest and mean scallop, evenness, coverage.

    .venv/bin/python benchmarks/machining_time.py [--part examples/part.step] [--angles 0,90]
        [--diameter 6] [--scallop 0.05] [--tolerance 0.002] [--cell 0.1]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.measures import program_measures, toolpath_lengths  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify_faces  # noqa: E402
from BSplineCAM.core.toolpath import to_moves  # noqa: E402
from BSplineCAM.core.toolpath.common import ToolParameters  # noqa: E402
from BSplineCAM.core.toolpath.faces_raster import raster_faces  # noqa: E402
from BSplineCAM.core.toolpath.faces_scallop import scallop_faces  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402


def gcode(toolpath, feed: float, plunge: float, hops=None) -> str:
    """The program of the core's moves (with ``hops``, :mod:`.retracts`' minimum retracts):
    rapids G0, vertical feeds at ``plunge``, others at ``feed`` (mm/min)."""
    lines = ["G21 G90 G17"]
    last = None
    for m in to_moves(toolpath, hops=hops):
        if m.kind == "rapid":
            lines.append(f"G0 X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}")
        else:
            vertical = last is not None and abs(m.x - last[0]) < 1e-9 and abs(m.y - last[1]) < 1e-9
            lines.append(f"G1 X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f} F{plunge if vertical else feed:g}")
        last = (m.x, m.y, m.z)
    lines.append("M2")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", default=str(ROOT / "examples" / "part.step"))
    parser.add_argument("--faces", default="up")
    parser.add_argument("--angles", default="0,90")
    parser.add_argument("--diameter", type=float, default=6.0)
    parser.add_argument("--scallop", type=float, default=0.05)
    parser.add_argument("--tolerance", type=float, default=0.002)
    parser.add_argument("--cell", type=float, default=0.1)
    parser.add_argument("--feed", type=float, default=1200.0)
    parser.add_argument("--plunge-feed", type=float, default=400.0)
    parser.add_argument("--no-scallop", action="store_true")
    args = parser.parse_args()
    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(args.part), args.faces)
    tool = ToolParameters.validate(args.diameter, args.scallop, args.tolerance)
    print(f"{args.part}: {len(faces)} faces ({sum(f.selected for f in faces)} selected), "
          f"ball {args.diameter:g} mm, scallop {args.scallop:g} mm, tolerance "
          f"{args.tolerance:g} mm")
    print("| angle | passes | cutting m | air m | time with acc. s | largest / mean scallop mm "
          "| evenness | mean/max | gouge um | coverage | compute s |")
    runs = [(float(a), partial) for a in args.angles.split(",") if a
            for partial in (False, True)]
    if not args.no_scallop:
        runs.append((None, None))
    for angle, partial in runs:
        faceset = FaceSet(faces)
        started = time.perf_counter()
        if angle is None:
            toolpath = scallop_faces(faceset, tool)
            label = "scallop"
        else:
            toolpath = raster_faces(faceset, tool, angle, partial=partial)
            label = f"{angle:g} {'partial' if partial else 'whole'}"
        seconds = time.perf_counter() - started
        text = gcode(toolpath, args.feed, args.plunge_feed)
        program = read_gcode(text, "program")
        figures = program_measures(program, toolpath_lengths(toolpath)["along_passes_mm"])
        m = verify_faces(faces, program, Tool(args.diameter), cell=args.cell).metrics
        print(f"| {label} | {toolpath.stats.passes} | "
              f"{figures['cutting_length_mm'] / 1000:.2f} | "
              f"{figures['air_length_mm'] / 1000:.2f} | "
              f"{figures['machining_time_with_acceleration_s']:.0f} | "
              f"{m['scallop_max_mm']:.3f} / {m['scallop_mean_mm']:.4f} | "
              f"{m['scallop_evenness']:.2f} | {m['scallop_mean_over_max']:.2f} | "
              f"{1000 * m['gouge_max_mm']:.2f} | {m['coverage']:.4f} | {seconds:.1f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
