"""The real-time interpolators (REFERENCE.md §3, §5; the paper's Eqs. 8–9 and Fig. 6).

Runs go through the public path, ``Interpolation(load_job(path, overrides)).chunks()``.
Each of the 24 runs on the paper's circle is computed once per module (lru_cache).

Independent references:
* the circle itself: |P − (50, 0)| = 50;
* Eq. 8 / Eq. 9 / RK4 recomputed step by step from the u column with the
  deliberately naive NURBS in tests/oracle.py;
* geomdl for points of the other curves;
* the after-interpolation filters re-implemented with numpy/scipy (convolution,
  lfilter) and the steady-state radius deficit of a filtered circle in closed form.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.signal import lfilter

import oracle  # tests/ is on sys.path (rootdir conftest / pytest's prepend import mode)
from nurbsinterp.errors import SpecError
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli
from layout import one_curve

CURVES = Path(__file__).resolve().parent.parent / "curves"
CIRCLE_YAML = CURVES / "circle.yaml"
CENTRE = np.array([50.0, 0.0])
RADIUS = 50.0
L_CIRCLE = 100.0 * math.pi
EPS = np.finfo(float).eps

METHODS = ("taylor1", "taylor2", "rk4", "exact")
SHAPES = ("trapezoidal", "exponential", "bell")
COMBOS = [(m, s) for m in METHODS for s in SHAPES]
COMBO_IDS = [f"{m}-{s}" for m, s in COMBOS]
SETTLE = 1e-6  # mm: 1 nm


@dataclass
class Run:
    run: Interpolation
    data: np.ndarray  # k, t, u, x, y[, z], v, a
    planned: np.ndarray  # S(t_k)

    @property
    def dim(self):
        return self.run.curve.dim

    @property
    def pts(self):
        return self.data[:, 3:3 + self.dim]

    @property
    def u(self):
        return self.data[:, 2]


def execute(path, chunk_ticks=None, **overrides) -> Run:
    job = load_cli(path, overrides={k: v for k, v in overrides.items() if v is not None})
    run = Interpolation(job) if chunk_ticks is None else Interpolation(job, chunk_ticks=chunk_ticks)
    chunks = list(run.chunks())
    data = one_curve(np.vstack([c.data for c in chunks]))
    planned = np.concatenate([c.planned for c in chunks])
    return Run(run, data, planned)


@functools.lru_cache(maxsize=None)
def circle(method, shape, accdec="before", **extra) -> Run:
    return execute(CIRCLE_YAML, interpolator=method, profile_type=shape, accdec=accdec, **extra)


@functools.lru_cache(maxsize=None)
def curve_file_run(name, method, accdec="before") -> Run:
    return execute(CURVES / name, interpolator=method, accdec=accdec)


def derivs(curve, u):
    """C, C', C'' at u (N,) from the oracle: shape (N, 3, dim)."""
    return oracle.curve_derivatives(curve.knots, curve.degree, curve.control_points, curve.weights,
                                    np.asarray(u, dtype=float), 2)


def geomdl_points(curve, u):
    NURBS = pytest.importorskip("geomdl.NURBS")
    c = NURBS.Curve(normalize_kv=False)
    c.degree = int(curve.degree)
    c.ctrlpts = curve.control_points.tolist()
    c.weights = curve.weights.tolist()
    c.knotvector = curve.knots.tolist()
    return np.array(c.evaluate_list([float(x) for x in u]))


def first_arrival(u, b):
    return int(np.flatnonzero(u == b)[0])


