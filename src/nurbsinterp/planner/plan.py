"""The plan: :func:`plan_adaptive`, the :class:`AdaptivePlan` it returns, and its per-tick evaluation (step 5 of the
algorithm in :mod:`nurbsinterp.planner`, and its "Interface for the per-tick kernel")."""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .._jit import njit
from ..errors import NurbsInterpError, SpecError
from ..nurbs import NurbsCurve
from .grid import _grid_arrays
from .jerk import _estimate_sums, _jerk_limited, _optimum_time, _scan
from .limits import LIMITS, _limits
from .sections import _grid_sections

# columns of the segment table
T_START, S_START, V_START, A_START, JERK = range(5)

MARGIN = 1e-9             # relative margin kept on caps, accelerations and jerk (absorbs the end scaling)
MAX_STEPS = 500_000  # forward steps the jerk-limited pass aims at: dt is coarsened to stay under it
STEP_BUDGET = 4.0  # ... and it gives up (an internal error) after this many times the estimated steps + 100000


# --------------------------------------------------------------------------- per-tick evaluation


@njit(cache=True)
def adaptive_at(segments, t):
    """(S, V, A) of an adaptive plan at time t: distance (mm), feedrate (mm/s), acceleration (mm/s²).

    Binary search for the piece holding t (the right-hand piece at a boundary,
    so that A is the value a forward step needs), then the cubic
    S = S0 + V0 τ + A0 τ²/2 + J τ³/6.  S is clamped to [0, length] and is
    exactly the length at and after the end; V >= 0; before t = 0 everything is 0.
    """
    m = segments.shape[0]
    end = segments[m - 1, 0]
    length = segments[m - 1, 1]
    if t >= end:
        return length, 0.0, 0.0
    if t < 0.0:
        return 0.0, 0.0, 0.0
    lo = 0
    hi = m - 1  # segments[hi, 0] > t
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if segments[mid, 0] <= t:
            lo = mid
        else:
            hi = mid
    tau = t - segments[lo, 0]
    s0 = segments[lo, 1]
    v0 = segments[lo, 2]
    a0 = segments[lo, 3]
    j = segments[lo, 4]
    S = s0 + tau * (v0 + tau * (0.5 * a0 + tau * j / 6.0))
    V = v0 + tau * (a0 + 0.5 * j * tau)
    A = a0 + j * tau
    if S < 0.0:
        S = 0.0
    elif S > length:
        S = length
    if V < 0.0:
        V = 0.0
    return S, V, A


@njit(cache=True)
def adaptive_many(segments, ts, S, V, A):
    for i in range(ts.shape[0]):
        S[i], V[i], A[i] = adaptive_at(segments, ts[i])


# --------------------------------------------------------------------------- the plan


def evaluate_many(kernel, params, t):
    """(S, V, A) of a plan at times t, arrays shaped like t: *kernel*(params, flat t, S, V, A) fills them."""
    t = np.asarray(t, dtype=float)
    flat = np.ascontiguousarray(t.reshape(-1))
    S, V, A = (np.empty_like(flat) for _ in range(3))
    kernel(params, flat, S, V, A)
    return S.reshape(t.shape), V.reshape(t.shape), A.reshape(t.shape)


@dataclass(frozen=True)
class Slowest:
    """The point of lowest feed limit: arc length s (mm), parameter u, V_lim there (mm/s), and which limit."""

    s: float
    u: float
    v: float
    limit: str


@dataclass(frozen=True)
class SlowestScheduled:
    """The lowest feedrate the schedule itself runs at between the end of its first acceleration and the start
    of its last deceleration (a stop counts, at 0): feedrate v (mm/s), at time t (s) and arc length s (mm)."""

    v: float
    t: float
    s: float


#: what bounds the schedule, in order: V held at the feed limit V_lim, |A| at its tangential bound (max_accel, or
#: lower where an axis budget leaves less), |dA/dt| at max_jerk, and the rest (the jerk-limited pass's steps
#: between two of them)
BOUNDS = ("feed limit", "max_accel", "axis_accel", "max_jerk", "between")
BOUND_RTOL = 1e-6  # a piece this close to a limit is at it (the pieces are exact to MARGIN; the end scaling 1e-10)


