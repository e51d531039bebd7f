"""Tests of the geometry kernel :mod:`nurbsinterp.nurbs`.

The reference is :mod:`oracle` (naive Cox–de Boor, Eq. 13–14 and 17 of the
paper, quotient rule on homogeneous coordinates), geomdl and scipy for a second
opinion, and closed forms on exact circles.  Tolerances follow from double
precision: 1e-10 relative for evaluation against the oracle, 1e-12 for closed
forms.
"""
from __future__ import annotations

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import quad
from scipy.interpolate import BSpline
from scipy.optimize import minimize_scalar

import oracle
from budgets import budgets
from conftest import (CIRCLE, CIRCLE_CENTRE, CIRCLE_RADIUS, CURVES_DIR, SEEDS, CurveData,
                      per_span_scale, random_curve_data, span_index)
from nurbsinterp import nurbs as kernel
from nurbsinterp.nurbs import NurbsCurve
from nurbsinterp.config import load_job

EVAL_RTOL = 1e-10  # kernel vs oracle, relative to the scale of the values on the span
CLOSED_RTOL = 1e-12  # closed forms
PROPERTY = settings(max_examples=50, deadline=None)


# --------------------------------------------------------------------------- helpers


@functools.lru_cache(maxsize=None)
def random_data(seed: int) -> CurveData:
    return random_curve_data(seed)


@functools.lru_cache(maxsize=None)
def random_curve(seed: int) -> NurbsCurve:
    return random_data(seed).curve()


def circle() -> NurbsCurve:
    return NurbsCurve(**CIRCLE)


def tilted_circle() -> NurbsCurve:
    return NurbsCurve.from_spec(load_job(CURVES_DIR / "tilted-circle-3d.yaml").curve)


def sample_parameters(data: CurveData, rng: np.random.Generator, per_span: int = 16, extra: int = 50) -> np.ndarray:
    """Parameters on every knot span (both ends, so every knot and both domain ends) plus random ones."""
    a, b = data.domain
    knots = np.unique(data.U)
    grid = np.concatenate([np.linspace(lo, hi, per_span + 1) for lo, hi in zip(knots[:-1], knots[1:])])
    return np.concatenate([grid, rng.uniform(a, b, extra), [a, b]])


def assert_matches(got: np.ndarray, want: np.ndarray, scale: np.ndarray, rtol: float, what: str) -> None:
    """|got - want| <= rtol * scale per sample and derivative order, with a readable failure."""
    err = np.linalg.norm(got - want, axis=-1)
    ratio = err / scale
    worst = np.unravel_index(np.argmax(ratio), ratio.shape)
    assert ratio[worst] <= rtol, (
        f"{what}: error {err[worst]:.3e} at sample/order {worst} is {ratio[worst]:.3e} of the scale "
        f"{scale[worst]:.3e} (allowed {rtol:g}); got {got[worst]}, want {want[worst]}")


def oracle_derivatives(data: CurveData, u, order: int = 3, side: str = "right") -> np.ndarray:
    return oracle.curve_derivatives(data.U, data.p, data.V, data.W, u, order, side=side)


def in_span_interiors(data: CurveData, rng: np.random.Generator, per_span: int = 8) -> np.ndarray:
    """Parameters at least 5 % of the span width away from every knot."""
    knots = np.unique(data.U)
    return np.concatenate([lo + (hi - lo) * rng.uniform(0.05, 0.95, per_span)
                           for lo, hi in zip(knots[:-1], knots[1:])])


# --------------------------------------------------------------------------- the oracle itself


@pytest.mark.parametrize("seed", SEEDS[:6])
def test_oracle_basis_matches_scipy(seed):
    """The oracle's basis and its derivatives equal scipy's B-spline basis (a check of the reference)."""
    data = random_data(seed)
    rng = np.random.default_rng(seed)
    us = sample_parameters(data, rng)
    n_ctrl = len(data.W)
    for i in range(n_ctrl):
        coef = np.zeros(n_ctrl)
        coef[i] = 1.0
        spline = BSpline(data.U, coef, data.p)
        for m in range(min(3, data.p) + 1):
            want = spline(us, nu=m)
            got = oracle.basis_derivative(data.U, data.p, i, m, us)
            scale = np.abs(want).max() + 1.0 / (data.domain[1] - data.domain[0]) ** m
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * scale)


def test_oracle_boehm_insertion_keeps_the_curve():
    """The oracle's knot insertion reproduces the oracle curve (a check of the reference)."""
    data = random_data(0)
    us = sample_parameters(data, np.random.default_rng(0))
    U2, V2, W2 = oracle.insert_knot(data.U, data.p, data.V, data.W, 1.234)
    np.testing.assert_allclose(oracle.curve_derivatives(U2, data.p, V2, W2, us, 1),
                               oracle_derivatives(data, us, 1), rtol=1e-12, atol=1e-9)


# --------------------------------------------------------------------------- evaluation vs the oracle


@pytest.mark.parametrize("seed", SEEDS)
def test_derivatives_match_oracle(seed):
    """C, C', C'', C''' match the oracle on every span, at every knot (right-sided) and at both ends."""
    data = random_data(seed)
    curve = random_curve(seed)
    us = sample_parameters(data, np.random.default_rng(seed))
    got = curve.derivatives(us, 3)
    want = oracle_derivatives(data, us)
    assert got.shape == want.shape == (len(us), 4, data.V.shape[1])
    assert_matches(got, want, per_span_scale(data.U, data.p, us, want), EVAL_RTOL, f"seed {seed}")


