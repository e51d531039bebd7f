"""Per-axis jerk on a path of segments: the caps that hold it, beside the tangential jerk the windowed pass holds.

An axis' position along the path is x_i(s(t)), so its jerk is

    x_i''' = τ_i J + 3 x_ss,i V A + x_sss,i V³

(τ = x_s the unit tangent, x_ss the curvature vector κn, x_sss its derivative
along s; V, A, J the feedrate and its derivatives).  Each axis' budget j_i is
split by *shares* (motion.limits.JERK_SHARES):

- the tangential part τ_i J: the windowed pass takes, along each segment, the
  jerk its JCAP allows (each axis' budget less the segment's normal part at its
  caps, over its largest |τ_i|: a line along x may ramp at j_x), and never less
  than the first share of min_i j_i; its braking manoeuvres take the smallest
  JCAP within their reach (planner.jerk._jerk_window's jerk_caps);
- the normal part inside a segment takes the rest, V³ max|x_sss,i| <= the
  second share of j_i capping V (VCAP), and 3 V max|x_ss,i| |A| <= the third
  capping |A| (ACAP, with V at VCAP: conservative while V ramps up, the pass's
  caps being constant along a segment);
- a joint where something jumps takes, on each axis, what the rows beside it
  leave: j_i less |τ_i| JCAP of either (their own caps kept); or, where that
  passes it slower, the normal share of j_i, the rows beside it keeping what
  the jump leaves at that speed (at least the first share; on the raster of
  benchmarks/cam.py the curvature of z jumps where a refitted row meets its
  last move, and the rows beside keep 0.9 of j_x where the share alone would
  leave them half).  Where the
  curvature vector jumps (a line into its blend, an arc's end), the
  acceleration jumps by V² Δx_ss,i, and the stream's third difference
  across that tick is at most 0.75 of the jump over T (the jump's quadratic,
  differenced: ½(1 + 2x − 2x²) at the tick's fraction x); where the direction
  jumps (a joint passed unblended) the velocity jumps by V Δτ_i, whose third
  difference is at most V |Δτ_i| / T², and the tangential acceleration A
  turns with it (0.75 |A| |Δτ_i| / T).  Those, and the larger of the two rows'
  normal parts at the feedrate three ticks can reach from the joint's, within
  what the rows beside it leave of j_i (or the normal part of j_i, as above)
  cap the joint's feedrate (NODECAP, by bisection).
- joints closer in time than three ticks (a row shorter than that at its
  speed cap between them: LHchips4.ngc has lines of 0.1 µm between two
  blends that turn opposite ways) fall in one third difference together, so
  a joint's cap counts the jumps of those before it too, each weighted by the
  most it can weigh where it lies at the speed tried (:func:`_rows_beside`),
  and the rows from the one before the earliest of them count as beside it.
  The pipeline holds those rows back until the next batch's first joint is
  done (:func:`chain_start`).

The stream's third difference over three ticks is a weighted mean of x_i'''
over them (a B-spline kernel of weights summing to 1), plus the jumps': so it
stays within j_i wherever these caps hold.

Inside a curve row (a cubic Bézier B(w), σ = |B'|), with σ' = B'·B''/σ and
σ'' = (|B''|² + B'·B''' − σ'²)/σ:

    x_ss  = B''/σ² − B' σ'/σ³
    x_sss = B'''/σ³ − 3 B'' σ'/σ⁴ − B' σ''/σ⁴ + 3 B' σ'²/σ⁵

bounded on equal parts of the row (QUARTERS) by the Bernstein coefficients of
their numerators, over σ from below (:func:`_curve_part_bounds`).
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from . import segments as seg

STEP_JUMP = seg.STEP_JUMP  # the largest third difference of an acceleration step of 1 over one tick, times T
CHAIN_TICKS = 3.0  # a third difference spans three ticks: the jumps of joints closer in time than that add up
QUARTERS = 4  # a curve row's bounds are taken on this many equal parts of its parameter, and halved from there
BOUND_SLACK = 0.05  # ... until within this of the values at their sample points
BOUND_DEPTH = 6  # ... at most this many times


@njit(cache=True)
def _arc_state(row, th, tang, curv):
    """Unit tangent and curvature vector x_ss of an arc row at the angle th from its start."""
    R = row[seg.RADIUS]
    h = row[seg.RISE] / row[seg.SWEEP]
    ell2 = R * R + h * h
    ell = math.sqrt(ell2)
    c = math.cos(th)
    s = math.sin(th)
    for i in range(3):
        tang[i] = (R * (-s * row[seg.D + i] + c * row[seg.E + i]) + h * row[seg.NRM + i]) / ell
        curv[i] = -R / ell2 * (c * row[seg.D + i] + s * row[seg.E + i])


@njit(cache=True)
def _curve_state(row, w, tang, curv):
    """Unit tangent and curvature vector x_ss of a curve row at its Bézier parameter w."""
    d1 = np.empty(3)
    d2 = np.empty(3)
    seg._bezier_d1(row, w, d1)
    seg._bezier_d2(row, w, d2)
    s2 = d1[0] * d1[0] + d1[1] * d1[1] + d1[2] * d1[2]
    sp = math.sqrt(s2)
    dot = d1[0] * d2[0] + d1[1] * d2[1] + d1[2] * d2[2]
    for i in range(3):
        tang[i] = d1[i] / sp
        curv[i] = (d2[i] * s2 - d1[i] * dot) / (s2 * s2)


@njit(cache=True)
def row_ends(row, ts, ks, te, ke):
    """Unit tangent and curvature vector at the row's start (ts, ks) and end (te, ke)."""
    kind = row[seg.KIND]
    if kind == seg.LINE:
        for i in range(3):
            ts[i] = row[seg.D + i]
            te[i] = row[seg.D + i]
            ks[i] = 0.0
            ke[i] = 0.0
    elif kind == seg.ARC:
        _arc_state(row, 0.0, ts, ks)
        _arc_state(row, row[seg.SWEEP], te, ke)
    else:
        _curve_state(row, 0.0, ts, ks)
        _curve_state(row, 1.0, te, ke)


