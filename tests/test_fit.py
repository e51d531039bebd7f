"""The refitting of runs of short moves (motion/fit.py), checked against brute force.

The two-sided deviation is measured independently of the module's bound: both curves sampled densely (the
polyline's segments and each piece), nearest distances by scipy's cKDTree both ways, plus half the larger
sample spacing (a point between samples is that close to one of them).  That brute-force figure must stay
within the tolerance and within each piece's reported (verified) deviation.
"""
from __future__ import annotations

import math
import time

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from scipy.interpolate import BSpline, make_lsq_spline
from scipy.optimize import brentq
from scipy.spatial import cKDTree

from nurbsinterp.motion import fit

TOL = 0.005  # mm: the 5 um


# ---------------------------------------------------------------------------------------------- polylines


def circle(radius=5.0, chord=0.2, turns=1.0, centre=(0.0, 0.0)):
    n = int(round(2 * math.pi * radius * turns / chord))
    th = np.linspace(0.0, 2 * math.pi * turns, n + 1)
    return np.c_[centre[0] + radius * np.cos(th), centre[1] + radius * np.sin(th)]


def spiral(n, chord=0.2):
    """The issue's spiral r = 5 + 0.5 theta / 2 pi, chords of about ``chord``."""
    th = np.empty(n)
    th[0] = 0.0
    for i in range(1, n):
        th[i] = th[i - 1] + chord / (5 + 0.5 * th[i - 1] / (2 * math.pi))
    r = 5 + 0.5 * th / (2 * math.pi)
    return np.c_[r * np.cos(th), r * np.sin(th)]


def raster_row(n=100, chord=0.2, y=1.3):
    """A row of the issue's raster over z = 2 sin(x/7) cos(y/5)."""
    x = np.arange(n + 1) * chord
    return np.c_[x, np.full_like(x, y), 2 * np.sin(x / 7) * np.cos(y / 5)]


def sine(n=300, chord=0.05, amplitude=0.5, wavelength=4.0):
    x = np.arange(n + 1) * chord
    return np.c_[x, amplitude * np.sin(2 * math.pi * x / wavelength)]


def rounded(points, decimals):
    return np.round(points, decimals)


def noisy(points, amplitude, seed=0):
    return points + np.random.default_rng(seed).uniform(-amplitude, amplitude, points.shape)


# ---------------------------------------------------------------------------------------------- brute force


def _dense_polyline(points, spacing):
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        k = max(1, int(math.ceil(np.linalg.norm(b - a) / spacing)))
        out.append(a + np.outer(np.arange(1, k + 1) / k, b - a))
    return np.concatenate(out)


def _dense_piece(piece, spacing):
    spl = BSpline(piece.knots, piece.ctrl, 3)
    coarse = spl(np.linspace(0, piece.knots[-1], 2001))
    length = np.linalg.norm(np.diff(coarse, axis=0), axis=1).sum()
    k = max(2, int(math.ceil(1.5 * length / spacing)))
    return spl(np.linspace(piece.knots[0], piece.knots[-1], k + 1))


def _exact_to_polyline(x, points, chunk=2000):
    """Exact distance of each point of x to the polyline (every segment, brute force)."""
    a, d = points[:-1], np.diff(points, axis=0)
    dd = np.maximum((d * d).sum(axis=1), 1e-300)
    out = np.empty(len(x))
    for i in range(0, len(x), chunk):
        rel = x[i:i + chunk, None, :] - a[None, :, :]
        w = np.clip((rel * d[None]).sum(axis=2) / dd[None], 0.0, 1.0)
        out[i:i + chunk] = np.sqrt(((rel - w[..., None] * d[None]) ** 2).sum(axis=2)).min(axis=1)
    return out


def brute_deviation(piece, points, spacing):
    """Two-sided deviation of one piece from the polyline points[first..last], by dense samples.

    Returns (upper, lower): ``upper`` bounds the true deviation from above (nearest sampled distances both
    ways plus half the largest sample spacing: a point between samples is that close to one of them);
    ``lower`` from below (exact distances from the curve's samples to the polyline's segments).
    """
    run = points[piece.first:piece.last + 1]
    poly = _dense_polyline(run, spacing)
    curve = _dense_piece(piece, spacing)
    gap = max(np.linalg.norm(np.diff(curve, axis=0), axis=1).max(), np.linalg.norm(np.diff(poly, axis=0), axis=1).max())
    d1 = cKDTree(poly).query(curve)[0]
    d2 = cKDTree(curve).query(poly)[0]
    far = curve[np.argsort(d1)[-64:]]  # the curve's samples farthest from the polyline: exactly measured
    lower = _exact_to_polyline(far, run).max()
    return max(d1.max(), d2.max()) + gap / 2, lower


