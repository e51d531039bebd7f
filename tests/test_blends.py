"""Corner blends never skip the path; reversals are stops; taylor1 keeps its lag at tangent joints (issue 27, item 5).

A path of several blocks is planned with look-ahead (motion.pipeline), its corners blended within the profile's
corner_tolerance (the tolerance of the blocks that state none); the issue's reproductions run there.

A blend's tolerance δ is two-sided: every command within δ of the programmed path
and every point of the programmed path within δ of the commanded one.  The
programmed paths here are lines, so the distance of a command to them is exact
(point to segment); the other way the programmed lines are sampled densely and
each sample's distance to the nearest *tick* is bounded:

    the commanded curve passes within δ of the sample (the claim), at a point c;
    c lies on one tick's step, whose arc length is at most h = T·F·STEP_FACTOR
    (the plan never exceeds F, the exact interpolator never exceeds its planned
    step by more than STEP_FACTOR), so c is within h/2 of arc, hence of space, of
    one of that step's two ticks;

so the nearest tick is within δ + T·F·STEP_FACTOR/2.  With F = 10 mm/s and
T = 0.1 ms that slack is 0.5 µm, a tenth of the smallest δ drawn; a corner point
left 0.39 δ outside the commanded path (the one-sided blend of a right angle)
or 3.4 mm of a slot's stroke never commanded fail it.  Between samples (spacing
σ) a programmed point may be σ/2 further; the samples are what is checked.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings, strategies as st
from scipy.spatial import cKDTree

from nurbsinterp.cli.common import load_cli
from nurbsinterp.config import load_job
from nurbsinterp.errors import SpecError
from nurbsinterp.interpolate import STEP_FACTOR, Interpolation
from nurbsinterp.motion.pipeline import LookAhead
from test_paths import CURVES, run_all, write

FEED = 10.0  # mm/s
PERIOD = 1e-4  # s
SLACK = PERIOD * FEED * STEP_FACTOR["exact"] / 2  # mm: a point of the commanded curve to its nearest tick (above)
SPACING = 2e-4  # mm between the samples of the programmed lines


def line_job(points, tolerance, **profile):
    return {"path": {"start": list(points[0]), "blocks": [{"line": {"to": list(p)}} for p in points[1:]]},
            "profile": {"type": "adaptive", "feedrate": FEED, "max_accel": 1000, "corner_tolerance": tolerance,
                        **profile},
            "interpolator": {"period": PERIOD}}


def segment_distance(q, a, b):
    """(N,) distance from points q (N, dim) to the union of segments a[i] → b[i], exactly."""
    out = np.full(q.shape[0], np.inf)
    for a0, b0 in zip(a, b):
        ab = b0 - a0
        t = np.clip(((q - a0) @ ab) / (ab @ ab), 0.0, 1.0)
        out = np.minimum(out, np.linalg.norm(a0 + t[:, None] * ab - q, axis=1))
    return out


def two_sided(points, ticks):
    """(commands' farthest from the programmed lines through *points*, programmed samples' farthest from a tick)."""
    points = np.asarray(points, dtype=float)
    a, b = points[:-1], points[1:]
    out = segment_distance(ticks, a, b).max()
    samples = np.vstack([a0 + np.linspace(0.0, 1.0, max(2, math.ceil(np.linalg.norm(b0 - a0) / SPACING)) + 1)[:, None]
                         * (b0 - a0) for a0, b0 in zip(a, b)])
    back, _ = cKDTree(ticks).query(samples)
    return float(out), float(back.max())


def look_ahead(job):
    """The look-ahead's run of *job* (its own tolerance: corner_tolerance) and every row of its stream."""
    run = LookAhead(job, None)
    return run, np.concatenate(list(run.chunks()))


def commanded(tmp_path, doc, name="job.yaml"):
    run, data = look_ahead(load_job(write(tmp_path, doc, name), every_profile=True, stream=True))
    return run, data[:, 4:4 + run.dim]


def assert_two_sided(points, ticks, tolerance):
    out, back = two_sided(points, ticks)
    assert out <= tolerance, f"a command {out * 1e3:.4g} um from the programmed path, tolerance {tolerance * 1e3:g} um"
    assert back <= tolerance + SLACK, (f"a programmed point {back * 1e3:.4g} um from every tick, tolerance "
                                       f"{tolerance * 1e3:g} um + {SLACK * 1e3:g} um between ticks")


# --------------------------------------------------------------------------- the reproductions

