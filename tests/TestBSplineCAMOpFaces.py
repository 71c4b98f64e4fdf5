# SPDX-License-Identifier: LGPL-2.1-or-later
"""The finishing op on faces of any object (issue 11, item 5), run by freecadcmd.

Parts are made here with Part (small, so the certified drop-cutter takes seconds): a 30 x 20 x
10 mm box whose long top edge at y = 0 is rounded by a 4 mm fillet (a cylinder, converted to a
rational NURBS), a 30 x 20 mm block whose top is a B-spline face, and a half cylinder (radius
10 mm, 20 mm long) for waterline passes.  Every program is posted by FreeCAD's linuxcnc post,
checked by LinuxCNC's ``rs274`` and simulated from its text on a Z-map; the reference is the
exact part: the closed forms of the fillet box and the half cylinder, and ``FaceSet.height`` (a
point probe, not the generator's drop-cutter) over ALL faces of the part.  User errors print
one console line and no traceback; a document saved and reopened recomputes the same path.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import sys
import tempfile
import unittest
from pathlib import Path
from unittest import mock

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from BSplineCAM.app import cam, compat, finishing_op, pipeline  # noqa: E402
from BSplineCAM.app import faces as app_faces  # noqa: E402
from BSplineCAM.core import toolpath as core_toolpath  # noqa: E402
from BSplineCAM.core.program import rs274  # noqa: E402
from BSplineCAM.core.program.gcode import MoveKind, read_gcode  # noqa: E402
from BSplineCAM.core.simulation.measures import program_measures  # noqa: E402
from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate_program  # noqa: E402
from BSplineCAM.core.toolpath.common import ToolpathCancelled  # noqa: E402
from BSplineCAM.core.toolpath.faceset import FaceSet  # noqa: E402
from BSplineCAM.orchestration.cli import flush_all  # noqa: E402

FreeCAD = compat.ensure_freecad()
import Part  # noqa: E402
from bsplinecam_freecad import bspline_block, rs274_or_skip  # noqa: E402

V = FreeCAD.Vector
TOOL = 6.0
SCALLOP = 0.05
TOLERANCE = 0.01
FILLET = 4.0
#: Largest accepted gouge (mm): 1 um.
GOUGE = 1e-3
#: Z-map cell (mm) and the chords of arcs in the simulation (mm, far below the gouge bound).
CELL = 0.1
CHORD = 1e-5
#: Lowest y (mm) of the fillet a ball centred at y >= 0 touches: 4 - 4 * 4 / (4 + 3).
REACHED = FILLET - FILLET * FILLET / (FILLET + TOOL / 2)
#: Posted coordinates carry 4 decimals.
ROUNDING = 1e-4


def fillet_box() -> Part.Shape:
    """30 x 20 x 10 mm box, its top edge along x at y = 0 rounded by a 4 mm fillet."""
    box = Part.makeBox(30, 20, 10)
    edge = next(e for e in box.Edges if e.BoundBox.ZMin > 10 - 1e-9 and e.BoundBox.YMax < 1e-9)
    return box.makeFillet(FILLET, [edge])


def fillet_height(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The fillet box's top (closed form): 10 for y >= 4, the fillet's arc below, NaN off it."""
    y = np.asarray(y, dtype=float)
    r = np.clip(FILLET - y, 0.0, FILLET)
    z = np.where(y >= FILLET, 10.0, 10.0 - FILLET + np.sqrt(FILLET ** 2 - r ** 2))
    inside = (x >= 0) & (x <= 30) & (y >= 0) & (y <= 20)
    return np.where(inside, z, np.nan)


@contextlib.contextmanager
def console_text(out: list):
    """What is written on descriptors 1 and 2 (FreeCAD's console, the tracebacks a failed
    recompute prints) while the block runs, appended to ``out`` as one string."""
    flush_all()
    saved = (os.dup(1), os.dup(2))
    with tempfile.TemporaryFile() as log:
        os.dup2(log.fileno(), 1)
        os.dup2(log.fileno(), 2)
        try:
            yield
        finally:
            flush_all()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            log.seek(0)
            out.append(log.read().decode("utf-8", "replace"))