class AdaptivePlan:
    """A limit-aware feedrate plan S(t), V(t), A(t) along a curve (see :mod:`nurbsinterp.planner`).

    Attributes
    ----------
    segments : float64 array (m, 5), read-only: rows [t_start, S_start, V_start, A_start, J]
        of constant-jerk pieces, the last row the end state [duration, length, 0, 0, 0]
    duration : float, s — K·period
    length : float, mm — the curve length; S(duration) == length
    peak : float, mm/s — the largest V of the plan
    period : float, s
    feedrate : float, mm/s — the commanded F
    lowered : bool — whether the plan never reaches F
    stretch : float — λ >= 1, the motion time over the sections' own: each section is stretched by its own
        λ_i >= 1 onto whole ticks, so that its stop falls on a tick (one section: the uniform stretch)
    accel_bound : float, mm/s² — the smallest tangential acceleration bound along the path
    sections : int — rest-to-rest sections (1 + the number of stops: corners, and knots where the parametric
        speed vanishes when a curvature limit is set)
    limit_fractions : dict — limit name -> fraction of the path length where it binds V_lim
    slowest : :class:`Slowest` — the lowest point of the feed limit V_lim (not of the schedule)
    slowest_scheduled : :class:`SlowestScheduled` — the lowest feedrate of the schedule between its ramps
    bound_fractions : dict — name of :data:`BOUNDS` -> fraction of the motion time the schedule is held at it
    s_grid, u_grid, v_limit, binding : the sampled feed limit (mm, -, mm/s, index into LIMITS), read-only
    a_limit : the tangential acceleration bound on the same grid, mm/s² (max_accel, lowered by the
        per-axis budgets left over by the centripetal part), read-only
    planning_time : float, s — wall time of :func:`plan_adaptive`

    The grid (``s_grid`` ... ``a_limit``, some 34 points per knot span) is not kept by the plan: it is
    rebuilt, the same to the bit, the first time one of them is read (plots and tests read them).
    """

    shape = "adaptive"

    def __init__(self, segments, *, length, period, feedrate, stretch, accel_bound, sections, limit_fractions: dict,
                 slowest: Slowest, grid, planning_time=0.0, bound_fractions: dict | None = None):
        self.segments = segments
        self.segments.setflags(write=False)
        self.duration = float(segments[-1, T_START])
        self.length = float(length)
        self.period = float(period)
        self.feedrate = float(feedrate)
        self.stretch = float(stretch)
        self.accel_bound = float(accel_bound)
        self.sections = int(sections)
        self.planning_time = float(planning_time)
        self.peak = _peak(segments)
        self.lowered = self.peak < self.feedrate * (1.0 - 1e-6)
        self.limit_fractions = limit_fractions
        self.slowest = slowest
        self.bound_fractions = bound_fractions if bound_fractions is not None else {}
        self._rebuild_grid = grid  # () -> the grid, on demand

    @cached_property
    def _grid(self):
        g = self._rebuild_grid()
        for arr in (g.s, g.u, g.v_limit, g.binding, g.acc_t):
            arr.setflags(write=False)
        return g

    @property
    def s_grid(self):
        return self._grid.s

    @property
    def u_grid(self):
        return self._grid.u

    @property
    def v_limit(self):
        return self._grid.v_limit

    @property
    def binding(self):
        return self._grid.binding

    @property
    def a_limit(self):
        return self._grid.acc_t

    def evaluate(self, t):
        """(S, V, A) at times t (s), arrays shaped like t: see :func:`adaptive_at`."""
        return evaluate_many(adaptive_many, self.segments, t)

    @cached_property
    def slowest_scheduled(self) -> SlowestScheduled:
        """The lowest feedrate between the end of the first acceleration (the first time A falls to 0 or below
        once the motion has started) and the start of the last deceleration (the last time A is still >= 0).

        Before and after these the motion only leaves or approaches rest, which says nothing; between them the
        minimum is a dip the path asks for (a tight turn, a blend) or a stop (0).  V is quadratic on each piece,
        so the minimum is at a piece boundary, at the window's ends or at an interior vertex t0 − A0/J (J > 0).
        """
        seg = self.segments
        t0, a0, j = seg[:-1, T_START], seg[:-1, A_START], seg[:-1, JERK]
        dur = np.diff(seg[:, T_START])
        a1 = a0 + j * dur
        with np.errstate(divide="ignore", invalid="ignore"):
            vertex = t0 - a0 / j  # where A crosses 0 inside the piece (J != 0)
        moving = np.flatnonzero((a0 > 0) | (a1 > 0))
        braking = np.flatnonzero((a0 < 0) | (a1 < 0))
        t_a, t_b = 0.0, self.duration
        if moving.size and braking.size:
            i0, i1 = moving[0], braking[-1]
            idx = np.arange(a0.shape[0])
            # the first fall of A to <= 0 after i0: at a piece's start, or inside a piece where it crosses
            falls = np.concatenate([t0[(idx > i0) & (a0 <= 0)], vertex[(idx >= i0) & (a0 > 0) & (a1 <= 0)]])
            # the last time A is >= 0 before it stays negative: a piece's end, or inside where it crosses
            rises = np.concatenate([(t0 + dur)[(idx < i1) & (a1 >= 0)], vertex[(idx <= i1) & (a0 >= 0) & (a1 < 0)]])
            t_a = float(falls.min()) if falls.size else 0.0
            t_b = float(rises.max()) if rises.size else self.duration
            if t_b < t_a:
                t_a = t_b = 0.5 * (t_a + t_b)
        inside = (vertex > t0) & (vertex < t0 + dur) & (j > 0)
        times = np.concatenate([[t_a, t_b], t0, vertex[inside]])
        times = times[(times >= t_a) & (times <= t_b)]
        S, V, _ = self.evaluate(times)
        k = int(np.argmin(V))
        return SlowestScheduled(float(V[k]), float(times[k]), float(S[k]))

    def ticks(self, period: float | None = None) -> int:
        """Index K of the last tick (K·T = duration)."""
        T = self.period if period is None else period
        return max(1, math.ceil(self.duration / T - 1e-9))

    def __repr__(self):
        return (f"AdaptivePlan(length={self.length:.6g} mm, duration={self.duration:.6g} s, peak={self.peak:.6g} mm/s, "
                f"pieces={self.segments.shape[0] - 1})")


