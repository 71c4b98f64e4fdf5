# SPDX-License-Identifier: LGPL-2.1-or-later
"""Verification at die size: a 64 x 64 net over 300 x 300 mm, 10 mm ball, 5 um scallop.

Computes the raster finishing toolpath with the core, writes it as plain G-code, then times
reading it and :func:`BSplineCAM.core.simulation.verify.verify` on 0.1 mm cells (9 million) (wall and
CPU seconds, and the load average: other work on the machine slows the wall time), and prints
the peak resident memory of the process.  Target (issue 14): verification in <= 20 s and
<= 1 GB on a 2-core machine.
Run:  .venv/bin/python benchmarks/verify_die.py [--profile]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from toolpath_core import gcode  # noqa: E402

from BSplineCAM.core import Surface  # noqa: E402
from BSplineCAM.core.geometry.netio import ControlNet, KnotLayout, write_json  # noqa: E402
from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify  # noqa: E402
from BSplineCAM.core.toolpath import generate  # noqa: E402


def die_net(n: int = 64, size: float = 300.0) -> np.ndarray:
    """A die-like height field: two bosses, a hollow and a gentle draft over size x size mm
    (drawn at 300 mm; another size scales every length, heights included), as an n x n net."""
    s = size / 300.0
    x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n), indexing="ij")
    u, v = x / s, y / s  # the 300 mm die's coordinates
    z = s * (40.0 + 0.03 * u
             + 25.0 * np.exp(-((u - 90) ** 2 + (v - 100) ** 2) / 2500.0)
             + 15.0 * np.exp(-((u - 210) ** 2 + (v - 220) ** 2) / 1800.0)
             - 18.0 * np.exp(-((u - 200) ** 2 + (v - 80) ** 2) / 3000.0))
    return np.stack([x, y, z], axis=-1)


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--profile", action="store_true", help="print the verify profile")
    parser.add_argument("--cell", type=float, default=0.1)
    parser.add_argument("--write", metavar="DIR",
                        help="also write the net (die.json) and the program (die.ngc) there, "
                        "for timing the CLI: bin/bsplinecam verify DIR/die.json DIR/die.ngc "
                        "--tool-diameter 10 --out OUT")
    args = parser.parse_args()
    surface = Surface(die_net(), knots="clamped", name="die")
    t0 = time.perf_counter()
    tp = generate(surface, "raster", 10.0, 0.005, 0.002)
    t_path = time.perf_counter() - t0
    text = gcode(tp)
    if args.write:
        folder = Path(args.write)
        folder.mkdir(parents=True, exist_ok=True)
        write_json(ControlNet(die_net(), KnotLayout.CLAMPED, "die"), folder / "die.json")
        (folder / "die.ngc").write_text(text)
    mem_before = peak_mb()
    t0 = time.perf_counter()
    program = read_gcode(text)
    t_read = time.perf_counter() - t0
    profiler = cProfile.Profile() if args.profile else None
    t0 = time.perf_counter()
    c0 = time.process_time()
    if profiler:
        profiler.enable()
    result = verify(surface, program, Tool(10.0), cell=args.cell)
    if profiler:
        profiler.disable()
    t_verify = time.perf_counter() - t0
    cpu_verify = time.process_time() - c0
    m = result.metrics
    print(json.dumps({
        "toolpath_s": round(t_path, 2), "moves": len(program), "program_bytes": len(text),
        "read_s": round(t_read, 2), "verify_s": round(t_verify, 2),
        # CPU seconds of all threads: on a machine shared with other work the wall time
        # grows, this does not; with both cores free the wall time is about cpu / 1.6
        "verify_cpu_s": round(cpu_verify, 2), "load_average": os.getloadavg()[0],
        "cells": m["grid_cells"], "peak_rss_mb_before_verify": round(mem_before),
        "peak_rss_mb": round(peak_mb()),
        "gouge_max_mm": m["gouge_max_mm"], "scallop_max_mm": m["scallop_max_mm"],
        "coverage": m["coverage"],
    }, indent=1))
    if profiler:
        pstats.Stats(profiler).sort_stats("cumulative").print_stats(18)


if __name__ == "__main__":
    main()
