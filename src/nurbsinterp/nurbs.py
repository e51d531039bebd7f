"""NURBS geometry: evaluation, derivatives, arc length, curvature, projection.

Conventions
-----------
Degree p (order = p + 1, the paper's k); control points V_0..V_n; knots
U_0..U_{n+p+1}; parameter domain [U_p, U_{n+1}].  Control points are stored
homogeneous, ``B[i] = (W_i V_i, W_i)``, so the rational derivatives are one
quotient rule (Piegl & Tiller, A4.2).

Derivatives are right-sided: at an interior knot u = U_i the polynomial of the
span [U_i, U_{i+1}) is used, so a knot of multiplicity p (the paper's circle
has one at 0.5) gives the exact one-sided derivative the interpolator needs
when it steps forward.  The domain end U_{n+1} belongs to the last span.

Every per-point routine is a numba kernel working on plain arrays with a
preallocated workspace, so that the per-tick path does no allocation and no
Python-level work; the vectorised methods of :class:`NurbsCurve` loop the same
kernels over arrays.
"""
from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from ._jit import njit
from .errors import SpecError
from .extrema import discrete_minima

# Gauss–Legendre rule used for every arc-length integral.  Panels are refined
# until this rule is converged on each of them (see build_panels), so it is
# also converged on any sub-interval of a panel.
GL_NODES, GL_WEIGHTS = np.polynomial.legendre.leggauss(10)
# A short step inside one panel needs far fewer nodes: the 3-point rule on a
# piece no wider than 1/16 of a converged panel is exact to rounding.
STEP_NODES, STEP_WEIGHTS = np.polynomial.legendre.leggauss(3)
STEP_FRACTION = 1.0 / 16.0
ARC_RTOL = 1e-14  # relative tolerance of the panel refinement (issue asks <= 1e-10)
MAX_PANEL_DEPTH = 40
MAX_PANELS = 1 << 22  # ~100 MB of table; a curve needing more is refused, not refined forever
PANELS_OK, PANELS_NOT_FINITE, PANELS_TOO_MANY = 0, 1, 2


# --------------------------------------------------------------------------- kernels


@njit(cache=True)
def find_span(U, n, p, u):
    """Index i with U[i] <= u < U[i+1] and U[i] < U[i+1]; the domain end maps to n."""
    if u >= U[n + 1]:
        return n
    if u <= U[p]:
        return p
    lo = p
    hi = n + 1
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if u < U[mid]:
            hi = mid
        else:
            lo = mid
    return lo


@njit(cache=True)
def find_span_from(U, n, p, u, hint):
    """find_span, first walking forward from *hint* (the interpolator moves forward)."""
    if hint < p or hint > n or u < U[hint]:
        return find_span(U, n, p, u)
    if u >= U[n + 1]:
        return n
    for _ in range(4):
        if u < U[hint + 1]:
            return hint
        hint += 1
    return find_span(U, n, p, u)


MAX_DERIVATIVE = 3  # derivatives kept in the Bezier table: the interpolators need 2, curvature tests 3


@njit(cache=True)
def make_work(p, nd, dimh):
    """Scratch arrays for :func:`curve_ders` (degree p, derivatives up to nd)."""
    return np.empty((p + 1, dimh)), np.empty((nd + 1, dimh))


@njit(cache=True)
def bezier_table(U, Pw, p, n):
    """Homogeneous Bezier control points of every knot span, and of its derivatives.

    ``B[i, d, j]`` is control point j of the d-th derivative (with respect to u)
    of the homogeneous curve on the non-empty span [U[i], U[i+1]) — a Bezier
    of degree p - d — for d up to MAX_DERIVATIVE; rows of other spans are zero.
    The segments come from knot insertion (Piegl & Tiller A5.6, DecomposeCurve),
    which is exact up to rounding and stable for any degree.
    """
    dimh = Pw.shape[1]
    B = np.zeros((n + 1, MAX_DERIVATIVE + 1, p + 1, dimh))
    m = n + p + 1
    Q = Pw[: p + 1].copy()
    Qn = np.zeros((p + 1, dimh))
    alphas = np.empty(p + 1)
    a = p
    b = p + 1
    while b < m:
        i = b
        while b < m and U[b + 1] == U[b]:
            b += 1
        mult = b - i + 1
        if mult < p:
            numer = U[b] - U[a]
            for j in range(p, mult, -1):
                alphas[j - mult - 1] = numer / (U[a + j] - U[a])
            r = p - mult
            for j in range(1, r + 1):
                save = r - j
                first = mult + j
                for k in range(p, first - 1, -1):
                    alpha = alphas[k - first]
                    for c in range(dimh):
                        Q[k, c] = alpha * Q[k, c] + (1.0 - alpha) * Q[k - 1, c]
                if b < m:
                    Qn[save] = Q[p]
        _store_segment(B, U, p, a, Q)
        if b < m:
            for j in range(p - mult, p + 1):
                Qn[j] = Pw[b - p + j]
            Q, Qn = Qn, Q
            a = b
            b += 1
    return B


@njit(cache=True)
def _store_segment(B, U, p, span, Q):
    h = U[span + 1] - U[span]
    B[span, 0] = Q
    for d in range(1, min(p, MAX_DERIVATIVE) + 1):
        factor = (p - d + 1) / h
        for j in range(p - d + 1):
            B[span, d, j] = factor * (B[span, d - 1, j + 1] - B[span, d - 1, j])


@njit(cache=True, inline="always")
def curve_ders(U, B, p, u, span, nd, work, CK):
    """Point and derivatives up to nd (<= MAX_DERIVATIVE) of the NURBS at u, on *span*.

    Writes ``CK[k, :dim]`` = k-th derivative.  Each homogeneous derivative is a
    de Casteljau evaluation of the span's Bezier table, then the rational
    quotient rule (Piegl & Tiller A4.2).  Passing the span explicitly lets a
    caller evaluate the left-hand limit at a knot (u = U[span + 1]).
    """
    tmp, Aw = work
    dimh = B.shape[3]
    dim = dimh - 1
    t = (u - U[span]) / (U[span + 1] - U[span])
    s = 1.0 - t
    top = min(nd, p)
    for d in range(top + 1):
        q = p - d
        for j in range(q + 1):
            for c in range(dimh):
                tmp[j, c] = B[span, d, j, c]
        for r in range(1, q + 1):
            for j in range(q - r + 1):
                for c in range(dimh):
                    tmp[j, c] = s * tmp[j, c] + t * tmp[j + 1, c]
        for c in range(dimh):
            Aw[d, c] = tmp[0, c]
    for d in range(top + 1, nd + 1):
        for c in range(dimh):
            Aw[d, c] = 0.0
    w0 = Aw[0, dim]
    for k in range(nd + 1):
        for c in range(dim):
            v = Aw[k, c]
            binom = 1.0
            for i in range(1, k + 1):
                binom = binom * (k - i + 1) / i
                v -= binom * Aw[i, dim] * CK[k - i, c]
            CK[k, c] = v / w0


@njit(cache=True, inline="always")
def ders_fast(U, B, p, u, span, nd, tmp, CK):
    """curve_ders for nd <= 2, from one de Casteljau pass over the span's points (tmp: (p + 1, dimh)).

    The last two levels of the pass give the homogeneous derivatives (A' = p/h·(c1 − c0),
    A'' = p(p − 1)/h²·(b2 − 2b1 + b0)) without the derivative tables' own passes; the
    rational quotient rule is curve_ders'.  For nd = 0 it is curve_ders to the bit.  The
    contour error's per-tick path (arc-length steps, Newton) runs on it.
    """
    dimh = B.shape[3]
    dim = dimh - 1
    h = U[span + 1] - U[span]
    t = (u - U[span]) / h
    s = 1.0 - t
    for j in range(p + 1):
        for c in range(dimh):
            tmp[j, c] = B[span, 0, j, c]
    m = min(nd, p)
    for r in range(1, p - m + 1):
        for j in range(p - r + 1):
            for c in range(dimh):
                tmp[j, c] = s * tmp[j, c] + t * tmp[j + 1, c]
    if m == 0:
        w = tmp[0, dim]
        for c in range(dim):
            CK[0, c] = tmp[0, c] / w
        for k in range(1, nd + 1):
            for c in range(dim):
                CK[k, c] = 0.0
        return
    f1 = p / h
    if m == 1:
        w = s * tmp[0, dim] + t * tmp[1, dim]
        w1 = f1 * (tmp[1, dim] - tmp[0, dim])
        for c in range(dim):
            CK[0, c] = (s * tmp[0, c] + t * tmp[1, c]) / w
            CK[1, c] = (f1 * (tmp[1, c] - tmp[0, c]) - w1 * CK[0, c]) / w
        if nd == 2:  # degree 1: no second derivative of A and w
            for c in range(dim):
                CK[2, c] = (0.0 - 2.0 * w1 * CK[1, c]) / w
        return
    f2 = f1 * (p - 1) / h
    c0 = s * tmp[0, dim] + t * tmp[1, dim]
    c1 = s * tmp[1, dim] + t * tmp[2, dim]
    w = s * c0 + t * c1
    w1 = f1 * (c1 - c0)
    w2 = f2 * (tmp[2, dim] - 2.0 * tmp[1, dim] + tmp[0, dim])
    for c in range(dim):
        c0 = s * tmp[0, c] + t * tmp[1, c]
        c1 = s * tmp[1, c] + t * tmp[2, c]
        CK[0, c] = (s * c0 + t * c1) / w
        CK[1, c] = (f1 * (c1 - c0) - w1 * CK[0, c]) / w
        CK[2, c] = (f2 * (tmp[2, c] - 2.0 * tmp[1, c] + tmp[0, c]) - 2.0 * w1 * CK[1, c] - w2 * CK[0, c]) / w


