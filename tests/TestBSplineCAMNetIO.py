# SPDX-License-Identifier: LGPL-2.1-or-later
"""Control-net and point files: round trips, row detection, and errors that name the fault."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import numpy as np
import pytest
from conftest import CASE_STUDY, ROOT, random_net

from BSplineCAM import Surface
from BSplineCAM.core.errors import NetError
from BSplineCAM.core.geometry import netio
from BSplineCAM.orchestration.cli import main as cli_main


def write_json(path, points, **extra):
    doc = {"name": "t", "units": "mm", "knots": "uniform", "control_points": points, **extra}
    path.write_text(json.dumps(doc))
    return path


def test_case_study_loads():
    s = Surface.from_json(CASE_STUDY)
    assert s.shape == (10, 10) and s.knots.value == "clamped" and s.name == "case-study"


def test_json_round_trip(tmp_path, rng):
    net = netio.ControlNet(random_net(rng), netio.KnotLayout.CLAMPED, "wave")
    netio.write_json(net, tmp_path / "n.json")
    back = netio.read_json(tmp_path / "n.json")
    np.testing.assert_array_equal(back.points, net.points)
    assert back.knots is net.knots and back.name == "wave"


def test_json_in_inches_is_converted(tmp_path, rng):
    pts = random_net(rng, 4, 4)
    net = netio.read_json(write_json(tmp_path / "i.json", pts.tolist(), units="in"))
    np.testing.assert_allclose(net.points, pts * 25.4)


def test_csv_round_trip_any_order(tmp_path, rng):
    net = netio.ControlNet(random_net(rng, 5, 6), netio.KnotLayout.UNIFORM, "c")
    netio.write_csv(net, tmp_path / "c.csv")
    lines = (tmp_path / "c.csv").read_text().splitlines()
    (tmp_path / "shuffled.csv").write_text("\n".join([lines[0], *reversed(lines[1:])]))
    back = netio.read_csv(tmp_path / "shuffled.csv")
    np.testing.assert_array_equal(back.points, net.points)


@pytest.mark.parametrize("with_header", [True, False])
def test_dat_round_trip_and_row_detection(tmp_path, with_header):
    grid = Surface.from_json(CASE_STUDY).grid(24, 18)
    path = tmp_path / "p.dat"
    netio.write_dat(grid, path)
    if not with_header:
        path.write_text("\n".join(line for line in path.read_text().splitlines() if not line.startswith("#")))
    back = netio.read_dat(path)
    assert back.shape == (24, 18, 3)
    np.testing.assert_allclose(back, grid, atol=1e-9)


def test_dat_given_row_count(tmp_path):
    grid = Surface.from_json(CASE_STUDY).grid(6, 8)
    np.savetxt(tmp_path / "g.dat", grid.reshape(-1, 3))
    assert netio.read_dat(tmp_path / "g.dat", rows=6).shape == (6, 8, 3)


BAD_JSON = [
    ("ragged", lambda p: [p[0], p[1][:-1], p[2], p[3]], r"ragged net: row 1 has 3 points, row 0 has 4"),
    ("small", lambda p: [r[:3] for r in p], r"at least 4x4 control points, got 4x3"),
    ("nan", lambda p: [[[float("nan"), 0, 0]] + r[1:] for r in p], r"point \[0\]\[0\] coordinate x is nan"),
    ("text", lambda p: [p[0], p[1], [p[2][0], [0, "a", 0], *p[2][2:]], p[3]], r"point \[2\]\[1\] coordinate y is not a number"),
    ("short point", lambda p: [p[0], [[1, 2], *p[1][1:]], p[2], p[3]], r"point \[1\]\[0\] must be \[x, y, z\]"),
]


@pytest.mark.parametrize("label,mutate,message", BAD_JSON, ids=[b[0] for b in BAD_JSON])
def test_bad_json_nets_name_the_fault(tmp_path, label, mutate, message):
    points = np.arange(48.0).reshape(4, 4, 3).tolist()
    path = write_json(tmp_path / "bad.json", mutate(points))
    with pytest.raises(NetError, match=message) as info:
        netio.read_json(path)
    assert str(path) in str(info.value)


def test_inf_in_array_is_named():
    pts = np.zeros((4, 5, 3))
    pts[2, 3, 2] = np.inf
    with pytest.raises(NetError, match=r"point \[2\]\[3\] coordinate z is inf"):
        Surface(pts)


def test_truncated_json_names_line(tmp_path):
    path = tmp_path / "t.json"
    path.write_text('{"control_points": [[[0, 0, 0],\n [1, 0')
    with pytest.raises(NetError, match=r"t.json: line 2, column \d+: invalid JSON"):
        netio.read_json(path)


def test_unknown_layout_in_file(tmp_path):
    path = write_json(tmp_path / "k.json", np.zeros((4, 4, 3)).tolist(), knots="bezier")
    with pytest.raises(NetError, match=r"k.json: unknown knot layout 'bezier'"):
        netio.read_json(path)


def test_binary_and_missing_files(tmp_path):
    (tmp_path / "b.json").write_bytes(b"\xff\xfe\x00binary")
    with pytest.raises(NetError, match="not a text file"):
        netio.read_json(tmp_path / "b.json")
    with pytest.raises(NetError, match="cannot read"):
        netio.read_json(tmp_path / "missing.json")
    with pytest.raises(NetError, match="unknown control-net format '.stl'"):
        netio.read_net(tmp_path / "x.stl")


def test_bad_dat_files(tmp_path):
    path = tmp_path / "d.dat"
    path.write_text("1 2 3\n4 five 6\n")
    with pytest.raises(NetError, match=r"d.dat: line 2: not numeric"):
        netio.read_dat(path)
    path.write_text("1 2 3 4\n")
    with pytest.raises(NetError, match=r"line 1: expected 'X Y Z', got 4 fields"):
        netio.read_dat(path)
    np.savetxt(path, np.arange(17 * 3.0).reshape(17, 3))  # 17 is prime: no grid
    with pytest.raises(NetError, match="17 points do not form a grid"):
        netio.read_dat(path)
    np.savetxt(path, np.arange(20 * 3.0).reshape(20, 3))
    with pytest.raises(NetError, match="do not form a grid of 3 rows"):
        netio.read_dat(path, rows=3)


def test_bad_csv_files(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("row,column,x,y,z\n0,0,1,2,3\n0,1,1,2\n")
    with pytest.raises(NetError, match="line 3: expected 5 fields"):
        netio.read_csv(path)
    path.write_text("row,column,x,y,z\n" + "\n".join(f"{i},{j},0,0,0" for i in range(4) for j in range(4) if (i, j) != (2, 1)))
    with pytest.raises(NetError, match=r"point \(2, 1\) is missing"):
        netio.read_csv(path)


def test_atomic_write_leaves_nothing_on_failure(tmp_path):
    with pytest.raises(RuntimeError), netio.atomic_write(tmp_path / "x.txt") as handle:
        handle.write("half")
        raise RuntimeError("disk full")
    assert list(tmp_path.iterdir()) == []


def test_cli_bad_input_writes_nothing(tmp_path, capsys):
    bad = write_json(tmp_path / "bad.json", [[[0, 0, 0]] * 4] * 3)
    out = tmp_path / "out"
    assert cli_main(["surface", str(bad), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and "at least 4x4" in err and "Traceback" not in err
    assert not out.exists() or list(out.iterdir()) == []


def test_surface_imports_without_freecad():
    code = "import sys; from BSplineCAM import Surface; Surface.from_json(sys.argv[1]).grid(5, 5); assert 'FreeCAD' not in sys.modules"
    subprocess.run([sys.executable, "-c", code, str(CASE_STUDY)], check=True, cwd=ROOT)


def test_core_never_imports_freecad():
    banned = re.compile(r"^\s*(import|from)\s+(FreeCAD|FreeCADGui|Part|Path|PathScripts|OCP|cadquery|matplotlib)\b", re.M)
    for path in (ROOT / "BSplineCAM" / "core").rglob("*.py"):
        match = banned.search(path.read_text())
        assert match is None, f"{path} imports {match.group(0).strip()!r}"


def test_layers_import_only_downwards():
    """core <- app <- gui, orchestration on top; nothing loose at the package root."""
    package = ROOT / "BSplineCAM"
    loose = sorted(p.name for p in package.glob("*.py") if p.name != "__init__.py")
    assert loose == [], f"modules loose at the package root: {loose}"
    upward = {
        "core": re.compile(r"^\s*(from\s+(BSplineCAM\.|\.\.)(app|gui|orchestration|ocp)\b)", re.M),
        # a factory may attach its view provider under ``if FreeCAD.GuiUp:`` (indented import)
        "app": re.compile(r"^(import\s+FreeCADGui|from\s+(BSplineCAM\.|\.\.)gui\b)", re.M),
    }
    for layer, banned in upward.items():
        for path in (package / layer).rglob("*.py"):
            match = banned.search(path.read_text())
            assert match is None, f"{path} imports upwards: {match.group(0).strip()!r}"
