# SPDX-License-Identifier: LGPL-2.1-or-later
"""A part file that makes OCCT crash or hang never takes a command down silently (issue 40).

Damaged copies of examples/part.step are made here at test time: truncations, garbage bytes,
an empty file, changed numbers in B_SPLINE and CARTESIAN_POINT entities and broken entity
references.  A block of garbage bytes in the middle makes OCCT's reader segfault in FreeCAD
0.20, 1.0 and 1.1, a B-spline whose pole list names a DIRECTION in FreeCAD 0.20; rescaled
coordinates keep it busy for minutes.  Two test hooks of the worker stand in for a broken
reader on any FreeCAD: BSPLINECAM_TEST_CRASH_READ=1 (SIGSEGV) and BSPLINECAM_TEST_HANG_READ=1
(sleeps).  Every command that reads a part (check, toolpath, verify, job) must then exit with
status 2 and one stderr line naming the file, no traceback, nothing in --out, within a bounded
time.  tests/parts/damaged/* (when present) go through check and toolpath: each is refused
under the same rule or, when FreeCAD recovers the file, read with a JSON result.

The real ``bin/bsplinecam`` (freecadcmd) is skipped when absent unless BSPLINECAM_REQUIRE_ALL=1.
The command runs go two at a time, in a module fixture: the module takes about 1.5 minutes on
two cores.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM.app import runtime  # noqa: E402
from BSplineCAM.orchestration import parts  # noqa: E402

EXAMPLE = ROOT / "examples" / "part.step"
BIN = ROOT / "bin" / "bsplinecam"
DAMAGED_CORPUS = ROOT / "tests" / "parts" / "damaged"
REQUIRE_ALL = os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1"
#: Seconds a command on a damaged part may take (a crash or a reader's error: a few seconds).
BOUND_S = 90.0
#: The short part time limit (s) of the hang cases.
SHORT_LIMIT_S = 3
SIGSEGV_LINE = "cannot read the part: OCCT stopped with signal 11 (SIGSEGV) while reading it"


def have_freecadcmd() -> bool:
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()[0]
    return shutil.which(cmd) is not None


needs_freecad = pytest.mark.skipif(not have_freecadcmd() and not REQUIRE_ALL,
                                   reason="freecadcmd is not installed")


# -- damaged copies of examples/part.step ---------------------------------------------------------
def _sub_once(pattern: str, repl, text: str) -> str:
    """``text`` with the first match of ``pattern`` replaced; the pattern must match."""
    changed, count = re.subn(pattern, repl, text, count=1, flags=re.S)
    assert count == 1, f"examples/part.step no longer holds {pattern!r}"
    return changed


def _direction_id(text: str) -> str:
    return re.search(r"#(\d+) = DIRECTION\(", text).group(1)


def _pole_to_direction(pattern: str):
    """The pole reference captured by ``pattern`` (group 1) replaced by a DIRECTION's."""
    def damage(text: str) -> str:
        direction = _direction_id(text)
        return _sub_once(pattern, lambda m: m.group(0)[: m.start(1) - m.start(0)]
                         + direction + m.group(0)[m.end(1) - m.start(0):], text)
    return damage


def _truncate(fraction: float):
    return lambda data: data[: int(len(data) * fraction)]


def _garbage_block(fraction: float):
    junk = bytes((i * 37) % 256 for i in range(4000))
    return lambda data: (data[: int(len(data) * fraction)] + junk
                         + data[int(len(data) * fraction) + len(junk):])


def _point_overflow(text: str) -> str:
    pole = re.search(r"B_SPLINE_SURFACE_WITH_KNOTS\('',\d+,\d+,\(\s*\(#(\d+)", text).group(1)
    return _sub_once(rf"(#{pole} = CARTESIAN_POINT\('',)\([^)]*\)", r"\1(-5.E308,-5.E999,1.)",
                     text)


def _shell_to_point(text: str) -> str:
    point = re.search(r"#(\d+) = CARTESIAN_POINT", text).group(1)
    return _sub_once(r"MANIFOLD_SOLID_BREP\('',#\d+\)", f"MANIFOLD_SOLID_BREP('',#{point})", text)


def _digits_rescaled(text: str) -> str:
    """Two digits of every CARTESIAN_POINT swapped around an exponent E9: OCCT's reader and
    its shape fixes run on for minutes."""
    changed = re.sub(r"(CARTESIAN_POINT\('',\([^)]*?)(\d)(\d)",
                     lambda m: m.group(1) + m.group(3) + "E9" + m.group(2), text)
    assert changed != text
    return changed


