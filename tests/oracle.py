"""A deliberately naive NURBS reference, for tests only.

Nothing here is shared with :mod:`nurbsinterp.nurbs`: the basis functions come
from the Cox–de Boor recursion (Eq. 13–14 of the paper), their derivatives from
the recursion of Eq. 17, and the rational derivatives from the quotient rule on
homogeneous coordinates.  It is slow on purpose: it trades speed for being easy
to check by eye.

Conventions
-----------
Knots ``U[0..n+p+1]``, degree ``p``, control points ``V[0..n]``, weights ``W``.
The basis is right-continuous (``N_{i,0}(u) = 1`` on ``U[i] <= u < U[i+1]``), and
the domain end ``u = U[n+1]`` belongs to the last non-empty span.  With
``side="left"`` the basis is left-continuous instead (``U[i] < u <= U[i+1]``, the
domain start belonging to the first non-empty span): this gives left limits at
interior knots.

Every function accepts a scalar ``u`` (Python float, fast path for
``scipy.integrate.quad``) or a 1-D array of parameters.
"""
from __future__ import annotations

import math

import numpy as np


def _indicator(U, n, i, u, side):
    """N_{i,0}(u): 1 on the half-open knot span, with the end convention above."""
    lo, hi = U[i], U[i + 1]
    if side == "right":
        inside = (lo <= u) & (u < hi)
        # the domain end belongs to the last non-empty span
        last = max(j for j in range(n + 1) if U[j] < U[j + 1])
        at_end = (u == U[n + 1]) & (i == last)
    else:
        inside = (lo < u) & (u <= hi)
        first = min(j for j in range(len(U) - 1) if U[j] < U[j + 1])
        at_end = (u == U[first]) & (i == first)
    hit = inside | at_end
    if np.ndim(hit) == 0:
        return 1.0 if hit else 0.0
    return hit.astype(float)


def basis(U, p, i, u, *, side="right", _memo=None):
    """Cox–de Boor N_{i,p}(u) (Eq. 13–14), with 0/0 := 0."""
    return basis_derivative(U, p, i, 0, u, side=side, _memo=_memo)


def basis_derivative(U, p, i, m, u, *, side="right", _memo=None):
    """m-th derivative of N_{i,p} at u.

    m = 0 is Eq. 13–14::

        N_{i,p} = (u - U_i)/(U_{i+p} - U_i) N_{i,p-1} + (U_{i+p+1} - u)/(U_{i+p+1} - U_{i+1}) N_{i+1,p-1}

    m > 0 is Eq. 17::

        N^(m)_{i,p} = p [N^(m-1)_{i,p-1}/(U_{i+p} - U_i) - N^(m-1)_{i+1,p-1}/(U_{i+p+1} - U_{i+1})]

    A term whose denominator is zero is zero.  ``_memo`` caches values for one
    parameter (or one array of them); it changes nothing but the running time.
    """
    U = [float(x) for x in U] if not isinstance(U, list) else U
    n = len(U) - p - 2
    memo = {} if _memo is None else _memo
    return _rec(U, n, i, p, m, u, side, memo)


def _rec(U, n, i, q, m, u, side, memo):
    key = (i, q, m)
    if key in memo:
        return memo[key]
    if m > q:
        value = 0.0 * u
    elif q == 0:
        value = _indicator(U, n, i, u, side)
    elif m == 0:
        value = 0.0 * u
        den = U[i + q] - U[i]
        if den != 0.0:
            value = value + (u - U[i]) / den * _rec(U, n, i, q - 1, 0, u, side, memo)
        den = U[i + q + 1] - U[i + 1]
        if den != 0.0:
            value = value + (U[i + q + 1] - u) / den * _rec(U, n, i + 1, q - 1, 0, u, side, memo)
    else:
        value = 0.0 * u
        den = U[i + q] - U[i]
        if den != 0.0:
            value = value + q * _rec(U, n, i, q - 1, m - 1, u, side, memo) / den
        den = U[i + q + 1] - U[i + 1]
        if den != 0.0:
            value = value - q * _rec(U, n, i + 1, q - 1, m - 1, u, side, memo) / den
    memo[key] = value
    return value


