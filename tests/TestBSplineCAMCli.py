# SPDX-License-Identifier: LGPL-2.1-or-later
"""The command line against adversarial options (issue 10): one stderr line naming the option
and its unit, exit status 2, no traceback, no folder or staging files left; strict JSON;
the cutter-location and Z-map limits; SIGINT and SIGTERM; verify's extent and units warnings.

Validation runs in-process through ``cli.main`` (no FreeCAD needed); a few cases run the real
``bin/bsplinecam`` (freecadcmd), skipped when it is absent unless BSPLINECAM_REQUIRE_ALL=1.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
from conftest import CASE_STUDY, ROOT, plane_net, run_main

from BSplineCAM.core import ParameterError, Surface
from BSplineCAM.core.program.gcode import read_gcode
from BSplineCAM.core.simulation.simulate import MAX_ZMAP_CELLS, Tool, zmap_shape
from BSplineCAM.core.simulation.verify import extent_warnings, verify
from BSplineCAM.core.toolpath import (
    MAX_CUTTER_LOCATIONS,
    check_request,
    estimated_cutter_locations,
    generate,
)
from BSplineCAM.core.toolpath.common import ToolParameters, flat_stepover
from BSplineCAM.orchestration import cli

CASE = str(CASE_STUDY)


def small_net(tmp_path: Path, size: float = 30.0) -> Path:
    """A 4 x 4 clamped net over size x size mm (a Bezier patch with a bump)."""
    t = np.linspace(0.0, size, 4)
    x, y = np.meshgrid(t, t, indexing="ij")
    z = np.array([0.0, 3.0, 2.0, 0.0])[:, None] + np.array([0.0, 1.0, 2.0, 0.0])[None, :]
    path = tmp_path / "n4.json"
    path.write_text(json.dumps({"name": "n4", "knots": "clamped",
                                "control_points": np.stack([x, y, z], -1).tolist()}))
    return path


def assert_refused(status: int, err: str, *fragments: str) -> None:
    assert status == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for fragment in fragments:
        assert fragment in lines[0], lines[0]


# -- toolpath options (refused before FreeCAD is needed) ----------------------------------------
TOOLPATH = ["toolpath", CASE, "--tool-diameter", "6", "--scallop", "0.01"]


@pytest.mark.parametrize("extra, fragments", [
    (["--spindle", "inf"], ["--spindle", "rpm"]),
    (["--spindle", "0"], ["--spindle", "rpm"]),
    (["--spindle", "1e308"], ["--spindle", "rpm"]),
    (["--feed", "inf"], ["--feed", "mm/min"]),
    (["--feed=-inf"], ["--feed", "mm/min"]),
    (["--feed", "nan"], ["--feed", "mm/min"]),
    (["--feed", "1e-9"], ["--feed", "mm/min"]),
    (["--feed", "1e-300"], ["--feed", "mm/min"]),
    (["--plunge-feed", "0"], ["--plunge-feed", "mm/min"]),
    (["--plunge-feed=-400"], ["--plunge-feed", "mm/min"]),
    (["--rapid", "nan"], ["--rapid", "mm/min"]),
    (["--rapid", "1e308"], ["--rapid", "mm/min"]),
    (["--angle", "inf"], ["--angle", "degrees"]),
    (["--angle", "1e20"], ["--angle", "degrees"]),
    (["--angle=-1e308"], ["--angle", "degrees"]),
    (["--angle", "nan"], ["--angle", "degrees"]),
    (["--tool-diameter", "0"], ["--tool-diameter", "mm"]),
    (["--tool-diameter=-6"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "1e308"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "1e-300"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "150"], ["--tool-diameter", "not smaller than the part"]),
    (["--scallop", "0"], ["--scallop", "mm"]),
    (["--scallop", "nan"], ["--scallop", "mm"]),
    (["--scallop", "4"], ["--scallop", "mm"]),
    (["--scallop", "1e-9"], ["--scallop", "million cutter locations"]),
    (["--scallop", "1e-300"], ["--scallop", "million cutter locations"]),
    (["--tolerance", "0"], ["--tolerance", "mm"]),
    (["--tolerance", "inf"], ["--tolerance", "mm"]),
    (["--tolerance", "1e-300"], ["--tolerance", "mm"]),
    (["--scallop", ""], ["--scallop"]),
    (["--feed", "fast"], ["--feed"]),
    (["--strategy", "spiral"], ["--strategy"]),
    (["--direction", ""], ["--direction"]),
    (["--knots", "periodic"], ["--knots"]),
    (["--tool-diameter", str(10**400)], ["--tool-diameter"]),
])
def test_toolpath_options_refused(capsys, tmp_path, extra, fragments):
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, *TOOLPATH, *extra, "--out", str(out))
    assert_refused(status, err, *fragments)
    assert stdout == ""
    assert not out.exists()


def test_small_net_tiny_scallop_refused_before_work(capsys, tmp_path):
    """The issue's case: a 1e-9 mm scallop on a 4x4 net ran out of memory."""
    net = small_net(tmp_path)
    out = tmp_path / "out"
    status, _, err = run_main(capsys, "toolpath", str(net), "--tool-diameter", "6",
                              "--scallop", "1e-9", "--out", str(out))
    assert_refused(status, err, "--scallop", "million cutter locations")
    assert not out.exists()


