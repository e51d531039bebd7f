"""Measures of a planned run: feedrate fluctuation and chord error.

Feedrate fluctuation, with exact arc length (the chord-based variant |ΔP|/(V T) − 1 has a
floor of about −κ²(VT)²/24 even for a perfect interpolator)::

    FF_k = Δs_k / ΔS_k − 1

Δs_k is the arc length the command moved along the curve from u_k to u_{k+1}
and ΔS_k the planned distance of that tick.  Ticks whose planned step is
below 1 % of Vp·T (the very start and end of a ramp) are left out, as is the
step into the end point, which the end gap measures instead.

Chord error of a step: the largest distance between the curve from u_k to
u_{k+1} and the chord joining their points.  The distance is sampled at 9
points of the step, its ends included, and Newton refines around the best
sample: a step through an inflection has a maximum each side of it, which
Newton from the middle would find either of.  A step with knots strictly
inside (u_k, u_{k+1}) is split there and each piece sampled so (at a C0 knot
the maximum sits on the kink); the distance is to the segment, not to its
line (a kink may turn by more than 90 degrees within one tick).

Both measures come from the derivatives the tick computed at each end of the
step, which make a quintic that matches the curve to O(h⁶) (:func:`_hermite_step`:
one evaluation of the curve per step, at its middle, checks it); the steps
where it cannot be trusted (across or onto a knot, a sharp turn within one
tick, a miss at the middle) are measured from the curve itself.

Contour and tracking error of a simulated run: contour.py.
"""
from __future__ import annotations

import math
import queue
import threading

import numpy as np

from ._jit import njit
from .contour import PathWindow
from .nurbs import curve_ders, ders_fast, find_span, find_span_from, make_work, norm_row, step_length_mid

FF_MIN_STEP = 0.01  # fraction of Vp·T below which a tick's FF is not counted


CHORD_NEWTON_STEPS = 8  # Newton steps on a maximum of the distance; from a bracket of 1/8 of a piece it needs 2-4


@njit(cache=True)
def _chord_newton(U, B, p, n, span, u0, u1, P0, P1, work, CK):
    """Chord error near a maximum inside [u0, u1], CK the derivative table at its middle (see chord_error).

    Newton on the squared distance from C(u) to the segment P0 P1.  That
    distance is piecewise: to the chord's line where C(u) projects between the
    ends, to P0 (P1) where it projects before (beyond) them.  The pieces meet
    with equal first derivatives (the term along² they differ by has the
    derivative 2·along·along', zero where along is), so Newton on the piece that
    holds u is Newton on one C¹ function.  A curve that turns back behind P0
    across a C0 knot has its maximum on the P0 piece; the line's Newton missed
    it by 0.3 µm (hypothesis' seed 2205).
    """
    dim = P0.shape[0]
    length2 = 0.0
    for c in range(dim):
        length2 += (P1[c] - P0[c]) ** 2
    inv2 = 1.0 / length2 if length2 > 0.0 else 0.0
    u = 0.5 * (u0 + u1)
    best = 0.0
    for it in range(CHORD_NEWTON_STEPS):
        if it > 0:
            span = find_span_from(U, n, p, u, span)
            curve_ders(U, B, p, u, span, 2, work, CK)
        t = 0.0
        for c in range(dim):
            t += (CK[0, c] - P0[c]) * (P1[c] - P0[c]) * inv2
        inside = 0.0 < t < 1.0
        t = min(max(t, 0.0), 1.0)
        d2 = 0.0
        g = 0.0
        gp = 0.0
        t1e = 0.0  # C'·(P1 - P0), the part of C' along the chord
        for c in range(dim):
            q = CK[0, c] - P0[c] - t * (P1[c] - P0[c])
            d2 += q * q
            g += CK[1, c] * q
            gp += CK[2, c] * q + CK[1, c] * CK[1, c]
            t1e += CK[1, c] * (P1[c] - P0[c])
        if inside:
            gp -= t1e * t1e * inv2
        best = max(best, math.sqrt(d2))
        if gp >= 0.0:  # not near a maximum of the distance: keep the best sample
            break
        if abs(g / gp) <= 1e-3 * (u1 - u0):
            # the maximum is close: the quadratic model of d² gives it to ~1e-9 relative
            best = max(best, math.sqrt(max(d2 - g * g / gp, 0.0)))
            break
        nxt = min(max(u - g / gp, u0), u1)
        # the distance is flat at its maximum: u to 1e-6 of the step gives it to ~1e-12
        if abs(nxt - u) <= 1e-6 * (u1 - u0):
            break
        u = nxt
    return best


