"""The run's measures from the tick's own derivatives (issue 16): the same FF and chord error as the curve gives.

``RunStats`` measures a step from the derivatives the tick computed at its ends
(``metrics._hermite_step``: a quintic Hermite checked against the curve at the
step's middle) and falls back on the curve itself (``metrics._step_exact``)
where that cannot be trusted.  Checked here:

- per step, against brute force (the oracle's points, dense samples refined by
  golden section; a 32-point Gauss rule on the oracle's speed for arc length),
  on the bundled jobs and on seeded random curves of every degree;
- a step through an inflection, whose distance from the chord has a maximum
  each side (Newton from the middle found the smaller one before);
- the run's summary the same whether the chunks carry derivatives or not, and
  the same as the reference kernel ``step_measures`` gives;
- hypothesis: random short steps of random curves.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import oracle
from conftest import random_curve_data
from test_hostile_misc import brute_chord_error

ROOT = Path(__file__).resolve().parents[1]
JOBS = sorted((ROOT / "curves").glob("*.yaml")) + [ROOT / "curves" / "pocket.ngc", ROOT / "curves" / "drawing.dxf"]
CHORD_TOL = 1e-9  # mm: the measures' agreement with brute force, everywhere
FF_TOL = 1e-12  # the arc length of a step, relative: FF to 1e-12


def _kernels():
    from nurbsinterp.metrics import _hermite_step, _step_exact
    from nurbsinterp.nurbs import find_span, make_work

    return _hermite_step, _step_exact, find_span, make_work


def _steps(curve, us, pts, ders):
    """(trusted, arc length, chord error) of every step by the derivative path, and (FF + 1 of a
    planned step of 1 mm, chord error) by the curve itself, per step."""
    hermite_step, step_exact, find_span, make_work = _kernels()
    U, B, p, n = curve.kernel_args
    work = make_work(p, 2, B.shape[3])
    dim = B.shape[3] - 1
    CK, CK2, Q = np.empty((3, dim)), np.empty((3, dim)), np.empty((9, dim))
    out = []
    for j in range(1, len(us)):
        u0, u1 = float(us[j - 1]), float(us[j])
        span = find_span(U, n, p, u0)
        fast = (False, 0.0, 0.0)
        if u1 < U[span + 1]:
            fast = hermite_step(U, B, p, span, u0, u1, pts[j - 1], ders[j - 1, 0], ders[j - 1, 1], pts[j],
                                ders[j, 0], ders[j, 1], work, CK, Q)
        ff, chord, _ = step_exact(U, B, p, n, *curve.panels, u0, u1, pts[j - 1], pts[j], 1.0, True, p, work, CK, CK2)
        out.append((fast, ff + 1.0, chord))
    return out


def _oracle_length(c, u0, u1):
    x, w = np.polynomial.legendre.leggauss(32)
    u = 0.5 * (u0 + u1) + 0.5 * (u1 - u0) * x
    return 0.5 * (u1 - u0) * sum(wi * oracle.speed(c.U, c.p, c.V, c.W, ui) for ui, wi in zip(u, w))


def _check_step(c, curve, u0, u1):
    """One step of curve c (CurveData) measured both ways against the oracle; True if the fast path took it."""
    us = np.array([u0, u1])
    both = curve.derivatives(us, 2)
    (fast, exact_len, exact_chord), = _steps(curve, us, np.ascontiguousarray(both[:, 0]),
                                             np.ascontiguousarray(both[:, 1:]))
    truth_chord, _, _ = brute_chord_error(c.U, c.p, c.V, c.W, u0, u1)
    truth_len = _oracle_length(c, u0, u1)
    scale = max(1.0, float(np.abs(both[:, 0]).max()))
    assert abs(exact_chord - truth_chord) <= CHORD_TOL, (u0, u1, exact_chord, truth_chord)
    ok, length, chord = fast
    if ok:
        assert abs(chord - truth_chord) <= CHORD_TOL, (u0, u1, chord, truth_chord)
        # the arc length from the speed: 1e-12 relative, or the rounding of the coordinates on a tiny step
        assert abs(length - truth_len) <= FF_TOL * truth_len + 1e-15 * scale, (u0, u1, length, truth_len)
    return ok


# --------------------------------------------------------------------------- the bundled jobs, step by step


@pytest.mark.parametrize("job", JOBS, ids=lambda p: p.name)
def test_every_step_of_a_bundled_job_agrees_with_the_curve(job):
    """The derivative path against the curve itself on every step of the run; brute force on a sample."""
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.interpolate import Interpolation

    run = Interpolation(load_cli(str(job)))
    chunks = list(run.chunks(derivatives=True))
    us = np.concatenate([c.u for c in chunks])
    pts = np.ascontiguousarray(np.vstack([c.points for c in chunks]))
    ders = np.ascontiguousarray(np.concatenate([c.ders for c in chunks]))
    # the tick's derivatives are the curve's (exact carries them from its predictor by a Taylor step whose
    # estimate of the third derivative leaves C'' within about 1e-5 h^2 |C''''| of the truth)
    truth = run.curve.derivatives(us, 2)[:, 1:]
    off = np.linalg.norm(ders - truth, axis=2) / np.maximum(np.linalg.norm(truth, axis=2), 1e-300)
    assert off[:, 0].max() <= 1e-12 and off[:, 1].max() <= 1e-8, off.max(axis=0)
    steps = _steps(run.curve, us, pts, ders)
    trusted = 0
    for j, ((ok, length, chord), exact_len, exact_chord) in enumerate(steps):
        if not ok:
            continue
        trusted += 1
        assert abs(chord - exact_chord) <= CHORD_TOL, (j, chord, exact_chord)
        assert abs(length - exact_len) <= 1e-11 * exact_len + 1e-14, (j, length, exact_len)
    # most steps of a smooth run are measured from the derivatives (else the fast path is dead code)
    assert trusted >= 0.5 * len(steps)


# --------------------------------------------------------------------------- random curves against the oracle


@pytest.mark.parametrize("seed", range(12))
def test_random_curves_step_by_step_against_brute_force(seed):
    c = random_curve_data(seed)
    curve = c.curve()
    a, b = c.domain
    rng = np.random.default_rng(1000 + seed)
    taken = 0
    for _ in range(12):
        u0 = float(rng.uniform(a, b))
        h = (b - a) * 10.0 ** rng.uniform(-6, -2.5)
        u1 = min(u0 + h, b)
        if u1 > u0:
            taken += _check_step(c, curve, u0, u1)
    assert taken > 0  # each curve has short steps the derivative path takes


def test_a_step_through_an_inflection_finds_the_larger_maximum():
    """An S-shaped cubic: the step's distance from its chord has one maximum each side of the
    inflection; the larger is the chord error.  Newton from the middle found the other one
    (0.6 % short on the butterfly) before issue 16."""
    from conftest import CurveData

    V = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, -0.6], [3.0, 0.0]])
    c = CurveData(3, np.array([0, 0, 0, 0, 1, 1, 1, 1.0]), V, np.ones(4))
    curve = c.curve()
    for u0, u1 in [(0.3, 0.62), (0.4, 0.55), (0.45, 0.5)]:
        _check_step(c, curve, u0, u1)
    # the distance has two maxima of different size here
    u = np.linspace(0.3, 0.62, 2001)
    P = curve.evaluate(u)
    e = (P[-1] - P[0]) / np.linalg.norm(P[-1] - P[0])
    f = (P - P[0]) @ np.array([-e[1], e[0]])
    assert f.max() > 0 > f.min() and abs(abs(f.max()) - abs(f.min())) > 1e-4


@settings(max_examples=40)
@given(seed=st.integers(0, 19), where=st.floats(0.0, 1.0), size=st.floats(-7.0, -2.0))
def test_property_a_random_short_step(seed, where, size):
    c = random_curve_data(seed)
    a, b = c.domain
    u0 = a + where * (b - a)
    u1 = min(u0 + (b - a) * 10.0 ** size, b)
    if u1 > u0:
        _check_step(c, c.curve(), u0, u1)


# --------------------------------------------------------------------------- the run's summary


def _summary(run_factory, derivatives):
    from nurbsinterp.metrics import RunStats

    run = run_factory()
    stats = RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
    for chunk in run.chunks(derivatives=derivatives):
        stats.update(chunk, run.curve.dim)
    return stats


def _reference(run_factory):
    """max |FF| (signed), RMS, max chord error by the reference kernel on the whole run at once."""
    from nurbsinterp.metrics import FF_MIN_STEP, step_measures

    run = run_factory()
    chunks = list(run.chunks())
    us = np.concatenate([c.u for c in chunks])
    pts = run.curve.evaluate(us) if run.after else np.vstack([c.points for c in chunks])
    S = np.concatenate([c.planned for c in chunks])
    m = len(us) - 1
    ff, chord, counted = np.empty(m), np.empty(m), np.empty(m, dtype=np.bool_)
    U, B, p, n = run.curve.kernel_args
    step_measures(U, B, p, n, *run.curve.panels, us, np.ascontiguousarray(pts), S,
                  FF_MIN_STEP * run.profile.peak * run.period, ff, chord, counted)
    f = ff[counted]
    return f[np.argmax(np.abs(f))], math.sqrt(float(np.sum(f * f)) / len(f)), float(chord.max())


@pytest.mark.parametrize("job,overrides", [
    ("circle.yaml", {}), ("circle.yaml", {"interpolator": "exact"}), ("circle.yaml", {"accdec": "after"}),
    ("butterfly.yaml", {}), ("quintic-wave.yaml", {"interpolator": "rk4"}), ("path-3d.yaml", {}),
    ("tilted-circle-3d.yaml", {}), ("pocket.ngc", {}), ("drawing.dxf", {"interpolator": "taylor1"}),
])
def test_the_summary_is_the_curves(job, overrides):
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.interpolate import Interpolation

    def factory():
        return Interpolation(load_cli(str(ROOT / "curves" / job), overrides=overrides), chunk_ticks=997)

    fused, evaluated = _summary(factory, True), _summary(factory, False)
    ff_max, ff_rms, chord_max = _reference(factory)
    for stats in (fused, evaluated):
        assert abs(stats.ff_max - ff_max) <= 1e-12
        assert abs(stats.ff_rms - ff_rms) <= 1e-9 * ff_rms + 1e-15
        assert abs(stats.chord_max - chord_max) <= 1e-12
    assert fused.ticks == evaluated.ticks
    assert fused.exact_steps < 0.5 * fused.ticks


# --------------------------------------------------------------------------- on the second core


def test_alongside_runs_every_call_in_order_and_stays_bounded():
    import threading

    from nurbsinterp.metrics import Alongside

    seen, gate = [], threading.Event()

    def update(i):
        gate.wait(60)
        seen.append(i)

    with Alongside(update, depth=2) as alongside:
        alongside.submit(0)
        alongside.submit(1)
        alongside.submit(2)  # the worker holds 0; 1 and 2 fill the queue
        blocked = threading.Thread(target=alongside.submit, args=(3,))
        blocked.start()
        blocked.join(0.2)
        assert blocked.is_alive()  # a fourth waits: memory stays bounded (a hang catcher below, not a timing)
        gate.set()
        blocked.join(60)
        for i in range(4, 50):
            alongside.submit(i)
    assert seen == list(range(50))


def test_alongside_hands_an_error_back():
    from nurbsinterp.metrics import Alongside

    def update(i):
        if i == 3:
            raise ValueError("bad chunk")

    with pytest.raises(ValueError, match="bad chunk"):
        with Alongside(update) as alongside:
            for i in range(10):
                alongside.submit(i)


def test_plan_summary_is_the_same_alongside(tmp_path):
    """`plan` measures on the second core: its summary is RunStats' own."""
    import subprocess
    import sys

    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.metrics import RunStats

    job = ROOT / "curves" / "butterfly.yaml"
    proc = subprocess.run([sys.executable, "-m", "nurbsinterp", "plan", str(job), "-o", str(tmp_path / "o.csv")],
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    run = Interpolation(load_cli(str(job)))
    stats = RunStats(run.curve, run.profile.peak, run.period)
    for chunk in run.chunks(derivatives=True):
        stats.update(chunk, run.curve.dim)
    line = next(l for l in proc.stderr.splitlines() if "chord error" in l)
    assert f"max {stats.chord_max * 1e3:.6g} um (step k = {stats.chord_max_k})" in line
    line = next(l for l in proc.stderr.splitlines() if "feedrate fluct." in l)
    assert f"max |FF| {abs(stats.ff_max):.3e} (k = {stats.ff_max_k})" in line