def _peak(seg):
    if seg.shape[0] < 2:
        return 0.0
    v0, a0, j = seg[:-1, V_START], seg[:-1, A_START], seg[:-1, JERK]
    dur = np.diff(seg[:, T_START])
    v1 = v0 + dur * (a0 + 0.5 * j * dur)
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(j != 0, -a0 / j, -1.0)
    inside = (tv > 0) & (tv < dur)
    vv = np.where(inside, v0 + tv * (a0 + 0.5 * j * tv), 0.0)
    return float(max(v0.max(), v1.max(), vv.max()))


#: s: the longest motion the jerk-limited pass plans.  Its table holds absolute times, and beyond ~1e13 s the
#: accelerations of such a motion (a 1 um chord tolerance at a period of 1e9 s caps the feed at 1e-10 mm/s) fall
#: below what those times resolve: the pass stalled (a fuzzed job, tests/test_robustness.py).  No machine's
#: motion comes near it: it is some 31 700 years.
MAX_JERK_MOTION = 1e12


class MotionTooLong(SpecError):
    """The plan would take longer than plan_adaptive's *max_duration*; ``duration`` (s) is the
    acceleration-limited optimum's, which the jerk-limited plan can only exceed (to its rounding)."""

    def __init__(self, duration: float):
        super().__init__(f"the adaptive plan takes about {duration:.6g} s or more")
        self.duration = duration


