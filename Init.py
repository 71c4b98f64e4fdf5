# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD start-up of the BSplineCAM addon (also in freecadcmd): file types, and the names
under which FreeCAD 0.20 saved CAM objects (so older documents open in 1.0 and 1.1).

Registering a type is a string; the handler module is imported only when a file is opened.
The legacy names cost an entry on sys.meta_path; nothing of CAM is imported at start-up.
"""

from BSplineCAM.app.compat import install_legacy_cam_modules

install_legacy_cam_modules()

FreeCAD.addImportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addImportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