@njit(cache=True)
def step_length_fast(U, B, p, starts, spans, cum, u0, u1, tmp, work, CK):
    """step_length (u0 <= u1) on ders_fast: the same rule (3-point Gauss inside one panel,
    else the panel table), its three speeds each from one de Casteljau pass."""
    if not u1 > u0:
        return 0.0
    k = np.searchsorted(starts, u0, side="right") - 1
    if 0 <= k < spans.shape[0] and u1 <= starts[k + 1] and u1 - u0 <= STEP_FRACTION * (starts[k + 1] - starts[k]):
        span = spans[k]
        half = 0.5 * (u1 - u0)
        mid = 0.5 * (u0 + u1)
        ders_fast(U, B, p, mid, span, 1, tmp, CK)
        s = STEP_WEIGHTS[1] * norm_row(CK, 1)
        ders_fast(U, B, p, mid + half * STEP_NODES[0], span, 1, tmp, CK)
        s += STEP_WEIGHTS[0] * norm_row(CK, 1)
        ders_fast(U, B, p, mid + half * STEP_NODES[2], span, 1, tmp, CK)
        s += STEP_WEIGHTS[2] * norm_row(CK, 1)
        return s * half
    return (arc_length_to(U, B, p, starts, spans, cum, u1, work, CK)
            - arc_length_to(U, B, p, starts, spans, cum, u0, work, CK))


@njit(cache=True)
def norm_row(CK, k):
    s = 0.0
    for c in range(CK.shape[1]):
        s += CK[k, c] * CK[k, c]
    return math.sqrt(s)


@njit(cache=True)
def dot_rows(CK, i, j):
    s = 0.0
    for c in range(CK.shape[1]):
        s += CK[i, c] * CK[j, c]
    return s


@njit(cache=True)
def speed_at(U, B, p, u, span, work, CK):
    """Parametric speed |C'(u)| (mm per unit of u) on *span*."""
    curve_ders(U, B, p, u, span, 1, work, CK)
    return norm_row(CK, 1)


@njit(cache=True)
def gauss_length(U, B, p, a, b, span, work, CK):
    """Arc length from a to b, both inside *span*, by one Gauss–Legendre rule."""
    half = 0.5 * (b - a)
    mid = 0.5 * (a + b)
    s = 0.0
    for i in range(GL_NODES.shape[0]):
        s += GL_WEIGHTS[i] * speed_at(U, B, p, mid + half * GL_NODES[i], span, work, CK)
    return s * half


@njit(cache=True)
def build_panels(U, B, p, n, rtol, floor, max_depth, max_panels):
    """Split the domain into panels on which the Gauss rule is converged.

    A panel is converged when its two halves agree with it to rtol times the
    curve's length, or to *floor* mm, the rounding noise no bisection removes.
    Returns (starts, spans, cum, status): panel k covers [starts[k], starts[k+1]]
    inside knot span spans[k]; cum[k] is the arc length from the domain start to
    starts[k]; cum[-1] is the curve length.  status is PANELS_OK, or
    PANELS_NOT_FINITE (the speed overflows; starts[0] is where) or
    PANELS_TOO_MANY (more than *max_panels* would be needed).
    """
    dimh = B.shape[3]
    work = make_work(p, 1, dimh)
    CK = np.empty((2, dimh - 1))
    estimate = 0.0
    for i in range(p, n + 1):
        if U[i + 1] > U[i]:
            m = 0.5 * (U[i] + U[i + 1])
            estimate += gauss_length(U, B, p, U[i], m, i, work, CK)
            estimate += gauss_length(U, B, p, m, U[i + 1], i, work, CK)
            if not math.isfinite(estimate):
                return np.full(1, U[i]), np.zeros(0, dtype=np.int64), np.zeros(1), PANELS_NOT_FINITE
    tol = max(rtol * estimate, floor)
    cap = 64
    starts = np.empty(cap)
    spans = np.empty(cap, dtype=np.int64)
    lengths = np.empty(cap)
    count = 0
    stack_a = np.empty(max_depth + 2)
    stack_b = np.empty(max_depth + 2)
    stack_d = np.empty(max_depth + 2, dtype=np.int64)
    for i in range(p, n + 1):
        if not U[i + 1] > U[i]:
            continue
        top = 0
        stack_a[0] = U[i]
        stack_b[0] = U[i + 1]
        stack_d[0] = 0
        while top >= 0:
            a = stack_a[top]
            b = stack_b[top]
            depth = stack_d[top]
            top -= 1
            m = 0.5 * (a + b)
            whole = gauss_length(U, B, p, a, b, i, work, CK)
            left = gauss_length(U, B, p, a, m, i, work, CK)
            right = gauss_length(U, B, p, m, b, i, work, CK)
            if abs(whole - (left + right)) <= tol or depth >= max_depth or not (a < m < b):
                if count + 2 > max_panels:
                    return np.full(1, a), np.zeros(0, dtype=np.int64), np.zeros(1), PANELS_TOO_MANY
                if count + 2 > cap:
                    cap *= 2
                    starts = _grow(starts, cap)
                    lengths = _grow(lengths, cap)
                    spans2 = np.empty(cap, dtype=np.int64)
                    spans2[:count] = spans[:count]
                    spans = spans2
                # store the halves: each is far more accurate than the test threshold
                starts[count] = a
                spans[count] = i
                lengths[count] = left
                starts[count + 1] = m
                spans[count + 1] = i
                lengths[count + 1] = right
                count += 2
            else:  # left half first, so that panels come out in order
                top += 1
                stack_a[top] = m
                stack_b[top] = b
                stack_d[top] = depth + 1
                top += 1
                stack_a[top] = a
                stack_b[top] = m
                stack_d[top] = depth + 1
    out_starts = np.empty(count + 1)
    out_starts[:count] = starts[:count]
    out_starts[count] = U[n + 1]
    cum = np.empty(count + 1)
    cum[0] = 0.0
    for k in range(count):
        cum[k + 1] = cum[k] + lengths[k]
    return out_starts, spans[:count].copy(), cum, PANELS_OK


@njit(cache=True)
def _grow(arr, cap):
    out = np.empty(cap)
    out[: arr.shape[0]] = arr
    return out


@njit(cache=True)
def arc_length_to(U, B, p, starts, spans, cum, u, work, CK):
    """s(u): arc length from the domain start to u."""
    if u <= starts[0]:
        return 0.0
    last = starts.shape[0] - 1
    if u >= starts[last]:
        return cum[last]
    k = np.searchsorted(starts, u, side="right") - 1
    return cum[k] + gauss_length(U, B, p, starts[k], u, spans[k], work, CK)


@njit(cache=True)
def step_length_mid(U, B, p, starts, spans, cum, u0, u1, speed_mid, work, CK):
    """Arc length from u0 to u1 >= u0, given the speed at the middle of the step.

    When both ends lie in one panel and the step is short against it, the
    3-point Gauss rule, whose centre node is the middle (hence *speed_mid*),
    is exact to rounding; otherwise s(u1) − s(u0) from the panel table.
    """
    k = np.searchsorted(starts, u0, side="right") - 1
    if 0 <= k < spans.shape[0] and u1 <= starts[k + 1] and u1 - u0 <= STEP_FRACTION * (starts[k + 1] - starts[k]):
        half = 0.5 * (u1 - u0)
        mid = 0.5 * (u0 + u1)
        s = STEP_WEIGHTS[1] * speed_mid
        s += STEP_WEIGHTS[0] * speed_at(U, B, p, mid + half * STEP_NODES[0], spans[k], work, CK)
        s += STEP_WEIGHTS[2] * speed_at(U, B, p, mid + half * STEP_NODES[2], spans[k], work, CK)
        return s * half
    return (arc_length_to(U, B, p, starts, spans, cum, u1, work, CK)
            - arc_length_to(U, B, p, starts, spans, cum, u0, work, CK))


@njit(cache=True)
def step_length(U, B, p, starts, spans, cum, u0, u1, work, CK):
    """Arc length from u0 to u1 >= u0 (see step_length_mid)."""
    mid = 0.5 * (u0 + u1)
    k = max(np.searchsorted(starts, mid, side="right") - 1, 0)
    return step_length_mid(U, B, p, starts, spans, cum, u0, u1,
                           speed_at(U, B, p, mid, spans[min(k, spans.shape[0] - 1)], work, CK), work, CK)


