# SPDX-License-Identifier: LGPL-2.1-or-later
"""Progress of long computations in the status bar, with a Cancel button and Esc.

The app layer asks :mod:`BSplineCAM.app.progress` for a reporter; this module installs the
factory (on import).  A :class:`ProgressBar` is the reporter: the core calls it with the
fraction done, and at most every ``INTERVAL`` seconds it updates a QProgressBar in FreeCAD's
status bar and lets Qt process events, so the GUI repaints and timers fire while the work
goes on.  Cancel (the button or Esc) sets a flag; the next call raises the core's
:class:`ToolpathCancelled`, which the op turns into "keep the previous toolpath".

While it runs, an application event filter takes Esc and clicks on Cancel, and drops other
keyboard and mouse input (as FreeCAD's own progress bar does), so no command starts in the
middle of a recompute.  FreeCAD's sequencer is not used: its abort would ask "Do you really
want to abort?" after the computation and fail the next recompute.
"""

from __future__ import annotations

import contextlib
import threading
import time

import FreeCAD
import FreeCADGui
from PySide import QtCore, QtGui

from ..app import progress as app_progress
from ..core import kernels
from ..core.toolpath.common import ToolpathCancelled

#: Longest time between two looks at the event queue (s).
INTERVAL = 0.05
#: Steps of the progress bar.
STEPS = 1000
#: Input dropped while a computation runs (Esc and the Cancel button excepted).
BLOCKED = {
    QtCore.QEvent.KeyPress, QtCore.QEvent.KeyRelease, QtCore.QEvent.MouseButtonPress,
    QtCore.QEvent.MouseButtonRelease, QtCore.QEvent.MouseButtonDblClick, QtCore.QEvent.Wheel,
    QtCore.QEvent.ContextMenu, QtCore.QEvent.Shortcut, QtCore.QEvent.ShortcutOverride,
}
#: A filter left behind by a reporter that was never closed lets input through after this (s).
STALE = 2.0


class StatusWidgets:
    """The bar and the Cancel button, made once and kept in FreeCAD's status bar."""

    bar: QtGui.QProgressBar | None = None
    button: QtGui.QPushButton | None = None
    label: QtGui.QLabel | None = None

    @classmethod
    def get(cls) -> tuple[QtGui.QLabel, QtGui.QProgressBar, QtGui.QPushButton]:
        alive = cls.bar is not None
        if alive:
            try:
                cls.bar.objectName()
            except RuntimeError:  # deleted with a main window
                alive = False
        if not alive:
            status = FreeCADGui.getMainWindow().statusBar()
            cls.label = QtGui.QLabel()
            cls.bar = QtGui.QProgressBar()
            cls.bar.setObjectName("BSplineCAM_progress")
            cls.bar.setRange(0, STEPS)
            cls.bar.setMaximumWidth(220)
            cls.bar.setTextVisible(True)
            cls.button = QtGui.QPushButton("Cancel")
            cls.button.setObjectName("BSplineCAM_cancel")
            cls.button.clicked.connect(cancel_active)
            cls.button.setToolTip("Stop the computation (Esc); the object keeps its previous "
                                  "result")
            for widget in (cls.label, cls.bar, cls.button):
                status.addPermanentWidget(widget)
                widget.hide()
        return cls.label, cls.bar, cls.button


class InputFilter(QtCore.QObject):
    """Esc and clicks on Cancel cancel; other input is dropped while the computation runs;
    another progress bar the status bar shows meanwhile (FreeCAD's recompute bar, shown late
    by its own timer) is hidden as it shows, before it is painted."""

    def __init__(self, owner: ProgressBar):
        super().__init__()
        self.owner = owner

    def eventFilter(self, watched, event) -> bool:  # noqa: N802 - Qt API
        kind = event.type()
        if kind == QtCore.QEvent.Show:
            if (self.owner.open and isinstance(watched, QtGui.QProgressBar)
                    and watched is not StatusWidgets.bar and _in_status_bar(watched)):
                watched.hide()
            return False
        if kind not in BLOCKED:
            return False
        owner = self.owner
        if time.monotonic() - owner.last_call > STALE:  # never closed: let the user work
            owner.close()
            return False
        if kind == QtCore.QEvent.KeyPress and event.key() == QtCore.Qt.Key_Escape:
            owner.cancel()
            return True
        if watched == owner.button and kind in (QtCore.QEvent.MouseButtonPress,
                                                QtCore.QEvent.MouseButtonRelease):
            if kind == QtCore.QEvent.MouseButtonRelease:
                owner.cancel()
            return True
        return True


