"""The look-ahead with a jerk limit (motion.jerk, lookahead.JerkWindow): per-axis jerk held by the stream itself.

References: the axes' third differences of the emitted commands (a weighted mean of the third derivative over
three ticks, plus the jumps the joint caps hold, so the limit binds them exactly, not only as T -> 0), the
curvature vector and its derivative of each curve row sampled densely from its own Bézier (derivatives in
closed form, numpy), and the arc's closed forms.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from budgets import budgets
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
    position_rounding,
    program,
    random_program,
)

from nurbsinterp.motion import jerk as jk
from nurbsinterp.motion import lookahead as la
from nurbsinterp.motion import segments as seg

ROOT = __import__("pathlib").Path(__file__).resolve().parents[1]
JERK = 20000.0  # mm/s³ per axis
JERK_OPTIONS = dict(axis_max_jerk="x=20000,y=20000,z=20000")


def check_jerk(run, rows, jerk=JERK):
    """Per-axis |Δ³x/T³| <= j_i over every tick, up to the positions' rounding (8ε/T³).  Returns the largest."""
    x = axes_of(run, rows)
    T = run.period
    eps = position_rounding(run, rows)
    j = np.abs(np.diff(x, 3, axis=0)) / T ** 3
    j_max = j.max(axis=0) if j.shape[0] else np.zeros(run.dim)
    assert np.all(j_max <= jerk * (1 + 1e-12) + 8 * eps / T ** 3), (j_max, int(j.max(axis=1).argmax()))
    return j_max


def bezier_derivatives(row, w):
    P = np.array([row[seg.B0:seg.B0 + 3], row[seg.B1:seg.B1 + 3], row[seg.B2:seg.B2 + 3], row[seg.B3:seg.B3 + 3]])
    a = 1.0 - w
    d1 = 3 * (a * a)[:, None] * (P[1] - P[0]) + 6 * (a * w)[:, None] * (P[2] - P[1]) + 3 * (w * w)[:, None] * (P[3] - P[2])
    d2 = 6 * (a[:, None] * (P[2] - 2 * P[1] + P[0]) + w[:, None] * (P[3] - 2 * P[2] + P[1]))
    d3 = np.broadcast_to(6 * (P[3] - 3 * P[2] + 3 * P[1] - P[0]), d1.shape)
    return d1, d2, d3


def sampled_xss_xsss(row, n=4001):
    """max |x_ss,i| and |x_sss,i| over the row at n parameters: the chain rule by arc length, term by term."""
    d1, d2, d3 = bezier_derivatives(row, np.linspace(0.0, 1.0, n))
    sig = np.linalg.norm(d1, axis=1)[:, None]
    sp = (d1 * d2).sum(axis=1)[:, None] / sig
    spp = ((d2 * d2).sum(axis=1)[:, None] + (d1 * d3).sum(axis=1)[:, None] - sp ** 2) / sig
    xss = d2 / sig ** 2 - d1 * sp / sig ** 3
    xsss = d3 / sig ** 3 - 3 * d2 * sp / sig ** 4 - d1 * spp / sig ** 4 + 3 * d1 * sp ** 2 / sig ** 5
    return np.abs(xss).max(axis=0), np.abs(xsss).max(axis=0)


def curve_row(points):
    row = np.zeros(seg.NCOL)
    row[seg.KIND] = seg.CURVE
    for k, c in enumerate((seg.B0, seg.B1, seg.B2, seg.B3)):
        row[c:c + 3] = points[k]
    return row


# --------------------------------------------------------------------------- the bounds of a row


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12), st.floats(0.01, 20.0))
def test_curve_row_bounds_above_samples_and_tight(coords, scale):
    """_row_bounds of a cubic Bézier: never below its dense samples, and within 10 % of them (or of a hair)."""
    P = np.array(coords).reshape(4, 3) * scale
    # control points in order along a direction, so that the row has no cusp (the smoother's rows never do)
    P += np.outer(np.arange(4), [scale, 0.3 * scale, 0.0])
    row = curve_row(P)
    x2 = np.empty(3)
    x3 = np.empty(3)
    jk._row_bounds(row, x2, x3)
    s2, s3 = sampled_xss_xsss(row)
    if not np.all(np.isfinite(x2)):
        return  # a part without a positive lower bound of |B'|: the row bounds nothing (inf), which is safe
    assert np.all(x2 >= s2 * (1 - 1e-9) - 1e-12) and np.all(x3 >= s3 * (1 - 1e-9) - 1e-12)
    # tightness where the curve is tame (|B'| varying by under 2x along it), as the smoother's rows are
    d1 = bezier_derivatives(row, np.linspace(0, 1, 201))[0]
    speed = np.linalg.norm(d1, axis=1)
    if speed.max() <= 2 * speed.min():
        assert np.all(x2 <= 1.1 * s2 + 1e-9 * s2.max() + 1e-300)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=12, max_size=12), st.floats(0.01, 20.0), st.floats(0.0, 0.5))