@njit(cache=True)
def parameter_at(U, B, p, starts, spans, cum, s, guess, work, CK):
    """u with s(u) = s, by Newton on the arc-length integral safeguarded by bisection.

    *guess* seeds Newton when it lies in the right panel (the interpolator passes
    its Taylor prediction); otherwise the seed is linear in the panel.
    """
    last = starts.shape[0] - 1
    if s <= 0.0:
        return starts[0]
    if s >= cum[last]:
        return starts[last]
    k = np.searchsorted(cum, s, side="right") - 1
    a = starts[k]
    b = starts[k + 1]
    span = spans[k]
    lo = a
    hi = b
    if a < guess < b:
        u = guess
    else:
        u = a + (b - a) * (s - cum[k]) / (cum[k + 1] - cum[k])
    tol = 4e-16 * cum[last]
    for _ in range(100):
        f = cum[k] + gauss_length(U, B, p, a, u, span, work, CK) - s
        if f > 0.0:
            hi = u
        else:
            lo = u
        if abs(f) <= tol:
            break
        curve_ders(U, B, p, u, span, 2, work, CK)
        sp = norm_row(CK, 1)
        nxt = u - f / sp if sp > 0.0 else 0.5 * (lo + hi)
        if not (lo < nxt < hi):
            nxt = 0.5 * (lo + hi)
        elif 0.5 * f * f * abs(dot_rows(CK, 1, 2)) <= tol * sp * sp * sp:
            # Newton's residual after this step is about f²·|σ'|/(2σ²) (σ' = C'·C''/σ):
            # below the tolerance, take the step without evaluating s(u) once more
            return nxt
        if nxt == u or hi - lo <= 4e-16 * max(abs(lo), abs(hi)):
            break
        u = nxt
    return u


@njit(cache=True)
def _distance2(CK, q):
    s = 0.0
    for c in range(q.shape[0]):
        d = CK[0, c] - q[c]
        s += d * d
    return s


@njit(cache=True)
def _newton_project(U, B, p, n, q, u, lo, hi, work, CK, have_ders=False):
    """Local minimum of |C(u) - q| in [lo, hi] by safeguarded Newton on C'.(C - q) = 0.

    ``have_ders``: CK already holds the derivatives up to 2 at u (saves one evaluation).
    """
    best_u = u
    best = math.inf
    lo0 = lo
    hi0 = hi
    tried_lo = False
    tried_hi = False
    for it in range(60):
        if it > 0 or not have_ders:
            span = find_span(U, n, p, u)
            curve_ders(U, B, p, u, span, 2, work, CK)
        d2 = _distance2(CK, q)
        if d2 < best:
            best = d2
            best_u = u
        g = 0.0
        gp = 0.0
        for c in range(q.shape[0]):
            diff = CK[0, c] - q[c]
            g += CK[1, c] * diff
            gp += CK[2, c] * diff + CK[1, c] * CK[1, c]
        if g > 0.0:
            hi = u
        elif g < 0.0:
            lo = u
        else:
            break
        if gp > 0.0 and abs(g / gp) * norm_row(CK, 1) <= 1e-8:
            # converged: the Newton step moves the foot by under 1e-8 mm.  Take it without
            # another evaluation, at its distance from the quadratic model (exact to ~1e-24).
            # (Tested before the bracket: a step below an ulp of u lands on the bracket end
            # it came from, and bisecting away from there would throw the answer away.)
            nxt = u - g / gp
            if lo0 <= nxt <= hi0 and d2 - g * g / gp < best:
                best_u = nxt
                best = max(d2 - g * g / gp, 0.0)
            break
        nxt = u - g / gp if gp > 0.0 else 0.5 * (lo + hi)
        # A Newton step that leaves the bracket bisects it instead — except that
        # the first step beyond an end of the original bracket goes exactly to
        # that end, so that a minimum there (q beyond the curve's end) is reached.
        if nxt >= hi:
            if hi == hi0 and not tried_hi:
                nxt = hi
                tried_hi = True
            else:
                nxt = 0.5 * (lo + hi)
        elif nxt <= lo:
            if lo == lo0 and not tried_lo:
                nxt = lo
                tried_lo = True
            else:
                nxt = 0.5 * (lo + hi)
        if nxt == u:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - u) <= 2e-16 * max(1.0, abs(u)) or hi - lo <= 2e-16 * max(1.0, abs(hi)):
            u = nxt
            span = find_span(U, n, p, u)
            curve_ders(U, B, p, u, span, 0, work, CK)
            d2 = _distance2(CK, q)
            if d2 < best:
                best = d2
                best_u = u
            break
        u = nxt
    return best_u, best


@njit(cache=True)
def _newton_project_fast(U, B, p, n, q, u, lo, hi, tmp, CK):
    """_newton_project on ders_fast (no derivatives handed in): the window search's Newton."""
    best_u, best, _how, _last, _span = newton_foot(U, B, p, n, q, u, lo, hi, find_span(U, n, p, u), 60, tmp, CK)
    return best_u, best


NEWTON_FAILED, NEWTON_CONVERGED, NEWTON_AT_END = 0, 1, 2  # how newton_foot ended


@njit(cache=True, inline="always")
def newton_foot(U, B, p, n, q, u, lo, hi, span, iterations, tmp, CK):
    """_newton_project_fast's iteration, telling how it ended: (u, squared distance, how, last u, its span).

    At most *iterations* evaluations (_newton_project_fast allows 60); *span* is a hint for the
    knot span of u (:func:`span_near`: the same spans as find_span's, by a short walk).

    how is NEWTON_CONVERGED where the iteration met a stationary point of the distance (C'·(C - q)
    = 0, or a Newton step moving the foot by under 1e-8 mm, inside [lo, hi]); the answer is then that
    point (the step taken, at its quadratic model's distance) or an iterate no farther from q, within
    rounding of it, and CK holds the derivatives up to 2 at *last u*, the last iterate.  NEWTON_AT_END where
    the answer is an end of [lo, hi] towards which the distance still falls; NEWTON_FAILED otherwise.
    contour.py certifies the first two (its convexity test stands in for the global search).
    """
    best_u = u
    best = math.inf
    lo0 = lo
    hi0 = hi
    tried_lo = False
    tried_hi = False
    for it in range(iterations):
        span = span_near(U, n, p, u, span)
        ders_fast(U, B, p, u, span, 2, tmp, CK)
        d2 = _distance2(CK, q)
        if d2 < best:
            best = d2
            best_u = u
        g = 0.0
        gp = 0.0
        for c in range(q.shape[0]):
            diff = CK[0, c] - q[c]
            g += CK[1, c] * diff
            gp += CK[2, c] * diff + CK[1, c] * CK[1, c]
        if g > 0.0:
            hi = u
        elif g < 0.0:
            lo = u
        else:
            return best_u, best, NEWTON_CONVERGED, u, span
        if gp > 0.0 and abs(g / gp) * norm_row(CK, 1) <= 1e-8:
            # converged: the Newton step moves the foot by under 1e-8 mm.  Take it without
            # another evaluation, at its distance from the quadratic model (exact to ~1e-24).
            # (Tested before the bracket: a step below an ulp of u lands on the bracket end
            # it came from, and bisecting away from there would throw the answer away.)
            nxt = u - g / gp
            if lo0 <= nxt <= hi0 and d2 - g * g / gp < best:
                best_u = nxt
                best = max(d2 - g * g / gp, 0.0)
            return best_u, best, (NEWTON_CONVERGED if lo0 <= nxt <= hi0 else NEWTON_FAILED), u, span
        nxt = u - g / gp if gp > 0.0 else 0.5 * (lo + hi)
        # A Newton step that leaves the bracket bisects it instead — except that
        # the first step beyond an end of the original bracket goes exactly to
        # that end, so that a minimum there (q beyond the curve's end) is reached.
        if nxt >= hi:
            if hi == hi0 and not tried_hi:
                nxt = hi
                tried_hi = True
            else:
                nxt = 0.5 * (lo + hi)
        elif nxt <= lo:
            if lo == lo0 and not tried_lo:
                nxt = lo
                tried_lo = True
            else:
                nxt = 0.5 * (lo + hi)
        if nxt == u:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - u) <= 2e-16 * max(1.0, abs(u)) or hi - lo <= 2e-16 * max(1.0, abs(hi)):
            # stuck at an end of the bracket that the distance falls towards: the answer is that end
            at_end = (u == hi0 and tried_hi and g < 0.0) or (u == lo0 and tried_lo and g > 0.0)
            u = nxt
            span = span_near(U, n, p, u, span)
            ders_fast(U, B, p, u, span, 0, tmp, CK)
            d2 = _distance2(CK, q)
            if d2 < best:
                best = d2
                best_u = u
            return best_u, best, (NEWTON_AT_END if at_end and best_u == u else NEWTON_FAILED), u, span
        u = nxt
    return best_u, best, NEWTON_FAILED, u, span


@njit(cache=True, inline="always")
def span_near(U, n, p, u, span):
    """find_span(U, n, p, u), walking from the span *hint* (a Newton iterate rarely leaves its span)."""
    if span < p or span > n:
        return find_span(U, n, p, u)
    if u >= U[n + 1]:
        return n
    if u <= U[p]:
        return p
    while u >= U[span + 1]:
        span += 1
    while u < U[span]:
        span -= 1
    return span


