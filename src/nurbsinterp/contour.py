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

Most ticks need no search (issue 16: the measure at millions of ticks per
second).  Where Newton ends at a stationary point inside the window and the
window is certified convex -- along it, the squared distance has f'' >= 2 (1 -
κ |C - q|) > 0, from a bound on the curvature κ of its panels
(``nurbs.is_convex``) -- that point is the window's nearest, as the search
would have found.  A tick then costs two evaluations of the curve: at the
command (r_k, and the arc length stepped from the last tick's) and one Newton
step from the previous feet extrapolated; the arc length of the foot is
stepped from the same derivatives.  The certified ticks are held to brute
force at 1e-9 mm in tests/test_contour.py.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from ._jit import njit
from .nurbs import (NEWTON_AT_END, NEWTON_CONVERGED, NEWTON_FAILED, _distance2, arc_length_to, ders_fast,
                    ders_fast_called, dot_rows, fill_certificate, is_convex, make_certificate, make_search, make_work,
                    newton_foot, newton_foot_called, norm_row, panel_at, panel_window, panel_window_called,
                    project_arc_window, step_length_fast, window_bounds)

WINDOW_MARGIN = 2.0  # the contour window reaches this many times |actual - C(u_cmd)| beyond foot and command
HERMITE_FRACTION = 1.0 / 1024.0  # the most of its panel a step integrated from its ends' speeds may span
CARRY = 17  # the length of contour_errors' carry (see there)


@njit(cache=True)
def _s_step(U, B, p, starts, spans, cum, u0, u1, s0, tmp, work, CK):
    """s(u1) from s0 = s(u0): the signed arc length of the step added."""
    if u1 == u0:
        return s0
    if u1 > u0:
        return s0 + step_length_fast(U, B, p, starts, spans, cum, u0, u1, tmp, work, CK)
    return s0 - step_length_fast(U, B, p, starts, spans, cum, u1, u0, tmp, work, CK)


@njit(cache=True, inline="always")
def _speed_and_slope(CK):
    """σ = |C'| and σ' = dσ/du = C'·C''/σ from CK (derivatives up to 2)."""
    sp = norm_row(CK, 1)
    return sp, (dot_rows(CK, 1, 2) / sp if sp > 0.0 else math.nan)


@njit(cache=True, inline="always")
def _hermite_step(starts, k0, u0, s0, sp0, dsp0, k1, u1, sp1, dsp1):
    """s(u1) from s0 = s(u0), given σ and σ' at both ends (in panels k0 and k1); NaN where the rule
    does not apply (:func:`_s_step` then).

    A step inside one panel and short against it -- every tick of a fine period -- is the
    corrected trapezoid rule h/2 (σ0 + σ1) + h²/12 (σ0' - σ1'), exact to h⁵ σ''''/720: within
    HERMITE_FRACTION of a panel on which the 10-point Gauss rule has converged it agrees with
    the 3-point Gauss rule of _s_step to rounding (tests/test_contour.py), and it needs no
    evaluation beyond the ones the tick made at its ends.
    """
    h = u1 - u0
    if k0 == k1 and abs(h) <= HERMITE_FRACTION * (starts[k0 + 1] - starts[k0]):
        return s0 + 0.5 * h * (sp0 + sp1) + h * h / 12.0 * (dsp0 - dsp1)
    return math.nan


@njit(cache=True, inline="always")
def _index(x):
    """A panel index kept in the carry (a hint: 0 where it is not known)."""
    return int(x) if x == x else 0


@njit(cache=True, inline="always")
def _inside(s_u, s_lo, s_hi, closed, length):
    """Whether arc length s_u lies in the window [s_lo, s_hi] (or a copy of it, on a closed curve)."""
    return s_lo <= s_u <= s_hi or (closed and (s_lo <= s_u - length <= s_hi or s_lo <= s_u + length <= s_hi))


@njit(cache=True)
def _search_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, start, uc, d2c, foot, s_foot,
                   tmp, work, CK, search):
    """(u, squared distance, s(u)) of the window's nearest point by the bounded global search.

    ``nurbs.project_arc_window`` over the window widened to panel ends (Newton from *start*,
    the candidate (uc, d2c)); a nearest point beyond the window's own ends sends it to the
    window itself (exact ends, by the inverse arc length).
    """
    length = cum[cum.shape[0] - 1]
    u, d2 = project_arc_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, False, start,
                               uc, d2c, work, CK, search)
    s_u = _s_step(U, B, p, starts, spans, cum, foot, u, s_foot, tmp, work, CK)
    if not _inside(s_u, s_lo, s_hi, closed, length):
        u, d2 = project_arc_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, True, start,
                                   uc, d2c, work, CK, search)
        s_u = arc_length_to(U, B, p, starts, spans, cum, u, work, CK)
    return u, d2, s_u