@njit(cache=True)
def _segment_distance(X, P0, P1):
    """Distance from the point X to the segment P0 P1."""
    dim = P0.shape[0]
    length2 = 0.0
    along = 0.0
    for c in range(dim):
        length2 += (P1[c] - P0[c]) ** 2
        along += (X[c] - P0[c]) * (P1[c] - P0[c])
    t = min(max(along / length2, 0.0), 1.0) if length2 > 0.0 else 0.0
    d2 = 0.0
    for c in range(dim):
        d2 += (X[c] - P0[c] - t * (P1[c] - P0[c])) ** 2
    return math.sqrt(d2)


CHORD_SAMPLES = 8  # intervals sampled on each piece of a step for the largest distance from its chord


@njit(cache=True)
def _chord_sampled(U, B, p, n, u0, u1, P0, P1, work, CK):
    """Chord error of a step from the curve itself, split at the knots strictly inside (u0, u1).

    The curve is one polynomial piece between consecutive knots, but not across
    them.  Each piece [lo, hi] is sampled at CHORD_SAMPLES + 1 points, its
    ends included (so every interior knot is a candidate: at a C0 knot the
    distance has a kink there, usually its maximum), on its own span; then
    :func:`_chord_newton` refines between the neighbours of the best sample (a
    piece may curl away from the chord, and a step through an inflection has a
    maximum each side of it: Newton from the middle finds either).  Distances
    are to the segment.  The steps the tick's derivatives cannot measure
    (:func:`_hermite_step`) come here.
    """
    best = 0.0
    lo = u0
    j = find_span(U, n, p, u0) + 1  # U[j] is the first knot above u0
    ns = CHORD_SAMPLES
    while True:
        while j <= n + 1 and U[j] <= lo:
            j += 1
        hi = U[j] if j <= n + 1 and U[j] < u1 else u1
        span = find_span(U, n, p, 0.5 * (lo + hi))
        top = 0
        piece = -1.0
        for i in range(ns + 1):
            u = hi if i == ns else lo + (hi - lo) * i / ns
            curve_ders(U, B, p, u, span, 0, work, CK)  # the piece's polynomial also at hi (C0: the same point)
            d = _segment_distance(CK[0], P0, P1)
            if d > piece:
                piece = d
                top = i
        best = max(best, piece)
        a = lo + (hi - lo) * max(top - 1, 0) / ns
        b = hi if top + 1 >= ns else lo + (hi - lo) * (top + 1) / ns
        mid = 0.5 * (a + b)
        curve_ders(U, B, p, mid, span, 2, work, CK)
        best = max(best, _chord_newton(U, B, p, n, span, a, b, P0, P1, work, CK))
        if hi >= u1:
            return best
        lo = hi


@njit(cache=True)
def chord_error(U, B, p, n, u0, u1, P0, P1, work, CK):
    """Max distance from C([u0, u1]) to the segment P0 P1 (P0 = C(u0), P1 = C(u1)), mm: :func:`_chord_sampled`."""
    return _chord_sampled(U, B, p, n, u0, u1, P0, P1, work, CK)