@njit(cache=True)
def project_window(U, B, p, n, q, lo, hi, samples, work, CK):
    """Closest point to q on C([lo, hi]): sample, then Newton around the best sample."""
    # Newton from every local minimum of the sampled distance, not only the best
    # sample: on a span that folds back the best sample can lie on the wrong branch
    step = (hi - lo) / samples
    best_u = lo
    best = math.inf
    prev2 = math.inf  # d² at sample i - 2 and i - 1
    prev1 = math.inf
    for i in range(samples + 2):
        if i <= samples:
            u = hi if i == samples else lo + step * i
            span = find_span(U, n, p, u)
            curve_ders(U, B, p, u, span, 0, work, CK)
            d2 = _distance2(CK, q)
            if d2 < best:
                best = d2
                best_u = u
        else:
            d2 = math.inf
        if i >= 1 and prev1 <= prev2 and prev1 <= d2:
            centre = hi if i - 1 == samples else lo + step * (i - 1)
            uu, dd = _newton_project(U, B, p, n, q, centre, max(lo, centre - step), min(hi, centre + step), work, CK)
            if dd < best:
                best = dd
                best_u = uu
        prev2 = prev1
        prev1 = d2
    return min(max(best_u, lo), hi), best


@njit(cache=True, inline="always")
def _box_distance2(boxes, i, q):
    """Squared distance from q to the bounding box of the Cartesian control points of span i."""
    total = 0.0
    for c in range(q.shape[0]):
        lo = boxes[i, c, 0]
        hi = boxes[i, c, 1]
        if q[c] < lo:
            total += (lo - q[c]) ** 2
        elif q[c] > hi:
            total += (q[c] - hi) ** 2
    return total


# Bounded global search on a parameter window.  The squared distance from q to a rational
# Bezier piece is |D(u)|^2 / w(u)^2 with D = A - q w (A the homogeneous numerator, w the
# weight): D is a Bezier of degree p with control points D_j = A_j - q w_j, so
#     g(u) = |D(u)|^2 - d^2 w(u)^2
# is a polynomial of degree 2p whose Bernstein coefficients are products of the piece's
# control points.  w > 0, so the piece holds a point closer than d exactly where g < 0, and
# if every Bernstein coefficient of g is >= 0 it holds none (the coefficients bound the
# polynomial).  Splitting at the foot found makes both halves start at a double root of g,
# where the test passes; pieces that still fail are halved, down to BB_DEPTH.  The test
# allows BB_ATOL: near a point of tiny parametric speed (the butterfly's tight turns) g is
# flat to rounding over a stretch of u, and without it the whole stretch goes to BB_DEPTH.
BB_DEPTH = 16  # halvings of a span piece before Newton settles what is left
BB_RTOL = 1e-13  # slack of the test, relative to the piece's |D_j|^2 (rounding of the products)
BB_ATOL = 1e-9  # mm: a piece that cannot hold a point nearer than d - BB_ATOL is dropped


@njit(cache=True)
def make_search(B, p):
    """Scratch for :func:`project_interval`: a stack of pieces, the product weights of g, and the
    bounding box of every span's Cartesian control points (``boxes[i, c] = (min, max)``), built
    here once so that the per-tick search only reads it."""
    dimh = B.shape[3]
    size = 2 * BB_DEPTH + 4
    fac = np.empty((p + 1, p + 1))
    for i in range(p + 1):
        for j in range(p + 1):
            fac[i, j] = _binom(p, i) * _binom(p, j) / _binom(2 * p, i + j)
    boxes = np.empty((B.shape[0], dimh - 1, 2))
    for i in range(B.shape[0]):
        for c in range(dimh - 1):
            if B[i, 0, 0, dimh - 1] == 0.0:  # the zero rows of an empty span (never searched)
                boxes[i, c, 0] = boxes[i, c, 1] = 0.0
                continue
            lo = math.inf
            hi = -math.inf
            for j in range(p + 1):
                x = B[i, 0, j, c] / B[i, 0, j, dimh - 1]
                lo = min(lo, x)
                hi = max(hi, x)
            boxes[i, c, 0] = lo
            boxes[i, c, 1] = hi
    return (np.empty((size, p + 1, dimh)), np.empty(size), np.empty(size), np.empty(size, dtype=np.int64),
            np.empty((p + 1, dimh)), np.empty(2 * p + 1), fac, boxes)


@njit(cache=True)
def _binom(n, k):
    r = 1.0
    for i in range(1, k + 1):
        r = r * (n - k + i) / i
    return r


@njit(cache=True, inline="always")
def _split_bezier(stack, si, t, left, di):
    """de Casteljau at t of the piece stack[si]: left (on [0, t]) -> *left*, right (on [t, 1]) ->
    stack[di] (di may be si).  Scalar loops on the buffers: no views, no temporaries."""
    p = stack.shape[1] - 1
    dimh = stack.shape[2]
    if di != si:
        for j in range(p + 1):
            for c in range(dimh):
                stack[di, j, c] = stack[si, j, c]
    s = 1.0 - t
    for j in range(p + 1):
        for c in range(dimh):
            left[j, c] = stack[di, 0, c]
        for k in range(p - j):
            for c in range(dimh):
                stack[di, k, c] = s * stack[di, k, c] + t * stack[di, k + 1, c]
    for c in range(dimh):
        left[p, c] = stack[di, 0, c]


@njit(cache=True, inline="always")
def _set_piece(stack, di, src):
    """stack[di] = src (a (p + 1, dimh) array), by scalar loops."""
    for j in range(src.shape[0]):
        for c in range(src.shape[1]):
            stack[di, j, c] = src[j, c]


@njit(cache=True, inline="always")
def _may_be_closer(stack, top, q, d2, fac, g):
    """False when no point of the rational Bezier stack[top] is closer to q than sqrt(d2) - BB_ATOL (see above)."""
    p = stack.shape[1] - 1
    dim = q.shape[0]
    for k in range(2 * p + 1):
        g[k] = 0.0
    scale = 0.0
    wmin = math.inf
    for i in range(p + 1):
        wi = stack[top, i, dim]
        wmin = min(wmin, wi)
        for j in range(i, p + 1):
            wj = stack[top, j, dim]
            dot = 0.0
            for c in range(dim):
                dot += (stack[top, i, c] - q[c] * wi) * (stack[top, j, c] - q[c] * wj)
            term = (dot - d2 * wi * wj) * fac[i, j]
            g[i + j] += term if i == j else 2.0 * term
            if i == j:
                scale = max(scale, dot + d2 * wi * wi)
    # g >= -tol holds |C - q| >= d - BB_ATOL (w >= wmin on the piece, by the hull property)
    d = math.sqrt(d2)
    tol = -max(BB_RTOL * scale, (d2 - max(d - BB_ATOL, 0.0) ** 2) * wmin * wmin)
    for k in range(2 * p + 1):
        if g[k] < tol:
            return True
    return False


@njit(cache=True)
def project_interval(U, B, p, n, q, lo, hi, best_u, best, work, CK, search, whole_first=False):
    """Closest point to q on C([lo, hi]) given a candidate (best_u, best = its squared distance).

    Global on the interval: every span piece of [lo, hi] is either shown to hold no
    closer point (a box of its control points, then the Bernstein test of g) or split —
    at the best foot if it lies inside, else in halves — and after BB_DEPTH halvings
    settled by bracketed Newton.  A good candidate (the previous tick's foot) lets most
    pieces go at the first test.  Returns the improved (u, squared distance).

    ``whole_first``: first test each span whole (split at the best foot when it lies in it,
    whose halves then start at a double root of g) before cutting out its part of [lo, hi]:
    the whole span holds that part, so when its pieces pass, so would the part.  Most spans
    of a short window go this way, at one split instead of three; the others are searched
    as without it.
    """
    stack, t0s, t1s, depths, left, g, fac, boxes = search
    if best <= 0.0:  # nothing is nearer than the candidate
        return best_u, best
    if not hi > lo:
        if hi == lo:
            curve_ders(U, B, p, lo, find_span(U, n, p, lo), 0, work, CK)
            d2 = _distance2(CK, q)
            if d2 < best:
                return lo, d2
        return best_u, best
    i = find_span(U, n, p, lo)
    first = i
    while i <= n:
        h = U[i + 1] - U[i]
        if i > first and U[i] >= hi:
            break
        if not h > 0 or _box_distance2(boxes, i, q) >= best:
            i += 1
            continue
        if whole_first:
            _set_piece(stack, 0, B[i, 0])
            tf = (best_u - U[i]) / h
            if 0.0 < tf < 1.0:
                _split_bezier(stack, 0, tf, left, 1)
                _set_piece(stack, 0, left)
                passed = not _may_be_closer(stack, 1, q, best, fac, g) and not _may_be_closer(stack, 0, q, best, fac, g)
            else:
                passed = not _may_be_closer(stack, 0, q, best, fac, g)
            if passed:
                i += 1
                continue
        # the piece [lo, hi] ∩ span i, in the span's local parameter
        a = max(0.0, (lo - U[i]) / h)
        b = min(1.0, (hi - U[i]) / h)
        top = 0
        _set_piece(stack, 0, B[i, 0])
        if b < 1.0:
            _split_bezier(stack, 0, b, left, 1)
            _set_piece(stack, 0, left)
        if a > 0.0:
            _split_bezier(stack, 0, a / b, left, 0)
        t0s[0] = a
        t1s[0] = b
        depths[0] = 0
        while top >= 0:
            t0 = t0s[top]
            t1 = t1s[top]
            depth = depths[top]
            u0 = U[i] + t0 * h
            u1 = U[i + 1] if t1 == 1.0 else U[i] + t1 * h
            if not _may_be_closer(stack, top, q, best, fac, g):
                top -= 1
                continue
            if depth >= BB_DEPTH or not u1 > u0:
                top -= 1
                u, d2 = _newton_project(U, B, p, n, q, 0.5 * (u0 + u1), u0, u1, work, CK)
                if d2 < best:
                    best = d2
                    best_u = u
                continue
            # split at the best foot when it is inside the piece (both halves then start at a
            # double root of g), else in the middle
            tm = 0.5
            if u0 < best_u < u1:
                tm = (best_u - u0) / (u1 - u0)
                if not 1e-3 < tm < 1.0 - 1e-3:
                    tm = 0.5
            # left half replaces the piece; the right half goes on top, to be tested first
            _split_bezier(stack, top, tm, left, top + 1)
            _set_piece(stack, top, left)
            mid = t0 + tm * (t1 - t0)
            t1s[top] = mid
            depths[top] = depth + 1
            top += 1
            t0s[top] = mid
            t1s[top] = t1
            depths[top] = depth + 1
        i += 1
    return best_u, best


