# SPDX-License-Identifier: LGPL-2.1-or-later
"""``bsplinecam job`` on a plate made with cadquery: a blind hole too narrow for the roughing end
mill's helix, and a closed pocket a helix enters and a slot a zig-zag ramp enters through the
plate (a boss is in TestBSplineCAMRoughingEntries' plate).
Without --centre-cutting the roughing leaves a plug of stock in the hole, and the finishing
ball would cut into it at full width, so the job fails naming T2 and the plug's region; with
--centre-cutting the roughing plunges into the hole and the job passes with every move of both
tools within its limits.  Needs FreeCAD (freecadcmd) and cadquery (the venv) to write the
part."""

from __future__ import annotations

import importlib.util
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from BSplineCAM.orchestration.cli_common import EXIT_CHECK_FAILED

ROOT = Path(__file__).resolve().parent.parent
#: The plate (mm): X 0..70, Y 0..50, Z 0..PLATE_TOP.  A blind hole of HOLE_DIAMETER, too narrow
#: for the roughing's helix, with a flat floor at HOLE_FLOOR_Z; a round pocket (centre,
#: diameter) a helix enters and a slot with round ends (centre, length, width) too narrow for a
#: helix, entered by a zig-zag ramp along it, both through the plate.
PLATE = (70.0, 50.0)
PLATE_TOP = 10.0
HOLE = (15.0, 15.0)
HOLE_DIAMETER = 12.0
HOLE_FLOOR_Z = 4.0
POCKET = ((15.0, 36.0), 16.0)
SLOT = ((48.0, 35.0), 36.0, 12.2)
STEPDOWN = 2.5
CELL = 0.2


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
    solid = cq.Workplane().box(*PLATE, PLATE_TOP, centered=False)
    hole = (cq.Workplane().workplane(offset=HOLE_FLOOR_Z).center(*HOLE)
            .circle(HOLE_DIAMETER / 2).extrude(PLATE_TOP - HOLE_FLOOR_Z))
    (px, py), diameter = POCKET
    pocket = cq.Workplane().center(px, py).circle(diameter / 2).extrude(PLATE_TOP)
    (sx, sy), length, width = SLOT
    slot = cq.Workplane().center(sx, sy).slot2D(length, width).extrude(PLATE_TOP)
    solid = solid.cut(hole).cut(pocket).cut(slot)
    cq.exporters.export(solid, str(path))
    return path


@pytest.fixture(scope="module")
def top_face(plate: Path) -> str:
    """The number of the plate's top face (z PLATE_TOP), the one the job finishes: the hole's
    floor, the other face that looks up, has a ring by its wall that the 6 mm ball cannot
    reach, whose scallop check is not this test's business."""
    from BSplineCAM.orchestration import parts

    tops = []
    for face in parts.load_faces(plate, "up"):
        u0, u1, v0, v1 = face.bounds()
        z = face.surface.evaluate(np.array([0.5 * (u0 + u1)]), np.array([0.5 * (v0 + v1)]))
        if face.selected and abs(float(np.ravel(z)[2]) - PLATE_TOP) < 1e-6:
            tops.append(face.index)
    assert len(tops) == 1, tops
    return str(tops[0])


def job(plate: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(ROOT / "bin" / "bsplinecam"), "job", str(plate), "--stock-margin", "2",
         "--rough", "flat:10", "--stepdown", str(STEPDOWN), "--stepover", "40", "--allowance", "0.3",
         "--finish", "ball:6", "--scallop", "0.1", "--tolerance", "0.01", "--cell", str(CELL),
         *extra, "--out", str(out)],
        capture_output=True, text=True, timeout=900)


def test_plug_in_the_hole_fails_the_job(plate: Path, top_face: str, tmp_path: Path) -> None:
    proc = job(plate, tmp_path / "out", "--faces", top_face)
    assert proc.returncode == EXIT_CHECK_FAILED, proc.stderr[-2000:]
    failed = [s for s in proc.stderr.splitlines() if "check failed: T2 (ball 6 mm) line " in s]
    assert failed, proc.stderr[-2000:]
    report = json.loads((tmp_path / "out" / "verify.json").read_text())
    assert report["checks"]["load_limits"]["ok"] is False
    assert report["ok"] is False
    regions = [r for r in report["loads"]["regions"] if r["tool"] == 2]
    # the region lies in the hole, and the stock it meets is the plug: far thicker than the
    # stock planned for the ball (0.3 + 0.1 + 1 mm), at most from the hole's floor to where
    # the roughing's levels left it, the plate's top + the 0.3 mm allowance
    r = HOLE_DIAMETER / 2
    plug = [g for g in regions if HOLE[0] - r <= g["x0"] <= g["x1"] <= HOLE[0] + r
            and HOLE[1] - r <= g["y0"] <= g["y1"] <= HOLE[1] + r]
    assert plug, regions
    thickest = max(g["stock_mm"] for g in plug)
    assert 3.0 < thickest <= PLATE_TOP + 0.3 - HOLE_FLOOR_Z + 0.05, plug
    message = next(s for s in failed if re.search(r"at x [\d.]+\.\.[\d.]+, y ", s))
    assert "meet" in message and "mm thick" in message
    for overload in report["loads"]["overloads"]:
        assert overload["value"] > overload["limit"]
    assert (tmp_path / "out" / "stock-T2.png").stat().st_size > 0
    # the roughing entered the pocket by a helix and the slot by a zig-zag ramp, and said
    # that it left the hole, and which tool would enter it
    rough = json.loads((tmp_path / "out" / "job.json").read_text())["roughing"]
    assert rough["entries"]["helical"] >= 1 and rough["entries"]["zigzag"] >= 1, rough["entries"]
    assert rough["entries"]["plunge"] == 0
    notes = [n for n in rough["notes"] if "too narrow for a helical entry" in n]
    assert len(notes) == 1 and notes[0].startswith("1 closed pocket"), rough["notes"]
    assert f"({HOLE[0]:.1f}, {HOLE[1]:.1f}) mm" in notes[0] and "--centre-cutting" in notes[0]


def test_centre_cutting_roughing_enters_the_hole(plate: Path, top_face: str,
                                                 tmp_path: Path) -> None:
    proc = job(plate, tmp_path / "out", "--faces", top_face, "--centre-cutting")
    report = json.loads((tmp_path / "out" / "verify.json").read_text()) \
        if (tmp_path / "out" / "verify.json").exists() else {}
    assert report.get("loads", {}).get("overloaded_moves") == 0, (
        proc.stderr[-2000:], report.get("loads", {}).get("regions"))
    assert proc.returncode == 0, proc.stderr[-2000:]
    # every move of both tools within its limits: the end mill a step-down deep at most,
    # entries (helix, zig-zag, plunges) included
    rough = json.loads((tmp_path / "out" / "job.json").read_text())["roughing"]
    assert rough["entries"]["plunge"] >= 1 and rough["entries"]["zigzag"] >= 1, rough["entries"]
    assert not [n for n in rough["notes"] if "too narrow" in n], rough["notes"]
    t1 = report["tools"]["1"]
    slack = CELL / 10 + 1e-6
    assert t1["axial_engagement_max_mm"] <= STEPDOWN + slack, t1
    assert t1["entry_axial_engagement_max_mm"] <= STEPDOWN + slack, t1
    assert report["loads"]["ok"] and report["ok"], report["checks"]
    # the program a controller would run: LinuxCNC's rs274 reads it through
    job_report = json.loads((tmp_path / "out" / "job.json").read_text())
    if shutil.which("rs274") or os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1":
        assert job_report["rs274"]["ok"], job_report["rs274"]
