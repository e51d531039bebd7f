"""Contour error and `simulate()`: a command stream through the closed loop, measured against the curve.

References built here: the paper's circle has closed forms (the distance from a point p
to it is | |p − (50, 0)| − 50 |, and the tilted 3-D circle's is
sqrt(h² + (ρ − 50)²) with h the height above its plane and ρ the in-plane radius),
and each axis' closed loop has the transfer-function reference of ``test_servo``.
"""
from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.errors import SpecError, StreamError
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.contour import CARRY, ServoStats, contour_errors
from nurbsinterp.nurbs import NurbsCurve, make_certificate
from nurbsinterp.servo import PAPER_TABLE, ServoModel, load_servo
from nurbsinterp.simulation import simulate, trace_columns
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli

from test_servo import tf_response

ROOT = Path(__file__).resolve().parents[1]
CIRCLE_JOB = ROOT / "curves" / "circle.yaml"
TILTED_JOB = ROOT / "curves" / "tilted-circle-3d.yaml"
XYZ_FILE = ROOT / "servo" / "example-xyz.yaml"
CENTRE = np.array([50.0, 0.0])
RADIUS = 50.0


def circle_distance(p):
    return np.abs(np.hypot(p[:, 0] - CENTRE[0], p[:, 1] - CENTRE[1]) - RADIUS)


def tilted_distance(p):
    """The tilted circle: centre (50, 0, 0), in the plane spanned by x and (0, cos 30°, sin 30°)."""
    n = np.array([0.0, -math.sin(math.radians(30)), math.cos(math.radians(30))])
    d = p - np.array([50.0, 0.0, 0.0])
    h = d @ n
    rho = np.linalg.norm(d - np.outer(h, n), axis=1)
    return np.hypot(h, rho - RADIUS)


@pytest.fixture(scope="module")
def circle():
    return NurbsCurve.from_spec(load_job(CIRCLE_JOB).curve)


def project(curve, act, seeds, carry=np.nan):
    act = np.ascontiguousarray(np.atleast_2d(np.asarray(act, float)))
    seeds = np.ascontiguousarray(np.atleast_1d(np.asarray(seeds, float)))
    out_u, out_d = np.empty(len(seeds)), np.empty(len(seeds))
    ends = curve.evaluate(np.array(curve.domain))
    closed = bool(np.linalg.norm(ends[0] - ends[1]) <= 1e-9 * curve.length)
    state = np.full(CARRY, np.nan)  # the previous foot and command (the rest of the carry is worked out)
    if carry == carry:
        state[:4] = [carry, carry, curve.arc_length_at(carry), curve.arc_length_at(carry)]
    cert = make_certificate(curve.bezier, curve.degree, curve.panels[1].shape[0])
    contour_errors(*curve.kernel_args, *curve.panels, cert, act, seeds, state, closed, out_u, out_d)
    return out_u, out_d


def radial(points, offset):
    """Points moved by *offset* along the circle's outward normal."""
    r = np.linalg.norm(points - CENTRE, axis=1)[:, None]
    return CENTRE + (points - CENTRE) * (RADIUS + offset) / r


# --------------------------------------------------------------------------- 6. contour error


def test_contour_error_zero_on_the_curve(circle):
    u = np.linspace(0.0, 1.0, 2001)  # includes the knots 0.25, 0.5 (double), 0.75 and both ends
    pts = circle.evaluate(u)
    _, d = project(circle, pts, u)
    assert d.max() < 1e-12
    stats = ServoStats(circle, ["x", "y"])
    t = 1e-3 * np.arange(len(u))
    err, speed = stats.update(t, u, pts, pts, np.zeros(len(u)), np.zeros_like(pts))
    rep = stats.report()
    assert err.max() < 1e-12 and rep.contour_error_max < 1e-12
    assert rep.tracking_error_max == {"x": 0.0, "y": 0.0}