@njit(cache=True)
def project_global(U, B, p, n, q, samples, work, CK):
    """Closest point to q on the whole curve.

    A first answer comes from sampling every span and Newton from each sampled
    local minimum; :func:`project_interval` over the whole domain then shows
    that no other piece holds a closer point, or finds it.
    """
    best_u = U[p]
    best = math.inf
    for i in range(p, n + 1):
        if U[i + 1] > U[i]:
            u, d2 = project_window(U, B, p, n, q, U[i], U[i + 1], samples, work, CK)
            if d2 < best:
                best = d2
                best_u = u
    best_u, best = project_interval(U, B, p, n, q, U[p], U[n + 1], best_u, best, work, CK,
                                    make_search(B, p))
    return min(max(best_u, U[p]), U[n + 1]), best


@njit(cache=True)
def _window_end(U, B, p, starts, spans, cum, s, upper, exact, work, CK):
    """The parameter of arc length s (0 <= s <= L): exact, or the end of the panel holding it
    (below s for a lower end, above for an upper one: a window that holds the exact one)."""
    if exact:
        return parameter_at(U, B, p, starts, spans, cum, s, -math.inf, work, CK)
    last = starts.shape[0] - 1
    if upper:
        return starts[min(np.searchsorted(cum, s, side="left"), last)]
    return starts[max(np.searchsorted(cum, s, side="right") - 1, 0)]


@njit(cache=True)
def project_arc_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, exact, start,
                   best_u, best, work, CK, search):
    """Closest point to q on the arc-length window [s_lo, s_hi] (wrapped on a closed curve,
    clipped to [0, L] on an open one), from the candidate (best_u, best) inside it: Newton
    from *start*, then the bounded global search of each interval.  With exact=False the
    window is widened to panel ends (no inverse arc length needed)."""
    length = cum[cum.shape[0] - 1]
    a = U[p]
    b = U[n + 1]
    lo1 = hi1 = lo2 = hi2 = 0.0
    two = False
    if closed and s_hi - s_lo >= length:
        lo1, hi1 = a, b
    elif closed and s_lo < 0.0:
        lo1 = _window_end(U, B, p, starts, spans, cum, s_lo + length, False, exact, work, CK)
        hi1 = b
        lo2 = a
        hi2 = _window_end(U, B, p, starts, spans, cum, s_hi, True, exact, work, CK)
        two = True
    elif closed and s_hi > length:
        lo1 = _window_end(U, B, p, starts, spans, cum, s_lo, False, exact, work, CK)
        hi1 = b
        lo2 = a
        hi2 = _window_end(U, B, p, starts, spans, cum, s_hi - length, True, exact, work, CK)
        two = True
    else:
        lo1 = _window_end(U, B, p, starts, spans, cum, max(s_lo, 0.0), False, exact, work, CK)
        hi1 = _window_end(U, B, p, starts, spans, cum, min(s_hi, length), True, exact, work, CK)
    if lo1 <= start <= hi1 or (two and lo2 <= start <= hi2):
        lo, hi = (lo1, hi1) if lo1 <= start <= hi1 else (lo2, hi2)
        u, d2 = _newton_project_fast(U, B, p, n, q, start, lo, hi, search[4], CK)
        if d2 < best:
            best_u, best = u, d2
    best_u, best = project_interval(U, B, p, n, q, lo1, hi1, best_u, best, work, CK, search, True)
    if two:
        best_u, best = project_interval(U, B, p, n, q, lo2, hi2, best_u, best, work, CK, search, True)
    return best_u, best


# The certificate that spares the window search (contour.py's common case).  Along the curve in
# arc length s, the squared distance f(s) = |C(s) - q|^2 has f'' = 2 (1 + κ N·(C - q)) >= 2 (1 - κ |C - q|),
# and on a window of length ℓ holding the foot s* (distance d) |C(s) - q| <= d + ℓ.  So where
# κ (d + ℓ) < 1 all along the window, f is strictly convex there and a stationary point Newton found
# is the nearest point of the whole window: no other branch can come closer.  κ comes from a bound
# per panel of the arc-length table (below), computed on first use.  A panel joint where the tangent
# turns by θ (a corner) breaks the convexity; rotating the far side about the joint straightens it and
# moves no point by more than θ ℓ, so joints are allowed while their turns sum to θ ℓ <= BB_ATOL, the
# global search's own tolerance (joints inside a span, and G1 knots such as the circle's, turn by 0).
CONVEX_LIMIT = 0.5  # κ (d + ℓ) at most this (< 1): convex with room to spare for the bound's rounding


@njit(cache=True)
def make_certificate(B, p, panels):
    """The tables of :func:`window_bounds` -- per panel the curvature bound and the turn of the
    tangent at its start, NaN until :func:`fill_certificate` computes them -- and its scratch."""
    dimh = B.shape[3]
    return (np.full(panels, np.nan), np.full(panels, np.nan), np.empty((p + 1, dimh)), np.empty((p + 1, dimh)),
            np.empty((2 * p, dimh - 1)), np.empty((3 * p - 1, dimh - 1)))


@njit(cache=True)
def _bezier_split(Q, t, keep_left, tmp):
    """Q (a Bezier piece, (p + 1, dimh)) := its part on [0, t] (keep_left) or [t, 1], by de Casteljau."""
    m = Q.shape[0]
    for j in range(m):
        for c in range(Q.shape[1]):
            tmp[j, c] = Q[j, c]
    s = 1.0 - t
    for r in range(m):  # level r: Q[r] (left) and Q[m - 1 - r] (right) are the ends of the level
        for c in range(Q.shape[1]):
            if keep_left:
                Q[r, c] = tmp[0, c]
            else:
                Q[m - 1 - r, c] = tmp[m - 1 - r, c]
        for j in range(m - 1 - r):
            for c in range(Q.shape[1]):
                tmp[j, c] = s * tmp[j, c] + t * tmp[j + 1, c]


@njit(cache=True)
def curvature_bound(Q, N1, N2):
    """An upper bound of the curvature of the rational Bezier piece Q ((p + 1, dimh), homogeneous), 1/mm;
    inf where the bound cannot show the speed is non-zero (split the piece and try again).

    With A the numerator and w the weight, C' = N1 / w² and C'' = N2 / w³ (derivatives in the piece's
    own parameter; curvature does not depend on it), N1 = A'w - Aw' and N2 = N1'w - 2 N1 w' being
    polynomials whose Bernstein coefficients are sums of products of Q's (scratch N1: (2p, dim),
    N2: (3p - 1, dim)).  κ <= |C''| / |C'|² = |N2| w / |N1|², and on the piece |N2| and w are at most
    their largest coefficient (convex hull), while |N1| >= e·N1 >= min_k e·N1_k for a unit vector e
    (the coefficients' mean direction).
    """
    p = Q.shape[0] - 1
    dim = Q.shape[1] - 1
    N1[:] = 0.0
    N2[:] = 0.0
    for i in range(p):  # A' and w' have degree p - 1, A and w degree p: N1 has degree 2p - 1
        for j in range(p + 1):
            f = p * _binom(p - 1, i) * _binom(p, j) / _binom(2 * p - 1, i + j)
            dw = Q[i + 1, dim] - Q[i, dim]
            for c in range(dim):
                N1[i + j, c] += f * ((Q[i + 1, c] - Q[i, c]) * Q[j, dim] - dw * Q[j, c])
    top = 3 * p - 2  # N1' w and N1 w' have degree 3p - 2
    for i in range(2 * p - 1):
        for j in range(p + 1):
            f = (2 * p - 1) * _binom(2 * p - 2, i) * _binom(p, j) / _binom(top, i + j)
            for c in range(dim):
                N2[i + j, c] += f * (N1[i + 1, c] - N1[i, c]) * Q[j, dim]
    for i in range(2 * p):
        for j in range(p):
            f = 2.0 * p * _binom(2 * p - 1, i) * _binom(p - 1, j) / _binom(top, i + j)
            dw = Q[j + 1, dim] - Q[j, dim]
            for c in range(dim):
                N2[i + j, c] -= f * N1[i, c] * dw
    e = np.zeros(dim)  # the coefficients' mean direction
    for k in range(2 * p):
        for c in range(dim):
            e[c] += N1[k, c]
    mean = 0.0
    for c in range(dim):
        mean += e[c] * e[c]
    mean = math.sqrt(mean)
    if not mean > 0.0:
        return math.inf
    low = math.inf
    for k in range(2 * p):
        along = 0.0
        for c in range(dim):
            along += N1[k, c] * e[c]
        low = min(low, along / mean)
    if not low > 0.0:
        return math.inf
    high = 0.0
    for k in range(top + 1):
        high = max(high, norm_row(N2, k))
    wmax = 0.0
    for j in range(p + 1):
        wmax = max(wmax, Q[j, dim])
    return high * wmax / (low * low)


