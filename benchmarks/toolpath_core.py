# SPDX-License-Identifier: LGPL-2.1-or-later
"""Time the finishing strategies on the case study (6 mm ball, 0.01 mm scallop by default).

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
from BSplineCAM.core.toolpath import generate  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--diameter", type=float, default=6.0)
    parser.add_argument("--scallop", type=float, default=0.01)
    parser.add_argument("--tolerance", type=float, default=0.002)
    parser.add_argument("--strategies", default="raster,waterline,isoparametric")
    args = parser.parse_args()
    surface = Surface.from_json(ROOT / "examples" / "case-study.json")
    results = {}
    for strategy in args.strategies.split(","):
        start = time.perf_counter()
        tp = generate(surface, strategy, args.diameter, args.scallop, args.tolerance)
        results[strategy] = {
            "seconds": round(time.perf_counter() - start, 3), "passes": tp.stats.passes,
            "moves": tp.stats.moves, "cutting_length_mm": round(tp.stats.cutting_length_mm, 1),
            "unreachable_regions": len(tp.unreachable),
        }
    print(json.dumps(results, indent=1))


if __name__ == "__main__":
    main()
