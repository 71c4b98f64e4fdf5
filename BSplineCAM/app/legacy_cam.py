# SPDX-License-Identifier: LGPL-2.1-or-later
"""Documents saved by FreeCAD 0.20 name their CAM objects' classes by 0.20's modules
(``PathScripts.PathJob``, ...); FreeCAD 1.0 moved those classes without forwarding modules.
This import hook forwards the old names, so such a document restores its Job, stock, tool bits
and tool controllers in 1.0 and 1.1.  Part of :mod:`BSplineCAM.app.compat`; standard library
only, because the addon's Init.py installs it at FreeCAD start-up, before anything else.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys

#: FreeCAD 0.20 module names that saved documents name as their objects' proxies, and where
#: 1.0 and 1.1 keep those classes.  FreeCAD 1.0 moved them without a forwarding module, so a
#: 0.20 CAM job opened there loses its Job, stock, tool bit and tool controller behaviour
#: (1.1 forwards 1.0's ``Path.Tool.Bit`` itself, once ``Path.Tool`` is imported).
LEGACY_CAM_MODULES = {
    "PathScripts.PathJob": "Path.Main.Job",
    "PathScripts.PathSetupSheet": "Path.Base.SetupSheet",
    "PathScripts.PathStock": "Path.Main.Stock",
    "PathScripts.PathToolBit": "Path.Tool.Bit",
    "PathScripts.PathToolController": "Path.Tool.Controller",
    "PathScripts.PathSurface": "Path.Op.Surface",
    "PathScripts.PathJobGui": "Path.Main.Gui.Job",
    "PathScripts.PathSetupSheetGui": "Path.Base.Gui.SetupSheet",
    "PathScripts.PathToolBitGui": "Path.Tool.Gui.Bit",
    "PathScripts.PathToolControllerGui": "Path.Tool.Gui.Controller",
    "PathScripts.PathIconViewProvider": "Path.Base.Gui.IconViewProvider",
    "PathScripts.PathSurfaceGui": "Path.Op.Gui.Surface",
}


class _LegacyCamFinder:
    """Import hook: an old ``PathScripts.X`` name imports the module that holds X's classes
    now.  Only names of :data:`LEGACY_CAM_MODULES`, only where the old module is gone."""

    bsplinecam_legacy_cam = True

    def find_spec(self, fullname, path=None, target=None):
        new = LEGACY_CAM_MODULES.get(fullname)
        if new is None:
            return None
        # last on sys.meta_path: reached only when no other finder has the old module (1.0, 1.1)
        try:
            if new == "Path.Tool.Bit" or new.startswith("Path.Tool.Gui."):
                importlib.import_module("Path.Tool")  # 1.1 registers its forwarding names here
            target_spec = importlib.util.find_spec(new)
        except (ImportError, ValueError):
            return None
        if target_spec is None:
            return None
        # the origin is the real file: FreeCAD restores objects only from modules that live in
        # FreeCAD's or an installed addon's folders, and judges by it
        return importlib.util.spec_from_loader(fullname, _LegacyCamLoader(new),
                                               origin=target_spec.origin)


class _LegacyCamLoader:
    def __init__(self, target: str) -> None:
        self.target = target

    def create_module(self, spec):
        module = importlib.import_module(self.target)
        self._spec = module.__spec__
        return module

    def exec_module(self, module) -> None:
        module.__spec__ = self._spec  # the module keeps its own identity


def install_legacy_cam_modules() -> None:
    """Let documents saved by FreeCAD 0.20 restore their CAM objects in 1.0 and 1.1 (a no-op
    in 0.20, whose modules exist).  Called at FreeCAD start-up by the addon's Init.py; once is
    enough (this file may be loaded under two names, so the finder is told by a marker)."""
    if not any(getattr(f, "bsplinecam_legacy_cam", False) for f in sys.meta_path):
        sys.meta_path.append(_LegacyCamFinder())
