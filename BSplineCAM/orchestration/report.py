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
                 f"{m['scallop_max_mm']:.4f} mm (p99 {m['scallop_p99_mm']:.4f})\n"
                 f"edge band (outside dashed line) scallop max {m['edge_scallop_max_mm']:.3f} mm, "
                 f"coverage {100 * m['coverage']:.1f} %", fontsize=9)
    ax.set_aspect("equal")
    fig.tight_layout()
    _save(fig, path)


def plot_simulated(result: Verification, path: str | os.PathLike) -> None:
    """The machined Z-map, hill-shaded (light from the north-west) and coloured by height."""
    from matplotlib.colors import LightSource

    plt = _pyplot()
    sim = result.simulation
    height = sim.height
    light = LightSource(azdeg=315, altdeg=35)
    cmap = plt.get_cmap("copper")
    lo, hi = float(np.min(height)), float(np.max(height))
    shaded = light.shade(height, cmap=cmap, vert_exag=3.0, dx=sim.grid.cell, dy=sim.grid.cell,
                         blend_mode="overlay", vmin=lo, vmax=hi if hi > lo else lo + 1.0)
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


def plot_stock(result: Verification, number: int, path: str | os.PathLike) -> None:
    """The stock after the last move of tool ``number`` (a whole-program verification):
    hill-shaded height, coloured by the material left above the design (mm), with the
    tool's figures in the title."""
    from matplotlib.colors import LightSource

    plt = _pyplot()
    job = result.job
    grid = job.grid
    height = np.asarray(job.snapshots[number], dtype=float)
    left = np.where(np.isfinite(result.design), height - result.design, np.nan)
    top = float(np.nanmax(left)) if np.isfinite(left).any() else 1.0
    cmap = plt.get_cmap("viridis")
    light = LightSource(azdeg=315, altdeg=35)
    colour = np.nan_to_num(np.clip(left, 0.0, max(top, 1e-3)) / max(top, 1e-3), nan=0.0)
    rgb = cmap(colour)[..., :3]
    shaded = light.shade_rgb(rgb, height, vert_exag=3.0, dx=grid.cell, dy=grid.cell,
                             blend_mode="overlay")
    fig, ax = plt.subplots(figsize=(7.5, 6.4), dpi=110)
    ax.imshow(shaded, origin="lower", extent=_extent(result), interpolation="nearest")
    mappable = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(0.0, max(top, 1e-3)))
    fig.colorbar(mappable, ax=ax).set_label("material left above the design (mm)")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    t = result.metrics["tools"][str(number)]
    tool = t["tool"]
    inside = np.isfinite(left)
    low = float(np.min(left[inside])) if inside.any() else float("nan")
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
