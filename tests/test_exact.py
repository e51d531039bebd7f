"""`exact` from the taylor2 predictor (issue 16): every command on S(t_k) to 1e-12 of the path, on long runs too.

exact corrects the taylor2 step by Newton on the arc length of the step alone
(``interpolate._exact_step``), carries s(u) from tick to tick and re-reads it
from the panel table every ANCHOR_TICKS ticks, and carries its derivative
table from the predictor to the next tick.  Checked here against the panel
table's s(u) (itself tested against the oracle in test_nurbs.py):

- on every bundled curve and on seeded random curves, every tick's s(u_k) is
  S(t_k) to 1e-14 of the path's length (the old Newton on the panel table:
  2.3e-13 mm at worst on the bundled curves; this one 3.5e-13 mm, 1e-15 of
  the butterfly's length);
- on a run of 180 000 ticks (700 re-anchorings), the same, tick by tick;
- the predictor's step is taken on nearly every tick, and its derivative table
  carried, so that the fast path is what runs (not only the fallback).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import random_curve_data

ROOT = Path(__file__).resolve().parents[1]
LANDING = 1e-14  # |s(u_k) − S(t_k)| / L (the issue asks for 1e-12)


def _run(job, **overrides):
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.interpolate import Interpolation

    overrides.setdefault("interpolator", "exact")
    return Interpolation(load_cli(str(job), overrides=overrides))


def _landing(run):
    chunks = list(run.chunks())
    u = np.concatenate([c.u for c in chunks])
    S = np.concatenate([c.planned for c in chunks])
    return np.abs(run.curve.arc_length_at(u) - S) / run.length


@pytest.mark.parametrize("job", sorted((ROOT / "curves").glob("*.yaml")) + [ROOT / "curves" / "pocket.ngc"],
                         ids=lambda p: p.name)
def test_every_tick_lands_on_the_plan(job):
    assert _landing(_run(job)).max() <= LANDING


def test_every_tick_lands_on_the_plan_with_the_adaptive_profile():
    run = _run(ROOT / "curves" / "butterfly.yaml", profile_type="adaptive")
    assert _landing(run).max() <= LANDING


@pytest.mark.parametrize("seed", range(0, 20, 3))
def test_random_curves_land_on_the_plan(seed, tmp_path):
    c = random_curve_data(seed)
    curve = c.curve()
    job = tmp_path / "random.yaml"
    job.write_text(
        "curve:\n"
        f"  degree: {c.p}\n"
        f"  control_points: {c.V.tolist()}\n"
        f"  weights: {c.W.tolist()}\n"
        f"  knots: {c.U.tolist()}\n"
        f"profile: {{type: trapezoidal, feedrate: {curve.length / 3:.17g}, accel_time: 0.5}}\n"
        "interpolator: {method: exact, period: 1 ms}\n")
    assert _landing(_run(job)).max() <= LANDING


def test_a_long_run_stays_on_the_plan():
    """180 000 ticks: the running s(u) is re-read every ANCHOR_TICKS, and never drifts in between."""
    from nurbsinterp.interpolate import ANCHOR_TICKS

    run = _run(ROOT / "curves" / "circle.yaml", period="20 us")
    assert run.last_tick > 500 * ANCHOR_TICKS
    assert _landing(run).max() <= LANDING


def test_the_predictor_step_is_what_runs():
    """On the circle's cruise, every tick takes the corrected predictor and carries its derivatives."""
    from numba import njit

    from nurbsinterp.interpolate import _ARC, _CARRIED, METHODS, interpolate_tick
    from nurbsinterp.nurbs import make_work

    @njit
    def ticks(method, geom, prof, T, sigma_min, K, state, dim, taken, carried):
        work = make_work(geom[2], 2, geom[1].shape[3])
        CK = np.empty((3, dim))
        point, plan, ders = np.empty(dim), np.empty(3), np.empty((2, dim))
        for k in range(K + 1):
            interpolate_tick(method, geom, prof, T, sigma_min, k, K, state, work, CK, point, plan, ders)
            taken[k] = state[_ARC] == state[_ARC]
            carried[k] = state[_CARRIED] != 0.0

    run = _run(ROOT / "curves" / "circle.yaml")
    K = run.last_tick
    taken, carried = np.zeros(K + 1, dtype=np.bool_), np.zeros(K + 1, dtype=np.bool_)
    ticks(METHODS["exact"], run.geometry, run.profile.params, run.period, run.sigma_min, K, run.new_state(),
          run.curve.dim, taken, carried)
    assert taken[:-1].mean() >= 0.99 and carried[:-1].mean() >= 0.95
