# SPDX-License-Identifier: LGPL-2.1-or-later
"""Time the finishing strategies on the case study (6 mm ball, 0.01 mm scallop by default).

Each toolpath's program is also counted with one-sided arcs (issue 14): moves and bytes of
the same plain 4-decimal G-code without and with G2/G3.  With ``--verify`` both programs are
simulated against the design (:func:`BSplineCAM.core.simulation.verify.verify`), reporting the largest
gouge and scallop.

Run with the project venv:  .venv/bin/python benchmarks/toolpath_core.py [--scallop 0.01]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from BSplineCAM.core import Surface  # noqa: E402
from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify  # noqa: E402
from BSplineCAM.core.toolpath import generate, program_moves, to_moves  # noqa: E402
from BSplineCAM.core.toolpath.arcs import counts, plain_gcode  # noqa: E402


def gcode(toolpath, feed: float = 1000.0) -> str:
    """A minimal program: G0 for rapids, G1 with F for feeds, 4 decimals."""
    lines = ["G21 G90"]
    for m in to_moves(toolpath):
        word = "G0" if m.kind == "rapid" else "G1"
        tail = "" if m.kind == "rapid" else f" F{feed:g}"
        lines.append(f"{word} X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}{tail}")
    lines.append("M2")
    return "\n".join(lines) + "\n"


def arc_fitting(surface, tp) -> dict:
    """Program moves and G-code bytes (same 4-decimal writer) without and with arcs."""
    start = time.perf_counter()
    fitted = program_moves(tp, arcs=True, surface=surface)
    seconds = time.perf_counter() - start
    lines = to_moves(tp)
    c = counts(fitted)
    return {"program_moves_lines": len(lines), "program_moves_arcs": c["moves"],
            "arcs": c["arcs"], "bytes_lines": len(plain_gcode(lines)),
            "bytes_arcs": len(plain_gcode(fitted)), "arc_fit_seconds": round(seconds, 3)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--diameter", type=float, default=6.0)
    parser.add_argument("--scallop", type=float, default=0.01)
    parser.add_argument("--tolerance", type=float, default=0.002)
    parser.add_argument("--strategies", default="raster,waterline,isoparametric")
    parser.add_argument("--angle", type=float, default=0.0, help="raster angle (degrees)")
    parser.add_argument("--verify", action="store_true", help="simulate and measure (slow)")
    args = parser.parse_args()
    surface = Surface.from_json(ROOT / "examples" / "case-study.json")
    results = {}
    for strategy in args.strategies.split(","):
        start = time.perf_counter()
        tp = generate(surface, strategy, args.diameter, args.scallop, args.tolerance,
                      angle=args.angle)
        results[strategy] = {
            "seconds": round(time.perf_counter() - start, 3), "passes": tp.stats.passes,
            "moves": tp.stats.moves, "cutting_length_mm": round(tp.stats.cutting_length_mm, 1),
            "unreachable_regions": len(tp.unreachable),
        }
        results[strategy].update(arc_fitting(surface, tp))
        if args.verify:
            m = verify(surface, read_gcode(gcode(tp)), Tool(args.diameter), cell=0.1).metrics
            results[strategy].update(gouge_max_mm=m["gouge_max_mm"],
                                     scallop_max_mm=m["scallop_max_mm"])
            arcs = plain_gcode(program_moves(tp, arcs=True, surface=surface))
            m = verify(surface, read_gcode(arcs), Tool(args.diameter), cell=0.1).metrics
            results[strategy].update(arcs_gouge_max_mm=m["gouge_max_mm"],
                                     arcs_scallop_max_mm=m["scallop_max_mm"])
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
