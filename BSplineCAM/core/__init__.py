# SPDX-License-Identifier: LGPL-2.1-or-later
"""BSplineCAM's numeric core: numpy only, no FreeCAD.  Control net → surface → toolpath → check."""

from __future__ import annotations

from .errors import BSplineCAMError, NetError, ParameterError
from .geometry.basis import KnotLayout, cox_de_boor, knot_vector
from .geometry.matrix import MB
from .geometry.netio import ControlNet, read_dat, read_net, write_dat
from .geometry.surface import Derivatives, Surface

__all__ = [
    "MB", "BSplineCAMError", "ControlNet", "Derivatives", "KnotLayout", "NetError",
    "ParameterError", "Surface", "cox_de_boor", "knot_vector", "read_dat", "read_net", "write_dat",
]