def _direction_rounding(leg):
    """How far the direction of a leg of two stored control points may be from the exact one: each of its
    coordinates is rounded once (half an ulp of the largest), so the direction errs by at most
    √dim · ulp / |leg| (and the unit vectors' own rounding, a few eps)."""
    scale = float(np.abs(leg).max())
    length = float(np.linalg.norm(leg[1] - leg[0]))
    return math.sqrt(leg.shape[1]) * float(np.spacing(scale)) / length + 4 * np.finfo(float).eps


def check_pieces(pieces, points, tolerance, t0=None, t1=None):
    """Every guarantee of fit_run, each measured independently; returns the largest brute-force deviation."""
    assert pieces[0].first == 0 and pieces[-1].last == len(points) - 1
    np.testing.assert_array_equal(pieces[0].ctrl[0], points[0])
    np.testing.assert_array_equal(pieces[-1].ctrl[-1], points[-1])
    worst = 0.0
    for p, q in zip(pieces[:-1], pieces[1:]):
        assert p.last == q.first
        np.testing.assert_array_equal(p.ctrl[-1], points[p.last])
        np.testing.assert_array_equal(q.ctrl[0], points[q.first])
        ta = _unit(p.ctrl[-1] - p.ctrl[-2])
        tb = _unit(q.ctrl[1] - q.ctrl[0])
        assert np.linalg.norm(ta - tb) <= _direction_rounding(p.ctrl[-2:]) + _direction_rounding(q.ctrl[:2]), (ta, tb)
    if t0 is not None:
        assert np.linalg.norm(_unit(pieces[0].ctrl[1] - pieces[0].ctrl[0]) - _unit(np.asarray(t0))) \
            <= _direction_rounding(pieces[0].ctrl[:2])
    if t1 is not None:
        assert np.linalg.norm(_unit(pieces[-1].ctrl[-1] - pieces[-1].ctrl[-2]) - _unit(np.asarray(t1))) \
            <= _direction_rounding(pieces[-1].ctrl[-2:])
    for p in pieces:
        assert p.deviation <= fit.BUDGET * tolerance
        upper, lower = brute_deviation(p, points, tolerance / 40)
        assert lower <= p.deviation + 1e-12, (lower, p.deviation)  # the verified bound is an upper bound
        assert upper <= tolerance, (upper, tolerance)
        worst = max(worst, upper)
    return worst


def _unit(v):
    return v / np.linalg.norm(v)


def sampled_curvature(piece, n=4001):
    spl = piece.spline()
    u = np.linspace(piece.knots[0], piece.knots[-1], n)
    d1, d2 = spl.derivative(1)(u), spl.derivative(2)(u)
    sp2 = (d1 * d1).sum(axis=1)
    cross2 = sp2 * (d2 * d2).sum(axis=1) - (d1 * d2).sum(axis=1) ** 2
    return np.sqrt(np.maximum(cross2, 0)) / sp2 ** 1.5


# ---------------------------------------------------------------------------------------------- fit_run


def test_knot_rule_calibration():
    """E_CUBIC: a least-squares cubic with uniform spans h on a circle of radius R errs by about E h^4 / R^3."""
    for h in (0.2, 0.4, 0.8):
        th = np.linspace(0, 6, 6001)
        pts = np.c_[np.cos(th), np.sin(th)]
        inner = np.linspace(0, 6, int(round(6 / h)) + 1)[1:-1]
        s = make_lsq_spline(th, pts, np.r_[[0] * 4, inner, [6] * 4], k=3)
        e = np.abs(np.linalg.norm(s(th), axis=1) - 1)[1000:-1000].max()
        assert 0.6 * fit.E_CUBIC <= e / h ** 4 <= 1.4 * fit.E_CUBIC


