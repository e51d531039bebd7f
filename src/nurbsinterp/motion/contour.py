"""The contour error against a program's blocks, window by window: the programmed path a stream of the look-ahead
was planned from, read alongside the stream, never held whole.

A tick of a look-ahead stream names its block (the ``n`` column).  The distance of a position from the programmed
path is the least exact distance from the blocks around that block: those whose arc length lies within
*reach* of it, reach = 2 (|position − command| + tolerance) — the nearest point of the path lies within
|position − command| + tolerance of the position (the command is within the tolerance of the path), so within
twice that of the command's own foot.  A path that comes back near itself further along (a raster's next row)
is not looked at: the contour error is the distance from the path being cut, as it is everywhere else in this
tool (PathWindow's windows).

Exact distances: a line by projection clamped to its ends; a circular arc by the radial projection when it falls
within the sweep (sqrt(h² + (ρ − R)²), h the height over the arc's plane, ρ the distance from its axis), else the
nearer end; a helix (no closed form) by sampling every π/16 of its sweep and a golden-section search, to 1e-12 of
the sweep, in the bracket of the nearest sample; a NURBS block by the curve's own closest point
(NurbsCurve.closest_point: every knot span searched, then Newton), outside the kernel, for the points whose
reach takes that block in.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from . import segments as seg

GOLDEN_STEPS = 64  # 0.618^64 = 4e-14 of the bracket
HELIX_SAMPLE = math.pi / 16.0  # rad between a helix's samples: one basin of |p − H(θ)| each


@njit(cache=True)
def _line_foot(p, a, b):
    """(t in [0, 1], distance) of p from the segment a → b."""
    den = 0.0
    num = 0.0
    for i in range(3):
        d = b[i] - a[i]
        den += d * d
        num += (p[i] - a[i]) * d
    t = 0.0 if den == 0.0 else min(1.0, max(0.0, num / den))
    s = 0.0
    for i in range(3):
        d = a[i] + t * (b[i] - a[i]) - p[i]
        s += d * d
    return t, math.sqrt(s)


@njit(cache=True)
def _helix_distance2(p, base, e1, e2, N, R, lift, th):
    c = math.cos(th)
    s = math.sin(th)
    out = 0.0
    for i in range(3):
        d = base[i] + R * (c * e1[i] + s * e2[i]) + lift * th * N[i] - p[i]
        out += d * d
    return out


@njit(cache=True)
def _arc_foot(p, P0, C, N, sweep, rise):
    """(t in [0, 1] of the sweep, distance) of p from the arc (a helix where rise ≠ 0) of segments' convention:
    from P0 about the axis N through C, counterclockwise by *sweep*, rising by *rise* along N."""
    e1, e2, R = seg._arc_frame(P0, C, N)
    h0 = 0.0
    for i in range(3):
        h0 += (P0[i] - C[i]) * N[i]
    base = C + h0 * N
    if rise == 0.0:
        q = p - base
        h = q[0] * N[0] + q[1] * N[1] + q[2] * N[2]
        x = q[0] * e1[0] + q[1] * e1[1] + q[2] * e1[2]
        y = q[0] * e2[0] + q[1] * e2[1] + q[2] * e2[2]
        rho = math.hypot(x, y)
        if rho == 0.0:
            return 0.0, math.sqrt(h * h + R * R)
        phi = math.atan2(y, x)
        if phi < 0.0:
            phi += 2.0 * math.pi
        if phi <= sweep:
            return phi / sweep, math.sqrt(h * h + (rho - R) * (rho - R))
        d0 = _helix_distance2(p, base, e1, e2, N, R, 0.0, 0.0)
        d1 = _helix_distance2(p, base, e1, e2, N, R, 0.0, sweep)
        return (0.0, math.sqrt(d0)) if d0 <= d1 else (1.0, math.sqrt(d1))
    lift = rise / sweep
    k = max(2, int(math.ceil(sweep / HELIX_SAMPLE)))
    best = 0
    best_d = math.inf
    for j in range(k + 1):
        d = _helix_distance2(p, base, e1, e2, N, R, lift, sweep * j / k)
        if d < best_d:
            best_d = d
            best = j
    lo = sweep * max(best - 1, 0) / k
    hi = sweep * min(best + 1, k) / k
    g = 0.5 * (math.sqrt(5.0) - 1.0)
    a = hi - g * (hi - lo)
    b = lo + g * (hi - lo)
    fa = _helix_distance2(p, base, e1, e2, N, R, lift, a)
    fb = _helix_distance2(p, base, e1, e2, N, R, lift, b)
    for _ in range(GOLDEN_STEPS):
        if fa <= fb:
            hi = b
            b = a
            fb = fa
            a = hi - g * (hi - lo)
            fa = _helix_distance2(p, base, e1, e2, N, R, lift, a)
        else:
            lo = a
            a = b
            fa = fb
            b = lo + g * (hi - lo)
            fb = _helix_distance2(p, base, e1, e2, N, R, lift, b)
    th = 0.5 * (lo + hi)
    d = _helix_distance2(p, base, e1, e2, N, R, lift, th)
    if d > best_d:  # the sample itself (an end of the sweep) is nearer
        th = sweep * best / k
        d = best_d
    return th / sweep, math.sqrt(d)


@njit(cache=True)
def block_foot(kind, P0, P1, C, N, sweep, rise, j, p):
    """(t, distance) of p from block j of the arrays (a NURBS block, CURVE: none here, see ProgramWindow.nearest)."""
    if kind[j] == seg.LINE:
        return _line_foot(p, P0[j], P1[j])
    if kind[j] == seg.CURVE:
        return 0.0, math.inf
    return _arc_foot(p, P0[j], C[j], N[j], sweep[j], rise[j])


@njit(cache=True)
def nearest_on_blocks(kind, P0, P1, C, N, sweep, rise, S, base, points, seeds, reach, foot, dist):
    """The nearest point of the blocks around each point's seed block (see the module's docstring).

    Block arrays (K,) or (K, 3) of blocks base .. base + K − 1 of the program, S (K + 1,) their ends' arc lengths
    from any origin; points (m, 3); seeds (m,) the program's block index of each point's command; reach (m,) mm.
    Into foot the block index plus the fraction t of it, into dist the distance."""
    K = kind.shape[0]
    p = np.empty(3)
    for i in range(points.shape[0]):
        b = min(max(int(seeds[i]) - base, 0), K - 1)
        lo = b
        while lo > 0 and S[b] - S[lo] < reach[i]:
            lo -= 1
        hi = b
        while hi < K - 1 and S[hi + 1] - S[b + 1] < reach[i]:
            hi += 1
        for c in range(3):
            p[c] = points[i, c]
        best = math.inf
        where = float(b)
        for j in range(lo, hi + 1):
            t, d = block_foot(kind, P0, P1, C, N, sweep, rise, j, p)
            if d < best:
                best = d
                where = base + j + t
        foot[i] = where
        dist[i] = best


def item_arrays(item):
    """(kind, P0, P1, C, N, sweep, rise) of a path item: a block, or a run of straight moves (config.gcode)."""
    if item.kind == "moves":
        n = item.starts.shape[0]
        return (np.zeros(n, np.int64), np.asarray(item.starts, float), np.asarray(item.ends, float),
                np.zeros((n, 3)), np.zeros((n, 3)), np.ones(n), np.zeros(n))
    d = item.start.shape[0]
    P0 = np.zeros((1, 3))
    P1 = np.zeros((1, 3))
    P0[0, :d] = item.start
    P1[0, :d] = item.end
    C = np.zeros((1, 3))
    N = np.zeros((1, 3))
    if item.kind == "arc":
        C[0, :d] = item.center
        N[0] = item.normal
        return np.array([seg.ARC]), P0, P1, C, N, np.array([item.sweep]), np.array([item.rise])
    if item.kind == "line":
        return np.array([seg.LINE]), P0, P1, C, N, np.ones(1), np.zeros(1)
    return np.array([seg.CURVE]), P0, P1, C, N, np.ones(1), np.zeros(1)  # NURBS: ProgramWindow measures it


def block_lengths(kind, P0, P1, C, N, sweep, rise):
    """Each block's length, mm (a NURBS block's chord: ProgramWindow puts its curve's length)."""
    out = np.linalg.norm(P1 - P0, axis=1)
    for j in np.flatnonzero(kind == seg.ARC):
        _, _, R = seg._arc_frame(P0[j], C[j], N[j])
        out[j] = math.hypot(R * sweep[j], rise[j])
    return out