@pytest.mark.parametrize("seed", SEEDS)
def test_left_limits_at_knots_match_oracle(seed):
    """eval_in_span with the span on the left of a knot gives the oracle's left-continuous derivatives."""
    data = random_data(seed)
    curve = random_curve(seed)
    p, U = data.p, data.U
    spans = np.array([i for i in range(p, len(U) - p - 1) if U[i] < U[i + 1]], dtype=np.int64)
    ends = U[spans + 1].copy()  # the right end of each span, the last one being the domain end
    out = np.empty((len(ends), 4, curve.dim))
    kernel.eval_in_span(U, curve.bezier, p, ends, spans, 3, out)
    want = oracle_derivatives(data, ends, side="left")
    # scale: the left span's own samples
    grid = np.concatenate([np.linspace(U[i], U[i + 1], 17)[1:] for i in spans])
    scale_of = {}
    ref = oracle_derivatives(data, grid, side="left")
    for k, i in enumerate(spans):
        scale_of[i] = np.linalg.norm(ref[16 * k:16 * (k + 1)], axis=-1).max(axis=0)
    scale = np.array([scale_of[i] for i in spans])
    assert_matches(out, want, scale, EVAL_RTOL, f"seed {seed} (left limits)")


@pytest.mark.parametrize("seed", SEEDS[:8])
def test_unsorted_parameters_give_the_same_values(seed):
    """The span-walking hint of eval_many must not change results when u goes backwards or jumps."""
    curve = random_curve(seed)
    us = sample_parameters(random_data(seed), np.random.default_rng(seed))
    order = np.random.default_rng(seed + 1).permutation(len(us))
    np.testing.assert_array_equal(curve.derivatives(us[order], 3), curve.derivatives(us, 3)[order])


@pytest.mark.parametrize("seed", SEEDS)
def test_points_and_tangents_match_geomdl(seed):
    """Points and first derivatives agree with geomdl (NURBS-Python) away from knots."""
    from geomdl import NURBS

    data = random_data(seed)
    curve = random_curve(seed)
    ref = NURBS.Curve(normalize_kv=False)
    ref.degree = data.p
    ref.ctrlptsw = np.column_stack([data.V * data.W[:, None], data.W]).tolist()
    ref.knotvector = data.U.tolist()
    us = in_span_interiors(data, np.random.default_rng(seed))
    want = np.array([ref.derivatives(float(u), order=1) for u in us])
    got = curve.derivatives(us, 1)
    assert_matches(got, want, per_span_scale(data.U, data.p, us, want), EVAL_RTOL, f"seed {seed} vs geomdl")


@pytest.mark.parametrize("seed", SEEDS[:10])
def test_bezier_table_reproduces_the_homogeneous_curve(seed):
    """Each span's Bezier segment (knot insertion) equals the oracle's homogeneous curve A(u), w(u) on that span."""
    from math import comb

    data = random_data(seed)
    curve = random_curve(seed)
    U, p = data.U, data.p
    n = len(U) - p - 2
    Pw = np.column_stack([data.V * data.W[:, None], data.W])
    for i in range(p, n + 1):
        if not U[i] < U[i + 1]:
            continue
        ts = np.linspace(0.0, 1.0, 9)
        us = U[i] + ts * (U[i + 1] - U[i])
        bern = np.array([[comb(p, j) * t ** j * (1 - t) ** (p - j) for j in range(p + 1)] for t in ts])
        got = bern @ curve.bezier[i, 0]
        A, w = oracle.homogeneous_derivatives(U, p, data.V, data.W, us[:-1], 0)
        A_end, w_end = oracle.homogeneous_derivatives(U, p, data.V, data.W, us[-1], 0, side="left")
        want = np.vstack([np.column_stack([A[:, 0], w[:, 0]]), np.append(A_end[0], w_end[0])])
        scale = np.abs(Pw).max()
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * scale, err_msg=f"seed {seed}, span {i}")
        assert kernel.find_span(U, n, p, float(us[3])) == span_index(U, p, np.array([us[3]]))[0]


# --------------------------------------------------------------------------- properties (Hypothesis)


@st.composite
def nurbs_data(draw, *, equal_weights: bool = False) -> CurveData:
    """A clamped NURBS of degree 1–5 in 2-D or 3-D on a domain [a, b] that is not [0, 1]."""
    p = draw(st.integers(1, 5))
    dim = draw(st.sampled_from([2, 3]))
    a = draw(st.floats(-20.0, 20.0))
    width = draw(st.floats(0.1, 30.0))
    b = a + width
    count = draw(st.integers(0, 4))
    gaps = np.array(draw(st.lists(st.floats(1.0, 5.0), min_size=count + 1, max_size=count + 1)))
    inner = a + width * np.cumsum(gaps)[:-1] / gaps.sum()
    mult = draw(st.lists(st.integers(1, p), min_size=count, max_size=count))
    U = np.concatenate([[a] * (p + 1), np.repeat(inner, np.array(mult, dtype=int)), [b] * (p + 1)])
    n_ctrl = len(U) - p - 1
    coord = st.floats(-100.0, 100.0)
    V = np.array(draw(st.lists(st.lists(coord, min_size=dim, max_size=dim), min_size=n_ctrl, max_size=n_ctrl)))
    if equal_weights:
        W = np.full(n_ctrl, draw(st.floats(0.2, 5.0)))
    else:
        W = np.array(draw(st.lists(st.floats(0.2, 5.0), min_size=n_ctrl, max_size=n_ctrl)))
    return CurveData(p, U, V, W)


def hypothesis_parameters(data: CurveData) -> np.ndarray:
    knots = np.unique(data.U)
    return np.concatenate([np.linspace(lo, hi, 9) for lo, hi in zip(knots[:-1], knots[1:])])


