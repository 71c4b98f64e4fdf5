# SPDX-License-Identifier: LGPL-2.1-or-later
"""The warm start of the drop-cutter's branch and bound (:mod:`.faceset_branch`): a caller
that knows a contact near a query (a neighbour's face and (u, v), e.g. the previous point of
a pass or the ends of a grid edge a crossing is sought on) offers it as a hint.

Any point p of a face inside its trim with |p_xy - q| <= R gives a lower bound of the ball
centre's height, f(p) = p_z + sqrt(R^2 - |p_xy - q|^2) (:mod:`.faceset`).  The hint's point
is such a point when it lies in the surface's domain and inside the trim and reaches the
query; Newton ascent from it (:func:`.faceset_contacts.polish`, whose steps count only at
real points inside the trim that raise f) carries it to the neighbouring maximum.  The
value starts the face's best lower bound and contact, so from the first level the pairs
whose upper bound lies below it (plus the certified tolerance) are dropped, and the local
certificate around the face's contact (:mod:`.faceset_regions`) is sought about it at the
first region level instead of wherever the halving first finds a contact near there.  A
hint that is no such point (outside the domain or the trim, out of the ball's reach, on a
face not searched, a wall) is ignored: the certificate never depends on it, only how soon
the bounds close.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ..typing import FloatArray
from .faceset_contacts import polish
from .faceset_params import POLISH_STEPS


def seed_hints(data: list, q: FloatArray, R: float, hint: tuple, fb: FloatArray,
               fu: FloatArray, fv: FloatArray) -> None:
    """Raise the faces' best lower bounds ``fb`` (rows follow ``data``; columns the queries
    ``q`` (m, 2)) and their contacts (``fu``, ``fv``) to the polished values of the hints
    (face index in the set, u, v; (m,) each, face -1 none), in place, where a hint is a
    point of a face of ``data`` inside its trim within R (mm) of its query in xy."""
    hf, hu, hv = (np.asarray(h).reshape(-1) for h in hint)
    if not (len(hf) == len(hu) == len(hv) == len(q)):
        raise ValueError(f"hint: {len(hf)}, {len(hu)}, {len(hv)} entries for {len(q)} queries")
    hu, hv = hu.astype(float), hv.astype(float)
    R2 = R * R
    for j, d in enumerate(data):
        idx = np.flatnonzero(hf == d.index)
        if len(idx) == 0:
            continue
        s = d.face.surface
        (u0, u1), (v0, v1) = s.domain
        u, v = hu[idx], hv[idx]
        ok = (u >= u0) & (u <= u1) & (v >= v0) & (v <= v1)  # False where NaN
        idx, u, v = idx[ok], u[ok], v[ok]
        if len(idx) == 0:
            continue
        ok = d.inside(u, v)
        idx, u, v = idx[ok], u[ok], v[ok]
        if len(idx) == 0:
            continue
        p = s.evaluate(u, v)
        e2 = ((p[:, :2] - q[idx]) ** 2).sum(axis=1)
        near = e2 <= R2
        idx, u, v = idx[near], u[near].copy(), v[near].copy()
        if len(idx) == 0:
            continue
        b = p[near, 2] + np.sqrt(R2 - e2[near])
        polish([d], q[idx], R, b, np.full(len(idx), d.index), u, v, steps=2 * POLISH_STEPS)
        up = b > fb[j, idx]
        idx = idx[up]
        fb[j, idx], fu[j, idx], fv[j, idx] = b[up], u[up], v[up]


#: The sides of :class:`ContactMemo`'s cells as fractions of the ball's radius, finest first:
#: the nearer the neighbour whose contact starts a query, the sooner its bounds close (on
#: part.step's waterline, R / 400 to R / 6 found hints that halved the pairs bounded).
HINT_CELLS = (0.0025, 0.01, 0.04, 0.16)


class ContactMemo:
    """The contacts of answered queries by place, offered as hints to the next queries near
    them (:meth:`.faceset.FaceSet.drop_ball`'s ``hint``).

    The plane is cut into square cells, of each side in ``cells`` (mm, finest first); each
    cell keeps the contact of the last query answered in it.  A query's hint is the nearest
    of those kept in its own cell and the eight around it on the finest grid that has one
    there (none farther than the coarsest cell): a near neighbour's contact is the better
    start.  A caller that asks its queries in a fixed order gets the same hints, so the same
    heights, on every run.

    >>> memo = ContactMemo((0.03, 0.2, 0.75))
    >>> memo.add(xy, face, u, v)
    >>> tip, face, u, v, sel = faceset.drop_ball(xy2, R, hint=memo.hints(xy2))
    """

    def __init__(self, cells: Sequence[float]):
        cells = sorted(float(c) for c in cells)
        if not cells or not all(c > 0 and np.isfinite(c) for c in cells):
            raise ValueError(f"cells must be finite lengths > 0 mm, got {cells!r}")
        self.cells = cells
        self._slots: list[dict[int, int]] = [{} for _ in cells]  # key -> row of the arrays
        self._xy = np.zeros((0, 2))
        self._face = np.zeros(0, np.int64)
        self._u = np.zeros(0)
        self._v = np.zeros(0)

    @classmethod
    def for_radius(cls, radius: float) -> ContactMemo:
        """A memo whose cells are :data:`HINT_CELLS` of the ball's ``radius`` (mm)."""
        return cls([radius * c for c in HINT_CELLS])

    @staticmethod
    def _cells(xy: FloatArray, cell: float) -> tuple[np.ndarray, np.ndarray]:
        c = np.clip(np.floor(xy / cell), -(2.0 ** 30), 2.0 ** 30).astype(np.int64)
        return c[:, 0], c[:, 1]

    @staticmethod
    def _key(ix: np.ndarray, iy: np.ndarray) -> list:
        return ((ix << 32) + iy).tolist()

    def add(self, xy: FloatArray, face: np.ndarray, u: FloatArray, v: FloatArray) -> None:
        """Remember the contacts (``face``, ``u``, ``v``) of queries ``xy`` (m, 2) (those
        with a face, index >= 0)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        face = np.asarray(face).reshape(-1)
        keep = (face >= 0) & np.isfinite(xy).all(axis=1)
        if not keep.any():
            return
        base = len(self._face)
        xy = xy[keep]
        self._xy = np.concatenate([self._xy, xy])
        self._face = np.concatenate([self._face, face[keep].astype(np.int64)])
        self._u = np.concatenate([self._u, np.asarray(u, dtype=float).reshape(-1)[keep]])
        self._v = np.concatenate([self._v, np.asarray(v, dtype=float).reshape(-1)[keep]])
        rows = range(base, base + len(xy))
        for cell, slot in zip(self.cells, self._slots):
            slot.update(zip(self._key(*self._cells(xy, cell)), rows))

    def hints(self, xy: FloatArray) -> tuple[np.ndarray, FloatArray, FloatArray]:
        """(face, u, v) (m,) each: a remembered contact near each of ``xy`` (m, 2) (face -1
        where none is kept in the nine coarsest cells around it)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        m = len(xy)
        row = np.full(m, -1, np.int64)
        todo = np.flatnonzero(np.isfinite(xy).all(axis=1))
        for cell, slot in zip(self.cells, self._slots):
            if len(todo) == 0 or not slot:
                break
            p = xy[todo]
            ix, iy = self._cells(p, cell)
            best = np.full(len(todo), np.inf)
            near = np.full(len(todo), -1, np.int64)
            for dx in (-1, 0, 1):
                for dy in (-1, 0, 1):
                    r = np.fromiter(map(slot.get, self._key(ix + dx, iy + dy),
                                        [-1] * len(todo)), dtype=np.int64, count=len(todo))
                    has = np.flatnonzero(r >= 0)
                    d2 = ((self._xy[r[has]] - p[has]) ** 2).sum(axis=1)
                    closer = d2 < best[has]
                    best[has[closer]] = d2[closer]
                    near[has[closer]] = r[has[closer]]
            found = near >= 0
            row[todo[found]] = near[found]
            todo = todo[~found]
        ok = row >= 0
        face = np.full(m, -1, np.int64)
        u = np.zeros(m)
        v = np.zeros(m)
        face[ok], u[ok], v[ok] = self._face[row[ok]], self._u[row[ok]], self._v[row[ok]]
        return face, u, v


__all__ = ["HINT_CELLS", "ContactMemo", "seed_hints"]
