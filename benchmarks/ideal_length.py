# SPDX-License-Identifier: LGPL-2.1-or-later
"""The least cutting length any finishing pattern needs to leave a scallop ``h``: what issue
44's machining-time targets can reach at best.

Passes that run perpendicular to the XY direction n, at a point where the exact faces allow
passes s(n) mm apart (XY distance; :func:`BSplineCAM.core.toolpath.faces_scallop.stepovers`,
the vertical cusp ``h`` from the ball's cross-section over the surface's normal curvature,
the same allowance the raster and the constant-scallop passes use), lay 1 / s(n) mm of path
per mm² of XY area there.  No pattern lays less than 1 / max_n s(n) anywhere, so

    L* = integral over the ball-centre region of dA / max_n s(n)

is a lower bound of the tool centre's XY cutting length.  Along the passes the ball centre
also climbs: its height field has the slope of the faces at the contact, -n_xy / n_z for the
normal n, so a pass along the XY unit vector t lays sqrt(1 + (n_xy . t / n_z)²) mm of path
per mm of XY, and

    L3* = integral of dA min_n sqrt(1 + (n_xy . t / n_z)²) / s(n),   t perpendicular to n,

is a lower bound of the centre's cutting length in space; L3* / feed a lower bound of the
cutting time (no links, no retracts, no acceleration).  The region is the XY grid of ball centres whose certified drop-cutter contact lies
on a selected face (those reached from above), cells ``--cell`` mm (default a quarter of the
flat stepover, at most R / 4); ``--directions`` across directions over a half turn.

Parts: ``part`` (examples/part.step), ``step`` (the plane-with-fillets step of
tests/TestBSplineCAMPartialPasses.py and benchmarks/machining_parts.py), or STEP/BREP files.
Run in the project venv (cadquery's OCCT reads the files):

    .venv/bin/python benchmarks/ideal_length.py [--parts part,step] [--scallop 0.05]
        [--diameter 6] [--feed 1200] [--cell C] [--directions 72] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
for folder in (ROOT, ROOT / "tests"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

from BSplineCAM.core.toolpath.common import ToolParameters  # noqa: E402
from BSplineCAM.core.toolpath.faces_raster import FaceQuery  # noqa: E402
from BSplineCAM.core.toolpath.faces_scallop import stepovers, surface_contacts  # noqa: E402
from BSplineCAM.core.toolpath.faces_waterline import _upward_signs  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402

DEFAULT_PARTS = "part,step,tests/parts/mal_vis.brep,tests/parts/MODERN_Exhaust_1.brep"


def part_faces(name: str) -> tuple[str, list]:
    """The label and the faces reached from above of ``name`` (see the module doc)."""
    if name == "step":
        from TestBSplineCAMPartialPasses import step_faces  # noqa: PLC0415

        return "plane-with-fillets step", step_faces()
    from BSplineCAM.ocp import faces as ocp  # noqa: PLC0415

    path = ROOT / "examples" / "part.step" if name == "part" else Path(name)
    label = "examples/part.step" if name == "part" else path.name
    return label, ocp.faces_from_shape(ocp.read_part(path), "up")


def ideal_length(faces: list, tool: ToolParameters, cell: float | None,
                 directions: int) -> dict:
    """L* (mm) over the faces' ball-centre region, with the region's area and the spread of
    max_n s(n) over it (see the module doc)."""
    fs = FaceSet(faces)
    R = tool.radius
    lo, hi = fs.bounds(selected_only=True)
    g = cell or min(tool.flat_stepover / 4.0, R / 4.0)
    xs = np.arange(lo[0] - R + g / 2, hi[0] + R, g)
    ys = np.arange(lo[1] - R + g / 2, hi[1] + R, g)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    xy = np.column_stack([X.ravel(), Y.ravel()])
    query = FaceQuery(fs, R)
    tip, face, u, v, sel = query.heights(xy)
    inside, jets = surface_contacts(fs, _upward_signs(fs), xy, tip, face, u, v, sel, R)
    t = np.arange(directions) * math.pi / directions
    across = np.column_stack([np.cos(t), np.sin(t)])
    along = np.column_stack([-across[:, 1], across[:, 0]])
    best = np.full(len(xy), np.nan)
    density = np.full(len(xy), np.nan)
    for idx, jet in jets:
        allowed = stepovers(jet, tool, across)  # (directions, m)
        best[idx] = allowed.max(axis=0)
        n = jet.normal
        slope = (n[:, :2] @ along.T).T / np.clip(n[:, 2], 1e-3, 1.0)  # (directions, m)
        density[idx] = (np.sqrt(1.0 + slope ** 2) / allowed).min(axis=0)
    keep = inside & np.isfinite(best)
    s = best[keep]
    return {"cells": int(s.size), "cell_mm": g, "area_mm2": float(s.size * g * g),
            "length_mm": float(np.sum(g * g / s)),
            "length_3d_mm": float(np.sum(g * g * density[keep])),
            "stepover_min_mm": float(s.min()),
            "stepover_median_mm": float(np.median(s)), "stepover_max_mm": float(s.max())}


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--parts", default=DEFAULT_PARTS)
    parser.add_argument("--diameter", type=float, default=6.0, help="ball diameter, mm")
    parser.add_argument("--scallop", type=float, default=0.05, help="scallop height, mm")
    parser.add_argument("--feed", type=float, default=1200.0, help="cutting feed, mm/min")
    parser.add_argument("--cell", type=float, default=None, help="grid cell, mm")
    parser.add_argument("--directions", type=int, default=72)
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    for name, value in (("--diameter", args.diameter), ("--scallop", args.scallop),
                        ("--feed", args.feed), ("--cell", args.cell or 1.0)):
        if not (math.isfinite(value) and value > 0):
            parser.error(f"{name} must be a positive number of mm (mm/min for --feed)")
    if args.directions < 4:
        parser.error("--directions must be at least 4")
    tool = ToolParameters.validate(args.diameter, args.scallop, 0.01)
    rows = []
    print(f"| part | region (mm²) | XY stepover min / median / max (mm) | least cutting length, "
          f"XY / in space (m) | least cutting time at {args.feed:g} mm/min (s) | compute (s) |")
    print("|---|---|---|---|---|---|")
    for name in [p for p in args.parts.split(",") if p]:
        started = time.perf_counter()
        label, faces = part_faces(name)
        row = {"part": label, **ideal_length(faces, tool, args.cell, args.directions)}
        row["seconds_at_feed"] = row["length_3d_mm"] / args.feed * 60.0
        row["compute_s"] = time.perf_counter() - started
        rows.append(row)
        print(f"| {label} | {row['area_mm2']:.0f} | {row['stepover_min_mm']:.3f} / "
              f"{row['stepover_median_mm']:.3f} / {row['stepover_max_mm']:.3f} | "
              f"{row['length_mm'] / 1000:.3f} / {row['length_3d_mm'] / 1000:.3f} | "
              f"{row['seconds_at_feed']:.1f} | "
              f"{row['compute_s']:.1f} |", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"diameter": args.diameter,
                                               "scallop": args.scallop, "feed": args.feed,
                                               "rows": rows}, indent=1))


if __name__ == "__main__":
    main()
