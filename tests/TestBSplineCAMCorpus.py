# SPDX-License-Identifier: LGPL-2.1-or-later
"""Real parts made by other CAD systems (issue 40, item 5): the corpus of tests/parts/.

Each part of tests/parts/corpus.json goes through the command line as a user would run it:
``check PART``; ``toolpath PART --faces up`` with the raster and the steep_shallow strategies
(ball end of the manifest's diameter, the part's scallop h and tolerance); ``verify PART
PROGRAM --faces up`` on each program; and each program through LinuxCNC's ``rs274 -t TABLE -g
FILE``.  Asserted: exit 0, every face's check ok, gouge <= 1 um (along the design's normal
where verify measures it, as job's gate reads it: :func:`.gouge_normal.gouge_gate_mm`), the
scallop within h + tolerance (plus the depth of the regions the toolpath reports the ball
cannot reach), coverage reported, rs274 accepting the program.  A command that refuses a part for a reason that is not
about to change (no face reachable from above, no solid, a tool wider than the faces, the
readers' limits on periodic trims) has that refusal in the manifest's "expect" (the reason in
"why"), and the test asserts the exact message instead; a refusal the product is being changed
to lift stays a failing test.  Toolpaths too slow for the module's budget (the manifest's
"slow": strategy -> reason) are measured by tools/corpus_table.py only.

The corpus takes minutes, so it runs once per CI: in the suite with BSPLINECAM_REQUIRE_ALL=1
(core-venv), skipped with a reason in the other (core-debian).  Parts whose origin is "shared"
are not committed here; they are read from $BSPLINECAM_SHARED_PARTS or ../shared/parts and
skipped when that folder does not hold them.  docs/parts-corpus.md has the measured table
(tools/corpus_table.py).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
BIN = ROOT / "bin" / "bsplinecam"
PARTS = ROOT / "tests" / "parts"
MANIFEST = json.loads((PARTS / "corpus.json").read_text())
TOOL = float(MANIFEST["tool_diameter_mm"])
REQUIRE_ALL = os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1"
STRATEGIES = ("raster", "steep_shallow")
GOUGE_MM = 1e-3

pytestmark = pytest.mark.skipif(
    not REQUIRE_ALL, reason="the parts corpus runs once per CI, in the suite with "
    "BSPLINECAM_REQUIRE_ALL=1 (core-venv)")


def shared_dir() -> Path:
    text = os.environ.get("BSPLINECAM_SHARED_PARTS")
    return Path(text) if text else ROOT.parent / "shared" / "parts"


def part_path(entry: dict) -> Path:
    """The part's file; skips a shared part that is not here, fails on a changed one."""
    if entry["origin"] != "shared":
        return PARTS / entry["file"]
    path = shared_dir() / entry["file"]
    if not path.is_file():
        pytest.skip(f"{entry['file']} is not in {shared_dir()} (a shared part, not committed "
                    "here: tests/parts/README.md)")
    digest = hashlib.sha256(path.read_bytes()).hexdigest()
    assert digest == entry["sha256"], f"{path} is not the file of the manifest"
    return path


def run_bin(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN), *args], capture_output=True, text=True, timeout=900,
                          cwd=ROOT, stdin=subprocess.DEVNULL, check=False)


def last_line(proc: subprocess.CompletedProcess) -> str:
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    return lines[-1] if lines else ""


def assert_refused(proc: subprocess.CompletedProcess, fragment: str) -> None:
    """The command's refusal of a part it cannot machine: exit 2 and one line naming it."""
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    assert fragment in last_line(proc), last_line(proc)


