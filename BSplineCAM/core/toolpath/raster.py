# SPDX-License-Identifier: LGPL-2.1-or-later
"""Parallel (raster) finishing: vertical cutting planes at any angle, drop-cutter heights.

Pass spacing follows the scallop height: at every dense surface sample the largest XY
stepover that keeps the cusp below h is found from the normal curvature across the pass
(:func:`common.curved_stepover`) and the slope (an arc s along the surface spans s cos(slope)
in XY), and filed under the across-coordinate of its ball centre p + R n.  Each next line
goes at the smallest stepover filed in the band from the current line to it, so the contacts
of both lines and everything between are honoured before any drop-cutter call; then all
lines are computed in one vectorised batch.  Along a pass the exact drop-cutter heights are sampled every sqrt(8 R tol) mm,
where no convex stretch of the cutter-location curve (radius >= R) can sag more than tol,
refined where a midpoint still deviates more than tol/2, and thinned by Douglas–Peucker to
tol/2, so no chord departs from the exact cutter-location curve by more than tol.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..typing import FloatArray
from .chords import ChordSamples, lift_chords
from .common import (
    NEAR_FIT,
    Direction,
    Monitor,
    ToolParameters,
    curved_stepover,
    normal_curvature,
    principal_curvatures,
    simplify,
)
from .dropcutter import DropCutter

#: Rounds of midpoint refinement along a pass.
REFINE_ROUNDS = 6
#: CL slopes (|dz/dx|, |dz/dy|) up to which the cubic Hermite midpoint screens an interval.
GENTLE = 1.0
#: Fraction of the midpoint allowance (tol / 2) below which a screened interval is left alone.
SCREEN = 0.25


def cross_section_stepover(radius: float, scallop: float, kappa: FloatArray, n: FloatArray,
                           across: FloatArray, along: FloatArray,
                           kappa_max: FloatArray | None = None) -> FloatArray:
    """Largest XY distance between passes (mm) leaving cusps at most ``scallop`` high, measured
    vertically as a Z-map (and the verification) sees them.

    Work in the vertical plane across the passes.  There the surface is a curve z(y) of slope
    p = tan(slope across) and z'' = kappa_n (1 + p^2)^(3/2) / cos(phi) (Meusnier; kappa_n the
    normal curvature along the curve's tangent, phi between the curve's principal normal and
    the surface normal n).  A ball moving along a path inclined by beta (the slope along the
    pass) sweeps a cylinder whose section is an ellipse, R across and R / cos(beta) vertically;
    scaling Z by cos(beta) turns it into the circle of radius R and the curve into one of
    slope p cos(beta) and z'' cos(beta), with vertical cusps scaled alike.  There the circular
    cusp formula (:func:`curved_stepover`) applies with the normal cusp
    h_n = h cos(beta) / sqrt(1 + (p cos(beta))^2), which stands h cos(beta) above the scaled
    curve, i.e. h above the real one.  The passes are spaced by their ball centres, which lie
    on the offset curve: the contact arc rho theta becomes (rho - R) theta (concave) or
    (rho + R) theta (convex).
    """
    nz = np.clip(n[:, 2], 1e-3, 1.0)
    p = -(n[:, :2] @ across) / nz  # slope across
    ta = -(n[:, :2] @ along) / nz  # slope along
    cos_b = 1.0 / np.sqrt(1.0 + ta * ta)
    sec = np.sqrt(1.0 + p * p)
    cos_phi = np.clip((nz - p * (n[:, :2] @ across)) / sec, 1e-3, 1.0)
    z2 = kappa * sec ** 3 / cos_phi * cos_b
    p2 = p * cos_b
    sec2 = np.sqrt(1.0 + p2 * p2)
    h_n = scallop * cos_b / sec2
    kappa2 = z2 / sec2 ** 3
    # curved_stepover is the arc between the contacts, rho theta; the passes are spaced by
    # their ball centres, on the offset curve of radius rho -+ R: (1 - kappa R) rho theta.
    spacing = curved_stepover(radius, h_n, kappa2) * np.clip(1.0 - kappa2 * radius, 0.0, None)
    # A hollow the ball fits (a concave radius up to R / (1 - NEAR_FIT), across the passes or,
    # with ``kappa_max`` (the largest concave principal curvature), in any direction) or
    # cannot enter: the centres of its contacts crowd on a curve (the offset surface
    # degenerates), so this bound would shrink to nothing wherever the passes cross it (a
    # 3 mm fillet round a boss's foot and a 6 mm ball: every pass over the plate 0.05 mm
    # apart, 50 times the path).  Such a contact bounds no stepover: the passes that cross
    # the hollow fill it where they cross, those along it leave material (a fillet round a
    # boss is left at the two sides parallel to the passes; the verification's edge band
    # beside the boss's wall shows it), and a hollow the ball cannot enter is reported
    # unreachable.
    fits = kappa2 * radius >= 1.0 - NEAR_FIT
    if kappa_max is not None:
        fits |= np.asarray(kappa_max) * radius >= 1.0 - NEAR_FIT
    spacing = np.where(fits, np.inf, spacing)
    return spacing / sec2


def scallop_line_offsets(b_off: FloatArray, allowed: FloatArray, b0: float, b1: float,
                         tool: ToolParameters, gap: float) -> list[float]:
    """Offsets of the passes from b0 to b1 (mm): each step the least allowed stepover
    ``allowed`` (mm) among the contacts whose offsets ``b_off`` (mm, ascending) lie in the band
    it spans, widened by ``gap`` (mm) each side.  Shared by one net's raster (here) and the
    faces' raster (faces_raster)."""
    lines = [b0]
    b = b0
    # Convex stretches allow more than the flat stepover (the centres lie on the larger
    # offset circle): start from the largest value anywhere and shrink to the band's least.
    widest = min(float(allowed.max(initial=tool.flat_stepover)), tool.radius)
    while b < b1 - 1e-9:
        step = widest
        for _ in range(8):
            lo, hi = np.searchsorted(b_off, [b - gap, b + step + gap])
            need = float(allowed[lo:hi].min()) if hi > lo else step
            if need >= step * 0.999:
                break
            step = need
        b = min(b + step, b1)
        lines.append(b)
    return lines


