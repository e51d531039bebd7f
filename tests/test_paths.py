"""Paths of line, arc and NURBS blocks planned and interpolated as one motion (issue 14).

Closed forms for lines and arcs, the naive oracle (tests/oracle.py) for NURBS blocks,
the plan's own S(t) for junction crossings; corner blends on the look-ahead within a path's corner_tolerance.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path as FsPath

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

import oracle

sys.path.insert(0, str(FsPath(__file__).resolve().parent.parent / "benchmarks"))
from paths import random_path_doc  # noqa: E402  (the benchmark's generator: one definition)
from nurbsinterp.cli.common import load_cli
from nurbsinterp.config import load_job
from nurbsinterp.errors import SpecError
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.path import elevate, insert_knot, job_path, split
from nurbsinterp.servo import PAPER_TABLE
from nurbsinterp.simulation import simulate, trace_columns

CURVES = FsPath(__file__).resolve().parent.parent / "curves"
POCKET, SQUARE, ROUNDED, PATH3D = (CURVES / f"{name}.yaml" for name in ("pocket", "square", "rounded-square", "path-3d"))
METHODS = ("taylor1", "taylor2", "rk4", "exact")


def write(tmp_path, doc, name="job.yaml"):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc))
    return path


def run_all(job):
    run = Interpolation(job)
    chunks = list(run.chunks())
    data = np.vstack([c.data for c in chunks])
    return run, data, np.concatenate([c.u for c in chunks]), np.concatenate([c.planned for c in chunks])


# --------------------------------------------------------------------------- the job format

def square_doc(**profile):
    ramp = {} if "max_accel" in profile else {"accel_time": 0.1}  # max_accel: the adaptive profile reads no accel_time
    return {"path": {"start": [0, 0], "blocks": [{"line": {"to": [40, 0]}}, {"line": {"to": [40, 40]}},
                                                  {"line": {"to": [0, 40]}}, {"line": {"to": [0, 0]}}]},
            "profile": {"type": "trapezoidal", "feedrate": 50, **ramp, **profile}}


@pytest.mark.parametrize("blocks, start, expected", [
    ([{"line": {"to": [0, 0]}}], [0, 0], "path.blocks[0].line.to = [0, 0] is 0 mm from the block's start: a zero-length block"),
    ([{"line": {"to": [1, 0]}}, {"spline": {"to": [2, 0]}}], [0, 0], "path.blocks[1] = 'spline' is not a known block kind"),
    ([{"line": {"to": [1, 0]}}, {"nurbs": {"degree": 1, "control_points": [[1.001, 0], [2, 0]]}}], [0, 0],
     "path.blocks[1].nurbs.control_points[0] = [1.001, 0.0] is 0.001 mm from the end of the previous block [1.0, 0.0]"),
    ([{"arc": {"to": [10, 0], "center": [5, 0.3]}}], [0, 0.2], "path.blocks[0].arc.center = [5, 0.3] is"),
    ([{"arc": {"to": [10, 0], "radius": 2}}], [0, 0], "path.blocks[0].arc.radius = 2 is smaller than half the chord"),
    ([{"line": {"to": [1, 0, 0]}}], [0, 0], "path.blocks[0].line.to = [1, 0, 0] has 3 coordinates; the path is 2-D"),
    ([{"line": {"to": [1, 0]}}], None, "path.start is needed: path.blocks[0].line has no start of its own"),
    ([{"arc": {"to": [1, 0], "center": [0.5, 0], "plane": "xy"}}], [0, 0], "path.blocks[0].arc.plane = 'xy' is for 3-D paths"),
    ([{"line": {"to": [1, 0], "feed": 3}}], [0, 0], "path.blocks[0].line.feed is not a known key"),
])
def test_block_errors_name_the_block(tmp_path, blocks, start, expected):
    doc = {"path": {"blocks": blocks, **({"start": start} if start is not None else {})}}
    with pytest.raises(SpecError) as info:
        load_job(write(tmp_path, doc))
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"{tmp_path / 'job.yaml'}: ")
    assert expected in message, message


def test_a_block_within_a_nanometre_starts_exactly_at_the_previous_end(tmp_path):
    doc = {"path": {"start": [0, 0], "blocks": [
        {"line": {"to": [1, 0]}}, {"nurbs": {"degree": 1, "control_points": [[1 + 5e-10, 0], [2, 0]]}}]}}
    path = job_path(load_job(write(tmp_path, doc)))
    assert path.programmed.evaluate(path.starts[1]).tolist() == [1.0, 0.0]


def test_curve_and_path_are_exclusive(tmp_path):
    doc = square_doc()
    doc["curve"] = {"degree": 1, "control_points": [[0, 0], [1, 0]]}
    with pytest.raises(SpecError, match="has both a 'curve' and a 'path' section"):
        load_job(write(tmp_path, doc))


# --------------------------------------------------------------------------- exact geometry

def test_lines_and_arcs_are_exact():
    path = job_path(load_job(ROUNDED))
    for i, block in enumerate(path.blocks):
        u = np.linspace(0.0, 1.0, 101)
        pts = path.programmed.evaluate(path.to_global(np.full(101, i), u))
        if block.kind == "line":
            ref = block.start + u[:, None] * (block.end - block.start)
            np.testing.assert_allclose(pts, ref, rtol=0, atol=1e-12 * 40)
            assert path.block_lengths[i] == pytest.approx(np.linalg.norm(block.end - block.start), rel=1e-12)
        else:
            r = np.linalg.norm(pts - block.center, axis=1)
            np.testing.assert_allclose(r, block.radius, rtol=1e-12)
            assert path.block_lengths[i] == pytest.approx(block.radius * block.sweep, rel=1e-12)
        np.testing.assert_array_equal(pts[0], block.start)
        np.testing.assert_array_equal(pts[-1], block.end)
    assert path.length == pytest.approx(4 * 30 + 2 * math.pi * 5, rel=1e-12)
    assert not any(j.corner for j in path.junctions)


def test_nurbs_block_keeps_its_parameter_against_the_oracle():
    path = job_path(load_job(POCKET))
    n = 3
    c = path.blocks[n].curve
    for u in np.linspace(0, 1, 41):
        ref = oracle.point(c.knots, c.degree, c.control_points, c.weights, float(u))
        got = path.programmed.evaluate(float(path.to_global(n, u)))
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * 50)
        m, local = path.locate(np.array([path.to_global(n, u)]))
        if 0 < u < 1:
            assert m[0] == n and local[0] == pytest.approx(u, abs=1e-15)


def test_junction_table_of_the_pocket():
    path = job_path(load_job(POCKET))
    angles = [round(math.degrees(j.angle), 3) for j in path.junctions]
    assert [j.corner for j in path.junctions] == [False, False, True, True, True]
    assert angles[2:] == [26.565, 45.0, 90.0]


@st.composite
def random_curve(draw):
    p = draw(st.integers(1, 4))
    n = draw(st.integers(p, p + 4))
    pts = np.array(draw(st.lists(st.lists(st.floats(-50, 50), min_size=2, max_size=2), min_size=n + 1, max_size=n + 1)))
    w = np.array(draw(st.lists(st.floats(0.2, 5), min_size=n + 1, max_size=n + 1)))
    inner = sorted(draw(st.lists(st.sampled_from([0.1, 0.2, 0.25, 0.4, 0.5, 0.6, 0.75, 0.9]), min_size=n - p,
                                 max_size=n - p, unique=True)))
    if p >= 2 and inner and draw(st.booleans()):  # a double knot (C^(p-2)) where p allows it
        inner = sorted(inner[:-1] + [inner[0]])
    U = np.array([0.0] * (p + 1) + inner + [1.0] * (p + 1))
    return p, pts, w, U


@settings(max_examples=40, deadline=None, database=None)
@given(random_curve(), st.integers(1, 3), st.floats(0.05, 0.95))
def test_elevation_insertion_and_split_keep_the_curve(data, t, cut):
    p, pts, w, U = data
    Pw = np.column_stack([pts * w[:, None], w])
    us = np.linspace(0, 1, 23)

    def points(q, Qw, V, where):
        return np.array([oracle.point(V, q, Qw[:, :-1] / Qw[:, -1:], Qw[:, -1], float(x)) for x in where])

    ref = points(p, Pw, U, us)
    scale = 1e-12 * max(1.0, float(np.abs(pts).max()))
    Ew, EU = elevate(p, Pw, U, p + t)
    np.testing.assert_allclose(points(p + t, Ew, EU, us), ref, rtol=0, atol=50 * scale)
    Iw, IU = insert_knot(p, Pw, U, cut, 1)
    np.testing.assert_allclose(points(p, Iw, IU, us), ref, rtol=0, atol=50 * scale)
    (Lw, LU), (Rw, RU) = split(p, Pw, U, cut)
    left, right = us[us <= cut], us[us >= cut]
    np.testing.assert_allclose(points(p, Lw, LU, left), points(p, Pw, U, left), rtol=0, atol=50 * scale)
    np.testing.assert_allclose(points(p, Rw, RU, right), points(p, Pw, U, right), rtol=0, atol=50 * scale)


# --------------------------------------------------------------------------- one motion across junctions

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("job_file, shape", [(POCKET, "trapezoidal"), (ROUNDED, "bell"), (PATH3D, "exponential")])
def test_junction_crossing_lands_on_the_plan(job_file, shape, method):
    job = load_cli(job_file, overrides={"interpolator": method, "profile_type": shape})
    run, data, u, S = run_all(job)
    s = run.curve.arc_length_at(u)
    n = data[:, 1]
    crossing = np.flatnonzero(np.diff(n) != 0)
    assert crossing.size == len(run.path.blocks) - 1 or job_file == ROUNDED  # every junction crossed once
    v, a = data[:, run.columns.index("v")], data[:, run.columns.index("a")]
    lag = run.period * (0.5 * v.max() + run.period * np.abs(a).max())  # Eq. 8's: T·V/2, and a T²A term
    for k in crossing:
        # the tick after a corner is on the plan's own arc length, whatever the method; a tangent joint
        # is crossed like any knot, the Taylor and RK runs keeping their lag (at most Eq. 8's) rather than
        # making it up in one tick; exact is on the plan everywhere
        corner = run.path.junctions[int(n[k + 1]) - 1].corner
        assert abs(s[k + 1] - S[k + 1]) <= (1e-9 if corner or method == "exact" else lag), (k, s[k + 1], S[k + 1])
    # (n, u) is the point of block n at its own parameter
    for i in range(len(run.path.blocks)):
        rows = data[n == i]
        pts = run.path.programmed.evaluate(run.path.to_global(np.full(rows.shape[0], i), rows[:, 3]))
        np.testing.assert_allclose(pts, rows[:, 4:4 + run.curve.dim], rtol=0, atol=1e-9)


@pytest.mark.parametrize("shape", ["trapezoidal", "exponential", "bell"])
@pytest.mark.parametrize("method", METHODS)
def test_paper_profiles_stop_on_a_tick_at_every_corner(shape, method):
    job = load_cli(POCKET, overrides={"interpolator": method, "profile_type": shape})
    run, data, u, S = run_all(job)
    pts = data[:, 4:6]
    for j in run.path.corners:
        corner = run.path.programmed.evaluate(j.u)
        k = int(np.argmin(np.linalg.norm(pts - corner, axis=1)))
        assert np.linalg.norm(pts[k] - corner) <= 1e-9
        assert data[k, 6] == 0.0  # v: at rest there
    # the plan is rest to rest: its speed is zero at each corner's arc length
    assert run.profile.duration == pytest.approx((data.shape[0] - 1) * run.period, abs=run.period)


def test_acc_dec_after_interpolation_filters_through_corners():
    job = load_cli(SQUARE, overrides={"accdec": "after"})
    run, data, u, S = run_all(job)
    v = data[:, 6]
    corners = [run.path.programmed.evaluate(j.u) for j in run.path.corners]
    for corner in corners:
        k = int(np.argmin(np.linalg.norm(data[:, 4:6] - corner, axis=1)))
        assert np.linalg.norm(data[k, 4:6] - corner) > 1e-3  # the filter cuts the corner ...
        assert v[k] > 1.0  # ... without stopping


# --------------------------------------------------------------------------- blended corners

def distance_to_square(pts):
    segs = [((0, 0), (40, 0)), ((40, 0), (40, 40)), ((40, 40), (0, 40)), ((0, 40), (0, 0))]
    best = np.full(pts.shape[0], np.inf)
    for a, b in segs:
        a, b = np.array(a, float), np.array(b, float)
        t = np.clip(((pts - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
        best = np.minimum(best, np.linalg.norm(a + t[:, None] * (b - a) - pts, axis=1))
    return best


AXES = {"x": {"max_accel": 1000}, "y": {"max_accel": 1000}}


def look_ahead(path):
    """`plan PATH` as the commands plan a path of several blocks: the look-ahead, within the job's own tolerance
    (its corner_tolerance); (run, rows)."""
    from nurbsinterp.motion.pipeline import LookAhead

    run = LookAhead(load_job(path, every_profile=True, stream=True), None)
    return run, np.concatenate(list(run.chunks()))


@pytest.mark.parametrize("profile", [dict(type="adaptive", max_accel=1000, axes=AXES), {}], ids=["adaptive",
                                                                                                  "trapezoidal"])
def test_blended_square_stays_within_the_corner_tolerance_and_is_faster(tmp_path, profile):
    """A path's corner_tolerance blends its corners on the look-ahead, whatever the profile."""
    stop = write(tmp_path, square_doc(**profile), "stop.yaml")
    blend = write(tmp_path, square_doc(**profile, corner_tolerance=0.01), "blend.yaml")
    run_stop, data_stop = look_ahead(stop)
    run, data = look_ahead(blend)
    dev = distance_to_square(data[:, 4:6])
    assert dev.max() <= 0.01 + 1e-9
    assert dev.max() > 0.001  # the corners are really blended
    assert run.facts.blends == 3 and run_stop.facts.blends == 0 and run_stop.facts.stops == 3
    assert data.shape[0] < data_stop.shape[0]  # faster than stopping at every corner
    # the limits: feedrate, tangential acceleration, and each axis's acceleration (the commands, exactly)
    accel = 1000.0 if profile else 50.0 / 0.1  # the adaptive profile's max_accel, the trapezoidal's ramp F/Ta
    assert data[:, 6].max() <= 50 * (1 + 1e-9)
    assert np.abs(data[:, 7]).max() <= accel * (1 + 1e-9)
    acc = np.diff(data[:, 4:6], 2, axis=0) / run.period ** 2
    assert np.abs(acc).max() <= accel * (1 + 1e-6)


