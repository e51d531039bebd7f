"""Measures of a run: feedrate fluctuation, chord error, contour and tracking error.

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

Contour error (the paper's Section 4.2 and Fig. 8): the distance from the table's actual
position q_k to the nearest point of the NURBS curve itself (not the command
polyline, not the per-axis tracking error), within an arc-length window that
keeps the measure local.  The window of tick k runs from the previous tick's
foot point σ_{k−1} (the nearest point found one tick earlier; the commanded
point at the first tick) to the commanded point s(u_k), whichever comes first,
and extends beyond both by WINDOW_MARGIN · r_k, where r_k = |q_k − C(u_k)| is
the table's distance from the commanded point: every point of the path the
table has yet to catch up with is in it, and so is every point within r_k of
arc on either side, which is all a straight stretch can offer nearer than the
command.  An open curve clips it to [0, L]; a closed one wraps it across the
seam (taking the copy of σ nearer the command).  Inside the window the search
is global (``nurbs.project_arc_window``): Newton from the previous foot, then
every span piece of the window either shown by its Bernstein bound to hold no
point nearer by more than 1e-9 mm, or split and searched.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np
from numba import njit

from .nurbs import (arc_length_to, curve_ders, ders_fast, find_span, find_span_from, make_search, make_work,
                    norm_row, project_arc_window, step_length_fast, step_length_mid)

FF_MIN_STEP = 0.01  # fraction of Vp·T below which a tick's FF is not counted
WINDOW_MARGIN = 2.0  # the contour window reaches this many times |actual - C(u_cmd)| beyond foot and command


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
            j = int(np.argmax(np.abs(f)))
            if abs(f[j]) > abs(self.ff_max):
                self.ff_max = float(f[j])
                self.ff_max_k = k_first + int(np.flatnonzero(counted)[j])
            self.ff_sumsq += float(f @ f)
            self.ff_count += int(f.shape[0])
        j = int(np.argmax(chord))
        if chord[j] > self.chord_max:
            self.chord_max, self.chord_max_k = float(chord[j]), k_first + j

    @property
    def ff_rms(self) -> float:
        return math.sqrt(self.ff_sumsq / self.ff_count) if self.ff_count else 0.0



@njit(cache=True)
def _s_step(U, B, p, starts, spans, cum, u0, u1, s0, tmp, work, CK):
    """s(u1) from s0 = s(u0): the signed arc length of the step added."""
    if u1 == u0:
        return s0
    if u1 > u0:
        return s0 + step_length_fast(U, B, p, starts, spans, cum, u0, u1, tmp, work, CK)
    return s0 - step_length_fast(U, B, p, starts, spans, cum, u1, u0, tmp, work, CK)


@njit(cache=True)
def contour_errors(U, B, p, n, starts, spans, cum, actual, seeds, carry, closed, out_u, out_d):
    """Contour error of each actual position (m, dim): its distance to the path window.

    The window of a tick (the definition, see the module docstring) is the arc
    length from the previous tick's foot point to the commanded point, widened
    on both sides by WINDOW_MARGIN times the table's distance r from the
    commanded point.  The search in it is global (:func:`project_interval`),
    seeded by Newton from the previous foot advanced as the command advanced.

    carry = [previous foot u, previous commanded u, s of that foot, s of that
    command] (NaN at the start), carried across chunks.
    """
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    search = make_search(B, p)
    tmp = search[4]  # de Casteljau scratch of ders_fast (project_interval uses it only inside)
    length = cum[cum.shape[0] - 1]
    a = U[p]
    b = U[n + 1]
    for i in range(actual.shape[0]):
        q = actual[i]
        uc = seeds[i]
        if carry[0] == carry[0]:
            s_c = _s_step(U, B, p, starts, spans, cum, carry[1], uc, carry[3], tmp, work, CK)
            foot, sigma = carry[0], carry[2]
            advance = uc - carry[1]
            start = min(max(foot + advance, a), b)
        else:
            s_c = arc_length_to(U, B, p, starts, spans, cum, uc, work, CK)
            foot, sigma, start = uc, s_c, uc
        if closed and abs(sigma - s_c) > 0.5 * length:  # the foot across the seam: the nearer copy
            sigma += length if sigma < s_c else -length
        ders_fast(U, B, p, uc, find_span(U, n, p, uc), 0, tmp, CK)
        d2c = 0.0
        for c in range(q.shape[0]):
            d2c += (CK[0, c] - q[c]) ** 2
        margin = WINDOW_MARGIN * math.sqrt(d2c)
        s_lo = min(sigma, s_c) - margin
        s_hi = max(sigma, s_c) + margin
        u, d2 = project_arc_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, False, start,
                               uc, d2c, work, CK, search)
        s_u = _s_step(U, B, p, starts, spans, cum, foot, u, carry[2] if carry[0] == carry[0] else s_c,
                      tmp, work, CK)
        inside = s_lo <= s_u <= s_hi or (closed and (s_lo <= s_u - length <= s_hi or s_lo <= s_u + length <= s_hi))
        if not inside:  # found in the panels beyond the window's ends: search the window itself
            u, d2 = project_arc_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, True, start,
                                   uc, d2c, work, CK, search)
            s_u = arc_length_to(U, B, p, starts, spans, cum, u, work, CK)
        carry[0] = u
        carry[1] = uc
        carry[2] = s_u
        carry[3] = s_c
        out_u[i] = u
        out_d[i] = math.sqrt(d2)


class _Extreme:
    """Running max of |x| with where it happened, and the sum of squares for the RMS."""

    def __init__(self):
        self.max = 0.0
        self.at = -1
        self.sumsq = 0.0
        self.count = 0

    def update(self, values: np.ndarray, offset: int) -> None:
        if values.size == 0:
            return
        j = int(np.argmax(np.abs(values)))
        if abs(values[j]) > abs(self.max) or self.at < 0:
            self.max, self.at = float(values[j]), offset + j
        self.sumsq += float(values @ values)
        self.count += values.size

    @property
    def rms(self) -> float:
        return math.sqrt(self.sumsq / self.count) if self.count else 0.0


class ServoStats:
    """Contour, tracking and feedrate error of a simulated run, accumulated chunk by chunk."""

    def __init__(self, curve, axes):
        self.curve = curve
        self.axes = list(axes)
        self.contour = _Extreme()
        self.contour_t = self.contour_u = 0.0
        self.tracking = {a: _Extreme() for a in self.axes}
        self.feedrate = _Extreme()
        self.feedrate_t = 0.0
        self.ticks = 0
        self._carry = np.full(4, np.nan)
        ends = curve.evaluate(np.array(curve.domain))
        self.closed = bool(np.linalg.norm(ends[0] - ends[1]) <= 1e-9 * max(1.0, curve.length))

    def update(self, t, u, cmd, act, v_cmd, vel):
        """One chunk: times, commanded u, commanded and actual positions (m, axes), feedrates.

        Returns (contour error, actual feedrate) per tick, for traces and plots.
        """
        dim = self.curve.dim
        m = t.shape[0]
        out_u = np.empty(m)
        err = np.empty(m)
        U, B, p, n = self.curve.kernel_args
        contour_errors(U, B, p, n, *self.curve.panels, np.ascontiguousarray(act[:, :dim]),
                       np.ascontiguousarray(u), self._carry, self.closed, out_u, err)
        before = self.contour.at
        self.contour.update(err, self.ticks)
        if self.contour.at != before:
            j = self.contour.at - self.ticks
            self.contour_t, self.contour_u = float(t[j]), float(out_u[j])
        for i, a in enumerate(self.axes):
            self.tracking[a].update(cmd[:, i] - act[:, i], self.ticks)
        speed = np.sqrt((vel * vel).sum(axis=1))
        before = self.feedrate.at
        self.feedrate.update(speed - v_cmd, self.ticks)
        if self.feedrate.at != before:
            self.feedrate_t = float(t[self.feedrate.at - self.ticks])
        self.ticks += m
        return err, speed

    def report(self) -> ServoReport:
        return ServoReport(
            contour_error_max=abs(self.contour.max),
            contour_error_rms=self.contour.rms,
            contour_error_max_t=self.contour_t,
            contour_error_max_u=self.contour_u,
            tracking_error_max={a: abs(e.max) for a, e in self.tracking.items()},
            tracking_error_rms={a: e.rms for a, e in self.tracking.items()},
            feedrate_error_max=abs(self.feedrate.max),
            feedrate_error_max_signed=self.feedrate.max,
            feedrate_error_max_t=self.feedrate_t,
            feedrate_error_rms=self.feedrate.rms,
        )


@dataclasses.dataclass(frozen=True)
class ServoReport:
    """The errors of a simulated run: mm, mm/s and s; per axis by axis name."""

    contour_error_max: float
    contour_error_rms: float
    contour_error_max_t: float  # when the largest contour error happened
    contour_error_max_u: float  # the curve parameter of its foot point
    tracking_error_max: dict[str, float]
    tracking_error_rms: dict[str, float]
    feedrate_error_max: float  # the largest |actual - commanded feedrate|
    feedrate_error_max_signed: float  # the same with its sign
    feedrate_error_max_t: float
    feedrate_error_rms: float

    def as_dict(self) -> dict:
        """The fields by name, in order: the JSON form."""
        return dataclasses.asdict(self)
