"""The motion along a section's caps: the scan without a jerk limit (step 3 of the algorithm in
:mod:`nurbsinterp.planner`) and the jerk-limited forward pass (step 4), numba kernels."""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from .._jit import njit

BISECTIONS = 24           # bisection steps for the jerk of one forward step
LEVELS = 64  # brake levels tried, a_top down to a_floor geometrically, for a window's start in motion without a carry
CRUISE_RTOL = 1e-9  # a feedrate this close under its interval's cap, with A = 0, is held there (a cruise)
ATOL_FACTOR = 1.0 - 1e-12  # |A| at a cap by construction (the braking manoeuvre) may exceed it by rounding
JTOL_FACTOR = 1.0 - 1e-12  # likewise a jerk at its cap (a ramp's −a/τ with τ = a/J)

#: The brackets and tolerances of the jerk-limited pass's searches, constants of a plan: a_floor and a_top bracket the
#: brake level (mm/s²), a_top also the jerks tried; v_top (mm/s) bounds V after a coarse step; vtol (mm/s) is the
#: rounding allowed below V = 0 and under a cap when landing on it; end_tol (mm), the gap to the end taken as reached
#: at rest.  A section planned whole takes them from its nodes and caps (_pass_bounds).
PassBounds = namedtuple("PassBounds", ["a_floor", "a_top", "v_top", "vtol", "end_tol"])
#: What a window of the pass hands to the next one beside the state (s, v, a): t (s), the time reached; ab_safe
#: (mm/s²), the brake level that certifies the state, and jb_safe (mm/s³) the jerk of that braking manoeuvre; last,
#: the last piece (t, s, v, a, j), NaNs when there is none.
Handover = namedtuple("Handover", ["t", "ab_safe", "jb_safe", "last"])


@njit(cache=True)
def _advance(s, v, a, j, t):
    """State (s, v, a) after time t of constant jerk j."""
    return (s + t * (v + t * (0.5 * a + t * j / 6.0)),
            v + t * (a + 0.5 * j * t),
            a + j * t)


@njit(cache=True)
def _v_range(v, a, j, t0, t1):
    """(min, max) of v + a t + j t²/2 over [t0, t1]."""
    va = v + t0 * (a + 0.5 * j * t0)
    vb = v + t1 * (a + 0.5 * j * t1)
    lo = min(va, vb)
    hi = max(va, vb)
    if j != 0.0:
        tv = -a / j
        if t0 < tv < t1:
            vv = v + tv * (a + 0.5 * j * tv)
            lo = min(lo, vv)
            hi = max(hi, vv)
    return lo, hi


@njit(cache=True)
def _interval(nodes, s):
    """k with nodes[k] <= s < nodes[k+1], clipped to the intervals 0 .. n-2."""
    k = np.searchsorted(nodes, s, side="right") - 1
    return min(max(k, 0), nodes.shape[0] - 2)


RMQ_BITS = 4  # range minima: blocks of 2**RMQ_BITS values, and blocks of as many blocks (see _min_table)


@njit(cache=True)
def _min_table(vals):
    """Range minima of *vals* (n,) in O(n) memory: (table, lg) for :func:`_range_min`.

    table holds the minimum of every block of 16 values (n/16 entries), then a sparse table over the
    blocks of 256 values (level l, entry c: the minimum of the 2**l blocks of 256 from block c; n/256 ·
    log2(n/256) entries), ~1 byte per value in all.  A sparse table over the values themselves took
    8·log2(n) bytes per value: 22 levels, 600 MB for each of the caps and the acceleration caps of the 3.4
    million intervals of a curve of 10⁵ control points.
    lg[k] = floor(log2(k)) for the sparse table's lengths.
    """
    n = vals.shape[0]
    b = 1 << RMQ_BITS
    n1 = (n + b - 1) >> RMQ_BITS  # blocks of 16 values
    n2 = (n1 + b - 1) >> RMQ_BITS  # blocks of 256
    levels = 1
    while (1 << levels) <= n2:
        levels += 1
    table = np.empty(n1 + levels * n2)
    for i in range(n1):
        m = vals[i << RMQ_BITS]
        for k in range((i << RMQ_BITS) + 1, min((i + 1) << RMQ_BITS, n)):
            m = min(m, vals[k])
        table[i] = m
    for c in range(n2):
        m = table[c << RMQ_BITS]
        for k in range((c << RMQ_BITS) + 1, min((c + 1) << RMQ_BITS, n1)):
            m = min(m, table[k])
        table[n1 + c] = m
    for lev in range(1, levels):
        half = 1 << (lev - 1)
        row = n1 + lev * n2
        prev = row - n2
        for c in range(n2):
            table[row + c] = min(table[prev + c], table[prev + c + half]) if c + (1 << lev) <= n2 else table[prev + c]
    lg = np.zeros(n2 + 1, dtype=np.int64)
    for i in range(2, n2 + 1):
        lg[i] = lg[i >> 1] + 1
    return table, lg


@njit(cache=True)
def _scan_min(vals, i, j):
    m = vals[i]
    for k in range(i + 1, j + 1):
        m = min(m, vals[k])
    return m


@njit(cache=True)
def _range_min(vals, table, lg, i, j):
    """min(vals[i : j + 1]) from its :func:`_min_table`; for j < i see :func:`_range_min_behind`."""
    if j < i:
        return _range_min_behind(vals, table, lg, i, j)
    return _range_min_ahead(vals, table, lg, i, j)