@njit(cache=True)
def _window_certificate(U, B, p, starts, spans, cum, closed, cert, s_lo, s_hi, hint, work, CK):
    """(curvature bound, joint turns, wrapped, k_lo, k_hi) of the window [s_lo, s_hi]'s panels, filling in
    the certificate's tables for a panel met for the first time.  Its own kernel, not inlined: the tick
    loop asks only when the window leaves the panels of the last one, and inlined its walks and table fills
    added to contour_errors' compilation, the longest of all."""
    _lo1, _hi1, _lo2, _hi2, wrapped, k_lo, k_hi = panel_window(starts, cum, closed, s_lo, s_hi, hint)
    worst, turned, missing = window_bounds(cert[0], cert[1], wrapped, k_lo, k_hi)
    while missing >= 0:  # a panel met for the first time: its bounds, once
        fill_certificate(U, B, p, starts, spans, missing, closed, cert, work, CK)
        worst, turned, missing = window_bounds(cert[0], cert[1], wrapped, k_lo, k_hi)
    return worst, turned, wrapped, k_lo, k_hi


@njit(cache=True)
def contour_errors(U, B, p, n, starts, spans, cum, cert, actual, seeds, carry, closed, out_u, out_d):
    """Contour error of each actual position (m, dim): its distance to the path window.

    The window of a tick (the definition, see the module docstring) is the arc
    length from the previous tick's foot point to the commanded point, widened
    on both sides by WINDOW_MARGIN times the table's distance r from the
    commanded point.

    Newton first takes one step from the last three feet extrapolated (at a
    fine period it lands within its 1e-8 mm tolerance at once); failing that
    it runs as ``nurbs.project_arc_window`` runs it -- from the same start on
    the same bracket, so to the same numbers.  Where it ends at a stationary
    point inside the window and ``nurbs.is_convex`` certifies the window (the
    distance is convex along it, so no other point of it is nearer), the
    bounded global search is spared; every other tick goes to the search
    (:func:`_search_window`).  The common case costs two evaluations of the
    curve: at the command (r, and σ, σ' that step its arc length) and Newton's.

    cert : ``nurbs.make_certificate(B, p, panels)``, kept across chunks (its
        tables fill in as the run meets panels)
    carry : (CARRY,) state across chunks, NaN at the start: the foot u, the
        previous commanded u, the arc length of each, σ and σ' at each, the
        panels of foot and command, a panel hint for the window, the foot before,
        the last certified window's panels (as arc lengths) and their bounds, the
        foot before that.

    Returns the number of ticks that went to the global search.
    """
    dimh = B.shape[3]
    work = make_work(p, 2, dimh)
    CK = np.empty((3, dimh - 1))
    search = make_search(B, p)
    tmp = search[4]  # de Casteljau scratch of ders_fast (project_interval uses it only inside)
    length = cum[cum.shape[0] - 1]
    a = U[p]
    b = U[n + 1]
    searched = 0
    # the carry, held in locals through the chunk: the previous foot, the previous command, hints
    foot, uc_prev, s_foot, s_prev = carry[0], carry[1], carry[2], carry[3]
    sp_f, dsp_f, sp_prev, dsp_prev = carry[4], carry[5], carry[6], carry[7]
    kf, kc, hint, foot_before = _index(carry[8]), _index(carry[9]), _index(carry[10]), carry[11]
    foot_before2 = carry[16]
    # the last certified window's panels, as arc lengths, and their bounds (NaN: none yet)
    cover_lo, cover_hi, cover_worst, cover_turned = carry[12], carry[13], carry[14], carry[15]
    q = np.empty(actual.shape[1])  # the tick's position, copied: a view per tick costs reference counting
    for i in range(actual.shape[0]):
        for c in range(q.shape[0]):
            q[c] = actual[i, c]
        uc = seeds[i]
        kc_prev = kc
        kc = panel_at(starts, uc, kc)
        ders_fast(U, B, p, uc, spans[kc], 2, tmp, CK)
        d2c = _distance2(CK, q)
        spc, dspc = _speed_and_slope(CK)
        if foot == foot:
            s_c = _hermite_step(starts, kc_prev, uc_prev, s_prev, sp_prev, dsp_prev, kc, uc, spc, dspc)
            if s_c != s_c:
                s_c = _s_step(U, B, p, starts, spans, cum, uc_prev, uc, s_prev, tmp, work, CK)
            start = min(max(foot + (uc - uc_prev), a), b)  # the foot advanced as the command advanced
        else:  # the first tick: the foot starts at the command
            s_c = arc_length_to(U, B, p, starts, spans, cum, uc, work, CK)
            foot, s_foot, sp_f, dsp_f, kf = uc, s_c, spc, dspc, kc
            start = uc
        sigma = s_foot
        if closed and abs(sigma - s_c) > 0.5 * length:  # the foot across the seam: the nearer copy
            sigma += length if sigma < s_c else -length
        margin = WINDOW_MARGIN * math.sqrt(d2c)
        s_lo = min(sigma, s_c) - margin
        s_hi = max(sigma, s_c) + margin

        # the common case: Newton as project_arc_window runs it, then the certificate in place of its search
        certified = False
        how = NEWTON_FAILED
        # the last three feet extrapolated (quadratically: at a fine period the table's jerk times T³
        # is far below Newton's tolerance): one evaluation settles the new foot, and the window's own
        # bracket is not needed (the foot is checked to lie inside the window below)
        guess = 3.0 * (foot - foot_before) + foot_before2 if foot_before2 == foot_before2 else 2.0 * foot - foot_before
        if a <= guess <= b:
            u, d2, how, last, span = newton_foot(U, B, p, n, q, guess, a, b, spans[kf], 1, tmp, CK)
        if how != NEWTON_CONVERGED:  # Newton from the search's start in the search's bracket, as it always ran
            # (the rare path: the window's and Newton's code called, not inlined a second time here)
            lo1, hi1, lo2, hi2, wrapped, _, _ = panel_window_called(starts, cum, closed, s_lo, s_hi, hint)
            if lo1 <= start <= hi1 or (wrapped and lo2 <= start <= hi2):
                lo, hi = (lo1, hi1) if lo1 <= start <= hi1 else (lo2, hi2)
                u, d2, how, last, span = newton_foot_called(U, B, p, n, q, start, lo, hi, spans[kf], 60, tmp, CK)
        if how == NEWTON_CONVERGED:  # CK: the derivatives at `last`, the iterate next to u
            sp_u, dsp_u = _speed_and_slope(CK)
            sp_u += dsp_u * (u - last)
        elif how == NEWTON_AT_END and not closed and (u == a or u == b):  # beyond an end of the path
            ders_fast_called(U, B, p, u, span, 2, tmp, CK)
            sp_u, dsp_u = _speed_and_slope(CK)
        else:
            how = NEWTON_FAILED
        if how != NEWTON_FAILED:
            if d2 < d2c:
                ku = panel_at(starts, u, kf)
                # s of the foot from the nearer of the previous foot and the command: a table settling
                # on its command gets the command's own s, not a sum along another train of ticks
                if abs(u - foot) <= abs(u - uc):
                    s_u = _hermite_step(starts, kf, foot, s_foot, sp_f, dsp_f, ku, u, sp_u, dsp_u)
                else:
                    s_u = _hermite_step(starts, kc, uc, s_c, spc, dspc, ku, u, sp_u, dsp_u)
                if s_u != s_u:
                    s_u = _s_step(U, B, p, starts, spans, cum, foot, u, s_foot, tmp, work, CK)
            else:  # the command is as near: the search keeps its candidate then
                u, d2, ku, sp_u, dsp_u, s_u = uc, d2c, kc, spc, dspc, s_c
            if _inside(s_u, s_lo, s_hi, closed, length) and not (closed and s_hi - s_lo >= length):
                wraps = closed and (s_lo < 0.0 or s_hi > length)
                x0, x1 = (s_lo, s_hi) if closed else (max(s_lo, 0.0), min(s_hi, length))
                if not wraps and cover_lo <= x0 and x1 <= cover_hi:
                    worst, turned = cover_worst, cover_turned  # inside the last window's panels: their bounds
                else:  # the window has moved on to another panel (once a panel, not once a tick): called
                    worst, turned, wrapped, k_lo, k_hi = _window_certificate(U, B, p, starts, spans, cum, closed,
                                                                             cert, s_lo, s_hi, hint, work, CK)
                    hint = k_lo
                    if not wrapped:
                        k1 = min(max(k_hi - 1, k_lo), spans.shape[0] - 1)
                        cover_lo, cover_hi, cover_worst, cover_turned = cum[k_lo], cum[k1 + 1], worst, turned
                certified = is_convex(worst, turned, x1 - x0, math.sqrt(d2))
        if not certified:
            searched += 1
            u, d2, s_u = _search_window(U, B, p, n, starts, spans, cum, q, s_lo, s_hi, closed, start, uc, d2c,
                                        foot, s_foot, tmp, work, CK, search)
            ku = panel_at(starts, u, kf)
            ders_fast_called(U, B, p, u, spans[ku], 2, tmp, CK)
            sp_u, dsp_u = _speed_and_slope(CK)
        foot_before2, foot_before, foot, s_foot, sp_f, dsp_f, kf = foot_before, foot, u, s_u, sp_u, dsp_u, ku
        uc_prev, s_prev, sp_prev, dsp_prev = uc, s_c, spc, dspc
        out_u[i] = u
        out_d[i] = math.sqrt(d2)
    carry[0], carry[1], carry[2], carry[3] = foot, uc_prev, s_foot, s_prev
    carry[4], carry[5], carry[6], carry[7] = sp_f, dsp_f, sp_prev, dsp_prev
    carry[8], carry[9], carry[10], carry[11] = kf, kc, hint, foot_before
    carry[12], carry[13], carry[14], carry[15] = cover_lo, cover_hi, cover_worst, cover_turned
    carry[16] = foot_before2
    return searched