# =========================================================================== before: the circle


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_circle_commands_stay_on_the_circle(method, shape):
    r = circle(method, shape)
    d = r.data
    assert np.isfinite(d).all()
    assert r.run.curve.dim == 2 and d.shape[1] == 7  # k, t, u, x, y, v, a (one_curve drops n)
    radius = np.hypot(d[:, 3] - CENTRE[0], d[:, 4] - CENTRE[1])
    assert np.max(np.abs(radius - RADIUS)) <= 1e-9


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_circle_ticks_time_and_end(method, shape):
    r = circle(method, shape)
    d = r.data
    T = 1e-3
    assert d.shape[0] == math.ceil(3.6416 / T) + 1 == 3643
    k = np.arange(d.shape[0])
    assert np.array_equal(d[:, 0], k.astype(float))
    assert np.array_equal(d[:, 1], k * T)  # k·T exactly, never a running sum
    assert d[0, 2] == 0.0 and d[0, 3] == 0.0 and d[0, 4] == 0.0
    assert d[-1, 2] == 1.0 and d[-1, 3] == 0.0 and d[-1, 4] == 0.0  # the end point, exactly
    assert r.planned[-1] == r.run.length


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_circle_parameter_monotone_and_never_past_the_end(method, shape):
    r = circle(method, shape)
    u = r.u
    assert (np.diff(u) >= 0.0).all()
    assert (u >= 0.0).all() and (u <= 1.0).all()
    j = first_arrival(u, 1.0)
    assert (u[j:] == 1.0).all()
    s = r.run.curve.arc_length_at(u)
    assert (s <= r.run.length).all()


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_circle_feedrate_columns_are_the_plan(method, shape):
    """v, a columns are V(t_k), A(t_k) of REFERENCE §2 at t = k·T."""
    r = circle(method, shape)
    t = r.data[:, 1]
    Ta, Vp, td = 0.5, 100.0, 3.641592653589793 - 0.5
    c = 4.0
    rdef = {"trapezoidal": lambda x: x, "bell": lambda x: (1 - np.cos(np.pi * x)) / 2,
            "exponential": lambda x: (1 - np.exp(-c * x)) / (1 - np.exp(-c))}[shape]
    V = np.where(t < Ta, Vp * rdef(np.clip(t / Ta, 0, 1)),
                 np.where(t < td, Vp, np.where(t < td + Ta, Vp * (1 - rdef(np.clip((t - td) / Ta, 0, 1))), 0.0)))
    assert np.max(np.abs(r.data[:, -2] - V)) <= 1e-12 * Vp
    assert r.data[-1, -2] == 0.0 and r.data[-1, -1] == 0.0
    # the planned distance that rides along (chunk.planned) never decreases and ends at L exactly
    assert np.all(np.diff(r.planned) >= 0) and r.planned[0] == 0.0 and r.planned[-1] == r.run.length


def _predicted_steps(r: Run, method: str):
    """u_{k+1} predicted from u_k by the method's own formula (oracle geometry), rows 0 .. j-1."""
    curve, T = r.run.curve, r.run.period
    u = r.u
    j = first_arrival(u, curve.domain[1])
    uk = u[:j]
    D = derivs(curve, uk)
    d1, d2 = D[:, 1, :], D[:, 2, :]
    sigma = np.linalg.norm(d1, axis=1)
    V, A = r.data[:j, -2], r.data[:j, -1]
    step = T * V / sigma
    if method == "taylor1":  # Eq. 8
        return j, uk + step, step
    if method == "taylor2":  # Eq. 9
        dot = np.sum(d1 * d2, axis=1)
        return j, uk + step + T * T / 2 * (A / sigma - V * V * dot / sigma ** 4), step
    # classical RK4 on du/dt = V(t)/sigma(u) with V at t, t + T/2, t + T
    b = curve.domain[1]
    t = r.data[:j, 1]
    prof = r.run.profile
    Vh = prof.evaluate(t + T / 2)[1]
    V1 = prof.evaluate(t + T)[1]

    def speed(x):
        return np.linalg.norm(derivs(curve, np.minimum(x, b))[:, 1, :], axis=1)

    k1 = V / sigma
    k2 = Vh / speed(uk + T / 2 * k1)
    k3 = Vh / speed(uk + T / 2 * k2)
    k4 = V1 / speed(uk + T * k3)
    return j, uk + T * (k1 + 2 * k2 + 2 * k3 + k4) / 6, step


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4"])
def test_steps_are_the_papers_formulas(method, shape):
    """Every step before the arrival is Eq. 8 (taylor1), Eq. 9 (taylor2) or RK4, to rounding."""
    r = circle(method, shape)
    j, pred, step = _predicted_steps(r, method)
    actual = r.u[1:j]
    err = np.abs(actual - pred[:-1])
    # the geometry of two codes differs by a few ulps of σ (relative 1e-13 of a step); u_{k+1} is rounded once
    allowed = 1e-12 * np.abs(step[:-1]) + 2 * EPS * np.abs(actual)
    assert (err <= allowed).all(), np.max(err / allowed)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4", "exact"])
