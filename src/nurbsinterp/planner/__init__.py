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
   a cusp inside a knot span is still refused.  The normal acceleration
   √(A_n ρ) has the same kind of floor, for the same reason: the commands are
   sampled, and two steps of at most V T each change the step by at most
   2 V T, so the acceleration the ticks command (their second difference over
   T²) is at most 2V/T <= A_n where V <= A_n T/2, whatever the curve does
   between them.  So below ρ = A_n T²/4, where √(A_n ρ) meets it, V_lim is
   A_n T/2, held within A_n T² of arc (both steps of any tick that touches the
   point) -- without it a near-cusp crawled at √(A_n ρ) ~ 1e-9 mm/s (1.6 s
   against the stop's 0.40 s at 1e-10 mm, since max_accel bounds the normal
   acceleration by default).  The axis terms have no such floor.
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

Cost: the grid has ~34 points per knot span (32 samples at least, the refinement and the refined
minima), and the golden-section searches (~4 brackets per span, 62 evaluations each) and the arc
length of every point (a 10-point Gauss rule) are most of the work; the forward pass costs some 25 cap
checks per step where it accelerates or brakes, one where it cruises.  On the butterfly (48 spans,
~10 000 grid points, 4 751 steps, 2 077 pieces) a plan takes ~0.08 s; on a cubic of 10⁵ control points
(3.4 million grid points) ~13 s of CPU, of which the derivatives and arc lengths (nurbs' kernels) are
half.  Memory is O(1) per grid point: the grid is built and consumed in blocks of knot spans (see
:mod:`.grid`); what outlives a block (:mod:`.sections`: arc length, V_lim and, where axis accelerations
make it vary, the tangential bound per node, and the limit fractions' interval lengths) is 24 to 32
bytes a point, and while the sections are planned the range-minimum tables add ~2: ~800 bytes per
control point measured (it was ~18 KB).

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

Layout
------
The package follows the stages above: :mod:`.limits` validates the limits once
into a typed, frozen object; :mod:`.feed` gives the terms of V_lim at a point
(numba kernels); :mod:`.grid` builds the feed limit along the path block by
block of knot spans (step 1) and :mod:`.sections` splits it at the stops (step 2);
:mod:`.jerk` holds the scan and the jerk-limited forward pass (steps 3 and 4, numba
kernels); :mod:`.plan` puts them together into an :class:`AdaptivePlan` (step 5)
and evaluates it per tick.
"""
from .limits import AXES, LIMITS
from .plan import (BOUNDS, MAX_STEPS, AdaptivePlan, MotionTooLong, Slowest, SlowestScheduled, adaptive_at,
                   adaptive_many, plan_adaptive)

__all__ = ["AXES", "BOUNDS", "LIMITS", "MAX_STEPS", "AdaptivePlan", "MotionTooLong", "Slowest", "SlowestScheduled",
           "adaptive_at", "adaptive_many", "plan_adaptive"]