# --------------------------------------------------------------------------- contour error across junctions

def brute_distance(path, q):
    """Distance from q to the programmed path: lines and arcs in closed form, NURBS blocks by dense
    sampling of the naive oracle refined by golden section."""
    best = math.inf
    for block in path.blocks:
        if block.kind == "line":
            a, b = block.start, block.end
            t = min(1.0, max(0.0, float((q - a) @ (b - a) / ((b - a) @ (b - a)))))
            best = min(best, float(np.linalg.norm(a + t * (b - a) - q)))
        elif block.kind == "arc":
            v = q - block.center
            r0 = block.start - block.center
            ang = math.atan2(float((r0[0] * v[1] - r0[1] * v[0]) * block.normal[2]),
                             float((block.start - block.center) @ v)) % (2 * math.pi)
            if ang <= block.sweep:
                best = min(best, abs(float(np.linalg.norm(v)) - block.radius))
            best = min(best, float(np.linalg.norm(q - block.start)), float(np.linalg.norm(q - block.end)))
        else:
            c = block.curve
            f = lambda x: float(np.linalg.norm(oracle.point(c.knots, c.degree, c.control_points, c.weights, x) - q))
            xs = np.linspace(0, 1, 401)
            # the samples in the oracle's array form (the same recursion on every x at once; it agrees with the
            # point-by-point form to a few 1e-16 of the curve's size), refined point by point below
            ds = list(np.linalg.norm(oracle.point(c.knots, c.degree, c.control_points, c.weights, xs) - q, axis=1))
            i = int(np.argmin(ds))
            lo, hi = xs[max(i - 1, 0)], xs[min(i + 1, 400)]
            for _ in range(80):
                m1, m2 = lo + (hi - lo) * 0.382, lo + (hi - lo) * 0.618
                if f(m1) < f(m2):
                    hi = m2
                else:
                    lo = m1
            best = min(best, f(0.5 * (lo + hi)), ds[i])
    return best


