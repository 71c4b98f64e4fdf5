# SPDX-License-Identifier: LGPL-2.1-or-later
"""The drop-cutter's chunks of queries on several threads (BSplineCAM.core.toolpath.parallel):
FaceSet.centre_heights gives the same heights, contacts, gaps and counters, to the last bit, on
1, 2 and 4 threads and with chunks of 64 or 2048 queries, under both kernel engines, on
trimmed faces (a plate with a hole, a boss's fillet, a wall) and on examples/part.step; the
setting BSPLINECAM_THREADS (core.threads), its notice and its cap for numpy work; an exception in a chunk reaches the caller and
nothing hangs.  No test asserts a time."""

from __future__ import annotations

import contextlib
import importlib.util
import threading
import time

import numpy as np
import pytest
from bsplinecam_helpers import fillet_ring, plate_with_hole, step_part_queries
from conftest import hang_guard

from BSplineCAM.core import kernels
from BSplineCAM.core.geometry.faces import Face
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.core.toolpath import faceset, parallel
from BSplineCAM.core.toolpath.faceset import FaceSet

needs_numba = pytest.mark.skipif(importlib.util.find_spec("numba") is None,
                                 reason="numba is not installed: no compiled engine")
ENGINES = ["numpy", pytest.param("numba", marks=needs_numba)]
#: (threads, QUERY_CHUNK) compared with one thread and the default chunk
RUNS = [(1, 64), (2, 2048), (2, 64), (4, 2048), (4, 64)]


@contextlib.contextmanager
def engine(name: str):
    """The kernel engine ``name`` for a block (skips when numba is asked for and missing)."""
    with kernels.forced(name) as chosen:
        if chosen.name != name:
            pytest.skip(f"no {name} engine: {chosen.reason}")
        yield chosen


def wall(x0: float, x1: float, y: float, z0: float, z1: float, index: int) -> Face:
    """A vertical unselected plane above the segment (x0, y)-(x1, y): a wall, met by its
    borders."""
    poles = np.array([[[x0, y, z0], [x0, y, z1]], [[x1, y, z0], [x1, y, z1]]], dtype=float)
    s = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name=f"Face{index}")
    loop = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    return Face(s, loop, index=index, selected=False, source="Plane")


def trimmed_faces() -> list[Face]:
    """A plate with a hole, the fillet of a boss (a ball of its radius crowds there: the
    uncertified counter moves) and a wall."""
    return [plate_with_hole(), fillet_ring(rho=3.0), wall(0.0, 40.0, 41.0, 10.0, 14.0, 3)]


def trimmed_queries() -> np.ndarray:
    rng = np.random.default_rng(43)
    return rng.uniform(-2.0, 42.0, (700, 2))


def drop(faces, xy, R, threads, chunk, monkeypatch, fs=None, selected_only=False):
    """(centre, face, u, v, gap) and the counters of ``fs`` (a new FaceSet if None)."""
    monkeypatch.setattr(faceset, "QUERY_CHUNK", chunk)
    # a call of a few hundred queries splits too
    monkeypatch.setattr(faceset, "PARALLEL_CHUNK", 64)
    monkeypatch.setattr(faceset, "PARALLEL_CHUNK_NUMPY", 64)
    fs = FaceSet(faces) if fs is None else fs
    before = dict(fs.stats)
    with parallel.forced(threads) as s:
        assert s.threads == threads
        r = fs.centre_heights(xy, R, selected_only)
    counted = {k: v - before[k] if k != "levels" else v for k, v in fs.stats.items()}
    return (r.centre, r.face, r.u, r.v, r.gap), counted


def assert_same(a, b, counters: bool = True):
    """Equal answers (NaN where NaN) and counters, to the last bit."""
    for x, y in zip(a[0], b[0]):
        assert x.dtype == y.dtype and x.shape == y.shape
        assert np.array_equal(x, y, equal_nan=True), np.nanmax(np.abs(x - y))
    if counters:
        assert a[1] == b[1]


