# SPDX-License-Identifier: LGPL-2.1-or-later
"""Arc moves and their measures: the :class:`Arc` feed move (G2/G3 in the G17, G18 or G19
plane, a helix in G17), its construction from start, end and centre, its motion words in R
form, the feed length of a list of lines and arcs, move counts, and a minimal program text
with the plane word before arcs and G17 restored after them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple, Union

import numpy as np

from ..program.gcode import PLANE_AXES
from ..typing import FloatArray
from .common import Move


class Arc(NamedTuple):
    """A circular feed move: ``kind`` 'cw' (G2) or 'ccw' (G3) seen from the plane's normal
    axis (+Z for G17, +Y for G18, +X for G19); x, y, z the end point, cx, cy, cz the centre
    (absolute, mm), ``radius`` (mm), ``plane`` 17, 18 or 19.  In G17 z may change (helix)."""

    kind: str
    x: float
    y: float
    z: float
    cx: float
    cy: float
    cz: float
    radius: float
    plane: int


AnyMove = Union[Move, Arc]


def _arc(start: FloatArray, end: FloatArray, centre: FloatArray, radius: float,
         plane: int) -> Arc:
    a1, a2, _ = PLANE_AXES[plane]
    s = start - centre
    e = end - centre
    cross = s[a1] * e[a2] - s[a2] * e[a1]
    kind = "ccw" if cross > 0 else "cw"
    return Arc(kind, float(end[0]), float(end[1]), float(end[2]), float(centre[0]),
               float(centre[1]), float(centre[2]), float(radius), plane)


def counts(moves: Sequence[AnyMove]) -> dict:
    """Numbers of rapid, line and arc moves (for reports)."""
    arcs = sum(isinstance(m, Arc) for m in moves)
    rapids = sum(m.kind == "rapid" for m in moves)
    return {"moves": len(moves), "arcs": arcs, "lines": len(moves) - arcs - rapids,
            "rapids": rapids}


def feed_length(moves: Sequence[AnyMove]) -> float:
    """Length (mm) of the feed moves (lines and arcs) of ``moves``, each from the end of the
    move before it (a feed with none before it has no length): the cutting length a program
    made of them has, as :mod:`BSplineCAM.core.program.gcode` measures its text.  An arc sweeps from
    its start to its end round its centre in its plane, the way its kind turns seen from the
    plane's normal axis (an end on its start: no sweep), and a helix adds its travel along
    that axis.  Lines are summed at once."""
    n = len(moves)
    if n < 2:
        return 0.0
    xyz = np.array([(m.x, m.y, m.z) for m in moves], dtype=float)
    line = np.array([m.kind == "feed" for m in moves[1:]], dtype=bool)
    seg = np.diff(xyz, axis=0)
    total = float(np.sqrt((seg[line] ** 2).sum(axis=1)).sum())
    for i in range(1, n):
        arc = moves[i]
        if not isinstance(arc, Arc):
            continue
        a1, a2, normal = PLANE_AXES[arc.plane]
        centre = (arc.cx, arc.cy, arc.cz)
        start, end = xyz[i - 1], xyz[i]
        t0 = math.atan2(start[a2] - centre[a2], start[a1] - centre[a1])
        t1 = math.atan2(end[a2] - centre[a2], end[a1] - centre[a1])
        sweep = (t1 - t0 if arc.kind == "ccw" else t0 - t1) % (2.0 * math.pi)
        total += math.hypot(arc.radius * sweep, end[normal] - start[normal])
    return total


def gcode_words(arc: Arc, decimals: int = 4) -> str:
    """The motion words of an arc in R form (``G2 X.. Y.. Z.. R..``): every post keeps R,
    while FreeCAD's linuxcnc, fanuc and mach3_mach4 posts drop K (needed by G18/G19)."""
    word = "G2" if arc.kind == "cw" else "G3"
    return (f"{word} X{arc.x:.{decimals}f} Y{arc.y:.{decimals}f} Z{arc.z:.{decimals}f} "
            f"R{arc.radius:.{decimals}f}")


def plain_gcode(moves: Sequence[AnyMove], feed: float = 1000.0, decimals: int = 4,
                plunge_feed: float | None = None) -> str:
    """A minimal program (G21 G90, G0 / G1 / G2 / G3 with F, the plane word before arcs and
    G17 restored after them, M2); with ``plunge_feed`` (mm/min) the feed lines that keep X
    and Y (plunges) take it instead of ``feed``."""
    lines = ["G17 G21 G90"]
    plane = 17
    last = None
    for m in moves:
        previous, last = last, (m.x, m.y)
        if isinstance(m, Arc):
            if m.plane != plane:
                lines.append(f"G{m.plane}")
                plane = m.plane
            lines.append(f"{gcode_words(m, decimals)} F{feed:g}")
            continue
        if plane != 17:
            lines.append("G17")
            plane = 17
        word = "G0" if m.kind == "rapid" else "G1"
        rate = feed
        if plunge_feed is not None and previous is not None and \
                abs(m.x - previous[0]) < 1e-9 and abs(m.y - previous[1]) < 1e-9:
            rate = plunge_feed
        tail = "" if m.kind == "rapid" else f" F{rate:g}"
        lines.append(f"{word} X{m.x:.{decimals}f} Y{m.y:.{decimals}f} Z{m.z:.{decimals}f}{tail}")
    if plane != 17:
        lines.append("G17")
    lines.append("M2")
    return "\n".join(lines) + "\n"
