"""Measures of a planned run: feedrate fluctuation and chord error.

Feedrate fluctuation, with exact arc length (the chord-based variant |ΔP|/(V T) − 1 has a
floor of about −κ²(VT)²/24 even for a perfect interpolator)::

    FF_k = Δs_k / ΔS_k − 1

Δs_k is the arc length the command moved along the curve from u_k to u_{k+1}
and ΔS_k the planned distance of that tick.  Ticks whose planned step is
below 1 % of Vp·T (the very start and end of a ramp) are left out, as is the
step into the end point, which the end gap measures instead.

Chord error of a step: the largest distance between the curve from u_k to
u_{k+1} and the chord joining their points, found by Newton on the
perpendicular distance from the middle of the step.  A step with knots
strictly inside (u_k, u_{k+1}) is split there: each piece between knots is
sampled at 9 points, its ends (the knots) included, and Newton refines around
the best sample (at a C0 knot the maximum sits on the kink, where Newton from
the middle of the step cannot see it); on those steps the distance is to the
segment, not to its line (a kink may turn by more than 90 degrees within one
tick).

Contour and tracking error of a simulated run: contour.py.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from .nurbs import curve_ders, find_span, find_span_from, make_work, norm_row, step_length_mid

FF_MIN_STEP = 0.01  # fraction of Vp·T below which a tick's FF is not counted


@njit(cache=True)
def _chord_newton(U, B, p, n, span, u0, u1, P0, P1, work, CK, segment=False):
    """Chord error from a derivative table CK at the middle of [u0, u1] (see chord_error).

    With *segment*, each sample's distance is to the segment P0 P1 (the part of
    the projection beyond either end added), else to its line."""
    dim = P0.shape[0]
    length = 0.0
    for c in range(dim):
        length += (P1[c] - P0[c]) ** 2
    length = math.sqrt(length)
    inv = 1.0 / length if length > 0.0 else 0.0
    u = 0.5 * (u0 + u1)
    best = 0.0
    for it in range(4):
        if it > 0:
            span = find_span_from(U, n, p, u, span)
            curve_ders(U, B, p, u, span, 2, work, CK)
        along = 0.0
        for c in range(dim):
            along += (CK[0, c] - P0[c]) * (P1[c] - P0[c]) * inv
        d2 = 0.0
        g = 0.0
        gp = 0.0
        t1e = 0.0
        for c in range(dim):
            e = (P1[c] - P0[c]) * inv
            perp = CK[0, c] - P0[c] - along * e
            d2 += perp * perp
            g += CK[1, c] * perp
            gp += CK[2, c] * perp + CK[1, c] * CK[1, c]
            t1e += CK[1, c] * e
        gp -= t1e * t1e
        if segment:
            out = max(-along, along - length, 0.0)
            best = max(best, math.sqrt(d2 + out * out))
        else:
            best = max(best, math.sqrt(d2))
        if gp >= 0.0:  # not near a maximum of the distance: keep the best sample
            break
        if abs(g / gp) <= 1e-3 * (u1 - u0):
            # the maximum is close: the quadratic model of d² gives it to ~1e-9 relative
            best = max(best, math.sqrt(max(d2 - g * g / gp, 0.0)))
            break
        nxt = min(max(u - g / gp, u0), u1)
        # the distance is flat at its maximum: u to 1e-6 of the step gives it to ~1e-12
        if abs(nxt - u) <= 1e-6 * (u1 - u0):
            break
        u = nxt
    return best


@njit(cache=True)
def _segment_distance(X, P0, P1):
    """Distance from the point X to the segment P0 P1."""
    dim = P0.shape[0]
    length2 = 0.0
    along = 0.0
    for c in range(dim):
        length2 += (P1[c] - P0[c]) ** 2
        along += (X[c] - P0[c]) * (P1[c] - P0[c])
    t = min(max(along / length2, 0.0), 1.0) if length2 > 0.0 else 0.0
    d2 = 0.0
    for c in range(dim):
        d2 += (X[c] - P0[c] - t * (P1[c] - P0[c])) ** 2
    return math.sqrt(d2)


CHORD_SPLIT_SAMPLES = 8  # intervals sampled on each piece of a step that crosses a knot


@njit(cache=True)
def _chord_split(U, B, p, n, u0, u1, P0, P1, work, CK):
    """Chord error of a step with knots strictly inside (u0, u1).

    The curve is one polynomial piece between consecutive knots, but not across
    them.  Each piece [lo, hi] is sampled at CHORD_SPLIT_SAMPLES + 1 points, its
    ends included (so every interior knot is a candidate: at a C0 knot the
    distance has a kink there, usually its maximum), on its own span; then
    :func:`_chord_newton` refines between the neighbours of the best sample (a
    piece may curl away from the chord, its maximum anywhere in it).  Distances
    are to the segment.  Only the few steps that cross a knot come here.
    """
    best = 0.0
    lo = u0
    j = find_span(U, n, p, u0) + 1  # U[j] is the first knot above u0
    ns = CHORD_SPLIT_SAMPLES
    while True:
        while j <= n + 1 and U[j] <= lo:
            j += 1
        hi = U[j] if j <= n + 1 and U[j] < u1 else u1
        span = find_span(U, n, p, 0.5 * (lo + hi))
        top = 0
        piece = -1.0
        for i in range(ns + 1):
            u = hi if i == ns else lo + (hi - lo) * i / ns
            curve_ders(U, B, p, u, span, 0, work, CK)  # the piece's polynomial also at hi (C0: the same point)
            d = _segment_distance(CK[0], P0, P1)
            if d > piece:
                piece = d
                top = i
        best = max(best, piece)
        a = lo + (hi - lo) * max(top - 1, 0) / ns
        b = hi if top + 1 >= ns else lo + (hi - lo) * (top + 1) / ns
        mid = 0.5 * (a + b)
        curve_ders(U, B, p, mid, span, 2, work, CK)
        best = max(best, _chord_newton(U, B, p, n, span, a, b, P0, P1, work, CK, True))
        if hi >= u1:
            return best
        lo = hi


@njit(cache=True, inline="always")
def _knot_inside(U, span, u0, u1):
    """Whether a knot lies strictly inside (u0, u1), given the span of a point of the step."""
    return U[span] > u0 or U[span + 1] < u1


@njit(cache=True)
def chord_error(U, B, p, n, u0, u1, P0, P1, work, CK):
    """Max distance from C([u0, u1]) to the segment P0 P1 (P0 = C(u0), P1 = C(u1)), mm.

    Newton on the derivative of the squared perpendicular distance, from the
    middle of the step, stopping when u moves less than 1e-6 of the step; a
    step with knots strictly inside is split at them (:func:`_chord_split`).
    """
    u = 0.5 * (u0 + u1)
    span = find_span_from(U, n, p, u, -1)
    if _knot_inside(U, span, u0, u1):
        return _chord_split(U, B, p, n, u0, u1, P0, P1, work, CK)
    curve_ders(U, B, p, u, span, 2, work, CK)
    return _chord_newton(U, B, p, n, span, u0, u1, P0, P1, work, CK)


@njit(cache=True)
def step_measures(U, B, p, n, starts, spans, cum, us, pts, S, min_step, ff, chord, counted):
    """Per-step FF and chord error over consecutive rows (len(us) - 1 steps).

    The middle of each step is evaluated once: it is the centre node of the
    3-point Gauss rule of the step's arc length and the start of the chord
    error's Newton iteration.  A step with a knot strictly inside has its chord
    error from :func:`_chord_split` (one comparison decides; the others cost
    what they did).
    """
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    CK2 = np.empty((3, dimh - 1))  # for the Gauss nodes, so that CK keeps the middle of the step
    b = U[n + 1]
    span = p
    for k in range(us.shape[0] - 1):
        u0 = us[k]
        u1 = us[k + 1]
        planned = S[k + 1] - S[k]
        counted[k] = planned >= min_step and u1 < b
        if not u1 > u0:
            ff[k] = -1.0 if counted[k] else 0.0
            chord[k] = 0.0
            continue
        mid = 0.5 * (u0 + u1)
        span = find_span_from(U, n, p, mid, span)
        curve_ders(U, B, p, mid, span, 2, work, CK)
        if counted[k]:
            ff[k] = step_length_mid(U, B, p, starts, spans, cum, u0, u1, norm_row(CK, 1), work, CK2) / planned - 1.0
        else:
            ff[k] = 0.0
        if _knot_inside(U, span, u0, u1):  # rare: the step crosses a knot (CK is free again)
            chord[k] = _chord_split(U, B, p, n, u0, u1, pts[k], pts[k + 1], work, CK)
        else:
            chord[k] = _chord_newton(U, B, p, n, span, u0, u1, pts[k], pts[k + 1], work, CK)


@njit(cache=True)
def abs_max_sumsq(values):
    """(index of the first largest |value|, sum of squares) in one pass.

    A plain loop, not ``values @ values``: NumPy hands a dot product to BLAS,
    whose threads then spin on the other core after every chunk (issue 16)."""
    j = 0
    top = -1.0
    total = 0.0
    for i in range(values.shape[0]):
        x = values[i]
        if abs(x) > top:
            top = abs(x)
            j = i
        total += x * x
    return j, total


class RunStats:
    """Accumulates the measures of a run chunk by chunk (memory independent of its length).

    Parameters
    ----------
    curve : the NurbsCurve
    peak : the planned peak feedrate, mm/s
    period : T, s
    deviation : also measure the distance of each command from the curve (for
        acc/dec after interpolation, whose commands leave the path)
    """

    def __init__(self, curve, peak: float, period: float, deviation: bool = False):
        self.curve = curve
        self.min_step = FF_MIN_STEP * peak * period
        self.deviation = deviation
        self.ticks = 0
        self.ff_max = 0.0  # the signed FF of largest magnitude
        self.ff_max_k = -1
        self.ff_sumsq = 0.0
        self.ff_count = 0
        self.chord_max = 0.0
        self.chord_max_k = -1
        self.deviation_max = 0.0
        self.deviation_max_k = -1
        self._carry = None  # (u, point on the curve, S) of the previous chunk's last row

    def update(self, chunk, dim: int) -> None:
        data = chunk.data
        m = data.shape[0]
        if m == 0:
            return
        us = chunk.u
        on_curve = self.curve.evaluate(us) if self.deviation else chunk.points
        if self.deviation:
            _, dist = self.curve.closest_point(chunk.points, seeds=us)
            j = int(np.argmax(dist))
            if dist[j] > self.deviation_max:
                self.deviation_max, self.deviation_max_k = float(dist[j]), int(data[j, 0])
        if self._carry is not None:
            us = np.concatenate([[self._carry[0]], us])
            on_curve = np.vstack([self._carry[1], on_curve])
            S = np.concatenate([[self._carry[2]], chunk.planned])
            k_first = int(data[0, 0]) - 1
        else:
            S = chunk.planned
            k_first = int(data[0, 0])
        self._carry = (us[-1], on_curve[-1].copy(), S[-1])
        self.ticks += m
        steps = us.shape[0] - 1
        if steps <= 0:
            return
        ff = np.empty(steps)
        chord = np.empty(steps)
        counted = np.empty(steps, dtype=np.bool_)
        U, B, p, n = self.curve.kernel_args
        step_measures(U, B, p, n, *self.curve.panels, np.ascontiguousarray(us),
                      np.ascontiguousarray(on_curve), np.ascontiguousarray(S), self.min_step, ff, chord, counted)
        if counted.any():
            f = ff[counted]
            j, sumsq = abs_max_sumsq(f)
            if abs(f[j]) > abs(self.ff_max):
                self.ff_max = float(f[j])
                self.ff_max_k = k_first + int(np.flatnonzero(counted)[j])
            self.ff_sumsq += sumsq
            self.ff_count += int(f.shape[0])
        j = int(np.argmax(chord))
        if chord[j] > self.chord_max:
            self.chord_max, self.chord_max_k = float(chord[j]), k_first + j

    @property
    def ff_rms(self) -> float:
        return math.sqrt(self.ff_sumsq / self.ff_count) if self.ff_count else 0.0
