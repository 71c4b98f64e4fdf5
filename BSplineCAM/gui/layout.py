# SPDX-License-Identifier: LGPL-2.1-or-later
"""The workbench's toolbars and menu: which commands, in which order, from which modules.

``InitGui.py`` calls :func:`setup` inside ``Workbench.Initialize()``.  Modules listed in
``COMMAND_MODULES`` must provide ``register() -> list[str]`` (FreeCADGui.addCommand calls).
"""

from __future__ import annotations

import importlib

import FreeCAD

#: Modules whose ``register()`` adds commands, imported when the workbench first activates.
COMMAND_MODULES: list[str] = [
    "BSplineCAM.gui.commands",
    "BSplineCAM.gui.cam_commands",
    "BSplineCAM.gui.rough_panel",
    # >>> toolpath / verify engineers: add your command modules here, e.g.
    # "BSplineCAM.gui.toolpath_commands",
]

#: Surface design commands (issue 3).
SURFACE_COMMANDS: list[str] = [
    "BSplineCAM_NewSurface",
    "BSplineCAM_EditNet",
    "BSplineCAM_CrossCheck",
    "BSplineCAM_ExportDat",
    "BSplineCAM_ExportStep",
    "BSplineCAM_PaperRoute",
]

# ============================================================================================
# >>> TOOLPATH AND VERIFY COMMANDS GO HERE (later issues).  Add the command names in toolbar
# >>> order; each becomes a toolbar and a submenu once the list is non-empty.
TOOLPATH_COMMANDS: list[str] = ["BSplineCAM_Job", "BSplineCAM_Rough", "BSplineCAM_PostProcess"]
VERIFY_COMMANDS: list[str] = ["BSplineCAM_Verify"]
# ============================================================================================

#: (toolbar title, command names); empty lists are skipped.
TOOLBARS: list[tuple[str, list[str]]] = [
    ("BSplineCAM surface", SURFACE_COMMANDS),
    ("BSplineCAM toolpath", TOOLPATH_COMMANDS),
    ("BSplineCAM verify", VERIFY_COMMANDS),
]
MENU = "&BSplineCAM"


def register_commands() -> list[str]:
    """Import every command module and register its commands; a broken module is reported
    and skipped so the rest of the workbench still loads."""
    names: list[str] = []
    for module in COMMAND_MODULES:
        try:
            names += importlib.import_module(module).register()
        except Exception as exc:  # noqa: BLE001 - one broken module must not kill the bench
            FreeCAD.Console.PrintError(f"BSplineCAM: cannot load {module}: {exc}\n")
    return names


def setup(workbench) -> list[str]:
    """Register the commands and build the toolbars and menu of ``workbench``."""
    registered = set(register_commands())
    all_names: list[str] = []
    for title, commands in TOOLBARS:
        present = [name for name in commands if name in registered]
        missing = sorted(set(commands) - registered)
        if missing:
            FreeCAD.Console.PrintWarning(f"BSplineCAM: unregistered commands {missing}\n")
        if present:
            workbench.appendToolbar(title, present)
            if all_names:
                all_names.append("Separator")
            all_names += present
    workbench.appendMenu(MENU, all_names)
    return all_names
