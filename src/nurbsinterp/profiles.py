"""Feedrate profiles planned before interpolation: V(t), A(t) and S(t) in closed form.

One shape function r on [0, 1] (r(0) = 0, r(1) = 1) drives both ramps of a
move with peak feedrate Vp and acc/dec time Ta (the paper's Section 3; docs/interpolation.md, "Profiles")::

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
from dataclasses import replace

import numpy as np

from ._jit import njit
from .errors import CuspError, SpecError
from .planner import MotionTooLong, adaptive_at
from .planner.plan import evaluate_many

from .names import SHAPES  # noqa: E402  (re-exported: the ramp shapes)

SETTLE_TOL = 1e-6  # mm: acc/dec after interpolation runs until the filtered command is this close to its target


def settle_time(spec, length: float) -> float:
    """How long (s) acc/dec after interpolation takes to bring the tool to rest once its input stops: the moving
    average's span for the trapezoidal and bell filters; for the exponential lag, until what is left of it, at
    most the path's *length* (mm), is within SETTLE_TOL."""
    if spec.type == "exponential":
        return spec.tau * math.log(max(length, 1.0) / SETTLE_TOL)
    return spec.accel_time


TRAPEZOIDAL, EXPONENTIAL, BELL, ADAPTIVE, SECTIONED = 0, 1, 2, 3, 4

# Layout of the parameter vector every kernel takes: one float64 array, so
# that the per-tick code needs no Python object.
KIND, RATIO, R1, PEAK, TA, LENGTH, DECEL_START, DURATION = range(8)
HEADER = 8  # an adaptive profile's piece table follows the header, flattened (see planner/plan.py)
SECTION_ROW = 2 + HEADER  # a sectioned profile's table: per section (start time, start distance, its own header)
MAX_TICKS = 100_000_000  # refuse, up front, a job longer than this (a typo in the period, say)


@njit(cache=True)
def shape_value(kind, c, x):
    """r(x): the shape of the acceleration ramp, r(0) = 0, r(1) = 1."""
    if kind == TRAPEZOIDAL:
        return x
    if kind == BELL:
        return 0.5 * (1.0 - math.cos(math.pi * x))
    return math.expm1(-c * x) / math.expm1(-c)


@njit(cache=True)
def shape_slope(kind, c, x):
    """r'(x)."""
    if kind == TRAPEZOIDAL:
        return 1.0
    if kind == BELL:
        return 0.5 * math.pi * math.sin(math.pi * x)
    return c * math.exp(-c * x) / -math.expm1(-c)


@njit(cache=True)
def shape_integral(kind, c, x):
    """R(x) = integral of r from 0 to x."""
    if kind == TRAPEZOIDAL:
        return 0.5 * x * x
    if kind == BELL:
        return 0.5 * x - math.sin(math.pi * x) / (2.0 * math.pi)
    return (x + math.expm1(-c * x) / c) / -math.expm1(-c)


@njit(cache=True)
def profile_at(prof, t):
    """(S, V, A) at time t: planned distance (mm), feedrate (mm/s), acceleration (mm/s²).

    A is the right-hand value where it jumps (at t = 0 it is the starting
    acceleration), which is what a forward Taylor step needs.
    """
    kind = int(prof[KIND])
    if kind == ADAPTIVE:
        return adaptive_at(prof[HEADER:].reshape((-1, 5)), t)
    if kind == SECTIONED:
        table = prof[HEADER:].reshape((-1, SECTION_ROW))
        if t >= prof[DURATION]:
            return prof[LENGTH], 0.0, 0.0
        lo, hi = 0, table.shape[0] - 1  # the last section starting at or before t
        while lo < hi:
            mid = (lo + hi + 1) // 2
            if table[mid, 0] <= t:
                lo = mid
            else:
                hi = mid - 1
        S, V, A = ramp_at(table[lo, 2:], t - table[lo, 0])
        return table[lo, 1] + S, V, A
    return ramp_at(prof, t)


