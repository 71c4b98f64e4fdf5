# SPDX-License-Identifier: LGPL-2.1-or-later
"""The job simulation's compiled cut (BSplineCAM/core/kernels/job_kernels.py) against the
numpy engine: bit-identical heights, snapshots and per-move figures (drop, axial and radial
engagement, volume, removal rate, deepest cell) and equal reports and collisions, for flat end
mill roughing with plunges, ramps and helices, ball finishing, bull-nose passes and tool
changes, on blocks, a block without bottom and a cylinder (the numba half skips where numba is
missing); the float64 sum of float32 cells as numpy's."""

from __future__ import annotations

import math

import numpy as np
import pytest

from BSplineCAM.core import kernels
from BSplineCAM.core.kernels import job_kernels
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.job_simulation import simulate_job
from BSplineCAM.core.simulation.simulate import Grid, Tool
from BSplineCAM.core.simulation.stock import CylinderStock

FLAT10 = Tool(10.0, "flat")
BALL6 = Tool(6.0, "ball")
BULL8 = Tool(8.0, "bullnose", 1.5)


def program(*lines: str) -> str:
    return "\n".join(["G21 G90 G17", *lines, "M2"]) + "\n"


def roughing_lines(depth: float, stepover: float) -> list[str]:
    """A helix entry (radius 3, two turns), a closing turn, then level passes beside each
    other at ``stepover``, a plunge and a ramp at the next level."""
    r, n = 3.0, 24
    lines = [f"G0 X{20 + r} Y20 Z5", "G0 Z0.5", "G1 Z0 F400"]
    for k in range(1, 2 * n + 1):
        a = 2 * math.pi * k / n
        lines.append(f"G1 X{20 + r * math.cos(a):.4f} Y{20 + r * math.sin(a):.4f} "
                     f"Z{-depth * k / (2 * n):.4f}")
    lines.append(f"G2 X{20 - r} Y20 I{-r} J0 Z{-depth}")
    lines.append(f"G2 X{20 + r} Y20 I{r} J0")
    for k, y in enumerate(np.arange(20.0, 36.0, stepover)):
        x = (5, 35) if k % 2 == 0 else (35, 5)
        lines += [f"G1 Y{y:.3f}", f"G1 X{x[1]}"]
    lines += ["G0 Z5", "G0 X8 Y8", "G1 Z-3 F200", "G1 X30 Y12 Z-4.5 F500", "G1 X8 Y30",
              "G0 Z5"]
    return lines


def finishing_lines(z: float, step: float) -> list[str]:
    lines = []
    for k, y in enumerate(np.arange(2.0, 38.0, step)):
        x0, x1 = (-4, 44) if k % 2 == 0 else (44, -4)
        lines += [f"G0 X{x0} Y{y:.3f} Z8", f"G1 Z{z + 0.2 * math.sin(y):.4f} F900",
                  f"G1 X{(x0 + x1) / 2} Z{z - 0.4:.4f}", f"G1 X{x1} Z{z:.4f}", "G0 Z8"]
    return lines


def _both(run):
    """``run()`` under the numpy engine, then under numba."""
    out = []
    for choice in ("numpy", "numba"):
        with kernels.forced(choice) as e:
            assert e.name == choice
            out.append(run())
            assert kernels.engine().name == choice  # no kernel fell back to numpy
    return out


def _bits(a) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(np.uint8)


def _same(a, b) -> None:
    assert np.array_equal(_bits(a.height), _bits(b.height))
    assert a.snapshots.keys() == b.snapshots.keys()
    for t in a.snapshots:
        assert np.array_equal(_bits(a.snapshots[t]), _bits(b.snapshots[t]))
    for name in ("volume", "axial", "radial", "rate", "deepest"):
        assert np.array_equal(_bits(getattr(a, name)), _bits(getattr(b, name))), name
    assert repr(a.tools) == repr(b.tools)  # NaN figures (no bottom) compare by their text
    assert a.collisions == b.collisions
    assert a.metrics() == b.metrics()


def _agree(text: str, tools: dict, grid: Grid, stock):
    pytest.importorskip("numba")
    prog = read_gcode(text)
    a, b = _both(lambda: simulate_job(prog, tools, grid, stock))
    _same(a, b)
    return a


