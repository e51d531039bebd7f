"""The feed limit at a point: the terms of V_lim, the tangential acceleration bound, κ and τ from the curve's
derivatives (step 1 of the algorithm in :mod:`nurbsinterp.planner`), numba kernels.

The planner evaluates them at some 34 grid points per knot span and ~250 golden-section points (4 brackets,
62 evaluations each), millions on a long curve.  As numpy arrays they were most of the planning time; here
:func:`_limits_row` computes one point, rounding every number as those arrays did (the same operations in the
same order: np.einsum's sums, np.minimum, np.nan_to_num), so that the plans stay the same to the bit
(tests/test_planner.py holds the numpy version as an oracle).  The kernels call only each other: numba caches
a kernel by its own file.
"""
from __future__ import annotations

import numpy as np

from .._jit import njit
from .limits import AXIS_ACCEL, AXIS_VELOCITY, CHORD, FEEDRATE, LIMITS, NORMAL_ACCEL, _Limits


def _feed_limits(d, lim: _Limits, singular=None, tangent=None, feedrate=None):
    """Every term of V_lim (N, 5), mm/s, the tangential acceleration bound (N,), mm/s², κ (N,), 1/mm, and τ (N, dim).

    *singular* marks span ends where the parametric speed vanishes; *tangent* holds their limit
    tangents; *feedrate* (N,) replaces F where blocks carry their own.  The curvature there is
    undefined (and mostly infinite: near such an end C − P_0 grows as (u − a)^j, j >= 2, and κ as
    s^(1/j − 1) unless the next leg is collinear), so the terms that depend on it are 0: a zero-speed
    end is a stop whenever a curvature limit is set.  At V = 0 the centripetal part of an axis budget
    is 0, so the tangential bound takes all of it.  One kernel computes them point by point (see
    :func:`_limits_row`).
    """
    n = d.shape[0]
    dim = d.shape[2]
    if singular is None:
        singular = np.zeros(n, dtype=bool)
        tangent = np.zeros((n, dim))
    feed = np.full(1, np.nan) if feedrate is None else np.ascontiguousarray(feedrate, dtype=float)
    comps = np.empty((n, len(LIMITS)))
    acc_t, kappa = np.empty(n), np.empty(n)
    tau = np.empty((n, dim))
    _feed_limits_kernel(d, singular, tangent, feed, *_kernel_limits(lim), comps, acc_t, kappa, tau)
    return comps, acc_t, kappa, tau


def _kernel_limits(lim: _Limits):
    """The limits as :func:`_feed_limits_kernel` takes them (NaN: not set)."""
    curving = np.zeros(len(LIMITS), dtype=bool)
    curving[list(lim.curvature_columns)] = True
    return (lim.feedrate, 2.0 / lim.period, np.nan if lim.chord_tolerance is None else lim.chord_tolerance,
            np.nan if lim.max_normal_accel is None else lim.max_normal_accel,
            np.inf if lim.max_accel is None else lim.max_accel, lim.has_axis_velocity, lim.axis_velocity,
            lim.has_axis_accel, lim.axis_accel, (1.0 - lim.share) * lim.axis_accel, curving)


@njit(cache=True)
def _dot(a, b):
    """Σ a_j b_j of two points (2 or 3 coordinates), rounded as np.einsum("ij,ij->i") rounds each row.

    numpy's einsum sums the row from 0 in two interleaved partial sums (j even, j odd) and adds them:
    (0 + a0b0) + a1b1 in 2-D, ((0 + a0b0) + a2b2) + a1b1 in 3-D (measured on numpy 2.4, contiguous
    rows and rows of a derivative table alike; tests/test_planner.py checks it on random rows).
    """
    if a.shape[0] == 3:
        return ((0.0 + a[0] * b[0]) + a[2] * b[2]) + a[1] * b[1]
    return (0.0 + a[0] * b[0]) + a[1] * b[1]


@njit(cache=True)
def _np_min(a, b):
    """np.minimum(a, b) of two floats: a if a < b or a is NaN, else b."""
    return a if (a < b or a != a) else b


@njit(cache=True)
def _nan_to_num(x):
    """np.nan_to_num(x, nan=0.0, posinf=inf): NaN -> 0, -inf -> the most negative float."""
    if x != x:
        return 0.0
    if x == -np.inf:
        return -1.7976931348623157e308
    return x


