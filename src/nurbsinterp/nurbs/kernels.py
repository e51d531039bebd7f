"""NURBS evaluation kernels: knot spans, the Bézier table of homogeneous control points, points and
derivatives (Piegl & Tiller A2.1, A4.2) at one parameter and over arrays of them.

Right-sided at knots (see the package's docstring); every routine works on plain arrays with a
preallocated workspace (``make_work``), so that the per-tick path allocates nothing.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit




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
def ders_fast_called(U, B, p, u, span, nd, tmp, CK):
    """ders_fast, called rather than inlined: for a caller's rare path (each inlined copy adds to the caller's
    compilation)."""
    ders_fast(U, B, p, u, span, nd, tmp, CK)


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