def test_end_gap_is_reported_as_defined(method, shape):
    """end_gap = S(t_j) − s(ũ_j) at the arrival tick j, ũ_j where the method itself would have gone
    (arc length extended linearly past the end)."""
    r = circle(method, shape)
    assert math.isfinite(r.run.end_gap)
    if method == "exact":
        assert abs(r.run.end_gap) <= 1e-9 * L_CIRCLE
        return
    curve = r.run.curve
    j, pred, _ = _predicted_steps(r, method)
    ut = max(pred[-1], r.u[j - 1])  # the interpolator never steps back (Eq. 9 can, as V -> 0 with A < 0)
    b = curve.domain[1]
    if ut <= b:
        reached = curve.arc_length_at(ut)
    else:
        reached = curve.length + (ut - b) * float(curve.speed(b))
    expected = r.planned[j] - reached
    assert r.run.end_gap == pytest.approx(expected, abs=1e-9)
    # it is small on the paper's circle: the interpolators track the plan to ~1e-4 mm
    assert abs(r.run.end_gap) <= 1e-3


def test_end_gap_is_known_only_after_the_run():
    job = load_cli(CIRCLE_YAML, overrides={"interpolator": "taylor1"})
    run = Interpolation(job)
    assert run.end_gap == 0.0
    for _ in run.chunks():
        pass
    assert run.end_gap == circle("taylor1", "trapezoidal").run.end_gap != 0.0


@pytest.mark.parametrize("shape", SHAPES)
def test_exact_method_has_no_feedrate_fluctuation(shape):
    r = circle("exact", shape)
    s = r.run.curve.arc_length_at(r.u)
    S = r.planned
    L = r.run.length
    assert np.max(np.abs(s - S)) <= 1e-9 * L
    ds, dS = np.diff(s), np.diff(S)
    # per tick, absolute: arc length to double precision
    assert np.max(np.abs(ds - dS)) <= 1e-12 * L
    # FF = Δs/ΔS − 1 on every tick whose planned step is at least 1 % of Vp·T (REFERENCE §4)
    counted = dS >= 0.01 * 100.0 * 1e-3
    assert counted.sum() >= 3500
    assert np.max(np.abs(ds[counted] / dS[counted] - 1.0)) <= 1e-9


def _cruise_ff(r: Run):
    s = r.run.curve.arc_length_at(r.u)
    t = r.data[:, 1]
    cruise = (t[:-1] >= 0.5) & (t[1:] <= r.run.profile.decel_start)
    return np.diff(s)[cruise] / np.diff(r.planned)[cruise] - 1.0


@pytest.mark.parametrize("shape", SHAPES)
def test_second_order_beats_first_order_in_cruise(shape):
    rms = {m: float(np.sqrt(np.mean(_cruise_ff(circle(m, shape)) ** 2))) for m in METHODS}
    assert rms["taylor2"] < rms["taylor1"]
    # a first-order local error O(VT·κ) against a second-order O((VT)²): at least ten times smaller here
    assert rms["taylor2"] < 0.1 * rms["taylor1"]
    assert rms["rk4"] < 0.1 * rms["taylor1"]
    assert rms["exact"] < 1e-9
    # Eq. 8's error on this circle: (C'·C'')VT/(2σ³) ~ 1e-3 at most
    assert 1e-5 < rms["taylor1"] < 2e-3


@pytest.mark.parametrize("chunk_ticks", [7, 1000])
@pytest.mark.parametrize("method,shape,accdec", [("taylor2", "trapezoidal", "before"), ("rk4", "exponential", "after"),
                                                 ("exact", "bell", "before"), ("taylor1", "bell", "after")])
def test_chunking_does_not_change_the_numbers(method, shape, accdec, chunk_ticks):
    ref = circle(method, shape, accdec)
    r = execute(CIRCLE_YAML, chunk_ticks=chunk_ticks, interpolator=method, profile_type=shape, accdec=accdec)
    assert np.array_equal(r.data, ref.data)
    assert np.array_equal(r.planned, ref.planned)
    assert r.run.end_gap == ref.run.end_gap


