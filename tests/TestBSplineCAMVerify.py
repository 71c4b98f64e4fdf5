# SPDX-License-Identifier: LGPL-2.1-or-later
"""Footprint inversion, verification metrics against closed forms, and the verify command."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import CASE_STUDY, ROOT, random_net
from hypothesis import given, settings
from hypothesis import strategies as st

from BSplineCAM.core import ParameterError, Surface
from BSplineCAM.core.geometry.footprint import surface_height
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import Tool
from BSplineCAM.core.simulation.verify import verify


def plane_surface(z: float = 10.0, width: float = 60.0, depth: float = 40.0) -> Surface:
    x, y = np.meshgrid(np.linspace(0, width, 7), np.linspace(0, depth, 5), indexing="ij")
    return Surface(np.stack([x, y, np.full_like(x, z)], axis=-1), "clamped", "plane")


def raster_program(passes_y: list[float], z: float, x0: float, x1: float,
                   extra: list[str] = ()) -> str:
    lines = ["%", "G17 G21 G90 G54", "T1 M6", "S10000 M3", f"G0 X{x0} Y{passes_y[0]} Z30"]
    for i, y in enumerate(passes_y):
        a, b = (x0, x1) if i % 2 == 0 else (x1, x0)
        lines += [f"G0 X{a} Y{y:.4f}", f"G1 Z{z:.4f} F600", f"G1 X{b} F1200", "G0 Z30"]
    return "\n".join([*lines, *extra, "M5", "M2", "%"]) + "\n"


def ball_raster(surface: Surface, radius: float, stepover: float, spacing: float) -> str:
    """Zig-zag ball-end finishing over a surface: tool tip = S + R n - R z."""
    rows = int(math.ceil(100 / stepover)) + 1
    us = np.linspace(0, 1, rows)
    ws = np.linspace(0, 1, int(math.ceil(100 / spacing)) + 1)
    pts = surface.evaluate_grid(us, ws)
    n = surface.normals(us, ws, grid=True)
    n = np.where(n[..., 2:3] < 0, -n, n)
    tip = pts + radius * n
    tip[..., 2] -= radius
    lines = ["%", "G17 G21 G90 G54 G40 G49 G80", "T1 M6", "S10000 M3", "G0 X0 Y0 Z50",
             f"G0 X{tip[0, 0, 0]:.4f} Y{tip[0, 0, 1]:.4f}", f"G1 Z{tip[0, 0, 2]:.4f} F500"]
    for i in range(rows):
        for p in tip[i] if i % 2 == 0 else tip[i, ::-1]:
            lines.append(f"G1 X{p[0]:.4f} Y{p[1]:.4f} Z{p[2]:.4f} F1500")
    return "\n".join([*lines, "G0 Z50", "M5", "M2", "%"]) + "\n"


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2 ** 32 - 1))
def test_surface_height_round_trip(seed: int) -> None:
    """S(u, w) -> (x, y) -> surface_height gives back z, u and w."""
    rng = np.random.default_rng(seed)
    surface = Surface(random_net(rng), rng.choice(["uniform", "clamped"]))
    u, w = rng.uniform(0.02, 0.98, (2, 500))
    p = surface.evaluate(u, w)
    z, uu, ww, inside = surface_height(surface, p[:, 0], p[:, 1])
    assert inside.all()
    np.testing.assert_allclose(z, p[:, 2], atol=1e-6)
    np.testing.assert_allclose(surface.evaluate(uu, ww)[:, :2], p[:, :2], atol=1e-6)


def test_surface_height_outside_is_nan() -> None:
    surface = Surface.from_json(CASE_STUDY)
    z, u, w, inside = surface_height(surface, np.array([-1.0, 50.0, 101.0, 50.0]),
                                     np.array([50.0, 50.0, 50.0, 100.5]))
    assert list(inside) == [False, True, False, False]
    assert np.isnan(z[[0, 2, 3]]).all() and np.isnan(u[0]) and np.isfinite(z[1])


@pytest.mark.parametrize("stepover", [1.0, 2.0])
def test_plane_raster_scallop(stepover: float) -> None:
    """Raster over a plane: scallop max = R - sqrt(R^2 - (s/2)^2), no gouge, full coverage."""
    R = 3.0
    ys = list(np.arange(-0.95, 41.0, stepover))  # midlines between passes on cell centres
    text = raster_program(ys, 10.0, -5.0, 65.0)
    result = verify(plane_surface(), read_gcode(text), Tool(2 * R), cell=0.1,
                    coverage_tolerance=0.2)
    m = result.metrics
    assert m["gouge_max_mm"] < 1e-5
    assert m["scallop_max_mm"] == pytest.approx(R - math.sqrt(R * R - (stepover / 2) ** 2),
                                                abs=1e-4)
    assert m["coverage"] == 1.0
    assert m["rapid_collisions"] == []
    passes = len(ys)
    assert m["cutting_length_mm"] == pytest.approx(passes * (70.0 + 20.0))
    assert m["machining_time_s"] == pytest.approx(
        passes * (20.0 / 600 + 70.0 / 1200) * 60 + m["rapid_length_mm"] / 5000 * 60)


def test_deliberate_gouge_and_collision_detected() -> None:
    ys = list(np.arange(-1.0, 41.0 + 1e-9, 1.0))
    text = raster_program(ys, 10.0, -5.0, 65.0,
                          extra=["G0 X30.05 Y20.05", "G1 Z9.8 F300", "G1 X35.05",
                                 "G0 X40.05 Z9.5"])
    m = verify(plane_surface(), read_gcode(text), Tool(6.0), cell=0.1).metrics
    assert m["gouge_max_mm"] == pytest.approx(0.5, abs=1e-4)  # the rapid dives deepest
    assert m["gouge_cells"] > 100
    lines = [c["line"] for c in m["rapid_collisions"]]
    assert len(lines) == 1 and text.splitlines()[lines[0] - 1] == "G0 X40.05 Z9.5"


def test_uncut_band_lowers_coverage() -> None:
    ys = list(np.arange(-1.0, 20.0, 1.0))  # only the lower half of the plate
    prog = read_gcode(raster_program(ys, 10.0, -5.0, 65.0))
    m = verify(plane_surface(), prog, Tool(6.0), cell=0.2).metrics
    assert m["stock_top_mm"] == pytest.approx(11.0)  # design top + 1 mm margin
    assert 0.45 < m["coverage"] < 0.6
    assert 0.4 < m["uncut_fraction"] <= 1 - m["coverage"]  # never touched by the tool
    # stock top at the program's highest cut: the plate is at the design height already
    m = verify(plane_surface(), prog, Tool(6.0), cell=0.2, stock_top="program").metrics
    assert m["stock_top_mm"] == 10.0 and m["coverage"] == 1.0


def test_tool_larger_than_part() -> None:
    text = raster_program([0.0], 10.0, 0.0, 10.0)
    with pytest.raises(ParameterError, match="not smaller than the part"):
        verify(plane_surface(width=8.0, depth=8.0), read_gcode(text), Tool(10.0))


def run_cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "BSplineCAM.orchestration.cli", *args], capture_output=True,
                          text=True, env=env, timeout=600)


def test_cli_verify_case_study(tmp_path: Path) -> None:
    surface = Surface.from_json(CASE_STUDY)
    ngc = tmp_path / "raster.ngc"
    ngc.write_text(ball_raster(surface, 3.0, 2.0, 1.0))
    out = tmp_path / "out"
    proc = run_cli("verify", str(CASE_STUDY), str(ngc), "--tool-diameter", "6", "--cell", "0.25",
                   "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads((out / "verify.json").read_text())
    for key in ("gouge_max_mm", "scallop_max_mm", "scallop_p99_mm", "coverage",
                "rapid_collisions", "cutting_length_mm", "machining_time_s",
                "edge_scallop_max_mm"):
        assert key in report
    assert report["gouge_max_mm"] < 0.01 and report["rapid_collisions"] == []
    assert sorted(p.name for p in out.iterdir()) == ["deviation.png", "simulated.png",
                                                     "verify.json"]
    assert (out / "deviation.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("program, message", [
    ("G21\nG0 X0 Y0 Z50\nG1 X1 E5 F100\nM2\n", "line 3: unknown word E5"),
    ("G20\nG0 X0 Y0 Z5\nG1 X1 Y1 F10\n", "truncated"),
])
def test_cli_bad_input(tmp_path: Path, program: str, message: str) -> None:
    ngc = tmp_path / "bad.ngc"
    ngc.write_text(program)
    out = tmp_path / "out"
    proc = run_cli("verify", str(CASE_STUDY), str(ngc), "--tool-diameter", "6", "--out", str(out))
    assert proc.returncode == 2
    assert len(proc.stderr.strip().splitlines()) == 1 and message in proc.stderr
    assert not out.exists() or not any(out.iterdir())


def test_cli_tool_too_big(tmp_path: Path) -> None:
    ngc = tmp_path / "p.ngc"
    ngc.write_text(raster_program([50.0], 30.0, 0.0, 100.0))
    proc = run_cli("verify", str(CASE_STUDY), str(ngc), "--tool-diameter", "150",
                   "--out", str(tmp_path / "out"))
    assert proc.returncode == 2 and "not smaller than the part" in proc.stderr
