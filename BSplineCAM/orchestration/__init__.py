# SPDX-License-Identifier: LGPL-2.1-or-later
"""Orchestration: the command line, worker processes, the rs274 bridge and report pictures.

Everything here drives the stages (core, and app inside FreeCAD) and is driven by nothing
below it: core never imports this package, app only lazily for the cross-check report.
"""