def slot(strokes=4, step=0.05, length=20.0):
    """A slot's zigzag: strokes out to X20 and back to X0, each 0.05 mm further in y (turns of 179.86°)."""
    return [(0.0, 0.0)] + [((length if i % 2 == 0 else 0.0), (i + 1) * step) for i in range(strokes)]


def turn(angle_deg, length=10.0):
    a = math.radians(angle_deg)
    return [(0.0, 0.0), (length, 0.0), (length + length * math.cos(a), length * math.sin(a))]


@pytest.mark.parametrize("points, tolerance", [
    (slot(), 0.010),  # turned back at x = 16.625 and 3.376 on main: 3.38 mm of each stroke never commanded
    (turn(179.9), 0.010),  # 1.71 mm short on main
    (turn(179.9), 0.001),  # 1.12 mm short
    (turn(90.0), 0.010),  # the corner itself 13.9 um from the one-sided blend (1.39 δ)
    (turn(120.0), 0.005),
])
def test_blends_keep_the_tolerance_both_ways(tmp_path, points, tolerance):
    run, ticks = commanded(tmp_path, line_job(points, tolerance))
    assert_two_sided(points, ticks, tolerance)


def test_slot_strokes_reach_their_ends(tmp_path):
    """The slot's strokes are commanded to X20 and back to X0 (to the tolerance), and each reversal is a stop."""
    points = slot()
    run, ticks = commanded(tmp_path, line_job(points, 0.010))
    assert ticks[:, 0].max() >= 20.0 - 0.010 and run.facts.blends == 0 and run.facts.stops == len(points) - 2
    for p in points[1:-1]:
        assert np.linalg.norm(ticks - p, axis=1).min() <= 1e-9  # a stop falls on a tick at the corner itself


def test_line_into_a_reversing_arc_is_not_skipped(tmp_path):
    """A line into an arc that turns straight back (cw about (10, 1)): 0.43 mm short at 5 um on main."""
    doc = {"path": {"start": [0, 0], "blocks": [{"line": {"to": [10, 0]}},
                                                {"arc": {"to": [10, 2], "center": [10, 1], "direction": "cw"}}]},
           "profile": {"type": "adaptive", "feedrate": FEED, "max_accel": 1000, "corner_tolerance": 0.005},
           "interpolator": {"period": PERIOD}}
    run, ticks = commanded(tmp_path, doc)
    # the programmed path: the line exactly, and the half circle sampled at SPACING
    phi = np.linspace(-math.pi / 2, -3 * math.pi / 2, math.ceil(math.pi / SPACING))
    arc = np.column_stack([10 + np.cos(phi), 1 + np.sin(phi)])
    line = np.column_stack([np.linspace(0, 10, math.ceil(10 / SPACING)), np.zeros(math.ceil(10 / SPACING))])
    back, _ = cKDTree(ticks).query(np.vstack([line, arc]))
    assert back.max() <= 0.005 + SLACK
    to_line = segment_distance(ticks, np.array([[0.0, 0.0]]), np.array([[10.0, 0.0]]))
    to_arc = np.abs(np.linalg.norm(ticks - [10.0, 1.0], axis=1) - 1.0)  # the full circle: <= the arc's distance
    assert np.minimum(to_line, to_arc).max() <= 0.005


@pytest.mark.parametrize("program", ["G0 X0 Y0 Z2\nG1 Z-0.5 F600\nG1 X10\nM2\n",  # a retract, then a plunge
                                     "G1 X10 F600\nG1 X0\nM2\n"])  # straight out and back
def test_an_exact_reversal_with_a_tolerance_is_a_stop(tmp_path, program):
    """Refused on main ("the parametric speed vanishes at u = 1.9625 ... insert a knot"): the blend was a cusp."""
    source = tmp_path / "reverse.ngc"
    source.write_text(program)
    job = load_cli(source, overrides={"profile_type": "adaptive", "max_accel": 1000.0, "corner_tolerance": 0.01},
                   every_profile=True, stream=True)
    run, data = look_ahead(job)
    assert run.facts.stops == 1  # the reversal (the plunge's right angle into X10 is blended)
    corner = [0.0, 0.0, 2.0] if "Z2" in program else [10.0, 0.0, 0.0]  # the first block's end
    dim = run.dim
    k = int(np.argmin(np.linalg.norm(data[:, 4:4 + dim] - corner, axis=1)))
    assert np.linalg.norm(data[k, 4:4 + dim] - corner) <= 1e-9 and data[k, run.columns.index("v")] == 0.0


