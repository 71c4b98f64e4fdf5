# SPDX-License-Identifier: LGPL-2.1-or-later
"""Exact transfer into FreeCAD's OCCT, run inside FreeCAD (``freecadcmd``), 0.20 and 1.0.

unittest classes, so FreeCAD's own interpreter runs them without pytest.
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM import Surface  # noqa: E402
from BSplineCAM.app import part  # noqa: E402
from BSplineCAM.app.compat import ensure_freecad  # noqa: E402

FreeCAD = ensure_freecad()
import Part  # noqa: E402

CASE_STUDY = ROOT / "examples" / "case-study.json"


def wavy_net(seed: int, rows: int = 7, cols: int = 9) -> np.ndarray:
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 60, rows), np.linspace(0, 40, cols), indexing="ij")
    z = 5 * np.sin(x / 9) * np.cos(y / 7) + rng.normal(scale=1.0, size=x.shape)
    return np.stack([x, y, z], axis=-1)


def gauss_grid(surface: Surface, order: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes and weights per patch over [0, 1] (exact for the polynomial pieces)."""
    nodes, weights = np.polynomial.legendre.leggauss(order)
    spans = surface.patches[0]
    t = np.concatenate([(j + (nodes + 1) / 2) / spans for j in range(spans)])
    return t, np.tile(weights / 2 / spans, spans)


class TestExactTransfer(unittest.TestCase):
    def assert_same_surface(self, occt, surface: Surface, samples: int = 41):
        t = np.linspace(0, 1, samples)
        u, w = (a.ravel() for a in np.meshgrid(t, t, indexing="ij"))
        ours = surface.evaluate(u, w)
        theirs = np.array([tuple(occt.value(float(a), float(b))) for a, b in zip(u, w)])
        deviation = np.abs(ours - theirs).max()
        self.assertLessEqual(deviation, 1e-9 * surface.size(), f"max deviation {deviation} mm")

    def test_part_surface_equals_matrix_form(self):
        for layout in ("uniform", "clamped"):
            for seed in (1, 2):
                surface = Surface(wavy_net(seed), layout)
                occt = part.to_part_surface(surface)
                self.assertEqual((occt.NbUPoles, occt.NbVPoles), surface.shape)
                self.assertEqual(occt.bounds(), (0.0, 1.0, 0.0, 1.0))
                self.assert_same_surface(occt, surface)

    def test_poles_knots_multiplicities(self):
        surface = Surface.from_json(CASE_STUDY)
        occt = part.to_part_surface(surface)
        k = surface.occt_knots()
        self.assertEqual(occt.getUKnots(), k["u_knots"].tolist())
        self.assertEqual(occt.getVMultiplicities(), k["w_mults"].tolist())
        poles = np.array([[tuple(p) for p in row] for row in occt.getPoles()])
        np.testing.assert_array_equal(poles, surface.control_points)

    def test_derivatives_and_normals_match_occt(self):
        surface = Surface(wavy_net(5), "clamped")
        occt = part.to_part_surface(surface)
        rng = np.random.default_rng(7)
        for a, b in rng.random((30, 2)):
            np.testing.assert_allclose(surface.normals(a, b), np.array(tuple(occt.normal(a, b))), atol=1e-9)
            for du, dw in ((1, 0), (0, 1), (2, 0), (1, 1), (0, 2)):
                occt_d = np.array(tuple(occt.getDN(a, b, du, dw)))
                np.testing.assert_allclose(surface.evaluate(a, b, du, dw), occt_d, atol=1e-9 * max(1, np.abs(occt_d).max()))

    def test_step_and_brep_round_trip(self):
        surface = Surface.from_json(CASE_STUDY)
        with tempfile.TemporaryDirectory() as tmp:
            for suffix in ("step", "brep"):
                path = Path(tmp) / f"s.{suffix}"
                part.export_shape(part.to_face(surface), path)
                shape = Part.read(str(path))
                self.assertEqual(len(shape.Faces), 1)
                self.assert_same_surface(shape.Faces[0].Surface, surface, 21)
            self.assertEqual(sorted(p.name for p in Path(tmp).iterdir()), ["s.brep", "s.step"])

    def test_solid_is_closed_and_its_volume_is_the_integral(self):
        surface = Surface.from_json(CASE_STUDY)
        base = 10.0
        solid = part.to_solid(surface, base_z=base)
        self.assertTrue(solid.isValid())
        self.assertTrue(solid.Shells[0].isClosed())
        t, wt = gauss_grid(surface)
        p = surface.evaluate_grid(t, t)
        xu, xw = surface.evaluate_grid(t, t, 1, 0), surface.evaluate_grid(t, t, 0, 1)
        jacobian = np.abs(xu[..., 0] * xw[..., 1] - xu[..., 1] * xw[..., 0])
        volume = wt @ ((p[..., 2] - base) * jacobian) @ wt
        # Shape.Volume uses OCCT's default (coarse) Gauss integration, good to about 1e-4
        self.assertAlmostEqual(solid.Volume / volume, 1.0, delta=5e-4)
        self.assertAlmostEqual(min(v.Z for v in solid.Vertexes), base, places=9)
        self.assertEqual(len(solid.Faces), 6)

    def test_paper_route_is_measurably_worse_than_exact(self):
        surface = Surface.from_json(CASE_STUDY)
        loft = part.paper_route(surface.grid(21, 21))
        result = part.deviation_between(loft, surface, samples=21, reverse_samples=5)
        exact = part.deviation_between(part.to_face(surface), surface, samples=11, reverse_samples=5)
        self.assertLess(exact["max_deviation_mm"], 1e-6)
        self.assertGreater(result["max_deviation_mm"], 100 * exact["max_deviation_mm"])
        self.assertLess(result["max_deviation_mm"], 2.0)