_BERN5 = seg._bernstein_inverse(5)
_BERN8 = seg._bernstein_inverse(8)


@njit(cache=True)
def _bernstein_absmax(inverse, values, i):
    """The largest |Bernstein coefficient| of a polynomial from its values (column i) at equispaced points."""
    m = 0.0
    for j in range(inverse.shape[0]):
        c = 0.0
        for q in range(inverse.shape[0]):
            c += inverse[j, q] * values[q, i]
        m = max(m, abs(c))
    return m


@njit(cache=True)
def _curve_part_bounds(row, lo, hi, x2, x3, seen):
    """Bounds of |x_ss,i| and |x_sss,i| over w in [lo, hi] of a curve row into x2, x3, and their values' largest
    at the points the bounds are taken from into seen (6,); False where |B'| has no positive bound from below
    there (a cusp).

    With g = |B'|², p = B'·B'', q = |B''|² + B'·B''' (derivatives in any one parameter):
    x_ss = (B'' g − B' p) / σ⁴, a polynomial of degree 5 over σ⁴, and
    x_sss = (B''' g² − 3 B'' p g − B' q g + 4 B' p²) / σ⁷, of degree 8 over σ⁷.  The largest of their
    numerators' Bernstein coefficients (from their values at 6 and 9 points of the part) over σ_min to those
    powers bound them; σ_min along B' at the part's middle, from the hodograph's Bernstein hull."""
    d1 = np.empty((9, 3))
    d2 = np.empty((9, 3))
    for q in range(9):
        w = lo + (hi - lo) * q / 8.0
        seg._bezier_d1(row, w, d1[q])
        seg._bezier_d2(row, w, d2[q])
    top = 0.0
    for q in range(9):
        top = max(top, math.sqrt(d1[q, 0] ** 2 + d1[q, 1] ** 2 + d1[q, 2] ** 2))
    if not top > 0.0:
        return False
    # the parameter u = w / sc, sc = 1 / max|B'|, so that |B'| ~ 1 (x_ss and x_sss do not depend on the
    # parameter): no under- or overflow in σ⁷ on a row of 1e-9 mm
    sc = 1.0 / top
    b3 = np.empty(3)
    for i in range(3):
        b3[i] = 6.0 * (row[seg.B3 + i] - 3.0 * row[seg.B2 + i] + 3.0 * row[seg.B1 + i] - row[seg.B0 + i]) * sc ** 3
        for q in range(9):
            d1[q, i] *= sc
            d2[q, i] *= sc * sc
    # σ from below: the hodograph (a quadratic over the part) against its direction at the middle
    mn = math.sqrt(d1[4, 0] ** 2 + d1[4, 1] ** 2 + d1[4, 2] ** 2)
    if not mn > 0.0:
        return False
    sig = math.inf
    for j in range(3):
        dot = 0.0
        for i in range(3):
            h = d1[0, i] if j == 0 else (d1[8, i] if j == 2 else 2.0 * d1[4, i] - 0.5 * (d1[0, i] + d1[8, i]))
            dot += h * d1[4, i]
        sig = min(sig, dot / mn)
    if not sig > 1e-9:
        return False
    n8 = np.empty((9, 3))
    for q in range(9):
        g = d1[q, 0] ** 2 + d1[q, 1] ** 2 + d1[q, 2] ** 2
        pp = d1[q, 0] * d2[q, 0] + d1[q, 1] * d2[q, 1] + d1[q, 2] * d2[q, 2]
        qq = d2[q, 0] ** 2 + d2[q, 1] ** 2 + d2[q, 2] ** 2 + d1[q, 0] * b3[0] + d1[q, 1] * b3[1] + d1[q, 2] * b3[2]
        for i in range(3):
            n8[q, i] = b3[i] * g * g - 3.0 * d2[q, i] * pp * g - d1[q, i] * qq * g + 4.0 * d1[q, i] * pp * pp
    n5 = np.empty((6, 3))
    e1 = np.empty(3)
    e2 = np.empty(3)
    for q in range(6):
        w = lo + (hi - lo) * q / 5.0
        seg._bezier_d1(row, w, e1)
        seg._bezier_d2(row, w, e2)
        g = 0.0
        pp = 0.0
        for i in range(3):
            e1[i] *= sc
            e2[i] *= sc * sc
            g += e1[i] * e1[i]
            pp += e1[i] * e2[i]
        for i in range(3):
            n5[q, i] = e2[i] * g - e1[i] * pp
    s4 = sig ** 4
    s7 = sig ** 7
    for i in range(3):
        seen[i] = 0.0
        seen[3 + i] = 0.0
        for q in range(9):
            g = d1[q, 0] ** 2 + d1[q, 1] ** 2 + d1[q, 2] ** 2
            seen[3 + i] = max(seen[3 + i], abs(n8[q, i]) / g ** 3.5)
        x2[i] = _bernstein_absmax(_BERN5, n5, i) / s4
        x3[i] = _bernstein_absmax(_BERN8, n8, i) / s7
    for q in range(6):
        w = lo + (hi - lo) * q / 5.0
        seg._bezier_d1(row, w, e1)
        g = (e1[0] ** 2 + e1[1] ** 2 + e1[2] ** 2) * sc * sc
        for i in range(3):
            seen[i] = max(seen[i], abs(n5[q, i]) / (g * g))
    return True


