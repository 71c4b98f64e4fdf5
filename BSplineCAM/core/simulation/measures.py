# SPDX-License-Identifier: LGPL-2.1-or-later
"""What a finishing program costs on the machine, printed with every toolpath.

* ``cutting_length_mm``: the length of the feed moves (G1, G2, G3), as Verify measures it.
* ``rapid_length_mm``: the length of the rapids (G0).
* ``air_length_mm``: the length of the moves that do not follow a pass: rapids, the feeds
  down to a pass and the stay-down links between passes; the program's whole length less the
  length along its passes (``along_passes_mm``, links left out: :func:`toolpath_lengths`).
* ``machining_time_s``: feed lengths over their feeds plus rapid lengths at the rapid rate.
* ``machining_time_with_acceleration_s``: the time of
  :func:`.machining_time.machining_time` on a machine of ``limits`` (trapezoidal speed
  profiles, junction speeds, look-ahead; the default machine without ``limits``).
"""

from __future__ import annotations

import numpy as np

from ..program.gcode import MoveKind, Program
from .machining_time import MachineLimits, machining_time


def toolpath_lengths(*toolpaths) -> dict:
    """``along_passes_mm`` (the passes alone) and ``link_length_mm`` (the stay-down links) of
    core toolpaths (mm)."""
    along = links = 0.0
    for toolpath in toolpaths:
        if toolpath is None:
            continue
        along += sum(float(np.linalg.norm(np.diff(p, axis=0), axis=1).sum())
                     for p in toolpath.passes)
        links += sum(float(np.linalg.norm(np.diff(lk, axis=0), axis=1).sum())
                     for lk in (toolpath.links or []) if lk is not None)
    return {"along_passes_mm": along, "link_length_mm": links}


def program_measures(program: Program, along_passes_mm: float | None = None,
                     limits: MachineLimits | None = None) -> dict:
    """The module's figures of ``program`` (``air_length_mm`` only with ``along_passes_mm``);
    the nominal time's rapid rate is the one of ``limits``."""
    limits = MachineLimits() if limits is None else limits
    lengths = program.lengths()
    rapid = program.kind == MoveKind.RAPID
    feed = ~rapid
    rate = limits.rapid_rate
    out = {
        "cutting_length_mm": float(lengths[feed].sum()),
        "rapid_length_mm": float(lengths[rapid].sum()),
        "machining_time_s": 60.0 * (float(np.sum(lengths[feed] / program.feed[feed]))
                                    + float(lengths[rapid].sum()) / rate),
        "machining_time_with_acceleration_s": machining_time(program, limits).total,
    }
    if along_passes_mm is not None:
        out["air_length_mm"] = max(float(lengths.sum()) - along_passes_mm, 0.0)
    return out


__all__ = ["program_measures", "toolpath_lengths"]
