"""The jerk-limited pass resumable in windows (planner.jerk._jerk_window, issue 29 deliver 4).

A long rest-to-rest section with random caps is planned whole (``_jerk_limited``) and in windows: each
window runs from the state the one before committed up to its commit point, its end a stop placed beyond
that point by the reach of any decision of the pass (``reach`` below).  Checked:

- windowed == whole: the committed rows, concatenated, are the whole section's rows to the bit (with the
  whole section's ``PassBounds`` and each window's ``Handover``); without them (the plain call) the plan is
  still safe and within the caps;
- stop-ability: at every commit point the state can stop (V = 0, A = 0) before its window's end within the
  caps, by the pass's own check and by an independent integration of the braking manoeuvre;
- caps: every row, evaluated densely by its own polynomial, keeps V <= cap, |A| <= acap, |J| <= J.

Tolerances: V and |A| are compared with their caps to the rounding the pass allows itself (vtol = 1e-12 of
the top cap below 0, |A| to 1e-12 relative: ATOL_FACTOR) plus what re-evaluating a piece from its row
loses: its duration is a difference of absolute times, known to ulp(t) only, so V to A·ulp(t) and A to
J·ulp(t), a few of each.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from nurbsinterp.planner.jerk import (PassBounds, _brake, _jerk_limited, _jerk_window, _min_table, _pass_bounds,
                                      _safe, _stop_distance)

BUDGET = 10 ** 7


# --------------------------------------------------------------------------- sections nobody tuned


def random_section(seed: int, regime: str):
    """(nodes, caps, acaps, J, dt, coarse): a long section with random caps.

    regimes: "cruise" — caps constant over long runs (the pass holds V at a cap, extending one row over
    many steps, across commit points); "varying" — a cap per interval (a curve's staircase), acceleration
    caps varying too; "coarse" — a step long against the jerk's ramps (the level-off and anchor paths);
    "tiny" — some acceleration caps far below the others (A/J under a step there).
    """
    rng = np.random.default_rng(seed)
    n = int(rng.integers(400, 1200))
    nodes = np.concatenate([[rng.uniform(0.0, 50.0)], rng.uniform(0.02, 1.5, n - 1)]).cumsum()
    J = float(rng.choice([5000.0, 20000.0, 60000.0]))
    dt = float(rng.choice([5e-4, 1e-3]))
    if regime == "cruise":
        runs = np.sort(rng.choice(np.arange(1, n - 1), size=12, replace=False))
        caps = np.repeat(rng.uniform(5.0, 100.0, 13), np.diff(np.concatenate([[0], runs, [n - 1]])))
        acaps = np.full(n - 1, float(rng.uniform(300.0, 3000.0)))
    elif regime == "varying":
        caps = np.clip(60.0 + np.cumsum(rng.normal(0.0, 4.0, n - 1)), 2.0, 150.0)
        acaps = rng.uniform(200.0, 2500.0, n - 1)
    elif regime == "coarse":
        caps = rng.uniform(10.0, 120.0, n - 1)
        acaps = rng.uniform(500.0, 3000.0, n - 1)
        J = 1e6
        dt = 2e-3
    else:  # tiny: on one interval in 20, A/J under a step or nearly (J dt >= 2.5 mm/s²)
        caps = rng.uniform(5.0, 20.0, n - 1)
        acaps = rng.uniform(500.0, 2000.0, n - 1)
        acaps[rng.choice(n - 1, size=n // 20, replace=False)] = rng.uniform(2.5, 10.0, n // 20)
    bounds = _pass_bounds(nodes, caps, acaps)
    ramp = min(bounds.a_top, math.sqrt(J * bounds.v_top)) / J  # as plan.py sets coarse
    return nodes, caps, acaps, J, dt, dt > ramp / 8.0


def reach(caps, acaps, J, dt, bounds):
    """How far beyond its commit point a window's end must lie for the window to decide as the whole does.

    The bound of _jerk_window's docstring: a step within the caps ends within v_top·dt; a braking manoeuvre
    that keeps V <= v_top levels A off within v_top·a_top/J and stops from there within
    _stop_distance(v_top, 0, J, a_floor); and at rest the pass finishes with one unbounded rest-to-rest move
    only over a gap of at most 2·(v_top³/J)^½.
    """
    v_top, a_top, a_floor = float(caps.max()), float(acaps.max()), bounds.a_floor
    return 1.01 * max(v_top * dt + v_top * a_top / J + _stop_distance(v_top, 0.0, J, a_floor),
                      2.0 * math.sqrt(v_top ** 3 / J))


def window(nodes, caps, acaps, s, end_at):
    """The window from s (its nodes[0]) to the first node at or beyond end_at (the section's end at most)."""
    k = min(int(np.searchsorted(nodes, s, side="right")) - 1, nodes.size - 2)
    kend = min(int(np.searchsorted(nodes, end_at, side="left")), nodes.size - 1)
    wnodes = nodes[k: kend + 1].copy()
    wnodes[0] = s
    return wnodes, caps[k: kend].copy(), acaps[k: kend].copy()


def plan_in_windows(nodes, caps, acaps, J, dt, coarse, seed, exact=True):
    """Plan the section window by window: the committed rows (and the end row), and per window
    (window nodes, caps, acaps, the state at its commit point, its Handover, status)."""
    rng = np.random.default_rng(seed + 1000)
    bounds = _pass_bounds(nodes, caps, acaps)
    far = reach(caps, acaps, J, dt, bounds)
    s, v, a = float(nodes[0]), 0.0, 0.0
    carry = None
    t_off = 0.0  # the plain call's windows count their time from 0: shifted onto the ones before
    committed, windows = [], []
    while True:
        s_commit = s + rng.uniform(0.2, 3.0) * far  # windows of every size against the reach
        if s_commit + far >= nodes[-1]:
            s_commit = math.inf
        wn, wc, wa = window(nodes, caps, acaps, s, s_commit + far)
        if exact:
            rows, status, (s, v, a), carry = _jerk_window(wn, wc, wa, J, dt, BUDGET, coarse, v, a, s_commit,
                                                          bounds, carry)
        else:
            rows, status, (s, v, a), carry = _jerk_window(wn, wc, wa, J, dt, BUDGET, coarse, v, a, s_commit)
            rows = rows.copy()
            rows[:, 0] += t_off
            t_off = rows[-1, 0]
        windows.append((wn, wc, wa, (s, v, a), carry, status))
        if status == 0:
            committed.append(rows)
            return np.vstack(committed), windows
        assert status == 2, status
        # the first step that ends at or beyond the commit point is the last (a step may be several pieces)
        assert s >= s_commit and np.all(rows[:-1, 0][rows[:-1, 1] >= s_commit] >= rows[-1, 0] - dt * (1.0 + 1e-9))
        committed.append(rows[:-1])


CASES = [(seed, regime) for regime in ("cruise", "varying", "coarse", "tiny") for seed in range(2)]
#: every regime's first section in the quick set, its second (another draw of the same regime) in the slow set
CASE_PARAMS = [pytest.param((seed, regime), id=f"{regime}-{seed}", marks=pytest.mark.slow if seed else ())
               for seed, regime in CASES]


@pytest.fixture(scope="module", params=CASE_PARAMS)
def planned(request):
    seed, regime = request.param
    sec = random_section(seed, regime)
    whole, status = _jerk_limited(*sec[:5], BUDGET, sec[5])
    assert status == 0
    rows, windows = plan_in_windows(*sec, seed)
    return sec, whole, rows, windows


# --------------------------------------------------------------------------- windowed == whole


def test_windows_plan_the_whole_sections_rows_to_the_bit(planned):
    sec, whole, rows, windows = planned
    assert len(windows) >= 4  # commit points inside the section, not one window over all of it
    assert rows.shape == whole.shape
    assert np.array_equal(rows, whole)


def test_a_cruise_goes_on_across_commit_points():
    """The carried last piece: a hold that spans a commit point stays one row, as in the whole plan."""
    nodes = np.linspace(0.0, 400.0, 401)
    caps = np.full(400, 50.0)
    acaps = np.full(400, 1000.0)
    whole, _ = _jerk_limited(nodes, caps, acaps, 20000.0, 1e-3, BUDGET, False)
    rows, windows = plan_in_windows(nodes, caps, acaps, 20000.0, 1e-3, False, 7)
    assert np.array_equal(rows, whole)
    holds = np.flatnonzero((whole[:-1, 4] == 0.0) & (whole[:-1, 3] == 0.0) & (whole[:-1, 2] == 50.0))
    assert holds.size == 1  # one row over the whole cruise
    t_hold = (whole[holds[0], 0], whole[holds[0] + 1, 0])
    assert sum(t_hold[0] < w[4].t < t_hold[1] for w in windows) >= 2  # commit points inside that row


def test_plain_windows_without_bounds_or_carry_are_safe(planned):
    """The plain call (the window's own bounds, time from 0, the brake level found afresh): a plan
    that keeps every cap and reaches the end at rest, within a few steps of the whole plan's time."""
    sec, whole, _rows, _windows = planned
    nodes, caps, acaps, J, dt, coarse = sec
    rows, windows = plan_in_windows(*sec, 0, exact=False)
    check_caps(rows, nodes, caps, acaps, J, _pass_bounds(nodes, caps, acaps))
    assert rows[-1, 2] == 0.0 and rows[-1, 3] == 0.0
    assert abs(rows[-1, 1] - nodes[-1]) <= 1e-10 * (nodes[-1] - nodes[0])
    for wn, wc, wa, (s, v, a), carry, status in windows[:-1]:
        assert stops_inside(wn, wc, wa, J, s, v, a, carry.ab_safe, _pass_bounds(wn, wc, wa))


# --------------------------------------------------------------------------- stop-ability at every commit point


def brake_path(v, a, J, Ab, samples=64):
    """The braking manoeuvre from (0, v, a), integrated here from its jerks alone: (t, s, v, a) at
    *samples* points per phase.  The phases' durations are _brake's; everything else is recomputed."""
    t1, t2, t3, _ap = _brake(v, a, J, Ab)
    assert t1 >= 0.0, "no stop without V < 0"
    ts, ss, vs, as_ = [], [], [], []
    t0 = s0 = 0.0
    for jerk, dur in ((-J, t1), (0.0, t2), (J, t3)):
        tau = np.linspace(0.0, dur, samples)
        ts.append(t0 + tau)
        ss.append(s0 + v * tau + a * tau ** 2 / 2.0 + jerk * tau ** 3 / 6.0)
        vs.append(v + a * tau + jerk * tau ** 2 / 2.0)
        as_.append(a + jerk * tau)
        t0, s0, v, a = t0 + dur, ss[-1][-1], vs[-1][-1], as_[-1][-1]
    return (np.concatenate(ts), np.concatenate(ss), np.concatenate(vs), np.concatenate(as_))


def stops_inside(wnodes, wcaps, wacaps, J, s, v, a, Ab, bounds):
    """Whether (s, v, a) stops before the window's end within its caps: the pass's own check (_safe)
    and the independent integration agree, and say so."""
    vtab, lg = _min_table(wcaps)
    atab = _min_table(wacaps)[0]
    s_end = wnodes[-1]
    stol = 1e-13 * max(abs(s_end), s_end - wnodes[0])
    jcaps = np.full(wcaps.shape[0], J)  # the pass's jerk everywhere (no per-interval jerk caps)
    kernel = _safe(wnodes, wcaps, wacaps, vtab, atab, jcaps, _min_table(jcaps)[0], lg, J, Ab, s, v, a, s_end, stol,
                   bounds.vtol)
    t, ds, vv, aa = brake_path(v, a, J, Ab)
    sb = s + ds
    k = np.clip(np.searchsorted(wnodes, sb, side="right") - 1, 0, wcaps.size - 1)
    v_scale = max(v, 1.0)
    a_scale = max(abs(a), Ab)
    # rounding of the closed forms against the pass's: a few ulps of the state's magnitudes
    tol_v = 1e-12 * v_scale + 16 * np.spacing(v_scale)
    tol_a = 1e-12 * a_scale
    ok = (np.all(vv >= -bounds.vtol - tol_v) and np.all(vv <= wcaps[k] + tol_v)
          and np.all(np.abs(aa) <= wacaps[k] * (1.0 + 1e-12) + tol_a)
          and abs(vv[-1]) <= tol_v and abs(aa[-1]) <= tol_a and sb[-1] <= s_end + stol)
    assert math.isclose(ds[-1], _stop_distance(v, a, J, Ab), rel_tol=1e-9, abs_tol=1e-12)
    assert kernel == ok
    return ok


def test_every_commit_point_can_stop_inside_its_window(planned):
    sec, _whole, _rows, windows = planned
    nodes, caps, acaps, J, dt, coarse = sec
    bounds = _pass_bounds(nodes, caps, acaps)
    moving = 0
    for wn, wc, wa, (s, v, a), carry, status in windows[:-1]:
        assert status == 2
        assert stops_inside(wn, wc, wa, J, s, v, a, carry.ab_safe, bounds)
        moving += v > 0.0
    assert moving >= 1  # commit points in motion, not only at rest


# --------------------------------------------------------------------------- every row within the caps


def check_caps(rows, nodes, caps, acaps, J, bounds: PassBounds):
    """Every piece evaluated at 16 points and at its V extremum: V <= cap(S), V >= −vtol, |A| <= acap(S),
    |J| <= J.  Near a node S may fall on either side by rounding: either interval's cap is taken there."""
    t0, s0, v0, a0, j = (rows[:-1, i] for i in range(5))
    dur = np.diff(rows[:, 0])
    assert np.all(dur >= 0.0)
    tau = dur[:, None] * np.linspace(0.0, 1.0, 16)[None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(j != 0.0, -a0 / j, 0.0)
    tv = np.clip(tv, 0.0, dur)
    tau = np.hstack([tau, tv[:, None]])
    s = s0[:, None] + tau * (v0[:, None] + tau * (a0[:, None] / 2.0 + tau * j[:, None] / 6.0))
    v = v0[:, None] + tau * (a0[:, None] + tau * j[:, None] / 2.0)
    a = a0[:, None] + tau * j[:, None]
    t_ulp = float(np.spacing(rows[-1, 0]))
    tol_v = 4.0 * bounds.a_top * t_ulp + 1e-12 * bounds.v_top
    tol_a = 4.0 * J * t_ulp + 1e-12 * bounds.a_top
    near = 1e-12 * (nodes[-1] - nodes[0])
    k_lo = np.clip(np.searchsorted(nodes, s - near, side="right") - 1, 0, caps.size - 1)
    k_hi = np.clip(np.searchsorted(nodes, s + near, side="right") - 1, 0, caps.size - 1)
    cap = np.maximum(caps[k_lo], caps[k_hi])
    acap = np.maximum(acaps[k_lo], acaps[k_hi])
    assert np.all(v <= cap + tol_v), float(np.max(v - cap))
    assert np.all(v >= -bounds.vtol - tol_v)
    assert np.all(np.abs(a) <= acap + tol_a), float(np.max(np.abs(a) - acap))
    assert np.all(np.abs(j) <= J * (1.0 + 1e-12))


def test_every_row_keeps_the_caps(planned):
    sec, _whole, rows, _windows = planned
    nodes, caps, acaps, J, _dt, _coarse = sec
    check_caps(rows, nodes, caps, acaps, J, _pass_bounds(nodes, caps, acaps))
    assert rows[-1, 2] == 0.0 and rows[-1, 3] == 0.0
    assert abs(rows[-1, 1] - nodes[-1]) <= 1e-10 * (nodes[-1] - nodes[0])


# --------------------------------------------------------------------------- the statuses


def test_statuses_and_the_state_returned():
    nodes = np.linspace(0.0, 100.0, 101)
    caps = np.full(100, 40.0)
    acaps = np.full(100, 800.0)
    J, dt = 20000.0, 1e-3
    rows, status, (s, v, a), carry = _jerk_window(nodes, caps, acaps, J, dt, 10, False, 0.0, 0.0, math.inf)
    assert status == 1 and tuple(rows[-1, 1:4]) == (s, v, a) and rows[-1, 0] == carry.t
    rows, status, (s, v, a), carry = _jerk_window(nodes, caps, acaps, J, dt, BUDGET, False, 0.0, 0.0, 30.0)
    assert status == 2 and s >= 30.0 and rows[-2, 1] < 30.0 and v > 0.0
    assert tuple(rows[-1, 1:]) == (s, v, a, 0.0)
    assert carry.last == tuple(rows[-2])
    rows2, status, state, _ = _jerk_window(*window(nodes, caps, acaps, s, 100.0), J, dt, BUDGET, False, v, a,
                                           math.inf, _pass_bounds(nodes, caps, acaps), carry)
    assert status == 0 and state[1] == 0.0 and state[2] == 0.0
    assert abs(state[0] - 100.0) <= 1e-10 * 100.0
    # a commit point at or behind the start: nothing to plan, the start is the state
    rows, status, state, carry = _jerk_window(nodes, caps, acaps, J, dt, BUDGET, False, 0.0, 0.0, 0.0)
    assert status == 2 and rows.shape == (1, 5) and state == (0.0, 0.0, 0.0)


def test_a_start_in_motion_with_the_pass_own_choices():
    """From a state in motion without a carry (the plain call) the window brakes to its end within the caps."""
    nodes = np.linspace(0.0, 30.0, 61)
    caps = np.full(60, 60.0)
    acaps = np.full(60, 1000.0)
    J, dt = 20000.0, 5e-4
    rows, status, state, _ = _jerk_window(nodes, caps, acaps, J, dt, BUDGET, False, 50.0, 200.0, math.inf)
    assert status == 0 and state[1] == 0.0
    assert rows[0, 2] == 50.0 and rows[0, 3] == 200.0
    check_caps(rows, nodes, caps, acaps, J, _pass_bounds(nodes, caps, acaps))


def test_a_start_that_cannot_stop_inside_the_window_is_refused():
    """status 3: without a carry, a start whose every braking manoeuvre overruns the window's end."""
    nodes = np.linspace(0.0, 1.0, 11)
    caps = np.full(10, 100.0)
    acaps = np.full(10, 1000.0)
    rows, status, state, _ = _jerk_window(nodes, caps, acaps, 20000.0, 1e-3, BUDGET, False, 90.0, 0.0, math.inf)
    assert status == 3 and rows.shape == (1, 5) and state == (0.0, 90.0, 0.0)
