"""The windowed look-ahead: the feedrate at every node of a window of segments, committed as far as it is final.

A window holds the segments not yet committed.  Its nodes are the segments'
ends; each has a cap (the lower of the two segments' caps and the joint's own,
0 at a stop) and the window's last node is a stop: whatever follows it, the
plan can always come to rest there.  The bidirectional scan (backward from
that stop, forward from the committed feedrate at the first node) gives the
time-optimal feedrate under constant-acceleration ramps; inside each segment
the feedrate rises at its acceleration cap, cruises at its cap, and falls at
it (v² linear in s on each ramp: the trapezoidal shape).

Commitment.  A node is committed when the window's end is at least the
braking distance from the window's highest cap beyond it,
v_max² / (2 a_min) (the window's lowest acceleration cap): the backward
constraint from that end is then above every cap there, so the node's
feedrate is what the whole program's scan gives it, to the bit (the backward
values differ only where that constraint binds, and min() of equal operands
is exact).  The first node of the next window keeps its committed feedrate,
which can stop before the previous window's end within the same caps, and
hence before the next window's end (extending a window only removes a stop).
The tests plan programs whole and in windows and compare the feedrates.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..planner.jerk import _push
from . import segments as seg

HOLD = 0.0  # a piece's jerk column (constant-acceleration pieces: always 0)


@njit(cache=True)
def scan(s, ncap, vcap, acap, v_start, v_end):
    """Node feedrates of a window: nodes s (n+1,), node caps (n+1,), interval caps and acceleration caps (n,).

    The first node starts at v_start (safe: at most its backward value, by construction), the last ends at
    v_end (0: the window's horizon, or the program's end)."""
    n = s.shape[0] - 1
    vb = np.empty(n + 1)
    vb[n] = min(v_end, ncap[n])
    for j in range(n - 1, -1, -1):
        vb[j] = min(ncap[j], math.sqrt(vb[j + 1] * vb[j + 1] + 2.0 * acap[j] * (s[j + 1] - s[j])))
    vf = np.empty(n + 1)
    vf[0] = min(v_start, vb[0])
    for j in range(n):
        vf[j + 1] = min(vb[j + 1], math.sqrt(vf[j] * vf[j] + 2.0 * acap[j] * (s[j + 1] - s[j])))
    return vf


@njit(cache=True)
def _rest(out, m, t, s, dwell, period):
    """The tool at rest at s from t until the next tick, and for *dwell* more rounded up to whole ticks."""
    hold = math.ceil(t / period - 1e-9) * period
    if dwell > 0.0:
        hold = math.ceil((hold + dwell) / period - 1e-9) * period
    if hold > t:
        out = _push(out, m, t, s, 0.0, 0.0, HOLD)
        return out, m + 1, hold
    return out, m, t


@njit(cache=True)
def pieces(s, v, vcap, acap, stop, dwell, t0, period, c):
    """The constant-acceleration pieces [t, s, v, a, 0] of intervals 0 .. c−1 from time t0, and the time at
    node c.

    Each interval: up at its acceleration cap from v[j] to vp = min(cap, sqrt((v[j]² + v[j+1]²)/2 + a L)),
    cruise, down to v[j+1].  At a node where the feedrate is 0 (a stop) the tool rests until the next tick
    (so that no tick straddles the stop, whose corner a tick's chord would cut), and for its dwell, rounded up
    to whole ticks: *stop*/*dwell* (per node) say which nodes are the program's stops."""
    out = np.empty((max(16, 3 * c + 4), 5))
    m = 0
    t = t0
    for j in range(c):
        if j > 0 and v[j] == 0.0:
            out, m, t = _rest(out, m, t, s[j], dwell[j], period)
        L = s[j + 1] - s[j]
        a = acap[j]
        v0 = v[j]
        v1 = v[j + 1]
        vp2 = min(vcap[j] * vcap[j], 0.5 * (v0 * v0 + v1 * v1) + a * L)
        vp = max(math.sqrt(vp2), v0, v1)
        t1 = (vp - v0) / a
        t3 = (vp - v1) / a
        d1 = 0.5 * t1 * (vp + v0)
        d3 = 0.5 * t3 * (vp + v1)
        d2 = L - d1 - d3
        if d2 < 0.0:
            d2 = 0.0
        if t1 > 0.0:
            out = _push(out, m, t, s[j], v0, a, HOLD)
            m += 1
            t += t1
        if d2 > 0.0 and vp > 0.0:
            out = _push(out, m, t, s[j] + d1, vp, 0.0, HOLD)
            m += 1
            t += d2 / vp
        if t3 > 0.0:
            out = _push(out, m, t, s[j + 1] - d3, vp, -a, HOLD)
            m += 1
            t += t3
    if c > 0 and v[c] == 0.0:  # the end of a stop is on a tick (and its dwell) before the next piece starts
        out, m, t = _rest(out, m, t, s[c], dwell[c], period)
    return out[:m], t


@njit(cache=True)
def commit_index(s, ncap, vcap, acap, v_start):
    """The last node of a window that is final (see the module's docstring): 0 when none is."""
    n = s.shape[0] - 1
    vmax = v_start
    amin = math.inf
    for j in range(n):
        vmax = max(vmax, vcap[j])
        amin = min(amin, acap[j])
    brake = vmax * vmax / (2.0 * amin)
    limit = s[n] - brake
    c = 0
    for j in range(n + 1):
        if s[j] <= limit:
            c = j
        else:
            break
    return c


class Window:
    """The segments not yet committed, and the state at the first of them.

    Attributes: rows (n, NCOL) with S0 set; v_start (mm/s at the first node); t_start (s)."""

    def __init__(self, period: float):
        self.period = period
        self.rows = np.empty((0, seg.NCOL))
        self.v_start = 0.0
        self.t_start = 0.0
        self.s_end = 0.0  # arc length at the end of the last segment

    def add(self, rows):
        """Append a batch's segment rows (their S0 is set here)."""
        if rows.shape[0] == 0:
            return
        # one running sum from the program's start, in order, whatever the batches: the arc lengths (and so the
        # plan) of a program do not depend on how it was cut into windows
        ends = np.cumsum(np.concatenate([[self.s_end], rows[:, seg.LEN]]))
        rows[:, seg.S0] = ends[:-1]
        self.s_end = float(ends[-1])
        self.rows = rows if self.rows.shape[0] == 0 else np.concatenate([self.rows, rows])

    def nodes(self, finished: bool):
        rows = self.rows
        n = rows.shape[0]
        s = np.empty(n + 1)
        s[:n] = rows[:, seg.S0]
        s[n] = self.s_end
        vcap = rows[:, seg.VCAP]
        ncap = np.empty(n + 1)
        ncap[:n] = rows[:, seg.NODECAP]
        ncap[1:n] = np.minimum(ncap[1:n], np.minimum(vcap[:-1], vcap[1:]))
        ncap[0] = min(ncap[0], vcap[0]) if n else 0.0
        ncap[n] = 0.0
        stop = np.zeros(n + 1)
        stop[:n] = rows[:, seg.STOP]
        dwell = np.zeros(n + 1)
        dwell[:n] = rows[:, seg.DWELL]
        stop[n] = 1.0 if finished else 0.0
        return s, ncap, vcap, rows[:, seg.ACAP], stop, dwell

    def plan(self, finished: bool):
        """Plan the window; commit what is final (everything when *finished*).

        Returns (pieces (m, 5), committed rows (c, NCOL), the time at the end of the committed part).  The
        committed rows leave the window."""
        n = self.rows.shape[0]
        if n == 0:
            return np.empty((0, 5)), self.rows[:0], self.t_start
        s, ncap, vcap, acap, stop, dwell = self.nodes(finished)
        c = n if finished else int(commit_index(s, ncap, vcap, acap, self.v_start))
        if c == 0:
            return np.empty((0, 5)), self.rows[:0], self.t_start
        v = scan(s, ncap, vcap, acap, self.v_start, 0.0)
        table, t_end = pieces(s, v, vcap, acap, stop, dwell, self.t_start, self.period, c)
        committed = self.rows[:c]
        self.rows = self.rows[c:]
        self.v_start = float(v[c])
        self.t_start = float(t_end)
        return table, committed, t_end
