"""Feedrate profiles planned before interpolation: V(t), A(t) and S(t) in closed form.

One shape function r on [0, 1] (r(0) = 0, r(1) = 1) drives both ramps of a
move with peak feedrate Vp and acc/dec time Ta (see ``REFERENCE.md`` §2)::

    acceleration   V(t)        = Vp r(t / Ta)          0 <= t <= Ta
    cruise         V           = Vp
    deceleration   V(t_d + t') = Vp (1 - r(t' / Ta))   0 <= t' <= Ta

Deceleration mirrors acceleration in velocity, so the two ramps together cover
Vp·Ta whatever the shape and the motion time is L / Vp + Ta.  A curve shorter
than Vp·Ta lowers the peak to L / Ta (no cruise).

The planned distance S(t) is integrated analytically with R(x) = ∫₀ˣ r; the
deceleration phase is written as L minus the distance still to go, so that
S(end) = L exactly in floating point.
"""
from __future__ import annotations

import math

import numpy as np

SHAPES = ("trapezoidal", "exponential", "bell")


class Shape:
    """r(x), r'(x) and R(x) = ∫₀ˣ r on [0, 1], vectorised."""

    def __init__(self, name: str, ratio: float = 4.0):
        if name not in SHAPES:
            raise ValueError(f"unknown profile shape {name!r}")
        self.name = name
        self.c = ratio  # Ta / tau, exponential only
        self.R1 = float(self.integral(np.array(1.0)))

    def value(self, x):
        if self.name == "trapezoidal":
            return x
        if self.name == "bell":
            return 0.5 * (1.0 - np.cos(np.pi * x))
        return np.expm1(-self.c * x) / math.expm1(-self.c)

    def slope(self, x):
        if self.name == "trapezoidal":
            return np.ones_like(x)
        if self.name == "bell":
            return 0.5 * np.pi * np.sin(np.pi * x)
        return self.c * np.exp(-self.c * x) / -math.expm1(-self.c)

    def integral(self, x):
        if self.name == "trapezoidal":
            return 0.5 * x * x
        if self.name == "bell":
            return 0.5 * x - np.sin(np.pi * x) / (2.0 * np.pi)
        return (x + np.expm1(-self.c * x) / self.c) / -math.expm1(-self.c)


class Profile:
    """A ramp–cruise–ramp feedrate plan along a path of length L.

    Parameters
    ----------
    shape : 'trapezoidal' | 'exponential' | 'bell'
    length : float, mm (L)
    feedrate : float, mm/s (commanded peak Vp)
    accel_time : float, s (Ta); 0 gives a constant feedrate with instant start and stop
    time_constant : float, s (exponential only; default Ta / 4)

    Attributes
    ----------
    peak : the feedrate actually reached (lowered to L / Ta on a short path)
    lowered : whether the peak was lowered
    duration : motion time L / peak + Ta, s
    """

    def __init__(self, shape: str, length: float, feedrate: float, accel_time: float,
                 time_constant: float | None = None):
        if not (length >= 0 and feedrate > 0 and accel_time >= 0):
            raise ValueError("profile needs length >= 0, feedrate > 0, accel_time >= 0")
        tau = time_constant if time_constant is not None else accel_time / 4.0
        self.shape = Shape(shape, accel_time / tau if accel_time > 0 else 4.0)
        self.length = float(length)
        self.feedrate = float(feedrate)
        self.accel_time = float(accel_time)
        self.time_constant = tau
        self.lowered = length < feedrate * accel_time
        self.peak = length / accel_time if self.lowered else self.feedrate
        if length == 0:
            self.peak, self.duration = 0.0, 0.0
        else:
            self.duration = length / self.peak + accel_time
        self.decel_start = self.duration - accel_time

    def evaluate(self, t):
        """(S, V, A) at times t (s): planned distance (mm), feedrate (mm/s), acceleration (mm/s²).

        A is the right-hand value where it jumps (at t = 0 it is the starting
        acceleration), which is what a forward Taylor step needs.
        """
        t = np.asarray(t, dtype=float)
        S = np.zeros_like(t)
        V = np.zeros_like(t)
        A = np.zeros_like(t)
        Vp, Ta, L, r = self.peak, self.accel_time, self.length, self.shape
        if self.duration == 0:
            return S, V, A
        acc = (t >= 0) & (t < Ta)
        cruise = (t >= Ta) & (t < self.decel_start)
        dec = (t >= self.decel_start) & (t < self.duration)
        done = t >= self.duration
        if acc.any():
            x = t[acc] / Ta
            S[acc] = Vp * Ta * r.integral(x)
            V[acc] = Vp * r.value(x)
            A[acc] = Vp * r.slope(x) / Ta
        if cruise.any():
            S[cruise] = Vp * Ta * r.R1 + Vp * (t[cruise] - Ta)
            V[cruise] = Vp
        if dec.any():  # empty when Ta = 0: the cruise then runs to the end
            x = (t[dec] - self.decel_start) / Ta
            S[dec] = L - Vp * Ta * ((1.0 - x) - (r.R1 - r.integral(x)))
            V[dec] = Vp * (1.0 - r.value(x))
            A[dec] = -Vp * r.slope(x) / Ta
        S[done] = L
        return S, V, A

    def ticks(self, period: float) -> int:
        """Index K of the last tick: the first k with k·T >= duration (its command is the end point)."""
        return max(1, math.ceil(self.duration / period - 1e-9))


def profile_for(spec, length: float, *, constant: bool = False) -> Profile:
    """The Profile of a :class:`~nurbsinterp.spec.ProfileSpec` on a path of *length*.

    ``constant=True`` drops the ramps (acc/dec after interpolation interpolates at
    constant feedrate and filters afterwards).
    """
    return Profile(spec.type, length, spec.feedrate, 0.0 if constant else spec.accel_time, spec.tau)
