# SPDX-License-Identifier: LGPL-2.1-or-later
"""Parts from STEP, BREP and FCStd on the command line (issue 11, item 5).

``bsplinecam check PART`` on the README's example part (examples/part.step) and on a part with
sphere, torus and cylinder faces made here by cadquery; the bad inputs (exit 2, one stderr line
naming the file and the face, nothing written in --out); ``--faces`` parsing and the refusals
of toolpath and verify in-process.  The faces FreeCAD extracts are measured against cadquery's
own reading of the same STEP (OCCT's projection onto the original surfaces), and the check's
verdict is shown to fail on a perturbed evaluation.

The real ``bin/bsplinecam`` (freecadcmd) is skipped when absent unless BSPLINECAM_REQUIRE_ALL=1;
the parts are made by cadquery in the project venv (skipped when it is absent, same rule).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pytest
from conftest import CASE_STUDY, ROOT, run_main

from BSplineCAM.app import runtime
from BSplineCAM.core.geometry.faces import Face, FaceError, sample_points, to_dict
from BSplineCAM.core.geometry.nurbs import NurbsSurface
from BSplineCAM.orchestration import cli_toolpath, parts

EXAMPLE = ROOT / "examples" / "part.step"
BIN = ROOT / "bin" / "bsplinecam"
VENV_PYTHON = ROOT / ".venv" / "bin" / "python"
REQUIRE_ALL = os.environ.get("BSPLINECAM_REQUIRE_ALL") == "1"


def have_freecadcmd() -> bool:
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()[0]
    return shutil.which(cmd) is not None


def have_cadquery() -> bool:
    return VENV_PYTHON.exists()


needs_freecad = pytest.mark.skipif(not have_freecadcmd() and not REQUIRE_ALL,
                                   reason="freecadcmd is not installed")
needs_cadquery = pytest.mark.skipif(not have_cadquery() and not REQUIRE_ALL,
                                    reason="the project venv (cadquery) is not installed")


def run_bin(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN), *args], capture_output=True, text=True, timeout=900,
                          cwd=ROOT, check=False)


def cadquery(code: str, *args: str) -> str:
    """Run ``code`` in the venv's Python (cadquery); its stdout."""
    proc = subprocess.run([str(VENV_PYTHON), "-c", code, *args], capture_output=True,
                          text=True, timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def assert_refused(proc: subprocess.CompletedProcess, *fragments: str) -> None:
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert lines[0].startswith("bsplinecam "), lines[0]
    for fragment in fragments:
        assert fragment in lines[0], lines[0]
    assert proc.stdout == ""


# -- --faces parsing (in-process) ------------------------------------------------------------
@pytest.mark.parametrize("text, expected", [
    (None, "up"), ("up", "up"), (" UP ", "up"), ("3", [3]), ("3,8,20", [3, 8, 20]),
    ("Face3, face8", [3, 8]), ("8,3,8", [8, 3]), ("face 12", [12]),
])
def test_parse_faces(text, expected):
    assert parts.parse_faces(text) == expected


def test_parse_faces_all_only_for_check():
    assert parts.parse_faces("all", allow_all=True) == "all"
    assert parts.parse_faces(None, allow_all=True, default="all") == "all"
    with pytest.raises(FaceError, match="--faces all: only 'check'"):
        parts.parse_faces("all")


@pytest.mark.parametrize("text, message", [
    ("", "the face selection is empty"), (",", "the face selection is empty"),
    (" , ", "the face selection is empty"), ("x3", "'x3' is not a face number"),
    ("3.5", "'3.5' is not a face number"), ("-1", "'-1' is not a face number"),
    ("0", "face 0: faces are numbered from 1"), ("3,,8", "an empty item"),
    ("3,", "an empty item"),
    ("Face", "'Face' is not a face number"),
])
def test_parse_faces_refused(text, message):
    with pytest.raises(FaceError, match="--faces") as info:
        parts.parse_faces(text)
    assert message in str(info.value)


def test_is_part():
    for name in ("a.step", "a.STP", "b.brep", "c.brp", "d.FCStd", "e.fcstd"):
        assert parts.is_part(name)
    for name in ("net.json", "net.csv", "net.dat", "a.iges", "step"):
        assert not parts.is_part(name)


def test_worker_passes_part_requests_on():
    from BSplineCAM.orchestration import worker

    assert worker.PART_REQUESTS == parts.REQUESTS
    with pytest.raises(ValueError, match="not available for backend 'cadquery'"):
        worker.handle({"op": "part_faces", "backend": "cadquery"})


# -- refusals before any FreeCAD work (in-process) ---------------------------------------------
@pytest.mark.parametrize("argv, fragments", [
    (["check", str(CASE_STUDY), "--faces", "up"], ["--faces applies to parts", "case-study"]),
    (["check", str(CASE_STUDY), "--out", "OUT"], ["--out applies to parts"]),
    (["check", str(EXAMPLE), "--knots", "clamped"], ["--knots applies to control nets"]),
    (["check", str(EXAMPLE), "--faces", ","], ["--faces", "empty"]),
    (["check", str(EXAMPLE), "--samples", "1"], ["--samples"]),
    (["toolpath", str(CASE_STUDY), "--faces", "up", "--tool-diameter", "6", "--scallop",
      "0.01", "--out", "OUT"], ["--faces applies to parts"]),
    (["toolpath", str(EXAMPLE), "--faces", "3,x", "--tool-diameter", "6", "--scallop", "0.01",
      "--out", "OUT"], ["--faces", "'x'"]),
    (["toolpath", str(EXAMPLE), "--faces", "all", "--tool-diameter", "6", "--scallop", "0.01",
      "--out", "OUT"], ["--faces all"]),
    (["toolpath", str(EXAMPLE), "--strategy", "steep_shallow", "--direction", "oneway",
      "--tool-diameter", "6", "--scallop", "0.01", "--out", "OUT"],
     ["--direction oneway", "zigzag"]),
    (["toolpath", str(EXAMPLE), "--strategy", "isoparametric", "--direction", "oneway",
      "--tool-diameter", "6", "--scallop", "0.01", "--out", "OUT"],
     ["--direction oneway", "zigzag"]),
    (["verify", str(CASE_STUDY), "p.ngc", "--faces", "up", "--tool-diameter", "6", "--out",
      "OUT"], ["--faces applies to parts"]),
    (["verify", str(EXAMPLE), "p.ngc", "--faces", "", "--tool-diameter", "6", "--out", "OUT"],
     ["--faces", "empty"]),
])
def test_refused_in_process(capsys, tmp_path, argv, fragments):
    out = tmp_path / "out"
    argv = [str(out) if a == "OUT" else a for a in argv]
    status, stdout, err = run_main(capsys, *argv)
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1, err
    for fragment in fragments:
        assert fragment in err, err
    assert stdout == ""
    assert not out.exists()


def test_toolpath_part_refused_without_faces_raster(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(cli_toolpath, "faces_raster_available", lambda: False)
    out = tmp_path / "out"
    status, stdout, err = run_main(capsys, "toolpath", str(EXAMPLE), "--faces", "1",
                                   "--tool-diameter", "6", "--scallop", "0.01", "--out",
                                   str(out))
    assert status == 2, err
    assert len(err.strip().splitlines()) == 1
    assert "part.step: toolpaths on parts need the multi-face raster" in err
    assert stdout == "" and not out.exists()


# -- the verdict can fail (in-process, fake OCCT answers) ----------------------------------------
def _plane_face() -> Face:
    x, y = np.meshgrid([0.0, 40.0], [0.0, 30.0], indexing="ij")
    poles = np.stack([x, y, 0.1 * x + 2.0], axis=-1)
    surface = NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name="Face1")
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    return Face(surface, outer, index=1, source="Plane")


@pytest.mark.parametrize("error, ok, machinable", [
    (0.0, True, True), (2e-8, True, True), (1e-7, False, True), (3e-5, False, False)])
def test_check_verdict(monkeypatch, error, ok, machinable):
    """Closed form: the plane z = 0.1 x + 2 over 40 x 30 mm; the fake FreeCAD answers it exactly
    plus ``error`` mm in z, the fake cadquery exactly; the size is the box diagonal."""
    face = _plane_face()
    uv = sample_points(face, 5)
    exact = np.column_stack([40 * uv[:, 0], 30 * uv[:, 1], 4 * uv[:, 0] + 2.0])
    size = float(np.linalg.norm([40.0, 30.0, 4.0]))
    noisy = exact + np.array([0.0, 0.0, error])
    fc = {"freecad": "x", "face_count": 1, "faces": [{
        "face": to_dict(face), "size_mm": size, "uv": uv.tolist(),
        "freecad_points": noisy.tolist()}]}
    monkeypatch.setattr(runtime, "freecad_in_process", lambda: False)
    monkeypatch.setattr(runtime, "cadquery_in_process", lambda: False)
    monkeypatch.setattr(parts, "_freecad_worker", lambda request: fc)
    monkeypatch.setattr(runtime, "run_worker", lambda backend, request: {
        "points": [exact.tolist()], "version": "y"})
    report = parts.check_part("fake.step", None, 5)
    assert report["ok"] is ok
    assert report["over_strict_limit"] == ([] if ok else ["Face1"])
    assert report["acceptance_limit_mm"] == pytest.approx(2e-5)  # 1 % of 0.002 mm
    (record,) = report["faces"]
    assert record["machinable"] is machinable
    assert record["cox_de_boor_max_mm"] < 1e-12
    assert record["freecad_max_mm"] == pytest.approx(error, abs=1e-12)
    assert record["cadquery_max_mm"] < 1e-12
    assert record["relative_max"] == pytest.approx(error / size, abs=1e-15)
    assert (record["source"], record["degree_u"], record["poles"], record["rational"],
            record["holes"]) == ("Plane", 1, [2, 2], False, 0)


def test_check_reports_a_face_that_cannot_be_built(monkeypatch):
    """A face whose conversion fails is reported with its error beside the others' figures; the
    verdict names it."""
    face = _plane_face()
    uv = sample_points(face, 5)
    exact = np.column_stack([40 * uv[:, 0], 30 * uv[:, 1], 4 * uv[:, 0] + 2.0])
    fc = {"freecad": "x", "face_count": 2, "faces": [
        {"face": to_dict(face), "size_mm": 50.0, "uv": uv.tolist(),
         "freecad_points": exact.tolist()},
        {"index": 2, "error": "Face2 (Torus): OCCT's NURBS conversion failed (x)"}]}
    monkeypatch.setattr(runtime, "cadquery_in_process", lambda: False)
    monkeypatch.setattr(parts, "_freecad_worker", lambda request: fc)
    monkeypatch.setattr(runtime, "run_worker", lambda backend, request: {
        "points": [exact.tolist()], "version": "y"})
    report = parts.check_part("fake.step", None, 5)
    assert [r["ok"] for r in report["faces"]] == [True, False]
    assert report["faces"][1]["error"].startswith("Face2 (Torus)")
    assert report["over_strict_limit"] == ["Face2"] and report["ok"] is False


# -- the real command line -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def example_check(tmp_path_factory):
    if not have_freecadcmd() and not REQUIRE_ALL:
        pytest.skip("freecadcmd is not installed")
    out = tmp_path_factory.mktemp("check") / "out"
    proc = run_bin("check", str(EXAMPLE), "--out", str(out))
    return proc, out


@pytest.mark.venv_only
@needs_freecad
def test_check_example_part(example_check):
    proc, out = example_check
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert json.loads((out / "check.json").read_text()) == report
    assert sorted(p.name for p in out.iterdir()) == ["check.json"]
    assert report["ok"] is True and report["faces_selection"] == "all"
    faces = report["faces"]
    assert [f["index"] for f in faces] == list(range(1, report["face_count"] + 1))
    for face in faces:
        assert face["ok"] and face["points"] >= 100
        for key in ("conversion_deviation_mm", "freecad_max_mm", "cadquery_max_mm"):
            assert 0 <= face[key] <= 1e-9 * face["size_mm"], (face["name"], key, face[key])
    # examples/make_part.py: the B-spline top (bicubic, 5 x 5 poles) with the through hole,
    # two fillets (rational B-splines), the hole's cylinder, walls and bottom (planes).
    top = faces[0]
    assert (top["source"], top["degree_u"], top["degree_v"], top["poles"], top["rational"],
            top["holes"]) == ("BSplineSurface", 3, 3, [5, 5], False, 1)
    kinds = sorted(f["source"] for f in faces)
    assert kinds.count("Plane") == 5 and kinds.count("Cylinder") == 1
    fillets = [f for f in faces[1:] if f["source"] == "BSplineSurface"]
    assert len(fillets) == 2 and all(f["rational"] for f in fillets)
    assert sum(f["holes"] for f in faces) == 2  # top and bottom


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_fillets_meeting_at_corners(tmp_path):
    """Four fillets meet at the top's corners: OCCT leaves their parameter curves apart by up
    to the vertex tolerance (~0.01 mm); both OCCTs' readers join them and every face passes."""
    step = tmp_path / "corners.step"
    subprocess.run([str(ROOT / ".venv" / "bin" / "python"), str(ROOT / "examples" / "make_part.py"),
                    str(step), "--all-edges"], check=True, capture_output=True, timeout=300)
    proc = run_bin("check", str(step), "--faces", "up")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    fillets = [f for f in report["faces"] if f["source"] == "BSplineSurface" and f["rational"]]
    assert len(fillets) >= 4 and report["ok"]
    theirs = json.loads(cadquery(
        "import json, sys\n"
        "sys.path.insert(0, sys.argv[2])\n"
        "from BSplineCAM.ocp import faces as F\n"
        "fs = F.faces_from_shape(F.read_part(sys.argv[1]), 'up')\n"
        "print(json.dumps([[f.index, len(f.holes)] for f in fs if f.selected]))",
        str(step), str(ROOT)))
    assert [[f["index"], f["holes"]] for f in report["faces"]] == theirs


BLENDED_BLOCK = """
import sys, cadquery as cq
top = [(60, 22), (45, 26), (30, 21), (15, 24), (0, 20)]
profile = cq.Workplane("XZ").moveTo(0, 0).lineTo(60, 0).lineTo(60, 22).spline(
    top[1:], includeCurrent=True).close()
block = profile.extrude(-40).edges("|Z").fillet(4)
spline_top = [f for f in block.faces().vals() if f.geomType() not in ("PLANE", "CYLINDER")]
solid = block.val().fillet(3, [e for f in spline_top for e in f.Edges()])
cq.exporters.export(cq.Workplane().add(solid), sys.argv[1])
"""


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_corner_blends_of_a_filleted_block_are_machined_from_above(tmp_path):
    """A block with a spline top, its vertical edges rounded (4 mm) and then the top's edges (3
    mm): OCCT's corner blends are rational B-splines of degree 2 x 9 to 13, tangent to the
    rounded walls, whose normal points down by up to ~1e-5 at their foot (the model's tolerance
    there is ~1e-5 mm).  They count as "up", the raster finishes them without gouging
    (<= 1 um over the whole model) and the scallop stays within h + tolerance inside the
    borders; the degree-14 rolling-ball fillet evaluates within 1e-12 of its size against
    Cox-de Boor."""
    step = tmp_path / "blended.step"
    cadquery(BLENDED_BLOCK, str(step))
    proc = run_bin("check", str(step))
    assert proc.returncode == 0, proc.stderr
    faces = json.loads(proc.stdout)["faces"]
    blends = [f["index"] for f in faces if f["source"] == "BSplineSurface" and f["size_mm"] < 10]
    assert len(blends) == 4
    (high,) = [f for f in faces if max(f["degree_u"], f["degree_v"]) == 14]
    assert high["rational"] and high["cox_de_boor_max_mm"] <= 1e-12 * high["size_mm"]
    assert all(f["machinable"] for f in faces)
    out = tmp_path / "out"
    proc = run_bin("toolpath", str(step), "--faces", "up", "--tool-diameter", "6",
                   "--scallop", "0.05", "--tolerance", "0.01", "--out", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert set(blends) <= set(report["faces"])
    proc = run_bin("verify", str(step), str(out / "blended.ngc"), "--faces", "up",
                   "--tool-diameter", "6", "--out", str(tmp_path / "verify"))
    assert proc.returncode == 0, proc.stderr
    verified = json.loads((tmp_path / "verify" / "verify.json").read_text())
    assert verified["gouge_max_mm"] <= 0.001
    assert verified["scallop_max_mm"] <= 0.05 + 0.01
    assert all(verified["face_cells"][f"Face{i}"] > 0 for i in blends)


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_check_example_matches_cadquery(example_check):
    """Face count, surface kinds and holes as cadquery reads the same STEP."""
    proc, _ = example_check
    report = json.loads(proc.stdout)
    names = {"PLANE": "Plane", "CYLINDER": "Cylinder", "BSPLINE": "BSplineSurface"}
    theirs = json.loads(cadquery(
        "import json, sys, cadquery as cq\n"
        "s = cq.importers.importStep(sys.argv[1]).val()\n"
        "print(json.dumps([[f.geomType(), len(f.innerWires())] for f in s.Faces()]))",
        str(EXAMPLE)))
    assert len(theirs) == report["face_count"]
    assert [[names[k], h] for k, h in theirs] == [[f["source"], f["holes"]]
                                                  for f in report["faces"]]


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_check_up_selection():
    """``--faces up`` picks exactly the faces whose outward normal (cadquery, at the face's
    centre) points up: the top and the two fillets."""
    proc = run_bin("check", str(EXAMPLE), "--faces", "up")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    nz = json.loads(cadquery(
        "import json, sys, cadquery as cq\n"
        "s = cq.importers.importStep(sys.argv[1]).val()\n"
        "print(json.dumps([f.normalAt(f.Center()).z for f in s.Faces()]))", str(EXAMPLE)))
    expected = [i for i, z in enumerate(nz, 1) if z > 0.1]
    assert [f["index"] for f in report["faces"]] == expected
    assert len(expected) == 3 and report["ok"]


ANALYTIC = """
import sys, cadquery as cq
box = cq.Workplane().box(60, 40, 10, centered=(False, False, False))
sphere = cq.Workplane().add(cq.Solid.makeSphere(8, cq.Vector(15, 20, 10)))
torus = cq.Workplane().add(cq.Solid.makeTorus(8, 3, cq.Vector(42, 20, 10)))
hole = cq.Workplane().add(cq.Solid.makeCylinder(3, 30, cq.Vector(42, 20, -5)))
part = box.union(sphere).union(torus).cut(hole)
assert part.val().isValid()
cq.exporters.export(part, sys.argv[1])
"""


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_check_analytic_faces(tmp_path):
    """A block with a spherical cap, a half torus and a through hole: every face converted by
    OCCT to NURBS (rational for the sphere, torus and cylinder) within 1e-9 of its size."""
    step = tmp_path / "analytic.step"
    cadquery(ANALYTIC, str(step))
    proc = run_bin("check", str(step))
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["ok"] is True
    by_kind = {}
    for face in report["faces"]:
        by_kind.setdefault(face["source"], []).append(face)
        for key in ("conversion_deviation_mm", "freecad_max_mm", "cadquery_max_mm"):
            assert 0 <= face[key] <= 1e-9 * face["size_mm"], (face["name"], key, face[key])
    assert sorted(by_kind) == ["Cylinder", "Plane", "Sphere", "Toroid"]
    for kind in ("Cylinder", "Sphere", "Toroid"):
        (face,) = by_kind[kind]
        assert face["rational"] is True
        assert face["degree_u"] == 2  # circles as rational quadratics (OCCT's conversion)
    assert all(not f["rational"] and f["degree_u"] == 1 for f in by_kind["Plane"])


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_load_faces_against_cadquery(tmp_path):
    """parts.load_faces (FreeCAD's extraction, through the worker when FreeCAD is not in this
    process) against cadquery's own reading of the STEP: the core NURBS's points lie on the
    original surfaces (OCCT's projection, GeomAPI_ProjectPointOnSurf) within 1e-9 of the size,
    and 'up' marks the top and fillets selected."""
    faces = parts.load_faces(EXAMPLE, "up")
    assert [f.index for f in faces if f.selected] == [1, 3, 4]
    points = []
    for face in faces:
        uv = sample_points(face, 7)
        points.append(np.asarray(face.surface.evaluate(uv[:, 0], uv[:, 1])).tolist())
    probe = tmp_path / "points.json"
    probe.write_text(json.dumps(points))
    distances = json.loads(cadquery(
        "import json, sys, cadquery as cq\n"
        "from OCP.BRep import BRep_Tool\n"
        "from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf\n"
        "from OCP.gp import gp_Pnt\n"
        "s = cq.importers.importStep(sys.argv[1]).val()\n"
        "pts = json.load(open(sys.argv[2]))\n"
        "out = []\n"
        "for f, ps in zip(s.Faces(), pts):\n"
        "    g = BRep_Tool.Surface_s(f.wrapped)\n"
        "    d = [GeomAPI_ProjectPointOnSurf(gp_Pnt(*p), g).LowerDistance() for p in ps]\n"
        "    out.append([max(d), f.BoundingBox().DiagonalLength])\n"
        "print(json.dumps(out))", str(EXAMPLE), str(probe)))
    assert len(distances) == len(faces)
    for face, (dist, size) in zip(faces, distances):
        assert dist <= 1e-9 * size, (face.name, dist)


# -- bad input on the real command line ------------------------------------------------------------
@pytest.mark.venv_only
@needs_freecad
@pytest.mark.parametrize("faces, fragments", [
    ("20", ["part.step: face 20 of 9: no such face"]),
    ("3,20", ["part.step: face 20 of 9"]),
    (",", ["--faces", "empty"]),
    ("2", ["part.step: Face2 is not reachable from above", "vertical"]),
    ("1,6", ["part.step: Face6 is not reachable from above"]),
])
def test_check_bad_selection(tmp_path, faces, fragments):
    out = tmp_path / "out"
    proc = run_bin("check", str(EXAMPLE), "--faces", faces, "--out", str(out))
    assert_refused(proc, *fragments)
    assert not out.exists()


BAD_PARTS = """
import sys, cadquery as cq
folder = sys.argv[1]
cq.exporters.export(cq.Workplane().add(cq.Face.makePlane(10, 10)), folder + "/face.step")
cq.Workplane().box(10, 10, 10).val().exportBrep(folder + "/box.brep")
"""


@pytest.mark.venv_only
@needs_freecad
@needs_cadquery
def test_check_bad_files(tmp_path):
    cadquery(BAD_PARTS, str(tmp_path))
    (tmp_path / "garbage.step").write_text("ISO-10303-21;\nthis is not STEP\n")
    # The box's first vertex moved 2 mm off its edges: BRepCheck finds the solid invalid.
    lines = (tmp_path / "box.brep").read_text().splitlines()
    at = lines.index("Ve") + 2
    lines[at] = " ".join(str(float(v) + 2.0) for v in lines[at].split())
    (tmp_path / "broken.brep").write_text("\n".join(lines) + "\n")
    cases = [("face.step", "holds no solid"), ("garbage.step", "cannot read the part"),
             ("broken.brep", "broken geometry"), ("missing.step", "no such file")]
    for name, fragment in cases:
        out = tmp_path / f"out-{name}"
        proc = run_bin("check", str(tmp_path / name), "--out", str(out))
        assert_refused(proc, f"{tmp_path / name}: {fragment}")
        # readable: no exception dicts of FreeCAD 0.20, no "No error" from BRepCheck
        assert "sclassname" not in proc.stderr and "No error" not in proc.stderr
        assert not out.exists()


FCSTD = """
import FreeCAD, Part
doc = FreeCAD.newDocument("Parts")
shape = Part.Shape()
shape.read({step!r})
part = doc.addObject("Part::Feature", "Part")
part.Shape = shape
hidden = doc.addObject("Part::Box", "Hidden")  # not visible: not part of the model
hidden.Visibility = False
doc.recompute()
doc.saveAs({out!r})
"""


@pytest.mark.venv_only
@needs_freecad
def test_check_fcstd_and_brep(tmp_path):
    """The example as a FreeCAD document (its visible solid only) and a cadquery box as BREP."""
    fcstd = tmp_path / "part.FCStd"
    script = tmp_path / "make.py"
    script.write_text(FCSTD.format(step=str(EXAMPLE), out=str(fcstd)))
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()
    subprocess.run([*cmd, str(script)], capture_output=True, timeout=300, check=False)
    assert fcstd.is_file()
    proc = run_bin("check", str(fcstd), "--faces", "up")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["face_count"] == 9 and report["ok"]
    assert [f["index"] for f in report["faces"]] == [1, 3, 4]
    if not have_cadquery():
        return
    cadquery(BAD_PARTS, str(tmp_path))
    proc = run_bin("check", str(tmp_path / "box.brep"), "--faces", "up")
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    assert report["face_count"] == 6 and report["ok"]
    (top,) = report["faces"]  # the box's top, the only face reached from above
    assert top["source"] == "Plane" and top["poles"] == [2, 2] and top["holes"] == 0


POST = """
import json, sys
sys.path.insert(0, {root!r})
from pathlib import Path
import numpy as np
from BSplineCAM.app import cam
from BSplineCAM.core.toolpath.common import Toolpath, ToolpathStats
from BSplineCAM.orchestration.parts import post_toolpath
passes = [np.array([[5.0, y, 20.0], [40.0, y, 21.0], [75.0, y, 22.0]]) for y in (10.0, 20.0)]
toolpath = Toolpath("raster", passes, {{}}, [], ToolpathStats()).finish(0.0, None)
posted = post_toolpath({step!r}, toolpath, 6.0, cam.Cutting(900.0, 300.0, 10000.0),
                      "linuxcnc", Path({ngc!r}), Path({doc!r}))
Path({ngc!r} + ".json").write_text(json.dumps(posted))
"""


@pytest.mark.venv_only
@needs_freecad
def test_post_toolpath_of_a_part(tmp_path):
    """A two-pass toolpath posted from a job whose model is the example part: the program's
    feed moves are the passes' points, the rapid approach stops at the safe height above the
    job's stock (the part's exact top 29.824 mm, not OCCT's box of its poles at 41.6 mm, + 1 mm
    of stock + CAM's SafeHeightOffset of 3 mm), the feeds and spindle are those given, and
    LinuxCNC's rs274 accepts it."""
    from BSplineCAM.core.program import rs274
    from BSplineCAM.core.program.gcode import MoveKind, read_gcode

    ngc, doc = tmp_path / "part.ngc", tmp_path / "part-job.FCStd"
    script = tmp_path / "post.py"
    script.write_text(POST.format(root=str(ROOT), step=str(EXAMPLE), ngc=str(ngc), doc=str(doc)))
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()
    proc = subprocess.run([*cmd, str(script)], capture_output=True, text=True, timeout=300,
                          check=False)
    assert ngc.is_file() and doc.is_file(), proc.stdout[-2000:] + proc.stderr[-2000:]
    text = ngc.read_text()
    assert "S10000" in text.replace(" ", "")
    program = read_gcode(text, "part.ngc")
    feeds = program.end[program.kind == MoveKind.LINE]
    expected = [[5, 10, 20], [40, 10, 21], [75, 10, 22], [5, 20, 20], [40, 20, 21], [75, 20, 22]]
    # each pass: a plunge feed from the safe height to its start, then its points
    starts = [k for k in range(len(feeds)) if np.allclose(feeds[k], expected[0])
              or np.allclose(feeds[k], expected[3])]
    assert len(starts) == 2
    got = np.concatenate([feeds[starts[0]:starts[0] + 3], feeds[starts[1]:starts[1] + 3]])
    assert np.allclose(got, expected, atol=1e-4)
    rapids = program.end[program.kind == MoveKind.RAPID]
    assert rapids[:, 2].min() == pytest.approx(29.8237 + 1.0 + 3.0, abs=1e-3)
    assert set(np.round(program.feed[program.kind == MoveKind.LINE], 6)) == {900.0, 300.0}
    if rs274.available():
        assert rs274.check(ngc, {1: 6.0}).ok


#: A 30 x 20 mm block whose top is one trimmed B-spline face (bsplinecam_freecad), as STEP.
BLOCK = """
import sys
sys.path[:0] = [{root!r}, {tests!r}]
from bsplinecam_freecad import bspline_block
bspline_block().exportStep({step!r})
"""


@pytest.mark.venv_only
@needs_freecad
@pytest.mark.parametrize("strategy", ["isoparametric"])
def test_toolpath_part_strategy(tmp_path, strategy):
    """``toolpath PART --strategy isoparametric`` on a block with a B-spline top: the program
    passes rs274 and, simulated from its text, never cuts below the exact faces (FaceSet.height
    of every face of the part) by more than 1 um, and leaves the scallop inside the top."""
    from BSplineCAM.core.program import rs274
    from BSplineCAM.core.program.gcode import MoveKind, read_gcode
    from BSplineCAM.core.simulation.simulate import Grid, Tool, simulate_program
    from BSplineCAM.core.toolpath.faceset import FaceSet

    step = tmp_path / "block.step"
    script = tmp_path / "block.py"
    script.write_text(BLOCK.format(root=str(ROOT), tests=str(ROOT / "tests"), step=str(step)))
    cmd = os.environ.get("BSPLINECAM_FREECADCMD", "freecadcmd").split()
    subprocess.run([*cmd, str(script)], capture_output=True, text=True, timeout=300,
                   check=False)
    assert step.is_file()
    out = tmp_path / "out"
    tool, scallop, tolerance = 6.0, 0.05, 0.01
    proc = run_bin("toolpath", str(step), "--strategy", strategy, "--tool-diameter",
                   str(tool), "--scallop", str(scallop), "--tolerance", str(tolerance),
                   "--out", str(out))
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = json.loads(proc.stdout)
    assert report["strategy"] == strategy and report["passes"] > 5
    assert report["parameters"]["strategy"] == strategy
    ngc = out / "block.ngc"
    if rs274.available():
        assert rs274.check(ngc, {1: tool}).ok
    elif REQUIRE_ALL:
        pytest.fail("rs274 (linuxcnc-uspace) is required here (BSPLINECAM_REQUIRE_ALL=1)")
    program = read_gcode(ngc.read_text(), "block.ngc")
    grid = Grid.covering(-4.0, 34.0, -4.0, 24.0, 0.1)
    top = report["clearance_height_mm"] - 0.5
    sim = simulate_program(program, Tool(tool), grid, top, 1e-5)
    faces = FaceSet(parts.load_faces(step, "up"))
    x, y = np.meshgrid(*grid.centres())
    z = faces.height(np.column_stack([x.ravel(), y.ravel()]))[0].reshape(sim.height.shape)
    on = np.isfinite(z)
    assert on.sum() > 0.3 * on.size
    assert float(np.max(z[on] - sim.height[on])) <= 1e-3
    # the program may meet the raw stock (the job's block, 1 mm above the part): no rapid
    # ends below its top; the plunge feed takes the tool down to each pass
    rapids = program.end[program.kind == MoveKind.RAPID]
    assert float(rapids[:, 2].min()) >= float(z[on].max()) + 1.0 - 1e-6
    r = tool / 2
    inner = on & (x > r) & (x < 30 - r) & (y > r) & (y < 20 - r)
    assert float(np.max(sim.height[inner] - z[inner])) <= scallop + tolerance + 1e-3


def test_conversion_distances_are_reported():
    """Every face's distance from OCCT is in the report; one above 1e-9 of its size (50 mm here)
    also gets a note naming it, the distance and the rule it passed."""
    from dataclasses import replace

    close, far = replace(_plane_face(), deviation=1e-11), replace(
        _plane_face(), index=2, name="Face2", deviation=1.02e-7)
    distances, notes = parts.conversion_report([close, far], 0.002)
    assert distances == {"Face1": 1e-11, "Face2": 1.02e-7}
    (note,) = notes
    assert note.startswith("Face2 (Plane): its NURBS is 1.02e-07 mm from OCCT's original")
    assert "within the 2e-05 mm accepted (1% of the chordal tolerance 0.002 mm)" in note
