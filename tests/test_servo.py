"""The servo model: model files, the exact ZOH discretisation and the closed-loop recurrence.

Every response of ``ClosedLoop(discretise(...))`` is checked against references built
here by other routes than the code's (which is tf2ss, controllable canonical form, the
matrix exponential of the plant with its integrator):

* the transfer-function route: P(z) = Z{G(s)/s} by ``cont2discrete`` on the
  transfer function (num, den·s), closed with the paper's controller
  C(z) = Kp + Kv(1 − z⁻¹)/T as X_a/X_c = P·C / (1 + Kp·P), run with ``lfilter``;
* the modal route: G(s)/s in partial fractions, each first-order mode sampled
  exactly with its own exponential, the closed loop (with quantisation and
  saturation) stepped by hand.  The transfer-function route loses digits in
  ``ss2tf`` when the numerator of P(z) is tiny against its denominator (a
  third-order plant at 1 ms); the modal route does not, so it is the reference
  for the unusual plants.

Timing (read from ``servo_chunk``): row k outputs the table's position at t_k, then
applies u_k = Kp(c_k − x_k) + Kv(c_k − c_{k−1})/T until t_{k+1}.  So x_k responds to
commands up to c_{k−1} (P(z) is strictly proper), and the loop starts at rest at c_0
with c_{−1} = c_0.
"""
from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.signal import cont2discrete, lfilter

from nurbsinterp.errors import SpecError
from nurbsinterp.servo import PAPER_TABLE, AxisModel, ClosedLoop, ModelError, ServoModel, discretise, load_servo, servo_text

ROOT = Path(__file__).resolve().parents[1]
PAPER_FILE = ROOT / "servo" / "paper-xy.yaml"
XYZ_FILE = ROOT / "servo" / "example-xyz.yaml"
PERIODS = (1e-3, 5e-4)


# --------------------------------------------------------------------------- independent references


def zoh_tf(num, den, T):
    """ZOH transfer function of num/den by the transfer-function route, numerator padded to len(den)."""
    n, d, *_ = cont2discrete((list(num), list(den)), T, method="zoh")
    n = np.atleast_1d(np.squeeze(np.asarray(n, dtype=float)))
    d = np.asarray(d, dtype=float)
    return np.concatenate([np.zeros(len(d) - len(n)), n]), d


def closed_loop_tf(ax: AxisModel, T: float, output: str = "position"):
    """(b, a) in powers of z⁻¹ of X_a/X_c (or V_a/X_c) of one axis."""
    Np, Dp = zoh_tf(ax.num, np.polymul(ax.den, [1.0, 0.0]), T)  # P(z) = Z{G(s)/s}
    ctrl = np.array([ax.kp + ax.kv / T, -ax.kv / T])  # C(z)·z
    if output == "position":
        b = np.polymul(Np, ctrl)
        a = np.polymul([1.0, 0.0], Dp + ax.kp * Np)
    else:  # velocity: V = Gd(z)·U, U = C·X_c/(1 + Kp P)
        Ng, Dg = zoh_tf(ax.num, ax.den, T)
        b = np.polymul(np.polymul(Ng, ctrl), Dp)
        a = np.polymul(np.polymul([1.0, 0.0], Dg), Dp + ax.kp * Np)
    b = np.concatenate([np.zeros(len(a) - len(b)), b])
    return b, a


def tf_response(ax, T, c, output="position"):
    """Response to the command sequence c, the loop at rest at c[0] (superposition of c − c[0])."""
    b, a = closed_loop_tf(ax, T, output)
    base = c[0] if output == "position" else 0.0
    return base + lfilter(b, a, c - c[0])


def modal_reference(ax: AxisModel, T, c, volts=None):
    """The closed loop by partial fractions (distinct poles), with quantisation and saturation.

    With *volts* given, the loop is opened: those voltages drive the plant instead.
    Returns (positions, velocities, voltages).
    """
    num, den = np.asarray(ax.num, float), np.asarray(ax.den, float)
    p = np.roots(den).astype(complex)
    r = np.polyval(num, p) / (p * np.polyval(np.polyder(den), p))  # residues of G(s)/s at p_i
    r0 = num[-1] / den[-1]  # residue at 0: G(0)
    e, g = np.exp(p * T), np.expm1(p * T) / p
    xi, x = c[0] / r0, np.zeros_like(p)
    res, lim = ax.encoder_resolution or 0.0, ax.voltage_limit or np.inf
    prev = c[0]
    n = len(c)
    pos, vel, volt = np.empty(n), np.empty(n), np.empty(n)
    for k in range(n):
        pos[k] = r0 * xi + (r * x).sum().real
        vel[k] = (r * p * x).sum().real
        if volts is None:
            meas = np.floor(pos[k] / res + 0.5) * res if res else pos[k]
            u = min(max(ax.kp * (c[k] - meas) + ax.kv * (c[k] - prev) / T, -lim), lim)
        else:
            u = volts[k]
        volt[k] = u
        prev = c[k]
        x = e * x + g * u
        xi = xi + T * u
    return pos, vel, volt


