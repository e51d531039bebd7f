"""Step 2 of the algorithm in :mod:`nurbsinterp.planner`: the grid, taken block by block, split at the stops into
rest-to-rest sections; and what the plan reports of the grid (where each limit binds, the slowest point).

What outlives the grid's blocks is kept here, in memory maps that grow without copies (:class:`_Growable`):
per point of the sections its arc length, V_lim and, where axis accelerations make it vary, the tangential
bound — the nodes and caps the forward pass reads — and per grid interval its length by the limit that binds
there, for the limit fractions: 24 to 32 bytes a point, where the whole grid held ~500.
"""
from __future__ import annotations

import mmap

import numpy as np

from .._jit import njit
from .grid import CORNER_COS, _Grid, _grid_blocks
from .limits import LIMITS, _Limits

MAPPED = 1 << 16  # a section of more nodes than this keeps them where they were gathered (see _SectionBuilder)


class _Growable:
    """A float64 vector that grows without being copied: an anonymous memory map, enlarged in place (mremap).

    The grid's points come block by block, and how many there will be is known only at the end.  A
    numpy vector grown by doubling copies itself (three times its size at that moment), and parts
    kept per block lie in the heap among the blocks' work arrays, which keeps them from being given
    back when they are freed (measured: +50 MB of RSS at 10⁵ control points, where the sections were
    copied out of them).  A memory map holds only the pages written, is enlarged by remapping them,
    and is given back whole when the last array on it goes.  Where the system cannot remap, it is
    copied into a larger one.
    """

    def __init__(self):
        self.map = mmap.mmap(-1, mmap.PAGESIZE, flags=mmap.MAP_PRIVATE)  # private: a shared one cannot grow
        self.size = 0

    def append(self, x):
        n = x.shape[0]
        if (self.size + n) * 8 > len(self.map):
            self._grow(max((self.size + n) * 8, 2 * len(self.map)))
        if n:
            np.frombuffer(self.map, np.float64, n, self.size * 8)[:] = x
        self.size += n

    def _grow(self, nbytes):
        nbytes = -(-nbytes // mmap.PAGESIZE) * mmap.PAGESIZE
        try:
            self.map.resize(nbytes)
        except (OSError, SystemError):  # no mremap
            bigger = mmap.mmap(-1, nbytes, flags=mmap.MAP_PRIVATE)
            bigger[:self.size * 8] = self.map[:self.size * 8]
            self.map.close()
            self.map = bigger

    def values(self):
        """The values, as a writable array on the map (which it keeps alive, and which cannot grow meanwhile)."""
        return np.frombuffer(self.map, np.float64, self.size, 0) if self.size else np.empty(0)


# --------------------------------------------------------------------------- what the plan reports of the grid


class _Summary:
    """What the plan reports of the grid, taken block by block: where each limit binds, and the slowest point.

    limit_fractions: the fraction of the path length where each limit binds V_lim, summing per limit
    the lengths of the grid intervals whose lower end it binds.  The lengths are kept per limit, in
    order, and summed at the end as one vector each (8 bytes per grid interval), as
    ``ds[lower == i].sum()`` summed them on the whole grid, to the bit.
    """

    def __init__(self, length: float):
        self.length = float(length)
        self.steps = [_Growable() for _ in LIMITS]  # per limit: arc-length steps of the intervals it binds, in order
        self.points = 0
        self.last = None  # (s, v_limit, binding) of the last point of the previous block
        self.best = None  # (V_lim or inf next to a stop, s, u, V_lim, binding) of the slowest point so far

    def add(self, g: _Grid):
        self.points += g.s.shape[0]
        s, vl, binding = g.s, g.v_limit, g.binding
        if self.last is not None:
            s, vl, binding = (np.concatenate([a, b]) for a, b in zip(self.last, (s, vl, binding)))
        ds = np.diff(s)
        lower = np.where(vl[:-1] <= vl[1:], binding[:-1], binding[1:])
        for i, steps in enumerate(self.steps):
            steps.append(ds[lower == i])
        self.last = (s[-1:].copy(), vl[-1:].copy(), binding[-1:].copy())
        # a zero-speed end's V_lim is 0 by decree (a stop), and next to it rounding: not a limit to report
        values = np.where(g.near, np.inf, g.v_limit)
        k = int(np.argmin(values))
        if self.best is None or values[k] < self.best[0]:
            self.best = (values[k], g.s[k], g.u[k], g.v_limit[k], g.binding[k])

    def fractions(self) -> dict:
        """Limit name -> fraction of the path length where it binds V_lim (once: the lengths are freed)."""
        out = {name: 0.0 for name in LIMITS}
        if self.length <= 0 or self.points < 2:
            return out
        for i, name in enumerate(LIMITS):
            out[name] = float(self.steps[i].values().sum() / self.length)
        self.steps = None
        return out

    def slowest(self):
        """(s, u, V_lim, binding) at the point of lowest feed limit (away from the zero-speed ends)."""
        _, s, u, v, b = self.best
        return float(s), float(u), float(v), int(b)


# --------------------------------------------------------------------------- the sections


@njit(cache=True)
def _np_min(a, b):
    """np.minimum(a, b) of two floats: a if a < b or a is NaN, else b (as feed._np_min: a kernel of this file)."""
    return a if (a < b or a != a) else b


@njit(cache=True)
def _merge_nodes(s, vl, at, tol, accel):
    """Merge the points of a section at the same arc length, in place: the first point of each group (a gap
    above tol to the point before starts one) and the smallest V_lim (and tangential bound, if *accel*) of
    the group, packed to the front.  Returns the number of groups."""
    g = -1
    prev = np.nan
    for i in range(s.shape[0]):
        x = s[i]
        v = vl[i]
        a = at[i] if accel else 0.0
        if i == 0 or x - prev > tol:
            g += 1
            s[g] = x
            vl[g] = np.inf
            if accel:
                at[g] = np.inf
        prev = x
        vl[g] = _np_min(vl[g], v)
        if accel:
            at[g] = _np_min(at[g], a)
    return g + 1


@njit(cache=True)
def _floor_nodes(nodes, vmin, lo, hi, tol, floor):
    """V_lim <= floor at the nodes inside the windows [lo, hi] (to tol), in place."""
    for i in range(nodes.shape[0]):
        w = np.searchsorted(lo, nodes[i] + tol, side="right") - 1  # the last window starting at or before the node
        if w >= 0 and nodes[i] - tol <= hi[w]:
            vmin[i] = _np_min(vmin[i], floor)


class _SectionBuilder:
    """Step 2, block by block: the grid split at the stops into rest-to-rest sections [(s nodes, V_lim at nodes,
    tangential bound at nodes)].

    At a smooth knot the two one-sided samples merge (the smaller limits win); at a corner they stay
    apart, ending one section and starting the next.  A zero-speed span end with V_lim = 0 (a
    curvature limit is set) is a stop too.  V_lim is at most *floor* within *reach* of arc length of
    every tight point (radius below the chord tolerance; see "Tight turns" in
    :mod:`nurbsinterp.planner`).  Where no axis acceleration limit is set the tangential bound is
    max_accel (or inf) at every point: it is then not stored, but returned as that value broadcast
    over the nodes (a read-only view of one float).
    """

    def __init__(self, lim: _Limits):
        self.accel = lim.has_axis_accel
        self.accel_value = np.float64(np.inf if lim.max_accel is None else lim.max_accel)
        self.floor, self.reach = lim.tight_turn
        self.carry = None  # the last point of the previous block, which meets the next block's first at a knot
        self.columns = self._columns()  # s, V_lim, tangential bound of the open section's points
        self.last_s = None  # the arc length of its last point so far
        self.closed = []
        self.tight = []  # arc lengths of the tight points

    def add(self, g: _Grid):
        cols = (g.s, g.v_limit, g.acc_t, g.span, g.singular, g.near, g.tangent)
        if self.carry is not None:
            cols = tuple(np.concatenate([a, b]) for a, b in zip(self.carry, cols))
        self.tight.append(g.s[g.tight])
        self._split(cols, last=False)
        self.carry = tuple(c[-1:].copy() for c in cols)

    def sections(self):
        """The sections, once every block is added."""
        if self.carry is not None:
            self._split(self.carry, last=True)
            self.carry = None
        lo_w, hi_w = _tight_windows(np.concatenate(self.tight), self.reach)
        out = self.closed
        if lo_w.size:
            out = [_floor_windows(*sec, lo_w, hi_w, self.floor) for sec in out]
        self.closed = []
        return out

    def _split(self, cols, last: bool):
        s, vl, at, span, singular, near, tangent = cols
        n = s.shape[0]
        boundary = np.flatnonzero(span[1:] != span[:-1])  # pairs (k, k+1) at a knot
        stop = singular & (vl == 0.0)
        corner = ~(np.einsum("ij,ij->i", tangent[boundary], tangent[boundary + 1]) >= CORNER_COS) \
            | stop[boundary] | stop[boundary + 1]
        # A stop's V_lim = 0 belongs to the point only: V = 0 there anyway.  The interval next to it was
        # halved down to the samples taken into the stop (V_lim changes from 0), which are left out,
        # and takes its cap from its other end.
        vl = np.where(stop, np.inf, vl)
        at = at.copy()
        drop = near & ~singular
        smooth = boundary[~corner]
        vl[smooth] = np.minimum(vl[smooth], vl[smooth + 1])
        at[smooth] = np.minimum(at[smooth], at[smooth + 1])
        drop[smooth + 1] = True
        a = 0
        for c in boundary[corner] + 1:
            self._emit(s, vl, at, drop, a, c)
            self._close()
            a = c
        # the block's last point is kept back: the next block's first may merge into it, or cut after it
        self._emit(s, vl, at, drop, a, n if last else n - 1)
        if last:
            self._close()

    def _emit(self, s, vl, at, drop, a, b):
        keep = np.flatnonzero(~drop[a:b]) + a
        if keep.size:
            self.last_s = s[keep[-1]]
        for column, values in zip(self.columns, (s, vl, at)):
            if column is not None:
                column.append(values[keep])

    def _columns(self):
        return _Growable(), _Growable(), _Growable() if self.accel else None

    def _close(self):
        """Merge the open section's nodes at the same arc length (a refined minimum on top of a sample: the
        smaller limits win), and keep the section if it has length.

        The nodes are merged where they were gathered.  A large section keeps them there (its arrays are
        views of the maps, which go with them) and the next section starts new ones; a small one is
        copied out, and the maps are reused.
        """
        tol = 1e-13 * max(abs(self.last_s), 1.0)
        self.last_s = None
        s_col, vl_col, at_col = self.columns
        nodes, vmin = s_col.values(), vl_col.values()
        amin = at_col.values() if self.accel else nodes
        m = _merge_nodes(nodes, vmin, amin, tol, self.accel)
        nodes, vmin, amin = nodes[:m], vmin[:m], amin[:m]
        if m > MAPPED:
            self.columns = self._columns()
        else:
            nodes, vmin, amin = nodes.copy(), vmin.copy(), amin.copy()
            for column in self.columns:
                if column is not None:
                    column.size = 0
        if not self.accel:
            amin = np.broadcast_to(self.accel_value, (m,))
        if nodes.shape[0] >= 2 and nodes[-1] > nodes[0]:
            if np.isinf(vmin[0]):
                vmin[0] = vmin[1]
            if np.isinf(vmin[-1]):
                vmin[-1] = vmin[-2]
            if nodes.shape[0] == 2:  # the scan needs a node between the two stops (V = 0 at both)
                nodes = np.array([nodes[0], 0.5 * (nodes[0] + nodes[1]), nodes[1]])
                vmin = np.array([vmin[0], vmin.min(), vmin[1]])
                amin = np.array([amin[0], amin.min(), amin[1]]) if self.accel else np.broadcast_to(amin[0], (3,))
            self.closed.append((nodes, vmin, amin))


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
        amin = np.insert(amin, k, np.minimum(amin[k - 1], amin[k])) if amin.strides[0] else \
            np.broadcast_to(amin[0], nodes.shape)
    _floor_nodes(nodes, vmin, lo, hi, tol, floor)
    return nodes, vmin, amin


def _grid_sections(curve, lim, samples, resolution, span_feedrates=None):
    """Steps 1 and 2 in one pass over the grid's blocks: (sections, :class:`_Summary`)."""
    summary = _Summary(curve.length)
    builder = _SectionBuilder(lim)
    for g in _grid_blocks(curve, lim, samples, resolution, span_feedrates):
        summary.add(g)
        builder.add(g)
    return builder.sections(), summary