@njit(cache=True)
def ramp_at(prof, t):
    """(S, V, A) of one ramp-cruise-ramp move (the header of a profile of the paper's shapes)."""
    kind = int(prof[KIND])
    c = prof[RATIO]
    Vp = prof[PEAK]
    Ta = prof[TA]
    L = prof[LENGTH]
    td = prof[DECEL_START]
    if t < 0.0 or prof[DURATION] == 0.0:
        return 0.0, 0.0, 0.0
    if t >= prof[DURATION]:
        return L, 0.0, 0.0
    if t < Ta:
        x = t / Ta
        return Vp * Ta * shape_integral(kind, c, x), Vp * shape_value(kind, c, x), Vp * shape_slope(kind, c, x) / Ta
    if t < td:  # cruise (also the whole motion when Ta = 0)
        return Vp * Ta * prof[R1] + Vp * (t - Ta), Vp, 0.0
    x = (t - td) / Ta
    # written as L minus the distance still to go, so that S(end) = L exactly
    S = L - Vp * Ta * ((1.0 - x) - (prof[R1] - shape_integral(kind, c, x)))
    return S, Vp * (1.0 - shape_value(kind, c, x)), -Vp * shape_slope(kind, c, x) / Ta


@njit(cache=True)
def profile_many(prof, ts, S, V, A):
    for i in range(ts.shape[0]):
        S[i], V[i], A[i] = profile_at(prof, ts[i])


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
        if shape not in SHAPES:
            raise ValueError(f"unknown profile shape {shape!r}")
        if not (length >= 0 and feedrate > 0 and accel_time >= 0):
            raise ValueError("profile needs length >= 0, feedrate > 0, accel_time >= 0")
        tau = time_constant if time_constant is not None else accel_time / 4.0
        self.shape = shape
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
        kind = SHAPES.index(shape)
        ratio = accel_time / tau if accel_time > 0 else 4.0
        self.params = np.array([kind, ratio, shape_integral(kind, ratio, 1.0), self.peak, self.accel_time,
                                self.length, self.decel_start, self.duration])
        self.params.setflags(write=False)

    def evaluate(self, t):
        """(S, V, A) at times t (s), arrays shaped like t: see :func:`profile_at`."""
        return evaluate_many(profile_many, self.params, t)

    def ticks(self, period: float) -> int:
        """Index K of the last tick: the first k with k·T >= duration (its command is the end point)."""
        return max(1, math.ceil(self.duration / period - 1e-9))


class SectionedProfile:
    """The paper's profiles on a path with corners: rest to rest from corner to corner.

    Each section between stops gets its own ramp-cruise-ramp move (a short one its
    own lowered peak), stretched in time so that it lasts a whole number of
    periods: every stop falls on a tick, so the tick at a corner commands the corner
    itself.  The stretch scales the section's time by c = ceil(D/T)·T / D (at most
    one period more): its feedrate by 1/c, its ramp time (and time constant) by c.
    A dwell before a section (G4) holds the tool at rest for it, rounded up to whole
    periods, before the section starts.
    """

    def __init__(self, shape: str, ends, feedrate, accel_time: float, time_constant: float | None,
                 period: float, dwells=None):
        """*feedrate*: mm/s, one for every section or an array of one per section (the blocks' own); *dwells*:
        s at rest before each section (None: none)."""
        ends = np.asarray(ends, dtype=float)
        feeds = np.broadcast_to(np.asarray(feedrate, dtype=float), ends.shape)
        lengths = np.diff(np.concatenate([[0.0], ends]))
        tau = time_constant if time_constant is not None else accel_time / 4.0
        rows, ticks = [], 0
        self.sections = []
        self.lowered = False  # a section too short for its ramps (not the stretch onto whole ticks)
        dwells = np.zeros(ends.shape) if dwells is None else np.asarray(dwells, dtype=float)
        for s0, length, feed, dwell in zip(np.concatenate([[0.0], ends[:-1]]), lengths, feeds, dwells):
            ticks += math.ceil(dwell / period - 1e-9) if dwell > 0 else 0  # at rest where the last section ended
            move = Profile(shape, length, feed, accel_time, tau)
            self.lowered = self.lowered or bool(move.lowered)
            if move.duration > 0:
                c = math.ceil(move.duration / period - 1e-9) * period / move.duration
                move = Profile(shape, length, move.peak / c, accel_time * c, tau * c)
            self.sections.append(move)
            # a section starts at tick k: its start time is k·T, the product the kernels form for t_k
            rows.append(np.concatenate([[ticks * period, s0], move.params]))
            ticks += move.ticks(period) if move.duration > 0 else 0
        t0 = ticks * period
        self.shape = shape
        self.length = float(ends[-1])
        self.feedrate = float(feeds.max())
        self.accel_time = float(accel_time)
        self.time_constant = tau
        self.peak = max(move.peak for move in self.sections)
        self.duration = t0
        header = [SECTIONED, 0.0, 0.0, self.peak, accel_time, self.length, t0, t0]
        self.params = np.concatenate([header, np.concatenate(rows)])
        self.params.setflags(write=False)

    evaluate = Profile.evaluate
    ticks = Profile.ticks


