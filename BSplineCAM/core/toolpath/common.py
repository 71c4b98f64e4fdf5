# SPDX-License-Identifier: LGPL-2.1-or-later
"""Shared pieces of the ball-end finishing strategies: validation, data, geometry helpers.

Everything here is plain data in, plain data out (numpy arrays and dataclasses); the app layer
turns a :class:`Toolpath` into ``Path.Command`` lists through :func:`to_moves`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from enum import Enum
from typing import Any, Callable, NamedTuple, Optional

import numpy as np

from ..errors import BSplineCAMError, ParameterError
from ..geometry.footprint import footprint_bounds
from ..typing import FloatArray
from ..validation import (  # noqa: F401  (re-exported: the toolpath modules take them from here)
    check_finite,
    check_positive,
    check_range,
    parse_enum,
)
from .links import join_links
from .primitives import Jet, max_into, min_into, upward_sign  # noqa: F401  (re-exported)

#: Valid range of the chordal tolerance (mm).
TOLERANCE_RANGE = (1e-5, 1.0)
#: Smallest and largest ball diameter (mm); the part's footprint bounds it further.
MIN_TOOL_DIAMETER = 0.01
MAX_TOOL_DIAMETER = 1000.0

ProgressFn = Optional[Callable[[float], Any]]
CancelFn = Optional[Callable[[], bool]]


class Strategy(str, Enum):
    """Finishing strategies of issue 4, steep-and-shallow (issue 12): waterline on the
    walls steeper than a slope threshold, raster on the rest, and constant scallop (faces
    only): passes offset inwards from the selected faces' border, each by the stepover that
    leaves the scallop (:mod:`.faces_scallop`)."""

    RASTER = "raster"
    WATERLINE = "waterline"
    ISOPARAMETRIC = "isoparametric"
    STEEP_SHALLOW = "steep_shallow"
    SCALLOP = "scallop"


class Direction(str, Enum):
    """Raster pass order: alternate sense (zigzag) or always the same sense (oneway)."""

    ZIGZAG = "zigzag"
    ONEWAY = "oneway"


class IsoDirection(str, Enum):
    """Parameter that varies along an iso-parametric pass."""

    U = "u"
    W = "w"


class ToolpathCancelled(BSplineCAMError):
    """Raised when the ``cancel`` callback asks to stop; the message says how far it got."""


#: Raster angle range (degrees): any direction is reachable within one turn either way.
ANGLE_RANGE = (-360.0, 360.0)
#: Feed range (mm/min): below 0.1 a post-processor's 3 decimals of mm/min (or 4 of mm/s)
#: would write F0; above 100 m/min no machining centre follows.
FEED_RANGE = (0.1, 100_000.0)
#: Spindle speed range (rpm).
SPINDLE_RANGE = (1.0, 200_000.0)
#: Rapid traverse range (mm/min).
RAPID_RANGE = (1.0, 1_000_000.0)


def check_angle(angle: Any, argument: str = "angle") -> float:
    """Raster pass direction from +X, a finite angle in [-360, 360] degrees."""
    return check_range(angle, argument, "degrees", *ANGLE_RANGE)


@dataclass(frozen=True)
class CuttingParameters:
    """Validated feeds (mm/min) and spindle speed (rpm) of a finishing job."""

    feed: float
    plunge_feed: float
    spindle: float
    rapid: float

    @classmethod
    def validate(cls, feed: Any, plunge_feed: Any, spindle: Any, rapid: Any,
                 names: tuple[str, str, str, str] = ("feed", "plunge_feed", "spindle", "rapid"),
                 ) -> CuttingParameters:
        """Each value finite and within FEED_RANGE, SPINDLE_RANGE or RAPID_RANGE; the error
        names the argument (``names``) and its unit."""
        return cls(check_range(feed, names[0], "mm/min", *FEED_RANGE),
                   check_range(plunge_feed, names[1], "mm/min", *FEED_RANGE),
                   check_range(spindle, names[2], "rpm", *SPINDLE_RANGE),
                   check_range(rapid, names[3], "mm/min", *RAPID_RANGE))


def check_tool_fits(surface: Any, tool_diameter: float, argument: str = "tool_diameter") -> None:
    """One rule for the toolpath and the verification: the tool must be smaller than the
    part's XY footprint in both directions (mm)."""
    x0, x1, y0, y1 = footprint_bounds(surface)
    if not tool_diameter < min(x1 - x0, y1 - y0):
        raise ParameterError(
            f"{argument} {tool_diameter:g} mm is not smaller than the part "
            f"({x1 - x0:.3g} x {y1 - y0:.3g} mm footprint)")


