# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD start-up of the BSplineCAM addon (also in freecadcmd): file types only.

Registering a type is a string; the handler module is imported only when a file is opened.
"""

FreeCAD.addImportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addImportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline control net (*.json *.csv)", "BSplineCAM.app.importers")  # noqa: F821
FreeCAD.addExportType("B-spline point grid (*.dat)", "BSplineCAM.app.importers")  # noqa: F821
