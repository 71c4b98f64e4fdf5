# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD GUI start-up of the BSplineCAM addon: registers the workbench, imports nothing heavy.

FreeCAD exec()s this file inside a function, so the class must not use other names defined
here; methods import what they need.  Commands, numpy and FreeCAD objects load on first
activation (``Initialize``), keeping FreeCAD's start fast.
"""


class BSplineCAMWorkbench(Workbench):  # noqa: F821 - FreeCAD provides Workbench
    """Cubic B-spline surface from control net to G-code."""

    MenuText = "BSplineCAM"
    ToolTip = "Cubic B-spline surfaces from control net to verified G-code"

    def __init__(self):
        # the package's location without importing it (find_spec does not run the package)
        import importlib.util
        import os

        spec = importlib.util.find_spec("BSplineCAM")
        if spec is not None and spec.origin:
            root = os.path.dirname(os.path.dirname(os.path.abspath(spec.origin)))
            self.__class__.Icon = os.path.join(root, "resources", "icons", "BSplineCAM.svg")

    def Initialize(self):
        from BSplineCAM.gui import layout

        layout.setup(self)

    def Activated(self):
        return None

    def Deactivated(self):
        return None

    def GetClassName(self):
        return "Gui::PythonWorkbench"


Gui.addWorkbench(BSplineCAMWorkbench())  # noqa: F821 - FreeCAD provides Gui