#: name -> (damage of the bytes or of the text, True when it is bytes)
DAMAGES = {
    "empty": (lambda data: b"", True),
    "truncated-5%": (_truncate(0.05), True),
    "truncated-30%": (_truncate(0.30), True),
    "truncated-77%": (_truncate(0.77), True),
    "truncated-99.9%": (_truncate(0.999), True),
    "garbage": (lambda data: bytes(range(256)) * 50, True),
    "garbage-block-42%": (_garbage_block(0.42), True),  # SIGSEGV in FreeCAD 0.20, 1.0, 1.1
    "garbage-block-60%": (_garbage_block(0.60), True),  # SIGSEGV in FreeCAD 0.20, 1.0, 1.1
    "surface-degree-30": (lambda t: _sub_once(r"(B_SPLINE_SURFACE_WITH_KNOTS\('',)\d+",
                                              r"\g<1>30", t), False),
    "curve-multiplicity-70": (lambda t: _sub_once(
        r"(B_SPLINE_CURVE_WITH_KNOTS\('',\d+,\([^;]*?\.[TF]\.,\.[TF]\.,\()\d+", r"\g<1>70", t),
        False),
    "rational-multiplicity-99": (lambda t: _sub_once(
        r"(B_SPLINE_SURFACE_WITH_KNOTS\(\()\d+", r"\g<1>99", t), False),
    "point-overflow": (_point_overflow, False),
    # a DIRECTION where a pole (CARTESIAN_POINT) belongs: SIGSEGV in FreeCAD 0.20's OCCT
    "surface-pole-is-direction": (_pole_to_direction(
        r"B_SPLINE_SURFACE_WITH_KNOTS\('',\d+,\d+,\(\s*\(#(\d+)"), False),
    "curve-pole-is-direction": (_pole_to_direction(
        r"B_SPLINE_CURVE_WITH_KNOTS\('',\d+,\(#\d+,#(\d+)"), False),
    "rational-pole-is-direction": (_pole_to_direction(
        r"B_SPLINE_SURFACE\(\d+,\d+,\(\s*\(#\d+,#(\d+)"), False),
    "shell-is-point": (_shell_to_point, False),
}
#: Damages that keep OCCT busy for minutes: run under a short time limit.
HANGING = {"digits-rescaled": (_digits_rescaled, False)}
#: Damages that crash FreeCAD 0.20's OCCT reader (the first also 1.0's and 1.1's); toolpath
#: (and check) run over these.
CRASHING = ("garbage-block-42%", "surface-pole-is-direction", "curve-pole-is-direction",
            "rational-pole-is-direction")


def make_damaged(folder: Path, name: str) -> Path:
    damage, on_bytes = {**DAMAGES, **HANGING}[name]
    data = EXAMPLE.read_bytes()
    damaged = damage(data) if on_bytes else damage(data.decode()).encode()
    assert damaged != data
    path = folder / f"{name}.step"
    path.write_bytes(damaged)
    return path


# -- running the command line ---------------------------------------------------------------------
@dataclass
class Run:
    part: Path
    out: Path
    returncode: int
    stdout: str
    stderr: str
    seconds: float


def command(kind: str, part: Path, out: Path, work: Path) -> list[str]:
    """``bsplinecam KIND PART ...`` with the options each command needs, writing in ``out``."""
    if kind == "check":
        return ["check", str(part), "--out", str(out)]
    if kind == "toolpath":
        return ["toolpath", str(part), "--tool-diameter", "6", "--scallop", "0.05",
                "--no-rs274", "--out", str(out)]
    if kind == "verify":
        program = work / "program.ngc"
        program.write_text("G21 G90\nG0 Z30\nG1 X10 Y10 Z20 F500\nM2\n")
        return ["verify", str(part), str(program), "--tool-diameter", "6", "--out", str(out)]
    if kind == "job":
        return ["job", str(part), "--no-rs274", "--out", str(out)]
    raise ValueError(kind)


def own_home(work: Path) -> dict:
    """HOME in ``work``: FreeCAD's user.cfg of this run alone (FreeCAD processes that start
    and end at the same time can catch each other's user.cfg half-written, and FreeCAD then
    prints "Malformed Parameter document" on stderr)."""
    home = work / "home"
    home.mkdir(parents=True, exist_ok=True)
    return {"HOME": str(home)}


