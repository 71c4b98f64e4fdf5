# SPDX-License-Identifier: LGPL-2.1-or-later
"""Simulation: the stock, the Z-map cut by a program's moves, whole jobs with tool changes, verification against the design and machining time."""
