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
