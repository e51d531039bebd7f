"""The adaptive profile's limits, validated once into a typed, frozen :class:`_Limits`."""
from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..errors import SpecError

LIMITS = ("feedrate", "chord", "normal_accel", "axis_velocity", "axis_accel")
FEEDRATE, CHORD, NORMAL_ACCEL, AXIS_VELOCITY, AXIS_ACCEL = range(5)
from ..names import AXES  # noqa: E402  (re-exported)
AXIS_KEYS = ("max_velocity", "max_accel")
FIELDS = {  # the job field behind each argument of plan_adaptive, as refusals name it
    "period": "interpolator.period", "feedrate": "profile.feedrate", "chord_tolerance": "profile.chord_tolerance",
    "max_accel": "profile.max_accel", "max_jerk": "profile.max_jerk", "max_normal_accel": "profile.max_normal_accel",
}


@dataclass(frozen=True)
class _Limits:
    """The limits of one plan, validated by :func:`_limits` (the planner's only check of them) and built once.

    The stages read what they need of the limits from here, derived once (cached on first use)
    instead of re-testing which limits are set: whether any curvature limit is set
    (:attr:`curving`, :attr:`curvature_columns`), the axis limits (:attr:`has_axis_velocity`,
    :attr:`has_axis_accel`), the tight-turn floor of the chord limit (:attr:`tight_turn`) and the
    curvature where a limit starts to bind (:attr:`kappa_bind`).  The axis arrays are read-only.
    """

    period: float
    feedrate: float
    chord_tolerance: float | None
    max_accel: float | None
    max_jerk: float | None
    max_normal_accel: float | None
    axis_velocity: np.ndarray  # (dim,), inf where none
    axis_accel: np.ndarray  # (dim,), inf where none
    share: float

    @cached_property
    def has_axis_velocity(self) -> bool:
        return bool(np.isfinite(self.axis_velocity).any())

    @cached_property
    def has_axis_accel(self) -> bool:
        return bool(np.isfinite(self.axis_accel).any())

    @cached_property
    def curvature_columns(self) -> tuple[int, ...]:
        """The terms of V_lim (columns of LIMITS) that depend on the curvature, of the limits set."""
        return tuple(col for col, active in ((CHORD, self.chord_tolerance is not None),
                                             (NORMAL_ACCEL, self.max_normal_accel is not None),
                                             (AXIS_ACCEL, self.has_axis_accel)) if active)

    @property
    def curving(self) -> bool:
        """Whether any limit depends on the curvature (chord, normal acceleration, axis acceleration)."""
        return bool(self.curvature_columns)

    @cached_property
    def tight_turn(self) -> tuple[float, float]:
        """(floor, reach): V <= floor within reach of arc of every tight point (see "Tight turns" in
        :mod:`nurbsinterp.planner`): 2δ/T within 2δ of a radius below δ (the chord tolerance), A_n T/2 within
        A_n T² of a radius below A_n T²/4 (the normal acceleration); with both, the lower floor and the longer
        reach at every tight point; (inf, 0) with neither."""
        floors = [(math.inf, 0.0)]
        if self.chord_tolerance is not None:
            floors.append((2.0 * self.chord_tolerance / self.period, 2.0 * self.chord_tolerance))
        if self.max_normal_accel is not None:
            floors.append((self.max_normal_accel * self.period / 2.0, self.max_normal_accel * self.period ** 2))
        return min(f for f, _ in floors), max(r for _, r in floors)

    @cached_property
    def kappa_bind(self) -> float:
        """The smallest curvature at which a curvature limit lowers V_lim below F (inf: none is set), 1/mm."""
        F = self.feedrate
        out = [float(np.min((1.0 - self.share) * self.axis_accel)) / F ** 2]
        if self.chord_tolerance is not None:
            dl = self.chord_tolerance
            out.append(2.0 * dl / ((F * self.period / 2.0) ** 2 + dl * dl))
        if self.max_normal_accel is not None:
            out.append(self.max_normal_accel / F ** 2)
        return min(out)


def _positive(name, value):
    """A limit as a positive finite float (None stays None); *name* is the argument, refusals name its job field."""
    if value is None:
        return None
    field = FIELDS.get(name, name)
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise SpecError(f"{field} = {value!r} is not a number") from None
    if not (x > 0 and math.isfinite(x)):
        raise SpecError(f"{field} = {value!r} must be a positive finite number")
    return x


def _limits(curve, period, feedrate, chord_tolerance, max_accel, max_jerk, max_normal_accel, axes, share) -> _Limits:
    """The arguments of plan_adaptive as one :class:`_Limits`; SpecError naming the job field of the first bad one."""
    period = _positive("period", period)
    feedrate = _positive("feedrate", feedrate)
    if period is None:
        raise SpecError("interpolator.period is not set: an adaptive plan needs the sampling period")
    if feedrate is None:
        raise SpecError("profile.feedrate is not set: an adaptive plan needs a feedrate")
    if not (isinstance(share, (int, float)) and 0.0 < share < 1.0):
        raise SpecError(f"tangential_share = {share!r} must lie strictly between 0 and 1")
    dim = curve.dim
    vel = np.full(dim, np.inf)
    acc = np.full(dim, np.inf)
    for name, entry in (axes or {}).items():
        if name not in AXES:
            raise SpecError(f"profile.axes: unknown axis {name!r} (expected one of {', '.join(AXES)})")
        entry = {} if entry is None else entry
        if not isinstance(entry, dict):
            raise SpecError(f"profile.axes.{name} = {entry!r} must be a mapping of max_velocity and max_accel")
        unknown = set(entry) - set(AXIS_KEYS)
        if unknown:
            raise SpecError(f"profile.axes.{name}: unknown key {sorted(unknown)[0]!r} "
                            f"(expected {' or '.join(AXIS_KEYS)})")
        i = AXES.index(name)
        v = _positive(f"profile.axes.{name}.max_velocity", entry.get("max_velocity"))
        a = _positive(f"profile.axes.{name}.max_accel", entry.get("max_accel"))
        if i >= dim:
            continue  # a z limit on a planar curve: that axis does not move
        if v is not None:
            vel[i] = v
        if a is not None:
            acc[i] = a
    vel.setflags(write=False)
    acc.setflags(write=False)
    lim = _Limits(period, feedrate, _positive("chord_tolerance", chord_tolerance), _positive("max_accel", max_accel),
                  _positive("max_jerk", max_jerk), _positive("max_normal_accel", max_normal_accel), vel, acc,
                  float(share))
    if lim.max_accel is None and not lim.has_axis_accel and lim.max_jerk is None:
        raise SpecError("profile.max_accel is not set: an adaptive plan needs max_accel (or accel_time > 0), "
                        "an axis max_accel or max_jerk; without any of them the feedrate could jump")
    return lim