@njit(cache=True)
def _step_exact(U, B, p, n, starts, spans, cum, u0, u1, P0, P1, planned, counted, span, work, CK, CK2):
    """(FF, chord error, span of the middle) of one step u0 < u1 from the curve itself.

    The middle of the step is evaluated once: it is the centre node of the
    3-point Gauss rule of the step's arc length and the start of the chord
    error's Newton iteration.  The chord error is :func:`_chord_sampled`'s.
    """
    mid = 0.5 * (u0 + u1)
    span = find_span_from(U, n, p, mid, span)
    curve_ders(U, B, p, mid, span, 2, work, CK)
    ff = 0.0
    if counted:
        ff = step_length_mid(U, B, p, starts, spans, cum, u0, u1, norm_row(CK, 1), work, CK2) / planned - 1.0
    return ff, _chord_sampled(U, B, p, n, u0, u1, P0, P1, work, CK), span


@njit(cache=True)
def step_measures(U, B, p, n, starts, spans, cum, us, pts, S, min_step, ff, chord, counted):
    """Per-step FF and chord error over consecutive rows (len(us) - 1 steps), from the curve itself
    (:func:`_step_exact`); the reference the run's own measures (:func:`measure_steps`) fall back on."""
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    CK2 = np.empty((3, dimh - 1))  # for the Gauss nodes, so that CK keeps the middle of the step
    b = U[n + 1]
    span = p
    for k in range(us.shape[0] - 1):
        u0 = us[k]
        u1 = us[k + 1]
        planned = S[k + 1] - S[k]
        counted[k] = planned >= min_step and u1 < b
        if not u1 > u0:
            ff[k] = -1.0 if counted[k] else 0.0
            chord[k] = 0.0
            continue
        ff[k], chord[k], span = _step_exact(U, B, p, n, starts, spans, cum, u0, u1, pts[k], pts[k + 1], planned,
                                            counted[k], span, work, CK, CK2)


#: a step's quintic is trusted where it misses the curve at the step's middle by at most this many
#: units in the last place of the step's largest coordinate (the rounding of the two evaluations)
HERMITE_ULPS = 32.0
HERMITE_LENGTH_TOL = 1e-9  # the most Simpson's rule may differ from the corrected one (exact to degree 5)
HERMITE_SPEED_CHANGE = 0.1  # the most |C'| may change along a step measured from its ends' derivatives
HERMITE_COS_TURN = math.cos(0.1)  # and the most its tangent may turn, rad


@njit(cache=True, inline="always")
def _quintic_perp(Q, e, t, x, d1):
    """Squared distance of Q(τ) (held as Q − P0) from the chord's line (unit direction e), and its
    half-derivatives g, g'; x and d1 are scratch (dim,)."""
    dim = e.shape[0]
    along = 0.0
    t1e = 0.0
    for c in range(dim):
        x[c] = t * (Q[1, c] + t * (Q[2, c] + t * (Q[3, c] + t * (Q[4, c] + t * Q[5, c]))))
        d1[c] = Q[1, c] + t * (2.0 * Q[2, c] + t * (3.0 * Q[3, c] + t * (4.0 * Q[4, c] + t * 5.0 * Q[5, c])))
        along += x[c] * e[c]
        t1e += d1[c] * e[c]
    d2 = 0.0
    g = 0.0
    gp = 0.0
    for c in range(dim):
        dd = 2.0 * Q[2, c] + t * (6.0 * Q[3, c] + t * (12.0 * Q[4, c] + t * 20.0 * Q[5, c]))
        perp = x[c] - along * e[c]
        d2 += perp * perp
        g += d1[c] * perp
        gp += dd * perp + d1[c] * d1[c]
    return d2, g, gp - t1e * t1e