# -- the setting -------------------------------------------------------------------------------
@pytest.mark.parametrize("value, count", [("1", 1), ("3", 3), (" 2 ", 2), ("16", 16)])
def test_thread_counts(value, count, capsys):
    with parallel.forced(value) as s:
        assert (s.threads, s.bad) == (count, False)
        assert parallel.threads() == count
        assert parallel.notice() == ""
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("value", ["auto", "AUTO", ""])
def test_auto_is_the_cores_capped(value, capsys):
    with parallel.forced(value) as s:
        assert s.threads == max(1, min(parallel.AUTO_CAP, parallel.cores()))
        assert not s.bad
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("value", ["0", "-2", "two", "1.5", "4x", "1e3"])
def test_bad_values_run_the_default_with_one_notice(value, capsys):
    with parallel.forced(value) as s:
        assert s.bad
        assert s.threads == max(1, min(parallel.AUTO_CAP, parallel.cores()))
        parallel.threads()  # read again: no second notice
        text = parallel.notice()
    err = capsys.readouterr().err
    assert err.strip() == text
    assert len(err.strip().splitlines()) == 1
    assert "BSPLINECAM_THREADS" in text and repr(value) in text and "auto" in text


def test_forced_restores_the_setting():
    before = parallel.setting()
    with parallel.forced(3):
        assert parallel.threads() == 3
    assert parallel.setting() == before


@pytest.mark.parametrize(("value", "expected"), [("1", 1), ("3", 3), ("9", 4)])
def test_numpy_work_follows_the_setting(value, expected):
    """The numpy work split into parts (net drop-cutter, Z-map, height grids) takes
    BSPLINECAM_THREADS too, at most four; the evaluator's grid products at most two."""
    from BSplineCAM.core import threads
    from BSplineCAM.core.geometry import matrix

    with threads.forced(value):
        assert threads.numpy_threads() == expected
        assert matrix._grid_threads(1 << 30, 64) == min(2, expected)
    assert parallel.setting is threads.setting