def lifted_line_runs(query, runs: list[tuple[int, int]], line: np.ndarray, a: FloatArray,
                     xy: FloatArray, z: FloatArray, grad: FloatArray, half: float,
                     monitor: Monitor) -> tuple[list[tuple[int, FloatArray]], dict]:
    """Runs ``(lo, hi)`` of dense cutter locations along raster lines made into passes:
    thinned vertically to ``half`` (mm, Douglas-Peucker), their chords lifted one-sided against
    the drop-cutter ``query`` (:func:`.chords.lift_chords`).  ``a`` (mm along the line), ``xy``,
    ``z`` (mm) and ``grad`` (dz/dx, dz/dy) hold the runs' samples end to end; ``line`` is
    indexed by ``lo``.  Returns [(line index, (n, 3) pass)] and the lift statistics: one net's
    raster (here) and the faces' (faces_raster) end alike."""
    starts = np.cumsum([0] + [hi - lo for lo, hi in runs])
    keep = simplify(np.column_stack([xy, z]), starts, half, "vertical")
    run_id = np.repeat(np.arange(len(runs)), np.diff(starts))
    samples = ChordSamples(a, xy, z, grad, run_id, keep, z.copy())
    monitor(0.85)
    stats = lift_chords(query, samples, half)
    vxy, vz, vline = samples.vertices()
    cuts = np.flatnonzero(np.diff(vline)) + 1
    return [(int(line[lo]), np.column_stack([pxy, pz]))
            for (lo, _hi), pxy, pz in zip(runs, np.split(vxy, cuts), np.split(vz, cuts))], stats


def zigzag_by_line(passes: list[tuple[int, FloatArray]]) -> list[FloatArray]:
    """Passes tagged with their line index, in line order, those of odd lines reversed (each
    and their order along the line): the zig-zag of the rasters and the faces' iso passes."""
    ordered = []
    for k in sorted({k for k, _ in passes}):
        group = [p for kk, p in passes if kk == k]
        if k % 2:
            group = [r[::-1] for r in group[::-1]]
        ordered.extend(group)
    return ordered


