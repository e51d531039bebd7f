"""Path geometry: the blocks of a toolpath as one exact NURBS, with its junctions and corner blends.

Every block is an exact NURBS — a line is degree 1, an arc is rational quadratic
(one piece per quarter turn at most), a nurbs block is itself — raised to the
path's highest degree (degree elevation is exact and keeps each block's own
parameter) and joined at knots of multiplicity p.  One curve then serves every
kernel (arc length, closest point, curvature, the per-tick interpolators): a
tick that crosses a junction is a tick that crosses a C⁰ knot, which the
interpolator already lands on the planned arc length.  Block i keeps its own
parameter: ``u_global = u_block + shift[i]``.

Corners.  A junction whose one-sided tangents differ by more than CORNER_ANGLE is
a corner: the motion stops there (the paper's rest-to-rest sections).  A path of
several blocks is planned here only under acc/dec after interpolation, whose filter
goes straight through its corners; every other one goes to the look-ahead
(motion.pipeline), which blends or passes its corners.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .config.curve import CurveSpec
from .config.path import ArcBlock, LineBlock, NurbsBlock, PathSpec
from .errors import SpecError
from .nurbs import NurbsCurve

CORNER_ANGLE = math.acos(1.0 - 1e-10)  # rad (1.4e-5): as the adaptive planner's stop test (planner CORNER_COS)
MAX_WEIGHT_SPREAD = 1e150  # joined blocks scale their weights to match at the joints; beyond this, refuse
HELIX_TOL = 1e-9  # mm: a helix (no NURBS is one) is approximated to within this along its axis
HELIX_DEGREE = 3


@dataclass(frozen=True)
class Junction:
    """Where block `index` ends and block `index + 1` starts."""

    index: int
    u: float  # global parameter
    s: float  # arc length along the programmed path, mm
    angle: float  # rad between the one-sided tangents
    corner: bool  # angle > CORNER_ANGLE


# --------------------------------------------------------------------------- blocks as NURBS


def _homogeneous(points, weights):
    return np.column_stack([points * weights[:, None], weights])


def block_nurbs(block):
    """(degree, homogeneous control points (n+1, dim+1), knots) of one block, exactly."""
    if isinstance(block, LineBlock):
        pts = np.vstack([block.start, block.end])
        return 1, _homogeneous(pts, np.ones(2)), np.array([0.0, 0.0, 1.0, 1.0])
    if isinstance(block, ArcBlock):
        return _arc_nurbs(block) if block.rise == 0.0 else _helix_nurbs(block)
    assert isinstance(block, NurbsBlock)
    c = block.curve
    return c.degree, _homogeneous(c.control_points, c.weights), np.array(c.knots, dtype=float)


def _arc_frame(block: ArcBlock):
    """(centre, radius, e1, e2) in 3-D: e1 towards the start, e2 a quarter turn on in the arc's direction."""
    c3 = np.append(block.center, 0.0)[:3]
    s3 = np.append(block.start, 0.0)[:3]
    r = float(np.linalg.norm(s3 - c3))
    e1 = (s3 - c3) / r
    return c3, r, e1, np.cross(block.normal, e1)


def _arc_nurbs(block: ArcBlock):
    dim = block.start.shape[0]
    c3, r, e1, e2 = _arc_frame(block)
    m = max(1, math.ceil(block.sweep / (math.pi / 2) - 1e-12))
    step = block.sweep / m
    w1 = math.cos(step / 2)
    pts, wts = [], []
    for k in range(m):
        a = k * step
        if k == 0:
            pts.append(c3 + r * e1)  # the start (set exactly below)
            wts.append(1.0)
        mid = a + step / 2
        pts.append(c3 + (r / w1) * (math.cos(mid) * e1 + math.sin(mid) * e2))
        wts.append(w1)
        end = a + step
        pts.append(c3 + r * (math.cos(end) * e1 + math.sin(end) * e2))
        wts.append(1.0)
    P = np.array(pts)[:, :dim]
    P[0] = block.start
    P[-1] = block.end
    inner = np.repeat(np.arange(1, m) / m, 2)
    U = np.concatenate([[0.0] * 3, inner, [1.0] * 3])
    return 2, _homogeneous(P, np.array(wts)), U


