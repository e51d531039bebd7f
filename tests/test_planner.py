"""The limit-aware feedrate planner (issue 7: the ``adaptive`` profile).

Everything is checked on what a controller would command, not on the planner's
own bookkeeping: the plan is sampled at the ticks k·T, the commanded points are
P(u(S(kT))) (curve.parameter_at, then evaluate), and the limits are recomputed
here from the curve's derivatives:

* chord error of each tick: the largest distance from the curve between two
  consecutive commands to their chord, by 16 samples of the arc;
* the feed limit V_lim = min(F, (2/T)√(2ρδ − δ²), √(A_n ρ), v_i/|τ_i|) with ρ from
  |C'×C''|/|C'|³, on a dense grid of the test's own (not the planner's) and at
  every curvature maximum;
* per-axis velocities and accelerations as first and second differences of the
  commanded positions;
* the time-optimal motion time without a jerk limit by a brute-force scan on a
  fine uniform arc-length grid.

Tolerances.  A first difference over one tick is the mean of the derivative
over that tick, and a second difference is its hat-weighted mean over two
ticks, so finite differences of a plan that keeps |A| <= A_max (or |a_i| <= a_i)
keep the same bound with no discretisation term: their error against the
pointwise value is O(T²·jerk) (O(T·ΔJ) where the jerk jumps), but a mean never
exceeds the maximum.  What is left is rounding: commanded positions are exact
to ~1e-13 mm (parameter_at), ~1e-7 mm/s² after dividing by T² = 1e-6 s², so
axis limits are checked to 1e-6 relative plus 1e-4 (mm/s or mm/s²) absolute.
The planner keeps a 1e-9 relative margin on every cap, so the table's
accelerations and jerks are checked to 1e-9 relative, and V <= V_lim to 1e-6
(the inversion S -> t adds ~1e-9 mm/s).  The chord error is limited through the
circle formula at each point while a tick spans a stretch of varying
curvature and feedrate: it is checked to 1 %.  Every check also asserts that
its limit is actually reached somewhere, so that a plan slack everywhere (or a
check that measures nothing) cannot pass.
"""
from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from numba import njit

from nurbsinterp.nurbs import NurbsCurve
from nurbsinterp.planner import LIMITS, AdaptivePlan, adaptive_at, plan_adaptive
from nurbsinterp.profiles import Profile
from nurbsinterp.config import load_job

CURVES = Path(__file__).resolve().parent.parent / "curves"
T = 1e-3  # s
F = 100.0  # mm/s
DELTA = 1e-3  # mm (1 µm)
A_MAX = 1000.0  # mm/s²
J_MAX = 30000.0  # mm/s³
AXES = {"x": {"max_velocity": 60.0, "max_accel": 800.0}, "y": {"max_velocity": 60.0, "max_accel": 800.0}}

TABLE_RTOL = 1e-9
VLIM_RTOL = 1e-6
AXIS_RTOL, AXIS_ATOL = 1e-6, 1e-4
CHORD_RTOL = 0.01


# --------------------------------------------------------------------------- the curves and plans under test


@functools.lru_cache(maxsize=None)
def curve_file(name: str) -> NurbsCurve:
    return NurbsCurve.from_spec(load_job(CURVES / name).curve)


def butterfly() -> NurbsCurve:
    return curve_file("butterfly.yaml")


def random_cubic(seed: int) -> NurbsCurve:
    """A clamped cubic NURBS nobody on the team wrote: 14 random control points in a 100 mm square."""
    rng = np.random.default_rng(seed)
    n = 14
    cps = rng.uniform(0.0, 100.0, (n, 2))
    w = rng.uniform(0.5, 2.0, n)
    inner = np.sort(rng.uniform(0.05, 0.95, n - 4))
    knots = np.concatenate([[0.0] * 4, inner, [1.0] * 4])
    return NurbsCurve(3, cps, w, knots)


BUTTERFLY = dict(feedrate=F, chord_tolerance=DELTA, max_accel=A_MAX, max_jerk=J_MAX)
#: plans without a jerk limit, checked against a brute-force optimum
NO_JERK = {
    "chord": dict(feedrate=F, chord_tolerance=DELTA, max_accel=A_MAX),
    "normal+axis": dict(feedrate=F, chord_tolerance=DELTA, max_accel=A_MAX, max_normal_accel=5000.0,
                        axes={"x": {"max_velocity": 80.0}}),
}
#: two sets of limits for the random curves: the chord tolerance binds in the first; in the
#: second the axis budgets do (for ρ >> δ the chord limit is a centripetal limit of 8δ/T²)
RANDOM_LIMITS = {
    "chord": dict(feedrate=80.0, chord_tolerance=1e-3, max_accel=1000.0, max_jerk=30000.0,
                  axes={"x": {"max_velocity": 60.0}}),
    "axes": dict(feedrate=80.0, chord_tolerance=2e-3, max_accel=800.0, max_jerk=20000.0, max_normal_accel=3000.0,
                 axes={"x": {"max_velocity": 50.0, "max_accel": 600.0},
                       "y": {"max_velocity": 70.0, "max_accel": 900.0}}),
}
#: the bundled curves, each at its own period, with every kind of limit (z where there is a z)
FILE_LIMITS = dict(feedrate=100.0, chord_tolerance=5e-4, max_accel=1500.0, max_jerk=40000.0,
                   max_normal_accel=3000.0,
                   axes={"x": {"max_velocity": 70.0, "max_accel": 900.0},
                         "y": {"max_velocity": 70.0, "max_accel": 900.0},
                         "z": {"max_velocity": 30.0, "max_accel": 400.0}})


@functools.lru_cache(maxsize=None)
def plan(name: str) -> AdaptivePlan:
    if name == "butterfly":
        return plan_adaptive(butterfly(), T, **BUTTERFLY)
    if name == "butterfly-axes":
        return plan_adaptive(butterfly(), T, **BUTTERFLY, axes=AXES)
    return plan_adaptive(butterfly(), T, **NO_JERK[name])


@functools.lru_cache(maxsize=None)
def random_plan(seed: int, limits: str) -> tuple[NurbsCurve, AdaptivePlan]:
    c = random_cubic(seed)
    return c, plan_adaptive(c, T, **RANDOM_LIMITS[limits])


# --------------------------------------------------------------------------- independent measures


def ticks(p: AdaptivePlan):
    """(t, S, V, A) at the ticks k·T, k = 0..K."""
    K = round(p.duration / p.period)
    t = np.arange(K + 1) * p.period
    return (t, *p.evaluate(t))


def commanded(curve: NurbsCurve, S: np.ndarray):
    u = curve.parameter_at(S)
    return u, curve.evaluate(u)


