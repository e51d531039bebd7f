"""NURBS blocks for the look-ahead: a G5.2/G6.2 block, a YAML ``nurbs`` block or a DXF spline as cubic curve rows.

The look-ahead's segments are lines, arcs and cubic Bézier rows (:mod:`.segments`), each with caps from rigorous
bounds of its own curvature and tangent (the rows smoothing makes).  A NURBS block becomes a CURVE block of such
rows.  Each row is the cubic Hermite interpolant of a piece of one knot span of the block: the curve's own points
and derivatives at the piece's ends, so that consecutive rows meet with the curve's tangent (no corner between
them) and a polynomial block of degree 3 or less is reproduced exactly, to rounding.  A piece is halved until

- the row lies within half the *budget* of the curve: the distance |H(w) − C(u(w))| of the row's and the curve's
  points at the same parameter, taken at SAMPLES points across the piece, bounds both sides at once (every point
  of the row lies within it of the curve, and every point of the curve within it of the row), and half the budget
  keeps the other half in hand for what falls between the samples (the error of a Hermite cubic is a smooth
  w²(1 − w)² shape, and its samples 1/33 of the piece apart see its peak to a small fraction of itself);
- the row's 8-point Gauss–Legendre length (segments.bezier_length, with which the interpolator maps arc length
  to the row's parameter) agrees with that of its two halves to LENGTH_RTOL: the rule is exact on the row.

The budget is APPROX_SHARE of the block's tolerance, the rest left to the sag of the interpolator's chords; with no
tolerance (0: followed as programmed) FLOOR, and the chords are held only by the job's own chord tolerance, as on
an arc.  Hand-written here, not scipy: scipy fits B-splines to data (smoothing uses it), it does not convert a
rational curve to cubic pieces; a NURBS library that does (geomdl) approximates without a verified bound.  A
piece is made and measured by compiled kernels (:func:`_moving_piece`): in numpy, piece by piece, the 26 251 rows
of a 600-line G6.2 gear on the exact path took 13 s of its 16 s (its first tick after 10.3 s; 1.2 s now).

A row's u is the fraction of the block's knot domain (in a look-ahead stream every block's u runs 0 … 1), and
follows the Hermite's parameter linearly: the programmed point the command stands for, to within the budget —
except on a row with an end at rest, whose geometric Hermite lies within the budget of the curve but does not
follow its parameter (there u is a point of the curve nearby, up to the row's length away).

A knot span that stays at one point (a control point repeated past the degree) makes no row.  Where the block's
pieces meet at an angle (a knot of full multiplicity, a control point repeated to the degree: a DXF polyline's
corner as one spline), the row that starts there has a node cap of 0: the plan comes to rest on the corner, on the
curve, as at a joint between blocks too sharp to pass moving (no blend inside a block).
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..errors import SpecError
from ..nurbs.kernels import bezier_table
from . import segments as seg

APPROX_SHARE = 0.1  # of the tolerance: the rows' budget from the curve
FLOOR = 2e-9  # mm: the budget with no tolerance (rows within 1e-9 mm of the curve)
SAMPLES = 32  # points inside each piece where the row is checked against the curve
LENGTH_RTOL = 1e-12  # a row's Gauss-Legendre length against that of its halves
MAX_DEPTH = 40  # halvings of a knot span at most
REST = 1e-9  # an end whose speed times the piece's parameter length is below this of its chord is at rest
DENSE = 257  # samples of a piece with an end at rest, each way
DISTINCT = 1e-9  # control points closer than this, relative to the span's size, are one point (rounding)
LENGTH_FLOOR = 1e-3  # of the budget: a row's length error below this is none (positions along the path only)
WITHOUT = "split the block there into two"
_W = np.ascontiguousarray(np.linspace(0.0, 1.0, SAMPLES + 2)[1:-1])
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


@njit(cache=True)
def _rational_at(Q, t, point, deriv):
    """*point* and *deriv* (dim,): the point and first derivative (with respect to t) of the rational Bézier with
    homogeneous control points Q (p + 1, dim + 1) at t in [0, 1] (degree >= 1: validated), from its Bernstein
    sums."""
    p = Q.shape[0] - 1
    d1 = Q.shape[1]
    u = 1.0 - t
    aw = 0.0
    dw = 0.0
    for i in range(d1 - 1):
        point[i] = 0.0
        deriv[i] = 0.0
    binom = 1.0  # C(p, j)
    for j in range(p + 1):
        b = binom * t ** j * u ** (p - j)
        for i in range(d1 - 1):
            point[i] += b * Q[j, i]
        aw += b * Q[j, d1 - 1]
        binom = binom * (p - j) / (j + 1)
    binom = 1.0  # C(p - 1, j)
    for j in range(p):
        b = p * binom * t ** j * u ** (p - 1 - j)
        for i in range(d1 - 1):
            deriv[i] += b * (Q[j + 1, i] - Q[j, i])
        dw += b * (Q[j + 1, d1 - 1] - Q[j, d1 - 1])
        binom = binom * (p - 1 - j) / (j + 1)
    for i in range(d1 - 1):
        point[i] /= aw
        deriv[i] = (deriv[i] - point[i] * dw) / aw


@njit(cache=True)
def _rational_many(Q, ts, points, derivs):
    """_rational_at at each of ts (m,): points and derivs (m, dim)."""
    for k in range(ts.shape[0]):
        _rational_at(Q, ts[k], points[k], derivs[k])


def _rational(Q, t):
    """Points and first derivatives (with respect to t) of the rational Bézier Q at t (m,) in [0, 1]."""
    t = np.ascontiguousarray(t, dtype=float)
    points = np.empty((t.shape[0], Q.shape[1] - 1))
    derivs = np.empty_like(points)
    _rational_many(Q, t, points, derivs)
    return points, derivs


@njit(cache=True)
def _gl_length(ctrl, lo, hi, gl_x, gl_w):
    """8-point Gauss–Legendre length of the cubic Bézier ctrl (4, dim) over [lo, hi] of its parameter."""
    half = 0.5 * (hi - lo)
    total = 0.0
    for k in range(gl_x.shape[0]):
        w = lo + half * (1.0 + gl_x[k])
        a = 1.0 - w
        sq = 0.0
        for i in range(ctrl.shape[1]):
            d = 3.0 * (a * a * (ctrl[1, i] - ctrl[0, i]) + 2.0 * a * w * (ctrl[2, i] - ctrl[1, i])
                       + w * w * (ctrl[3, i] - ctrl[2, i]))
            sq += d * d
        total += gl_w[k] * math.sqrt(sq)
    return half * total


@njit(cache=True)
def _moving_piece(Q, t0, t1, samples, gl_x, gl_w, ctrl, work):
    """The cubic Hermite Bézier *ctrl* (4, dim) of the rational Bézier Q over [t0, t1] and (at rest, deviation,
    its Gauss–Legendre length, that of its two halves): the deviation the largest distance from the curve at the
    same parameter at *samples* (fractions of the piece).  At rest (an end where the curve's speed vanishes, see
    REST): nothing else is computed, the piece is _at_rest's.  *work* (4, dim): scratch."""
    dim = Q.shape[1] - 1
    h = t1 - t0
    _rational_at(Q, t0, work[0], work[1])
    _rational_at(Q, t1, work[2], work[3])
    chord = 0.0
    s0 = 0.0
    s1 = 0.0
    top = 0.0
    for i in range(dim):
        chord += (work[2, i] - work[0, i]) ** 2
        s0 += work[1, i] ** 2
        s1 += work[3, i] ** 2
        top = max(top, abs(work[0, i]), abs(work[2, i]))
    chord = math.sqrt(chord)
    moving = REST * max(chord, top * 1e-12)
    if not (math.sqrt(s0) * h > moving and math.sqrt(s1) * h > moving):
        return True, 0.0, 0.0, 0.0
    for i in range(dim):
        ctrl[0, i] = work[0, i]
        ctrl[1, i] = work[0, i] + (h / 3.0) * work[1, i]
        ctrl[2, i] = work[2, i] - (h / 3.0) * work[3, i]
        ctrl[3, i] = work[2, i]
    dev = 0.0
    for k in range(samples.shape[0]):
        b = samples[k]
        a = 1.0 - b
        _rational_at(Q, t0 + h * b, work[0], work[1])
        sq = 0.0
        for i in range(dim):
            row = a ** 3 * ctrl[0, i] + 3.0 * a * a * b * ctrl[1, i] + 3.0 * a * b * b * ctrl[2, i] + b ** 3 * ctrl[3, i]
            sq += (row - work[0, i]) ** 2
        dev = max(dev, math.sqrt(sq))
    whole = _gl_length(ctrl, 0.0, 1.0, gl_x, gl_w)
    halves = _gl_length(ctrl, 0.0, 0.5, gl_x, gl_w) + _gl_length(ctrl, 0.5, 1.0, gl_x, gl_w)
    return False, dev, whole, halves