def face_number(shape: Part.Shape, test) -> int:
    """1-based number of the first face of ``shape`` for which ``test(face)`` holds."""
    return next(i for i, f in enumerate(shape.Faces, 1) if test(f))


def centre_normal(face: Part.Face):
    u0, u1, v0, v1 = face.ParameterRange
    return face.normalAt(0.5 * (u0 + u1), 0.5 * (v0 + v1))


def all_faces(shape: Part.Shape) -> FaceSet:
    """Every face of the part (walls and bottom included), none selected: the reference."""
    faces = app_faces.faces_from_shape(shape, "up")
    return FaceSet(faces)


class PartJob(unittest.TestCase):
    """A document with a Part object, a job on it and the op; each class posts its program."""

    shape_maker = staticmethod(fillet_box)
    base: list | None = None  # face names for Base; None: the default ("up")
    strategy = "raster"

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument(cls.__name__)
        cls.part = cls.doc.addObject("Part::Feature", "Part")
        cls.part.Shape = cls.shape_maker()
        cls.doc.recompute()
        params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=SCALLOP,
                                              tolerance=TOLERANCE, strategy=cls.strategy)
        cls.job, cls.op = pipeline.build_faces_job(cls.part, params, faces=cls.base)
        cls.doc.recompute()
        cls.model = cls.job.Model.Group[0]
        cls.tmp = tempfile.TemporaryDirectory()
        cls.path = Path(cls.tmp.name) / "faces.ngc"
        report = json.loads(cls.op.Report or "{}")
        cls.text = cam.post_process(cls.job, "linuxcnc", cls.path) if "error" not in report else ""

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)
        cls.tmp.cleanup()

    def report(self) -> dict:
        return json.loads(self.op.Report or "{}")

    def assert_rs274(self):
        rs274_or_skip(self)
        check = rs274.check(self.path, {1: TOOL})
        self.assertTrue(check.ok, check.message)
        self.assertGreater(check.feeds + check.arcs, 2)

    def simulate(self, margin: float = 4.0):
        """The posted program's text cut on a Z-map over the part (plus ``margin`` mm)."""
        program = read_gcode(self.text)
        box = self.part.Shape.BoundBox
        grid = Grid.covering(box.XMin - margin, box.XMax + margin, box.YMin - margin,
                             box.YMax + margin, CELL)
        top = self.job.Stock.Shape.BoundBox.ZMax
        return program, simulate_program(program, Tool(TOOL), grid, top, CHORD)

    def gouge(self, sim) -> float:
        """Largest depth (mm) of the simulated cut below the part's top (FaceSet.height of
        every face), over the cells above the part."""
        x, y = np.meshgrid(*sim.grid.centres())
        xy = np.column_stack([np.ravel(x), np.ravel(y)])
        z = all_faces(self.part.Shape).height(xy)[0].reshape(sim.height.shape)
        above = np.isfinite(z)
        self.assertGreater(above.sum(), 0.3 * above.size)
        return float(np.max(z[above] - sim.height[above]))