@pytest.mark.parametrize("offset", [-10.0, -2.0, -0.3, -1e-3, 1e-6, 0.05, 0.3, 2.0, 10.0])
def test_contour_error_equals_normal_offset(circle, offset):
    u = np.linspace(0.0, 1.0, 801)
    q = radial(circle.evaluate(u), offset)
    foot, d = project(circle, q, u)
    np.testing.assert_allclose(d, abs(offset), rtol=0, atol=1e-9)
    # the closest point is the radial foot
    np.testing.assert_allclose(circle.evaluate(foot), radial(q, 0.0), rtol=0, atol=1e-6)
    # a seed some way off (the commanded u ahead of the table) finds the same distance
    _, d2 = project(circle, q, np.clip(u + 0.02, 0, 1))
    np.testing.assert_allclose(d2, abs(offset), rtol=0, atol=1e-9)


@pytest.mark.parametrize("lag", [5.0, 30.0, 50.0])
def test_contour_error_is_not_tracking_error(circle, lag):
    """The table lags *lag* mm of arc behind its command, exactly on the circle or 0.2 mm outside:
    the tracking error is millimetres, the contour error 0 or 0.2 mm."""
    u = np.linspace(0.3, 0.9, 200)
    s = circle.arc_length_at(u)
    behind = circle.evaluate(circle.parameter_at(s - lag))
    cmd = circle.evaluate(u)
    t = 1e-3 * np.arange(len(u))
    for offset in (0.0, 0.2):
        stats = ServoStats(circle, ["x", "y"])
        act = radial(behind, offset) if offset else behind
        err, _ = stats.update(t, u, cmd, act, np.zeros(len(u)), np.zeros_like(cmd))
        rep = stats.report()
        np.testing.assert_allclose(err, offset, rtol=0, atol=1e-9)
        tracking = max(rep.tracking_error_max.values())
        assert tracking > 0.5 * lag * 0.7  # at least the larger component of a chord of ~lag mm
        assert tracking > 10 * max(offset, 1e-3)
        assert rep.contour_error_max == pytest.approx(offset, abs=1e-9)
        expected = np.abs(cmd - act).max(axis=0)
        assert rep.tracking_error_max["x"] == pytest.approx(expected[0], abs=1e-12)
        assert rep.tracking_error_max["y"] == pytest.approx(expected[1], abs=1e-12)


def test_contour_error_carries_the_previous_closest_point(circle):
    """A table far behind a command that keeps running away: the second seed (the previous
    tick's closest u, carried across chunks) keeps the projection on the right branch."""
    stats = ServoStats(circle, ["x", "y"])
    u_cmd = np.linspace(0.5, 0.95, 300)
    act = radial(circle.evaluate(np.linspace(0.1, 0.12, 300)), 0.5)  # 0.5 mm out, far behind
    errs = []
    for a, b in [(0, 1), (1, 150), (150, 300)]:
        e, _ = stats.update(1e-3 * np.arange(a, b), u_cmd[a:b], circle.evaluate(u_cmd[a:b]), act[a:b],
                            np.zeros(b - a), np.zeros((b - a, 2)))
        errs.append(e)
    np.testing.assert_allclose(np.concatenate(errs), 0.5, rtol=0, atol=1e-9)


@pytest.mark.parametrize("lag", [45.0, 60.0])
def test_contour_error_from_a_far_seed(circle, lag):
    """One tick, no previous closest point: the table on the circle *lag* mm of arc behind the
    command u = 0.3 (acc/dec after interpolation puts the command ~Ta/2·F = 25 mm ahead).
    Regression: 02c88c0 clamped Newton steps to the bracket, which oscillated between its ends
    and returned 33.5 / 37.4 mm (fixed in 1aa3bbb).  If this fails while ``project_seeded`` alone
    gets it right, contour.contour_errors runs a stale numba cache: ``cache=True`` keys it on
    contour.py only, not on the nurbs/ functions compiled into it; clear __pycache__."""
    u_act = circle.parameter_at(circle.arc_length_at(0.3) - lag)
    _, d = project(circle, circle.evaluate(np.array([u_act])), [0.3])
    assert d[0] < 1e-9