def test_contour_error_across_junctions_matches_brute_force():
    job = load_job(POCKET)
    run = Interpolation(job)
    rows = []
    simulate(run.path, PAPER_TABLE, run.columns, (c.data for c in run.chunks()), trace=rows.append)
    trace = np.vstack(rows)
    cols = trace_columns(["x", "y"])
    act = trace[:, [cols.index("x_act"), cols.index("y_act")]]
    err = trace[:, cols.index("contour_error")]
    n = np.asarray(rows and np.vstack([c.data for c in Interpolation(job).chunks()])[:, 1])
    near = np.zeros(trace.shape[0], bool)  # every tick within 50 of a junction crossing, and a sample elsewhere
    for k in np.flatnonzero(np.diff(n) != 0):
        near[max(0, k - 50): k + 50] = True
    near[::97] = True
    for k in np.flatnonzero(near):
        assert abs(err[k] - brute_distance(run.path, act[k])) <= 1e-6, k


# --------------------------------------------------------------------------- many blocks

def test_ten_thousand_random_blocks_plan(tmp_path):
    job = load_job(write(tmp_path, random_path_doc(10_000)))
    run = Interpolation(job)
    path = run.path
    assert len(path.blocks) == 10_000
    assert path.length == pytest.approx(path.block_lengths.sum(), rel=1e-12)
    stops = path.section_ends()
    assert len(stops) == sum(j.corner for j in path.junctions) + 1
    S, V, _ = run.profile.evaluate(np.array([0.0, run.profile.duration]))
    assert S[-1] == pytest.approx(path.length, rel=1e-12) and V[-1] == 0.0


