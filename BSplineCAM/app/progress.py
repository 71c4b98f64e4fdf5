# SPDX-License-Identifier: LGPL-2.1-or-later
"""Progress of long computations, shown by the reporter the GUI installs; cancel keeps the past.

App layer: it imports no FreeCADGui.  The GUI installs a factory of reporters
(:func:`install`, done by ``BSplineCAM.gui.progress_bar``): a reporter is a callable
``progress(fraction)`` (fraction in [0, 1]) that keeps the GUI responsive and raises the core's
:class:`ToolpathCancelled` once the user cancelled.  Headless, or before the GUI installed one,
there is no reporter (``None``), and nothing is shown.

FreeCAD's own ``Base.ProgressIndicator`` is not used: its abort asks "Do you really want to
abort?" after the op has finished, and leaves an abort flag that fails the next recompute.

An op whose computation is cancelled keeps its previous toolpath (:func:`previous_commands`)
and says so in one report-view line (:func:`report_cancelled`).
"""

from __future__ import annotations

from collections.abc import Callable

import FreeCAD

from ..core.toolpath.common import ToolpathCancelled

#: A reporter: ``progress(fraction)``; it may raise ToolpathCancelled.
Reporter = Callable[[float], None]
#: A factory of reporters: ``factory(message, obj)`` (obj: the document object computed, or None).
Factory = Callable[[str, object], Reporter]


class Reporters:
    """Where the GUI's reporter factory is kept (one per FreeCAD session, not saved)."""

    factory: Factory | None = None


def install(factory: Factory | None) -> None:
    """Make ``factory(message, obj)`` give the reporters of long computations (None: none)."""
    Reporters.factory = factory


def reporter(message: str, obj=None) -> Reporter | None:
    """A reporter for one computation, or None (headless, or no GUI reporter installed)."""
    factory = Reporters.factory
    if factory is None or not FreeCAD.GuiUp:
        return None
    return factory(message, obj)


def op_progress(obj) -> Reporter | None:
    """The reporter of an op's toolpath computation."""
    return reporter(f"{obj.Label}: computing the toolpath", obj)


class StatusProgress:
    """A reporter that is always callable (a no-op without the GUI's), with ``close()``."""

    def __init__(self, message: str, obj=None):
        self.inner = reporter(message, obj)

    def __call__(self, fraction: float) -> None:
        if self.inner is not None:
            self.inner(fraction)

    def close(self) -> None:
        close = getattr(self.inner, "close", None)
        if close is not None:
            close()


def previous_commands(obj) -> list:
    """The op's previous Path commands, to keep when its new computation is cancelled.

    CAM's ObjectOp.execute ends every non-empty path with a lone ``G0 Z<clearance>`` that it
    adds again after opExecute; it is left out here so the path comes back unchanged.
    """
    commands = list(obj.Path.Commands) if getattr(obj, "Path", None) is not None else []
    if commands and commands[-1].Name in ("G0", "G00") and \
            set(commands[-1].Parameters) == {"Z"}:
        commands.pop()
    return commands


def report_cancelled(obj, exc: ToolpathCancelled) -> None:
    """The one report-view line of a cancelled computation."""
    kept = "the previous toolpath is kept" if len(obj.Path.Commands) else "no toolpath"
    FreeCAD.Console.PrintMessage(f"{obj.Label}: {exc}; {kept}\n")