def chord_errors(curve: NurbsCurve, u: np.ndarray, pts: np.ndarray, samples: int = 16) -> np.ndarray:
    """Largest distance of the arc between consecutive commands from their chord, per tick."""
    frac = np.linspace(0.0, 1.0, samples + 1)
    uu = u[:-1, None] + (u[1:] - u[:-1])[:, None] * frac[None, :]
    arc = curve.evaluate(uu.ravel()).reshape(uu.shape + (curve.dim,))
    a, b = pts[:-1], pts[1:]
    d = b - a
    length = np.linalg.norm(d, axis=1)
    w = arc - a[:, None, :]
    along = np.einsum("kmd,kd->km", w, d) / np.maximum(length, 1e-300)[:, None] ** 2
    foot = a[:, None, :] + along[..., None] * d[:, None, :]
    return np.linalg.norm(arc - foot, axis=-1).max(axis=1)


def feed_limit(curve: NurbsCurve, u, period, *, feedrate, chord_tolerance=None, max_normal_accel=None, axes=None,
               **_other):
    """V_lim from the definitions (no centripetal axis term: that one is checked on the axes)."""
    d = curve.derivatives(u, 2)
    d1, d2 = d[:, 1, :], d[:, 2, :]
    speed = np.linalg.norm(d1, axis=1)
    if curve.dim == 2:
        cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    else:
        cross = np.linalg.norm(np.cross(d1, d2), axis=1)
    rho = speed ** 3 / np.maximum(cross, 1e-300)
    v = np.full(u.shape, float(feedrate))
    if chord_tolerance is not None:
        dl = chord_tolerance
        v = np.minimum(v, 2.0 / period * np.sqrt(np.maximum(2.0 * rho * dl - dl ** 2, 0.0)))
    if max_normal_accel is not None:
        v = np.minimum(v, np.maximum(np.sqrt(max_normal_accel * rho), max_normal_accel * period / 2.0))
    for i, name in enumerate("xyz"[: curve.dim]):
        vmax = ((axes or {}).get(name) or {}).get("max_velocity")
        if vmax is not None:
            v = np.minimum(v, vmax * speed / np.maximum(np.abs(d1[:, i]), 1e-300))
    return v


def v_at_s(p: AdaptivePlan, s: np.ndarray) -> np.ndarray:
    """The plan's feedrate where it passes arc length s: S(t) = s inverted by interpolation plus Newton."""
    tg = np.linspace(0.0, p.duration, round(p.duration / p.period) * 8 + 1)
    Sg = p.evaluate(tg)[0]
    t = np.interp(s, Sg, tg)
    for _ in range(4):
        S, V, _ = p.evaluate(t)
        t = np.clip(t - (S - s) / np.maximum(V, 1e-3), 0.0, p.duration)
    return p.evaluate(t)[1]


def dense_u(curve: NurbsCurve, per_span: int) -> np.ndarray:
    u = [np.linspace(a, b, per_span + 1) for _, a, b in curve.span_ranges()]
    return np.unique(np.concatenate(u))


def axis_rates(curve: NurbsCurve, p: AdaptivePlan):
    """Per-axis velocities and accelerations of the commanded positions by finite differences."""
    _, S, _, _ = ticks(p)
    _, pts = commanded(curve, S)
    return np.diff(pts, axis=0) / p.period, np.diff(pts, 2, axis=0) / p.period ** 2


def check_axes(curve, p, axes):
    """Assert the axis limits; returns {'xv': max |v_x| / limit, 'xa': ...} for the limits given."""
    vel, acc = axis_rates(curve, p)
    worst = {}
    for i, name in enumerate("xyz"[: curve.dim]):
        lim = axes.get(name, {})
        for key, rates, tag in (("max_velocity", vel, "v"), ("max_accel", acc, "a")):
            if lim.get(key) is not None:
                top = np.abs(rates[:, i]).max()
                assert top <= lim[key] * (1 + AXIS_RTOL) + AXIS_ATOL, (name, key, top)
                worst[name + tag] = top / lim[key]
    return worst


def check_plan(curve: NurbsCurve, p: AdaptivePlan, limits: dict, per_span: int = 1500):
    """Every limit on the commanded motion; returns the largest ratio to its limit of each measure."""
    T_ = p.period
    worst = {}
    K = p.duration / T_
    assert abs(K - round(K)) < 1e-9
    t, S, V, A = ticks(p)
    assert S[-1] == curve.length and V[-1] == 0.0 and A[-1] == 0.0
    assert np.all(np.diff(S) >= 0.0) and np.all(V >= 0.0)
    u, pts = commanded(curve, S)
    if limits.get("chord_tolerance") is not None:
        worst["chord"] = chord_errors(curve, u, pts).max() / limits["chord_tolerance"]
        assert worst["chord"] <= 1 + CHORD_RTOL
    seg = p.segments
    dur = np.diff(seg[:, 0])
    assert np.all(dur > 0.0)
    if limits.get("max_accel") is not None:
        a_end = seg[:-1, 3] + seg[:-1, 4] * dur  # A is linear on each piece: its ends bound it
        worst["accel"] = max(np.abs(seg[:, 3]).max(), np.abs(a_end).max()) / limits["max_accel"]
        assert worst["accel"] <= 1 + TABLE_RTOL
        assert np.abs(np.diff(V)).max() / T_ <= limits["max_accel"] * (1 + TABLE_RTOL) + 1e-6
    if limits.get("max_jerk") is not None:
        worst["jerk"] = np.abs(seg[:, 4]).max() / limits["max_jerk"]
        assert worst["jerk"] <= 1 + TABLE_RTOL
        assert np.abs(np.diff(V, 2)).max() / T_ ** 2 <= limits["max_jerk"] * (1 + TABLE_RTOL) + 1e-3
    worst.update(check_axes(curve, p, limits.get("axes") or {}))
    ud = np.concatenate([dense_u(curve, per_span), [uk for _, uk in curve.curvature_maxima(per_span=128)]])
    ratio = v_at_s(p, curve.arc_length_at(ud)) / feed_limit(curve, ud, T_, **limits)
    worst["v_limit"] = ratio.max()
    assert worst["v_limit"] <= 1 + VLIM_RTOL, f"V/V_lim = {ratio.max()} at u = {ud[ratio.argmax()]}"
    return worst


# --------------------------------------------------------------------------- the butterfly (F, δ, A, J)


def test_butterfly_keeps_every_limit():
    worst = check_plan(butterfly(), plan("butterfly"), BUTTERFLY, per_span=2000)
    # each limit is reached, not merely respected
    assert worst["chord"] > 0.95 and worst["accel"] > 0.99 and worst["jerk"] > 0.99 and worst["v_limit"] > 0.999


def test_ends_on_a_tick_at_the_end_of_the_curve():
    p = plan("butterfly")
    c = butterfly()
    K = p.duration / T
    assert abs(K - round(K)) < 1e-9
    assert p.ticks() == round(K)
    assert p.length == c.length
    S, V, A = p.evaluate(np.array([p.duration, p.duration + 1.0]))
    assert S[0] == c.length and S[1] == c.length  # exactly, not approximately
    assert np.all(V == 0.0) and np.all(A == 0.0)
    assert p.evaluate(0.0) == (0.0, 0.0, 0.0)
    assert p.stretch >= 1.0 and p.stretch - 1.0 < T / p.duration * 1.000001  # one tick at most
    # the last piece lands on the end: S, V, A of its cubic at the end
    seg = p.segments
    tau = seg[-1, 0] - seg[-2, 0]
    s0, v0, a0, j = seg[-2, 1:]
    assert s0 + v0 * tau + a0 * tau ** 2 / 2 + j * tau ** 3 / 6 == pytest.approx(c.length, abs=1e-9)
    assert abs(v0 + a0 * tau + j * tau ** 2 / 2) < 1e-6 and abs(a0 + j * tau) < 1e-3


