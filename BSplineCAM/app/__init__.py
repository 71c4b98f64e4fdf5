# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD application layer: turns core data into FreeCAD things; never imports FreeCADGui."""