def run_axis(ax: AxisModel, T, c):
    """The code under test, one axis: (positions, velocities, voltages) as 1-D arrays."""
    model = ServoModel({"x": ax})
    pos, vel, volt = ClosedLoop(discretise(model, T, ["x"])).run(np.asarray(c, float)[:, None])
    return pos[:, 0], vel[:, 0], volt[:, 0]


def step(n, size=1.0):
    c = np.full(n, size)
    c[0] = 0.0
    return c


def ramp(n, T, v):
    return v * T * np.arange(n)


# --------------------------------------------------------------------------- 1. step and ramp responses


@pytest.mark.parametrize("T", PERIODS)
@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("kind", ["step", "ramp"])
def test_paper_axis_responses_match_transfer_function_route(axis, T, kind):
    ax = PAPER_TABLE.axes[axis]
    n = int(round(2.0 / T))
    c = step(n) if kind == "step" else ramp(n, T, 100.0)
    pos, vel, _ = ClosedLoop(discretise(PAPER_TABLE, T, [axis])).run(c[:, None])
    ref = tf_response(ax, T, c)
    np.testing.assert_allclose(pos[:, 0], ref, rtol=0, atol=1e-9)
    assert pos[1, 0] == 0.0 and pos[2, 0] != 0.0  # x_1 responds to c_0 only, x_2 to c_1
    if kind == "step":
        # velocities (up to ~110 mm/s after the feed-forward kick) to 1e-9 relative.  Not for the
        # ramp: there this reference's velocity filter carries Dp(z) in its numerator, whose
        # computed root near z = 1 fails to cancel the ramp's double pole and drifts by ~1e-7 over
        # seconds; ramp velocities are checked by the modal route and the following-error tests.
        vref = tf_response(ax, T, c, "velocity")
        np.testing.assert_allclose(vel[:, 0], vref, rtol=0, atol=1e-9 * np.abs(vref).max())


@pytest.mark.parametrize("T", PERIODS)
@pytest.mark.parametrize("axis", ["x", "y"])
def test_paper_axis_responses_match_modal_route(axis, T):
    """A command with steps, ramps and a sine: positions to 1e-11 mm, velocities to 1e-10 mm/s."""
    ax = PAPER_TABLE.axes[axis]
    n = int(round(0.6 / T))
    t = T * np.arange(n)
    c = 3.0 + np.where(t > 0.05, 1.0, 0.0) + 40.0 * np.clip(t - 0.2, 0, None) + 2.0 * np.sin(2 * np.pi * 7 * t)
    pos, vel, volt = run_axis(ax, T, c)
    P, V, U = modal_reference(ax, T, c)
    np.testing.assert_allclose(pos, P, rtol=0, atol=1e-11)
    np.testing.assert_allclose(vel, V, rtol=0, atol=1e-10)
    np.testing.assert_allclose(volt, U, rtol=1e-12, atol=1e-9)


def test_response_is_causal_by_one_tick():
    """x_k responds to c_0..c_{k-1}: changing c_k leaves x_0..x_k untouched, exactly."""
    T = 1e-3
    c = ramp(200, T, 50.0)
    c2 = c.copy()
    c2[120] += 5.0
    pos, _, _ = run_axis(PAPER_TABLE.axes["x"], T, c)
    pos2, _, _ = run_axis(PAPER_TABLE.axes["x"], T, c2)
    assert np.array_equal(pos[:121], pos2[:121])
    assert pos2[121] != pos[121]


def test_starts_at_rest_at_the_first_command():
    """No motion for a constant command; an offset start is the same response shifted."""
    T = 1e-3
    ax = PAPER_TABLE.axes["y"]
    pos, vel, volt = run_axis(ax, T, np.full(50, -12.5))
    assert np.all(pos == -12.5) and np.all(vel == 0.0) and np.all(volt == 0.0)
    c = step(800, 2.0)
    p0, _, _ = run_axis(ax, T, c)
    p1, _, _ = run_axis(ax, T, c + 37.0)
    np.testing.assert_allclose(p1 - 37.0, p0, rtol=0, atol=1e-12)


def test_chunked_run_equals_one_run_exactly():
    T = 1e-3
    c = np.column_stack([ramp(1000, T, 80.0), 5 * np.sin(np.arange(1000) * T * 9.0)])
    one = ClosedLoop(discretise(PAPER_TABLE, T))
    whole = one.run(c)
    loop = ClosedLoop(discretise(PAPER_TABLE, T))
    parts = [loop.run(c[a:b]) for a, b in [(0, 1), (1, 2), (2, 333), (333, 334), (334, 1000)]]
    for i in range(3):
        assert np.array_equal(np.vstack([p[i] for p in parts]), whole[i])


