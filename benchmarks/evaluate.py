# SPDX-License-Identifier: LGPL-2.1-or-later
"""Evaluate a 1000 x 1000 grid (points and normals) on a 16 x 16 net; ratios against peers.

Peers, timed in this same process on the same net and parameters: SciPy's FITPACK
(``bisplev``, points and first derivatives), geomdl (pure Python NURBS), and OCCT's per-point
evaluation through cadquery's OCP (``Geom_BSplineSurface::D0``/``D1`` on a subset, scaled).
Also the cost of unit normals against points alone, for each evaluator: "points+normals /
points" is the time of the points plus that of the unit normals over the time of the points
(ours timed in turns with the points, so a slow spell of the machine hits both alike).
Set OPENBLAS_NUM_THREADS=1 and BSPLINECAM_GRID_THREADS=1 for single-core figures (our grid
products are shared among our own threads: ``matrix.GRID_THREADS``, by default
BSPLINECAM_THREADS capped at 2).
Run with the project venv:  .venv/bin/python benchmarks/evaluate.py
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.core.geometry import matrix  # noqa: E402
from BSplineCAM.core.threads import numpy_threads  # noqa: E402


def best_of(fn, repeat: int) -> float:
    """Best wall time of ``repeat`` runs (s): the least disturbed by the machine's other work."""
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def best_interleaved(fns: dict, repeat: int) -> dict:
    """Best wall time (s) of each function, run in turns so that a slow spell of a shared
    machine hits every contender alike."""
    times = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            start = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - start)
    return {name: min(values) for name, values in times.items()}


