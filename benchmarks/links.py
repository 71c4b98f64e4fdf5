# SPDX-License-Identifier: LGPL-2.1-or-later
"""Links between passes: waterline contours level by level with a full retract between any
two, against the same contours as the strategy cuts them (climb, in the order of short moves,
stay-down links, minimum retracts over the model).

On examples/part.step's faces seen from above (the certified drop-cutter over all faces) and
on the case-study net, 6 mm ball, waterline at ``--scallop`` (0.2 mm): each program's core
moves as G-code (feed 1200 mm/min, plunges 400, rapids 5000), measured on its text: air length
and the time with acceleration on the default machine
(:func:`BSplineCAM.core.simulation.measures.program_measures`).

Run:  .venv/bin/python benchmarks/links.py [--scallop 0.2] [--tolerance 0.002]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from machining_time import gcode  # noqa: E402

from BSplineCAM.core import Surface  # noqa: E402
from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.measures import program_measures, toolpath_lengths  # noqa: E402
from BSplineCAM.core.toolpath import generate, generate_faces  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402
from BSplineCAM.core.toolpath.retracts import faces_hops, surface_hops  # noqa: E402


def level_by_level(toolpath):
    """The toolpath's contours sorted top level first (stable), no link, no hop."""
    passes = sorted(toolpath.passes, key=lambda p: -float(p[0, 2]))
    return type(toolpath)(toolpath.strategy, passes, toolpath.parameters, [], toolpath.stats,
                          toolpath.clearance_height, links=[None] * (len(passes) - 1))


def figures(toolpath, hops=None) -> dict:
    program = read_gcode(gcode(toolpath, 1200.0, 400.0, hops=hops), "links")
    return program_measures(program, toolpath_lengths(toolpath)["along_passes_mm"])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scallop", type=float, default=0.2)
    parser.add_argument("--tolerance", type=float, default=0.002)
    args = parser.parse_args()
    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(str(ROOT / "examples" / "part.step")), "up")
    faceset = FaceSet(faces)
    part = generate_faces(faceset, "waterline", 6.0, args.scallop, args.tolerance)
    net = Surface.from_file(str(ROOT / "examples" / "case-study.json"))
    study = generate(net, "waterline", 6.0, args.scallop, args.tolerance)
    rows = [("examples/part.step", part, faces_hops(part, faceset, part.clearance_height)),
            ("case study (net)", study, surface_hops(study, net, study.clearance_height))]
    print("| program | contours | air: level by level, full retracts / ordered, linked, hops "
          "| time with acceleration: the same two |")
    print("|---|---|---|---|")
    for name, tp, hops in rows:
        a, b = figures(level_by_level(tp)), figures(tp, hops)
        print(f"| {name}, waterline, {args.scallop:g} mm | {len(tp.passes)} | "
              f"{a['air_length_mm'] / 1000:.2f} m / {b['air_length_mm'] / 1000:.2f} m | "
              f"{a['machining_time_with_acceleration_s']:.0f} s / "
              f"{b['machining_time_with_acceleration_s']:.0f} s |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
