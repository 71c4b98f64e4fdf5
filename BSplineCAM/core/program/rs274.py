# SPDX-License-Identifier: LGPL-2.1-or-later
"""LinuxCNC's standalone interpreter ``rs274``: the parser a real controller runs.

``rs274 -t TOOLTABLE -g FILE`` prints the canonical machine calls, or the error the machine
would stop on.  Every program BSplineCAM writes goes through it.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

#: A canonical call line: "   16 N..... STRAIGHT_FEED(10.0000, ...)".
_CANONICAL = re.compile(r"^\s*\d+\s+N[.\d]*\s+[A-Z_0-9]+\(")


@dataclass(frozen=True)
class Rs274Result:
    ok: bool
    canonical: str
    message: str
    feeds: int
    traverses: int
    arcs: int

    def as_dict(self) -> dict:
        return {"ok": self.ok, "message": self.message, "straight_feeds": self.feeds,
                "straight_traverses": self.traverses, "arc_feeds": self.arcs}


def available() -> bool:
    return shutil.which("rs274") is not None


def tool_table(tools: dict[int, float]) -> str:
    """LinuxCNC tool-table text: ``T<n> P<n> D<diameter> Z0`` per tool (mm)."""
    return "".join(f"T{n} P{n} D{d:.4f} Z0 ;BSplineCAM tool {n}\n" for n, d in sorted(tools.items()))


def _status(code: int) -> str:
    """``exit status N``, or the signal that killed rs274 (a crash, not a verdict on the program)."""
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"rs274 was killed by {name}"
    return f"exit status {code}"


def check(program: str | os.PathLike, tools: dict[int, float], timeout: float = 600.0) -> Rs274Result:
    """Run ``rs274 -g`` on a program file; ``ok`` is False if it reports any error."""
    exe = shutil.which("rs274")
    if exe is None:
        raise FileNotFoundError("rs274 (Debian package linuxcnc-uspace) is not installed")
    with tempfile.TemporaryDirectory(prefix="rs274-") as tmp:
        table = Path(tmp) / "tool.tbl"
        table.write_text(tool_table(tools))
        # rs274 maps its tool table into $HOME/.tool.mmap, truncating it first: two runs that
        # share a HOME cut each other's mapping and die of SIGBUS.  Each run gets its own.
        env = {**os.environ, "HOME": tmp}
        proc = subprocess.run([exe, "-t", str(table), "-g", str(program)], capture_output=True,
                              text=True, timeout=timeout, stdin=subprocess.DEVNULL, check=False,
                              env=env)
    out = proc.stdout
    lines = out.splitlines()
    canonical = [ln for ln in lines if _CANONICAL.match(ln)]
    # rs274 exits non-zero and prints the error and the offending block on a failure
    errors = [ln for ln in (lines + proc.stderr.splitlines())
              if ln.strip() and not _CANONICAL.match(ln) and ln.strip() != "executing"]
    ok = proc.returncode == 0
    message = "; ".join(dict.fromkeys(e.strip() for e in errors)) or ("" if ok else _status(proc.returncode))
    return Rs274Result(
        ok=ok, canonical="\n".join(canonical), message=message,
        feeds=sum("STRAIGHT_FEED(" in ln for ln in canonical),
        traverses=sum("STRAIGHT_TRAVERSE(" in ln for ln in canonical),
        arcs=sum("ARC_FEED(" in ln for ln in canonical),
    )
