#!/usr/bin/env python3
# SPDX-License-Identifier: LGPL-2.1-or-later
"""Link this repository into the Mod folder that a FreeCAD reads, as the Addon Manager would.

FreeCAD 0.20 and 1.0 read ``~/.local/share/FreeCAD/Mod``; FreeCAD 1.1 reads a versioned user
folder (``~/.local/share/FreeCAD/v1-1/Mod``).  So FreeCAD itself is asked where its user data
folder is (``FreeCAD.getUserAppDataDir()``), never guessed.

A ``Mod/BSplineCAM`` that already links here is left alone; a link elsewhere (another
checkout) is replaced, which deletes no file.  A real folder there (an addon installed by the
Addon Manager, or a copy) is never deleted: it is moved aside, out of ``Mod`` so that FreeCAD
does not load two workbenches, to ``<user data>/BSplineCAM.moved-<time>``, and the message
says where.

Usage:
  tools/install_addon.py [--freecadcmd CMD] [--user-data DIR]
      CMD: FreeCAD's command-line binary to ask (default: freecadcmd), split on spaces;
      DIR: the user data folder, when it is known already (then FreeCAD is not asked).
Prints the link it made or found; exit status 2 with one line on stderr when FreeCAD is
missing or gives no answer.  Standard library only: it runs in any Debian python3.
"""

from __future__ import annotations

import argparse
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
NAME = "BSplineCAM"
_MARK = "@@BSPLINECAM-USER-DATA@@"


class InstallError(RuntimeError):
    """What went wrong, in one line for the user."""


def ask_user_data_dir(freecadcmd: list[str], timeout: float = 300.0) -> Path:
    """FreeCAD's user data folder, as that FreeCAD reports it."""
    code = f"import FreeCAD, sys; sys.stdout.write('{_MARK}' + FreeCAD.getUserAppDataDir() + '{_MARK}\\n')"
    try:
        proc = subprocess.run(freecadcmd + ["-c", code], capture_output=True, text=True,
                              timeout=timeout, check=False)
    except FileNotFoundError as exc:
        raise InstallError(f"{freecadcmd[0]} not found: install FreeCAD first (Debian: apt-get "
                           "install freecad), or name its command with --freecadcmd") from exc
    except subprocess.TimeoutExpired as exc:
        raise InstallError(f"{' '.join(freecadcmd)} did not answer within {timeout:g} s") from exc
    parts = proc.stdout.split(_MARK)
    if len(parts) < 3 or not parts[1].strip():
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-1:] or ["no output"]
        raise InstallError(f"{' '.join(freecadcmd)} did not report its user data folder "
                           f"(exit {proc.returncode}): {tail[0]}")
    return Path(parts[1].strip())


def install(user_data: Path, repo: Path = REPO, now: float | None = None) -> str:
    """Make ``user_data/Mod/BSplineCAM`` a link to ``repo``; return what was done, in words."""
    mod = user_data / "Mod"
    mod.mkdir(parents=True, exist_ok=True)
    target = mod / NAME
    repo = repo.resolve()
    if target.is_symlink():
        if target.resolve() == repo:
            return f"{target} already links to {repo}"
        old = os.readlink(target)
        target.unlink()  # a link only: the files it pointed to stay where they are
        target.symlink_to(repo)
        return f"{target} linked to {repo} (it linked to {old})"
    if target.exists():
        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(now))
        aside = user_data / f"{NAME}.moved-{stamp}"
        n = 1
        while aside.exists():
            n += 1
            aside = user_data / f"{NAME}.moved-{stamp}-{n}"
        target.rename(aside)
        target.symlink_to(repo)
        return (f"{target} linked to {repo}; the {NAME} folder that was there (an Addon Manager "
                f"install?) was moved, not deleted, to {aside}: move it back to restore it")
    target.symlink_to(repo)
    return f"{target} linked to {repo}"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--freecadcmd", default="freecadcmd")
    parser.add_argument("--user-data", type=Path)
    args = parser.parse_args(argv)
    try:
        user_data = args.user_data or ask_user_data_dir(shlex.split(args.freecadcmd))
        print(install(user_data))
    except (InstallError, OSError) as exc:
        print(f"install_addon: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