class RasterPlanner:
    """State shared by the passes of one raster: frame, drop-cutter and sampling steps."""

    def __init__(self, surface: Any, tool: ToolParameters, angle_deg: float,
                 dropcutter: DropCutter | None = None):
        self.tool = tool
        self.dc = dropcutter or DropCutter(surface, tool.radius)
        theta = math.radians(angle_deg)
        self.along = np.array([math.cos(theta), math.sin(theta)])
        self.across = np.array([-math.sin(theta), math.cos(theta)])
        xy = self.dc.samples[:, :2]
        self.sa = xy @ self.along
        self.sb = xy @ self.across
        order = np.argsort(self.sb)
        self.sb_sorted, self.sa_sorted = self.sb[order], self.sa[order]
        self.b_range = (float(self.sb.min()), float(self.sb.max()))
        self.gap = 1.5 * max(
            float(np.abs(np.diff(self.dc.samples.reshape(self.dc.n_u, self.dc.n_w, 3)[..., :2],
                                 axis=k)).max()) for k in (0, 1))
        self.step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)

    def _extent(self, b: float) -> tuple[float, float] | None:
        lo, hi = np.searchsorted(self.sb_sorted, [b - self.gap, b + self.gap])
        if hi <= lo:
            return None
        a = self.sa_sorted[lo:hi]
        return float(a.min()), float(a.max())

    def _xy(self, a: FloatArray, b: FloatArray) -> FloatArray:
        return a[:, None] * self.along + np.asarray(b)[..., None] * self.across

    def stepover_field(self) -> tuple[FloatArray, FloatArray]:
        """Per dense sample: the across-coordinate of its ball centre (p + R n) and the largest
        XY stepover (mm) keeping the scallop <= h there, sorted by the former."""
        dc, tool = self.dc, self.tool
        uu, ww = np.meshgrid(dc.u, dc.w, indexing="ij")
        jet = dc.jet(uu.ravel(), ww.ravel())
        n = jet.normal
        c = self.across
        nz = np.clip(n[:, 2], 1e-3, 1.0)
        tz = -(n[:, 0] * c[0] + n[:, 1] * c[1]) / nz
        t = np.column_stack([np.full(len(tz), c[0]), np.full(len(tz), c[1]), tz])
        kappa = normal_curvature(jet, t)
        xy = cross_section_stepover(tool.radius, tool.scallop, kappa, n, c, self.along,
                                    principal_curvatures(jet)[1])
        xy = np.maximum(xy, 0.02 * tool.flat_stepover)
        b_off = (jet.p[:, :2] + tool.radius * n[:, :2]) @ c
        order = np.argsort(b_off)
        return b_off[order], xy[order]

    def line_offsets(self) -> list[float]:
        """Offsets of the passes from the first edge to the last (mm), scallop-driven: the
        step to the next line is the smallest allowed stepover among contacts in the band
        the two lines and the strip between them touch."""
        b_off, allowed = self.stepover_field()
        return scallop_line_offsets(b_off, allowed, *self.b_range, self.tool, self.gap)

    def cl_passes(self, offsets: list[float], monitor: Monitor) -> tuple[FloatArray, ...]:
        """Dense cutter locations of all lines at once: (line index, a, tip z, contact u, w)."""
        pieces = []
        for k, b in enumerate(offsets):
            extent = self._extent(b)
            if extent is None:
                continue
            n = max(2, math.ceil((extent[1] - extent[0]) / self.step) + 1)
            pieces.append((np.full(n, k), np.linspace(extent[0], extent[1], n)))
        line = np.concatenate([p[0] for p in pieces])
        a = np.concatenate([p[1] for p in pieces])
        b = np.asarray(offsets)
        z, u, w = self._heights(a, b[line], monitor, 0.0, 0.6)
        slope, steep = self._along_slopes(a, b[line], u, w)
        half = 0.5 * self.tool.tolerance
        fresh = np.ones(len(a), bool)  # intervals not yet checked start at these samples
        for r in range(REFINE_ROUNDS):
            ok = np.isfinite(z[:-1]) & np.isfinite(z[1:]) & (line[:-1] == line[1:])
            idx = np.flatnonzero(ok & (np.diff(a) > 1e-6) & (fresh[:-1] | fresh[1:]))
            # Screen by the cubic Hermite midpoint, whose chord deviation is d (m0 - m1) / 8:
            # where both slopes are gentle (its error d^4 z^(4) / 384 is then below 1e-4 tol)
            # and it predicts less than SCREEN * tol / 2, no exact midpoint is needed.
            d = a[idx + 1] - a[idx]
            predicted = np.abs(d * (slope[idx] - slope[idx + 1])) / 8.0
            smooth = ~(steep[idx] | steep[idx + 1]) & (predicted <= SCREEN * half)
            idx = idx[~smooth]
            if len(idx) == 0:
                break
            am = 0.5 * (a[idx] + a[idx + 1])
            lm = line[idx]
            zm, um, wm = self._heights(am, b[lm], monitor, 0.6 + 0.07 * r, 0.6 + 0.07 * (r + 1))
            bad = np.abs(zm - 0.5 * (z[idx] + z[idx + 1])) > half
            bad &= np.isfinite(zm)
            if not bad.any():
                break
            sm, stm = self._along_slopes(am[bad], b[lm[bad]], um[bad], wm[bad])
            line = np.concatenate([line, lm[bad]])
            a = np.concatenate([a, am[bad]])
            z = np.concatenate([z, zm[bad]])
            u = np.concatenate([u, um[bad]])
            w = np.concatenate([w, wm[bad]])
            slope = np.concatenate([slope, sm])
            steep = np.concatenate([steep, stm])
            fresh = np.concatenate([np.zeros(len(fresh), bool), np.ones(int(bad.sum()), bool)])
            order = np.lexsort((a, line))
            line, a, z, u, w = line[order], a[order], z[order], u[order], w[order]
            slope, steep, fresh = slope[order], steep[order], fresh[order]
        return line, a, z, u, w

    def _along_slopes(self, a: FloatArray, b: FloatArray, u: FloatArray,
                      w: FloatArray) -> tuple[FloatArray, np.ndarray]:
        """Slope of the CL height along the pass, and where the CL surface is too steep (or
        has no height) for a cubic model of it to be trusted."""
        grad = self.dc.slopes(self._xy(a, b), u, w)
        steep = ~(np.abs(grad).max(axis=1) <= GENTLE)  # NaN counts as steep
        return np.nan_to_num(grad @ self.along), steep

    def _heights(self, a: FloatArray, b: FloatArray, monitor: Monitor, f0: float, f1: float):
        """Drop-cutter heights in chunks, reporting progress between f0 and f1."""
        out = [np.empty(len(a)) for _ in range(3)]
        chunk = 16384
        for start in range(0, len(a), chunk):
            sl = slice(start, start + chunk)
            res = self.dc.heights(self._xy(a[sl], b[sl]))
            for o, r in zip(out, res):
                o[sl] = r
            monitor(f0 + (f1 - f0) * min(1.0, (start + chunk) / max(len(a), 1)))
        return out