@njit(cache=True)
def _row_bounds(row, x2, x3):
    """Bounds over the row of |x_ss,i| (x2) and |x_sss,i| (x3); inf where a curve row bounds nothing."""
    for i in range(3):
        x2[i] = 0.0
        x3[i] = 0.0
    kind = row[seg.KIND]
    if kind == seg.LINE:
        return
    if kind == seg.ARC:
        R = row[seg.RADIUS]
        phi = row[seg.SWEEP]
        h = row[seg.RISE] / phi
        ell2 = R * R + h * h
        ell = math.sqrt(ell2)
        for i in range(3):
            # x_ss,i = −R/ℓ² (cos θ e1_i + sin θ e2_i); x_sss,i = R/ℓ³ (sin θ e1_i − cos θ e2_i)
            x2[i] = R / ell2 * seg.trig_absmax(-row[seg.D + i], -row[seg.E + i], 0.0, phi)
            x3[i] = R / (ell2 * ell) * seg.trig_absmax(-row[seg.E + i], row[seg.D + i], 0.0, phi)
        return
    # parts whose bounds exceed the values sampled on them by more than BOUND_SLACK are halved (as
    # segments.curve_bounds does), up to BOUND_DEPTH times: the bounds converge to the maxima as parts shrink
    b2 = np.empty(3)
    b3 = np.empty(3)
    seen = np.empty(6)
    stack_lo = np.empty(QUARTERS + 2 * BOUND_DEPTH + 2)
    stack_hi = np.empty(QUARTERS + 2 * BOUND_DEPTH + 2)
    stack_d = np.empty(QUARTERS + 2 * BOUND_DEPTH + 2, dtype=np.int64)
    top = 0
    for q in range(QUARTERS - 1, -1, -1):
        stack_lo[top] = q / QUARTERS
        stack_hi[top] = (q + 1) / QUARTERS
        stack_d[top] = 0
        top += 1
    while top > 0:
        top -= 1
        lo = stack_lo[top]
        hi = stack_hi[top]
        depth = stack_d[top]
        if not _curve_part_bounds(row, lo, hi, b2, b3, seen):
            if depth >= BOUND_DEPTH:
                for i in range(3):
                    x2[i] = math.inf
                    x3[i] = math.inf
                return
            good = False
        else:
            good = depth >= BOUND_DEPTH
            if not good:
                good = True
                for i in range(3):
                    if not (b2[i] <= seen[i] * (1.0 + BOUND_SLACK) + 1e-12 * b2.max()
                            and b3[i] <= seen[3 + i] * (1.0 + BOUND_SLACK) + 1e-12 * b3.max()):
                        good = False
        if good:
            for i in range(3):
                x2[i] = max(x2[i], b2[i])
                x3[i] = max(x3[i], b3[i])
        else:
            top = seg.push_halves(stack_lo, stack_hi, stack_d, top, lo, hi, depth)


