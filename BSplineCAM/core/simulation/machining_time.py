# SPDX-License-Identifier: LGPL-2.1-or-later
"""The time a machine takes for a program, its feeds limited by the axes' acceleration.

The nominal time (length / feed, rapids at the rapid rate) assumes the tool is at full feed
from the first millimetre of every move.  A machine is not: it accelerates and decelerates
along trapezoidal velocity profiles, slows down at corners, and on the short moves of a
finishing program may never reach the programmed feed.  This module plans the moves as a
look-ahead motion planner does and sums the profile times:

* **Per move** a trapezoidal profile: acceleration ``a`` up to the nominal speed ``v``,
  cruise, deceleration; a move too short to reach ``v`` peaks at
  ``sqrt(a L + (v0^2 + v1^2) / 2)``.  ``a`` and ``v`` along a straight move of unit direction
  ``d`` are the largest the axes allow, ``min_i a_i / |d_i|`` and ``min_i vmax_i / |d_i|``
  (grbl's ``limit_value_by_axis_maximum``); ``v`` is also at most the programmed feed (G1/G2/
  G3) or the rapid rate (G0).
* **Arcs** as LinuxCNC's trajectory planner treats circles (``tp.c`` / ``blendmath.h``,
  BLEND_ACC_RATIO_TANGENTIAL = 0.5): half the acceleration of the arc's axes is left for the
  tangential direction, and the speed is capped where the normal acceleration v^2 / r reaches
  the other sqrt(3)/2 of it, ``v <= sqrt(a r sqrt(3) / 2)``.
* **Junctions** by the junction-deviation model of grbl's planner (S. Jeon, grbl
  ``planner.c``, ``plan_buffer_line``; also Marlin's): between moves of unit directions
  ``t1`` (leaving) and ``t2`` (entering) with ``cos(theta) = -t1 . t2``, the junction speed
  is ``v^2 = a_j delta sin(theta/2) / (1 - sin(theta/2))``: the speed at which a circle
  tangent to both moves, whose distance to the corner is the junction deviation ``delta``
  (mm), is run with the centripetal acceleration ``a_j`` the axes allow along ``t2 - t1``.
  A straight continuation keeps its speed, a reversal stops, and no junction is faster than
  either move's nominal speed.  The program's start, its end and any gap between moves
  (an unknown position) are full stops.
* **Look-ahead** over the whole program: the entry speed of each move is the largest that
  the junction limits allow and from which every later stop can still be reached (the
  backward and forward passes of grbl's ``planner_recalculate``, here in closed form as two
  running minima, so millions of moves plan in well under a second).

Units: lengths mm, speeds mm/s inside (feeds and rapid rates mm/min at the interface),
acceleration mm/s^2, times s.  Jerk, the servo lag and the controller's look-ahead buffer
length are not modelled: a real grbl with a 16-block buffer is slower on programs of many
tiny moves; LinuxCNC's blends (G64) are close to this model.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ParameterError
from ..program.gcode import PLANE_AXES, MoveKind, Program
from ..toolpath.common import RAPID_RANGE, check_range
from ..typing import FloatArray

#: Default acceleration of every axis (mm/s^2): a hobby or light machining-centre value.
DEFAULT_ACCELERATION = 500.0
#: Default rapid traverse rate (mm/min), also each axis's velocity limit.
DEFAULT_RAPID_RATE = 5000.0
#: Default junction deviation (mm), grbl's default ($11 = 0.010 mm).
DEFAULT_JUNCTION_DEVIATION = 0.01
#: Accepted acceleration (mm/s^2): from a slow gantry to several g.
ACCELERATION_RANGE = (1.0, 100_000.0)
#: Accepted junction deviation (mm); 0 stops at every corner that is not straight.
JUNCTION_DEVIATION_RANGE = (0.0, 10.0)
#: Share of an arc's acceleration left for the tangential direction (LinuxCNC, blendmath.h).
ARC_TANGENTIAL_RATIO = 0.5
#: Share left for the normal (centripetal) direction: sqrt(1 - 0.5^2).
ARC_NORMAL_RATIO = math.sqrt(1.0 - ARC_TANGENTIAL_RATIO**2)
#: grbl's thresholds on cos(theta) for a reversal (stop) and a straight line (no limit).
_REVERSAL_COS = 0.999999
_STRAIGHT_COS = -0.999999
#: Moves shorter than this (mm) take no time and do not break the look-ahead (grbl drops them).
_MIN_LENGTH_MM = 1e-9
#: Gap (mm) between one move's end and the next one's start that counts as a stop.
_GAP_MM = 1e-6


@dataclass(frozen=True)
class MachineLimits:
    """Axis limits of the machine: acceleration (mm/s^2) and velocity (mm/min) per axis
    X, Y, Z, the rapid rate (mm/min) and the junction deviation (mm)."""

    acceleration: tuple[float, float, float] = (DEFAULT_ACCELERATION,) * 3
    rapid_rate: float = DEFAULT_RAPID_RATE
    junction_deviation: float = DEFAULT_JUNCTION_DEVIATION
    #: Per-axis velocity limit (mm/min); None: the rapid rate on every axis.
    max_velocity: tuple[float, float, float] | None = None

    @classmethod
    def checked(cls, acceleration: float | Sequence[float] = DEFAULT_ACCELERATION,
                rapid_rate: float = DEFAULT_RAPID_RATE,
                junction_deviation: float = DEFAULT_JUNCTION_DEVIATION,
                max_velocity: float | Sequence[float] | None = None,
                names: tuple[str, str, str, str] = ("acceleration", "rapid rate",
                                                    "junction deviation", "max velocity"),
                ) -> MachineLimits:
        """Limits with every value finite and in range; the error names ``names[k]``, the
        range and the unit.  ``acceleration`` and ``max_velocity`` take one value for all
        axes or three (X, Y, Z)."""
        acc = _per_axis(acceleration, names[0], "mm/s^2", ACCELERATION_RANGE)
        rapid = check_range(rapid_rate, names[1], "mm/min", *RAPID_RANGE)
        deviation = check_range(junction_deviation, names[2], "mm", *JUNCTION_DEVIATION_RANGE)
        vmax = None if max_velocity is None else _per_axis(max_velocity, names[3], "mm/min",
                                                           RAPID_RANGE)
        return cls(acc, rapid, deviation, vmax)

    def axis_velocity(self) -> FloatArray:
        """Velocity limit per axis (mm/s)."""
        vmax = self.max_velocity if self.max_velocity is not None else (self.rapid_rate,) * 3
        return np.asarray(vmax, dtype=float) / 60.0

    def to_dict(self) -> dict:
        return {"acceleration_mm_per_s2": list(self.acceleration),
                "rapid_rate_mm_per_min": self.rapid_rate,
                "junction_deviation_mm": self.junction_deviation,
                "max_velocity_mm_per_min": [float(v) for v in self.axis_velocity() * 60.0]}


def _per_axis(value, name: str, unit: str, bounds: tuple[float, float]) -> tuple[float, ...]:
    values = [value] if np.isscalar(value) else list(value)
    if len(values) == 1:
        values = values * 3
    if len(values) != 3:
        raise ParameterError(f"{name} takes one value or three (X, Y, Z) in {unit}, got "
                             f"{len(values)} values")
    return tuple(check_range(v, f"{name} ({axis})" if len(set(values)) > 1 else name, unit,
                             *bounds) for v, axis in zip(values, "XYZ"))


def parse_axis_values(text: str, name: str, unit: str) -> tuple[float, ...]:
    """Numbers of a command-line option such as ``--accel 500`` or ``--accel 800,800,300``
    (X, Y, Z); a ParameterError names the option and the unit when a value is not a number."""
    parts = [p.strip() for p in str(text).split(",")]
    try:
        return tuple(float(p) for p in parts)
    except ValueError:
        raise ParameterError(f"{name} takes one number or three separated by commas (X,Y,Z) "
                             f"in {unit}, got {text!r}") from None


@dataclass(frozen=True)
class MachineTime:
    """Planned time of a program (s), per move and summed, beside the nominal time.

    ``entry_speed`` and ``exit_speed`` are the planned speeds (mm/s) at each move's ends,
    ``nominal_speed`` the speed it cruises at if long enough (mm/s)."""

    move_time: FloatArray
    nominal_time: FloatArray
    entry_speed: FloatArray
    exit_speed: FloatArray
    nominal_speed: FloatArray
    rapid: np.ndarray
    limits: MachineLimits

    @property
    def total(self) -> float:
        return float(self.move_time.sum())

    @property
    def feed(self) -> float:
        return float(self.move_time[~self.rapid].sum())

    @property
    def rapids(self) -> float:
        return float(self.move_time[self.rapid].sum())

    @property
    def nominal(self) -> float:
        return float(self.nominal_time.sum())

    def metrics(self) -> dict:
        """Figures for verify.json, beside ``machining_time_s`` (the nominal time)."""
        nominal = self.nominal
        return {
            "machining_time_with_acceleration_s": self.total,
            "feed_time_with_acceleration_s": self.feed,
            "rapid_time_with_acceleration_s": self.rapids,
            "acceleration_time_ratio": self.total / nominal if nominal > 0 else 1.0,
            "machine_limits": self.limits.to_dict(),
        }


def machining_time(program: Program, limits: MachineLimits | None = None) -> MachineTime:
    """Plan ``program`` on a machine with ``limits`` and return the time of every move."""
    limits = MachineLimits() if limits is None else limits
    n = len(program)
    acc_axes = np.asarray(limits.acceleration, dtype=float)
    vel_axes = limits.axis_velocity()
    rapid = program.kind == MoveKind.RAPID
    length = program.lengths()
    feed = np.where(rapid, limits.rapid_rate, program.feed) / 60.0  # mm/s
    bad = ~rapid & ~(np.isfinite(feed) & (feed > 0))
    if np.any(bad):
        i = int(np.flatnonzero(bad)[0])
        raise ParameterError(f"{program.source}: line {int(program.line[i])}: feed move "
                             "without a positive feed rate (mm/min)")
    t_in, t_out, accel, speed_cap = _move_geometry(program, length, acc_axes, vel_axes)
    nominal = np.minimum(feed, speed_cap)
    nominal_time = np.divide(length, feed, out=np.zeros(n), where=length > 0)
    move_time = np.zeros(n)
    entry = np.zeros(n)
    exit_ = np.zeros(n)
    keep = np.flatnonzero(length > _MIN_LENGTH_MM)
    if len(keep):
        v2 = _plan(program, keep, t_in, t_out, accel, nominal, length, limits, acc_axes)
        v0, v1 = np.sqrt(v2[:-1]), np.sqrt(v2[1:])
        move_time[keep] = _profile_time(length[keep], accel[keep], nominal[keep], v0, v1)
        entry[keep], exit_[keep] = v0, v1
    return MachineTime(move_time, nominal_time, entry, exit_, nominal, rapid, limits)


def _move_geometry(program: Program, length: FloatArray, acc_axes: FloatArray,
                   vel_axes: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Unit tangents at both ends, tangential acceleration (mm/s^2) and speed cap (mm/s)."""
    safe = np.where(length > 0, length, 1.0)[:, None]
    chord = (program.end - program.start) / safe
    t_in = chord.copy()
    t_out = chord.copy()
    accel = _limit_by_axes(acc_axes, chord)
    cap = _limit_by_axes(vel_axes, chord)
    arcs = np.flatnonzero(program.kind >= MoveKind.ARC_CW)
    for code, (a1, a2, normal) in PLANE_AXES.items():
        i = arcs[program.plane[arcs] == code]
        if not len(i):
            continue
        sense = np.where(program.kind[i] == MoveKind.ARC_CCW, 1.0, -1.0)
        axial = program.end[i, normal] - program.start[i, normal]
        planar = np.sqrt(np.maximum(length[i] ** 2 - axial**2, 0.0))
        radius = None
        for point, tangent in ((program.start, t_in), (program.end, t_out)):
            r1 = point[i, a1] - program.centre[i, a1]
            r2 = point[i, a2] - program.centre[i, a2]
            r = np.hypot(r1, r2)
            radius = r if radius is None else 0.5 * (radius + r)
            scale = planar / np.where(r > 0, r, 1.0) / length[i]
            tangent[i] = 0.0
            tangent[i, a1] = -sense * r2 * scale
            tangent[i, a2] = sense * r1 * scale
            tangent[i, normal] = axial / length[i]
        helical = np.abs(axial) > _MIN_LENGTH_MM
        axis_acc = np.minimum(acc_axes[a1], acc_axes[a2])
        axis_acc = np.where(helical, np.minimum(axis_acc, acc_axes[normal]), axis_acc)
        accel[i] = ARC_TANGENTIAL_RATIO * axis_acc
        axis_vel = np.minimum(vel_axes[a1], vel_axes[a2])
        axial_vel = vel_axes[normal] * length[i] / np.maximum(np.abs(axial), 1e-300)
        cap[i] = np.minimum(np.minimum(axis_vel, axial_vel),
                            np.sqrt(ARC_NORMAL_RATIO * axis_acc * radius))
    return t_in, t_out, accel, cap


