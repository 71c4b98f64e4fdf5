# SPDX-License-Identifier: LGPL-2.1-or-later
"""Write examples/part.step: the README's second example, a part to machine from STEP.

An 80 x 60 mm block whose top is a B-spline surface (cadquery's ``Face.makeSplineApprox``,
i.e. OCCT's GeomAPI_PointsToBSplineSurface, through a grid of points of a gentle hill and
hollow), with a 12 mm through hole and its two long top edges rounded by 4 mm rolling-ball
fillets (rational B-spline faces, OCCT's approximation).  The top face is thus a trimmed
B-spline face with a hole, bounded by two fillet faces and two walls.

Run in the project's venv (cadquery):  .venv/bin/python examples/make_part.py [OUT.step]
[--all-edges] (fillet all four top edges; the example fillets the two long ones)
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import cadquery as cq

LENGTH, WIDTH = 80.0, 60.0  # mm, along x and y
BASE = 25.0  # mm, mean height of the top
HOLE = (58.0, 22.0, 6.0)  # centre x, y and radius of the through hole (mm)
FILLET = 4.0  # mm, radius of the fillets along the top edges
GRID = 5  # points per side of the approximated top surface (a 5 x 5 bicubic net)
MAX_DEGREE = 9  # the core evaluator takes degrees 1 to 9


def top_height(x: float, y: float) -> float:
    """Height (mm) of the designed top at (x, y): a hill and a hollow on a slope."""
    hill = 5.0 * math.exp(-((x - 28.0) ** 2 + (y - 34.0) ** 2) / 320.0)
    hollow = -3.0 * math.exp(-((x - 60.0) ** 2 + (y - 22.0) ** 2) / 250.0)
    return BASE + hill + hollow + 0.04 * x


def make_part(all_edges: bool = False) -> cq.Shape:
    """The solid: block, B-spline top, through hole, filleted top edges (the two long ones,
    or all four with ``all_edges``: the fillets then meet at the corners)."""
    margin = 5.0  # the surface reaches past the block so that the walls trim it
    xs = [-margin + (LENGTH + 2 * margin) * i / (GRID - 1) for i in range(GRID)]
    ys = [-margin + (WIDTH + 2 * margin) * j / (GRID - 1) for j in range(GRID)]
    points = [[cq.Vector(x, y, top_height(x, y)) for y in ys] for x in xs]
    top = cq.Face.makeSplineApprox(points, tol=1e-4, minDeg=3, maxDeg=3)
    # The top face pushed down well below the block's bottom sweeps a prism; the block's box
    # cuts it to 80 x 60 with a flat bottom at z = 0.
    prism = cq.Solid.extrudeLinear(top, cq.Vector(0, 0, -3 * BASE))
    box = cq.Solid.makeBox(LENGTH, WIDTH, 3 * BASE)
    block = cq.Workplane().add(prism.intersect(box).clean())
    hole = cq.Solid.makeCylinder(HOLE[2], 3 * BASE, cq.Vector(HOLE[0], HOLE[1], -BASE / 2))
    block = block.cut(cq.Workplane().add(hole))
    # The two long top edges (along x), or all four.  Where fillets meet at a corner OCCT
    # leaves their parameter curves up to 0.01 mm apart, within the vertex tolerances (the
    # trim readers measure joints on the surface against them).
    shape = block.val()
    top_face = max(shape.Faces(), key=lambda f: f.Center().z)
    long_edges = [e for e in top_face.outerWire().Edges()
                  if all_edges or abs((e.endPoint() - e.startPoint()).x) > LENGTH / 2]
    return shape.fillet(FILLET, long_edges).clean()


def max_degree(shape: cq.Shape) -> int:
    """The highest degree of the shape's B-spline faces (OCCT's fillets are B-spline
    approximations whose degree grows with the top's complexity)."""
    from OCP.BRep import BRep_Tool
    from OCP.Geom import Geom_BSplineSurface

    degrees = [0]
    for face in shape.Faces():
        surface = BRep_Tool.Surface_s(face.wrapped)
        if surface.DynamicType().Name() == "Geom_BSplineSurface":
            spline = Geom_BSplineSurface.DownCast(surface) if hasattr(
                Geom_BSplineSurface, "DownCast") else surface
            degrees += [spline.UDegree(), spline.VDegree()]
    return max(degrees)


def main(argv: list[str]) -> int:
    all_edges = "--all-edges" in argv
    argv = [a for a in argv if a != "--all-edges"]
    out = Path(argv[1]) if len(argv) > 1 else Path(__file__).with_name("part.step")
    shape = make_part(all_edges)
    if not shape.isValid():
        raise SystemExit("make_part: OCCT reports the part invalid")
    if max_degree(shape) > MAX_DEGREE:
        raise SystemExit(f"make_part: a face has degree {max_degree(shape)}, more than "
                         f"{MAX_DEGREE}")
    shape.exportStep(str(out))
    print(f"{out}: {len(shape.Faces())} faces, volume {shape.Volume():.1f} mm^3")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
