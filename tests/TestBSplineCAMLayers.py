# SPDX-License-Identifier: LGPL-2.1-or-later
"""The import graph of BSplineCAM (issue 42): acyclic, layered, and lazy only where listed.

Every module under BSplineCAM/ is parsed with ``ast`` (nothing is imported); its imports of
BSplineCAM modules, module-level and inside functions, relative ones resolved, make the graph.

* (a) the module-level imports have no cycle (``if TYPE_CHECKING:`` blocks do not count);
* (b) no layer imports upwards: core imports nothing of app, gui, orchestration or ocp; app
  nothing of gui or orchestration; ocp nothing of app, gui or orchestration; gui nothing of
  orchestration.  Core never imports FreeCAD, its GUI or OCCT; app and orchestration never
  import FreeCADGui or Qt at module level, orchestration not even FreeCAD;
* (c) an import of a project module inside a function is listed in :data:`LAZY` with the
  reason it cannot be at module level (or lies in a module :data:`LAZY_OWNERS` names).
"""

from __future__ import annotations

import ast
import textwrap
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = "BSplineCAM"

#: layer -> the layers it must not import (module level or in a function, unless in LAZY).
UPWARD = {
    "core": {"app", "gui", "orchestration", "ocp"},
    "app": {"gui", "orchestration"},
    "ocp": {"app", "gui", "orchestration"},
    "gui": {"orchestration"},
}
#: layer -> (external top-level modules it must not import, module level only?)
EXTERNAL = {
    "core": ({"FreeCAD", "FreeCADGui", "Part", "Path", "Mesh", "OCP", "cadquery", "PySide",
              "PySide2", "PySide6"}, False),
    "app": ({"FreeCADGui", "PySide", "PySide2", "PySide6"}, True),
    "orchestration": ({"FreeCAD", "FreeCADGui", "Part", "Path", "Mesh", "PySide", "PySide2",
                       "PySide6"}, True),
}

GUI_UP = "view provider or message box, only when FreeCAD.GuiUp"
FREECAD = "needs FreeCAD (Part, CAM), and this module must import without it (venv, worker)"
OPTIONAL = "optional dependency: OCP / cadquery"
STARTUP = "a worker's net request never loads the part machinery"
OWNER = "owner to move to module level (issue 42 item 3)"
LOAD_ON_USE = "loaded by the command that uses it: the workbench activates fast"

#: (importer, imported) relative to BSplineCAM -> why the import sits inside a function.
LAZY = {
    ("app.crosscheck", "app.part"): FREECAD,
    ("app.crosscheck", "ocp.occ"): OPTIONAL,
    ("app.importers", "gui.messages"): GUI_UP,
    ("app.surface_feature", "gui.surface_view"): GUI_UP,
    ("app.verify_feature", "gui.verify_view"): GUI_UP,
    ("orchestration.cli_job", "app.pipeline"): FREECAD,
    ("orchestration.cli_toolpath", "app.pipeline"): FREECAD,
    ("orchestration.parts", "app.cam"): FREECAD,
    ("orchestration.parts", "app.faces"): FREECAD,
    ("orchestration.parts", "app.finishing_op"): FREECAD,
    ("orchestration.parts", "app.retract"): FREECAD,
    ("orchestration.parts", "ocp.occ"): OPTIONAL,
    ("orchestration.pipeline_run", "app.cam"): FREECAD,
    ("orchestration.worker", "app.faces"): FREECAD,
    ("orchestration.worker", "app.part"): FREECAD,
    ("orchestration.worker", "app.surface_feature"): FREECAD,
    ("orchestration.worker", "ocp.occ"): OPTIONAL,
    ("orchestration.worker", "orchestration.parts"): STARTUP,
    # gui/: the workbench activates without loading CAM, the ops or the simulation; each
    # command loads what it runs when it runs
    **{("gui.cam_commands", t): LOAD_ON_USE for t in (
        "app.cam", "app.finishing_op", "app.pipeline", "app.verify_feature",
        "core.program.rs274", "core.toolpath.common")},
    **{("gui.commands", t): LOAD_ON_USE for t in ("app.importers", "core", "gui.results_panel")},
    **{("gui.results_panel", t): LOAD_ON_USE for t in ("app.surface_feature", "app.verify_feature")},
    **{("gui.rough_panel", t): LOAD_ON_USE for t in (
        "app.cam", "app.pipeline", "app.roughing_op", "core.simulation.simulate")},
    **{("gui.surface_view", t): LOAD_ON_USE for t in ("gui.net_panel", "gui.results_panel")},
    **{("gui.verify_view", t): LOAD_ON_USE for t in ("app.verify_feature", "gui.results_panel")},
}
#: Modules being split by their owners: function-local imports allowed there for now.
LAZY_OWNERS: tuple[str, ...] = ()