@njit(cache=True)
def _interval_caps(limits, keep):
    """The cap of each interval, min of its two nodes' limits times *keep*, written over *limits* (n,): the
    caps are then limits[:-1].  In place, so that a section's nodes, caps and acceleration caps are all it
    holds per grid point (24 bytes) while it is planned."""
    for k in range(limits.shape[0] - 1):
        a = limits[k]
        b = limits[k + 1]
        limits[k] = (a if (a < b or a != a) else b) * keep  # np.minimum(a, b) * keep


def _caps(limits, keep):
    """np.minimum(limits[:-1], limits[1:]) * keep, in place; a constant (a broadcast value: see
    sections._SectionBuilder) stays one."""
    if limits.strides[0] == 0:
        return np.broadcast_to(np.minimum(limits[0], limits[0]) * keep, (limits.shape[0] - 1,))
    _interval_caps(limits, keep)
    return limits[:-1]


def _cruise_time(nodes, caps) -> float:
    """Time (s) to cover the section at its caps: each interval at the lower cap of its two nodes."""
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        return float(np.sum(np.diff(nodes) / np.minimum(caps[: nodes.shape[0] - 1], caps[1: nodes.shape[0]])))


def _time_estimate(nodes, caps, acc, J, accel_top):
    """Motion time (s) of a rest-to-rest section, roughly, for the jerk-limited pass's step count.

    The acceleration-limited optimum (the scan), plus what the jerk adds to each monotone run
    of its feedrate: a change Δv takes Δv/A + A/J with ramps, or 2√(Δv/J) when A is not
    reached, i.e. at most 2 min(A/J, √(Δv/J)) more than with instant changes of acceleration;
    and at least the jerk-only rest-to-rest move over the section, 4 (L / 2J)^(1/3).
    The acceleration-limited optimum's time is Σ 2Δs/(v_k + v_k+1) over its intervals (see
    :func:`~nurbsinterp.planner.jerk._estimate_sums`, which sums without arrays).
    """
    times, changes, ramps = _estimate_sums(nodes, caps, acc, accel_top / J, J)
    extra = 2.0 * np.float64(ramps) if changes else 0.0
    total = float(np.float64(times) + extra)
    return max(total, 4.0 * (0.5 * float(nodes[-1] - nodes[0]) / J) ** (1.0 / 3.0)) if math.isfinite(total) else \
        4.0 * (0.5 * float(nodes[-1] - nodes[0]) / J) ** (1.0 / 3.0) + _cruise_time(nodes, caps)


def _bound_times(sec, end_t, nodes, acc, J, max_accel):
    """How long each piece of one section (before its stretch) is held at which limit: seconds per name of
    :data:`BOUNDS`.

    A piece with |J| at the jerk limit is jerk-bound; with J = 0 and |A| at its interval's tangential
    bound, acceleration-bound (max_accel where the bound is max_accel, else an axis budget's); with J = 0
    and A = 0 the feedrate is held at the interval's cap (the jerk-limited pass holds V only there), and
    without a jerk limit every other piece of the scan runs between two nodes at their caps: feed-bound.
    The rest are the jerk-limited pass's steps between two of these.
    """
    t, S, A, jerk = sec[:, T_START], sec[:, S_START], sec[:, A_START], sec[:, JERK]
    dur = np.diff(np.append(t, end_t))
    k = np.clip(np.searchsorted(nodes, S, side="right") - 1, 0, nodes.shape[0] - 2)
    acc_cap = np.asarray(acc)[k]
    at_accel = (jerk == 0) & (np.abs(A) >= acc_cap * (1.0 - BOUND_RTOL))
    if max_accel is None:
        on_max = np.zeros_like(at_accel)
    else:  # the caps are the bounds times 1 − MARGIN
        on_max = at_accel & (acc_cap >= max_accel * (1.0 - MARGIN) * (1.0 - BOUND_RTOL))
    at_jerk = np.zeros_like(at_accel) if J is None else (np.abs(jerk) >= J * (1.0 - BOUND_RTOL))
    feed = ~at_accel & ~at_jerk & ((jerk == 0) & (A == 0) if J is not None else True)
    rest = ~(at_accel | at_jerk | feed)
    return {"feed limit": float(dur[feed].sum()), "max_accel": float(dur[on_max].sum()),
            "axis_accel": float(dur[at_accel & ~on_max].sum()), "max_jerk": float(dur[at_jerk].sum()),
            "between": float(dur[rest].sum())}


