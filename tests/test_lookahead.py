"""The look-ahead pipeline (nurbsinterp.motion, `plan --tolerance`): blends, limits, stops, windows, the stream.

References are independent of the pipeline: the programmed polyline and the distance to it by brute force
(every segment, exact point-to-segment distance), the axes' finite differences of the emitted commands,
closed forms (a trapezoid's time, a blend's deviation d·tan(θ/4)), and the same program planned whole and in
windows of three blocks.  Tolerances: positions are sums of a few products of numbers <= 100 mm, so 1e-9 mm
holds them with a wide margin; the limits hold to the caps' rounding (1e-12 relative) plus the rounding of
a second difference of positions (check_limits: 4ε/T², ε a few ulps of |x|, of the arc length and of V·t).
"""
from __future__ import annotations

import json
import math
import textwrap

import numpy as np
import oracle
import pytest
from test_cli_contract import one_line_error, run_main

from nurbsinterp.cli.common import load
from nurbsinterp.config.gcode import read_gcode
from nurbsinterp.errors import SpecError
from nurbsinterp.motion import segments as seg
from nurbsinterp.motion import smooth as smoothing
from nurbsinterp.motion.limits import BLEND_TANGENTIAL_SHARE
from nurbsinterp.motion.lookahead import Window, scan
from nurbsinterp.motion.pipeline import LookAhead
from nurbsinterp.path import block_nurbs
from nurbsinterp.streams import read_stream

TOL = 0.005  # mm
LIMITS = dict(profile_type="adaptive", axis_max_velocity="x=100,y=100,z=100", axis_max_accel="x=1000,y=1000,z=1000",
              rapid_feedrate="6000mm/min")
TIGHT = 1e-9  # mm