@njit(cache=True)
def chunk_measures(err, cmd, act, vel, v_cmd, speed, at, sumsq):
    """One pass over a chunk of m ticks: the actual feedrate |vel| of each tick into *speed*, and
    for each measure -- the contour error *err*, the tracking error cmd - act of each axis, the
    feedrate error speed - v_cmd -- the index of its first largest |value| into *at* and its sum
    of squares into *sumsq* (both (axes + 2,), in that order).

    Plain loops, in tick order (the sums are NumPy's to the bit): no temporaries, and no BLAS
    dot product, whose threads spin on the other core after every chunk (issue 16).
    """
    axes = cmd.shape[1]
    last = axes + 1
    top = np.full(axes + 2, -1.0)
    at[:] = 0
    sumsq[:] = 0.0
    axis_deviations(cmd, act, at[1:last], sumsq[1:last])
    for k in range(err.shape[0]):
        x = err[k]
        if abs(x) > top[0]:
            top[0] = abs(x)
            at[0] = k
        sumsq[0] += x * x
        v2 = 0.0
        for c in range(vel.shape[1]):
            v2 += vel[k, c] * vel[k, c]
        speed[k] = math.sqrt(v2)
        x = speed[k] - v_cmd[k]
        if abs(x) > top[last]:
            top[last] = abs(x)
            at[last] = k
        sumsq[last] += x * x