@njit(cache=True)
def _range_min_ahead(vals, table, lg, i, j):
    """min(vals[i : j + 1]), i <= j: at most 4 runs of under 32 entries, and two of the sparse table."""
    if j - i < 32:
        return _scan_min(vals, i, j)
    n1 = (vals.shape[0] + (1 << RMQ_BITS) - 1) >> RMQ_BITS
    n2 = (n1 + (1 << RMQ_BITS) - 1) >> RMQ_BITS
    bi = (i >> RMQ_BITS) + 1  # the whole blocks of 16 past i's, up to j: bi .. bj
    bj = ((j + 1) >> RMQ_BITS) - 1
    m = _scan_min(vals, i, (bi << RMQ_BITS) - 1)
    if (bj + 1) << RMQ_BITS <= j:
        m = min(m, _scan_min(vals, (bj + 1) << RMQ_BITS, j))
    if bj - bi < 32:
        return min(m, _scan_min(table, bi, bj))
    ci = (bi >> RMQ_BITS) + 1  # the whole blocks of 256 past bi's, up to bj: ci .. cj
    cj = ((bj + 1) >> RMQ_BITS) - 1
    m = min(m, _scan_min(table, bi, (ci << RMQ_BITS) - 1))
    if (cj + 1) << RMQ_BITS <= bj:
        m = min(m, _scan_min(table, (cj + 1) << RMQ_BITS, bj))
    lev = lg[cj - ci + 1]
    row = n1 + lev * n2
    return min(m, table[row + ci], table[row + cj - (1 << lev) + 1])


@njit(cache=True)
def _range_min_behind(vals, table, lg, i, j):
    """What the sparse table over the values themselves (before :func:`_min_table`) answered for j < i.

    A piece that ends behind its start by rounding (V down to −vtol) asks for such a range.  That
    table read level lev = lg[j − i + 1] (an index below 0 wraps around, to floor(log2(n + 2 + j − i)))
    at entries i and j − 2**lev + 1 (wrapped likewise), each entry x of a level l the minimum of
    vals[x : x + 2**l], or of the highest level below that fits before n.  Kept, so that the plans
    stay what they were to the bit.
    """
    n = vals.shape[0]
    k = j - i + 1
    if k < 0:
        k += n + 1
    lev = 0
    while (2 << lev) <= k:
        lev += 1
    x = j - (1 << lev) + 1
    if x < 0:
        x += n
    return min(_old_entry(vals, table, lg, lev, i), _old_entry(vals, table, lg, lev, x))


@njit(cache=True)
def _old_entry(vals, table, lg, lev, x):
    while x + (1 << lev) > vals.shape[0]:
        lev -= 1
    return _range_min_ahead(vals, table, lg, x, x + (1 << lev) - 1)


@njit(cache=True)
def _time_at(s0, v0, a0, j, target, tlo, thi):
    """t in [tlo, thi] with s(t) = target (s non-decreasing there): safeguarded Newton."""
    t = 0.5 * (tlo + thi)
    for _ in range(100):
        s, v, _a = _advance(s0, v0, a0, j, t)
        f = s - target
        if f > 0.0:
            thi = t
        elif f < 0.0:
            tlo = t
        else:
            return t
        nt = t - f / v if v > 0.0 else 0.5 * (tlo + thi)
        if not (tlo < nt < thi):
            nt = 0.5 * (tlo + thi)
        if nt == t or thi - tlo <= 1e-16 * thi:
            return t
        t = nt
    return t


@njit(cache=True)
def _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s0, v0, a0, j, tau, s_end, stol, vtol):
    """Whether the piece (s0, v0, a0, jerk j, duration tau) keeps 0 <= V <= cap(S), |A| <= acap(S), |j| <= jcap(S),
    S <= s_end.

    A range-minimum query accepts the whole piece at once when its largest V and |A|
    are below the smallest caps it meets; otherwise it is split where it crosses a
    grid point, until every part is accepted or a part inside one interval fails.
    """
    if tau <= 0.0:
        return True
    vlo, vhi = _v_range(v0, a0, j, 0.0, tau)
    if vlo < -vtol:
        return False
    s1 = _advance(s0, v0, a0, j, tau)[0]
    if s1 > s_end + stol:
        return False
    ka = _interval(nodes, s0)
    kb = _interval(nodes, s1)
    ahi = max(abs(a0), abs(a0 + j * tau)) * ATOL_FACTOR
    jhi = abs(j) * JTOL_FACTOR
    if (vhi <= _range_min(caps, vtab, lg, ka, kb) and ahi <= _range_min(acaps, atab, lg, ka, kb)
            and jhi <= _range_min(jcaps, jtab, lg, ka, kb)):
        return True
    st_a = np.empty(64)
    st_b = np.empty(64)
    st_ka = np.empty(64, dtype=np.int64)
    st_kb = np.empty(64, dtype=np.int64)
    top = 0
    st_a[0] = 0.0
    st_b[0] = tau
    st_ka[0] = ka
    st_kb[0] = kb
    while top >= 0:
        ta = st_a[top]
        tb = st_b[top]
        ia = st_ka[top]
        ib = st_kb[top]
        top -= 1
        vh = _v_range(v0, a0, j, ta, tb)[1]
        ah = max(abs(a0 + j * ta), abs(a0 + j * tb)) * ATOL_FACTOR
        if (vh <= _range_min(caps, vtab, lg, ia, ib) and ah <= _range_min(acaps, atab, lg, ia, ib)
                and jhi <= _range_min(jcaps, jtab, lg, ia, ib)):
            continue
        if ia >= ib:
            return False
        km = (ia + ib + 1) >> 1
        tc = _time_at(s0, v0, a0, j, nodes[km], ta, tb)
        top += 1
        st_a[top] = tc
        st_b[top] = tb
        st_ka[top] = km
        st_kb[top] = ib
        top += 1
        st_a[top] = ta
        st_b[top] = tc
        st_ka[top] = ia
        st_kb[top] = km - 1
    return True