class ProgressBar:
    """A reporter (``progress(fraction)``) shown in the status bar; Cancel and Esc stop it."""

    #: The reporter now running (None between computations) and the last one (for tests and
    #: for :func:`cancelled`); not saved.
    active: ProgressBar | None = None
    last: ProgressBar | None = None

    def __init__(self, message: str, obj=None):
        self.message = message
        self.target = (obj.Document.Name, obj.Name) if obj is not None else None
        self.fraction = 0.0
        self.cancelled = False
        self.open = True
        self.events = 0  # times the event queue was processed
        self.calls = 0
        self.calls_at_cancel = 0
        self.noted = False
        self.last_call = self.last_events = time.monotonic()
        previous = ProgressBar.active  # one bar at a time (the widgets are shared)
        if previous is not None:
            previous.close()
        self.label, self.bar, self.button = StatusWidgets.get()
        self.label.setText(message)
        self.bar.setValue(0)
        self.bar.setFormat("%p %")
        for widget in (self.label, self.bar, self.button):
            widget.show()
        self.filter = InputFilter(self)
        QtGui.QApplication.instance().installEventFilter(self.filter)
        ProgressBar.active = ProgressBar.last = self
        # closes the bar once the reports stop (a computation that failed before its end)
        self.watchdog = QtCore.QTimer()
        self.watchdog.setSingleShot(True)
        self.watchdog.timeout.connect(self._check_stale)
        self.watchdog.start(int(1000 * STALE))
        self._process()

    def __call__(self, fraction: float) -> None:
        self.calls += 1
        if self.cancelled:
            self._stop()
        if not self.open:  # done (or closed from outside): no more events, input is let through
            return
        self.fraction = min(max(float(fraction), self.fraction), 1.0)
        if self.noted:
            self.label.setText(self.message)
            self.noted = False
        self.last_call = now = time.monotonic()
        if now - self.last_events >= INTERVAL or self.fraction >= 1.0:
            self._process()
        if self.cancelled:
            self._stop()
        if self.fraction >= 1.0:
            self.close()

    def note(self, text: str) -> None:
        """Show ``text`` beside the message until the next report (a kernel compiling on its
        first use: the bar stands still meanwhile).  Never raises: a Cancel clicked now stops
        the computation at its next report."""
        if not self.open:
            return
        self.label.setText(f"{self.message} ({text})")
        self.noted = True
        hide_other_bars()
        QtGui.QApplication.processEvents()
        self.events += 1

    def _process(self) -> None:
        if self.open:
            self.bar.setValue(int(round(self.fraction * STEPS)))
            hide_other_bars()
        QtGui.QApplication.processEvents()
        self.events += 1
        self.last_events = self.last_call = time.monotonic()

    def _check_stale(self) -> None:
        if not self.open:
            return
        if time.monotonic() - self.last_call > STALE:
            self.close()
        else:
            self.watchdog.start(int(1000 * STALE))

    def _stop(self) -> None:
        done = 100 * self.fraction
        self.close()
        raise ToolpathCancelled(f"cancelled by the user at {done:.0f} % of the work")

    def cancel(self) -> None:
        """Stop at the next call (the Cancel button, Esc, or a script)."""
        if self.open and not self.cancelled:
            self.cancelled = True
            self.calls_at_cancel = self.calls
            self.bar.setFormat("cancelling...")

    def close(self) -> None:
        """Hide the bar, let input through; a cancelled object is marked for recompute again."""
        if not self.open:
            return
        self.open = False
        self.watchdog.stop()
        QtGui.QApplication.instance().removeEventFilter(self.filter)
        for widget in (self.label, self.bar, self.button):
            widget.hide()
        if ProgressBar.active is self:
            ProgressBar.active = None
        if self.cancelled and self.target is not None:
            # after the recompute ends: the object still needs one, as before it started
            QtCore.QTimer.singleShot(0, self._touch_target)

    def _touch_target(self) -> None:
        doc_name, name = self.target
        doc = FreeCAD.listDocuments().get(doc_name)
        if doc is not None and getattr(doc, "Recomputing", False):
            # touched within the recompute, the op would be computed again at once
            QtCore.QTimer.singleShot(50, self._touch_target)
            return
        obj = doc.getObject(name) if doc is not None else None
        if obj is not None:
            obj.touch()

    def __del__(self):
        with contextlib.suppress(RuntimeError, AttributeError):  # Qt already gone at exit
            self.close()


def _in_status_bar(widget) -> bool:
    """Whether ``widget`` lies in the main window's status bar."""
    return FreeCADGui.getMainWindow().statusBar().isAncestorOf(widget)


def other_bars() -> list:
    """The status bar's visible progress bars other than ours (FreeCAD's "Recompute...")."""
    ours = StatusWidgets.bar
    status = FreeCADGui.getMainWindow().statusBar()
    return [w for w in status.findChildren(QtGui.QProgressBar)
            if w is not ours and w.isVisible()]


def hide_other_bars() -> None:
    """One progress bar while ours runs: FreeCAD's recompute bar says less (the document, not
    the op's work) and cannot cancel it; its sequencer shows it again at its next start."""
    for widget in other_bars():
        widget.hide()


def cancelled(obj) -> bool:
    """Whether the last computation of ``obj`` was cancelled by the user."""
    last = ProgressBar.last
    return bool(last is not None and last.cancelled and obj is not None
                and last.target == (obj.Document.Name, obj.Name))


def cancel_active() -> None:
    """Cancel the running computation, if any (the Cancel button)."""
    if ProgressBar.active is not None:
        ProgressBar.active.cancel()


def finish() -> None:
    """Close the running reporter, if any (after a recompute, whatever happened in it)."""
    if ProgressBar.active is not None:
        ProgressBar.active.close()


def first_use(name: str) -> None:
    """A compiled kernel's first use this session (it loads or compiles, seconds on a first
    start): said on the running bar, if any, when it happens on the GUI's thread (the
    drop-cutter's worker threads touch no widget)."""
    bar = ProgressBar.active
    if bar is not None and threading.current_thread() is threading.main_thread():
        with contextlib.suppress(RuntimeError):  # the widgets went with FreeCAD's window
            bar.note(f"preparing the compiled kernel {name}, first use this session")


def install() -> None:
    """Make the app layer's long computations report here, and the kernels' first use."""
    app_progress.install(ProgressBar)
    kernels.on_first_use(first_use)


install()