def test_curve_row_tangent_bounds_above_samples(coords, scale, wobble):
    """_tangent_bounds of a cubic Bézier: at least its dense samples of |τ_i|, at most 1; near its slope on a row
    that runs along x with a gentle rise in z (a refitted raster row), so z's budget does not bind along it."""
    P = np.array(coords).reshape(4, 3) * scale * wobble
    P += np.outer(np.arange(4), [scale, 0.0, 0.25 * scale])
    row = curve_row(P)
    tau = np.empty(3)
    jk._tangent_bounds(row, tau)
    d1 = bezier_derivatives(row, np.linspace(0, 1, 4001))[0]
    sampled = (np.abs(d1) / np.linalg.norm(d1, axis=1)[:, None]).max(axis=0)
    assert np.all(tau >= sampled * (1 - 1e-12)) and np.all(tau <= 1.0)
    if wobble <= 0.01:
        assert tau[2] <= 0.3 and tau[1] <= 0.1


def test_brake_jerk_is_the_smallest_cap_in_reach():
    """_brake_jerk: the smallest jerk cap within the reach of the braking manoeuvre at J, never below J."""
    from nurbsinterp.planner.jerk import _brake_jerk, _min_table, _stop_distance

    nodes = np.array([0.0, 0.6, 1.2, 3.0, 50.0])
    jcaps = np.array([30000.0, 20000.0, 25000.0, 12000.0])
    jtab, lg = _min_table(jcaps)
    J = 10000.0
    reach = _stop_distance(20.0, 0.0, J, 1000.0)  # from 20 mm/s, no acceleration: 0.894 mm
    assert 0.7 < reach < 1.0
    assert _brake_jerk(nodes, jcaps, jtab, lg, J, 0.5, 20.0, 0.0, 1000.0) == 20000.0
    assert _brake_jerk(nodes, jcaps, jtab, lg, J, 0.0, 1.0, 0.0, 1000.0) == 30000.0  # stops inside the first
    assert _brake_jerk(nodes, jcaps, jtab, lg, J, 2.5, 20.0, 0.0, 1000.0) == 12000.0
    assert _brake_jerk(nodes, np.full(4, 5000.0), _min_table(np.full(4, 5000.0))[0], lg, J, 0.5, 20.0, 0.0,
                       1000.0) == J


def test_blend_crawls_under_jerk_only_where_a_stop_is_faster():
    """segments._blend_crawls: the raster's 90° corner within 5 µm (R = 12 µm) is taken at rest under 20 000
    mm/s³ per axis (crossing the blend at its jerk-capped speed takes longer than stopping); a 10° corner of a
    1 mm blend is crossed; without a jerk limit nothing is taken at rest."""
    from nurbsinterp.motion.limits import MotionLimits

    inf = math.inf
    jerked = MotionLimits(1e-3, 50.0, 100.0, inf, inf, inf, inf, (100.0,) * 3, (1000.0,) * 3, 0.005,
                          axis_jerk=(20000.0,) * 3).vector()
    free = MotionLimits(1e-3, 50.0, 100.0, inf, inf, inf, inf, (100.0,) * 3, (1000.0,) * 3, 0.005).vector()
    t1 = np.array([1.0, 0.0, 0.0])
    inward = np.array([0.0, 1.0, 0.0])
    theta = math.pi / 2
    d = 0.005 / math.tan(theta / 4)
    R = d / math.tan(theta / 2)
    vcap = math.sqrt(0.9 * 1000.0 * R)  # the blend's acceleration cap, far above what the jerk leaves
    assert seg._blend_crawls(R, theta, t1, inward, vcap, 33.3, jerked)
    assert not seg._blend_crawls(R, theta, t1, inward, vcap, 33.3, free)
    theta = math.radians(10.0)
    R = 1.0 / math.tan(theta / 2)  # d = 1 mm: crossed at 12 mm/s in 0.16 s, where the rest costs 0.21 s
    assert not seg._blend_crawls(R, theta, t1, inward, 30.0, 30.0, jerked)


