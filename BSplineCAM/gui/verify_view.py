# SPDX-License-Identifier: LGPL-2.1-or-later
"""View provider of the simulated part: the Z-map mesh coloured by deviation, with a legend.

Colours per top vertex from the object's ``Deviation`` (machined - design, mm): green within
``Band`` of the design, blending to blue where material is left (full blue at the scallop
scale) and to red where the tool gouged (full red at the gouge scale); walls and base grey.
The mesh is drawn by our own Coin nodes (a ``Deviation`` display mode, per-vertex material)
with a colour bar fixed to the screen, as FEM's result colour bar: it hangs in the display
mode under an orthographic camera of its own (``LEAVE_ALONE``: x and y in [-1, 1] span the
view whatever the 3D camera does), in an annotation (drawn last, over the part) inside a
group that fitAll leaves out.  Its size on screen does not change with zoom or rotation, and it
never overlaps the part from a side.  The figures themselves are in the results task panel
(:mod:`.results_panel`).  The proxy keeps only nodes that ``attach`` rebuilds; it pickles as
None.
"""

from __future__ import annotations

import json

import FreeCAD
import numpy as np

from ..app.proxy import StatelessProxy
from .resources import icon

MODE = "Deviation"
GREEN = np.array([0.1, 0.75, 0.2])
BLUE = np.array([0.1, 0.25, 0.95])
RED = np.array([0.95, 0.1, 0.1])
GREY = np.array([0.62, 0.62, 0.62])
#: (type, name, group, tooltip, default) of the view properties.
VIEW_PROPERTIES: tuple[tuple[str, str, str, str, object], ...] = (
    ("App::PropertyFloat", "Band", "Deviation colours",
     "Green within this distance of the design (mm)", 0.005),
    ("App::PropertyFloat", "ScallopScale", "Deviation colours",
     "Material left shown full blue (mm; 0 = the inner scallop p99)", 0.0),
    ("App::PropertyFloat", "GougeScale", "Deviation colours",
     "Gouge shown full red (mm; 0 = the largest gouge)", 0.0),
    ("App::PropertyBool", "ShowLegend", "Deviation colours", "Draw the colour bar", True),
)


def ensure_view_properties(vobj) -> None:
    for kind, name, group, tip, default in VIEW_PROPERTIES:
        if not hasattr(vobj, name):
            vobj.addProperty(kind, name, group, tip)
            setattr(vobj, name, default)


def colour_scale(metrics: dict, band: float, scallop: float = 0.0,
                 gouge: float = 0.0) -> tuple[float, float, float]:
    """(band, scallop scale, gouge scale) in mm; zero scales follow the metrics."""
    band = max(float(band), 1e-6)
    if not scallop > 0:
        scallop = float(metrics.get("scallop_p99_mm", 0.0))
    if not gouge > 0:
        gouge = float(metrics.get("gouge_max_mm", 0.0))
    return band, max(scallop, 2 * band), max(gouge, 2 * band)


def deviation_colours(deviation: np.ndarray, band: float, scallop: float,
                      gouge: float) -> np.ndarray:
    """RGB (n, 3) per deviation (mm): green in [-band, band], to blue at +scallop, to red at
    -gouge, grey for NaN (off the footprint)."""
    d = np.asarray(deviation, dtype=float)
    out = np.tile(GREY, (len(d), 1))
    ok = ~np.isnan(d)
    dv = np.where(ok, d, 0.0)
    up = np.clip((dv - band) / max(scallop - band, 1e-12), 0.0, 1.0)[:, None]
    down = np.clip((-dv - band) / max(gouge - band, 1e-12), 0.0, 1.0)[:, None]
    colour = GREEN + up * (BLUE - GREEN) + down * (RED - GREEN)
    out[ok] = colour[ok]
    return out