@njit(cache=True, error_model="numpy")
def _limits_row(d1, d2, singular, tangent, feed, feedrate, two_over_T, chord_tol, normal_accel, max_accel,
                has_axis_velocity, axis_velocity, has_axis_accel, axis_accel, axis_centripetal, curving, comps, t, kn,
                frame):
    """The terms of V_lim (into comps, (5,)) and, if *frame* or an axis limit needs it, τ (into t) at one
    point from C' = d1 and C'' = d2; returns (tangential bound, κ).

    Each number rounded as the numpy arrays of the planner before it rounded them (the same operations in
    the same order: _dot for np.einsum, min over the axes propagating NaN, nan_to_num), so that the grid,
    and every plan, stay the same to the bit; tests/test_planner.py holds that numpy version and checks
    the two against each other.  feed: the block's own feedrate (NaN: F); chord_tol, normal_accel: NaN if
    not set; kn: scratch.
    """
    dim = d1.shape[0]
    k = _curvature_row(d1, d2, singular, kn)
    if frame or has_axis_velocity or has_axis_accel:
        if singular:
            for j in range(dim):
                t[j] = tangent[j]
        else:
            root = np.sqrt(_dot(d1, d1))
            for j in range(dim):  # τ = C'/σ
                t[j] = d1[j] / root
    rho = 1.0 / k
    for c in range(comps.shape[0]):
        comps[c] = np.inf
    comps[FEEDRATE] = feedrate if feed != feed else feed
    if chord_tol == chord_tol:  # (2/T) √(2ρδ − δ²), δ below ρ = δ (see "Tight turns")
        x = 2.0 * rho * chord_tol - chord_tol * chord_tol
        x = x if (x >= 0.0 or x != x) else 0.0  # np.maximum(x, 0.0)
        comps[CHORD] = two_over_T * (chord_tol if rho < chord_tol else np.sqrt(x))
    if normal_accel == normal_accel:  # √(A_n ρ), A_n T/2 below ρ = A_n T²/4 (see "Tight turns")
        v = np.sqrt(normal_accel * rho)
        floor = normal_accel / two_over_T
        comps[NORMAL_ACCEL] = v if (v >= floor or v != v) else floor
    if has_axis_velocity:
        m = axis_velocity[0] / abs(t[0])
        for j in range(1, dim):
            m = _np_min(m, axis_velocity[j] / abs(t[j]))
        comps[AXIS_VELOCITY] = m
    if has_axis_accel:
        m = np.sqrt(axis_centripetal[0] / abs(kn[0]))
        for j in range(1, dim):
            m = _np_min(m, np.sqrt(axis_centripetal[j] / abs(kn[j])))
        comps[AXIS_ACCEL] = m
    for c in range(comps.shape[0]):
        comps[c] = _nan_to_num(comps[c])  # a zero tangent (cusp) stops the motion
    if singular:
        for c in range(comps.shape[0]):
            if curving[c]:
                comps[c] = 0.0
    a = max_accel
    if has_axis_accel:
        # what the centripetal part leaves of each axis budget at the highest feedrate allowed here
        vmax = comps[0]
        for c in range(1, comps.shape[0]):
            vmax = _np_min(vmax, comps[c])
        m = (axis_accel[0] - vmax * vmax * abs(kn[0])) / abs(t[0])
        for j in range(1, dim):
            m = _np_min(m, (axis_accel[j] - vmax * vmax * abs(kn[j])) / abs(t[j]))
        a = _np_min(a, _nan_to_num(m))
    return a, k


@njit(cache=True, error_model="numpy")
def _curvature_row(d1, d2, singular, kn):
    """κ at one point from C' = d1 and C'' = d2, NaN at a zero-speed span end, and the curvature vector κn
    = dτ/ds = C''/σ² − C'(C'·C'')/σ⁴ into kn (0 at such an end)."""
    sig2 = _dot(d1, d1)
    along = _dot(d1, d2) / (sig2 * sig2)
    for j in range(d1.shape[0]):
        kn[j] = 0.0 if singular else d2[j] / sig2 - d1[j] * along
    return np.nan if singular else np.sqrt(_dot(kn, kn))


@njit(cache=True, error_model="numpy")
def _feed_limits_kernel(d, singular, tangent, feed, feedrate, two_over_T, chord_tol, normal_accel, max_accel,
                        has_axis_velocity, axis_velocity, has_axis_accel, axis_accel, axis_centripetal, curving,
                        comps, acc_t, kappa, tau):
    """_limits_row at every row of the derivative table d (N, 3, dim); feed (N,), or [NaN]: F everywhere."""
    dim = d.shape[2]
    t = np.empty(dim)
    kn = np.empty(dim)
    for i in range(d.shape[0]):
        acc_t[i], kappa[i] = _limits_row(
            d[i, 1], d[i, 2], singular[i], tangent[i], feed[i] if feed.shape[0] == d.shape[0] else feed[0], feedrate,
            two_over_T, chord_tol, normal_accel, max_accel, has_axis_velocity, axis_velocity, has_axis_accel,
            axis_accel, axis_centripetal, curving, comps[i], t, kn, True)
        for j in range(dim):
            tau[i, j] = t[j]


@njit(cache=True, error_model="numpy")
def _column_kernel(d, uu, loc, start, end, end_sing, end_tan, feed, column, feedrate, two_over_T, chord_tol,
                   normal_accel, max_accel, has_axis_velocity, axis_velocity, has_axis_accel, axis_accel,
                   axis_centripetal, curving, out):
    """At the samples uu on the block's spans loc, from their derivative table d: V_lim (column 0), the
    tangential bound (1) or −κ (2), as _Spans.at_ends and _feed_limits give them; feed: per span, or [NaN]."""
    dim = d.shape[2]
    comps = np.empty(len(LIMITS))
    t = np.empty(dim)
    kn = np.empty(dim)
    for i in range(d.shape[0]):
        sp = loc[i]
        at_start = uu[i] == start[sp]
        singular = (at_start and end_sing[0, sp]) or (uu[i] == end[sp] and end_sing[1, sp])
        if column == 2:  # κ alone
            out[i] = -_curvature_row(d[i, 1], d[i, 2], singular, kn)
            continue
        a, k = _limits_row(d[i, 1], d[i, 2], singular, end_tan[0, sp] if at_start else end_tan[1, sp],
                           feed[sp] if feed.shape[0] == start.shape[0] else feed[0], feedrate, two_over_T,
                           chord_tol, normal_accel, max_accel, has_axis_velocity, axis_velocity, has_axis_accel,
                           axis_accel, axis_centripetal, curving, comps, t, kn, False)
        if column == 0:
            v = comps[0]
            for c in range(1, comps.shape[0]):
                v = _np_min(v, comps[c])
            out[i] = v
        else:
            out[i] = a if column == 1 else -k