@njit(cache=True)
def _brake(v, a, J, Ab):
    """Shortest jerk-limited stop from (v, a) with deceleration at most Ab.

    Jerk −J for t1 (down to −ap), hold −ap for t2, jerk +J for t3 (to A = 0 as V
    reaches 0): returns (t1, t2, t3, ap); t1 < 0 means there is no stop without V < 0.
    """
    ap = math.sqrt(max(J * v + 0.5 * a * a, 0.0))
    if a < 0.0 and ap < -a:
        if -a - ap > 1e-9 * -a:
            return -1.0, 0.0, 0.0, 0.0
        ap = -a
    if ap <= Ab:
        return (a + ap) / J, 0.0, ap / J, ap
    v1 = v + (a * a - Ab * Ab) / (2.0 * J)
    t2 = (v1 - Ab * Ab / (2.0 * J)) / Ab
    return (a + Ab) / J, max(t2, 0.0), Ab / J, Ab


@njit(cache=True)
def _stop_distance(v, a, J, Ab):
    t1, t2, t3, ap = _brake(v, a, J, Ab)
    if t1 < 0.0:
        return 0.0
    s1, v1, _a = _advance(0.0, v, a, -J, t1)
    s2 = s1 + t2 * (v1 - 0.5 * ap * t2)
    v2 = v1 - ap * t2
    return _advance(s2, v2, -ap, J, t3)[0]


@njit(cache=True)
def _brake_level(nodes, acaps, atab, lg, a_floor, a_top, J, s, v, a):
    """Deceleration for the braking manoeuvre from (s, v, a).

    The largest Ab such that every acceleration cap within the manoeuvre's reach
    is at least Ab (a harder brake stops sooner, so the reach shrinks as Ab
    grows; the path's smallest cap always qualifies), found by bisection.
    """
    ka = _interval(nodes, s)
    if not a_top < math.inf:
        return a_top
    if _range_min(acaps, atab, lg, ka, _interval(nodes, s + _stop_distance(v, a, J, a_top))) >= a_top:
        return a_top
    lo = a_floor
    hi = a_top
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        if _range_min(acaps, atab, lg, ka, _interval(nodes, s + _stop_distance(v, a, J, mid))) >= mid:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-6 * hi:
            break
    return lo


@njit(cache=True)
def _brake_jerk(nodes, jcaps, jtab, lg, J, s, v, a, Ab):
    """The jerk of the braking manoeuvre from (s, v, a) at deceleration Ab: the smallest jerk cap within the reach
    of the one at J (the pass's, at most every cap), and at least J.  A manoeuvre at a higher jerk stops sooner, so
    its reach lies inside that one: every cap it meets allows it (a line along x brakes at the full j_x, not at
    the share of the smallest axis' every segment allows)."""
    ka = _interval(nodes, s)
    kb = _interval(nodes, s + _stop_distance(v, a, J, Ab))
    return max(J, _range_min(jcaps, jtab, lg, ka, kb))


@njit(cache=True)
def _certified(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, s_end, stol, vtol):
    """Whether the state (s, v, a) is safe, with the manoeuvre that certifies it: (ok, Ab, Jb).  The brake level
    Ab from the reach at J; the manoeuvre's jerk Jb from the caps within it, or J where that one is not safe."""
    Ab = _brake_level(nodes, acaps, atab, lg, a_floor, a_top, J, s, v, a)
    Jb = _brake_jerk(nodes, jcaps, jtab, lg, J, s, v, a, Ab)
    if Jb > J and _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, Jb, Ab, s, v, a, s_end, stol, vtol):
        return True, Ab, Jb
    return _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, Ab, s, v, a, s_end, stol, vtol), Ab, J


@njit(cache=True)
def _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, Ab, s, v, a, s_end, stol, vtol):
    """Whether the braking manoeuvre (deceleration Ab) from (s, v, a) keeps every cap and stops by s_end."""
    t1, t2, t3, ap = _brake(v, a, J, Ab)
    if t1 < 0.0:
        return False
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s, v, a, -J, t1, s_end, stol, vtol):
        return False
    s1, v1, _a1 = _advance(s, v, a, -J, t1)
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s1, v1, -ap, 0.0, t2, s_end, stol, vtol):
        return False
    s2 = s1 + t2 * (v1 - 0.5 * ap * t2)
    v2 = v1 - ap * t2
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s2, v2, -ap, J, t3, s_end, stol, vtol):
        return False
    return _advance(s2, v2, -ap, J, t3)[0] <= s_end + stol


@njit(cache=True)
def _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, j, dt, s_end, stol, vtol):
    """Whether a step of jerk j keeps the caps and ends in a safe state; also the brake level and jerk that certify
    it."""
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s, v, a, j, dt, s_end, stol, vtol):
        return False, 0.0, J
    s1, v1, a1 = _advance(s, v, a, j, dt)
    return _certified(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s1, v1, a1, s_end, stol, vtol)


