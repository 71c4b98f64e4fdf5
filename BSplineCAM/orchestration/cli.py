# SPDX-License-Identifier: LGPL-2.1-or-later
"""Command line: ``bin/bsplinecam {check,surface,...}``.

Runs under FreeCAD's Python (Debian's python3 with FreeCAD on its path); cadquery's OCCT is
reached through a worker in the project's virtual environment.  Input errors print one line
naming the problem and exit with status 2; nothing half-written is left in the output folder.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import importlib.util
import json
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ..core import BSplineCAMError, Surface
from ..core.netio import write_dat
from . import runtime

EXIT_INPUT_ERROR = 2
EXIT_CHECK_FAILED = 1
DAT_SAMPLES = 51


@contextlib.contextmanager
def staged_output(out_dir: Path) -> Iterator[Path]:
    """A staging folder inside ``out_dir`` whose files are moved in only if all succeeded."""
    out_dir.mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(prefix=".staging-", dir=out_dir))
    try:
        yield stage
        for item in stage.iterdir():
            os.replace(item, out_dir / item.name)
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def emit(result: dict) -> None:
    """Print a command's JSON result on stdout (descriptor BSPLINECAM_RESULT_FD when set, so
    FreeCAD's own console output cannot mix into it)."""
    text = json.dumps(result, indent=1) + "\n"
    fd = os.environ.get("BSPLINECAM_RESULT_FD")
    if fd:
        os.write(int(fd), text.encode())
    else:
        sys.stdout.write(text)
        sys.stdout.flush()


def _load(path: str, knots: str | None) -> Surface:
    return Surface.from_file(path, knots)


def cmd_check(args: argparse.Namespace) -> int:
    from .crosscheck import crosscheck

    surface = _load(args.net, args.knots)
    report = crosscheck(surface, samples=args.samples, paper_route=not args.no_paper_route)
    emit(report)
    return 0 if report["exact_route_ok"] else EXIT_CHECK_FAILED


def cmd_surface(args: argparse.Namespace) -> int:
    """NAME.dat, NAME.step, NAME.brep, NAME.FCStd and crosscheck.json in --out."""
    from .crosscheck import crosscheck

    surface = _load(args.net, args.knots)
    name = _safe_name(surface.name)
    with staged_output(Path(args.out)) as stage:
        write_dat(surface.grid(args.dat_samples, args.dat_samples), stage / f"{name}.dat",
                  comment=f"BSplineCAM sampled points of {surface.name} ({surface.knots.value} knots)")
        request = {"net": surface.to_net().to_json_dict()}
        for suffix in ("step", "brep"):
            _freecad_call({"op": "export", "path": str(stage / f"{name}.{suffix}"), **request}, surface)
        _freecad_call({"op": "save_document", "path": str(stage / f"{name}.FCStd"), "solid": True, **request}, surface)
        report = crosscheck(surface, samples=args.samples)
        (stage / "crosscheck.json").write_text(json.dumps(report, indent=1) + "\n")
    emit({"out": str(Path(args.out).resolve()), "files": sorted(
        f"{name}.{s}" for s in ("dat", "step", "brep", "FCStd")) + ["crosscheck.json"],
        "exact_route_ok": report["exact_route_ok"],
        "max_deviation_mm": report["max_deviation_mm"],
        "paper_route_max_deviation_mm": report.get("paper_route", {}).get("max_deviation_mm")})
    return 0 if report["exact_route_ok"] else EXIT_CHECK_FAILED


def _freecad_call(request: dict, surface: Surface) -> dict:
    """Run a FreeCAD request here when FreeCAD is importable, else in FreeCAD's Python."""
    if runtime.freecad_in_process():
        from .worker import handle

        return handle({**request, "backend": "freecad"})
    return runtime.run_worker("freecad", request)


def _safe_name(name: str) -> str:
    clean = "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in name).strip("._")
    return clean or "surface"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bsplinecam", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    def add_net(p: argparse.ArgumentParser) -> None:
        p.add_argument("net", help="control net: .json (canonical), .csv or .dat")
        p.add_argument("--knots", choices=["uniform", "clamped"], help="override the file's knot layout")

    p = sub.add_parser("check", help="cross-check the matrix evaluator against Cox–de Boor and OCCT")
    add_net(p)
    p.add_argument("--samples", type=int, default=101, help="grid samples per direction (default 101)")
    p.add_argument("--no-paper-route", action="store_true", help="skip measuring the paper's loft route")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("surface", help="export .dat, STEP, BREP, FCStd and the cross-check")
    add_net(p)
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--samples", type=int, default=101, help="cross-check grid samples per direction")
    p.add_argument("--dat-samples", type=int, default=DAT_SAMPLES, help="points per side in NAME.dat")
    p.set_defaults(func=cmd_surface)

    for module in STAGE_COMMANDS:
        importlib.import_module(module).register(sub)
    return parser


#: Modules of later stages; each has ``register(subparsers)`` adding its subcommand.
STAGE_COMMANDS = [m for m in ("BSplineCAM.orchestration.cli_toolpath", "BSplineCAM.orchestration.cli_verify")
                  if importlib.util.find_spec(m) is not None]


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args))
    except BSplineCAMError as exc:
        print(f"bsplinecam {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT_ERROR
    except runtime.BackendUnavailable as exc:
        print(f"bsplinecam {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INPUT_ERROR


if __name__ == "__main__":
    sys.exit(main())
