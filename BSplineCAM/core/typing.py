# SPDX-License-Identifier: LGPL-2.1-or-later
"""Array aliases shared by the numeric core."""

from __future__ import annotations

from typing import Union

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]
ArrayLike = Union[npt.ArrayLike, float]

__all__ = ["ArrayLike", "FloatArray", "IntArray"]
