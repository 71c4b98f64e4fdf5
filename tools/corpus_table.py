# SPDX-License-Identifier: LGPL-2.1-or-later
"""Run every part of the corpus (tests/parts/corpus.json) through the command line and print the
markdown table of docs/parts-corpus.md: faces, degrees, the time of each command, gouge, scallop,
coverage and LinuxCNC's rs274 verdict, so the figures there are measured, not typed.

    python3 tools/corpus_table.py [--jobs N] [--timeout S] [--json FILE] [--only NAME ...]
                                  [--shared DIR]
    python3 tools/corpus_table.py --merge FILE.json ...   # the table of earlier runs

Per part: ``check PART``; ``toolpath PART --faces up --tool-diameter D --scallop H --tolerance T
--strategy raster`` and ``--strategy steep_shallow`` (H and T from the manifest); ``verify PART
PROGRAM --faces up --tool-diameter D`` on each program; ``rs274 -t TABLE -g PROGRAM`` on each.
A command that fails is shown by its exit status and the last line of its stderr.  Parts whose
origin is "shared" are read from --shared (default $BSPLINECAM_SHARED_PARTS, else
../shared/parts beside the repository) and left out when absent.  Times are wall-clock seconds
of one command on this machine; --jobs 1 (default) keeps them free of each other's load.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
BIN = ROOT / "bin" / "bsplinecam"
PARTS = ROOT / "tests" / "parts"
MANIFEST = PARTS / "corpus.json"
STRATEGIES = ("raster", "steep_shallow")
#: Seconds one command may take (--timeout).
TIMEOUT = [900.0]


def shared_dir(option: str | None = None) -> Path:
    """Folder of the parts whose origin is "shared" (not committed here)."""
    text = option or os.environ.get("BSPLINECAM_SHARED_PARTS")
    return Path(text) if text else ROOT.parent / "shared" / "parts"


def part_path(entry: dict, shared: Path) -> Path:
    """The part's file, relative to the repository when it is inside (commands run there)."""
    path = (shared if entry["origin"] == "shared" else PARTS) / entry["file"]
    return path.relative_to(ROOT) if path.is_relative_to(ROOT) else path


def run(args: list[str], timeout: float = 900.0) -> dict:
    timeout = TIMEOUT[0]
    """``bin/bsplinecam ARGS``: exit status, seconds, stdout JSON (or None), last stderr line."""
    start = time.monotonic()
    try:
        proc = subprocess.run([str(BIN), *args], capture_output=True, text=True, timeout=timeout,
                              cwd=ROOT, stdin=subprocess.DEVNULL, check=False)
    except subprocess.TimeoutExpired:
        print(f"{timeout:7.1f} s  timeout  {' '.join(args[:2])} {args[-1]}", file=sys.stderr,
              flush=True)
        return {"rc": None, "seconds": timeout, "json": None,
                "error": f"no end within {timeout:g} s"}
    seconds = time.monotonic() - start
    lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
    error = "" if proc.returncode == 0 else (lines[-1] if lines else f"exit {proc.returncode}")
    print(f"{seconds:7.1f} s  exit {proc.returncode}  {' '.join(args[:2])} {args[-1]}  "
          f"{error}", file=sys.stderr, flush=True)
    try:
        data = json.loads(proc.stdout) if proc.stdout.strip() else None
    except json.JSONDecodeError:
        data = None
    return {"rc": proc.returncode, "seconds": round(seconds, 2), "json": data, "error": error}


def measure(entry: dict, shared: Path, tool: float, work: Path) -> dict:
    """Every command of the table on one part."""
    from BSplineCAM.core.program import rs274

    path = part_path(entry, shared)
    result: dict = {"file": entry["file"], "cad": entry["cad"], "origin": entry["origin"]}
    if not (ROOT / path).is_file():
        result["missing"] = str(path)
        return result
    check = run(["check", str(path)])
    faces = (check["json"] or {}).get("faces", [])
    result["check"] = {k: check[k] for k in ("rc", "seconds", "error")}
    result["check"].update(
        face_count=(check["json"] or {}).get("face_count"),
        faces_ok=sum(bool(f.get("ok")) for f in faces),
        degrees=sorted({(f["degree_u"], f["degree_v"]) for f in faces if "degree_u" in f}),
        rational=any(f.get("rational") for f in faces),
        sources=sorted({f.get("source", "?") for f in faces}))
    stem = path.stem
    for strategy in STRATEGIES:
        out = work / f"{stem}-{strategy}"
        tp = run(["toolpath", str(path), "--faces", "up", "--tool-diameter", str(tool),
                  "--scallop", str(entry["scallop"]), "--tolerance", str(entry["tolerance"]),
                  "--strategy", strategy, "--out", str(out)])
        report = tp["json"] or {}
        row = {k: tp[k] for k in ("rc", "seconds", "error")}
        row.update(faces=report.get("faces"), passes=report.get("passes"),
                   unreachable=[u.get("depth_mm") for u in report.get("unreachable", [])],
                   rs274_in_toolpath=(report.get("rs274") or {}).get("ok"))
        ngc = out / f"{stem}.ngc"
        if tp["rc"] == 0 and ngc.is_file():
            ver = run(["verify", str(path), str(ngc), "--faces", "up", "--tool-diameter",
                       str(tool), "--out", str(out)])
            v = ver["json"] or {}
            row["verify"] = {k: ver[k] for k in ("rc", "seconds", "error")}
            row["verify"].update({k: v.get(k) for k in (
                "gouge_max_mm", "gouge_normal_max_mm", "scallop_max_mm", "scallop_p99_mm",
                "edge_scallop_max_mm", "coverage")})
            if rs274.available():
                check_rs = rs274.check(ngc, {1: tool})
                row["rs274"] = {"ok": check_rs.ok, "message": check_rs.message}
        result[strategy] = row
    return result


