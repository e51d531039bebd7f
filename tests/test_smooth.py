"""Smoothing in the look-ahead (motion.smooth): runs of short moves refitted as cubic B-splines, their rows
exact Béziers of the fitted pieces, within the tolerance both ways, their caps holding the axes' limits, the
ticks' (n, u) naming programmed points within the tolerance, the same plan whatever the batches.

test_lookahead.py's two-sided tolerance and finite-difference tests run with smoothing on (the default):
here, what is particular to it."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad
from test_cli_contract import one_line_error, run_main
from test_lookahead import (
    LIMITS,
    TIGHT,
    TOL,
    axes_of,
    check_limits,
    distance_to_polyline,
    planned,
    polyline,
    program,
    random_program,
)

from nurbsinterp.cli.common import load
from nurbsinterp.motion import fit, smooth
from nurbsinterp.motion import segments as seg
from nurbsinterp.motion.pipeline import LookAhead

CIRCLE = str(Path(__file__).resolve().parents[1] / "curves" / "circle.yaml")  # one curve: look-ahead when asked

def circle_program(radius=5.0, chord=1e-3, turns=0.25, digits=4, feed=3000):
    """A quarter circle in chords of *chord* mm, end points rounded to *digits* decimals (CAM's micro-segments)."""
    n = int(round(turns * 2 * math.pi * radius / chord))
    a = np.linspace(0.0, turns * 2 * math.pi, n + 1)
    lines = ["G21 G90 G64", f"G0 X{radius:.{digits}f} Y0", f"F{feed}"]
    lines += [f"G1 X{radius * math.cos(t):.{digits}f} Y{radius * math.sin(t):.{digits}f}" for t in a[1:]]
    return "\n".join(lines + ["M2"]) + "\n"


def row_derivatives(row, w):
    """B'(w), B''(w) of a curve row's cubic Bézier (w: (m,)): the geometry the commands follow, exactly as stored
    (a row of 1 um carries its control points' rounding into its curvature: some 1e-8 relative, so that the
    rows, not the fitted spline, are what the bounds bound)."""
    B = [row[c:c + 3] for c in (seg.B0, seg.B1, seg.B2, seg.B3)]
    a = (1 - w)[:, None]
    w = w[:, None]
    d1 = 3 * (a * a * (B[1] - B[0]) + 2 * a * w * (B[2] - B[1]) + w * w * (B[3] - B[2]))
    d2 = 6 * (a * (B[2] - 2 * B[1] + B[0]) + w * (B[3] - 2 * B[2] + B[1]))
    return d1, d2


def test_micro_segments_run_at_the_curvature_not_the_segments(tmp_path):
    """A 5 mm circle in 1 um chords rounded to 0.1 um: blended, each corner's arc is capped by the chords' length
    (a blend takes at most half a line); smoothed, the feed is the circle's own cap, sqrt((1 − β) a R / |n_i|) per
    axis (the centripetal share of the axis' acceleration, β = 0.4), within the curve's 2.5 % curvature ripple."""
    path = program(tmp_path, circle_program(feed=6000))
    smoothed, rows = planned(path)
    blended, _ = planned(path, smooth=False)
    v = rows[rows[:, smoothed.columns.index("rapid")] == 0, smoothed.columns.index("v")]
    # mid-quarter both axes' normal components are 1/sqrt(2): V² / R · 0.707 <= 0.6 · 1000 (F, 100 mm/s, is above)
    cap = math.sqrt(0.6 * 1000.0 * 5.0 / math.sqrt(0.5))
    assert smoothed.smoothing.moves > 7000 and smoothed.smoothing.curves >= 1
    assert v.max() <= cap * 1.03
    assert v.max() >= cap * 0.95, v.max()
    assert smoothed.facts.motion_time < 0.2 * blended.facts.motion_time, (smoothed.facts.motion_time,
                                                                          blended.facts.motion_time)
    vertices = polyline(path)
    x = np.zeros((rows.shape[0], 3))
    x[:, :smoothed.dim] = axes_of(smoothed, rows)
    moving = x[rows[:, smoothed.columns.index("rapid")] == 0]
    assert distance_to_polyline(moving, vertices).max() <= TOL + TIGHT
    # each vertex of the cut within the tolerance of the commands' polyline (the rapid's end onwards)
    assert distance_to_polyline(vertices[1:], x).max() <= TOL + TIGHT
    check_limits(smoothed, rows)


def test_rows_are_the_fitted_pieces(tmp_path):
    """Each curve row is its piece between two parameters, exactly: its Bézier at w equals scipy's BSpline of the
    piece at lo + w (hi − lo) to rounding; its LEN the piece's arc length there (scipy's quad); and the rows of a
    piece join end to end bit for bit."""
    rng = np.random.default_rng(3)
    th = np.cumsum(rng.uniform(0.01, 0.05, 300))
    verts = np.round(np.c_[8 * np.cos(th), 5 * np.sin(th), 0.3 * th], 4)
    facts = smooth.SmoothFacts()
    lim = LookAhead(load(program(tmp_path, circle_program()), **LIMITS), TOL).limits.vector()
    smoother = smooth.Smoother(lim, True, facts)
    (piece,) = fit.fit_run(verts, TOL, verts[1] - verts[0], verts[-1] - verts[-2])
    rows = smoother._rows(piece, verts, np.arange(len(verts) - 1, dtype=float), 50.0, TOL)
    spl = piece.spline()
    chords = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(verts, axis=0), axis=1))))
    out = np.empty(3)
    for r, row in enumerate(rows):
        block = int(row[seg.BLOCK])
        lo = chords[block] + row[seg.U0] * (chords[block + 1] - chords[block])
        hi = lo + row[seg.DU] * (chords[block + 1] - chords[block])
        for w in (0.0, 0.25, 0.5, 0.9, 1.0):
            a = 1 - w
            bez = (a ** 3 * row[seg.B0:seg.B0 + 3] + 3 * a * a * w * row[seg.B1:seg.B1 + 3]
                   + 3 * a * w * w * row[seg.B2:seg.B2 + 3] + w ** 3 * row[seg.B3:seg.B3 + 3])
            assert np.abs(bez - spl(lo + w * (hi - lo))).max() <= 1e-12
        d1 = spl.derivative()
        length, _ = quad(lambda u: np.linalg.norm(d1(u)), lo, hi, epsabs=1e-15, epsrel=1e-13)
        assert row[seg.LEN] == pytest.approx(length, rel=1e-11, abs=1e-15)
        if r + 1 < len(rows):
            assert np.array_equal(row[seg.B3:seg.B3 + 3], rows[r + 1, seg.B0:seg.B0 + 3])
        # the arc length → w → point chain of the ticks, at a few lengths
        for s in (0.0, 0.3 * row[seg.LEN], row[seg.LEN]):
            w = seg.segment_point(row, s, out)
            assert seg.bezier_length(row, w) == pytest.approx(s, rel=1e-12, abs=1e-15)
    assert np.array_equal(rows[0, seg.B0:seg.B0 + 3], verts[0])
    assert np.array_equal(rows[-1, seg.B3:seg.B3 + 3], verts[-1])
    assert np.all(rows[:, seg.VCAP] > 0) and np.all(rows[:, seg.ACAP] > 0)


