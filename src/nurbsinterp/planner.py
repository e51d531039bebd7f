"""Limit-aware feedrate planning along a NURBS curve: the ``adaptive`` profile (issue 7).

Given the curve, the sampling period T and a set of limits, :func:`plan_adaptive`
returns an :class:`AdaptivePlan`: a piecewise-constant-jerk motion S(t), V(t),
A(t) along the arc length that starts and ends at rest, keeps every limit, stops
(at corners) and ends exactly on ticks, and that the interpolators consume like
any other profile.

Limits (any subset; ``None`` = no limit)::

    feedrate F            mm/s    V <= F                                (required)
    chord_tolerance δ     mm      V <= (2/T) √(2ρδ − δ²)   (the chord of a step on radius ρ >= δ; 2δ/T within
                                                             2δ of arc of any ρ < δ: see "Tight turns")
    max_normal_accel A_n  mm/s²   V <= √(A_n ρ)
    axes[i].max_velocity  mm/s    V |τ_i| <= v_i
    axes[i].max_accel     mm/s²   |A τ_i + V² κ n_i| <= a_i    (see "per-axis acceleration")
    max_accel             mm/s²   |A| <= A_max                 (tangential)
    max_jerk              mm/s³   |dA/dt| <= J_max             (tangential)

Algorithm
---------
1. *Feed limit along the path.*  The curve is sampled per knot span (points
   spread in proportion to the span's length, ``samples`` in all, at least 32
   per span, both one-sided ends of every span), and V_lim = min(F, chord,
   normal, axis velocity, axis acceleration) is evaluated from the tangent τ
   and the curvature vector κn = dτ/ds = C''/σ² − C'(C'·C'')/σ⁴.  Intervals
   over which V_lim changes by more than ``resolution`` (relative) are halved
   until it does not.  Then the critical points are located exactly, per knot
   span and over all spans at once, as :meth:`NurbsCurve.curvature_maxima` does
   it: every sampled local maximum of κ and every sampled local minimum of
   V_lim (span ends included) is refined by golden section inside its bracket
   and becomes a grid point, as do the knots.  A minimum of V_lim is a minimum
   of one of its terms (where the binding term changes, min() has a concave
   kink, never a minimum), so between two grid points V_lim is at least the
   smaller of its two end values: the planner bounds V on each interval by
   that *interval cap*, and V <= V_lim holds everywhere, not only on the grid.
   The tangential acceleration bound (see below) gets the same treatment.
   *Degenerate parametrisations.*  A knot span of zero length (p + 1 equal
   control points, a repeated point of a polyline) is a point in arc length and
   is left out.  Where the parametric speed vanishes at a span end, the tangent
   there is the limit one (towards the first Bezier control point apart from the
   end) and the curvature terms of V_lim are 0 (κ grows without bound there
   unless the path goes straight on): such an end is a stop when a curvature
   limit is set.  The samples next to it whose curvature is lost in rounding
   (|C'| → 0 makes the formula cancel) are taken into the stop.  A zero of the
   speed *inside* a span where the path turns (a cusp) is refused: the planner
   stops only at knots, and without a curvature limit V_lim would not even dip
   there; inserting a knot there makes it a stop.
   *Tight turns.*  The circle formula bounds the chord h = VT on radius ρ by
   its sagitta, ρ − √(ρ² − h²/4) <= δ.  Below ρ = δ it falls, to 0 at ρ = δ/2
   (where a circle lies within 2ρ < δ of any of its chords anyway), yet a
   radius far below δ is a turn concentrated in a point: a near-cusp (two control points
   1e-10 mm apart at a turn back, ρ ~ 1e-21 mm), which the formula crawled
   through at ~1e-18 mm/s (a plan of 1e9 s; the jerk-limited pass gave up),
   while the same job with the points coincident stops there in 0.4 s.  What
   holds at any such point is simpler: a tick whose arc length is at most 2δ
   cuts its chord by at most δ, whatever the curve does, since every point of
   the arc lies within δ of arc (hence of space) of one of the tick's ends,
   which are on the chord.  So wherever ρ < δ (a grid point: the curvature
   maxima are grid points), V <= 2δ/T over a window of 2δ of arc on either side
   of it (nodes are added at the window's edges): a tick that touches the
   point lies inside the window (to leave it, it would need more than T at
   2δ/T), so its arc is at most 2δ.  The floor meets the circle formula at
   ρ = δ, where both give 2δ/T, so the limit is continuous in ρ; a near-cusp is
   passed at 2δ/T over 4δ of arc, and the motion time is continuous in the
   perturbation (within 1 % of the stop's at 0, 1e-10 ... 1e-6 mm, with or
   without a jerk limit).  A near-cusp at a knot whose first Bezier leg is
   below SINGULAR_RTOL of the span's polygon (1e-10 ... 1e-8 mm on a 10 mm
   turn back) is a zero-speed end, hence a stop, as with coincident points;
   a cusp inside a knot span is still refused.  The other curvature limits,
   √(A_n ρ) and the axis terms, have no such floor: under them alone a
   near-cusp is planned slower than the stop (2.1 s against 0.40 s at 1e-10 mm
   with A_n = 500 mm/s²), the interval caps at so sharp a minimum being far
   below the feed limit between the grid points.
2. *Stops.*  A knot where the tangent turns (a C⁰ join) is a stop: V = 0 there,
   and the path is planned as independent rest-to-rest sections.
3. *Without a jerk limit* the classic bidirectional scan on the grid is exact
   and time-optimal for the interval caps: forward v²_{k+1} <= v²_k + 2a_k Δs,
   backward v²_k <= v²_{k+1} + 2a_k Δs, v = min of both; V² is linear in s on
   each interval, i.e. one constant-acceleration piece per interval.
4. *With a jerk limit* the scan keeps its two directions, but the backward
   (deceleration) side is evaluated on demand, as a look-ahead.  The forward
   pass steps in time (``step``, T by default) and takes, by bisection, the
   largest jerk j in [−J, J] such that the step keeps the caps and the state
   after it is *safe*: the jerk-limited braking manoeuvre from that state — an
   S-curve: jerk −J down to −A_b, hold, jerk +J to A = 0 just as V reaches 0 —
   keeps V and |A| under their caps and stops before the section end.  A_b is
   the largest deceleration that every acceleration cap within the
   manoeuvre's reach allows (a harder brake stops sooner).  The bisection
   starts from the gentlest jerk (A down to −cap, V >= 0 at the end of the
   step); where the step is long against the local ramp cap/J (a tiny cap)
   that state may have too little feedrate left to bring A back to 0, and the
   bisection then starts from the jerk that ends the step with A = 0.  When no
   jerk is safe over a whole step, the manoeuvre that certified the current
   state is followed (the rest of a safe manoeuvre is safe).  Acceleration phases thus
   end in jerk-limited transitions exactly when a cap or a later slow-down
   demands it.  Each check of a constant-jerk piece against the caps is
   exact: a range-minimum table accepts or rejects whole stretches at once,
   and only near a touch is the piece split where it crosses grid points.
   *Cruise.*  Where the largest safe jerk would carry a step past the cap
   it cannot exceed, it overshoots into the opposite acceleration and the
   next step swings back: ±J·dt about the cap from step to step, a jerk
   chatter a drive turns into vibration.  So an acceleration a > 0 that can
   end on the interval's cap within the step takes the jerk that lands there,
   −a²/(2(cap − V)) >= −J (A = 0 just as V reaches the cap), and holds V for
   the rest of the step; and at the cap (to CRUISE_RTOL) with A = 0 the step
   holds V, jerk 0, for as long as that is safe (consecutive holds are one
   piece of the table).  A lower cap ahead makes the hold unsafe and the
   steps above brake for it; a higher one lets them accelerate.  A and the
   jerk are then exactly 0 wherever the plan cruises at a constant cap.  A
   cap that varies along the path is a staircase of interval caps (0.5 %
   apart at most); pressed against one (an axis velocity limit on a curve)
   the pass still swings about it.
   Safety is invariant, so the plan never violates a cap; each section ends
   within rounding of its end (measured: 1e-13 relative) and is scaled onto it.
   At rest, when the rest of the section is one rest-to-rest move that no cap
   limits (jerk +J, −J, +J: the time-optimal one), that move ends the section
   exactly; it also takes up the remainder the bisection cannot resolve.
   The step is at most 16 per period and resolves the ramps A/J (8 steps), but
   it is never below 1/64 of the time the acceleration takes to build up, nor
   so fine that the motion (as estimated from the acceleration-limited optimum
   plus the ramps) takes more than MAX_STEPS steps: the pass's cost and memory
   are bounded whatever the period or the motion time.  Where the step is long
   against the ramps, a step may also level off (A to 0 at full jerk, then V
   held), which keeps the feedrate at its cap instead of swinging about it.
5. *Stops and the end on ticks.*  Each rest-to-rest section's time D_i is
   stretched to K_i·T, K_i = ⌈D_i/T⌉, by λ_i = K_i·T/D_i >= 1: t → λ_i t,
   V → V/λ_i, A → A/λ_i², J → J/λ_i³; S(t) as a function of the path is
   unchanged, so every limit is kept (the stretch only slows, by at most one
   tick per section).  Every stop then falls on a tick: a tick that straddled
   one cut the corner by up to A T²/8 on each leg, whatever the chord limit
   does on either side (1.47 µm against δ = 1 µm at a 90° polyline corner at
   2 g and T = 1 ms; 1.28 µm at T = 4 ms and 1 000 mm/s² on a degree-2 double
   knot turning back by 159°; 13.4 µm against 10 µm on a 300-point polyline
   at 20 g).

Cost: the grid is ~30 numpy operations on a few thousand to a few tens of
thousands of points (32 per span at least, so it grows with the number of
spans), the forward pass some 25 cap checks per step where it accelerates or
brakes, one where it cruises.  On the butterfly (48 spans, ~10 000 grid points,
4 751 steps, 2 077 pieces) a plan takes ~0.08 s; the same curve with 768 spans
(knots inserted) ~0.12 s.

Per-axis acceleration
---------------------
a_i = A τ_i + V² κ n_i couples the tangential acceleration with the feedrate.
The planner splits each axis budget a_i with ``tangential_share`` β (0.4 by
default): V² κ|n_i| <= (1 − β) a_i enters V_lim, and the tangential
acceleration is bounded by what the centripetal part leaves at the highest
feedrate allowed there,

    |A| <= A_t(s) = min(A_max, min_i (a_i − V_lim(s)² κ|n_i|) / |τ_i|)   (>= β a_i / |τ_i|),

so |a_i| <= |A||τ_i| + V²κ|n_i| <= a_i always, since V <= V_lim.  The split is
conservative against the coupled constraint.  On the butterfly at F = 100 mm/s,
δ = 1 µm, A_max = 1000 mm/s² with x/y limits of 60 mm/s and 800 mm/s², the
coupled acceleration-limited optimum (a brute-force phase-plane scan) takes
6.50 s; this planner without a jerk limit takes 6.93 s (+6.5 %; +5.1 % at the
best share, β = 0.25; a fixed split |A||τ_i| <= β a_i would cost +15 %), and
7.27 s with J_max = 30 000 mm/s³.

Finite differences of the commanded positions are local averages of the
continuous derivatives (a second difference is the hat-weighted mean of a(t)
over ±T), so the per-tick axis velocities and accelerations keep the same
bounds, up to the accuracy of the positions themselves.

Interface for the per-tick kernel
---------------------------------
``AdaptivePlan.segments`` is a read-only float64 array (m, 5), one row per
constant-jerk piece ``[t_start, S_start, V_start, A_start, J]``, rows sorted by
t_start, the first at t = 0; the last row is the end state
``[duration, length, 0, 0, 0]``.  :func:`adaptive_at` (numba) evaluates it at any t.
A per-tick kernel that holds its profile as one flat float64 vector can carry
``segments.ravel()`` and call ``adaptive_at(flat.reshape(-1, 5), t)``.
:class:`AdaptivePlan` has the attributes of :class:`~nurbsinterp.profiles.Profile`
that the interpolation reads (``duration``, ``peak``, ``lowered``, ``length``,
``evaluate(t)``, ``ticks(T)``).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from .errors import NurbsInterpError, SpecError
from .nurbs import NurbsCurve, arc_length_many, eval_in_span, golden_minimum

LIMITS = ("feedrate", "chord", "normal_accel", "axis_velocity", "axis_accel")
FEEDRATE, CHORD, NORMAL_ACCEL, AXIS_VELOCITY, AXIS_ACCEL = range(5)
AXES = ("x", "y", "z")
AXIS_KEYS = ("max_velocity", "max_accel")

# columns of the segment table
T_START, S_START, V_START, A_START, JERK = range(5)

MARGIN = 1e-9             # relative margin kept on caps, accelerations and jerk (absorbs the end scaling)
CORNER_COS = 1.0 - 1e-10  # a knot whose one-sided tangents differ by more (about 1.4e-5 rad) is a stop
BISECTIONS = 24           # bisection steps for the jerk of one forward step
MIN_PER_SPAN = 32  # samples per knot span at least (as NurbsCurve.curvature_maxima)
CRUISE_RTOL = 1e-9  # a feedrate this close under its interval's cap, with A = 0, is held there (a cruise)
ATOL_FACTOR = 1.0 - 1e-12  # |A| at a cap by construction (the braking manoeuvre) may exceed it by rounding
ZERO_SPAN = 1e-13  # a knot span shorter than this fraction of the path is a point (nodes this close merge anyway)
SINGULAR_RTOL = 1e-9  # a span end whose first Bezier leg is shorter than this (relative to the span's control
#                       polygon) has zero parametric speed: its tangent is the limit one, from the next leg
CUSP_RTOL = 1e-9  # a minimum of |C'| inside a span below this fraction of the span's largest |C'| is a zero
CUSP_END = 1e-6  # ... when it lies further than this (relative to the span width) from the span's ends
MAX_REFINED = 2_000_000  # grid points the refinement may add (a bound on memory for pathological curves)
MAX_STEPS = 500_000  # forward steps the jerk-limited pass aims at: dt is coarsened to stay under it
STEP_BUDGET = 4.0  # ... and it gives up (an internal error) after this many times the estimated steps + 100000
FIELDS = {  # the job field behind each argument of plan_adaptive, as refusals name it
    "period": "interpolator.period", "feedrate": "profile.feedrate", "chord_tolerance": "profile.chord_tolerance",
    "max_accel": "profile.max_accel", "max_jerk": "profile.max_jerk", "max_normal_accel": "profile.max_normal_accel",
}


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


# --------------------------------------------------------------------------- constant-jerk pieces


@njit(cache=True)
def _advance(s, v, a, j, t):
    """State (s, v, a) after time t of constant jerk j."""
    return (s + t * (v + t * (0.5 * a + t * j / 6.0)),
            v + t * (a + 0.5 * j * t),
            a + j * t)


@njit(cache=True)
def _v_range(v, a, j, t0, t1):
    """(min, max) of v + a t + j t²/2 over [t0, t1]."""
    va = v + t0 * (a + 0.5 * j * t0)
    vb = v + t1 * (a + 0.5 * j * t1)
    lo = min(va, vb)
    hi = max(va, vb)
    if j != 0.0:
        tv = -a / j
        if t0 < tv < t1:
            vv = v + tv * (a + 0.5 * j * tv)
            lo = min(lo, vv)
            hi = max(hi, vv)
    return lo, hi


@njit(cache=True)
def _interval(nodes, s):
    """k with nodes[k] <= s < nodes[k+1], clipped to the intervals 0 .. n-2."""
    k = np.searchsorted(nodes, s, side="right") - 1
    return min(max(k, 0), nodes.shape[0] - 2)


@njit(cache=True)
def _min_table(caps):
    """Sparse table for range minima: table[l, i] = min(caps[i : i + 2**l])."""
    n = caps.shape[0]
    levels = 1
    while (1 << levels) <= n:
        levels += 1
    table = np.empty((levels, n))
    table[0] = caps
    for lev in range(1, levels):
        half = 1 << (lev - 1)
        for i in range(n - (1 << lev) + 1):
            table[lev, i] = min(table[lev - 1, i], table[lev - 1, i + half])
        for i in range(n - (1 << lev) + 1, n):
            table[lev, i] = table[lev - 1, i]
    lg = np.zeros(n + 1, dtype=np.int64)
    for i in range(2, n + 1):
        lg[i] = lg[i >> 1] + 1
    return table, lg


@njit(cache=True)
def _range_min(table, lg, i, j):
    lev = lg[j - i + 1]
    return min(table[lev, i], table[lev, j - (1 << lev) + 1])


@njit(cache=True)
def _time_at(s0, v0, a0, j, target, tlo, thi):
    """t in [tlo, thi] with s(t) = target (s non-decreasing there): safeguarded Newton."""
    t = 0.5 * (tlo + thi)
    for _ in range(100):
        s, v, _a = _advance(s0, v0, a0, j, t)
        f = s - target
        if f > 0.0:
            thi = t
        elif f < 0.0:
            tlo = t
        else:
            return t
        nt = t - f / v if v > 0.0 else 0.5 * (tlo + thi)
        if not (tlo < nt < thi):
            nt = 0.5 * (tlo + thi)
        if nt == t or thi - tlo <= 1e-16 * thi:
            return t
        t = nt
    return t


@njit(cache=True)
def _piece_ok(nodes, caps, acaps, vtab, atab, lg, s0, v0, a0, j, tau, s_end, stol, vtol):
    """Whether the piece (s0, v0, a0, jerk j, duration tau) keeps 0 <= V <= cap(S), |A| <= acap(S), S <= s_end.

    A range-minimum query accepts the whole piece at once when its largest V and |A|
    are below the smallest caps it meets; otherwise it is split where it crosses a
    grid point, until every part is accepted or a part inside one interval fails.
    """
    if tau <= 0.0:
        return True
    vlo, vhi = _v_range(v0, a0, j, 0.0, tau)
    if vlo < -vtol:
        return False
    s1 = _advance(s0, v0, a0, j, tau)[0]
    if s1 > s_end + stol:
        return False
    ka = _interval(nodes, s0)
    kb = _interval(nodes, s1)
    ahi = max(abs(a0), abs(a0 + j * tau)) * ATOL_FACTOR
    if vhi <= _range_min(vtab, lg, ka, kb) and ahi <= _range_min(atab, lg, ka, kb):
        return True
    st_a = np.empty(64)
    st_b = np.empty(64)
    st_ka = np.empty(64, dtype=np.int64)
    st_kb = np.empty(64, dtype=np.int64)
    top = 0
    st_a[0] = 0.0
    st_b[0] = tau
    st_ka[0] = ka
    st_kb[0] = kb
    while top >= 0:
        ta = st_a[top]
        tb = st_b[top]
        ia = st_ka[top]
        ib = st_kb[top]
        top -= 1
        vh = _v_range(v0, a0, j, ta, tb)[1]
        ah = max(abs(a0 + j * ta), abs(a0 + j * tb)) * ATOL_FACTOR
        if vh <= _range_min(vtab, lg, ia, ib) and ah <= _range_min(atab, lg, ia, ib):
            continue
        if ia >= ib:
            return False
        km = (ia + ib + 1) >> 1
        tc = _time_at(s0, v0, a0, j, nodes[km], ta, tb)
        top += 1
        st_a[top] = tc
        st_b[top] = tb
        st_ka[top] = km
        st_kb[top] = ib
        top += 1
        st_a[top] = ta
        st_b[top] = tc
        st_ka[top] = ia
        st_kb[top] = km - 1
    return True


@njit(cache=True)
def _brake(v, a, J, Ab):
    """Shortest jerk-limited stop from (v, a) with deceleration at most Ab.

    Jerk −J for t1 (down to −ap), hold −ap for t2, jerk +J for t3 (to A = 0 as V
    reaches 0): returns (t1, t2, t3, ap); t1 < 0 means there is no stop without V < 0.
    """
    ap = math.sqrt(max(J * v + 0.5 * a * a, 0.0))
    if a < 0.0 and ap < -a:
        if -a - ap > 1e-9 * -a:
            return -1.0, 0.0, 0.0, 0.0
        ap = -a
    if ap <= Ab:
        return (a + ap) / J, 0.0, ap / J, ap
    v1 = v + (a * a - Ab * Ab) / (2.0 * J)
    t2 = (v1 - Ab * Ab / (2.0 * J)) / Ab
    return (a + Ab) / J, max(t2, 0.0), Ab / J, Ab


@njit(cache=True)
def _stop_distance(v, a, J, Ab):
    t1, t2, t3, ap = _brake(v, a, J, Ab)
    if t1 < 0.0:
        return 0.0
    s1, v1, _a = _advance(0.0, v, a, -J, t1)
    s2 = s1 + t2 * (v1 - 0.5 * ap * t2)
    v2 = v1 - ap * t2
    return _advance(s2, v2, -ap, J, t3)[0]


@njit(cache=True)
def _brake_level(nodes, atab, lg, a_floor, a_top, J, s, v, a):
    """Deceleration for the braking manoeuvre from (s, v, a).

    The largest Ab such that every acceleration cap within the manoeuvre's reach
    is at least Ab (a harder brake stops sooner, so the reach shrinks as Ab
    grows; the path's smallest cap always qualifies), found by bisection.
    """
    ka = _interval(nodes, s)
    if not a_top < math.inf:
        return a_top
    if _range_min(atab, lg, ka, _interval(nodes, s + _stop_distance(v, a, J, a_top))) >= a_top:
        return a_top
    lo = a_floor
    hi = a_top
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _range_min(atab, lg, ka, _interval(nodes, s + _stop_distance(v, a, J, mid))) >= mid:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-6 * hi:
            break
    return lo


@njit(cache=True)
def _safe(nodes, caps, acaps, vtab, atab, lg, J, Ab, s, v, a, s_end, stol, vtol):
    """Whether the braking manoeuvre (deceleration Ab) from (s, v, a) keeps every cap and stops by s_end."""
    t1, t2, t3, ap = _brake(v, a, J, Ab)
    if t1 < 0.0:
        return False
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s, v, a, -J, t1, s_end, stol, vtol):
        return False
    s1, v1, _a1 = _advance(s, v, a, -J, t1)
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s1, v1, -ap, 0.0, t2, s_end, stol, vtol):
        return False
    s2 = s1 + t2 * (v1 - 0.5 * ap * t2)
    v2 = v1 - ap * t2
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s2, v2, -ap, J, t3, s_end, stol, vtol):
        return False
    return _advance(s2, v2, -ap, J, t3)[0] <= s_end + stol


@njit(cache=True)
def _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, j, dt, s_end, stol, vtol):
    """Whether a step of jerk j keeps the caps and ends in a safe state; also the brake level that certifies it."""
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s, v, a, j, dt, s_end, stol, vtol):
        return False, 0.0
    s1, v1, a1 = _advance(s, v, a, j, dt)
    Ab = _brake_level(nodes, atab, lg, a_floor, a_top, J, s1, v1, a1)
    return _safe(nodes, caps, acaps, vtab, atab, lg, J, Ab, s1, v1, a1, s_end, stol, vtol), Ab


@njit(cache=True)
def _level_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, jj, tau, dt, s_end, stol, vtol):
    """Whether the step that brings A to 0 with jerk jj (over tau = −a/jj <= dt) and then holds V (the rest
    of dt) keeps the caps and ends in a safe state; also the brake level that certifies it.

    Two uses: leveling off at full jerk, where dt is long against the jerk's ramps A/J (one
    constant jerk per step cannot both undo an acceleration and hold the feedrate, and the pass
    would brake to rest instead); and landing on a cap, where jj is the jerk that reaches A = 0
    just as V reaches the cap.
    """
    if not tau < dt:
        return False, 0.0
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s, v, a, jj, tau, s_end, stol, vtol):
        return False, 0.0
    s1, v1, _a1 = _advance(s, v, a, jj, tau)
    if v1 <= vtol:  # the ramp comes to rest: that is the braking manoeuvre, which ends the step there
        return False, 0.0
    if not _piece_ok(nodes, caps, acaps, vtab, atab, lg, s1, v1, 0.0, 0.0, dt - tau, s_end, stol, vtol):
        return False, 0.0
    s2 = s1 + v1 * (dt - tau)
    Ab = _brake_level(nodes, atab, lg, a_floor, a_top, J, s2, v1, 0.0)
    return _safe(nodes, caps, acaps, vtab, atab, lg, J, Ab, s2, v1, 0.0, s_end, stol, vtol), Ab


@njit(cache=True)
def _hold(out, m, t, s, v, dt):
    """Append dt of constant feedrate v from (t, s): the last row is extended when it holds v already.

    Returns (out, m, s after the hold).  An extended row keeps its start, so s is taken from it
    (s0 + v (t + dt − t0)), exactly as the table will evaluate it.
    """
    if m > 0 and out[m - 1, 4] == 0.0 and out[m - 1, 3] == 0.0 and out[m - 1, 2] == v:
        return out, m, out[m - 1, 1] + v * (t + dt - out[m - 1, 0])
    out = _push(out, m, t, s, v, 0.0, 0.0)
    return out, m + 1, s + v * dt


@njit(cache=True)
def _push(out, m, t, s, v, a, j):
    if m >= out.shape[0]:
        bigger = np.empty((2 * out.shape[0], 5))
        bigger[:m] = out[:m]
        out = bigger
    out[m, 0] = t
    out[m, 1] = s
    out[m, 2] = v
    out[m, 3] = a
    out[m, 4] = j
    return out


@njit(cache=True)
def _creep_jerk(nodes, vtab, atab, lg, J, s, gap):
    """Largest jerk (<= J) of the rest-to-rest move over *gap* from s that keeps the smallest caps on the way.

    The move is jerk +j for τ, −j for 2τ, +j for τ with 2jτ³ = gap (the time-optimal
    rest-to-rest move when no cap binds); its largest |A| is jτ and its largest V
    is jτ², so j = min(J, a³ᐟ²/√(gap/2), v³/(gap/2)²) keeps the smallest V and |A| caps.
    """
    ka = _interval(nodes, s)
    kb = _interval(nodes, s + gap)
    vc = _range_min(vtab, lg, ka, kb) * ATOL_FACTOR
    ac = _range_min(atab, lg, ka, kb) * ATOL_FACTOR
    h = 0.5 * gap
    return min(J, ac * math.sqrt(ac / h), vc * vc * vc / (h * h))


@njit(cache=True)
def _jerk_limited(nodes, caps, acaps, J, dt, max_steps, coarse):
    """Forward pass of the jerk-limited planner on one rest-to-rest section.

    caps, acaps : per interval, the bounds of V and |A|; coarse : dt is long against the
    jerk's ramps (see the level-off step below).  Returns (pieces, status):
    rows [t, s, v, a, j] (t from 0, s absolute), the last row being the final
    state with j = 0; status 0 on success, 1 when the end was not reached within
    max_steps.
    """
    n = nodes.shape[0]
    s_end = nodes[n - 1]
    span = s_end - nodes[0]
    stol = 1e-13 * max(abs(s_end), span)
    end_tol = 1e-10 * span  # the section is scaled onto its length: within MARGIN of every limit
    vtol = 1e-12 * max(caps.max(), 1.0)
    vtab, lg = _min_table(caps)
    atab = _min_table(acaps)[0]
    a_floor = acaps.min()
    a_top = acaps.max()
    v_top = caps.max()
    out = np.empty((1024, 5))
    m = 0
    s = nodes[0]
    v = 0.0
    a = 0.0
    t = 0.0
    Ab_safe = a_floor  # the brake level that certified the current state
    status = 1
    stalled = False
    for step in range(max_steps + 1):
        if v == 0.0 and a == 0.0:
            # At rest (the start, or the end of a braking manoeuvre short of the section end, where
            # the bisection's resolution leaves it): when the rest of the section is a single
            # rest-to-rest move that no cap limits, that move is time-optimal and lands exactly on
            # the end, so it finishes the section.  After a step that could not move at all (no
            # positive jerk was safe, down to the smallest double: a gap of rounding size) the move
            # is taken with the jerk lowered to fit the caps.
            gap = s_end - s
            if gap <= end_tol:
                status = 0
                break
            jc = _creep_jerk(nodes, vtab, atab, lg, J, s, gap)
            if jc > 0.0 and (jc >= J or stalled):
                tau = (gap / (2.0 * jc)) ** (1.0 / 3.0)
                for jj, d in ((jc, tau), (-jc, 2.0 * tau), (jc, tau)):
                    out = _push(out, m, t, s, v, a, jj)
                    m += 1
                    s, v, a = _advance(s, v, a, jj, d)
                    t += d
                v = 0.0
                a = 0.0
                status = 0
                break
        if step == max_steps:
            break
        # Cruise.  At a cap with A = 0 the feedrate is held (jerk 0) for as long as that is safe; and
        # an acceleration that can end on the cap within the step takes the jerk that lands there,
        # A = 0 just as V reaches the cap, then holds.  The largest constant jerk of a whole step
        # would overshoot into the opposite acceleration instead, and swing from −J to +J about the
        # cap from step to step (a chatter of ±J·dt in A).  The cap ahead, if lower, makes the
        # hold unsafe, and the steps below brake for it.
        cap = caps[_interval(nodes, s)]
        if v > 0.0 and a == 0.0 and v >= cap * (1.0 - CRUISE_RTOL):
            ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, 0.0, 0.0, dt, s_end,
                              stol, vtol)
            if ok:
                out, m, s = _hold(out, m, t, s, v, dt)
                t += dt
                Ab_safe = Ab
                continue
        elif a > 0.0 and v < cap - vtol and 2.0 * (cap - vtol - v) < a * dt:
            # the ramp from a to 0 that ends on the cap (less vtol) takes tau = 2 (cap − v) / a; a
            # state on the brake's frontier, V + A²/2J at the cap, may ask a hair more than J: the
            # ramp at J then ends within vtol of the cap
            tau = max(2.0 * (cap - vtol - v) / a, a / J)
            ok, Ab = _level_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, -a / tau, tau, dt,
                               s_end, stol, vtol)
            if ok:
                out = _push(out, m, t, s, v, a, -a / tau)
                m += 1
                s, v, _a = _advance(s, v, a, -a / tau, tau)
                a = 0.0
                out, m, s = _hold(out, m, t + tau, s, v, dt - tau)
                t += dt
                Ab_safe = Ab
                continue
        # the jerks worth trying: |A| within the caps here, V >= 0 at the end of the step
        ac = acaps[_interval(nodes, s)]
        jhi = min(J, (a_top - a) / dt)
        if coarse:  # no V above the largest cap at the end of the step: the bisection's range to scale
            jhi = min(jhi, max(2.0 * (v_top - v - a * dt) / (dt * dt), 0.0))
        jlo = max(-J, (-ac - a) / dt, -2.0 * (v + a * dt) / (dt * dt))
        if jlo > jhi:
            jlo = jhi
        j = math.nan
        ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, jhi, dt, s_end,
                          stol, vtol)
        if ok:
            j = jhi
        else:
            ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, jlo, dt, s_end,
                              stol, vtol)
            anchor = jlo
            if not ok and (coarse or ac < J * dt):
                # over a step long against the ramps (everywhere, or here, where the acceleration cap
                # is tiny: A/J below the step) the gentlest jerk ends at V = 0 with A < 0 or at
                # A = −cap with too little V left to ramp A back to 0, which is not safe; the jerk
                # that ends the step with A = 0 (cruising, from a steady state) may be.  Without it
                # the pass followed the brake to rest and crawled (issue 13: y max_accel 1 mm/s²)
                anchor = min(max(-a / dt, jlo), jhi)
                ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, anchor, dt, s_end,
                                  stol, vtol)
            if ok:
                lo = anchor
                hi = jhi
                Ab_lo = Ab
                for _b in range(BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, mid, dt, s_end,
                                      stol, vtol)
                    if ok:
                        lo = mid
                        Ab_lo = Ab
                    else:
                        hi = mid
                if v == 0.0 and a == 0.0 and lo <= 0.0:
                    # at rest, a safe jerk may lie below the bisection's resolution (a tiny cap, as
                    # next to a zero-speed end): keep halving until one moves
                    for _b in range(1000):
                        hi = 0.5 * hi
                        if hi <= 0.0:
                            break
                        ok, Ab = _step_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, hi, dt,
                                          s_end, stol, vtol)
                        if ok:
                            lo = hi
                            Ab_lo = Ab
                            break
                j = lo
                Ab = Ab_lo
        # Leveling off (A to 0 at full jerk, then V held) when no constant jerk is safe, and, where
        # dt is long against the ramps (coarse), also when it gets farther: there the largest safe
        # constant jerk overshoots into the opposite acceleration and the feedrate swings about
        # its cap from step to step.
        if v > 0.0 and a != 0.0 and abs(a) < J * dt:
            tau = abs(a) / J
            jj = -J if a > 0.0 else J
            s_lev = _advance(s, v, a, jj, tau)[0] + _advance(0.0, v, a, jj, tau)[1] * (dt - tau)
            if j != j or (coarse and s_lev > _advance(s, v, a, j, dt)[0]):
                ok, Ab_lev = _level_ok(nodes, caps, acaps, vtab, atab, lg, a_floor, a_top, J, s, v, a, jj, tau, dt,
                                       s_end, stol, vtol)
                if ok:
                    out = _push(out, m, t, s, v, a, jj)
                    m += 1
                    s, v, a = _advance(s, v, a, jj, tau)
                    out = _push(out, m, t + tau, s, v, 0.0, 0.0)
                    m += 1
                    s += v * (dt - tau)
                    a = 0.0
                    t += dt
                    Ab_safe = Ab_lev
                    continue
        if j == j:
            stalled = v == 0.0 and a == 0.0 and j <= 0.0
            if stalled:
                continue  # a step at rest that would not move: the move above takes over
            out = _push(out, m, t, s, v, a, j)
            m += 1
            s, v, a = _advance(s, v, a, j, dt)
            t += dt
            Ab_safe = Ab
            continue
        # no step is safe: follow the braking manoeuvre that certified the current state (the
        # rest of a safe manoeuvre is safe)
        t1, t2, t3, ap = _brake(v, a, J, Ab_safe)
        if t1 < 0.0:
            t1 = 0.0
            t3 = max(-a, 0.0) / J
            ap = max(-a, 0.0)
        left = dt
        for phase in range(3):
            dur = t1 if phase == 0 else (t2 if phase == 1 else t3)
            if dur <= 0.0 or left <= 0.0:
                continue
            jj = -J if phase == 0 else (0.0 if phase == 1 else J)
            if phase > 0:
                a = -ap
            d = min(dur, left)
            out = _push(out, m, t, s, v, a, jj)
            m += 1
            s, v, a = _advance(s, v, a, jj, d)
            t += d
            left -= d
        if t1 + t2 + t3 <= dt:  # at rest
            v = 0.0
            a = 0.0
            Ab_safe = a_floor
    out = _push(out, m, t, s, v, a, 0.0)
    return out[: m + 1], status


@njit(cache=True)
def _scan(nodes, caps, acc):
    """Bidirectional scan without a jerk limit: V at the nodes (0 at both ends)."""
    n = nodes.shape[0]
    v = np.empty(n)
    v[0] = 0.0
    for k in range(n - 1):
        w = 0.0 if k + 1 == n - 1 else min(caps[k], caps[k + 1])
        v[k + 1] = min(w, math.sqrt(v[k] * v[k] + 2.0 * acc[k] * (nodes[k + 1] - nodes[k])))
    v[n - 1] = 0.0
    for k in range(n - 2, -1, -1):
        v[k] = min(v[k], math.sqrt(v[k + 1] * v[k + 1] + 2.0 * acc[k] * (nodes[k + 1] - nodes[k])))
    return v


# --------------------------------------------------------------------------- the feed limit along the path


@dataclass(frozen=True)
class _Limits:
    period: float
    feedrate: float
    chord_tolerance: float | None
    max_accel: float | None
    max_jerk: float | None
    max_normal_accel: float | None
    axis_velocity: np.ndarray  # (dim,), inf where none
    axis_accel: np.ndarray  # (dim,), inf where none
    share: float

    @property
    def has_axis_accel(self) -> bool:
        return bool(np.isfinite(self.axis_accel).any())

    @property
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


def _limits(curve, period, feedrate, chord_tolerance, max_accel, max_jerk, max_normal_accel, axes, share):
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
    lim = _Limits(period, feedrate, _positive("chord_tolerance", chord_tolerance), _positive("max_accel", max_accel),
                  _positive("max_jerk", max_jerk), _positive("max_normal_accel", max_normal_accel), vel, acc,
                  float(share))
    if lim.max_accel is None and not lim.has_axis_accel and lim.max_jerk is None:
        raise SpecError("profile.max_accel is not set: an adaptive plan needs max_accel (or accel_time > 0), "
                        "an axis max_accel or max_jerk; without any of them the feedrate could jump")
    return lim


def _derivs(curve, us, spans):
    out = np.empty((us.shape[0], 3, curve.dim))
    eval_in_span(curve.knots, curve.bezier, curve.degree, np.ascontiguousarray(us, dtype=float),
                 np.ascontiguousarray(spans, dtype=np.int64), 2, out)
    return out


def _frame(d):
    """Unit tangent τ and curvature vector κn = dτ/ds from a derivative table (N, 3, dim)."""
    d1 = d[:, 1, :]
    d2 = d[:, 2, :]
    sig2 = np.einsum("ij,ij->i", d1, d1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tau = d1 / np.sqrt(sig2)[:, None]
        kn = d2 / sig2[:, None] - d1 * (np.einsum("ij,ij->i", d1, d2) / (sig2 * sig2))[:, None]
    return tau, kn


def _is_point(curve, i):
    """Whether knot span i is a single point: its Bezier control points coincide up to rounding."""
    B = curve.bezier[i, 0]
    P = B[:, :-1] / B[:, -1:]
    return bool(np.ptp(P, axis=0).max() <= 64.0 * np.finfo(float).eps * max(float(np.abs(P).max()), 1e-300))


def _end_tangents(curve, spans):
    """Per span index (arrays of curve.n + 2 rows): whether the parametric speed vanishes at the span's start
    and at its end, and the one-sided unit tangents there (the direction of motion).

    From the span's Bezier control points P_0..P_p: near the start C(u) − P_0 is dominated by
    (P_j − P_0)(u − a)^j for the first P_j apart from P_0, so the limit tangent points from P_0
    to that P_j (rational or not), and likewise backwards at the end.  Where P_1 ≈ P_0 the
    derivative is zero or rounding noise and gives no direction.
    """
    rows = curve.n + 2
    dim = curve.dim
    sing = np.zeros((2, rows), dtype=bool)
    tang = np.full((2, rows, dim), np.nan)
    for i, _a, _b in spans:
        B = curve.bezier[i, 0]
        P = B[:, :dim] / B[:, dim:]
        for side, (base, others, sign) in enumerate(((P[0], P[1:], 1.0), (P[-1], P[-2::-1], -1.0))):
            d = others - base
            dist = np.sqrt(np.einsum("ij,ij->i", d, d))
            far = dist > SINGULAR_RTOL * dist.max()
            if not far.any():
                sing[side, i] = True  # a point: such spans are left out of the grid
                continue
            k = int(np.argmax(far))
            sing[side, i] = k > 0
            tang[side, i] = sign * d[k] / dist[k]
    return sing, tang


def _feed_limits(d, lim: _Limits, singular=None, tangent=None):
    """Every term of V_lim (N, 5), mm/s, the tangential acceleration bound (N,), mm/s², κ (N,), 1/mm, and τ (N, dim).

    *singular* marks span ends where the parametric speed vanishes; *tangent* holds their limit
    tangents.  The curvature there is undefined (and mostly infinite: near such an end C − P_0
    grows as (u − a)^j, j >= 2, and κ as s^(1/j − 1) unless the next leg is collinear), so the
    terms that depend on it are 0: a zero-speed end is a stop whenever a curvature limit is set.
    At V = 0 the centripetal part of an axis budget is 0, so the tangential bound takes all of it.
    """
    tau, kn = _frame(d)
    sing = singular is not None and bool(singular.any())
    if sing:
        tau = np.where(singular[:, None], tangent, tau)
        kn = np.where(singular[:, None], 0.0, kn)
    n = tau.shape[0]
    comps = np.full((n, len(LIMITS)), np.inf)
    comps[:, FEEDRATE] = lim.feedrate
    kappa = np.sqrt(np.einsum("ij,ij->i", kn, kn))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rho = 1.0 / kappa
        if lim.chord_tolerance is not None:
            dl = lim.chord_tolerance
            # below ρ = δ the circle formula falls to 0 (ρ < δ/2) while the chord error it guards against
            # vanishes; the floor 2δ/T holds V on a tick's worth of arc either side (see "Tight turns")
            chord = np.where(rho < dl, dl, np.sqrt(np.maximum(2.0 * rho * dl - dl * dl, 0.0)))
            comps[:, CHORD] = 2.0 / lim.period * chord
        if lim.max_normal_accel is not None:
            comps[:, NORMAL_ACCEL] = np.sqrt(lim.max_normal_accel * rho)
        abs_tau = np.abs(tau)
        if np.isfinite(lim.axis_velocity).any():
            comps[:, AXIS_VELOCITY] = np.min(lim.axis_velocity / abs_tau, axis=1)
        acc_t = np.full(n, np.inf if lim.max_accel is None else lim.max_accel)
        if lim.has_axis_accel:
            comps[:, AXIS_ACCEL] = np.min(np.sqrt((1.0 - lim.share) * lim.axis_accel / np.abs(kn)), axis=1)
    comps = np.nan_to_num(comps, nan=0.0, posinf=np.inf)  # a zero tangent (cusp) stops the motion
    if sing:
        for col, active in ((CHORD, lim.chord_tolerance is not None), (NORMAL_ACCEL, lim.max_normal_accel is not None),
                            (AXIS_ACCEL, lim.has_axis_accel)):
            if active:
                comps[singular, col] = 0.0
        kappa = np.where(singular, np.nan, kappa)
    if lim.has_axis_accel:
        # what the centripetal part leaves of each axis budget at the highest feedrate allowed here
        vmax = comps.min(axis=1)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            left = (lim.axis_accel - vmax[:, None] ** 2 * np.abs(kn)) / abs_tau
        acc_t = np.minimum(acc_t, np.nan_to_num(np.min(left, axis=1), nan=0.0, posinf=np.inf))
    return comps, acc_t, kappa, tau


def _rel_change(x):
    """|Δx| / min of the two, between neighbours: 0 where they are equal (0 and 0, inf and inf), inf from 0."""
    a, b = x[:-1], x[1:]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = np.abs(a - b) / np.minimum(a, b)
    out = np.where(a == b, 0.0, out)
    return np.nan_to_num(out, nan=np.inf, posinf=np.inf)


def _discrete_minima(values, spans, valid=None):
    """Sampled local minima of values within each knot span: (index, bracket lo, bracket hi).

    A sample no larger than its neighbours in the same span, and smaller than one
    of them, brackets a minimum between those neighbours; at a span end the
    bracket is the last interval (the minimum may lie just inside the span).
    Samples not *valid* (zero-speed span ends) are no minima and end the span for
    their neighbours, so that no bracket reaches them.
    """
    n = values.shape[0]
    idx = np.arange(n)
    ok = np.ones(n, dtype=bool) if valid is None else valid
    has_prev = np.zeros(n, dtype=bool)
    has_next = np.zeros(n, dtype=bool)
    has_prev[1:] = (spans[1:] == spans[:-1]) & ok[:-1]
    has_next[:-1] = (spans[:-1] == spans[1:]) & ok[1:]
    prev = np.where(has_prev, np.roll(values, 1), np.inf)
    nxt = np.where(has_next, np.roll(values, -1), np.inf)
    is_min = (values <= prev) & (values <= nxt) & ((values < prev) | (values < nxt)) & np.isfinite(values) \
        & (has_prev | has_next) & ok
    j = idx[is_min]
    return j, np.where(has_prev[j], j - 1, j), np.where(has_next[j], j + 1, j)


def _refuse_cusps(curve, u, span, speed, singular, width):
    """SpecError when the parametric speed vanishes inside a knot span and the tangent turns there.

    A zero-speed point at a knot is planned as a stop; inside a span it is refused
    (the planner stops only at knots): a cusp has no feed limit to find there —
    without a curvature limit V_lim stays F on both sides of a reversal — so
    it would be passed at speed.  Inserting a knot there makes it a stop.  The
    sampled minima of |C'| are refined by golden section; zero-speed points where
    the path goes straight on (a stationary parametrisation) are planned through.
    """
    smax = np.zeros(width.shape[0])
    np.maximum.at(smax, span, speed)
    j, lo, hi = _discrete_minima(speed, span)
    pick = ~singular[j] & (speed[j] <= 0.1 * smax[span[j]])
    if not pick.any():
        return
    lo, hi, sp = u[lo[pick]], u[hi[pick]], span[j[pick]]

    def f(uu):
        d1 = _derivs(curve, uu, sp)[:, 1, :]
        return np.sqrt(np.einsum("ij,ij->i", d1, d1))

    uc = golden_minimum(f, lo, hi)
    w = width[sp]
    a0 = curve.knots[sp]
    b0 = curve.knots[sp + 1]
    inside = (uc - a0 > CUSP_END * w) & (b0 - uc > CUSP_END * w) & (f(uc) <= CUSP_RTOL * smax[sp])
    if not inside.any():
        return
    k = np.flatnonzero(inside)
    delta = 0.5 * CUSP_END * w[k]
    tb = _frame(_derivs(curve, uc[k] - delta, sp[k]))[0]
    ta = _frame(_derivs(curve, uc[k] + delta, sp[k]))[0]
    turn = np.einsum("ij,ij->i", tb, ta)
    bad = np.flatnonzero(~(turn >= CORNER_COS))
    if bad.size:
        i = k[bad[0]]
        point = ", ".join(f"{x:.6g}" for x in curve.evaluate(float(uc[i])))
        angle = math.degrees(math.acos(min(1.0, max(-1.0, float(turn[bad[0]]))))) if np.isfinite(turn[bad[0]]) \
            else 180.0
        raise SpecError(f"curve: the parametric speed vanishes at u = {uc[i]:.9g}, point ({point}), inside the knot "
                        f"span [{a0[i]:.6g}, {b0[i]:.6g}], and the path turns by {angle:.3g} degrees there (a cusp); "
                        f"the adaptive planner stops only at knots: insert a knot at u = {uc[i]:.9g}")


def _curvature_noise(curve, spans):
    """Per span index: the rounding of C' and of C'' (absolute, mm per unit u and per unit u²), generously.

    C' = (A' − w'C)/w from the homogeneous derivative A' = (A'_xyz, w'), each a de Casteljau sum
    of the span's derivative Bezier coefficients: its error is some ulp of those coefficients
    (not of |C'|, which is far smaller where the speed vanishes, above all with unequal weights).
    """
    rows = curve.n + 2
    dim = curve.dim
    d1 = np.zeros(rows)
    d1w = np.zeros(rows)
    d2 = np.zeros(rows)
    d2w = np.zeros(rows)
    wmin = np.ones(rows)
    for i in spans:
        B = curve.bezier[i]
        wmin[i] = float(np.min(B[0, :, dim]))
        d1[i] = float(np.abs(B[1, :, :dim]).max())
        d1w[i] = float(np.abs(B[1, :, dim]).max())
        if curve.degree >= 2:
            d2[i] = float(np.abs(B[2, :, :dim]).max())
            d2w[i] = float(np.abs(B[2, :, dim]).max())
    ulp = 16.0 * np.finfo(float).eps
    return ulp * d1 / wmin, ulp * d1w / wmin, ulp * (d2 + 2.0 * d1w * d1 / wmin) / wmin, ulp * d2w / wmin


def _near_stops(span, singular, unresolved):
    """The zero-speed span ends, and the samples next to them whose curvature is lost in rounding.

    As |C'| → 0 the curvature formula cancels: on a straight span that starts with zero speed
    it gives ~1e29 1/mm at u − a = 1e-13, and V_lim ~ 1e-18 mm/s.  Such samples (within ~1e-6
    mm of the end on the curves measured, 1e-8 of their length) are taken into the stop: their
    limits are ignored, the refinement does not go past them, and the interval from the stop to
    the first sample whose curvature is resolved takes that sample's limits — the plan leaving
    or reaching a stop is far below the feed limit that close to it (V ~ √(2As) from rest,
    V_lim ~ s^(1/4..1/3) where κ grows at a zero-speed end).
    """
    near = singular.copy()
    n = span.shape[0]
    for k in np.flatnonzero(singular):
        for step in (1, -1):
            i = k + step
            while 0 <= i < n and span[i] == span[k] and unresolved[i]:
                near[i] = True
                i += step
    return near


@dataclass
class _Grid:
    u: np.ndarray
    span: np.ndarray
    s: np.ndarray
    comps: np.ndarray
    acc_t: np.ndarray
    tangent: np.ndarray
    singular: np.ndarray  # zero-speed span ends (their tangent is the limit one)
    near: np.ndarray  # singular, and the samples taken into it (see _near_stops)
    tight: np.ndarray  # radius of curvature below the chord tolerance (see "Tight turns")

    @property
    def v_limit(self):
        return self.comps.min(axis=1)


def _build_grid(curve: NurbsCurve, lim: _Limits, samples: int, resolution: float) -> _Grid:
    spans = curve.span_ranges()
    starts = np.array([a for _, a, _ in spans] + [spans[-1][2]])
    s_knots = curve.arc_length_at(starts)
    length = curve.length
    # A span of zero length (its control points coincide: a repeated point of a polyline, p + 1 equal
    # points) has no place in arc length: it is left out, and its neighbours meet at one point, a stop
    # if the tangent turns there.  Its V_lim would be 0/0 everywhere.
    kept = [(sp, ls) for sp, ls in zip(spans, np.diff(s_knots))
            if ls > ZERO_SPAN * length and not _is_point(curve, sp[0])]
    if not kept:  # a rational curve whose control points coincide: its length is rounding
        raise SpecError(f"curve: has zero length (its control points coincide; the {length:.3g} mm computed is "
                        "rounding); there is nothing to plan")
    us, sp = [], []
    for (i, a, b), ls in kept:
        count = max(MIN_PER_SPAN, int(math.ceil(samples * ls / length)))
        us.append(np.linspace(a, b, count + 1))
        sp.append(np.full(count + 1, i, dtype=np.int64))
    u = np.concatenate(us)
    span = np.concatenate(sp)
    width = np.zeros(curve.n + 2)
    for (i, a, b), _ls in kept:
        width[i] = b - a
    end_sing, end_tan = _end_tangents(curve, [k for k, _ls in kept])
    knots = curve.knots

    def at_ends(uu, ss):
        start = uu == knots[ss]
        end = uu == knots[ss + 1]
        singular = (start & end_sing[0, ss]) | (end & end_sing[1, ss])
        return singular, np.where(start[:, None], end_tan[0, ss], end_tan[1, ss])

    e1, e1w, e2, e2w = _curvature_noise(curve, [k for (k, _a, _b), _ls in kept])
    kappa_bind = lim.kappa_bind
    curving = lim.chord_tolerance is not None or lim.max_normal_accel is not None or lim.has_axis_accel

    def evaluate(uu, ss):
        singular, tangent = at_ends(uu, ss)
        d = _derivs(curve, uu, ss)
        comps, acc_t, kappa, tau = _feed_limits(d, lim, singular, tangent)
        # Where rounding alone could move κ by 1e-3 of what matters, the curvature terms are noise
        # (next to a zero-speed end: see _near_stops).  κ = |C''⊥|/σ²: an error δ1 in C' tilts
        # the tangent by δ1/σ, so κ's error is (δ2 + |C''| δ1/σ)/σ².
        unresolved = np.zeros(uu.shape[0], dtype=bool)
        if curving:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                c = np.sqrt(np.einsum("ij,ij->i", d[:, 0], d[:, 0]))
                sig = np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1]))
                acc2 = np.sqrt(np.einsum("ij,ij->i", d[:, 2], d[:, 2]))
                err = (e2[ss] + e2w[ss] * c + acc2 * (e1[ss] + e1w[ss] * c) / sig) / (sig * sig)
                unresolved = ~(err <= 1e-3 * np.maximum(np.nan_to_num(kappa, nan=0.0), kappa_bind)) & ~singular
        return comps, acc_t, kappa, tau, unresolved, singular

    d = _derivs(curve, u, span)
    _refuse_cusps(curve, u, span, np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1])), at_ends(u, span)[0], width)
    cols = (u, span, *evaluate(u, span))  # u, span, comps, acc_t, kappa, tangent, unresolved, singular
    initial = u.shape[0]
    # halve every interval over which V_lim (or the tangential bound) changes too much; next to a
    # zero-speed end (V_lim = 0 there) that goes on down to the samples taken into the stop, or
    # to 2^-40 of the span
    for _ in range(40):
        u, span, comps, acc_t = cols[:4]
        taken = _near_stops(span, cols[7], cols[6]) & ~cols[7]
        need = (span[1:] == span[:-1]) & ((_rel_change(comps.min(axis=1)) > resolution)
                                          | (_rel_change(acc_t) > resolution)) \
            & (np.diff(u) > width[span[:-1]] * 2.0 ** -40) & ~taken[:-1] & ~taken[1:]
        idx = np.flatnonzero(need)
        if idx.size == 0:
            break
        if u.shape[0] + idx.size > initial + MAX_REFINED:
            k = int(idx[0])
            raise SpecError(f"curve: the feed limit varies too fast to be resolved near u = {u[k]:.9g} (more than "
                            f"{MAX_REFINED} grid points; extreme weights, knot spans or curvature)")
        nu = 0.5 * (u[idx] + u[idx + 1])
        nsp = span[idx]
        cols = _merge(cols, (nu, nsp, *evaluate(nu, nsp)))
    u, span, comps, acc_t, kappa, tangent, unresolved, singular = cols
    near = _near_stops(span, singular, unresolved)
    # the exact local minima of V_lim and of the tangential bound, and the curvature maxima
    # (as NurbsCurve.curvature_maxima finds them), become grid points; the stops
    # at zero-speed span ends take no part (their V_lim is 0 by decree, not a minimum to refine)
    extra_u, extra_sp = [], []
    searches = [(comps.min(axis=1), "v"), (acc_t, "a")]
    if lim.chord_tolerance is not None or lim.max_normal_accel is not None or lim.has_axis_accel:
        searches.append((-kappa, "k"))
    for values, column in searches:
        _j, lo, hi = _discrete_minima(values, span, ~near)
        if lo.size:
            ss = span[lo]

            def f(uu, ss=ss, column=column):
                comps_, acc_, kappa_ = evaluate(uu, ss)[:3]
                return comps_.min(axis=1) if column == "v" else (acc_ if column == "a" else -kappa_)

            extra_u.append(golden_minimum(f, u[lo], u[hi]))
            extra_sp.append(ss)
    if extra_u:
        nu = np.concatenate(extra_u)
        nsp = np.concatenate(extra_sp)
        cols = _merge(cols, (nu, nsp, *evaluate(nu, nsp)))
        u, span, comps, acc_t, kappa, tangent, unresolved, singular = cols
        near = _near_stops(span, singular, unresolved)
    s = np.empty(u.shape[0])
    arc_length_many(curve.knots, curve.bezier, curve.degree, *curve.panels, np.ascontiguousarray(u), s)
    # one-sided values at the knots: both ends of a span are evaluated on that span
    tight = np.zeros(u.shape[0], dtype=bool)
    if lim.chord_tolerance is not None:
        with np.errstate(invalid="ignore"):
            tight = (kappa * lim.chord_tolerance > 1.0) & ~near
    return _Grid(u, span, s, comps, acc_t, tangent, singular, near, tight)


def _merge(old, new):
    """Merge two sets of samples (u, span, values...), sorted by (span, u), without duplicates."""
    cols = [np.concatenate([a, b]) for a, b in zip(old, new)]
    u, span = cols[0], cols[1]
    order = np.lexsort((u, span))
    cols = [c[order] for c in cols]
    u, span = cols[0], cols[1]
    keep = np.ones(u.shape[0], dtype=bool)
    keep[1:] = (u[1:] != u[:-1]) | (span[1:] != span[:-1])
    return tuple(c[keep] for c in cols)


def _tight_windows(s_tight, reach):
    """The arc-length windows [s − reach, s + reach] around the tight points, merged: (lo, hi) arrays."""
    if s_tight.size == 0:
        return np.empty(0), np.empty(0)
    s_tight = np.sort(s_tight)
    lo, hi = s_tight - reach, s_tight + reach
    new = np.concatenate([[True], lo[1:] > hi[:-1]])  # a window that starts past the previous end
    starts = np.flatnonzero(new)
    ends = np.concatenate([starts[1:], [s_tight.size]]) - 1
    return lo[starts], np.maximum.accumulate(hi)[ends]


def _floor_windows(nodes, vmin, amin, lo, hi, floor):
    """Cap V at *floor* over the windows [lo, hi]: nodes at the window edges (their limits the smaller of
    the interval's ends, which bound it from below), and V_lim <= floor at every node inside."""
    tol = 1e-13 * max(abs(float(nodes[-1])), 1.0)
    edges = np.concatenate([lo, hi])
    edges = edges[(edges > nodes[0] + tol) & (edges < nodes[-1] - tol)]
    if edges.size:
        edges = np.unique(edges)
        k = np.searchsorted(nodes, edges)
        far = (edges - nodes[k - 1] > tol) & (nodes[k] - edges > tol)  # otherwise a node is there already
        edges, k = edges[far], k[far]
        nodes = np.insert(nodes, k, edges)
        vmin = np.insert(vmin, k, np.minimum(vmin[k - 1], vmin[k]))
        amin = np.insert(amin, k, np.minimum(amin[k - 1], amin[k]))
    w = np.searchsorted(lo, nodes + tol, side="right") - 1  # the last window starting at or before the node
    inside = (w >= 0) & (nodes - tol <= hi[np.maximum(w, 0)])
    return nodes, np.where(inside, np.minimum(vmin, floor), vmin), amin


def _sections(grid: _Grid, floor: float = math.inf, reach: float = 0.0):
    """Split the grid at stops: [(s nodes, V_lim at nodes, tangential bound at nodes)] per rest-to-rest section.

    At a smooth knot the two one-sided samples merge (the smaller limits win);
    at a corner they stay apart, ending one section and starting the next.  A
    zero-speed span end with V_lim = 0 (a curvature limit is set) is a stop too.
    V_lim is at most *floor* within *reach* of arc length of every tight point
    (radius below the chord tolerance; see "Tight turns" in the module docstring).
    """
    lo_w, hi_w = _tight_windows(grid.s[grid.tight], reach)
    s, vl, at, span = grid.s, grid.v_limit, grid.acc_t, grid.span
    n = s.shape[0]
    boundary = np.flatnonzero(span[1:] != span[:-1])  # pairs (k, k+1) at a knot
    stop = grid.singular & (vl == 0.0)
    corner = ~(np.einsum("ij,ij->i", grid.tangent[boundary], grid.tangent[boundary + 1]) >= CORNER_COS) \
        | stop[boundary] | stop[boundary + 1]
    # A stop's V_lim = 0 belongs to the point only: V = 0 there anyway.  The interval next to it was
    # halved down to the samples taken into the stop (V_lim changes from 0), which are left out,
    # and takes its cap from its other end.
    vl = np.where(stop, np.inf, vl)
    at = at.copy()
    drop = grid.near & ~grid.singular
    smooth = boundary[~corner]
    vl[smooth] = np.minimum(vl[smooth], vl[smooth + 1])
    at[smooth] = np.minimum(at[smooth], at[smooth + 1])
    drop[smooth + 1] = True
    cuts = [0] + list(boundary[corner] + 1) + [n]
    out = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        keep = np.flatnonzero(~drop[a:b]) + a
        ss, vv, aa = s[keep], vl[keep], at[keep]
        # nodes at the same arc length (a refined minimum on top of a sample): the smaller limits win
        first = np.ones(ss.shape[0], dtype=bool)
        first[1:] = np.diff(ss) > 1e-13 * max(abs(ss[-1]), 1.0)
        groups = np.cumsum(first) - 1
        m = groups[-1] + 1
        nodes = ss[first]
        vmin = np.full(m, np.inf)
        amin = np.full(m, np.inf)
        np.minimum.at(vmin, groups, vv)
        np.minimum.at(amin, groups, aa)
        if nodes.shape[0] >= 2 and nodes[-1] > nodes[0]:
            if np.isinf(vmin[0]):
                vmin[0] = vmin[1]
            if np.isinf(vmin[-1]):
                vmin[-1] = vmin[-2]
            if nodes.shape[0] == 2:  # the scan needs a node between the two stops (V = 0 at both)
                nodes = np.array([nodes[0], 0.5 * (nodes[0] + nodes[1]), nodes[1]])
                vmin = np.array([vmin[0], vmin.min(), vmin[1]])
                amin = np.array([amin[0], amin.min(), amin[1]])
            if lo_w.size:
                nodes, vmin, amin = _floor_windows(nodes, vmin, amin, lo_w, hi_w, floor)
            out.append((nodes, vmin, amin))
    return out


# --------------------------------------------------------------------------- the plan


@dataclass(frozen=True)
class Slowest:
    """The point of lowest feed limit: arc length s (mm), parameter u, V_lim there (mm/s), and which limit."""

    s: float
    u: float
    v: float
    limit: str


class AdaptivePlan:
    """A limit-aware feedrate plan S(t), V(t), A(t) along a curve (see the module docstring).

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
    slowest : :class:`Slowest`
    s_grid, u_grid, v_limit, binding : the sampled feed limit (mm, -, mm/s, index into LIMITS)
    a_limit : the tangential acceleration bound on the same grid, mm/s² (max_accel, lowered by the
        per-axis budgets left over by the centripetal part)
    planning_time : float, s — wall time of :func:`plan_adaptive`
    """

    shape = "adaptive"

    def __init__(self, segments, *, length, period, feedrate, stretch, accel_bound, sections, grid: _Grid,
                 planning_time=0.0):
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
        self.s_grid = grid.s
        self.u_grid = grid.u
        self.v_limit = grid.v_limit
        self.binding = np.argmin(grid.comps, axis=1)
        self.a_limit = grid.acc_t
        for arr in (self.s_grid, self.u_grid, self.v_limit, self.binding, self.a_limit):
            arr.setflags(write=False)
        self.limit_fractions = _fractions(self.s_grid, self.v_limit, self.binding, self.length)
        # a zero-speed end's V_lim is 0 by decree (a stop), and next to it rounding: not a limit to report
        k = int(np.argmin(np.where(grid.near, np.inf, self.v_limit))) if not grid.near.all() else 0
        self.slowest = Slowest(float(self.s_grid[k]), float(self.u_grid[k]), float(self.v_limit[k]),
                               LIMITS[int(self.binding[k])])

    def evaluate(self, t):
        """(S, V, A) at times t (s), arrays shaped like t: see :func:`adaptive_at`."""
        t = np.asarray(t, dtype=float)
        flat = np.ascontiguousarray(t.reshape(-1))
        S, V, A = (np.empty_like(flat) for _ in range(3))
        adaptive_many(self.segments, flat, S, V, A)
        return S.reshape(t.shape), V.reshape(t.shape), A.reshape(t.shape)

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


def _fractions(s, vl, binding, length):
    out = {name: 0.0 for name in LIMITS}
    if length <= 0 or s.shape[0] < 2:
        return out
    ds = np.diff(s)
    lower = np.where(vl[:-1] <= vl[1:], binding[:-1], binding[1:])
    for i, name in enumerate(LIMITS):
        out[name] = float(ds[lower == i].sum() / length)
    return out


class MotionTooLong(SpecError):
    """The plan would take longer than plan_adaptive's *max_duration*; ``duration`` (s) is the
    acceleration-limited optimum's, which the jerk-limited plan can only exceed (to its rounding)."""

    def __init__(self, duration: float):
        super().__init__(f"the adaptive plan takes about {duration:.6g} s or more")
        self.duration = duration


def _scan_times(nodes, caps, acc):
    """The acceleration-limited optimum of a rest-to-rest section: V at its nodes and the time
    (s) of each interval.  No jerk-limited motion is faster, so its sum bounds the motion time
    from below (to the rounding of the pieces)."""
    v = _scan(nodes, caps, acc)
    ds = np.diff(nodes)
    vs = v[:-1] + v[1:]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # an interval with V = 0 at both ends (a section of one interval): cruise at its cap plus the ramps
        t = np.where(vs > 0, 2.0 * ds / np.where(vs > 0, vs, 1.0), ds / caps + 2.0 * caps / acc)
    return v, t


def _time_estimate(nodes, caps, acc, J, accel_top):
    """Motion time (s) of a rest-to-rest section, roughly, for the jerk-limited pass's step count.

    The acceleration-limited optimum (the scan), plus what the jerk adds to each monotone run
    of its feedrate: a change Δv takes Δv/A + A/J with ramps, or 2√(Δv/J) when A is not
    reached, i.e. at most 2 min(A/J, √(Δv/J)) more than with instant changes of acceleration;
    and at least the jerk-only rest-to-rest move over the section, 4 (L / 2J)^(1/3).
    """
    v, t = _scan_times(nodes, caps, acc)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        dv = np.diff(v)
        dv = dv[dv != 0]
        runs = np.cumsum(np.concatenate([[True], np.sign(dv[1:]) != np.sign(dv[:-1])])) - 1 if dv.size else dv
        extra = 2.0 * np.minimum(accel_top / J, np.sqrt(np.bincount(runs.astype(np.int64), np.abs(dv)) / J)).sum() \
            if dv.size else 0.0
    total = float(t.sum() + extra)
    return max(total, 4.0 * (0.5 * float(nodes[-1] - nodes[0]) / J) ** (1.0 / 3.0)) if math.isfinite(total) else \
        4.0 * (0.5 * float(nodes[-1] - nodes[0]) / J) ** (1.0 / 3.0) + float(np.sum(ds / caps))


def plan_adaptive(curve: NurbsCurve, period: float, feedrate: float, chord_tolerance: float | None = None,
                  max_accel: float | None = None, max_jerk: float | None = None,
                  max_normal_accel: float | None = None, axes: dict | None = None, *,
                  tangential_share: float = 0.4, samples: int = 4000, resolution: float = 0.005,
                  step: float | None = None, max_duration: float = math.inf) -> AdaptivePlan:
    """Plan a limit-aware feedrate along *curve* (see the module docstring for the algorithm).

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
    grid = _build_grid(curve, lim, int(samples), float(resolution))
    if lim.chord_tolerance is not None:  # see "Tight turns"
        sections = _sections(grid, 2.0 * lim.chord_tolerance / lim.period, 2.0 * lim.chord_tolerance)
    else:
        sections = _sections(grid)
    if not sections:  # every node at one arc length: nothing but rounding moves
        raise SpecError(f"curve: has zero length (the {length:.3g} mm computed is rounding); there is nothing to plan")
    keep = 1.0 - MARGIN
    J = None if lim.max_jerk is None else lim.max_jerk * keep
    accel_bound = min(float(a.min()) for _, _, a in sections) * keep
    accel_top = max(float(a.max()) for _, _, a in sections) * keep
    if J is None and not math.isfinite(accel_bound):
        raise SpecError("profile.max_accel is not set and the axes' max_accel do not bound the acceleration along "
                        "this path: an adaptive plan without max_jerk needs a finite acceleration limit")
    work = []
    for nodes, vl, at in sections:
        caps = np.minimum(vl[:-1], vl[1:]) * keep
        if not np.all(caps > 0):
            # not reached: V_lim is 0 only at a zero-speed span end, which is a section end (see _sections)
            k = int(np.argmin(caps))
            raise SpecError(f"curve: the feed limit is zero near s = {nodes[k]:.6g} mm, where the adaptive planner "
                            f"cannot stop (a cusp or a zero tangent inside a knot span: insert a knot there)")
        work.append((nodes, caps, np.minimum(at[:-1], at[1:]) * keep))
    with np.errstate(over="ignore", invalid="ignore"):
        fastest = float(sum(_scan_times(nodes, caps, acc)[1].sum() for nodes, caps, acc in work))
    # the jerk-limited plan differs from this optimum by its pieces' rounding too (~1e-4 measured):
    # refuse only clearly beyond the limit and leave the rest to the caller's check of the plan
    if not fastest * 0.99 <= max_duration:
        raise MotionTooLong(fastest)
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
    ticks = 0  # the tick on which the section starts (the previous one's stop)
    motion = 0.0  # the sum of the sections' times before their stretch
    for k, (nodes, caps, acc) in enumerate(work):
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
                        stretch=lam, accel_bound=accel_bound, sections=len(sections), grid=grid,
                        planning_time=time.perf_counter() - t0)
