"""Hostile but valid jobs against the interpolators (issue 13, items 1, 2 and 4).

* No tick leaps across a knot where the parametric speed jumps (item 1): every
  tick's arc-length step is at most the method's stated factor of its planned
  step (:data:`nurbsinterp.interpolate.STEP_FACTOR`), on the issue's
  reproductions and on seeded random rational curves of degree 1–5 with C⁰/C¹
  knots, for every method and every profile.
* No first-tick leap on ramps far shorter than a period (item 2).
* The adaptive profile's stream holds every limit it names, checked by finite
  differences of the emitted commands (item 4).

The arc length of each step is the library's (tested against quadrature in
test_nurbs.py); the points are checked against the naive oracle.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import yaml
from hypothesis import given, settings, strategies as st

import oracle
from conftest import CIRCLE, random_curve_data
from nurbsinterp.interpolate import STEP_FACTOR, Interpolation
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli
from layout import one_curve

METHODS = ("taylor1", "taylor2", "rk4", "exact")
PERIOD = 1e-3


def write_job(tmp_path, curve: dict, profile: dict, method: str | None = None, period: str = "1 ms", name="job"):
    doc = {"curve": curve, "profile": profile, "interpolator": {"period": period}}
    if method is not None:
        doc["interpolator"]["method"] = method
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def execute(path, **overrides):
    run = Interpolation(load_cli(path, overrides=overrides))
    chunks = list(run.chunks())
    return run, one_curve(np.vstack([c.data for c in chunks])), np.concatenate([c.planned for c in chunks])


def step_excess(run, data, planned):
    """Each step's arc length over what STEP_FACTOR allows (<= 0 everywhere when the promise holds).

    The last step (the snap to the end point, reported as the end gap) is left out.
    """
    s = run.curve.arc_length_at(data[:, 2])
    ds, dS = np.diff(s), np.diff(planned)
    base = dS
    if run.method == "taylor1":
        # Eq. 8 steps by V_k alone: it lags the plan by T²A/2 in a ramp, and makes it up
        # on the way down (T·V_k > ΔS_k while decelerating), by design
        base = np.maximum(dS, run.period * data[:-1, -2])
    # plus the rounding of s(u) along the path (1e-11 of its length)
    allowed = STEP_FACTOR[run.method] * base + 1e-11 * (1.0 + run.length)
    return (ds - allowed)[:-1], ds, base


def assert_no_leap(run, data, planned):
    excess, ds, base = step_excess(run, data, planned)
    k = int(np.argmax(excess))
    assert excess[k] <= 0.0, (f"{run.method}: tick {k} moved {ds[k]:.6g} mm where {base[k]:.6g} mm was planned "
                              f"({ds[k] / base[k]:.4g}x, allowed {STEP_FACTOR[run.method]})")


# -- item 1: knots where the parametric speed jumps

JUMP = dict(degree=1, control_points=[[0, 0], [1, 0], [1, 100]], knots=[0, 0, 0.5, 1, 1])  # |P'| 2 -> 200 at 0.5
TRAPEZOID = {"type": "trapezoidal", "feedrate": "100 mm/s", "accel_time": "0.1 s"}


@pytest.mark.parametrize("method", METHODS)
def test_no_leap_where_the_parametric_speed_jumps_100_fold(tmp_path, method):
    run, data, planned = execute(write_job(tmp_path, JUMP, TRAPEZOID, method))
    assert_no_leap(run, data, planned)


@pytest.mark.parametrize("method", METHODS)
def test_no_leap_next_to_a_heavy_weight(tmp_path, method):
    heavy = dict(degree=1, control_points=[[0, 0], [10, 0], [10, 10], [0, 10], [0, 20]],
                 weights=[1, 1, 2321, 1, 1], knots=[0, 0, 0.25, 0.5, 0.75, 1, 1])
    run, data, planned = execute(write_job(tmp_path, heavy, TRAPEZOID, method))
    assert_no_leap(run, data, planned)


# -- item 2: ramps far shorter than a period

@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("ramp", [{"type": "trapezoidal", "accel_time": "1 ns"},
                                  {"type": "trapezoidal", "accel_time": "10 us"},
                                  {"type": "bell", "accel_time": "10 us"},
                                  {"type": "exponential", "time_constant": "10 us"}],
                         ids=["trap-1ns", "trap-10us", "bell-10us", "exp-10us"])
def test_no_first_tick_leap_on_a_short_ramp(tmp_path, method, ramp):
    run, data, planned = execute(write_job(tmp_path, CIRCLE, {"feedrate": "100 mm/s", **ramp}, method))
    assert_no_leap(run, data, planned)
    # the run really moves along the circle with the plan: it reaches the end point no
    # earlier than a tick before the plan does (the plan's own tail may crawl the last nm)
    b = run.curve.domain[1]
    first = np.flatnonzero(data[:, 2] == b)[0]
    assert run.length - planned[first] <= 2 * run.period * 100.0


# -- the property: random rational curves with C0/C1 knots, every method and profile

PROFILES = {
    "trapezoidal": {"type": "trapezoidal", "feedrate": "100 mm/s", "accel_time": "0.05 s"},
    "bell": {"type": "bell", "feedrate": "100 mm/s", "accel_time": "0.05 s"},
    "exponential": {"type": "exponential", "feedrate": "100 mm/s", "time_constant": "0.02 s"},
    "adaptive": {"type": "adaptive", "feedrate": "100 mm/s", "chord_tolerance": "1 um", "max_accel": "1000 mm/s^2",
                 "max_jerk": "30000 mm/s^3"},
}


def curve_dict(seed):
    cd = random_curve_data(seed)
    return cd, dict(degree=int(cd.p), control_points=cd.V.tolist(), weights=cd.W.tolist(), knots=cd.U.tolist())


@settings(max_examples=12)
@given(seed=st.integers(0, 10_000), method=st.sampled_from(METHODS), profile=st.sampled_from(sorted(PROFILES)))
def test_no_tick_leaps_on_random_curves(tmp_path_factory, seed, method, profile):
    cd, curve = curve_dict(seed)
    run, data, planned = execute(write_job(tmp_path_factory.mktemp("j"), curve, PROFILES[profile], method))
    assert_no_leap(run, data, planned)
    # every command is the curve's point at its own u (naive oracle), to 1e-9 mm
    pick = np.unique(np.linspace(0, len(data) - 1, 200).astype(int))
    ref = oracle.point(cd.U, cd.p, cd.V, cd.W, data[pick, 2])
    assert np.abs(data[pick, 3:3 + cd.V.shape[1]] - ref).max() <= 1e-9


@pytest.mark.parametrize("seed", [1, 7, 14, 15, 19])
@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4"])
def test_no_tick_leaps_on_the_seeds_that_showed_them(tmp_path, seed, method):
    """Seeds where main's taylor2 moved 2-71x its planned step at a C0 knot (issue 13)."""
    cd, curve = curve_dict(seed)
    run, data, planned = execute(write_job(tmp_path, curve, PROFILES["trapezoidal"], method))
    assert_no_leap(run, data, planned)