def program(tmp_path, text, name="p.ngc"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return str(path)


def planned(path, tol=TOL, batch=4096, smooth=True, **options):
    """(the run, every row of its stream)."""
    job = load(path, **{**LIMITS, **options})
    run = LookAhead(job, tol, batch=batch, smooth=smooth)
    rows = np.concatenate(list(run.chunks()))
    return run, rows


def polyline(path):
    """The programmed path as (vertices (n+1, 3)) of a program of lines, its start first."""
    blocks = read_gcode(path).blocks
    pts = [np.append(blocks[0].start, [0.0] * (3 - len(blocks[0].start)))]
    for b in blocks:
        pts.append(np.append(b.end, [0.0] * (3 - len(b.end))))
    return np.array(pts)


def distance_to_polyline(points, vertices):
    """Exact distance of each point to the polyline (every segment, brute force).

    Written one coordinate at a time over small blocks of points: the same operations in the same order as
    the whole-array form ((q - a)·ab summed x, y, z; the minimum of the squares, then its square root, which is
    monotone), so the same doubles, without temporaries of hundreds of megabytes.
    """
    a = vertices[:-1]
    ab = vertices[1:] - a
    den = (ab * ab).sum(axis=1)
    moving = den > 0
    safe = np.where(moving, den, 1.0)
    A = [np.ascontiguousarray(a[:, j]) for j in range(a.shape[1])]
    B = [np.ascontiguousarray(ab[:, j]) for j in range(a.shape[1])]
    out = np.empty(points.shape[0])
    for lo in range(0, points.shape[0], 16):
        q = points[lo:lo + 16]
        dot = (q[:, 0, None] - A[0]) * B[0]
        for j in range(1, len(A)):
            dot += (q[:, j, None] - A[j]) * B[j]
        t = np.clip(np.where(moving, dot / safe, 0.0), 0.0, 1.0)
        d2 = (A[0] + t * B[0] - q[:, 0, None]) ** 2
        for j in range(1, len(A)):
            d2 += (A[j] + t * B[j] - q[:, j, None]) ** 2
        out[lo:lo + 16] = np.sqrt(d2.min(axis=1))
    return out


def _distance_to_polyline_whole_arrays(points, vertices):
    """The same distance in whole arrays (512 points at a time): what distance_to_polyline is checked against."""
    a = vertices[:-1]
    ab = vertices[1:] - a
    den = (ab * ab).sum(axis=1)
    out = np.empty(points.shape[0])
    for lo in range(0, points.shape[0], 512):
        q = points[lo:lo + 512, None, :]
        t = np.clip(np.where(den > 0, ((q - a) * ab).sum(axis=2) / np.where(den > 0, den, 1.0), 0.0), 0.0, 1.0)
        out[lo:lo + 512] = np.sqrt(((a + t[..., None] * ab - q) ** 2).sum(axis=2)).min(axis=1)
    return out


def test_the_brute_force_distance_is_the_whole_array_one():
    """distance_to_polyline, the oracle of the look-ahead's tests, against its whole-array form to the bit:
    points far, near and on random polylines in 2-D and 3-D, with segments of zero length."""
    rng = np.random.default_rng(11)
    for dim in (2, 3):
        vertices = np.cumsum(rng.normal(size=(700, dim)), axis=0)
        vertices[5] = vertices[4]
        vertices[-1] = vertices[-2]
        points = np.concatenate([rng.normal(size=(300, dim)) * 30, vertices[::7], vertices[::7] + 1e-12])
        assert np.array_equal(distance_to_polyline(points, vertices),
                              _distance_to_polyline_whole_arrays(points, vertices))


def col(run, name):
    return run.columns.index(name)


def axes_of(run, rows):
    return rows[:, 4:4 + run.dim]


#: relative slack of a limit: the caps are a chain of a few sqrt, products and quotients of the limits (segments.py),
#: each rounded to half an ulp -- some 1e-15 relative; 1e-12 leaves room for a hundred of them
CAP_ROUNDING = 1e-12


def position_rounding(run, rows):
    """ε (mm): a bound on the rounding of one emitted position, from the stream itself.

    A command is x = P + ℓ·d (or an arc's R((cos θ − 1)e1 + sin θ e2), as exact as its arc length ℓ), with
    ℓ = S(t) − S0, S(t) = S_p + τ(v0 + τa/2), τ = k·T − t_p: each rounded to an ulp of its magnitude, so x is
    off by a few ulps of |x|, of the arc length S (<= motion time · largest feed) and V times an ulp of t.
    Four of each per position is generous; a difference of two positions carries 2ε, a second difference 4ε."""
    x = axes_of(run, rows)
    t_end = float(rows[-1, col(run, "t")])
    v_max = float(rows[:, col(run, "v")].max())
    X = float(np.abs(x).max())
    return 4.0 * (np.spacing(X) + np.spacing(t_end * v_max + X) + v_max * np.spacing(t_end))


def check_limits(run, rows, vel=100.0, acc=1000.0):
    """Per-axis |Δx/T| <= v_i and |Δ²x/T²| <= a_i over every tick (*vel*, *acc*: scalars or (dim,) per axis, inf
    where there is none), up to the positions' rounding (:func:`position_rounding`) and CAP_ROUNDING.  A first
    difference over T is the mean velocity over the tick, a second difference over T² the hat-weighted mean of the
    acceleration over ±T (plus the jump of velocity at an unblended joint, which its cap holds within γ a_i):
    the limits bind them exactly, not just in the limit T -> 0.  Returns the largest of each per axis."""
    x = axes_of(run, rows)
    T = run.period
    vel = np.broadcast_to(np.asarray(vel, dtype=float), (run.dim,))
    acc = np.broadcast_to(np.asarray(acc, dtype=float), (run.dim,))
    eps = position_rounding(run, rows)
    v = np.abs(np.diff(x, axis=0)) / T
    a = np.abs(np.diff(x, 2, axis=0)) / T ** 2
    v_max = v.max(axis=0) if v.shape[0] else np.zeros(run.dim)
    a_max = a.max(axis=0) if a.shape[0] else np.zeros(run.dim)
    assert np.all(v_max <= vel * (1 + CAP_ROUNDING) + 2 * eps / T), (v_max, vel, int(v.max(axis=1).argmax()))
    assert np.all(a_max <= acc * (1 + CAP_ROUNDING) + 4 * eps / T ** 2), (a_max, acc, int(a.max(axis=1).argmax()))
    return v_max, a_max


def random_program(rng, kind, n=60):
    """G-code of a random polyline: 'noisy' (short moves, rounded), 'corners' (real corners), 'reversals'
    (some moves turn back, some nearly), 'micro' (1 um moves), 'mixed' (lines, arcs and rapids in 3-D)."""
    lines = ["G21 G90 G64", "F1500"]
    p = np.zeros(3)
    heading = 0.0
    for i in range(n):
        if kind == "noisy":
            heading += rng.normal(0, 0.05)
            step = rng.uniform(0.05, 0.3)
            p = p + step * np.array([math.cos(heading), math.sin(heading), 0.0])
            q = np.round(p + rng.normal(0, 3e-4, 3) * [1, 1, 0], 4)
        elif kind == "corners":
            heading += rng.choice([0.0, 0.3, math.pi / 2, -2.0, 2.8])
            p = p + rng.uniform(0.2, 5.0) * np.array([math.cos(heading), math.sin(heading), 0.0])
            q = p
        elif kind == "reversals":
            heading += rng.choice([math.pi, math.pi - 1e-3, math.pi - 0.02, 0.5, 0.0])
            p = p + rng.uniform(0.1, 2.0) * np.array([math.cos(heading), math.sin(heading), rng.normal(0, 0.3)])
            q = p
        elif kind == "micro":
            heading += rng.normal(0, 0.02)
            p = p + 1e-3 * np.array([math.cos(heading), math.sin(heading), 0.0])
            q = p
        else:
            heading += rng.uniform(-1.5, 1.5)
            p = p + rng.uniform(0.3, 4.0) * np.array([math.cos(heading), math.sin(heading), rng.normal(0, 0.5)])
            q = p
            if i % 7 == 3:
                lines.append(f"G0 X{q[0]:.6f} Y{q[1]:.6f} Z{q[2]:.6f}")
                continue
        lines.append(f"G1 X{q[0]:.6f} Y{q[1]:.6f} Z{q[2]:.6f}")
    lines.append("M2")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- the tolerance, both ways


@pytest.mark.parametrize("kind", ["noisy", "corners", "reversals", "micro", "mixed"])
@pytest.mark.parametrize("seed", range(3))
def test_commands_within_tolerance_and_limits(tmp_path, kind, seed):
    """Every command within the tolerance of the programmed polyline; every corner of the polyline within it
    of the planned path; the per-axis limits by finite differences."""
    rng = np.random.default_rng(1000 * seed + len(kind))
    path = program(tmp_path, random_program(rng, kind))
    run, rows = planned(path)
    vertices = polyline(path)
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    assert distance_to_polyline(x, vertices).max() <= TOL + TIGHT
    # the planned path, densely: its segments evaluated, and each vertex's distance to them
    segs = np.concatenate(list(LookAhead(load(path, **LIMITS), TOL)._segments()))
    dense = []
    out = np.empty(3)
    for row in segs:
        for s in np.linspace(0.0, row[seg.LEN], 9):
            seg.segment_point(row, s, out)
            dense.append(out.copy())
    dense = np.array(dense)
    assert distance_to_polyline(dense, vertices).max() <= TOL + TIGHT
    # each vertex to the dense samples: within the tolerance plus the samples' spacing on the blends
    spacing = max(float(np.max(segs[:, seg.LEN] / 8.0)), 0.0)
    near = np.array([np.sqrt(((dense - v) ** 2).sum(axis=1)).min() for v in vertices])
    assert near.max() <= TOL + spacing + TIGHT
    # and both ways at the commands themselves: each vertex within the tolerance of the commands' polyline
    assert distance_to_polyline(vertices, x).max() <= TOL + TIGHT
    check_limits(run, rows)
    assert np.all(np.isfinite(rows))
    assert rows[-1, 4:4 + run.dim] == pytest.approx(vertices[-1][:run.dim], abs=0)  # the end, exactly


def test_blend_deviation_two_sided_brute_force(tmp_path):
    """Each blend's deviation d·tan(θ/4), against a brute-force two-sided distance between its arc and the
    corner's two legs (dense samples of both, exact distance to the other's polyline, plus the sag bound)."""
    rng = np.random.default_rng(7)
    path = program(tmp_path, random_program(rng, "corners", n=30))
    run = LookAhead(load(path, **LIMITS), TOL)
    rows = np.concatenate(list(run._segments()))
    halves = np.flatnonzero(rows[:, seg.UKIND] == seg.U_BLEND_IN)
    assert halves.size > 5
    out = np.empty(3)
    for i in halves:
        first, second = rows[i], rows[i + 1]
        arc = []
        for row in (first, second):
            for s in np.linspace(0.0, row[seg.LEN], 2001):
                seg.segment_point(row, s, out)
                arc.append(out.copy())
        arc = np.array(arc)
        a, b = arc[0], arc[-1]
        # the corner: where the tangents at a and b meet
        t1 = first[seg.E:seg.E + 3]
        R, half = first[seg.RADIUS], first[seg.SWEEP]
        d = R * math.tan(half)
        corner = a + d * t1
        legs = np.array([a, corner, b])
        e = d * math.tan(0.5 * half)
        assert e <= TOL * (1 + 1e-12)
        sag = (rows[i, seg.LEN] / 2000) ** 2 / (8 * R)
        one = distance_to_polyline(arc, legs).max()
        leg_points = np.concatenate([np.linspace(a, corner, 2001), np.linspace(corner, b, 2001)])
        other = distance_to_polyline(leg_points, arc).max()
        assert max(one, other) == pytest.approx(e, abs=sag + TIGHT)


# --------------------------------------------------------------------------- closed forms


def test_one_line_is_a_trapezoid(tmp_path):
    path = program(tmp_path, "G21 G90 F3000\nG1 X100\nM2\n")
    run, rows = planned(path)
    F, A, T = 50.0, 1000.0, 0.001
    assert run.facts.motion_time == pytest.approx(math.ceil((100 / F + F / A) / T - 1e-9) * T, abs=1e-12)
    assert rows[:, col(run, "v")].max() == pytest.approx(F, rel=1e-12)
    check_limits(run, rows)


def test_right_angle_blend_speed(tmp_path):
    """A 90° corner of two long lines: the blend takes d = δ / tan(22.5°), R = d, and the feed there is the
    centripetal share's: V = sqrt((1 − β) a R) (both axes see cos 45° of the normal at the arc's middle... at
    its ends one axis sees all of it: max |n_i| = 1)."""
    path = program(tmp_path, "G21 G90 F3000\nG1 X20\nG1 Y20\nM2\n")
    run, rows = planned(path)
    # the blend leaves room for its chords' sag at its feed, (VT)²/8R = (1 − β) a T²/8 where V² = (1 − β) a R
    sag = (1 - BLEND_TANGENTIAL_SHARE) * 1000.0 * 0.001 ** 2 / 8
    d = (TOL - sag) / math.tan(math.pi / 8)
    R = d / math.tan(math.pi / 4)
    v = math.sqrt((1 - BLEND_TANGENTIAL_SHARE) * 1000.0 * R)
    assert run.facts.blends == 1 and run.facts.worst_blend == pytest.approx(TOL - sag, rel=1e-8)
    on_blend = rows[(rows[:, 4] > 20 - d) & (rows[:, 5] < d)]
    assert on_blend.shape[0] > 0
    assert on_blend[:, col(run, "v")].max() == pytest.approx(v, rel=1e-8)


# --------------------------------------------------------------------------- stops


def test_program_stops_and_dwell(tmp_path):
    path = program(tmp_path, """
        G21 G90 G64 F3000
        G1 X10
        M0
        G1 X20
        G4 P0.25
        G1 X30 Y1
        M2
        """)
    run, rows = planned(path)
    x = rows[:, 4]
    for where, ticks in ((10.0, 0), (20.0, 250)):  # M0: at rest on a tick; G4 P0.25: 250 ticks more
        at = np.flatnonzero(np.abs(x - where) < 1e-12)
        assert at.size >= ticks + 1, (where, at.size)
        assert np.all(rows[at, col(run, "v")] == 0.0)
    assert run.facts.stops == 2


def test_reversal_is_a_stop_not_an_error(tmp_path):
    """A retract then a plunge (the raster's start) turns by 180°: the tool stops there."""
    path = program(tmp_path, "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F2000\nG1 X10\nM2\n")
    run, rows = planned(path)
    top = np.flatnonzero(np.abs(rows[:, 6] - 5.0) < 1e-12)
    assert top.size >= 1 and np.all(rows[top, col(run, "v")] == 0.0)
    assert run.facts.stops == 1
    check_limits(run, rows)


@pytest.mark.parametrize("mode, stops", [("G61.1", 3), ("G61", 2), ("G64", 0)])
def test_path_control_modes(tmp_path, mode, stops):
    """G61.1 stops at every joint; G61 (the exact path) at the right angles, too sharp to pass moving (X5 -> X10
    is straight on); G64 at none."""
    path = program(tmp_path, f"G21 G90 {mode} F3000\nG1 X5\nG1 X10\nG1 Y10\nG1 X0\nM2\n")
    run, rows = planned(path)
    assert run.facts.stops == stops
    check_limits(run, rows)


@pytest.mark.parametrize("mode, tol", [("G61", TOL), ("G64", 0.0)], ids=["G61", "no tolerance"])
def test_the_exact_path_passes_a_shallow_kink_moving_and_rests_at_a_right_angle(tmp_path, mode, tol):
    """The exact path (G61, or no tolerance anywhere): no blend; a kink of 2.3° is passed moving, at the speed whose
    jump of direction the axes allow (their limits held over every tick, the jump included), a right angle at
    rest; every tick on the programmed path."""
    path = program(tmp_path, f"G21 G90 {mode} F3000\nG1 X5\nG1 X10 Y0.2\nG1 Y10\nM2\n")
    run, rows = planned(path, tol=tol)
    assert run.facts.blends == 0 and run.facts.unblended == 1 and run.facts.sharp_stops == 1
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    v = rows[:, col(run, "v")]
    kink = np.flatnonzero(np.linalg.norm(x - [5.0, 0.0, 0.0], axis=1) < 0.02)
    corner = np.flatnonzero(np.linalg.norm(x - [10.0, 0.2, 0.0], axis=1) <= 1e-12)
    assert v[kink].min() > 1.0 and corner.size and v[corner].max() == 0.0
    assert distance_to_polyline(x, polyline(path)).max() <= TIGHT
    check_limits(run, rows)


# --------------------------------------------------------------------------- windows


@pytest.mark.parametrize("kind", ["noisy", "corners", "reversals", "mixed"])
def test_windows_equal_whole(tmp_path, kind):
    """Planned three blocks at a time and all at once: the same stream, to the bit."""
    path = program(tmp_path, random_program(np.random.default_rng(11), kind, n=200))
    _, whole = planned(path, batch=10_000)
    _, windowed = planned(path, batch=3)
    assert whole.shape == windowed.shape
    assert np.array_equal(whole, windowed)


@pytest.mark.parametrize("smooth", [False, True])
def test_every_window_boundary_can_stop(tmp_path, monkeypatch, smooth):
    """After every commit, the feedrate handed to the next window can still stop at the window's end: the
    scan of what is left, from that feedrate, keeps it.  With smoothing, its windows made small (64 blocks)
    so that the planner sees many."""
    if smooth:
        monkeypatch.setattr(smoothing, "WINDOW", 64)
        monkeypatch.setattr(smoothing, "MAX_HOLD", 64)
        monkeypatch.setattr(smoothing, "CUT", 32)
    path = program(tmp_path, random_program(np.random.default_rng(5), "noisy", n=400))
    checked = []
    original = Window.plan

    def plan_and_check(self, finished):
        out = original(self, finished)
        if not finished and self.rows.shape[0]:
            s, ncap, vcap, acap, _, _ = self.nodes(False)
            v = scan(s, ncap, vcap, acap, self.v_start, 0.0)
            assert v[0] == self.v_start
            checked.append(self.v_start)
        return out

    monkeypatch.setattr(Window, "plan", plan_and_check)
    run, _ = planned(path, batch=5, smooth=smooth)
    assert len(checked) > (5 if smooth else 20) and max(checked) > 0
    assert (run.smoothing.curves > 0) == smooth


# --------------------------------------------------------------------------- the stream's u column


def test_u_is_the_blocks_own_parameter(tmp_path):
    """On an arc block, u is the parameter of its NURBS (path.block_nurbs): the NURBS at u is the command."""
    path = program(tmp_path, "G21 G90 G17 F600\nG1 X10\nG3 X10 Y20 I0 J10\nG1 X0\nM2\n")
    run, rows = planned(path, tol=0.0)
    blocks = read_gcode(path).blocks
    for k in range(1, len(blocks)):
        p, Pw, U = block_nurbs(blocks[k])
        on = rows[rows[:, 1] == k]
        for r in on[:: max(1, on.shape[0] // 50)]:
            u = r[3]
            pt = oracle.point(U, p, Pw[:, :-1] / Pw[:, -1:], Pw[:, -1], u)  # the naive rational curve at u
            assert np.abs(pt - r[4:4 + run.dim]).max() <= TIGHT


# --------------------------------------------------------------------------- the command line


def test_cli_plan_tolerance(tmp_path, capsys):
    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nG1 Y10\nM2\n")
    out = tmp_path / "run.bin"
    code, stdout, err = run_main(capsys, "plan", path, "--tolerance", "5um", "--format", "bin", "-o", out,
                                 "--axis-max-accel", "x=1000,y=1000")
    assert code == 0, err
    assert "1 corners rounded within 5 um" in err and "look-ahead" in err
    with open(out, "rb") as fh:
        columns, chunks = read_stream(fh, str(out))
        data = np.concatenate(list(chunks))
    assert columns[:4] == ["k", "n", "t", "u"] and data[-1, 4] == 10.0 and data[-1, 5] == 10.0


@pytest.mark.parametrize("args, parts", [
    (["--tolerance", "abc"], ["--tolerance", "abc"]),
    (["--tolerance", "-1"], ["--tolerance", "-1"]),
    (["--tolerance", "5um", "--precompensate", "x.yaml"], ["x.yaml", "cannot read"]),  # pre-compensated, once read
])
def test_cli_bad_tolerance(tmp_path, capsys, args, parts):
    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nM2\n")
    one_line_error(*run_main(capsys, "plan", path, *args), *parts)


def test_no_acceleration_limit_refused(tmp_path):
    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nM2\n")
    with pytest.raises(SpecError, match="acceleration limit"):
        LookAhead(load(path, profile_type="adaptive", accel_time="0"), TOL)


def test_the_adaptive_profile_without_any_limit_ramps_at_f_over_ta_as_on_a_curve(tmp_path):
    """Nothing limits the acceleration (no max_accel, no axis' max_accel): the adaptive profile's max_accel is
    F/Ta of the default accel_time across blocks, as on one curve (profiles.profile_for), not a refusal."""
    from nurbsinterp.motion.limits import motion_limits

    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nM2\n")
    limits = motion_limits(load(path, every_profile=True, profile_type="adaptive", feedrate="50"), TOL)
    assert limits.accel == 50.0 / 0.5 and limits.source == "the adaptive profile's ramp, F/Ta"


# --------------------------------------------------------------------------- the profiles' limits


@pytest.mark.parametrize("options, accel, jerk", [
    ({"profile_type": "trapezoidal", "feedrate": "100", "accel_time": "0.5"}, 200.0, math.inf),
    ({"profile_type": "bell", "feedrate": "100", "accel_time": "0.5"}, 0.5 * math.pi * 200.0,
     math.pi ** 2 * 100.0 / (2.0 * (math.pi - 2.0) * 0.25)),
    # the exponential's ramps lose Ta a move, as F/Ta does (its peak, 4 / (1 - e^-4) F/Ta, is higher)
    ({"profile_type": "exponential", "feedrate": "100", "accel_time": "0.5", "time_constant": "0.125"},
     200.0, math.inf),
    ({"profile_type": "adaptive", "axis_max_accel": "x=1000,y=1000"}, math.inf, math.inf),
    ({"profile_type": "adaptive", "accel_time": "0.5", "feedrate": "100"}, 200.0, math.inf),
    ({"profile_type": "trapezoidal", "max_accel": "150"}, 150.0, math.inf),
])
def test_profile_limits(tmp_path, options, accel, jerk):
    """A profile's ramp as the look-ahead's tangential acceleration (README's table): F/Ta, the bell's peak with
    the jerk that reaches F in Ta, the exponential's loss of time; the adaptive profile has none of its own; the
    machine's max_accel binds below it."""
    from nurbsinterp.motion.limits import motion_limits

    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nM2\n")
    limits = motion_limits(load(path, every_profile=True, **options), TOL)
    assert limits.accel == pytest.approx(accel, rel=1e-15)
    assert limits.jerk == pytest.approx(jerk, rel=1e-15)


def test_bundled_raster_example(capsys):
    """README's example: the bundled raster program planned with look-ahead, its summary on stderr."""
    from pathlib import Path

    raster = Path(__file__).resolve().parents[1] / "curves" / "raster.ngc"
    code, out, err = run_main(capsys, "plan", raster, "--tolerance", "5um", "-q", "--columns", "k")
    assert code == 0 and err == "" and out.count("\n") == 8279 + 2  # header, ticks, end mark
    code, out, err = run_main(capsys, "plan", raster, "--tolerance", "5um", "--columns", "k,x,y,z")
    assert code == 0, err
    assert "look-ahead across 1007 blocks" in err and "corners rounded within 5 um" in err
    rows = np.loadtxt(out.splitlines()[1:-1], delimiter=",")
    assert rows.shape[1] == 4 and rows[-1, 3] == 5.0


@pytest.mark.parametrize("tolerance", [[], ["--tolerance", "5um"]], ids=["own G64 P", "--tolerance"])
def test_zero_length_moves_are_counted_once_the_same_everywhere(capsys, tmp_path, tolerance):
    """The reader leaves a zero-length move out and says so; the look-ahead's summary and its JSON count the
    same moves (they once said "0 of zero length dropped" under the reader's "3 zero-length moves dropped")."""
    path = program(tmp_path, "G21 G90 G64 P0.01\nG1 X10 F600\nG1 X10\nG1 X10 Y0\nG1 Y10\nG1 Y10\nG1 X0 Y10 Z0\nM2\n")
    code, _, err = run_main(capsys, "plan", path, *tolerance, "-o", tmp_path / "z.csv")
    assert code == 0, err
    assert f"{path}: 3 zero-length moves dropped" in err, err
    assert "look-ahead across 6 blocks (3 of zero length dropped)" in err, err  # the program's six moves
    code, out, err = run_main(capsys, "info", path, *tolerance, "--json")
    assert code == 0, err
    assert json.loads(out)["dropped"] == 3, out
