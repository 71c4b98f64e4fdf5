# SPDX-License-Identifier: LGPL-2.1-or-later
"""Core faces (BSplineCAM.core.geometry.faces): the trim test, plain data, validation, densification;
and the extraction in cadquery's OCCT (BSplineCAM.ocp.faces) against OCCT itself.

References: matplotlib's point-in-polygon (``Path.contains_points``), the sagitta of a circle's
chord, and OCP's own classifier, projection and normals.
"""

from __future__ import annotations

import json
import math
import os
import re

import numpy as np
import pytest

from BSplineCAM.core.geometry import face_import
from BSplineCAM.core.geometry import faces as cf
from BSplineCAM.core.geometry.faces import Face, FaceError
from BSplineCAM.core.geometry.nurbs import NurbsSurface

# --------------------------------------------------------------------------- helpers


def star(rng, centre, r_min, r_max, k=23):
    """A random star-shaped polygon (never self-crossing), closed (first point repeated)."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, k))
    radii = rng.uniform(r_min, r_max, k)
    pts = np.column_stack([centre[0] + radii * np.cos(angles), centre[1] + radii * np.sin(angles)])
    return np.vstack([pts, pts[:1]])


def plane_surface(size=10.0, name="face"):
    """S(u, v) = (size u, size v, 0) over [0, 1]²: a degree-1 NURBS with 2 x 2 poles."""
    poles = np.array([[[0, 0, 0], [0, size, 0]], [[size, 0, 0], [size, size, 0]]], dtype=float)
    return NurbsSurface(poles, [0, 0, 1, 1], [0, 0, 1, 1], 1, 1, name=name)


def wavy_surface(rng):
    """Degree (3, 2), non-uniform knots with a double knot, rational."""
    n, m = 6, 5
    x, y = np.meshgrid(np.linspace(0, 50, n), np.linspace(0, 30, m), indexing="ij")
    z = rng.normal(scale=2.0, size=x.shape)
    poles = np.stack([x, y, z], axis=-1)
    weights = rng.uniform(0.5, 2.0, size=(n, m))
    ku = [0, 0, 0, 0, 0.3, 0.7, 1, 1, 1, 1]
    kv = [0, 0, 0, 0.5, 0.5, 1, 1, 1]
    return NurbsSurface(poles, ku, kv, 3, 2, weights=weights, name="wavy")


def square(u0, v0, u1, v1):
    return np.array([[u0, v0], [u1, v0], [u1, v1], [u0, v1], [u0, v0]], dtype=float)


def far_from(loops, pts, margin):
    keep = np.ones(len(pts), dtype=bool)
    for loop in loops:
        a, b = loop[:-1], loop[1:]
        d = b - a
        t = np.clip(((pts[:, None] - a) * d).sum(-1) / (d * d).sum(-1), 0, 1)
        dist = np.linalg.norm(pts[:, None] - (a + t[..., None] * d), axis=-1).min(1)
        keep &= dist > margin
    return keep


# --------------------------------------------------------------------------- inside()


@pytest.mark.parametrize("seed", range(6))
def test_inside_matches_matplotlib_even_odd(seed):
    mpath = pytest.importorskip("matplotlib.path")
    rng = np.random.default_rng(seed)
    outer = star(rng, (0.5, 0.5), 0.3, 0.5)
    holes = (star(rng, (0.45, 0.5), 0.05, 0.12, 9), star(rng, (0.55, 0.62), 0.02, 0.06, 7))
    # The holes may overlap each other: even-odd is the rule on both sides either way.
    face = Face(plane_surface(), outer, holes)
    pts = rng.uniform(-0.1, 1.1, size=(4000, 2))
    pts = pts[far_from(face.loops, pts, 1e-6)]
    expected = np.zeros(len(pts), dtype=bool)
    for loop in face.loops:
        expected ^= mpath.Path(loop).contains_points(pts)
    got = cf.inside(face, pts[:, 0], pts[:, 1])
    assert np.array_equal(got, expected)
    assert 0 < np.count_nonzero(got) < len(pts)


def test_inside_broadcasts_and_keeps_shape():
    face = Face(plane_surface(), square(0, 0, 1, 1), (square(0.4, 0.4, 0.6, 0.6),))
    u, v = np.meshgrid([0.1, 0.5, 1.5], [0.1, 0.5], indexing="ij")
    got = cf.inside(face, u, v)
    assert got.shape == (3, 2)
    assert got.tolist() == [[True, True], [True, False], [False, False]]
    assert cf.inside(face, 0.2, 0.2).shape == ()


# --------------------------------------------------------------------------- plain data


def test_dict_round_trip_through_json(rng):
    surface = wavy_surface(rng)
    face = Face(surface, square(0.05, 0.1, 0.95, 0.9), (star(rng, (0.5, 0.5), 0.1, 0.2),),
                index=3, selected=False, flipped_v=True, source="Cylinder", deviation=1e-13,
                tolerance=0.002)
    back = cf.face_from_dict(json.loads(json.dumps(cf.to_dict(face))))
    assert (back.index, back.name, back.selected, back.flipped_v, back.source) == (
        3, "Face3", False, True, "Cylinder")
    assert back.deviation == 1e-13 and back.tolerance == 0.002
    np.testing.assert_array_equal(back.outer, face.outer)
    np.testing.assert_array_equal(back.holes[0], face.holes[0])
    uv = rng.uniform(0, 1, size=(200, 2))
    np.testing.assert_array_equal(back.surface.evaluate(uv[:, 0], uv[:, 1]),
                                  surface.evaluate(uv[:, 0], uv[:, 1]))
    np.testing.assert_array_equal(cf.inside(back, uv[:, 0], uv[:, 1]),
                                  cf.inside(face, uv[:, 0], uv[:, 1]))


def _doc(rng):
    return cf.to_dict(Face(wavy_surface(rng), square(0, 0, 1, 1), index=2))


@pytest.mark.parametrize(("change", "message"), [
    (lambda d: d.pop("outer"), r"missing key\(s\) outer"),
    (lambda d: d.update(extra=1), r"unknown key\(s\) extra"),
    (lambda d: d.update(index=True), r"index must be int"),
    (lambda d: d.update(index=0), r"index is 1-based"),
    (lambda d: d.update(version=2), r"version 1"),
    (lambda d: d.update(selected="yes"), r"Face2: selected must be bool"),
    (lambda d: d["surface"].pop("knots_u"), r"Face2: surface: missing key\(s\) knots_u"),
    (lambda d: d["surface"].update(poles="x"), r"Face2: surface poles"),
    (lambda d: d["surface"].update(weights=[[1.0]]), r"Face2: surface weights have shape"),
    (lambda d: d["surface"]["weights"][0].__setitem__(0, -1.0), r"weights must be positive"),
    (lambda d: d["surface"].update(degree_u=26), r"Face2: surface: .*degree_u"),
    (lambda d: d.update(outer=[[0, 0], [1, 0], [1, 1]]), r"Face2: outer loop is empty"),
    (lambda d: d.update(outer=[[0, 0], [1, 0], [1, "a"], [0, 0]]), r"Face2: outer must be"),
    (lambda d: d.update(holes={}), r"holes must be a list"),
])
def test_dict_is_strict(rng, change, message):
    doc = _doc(rng)
    change(doc)
    with pytest.raises(FaceError, match=message):
        cf.face_from_dict(doc, source="faces.json")


def test_dict_error_names_the_source(rng):
    with pytest.raises(FaceError, match=r"^faces\.json: expected an object"):
        cf.face_from_dict([1, 2], source="faces.json")


# --------------------------------------------------------------------------- validation


def test_open_loop_is_refused():
    loop = square(0, 0, 1, 1)[:-1]
    with pytest.raises(FaceError, match=r"Face7: outer loop is not closed"):
        Face(plane_surface(), loop, index=7)


def test_self_crossing_outer_loop_is_refused():
    bowtie = np.array([[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]], dtype=float)
    with pytest.raises(FaceError, match=r"Face4: outer loop crosses itself: segment 0 .* "
                                        r"segment 2"):
        Face(plane_surface(), bowtie, index=4)


def test_self_crossing_hole_is_refused():
    bowtie = np.array([[0.2, 0.2], [0.4, 0.4], [0.4, 0.2], [0.2, 0.4], [0.2, 0.2]])
    with pytest.raises(FaceError, match=r"Face1: hole 1 crosses itself"):
        Face(plane_surface(), square(0, 0, 1, 1), (bowtie,))


@pytest.mark.parametrize("loop", [
    np.zeros((0, 2)),
    np.array([[0, 0], [1, 0], [0, 0]], dtype=float),
    np.array([[0, 0], [1, 0], [2, 0], [0, 0]], dtype=float),  # no area
])
def test_empty_loop_is_refused(loop):
    with pytest.raises(FaceError, match=r"Face2: outer loop is empty"):
        Face(plane_surface(), loop, index=2)


def test_non_finite_loop_is_refused():
    loop = square(0, 0, 1, 1)
    loop[2, 1] = np.nan
    with pytest.raises(FaceError, match=r"non-finite"):
        Face(plane_surface(), loop)


def test_big_valid_loop_is_accepted():
    rng = np.random.default_rng(1)
    outer = star(rng, (0.5, 0.5), 0.3, 0.5, k=3000)
    face = Face(plane_surface(), outer)
    assert len(face.outer) == 3001


# --------------------------------------------------------------------------- densification


@pytest.mark.parametrize(("radius", "tol"), [(5.0, 1e-3), (20.0, 1e-2), (3.0, 1e-4)])
@pytest.mark.parametrize("backwards", [False, True])
def test_densified_circle_keeps_sagitta_within_tolerance(radius, tol, backwards):
    """On the plane S(u, v) = (u, v, 0) mm a circle's chord error is its sagitta
    r (1 - cos(dθ / 2)): every segment within tol, and none refined needlessly."""

    def pcurve(t):
        t = np.asarray(t, dtype=float)
        return np.column_stack([radius * np.cos(t), radius * np.sin(t)])

    def point(uv):
        uv = np.asarray(uv)
        return np.column_stack([uv, np.zeros(len(uv))])

    t0, t1 = (2 * np.pi, 0.0) if backwards else (0.0, 2 * np.pi)
    poly = cf.densify_edge(pcurve, point, t0, t1, tol)
    np.testing.assert_allclose(poly[0], pcurve([t0])[0], atol=1e-12)
    np.testing.assert_allclose(poly[-1], pcurve([t1])[0], atol=1e-12)
    angles = np.unwrap(np.arctan2(poly[:, 1], poly[:, 0]))
    steps = np.abs(np.diff(angles))
    sagitta = radius * (1 - np.cos(steps / 2))
    assert sagitta.max() <= tol
    assert sagitta.max() > tol / 4.5  # bisection stops within a factor 4 of the tolerance
    fewest = math.ceil(2 * np.pi / (2 * math.acos(1 - tol / radius)))
    assert fewest <= len(poly) - 1 <= 2 * fewest + 8
    assert (np.diff(angles) < 0).all() if backwards else (np.diff(angles) > 0).all()


def test_densify_refuses_a_bad_tolerance():
    with pytest.raises(FaceError, match=r"Face9: trim tolerance must be a positive length in mm"):
        cf.densify_edge(lambda t: np.zeros((len(t), 2)), lambda uv: np.zeros((len(uv), 3)),
                        0, 1, 0.0, name="Face9")


def test_join_edges_walks_each_edge_either_way():
    a = np.array([[0, 0], [0.5, 0], [1, 0]], dtype=float)
    b = np.array([[1, 1], [1, 0]], dtype=float)  # backwards
    c = np.array([[1, 1], [0, 1]], dtype=float)
    d = np.array([[0, 0], [0, 1]], dtype=float)  # backwards
    loop = cf.join_edges([a, b, c, d], "Face1", "outer wire", 1e-9)
    np.testing.assert_array_equal(loop, [[0, 0], [0.5, 0], [1, 0], [1, 1], [0, 1], [0, 0]])
    with pytest.raises(FaceError, match=r"Face1: outer wire is not closed: edge 3"):
        cf.join_edges([a, b, c + [0, 0.1], d], "Face1", "outer wire", 1e-9)


def test_flip_v_reverses_the_surface():
    rng = np.random.default_rng(3)
    s = wavy_surface(rng)
    poles, weights, knots_v = cf.flip_v(s.poles, s.weights, s.knots_v)
    f = NurbsSurface(poles, s.knots_u, knots_v, s.degree_u, s.degree_v, weights=weights)
    u, v = rng.uniform(0, 1, 50), rng.uniform(0, 1, 50)
    np.testing.assert_allclose(f.evaluate(u, v), s.evaluate(u, 1 - v), rtol=0, atol=1e-11)
    n1, n2 = f.normals(u, v), s.normals(u, 1 - v)
    np.testing.assert_allclose((n1 * n2).sum(1) / np.linalg.norm(n1, axis=1)
                               / np.linalg.norm(n2, axis=1), -1, atol=1e-9)


def test_period_shift():
    tau = 2 * np.pi
    assert cf.period_shift((tau, 2 * tau, 0, 1), (-1e-15, 0), (tau, 0)) == (tau, 0.0)
    assert cf.period_shift((0, tau, 0, 1), (0, 0), (tau, 0)) == (0.0, 0.0)


# --------------------------------------------------------------------------- selection


def test_parse_selection():
    assert cf.parse_selection("up", 12) == "up"
    assert cf.parse_selection(" UP ", 12) == "up"
    assert cf.parse_selection("3,8", 12) == [3, 8]
    assert cf.parse_selection(["Face3", 8, 3], 12) == [3, 8]
    with pytest.raises(FaceError, match=r"part\.step: face 20 of 12"):
        cf.parse_selection("3,20", 12, "part.step")
    with pytest.raises(FaceError, match=r"selection is empty"):
        cf.parse_selection([], 12)
    with pytest.raises(FaceError, match=r"'top' is neither a face number"):
        cf.parse_selection("top", 12)
    with pytest.raises(FaceError, match=r"not a face number"):
        cf.parse_selection([True], 12)


def test_apply_selection():
    faces = [Face(plane_surface(), square(0, 0, 1, 1), index=i) for i in (1, 2, 3)]
    reach = [(False, "it is vertical"), (True, ""), (True, "")]
    assert [f.selected for f in cf.apply_selection(faces, reach, "up")] == [False, True, True]
    assert [f.selected for f in cf.apply_selection(faces, reach, [3])] == [False, False, True]
    with pytest.raises(FaceError, match=r"Face1 is not reachable from above.*vertical"):
        cf.apply_selection(faces, reach, [1])
    with pytest.raises(FaceError, match=r"no face is reachable from above"):
        cf.apply_selection(faces, [(False, "")] * 3, "up")


# --------------------------------------------------------------------------- OCP extraction


@pytest.fixture(scope="module")
def ocp():
    if os.environ.get("BSPLINECAM_REQUIRE_ALL") != "1":
        pytest.importorskip("OCP", reason="cadquery's OCP lives in the project venv")
        pytest.importorskip("cadquery")
    from BSplineCAM.ocp import faces as ocp_faces

    return ocp_faces


def _bspline_block_step(path):
    """A cadquery STEP: a block whose top is a B-spline face (the core net's exact face), cut
    by a through hole, its other top edges filleted."""
    import cadquery as cq
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Common
    from OCP.BRepPrimAPI import BRepPrimAPI_MakePrism
    from OCP.gp import gp_Vec

    from BSplineCAM import Surface
    from BSplineCAM.ocp import occ

    x, y = np.meshgrid(np.linspace(0, 60, 7), np.linspace(0, 40, 6), indexing="ij")
    z = 20 + 3 * np.sin(x / 11) * np.cos(y / 9)
    top = occ.to_face(Surface(np.stack([x, y, z], axis=-1), "clamped"))
    prism = BRepPrimAPI_MakePrism(top, gp_Vec(0, 0, -40)).Shape()
    box = cq.Solid.makeBox(60, 40, 40, cq.Vector(0, 0, -5)).wrapped
    block = cq.Shape.cast(BRepAlgoAPI_Common(prism, box).Shape())
    block = block.cut(cq.Solid.makeCylinder(6, 80, cq.Vector(30, 20, -20)))
    drilled = (cq.Workplane().box(40, 30, 20).faces(">Z").workplane().hole(10)
               .edges(">Z").fillet(3).translate((0, 60, 10)).val())
    cq.exporters.export(cq.Workplane().add(cq.Compound.makeCompound([block, drilled])), str(path))


def test_ocp_extraction_against_occt(ocp, tmp_path):
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex, BRepBuilderAPI_NurbsConvert
    from OCP.BRepClass import BRepClass_FaceClassifier
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.BRepGProp import BRepGProp
    from OCP.gp import gp_Pnt, gp_Pnt2d
    from OCP.GProp import GProp_GProps
    from OCP.TopAbs import TopAbs_IN

    step = tmp_path / "part.step"
    _bspline_block_step(step)
    shape = ocp.read_part(step)
    faces = ocp.faces_from_shape(shape, "up", tolerance=0.01)
    sources = ocp.shape_faces(shape)
    assert len(faces) == len(sources) > 10
    kinds = {f.source for f in faces}
    assert {"BSplineSurface", "Plane", "Cylinder", "Toroid"} <= kinds
    rng = np.random.default_rng(11)
    for face, source in zip(faces, sources):
        props = GProp_GProps()
        BRepGProp.SurfaceProperties_s(source, props)
        centre = props.CentreOfMass()
        box = ocp._diagonal(source)
        # "up": the tops (z 20 or the B-spline top) and the fillets, never walls or bottoms.
        if face.selected:
            assert centre.Z() > 14, face.name
        work = source if face.source == "BSplineSurface" else ocp.shape_faces(
            BRepBuilderAPI_NurbsConvert(source, True).Shape())[0]
        u0, u1, v0, v1 = face.bounds()
        uv = np.column_stack([rng.uniform(u0, u1, 150), rng.uniform(v0, v1, 150)])
        scaled = [(loop - [u0, v0]) / [u1 - u0, v1 - v0] for loop in face.loops]
        uv = uv[far_from(scaled, (uv - [u0, v0]) / [u1 - u0, v1 - v0], 0.02)]
        ours = cf.inside(face, uv[:, 0], uv[:, 1])
        vo = uv[:, 1] if not face.flipped_v else (
            face.surface.knots_v[0] + face.surface.knots_v[-1] - uv[:, 1])
        theirs = np.array([
            BRepClass_FaceClassifier(work, gp_Pnt2d(float(a), float(b)), 1e-9).State() == TopAbs_IN
            for a, b in zip(uv[:, 0], vo)])
        assert np.array_equal(ours, theirs), face.name
        assert np.count_nonzero(ours) > 5, face.name
        pts = face.surface.evaluate(uv[ours, 0], uv[ours, 1])
        surf = BRep_Tool.Surface_s(work)
        occt = np.array([(lambda p: (p.X(), p.Y(), p.Z()))(surf.Value(float(a), float(b)))
                         for a, b in zip(uv[ours, 0], vo[ours])])
        assert np.linalg.norm(pts - occt, axis=1).max() <= 1e-9 * box, face.name
        for p in pts[:: max(1, len(pts) // 10)]:
            vertex = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex()
            dist = BRepExtrema_DistShapeShape(vertex, source)
            assert dist.Value() <= 1e-9 * box, face.name
    selected = [f for f in faces if f.selected]
    assert sum(f.source == "BSplineSurface" for f in selected) == 1
    assert sum(f.source == "Toroid" for f in selected) == 1  # the hole's rim fillet


def test_ocp_sphere_dimple_with_its_rim_filleted(ocp, tmp_path):
    """A block with a spherical dimple whose rim is filleted: cadquery makes the fillet a
    rational B-spline of degree 10, and the sphere's trim runs past its pole's parameter by
    1.6e-7 rad.  Every face is taken, inside its domain, and evaluates as OCCT does."""
    import cadquery as cq
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_NurbsConvert

    block = cq.Workplane().box(60, 40, 20, centered=False)
    sphere = cq.Solid.makeSphere(15, cq.Vector(30, 20, 30), angleDegrees1=-90,
                                 angleDegrees2=90)
    dimple = block.cut(cq.Workplane().add(sphere))
    rim = dimple.edges(cq.selectors.BoxSelector((10, 0, 19.9), (50, 40, 20.1))).edges("%CIRCLE")
    step = tmp_path / "dimple.step"
    cq.exporters.export(dimple.newObject(rim.vals()).fillet(3), str(step))
    shape = ocp.read_part(step)
    faces = ocp.faces_from_shape(shape, "up", tolerance=0.01)  # all faces, some selected
    sources = ocp.shape_faces(shape)
    degrees = {(f.surface.degree_u, f.surface.degree_v) for f in faces}
    assert any(max(d) >= 10 for d in degrees), degrees
    assert "Sphere" in {f.source for f in faces}
    rng = np.random.default_rng(3)
    for face, source in zip(faces, sources):
        (u0, u1), (v0, v1) = face.surface.domain
        for loop in face.loops:
            assert loop[:, 0].min() >= u0 and loop[:, 0].max() <= u1, face.name
            assert loop[:, 1].min() >= v0 and loop[:, 1].max() <= v1, face.name
        work = source if face.source == "BSplineSurface" else ocp.shape_faces(
            BRepBuilderAPI_NurbsConvert(source, True).Shape())[0]
        a0, a1, b0, b1 = face.bounds()
        uv = np.column_stack([rng.uniform(a0, a1, 60), rng.uniform(b0, b1, 60)])
        uv = uv[cf.inside(face, uv[:, 0], uv[:, 1])]
        vo = uv[:, 1] if not face.flipped_v else (
            face.surface.knots_v[0] + face.surface.knots_v[-1] - uv[:, 1])
        surf = BRep_Tool.Surface_s(work)
        occt = np.array([(lambda p: (p.X(), p.Y(), p.Z()))(surf.Value(float(a), float(b)))
                         for a, b in zip(uv[:, 0], vo)]).reshape(-1, 3)
        ours = face.surface.evaluate(uv[:, 0], uv[:, 1]).reshape(-1, 3)
        assert np.abs(ours - occt).max(initial=0.0) <= 1e-9 * 72.2, face.name


def test_trim_points_just_outside_the_domain_go_onto_its_side():
    from BSplineCAM.core.geometry.face_import import DOMAIN_SLACK, into_domain

    domain = ((0.0, 2.0), (-1.0, 1.0))
    loop = np.array([[-1e-4, -1.0 - 1e-7], [2.0, -1.0], [2.0 + 1e-5, 1.0], [0.0, 1.0],
                     [-1e-4, -1.0 - 1e-7]])
    (moved,) = into_domain([loop], domain, "Face7 (Sphere)")
    np.testing.assert_array_equal(moved[:, 0], [0.0, 2.0, 2.0, 0.0, 0.0])
    np.testing.assert_array_equal(moved[:, 1], [-1.0, -1.0, 1.0, 1.0, -1.0])
    far = loop.copy()
    far[1, 1] = -1.0 - 3 * DOMAIN_SLACK * 2.0
    with pytest.raises(FaceError, match=r"Face7 \(Sphere\): its trim reaches 0.006 outside "
                                        r"the surface's v domain \[-1, 1\]"):
        into_domain([far], domain, "Face7 (Sphere)")


def test_ocp_bad_input(ocp, tmp_path):
    import cadquery as cq

    with pytest.raises(FaceError, match=r"no such file"):
        ocp.read_part(tmp_path / "missing.step")
    face_only = tmp_path / "face.step"
    cq.exporters.export(cq.Workplane().add(cq.Face.makePlane(10, 10)), str(face_only))
    with pytest.raises(FaceError, match=r"face\.step: holds no solid"):
        ocp.read_part(face_only)
    box = cq.Solid.makeBox(10, 10, 10).wrapped
    with pytest.raises(FaceError, match=r"face 20 of 6"):
        ocp.faces_from_shape(box, [20])
    with pytest.raises(FaceError, match=r"Face\d is not reachable from above"):
        ocp.faces_from_shape(box, [1])


# -- "up" up to the model's tolerance (core.faces.reach) -----------------------------------------
def _blend_foot(tilt: float, radius: float = 3.0, rows: int = 40):
    """Normals' z and heights of a quarter-round blend of ``radius`` (mm) standing on a wall:
    its profile turns from the horizontal at the top to ``tilt`` rad below it at the foot."""
    angle = np.linspace(np.pi / 2, -tilt, rows)  # the normal's angle above the horizontal
    return np.sin(angle), radius * np.sin(angle)


def test_reach_accepts_a_blend_whose_foot_tilts_within_the_model_tolerance():
    """A blend's foot 1.1e-5 rad below the horizontal on a 3 mm radius: the part that faces down
    is ~3e-5 mm tall, its overhang ~1e-10 mm (estimated with half a spacing beyond each end),
    far inside a model tolerance of 1e-5 mm."""
    nz, z = _blend_foot(1.1e-5)
    assert cf.reach(nz, z, 1e-5, spacing=0.5) == (True, "")


def test_reach_refuses_a_drafted_undercut_with_its_overhang():
    """A plane drafted 1 degree the wrong way, 20 mm tall: it overhangs by 20 tan(1 deg) = 0.35
    mm, named in the message."""
    z = np.linspace(0.0, 20.0, 15)
    nz = np.full_like(z, -np.sin(np.radians(1.0)))
    up, why = cf.reach(nz, z, 1e-5, spacing=20.0 / 14)
    assert not up
    overhang = float(re.search(r"overhangs by about ([0-9.e+-]+) mm", why).group(1))
    # the samples span 20 mm, plus half a spacing beyond each end
    assert overhang == pytest.approx(np.tan(np.radians(1.0)) * (20.0 + 20.0 / 14), rel=1e-3)
    assert "model's tolerance 1e-05 mm" in why


@pytest.mark.parametrize("tolerance, up", [(1e-6, False), (1e-4, True)])
def test_reach_follows_the_model_tolerance(tolerance, up):
    """The same slight undercut (normal z = -2e-6 over 5 mm: an overhang of about 1e-5 mm) is an
    undercut for a model held to 1 um and vertical for one held to 0.1 mm."""
    z = np.linspace(0.0, 5.0, 11)
    nz = np.concatenate([np.full(11, -2e-6), [0.5]])
    assert cf.reach(nz, np.concatenate([z, [5.0]]), tolerance, spacing=0.5)[0] is up


def test_reach_bottoms_walls_and_no_normal():
    assert cf.reach([-1.0, -1.0], [0.0, 0.0], 1.0, 1.0) == (
        False, "its outward normal points down (normal z = -1)")
    assert cf.reach([0.0, 1e-12, -1e-12], [0.0, 1.0, 2.0], 1e-5, 1.0)[1].startswith(
        "it is vertical")
    assert cf.reach([], [], 1e-5, 1.0) == (False, "its normal is defined nowhere")
    # the floor: a model tolerance of 0 counts as OCCT's Precision::Confusion (1e-7 mm)
    assert cf.reach([-1e-8, 1.0], [0.0, 1.0], 0.0, 1.0)[0] is True


# -- faces accepted by the machining's chordal tolerance (core.face_import) ----------------------
@pytest.mark.parametrize("measured, chordal, refused", [
    (1.02e-8, 0.002, False),   # the 10 nm of a degree-14 blend: accepted, and kept
    (1.9e-5, 0.002, False),    # just inside 1 % of 2 um
    (2.1e-5, 0.002, True),     # just outside
    (2.1e-5, 0.01, False),     # a coarser tolerance allows more
    (1.0, None, False),        # check: measured, never refused
])
def test_faces_are_accepted_by_the_chordal_tolerance(measured, chordal, refused):
    x, y = np.meshgrid([0.0, 40.0], [0.0, 30.0], indexing="ij")
    data = dict(poles=np.stack([x, y, 0.1 * x], axis=-1), weights=None, knots_u=[0, 0, 1, 1],
                knots_v=[0, 0, 1, 1], degree_u=1, degree_v=1)
    outer = np.array([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], dtype=float)
    kwargs = dict(index=3, name="Face3", kind="BSplineSurface", selected=True, tolerance=1e-3,
                  chordal_tolerance=chordal)
    if refused:
        with pytest.raises(FaceError, match=(
                rf"Face3 \(BSplineSurface\): its NURBS is {measured:.3g} mm from OCCT's original"
                rf" surface .*more than {0.01 * chordal:.3g} mm, 1% of the chordal tolerance "
                rf"{chordal:g} mm")):
            face_import.checked_face(dict(data), outer, [], False, lambda face: measured, 50.0,
                                     **kwargs)
    else:
        face = face_import.checked_face(dict(data), outer, [], False, lambda face: measured,
                                        50.0, **kwargs)
        assert face.deviation == measured