def test_job_longer_than_max_ticks_is_refused():
    job = load_job(CIRCLE_YAML)
    with pytest.raises(SpecError, match=r"about 3\.64e\+03 ticks \(3\.64159 s of motion at T = 0\.001 s\), "
                                        r"more than the limit of 1e\+03$"):
        Interpolation(job, max_ticks=1000)
    with pytest.raises(SpecError, match=r"limit of 1e\+03 \(--max-ticks\)$"):
        Interpolation(job, max_ticks=1000, max_ticks_hint=" (--max-ticks)")
    # the refusal comes before the plan: a period of 1e-320 s overflows the estimate, and is still refused
    tiny = replace(job, interpolator=replace(job.interpolator, period=1e-320))
    with pytest.raises(SpecError, match="more than 1e308 ticks"):
        Interpolation(tiny)


# =========================================================================== after: the filters


def _filtered_reference(r: Run, shape: str, extra: int = 3000):
    """Re-run the acc/dec-after filter with numpy/scipy from the unfiltered parameters."""
    run = r.run
    T, dim = run.period, run.curve.dim
    K = run.last_tick
    u = r.u[:K + 1]
    x = run.curve.evaluate(u)
    x[u == run.curve.domain[0]] = run.curve.control_points[0]
    x[u == run.curve.domain[1]] = run.curve.control_points[-1]
    k = np.arange(K + 1 + extra)
    Vp = run.job.profile.feedrate
    v = np.where(k * T < run.length / Vp, Vp, 0.0)
    X = np.column_stack([np.vstack([x, np.tile(run.curve.control_points[-1], (extra, 1))]), v])
    start = np.append(run.curve.control_points[0], 0.0)
    Ta = run.job.profile.accel_time
    if shape == "exponential":
        alpha = -math.expm1(-T / run.job.profile.tau)
        Y = lfilter([alpha], [1.0, alpha - 1.0], X - start, axis=0) + start
    else:
        sizes = [max(1, round(Ta / T))] if shape == "trapezoidal" else [max(1, round(Ta / (2 * T)))] * 2
        Y = X
        for N in sizes:
            padded = np.vstack([np.tile(start, (N - 1, 1)), Y])
            Y = np.column_stack([np.convolve(padded[:, c], np.ones(N) / N, mode="valid") for c in range(dim + 1)])
    return Y


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_after_mode_is_the_filtered_constant_feed_run(method, shape):
    r = circle(method, shape, "after")
    n = r.data.shape[0]
    Y = _filtered_reference(r, shape)
    assert np.isfinite(r.data).all()
    assert np.max(np.abs(r.pts[:-1] - Y[:n - 1, :2])) <= 1e-9
    assert np.max(np.abs(r.data[:-1, -2] - Y[:n - 1, 2])) <= 1e-9
    acc = np.diff(Y[:n - 1, 2], prepend=0.0) / r.run.period
    assert np.max(np.abs(r.data[:-1, -1] - acc)) <= 1e-5
    k = np.arange(n)
    assert np.array_equal(r.data[:, 0], k.astype(float)) and np.array_equal(r.data[:, 1], k * 1e-3)
    # the last row is the end point exactly, at rest
    assert r.data[-1, 3] == 0.0 and r.data[-1, 4] == 0.0 and r.data[-1, -2] == 0.0 and r.data[-1, -1] == 0.0
    # the feedrate is filtered too: it ramps, never overshoots
    assert (r.data[:, -2] >= 0.0).all() and (r.data[:, -2] <= 100.0 * (1 + 1e-12)).all()


