# SPDX-License-Identifier: LGPL-2.1-or-later
"""Parts (STEP, BREP, FreeCAD documents) as core faces for the command line.

:func:`load_faces` reads a part with FreeCAD's OCCT (:mod:`BSplineCAM.app.faces`) and returns
its faces as core :class:`~BSplineCAM.core.geometry.faces.Face` objects, the selected ones marked.
:func:`check_part` is ``bsplinecam check PART``: every selected face's conversion, and the
core's matrix evaluator against FreeCAD's OCCT and cadquery's OCCT at the same parameters
inside the trim.  Faces cross between processes as :func:`~BSplineCAM.core.geometry.faces.to_dict` JSON.

A part file is always read, and its faces converted, in a FreeCAD worker (FreeCAD's own
Python, :func:`runtime.freecad_python`), also when FreeCAD is loaded here: a damaged file can
make OCCT's reader crash (SIGSEGV on a B-spline whose pole list names a non-point entity) or
run on without end (coordinates out of scale), and neither may take the command down with it.
A worker is one code path for every caller, costs one start of that Python (1-2 s, small
beside a toolpath), and its answer is the same JSON the other interpreters already receive;
a probe child that only reads before an in-process read would cost the same start and read
the file twice.  A worker killed by a signal, ending without a reply, or still running after
:func:`part_time_limit` seconds (killed then) becomes one FaceError (exit status 2) naming the
file: ``PART: cannot read the part: OCCT stopped with signal 11 (SIGSEGV) while reading it``.
``toolpath`` and ``job`` read the part once more in this process to give CAM's job its model,
only after the worker has read the same file with the same FreeCAD.
"""

from __future__ import annotations

import os
import re
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

import numpy as np

from ..app import compat, runtime
from ..core.errors import BSplineCAMError, ParameterError
from ..core.geometry import faces as core_faces
from ..core.geometry.basis import cox_de_boor
from ..core.geometry.face_import import ACCEPT_SHARE, DEFAULT_CHORDAL_TOLERANCE, acceptance_limit
from ..core.geometry.faces import DEFAULT_TOLERANCE, Face, FaceError
from ..core.program import rs274
from ..core.simulation.measures import toolpath_lengths
from ..core.toolpath import faces_program_moves, generate_faces, program_moves
from ..core.toolpath.faceset import FaceSet
from ..core.toolpath.retracts import RaisedModel, faces_hops
from .cli_common import (
    EXIT_CHECK_FAILED,
    _safe_name,
    captured_console,
    check_interrupted,
    emit,
    json_text,
    staged_output,
    with_engine,
)
from .pipeline_run import program_figures

if TYPE_CHECKING:
    import argparse

    from ..core.toolpath.common import CuttingParameters, ToolParameters, Toolpath

#: File types read as parts (the rest are control nets); as in ``app.faces.PART_SUFFIXES``.
PART_SUFFIXES = (".step", ".stp", ".brep", ".brp", ".fcstd")
#: Largest accepted distance (mm) of the matrix evaluator from either OCCT, relative to the
#: face's size (the diagonal of its bounding box).
RELATIVE_TOLERANCE = 1e-9
#: Default grid points per side of the parameter box (cell centres inside the trim are kept).
PART_SAMPLES = 31
#: Worker request kinds handled here (``worker.handle`` passes them on).
REQUESTS = ("part_faces", "part_check", "evaluate_faces")
#: Seconds a worker may take to read a part and convert its faces (check: and evaluate them)
#: before it is killed; BSPLINECAM_PART_TIMEOUT overrides it.
PART_TIME_LIMIT_S = 300.0
PART_TIME_LIMIT_ENV = "BSPLINECAM_PART_TIMEOUT"

#: What ``--faces`` may hold: "up", "all" (check only), or 1-based face numbers.
FacesArg = Union[str, list]


def is_part(path: str | os.PathLike) -> bool:
    """True for a .step, .stp, .brep, .brp or .FCStd file name (any case)."""
    return Path(path).suffix.lower() in PART_SUFFIXES


def refuse_faces_on_net(faces: str | None, net: str) -> None:
    """``--faces`` given with a control net: a ParameterError naming both."""
    if faces is not None:
        raise ParameterError(f"--faces applies to parts ({', '.join(PART_SUFFIXES)}), "
                             f"not to the control net {net}")