@njit(cache=True)
def _normal_jerk(v, acap, x2, x3, i, period):
    """The largest normal part of axis i's jerk on a row (bounds x2, x3) within three ticks of a point passed at v:
    the feedrate there at most v + 3 T |A|."""
    vc = v + 3.0 * period * acap
    return vc * vc * vc * x3[i] + 3.0 * vc * acap * x2[i]


# the rows beside a joint (motion.jerk.jerk_caps' *beside*): one line per row, from the row before the joint
# back, each with the joint at its end (none on the first line: that is the joint being capped)
B_TIME = 0  # the least time from that joint to the one capped (the rows between at their speed caps)
B_DIST = 1  # the path length between them
B_PASS = 2  # the fastest that joint can be passed (its node cap, and the rows' beside it)
B_AMAX = 3  # the largest ACAP of the rows from this one to the joint capped
B_ROW = 4  # the row's index in the batch
B_ACAP = 5  # the row's ACAP
B_KINK = 6  # 6:9 the joint's |Δτ_i| / T²
B_STEP = 9  # 9:12 the joint's |Δx_ss,i| / T
B_X2 = 12  # 12:15 the row's bounds of |x_ss,i|
B_X3 = 15  # 15:18 ... and of |x_sss,i|
B_TJ = 18  # 18:21 the row's |τ_i| JCAP
B_TAU = 21  # 21:24 the row's largest |τ_i|
B_NCOL = 24
BESIDE = 32  # rows kept apart in *beside*; those further back merge into the last, at its (closest) time


@njit(cache=True)
def _step_weight(y):
    """The largest weight of an acceleration step in a third difference, over its positions in [0, y] of the
    three ticks: y²/2 up to 1, 0.75 − (y − 1.5)² up to 1.5, 0.75 (STEP_JUMP) beyond."""
    if y <= 0.0:
        return 0.0
    if y <= 1.0:
        return 0.5 * y * y
    if y <= 1.5:
        return STEP_JUMP - (y - 1.5) ** 2
    return STEP_JUMP


@njit(cache=True)
def _kink_speed(v, acap, period):
    """The most a kink's third difference can reach, over |Δτ_i| / T², passed at v with |A| <= acap: the velocity
    jumps by V Δτ_i (a weight in [−1, 1] over the three ticks) and the acceleration by A Δτ_i (a weight in
    [0, 0.75]), their sum at most v + 0.5 |A| T (the weights 1 and 0.5 two ticks in) once v >= 0.5 |A| T, and
    v² / (|A| T) + 0.75 |A| T below (the sum's peak inside the middle tick)."""
    at = acap * period
    if not at > 0.0:
        return v
    if v >= 0.5 * at:
        return v + 0.5 * at
    return v * v / at + STEP_JUMP * at