@pytest.mark.parametrize("shape", SHAPES)
def test_after_mode_on_a_curve_with_another_domain(shape):
    """The quintic wave (u in [2, 7], τ = 50 ms given, T = 0.5 ms) through each filter."""
    r = execute(CURVES / "quintic-wave.yaml", interpolator="taylor2", accdec="after", profile_type=shape)
    n = r.data.shape[0]
    Y = _filtered_reference(r, shape, extra=4000)
    assert np.max(np.abs(r.pts[:-1] - Y[:n - 1, :2])) <= 1e-9
    assert np.array_equal(r.pts[-1], [150.0, 10.0]) and r.u[0] == 2.0 and r.u[-1] == 7.0
    K = r.run.last_tick
    dist = np.hypot(Y[:, 0] - 150.0, Y[:, 1] - 10.0)
    assert (dist[:n - 1] > SETTLE).all()
    assert np.max(np.abs(Y[n - 1, :2] - [150.0, 10.0])) <= SETTLE
    assert n - 1 > K


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_after_mode_stops_at_the_first_tick_within_1nm(method, shape):
    """Output goes on while the filtered command is more than 1 nm from the end point."""
    r = circle(method, shape, "after")
    n = r.data.shape[0]
    Y = _filtered_reference(r, shape)
    dist = np.hypot(Y[:, 0], Y[:, 1])  # the end point is (0, 0)
    assert n - 1 > r.run.last_tick
    assert (dist[r.run.last_tick + 1:n - 1] > SETTLE).all()  # nothing before the last row had settled


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_after_mode_last_row_was_within_1nm(method, shape):
    r = circle(method, shape, "after")
    n = r.data.shape[0]
    Y = _filtered_reference(r, shape)
    assert math.hypot(Y[n - 1, 0], Y[n - 1, 1]) <= SETTLE


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_after_mode_u_is_the_unfiltered_parameter(method, shape):
    r = circle(method, shape, "after")
    const = circle(method, shape, "before", accel_time=0)  # the same constant-feed interpolation, unfiltered
    K = r.run.last_tick
    assert K == const.run.last_tick == math.ceil(math.pi / 1e-3)
    assert np.array_equal(r.u[:K + 1], const.u)
    assert (r.u[K:] == 1.0).all()
    # ... while the commanded points are not on the curve at u
    inside = RADIUS - np.hypot(r.data[:, 3] - 50.0, r.data[:, 4])
    assert inside[1000:3000].min() > 0.5


def _deficit_formulas(shape, v=100.0, r=RADIUS, Ta=0.5, T=1e-3):
    """(continuous, discrete) steady-state radius deficit of a circle through the filter."""
    w = v / r
    if shape == "trapezoidal":
        th = w * Ta / 2
        N = round(Ta / T)
        return r * (1 - math.sin(th) / th), r * (1 - abs(math.sin(N * w * T / 2) / (N * math.sin(w * T / 2))))
    if shape == "bell":
        th = w * Ta / 4
        N = round(Ta / (2 * T))
        g = math.sin(N * w * T / 2) / (N * math.sin(w * T / 2))
        return r * (1 - (math.sin(th) / th) ** 2), r * (1 - g * g)
    tau = Ta / 4
    alpha = -math.expm1(-T / tau)
    return r * (1 - 1 / math.sqrt(1 + (w * tau) ** 2)), r * (1 - alpha / abs(1 - (1 - alpha) * np.exp(-1j * w * T)))


@pytest.mark.parametrize("method,shape", COMBOS, ids=COMBO_IDS)
def test_after_mode_cuts_inside_the_circle_by_the_steady_state_deficit(method, shape):
    """REFERENCE §5: Δr = r(1 − sinc(ωT1/2)) (moving average), r(1 − 1/√(1+ω²τ²)) (lag), sinc² (bell)."""
    r = circle(method, shape, "after")
    K = r.run.last_tick
    t = r.data[:, 1]
    # steady state: the moving-average windows hold only cruise points; the lag's transient e^(−t/τ) < 2e-9
    first = {"trapezoidal": 0.5, "bell": 0.5, "exponential": 2.5}[shape]
    window = (t >= first) & (np.arange(len(t)) < K)
    deficit = RADIUS - np.hypot(r.data[window, 3] - 50.0, r.data[window, 4])
    continuous, discrete = _deficit_formulas(shape)
    assert {"trapezoidal": 2.0574, "exponential": 1.4929, "bell": 1.0330}[shape] == pytest.approx(continuous, abs=1e-4)
    # first order's own feedrate error (~1e-3) moves the deficit by ~2e-3 (Δr ∝ v²); the others track to 1e-5
    tol = 2e-3 if method == "taylor1" else 1e-4
    assert deficit.mean() == pytest.approx(continuous, rel=tol)
    if method == "exact":  # equal arc steps: the discrete steady state, tick by tick
        assert np.max(np.abs(deficit / discrete - 1)) <= (1e-7 if shape == "exponential" else 1e-9)