class TestSurfaceCommand(unittest.TestCase):
    def test_surface_command_writes_every_file(self):
        with tempfile.TemporaryDirectory() as tmp:
            proc = subprocess.run(
                [str(ROOT / "bin" / "bsplinecam"), "surface", str(CASE_STUDY), "--out", tmp, "--samples", "41"],
                capture_output=True, text=True, check=False,
            )
            self.assertEqual(proc.returncode, 0, proc.stderr)
            names = sorted(p.name for p in Path(tmp).iterdir())
            self.assertEqual(names, sorted(["case-study.dat", "case-study.step", "case-study.brep", "case-study.FCStd", "crosscheck.json"]))
            report = json.loads((Path(tmp) / "crosscheck.json").read_text())
            self.assertTrue(report["exact_route_ok"])
            for key in ("cox_de_boor", "freecad_occt", "cadquery_occt"):
                self.assertLessEqual(report["max_deviation_mm"][key], 1e-9 * report["size_mm"])
            self.assertGreater(report["paper_route"]["max_deviation_mm"], 1e-4)
            doc = FreeCAD.openDocument(str(Path(tmp) / "case-study.FCStd"))
            try:
                obj = doc.Objects[0]
                self.assertEqual(obj.Proxy.surface(obj).shape, (10, 10))
                self.assertTrue(obj.Shape.isValid())
            finally:
                FreeCAD.closeDocument(doc.Name)

    def test_check_command_on_bad_file_is_one_clear_line(self):
        with tempfile.TemporaryDirectory() as tmp:
            bad = Path(tmp) / "bad.json"
            bad.write_text('{"control_points": [[[0, 0, 0]]]}')
            proc = subprocess.run([str(ROOT / "bin" / "bsplinecam"), "check", str(bad)], capture_output=True, text=True, check=False)
            self.assertEqual(proc.returncode, 2)
            self.assertIn("bad.json", proc.stderr)
            self.assertNotIn("Traceback", proc.stderr)


if __name__ == "__main__":
    unittest.main()
