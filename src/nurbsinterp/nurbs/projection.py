"""The nearest point of a NURBS curve: Newton feet, windowed and global projections certified by
Bézier bounds, the curvature and turn bounds that certify a window convex.  Used by the measures (contour
error, chord error, deviation), never by the interpolator's own stepping.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from .kernels import curve_ders, ders_fast, ders_fast_called, find_span, make_work, norm_row
from .arclength import parameter_at


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
            ders_fast_called(U, B, p, u, span, 0, tmp, CK)  # (once a search at most: called, not inlined)
            d2 = _distance2(CK, q)
            if d2 < best:
                best = d2
                best_u = u
            return best_u, best, (NEWTON_AT_END if at_end and best_u == u else NEWTON_FAILED), u, span
        u = nxt
    return best_u, best, NEWTON_FAILED, u, span


@njit(cache=True)
def newton_foot_called(U, B, p, n, q, u, lo, hi, span, iterations, tmp, CK):
    """newton_foot, called rather than inlined: for a caller's rare second Newton (a copy of the iteration
    inlined there would double that caller's compilation for a path few ticks take)."""
    return newton_foot(U, B, p, n, q, u, lo, hi, span, iterations, tmp, CK)


@njit(cache=True)
def _newton_project_fast(U, B, p, n, q, u, lo, hi, tmp, CK):
    """_newton_project on ders_fast (no derivatives handed in): the window search's Newton."""
    best_u, best, _how, _last, _span = newton_foot_called(U, B, p, n, q, u, lo, hi, find_span(U, n, p, u), 60, tmp,
                                                          CK)
    return best_u, best


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
            uu, dd = _newton_project(U, B, p, n, q, centre, max(lo, centre - step), min(hi, centre + step), work, CK,
                                     False)
            if dd < best:
                best = dd
                best_u = uu
        prev2 = prev1
        prev1 = d2
    return min(max(best_u, lo), hi), best


@njit(cache=True)  # not inlined: the global search is rare; inlined, it cost seconds of compilation
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


@njit(cache=True)  # not inlined: the global search is rare; inlined, it cost seconds of compilation
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


@njit(cache=True, inline="always")  # (a copy: inlined, one version serves the curve's read-only table and the stack)
def _set_piece(stack, di, src):
    """stack[di] = src (a (p + 1, dimh) array), by scalar loops."""
    for j in range(src.shape[0]):
        for c in range(src.shape[1]):
            stack[di, j, c] = src[j, c]


@njit(cache=True)  # not inlined: the global search is rare; inlined, it cost seconds of compilation
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
                u, d2 = _newton_project(U, B, p, n, q, 0.5 * (u0 + u1), u0, u1, work, CK, False)
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
                                    make_search(B, p), False)
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


@njit(cache=True)
def panel_window_called(starts, cum, closed, s_lo, s_hi, hint):
    """panel_window, called rather than inlined: for a caller's rare path (inlined there, its six walks would
    add to that caller's compilation for ticks that seldom take it)."""
    return panel_window(starts, cum, closed, s_lo, s_hi, hint)


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