class AdaptiveProfile:
    """The limit-aware plan of :mod:`planner` in the shape of a :class:`Profile`."""

    def __init__(self, plan):
        self.plan = plan
        self.shape = "adaptive"
        self.length = plan.length
        self.feedrate = plan.feedrate
        self.accel_time = 0.0
        self.peak = plan.peak
        self.lowered = plan.lowered
        self.duration = plan.duration
        header = [ADAPTIVE, 0.0, 0.0, plan.peak, 0.0, plan.length, plan.duration, plan.duration]
        self.params = np.concatenate([header, plan.segments.ravel()])
        self.params.setflags(write=False)

    def evaluate(self, t):
        return self.plan.evaluate(t)

    def ticks(self, period: float) -> int:
        return self.plan.ticks(period)


def tick_limit_error(source: str, ticks: float, what: str, max_ticks: int, hint: str) -> SpecError | None:
    """The refusal of a job needing more than *max_ticks* ticks (None if it does not).

    *ticks* is a float so that an overflowing estimate (a period of 1e-320 s) is
    refused like any other instead of failing inside ``math.ceil``."""
    if ticks <= max_ticks:  # False for NaN and inf as well
        return None
    amount = f"about {ticks:.3g}" if math.isfinite(ticks) else "more than 1e308"
    return SpecError(f"{source}: the job needs {amount} ticks ({what}), more than the limit of {max_ticks:.3g}{hint}")


def planned_profile(job, path, *, constant: bool = False, max_ticks: int = MAX_TICKS,
                    hint: str = ""):
    """(profile, K): the job's profile on *path* and the index K of its last tick, within *max_ticks*.

    An adaptive job longer than the limit is refused before it is planned, from
    the lower bound L / (F T) of its tick count: the planner's own work grows with
    the motion time, and a typo in the period must not cost minutes before the
    refusal.  The planned duration (closed form for the ramp profiles) is checked
    for every type.
    """
    spec, period, length = job.profile, job.interpolator.period, path.length
    if spec.type == "adaptive":
        top = spec.feedrate if path.feedrates is None else float(path.feedrates.max())
        with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
            lower = length / top / period
        error = tick_limit_error(job.source, lower, f"{length:.6g} mm at {top:.6g} mm/s or less, "
                                 f"T = {period:g} s", max_ticks, hint)
        if error is not None:
            raise error
    try:
        stops = path.section_ends()
        feeds = path.section_feedrates()
        if spec.type != "adaptive" and not constant and (len(stops) > 1 or path.program_stops()):
            profile = SectionedProfile(spec.type, stops, spec.feedrate if feeds is None else feeds, spec.accel_time,
                                       spec.time_constant, period, path.section_holds())
        elif constant and ((feeds is not None and len(stops) > 1) or path.program_stops()):
            # acc/dec after interpolation: each section at its blocks' feedrate, changed at once (the filter ramps);
            # where the program stops, the commands hold until the filter has brought the tool to rest, then dwell
            profile = SectionedProfile(spec.type, stops, spec.feedrate if feeds is None else feeds, 0.0, spec.tau,
                                       period, path.section_holds(flush=settle_time(spec, length)))
        else:
            if feeds is not None and spec.type != "adaptive":  # one section: its blocks' feedrate
                spec = replace(spec, feedrate=float(feeds.min()))
            profile = profile_for(spec, length, constant=constant, curve=path.curve, period=period,
                                  max_duration=(max_ticks + 1) * period, span_feedrates=path.span_feedrates())
    except CuspError as cusp:
        if len(path.blocks) == 1:  # one curve (a `curve:` job or a path of one block): its u is the user's own
            raise
        raise SpecError(_cusp_on_path(path, cusp)) from None
    except MotionTooLong as too_long:
        error = tick_limit_error(job.source, max(too_long.duration / period, max_ticks + 1.0),
                                 f"{too_long.duration:.6g} s of motion or more at T = {period:g} s", max_ticks, hint)
        raise error from None
    if not math.isfinite(profile.peak) or (profile.duration > 0 and not profile.peak > 0):
        raise SpecError(f"{job.source}: profile.feedrate = {spec.feedrate:g} mm/s and profile.accel_time = "
                        f"{spec.accel_time:g} s give a peak feedrate of {profile.peak:g} mm/s on {length:.6g} mm; "
                        "nothing can be planned from that")
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        ticks = profile.duration / period
    motion = f"{profile.duration:.6g} s of motion" if math.isfinite(profile.duration) else "a motion time that overflows"
    error = tick_limit_error(job.source, ticks, f"{motion} at T = {period:g} s", max_ticks, hint)
    if error is not None:
        raise error
    return profile, profile.ticks(period)


