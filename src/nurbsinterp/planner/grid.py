"""The feed limit along the path: the grid of V_lim and of the tangential bound, and its rest-to-rest sections
(steps 1 and 2 of the algorithm in :mod:`nurbsinterp.planner`)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SpecError
from ..extrema import discrete_minima
from ..nurbs import NurbsCurve, arc_length_many, eval_in_span, golden_minimum
from .limits import AXIS_ACCEL, AXIS_VELOCITY, CHORD, FEEDRATE, LIMITS, NORMAL_ACCEL, _Limits

CORNER_COS = 1.0 - 1e-10  # a knot whose one-sided tangents differ by more (about 1.4e-5 rad) is a stop
MIN_PER_SPAN = 32  # samples per knot span at least (as NurbsCurve.curvature_maxima)
ZERO_SPAN = 1e-13  # a knot span shorter than this fraction of the path is a point (nodes this close merge anyway)
SINGULAR_RTOL = 1e-9  # a span end whose first Bezier leg is shorter than this (relative to the span's control
#                       polygon) has zero parametric speed: its tangent is the limit one, from the next leg
CUSP_RTOL = 1e-9  # a minimum of |C'| inside a span below this fraction of the span's largest |C'| is a zero
CUSP_END = 1e-6  # ... when it lies further than this (relative to the span width) from the span's ends
MAX_REFINED = 2_000_000  # grid points the refinement may add (a bound on memory for pathological curves)


def _derivs(curve, us, spans):
    out = np.empty((us.shape[0], 3, curve.dim))
    eval_in_span(curve.knots, curve.bezier, curve.degree, np.ascontiguousarray(us, dtype=float),
                 np.ascontiguousarray(spans, dtype=np.int64), 2, out)
    return out


def _frame(d):
    """Unit tangent τ and curvature vector κn = dτ/ds from a derivative table (N, 3, dim)."""
    d1 = d[:, 1, :]
    d2 = d[:, 2, :]
    sig2 = np.einsum("ij,ij->i", d1, d1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tau = d1 / np.sqrt(sig2)[:, None]
        kn = d2 / sig2[:, None] - d1 * (np.einsum("ij,ij->i", d1, d2) / (sig2 * sig2))[:, None]
    return tau, kn


def _is_point(curve, i):
    """Whether knot span i is a single point: its Bezier control points coincide up to rounding."""
    B = curve.bezier[i, 0]
    P = B[:, :-1] / B[:, -1:]
    return bool(np.ptp(P, axis=0).max() <= 64.0 * np.finfo(float).eps * max(float(np.abs(P).max()), 1e-300))


def _end_tangents(curve, spans):
    """Per span index (arrays of curve.n + 2 rows): whether the parametric speed vanishes at the span's start
    and at its end, and the one-sided unit tangents there (the direction of motion).

    From the span's Bezier control points P_0..P_p: near the start C(u) − P_0 is dominated by
    (P_j − P_0)(u − a)^j for the first P_j apart from P_0, so the limit tangent points from P_0
    to that P_j (rational or not), and likewise backwards at the end.  Where P_1 ≈ P_0 the
    derivative is zero or rounding noise and gives no direction.
    """
    rows = curve.n + 2
    dim = curve.dim
    sing = np.zeros((2, rows), dtype=bool)
    tang = np.full((2, rows, dim), np.nan)
    for i, _a, _b in spans:
        B = curve.bezier[i, 0]
        P = B[:, :dim] / B[:, dim:]
        for side, (base, others, sign) in enumerate(((P[0], P[1:], 1.0), (P[-1], P[-2::-1], -1.0))):
            d = others - base
            dist = np.sqrt(np.einsum("ij,ij->i", d, d))
            far = dist > SINGULAR_RTOL * dist.max()
            if not far.any():
                sing[side, i] = True  # a point: such spans are left out of the grid
                continue
            k = int(np.argmax(far))
            sing[side, i] = k > 0
            tang[side, i] = sign * d[k] / dist[k]
    return sing, tang


def _feed_limits(d, lim: _Limits, singular=None, tangent=None, feedrate=None):
    """Every term of V_lim (N, 5), mm/s, the tangential acceleration bound (N,), mm/s², κ (N,), 1/mm, and τ (N, dim).

    *singular* marks span ends where the parametric speed vanishes; *tangent* holds their limit
    tangents; *feedrate* (N,) replaces F where blocks carry their own.  The curvature there is undefined (and mostly infinite: near such an end C − P_0
    grows as (u − a)^j, j >= 2, and κ as s^(1/j − 1) unless the next leg is collinear), so the
    terms that depend on it are 0: a zero-speed end is a stop whenever a curvature limit is set.
    At V = 0 the centripetal part of an axis budget is 0, so the tangential bound takes all of it.
    """
    tau, kn = _frame(d)
    sing = singular is not None and bool(singular.any())
    if sing:
        tau = np.where(singular[:, None], tangent, tau)
        kn = np.where(singular[:, None], 0.0, kn)
    n = tau.shape[0]
    comps = np.full((n, len(LIMITS)), np.inf)
    comps[:, FEEDRATE] = lim.feedrate if feedrate is None else feedrate
    kappa = np.sqrt(np.einsum("ij,ij->i", kn, kn))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rho = 1.0 / kappa
        if lim.chord_tolerance is not None:
            dl = lim.chord_tolerance
            # below ρ = δ the circle formula falls to 0 (ρ < δ/2) while the chord error it guards against
            # vanishes; the floor 2δ/T holds V on a tick's worth of arc either side (see "Tight turns")
            chord = np.where(rho < dl, dl, np.sqrt(np.maximum(2.0 * rho * dl - dl * dl, 0.0)))
            comps[:, CHORD] = 2.0 / lim.period * chord
        if lim.max_normal_accel is not None:
            comps[:, NORMAL_ACCEL] = np.sqrt(lim.max_normal_accel * rho)
        abs_tau = np.abs(tau)
        if lim.has_axis_velocity:
            comps[:, AXIS_VELOCITY] = np.min(lim.axis_velocity / abs_tau, axis=1)
        acc_t = np.full(n, np.inf if lim.max_accel is None else lim.max_accel)
        if lim.has_axis_accel:
            comps[:, AXIS_ACCEL] = np.min(np.sqrt((1.0 - lim.share) * lim.axis_accel / np.abs(kn)), axis=1)
    comps = np.nan_to_num(comps, nan=0.0, posinf=np.inf)  # a zero tangent (cusp) stops the motion
    if sing:
        for col in lim.curvature_columns:
            comps[singular, col] = 0.0
        kappa = np.where(singular, np.nan, kappa)
    if lim.has_axis_accel:
        # what the centripetal part leaves of each axis budget at the highest feedrate allowed here
        vmax = comps.min(axis=1)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            left = (lim.axis_accel - vmax[:, None] ** 2 * np.abs(kn)) / abs_tau
        acc_t = np.minimum(acc_t, np.nan_to_num(np.min(left, axis=1), nan=0.0, posinf=np.inf))
    return comps, acc_t, kappa, tau


def _rel_change(x):
    """|Δx| / min of the two, between neighbours: 0 where they are equal (0 and 0, inf and inf), inf from 0."""
    a, b = x[:-1], x[1:]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = np.abs(a - b) / np.minimum(a, b)
    out = np.where(a == b, 0.0, out)
    return np.nan_to_num(out, nan=np.inf, posinf=np.inf)


def _refuse_cusps(curve, u, span, speed, singular, width):
    """SpecError when the parametric speed vanishes inside a knot span and the tangent turns there.

    A zero-speed point at a knot is planned as a stop; inside a span it is refused
    (the planner stops only at knots): a cusp has no feed limit to find there —
    without a curvature limit V_lim stays F on both sides of a reversal — so
    it would be passed at speed.  Inserting a knot there makes it a stop.  The
    sampled minima of |C'| are refined by golden section; zero-speed points where
    the path goes straight on (a stationary parametrisation) are planned through.
    """
    smax = np.zeros(width.shape[0])
    np.maximum.at(smax, span, speed)
    j, lo, hi = discrete_minima(speed, span)
    pick = ~singular[j] & (speed[j] <= 0.1 * smax[span[j]])
    if not pick.any():
        return
    lo, hi, sp = u[lo[pick]], u[hi[pick]], span[j[pick]]

    def f(uu):
        d1 = _derivs(curve, uu, sp)[:, 1, :]
        return np.sqrt(np.einsum("ij,ij->i", d1, d1))

    uc = golden_minimum(f, lo, hi)
    w = width[sp]
    a0 = curve.knots[sp]
    b0 = curve.knots[sp + 1]
    inside = (uc - a0 > CUSP_END * w) & (b0 - uc > CUSP_END * w) & (f(uc) <= CUSP_RTOL * smax[sp])
    if not inside.any():
        return
    k = np.flatnonzero(inside)
    delta = 0.5 * CUSP_END * w[k]
    tb = _frame(_derivs(curve, uc[k] - delta, sp[k]))[0]
    ta = _frame(_derivs(curve, uc[k] + delta, sp[k]))[0]
    turn = np.einsum("ij,ij->i", tb, ta)
    bad = np.flatnonzero(~(turn >= CORNER_COS))
    if bad.size:
        i = k[bad[0]]
        point = ", ".join(f"{x:.6g}" for x in curve.evaluate(float(uc[i])))
        angle = math.degrees(math.acos(min(1.0, max(-1.0, float(turn[bad[0]]))))) if np.isfinite(turn[bad[0]]) \
            else 180.0
        raise SpecError(f"curve: the parametric speed vanishes at u = {uc[i]:.9g}, point ({point}), inside the knot "
                        f"span [{a0[i]:.6g}, {b0[i]:.6g}], and the path turns by {angle:.3g} degrees there (a cusp); "
                        f"the adaptive planner stops only at knots: insert a knot at u = {uc[i]:.9g}")


def _curvature_noise(curve, spans):
    """Per span index: the rounding of C' and of C'' (absolute, mm per unit u and per unit u²), generously.

    C' = (A' − w'C)/w from the homogeneous derivative A' = (A'_xyz, w'), each a de Casteljau sum
    of the span's derivative Bezier coefficients: its error is some ulp of those coefficients
    (not of |C'|, which is far smaller where the speed vanishes, above all with unequal weights).
    """
    rows = curve.n + 2
    dim = curve.dim
    d1 = np.zeros(rows)
    d1w = np.zeros(rows)
    d2 = np.zeros(rows)
    d2w = np.zeros(rows)
    wmin = np.ones(rows)
    for i in spans:
        B = curve.bezier[i]
        wmin[i] = float(np.min(B[0, :, dim]))
        d1[i] = float(np.abs(B[1, :, :dim]).max())
        d1w[i] = float(np.abs(B[1, :, dim]).max())
        if curve.degree >= 2:
            d2[i] = float(np.abs(B[2, :, :dim]).max())
            d2w[i] = float(np.abs(B[2, :, dim]).max())
    ulp = 16.0 * np.finfo(float).eps
    return ulp * d1 / wmin, ulp * d1w / wmin, ulp * (d2 + 2.0 * d1w * d1 / wmin) / wmin, ulp * d2w / wmin


def _near_stops(span, singular, unresolved):
    """The zero-speed span ends, and the samples next to them whose curvature is lost in rounding.

    As |C'| → 0 the curvature formula cancels: on a straight span that starts with zero speed
    it gives ~1e29 1/mm at u − a = 1e-13, and V_lim ~ 1e-18 mm/s.  Such samples (within ~1e-6
    mm of the end on the curves measured, 1e-8 of their length) are taken into the stop: their
    limits are ignored, the refinement does not go past them, and the interval from the stop to
    the first sample whose curvature is resolved takes that sample's limits — the plan leaving
    or reaching a stop is far below the feed limit that close to it (V ~ √(2As) from rest,
    V_lim ~ s^(1/4..1/3) where κ grows at a zero-speed end).
    """
    near = singular.copy()
    n = span.shape[0]
    for k in np.flatnonzero(singular):
        for step in (1, -1):
            i = k + step
            while 0 <= i < n and span[i] == span[k] and unresolved[i]:
                near[i] = True
                i += step
    return near


@dataclass
class _Grid:
    u: np.ndarray
    span: np.ndarray
    s: np.ndarray
    comps: np.ndarray
    acc_t: np.ndarray
    tangent: np.ndarray
    singular: np.ndarray  # zero-speed span ends (their tangent is the limit one)
    near: np.ndarray  # singular, and the samples taken into it (see _near_stops)
    tight: np.ndarray  # radius of curvature below the chord tolerance (see "Tight turns")

    @property
    def v_limit(self):
        return self.comps.min(axis=1)


def _build_grid(curve: NurbsCurve, lim: _Limits, samples: int, resolution: float, span_feedrates=None) -> _Grid:
    spans = curve.span_ranges()
    starts = np.array([a for _, a, _ in spans] + [spans[-1][2]])
    s_knots = curve.arc_length_at(starts)
    length = curve.length
    # A span of zero length (its control points coincide: a repeated point of a polyline, p + 1 equal
    # points) has no place in arc length: it is left out, and its neighbours meet at one point, a stop
    # if the tangent turns there.  Its V_lim would be 0/0 everywhere.
    kept = [(sp, ls) for sp, ls in zip(spans, np.diff(s_knots))
            if ls > ZERO_SPAN * length and not _is_point(curve, sp[0])]
    if not kept:  # a rational curve whose control points coincide: its length is rounding
        raise SpecError(f"curve: has zero length (its control points coincide; the {length:.3g} mm computed is "
                        "rounding); there is nothing to plan")
    us, sp = [], []
    for (i, a, b), ls in kept:
        count = max(MIN_PER_SPAN, int(math.ceil(samples * ls / length)))
        us.append(np.linspace(a, b, count + 1))
        sp.append(np.full(count + 1, i, dtype=np.int64))
    u = np.concatenate(us)
    span = np.concatenate(sp)
    width = np.zeros(curve.n + 2)
    for (i, a, b), _ls in kept:
        width[i] = b - a
    end_sing, end_tan = _end_tangents(curve, [k for k, _ls in kept])
    knots = curve.knots

    def at_ends(uu, ss):
        start = uu == knots[ss]
        end = uu == knots[ss + 1]
        singular = (start & end_sing[0, ss]) | (end & end_sing[1, ss])
        return singular, np.where(start[:, None], end_tan[0, ss], end_tan[1, ss])

    e1, e1w, e2, e2w = _curvature_noise(curve, [k for (k, _a, _b), _ls in kept])
    kappa_bind = lim.kappa_bind

    def evaluate(uu, ss):
        singular, tangent = at_ends(uu, ss)
        d = _derivs(curve, uu, ss)
        feed = None if span_feedrates is None else span_feedrates[ss]
        comps, acc_t, kappa, tau = _feed_limits(d, lim, singular, tangent, feed)
        # Where rounding alone could move κ by 1e-3 of what matters, the curvature terms are noise
        # (next to a zero-speed end: see _near_stops).  κ = |C''⊥|/σ²: an error δ1 in C' tilts
        # the tangent by δ1/σ, so κ's error is (δ2 + |C''| δ1/σ)/σ².
        unresolved = np.zeros(uu.shape[0], dtype=bool)
        if lim.curving:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                c = np.sqrt(np.einsum("ij,ij->i", d[:, 0], d[:, 0]))
                sig = np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1]))
                acc2 = np.sqrt(np.einsum("ij,ij->i", d[:, 2], d[:, 2]))
                err = (e2[ss] + e2w[ss] * c + acc2 * (e1[ss] + e1w[ss] * c) / sig) / (sig * sig)
                unresolved = ~(err <= 1e-3 * np.maximum(np.nan_to_num(kappa, nan=0.0), kappa_bind)) & ~singular
        return comps, acc_t, kappa, tau, unresolved, singular

    d = _derivs(curve, u, span)
    _refuse_cusps(curve, u, span, np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1])), at_ends(u, span)[0], width)
    cols = (u, span, *evaluate(u, span))  # u, span, comps, acc_t, kappa, tangent, unresolved, singular
    initial = u.shape[0]
    # halve every interval over which V_lim (or the tangential bound) changes too much; next to a
    # zero-speed end (V_lim = 0 there) that goes on down to the samples taken into the stop, or
    # to 2^-40 of the span
    for _ in range(40):
        u, span, comps, acc_t = cols[:4]
        taken = _near_stops(span, cols[7], cols[6]) & ~cols[7]
        need = (span[1:] == span[:-1]) & ((_rel_change(comps.min(axis=1)) > resolution)
                                          | (_rel_change(acc_t) > resolution)) \
            & (np.diff(u) > width[span[:-1]] * 2.0 ** -40) & ~taken[:-1] & ~taken[1:]
        idx = np.flatnonzero(need)
        if idx.size == 0:
            break
        if u.shape[0] + idx.size > initial + MAX_REFINED:
            k = int(idx[0])
            raise SpecError(f"curve: the feed limit varies too fast to be resolved near u = {u[k]:.9g} (more than "
                            f"{MAX_REFINED} grid points; extreme weights, knot spans or curvature)")
        nu = 0.5 * (u[idx] + u[idx + 1])
        nsp = span[idx]
        cols = _merge(cols, (nu, nsp, *evaluate(nu, nsp)))
    u, span, comps, acc_t, kappa, tangent, unresolved, singular = cols
    near = _near_stops(span, singular, unresolved)
    # the exact local minima of V_lim and of the tangential bound, and the curvature maxima
    # (as NurbsCurve.curvature_maxima finds them), become grid points; the stops
    # at zero-speed span ends take no part (their V_lim is 0 by decree, not a minimum to refine)
    extra_u, extra_sp = [], []
    searches = [(comps.min(axis=1), "v"), (acc_t, "a")]
    if lim.curving:
        searches.append((-kappa, "k"))
    for values, column in searches:
        _j, lo, hi = discrete_minima(values, span, ~near)
        if lo.size:
            ss = span[lo]

            def f(uu, ss=ss, column=column):
                comps_, acc_, kappa_ = evaluate(uu, ss)[:3]
                return comps_.min(axis=1) if column == "v" else (acc_ if column == "a" else -kappa_)

            extra_u.append(golden_minimum(f, u[lo], u[hi]))
            extra_sp.append(ss)
    if extra_u:
        nu = np.concatenate(extra_u)
        nsp = np.concatenate(extra_sp)
        cols = _merge(cols, (nu, nsp, *evaluate(nu, nsp)))
        u, span, comps, acc_t, kappa, tangent, unresolved, singular = cols
        near = _near_stops(span, singular, unresolved)
    s = np.empty(u.shape[0])
    arc_length_many(curve.knots, curve.bezier, curve.degree, *curve.panels, np.ascontiguousarray(u), s)
    # one-sided values at the knots: both ends of a span are evaluated on that span
    tight = np.zeros(u.shape[0], dtype=bool)
    if lim.chord_tolerance is not None:
        with np.errstate(invalid="ignore"):
            tight = (kappa * lim.chord_tolerance > 1.0) & ~near
    return _Grid(u, span, s, comps, acc_t, tangent, singular, near, tight)


def _merge(old, new):
    """Merge two sets of samples (u, span, values...), sorted by (span, u), without duplicates."""
    cols = [np.concatenate([a, b]) for a, b in zip(old, new)]
    u, span = cols[0], cols[1]
    order = np.lexsort((u, span))
    cols = [c[order] for c in cols]
    u, span = cols[0], cols[1]
    keep = np.ones(u.shape[0], dtype=bool)
    keep[1:] = (u[1:] != u[:-1]) | (span[1:] != span[:-1])
    return tuple(c[keep] for c in cols)


def _tight_windows(s_tight, reach):
    """The arc-length windows [s − reach, s + reach] around the tight points, merged: (lo, hi) arrays."""
    if s_tight.size == 0:
        return np.empty(0), np.empty(0)
    s_tight = np.sort(s_tight)
    lo, hi = s_tight - reach, s_tight + reach
    new = np.concatenate([[True], lo[1:] > hi[:-1]])  # a window that starts past the previous end
    starts = np.flatnonzero(new)
    ends = np.concatenate([starts[1:], [s_tight.size]]) - 1
    return lo[starts], np.maximum.accumulate(hi)[ends]


def _floor_windows(nodes, vmin, amin, lo, hi, floor):
    """Cap V at *floor* over the windows [lo, hi]: nodes at the window edges (their limits the smaller of
    the interval's ends, which bound it from below), and V_lim <= floor at every node inside."""
    tol = 1e-13 * max(abs(float(nodes[-1])), 1.0)
    edges = np.concatenate([lo, hi])
    edges = edges[(edges > nodes[0] + tol) & (edges < nodes[-1] - tol)]
    if edges.size:
        edges = np.unique(edges)
        k = np.searchsorted(nodes, edges)
        far = (edges - nodes[k - 1] > tol) & (nodes[k] - edges > tol)  # otherwise a node is there already
        edges, k = edges[far], k[far]
        nodes = np.insert(nodes, k, edges)
        vmin = np.insert(vmin, k, np.minimum(vmin[k - 1], vmin[k]))
        amin = np.insert(amin, k, np.minimum(amin[k - 1], amin[k]))
    w = np.searchsorted(lo, nodes + tol, side="right") - 1  # the last window starting at or before the node
    inside = (w >= 0) & (nodes - tol <= hi[np.maximum(w, 0)])
    return nodes, np.where(inside, np.minimum(vmin, floor), vmin), amin


def _sections(grid: _Grid, floor: float = math.inf, reach: float = 0.0):
    """Split the grid at stops: [(s nodes, V_lim at nodes, tangential bound at nodes)] per rest-to-rest section.

    At a smooth knot the two one-sided samples merge (the smaller limits win);
    at a corner they stay apart, ending one section and starting the next.  A
    zero-speed span end with V_lim = 0 (a curvature limit is set) is a stop too.
    V_lim is at most *floor* within *reach* of arc length of every tight point
    (radius below the chord tolerance; see "Tight turns" in :mod:`nurbsinterp.planner`).
    """
    lo_w, hi_w = _tight_windows(grid.s[grid.tight], reach)
    s, vl, at, span = grid.s, grid.v_limit, grid.acc_t, grid.span
    n = s.shape[0]
    boundary = np.flatnonzero(span[1:] != span[:-1])  # pairs (k, k+1) at a knot
    stop = grid.singular & (vl == 0.0)
    corner = ~(np.einsum("ij,ij->i", grid.tangent[boundary], grid.tangent[boundary + 1]) >= CORNER_COS) \
        | stop[boundary] | stop[boundary + 1]
    # A stop's V_lim = 0 belongs to the point only: V = 0 there anyway.  The interval next to it was
    # halved down to the samples taken into the stop (V_lim changes from 0), which are left out,
    # and takes its cap from its other end.
    vl = np.where(stop, np.inf, vl)
    at = at.copy()
    drop = grid.near & ~grid.singular
    smooth = boundary[~corner]
    vl[smooth] = np.minimum(vl[smooth], vl[smooth + 1])
    at[smooth] = np.minimum(at[smooth], at[smooth + 1])
    drop[smooth + 1] = True
    cuts = [0] + list(boundary[corner] + 1) + [n]
    out = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        keep = np.flatnonzero(~drop[a:b]) + a
        ss, vv, aa = s[keep], vl[keep], at[keep]
        # nodes at the same arc length (a refined minimum on top of a sample): the smaller limits win
        first = np.ones(ss.shape[0], dtype=bool)
        first[1:] = np.diff(ss) > 1e-13 * max(abs(ss[-1]), 1.0)
        groups = np.cumsum(first) - 1
        m = groups[-1] + 1
        nodes = ss[first]
        vmin = np.full(m, np.inf)
        amin = np.full(m, np.inf)
        np.minimum.at(vmin, groups, vv)
        np.minimum.at(amin, groups, aa)
        if nodes.shape[0] >= 2 and nodes[-1] > nodes[0]:
            if np.isinf(vmin[0]):
                vmin[0] = vmin[1]
            if np.isinf(vmin[-1]):
                vmin[-1] = vmin[-2]
            if nodes.shape[0] == 2:  # the scan needs a node between the two stops (V = 0 at both)
                nodes = np.array([nodes[0], 0.5 * (nodes[0] + nodes[1]), nodes[1]])
                vmin = np.array([vmin[0], vmin.min(), vmin[1]])
                amin = np.array([amin[0], amin.min(), amin[1]])
            if lo_w.size:
                nodes, vmin, amin = _floor_windows(nodes, vmin, amin, lo_w, hi_w, floor)
            out.append((nodes, vmin, amin))
    return out
