# SPDX-License-Identifier: LGPL-2.1-or-later
"""Speed and certification of the drop-cutter over trimmed faces (:meth:`FaceSet.drop_ball`)
on a STEP part (issue 11).

The part's faces are read with cadquery's OCCT (``BSplineCAM.ocp``, no FreeCAD), the faces
reached from above selected and the others kept as check surfaces, as ``bsplinecam toolpath
PART.step`` does.  The queries are the base samples of a raster finish over the selected faces
(passes along X, every sqrt(8 R tol) mm, spaced by the scallop allowance of the faces below, as
:mod:`.faces_raster` lays them out);
they go to ``drop_ball`` in one call (as the raster's first stage) or pass by pass
(``--batch pass``, as its refinement and chord checks).  It prints queries per second and the
branch-and-bound counters (``FaceSet.stats``), then compares ``--check`` of the heights with a
brute-force reference that shares no code with the drop-cutter: every face (check faces and
walls included) sampled densely inside its trim (core.faces.inside) and along its trim
polylines, the best samples zoomed in three times.  The reference is f at real face points, so
it never exceeds the true height: a certified height lies at most CERTIFY below it, and above
it only by what the sampling missed.

    .venv/bin/python benchmarks/dropcutter_faces.py [--part examples/part.step] [--every 3]
        [--baseline OLD_faceset.py] [--profile] [--batch pass] [--hints]

``--hints`` times the midpoints of each pass's consecutive samples (the chord checks'
queries) pass by pass, without hints and with the contacts of the samples answered before
as hints (:class:`.faceset_hints.ContactMemo`, as the waterline offers them), in the same
process.

``--baseline`` loads another copy of faceset.py (e.g. ``git show HEAD:BSplineCAM/core/
toolpath/faceset.py > /tmp/old.py``) and times it on the same queries in the same process, so
both figures see the same machine load.
"""

from __future__ import annotations

import argparse
import cProfile
import importlib.util
import math
import pstats
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from BSplineCAM.core.geometry import faces as core_faces  # noqa: E402
from BSplineCAM.core.toolpath import faceset as current  # noqa: E402