@dataclass(frozen=True)
class ToolParameters:
    """The ball-end tool of a finishing request, validated once where the request comes in
    (:meth:`validate`) and passed down as is: diameter D (radius R = D / 2), scallop h and
    chordal tolerance (all mm)."""

    diameter: float
    scallop: float
    tolerance: float

    @property
    def radius(self) -> float:
        """Ball radius R = D / 2 (mm)."""
        return self.diameter / 2.0

    @classmethod
    def validate(cls, tool_diameter: Any, scallop: Any, tolerance: Any,
                 names: tuple[str, str, str] = ("tool_diameter", "scallop", "tolerance"),
                 ) -> ToolParameters:
        """Diameter in [MIN_TOOL_DIAMETER, MAX_TOOL_DIAMETER], scallop in (0, radius],
        tolerance in TOLERANCE_RANGE (all mm); errors name the argument (``names``)."""
        diameter = check_positive(tool_diameter, names[0], "mm")
        if not MIN_TOOL_DIAMETER <= diameter <= MAX_TOOL_DIAMETER:
            raise ParameterError(
                f"{names[0]} must lie in [{MIN_TOOL_DIAMETER:g}, {MAX_TOOL_DIAMETER:g}] mm, "
                f"got {diameter:g} mm")
        radius = diameter / 2.0
        h = check_positive(scallop, names[1], "mm")
        if h > radius:
            raise ParameterError(
                f"{names[1]} must not exceed the tool radius ({radius:g} mm), got {h:g} mm"
            )
        tol = check_positive(tolerance, names[2], "mm")
        lo, hi = TOLERANCE_RANGE
        if not lo <= tol <= hi:
            raise ParameterError(f"{names[2]} must lie in [{lo:g}, {hi:g}] mm, got {tol:g} mm")
        return cls(diameter, h, tol)

    @property
    def flat_stepover(self) -> float:
        """Stepover on a flat: s = 2 sqrt(2Rh - h^2) (mm)."""
        return flat_stepover(self.radius, self.scallop)


# -- scallop geometry ---------------------------------------------------------------------------
#: Share of the ball's curvature within which a concave cross-section counts as one the ball
#: fits (a concave radius up to R / (1 - NEAR_FIT)): such a hollow bounds neither a raster's
#: stepover (:func:`.raster.cross_section_stepover`) nor a waterline's step-down
#: (:func:`.waterline.level_steps`).
NEAR_FIT = 0.05


def flat_stepover(radius: float, scallop: float) -> float:
    """Distance between passes on a plane leaving cusps of height h: 2 sqrt(2Rh - h^2) (mm)."""
    return 2.0 * math.sqrt(max(2.0 * radius * scallop - scallop * scallop, 0.0))


def curved_stepover(radius: float, scallop: float, curvature: FloatArray) -> FloatArray:
    """Arc length between passes on a surface of normal curvature ``curvature`` (1/mm).

    Sign convention: curvature > 0 is concave (the surface bends towards its upward normal).
    In the plane across the passes the ball centres lie on a circle of radius rho + R (convex)
    or rho - R (concave) about the centre of curvature; the cusp lies at distance rho + h
    (resp. rho - h) from it and R from either centre, so by the law of cosines

        convex:   cos(theta/2) = ((rho+R)^2 + (rho+h)^2 - R^2) / (2 (rho+R)(rho+h))
        concave:  cos(theta/2) = ((rho-R)^2 + (rho-h)^2 - R^2) / (2 (rho-R)(rho-h))

    and the stepover is s = rho * theta (Lin & Koren 1996; Suresh & Yang 1994).  As rho grows
    both tend to the flat 2 sqrt(2Rh - h^2).  Where a concave rho <= R the ball cannot follow
    the surface; the flat value is returned there (those regions are reported separately).
    ``scallop`` may be an array broadcasting against ``curvature``.
    """
    R = float(radius)
    kappa = np.asarray(curvature, dtype=float)
    h = np.broadcast_to(np.asarray(scallop, dtype=float), kappa.shape)
    flat = 2.0 * np.sqrt(np.maximum(2.0 * R * h - h * h, 0.0))
    out = flat.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = 1.0 / np.abs(kappa)
        convex = (kappa < 0) & (rho < 1e7)
        concave = (kappa > 0) & (rho > R * (1 + 1e-9)) & (rho < 1e7)
        r, hh = rho[convex], h[convex]
        c = ((r + R) ** 2 + (r + hh) ** 2 - R * R) / (2 * (r + R) * (r + hh))
        out[convex] = 2 * r * np.arccos(np.clip(c, -1.0, 1.0))
        r, hh = rho[concave], h[concave]
        c = ((r - R) ** 2 + (r - hh) ** 2 - R * R) / (2 * (r - R) * (r - hh))
        out[concave] = 2 * r * np.arccos(np.clip(c, -1.0, 1.0))
    # Where the arccos loses precision (nearly flat), keep the flat value.
    bad = ~np.isfinite(out) | (out <= 0)
    out[bad] = flat[bad]
    return out