def test_arc_row_bounds_closed_form():
    """An arc's |x_ss,i| and |x_sss,i|: κ|n_i| and κ²|τ_i| of a circle, at their largest over its sweep."""
    R, phi = 2.0, 1.0
    row = np.zeros(seg.NCOL)
    row[seg.KIND] = seg.ARC
    row[seg.RADIUS] = R
    row[seg.SWEEP] = phi
    row[seg.D:seg.D + 3] = (1.0, 0.0, 0.0)
    row[seg.E:seg.E + 3] = (0.0, 1.0, 0.0)
    row[seg.NRM:seg.NRM + 3] = (0.0, 0.0, 1.0)
    x2 = np.empty(3)
    x3 = np.empty(3)
    jk._row_bounds(row, x2, x3)
    th = np.linspace(0.0, phi, 100001)
    np.testing.assert_allclose(x2, [np.abs(np.cos(th)).max() / R, np.abs(np.sin(th)).max() / R, 0.0], rtol=1e-9)
    np.testing.assert_allclose(x3, [np.abs(np.sin(th)).max() / R ** 2, np.abs(np.cos(th)).max() / R ** 2, 0.0],
                               rtol=1e-9)


def test_row_ends_of_a_curve():
    """Tangent and curvature vector at a curve row's ends, against the chain rule at w = 0 and 1."""
    row = curve_row(np.array([[0, 0, 0], [1, 0.2, 0], [2, 0.9, 0.1], [3, 1.0, 0.5]], dtype=float))
    ts, ks, te, ke = (np.empty(3) for _ in range(4))
    jk.row_ends(row, ts, ks, te, ke)
    d1, d2, _ = bezier_derivatives(row, np.array([0.0, 1.0]))
    for q, (t, k) in enumerate(((ts, ks), (te, ke))):
        g = d1[q] @ d1[q]
        np.testing.assert_allclose(t, d1[q] / math.sqrt(g), rtol=1e-14)
        np.testing.assert_allclose(k, (d2[q] * g - d1[q] * (d1[q] @ d2[q])) / g ** 2, rtol=1e-12, atol=1e-15)


# --------------------------------------------------------------------------- the stream: jerk held


@pytest.mark.parametrize("kind", ["noisy", "corners", "reversals", "micro", "mixed"])
@pytest.mark.parametrize("smooth", [True, False])
def test_jerk_held_by_third_differences(tmp_path, kind, smooth):
    """Every axis' jerk (third differences of the stream), velocity and acceleration within its limit, every
    command within the tolerance of the programmed path, on random programs with and without smoothing."""
    path = program(tmp_path, random_program(np.random.default_rng(77 + len(kind)), kind))
    run, rows = planned(path, smooth=smooth, **JERK_OPTIONS)
    assert math.isfinite(run.limits.tangential_jerk())
    check_limits(run, rows)
    check_jerk(run, rows)
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    vertices = polyline(path)
    assert distance_to_polyline(x, vertices).max() <= TOL + TIGHT
    assert np.all(np.isfinite(rows))
    assert rows[-1, 4:4 + run.dim] == pytest.approx(vertices[-1][:run.dim], abs=0)


def test_tangential_jerk_alone(tmp_path):
    """--max-jerk alone (the path's jerk): the stream's acceleration column changes by at most J·T a tick, and
    the motion is slower than without it."""
    path = program(tmp_path, "G21 G90 F3000\nG1 X40\nG1 Y30\nM2\n")
    run, rows = planned(path, max_jerk="5000")
    a = rows[:, run.columns.index("a")]
    assert run.limits.tangential_jerk() == 5000.0
    assert np.abs(np.diff(a)).max() <= 5000.0 * run.period * (1 + 1e-9)
    plain, plain_rows = planned(path)
    assert run.facts.motion_time > plain.facts.motion_time
    check_limits(run, rows)


@pytest.mark.parametrize("batch", [3, 17])
def test_windows_close_to_whole(tmp_path, batch):
    """Planned in windows of a few blocks and whole: the same path, jerk held in both, the motion times within
    a few ticks (the windows' search brackets differ: not the same plan to the bit).  Without smoothing, whose
    own window (8 192 blocks) would hand the planner this program whole."""
    path = program(tmp_path, random_program(np.random.default_rng(3), "noisy", n=300))
    whole, whole_rows = planned(path, batch=10_000, smooth=False, **JERK_OPTIONS)
    windowed, rows = planned(path, batch=batch, smooth=False, **JERK_OPTIONS)
    check_jerk(windowed, rows)
    assert abs(windowed.facts.motion_time - whole.facts.motion_time) <= 0.01 * whole.facts.motion_time
    assert windowed.facts.max_window < whole.facts.max_window