CASES = {
    "circle": circle(),
    "circle-1e-4": rounded(circle(), 4),
    "circle-1e-3": rounded(circle(), 3),
    "circle-noise": noisy(circle(), 1e-3, seed=3),
    "small-circle": circle(radius=1.0, chord=0.05),
    "spiral": spiral(150),
    "spiral-1e-3": rounded(spiral(150), 3),
    "raster-row": raster_row(),
    "raster-row-1e-4": rounded(raster_row(), 4),
    "sine": sine(),
    "sine-noise": noisy(sine(), 5e-4, seed=1),
    "micro-1um": circle(radius=1.0, chord=0.001, turns=0.2),
    "micro-1um-1e-4": rounded(circle(radius=1.0, chord=0.001, turns=0.2), 4),
    "micro-1um-1e-3": rounded(circle(radius=1.0, chord=0.001, turns=0.2), 3),
    "micro-4um-1e-3": rounded(circle(radius=2.0, chord=0.004, turns=0.1), 3),
    "near-straight": noisy(np.c_[np.linspace(0, 20, 101), 1e-3 * np.linspace(0, 20, 101) ** 2 / 20], 2e-4),
    "straight": np.c_[np.linspace(0, 10, 51), np.linspace(0, 5, 51), np.linspace(3, 1, 51)],
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_fit_within_tolerance_both_ways(name):
    points = CASES[name]
    pieces = fit.fit_run(points, TOL)
    check_pieces(pieces, points, TOL)


@pytest.mark.parametrize("name", ["circle-1e-4", "spiral", "raster-row-1e-4", "micro-1um-1e-3"])
def test_end_tangents_honoured(name):
    points = CASES[name]
    d0 = _unit(points[1] - points[0])
    d1 = _unit(points[-1] - points[-2])
    # the neighbouring lines' directions, turned a little (a line beside the run joins it without a corner)
    rot = np.eye(points.shape[1])
    rot[:2, :2] = [[math.cos(0.05), -math.sin(0.05)], [math.sin(0.05), math.cos(0.05)]]
    for t0, t1 in ((d0, d1), (rot @ d0, rot.T @ d1), (None, d1), (d0, None)):
        pieces = fit.fit_run(points, TOL, t0, t1)
        check_pieces(pieces, points, TOL, t0, t1)


def test_pieces_join_g1_where_a_long_run_is_cut():
    points = rounded(spiral(400), 4)
    pieces = fit.fit_run(points, TOL, max_vertices=60)
    assert len(pieces) >= 7
    check_pieces(pieces, points, TOL)


def test_a_corner_inside_a_run_is_split_and_still_within_tolerance():
    """fit_run given a real corner (split_runs would cut it): refined, split, still G1 and within tolerance."""
    a = np.c_[np.linspace(0, 2, 11), np.zeros(11)]
    b = np.c_[2 + np.zeros(10), np.linspace(0.2, 2, 10)]
    points = np.concatenate((a, b))
    pieces = fit.fit_run(points, TOL)
    check_pieces(pieces, points, TOL)
    # a retract then a plunge on the same line, and a near-reversal
    down = np.c_[np.zeros(10), np.zeros(10), np.linspace(5, 0, 10)]
    for back in (down[::-1][1:], down[::-1][1:] + [0.05, 0, 0]):
        points = np.concatenate((down, back))
        check_pieces(fit.fit_run(points, TOL), points, TOL)


def test_single_segment_and_short_runs():
    seg = np.array([[0.0, 0.0], [1.0, 0.0]])
    for t0, t1 in ((None, None), ((0, 1), None), ((1, 1), (1, -1)), ((-1, 0), (-1, 0))):
        pieces = fit.fit_run(seg, TOL, t0, t1)
        check_pieces(pieces, seg, TOL, t0, t1)
    tri = np.array([[0.0, 0.0], [0.1, 0.001], [0.2, 0.0]])
    check_pieces(fit.fit_run(tri, TOL), tri, TOL)


def test_zero_length_moves_are_covered():
    points = circle(turns=0.5)
    points = np.insert(points, [5, 5, 40, len(points)], points[[5, 5, 40, -1]], axis=0)
    pieces = fit.fit_run(points, TOL)
    assert pieces[-1].last == len(points) - 1
    check_pieces(pieces, points, TOL)


def test_bad_runs_are_refused_in_words():
    with pytest.raises(ValueError, match="no length"):
        fit.fit_run(np.zeros((5, 2)), TOL)
    with pytest.raises(ValueError, match="start_tangent"):
        fit.fit_run(circle(), TOL, start_tangent=(0, 0))
    with pytest.raises(ValueError, match="tolerance"):
        fit.fit_run(circle(), 0.0)
    with pytest.raises(ValueError, match="shape"):
        fit.fit_run(np.zeros(4), TOL)


def test_curvature_follows_the_circle_not_the_rounding():
    """A circle of radius 5 mm in 0.2 mm chords rounded to 1e-4 mm: curvature within 3 % of 1/5 throughout,
    with few knots (spans of millimetres, not of chords)."""
    for decimals in (4, 3):
        points = rounded(circle(turns=2), decimals)
        (piece,) = fit.fit_run(points, TOL, (0, 1), (0, 1))  # the circle's own tangent at both ends
        kappa = sampled_curvature(piece)
        assert np.abs(kappa * 5 - 1).max() <= 0.03, (decimals, kappa.min() * 5, kappa.max() * 5)
        assert len(piece.knots) - 7 <= 2 * math.pi * 5 * 2 / 1.0  # spans of a millimetre or more
    # free ends too, away from the end spans
    (piece,) = fit.fit_run(rounded(circle(turns=2), 4), TOL)
    kappa = sampled_curvature(piece)
    assert np.abs(kappa[200:-200] * 5 - 1).max() <= 0.03


@settings(max_examples=25)
@given(seed=st.integers(0, 10 ** 6), chord=st.sampled_from([0.001, 0.004, 0.02, 0.2]),
       noise=st.sampled_from([0.0, 1e-4, 5e-4, 2e-3]), tol=st.sampled_from([0.002, 0.005, 0.02]),
       dim=st.sampled_from([2, 3]), tangents=st.booleans())
def test_random_smooth_polylines(seed, chord, noise, tol, dim, tangents):
    """Random smooth paths (sums of sines) sampled by chords, with noise: within tolerance both ways."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, min(400, 10 / chord) + 1))  # at most 10 mm: the brute force stays quick
    s = np.arange(n) * chord
    pts = np.zeros((n, dim))
    pts[:, 0] = s
    for d in range(1, dim):
        for _ in range(3):
            w = rng.uniform(0.1, 3.0) / max(s[-1], chord) * 2 * math.pi
            pts[:, d] += rng.uniform(-0.3, 0.3) * s[-1] / 3 * np.sin(w * s + rng.uniform(0, 6))
    pts += rng.uniform(-noise, noise, pts.shape)
    t0 = t1 = None
    if tangents:
        t0 = _unit(pts[1] - pts[0] + rng.normal(0, 0.05, dim))
        t1 = _unit(pts[-1] - pts[-2] + rng.normal(0, 0.05, dim))
    pieces = fit.fit_run(pts, tol, t0, t1)
    check_pieces(pieces, pts, tol, t0, t1)


@settings(max_examples=30)
@given(seed=st.integers(0, 10 ** 6), chord=st.sampled_from([0.001, 0.004, 0.05, 0.2]),
       decimals=st.sampled_from([None, 4, 3]), dim=st.sampled_from([2, 3]))
def test_random_polylines_with_corners_and_reversals(seed, chord, decimals, dim):
    """Smooth stretches joined by real corners, near-reversals and reversals, rounded: split_runs covers the
    polyline with runs and lines, and every run's fit is within tolerance both ways."""
    rng = np.random.default_rng(seed)
    pts = [np.zeros(dim)]
    heading = _unit(rng.normal(size=dim))
    for _ in range(int(rng.integers(1, 5))):
        turn = rng.choice([0.0, 0.3, 1.5, 3.0, math.pi])  # none, corners, a near-reversal, a reversal
        axis = _unit(rng.normal(size=dim))
        heading = _unit(heading * math.cos(turn) + _unit(axis - axis @ heading * heading) * math.sin(turn))
        bend = _unit(rng.normal(size=dim))
        bend = _unit(bend - bend @ heading * heading)
        for _ in range(int(rng.integers(2, min(120, 3 / chord)))):
            heading = _unit(heading + bend * chord * rng.uniform(0, 1.0))  # curvature up to 1/mm
            pts.append(pts[-1] + heading * chord)
    points = np.array(pts)
    if decimals is not None:
        points = np.round(points, decimals)
    runs = fit.split_runs(points, TOL)
    covered = np.zeros(len(points) - 1, dtype=bool)
    previous = -1
    for a, b in runs:
        assert b - a + 1 >= 4 and a >= previous
        covered[a:b] = True
        previous = b
        check_pieces(fit.fit_run(points[a:b + 1], TOL), points[a:b + 1], TOL)
    if chord <= 0.004 and decimals is None and len(points) > 40:
        assert covered.mean() > 0.5  # short moves of gentle curves are mostly smoothed, not left as lines


# ---------------------------------------------------------------------------------------------- split_runs


def test_split_runs_cuts_corners_and_keeps_long_moves_as_lines():
    a = circle(turns=0.25)  # quarter circle from (5, 0) to (0, 5): 39 chords
    line = np.array([[0.0, 5.0], [-3.0, 5.0]])  # 3 mm line leaving it at right angles to the radius...
    b = np.c_[np.linspace(-3.0, -3.0, 30), np.linspace(5.0, 2.1, 30)][1:]  # ...then a corner and short moves
    points = np.concatenate((a, line[1:], b))
    runs = fit.split_runs(points, TOL)
    assert runs[0] == (0, len(a) - 1)
    assert runs[1] == (len(a), len(points) - 1)


def test_split_runs_cuts_at_the_corner_vertex():
    a = np.c_[np.linspace(0, 2, 11), np.zeros(11)]
    b = np.c_[2 + np.linspace(0, 2, 11) * math.cos(1.0), np.linspace(0, 2, 11) * math.sin(1.0)][1:]
    points = np.concatenate((a, b))
    assert fit.split_runs(points, TOL) == [(0, 10), (10, 20)]
    # 10 degrees between 0.2 mm moves is no corner by default (a smooth fit rounds it), one by a smaller angle
    b = np.c_[2 + np.linspace(0, 2, 11) * math.cos(0.175), np.linspace(0, 2, 11) * math.sin(0.175)][1:]
    points = np.concatenate((a, b))
    assert fit.split_runs(points, TOL) == [(0, 20)]
    assert fit.split_runs(points, TOL, corner_angle=math.radians(5)) == [(0, 10), (10, 20)]
    # 20 degrees is a corner: the smooth curve could not turn by it within a move and the tolerance
    b = np.c_[2 + np.linspace(0, 2, 11) * math.cos(0.35), np.linspace(0, 2, 11) * math.sin(0.35)][1:]
    assert fit.split_runs(np.concatenate((a, b)), TOL) == [(0, 10), (10, 20)]


def test_split_runs_ignores_rounding_on_micro_segments_but_not_a_real_corner():
    arc = rounded(circle(radius=1.0, chord=0.001, turns=0.1), 3)  # 1 um chords rounded to 1 um
    assert fit.split_runs(arc, TOL) == [(0, len(arc) - 1)]
    leg = arc[-1] + np.outer(np.arange(1, 300) * 0.001, [1.0, 0.0])
    points = rounded(np.concatenate((arc, leg)), 3)
    runs = fit.split_runs(points, TOL)
    assert len(runs) == 2 and abs(runs[0][1] - (len(arc) - 1)) <= 2 and runs[1][0] == runs[0][1]


def test_split_runs_reversal_and_raster():
    """A retract then a plunge (a reversal) is cut; the raster's 0.5 mm step between rows stays a line."""
    rows = [raster_row(50, y=0.0), raster_row(50, y=0.5)[::-1]]
    points = np.concatenate(rows)
    runs = fit.split_runs(points, TOL)
    assert runs == [(0, 50), (51, 101)]
    down = np.c_[np.zeros(10), np.zeros(10), np.linspace(5, 0, 10)]
    up = down[::-1][1:]
    assert fit.split_runs(np.concatenate((down, up)), TOL) == [(0, 9), (9, 18)]


def test_split_runs_short_stretches_stay_lines():
    points = np.array([[0, 0], [1, 0], [1, 1], [2, 1.0]])
    assert fit.split_runs(points, TOL) == []
    assert fit.split_runs(points[:1], TOL) == []


# ---------------------------------------------------------------------------------------------- span_bounds


def _reference_length(spl, a, b):
    d1 = spl.derivative(1)
    return quad(lambda x: np.linalg.norm(d1(x)), a, b, epsabs=0, epsrel=2e-14, limit=200)[0]


@pytest.mark.parametrize("name", ["circle-1e-4", "spiral-1e-3", "raster-row", "micro-1um-1e-3", "sine-noise"])
def test_span_bounds_hold_and_are_tight(name):
    points = CASES[name]
    for piece in fit.fit_run(points, TOL)[:3]:
        b = fit.span_bounds(piece)
        spl = piece.spline()
        d1, d2 = spl.derivative(1), spl.derivative(2)
        assert np.all(np.diff(b.start) > 0) and b.start[0] == 0 and b.start[-1] == piece.knots[-1]
        np.testing.assert_allclose(b.cumulative, np.r_[0, np.cumsum(b.length)], rtol=1e-15)
        for k in range(len(b.length)):
            ref = _reference_length(spl, b.start[k], b.start[k + 1])
            assert abs(b.length[k] - ref) <= 1e-12 * ref
            u = np.linspace(b.start[k], b.start[k + 1], 801)
            v, a = d1(u), d2(u)
            sp = np.linalg.norm(v, axis=1)
            kvec = (a * sp[:, None] ** 2 - v * (v * a).sum(axis=1)[:, None]) / sp[:, None] ** 4
            kap = np.linalg.norm(kvec, axis=1)
            tan = np.abs(v / sp[:, None])
            assert kap.max() <= b.curvature[k] * (1 + 1e-12)
            assert np.all(np.abs(kvec).max(axis=0) <= b.curvature_vector[k] * (1 + 1e-12) + 1e-15)
            assert np.all(tan.max(axis=0) <= b.tangent[k] * (1 + 1e-12))
            # tight: a few per cent above the sampled maximum where the curve bends at all
            if kap.max() > 1e-3:
                assert b.curvature[k] <= 1.02 * kap.max()


# ---------------------------------------------------------------------------------------------- points_at_length


def test_points_at_length_against_quadrature_and_root_finding():
    rng = np.random.default_rng(5)
    for name in ("circle-1e-4", "micro-1um-1e-3", "raster-row"):
        piece = fit.fit_run(CASES[name], TOL)[0]
        b = fit.span_bounds(piece)
        spl = piece.spline()
        total = b.cumulative[-1]
        s = np.sort(np.concatenate((rng.uniform(0, total, 40), b.cumulative, [0.0, total, -1.0, total + 1])))
        out = np.empty((len(s), piece.ctrl.shape[1]))
        fit.points_at_length(piece.knots, piece.ctrl, b.cumulative, s, out)
        out_shuffled = np.empty_like(out)
        order = rng.permutation(len(s))
        fit.points_at_length(piece.knots, piece.ctrl, b.cumulative, s[order], out_shuffled)
        np.testing.assert_allclose(out_shuffled, out[order], rtol=0, atol=1e-9)
        for si, p in zip(s, out):
            if si <= 0:
                ref = spl(0.0)
            elif si >= total:
                ref = spl(piece.knots[-1])
            else:
                k = int(np.searchsorted(b.cumulative, si, side="right") - 1)
                a = b.start[k]
                u = brentq(lambda x: b.cumulative[k] + _reference_length(spl, a, x) - si, a, b.start[k + 1],
                           xtol=1e-15, rtol=1e-15)
                ref = spl(u)
            assert np.linalg.norm(p - ref) <= 1e-9, (name, si, np.linalg.norm(p - ref))


def test_points_at_length_dense_ticks_are_evenly_spaced():
    piece = fit.fit_run(CASES["spiral"], TOL)[0]
    b = fit.span_bounds(piece)
    s = np.linspace(0, b.cumulative[-1], 20001)
    out = np.empty((len(s), 2))
    fit.points_at_length(piece.knots, piece.ctrl, b.cumulative, s, out)
    chords = np.linalg.norm(np.diff(out, axis=0), axis=1)
    step = s[1] - s[0]
    # a chord is shorter than its arc by at most step^3 kappa^2 / 24; both within 1e-9 mm of their lengths
    assert np.all(chords <= step + 2e-9)
    assert np.all(chords >= step - step ** 3 * 0.25 / 24 - 2e-9)


# ---------------------------------------------------------------------------------------------- speed


def test_speed_report(capsys):
    """Fitting + verification rate on the issue's spiral of 0.2 mm chords (printed, never asserted)."""
    points = rounded(spiral(20000), 4)
    fit.fit_run(points[:200], TOL)  # warm
    t = time.perf_counter()
    pieces = fit.fit_run(points, TOL)
    dt = time.perf_counter() - t
    t = time.perf_counter()
    for p in pieces:
        fit.span_bounds(p)
    db = time.perf_counter() - t
    with capsys.disabled():
        print(f"\nfit_run: {len(points)} vertices in {dt:.3f} s = {len(points) / dt:,.0f} vertices/s, "
              f"{len(pieces)} pieces, {sum(len(p.knots) - 7 for p in pieces)} spans; "
              f"span_bounds {db:.3f} s")


def test_docstring_examples_run():
    import doctest

    globs = {"np": np, "fit_run": fit.fit_run, "span_bounds": fit.span_bounds}
    finder, runner = doctest.DocTestFinder(), doctest.DocTestRunner()
    for test in finder.find(fit.fit_run, "fit_run", globs=globs):
        runner.run(test)
    assert runner.failures == 0 and runner.tries > 0
