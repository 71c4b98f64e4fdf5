# SPDX-License-Identifier: LGPL-2.1-or-later
"""A core Face from a face's B-spline arrays and trim loops as OCCT gives them.

The reader of parts (:mod:`.part_reader`, with FreeCAD's Part or OCP as its adapter) makes
every core Face the same way:

* the core takes clamped knot vectors only, so a periodic or unclamped surface is segmented
  first (OCCT's exact knot insertion keeps its parameters) to its own bounds, but a periodic
  direction to the trim's range, which must span one period at the most
  (:func:`segment_box`); then :func:`.faces.period_shift` puts the knots back on the trim's
  parameters;
* a face whose orientation is reversed is flipped in v, so that its normal points outwards,
  and the result, evaluated by the core, must lie within :data:`ACCEPT_SHARE` (1 %) of the
  machining's chordal tolerance from OCCT's evaluation of the original surface
  (:func:`checked_face`): a thousandth of a micrometre more or less does not change a cut, a
  hundredth of the tolerance is what the toolpath may spend on it.  The distance is kept in
  the face (``Face.deviation``) and reported by ``check`` and in the notes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence

import numpy as np

from ..errors import BSplineCAMError
from ..numeric import clamp
from ..typing import FloatArray
from . import faces as core_faces
from .faces import Face, FaceError

#: Largest distance of a face's NURBS (as the core evaluates it) from OCCT's original
#: surface, as a share of the chordal tolerance the face is machined to.
ACCEPT_SHARE = 0.01
#: The chordal tolerance (mm) faces are accepted for when the caller names none: the
#: toolpath's default (``--tolerance``).
DEFAULT_CHORDAL_TOLERANCE = 0.002
#: Trim loops may reach outside their surface's parameter domain by up to this share of its
#: span in each direction (the parameter curves' own tolerance: a seam's curve on a sphere or
#: torus lies 1e-7 to 1e-4 of the span beyond it); such points are moved onto the domain's
#: side, where the face ends.  A trim reaching farther is refused.
DOMAIN_SLACK = 1e-3


def periodic_range(a: float, b: float, period: float, which: str,
                   name: str) -> tuple[float, float]:
    """The trim's parameter range [a, b] of a periodic direction ``which`` ("u" or "v"),
    widened to exactly one ``period`` when it spans one up to rounding; FaceError naming the
    face ``name`` when it spans more."""
    if b - a > period * (1 + 1e-12):
        raise FaceError(f"{name}: its trim spans more than one period in {which}")
    if b - a >= period * (1 - 1e-12):
        b = a + period
    return a, b


def segment_box(bounds: Sequence[float], uv_box: Sequence[float], periods: Sequence[float],
                name: str) -> tuple[float, float, float, float]:
    """(u0, u1, v0, v1) to segment a surface to before clamping it: its ``bounds`` (u0, u1,
    v0, v1), each periodic direction (``periods`` (u, v) > 0; 0 for a non-periodic one) cut to
    the trim's range in ``uv_box`` (u0, u1, v0, v1) by :func:`periodic_range`."""
    u0, u1, v0, v1 = (float(x) for x in bounds)
    if periods[0] > 0:
        u0, u1 = periodic_range(uv_box[0], uv_box[1], periods[0], "u", name)
    if periods[1] > 0:
        v0, v1 = periodic_range(uv_box[2], uv_box[3], periods[1], "v", name)
    return u0, u1, v0, v1


def into_domain(loops: Sequence[FloatArray], domain: Sequence[Sequence[float]],
                name: str) -> list[FloatArray]:
    """The trim ``loops`` ((k, 2) parameters) with points outside ``domain`` ((u0, u1),
    (v0, v1)) by at most DOMAIN_SLACK of its span moved onto its side; FaceError naming the
    face ``name`` for a loop reaching farther out."""
    out = []
    for loop in loops:
        loop = np.asarray(loop, dtype=float)
        for axis, (lo, hi) in enumerate(domain):
            if not len(loop):
                break
            beyond = max(lo - float(loop[:, axis].min()), float(loop[:, axis].max()) - hi)
            if beyond > DOMAIN_SLACK * (hi - lo):
                raise FaceError(f"{name}: its trim reaches {beyond:.3g} outside the surface's "
                                f"{'uv'[axis]} domain [{lo:.9g}, {hi:.9g}]")
        (u0, u1), (v0, v1) = domain
        out.append(np.column_stack([clamp(loop[:, 0], u0, u1), clamp(loop[:, 1], v0, v1)])
                   if len(loop) else loop)
    return out


def acceptance_limit(chordal_tolerance: float) -> float:
    """Largest accepted distance (mm) of a face's NURBS from OCCT's original surface when it
    is machined to ``chordal_tolerance`` (mm): :data:`ACCEPT_SHARE` of it."""
    if not (isinstance(chordal_tolerance, (int, float)) and np.isfinite(chordal_tolerance)
            and chordal_tolerance > 0):
        raise FaceError(f"chordal tolerance must be a positive length in mm, got "
                        f"{chordal_tolerance!r}")
    return ACCEPT_SHARE * float(chordal_tolerance)


def checked_face(data: dict, outer: FloatArray, holes: list[FloatArray], flipped: bool,
                 deviation: Callable[[Face], float], size: float, *, index: int, name: str,
                 kind: str, selected: bool, tolerance: float,
                 chordal_tolerance: float | None = DEFAULT_CHORDAL_TOLERANCE) -> Face:
    """The core Face of the NURBS arrays ``data`` (core.faces.make_surface's keywords) and
    the trim loops ``outer``, ``holes`` (parameters), flipped in v when OCCT's face is
    ``flipped`` (reversed), with its ``deviation(face)`` (mm) from OCCT's surfaces; FaceError
    naming the face ``name`` (of surface type ``kind``) when the arrays make no surface or the
    deviation exceeds :func:`acceptance_limit` of ``chordal_tolerance`` (mm).  With
    ``chordal_tolerance`` None the deviation is only measured and kept (``check`` reports
    every face).  ``size`` (mm, the face's diagonal) scales the message's relative figure."""
    if flipped:
        vsum = data["knots_v"][0] + data["knots_v"][-1]
        data["poles"], data["weights"], data["knots_v"] = core_faces.flip_v(
            data["poles"], data["weights"], data["knots_v"])
        outer = np.column_stack([outer[:, 0], vsum - outer[:, 1]])
        holes = [np.column_stack([h[:, 0], vsum - h[:, 1]]) for h in holes]
    try:
        surface = core_faces.make_surface(name=name, **data)
    except BSplineCAMError as exc:
        raise FaceError(f"{name} ({kind}): {exc}") from None
    outer, *holes = into_domain([outer, *holes], surface.domain, f"{name} ({kind})")
    face = Face(surface, outer, tuple(holes), index=index, name=name, selected=selected,
                flipped_v=flipped, source=kind, tolerance=tolerance)
    measured = deviation(face)
    if chordal_tolerance is not None:
        limit = acceptance_limit(chordal_tolerance)
        if not measured <= limit:
            raise FaceError(
                f"{name} ({kind}): its NURBS is {measured:.3g} mm from OCCT's original surface "
                f"({measured / max(size, 1e-300):.2g} of its size {size:.6g} mm), more than "
                f"{limit:.3g} mm, {ACCEPT_SHARE:.0%} of the chordal tolerance "
                f"{chordal_tolerance:g} mm")
    return dataclasses.replace(face, deviation=measured)