def test_axes_are_independent():
    """x and y in one loop run exactly as each alone."""
    T = 5e-4
    c = np.column_stack([ramp(600, T, 100.0), step(600, -3.0)])
    pos, vel, volt = ClosedLoop(discretise(PAPER_TABLE, T)).run(c)
    for i, a in enumerate("xy"):
        p1, v1, u1 = ClosedLoop(discretise(PAPER_TABLE, T, [a])).run(c[:, [i]])
        assert np.array_equal(pos[:, i], p1[:, 0]) and np.array_equal(vel[:, i], v1[:, 0])
        assert np.array_equal(volt[:, i], u1[:, 0])


def test_chunk_kernel_is_the_per_tick_task_to_the_bit():
    """servo_chunk runs each axis through the chunk on its own; servo_tick is what a real-time task
    computes per tick (and what `bench` times).  Same numbers to the bit, with quantisation,
    saturation and plants of different orders, chunk after chunk, and into caller-owned arrays."""
    from nurbsinterp.servo import servo_tick

    T = 1e-4
    model = ServoModel({
        "x": AxisModel((50.0,), (1.0, 40.0), kp=20.0, kv=0.5, encoder_resolution=1e-3),
        "y": AxisModel((2.0, 3000.0), (1.0, 80.0, 4000.0, 60000.0), kp=10.0, kv=0.3, voltage_limit=2.0),
        "z": PAPER_TABLE.axes["y"],
    })
    lp = discretise(model, T)
    rng = np.random.default_rng(5)
    c = np.cumsum(rng.normal(scale=0.05, size=(3000, 3)), axis=0)
    state = np.zeros((3, lp.A.shape[1]))
    state[:, -1] = c[0]
    prev = c[0].copy()
    want = np.empty((3, 3000, 3))
    tmp = np.empty(lp.A.shape[1])
    for k in range(3000):
        servo_tick(c[k], lp.A, lp.B, lp.Cv, lp.kp, lp.kv, lp.resolution, lp.limit, lp.period, state, prev,
                   want[0, k], want[1, k], want[2, k], tmp)
    loop = ClosedLoop(lp)
    out = tuple(np.empty((3000, 3)) for _ in range(3))
    for a, b in [(0, 1), (1, 1200), (1200, 3000)]:
        loop.run(c[a:b], out=tuple(o[a:b] for o in out))
    for i in range(3):
        assert np.array_equal(out[i], want[i])
    assert np.array_equal(loop.state, state) and np.array_equal(loop.prev_cmd, prev)


def test_plants_of_different_orders_share_one_kernel():
    """First-, third- and second-order plants (one with a zero) padded to one state size."""
    T = 1e-3
    model = ServoModel({
        "x": AxisModel((50.0,), (1.0, 40.0), kp=20.0, kv=0.5),
        "y": AxisModel((2.0, 3000.0), (1.0, 80.0, 4000.0, 60000.0), kp=10.0, kv=0.3),
        "z": PAPER_TABLE.axes["y"],
    })
    loop = discretise(model, T)
    assert loop.A.shape == (3, 4, 4)
    n = 2000
    k = np.arange(n)
    c = np.column_stack([step(n), 50 * k * T, 5 * np.sin(2 * np.pi * 3 * k * T)])
    pos, vel, _ = ClosedLoop(loop).run(c)
    for i, a in enumerate("xyz"):
        P, V, _ = modal_reference(model.axes[a], T, c[:, i])
        np.testing.assert_allclose(pos[:, i], P, rtol=0, atol=1e-10)
        np.testing.assert_allclose(vel[:, i], V, rtol=0, atol=1e-10)


# --------------------------------------------------------------------------- 2. following error


