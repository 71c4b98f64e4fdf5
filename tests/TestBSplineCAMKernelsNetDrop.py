# SPDX-License-Identifier: LGPL-2.1-or-later
"""The net drop-cutter's compiled kernel (BSplineCAM.core.kernels.net_drop_kernels) against
the numpy engine of ``DropCutter`` it replaces: heights and contacts to 1e-12 mm on generated
nets (hypothesis) and on the case study, the same raster program line for line, and on an
adversarial narrow spike between the samples the same heights in both, each a lower bound of
the exact height (every value is f at a real surface point), the raster's chords lifted over
them in both.

The kernel's loop function also runs as plain Python against the numpy engine, so the
algorithm is checked where numba is missing; the compiled half is skipped there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bsplinecam_helpers import close, gcode, numba_ready, same, under_both
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from BSplineCAM.core import Surface, kernels
from BSplineCAM.core.kernels import net_drop_kernels
from BSplineCAM.core.toolpath import chords, generate
from BSplineCAM.core.toolpath.dropcutter import DropCutter

CASE_STUDY = Path(__file__).resolve().parent.parent / "examples" / "case-study.json"
needs_numba = pytest.mark.skipif(not numba_ready(), reason="numba does not import")
SETTINGS = settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def nets(draw):
    """A height-field net (4..9 poles a side, uniform or clamped knots) over a footprint of
    10..60 mm, heights of up to 25 mm, smooth or rough."""
    nu, nw = draw(st.integers(4, 9)), draw(st.integers(4, 9))
    size = draw(st.floats(10.0, 60.0))
    seed = draw(st.integers(0, 2**32 - 1))
    rough = draw(st.floats(0.0, 25.0))
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0.0, size, nu), np.linspace(0.0, 0.8 * size, nw),
                       indexing="ij")
    z = rng.uniform(0.0, rough, (nu, nw))
    return Surface(np.stack([x, y, z], axis=-1), draw(st.sampled_from(["clamped", "uniform"])))


def queries(dc: DropCutter, count: int, seed: int) -> np.ndarray:
    """Queries over the footprint and 5 mm beyond it (some meet no surface)."""
    rng = np.random.default_rng(seed)
    return dc.lo - 5.0 + rng.uniform(size=(count, 2)) * (dc.hi - dc.lo + 10.0)


def spike_net(height: float = 11.25) -> Surface:
    """Uniform cubic net, 0.1 mm pole spacing, one raised pole: a spike 5 mm tall and about
    0.4 mm wide at its base on a flat plate, its apex between the drop-cutter's samples."""
    n = 81
    x = np.linspace(0.0, 8.0, n)
    pts = np.zeros((n, n, 3))
    pts[..., 0], pts[..., 1] = np.meshgrid(x, x, indexing="ij")
    pts[41, 41, 2] = height
    return Surface(pts, knots="uniform")


def exact_heights(surface: Surface, R: float, xy: np.ndarray, centre=(0.5, 0.5),
                  half=0.5) -> np.ndarray:
    """Tip heights by brute force: the best of a 81 x 81 parameter sample, then three 10x
    zooms around the best sample (a maximum of f: the sampling error is quadratic)."""
    out = np.empty(len(xy))
    for k, q in enumerate(xy):
        cu, cv, du = centre[0], centre[1], half
        best = -np.inf
        for _ in range(4):
            gu = np.clip(np.linspace(cu - du, cu + du, 81), 0, 1)
            gv = np.clip(np.linspace(cv - du, cv + du, 81), 0, 1)
            pts = surface.evaluate_grid(gu, gv)
            d2 = ((pts[..., :2] - q) ** 2).sum(axis=-1)
            f = np.where(d2 <= R * R, pts[..., 2] + np.sqrt(np.maximum(R * R - d2, 0)), -np.inf)
            i, j = np.unravel_index(np.argmax(f), f.shape)
            best = max(best, f[i, j])
            cu, cv, du = gu[i], gv[j], du / 20
        out[k] = best - R
    return out