@pytest.mark.parametrize("m", [1, 10, 255, 256, 370, 600, 1000, 3000, 17_020, 100_000])
@pytest.mark.parametrize("threads", [1, 2, 3, 4, 8])
@pytest.mark.parametrize("least", [256, 512, 2048])
def test_chunk_size(m, threads, least):
    spread = faceset.spread(m, threads, least)
    assert spread == (threads if m >= 2 * least else 1)
    size = faceset.chunk_size(m, spread, least)
    n = -(-m // size)
    assert 1 <= size <= faceset.QUERY_CHUNK
    if spread == 1:
        assert size == faceset.QUERY_CHUNK
        return
    # two chunks or more of at least ``least`` queries (unless QUERY_CHUNK asks for more
    # chunks); as many as the threads or more, a multiple of them where the call is large
    # enough; the chunks as equal as they come
    assert n >= 2
    assert size >= least or n == -(-m // faceset.QUERY_CHUNK)  # QUERY_CHUNK bounds them
    if m >= faceset.CHUNKS_PER_THREAD * threads * least:
        assert n >= faceset.CHUNKS_PER_THREAD * threads
    if m // (-(-n // threads) * threads) >= least:
        assert n % threads == 0
    assert m - (n - 1) * size <= size


# -- the pool ----------------------------------------------------------------------------------
def test_run_returns_in_order_and_nests():
    with parallel.forced(2), hang_guard(20.0, "parallel.run"):
        out = parallel.run(lambda k: parallel.run(lambda j: (k, j, parallel.in_pool()), 3), 5)
    assert [[(k, j) for k, j, _ in row] for row in out] == [
        [(k, j) for j in range(3)] for k in range(5)]
    # the inner pieces ran on the pool's thread that ran their outer piece
    assert all(inner for row in out for _, _, inner in row)
    assert not parallel.in_pool()


def test_run_raises_the_first_failed_piece_and_cancels_the_rest():
    started = []
    lock = threading.Lock()
    third_failed = threading.Event()

    def work(k):
        with lock:
            started.append(k)
        if k == 1:
            third_failed.wait(5.0)  # fails after piece 3 has failed, before the call returns
            raise ValueError("piece 1")
        if k == 3:
            third_failed.set()
            raise KeyError("piece 3")
        time.sleep(0.01)
        return k

    with parallel.forced(2), hang_guard(20.0, "parallel.run"):
        # the exception of one thread (as in the order of the pieces on one thread)
        with pytest.raises(ValueError, match="piece 1"):
            parallel.run(work, 200)
        # the pool still serves
        assert parallel.run(lambda k: k * k, 6) == [0, 1, 4, 9, 16, 25]
    assert len(started) < 200


def test_run_first_here_runs_piece_zero_on_the_caller():
    me = threading.get_ident()
    with parallel.forced(2):
        out = parallel.run(lambda k: threading.get_ident() == me, 4, first_here=True)
    assert out[0] is True


def test_an_exception_in_a_chunk_reaches_the_caller(monkeypatch):
    faces = trimmed_faces()
    xy = trimmed_queries()
    # the kernels compile first, outside the guard (a fresh cache under load takes a minute)
    expected = FaceSet(faces).centre_heights(xy, 3.0)
    real = faceset.drop_chunk
    marker = xy[300, 0]

    ran_on = set()

    def failing(*args):
        ran_on.add(threading.get_ident())
        q = args[3]
        if np.any(q[:, 0] == marker):
            raise RuntimeError("chunk failed")
        return real(*args)

    monkeypatch.setattr(faceset, "drop_chunk", failing)
    monkeypatch.setattr(faceset, "QUERY_CHUNK", 64)
    monkeypatch.setattr(faceset, "PARALLEL_CHUNK", 64)
    monkeypatch.setattr(faceset, "PARALLEL_CHUNK_NUMPY", 64)
    fs = FaceSet(faces)
    with parallel.forced(2), hang_guard(60.0, "a failing drop"):
        with pytest.raises(RuntimeError, match="chunk failed"):
            fs.centre_heights(xy, 3.0)
        assert ran_on - {threading.get_ident()}  # on the pool
        monkeypatch.setattr(faceset, "drop_chunk", real)
        # the set and the pool serve the next call, with its answers
        a = FaceSet(faces).centre_heights(xy, 3.0)
        b = fs.centre_heights(xy, 3.0)
    assert np.array_equal(a.centre, b.centre)
    assert np.array_equal(a.centre, expected.centre)


# -- the same answers on any number of threads -------------------------------------------------
@pytest.mark.parametrize("name", ENGINES)
def test_threads_and_chunks_agree_on_trimmed_faces(name, monkeypatch):
    faces = trimmed_faces()
    xy = trimmed_queries()
    R = 3.0
    with engine(name):
        ref = drop(faces, xy, R, 1, 2048, monkeypatch)
        assert ref[1]["pairs"] > 10_000 and ref[1]["uncertified"] > 0
        assert (ref[0][1] == 1).any() and (ref[0][1] == 2).any()  # the fillet, the wall
        for threads, chunk in RUNS:
            assert_same(drop(faces, xy, R, threads, chunk, monkeypatch), ref)
        # a set whose caches are filled by earlier calls answers alike
        fs = FaceSet(faces)
        drop(faces, xy[::-1], R, 2, 64, monkeypatch, fs)
        assert_same(drop(faces, xy, R, 4, 64, monkeypatch, fs), ref, counters=False)
        # selected faces only (no walls)
        sel = drop(faces, xy, R, 1, 2048, monkeypatch, selected_only=True)
        assert_same(drop(faces, xy, R, 2, 64, monkeypatch, selected_only=True), sel)


@pytest.mark.parametrize("name", ENGINES)
def test_threads_and_chunks_agree_on_the_step_part(name, monkeypatch):
    pytest.importorskip("OCP")
    R = 3.0
    faces, xy = step_part_queries(4, R)
    with engine(name):
        ref = drop(faces, xy, R, 1, 2048, monkeypatch)
        assert ref[1]["pairs"] > 10_000
        for threads, chunk in RUNS if name == "numba" else RUNS[1:3]:
            assert_same(drop(faces, xy, R, threads, chunk, monkeypatch), ref)
