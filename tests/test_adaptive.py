"""The adaptive profile wired through the job file, the interpolators and the commands.

The planner itself is tested in test_planner.py; here: the job fields and their
errors, and the issue's acceptance on the butterfly through `Interpolation`
(what `plan` streams), with the measures of the run.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.cli import main
from nurbsinterp.errors import SpecError
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.metrics import RunStats
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli
from layout import one_curve

ROOT = Path(__file__).parent.parent
BUTTERFLY = ROOT / "curves" / "butterfly.yaml"
CIRCLE = ROOT / "curves" / "circle.yaml"
ADAPTIVE = ROOT / "profiles" / "adaptive.yaml"
T = 1e-3
F, DELTA, A_MAX, J_MAX = 100.0, 1e-3, 1000.0, 30000.0


def run_ticks(job):
    run = Interpolation(job)
    stats = RunStats(run.curve, run.profile.peak, run.period)
    rows = []
    for chunk in run.chunks():
        stats.update(chunk, run.curve.dim)
        rows.append(one_curve(chunk.data))
    return run, stats, np.vstack(rows)


@pytest.fixture(scope="module")
def butterfly_exact():
    return run_ticks(load_job(BUTTERFLY, profile_file=ADAPTIVE))


def test_profile_file_sets_the_issue_setting():
    job = load_job(BUTTERFLY, profile_file=ADAPTIVE)
    p = job.profile
    assert (p.type, p.feedrate, p.chord_tolerance, p.max_accel, p.max_jerk) == ("adaptive", F, DELTA, A_MAX, J_MAX)
    assert job.interpolator.method == "exact"


def test_butterfly_acceptance(butterfly_exact):
    """Issue 7: chord error <= 1 um, |A| <= 1000, |J| <= 30000 (1 % for discretisation), ending on a tick."""
    run, stats, d = butterfly_exact
    assert stats.chord_max <= DELTA * 1.01
    a = d[:, -1]
    assert np.abs(a).max() <= A_MAX * 1.01
    jerk = np.diff(a) / T  # A is piecewise linear in t: its tick differences are the jerk
    assert np.abs(jerk).max() <= J_MAX * 1.01
    assert abs(run.profile.duration / T - round(run.profile.duration / T)) < 1e-9
    assert d.shape[0] == round(run.profile.duration / T) + 1
    np.testing.assert_array_equal(d[-1, 3:5], run.curve.control_points[-1])
    # the exact interpolator follows the plan: every command at s(u_k) = S(t_k)
    s = run.curve.arc_length_at(d[:, 2])
    S = run.profile.evaluate(d[:, 1])[0]
    assert np.abs(s - S).max() <= 1e-9 * run.length
    assert abs(stats.ff_max) <= 1e-9
    # and the feedrate stays below the commanded one
    assert d[:, -2].max() <= F * (1 + 1e-9)


def test_butterfly_stream_is_quiet_in_cruise(butterfly_exact):
    """Issue 12, item 5, on what `plan` streams: in every cruise stretch (test_cruise.py) the `a` column is 0
    and the `v` column constant; the old plan's `a` flipped by ±8–30 mm/s² every tick there."""
    from test_cruise import cruise_stretches

    run, _, d = butterfly_exact
    stretches = cruise_stretches(run.profile.plan, J_MAX)
    # since max_accel bounds the centripetal acceleration too (issue 27), the feed follows the curvature over
    # most of the wings: 0.93 s of the 5.58 s cruise at a constant cap (1.7 s of 4.75 s before)
    assert sum(tb - ta for ta, tb, _ in stretches) > 0.15 * run.profile.duration
    for ta, tb, cap in stretches:
        rows = d[(d[:, 1] >= ta) & (d[:, 1] <= tb)]
        assert rows.shape[0] > 10
        a, v = rows[:, -1], rows[:, -2]
        assert np.abs(a).max() <= 1e-6 * A_MAX
        assert np.abs(np.diff(a)).max() / T <= 1e-6 * J_MAX
        assert np.ptp(v) <= 1e-9 * cap and v.min() >= (1 - 1e-6) * cap / run.profile.plan.stretch


def test_butterfly_is_not_much_slower_than_acceleration_limited(butterfly_exact):
    """A fair margin above the optimum: the jerk limit costs time, but not more than ~15 % here."""
    run, _, _ = butterfly_exact
    job = load_job(BUTTERFLY, profile_file=ADAPTIVE)
    fast = Interpolation(job.with_overrides(profile=job.profile.__class__(**{**job.profile.__dict__, "max_jerk": None})))
    assert fast.profile.duration < run.profile.duration <= 1.15 * fast.profile.duration


def test_constant_feed_breaks_the_chord_tolerance_adaptive_keeps_it(butterfly_exact):
    """The motivation: the paper's constant-feed plan on the butterfly has a chord error of tens of um."""
    _, stats_trap, _ = run_ticks(load_cli(BUTTERFLY, overrides={"interpolator": "exact"}))
    _, stats_adaptive, _ = butterfly_exact
    assert stats_trap.chord_max > 20 * DELTA
    assert stats_adaptive.chord_max <= DELTA * 1.01


