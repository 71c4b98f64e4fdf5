# SPDX-License-Identifier: LGPL-2.1-or-later
"""The two engines of :mod:`BSplineCAM.core.kernels` side by side, in one process.

Each case runs under the numpy engine and under the numba engine (warm: its kernels compiled
before the clock starts), and prints both times, their ratio and how far the answers differ
(heights in mm, programs line by line).  Then the cold start: a new process with an empty
compile cache runs the warm-up (:func:`BSplineCAM.core.kernels.warm.warm_up`) and reports the
compile seconds per kernel; a second process with the cache filled shows what a later start
costs.

    .venv/bin/python benchmarks/kernels.py [--part examples/part.step] [--scallop 0.2]
        [--strategies raster,waterline,isoparametric,steep_shallow] [--no-cold] [--json FILE]

The part's faces are read with cadquery's OCCT (no FreeCAD), the faces reached from above
selected, as ``bsplinecam toolpath PART`` does.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from BSplineCAM.core import kernels  # noqa: E402
from BSplineCAM.core.toolpath import generate_faces, to_moves  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402


def _program(tp) -> list[str]:
    return [f"{m.kind} {m.x:.4f} {m.y:.4f} {m.z:.4f}" for m in to_moves(tp)]


def _timed(engine: str, work, repeat: int = 1):
    """(best seconds, last answer) of ``work()`` under ``engine``; under numba one call runs
    first, untimed, so that its kernels are compiled."""
    with kernels.forced(engine):
        if engine == "numba":
            work()
        best = float("inf")
        out = None
        for _ in range(repeat):
            start = time.perf_counter()
            out = work()
            best = min(best, time.perf_counter() - start)
    return best, out


def _row(name: str, numpy_s: float, numba_s: float, agree: str) -> dict:
    ratio = numpy_s / numba_s if numba_s > 0 else float("inf")
    print(f"{name:42s} numpy {numpy_s:8.3f} s   numba {numba_s:8.3f} s   {ratio:6.2f}x   {agree}")
    return {"case": name, "numpy_s": numpy_s, "numba_s": numba_s, "ratio": ratio,
            "agreement": agree}


def evaluation_cases(faces) -> list[dict]:
    """Scattered points with derivatives on the part's face with the most poles."""
    surface = max((f.surface for f in faces), key=lambda s: s.poles.size)
    (u0, u1), (v0, v1) = surface.domain
    rng = np.random.default_rng(3)
    rows = []
    for n, repeat in ((10, 2000), (1000, 200), (100_000, 3)):
        u = rng.uniform(u0, u1, n)
        v = rng.uniform(v0, v1, n)

        def work(u=u, v=v, repeat=repeat):
            for _ in range(repeat):
                d = surface.derivatives(u, v)
            return np.stack([d.point, d.su, d.sw, d.suu, d.suw, d.sww])

        a_s, a = _timed("numpy", work)
        b_s, b = _timed("numba", work)
        rel = float(np.abs(a - b).max() / max(np.abs(a).max(), 1.0))
        rows.append(_row(f"NURBS derivatives, {n} points x {repeat}", a_s, b_s,
                         f"largest difference {rel:.1e} of the size"))
    return rows


def dropcutter_case(faces, scallop: float) -> list[dict]:
    """The base samples of a raster finish over the part, in one call and pass by pass."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from dropcutter_faces import raster_queries  # noqa: PLC0415

    R = 3.0
    passes = raster_queries(FaceSet(faces), R, scallop, 0.002, 1)
    rows = []
    for batch in ("all", "pass"):
        def work(batch=batch):
            fs = FaceSet(faces)
            qs = [np.concatenate(passes)] if batch == "all" else passes
            outs = [fs.centre_heights(q, R) for q in qs]
            return np.concatenate([o.centre for o in outs]), dict(fs.stats)

        a_s, (a, sa) = _timed("numpy", work)
        b_s, (b, sb) = _timed("numba", work)
        both = np.isfinite(a) & np.isfinite(b)
        diff = float(np.abs(a[both] - b[both]).max(initial=0.0))
        same = np.array_equal(np.isfinite(a), np.isfinite(b)) and sa == sb
        n = sum(len(p) for p in passes)
        rows.append(_row(f"drop-cutter, {n} raster queries ({batch})", a_s, b_s,
                         f"heights within {diff:.1e} mm, same decisions {same}"))
    return rows


def strategy_cases(faces, strategies: list[str], scallop: float) -> list[dict]:
    rows = []
    for strategy in strategies:
        def work(strategy=strategy):
            return _program(generate_faces(FaceSet(faces), strategy, tool_diameter=6.0,
                                           scallop=scallop, tolerance=0.002))

        a_s, a = _timed("numpy", work)
        b_s, b = _timed("numba", work)
        same = "programs identical" if a == b else (
            f"programs differ: {sum(x != y for x, y in zip(a, b)) + abs(len(a) - len(b))} "
            f"of {len(a)} lines")
        rows.append(_row(f"{strategy} on the part, scallop {scallop} mm", a_s, b_s, same))
    return rows


def cold_start() -> dict:
    """Compile seconds in a process with an empty cache, then with the cache filled."""
    out = {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "BSPLINECAM_CACHE": cache, "BSPLINECAM_KERNELS": "numba",
               "PYTHONPATH": str(ROOT)}
        env.pop("NUMBA_CACHE_DIR", None)
        code = ("import json, time; t = time.perf_counter()\n"
                "from BSplineCAM.core.kernels.warm import warm_up\n"
                "warm_up()\n"
                "from BSplineCAM.core import kernels\n"
                "print(json.dumps({'seconds': time.perf_counter() - t, "
                "**kernels.engine().to_dict()}))\n")
        for label in ("cold", "cached"):
            run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                                 text=True, check=True)
            data = json.loads(run.stdout.strip().splitlines()[-1])
            out[label] = data
            total = sum(data["compile_seconds"].values())
            print(f"warm-up, {label} cache: {data['seconds']:.2f} s in all, kernels "
                  f"{total:.2f} s ({len(data['compile_seconds'])} kernels)")
    return out


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", default=str(ROOT / "examples" / "part.step"))
    parser.add_argument("--scallop", type=float, default=0.2)
    parser.add_argument("--strategies", default="raster")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold-start runs")
    parser.add_argument("--json", help="write the figures to this file")
    args = parser.parse_args(argv)
    from BSplineCAM.ocp import faces as ocp  # noqa: PLC0415

    faces = ocp.faces_from_shape(ocp.read_part(args.part), "up")
    with kernels.forced("numba") as e:
        if e.name != "numba":
            raise SystemExit(f"numba engine unavailable: {e.reason}")
        version = e.numba_version
    print(f"{args.part}: {len(faces)} faces; numpy {np.__version__}, numba {version}, "
          f"Python {sys.version.split()[0]}, {os.cpu_count()} cores")
    rows = evaluation_cases(faces)
    rows += dropcutter_case(faces, args.scallop)
    strategies = [s for s in args.strategies.split(",") if s]
    rows += strategy_cases(faces, strategies, args.scallop)
    cold = None if args.no_cold else cold_start()
    if args.json:
        Path(args.json).write_text(json.dumps({"rows": rows, "cold": cold}, indent=1))


if __name__ == "__main__":
    main()