def _helix_nurbs(block: ArcBlock):
    """A helical arc as a cubic NURBS: its circle exact, its rise within HELIX_TOL.

    A helix is no rational curve, so it has no exact NURBS.  Each of m pieces is the
    circle's exact rational quadratic raised to degree 3; the rise's homogeneous
    coordinate W(t)·z(θ(t)) is the cubic Hermite interpolant of its value and
    derivative at both piece ends, so consecutive pieces share their tangent exactly
    and only z between the ends is approximate (error ~ rise/sweep · φ⁴, φ the piece's
    angle).  m doubles until the error, checked on 65 points a piece, is <= HELIX_TOL.
    """
    c3, r, e1, e2 = _arc_frame(block)
    lead = block.rise / block.sweep  # mm per radian
    t = np.linspace(0.0, 1.0, 65)[:, None]
    bern = np.hstack([(1 - t) ** 3, 3 * t * (1 - t) ** 2, 3 * t ** 2 * (1 - t), t ** 3])
    m = max(1, math.ceil(block.sweep / (math.pi / 8)))
    while True:
        step = block.sweep / m
        w1 = math.cos(step / 2)
        pieces = []
        worst = 0.0
        for k in range(m):
            a = k * step
            quad = np.array([[math.cos(a), math.sin(a), 1.0],
                             [math.cos(a + step / 2), math.sin(a + step / 2), w1],
                             [math.cos(a + step), math.sin(a + step), 1.0]])  # (w·cos, w·sin, w)
            cub = _elevate_bezier(quad, 1)
            W = cub[:, 2]
            # z(θ) = lead·θ, θ from a (local angle θ - a in [0, step]); dθ/dt at the ends of the
            # rational quadratic arc: 2·w1·tan(step/2) at t = 0 and t = 1 (its end speeds, over r)
            dtheta = 2.0 * w1 * math.tan(step / 2)
            dW0, dW1 = 3 * (W[1] - W[0]), 3 * (W[3] - W[2])
            z0, z1 = lead * a, lead * (a + step)
            N0, N1 = W[0] * z0, W[3] * z1
            dN0 = dW0 * z0 + W[0] * lead * dtheta
            dN1 = dW1 * z1 + W[3] * lead * dtheta
            Z = np.array([N0, N0 + dN0 / 3, N1 - dN1 / 3, N1])
            xw, yw, w = bern @ cub[:, 0], bern @ cub[:, 1], bern @ W
            theta = a + np.unwrap(np.mod(np.arctan2(yw, xw) - a + math.pi, 2 * math.pi) - math.pi)
            worst = max(worst, float(np.abs((bern @ Z) / w - lead * theta).max()))
            pieces.append(np.column_stack([cub, Z]))
        if worst <= HELIX_TOL or m >= 1 << 16:
            break
        m *= 2
    pts, wts = [], []
    for k, piece in enumerate(pieces):
        for j in range(0 if k == 0 else 1, 4):
            xw, yw, w, zw = piece[j]
            pts.append(c3 + r * (xw / w) * e1 + r * (yw / w) * e2 + (zw / w) * block.normal)
            wts.append(w)
    P = np.array(pts)
    P[0] = block.start
    P[-1] = block.end
    inner = np.repeat(np.arange(1, m) / m, HELIX_DEGREE)
    U = np.concatenate([[0.0] * (HELIX_DEGREE + 1), inner, [1.0] * (HELIX_DEGREE + 1)])
    return HELIX_DEGREE, _homogeneous(P, np.array(wts)), U


# --------------------------------------------------------------------------- exact NURBS operations


def insert_knot(p, Pw, U, u, times):
    """Boehm's knot insertion (Piegl & Tiller A5.1): (Pw, U) with u inserted *times* more times.

    The knots need not be clamped (the DXF reader clamps periodic splines with it)."""
    for _ in range(times):
        k = int(np.searchsorted(U, u, side="right")) - 1
        if U[k] == U[-1]:  # u at the end of the knots: the span that ends there
            k = int(np.searchsorted(U, u, side="left")) - 1
        s = int(np.count_nonzero(U == u))
        Q = np.empty((Pw.shape[0] + 1, Pw.shape[1]))
        Q[: k - p + 1] = Pw[: k - p + 1]
        Q[k - s + 1:] = Pw[k - s:]
        for i in range(k - p + 1, k - s + 1):
            alpha = (u - U[i]) / (U[i + p] - U[i])
            Q[i] = alpha * Pw[i] + (1.0 - alpha) * Pw[i - 1]
        Pw, U = Q, np.insert(U, k + 1, u)
    return Pw, U


