"""Runs of short moves refitted as smooth cubic B-splines, verified within the tolerance two-sided.

CAM programs sample a smooth surface path by runs of short G1 moves (0.2 mm down to 1-4 um), their end points
often rounded to 1e-4 mm or 1e-3 mm.  Blending each joint with an arc is capped by the tiny segments; a smooth
curve refitted through the run within the tolerance lets the feed be set by the machine's limits instead.

The stages, in the order the planner uses them:

* :func:`split_runs` cuts a polyline at its corners and at its long moves into runs worth refitting;
* :func:`fit_run` fits one run by clamped cubic B-splines (:class:`Piece`), each verified with a rigorous bound
  on its two-sided deviation from the polyline, refined or split where the bound exceeds the tolerance;
* :func:`span_bounds` gives, per knot span of a piece, its arc length and upper bounds on its curvature and
  on the per-axis components of its unit tangent and curvature vector (the planner's speed caps);
* :func:`points_at_length` (a numba kernel) gives the points of a piece at given arc lengths (the ticks).

Conventions: degree p = 3 (order 4), clamped knots; a piece's parameter u is the polyline's chord length
from the piece's first vertex (mm), so that ``|C'(u)|`` is close to 1 and the knots read in mm.

Deviation, two-sided: every point of the curve lies within the tolerance of the polyline, and every point of
the polyline (its segments, not only its vertices) within the tolerance of the curve.  Both follow from one
number, ``sup_u |C(u) - P(u)|``, where P(u) is the polyline at chord length u: a point C(u) is within
``|C(u) - P(u)|`` of the point P(u) of the polyline and conversely (see :func:`_deviation_bound`).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import BSpline
from scipy.linalg import solveh_banded

from .._jit import njit

DEGREE = 3
#: share of the tolerance a fit may use, as verified: the rest is left to the interpolator's chords and rounding
BUDGET = 0.9
#: default corner: a joint that turns by more than this, measured over chords of CORNER_REACH tolerances
CORNER_ANGLE = math.radians(30.0)
#: the reach, in tolerances, of the chords that measure a joint's turning (see split_runs)
CORNER_REACH = 8.0
#: the reach, in tolerances, of the chords that estimate the curvature for the first knots (noise averaged out)
CURVATURE_REACH = 32.0
#: most vertices in one piece: a longer run is cut into pieces joined G1 (bounded work and memory per piece)
MAX_VERTICES = 4096
#: the error of a least-squares cubic with uniform spans h on a circle of radius R is about E_CUBIC h^4 / R^3
#: (measured, tests/test_fit.py::test_knot_rule_calibration); the first knots are placed by it
E_CUBIC = 0.0015
#: the first knots aim at this share of the tolerance; refinement adds knots where the verified bound exceeds
#: BUDGET.  Not the budget itself: a cubic's curvature ripples by about 5 (h/R)^2 where its position errs by
#: E_CUBIC h^4 / R^3, so spans aimed at 0.1 tolerance keep the curvature within ~2.5 % on a 5 mm circle at
#: 5 um (at 0.3: ~4 %) for 25 spans instead of 19 on 63 mm, still a dozen chords of 0.2 mm a span.
FIRST_AIM = 0.1
#: most refinement passes before a run is split at its worst vertex
MAX_PASSES = 12


@dataclass(frozen=True)
class Piece:
    """One clamped cubic B-spline of a refitted run.

    Attributes
    ----------
    knots : ndarray, shape (m + 4,), mm
        Clamped knot vector: four knots at 0 and four at the piece's chord length; u is the chord length of
        the polyline from vertex ``first``.
    ctrl : ndarray, shape (m, dim), mm
        Control points; ``ctrl[0]`` is the vertex ``first`` exactly and ``ctrl[-1]`` the vertex ``last``.
    first, last : int
        The run's vertices the piece covers (indices into the points given to :func:`fit_run`).
    deviation : float, mm
        Verified upper bound on the two-sided deviation of the piece from the polyline first..last.
    """

    knots: np.ndarray
    ctrl: np.ndarray
    first: int
    last: int
    deviation: float

    @property
    def degree(self) -> int:
        return DEGREE

    def spline(self) -> BSpline:
        """The piece as scipy's ``BSpline`` (evaluation with ``(N,)`` in, ``(N, dim)`` out)."""
        return BSpline.construct_fast(self.knots, self.ctrl, DEGREE)


# ---------------------------------------------------------------------------------------------- the polyline


def _lengths(points):
    seg = np.diff(points, axis=0)
    return seg, np.sqrt(np.einsum("ij,ij->i", seg, seg))


def _angle(a, b):
    """Angle between the rows of a and b (radians, 0 where either is zero), by atan2: exact near 0 and pi."""
    cross = np.sqrt(np.maximum(np.einsum("ij,ij->i", a, a) * np.einsum("ij,ij->i", b, b)
                               - np.einsum("ij,ij->i", a, b) ** 2, 0.0))
    return np.arctan2(cross, np.einsum("ij,ij->i", a, b))


def _reach_turning(points, s, reach):
    """Each vertex's turning between the chords to the vertices at least ``reach`` mm (of path) behind and ahead.

    Noise of amplitude e on the vertices moves such a chord's direction by at most about 2e/reach: with the
    reach a few tolerances, rounding noise (<= tolerance/2) cannot make a corner, while a corner of a few
    tolerances' size still turns the chords by its full angle.  Segments longer than the reach give the
    plain joint angle.  The end vertices turn by 0.
    """
    n = len(points)
    i = np.arange(n)
    back = np.clip(np.searchsorted(s, s - reach, side="right") - 1, 0, n - 1)
    ahead = np.clip(np.searchsorted(s, s + reach, side="left"), 0, n - 1)
    turn = _angle(points - points[back], points[ahead] - points)
    turn[(back == i) | (ahead == i)] = 0.0
    return turn, back, ahead


