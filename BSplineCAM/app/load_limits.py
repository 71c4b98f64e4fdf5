# SPDX-License-Identifier: LGPL-2.1-or-later
"""The load limits of a job's tools, from its BSplineCAM ops (no GUI).

Each op (roughing and finishing) carries three properties that cap what its tool may take per
move: ``MaxAxialEngagement`` and ``MaxRadialEngagement`` (mm) and ``MaxRemovalRate``
(mm^3/min); 0 keeps the job's own limit.  The job's own limits are those of
:func:`BSplineCAM.core.simulation.load_limits.job_limits`: the roughing tool's from its
step-down, stepover and allowances, the finishing ball's from the stock the roughing and the
rest passes leave it (allowance + scallop + rest limit).  A job without a roughing op gets
:func:`~BSplineCAM.core.simulation.load_limits.default_limits` of each tool's kind and
diameter.  The verification of a whole job (:mod:`.verify_feature`) checks every move of the
program against them.
"""

from __future__ import annotations

import dataclasses

from ..core.simulation.load_limits import LoadLimits, default_limits, job_limits

#: (type, name, group, tooltip, flags, default) of the load-limit properties every op has.
LOAD_PROPERTIES = (
    ("App::PropertyLength", "MaxAxialEngagement", "Load limits",
     "Deepest cut the tool may take in one move, checked by Verify (mm; 0: the job's limit, "
     "from the step-down, or for a finishing ball the stock it is left)", 0, 0.0),
    ("App::PropertyLength", "MaxRadialEngagement", "Load limits",
     "Widest cut the tool may take in one move, entries apart, checked by Verify (mm; 0: the "
     "job's limit, from the stepover)", 0, 0.0),
    ("App::PropertyFloat", "MaxRemovalRate", "Load limits",
     "Largest material removal rate of the tool, checked by Verify (mm^3/min; 0: the job's "
     "limit)", 0, 0.0),
)

_FIELDS = (("MaxAxialEngagement", "axial_mm"), ("MaxRadialEngagement", "radial_mm"),
           ("MaxRemovalRate", "removal_rate_mm3_per_min"))


def _value(prop) -> float:
    return float(getattr(prop, "Value", prop))


def op_overrides(op, limits: LoadLimits) -> LoadLimits:
    """``limits`` with each of the op's load properties that is set (above 0) in its place;
    an op saved before these properties existed keeps ``limits``."""
    changes = {}
    for prop, field in _FIELDS:
        if hasattr(op, prop) and _value(getattr(op, prop)) > 0:
            changes[field] = _value(getattr(op, prop))
    return dataclasses.replace(limits, **changes) if changes else limits


def _loosest(a: LoadLimits, b: LoadLimits) -> LoadLimits:
    """Per figure the larger limit (None, no limit, is the largest), and the larger depth from
    which the width limit holds: a tool that two ops use is held to the looser of their
    limits."""
    def pick(x, y):
        return None if x is None or y is None else max(x, y)

    def deeper(x, y):  # the depth from which the width holds: None, every cut, is the least
        return y if x is None else x if y is None else max(x, y)

    return LoadLimits(*(pick(getattr(a, f), getattr(b, f)) for _, f in _FIELDS),
                      radial_from_depth_mm=deeper(a.radial_from_depth_mm,
                                                  b.radial_from_depth_mm))


def is_roughing(op) -> bool:
    """True for a roughing op (it has a step-down), False for a finishing op."""
    return hasattr(op, "StepDown") and not hasattr(op, "ScallopHeight")


def job_load_limits(job, ops, tools: dict, cell: float) -> dict[int, LoadLimits]:
    """{tool number: LoadLimits} of the job's active BSplineCAM ``ops`` (roughing and
    finishing, in program order) whose tools are in ``tools`` ({number: core Tool}); ``cell``
    (mm) is the simulation's Z-map cell, the resolution the limits allow for."""
    rough = next((op for op in ops if is_roughing(op)), None)
    if rough is not None and (rough.ToolController is None
                              or int(rough.ToolController.ToolNumber) not in tools):
        rough = None
    finishers = [op for op in ops if not is_roughing(op)]
    out: dict[int, LoadLimits] = {}
    for op in ops:
        tc = getattr(op, "ToolController", None)
        if tc is None or int(tc.ToolNumber) not in tools:
            continue
        number = int(tc.ToolNumber)
        tool = tools[number]
        if rough is None:
            limits = default_limits(tool)
        else:
            # the roughing tool's limits depend on the roughing alone; a finishing op's on
            # the stock the roughing leaves it and its own scallop and rest limit
            finishing = op if not is_roughing(op) else (finishers[0] if finishers else None)
            rough_tool = tools[int(rough.ToolController.ToolNumber)]
            stepdown = _value(rough.StepDown)
            pair = job_limits(
                rough_tool, tool if finishing is op else rough_tool,
                stepdown=stepdown,
                stepover=0.01 * int(rough.StepOver) * rough_tool.diameter,
                axial_allowance=_value(rough.AxialAllowance),
                radial_allowance=_value(rough.RadialAllowance),
                scallop=_value(finishing.ScallopHeight) if finishing is not None else stepdown,
                rest_limit=_value(getattr(finishing, "RestLimit", 0.0))
                if finishing is not None else 0.0,
                cell=cell)
            limits = pair[2] if finishing is op else pair[1]
        limits = op_overrides(op, limits)
        out[number] = limits if number not in out else _loosest(out[number], limits)
    return out