class TestFilletFace(PartJob):
    """Base = the fillet alone: the top plane beside it is a check surface."""

    base = ["FILLET"]  # replaced by the fillet's face name in setUpClass

    @classmethod
    def setUpClass(cls):
        shape = fillet_box()
        cls.fillet = face_number(shape, lambda f: isinstance(f.Surface, Part.Cylinder))
        cls.top = face_number(shape, lambda f: isinstance(f.Surface, Part.Plane)
                              and centre_normal(f).z > 0.5)
        cls.bottom = face_number(shape, lambda f: centre_normal(f).z < -0.5)
        cls.base = [f"Face{cls.fillet}"]
        super().setUpClass()

    def test_report_names_the_fillet_and_heights_follow_it(self):
        report = self.report()
        self.assertNotIn("error", report)
        self.assertEqual(report["faces"], [f"{self.model.Label}.Face{self.fillet}"])
        self.assertEqual(report["strategy"], "raster")
        self.assertGreater(report["passes"], 2)
        # the fillet runs from z = 6 (y = 0) to z = 10 (y = 4): exact, not OCCT's pole box
        self.assertAlmostEqual(self.op.OpFinalDepth.Value, 10.0 - FILLET, delta=1e-4)
        self.assertGreaterEqual(self.op.OpStartDepth.Value, 10.0 - 1e-4)
        self.assertGreater(self.op.SafeHeight.Value, self.job.Stock.Shape.BoundBox.ZMax - 1e-9)
        self.assertGreater(self.op.ClearanceHeight.Value, self.op.SafeHeight.Value)

    def test_report_gives_the_machine_figures(self):
        """Rapid, air and link length and the machining time with acceleration, from the op's
        moves at its tool controller's feeds: as the posted program measures them."""
        report = self.report()
        for key in ("rapid_length_mm", "air_length_mm", "link_length_mm", "machining_time_s",
                    "machining_time_with_acceleration_s"):
            self.assertIn(key, report)
        self.assertGreaterEqual(report["air_length_mm"], report["rapid_length_mm"] - 1e-6)
        self.assertGreater(report["machining_time_with_acceleration_s"],
                           report["machining_time_s"])
        posted = program_measures(read_gcode(self.text))
        self.assertAlmostEqual(report["machining_time_with_acceleration_s"],
                               posted["machining_time_with_acceleration_s"],
                               delta=0.1 * posted["machining_time_with_acceleration_s"])

    def test_program_passes_rs274(self):
        self.assert_rs274()

    def test_never_below_the_part_and_only_on_the_fillet(self):
        program, sim = self.simulate()
        self.assertLessEqual(self.gouge(sim), GOUGE)
        # the closed form agrees with FaceSet.height (two references, one answer)
        x, y = np.meshgrid(*sim.grid.centres())
        exact = fillet_height(np.ravel(x), np.ravel(y)).reshape(sim.height.shape)
        on = np.isfinite(exact)
        self.assertLessEqual(float(np.max(exact[on] - sim.height[on])), GOUGE)
        # cutting moves: the ball's contact lies on the fillet, i.e. its centre has y <= 4
        # (beyond, it would rest on the top plane) and y >= -R (touching the fillet's lower,
        # vertical edge with its equator)
        feeds = np.flatnonzero(program.kind != MoveKind.RAPID)
        low = feeds[np.minimum(program.start[feeds, 2], program.end[feeds, 2]) < 10.0 + 1e-6]
        self.assertGreater(len(low), 3)
        ends = np.concatenate([program.start[low], program.end[low]])
        self.assertLessEqual(float(ends[:, 1].max()), FILLET + ROUNDING)
        self.assertGreaterEqual(float(ends[:, 1].min()), -TOOL / 2 - ROUNDING)
        # the top plane is not cut (the stock above it is the check surface's business)
        far = (y > FILLET + TOOL / 2 + CELL) & on
        self.assertGreaterEqual(float(sim.height[far].min()), 10.0 - GOUGE)
        # the fillet is machined where a ball centred over it (0 <= y <= 4) touches it: from
        # y = 4 - 4 * 4 / 7 (the contact of a centre at y = 0) up, within scallop + tolerance
        mid = on & (y > REACHED + 0.3) & (y < FILLET - 0.3) & (x > 1.0) & (x < 29.0)
        excess = sim.height[mid] - exact[mid]
        self.assertLessEqual(float(excess.max()), SCALLOP + TOLERANCE + 1e-3)

    def test_steep_part_of_the_fillet_is_machined(self):
        """Below y = REACHED the fillet is steeper than 35 degrees: the ball touches it only
        from centres at y < 0, outside the selected faces' box, where the face raster
        (core.toolpath.faces_raster) reaches as far as the steep border's contacts need."""
        _program, sim = self.simulate()
        x, y = np.meshgrid(*sim.grid.centres())
        exact = fillet_height(x, y)
        low = np.isfinite(exact) & (y > 0.3) & (y < REACHED) & (x > 1.0) & (x < 29.0)
        excess = sim.height[low] - exact[low]
        self.assertLessEqual(float(excess.max()), SCALLOP + TOLERANCE + 1e-3)

    def test_original_object_in_base_means_the_job_model(self):
        """Base may name the part itself (the job machines its clone): the same faces."""
        faces = finishing_op.job_faces(self.op_with_base([(self.part, [f"Face{self.fillet}"])]),
                                       self.job)
        selected = [f.name for f in faces if f.selected]
        self.assertEqual(selected, [f"{self.model.Label}.Face{self.fillet}"])
        # the walls and bottom no ball reaches first are left out; the top plane stays
        names = {f.name for f in faces}
        self.assertIn(f"{self.model.Label}.Face{self.top}", names)
        self.assertNotIn(f"{self.model.Label}.Face{self.bottom}", names)

    def op_with_base(self, base):
        return mock.Mock(Base=base, Label="op")

    def assert_bad_base(self, base, *words):
        """Base ``base``: the error in the report names ``words``; the previous Path stays;
        with Base restored, the document recomputes to the same program."""
        before = [c.toGCode() for c in self.op.Path.Commands]
        good = self.op.Base
        self.op.Base = base
        try:
            self.doc.recompute()
            error = json.loads(self.op.Report or "{}").get("error", "")
            for word in words:
                self.assertIn(word, error)
            self.assertEqual([c.toGCode() for c in self.op.Path.Commands], before)
        finally:
            self.op.Base = good
            self.doc.recompute()
        self.assertNotIn("error", self.report())
        self.assertEqual([c.toGCode() for c in self.op.Path.Commands], before)
        self.assertTrue(self.job.isValid())
        self.assertTrue(all(o.isValid() for o in self.doc.Objects), "an object is left in error")

    def test_bad_base_not_a_face(self):
        self.assert_bad_base([(self.model, ["Edge1"])], "Edge1", "not a face", self.op.Label)

    def test_bad_base_face_seen_from_below(self):
        self.assert_bad_base([(self.model, [f"Face{self.bottom}"])], f"Face{self.bottom}",
                             "not reachable from above")

    def test_bad_base_empty_selection(self):
        """The object picked without a face (stored as ("",)): CAM's onChanged clears such an
        entry at once (its sanitizeBase), so the op is asked directly here."""
        with self.assertRaises(ValueError) as caught:
            finishing_op.job_faces(self.op_with_base([(self.model, ("",))]), self.job)
        self.assertIn("selection is empty", str(caught.exception))
        self.assertIn(self.model.Label, str(caught.exception))

    def test_other_directions_are_named(self):
        """Every strategy runs on faces, steep_shallow too, but its raster only zigzag: a
        oneway one is refused by name and the previous path is kept."""
        before = [c.toGCode() for c in self.op.Path.Commands]
        self.op.Strategy = "steep_shallow"
        self.op.Direction = "oneway"
        try:
            self.doc.recompute()
            error = self.report().get("error", "")
            self.assertIn("Direction 'oneway' is not available on faces with steep_shallow",
                          error)
            self.assertIn("zigzag", error)
            self.assertEqual([c.toGCode() for c in self.op.Path.Commands], before)
        finally:
            self.op.Strategy = "raster"
            self.op.Direction = "zigzag"
            self.doc.recompute()
        self.assertNotIn("error", self.report())

    def test_cancel_keeps_the_previous_path(self):
        before = [c.toGCode() for c in self.op.Path.Commands]
        seen = []

        def cancel(fraction):
            seen.append(fraction)
            if fraction > 0.3:
                raise ToolpathCancelled("cancelled by the test")

        with mock.patch.object(finishing_op, "progress_reporter", lambda obj: cancel):
            self.op.touch()
            self.doc.recompute()
        self.assertTrue(seen and max(seen) > 0.3)
        self.assertEqual([c.toGCode() for c in self.op.Path.Commands], before)


