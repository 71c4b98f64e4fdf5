#!/usr/bin/env python3
# SPDX-License-Identifier: LGPL-2.1-or-later
"""Proves that a change of structure leaves every program the same, line for line.

The cases are the benchmark nets (case study, dome, saddle, waves) with every finishing
strategy and a roughing job, examples/part.step with every strategy (the constant scallop's
at 0.2 mm) and a job, and the parts of
tests/parts whose toolpath the corpus expects to build within a minute.  Each case runs
``bin/bsplinecam`` and keeps its G-code programs (``*.ngc``); the post's own time stamp is the
only line left out of the comparison.

    tools/program_identity.py write DIR             # this tree's programs into DIR
    tools/program_identity.py compare OLD NEW       # exit 1 naming the first differing line
    tools/program_identity.py check [--ref REF]     # REF (default HEAD) in a git worktree
                                                    # against this tree, both written afresh
    tools/program_identity.py list                  # the case names

``--only NAME[,NAME]`` limits write and check to some cases (substring match) and ``--jobs N``
runs N cases at a time (default 2).  Exit status: 0 identical, 1 a difference, 2 a case failed.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

#: name -> (net points per side, footprint side mm, z(u, w) in numpy syntax on [0, 1]^2); the
#: benchmark's nets (benchmarks/toolpath.py SURFACES).
NETS = {
    "dome": (9, 60.0, "10 + 40 * np.exp(-((u - 0.5) ** 2 + (w - 0.5) ** 2) / 0.05)"),
    "saddle": (8, 80.0, "20 + 30 * (u - 0.5) ** 2 - 30 * (w - 0.5) ** 2"),
    "waves": (14, 100.0, "15 + 4 * np.sin(6 * u) * np.cos(5 * w) + 3 * u"),
}

STRATEGIES = ("raster", "waterline", "isoparametric", "steep_shallow")


def write_nets(folder: Path) -> dict[str, Path]:
    """The benchmark nets as JSON files in ``folder`` (numpy only, no project code)."""
    import numpy as np

    paths = {"case-study": ROOT / "examples" / "case-study.json"}
    for name, (n, size, expr) in NETS.items():
        x, y = np.meshgrid(np.linspace(0, size, n), np.linspace(0, size, n), indexing="ij")
        u, w = x / size, y / size  # noqa: F841 (used by eval)
        z = eval(expr, {"np": np, "u": u, "w": w})  # constant expressions above
        points = np.stack([x, y, z], axis=-1).tolist()
        path = folder / f"{name}.json"
        path.write_text(json.dumps({"name": name, "units": "mm", "knots": "clamped",
                                    "control_points": points}))
        paths[name] = path
    return paths


def cases(nets: dict[str, Path]) -> dict[str, list[str]]:
    """Case name -> bin/bsplinecam arguments (without --out)."""
    out: dict[str, list[str]] = {}
    for name, path in nets.items():
        for strategy in STRATEGIES:
            scallop = "0.02" if strategy in ("raster", "isoparametric") else "0.05"
            out[f"net-{name}-{strategy}"] = [
                "toolpath", str(path), "--tool-diameter", "6", "--scallop", scallop,
                "--strategy", strategy, "--no-rs274"]
    out["net-case-study-job"] = [
        "job", str(nets["case-study"]), "--rough", "flat:10", "--finish", "ball:6",
        "--scallop", "0.05", "--no-rs274"]
    part = str(ROOT / "examples" / "part.step")
    for strategy in STRATEGIES:
        out[f"part-{strategy}"] = ["toolpath", part, "--tool-diameter", "6", "--scallop", "0.05",
                                   "--strategy", strategy, "--no-rs274"]
    out["part-scallop"] = ["toolpath", part, "--tool-diameter", "6", "--scallop", "0.2",
                           "--strategy", "scallop", "--no-rs274"]
    out["part-job"] = ["job", part, "--rough", "flat:10", "--finish", "ball:6",
                       "--scallop", "0.1", "--no-rs274"]
    corpus = json.loads((ROOT / "tests" / "parts" / "corpus.json").read_text())
    for entry in corpus["parts"]:
        expect = entry.get("expect", {})
        if "toolpath" in expect or "raster" in entry.get("slow", {}):
            continue
        file = ROOT / "tests" / "parts" / entry["file"]
        if not file.exists():
            continue
        out[f"corpus-{Path(entry['file']).stem}"] = [
            "toolpath", str(file), "--tool-diameter", str(corpus.get("tool_diameter_mm", 6.0)),
            "--scallop", str(entry.get("scallop", 0.1)),
            "--tolerance", str(entry.get("tolerance", 0.002)), "--no-rs274"]
    return out


#: Lines a post writes from the clock, not from the toolpath.
VOLATILE = re.compile(r"\((Output Time|Exported by|Post Processor:.*time)[^)]*\)|"
                      r"\d{4}-\d{2}-\d{2}[ T]\d{2}:\d{2}", re.IGNORECASE)


def program_lines(path: Path) -> list[str]:
    return [line for line in path.read_text().splitlines() if not VOLATILE.search(line)]


def run_case(tree: Path, name: str, argv: list[str], dest: Path) -> tuple[str, str | None]:
    """Runs one case in ``tree`` and copies its programs to dest/name/; (name, error or None)."""
    with tempfile.TemporaryDirectory(prefix="identity-") as tmp:
        out = Path(tmp) / "out"
        proc = subprocess.run([str(tree / "bin" / "bsplinecam"), *argv, "--out", str(out)],
                              cwd=tree, capture_output=True, text=True)
        programs = sorted(out.glob("*.ngc")) if out.exists() else []
        if not programs:
            tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            return name, f"exit {proc.returncode}, no program: {tail}"
        target = dest / name
        target.mkdir(parents=True, exist_ok=True)
        for program in programs:
            shutil.copy(program, target / program.name)
        (target / "exit-status").write_text(f"{proc.returncode}\n")
    return name, None


def write(tree: Path, dest: Path, only: list[str], jobs: int) -> int:
    dest.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="identity-nets-") as tmp:
        selected = {k: v for k, v in cases(write_nets(Path(tmp))).items()
                    if not only or any(o in k for o in only)}
        # the tree's own paths: cases name files under ROOT, rewritten to the tree's copy
        selected = {k: [a.replace(str(ROOT), str(tree)) if a.startswith(str(ROOT)) else a
                        for a in v] for k, v in selected.items()}
        failed = 0
        with concurrent.futures.ThreadPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(run_case, tree, k, v, dest) for k, v in selected.items()]
            for future in concurrent.futures.as_completed(futures):
                name, error = future.result()
                print(f"{name}: {error or 'ok'}", flush=True)
                failed += error is not None
    return 2 if failed else 0


def compare(old: Path, new: Path) -> int:
    names = sorted({p.name for p in old.iterdir()} | {p.name for p in new.iterdir()})
    differ = 0
    for name in names:
        a, b = old / name, new / name
        if not a.exists() or not b.exists():
            print(f"{name}: only in {'new' if b.exists() else 'old'}")
            differ += 1
            continue
        files = sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()})
        for file in files:
            fa, fb = a / file, b / file
            if not fa.exists() or not fb.exists():
                print(f"{name}/{file}: only in {'new' if fb.exists() else 'old'}")
                differ += 1
                continue
            la, lb = program_lines(fa), program_lines(fb)
            if la != lb:
                line = next((i for i, (x, y) in enumerate(zip(la, lb)) if x != y),
                            min(len(la), len(lb)))
                print(f"{name}/{file}: line {line + 1} differs: "
                      f"{la[line] if line < len(la) else '<end>'!r} -> "
                      f"{lb[line] if line < len(lb) else '<end>'!r} ({len(la)} vs {len(lb)} lines)")
                differ += 1
    print(f"{len(names)} cases compared, {differ} differ")
    return 1 if differ else 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    for name in ("write", "check"):
        p = sub.add_parser(name)
        if name == "write":
            p.add_argument("dest")
        else:
            p.add_argument("--ref", default="HEAD")
            p.add_argument("--keep", help="keep both program sets in this folder")
        p.add_argument("--only", default="")
        p.add_argument("--jobs", type=int, default=2)
    p = sub.add_parser("compare")
    p.add_argument("old")
    p.add_argument("new")
    sub.add_parser("list")
    args = parser.parse_args(argv)
    if args.cmd == "list":
        with tempfile.TemporaryDirectory() as tmp:
            for name, case in cases(write_nets(Path(tmp))).items():
                print(name, " ".join(case))
        return 0
    if args.cmd == "compare":
        return compare(Path(args.old), Path(args.new))
    only = [o for o in args.only.split(",") if o]
    if args.cmd == "write":
        return write(ROOT, Path(args.dest), only, args.jobs)
    keep = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="identity-"))
    worktree = keep / "ref-tree"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(worktree),
                    args.ref], check=True, capture_output=True)
    try:
        status = write(worktree, keep / "old", only, args.jobs)
        status = max(status, write(ROOT, keep / "new", only, args.jobs))
        if status:
            print("a case failed; programs kept in", keep)
            return status
        return compare(keep / "old", keep / "new")
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(worktree)],
                       capture_output=True)
        if not args.keep:
            shutil.rmtree(keep, ignore_errors=True)


if __name__ == "__main__":
    os.environ.setdefault("PYTHONDONTWRITEBYTECODE", "1")
    sys.exit(main())
