"""A smooth cruise in the adaptive schedule (issue 12, item 5).

Where the jerk-limited plan holds its feedrate at a constant cap, the acceleration
and the jerk must be zero, not a bang-bang chatter of ±J·T from tick to tick (which a
drive turns into audible vibration).

*Cruise stretch*, as measured here from the plan alone: the cap at a point of the path
is the planner's interval cap min(V_lim) of the grid interval holding it
(``AdaptivePlan.s_grid``, ``v_limit``).  A cruise stretch is a maximal run of ticks
whose cap is one constant C (to 1e-9) and whose feedrate is within RHO of it,
V >= (1 − RHO) C / λ (λ the stretch onto a tick), minus its *ramp ends*: the time
a jerk-limited motion needs to cross that band, twice the cubic ramp from A = 0,
(6 RHO C / J)^(1/3), at each end.  RHO = 1e-3 holds the chatter of the old planner
(its feedrate swung by 3e-4 of F) and still leaves the ends a few ticks long.  On
every stretch, the acceptance: |A| <= 1e-6 max_accel and |J| <= 1e-6 max_jerk, on
the ticks, on the tick differences of A, and on every piece of the segment table.
"""
from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from conftest import random_curve_data

from nurbsinterp.nurbs import NurbsCurve
from nurbsinterp.planner import AdaptivePlan, plan_adaptive
from nurbsinterp.config import load_job

ROOT = Path(__file__).resolve().parent.parent
T = 1e-3  # s
A_MAX, J_MAX = 1000.0, 30000.0
BUTTERFLY = dict(feedrate=100.0, chord_tolerance=1e-3, max_accel=A_MAX, max_jerk=J_MAX)  # profiles/adaptive.yaml
#: the random curves: the chord tolerance and an axis velocity bind besides the feedrate, so that
#: the caps held are F, v_x/|τ_x| on the straight legs of a polyline, and levels between
RANDOM = dict(feedrate=80.0, chord_tolerance=1e-3, max_accel=A_MAX, max_jerk=J_MAX, axes={"x": {"max_velocity": 60.0}})
#: two seeds of conftest.random_curve_data for each degree 1..5 (2-D and 3-D, C⁰ joins, any domain)
SEEDS = {1: (11, 14), 2: (21, 24), 3: (1, 6), 4: (5, 8), 5: (2, 3)}
RHO = 1e-3
QUIET = 1e-6  # of max_accel and of max_jerk


@functools.lru_cache(maxsize=None)
def butterfly_plan() -> AdaptivePlan:
    curve = NurbsCurve.from_spec(load_job(ROOT / "curves" / "butterfly.yaml").curve)
    return plan_adaptive(curve, T, **BUTTERFLY)


@functools.lru_cache(maxsize=None)
def random_plan(seed: int) -> AdaptivePlan:
    return plan_adaptive(random_curve_data(seed).curve(), T, **RANDOM)


def interval_caps(p: AdaptivePlan, S: np.ndarray) -> np.ndarray:
    """The planner's interval cap min(V_lim(s_i), V_lim(s_i+1)) at arc lengths S (mm/s)."""
    i = np.clip(np.searchsorted(p.s_grid, S, side="right") - 1, 0, p.s_grid.shape[0] - 2)
    return np.minimum(p.v_limit[i], p.v_limit[i + 1])


def cruise_stretches(p: AdaptivePlan, jerk: float) -> list[tuple[float, float, float]]:
    """[(t_start, t_end, cap)]: the cruise stretches of the plan (see the module docstring), ramp ends removed."""
    K = round(p.duration / p.period)
    t = np.arange(K + 1) * p.period
    S, V, _A = p.evaluate(t)
    cap = interval_caps(p, S)
    band = V >= (1.0 - RHO) * cap / p.stretch
    same = np.abs(np.diff(cap)) <= 1e-9 * cap[1:]
    out = []
    k = 0
    while k <= K:
        if not band[k]:
            k += 1
            continue
        e = k
        while e < K and band[e + 1] and same[e]:
            e += 1
        ramp = 2.0 * (6.0 * RHO * cap[k] / (jerk / p.stretch ** 3)) ** (1.0 / 3.0)
        if t[e] - t[k] > 2.0 * ramp:
            out.append((t[k] + ramp, t[e] - ramp, float(cap[k])))
        k = e + 1
    return out


def cruise_noise(p: AdaptivePlan, stretches) -> tuple[float, float, float]:
    """(max |A| on the ticks, max |ΔA|/T between them, max |A| and max |J| of the table's pieces) over the stretches."""
    a_tick = d_tick = a_piece = j_piece = 0.0
    seg = p.segments
    t0, a0, j = seg[:-1, 0], seg[:-1, 3], seg[:-1, 4]
    t1 = seg[1:, 0]
    for ta, tb, _cap in stretches:
        t = np.arange(np.ceil(ta / p.period), np.floor(tb / p.period) + 1) * p.period
        A = p.evaluate(t)[2]
        a_tick = max(a_tick, float(np.abs(A).max()))
        d_tick = max(d_tick, float(np.abs(np.diff(A)).max() / p.period))
        inside = (t1 > ta) & (t0 < tb)
        a_piece = max(a_piece, float(np.abs(a0[inside]).max()), float(np.abs((a0 + j * (t1 - t0))[inside]).max()))
        j_piece = max(j_piece, float(np.abs(j[inside]).max()))
    return a_tick, d_tick, a_piece, j_piece


def check_quiet(p: AdaptivePlan, stretches):
    a_tick, d_tick, a_piece, j_piece = cruise_noise(p, stretches)
    assert a_tick <= QUIET * A_MAX and a_piece <= QUIET * A_MAX, (a_tick, a_piece)
    assert d_tick <= QUIET * J_MAX and j_piece <= QUIET * J_MAX, (d_tick, j_piece)


def test_butterfly_cruises_without_chatter():
    """The issue's case: between t = 0.3 and 0.95 s the old plan flipped A by ±8–30 mm/s² every tick."""
    p = butterfly_plan()
    stretches = cruise_stretches(p, J_MAX)
    # the long cruise at F of the issue is one of them, and they cover most of the motion
    assert any(ta <= 0.35 and tb >= 0.9 and cap == 100.0 for ta, tb, cap in stretches), stretches
    assert sum(tb - ta for ta, tb, _ in stretches) > 0.35 * p.duration
    check_quiet(p, stretches)


@pytest.mark.parametrize("degree", sorted(SEEDS))
def test_random_curves_cruise_without_chatter(degree):
    held = set()
    for seed in SEEDS[degree]:
        p = random_plan(seed)
        stretches = cruise_stretches(p, J_MAX)
        assert stretches, f"seed {seed}: no cruise stretch to check"
        check_quiet(p, stretches)
        held |= {round(cap, 6) for _, _, cap in stretches}
    if degree == 1:  # straight legs: the axis velocity is held, at a level of its own on each leg
        assert any(cap < RANDOM["feedrate"] * (1 - 1e-6) for cap in held), held