def plan_adaptive(curve: NurbsCurve, period: float, feedrate: float, chord_tolerance: float | None = None,
                  max_accel: float | None = None, max_jerk: float | None = None,
                  max_normal_accel: float | None = None, axes: dict | None = None, *,
                  tangential_share: float = 0.4, samples: int = 4000, resolution: float = 0.005,
                  step: float | None = None, max_duration: float = math.inf, span_feedrates=None) -> AdaptivePlan:
    """Plan a limit-aware feedrate along *curve* (see :mod:`nurbsinterp.planner` for the algorithm).

    Parameters
    ----------
    curve : NurbsCurve
    period : float, s — the interpolator's sampling period T
    feedrate : float, mm/s — F, the commanded feedrate
    chord_tolerance : float, mm — δ, the largest chord error of one tick
    max_accel : float, mm/s² — tangential acceleration
    max_jerk : float, mm/s³ — tangential jerk
    max_normal_accel : float, mm/s² — centripetal acceleration V²κ
    axes : {"x": {"max_velocity": mm/s, "max_accel": mm/s²}, "y": ..., "z": ...}, entries optional
    tangential_share : float in (0, 1) — β, the share of each axis acceleration budget given to the
        tangential part (the rest bounds the centripetal part)
    samples : int — grid points spread along the path before refinement
    resolution : float — largest relative change of V_lim between neighbouring grid points
    step : float, s — time step of the jerk-limited forward pass (default: the period, shortened to
        resolve the jerk's time scale, A/(8J), but not below period/16, nor below 1/64 of the time the
        acceleration takes to build up); given or not, never so short that the motion takes more than
        MAX_STEPS steps
    max_duration : float, s — refuse (:class:`MotionTooLong`) a motion that, by the acceleration-limited
        optimum, takes clearly longer (1 %), before the jerk-limited pass spends its time on it
    span_feedrates : array, mm/s, one per knot span of *curve* (as its span indices), or None — a
        feedrate cap per span (the blocks' own feedrates of a path; *feedrate* is then their highest)

    Returns
    -------
    AdaptivePlan

    Examples
    --------
    >>> from nurbsinterp.nurbs import NurbsCurve
    >>> c = NurbsCurve(2, [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]],
    ...                [1, .5, .5, 1, .5, .5, 1], [0, 0, 0, .25, .5, .5, .75, 1, 1, 1])
    >>> plan = plan_adaptive(c, 0.001, 100.0, max_accel=1000.0, max_jerk=30000.0, max_normal_accel=100.0)
    >>> plan.slowest.limit, round(plan.slowest.v, 3)    # √(A_n ρ) = √(100 · 50)
    ('normal_accel', 70.711)
    >>> plan.duration == plan.ticks() * 0.001, float(plan.evaluate(plan.duration)[0]) == c.length
    (True, True)
    """
    t0 = time.perf_counter()
    lim = _limits(curve, period, feedrate, chord_tolerance, max_accel, max_jerk, max_normal_accel, axes,
                  tangential_share)
    length = curve.length
    if not length > 0:
        raise SpecError("curve: has zero length (all its control points coincide); there is nothing to plan")
    # steps 1 and 2 in one pass over the grid's blocks (see .grid and .sections): the grid is not kept
    sections, summary = _grid_sections(curve, lim, int(samples), float(resolution), span_feedrates)
    fractions = summary.fractions()
    s, u, v, binding = summary.slowest()
    slowest = Slowest(s, u, v, LIMITS[binding])
    del summary
    if not sections:  # every node at one arc length: nothing but rounding moves
        raise SpecError(f"curve: has zero length (the {length:.3g} mm computed is rounding); there is nothing to plan")
    keep = 1.0 - MARGIN
    J = None if lim.max_jerk is None else lim.max_jerk * keep
    accel_bound = min(float(a.min()) for _, _, a in sections) * keep
    accel_top = max(float(a.max()) for _, _, a in sections) * keep
    if J is None and not math.isfinite(accel_bound):
        raise SpecError("profile.max_accel is not set and the axes' max_accel do not bound the acceleration along "
                        "this path: an adaptive plan without max_jerk needs a finite acceleration limit")
    n_sections = len(sections)
    work = []
    while sections:  # the nodes' limits become the intervals' caps in place
        nodes, vl, at = sections.pop(0)
        caps = _caps(vl, keep)
        if not np.all(caps > 0):
            # not reached: V_lim is 0 only at a zero-speed span end, a section end (see sections._SectionBuilder)
            k = int(np.argmin(caps))
            raise SpecError(f"curve: the feed limit is zero near s = {nodes[k]:.6g} mm, where the adaptive planner "
                            f"cannot stop (a cusp or a zero tangent inside a knot span: insert a knot there)")
        # (a constant cap stays a broadcast view, read-only and strided: the jerk pass's kernels compile for it
        # beside the look-ahead's arrays -- their one exception to one specialisation each, until issue 47 leaves
        # one planner -- since materialising it cost 250 bytes of peak memory per control point, over the 1 KB
        # of tests/test_planner.py)
        work.append((nodes, caps, _caps(at, keep)))
    fastest = np.float64(0.0)
    for nodes, caps, acc in work:
        fastest += np.float64(_optimum_time(nodes, caps, acc))
    fastest = float(fastest)
    # the jerk-limited plan differs from this optimum by its pieces' rounding too (~1e-4 measured):
    # refuse only clearly beyond the limit and leave the rest to the caller's check of the plan
    if not fastest * 0.99 <= max_duration:
        raise MotionTooLong(fastest)
    if J is not None and not fastest <= MAX_JERK_MOTION:
        raise SpecError(f"the motion would take {fastest:.3g} s at these limits (over {MAX_JERK_MOTION:.0e} s, some "
                        f"{MAX_JERK_MOTION / 3.15576e7:,.0f} years): a jerk-limited plan that long is not made (its "
                        f"steps lose the accelerations to rounding); check interpolator.period ({lim.period:g} s), "
                        "the feedrate and chord_tolerance")
    if J is not None:
        # The forward pass costs one step per dt of motion.  dt resolves the jerk's time scale (at
        # least 8 steps in a ramp A/J, at most 16 per period), but no finer than 1/64 of the time the
        # acceleration takes to build up, whatever the period (a 1 ns period needs no 1 ns steps: the
        # plan is continuous in time), and coarse enough that the whole motion, as estimated from the
        # acceleration-limited optimum plus the jerk's ramps, takes at most MAX_STEPS steps.  A
        # coarser dt only makes the plan slower, never unsafe: every step is checked exactly.
        estimates = [_time_estimate(nodes, caps, acc, J, accel_top) for nodes, caps, acc in work]
        # The table holds absolute start times, so a piece's duration is known to ulp(t) only, and
        # the acceleration at its end to J ulp(t): the jerk is lowered so that this stays under a
        # tenth of MARGIN of the smallest acceleration cap (it binds when A/J is under ~1e-5 of the
        # motion time: a tiny cap, e.g. 0.4 mm/s² over a motion of 64 s lowers 30 000 mm/s³ to
        # 1 407 mm/s³; the ramps it lengthens are that short, 0.3 ms there).
        if math.isfinite(accel_bound):
            J_fine = 0.1 * MARGIN * accel_bound / float(np.spacing(STEP_BUDGET * sum(estimates)))
            if J_fine < J:
                J = J_fine
                estimates = [_time_estimate(nodes, caps, acc, J, accel_top) for nodes, caps, acc in work]
        v_top = max(float(caps.max()) for _, caps, _ in work)
        ramp = min(accel_top, math.sqrt(J * v_top)) / J  # the time the acceleration takes to build up
        if step is not None:
            dt = max(float(step), sum(estimates) / MAX_STEPS)
        else:
            dt = max(lim.period * min(1.0, max(1.0 / 16.0, accel_top / (8.0 * J * lim.period))), ramp / 64.0,
                     sum(estimates) / MAX_STEPS)
        coarse = dt > ramp / 8.0
    pieces = []
    bound = dict.fromkeys(BOUNDS, 0.0)  # seconds of the (stretched) motion held at each limit
    ticks = 0  # the tick on which the section starts (the previous one's stop)
    motion = 0.0  # the sum of the sections' times before their stretch
    for k in range(len(work)):
        nodes, caps, acc = work[k]
        work[k] = None  # freed as the section is planned
        if J is None:
            v = _scan(nodes, caps, acc)
            ds = np.diff(nodes)
            dur = 2.0 * ds / (v[:-1] + v[1:])
            A = (v[1:] ** 2 - v[:-1] ** 2) / (2.0 * ds)
            t_rel = np.concatenate([[0.0], np.cumsum(dur)])
            sec = np.column_stack([t_rel[:-1], nodes[:-1], v[:-1], A, np.zeros_like(A)])
            end_t = t_rel[-1]
        else:
            budget = int(min(STEP_BUDGET * estimates[k] / dt, 1e12)) + 100000
            rows, status = _jerk_limited(nodes, caps, acc, J, dt, budget, coarse)
            if status != 0:
                raise NurbsInterpError(f"the jerk-limited pass did not reach the end of the section "
                                       f"[{nodes[0]:.6g}, {nodes[-1]:.6g}] mm within {budget} steps of {dt:.3g} s "
                                       f"(stopped at s = {rows[-1, 1]:.9g} mm, t = {rows[-1, 0]:.6g} s; the "
                                       f"estimate was {estimates[k]:.6g} s)")
            # scale the section onto its exact length (it ends within 1e-10 of it)
            f = (nodes[-1] - nodes[0]) / (rows[-1, 1] - nodes[0])
            sec = rows[:-1].copy()
            sec[:, 1] = nodes[0] + (sec[:, 1] - nodes[0]) * f
            sec[:, 2:] *= f
            end_t = rows[-1, 0]
        # Stretch the section onto a whole number of ticks, so that its stop (a corner) falls on a tick:
        # a tick straddling a stop would cut the corner by up to A T²/8 (each leg A (T/2)²/2 at rest).
        # t -> λt with λ = K·T/D >= 1 (to rounding, within MARGIN) only slows: V/λ, A/λ², J/λ³.
        K = max(1, math.ceil(end_t / lim.period - 1e-9))
        lam = K * lim.period / end_t
        for name, seconds in _bound_times(sec, end_t, nodes, acc, J, lim.max_accel).items():
            bound[name] += seconds * lam
        sec[:, 0] = ticks * lim.period + sec[:, 0] * lam
        sec[:, 2] /= lam
        sec[:, 3] /= lam * lam
        sec[:, 4] /= lam ** 3
        pieces.append(sec)
        ticks += K
        motion += end_t
    duration = ticks * lim.period
    table = np.concatenate(pieces + [np.array([[duration, length, 0.0, 0.0, 0.0]])])
    lam = duration / motion
    # a piece shorter than ulp(t) (a ramp from a rounding-size acceleration) has no time of its own:
    # adaptive_at would never use it (it takes the last row at a given t)
    table = table[np.concatenate([np.diff(table[:, T_START]) > 0.0, [True]])]
    return AdaptivePlan(np.ascontiguousarray(table), length=length, period=lim.period, feedrate=lim.feedrate,
                        stretch=lam, accel_bound=accel_bound, sections=n_sections, limit_fractions=fractions,
                        slowest=slowest,
                        grid=lambda: _grid_arrays(curve, lim, int(samples), float(resolution), span_feedrates),
                        planning_time=time.perf_counter() - t0,
                        bound_fractions={name: seconds / duration for name, seconds in bound.items()})