class TestNoFaceFromAbove(unittest.TestCase):
    """A model with no face a 3-axis tool reaches (a lone face looking down): the default
    "up" selection is empty, the report says so and nothing else changes."""

    def test_error_in_the_report(self):
        doc = FreeCAD.newDocument("TestNoFaceFromAbove")
        try:
            part = doc.addObject("Part::Feature", "Ceiling")
            face = Part.makePlane(30, 20, V(0, 0, 5), V(0, 0, -1))
            part.Shape = face
            doc.recompute()
            params = pipeline.FinishingParameters(tool_diameter=TOOL, scallop=SCALLOP)
            job, op = pipeline.build_faces_job(part, params)
            doc.recompute()
            error = json.loads(op.Report or "{}").get("error", "")
            self.assertIn("no face", error)
            self.assertIn("reachable from above", error)
            self.assertEqual(len(op.Path.Commands), 0)
            self.assertTrue(job.isValid())
            self.assertTrue(part.isValid())
        finally:
            FreeCAD.closeDocument(doc.Name)


class UserErrorsAndReopen:
    """Mixed into a PartJob: the console on user errors and bugs; save, reopen, recompute."""

    def test_user_error_prints_one_line_and_no_traceback(self):
        """A bad Base is the op's own error, one line on the console; the path is kept."""
        before = [c.toGCode() for c in self.op.Path.Commands]
        out: list = []
        self.op.Base = [(self.model, ["Edge1"])]
        try:
            with console_text(out):
                self.doc.recompute()
            error = self.report().get("error", "")
        finally:
            self.op.Base = []
            self.doc.recompute()
        self.assertIn("Edge1 is not a face", error)
        self.assertNotIn("Traceback", out[0])
        lines = [line for line in out[0].splitlines() if "Edge1" in line]
        self.assertEqual(len(lines), 1, out[0])
        self.assertIn(f"{self.op.Label}: Base {self.model.Label}.Edge1 is not a face", lines[0])
        self.assertEqual(lines[0].count(self.op.Label), 1)
        self.assertEqual([c.toGCode() for c in self.op.Path.Commands], before)
        self.assertNotIn("error", self.report())

    def test_bugs_still_raise_with_their_traceback(self):
        """Only user errors (BSplineCAMError) are reported in one line: a bug in the code
        (here a TypeError) still fails the recompute, traceback and all."""
        out: list = []

        def broken(*_args, **_kwargs):
            raise TypeError("a bug planted by the test")

        with mock.patch.object(core_toolpath, "generate_faces", broken):
            self.op.touch()
            with console_text(out):
                self.doc.recompute()
            self.assertFalse(self.op.isValid())
        self.op.touch()
        self.doc.recompute()
        self.assertTrue(self.op.isValid())
        self.assertIn("a bug planted by the test", out[0])
        self.assertIn("Traceback", out[0])

    def test_saved_and_reopened_document_recomputes_the_same_path(self):
        """The document saved, reopened (the op's proxy restored from its class alone) and
        its op recomputed from an empty path: the same program, command for command."""
        before = [c.toGCode() for c in self.op.Path.Commands]
        self.assertGreater(len(before), 20)
        saved = Path(self.tmp.name) / "saved.FCStd"
        self.doc.saveCopy(str(saved))
        doc = FreeCAD.openDocument(str(saved))
        try:
            op = doc.getObject(self.op.Name)
            self.assertEqual([c.toGCode() for c in op.Path.Commands], before)
            op.Path = freecad_path().Path()
            op.touch()
            doc.recompute()
            self.assertNotIn("error", json.loads(op.Report or "{}"))
            self.assertTrue(op.isValid())
            self.assertEqual([c.toGCode() for c in op.Path.Commands], before)
        finally:
            FreeCAD.closeDocument(doc.Name)


