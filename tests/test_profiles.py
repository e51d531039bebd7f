"""Feedrate profiles planned before interpolation (REFERENCE.md §2).

Every expectation is written from the definitions, not from the code:
r(x) = x (trapezoidal), (1 − cos πx)/2 (bell), (1 − e^(−x·Ta/τ)) / (1 − e^(−Ta/τ))
(exponential, τ = Ta/4 unless given); V = Vp·r(t/Ta) up, Vp cruise, Vp·(1 − r(t'/Ta))
down; motion time L/Vp + Ta; peak lowered to L/Ta when L < Vp·Ta.  The calculus
(dS/dt = V, dV/dt = A) is checked against scipy's adaptive quadrature and a
five-point difference, with tolerances set by double precision, not by comfort.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad

from nurbsinterp.interpolate import Interpolation
from nurbsinterp.profiles import SHAPES, Profile, profile_for
from nurbsinterp.config import ProfileSpec, load_job
from nurbsinterp.cli.common import load_cli
from layout import one_curve

CURVES = Path(__file__).resolve().parent.parent / "curves"
CIRCLE_YAML = CURVES / "circle.yaml"
EPS = np.finfo(float).eps

# (L mm, Vp mm/s, Ta s, tau s or None): the paper's circle, the quintic wave's plan,
# odd numbers, a slow exponential (tau > Ta), and a path too short for full speed.
CASES = {
    "circle": (100.0 * math.pi, 100.0, 0.5, None),
    "quintic": (172.3748, 50.0, 0.2, 0.05),
    "odd": (1234.5, 333.3, 0.37, 0.3),
    "slow-tau": (80.0, 20.0, 0.25, 1.0),
    "short": (30.0, 100.0, 0.5, None),
}


# --------------------------------------------------------------------------- the definitions


def ratio(Ta, tau):
    return Ta / (Ta / 4.0 if tau is None else tau)


def r_def(shape, x, c=4.0):
    """r(x) as REFERENCE §2 writes it (plain exp, not the library's expm1)."""
    x = np.asarray(x, dtype=float)
    if shape == "trapezoidal":
        return x
    if shape == "bell":
        return (1.0 - np.cos(np.pi * x)) / 2.0
    return (1.0 - np.exp(-x * c)) / (1.0 - np.exp(-c))


def rprime_def(shape, x, c=4.0):
    x = np.asarray(x, dtype=float)
    if shape == "trapezoidal":
        return np.ones_like(x)
    if shape == "bell":
        return np.pi / 2.0 * np.sin(np.pi * x)
    return c * np.exp(-x * c) / (1.0 - np.exp(-c))


def max_slope(shape, c=4.0):
    """max r' on [0, 1]."""
    return {"trapezoidal": 1.0, "bell": np.pi / 2.0}.get(shape, c / (1.0 - math.exp(-c)))


def make(shape, case):
    L, Vp, Ta, tau = CASES[case]
    return Profile(shape, L, Vp, Ta, tau)


def S_at(prof, t):
    return float(prof.evaluate(np.array(t))[0])


def V_at(prof, t):
    return float(prof.evaluate(np.array(t))[1])


def A_at(prof, t):
    return float(prof.evaluate(np.array(t))[2])


ALL = [(s, c) for s in SHAPES for c in CASES]
IDS = [f"{s}-{c}" for s, c in ALL]


# --------------------------------------------------------------------------- end and motion time


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_distance_at_the_end_is_the_length_exactly(shape, case):
    prof = make(shape, case)
    L = CASES[case][0]
    S, V, A = prof.evaluate(np.array([prof.duration, prof.duration + 1e-3, prof.duration * 7.0]))
    assert (S == L).all()
    assert (V == 0.0).all() and (A == 0.0).all()
    # just before the end: never past the end
    before = np.nextafter(prof.duration, 0.0) - np.array([0.0, 1e-12, 1e-9, 1e-6])
    S, V, _ = prof.evaluate(before)
    assert (S <= L).all() and (S > L - 1e-6 * CASES[case][1]).all()


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_motion_time_is_length_over_peak_plus_accel_time(shape, case):
    L, Vp, Ta, _ = CASES[case]
    prof = make(shape, case)
    peak = min(Vp, L / Ta)
    assert prof.peak == pytest.approx(peak, rel=EPS)
    assert prof.duration == pytest.approx(L / peak + Ta, rel=2 * EPS)
    assert prof.decel_start == pytest.approx(prof.duration - Ta, abs=4 * EPS * prof.duration)


@pytest.mark.parametrize("shape", SHAPES)
def test_paper_circle_motion_time(shape):
    """Section 5.2: 100π mm at 100 mm/s with Ta = 0.5 s takes 3.6416 s (= π + 0.5)."""
    job = load_cli(CIRCLE_YAML, overrides={"profile_type": shape})
    run = Interpolation(job)
    assert run.length == pytest.approx(100.0 * math.pi, rel=1e-14)
    assert run.profile.duration == pytest.approx(3.641592653589793, rel=2 * EPS)
    assert Profile(shape, 100.0 * math.pi, 100.0, 0.5).duration == 3.641592653589793
    assert not run.profile.lowered and run.profile.peak == 100.0


# --------------------------------------------------------------------------- calculus


def _phase_points(prof):
    return sorted({0.0, prof.accel_time, prof.decel_start, prof.duration})


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_distance_is_the_integral_of_the_feedrate(shape, case):
    prof = make(shape, case)
    pts = _phase_points(prof)
    ts = np.linspace(0.0, prof.duration, 41)[1:]
    ts = np.concatenate([ts, pts[1:], [p + 1e-7 for p in pts[1:-1]]])
    for t in ts:
        inner = [p for p in pts if 0.0 < p < t]
        Q, err = quad(lambda s: V_at(prof, s), 0.0, t, points=inner or None, epsabs=0.0, epsrel=1e-13, limit=200)
        S = S_at(prof, t)
        assert abs(S - Q) <= 1e-12 * abs(Q) + 1e-13, (t, S, Q)


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_feedrate_is_the_integral_of_the_acceleration(shape, case):
    prof = make(shape, case)
    pts = _phase_points(prof)
    ts = np.linspace(0.0, prof.duration, 37)[1:]
    for t in ts:
        inner = [p for p in pts if 0.0 < p < t]
        Q, err = quad(lambda s: A_at(prof, s), 0.0, t, points=inner or None, epsabs=1e-13 * prof.peak, epsrel=1e-13, limit=200)
        dV = V_at(prof, t) - V_at(prof, 0.0)
        assert abs(dV - Q) <= 1e-11 * prof.peak, (t, dV, Q)


def _stencil(f, t, h):
    """Five-point central difference: error h⁴ f⁽⁵⁾/30."""
    return (f(t - 2 * h) - 8 * f(t - h) + 8 * f(t + h) - f(t + 2 * h)) / (12 * h)


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_derivatives_by_finite_differences(shape, case):
    """dS/dt = V and dV/dt = A pointwise, away from the phase boundaries."""
    prof = make(shape, case)
    Ta = prof.accel_time
    h = 5e-4 * Ta
    ts = np.linspace(0.0, prof.duration, 2001)
    pts = np.array(_phase_points(prof))
    ts = ts[np.min(np.abs(ts[:, None] - pts[None, :]), axis=1) > 3 * h]
    S = lambda t: prof.evaluate(t)[0]  # noqa: E731
    V = lambda t: prof.evaluate(t)[1]  # noqa: E731
    _, Vt, At = prof.evaluate(ts)
    c = ratio(Ta, CASES[case][3])
    a_scale = prof.peak / Ta * max_slope(shape, c)
    assert np.max(np.abs(_stencil(S, ts, h) - Vt)) <= 1e-9 * prof.peak
    assert np.max(np.abs(_stencil(V, ts, h) - At)) <= 1e-9 * a_scale


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_feedrate_is_continuous(shape, case):
    prof = make(shape, case)
    c = ratio(prof.accel_time, CASES[case][3])
    a_max = prof.peak / prof.accel_time * max_slope(shape, c)
    assert V_at(prof, 0.0) == 0.0
    for b in _phase_points(prof)[1:]:
        for d in (1e-12, 1e-9, 1e-6):
            left, right = V_at(prof, b - d), V_at(prof, b)
            assert abs(left - right) <= a_max * d * 1.001 + 8 * EPS * prof.peak, (b, d, left, right)
    assert V_at(prof, prof.duration) == 0.0


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_bounds_and_monotone_distance(shape, case):
    prof = make(shape, case)
    ts = np.concatenate([np.linspace(-0.1, prof.duration + 0.1, 20001),
                         [p + d for p in _phase_points(prof) for d in (-1e-12, 0.0, 1e-12)]])
    ts.sort()
    S, V, _ = prof.evaluate(ts)
    assert np.isfinite(S).all() and np.isfinite(V).all()
    assert (V >= 0.0).all() and (V <= prof.peak).all()
    assert (S >= 0.0).all() and (S <= prof.length).all()
    assert (np.diff(S) >= 0.0).all()
    assert V.max() == pytest.approx(prof.peak, rel=1e-12)


# --------------------------------------------------------------------------- shapes


@pytest.mark.parametrize("shape,case", ALL, ids=IDS)
def test_ramps_follow_the_shape_function(shape, case):
    L, Vp, Ta, tau = CASES[case]
    prof = make(shape, case)
    c = ratio(Ta, tau)
    Vp = prof.peak
    x = np.linspace(0.0, 1.0, 1001)[:-1]
    _, V, A = prof.evaluate(x * Ta)
    assert np.max(np.abs(V - Vp * r_def(shape, x, c))) <= 16 * EPS * Vp
    assert np.max(np.abs(A - Vp * rprime_def(shape, x, c) / Ta)) <= 64 * EPS * Vp * max_slope(shape, c) / Ta
    # deceleration mirrors acceleration in velocity
    _, V, A = prof.evaluate(prof.decel_start + x * Ta)
    assert np.max(np.abs(V - Vp * (1.0 - r_def(shape, x, c)))) <= 16 * EPS * Vp * max(1.0, prof.duration / Ta)
    assert np.max(np.abs(A + Vp * rprime_def(shape, x, c) / Ta)) <= 64 * EPS * Vp * max_slope(shape, c) / Ta
    if prof.decel_start > Ta:  # a cruise
        _, V, A = prof.evaluate(np.linspace(Ta, prof.decel_start, 101)[:-1])
        assert (V == Vp).all() and (A == 0.0).all()


def test_shape_endpoints_and_acceleration_jumps():
    """r(0) = 0, r(1) = 1; bell starts with A = 0, the exponential with a jump (as the classical one does)."""
    L, Vp, Ta = 100.0 * math.pi, 100.0, 0.5
    for shape in SHAPES:
        prof = Profile(shape, L, Vp, Ta)
        assert V_at(prof, 0.0) == 0.0 and V_at(prof, Ta) == Vp
    assert A_at(Profile("bell", L, Vp, Ta), 0.0) == 0.0
    assert A_at(Profile("trapezoidal", L, Vp, Ta), 0.0) == pytest.approx(Vp / Ta, rel=EPS)
    exp = Profile("exponential", L, Vp, Ta)
    jump = Vp * 4.0 / (Ta * (1.0 - math.exp(-4.0)))
    assert A_at(exp, 0.0) == pytest.approx(jump, rel=1e-14)
    assert A_at(exp, exp.decel_start) == pytest.approx(-jump, rel=1e-14)
    assert A_at(exp, np.nextafter(exp.decel_start, 0.0)) == 0.0


@pytest.mark.parametrize("tau", [None, 0.125, 0.05, 0.3, 2.0])
def test_exponential_time_constant_default_and_settable(tau):
    L, Vp, Ta = 100.0 * math.pi, 100.0, 0.5
    prof = Profile("exponential", L, Vp, Ta, tau)
    expected_tau = Ta / 4.0 if tau is None else tau
    assert prof.time_constant == pytest.approx(expected_tau, rel=EPS)
    x = np.linspace(0.0, 1.0, 257)
    V = prof.evaluate(x * Ta)[1]
    assert np.max(np.abs(V - Vp * r_def("exponential", x, Ta / expected_tau))) <= 16 * EPS * Vp
    # the default is tau = Ta/4, i.e. the same profile as an explicit 0.125 s
    if tau is None:
        assert np.array_equal(V, Profile("exponential", L, Vp, Ta, 0.125).evaluate(x * Ta)[1])


@pytest.mark.parametrize("override,tau", [(None, 0.125), ("50 ms", 0.05), ("0.3", 0.3)])
def test_job_time_constant_reaches_the_profile(override, tau):
    job = load_cli(CIRCLE_YAML, overrides={"profile_type": "exponential", "time_constant": override})
    prof = Interpolation(job).profile
    assert prof.time_constant == pytest.approx(tau, rel=EPS)
    x = np.linspace(0.0, 1.0, 65)
    V = prof.evaluate(x * 0.5)[1]
    assert np.max(np.abs(V - 100.0 * r_def("exponential", x, 0.5 / tau))) <= 16 * EPS * 100.0


def test_profile_for_uses_the_spec():
    spec = ProfileSpec(type="bell", feedrate=50.0, accel_time=0.2)
    prof = profile_for(spec, 40.0)
    assert (prof.peak, prof.accel_time, prof.duration) == (50.0, 0.2, pytest.approx(40.0 / 50.0 + 0.2, rel=EPS))
    const = profile_for(spec, 40.0, constant=True)
    assert const.accel_time == 0.0 and const.duration == pytest.approx(0.8, rel=EPS)


# --------------------------------------------------------------------------- short paths, no ramps


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("L", [30.0, 1e-3, 49.999999])
def test_short_path_lowers_the_peak(shape, L):
    Vp, Ta = 100.0, 0.5
    prof = Profile(shape, L, Vp, Ta)
    assert prof.lowered
    assert prof.peak == pytest.approx(L / Ta, rel=EPS)
    assert prof.duration == pytest.approx(2 * Ta, rel=2 * EPS)
    ts = np.linspace(0.0, prof.duration, 4001)
    S, V, _ = prof.evaluate(ts)
    assert V.max() == pytest.approx(L / Ta, rel=1e-12) and (V <= prof.peak).all()
    assert S_at(prof, prof.duration) == L
    assert (np.diff(S) >= 0).all()


@pytest.mark.parametrize("shape", SHAPES)
def test_path_of_exactly_feedrate_times_accel_time_is_not_lowered(shape):
    prof = Profile(shape, 50.0, 100.0, 0.5)
    assert not prof.lowered and prof.peak == 100.0
    assert prof.duration == pytest.approx(1.0, rel=2 * EPS)
    assert S_at(prof, prof.duration) == 50.0


@pytest.mark.parametrize("shape", SHAPES)
def test_short_job_through_the_interpolator(shape, tmp_path):
    """A 30 mm line at 100 mm/s with Ta = 0.5 s: peak 60 mm/s, 1 s of motion, 1001 ticks."""
    path = tmp_path / "line.yaml"
    path.write_text("curve:\n  degree: 1\n  control_points: [[0, 0], [30, 0]]\n"
                    f"profile: {{type: {shape}, feedrate: 100, accel_time: 0.5}}\n"
                    "interpolator: {method: exact, period: 1 ms}\n")
    run = Interpolation(load_job(path))
    assert run.profile.lowered and run.profile.peak == pytest.approx(60.0, rel=EPS)
    assert run.profile.duration == pytest.approx(1.0, rel=2 * EPS)
    chunks = list(run.chunks())
    data = one_curve(np.vstack([c.data for c in chunks]))
    assert data.shape[0] == 1001
    assert data[:, -2].max() == pytest.approx(60.0, rel=1e-12)
    assert chunks[-1].planned[-1] == run.length
    assert data[-1, 3] == 30.0 and data[-1, 4] == 0.0


@pytest.mark.parametrize("shape", SHAPES)
def test_zero_accel_time_is_constant_feed(shape):
    L, Vp = 100.0 * math.pi, 100.0
    prof = Profile(shape, L, Vp, 0.0)
    assert not prof.lowered
    assert prof.duration == pytest.approx(L / Vp, rel=EPS)
    ts = np.linspace(0.0, prof.duration, 1001)[:-1]
    S, V, A = prof.evaluate(ts)
    assert (V == Vp).all() and (A == 0.0).all()
    assert np.max(np.abs(S - Vp * ts)) <= 4 * EPS * L
    assert S_at(prof, prof.duration) == L and V_at(prof, prof.duration) == 0.0


@pytest.mark.parametrize("shape", SHAPES)
def test_zero_accel_time_job_has_constant_feed(shape):
    job = load_cli(CIRCLE_YAML, overrides={"profile_type": shape, "accel_time": 0})
    data = one_curve(np.vstack([c.data for c in Interpolation(job).chunks()]))
    assert data.shape[0] == math.ceil(math.pi / 1e-3) + 1  # K = ceil(L/Vp / T)
    assert (data[:-1, -2] == 100.0).all() and (data[:-1, -1] == 0.0).all()
    assert data[-1, -2] == 0.0


def test_zero_length_and_bad_arguments():
    prof = Profile("bell", 0.0, 100.0, 0.5)
    assert prof.duration == 0.0
    S, V, A = prof.evaluate(np.array([0.0, 1.0]))
    assert (S == 0).all() and (V == 0).all() and (A == 0).all()
    for args in [("bell", -1.0, 100.0, 0.5), ("bell", 1.0, 0.0, 0.5), ("bell", 1.0, -5.0, 0.5),
                 ("bell", 1.0, 100.0, -0.1), ("parabolic", 1.0, 100.0, 0.5),
                 ("bell", float("nan"), 100.0, 0.5)]:
        with pytest.raises(ValueError):
            Profile(*args)


def test_evaluate_keeps_the_shape_of_t():
    prof = Profile("bell", 100.0, 50.0, 0.3)
    for t in (np.array(0.4), np.linspace(0, 1, 6), np.linspace(0, 1, 12).reshape(3, 4)):
        S, V, A = prof.evaluate(t)
        assert S.shape == V.shape == A.shape == np.shape(t)
    S, V, A = prof.evaluate(np.array([-1.0, -1e-12]))
    assert (S == 0).all() and (V == 0).all() and (A == 0).all()