def parse_faces(text: str | None, option: str = "--faces", allow_all: bool = False,
                default: str = "up") -> FacesArg:
    """``--faces``: "up", "all" (when ``allow_all``), or distinct 1-based face numbers written
    as ``3,8,20`` or ``Face3,Face8``; a FaceError naming the option for an
    empty selection or a bad item.  Numbers are checked against the part's face count later
    (``face 20 of 12``)."""
    if text is None:
        return default
    if not isinstance(text, str):
        raise FaceError(f"{option} must be 'up', a list of face numbers such as 3,8,20"
                        + (" or 'all'" if allow_all else "") + f", got {text!r}")
    word = text.strip().lower()
    if word == "up":
        return "up"
    if word == "all":
        if not allow_all:
            raise FaceError(f"{option} all: only 'check' takes every face; a toolpath takes "
                            "'up' or face numbers such as 3,8,20")
        return "all"
    items = [item.strip() for item in text.split(",")]
    if not any(items):
        raise FaceError(f"{option}: the face selection is empty (give 'up' or face numbers "
                        "such as 3,8,20)")
    numbers: list[int] = []
    for item in items:
        if not item:
            raise FaceError(f"{option} {text!r}: an empty item (two commas in a row, or a "
                            "comma at an end)")
        match = re.fullmatch(r"(?i:face)?\s*(\d+)", item)
        if not match:
            raise FaceError(f"{option}: {item!r} is not a face number (3 or Face3), 'up'"
                            + (" or 'all'" if allow_all else ""))
        number = int(match.group(1))
        if number < 1:
            raise FaceError(f"{option}: face {number}: faces are numbered from 1")
        if number not in numbers:
            numbers.append(number)
    return numbers


def _selection_text(selection: FacesArg) -> str:
    return selection if isinstance(selection, str) else ",".join(map(str, selection))


# --------------------------------------------------------------------------- loading


def load_faces(path: str | os.PathLike, faces: str | None = None,
               tolerance: float = DEFAULT_TOLERANCE, option: str = "--faces",
               allow_all: bool = False,
               chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """Every face of the part at ``path`` as a core Face (mm), the ``faces`` selection
    ("up" by default, or face numbers) marked ``selected``, the others check surfaces.

    FreeCAD reads the part: here when it loads in this process, else in a FreeCAD worker.
    ``tolerance`` is the trim polylines' chord tolerance (mm).  Errors (FaceError) name the
    file and the face.  With ``allow_all``, "all" marks every face selected (verification
    measures every face seen from above).  A face whose NURBS is farther from OCCT's than
    1 % of ``chordal_tolerance`` (mm, the machining's) is refused
    (:mod:`BSplineCAM.core.geometry.face_import`).
    """
    selection = parse_faces(faces, option, allow_all=allow_all)
    if selection == "all":
        return [replace(face, selected=True) for face in load_faces(
            path, "up", tolerance, option, chordal_tolerance=chordal_tolerance)]
    path = str(path)
    reply = _freecad_worker({"op": "part_faces", "path": path,
                             "faces": _selection_text(selection), "tolerance": tolerance,
                             "chordal_tolerance": chordal_tolerance})
    return [core_faces.face_from_dict(doc, f"{path} (FreeCAD worker)") for doc in reply["faces"]]


def part_time_limit() -> float:
    """Seconds a part's reading may take: BSPLINECAM_PART_TIMEOUT if set (a positive number),
    else :data:`PART_TIME_LIMIT_S`."""
    text = os.environ.get(PART_TIME_LIMIT_ENV, "").strip()
    if not text:
        return PART_TIME_LIMIT_S
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0 and np.isfinite(value)):
        raise ParameterError(f"{PART_TIME_LIMIT_ENV} must be a positive number of seconds, "
                             f"got {text!r}")
    return value


