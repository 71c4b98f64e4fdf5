# SPDX-License-Identifier: LGPL-2.1-or-later
"""Progress of the verification's simulation (core, no FreeCAD): reported while it runs, and a
cancel raised by the reporter returns at once, without waiting for the worker."""

from __future__ import annotations

import threading

import pytest

from BSplineCAM.core.simulation.verify import run_reporting


class Stop(Exception):
    pass


def test_reports_while_work_runs_and_returns_its_value() -> None:
    release = threading.Event()
    seen: list[float] = []

    def work() -> int:
        release.wait(30)  # runs until the reporter has been called a few times
        return 42

    def progress(fraction: float) -> None:
        seen.append(fraction)
        if len(seen) == 3:
            release.set()

    assert run_reporting(work, progress, 0.2, 0.9, interval=0.01) == 42
    assert len(seen) >= 3
    assert all(0.2 <= f < 0.9 for f in seen)
    assert seen == sorted(seen)


def test_cancel_returns_before_the_work_ends() -> None:
    release = threading.Event()
    finished = threading.Event()

    def work() -> None:
        release.wait(30)
        finished.set()

    def progress(fraction: float) -> None:
        raise Stop("cancelled")

    with pytest.raises(Stop):
        run_reporting(work, progress, 0.0, 1.0, interval=0.01)
    assert not finished.is_set()  # the caller was not held until the work ended
    release.set()
    assert finished.wait(30)


def test_errors_of_the_work_reach_the_caller() -> None:
    def work() -> None:
        raise ValueError("bad program")

    with pytest.raises(ValueError, match="bad program"):
        run_reporting(work, lambda f: None, 0.0, 1.0, interval=0.01)