# --------------------------------------------------------------------------- random paths

@st.composite
def turning_lines(draw):
    """3-5 lines of 0.5-4 mm in 2-D or 3-D, each turning from the last by up to 180° (180° and near it often)."""
    dim = draw(st.sampled_from([2, 3]))
    rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
    count = draw(st.integers(2, 5))
    here = np.zeros(dim)
    heading = np.eye(dim)[0]
    points = [here.copy()]
    for i in range(count):
        if i:
            angle = math.radians(draw(st.one_of(st.floats(0.0, 180.0), st.sampled_from([90.0, 170.0, 178.8, 179.0,
                                                                                         179.9, 180.0]))))
            side = rng.normal(size=dim)
            side -= (side @ heading) * heading
            side /= np.linalg.norm(side)
            heading = math.cos(angle) * heading + math.sin(angle) * side
            heading /= np.linalg.norm(heading)
        here = here + draw(st.floats(0.5, 4.0)) * heading
        points.append(here.copy())
    return [tuple(float(c) for c in p) for p in points]


@settings(max_examples=25, deadline=None, database=None)
@given(turning_lines(), st.floats(0.005, 0.05))
def test_random_turns_keep_the_tolerance_both_ways(tmp_path_factory, points, tolerance):
    """Any turn up to 180° and any tolerance: blended within it both ways, or a stop (never an error)."""
    run, ticks = commanded(tmp_path_factory.mktemp("b"), line_job(points, tolerance))
    assert_two_sided(points, ticks, tolerance)


# --------------------------------------------------------------------------- taylor1 at tangent joints

@pytest.mark.parametrize("job_file", ["rounded-square.yaml", "pocket.yaml", "pocket.ngc", "path-3d.yaml"])
@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4"])
def test_no_step_across_a_tangent_joint_makes_up_the_lag(job_file, method):
    """Every step, junctions included, within STEP_FACTOR of the larger of its planned step and T·V_k (taylor1).

    On main taylor1 made up its whole ramp lag in the tick crossing a tangent joint of rounded-square:
    0.075 mm against 0.050 mm cruise steps (1.50x, the bound is 1.06x).  The steps that land on a stop
    (the plan at rest at their end) are left out, as the snap to the end point is: there every method
    lands on the stop itself, making up what its truncation error gathered since the last one."""
    run, data, u, S = run_all(load_cli(CURVES / job_file, overrides={"interpolator": method}))
    s = run.curve.arc_length_at(u)
    ds, dS = np.diff(s), np.diff(S)
    v = data[:, run.columns.index("v")]
    base = np.maximum(dS, run.period * v[:-1]) if method == "taylor1" else dS
    excess = ds - (STEP_FACTOR[method] * base + 1e-11 * (1.0 + run.length))
    excess[v[1:] == 0.0] = -np.inf  # onto a stop (the last step, the snap to the end point, among them)
    k = int(np.argmax(excess))
    assert excess[k] <= 0.0, f"tick {k} moved {ds[k]:.6g} mm where {base[k]:.6g} mm was planned " \
                             f"({ds[k] / base[k]:.4g}x)"


def test_rounded_square_largest_step_is_the_cruise_step():
    run, data, u, S = run_all(load_cli(CURVES / "rounded-square.yaml", overrides={"interpolator": "taylor1"}))
    ds = np.diff(run.curve.arc_length_at(u))[:-1]
    cruise = run.period * float(data[:, run.columns.index("v")].max())
    assert ds.max() <= STEP_FACTOR["taylor1"] * cruise, ds.max() / cruise


def test_a_cusp_in_a_path_is_named_by_its_block_and_its_own_parameter(tmp_path):
    """A nurbs block that turns straight back inside a span (a quadratic out to (1, 0) and back): the message names
    path.blocks[1] at its own u = 0.5, never the u = 1.5 of the joined curve (main said "insert a knot at u = 1.5")."""
    doc = {"path": {"start": [0, 1], "blocks": [{"line": {"to": [0, 0]}},
                                                {"nurbs": {"degree": 2, "control_points": [[0, 0], [1, 0], [0, 0]]}}]},
           "profile": {"type": "adaptive", "feedrate": FEED, "max_accel": 1000}}
    with pytest.raises(SpecError) as info:
        Interpolation(load_job(write(tmp_path, doc)))
    message = str(info.value)
    assert "path.blocks[1]" in message and "u = 0.5," in message and "1.5" not in message, message