@settings(max_examples=25, deadline=None)
@given(radius=st.floats(0.3, 50.0), chord=st.sampled_from([1e-3, 4e-3, 0.05, 0.2]), seed=st.integers(0, 10 ** 6))
def test_row_caps_bound_the_axes(radius, chord, seed):
    """Per axis, |τ_i| V + |κ n_i| V² at the row's cap, sampled densely along each row, stays within the axis'
    velocity and acceleration: the bounds are bounds (brute force over each row's own curve)."""
    rng = np.random.default_rng(seed)
    n = max(8, min(400, int(1.5 * radius / chord)))
    th = np.arange(n + 1) * chord / radius + rng.uniform(0, 6)
    verts = np.round(np.c_[radius * np.cos(th), radius * np.sin(th), 0.1 * radius * np.sin(3 * th)], 4)
    try:
        pieces = fit.fit_run(verts, TOL, verts[1] - verts[0], verts[-1] - verts[-2])
    except ValueError:
        return
    vel, acc = np.array([100.0, 80.0, 60.0]), np.array([1000.0, 800.0, 500.0])
    lim = np.zeros(seg.NLIM)
    lim[seg.L_PERIOD], lim[seg.L_BETA], lim[seg.L_ACCEL], lim[seg.L_NORMAL], lim[seg.L_CHORD] = 1e-3, 0.4, np.inf, \
        np.inf, np.inf
    lim[seg.L_VEL:seg.L_VEL + 3], lim[seg.L_ACC:seg.L_ACC + 3] = vel, acc
    smoother = smooth.Smoother(lim, True, smooth.SmoothFacts())
    for piece in pieces:
        rows = smoother._rows(piece, verts[piece.first:piece.last + 1], np.arange(piece.last - piece.first,
                                                                                  dtype=float), 200.0, TOL)
        for row in rows:
            D1, D2 = row_derivatives(row, np.linspace(0.0, 1.0, 41))
            sp = np.linalg.norm(D1, axis=1)
            tau = D1 / sp[:, None]
            kvec = (D2 - tau * (tau * D2).sum(axis=1)[:, None]) / sp[:, None] ** 2  # dT/ds
            V, A = row[seg.VCAP], row[seg.ACAP]
            assert np.all(np.abs(tau).max(axis=0) * V <= vel * (1 + 1e-9))
            assert np.all(np.abs(tau) * A + np.abs(kvec) * V * V <= acc * (1 + 1e-9) + 1e-9)


