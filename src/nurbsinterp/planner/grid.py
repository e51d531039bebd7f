"""The feed limit along the path: the grid of V_lim and of the tangential bound (step 1 of the algorithm in
:mod:`nurbsinterp.planner`), built block by block of knot spans.

Memory.  The grid has some 34 points per knot span (MIN_PER_SPAN, the refinement and the refined minima): 3.4
million on a curve of 10⁵ control points.  Held whole, with the derivative tables, the terms of V_lim and the
refinement's copies, it took ~18 KB per control point (1.97 GB).  It is built in blocks of whole knot spans
(about BLOCK_SAMPLES initial samples each), each handed on (to :mod:`.sections`) and dropped: every stage of
the grid works within one knot span (sampling, refinement, the minima searches), so a block computes exactly
what the whole grid did for its spans.  Only the refinement's bound on added points counts over the whole
grid (:class:`_Refinement`).  The grid itself, which the plan reports (:attr:`AdaptivePlan.s_grid` ...), is
rebuilt on demand (:func:`_grid_arrays`).

Time.  The terms of V_lim are kernels (:mod:`.feed`), and the golden-section searches run their steps in
kernels too (``nurbs.golden_minimum``): a few brackets per knot span, 62 evaluations each, were most of the planning
time as numpy arrays.  The derivatives and the arc length are nurbs' kernels.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import CuspError, SpecError
from ..extrema import discrete_minima
from ..nurbs import NurbsCurve, arc_length_many, eval_in_span, golden_minimum
from .feed import _column_kernel, _feed_limits, _kernel_limits
from .limits import _Limits

CORNER_COS = 1.0 - 1e-10  # a knot whose one-sided tangents differ by more (about 1.4e-5 rad) is a stop
MIN_PER_SPAN = 32  # samples per knot span at least (as NurbsCurve.curvature_maxima)
ZERO_SPAN = 1e-13  # a knot span shorter than this fraction of the path is a point (nodes this close merge anyway)
SINGULAR_RTOL = 1e-9  # a span end whose first Bezier leg is shorter than this (relative to the span's control
#                       polygon) has zero parametric speed: its tangent is the limit one, from the next leg
CUSP_RTOL = 1e-9  # a minimum of |C'| inside a span below this fraction of the span's largest |C'| is a zero
CUSP_END = 1e-6  # ... when it lies further than this (relative to the span width) from the span's ends
MAX_REFINED = 2_000_000  # grid points the refinement may add (a bound on memory for pathological curves)
ROUNDS = 40  # rounds of halving at most (down to 2^-40 of a span)
BLOCK_SAMPLES = 1 << 13  # initial samples per block of knot spans (a block holds ~3 MB while it is built)


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


def _rows_dot(d):
    """Σ_j d[..., j]² over the last axis, row by row as np.einsum("ij,ij->i") takes it."""
    flat = d.reshape(-1, d.shape[-1])
    return np.einsum("ij,ij->i", flat, flat).reshape(d.shape[:-1])


def _point_spans(curve, index):
    """Per knot span of *index*: whether it is a single point, its Bezier control points equal up to rounding."""
    out = np.empty(index.shape[0], dtype=bool)
    for lo in range(0, index.shape[0], 4096):  # the control points of 4096 spans at a time
        B = curve.bezier[index[lo:lo + 4096], 0]
        P = B[..., :-1] / B[..., -1:]
        out[lo:lo + 4096] = np.ptp(P, axis=1).max(axis=1) <= \
            64.0 * np.finfo(float).eps * np.maximum(np.abs(P).max(axis=(1, 2)), 1e-300)
    return out


def _kept_spans(curve: NurbsCurve):
    """(index, start, end, s_start, s_end): the knot spans the grid samples, and the arc length at their ends (mm).

    A span of zero length (its control points coincide: a repeated point of a polyline, p + 1 equal
    points) has no place in arc length: it is left out, and its neighbours meet at one point, a stop
    if the tangent turns there.  Its V_lim would be 0/0 everywhere.
    """
    U, p = curve.knots, curve.degree
    index = np.arange(p, curve.n + 1)
    index = index[U[index + 1] > U[index]]
    start, end = U[index], U[index + 1]
    s_knots = curve.arc_length_at(np.append(start, end[-1]))
    ls = np.diff(s_knots)
    length = curve.length
    kept = ls > ZERO_SPAN * length
    kept[kept] = ~_point_spans(curve, index[kept])
    if not kept.any():  # a rational curve whose control points coincide: its length is rounding
        raise SpecError(f"curve: has zero length (its control points coincide; the {length:.3g} mm computed is "
                        "rounding); there is nothing to plan")
    return index[kept], start[kept], end[kept], s_knots[:-1][kept], s_knots[1:][kept]


@dataclass
class _Spans:
    """The knot spans of one block and what the grid reads of each (arrays over the block's spans, in order).

    end_sing[0|1] : whether the parametric speed vanishes at the span's start | end
    end_tan[0|1] : the one-sided unit tangents there (the direction of motion), (m, dim)
    noise : the rounding of C' and C'' (see :func:`_curvature_noise`)
    feed : the blocks' own feedrates (mm/s) where a path has them, else None
    s_start, s_end : the arc length at the span's ends, mm
    """

    index: np.ndarray
    start: np.ndarray
    end: np.ndarray
    end_sing: np.ndarray
    end_tan: np.ndarray
    noise: tuple
    feed: np.ndarray | None
    s_start: np.ndarray = None
    s_end: np.ndarray = None

    @property
    def width(self):
        return self.end - self.start

    def at_ends(self, uu, loc):
        """Which of the samples uu (on the block's spans loc) are zero-speed span ends; the tangents there."""
        start = uu == self.start[loc]
        end = uu == self.end[loc]
        singular = (start & self.end_sing[0, loc]) | (end & self.end_sing[1, loc])
        return singular, np.where(start[:, None], self.end_tan[0, loc], self.end_tan[1, loc])


def _span_table(curve, index, start, end, s_start, s_end, span_feedrates) -> _Spans:
    sing, tang = _end_tangents(curve, index)
    feed = None if span_feedrates is None else span_feedrates[index]
    return _Spans(index, start, end, sing, tang, _curvature_noise(curve, index), feed, s_start, s_end)


def _end_tangents(curve, index):
    """Per knot span of *index*: whether the parametric speed vanishes at its start and at its end (2, m), and
    the one-sided unit tangents there (the direction of motion), (2, m, dim).

    From the span's Bezier control points P_0..P_p: near the start C(u) − P_0 is dominated by
    (P_j − P_0)(u − a)^j for the first P_j apart from P_0, so the limit tangent points from P_0
    to that P_j (rational or not), and likewise backwards at the end.  Where P_1 ≈ P_0 the
    derivative is zero or rounding noise and gives no direction.
    """
    dim = curve.dim
    B = curve.bezier[index, 0]
    P = B[..., :dim] / B[..., dim:]
    m = index.shape[0]
    rows = np.arange(m)
    sing = np.zeros((2, m), dtype=bool)
    tang = np.full((2, m, dim), np.nan)
    for side, (base, others, sign) in enumerate(((P[:, 0], P[:, 1:], 1.0), (P[:, -1], P[:, -2::-1], -1.0))):
        d = others - base[:, None, :]
        dist = np.sqrt(_rows_dot(d))
        far = dist > SINGULAR_RTOL * dist.max(axis=1)[:, None]
        some = far.any(axis=1)  # none: a point (such spans are left out of the grid)
        k = np.argmax(far, axis=1)
        sing[side] = ~some | (k > 0)
        tang[side, some] = sign * d[rows, k][some] / dist[rows, k][some, None]
    return sing, tang


def _rel_change(x):
    """|Δx| / min of the two, between neighbours: 0 where they are equal (0 and 0, inf and inf), inf from 0."""
    a, b = x[:-1], x[1:]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        out = np.abs(a - b) / np.minimum(a, b)
    out = np.where(a == b, 0.0, out)
    return np.nan_to_num(out, nan=np.inf, posinf=np.inf)


def _refuse_cusps(curve, spans: _Spans, u, loc, speed, singular):
    """SpecError when the parametric speed vanishes inside a knot span and the tangent turns there.

    A zero-speed point at a knot is planned as a stop; inside a span it is refused
    (the planner stops only at knots): a cusp has no feed limit to find there —
    without a curvature limit V_lim stays F on both sides of a reversal — so
    it would be passed at speed.  Inserting a knot there makes it a stop.  The
    sampled minima of |C'| are refined by golden section; zero-speed points where
    the path goes straight on (a stationary parametrisation) are planned through.
    """
    smax = np.zeros(spans.index.shape[0])
    np.maximum.at(smax, loc, speed)
    j, lo, hi = discrete_minima(speed, loc)
    pick = ~singular[j] & (speed[j] <= 0.1 * smax[loc[j]])
    if not pick.any():
        return
    lo, hi, lp = u[lo[pick]], u[hi[pick]], loc[j[pick]]
    sp = spans.index[lp]

    def f(uu):
        d1 = _derivs(curve, uu, sp)[:, 1, :]
        return np.sqrt(np.einsum("ij,ij->i", d1, d1))

    uc = golden_minimum(f, lo, hi)
    w = spans.width[lp]
    a0 = curve.knots[sp]
    b0 = curve.knots[sp + 1]
    inside = (uc - a0 > CUSP_END * w) & (b0 - uc > CUSP_END * w) & (f(uc) <= CUSP_RTOL * smax[lp])
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
        raise CuspError(f"curve: the parametric speed vanishes at u = {uc[i]:.9g}, point ({point}), inside the knot "
                        f"span [{a0[i]:.6g}, {b0[i]:.6g}], and the path turns by {angle:.3g} degrees there (a cusp); "
                        f"the adaptive planner stops only at knots: insert a knot at u = {uc[i]:.9g}",
                        float(uc[i]), point, angle)


def _curvature_noise(curve, index):
    """Per knot span of *index*: the rounding of C' and of C'' (absolute, mm per unit u and per unit u²), generously.

    C' = (A' − w'C)/w from the homogeneous derivative A' = (A'_xyz, w'), each a de Casteljau sum
    of the span's derivative Bezier coefficients: its error is some ulp of those coefficients
    (not of |C'|, which is far smaller where the speed vanishes, above all with unequal weights).
    """
    dim = curve.dim
    B = curve.bezier[index]
    wmin = B[:, 0, :, dim].min(axis=1)
    d1 = np.abs(B[:, 1, :, :dim]).max(axis=(1, 2))
    d1w = np.abs(B[:, 1, :, dim]).max(axis=1)
    d2 = np.abs(B[:, 2, :, :dim]).max(axis=(1, 2)) if curve.degree >= 2 else np.zeros(index.shape[0])
    d2w = np.abs(B[:, 2, :, dim]).max(axis=1) if curve.degree >= 2 else np.zeros(index.shape[0])
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
    """The grid on the knot spans of one block (or all of them), sorted by (span, u)."""

    u: np.ndarray
    span: np.ndarray
    s: np.ndarray
    v_limit: np.ndarray  # the smallest term of V_lim, mm/s
    binding: np.ndarray  # which term (index into LIMITS)
    acc_t: np.ndarray  # the tangential acceleration bound, mm/s²
    tangent: np.ndarray
    singular: np.ndarray  # zero-speed span ends (their tangent is the limit one)
    near: np.ndarray  # singular, and the samples taken into it (see _near_stops)
    tight: np.ndarray  # radius of curvature below the chord tolerance (see "Tight turns")


class _Refinement:
    """The refinement's bound (MAX_REFINED added points), kept over the blocks as it was over the whole grid.

    The whole grid halved in rounds, every interval that needed it at once, and refused the round
    that would take it past its initial size + MAX_REFINED, naming the first interval of that round.
    The grid's count in round r is the sum over the blocks of what each has added before round r
    and proposes in it (what it holds at the end, once it needs no more rounds).  Once that sum
    passes the bound in some round, the plan is refused; the blocks still to come are refined just
    as far as that round, to find the first round that passes it, and checked for cusps, which are
    refused first (they were checked on the whole grid before it was refined).
    """

    def __init__(self):
        self.count = np.zeros(ROUNDS, dtype=np.int64)  # per round, over the blocks seen
        self.first = [None] * ROUNDS  # per round: u of the first interval proposed
        self.last = ROUNDS  # the first round that passes the bound, once one does: the blocks stop there

    def propose(self, r, added, proposed, u_first) -> bool:
        """A block's round r: *added* points so far, *proposed* now.  Whether it should go on refining."""
        if proposed == 0:
            self.count[r:] += added
            return False
        self.count[r] += added + proposed
        if self.first[r] is None:
            self.first[r] = u_first
        over = np.flatnonzero(self.count > MAX_REFINED)
        if over.size:
            self.last = min(self.last, int(over[0]))
        return r < self.last

    @property
    def over(self) -> bool:
        return bool((self.count > MAX_REFINED).any())

    def check(self):
        over = np.flatnonzero(self.count > MAX_REFINED)
        if over.size:
            raise SpecError(f"curve: the feed limit varies too fast to be resolved near u = {self.first[over[0]]:.9g} "
                            f"(more than {MAX_REFINED} grid points; extreme weights, knot spans or curvature)")


def _samples(spans: _Spans, counts):
    """The initial samples of the block's spans: np.linspace(start, end, count + 1) on each, to the bit; (u, loc)."""
    m = spans.index.shape[0]
    loc = np.repeat(np.arange(m), counts + 1)
    first = np.concatenate([[0], np.cumsum(counts + 1)[:-1]])
    k = (np.arange(loc.shape[0]) - first[loc]).astype(float)
    delta = spans.end - spans.start
    div = counts.astype(float)
    step = delta / div
    u = k * step[loc]
    tiny = step[loc] == 0.0  # linspace's special case (gh-5437): a denormal step
    if tiny.any():
        u[tiny] = k[tiny] / div[loc[tiny]] * delta[loc[tiny]]
    u += spans.start[loc]
    u[first + counts] = spans.end
    return u, loc


def _evaluate(curve, lim, spans: _Spans, uu, loc, d=None):
    """(terms of V_lim, tangential bound, κ, τ, unresolved, singular) at the samples uu on the block's spans loc.

    *unresolved*: where rounding alone could move κ by 1e-3 of what matters, the
    curvature terms are noise (next to a zero-speed end: see _near_stops).  κ = |C''⊥|/σ²: an
    error δ1 in C' tilts the tangent by δ1/σ, so κ's error is (δ2 + |C''| δ1/σ)/σ².
    """
    singular, tangent = spans.at_ends(uu, loc)
    if d is None:
        d = _derivs(curve, uu, spans.index[loc])
    feed = None if spans.feed is None else spans.feed[loc]
    comps, acc_t, kappa, tau = _feed_limits(d, lim, singular, tangent, feed)
    unresolved = np.zeros(uu.shape[0], dtype=bool)
    if lim.curving:
        e1, e1w, e2, e2w = spans.noise
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            c = np.sqrt(np.einsum("ij,ij->i", d[:, 0], d[:, 0]))
            sig = np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1]))
            acc2 = np.sqrt(np.einsum("ij,ij->i", d[:, 2], d[:, 2]))
            err = (e2[loc] + e2w[loc] * c + acc2 * (e1[loc] + e1w[loc] * c) / sig) / (sig * sig)
            unresolved = ~(err <= 1e-3 * np.maximum(np.nan_to_num(kappa, nan=0.0), lim.kappa_bind)) & ~singular
    return comps, acc_t, kappa, tau, unresolved, singular