def homogeneous_derivatives(U, p, V, W, u, order=3, *, side="right"):
    """A^(k)(u) = sum N^(k)_i W_i V_i and w^(k)(u) = sum N^(k)_i W_i, k = 0..order.

    Returns (A, w): A has shape (order+1, dim) for scalar u, (N, order+1, dim)
    for an array; w has the shape of A without the last axis.
    """
    U = [float(x) for x in U]
    V = np.asarray(V, dtype=float)
    W = np.asarray(W, dtype=float)
    memo = {}
    scalar = np.ndim(u) == 0
    uu = float(u) if scalar else np.asarray(u, dtype=float)
    A = []
    w = []
    for k in range(order + 1):
        Ak = 0.0
        wk = 0.0
        for i in range(len(V)):
            N = _rec(U, len(V) - 1, i, p, k, uu, side, memo)
            if scalar:
                Ak = Ak + N * W[i] * V[i]
            else:
                Ak = Ak + np.multiply.outer(N, W[i] * V[i])
            wk = wk + N * W[i]
        A.append(Ak)
        w.append(wk)
    if scalar:
        return np.array(A), np.array(w)
    return np.stack(A, axis=-2), np.stack(np.broadcast_arrays(*w), axis=-1)


def curve_derivatives(U, p, V, W, u, order=3, *, side="right"):
    """C(u) and its derivatives up to order 3 by the quotient rule on C = A / w.

    ::

        C   =  A / w
        C'  = (A'   -  w' C) / w
        C'' = (A''  - 2w' C'  -  w'' C) / w
        C'''= (A''' - 3w' C'' - 3w'' C' - w''' C) / w

    Shape (order+1, dim) for scalar u, (N, order+1, dim) for an array.
    """
    if order > 3:
        raise ValueError("the oracle writes the quotient rule out up to order 3")
    A, w = homogeneous_derivatives(U, p, V, W, u, order, side=side)
    A = np.moveaxis(A, -2, 0)  # (order+1, ..., dim)
    w = np.moveaxis(w, -1, 0)[..., None]  # (order+1, ..., 1)
    C = [A[0] / w[0]]
    if order >= 1:
        C.append((A[1] - w[1] * C[0]) / w[0])
    if order >= 2:
        C.append((A[2] - 2 * w[1] * C[1] - w[2] * C[0]) / w[0])
    if order >= 3:
        C.append((A[3] - 3 * w[1] * C[2] - 3 * w[2] * C[1] - w[3] * C[0]) / w[0])
    return np.stack(C, axis=-2)


def point(U, p, V, W, u):
    """C(u)."""
    return curve_derivatives(U, p, V, W, u, 0)[..., 0, :]


def speed(U, p, V, W, u):
    """|C'(u)| for a scalar u (the integrand of the arc length)."""
    return math.sqrt(float(np.sum(curve_derivatives(U, p, V, W, u, 1)[1] ** 2)))


def insert_knot(U, p, V, W, ubar):
    """Boehm's insertion of ubar once (P&T A5.1 with r = 1), on homogeneous points.

    Returns (U', V', W'): the same curve with one more knot and control point.
    """
    U = np.asarray(U, dtype=float)
    Pw = np.column_stack([np.asarray(V, dtype=float) * np.asarray(W, dtype=float)[:, None], W])
    n = len(Pw) - 1
    k = max(j for j in range(p, n + 1) if U[j] <= ubar < U[j + 1])  # the span of ubar
    Q = np.empty((n + 2, Pw.shape[1]))
    for i in range(n + 2):
        if i <= k - p:
            Q[i] = Pw[i]
        elif i >= k + 1:
            Q[i] = Pw[i - 1]
        else:
            alpha = (ubar - U[i]) / (U[i + p] - U[i])
            Q[i] = alpha * Pw[i] + (1.0 - alpha) * Pw[i - 1]
    U2 = np.concatenate([U[: k + 1], [ubar], U[k + 1:]])
    return U2, Q[:, :-1] / Q[:, -1:], Q[:, -1]