class TestDefaultUpFaces(UserErrorsAndReopen, PartJob):
    """Base empty on a model that is no BSplineCAM surface: every upward face."""

    shape_maker = staticmethod(bspline_block)
    base = None

    def test_up_selection_is_the_top(self):
        report = self.report()
        self.assertNotIn("error", report)
        shape = self.model.Shape
        # OCCT's own normals: the faces facing up (here the B-spline top alone)
        up = [i for i, f in enumerate(shape.Faces, 1) if centre_normal(f).z > 1e-6]
        self.assertEqual(report["faces"], [f"{self.model.Label}.Face{i}" for i in up])
        self.assertEqual(len(up), 1)
        self.assertIsInstance(shape.Faces[up[0] - 1].Surface, Part.BSplineSurface)
        self.assertEqual(list(self.op.Base), [])

    def test_program_passes_rs274_and_never_gouges(self):
        self.assert_rs274()
        _program, sim = self.simulate()
        self.assertLessEqual(self.gouge(sim), GOUGE)

    def test_heights_from_the_exact_top(self):
        top = self.model.Shape.Faces[0]
        if not isinstance(top.Surface, Part.BSplineSurface):
            top = next(f for f in self.model.Shape.Faces if isinstance(f.Surface, Part.BSplineSurface))
        u0, u1, v0, v1 = top.ParameterRange
        zs = [top.valueAt(u, v).z for u in np.linspace(u0, u1, 121)
              for v in np.linspace(v0, v1, 121) if top.isPartOfDomain(u, v)]
        self.assertAlmostEqual(self.op.OpFinalDepth.Value, min(zs), delta=2e-3)
        self.assertLessEqual(self.op.OpFinalDepth.Value, min(zs) + 1e-9)
        self.assertGreaterEqual(self.op.OpStartDepth.Value, max(zs) - 1e-9)


