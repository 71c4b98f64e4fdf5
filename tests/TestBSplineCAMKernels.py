# SPDX-License-Identifier: LGPL-2.1-or-later
"""The kernels' engine (BSplineCAM.core.kernels): chosen once per process, numba when it
imports, numpy otherwise, with one notice line; a numba that is missing, refuses to compile or
finds no writable cache folder never stops the work."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

from BSplineCAM.core import kernels

ROOT = Path(__file__).resolve().parent.parent


def _total(a):
    s = 0.0
    for i in range(a.shape[0]):
        s += a[i]
    return s


TOTAL = kernels.Kernel(_total)


def _child(code: str, **env) -> subprocess.CompletedProcess:
    """Run ``code`` in a new Python (this one) with the repository on its path."""
    full = {**os.environ, "PYTHONPATH": str(ROOT), **env}
    for k, v in env.items():
        if v is None:
            full.pop(k)
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=full, timeout=300, check=False)


def test_numpy_engine_by_choice_says_so_once():
    with kernels.forced("numpy") as e:
        assert e.name == "numpy" and "BSPLINECAM_KERNELS=numpy" in e.reason
        assert not kernels.use_numba()
        assert "numpy engine runs" in kernels.notice()
        with pytest.raises(kernels.KernelUnavailable):
            TOTAL(np.arange(4.0))


def test_unknown_choice_names_the_variable_and_runs_numpy():
    with kernels.forced("fast") as e:
        assert e.name == "numpy"
        assert "BSPLINECAM_KERNELS='fast'" in e.reason and "auto, numba, numpy" in e.reason


def test_kernel_under_numba_and_its_compile_time():
    pytest.importorskip("numba")
    with kernels.forced("numba") as e:
        assert e.name == "numba" and kernels.notice() == ""
        assert TOTAL(np.arange(5.0)) == 10.0
        assert e.compile_seconds["_total"] >= 0.0
        assert TOTAL.py(np.arange(5.0)) == 10.0
        assert e.to_dict()["engine"] == "numba"


def test_first_use_is_told_once_per_kernel_and_a_failing_listener_is_dropped():
    pytest.importorskip("numba")
    heard = []
    try:
        kernels.on_first_use(heard.append)
        with kernels.forced("numba"):
            assert TOTAL(np.arange(3.0)) == 3.0
            assert TOTAL(np.arange(4.0)) == 6.0
            assert heard == ["_total"]

        def broken(name):
            raise RuntimeError("display gone")

        kernels.on_first_use(broken)
        with kernels.forced("numba"):  # a new engine: the first use again
            assert TOTAL(np.arange(5.0)) == 10.0  # runs anyway
        assert kernels._first_use_listener is None
    finally:
        kernels.on_first_use(None)


def test_missing_numba_falls_back_with_one_line():
    code = ("import sys; sys.modules['numba'] = None\n"
            "import numpy as np\n"
            "from BSplineCAM.core import kernels\n"
            "def f(a):\n    return a.sum()\n"
            "k = kernels.Kernel(f)\n"
            "for _ in range(3):\n"
            "    try:\n        k(np.ones(3))\n    except kernels.KernelUnavailable:\n"
            "        pass\n"
            "print(kernels.engine().name, kernels.use_numba())\n")
    run = _child(code, BSPLINECAM_KERNELS="numba")
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["numpy", "False"]
    lines = [ln for ln in run.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "numba does not import" in lines[0] and "slower" in lines[0]


def test_unwritable_cache_folders_fall_back_to_a_temporary_one():
    pytest.importorskip("numba")
    ro = "/proc/self/nonexistent"  # not writable, root or not
    code = ("import numpy as np\n"
            "from BSplineCAM.core import kernels\n"
            f"{_source_of_total()}"
            "k = kernels.Kernel(_total)\n"
            "print(k(np.arange(4.0)), kernels.engine().cache)\n")
    run = _child(code, BSPLINECAM_KERNELS="auto", BSPLINECAM_CACHE=f"{ro}/a",
                 XDG_CACHE_HOME=f"{ro}/b", HOME=f"{ro}/c", NUMBA_CACHE_DIR=None)
    assert run.returncode == 0, run.stderr
    value, folder = run.stdout.split()
    assert value == "6.0" and folder.startswith(tempfile.gettempdir())
    assert Path(folder).name.startswith(f"py{sys.version_info[0]}{sys.version_info[1]}-numba")


def test_no_cache_folder_compiles_in_memory(monkeypatch):
    pytest.importorskip("numba")
    monkeypatch.setattr(kernels, "_cache_folder", lambda: "")
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    k = kernels.Kernel(_total)
    with kernels.forced("numba") as e:
        assert e.cache == ""
        assert k(np.arange(4.0)) == 6.0


def test_compile_failure_switches_to_numpy_and_names_the_kernel(capfd):
    pytest.importorskip("numba")

    def untypable(a):
        return object()  # a Python object: numba cannot type it

    k = kernels.Kernel(untypable)
    with kernels.forced("numba"):
        with pytest.raises(kernels.KernelUnavailable):
            k(np.ones(2))
        e = kernels.engine()
        assert e.name == "numpy" and "untypable" in e.reason
        assert not kernels.use_numba()
    err = capfd.readouterr().err
    assert err.count("compiled kernels off") == 1 and "untypable" in err


def test_cli_json_names_the_engine(tmp_path):
    """Every command's JSON result carries the engine that computed it."""
    from BSplineCAM.orchestration import cli_common

    out = tmp_path / "r.json"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT)
    old = os.environ.get("BSPLINECAM_RESULT_FD")
    os.environ["BSPLINECAM_RESULT_FD"] = str(fd)
    try:
        cli_common.emit({"ok": True})
    finally:
        os.close(fd)
        if old is None:
            os.environ.pop("BSPLINECAM_RESULT_FD")
        else:
            os.environ["BSPLINECAM_RESULT_FD"] = old
    data = json.loads(out.read_text())
    assert data["ok"] is True and data["kernels"]["engine"] in ("numba", "numpy")


def _source_of_total() -> str:
    return ("def _total(a):\n    s = 0.0\n    for i in range(a.shape[0]):\n"
            "        s += a[i]\n    return s\n")


@kernels.helper
def _square(x):
    return x * x


@kernels.helper
def _sum_of_squares(a):
    s = 0.0
    for i in range(a.shape[0]):
        s += _square(a[i])
    return s


def _norm2(a):
    return _sum_of_squares(a)


NORM2 = kernels.Kernel(_norm2)


def test_helpers_compile_with_the_kernel_that_calls_them():
    a = np.arange(4.0)
    assert NORM2.py(a) == 14.0  # plain Python before any compile
    pytest.importorskip("numba")
    with kernels.forced("numba"):
        assert NORM2(a) == 14.0
    assert hasattr(globals()["_sum_of_squares"], "py_func")  # the compiled twin
    assert hasattr(globals()["_square"], "py_func")
    assert NORM2.py(a) == 14.0  # Python callers still reach it