ENTRIES = {entry["file"]: entry for entry in MANIFEST["parts"]}
NAMES = list(ENTRIES)
#: (part, strategy) whose toolpath ends within the module's budget; the others (the manifest's
#: "slow", with the reason) are measured by tools/corpus_table.py only.
RUNS = [(name, strategy) for name, entry in ENTRIES.items() for strategy in STRATEGIES
        if strategy not in entry.get("slow", {})]


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Results of the commands by (part, command), so that each runs once per module."""
    cache: dict = {"dir": tmp_path_factory.mktemp("corpus")}
    return cache


def toolpath(runs: dict, name: str, strategy: str) -> tuple[subprocess.CompletedProcess, Path]:
    key = (name, strategy)
    if key not in runs:
        entry = ENTRIES[name]
        out = runs["dir"] / f"{Path(name).stem}-{strategy}"
        proc = run_bin("toolpath", str(part_path(entry)), "--faces", "up", "--tool-diameter",
                       str(TOOL), "--scallop", str(entry["scallop"]), "--tolerance",
                       str(entry["tolerance"]), "--strategy", strategy, "--out", str(out))
        runs[key] = (proc, out)
    return runs[key]


@pytest.mark.parametrize("name", NAMES)
def test_check(name):
    """check reports every face; the faces the readers cannot build (the manifest's
    "unbuilt": face -> the start of its error) are reported with their error and named in the
    verdict (exit 1), every other face within the strict limit."""
    entry = ENTRIES[name]
    proc = run_bin("check", str(part_path(entry)))
    if "check" in entry["expect"]:
        assert_refused(proc, entry["expect"]["check"])
        return
    unbuilt = entry["expect"].get("unbuilt", {})
    assert proc.returncode == (1 if unbuilt else 0), last_line(proc)
    report = json.loads(proc.stdout)
    assert report["face_count"] == len(report["faces"]) > 0
    assert report["over_strict_limit"] == list(unbuilt)
    for face in report["faces"]:
        if face["name"] in unbuilt:
            assert face["error"].startswith(unbuilt[face["name"]]), face["error"]
    bad = [(f["index"], f.get("source")) for f in report["faces"]
           if not f["ok"] and f["name"] not in unbuilt]
    assert not bad, f"faces whose NURBS does not match OCCT's: {bad}"
    if unbuilt:
        assert "over the strict limit" in last_line(proc) and \
            ", ".join(unbuilt) in last_line(proc), last_line(proc)


@pytest.mark.parametrize("name, strategy", RUNS)
def test_toolpath(runs, name, strategy):
    entry = ENTRIES[name]
    proc, out = toolpath(runs, name, strategy)
    if "toolpath" in entry["expect"]:
        assert_refused(proc, entry["expect"]["toolpath"])
        return
    assert proc.returncode == 0, last_line(proc)
    report = json.loads(proc.stdout)
    assert report["strategy"] == strategy and report["passes"] > 0 and report["faces"]
    assert report["rs274"]["ok"], report["rs274"]
    assert (out / report["program"]).is_file()


@pytest.mark.parametrize("name, strategy", RUNS)
def test_verify_and_rs274(request, runs, name, strategy):
    """The program, read back from its text: no gouge, the scallop asked for (where the ball
    reaches), coverage reported, and LinuxCNC's interpreter accepting every block.  A known
    fault of the product on a part (the manifest's "known": strategy -> what is measured) is
    a strict expected failure: it fails the suite once it is mended, until the entry goes."""
    from BSplineCAM.core.program import rs274
    from BSplineCAM.core.simulation.gouge_normal import gouge_gate_mm

    entry = ENTRIES[name]
    if strategy in entry.get("known", {}):
        request.applymarker(pytest.mark.xfail(strict=True, reason=entry["known"][strategy]))
    if "toolpath" in entry["expect"]:
        pytest.skip(f"toolpath refuses {name}: {entry['expect']['toolpath']}")
    proc, out = toolpath(runs, name, strategy)
    assert proc.returncode == 0, f"toolpath failed: {last_line(proc)}"
    report = json.loads(proc.stdout)
    ngc = out / report["program"]

    if shutil.which("rs274") is None:
        pytest.fail("rs274 (linuxcnc-uspace) is required here (BSPLINECAM_REQUIRE_ALL=1)")
    result = rs274.check(ngc, {1: TOOL})
    assert result.ok, result.message
    assert result.feeds + result.arcs > 0

    ver = run_bin("verify", str(part_path(entry)), str(ngc), "--faces", "up",
                  "--tool-diameter", str(TOOL), "--out", str(out))
    if "verify" in entry["expect"]:
        assert_refused(ver, entry["expect"]["verify"])
        return
    assert ver.returncode == 0, last_line(ver)
    m = json.loads(ver.stdout)
    assert m["faces"] == report["faces"]
    full = json.loads((out / "verify.json").read_text())  # stdout holds the summary only
    gouge = gouge_gate_mm(full)
    assert gouge <= GOUGE_MM, (gouge, full["gouge_max_mm"], full.get("gouge_normal_at"))
    assert 0.0 < m["coverage"] <= 1.0
    if m.get("scallop_max_mm") is not None:
        # cells the toolpath reports out of the ball's reach keep their depth by design
        left = max([u["depth_mm"] for u in report.get("unreachable", [])], default=0.0)
        bound = entry["scallop"] + entry["tolerance"] + left + GOUGE_MM
        assert m["scallop_max_mm"] <= bound, (m["scallop_max_mm"], bound)
