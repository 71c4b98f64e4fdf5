# SPDX-License-Identifier: LGPL-2.1-or-later
"""Handlers for FreeCAD's Import/Export dialogs: control nets (.json, .csv) and .dat points.

``Init.py`` registers this module with ``FreeCAD.addImportType`` / ``addExportType``; FreeCAD
then calls ``open(filename)``, ``insert(filename, docname)`` and ``export(objects, filename)``.
A bad file is reported (report view, and a dialog when the GUI is up) instead of raising, and
leaves the documents as they were: files are read and validated before any document changes.
"""

from __future__ import annotations

import os
from pathlib import Path

from ..core import BSplineCAMError, Surface
from ..core.geometry import netio
from . import part
from .compat import ensure_freecad
from .surface_feature import make_surface, surface_of, surfaces_in

FreeCAD = ensure_freecad()

#: Points per side of an exported .dat grid: the paper's sampling (see crosscheck).
DAT_POINTS = 21
NET_SUFFIXES = (".json", ".csv")
DAT_SUFFIXES = (".dat",)


def report_error(title: str, message: str) -> None:
    """Report a user error: report view always, a message box only when the GUI is up."""
    FreeCAD.Console.PrintError(f"{title}: {message}\n")
    if FreeCAD.GuiUp:
        from ..gui.messages import show_error

        show_error(title, message)


def read_surface(filename: str | os.PathLike) -> Surface:
    """The core Surface of a control-net or .dat file (NetError names the file and line)."""
    return Surface.from_file(filename)


def open(filename: str) -> object | None:  # noqa: A001 - FreeCAD's importer API
    """Open a net file as a new document holding one parametric surface (None if bad)."""
    try:
        surface = read_surface(filename)
    except (BSplineCAMError, OSError) as exc:
        report_error("BSplineCAM import", str(exc))
        return None
    doc = FreeCAD.newDocument(_doc_name(filename))
    try:
        return _insert_surface(surface, doc)
    except Exception as exc:  # noqa: BLE001 - reported, the new document is closed again
        FreeCAD.closeDocument(doc.Name)
        report_error("BSplineCAM import", str(exc))
        return None


def insert(filename: str, docname: str | None = None) -> object | None:
    """Insert a net file into document ``docname`` as a parametric surface (None if bad)."""
    try:
        surface = read_surface(filename)
    except (BSplineCAMError, OSError) as exc:
        report_error("BSplineCAM import", str(exc))
        return None
    doc = _document(docname)
    try:
        return _insert_surface(surface, doc)
    except Exception as exc:  # noqa: BLE001 - make_surface removed its object already
        report_error("BSplineCAM import", str(exc))
        return None


def export(objects, filename: str) -> bool:
    """Export the first surface among ``objects``: its net (.json/.csv) or points (.dat)."""
    targets = surfaces_in(_flatten(objects))
    if not targets:
        report_error("BSplineCAM export", "select a B-spline surface object to export")
        return False
    try:
        write_surface(surface_of(targets[0]), filename)
    except (BSplineCAMError, OSError, ValueError) as exc:
        report_error("BSplineCAM export", str(exc))
        return False
    FreeCAD.Console.PrintMessage(f"BSplineCAM: exported {targets[0].Label} to {filename}\n")
    return True


def write_surface(surface: Surface, filename: str | os.PathLike, points: int = DAT_POINTS) -> None:
    """Write a surface by extension: net as .json/.csv, ``points``² surface points as .dat."""
    suffix = Path(filename).suffix.lower()
    if suffix == ".json":
        netio.write_json(surface.to_net(), filename)
    elif suffix == ".csv":
        netio.write_csv(surface.to_net(), filename)
    elif suffix in DAT_SUFFIXES:
        netio.write_dat(
            surface.grid(points, points), filename,
            comment=f"{surface.name}: {points}x{points} points on the surface (mm)",
        )
    else:
        raise ValueError(f"{filename}: unknown format {suffix!r}: expected .json, .csv or .dat")


def import_paper_route(filename: str | os.PathLike, design=None, doc=None):
    """The paper's import route: a .dat grid → a spline per row → a loft (a Part::Feature).

    When ``design`` (a surface object) is given, the deviation of the loft from the exact
    design surface is measured both ways by OCCT (mm) and stored on the new object in its
    ``Deviation`` (JSON) and ``MaxDeviation`` properties.  Raises NetError on a bad file
    before the document changes.
    """
    import json

    grid = netio.read_dat(filename)
    if doc is None:
        doc = design.Document if design is not None else FreeCAD.ActiveDocument
    if doc is None:
        doc = FreeCAD.newDocument()
    face = part.paper_route(grid)
    deviation = part.deviation_between(face, surface_of(design)) if design is not None else None
    label = f"{design.Label} (paper route)" if design is not None else Path(filename).stem
    obj = doc.addObject("Part::Feature", "PaperRoute")
    try:
        obj.Label = label
        obj.Shape = face
        obj.addProperty("App::PropertyString", "Source", "Paper route", ".dat file of points")
        obj.Source = str(filename)
        obj.addProperty("App::PropertyIntegerList", "Grid", "Paper route", "rows, columns")
        obj.Grid = [int(grid.shape[0]), int(grid.shape[1])]
        if deviation is not None:
            obj.addProperty("App::PropertyString", "Deviation", "Paper route",
                            "Deviation from the design surface (JSON, mm)")
            obj.Deviation = json.dumps(deviation, sort_keys=True)
            obj.addProperty("App::PropertyDistance", "MaxDeviation", "Paper route",
                            "Largest distance between the loft and the design (mm)")
            obj.MaxDeviation = float(deviation["max_deviation_mm"])
            FreeCAD.Console.PrintMessage(
                f"BSplineCAM paper route from {Path(filename).name} "
                f"({grid.shape[0]}x{grid.shape[1]} points): max deviation from "
                f"{design.Label} {deviation['max_deviation_mm']:.4g} mm "
                f"(design→loft {deviation['design_to_result_mm']:.3g} mm, "
                f"loft→design {deviation['result_to_design_mm']:.3g} mm)\n"
            )
    except BaseException:
        doc.removeObject(obj.Name)
        raise
    if FreeCAD.GuiUp and obj.ViewObject is not None:
        obj.ViewObject.ShapeColor = (0.9, 0.55, 0.2)
        obj.ViewObject.Transparency = 40
    doc.recompute()
    return obj


def _insert_surface(surface: Surface, doc):
    obj = make_surface(surface, doc=doc)
    doc.recompute()
    return obj


def _document(docname: str | None):
    if docname:
        try:
            return FreeCAD.getDocument(docname)
        except NameError:
            pass
    return FreeCAD.ActiveDocument or FreeCAD.newDocument()


def _doc_name(filename: str | os.PathLike) -> str:
    stem = "".join(ch if ch.isalnum() else "_" for ch in Path(filename).stem)
    return stem if stem and not stem[0].isdigit() else "BSplineCAM"


def _flatten(objects) -> list:
    if objects is None:
        return []
    if isinstance(objects, (list, tuple)):
        return list(objects)
    return [objects]


__all__ = ["DAT_POINTS", "export", "import_paper_route", "insert", "open", "write_surface"]