def _cusp_on_path(path, cusp: CuspError) -> str:
    """A cusp of the path's curve in the path's own terms: the block and its parameter, never the u of the joined
    curve (whose blocks are shifted)."""
    where = f"point ({cusp.point}), where the path turns by {cusp.angle:.3g} degrees (a cusp)"
    n, u = path.locate(cusp.u)
    block = path.blocks[int(n)]
    source = f" ({block.source})" if block.source else ""
    return (f"path.blocks[{int(n)}]{source}: the parametric speed vanishes at its u = {float(u):.9g}, {where}; the "
            f"adaptive planner stops only at knots and block ends: insert a knot there, or end the block there")


def profile_for(spec, length: float, *, constant: bool = False, curve=None, period: float | None = None,
                max_duration: float = math.inf, span_feedrates=None):
    """The profile of a :class:`~nurbsinterp.config.ProfileSpec` on a path of *length*.

    ``constant=True`` drops the ramps (acc/dec after interpolation interpolates at
    constant feedrate and filters afterwards).  The adaptive type plans along
    *curve* for the sampling *period*; without max_accel it uses the ramp's
    acceleration feedrate / accel_time, which also bounds the centripetal acceleration
    unless max_normal_accel is set, and refuses (planner.MotionTooLong) a
    plan longer than *max_duration* before its costly part; *span_feedrates*
    (mm/s per knot span of *curve*) are the blocks' own feedrates, each a cap
    where its block lies (the plan's F is then the highest of them).
    """
    if spec.type == "adaptive":
        from .planner import plan_adaptive

        max_accel = spec.max_accel
        if max_accel is None and spec.accel_time > 0:
            max_accel = spec.feedrate / spec.accel_time
        # A machinist's acceleration limit is the machine's, whichever way the path turns: it bounds the
        # centripetal part V²κ too unless the job sets max_normal_accel itself, so that the acceleration
        # vector stays within √2 of it (a bound on the vector itself would couple the two: see README).
        max_normal_accel = spec.max_normal_accel if spec.max_normal_accel is not None else max_accel
        jerks = [f"profile.axes.{axis}.max_jerk = {j:g} mm/s^3" for axis, _, _, j in spec.axes if j is not None]
        if jerks:
            raise SpecError(f"{jerks[0]}: a per-axis jerk limit is held by the look-ahead planner only (plan with "
                            "--tolerance); the adaptive profile holds the path's max_jerk (--max-jerk)")
        axes = {axis: {"max_velocity": v, "max_accel": a} for axis, v, a, _ in spec.axes}
        feedrate = spec.feedrate if span_feedrates is None else float(np.max(span_feedrates[np.isfinite(span_feedrates)]))
        return AdaptiveProfile(plan_adaptive(curve, period, feedrate, chord_tolerance=spec.chord_tolerance,
                                             max_accel=max_accel, max_jerk=spec.max_jerk,
                                             max_normal_accel=max_normal_accel, axes=axes or None,
                                             max_duration=max_duration, span_feedrates=span_feedrates))
    return Profile(spec.type, length, spec.feedrate, 0.0 if constant else spec.accel_time, spec.tau)