def test_random_path_run_crosses_every_corner_on_the_plan(tmp_path):
    job = load_job(write(tmp_path, random_path_doc(60, seed=3)))
    run, data, u, S = run_all(job)
    s = run.curve.arc_length_at(u)
    crossing = np.flatnonzero(np.diff(data[:, 1]) != 0)
    crossing = crossing[[run.path.junctions[int(data[k + 1, 1]) - 1].corner for k in crossing]]
    assert crossing.size  # (a tangent joint is crossed like any knot: see test_junction_crossing_lands_on_the_plan)
    np.testing.assert_allclose(s[crossing + 1], S[crossing + 1], rtol=0, atol=1e-9)
    assert np.all(np.diff(data[:, 1]) >= 0)


@settings(max_examples=12, deadline=None, database=None)
@given(st.integers(1, 12), st.integers(0, 10_000), st.sampled_from(["trapezoidal", "exponential", "bell", "adaptive"]),
       st.sampled_from(METHODS))
def test_random_paths_run_on_their_plan(tmp_path_factory, count, seed, shape, method):
    """Any random path, profile and method (the paper's planner over the whole path, as the library still plans
    it): finite ticks, block by block in order, every junction on the plan."""
    doc = random_path_doc(count, seed)
    doc["profile"]["type"] = shape
    if shape == "adaptive":
        doc["profile"].update(max_accel=2000)
        doc["profile"].pop("accel_time", None)  # which the adaptive profile with max_accel does not read
    doc["interpolator"] = {"method": method}
    job = load_job(write(tmp_path_factory.mktemp("p"), doc))
    run, data, u, S = run_all(job)
    assert np.isfinite(data).all()
    assert np.all(np.diff(data[:, 1]) >= 0) and data[-1, 1] == count - 1
    np.testing.assert_array_equal(data[-1, 4:6], run.path.blocks[-1].end)
    s = run.curve.arc_length_at(u)
    crossing = np.flatnonzero(np.diff(data[:, 1]) != 0)
    # a tangent joint is crossed like any knot (exact aside): the corners, stops, are landed on exactly
    crossing = np.array([k for k in crossing if run.path.junctions[int(data[k + 1, 1]) - 1].corner
                         or method == "exact"], dtype=int)
    np.testing.assert_allclose(s[np.add(crossing, 1)], S[np.add(crossing, 1)], rtol=0, atol=1e-9)