@njit(cache=True, nogil=True)
def axis_deviations(ref, act, at, sumsq):
    """Per axis of a chunk (m, axes): the index of the first largest |ref - act| into *at*, the sum of squares
    into *sumsq* (tick order).  The tracking error: ref the commands, or the plan's points under shaped ones."""
    for i in range(ref.shape[1]):
        top = -1.0
        at[i] = 0
        total = 0.0
        for k in range(ref.shape[0]):
            x = ref[k, i] - act[k, i]
            if abs(x) > top:
                top = abs(x)
                at[i] = k
            total += x * x
        sumsq[i] = total


class _Extreme:
    """Running max of |x| with where it happened, and the sum of squares for the RMS."""

    def __init__(self):
        self.max = 0.0
        self.at = -1
        self.sumsq = 0.0
        self.count = 0

    def merge(self, value: float, at: int, sumsq: float, count: int) -> bool:
        """Add a chunk of *count* values: its first largest *value* (tick *at*), its sum of squares.
        Returns whether the running max moved to this chunk."""
        moved = abs(value) > abs(self.max) or self.at < 0
        if moved:
            self.max, self.at = value, at
        self.sumsq += sumsq
        self.count += count
        return moved

    @property
    def rms(self) -> float:
        return math.sqrt(self.sumsq / self.count) if self.count else 0.0