def test_every_window_can_stop(tmp_path, monkeypatch):
    """After every commit the pass's state stops inside what has been read: the window planned as if the
    program ended there reaches its end at rest within the caps (no stall, no refusal)."""
    path = program(tmp_path, random_program(np.random.default_rng(5), "noisy", n=400))
    checked = []
    original = la.JerkWindow.plan

    def plan_and_check(self, finished):
        out = original(self, finished)
        if not finished and self.rows.shape[0] and self.v_start > 0:
            probe = la.JerkWindow(self.period, self.jerk, self.jerk_top)
            for name in ("rows", "s_end", "t_start", "v_start", "s", "a", "carry", "t_section"):
                setattr(probe, name, getattr(self, name))
            table, _, _ = original(probe, True)
            assert table[-1, 2] == 0.0 and table[-1, 3] == 0.0  # at rest at the end
            assert np.all(table[:, 2] >= -1e-9)
            checked.append(self.v_start)
        return out

    monkeypatch.setattr(la.JerkWindow, "plan", plan_and_check)
    monkeypatch.setattr("nurbsinterp.motion.smooth.WINDOW", 64)
    monkeypatch.setattr("nurbsinterp.motion.smooth.MAX_HOLD", 64)
    monkeypatch.setattr("nurbsinterp.motion.smooth.CUT", 32)
    planned(path, batch=5, **JERK_OPTIONS)
    assert len(checked) > 5 and max(checked) > 1.0


def test_stops_and_dwell_with_jerk(tmp_path):
    """A program stop and a dwell: the tool at rest there, on ticks, for the dwell; jerk held across."""
    path = program(tmp_path, "G21 G90 G64 F3000\nG1 X10\nG4 P0.05\nG1 X20\nM0\nG1 X20 Y10\nM2\n")
    run, rows = planned(path, **JERK_OPTIONS)
    check_jerk(run, rows)
    v = rows[:, run.columns.index("v")]
    x = axes_of(run, rows)
    # the 50 ms dwell on whole ticks (the tick before may lie within 1e-12 mm of the stop, a few µs before it)
    at_rest = np.flatnonzero(np.all(np.abs(x - [10.0, 0.0]) <= 1e-12, axis=1) & (v == 0.0))
    assert at_rest.shape[0] >= 50 and np.all(np.diff(at_rest) == 1)


