# SPDX-License-Identifier: LGPL-2.1-or-later
"""Scale: does the cost per cutter location stay flat as the job grows?

The die of ``benchmarks/verify_die.py`` (a 64 x 64 net over 300 x 300 mm: two bosses, a
hollow, a gentle draft) and the same shape twice as large, a 128 x 128 net over 600 x 600 mm
(every length doubled: the same slopes, half the curvature), finished with a 10 mm ball at a
5 um scallop (options).  Each size runs in a process of its own, so its peak resident memory is
its own: the raster toolpath (core), its program as plain G-code, then ``verify`` on cells of
0.1 mm on the first size, scaled with the part on the others (0.2 mm at 600 mm: the same
3000 x 3000 cells; 0.1 mm there would be 36 million, past the Z-map's bound of 16 million
that ``verify`` refuses).  Printed per size: cutter locations, moves, cells, wall and CPU seconds and peak
memory of each stage, and per cutter location (toolpath) and per move and cell (verify); the
last column is each figure's ratio from the smallest size to the largest (issue 43's target:
within 1.5x).  Other work on the machine slows the wall times (the load average is printed);
CPU seconds less so.

Run:  .venv/bin/python benchmarks/scale.py [--sizes 64:300,128:600] [--scallop 0.005]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from toolpath_core import gcode  # noqa: E402
from verify_die import die_net  # noqa: E402

from BSplineCAM.core import Surface, kernels  # noqa: E402
from BSplineCAM.core.kernels.warm import warm_up  # noqa: E402
from BSplineCAM.core.program.gcode import read_gcode  # noqa: E402
from BSplineCAM.core.simulation.simulate import Tool  # noqa: E402
from BSplineCAM.core.simulation.verify import verify  # noqa: E402
from BSplineCAM.core.toolpath import generate  # noqa: E402


def peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def one_size(n: int, size: float, diameter: float, scallop: float, tolerance: float,
             cell: float) -> dict:
    """The figures of one size, in this process."""
    warm_up()  # compiled kernels loaded (or compiled) before the clocks start
    surface = Surface(die_net(n, size), knots="clamped", name=f"die{n}")
    base = peak_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    tp = generate(surface, "raster", diameter, scallop, tolerance)
    out = {"net": n, "size_mm": size, "toolpath_s": time.perf_counter() - t0,
           "toolpath_cpu_s": time.process_time() - c0,
           "cutter_locations": int(sum(len(p) for p in tp.passes)),
           "passes": len(tp.passes), "peak_mb_toolpath": peak_mb(), "peak_mb_start": base}
    text = gcode(tp)
    del tp
    program = read_gcode(text)
    del text
    out["moves"] = len(program)
    out["cell_mm"] = cell
    t0, c0 = time.perf_counter(), time.process_time()
    result = verify(surface, program, Tool(diameter), cell=cell)
    m = result.metrics
    out.update({"verify_s": time.perf_counter() - t0, "verify_cpu_s": time.process_time() - c0,
                "cells": int(np.prod(m["grid_cells"])), "peak_mb": peak_mb(),
                "gouge_max_mm": m["gouge_max_mm"], "scallop_max_mm": m["scallop_max_mm"],
                "coverage": m["coverage"], "load_average": os.getloadavg()[0],
                "engine": kernels.engine().name})
    return out


def per_unit(r: dict) -> dict:
    """The figures that should stay flat: microseconds and kilobytes per unit of work."""
    cl, moves, cells = r["cutter_locations"], r["moves"], r["cells"]
    return {
        "toolpath us / CL": 1e6 * r["toolpath_s"] / cl,
        "toolpath CPU us / CL": 1e6 * r["toolpath_cpu_s"] / cl,
        "toolpath kB / CL": 1024.0 * (r["peak_mb_toolpath"] - r["peak_mb_start"]) / cl,
        "verify us / move": 1e6 * r["verify_s"] / moves,
        "verify CPU ns / cell": 1e9 * r["verify_cpu_s"] / cells,
        "peak B / cell": 1024.0 * 1024.0 * r["peak_mb"] / cells,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="64:300,128:600",
                        help="NET:SIZE_MM pairs, comma-separated (default 64:300,128:600)")
    parser.add_argument("--diameter", type=float, default=10.0)
    parser.add_argument("--scallop", type=float, default=0.005)
    parser.add_argument("--tolerance", type=float, default=0.002)
    parser.add_argument("--cell", type=float, default=0.1,
                        help="verify's cell on the first size (mm), scaled with the others")
    parser.add_argument("--one", help=argparse.SUPPRESS)  # NET:SIZE run in this process
    args = parser.parse_args()
    if args.one:
        n, size = args.one.split(":")
        print(json.dumps(one_size(int(n), float(size), args.diameter, args.scallop,
                                  args.tolerance, args.cell)))
        return 0
    rows = []
    pairs = args.sizes.split(",")
    first = float(pairs[0].split(":")[1])
    for pair in pairs:
        cell = args.cell * float(pair.split(":")[1]) / first
        cmd = [sys.executable, __file__, "--one", pair, "--diameter", str(args.diameter),
               "--scallop", str(args.scallop), "--tolerance", str(args.tolerance),
               "--cell", str(cell)]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode:
            print(f"size {pair}: exit {done.returncode}\n{done.stderr[-3000:]}", file=sys.stderr)
            return 1
        rows.append(json.loads(done.stdout.strip().splitlines()[-1]))
        print(json.dumps(rows[-1]), flush=True)
    units = [per_unit(r) for r in rows]
    head = " | ".join(f"{r['net']}x{r['net']}, {r['size_mm']:g} mm" for r in rows)
    print(f"\n| figure | {head} | last / first |")
    print("|---|" + "---|" * (len(rows) + 1))
    for key in ("cutter_locations", "moves", "cells", "toolpath_s", "toolpath_cpu_s",
                "peak_mb_toolpath", "verify_s", "verify_cpu_s", "peak_mb"):
        vals = [r[key] for r in rows]
        print(f"| {key} | " + " | ".join(f"{v:.4g}" for v in vals)
              + f" | {vals[-1] / vals[0]:.2f} |")
    for key in units[0]:
        vals = [u[key] for u in units]
        print(f"| {key} | " + " | ".join(f"{v:.4g}" for v in vals)
              + f" | {vals[-1] / vals[0]:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