def test_chord_check_detects_a_plain_profile():
    """The same measure fails on a constant-feed trapezoidal plan (~54 µm at the sharpest turn)."""
    c = butterfly()
    prof = Profile("trapezoidal", c.length, F, 0.1)
    K = prof.ticks(T)
    S = prof.evaluate(np.arange(K + 1) * T)[0]
    u, pts = commanded(c, S)
    assert chord_errors(c, u, pts).max() > 20 * DELTA


def test_continuity_of_the_segment_table():
    p = plan("butterfly")
    seg = p.segments
    dur = np.diff(seg[:, 0])
    s0, v0, a0, j = seg[:-1, 1], seg[:-1, 2], seg[:-1, 3], seg[:-1, 4]
    s1 = s0 + v0 * dur + a0 * dur ** 2 / 2 + j * dur ** 3 / 6
    v1 = v0 + a0 * dur + j * dur ** 2 / 2
    a1 = a0 + j * dur
    assert np.abs(s1 - seg[1:, 1]).max() < 1e-9
    assert np.abs(v1 - seg[1:, 2]).max() < 1e-7
    assert np.abs(a1[:-1] - seg[1:-1, 3]).max() < 1e-5  # jerk-limited: A is continuous


def test_interface_and_adaptive_at():
    p, c = plan("butterfly"), butterfly()
    assert p.segments.shape[1] == 5 and p.segments.dtype == np.float64 and not p.segments.flags.writeable
    assert p.segments[0, 0] == 0.0 and np.all(np.diff(p.segments[:, 0]) > 0)
    assert list(p.segments[-1]) == [p.duration, c.length, 0.0, 0.0, 0.0]
    t = np.array([-1.0, 0.0, 0.123456, 1.0, p.duration * 0.5, p.duration - 1e-9, p.duration, 99.0])
    S, V, A = p.evaluate(t)
    for k, tk in enumerate(t):
        assert adaptive_at(p.segments, tk) == (S[k], V[k], A[k])
    assert (S[0], V[0], A[0]) == (0.0, 0.0, 0.0)
    assert S[-1] == c.length
    assert p.evaluate(np.zeros((2, 3)))[0].shape == (2, 3)

    @njit
    def from_flat(flat, ts):  # as a per-tick kernel would hold it: one flat float64 vector
        seg = flat.reshape(-1, 5)
        out = np.empty(ts.shape[0])
        for i in range(ts.shape[0]):
            out[i] = adaptive_at(seg, ts[i])[0]
        return out

    assert np.array_equal(from_flat(p.segments.ravel().copy(), t), S)
    # the plan's own evaluate agrees with integrating V (trapezoid rule on a fine grid)
    tt = np.linspace(0.0, p.duration, 400001)
    SS, VV, _ = p.evaluate(tt)
    integ = np.concatenate([[0.0], np.cumsum((VV[1:] + VV[:-1]) / 2 * np.diff(tt))])
    assert np.abs(integ - SS).max() < 1e-6
    assert p.peak == pytest.approx(VV.max(), rel=1e-6)


def test_report_data():
    p = plan("butterfly")
    frac = p.limit_fractions
    assert set(frac) == set(LIMITS)
    assert sum(frac.values()) == pytest.approx(1.0, abs=1e-12)
    assert frac["chord"] > 0 and frac["feedrate"] > 0.5
    assert frac["normal_accel"] == frac["axis_velocity"] == frac["axis_accel"] == 0.0
    assert p.slowest.limit == "chord" and p.slowest.v == p.v_limit.min()
    c = butterfly()
    # the sharpest turn: V_lim there is the chord limit at the minimum radius of curvature
    rho, u_min = c.min_radius()
    assert p.slowest.v == pytest.approx(2 / T * math.sqrt(2 * rho * DELTA - DELTA ** 2), rel=1e-6)
    assert p.slowest.u == pytest.approx(u_min, abs=1e-6)
    assert p.s_grid.shape == p.v_limit.shape == p.binding.shape == p.a_limit.shape
    assert np.all(np.diff(p.s_grid) >= 0)


# --------------------------------------------------------------------------- per-axis limits


def test_axis_limits_on_the_butterfly():
    p, c = plan("butterfly-axes"), butterfly()
    worst = check_plan(c, p, {**BUTTERFLY, "axes": AXES})
    assert max(worst["xv"], worst["yv"]) > 0.99  # the velocity limits bind
    assert max(worst["xa"], worst["ya"]) > 0.99  # and so do the acceleration limits
    assert p.limit_fractions["axis_velocity"] > 0.3 and p.limit_fractions["axis_accel"] > 0.1
    assert p.duration > plan("butterfly").duration
    # the tangential bound is lowered where the centripetal part takes its share
    assert p.accel_bound < 800.0 and np.all(p.a_limit <= A_MAX)


# --------------------------------------------------------------------------- time-optimal without jerk


def brute_force_time(curve, n, *, feedrate, max_accel, **limits):
    """Motion time of the acceleration-limited optimum on a uniform arc-length grid of n intervals."""
    s = np.linspace(0.0, curve.length, n + 1)
    u = curve.parameter_at(s)
    vlim = feed_limit(curve, u, T, feedrate=feedrate, **limits)
    ds = s[1] - s[0]
    v2 = vlim ** 2
    v2[0] = v2[-1] = 0.0
    reach = 2.0 * max_accel * ds
    for i in range(n):  # forward: accelerate at most max_accel
        v2[i + 1] = min(v2[i + 1], v2[i] + reach)
    for i in range(n - 1, -1, -1):  # backward: decelerate at most max_accel
        v2[i] = min(v2[i], v2[i + 1] + reach)
    v = np.sqrt(v2)
    return float(np.sum(2.0 * ds / (v[:-1] + v[1:])))


@pytest.mark.parametrize("name", sorted(NO_JERK))
def test_without_jerk_the_plan_is_time_optimal(name):
    p, c = plan(name), butterfly()
    limits = NO_JERK[name]
    reference = brute_force_time(c, 100000, **limits)
    motion = p.duration / p.stretch  # before the stretch onto a tick
    assert abs(motion - reference) <= 0.01 * reference, (motion, reference)
    assert np.all(p.segments[:, 4] == 0.0)
    worst = check_plan(c, p, limits, per_span=1000)
    assert worst["accel"] > 0.99 and worst["v_limit"] > 0.999
    assert p.limit_fractions["chord" if name == "chord" else "normal_accel"] > 0


# --------------------------------------------------------------------------- other curves