def _hermite(Q, t0, t1):
    """The cubic Hermite Bézier (4, dim) of the rational Bézier Q over [t0, t1], its largest sampled distance from
    the curve at the same parameter, and its Gauss–Legendre length and that of its halves (_moving_piece).  At an
    end where the curve is at rest (C' = 0: a control point repeated, as G5.2 programs that restate the current
    position make), see _at_rest."""
    dim = Q.shape[1] - 1
    ctrl = np.empty((4, dim))
    at_rest, dev, whole, halves = _moving_piece(Q, t0, t1, _W, _GL_X, _GL_W, ctrl, np.empty((4, dim)))
    if at_rest:
        pts, der = _rational(Q, np.array([t0, t1]))
        speed = np.sqrt((der * der).sum(axis=1)) * (t1 - t0)
        chord = math.sqrt(float(((pts[1] - pts[0]) ** 2).sum()))
        ctrl, dev = _at_rest(Q, t0, t1, pts, der, speed, REST * max(chord, float(np.abs(pts).max()) * 1e-12))
        whole = _gl_length(ctrl, 0.0, 1.0, _GL_X, _GL_W)
        halves = _gl_length(ctrl, 0.0, 0.5, _GL_X, _GL_W) + _gl_length(ctrl, 0.5, 1.0, _GL_X, _GL_W)
    return ctrl, dev, whole, halves