@pytest.mark.parametrize("cell", [0.2, 0.13])
def test_roughing_then_finishing_with_tool_changes(cell: float) -> None:
    """T1 flat roughing (helix, closing turn, passes, plunge, ramp), T2 ball finishing over
    the roughed block, T3 bull-nose passes, a rapid through the stock."""
    lines = ["T1 M6", *roughing_lines(2.0, 4.0), "M6 T2", *finishing_lines(-1.5, 1.7),
             "M6 T3", "G0 X-6 Y10 Z5", "G1 Z-2.5 F600", "G1 X46 Y14", "G0 Z5",
             "G0 X38 Y2 Z5", "G0 Z-3", "G0 Z5"]
    grid = Grid(-10.0, -10.0, cell, round(60 / cell), round(60 / cell))
    job = _agree(program(*lines), {1: FLAT10, 2: BALL6, 3: BULL8}, grid,
                 (0, 40, 0, 40, -10, 0))
    assert job.tools[1].entries >= 1 and job.tools[1].axial_engagement_max_mm > 1.0
    assert job.tools[2].removed_volume_mm3 > 0 and job.tools[3].removed_volume_mm3 > 0
    assert job.collisions  # the rapid plunge to Z-3 into the stock


def test_ball_finishing_on_a_block_without_bottom() -> None:
    """A ball raster over a block without bottom, the grid wider than the block (cells at
    -inf): NaN drops there decide the figures alike."""
    grid = Grid(-8.0, -8.0, 0.25, 224, 224)
    _agree(program("T2 M6", *finishing_lines(-0.5, 2.3)), {2: BALL6}, grid,
           (0, 40, 0, 40, -math.inf, 0))


def test_roughing_in_a_cylinder_with_long_moves() -> None:
    """Flat roughing of a cylinder stock with long diagonal moves (pieces, the float64 path of
    the envelope) and a slot through it."""
    lines = ["T1 M6", "G0 X-30 Y-30 Z5", "G1 Z-1.5 F800", "G1 X30 Y28", "G1 X-28 Y30",
             "G1 X30 Y-30 Z-2.5", "G0 Z5", "G0 X-30 Y0", "G1 Z-3 F300", "G1 X30", "G0 Z5"]
    grid = Grid(-30.0, -30.0, 0.3, 200, 200)
    _agree(program(*lines), {1: FLAT10}, grid, CylinderStock(0.0, 0.0, 22.0, -10.0, 0.0))


def test_verify_job_metrics_agree() -> None:
    """verify_job's figures (the per-tool reports among them) are the same under both
    engines."""
    pytest.importorskip("numba")
    from BSplineCAM.core.geometry.surface import Surface
    from BSplineCAM.core.simulation.verify import verify_job

    x, y = np.meshgrid(np.linspace(0, 40, 5), np.linspace(0, 40, 5), indexing="ij")
    surface = Surface(np.stack([x, y, np.full_like(x, -2.0)], axis=-1), "clamped", "plane")
    prog = read_gcode(program("T1 M6", *roughing_lines(1.5, 3.0), "M6 T2",
                              *finishing_lines(-1.8, 2.0)))
    a, b = _both(lambda: verify_job(surface, prog, {1: FLAT10, 2: BALL6},
                                    (0, 40, 0, 40, -10, 0), cell=0.2))
    assert a.metrics == b.metrics
    _same(a.job, b.job)


@pytest.mark.parametrize("n", [0, 1, 7, 8, 9, 127, 128, 129, 1000, 8191, 8192, 8193, 20011])
def test_pairwise_sum_is_numpys(n: int) -> None:
    """The float64 sum of float32 cells, as numpy sums a float32 array in float64 (plain
    Python here: no numba needed)."""
    rng = np.random.default_rng(n)
    values = (rng.random(n + 3) * 3.0 - 0.5).astype(np.float32)
    assert job_kernels.pairwise_sum(values, 3, n) == values[3:].sum(dtype=np.float64)
    grid = values[3:3 + (n // 7) * 7].reshape(-1, 7)
    assert job_kernels.pairwise_sum(values, 3, grid.size) == grid.sum(dtype=np.float64)