def load_module(path: str):
    """A copy of faceset.py as a module of the same package (its relative imports resolve)."""
    spec = importlib.util.spec_from_file_location("BSplineCAM.core.toolpath._faceset_baseline",
                                                  path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def raster_queries(faceset, radius: float, scallop: float, tolerance: float,
                   every: int) -> list[np.ndarray]:
    """The base samples (mm) of raster passes along X over the selected faces, one array per
    pass (every ``every``-th pass kept): passes spaced by the scallop allowance of the faces
    below them and reaching as far as the raster on faces reaches (its stepover field, when
    :mod:`.faces_raster` offers it; else the flat scallop stepover over the faces' box widened
    by R)."""
    from BSplineCAM.core.toolpath import faces_raster
    from BSplineCAM.core.toolpath.common import ToolParameters
    from BSplineCAM.core.toolpath.raster import scallop_line_offsets

    lo, hi = faceset.bounds(selected_only=True)
    h = min(scallop, radius)
    flat = min(2.0 * math.sqrt(max(2.0 * radius * h - h * h, 0.0)), radius)
    step = min(math.sqrt(8.0 * radius * tolerance), radius / 2.0)
    field = getattr(faces_raster, "_stepover_field", None)
    if field is not None:
        tool = ToolParameters.validate(2.0 * radius, scallop, tolerance)
        b_off, allowed, reach = field(faceset, tool, np.array([1.0, 0.0]), np.array([0.0, 1.0]))
        x0, x1 = min(lo[0], reach[0, 0]), max(hi[0], reach[1, 0])
        y0, y1 = min(lo[1], reach[0, 1]), max(hi[1], reach[1, 1])
        ys = np.array(scallop_line_offsets(b_off, allowed, y0, y1, tool, 0.5 * flat))
    else:
        x0, x1 = lo[0] - radius, hi[0] + radius
        y0, y1 = lo[1] - radius, hi[1] + radius
        ys = np.linspace(y0, y1, max(2, math.ceil((y1 - y0) / flat) + 1))
    n = max(2, math.ceil((x1 - x0) / step) + 1)
    xs = np.linspace(x0, x1, n)
    return [np.column_stack([xs, np.full(n, y)]) for y in ys[::every]]


class BruteForce:
    """Largest f(p) = p_z + sqrt(R^2 - |p_xy - q|^2) over the faces' material by dense
    sampling and zooming (no branch and bound, no Bezier patches)."""

    def __init__(self, faces, radius: float, grid: int = 301, per_edge: int = 6):
        self.faces = faces
        self.R = radius
        self.samples = []
        for f in faces:
            (u0, u1), (v0, v1) = f.surface.domain
            gu, gv = np.meshgrid(np.linspace(u0, u1, grid), np.linspace(v0, v1, grid),
                                 indexing="ij")
            uv = np.column_stack([gu.ravel(), gv.ravel()])
            uv = uv[core_faces.inside(f, uv[:, 0], uv[:, 1])]
            t = np.linspace(0.0, 1.0, per_edge, endpoint=False)
            for loop in f.loops:
                a, b = loop[:-1], loop[1:]
                pts = (a[:, None] + t[None, :, None] * (b - a)[:, None]).reshape(-1, 2)
                uv = np.concatenate([uv, pts, loop])
            self.samples.append((uv, f.surface.evaluate(uv[:, 0], uv[:, 1]),
                                 ((u1 - u0) / (grid - 1), (v1 - v0) / (grid - 1))))

    def f(self, p: np.ndarray, q: np.ndarray) -> np.ndarray:
        d2 = ((p[..., :2] - q) ** 2).sum(axis=-1)
        R2 = self.R * self.R
        return np.where(d2 <= R2, p[..., 2] + np.sqrt(np.maximum(R2 - d2, 0.0)), -np.inf)

    def centre(self, q: np.ndarray, seeds: int = 4) -> float:
        best = -np.inf
        for f, (uv, pts, (hu, hv)) in zip(self.faces, self.samples):
            fv = self.f(pts, q)
            if not np.isfinite(fv).any():
                continue
            (u0, u1), (v0, v1) = f.surface.domain
            for k in np.argsort(fv)[-seeds:]:
                if not np.isfinite(fv[k]):
                    continue
                best = max(best, float(fv[k]))
                cu, cv, du, dv = uv[k, 0], uv[k, 1], 2.0 * hu, 2.0 * hv
                for _ in range(4):
                    zu, zv = np.meshgrid(np.clip(np.linspace(cu - du, cu + du, 41), u0, u1),
                                         np.clip(np.linspace(cv - dv, cv + dv, 41), v0, v1),
                                         indexing="ij")
                    zu, zv = zu.ravel(), zv.ravel()
                    keep = core_faces.inside(f, zu, zv)
                    if not keep.any():
                        break
                    zu, zv = zu[keep], zv[keep]
                    fz = self.f(f.surface.evaluate(zu, zv), q)
                    j = int(np.argmax(fz))
                    best = max(best, float(fz[j]))
                    cu, cv, du, dv = zu[j], zv[j], du / 10.0, dv / 10.0
        return best


def time_module(module, faces, passes, radius: float, batch: str, profile: bool) -> dict:
    fs = module.FaceSet(faces)
    prof = cProfile.Profile() if profile else None
    started = time.perf_counter()
    if prof:
        prof.enable()
    # centre_heights is drop_ball without the argument checks, with the gaps
    if batch == "all":
        outs = [fs.centre_heights(np.concatenate(passes), radius)]
    else:
        outs = [fs.centre_heights(p, radius) for p in passes]
    tip = np.concatenate([o.centre for o in outs]) - radius
    face = np.concatenate([o.face for o in outs])
    gap = np.concatenate([o.gap for o in outs])
    if prof:
        prof.disable()
    seconds = time.perf_counter() - started
    if prof:
        pstats.Stats(prof).sort_stats("tottime").print_stats(18)
    n = sum(len(p) for p in passes)
    return {"queries": n, "seconds": seconds, "per_second": n / seconds, "tip": tip,
            "face": face, "gap": gap, "stats": dict(fs.stats)}


def time_hints(faces, passes, radius: float) -> None:
    """Midpoints of each pass's consecutive samples, pass by pass, without and with hints
    (the contacts of the passes' samples, :class:`ContactMemo`)."""
    from BSplineCAM.core.toolpath.faceset_hints import ContactMemo

    mids = [0.5 * (p[1:] + p[:-1]) for p in passes if len(p) > 1]
    rows = {}
    for hinted in (False, True):
        fs = current.FaceSet(faces)
        memo = ContactMemo.for_radius(radius)
        seconds, cpu, tips = 0.0, 0.0, []
        for p, mid in zip([p for p in passes if len(p) > 1], mids):
            base = fs.centre_heights(p, radius)  # the samples' answers: not timed
            memo.add(p, base.face, base.u, base.v)
            started, c0 = time.perf_counter(), time.process_time()
            hint = memo.hints(mid) if hinted else None
            out = fs.centre_heights(mid, radius, hint=hint)
            seconds += time.perf_counter() - started
            cpu += time.process_time() - c0
            tips.append(out.centre - radius)
        rows[hinted] = (seconds, cpu, np.concatenate(tips))
        n = sum(len(m) for m in mids)
        print(f"midpoints {'with hints   ' if hinted else 'without hints'} {n} queries in "
              f"{seconds:.2f} s ({cpu:.2f} s CPU): {n / seconds:.0f} queries/s")
    a, b = rows[False][2], rows[True][2]
    ok = np.isfinite(a)
    print(f"hints: speed-up {rows[False][0] / rows[True][0]:.2f}x; heights: largest difference "
          f"{np.abs(a[ok] - b[ok]).max(initial=0.0):.3g} mm, "
          f"{int((a[ok] != b[ok]).sum())} of {int(ok.sum())} not the same bits, same misses "
          f"{np.array_equal(ok, np.isfinite(b))}")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--part", default=str(ROOT / "examples" / "part.step"))
    parser.add_argument("--faces", default="up", help="selection: up or face numbers")
    parser.add_argument("--tool-diameter", type=float, default=6.0, help="ball diameter (mm)")
    parser.add_argument("--scallop", type=float, default=0.2, help="sets the pass spacing (mm)")
    parser.add_argument("--tolerance", type=float, default=0.002,
                        help="sets the sample spacing along a pass (mm)")
    parser.add_argument("--every", type=int, default=1, help="keep every n-th pass")
    parser.add_argument("--batch", choices=("all", "pass"), default="all")
    parser.add_argument("--check", type=int, default=60,
                        help="heights compared with the brute-force reference")
    parser.add_argument("--baseline", help="another faceset.py to time on the same queries")
    parser.add_argument("--profile", action="store_true", help="print cProfile's top functions")
    parser.add_argument("--hints", action="store_true",
                        help="time the passes' midpoints without and with neighbours' hints")
    args = parser.parse_args(argv)

    from BSplineCAM.ocp import faces as ocp

    faces = ocp.faces_from_shape(ocp.read_part(args.part), args.faces)
    R = 0.5 * args.tool_diameter
    passes = raster_queries(current.FaceSet(faces), R, args.scallop, args.tolerance,
                            args.every)
    print(f"{args.part}: {len(faces)} faces ({sum(f.selected for f in faces)} selected), "
          f"{len(passes)} passes, {sum(len(p) for p in passes)} queries, ball R {R} mm, "
          f"batch {args.batch}")
    runs = []
    if args.baseline:
        runs.append(("baseline", load_module(args.baseline)))
    runs.append(("current", current))
    results = {}
    for name, module in runs:
        r = time_module(module, faces, passes, R, args.batch, args.profile)
        results[name] = r
        print(f"{name:9s} {r['queries']} queries in {r['seconds']:.2f} s: "
              f"{r['per_second']:.0f} queries/s; counters {r['stats']}; largest gap "
              f"{r['gap'].max(initial=0.0):.3g} mm, {int((r['gap'] > current.CERTIFY).sum())} "
              "queries with a gap over CERTIFY")
    cur = results["current"]
    if args.hints:
        time_hints(faces, passes, R)
    if "baseline" in results:
        base = results["baseline"]
        both = np.isfinite(base["tip"]) & np.isfinite(cur["tip"])
        same_nan = np.array_equal(np.isnan(base["tip"]), np.isnan(cur["tip"]))
        diff = float(np.abs(base["tip"][both] - cur["tip"][both]).max(initial=0.0))
        print(f"speed-up {cur['per_second'] / base['per_second']:.2f}x; heights: largest "
              f"difference {diff:.3g} mm, same misses {same_nan}")
    if args.check:
        xy = np.concatenate(passes)
        found = np.flatnonzero(np.isfinite(cur["tip"]))
        rng = np.random.default_rng(11)
        # half at random, half where the contact is on a fillet or a check face (the joints)
        joint = found[cur["face"][found] != 0]
        pick = np.concatenate([rng.choice(found, min(len(found), args.check // 2), False),
                               rng.choice(joint, min(len(joint), args.check - args.check // 2),
                                          False) if len(joint) else []]).astype(int)
        brute = BruteForce(faces, R)
        started = time.perf_counter()
        ref = np.array([brute.centre(q) for q in xy[pick]]) - R
        tip = cur["tip"][pick]
        below = float((ref - tip).max())
        # a contact on a vertical check face (a wall) is on its trim polyline's chord, within
        # the trim tolerance of the face and possibly above it: a safe height, reported apart
        wall = np.isin(cur["face"][pick], current.FaceSet(faces).walls.owner)
        above = float((tip - ref)[~wall].max(initial=-np.inf))
        above_wall = float((tip - ref)[wall].max(initial=-np.inf))
        print(f"check: {len(pick)} heights against brute force ({time.perf_counter() - started:.1f}"
              f" s): at most {below:.3g} mm below it (certified: <= {current.CERTIFY:g}), "
              f"at most {above:.3g} mm above it (what the sampling missed); "
              f"{int(wall.sum())} contacts on walls' trim chords: at most {above_wall:.3g} mm "
              "above")
        if below > current.CERTIFY + 1e-9:
            raise SystemExit("certification FAILED: a height lies more than CERTIFY below a "
                             "face point's")


if __name__ == "__main__":
    main()