class TestBSplineTopIso(PartJob):
    """Iso-parametric passes on the block's trimmed B-spline top (Base empty: the one face
    facing up; the walls and bottom are no check surface a ball reaches first)."""

    shape_maker = staticmethod(bspline_block)
    strategy = "isoparametric"

    def test_report(self):
        report = self.report()
        self.assertNotIn("error", report)
        self.assertEqual(report["strategy"], "isoparametric")
        self.assertEqual(len(report["faces"]), 1)
        self.assertGreater(report["passes"], 5)

    def test_program_passes_rs274(self):
        self.assert_rs274()

    def test_never_below_the_part_and_within_the_scallop(self):
        _program, sim = self.simulate()
        self.assertLessEqual(self.gouge(sim), GOUGE)
        # away from the block's edges (one tool radius), the top is finished to the scallop
        x, y = np.meshgrid(*sim.grid.centres())
        xy = np.column_stack([np.ravel(x), np.ravel(y)])
        z = all_faces(self.part.Shape).height(xy)[0].reshape(sim.height.shape)
        r = TOOL / 2
        inner = np.isfinite(z) & (x > r) & (x < 30 - r) & (y > r) & (y < 20 - r)
        self.assertGreater(inner.sum(), 10000)
        excess = sim.height[inner] - z[inner]
        self.assertLessEqual(float(excess.max()), SCALLOP + TOLERANCE + 1e-3)


class TestFilletBoxWaterline(PartJob):
    """Waterline on the fillet box's faces seen from above (top and fillet): the op says in
    its report, and the report view, what share of them is too flat for it."""

    strategy = "waterline"

    def test_report_says_the_share_too_flat_for_waterline(self):
        report = self.report()
        self.assertNotIn("error", report)
        self.assertGreater(report["passes"], 1)
        # closed form: the top beside the fillet (30 x 16 mm) and the fillet's first 30
        # degrees of its quarter circle (30 x 4 pi / 6), of the top and the whole fillet
        flat = 30 * 16 + 30 * FILLET * math.pi / 6
        share = 100 * flat / (30 * 16 + 30 * FILLET * math.pi / 2)
        said = [n for n in report["notes"] if "flatter than 30 degrees" in n]
        self.assertTrue(said and said[0].startswith(f"{share:.0f} %"), (report["notes"], share))

    def test_program_passes_rs274(self):
        self.assert_rs274()