@PROPERTY
@given(nurbs_data(equal_weights=True))
def test_equal_weights_give_the_b_spline(data):
    """All weights equal: the NURBS is the polynomial B-spline (scipy), derivatives included."""
    curve = data.curve()
    us = hypothesis_parameters(data)
    top = min(3, data.p)
    got = curve.derivatives(us, 3)
    spline = BSpline(data.U, data.V, data.p)
    want = np.stack([spline(us, nu=k) for k in range(top + 1)], axis=1)
    size = np.abs(data.V).max()
    scale = per_span_scale(data.U, data.p, us, want, size=size)
    assert_matches(got[:, : top + 1], want, scale, EVAL_RTOL, "equal weights vs B-spline")
    # above the degree the B-spline's derivatives vanish; the rational kernel leaves rounding only
    if top == 3:
        return
    zero = np.zeros((len(us), 4, data.V.shape[1]))
    scale = per_span_scale(data.U, data.p, us, zero, size=size)
    assert_matches(got[:, top + 1:], zero[:, top + 1:], scale[:, top + 1:], EVAL_RTOL, "above the degree")


@budgets(quick=10, full=50)
def test_scaling_all_weights_leaves_the_curve(budget):
    """W -> c W is the same curve (homogeneous coordinates): points and derivatives unchanged."""
    @settings(max_examples=budget, deadline=None)
    @given(nurbs_data(), st.floats(1e-3, 1e3))
    def check(data, factor):
        us = hypothesis_parameters(data)
        base = data.curve().derivatives(us, 3)
        scaled = NurbsCurve(data.p, data.V, factor * data.W, data.U).derivatives(us, 3)
        assert_matches(scaled, base, per_span_scale(data.U, data.p, us, base, size=np.abs(data.V).max()),
                       EVAL_RTOL, f"weights x {factor}")

    check()


@PROPERTY
@given(nurbs_data())
def test_endpoint_interpolation(data):
    """C(a) = V_0, C(b) = V_n, and the clamped end tangents C'(a) = p W_1 (V_1 - V_0) / (W_0 (U_{p+1} - U_p))."""
    curve = data.curve()
    a, b = data.domain
    p, U, V, W = data.p, data.U, data.V, data.W
    size = np.abs(V).max()
    np.testing.assert_allclose(curve.evaluate(a), V[0], rtol=0, atol=CLOSED_RTOL * size)
    np.testing.assert_allclose(curve.evaluate(b), V[-1], rtol=0, atol=CLOSED_RTOL * size)
    start = p * W[1] / (W[0] * (U[p + 1] - U[p])) * (V[1] - V[0])
    end = p * W[-2] / (W[-1] * (U[-p - 1] - U[-p - 2])) * (V[-1] - V[-2])
    d = curve.derivatives(np.array([a, b]), 1)
    # rounding scale of a first derivative: p/h times the largest weighted control point over w
    ratio = W.max() / W.min()
    np.testing.assert_allclose(d[0, 1], start, rtol=0, atol=CLOSED_RTOL * p * ratio * size / (U[p + 1] - U[p]))
    np.testing.assert_allclose(d[1, 1], end, rtol=0, atol=CLOSED_RTOL * p * ratio * size / (U[-p - 1] - U[-p - 2]))


@PROPERTY
@given(nurbs_data(), st.integers(0, 2**32 - 1))
def test_affine_invariance(data, seed):
    """Mapping the control points by x -> M x + t maps C by the same map and C^(k) by M."""
    rng = np.random.default_rng(seed)
    dim = data.V.shape[1]
    M = np.linalg.qr(rng.normal(size=(dim, dim)))[0] @ np.diag(rng.uniform(0.5, 2.0, dim))
    t = rng.uniform(-100.0, 100.0, dim)
    us = hypothesis_parameters(data)
    base = data.curve().derivatives(us, 3)
    moved = NurbsCurve(data.p, data.V @ M.T + t, data.W, data.U).derivatives(us, 3)
    want = base @ M.T
    want[:, 0] += t
    scale = per_span_scale(data.U, data.p, us, want, size=np.abs(data.V @ M.T + t).max())
    assert_matches(moved, want, scale, EVAL_RTOL, "affine map")


@PROPERTY
@given(nurbs_data(), st.floats(0.0, 1.0))
def test_knot_insertion_leaves_the_curve(data, where):
    """Boehm insertion of one knot (multiplicity kept <= p) changes no point or derivative."""
    a, b = data.domain
    inner, mult = np.unique(data.U[data.p + 1:-data.p - 1], return_counts=True)
    open_knots = inner[mult < data.p]
    if where < 0.3 and len(open_knots):  # raise the multiplicity of an existing knot
        ubar = float(open_knots[int(where / 0.3 * len(open_knots)) % len(open_knots)])
    else:  # a new knot, not within rounding distance of an old one (knots are >= 4 % apart)
        ubar = a + (b - a) * (0.05 + 0.9 * where)
        if np.min(np.abs(data.U - ubar)) < 0.01 * (b - a):
            ubar += 0.015 * (b - a)
    U2, V2, W2 = oracle.insert_knot(data.U, data.p, data.V, data.W, ubar)
    us = np.concatenate([hypothesis_parameters(data), [ubar]])
    base = data.curve().derivatives(us, 3)
    refined = NurbsCurve(data.p, V2, W2, U2).derivatives(us, 3)
    assert_matches(refined, base, per_span_scale(data.U, data.p, us, base, size=np.abs(data.V).max()),
                   EVAL_RTOL, f"insert {ubar}")


# --------------------------------------------------------------------------- closed forms: circles


def rotated_circle(degrees: float) -> NurbsCurve:
    """The paper's circle turned in its plane about its centre: still radius 50 about (50, 0)."""
    th = math.radians(degrees)
    R = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
    P = (np.array(CIRCLE["control_points"], float) - CIRCLE_CENTRE) @ R.T + CIRCLE_CENTRE
    return NurbsCurve(2, P, CIRCLE["weights"], CIRCLE["knots"])