def _limit_direction(Q, end):
    """The unit tangent of the rational Bézier Q at t = 0 (end 0) or 1 (end 1) where its derivative vanishes: along
    the first control point, from that end, that differs from the end's (exact for positive weights)."""
    P = Q[:, :-1] / Q[:, -1:]
    # a point repeated in the block comes out of knot insertion and the division by its weight a few ulps away
    # from its twin: a difference below DISTINCT of the span's size is that rounding, not a direction
    floor = DISTINCT * max(float(np.abs(P).max()), float(np.sqrt(((P[1:] - P[:-1]) ** 2).sum(axis=1)).sum()))
    order = range(1, P.shape[0]) if end == 0 else range(P.shape[0] - 2, -1, -1)
    for k in order:
        d = (P[k] - P[0]) if end == 0 else (P[-1] - P[k])
        n = math.sqrt(float(d @ d))
        if n > floor:
            return d / n
    return None


def _at_rest(Q, t0, t1, pts, der, speed, moving):
    """A piece with an end where the curve is at rest (speed <= *moving*): a geometric Hermite (the end's tangent
    the curve's limit direction there, its length a third of the chord; a moving end as _hermite makes it),
    measured geometrically: the two-sided distance of DENSE samples of each from the other's polyline, plus the
    polylines' sag bound (the largest distance of a sample from its neighbours' chord).  Only a knot span's own
    ends have a limit direction from its control points; at rest inside a span (a cusp) the piece fails (inf)."""
    h = t1 - t0
    chord = math.sqrt(float(((pts[1] - pts[0]) ** 2).sum()))
    ctrl = np.array([pts[0], pts[0], pts[1], pts[1]], dtype=float)
    for end in (0, 1):
        if speed[end] > moving:
            tangent = der[end] * (h / 3.0)
        else:
            direction = _limit_direction(Q, end) if (t0 == 0.0 if end == 0 else t1 == 1.0) else None
            if direction is None or chord == 0.0:
                return ctrl, math.inf
            tangent = direction * (chord / 3.0)
        if end == 0:
            ctrl[1] = pts[0] + tangent
        else:
            ctrl[2] = pts[1] - tangent
    t = np.linspace(0.0, 1.0, DENSE)
    curve, _ = _rational(Q, t0 + h * t)
    a = (1.0 - t)[:, None]
    b = t[:, None]
    row = a ** 3 * ctrl[0] + 3.0 * a * a * b * ctrl[1] + 3.0 * a * b * b * ctrl[2] + b ** 3 * ctrl[3]
    dev = max(_to_polyline(row, curve), _to_polyline(curve, row))
    return ctrl, dev + _sag(row) + _sag(curve)