@njit(cache=True)
def _reached(v, beside, m, period):
    """How far into three ticks before a joint passed at v the joint at the end of beside[m] can lie (in ticks;
    <= 0: not within them): at least its least time there, and its distance over the fastest within three ticks
    of v."""
    reach = v + CHAIN_TICKS * period * beside[m, B_AMAX]
    d = beside[m, B_DIST]
    far = d / reach if reach > 0.0 else (0.0 if d == 0.0 else math.inf)
    return CHAIN_TICKS - max(beside[m, B_TIME], far) / period


@njit(cache=True)
def _joint_jerk(v, i, p, q, acap, x2, x3, tj, beside, n, mode, period, jtop):
    """Axis i's jerk across a joint passed at v: its jumps (p :func:`_kink_speed` + q V²: a kink turns the
    tangential acceleration A too, |A| <= √(2 jtop V) and the rows' ACAP), those of the joints within three ticks before it (weighted by the most
    they can weigh where they lie, at the fastest they can be passed there); *mode* >= 1: with the largest normal
    part of the rows beside within three ticks (of the row after it: *acap*, *x2*, *x3*); 2: and their largest
    |τ_i| JCAP (the row after it's: *tj*)."""
    T = period
    amax = max(acap, beside[0, B_ACAP])
    total = p * _kink_speed(v, min(amax, math.sqrt(2.0 * jtop * v)), T) + q * v * v
    normal = 0.0
    tangential = 0.0
    if mode >= 1:
        normal = max(_normal_jerk(v, acap, x2, x3, i, T),
                     _normal_jerk(v, beside[0, B_ACAP], beside[0, B_X2:B_X2 + 3], beside[0, B_X3:B_X3 + 3], i, T))
    if mode >= 2:
        tangential = max(tj, beside[0, B_TJ + i])
    for m in range(1, n):
        y = _reached(v, beside, m, T)
        if not y > 0.0:
            break
        a_m = max(amax, beside[m, B_AMAX])
        vr = min(v + CHAIN_TICKS * T * a_m, beside[m, B_PASS])
        if vr > 0.0:  # (a joint passed at rest jumps by nothing: the pass reaches rest with A = 0)
            a_r = min(a_m, math.sqrt(2.0 * jtop * vr))
            total += (min(1.0, y) * beside[m, B_KINK + i] * vr + _step_weight(y) * beside[m, B_KINK + i] * T * a_r
                      + _step_weight(y) * beside[m, B_STEP + i] * vr * vr)
        if mode >= 1:
            # the row's own |A| <= its ACAP, at the fastest the rows between let it be passed
            vc = v + CHAIN_TICKS * T * a_m
            normal = max(normal, vc * vc * vc * beside[m, B_X3 + i]
                         + 3.0 * vc * beside[m, B_ACAP] * beside[m, B_X2 + i])
        if mode >= 2:
            tangential = max(tangential, beside[m, B_TJ + i])
    return total + normal + tangential


@njit(cache=True)
def _joint_cap(hi, budget, shared, mode, p, q, acap, x2, x3, tj, beside, n, period, jtop):
    """The largest feedrate <= hi at which a joint (:func:`_joint_jerk` in *mode*) keeps every axis' jerk within
    *budget* (3,), by bisection (0 where a budget is not positive); an axis whose jumps at hi are within 1e-9 of
    its normal share *shared* jumps by nothing."""
    node = hi
    for i in range(3):
        if not (_joint_jerk(hi, i, p[i], q[i], acap, x2, x3, tj[i], beside, n, 0, period, jtop) > 1e-9 * shared[i]):
            continue
        if budget[i] <= 0.0:
            return 0.0
        if _joint_jerk(node, i, p[i], q[i], acap, x2, x3, tj[i], beside, n, mode, period, jtop) > budget[i]:
            lo = 0.0
            up = node
            for _ in range(60):
                mid = 0.5 * (lo + up)
                if _joint_jerk(mid, i, p[i], q[i], acap, x2, x3, tj[i], beside, n, mode, period, jtop) > budget[i]:
                    up = mid
                else:
                    lo = mid
            node = lo
    return node