def test_each_tick_names_a_programmed_point_within_the_tolerance(tmp_path):
    """On a curve row, the tick's (n, u) is the chord-length point the fit was verified against: the programmed
    point of block n at u lies within the fit's deviation of the command (sup |C(u) − P(u)| is what the fit
    bounds), so within the tolerance."""
    path = program(tmp_path, random_program(np.random.default_rng(4), "noisy", n=300))
    run, rows = planned(path)
    assert run.smoothing.moves > 100
    vertices = polyline(path)
    n = rows[:, run.columns.index("n")].astype(int)
    u = rows[:, run.columns.index("u")]
    assert np.all((u >= -1e-12) & (u <= 1 + 1e-12))
    foot = vertices[n] + u[:, None] * (vertices[n + 1] - vertices[n])
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    assert np.sqrt(((x - foot) ** 2).sum(axis=1)).max() <= TOL + TIGHT


@pytest.mark.parametrize("kind", ["noisy", "micro", "mixed", "corners"])
def test_the_same_plan_whatever_the_batches(tmp_path, monkeypatch, kind):
    """Smoothing decides WINDOW blocks at a time, whatever the reader's batches: with small windows (64 blocks,
    runs cut at 32) so that a program of 400 blocks spans many, batches of 3, 17 and all at once give the same
    stream to the bit."""
    monkeypatch.setattr(smooth, "WINDOW", 64)
    monkeypatch.setattr(smooth, "MAX_HOLD", 64)
    monkeypatch.setattr(smooth, "CUT", 32)
    path = program(tmp_path, random_program(np.random.default_rng(21), kind, n=400))
    run, whole = planned(path, batch=100_000)
    for batch in (3, 17):
        _, part = planned(path, batch=batch)
        assert part.shape == whole.shape
        assert np.array_equal(part, whole)
    if kind == "noisy":  # (1 um moves: a window of 64 is within the 0.12 mm margin, mostly left to blends)
        assert run.smoothing.curves > 3


def test_a_long_run_is_cut_and_goes_on_along_its_tangent(tmp_path, monkeypatch):
    """A run longer than the window (a spiral of 600 moves, windows of 64) is fitted in pieces joined along the
    tangent its neighbourhood shows: every joint between curves passed without slowing (no unblended joint's
    cap binds), within the tolerance both ways."""
    monkeypatch.setattr(smooth, "WINDOW", 64)
    monkeypatch.setattr(smooth, "MAX_HOLD", 64)
    monkeypatch.setattr(smooth, "CUT", 32)
    th = np.linspace(0.0, 12.0, 601)
    r = 5 + 0.3 * th
    lines = ["G21 G90 G64 F3000", f"G0 X{r[0]:.4f} Y0"]
    lines += [f"G1 X{a * math.cos(t):.4f} Y{a * math.sin(t):.4f}" for a, t in zip(r[1:], th[1:])]
    path = program(tmp_path, "\n".join(lines + ["M2"]) + "\n")
    run, rows = planned(path)
    assert run.smoothing.curves > 10
    assert run.facts.stops == 0
    vertices = polyline(path)
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    assert distance_to_polyline(x[rows[:, run.columns.index("rapid")] == 0], vertices).max() <= TOL + TIGHT
    assert distance_to_polyline(vertices[1:], x).max() <= TOL + TIGHT
    check_limits(run, rows)