@dataclass(frozen=True)
class Import:
    source: str  #: importing module, dotted
    target: str  #: imported module (a package's __init__ is the package's name)
    line: int
    local: bool  #: inside a function
    type_checking: bool  #: under ``if TYPE_CHECKING:``
    external: bool = False  #: target is outside the package (its top-level name)


def modules(root: Path, package: str) -> dict[str, tuple[Path, bool]]:
    """Dotted name -> (file, is a package's __init__) of every module under root/package."""
    found = {}
    for path in sorted((root / package).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        is_pkg = parts[-1] == "__init__"
        if is_pkg:
            parts = parts[:-1]
        found[".".join(parts)] = (path, is_pkg)
    return found


def _resolve(name: str, known: dict) -> str:
    while name and name not in known:
        name = name.rpartition(".")[0]
    return name


def imports(root: Path, package: str) -> list[Import]:
    """Every import statement of the package's modules, relative ones resolved."""
    known = modules(root, package)
    found: list[Import] = []
    for name, (path, is_pkg) in known.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        base = name if is_pkg else name.rpartition(".")[0]

        def targets(node: ast.Import | ast.ImportFrom) -> Iterator[tuple[str, bool]]:
            if isinstance(node, ast.Import):
                for alias in node.names:
                    top = alias.name.split(".")[0]
                    yield (alias.name, False) if top == package else (top, True)
                return
            if node.level:
                parts = base.split(".")
                parent = ".".join(parts[: len(parts) - node.level + 1])
                module = parent + ("." + node.module if node.module else "")
            else:
                module = node.module or ""
                if module.split(".")[0] != package:
                    yield module.split(".")[0], True
                    return
            for alias in node.names:  # ``from pkg import submodule`` imports the submodule
                sub = f"{module}.{alias.name}"
                yield (sub if sub in known else module), False

        def visit(node: ast.AST, local: bool, checking: bool) -> None:
            for child in ast.iter_child_nodes(node):
                if isinstance(child, (ast.Import, ast.ImportFrom)):
                    for target, external in targets(child):
                        if not external:
                            target = _resolve(target, known)
                            if target == name:
                                continue
                        found.append(Import(name, target, child.lineno, local, checking,
                                            external))
                elif isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                    visit(child, True, checking)
                elif isinstance(child, ast.If) and _is_type_checking(child.test):
                    for stmt in child.body:
                        visit(ast.Module(body=[stmt], type_ignores=[]), local, True)
                    for stmt in child.orelse:
                        visit(ast.Module(body=[stmt], type_ignores=[]), local, checking)
                else:
                    visit(child, local, checking)

        visit(tree, False, False)
    return found


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def find_cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """One cycle (a -> ... -> a) through each strongly connected part of the graph."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    parts: list[list[str]] = []

    def connect(v: str) -> None:  # Tarjan; the package is small enough for recursion
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                part.append(w)
                if w == v:
                    break
            if len(part) > 1:
                parts.append(part)

    for v in sorted(edges):
        if v not in index:
            connect(v)
    cycles = []
    for part in parts:  # a shortest way back to the start within the part
        members = set(part)
        start = min(part)
        paths = {start: [start]}
        queue = [start]
        cycle = None
        while queue and cycle is None:
            v = queue.pop(0)
            for w in sorted(edges.get(v, ())):
                if w == start:
                    cycle = paths[v] + [start]
                    break
                if w in members and w not in paths:
                    paths[w] = paths[v] + [w]
                    queue.append(w)
        cycles.append(cycle)
    return cycles


def _short(name: str, package: str) -> str:
    return name[len(package) + 1:] if name.startswith(package + ".") else name


def _layer(name: str, package: str) -> str:
    parts = name.split(".")
    return parts[1] if len(parts) > 1 and parts[0] == package else ""


def problems(root: Path = ROOT, package: str = PACKAGE, lazy: dict | None = None,
             lazy_owners: tuple[str, ...] = LAZY_OWNERS) -> list[str]:
    """Every breach of (a), (b) and (c), one line each; empty when the graph is clean."""
    lazy = LAZY if lazy is None else lazy
    found = imports(root, package)
    out = []
    edges: dict[str, set[str]] = {}
    for imp in found:
        if not imp.external and not imp.local and not imp.type_checking:
            edges.setdefault(imp.source, set()).add(imp.target)
    for cycle in find_cycles(edges):
        out.append("cycle of module-level imports: "
                   + " -> ".join(_short(m, package) for m in cycle))
    used = set()
    for imp in found:
        src, layer = _short(imp.source, package), _layer(imp.source, package)
        where = f"{src}:{imp.line}"
        if imp.external:
            banned, module_level_only = EXTERNAL.get(layer, (set(), True))
            if imp.target in banned and not (module_level_only and imp.local):
                out.append(f"{where}: {layer} imports {imp.target}"
                           + ("" if module_level_only else " (anywhere)"))
            continue
        dst = _short(imp.target, package)
        allowed = imp.local and (src, dst) in lazy
        if allowed:
            used.add((src, dst))
        if _layer(imp.target, package) in UPWARD.get(layer, ()) and not allowed:
            out.append(f"{where}: upward import {src} -> {dst}")
        elif imp.local and not allowed and not src.startswith(lazy_owners):
            out.append(f"{where}: {src} imports {dst} inside a function (not in LAZY)")
    for src, dst in sorted(set(lazy) - used):
        out.append(f"LAZY lists {src} -> {dst}, which is no longer imported in a function")
    return out


def test_import_graph_is_acyclic_layered_and_lazy_only_where_listed():
    found = problems()
    assert not found, "import graph of BSplineCAM:\n  " + "\n  ".join(found)


def test_lazy_list_gives_reasons():
    for pair, reason in LAZY.items():
        assert isinstance(reason, str) and reason.strip(), pair


def test_checker_reports_a_cycle_an_upward_import_and_an_unlisted_lazy_import(tmp_path):
    """A fake package with each fault: the checker names every one."""
    files = {
        "__init__.py": "",
        "core/__init__.py": "",
        "core/a.py": "from . import b\n",
        "core/b.py": "from .c import X\n",
        "core/c.py": "from .a import *\nX = 1\n",
        "core/d.py": "from ..app import e\nimport FreeCAD\n",
        "core/typed.py": ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n"
                          "    from .untyped import Y\n"),
        "core/untyped.py": "from .typed import TYPE_CHECKING\nY = 2\n",
        "app/__init__.py": "",
        "app/e.py": textwrap.dedent("""\
            import FreeCADGui
            from fake.core import a
            def f():
                from ..gui import view
                from ..core import d
                return view, d
            def g():
                from ..gui import view
                return view
            """),
        "gui/__init__.py": "",
        "gui/view.py": "",
    }
    for name, text in files.items():
        path = tmp_path / "fake" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    found = problems(tmp_path, "fake", lazy={("app.e", "gui.view"): GUI_UP,
                                             ("app.e", "app.gone"): GUI_UP}, lazy_owners=())
    text = "\n".join(found)
    assert "cycle of module-level imports: core.a -> core.b -> core.c -> core.a" in found, text
    assert "core.d:1: upward import core.d -> app.e" in found, text
    assert "core.d:2: core imports FreeCAD (anywhere)" in found, text
    assert "app.e:1: app imports FreeCADGui" in found, text
    assert "app.e:5: app.e imports core.d inside a function (not in LAZY)" in found, text
    assert "LAZY lists app.e -> app.gone, which is no longer imported in a function" in found
    assert not any("core.typed" in line or "core.untyped" in line for line in found), text
    assert not any("gui.view" in line for line in found), text  # listed in LAZY
    assert len(found) == 6, text


def test_cli_helpers_live_below_the_entry_point():
    """The command line's shared helpers come from cli_common: nothing imports the entry
    point, orchestration.cli, back."""
    importers = sorted({imp.source for imp in imports(ROOT, PACKAGE)
                        if imp.target == f"{PACKAGE}.orchestration.cli"})
    assert importers == []
