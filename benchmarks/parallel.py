# SPDX-License-Identifier: LGPL-2.1-or-later
"""The drop-cutter's queries on 1, 2, ... threads (:mod:`BSplineCAM.core.toolpath.parallel`).

On examples/part.step (its faces reached from above, read with cadquery's OCCT, as
``bsplinecam toolpath PART`` selects them), 6 mm ball:

* the base samples of a raster finish at the given scallop, answered in one call
  (:meth:`FaceSet.centre_heights`), then eight passes a call (a few thousand queries), then
  pass by pass (a few hundred);
* the raster toolpath on the faces end to end (:func:`generate_faces`), with the number of
  drop-cutter calls it makes and how many of them are large enough to be split.

Each case runs on every thread count in turn, ``--repeat`` times, interleaved (so that a change
of the machine's load touches every count alike), and the best time is kept; a first run per
case, untimed, compiles the kernels.  It prints the wall time, the cores this process kept busy
(its CPU seconds over the wall time: near the thread count, the threads ran at once; well under
it, they waited on the GIL or for a core) and those other processes kept busy meanwhile (from
/proc/stat; above 0 the machine was shared and the figure is loose), the speed-up against one
thread and whether the answers are those of one thread bit for bit.

    .venv/bin/python benchmarks/parallel.py [--part examples/part.step] [--scallop 0.2]
        [--threads 1,2,N] [--engine numba|numpy] [--repeat 3] [--no-raster] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from BSplineCAM.core import kernels  # noqa: E402
from BSplineCAM.core.toolpath import faceset, generate_faces, parallel, to_moves  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402

R = 3.0
TOLERANCE = 0.002


def _load() -> str:
    one, five, _ = os.getloadavg()
    return f"load average {one:.2f} (1 min), {five:.2f} (5 min)"


def _busy() -> float:
    """CPU seconds the whole machine has run (Linux; 0 elsewhere)."""
    try:
        with open("/proc/stat") as f:
            t = [int(x) for x in f.readline().split()[1:9]]
    except OSError:
        return 0.0
    return (sum(t) - t[3] - t[4]) / os.sysconf("SC_CLK_TCK")


def _timed(work) -> tuple[float, float, float, object]:
    """(wall s, this process's CPU s, other processes' CPU s, answer) of ``work()``."""
    busy, wall, cpu = _busy(), time.perf_counter(), time.process_time()
    out = work()
    wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
    return wall, cpu, max(0.0, _busy() - busy - cpu), out


def _same(a, b) -> bool:
    if isinstance(a, tuple | list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    return a == b


def compare(name: str, work, counts: list[int], repeat: int) -> list[dict]:
    """``work()`` on each thread count of ``counts`` (best of ``repeat``, interleaved)."""
    with parallel.forced(counts[0]):
        work()  # compile, fill nothing that later runs reuse (each run builds its FaceSet)
    best = {n: (float("inf"), 0.0, 0.0) for n in counts}
    answers: dict = {}
    for _ in range(repeat):
        for n in counts:
            with parallel.forced(n):
                wall, cpu, others, out = _timed(work)
            if wall < best[n][0]:
                best[n] = (wall, cpu, others)
            answers.setdefault(n, out)
    rows = []
    one = best[counts[0]][0]
    for n in counts:
        wall, cpu, others = best[n]
        same = _same(answers[n], answers[counts[0]])
        print(f"{name:44s} {n:2d} thread{'s' if n > 1 else ' '} {wall:6.2f} s  "
              f"cores: ours {cpu / wall:4.2f}, others {others / wall:4.2f}  "
              f"{one / wall:5.2f}x  {'identical' if same else 'DIFFERENT'}", flush=True)
        rows.append({"case": name, "threads": n, "wall_s": wall, "cpu_s": cpu,
                     "others_cpu_s": others, "speedup": one / wall, "identical": same})
    return rows


def drop_cases(faces, scallop: float, counts: list[int], repeat: int) -> list[dict]:
    from dropcutter_faces import raster_queries  # noqa: PLC0415

    passes = raster_queries(FaceSet(faces), R, scallop, TOLERANCE, 1)
    every = np.concatenate(passes)
    sizes = [len(p) for p in passes]

    def one_call():
        fs = FaceSet(faces)
        r = fs.centre_heights(every, R)
        return (r.centre, r.face, r.u, r.v, r.gap), dict(fs.stats)

    def by_pass():
        fs = FaceSet(faces)
        out = [fs.centre_heights(p, R) for p in passes]
        return [(r.centre, r.face, r.u, r.v, r.gap) for r in out], dict(fs.stats)

    def grouped():
        fs = FaceSet(faces)
        out = [fs.centre_heights(g, R) for g in groups]
        return [(r.centre, r.face, r.u, r.v, r.gap) for r in out], dict(fs.stats)

    # calls of a few thousand queries (eight passes each)
    groups = [np.concatenate(passes[k:k + 8]) for k in range(0, len(passes), 8)]
    rows = compare(f"drop-cutter, {len(every)} queries, one call", one_call, counts, repeat)
    rows += compare(f"the same, {len(groups)} calls of up to {max(len(g) for g in groups)}",
                    grouped, counts, repeat)
    rows += compare(f"the same, {len(passes)} calls of {min(sizes)}-{max(sizes)} (a pass)",
                    by_pass, counts, repeat)
    return rows


def raster_case(faces, scallop: float, counts: list[int], repeat: int) -> list[dict]:
    calls: list[int] = []
    spent: list[float] = []
    real = FaceSet.centre_heights

    def counted(self, q, *args, **kwargs):
        calls.append(len(q))
        start = time.perf_counter()
        out = real(self, q, *args, **kwargs)
        spent.append(time.perf_counter() - start)
        return out

    def work():
        tp = generate_faces(FaceSet(faces), "raster", tool_diameter=2 * R, scallop=scallop,
                            tolerance=TOLERANCE)
        return [(m.kind, m.x, m.y, m.z) for m in to_moves(tp)]

    FaceSet.centre_heights = counted
    try:
        with parallel.forced(1):
            start = time.perf_counter()
            work()
            total = time.perf_counter() - start
    finally:
        FaceSet.centre_heights = real
    sizes = np.array(calls)
    split = sizes >= 2 * faceset.PARALLEL_CHUNK
    print(f"raster, one thread: {total:.2f} s, of which {sum(spent):.2f} s in {len(sizes)} "
          f"drop-cutter calls of {int(sizes.sum())} queries; {int(split.sum())} calls "
          f"({', '.join(str(n) for n in sorted(sizes[split].tolist(), reverse=True))} queries, "
          f"{sum(t for t, b in zip(spent, split) if b):.2f} s) are split among threads",
          flush=True)
    return compare(f"raster on the part, scallop {scallop} mm", work, counts, repeat)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", default=str(ROOT / "examples" / "part.step"))
    parser.add_argument("--scallop", type=float, default=0.2)
    parser.add_argument("--threads", default=f"1,2,{os.cpu_count() or 1}",
                        help="thread counts, comma-separated (the first is the reference)")
    parser.add_argument("--engine", default="numba", choices=("numba", "numpy"))
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--chunks-per-thread", type=int, default=faceset.CHUNKS_PER_THREAD)
    parser.add_argument("--min-chunk", type=int, default=faceset.PARALLEL_CHUNK)
    parser.add_argument("--no-raster", action="store_true", help="skip the raster toolpath")
    parser.add_argument("--json", help="write the figures to this file")
    args = parser.parse_args(argv)
    counts = list(dict.fromkeys(int(n) for n in args.threads.split(",") if n.strip()))
    faceset.CHUNKS_PER_THREAD = args.chunks_per_thread
    faceset.PARALLEL_CHUNK = args.min_chunk
    from BSplineCAM.ocp import faces as ocp  # noqa: PLC0415

    faces = ocp.faces_from_shape(ocp.read_part(args.part), "up")
    rows: list[dict] = []
    with kernels.forced(args.engine) as e:
        if e.name != args.engine:
            raise SystemExit(f"{args.engine} engine unavailable: {e.reason}")
        print(f"{args.part}: {len(faces)} faces; {e.name} engine, numpy {np.__version__}, "
              f"Python {sys.version.split()[0]}, {os.cpu_count()} cores "
              f"({parallel.cores()} usable), chunks >= {faceset.PARALLEL_CHUNK} queries, "
              f"{faceset.CHUNKS_PER_THREAD} per thread; OPENBLAS_NUM_THREADS="
              f"{os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}; {_load()}", flush=True)
        rows += drop_cases(faces, args.scallop, counts, args.repeat)
        if not args.no_raster:
            rows += raster_case(faces, args.scallop, counts, args.repeat)
    print(f"after: {_load()}")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
