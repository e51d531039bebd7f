"""One command per tick from committed pieces of the plan and their segments.

The plan is S(t), exact in closed form on each constant-acceleration piece; a
tick's point is the segment's point at that arc length, exact too (a line, or
an arc in its own arc length).  So the commands lie on the planned path to
rounding, whatever the feedrate: a tick may cross many segments, and the feed
is never capped by the segments' length per tick.
"""
from __future__ import annotations

import numpy as np

from .._jit import njit
from . import segments as seg

# columns of the rows this kernel writes: k, n, t, u, x, y, z, v, a, rapid
K_COL, N_COL, T_COL, U_COL, X_COL, V_COL, A_COL, RAPID_COL = 0, 1, 2, 3, 4, 7, 8, 9
NROW = 10


@njit(cache=True)
def emit(table, rows, k0, k1, period, out):
    """Ticks k0 .. k1−1 (their times inside the pieces' span) into out (k1 − k0, NROW).

    table: pieces [t, s, v, a, jerk] sorted by t (constant-jerk pieces: the cubic S(t) on each); rows: the
    segments they run over, S0 sorted."""
    m = table.shape[0]
    n = rows.shape[0]
    p = 0
    q = 0
    point = np.empty(3)
    for i in range(k1 - k0):
        k = k0 + i
        t = k * period
        while p + 1 < m and table[p + 1, 0] <= t:
            p += 1
        tau = t - table[p, 0]
        if tau < 0.0:
            tau = 0.0
        v0 = table[p, 2]
        a0 = table[p, 3]
        j = table[p, 4]
        S = table[p, 1] + tau * (v0 + tau * (0.5 * a0 + tau * j / 6.0))
        V = v0 + tau * (a0 + 0.5 * j * tau)
        a = a0 + j * tau
        if V < 0.0:
            V = 0.0
        while q + 1 < n and rows[q + 1, seg.S0] <= S:
            q += 1
        ls = S - rows[q, seg.S0]
        if ls < 0.0:
            ls = 0.0
        elif ls > rows[q, seg.LEN]:
            ls = rows[q, seg.LEN]
        w = seg.segment_point(rows[q], ls, point)
        r = out[i]
        r[K_COL] = k
        r[N_COL] = rows[q, seg.BLOCK]
        r[T_COL] = t
        r[U_COL] = seg.segment_u(rows[q], ls, w)
        r[X_COL] = point[0]
        r[X_COL + 1] = point[1]
        r[X_COL + 2] = point[2]
        r[V_COL] = V
        r[A_COL] = a if V > 0.0 or a > 0.0 else 0.0
        r[RAPID_COL] = rows[q, seg.RAPID]


@njit(cache=True)
def axis_extremes(x, prev, count, period, out):
    """Largest |first|, |second| and |third| difference per axis over ticks (x: (m, dim) commands), carrying the
    last three commands of the previous chunk in *prev* ((3, dim), *count* of them valid).  out (3, dim) is
    updated: velocity (mm/s), acceleration (mm/s²), jerk (mm/s³).  Returns the new count."""
    dim = x.shape[1]
    for i in range(x.shape[0]):
        for a in range(dim):
            if count >= 1:
                v = (x[i, a] - prev[2, a]) / period
                out[0, a] = max(out[0, a], abs(v))
            if count >= 2:
                acc = (x[i, a] - 2.0 * prev[2, a] + prev[1, a]) / (period * period)
                out[1, a] = max(out[1, a], abs(acc))
            if count >= 3:
                j = (x[i, a] - 3.0 * prev[2, a] + 3.0 * prev[1, a] - prev[0, a]) / (period * period * period)
                out[2, a] = max(out[2, a], abs(j))
        for a in range(dim):
            prev[0, a] = prev[1, a]
            prev[1, a] = prev[2, a]
            prev[2, a] = x[i, a]
        count = min(count + 1, 3)
    return count