@njit(cache=True)
def _hermite_step(U, B, p, span, u0, u1, P0, D0, W0, P1, D1, W1, work, CK, Q):
    """(trusted, arc length, chord error) of a step from the derivatives at its ends.

    Only a step along which the tangent turns by at most 0.01 rad and the
    parametric speed σ = |C'| changes by at most 1 % is measured here.  The
    quintic Hermite Q(τ), τ in [0, 1], through P0, P1 with the ends' first and
    second derivatives (D, W, per unit of u) matches the curve's piece to
    O(h⁶); it is trusted when it meets the curve at the step's middle (one
    evaluation, of the point and C') within HERMITE_ULPS of the coordinates —
    its error τ³(1 − τ)³ h⁶ C⁽⁶⁾/720 is largest there.  The chord error is
    Newton on Q's perpendicular distance from the chord, as
    :func:`_chord_newton` does on the curve but from the best of CHORD_SAMPLES − 1
    samples (a step through an inflection has a maximum each side) — or, in
    2-D where the quintic's distance is concave, Newton from the middle on the
    signed distance alone — and errs by at most |Q − C|.  The
    arc length is the corrected Simpson rule on σ, exact for quintics,
    h(7σ0 + 16σm + 7σ1)/30 + h²(σ0' − σ1')/60, trusted where plain Simpson
    agrees with it to HERMITE_LENGTH_TOL (its own error is smaller by about
    (h/ℓ)², ℓ the scale on which σ changes).  ``Q`` (6, dim) holds Q − P0 in
    powers of τ.
    """
    dim = P0.shape[0]
    # only a step along which the tangent turns and the parametric speed changes little: elsewhere
    # (a tight turn within one tick) neither the quintic nor a 3-point rule on it can be trusted
    s0 = 0.0
    s1 = 0.0
    dot = 0.0
    for c in range(dim):
        s0 += D0[c] * D0[c]
        s1 += D1[c] * D1[c]
        dot += D0[c] * D1[c]
    s0 = math.sqrt(s0)
    s1 = math.sqrt(s1)
    if not (abs(s1 - s0) <= HERMITE_SPEED_CHANGE * s0 and dot >= HERMITE_COS_TURN * s0 * s1):
        return False, 0.0, 0.0
    h = u1 - u0
    h2 = h * h
    scale = 1.0
    for c in range(dim):
        dp = P1[c] - P0[c]
        v0 = h * D0[c]
        v1 = h * D1[c]
        w0 = h2 * W0[c]
        w1 = h2 * W1[c]
        Q[0, c] = 0.0
        Q[1, c] = v0
        Q[2, c] = 0.5 * w0
        Q[3, c] = 10.0 * dp - 6.0 * v0 - 4.0 * v1 - 1.5 * w0 + 0.5 * w1
        Q[4, c] = -15.0 * dp + 8.0 * v0 + 7.0 * v1 + 1.5 * w0 - w1
        Q[5, c] = 6.0 * dp - 3.0 * v0 - 3.0 * v1 - 0.5 * w0 + 0.5 * w1
        scale = max(scale, abs(P0[c]), abs(P1[c]))
    ders_fast(U, B, p, 0.5 * (u0 + u1), span, 1, work[0], CK)
    miss = 0.0
    for c in range(dim):
        q = Q[1, c] / 2 + Q[2, c] / 4 + Q[3, c] / 8 + Q[4, c] / 16 + Q[5, c] / 32
        miss += (CK[0, c] - P0[c] - q) ** 2
    if math.sqrt(miss) > HERMITE_ULPS * 2.220446049250313e-16 * scale:
        return False, 0.0, 0.0
    # the arc length from the speed σ = |C'| alone (the ends' σ and σ' = C'·C''/σ, the middle's σ), not
    # from the points: on a step of a few µm the rounding of the points would be its 1e-9
    sm = norm_row(CK, 1)
    ds0 = 0.0
    ds1 = 0.0
    for c in range(dim):
        ds0 += D0[c] * W0[c]
        ds1 += D1[c] * W1[c]
    simpson = h * (s0 + 4.0 * sm + s1) / 6.0
    length = h * (7.0 * (s0 + s1) + 16.0 * sm) / 30.0 + h2 * (ds0 / s0 - ds1 / s1) / 60.0
    if abs(length - simpson) > HERMITE_LENGTH_TOL * length:
        return False, 0.0, 0.0
    chord_len = 0.0
    for c in range(dim):
        chord_len += (P1[c] - P0[c]) ** 2
    chord_len = math.sqrt(chord_len)
    if not chord_len > 0.0:  # the step returns to its start: no chord to measure from
        return False, 0.0, 0.0
    if dim == 2:
        # the signed distance from the chord's line, f(τ) = e × (Q(τ) − P0), is a quintic with f(0) = f(1) = 0;
        # where f'' keeps its sign on [0, 1] (no inflection in the step: the common case) it has one extremum,
        # which Newton on f' from the middle finds
        ex = (P1[0] - P0[0]) / chord_len
        ey = (P1[1] - P0[1]) / chord_len
        f1 = ex * Q[1, 1] - ey * Q[1, 0]
        f2 = ex * Q[2, 1] - ey * Q[2, 0]
        f3 = ex * Q[3, 1] - ey * Q[3, 0]
        f4 = ex * Q[4, 1] - ey * Q[4, 0]
        f5 = ex * Q[5, 1] - ey * Q[5, 0]
        if abs(2.0 * f2) > 6.0 * abs(f3) + 12.0 * abs(f4) + 20.0 * abs(f5):
            t = 0.5
            for it in range(8):
                fv = t * (f1 + t * (f2 + t * (f3 + t * (f4 + t * f5))))
                d1 = f1 + t * (2.0 * f2 + t * (3.0 * f3 + t * (4.0 * f4 + t * 5.0 * f5)))
                dd = 2.0 * f2 + t * (6.0 * f3 + t * (12.0 * f4 + t * 20.0 * f5))
                step = d1 / dd
                if abs(step) <= 1e-4:
                    # f at t - step by its quadratic model: off by about step³ times the third derivative
                    return True, length, abs(fv - 0.5 * d1 * step)
                t = min(max(t - step, 0.0), 1.0)
            return True, length, abs(t * (f1 + t * (f2 + t * (f3 + t * (f4 + t * f5)))))
    # the distance from the chord is a polynomial in τ: sample it (a step through an inflection has
    # two maxima, one each side, and Newton from the middle would find either), then Newton from the best
    e, x, d1 = Q[6], Q[7], Q[8]
    for c in range(dim):
        e[c] = (P1[c] - P0[c]) / chord_len
    t = 0.5
    best = -1.0
    for i in range(1, CHORD_SAMPLES):
        ti = i / CHORD_SAMPLES
        d2, _, _ = _quintic_perp(Q, e, ti, x, d1)
        if d2 > best:
            best = d2
            t = ti
    lo = t - 1.0 / CHORD_SAMPLES
    hi = t + 1.0 / CHORD_SAMPLES
    best = math.sqrt(best)
    for it in range(8):
        d2, g, gp = _quintic_perp(Q, e, t, x, d1)
        best = max(best, math.sqrt(d2))
        if gp >= 0.0:  # not near a maximum of the distance: keep the best sample
            break
        if abs(g / gp) <= 1e-3 / CHORD_SAMPLES:  # the quadratic model of d² gives the maximum to ~1e-9 relative
            best = max(best, math.sqrt(max(d2 - g * g / gp, 0.0)))
            break
        nxt = min(max(t - g / gp, lo), hi)
        if abs(nxt - t) <= 1e-6 / CHORD_SAMPLES:
            break
        t = nxt
    return True, length, best