def fmt(value, spec: str = ".3g") -> str:
    return "—" if value is None else format(value, spec)


def cell(row: dict | None, key: str, spec: str = ".3g") -> str:
    if not row or row.get("rc") != 0:
        return "—"
    return fmt((row.get("verify") or {}).get(key), spec)


def gouge(row: dict | None) -> str:
    """The vertical gouge, and the gouge along the design's normal where verify measured
    it and it differs."""
    text = cell(row, "gouge_max_mm")
    normal = (row or {}).get("verify", {}).get("gouge_normal_max_mm")
    if text == "—" or normal is None or fmt(normal, ".3g") == text:
        return text
    return f"{text} ({fmt(normal, '.3g')} normal)"


def status(row: dict | None) -> str:
    if not row:
        return "—"
    if row["rc"] is None:
        return f"> {row['seconds']:.0f} (stopped)"
    return f"{row['seconds']:.1f}" if row["rc"] == 0 else f"refused ({row['seconds']:.1f})"


def table(results: list[dict]) -> str:
    head = ("| part | written by | faces | degrees (u,v) | rational | check s | raster s "
            "| steep_shallow s | verify s | gouge mm | scallop mm | coverage | rs274 |")
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    errors = []
    for r in results:
        if "missing" in r:
            lines.append(f"| {r['file']} | {r['cad']} | not here ({r['missing']}) |"
                         + " |" * 10)
            continue
        c = r["check"]
        degrees = " ".join(f"{u},{v}" for u, v in c["degrees"]) or "—"
        faces = "—" if c["face_count"] is None else f"{c['faces_ok']}/{c['face_count']}"
        ras, st = r.get("raster"), r.get("steep_shallow")
        ver = [x.get("verify") for x in (ras, st) if x and x.get("verify")]
        verify_s = " / ".join(f"{v['seconds']:.1f}" for v in ver) or "—"
        rs = [x.get("rs274") for x in (ras, st) if x and x.get("rs274")]
        rs_text = " / ".join("ok" if x["ok"] else "error" for x in rs) or "—"
        check_exit = "" if c["rc"] == 0 else f" (exit {c['rc']})"
        lines.append(
            f"| {r['file']} | {r['cad']} | {faces} | {degrees} | "
            f"{'yes' if c['rational'] else 'no'} | "
            f"{c['seconds']:.1f}{check_exit} | {status(ras)} | "
            f"{status(st)} | {verify_s} | {gouge(ras)} / "
            f"{gouge(st)} | {cell(ras, 'scallop_max_mm')} / "
            f"{cell(st, 'scallop_max_mm')} | {cell(ras, 'coverage', '.3f')} / "
            f"{cell(st, 'coverage', '.3f')} | {rs_text} |")
        for name, row in (("check", c), ("raster", ras), ("steep_shallow", st)):
            if row and row.get("rc") != 0:
                how = "stopped" if row["rc"] is None else f"exit {row['rc']}"
                errors.append(f"- {r['file']}, {name} ({how}): `{row['error']}`")
            ver = (row or {}).get("verify")
            if ver and ver.get("rc") != 0:
                errors.append(f"- {r['file']}, verify of {name} (exit {ver['rc']}): "
                              f"`{ver['error']}`")
    if errors:
        lines += ["", "Errors, verbatim (the last line of stderr):", "", *errors]
    return "\n".join(lines)


def machine() -> str:
    cpu = "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{os.cpu_count()} cores ({cpu}), {platform.system()} {platform.release()}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--jobs", type=int, default=1, help="parts run at once (default 1)")
    parser.add_argument("--json", help="also write the raw measurements to this file")
    parser.add_argument("--only", nargs="*", help="file names of the parts to run")
    parser.add_argument("--shared", help="folder of the parts whose origin is 'shared'")
    parser.add_argument("--merge", nargs="+", metavar="JSON",
                        help="print the table of earlier --json files instead of running")
    parser.add_argument("--timeout", type=float, default=900.0,
                        help="seconds one command may take (default 900)")
    args = parser.parse_args(argv)
    TIMEOUT[0] = args.timeout
    manifest = json.loads(MANIFEST.read_text())
    entries = [e for e in manifest["parts"] if not args.only or e["file"] in args.only]
    shared = shared_dir(args.shared)
    tool = float(manifest["tool_diameter_mm"])
    if args.merge:
        done = {}
        for name in args.merge:
            blob = json.loads(Path(name).read_text())
            done.update({r["file"]: r for r in blob["results"]})
            today, host, jobs = blob["date"], blob["machine"], blob["jobs"]
        results = [done[e["file"]] for e in entries if e["file"] in done]
    else:
        with tempfile.TemporaryDirectory(prefix="corpus-") as tmp, \
                ThreadPoolExecutor(max(1, args.jobs)) as pool:
            results = list(pool.map(lambda e: measure(e, shared, tool, Path(tmp)), entries))
        today = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
        host, jobs = machine(), args.jobs
    if args.json:
        Path(args.json).write_text(json.dumps(
            {"date": today, "machine": host, "jobs": jobs, "results": results}, indent=1))
    print(f"Measured {today} on {host}, {jobs} part(s) at a time; ball end "
          f"{tool:g} mm, `--faces up`; scallop h and tolerance per part as in "
          f"tests/parts/corpus.json. Figures are raster / steep_shallow.\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