def split_runs(points, tolerance, *, corner_angle=CORNER_ANGLE, min_vertices=4):
    """The runs of a polyline worth refitting by :func:`fit_run`: cut at its corners and at its long moves.

    Parameters
    ----------
    points : array_like, shape (n, dim), mm
        The polyline's vertices (the programmed end points of consecutive moves).
    tolerance : float, mm
        The path tolerance the fit will be held to.
    corner_angle : float, radians
        A joint turning by more than this is a corner: the runs end there (the planner blends it).
    min_vertices : int
        Shortest run returned; shorter stretches stay lines.

    Returns
    -------
    list of (first, last)
        Inclusive vertex index ranges, in order, each of at least ``min_vertices`` vertices; consecutive runs
        may share a vertex (a corner between them).  Every segment not inside a run stays a line.

    Notes
    -----
    *Corners.*  A joint's turning is measured between chords reaching ``CORNER_REACH = 8`` tolerances of path
    behind and ahead of it (:func:`_reach_turning`), not between its two segments: on 1 um segments rounded to
    1 um the segments' own directions are noise, turning by tens of degrees, while the chords over 40 um
    (tolerance 5 um) turn by less than 2 degrees from it.  A real corner turns the chords by its own angle
    at its vertex and by less on either side: the run is cut at the vertex of largest turning in each stretch
    of vertices above ``corner_angle``, and at any joint above it between two segments longer than the reach.
    The default, 30 degrees, is where a smooth curve stops paying: a joint that turns by 30 degrees within
    8 tolerances bends with a radius below about 15 tolerances (75 um at 5 um), where the speed is set by the
    curvature whether the joint is blended by an arc or smoothed, while the smooth surfaces CAM samples at
    0.2 mm turn by under 30 degrees a chord down to radii of 0.4 mm.

    *Long moves.*  A segment of length L whose end joints turn by a and b is a chord of a smooth curve only
    if the arc through its ends, turning by (a + b) / 2 across it, sags L (a + b) / 16 within the tolerance:
    that is L < sqrt(8 R tol) with the radius R = 2L / (a + b) the joints imply.  First, a joint that turns
    by a between segments of which the shorter is L is a corner when L a / 16 exceeds half the tolerance:
    the smooth curve could not turn there even within the shorter segment (0.2 mm segments meeting at 20
    degrees, tolerance 5 um: a corner; at 10 degrees: smoothed).  Then, over the joints left, a segment whose
    sag would exceed half the tolerance stays a line, its ends cutting the runs (a 3 mm move continuing a
    curve of 0.2 mm chords at a joint of 1 degree, say); a long segment between collinear neighbours sags
    nothing and is fitted with them (a straight stretch is a cubic too).  Noise cannot make a short segment
    long nor a joint between short segments sharp: 1 um turning by pi sags 0.2 um.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or len(points) < 2:
        return []
    n = len(points)
    tolerance = float(tolerance)
    seg, length = _lengths(points)
    s = np.concatenate(([0.0], np.cumsum(length)))
    reach = CORNER_REACH * tolerance
    turn, _, _ = _reach_turning(points, s, reach)
    # plain joint angles (vertices 1..n-2), over the nearest segments of nonzero length on either side
    joint = np.zeros(n)
    if n > 2:
        joint[1:-1] = _angle(seg[:-1], seg[1:])
        joint[1:-1][(length[:-1] == 0) | (length[1:] == 0)] = 0.0
    cut = np.zeros(n, dtype=bool)
    above = turn > corner_angle
    if above.any():
        # each stretch of consecutive vertices above the angle: cut at its largest turning
        edges = np.flatnonzero(np.diff(np.concatenate(([0], above.view(np.int8), [0]))))
        for a, b in zip(edges[::2], edges[1::2]):
            cut[a + int(np.argmax(turn[a:b]))] = True
    if n > 2:
        long_sides = np.zeros(n, dtype=bool)
        long_sides[1:-1] = (length[:-1] > reach) & (length[1:] > reach)
        cut |= long_sides & (joint > corner_angle)
    # sharp joints: a joint whose turning even its shorter segment cannot absorb within half the tolerance
    if n > 2:
        shorter = np.zeros(n)
        shorter[1:-1] = np.minimum(length[:-1], length[1:])
        cut |= np.minimum(joint, math.pi / 2) * shorter / 16.0 > 0.5 * tolerance
    # long moves: the sag of the arc the joints at their ends imply (a corner, cut already, implies none)
    ends = np.where(cut, 0.0, np.minimum(joint, math.pi / 2))
    sag = length * (ends[:-1] + ends[1:]) / 16.0
    line = sag > 0.5 * tolerance
    runs = []
    first = 0
    for i in range(n - 1):
        if line[i]:
            if i - first + 1 >= min_vertices:
                runs.append((first, i))
            first = i + 1
        elif cut[i + 1] or i + 1 == n - 1:
            if i + 1 - first + 1 >= min_vertices:
                runs.append((first, i + 1))
            first = i + 1
    return runs


# ---------------------------------------------------------------------------------------------- the fit


@njit(cache=True)
def _normal_equations(t, u, q, ab, rhs):
    """B^T B (upper banded, into ab) and B^T q (into rhs) for the cubic basis on knots t at the sorted u:
    each point's four nonzero basis values by Cox-de Boor's triangle, added where they belong."""
    m = len(t) - 4
    dim = q.shape[1]
    N = np.empty(4)
    left = np.empty(4)
    right = np.empty(4)
    j = 3
    for p in range(len(u)):
        x = u[p]
        while j < m - 1 and t[j + 1] <= x:
            j += 1
        N[0] = 1.0
        for r in range(1, 4):
            left[r] = x - t[j + 1 - r]
            right[r] = t[j + r] - x
            saved = 0.0
            for k in range(r):
                temp = N[k] / (right[k + 1] + left[r - k])
                N[k] = saved + right[k + 1] * temp
                saved = left[r - k] * temp
            N[r] = saved
        c0 = j - 3
        for a in range(4):
            for b in range(a, 4):
                ab[3 - (b - a), c0 + b] += N[a] * N[b]
            for k in range(dim):
                rhs[c0 + a, k] += N[a] * q[p, k]


def _solve(u, q, t, fixed):
    """Least-squares control points for data q (N, dim) at u on knots t, with the control points in ``fixed``.

    The normal equations B^T B c = B^T q are banded (bandwidth 3: each row of B has four neighbouring
    entries; built by the kernel :func:`_normal_equations`), so scipy's ``solveh_banded`` (a banded
    Cholesky) solves them in O(m) for any knot count; scipy's ``make_lsq_spline`` solves the same
    equations but cannot hold control points fixed, which the exact end points and the prescribed end
    tangents need.  The fixed control points are moved to the right-hand side.
    A second-difference penalty 1e-9 times the matrix's scale (Eilers and Marx's P-spline, far below any
    effect on the fit) keeps the equations definite where a knot span holds no data.
    """
    m = len(t) - DEGREE - 1
    dim = q.shape[1]
    # upper banded form ab[3 + i - j, j] = A[i, j], accumulated point by point in a kernel
    ab = np.zeros((DEGREE + 1, m))
    rhs = np.zeros((m, dim))
    _normal_equations(np.ascontiguousarray(t), np.ascontiguousarray(u), np.ascontiguousarray(q), ab, rhs)
    if m >= 3:
        w = 1e-9 * ab[DEGREE].max()
        ab[DEGREE, :-2] += w
        ab[DEGREE, 1:-1] += 4 * w
        ab[DEGREE, 2:] += w
        ab[DEGREE - 1, 1:-1] -= 2 * w
        ab[DEGREE - 1, 2:] -= 2 * w
        ab[DEGREE - 2, 2:] += w
    A = _full_rows(ab, fixed)
    for f, value in fixed.items():
        rhs -= np.outer(A[f], value)
    for f, value in fixed.items():
        for off in range(1, DEGREE + 1):
            if f + off < m:
                ab[DEGREE - off, f + off] = 0.0
            if f - off >= 0:
                ab[DEGREE - off, f] = 0.0
        ab[DEGREE, f] = 1.0
    for f, value in fixed.items():
        rhs[f] = value
    return solveh_banded(ab, rhs, check_finite=False)


def _full_rows(ab, fixed):
    """The columns of the banded symmetric matrix at the fixed indices, as dense rows (m,) each."""
    m = ab.shape[1]
    out = {}
    for f in fixed:
        row = np.zeros(m)
        for off in range(-DEGREE, DEGREE + 1):
            i = f + off
            if 0 <= i < m and i != f:
                row[i] = ab[DEGREE - abs(off), max(i, f)]
        out[f] = row
    return out


def _first_knots(u, kappa, tolerance, total, tangents):
    """Interior knots equidistributing the span rule h = (E_CUBIC^-1 e R^3)^(1/4), e = FIRST_AIM tolerance.

    Knot density rho = (E_CUBIC kappa^3 / e)^(1/4) per mm of chord, integrated along the run; at least one
    span, and two more where end tangents are prescribed (each fixes one more control point).
    """
    e = FIRST_AIM * tolerance
    rho = (E_CUBIC * np.maximum(kappa, 0.0) ** 3 / e) ** 0.25
    cum = np.concatenate(([0.0], np.cumsum(0.5 * (rho[1:] + rho[:-1]) * np.diff(u))))
    spans = max(1 + tangents, int(math.ceil(cum[-1])))
    if cum[-1] <= 0 or not np.all(np.diff(cum) >= 0):
        return np.linspace(0.0, total, spans + 1)[1:-1]
    targets = np.linspace(0.0, cum[-1], spans + 1)[1:-1]
    # cum may be flat (straight stretches): invert on its increasing points, then fall back to uniform
    keep = np.concatenate(([True], np.diff(cum) > 0))
    inner = np.interp(targets, cum[keep], u[keep])
    inner = np.unique(inner)
    inner = inner[(inner > 0) & (inner < total)]
    if len(inner) < spans - 1:
        return np.linspace(0.0, total, spans + 1)[1:-1]
    return inner


def _clamped(inner, total):
    return np.concatenate(([0.0] * (DEGREE + 1), inner, [total] * (DEGREE + 1)))


def _deviation_bound(t, c, u, points, tolerance):
    """A rigorous upper bound on sup |C(u) - P(u)| over each knot span of the curve C (knots t, control c).

    P(u) is the polyline at chord length u (linear between the vertices' parameters).  Samples s_k include
    every vertex parameter and every knot; K is the polygon through the curve's samples.

    * Between consecutive breakpoints both K(u) and P(u) are linear in u, so |K - P| is convex there and at
      most its value at one end: sup |K - P| is the largest |C(s_k) - P(s_k)| of the interval's two ends.
    * Inside a knot span C'' is linear in u, so |C''| over an interval is at most its value at one end
      (convexity), and C departs from its chord by at most h^2/8 max|C''| (the interpolation remainder
      e(u) = -int G(u, s) C''(s) ds, G >= 0, int G = u (h - u) / 2 <= h^2 / 8).

    Hence |C(u) - P(u)| <= max(|C - P| at the ends) + h^2/8 max(|C''| at the ends) on every interval, and each
    point of the curve is within that of the polyline (the point P(u)) and conversely.  The intervals are
    subdivided so that the sag term stays under 2 % of the deviation allowed.  A relative margin of 1e-12 of
    the coordinates covers rounding.

    Returns
    -------
    bound : ndarray (number of knot spans,)
    """
    edges = np.ascontiguousarray(t[DEGREE:-DEGREE])
    coef = np.empty((len(edges) - 1, 4, c.shape[1]))
    _power_form(np.ascontiguousarray(t), np.ascontiguousarray(c), coef)
    scale = float(np.abs(points).max()) + float(np.abs(c).max())
    out = np.zeros(len(edges) - 1)
    _deviation_kernel(np.ascontiguousarray(edges), coef, u, np.ascontiguousarray(points), 0.02 * tolerance,
                      1e-12 * scale, out)
    return out


#: power-form coefficients of a cubic from its values at y = 0, 1/3, 2/3, 1 (the inverse Vandermonde matrix)
_TO_POWER = np.linalg.inv(np.vander(np.linspace(0.0, 1.0, 4), 4, increasing=True))


@njit(cache=True)
def _power_form(knots, ctrl, coef):
    """Each span j of a clamped cubic with distinct interior knots as a cubic in x = u - knots[j + 3]:
    coef[j, r] is the coefficient of x^r, from the span's values at four equispaced points (exact for a cubic
    but for rounding, which the verification's margin covers)."""
    dim = ctrl.shape[1]
    nspan = coef.shape[0]
    val = np.empty((4, dim))
    for j in range(nspan):
        jj = j + 3
        a, b = knots[jj], knots[jj + 1]
        h = b - a
        for q in range(4):
            _deboor(knots, ctrl, jj, a + h * q / 3.0 if q < 3 else b, val[q])
        for r in range(4):
            scale = 1.0 / h ** r
            for k in range(dim):
                acc = 0.0
                for q in range(4):
                    acc += _TO_POWER[r, q] * val[q, k]
                coef[j, r, k] = acc * scale


@njit(cache=True)
def _deviation_kernel(edges, coef, u, points, eta, margin, out):
    """The loop of :func:`_deviation_bound`: breakpoints (the vertices' parameters and the knots) merged in
    order, each interval between them subdivided so that its sag term h^2/8 max|C''| is at most eta, the
    bound of each sub-interval folded into its span's entry of out (zeroed by the caller)."""
    nspan = len(edges) - 1
    n = len(u)
    dim = points.shape[1]
    j = 0  # the span of the current interval
    i = 0  # the polyline segment: u[i] <= s <= u[i + 1]
    prev = u[0]
    err_prev = 0.0
    for k in range(dim):
        d = coef[0, 0, k] - points[0, k]
        err_prev += d * d
    err_prev = math.sqrt(err_prev)
    iu, ie = 1, 1
    while iu < n or ie < nspan:
        if ie < nspan and (iu >= n or edges[ie] <= u[iu]):
            nb = edges[ie]
            ie += 1
        else:
            nb = u[iu]
            iu += 1
        if nb <= prev:
            continue
        while j < nspan - 1 and edges[j + 1] <= prev:
            j += 1
        # |C''| at both ends of [prev, nb] (C'' = 2 c2 + 6 c3 x, linear: its largest norm is at an end)
        xa = prev - edges[j]
        xb = nb - edges[j]
        qa = 0.0
        qb = 0.0
        for k in range(dim):
            va = 2.0 * coef[j, 2, k] + 6.0 * coef[j, 3, k] * xa
            vb = 2.0 * coef[j, 2, k] + 6.0 * coef[j, 3, k] * xb
            qa += va * va
            qb += vb * vb
        m2 = math.sqrt(max(qa, qb))
        h = nb - prev
        nsub = int(math.ceil(h * math.sqrt(m2 / (8.0 * eta)))) if m2 > 0 else 1
        nsub = min(max(nsub, 1), 64)  # beyond 64 the curve is far off anyway: the bound then only grows
        step = h / nsub
        sag = step * step / 8.0 * m2
        for q in range(1, nsub + 1):
            s = prev + step * q if q < nsub else nb
            x = s - edges[j]
            while i < n - 2 and u[i + 1] < s:
                i += 1
            du = u[i + 1] - u[i]
            w = (s - u[i]) / du if du > 0 else 1.0
            w = min(max(w, 0.0), 1.0)
            err = 0.0
            for k in range(dim):
                cx = coef[j, 0, k] + x * (coef[j, 1, k] + x * (coef[j, 2, k] + x * coef[j, 3, k]))
                px = points[i, k] + w * (points[i + 1, k] - points[i, k])
                err += (cx - px) * (cx - px)
            err = math.sqrt(err)
            b = max(err_prev, err) + sag + margin
            if b > out[j]:
                out[j] = b
            err_prev = err
        prev = nb


def _bezier_piece(points, t0, t1, tolerance):
    """One segment as one cubic Bezier, straight or leaving and arriving along the prescribed tangents.

    The handles are short enough that every control point lies within a quarter of the tolerance of the
    segment.  Then (convex hull) every point of the curve does, and, the curve running from one end of the
    segment to the other, its projection on the segment covers it: every point x of the segment is the
    projection of a point of the curve, which is within a quarter of the tolerance of the segment's line, so of
    x.  The deviation returned is that of the control points, a rigorous bound both ways.
    """
    p0, p1 = points[0], points[-1]
    L = float(np.linalg.norm(p1 - p0))
    d = (p1 - p0) / L
    ctrl = np.array([p0, p0 + d * L / 3, p1 - d * L / 3, p1])
    for k, (tan, end, sign) in enumerate(((t0, p0, 1.0), (t1, p1, -1.0))):  # handles p0 + lam t0, p1 - lam t1
        if tan is None:
            continue
        along = float(np.dot(tan, d))
        sin = float(np.linalg.norm(tan - along * d))
        # a handle pointing back off the segment leaves it by its whole length, one at an angle by lam sin
        off = sin if along >= 0 else 1.0
        lam = L / 3 if off * L / 3 <= 0.25 * tolerance else 0.25 * tolerance / off
        ctrl[1 + k] = end + sign * lam * tan
    rel = ctrl - p0
    along = np.clip(rel @ d, 0.0, L)
    dev = float(np.sqrt(np.einsum("ij,ij->i", rel - np.outer(along, d), rel - np.outer(along, d))).max())
    return np.concatenate(([0.0] * 4, [L] * 4)), ctrl, dev + 1e-12 * (float(np.abs(ctrl).max()) + 1.0)


def _unit(v):
    n = float(np.linalg.norm(v))
    return v / n if n > 0 else None


def _local_curvature(points, s, tolerance):
    """Curvature at each vertex from the turning of chords reaching CURVATURE_REACH tolerances (noise averaged)."""
    reach = max(CURVATURE_REACH * tolerance, 0.0)
    turn, back, ahead = _reach_turning(points, s, reach)
    span = s[ahead] - s[back]
    return np.where(span > 0, 2.0 * turn / np.where(span > 0, span, 1.0), 0.0)


def _fit_chunk(points, u, kappa, tolerance, t0, t1, offset, out):
    """Fit points (chord parameters u from 0) with end tangents t0, t1 (unit or None); append Pieces to out."""
    n = len(points)
    total = float(u[-1])
    target = BUDGET * tolerance
    if n == 2 or total <= 0:
        t, c, dev = _bezier_piece(points[[0, -1]], t0, t1, tolerance)
        out.append(Piece(_ro(t), _ro(c), offset, offset + n - 1, dev))
        return
    tangents = (t0 is not None) + (t1 is not None)
    inner = _first_knots(u, kappa, tolerance, total, tangents)
    for _ in range(MAX_PASSES):
        t = _clamped(inner, total)
        fixed = {0: points[0], len(t) - DEGREE - 2: points[-1]}
        m = len(t) - DEGREE - 1
        if t0 is not None:
            fixed[1] = points[0] + (t[DEGREE + 1] - t[0]) / 3.0 * t0
        if t1 is not None:
            fixed[m - 2] = points[-1] - (t[-1] - t[-DEGREE - 2]) / 3.0 * t1
        c = _solve(u, points, t, fixed)
        bound = _deviation_bound(t, c, u, points, tolerance)
        bad = bound > target
        if not bad.any():
            out.append(Piece(_ro(t), _ro(c), offset, offset + n - 1, float(bound.max())))
            return
        edges = np.concatenate(([0.0], inner, [total]))
        mids = 0.5 * (edges[:-1] + edges[1:])[bad]
        inner = np.union1d(inner, mids)
        if len(inner) + 4 > 2 * n + 8:  # more control points than the data: refining no longer fits, split
            break
    # split at the vertex nearest the middle of the worst span, along the tangent the last fit had there
    worst = int(np.argmax(bound))
    edges = np.concatenate(([0.0], t[DEGREE + 1:-DEGREE - 1], [total]))
    mid = 0.5 * (edges[worst] + edges[worst + 1])
    k = int(np.clip(np.searchsorted(u, mid), 1, n - 2))
    spl = BSpline.construct_fast(t, c, DEGREE)
    tan = _unit(spl.derivative(1)(u[k]))
    if tan is None:  # the fit stalled there: the joint's bisector, or at a reversal the move arriving
        tan = _unit(_unit(points[k] - points[k - 1]) + _unit(points[k + 1] - points[k]))
    if tan is None:
        tan = _unit(points[k] - points[k - 1])
    _fit_chunk(points[:k + 1], u[:k + 1], kappa[:k + 1], tolerance, t0, tan, offset, out)
    _fit_chunk(points[k:], u[k:] - u[k], kappa[k:], tolerance, tan, t1, offset + k, out)


def _ro(a):
    a = np.ascontiguousarray(a, dtype=float)
    a.setflags(write=False)
    return a


def _local_tangent(points, s, kappa, k, tolerance, reach=256):
    """The unit tangent at vertex k of a least-squares cubic fitted over up to ``reach`` vertices either side.

    Where a long run is cut into pieces, both pieces take this tangent at the shared vertex (G1): it is the
    direction the smooth curve through the vertex's neighbourhood has there, not the noise of one segment.
    """
    a, b = max(0, k - reach), min(len(points) - 1, k + reach)
    u = s[a:b + 1] - s[a]
    inner = _first_knots(u, kappa[a:b + 1], tolerance, float(u[-1]), 0)
    t = _clamped(inner, float(u[-1]))
    c = _solve(u, points[a:b + 1], t, {0: points[a], len(t) - DEGREE - 2: points[b]})
    tan = _unit(BSpline.construct_fast(t, c, DEGREE).derivative(1)(s[k] - s[a]))
    if tan is None:
        tan = _unit(points[min(k + 1, b)] - points[max(k - 1, a)])
    return tan


def _as_tangent(value, dim, name):
    if value is None:
        return None
    v = np.asarray(value, dtype=float).reshape(-1)
    n = float(np.linalg.norm(v)) if v.shape == (dim,) else 0.0
    if not (n > 0 and math.isfinite(n)):
        raise ValueError(f"{name} = {value!r} is not a nonzero direction of dimension {dim}")
    return v / n


def fit_run(points, tolerance, start_tangent=None, end_tangent=None, *, max_vertices=MAX_VERTICES):
    """Smooth clamped cubic B-splines through a run of short moves, verified within the tolerance.

    Parameters
    ----------
    points : array_like, shape (n, dim), mm
        The run's vertices, n >= 2 (as :func:`split_runs` delimits them), of positive total length.
    tolerance : float, mm
        The largest two-sided deviation allowed between the pieces and the polyline.
    start_tangent, end_tangent : array_like (dim,) or None
        The direction the first piece leaves ``points[0]`` along and the last one arrives at ``points[-1]``
        along (normalised here), so that the pieces join the lines or arcs beside them without a corner;
        None leaves it to the fit.
    max_vertices : int
        Most vertices in one piece (a longer run is cut into pieces of about equal size).

    Returns
    -------
    list of Piece
        In order along the run: the first starts at ``points[0]`` exactly, the last ends at ``points[-1]``
        exactly, each ends on a vertex where the next starts with the same unit tangent (G1; C2 inside a
        piece).  Each piece's ``deviation`` is a verified upper bound of its two-sided deviation from its
        vertices' polyline, at most ``BUDGET * tolerance`` (the rest is the interpolator's margin).

    Notes
    -----
    *Fit.*  Chord-length parameter; knots first placed by the curvature the run's chords show
    (:func:`_first_knots`: a cubic's error on a circle is about ``E_CUBIC h^4 / R^3``), then control points by
    least squares on the vertices with banded normal equations (:func:`_solve`, scipy's
    ``solveh_banded``).  The end points are fixed control points; a prescribed tangent fixes the second
    control point at ``P0 + lambda t0`` with ``lambda = (t_4 - t_3) / 3``, which makes ``|C'| = 1`` at the
    end as the chord-length parameter has it elsewhere, and keeps the least squares separable by axis
    (lambda free would couple the axes for a gain the verification does not need).

    *Verification* (:func:`_deviation_bound`).  A rigorous bound on ``sup |C(u) - P(u)|`` per knot span,
    where P(u) is the polyline at chord length u, bounds both sides of the deviation.  A span whose bound
    exceeds ``BUDGET * tolerance`` is halved and the run refitted; after ``MAX_PASSES`` passes, or when the
    knots outnumber the vertices, the run is split at the vertex nearest its worst span along the tangent
    the fit had there, and each side fitted again.  A single segment is one cubic Bezier whose control points
    lie within a quarter of the tolerance of it (:func:`_bezier_piece`): the recursion always ends, within
    the tolerance.  Zero-length moves are dropped (their vertices are covered by their neighbours).

    *Smoothness.*  Knots are added only where the verified bound asks for them, so the curvature follows
    the curve the vertices sample and not their rounding: on a circle of radius 5 mm in 0.2 mm chords
    rounded to 1e-4 mm (tolerance 5 um) the curvature stays within a few per cent of 1/5 (tested).

    Examples
    --------
    >>> th = np.linspace(0.0, np.pi, 80)
    >>> arc = np.round(np.c_[5 * np.cos(th), 5 * np.sin(th)], 4)        # 0.2 mm chords, rounded to 0.1 um
    >>> (piece,) = fit_run(arc, 0.005, start_tangent=(0, 1), end_tangent=(0, -1))
    >>> piece.first, piece.last, bool(piece.deviation <= 0.9 * 0.005), len(piece.knots) - 7
    (0, 79, True, 7)
    >>> bounds = span_bounds(piece)
    >>> bool(abs(bounds.cumulative[-1] - 5 * np.pi) < 1e-3), bool(np.all(bounds.curvature < 0.21))
    (True, True)
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or len(points) < 2:
        raise ValueError(f"a run needs at least 2 vertices of one dimension, not an array of shape {points.shape}")
    tolerance = float(tolerance)
    if not (tolerance > 0 and math.isfinite(tolerance)):
        raise ValueError(f"tolerance = {tolerance!r} is not a positive length")
    n, dim = points.shape
    t0 = _as_tangent(start_tangent, dim, "start_tangent")
    t1 = _as_tangent(end_tangent, dim, "end_tangent")
    _, length = _lengths(points)
    keep = np.concatenate(([True], length > 0))
    index = np.flatnonzero(keep)
    pts = points[keep]
    if len(pts) < 2:
        raise ValueError(f"the run of {n} vertices has no length (all at {points[0].tolist()})")
    s = np.concatenate(([0.0], np.cumsum(length[length > 0])))
    kappa = _local_curvature(pts, s, tolerance)
    m = len(pts)
    chunks = max(1, int(math.ceil((m - 1) / max(int(max_vertices) - 1, 1))))
    cuts = np.unique(np.round(np.linspace(0, m - 1, chunks + 1)).astype(np.int64))
    tangents = [t0] + [_local_tangent(pts, s, kappa, int(k), tolerance) for k in cuts[1:-1]] + [t1]
    out: list[Piece] = []
    for a, b, ta, tb in zip(cuts[:-1], cuts[1:], tangents[:-1], tangents[1:]):
        _fit_chunk(pts[a:b + 1], s[a:b + 1] - s[a], kappa[a:b + 1], tolerance, ta, tb, int(a), out)
    result = []
    for p in out:
        last = n - 1 if p.last == m - 1 else int(index[p.last])
        result.append(Piece(p.knots, p.ctrl, int(index[p.first]), last, p.deviation))
    return result


# ---------------------------------------------------------------------------------------------- the planner's view


@dataclass(frozen=True)
class SpanBounds:
    """Per knot span of a piece (the intervals between its distinct knots), for the planner.

    Attributes
    ----------
    start : ndarray (spans + 1,), mm of parameter
        The spans' edges in the piece's parameter u.
    length : ndarray (spans,), mm
        Arc length of each span (Gauss-Legendre, adaptively to 1e-13 relative).
    cumulative : ndarray (spans + 1,), mm
        Arc length from the piece's start to each edge (``points_at_length``'s ``span_s``).
    curvature : ndarray (spans,), 1/mm
        Upper bound of the curvature over each span.
    tangent : ndarray (spans, dim)
        Upper bound of each axis's component of the unit tangent (at most 1).
    curvature_vector : ndarray (spans, dim), 1/mm
        Upper bound of each axis's component of the curvature vector dT/ds (at most ``curvature``).
    """

    start: np.ndarray
    length: np.ndarray
    cumulative: np.ndarray
    curvature: np.ndarray
    tangent: np.ndarray
    curvature_vector: np.ndarray


_GL_X, _GL_W = np.polynomial.legendre.leggauss(16)


def _bernstein_inverse(degree):
    """The matrix taking a polynomial's values at degree + 1 equispaced points of [0, 1] to its Bernstein
    coefficients there (exact: both are bases of the polynomials of that degree)."""
    v = np.linspace(0.0, 1.0, degree + 1)
    M = np.array([[math.comb(degree, j) * x ** j * (1 - x) ** (degree - j) for j in range(degree + 1)] for x in v])
    return np.linalg.inv(M)


_BERN5 = _bernstein_inverse(5)
_BERN6 = _bernstein_inverse(6)


def _arc_lengths(d1, edges):
    """Arc length over each interval of edges, Gauss-Legendre 16 points, halving until two levels agree."""
    a, b = edges[:-1].copy(), edges[1:].copy()
    owner = np.arange(len(a))
    total = np.zeros(len(a))

    def gl(lo, hi):
        mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
        x = mid[:, None] + half[:, None] * _GL_X[None, :]
        v = d1(x.ravel()).reshape(x.shape + (-1,))
        return half * (np.sqrt((v * v).sum(axis=-1)) @ _GL_W)

    whole = gl(a, b)
    for _ in range(40):
        if len(a) == 0:
            break
        m = 0.5 * (a + b)
        left, right = gl(a, m), gl(m, b)
        two = left + right
        ok = np.abs(two - whole) <= 1e-13 * np.abs(two) + 1e-300
        np.add.at(total, owner[ok], two[ok])
        nk = ~ok
        a, b, owner = np.concatenate((a[nk], m[nk])), np.concatenate((m[nk], b[nk])), np.concatenate((owner[nk],) * 2)
        whole = np.concatenate((left[nk], right[nk]))
    if len(a):  # not converged in 40 halvings (a cusp): the last estimate
        np.add.at(total, owner, whole)
    return total


def _interval_bounds(d1, d2, lo, hi):
    """Bounds over each parameter interval [lo, hi] (see :func:`span_bounds`), and the values sampled there.

    Returns kappa, tangent (I, dim), curvature_vector (I, dim) bounds and the same three sampled at the
    interval's 7 equispaced points (lower bounds of the maxima: how tight the bounds are).
    """
    v = np.linspace(0.0, 1.0, 7)
    x6 = lo[:, None] + (hi - lo)[:, None] * v[None, :]
    D1 = d1(x6.ravel()).reshape(x6.shape + (-1,))
    D2 = d2(x6.ravel()).reshape(x6.shape + (-1,))
    # hodograph Bernstein coefficients from the values at 0, 1/2, 1 (indices 0, 3, 6 of the 7 points)
    B0, Bh, B2 = D1[:, 0], D1[:, 3], D1[:, 6]
    B1 = 2.0 * Bh - 0.5 * (B0 + B2)
    hodo = np.stack((B0, B1, B2), axis=1)  # (I, 3, dim)
    dn = np.linalg.norm(Bh, axis=1)
    d = Bh / np.where(dn > 0, dn, 1.0)[:, None]
    smin = np.min(np.einsum("ijk,ik->ij", hodo, d), axis=1)
    ok = (dn > 0) & (smin > 0)
    safe = np.where(ok, smin, 1.0)
    sp2 = np.einsum("ijk,ijk->ij", D1, D1)
    dot = np.einsum("ijk,ijk->ij", D1, D2)
    g = sp2 * np.einsum("ijk,ijk->ij", D2, D2) - dot ** 2
    gmax = np.maximum((g @ _BERN6.T).max(axis=1), 0.0)
    kappa = np.where(ok, np.sqrt(gmax) / safe ** 3, np.inf)
    tang = np.where(ok[:, None], np.minimum(np.abs(hodo).max(axis=1) / safe[:, None], 1.0), 1.0)
    # curvature vector numerator, degree 5: its values at 6 equispaced points, evaluated afresh
    v5 = np.linspace(0.0, 1.0, 6)
    x5 = lo[:, None] + (hi - lo)[:, None] * v5[None, :]
    E1 = d1(x5.ravel()).reshape(x5.shape + (-1,))
    E2 = d2(x5.ravel()).reshape(x5.shape + (-1,))
    num = (E2 * np.einsum("ijk,ijk->ij", E1, E1)[..., None]
           - E1 * np.einsum("ijk,ijk->ij", E1, E2)[..., None])  # (I, 6, dim)
    coef = np.einsum("ab,ibk->iak", _BERN5, num)
    kvec = np.where(ok[:, None], np.abs(coef).max(axis=1) / safe[:, None] ** 4, np.inf)
    kvec = np.minimum(kvec, kappa[:, None])
    # sampled at the 7 points: true values, lower bounds of the maxima
    sp = np.sqrt(np.maximum(sp2, 1e-300))
    k_s = np.sqrt(np.maximum(g, 0.0)) / sp ** 3
    t_s = np.abs(D1) / sp[..., None]
    kv_s = np.abs(D2 * sp2[..., None] - D1 * dot[..., None]) / sp2[..., None] ** 2
    return kappa, tang, kvec, k_s.max(axis=1), t_s.max(axis=1), kv_s.max(axis=1)


def span_bounds(piece: Piece, subdivisions: int = 8, slack: float = 0.01) -> SpanBounds:
    """Arc length and rigorous upper bounds of curvature and per-axis tangent / curvature-vector components.

    Each span is cut into ``subdivisions`` equal intervals; on each, with v in [0, 1] across it:

    * C'(v) is a quadratic: its Bernstein coefficients B0, B1, B2 (from its values at 0, 1/2, 1) bound each
      axis's |C'_i| by max_j |B_j,i| (convex hull), and, along the unit d of C'(1/2), the speed from below
      by s_min = min_j <B_j, d> (<C'(v), d> is a convex combination of the <B_j, d>, and |C'| >= <C', d>);
    * the curvature kappa = |C' ^ C''| / |C'|^3, where g = |C'|^2 |C''|^2 - (C'.C'')^2 = |C' ^ C''|^2 is a
      polynomial of degree 6 in v: its largest Bernstein coefficient bounds it, so
      kappa <= sqrt(max coef) / s_min^3;
    * the curvature vector K = (C'' |C'|^2 - C' (C'.C'')) / |C'|^4 has components of degree 5 in v over
      s_min^4, bounded the same way (and by kappa); the tangent's components by max|C'_i| / s_min (and 1).

    The Bernstein bounds converge to the maxima as the intervals shrink (quadratically): an interval whose
    bounds exceed the values sampled at its 7 points by more than ``slack`` (relative, or 1e-9 absolute) is
    halved, up to 8 times, so that the bounds are within about 1 % of the true maxima.  An interval where
    s_min <= 0 (a cusp, which the fit does not make) bounds nothing: inf.
    """
    t, c = piece.knots, piece.ctrl
    spl = BSpline.construct_fast(t, c, DEGREE)
    d1 = spl.derivative(1)
    edges = np.unique(t)
    length = _arc_lengths(d1, edges)
    kappa, tang, kvec = interval_bounds(piece, edges[:-1], edges[1:], subdivisions, slack)
    cumulative = np.concatenate(([0.0], np.cumsum(length)))
    return SpanBounds(_ro(edges), _ro(length), _ro(cumulative), _ro(kappa), _ro(tang), _ro(kvec))


def interval_bounds(piece: Piece, lo, hi, subdivisions: int = 8, slack: float = 0.01):
    """Upper bounds of the curvature, and of each axis's unit tangent and curvature-vector components, over each
    parameter interval [lo_i, hi_i] of a piece, each inside one knot span (see :func:`span_bounds`).

    Returns kappa (I,), tangent (I, dim), curvature_vector (I, dim)."""
    spl = BSpline.construct_fast(piece.knots, piece.ctrl, DEGREE)
    d1, d2 = spl.derivative(1), spl.derivative(2)
    lo0 = np.asarray(lo, dtype=float)
    hi0 = np.asarray(hi, dtype=float)
    nspan = len(lo0)
    dim = piece.ctrl.shape[1]
    S = int(subdivisions)
    widths = (hi0 - lo0) / S
    lo = np.repeat(lo0, S) + np.tile(np.arange(S), nspan) * np.repeat(widths, S)
    hi = np.concatenate((lo[1:], hi0[-1:])) if nspan else lo.copy()
    hi[S - 1::S] = hi0
    owner = np.repeat(np.arange(nspan), S)
    kappa = np.zeros(nspan)
    tang = np.zeros((nspan, dim))
    kvec = np.zeros((nspan, dim))
    for depth in range(9):
        if len(lo) == 0:
            break
        kb, tb, vb, ks, ts, vs = _interval_bounds(d1, d2, lo, hi)
        good = ((kb <= ks * (1 + slack) + 1e-9) & np.all(tb <= ts * (1 + slack) + 1e-9, axis=1)
                & np.all(vb <= vs * (1 + slack) + 1e-9, axis=1))
        if depth == 8:
            good[:] = True
        np.maximum.at(kappa, owner[good], kb[good])
        np.maximum.at(tang, owner[good], tb[good])
        np.maximum.at(kvec, owner[good], vb[good])
        bad = ~good
        if not bad.any():
            break
        mid = 0.5 * (lo[bad] + hi[bad])
        lo, hi = np.concatenate((lo[bad], mid)), np.concatenate((mid, hi[bad]))
        owner = np.concatenate((owner[bad], owner[bad]))
    return kappa, tang, kvec


# ---------------------------------------------------------------------------------------------- the ticks' kernel


@njit(cache=True)
def _deboor(knots, ctrl, j, u, out):
    """C(u) into out (dim,), u in the knot span j: de Boor's algorithm, degree 3, axis by axis in scalars
    (no allocation: this runs per tick)."""
    # the blending weights depend on the knots only: a[r][i] for the triangle's steps
    a31 = (u - knots[j]) / (knots[j + 1] - knots[j]) if knots[j + 1] > knots[j] else 0.0
    a21 = (u - knots[j - 1]) / (knots[j + 1] - knots[j - 1]) if knots[j + 1] > knots[j - 1] else 0.0
    a32 = (u - knots[j]) / (knots[j + 2] - knots[j]) if knots[j + 2] > knots[j] else 0.0
    a11 = (u - knots[j - 2]) / (knots[j + 1] - knots[j - 2]) if knots[j + 1] > knots[j - 2] else 0.0
    a22 = (u - knots[j - 1]) / (knots[j + 2] - knots[j - 1]) if knots[j + 2] > knots[j - 1] else 0.0
    a33 = (u - knots[j]) / (knots[j + 3] - knots[j]) if knots[j + 3] > knots[j] else 0.0
    for k in range(ctrl.shape[1]):
        d0, d1, d2, d3 = ctrl[j - 3, k], ctrl[j - 2, k], ctrl[j - 1, k], ctrl[j, k]
        # r = 1: i = 3, 2, 1 with alpha = (u - t[i+j-3]) / (t[i+j] - t[i+j-3])
        d3 = (1.0 - a33) * d2 + a33 * d3
        d2 = (1.0 - a22) * d1 + a22 * d2
        d1 = (1.0 - a11) * d0 + a11 * d1
        # r = 2: i = 3, 2 with alpha = (u - t[i+j-3]) / (t[i+j-1] - t[i+j-3])
        d3 = (1.0 - a32) * d2 + a32 * d3
        d2 = (1.0 - a21) * d1 + a21 * d2
        # r = 3: i = 3 with alpha = (u - t[j]) / (t[j+1] - t[j])
        out[k] = (1.0 - a31) * d2 + a31 * d3


@njit(cache=True)
def _speed(knots, ctrl, j, u):
    """|C'(u)|, u in the knot span j: de Boor on the hodograph (degree 2 on knots[1:-1], control points
    Q_i = 3 (P_i+1 - P_i) / (t_i+4 - t_i+1)), axis by axis in scalars."""
    # r = 1: i = 2, 1 with alpha = (u - t[i+j-2]) / (t[i+j] - t[i+j-2]); r = 2: i = 2, (u - t[j]) / (t[j+1] - t[j])
    b2 = (u - knots[j]) / (knots[j + 2] - knots[j]) if knots[j + 2] > knots[j] else 0.0
    b1 = (u - knots[j - 1]) / (knots[j + 1] - knots[j - 1]) if knots[j + 1] > knots[j - 1] else 0.0
    c2 = (u - knots[j]) / (knots[j + 1] - knots[j]) if knots[j + 1] > knots[j] else 0.0
    w0 = knots[j + 1] - knots[j - 2]
    w1 = knots[j + 2] - knots[j - 1]
    w2 = knots[j + 3] - knots[j]
    w0 = 3.0 / w0 if w0 > 0 else 0.0
    w1 = 3.0 / w1 if w1 > 0 else 0.0
    w2 = 3.0 / w2 if w2 > 0 else 0.0
    total = 0.0
    for k in range(ctrl.shape[1]):
        q0 = w0 * (ctrl[j - 2, k] - ctrl[j - 3, k])
        q1 = w1 * (ctrl[j - 1, k] - ctrl[j - 2, k])
        q2 = w2 * (ctrl[j, k] - ctrl[j - 1, k])
        q2 = (1.0 - b2) * q1 + b2 * q2
        q1 = (1.0 - b1) * q0 + b1 * q1
        v = (1.0 - c2) * q1 + c2 * q2
        total += v * v
    return math.sqrt(total)


@njit(cache=True)
def _length_in_span(knots, ctrl, j, a, b):
    """Arc length from u = a to u = b inside span j (Gauss-Legendre, 16 points)."""
    mid = 0.5 * (a + b)
    half = 0.5 * (b - a)
    total = 0.0
    for q in range(16):
        total += _GL_W[q] * _speed(knots, ctrl, j, mid + half * _GL_X[q])
    return half * total


@njit(cache=True)
def points_at_length(knots, ctrl, span_s, s_values, out):
    """The points of a piece at the arc lengths s_values (mm from its start) into out (len(s_values), dim).

    ``span_s`` is :class:`SpanBounds`'s ``cumulative`` (arc length at each distinct knot).  In its span, the
    parameter of each length solves L(u) = s by Newton's method (L' = |C'|), L by 16-point Gauss-Legendre,
    safeguarded by bisection on the span, to |L(u) - s| <= 1e-10 mm: the step is taken once more after
    |L(u) - s| < 1e-7 mm, which Newton's quadratic convergence (|L''/L'| = |d|C'|/du| / |C'|, of order
    the curvature on chord-length pieces) takes below 1e-12 mm.  For lengths in increasing order (the ticks)
    each starts from the previous one's parameter and integrates only the gap: a step or two a point.
    Lengths outside [0, total] give the end points.
    """
    nspan = len(span_s) - 1
    m = len(knots) - 4
    first = np.empty(nspan, dtype=np.int64)  # the knot index of each nonzero span
    count = 0
    for jj in range(3, m):
        if knots[jj + 1] > knots[jj] and count < nspan:
            first[count] = jj
            count += 1
    prev_k = -1
    prev_u = 0.0
    prev_len = 0.0  # arc length from the span's start to prev_u
    for q in range(len(s_values)):
        s = s_values[q]
        lo, hi = 0, nspan - 1
        while lo < hi:  # the span: the last edge at or before s
            mid = (lo + hi + 1) // 2
            if span_s[mid] <= s:
                lo = mid
            else:
                hi = mid - 1
        k = lo
        j = first[k]
        a, b = knots[j], knots[j + 1]
        target = s - span_s[k]
        total = span_s[k + 1] - span_s[k]
        if target <= 0.0:
            u = a
            length = 0.0
        elif target >= total:
            u = b
            length = total
        else:
            base, base_len = a, 0.0
            if k == prev_k and target >= prev_len:
                base, base_len = prev_u, prev_len
            lo_u, hi_u = base, b
            sp = _speed(knots, ctrl, j, base)
            u = base + (target - base_len) / sp if sp > 0 else 0.5 * (base + b)
            if not (lo_u < u < hi_u):
                u = 0.5 * (lo_u + hi_u)
            length = target
            for _ in range(60):
                f = base_len + _length_in_span(knots, ctrl, j, base, u) - target
                if abs(f) <= 1e-10:
                    break
                if f > 0:
                    hi_u = u
                else:
                    lo_u = u
                sp = _speed(knots, ctrl, j, u)
                nu = u - f / sp if sp > 0 else 0.5 * (lo_u + hi_u)
                if not (lo_u < nu < hi_u):
                    nu = 0.5 * (lo_u + hi_u)
                u = nu
                if abs(f) < 1e-7:
                    break
        prev_k, prev_u, prev_len = k, u, length
        _deboor(knots, ctrl, j, u, out[q])