# the accumulators of measure_steps
FF_MAX, FF_MAX_K, FF_SUMSQ, FF_COUNT, CHORD_MAX, CHORD_MAX_K, EXACT_STEPS = range(7)


@njit(cache=True, nogil=True)  # nogil: it runs beside the interpolation (Alongside)
def measure_steps(U, B, p, n, starts, spans, cum, us, pts, ders, S, k0, prev_u, prev_S, prev_P, prev_D, min_step, acc):
    """FF and chord error of the steps into rows 0 .. m-1 of a chunk, accumulated into *acc*.

    Step j runs from row j − 1 to row j; row −1 is the previous chunk's last
    (prev_u, prev_S, prev_P, prev_D; prev_u NaN at the start of the run).  ``ders``
    are the derivatives the tick computed at each u (:class:`~nurbsinterp.interpolate.Chunk`),
    so that a step inside one knot span costs one point evaluation
    (:func:`_hermite_step`); a step across or onto a knot, or one the quintic
    does not match, is measured from the curve itself (:func:`_step_exact`) and
    counted in acc[EXACT_STEPS].  ``acc`` holds the signed FF of largest
    magnitude and its tick, the sum of its squares and count, the largest chord
    error and its step's first tick: the first tick wins a tie, as np.argmax.
    """
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    CK2 = np.empty((3, dimh - 1))
    Q = np.empty((9, dimh - 1))
    b = U[n + 1]
    span = p
    for j in range(us.shape[0]):
        if j == 0:
            if not prev_u == prev_u:
                continue
            u0, S0, P0, D0, W0 = prev_u, prev_S, prev_P, prev_D[0], prev_D[1]
        else:
            u0, S0, P0, D0, W0 = us[j - 1], S[j - 1], pts[j - 1], ders[j - 1, 0], ders[j - 1, 1]
        u1 = us[j]
        planned = S[j] - S0
        counted = planned >= min_step and u1 < b
        k = k0 + j - 1  # the step's first tick
        ff = -1.0
        chord = 0.0
        if u1 > u0:
            span = find_span_from(U, n, p, u0, span)
            ok = False
            if u1 < U[span + 1]:  # inside the span both ends' derivatives were computed on
                ok, length, chord = _hermite_step(U, B, p, span, u0, u1, P0, D0, W0, pts[j], ders[j, 0],
                                                  ders[j, 1], work, CK, Q)
                ff = length / planned - 1.0 if counted else 0.0
            if not ok:
                ff, chord, span = _step_exact(U, B, p, n, starts, spans, cum, u0, u1, P0, pts[j], planned, counted,
                                              span, work, CK, CK2)
                acc[EXACT_STEPS] += 1.0
        if counted:
            if abs(ff) > abs(acc[FF_MAX]):
                acc[FF_MAX] = ff
                acc[FF_MAX_K] = k
            acc[FF_SUMSQ] += ff * ff
            acc[FF_COUNT] += 1.0
        if chord > acc[CHORD_MAX]:
            acc[CHORD_MAX] = chord
            acc[CHORD_MAX_K] = k