@pytest.mark.parametrize("shape", SHAPES)
@pytest.mark.parametrize("method", ["taylor2", "exact"])
def test_after_mode_on_a_3d_curve(method, shape):
    """The tilted circle through the filters: still in its plane (filters are linear), inside its circle."""
    r = execute(CURVES / "tilted-circle-3d.yaml", interpolator=method, accdec="after", profile_type=shape)
    d = r.data
    assert d.shape[1] == 8 and np.isfinite(d).all()
    normal = np.array([0.0, -0.5, math.sqrt(3) / 2])
    assert np.max(np.abs(r.pts @ normal)) <= 1e-9
    assert (np.linalg.norm(r.pts - [50.0, 0.0, 0.0], axis=1) <= RADIUS + 1e-9).all()
    assert (d[-1, 3:6] == 0.0).all()


@pytest.mark.parametrize("shape", [
    "trapezoidal", "bell",
    "exponential",
])
def test_after_mode_with_zero_accel_time_is_unfiltered(shape):
    r = circle("taylor2", shape, "after", accel_time=0)
    const = circle("taylor2", shape, "before", accel_time=0)
    m = const.data.shape[0]
    assert np.max(np.abs(r.pts[:m] - const.pts)) <= 1e-12
    assert (r.pts[m:] == 0.0).all()


# =========================================================================== other curves


@pytest.mark.parametrize("method", METHODS)
def test_tilted_circle_points_are_on_the_3d_circle(method):
    r = curve_file_run("tilted-circle-3d.yaml", method)
    d = r.data
    assert d.shape[1] == 8 and r.run.columns == ["k", "n", "t", "u", "x", "y", "z", "v", "a"]  # d: without n
    assert np.isfinite(d).all()
    P = r.pts
    normal = np.array([0.0, -0.5, math.sqrt(3) / 2])  # x axis and (0, cos 30°, sin 30°) span the plane
    assert np.max(np.abs(P @ normal)) <= 1e-9
    assert np.max(np.abs(np.linalg.norm(P - [50.0, 0.0, 0.0], axis=1) - RADIUS)) <= 1e-9
    assert (d[-1, 3:6] == 0.0).all() and d[-1, 2] == 1.0
    assert (np.diff(r.u) >= 0).all()
    # bell, 6 m/min, 200 ms, T = 500 us: ceil((100π/100 + 0.2) / 5e-4) + 1 ticks
    assert d.shape[0] == math.ceil((math.pi + 0.2) / 5e-4) + 1
    assert np.array_equal(d[:, 1], np.arange(d.shape[0]) * 5e-4)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name", ["quintic-wave.yaml", "butterfly.yaml"])
def test_points_match_an_independent_evaluation(name, method):
    r = curve_file_run(name, method)
    curve = r.run.curve
    a, b = curve.domain
    u = r.u
    assert np.isfinite(r.data).all()
    ref = geomdl_points(curve, u)
    assert np.max(np.abs(r.pts - ref)) <= 1e-9
    # start and end exactly; the parameter never decreases and never passes the end
    assert u[0] == a and u[-1] == b
    assert np.array_equal(r.pts[0], curve.control_points[0]) and np.array_equal(r.pts[-1], curve.control_points[-1])
    assert (np.diff(u) >= 0).all() and (u <= b).all()
    assert (curve.arc_length_at(u) <= curve.length).all()
    assert math.isfinite(r.run.end_gap)
    if method == "exact":
        assert r.run.end_gap == pytest.approx(0.0, abs=1e-9 * curve.length)


@pytest.mark.parametrize("name", ["quintic-wave.yaml", "butterfly.yaml", "tilted-circle-3d.yaml"])
def test_exact_method_follows_the_plan_on_other_curves(name):
    r = curve_file_run(name, "exact")
    s = r.run.curve.arc_length_at(r.u)
    L = r.run.length
    assert np.max(np.abs(s - r.planned)) <= 1e-9 * L
    ds, dS = np.diff(s), np.diff(r.planned)
    counted = dS >= 0.01 * r.run.profile.peak * r.run.period
    assert np.max(np.abs(ds[counted] / dS[counted] - 1.0)) <= 1e-9


