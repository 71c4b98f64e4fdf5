# SPDX-License-Identifier: LGPL-2.1-or-later
"""Progress of long computations in FreeCAD's status bar, interruptible with its cancel button.

App layer: ``Base.ProgressIndicator`` is FreeCAD's own sequencer, not FreeCADGui; callers use it
only when the GUI is up (headless it would merely print).

FreeCAD's sequencer (``Base.ProgressIndicator``) shows a progress bar and, while it runs, lets
the user abort: ``next(True)`` then raises.  The core's callbacks take a fraction in [0, 1].
"""

from __future__ import annotations

import FreeCAD

from ..core.toolpath.common import ToolpathCancelled

STEPS = 100


class StatusProgress:
    """A ``progress(fraction)`` callable driving one FreeCAD progress bar."""

    def __init__(self, message: str):
        self.indicator = FreeCAD.Base.ProgressIndicator()
        self.indicator.start(message, STEPS)
        self.step = 0
        self.open = True

    def __call__(self, fraction: float) -> None:
        target = min(STEPS, int(round(float(fraction) * STEPS)))
        try:
            while self.step < target:
                self.indicator.next(True)
                self.step += 1
        except Exception as exc:  # the sequencer raises when the user presses cancel
            self.close()
            raise ToolpathCancelled(f"interrupted by the user at {self.step}%") from exc
        if self.step >= STEPS:
            self.close()

    def close(self) -> None:
        if self.open:
            self.indicator.stop()
            self.open = False

    def __del__(self):
        self.close()


def op_progress(obj) -> StatusProgress:
    return StatusProgress(f"{obj.Label}: computing the toolpath")
