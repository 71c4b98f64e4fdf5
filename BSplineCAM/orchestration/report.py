# SPDX-License-Identifier: LGPL-2.1-or-later
"""Pictures of a verification: deviation map and rendered simulated part (matplotlib, Agg).

Kept out of ``core`` because it needs matplotlib; the core hands over plain arrays.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.simulation.verify import Verification


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _extent(result: Verification) -> list[float]:
    g = result.simulation.grid
    return [g.x0, g.x0 + g.nx * g.cell, g.y0, g.y0 + g.ny * g.cell]


def plot_deviation(result: Verification, path: str | os.PathLike) -> None:
    """Colour map of machined - design (mm): red gouges below zero, blue material left above.

    The colour scale spans the inner footprint's gouge and scallop (the edge band, with more
    material left, saturates); the dashed line marks the
    inner footprint (shrunk by one tool diameter), outside which the edge band lies.
    """
    from matplotlib.colors import TwoSlopeNorm

    plt = _pyplot()
    m = result.metrics
    dev = result.deviation
    top = max(m["scallop_max_mm"], 1e-3)  # the edge band saturates (the bar extends)
    bottom = -max(m["gouge_max_mm"], 0.1 * top, 1e-4)
    fig, ax = plt.subplots(figsize=(7.5, 6.4), dpi=110)
    cmap = plt.get_cmap("RdYlBu").with_extremes(bad="0.85")
    image = ax.imshow(dev, origin="lower", extent=_extent(result), cmap=cmap,
                      norm=TwoSlopeNorm(vmin=bottom, vcenter=0.0, vmax=top),
                      interpolation="nearest")
    xs, ys = result.simulation.grid.centres()
    ax.contour(xs, ys, result.inner.astype(float), levels=[0.5], colors="k",
               linestyles="--", linewidths=0.8)
    bar = fig.colorbar(image, ax=ax, extend="both")
    bar.set_label("machined − design (mm)   (< 0: gouge)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"Deviation: gouge max {m['gouge_max_mm']:.4f} mm, scallop max "
                 f"{m['scallop_max_mm']:.4f} mm (p99 {m['scallop_p99_mm']:.4f}, evenness "
                 f"{m.get('scallop_evenness', float('nan')):.2f})\n"
                 f"edge band (outside dashed line) scallop max {m['edge_scallop_max_mm']:.3f} mm, "
                 f"coverage {100 * m['coverage']:.1f} %", fontsize=9)
    ax.set_aspect("equal")
    fig.tight_layout()
    _save(fig, path)


#: Most cells per side a shaded picture draws: a larger Z-map is drawn from every k-th cell
#: (the picture is about 600 pixels wide; shading 3000 x 3000 cells in float64 takes 1.2 GB).
PLOT_CELLS = 1200


def _thinned(height: np.ndarray, cell: float) -> tuple[np.ndarray, float]:
    """Every k-th cell of a Z-map in each direction, k the least that keeps at most
    PLOT_CELLS per side, and the cell size of the result (mm)."""
    k = max(1, -(-max(height.shape) // PLOT_CELLS))
    return height[::k, ::k], cell * k


def plot_simulated(result: Verification, path: str | os.PathLike) -> None:
    """The machined Z-map, hill-shaded (light from the north-west) and coloured by height
    (a map of more than PLOT_CELLS cells per side from every k-th cell); cells without
    stock (off the model when the stock was the model raised by a margin) in OFF_PART_COLOUR."""
    from matplotlib.colors import LightSource

    plt = _pyplot()
    sim = result.simulation
    height, cell = _thinned(sim.height, sim.grid.cell)
    empty = ~np.isfinite(height)
    lo = float(np.min(height[~empty])) if (~empty).any() else 0.0
    hi = float(np.max(height[~empty])) if (~empty).any() else 1.0
    height = np.where(empty, lo, height)
    light = LightSource(azdeg=315, altdeg=35)
    cmap = plt.get_cmap("copper")
    shaded = light.shade(height, cmap=cmap, vert_exag=3.0, dx=cell, dy=cell,
                         blend_mode="overlay", vmin=lo, vmax=hi if hi > lo else lo + 1.0)
    shaded[empty, :3] = OFF_PART_COLOUR
    fig, ax = plt.subplots(figsize=(7.5, 6.4), dpi=110)
    ax.imshow(shaded, origin="lower", extent=_extent(result), interpolation="nearest")
    mappable = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(lo, hi if hi > lo else lo + 1))
    fig.colorbar(mappable, ax=ax).set_label("machined height z (mm)")
    collisions = result.metrics["rapid_collisions"]
    if collisions:
        ax.plot([c["x"] for c in collisions], [c["y"] for c in collisions], "rx", ms=9,
                label="rapid collision")
        ax.legend(loc="upper right")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    tool = result.metrics["tool"]
    ax.set_title(f"Simulated part ({sim.grid.nx} x {sim.grid.ny} cells of {sim.grid.cell:g} mm, "
                 f"{tool['shape']} Ø{tool['diameter_mm']:g} mm)", fontsize=9)
    ax.set_aspect("equal")
    fig.tight_layout()
    _save(fig, path)


#: Stock higher than the part's top plus this (mm), or off the part higher than the block's
#: bottom plus this, is drawn apart in a stock picture (uncut stock, plugs in holes), so that it
#: does not set the colour scale.
PART_TOP_MARGIN_MM = 1.0
#: Colours of the stock above the part's top, and of the stock off the part.
ABOVE_PART_COLOUR = (0.85, 0.35, 0.75)
OFF_PART_COLOUR = (0.6, 0.6, 0.6)


def plot_stock(result: Verification, number: int, path: str | os.PathLike) -> None:
    """The stock after the last move of tool ``number`` (a whole-program verification):
    hill-shaded height, coloured by the material left above the design (mm), with the
    tool's figures in the title.

    The colour scale spans the material left on the model where the stock stands at most
    PART_TOP_MARGIN_MM above the part's top (the design's highest point).  Stock higher than
    that, and stock off the model (in a hole, beside the part's walls, the block's margin)
    standing more than the margin above the block's bottom, are drawn in two flat colours,
    each labelled with its height.  The moves of the tool over its load limits
    (``result.loads``) are drawn in red, each region of them framed with the thickness of
    stock it met.
    """
    from matplotlib.colors import LightSource
    from matplotlib.patches import Patch, Rectangle

    plt = _pyplot()
    job = result.job
    grid = job.grid
    height = np.asarray(job.snapshots[number], dtype=float)
    design = result.design
    on_model = np.isfinite(design)
    part_top = float(np.nanmax(design)) if on_model.any() else float(job.stock[5])
    material = job.in_stock & np.isfinite(height)
    bottom = float(job.stock[4]) if np.isfinite(job.stock[4]) else (
        float(height[material].min()) if material.any() else 0.0)
    left = np.where(on_model, height - np.where(on_model, design, 0.0), height - bottom)
    left = np.where(material, left, 0.0)
    above = material & (height > part_top + PART_TOP_MARGIN_MM)
    off = material & ~on_model & ~above & (height > bottom + PART_TOP_MARGIN_MM)
    scaled = on_model & ~above
    top = float(np.max(left[scaled])) if scaled.any() else 1.0
    top = max(top, 1e-3)
    cmap = plt.get_cmap("viridis")
    light = LightSource(azdeg=315, altdeg=35)
    rgb = cmap(np.clip(left, 0.0, top) / top)[..., :3]
    rgb[above] = ABOVE_PART_COLOUR
    rgb[off] = OFF_PART_COLOUR
    shade_height = np.where(np.isfinite(height), height, bottom)
    shaded = light.shade_rgb(rgb, shade_height, vert_exag=3.0, dx=grid.cell, dy=grid.cell,
                             blend_mode="overlay")
    fig, ax = plt.subplots(figsize=(7.5, 6.8), dpi=110)
    extent = _extent(result)
    ax.imshow(shaded, origin="lower", extent=extent, interpolation="nearest")
    mappable = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0.0, top))
    fig.colorbar(mappable, ax=ax, extend="max").set_label(
        "material left above the design (mm)")
    handles = []
    if above.any():
        high = float(height[above].max())
        handles.append(Patch(color=ABOVE_PART_COLOUR, label=(
            f"stock above the part's top (z {part_top:.2f} mm): up to z {high:.2f} mm, "
            f"{high - part_top:.2f} mm above it")))
    if off.any():
        high = float(height[off].max())
        handles.append(Patch(color=OFF_PART_COLOUR, label=(
            f"stock off the part (holes, beside its walls): up to z {high:.2f} mm, "
            f"{high - bottom:.2f} mm above the block's bottom")))
    handles += _draw_overloads(ax, result, number, Rectangle)
    if handles:
        ax.legend(handles=handles, loc="upper center", bbox_to_anchor=(0.5, -0.09),
                  fontsize=8, frameon=False)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    t = result.metrics["tools"][str(number)]
    tool = t["tool"]
    low = float(np.min(left[scaled])) if scaled.any() else float("nan")

    def mm(value) -> str:
        return "-" if value is None else f"{value:.2f}"

    ax.set_title(f"Stock after T{number} ({tool['shape']} Ø{tool['diameter_mm']:g} mm): "
                 f"left {max(low, 0.0) if low > -5e-4 else low:.3f} to {top:.3f} mm above "
                 f"the design\nremoved {t['removed_volume_mm3'] / 1000:.1f} cm³, radial "
                 f"engagement max {mm(t['radial_engagement_max_mm'])} mm, axial max "
                 f"{mm(t['axial_engagement_max_mm'])} mm (entries apart)", fontsize=9)
    ax.set_aspect("equal")
    fig.tight_layout()
    _save(fig, path)


def _draw_overloads(ax, result: Verification, number: int, rectangle) -> list:
    """The XY segments of tool ``number``'s moves over its load limits in red, and a frame
    round each region with the stock it met; the legend's handles."""
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D

    loads = getattr(result, "loads", None)
    if loads is None:
        return []
    moves = {o.move for o in loads.overloads if o.tool == number}
    if not moves:
        return []
    seg = result.job.segments
    mine = (result.job.tool == number) & np.isin(seg.move, list(moves)) & ~np.asarray(
        seg.rapid, bool)
    lines = np.stack([seg.start[mine, :2], seg.end[mine, :2]], axis=1)
    ax.add_collection(LineCollection(lines, colors="red", linewidths=1.4, zorder=3))
    points = np.array([(o.x, o.y) for o in loads.overloads if o.tool == number])
    ax.plot(points[:, 0], points[:, 1], "r.", ms=3, zorder=3)
    pad = result.job.grid.cell
    for region in (r for r in loads.regions if r.tool == number):
        ax.add_patch(rectangle((region.x0 - pad, region.y0 - pad),
                               region.x1 - region.x0 + 2 * pad, region.y1 - region.y0 + 2 * pad,
                               fill=False, edgecolor="red", linestyle="--", linewidth=0.9,
                               zorder=3))
        ax.annotate(f"{region.stock_mm:.1f} mm", (region.x1 + pad, region.y1 + pad),
                    color="red", fontsize=7, zorder=4)
    return [Line2D([], [], color="red", lw=1.4, label=(
        f"{len(moves)} moves over T{number}'s load limits (lines "
        f"{min(o.line for o in loads.overloads if o.tool == number)}.."
        f"{max(o.line for o in loads.overloads if o.tool == number)}); framed: the stock "
        "they meet"))]


def _save(fig, path: str | os.PathLike) -> None:
    """Save to a temporary name beside ``path`` and rename: no half-written picture."""
    plt = _pyplot()
    path = Path(path)
    tmp = path.with_name(f".{path.name}.part")
    try:
        fig.savefig(tmp, format="png")
        os.replace(tmp, path)
    finally:
        plt.close(fig)
        if tmp.exists():
            tmp.unlink()