CIRCLES = {
    "paper": (circle, np.array([50.0, 0.0]), None),
    "tilted-3d": (tilted_circle, np.array([50.0, 0.0, 0.0]), np.array([0.0, -0.5, math.sqrt(3) / 2])),
}


@pytest.mark.parametrize("name", CIRCLES)
def test_circle_radius(name):
    """|C(u) - centre| = 50 to 1e-12 mm at 10^4 parameters (and every knot); 3-D: C stays in its plane."""
    make, centre, normal = CIRCLES[name]
    curve = make()
    us = np.union1d(np.linspace(0.0, 1.0, 10_000), curve.knots)
    P = curve.evaluate(us)
    np.testing.assert_allclose(np.linalg.norm(P - centre, axis=1), CIRCLE_RADIUS, rtol=0, atol=1e-12)
    if normal is not None:
        np.testing.assert_allclose((P - centre) @ normal, 0.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", CIRCLES)
def test_circle_length(name):
    curve = CIRCLES[name][0]()
    assert abs(curve.length - 2 * math.pi * CIRCLE_RADIUS) <= 1e-9


@pytest.mark.parametrize("name", CIRCLES)
def test_circle_curvature(name):
    """kappa = 1/50 to 1e-12 relative everywhere, right-sided at the knots (including the double knot)."""
    curve = CIRCLES[name][0]()
    us = np.union1d(np.linspace(0.0, 1.0, 2001), curve.knots)
    np.testing.assert_allclose(curve.curvature(us), 1.0 / CIRCLE_RADIUS, rtol=CLOSED_RTOL, atol=0)
    assert curve.curvature(0.5) == pytest.approx(1.0 / CIRCLE_RADIUS, rel=CLOSED_RTOL)


@pytest.mark.parametrize("name", CIRCLES)
def test_circle_min_radius(name):
    rho, u = CIRCLES[name][0]().min_radius()
    assert abs(rho - CIRCLE_RADIUS) <= 1e-10
    assert 0.0 <= u <= 1.0


def test_circle_bounding_box():
    lo, hi = circle().bounding_box()
    np.testing.assert_allclose(lo, [0.0, -50.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, [100.0, 50.0], rtol=0, atol=1e-9)


def test_tilted_circle_bounding_box():
    """Radius 50 in the plane turned 30 degrees about x: y spans 50 cos 30, z spans 50 sin 30."""
    lo, hi = tilted_circle().bounding_box()
    h = 50 * math.cos(math.radians(30))
    np.testing.assert_allclose(lo, [0.0, -h, -25.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, [100.0, h, 25.0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("degrees", [17.0, 3.0])
def test_rotated_circle_bounding_box(degrees):
    """Extremes inside knot spans (found by the Brent refinement): box = centre -+ 50."""
    lo, hi = rotated_circle(degrees).bounding_box()
    np.testing.assert_allclose(lo, CIRCLE_CENTRE - 50.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, CIRCLE_CENTRE + 50.0, rtol=0, atol=1e-9)


@pytest.mark.parametrize("degrees", [1.0, 0.5])
def test_rotated_circle_bounding_box_extreme_next_to_a_knot(degrees):
    """Turned by 1 degree, the top of the circle is just inside a span, one sample from its knot."""
    lo, hi = rotated_circle(degrees).bounding_box()
    np.testing.assert_allclose(lo, CIRCLE_CENTRE - 50.0, rtol=0, atol=1e-9)
    np.testing.assert_allclose(hi, CIRCLE_CENTRE + 50.0, rtol=0, atol=1e-9)


def parabola(x0: float) -> NurbsCurve:
    """y = x^2 for x in [x0, 1] as a quadratic Bezier; x is linear in u, the vertex is at u = -x0/(1-x0)."""
    return NurbsCurve(2, [[x0, x0 * x0], [0.5 * (x0 + 1.0), x0], [1.0, 1.0]])


def test_parabola_min_radius():
    """Radius of curvature of y = x^2 at its vertex is 1/2; here the vertex is mid-span."""
    rho, u = parabola(-0.5).min_radius()
    assert rho == pytest.approx(0.5, rel=1e-10)
    assert u == pytest.approx(1.0 / 3.0, abs=1e-6)


def test_parabola_min_radius_peak_next_to_a_knot():
    """The same parabola with its vertex at u = 0.004975, inside the first of 32 sample intervals."""
    rho, _ = parabola(-0.005).min_radius()
    assert rho == pytest.approx(0.5, rel=1e-10)


# --------------------------------------------------------------------------- arc length


@functools.lru_cache(maxsize=None)
def span_lengths(seed: int) -> tuple[tuple[float, float, float], ...]:
    """(start, end, length) of each non-empty knot span, by scipy quad of the oracle's |C'|."""
    data = random_data(seed)
    U = [float(x) for x in data.U]
    out = []
    for lo, hi in zip(np.unique(data.U)[:-1], np.unique(data.U)[1:]):
        def speed(u):  # quad's nodes are interior, so this is the span's own polynomial
            return oracle.speed(U, data.p, data.V, data.W, u)
        val, _ = quad(speed, lo, hi, epsabs=0, epsrel=1e-13, limit=200)
        out.append((float(lo), float(hi), val))
    return tuple(out)


def reference_arc_length(seed: int, u: float) -> float:
    """s(u) from the per-span quad integrals (the last, partial span integrated separately)."""
    data = random_data(seed)
    U = [float(x) for x in data.U]
    s = 0.0
    for lo, hi, length in span_lengths(seed):
        if u >= hi:
            s += length
        elif u > lo:
            s += quad(lambda x: oracle.speed(U, data.p, data.V, data.W, x), lo, u, epsabs=0, epsrel=1e-13, limit=200)[0]
    return s


@pytest.mark.parametrize("seed", SEEDS)
def test_length_matches_independent_integration(seed):
    """Length and s(u) at a few parameters against scipy quad of the oracle speed, per knot span."""
    curve = random_curve(seed)
    want = sum(length for _, _, length in span_lengths(seed))
    assert curve.length == pytest.approx(want, rel=1e-10, abs=0)
    a, b = curve.domain
    us = np.concatenate([np.random.default_rng(seed).uniform(a, b, 3), np.unique(curve.knots)[1:-1]])
    for u in us:
        assert curve.arc_length_at(u) == pytest.approx(reference_arc_length(seed, u), rel=1e-10, abs=1e-12 * want)


@pytest.mark.parametrize("seed", SEEDS)
def test_arc_length_is_additive(seed):
    curve = random_curve(seed)
    a, b = curve.domain
    rng = np.random.default_rng(seed)
    for _ in range(20):
        u0, u1, u2 = np.sort(np.concatenate([rng.uniform(a, b, 2), rng.choice(curve.knots, 1)]))
        whole = curve.arc_length(u0, u2)
        assert whole == pytest.approx(curve.arc_length(u0, u1) + curve.arc_length(u1, u2), rel=CLOSED_RTOL,
                                      abs=CLOSED_RTOL * curve.length)
    assert curve.arc_length() == curve.length
    assert curve.arc_length_at(a) == 0.0
    assert curve.arc_length_at(b) == pytest.approx(curve.length, rel=CLOSED_RTOL)


@pytest.mark.parametrize("seed", SEEDS + ["circle", "tilted"])
def test_parameter_at_inverts_arc_length(seed):
    """u -> s -> u round trip to 1e-12 of the domain (or to 1e-12 L in s where the speed is tiny), and s -> u -> s."""
    curve = {"circle": circle, "tilted": tilted_circle}.get(seed, lambda: random_curve(seed))()
    a, b = curve.domain
    rng = np.random.default_rng(0 if isinstance(seed, str) else seed)
    us = np.concatenate([np.linspace(a, b, 401), rng.uniform(a, b, 200), np.unique(curve.knots)])
    s = curve.arc_length_at(us)
    back = curve.parameter_at(s)
    s_back = curve.arc_length_at(back)
    ok = (np.abs(back - us) <= CLOSED_RTOL * (b - a)) | (np.abs(s_back - s) <= CLOSED_RTOL * curve.length)
    assert ok.all(), f"u {us[~ok]} -> {back[~ok]}"
    ss = np.linspace(0.0, curve.length, 301)
    np.testing.assert_allclose(curve.arc_length_at(curve.parameter_at(ss)), ss, rtol=0, atol=CLOSED_RTOL * curve.length)
    assert np.all(np.diff(curve.parameter_at(ss)) >= 0)


@pytest.mark.parametrize("seed", SEEDS[:10])
def test_step_length_matches_independent_integration(seed):
    """step_length (the per-tick Delta s): short steps inside one panel by the 3-point rule, to 1e-11 of
    the step against quad; steps across panels equal s(u1) - s(u0)."""
    data = random_data(seed)
    curve = random_curve(seed)
    starts, spans, cum = curve.panels
    U = [float(x) for x in data.U]
    work = kernel.make_work(data.p, 1, curve.Pw.shape[1])
    CK = np.empty((2, curve.dim))
    rng = np.random.default_rng(seed)
    for k in rng.integers(0, len(spans), 10):
        width = starts[k + 1] - starts[k]
        h = width / 16 * rng.uniform(0.01, 1.0)
        u0 = starts[k] + rng.uniform(0.0, width - h)
        got = kernel.step_length(data.U, curve.bezier, data.p, starts, spans, cum, u0, u0 + h, work, CK)
        want = quad(lambda x: oracle.speed(U, data.p, data.V, data.W, x), u0, u0 + h,
                    epsabs=0, epsrel=1e-13, limit=200)[0]
        assert got == pytest.approx(want, rel=1e-11, abs=0)
    a, b = curve.domain
    for u0, u1 in np.sort(rng.uniform(a, b, (10, 2)), axis=1):
        got = kernel.step_length(data.U, curve.bezier, data.p, starts, spans, cum, u0, u1, work, CK)
        assert got == pytest.approx(curve.arc_length(u0, u1), rel=0, abs=CLOSED_RTOL * curve.length)


@pytest.mark.parametrize("seed", range(6))
def test_polyline_length_is_the_sum_of_segments(seed):
    """Degree 1 (any weights: a rational map of a segment is the segment): L = sum |V_i+1 - V_i|, s(U_i+1) = partial sums."""
    rng = np.random.default_rng(seed)
    n_ctrl = int(rng.integers(2, 12))
    dim = 2 + seed % 2
    V = rng.uniform(-100.0, 100.0, (n_ctrl, dim))
    W = rng.uniform(0.2, 5.0, n_ctrl)
    a, b = -3.7, 12.1
    inner = np.sort(rng.uniform(a, b, n_ctrl - 2))
    U = np.concatenate([[a, a], inner, [b, b]])
    curve = NurbsCurve(1, V, W, U)
    segments = np.linalg.norm(np.diff(V, axis=0), axis=1)
    assert curve.length == pytest.approx(segments.sum(), rel=CLOSED_RTOL, abs=0)
    np.testing.assert_allclose(curve.arc_length_at(U[1:-1]), np.concatenate([[0.0], np.cumsum(segments)]),
                               rtol=CLOSED_RTOL, atol=CLOSED_RTOL * segments.sum())


# --------------------------------------------------------------------------- closest point


DENSE = 200_000


@functools.lru_cache(maxsize=None)
def dense_samples(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, C(u)) at 2e5 even parameters plus every knot, by the oracle."""
    data = random_data(seed)
    a, b = data.domain
    us = np.union1d(np.linspace(a, b, DENSE + 1), data.U)
    return us, oracle.point(data.U, data.p, data.V, data.W, us)


def brute_force_distance(seed: int, q: np.ndarray) -> tuple[float, float]:
    """(u, distance): best dense sample, refined by bounded Brent between its neighbours."""
    data = random_data(seed)
    us, P = dense_samples(seed)
    d = np.linalg.norm(P - q, axis=1)
    j = int(np.argmin(d))
    lo, hi = us[max(j - 1, 0)], us[min(j + 1, len(us) - 1)]
    U = [float(x) for x in data.U]

    def dist(t):  # offset from the sample: Brent's relative tolerance then acts on t, not u
        u = min(max(us[j] + t, lo), hi)
        return float(np.linalg.norm(oracle.point(U, data.p, data.V, data.W, u) - q))

    res = minimize_scalar(dist, bounds=(lo - us[j], hi - us[j]), method="bounded",
                          options={"xatol": 1e-15 * (us[-1] - us[0])})
    return (float(us[j] + res.x), float(res.fun)) if res.fun < d[j] else (float(us[j]), float(d[j]))


def query_points(seed: int, kind: str) -> np.ndarray:
    """'near': C(u) + a 0.01–2 mm offset in a random direction; 'far': anywhere in a box 3x the curve's."""
    data = random_data(seed)
    rng = np.random.default_rng(10_000 + seed)
    if kind == "near":
        a, b = data.domain
        base = oracle.point(data.U, data.p, data.V, data.W, rng.uniform(a, b, 8))
        offset = rng.normal(size=base.shape)
        offset *= rng.uniform(0.01, 2.0, (len(base), 1)) / np.linalg.norm(offset, axis=1, keepdims=True)
        return base + offset
    lo, hi = data.V.min(axis=0), data.V.max(axis=0)
    mid, half = 0.5 * (lo + hi), 1.5 * (hi - lo)
    return rng.uniform(mid - half, mid + half, (6, data.V.shape[1]))


# Seeds on which the sampled global search (16 samples per span) misses the closest point.
MISSED = {
    ("near", 0): "1.44 mm from the curve, reported 24.4 mm",
    ("near", 11): "1.63 mm from the curve, reported 1.90 mm",
    ("near", 16): "0.34 mm from the curve, reported 2.20 mm",
}


def closest_point_cases() -> list:
    cases = []
    for kind in ("near", "far"):
        for seed in SEEDS:
            marks = ()
            if (kind, seed) in MISSED and False:  # fixed: Newton now starts from every sampled local minimum
                marks = pytest.mark.xfail(
                    reason=f"BUG: project_global samples a fixed 16 points per knot span and runs Newton "
                           f"from the best sample only, so it lands in the wrong basin ({MISSED[kind, seed]})",
                    strict=True)
            cases.append(pytest.param(kind, seed, marks=marks, id=f"{kind}-{seed}"))
    return cases


@pytest.mark.parametrize("kind, seed", closest_point_cases())
def test_closest_point_matches_brute_force(kind, seed):
    """Global closest_point: distance equals brute force to 1e-9 mm and never exceeds it by more."""
    data = random_data(seed)
    curve = random_curve(seed)
    qs = query_points(seed, kind)
    u_found, d_found = curve.closest_point(qs)
    a, b = curve.domain
    assert np.all((u_found >= a) & (u_found <= b)), f"u outside [{a}, {b}]: {u_found}"
    # the reported distance is the distance to the reported parameter
    P = oracle.point(data.U, data.p, data.V, data.W, u_found)
    np.testing.assert_allclose(d_found, np.linalg.norm(P - qs, axis=1), rtol=0, atol=1e-9)
    for q, uf, df in zip(qs, u_found, d_found):
        ub, db = brute_force_distance(seed, q)
        assert df <= db + 1e-9, f"q = {q.tolist()}: found {df} at u = {uf}, brute force {db} at u = {ub}"
        assert abs(df - db) <= 1e-9, f"q = {q.tolist()}: found {df} at u = {uf}, brute force {db} at u = {ub}"


def test_closest_point_at_the_domain_end_stays_in_the_domain():
    """q beyond the end of a Bezier on [-3.7, 12.1]: the answer is exactly the end, u = 12.1."""
    curve = NurbsCurve(2, [[0, 0], [10, 10], [20, 0]], knots=[-3.7] * 3 + [12.1] * 3)
    u, d = curve.closest_point([30.0, 1.0])
    assert u == 12.1
    assert d == pytest.approx(math.hypot(10.0, 1.0), abs=1e-12)
    curve.evaluate(u)  # must not raise


def test_closest_point_on_a_hairpin():
    """Minimal reproduction: one rational quadratic span folding back on itself."""
    data = CurveData(2, np.array([0.0, 0, 0, 1, 1, 1]), np.array([[1.0, 51], [72, 43], [40, 49]]),
                     np.array([0.2, 1.0, 0.2]))
    curve = data.curve()
    q = np.array([36.6, 46.9])
    us = np.linspace(0.0, 1.0, DENSE + 1)
    dist = np.linalg.norm(oracle.point(data.U, 2, data.V, data.W, us) - q, axis=1)
    assert dist.min() < 0.1002  # the true distance, 0.1001 mm near u = 0.091
    _, d = curve.closest_point(q)
    assert d <= dist.min() + 1e-9


@pytest.mark.parametrize("seed", SEEDS)
def test_seeded_closest_point_on_random_curves(seed):
    """Seeded at the parameter a near point came from: never worse than the seed, never below the
    true distance, and never a far branch (the answer lies within 2 |q - C(seed)| of C(seed))."""
    data = random_data(seed)
    curve = random_curve(seed)
    rng = np.random.default_rng(20_000 + seed)
    a, b = curve.domain
    seeds = rng.uniform(a, b, 8)
    base = oracle.point(data.U, data.p, data.V, data.W, seeds)
    offset = rng.normal(size=base.shape)
    offset *= rng.uniform(0.01, 2.0, (len(base), 1)) / np.linalg.norm(offset, axis=1, keepdims=True)
    qs = base + offset
    u, d = curve.closest_point(qs, seeds=seeds)
    assert np.all((u >= a) & (u <= b))
    found = oracle.point(data.U, data.p, data.V, data.W, u)
    np.testing.assert_allclose(d, np.linalg.norm(found - qs, axis=1), rtol=0, atol=1e-9)
    assert np.all(d <= np.linalg.norm(offset, axis=1) + 1e-9)
    assert np.all(np.linalg.norm(found - base, axis=1) <= 2 * np.linalg.norm(offset, axis=1) + 1e-9)
    for q, dq in zip(qs, d):
        assert dq >= brute_force_distance(seed, q)[1] - 1e-9


def circle_seed_cases(curve: NurbsCurve, rng: np.random.Generator, count: int = 400):
    """(seeds, points, exact distances) on a circle: C(u_seed) + offset along the normal, or in any direction."""
    knots = np.unique(curve.knots)
    seeds = np.concatenate([rng.uniform(0.02, 0.98, count), knots])
    d = curve.derivatives(seeds, 2)
    centre = CIRCLE_CENTRE if curve.dim == 2 else np.array([50.0, 0.0, 0.0])
    radial = (d[:, 0] - centre) / CIRCLE_RADIUS
    size = rng.uniform(0.01, 2.0, len(seeds)) * rng.choice([-1.0, 1.0], len(seeds))
    along_normal = d[:, 0] + size[:, None] * radial
    # at the domain ends (the seam C(0) = C(1)) a sideways offset may be closest to the other
    # end, which a seeded search rightly does not look at: there only normal offsets are used
    ends = (seeds == 0.0) | (seeds == 1.0)
    anywhere = rng.normal(size=d[:, 0].shape)
    anywhere[ends] = radial[ends]
    anywhere *= np.abs(size)[:, None] / np.linalg.norm(anywhere, axis=1, keepdims=True)
    anywhere = d[:, 0] + anywhere
    if curve.dim == 3:  # exact distance to a circle in 3-D: in-plane and out-of-plane parts
        normal = np.array([0.0, -0.5, math.sqrt(3) / 2])
        rel = anywhere - centre
        h = rel @ normal
        r = np.linalg.norm(rel - h[:, None] * normal, axis=1)
        exact_any = np.hypot(r - CIRCLE_RADIUS, h)
    else:
        exact_any = np.abs(np.linalg.norm(anywhere - centre, axis=1) - CIRCLE_RADIUS)
    return (np.concatenate([seeds, seeds]), np.concatenate([along_normal, anywhere]),
            np.concatenate([np.abs(size), exact_any]))


@pytest.mark.parametrize("name", CIRCLES)
def test_seeded_closest_point_on_a_circle(name):
    """Seeded projection: exact distance to 1e-9 mm, and the point found is near the seed (no far branch)."""
    curve = CIRCLES[name][0]()
    seeds, qs, exact = circle_seed_cases(curve, np.random.default_rng(7))
    u, d = curve.closest_point(qs, seeds=seeds)
    np.testing.assert_allclose(d, exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(curve.evaluate(u) - qs, axis=1), d, rtol=0, atol=1e-12)
    # the closest point is within |q - C(seed)| of q, hence within twice that of C(seed)
    near = np.linalg.norm(curve.evaluate(u) - curve.evaluate(seeds), axis=1)
    assert np.all(near <= 2 * np.linalg.norm(qs - curve.evaluate(seeds), axis=1) + 1e-9)


@pytest.mark.parametrize("name", CIRCLES)
def test_global_closest_point_on_a_circle(name):
    """Global projection of the same points also gives the exact distance."""
    curve = CIRCLES[name][0]()
    _, qs, exact = circle_seed_cases(curve, np.random.default_rng(8), count=100)
    _, d = curve.closest_point(qs)
    np.testing.assert_allclose(d, exact, rtol=0, atol=1e-9)


@pytest.mark.parametrize("u_end", [0.0, 1.0])
def test_seeded_closest_point_at_the_domain_ends(u_end):
    """Seed at a domain end and a point on the normal there: the answer is that end point."""
    curve = circle()
    for size in (-2.0, -0.01, 0.01, 2.0):
        q = np.array([0.0 + size, 0.0])  # C(0) = C(1) = (0, 0); the normal is the x axis
        u, d = curve.closest_point(q[None], seeds=[u_end])
        assert d[0] == pytest.approx(abs(size), abs=1e-9)
        assert abs(u[0] - u_end) <= 1e-6


# --------------------------------------------------------------------------- shape contract


@pytest.mark.parametrize("name", ["paper", "tilted-3d"])
def test_shapes(name):
    curve = CIRCLES[name][0]()
    dim = curve.dim
    assert curve.evaluate(0.3).shape == (dim,)
    assert curve(0.3).shape == (dim,)
    assert curve.derivatives(0.3, 3).shape == (4, dim)
    assert curve.derivatives(0.3).shape == (2, dim)
    us = np.linspace(0, 1, 7)
    assert curve.evaluate(us).shape == (7, dim)
    assert curve.derivatives(us, 2).shape == (7, 3, dim)
    assert curve.evaluate(us.tolist()).shape == (7, dim)
    assert curve.evaluate(np.array([])).shape == (0, dim)
    assert curve.speed(us).shape == (7,)
    assert isinstance(curve.curvature(0.3), float)
    assert curve.curvature(us).shape == (7,)
    assert isinstance(curve.arc_length_at(0.3), float)
    assert curve.arc_length_at(us).shape == (7,)
    assert isinstance(curve.parameter_at(10.0), float)
    assert curve.parameter_at(np.array([1.0, 2.0])).shape == (2,)
    u, d = curve.closest_point(np.zeros(dim))
    assert isinstance(u, float) and isinstance(d, float)
    u, d = curve.closest_point(np.zeros((5, dim)))
    assert u.shape == d.shape == (5,)
    # the scalar result is the row of the vector result
    np.testing.assert_array_equal(curve.derivatives(0.3, 3), curve.derivatives(np.array([0.3]), 3)[0])


def test_arrays_are_read_only():
    curve = circle()
    for arr in (curve.knots, curve.control_points, curve.weights, curve.Pw, curve.bezier, *curve.panels):
        assert arr.flags.writeable is False
        with pytest.raises(ValueError):
            arr[0] = 0


def test_constructor_copies_its_inputs():
    P = np.array(CIRCLE["control_points"], dtype=float)
    curve = NurbsCurve(2, P, CIRCLE["weights"], CIRCLE["knots"])
    P[:] = 0.0
    assert curve.evaluate(0.25) == pytest.approx([50.0, 50.0], abs=1e-12)


@pytest.mark.parametrize("bad", [-1e-9, 1.0 + 1e-9, -1.0, 2.0, math.nan, math.inf, -math.inf])
def test_out_of_domain_raises(bad):
    curve = circle()
    for call in (curve.evaluate, lambda u: curve.derivatives(u, 2), curve.speed, curve.curvature,
                 curve.arc_length_at):
        with pytest.raises(ValueError):
            call(bad)
        with pytest.raises(ValueError):
            call(np.array([0.5, bad, 0.2]))


def test_out_of_domain_raises_on_a_shifted_domain():
    curve = random_curve(0)  # domain [-3.7, 12.1]
    a, b = curve.domain
    curve.evaluate(np.array([a, b]))  # the ends themselves are fine
    for bad in (np.nextafter(a, -np.inf), np.nextafter(b, np.inf), a - 1.0):
        with pytest.raises(ValueError):
            curve.evaluate(bad)


def test_parameter_at_clamps_and_rejects_non_finite():
    curve = circle()
    assert curve.parameter_at(-5.0) == 0.0
    assert curve.parameter_at(1e9) == 1.0
    for bad in (math.nan, math.inf):
        with pytest.raises(ValueError):
            curve.parameter_at(bad)


def test_zero_speed_gives_infinite_curvature():
    """Two coincident control points at the start: C'(a) = 0, curvature reported as inf."""
    curve = NurbsCurve(2, [[0, 0], [0, 0], [1, 1], [2, 0]])
    assert curve.speed(0.0) == 0.0
    assert curve.curvature(0.0) == math.inf


# --------------------------------------------------------------------------- bundled curves


BUNDLED = sorted(CURVES_DIR.glob("*.yaml"))


def test_there_are_bundled_curves():
    assert len(BUNDLED) >= 4


@pytest.mark.parametrize("path", BUNDLED, ids=[p.stem for p in BUNDLED])
def test_bundled_curve_loads_with_positive_length(path):
    from nurbsinterp.path import job_path

    curve = job_path(load_job(path)).curve  # a path job: the one NURBS of all its blocks
    assert math.isfinite(curve.length) and curve.length > 0
    a, b = curve.domain
    assert np.all(np.isfinite(curve.derivatives(np.linspace(a, b, 101), 3)))


# --------------------------------------------------------------------------- length noise, discrete extrema


def test_length_noise_is_known_without_the_panels_being_asked_for():
    """length_noise is a property of its own: once it was set only as a side effect of `panels`."""
    fresh = circle()
    noise = fresh.length_noise
    assert "panels" not in vars(fresh)
    reference = circle()
    reference.panels  # noqa: B018
    assert noise == reference.length_noise > 0
    assert fresh.resolvable


def test_discrete_minima_brackets_per_span():
    """The sampled extrema search NurbsCurve and the planner share: per span, plateaus and invalid samples."""
    from nurbsinterp.extrema import discrete_minima

    values = np.array([3.0, 1.0, 2.0, 2.0, 5.0, 5.0, 4.0, np.nan, 0.0, -np.inf, 1.0])
    spans = np.array([0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2])
    j, lo, hi = discrete_minima(values, spans)
    # 1.0 inside span 0; 2.0 at span 1's start (bracket: the first interval); 4.0 at its end;
    # nothing next to the NaN; -inf only with finite=False
    assert j.tolist() == [1, 3, 6] and lo.tolist() == [0, 3, 5] and hi.tolist() == [2, 4, 6]
    j, lo, hi = discrete_minima(values, spans, finite=False)
    assert j.tolist() == [1, 3, 6, 9]
    valid = np.ones(values.shape[0], dtype=bool)
    valid[2] = False  # an invalid sample is no minimum and ends the span for its neighbours: no bracket reaches it
    j, lo, hi = discrete_minima(values, spans, valid)
    assert j.tolist() == [1, 3, 6] and lo.tolist() == [0, 3, 5] and hi.tolist() == [1, 4, 6]