CURVATURE_SPLITS = 3  # a panel's bound is the largest of its 2^3 pieces' (tighter than the whole panel's)
CURVATURE_DEPTH = 10  # a piece whose bound fails (its hull reaches speed 0) is halved down to this depth, then inf


@njit(cache=True)
def panel_curvature(U, B, p, starts, spans, k, cert):
    """The curvature bound of panel k (1/mm): the largest :func:`curvature_bound` of its pieces."""
    _kappa, _turn, Q, tmp, N1, N2 = cert
    span = spans[k]
    h = U[span + 1] - U[span]
    t0 = (starts[k] - U[span]) / h
    t1 = (starts[k + 1] - U[span]) / h
    size = (1 << CURVATURE_SPLITS) + CURVATURE_DEPTH + 1
    lo = np.empty(size)
    hi = np.empty(size)
    depth = np.empty(size, dtype=np.int64)
    top = -1
    pieces = 1 << CURVATURE_SPLITS
    for j in range(pieces - 1, -1, -1):  # the first piece on top
        top += 1
        lo[top] = t0 + (t1 - t0) * j / pieces
        hi[top] = t0 + (t1 - t0) * (j + 1) / pieces
        depth[top] = CURVATURE_SPLITS
    worst = 0.0
    while top >= 0:
        a, b, level = lo[top], hi[top], depth[top]
        top -= 1
        for r in range(p + 1):
            for c in range(B.shape[3]):
                Q[r, c] = B[span, 0, r, c]
        if b < 1.0:
            _bezier_split(Q, b, True, tmp)
        if a > 0.0:
            _bezier_split(Q, a / b, False, tmp)
        bound = curvature_bound(Q, N1, N2)
        if bound < math.inf or level >= CURVATURE_DEPTH:
            worst = max(worst, bound)
            if worst == math.inf:
                break
            continue
        m = 0.5 * (a + b)
        lo[top + 1], hi[top + 1], depth[top + 1] = m, b, level + 1
        lo[top + 2], hi[top + 2], depth[top + 2] = a, m, level + 1
        top += 2
    return worst


@njit(cache=True)
def _unit_tangent(U, B, p, u, span, work, CK, out):
    curve_ders(U, B, p, u, span, 1, work, CK)
    speed = norm_row(CK, 1)
    for c in range(out.shape[0]):
        out[c] = CK[1, c] / speed if speed > 0.0 else math.nan
    return speed > 0.0


@njit(cache=True)
def joint_turn(U, B, p, starts, spans, k, closed, work, CK):
    """The angle (rad) the tangent turns by at the start of panel k: 0 inside a span; at a knot the
    angle between its two one-sided tangents (π where either is zero); at the start of a closed curve
    the turn across its seam (0 on an open one, whose windows never cross it)."""
    last = spans.shape[0] - 1
    if k > 0 and spans[k] == spans[k - 1]:
        return 0.0
    if k == 0 and not closed:
        return 0.0
    dim = B.shape[3] - 1
    before = np.empty(dim)
    after = np.empty(dim)
    if k == 0:
        ok = _unit_tangent(U, B, p, starts[last + 1], spans[last], work, CK, before)
    else:
        ok = _unit_tangent(U, B, p, starts[k], spans[k - 1], work, CK, before)
    ok = _unit_tangent(U, B, p, starts[k], spans[k], work, CK, after) and ok
    if not ok:
        return math.pi
    chord = 0.0
    for c in range(dim):
        chord += (after[c] - before[c]) ** 2
    return 2.0 * math.asin(min(1.0, 0.5 * math.sqrt(chord)))


@njit(cache=True, inline="always")
def panel_at(starts, u, k):
    """The panel holding parameter u (starts[k] <= u < starts[k + 1]; the domain end in the last),
    walking from the hint k: its span (spans[k]) is find_span's."""
    last = starts.shape[0] - 2
    k = min(max(k, 0), last)
    while k < last and u >= starts[k + 1]:
        k += 1
    while k > 0 and u < starts[k]:
        k -= 1
    return k


@njit(cache=True)
def fill_certificate(U, B, p, starts, spans, k, closed, cert, work, CK):
    """Compute panel k's entries of the certificate's tables (see :func:`make_certificate`)."""
    cert[0][k] = panel_curvature(U, B, p, starts, spans, k, cert)
    cert[1][k] = joint_turn(U, B, p, starts, spans, k, closed, work, CK)


@njit(cache=True, inline="always")
def window_bounds(kappa, turn, wrapped, k_lo, k_hi):
    """(largest curvature bound, sum of the joint turns, -1) over a window's panels k_lo to k_hi - 1
    (wrapped: k_lo to the last, then 0 to k_hi - 1, across a closed curve's seam; see
    :func:`panel_window`); (nan, nan, k) where panel k's entries of the tables are missing:
    :func:`fill_certificate` them and ask again.

    Plain arrays only: it runs at every tick, where numba's handling of a tuple argument would
    cost more than the work.
    """
    last = kappa.shape[0] - 1
    worst = 0.0
    turned = 0.0
    for run in range(2 if wrapped else 1):
        k0 = min(k_lo, last) if run == 0 else 0
        k1 = (last if wrapped else max(k_hi - 1, k0)) if run == 0 else k_hi - 1
        for k in range(k0, min(k1, last) + 1):
            if kappa[k] != kappa[k] or turn[k] != turn[k]:
                return math.nan, math.nan, k
            worst = max(worst, kappa[k])
            if k > k0:
                turned += turn[k]
    if wrapped:
        turned += turn[0]  # the seam's turn (panel 0's entry)
    return worst, turned, -1


@njit(cache=True, inline="always")
def is_convex(worst, turned, ell, d):
    """The certificate (see above): whether the squared distance is convex along a window of arc
    length ell, whose panels' curvature bound is *worst* and whose joints turn by *turned* in all,
    for a point at distance d from a foot inside it; then a stationary point is its nearest."""
    return worst * (d + ell) <= CONVEX_LIMIT and turned * ell <= BB_ATOL


@njit(cache=True, inline="always")
def panel_window(starts, cum, closed, s_lo, s_hi, hint):
    """The window [s_lo, s_hi] widened to panel ends as :func:`project_arc_window` (exact=False)
    takes it -- the same ends -- by walking from the *hint* panel instead of bisecting the table.

    (lo1, hi1, lo2, hi2, wrapped, k_lo, k_hi): the interval [lo1, hi1], and [lo2, hi2] where a
    closed curve's window wraps across the seam; its panels k_lo to k_hi - 1 (wrapped: k_lo to the
    last, then 0 to k_hi - 1).  A closed curve's window as long as the curve is the whole domain
    with k_lo = -1.
    """
    length = cum[cum.shape[0] - 1]
    a = starts[0]
    b = starts[starts.shape[0] - 1]
    if closed and s_hi - s_lo >= length:
        return a, b, 0.0, 0.0, False, -1, 0
    if closed and s_lo < 0.0:
        lo = _lower_panel_end(cum, s_lo + length, hint)
        hi = _upper_panel_end(cum, s_hi, 0)
        return starts[lo], b, a, starts[hi], True, lo, hi
    if closed and s_hi > length:
        lo = _lower_panel_end(cum, s_lo, hint)
        hi = _upper_panel_end(cum, s_hi - length, 0)
        return starts[lo], b, a, starts[hi], True, lo, hi
    lo = _lower_panel_end(cum, max(s_lo, 0.0), hint)
    hi = _upper_panel_end(cum, min(s_hi, length), lo)
    return starts[lo], starts[hi], 0.0, 0.0, False, lo, hi


@njit(cache=True, inline="always")
def _lower_panel_end(cum, s, k):
    """max(searchsorted(cum, s, "right") - 1, 0), walking from k."""
    last = cum.shape[0] - 1
    k = min(max(k, 0), last)
    while k < last and cum[k + 1] <= s:
        k += 1
    while k > 0 and cum[k] > s:
        k -= 1
    return k


@njit(cache=True, inline="always")
def _upper_panel_end(cum, s, k):
    """min(searchsorted(cum, s, "left"), len(cum) - 1), walking from k."""
    last = cum.shape[0] - 1
    k = min(max(k, 0), last)
    while k > 0 and cum[k - 1] >= s:
        k -= 1
    while k < last and cum[k] < s:
        k += 1
    return k


@njit(cache=True)
def project_seeded(U, B, p, n, q, seed, work, CK):
    """Closest point to q near parameter *seed* (the commanded u of a servo tick).

    Newton starts at the seed inside a bracket a few times wider than the
    seed's distance to q (in parameter units, through the local speed); a
    result worse than the seed, or no convergence, falls back to a sampled
    search of that bracket, so it cannot wander to a far branch of the curve.
    """
    a = U[p]
    b = U[n + 1]
    span = find_span(U, n, p, seed)
    curve_ders(U, B, p, seed, span, 2, work, CK)
    # compare squares as computed: sqrt(d2)² can exceed d2 by an ulp and send an
    # exact answer to the sampled fallback
    d2_seed = _distance2(CK, q)
    d_seed = math.sqrt(d2_seed)
    sp = norm_row(CK, 1)
    width = (b - a) * 1e-9
    if sp > 0.0:
        width = max(width, 4.0 * d_seed / sp)
    else:
        width = max(width, (b - a) * 1e-3)
    lo = max(a, seed - width)
    hi = min(b, seed + width)
    u, d2 = _newton_project(U, B, p, n, q, seed, lo, hi, work, CK, True)
    if d2 <= d2_seed:
        return min(max(u, lo), hi), d2
    return project_window(U, B, p, n, q, lo, hi, 32, work, CK)


