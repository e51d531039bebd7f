"""Contour, tracking and feedrate error of a simulated run.

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

from .metrics import abs_max_sumsq
from .nurbs import (arc_length_to, ders_fast, find_span, make_search, make_work, project_arc_window,
                    step_length_fast)

WINDOW_MARGIN = 2.0  # the contour window reaches this many times |actual - C(u_cmd)| beyond foot and command


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
        j, sumsq = abs_max_sumsq(np.ascontiguousarray(values, dtype=np.float64))
        if abs(values[j]) > abs(self.max) or self.at < 0:
            self.max, self.at = float(values[j]), offset + j
        self.sumsq += sumsq
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