# -- output folders ---------------------------------------------------------------------------------
def out_cases(tmp_path: Path) -> dict[str, tuple[str, str]]:
    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    return {
        "file": (str(a_file), "is a file"),
        "under a file": (str(a_file / "sub" / "deeper"), "is a file"),
        "empty": ("", "must name a folder"),
        "unwritable": ("/proc/bsplinecam-test/out", "--out"),
    }


@pytest.mark.parametrize("case", ["file", "under a file", "empty", "unwritable"])
@pytest.mark.parametrize("command", ["surface", "toolpath", "verify"])
def test_bad_output_folder(capsys, tmp_path, command, case):
    out, fragment = out_cases(tmp_path)[case]
    program = tmp_path / "p.ngc"
    program.write_text("G21 G90\nG0 X10 Y10 Z30\nG1 Z20 F500\nG1 X90\nG0 Z30\nM2\n")
    argv = {"surface": ["surface", CASE],
            "toolpath": TOOLPATH,
            "verify": ["verify", CASE, str(program), "--tool-diameter", "6"]}[command]
    status, _, err = run_main(capsys, *argv, "--out", out)
    assert_refused(status, err, "--out", fragment)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "p.ngc"]


def test_staged_output_removes_created_folders_on_error(tmp_path):
    out = tmp_path / "a" / "b"
    with pytest.raises(ParameterError), cli.staged_output(out) as stage:
        (stage / "x.json").write_text("{}")
        raise ParameterError("refused")
    assert list(tmp_path.iterdir()) == []
    existing = tmp_path / "kept"
    existing.mkdir()
    (existing / "old.txt").write_text("old")
    with pytest.raises(cli.Interrupted), cli.staged_output(existing) as stage:
        (stage / "x.json").write_text("{}")
        raise cli.Interrupted(signal.SIGTERM)
    assert [p.name for p in existing.iterdir()] == ["old.txt"]


def test_output_file_over_a_folder_writes_nothing(tmp_path):
    out = tmp_path / "out"
    (out / "b.json").mkdir(parents=True)
    with pytest.raises(cli.OutputError, match="b.json"), cli.staged_output(out) as stage:
        (stage / "a.json").write_text("{}")
        (stage / "b.json").write_text("{}")
    assert [p.name for p in out.iterdir()] == ["b.json"]  # a.json not moved in either


# -- check and surface --------------------------------------------------------------------------------
@pytest.mark.parametrize("argv, fragment", [
    (["check", CASE, "--samples", "0"], "--samples"),
    (["check", CASE, "--samples", "-5"], "--samples"),
    (["check", CASE, "--samples", "1"], "--samples"),
    (["check", CASE, "--samples", str(10**30)], "--samples"),
    (["check", CASE, "--samples", "1.5"], "--samples"),
    (["check", CASE, "--samples", "nan"], "--samples"),
    (["surface", CASE, "--samples", "0"], "--samples"),
    (["surface", CASE, "--dat-samples", "0"], "--dat-samples"),
    (["surface", CASE, "--dat-samples", str(10**18)], "--dat-samples"),
])
def test_samples_refused(capsys, tmp_path, argv, fragment):
    out = tmp_path / "out"
    extra = ["--out", str(out)] if argv[0] == "surface" else []
    status, stdout, err = run_main(capsys, *argv, *extra)
    assert_refused(status, err, fragment)
    assert stdout == "" and not out.exists()