def _to_polyline(points, vertices):
    """The largest distance of the points from the polyline through vertices."""
    a = vertices[:-1]
    ab = vertices[1:] - a
    den = np.maximum((ab * ab).sum(axis=1), 1e-300)
    worst = 0.0
    for lo in range(0, points.shape[0], 128):
        q = points[lo:lo + 128, None, :]
        t = np.clip(((q - a) * ab).sum(axis=2) / den, 0.0, 1.0)
        worst = max(worst, float(np.sqrt(((a + t[..., None] * ab - q) ** 2).sum(axis=2)).min(axis=1).max()))
    return worst


def _sag(points):
    """The largest distance of a sample from the chord of its two neighbours (a bound on the polyline's sag)."""
    a, p, b = points[:-2], points[1:-1], points[2:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300), 0.0, 1.0)
    return float(np.sqrt(((a + t[:, None] * ab - p) ** 2).sum(axis=1)).max()) if p.shape[0] else 0.0


def _pieces(Q, budget, where, u_of):
    """[(t0, t1, ctrl, deviation)] of the span's rational Bézier Q, in order, each accepted (see the module);
    *u_of* maps the span's parameter to the block's own (for a refusal)."""
    out = []
    stack = [(0.0, 1.0, 0)]
    while stack:
        t0, t1, depth = stack.pop()
        ctrl, dev, whole, halves = _hermite(Q, t0, t1)
        if dev <= 0.5 * budget and abs(whole - halves) <= max(LENGTH_RTOL * whole, LENGTH_FLOOR * budget):
            out.append((t0, t1, ctrl, dev))
            continue
        if depth >= MAX_DEPTH:
            raise SpecError(f"{where}: a NURBS block the look-ahead cannot follow: no cubic piece of it within "
                            f"{0.5 * budget * 1e3:.3g} um near u = {u_of(t0):.9g} (a cusp, or the curve at rest "
                            f"there: its speed |C'(u)| is 0); {WITHOUT}")
        mid = 0.5 * (t0 + t1)
        stack.append((mid, t1, depth + 1))  # the left half first
        stack.append((t0, mid, depth + 1))
    return out