def run_bin(kind: str, part: Path, work: Path, env: dict | None = None) -> Run:
    work.mkdir(parents=True, exist_ok=True)
    out = work / "out"
    started = time.perf_counter()
    proc = subprocess.run([str(BIN), *command(kind, part, out, work)], capture_output=True,
                          text=True, timeout=600, cwd=ROOT, check=False,
                          env={**os.environ, **own_home(work), **(env or {})})
    return Run(part, out, proc.returncode, proc.stdout, proc.stderr,
               time.perf_counter() - started)


def assert_isolated(run: Run, bound: float = BOUND_S) -> str:
    """Exit status 2, one stderr line naming the file, no traceback, no stdout, nothing in
    --out, within ``bound`` seconds; returns the line."""
    assert run.returncode == 2, (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr, run.stderr
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1, run.stderr
    assert lines[0].startswith("bsplinecam "), lines[0]
    assert str(run.part) in lines[0], lines[0]
    assert run.stdout == ""
    assert not run.out.exists(), sorted(p.name for p in run.out.iterdir())
    assert run.seconds < bound, run.seconds
    return lines[0]


def assert_not_silent(run: Run) -> None:
    """A corpus file: refused as :func:`assert_isolated` says, or read (FreeCAD recovers some
    damaged documents) with a JSON result and no traceback; never a crash."""
    if run.returncode == 2:
        assert_isolated(run)
        return
    assert run.returncode in (0, 1), (run.returncode, run.stderr)
    assert "Traceback" not in run.stderr and "signal" not in run.stderr, run.stderr
    assert run.stdout.lstrip().startswith("{"), run.stdout
    assert run.seconds < 300, run.seconds


def _corpus() -> list[Path]:
    if not DAMAGED_CORPUS.is_dir():
        return []
    return sorted(p for p in DAMAGED_CORPUS.iterdir() if p.is_file() and parts.is_part(p))


#: (id, command, damage name or corpus file, extra environment, time bound s)
CASES = (
    [(f"check-{name}", "check", name, {}, BOUND_S) for name in DAMAGES]
    + [(f"toolpath-{name}", "toolpath", name, {}, BOUND_S) for name in CRASHING]
    + [(f"{kind}-crash-hook", kind, EXAMPLE, {"BSPLINECAM_TEST_CRASH_READ": "1"}, BOUND_S)
       for kind in ("check", "toolpath", "verify", "job")]
    + [(f"{kind}-hang-hook", kind, EXAMPLE,
        {"BSPLINECAM_TEST_HANG_READ": "1", "BSPLINECAM_PART_TIMEOUT": str(SHORT_LIMIT_S)},
        SHORT_LIMIT_S + 30) for kind in ("check", "toolpath")]
    + [("check-digits-rescaled-hang", "check", "digits-rescaled",
        {"BSPLINECAM_PART_TIMEOUT": str(SHORT_LIMIT_S)}, SHORT_LIMIT_S + 30)]
    + [(f"{kind}-corpus-{path.name}", kind, path, {}, BOUND_S) for path in _corpus()
       for kind in ("check", "toolpath")]
)


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Run]:
    """Every case of CASES run by the real command line, two at a time."""
    if not have_freecadcmd() and not REQUIRE_ALL:
        pytest.skip("freecadcmd is not installed")
    base = tmp_path_factory.mktemp("isolation")
    parts_dir = base / "parts"
    parts_dir.mkdir()

    made = {name: make_damaged(parts_dir, name) for name in {**DAMAGES, **HANGING}}

    def one(case) -> tuple[str, Run]:
        ident, kind, source, env, _ = case
        part = source if isinstance(source, Path) else made[source]
        return ident, run_bin(kind, part, base / re.sub(r"[^\w.-]", "_", ident), env)
    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(pool.map(one, CASES))


@pytest.mark.venv_only
@needs_freecad
@pytest.mark.parametrize("ident, bound", [(case[0], case[4]) for case in CASES],
                         ids=[case[0] for case in CASES])
def test_isolated(runs, ident, bound):
    if "-corpus-" in ident:
        assert_not_silent(runs[ident])
        return
    line = assert_isolated(runs[ident], bound)
    if "hook" in ident and "crash" in ident:
        assert line.endswith(f"{EXAMPLE}: {SIGSEGV_LINE}"), line
    if "hang" in ident:
        assert f"did not finish within {SHORT_LIMIT_S} s" in line, line


