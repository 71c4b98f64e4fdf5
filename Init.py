# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD start-up of the BSplineCAM addon (also in freecadcmd): file types, and the names
under which FreeCAD 0.20 saved CAM objects (so older documents open in 1.0 and 1.1).

Registering a type is a string; the handler module is imported only when a file is opened.
The legacy names cost an entry on sys.meta_path: BSplineCAM/app/legacy_cam.py is loaded by its
path (standard library only), so neither BSplineCAM nor CAM is imported at start-up.
"""

import importlib.util as _util
import os as _os

_package = _util.find_spec("BSplineCAM")  # located, not imported
if _package is not None and _package.origin:
    _spec = _util.spec_from_file_location(
        "_bsplinecam_legacy_cam", _os.path.join(_os.path.dirname(_package.origin), "app", "legacy_cam.py"))
    _legacy = _util.module_from_spec(_spec)
    _spec.loader.exec_module(_legacy)
    _legacy.install_legacy_cam_modules()

FreeCAD.addImportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addImportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