# -- item 4: the adaptive profile's limits, held by the emitted stream

def finite_differences(run, data):
    """|V|, |A|, |J| of the commanded motion along the path: differences of s(u_k) over T."""
    s = run.curve.arc_length_at(data[:, 2])
    T = run.period
    v = np.diff(s) / T
    return v, np.diff(v) / T, np.diff(v, 2) / T ** 2


def assert_limits_held(run, data, feed, accel, jerk):
    v, a, j = finite_differences(run, data)
    # rounding: s is known to ~1e-12 of the path; its third difference divides that by T³
    noise = 8 * 1e-12 * max(run.length, 1.0)
    assert v.max() <= feed * (1 + 1e-9) + noise / run.period
    assert np.abs(a).max() <= accel * (1 + 1e-9) + noise / run.period ** 2, np.abs(a).max()
    assert np.abs(j).max() <= jerk * (1 + 1e-9) + noise / run.period ** 3, np.abs(j).max()


def test_adaptive_profile_defaults_to_the_exact_interpolator(tmp_path):
    run, _, _ = execute(write_job(tmp_path, CIRCLE, PROFILES["adaptive"]))
    assert run.method == "exact"
    run, _, _ = execute(write_job(tmp_path, CIRCLE, PROFILES["trapezoidal"]))
    assert run.method == "taylor2"


@settings(max_examples=6)
@given(seed=st.integers(0, 10_000))
def test_adaptive_stream_holds_its_limits_on_random_curves(tmp_path_factory, seed):
    _, curve = curve_dict(seed)
    run, data, _ = execute(write_job(tmp_path_factory.mktemp("j"), curve, PROFILES["adaptive"]))
    assert_limits_held(run, data, 100.0, 1000.0, 30000.0)


def test_adaptive_stream_holds_its_limits_on_the_butterfly(tmp_path):
    from conftest import CURVES_DIR

    doc = yaml.safe_load((CURVES_DIR / "butterfly.yaml").read_text())
    run, data, _ = execute(write_job(tmp_path, doc["curve"], PROFILES["adaptive"]))
    assert_limits_held(run, data, 100.0, 1000.0, 30000.0)
    assert math.isclose(data[-1, 1], run.last_tick * run.period)


def _plan_summary(capsys, *args):
    from test_cli_contract import run_main

    code, _, err = run_main(capsys, "plan", *args)
    assert code in (0, None), err
    return err


def test_summary_says_which_interpolator_the_adaptive_profile_took(tmp_path, capsys):
    job = write_job(tmp_path, CIRCLE, PROFILES["adaptive"])
    err = _plan_summary(capsys, job, "-o", tmp_path / "run.csv")
    assert "exact (the adaptive profile's default" in err.splitlines()[0]
    err = _plan_summary(capsys, job, "--interpolator", "taylor2", "-o", tmp_path / "run.csv")
    assert "default" not in err.splitlines()[0]
    assert "this stream can exceed them" in err
