"""Arc length of a NURBS curve: panels refined until a 10-point Gauss–Legendre rule is converged on each
(``build_panels``), the length to any parameter, a step's length, and the parameter at a length.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from .kernels import curve_ders, ders_fast, dot_rows, make_work, norm_row, speed_at


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
        # the middle node (exactly 0) first, then the outer two: the sum in the order it always took, with
        # one inlined copy of ders_fast rather than three (each copy adds to the kernel's compilation)
        s = 0.0
        for j in (1, 0, 2):
            ders_fast(U, B, p, mid + half * STEP_NODES[j], span, 1, tmp, CK)
            s += STEP_WEIGHTS[j] * norm_row(CK, 1)
        return s * half
    return (arc_length_to(U, B, p, starts, spans, cum, u1, work, CK)
            - arc_length_to(U, B, p, starts, spans, cum, u0, work, CK))


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