def nurbs_rows(spec, tolerance, index, feed, lim, where):
    """The curve rows of a NURBS block (config.CurveSpec *spec*), its program index *index*, feedrate *feed* (mm/s),
    blend *tolerance* (mm; 0: none), the segments' limits vector *lim*.  Returns (rows (m, NCOL), the largest
    sampled deviation of a row from the curve, mm).  *where* names the block in a refusal."""
    from .smooth import finish_rows

    U = np.array(spec.knots, dtype=float)  # a writable copy: the block's own knots are frozen (one kernel layout)
    p = int(spec.degree)
    cps = np.asarray(spec.control_points, dtype=float)
    w = np.asarray(spec.weights, dtype=float)
    n = cps.shape[0] - 1
    dim = cps.shape[1]
    B = bezier_table(U, np.ascontiguousarray(np.column_stack([cps * w[:, None], w])), p, n)
    a0, b0 = float(U[p]), float(U[n + 1])
    # with no tolerance, 1e-9 mm, or the rounding of coordinates as large as the block's (64 ulps) if more
    budget = APPROX_SHARE * tolerance if tolerance > 0.0 else max(FLOOR, 64.0 * np.finfo(float).eps
                                                                   * float(np.abs(cps).max()))
    parts = []
    for span in range(p, n + 1):
        if U[span + 1] > U[span]:
            Q = B[span, 0]
            P = Q[:, :-1] / Q[:, -1:]
            if float(np.abs(P - P[0]).max()) <= DISTINCT * max(float(np.abs(P).max()), 1e-300):
                continue  # a span that stays at one point (a control point repeated): no motion, no row

            def u_of(t, span=span):
                return U[span] + t * (U[span + 1] - U[span])

            for t0, t1, ctrl, dev in _pieces(Q, budget, where, u_of):
                u0 = (U[span] + t0 * (U[span + 1] - U[span]) - a0) / (b0 - a0)
                u1 = (U[span] + t1 * (U[span + 1] - U[span]) - a0) / (b0 - a0)
                parts.append((u0, u1, ctrl, dev))
    if not parts:
        raise SpecError(f"{where}: a NURBS block that does not move (every control point one point)")
    rows = np.zeros((len(parts), seg.NCOL))
    for r, (u0, u1, ctrl, _) in enumerate(parts):
        for j, col in enumerate((seg.B0, seg.B1, seg.B2, seg.B3)):
            rows[r, col:col + dim] = ctrl[j]
        rows[r, seg.U0] = u0
        rows[r, seg.DU] = u1 - u0
    # the block's ends exactly as programmed, and each row starting where the one before ends
    rows[0, seg.B0:seg.B0 + dim] = cps[0]
    rows[-1, seg.B3:seg.B3 + dim] = cps[-1]
    rows[1:, seg.B0:seg.B0 + 3] = rows[:-1, seg.B3:seg.B3 + 3]
    rows[:, seg.KIND] = seg.CURVE
    rows[:, seg.BLOCK] = index
    rows[:, seg.UKIND] = seg.U_CURVE
    rows[:, seg.NODECAP] = math.inf
    rows[:, seg.JCAP] = math.inf
    deviation = max(dev for *_, dev in parts)
    finish_rows(rows, lim, feed, tolerance - budget if tolerance > 0.0 else math.inf)
    rows[_corners(parts), seg.NODECAP] = 0.0  # a corner inside the block: at rest there
    if not np.all(rows[:, seg.VCAP] > 0.0) or not np.all(np.isfinite(rows[:, seg.ACAP])):
        bad = int(np.flatnonzero(~(rows[:, seg.VCAP] > 0.0) | ~np.isfinite(rows[:, seg.ACAP]))[0])
        lo = a0 + rows[bad, seg.U0] * (b0 - a0)
        hi = a0 + (rows[bad, seg.U0] + rows[bad, seg.DU]) * (b0 - a0)
        raise SpecError(f"{where}: a NURBS block the look-ahead cannot follow: its speed |C'(u)| falls to 0 (a cusp, "
                        f"or control points repeated) in u = {lo:.9g} .. {hi:.9g}; {WITHOUT}")
    return rows, deviation


def _corners(parts):
    """The rows (their indices) that start where the block's pieces do not meet along one tangent (a knot of full
    multiplicity, or a control point repeated to the degree, inside it): the block turns there, and the plan
    comes to rest on that point, exactly on the curve, as at a joint too sharp to pass moving."""
    corners = []
    for r, ((_, u1, c0, _), (_, _, c1, _)) in enumerate(zip(parts[:-1], parts[1:])):
        t_out = c0[3] - c0[2]
        t_in = c1[1] - c1[0]
        n = math.sqrt(float(t_out @ t_out) * float(t_in @ t_in))
        cosine = float(t_out @ t_in) / n if n > 0.0 else -1.0
        if cosine < math.cos(seg.EXACT_PATH_KINK):
            corners.append(r + 1)
    return corners


def end_tangents(rows):
    """Unit tangents at the start and the end of a CURVE block's rows (the first and last rows' hodographs)."""
    first, last = rows[0], rows[-1]
    return _direction(first, (seg.B1, seg.B2, seg.B3), seg.B0, 1.0), _direction(last, (seg.B2, seg.B1, seg.B0),
                                                                               seg.B3, -1.0)


def _direction(row, others, origin, sign):
    # a zero end derivative (rejected above as a cusp) would leave the next control point: the first that differs
    for col in others:
        d = sign * (row[col:col + 3] - row[origin:origin + 3])
        n = math.sqrt(float(d @ d))
        if n > 0.0:
            return d / n
    return np.array([1.0, 0.0, 0.0])
