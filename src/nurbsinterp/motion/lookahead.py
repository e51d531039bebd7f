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
from ..planner.jerk import _jerk_window, _pass_bounds, _push, _stop_distance
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

    def start_at(self, t: float) -> None:
        """The motion starts at time *t* (s), the tool at rest on the path's start before it (a dwell there)."""
        self.t_start = t

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
        # the columns copied into arrays of their own: a column view of a one-row window is contiguous, of a
        # longer one strided, and numba compiles the kernels once per layout (a second specialisation each)
        vcap = np.ascontiguousarray(rows[:, seg.VCAP])
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
        return s, ncap, vcap, np.ascontiguousarray(rows[:, seg.ACAP]), stop, dwell

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


#: steps of the jerk-limited pass one window may take before the run is refused (a hang, not a plan)
MAX_PASS_STEPS = 50_000_000


@njit(cache=True)
def section_nodes(s0, rows, end, s_last, jerk, jerk_top):
    """The jerk-limited pass's nodes, caps and acceleration caps over rows[:end] from the arc length s0 (inside
    rows[0]) to s_last (the end of rows[end − 1]): an interval per row, and a joint's own cap (NODECAP below both
    rows' VCAP) as an interval of zero length at its node, whose cap the pass's range minima then meet wherever
    a piece crosses it.  The jerk caps: each row's JCAP within [jerk, jerk_top]."""
    extra = 0
    for r in range(1, end):
        if rows[r, seg.NODECAP] < min(rows[r - 1, seg.VCAP], rows[r, seg.VCAP]):
            extra += 1
    nodes = np.empty(end + extra + 1)
    caps = np.empty(end + extra)
    acaps = np.empty(end + extra)
    jcaps = np.empty(end + extra)
    nodes[0] = s0
    k = 0
    for r in range(end):
        if r > 0 and rows[r, seg.NODECAP] < min(rows[r - 1, seg.VCAP], rows[r, seg.VCAP]):
            caps[k] = rows[r, seg.NODECAP]
            acaps[k] = min(rows[r - 1, seg.ACAP], rows[r, seg.ACAP])
            jcaps[k] = max(min(rows[r - 1, seg.JCAP], rows[r, seg.JCAP], jerk_top), jerk)
            nodes[k + 1] = nodes[k]
            k += 1
        caps[k] = rows[r, seg.VCAP]
        acaps[k] = rows[r, seg.ACAP]
        jcaps[k] = max(min(rows[r, seg.JCAP], jerk_top), jerk)
        nodes[k + 1] = rows[r + 1, seg.S0] if r + 1 < end else s_last
        k += 1
    return nodes, caps, acaps, jcaps