def test_quintic_wave_end_gap_is_reported_and_small_for_higher_orders():
    gaps = {m: curve_file_run("quintic-wave.yaml", m).run.end_gap for m in METHODS}
    assert all(math.isfinite(g) for g in gaps.values())
    assert abs(gaps["rk4"]) < abs(gaps["taylor2"]) < abs(gaps["taylor1"])


# =========================================================================== zero parametric speed


ZERO_SPEED = {
    # the example: degree 2 with a repeated control point; speed 0 at u = 0.5
    "deg2-repeated": dict(degree=2, control_points=[[0, 0], [10, 0], [10, 0], [20, 0]]),
    # degree 3 with a doubled interior control point (speed dips, stays > 0)
    "deg3-doubled": dict(degree=3, control_points=[[0, 0], [10, 10], [20, 0], [20, 0], [30, 10], [40, 0]]),
    # degree 3 with a tripled interior control point: speed 0 at the knot u = 0.5
    "deg3-tripled": dict(degree=3, control_points=[[0, 0], [10, 10], [20, 0], [20, 0], [20, 0], [30, 10], [40, 0]]),
    # a cusp: out along x and back, speed 0 at the turn
    "cusp": dict(degree=3, control_points=[[0, 0], [10, 0], [10, 0], [0, 0]]),
    # zero speed at the very first tick
    "start-doubled": dict(degree=2, control_points=[[0, 0], [0, 0], [10, 0], [20, 5]]),
}


@pytest.fixture(scope="module")
def zero_speed_files(tmp_path_factory):
    root = tmp_path_factory.mktemp("zero-speed")
    paths = {}
    for name, curve in ZERO_SPEED.items():
        paths[name] = root / f"{name}.yaml"
        paths[name].write_text(yaml.safe_dump({"curve": curve, "profile": {"feedrate": 50, "accel_time": 0.2},
                                               "interpolator": {"period": "1 ms"}}))
    return paths


_zero_cache: dict = {}


def zero_run(paths, name, method, accdec) -> Run:
    key = (name, method, accdec)
    if key not in _zero_cache:
        _zero_cache[key] = execute(paths[name], interpolator=method, accdec=accdec)
    return _zero_cache[key]


@pytest.mark.parametrize("accdec", ["before", "after"])
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("name", list(ZERO_SPEED))
def test_zero_speed_never_gives_inf_or_nan(zero_speed_files, name, method, accdec):
    r = zero_run(zero_speed_files, name, method, accdec)
    curve = r.run.curve
    a, b = curve.domain
    assert np.isfinite(r.data).all() and np.isfinite(r.planned).all()
    assert math.isfinite(r.run.end_gap)
    assert (np.diff(r.u) >= 0).all() and (r.u >= a).all() and (r.u <= b).all()
    assert np.array_equal(r.pts[-1], curve.control_points[-1])
    if accdec == "before":
        assert np.max(np.abs(r.pts - geomdl_points(curve, r.u))) <= 1e-9


def _zero_params():
    for name in ZERO_SPEED:
        for method in METHODS:
            for accdec in ("before", "after"):
                yield pytest.param(name, method, accdec, id=f"{name}-{method}-{accdec}")


@pytest.mark.parametrize("name,method,accdec", list(_zero_params()))
def test_zero_speed_point_does_not_make_the_command_jump(zero_speed_files, name, method, accdec):
    """Through a point of zero parametric speed the interpolator keeps tracking the plan.

    A planned step is at most Vp·T = 0.05 mm.  Allowed: no tick moves more than 10 planned
    steps and the command never strays more than 20 planned steps from the plan (Taylor
    steps have O(1) relative errors for a few ticks around the singular point; the guard in
    the module docstring promises exact steps where σ is too small for them).
    """
    r = zero_run(zero_speed_files, name, method, accdec)
    K = r.run.last_tick
    VT = 50.0 * 1e-3
    s = r.run.curve.arc_length_at(r.u[:K + 1])
    S = r.planned[:K + 1]
    assert np.max(np.diff(s)) <= 10 * VT
    assert np.max(np.abs(s - S)) <= 20 * VT
    assert abs(r.run.end_gap) <= 20 * VT