@pytest.mark.parametrize("T", PERIODS)
@pytest.mark.parametrize("axis", ["x", "y"])
@pytest.mark.parametrize("v", [100.0, -37.5])
def test_steady_following_error(axis, T, v):
    ax = PAPER_TABLE.axes[axis]
    g0 = ax.num[-1] / ax.den[-1]
    expected = (1.0 - ax.kv * g0) * v / (ax.kp * g0)
    assert ax.following_error(v) == pytest.approx(expected, rel=1e-15)
    n = int(round(3.0 / T))  # the slowest closed-loop pole decays below 1e-12 well before 3 s
    c = ramp(n, T, v)
    pos, vel, _ = run_axis(ax, T, c)
    err = c - pos
    np.testing.assert_allclose(err[-int(0.5 / T):], expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(vel[-int(0.5 / T):], v, rtol=0, atol=1e-9)


def test_paper_following_errors_at_100_mm_per_s():
    """X lags 1.0257 mm, Y 0.6725 mm at 100 mm/s (REFERENCE §6 formula, the paper's numbers)."""
    assert PAPER_TABLE.axes["x"].following_error(100.0) == pytest.approx(1.0256851608151167, abs=1e-12)
    assert PAPER_TABLE.axes["y"].following_error(100.0) == pytest.approx(0.6724771468922067, abs=1e-12)
    assert PAPER_TABLE.axes["x"].dc_gain == 112570.543 / 113727.10


# --------------------------------------------------------------------------- 3. quantisation and saturation


def decomposition_check(ax, T, c, pos, volt):
    """The loop is fully pinned down by (a) the voltage law applied to the measured position
    and (b) the plant driven by those voltages."""
    res, lim = ax.encoder_resolution or 0.0, ax.voltage_limit or np.inf
    meas = np.floor(pos / res + 0.5) * res if res else pos
    prev = np.concatenate([[c[0]], c[:-1]])
    law = np.clip(ax.kp * (c - meas) + ax.kv * (c - prev) / T, -lim, lim)
    np.testing.assert_allclose(volt, law, rtol=1e-13, atol=1e-12)
    P, _, _ = modal_reference(ax, T, c, volts=volt)
    np.testing.assert_allclose(pos, P, rtol=0, atol=1e-10)
    return meas, law


@pytest.mark.parametrize("axis", ["x", "y"])
def test_encoder_quantises_the_measured_position(axis):
    T, r = 1e-3, 0.01
    ax = dataclasses.replace(PAPER_TABLE.axes[axis], encoder_resolution=r)
    n = 1500
    c = np.concatenate([ramp(500, T, 23.0), np.full(n - 500, 500 * T * 23.0)])
    pos, vel, volt = run_axis(ax, T, c)
    meas, _ = decomposition_check(ax, T, c, pos, volt)
    # the voltage is computed from a multiple of r, never from the true position
    assert np.allclose(np.round(meas / r), meas / r, rtol=0, atol=1e-9)
    exact, _, volt_exact = run_axis(PAPER_TABLE.axes[axis], T, c)
    assert np.abs(pos - exact).max() > r / 10  # quantisation changes the motion
    # the full nonlinear loop by the modal route agrees
    P, _, U = modal_reference(ax, T, c)
    np.testing.assert_allclose(pos, P, rtol=0, atol=1e-10)
    np.testing.assert_allclose(volt, U, rtol=0, atol=1e-9)


@pytest.mark.parametrize("axis", ["x", "y"])
def test_quantised_loop_stops_inside_the_dead_band(axis):
    """A step of 10 counts: the loop stops where the encoder reads the command; the true
    position keeps a static error below half a count, and the voltage is exactly 0."""
    T, r = 1e-3, 0.01
    ax = dataclasses.replace(PAPER_TABLE.axes[axis], encoder_resolution=r)
    c = step(3000, 10 * r)
    pos, vel, volt = run_axis(ax, T, c)
    tail = slice(2000, None)
    assert np.all(volt[tail] == 0.0)
    assert np.all(np.floor(pos[tail] / r + 0.5) * r == c[-1])
    assert 0 < abs(pos[-1] - c[-1]) <= r / 2
    exact, _, _ = run_axis(PAPER_TABLE.axes[axis], T, c)
    assert abs(exact[-1] - c[-1]) < 1e-12  # without the encoder the type-1 loop has no static error


@pytest.mark.parametrize("size", [1.0, -1.0])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_voltage_saturation(axis, size):
    T, lim = 1e-3, 5.0
    ax = dataclasses.replace(PAPER_TABLE.axes[axis], voltage_limit=lim)
    c = step(1500, size)
    pos, vel, volt = run_axis(ax, T, c)
    _, law = decomposition_check(ax, T, c, pos, volt)
    assert np.abs(volt).max() == lim and volt[1] == np.sign(size) * lim
    unclipped = ax.kp * (c - pos) + ax.kv * (c - np.concatenate([[0.0], c[:-1]])) / T
    hit = np.abs(unclipped) > lim
    assert hit.sum() > 10
    assert np.all(volt[hit] == np.sign(unclipped[hit]) * lim)
    np.testing.assert_allclose(volt[~hit], unclipped[~hit], rtol=1e-13, atol=1e-12)
    P, _, U = modal_reference(ax, T, c)
    np.testing.assert_allclose(pos, P, rtol=0, atol=1e-10)
    np.testing.assert_allclose(volt, U, rtol=0, atol=1e-9)


@pytest.mark.parametrize("v", [100.0, -100.0])
@pytest.mark.parametrize("axis", ["x", "y"])
def test_saturated_table_runs_at_its_top_speed(axis, v):
    """Commanded faster than G(0)·limit, the table settles at exactly that speed."""
    T, lim = 1e-3, 20.0
    ax = dataclasses.replace(PAPER_TABLE.axes[axis], voltage_limit=lim)
    pos, vel, volt = run_axis(ax, T, ramp(2000, T, v))
    assert np.all(volt[-500:] == np.sign(v) * lim)
    np.testing.assert_allclose(vel[-100:], np.sign(v) * ax.dc_gain * lim, rtol=0, atol=1e-9)


def test_quantisation_and_saturation_are_per_axis():
    T = 1e-3
    model = ServoModel({"x": dataclasses.replace(PAPER_TABLE.axes["x"], encoder_resolution=0.01, voltage_limit=3.0),
                        "y": PAPER_TABLE.axes["y"]})
    c = np.column_stack([step(800, 1.0), step(800, 1.0)])
    pos, _, volt = ClosedLoop(discretise(model, T)).run(c)
    ref, _, _ = ClosedLoop(discretise(PAPER_TABLE, T, ["y"])).run(c[:, [1]])
    assert np.array_equal(pos[:, 1], ref[:, 0])
    assert np.abs(volt[:, 0]).max() == 3.0 and np.abs(volt[:, 1]).max() > 100.0


def test_example_xyz_z_axis_quantised_and_saturated():
    model = load_servo(XYZ_FILE)
    z = model.axes["z"]
    T = 1e-3
    c = step(1000, 0.5)
    pos, vel, volt = run_axis(z, T, c)
    decomposition_check(z, T, c, pos, volt)
    assert np.abs(volt).max() == 10.0


# --------------------------------------------------------------------------- 4. stability


def closed_loop_radius(ax, T, kp, _cache={}):
    key = (ax.num, ax.den, T)
    if key not in _cache:
        _cache[key] = zoh_tf(ax.num, np.polymul(ax.den, [1.0, 0.0]), T)
    Np, Dp = _cache[key]
    return float(np.abs(np.roots(Dp + kp * Np)).max())


@pytest.mark.parametrize("axis", ["x", "y"])
def test_unstable_loop_refused(axis):
    bad = ServoModel({**PAPER_TABLE.axes, axis: dataclasses.replace(PAPER_TABLE.axes[axis], kp=1e5)}, "m.yaml")
    with pytest.raises(SpecError) as info:
        discretise(bad, 1e-3)
    msg = str(info.value)
    assert "\n" not in msg
    assert f"axes.{axis}" in msg and "unstable" in msg and "m.yaml" in msg and "0.001" in msg
    radius = float(re.search(r"pole magnitude ([0-9.eE+-]+)", msg).group(1))
    assert radius == pytest.approx(closed_loop_radius(PAPER_TABLE.axes[axis], 1e-3, 1e5), rel=1e-5)


@pytest.mark.parametrize("T", PERIODS)
@pytest.mark.parametrize("axis", ["x", "y"])
def test_stability_limit_matches_characteristic_polynomial(axis, T):
    """Bisect the critical kp on roots(Dp + kp·Np) (transfer-function route); the code accepts
    1 % below it and refuses 1 % above it."""
    ax = PAPER_TABLE.axes[axis]
    lo, hi = 1.0, 1e7
    for _ in range(100):
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if closed_loop_radius(ax, T, mid) < 1 else (lo, mid)
    assert 100 < lo < 1e4  # the paper's gains have a wide margin
    discretise(ServoModel({axis: dataclasses.replace(ax, kp=0.99 * lo)}), T)
    with pytest.raises(SpecError, match="unstable"):
        discretise(ServoModel({axis: dataclasses.replace(ax, kp=1.01 * lo)}), T)


# --------------------------------------------------------------------------- 5. model files


def paper_doc():
    return yaml.safe_load(PAPER_FILE.read_text())


def write(tmp_path, doc_or_text):
    path = tmp_path / "servo.yaml"
    path.write_text(doc_or_text if isinstance(doc_or_text, str) else yaml.safe_dump(doc_or_text, sort_keys=False))
    return path


def refused(tmp_path, doc_or_text, *parts):
    path = write(tmp_path, doc_or_text)
    with pytest.raises(SpecError) as info:
        load_servo(path)
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert msg.startswith(str(path)), msg
    for part in parts:
        assert part in msg, (part, msg)
    return msg


def edit(func):
    doc = paper_doc()
    func(doc)
    return doc


def test_paper_file_equals_builtin_table():
    model = load_servo(PAPER_FILE)
    assert model.names == ["x", "y"]
    assert model.axes == PAPER_TABLE.axes
    assert model.source == str(PAPER_FILE)
    assert load_servo(None) is PAPER_TABLE


def test_example_xyz_loads_with_three_axes():
    model = load_servo(XYZ_FILE)
    assert model.names == ["x", "y", "z"]
    assert model.axes["x"] == PAPER_TABLE.axes["x"] and model.axes["y"] == PAPER_TABLE.axes["y"]
    z = model.axes["z"]
    assert (z.num, z.den, z.kp, z.kv) == ((4e6,), (1.0, 1800.0, 4e5), 6.0, 0.09)
    assert (z.encoder_resolution, z.voltage_limit) == (0.001, 10.0)
    assert z.dc_gain == 10.0
    discretise(model, 1e-3)  # stable at the paper's period


@pytest.mark.parametrize("text, parts", [
    ("foo: 1\n", ["foo", "not a known key"]),
    ("{}\n", ["axes"]),
    ("axes:\n", ["axes", "mapping"]),
    ("axes: {}\n", ["axes", "empty"]),
    ("axes: [1, 2]\n", ["axes", "mapping"]),
], ids=["unknown-top-key", "missing-axes", "axes-null", "axes-empty", "axes-list"])
def test_missing_or_malformed_axes(tmp_path, text, parts):
    refused(tmp_path, text, *parts)


CASES = {
    "unknown-top-key": (lambda d: d.update(extra=1), ["extra", "not a known key"]),
    "unknown-axis-name": (lambda d: d["axes"].update(w={"kp": 1}), ["axes.w", "not a known key"]),
    "unknown-axis-key": (lambda d: d["axes"]["x"].update(gain=1), ["axes.x.gain", "not a known key"]),
    "unknown-plant-key": (lambda d: d["axes"]["y"]["plant"].update(zeros=[1]), ["axes.y.plant.zeros", "not a known key"]),
    "missing-x": (lambda d: d["axes"].pop("x"), ["axes", "'x'"]),
    "missing-y": (lambda d: d["axes"].pop("y"), ["axes", "'y'"]),
    "missing-plant": (lambda d: d["axes"]["x"].pop("plant"), ["axes.x", "'plant'"]),
    "missing-kp": (lambda d: d["axes"]["y"].pop("kp"), ["axes.y", "'kp'"]),
    "missing-kv": (lambda d: d["axes"]["x"].pop("kv"), ["axes.x", "'kv'"]),
    "axis-not-mapping": (lambda d: d["axes"].update(x=5), ["axes.x", "mapping"]),
    "plant-not-mapping": (lambda d: d["axes"]["x"].update(plant=[1, 2]), ["axes.x.plant", "mapping"]),
    "plant-missing-num": (lambda d: d["axes"]["x"]["plant"].pop("num"), ["axes.x.plant", "'num'"]),
    "plant-missing-den": (lambda d: d["axes"]["y"]["plant"].pop("den"), ["axes.y.plant", "'den'"]),
    "num-not-number": (lambda d: d["axes"]["x"]["plant"].update(num=["abc"]), ["axes.x.plant.num[0]", "not a number"]),
    "den-not-number": (lambda d: d["axes"]["y"]["plant"].update(den=[1, "x", 3]), ["axes.y.plant.den[1]", "not a number"]),
    "den-bool": (lambda d: d["axes"]["x"]["plant"].update(den=[1, True, 3]), ["axes.x.plant.den[1]", "not a number"]),
    "den-nan": (lambda d: d["axes"]["x"]["plant"].update(den=[1, float("nan"), 3]), ["axes.x.plant.den[1]", "finite"]),
    "den-empty": (lambda d: d["axes"]["x"]["plant"].update(den=[]), ["axes.x.plant.den", "non-empty list"]),
    "num-scalar": (lambda d: d["axes"]["x"]["plant"].update(num=5), ["axes.x.plant.num", "list"]),
    "den-leading-zero": (lambda d: d["axes"]["x"]["plant"].update(den=[0, 1, 3]), ["axes.x.plant.den[0]", "must not be 0"]),
    "improper": (lambda d: d["axes"]["x"]["plant"].update(num=[1, 2, 3, 4]), ["axes.x.plant", "must be proper"]),
    "improper-order-0": (lambda d: d["axes"]["y"]["plant"].update(num=[1, 2], den=[3]), ["axes.y.plant", "must be proper"]),
    "order-above-8": (lambda d: d["axes"]["x"]["plant"].update(den=[1] * 10), ["axes.x.plant.den", "order of 8"]),
    "kp-zero": (lambda d: d["axes"]["x"].update(kp=0), ["axes.x.kp", "> 0"]),
    "kp-negative": (lambda d: d["axes"]["y"].update(kp=-3), ["axes.y.kp", "> 0"]),
    "kp-text": (lambda d: d["axes"]["y"].update(kp="fast"), ["axes.y.kp", "not a number"]),
    "kp-inf": (lambda d: d["axes"]["y"].update(kp=float("inf")), ["axes.y.kp", "finite"]),
    "kv-text": (lambda d: d["axes"]["x"].update(kv="x"), ["axes.x.kv", "not a number"]),
    "encoder-zero": (lambda d: d["axes"]["x"].update(encoder_resolution=0), ["axes.x.encoder_resolution", "> 0"]),
    "encoder-negative": (lambda d: d["axes"]["y"].update(encoder_resolution=-1e-3), ["axes.y.encoder_resolution", "> 0"]),
    "voltage-limit-zero": (lambda d: d["axes"]["x"].update(voltage_limit=0), ["axes.x.voltage_limit", "> 0"]),
    "voltage-limit-negative": (lambda d: d["axes"]["y"].update(voltage_limit=-10), ["axes.y.voltage_limit", "> 0"]),
    "dc-gain-zero-num": (lambda d: d["axes"]["x"]["plant"].update(num=[1, 0]), ["axes.x.plant", "DC gain"]),
    "dc-gain-all-zero-num": (lambda d: d["axes"]["y"]["plant"].update(num=[0, 0]), ["axes.y.plant", "DC gain"]),
    "dc-gain-pole-at-zero": (lambda d: d["axes"]["x"]["plant"].update(den=[1, 2, 0]), ["axes.x.plant", "DC gain"]),
    "period-text": (lambda d: d.update(period="fast"), ["period", "'fast'"]),
    "period-zero": (lambda d: d.update(period=0), ["period", "> 0"]),
    "period-length": (lambda d: d.update(period="1 mm"), ["period", "not a time"]),
}


@pytest.mark.parametrize("case", list(CASES))
def test_model_file_rule(tmp_path, case):
    mutate, parts = CASES[case]
    refused(tmp_path, edit(mutate), *parts)


def test_model_file_unreadable(tmp_path):
    with pytest.raises(SpecError, match="cannot read"):
        load_servo(tmp_path / "nope.yaml")
    refused(tmp_path, "", "empty")
    refused(tmp_path, "axes: [\n", "line")


def test_model_file_accepts_what_the_rules_allow(tmp_path):
    doc = edit(lambda d: (d["axes"]["x"]["plant"].update(num=[0, 0, 112570.543]),
                          d["axes"]["x"].update(kv=-0.1, kp="40", encoder_resolution=None),
                          d["axes"]["y"].update(encoder_resolution=0.0005, voltage_limit=10)))
    model = load_servo(write(tmp_path, doc))
    assert model.axes["x"] == dataclasses.replace(PAPER_TABLE.axes["x"], kv=-0.1)  # leading zeros dropped
    assert model.axes["y"].encoder_resolution == 0.0005 and model.axes["y"].voltage_limit == 10.0


# --------------------------------------------------------------------------- proper plants: a drive with a direct path


def hal_drive_loop(c, T, kp, kv, gain, lowpass):
    """LinuxCNC's loop of examples/linuxcnc/sim-machine.hal by hand, per tick: pid (P on the previous command, FF1:
    u = kp (c_k − x_k) + kv (c_k − c_{k−1}) / T with kp = Pgain, kv = FF1 − Pgain T), a ``lowpass`` of gain
    *lowpass* (out += (in − out) g; None: none), ``integ`` (x += out T) scaled by *gain*.  Positions at the
    ticks, before each tick's update (servo.py's timing)."""
    x, y, prev = c[0], 0.0, c[0]
    pos = np.empty(len(c))
    for k in range(len(c)):
        pos[k] = x
        u = kp * (c[k] - x) + kv * (c[k] - prev) / T
        prev = c[k]
        y = u if lowpass is None else y + (u - y) * lowpass
        x += gain * y * T
    return pos


def hal_lowpass_plant(gain, g, T):
    """The continuous plant whose ZOH sample, with position appended, is ``lowpass`` (gain g) then ``integ``:
    K (b₁ s + a) / (s + a), p = 1 − g, a = −ln p / T, b₁ = 1 − a T p / (1 − p)."""
    p = 1.0 - g
    a = -np.log(p) / T
    b1 = 1.0 - a * T * p / (1.0 - p)
    return (gain * b1, gain * a), (1.0, a)


def wiggly_commands(n, T, seed):
    """A command of n ticks from rest: a smoothed random walk (mm)."""
    rng = np.random.default_rng(seed)
    v = np.cumsum(rng.normal(0.0, 2.0, n))  # mm/s
    c = np.cumsum(v) * T
    c[:20] = 0.0
    return c - c[20] + 0.0


@pytest.mark.parametrize("g", [0.05, 0.2, 0.35, 0.9])
@pytest.mark.parametrize("T", PERIODS)
def test_hal_lowpass_drive_is_a_proper_plant(g, T):
    """A HAL ``lowpass`` before ``integ`` is the ZOH sample of the proper K(b₁s + a)/(s + a): the loop through it,
    simulated from the model file's form, follows the loop run by hand tick by tick to 1e-9 mm."""
    kp, ff1, gain = 60.0, 0.95, 1.3
    kv = ff1 - kp * T
    num, den = hal_lowpass_plant(gain, g, T)
    ax = AxisModel(num, den, kp, kv)
    c = wiggly_commands(4000, T, int(g * 100))
    pos, vel, _ = run_axis(ax, T, c)
    ref = hal_drive_loop(c, T, kp, kv, gain, g)
    assert np.abs(pos - ref).max() <= 1e-9 * max(1.0, np.abs(c).max()), np.abs(pos - ref).max()
    assert np.abs(c).max() > 0.1  # it moved
    # the velocity just before each tick: the plant's lag state plus its direct part of the voltage held
    assert np.all(np.isfinite(vel)) and abs(vel[0]) == 0.0


@pytest.mark.parametrize("T", PERIODS)
def test_ideal_velocity_drive(T):
    """G = K (num [K], den [1]: ``integ`` alone): the position moves by K u T a tick, the velocity before a tick is
    K times the voltage held over the tick before, and the loop is the one run by hand."""
    kp, ff1, gain = 80.0, 1.0, 0.9
    kv = ff1 - kp * T
    ax = AxisModel((gain,), (1.0,), kp, kv)
    c = wiggly_commands(3000, T, 5)
    pos, vel, volt = run_axis(ax, T, c)
    np.testing.assert_allclose(pos, hal_drive_loop(c, T, kp, kv, gain, None), rtol=0, atol=1e-12)
    np.testing.assert_allclose(vel[1:], gain * volt[:-1], rtol=1e-14, atol=1e-12)
    np.testing.assert_allclose(np.diff(pos) / T, vel[1:], rtol=0, atol=1e-9)


def test_proper_plant_in_a_model_file_and_beside_a_strict_one(tmp_path):
    """A model file with a proper plant on one axis (the held voltage an extra state) and the paper's on the
    other: each axis as it runs alone, and the pre-compensator's closed loop of the proper one (its
    polynomials, run with lfilter) gives the simulated positions."""
    from nurbsinterp import precompensate as P

    T = 1e-3
    num, den = hal_lowpass_plant(1.0, 0.2, T)
    doc = paper_doc()
    doc["axes"]["y"]["plant"] = {"num": [float(v) for v in num], "den": [float(v) for v in den]}
    doc["axes"]["y"]["kp"] = 60.0
    doc["axes"]["y"]["kv"] = 0.95 - 60.0 * T
    model = load_servo(write(tmp_path, doc))
    c = np.stack([wiggly_commands(2000, T, 1), wiggly_commands(2000, T, 2)], axis=1)
    pos, _, _ = ClosedLoop(discretise(model, T)).run(c)
    for i, name in enumerate(model.names):
        alone, _, _ = run_axis(model.axes[name], T, c[:, i])
        np.testing.assert_array_equal(pos[:, i], alone)
    np.testing.assert_allclose(pos[:, 1], hal_drive_loop(c[:, 1], T, 60.0, 0.95 - 60.0 * T, 1.0, 0.2), rtol=0,
                               atol=1e-9)
    loop = P.closed_loop(model, T, ["y"])[0]
    b = np.concatenate([np.zeros(loop.delay), loop.num])
    via = c[0, 1] + lfilter(b, loop.den, c[:, 1] - c[0, 1])
    np.testing.assert_allclose(via, pos[:, 1], rtol=0, atol=1e-9)


def test_a_model_written_back_reads_back_to_the_bit(tmp_path):
    """servo_text (identify's writer): every coefficient, gain, encoder, limit and the period read back exactly."""
    model = ServoModel({"x": AxisModel((0.1 + 0.2, 7.0 / 3.0), (1.0, 1e-300 + 287.68207245178087), 60.0, 0.95 - 0.06,
                                       5e-4, 10.0),
                        "y": PAPER_TABLE.axes["y"],
                        "z": AxisModel((1.02,), (1.0,), 90.0, 0.86)}, "src", 1e-3)
    path = tmp_path / "back.yaml"
    path.write_text(servo_text(model, ["a header"], {"x": ["a note"]}))
    back = load_servo(path)
    assert back.period == model.period and back.axes == model.axes


def test_a_model_holds_at_its_period_only(tmp_path):
    path = tmp_path / "timed.yaml"
    path.write_text(PAPER_FILE.read_text() + "period: 1 ms\n")
    model = load_servo(path)
    assert model.period == 1e-3
    discretise(model, 1e-3 * (1 + 1e-12))  # a CSV period's rounding
    with pytest.raises(SpecError, match=r"period = 1 ms: the model holds at that period only .* 0.5 ms"):
        discretise(model, 0.5e-3)
    assert ModelError("g", {"x": 1.05}, {}).apply(model).period == 1e-3
