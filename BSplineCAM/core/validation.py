# SPDX-License-Identifier: LGPL-2.1-or-later
"""Checks of user-given numbers and names: each returns the clean value or raises
ParameterError naming the argument, its unit and what was expected.

Shared by the stock models (:mod:`BSplineCAM.core.simulation.stock`) and the toolpath parameters
(:mod:`BSplineCAM.core.toolpath.common`, which re-exports them), so neither imports the other.
"""

from __future__ import annotations

import math
from enum import Enum
from typing import Any

from .errors import ParameterError


def parse_enum(enum: type[Enum], value: Any, argument: str,
               error: type[Exception] = ParameterError) -> Any:
    """Enum member from itself or its string; ``error`` (ParameterError by default) naming
    ``argument`` and the valid values otherwise."""
    if isinstance(value, enum):
        return value
    try:
        return enum(str(value).strip().lower())
    except ValueError:
        valid = ", ".join(repr(m.value) for m in enum)
        raise error(f"unknown {argument} {value!r}: expected one of {valid}") from None


def check_positive(value: Any, argument: str, unit: str = "mm") -> float:
    """A finite number > 0, else ParameterError naming argument and unit."""
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{argument} must be a number in {unit}, got {value!r}") from None
    if not math.isfinite(number) or number <= 0.0:
        raise ParameterError(f"{argument} must be a finite number > 0 {unit}, got {value!r}")
    return number


def check_finite(value: Any, argument: str, unit: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{argument} must be a number in {unit}, got {value!r}") from None
    if not math.isfinite(number):
        raise ParameterError(f"{argument} must be finite ({unit}), got {value!r}")
    return number


def check_range(value: Any, argument: str, unit: str, low: float, high: float,
                low_open: bool = False) -> float:
    """A finite number in [low, high] ((low, high] if ``low_open``), else ParameterError
    naming ``argument``, the range and ``unit``."""
    number = check_finite(value, argument, unit)
    if number < low or number > high or (low_open and number == low):
        bracket = "(" if low_open else "["
        raise ParameterError(
            f"{argument} must lie in {bracket}{low:g}, {high:g}] {unit}, got {number:g} {unit}")
    return number
