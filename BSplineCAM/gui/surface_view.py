# SPDX-License-Identifier: LGPL-2.1-or-later
"""View provider of the B-spline surface: Part's shaded face plus the control polygon in Coin.

The control net is drawn under the object's own root node (so it follows the Placement) in a
switch driven by the ``ShowControlNet`` view property, on top of the surface (an annotation:
control points under the surface stay visible).  Like the feature, the proxy keeps only
Coin nodes it rebuilds in ``attach``; it pickles as None.
"""

from __future__ import annotations

import FreeCAD
import FreeCADGui

from ..app.proxy import StatelessProxy
from .resources import icon

#: (type, name, group, tooltip, default) of the view properties.
VIEW_PROPERTIES: tuple[tuple[str, str, str, str, object], ...] = (
    ("App::PropertyBool", "ShowControlNet", "Control net",
     "Draw the control polygon and its points", True),
    ("App::PropertyColor", "ControlNetColor", "Control net",
     "Colour of the control polygon", (0.85, 0.2, 0.15)),
    ("App::PropertyFloatConstraint", "ControlNetLineWidth", "Control net",
     "Line width of the control polygon (pixels)", (1.5, 0.5, 10.0, 0.5)),
    ("App::PropertyFloatConstraint", "ControlNetPointSize", "Control net",
     "Size of the control points (pixels)", (6.0, 1.0, 20.0, 1.0)),
)
#: Data properties whose change redraws the control net.
NET_PROPERTIES = ("ControlPoints", "Rows", "Columns")
EDIT_MODE_NET = 0


def ensure_view_properties(vobj) -> None:
    """Add missing view properties (new objects and documents from older versions)."""
    for kind, name, group, tip, default in VIEW_PROPERTIES:
        if not hasattr(vobj, name):
            vobj.addProperty(kind, name, group, tip)
            setattr(vobj, name, default)


def net_line_indices(rows: int, cols: int) -> list[int]:
    """Coin coordIndex of the control polygon: every row, then every column, -1 separated."""
    indices: list[int] = []
    for i in range(rows):
        indices += [i * cols + j for j in range(cols)] + [-1]
    for j in range(cols):
        indices += [i * cols + j for i in range(rows)] + [-1]
    return indices


class SurfaceViewProvider(StatelessProxy):
    """Draws the control net beside Part's rendering; double-click opens the net editor."""

    def __init__(self, vobj) -> None:
        vobj.Proxy = self
        ensure_view_properties(vobj)

    def attach(self, vobj) -> None:
        """Build the Coin nodes (called for new and restored objects)."""
        from pivy import coin

        ensure_view_properties(vobj)
        self.ViewObject = vobj
        self.switch = coin.SoSwitch()
        # an annotation: drawn after the surface, without depth test, so the points under the
        # surface (a hollow's) show through it instead of hiding half the net
        sep = coin.SoAnnotation()
        self.net_root = sep
        self.light = coin.SoLightModel()
        self.light.model = coin.SoLightModel.BASE_COLOR
        self.color = coin.SoBaseColor()
        self.style = coin.SoDrawStyle()
        self.coords = coin.SoCoordinate3()
        self.lines = coin.SoIndexedLineSet()
        self.point_style = coin.SoDrawStyle()
        self.points = coin.SoPointSet()
        for node in (self.light, self.color, self.style, self.coords, self.lines,
                     self.point_style, self.points):
            sep.addChild(node)
        self.switch.addChild(sep)
        vobj.RootNode.addChild(self.switch)
        self._update_style(vobj)
        self._update_net(vobj.Object)

    # -- reacting to changes -------------------------------------------------------------------
    def updateData(self, obj, prop: str) -> None:  # noqa: N802 - FreeCAD API
        if prop in NET_PROPERTIES and hasattr(self, "coords"):
            self._update_net(obj)

    def onChanged(self, vobj, prop: str) -> None:  # noqa: N802 - FreeCAD API
        if hasattr(self, "switch") and prop.startswith(("ShowControlNet", "ControlNet", "Visibility")):
            self._update_style(vobj)

    def _update_style(self, vobj) -> None:
        # the net hangs off the root node, outside the display modes: hide it with the object
        show = bool(getattr(vobj, "ShowControlNet", True)) and bool(getattr(vobj, "Visibility", True))
        self.switch.whichChild = 0 if show else -1
        r, g, b = tuple(getattr(vobj, "ControlNetColor", (0.85, 0.2, 0.15)))[:3]
        self.color.rgb.setValue(r, g, b)
        self.style.lineWidth = float(getattr(vobj, "ControlNetLineWidth", 1.5))
        self.point_style.pointSize = float(getattr(vobj, "ControlNetPointSize", 6.0))

    def _update_net(self, obj) -> None:
        rows = int(getattr(obj, "Rows", 0))
        cols = int(getattr(obj, "Columns", 0))
        points = [tuple(v) for v in getattr(obj, "ControlPoints", [])]
        if rows * cols != len(points) or not points:
            self.coords.point.setNum(0)
            self.lines.coordIndex.setNum(0)
            self.points.numPoints = 0
            return
        self.coords.point.setValues(0, len(points), points)
        self.coords.point.setNum(len(points))
        indices = net_line_indices(rows, cols)
        self.lines.coordIndex.setValues(0, len(indices), indices)
        self.lines.coordIndex.setNum(len(indices))
        self.points.numPoints = len(points)

    # -- editing -------------------------------------------------------------------------------
    def setEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        """Mode 0 opens the control-net task panel; other modes fall back to FreeCAD's."""
        if mode != EDIT_MODE_NET:
            return None
        from .net_panel import NetEditPanel

        self.panel = NetEditPanel(vobj.Object)  # kept for scripting and tests; not saved
        FreeCADGui.Control.showDialog(self.panel)
        return True

    def unsetEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        if mode != EDIT_MODE_NET:
            return None
        self.panel = None
        FreeCADGui.Control.closeDialog()
        return True

    def doubleClicked(self, vobj) -> bool:  # noqa: N802 - FreeCAD API
        from .results_panel import close_results, editing_dialog

        if editing_dialog():
            return False
        close_results()
        FreeCADGui.ActiveDocument.setEdit(vobj.Object.Name, EDIT_MODE_NET)
        return True

    def setupContextMenu(self, vobj, menu) -> None:  # noqa: N802 - FreeCAD API
        from PySide import QtGui

        action = QtGui.QAction(QtGui.QIcon(icon("edit_net")), "Edit control net", menu)
        name = vobj.Object.Name
        action.triggered.connect(lambda: FreeCADGui.ActiveDocument.setEdit(name, EDIT_MODE_NET))
        menu.addAction(action)

    def getIcon(self) -> str:  # noqa: N802 - FreeCAD API
        return icon("surface")


def attach_view_provider(obj) -> None:
    """Give a surface object this view provider (called by make_surface when the GUI is up)."""
    vobj = getattr(obj, "ViewObject", None)
    if vobj is None:
        FreeCAD.Console.PrintWarning(f"{obj.Label}: no view object to attach to\n")
        return
    SurfaceViewProvider(vobj)
    vobj.ShapeColor = (0.45, 0.62, 0.85)
