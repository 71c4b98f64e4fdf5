# SPDX-License-Identifier: LGPL-2.1-or-later
"""Icons and other files in the repository's ``resources/`` folder, found from the package.

The addon is installed by linking the repository root into FreeCAD's Mod folder, so the
folder sits beside the package; resolving it from ``__file__`` works wherever that link is.
"""

from __future__ import annotations

from pathlib import Path

#: ``resources/`` at the repository root, beside the ``BSplineCAM`` package.
RESOURCES = Path(__file__).resolve().parent.parent.parent / "resources"
ICONS = RESOURCES / "icons"


def icon(name: str) -> str:
    """Absolute path of ``resources/icons/<name>.svg`` (as FreeCAD's Pixmap wants a str)."""
    path = ICONS / f"{name}.svg"
    if not path.is_file():
        raise FileNotFoundError(f"BSplineCAM icon {name!r} missing: {path}")
    return str(path)