def make_net(size: int = 16) -> np.ndarray:
    x, y = np.meshgrid(np.linspace(0, 150, size), np.linspace(0, 150, size), indexing="ij")
    z = 12 * np.sin(x / 25) * np.cos(y / 30) + 0.05 * x
    return np.stack([x, y, z], axis=-1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="grid samples per direction")
    parser.add_argument("--repeat", type=int, default=25)
    parser.add_argument("--occt-points", type=int, default=20000, help="points timed per-point in OCCT")
    parser.add_argument("--geomdl-points", type=int, default=5000, help="points timed in geomdl")
    parser.add_argument("--json", help="also write the figures to this file")
    args = parser.parse_args()

    if os.environ.get("BSPLINECAM_GRID_THREADS"):
        matrix.GRID_THREADS = max(1, int(os.environ["BSPLINECAM_GRID_THREADS"]))
    net = make_net()
    surface = Surface(net, "uniform", "bench")
    t = np.linspace(0.0, 1.0, args.n)
    total = args.n * args.n
    figures: dict[str, float] = {}

    from scipy.interpolate import bisplev

    ku, kw = surface.knot_vectors()
    tcks = [(ku, kw, net[:, :, c].ravel(), 3, 3) for c in range(3)]

    def fitpack_points():
        return [bisplev(t, t, tck) for tck in tcks]

    def fitpack_normals():
        su = np.stack([bisplev(t, t, tck, dx=1) for tck in tcks], -1)
        sw = np.stack([bisplev(t, t, tck, dy=1) for tck in tcks], -1)
        n = np.cross(su, sw)
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    check = np.stack(fitpack_points(), -1)
    figures["max_diff_vs_fitpack_mm"] = float(np.abs(check - surface.evaluate_grid(t, t)).max())
    figures["max_normal_diff_vs_fitpack"] = float(
        np.abs(fitpack_normals() - surface.normals(t, t, grid=True)).max())
    best = best_interleaved({
        "ours_points": lambda: surface.evaluate_grid(t, t),
        "ours_normals": lambda: surface.normals(t, t, grid=True),
        "fitpack_points": fitpack_points,
    }, args.repeat)
    normals = best_interleaved({"fitpack_normals": fitpack_normals}, max(2, args.repeat // 3))
    ours_points = best["ours_points"]
    figures["ours_points_s"] = ours_points
    figures["ours_points_and_normals_s"] = ours_points + best["ours_normals"]
    figures["ours_normals_over_points"] = figures["ours_points_and_normals_s"] / ours_points
    figures["ours_normals_s"] = best["ours_normals"]
    figures["ours_normals_alone_over_points"] = best["ours_normals"] / ours_points
    figures["fitpack_points_s"] = best["fitpack_points"]
    figures["fitpack_points_and_normals_s"] = best["fitpack_points"] + normals["fitpack_normals"]
    figures["fitpack_normals_over_points"] = (figures["fitpack_points_and_normals_s"]
                                              / best["fitpack_points"])

    try:
        from geomdl import BSpline as GeomdlBSpline

        gs = GeomdlBSpline.Surface(normalize_kv=False)
        gs.degree_u = gs.degree_v = 3
        gs.ctrlpts_size_u, gs.ctrlpts_size_v = net.shape[:2]
        gs.ctrlpts = net.reshape(-1, 3).tolist()
        gs.knotvector_u, gs.knotvector_v = ku.tolist(), kw.tolist()
        rng = np.random.default_rng(0)
        params = rng.uniform(0, 1, size=(args.geomdl_points, 2)).tolist()
        seconds = best_of(lambda: gs.evaluate_list(params), 1)
        figures["geomdl_points_s"] = seconds * total / args.geomdl_points
        from geomdl import operations

        few = params[: max(1, args.geomdl_points // 5)]
        seconds = best_of(lambda: operations.normal(gs, few), 1)  # point and unit normal
        figures["geomdl_points_and_normals_s"] = seconds * total / len(few)
        figures["geomdl_normals_over_points"] = (figures["geomdl_points_and_normals_s"]
                                                 / figures["geomdl_points_s"])
        ref = np.array(gs.evaluate_list(params[:200]))
        figures["max_diff_vs_geomdl_mm"] = float(np.abs(ref - surface.evaluate(*np.array(params[:200]).T)).max())
    except ImportError:
        figures["geomdl_points_s"] = float("nan")

    try:
        from OCP.gp import gp_Pnt, gp_Vec

        from BSplineCAM.ocp.occ import to_geom

        geom = to_geom(surface)
        rng = np.random.default_rng(1)
        uv = rng.uniform(0, 1, size=(args.occt_points, 2))

        def occt_points():
            for a, b in uv:
                geom.Value(a, b)

        def occt_d1():
            p, du, dv = gp_Pnt(), gp_Vec(), gp_Vec()
            for a, b in uv:
                geom.D1(a, b, p, du, dv)
                du.Crossed(dv).Normalized()

        figures["occt_points_s"] = best_of(occt_points, 2) * total / len(uv)
        figures["occt_points_and_normals_s"] = best_of(occt_d1, 2) * total / len(uv)
        figures["occt_normals_over_points"] = (figures["occt_points_and_normals_s"]
                                               / figures["occt_points_s"])
    except ImportError:
        figures["occt_points_s"] = float("nan")

    ratios = {
        "fitpack_points": figures["fitpack_points_s"] / ours_points,
        "fitpack_points_and_normals": figures["fitpack_points_and_normals_s"] / figures["ours_points_and_normals_s"],
        "geomdl_points": figures["geomdl_points_s"] / ours_points,
        "occt_per_point_points": figures["occt_points_s"] / ours_points,
        "occt_per_point_points_and_normals": figures.get("occt_points_and_normals_s", float("nan")) / figures["ours_points_and_normals_s"],
    }
    print(f"grid {args.n} x {args.n} on a 16 x 16 net, best of {args.repeat}; numpy {np.__version__}, {platform.python_version()}; "
          f"normals in {matrix.GRID_THREADS or min(2, numpy_threads())} thread(s)")
    print(f"  ours      points {ours_points * 1e3:9.1f} ms   points+normals {figures['ours_points_and_normals_s'] * 1e3:9.1f} ms")
    print(f"  FITPACK   points {figures['fitpack_points_s'] * 1e3:9.1f} ms   points+normals {figures['fitpack_points_and_normals_s'] * 1e3:9.1f} ms")
    print(f"  geomdl    points {figures['geomdl_points_s'] * 1e3:9.1f} ms   (extrapolated from {args.geomdl_points} points)")
    print(f"  OCCT      points {figures['occt_points_s'] * 1e3:9.1f} ms   points+normals {figures.get('occt_points_and_normals_s', float('nan')) * 1e3:9.1f} ms (per point, extrapolated)")
    for key, value in ratios.items():
        print(f"  speed-up vs {key:36s} {value:10.1f}x")
    cost = ", ".join(f"{name} {figures.get(f'{key}_normals_over_points', float('nan')):.1f}x"
                     for name, key in (("ours", "ours"), ("FITPACK", "fitpack"),
                                       ("geomdl", "geomdl"), ("OCCT", "occt")))
    print(f"  points+normals / points: {cost}")
    print(f"  ours: unit normals alone {best['ours_normals'] * 1e3:.1f} ms = "
          f"{figures['ours_normals_alone_over_points']:.2f}x the points (target: at most 3x)")
    print(f"  max |unit normal ours - FITPACK| = {figures['max_normal_diff_vs_fitpack']:.2e}")
    print(f"  max |ours - FITPACK| = {figures['max_diff_vs_fitpack_mm']:.2e} mm, max |ours - geomdl| = {figures.get('max_diff_vs_geomdl_mm', float('nan')):.2e} mm")
    if args.json:
        Path(args.json).write_text(json.dumps({"figures": figures, "ratios": ratios}, indent=1))


if __name__ == "__main__":
    main()