def _grid_blocks(curve: NurbsCurve, lim: _Limits, samples: int, resolution: float, span_feedrates=None):
    """The grid (step 1), block by block of whole knot spans, in order: a :class:`_Grid` per block.

    The curve is sampled per knot span (``samples`` spread in proportion to the spans' lengths, at
    least MIN_PER_SPAN per span, both one-sided ends of every span); see :func:`_block`.
    """
    index, start, end, s_start, s_end = _kept_spans(curve)
    length = curve.length
    counts = np.maximum(MIN_PER_SPAN, np.ceil(samples * (s_end - s_start) / length)).astype(np.int64)
    # blocks of whole spans, BLOCK_SAMPLES samples or so each
    ends = np.cumsum(counts + 1)
    cuts = np.concatenate([[0], np.flatnonzero(np.diff((ends - 1) // BLOCK_SAMPLES)) + 1, [index.shape[0]]])
    refinement = _Refinement()
    for a, b in zip(cuts[:-1], cuts[1:]):
        spans = _span_table(curve, index[a:b], start[a:b], end[a:b], s_start[a:b], s_end[a:b], span_feedrates)
        grid = _block(curve, lim, spans, counts[a:b], resolution, refinement)
        if grid is not None:
            yield grid
    refinement.check()


def _block(curve, lim, spans: _Spans, counts, resolution, refinement: _Refinement) -> _Grid | None:
    """The grid on one block's knot spans; None once the refinement's bound is passed (see :class:`_Refinement`).

    V_lim = min(F, chord, normal, axis velocity, axis acceleration) from the tangent τ and the
    curvature vector κn.  Intervals over which V_lim (or the tangential bound) changes by more than
    *resolution* are halved until it does not; next to a zero-speed end (V_lim = 0 there) that goes
    on down to the samples taken into the stop, or to 2^-40 of the span.  Then the exact local minima
    of V_lim and of the tangential bound, and the curvature maxima (as NurbsCurve.curvature_maxima
    finds them) become grid points, refined by golden section; the stops at zero-speed span ends take
    no part (their V_lim is 0 by decree, not a minimum to refine).  Last the arc length of every point.
    """
    u, loc = _samples(spans, counts)
    d = _derivs(curve, u, spans.index[loc])
    singular = spans.at_ends(u, loc)[0]
    _refuse_cusps(curve, spans, u, loc, np.sqrt(np.einsum("ij,ij->i", d[:, 1], d[:, 1])), singular)
    # u, loc, comps, acc_t, kappa, tangent, unresolved, singular
    cols = (u, loc, *_evaluate(curve, lim, spans, u, loc, d))
    del d
    initial = u.shape[0]
    width = spans.width
    for r in range(ROUNDS):
        u, loc, comps, acc_t = cols[:4]
        taken = _near_stops(loc, cols[7], cols[6]) & ~cols[7]
        need = (loc[1:] == loc[:-1]) & ((_rel_change(comps.min(axis=1)) > resolution)
                                        | (_rel_change(acc_t) > resolution)) \
            & (np.diff(u) > width[loc[:-1]] * 2.0 ** -40) & ~taken[:-1] & ~taken[1:]
        idx = np.flatnonzero(need)
        if not refinement.propose(r, u.shape[0] - initial, idx.size, float(u[idx[0]]) if idx.size else None):
            break
        nu = 0.5 * (u[idx] + u[idx + 1])
        nloc = loc[idx]
        cols = _merge(cols, (nu, nloc, *_evaluate(curve, lim, spans, nu, nloc)))
    if refinement.over:
        return None
    u, loc, comps, acc_t, kappa, tangent, unresolved, singular = cols
    near = _near_stops(loc, singular, unresolved)
    extra_u, extra_loc = [], []
    limits = _kernel_limits(lim)
    feed = np.full(1, np.nan) if spans.feed is None else spans.feed
    for column in ("v", "a", "k") if lim.curving else ("v", "a"):
        values = comps.min(axis=1) if column == "v" else (acc_t if column == "a" else -kappa)
        _j, lo, hi = discrete_minima(values, loc, ~near)
        if lo.size:
            ll = loc[lo]
            if column == "a" and not lim.has_axis_accel:
                # the bound is max_accel everywhere, so golden section compares equal values: its path does
                # not depend on them, and it need not evaluate them
                def f(uu):
                    return np.zeros(uu.shape[0])
            else:
                def f(uu, ll=ll, which="vak".index(column)):
                    out = np.empty(uu.shape[0])
                    _column_kernel(_derivs(curve, uu, spans.index[ll]), uu, ll, spans.start, spans.end,
                                   spans.end_sing, spans.end_tan, feed, which, *limits, out)
                    return out

            extra_u.append(golden_minimum(f, u[lo], u[hi]))
            extra_loc.append(ll)
    if extra_u:
        nu = np.concatenate(extra_u)
        nloc = np.concatenate(extra_loc)
        cols = _merge(cols, (nu, nloc, *_evaluate(curve, lim, spans, nu, nloc)))
        u, loc, comps, acc_t, kappa, tangent, unresolved, singular = cols
        near = _near_stops(loc, singular, unresolved)
    # the arc length of every point; at the span ends it is known (s(u) depends on u alone)
    s = np.empty(u.shape[0])
    at_start, at_end = u == spans.start[loc], u == spans.end[loc]
    s[at_start] = spans.s_start[loc[at_start]]
    s[at_end] = spans.s_end[loc[at_end]]
    inner = ~(at_start | at_end)
    s_inner = np.empty(int(inner.sum()))
    arc_length_many(curve.knots, curve.bezier, curve.degree, *curve.panels, np.ascontiguousarray(u[inner]), s_inner)
    s[inner] = s_inner
    # one-sided values at the knots: both ends of a span are evaluated on that span
    tight = np.zeros(u.shape[0], dtype=bool)
    with np.errstate(invalid="ignore"):
        if lim.chord_tolerance is not None:
            tight |= (kappa * lim.chord_tolerance > 1.0) & ~near
        if lim.max_normal_accel is not None:
            tight |= (kappa * (lim.max_normal_accel * lim.period ** 2 / 4.0) > 1.0) & ~near
    return _Grid(u, spans.index[loc], s, comps.min(axis=1), np.argmin(comps, axis=1), acc_t, tangent, singular,
                 near, tight)


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


def _grid_arrays(curve, lim, samples, resolution, span_feedrates=None) -> _Grid:
    """The whole grid, the blocks joined (what :class:`AdaptivePlan` reports of it, on demand)."""
    blocks = list(_grid_blocks(curve, lim, samples, resolution, span_feedrates))
    return _Grid(*(np.concatenate([getattr(g, name) for g in blocks]) for name in _Grid.__dataclass_fields__))
