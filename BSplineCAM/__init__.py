# SPDX-License-Identifier: LGPL-2.1-or-later
"""BSplineCAM: a cubic B-spline surface from control net to verified G-code.

The numeric core works in any Python with numpy::

    from BSplineCAM import Surface
    s = Surface.from_json("examples/case-study.json")
    s.grid(101, 101)

Inside FreeCAD, the same module makes document objects (``make_surface``), resolved lazily so
that importing BSplineCAM never imports FreeCAD by itself.
"""

from __future__ import annotations

from .core import BSplineCAMError, KnotLayout, NetError, ParameterError, Surface

__version__ = "0.1.0"

_APP_EXPORTS = {
    "make_surface": ("BSplineCAM.app.surface_feature", "make_surface"),
    "to_part": ("BSplineCAM.app.part", "to_part_surface"),
}


def __getattr__(name: str):
    """Resolve FreeCAD-dependent helpers on first use (PEP 562)."""
    if name in _APP_EXPORTS:
        import importlib

        module, attr = _APP_EXPORTS[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'BSplineCAM' has no attribute {name!r}")


__all__ = ["BSplineCAMError", "KnotLayout", "NetError", "ParameterError", "Surface", "__version__"]