def split(p, Pw, U, u):
    """The curve cut at u (strictly inside its domain): ((Pw, U) left, (Pw, U) right), both clamped."""
    s = int(np.count_nonzero(U == u))
    Pw, U = insert_knot(p, Pw, U, u, p - s)
    k = int(np.searchsorted(U, u, side="left"))  # U[k : k + p] == u
    left = (Pw[:k], np.concatenate([U[:k + p], [u]]))
    right = (Pw[k - 1:], np.concatenate([[u], U[k:]]))
    return left, right


def _elevate_bezier(Q, t):
    """A Bézier's control points raised by t degrees (exact)."""
    p = Q.shape[0] - 1
    out = np.zeros((p + t + 1, Q.shape[1]))
    for i in range(p + t + 1):
        for j in range(max(0, i - t), min(p, i) + 1):
            out[i] += math.comb(p, j) * math.comb(t, i - j) / math.comb(p + t, i) * Q[j]
    return out


def elevate(p, Pw, U, target):
    """(Pw, U) of the same curve, same parameter, at degree *target* >= p.

    Cut into Bézier pieces at every interior knot, each raised exactly; the joints
    keep knots of full multiplicity (C⁰ in the knot vector, as smooth as before in
    the geometry)."""
    if target == p:
        return Pw, U
    for u in np.unique(U[p + 1:-p - 1]):
        s = int(np.count_nonzero(U == u))
        if s < p:
            Pw, U = insert_knot(p, Pw, U, u, p - s)
    t = target - p
    breaks = np.unique(U)
    pieces = [_elevate_bezier(Pw[i * p: i * p + p + 1], t) for i in range(len(breaks) - 1)]
    out = [pieces[0]] + [q[1:] for q in pieces[1:]]
    knots = np.concatenate([[breaks[0]] * (target + 1)] + [[b] * target for b in breaks[1:-1]]
                           + [[breaks[-1]] * (target + 1)])
    return np.vstack(out), knots


def _tangent_out(Pw, at_end):
    """Unit tangent at a clamped end: towards the first control point distinct from the end one."""
    P = Pw[:, :-1] / Pw[:, -1:]
    seq = P[::-1] if at_end else P
    for q in seq[1:]:
        d = (seq[0] - q) if at_end else (q - seq[0])
        norm = float(np.linalg.norm(d))
        if norm > 0:
            return d / norm
    return np.zeros(P.shape[1])


def join(pieces, degree, ends=None):
    """One curve from (Pw, U) pieces of *degree*, each starting where the previous ends.

    Each piece keeps its parameter up to a shift: the first starts at its own first
    knot, each next one where the previous ended.  The weights of each piece are
    scaled (the piece does not change) so that the control point it shares with the
    previous one has one weight; the points themselves are divided out once, before
    any scaling, and *ends* ((start, end) per piece, or None) pins each piece's end
    points to their exact values (the block's own start and end).
    Returns (points, weights, U, shifts)."""
    Ps, ws, Us, shifts = [], [], [], []
    end = None
    w_end = None
    for i, (Pw, U) in enumerate(pieces):
        w = np.array(Pw[:, -1], dtype=float)
        P = Pw[:, :-1] / w[:, None]
        if ends is not None and ends[i] is not None:
            P[0], P[-1] = ends[i]
        if w_end is not None:  # scale the piece so that the shared control point has one weight
            w *= w_end / w[0]
        shift = 0.0 if end is None else end - U[0]
        V = U + shift
        if end is not None:
            V[: degree + 1] = end
        stop = U[-1] + shift
        V[-degree - 1:] = stop
        first = i == 0
        last = i == len(pieces) - 1
        Ps.append(P if first else P[1:])
        ws.append(w if first else w[1:])
        Us.append(V[: len(V) - (0 if last else 1)] if first else V[degree + 1: len(V) - (0 if last else 1)])
        shifts.append(shift)
        end, w_end = stop, w[-1]
    w = np.concatenate(ws)
    if not w.max() / w.min() <= MAX_WEIGHT_SPREAD:
        raise SpecError("path: the blocks' weights, matched at the joints, spread over more than "
                        f"{MAX_WEIGHT_SPREAD:g}; rescale the weights of the nurbs blocks so that each starts "
                        "near the weight the previous one ends with")
    return np.vstack(Ps), w / w.max(), np.concatenate(Us), np.array(shifts)