@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4"])
def test_every_interpolator_consumes_the_adaptive_plan(method):
    job = load_cli(BUTTERFLY, profile_file=ADAPTIVE, overrides={"interpolator": method})
    run, stats, d = run_ticks(job)
    assert np.isfinite(d).all()
    assert (np.diff(d[:, 2]) >= 0).all()
    np.testing.assert_array_equal(d[-1, 3:5], run.curve.control_points[-1])
    # the plan's columns are the same whatever the interpolator
    S, V, A = run.profile.evaluate(d[:, 1])
    np.testing.assert_array_equal(d[:, -2], V)
    # mm. taylor1 omits Eq. 9's A·T²/2 term (0.5 µm a tick at 1000 mm/s²) and, through the butterfly's
    # stops, keeps the drift it gathers rather than catching it up in a leap: measured 0.105 mm, against
    # 0.011 mm for taylor2 and 1.2e-6 mm for rk4
    assert abs(run.end_gap) < {"taylor1": 0.15, "taylor2": 0.02, "rk4": 1e-5}[method]


@pytest.mark.parametrize("field,value,message", [
    ("chord_tolerance", -1, "profile.chord_tolerance = -1 must be > 0"),
    ("chord_tolerance", "1 s", "profile.chord_tolerance = '1 s' is not a length"),
    ("max_accel", "5 mm/s", "profile.max_accel = '5 mm/s' is not an acceleration"),
    ("max_jerk", 0, "profile.max_jerk = 0 must be > 0"),
    ("max_normal_accel", "fast", "profile.max_normal_accel = 'fast' is not a number"),
    ("axes", {"w": {"max_velocity": 1}}, "profile.axes.w is not a known key"),
    ("axes", {"x": {"max_speed": 1}}, "profile.axes.x.max_speed is not a known key"),
    ("axes", {"x": {"max_velocity": -3}}, "profile.axes.x.max_velocity = -3 must be > 0"),
    ("accdec", "after", "profile.accdec = 'after' cannot be used with profile.type = 'adaptive'"),
])
def test_adaptive_fields_are_validated(tmp_path, field, value, message):
    import yaml

    doc = yaml.safe_load(CIRCLE.read_text())
    doc["profile"] = {"type": "adaptive", "feedrate": 100, field: value}
    path = tmp_path / "job.yaml"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(SpecError) as info:
        load_job(path)
    assert str(info.value) == f"{path}: {message}" or str(info.value).startswith(f"{path}: {message}")


def test_info_json_reports_where_limits_bind(capsys):
    with pytest.raises(SystemExit) as code:
        main(["info", str(BUTTERFLY), "--profile", str(ADAPTIVE), "--json"])
    assert code.value.code == 0
    facts = json.loads(capsys.readouterr().out)
    a = facts["adaptive"]
    assert set(a["limit_fractions"]) >= {"feedrate", "chord", "normal_accel"}
    assert math.isclose(sum(a["limit_fractions"].values()), 1.0, rel_tol=1e-9)
    # max_accel bounds V²κ too: √(1000 ρ) is below the chord limit 2000 √(2ρ·0.001 − 1e-6) at every radius
    assert a["limit_fractions"]["normal_accel"] > 0 and a["limit_fractions"]["chord"] == 0
    assert a["lowest_feed_limit"]["limit"] == "normal_accel"
    assert math.isclose(sum(a["bound_fractions"].values()), 1.0, rel_tol=1e-9)
    assert facts["motion_time"] == pytest.approx(facts["ticks"] - 1, rel=1e-12) or \
        facts["motion_time"] == pytest.approx((facts["ticks"] - 1) * T, rel=1e-12)


def test_plan_summary_and_info_plot(tmp_path, capsys):
    png = tmp_path / "adaptive.png"
    with pytest.raises(SystemExit) as code:
        main(["info", str(BUTTERFLY), "--profile", str(ADAPTIVE), "--plot", str(png)])
    assert code.value.code == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    capsys.readouterr()
    with pytest.raises(SystemExit) as code:
        main(["plan", str(BUTTERFLY), "--profile", str(ADAPTIVE), "--format", "bin", "-o", str(tmp_path / "b.bin")])
    assert code.value.code == 0
    err = capsys.readouterr().err
    assert "bound by" in err and "feed limit" in err and "normal_accel" in err and "slowest" in err


def test_compare_has_adaptive_rows(capsys):
    with pytest.raises(SystemExit) as code:
        main(["compare", str(CIRCLE), "--json"])
    assert code.value.code == 0
    rows = json.loads(capsys.readouterr().out)
    adaptive = [r for r in rows if r["profile"] == "adaptive"]
    assert {r["interpolator"] for r in adaptive} == {"taylor2", "exact"}
    assert len(rows) == 17