def test_unknown_command_and_missing_option_one_line(capsys):
    for argv in (["mill", CASE], ["toolpath", CASE, "--out", "x"], []):
        status, _, err = run_main(capsys, *argv)
        assert_refused(status, err)


# -- verify ------------------------------------------------------------------------------------------
def raster_text(units: str = "G21", scale: float = 1.0, dx: float = 0.0) -> str:
    """Ball passes at z = 10 over the 60 x 40 plane, every 2 mm, numbers times ``scale``."""
    lines = [f"{units} G90 G17", f"G0 X{dx:.4f} Y0 Z{30 * scale:.4f}"]
    for k, y in enumerate(np.arange(0.0, 40.01, 2.0)):
        x0, x1 = (0.0, 60.0) if k % 2 == 0 else (60.0, 0.0)
        lines.append(f"G1 X{(x0 + dx) * scale:.4f} Y{y * scale:.4f} Z{10 * scale:.4f} F{600 * scale:.3f}")
        lines.append(f"G1 X{(x1 + dx) * scale:.4f}")
    lines += [f"G0 Z{30 * scale:.4f}", "M2"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("extra, fragments", [
    (["--tool-diameter", "inf"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "0"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "1e308"], ["--tool-diameter", "mm"]),
    (["--tool-diameter", "50"], ["--tool-diameter", "not smaller than the part"]),
    (["--cell", "0"], ["--cell", "mm"]),
    (["--cell", "1e-300"], ["--cell", "mm"]),
    (["--cell", "0.002"], ["--cell", "million Z-map cells"]),
    (["--cell", "inf"], ["--cell", "mm"]),
    (["--stock-margin=-1"], ["--stock-margin", "mm"]),
    (["--stock-margin", "1e308"], ["--stock-margin", "mm"]),
    (["--stock-margin", "nan"], ["--stock-margin", "mm"]),
    (["--rapid-rate", "0"], ["--rapid-rate", "mm/min"]),
    (["--rapid-rate", "inf"], ["--rapid-rate", "mm/min"]),
    (["--coverage-tolerance", "0"], ["--coverage-tolerance", "mm"]),
    (["--coverage-tolerance=-inf"], ["--coverage-tolerance", "mm"]),
    (["--corner-radius", "nan"], ["--corner-radius", "mm"]),
    (["--tool-shape", "bullnose", "--corner-radius", "0"], ["--corner-radius", "mm"]),
    (["--tool-shape", "bullnose", "--corner-radius", "9"], ["--corner-radius", "mm"]),
    (["--tool-shape", "cone"], ["--tool-shape"]),
    (["--stock-top", "air"], ["--stock-top"]),
])
def test_verify_options_refused(capsys, tmp_path, extra, fragments):
    program = tmp_path / "p.ngc"
    program.write_text(raster_text())
    out = tmp_path / "out"
    argv = ["verify", str(plane_net(tmp_path)), str(program), "--tool-diameter", "6", *extra,
            "--out", str(out)]
    status, stdout, err = run_main(capsys, *argv)
    assert_refused(status, err, *fragments)
    assert stdout == "" and not out.exists()


def test_verify_warns_on_mm_numbers_under_g20(capsys, tmp_path):
    """The issue's case: a G20 program whose numbers are mm is warned about, not verified to
    coverage 0 without a word."""
    if os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1":
        pytest.importorskip("matplotlib")  # the pictures (Debian's python3 has none)
    program = tmp_path / "p.ngc"
    program.write_text(raster_text("G20"))
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, "verify", str(plane_net(tmp_path)), str(program),
                                   "--tool-diameter", "6", "--cell", "0.5", "--out", str(out))
    assert status == 0, err
    report = json.loads((out / "verify.json").read_text())
    assert report["converted_from_inches"] is True
    assert any("units look wrong" in w and "G20" in w for w in report["warnings"])
    assert "warning" in err and "units look wrong" in err and "Traceback" not in err
    assert json.loads(stdout)["warnings"] == report["warnings"]