def test_raster_row_changes_at_rest_and_at_the_axes_jerk(tmp_path):
    """benchmarks/cam.py's raster, 3 rows of 40 moves: its 90° row-change corners are taken at rest on the
    programmed corners (the summary counts them), every tick within the tolerance and every axis' limits, and the
    braking into a corner and the ramp out of it along x run at nearly the full j_x (above 0.8 of it), not at
    the tangential share (half of it) every segment allows."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import cam

    path = program(tmp_path, cam.raster_program(600))
    run, rows = planned(path, **JERK_OPTIONS)
    check_limits(run, rows)
    j_max = check_jerk(run, rows)
    assert j_max[0] > 0.8 * JERK
    x = axes_of(run, rows)
    vertices = polyline(path)
    assert distance_to_polyline(x, vertices).max() <= TOL + TIGHT
    # each row change: two corners at rest, the tool exactly on them for at least one tick
    legs = np.diff(vertices, axis=0)  # the corners: the plunge into the first row, the row changes, the retract
    legs /= np.linalg.norm(legs, axis=1)[:, None]
    turn = np.degrees(np.arccos(np.clip((legs[:-1] * legs[1:]).sum(axis=1), -1.0, 1.0)))
    corners = vertices[1:-1][(turn > 45.0) & (turn < 179.0)]
    assert run.facts.corners_at_rest == len(corners) == 6
    v = rows[:, run.columns.index("v")]
    for q in corners:
        assert np.any(np.all(np.abs(x - q[:run.dim]) <= 1e-9, axis=1) & (v == 0.0))


def kernels(tau):
    """The third difference over ticks 0..3 of a velocity step of 1 at tick fraction tau (times T²) and of an
    acceleration step of 1 (times T), by brute force from the positions."""
    k = np.arange(4.0)
    c = np.array([-1.0, 3.0, -3.0, 1.0])
    after = np.maximum(k[None, :] - tau[:, None], 0.0)
    return (c * after).sum(axis=1), (c * after ** 2 / 2).sum(axis=1)


@budgets(quick=50, full=200)
def test_kink_speed_is_the_peak_of_both_jumps(budget):
    """_kink_speed(v, |A|) T⁻² is the largest third difference a unit kink passed at v with acceleration A makes
    wherever it falls in the three ticks (velocity jump v, acceleration jump A): brute force over 30 001
    positions, from below and within their spacing."""
    @settings(max_examples=budget, deadline=None)
    @given(st.floats(0.0, 50.0), st.floats(-3000.0, 3000.0))
    def check(v, acc):
        T = 1e-3
        k1, k2 = kernels(np.linspace(0.0, 3.0, 30001))
        brute = np.abs(v * k1 + acc * T * k2).max()
        bound = jk._kink_speed(v, abs(acc), T)
        assert brute <= bound * (1 + 1e-12) + 1e-15
        assert bound <= brute + (v + abs(acc) * T) * 3e-4

    check()


def test_step_weight_is_the_kernel_peak_before_y():
    """_step_weight(y): the largest weight of an acceleration step over positions [0, y] of the three ticks."""
    tau = np.linspace(0.0, 3.0, 30001)
    _, k2 = kernels(tau)
    for y in np.linspace(-0.5, 3.5, 81):
        brute = k2[tau <= y].max() if y >= 0 else 0.0
        assert jk._step_weight(y) == pytest.approx(brute, abs=1e-4)
        assert jk._step_weight(y) >= brute * (1 - 1e-12) - 1e-15


def wiggle(n, length, heading, turn, feed):
    """A program of n moves of *length* in the xz plane, heading alternately *heading* and *heading* + *turn*
    degrees: each corner's blend reaches half way along its moves, so blends turning opposite ways meet across
    lines of a fraction of a micrometre (as on LHchips4.ngc)."""
    lines = [f"G21 G90 F{feed}", "G1 X0 Z0"]
    x = z = 0.0
    for k in range(n):
        a = math.radians(heading + (turn if k % 2 else 0.0))
        x += length * math.cos(a)
        z += length * math.sin(a)
        lines.append(f"G1 X{x:.6f} Z{z:.6f}")
    return "\n".join(lines + ["M2"]) + "\n"


@pytest.mark.parametrize("length, turn", [(0.2, 1.0), (0.1, 1.0), (0.4, 2.0)])
def test_joints_within_three_ticks_add_their_jumps(tmp_path, length, turn):
    """Blends turning opposite ways a fraction of a micrometre apart: their curvature jumps fall in one third
    difference, and the joints' caps count both (motion.jerk._rows_beside).  Counting each alone let x and z
    reach 22 000–24 500 mm/s³ on these programs."""
    path = program(tmp_path, wiggle(60, length, -65.0, turn, 3000))
    run, rows = planned(path, smooth=False, **JERK_OPTIONS)
    assert run.facts.blends >= 50
    check_limits(run, rows)
    check_jerk(run, rows)
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    vertices = polyline(path)
    assert distance_to_polyline(x, vertices).max() <= TOL + TIGHT
    assert distance_to_polyline(vertices, x).max() <= TOL + TIGHT  # both ways: the corners near the commands


def test_commits_keep_a_row_that_shares_the_s0_of_a_short_one():
    """lookahead._unique_rows: the row a window ended inside is handed over twice and kept once, and a row after a
    row of rounding length (the same S0) is kept (vcarve.ngc under a jerk limit lost a blend half so: its ticks
    stood on the short row's end, then jumped 1.4 µm)."""
    rows = np.zeros((4, seg.NCOL))
    rows[:, seg.S0] = [0.0, 1000.0, 1000.0 + 3e-17, 1000.5]  # the third rounds to the second's S0
    rows[:, seg.LEN] = [1000.0, 3e-17, 0.5, 1.0]
    rows[:, seg.BLOCK] = [1, 2, 2, 3]
    rows[:, seg.UKIND] = [seg.U_LINEAR, seg.U_LINEAR, seg.U_BLEND_IN, seg.U_BLEND_OUT]
    assert rows[1, seg.S0] == rows[2, seg.S0]
    out = la._unique_rows([rows[:2], rows[1:]])
    np.testing.assert_array_equal(out, rows)
    np.testing.assert_array_equal(la._unique_rows([rows[:2], rows[1:2], rows[1:]]), rows)


# --------------------------------------------------------------------------- options and the summary


def test_summary_and_json(tmp_path, capsys):
    path = program(tmp_path, random_program(np.random.default_rng(1), "corners", n=20))
    args = ["--tolerance", "5um", "--profile-type", "adaptive", "--axis-max-accel", "x=1000,y=1000,z=1000",
            "--axis-max-velocity", "x=100,y=100,z=100", "--axis-max-jerk", "x=20000,y=20000,z=20000"]
    code, out, err = run_main(capsys, "plan", path, *args, "-o", str(tmp_path / "o.csv"))
    assert code == 0, err
    assert "ramps jerk-limited at 10000 mm/s^3" in err and "max jerk x 20000" in err
    code, out, err = run_main(capsys, "info", path, *args, "--json")
    assert code == 0, err
    import json

    doc = json.loads(out)
    assert doc["limits"]["axis_max_jerk"] == {"x": 20000.0, "y": 20000.0, "z": 20000.0}
    assert doc["limits"]["tangential_jerk"] == 10000.0
    assert max(doc["commands"]["max_jerk"].values()) <= 20000.0


def test_axis_jerk_without_look_ahead_refused(tmp_path, capsys):
    """A curve (one block) is planned by the paper's planner unless --tolerance asks for the look-ahead: a per-axis
    jerk limit is refused there.  A program is always planned with look-ahead: it holds the limit."""
    square = str(Path(__file__).resolve().parents[1] / "curves" / "circle.yaml")
    code, out, err = run_main(capsys, "plan", square, "--profile-type", "adaptive", "--axis-max-accel",
                              "x=1000,y=1000", "--axis-max-jerk", "x=20000", "-o", str(tmp_path / "o.csv"))
    one_line_error(code, out, err, "max_jerk", "20000", "--tolerance")
    assert not (tmp_path / "o.csv").exists()
    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nM2\n")
    code, out, err = run_main(capsys, "plan", path, "--axis-max-accel", "x=1000,y=1000,z=1000", "--axis-max-jerk",
                              "x=20000", "-o", str(tmp_path / "p.csv"))
    assert code == 0 and "max jerk x 20000 mm/s^3" in err, err


def test_machine_ini_max_jerk(tmp_path, capsys):
    """An INI's [AXIS_X] MAX_JERK: held by the look-ahead (a program, or --tolerance); a note (not applied) where
    the paper's planner plans (a curve without --tolerance); a YAML path of several blocks is the look-ahead's."""
    ini = tmp_path / "m.ini"
    ini.write_text("[TRAJ]\nLINEAR_UNITS = mm\n" + "".join(
        f"[AXIS_{a}]\nMAX_VELOCITY = 100\nMAX_ACCELERATION = 1000\nMAX_JERK = 20000\n" for a in "XYZ"))
    path = program(tmp_path, random_program(np.random.default_rng(2), "noisy", n=40))
    code, out, err = run_main(capsys, "plan", path, "--machine", str(ini), "--tolerance", "5um",
                              "--profile-type", "adaptive", "-o", str(tmp_path / "o.csv"))
    assert code == 0, err
    assert "max jerk x 20000, y 20000, z 20000 mm/s^3" in err and "not applied" not in err
    code, out, err = run_main(capsys, "plan", path, "--machine", str(ini), "--profile-type", "adaptive",
                              "-o", str(tmp_path / "q.csv"))
    assert code == 0, err
    assert "max jerk x 20000, y 20000, z 20000 mm/s^3" in err and "not applied" not in err
    root = Path(__file__).resolve().parents[1] / "curves"
    code, out, err = run_main(capsys, "plan", str(root / "square.yaml"), "--machine", str(ini), "--profile-type",
                              "adaptive", "-o", str(tmp_path / "s.csv"))
    assert code == 0, err
    assert "max jerk x 20000, y 20000 mm/s^3" in err and "not applied" not in err
    code, out, err = run_main(capsys, "plan", str(root / "circle.yaml"), "--machine", str(ini), "--profile-type",
                              "adaptive", "--chord-tolerance", "1um", "-o", str(tmp_path / "p.csv"))
    assert code == 0, err
    assert "MAX_JERK = 20000 mm/s^3 is not applied" in err