class PathWindow:
    """The contour error of positions that follow a commanded u, tick after tick: :func:`contour_errors` with
    its state across chunks.

    Every measure of a distance from the path goes through here -- the servo's contour error, the measured
    positions of a capture, the commands of acc/dec after interpolation (which leave the path at corners),
    the feet of a plot's magnified path -- so that all of them are the windowed nearest point that brute
    force gives (tests/test_contour.py), never a projection seeded at the command, which a tight turn
    leads into the wrong local minimum (2.3x the contour error on the butterfly, issue 12).
    """

    def __init__(self, curve):
        self.curve = curve
        self.searched = 0  # ticks that needed the window search (not certified by convexity)
        self._carry = np.full(CARRY, np.nan)
        self._cert = make_certificate(curve.bezier, curve.degree, curve.panels[1].shape[0])
        ends = curve.evaluate(np.array(curve.domain))
        self.closed = bool(np.linalg.norm(ends[0] - ends[1]) <= 1e-9 * max(1.0, curve.length))

    def nearest(self, positions, u_cmd, commands=None):
        """(foot u, distance) of each of the next positions (m, dim), whose commanded parameters are u_cmd (m,).

        (*commands*: the commanded points, which a window over a program's blocks needs and this one does not.)"""
        m = positions.shape[0]
        foot, dist = np.empty(m), np.empty(m)
        if m:
            U, B, p, n = self.curve.kernel_args
            seeds = np.clip(np.ascontiguousarray(u_cmd, dtype=float), *self.curve.domain)
            self.searched += contour_errors(U, B, p, n, *self.curve.panels, self._cert,
                                            np.ascontiguousarray(positions, dtype=float), seeds, self._carry,
                                            self.closed, foot, dist)
        return foot, dist


class _Errors:
    """The running extremes and sums of squares of one kind of motion (the cutting ticks, or the rapids')."""

    def __init__(self, axes):
        self.axes = list(axes)
        self.contour = _Extreme()
        self.contour_t = self.contour_u = 0.0
        self.tracking = {a: _Extreme() for a in self.axes}
        self.feedrate = _Extreme()
        self.feedrate_t = 0.0
        # the tracking error against the plan's points where the commands are not them (pre-compensated)
        self.planned = {a: _Extreme() for a in self.axes}
        self._at = np.zeros(len(self.axes) + 2, dtype=np.int64)
        self._sumsq = np.zeros(len(self.axes) + 2)

    @property
    def ticks(self) -> int:
        return self.contour.count

    def merge(self, ticks, t, foot, err, cmd, act, vel, v_cmd, speed, planned):
        """A run of ticks (*ticks*: their numbers) of this kind; *speed* receives their actual feedrates."""
        m = t.shape[0]
        at, sumsq = self._at, self._sumsq
        chunk_measures(err, cmd, act, vel, v_cmd, speed, at, sumsq)
        if self.contour.merge(float(err[at[0]]), int(ticks[at[0]]), float(sumsq[0]), m):
            self.contour_t, self.contour_u = float(t[at[0]]), float(foot[at[0]])
        for i, a in enumerate(self.axes):
            j = int(at[1 + i])
            self.tracking[a].merge(float(cmd[j, i] - act[j, i]), int(ticks[j]), float(sumsq[1 + i]), m)
        if planned is not None:
            axis_deviations(planned, act, at[1:-1], sumsq[1:-1])
            for i, a in enumerate(self.axes):
                j = int(at[1 + i])
                self.planned[a].merge(float(planned[j, i] - act[j, i]), int(ticks[j]), float(sumsq[1 + i]), m)
        j = int(at[-1])
        if self.feedrate.merge(float(speed[j] - v_cmd[j]), int(ticks[j]), float(sumsq[-1]), m):
            self.feedrate_t = float(t[j])

    def has_planned(self) -> bool:
        return all(e.count == self.ticks for e in self.planned.values())

    def fields(self, against_plan: bool) -> dict:
        tracking = self.planned if against_plan else self.tracking
        return dict(
            contour_error_max=abs(self.contour.max),
            contour_error_rms=self.contour.rms,
            contour_error_max_t=self.contour_t,
            contour_error_max_u=self.contour_u,
            tracking_error_max={a: abs(e.max) for a, e in tracking.items()},
            tracking_error_rms={a: e.rms for a, e in tracking.items()},
            feedrate_error_max=abs(self.feedrate.max),
            feedrate_error_max_signed=self.feedrate.max,
            feedrate_error_max_t=self.feedrate_t,
            feedrate_error_rms=self.feedrate.rms,
        )