# --- the loop function, compiled or not, against the numpy engine -----------------------------
@SETTINGS
@given(nets(), st.floats(0.5, 6.0), st.integers(0, 2**32 - 1))
def test_loops_as_python_agree_with_the_numpy_engine(surface, R, seed):
    dc = DropCutter(surface, R)
    q = queries(dc, 12, seed)
    with kernels.forced("numpy"):
        want = dc.centre_heights(q)
    args = dc.kernel_arguments(q)
    net_drop_kernels.centre_heights.py(*args)
    close(args[-3:], want)
    _z, u, w = want
    with kernels.forced("numpy"):
        slopes = dc.slopes(q, u, w)
    out = np.empty((len(q), 2))
    net_drop_kernels.slopes.py(q, u, w, dc.form.coef, *dc.form.spans, R, out)
    close(out, slopes)


@needs_numba
@SETTINGS
@given(nets(), st.floats(0.5, 6.0), st.integers(0, 2**32 - 1))
def test_engines_agree_on_generated_nets(surface, R, seed):
    dc = DropCutter(surface, R)
    q = queries(dc, 400, seed)
    numpy_, numba_ = under_both(lambda: dc.heights_and_slopes(q))
    close(numpy_, numba_)
    assert np.isfinite(numpy_[0]).any()


@needs_numba
def test_engines_agree_on_the_case_study():
    s = Surface.from_json(CASE_STUDY)
    dc = DropCutter(s, 3.0)
    q = queries(dc, 20000, 7)
    numpy_, numba_ = under_both(lambda: dc.heights_and_slopes(q))
    close(numpy_, numba_)


@needs_numba
def test_engines_give_the_same_case_study_program():
    s = Surface.from_json(CASE_STUDY)
    numpy_, numba_ = under_both(lambda: generate(s, "raster", 6.0, 0.05))
    assert gcode(numpy_) == gcode(numba_)
    assert numpy_.extra["chord_lift"] == numba_.extra["chord_lift"]
    same(np.concatenate(numpy_.passes), np.concatenate(numba_.passes))


# --- an adversarial narrow spike between the samples ------------------------------------------
def test_spike_heights_are_lower_bounds_in_both_engines():
    s = spike_net()
    R = 3.0
    dc = DropCutter(s, R)
    u = np.linspace(0.45, 0.55, 401)
    dense = s.evaluate_grid(u, u).reshape(-1, 3)
    apex = dense[np.argmax(dense[:, 2])]
    assert 4.9 < apex[2] < 5.1
    # every sample misses the spike: the nearest lies 0.2 mm from the apex, on the plate
    nearest = np.argmin(np.hypot(*(dc.samples[:, :2] - apex[:2]).T))
    assert np.hypot(*(dc.samples[nearest, :2] - apex[:2])) > 0.2
    assert dc.samples[nearest, 2] < 0.01
    rng = np.random.default_rng(5)
    xy = apex[:2] + rng.uniform(-2.5, 2.5, (60, 2))
    exact = exact_heights(s, R, xy)
    engines = ("numpy", "numba") if numba_ready() else ("numpy",)
    got = []
    for name in engines:
        with kernels.forced(name):
            tip, _u, _w = dc.heights(xy)
        assert np.all(tip <= exact + 1e-9), name  # a height never exceeds the true one
        got.append(tip)
    if len(got) == 2:
        close(got[0], got[1])


def test_spike_raster_chords_stay_above_the_heights_in_both_engines():
    s = spike_net()
    R = 3.0
    engines = ("numpy", "numba") if numba_ready() else ("numpy",)
    programs = []
    for name in engines:
        with kernels.forced(name):
            tp = generate(s, "raster", 2 * R, 0.02, tolerance=0.005)
            dc = DropCutter(s, R)
            for p in tp.passes:
                # the chords' certificate: every chord clears the drop-cutter's heights
                t = np.linspace(0.0, 1.0, 9)[1:-1, None]
                inner = (p[:-1, None, :] * (1 - t) + p[1:, None, :] * t).reshape(-1, 3)
                tip, _u, _w = dc.heights(inner[:, :2])
                ok = np.isfinite(tip)
                assert np.all(inner[ok, 2] >= tip[ok] - chords.DIP_LIMIT), name
        programs.append(gcode(tp))
    if len(programs) == 2:
        assert programs[0] == programs[1]