@pytest.mark.parametrize("seed, point", [(1.0, (0.0, 0.01)), (0.0, (0.0, -0.01))],
                         ids=["past-the-end", "before-the-start"])
def test_contour_error_across_the_seam_of_a_closed_curve(circle, seed, point):
    """The circle starts and ends at (0, 0), moving +y.  A table overshooting the end by 10 µm in y
    is 1e-6 mm from the circle (its beginning), not 0.01 mm."""
    _, d = project(circle, [point], [seed], carry=seed)
    assert d[0] == pytest.approx(math.hypot(50.0, 0.01) - 50.0, abs=1e-12)


def test_chunk_measures_are_numpys():
    """contour.chunk_measures, one pass for every measure: the first largest |value| of each (as
    np.argmax finds it), the sums of squares (in tick order, NumPy's pairwise sum to rounding), and
    the actual feedrate |vel| to the bit."""
    from nurbsinterp.contour import chunk_measures

    rng = np.random.default_rng(2)
    m = 5000
    err = np.abs(rng.normal(size=m))
    cmd, act, vel = rng.normal(size=(m, 3)), rng.normal(size=(m, 3)), rng.normal(size=(m, 3))
    act[17] = cmd[17] + 9.0  # ties and a clear winner
    err[[40, 41]] = 7.0
    v_cmd = rng.normal(size=m)
    speed, at, sumsq = np.empty(m), np.empty(5, dtype=np.int64), np.empty(5)
    chunk_measures(err, cmd, act, vel, v_cmd, speed, at, sumsq)
    assert np.array_equal(speed, np.sqrt((vel * vel).sum(axis=1)))
    measures = [err, *(cmd - act).T, speed - v_cmd]
    for j, x in enumerate(measures):
        assert at[j] == int(np.argmax(np.abs(x)))
        assert sumsq[j] == pytest.approx(float(np.sum(x * x)), rel=1e-13)
    assert at[0] == 40


def test_feedrate_error_and_rms(circle):
    stats = ServoStats(circle, ["x", "y"])
    u = np.linspace(0.1, 0.2, 50)
    pts = circle.evaluate(u)
    vel = np.column_stack([np.linspace(0, 30, 50), np.linspace(0, -40, 50)])  # speed 0..50
    v_cmd = np.full(50, 48.0)
    _, speed = stats.update(1e-3 * np.arange(50), u, pts, pts, v_cmd, vel)
    np.testing.assert_allclose(speed, np.linspace(0, 50, 50), rtol=1e-15, atol=1e-13)
    rep = stats.report()
    e = np.linspace(0, 50, 50) - 48.0
    assert rep.feedrate_error_max == pytest.approx(48.0, abs=1e-12)
    assert rep.feedrate_error_max_signed == pytest.approx(-48.0, abs=1e-12)
    assert rep.feedrate_error_max_t == 0.0
    assert rep.feedrate_error_rms == pytest.approx(math.sqrt(np.mean(e * e)), rel=1e-13)


# --------------------------------------------------------------------------- simulate() on the circle


class Run:
    """A job planned in memory, its stream as one array, and its simulation with the full trace."""

    def __init__(self, path, model=PAPER_TABLE, chunk=None, **overrides):
        self.job = load_cli(path, overrides=overrides)
        self.curve = NurbsCurve.from_spec(self.job.curve)
        run = Interpolation(self.job, self.curve)
        self.columns = run.columns
        self.stream = np.vstack([c.data for c in run.chunks()])
        self.model = model
        rows = []
        self.report, _ = simulate(self.curve, model, self.columns, self.chunks(chunk), name="mem",
                                  trace=rows.append)
        self.trace = np.vstack(rows)
        self.cols = trace_columns(self.report.axes)

    def chunks(self, size=None):
        size = size or len(self.stream)
        return (self.stream[i:i + size] for i in range(0, len(self.stream), size))

    def col(self, name):
        return self.trace[:, self.cols.index(name)]

    def act(self):
        return np.column_stack([self.col(f"{a}_act") for a in self.report.axes])


@pytest.fixture(scope="module")
def before():
    return Run(CIRCLE_JOB)