# --------------------------------------------------------------------------- vectorised loops


@njit(cache=True)
def eval_many(U, B, p, n, us, nd, out):
    """out[i, k, :] = k-th derivative at us[i], k = 0..nd."""
    dimh = B.shape[3]
    work = make_work(p, nd, dimh)
    CK = np.empty((nd + 1, dimh - 1))
    span = p
    for i in range(us.shape[0]):
        span = find_span_from(U, n, p, us[i], span)
        curve_ders(U, B, p, us[i], span, nd, work, CK)
        out[i] = CK


@njit(cache=True)
def eval_in_span(U, B, p, us, spans, nd, out):
    """Like eval_many but with the span of each point given (for left limits at knots)."""
    dimh = B.shape[3]
    work = make_work(p, nd, dimh)
    CK = np.empty((nd + 1, dimh - 1))
    for i in range(us.shape[0]):
        curve_ders(U, B, p, us[i], spans[i], nd, work, CK)
        out[i] = CK


@njit(cache=True)
def arc_length_many(U, B, p, starts, spans, cum, us, out):
    dimh = B.shape[3]
    work = make_work(p, 1, dimh)
    CK = np.empty((2, dimh - 1))
    for i in range(us.shape[0]):
        out[i] = arc_length_to(U, B, p, starts, spans, cum, us[i], work, CK)


@njit(cache=True)
def parameter_at_many(U, B, p, starts, spans, cum, ss, out):
    dimh = B.shape[3]
    work = make_work(p, 1, dimh)
    CK = np.empty((2, dimh - 1))
    for i in range(ss.shape[0]):
        out[i] = parameter_at(U, B, p, starts, spans, cum, ss[i], -math.inf, work, CK)


@njit(cache=True)
def project_many(U, B, p, n, qs, seeds, use_seeds, samples, out_u, out_d):
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    for i in range(qs.shape[0]):
        if use_seeds:
            u, d2 = project_seeded(U, B, p, n, qs[i], seeds[i], work, CK)
        else:
            u, d2 = project_global(U, B, p, n, qs[i], samples, work, CK)
        out_u[i] = u
        out_d[i] = math.sqrt(d2)


# --------------------------------------------------------------------------- the curve object


def _as_params(u):
    arr = np.asarray(u, dtype=float)
    return arr, arr.ndim == 0


