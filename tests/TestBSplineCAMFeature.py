# SPDX-License-Identifier: LGPL-2.1-or-later
"""FreeCAD-layer tests of the "B-spline surface" object and the Import/Export handlers.

Run by FreeCAD's own Python (0.20 and 1.0): ``tools/run_freecad_tests.sh TestBSplineCAMFeature``.
Every shape is compared with the numpy core evaluator at many (u, w) to 1e-9 of the net's size,
before and after property changes, and after a save and a fresh load of the document.
"""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import sys
import tempfile
import unittest
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

try:
    import FreeCAD
except ImportError:  # a plain Python (the core's pytest run): these tests need FreeCAD's
    raise unittest.SkipTest("needs FreeCAD: run tools/run_freecad_tests.sh") from None

import numpy as np  # noqa: E402

import BSplineCAM  # noqa: E402
from BSplineCAM import NetError, Surface  # noqa: E402
from BSplineCAM.app import importers  # noqa: E402
from BSplineCAM.app import surface_feature as sf  # noqa: E402
from BSplineCAM.core.geometry import netio  # noqa: E402

CASE_STUDY = ROOT / "examples" / "case-study.json"
RELATIVE_TOLERANCE = 1e-9
SAMPLES = 400


def wavy_net(rows: int = 6, cols: int = 8, seed: int = 3) -> np.ndarray:
    """A height-field net with jitter, unlike the case study in size and shape."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 60, rows), np.linspace(-10, 30, cols), indexing="ij")
    z = 5 * np.sin(x / 9) * np.cos(y / 7) + rng.normal(scale=1.0, size=x.shape)
    net = np.stack([x, y, z], axis=-1)
    net[..., :2] += rng.normal(scale=0.5, size=net[..., :2].shape)
    return net


def design_face(shape, rows: int, cols: int):
    """The face carrying the design surface (the solid's sides have 2 poles one way)."""
    for face in shape.Faces:
        surf = face.Surface
        is_bspline = type(surf).__name__ == "BSplineSurface"
        if is_bspline and (surf.NbUPoles, surf.NbVPoles) == (rows, cols):
            return face
    raise AssertionError(f"no {rows}x{cols} B-spline face in {shape.ShapeType}")


def base_z(solid) -> float:
    """Height of the solid's planar base face (BoundBox is loose for B-spline faces)."""
    planes = [f for f in solid.Faces if type(f.Surface).__name__ == "Plane"]
    assert len(planes) == 1, f"{len(planes)} planar faces"
    heights = {round(v.Point.z, 9) for v in planes[0].Vertexes}
    assert len(heights) == 1, heights
    return heights.pop()


class BSplineCAMTestCase(unittest.TestCase):
    """A fresh document per test, and the comparison with the core evaluator."""

    def setUp(self) -> None:
        self.doc = FreeCAD.newDocument(f"TestBSplineCAM{abs(hash(self.id())) % 100000}")
        self.tmp = Path(tempfile.mkdtemp(prefix="bsplinecam-test-"))

    def tearDown(self) -> None:
        for name in list(FreeCAD.listDocuments()):
            if name.startswith("TestBSplineCAM") or name in getattr(self, "extra_docs", ()):
                FreeCAD.closeDocument(name)
        shutil.rmtree(self.tmp, ignore_errors=True)

    def assertSuccessfulRecompute(self, *objs) -> None:  # noqa: N802 - unittest style
        """Recompute the document and require every object valid and up to date."""
        self.doc.recompute()
        for obj in objs or self.doc.Objects:
            self.assertTrue(obj.isValid(), f"{obj.Label}: {obj.getStatusString()}")
            self.assertNotIn("Touched", obj.State)
            self.assertNotIn("Invalid", obj.State)

    def assertMatchesCore(self, obj, surface: Surface | None = None) -> None:  # noqa: N802
        """The object's face equals the core evaluator at many (u, w), boundaries included."""
        surface = surface or sf.surface_of(obj)
        rows, cols = surface.shape
        face = design_face(obj.Shape, rows, cols)
        self.assertTrue(obj.Shape.isValid())
        u0, u1, w0, w1 = face.ParameterRange
        for a, b in ((u0, 0.0), (u1, 1.0), (w0, 0.0), (w1, 1.0)):
            self.assertAlmostEqual(a, b, delta=1e-12)
        rng = np.random.default_rng(7)
        edge = np.linspace(0, 1, 11)
        u = np.concatenate([rng.random(SAMPLES), edge, edge, np.zeros(11), np.ones(11)])
        w = np.concatenate([rng.random(SAMPLES), np.zeros(11), np.ones(11), edge, edge])
        expected = surface.evaluate(u, w)
        got = np.array([tuple(face.valueAt(float(a), float(b))) for a, b in zip(u, w)])
        geom = face.Surface
        got_surface = np.array([tuple(geom.value(float(a), float(b))) for a, b in zip(u, w)])
        tolerance = RELATIVE_TOLERANCE * surface.size()
        self.assertLessEqual(float(np.abs(got - expected).max()), tolerance)
        self.assertLessEqual(float(np.abs(got_surface - expected).max()), tolerance)
        poles = np.array([[tuple(p) for p in row] for row in face.Surface.getPoles()])
        atol = 1e-12 * surface.size()
        np.testing.assert_allclose(poles, surface.control_points, rtol=0, atol=atol)

    def reopen(self, obj):
        """Save, close, load the file into a new document; the reloaded object."""
        name = obj.Name
        path = self.tmp / "surface.FCStd"
        self.doc.saveAs(str(path))
        FreeCAD.closeDocument(self.doc.Name)
        self.doc = FreeCAD.openDocument(str(path))
        return self.doc.getObject(name)


class TestSurfaceObject(BSplineCAMTestCase):
    def test_make_surface_from_path_via_package(self) -> None:
        """BSplineCAM.make_surface (lazy attribute) builds the exact case-study face."""
        obj = BSplineCAM.make_surface(str(CASE_STUDY), doc=self.doc)
        self.assertSuccessfulRecompute(obj)
        self.assertTrue(sf.is_surface(obj))
        self.assertEqual((obj.Rows, obj.Columns), (10, 10))
        self.assertEqual(obj.Knots, "clamped")
        self.assertEqual(obj.Version, sf.OBJECT_VERSION)
        self.assertEqual(obj.Shape.ShapeType, "Face")
        self.assertMatchesCore(obj, Surface.from_json(CASE_STUDY))

    def test_make_surface_in_active_document(self) -> None:
        FreeCAD.setActiveDocument(self.doc.Name)
        obj = sf.make_surface(wavy_net())
        self.assertIs(obj.Document, self.doc)
        self.assertEqual(obj.Knots, "uniform")
        self.assertMatchesCore(obj, Surface(wavy_net(), "uniform"))

    def test_change_control_point(self) -> None:
        obj = sf.make_surface(wavy_net(), doc=self.doc, knots="clamped")
        sf.set_control_point(obj, 2, 3, (20.0, 5.0, 17.5))
        self.assertIn("Touched", obj.State)
        self.assertSuccessfulRecompute(obj)
        net = wavy_net()
        net[2, 3] = (20.0, 5.0, 17.5)
        self.assertMatchesCore(obj, Surface(net, "clamped"))
        with self.assertRaises(IndexError):
            sf.set_control_point(obj, 6, 0, (0, 0, 0))

    def test_change_knot_layout(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc)
        corner = FreeCAD.Vector(*Surface.from_json(CASE_STUDY).control_points[0, 0])
        self.assertLess((obj.Shape.Faces[0].valueAt(0, 0) - corner).Length, 1e-9)
        obj.Knots = "uniform"
        self.assertSuccessfulRecompute(obj)
        surface = Surface(Surface.from_json(CASE_STUDY).control_points, "uniform")
        self.assertMatchesCore(obj, surface)
        self.assertGreater((obj.Shape.Faces[0].valueAt(0, 0) - corner).Length, 0.1)

    def test_make_solid_and_base_offset(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc)
        obj.MakeSolid = True
        self.assertSuccessfulRecompute(obj)
        self.assertEqual(obj.Shape.ShapeType, "Solid")
        self.assertGreater(obj.Shape.Volume, 0)
        self.assertMatchesCore(obj)
        surface = sf.surface_of(obj)
        lowest = float(surface.grid(65, 65)[..., 2].min())
        first = base_z(obj.Shape)
        self.assertLessEqual(first, lowest - 5.0 + 1e-9)  # at least BaseOffset below
        obj.BaseOffset = 12.0
        self.assertSuccessfulRecompute(obj)
        self.assertAlmostEqual(base_z(obj.Shape), first - 7.0, places=6)
        obj.MakeSolid = False
        self.assertSuccessfulRecompute(obj)
        self.assertEqual(obj.Shape.ShapeType, "Face")

    def test_extent_is_the_surface_not_its_poles(self) -> None:
        """The exact extent (heights and stock of a job) against a dense grid of the core's
        evaluation; OCCT's box of the face encloses the poles and stands higher on a hill."""
        from BSplineCAM.app import part

        for knots in ("clamped", "uniform"):
            with self.subTest(knots=knots):
                surface = Surface(wavy_net(), knots)
                extent = part.surface_extent(surface)
                g = np.linspace(0.0, 1.0, 601)
                points = surface.evaluate_grid(g, g).reshape(-1, 3)
                low, high = points.min(axis=0), points.max(axis=0)
                found = np.array([[extent.x_min, extent.y_min, extent.z_min],
                                  [extent.x_max, extent.y_max, extent.z_max]])
                np.testing.assert_allclose(found, [low, high], atol=1e-3)
                self.assertTrue(np.all(found[0] <= low + 1e-12) and np.all(found[1] >= high - 1e-12))
        x, y = np.meshgrid(np.linspace(0, 60, 7), np.linspace(0, 60, 7), indexing="ij")
        net = np.stack([x, y, np.full((7, 7), 10.0)], axis=-1)
        net[3, 3, 2] = 40.0
        hill = Surface(net, "clamped")
        self.assertLess(part.surface_extent(hill).z_max, part.to_face(hill).BoundBox.ZMax - 10.0)
        # extents are remembered by the net: the same shape with a higher pole is searched anew
        net[3, 3, 2] = 70.0
        higher = Surface(net, "clamped")
        top = higher.evaluate_grid(np.linspace(0.4, 0.6, 201), np.linspace(0.4, 0.6, 201))
        self.assertAlmostEqual(part.surface_extent(higher).z_max, float(top[..., 2].max()),
                               places=3)
        self.assertGreater(part.surface_extent(higher).z_max,
                           part.surface_extent(hill).z_max + 10.0)

    def test_placement_is_kept(self) -> None:
        obj = sf.make_surface(wavy_net(), doc=self.doc)
        obj.Placement = FreeCAD.Placement(FreeCAD.Vector(100, 0, 0), FreeCAD.Rotation())
        obj.touch()
        self.assertSuccessfulRecompute(obj)
        self.assertAlmostEqual(obj.Placement.Base.x, 100.0)
        corner = Surface(wavy_net()).evaluate(0.5, 0.5)
        got = obj.Shape.Faces[0].valueAt(0.5, 0.5)
        self.assertAlmostEqual(got.x, corner[0] + 100.0, places=9)

    def test_inconsistent_net_is_an_error_not_a_crash(self) -> None:
        obj = sf.make_surface(wavy_net(), doc=self.doc)
        obj.Rows = 5
        self.doc.recompute()
        self.assertFalse(obj.isValid())
        obj.Rows = 6
        self.assertSuccessfulRecompute(obj)

    def test_bad_array_leaves_document_unchanged(self) -> None:
        for bad in (np.zeros((2, 5, 3)), np.full((4, 4, 3), np.nan), [[1, 2, 3]]):
            with self.assertRaises(NetError):
                sf.make_surface(bad, doc=self.doc)
        self.assertEqual(self.doc.Objects, [])

    def test_no_gui_code_imported(self) -> None:
        """The app layer works headless and never pulls in BSplineCAM.gui."""
        sf.make_surface(wavy_net(), doc=self.doc)
        importers.export(self.doc.Objects, str(self.tmp / "net.json"))
        self.assertFalse(FreeCAD.GuiUp)
        self.assertEqual([m for m in sys.modules if m.startswith("BSplineCAM.gui")], [])

    def test_crosscheck_stored_without_touching(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc)
        report = sf.run_crosscheck(obj, backends=("freecad",), paper_route=False, samples=41)
        self.assertTrue(report["exact_route_ok"])
        stored = json.loads(obj.CrossCheck)
        self.assertEqual(stored["max_deviation_mm"], report["max_deviation_mm"])
        self.assertNotIn("Touched", obj.State)
        self.assertEqual(obj.getEditorMode("CrossCheck"), ["ReadOnly"])
        self.assertEqual(obj.getEditorMode("Version"), ["ReadOnly"])


class TestPersistence(BSplineCAMTestCase):
    def test_save_close_reopen_identical(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc, name="Design")
        sf.set_control_point(obj, 4, 4, (44.0, 44.0, 30.0))
        obj.MakeSolid = True
        obj.BaseOffset = 7.5
        self.assertSuccessfulRecompute(obj)
        expected = sf.surface_of(obj)
        points = [tuple(v) for v in obj.ControlPoints]
        obj = self.reopen(obj)
        self.assertIsNotNone(obj)
        self.assertIsInstance(obj.Proxy, sf.SurfaceFeature)
        self.assertEqual([tuple(v) for v in obj.ControlPoints], points)  # bit-identical
        self.assertEqual((obj.Rows, obj.Columns, obj.Knots), (10, 10, "clamped"))
        self.assertTrue(obj.MakeSolid)
        self.assertAlmostEqual(float(obj.BaseOffset), 7.5)
        self.assertEqual(obj.Version, sf.OBJECT_VERSION)
        self.assertEqual(obj.Shape.ShapeType, "Solid")
        self.assertMatchesCore(obj, expected)  # the shape as restored from the file
        obj.touch()
        self.assertSuccessfulRecompute(obj)
        self.assertMatchesCore(obj, expected)  # and as rebuilt after the reload
        obj.Knots = "uniform"
        self.assertSuccessfulRecompute(obj)
        self.assertMatchesCore(obj, Surface(expected.control_points, "uniform"))

    def test_file_holds_no_pickled_state(self) -> None:
        sf.make_surface(wavy_net(), doc=self.doc)
        path = self.tmp / "plain.FCStd"
        self.doc.saveAs(str(path))
        with zipfile.ZipFile(path) as archive:
            xml = archive.read("Document.xml").decode("utf-8")
        values = re.findall(r'<Python value="([^"]*)" encoded="yes"', xml)
        self.assertTrue(values, "no Python proxy stored")
        for value in values:
            self.assertIn(base64.b64decode(value).decode("utf-8").strip(), ("null", "None"))
        self.assertIn('module="BSplineCAM.app.surface_feature"', xml)

    def test_restore_adds_missing_properties(self) -> None:
        """A document from an older version (properties missing) is upgraded on load."""
        obj = sf.make_surface(wavy_net(), doc=self.doc)
        obj.removeProperty("CrossCheck")
        obj.removeProperty("BaseOffset")
        self.assertFalse(hasattr(obj, "BaseOffset"))
        obj = self.reopen(obj)
        self.assertTrue(hasattr(obj, "CrossCheck"))
        self.assertAlmostEqual(float(obj.BaseOffset), 5.0)
        self.assertEqual(obj.getEditorMode("CrossCheck"), ["ReadOnly"])
        self.assertSuccessfulRecompute(obj)
        self.assertMatchesCore(obj)


class TestImportExport(BSplineCAMTestCase):
    def write(self, name: str, text: str) -> str:
        path = self.tmp / name
        path.write_text(text, encoding="utf-8")
        return str(path)

    def bad_files(self) -> list[str]:
        return [
            self.write("ragged.json", json.dumps({"control_points": [[[0, 0, 0]] * 4] * 3
                                                  + [[[0, 0, 0]] * 3]})),
            self.write("notjson.json", "{ this is not json"),
            self.write("text.csv", "row,col,x,y,z\n0,0,a,b,c\n"),
            self.write("short.dat", "0 0 0\n1 1 1\n"),
            self.write("words.dat", "# rows=4\n" + "1 2 x\n" * 16),
            self.write("unknown.xyz2", "1 2 3\n"),
            str(self.tmp / "missing.json"),
        ]

    def test_registered_with_freecad(self) -> None:
        """Init.py registers the handlers (when the addon is installed in a Mod folder)."""
        registered = set()
        for module in (FreeCAD.getImportType() or {}).values():
            registered.update(module if isinstance(module, list) else [module])
        if "BSplineCAM.app.importers" not in registered:
            self.skipTest("addon not installed in FreeCAD's Mod folder")
        self.assertIn("BSplineCAM.app.importers", FreeCAD.getImportType("json"))
        self.assertIn("BSplineCAM.app.importers", FreeCAD.getExportType("dat"))
        # and the old CAM module names (documents of 0.20 open in 1.0 and 1.1)
        self.assertTrue(any(type(f).__name__ == "_LegacyCamFinder" for f in sys.meta_path))

    def test_insert_good_files(self) -> None:
        surface = Surface(wavy_net(), "clamped", "wavy")
        for suffix in (".json", ".csv"):
            path = self.tmp / f"net{suffix}"
            importers.write_surface(surface, path)
            obj = importers.insert(str(path), self.doc.Name)
            self.assertIsNotNone(obj)
            expected = surface if suffix == ".json" else Surface(surface.control_points, "uniform")
            self.assertMatchesCore(obj, expected)

    def test_bad_files_leave_document_unchanged(self) -> None:
        sf.make_surface(wavy_net(), doc=self.doc)
        self.doc.recompute()
        before = [(o.Name, o.Label) for o in self.doc.Objects]
        documents = sorted(FreeCAD.listDocuments())
        for path in self.bad_files():
            with self.subTest(path=Path(path).name):
                self.assertIsNone(importers.insert(path, self.doc.Name))
                self.assertIsNone(importers.open(path))
                self.assertEqual([(o.Name, o.Label) for o in self.doc.Objects], before)
                self.assertEqual(sorted(FreeCAD.listDocuments()), documents)
                self.assertTrue(all(o.isValid() for o in self.doc.Objects))

    def test_open_makes_a_document(self) -> None:
        before = set(FreeCAD.listDocuments())
        obj = importers.open(str(CASE_STUDY))
        self.extra_docs = set(FreeCAD.listDocuments()) - before
        self.assertEqual(len(self.extra_docs), 1)
        self.assertMatchesCore(obj, Surface.from_json(CASE_STUDY))

    def test_export_json_csv_dat(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc)
        surface = Surface.from_json(CASE_STUDY)
        for suffix in (".json", ".csv"):
            path = self.tmp / f"out{suffix}"
            self.assertTrue(importers.export([obj], str(path)))
            np.testing.assert_array_equal(netio.read_net(path).points, surface.control_points)
        path = self.tmp / "out.dat"
        self.assertTrue(importers.export([obj], str(path)))
        grid = netio.read_dat(path)
        self.assertEqual(grid.shape, (importers.DAT_POINTS, importers.DAT_POINTS, 3))
        np.testing.assert_allclose(grid, surface.grid(*grid.shape[:2]), atol=1e-9)
        self.assertFalse(importers.export([], str(self.tmp / "none.json")))
        self.assertFalse(importers.export([obj], str(self.tmp / "out.obj")))
        self.assertFalse((self.tmp / "out.obj").exists())

    def test_paper_route_deviation(self) -> None:
        obj = sf.make_surface(str(CASE_STUDY), doc=self.doc)
        path = self.tmp / "points.dat"
        importers.export([obj], str(path))
        route = importers.import_paper_route(str(path), design=obj)
        deviation = json.loads(route.Deviation)
        self.assertAlmostEqual(deviation["max_deviation_mm"], float(route.MaxDeviation), places=9)
        self.assertGreater(float(route.MaxDeviation), 1e-4)  # but not the surface between
        self.assertLess(float(route.MaxDeviation), 1.0)
        self.assertEqual(list(route.Grid), [importers.DAT_POINTS, importers.DAT_POINTS])
        count = len(self.doc.Objects)
        with self.assertRaises(NetError):
            importers.import_paper_route(self.bad_files()[3], design=obj)
        self.assertEqual(len(self.doc.Objects), count)


if __name__ == "__main__":
    unittest.main(argv=[sys.argv[0], *os.environ.get("TEST_ARGS", "").split()])
