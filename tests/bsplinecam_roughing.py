# SPDX-License-Identifier: LGPL-2.1-or-later
"""Helpers of the roughing tests (TestBSplineCAMRoughing*.py): the moves cut one at a time out of
a Z-map of the stock block by core.simulate's swept-tool envelope (:class:`Machined`), the
common checks of a roughing (:func:`check_common`), the parts known in closed form and the
case study's block."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from bsplinecam_helpers import cut_moves

from BSplineCAM.core.simulation.simulate import Grid, Tool
from BSplineCAM.core.simulation.stock import CylinderStock
from BSplineCAM.core.toolpath.roughing import (
    RAMP_ANGLE_DEG,
    Stock,
    generate_roughing,
)

SIM_CELL = 0.2


EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


CUT_EPS = 0.05  # mm: a cell counts as cut when the move lowers it by more


def disk_max(values: np.ndarray, radius_cells: float) -> np.ndarray:
    """max over a disk of the given radius (cells), by scipy as an independent reference."""
    ndimage = pytest.importorskip("scipy.ndimage")
    k = int(math.floor(radius_cells))
    yy, xx = np.mgrid[-k:k + 1, -k:k + 1]
    foot = xx * xx + yy * yy <= radius_cells ** 2 + 1e-9
    return ndimage.maximum_filter(values, footprint=foot, mode="nearest")


class Machined:
    """The result of cutting the moves one by one, with per-move observations."""

    def __init__(self, rough, stock: Stock | CylinderStock, tool: Tool,
                 fresh_only: bool = False):
        grid = Grid.covering(stock.x_min, stock.x_max, stock.y_min, stock.y_max, SIM_CELL)
        self.grid = grid
        h = np.full((grid.ny, grid.nx), stock.z_max, dtype=np.float32)
        xs, ys = grid.centres()
        # a cylinder holds material only inside its circle (z_min, its bottom, elsewhere)
        self.inside = np.ones(h.shape, bool)
        if isinstance(stock, CylinderStock):
            self.inside = np.hypot(xs[None, :] - stock.x, ys[:, None] - stock.y) <= stock.radius
            h[~self.inside] = stock.z_min
        moves = rough.moves
        self.rapid_cut = 0.0
        self.engagement = []  # (move index, width mm) of non-descending cutting feeds
        self.descents = []    # (move index, slope dz/dxy) of descending feeds that cut
        for i, m, pos, end, (ix0, iy0), before, depth in cut_moves(
                moves, rough.clearance_height, h, tool, grid, stock.z_min, stock.z_max):
            cut = depth > CUT_EPS
            if m.kind == "rapid":
                self.rapid_cut = max(self.rapid_cut, float(depth.max(initial=0.0)))
            elif cut.any():
                d = end[:2] - pos[:2]
                length = float(np.hypot(*d))
                dz = end[2] - pos[2]
                if dz < -1e-9:
                    self.descents.append((i, -dz / max(length, 1e-12)))
                elif length > 1e-9:
                    if fresh_only:
                        # only material still at the top of the move's level (its slab)
                        above = [z for z in (stock.z_max, *rough.levels) if z > m.z + 1e-9]
                        cut &= before > min(above) - CUT_EPS
                    n = np.array([-d[1], d[0]]) / length
                    iy, ix = np.nonzero(cut)
                    if not len(iy):
                        continue
                    across = (xs[ix0 + ix] - pos[0]) * n[0] + (ys[iy0 + iy] - pos[1]) * n[1]
                    width = min(float(across.max() - across.min()), tool.diameter)
                    self.engagement.append((i, width))
        self.height = h.astype(float)
        self.xs, self.ys = xs, ys


def check_common(rough, stock, tool, part_fn, stepdown, stepover, ar, aa, head_on=False,
                 ramp_angle=RAMP_ANGLE_DEG):
    """(a) no gouge, (b) bounded stock left, (c) engagement, (d) clean rapids, (e) ramps;
    returns the machined Z-map and the part on its grid.

    Width of cut: a flat end mill's counts every cell the move lowers by more than CUT_EPS.
    A ball or bull-nose also shaves, over its whole width, the cusps or corner fillets the
    previous pass of the level left below the level above (0.25 mm cusps for the ball test);
    for them the width counts the cells of fresh material, still at the top of the level's
    slab, that the move lowers."""
    sim = Machined(rough, stock, tool, fresh_only=tool.shape.value != "flat")
    part = part_fn(sim.xs, sim.ys)
    base = np.where(np.isfinite(part), part, stock.z_min)
    # (a) the stock left covers the part offset by the allowances (horizontal ar, vertical aa)
    offset = np.where(sim.inside, np.minimum(disk_max(base, ar / SIM_CELL) + aa, stock.z_max),
                      stock.z_min)
    gouge = float((offset - sim.height).max())
    assert gouge <= 0.02, f"gouge {gouge:.4f} mm"
    # (b) at most one stepdown above the part (plus the allowances and half a millimetre of
    # wall scallop and grid slack sideways)
    upper = disk_max(base, (ar + 0.5) / SIM_CELL) + aa + stepdown + 0.05
    excess = float((sim.height - upper).max())
    assert excess <= 0.0, f"stock left {excess:.3f} mm above part + allowance + stepdown"
    # (c) radial width of cut: within 1.1 s.  With ``head_on`` (fronts meeting a sloped wall
    # head-on), a pass ends with its front half over the terrace above the slope, which the
    # previous pass's end only half covered: within a tool radius of the wall the width is
    # then at most R + s/2 (the crescent between two end disks s apart, each at most s
    # thick).  On a level whose fronts were bent towards the walls the zone next to a wall
    # is the bending layer, where two bent fronts closing in cut a little over s.
    widths = [(i, w) for i, w in sim.engagement if not _in_entry(rough, i)]
    assert widths, "no cutting feed moves"
    at_wall = [w for i, w in widths if _ends_at_wall(rough, i)]
    inner = [w for i, w in widths if not _ends_at_wall(rough, i)]
    worst = max(inner, default=0.0)
    assert worst <= 1.1 * stepover, f"engagement {worst:.3f} mm > 1.1 * {stepover}"
    cap = min(tool.diameter, tool.radius + stepover / 2) if head_on else stepover
    assert max(at_wall, default=0.0) <= 1.1 * cap, f"{max(at_wall):.3f} mm next to a wall"
    # (d) rapids remove nothing
    assert sim.rapid_cut <= 0.01, f"a rapid cut {sim.rapid_cut:.4f} mm"
    # (e) no straight plunge: descending feeds into material ramp at most at the ramp angle
    limit = math.tan(math.radians(ramp_angle)) * 1.05
    steep = [s for i, s in sim.descents if s > limit]
    assert not steep, f"{len(steep)} descending cuts steeper than the ramp, up to {max(steep)}"
    return sim, base


def _ends_at_wall(rough, i):
    """The move ends within a tool radius (plus the allowance and the grid's growth) of
    tip heights above its level: its tool reaches over the wall's contour.  On a level cut
    with the fronts bent towards the walls (``bent_levels``), within the bending layer
    (WALL_LAYER_RADII tool radii) and a tool radius."""
    from BSplineCAM.core.toolpath.roughing import WALL_LAYER_RADII

    tip = rough.tip_height
    g = tip.grid
    m = rough.moves[i]
    R = rough.parameters["tool"]["diameter"] / 2
    bent = any(abs(m.z - z) < 1e-9 for z in rough.stats["bent_levels"])
    reach = (R * (1 + WALL_LAYER_RADII * bent) + rough.parameters["radial_allowance"]
             ) / g.cell + 4
    j = (m.x - g.x0) / g.cell - 0.5
    k = (m.y - g.y0) / g.cell - 0.5
    j0, j1 = max(int(j - reach), 0), int(j + reach) + 2
    k0, k1 = max(int(k - reach), 0), int(k + reach) + 2
    jj, kk = np.meshgrid(np.arange(j0, min(j1, g.nx)), np.arange(k0, min(k1, g.ny)))
    near = np.hypot(jj - j, kk - k) <= reach
    return bool((tip.z[k0:k1, j0:j1][near] > m.z + 1e-6).any())


def _ramps_retraced(rough):
    """Per entry: the length of the level moves right after it that run along its XY track
    (within 0.05 mm, sampled at ten points per move) over the track's length."""
    out = []
    moves = rough.moves
    for a, b in rough.stats["entry_spans"]:
        track = np.array([[m.x, m.y] for m in moves[a - 1:b]])
        seg_a, seg_b = track[:-1], track[1:]
        ab = seg_b - seg_a
        length = float(np.hypot(*ab.T).sum())
        if length < 1e-6:
            continue
        level = moves[b - 1].z
        along = 0.0
        i = b
        while i < len(moves) and moves[i].kind == "feed" and abs(moves[i].z - level) < 1e-9:
            p0, p1 = np.array(moves[i - 1][1:3]), np.array(moves[i][1:3])
            q = p0 + np.linspace(0.05, 0.95, 10)[:, None] * (p1 - p0)
            t = np.einsum("kij,ij->ki", q[:, None, :] - seg_a[None],
                          ab) / np.maximum((ab * ab).sum(axis=1), 1e-300)
            foot = seg_a[None] + np.clip(t, 0.0, 1.0)[..., None] * ab[None]
            d = np.hypot(*np.moveaxis(q[:, None, :] - foot, -1, 0)).min(axis=1)
            along += 0.1 * float(np.hypot(*(p1 - p0))) * int((d < 0.05).sum())
            i += 1
        out.append(along / length)
    return out


def _in_entry(rough, i):
    return any(a <= i < b for a, b in rough.stats["entry_spans"])


def bare_job(cell: float, half: float, tool: Tool = Tool(8.0, "flat"), stepover: float = 3.0):
    """A roughing run's state (core.toolpath.roughing._Job) on a flat grid of ``cell`` mm over
    [-half, half]^2, its grids to be set by the test: (job, cell centres x, y)."""
    from BSplineCAM.core.toolpath.roughing import _Job

    grid = Grid.covering(-half, half, -half, half, cell)
    zeros = np.zeros((grid.ny, grid.nx))
    job = _Job(grid, zeros, zeros, tool, stepover, 0.0, cell,
               Stock(-half, half, -half, half, 0, 10), 20.0, [], None)
    xs, ys = grid.centres()
    return job, xs, ys


# -- parts ----------------------------------------------------------------------------------
def hemisphere_on_plate(xs, ys):
    X, Y = np.meshgrid(xs, ys)
    r2 = X * X + Y * Y
    h = np.where(r2 <= 100.0, 5.0 + np.sqrt(np.maximum(100.0 - r2, 0.0)), 5.0)
    return np.where((np.abs(X) <= 25) & (np.abs(Y) <= 25), h, np.nan)


def bowl(xs, ys):
    X, Y = np.meshgrid(xs, ys)
    h = np.minimum(2.0 + (X * X + Y * Y) / 20.0, 10.0)
    return np.where((np.abs(X) <= 20) & (np.abs(Y) <= 20), h, np.nan)


def slope(xs, ys):
    X, Y = np.meshgrid(xs, ys)
    h = 4.0 + 0.25 * X
    return np.where((np.abs(X) <= 16) & (np.abs(Y) <= 12), h, np.nan)


def slot_plate(xs, ys):
    """A plate at z 10 with a 6 mm slot down to z 4 along y = 0, x in [-10, 10], and a round
    pocket of radius 4.8 mm down to z 4 at (14, 9)."""
    X, Y = np.meshgrid(xs, ys)
    slot = (np.abs(Y) <= 3.0) & (np.abs(X) <= 10.0)
    pocket = np.hypot(X - 14.0, Y - 9.0) <= 4.8
    h = np.where(slot | pocket, 4.0, 10.0)
    return np.where((np.abs(X) <= 20) & (np.abs(Y) <= 15), h, np.nan)


def plateau(xs, ys):
    """A plate at z 5 with a 24 x 24 mm plateau at z 9.3 (vertical sides)."""
    X, Y = np.meshgrid(xs, ys)
    h = np.where((np.abs(X) <= 12) & (np.abs(Y) <= 12), 9.3, 5.0)
    return np.where((np.abs(X) <= 22) & (np.abs(Y) <= 22), h, np.nan)


def _bands(levels, top, stepdown):
    """The cutting order split into (main level, [levels of its band]) pairs: the main
    levels lie a whole number of step-downs below the top, or are the lowest."""
    out = []
    for z in levels:
        if abs((top - z) / stepdown - round((top - z) / stepdown)) < 1e-6 or z == min(levels):
            out.append((z, []))
        else:
            out[-1][1].append(z)
    return out


def case_study_part():
    """The case study's height function (NaN off the surface) and its block: the part's box
    grown by 2 mm on every side."""
    from BSplineCAM.core.geometry.footprint import surface_height
    from BSplineCAM.core.geometry.surface import Surface

    surf = Surface.from_json(str(EXAMPLES / "case-study.json"))
    P = surf.evaluate_grid(np.linspace(0, 1, 101), np.linspace(0, 1, 101)).reshape(-1, 3)
    lo, hi = P.min(axis=0), P.max(axis=0)
    stock = Stock(lo[0] - 2, hi[0] + 2, lo[1] - 2, hi[1] + 2, lo[2] - 2, hi[2] + 2)

    def height(xs, ys):
        return surface_height(surf, np.asarray(xs)[None, :], np.asarray(ys)[:, None])[0]

    return height, stock


def _blobs(shape, rng):
    """Masks where cropping to the set and unset cells' boxes matters: none, all, a disc in
    a corner, everything but a hole, random specks and their complement, one cell."""
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    disc = (xx - 3) ** 2 + (yy - 4) ** 2 <= 9
    hole = (xx - shape[1] // 2) ** 2 + (yy - shape[0] // 2) ** 2 > 25
    specks = rng.random(shape) < 0.01
    one = np.zeros(shape, bool)
    one[-1, max(shape[1] - 2, 0)] = True
    return [np.zeros(shape, bool), np.ones(shape, bool), disc, hole, specks, ~specks, one]


def _job_radial(rough, stock, tool, cell):
    """Per-move radial engagement (mm) outside entries, by core.job_simulation cutting the
    program written as G-code out of the block, and the number of colliding rapids."""
    from BSplineCAM.core.program.gcode import read_gcode
    from BSplineCAM.core.simulation.job_simulation import simulate_job

    lines = ["G21 G90 G17", "T1 M6"]
    for m in rough.moves:
        code = "G0" if m.kind == "rapid" else "G1"
        feed = "" if m.kind == "rapid" else " F1000"
        lines.append(f"{code} X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}{feed}")
    lines.append("M2")
    program = read_gcode("\n".join(lines) + "\n", "roughing")
    box = (stock.x_min, stock.x_max, stock.y_min, stock.y_max, stock.z_min, stock.z_max)
    job = simulate_job(program, {1: tool}, Grid.covering(*box[:4], cell), box)
    cutting = ~job.entry & (job.volume > 0)
    return job.radial[cutting], len(job.tools[1].collisions)


def boss_near_corner(xs, ys):
    """A hemisphere of radius 12 mm on a plate at z = 2, centred at (-10, -10) in a 60 mm
    square: the fronts from the block's far sides sweep along it."""
    X, Y = np.meshgrid(xs, ys)
    r2 = (X + 10.0) ** 2 + (Y + 10.0) ** 2
    h = np.where(r2 <= 144.0, 2.0 + np.sqrt(np.maximum(144.0 - r2, 0.0)), 2.0)
    return np.where((np.abs(X) <= 30) & (np.abs(Y) <= 30), h, np.nan)


def _rough_boss_near_corner(s: float):
    """The boss near the block's corner roughed with a 10 mm flat at stepover s, 2 mm down:
    (roughing, radial engagement per cutting move outside entries by the job simulation,
    moves over 1.1 s plus a cell); no rapid touches the stock."""
    stock = Stock(-30, 30, -30, 30, 0.0, 15.0)
    tool = Tool(10.0, "flat")
    rough = generate_roughing(boss_near_corner, stock, tool, stepdown=2.0, stepover=s,
                              radial_allowance=0.3, axial_allowance=0.3)
    radial, collisions = _job_radial(rough, stock, tool, SIM_CELL)
    assert collisions == 0
    return rough, radial, int((radial > 1.1 * s + SIM_CELL).sum())


# -- a cylinder stock (CAM's "CreateCylinder") ------------------------------------------------
CYLINDER = CylinderStock(3.0, -2.0, 20.0, 0.0, 12.0)


PLANE_Z = 4.0


def plane_in_cylinder(xs, ys):
    """A flat part top at PLANE_Z over the cylinder's disk (nothing outside it)."""
    X, Y = np.meshgrid(xs, ys)
    inside = np.hypot(X - CYLINDER.x, Y - CYLINDER.y) <= CYLINDER.radius
    return np.where(inside, PLANE_Z, np.nan)


def boss_in_cylinder(xs, ys):
    """A hemisphere of radius 8 mm on the cylinder's axis, on a floor rising outwards from
    PLANE_Z at 1:20.  Not flat: on a level exactly at a flat floor (T - z = 0 over an area)
    the round fronts follow the grid's cells in stairs, whose short diagonal moves the width
    of cut of check_common overstates (up to 4.4 mm at a 3.2 mm stepover)."""
    X, Y = np.meshgrid(xs, ys)
    d2 = (X - CYLINDER.x) ** 2 + (Y - CYLINDER.y) ** 2
    floor = PLANE_Z + 0.05 * np.maximum(np.sqrt(d2) - 8.0, 0.0)
    h = np.where(d2 <= 64.0, PLANE_Z + np.sqrt(np.maximum(64.0 - d2, 0.0)), floor)
    return np.where(d2 <= CYLINDER.radius ** 2, h, np.nan)


def simulate_text(rough, stock, tool, cell=SIM_CELL):
    """The roughing written as G-code text, read back and cut out of ``stock`` by
    core.job_simulation on the stock's bounding box."""
    from BSplineCAM.core.program.gcode import read_gcode
    from BSplineCAM.core.simulation.job_simulation import simulate_job

    lines = ["G21 G90 G17", "T1 M6"]
    for m in rough.moves:
        code, feed = ("G0", "") if m.kind == "rapid" else ("G1", " F1000")
        lines.append(f"{code} X{m.x:.4f} Y{m.y:.4f} Z{m.z:.4f}{feed}")
    lines.append("M2")
    program = read_gcode("\n".join(lines) + "\n", "roughing")
    return simulate_job(program, {1: tool}, Grid.covering(*stock.bounds[:4], cell), stock)


def farthest_clearing_feed(rough, centre, allowed):
    """Largest distance (mm) from the cylinder's axis to the nearest point of a feed move with
    XY travel that is neither a stay-down link between passes nor part of an entry; and the
    number of those lying wholly beyond ``allowed`` (mm) from the axis."""
    links = set(rough.stats["link_moves"])
    worst, beyond = -math.inf, 0
    c = np.asarray(centre, dtype=float)
    for i in range(1, len(rough.moves)):
        m = rough.moves[i]
        if m.kind != "feed" or i in links or _in_entry(rough, i):
            continue
        a = np.array(rough.moves[i - 1][1:3]) - c
        b = np.array(m[1:3]) - c
        ab = b - a
        length2 = float(ab @ ab)
        if length2 < 1e-12:  # a straight descent (beside the stock, or into cleared cells)
            continue
        t = min(max(-float(a @ ab) / length2, 0.0), 1.0)
        d = float(np.hypot(*(a + t * ab)))
        worst = max(worst, d)
        beyond += d > allowed
    return worst, beyond


# -- round fronts grown from a helix --------------------------------------------------------------
def _edge_arc_in_material(rho: float, cleared: float, R: float) -> float:
    """Largest angle (rad, from the outward normal) of the edge of a tool of radius R whose
    centre lies at radius ``rho`` that is outside the cleared disc of radius ``cleared``:
    a dense sample of the edge, not the closed form."""
    phi = np.linspace(0.0, math.pi, 200_001)
    x, y = rho + R * np.cos(phi), R * np.sin(phi)
    return float(phi[np.hypot(x, y) >= cleared].max())


def cone_pocket(xs, ys):
    """A conical pocket: floor at z 2 within r 4 mm, 45 degree walls up to z 14."""
    X, Y = np.meshgrid(xs, ys)
    h = np.clip(2.0 + (np.hypot(X, Y) - 4.0), 2.0, 14.0)
    return np.where((np.abs(X) <= 25) & (np.abs(Y) <= 25), h, np.nan)