def _curve(degree, P, w, U) -> NurbsCurve:
    return NurbsCurve.from_spec(CurveSpec(degree, P, w, U))


# --------------------------------------------------------------------------- the path


class Path:
    """A toolpath as one motion: the programmed blocks, the curve the tool follows, the junctions.

    Attributes
    ----------
    spec : the validated :class:`~nurbsinterp.config.path.PathSpec`
    programmed : NurbsCurve of the blocks as written (contour error is measured to it)
    curve : NurbsCurve the interpolator follows: ``programmed`` itself
    starts : (m + 1,) global parameter where each block starts, and the end
    shifts : (m,) ``u_global - u_block`` of each block
    block_lengths : (m,) mm;  block_s : (m + 1,) arc length where each block starts, and the total
    junctions : the m - 1 :class:`Junction` s
    """

    def __init__(self, spec: PathSpec, *, min_degree: int = 1, curve: NurbsCurve | None = None, feedrates=None):
        self.spec = spec
        # mm/s per block (see block_feedrates); None: one feedrate, the profile's, everywhere
        self.feedrates = None if feedrates is None else np.asarray(feedrates, dtype=float)
        blocks = spec.blocks
        if len(blocks) == 1 and blocks[0].kind == "nurbs":
            # exactly the curve (or the caller's copy of it, with its tables built): same numbers as ever
            self.programmed = curve if curve is not None else NurbsCurve.from_spec(blocks[0].curve)
            self.degree = self.programmed.degree
            self.shifts = np.zeros(1)
            self.pieces = [block_nurbs(blocks[0])]
        else:
            raw = [block_nurbs(b) for b in blocks]
            self.degree = max(min_degree, max(p for p, _, _ in raw))
            self.pieces = [(self.degree, *elevate(p, Pw, U, self.degree)) for p, Pw, U in raw]
            P, w, U, self.shifts = join([(Pw, U) for _, Pw, U in self.pieces], self.degree,
                                        [(b.start, b.end) for b in blocks])
            self.programmed = _curve(self.degree, P, w, U)
        self.starts = np.array([piece[2][0] + sh for piece, sh in zip(self.pieces, self.shifts)]
                               + [self.programmed.domain[1]])
        self.starts[0] = self.programmed.domain[0]
        self.block_s = self.programmed.arc_length_at(self.starts)
        self.block_s[0] = 0.0
        self._lo = np.array([piece[2][0] for piece in self.pieces])
        self._hi = np.array([piece[2][-1] for piece in self.pieces])
        self.block_lengths = np.diff(self.block_s)
        self.junctions = self._junctions()
        self.curve = self.programmed

    # -- facts
    @property
    def blocks(self):
        return self.spec.blocks

    @property
    def dim(self) -> int:
        return self.programmed.dim

    @property
    def length(self) -> float:
        return self.curve.length

    @property
    def corners(self):
        return [j for j in self.junctions if j.corner]

    def _junctions(self):
        out = []
        for i in range(len(self.pieces) - 1):
            t1 = _tangent_out(self.pieces[i][1], at_end=True)
            t2 = _tangent_out(self.pieces[i + 1][1], at_end=False)
            angle = math.acos(max(-1.0, min(1.0, float(t1 @ t2))))
            out.append(Junction(i, float(self.starts[i + 1]), float(self.block_s[i + 1]), angle, bool(angle > CORNER_ANGLE)))
        return out

    def locate(self, u):
        """(n, u_block) of global parameters u: the block each lies on (a junction belongs to the next
        block) and its own parameter there."""
        u = np.asarray(u, dtype=float)
        n = np.searchsorted(self.starts[1:-1], u, side="right")
        return n, np.clip(u - self.shifts[n], self._lo[n], self._hi[n])

    def to_global(self, n, u_block):
        """The inverse of :meth:`locate`."""
        n = np.clip(np.asarray(n, dtype=np.int64), 0, len(self.pieces) - 1)
        return np.asarray(u_block, dtype=float) + self.shifts[n]

    def _stops(self):
        """The junctions where the motion stops: corners, a stop the program asks for before the next
        block (M0, M1, M6, a G4 dwell), and (for the paper's rest-to-rest profiles) a change of feedrate, which
        their ramps cannot make on the move."""
        feeds = self.feedrates
        return [j for j in self.junctions if j.corner
                or self.blocks[j.index + 1].stop is not None
                or (feeds is not None and feeds[j.index] != feeds[j.index + 1])]

    def section_holds(self, flush: float = 0.0):
        """The seconds the commands hold still before each section between stops: a G4's dwell before its first
        block (the first section's: before the motion starts), and where the program stops there (M0, G4 ...)
        *flush* more, the time a filter after interpolation needs to bring the tool to rest on the point."""
        firsts = [0] + [j.index + 1 for j in self._stops()]
        return np.array([float(self.blocks[i].dwell)
                         + (flush if i > 0 and self.blocks[i].stop is not None else 0.0)
                         for i in firsts])

    def program_stops(self) -> int:
        """How many stops the program asks for within its motion (M0, M1, M6, G4 ... before a block but the
        first, where the tool is at rest anyway), and a dwell before the first block."""
        first = self.blocks[0]
        return (sum(b.stop is not None for b in self.blocks[1:])
                + (first.dwell > 0.0))

    def section_ends(self):
        """Arc lengths (mm, along :attr:`curve`) where the motion must stop (see _stops), and the end."""
        stops = [self.curve.arc_length_at(j.u) for j in self._stops()]
        return np.array(stops + [self.curve.length])

    def section_feedrates(self):
        """The feedrate (mm/s) of each section between stops: the lowest of its blocks' (None without feedrates)."""
        if self.feedrates is None:
            return None
        bounds = [0] + [j.index + 1 for j in self._stops()] + [len(self.blocks)]
        return np.array([self.feedrates[a:b].min() for a, b in zip(bounds[:-1], bounds[1:])])

    def span_feedrates(self):
        """The feedrate cap (mm/s) of each knot span of :attr:`curve`, indexed as its spans (None without
        feedrates): the lowest of the blocks the span lies on."""
        if self.feedrates is None:
            return None
        knots = self.curve.knots
        inner = self.starts[1:-1]
        last = len(self.blocks) - 1
        lo = np.minimum(np.searchsorted(inner, knots[:-1], side="right"), last)
        hi = np.minimum(np.searchsorted(inner, knots[1:], side="left"), last)
        out = np.minimum(self.feedrates[lo], self.feedrates[hi])
        for i in np.flatnonzero(hi - lo > 1):
            out[i] = self.feedrates[lo[i]:hi[i] + 1].min()
        return out

def job_path(job, curve: NurbsCurve | None = None) -> Path:
    """The path a job's motion follows (the paper's planner: one curve, or a path under acc/dec after).

    *curve*: the job's one NURBS already built (a `curve:` job), to reuse its tables."""
    return Path(job.path, curve=curve, feedrates=block_feedrates(job))


def block_feedrates(job):
    """The feedrate of each block, mm/s, or None where every block moves at the profile's feedrate.

    A feedrate on the command line (``job.feedrate_override``) sets every block's, rapids too; otherwise
    a rapid moves at ``profile.rapid_feedrate``, a block with its own feedrate (a G-code F word, a YAML
    block's ``feedrate``) at that, and any other at ``profile.feedrate``."""
    spec = job.profile
    blocks = job.path.blocks
    if job.feedrate_override or all(b.feedrate is None and not b.rapid for b in blocks):
        return None
    feeds = np.array([spec.rapid_feedrate if b.rapid else (spec.feedrate if b.feedrate is None else b.feedrate)
                      for b in blocks])
    return None if np.all(feeds == spec.feedrate) else feeds
