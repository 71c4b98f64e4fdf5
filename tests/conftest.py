# SPDX-License-Identifier: LGPL-2.1-or-later
"""Shared fixtures: the repository on sys.path, small reference nets, the fuzz harness (settings
and a hang guard) and the in-process runner of the command line."""

from __future__ import annotations

import contextlib
import json
import signal
import sys
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, settings

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

CASE_STUDY = ROOT / "examples" / "case-study.json"


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261123)


def random_net(rng: np.random.Generator, rows: int = 7, cols: int = 9) -> np.ndarray:
    """A wavy height-field net over a rows x cols grid, with jitter in x and y."""
    x, y = np.meshgrid(np.linspace(0, 60, rows), np.linspace(0, 40, cols), indexing="ij")
    z = 5 * np.sin(x / 9) * np.cos(y / 7) + rng.normal(scale=1.0, size=x.shape)
    net = np.stack([x, y, z], axis=-1)
    net[..., :2] += rng.normal(scale=0.5, size=net[..., :2].shape)
    return net


def plane_net(tmp_path: Path, width: float = 60.0, depth: float = 40.0, z: float = 10.0) -> Path:
    """A 4 x 4 clamped net of the plane z (mm) over width x depth mm, written as plane.json."""
    t = np.linspace(0.0, 1.0, 4)
    x, y = np.meshgrid(t * width, t * depth, indexing="ij")
    net = np.stack([x, y, np.full_like(x, z)], -1)
    path = tmp_path / "plane.json"
    path.write_text(json.dumps({"name": "plane", "knots": "clamped",
                                "control_points": net.tolist()}))
    return path


def run_main(capsys, *argv: str) -> tuple[int, str, str]:
    """``bsplinecam ARGV`` in-process: (exit status, stdout, stderr)."""
    from BSplineCAM.orchestration import cli

    try:
        status = cli.main(list(argv))
    except SystemExit as exc:  # argparse
        status = int(exc.code)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


# -- fuzzing -----------------------------------------------------------------------------------

#: Seconds after which a reader is taken as hung: generous enough never to trip on a slow
#: machine for the inputs of at most a few hundred kilobytes the fuzz tests draw.
HANG_S = 20.0

#: Hypothesis settings of the fuzz tests: derandomised (CI runs the same cases each time), no
#: example database, no per-example deadline (hang_guard bounds a call instead).
FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                           HealthCheck.function_scoped_fixture],
)


class ReaderHung(AssertionError):
    """A reader ran past HANG_S on a fuzzed input."""


@contextlib.contextmanager
def hang_guard(seconds: float = HANG_S, what: str = "a reader") -> Iterator[None]:
    """Fail with ReaderHung when the block runs longer than ``seconds`` (SIGALRM)."""
    def expire(_signum, _frame):
        raise ReaderHung(f"{what} ran longer than HANG_S={seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


#: Modules that run inside FreeCAD (listed in freecad_modules.txt) or its GUI, not in pytest.
FREECAD_MODULES = [
    line.strip() + ".py"
    for line in (Path(__file__).parent / "freecad_modules.txt").read_text().splitlines()
    if line.strip() and not line.startswith("#")
]
collect_ignore = [*FREECAD_MODULES, "TestBSplineCAMGui.py", "TestBSplineCAMGuiCam.py",
                  "TestBSplineCAMGuiPanels.py", "TestBSplineCAMGuiPart.py", "gui_run_tests.py"]
