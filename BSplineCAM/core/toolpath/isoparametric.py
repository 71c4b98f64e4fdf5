# SPDX-License-Identifier: LGPL-2.1-or-later
"""Iso-parametric finishing: passes along u (or w) curves, the ball offset along the normal.

The tip follows CL = S + R n - R z (the ball centre on the offset surface, Farouki 1986),
lifted to the exact drop-cutter height wherever the offset point would make the ball cut
elsewhere (concave radius below R, or a neighbouring wall), so nothing is gouged.  The next
iso-curve is placed where the surface distance across the pass reaches the curvature-adjusted
stepover s (:func:`common.curved_stepover`): dw = s / |Sw . t| with t the unit tangent across
the pass, taken at its smallest along both curves.  Points along a pass are refined at chord
midpoints and thinned by Douglas–Peucker to tolerance / 2 in 3-D; then each chord is checked
against the exact drop-cutter and its ends lifted where it would dip (:mod:`chords`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import ParameterError
from ..typing import FloatArray
from .chords import lift_chords, sample_chords
from .common import (
    Direction,
    IsoDirection,
    Monitor,
    ToolParameters,
    curved_stepover,
    normal_curvature,
    simplify,
)
from .dropcutter import DropCutter

#: A lift (mm) up to which a tip counts as on the offset curve (the drop-cutter height there
#: agrees with the offset point up to rounding).
ON_OFFSET = 1e-9
#: Fraction of the midpoint allowance (tol / 2) below which a pass interval whose cubic
#: Hermite model predicts no more is left without an exact midpoint.
SCREEN = 0.25
#: A pass's tangent shorter than this fraction of the curve's longest tangent or cross
#: derivative marks a point where the curve degenerates (a pole): it sets no step across.
DEGENERATE = 1e-6
#: Most iso-curves across one surface or face: more means a step that creeps (bounded time).
MAX_CURVES = 20_000


def _uw(along: FloatArray, fixed: FloatArray, iso: IsoDirection) -> tuple[FloatArray, FloatArray]:
    return (along, fixed) if iso is IsoDirection.U else (fixed, along)


def _cl(dc: DropCutter, along: FloatArray, fixed: FloatArray, iso: IsoDirection,
        radius: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Tip points (m, 3), how far each was lifted to the drop-cutter height (mm), and the
    derivative of the offset curve S + R n - R z along the pass (mm per parameter unit).

    The normal's derivative comes from that of N = Su x Sw (n = N / |N|, so
    n' = (N' - n (n . N')) / |N|), with the second derivatives of the jet.
    """
    u, w = _uw(along, fixed, iso)
    jet = dc.jet(u, w)
    cl = jet.p + radius * jet.normal
    cl[:, 2] -= radius
    drop = dc.heights(cl[:, :2])[0]
    lift = np.where(np.isfinite(drop), np.maximum(drop - cl[:, 2], 0.0), 0.0)
    cl[:, 2] += lift
    if iso is IsoDirection.U:
        s_t, su_t, sw_t = jet.su, jet.suu, jet.suw
    else:
        s_t, su_t, sw_t = jet.sw, jet.suw, jet.sww
    big_n = np.cross(jet.su, jet.sw)
    length = np.maximum(np.linalg.norm(big_n, axis=1, keepdims=True), 1e-300)
    dn = np.cross(su_t, jet.sw) + np.cross(jet.su, sw_t)
    unit = big_n / length
    dn = jet.sign * (dn - unit * np.einsum("ij,ij->i", unit, dn)[:, None]) / length
    return cl, lift, s_t + radius * dn


def lifted_runs(query, cl: FloatArray, starts: np.ndarray, half: float,
                step: float) -> tuple[list[FloatArray], dict]:
    """The runs ``cl[starts[k]:starts[k + 1]]`` of cutter locations (mm) thinned to ``half``
    (mm, Douglas-Peucker by distance), their chords sampled every ``step`` (mm) and lifted
    one-sided against the drop-cutter ``query`` (:func:`.chords.lift_chords`): one (n, 3)
    polyline per run and the lift statistics.  One net's iso-parametric passes (here) and the
    faces' (faces_iso) end alike."""
    keep = simplify(cl, starts, half, "distance")
    raw = [cl[a:b][keep[a:b]] for a, b in zip(starts[:-1], starts[1:])]
    samples = sample_chords(query, raw, [p[:, 2] for p in raw], step)
    stats = lift_chords(query, samples, half)
    vxy, vz, vline = samples.vertices()
    cuts = np.flatnonzero(np.diff(vline)) + 1
    return [np.column_stack([pxy, pz])
            for pxy, pz in zip(np.split(vxy, cuts), np.split(vz, cuts))], stats


def too_many_curves(count: int, what: str) -> None:
    """Refuse a scallop that would need more than MAX_CURVES iso-curves across ``what``."""
    if count > MAX_CURVES:
        raise ParameterError(
            f"{what} needs more than {MAX_CURVES} iso-curves across it at this scallop: use a "
            "larger scallop, or raster for a face this large or this degenerate")