@pytest.fixture(scope="module")
def after():
    return Run(CIRCLE_JOB, accdec="after")


def test_paper_finding_contour_error_before_is_smaller_than_after(before, after):
    """Section 5, Fig. 8: acc/dec before interpolation gives the smaller contour error."""
    b, a = before.report.contour_error_max, after.report.contour_error_max
    print(f"\ncircle contour error max: before {b * 1e3:.1f} um, after {a * 1e3:.1f} um, ratio {a / b:.2f}")
    assert 0.05 < b < 0.5  # some tenths of a mm at most
    assert a > 1.0
    assert a / b > 3
    assert after.report.contour_error_rms > 3 * before.report.contour_error_rms


def closed_form(run):
    return (tilted_distance if run.curve.dim == 3 else circle_distance)(run.act())


def across_the_seam(run):
    """Ticks whose command is in the second half of the circle while the table's closest point is
    at the beginning of it, past the start (= end) point (0, 0[, 0]): where the seam bug below applies.
    The circle leaves (0, 0) towards +y (the tilted one towards (0, cos 30°, sin 30°))."""
    act = run.act()
    ahead = act[:, 1] if run.curve.dim == 2 else act[:, 1:] @ [math.cos(math.radians(30)), math.sin(math.radians(30))]
    return (run.col("u") > 0.5) & (ahead > 0) & (np.linalg.norm(act, axis=1) < 1.0)


@pytest.fixture(scope="module")
def tilted():
    return Run(TILTED_JOB, model=load_servo(XYZ_FILE))


RUNS = ["before", "after", "tilted"]


@pytest.mark.parametrize("which", RUNS)
def test_contour_error_per_tick_is_distance_to_circle(request, which):
    """Every tick away from the seam, holding ticks included, to 1e-9 mm of the closed form."""
    run = request.getfixturevalue(which)
    keep = ~across_the_seam(run)
    assert keep.sum() > 0.95 * len(keep)
    np.testing.assert_allclose(run.col("contour_error")[keep], closed_form(run)[keep], rtol=0, atol=1e-9)
    assert run.report.contour_error_max == pytest.approx(closed_form(run).max(), abs=1e-9)


@pytest.mark.parametrize("which", RUNS)
def test_contour_error_per_tick_is_distance_to_circle_across_the_seam(request, which):
    run = request.getfixturevalue(which)
    np.testing.assert_allclose(run.col("contour_error"), closed_form(run), rtol=0, atol=1e-9)


@pytest.mark.parametrize("which", ["before", "after"])
def test_actual_positions_match_transfer_function_closed_loop(request, which):
    """End to end: the trace's actual axes are each axis' closed loop (TF route) driven by the
    stream's commands, then the held last command."""
    run = request.getfixturevalue(which)
    for a in ("x", "y"):
        cmd = run.col(f"{a}_cmd")
        assert np.array_equal(cmd[:len(run.stream)], run.stream[:, run.columns.index(a)])
        assert np.all(cmd[len(run.stream):] == run.stream[-1, run.columns.index(a)])
        ref = tf_response(PAPER_TABLE.axes[a], run.report.period, cmd)
        np.testing.assert_allclose(run.col(f"{a}_act"), ref, rtol=0, atol=1e-9)


@pytest.mark.parametrize("which", ["before", "after"])
def test_report_agrees_with_its_trace(request, which):
    run = request.getfixturevalue(which)
    rep = run.report
    ce = run.col("contour_error")
    j = int(np.argmax(ce))
    assert rep.contour_error_max == ce[j]
    assert rep.contour_error_max_t == run.col("t")[j]
    assert rep.contour_error_rms == pytest.approx(math.sqrt(np.mean(ce ** 2)), rel=1e-12)
    for a in ("x", "y"):
        e = run.col(f"{a}_cmd") - run.col(f"{a}_act")
        assert rep.tracking_error_max[a] == np.abs(e).max()
        assert rep.tracking_error_rms[a] == pytest.approx(math.sqrt(np.mean(e ** 2)), rel=1e-12)
    fe = run.col("v_act") - run.col("v_cmd")
    assert rep.feedrate_error_max == np.abs(fe).max()
    assert rep.feedrate_error_rms == pytest.approx(math.sqrt(np.mean(fe ** 2)), rel=1e-12)
    # the trace's columns, ticks and times
    assert run.cols == ["k", "t", "u", "x_cmd", "y_cmd", "x_act", "y_act", "contour_error", "v_cmd", "v_act"]
    k = run.col("k")
    assert np.array_equal(k, np.arange(rep.ticks))
    np.testing.assert_allclose(run.col("t"), k * rep.period, rtol=1e-15, atol=0)
    assert np.array_equal(run.col("v_cmd")[:len(run.stream)], run.stream[:, -2])


