"""The real-time interpolator: one curve parameter u_k per sampling period T.

Methods (Cheng, Tsai & Cheng 2002, Eqs. 8–9; Farouki & Tsai, CAD 33 (2001) 155–165 for
the second-order coefficients with the A_k term; σ = |P'(u_k)|, V_k, A_k from the planned profile):

``taylor1``  the paper's Eq. 8: u_{k+1} = u_k + T V_k / σ
``taylor2``  the paper's Eq. 9: + T²/2 (A_k/σ − V_k² (P'·P'')/σ⁴)
``rk4``      classical Runge–Kutta on du/dt = V(t)/σ(u) over each period
``exact``    arc-length exact: s(u_{k+1}) = S(t_{k+1}), the taylor2 step corrected by
             Newton on the arc length of the step alone (a predictor–corrector;
             see :func:`_exact_step`), or by Newton on the panel table's s(u)
             where that step cannot be trusted

End of motion: the last tick K is the first with K·T >= motion time, and its
command is exactly the curve's end point.  A Taylor/RK run that is still short
of the end at tick K snaps to it; one that would pass the end earlier stops
there and holds.  Either way the *end gap* is S(t_j) − s(ũ_j) at the tick j of
the snap, ũ_j being where the interpolator itself would have put the command
(arc length extended linearly past the end): > 0 when it was behind the plan,
< 0 when ahead.  No command ever passes the end.

Safe steps: the Taylor and RK formulas are not trusted, and the tick takes the
arc-length-exact step instead (the planned increment S(t_k+1) − S(t_k) from
where the run is), where
- the parametric speed σ falls below 1e-6 of its mean over the curve (repeated
  control points, a cusp), or would change by more than 10 % within the tick
  (|Δu|·|P''| > 0.1 σ over the whole step, the acceleration term included);
- Eq. 9's or RK4's model of the plan over the tick (T·V + T²A/2; Simpson's
  rule on V) overshoots the plan's own step by more than 1 %: a ramp far
  shorter than T, which would otherwise make T²A/2 a leap;
- the step (or an RK4 stage) crosses a knot and the arc length it really
  covers, measured there, misses what the method expected by more than its
  accuracy inside a span (5 % Eq. 8, 1 % Eq. 9, 0.1 % RK4): the derivatives
  of one span say nothing of the next, and where |P'| jumps at the knot (a C⁰
  join, a heavy weight beside it) the step would leap;
- a Taylor step would stall or go backwards while the plan still moves.
So no inf or NaN can arise, and no tick other than the snap to the end moves
more than STEP_FACTOR times its planned step (taylor1: times the larger of
that step and T·V_k, its own ramp lag).  On the paper's circle no tick needs
a safe step.

Acc/dec after interpolation (the conventional method the paper improves on;
docs/interpolation.md, "Acc/dec after interpolation") interpolates at constant feedrate and then filters each
axis: a moving average over Ta (trapezoidal), two moving averages of Ta/2
(bell), or a first-order lag of time constant τ (exponential).  Output goes
on until the filtered command has settled at the end point within 1 nm; that
last row is then set exactly to the end point.

Ticks are produced in chunks (:meth:`Interpolation.chunks`) so that memory does
not grow with the length of the job.  The per-tick work is one numba kernel
(:func:`interpolate_tick`: profile, step, command), which the chunk loop and
the benchmark's per-tick timer both call.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._jit import njit
from .errors import SpecError, located
from .nurbs import (NurbsCurve, arc_length_to, curve_ders, ders_fast, dot_rows, find_span, find_span_from, make_work,
                    norm_row, parameter_at, speed_at)
from . import names
from .config import Job
from .path import CORNER_ANGLE, Path, job_path
from .profiles import MAX_TICKS, SETTLE_TOL, planned_profile, profile_at, settle_time, tick_limit_error

METHODS = {name: code for code, name in enumerate(names.METHODS, start=1)}  # method -> kernel code
TAYLOR1, TAYLOR2, RK4, EXACT = 1, 2, 3, 4
CHUNK_TICKS = 1 << 16
AXIS_COLUMN = 4  # the first axis column of a stream
SLOW_SPEED = 1e-6  # fraction of the mean parametric speed below which Taylor/RK steps are replaced by exact ones
RAPID_SPEED_CHANGE = 0.1  # largest relative change of |P'| within one tick that a Taylor/RK step is trusted with
#: the most a tick (other than the snap to the end) moves along the path, as a multiple of its planned step
STEP_FACTOR = {"taylor1": 1.06, "taylor2": 1.02, "rk4": 1.01, "exact": 1.0 + 1e-9}
NO_JOINT, TANGENT_JOINT, CORNER_JOINT = 0, 1, 2  # what a step crosses (see _joint_crossed)
CORNER_COS = math.cos(CORNER_ANGLE)  # a joint whose one-sided tangents differ by more is a corner (as the planner's)
PROFILE_MISMATCH = 0.01  # largest relative miss of the plan's step within one tick by the Eq. 9 / RK4 model of it
# largest relative miss of a knot-crossing step's arc length by the method's own expectation, per method
# (1-based by METHODS code): Eq. 8 misses by |σ'|Δu/2σ <= 5 % inside a span anyway, Eq. 9 and RK4 by far less
KNOT_MISMATCH = np.array([0.0, RAPID_SPEED_CHANGE / 2, 1e-2, 1e-3, 0.0])

# state vector of interpolate_chunk
# _JOINS: 1 where C0 knots are block junctions; s(u), the arc length at u, is _ARC + _ARC_OFF (exact's; _ARC
# NaN: not known): a value of the plan, which exact aimed at, and the small miss, kept apart so that neither
# the rounding of s nor that of u gathers from tick to tick;
# _CARRIED: 1 where the derivative table at u follows (3·dim values from _CK on), carried by exact from its
# evaluation at the predictor (see _exact_step)
_U, _SPAN, _ARRIVED, _GAP, _JOINS, _ARC, _ARC_OFF, _CARRIED, _CK = 0, 1, 2, 3, 4, 5, 6, 7, 8
#: exact re-reads s(u) from the panel table every this many ticks (and after any step it did not take itself),
#: so that the rounding its running sum gathers stays below 1e-14 of the path's length
ANCHOR_TICKS = 256
#: exact's step is trusted where Simpson's rule on the step agrees with the corrected one to this, relative
EXACT_LENGTH_TOL = 1e-9
#: and where the Newton correction to the taylor2 predictor is at most this fraction of the step
EXACT_CORRECTION = 1e-3
#: exact carries its derivative table at the predictor to the next tick where the correction is at most
#: this fraction of the step (elsewhere the next tick evaluates the curve afresh)
CARRY_CORRECTION = 1e-5


@njit(cache=True)
def _speed_near(U, B, p, n, u, work, CK):
    return speed_at(U, B, p, u, find_span(U, n, p, u), work, CK)


@njit(cache=True)
def _rk4(U, B, p, n, u, T, v0, vh, v1, sigma0, sigma_min, work, CK):
    """One RK4 step of du/dt = V(t)/σ(u) and the furthest u a stage looked at.

    The step is NaN when a stage meets a near-zero speed.
    """
    b = U[n + 1]
    k1 = v0 / sigma0
    u2 = min(u + 0.5 * T * k1, b)
    s2 = _speed_near(U, B, p, n, u2, work, CK)
    if s2 < sigma_min:
        return math.nan, u2
    k2 = vh / s2
    u3 = min(u + 0.5 * T * k2, b)
    s3 = _speed_near(U, B, p, n, u3, work, CK)
    if s3 < sigma_min:
        return math.nan, max(u2, u3)
    k3 = vh / s3
    u4 = min(u + T * k3, b)
    s4 = _speed_near(U, B, p, n, u4, work, CK)
    if s4 < sigma_min:
        return math.nan, max(u2, u3, u4)
    k4 = v1 / s4
    return u + T * (k1 + 2.0 * k2 + 2.0 * k3 + k4) / 6.0, max(u2, u3, u4)


@njit(cache=True)
def _joint_crossed(U, B, p, n, span, until):
    """What the knots of multiplicity >= p (C0 joints of the knot vector) in (U[span], until] are:
    NO_JOINT (none there), TANGENT_JOINT (tangent joints only) or CORNER_JOINT (a corner among them).

    Every joint of a path is a knot of full multiplicity, whether its blocks meet
    tangentially or not; only where the one-sided tangents differ (as the planner's
    CORNER_COS tells a stop from a smooth join) must the run be held to the plan's
    own arc length."""
    found = NO_JOINT
    j = span + 1
    while j <= n and U[j] <= until:
        m = 1
        while j + m <= n and U[j + m] == U[j]:
            m += 1
        if m >= p:
            if _turns_at(B, p, j - 1, j + m - 1):
                return CORNER_JOINT
            found = TANGENT_JOINT
        j += m
    return found


@njit(cache=True)
def _turns_at(B, p, left, right):
    """Whether the one-sided tangents where span *left* ends and span *right* starts differ by more than
    CORNER_COS, from their Bezier control points (towards the nearest distinct one, as planner.grid takes them;
    a span all of one point has no direction and counts as a turn)."""
    dim = B.shape[3] - 1
    if right >= B.shape[0] or not B[right, 0, 0, dim] != 0.0:  # no span after the knot (the end): no turn to pass
        return False
    tl = np.zeros(dim)
    tr = np.zeros(dim)
    for side in range(2):
        t = tl if side == 0 else tr
        row = left if side == 0 else right
        base = p if side == 0 else 0
        sign = 1.0 if side == 0 else -1.0
        found = False
        for k in range(1, p + 1):
            other = p - k if side == 0 else k
            size = 0.0
            for c in range(dim):
                t[c] = sign * (B[row, 0, base, c] / B[row, 0, base, dim] - B[row, 0, other, c] / B[row, 0, other, dim])
                size += t[c] * t[c]
            if size > 0.0:
                size = math.sqrt(size)
                for c in range(dim):
                    t[c] /= size
                found = True
                break
        if not found:
            return True
    cos = 0.0
    for c in range(dim):
        cos += tl[c] * tr[c]
    return not cos >= CORNER_COS


@njit(cache=True)
def _exact_step(U, B, p, span, u, sg0, D0, W0, pred, s0, s0_off, S1, work, CK):
    """(u_{k+1}, its arc length) for ``exact``: the taylor2 predictor *pred* corrected so that s = S1.

    The arc length of the step [u, pred] is the corrected Simpson rule on the
    parametric speed σ = |C'| (exact for quintics: σ and σ' = C'·C''/σ at both
    ends, σ at the middle), s(u) = s0 + s0_off carried from the last tick; one Newton
    step with its second-order term, σ1·δ + σ1'·δ²/2 = S1 − s(pred), then
    lands on S1 to about δ³σ''.  Two evaluations of the curve (at pred and at
    the middle) where the panel table's Newton needs two Gauss rules of ten.
    NaN where it cannot be trusted: the step leaves the span (a knot's
    derivatives say nothing of the next piece), Simpson's rule disagrees with
    the corrected one by more than EXACT_LENGTH_TOL (σ is not smooth on the
    step's scale), or the correction is over EXACT_CORRECTION of the step.
    sg0, D0, W0: σ(u), C'(u), C''(u).
    """
    h = pred - u
    if not (h > 0.0) or pred >= U[span + 1]:
        return math.nan, math.nan
    dd0 = 0.0
    for c in range(D0.shape[0]):
        dd0 += D0[c] * W0[c]
    # ders_fast: one de Casteljau pass for the point and both derivatives (curve_ders runs one per order)
    ders_fast(U, B, p, u + 0.5 * h, span, 1, work[0], CK)
    sgm = norm_row(CK, 1)
    ders_fast(U, B, p, pred, span, 2, work[0], CK)
    sg1 = norm_row(CK, 1)
    dd1 = dot_rows(CK, 1, 2)
    if not (sg0 > 0.0 and sg1 > 0.0):
        return math.nan, math.nan
    inv1 = 1.0 / sg1  # one division where the formulas have four
    simpson = h * (sg0 + 4.0 * sgm + sg1) * (1.0 / 6.0)
    length = h * ((7.0 / 30.0) * (sg0 + sg1) + (16.0 / 30.0) * sgm) + h * h * (dd0 * sg1 - dd1 * sg0) * inv1 / (60.0 * sg0)
    if abs(length - simpson) > EXACT_LENGTH_TOL * length:
        return math.nan, math.nan
    # s(pred + δ) = S1: σ1 δ + σ1' δ²/2 = miss; S1 − s0 is exact (two near values of the plan: Sterbenz)
    miss = ((S1 - s0) - s0_off) - length
    slope = dd1 * inv1  # σ1'
    delta = miss * inv1
    delta -= 0.5 * slope * delta * delta * inv1
    nxt = pred + delta
    if abs(delta) > EXACT_CORRECTION * h or not (u < nxt < U[span + 1]):
        return math.nan, math.nan
    # s(nxt) − S1: what the rounding of nxt left (nxt − pred is exact, Sterbenz again)
    return nxt, sg1 * ((nxt - pred) - delta)


@njit(cache=True, inline="always")
def _carry_derivatives(CK, W0, delta, h, state):
    """Keep the derivative table CK at the predictor, moved by exact's correction delta, for the next tick.

    C(pred + δ) by its Taylor series to δ³, the third derivative estimated as the
    change of C'' over the step (h: its length in u, W0 = C'' at its start):
    the correction is at most CARRY_CORRECTION of the step, so what is left is
    about 1e-5·h² times the fourth derivative on C'' and below rounding on the
    point — and the next tick does not evaluate the curve again.
    """
    dim = CK.shape[1]
    inv_h = 1.0 / h
    for c in range(dim):
        third = (CK[2, c] - W0[c]) * inv_h
        state[_CK + c] = CK[0, c] + delta * (CK[1, c] + delta * (0.5 * CK[2, c] + delta * third / 6.0))
        state[_CK + dim + c] = CK[1, c] + delta * (CK[2, c] + 0.5 * delta * third)
        state[_CK + 2 * dim + c] = CK[2, c] + delta * third
    state[_CARRIED] = 1.0


@njit(cache=True, inline="always")  # inlined into its loops: a call per tick passed 13 arguments (a fifth of the tick)
def interpolate_tick(method, geom, prof, T, sigma_min, k, K, state, work, CK, point, plan, ders):
    """One tick of the real-time interpolator: everything a controller computes per period.

    Writes the command of tick k — ``point`` = P(u_k) and ``plan`` = (S, V, A) at
    t_k, and ``ders`` = (P'(u_k), P''(u_k)), which the run's measures reuse — then
    advances ``state`` (u, span hint, arrived flag, end gap) to u_{k+1}.
    ``geom`` is (U, B, p, n, panel starts, panel spans, cumulative lengths,
    start point, end point); ``prof`` the profile's parameter vector.
    """
    U, B, p, n, starts, spans, cum, start_pt, end_pt = geom
    a = U[p]
    b = U[n + 1]
    u = state[_U]
    t = k * T
    S0, V0, A0 = profile_at(prof, t)
    plan[0] = S0
    plan[1] = V0
    plan[2] = A0
    span = find_span_from(U, n, p, u, int(state[_SPAN]))
    state[_SPAN] = span
    dim = point.shape[0]
    if state[_CARRIED] != 0.0:
        for r in range(3):
            for c in range(dim):
                CK[r, c] = state[_CK + r * dim + c]
        state[_CARRIED] = 0.0
    else:
        curve_ders(U, B, p, u, span, 2, work, CK)
    for c in range(point.shape[0]):
        # the ends are the first and last control points exactly (clamped knots)
        point[c] = end_pt[c] if u == b else (start_pt[c] if u == a else CK[0, c])
        ders[0, c] = CK[1, c]
        ders[1, c] = CK[2, c]
    if k >= K:
        return
    if state[_ARRIVED] != 0.0:
        state[_U] = b
        return
    sigma = norm_row(CK, 1)
    nxt = math.nan
    absolute = False  # land on S(t_k+1) itself (paths: junctions and stops)
    model = 0.0  # mm: the arc length the method's own formula expects the step to cover
    reach = u  # the furthest u the step's formula looked at (RK4's stages may pass its end)
    S1 = math.nan
    step = T * V0 / sigma if sigma > 0.0 else math.inf
    curving = norm_row(CK, 2)
    # Taylor and RK steps assume the parametric speed barely changes within a tick;
    # where it would change by more than 10 % (near a point where P' = 0) the
    # exact step is taken instead (see the module docstring)
    if sigma >= sigma_min and step * curving <= RAPID_SPEED_CHANGE * sigma:
        if method == TAYLOR1:
            nxt = u + step
            model = T * V0
        elif method == RK4:
            S1, v1, _ = profile_at(prof, t + T)
            vh = profile_at(prof, t + 0.5 * T)[1]
            nxt, reach = _rk4(U, B, p, n, u, T, V0, vh, v1, sigma, sigma_min, work, CK)
            model = T * (V0 + 4.0 * vh + v1) / 6.0
        else:  # taylor2, and the predictor of exact
            nxt = u + step + 0.5 * T * T * A0 / sigma - 0.5 * step * step * dot_rows(CK, 1, 2) / (sigma * sigma)
            model = T * V0 + 0.5 * T * T * A0
    if method != EXACT and nxt == nxt:
        if (nxt - u) * curving > RAPID_SPEED_CHANGE * sigma:
            # the same test on the whole step, acceleration term included (a ramp far
            # shorter than T makes T²A/2 the larger part)
            nxt = math.nan
        elif method != TAYLOR1:
            # Eq. 9 and RK4 model the plan within the tick as well (V and A, or V at three
            # instants): where that model overshoots the plan's own step (a ramp that ends
            # inside the tick, shorter than a few periods) they are not trusted.  Falling
            # short of it is the lag these methods have at the start of a ramp, not a leap.
            if S1 != S1:
                S1 = profile_at(prof, t + T)[0]
            if model - (S1 - S0) > PROFILE_MISMATCH * (S1 - S0):
                nxt = math.nan
        if nxt == nxt and max(nxt, reach) > U[span + 1] and span < n:
            # the step (or one of RK4's stages) crosses a knot: the derivatives it was built
            # from belong to this span only, and a knot where |P'| jumps (a C0 join, a heavy
            # weight next to it) would turn it into a leap; measure the arc length it covers
            # and keep it only if that is what the method expected, within its accuracy
            # inside a span
            joint = _joint_crossed(U, B, p, n, span, max(nxt, reach)) if state[_JOINS] != 0.0 else NO_JOINT
            if joint == CORNER_JOINT:
                # a corner of a path: the step lands on the plan's own arc length S(t_k+1)
                # exactly, so that no run (ahead of the plan or behind it) passes a corner
                nxt = math.nan
                absolute = True
            elif joint == TANGENT_JOINT:
                # a tangent joint of a path (a line into a tangent arc, a corner blend's ends):
                # |P'| may jump there, so the formula's u says nothing past it; the step covers
                # the arc length the method expected, measured across the joint, and so keeps
                # the method's own lag (Eq. 8's T·V/2 after a ramp) as inside a block — landing
                # on S(t_k+1) here made all of it up in this one tick (1.5 steps at 1 ms)
                nxt = parameter_at(U, B, p, starts, spans, cum,
                                   arc_length_to(U, B, p, starts, spans, cum, u, work, CK) + model, -math.inf,
                                   work, CK)
                if _joint_crossed(U, B, p, n, span, nxt) == CORNER_JOINT:  # a short block, then a corner
                    nxt = math.nan
                    absolute = True
            else:
                covered = (arc_length_to(U, B, p, starts, spans, cum, nxt, work, CK)
                           - arc_length_to(U, B, p, starts, spans, cum, u, work, CK))
                if abs(covered - model) > KNOT_MISMATCH[method] * model:
                    nxt = math.nan
    if nxt <= u and V0 > 0.0 and k + 1 < K:
        # a Taylor step that stalls or goes back while the plan moves on; at the last
        # step the snap to the end point takes over and the end gap reports it
        nxt = math.nan
    safe = method != EXACT and not (nxt == nxt)
    if state[_JOINS] != 0.0 and method != EXACT and not absolute:
        # on a path, a section ends at rest on a tick (a corner): every method lands on it exactly,
        # as on the path's end, so that the tool stops at the corner and not a lag short of it
        S1, V1, _ = profile_at(prof, t + T)
        absolute = V1 == 0.0
    if S1 != S1 and (method == EXACT or safe or absolute or k + 1 == K or nxt >= b):
        S1 = profile_at(prof, t + T)[0]
    arc = math.nan
    arc_off = 0.0
    if method == EXACT:
        guess = nxt if nxt == nxt else -math.inf
        if nxt == nxt:
            s0, s0_off = state[_ARC], state[_ARC_OFF]
            if not (s0 == s0) or k % ANCHOR_TICKS == 0:
                s0, s0_off = arc_length_to(U, B, p, starts, spans, cum, u, work, CK), 0.0
            nxt, arc_off = _exact_step(U, B, p, span, u, sigma, ders[0], ders[1], guess, s0, s0_off, S1, work, CK)
            arc = S1 if nxt == nxt else math.nan
            if arc == arc and abs(nxt - guess) <= CARRY_CORRECTION * (guess - u):
                _carry_derivatives(CK, ders[1], nxt - guess, guess - u, state)
        if not (nxt == nxt):  # no predictor, or a step it cannot take: Newton on the panel table
            nxt = parameter_at(U, B, p, starts, spans, cum, S1, guess, work, CK)
    elif absolute:
        nxt = parameter_at(U, B, p, starts, spans, cum, S1, nxt if nxt == nxt else -math.inf, work, CK)
    elif safe:
        # the planned increment from where the run is, not the plan's absolute S(t_k+1):
        # a Taylor run that lags the plan must not make up all of its lag in this one tick
        target = arc_length_to(U, B, p, starts, spans, cum, u, work, CK) + (S1 - S0)
        nxt = parameter_at(U, B, p, starts, spans, cum, target, -math.inf, work, CK)
        if state[_JOINS] != 0.0 and _joint_crossed(U, B, p, n, span, nxt) == CORNER_JOINT:
            # a corner of a path, as above: on S(t_k+1) itself
            nxt = parameter_at(U, B, p, starts, spans, cum, S1, -math.inf, work, CK)
    if nxt < u:
        nxt = u
    if k + 1 == K or nxt >= b:
        # snap to the end: the gap is how far the interpolator was behind the
        # plan there (arc length, linearly extended past the end), in mm
        if nxt <= b:
            reached = arc_length_to(U, B, p, starts, spans, cum, nxt, work, CK)
        else:
            reached = cum[cum.shape[0] - 1] + (nxt - b) * speed_at(U, B, p, b, n, work, CK)
        state[_GAP] = S1 - reached
        state[_ARRIVED] = 1.0
        state[_CARRIED] = 0.0
        nxt = b
    state[_U] = nxt
    state[_ARC] = arc
    state[_ARC_OFF] = arc_off


@njit(cache=True, nogil=True)  # nogil: the run's measures go on beside it (metrics.Alongside)
def interpolate_chunk(method, geom, prof, T, sigma_min, k0, K, state, out_u, out_pts, out_plan, out_ders):
    """Ticks k0 .. k0 + m - 1 (m = len(out_u)): u_k, P(u_k) and the plan (S, V, A) per row.

    ``out_ders`` (m, 2, dim) gets P'(u_k) and P''(u_k) per row; an empty array
    when nobody measures the run."""
    dimh = geom[1].shape[3]
    work = make_work(geom[2], 2, dimh)
    CK = np.empty((3, dimh - 1))
    scratch = np.empty((2, dimh - 1))
    keep = out_ders.shape[0] > 0
    for i in range(out_u.shape[0]):
        out_u[i] = state[_U]
        # one inlined copy of the tick, whichever array takes its derivatives (two copies, one per branch,
        # doubled this kernel's compilation)
        ders = out_ders[i] if keep else scratch
        interpolate_tick(method, geom, prof, T, sigma_min, k0 + i, K, state, work, CK, out_pts[i], out_plan[i], ders)


@njit(cache=True, nogil=True)
def assemble_rows(k0, us, pts, V, A, inner_starts, shifts, lo, hi, period, rapid, data):
    """The stream's rows of ticks k0 .. k0 + m − 1 in one pass: k, n, t, the block's u, the axes, v, a[, rapid].

    n is the block of each global u (a junction belongs to the next block:
    ``Path.locate``'s searchsorted, walked forward since u never decreases),
    the block's u its own parameter, clipped to the block's domain; t = k·T,
    exact to the tick, never a running sum.  *rapid* (one flag per block) is
    empty on a path without rapids.
    """
    dim = pts.shape[1]
    n = 0
    for i in range(us.shape[0]):
        u = us[i]
        if i == 0 or u < us[i - 1]:
            n = np.searchsorted(inner_starts, u, side="right")
        while n < inner_starts.shape[0] and inner_starts[n] <= u:
            n += 1
        k = float(k0 + i)
        data[i, 0] = k
        data[i, 1] = n
        data[i, 2] = k * period
        data[i, 3] = min(max(u - shifts[n], lo[n]), hi[n])
        for c in range(dim):
            data[i, AXIS_COLUMN + c] = pts[i, c]
        data[i, AXIS_COLUMN + dim] = V[i]
        data[i, AXIS_COLUMN + dim + 1] = A[i]
        if rapid.shape[0] > 0:
            data[i, AXIS_COLUMN + dim + 2] = rapid[n]


@njit(cache=True)
def filter_chunk(x, ring1, ring2, pos, sums, lag, alpha, out):
    """Acc/dec after interpolation on each channel (column) of x.

    ring1 (N1, ch) and ring2 (N2, ch) are the moving-average windows (N2 = 0:
    one stage only; N1 = 0: no moving average), ``lag`` the state of a
    first-order lag with gain alpha (alpha = 0: no lag).  ``pos`` holds the
    ring positions, ``sums`` the running window sums (2, ch); each window is
    re-summed when its position wraps, so rounding cannot drift over long jobs.
    """
    ch = x.shape[1]
    n1 = ring1.shape[0]
    n2 = ring2.shape[0]
    for i in range(x.shape[0]):
        for c in range(ch):
            y = x[i, c]
            if n1 > 0:
                sums[0, c] += y - ring1[pos[0], c]
                ring1[pos[0], c] = y
                y = sums[0, c] / n1
            if n2 > 0:
                sums[1, c] += y - ring2[pos[1], c]
                ring2[pos[1], c] = y
                y = sums[1, c] / n2
            if alpha > 0.0:
                lag[c] += alpha * (y - lag[c])
                y = lag[c]
            out[i, c] = y
        if n1 > 0:
            pos[0] += 1
            if pos[0] == n1:
                pos[0] = 0
                for c in range(ch):
                    sums[0, c] = ring1[:, c].sum()
        if n2 > 0:
            pos[1] += 1
            if pos[1] == n2:
                pos[1] = 0
                for c in range(ch):
                    sums[1, c] = ring2[:, c].sum()


@dataclass
class Chunk:
    """Consecutive ticks k0 .. k0 + m - 1 of a run.

    ``data`` has one row per tick and the columns of :attr:`Interpolation.columns`
    (k, n, t, u, x, y[, z], v, a: n the block, u the block's own parameter);
    ``planned`` is the planned distance S(t_k) (mm) and ``u`` the parameter along
    the whole path, which the measures need and the streams do not carry;
    ``ders`` (m, 2, dim) the curve's P'(u_k) and P''(u_k) as the tick computed
    them (None unless asked for: :meth:`Interpolation.chunks`).
    """

    k0: int
    data: np.ndarray
    planned: np.ndarray
    u: np.ndarray
    dim: int = 2
    ders: np.ndarray | None = None

    @property
    def points(self) -> np.ndarray:
        """The axis commands (m, dim)."""
        return self.data[:, AXIS_COLUMN:AXIS_COLUMN + self.dim]


def stream_columns(dim: int, rapid: bool = False) -> list[str]:
    """The columns of a plan stream: tick, block, time, the block's parameter, the axes, feedrate, acceleration,
    and on a path with rapid (G0) blocks, ``rapid``: 1 on a rapid block's ticks, 0 on the others."""
    return ["k", "n", "t", "u", *names.AXES[:dim], "v", "a", *(["rapid"] if rapid else [])]


class Interpolation:
    """A planned job, ready to produce its ticks.

    Parameters
    ----------
    job : a validated :class:`~nurbsinterp.config.Job`
    curve : the job's curve, if already built (it caches its arc-length table)
    chunk_ticks : rows per chunk
    max_ticks : refuse (SpecError) a job whose tick count would exceed this
    max_ticks_hint : how the refusal tells the user to raise the limit (the CLI option, if the command has one)

    Attributes
    ----------
    profile : the feedrate plan (constant feed when acc/dec is after interpolation)
    last_tick : K, index of the last tick of the interpolation itself (before filtering)
    end_gap : mm, known once :meth:`chunks` is exhausted (see the module docstring)
    """

    def __init__(self, job: Job, path: Path | NurbsCurve | None = None, chunk_ticks: int = CHUNK_TICKS,
                 max_ticks: int = MAX_TICKS, max_ticks_hint: str = ""):
        with located(job.source):
            self._plan(job, path, chunk_ticks, max_ticks, max_ticks_hint)

    def _plan(self, job, path, chunk_ticks, max_ticks, max_ticks_hint):
        self.job = job
        self.path = path if isinstance(path, Path) else job_path(job, path)
        self.curve = self.path.curve
        self.length = self.curve.length
        if not self.curve.resolvable:
            raise SpecError(f"{job.source}: the curve has zero length (to the rounding of its control points, "
                            f"{self.curve.length_noise:.3g} mm); there is no path to interpolate")
        self.period = job.interpolator.period
        self.method = job.interpolator.method
        self.after = job.profile.accdec == "after"
        self.profile, self.last_tick = planned_profile(job, self.path, constant=self.after, max_ticks=max_ticks,
                                                       hint=max_ticks_hint)
        self.chunk_ticks = int(chunk_ticks)
        self.columns = stream_columns(self.curve.dim, self.path.spec.has_rapids)
        self._rapid = np.array([float(b.rapid) for b in self.path.blocks]) if self.path.spec.has_rapids else None
        a, b = self.curve.domain
        self.sigma_min = SLOW_SPEED * self.length / (b - a)
        self.end_gap = 0.0
        error = tick_limit_error(job.source, self.ticks_estimate, f"{self.length:.6g} mm at {self.profile.peak:.6g} "
                                 f"mm/s, T = {self.period:g} s", max_ticks, max_ticks_hint)
        if error is not None:
            raise error

    # -- estimates for progress reporting and resource checks
    @property
    def filter_ticks(self) -> int:
        """Ticks the after-interpolation filter adds (an estimate for the exponential lag)."""
        if not self.after:
            return 0
        spec, T = self.job.profile, self.period
        if spec.type == "exponential":
            return int(math.ceil(settle_time(spec, self.length) / T))
        return max(1, round(settle_time(spec, self.length) / T))

    @property
    def ticks_estimate(self) -> int:
        return self.last_tick + 1 + self.filter_ticks

    # -- the run
    @property
    def geometry(self):
        """The plain-array tuple the tick kernel takes (see :func:`interpolate_tick`)."""
        curve = self.curve
        return (*curve.kernel_args, *curve.panels, np.ascontiguousarray(curve.control_points[0], dtype=float),
                np.ascontiguousarray(curve.control_points[-1], dtype=float))

    def new_state(self) -> np.ndarray:
        """The interpolator's state at tick 0: u at the start of the domain (see _U .. _CK)."""
        head = [self.curve.domain[0], self.curve.degree, 0.0, 0.0, float(len(self.path.blocks) > 1), 0.0, 0.0, 0.0]
        return np.concatenate([head, np.zeros(3 * self.curve.dim)])

    def _interpolated(self, derivatives):
        """Yield (k0, u, points, plan, ders) chunks of the interpolation itself, ticks 0..K; plan = (S, V, A)
        columns, ders as in :class:`Chunk` (None without *derivatives*)."""
        K = self.last_tick
        geom = self.geometry
        state = self.new_state()
        method = METHODS[self.method]
        dim = self.curve.dim
        for k0 in range(0, K + 1, self.chunk_ticks):
            m = min(self.chunk_ticks, K + 1 - k0)
            us = np.empty(m)
            pts = np.empty((m, dim))
            plan = np.empty((m, 3))
            ders = np.empty((m if derivatives else 0, 2, dim))
            interpolate_chunk(method, geom, self.profile.params, self.period, self.sigma_min, k0, K, state, us, pts,
                              plan, ders)
            yield k0, us, pts, plan, (ders if derivatives else None)
        self.end_gap = float(state[_GAP])

    def chunks(self, derivatives: bool = False):
        """Yield :class:`Chunk` objects covering every tick of the run, in order.

        *derivatives*: each chunk also carries the curve's derivatives at its u_k
        (``Chunk.ders``), which :class:`~nurbsinterp.metrics.RunStats` measures the
        steps with at a fraction of the cost of evaluating the curve again."""
        if not self.after:
            for k0, us, pts, plan, ders in self._interpolated(derivatives):
                yield self._chunk(k0, us, pts, plan[:, 1], plan[:, 2], plan[:, 0], ders)
            return
        yield from self._filtered(derivatives)

    def _chunk(self, k0, us, pts, V, A, S, ders=None):
        data = np.empty((us.shape[0], len(self.columns)))
        path = self.path
        # one layout at the kernel's boundary: the plan's columns are strided views (compiled a second time)
        pts, V, A = np.ascontiguousarray(pts), np.ascontiguousarray(V), np.ascontiguousarray(A)
        assemble_rows(k0, us, pts, V, A, path.starts[1:-1], path.shifts, path._lo, path._hi, self.period,
                      self._rapid if self._rapid is not None else np.empty(0), data)
        return Chunk(k0, data, S, us, self.curve.dim, ders)

    def _filtered(self, derivatives):
        spec, T, dim = self.job.profile, self.period, self.curve.dim
        n1 = n2 = 0
        alpha = 0.0
        if spec.type == "trapezoidal":
            n1 = max(1, round(spec.accel_time / T))
        elif spec.type == "bell":
            n1 = n2 = max(1, round(spec.accel_time / (2 * T)))
        elif spec.tau > 0:
            alpha = -math.expm1(-T / spec.tau)  # else no ramp at all: accel_time 0 and no time constant
        start = np.append(self.curve.control_points[0], 0.0)
        end = np.append(self.curve.control_points[-1], 0.0)
        ring1 = np.tile(start, (n1, 1))
        ring2 = np.tile(start, (n2, 1))
        sums = np.vstack([start * n1, start * n2])
        pos = np.zeros(2, dtype=np.int64)
        lag = start.copy()
        v_prev = 0.0
        b = self.curve.domain[1]

        def run(k0, us, x, S, ders):
            nonlocal v_prev
            y = np.empty_like(x)
            filter_chunk(x, ring1, ring2, pos, sums, lag, alpha, y)
            v = y[:, dim]
            acc = np.diff(v, prepend=v_prev) / T
            v_prev = v[-1]
            return self._chunk(k0, us, y[:, :dim], v, acc, S, ders), y

        for k0, us, pts, plan, ders in self._interpolated(derivatives):
            chunk, _ = run(k0, us, np.column_stack([pts, plan[:, 1]]), plan[:, 0], ders)
            yield chunk
        # the interpolation has ended: hold its end point until the filter settles (u stays at the end:
        # no step to measure, so the derivatives there are never read)
        k0 = self.last_tick + 1
        hold = np.tile(end, (self.chunk_ticks, 1))
        hold_ders = np.zeros((self.chunk_ticks, 2, dim)) if derivatives else None
        while True:
            m = self.chunk_ticks
            chunk, y = run(k0, np.full(m, b), hold, np.full(m, self.length), hold_ders)
            off = np.linalg.norm(y[:, :dim] - end[:dim], axis=1)
            settled = np.flatnonzero(off <= SETTLE_TOL)
            if settled.size:
                last = settled[0]
                chunk.data = chunk.data[: last + 1]
                chunk.planned = chunk.planned[: last + 1]
                chunk.u = chunk.u[: last + 1]
                if derivatives:
                    chunk.ders = chunk.ders[: last + 1]
                chunk.data[last, AXIS_COLUMN:AXIS_COLUMN + dim] = end[:dim]
                chunk.data[last, AXIS_COLUMN + dim:AXIS_COLUMN + dim + 2] = 0.0
                yield chunk
                return
            yield chunk
            k0 += m