@njit(cache=True)
def _level_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, jj, tau, dt, s_end, stol, vtol):
    """Whether the step that brings A to 0 with jerk jj (over tau = −a/jj <= dt) and then holds V (the rest
    of dt) keeps the caps and ends in a safe state; also the brake level and jerk that certify it.

    Two uses: leveling off at full jerk, where dt is long against the jerk's ramps A/J (one
    constant jerk per step cannot both undo an acceleration and hold the feedrate, and the pass
    would brake to rest instead); and landing on a cap, where jj is the jerk that reaches A = 0
    just as V reaches the cap.
    """
    if not tau < dt:
        return False, 0.0, J
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s, v, a, jj, tau, s_end, stol, vtol):
        return False, 0.0, J
    s1, v1, _a1 = _advance(s, v, a, jj, tau)
    if v1 <= vtol:  # the ramp comes to rest: that is the braking manoeuvre, which ends the step there
        return False, 0.0, J
    if not _piece_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, s1, v1, 0.0, 0.0, dt - tau, s_end, stol, vtol):
        return False, 0.0, J
    s2 = s1 + v1 * (dt - tau)
    return _certified(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s2, v1, 0.0, s_end, stol, vtol)


@njit(cache=True)
def _hold(out, m, t, s, v, dt):
    """Append dt of constant feedrate v from (t, s): the last row is extended when it holds v already.

    Returns (out, m, s after the hold).  An extended row keeps its start, so s is taken from it
    (s0 + v (t + dt − t0)), exactly as the table will evaluate it.
    """
    if m > 0 and out[m - 1, 4] == 0.0 and out[m - 1, 3] == 0.0 and out[m - 1, 2] == v:
        return out, m, out[m - 1, 1] + v * (t + dt - out[m - 1, 0])
    out = _push(out, m, t, s, v, 0.0, 0.0)
    return out, m + 1, s + v * dt


@njit(cache=True)
def _push(out, m, t, s, v, a, j):
    if m >= out.shape[0]:
        bigger = np.empty((2 * out.shape[0], 5))
        bigger[:m] = out[:m]
        out = bigger
    out[m, 0] = t
    out[m, 1] = s
    out[m, 2] = v
    out[m, 3] = a
    out[m, 4] = j
    return out


@njit(cache=True)
def _creep_jerk(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, s, gap):
    """Largest jerk of the rest-to-rest move over *gap* from s that keeps the smallest caps on the way, and the
    jerk the move may take at all: the smallest jerk cap on the way (at least J, the pass's).

    The move is jerk +j for τ, −j for 2τ, +j for τ with 2jτ³ = gap (the time-optimal
    rest-to-rest move when no cap binds); its largest |A| is jτ and its largest V
    is jτ², so j = min(J_gap, a³ᐟ²/√(gap/2), v³/(gap/2)²) keeps the smallest V, |A| and jerk caps.
    """
    ka = _interval(nodes, s)
    kb = _interval(nodes, s + gap)
    vc = _range_min(caps, vtab, lg, ka, kb) * ATOL_FACTOR
    ac = _range_min(acaps, atab, lg, ka, kb) * ATOL_FACTOR
    jg = max(J, _range_min(jcaps, jtab, lg, ka, kb) * JTOL_FACTOR)
    h = 0.5 * gap
    return min(jg, ac * math.sqrt(ac / h), vc * vc * vc / (h * h)), jg


@njit(cache=True)
def _pass_bounds(nodes, caps, acaps):
    """The :class:`PassBounds` of a section planned whole: from its own nodes and caps (what :func:`_jerk_limited`
    uses; end_tol: the section is scaled onto its length afterwards, within MARGIN of every limit)."""
    return PassBounds(acaps.min(), acaps.max(), caps.max(), 1e-12 * max(caps.max(), 1.0),
                      1e-10 * (nodes[nodes.shape[0] - 1] - nodes[0]))


@njit(cache=True)
def _jerk_limited(nodes, caps, acaps, J, dt, max_steps, coarse):
    """Forward pass of the jerk-limited planner on one rest-to-rest section.

    caps, acaps : per interval, the bounds of V and |A|; coarse : dt is long against the
    jerk's ramps (see the level-off step below).  Returns (pieces, status):
    rows [t, s, v, a, j] (t from 0, s absolute), the last row being the final
    state with j = 0; status 0 on success, 1 when the end was not reached within
    max_steps.  It is :func:`_jerk_window` from rest with no commit point.
    """
    rows, status, _state, _carry = _jerk_window(nodes, caps, acaps, J, dt, max_steps, coarse, 0.0, 0.0, math.inf,
                                                None, None, None)  # (every argument given: no omitted variant)
    return rows, status


@njit(cache=True)
def _certify(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, a_floor, a_top, s, v, a, s_end, stol, vtol):
    """The highest brake level that certifies (s, v, a) (see :func:`_safe`), or NaN: tried from the top, the
    current deceleration (a brake's hold), a geometric ladder of LEVELS from a_top down to max(a_floor, −a),
    and the acceleration caps within the reach of the lowest (a level the search found under other bounds
    lies just under one of them or where the reach crosses a node, and the caps bound it from above)."""
    low = max(a_floor, -a)
    if low > a_top:
        return math.nan
    ka = _interval(nodes, s)
    kb = _interval(nodes, s + _stop_distance(v, a, J, low))
    kb = min(kb, ka + 4096)
    levels = np.empty(LEVELS + 2 + kb - ka + 1)
    for i in range(LEVELS + 1):
        levels[i] = a_top * (low / a_top) ** (i / LEVELS)
    levels[LEVELS + 1] = -a
    for k in range(ka, kb + 1):
        levels[LEVELS + 2 + k - ka] = acaps[k]
    levels = np.sort(levels)
    for i in range(levels.shape[0] - 1, -1, -1):
        level = levels[i]
        if low <= level <= a_top and _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, level, s, v, a, s_end, stol, vtol):
            return level
    return math.nan


