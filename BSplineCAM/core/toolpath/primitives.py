# SPDX-License-Identifier: LGPL-2.1-or-later
"""Local geometry and segment reductions the drop-cutter and the chord sampler build on: the
surface's jet (point, derivatives, upward normal), its upward side, and max/min by key.

Below :mod:`BSplineCAM.core.toolpath.common` (which re-exports them) so that ``common`` can
import the links, chords and drop-cutter that use them without an import cycle.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..typing import FloatArray


# -- local geometry -------------------------------------------------------------------------------
@dataclass
class Jet:
    """Point, first and second derivatives and the upward unit normal at scattered parameters.

    Built by :meth:`at` from :meth:`Surface.derivatives` (the cached per-patch matrix form);
    ``sign`` (+1 or -1) orients the normal sign * Su x Sw up, the side the ball comes from.
    """

    u: FloatArray
    w: FloatArray
    p: FloatArray
    su: FloatArray
    sw: FloatArray
    suu: FloatArray
    suw: FloatArray
    sww: FloatArray
    sign: float = 1.0

    @classmethod
    def at(cls, surface: Any, u: FloatArray, w: FloatArray, sign: float = 1.0) -> Jet:
        """Jet at parameters (u, w), clipped to the surface's parameter domain (its
        ``domain`` where it has one, as a NURBS face's surface does; [0, 1] for a net)."""
        (u0, u1), (w0, w1) = getattr(surface, "domain", ((0.0, 1.0), (0.0, 1.0)))
        u = np.clip(np.asarray(u, dtype=float).ravel(), u0, u1)
        w = np.clip(np.asarray(w, dtype=float).ravel(), w0, w1)
        d = surface.derivatives(u, w)
        return cls(u, w, d.point, d.su, d.sw, d.suu, d.suw, d.sww, sign)

    @property
    def normal(self) -> FloatArray:
        n = self.sign * np.cross(self.su, self.sw)
        length = np.linalg.norm(n, axis=-1, keepdims=True)
        return n / np.where(length > 0, length, 1.0)


def upward_sign(surface: Any) -> float:
    """+1 if Su x Sw points up (+z) on average over the surface, else -1."""
    pts = surface.grid(9, 9)
    nz = np.cross(np.gradient(pts, axis=0), np.gradient(pts, axis=1))[..., 2]
    return 1.0 if float(nz.sum()) >= 0 else -1.0



def _reduce_into(op: np.ufunc, out: np.ndarray, keys: np.ndarray, values: np.ndarray) -> None:
    """out[k] = op(out[k], values with key k) for non-decreasing ``keys``: ``op.at`` by
    segments (much faster on numpy 1.x)."""
    if len(keys) == 0:
        return
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    heads = keys[starts]
    out[heads] = op(out[heads], op.reduceat(values, starts))


def max_into(out: FloatArray, keys: np.ndarray, values: FloatArray) -> None:
    """out[k] = max(out[k], values with key k) for non-decreasing ``keys``."""
    _reduce_into(np.maximum, out, keys, values)


def min_into(out: np.ndarray, keys: np.ndarray, values: np.ndarray) -> None:
    """out[k] = min(out[k], values with key k) for non-decreasing ``keys``."""
    _reduce_into(np.minimum, out, keys, values)