@njit(cache=True)
def _tangential(tau, jcap):
    """An axis' tangential part |τ_i| JCAP of a row: 0 where the row does not move the axis (its JCAP may be inf,
    where it moves only axes without a jerk limit)."""
    return tau * jcap if tau > 0.0 else 0.0


@njit(cache=True)
def _ticks_before(row):
    """The least time a row takes, in s (its length over its speed cap; inf where it has no positive cap)."""
    v = row[seg.VCAP]
    if not (v > 0.0 and v < math.inf):
        return math.inf
    return row[seg.LEN] / v


@njit(cache=True)
def _rows_beside(rows, r, hi, prev, period, beside, scratch):
    """Fill *beside* with the rows before the joint at rows[r]'s start that lie within three ticks of it passed
    at hi (or slower), and the joints between them (their jumps add to its own in the stream's third difference:
    LHchips4.ngc has lines of 0.1 µm between blends turning opposite ways); rows[r − 1] first, its bounds from
    *prev*.  Returns how many.  Needs rows from the first of them on: the pipeline holds them back
    (:func:`chain_start`)."""
    ts = scratch[0]
    ks = scratch[1]
    te = scratch[2]
    ke = scratch[3]
    tau = scratch[4]
    T = period
    beside[0, :] = 0.0
    beside[0, B_ROW] = r - 1
    beside[0, B_ACAP] = prev[12]
    beside[0, B_AMAX] = prev[12]
    _tangent_bounds(rows[r - 1], tau)
    for i in range(3):
        beside[0, B_X2 + i] = prev[6 + i]
        beside[0, B_X3 + i] = prev[9 + i]
        beside[0, B_TAU + i] = tau[i]
        beside[0, B_TJ + i] = _tangential(tau[i], rows[r - 1, seg.JCAP])
    n = 1
    t = 0.0
    d = 0.0
    amax = prev[12]
    k = r - 1
    while k >= 1:
        t += _ticks_before(rows[k])
        d += rows[k, seg.LEN]
        amax = max(amax, rows[k - 1, seg.ACAP])
        if not (t < CHAIN_TICKS * T and d < CHAIN_TICKS * T * (hi + CHAIN_TICKS * T * amax)):
            break
        # the joint at rows[k]'s start lies within three ticks before this one, and rows[k − 1] beside it
        m = n if n < BESIDE else BESIDE - 1
        if m == n:
            beside[m, :] = 0.0
            beside[m, B_TIME] = t
            beside[m, B_DIST] = d
            n += 1
        row_ends(rows[k - 1], ts, ks, te, ke)
        row_ends(rows[k], ts, ks, tau, tau)
        beside[m, B_PASS] = max(beside[m, B_PASS], min(rows[k, seg.NODECAP], rows[k, seg.VCAP],
                                                       rows[k - 1, seg.VCAP]))
        beside[m, B_AMAX] = amax
        beside[m, B_ROW] = k - 1
        beside[m, B_ACAP] = max(beside[m, B_ACAP], rows[k - 1, seg.ACAP])
        for i in range(3):
            beside[m, B_KINK + i] += abs(ts[i] - te[i]) / (T * T)
            beside[m, B_STEP + i] += abs(ks[i] - ke[i]) / T
        _row_bounds(rows[k - 1], ts, ks)
        _tangent_bounds(rows[k - 1], tau)
        for i in range(3):
            beside[m, B_X2 + i] = max(beside[m, B_X2 + i], ts[i])
            beside[m, B_X3 + i] = max(beside[m, B_X3 + i], ks[i])
            beside[m, B_TAU + i] = max(beside[m, B_TAU + i], tau[i])
            beside[m, B_TJ + i] = max(beside[m, B_TJ + i], _tangential(tau[i], rows[k - 1, seg.JCAP]))
        k -= 1
    return n


@njit(cache=True)
def chain_start(rows, period):
    """The first of the rows a batch must keep back for the next one's first joint (motion.pipeline): the last
    row, and every row before a joint within three ticks of the batch's end (:func:`_rows_beside`)."""
    k = rows.shape[0] - 1
    t = 0.0
    while k >= 1:
        t += _ticks_before(rows[k])
        if not t < CHAIN_TICKS * period:
            break
        k -= 1
    return max(k, 0)