@pytest.mark.parametrize("limits", sorted(RANDOM_LIMITS))
@pytest.mark.parametrize("seed", [3, 11, 2024])
def test_random_cubic_keeps_every_limit(seed, limits):
    c, p = random_plan(seed, limits)
    worst = check_plan(c, p, RANDOM_LIMITS[limits])
    assert worst["jerk"] > 0.99 and worst["v_limit"] > 0.999
    if limits == "chord":  # the tolerance is what slows the sharpest turn
        assert p.limit_fractions["chord"] > 0 and worst["chord"] > 0.9
    else:
        assert max(worst["xa"], worst["ya"]) > 0.99


@pytest.mark.parametrize("name", ["circle.yaml", "quintic-wave.yaml", "tilted-circle-3d.yaml", "butterfly.yaml"])
def test_bundled_curves_keep_every_limit(name):
    c = curve_file(name)
    period = load_job(CURVES / name).interpolator.period
    p = plan_adaptive(c, period, **FILE_LIMITS)
    assert p.sections == 1  # the double knots of the circles and the wave are not corners
    worst = check_plan(c, p, FILE_LIMITS, per_span=4000 // len(c.span_ranges()))
    assert worst["jerk"] > 0.99


def test_jerk_without_an_acceleration_limit():
    c = random_cubic(5)
    limits = dict(feedrate=80.0, chord_tolerance=1e-3, max_jerk=20000.0)
    p = plan_adaptive(c, T, **limits)
    worst = check_plan(c, p, limits)
    assert worst["jerk"] > 0.99 and np.isinf(p.accel_bound)


# --------------------------------------------------------------------------- stops and input checks


def test_a_corner_is_a_stop():
    """A degree-1 path with a 90° corner: rest at the corner, rest-to-rest on each leg."""
    c = NurbsCurve(1, [[0, 0], [30, 0], [30, 20]])
    limits = dict(feedrate=50.0, max_accel=500.0, max_jerk=10000.0)
    p = plan_adaptive(c, T, **limits)
    assert p.sections == 2
    check_plan(c, p, limits, per_span=200)
    tc = np.linspace(0, p.duration, 100001)
    S, V, _ = p.evaluate(tc)
    assert V[np.argmin(np.abs(S - 30.0))] < 1e-3
    vel, _ = axis_rates(c, p)
    # x dies out before y starts: only the tick holding the stop moves along both legs, and
    # barely (from rest with jerk J, a tick covers at most J T³/6 on each side of the stop)
    both = np.minimum(np.abs(vel[:, 0]), np.abs(vel[:, 1]))
    assert np.count_nonzero(both) <= 1 and both.max() * T <= 2 * 10000.0 * T ** 3 / 6


@pytest.mark.parametrize("kwargs, message", [
    (dict(max_accel=-1.0), "max_accel"),
    (dict(max_accel=1000.0, axes={"w": {"max_velocity": 1.0}}), "unknown axis"),
    (dict(max_accel=1000.0, axes={"x": {"max_speed": 1.0}}), "unknown key"),
    (dict(max_accel=1000.0, tangential_share=1.0), "tangential_share"),
    (dict(chord_tolerance=1e-3), "needs max_accel"),
])
def test_bad_limits_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        plan_adaptive(butterfly(), T, F, **kwargs)


# --------------------------------------------------------------------------- degenerate curves and extreme limits


def check_table(p: AdaptivePlan, length: float, limits: dict):
    """The plan's own pieces against F, max_accel and max_jerk (exact on a piecewise-cubic S), its end and ticks."""
    seg = p.segments
    dur = np.diff(seg[:, 0])
    assert np.all(dur > 0.0) and seg[0, 0] == 0.0
    assert list(seg[-1]) == [p.duration, length, 0.0, 0.0, 0.0]
    assert abs(p.duration / p.period - round(p.duration / p.period)) < 1e-9
    v0, a0, j = seg[:-1, 2], seg[:-1, 3], seg[:-1, 4]
    v1 = v0 + a0 * dur + j * dur ** 2 / 2
    assert min(v0.min(), v1.min()) >= -1e-9 * max(1.0, p.peak)
    assert p.peak <= limits["feedrate"] * (1 + TABLE_RTOL)
    if limits.get("max_accel") is not None:
        assert max(np.abs(a0).max(), np.abs(a0 + j * dur).max()) <= limits["max_accel"] * (1 + TABLE_RTOL)
    if limits.get("max_jerk") is not None:
        assert np.abs(j).max() <= limits["max_jerk"] * (1 + TABLE_RTOL)


def check_v_limit_where_the_speed_is_not_zero(curve, p, limits, per_span=400):
    """V <= V_lim as in check_plan, except within 1e-6 of the span width of a point where |C'| vanishes
    (V_lim is 0 there by definition, and the plan stops)."""
    ud = dense_u(curve, per_span)
    speed = np.linalg.norm(curve.derivatives(ud, 1)[:, 1], axis=1)
    ud = ud[speed > 1e-6 * speed.max()]
    ratio = v_at_s(p, curve.arc_length_at(ud)) / feed_limit(curve, ud, p.period, **limits)
    assert ratio.max() <= 1 + VLIM_RTOL, f"V/V_lim = {ratio.max()} at u = {ud[ratio.argmax()]}"


def v_near(p: AdaptivePlan, s: float) -> float:
    """The plan's feedrate where it passes arc length s (on a fine time grid)."""
    tt = np.linspace(0.0, p.duration, 200001)
    S, V, _ = p.evaluate(tt)
    return float(V[np.argmin(np.abs(S - s))])


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("limits", [dict(chord_tolerance=1e-3), dict(max_normal_accel=500.0), {}])
def test_zero_length_polyline_segment_is_a_point_with_a_corner(limits):
    """A repeated point of a polyline is a knot span of zero length.  Its V_lim was 0/0, and the grid
    refinement halved it forever (gigabytes).  It has no length to plan: the corner there is a stop."""
    c = NurbsCurve(1, [[0, 0], [20, 0], [20, 0], [20, 10], [0, 10]])
    limits = dict(feedrate=50.0, max_accel=500.0, max_jerk=10000.0, **limits)
    p = plan_adaptive(c, 2e-3, **limits)
    assert p.sections == 3 and p.s_grid.shape[0] < 20000
    check_table(p, c.length, limits)
    assert v_near(p, 20.0) < 1e-3 and v_near(p, 30.0) < 1e-3  # both corners are stops
    # the same polyline without the repeated point: the same plan
    q = plan_adaptive(NurbsCurve(1, [[0, 0], [20, 0], [20, 10], [0, 10]]), 2e-3, **limits)
    assert p.duration == q.duration


@pytest.mark.filterwarnings("error")
def test_three_equal_control_points_make_a_stop():
    """p + 1 equal control points: a span of zero length between two spans whose speed vanishes at the
    shared knot.  With a curvature limit that knot is a stop (V_lim there is 0); without one the plan goes
    through when the path goes straight on, and stops at a turn."""
    turn = NurbsCurve(2, [[0, 0], [5, 0], [5, 0], [5, 0], [5, 5]])
    limits = dict(feedrate=100.0, max_accel=200.0, max_jerk=30000.0, max_normal_accel=500.0)
    p = plan_adaptive(turn, T, **limits)
    assert p.sections == 2 and p.duration < 1.0
    check_table(p, turn.length, limits)
    check_v_limit_where_the_speed_is_not_zero(turn, p, limits)
    straight = NurbsCurve(2, [[0, 0], [5, 0], [5, 0], [5, 0], [10, 0]])
    assert plan_adaptive(straight, T, 100.0, max_accel=200.0).sections == 1
    assert plan_adaptive(straight, T, 100.0, max_accel=200.0, max_normal_accel=500.0).sections == 2
    assert plan_adaptive(turn, T, 100.0, max_accel=200.0).sections == 2  # the corner


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("jerk", [30000.0, None])
def test_zero_speed_at_the_ends_is_planned(jerk):
    """Repeated first (and last) control points: C' = 0 at the ends of the domain, where V = 0 anyway.  It was
    refused as a cusp; near such an end the curvature formula is rounding noise (V_lim ~ 1e-18 mm/s at
    u = 1e-13, which made the motion last for weeks), so those samples are left to the stop."""
    c = NurbsCurve(3, [[0, 0], [0, 0], [0, 0], [10, 0], [10, 10], [20, 10], [20, 10], [20, 10]])
    limits = dict(feedrate=100.0, max_accel=200.0, max_jerk=jerk, chord_tolerance=1e-3, max_normal_accel=500.0,
                  axes={"x": {"max_velocity": 50.0, "max_accel": 300.0}})
    p = plan_adaptive(c, T, **limits)
    assert p.sections == 1 and 0.5 < p.duration < 1.5
    check_table(p, c.length, limits)
    check_v_limit_where_the_speed_is_not_zero(c, p, limits)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("kwargs", [dict(chord_tolerance=1e-3), {}])
def test_a_cusp_inside_a_span_is_refused_naming_the_point(kwargs):
    """The speed vanishes at u = 0.5 and the path turns back.  Without a curvature limit V_lim stays F on both
    sides, so the reversal was taken at full speed; the planner stops only at knots, so it refuses it, and
    with a knot there it stops."""
    from nurbsinterp.errors import SpecError

    with pytest.raises(SpecError, match=r"^curve: the parametric speed vanishes at u = 0\.5, point \(5, 0\).*"
                                        r"turns by 180 degrees.*insert a knot at u = 0\.5"):
        plan_adaptive(NurbsCurve(2, [[0, 0], [10, 0], [0, 0]]), T, 100.0, max_accel=200.0, **kwargs)
    knotted = NurbsCurve(2, [[0, 0], [5, 0], [5, 0], [0, 0]], knots=[0, 0, 0, 0.5, 1, 1, 1])  # the same curve
    p = plan_adaptive(knotted, T, 100.0, max_accel=200.0, **kwargs)
    assert p.sections == 2 and v_near(p, 5.0) < 1e-3


@pytest.mark.filterwarnings("error")
def test_a_rational_point_has_zero_length():
    """Equal control points with unequal weights: the arc length is rounding (~1e-16 mm)."""
    from nurbsinterp.errors import SpecError

    for c in (NurbsCurve(1, [[-19.3, -3.6, 1.6], [-19.3, -3.6, 1.6]], [4.79, 5.33]),
              NurbsCurve(2, [[5, 5], [5, 5], [5, 5]], [1, 0.5, 1])):
        with pytest.raises(SpecError, match="^curve: has zero length"):
            plan_adaptive(c, T, 100.0, max_accel=200.0, chord_tolerance=1e-3, max_jerk=30000.0)


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("period, feedrate, limits, optimum", [
    # a 1 mm line at a coarse period: it came to rest 1e-9 mm short and could not creep the rest
    (0.02, 10.0, dict(max_jerk=2474.0), 4 * (1 / (2 * 2474.0)) ** (1 / 3)),
    (0.02, 10.0, dict(max_jerk=30000.0), None),
    # 35 s of motion: the step budget ignored the acceleration limit
    (1e-3, 100.0, dict(max_accel=1.0, max_jerk=1e5), 2 * math.sqrt(math.pi * 100.0)),
    # 216 s: a jerk-only S-curve over the whole circle, 4 (L / 2J)^(1/3)
    (1e-3, 100.0, dict(max_accel=200.0, max_jerk=1e-3), 4 * (math.pi * 50.0 / 1e-3) ** (1 / 3)),
], ids=["line-J2474", "line-J30000", "circle-A1", "circle-J1e-3"])
def test_jerk_pass_reaches_the_end(period, feedrate, limits, optimum):
    c = NurbsCurve(1, [[0, 0], [1, 0]]) if period == 0.02 else curve_file("circle.yaml")
    limits = dict(feedrate=feedrate, **limits)
    p = plan_adaptive(c, period, **limits)
    check_table(p, c.length, limits)
    if optimum is not None:  # within the last tick of the time-optimal motion
        assert optimum * (1 - 1e-6) <= p.duration <= optimum * (1 + 1e-4) + period
    if period == 0.02:
        check_plan(c, p, limits, per_span=2000)


@pytest.mark.filterwarnings("error")
def test_planning_is_bounded_by_steps_not_by_the_motion_time():
    """The jerk pass steps in time: 3e5 s of motion (F = 1e-3 mm/s) or a 1 ns period once meant 3e8..5e10 steps
    (minutes and gigabytes).  Its step is now at most 1/64 of the acceleration ramp below the period, and
    coarse enough for about MAX_STEPS steps, where a level-off step keeps the feedrate at its cap."""
    from nurbsinterp.planner import MAX_STEPS

    c = curve_file("circle.yaml")
    slow = dict(feedrate=1e-3, max_accel=2e-3, max_jerk=30000.0)
    p = plan_adaptive(c, T, **slow)
    assert p.segments.shape[0] < 2.5 * MAX_STEPS
    check_table(p, c.length, slow)
    ideal = c.length / 1e-3 + 1e-3 / 2e-3  # cruise, and the ramps' extra time
    assert ideal <= p.duration <= ideal * (1 + 1e-5)
    fast = dict(feedrate=100.0, max_accel=200.0, max_jerk=30000.0)
    ns, ms = plan_adaptive(c, 1e-9, **fast), plan_adaptive(c, T, **fast)
    assert ns.segments.shape[0] < 100000
    check_table(ns, c.length, fast)
    assert abs(ns.duration - ms.duration) <= T


@pytest.mark.filterwarnings("error")
@pytest.mark.parametrize("curve, args, kwargs, message", [
    ("quad", (T, 100.0), dict(chord_tolerance=1e-3), "^profile.max_accel is not set: .*needs max_accel"),
    ("quad", (T, 100.0), dict(max_accel=-1.0), r"^profile.max_accel = -1.0 must be a positive finite number"),
    ("quad", (0.0, 100.0), dict(max_accel=1.0), r"^interpolator.period = 0.0 must be"),
    ("quad", (T, math.inf), dict(max_accel=1.0), r"^profile.feedrate = inf must be"),
    ("quad", (T, 100.0), dict(max_accel=1.0, chord_tolerance="fine"), r"^profile.chord_tolerance = 'fine' is not"),
    ("quad", (T, 100.0), dict(max_jerk=1.0, max_normal_accel=math.nan), r"^profile.max_normal_accel = nan"),
    ("quad", (T, 100.0), dict(max_accel=1.0, axes={"x": {"max_velocity": 0}}), r"^profile.axes.x.max_velocity = 0"),
    ("quad", (T, 100.0), dict(max_accel=1.0, axes={"w": {}}), r"^profile.axes: unknown axis 'w'"),
    ("line", (T, 100.0), dict(axes={"y": {"max_accel": 10.0}}), r"^profile.max_accel is not set and the axes'"),
    ("cusp", (T, 100.0), dict(max_accel=1.0), r"^curve: the parametric speed vanishes at u = 0.5"),
    ("point", (T, 100.0), dict(max_accel=1.0), r"^curve: has zero length"),
])
def test_refusals_name_the_field_and_value(curve, args, kwargs, message):
    """Every SpecError of the planner names the job field (the caller prefixes the file), without warnings."""
    from nurbsinterp.errors import SpecError

    c = {"quad": NurbsCurve(2, [[0, 0], [10, 0], [10, 10]]), "cusp": NurbsCurve(2, [[0, 0], [10, 0], [0, 0]]),
         "point": NurbsCurve(1, [[1, 1], [1, 1]]), "line": NurbsCurve(1, [[0, 0], [10, 0]])}[curve]
    with pytest.raises(SpecError, match=message):
        plan_adaptive(c, *args, **kwargs)


def test_the_limits_are_validated_once_into_a_frozen_typed_object():
    """The stages read what they need of the limits from one _Limits, derived once."""
    import dataclasses

    from nurbsinterp.planner.limits import AXIS_ACCEL, CHORD, NORMAL_ACCEL, _limits

    quad = NurbsCurve(2, [[0, 0], [10, 0], [10, 10]])
    lim = _limits(quad, T, F, DELTA, A_MAX, None, None, {"x": {"max_velocity": 60.0}, "z": {"max_accel": 5.0}}, 0.4)
    assert lim.curvature_columns == (CHORD,) and lim.curving
    assert lim.has_axis_velocity and not lim.has_axis_accel  # z does not move on a planar curve
    assert lim.tight_turn == (2.0 * DELTA / T, 2.0 * DELTA)
    with pytest.raises(dataclasses.FrozenInstanceError):
        lim.feedrate = 1.0
    with pytest.raises(ValueError):
        lim.axis_velocity[0] = 1.0
    bare = _limits(quad, T, F, None, A_MAX, None, 100.0, {"y": {"max_accel": 800.0}}, 0.4)
    assert bare.curvature_columns == (NORMAL_ACCEL, AXIS_ACCEL)
    assert bare.tight_turn == (100.0 * T / 2.0, 100.0 * T ** 2)  # the normal acceleration's floor and reach
    assert not _limits(quad, T, F, None, A_MAX, None, None, None, 0.4).curving
    assert _limits(quad, T, F, None, A_MAX, None, None, None, 0.4).tight_turn == (math.inf, 0.0)


# --------------------------------------------------------------------------- memory, and the kernels behind it
#
# Issue 16: the grid (~34 points per knot span) is built and consumed in blocks of knot spans, the sections
# are kept at 16-24 bytes a point, and the terms of V_lim, the golden-section steps, the time estimates'
# sums and the range minima are kernels.  What must not change is any number of a plan: each kernel is
# checked here bit for bit against what it replaces (the oracles below are that numpy, as the planner had
# it), and whole plans for not depending on the blocks.  tests/test_digests.py holds the bundled jobs'
# streams.


def wavy_cubic(n: int, seed: int = 0) -> NurbsCurve:
    """A clamped uniform cubic B-spline of n control points 1 mm apart along x, y = 5 sin(2πx/40 mm) ± 0.2 mm
    (seeded): a long line of realistic size.  benchmarks/adaptive_memory.py plans the same curve."""
    rng = np.random.default_rng(seed)
    x = np.arange(n, dtype=float)
    y = 5.0 * np.sin(2.0 * np.pi * x / 40.0) + rng.uniform(-0.2, 0.2, n)
    knots = np.concatenate([np.zeros(4), np.arange(1, n - 3) / (n - 3), np.ones(4)])
    return NurbsCurve(3, np.column_stack([x, y]), knots=knots)


MEMORY_CHILD = """
import sys
sys.path.insert(0, {tests!r})
from test_planner import BUTTERFLY, T, wavy_cubic
from nurbsinterp.planner import plan_adaptive

def status(field):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(field + ":"))

plan_adaptive(wavy_cubic(300), T, **BUTTERFLY)  # the kernels, loaded before the measure
curve = wavy_cubic({n})
curve.length  # the curve's own tables
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")  # VmHWM := VmRSS
before = status("VmRSS")
plan_adaptive(curve, T, **BUTTERFLY)
print(status("VmHWM") - before)
"""


def planning_peak(n: int) -> int:
    """How far planning the wavy cubic of n control points raises the peak RSS of a fresh process, bytes."""
    import subprocess
    import sys

    script = MEMORY_CHILD.format(tests=str(Path(__file__).parent), n=n)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    return int(out.stdout.split()[-1])


@pytest.mark.skipif(not Path("/proc/self/clear_refs").exists(), reason="needs Linux's /proc to reset VmHWM")
def test_planning_memory_per_control_point():
    """Issue 16: <= 1 KB per control point (it was ~18 KB: 1.97 GB at 10⁵), measured as the rise of the peak
    RSS (the planner's sections live in memory maps and numba's arrays, which tracemalloc does not see)
    between 2 000 and 20 000 control points, so that what does not grow with the curve cancels.  Bytes,
    never time.  Measured: ~790 bytes per control point."""
    small, large = planning_peak(2_000), planning_peak(20_000)
    per_point = (large - small) / 18_000
    assert per_point <= 1024, f"{per_point:.0f} bytes per control point ({small} B at 2 000, {large} B at 20 000)"


@pytest.mark.parametrize("name, limits", [("butterfly", BUTTERFLY), ("axes", RANDOM_LIMITS["axes"]),
                                          ("corners", dict(feedrate=50.0, chord_tolerance=1e-3, max_accel=500.0))])
def test_blocks_do_not_change_the_plan(monkeypatch, name, limits):
    """The grid is built in blocks of knot spans; a block of one span each (every knot a block boundary,
    corners and smooth joins alike) gives the plan of the default blocks, to the bit, grid included."""
    import nurbsinterp.planner.grid as grid
    import nurbsinterp.planner.sections as sections

    c = {"butterfly": butterfly(), "axes": random_cubic(3),
         "corners": NurbsCurve(2, [[0, 0], [10, 0], [10, 0], [20, 5], [20, 15], [10, 15], [10, 15], [0, 20]],
                               knots=[0, 0, 0, 0.25, 0.25, 0.5, 0.75, 0.75, 1, 1, 1])}[name]
    ref = plan_adaptive(c, T, **limits)
    monkeypatch.setattr(grid, "BLOCK_SAMPLES", 1)
    monkeypatch.setattr(sections, "MAPPED", 8)  # sections kept in their maps, and copied out
    p = plan_adaptive(c, T, **limits)
    for a, b in [(ref.segments, p.segments), (ref.s_grid, p.s_grid), (ref.u_grid, p.u_grid),
                 (ref.v_limit, p.v_limit), (ref.binding, p.binding), (ref.a_limit, p.a_limit)]:
        np.testing.assert_array_equal(a, b)
    assert (ref.limit_fractions, ref.slowest, ref.sections, ref.stretch) == \
        (p.limit_fractions, p.slowest, p.sections, p.stretch)


def test_the_refinement_bound_is_counted_over_the_blocks(monkeypatch):
    """The refinement's bound on added grid points is the whole grid's, whatever the blocks: the same round
    passes it and the same point is named."""
    import nurbsinterp.planner.grid as grid
    from nurbsinterp.errors import SpecError

    monkeypatch.setattr(grid, "MAX_REFINED", 300)
    messages = set()
    for block in (1, 200, 10 ** 9):
        monkeypatch.setattr(grid, "BLOCK_SAMPLES", block)
        with pytest.raises(SpecError, match="varies too fast to be resolved near u = ") as err:
            plan_adaptive(random_cubic(2), T, **RANDOM_LIMITS["axes"])
        messages.add(str(err.value))
    assert len(messages) == 1


def frame_oracle(d):
    d1, d2 = d[:, 1, :], d[:, 2, :]
    sig2 = np.einsum("ij,ij->i", d1, d1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tau = d1 / np.sqrt(sig2)[:, None]
        kn = d2 / sig2[:, None] - d1 * (np.einsum("ij,ij->i", d1, d2) / (sig2 * sig2))[:, None]
    return tau, kn


def feed_limits_oracle(d, lim, singular, tangent, feedrate=None):
    """The terms of V_lim, the tangential bound, κ and τ as numpy arrays: the planner's code before the kernel."""
    from nurbsinterp.planner.limits import AXIS_ACCEL, AXIS_VELOCITY, CHORD, FEEDRATE, NORMAL_ACCEL

    tau, kn = frame_oracle(d)
    sing = bool(singular.any())
    if sing:
        tau = np.where(singular[:, None], tangent, tau)
        kn = np.where(singular[:, None], 0.0, kn)
    n = tau.shape[0]
    comps = np.full((n, len(LIMITS)), np.inf)
    comps[:, FEEDRATE] = lim.feedrate if feedrate is None else feedrate
    kappa = np.sqrt(np.einsum("ij,ij->i", kn, kn))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        rho = 1.0 / kappa
        if lim.chord_tolerance is not None:
            dl = lim.chord_tolerance
            chord = np.where(rho < dl, dl, np.sqrt(np.maximum(2.0 * rho * dl - dl * dl, 0.0)))
            comps[:, CHORD] = 2.0 / lim.period * chord
        if lim.max_normal_accel is not None:
            v = np.sqrt(lim.max_normal_accel * rho)  # and its floor A_n T/2 (tight turns)
            floor = lim.max_normal_accel / (2.0 / lim.period)
            comps[:, NORMAL_ACCEL] = np.where((v >= floor) | np.isnan(v), v, floor)
        abs_tau = np.abs(tau)
        if lim.has_axis_velocity:
            comps[:, AXIS_VELOCITY] = np.min(lim.axis_velocity / abs_tau, axis=1)
        acc_t = np.full(n, np.inf if lim.max_accel is None else lim.max_accel)
        if lim.has_axis_accel:
            comps[:, AXIS_ACCEL] = np.min(np.sqrt((1.0 - lim.share) * lim.axis_accel / np.abs(kn)), axis=1)
    comps = np.nan_to_num(comps, nan=0.0, posinf=np.inf)
    if sing:
        for col in lim.curvature_columns:
            comps[singular, col] = 0.0
        kappa = np.where(singular, np.nan, kappa)
    if lim.has_axis_accel:
        vmax = comps.min(axis=1)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            left = (lim.axis_accel - vmax[:, None] ** 2 * np.abs(kn)) / abs_tau
        acc_t = np.minimum(acc_t, np.nan_to_num(np.min(left, axis=1), nan=0.0, posinf=np.inf))
    return comps, acc_t, kappa, tau


def same_bits(a, b):
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and np.array_equal(a.view(np.int64), b.view(np.int64))


@pytest.mark.parametrize("dim", [2, 3])
def test_the_feed_limit_kernel_is_the_numpy_it_replaced(dim):
    """Every output of feed._feed_limits, bit for bit (NaN included), against the numpy oracle: random
    derivative tables over 50 decades, zero speeds, straight points, zero-speed ends with and without a
    limit tangent, the blocks' own feedrates, and every kind of limit."""
    from nurbsinterp.planner.feed import _feed_limits
    from nurbsinterp.planner.limits import _limits

    rng = np.random.default_rng(dim)
    axes = {"x": {"max_velocity": 60.0, "max_accel": 800.0}, "y": {"max_velocity": 70.0, "max_accel": 900.0},
            "z": {"max_velocity": 30.0, "max_accel": 400.0}}
    sets = [dict(chord_tolerance=1e-3, max_accel=1000.0), dict(max_jerk=1e4),
            dict(chord_tolerance=2e-3, max_accel=800.0, max_normal_accel=3000.0, axes=axes),
            dict(max_normal_accel=500.0, axes={"y": {"max_accel": 300.0}}),
            dict(max_accel=5.0, axes={"x": {"max_velocity": 1.0}})]
    line = NurbsCurve(1, [[0.0] * dim, [1.0] * dim])
    for trial in range(20):
        n = 3000
        d = rng.standard_normal((n, 3, dim)) * np.exp(rng.uniform(-25, 25, (n, 3, 1)))
        d[rng.random((n, 3, dim)) < 0.05] = 0.0
        d[rng.random(n) < 0.02, 1] = 0.0
        d[rng.random(n) < 0.02, 2] = 0.0
        singular = rng.random(n) < 0.1
        tangent = rng.standard_normal((n, dim))
        tangent[rng.random(n) < 0.3] = np.nan
        feed = None if trial % 2 else rng.uniform(1.0, 200.0, n) * (rng.random(n) < 0.9)
        for limits in sets:
            lim = _limits(line, 10 ** rng.uniform(-6, -2), float(rng.uniform(1, 300)), limits.get("chord_tolerance"),
                          limits.get("max_accel"), limits.get("max_jerk"), limits.get("max_normal_accel"),
                          limits.get("axes"), 0.4)
            for sing in (singular, np.zeros(n, dtype=bool)):
                got = _feed_limits(d, lim, sing, tangent, feed)
                for name, a, b in zip(("terms", "bound", "kappa", "tau"), feed_limits_oracle(d, lim, sing, tangent,
                                                                                            feed), got):
                    assert same_bits(a, b), (name, limits, trial)


@pytest.mark.parametrize("dim", [2, 3])
def test_dot_rounds_as_einsum(dim):
    """feed._dot against np.einsum("ij,ij->i") on contiguous rows and on rows of a derivative table, signed
    zeros included: the order in which numpy sums a row is what the kernel must follow."""
    from nurbsinterp.planner.feed import _dot

    rng = np.random.default_rng(10 + dim)
    d = rng.standard_normal((20000, 3, dim)) * np.exp(rng.uniform(-30, 30, (20000, 3, dim)))
    d[rng.random(d.shape) < 0.1] = 0.0
    d[rng.random(d.shape) < 0.1] = -0.0
    for a, b in ((d[:, 1], d[:, 2]), (np.ascontiguousarray(d[:, 0]), np.ascontiguousarray(d[:, 1]))):
        ref = np.einsum("ij,ij->i", a, b)
        got = np.array([_dot(a[i], b[i]) for i in range(a.shape[0])])
        assert same_bits(ref, got)


def test_pairwise_sum_is_ndarray_sum():
    """jerk._sum sums as ndarray.sum() does (numpy's pairwise summation), lengths 0 .. 200 000."""
    from nurbsinterp.planner.jerk import _sum

    rng = np.random.default_rng(5)
    for n in [0, 1, 7, 8, 9, 127, 128, 129, 255, 256, 1000, 4097, 65536, 200_000, *rng.integers(0, 20000, 40)]:
        a = rng.standard_normal(int(n)) * np.exp(rng.uniform(-30, 30, int(n)))
        assert _sum(a, a.shape[0]) == a.sum()
        assert _sum(np.abs(a), a.shape[0] // 2) == np.abs(a)[: a.shape[0] // 2].sum()


def sparse_table_oracle(vals):
    """What the sparse table over the values (levels of minima over 2**l values) answered, also for j < i,
    where an index below 0 wrapped around: the forward pass's range minima before the O(n) table.  The table
    is built once for *vals*; the answer to a range (i, j) is query(i, j)."""
    n = vals.shape[0]
    levels = 1
    while (1 << levels) <= n:
        levels += 1
    table = [vals.copy()]
    for lev in range(1, levels):
        prev, half = table[-1], 1 << (lev - 1)
        row = prev.copy()
        for k in range(n - (1 << lev) + 1):
            row[k] = min(prev[k], prev[k + half])
        table.append(row)
    lg = np.zeros(n + 1, dtype=np.int64)
    for k in range(2, n + 1):
        lg[k] = lg[k >> 1] + 1

    def query(i, j):
        lev = lg[j - i + 1]  # numpy's negative indices wrap, as numba's did
        return min(table[lev][i], table[lev][j - (1 << lev) + 1])

    return query


def test_range_minima_are_the_sparse_tables():
    """jerk._range_min against the sparse table it replaced: every range of small vectors, random ranges
    of large ones (every branch: runs of values, of blocks of 16, the table of blocks of 256), and the
    ranges that end one or two before they start (a piece that ends behind its start by rounding)."""
    from nurbsinterp.planner.jerk import _min_table, _range_min

    rng = np.random.default_rng(3)
    for n in (1, 2, 3, 17, 40, 300):
        vals = rng.uniform(0.0, 1.0, n)
        table, lg = _min_table(vals)
        oracle_min = sparse_table_oracle(vals)
        for i in range(n):
            for j in range(max(0, i - 2), n):
                assert _range_min(vals, table, lg, i, j) == oracle_min(i, j), (n, i, j)
    for n in (5000, 70000):
        vals = rng.uniform(0.0, 1.0, n)
        table, lg = _min_table(vals)
        oracle_min = sparse_table_oracle(vals)
        for _ in range(3000):
            i = int(rng.integers(0, n))
            j = min(n - 1, i + int(rng.choice([rng.integers(0, 40), rng.integers(0, 600), rng.integers(0, n)])))
            assert _range_min(vals, table, lg, i, j) == vals[i:j + 1].min()
        for i in (0, 1, 15, 16, 255, 256, n - 1):
            for j in (i - 1, i - 2):
                if j >= -1:
                    assert _range_min(vals, table, lg, i, j) == oracle_min(i, j), (n, i, j)


def test_growable_vectors_keep_their_values():
    """sections._Growable: appends of every size, across many enlargements of the map."""
    from nurbsinterp.planner.sections import _Growable

    rng = np.random.default_rng(1)
    g, parts = _Growable(), []
    for _ in range(300):
        x = rng.standard_normal(int(rng.integers(0, 3000)))
        g.append(x)
        parts.append(x)
    np.testing.assert_array_equal(g.values(), np.concatenate(parts))


def _golden_numpy(f, lo, hi, iterations=60):
    """golden_minimum as it was, in numpy operations: the oracle of its kernels."""
    g = (math.sqrt(5.0) - 1.0) / 2.0
    a, b = np.array(lo, dtype=float), np.array(hi, dtype=float)
    c, e = b - g * (b - a), a + g * (b - a)
    fc, fe = f(c), f(e)
    for _ in range(iterations):
        left = fc <= fe
        b = np.where(left, e, b)
        a = np.where(left, a, c)
        new = np.where(left, b - g * (b - a), a + g * (b - a))
        fn = f(new)
        e, fe, c, fc = (np.where(left, c, new), np.where(left, fc, fn), np.where(left, new, e), np.where(left, fn, fe))
    return np.where(fc <= fe, c, e)


def test_golden_steps_are_the_numpy_golden_section():
    """nurbs.golden_minimum's kernels take the numpy version's steps to the bit: ties (plateaus), NaN, steep minima."""
    from nurbsinterp.nurbs import GOLDEN_ITERATIONS, golden_minimum

    rng = np.random.default_rng(8)
    lo = rng.uniform(-5.0, 5.0, 4000)
    hi = lo + rng.uniform(1e-12, 3.0, 4000)
    centre = rng.uniform(-5.0, 8.0, 4000)

    def f(u):  # a parabola, flat tops where it is clipped, NaN in a band
        with np.errstate(invalid="ignore"):
            return np.where(np.abs(u - 1.0) < 0.01, np.nan, np.minimum((u - centre) ** 2, 4.0))

    assert same_bits(golden_minimum(f, lo, hi), _golden_numpy(f, lo, hi, GOLDEN_ITERATIONS))


def test_initial_samples_are_linspace():
    """grid._samples: np.linspace(start, end, count + 1) on every span, to the bit, denormal steps included."""
    from nurbsinterp.planner.grid import _samples, _Spans

    rng = np.random.default_rng(9)
    start = np.cumsum(rng.uniform(0.0, 2.0, 50)) * 10.0 ** rng.integers(-8, 8)
    end = start + rng.uniform(1e-9, 2.0, 50) * np.abs(start).max()
    start[3], end[3] = 0.0, 5e-324  # a step that underflows to 0
    counts = rng.integers(32, 90, 50)
    spans = _Spans(np.arange(50), start, end, None, None, (), None)
    u, loc = _samples(spans, counts)
    ref = np.concatenate([np.linspace(a, b, c + 1) for a, b, c in zip(start, end, counts)])
    assert same_bits(u, ref) and np.array_equal(loc, np.repeat(np.arange(50), counts + 1))
