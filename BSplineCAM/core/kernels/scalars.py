# SPDX-License-Identifier: LGPL-2.1-or-later
"""Two-float minimum and maximum for the compiled kernels, with numpy's NaN rule, in the two
tie rules the kernels' numpy twins need to agree to the bit:

* :func:`nan_min`, :func:`nan_max`: ``np.minimum`` / ``np.maximum`` (NaN if either is), the
  first operand on a tie;
* :func:`least`, :func:`most`: the same, the second operand on a tie and a NaN operand
  returned as it is.
"""

from __future__ import annotations

from . import helper


@helper
def nan_min(a, b):
    """``np.minimum`` of two floats (a NaN operand gives NaN)."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


@helper
def nan_max(a, b):
    """``np.maximum`` of two floats (a NaN operand gives NaN)."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@helper
def least(a, b):
    """np.minimum(a, b) of two floats (NaN wins)."""
    if a < b or a != a:
        return a
    return b


@helper
def most(a, b):
    """np.maximum(a, b) of two floats (NaN wins)."""
    if a > b or a != a:
        return a
    return b
