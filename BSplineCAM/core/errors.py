# SPDX-License-Identifier: LGPL-2.1-or-later
"""Errors the core raises for bad input; each message names the file, line or index at fault."""

from __future__ import annotations


class BSplineCAMError(ValueError):
    """Base class: bad input that the user can correct."""


class NetError(BSplineCAMError):
    """A control net or point file that cannot form a valid cubic B-spline surface."""


class ParameterError(BSplineCAMError):
    """A numeric option (tool, stepover, tolerance, parameter value) out of its valid range."""
