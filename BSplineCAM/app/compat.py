# SPDX-License-Identifier: LGPL-2.1-or-later
"""Every difference between FreeCAD 0.20 and 1.0 lives here, and nowhere else.

0.20 calls its machining module "Path" with Python code under ``PathScripts``; 1.0 calls it
"CAM" with the code under ``Path.Main``, ``Path.Op``, ``Path.Tool`` and ``Path.Post``.
"""

from __future__ import annotations

import glob
import importlib
import os
import sys

#: Where Debian's FreeCAD packages put FreeCAD.so, tried in order when FreeCAD is not importable.
FREECAD_LIB_DIRS = (
    "/usr/lib/freecad-python3/lib",
    "/usr/lib/freecad/lib",
    "/usr/lib/freecad-daily-python3/lib",
)


def ensure_freecad() -> object:
    """Import FreeCAD, adding Debian's library folder to sys.path from a plain python3."""
    try:
        return importlib.import_module("FreeCAD")
    except ImportError:
        pass
    extra = os.environ.get("BSPLINECAM_FREECAD_LIB")
    for folder in ([extra] if extra else []) + list(FREECAD_LIB_DIRS):
        if folder and glob.glob(os.path.join(folder, "FreeCAD*.so")):
            if folder not in sys.path:
                sys.path.append(folder)
            return importlib.import_module("FreeCAD")
    raise ImportError(
        "FreeCAD is not importable: install Debian's 'freecad' package "
        "(or set BSPLINECAM_FREECAD_LIB to the folder holding FreeCAD.so)"
    )


def freecad_version() -> tuple[int, int, int]:
    """(major, minor, patch) of the running FreeCAD."""
    fc = ensure_freecad()
    parts = list(fc.Version()[:3])
    numbers = []
    for p in parts:
        digits = "".join(ch for ch in str(p) if ch.isdigit())
        numbers.append(int(digits) if digits else 0)
    return tuple(numbers)  # type: ignore[return-value]


def is_freecad_1() -> bool:
    return freecad_version() >= (0, 22, 0)