class NurbsCurve:
    """A NURBS curve of degree p in 2-D or 3-D.

    Parameters
    ----------
    degree : int, p >= 1 (order = p + 1, the paper's k)
    control_points : array (n+1, dim), mm, dim 2 or 3
    weights : array (n+1,), > 0; default all 1
    knots : array (n+p+2,), non-decreasing, clamped; default clamped uniform on [0, 1]

    The constructor validates with the same rules and messages as job files;
    :meth:`from_spec` takes an already validated :class:`~nurbsinterp.config.CurveSpec`.

    Shape contract: a parameter array of shape (N,) gives points of shape
    (N, dim); a scalar gives (dim,).

    Examples
    --------
    >>> c = NurbsCurve(2, [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]],
    ...                [1, .5, .5, 1, .5, .5, 1], [0, 0, 0, .25, .5, .5, .75, 1, 1, 1])
    >>> round(c.length, 9)
    314.159265359
    """

    def __init__(self, degree, control_points, weights=None, knots=None):
        from .config import Where, validate_curve

        def plain(value):  # lists as they are, so that validation names what is wrong in them
            return value.tolist() if isinstance(value, np.ndarray) else (list(value) if isinstance(value, tuple) else value)

        raw = {"degree": degree, "control_points": [plain(cp) for cp in plain(control_points)]
               if isinstance(plain(control_points), list) else control_points}
        if weights is not None:
            raw["weights"] = plain(weights)
        if knots is not None:
            raw["knots"] = plain(knots)
        spec = validate_curve(raw, Where("NurbsCurve"))
        self._init(spec.degree, spec.control_points, spec.weights, spec.knots)

    @classmethod
    def from_spec(cls, spec) -> "NurbsCurve":
        obj = cls.__new__(cls)
        obj._init(spec.degree, spec.control_points, spec.weights, spec.knots)
        return obj

    def _init(self, degree, control_points, weights, knots):
        cps = np.array(control_points, dtype=float)
        w = np.array(weights, dtype=float)
        self.degree = int(degree)
        self.knots = np.array(knots, dtype=float)
        self.control_points = cps
        self.weights = w
        self.Pw = np.ascontiguousarray(np.column_stack([cps * w[:, None], w]))
        self.n = cps.shape[0] - 1
        self.bezier = bezier_table(self.knots, self.Pw, self.degree, self.n)
        for arr in (self.knots, self.control_points, self.weights, self.Pw, self.bezier):
            arr.setflags(write=False)

    # -- basic facts
    @property
    def dim(self) -> int:
        return self.control_points.shape[1]

    @property
    def domain(self) -> tuple[float, float]:
        return float(self.knots[self.degree]), float(self.knots[self.n + 1])

    @property
    def kernel_args(self):
        """(U, B, p, n): the plain-array form every kernel takes (B: the Bezier table, see :func:`bezier_table`)."""
        return self.knots, self.bezier, self.degree, self.n

    def span_ranges(self):
        """[(span index, start, end)] of the non-empty knot spans."""
        U, p, n = self.knots, self.degree, self.n
        return [(i, float(U[i]), float(U[i + 1])) for i in range(p, n + 1) if U[i + 1] > U[i]]

    # -- evaluation
    def derivatives(self, u, order: int = 1) -> np.ndarray:
        """Point and derivatives up to *order*: shape (N, order+1, dim), or (order+1, dim) for scalar u."""
        if not 0 <= order <= MAX_DERIVATIVE:
            raise ValueError(f"derivative order {order} is not supported (0 .. {MAX_DERIVATIVE})")
        arr, scalar = _as_params(u)
        flat = np.ascontiguousarray(arr.reshape(-1))
        self._check_domain(flat)
        out = np.empty((flat.shape[0], order + 1, self.dim))
        eval_many(*self.kernel_args, flat, order, out)
        return out[0] if scalar else out.reshape(arr.shape + (order + 1, self.dim))

    def evaluate(self, u) -> np.ndarray:
        """Points C(u): (N, dim) for u of shape (N,), (dim,) for a scalar."""
        d = self.derivatives(u, 0)
        return d[..., 0, :]

    __call__ = evaluate

    def _check_domain(self, flat):
        a, b = self.domain
        if flat.size and not (np.all(flat >= a) and np.all(flat <= b)):
            bad = flat[~((flat >= a) & (flat <= b))][0]
            raise ValueError(f"parameter u = {bad!r} is outside the domain [{a!r}, {b!r}]")

    def speed(self, u) -> np.ndarray:
        """Parametric speed |C'(u)|, mm per unit of u."""
        return np.linalg.norm(self.derivatives(u, 1)[..., 1, :], axis=-1)

    def curvature(self, u) -> np.ndarray:
        """Curvature (1/mm); inf where the parametric speed is zero."""
        d = self.derivatives(u, 2)
        return _curvature_table(d.reshape(-1, 3, self.dim), self.dim).reshape(d.shape[:-2]) if d.ndim > 2 \
            else float(_curvature_table(d[None], self.dim)[0])

    # -- arc length
    @cached_property
    def _panel_build(self):
        """(starts, spans, cum, status, floor): :func:`build_panels` as it returned, unchecked (see :attr:`panels`)."""
        # rounding in the control points leaves about p eps |P| (times the weight ratio) of noise
        # in each panel's length; below that the test could never pass (a rational curve shrunk
        # to one point has a length of pure noise, and would be bisected 2^40 times)
        floor = 4.0 * self.degree * np.finfo(float).eps * float(np.abs(self.control_points).max()) \
            * float(self.weights.max() / self.weights.min())
        return (*build_panels(*self.kernel_args, ARC_RTOL, floor, MAX_PANEL_DEPTH, MAX_PANELS), floor)

    @cached_property
    def length_noise(self) -> float:
        """The rounding noise of :attr:`length` (mm): the panels' floor times their number."""
        _starts, spans, _cum, _status, floor = self._panel_build
        return floor * max(1, spans.shape[0])

    @cached_property
    def panels(self):
        """(starts, spans, cum): the arc-length table (see :func:`build_panels`)."""
        starts, spans, cum, status, _floor = self._panel_build
        if status == PANELS_NOT_FINITE:
            raise SpecError(f"curve: the parametric speed overflows near u = {starts[0]!r} (coordinates, weights "
                            "or knot spans too extreme); the arc length cannot be computed")
        if status == PANELS_TOO_MANY:
            raise SpecError(f"curve: the arc length needs more than {MAX_PANELS} Gauss panels to converge (near "
                            f"u = {starts[0]!r}): the speed varies too wildly (extreme weights or knot spans)")
        for arr in (starts, spans, cum):
            arr.setflags(write=False)
        return starts, spans, cum

    @property
    def length(self) -> float:
        """Total arc length, mm."""
        return float(self.panels[2][-1])

    @property
    def resolvable(self) -> bool:
        """Whether the length stands above the rounding noise of the control points (:attr:`length_noise`, mm)."""
        return self.length > self.length_noise

    def arc_length_at(self, u) -> np.ndarray:
        """s(u): arc length from the domain start to u, mm."""
        arr, scalar = _as_params(u)
        flat = np.ascontiguousarray(arr.reshape(-1))
        self._check_domain(flat)
        out = np.empty(flat.shape[0])
        arc_length_many(self.knots, self.bezier, self.degree, *self.panels, flat, out)
        return float(out[0]) if scalar else out.reshape(arr.shape)

    def arc_length(self, u0=None, u1=None):
        """Arc length from u0 to u1 (default: the whole domain), mm."""
        a, b = self.domain
        return self.arc_length_at(b if u1 is None else u1) - self.arc_length_at(a if u0 is None else u0)

    def parameter_at(self, s) -> np.ndarray:
        """The inverse of :meth:`arc_length_at`: u with s(u) = s (s clamped to [0, L])."""
        arr, scalar = _as_params(s)
        flat = np.ascontiguousarray(arr.reshape(-1))
        if not np.all(np.isfinite(flat)):
            raise ValueError("arc length must be finite")
        out = np.empty(flat.shape[0])
        parameter_at_many(self.knots, self.bezier, self.degree, *self.panels, flat, out)
        return float(out[0]) if scalar else out.reshape(arr.shape)

    # -- projection
    def closest_point(self, points, seeds=None, samples: int = 16):
        """Closest point on the curve: returns (u, distance).

        points : (N, dim) or (dim,).  seeds : optional (N,) parameters near the
        answer (e.g. the commanded u of each servo tick); without seeds every
        knot span is searched (*samples* per span, then Newton).
        """
        q = np.asarray(points, dtype=float)
        scalar = q.ndim == 1
        q2 = np.ascontiguousarray(q.reshape(-1, self.dim))
        if seeds is None:
            s = np.zeros(q2.shape[0])
        else:
            s = np.ascontiguousarray(np.broadcast_to(np.asarray(seeds, dtype=float), (q2.shape[0],)))
            a, b = self.domain
            s = np.clip(s, a, b)
        out_u = np.empty(q2.shape[0])
        out_d = np.empty(q2.shape[0])
        project_many(*self.kernel_args, q2, s, seeds is not None, samples, out_u, out_d)
        if scalar:
            return float(out_u[0]), float(out_d[0])
        return out_u, out_d

    # -- shape facts (one-time, for `info` and planning)
    def _in_span(self, us, spans, order):
        out = np.empty((us.shape[0], order + 1, self.dim))
        eval_in_span(self.knots, self.bezier, self.degree, np.ascontiguousarray(us), np.ascontiguousarray(spans), order, out)
        return out

    def _samples(self, per_span: int, order: int):
        """(span ranges, span index per sample, u per sample, derivative table) on a grid of
        per_span + 1 samples in every non-empty knot span, all spans at once."""
        ranges = np.array(self.span_ranges(), dtype=float).reshape(-1, 3)
        spans = np.repeat(ranges[:, :1].astype(np.int64), per_span + 1, axis=1)
        us = ranges[:, 1:2] + (ranges[:, 2:3] - ranges[:, 1:2]) * np.linspace(0.0, 1.0, per_span + 1)
        us[:, -1] = ranges[:, 2]
        return ranges, spans, us, self._in_span(us.ravel(), spans.ravel(), order)

    def _refine_extrema(self, func, samples, order: int, sign: float, hull=None):
        """Maxima of sign*func(d) per knot span: the samples, then golden section, all spans at once.

        *func* maps a derivative table (N, order + 1, dim) to values (N,); *samples*
        come from :meth:`_samples`.  Returns a list of (value, u) for every sampled
        local maximum (span ends included; inside a run of equal samples only its
        ends), refined within one sample either side.  *hull*: optional coordinate
        index; then only the spans whose Bezier control points reach beyond the
        largest sample are refined (a span lies in their convex hull), since the
        caller wants the largest value only.
        """
        ranges, spans, us, table = samples
        vals = sign * func(table)
        flat_u = us.ravel()
        # a straight line's curvature or a constant coordinate is one plateau: its inside holds no peak
        k, lo, hi = discrete_minima(-vals, spans.ravel(), finite=False)
        row = k // us.shape[1]
        best_v, best_u = vals[k], flat_u[k]
        fine = np.isfinite(best_v)
        if hull is not None and fine.any():
            bz = self.bezier[ranges[:, 0].astype(np.int64), 0]  # (spans, p + 1, dim + 1), homogeneous
            reach = (sign * bz[:, :, hull] / bz[:, :, -1]).max(axis=1)
            fine &= reach[row] > best_v[fine].max()
        if fine.any():
            span = spans.ravel()[k[fine]]

            def neg(x):
                return -sign * func(self._in_span(x, span, order))

            u = golden_minimum(neg, flat_u[lo[fine]], flat_u[hi[fine]])
            v = -neg(u)
            better = v > best_v[fine]
            best_v[fine] = np.where(better, v, best_v[fine])
            best_u[fine] = np.where(better, u, best_u[fine])
        return [(sign * float(v), float(u)) for v, u in zip(best_v, best_u)]

    def curvature_maxima(self, per_span: int = 32):
        """Local curvature maxima per knot span as (curvature, u), span ends included.

        Sampling alone can miss a sharp peak between samples; each sampled local
        maximum is refined by golden section inside its bracket.
        """
        return self._refine_extrema(lambda d: _curvature_table(d, self.dim), self._samples(per_span, 2), 2, 1.0)

    def min_radius(self):
        """(minimum radius of curvature in mm, u where it occurs)."""
        kappa, u = max(self.curvature_maxima(), key=lambda t: t[0])
        return (1.0 / kappa if kappa > 0 else math.inf), u

    def bounding_box(self, per_span: int = 32):
        """(lower corner, upper corner) of the curve itself (not of its control polygon)."""
        samples = self._samples(per_span, 0)
        lo = np.empty(self.dim)
        hi = np.empty(self.dim)
        for c in range(self.dim):
            def coord(d, c=c):
                return d[:, 0, c]
            hi[c] = max(v for v, _ in self._refine_extrema(coord, samples, 0, 1.0, hull=c))
            lo[c] = min(v for v, _ in self._refine_extrema(coord, samples, 0, -1.0, hull=c))
        return lo, hi


GOLDEN_ITERATIONS = 60  # shrinks a bracket by 0.618^60 = 3e-13


_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@njit(cache=True)
def _golden_shrink(a, b, c, e, fc, fe, left, new):
    """One step of golden section on every bracket [a, b], as nurbs.golden_minimum takes it: keep the side of
    the smaller of f(c), f(e) (the left one on a tie), and the next point to try (into new)."""
    for i in range(a.shape[0]):
        keep_left = fc[i] <= fe[i]
        left[i] = keep_left
        if keep_left:
            b[i] = e[i]
            new[i] = b[i] - _GOLDEN * (b[i] - a[i])
        else:
            a[i] = c[i]
            new[i] = a[i] + _GOLDEN * (b[i] - a[i])


@njit(cache=True)
def _golden_keep(c, e, fc, fe, new, fn, left):
    """The two inner points after a step: the new one and the better of the old ones, in order."""
    for i in range(c.shape[0]):
        if left[i]:
            e[i] = c[i]
            fe[i] = fc[i]
            c[i] = new[i]
            fc[i] = fn[i]
        else:
            c[i] = e[i]
            fc[i] = fe[i]
            e[i] = new[i]
            fe[i] = fn[i]


def golden_minimum(f, lo, hi, iterations: int = GOLDEN_ITERATIONS):
    """Minimum of f (vectorised over the brackets [lo, hi]) by golden section.

    One call of f per iteration for all brackets at once, so thousands of
    brackets cost what one does in Python overhead; each step's updates are two
    kernels (the planner runs it on a few brackets per knot span).
    """
    a = np.array(lo, dtype=float)
    b = np.array(hi, dtype=float)
    c = b - _GOLDEN * (b - a)
    e = a + _GOLDEN * (b - a)
    fc = np.array(f(c), dtype=float)  # copies: the kernels update them in place
    fe = np.array(f(e), dtype=float)
    left = np.empty(a.shape, dtype=np.bool_)
    new = np.empty(a.shape)
    for _ in range(iterations):
        _golden_shrink(a, b, c, e, fc, fe, left, new)
        _golden_keep(c, e, fc, fe, new, np.ascontiguousarray(f(new), dtype=float), left)
    return np.where(fc <= fe, c, e)


def _curvature_table(d, dim):
    d1, d2 = d[:, 1, :], d[:, 2, :]
    if dim == 2:
        cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    else:
        cross = np.linalg.norm(np.cross(d1, d2), axis=-1)
    sp = np.linalg.norm(d1, axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(sp > 0, cross / np.where(sp > 0, sp, 1.0) ** 3, np.inf)