class ServoStats:
    """Contour, tracking and feedrate error of a simulated run, accumulated chunk by chunk: the cutting ticks'
    and, apart, the rapids' (G0).

    A program's first plunge or a long rapid traverse lags far more than any cut (Cereal.ngc's first G0 made
    a 628 um contour error), and on a rapid only where it ends counts: the errors a part carries are the
    cutting moves'.  A tick belongs to the rapids when its command lies on a rapid block (the stream's
    ``rapid`` column); the hold after the last command belongs to that command's kind.
    """

    def __init__(self, curve, axes, window=None):
        """*window*: where the distances from the path come from (default the curve's PathWindow; a program's
        blocks: motion.contour.ProgramWindow, whose foot is a block index plus the fraction of the block)."""
        self.curve = curve
        self.dim = curve.dim if window is None else window.dim
        self.axes = list(axes)
        self.cutting = _Errors(self.axes)
        self.rapids = _Errors(self.axes)
        self.ticks = 0
        self.window = PathWindow(curve) if window is None else window
        self.feet = np.empty(0)  # the foot points' u of the chunk last updated (the plot's magnified path)

    searched = property(lambda self: self.window.searched,
                        doc="ticks whose contour error needed the window search (not certified by convexity)")
    closed = property(lambda self: self.window.closed)

    def update(self, t, u, cmd, act, v_cmd, vel, planned=None, rapid=None):
        """One chunk: times, commanded u, commanded and actual positions (m, axes), feedrates; *planned* the
        plan's points (m, axes) where the commands may not be them, for :meth:`report`'s ``against_plan``;
        *rapid* (m,) bool: the ticks on rapids (None: none are).

        Returns (contour error, actual feedrate) per tick, for traces and plots.
        """
        dim = self.dim
        m = t.shape[0]
        if m == 0:
            return np.empty(0), np.empty(0)
        speed = np.empty(m)
        out_u, err = self.window.nearest(act[:, :dim], u, cmd[:, :dim])
        self.feet = out_u
        ticks = self.ticks + np.arange(m)
        if rapid is None or not rapid.any():
            self.cutting.merge(ticks, t, out_u, err, cmd, act, vel, v_cmd, speed, planned)
        elif rapid.all():
            self.rapids.merge(ticks, t, out_u, err, cmd, act, vel, v_cmd, speed, planned)
        else:
            for kind, mask in ((self.cutting, ~rapid), (self.rapids, rapid)):
                part = np.empty(int(mask.sum()))
                kind.merge(ticks[mask], t[mask], out_u[mask], err[mask], np.ascontiguousarray(cmd[mask]),
                           np.ascontiguousarray(act[mask]), np.ascontiguousarray(vel[mask]), v_cmd[mask], part,
                           None if planned is None else np.ascontiguousarray(planned[mask]))
                speed[mask] = part
        self.ticks += m
        return err, speed

    @property
    def has_planned(self) -> bool:
        """Whether every tick so far came with the plan's points (update's *planned*)."""
        return self.cutting.has_planned() and self.rapids.has_planned()

    def report(self, against_plan: bool = False) -> ServoReport:
        """The errors of the cutting ticks, the rapids' apart (``rapids``; None without any); with *against_plan*
        the tracking error is the plan's points - the table (update's *planned*; every tick must have had
        them), not the commands - the table."""
        if against_plan and not self.has_planned:
            raise ValueError("the tracking error against the plan needs the plan's points of every tick")
        rapids = None
        if self.rapids.ticks:
            rapids = ServoReport(**self.rapids.fields(against_plan), cutting_ticks=0, rapid_ticks=self.rapids.ticks,
                                 rapids=None)
        return ServoReport(**self.cutting.fields(against_plan), cutting_ticks=self.cutting.ticks,
                           rapid_ticks=self.rapids.ticks, rapids=rapids)


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
    # the errors above are the cutting (feed) moves' ticks; the rapids' (G0) apart, None without any
    cutting_ticks: int
    rapid_ticks: int
    rapids: ServoReport | None

    def as_dict(self) -> dict:
        """The fields by name, in order: the JSON form (``rapids`` only when there were rapid ticks)."""
        out = dataclasses.asdict(self)
        if out["rapids"] is None:
            del out["rapids"]
        else:
            for key in ("cutting_ticks", "rapid_ticks", "rapids"):
                del out["rapids"][key]
        return out