@pytest.mark.venv_only
@needs_freecad
def test_crashing_damages_crash_the_reader(runs):
    """At least one damaged copy really kills FreeCAD's OCCT reader with SIGSEGV (the garbage
    block does in FreeCAD 0.20, 1.0 and 1.1): the isolation is needed, not only the hooks."""
    lines = [runs[f"check-{name}"].stderr for name in CRASHING]
    assert any(SIGSEGV_LINE in line for line in lines), lines


# -- the worker's child is killed on a time-out and on Ctrl-C ------------------------------
def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie or a missing process counts as ended)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


def _children(pid: int) -> list[int]:
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _is_worker(pid: int) -> bool:
    try:
        return b"orchestration.worker" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def _gone(pid: int, seconds: float = 10.0) -> bool:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if not _alive(pid):
            return True
        time.sleep(0.1)
    return False


@pytest.mark.venv_only
@needs_freecad
def test_time_limit_kills_the_worker(monkeypatch, tmp_path):
    """In-process: the hanging worker is killed at the limit and the error names the file."""
    started: list[int] = []
    popen = subprocess.Popen

    def spy(*args, **kwargs):
        proc = popen(*args, **kwargs)
        started.append(proc.pid)
        return proc

    monkeypatch.setattr(runtime.subprocess, "Popen", spy)
    monkeypatch.setenv("HOME", own_home(tmp_path)["HOME"])
    monkeypatch.setenv("BSPLINECAM_TEST_HANG_READ", "1")
    monkeypatch.setenv("BSPLINECAM_PART_TIMEOUT", "2")
    began = time.perf_counter()
    with pytest.raises(parts.FaceError) as info:
        parts.load_faces(EXAMPLE)
    assert time.perf_counter() - began < 30
    assert str(info.value) == (f"{EXAMPLE}: cannot read the part: OCCT did not finish within "
                               "2 s (the limit is BSPLINECAM_PART_TIMEOUT, in seconds)")
    assert len(started) == 1 and _gone(started[0])


@pytest.mark.venv_only
@needs_freecad
def test_crash_hook_in_process(monkeypatch, tmp_path):
    monkeypatch.setenv("HOME", own_home(tmp_path)["HOME"])
    monkeypatch.setenv("BSPLINECAM_TEST_CRASH_READ", "1")
    with pytest.raises(parts.FaceError) as info:
        parts.check_part(str(EXAMPLE), None)
    assert str(info.value) == f"{EXAMPLE}: {SIGSEGV_LINE}"


@pytest.mark.parametrize("value", ["abc", "0", "-5", "nan", "inf"])
def test_time_limit_variable_checked(monkeypatch, value):
    monkeypatch.setenv("BSPLINECAM_PART_TIMEOUT", value)
    with pytest.raises(parts.ParameterError, match="BSPLINECAM_PART_TIMEOUT must be a positive"):
        parts.part_time_limit()


def test_time_limit_default(monkeypatch):
    monkeypatch.delenv("BSPLINECAM_PART_TIMEOUT", raising=False)
    assert parts.part_time_limit() == parts.PART_TIME_LIMIT_S
    monkeypatch.setenv("BSPLINECAM_PART_TIMEOUT", "12.5")
    assert parts.part_time_limit() == 12.5


@pytest.mark.venv_only
@needs_freecad
def test_ctrl_c_kills_the_worker(tmp_path):
    """SIGINT to the command while its worker reads: status 130, one line, the worker gone."""
    out = tmp_path / "out"
    proc = subprocess.Popen([str(BIN), "check", str(EXAMPLE), "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            env={**os.environ, **own_home(tmp_path),
                                 "BSPLINECAM_TEST_HANG_READ": "1"})
    try:
        workers: list[int] = []
        end = time.monotonic() + 60
        while not workers and time.monotonic() < end:  # bin/bsplinecam execs freecadcmd
            workers = [pid for pid in _children(proc.pid) if _is_worker(pid)]
            time.sleep(0.2)
        assert workers, "no worker started"
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 128 + signal.SIGINT, stderr
    assert stderr.strip().splitlines() == ["bsplinecam check: interrupted by SIGINT; nothing "
                                           "was written"], stderr
    assert stdout == "" and not out.exists()
    assert _gone(workers[0])