class JerkWindow:
    """The windowed look-ahead with a jerk limit: the jerk-limited pass (planner.jerk._jerk_window) over the
    segments not yet committed.

    The pass plans rest to rest: a section ends at the program's stops (a STOP row, a joint of cap 0) and at its
    end.  A section held whole in the window is planned to its end; otherwise the pass goes on to a commit point
    a horizon before the window's end, beyond which nothing the pass decides there can reach (the braking
    distance from the window's highest cap at its lowest acceleration cap, and a step: _jerk_window's
    docstring), and hands its state over (time, brake level, last piece) to the next window.  Every state the
    pass reaches is certified by a braking manoeuvre that keeps every cap and stops before the window's end,
    which lies before the next window's end: so the plan can stop inside every window.  Rows are committed as
    the pass leaves them; a row the pass is inside stays, and is handed to the ticks again with the next
    window's pieces.

    Attributes as :class:`Window`'s; *jerk* (mm/s³) the pass's tangential jerk where the segments say nothing
    (JCAP), and its braking manoeuvres' everywhere; *jerk_top* the most a segment's JCAP may give its steps;
    *step* (s) the pass's time step."""

    def __init__(self, period: float, jerk: float, jerk_top: float | None = None, step: float | None = None):
        self.period = period
        self.jerk = jerk
        self.jerk_top = jerk if jerk_top is None else jerk_top
        self.step = period if step is None else step
        self.rows = np.empty((0, seg.NCOL))
        self.s_end = 0.0
        self.t_start = 0.0
        self.v_start = 0.0
        self.s = 0.0  # the pass's arc length (inside rows[0])
        self.a = 0.0
        self.carry = None  # Handover of the pass, None at a section's start (at rest)
        self.t_section = 0.0  # the time the section started at (the pass's clock starts at 0 in each)

    add = Window.add

    def start_at(self, t: float) -> None:
        self.t_start = self.t_section = t

    def _stop_index(self):
        """The first row (after the first) whose start is a stop, or None."""
        rows = self.rows
        stops = np.flatnonzero((rows[1:, seg.STOP] != 0) | (rows[1:, seg.NODECAP] == 0))
        return int(stops[0]) + 1 if stops.shape[0] else None

    def plan(self, finished: bool):
        tables = []
        emitted = []
        while self.rows.shape[0]:
            stop = self._stop_index()
            end = stop if stop is not None else (self.rows.shape[0] if finished else None)
            whole = end is not None
            n = self.rows.shape[0]
            last = (float(self.rows[end, seg.S0]) if end < n else self.s_end) if whole else self.s_end
            nodes, caps, acaps, jcaps = section_nodes(self.s, self.rows, end if whole else n, last, self.jerk,
                                                      self.jerk_top)
            bd = _pass_bounds(nodes, caps, acaps)
            J = self.jerk
            # the pass ends a section at rest within end_tol short of its node (or the rounding allowance past it),
            # and the tool is put on the node: a step of that size in the last ticks, whose third difference
            # (size / T³: 1e-10 of a 5 mm window is 0.5 mm/s³ at T = 1 ms) the jerk caps above J leave room for
            snap = (bd.end_tol + 1e-13 * max(abs(last), last - self.s)) / self.period ** 3
            jcaps = np.maximum(jcaps - snap, J)
            coarse = self.step > bd.a_top / J / 8.0
            if whole:
                s_commit = math.inf
            else:
                horizon = (bd.v_top * self.step + bd.v_top * bd.a_top / J
                           + _stop_distance(bd.v_top, 0.0, J, bd.a_floor) + 2.0 * math.sqrt(bd.v_top ** 3 / J))
                s_commit = nodes[-1] - horizon
                if s_commit <= self.s:
                    break
            out, status, state, carry = _jerk_window(nodes, caps, acaps, self.jerk, self.step, MAX_PASS_STEPS,
                                                     coarse, self.v_start, self.a, s_commit, None, self.carry, jcaps)
            if status == 1 or status == 3:
                raise RuntimeError(f"the jerk-limited pass stalled at s = {self.s:.9g} mm (status {status})")
            pieces = out[:-1]
            if self.carry is not None and self.carry.last[0] == self.carry.last[0]:
                # the piece the last window ended in goes on here (a cruise extends it rather than starting a
                # new one): the ticks between that window's end and this window's first piece are on it
                pieces = np.concatenate([np.array([self.carry.last]), pieces])
            else:
                pieces = pieces.copy()
            pieces[:, 0] += self.t_section
            s, v, a = state
            t = carry.t + self.t_section
            if whole:
                # the section's end, at rest: the tool waits there for the next tick, and the stop's dwell
                node = float(nodes[-1])
                dwell = float(self.rows[end, seg.DWELL]) if end < self.rows.shape[0] else 0.0
                rest, m, t = _rest(np.empty((1, 5)), 0, t, node, dwell, self.period)
                pieces = np.concatenate([pieces, rest[:m]])
                emitted.append(self.rows[:end])
                self.rows = self.rows[end:]
                self.s = node
                self.v_start = 0.0
                self.a = 0.0
                self.carry = None
                self.t_section = t
            else:
                # rows the pass has left behind go; the one it is inside stays for the next window too
                ends = self.rows[:, seg.S0] + self.rows[:, seg.LEN]
                gone = int(np.searchsorted(ends, s, side="right"))
                gone = min(gone, self.rows.shape[0] - 1)
                inside = int(np.searchsorted(self.rows[:, seg.S0], s, side="right"))
                emitted.append(self.rows[:max(inside, gone, 1)])
                self.rows = self.rows[gone:]
                self.s = s
                self.v_start = v
                self.a = a
                self.carry = carry
            tables.append(pieces)
            self.t_start = t
            if not whole:
                break
        if not tables:
            return np.empty((0, 5)), self.rows[:0], self.t_start
        rows = emitted[0] if len(emitted) == 1 else _unique_rows(emitted)
        return np.concatenate(tables), rows, self.t_start


def _unique_rows(parts):
    """The rows of several commits in order, a row handed over twice (the one a window ended inside: a part's
    first row, the same as the last part's last) once.  Not by S0: a row of rounding length (3e-17 mm of a line a
    blend took nearly whole) has the S0 of the row after it, which was dropped with it, and the ticks over that
    row stood on the short one's end and then jumped (vcarve.ngc under a jerk limit: 1.4 µm in one tick)."""
    out = [parts[0]]
    last = parts[0][-1] if parts[0].shape[0] else None
    for p in parts[1:]:
        if p.shape[0] and last is not None and np.array_equal(p[0], last, equal_nan=True):
            p = p[1:]
        if p.shape[0]:
            out.append(p)
            last = p[-1]
    return np.concatenate(out)
