# SPDX-License-Identifier: LGPL-2.1-or-later
"""Iso-parametric finishing of trimmed faces: passes along the u (or v) curves of each
selected face of a :class:`FaceSet`, only inside the face's trim (issue 11, item 3).

Per selected face, as :mod:`.isoparametric` does for one control net:

* the iso-curves across are spaced by the scallop height from the curvature and slope of the
  face (:func:`.isoparametric._allowed_step`, curvature-adjusted stepover held vertically,
  checked on both neighbouring curves), over the points of each curve inside the trim;
  where a trim edge crosses the curves at an angle (a seam between two selected faces, a
  hole's rim) short partial curves cover the material between the last curve and the edge
  (:func:`_edge_curves`), so no point of the face lies farther than half a step from a pass;
* along a curve the contact point p runs from the trim's parameter box start to its end; the
  ball centre is p + R n (n the upward unit normal, Farouki 1986) and the tip that centre
  minus R; the tip is then raised to at least the certified :meth:`FaceSet.drop_ball` height
  at its XY over EVERY face of the set, so other faces and check surfaces are never gouged;
* a curve is cut only where (u, v) lies inside the trim (:meth:`_FaceData.inside`, the even-odd
  test of :func:`faces.inside`) and the face is no steeper than
  :data:`.faces_raster.STEEPEST_REACHED` (75 degrees: as far as the raster reaches; beyond it
  the contact nears the ball's rim, where the height's slope across the pass grows without
  bound and every chord check would have to sample it densely); the crossings are found by
  bisection in the parameter to ``TRIM_BISECTIONS`` halvings, and a stretch lifted more than
  tolerance / 2 by a face that is not selected (the ball rides a check surface) is left out
  as well;
* a face the ball fits across (a fillet of its radius: every curve's cutter locations on one
  line, :func:`_collapsed`) is left, with a note naming it, for raster or waterline;
* points are refined at chord midpoints until the CL curve departs at most tolerance / 2 from
  the chords, thinned by Douglas-Peucker to tolerance / 2 in 3-D, and every chord is made
  one-sided against the exact drop-cutter (:func:`.chords.lift_chords`).

Passes alternate in sense (zig-zag) face by face; stay-down links join neighbours
(:func:`.links.stay_down_links`) as in :mod:`.faces_raster`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..errors import ParameterError
from ..typing import FloatArray
from .common import (
    IsoDirection,
    Jet,
    Monitor,
    ProgressFn,
    ToolParameters,
    Toolpath,
    ToolpathStats,
)
from .faces_raster import STAY_DOWN_LINK, STEEPEST_REACHED, FaceQuery
from .faceset import FaceSet
from .isoparametric import _allowed_step, lifted_runs, too_many_curves
from .links import stay_down_links
from .raster import zigzag_by_line

#: Halvings of a parameter interval that crosses the trim (the crossing is then known to
#: 2^-40 of the interval).
TRIM_BISECTIONS = 40
#: Rounds of midpoint refinement along the passes.
REFINE_ROUNDS = 6
#: Probe points along a curve for the stepover across it.
PROBES = 65
#: Samples per probe column in the smallest step that find the trim edges between the
#: iso-curves (:func:`_edge_curves`; at most EDGE_SAMPLES_MAX a column).
EDGE_SAMPLES = 16
EDGE_SAMPLES_MAX = 4096
#: Columns along and rows across of the grid that tells a face the ball fits across
#: (:func:`_collapsed`).
COLLAPSE_GRID = (17, 9)


class _FaceJets:
    """``jet(u, w)`` of one face (the interface :func:`.isoparametric._allowed_step` reads),
    with the normal oriented up (``sign``)."""

    def __init__(self, surface, sign: float):
        self.surface = surface
        self.sign = sign

    def jet(self, u: FloatArray, w: FloatArray) -> Jet:
        (u0, u1), (v0, v1) = self.surface.domain
        u = np.clip(np.asarray(u, dtype=float).ravel(), u0, u1)
        w = np.clip(np.asarray(w, dtype=float).ravel(), v0, v1)
        d = self.surface.derivatives(u, w)
        return Jet(u, w, d.point, d.su, d.sw, d.suu, d.suw, d.sww, self.sign)


def _check_direction(direction) -> IsoDirection:
    """'u' (u varies along a pass) or 'v' ('w' accepted, the nets' name for it)."""
    if isinstance(direction, IsoDirection):
        return direction
    text = str(direction).strip().lower()
    if text in ("v", "w"):
        return IsoDirection.W
    if text == "u":
        return IsoDirection.U
    raise ParameterError(f"unknown direction {direction!r}: expected 'u' or 'v' (the face "
                         "parameter that varies along a pass)")


def _uv(along: FloatArray, fixed: FloatArray, iso: IsoDirection) -> tuple[FloatArray, FloatArray]:
    return (along, fixed) if iso is IsoDirection.U else (fixed, along)


def _mid_probes(a0: float, a1: float) -> FloatArray:
    """PROBES values of the parameter along the passes, mid-way in PROBES equal spans of the
    trim box's [a0, a1]: none on the box's sides, where a probe (or a probe column) would lie
    on a trim edge, in or out by rounding (a document saved and reopened got other curves
    and other partial passes)."""
    return a0 + (np.arange(PROBES) + 0.5) * ((a1 - a0) / PROBES)


def _collapsed(jets: _FaceJets, inside, R: float, tolerance: float, iso: IsoDirection,
               a0: float, a1: float, f0: float, f1: float) -> bool:
    """Whether the ball fits the face across its iso-curves: every curve's cutter locations
    (p + R n) fall on one line, within ``tolerance`` (mm), on COLLAPSE_GRID columns across
    the material (a fillet of the ball's radius).  Iso would cut that line once per curve,
    and where the fillet is tangent to a wall the line lies on the wall's edge at the ball's
    rim, where the drop height jumps by the wall's height at any rounding."""
    ga, gf = np.meshgrid(np.linspace(a0, a1, COLLAPSE_GRID[0]),
                         np.linspace(f0, f1, COLLAPSE_GRID[1]), indexing="ij")
    u, v = _uv(ga.ravel(), gf.ravel(), iso)
    ins = np.asarray(inside(u, v), bool).reshape(ga.shape)
    cols = ins.sum(axis=1) >= 2
    if not cols.any():
        return False
    jet = jets.jet(u, v)

    def spread(points: FloatArray) -> float:
        pts = points.reshape(ga.shape + (3,))
        lo = np.where(ins[..., None], pts, np.inf).min(axis=1)
        hi = np.where(ins[..., None], pts, -np.inf).max(axis=1)
        return float(np.linalg.norm((hi - lo)[cols], axis=1).max())

    # a sliver narrower than the tolerance is not one the ball fits: its points crowd too
    return spread(jet.p + R * jet.normal) <= tolerance < spread(jet.p)


def _iso_values(jets: _FaceJets, inside, tool: ToolParameters, iso: IsoDirection,
                a0: float, a1: float, f0: float, f1: float, name: str = "the face") -> list[float]:
    """Fixed-parameter values of the passes from f0 to f1, each step the least allowed on
    this curve and the next one (probes inside the trim, :func:`_mid_probes`; all probes
    where none is)."""
    probe = _mid_probes(a0, a1)

    def step(c: float) -> float:
        u, v = _uv(probe, np.full(PROBES, c), iso)
        ins = inside(u, v)
        along = probe[ins] if ins.sum() >= 2 else probe
        return _allowed_step(jets, tool, along, c, iso)

    fixed = [f0]
    while fixed[-1] < f1:
        c = fixed[-1]
        d = step(c)
        for _ in range(6):
            nxt = min(c + d, f1)
            d2 = step(nxt)
            if d2 >= 0.999 * (nxt - c):
                break
            d = d2
        fixed.append(min(c + max(d, 1e-9 * (f1 - f0)), f1))
        too_many_curves(len(fixed), name)
    return fixed


def _material_runs(inside, probe: FloatArray, f0: float, f1: float, df: float,
                   iso: IsoDirection) -> list[list[tuple[float, float]]]:
    """Per probe column (a fixed value of the parameter along the passes), the stretches of
    the fixed parameter in [f0, f1] inside the material, sampled every ``df`` at most (at
    most ``EDGE_SAMPLES_MAX`` samples), their ends the inside ends of the crossings
    (:func:`_trim_crossings` along the column: the directions swapped)."""
    n = min(EDGE_SAMPLES_MAX, max(2, math.ceil((f1 - f0) / max(df, 1e-300)) + 1))
    f = np.linspace(f0, f1, n)
    cols = len(probe)
    column = np.repeat(np.arange(cols), n)
    across = IsoDirection.W if iso is IsoDirection.U else IsoDirection.U
    ins = np.asarray(inside(*_uv(np.tile(f, cols), probe[column], across)), bool)
    rows, x, _ = _trim_crossings(inside, column, np.tile(f, cols), probe[column], ins, across)
    ins = ins.reshape(cols, n)
    runs: list[list[tuple[float, float]]] = []
    for j in range(cols):
        edges = x[rows == j].tolist()  # in order along the column
        if ins[j, 0]:
            edges.insert(0, f0)
        if ins[j, -1]:
            edges.append(f1)
        runs.append(list(zip(edges[0::2], edges[1::2])))
    return runs


def _edge_curves(inside, probe: FloatArray, fixed: list[float],
                 iso: IsoDirection) -> list[tuple[float, float, float]]:
    """Partial curves (fixed value, along from, along to) that cover the material next to
    trim edges running at an angle to the iso-curves.

    A pass is cut only inside the trim, so where a trim edge crosses the iso-curves (the seam
    of two selected faces, a hole's rim) the material next to it lies between a curve and
    the edge, not between two curves, and may lie up to a step from the nearest cut.  Along
    each probe column the material's stretches are found (:func:`_material_runs`); in each,
    a point farther than half the step from the curves cut there (the step of the gap it lies
    in, the allowed one) is uncovered.  An uncovered stretch [p, q] (shorter than a step) is
    covered by one curve in [max(p, q - h), min(q, p + h)] (h that half step; kept h / 8 off
    q, where the stretch may end at the edge itself); those
    intervals of all columns are met by the fewest curves by greedy interval stabbing (each
    curve at the earliest end of the intervals still open), and each curve is cut only over
    the columns whose intervals it meets, two probe spacings wider on each side.  So every
    point of the material lies within half a step of a curve cut there, or between two cut
    curves at most a step apart (as the scallop's step assumes)."""
    c = np.asarray(fixed, float)
    if len(c) < 2:
        return []
    steps = np.diff(c)
    runs = _material_runs(inside, probe, float(c[0]), float(c[-1]),
                          float(steps.min()) / EDGE_SAMPLES, iso)
    want = []  # (lo, hi, column): a curve must lie in [lo, hi]
    for j, stretches in enumerate(runs):
        for p, q in stretches:
            k = np.flatnonzero((c >= p) & (c <= q))
            if len(k) == 0:
                g = min(max(int(np.searchsorted(c, p)) - 1, 0), len(steps) - 1)
                gaps = [(p, q, 0.5 * steps[g])]
            else:
                gaps = []
                first, last = int(k[0]), int(k[-1])
                if first > 0 and c[first] - p > 0.5 * steps[first - 1]:
                    gaps.append((p, c[first] - 0.5 * steps[first - 1], 0.5 * steps[first - 1]))
                if last < len(steps) and q - c[last] > 0.5 * steps[last]:
                    gaps.append((c[last] + 0.5 * steps[last], q, 0.5 * steps[last]))
            for a, b, h in gaps:
                # a little inside the stretch's end (at an edge the curve would not be cut
                # there): any curve within h of both ends covers it
                want.append((max(a, b - h), min(b - min(h / 8.0, 0.5 * (b - a)), a + h), j))
    want.sort(key=lambda w: w[1])
    spacing = float(probe[1] - probe[0]) if len(probe) > 1 else 0.0
    curves = []
    while want:
        g = want[0][1]
        met = [w[2] for w in want if w[0] <= g]
        want = [w for w in want if w[0] > g]
        curves.append((g, float(probe[min(met)]) - 2 * spacing,
                       float(probe[max(met)]) + 2 * spacing))
    return curves


def _tips(jets: _FaceJets, query: FaceQuery, along: FloatArray, fixed: FloatArray,
          iso: IsoDirection) -> tuple[FloatArray, FloatArray, np.ndarray]:
    """Tip points (m, 3): the offset point p + R n - R z raised to the drop-cutter height;
    the raise (mm) and whether the drop-cutter contact lies on a selected face."""
    u, v = _uv(along, fixed, iso)
    jet = jets.jet(u, v)
    R = query.radius
    cl = jet.p + R * jet.normal
    cl[:, 2] -= R
    drop, _f, _u, _v, on_sel = query.heights(cl[:, :2])
    lift = np.where(np.isfinite(drop), np.maximum(drop - cl[:, 2], 0.0), 0.0)
    cl[:, 2] += lift
    return cl, lift, on_sel


def _trim_crossings(inside, line: np.ndarray, t: FloatArray, f: FloatArray, ins: np.ndarray,
                    iso: IsoDirection):
    """The inside end of every interval of a line whose ends differ in trim status, by
    bisection: (line, t, fixed) of those points."""
    k = np.flatnonzero((line[:-1] == line[1:]) & (ins[:-1] != ins[1:]))
    if len(k) == 0:
        return k, t[k], f[k]
    a, b = t[k].copy(), t[k + 1].copy()  # a inside, b outside
    swap = ~ins[k]
    a[swap], b[swap] = b[swap], a[swap]
    fk = f[k]
    for _ in range(TRIM_BISECTIONS):
        m = 0.5 * (a + b)
        mi = inside(*_uv(m, fk, iso))
        a = np.where(mi, m, a)
        b = np.where(mi, b, m)
    return line[k], a, fk


def _face_passes(face, k: int, faceset: FaceSet, query: FaceQuery, tool: ToolParameters,
                 iso: IsoDirection, monitor: Monitor, lo: float, hi: float):
    """Passes (list of (n, 3) tip arrays, zig-zag order), iso values and statistics of one
    selected face."""
    s = face.surface
    in_trim = faceset.trim_test(k)
    R = tool.radius
    u0, u1, v0, v1 = face.bounds()
    (du0, du1), (dv0, dv1) = s.domain
    u0, u1, v0, v1 = max(u0, du0), min(u1, du1), max(v0, dv0), min(v1, dv1)
    a0, a1, f0, f1 = (u0, u1, v0, v1) if iso is IsoDirection.U else (v0, v1, u0, u1)
    # upward normal: the sign that makes the face's normals point up on average
    gu, gv = np.meshgrid(np.linspace(u0, u1, 9), np.linspace(v0, v1, 9), indexing="ij")
    d = s.derivatives(gu.ravel(), gv.ravel())
    sign = 1.0 if float(np.cross(d.su, d.sw)[:, 2].sum()) >= 0 else -1.0
    jets = _FaceJets(s, sign)
    cap = math.sin(math.radians(STEEPEST_REACHED))

    def inside(u: FloatArray, v: FloatArray) -> np.ndarray:
        """Inside the trim and no steeper than STEEPEST_REACHED (as the raster reaches)."""
        ins = np.asarray(in_trim(u, v), bool)
        if ins.any():
            n = jets.jet(np.asarray(u, float)[ins], np.asarray(v, float)[ins]).normal
            ins[ins] = np.hypot(n[:, 0], n[:, 1]) <= cap
        return ins

    if _collapsed(jets, inside, R, tool.tolerance, iso, a0, a1, f0, f1):
        return [], [], {"edge_curves": 0, "collapsed": True}
    fixed = _iso_values(jets, inside, tool, iso, a0, a1, f0, f1, face.name)
    monitor(lo + 0.3 * (hi - lo))
    # points along each curve about sqrt(8 R tol) apart in 3-D
    ta = np.linspace(a0, a1, 33)
    tf = np.linspace(f0, f1, 9)
    pa, pf = _uv(np.tile(ta, 9), np.repeat(tf, 33), iso)
    pts = s.evaluate(pa, pf).reshape(9, 33, 3)
    length = float(np.linalg.norm(np.diff(pts, axis=1), axis=-1).sum(axis=1).max())
    step = min(math.sqrt(8.0 * R * tool.tolerance), R / 2.0)
    n = max(8, math.ceil(length / step) + 1)
    along = np.linspace(a0, a1, n)
    # the scallop-spaced curves, and partial ones along trim edges that cross them, probed in
    # PROBES columns (:func:`_mid_probes`)
    edge = _edge_curves(inside, _mid_probes(a0, a1), fixed, iso)
    values = np.array(list(fixed) + [g for g, _, _ in edge])
    span_lo = np.array([-np.inf] * len(fixed) + [b for _, b, _ in edge])
    span_hi = np.array([np.inf] * len(fixed) + [b for _, _, b in edge])
    order = np.argsort(values, kind="stable")
    values, span_lo, span_hi = values[order], span_lo[order], span_hi[order]
    line = np.repeat(np.arange(len(values)), n)
    t = np.tile(along, len(values))
    f = values[line]
    ins = inside(*_uv(t, f, iso))
    # trim crossings: the last point inside, by bisection
    cl_line, cl_t, cl_f = _trim_crossings(inside, line, t, f, ins, iso)
    line = np.concatenate([line, cl_line])
    t = np.concatenate([t, cl_t])
    f = np.concatenate([f, cl_f])
    ins = np.concatenate([ins, np.ones(len(cl_t), bool)])
    ins &= (t >= span_lo[line]) & (t <= span_hi[line])  # a partial curve: its span only
    order = np.lexsort((t, line))
    line, t, f, ins = line[order], t[order], f[order], ins[order]
    line, t, f = line[ins], t[ins], f[ins]
    single = np.r_[True, (line[1:] != line[:-1]) | (t[1:] != t[:-1])]  # a crossing on a sample
    line, t, f = line[single], t[single], f[single]
    cl, lift, sel = _tips(jets, query, t, f, iso)
    # a run ends where the trim (an outside stretch) or a check surface interrupts it
    half = 0.5 * tool.tolerance
    gap_ok = np.ones(len(t), bool)  # interval (i, i+1) lies inside the trim
    fresh = np.ones(len(t), bool)  # intervals not yet checked start or end at these
    monitor(lo + 0.5 * (hi - lo))
    for _ in range(REFINE_ROUNDS):
        same = (line[:-1] == line[1:]) & (np.diff(t) > 1e-12 * (a1 - a0)) & gap_ok[:-1]
        same &= fresh[:-1] | fresh[1:]
        idx = np.flatnonzero(same)
        if len(idx) == 0:
            break
        tm = 0.5 * (t[idx] + t[idx + 1])
        fm = f[idx]
        mins = inside(*_uv(tm, fm, iso))
        cm = np.full((len(idx), 3), np.nan)
        lm = np.zeros(len(idx))
        sm = np.zeros(len(idx), bool)
        if mins.any():
            cm[mins], lm[mins], sm[mins] = _tips(jets, query, tm[mins], fm[mins], iso)
        dev = np.linalg.norm(cm - 0.5 * (cl[idx] + cl[idx + 1]), axis=1)
        bad = ~mins | (dev > half)
        if not bad.any():
            break
        # an interval whose midpoint left the trim (a narrow hole) is cut there
        cut_at = idx[~mins]
        gap_ok[cut_at] = False
        add = bad & mins
        line = np.concatenate([line, line[idx][add]])
        t = np.concatenate([t, tm[add]])
        f = np.concatenate([f, fm[add]])
        cl = np.concatenate([cl, cm[add]])
        lift = np.concatenate([lift, lm[add]])
        sel = np.concatenate([sel, sm[add]])
        # a new point inherits its interval's status on both sides
        gap_ok = np.concatenate([gap_ok, gap_ok[idx][add]])
        fresh = np.concatenate([np.zeros(len(fresh), bool), np.ones(int(add.sum()), bool)])
        order = np.lexsort((t, line))
        line, t, f, cl, lift, sel, gap_ok, fresh = (
            a[order] for a in (line, t, f, cl, lift, sel, gap_ok, fresh))
    cut = sel | (lift <= half)
    brk = np.flatnonzero((line[1:] != line[:-1]) | ~gap_ok[:-1] | (cut[1:] != cut[:-1]))
    bounds = np.concatenate([[0], brk + 1, [len(t)]])
    runs = [(a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b - a >= 2 and cut[a]]
    monitor(lo + 0.7 * (hi - lo))
    if not runs:
        return [], fixed, {"edge_curves": len(edge)}
    starts = np.cumsum([0] + [b - a for a, b in runs])
    idx = np.concatenate([np.arange(a, b) for a, b in runs])
    pieces, stats = lifted_runs(query.heights_and_slopes, cl[idx], starts, half, step)
    passes = [(int(line[a]), p) for (a, _b), p in zip(runs, pieces)]
    ordered = zigzag_by_line(passes)
    stats["lifted_points"] = int((lift > tool.tolerance).sum())
    stats["edge_curves"] = len(edge)
    return ordered, fixed, stats


def generate_faces_iso(faceset: FaceSet, tool_diameter: float, scallop: float,
                       tolerance: float, direction: str = "u",
                       progress: ProgressFn = None) -> Toolpath:
    """:func:`iso_faces` with the tool given by its diameter, scallop (cusp height) and
    tolerance (one-sided chordal), all mm, validated here."""
    return iso_faces(faceset, ToolParameters.validate(tool_diameter, scallop, tolerance),
                     direction, progress)


def iso_faces(faceset: FaceSet, tool: ToolParameters, direction: str = "u",
              progress: ProgressFn = None) -> Toolpath:
    """Iso-parametric toolpath (tool-tip positions, mm) of the selected faces of ``faceset``.

    ``tool`` is validated (:meth:`ToolParameters.validate`); ``direction`` names the face
    parameter that varies along a pass ('u' or 'v').  Each selected face is machined by its
    own iso-curves inside its trim; heights are never below the certified drop-cutter over
    every face of the set (check surfaces included).
    """
    started = time.perf_counter()
    iso = _check_direction(direction)
    if not isinstance(faceset, FaceSet):
        raise ParameterError(f"faceset must be a FaceSet, got {type(faceset).__name__}")
    faceset.bounds(selected_only=True)  # refuses an empty selection
    monitor = Monitor(progress, None, "isoparametric")
    monitor(0.0)
    query = FaceQuery(faceset, tool.radius)
    chosen = [k for k, fc in enumerate(faceset.faces) if fc.selected]
    passes: list = []
    per_face: dict = {}
    for j, k in enumerate(chosen):
        lo, hi = 0.9 * j / len(chosen), 0.9 * (j + 1) / len(chosen)
        face = faceset.faces[k]
        ordered, fixed, stats = _face_passes(face, k, faceset, query, tool, iso, monitor, lo, hi)
        passes.extend(ordered)
        steps = np.diff(fixed)
        per_face[face.name] = {
            "iso_values": [float(x) for x in fixed], "passes": len(ordered),
            "edge_curves": stats.pop("edge_curves", 0),
            "parameter_step_min": float(steps.min()) if len(steps) else float("nan"),
            "parameter_step_max": float(steps.max()) if len(steps) else float("nan"),
            "chord_lift": stats}
    lifted = sum(v["chord_lift"].get("lifted_points", 0) for v in per_face.values())
    notes = [f"{lifted} cutter locations lifted to avoid gouging"] if lifted else []
    fits = [name for name, v in per_face.items() if v["chord_lift"].get("collapsed")]
    if fits:
        notes.append(f"the {tool.diameter:g} mm ball fits {', '.join(fits)} across: all "
                     "its iso-curves fall on one line of cutter locations, so iso leaves it; "
                     "finish it by raster or waterline")
    parameters = {"strategy": "isoparametric", "tool_diameter": tool.diameter,
                  "scallop": tool.scallop, "tolerance": tool.tolerance,
                  "direction": "zigzag", "iso_direction": "u" if iso is IsoDirection.U else "v",
                  "faces": [faceset.faces[k].name for k in chosen]}
    extra = {"faces": per_face, "dropcutter": dict(faceset.stats)}
    toolpath = Toolpath("isoparametric", passes, parameters, [], ToolpathStats(notes=notes),
                        extra=extra)
    toolpath.finish(started, None)
    toolpath.links = stay_down_links(query, toolpath.passes, STAY_DOWN_LINK * tool.radius,
                                     tool.tolerance)
    toolpath.finish(started, None)
    monitor(1.0)
    return toolpath


__all__ = ["generate_faces_iso", "iso_faces"]