@njit(cache=True)
def _jerk_window(nodes, caps, acaps, J, dt, max_steps, coarse, v0, a0, s_commit, bounds=None, carry=None,
                 jerk_caps=None):
    """The forward pass over a window of a section, from the state (nodes[0], v0, a0) up to a commit point.

    The window's end nodes[-1] is a stop (V = 0 there), as a section's end is.  The pass steps as
    :func:`_jerk_limited` does until s reaches *s_commit* (the first step that ends at or beyond it) or
    the end at rest.  Returns (rows, status, (s, v, a), carry):

    rows : (m, 5) [t, s, v, a, j], the constant-jerk pieces from the start, the last row the state
        reached with j = 0 (the committed pieces are rows[:-1])
    status : 0 the end reached at rest, 2 s >= s_commit, 1 the step budget max_steps exhausted, 3 the
        start (without a carry) cannot stop inside the window within the caps: rows is its state alone
    (s, v, a) : the state reached (the last row's), where the next window starts: its nodes[0] = s
    carry : :class:`Handover`, what the next window needs to go on exactly as the pass over the
        whole section would (pass it as that window's *carry*)

    bounds : :class:`PassBounds` or None — the brackets and tolerances of the pass's searches.  None
        takes them from this window's caps (:func:`_pass_bounds`, as a section planned whole does);
        windows that are to plan what the whole section would plan, to the bit, take the whole
        section's (any values bracket the searches correctly; only the last bits of their results
        depend on them; end_tol, the gap at rest taken as the end, is the section's by nature).
    carry : :class:`Handover` or None — None starts at t = 0 with no piece before, and the brake level
        of the start found afresh (a_floor at rest), checked (status 3 when no level certifies it).
    jerk_caps : (n − 1,) or None — the jerk each interval allows its steps (None: J everywhere).  J is then
        the least jerk of a braking manoeuvre, which must be at most every interval's: a state is certified
        by a manoeuvre at the smallest cap within the reach of the one at J (:func:`_brake_jerk`; at J where
        that one fails), and the steps take up to the cap where they are (every piece is checked against the
        caps it crosses, as its V and A are).

    Why the state at a commit point is safe for the next window
    ------------------------------------------------------------
    Every state the pass reaches is *safe*: certified by a brake level A_b (carry.ab_safe), the
    braking manoeuvre from it keeps every cap it meets and stops before this window's end.  The next
    window has the same caps up to this window's end (both are the section's caps; only the stop at
    the old end is gone, and the caps behind the old end are the section's own, not lowered for that
    stop) and its end lies beyond: so the same manoeuvre keeps the same caps and stops before the old
    end, hence before the new one.  The state is safe in the next window, certified by the same A_b,
    and safety is invariant along the pass.  Extending the horizon only removes a constraint.

    Why windows plan what the whole section plans
    ---------------------------------------------
    A decision of the pass at a state S (s < s_commit) tests steps of dt from S and the braking
    manoeuvres from their ends.  A step within the caps keeps V <= v_top, so it ends before
    s + v_top dt.  A manoeuvre from its end that keeps V <= v_top levels A off (from at most a_top)
    within v_top a_top / J, then stops within _stop_distance(v_top, 0, J, A_b), A_b >= a_floor: all
    within D = v_top a_top / J + _stop_distance(v_top, 0, J, a_floor), and so do the reaches that
    choose its brake level.  One that would raise V above v_top breaks a cap while A levels off, in
    the whole section and in any window alike (unsafe whatever its brake level).  When the window's
    end lies beyond s_commit + v_top dt + D, every test sees the same caps (the window's are the
    section's, shifted by the index of its first interval: the range minima and the splits at nodes
    are the same numbers) and no test reaches the end in either, so each has the same outcome.  At
    rest the pass may finish with one rest-to-rest move when no cap binds it (jerk J over the whole
    gap, which then is at most 2 (v_top^3/J)^(1/2)): a window whose end lies farther than that beyond
    s_commit never does before it, nor does the whole section.  With the same *bounds* and the *carry*
    of the window before (the time, the brake level and jerk, and the last piece, which a cruise extends), the
    committed rows are then the whole section's rows, to the bit (tests/test_jerk_window.py).
    Unproven corners, never met in the tests: a piece that ends behind its start by rounding across
    the window's first node, and a pass stalled at rest mid-section (no positive jerk safe, which
    needs a gap of rounding size to the end), would decide otherwise.
    """
    n = nodes.shape[0]
    s_end = nodes[n - 1]
    span = s_end - nodes[0]
    stol = 1e-13 * max(abs(s_end), span)
    if bounds is None:
        bd = _pass_bounds(nodes, caps, acaps)
    else:
        bd = bounds
    end_tol = bd.end_tol
    vtol = bd.vtol
    vtab, lg = _min_table(caps)
    atab = _min_table(acaps)[0]
    if jerk_caps is None:
        jcaps = np.full(caps.shape[0], J)
    else:
        jcaps = jerk_caps
    jtab = _min_table(jcaps)[0]
    a_floor = bd.a_floor
    a_top = bd.a_top
    v_top = bd.v_top
    out = np.empty((1024, 5))
    m = 0
    s = nodes[0]
    v = v0
    a = a0
    if carry is None:
        t = 0.0
        # the brake level that certifies the start: at rest any; in motion the one the pass would find
        # for it, if it does (the level the window before found under other bounds may differ: where a
        # level below −A leaves no manoeuvre at all, the search's test is not monotone), else the
        # highest of a ladder of levels that does
        Ab_safe = a_floor
        Jb_safe = J
        if v != 0.0 or a != 0.0:
            Ab_safe = _brake_level(nodes, acaps, atab, lg, a_floor, a_top, J, s, v, a)
            if not _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, Ab_safe, s, v, a, s_end, stol, vtol):
                Ab_safe = _certify(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, a_floor, a_top, s, v, a, s_end, stol, vtol)
                if Ab_safe != Ab_safe:  # the start cannot stop inside this window: not a state to go on from
                    out = _push(out, m, t, s, v, a, 0.0)
                    none = (math.nan, math.nan, math.nan, math.nan, math.nan)
                    return out[: m + 1], 3, (s, v, a), Handover(t, a_floor, J, none)
    else:
        t = carry.t
        Ab_safe = carry.ab_safe
        Jb_safe = carry.jb_safe
        if (Jb_safe > J and (v != 0.0 or a != 0.0)
                and not _safe(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, Jb_safe, Ab_safe, s, v, a, s_end, stol,
                              vtol)):
            # the jerk caps here may lie a hair under the last window's (the room motion.lookahead leaves for a
            # section end's snap grows with the window): certify the state afresh, as the window before would have
            # here; where nothing does, the carried manoeuvre still keeps the axes' own limits
            ok, Ab_new, Jb_new = _certified(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a,
                                            s_end, stol, vtol)
            if ok:
                Ab_safe = Ab_new
                Jb_safe = Jb_new
        # the last piece of the window before, where the first steps here may go on (a cruise extends
        # its row): held as row 0, which is not returned
        lt, ls, lv, la, lj = carry.last
        out = _push(out, m, lt, ls, lv, la, lj)
        m += 1
    first = m
    status = 1
    stalled = False
    for step in range(max_steps + 1):
        if s >= s_commit:
            status = 2
            break
        if v == 0.0 and a == 0.0:
            # At rest (the start, or the end of a braking manoeuvre short of the section end, where
            # the bisection's resolution leaves it): when the rest of the section is a single
            # rest-to-rest move that no cap limits, that move is time-optimal and lands exactly on
            # the end, so it finishes the section.  After a step that could not move at all (no
            # positive jerk was safe, down to the smallest double: a gap of rounding size) the move
            # is taken with the jerk lowered to fit the caps.
            gap = s_end - s
            if gap <= end_tol:
                status = 0
                break
            jc, jg = _creep_jerk(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, J, s, gap)
            if jc > 0.0 and (jc >= jg or stalled):
                tau = (gap / (2.0 * jc)) ** (1.0 / 3.0)
                for jj, d in ((jc, tau), (-jc, 2.0 * tau), (jc, tau)):
                    out = _push(out, m, t, s, v, a, jj)
                    m += 1
                    s, v, a = _advance(s, v, a, jj, d)
                    t += d
                v = 0.0
                a = 0.0
                status = 0
                break
        if step == max_steps:
            break
        # Cruise.  At a cap with A = 0 the feedrate is held (jerk 0) for as long as that is safe; and
        # an acceleration that can end on the cap within the step takes the jerk that lands there,
        # A = 0 just as V reaches the cap, then holds.  The largest constant jerk of a whole step
        # would overshoot into the opposite acceleration instead, and swing from −J to +J about the
        # cap from step to step (a chatter of ±J·dt in A).  The cap ahead, if lower, makes the
        # hold unsafe, and the steps below brake for it.
        cap = caps[_interval(nodes, s)]
        Jh = jcaps[_interval(nodes, s)]  # the steps' jerk here (J, the braking manoeuvres', is at most it)
        if v > 0.0 and a == 0.0 and v >= cap * (1.0 - CRUISE_RTOL):
            ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, 0.0, 0.0, dt, s_end,
                              stol, vtol)
            if ok:
                out, m, s = _hold(out, m, t, s, v, dt)
                t += dt
                Ab_safe = Ab
                Jb_safe = Jb
                continue
        elif a > 0.0 and v < cap - vtol and 2.0 * (cap - vtol - v) < a * dt:
            # the ramp from a to 0 that ends on the cap (less vtol) takes tau = 2 (cap − v) / a; a
            # state on the brake's frontier, V + A²/2J at the cap, may ask a hair more than J: the
            # ramp at J then ends within vtol of the cap
            tau = max(2.0 * (cap - vtol - v) / a, a / Jh)
            ok, Ab, Jb = _level_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, -a / tau, tau, dt,
                               s_end, stol, vtol)
            if ok:
                out = _push(out, m, t, s, v, a, -a / tau)
                m += 1
                s, v, _a = _advance(s, v, a, -a / tau, tau)
                a = 0.0
                out, m, s = _hold(out, m, t + tau, s, v, dt - tau)
                t += dt
                Ab_safe = Ab
                Jb_safe = Jb
                continue
        # the jerks worth trying: |A| within the caps here, V >= 0 at the end of the step
        ac = acaps[_interval(nodes, s)]
        jhi = min(Jh, (a_top - a) / dt)
        if coarse:  # no V above the largest cap at the end of the step: the bisection's range to scale
            jhi = min(jhi, max(2.0 * (v_top - v - a * dt) / (dt * dt), 0.0))
        jlo = max(-Jh, (-ac - a) / dt, -2.0 * (v + a * dt) / (dt * dt))
        if jlo > jhi:
            jlo = jhi
        j = math.nan
        ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, jhi, dt, s_end,
                          stol, vtol)
        if ok:
            j = jhi
        else:
            ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, jlo, dt, s_end,
                              stol, vtol)
            anchor = jlo
            if not ok and (coarse or ac < Jh * dt):
                # over a step long against the ramps (everywhere, or here, where the acceleration cap
                # is tiny: A/J below the step) the gentlest jerk ends at V = 0 with A < 0 or at
                # A = −cap with too little V left to ramp A back to 0, which is not safe; the jerk
                # that ends the step with A = 0 (cruising, from a steady state) may be.  Without it
                # the pass followed the brake to rest and crawled (issue 13: y max_accel 1 mm/s²)
                anchor = min(max(-a / dt, jlo), jhi)
                ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, anchor, dt, s_end,
                                  stol, vtol)
            if ok:
                lo = anchor
                hi = jhi
                Ab_lo = Ab
                Jb_lo = Jb
                for _b in range(BISECTIONS):
                    mid = 0.5 * (lo + hi)
                    ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, mid, dt, s_end,
                                      stol, vtol)
                    if ok:
                        lo = mid
                        Ab_lo = Ab
                        Jb_lo = Jb
                    else:
                        hi = mid
                if v == 0.0 and a == 0.0 and lo <= 0.0:
                    # at rest, a safe jerk may lie below the bisection's resolution (a tiny cap, as
                    # next to a zero-speed end): keep halving until one moves
                    for _b in range(1000):
                        hi = 0.5 * hi
                        if hi <= 0.0:
                            break
                        ok, Ab, Jb = _step_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, hi, dt,
                                          s_end, stol, vtol)
                        if ok:
                            lo = hi
                            Ab_lo = Ab
                            Jb_lo = Jb
                            break
                j = lo
                Ab = Ab_lo
                Jb = Jb_lo
        # Leveling off (A to 0 at full jerk, then V held) when no constant jerk is safe, and, where
        # dt is long against the ramps (coarse), also when it gets farther: there the largest safe
        # constant jerk overshoots into the opposite acceleration and the feedrate swings about
        # its cap from step to step.
        if v > 0.0 and a != 0.0 and abs(a) < Jh * dt:
            tau = abs(a) / Jh
            jj = -Jh if a > 0.0 else Jh
            s_lev = _advance(s, v, a, jj, tau)[0] + _advance(0.0, v, a, jj, tau)[1] * (dt - tau)
            if j != j or (coarse and s_lev > _advance(s, v, a, j, dt)[0]):
                ok, Ab_lev, Jb_lev = _level_ok(nodes, caps, acaps, vtab, atab, jcaps, jtab, lg, a_floor, a_top, J, s, v, a, jj, tau, dt,
                                       s_end, stol, vtol)
                if ok:
                    out = _push(out, m, t, s, v, a, jj)
                    m += 1
                    s, v, a = _advance(s, v, a, jj, tau)
                    out = _push(out, m, t + tau, s, v, 0.0, 0.0)
                    m += 1
                    s += v * (dt - tau)
                    a = 0.0
                    t += dt
                    Ab_safe = Ab_lev
                    Jb_safe = Jb_lev
                    continue
        if j == j:
            stalled = v == 0.0 and a == 0.0 and j <= 0.0
            if stalled:
                continue  # a step at rest that would not move: the move above takes over
            out = _push(out, m, t, s, v, a, j)
            m += 1
            s, v, a = _advance(s, v, a, j, dt)
            t += dt
            Ab_safe = Ab
            Jb_safe = Jb
            continue
        # no step is safe: follow the braking manoeuvre that certified the current state (the
        # rest of a safe manoeuvre is safe)
        t1, t2, t3, ap = _brake(v, a, Jb_safe, Ab_safe)
        if t1 < 0.0:
            t1 = 0.0
            t3 = max(-a, 0.0) / Jb_safe
            ap = max(-a, 0.0)
        left = dt
        for phase in range(3):
            dur = t1 if phase == 0 else (t2 if phase == 1 else t3)
            if dur <= 0.0 or left <= 0.0:
                continue
            jj = -Jb_safe if phase == 0 else (0.0 if phase == 1 else Jb_safe)
            if phase > 0:
                a = -ap
            d = min(dur, left)
            out = _push(out, m, t, s, v, a, jj)
            m += 1
            s, v, a = _advance(s, v, a, jj, d)
            t += d
            left -= d
        if t1 + t2 + t3 <= dt:  # at rest
            v = 0.0
            a = 0.0
            Ab_safe = a_floor
            Jb_safe = J
    out = _push(out, m, t, s, v, a, 0.0)
    if m > 0:
        last = (out[m - 1, 0], out[m - 1, 1], out[m - 1, 2], out[m - 1, 3], out[m - 1, 4])
    else:
        last = (math.nan, math.nan, math.nan, math.nan, math.nan)
    return out[first: m + 1], status, (s, v, a), Handover(t, Ab_safe, Jb_safe, last)