def test_summary_and_options(tmp_path, capsys):
    path = program(tmp_path, circle_program(chord=0.05))
    out = tmp_path / "run.bin"
    code, _, err = run_main(capsys, "plan", path, "--tolerance", "5um", "--format", "bin", "-o", out,
                            "--axis-max-accel", "x=1000,y=1000")
    assert code == 0, err
    assert "moves in 1 runs refitted as" in err and "verified bound" in err
    code, _, err = run_main(capsys, "plan", path, "--tolerance", "5um", "--no-smooth", "--format", "bin", "-o", out,
                            "--axis-max-accel", "x=1000,y=1000")
    assert code == 0, err
    assert "smoothing        off (--no-smooth)" in err
    # a program is planned with look-ahead whatever it states (on the exact path nothing is refitted); a YAML path
    # only with --tolerance
    assert run_main(capsys, "plan", path, "--no-smooth", "-q", "-o", tmp_path / "exact.csv")[0] == 0
    one_line_error(*run_main(capsys, "plan", CIRCLE, "--no-smooth"), "--no-smooth", "--tolerance")
    one_line_error(*run_main(capsys, "simulate", "-", "--job", path, "--tolerance", "5um", "--smooth"), "--smooth",
                   "--plan")


def test_info_reports_the_look_ahead(tmp_path, capsys):
    """`info PROGRAM --tolerance D` runs the plan `plan --tolerance D` writes, to its last tick, and reports its
    facts: the same ticks, motion time, smoothing and extremes as the library's run of it; a table, or --json."""
    import json

    path = program(tmp_path, random_program(np.random.default_rng(8), "noisy", n=200))
    code, out, err = run_main(capsys, "info", path, "--tolerance", "5um", "--json", "--profile-type", "adaptive",
                              "--axis-max-velocity", "x=100,y=100,z=100", "--axis-max-accel", "x=1000,y=1000,z=1000",
                              "--rapid-feedrate", "6000mm/min")
    assert code == 0, err
    facts = json.loads(out)
    run, rows = planned(path)
    assert facts["ticks"] == rows.shape[0] == run.facts.ticks
    assert facts["motion_time"] == run.facts.motion_time
    assert facts["smoothing"]["moves"] == run.smoothing.moves > 0
    assert facts["smoothing"]["worst_deviation"] == run.smoothing.worst <= 0.9 * TOL
    assert facts["commands"]["max_accel"]["x"] == run.facts.axis_extremes[1, 0]
    assert facts["limits"]["axis_max_accel"] == {"x": 1000.0, "y": 1000.0, "z": 1000.0}
    code, out, err = run_main(capsys, "info", path, "--tolerance", "5um", "--no-smooth")
    assert code == 0, err
    assert out.startswith(f"{path}: look-ahead plan, 200 blocks") and "smoothing        off" in out and err == ""
    one_line_error(*run_main(capsys, "info", CIRCLE, "--smooth"), "--smooth", "--tolerance")
    one_line_error(*run_main(capsys, "info", path, "--tolerance", "5um", "--plot", str(tmp_path / "p.png")),
                   "--plot", "--tolerance")
    one_line_error(*run_main(capsys, "info", path, "--tolerance", "-1"), "--tolerance")