def test_extent_warnings_against_the_footprint():
    x, y = np.meshgrid(np.linspace(0, 60, 4), np.linspace(0, 40, 4), indexing="ij")
    surface = Surface(np.stack([x, y, np.full((4, 4), 10.0)], -1), "clamped")
    footprint = (0.0, 60.0, 0.0, 40.0)
    assert extent_warnings(read_gcode(raster_text()), footprint, 3.0) == []
    far = extent_warnings(read_gcode(raster_text(dx=500.0)), footprint, 3.0)
    assert len(far) == 1 and "does not overlap" in far[0]
    inches = extent_warnings(read_gcode(raster_text("G21", 1 / 25.4)), footprint, 3.0)
    assert len(inches) == 1 and "numbers inches" in inches[0]
    # verify() records them too, and a program off the part leaves coverage 0 with a warning
    result = verify(surface, read_gcode(raster_text(dx=500.0)), Tool(6.0), cell=0.5)
    assert result.metrics["coverage"] == 0.0
    assert [w.split(":")[0] for w in result.metrics["warnings"]] == [far[0].split(":")[0]]
    assert "does not overlap the part's footprint X 0 to 60" in result.metrics["warnings"][0]


# -- limits in the core --------------------------------------------------------------------------------
def test_estimate_bounds_real_toolpaths():
    """The estimate is an upper bound of the cutter locations actually produced, and the
    closed form on a plane: area / (flat stepover * sqrt(8 R tol))."""
    surface = Surface.from_json(CASE_STUDY)
    t = np.linspace(0.0, 1.0, 4)
    x, y = np.meshgrid(t * 60.0, t * 40.0, indexing="ij")
    plane = Surface(np.stack([x, y, np.full_like(x, 5.0)], -1), "clamped")
    tool = ToolParameters.validate(6.0, 0.05, 0.002)
    expected = 60.0 * 40.0 / (flat_stepover(3.0, 0.05) * math.sqrt(8 * 3.0 * 0.002))
    assert estimated_cutter_locations(plane, tool, "raster") == pytest.approx(expected, rel=1e-9)
    for s, strategy in ((plane, "raster"), (surface, "raster"), (surface, "isoparametric")):
        tp = generate(s, strategy, tool_diameter=6.0, scallop=0.05)
        produced = sum(len(p) for p in tp.passes)
        assert produced <= estimated_cutter_locations(s, tool, strategy)


@pytest.mark.parametrize("strategy", ["raster", "waterline", "isoparametric"])
def test_absurd_requests_refused_by_generate(tmp_path, strategy):
    """The FreeCAD op calls generate(): the same refusal, before any allocation."""
    surface = Surface.from_file(small_net(tmp_path))
    for kwargs in ({"scallop": 1e-9}, {"scallop": 1e-300}, {"tool_diameter": 0.02,
                                                            "scallop": 1e-6}):
        with pytest.raises(ParameterError, match="million cutter locations"):
            generate(surface, strategy, **{"tool_diameter": 6.0, **kwargs})
    for kwargs, name in (({"angle": 1e20}, "angle"), ({"tool_diameter": 40.0}, "tool_diameter"),
                         ({"tool_diameter": float("inf")}, "tool_diameter")):
        with pytest.raises(ParameterError, match=name):
            generate(surface, strategy, **{"tool_diameter": 6.0, "scallop": 0.1, **kwargs})
    assert MAX_CUTTER_LOCATIONS >= 1_000_000


def test_check_request_names_the_options():
    surface = Surface.from_json(CASE_STUDY)
    names = ("--tool-diameter", "--scallop", "--tolerance", "--angle")
    with pytest.raises(ParameterError, match="--angle must lie in"):
        check_request(surface, "raster", 6, 0.01, 0.002, 400.0, names)
    strategy, tool, angle = check_request(surface, "raster", 6, 0.01, 0.002, -30.0, names)
    assert (strategy.value, tool.radius, angle) == ("raster", 3.0, -30.0)


