# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam job`` on a plate with a through hole too narrow for the roughing end mill's
helix: the roughing leaves a plug of stock in the hole, and the finishing ball would cut into
it at full width, so the job fails naming T2 and the plug's region; with --centre-cutting the
roughing plunges into the hole and the job passes with no overload.  Needs FreeCAD
(freecadcmd) and cadquery (the venv) to write the part."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from BSplineCAM.orchestration.cli_common import EXIT_CHECK_FAILED

ROOT = Path(__file__).resolve().parent.parent
#: The plate (mm): X 0..40, Y 0..30, Z 0..10, a through hole of HOLE_DIAMETER at its centre.
HOLE = (20.0, 15.0)
HOLE_DIAMETER = 12.0
PLATE_TOP = 10.0


def have(command: str) -> bool:
    return shutil.which(command) is not None


pytestmark = [
    pytest.mark.venv_only,
    pytest.mark.skipif(
        not have(os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()[0])
        and os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1", reason="freecadcmd is not installed"),
    pytest.mark.skipif(importlib.util.find_spec("cadquery") is None
                       and os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1",
                       reason="cadquery is not installed (the venv has it)"),
]


@pytest.fixture(scope="module")
def plate(tmp_path_factory) -> Path:
    import cadquery as cq

    path = tmp_path_factory.mktemp("plate") / "plate.step"
    solid = (cq.Workplane().box(40, 30, PLATE_TOP, centered=False)
             .faces(">Z").workplane(centerOption="CenterOfBoundBox").hole(HOLE_DIAMETER))
    cq.exporters.export(solid, str(path))
    return path


def job(plate: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(ROOT / "bin" / "bsplinecam"), "job", str(plate), "--stock-margin", "2",
         "--rough", "flat:10", "--stepdown", "2.5", "--stepover", "40", "--allowance", "0.3",
         "--finish", "ball:6", "--scallop", "0.1", "--tolerance", "0.01", "--cell", "0.2",
         "--no-rs274", *extra, "--out", str(out)],
        capture_output=True, text=True, timeout=900)


def test_plug_in_the_hole_fails_the_job(plate: Path, tmp_path: Path) -> None:
    proc = job(plate, tmp_path / "out")
    assert proc.returncode == EXIT_CHECK_FAILED, proc.stderr[-2000:]
    failed = [s for s in proc.stderr.splitlines() if "check failed: T2 (ball 6 mm) line " in s]
    assert failed, proc.stderr[-2000:]
    report = json.loads((tmp_path / "out" / "verify.json").read_text())
    assert report["checks"]["load_limits"]["ok"] is False
    assert report["ok"] is False
    regions = [r for r in report["loads"]["regions"] if r["tool"] == 2]
    # the region lies in the hole, and the stock it meets stands from the block's bottom (the
    # plate's, z 0) to where the roughing's levels left it: the plate's top + the 0.3 mm
    # allowance
    r = HOLE_DIAMETER / 2
    plug = [g for g in regions if HOLE[0] - r <= g["x0"] <= g["x1"] <= HOLE[0] + r
            and HOLE[1] - r <= g["y0"] <= g["y1"] <= HOLE[1] + r]
    assert plug, regions
    assert max(g["stock_mm"] for g in plug) == pytest.approx(PLATE_TOP + 0.3, abs=0.05)
    message = next(s for s in failed if re.search(r"at x [\d.]+\.\.[\d.]+, y ", s))
    assert "meet" in message and "mm thick" in message
    for overload in report["loads"]["overloads"]:
        assert overload["value"] > overload["limit"]
    assert (tmp_path / "out" / "stock-T2.png").stat().st_size > 0


def _centre_cutting_available() -> bool:
    text = (ROOT / "BSplineCAM" / "core" / "toolpath" / "roughing" / "__init__.py").read_text()
    return "centre_cutting" in text


@pytest.mark.skipif(not _centre_cutting_available(),
                    reason="the roughing's centre-cutting plunge (generate_roughing("
                           "centre_cutting=True)) is not in this tree")
def test_centre_cutting_roughing_enters_the_hole(plate: Path, tmp_path: Path) -> None:
    proc = job(plate, tmp_path / "out", "--centre-cutting")
    report = json.loads((tmp_path / "out" / "verify.json").read_text()) \
        if (tmp_path / "out" / "verify.json").exists() else {}
    assert report.get("loads", {}).get("overloaded_moves") == 0, (
        proc.stderr[-2000:], report.get("loads", {}).get("regions"))
    assert proc.returncode == 0, proc.stderr[-2000:]
