# SPDX-License-Identifier: LGPL-2.1-or-later
"""The general NURBS evaluator (core.nurbs) against today's cubic Surface and peers, one run.

Case study (examples/case-study.json): a 1000 x 1000 grid (points; points + normals) and 1e6
scattered points (points; point + first and second derivatives; normals), NurbsSurface built
by ``NurbsSurface.from_surface`` against the cubic ``Surface`` (ratio > 1: NurbsSurface is
slower).  Then a rational, non-uniform degree 5 x 4 surface against peers: SciPy's NdBSpline
(non-rational only, so timed on the case study), geomdl (pure Python, extrapolated from a
subset) and OCCT's per-point ``Geom_BSplineSurface::D0`` through cadquery's OCP (extrapolated).
Timings are the best of interleaved runs.  Run with the project venv:
    .venv/bin/python benchmarks/nurbs.py
"""

from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.core.geometry.nurbs import NurbsSurface, expand_knots  # noqa: E402

sys.path.insert(0, str(ROOT / "benchmarks"))
from evaluate import best_interleaved  # noqa: E402


def best_of(fn, repeat: int) -> float:
    return best_interleaved({"f": fn}, repeat)["f"]


def rational_surface() -> dict:
    """A rational degree 5 x 4 surface with non-uniform knots and interior multiplicities."""
    rng = np.random.default_rng(7)
    ku = expand_knots([0.0, 0.1, 0.35, 0.4, 0.7, 0.85, 1.0], [6, 1, 2, 1, 3, 1, 6])
    kv = expand_knots([0.0, 0.2, 0.3, 0.6, 1.0], [5, 2, 1, 4, 5])
    n, m = len(ku) - 6, len(kv) - 5
    x, y = np.meshgrid(np.linspace(0, 100, n), np.linspace(0, 100, m), indexing="ij")
    z = 10 * np.sin(x / 20) * np.cos(y / 25) + rng.normal(scale=0.5, size=x.shape)
    poles = np.stack([x, y, z], axis=-1)
    return dict(poles=poles, knots_u=ku, knots_v=kv, degree_u=5, degree_v=4,
                weights=rng.uniform(0.5, 2.0, (n, m)))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="grid samples per direction")
    parser.add_argument("--points", type=int, default=1_000_000, help="scattered points")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--peer-points", type=int, default=5000,
                        help="points timed in geomdl and OCCT (per point), then extrapolated")
    args = parser.parse_args()

    surface = Surface.from_json(ROOT / "examples" / "case-study.json")
    nurbs = NurbsSurface.from_surface(surface)
    t = np.linspace(0.0, 1.0, args.n)
    rng = np.random.default_rng(0)
    u, w = rng.random(args.points), rng.random(args.points)
    print(f"case study {surface}; numpy {np.__version__}, Python {platform.python_version()}")
    print(f"  {'':34s} {'Surface':>10s} {'Nurbs':>10s} {'ratio':>7s}")
    cases = {
        f"grid {args.n}^2 points": lambda s: s.evaluate_grid(t, t),
        f"grid {args.n}^2 normals": lambda s: s.normals(t, t, grid=True),
        f"scattered {args.points:.0e} points": lambda s: s.evaluate(u, w),
        f"scattered {args.points:.0e} derivatives": lambda s: s.derivatives(u, w),
        f"scattered {args.points:.0e} normals": lambda s: s.normals(u, w),
    }
    grid_points = None
    for label, fn in cases.items():
        best = best_interleaved({"s": lambda fn=fn: fn(surface), "n": lambda fn=fn: fn(nurbs)},
                                args.repeat)
        if grid_points is None:
            grid_points = best["n"]
        print(f"  {label:34s} {best['s'] * 1e3:8.1f}ms {best['n'] * 1e3:8.1f}ms "
              f"{best['n'] / best['s']:7.2f}")
        if "grid" in label and "normals" in label:
            print(f"  {'  (Nurbs normals / Nurbs points)':34s} {'':10s} {'':10s} "
                  f"{best['n'] / grid_points:7.2f}")
    diff = max(float(np.abs(surface.evaluate(u[:10000], w[:10000])
                            - nurbs.evaluate(u[:10000], w[:10000])).max()),
               float(np.abs(surface.evaluate_grid(t, t) - nurbs.evaluate_grid(t, t)).max()))
    print(f"  max |Surface - Nurbs| = {diff:.2e} mm (size {surface.size():.1f} mm)")

    try:
        from scipy.interpolate import NdBSpline

        ku, kv = nurbs.knots_u, nurbs.knots_v
        spline = NdBSpline((ku, kv), np.array(nurbs.poles), (3, 3))
        xi = np.stack([u, w], axis=-1)
        best = best_interleaved({"scipy": lambda: spline(xi), "ours": lambda: nurbs.evaluate(u, w)},
                                args.repeat)
        err = float(np.abs(spline(xi[:10000]) - nurbs.evaluate(u[:10000], w[:10000])).max())
        print(f"  SciPy NdBSpline, {args.points:.0e} scattered points: "
              f"{best['scipy'] * 1e3:.1f} ms, ours {best['ours'] * 1e3:.1f} ms, "
              f"ratio {best['scipy'] / best['ours']:.2f}x (max diff {err:.1e} mm)")
    except ImportError:
        print("  SciPy NdBSpline: not available")

    data = rational_surface()
    general = NurbsSurface(**data)
    (u0, u1), (v0, v1) = general.domain
    gu, gw = np.linspace(u0, u1, args.n), np.linspace(v0, v1, args.n)
    su, sw = rng.uniform(u0, u1, args.points), rng.uniform(v0, v1, args.points)
    print(f"\ngeneral surface {general}, {len(general.span_matrices()[0])} x "
          f"{len(general.span_matrices()[1])} span matrices")
    best = best_interleaved({
        "grid": lambda: general.evaluate_grid(gu, gw),
        "normals": lambda: general.normals(gu, gw, grid=True),
        "scatter": lambda: general.evaluate(su, sw),
        "derivatives": lambda: general.derivatives(su, sw),
    }, args.repeat)
    ours_point = best["scatter"] / args.points
    print(f"  grid {args.n}^2 points {best['grid'] * 1e3:.1f} ms, normals "
          f"{best['normals'] * 1e3:.1f} ms ({best['normals'] / best['grid']:.2f}x points); "
          f"{args.points:.0e} scattered points {best['scatter'] * 1e3:.1f} ms, "
          f"with derivatives {best['derivatives'] * 1e3:.1f} ms")
    k = args.peer_points
    pu, pw = su[:k], sw[:k]
    try:
        from geomdl import NURBS

        gs = NURBS.Surface(normalize_kv=False)
        gs.degree_u, gs.degree_v = data["degree_u"], data["degree_v"]
        gs.ctrlpts_size_u, gs.ctrlpts_size_v = data["poles"].shape[:2]
        gs.ctrlptsw = np.concatenate([data["poles"] * data["weights"][..., None],
                                      data["weights"][..., None]], -1).reshape(-1, 4).tolist()
        gs.knotvector_u, gs.knotvector_v = data["knots_u"].tolist(), data["knots_v"].tolist()
        params = np.stack([pu, pw], -1).tolist()
        seconds = best_of(lambda: gs.evaluate_list(params), 1) / k
        err = float(np.abs(np.array(gs.evaluate_list(params[:500]))
                           - general.evaluate(pu[:500], pw[:500])).max())
        print(f"  geomdl NURBS: {seconds * 1e6:.2f} us/point, ours {ours_point * 1e6:.3f} "
              f"us/point: ratio {seconds / ours_point:.0f}x (max diff {err:.1e} mm)")
    except ImportError:
        print("  geomdl: not available")
    try:
        from BSplineCAM.ocp import occ

        geom = occ.nurbs_geom(**data)

        def occt():
            for a, b in zip(pu, pw):
                geom.Value(float(a), float(b))

        seconds = best_of(occt, 2) / k
        ref = occ.nurbs_d2(geom, pu[:500], pw[:500])[0]
        err = float(np.abs(ref - general.evaluate(pu[:500], pw[:500])).max())
        print(f"  OCCT per point (Value): {seconds * 1e6:.2f} us/point, ours "
              f"{ours_point * 1e6:.3f} us/point: ratio {seconds / ours_point:.1f}x "
              f"(max diff {err:.1e} mm)")
    except ImportError:
        print("  OCCT (cadquery's OCP): not available")


if __name__ == "__main__":
    main()