@njit(cache=True)
def abs_max_sumsq(values):
    """(index of the first largest |value|, sum of squares) in one pass.

    A plain loop, not ``values @ values``: NumPy hands a dot product to BLAS,
    whose threads then spin on the other core after every chunk (issue 16)."""
    j = 0
    top = -1.0
    total = 0.0
    for i in range(values.shape[0]):
        x = values[i]
        if abs(x) > top:
            top = abs(x)
            j = i
        total += x * x
    return j, total


class RunStats:
    """Accumulates the measures of a run chunk by chunk (memory independent of its length).

    Parameters
    ----------
    curve : the NurbsCurve
    peak : the planned peak feedrate, mm/s
    period : T, s
    deviation : also measure the distance of each command from the curve (for
        acc/dec after interpolation, whose commands leave the path)

    Chunks that carry the tick's derivatives (``Interpolation.chunks(derivatives=True)``)
    are measured from them (:func:`measure_steps`); others have them evaluated here.
    """

    def __init__(self, curve, peak: float, period: float, deviation: bool = False):
        self.curve = curve
        self.min_step = FF_MIN_STEP * peak * period
        self.deviation = deviation
        # the distance of a command from the path as simulate measures the table's (windowed, exact)
        self._window = PathWindow(curve) if deviation else None
        self.ticks = 0
        self.deviation_max = 0.0
        self.deviation_max_k = -1
        self._acc = np.zeros(7)
        self._acc[FF_MAX_K] = self._acc[CHORD_MAX_K] = -1.0
        # the previous chunk's last row: u (NaN: none yet), S, the point on the curve, its derivatives
        dim = curve.dim
        self._prev = np.full(2, np.nan), np.zeros(dim), np.zeros((2, dim))

    def update(self, chunk, dim: int) -> None:
        data = chunk.data
        m = data.shape[0]
        if m == 0:
            return
        us = np.ascontiguousarray(chunk.u)
        if chunk.ders is not None:
            ders = chunk.ders
            on_curve = self.curve.evaluate(us) if self.deviation else chunk.points
        else:
            both = self.curve.derivatives(us, 2)
            on_curve, ders = both[:, 0], both[:, 1:]
            if not self.deviation:
                on_curve = chunk.points
        if self.deviation:
            _, dist = self._window.nearest(chunk.points, us)
            j = int(np.argmax(dist))
            if dist[j] > self.deviation_max:
                self.deviation_max, self.deviation_max_k = float(dist[j]), int(data[j, 0])
        (prev_u, prev_S), prev_P, prev_D = self._prev
        U, B, p, n = self.curve.kernel_args
        on_curve = np.ascontiguousarray(on_curve)
        ders = np.ascontiguousarray(ders)
        S = np.ascontiguousarray(chunk.planned)
        measure_steps(U, B, p, n, *self.curve.panels, us, on_curve, ders, S, int(data[0, 0]), prev_u, prev_S,
                      prev_P, prev_D, self.min_step, self._acc)
        self._prev = np.array([us[-1], S[-1]]), on_curve[-1].copy(), ders[-1].copy()
        self.ticks += m

    ff_max = property(lambda self: float(self._acc[FF_MAX]), doc="the signed FF of largest magnitude")
    ff_max_k = property(lambda self: int(self._acc[FF_MAX_K]))
    ff_sumsq = property(lambda self: float(self._acc[FF_SUMSQ]))
    ff_count = property(lambda self: int(self._acc[FF_COUNT]))
    chord_max = property(lambda self: float(self._acc[CHORD_MAX]), doc="mm")
    chord_max_k = property(lambda self: int(self._acc[CHORD_MAX_K]))
    exact_steps = property(lambda self: int(self._acc[EXACT_STEPS]),
                           doc="steps measured from the curve itself, not from the tick's derivatives")

    @property
    def ff_rms(self) -> float:
        return math.sqrt(self.ff_sumsq / self.ff_count) if self.ff_count else 0.0


class Alongside:
    """Calls ``update(*args)`` for each :meth:`submit` on a second thread, in order, at most *depth* calls behind.

    The run's measures then cost the first core nothing but the hand-over:
    :func:`measure_steps` and the tick kernel release the GIL, so the two
    kernels run on two cores at once.  On a machine whose other core is busy
    the work is the same, only not overlapped.  Use as a context manager: on
    leaving it every submitted call has run, and an exception raised in one of
    them is raised here (or by the next submit).
    """

    def __init__(self, update, depth: int = 2):
        self._update = update
        self._calls = queue.Queue(maxsize=depth)  # bounded: a slow consumer holds up the producer, memory stays flat
        self._error = None
        self._thread = threading.Thread(target=self._run, name="nurbsinterp-measures", daemon=True)
        self._thread.start()

    def _run(self):
        while True:
            args = self._calls.get()
            if args is None:
                return
            if self._error is None:
                try:
                    self._update(*args)
                except BaseException as exc:  # handed to the submitting thread
                    self._error = exc

    def submit(self, *args) -> None:
        if self._error is not None:
            raise self._error
        self._calls.put(args)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        self._calls.put(None)
        self._thread.join()
        if kind is None and self._error is not None:
            raise self._error
        return False