def _freecad_worker(request: dict) -> dict:
    """A FreeCAD worker's reply to a request that reads the part ``request["path"]``; its
    input errors come back as FaceError with its message, and a worker that crashed, ended
    without a reply or ran past :func:`part_time_limit` as a FaceError naming the file."""
    path = request["path"]
    try:
        return runtime.run_worker("freecad", request, timeout=part_time_limit())
    except BSplineCAMError as exc:
        text = re.sub(r"^freecad worker: (\w*Error: )?", "", str(exc))
        raise FaceError(text) from None
    except runtime.WorkerStopped as exc:
        if exc.timed_out:
            how = (f"did not finish within {exc.time_limit:g} s (the limit is "
                   f"{PART_TIME_LIMIT_ENV}, in seconds)")
        else:
            how = f"stopped with {exc.ending()} while reading it"
        raise FaceError(f"{path}: cannot read the part: OCCT {how}") from None


def _name_file(path: str, exc: FaceError) -> FaceError:
    """``exc`` with the part's file name in front (a face's error names only the face)."""
    text = str(exc)
    return exc if text.startswith(path) else FaceError(f"{path}: {text}")


def freecad_faces(path: str, selection: FacesArg, tolerance: float,
                  chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> list[Face]:
    """In FreeCAD: read the part and extract its faces (``app.faces``)."""
    from ..app import faces as app_faces

    try:
        shape = app_faces.read_part(path)
        return app_faces.faces_from_shape(shape, selection, tolerance, where=path,
                                          chordal_tolerance=chordal_tolerance)
    except FaceError as exc:
        raise _name_file(path, exc) from None


def conversion_report(faces: Sequence[Face], chordal_tolerance: float) -> tuple[dict, list]:
    """Each face's distance (mm) from OCCT's original surface, by name, and a note for every
    face farther than RELATIVE_TOLERANCE of its size (accepted, since it is within
    1 % of ``chordal_tolerance``, but worth knowing)."""
    limit = acceptance_limit(chordal_tolerance)
    distances, notes = {}, []
    for face in faces:
        distances[face.name] = face.deviation
        size = face.surface.size()
        if face.deviation > RELATIVE_TOLERANCE * size:
            notes.append(f"{face.name} ({face.source}): its NURBS is {face.deviation:.3g} mm "
                         f"from OCCT's original surface ({face.deviation / size:.2g} of its "
                         f"size), within the {limit:.3g} mm accepted ({ACCEPT_SHARE:.0%} of the "
                         f"chordal tolerance {chordal_tolerance:g} mm)")
    return distances, notes


# --------------------------------------------------------------------------- check


def _work_face(source):
    """OCCT's B-spline face that ``app.faces`` took the core face from: the face itself for
    a B-spline or Bézier surface, else OCCT's NURBS conversion of it."""
    import Part

    if isinstance(source.Surface, (Part.BSplineSurface, Part.BezierSurface)):
        return source
    return source.toNurbs().Faces[0]


def freecad_check(path: str, selection: FacesArg, tolerance: float, samples: int) -> dict:
    """In FreeCAD: extract every face of the part, select, and evaluate OCCT's B-spline face
    (``valueAt``) at the sample parameters of each selected face.

    Returns {"freecad": version, "face_count": n, "faces": [{"face": to_dict, "size_mm",
    "uv", "freecad_points"}]}.
    """
    try:
        return _freecad_check(path, selection, tolerance, samples)
    except FaceError as exc:
        raise _name_file(path, exc) from None


def _freecad_check(path: str, selection: FacesArg, tolerance: float, samples: int) -> dict:
    from ..app import faces as app_faces

    shape = app_faces.read_part(path)
    sources = shape.Faces
    chosen = "all" if selection == "all" else core_faces.parse_selection(
        selection, len(sources), path)
    faces, works, errors = [], [], {}
    for index, source in enumerate(sources, start=1):
        try:  # measured, never refused: check reports every face's figures
            face = app_faces.extract_face(source, index, tolerance, selected=False,
                                          chordal_tolerance=None)
            work = _work_face(source)
        except FaceError as exc:
            errors[index] = str(exc)
            face, work = None, None
        faces.append(face)
        works.append(work)
    if chosen == "all":
        chosen = list(range(1, len(sources) + 1))
    elif chosen == "up":
        reach = [app_faces.reaches_from_above(face, work) if face is not None else (False, "")
                 for face, work in zip(faces, works)]
        chosen = [i for i, (up, _) in enumerate(reach, 1) if up]
        if not chosen and not errors:
            raise FaceError(f"{path}: no face is reachable from above by a 3-axis tool")
    else:
        for number in chosen:
            if faces[number - 1] is None:
                continue
            up, why = app_faces.reaches_from_above(faces[number - 1], works[number - 1])
            if not up:
                raise FaceError(f"{path}: Face{number} is not reachable from above by a "
                                f"3-axis tool: {why}")
    records = []
    for index, (face, work, source) in enumerate(zip(faces, works, sources), start=1):
        if face is None and (index in chosen or selection == "up"):
            records.append({"index": index, "error": errors[index]})
        if face is None or index not in chosen:
            continue
        uv = core_faces.sample_points(face, samples)
        v_occt = uv[:, 1]
        if face.flipped_v:
            knots = np.asarray(face.surface.knots_v, dtype=float)
            v_occt = knots[0] + knots[-1] - v_occt
        points = [tuple(work.valueAt(float(a), float(b))) for a, b in zip(uv[:, 0], v_occt)]
        records.append({"face": core_faces.to_dict(replace(face, selected=True)),
                        "size_mm": float(source.BoundBox.DiagonalLength),
                        "model_tolerance_mm": app_faces.model_tolerance(work),
                        "uv": uv.tolist(), "freecad_points": points})
    return {"freecad": ".".join(map(str, compat.freecad_version())),
            "face_count": len(sources), "faces": records}


def evaluate_faces(faces: Sequence[dict], uvs: Sequence[Sequence[Sequence[float]]]) -> dict:
    """In cadquery's Python: each face's NURBS (``to_dict`` data) built as an OCCT
    Geom_BSplineSurface and evaluated (``Value``) at its (u, v) list."""
    import OCP

    from ..ocp.occ import nurbs_geom

    out = []
    for doc, uv in zip(faces, uvs):
        s = doc["surface"]
        weights = None if s["weights"] is None else np.asarray(s["weights"], dtype=float)
        geom = nurbs_geom(np.asarray(s["poles"], dtype=float), s["knots_u"], s["knots_v"],
                          s["degree_u"], s["degree_v"], weights=weights)
        pts = []
        for a, b in uv:
            p = geom.Value(float(a), float(b))
            pts.append((p.X(), p.Y(), p.Z()))
        out.append(pts)
    return {"points": out, "version": getattr(OCP, "__version__", "unknown")}


def handle(request: dict) -> dict:
    """A worker request of one of :data:`REQUESTS`."""
    op = request["op"]
    if op == "part_faces" and request["backend"] == "freecad":
        selection = parse_faces(request["faces"])
        found = freecad_faces(request["path"], selection, float(request["tolerance"]),
                              float(request.get("chordal_tolerance",
                                                DEFAULT_CHORDAL_TOLERANCE)))
        return {"faces": [core_faces.to_dict(face) for face in found]}
    if op == "part_check" and request["backend"] == "freecad":
        selection = parse_faces(request["faces"], allow_all=True)
        return freecad_check(request["path"], selection, float(request["tolerance"]),
                             int(request["samples"]))
    if op == "evaluate_faces" and request["backend"] == "cadquery":
        return evaluate_faces(request["faces"], request["uv"])
    raise ValueError(f"operation {op!r} is not available for backend {request['backend']!r}")


def cox_de_boor_points(face: Face, uv: np.ndarray) -> np.ndarray:
    """The face's NURBS at ``uv`` by Cox-de Boor's recursion (``core.basis``, independent of
    the matrix evaluator), rational by the weighted sum: (k, 3) mm."""
    surface = face.surface
    nu = cox_de_boor(surface.knots_u, surface.degree_u, uv[:, 0])
    nv = cox_de_boor(surface.knots_v, surface.degree_v, uv[:, 1])
    w = surface.weights if surface.weights is not None else np.ones(surface.shape)
    num = np.einsum("mi,ijc,mj->mc", nu, surface.poles * w[..., None], nv)
    den = np.einsum("mi,ij,mj->m", nu, w, nv)
    return num / den[:, None]


def check_part(path: str, faces: str | None, samples: int = PART_SAMPLES,
               tolerance: float = DEFAULT_TOLERANCE,
               chordal_tolerance: float = DEFAULT_CHORDAL_TOLERANCE) -> dict:
    """``bsplinecam check PART``: per selected face ("all" by default) its source surface,
    degrees, poles, rationality, holes, the model's tolerance there, the conversion deviation
    (mm, measured by ``app.faces`` against OCCT's original), and the largest distance of the
    core's matrix evaluator from FreeCAD's OCCT (``valueAt`` of the B-spline face), from
    cadquery's OCCT (the same NURBS built in OCP) and from Cox-de Boor's recursion at the
    sample parameters, also relative to the face's size.

    Every face is reported, a face that cannot be built with its error.  A face is
    ``machinable`` when the conversion and FreeCAD's evaluation are within
    :func:`~BSplineCAM.core.geometry.face_import.acceptance_limit` of ``chordal_tolerance`` (the rule
    that refuses faces for toolpaths); ``ok`` is the strict limit: every distance at most
    :data:`RELATIVE_TOLERANCE` of the face's size.  ``over_strict_limit`` names the faces that
    are not ``ok``."""
    selection = parse_faces(faces, allow_all=True, default="all")
    limit = acceptance_limit(chordal_tolerance)
    fc = _freecad_worker({"op": "part_check", "path": str(path),
                          "faces": _selection_text(selection), "tolerance": tolerance,
                          "samples": samples})
    built = [record for record in fc["faces"] if "error" not in record]
    docs = [record["face"] for record in built]
    uvs = [record["uv"] for record in built]
    if runtime.cadquery_in_process():
        cq = evaluate_faces(docs, uvs)
    else:
        cq = runtime.run_worker("cadquery", {"op": "evaluate_faces", "faces": docs, "uv": uvs})
    cq_points = iter(cq["points"])
    reports = []
    for record in fc["faces"]:
        if "error" in record:
            reports.append({"index": record["index"], "name": f"Face{record['index']}",
                            "error": record["error"], "machinable": False, "ok": False})
            continue
        face = core_faces.face_from_dict(record["face"], path)
        uv = np.asarray(record["uv"], dtype=float)
        ours = np.asarray(face.surface.evaluate(uv[:, 0], uv[:, 1]), dtype=float)
        size = max(float(record["size_mm"]), 1e-300)
        d_fc = float(np.linalg.norm(ours - np.asarray(record["freecad_points"]), axis=1).max())
        d_cq = float(np.linalg.norm(ours - np.asarray(next(cq_points)), axis=1).max())
        d_cdb = float(np.linalg.norm(ours - cox_de_boor_points(face, uv), axis=1).max())
        relative = max(d_fc, d_cq, d_cdb, face.deviation) / size
        surface = face.surface
        reports.append({
            "index": face.index, "name": face.name, "source": face.source,
            "degree_u": surface.degree_u, "degree_v": surface.degree_v,
            "poles": list(surface.shape), "rational": bool(surface.rational),
            "holes": len(face.holes), "flipped_v": face.flipped_v,
            "size_mm": size, "points": len(uv),
            "model_tolerance_mm": record.get("model_tolerance_mm"),
            "conversion_deviation_mm": face.deviation,
            "freecad_max_mm": d_fc, "cadquery_max_mm": d_cq, "cox_de_boor_max_mm": d_cdb,
            "relative_max": relative,
            "machinable": bool(max(face.deviation, d_fc) <= limit),
            "ok": bool(relative <= RELATIVE_TOLERANCE)})
    worst = max((r["relative_max"] for r in reports if "error" not in r), default=0.0)
    over = [r["name"] for r in reports if not r["ok"]]
    return {"part": str(path), "faces_selection": _selection_text(selection),
            "face_count": fc["face_count"], "samples": samples,
            "trim_tolerance_mm": tolerance, "relative_tolerance": RELATIVE_TOLERANCE,
            "chordal_tolerance_mm": chordal_tolerance, "acceptance_limit_mm": limit,
            "freecad": fc["freecad"], "cadquery_ocp": cq["version"],
            "faces": reports, "max_relative_deviation": worst,
            "over_strict_limit": over, "ok": not over}


# --------------------------------------------------------------------------- toolpath


def machine_faces(args: argparse.Namespace, faces: Sequence[Face], tool: ToolParameters,
                  angle: float, cutting_params: CuttingParameters) -> int:
    """``toolpath PART``: the selected faces' raster, waterline or isoparametric passes
    (``args.strategy``; multi-face certified drop-cutter, the unselected faces as check
    surfaces), posted by FreeCAD from a job whose model is the part, with one-sided arcs as
    for nets if ``--arcs on``; writes --out/NAME.ngc, toolpath.json and NAME-job.FCStd, all
    or nothing."""
    if not runtime.freecad_in_process():
        raise runtime.BackendUnavailable("toolpath on a part: run bin/bsplinecam (FreeCAD's "
                                         "Python) to post the program")
    from ..app import cam

    try:
        compat.post_module(args.post)
    except ValueError as exc:
        raise ParameterError(f"--post: {' '.join(str(exc).split())}") from None
    faceset = FaceSet(faces)
    strategy = getattr(args, "strategy", "raster")
    toolpath = generate_faces(faceset, strategy, angle=angle,
                              direction=getattr(args, "direction", "zigzag"),
                              iso_direction=getattr(args, "iso_direction", "u"),
                              where=str(args.net), names=("--strategy", "--direction"),
                              tool=tool)
    check_interrupted()
    if not toolpath.passes:
        notes = "; ".join(toolpath.stats.notes)
        raise FaceError(f"{args.net}: --strategy {strategy}: the selected faces gave no "
                        f"toolpath" + (f" ({notes})" if notes else ""))
    cutting = cam.Cutting(cutting_params.feed, cutting_params.plunge_feed,
                          cutting_params.spindle, cutting_params.rapid)
    name = _safe_name(Path(args.net).stem)
    with staged_output(Path(args.out)) as stage:
        program = stage / f"{name}.ngc"
        with captured_console():
            commands, clearance, safe = post_toolpath(
                args.net, toolpath, tool.diameter, cutting, args.post, program,
                stage / f"{name}-job.FCStd", arcs=getattr(args, "arcs", "off") == "on",
                faceset=faceset, retract_margin=(args.retract_margin if getattr(
                    args, "retract", "full") == "minimum" else None),
                stock_allowance=(args.stock_allowance if getattr(
                    args, "start_stock", "job") == "model" else None))
        check_interrupted()
        text = program.read_text()
        stats = toolpath.stats
        distances, conversion_notes = conversion_report(faces, tool.tolerance)
        report = {
            "part": str(args.net), "faces": [f.index for f in faces if f.selected],
            "check_faces": [f.index for f in faces if not f.selected],
            "strategy": toolpath.strategy, "passes": stats.passes, "moves": stats.moves,
            "commands": commands, "pass_length_mm": round(stats.cutting_length_mm, 6),
            "seconds": round(stats.seconds, 4), "unreachable": [
                getattr(r, "as_dict", lambda r=r: str(r))() for r in toolpath.unreachable],
            "notes": list(stats.notes) + conversion_notes,
            "conversion_deviation_mm": distances,
            "clearance_height_mm": clearance,
            "safe_height_mm": safe, "post": args.post, "program": program.name,
            "parameters": {"strategy": toolpath.strategy, "angle_deg": angle,
                           "direction": getattr(args, "direction", "zigzag"),
                           "iso_direction": getattr(args, "iso_direction", "u"),
                           "arcs": getattr(args, "arcs", "off"),
                           "retract": getattr(args, "retract", "full"),
                           "retract_margin_mm": getattr(args, "retract_margin", None),
                           "start_stock": getattr(args, "start_stock", "job"),
                           "stock_allowance_mm": getattr(args, "stock_allowance", None),
                           "tool_diameter_mm": tool.diameter, "scallop_mm": tool.scallop,
                           "tolerance_mm": tool.tolerance}}
        lengths = toolpath_lengths(toolpath)
        report["link_length_mm"] = round(lengths["link_length_mm"], 3)
        report.update(program_figures(text, cutting_params.rapid, lengths["along_passes_mm"]))
        if not args.no_rs274 and rs274.available():
            check = rs274.check(program, {1: tool.diameter})
            report["rs274"] = check.as_dict()
            if not check.ok:
                emit(report)
                raise BSplineCAMError(f"{program.name}: LinuxCNC's rs274 rejects the program: "
                                      f"{check.message}")
        (stage / "toolpath.json").write_text(json_text(with_engine(report)))
    emit(report)
    return 0 if report.get("rs274", {"ok": True})["ok"] else EXIT_CHECK_FAILED


def post_toolpath(path: str, toolpath: Toolpath, tool_diameter: float, cutting: Any,
                  post: str, program: Path, document: Path | None = None,
                  arcs: bool = False, faceset: Any = None,
                  retract_margin: float | None = None,
                  stock_allowance: float | None = None) -> int:
    """In FreeCAD: a document with the part (Part::Feature), a job around it with a ball-end
    tool controller, the toolpath as a path operation of that controller; posted by ``post``
    to ``program`` (and saved to ``document``), with one-sided arcs if ``arcs`` (waterline
    contours in G17 only with ``faceset``, the core FaceSet whose drop-cutter tells their free
    side); with ``retract_margin`` (mm) and ``faceset`` the tool climbs between passes only
    ``retract_margin`` over the model and the job's raw stock block, or over the model
    raised by ``stock_allowance`` (mm) when given
    (:func:`~BSplineCAM.core.toolpath.retracts.faces_hops`), else to the clearance height.
    Returns the number of path commands, the clearance and the safe height (mm) of the
    program."""
    import FreeCAD
    import Path as FreeCADPath

    from ..app import cam
    from ..app import faces as app_faces
    from ..app.finishing_op import moves_to_commands

    shape = app_faces.read_part(path)
    doc = FreeCAD.newDocument("BSplineCAMPart")
    try:
        model = doc.addObject("Part::Feature", "Part")
        model.Shape = shape
        model.Label = Path(path).stem
        doc.recompute()
        job = cam.make_job(model, tool_diameter, cutting, post=post)
        tc = job.Tools.Group[0]
        op = doc.addObject("Path::Feature", "Faces")
        op.Label = f"Faces {toolpath.strategy}"
        op.addProperty("App::PropertyLink", "ToolController", "Path", "tool controller")
        op.addProperty("App::PropertyBool", "Active", "Path", "posted when true")
        op.ToolController = tc
        op.Active = True
        # rapids stop at the safe height CAM's own ops take: the job's stock top plus the
        # setup sheet's SafeHeightOffset (the program may meet the raw stock: no rapid goes
        # below its top), the plunge feed goes on to each pass start; the clearance is at
        # least the stock top plus ClearanceHeightOffset; passes in a coordinate plane as
        # G2/G3 arcs
        stock_top = float(job.Stock.Shape.BoundBox.ZMax)
        sheet = job.SetupSheet
        clearance = max(toolpath.clearance_height,
                        stock_top + float(sheet.ClearanceHeightOffset.Value))
        safe = min(clearance, stock_top + float(sheet.SafeHeightOffset.Value))
        if faceset is not None:
            hops = None
            if retract_margin is not None:
                from ..app.retract import job_stock_map
                stock = (RaisedModel(stock_allowance) if stock_allowance is not None
                         else job_stock_map(job, op, 0.5 * tool_diameter))
                hops = faces_hops(toolpath, faceset, clearance, retract_margin, stock)
            moves = faces_program_moves(toolpath, faceset, clearance, safe, arcs=arcs,
                                        hops=hops)
        else:
            moves = program_moves(toolpath, clearance, safe, arcs=arcs)
        commands = moves_to_commands(moves, tc.HorizFeed.Value, tc.VertFeed.Value, clearance)
        op.Path = FreeCADPath.Path(commands)
        job.Operations.addObject(op)
        doc.recompute()
        cam.post_process(job, post, program)
        if document is not None:
            doc.saveAs(str(document))
        return len(commands), clearance, safe
    finally:
        FreeCAD.closeDocument(doc.Name)


__all__ = ["PART_SAMPLES", "PART_SUFFIXES", "PART_TIME_LIMIT_S", "RELATIVE_TOLERANCE", "REQUESTS",
           "check_part", "evaluate_faces", "freecad_check", "freecad_faces", "handle", "is_part",
           "load_faces", "machine_faces", "parse_faces", "part_time_limit", "post_toolpath"]