@njit(cache=True)
def _tangent_bounds(row, out):
    """Bounds of |τ_i| over the row into out (3,): a line's direction, an arc's largest over its sweep; on a
    curve the largest |B'_i| over |B'| from below, from the hodograph's Bernstein hull (B' = Σ h_j b_j,2 with
    h_j = 3 (B_j+1 − B_j): |B'_i| <= max |h_j,i|, and |B'| >= B'·m >= min h_j·m for m the unit tangent at the
    middle), at most 1.  A refitted row along x keeps |τ_z| at its slope, so z's budget does not bound the jerk
    along it."""
    kind = row[seg.KIND]
    if kind == seg.LINE:
        for i in range(3):
            out[i] = abs(row[seg.D + i])
    elif kind == seg.ARC:
        R = row[seg.RADIUS]
        phi = row[seg.SWEEP]
        h = row[seg.RISE] / phi
        ell = math.sqrt(R * R + h * h)
        for i in range(3):
            out[i] = seg.trig_absmax(R * row[seg.E + i] / ell, -R * row[seg.D + i] / ell, h * row[seg.NRM + i] / ell,
                                     phi)
    else:
        for i in range(3):
            out[i] = 1.0
        h = np.empty((3, 3))
        m = np.empty(3)
        for i in range(3):
            h[0, i] = 3.0 * (row[seg.B1 + i] - row[seg.B0 + i])
            h[1, i] = 3.0 * (row[seg.B2 + i] - row[seg.B1 + i])
            h[2, i] = 3.0 * (row[seg.B3 + i] - row[seg.B2 + i])
            m[i] = 0.25 * (h[0, i] + 2.0 * h[1, i] + h[2, i])
        mn = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
        if not mn > 0.0:
            return
        sig = math.inf
        for j in range(3):
            sig = min(sig, (h[j, 0] * m[0] + h[j, 1] * m[1] + h[j, 2] * m[2]) / mn)
        if not sig > 0.0:
            return
        for i in range(3):
            out[i] = min(1.0, max(abs(h[0, i]), abs(h[1, i]), abs(h[2, i])) / sig)