class VerificationViewProvider(StatelessProxy):
    """Per-vertex deviation colours on the simulated part's mesh and a colour bar."""

    def __init__(self, vobj) -> None:
        vobj.Proxy = self
        ensure_view_properties(vobj)

    def attach(self, vobj) -> None:
        from pivy import coin

        ensure_view_properties(vobj)
        self.ViewObject = vobj
        self.root = coin.SoSeparator()
        hints = coin.SoShapeHints()
        hints.vertexOrdering = coin.SoShapeHints.COUNTERCLOCKWISE
        hints.shapeType = coin.SoShapeHints.SOLID
        hints.creaseAngle = 0.6
        self.coords = coin.SoCoordinate3()
        # the machined top: a colour per vertex
        top = coin.SoSeparator()
        self.binding = coin.SoMaterialBinding()
        self.binding.value = coin.SoMaterialBinding.PER_VERTEX_INDEXED
        self.material = coin.SoMaterial()
        self.faces = coin.SoIndexedFaceSet()
        for node in (self.binding, self.material, self.faces):
            top.addChild(node)
        # the block's walls and base: grey
        sides = coin.SoSeparator()
        grey = coin.SoMaterial()
        grey.diffuseColor = tuple(map(float, GREY))
        self.side_faces = coin.SoIndexedFaceSet()
        sides.addChild(grey)
        sides.addChild(self.side_faces)
        for node in (hints, self.coords, top, sides):
            self.root.addChild(node)
        self.legend_switch = coin.SoSwitch()
        self.legend = screen_overlay()
        self.hud_camera = self.legend.getChild(0).getChild(0)
        self.legend_content = coin.SoSeparator()
        self.legend.getChild(0).addChild(self.legend_content)
        self.legend_switch.addChild(self.legend)
        self.root.addChild(self.legend_switch)
        vobj.addDisplayMode(self.root, MODE)
        self.colours = np.zeros((0, 3))
        self.scale = (0.005, 0.01, 0.01)
        self._rebuild(vobj.Object)

    # -- FreeCAD display modes -----------------------------------------------------------------
    def getDisplayModes(self, vobj):  # noqa: N802 - FreeCAD API
        return [MODE]

    def getDefaultDisplayMode(self):  # noqa: N802 - FreeCAD API
        return MODE

    def setDisplayMode(self, mode):  # noqa: N802 - FreeCAD API
        return mode

    # -- reacting to changes -------------------------------------------------------------------
    def updateData(self, obj, prop: str) -> None:  # noqa: N802 - FreeCAD API
        if prop in ("Mesh", "Deviation", "Metrics") and hasattr(self, "coords"):
            self._rebuild(obj)

    def onChanged(self, vobj, prop: str) -> None:  # noqa: N802 - FreeCAD API
        if hasattr(self, "coords") and prop in {p[1] for p in VIEW_PROPERTIES}:
            self._rebuild(vobj.Object)

    def _rebuild(self, obj) -> None:
        from ..app.verify_feature import deviation_of

        mesh = obj.Mesh
        points, facets = mesh.Topology
        n = len(points)
        if n == 0:
            self.coords.point.setNum(0)
            self.faces.coordIndex.setNum(0)
            return
        vobj = self.ViewObject
        metrics = json.loads(obj.Metrics or "{}")
        self.scale = colour_scale(metrics, getattr(vobj, "Band", 0.005),
                                  getattr(vobj, "ScallopScale", 0.0),
                                  getattr(vobj, "GougeScale", 0.0))
        deviation = np.full(n, np.nan)
        top = deviation_of(obj)
        deviation[:min(len(top), n)] = top[:n]
        self.colours = deviation_colours(deviation, *self.scale)
        self.coords.point.setValues(0, n, [tuple(p) for p in points])
        self.coords.point.setNum(n)
        facets = np.asarray(facets, dtype=np.int64).reshape(-1, 3)
        on_top = np.all(facets < int(obj.GridRows) * int(obj.GridColumns), axis=1)
        for faces, chosen, coloured in ((self.faces, facets[on_top], True),
                                        (self.side_faces, facets[~on_top], False)):
            index = np.column_stack([chosen, np.full(len(chosen), -1)]).ravel().tolist()
            faces.coordIndex.setValues(0, len(index), index)
            faces.coordIndex.setNum(len(index))
            if coloured:
                faces.materialIndex.setValues(0, len(index), index)
                faces.materialIndex.setNum(len(index))
        self.material.diffuseColor.setValues(0, n, [tuple(map(float, c)) for c in self.colours])
        self.material.diffuseColor.setNum(n)
        self._build_legend()
        self.legend_switch.whichChild = 0 if getattr(vobj, "ShowLegend", True) else -1

    def _build_legend(self) -> None:
        """The colour bar in screen coordinates: red (gouge) at the bottom, blue on top."""
        from pivy import coin

        content = self.legend_content
        content.removeAllChildren()
        band, scallop, gouge = self.scale
        x0, x1 = LEGEND_X
        y0, y1 = LEGEND_Y
        stops = [(-gouge, RED), (-band, GREEN), (band, GREEN), (scallop, BLUE)]
        # heights of the stops on the bar: gouge quarter, green band, scallop half
        levels = [0.0, 0.25, 0.45, 1.0]
        verts, colours = [], []
        for (_, colour), level in zip(stops, levels):
            y = y0 + level * (y1 - y0)
            verts += [(x0, y, 0.0), (x1, y, 0.0)]
            colours += [tuple(map(float, colour))] * 2
        binding = coin.SoMaterialBinding()
        binding.value = coin.SoMaterialBinding.PER_VERTEX
        material = coin.SoMaterial()
        material.diffuseColor.setValues(0, len(colours), colours)
        self.legend_coords = coords = coin.SoCoordinate3()
        coords.point.setValues(0, len(verts), verts)
        strip = coin.SoQuadMesh()
        strip.verticesPerRow = 2
        strip.verticesPerColumn = len(levels)
        bar = coin.SoSeparator()
        for node in (binding, material, coords, strip):
            bar.addChild(node)
        content.addChild(bar)
        labels = [(levels[0], f"-{gouge:.3g} mm gouge"),
                  (0.5 * (levels[1] + levels[2]), f"\u00b1{band:.3g} mm on design"),
                  (levels[3], f"+{scallop:.3g} mm material left"),
                  (1.1, "Deviation from design")]
        self.legend_labels = []
        for level, text in labels:
            node = coin.SoSeparator()
            move = coin.SoTranslation()
            # to the right of the bar, which stands at the view's left edge (FreeCAD 1.1 lays
            # its task panel over the right of the view)
            move.translation = (x1 + 0.012, y0 + level * (y1 - y0) - 0.01, 0.0)
            colour = coin.SoBaseColor()
            colour.rgb = (0.05, 0.05, 0.05)
            font = coin.SoFont()
            font.size = 14
            label = coin.SoText2()
            label.string = text
            label.justification = coin.SoText2.LEFT
            for child in (move, colour, font, label):
                node.addChild(child)
            content.addChild(node)
            self.legend_labels.append(text)

    # -- editing: the figures in a task panel ----------------------------------------------------
    def setEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        if mode != 0:
            return None
        from . import results_panel

        results_panel.show(results_panel.verification_panel(vobj.Object))
        return True

    def unsetEdit(self, vobj, mode: int = 0):  # noqa: N802 - FreeCAD API
        if mode != 0:
            return None
        return True

    def doubleClicked(self, vobj) -> bool:  # noqa: N802 - FreeCAD API
        from . import results_panel

        return results_panel.show(results_panel.verification_panel(vobj.Object))

    def getIcon(self) -> str:  # noqa: N802 - FreeCAD API
        return icon("verify")


