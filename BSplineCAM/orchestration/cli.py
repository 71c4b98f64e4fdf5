# SPDX-License-Identifier: LGPL-2.1-or-later
"""Command line: ``bin/bsplinecam {check,surface,...}``.

Runs under FreeCAD's Python (Debian's python3 with FreeCAD on its path); cadquery's OCCT is
reached through a worker in the project's virtual environment.  Input errors print one line
naming the problem and exit with status 2; nothing half-written is left in the output folder.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.util
import os
import signal
import sys
from pathlib import Path

from ..app import runtime
from ..app.crosscheck import crosscheck
from ..core import Surface
from ..core.errors import ParameterError
from ..core.geometry.netio import write_dat
from . import parts
from .cli_common import (  # noqa: F401  (re-exported: the command line's helpers, for callers of cli)
    DAT_SAMPLES,
    DAT_SAMPLES_RANGE,
    EXIT_CHECK_FAILED,
    EXIT_INPUT_ERROR,
    EXIT_INTERNAL_ERROR,
    NET_SAMPLES,
    SAMPLES_RANGE,
    Interrupted,
    OneLineParser,
    OutputError,
    _exit_status,
    _one_line,
    _safe_name,
    _Signals,
    captured_console,
    check_int,
    check_interrupted,
    check_output,
    emit,
    flush_all,
    json_text,
    signal_handlers,
    staged_output,
    strict,
    with_engine,
)
from .worker import handle


def _load(path: str, knots: str | None) -> Surface:
    return Surface.from_file(path, knots)


def cmd_check(args: argparse.Namespace) -> int:
    if parts.is_part(args.net):
        return cmd_check_part(args)
    for option, value in (("--faces", args.faces), ("--out", args.out)):
        if value is not None:
            raise ParameterError(f"{option} applies to parts ({', '.join(parts.PART_SUFFIXES)}),"
                                 f" not to the control net {args.net}")
    if args.samples is None:
        args.samples = NET_SAMPLES
    check_int(args.samples, "--samples", *SAMPLES_RANGE)
    surface = _load(args.net, args.knots)
    report = crosscheck(surface, samples=args.samples, paper_route=not args.no_paper_route)
    check_interrupted()
    emit(report)
    return 0 if report["exact_route_ok"] else EXIT_CHECK_FAILED


def cmd_check_part(args: argparse.Namespace) -> int:
    """``check PART``: each selected face's conversion and evaluation cross-checked (see
    :func:`BSplineCAM.orchestration.parts.check_part`); JSON on stdout and in --out/check.json;
    exit 1 if a face exceeds the tolerance."""
    for option, value in (("--knots", args.knots), ("--no-paper-route", args.no_paper_route)):
        if value:
            raise ParameterError(f"{option} applies to control nets, not to the part {args.net}")
    samples = check_int(parts.PART_SAMPLES if args.samples is None else args.samples,
                        "--samples", *SAMPLES_RANGE)
    if args.out is not None:
        check_output(args.out)
    report = parts.check_part(args.net, args.faces, samples)
    check_interrupted()
    if args.out is not None:
        with staged_output(Path(args.out)) as stage:
            (stage / "check.json").write_text(json_text(with_engine(report)))
    emit(report)
    if not report["ok"]:
        print(f"bsplinecam check: {args.net}: over the strict limit "
              f"({report['relative_tolerance']:g} of the face's size, or not built): "
              f"{', '.join(report['over_strict_limit'])}", file=sys.stderr)
    return 0 if report["ok"] else EXIT_CHECK_FAILED


def cmd_surface(args: argparse.Namespace) -> int:
    """NAME.dat, NAME.step, NAME.brep, NAME.FCStd and crosscheck.json in --out."""
    check_int(args.samples, "--samples", *SAMPLES_RANGE)
    check_int(args.dat_samples, "--dat-samples", *DAT_SAMPLES_RANGE)
    check_output(args.out)
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
        (stage / "crosscheck.json").write_text(json_text(with_engine(report)))
    emit({"out": str(Path(args.out).resolve()), "files": sorted(
        f"{name}.{s}" for s in ("dat", "step", "brep", "FCStd")) + ["crosscheck.json"],
        "exact_route_ok": report["exact_route_ok"],
        "max_deviation_mm": report["max_deviation_mm"],
        "paper_route_max_deviation_mm": report.get("paper_route", {}).get("max_deviation_mm")})
    return 0 if report["exact_route_ok"] else EXIT_CHECK_FAILED


def _freecad_call(request: dict, surface: Surface) -> dict:
    """Run a FreeCAD request here when FreeCAD is importable, else in FreeCAD's Python."""
    if runtime.freecad_in_process():
        with captured_console():
            reply = handle({**request, "backend": "freecad"})
        check_interrupted()
        return reply
    return runtime.run_worker("freecad", request)


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(prog="bsplinecam", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)

    def add_net(p: argparse.ArgumentParser) -> None:
        p.add_argument("net", help="control net: .json (canonical), .csv or .dat")
        p.add_argument("--knots", choices=["uniform", "clamped"], help="override the file's knot layout")

    p = sub.add_parser("check", help="cross-check the matrix evaluator against Cox–de Boor and OCCT"
                       " (a net), or each face's conversion and evaluation (a part)")
    add_net(p)
    p.add_argument("--samples", type=int, default=None,
                   help=f"grid samples per direction (default {NET_SAMPLES} for a net, "
                        "31 per face of a part)")
    p.add_argument("--no-paper-route", action="store_true", help="skip measuring the paper's loft route")
    p.add_argument("--faces", default=None,
                   help="faces of a part: all (default), up, or numbers such as 3,8,20")
    p.add_argument("--out", default=None, help="also write DIR/check.json (parts only)")
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
STAGE_COMMANDS = [m for m in ("BSplineCAM.orchestration.cli_toolpath", "BSplineCAM.orchestration.cli_verify",
                                "BSplineCAM.orchestration.cli_job")
                  if importlib.util.find_spec(m) is not None]


def main(argv: list[str] | None = None) -> int:
    """Run one command; bad input, an unwritable output, an interruption or an unexpected
    failure each end in one line on stderr (no traceback) and an exit status."""
    parser = build_parser()
    with signal_handlers():
        try:
            args = parser.parse_args(argv)
        except Interrupted as exc:
            return 128 + exc.signum
        prog = f"bsplinecam {args.command}"
        try:
            status = int(args.func(args))
            check_interrupted()
            return status
        except Interrupted as exc:
            name = signal.Signals(exc.signum).name
            print(f"{prog}: interrupted by {name}; nothing was written", file=sys.stderr)
            return 128 + exc.signum
        except Exception as exc:  # every failure ends in one line (BSPLINECAM_TRACEBACK=1: all)
            if _Signals.received is not None:  # FreeCAD turned the signal into another error
                name = signal.Signals(_Signals.received).name
                print(f"{prog}: interrupted by {name}; nothing was written", file=sys.stderr)
                return 128 + _Signals.received
            if os.environ.get("BSPLINECAM_TRACEBACK") == "1":
                import traceback

                traceback.print_exc()
            print(f"{prog}: error: {_one_line(exc)}", file=sys.stderr)
            return _exit_status(exc)


if __name__ == "__main__":
    # run the imported module's main, not this __main__ copy, so that there is one module
    # object (tests and callers patch BSplineCAM.orchestration.cli; the signal state itself
    # lives in cli_common)
    from BSplineCAM.orchestration import cli as _cli

    sys.exit(_cli.main())