def normal_curvature(jet: Jet, direction: FloatArray) -> FloatArray:
    """Normal curvature II(t)/I(t) (1/mm) in the tangent direction nearest ``direction`` (3-vectors).

    Positive means concave (the surface bends towards the upward normal), as in
    :func:`curved_stepover`.  The direction is projected on the tangent plane and written in
    (Su, Sw) by the first fundamental form (do Carmo, section 3-2).
    """
    n = jet.normal
    d = np.asarray(direction, dtype=float)
    d = d - np.einsum("ij,ij->i", d, n)[:, None] * n
    E = np.einsum("ij,ij->i", jet.su, jet.su)
    F = np.einsum("ij,ij->i", jet.su, jet.sw)
    G = np.einsum("ij,ij->i", jet.sw, jet.sw)
    bu = np.einsum("ij,ij->i", d, jet.su)
    bw = np.einsum("ij,ij->i", d, jet.sw)
    det = E * G - F * F
    det = np.where(np.abs(det) > 0, det, 1.0)
    a = (G * bu - F * bw) / det
    b = (E * bw - F * bu) / det
    L = np.einsum("ij,ij->i", jet.suu, n)
    M = np.einsum("ij,ij->i", jet.suw, n)
    N = np.einsum("ij,ij->i", jet.sww, n)
    first = E * a * a + 2 * F * a * b + G * b * b
    second = L * a * a + 2 * M * a * b + N * b * b
    return second / np.where(first > 0, first, 1.0)


def principal_curvatures(jet: Jet) -> tuple[FloatArray, FloatArray]:
    """(k_min, k_max) in 1/mm from the shape operator; positive = concave (bends to the normal)."""
    n = jet.normal
    E = np.einsum("ij,ij->i", jet.su, jet.su)
    F = np.einsum("ij,ij->i", jet.su, jet.sw)
    G = np.einsum("ij,ij->i", jet.sw, jet.sw)
    L = np.einsum("ij,ij->i", jet.suu, n)
    M = np.einsum("ij,ij->i", jet.suw, n)
    N = np.einsum("ij,ij->i", jet.sww, n)
    det = E * G - F * F
    det = np.where(det > 0, det, np.inf)
    H = (E * N - 2 * F * M + G * L) / (2 * det)
    K = (L * N - M * M) / det
    disc = np.sqrt(np.maximum(H * H - K, 0.0))
    return H - disc, H + disc


# -- unreachable regions ------------------------------------------------------------------------
@dataclass(frozen=True)
class Region:
    """A connected patch the ball cannot reach: concave radius of curvature below R.

    Boxes in parameters (u, w in [0, 1]) and model XY (mm); ``min_radius_mm`` is the tightest
    concave radius found there.
    """

    u_range: tuple[float, float]
    w_range: tuple[float, float]
    x_range: tuple[float, float]
    y_range: tuple[float, float]
    min_radius_mm: float

    def as_dict(self) -> dict:
        return {
            "u_range": list(self.u_range), "w_range": list(self.w_range),
            "x_range": list(self.x_range), "y_range": list(self.y_range),
            "min_radius_mm": self.min_radius_mm,
        }


