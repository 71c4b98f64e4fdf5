# SPDX-License-Identifier: LGPL-2.1-or-later
"""Geometry: knots and bases, the matrix and Bernstein evaluators, surfaces, nets, trimmed faces and the heights of a part seen from above."""