def test_zmap_cell_limit():
    nx, ny = zmap_shape(100.0, 100.0, 0.1)
    assert (nx, ny) == (1000, 1000)
    side = math.sqrt(MAX_ZMAP_CELLS) * 0.1
    with pytest.raises(ParameterError, match="--cell 0.05 mm"):
        zmap_shape(side, side, 0.05, "--cell")
    for cell in (1e-300, 5e-324):
        with pytest.raises(ParameterError, match="Z-map cells"):
            zmap_shape(100.0, 100.0, cell)


# -- strict JSON and the console capture -----------------------------------------------------------
def test_strict_json():
    text = cli.json_text({"a": float("nan"), "b": [float("inf"), 1.5, np.float64(-np.inf)],
                          "c": np.array([1.0, np.nan]), "d": np.int64(3)})
    assert json.loads(text) == {"a": None, "b": [None, 1.5, None], "c": [1.0, None], "d": 3}
    assert "NaN" not in text and "Infinity" not in text


def test_refusal_inside_captured_console_prints_one_line(capfd, monkeypatch):
    """What FreeCAD prints during a refused recompute (its traceback) is dropped."""
    def refused(args):
        with cli.captured_console():
            os.write(2, b"Traceback (most recent call last):\n  File ...\nValueError: x\n")
            os.write(1, b"Recompute......\n")
            raise ValueError("SurfaceFinish: refused inside the recompute")

    def accepted(args):
        with cli.captured_console():
            os.write(2, b"progress chatter\n")
        return 0

    parser = cli.build_parser()
    monkeypatch.setattr(cli, "build_parser", lambda: parser)
    for func, status_expected in ((refused, 2), (accepted, 0)):
        parser._subparsers._group_actions[0].choices["check"].set_defaults(func=func)
        status = cli.main(["check", CASE])
        out, err = capfd.readouterr()
        assert status == status_expected
        if func is refused:
            assert err.strip().splitlines() == [
                "bsplinecam check: error: SurfaceFinish: refused inside the recompute"]
            assert out == ""
        else:
            assert "progress chatter" in err


# -- the real command line: signals -------------------------------------------------------------------
def have_freecadcmd() -> bool:
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()[0]
    return shutil.which(cmd) is not None


needs_freecad = pytest.mark.skipif(
    not have_freecadcmd() and os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1",
    reason="freecadcmd is not installed")