def raster(surface: Any, tool: ToolParameters, angle_deg: float, direction: Direction,
           monitor: Monitor, dropcutter: DropCutter | None = None) -> tuple[list, dict]:
    """Passes (lists of (n, 3) tip positions) and extra stats for a raster at ``angle_deg``."""
    plan = RasterPlanner(surface, tool, angle_deg, dropcutter)
    offsets = plan.line_offsets()
    line, a, z, _u, _w = plan.cl_passes(offsets, monitor)
    bvals = np.asarray(offsets)
    # Runs of valid heights within each line: split where the ball meets no surface.
    brk = np.flatnonzero((line[1:] != line[:-1]) | (np.isfinite(z[1:]) != np.isfinite(z[:-1])))
    bounds = np.concatenate([[0], brk + 1, [len(z)]])
    runs = [(lo, hi) for lo, hi in zip(bounds[:-1], bounds[1:])
            if hi - lo >= 2 and np.isfinite(z[lo])]
    passes: list = []
    lift_stats: dict = {}
    if runs:
        idx = np.concatenate([np.arange(lo, hi) for lo, hi in runs])
        xy = plan._xy(a[idx], bvals[line[idx]])
        passes, lift_stats = lifted_line_runs(
            plan.dc.heights_and_slopes, runs, line, a[idx], xy, z[idx],
            plan.dc.slopes(xy, _u[idx], _w[idx]), 0.5 * tool.tolerance, monitor)
    monitor(1.0)
    ordered = (zigzag_by_line(passes) if direction is Direction.ZIGZAG
               else [p for _, p in passes])
    steps = np.diff(bvals)
    extra = {
        "stepover_min_mm": float(steps.min()) if len(steps) else float("nan"),
        "stepover_max_mm": float(steps.max()) if len(steps) else float("nan"),
        "line_offsets_mm": bvals.tolist(),
        "angle_frame": (plan.along.tolist(), plan.across.tolist()),
        "chord_lift": lift_stats,
    }
    return ordered, extra
