# SPDX-License-Identifier: LGPL-2.1-or-later
"""Bridge to cadquery's OCCT (OCP): the second, independent OCCT, run outside FreeCAD."""