class ProgramWindow:
    """The programmed blocks around the ticks of a stream, read from the program as the stream advances.

    *items*: the path's items in order (``ProgramStream.items()`` or a path's blocks); *tolerance*: how far the
    commands may lie from the path (the plan's blend tolerance; None: the program's own G64 P, the largest of the
    blocks read so far, which bounds that of every block up to the one after the furthest tick asked for; at least
    *own_default*, the tolerance of the blocks that state none: profile.corner_tolerance).  :meth:`nearest` has
    PathWindow's form: (foot, distance) of positions given their commands' block indices (*seeds*) and the
    commands."""

    KEEP = 10.0  # mm of path kept behind the earliest block asked for, beyond the reach (a lag that grows)
    READ = 4096  # blocks read at a time

    def __init__(self, items, tolerance: float | None, dim: int = 3, name: str = "<program>",
                 own_default: float = 0.0):
        self._items = iter(items)
        self.own = tolerance is None
        self.tolerance = float(own_default) if self.own else float(tolerance)
        self.dim = dim
        self.name = name
        self.base = 0
        self.arrays = tuple(np.empty((0, 3)) if k in (1, 2, 3, 4) else np.empty(0, np.int64 if k == 0 else float)
                            for k in range(7))
        self.S = np.zeros(1)
        self.ended = False
        self.searched = 0
        self.closed = False
        self.curves = {}  # the program's index of each NURBS block in the window: its NurbsCurve

    @property
    def count(self) -> int:
        """The program's blocks read so far."""
        return self.base + self.arrays[0].shape[0]

    def _read(self):
        """Read the next READ blocks or so (a run of moves whole), appended at once."""
        parts = []
        count = 0
        curves = {}
        while count < self.READ:
            item = next(self._items, None)
            if item is None:
                self.ended = True
                break
            parts.append(item_arrays(item))
            if item.kind == "nurbs":
                from ..nurbs import NurbsCurve

                curves[self.count + count] = NurbsCurve.from_spec(item.curve)
            count += parts[-1][0].shape[0]
            mode = item.mode
            if self.own and mode.control == "blend" and mode.tolerance is not None:
                self.tolerance = max(self.tolerance, float(mode.tolerance))
        if not parts:
            return
        new = tuple(np.concatenate(a) for a in zip(*parts))
        lengths = block_lengths(*new)
        for j, curve in curves.items():
            lengths[j - self.count] = curve.length
        self.curves.update(curves)
        self.arrays = tuple(np.concatenate([a, b]) for a, b in zip(self.arrays, new))
        self.S = np.concatenate([self.S, self.S[-1] + np.cumsum(lengths)])

    def _trim(self, first: int, behind: float):
        """Drop the blocks that end more than *behind* mm before block *first* starts."""
        k = first - self.base
        if k <= 0:
            return
        cut = int(np.searchsorted(self.S[1:k + 1], self.S[k] - behind, side="left"))
        if cut > 0:
            self.arrays = tuple(a[cut:] for a in self.arrays)
            self.S = self.S[cut:]
            self.base += cut
            for j in [j for j in self.curves if j < self.base]:
                del self.curves[j]

    def nearest(self, positions, seeds, commands):
        """(foot, distance) of each position (m, dim): foot is the block index plus the fraction of the block.

        *seeds*: each command's block index plus its own u (a look-ahead stream's n + u)."""
        m = positions.shape[0]
        foot, dist = np.empty(m), np.empty(m)
        if m == 0:
            return foot, dist
        pts = np.zeros((m, 3))
        pts[:, :self.dim] = positions
        # a seed is the block's index plus its u in [0, 1]: u = 1 (the block's end) is still that block's
        seeds = np.maximum(np.ceil(np.asarray(seeds, dtype=float)) - 1.0, 0.0)
        top = int(seeds.max())
        if top < self.base:
            raise ValueError("a block before the window")
        while not self.ended and self.count <= top + 1:
            self._read()
        # the tolerance now covers every block up to the one after the furthest seed (the program's own: read so far)
        reach = 2.0 * (np.linalg.norm(positions - commands, axis=1) + self.tolerance) + 1e-9
        far = float(reach.max())
        while not self.ended and self.S[-1] - self.S[top + 1 - self.base] < far:
            self._read()
        if top >= self.count:
            from ..errors import StreamError

            raise StreamError(f"{self.name}: a tick names block {top}, beyond the program's {self.count} blocks: "
                              "is this stream from this job?")
        self._trim(int(seeds.min()), far + self.KEEP)
        kind, P0, P1, C, N, sweep, rise = self.arrays
        nearest_on_blocks(kind, P0, P1, C, N, sweep, rise, self.S, self.base, pts, seeds, reach, foot, dist)
        if self.curves:
            self._nearest_curves(positions, seeds, reach, foot, dist)
        return foot, dist

    def _nearest_curves(self, positions, seeds, reach, foot, dist):
        """The NURBS blocks' part of :meth:`nearest`: each block for the points whose reach takes it in (the
        kernel's window: block j before a point's block b while S[b] − S[j + 1] < reach, after it while
        S[j] − S[b + 1] < reach, b itself), measured by the curve's own closest point."""
        S = self.S
        K = self.arrays[0].shape[0]
        b = np.clip(seeds.astype(np.int64) - self.base, 0, K - 1)
        for index, curve in self.curves.items():
            j = index - self.base
            if j < 0 or j >= K:
                continue
            near = (b == j) | ((j < b) & (S[b] - S[j + 1] < reach)) | ((j > b) & (S[j] - S[b + 1] < reach))
            rows = np.flatnonzero(near)
            if not rows.size:
                continue
            u, d = curve.closest_point(np.ascontiguousarray(positions[rows]))
            a, z = curve.domain
            better = d < dist[rows]
            dist[rows[better]] = d[better]
            foot[rows[better]] = index + (u[better] - a) / (z - a)

    def points(self, feet):
        """The points (m, dim) of feet as :meth:`nearest` gives them (block index plus the fraction of it), of
        blocks still in the window: the plot's path, taken for the few ticks it keeps."""
        feet = np.asarray(feet, dtype=float)
        kind, P0, P1, C, N, sweep, rise = self.arrays
        K = kind.shape[0]
        j = np.floor(feet).astype(np.int64) - self.base
        if feet.shape[0] and (j.min() < 0 or j.max() > K):
            raise ValueError("a foot outside the window")
        t = feet - (j + self.base)
        end = j == K  # fraction 1 of the window's last block
        j[end] = K - 1
        t[end] = 1.0
        out = P0[j] + t[:, None] * (P1[j] - P0[j])
        for b in np.unique(j[kind[j] == seg.CURVE]):
            rows = np.flatnonzero(j == b)
            curve = self.curves[b + self.base]
            a, z = curve.domain
            out[rows, :curve.dim] = curve.evaluate(np.clip(a + t[rows] * (z - a), a, z))
        for b in np.unique(j[kind[j] == seg.ARC]):
            rows = np.flatnonzero(j == b)
            e1, e2, R = seg._arc_frame(P0[b], C[b], N[b])
            base = C[b] + float(np.dot(P0[b] - C[b], N[b])) * N[b]
            th = t[rows] * sweep[b]
            out[rows] = (base + R * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2)
                         + (rise[b] * t[rows])[:, None] * N[b])
        return out[:, :self.dim]