def test_row_bounds_agree_with_the_pieces_bounds(tmp_path):
    """segments.curve_bounds (per Bézier row, compiled) against fit.interval_bounds (per parameter interval of the
    piece, numpy): both upper bounds of the same maxima, within their 1 % slack of each other, and the rows' above
    their values sampled densely."""
    th = np.linspace(0.0, 2.5, 200)
    verts = np.round(np.c_[6 * np.cos(th), 4 * np.sin(th), 0.5 * np.sin(2 * th)], 4)
    (piece,) = fit.fit_run(verts, TOL, verts[1] - verts[0], verts[-1] - verts[-2])
    lim = LookAhead(load(program(tmp_path, circle_program()), **LIMITS), TOL).limits.vector()
    rows = smooth.Smoother(lim, True, smooth.SmoothFacts())._rows(piece, verts, np.arange(199, dtype=float), 50.0,
                                                                   TOL)
    chords = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(verts, axis=0), axis=1))))
    b = rows[:, seg.BLOCK].astype(int)
    lo = chords[b] + rows[:, seg.U0] * (chords[b + 1] - chords[b])
    hi = lo + rows[:, seg.DU] * (chords[b + 1] - chords[b])
    kappa, tang, kvec = fit.interval_bounds(piece, lo, hi, subdivisions=2)
    mine = np.empty((rows.shape[0], 7))
    seg.curve_bounds(rows, 0.01, mine)
    for ours, theirs in ((mine[:, 0], kappa), (mine[:, 1:4], tang), (mine[:, 4:7], kvec)):
        assert np.all(np.abs(ours - theirs) <= 0.03 * np.maximum(ours, theirs) + 2e-9)
    for r in range(rows.shape[0]):
        D1, D2 = row_derivatives(rows[r], np.linspace(0.0, 1.0, 101))
        sp = np.linalg.norm(D1, axis=1)
        k = np.linalg.norm(np.cross(D1, D2), axis=1) / sp ** 3
        tau = D1 / sp[:, None]
        kv = (D2 - tau * (tau * D2).sum(axis=1)[:, None]) / sp[:, None] ** 2
        assert k.max() <= mine[r, 0] * (1 + 1e-12)
        assert np.all(np.abs(tau).max(axis=0) <= mine[r, 1:4] * (1 + 1e-12))
        assert np.all(np.abs(kv).max(axis=0) <= mine[r, 4:7] * (1 + 1e-12) + 1e-12)


def test_a_knot_beside_a_move_end_makes_no_sliver_row(tmp_path):
    """A knot within rounding of a move's end would cut a row of 1e-14 mm (its control points equal to the last
    digit, its bounds a cusp's): the move's end gives way to the knot, the rows keep to one knot span each, and
    their caps stay those of the curve (MB-3.1_test.nc had such a row: a ZeroDivisionError once)."""
    from scipy.interpolate import insert

    th = np.linspace(0.0, 1.5, 60)
    verts = np.round(np.c_[5 * np.cos(th), 5 * np.sin(th), 0 * th], 4)
    (piece,) = fit.fit_run(verts, TOL, verts[1] - verts[0], verts[-1] - verts[-2])
    chords = np.concatenate(([0.0], np.cumsum(np.linalg.norm(np.diff(verts, axis=0), axis=1))))
    spl = piece.spline()
    for at in (chords[20] + 1e-14, chords[33] - 1e-14):
        spl = insert(at, spl)
    sliver = fit.Piece(spl.t, spl.c, piece.first, piece.last, piece.deviation)
    lim = LookAhead(load(program(tmp_path, circle_program()), **LIMITS), TOL).limits.vector()
    rows = smooth.Smoother(lim, True, smooth.SmoothFacts())._rows(sliver, verts, np.arange(59, dtype=float), 50.0,
                                                                   TOL)
    plain = smooth.Smoother(lim, True, smooth.SmoothFacts())._rows(piece, verts, np.arange(59, dtype=float), 50.0,
                                                                    TOL)
    assert rows[:, seg.LEN].min() > 1e-3
    assert np.all(rows[:, seg.VCAP] > 0.5 * plain[:, seg.VCAP].min())
    assert rows[:, seg.LEN].sum() == pytest.approx(plain[:, seg.LEN].sum(), rel=1e-12)
    u = rows[:, seg.U0]
    assert np.all((u > -1e-9) & (u + rows[:, seg.DU] < 1 + 1e-9))
