# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD GUI layer: commands, task panels and view providers.

Imported only when the GUI is up (``InitGui.py`` imports it inside ``Initialize()``); importing
it from ``freecadcmd`` is a bug.  Gui imports app, app imports core, never the other way.
"""