#: Where the colour bar stands on screen: x and y from -1 (left, bottom) to 1 (right, top).
LEGEND_X = (-0.94, -0.90)
LEGEND_Y = (-0.55, 0.45)


def screen_overlay():
    """Nodes drawn fixed to the screen: a group fitAll leaves out (FreeCAD's
    SoSkipBoundingGroup), holding an annotation (drawn last, no depth test) whose first child
    is an orthographic camera mapping x, y in [-1, 1] onto the whole view."""
    from pivy import coin

    kind = coin.SoType.fromName("SoSkipBoundingGroup")
    # FreeCAD's fitAll switches its SoSkipBoundingGroups to EXCLUDE_BBOX while it measures
    group = coin.SoSeparator() if kind.isBad() else kind.createInstance()
    overlay = coin.SoAnnotation()
    camera = coin.SoOrthographicCamera()
    camera.viewportMapping = coin.SoCamera.LEAVE_ALONE
    camera.position = (0.0, 0.0, 5.0)
    camera.height = 2.0
    camera.aspectRatio = 1.0
    camera.nearDistance = 1.0
    camera.farDistance = 10.0
    light = coin.SoLightModel()
    light.model = coin.SoLightModel.BASE_COLOR
    pick = coin.SoPickStyle()
    pick.style = coin.SoPickStyle.UNPICKABLE
    hints = coin.SoShapeHints()  # seen from both sides (the part's hints cull back faces)
    hints.shapeType = coin.SoShapeHints.UNKNOWN_SHAPE_TYPE
    hints.vertexOrdering = coin.SoShapeHints.UNKNOWN_ORDERING
    for node in (camera, light, pick, hints):
        overlay.addChild(node)
    group.addChild(overlay)
    return group


def attach_view_provider(obj) -> None:
    """Give a verification object this view provider (make_verification calls it)."""
    vobj = getattr(obj, "ViewObject", None)
    if vobj is None:
        FreeCAD.Console.PrintWarning(f"{obj.Label}: no view object to attach to\n")
        return
    VerificationViewProvider(vobj)
    vobj.DisplayMode = MODE