@njit(cache=True)
def jerk_caps(rows, axis_jerk, period, shares, prev, first, jtop):
    """Lower the rows' VCAP, ACAP and NODECAP and set their JCAP (in place) so that each axis' jerk stays within
    *axis_jerk* (see the module's docstring), from rows[first] on (rows[0] may be the last row of the batch before,
    done already but for its JCAP, which its end joint decides).

    *shares* (3,): the tangential, speed and acceleration shares of each axis' budget.  *prev* (13,): the unit
    tangent, curvature vector, bounds of |x_ss,i| and |x_sss,i| at the end of the row before rows[first], and its
    ACAP (NaN: none, the program's start), updated to the last row's.  Where *prev* is set, that row must be
    rows[first − 1] (first >= 1: the pipeline holds it back for this), whose JCAP its end joint may lower.
    *jtop*: the most jerk the pass takes along the path (lookahead.JerkWindow's jerk_top): at a feedrate V it
    carries at most |A| = √(2 jtop V) (less could not have come from rest, or reach rest, or turn round), which
    bounds the acceleration a kink turns there.

    JCAP: each axis' budget less the row's normal part at its caps, over its largest |τ_i|.  A joint where
    something jumps fits in what the rows beside it leave (their JCAP kept), or, where that passes it slower, in
    the normal share, the rows beside it keeping what the jump leaves at that speed (at least the first share)."""
    ts = np.empty(3)
    ks = np.empty(3)
    te = np.empty(3)
    ke = np.empty(3)
    x2 = np.empty(3)
    x3 = np.empty(3)
    tau = np.empty(3)
    pj = np.empty(3)
    qj = np.empty(3)
    beside = np.empty((BESIDE, B_NCOL))
    scratch = np.empty((5, 3))  # _rows_beside's, allocated once
    shared = np.empty(3)
    left = np.empty(3)
    T = period
    normal = 1.0 - shares[0]
    floor = math.inf
    for i in range(3):
        floor = min(floor, shares[0] * axis_jerk[i])
    for r in range(first, rows.shape[0]):
        row = rows[r]
        row_ends(row, ts, ks, te, ke)
        _row_bounds(row, x2, x3)
        _tangent_bounds(row, tau)
        v = row[seg.VCAP]
        for i in range(3):
            if x3[i] > 0.0:
                v = min(v, (shares[1] * axis_jerk[i] / x3[i]) ** (1.0 / 3.0))
        a = row[seg.ACAP]
        for i in range(3):
            if x2[i] > 0.0 and v > 0.0:
                a = min(a, shares[2] * axis_jerk[i] / (3.0 * v * x2[i]))
        row[seg.VCAP] = v
        row[seg.ACAP] = a
        jcap = math.inf
        for i in range(3):
            if tau[i] > 0.0:
                jcap = min(jcap, (axis_jerk[i] - _normal_jerk(v, a, x2, x3, i, 0.0)) / tau[i])
        row[seg.JCAP] = max(jcap, floor)
        if prev[0] == prev[0]:
            # the joint: V |Δτ_i| / T² + 0.75 V² |Δx_ss,i| / T, with those of the joints within three ticks before
            # it (a short row between), and the rows' normal parts within three ticks of it, within what the
            # tangential parts beside it leave (where nothing jumps, the rows' own caps hold it)
            for i in range(3):
                pj[i] = abs(ts[i] - prev[i]) / (T * T)
                qj[i] = STEP_JUMP * abs(ks[i] - prev[3 + i]) / T
                shared[i] = normal * axis_jerk[i]
            node = row[seg.NODECAP]
            hi = min(node, v)
            n = 0
            if r > 0:
                n = _rows_beside(rows, r, hi, prev, T, beside, scratch)
            else:
                # the row before is not here (the program's start is no joint; the pipeline keeps it otherwise)
                beside[0, :] = 0.0
                beside[0, B_ACAP] = prev[12]
                for i in range(3):
                    beside[0, B_X2 + i] = prev[6 + i]
                    beside[0, B_X3 + i] = prev[9 + i]
                n = 1
            jumps = False
            for i in range(3):
                if _joint_jerk(hi, i, pj[i], qj[i], a, x2, x3, 0.0, beside, n, 0, T, jtop) > 1e-9 * shared[i]:
                    jumps = True
            if jumps:
                for i in range(3):
                    left[i] = 0.0
                at_share = _joint_cap(hi, shared, shared, 1, pj, qj, a, x2, x3, left, beside, n, T, jtop)
                kept = -1.0  # the rows keep their own JCAP (r > 0: the row before is here to lower otherwise)
                if r > 0:
                    for i in range(3):
                        left[i] = _tangential(tau[i], row[seg.JCAP])
                    kept = _joint_cap(hi, axis_jerk, shared, 2, pj, qj, a, x2, x3, left, beside, n, T, jtop)
                if kept >= at_share:
                    node = min(node, kept)
                else:
                    # the joint at the normal share's speed, the rows beside it at what that leaves them: at least
                    # the tangential share (the jump takes at most the normal share), more on an axis the jump
                    # barely touches
                    node = min(node, at_share)
                    jcap = floor
                    if r > 0:
                        # the rows within three ticks of the joint passed at node
                        reached = 1
                        while reached < n and _reached(node, beside, reached, T) > 0.0:
                            reached += 1
                        jcap = math.inf
                        for i in range(3):
                            if _joint_jerk(hi, i, pj[i], qj[i], a, x2, x3, 0.0, beside, n, 0, T, jtop) > 1e-9 * shared[i]:
                                top = tau[i]
                                for m in range(reached):
                                    top = max(top, beside[m, B_TAU + i])
                                if top > 0.0:
                                    jcap = min(jcap, (axis_jerk[i] - _joint_jerk(node, i, pj[i], qj[i], a, x2, x3,
                                                                                 0.0, beside, n, 1, T, jtop)) / top)
                        jcap = max(jcap, floor)
                        for k in range(int(beside[reached - 1, B_ROW]), r):
                            rows[k, seg.JCAP] = min(rows[k, seg.JCAP], jcap)
                    row[seg.JCAP] = min(row[seg.JCAP], jcap)
            row[seg.NODECAP] = node
        for i in range(3):
            prev[i] = te[i]
            prev[3 + i] = ke[i]
            prev[6 + i] = x2[i]
            prev[9 + i] = x3[i]
        prev[12] = a