def label_regions(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """4-connected components of a 2-D boolean mask: (labels, count), -1 off the mask, the
    components numbered in the row-major order of their first cell.

    The mask's runs along the rows are the nodes; a run is joined to the runs of the next row
    that share a column with it (a contiguous range of them, found by binary search), and
    each run takes the least index of its component (the runs in order, so that least run
    holds the first cell) by hooking and pointer jumping over those few nodes."""
    mask = np.asarray(mask, bool)
    rows, cols = mask.shape
    out = np.full(mask.shape, -1)
    if not mask.any():
        return out, 0
    width = cols + 2
    padded = np.zeros((rows, width), np.int8)
    padded[:, 1:-1] = mask
    edge = np.diff(padded, axis=1)  # +1 where a run starts, -1 just past its end
    row, first = np.nonzero(edge == 1)
    _, stop = np.nonzero(edge == -1)
    start = row * width + first  # row-major keys, increasing with the run's index
    end = row * width + stop
    lo = np.searchsorted(end, start + width, side="right")  # next row's runs ending past it
    hi = np.searchsorted(start, end + width, side="left")  # ... and starting before its end
    count = np.maximum(hi - lo, 0)
    a = np.repeat(np.arange(len(row)), count)
    b = np.repeat(lo - np.cumsum(count) + count, count) + np.arange(int(count.sum()))
    root = np.arange(len(row))
    while len(a):
        # hook the larger root of every edge joining two trees under the smaller one (each
        # root under the least offered), then compress every path to its root: a few rounds
        # even along a spiral (Shiloach & Vishkin 1982)
        ra, rb = root[a], root[b]
        apart = ra != rb
        if not apart.any():
            break
        a, b = a[apart], b[apart]
        upper = np.maximum(ra[apart], rb[apart])
        lower = np.minimum(ra[apart], rb[apart])
        order = np.argsort(upper, kind="stable")
        min_into(root, upper[order], lower[order])
        while True:
            up = root[root]
            if np.array_equal(up, root):
                break
            root = up
    unique, comp = np.unique(root, return_inverse=True)
    out[mask] = np.repeat(comp.ravel(), stop - first)
    return out, len(unique)


def unreachable_regions(surface: Any, radius: float, sign: float | None = None,
                        samples: int = 201) -> list[Region]:
    """Regions whose largest concave principal curvature exceeds 1/R, on a parameter grid."""
    u = np.linspace(0.0, 1.0, samples)
    uu, ww = np.meshgrid(u, u, indexing="ij")
    sign = upward_sign(surface) if sign is None else sign
    jet = Jet.at(surface, uu.ravel(), ww.ravel(), sign)
    _, kmax = principal_curvatures(jet)
    kmax = kmax.reshape(samples, samples)
    mask = kmax > 1.0 / radius
    if not mask.any():
        return []
    labels, count = label_regions(mask)
    pts = jet.p.reshape(samples, samples, 3)
    regions = []
    for k in range(count):
        sel = labels == k
        pu, pw = uu[sel], ww[sel]
        xy = pts[sel]
        step = 1.0 / (samples - 1)
        regions.append(Region(
            (max(0.0, float(pu.min()) - step), min(1.0, float(pu.max()) + step)),
            (max(0.0, float(pw.min()) - step), min(1.0, float(pw.max()) + step)),
            (float(xy[:, 0].min()), float(xy[:, 0].max())),
            (float(xy[:, 1].min()), float(xy[:, 1].max())),
            float(1.0 / kmax[sel].max()),
        ))
    return regions


# -- polylines ----------------------------------------------------------------------------------
def split_runs(valid: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) index ranges of consecutive True entries."""
    v = np.concatenate([[False], np.asarray(valid, bool), [False]])
    edges = np.flatnonzero(v[1:] != v[:-1])
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist()))


def simplify(points: FloatArray, starts: np.ndarray, tolerance: float, metric: str) -> np.ndarray:
    """Douglas–Peucker (1973) on many polylines at once; returns the mask of kept points.

    ``points`` holds all polylines back to back, ``starts`` the first index of each (plus the
    end).  Each round splits every segment whose worst interior point deviates more than
    ``tolerance``, at that point, for all polylines in one vectorised step.  ``metric``:
    'vertical' (z of the chord at the point's XY position along it, for drop-cutter passes),
    'distance' (3-D distance to the chord) or 'planar' (XY distance, for waterlines).
    """
    n = len(points)
    keep = np.zeros(n, bool)
    keep[starts[:-1]] = True
    keep[starts[1:] - 1] = True
    while True:
        kept = np.flatnonzero(keep)
        free = np.flatnonzero(~keep)
        if len(free) == 0:
            break
        pos = np.searchsorted(kept, free)
        a = points[kept[pos - 1]]
        b = points[kept[pos]]
        p = points[free]
        dev = chord_deviation(a, b, p, metric)
        seg = pos  # free points between the same kept pair share pos (non-decreasing)
        worst = np.full(len(kept) + 1, -np.inf)
        max_into(worst, seg, dev)
        bad = dev > tolerance
        bad &= dev >= worst[seg]
        if not bad.any():
            break
        cand, hit = free[bad], seg[bad]
        first = np.r_[True, hit[1:] != hit[:-1]]  # the first worst point of each segment
        keep[cand[first]] = True
    return keep


def chord_deviation(a: FloatArray, b: FloatArray, p: FloatArray, metric: str) -> FloatArray:
    """Deviation of points p from chords a-b (mm) in the given metric (see :func:`simplify`)."""
    if metric == "distance":
        ab = b - a
        t = np.einsum("ij,ij->i", p - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-300)
        t = np.clip(t, 0.0, 1.0)
        return np.linalg.norm(a + t[:, None] * ab - p, axis=1)
    ab = b[:, :2] - a[:, :2]
    t = np.einsum("ij,ij->i", p[:, :2] - a[:, :2], ab) / np.maximum(
        np.einsum("ij,ij->i", ab, ab), 1e-300)
    t = np.clip(t, 0.0, 1.0)
    if metric == "planar":
        return np.linalg.norm(a[:, :2] + t[:, None] * ab - p[:, :2], axis=1)
    return np.abs(a[:, 2] + t * (b[:, 2] - a[:, 2]) - p[:, 2])


# -- result -------------------------------------------------------------------------------------
@dataclass
class ToolpathStats:
    """Summary numbers: counts, cutting length (mm), compute time (s), stepover range (mm)."""

    passes: int = 0
    moves: int = 0
    points: int = 0
    cutting_length_mm: float = 0.0
    seconds: float = 0.0
    stepover_min_mm: float = float("nan")
    stepover_max_mm: float = float("nan")
    notes: list = field(default_factory=list)


@dataclass
class Toolpath:
    """Finishing passes as tool-TIP positions (mm, model coordinates), in machining order.

    ``passes`` is a list of (n, 3) float arrays, each cut as straight feed moves.  ``links``
    (when not empty) holds, per gap between consecutive passes, a stay-down feed polyline from
    one pass's end to the next one's start, or None where the tool retracts; :func:`to_moves`
    turns both into moves.
    """

    strategy: str
    passes: list
    parameters: dict
    unreachable: list
    stats: ToolpathStats
    clearance_height: float = float("nan")
    extra: dict = field(default_factory=dict)
    links: list = field(default_factory=list)

    def finish(self, started: float, clearance_height: float | None) -> Toolpath:
        self.passes = [np.ascontiguousarray(p, dtype=float) for p in self.passes if len(p) >= 2]
        st = self.stats
        st.passes = len(self.passes)
        st.moves = int(sum(len(p) - 1 for p in self.passes))
        st.points = int(sum(len(p) for p in self.passes))
        cut = [*self.passes, *(lk for lk in self.links if lk is not None)]
        st.moves = int(sum(len(p) - 1 for p in cut))
        st.cutting_length_mm = float(
            sum(np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p in cut))
        top = max((float(p[:, 2].max()) for p in self.passes), default=0.0)
        if clearance_height is None:
            self.clearance_height = top + 5.0
        else:
            clear = check_finite(clearance_height, "clearance_height", "mm")
            if clear <= top:
                raise ParameterError(
                    f"clearance_height must lie above the highest cutter location "
                    f"({top:.3f} mm), got {clear:g} mm")
            self.clearance_height = clear
        self.parameters["clearance_height"] = self.clearance_height
        st.seconds = time.perf_counter() - started
        return self


class Move(NamedTuple):
    """One motion: ``kind`` is 'rapid' or 'feed'; x, y, z the end point (mm)."""

    kind: str
    x: float
    y: float
    z: float


def to_moves(toolpath: Toolpath, clearance_height: float | None = None,
             safe_height: float | None = None, hops: Any = None) -> list[Move]:
    """Flat list of moves: per pass rapid to clearance above the start, rapid down to the safe
    height, feed down to the start, feed along the pass, rapid back up to clearance.  Where the
    toolpath has a stay-down link to the next pass, the tool feeds along it instead of
    retracting; where ``hops`` (:class:`.retracts.Hops`) gives a gap a travel height, the tool
    climbs only to it, crosses, comes down rapidly to the hop's approach height and feeds
    from there.  Its ``entry`` heights, where given, lower the rapid descent from the
    clearance plane (never raise it).

    ``clearance_height`` (absolute Z, mm; default the toolpath's) must clear every pass;
    ``safe_height`` (absolute Z, mm) is where the rapid descent stops and the plunge feed starts
    (default 1 mm above each pass start, never above clearance).
    """
    clear = toolpath.clearance_height if clearance_height is None else check_finite(
        clearance_height, "clearance_height", "mm")
    top = max((float(p[:, 2].max()) for p in toolpath.passes), default=-math.inf)
    if not clear > top:
        raise ParameterError(
            f"clearance_height must lie above the highest cutter location ({top:.3f} mm), "
            f"got {clear:g} mm")
    if safe_height is not None:
        safe_height = check_finite(safe_height, "safe_height", "mm")
        if safe_height > clear:
            raise ParameterError(f"safe_height ({safe_height:g} mm) must not exceed "
                                 f"clearance_height ({clear:g} mm)")
    moves: list[Move] = []
    # a stay-down link may have lifted its end vertices: the pass ends and starts there
    passes = [p.copy() for p in toolpath.passes]
    links = [None if lk is None else np.array(lk, dtype=float) for lk in
             (toolpath.links or [None] * max(len(passes) - 1, 0))]
    join_links(passes, links[: max(len(passes) - 1, 0)])
    travel = approach_at = entry = None
    if hops is not None:
        travel, approach_at = np.asarray(hops.travel, float), np.asarray(hops.approach, float)
        if len(travel) != max(len(passes) - 1, 0):
            raise ParameterError(f"hops: {len(travel)} gaps given for {len(passes)} passes")
        if getattr(hops, "entry", None) is not None:
            entry = np.asarray(hops.entry, float)
            if len(entry) != len(passes):
                raise ParameterError(f"hops: {len(entry)} entries given for {len(passes)} "
                                     "passes")
    linked = False
    hop = math.nan
    for k, p in enumerate(passes):
        x0, y0, z0 = (float(v) for v in p[0])
        if not linked:
            top = clear if math.isnan(hop) else hop
            moves.append(Move("rapid", x0, y0, top))
            if not math.isnan(hop):
                approach = float(approach_at[k - 1])
            else:
                approach = min(clear, z0 + 1.0) if safe_height is None else max(safe_height, z0)
                if entry is not None and math.isfinite(entry[k]):
                    approach = max(min(approach, float(entry[k])), z0)
            if approach < top:
                moves.append(Move("rapid", x0, y0, approach))
            if approach > z0:
                moves.append(Move("feed", x0, y0, z0))
        # tolist: Python floats at once (iterating the rows makes a float per element)
        moves.extend(Move("feed", x, y, z) for x, y, z in p[1:].tolist())
        link = links[k] if k < len(links) else None
        linked = link is not None
        hop = math.nan
        if linked:
            moves.extend(Move("feed", x, y, z) for x, y, z in link[1:].tolist())
        else:
            if travel is not None and k < len(travel) and math.isfinite(travel[k]):
                hop = max(float(travel[k]), float(p[-1, 2]))
            moves.append(Move("rapid", float(p[-1, 0]), float(p[-1, 1]),
                              clear if math.isnan(hop) else hop))
    return moves


class Monitor:
    """Calls ``progress(fraction)`` and polls ``cancel()``; raises ToolpathCancelled."""

    def __init__(self, progress: ProgressFn, cancel: CancelFn, what: str):
        for name, fn in (("progress", progress), ("cancel", cancel)):
            if fn is not None and not callable(fn):
                raise ParameterError(f"{name} must be callable or None, got {fn!r}")
        self.progress, self.cancel, self.what = progress, cancel, what
        self.last = 0.0

    def __call__(self, fraction: float) -> None:
        fraction = min(max(float(fraction), self.last), 1.0)
        self.last = fraction
        if self.cancel is not None and self.cancel():
            raise ToolpathCancelled(
                f"{self.what} toolpath cancelled at {100 * fraction:.0f}% of the work")
        if self.progress is not None:
            self.progress(fraction)