@njit(cache=True)
def _scan(nodes, caps, acc):
    """Bidirectional scan without a jerk limit: V at the nodes (0 at both ends)."""
    n = nodes.shape[0]
    v = np.empty(n)
    v[0] = 0.0
    for k in range(n - 1):
        w = 0.0 if k + 1 == n - 1 else min(caps[k], caps[k + 1])
        v[k + 1] = min(w, math.sqrt(v[k] * v[k] + 2.0 * acc[k] * (nodes[k + 1] - nodes[k])))
    v[n - 1] = 0.0
    for k in range(n - 2, -1, -1):
        v[k] = min(v[k], math.sqrt(v[k + 1] * v[k + 1] + 2.0 * acc[k] * (nodes[k + 1] - nodes[k])))
    return v



# --------------------------------------------------------------------------- sums over a section, without its arrays
#
# The motion-time estimates (plan._time_estimate) sum a value per interval of a section.  Held as numpy
# arrays (the interval times, their differences, the runs...) they took some 60 bytes per grid point at
# once; these kernels write the times over the scan's feedrates, the only array they keep.  They sum
# exactly as ndarray.sum() does on a float64 vector — numpy's pairwise summation: 8 interleaved partial
# sums in blocks of at most 128 values, blocks halved at multiples of 8, the result added to the identity
# 0 — so the estimates, and the step of the jerk-limited pass chosen from them, stay what they were to the
# bit (tests/test_planner.py checks the sums against numpy's on random vectors).  The halving runs on an
# explicit stack: numba's cache cannot hold a recursive kernel.