@pytest.mark.venv_only
@needs_freecad
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_signal_removes_staging(tmp_path, signum):
    out = tmp_path / "new" / "out"
    proc = subprocess.Popen(
        [str(ROOT / "bin" / "bsplinecam"), "toolpath", CASE, "--tool-diameter", "6",
         "--scallop", "0.001", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 300
        while not (out.exists() and any(p.name.startswith(".staging-") for p in out.iterdir())):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no staging folder appeared"
            time.sleep(0.1)
        time.sleep(1.0)  # inside FreeCAD's job by now
        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signum, stderr
    # FreeCAD's own chatter from outside the captured recompute may precede it (it is not a
    # traceback); the command's last word is one line
    assert stderr.strip().splitlines()[-1] == (
        f"bsplinecam toolpath: interrupted by {signal.Signals(signum).name}; nothing was written")
    assert "Traceback" not in stderr
    assert stdout == ""
    assert not (tmp_path / "new").exists()


@pytest.mark.venv_only
@needs_freecad
def test_real_cli_refusal_is_one_line(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.run(
        [str(ROOT / "bin" / "bsplinecam"), "toolpath", str(small_net(tmp_path)),
         "--tool-diameter", "6", "--scallop", "1e-9", "--out", str(out)],
        capture_output=True, text=True, timeout=300)
    assert_refused(proc.returncode, proc.stderr, "--scallop", "million cutter locations")
    assert not out.exists()


# -- job options (refused before FreeCAD is needed) ---------------------------------------------
JOB = ["job", CASE]


@pytest.mark.parametrize("extra, fragments", [
    (["--stepdown", "0"], ["--stepdown", "mm"]),
    (["--stepdown=-2"], ["--stepdown", "mm"]),
    (["--stepdown", "nan"], ["--stepdown", "mm"]),
    (["--fine-stepdown", "3"], ["--fine-stepdown", "mm"]),
    (["--fine-stepdown=-1"], ["--fine-stepdown", "mm"]),
    (["--fine-stepdown", "inf"], ["--fine-stepdown", "mm"]),
    (["--ramp-angle", "0"], ["--ramp-angle", "degrees"]),
    (["--ramp-angle", "45"], ["--ramp-angle", "degrees"]),
    (["--ramp-angle", "nan"], ["--ramp-angle", "degrees"]),
    (["--stepover", "0"], ["--stepover", "%"]),
    (["--stepover", "150"], ["--stepover", "%"]),
    (["--allowance=-0.3"], ["--allowance", "mm"]),
    (["--radial-allowance", "inf"], ["--radial-allowance", "mm"]),
    (["--axial-allowance=-1"], ["--axial-allowance", "mm"]),
    (["--stock-margin=-2"], ["--stock-margin", "mm"]),
    (["--rough", "drill:5"], ["--rough", "drill"]),
    (["--rough", "flat"], ["--rough"]),
    (["--rough", "flat:0"], ["--rough"]),
    (["--rough", "bullnose:10:7"], ["--rough bullnose:10:7: bull-nose corner radius"]),
    (["--rough", "flat:ten"], ["--rough flat:ten: diameter 'ten' is not a number"]),
    (["--finish", "flat:6"], ["--finish", "ball end"]),
    (["--finish", "ball:-6"], ["--finish"]),
    (["--scallop", "0"], ["--scallop", "mm"]),
    (["--rest-limit=-1"], ["--rest-limit", "mm"]),
    (["--cell", "0"], ["--cell", "mm"]),
    (["--post", "linuxcnc,,grbl"], ["--post"]),
    (["--post", "linuxcnc,linuxcnc"], ["--post"]),
    (["--feed", "0"], ["--feed", "mm/min"]),
    (["--faces", "3"], ["--faces"]),
])
def test_job_options_refused(capsys, tmp_path, extra, fragments):
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, *JOB, *extra, "--out", str(out))
    assert_refused(status, err, *fragments)
    assert stdout == ""
    assert not out.exists()


@pytest.mark.parametrize("extra, fragments", [
    (["--knots", "uniform"], ["--knots", "control nets"]),
])
def test_job_on_a_part_refuses_what_parts_lack(capsys, tmp_path, extra, fragments):
    """Knots belong to control nets; the refusal comes before the part is read or FreeCAD
    loaded."""
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, "job", str(ROOT / "examples" / "part.step"), *extra,
                                   "--out", str(out))
    assert_refused(status, err, *fragments)
    assert stdout == ""
    assert not out.exists()


def test_job_engagement_target_allows_the_simulation_cell_and_warns_when_missed():
    """``job`` reports the roughing's widest cut against 1.1 stepover plus the simulation's
    cell (its width is the engaged cells' extent plus a cell: a cut at 1.1 s measures up to
    a cell more), and warns when it is missed, naming the width, the program line and the
    limit in mm."""
    from BSplineCAM.orchestration.cli_job import engagement_targets, engagement_warnings

    def as_report(targets):
        return {k: {"value": v, "limit": lim, "ok": ok} for k, (v, lim, ok) in targets.items()}

    within = engagement_targets({"radial_engagement_max_mm": 4.5}, 4.0, 0.1)
    assert within["roughing_radial_engagement_max_mm"] == [4.5, 4.5, True]
    assert engagement_warnings(as_report(within), {"max_radial_line": 9}, 4.0, 0.1) == []
    rough = {"radial_engagement_max_mm": 4.62, "max_radial_line": 812}
    over = as_report(engagement_targets(rough, 4.0, 0.1))
    assert over["roughing_radial_engagement_max_mm"]["ok"] is False
    (warning,) = engagement_warnings(over, rough, 4.0, 0.1)
    for part in ("4.62 mm", "line 812", "stepover 4 mm", "0.1 mm cell", "(4.5 mm)"):
        assert part in warning, warning
    # no cut at all (a program without roughing moves): within, nothing to say
    none = engagement_targets({"radial_engagement_max_mm": None}, 4.0, 0.1)
    assert none["roughing_radial_engagement_max_mm"][2] is True
