# SPDX-License-Identifier: LGPL-2.1-or-later
"""Simulate 100 000 moves on a 100 x 100 mm part at 0.1 mm cells (1000 x 1000 Z-map).

The program is a zig-zag ball-end finishing raster over a wavy surface: 100 passes 1 mm apart,
1000 moves of 0.1 mm each, as a surface-finishing post writes it.  Reports the G-code reading
time and the simulation time (best of --repeat) with moves per second.
Run with either interpreter:  .venv/bin/python benchmarks/simulate.py   (or /usr/bin/python3)
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from BSplineCAM.core.program.gcode import linearise, read_gcode  # noqa: E402
from BSplineCAM.core.simulation import simulate as sim  # noqa: E402


def raster_gcode(passes: int, per_pass: int) -> str:
    """Zig-zag over z = 20 + 5 sin(x/15) cos(y/20) on [0, 100]^2 (mm)."""
    lines = ["%", "G17 G21 G90 G54 G40 G49 G80", "T1 M6", "S12000 M3", "G0 X0 Y0 Z40"]
    x = np.linspace(0.0, 100.0, per_pass + 1)
    for i, y in enumerate(np.linspace(0.0, 100.0, passes)):
        xs = x if i % 2 == 0 else x[::-1]
        z = 20.0 + 5.0 * np.sin(xs / 15.0) * np.cos(y / 20.0)
        body = [f"G1 X{a:.4f} Y{y:.4f} Z{b:.4f}" for a, b in zip(xs, z)]
        body[0] += " F2000"
        lines += body
    lines += ["G0 Z40", "M5", "M2", "%"]
    return "\n".join(lines) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--passes", type=int, default=100)
    parser.add_argument("--per-pass", type=int, default=1000)
    parser.add_argument("--tool", type=float, default=6.0, help="ball diameter (mm)")
    parser.add_argument("--shape", default="ball", choices=[s.value for s in sim.ToolShape])
    parser.add_argument("--corner-radius", type=float, default=0.0)
    parser.add_argument("--cell", type=float, default=0.1)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--threads", type=int, default=sim.THREADS)
    args = parser.parse_args()
    sim.THREADS = args.threads

    text = raster_gcode(args.passes, args.per_pass)
    start = time.perf_counter()
    program = read_gcode(text)
    read_s = time.perf_counter() - start
    segments = linearise(program, args.cell / 10)
    tool = sim.Tool(args.tool, args.shape, args.corner_radius)
    grid = sim.Grid.covering(0.0, 100.0, 0.0, 100.0, args.cell)
    times = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        result = sim.simulate(segments, tool, grid, 40.0)
        times.append(time.perf_counter() - start)
    best = min(times)
    print(json.dumps({
        "moves": len(program), "grid": [grid.ny, grid.nx], "cell_mm": grid.cell,
        "tool": f"{tool.shape.value} {tool.diameter:g} mm", "threads": sim.THREADS,
        "read_gcode_s": round(read_s, 3), "simulate_s": round(best, 3),
        "simulate_moves_per_s": round(len(program) / best),
        "removed_volume_mm3": round(result.removed_volume(), 1),
        "python": platform.python_version(), "numpy": np.__version__,
    }, indent=1))


if __name__ == "__main__":
    main()