def _allowed_step(dc: DropCutter, tool: ToolParameters, along: FloatArray, fixed: float,
                  iso: IsoDirection) -> float:
    """Largest parameter step across the pass keeping the scallop <= h along this curve."""
    u, w = _uw(along, np.full(len(along), fixed), iso)
    jet = dc.jet(u, w)
    tangent = jet.su if iso is IsoDirection.U else jet.sw
    cross_d = jet.sw if iso is IsoDirection.U else jet.su
    # a curve shrunk to a point there (a pole: a sphere's, a cone's apex) bounds nothing: its
    # normal curvature is 0/0 (it gave steps of 1e-16 and an endless loop)
    speed = np.linalg.norm(tangent, axis=1)
    scale = max(float(speed.max(initial=0.0)),
                float(np.linalg.norm(cross_d, axis=1).max(initial=0.0)), 1e-300)
    live = speed > DEGENERATE * scale
    if not live.any():
        return math.inf
    n = jet.normal
    t = np.cross(n, tangent)
    t /= np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300)
    kappa = normal_curvature(jet, t)
    # Cusps are measured vertically (as a Z-map sees them): h_n along the normal stands
    # h_n / n_z above the surface, so aim for h_n = h n_z.
    s = curved_stepover(tool.radius, tool.scallop * np.clip(n[:, 2], 1e-3, 1.0), kappa)
    rate = np.abs(np.einsum("ij,ij->i", cross_d, t))
    return float((s / np.maximum(rate, 1e-12))[live].min())


def isoparametric(surface: Any, tool: ToolParameters, iso: IsoDirection, direction: Direction,
                  monitor: Monitor, dc: DropCutter) -> tuple[list, dict]:
    """Passes of constant w (iso='u') or constant u (iso='w'), tips in mm."""
    coarse = surface.grid(33, 33)
    axis = 0 if iso is IsoDirection.U else 1
    length = float(np.linalg.norm(np.diff(coarse, axis=axis), axis=-1).sum(axis=axis).max())
    step = min(math.sqrt(8.0 * tool.radius * tool.tolerance), tool.radius / 2.0)
    n = max(8, math.ceil(length / step) + 1)
    along = np.linspace(0.0, 1.0, n)
    probe = np.linspace(0.0, 1.0, max(65, n // 4))
    # Positions of the iso-curves across, scallop-driven, checked on both neighbours.
    fixed = [0.0]
    while fixed[-1] < 1.0:
        c = fixed[-1]
        d = _allowed_step(dc, tool, probe, c, iso)
        for _ in range(6):
            nxt = min(c + d, 1.0)
            d2 = _allowed_step(dc, tool, probe, nxt, iso)
            if d2 >= 0.999 * (nxt - c):
                break
            d = d2
        fixed.append(min(c + d, 1.0))
        too_many_curves(len(fixed), "the surface")
        monitor(0.4 * fixed[-1])
    lines = np.repeat(np.arange(len(fixed)), n)
    t = np.tile(along, len(fixed))
    f = np.asarray(fixed)[lines]
    cl, lift, dcl = _cl(dc, t, f, iso, tool.radius)
    monitor(0.7)
    half = 0.5 * tool.tolerance
    fresh = np.ones(len(t), bool)  # intervals not yet checked start or end at these
    for _ in range(6):
        ok = lines[:-1] == lines[1:]
        idx = np.flatnonzero(ok & (np.diff(t) > 1e-9) & (fresh[:-1] | fresh[1:]))
        # Screen by the cubic Hermite midpoint of the offset curve, off the chord by
        # dt (c0' - c1') / 8: where neither end was lifted and it predicts less than
        # SCREEN * tol / 2, no exact midpoint is needed (the chord check below still holds
        # every chord to the exact drop-cutter height).
        dt = (t[idx + 1] - t[idx])[:, None]
        predicted = np.linalg.norm(dt * (dcl[idx] - dcl[idx + 1]), axis=1) / 8.0
        on_offset = np.maximum(lift[idx], lift[idx + 1]) <= ON_OFFSET
        smooth = on_offset & (predicted <= SCREEN * half)
        idx = idx[~smooth]
        if len(idx) == 0:
            break
        tm = 0.5 * (t[idx] + t[idx + 1])
        cm, lm, dm = _cl(dc, tm, f[idx], iso, tool.radius)
        dev = np.linalg.norm(cm - 0.5 * (cl[idx] + cl[idx + 1]), axis=1)
        bad = dev > half
        if not bad.any():
            break
        lines = np.concatenate([lines, lines[idx][bad]])
        t = np.concatenate([t, tm[bad]])
        f = np.concatenate([f, f[idx][bad]])
        cl = np.concatenate([cl, cm[bad]])
        lift = np.concatenate([lift, lm[bad]])
        dcl = np.concatenate([dcl, dm[bad]])
        fresh = np.concatenate([np.zeros(len(fresh), bool), np.ones(int(bad.sum()), bool)])
        order = np.lexsort((t, lines))
        lines, t, f, cl, lift = lines[order], t[order], f[order], cl[order], lift[order]
        dcl, fresh = dcl[order], fresh[order]
    monitor(0.9)
    starts = np.concatenate([[0], np.flatnonzero(np.diff(lines)) + 1, [len(lines)]])
    pieces, lift_stats = lifted_runs(dc.heights_and_slopes, cl, starts, half, step)
    passes = [p[::-1] if direction is Direction.ZIGZAG and k % 2 else p
              for k, p in enumerate(pieces)]
    steps = np.diff(fixed)
    lifted = int((lift > tool.tolerance).sum())
    notes = [f"{lifted} cutter locations lifted to avoid gouging"] if lifted else []
    return passes, {
        "stepover_min_mm": float("nan"), "stepover_max_mm": float("nan"),
        "parameter_step_min": float(steps.min()), "parameter_step_max": float(steps.max()),
        "iso_values": fixed, "lifted_points": lifted, "notes": notes, "chord_lift": lift_stats,
    }
