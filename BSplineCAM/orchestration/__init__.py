# SPDX-License-Identifier: LGPL-2.1-or-later
"""Orchestration: the command line, worker processes, the rs274 bridge and report pictures.

Everything here drives the stages (core, and app inside FreeCAD) and is driven by nothing
below it: neither core nor app imports this package (the worker processes' launcher and the
cross-check live in app: :mod:`BSplineCAM.app.runtime`, :mod:`BSplineCAM.app.crosscheck`).
"""