def freecad_path():
    """FreeCAD's Path module (the tests' ``Path`` is pathlib's)."""
    import Path as freecad_path

    return freecad_path


@unittest.skipUnless(FreeCAD.GuiUp, "needs the GUI (tools/run_gui_test.sh TestBSplineCAMOpFaces)")
class TestFacesFromTheView(unittest.TestCase):
    """The job command with faces picked in the 3D view; the panel's face list."""

    @classmethod
    def setUpClass(cls):
        import FreeCADGui
        from PySide import QtGui

        FreeCADGui.activateWorkbench("BSplineCAMWorkbench")
        for _ in range(5):
            QtGui.QApplication.processEvents()

    def setUp(self):
        import FreeCADGui

        self.gui = FreeCADGui
        self.doc = FreeCAD.newDocument("TestFacesFromTheView")
        self.part = self.doc.addObject("Part::Feature", "Part")
        self.part.Shape = fillet_box()
        self.doc.recompute()
        self.fillet = face_number(self.part.Shape, lambda f: isinstance(f.Surface, Part.Cylinder))
        self.top = face_number(self.part.Shape, lambda f: isinstance(f.Surface, Part.Plane)
                               and centre_normal(f).z > 0.5)

    def tearDown(self):
        if self.gui.Control.activeDialog():
            self.gui.Control.closeDialog()
        self.gui.Selection.clearSelection()
        FreeCAD.closeDocument(self.doc.Name)

    def test_job_on_selected_faces(self):
        from BSplineCAM.gui import cam_commands

        self.gui.Selection.clearSelection()
        self.assertFalse(self.gui.Command.get("BSplineCAM_Job").isActive())
        self.gui.Selection.addSelection(self.part, f"Face{self.fillet}")
        self.assertTrue(self.gui.Command.get("BSplineCAM_Job").isActive())
        cam_commands.JobPanel.last = None
        self.gui.runCommand("BSplineCAM_Job")
        panel = cam_commands.JobPanel.last
        self.assertIsNotNone(panel)
        self.assertEqual(panel.face_list.count(), 1)
        # the list takes more faces from the view and lets them go again
        self.gui.Selection.clearSelection()
        self.gui.Selection.addSelection(self.part, f"Face{self.top}")
        panel.add_selected_faces()
        self.assertEqual(panel.face_list.count(), 2)
        panel.face_list.item(1).setSelected(True)
        panel.remove_faces()
        self.assertEqual([panel.face_list.item(i).text() for i in range(panel.face_list.count())],
                         [f"{self.part.Label}.Face{self.fillet}"])
        panel.tool.setValue(TOOL)
        panel.scallop.setValue(SCALLOP)
        panel.tolerance.setValue(TOLERANCE)
        undo = self.doc.UndoCount
        with mock.patch.object(cam_commands, "show_info"), \
                mock.patch.object(cam_commands, "report_error") as error:
            accepted = panel.accept()
        if not accepted:
            self.fail(f"the job panel refused: {panel.message.text()} {error.call_args_list}")
        self.assertFalse(self.gui.Control.activeDialog())
        self.assertEqual(self.doc.UndoCount, undo + 1)  # one transaction
        op = panel.op
        self.assertEqual([(o.Name, tuple(s)) for o, s in op.Base],
                         [(self.part.Name, (f"Face{self.fillet}",))])
        report = json.loads(op.Report)
        model = panel.job.Model.Group[0]
        self.assertEqual(report["faces"], [f"{model.Label}.Face{self.fillet}"])
        self.assertGreater(len(op.Path.Commands), 5)


if __name__ == "__main__":
    unittest.main()
