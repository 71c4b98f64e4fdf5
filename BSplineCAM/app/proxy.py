# SPDX-License-Identifier: LGPL-2.1-or-later
"""Base of every BSplineCAM proxy (document objects and view providers).

All state lives in properties, so a proxy pickles as nothing: FreeCAD 0.20 calls
``__getstate__``/``__setstate__``, 1.0 calls ``dumps``/``loads``; both return None.
"""

from __future__ import annotations


class StatelessProxy:
    """Saves nothing and restores nothing; whatever a proxy needs it rebuilds from properties."""

    def __getstate__(self):
        return None

    def __setstate__(self, state) -> None:
        return None

    def dumps(self):
        return None

    def loads(self, state) -> None:
        return None


def add_missing_properties(obj, spec) -> list[str]:
    """Add each property of ``spec`` that ``obj`` lacks (new objects, and documents saved by an
    older version); return the names added.

    ``spec`` rows are (type, name, group, tooltip, flags, default): ``flags`` are FreeCAD's
    property status bits (1 read-only, 8 output), ``default`` None leaves FreeCAD's value (a
    list for an enumeration gives its choices).
    """
    added = []
    for kind, name, group, tip, flags, default in spec:
        if hasattr(obj, name):
            continue
        obj.addProperty(kind, name, group, tip, flags)
        if default is not None:
            setattr(obj, name, default)
        added.append(name)
    return added