@pytest.mark.parametrize("which", ["before", "after"])
def test_hold_until_settled(request, which):
    run = request.getfixturevalue(which)
    rep = run.report
    T = rep.period
    assert rep.period == 1e-3 and rep.axes == ["x", "y"]
    assert rep.command_ticks == len(run.stream)
    assert rep.settled is True
    held = rep.ticks - rep.command_ticks
    assert held > 0 and held % 50 == 0  # whole blocks of 0.05 s
    assert rep.settle_time == pytest.approx(held * T, rel=1e-15)
    end = run.stream[-1, 4:6]
    last_block = run.act()[-50:]
    assert np.abs(last_block - end).max() <= 1e-6  # README: settled within 1 nm
    before_block = run.act()[-100:-50]
    assert held == 50 or np.abs(before_block - end).max() > 1e-6  # it stopped at the first settled block
    assert np.all(run.col("v_cmd")[rep.command_ticks:] == 0.0)
    assert np.all(run.col("u")[rep.command_ticks:] == run.stream[-1, 3])


def test_report_does_not_depend_on_chunking(before):
    for size in (2, 1000, 1777):
        rows = []
        rep, _ = simulate(before.curve, PAPER_TABLE, before.columns, before.chunks(size), trace=rows.append)
        assert np.array_equal(np.vstack(rows), before.trace)
        fields = rep.as_dict()
        for key, value in before.report.as_dict().items():
            if key.endswith("_rms"):
                assert fields[key] == pytest.approx(value, rel=1e-12), key
            else:
                assert fields[key] == value, key


def test_half_millisecond_stream():
    run = Run(CIRCLE_JOB, period="0.5 ms")
    assert run.report.period == 5e-4
    for a in ("x", "y"):
        ref = tf_response(PAPER_TABLE.axes[a], 5e-4, run.col(f"{a}_cmd"))
        np.testing.assert_allclose(run.col(f"{a}_act"), ref, rtol=0, atol=1e-9)
    moving = slice(0, run.report.command_ticks)
    np.testing.assert_allclose(run.col("contour_error")[moving], circle_distance(run.act())[moving],
                               rtol=0, atol=1e-9)
    assert 0.05 < run.report.contour_error_max < 0.5


def test_tilted_3d_circle_with_the_xyz_model(tilted):
    run, model = tilted, tilted.model
    rep = run.report
    assert rep.axes == ["x", "y", "z"] and set(rep.tracking_error_max) == {"x", "y", "z"}
    assert rep.period == 5e-4
    for a in ("x", "y"):  # the paper's axes are linear; z has an encoder and a voltage limit
        ref = tf_response(model.axes[a], rep.period, run.col(f"{a}_cmd"))
        np.testing.assert_allclose(run.col(f"{a}_act"), ref, rtol=0, atol=1e-9)
    z_err = np.abs(run.col("z_act") - run.col("z_cmd"))[-100:]
    assert rep.settled and z_err.max() <= 2 * model.axes["z"].encoder_resolution


# --------------------------------------------------------------------------- simulate() refusals