def _limit_by_axes(limits: FloatArray, direction: FloatArray) -> FloatArray:
    """min_i limits_i / |direction_i| over the axes a unit direction moves (grbl's
    ``limit_value_by_axis_maximum``); a zero direction gets the smallest limit."""
    share = np.abs(direction)
    with np.errstate(divide="ignore"):
        ratio = np.where(share > 0, limits / np.where(share > 0, share, 1.0), np.inf)
    out = ratio.min(axis=-1)
    return np.where(np.isfinite(out), out, limits.min())


def _plan(program: Program, keep: np.ndarray, t_in: FloatArray, t_out: FloatArray,
          accel: FloatArray, nominal: FloatArray, length: FloatArray, limits: MachineLimits,
          acc_axes: FloatArray) -> FloatArray:
    """Squared speeds (mm^2/s^2) at the m + 1 nodes of the m kept moves: start, junctions,
    end.  Backward pass E_i = min(J_i, E_(i+1) + 2 a_i L_i) and forward pass
    F_(i+1) = min(E_(i+1), F_i + 2 a_i L_i) as running minima over prefix sums."""
    m = len(keep)
    limit = np.zeros(m + 1)
    if m > 1:
        prev, nxt = keep[:-1], keep[1:]
        cos = -np.einsum("mc,mc->m", t_out[prev], t_in[nxt])
        bend = t_in[nxt] - t_out[prev]
        norm = np.linalg.norm(bend, axis=1)
        a_j = _limit_by_axes(acc_axes, bend / np.where(norm > 0, norm, 1.0)[:, None])
        sin_half = np.sqrt(np.clip(0.5 * (1.0 - cos), 0.0, 1.0))
        with np.errstate(divide="ignore", invalid="ignore"):
            corner = a_j * limits.junction_deviation * sin_half / (1.0 - sin_half)
        corner = np.where(cos > _REVERSAL_COS, 0.0, np.where(cos < _STRAIGHT_COS, np.inf, corner))
        corner = np.minimum(corner, np.minimum(nominal[prev], nominal[nxt]) ** 2)
        gap = np.linalg.norm(program.start[nxt] - program.end[prev], axis=1) > _GAP_MM
        limit[1:-1] = np.where(gap, 0.0, corner)
    reach = 2.0 * accel[keep] * length[keep]
    prefix = np.concatenate(([0.0], np.cumsum(reach)))
    backward = np.minimum.accumulate((limit + prefix)[::-1])[::-1] - prefix
    backward = np.clip(np.minimum(backward, limit), 0.0, None)
    forward = np.minimum.accumulate(backward - prefix) + prefix
    return np.clip(np.minimum(forward, backward), 0.0, None)


def _profile_time(length: FloatArray, accel: FloatArray, nominal: FloatArray, v0: FloatArray,
                  v1: FloatArray) -> FloatArray:
    """Time (s) of trapezoidal profiles from v0 to v1 (mm/s) over ``length`` (mm).

    Differences of speeds are written as differences of squares over sums, so a move whose
    ends are at nearly the same speed keeps its accuracy."""
    v0 = np.minimum(v0, nominal)
    v1 = np.minimum(v1, nominal)
    up = (nominal**2 - v0**2) / (2.0 * accel)  # distance to reach the nominal speed
    down = (nominal**2 - v1**2) / (2.0 * accel)
    cruise = length - up - down
    trapezoid = 2.0 * up / (nominal + v0) + 2.0 * down / (nominal + v1) + cruise / nominal
    peak2 = accel * length + 0.5 * (v0**2 + v1**2)
    peak = np.sqrt(peak2)
    with np.errstate(divide="ignore", invalid="ignore"):
        triangle = (np.maximum(peak2 - v0**2, 0.0) / (peak + v0)
                    + np.maximum(peak2 - v1**2, 0.0) / (peak + v1)) / accel
    return np.where(cruise >= 0.0, trapezoid, triangle)