PAIRWISE_BLOCK = 128  # numpy's PW_BLOCKSIZE


@njit(cache=True)
def _pairwise_block(a, lo, n):
    """Sum of a[lo : lo + n], n <= PAIRWISE_BLOCK, as numpy's pairwise_sum sums one block."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += a[lo + i]
        return res
    r0, r1, r2, r3 = a[lo], a[lo + 1], a[lo + 2], a[lo + 3]
    r4, r5, r6, r7 = a[lo + 4], a[lo + 5], a[lo + 6], a[lo + 7]
    i = 8
    while i < n - n % 8:
        r0 += a[lo + i]
        r1 += a[lo + i + 1]
        r2 += a[lo + i + 2]
        r3 += a[lo + i + 3]
        r4 += a[lo + i + 4]
        r5 += a[lo + i + 5]
        r6 += a[lo + i + 6]
        r7 += a[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += a[lo + i]
        i += 1
    return res


@njit(cache=True)
def _sum(a, n):
    """a[:n].sum() of a float64 vector, to the bit: the halving (left half, then right, then their sum) on a stack."""
    if n <= PAIRWISE_BLOCK:
        return 0.0 + _pairwise_block(a, 0, n)
    los = np.empty(64, dtype=np.int64)  # frames: range [lo, lo + n), and how far it got (0, 1, 2 halves done)
    ns = np.empty(64, dtype=np.int64)
    stage = np.empty(64, dtype=np.int64)
    sums = np.empty(64)
    top = 0
    los[0], ns[0], stage[0] = 0, n, 0
    depth = 0  # partial sums on the stack
    while top >= 0:
        lo, m = los[top], ns[top]
        if m <= PAIRWISE_BLOCK:
            sums[depth] = _pairwise_block(a, lo, m)
            depth += 1
            top -= 1
            continue
        half = m // 2
        half -= half % 8
        if stage[top] == 0:
            stage[top] = 1
            top += 1
            los[top], ns[top], stage[top] = lo, half, 0
        elif stage[top] == 1:
            stage[top] = 2
            top += 1
            los[top], ns[top], stage[top] = lo + half, m - half, 0
        else:
            depth -= 1
            sums[depth - 1] = sums[depth - 1] + sums[depth]
            top -= 1
    return 0.0 + sums[0]


@njit(cache=True, error_model="numpy")
def _times_over(v, nodes, caps, acc):
    """The time (s) of each interval of the acceleration-limited optimum v (the scan's feedrates at the nodes),
    written over v[:-1]: V² linear in s, 2Δs / (v_k + v_k+1); with V = 0 at both ends (a section of one
    interval), its cap plus the ramps."""
    for k in range(nodes.shape[0] - 1):
        ds = nodes[k + 1] - nodes[k]
        vs = v[k] + v[k + 1]
        v[k] = 2.0 * ds / vs if vs > 0 else ds / caps[k] + 2.0 * caps[k] / acc[k]


@njit(cache=True, error_model="numpy")
def _optimum_time(nodes, caps, acc):
    """Motion time (s) of the acceleration-limited optimum of a section (the scan): Σ of its interval times."""
    v = _scan(nodes, caps, acc)
    _times_over(v, nodes, caps, acc)
    return _sum(v, nodes.shape[0] - 1)


@njit(cache=True)
def _sign(x):
    if x > 0.0:
        return 1.0
    if x < 0.0:
        return -1.0
    return x  # 0, or NaN


@njit(cache=True, error_model="numpy")
def _estimate_sums(nodes, caps, acc, ramp_top, J):
    """The sums of plan._time_estimate: (Σ interval times of the optimum, whether its feedrate changes at all,
    Σ over the monotone runs of the feedrate of min(ramp_top, √(Δv_run / J))).

    A run is a maximal sequence of nonzero changes of v between nodes of one sign (as np.sign takes
    it); its Δv is the sum of their magnitudes in order, from 0 (as np.bincount adds them).
    """
    v = _scan(nodes, caps, acc)
    n = nodes.shape[0]
    runs = 0
    last = 0.0
    for k in range(n - 1):
        d = v[k + 1] - v[k]
        if d != 0.0:
            sg = _sign(d)
            if runs == 0 or sg != last:
                runs += 1
            last = sg
    dv = np.zeros(runs)
    r = -1
    for k in range(n - 1):
        d = v[k + 1] - v[k]
        if d != 0.0:
            sg = _sign(d)
            if r < 0 or sg != last:
                r += 1
            last = sg
            dv[r] += abs(d)
    for r in range(runs):
        x = math.sqrt(dv[r] / J)
        dv[r] = ramp_top if (ramp_top < x or ramp_top != ramp_top) else x  # np.minimum(ramp_top, x)
    _times_over(v, nodes, caps, acc)
    return _sum(v, n - 1), runs > 0, _sum(dv, runs)