def test_stream_from_another_job_refused(before):
    job = load_job(TILTED_JOB)
    stream3 = np.vstack([c.data for c in Interpolation(job).chunks()])
    cols3 = ["k", "t", "u", "x", "y", "z", "v", "a"]
    with pytest.raises(StreamError, match=r"mem: the stream has 3 axes \(x,y,z\), the job's curve is 2-D"):
        simulate(before.curve, PAPER_TABLE, cols3, iter([stream3]), name="mem")
    curve3 = NurbsCurve.from_spec(job.curve)
    with pytest.raises(StreamError, match=r"mem: the stream has a z axis, the servo model .* has none"):
        simulate(curve3, PAPER_TABLE, cols3, iter([stream3]), name="mem")
    with pytest.raises(StreamError, match="2 axes"):
        simulate(curve3, load_servo(XYZ_FILE), before.columns, iter([before.stream]), name="mem")


def bad_stream(before, row, col, value):
    data = before.stream.copy()
    data[row, before.columns.index(col)] = value
    return data


def test_non_uniform_period_refused(before):
    data = bad_stream(before, 1234, "t", before.stream[1234, 2] + 1e-6)
    with pytest.raises(StreamError, match=r"^mem: tick 1234: t = .* breaks the uniform period") as info:
        simulate(before.curve, PAPER_TABLE, before.columns, [data[:1000], data[1000:]], name="mem")
    assert "\n" not in str(info.value)
    # 2 ns is the CSV rounding allowance: a jitter below it passes
    ok = bad_stream(before, 1234, "t", before.stream[1234, 2] + 1.5e-9)
    simulate(before.curve, PAPER_TABLE, before.columns, [ok], name="mem")


@pytest.mark.parametrize("value", [1.5, -0.25, 1.0 + 1e-9])
def test_u_outside_the_domain_refused(before, value):
    data = bad_stream(before, 77, "u", value)
    with pytest.raises(StreamError, match=r"^mem: tick 77: u = .* is outside the curve's domain"):
        simulate(before.curve, PAPER_TABLE, before.columns, [data], name="mem")


def test_streams_without_two_ticks_refused(before):
    with pytest.raises(StreamError, match="mem: the stream has a header but no ticks"):
        simulate(before.curve, PAPER_TABLE, before.columns, iter([]), name="mem")
    with pytest.raises(StreamError, match="mem: the stream has a header but no ticks"):
        simulate(before.curve, PAPER_TABLE, before.columns, [before.stream[:0]], name="mem")
    with pytest.raises(StreamError, match="mem: needs at least two ticks"):
        simulate(before.curve, PAPER_TABLE, before.columns, [before.stream[:1]], name="mem")


def test_loop_checked_at_the_streams_period():
    """kp = 500 on X is unstable at 1 ms (critical ~473) and stable at 0.5 ms (critical ~530)."""
    model = ServoModel({"x": dataclasses.replace(PAPER_TABLE.axes["x"], kp=500.0), "y": PAPER_TABLE.axes["y"]},
                       "fast.yaml")
    job = load_job(CIRCLE_JOB)
    curve = NurbsCurve.from_spec(job.curve)
    for period, ok in (("1 ms", False), ("0.5 ms", True)):
        run = Interpolation(load_cli(CIRCLE_JOB, overrides={"period": period}), curve)
        chunks = (c.data for c in run.chunks())
        if ok:
            rep, _ = simulate(curve, model, run.columns, chunks)
            assert rep.settled
        else:
            with pytest.raises(SpecError, match=r"fast.yaml: axes.x: the closed loop is unstable at T = 0.001 s"):
                simulate(curve, model, run.columns, chunks)


def test_table_that_cannot_settle_is_reported(before):
    """kp = 0.05 V/mm on both axes: a time constant of ~20 s; the hold gives up after 10 s."""
    slow = ServoModel({a: dataclasses.replace(PAPER_TABLE.axes[a], kp=0.05) for a in ("x", "y")}, "slow.yaml")
    rep, _ = simulate(before.curve, slow, before.columns, before.chunks())
    assert rep.settled is False
    assert rep.settle_time == pytest.approx(10.0, rel=1e-12)
    assert rep.ticks == rep.command_ticks + 10_000
    assert rep.servo == "slow.yaml"
