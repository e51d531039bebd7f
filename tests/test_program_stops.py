"""A program's stops and dwells (issue 47's acceptance, the part without a tolerance).

`G4 P2` between two collinear moves held the tool nowhere (`info` gave 2.5 s with or without it) and `M0` was
passed at 10 mm/s.  Now a program is planned with look-ahead, on the exact path where it states no G64 P: each
stop brings the tool to rest on its point, and a dwell holds it there for its seconds (whole periods), for every
profile; `info` says what `plan` writes.  Each figure is checked against the stream itself: the ticks at rest on
the stop's point, and the motion times compared with the same program without the dwell (the difference is the
dwell, exactly).  A YAML path's dwell is held by the paper's planner, which plans it.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from clirun import read_trace, run_main

PERIOD = 1e-3
PROFILES = [[], ["--profile-type", "exponential"], ["--profile-type", "bell"],
            ["--profile-type", "adaptive", "--max-accel", "100"]]


def program(tmp_path, between: str, name: str):
    path = tmp_path / f"{name}.ngc"
    path.write_text(f"G21 G90\nG1 X10 F600\n{between}G1 X20\nM2\n")
    return path


def stream(capsys, tmp_path, path, *options):
    out = tmp_path / (path.stem + "".join(o.strip("-") for o in options) + ".csv")
    code, _, err = run_main(capsys, "plan", path, "-q", "-o", out, *options)
    assert code == 0, err
    cols, data = read_trace(out)
    return cols, data


def resting_at(cols, data, x):
    """The ticks commanding x (to 1e-12 mm), one run of them: (first, last) tick numbers."""
    pos = data[:, cols.index("x")]
    at = np.flatnonzero(np.abs(pos - x) <= 1e-12)
    assert at.size and np.all(np.diff(at) == 1), at
    return int(data[at[0], 0]), int(data[at[-1], 0])


@pytest.mark.parametrize("options", PROFILES, ids=lambda o: " ".join(o) or "trapezoidal")
def test_a_dwell_holds_the_tool_at_rest_for_its_seconds(capsys, tmp_path, options):
    stop = program(tmp_path, "M0\n", "m0")
    dwell = program(tmp_path, "G4 P2\n", "dwell")
    cols, at_stop = stream(capsys, tmp_path, stop, *options)
    cols2, held = stream(capsys, tmp_path, dwell, *options)
    assert cols == cols2
    first, last = resting_at(cols, held, 10.0)
    s_first, s_last = resting_at(cols, at_stop, 10.0)
    # the dwell adds exactly its 2 s, at rest on the point, to what the stop alone holds there
    assert (last - first) - (s_last - s_first) == round(2.0 / PERIOD)
    assert held.shape[0] - at_stop.shape[0] == round(2.0 / PERIOD)
    np.testing.assert_array_equal(held[first:last + 1, cols.index("x")], 10.0)
    # at rest from the tick after the first on the point: a jerk-limited stop (the bell's S-curve) may come to rest
    # between two ticks, the first within J T^2/2 of rest and within the CSV's 1e-9 mm of the point
    creep = 0.0 if "bell" not in options else 0.5 * math.pi ** 2 * 100.0 / (2 * (math.pi - 2) * 0.25) * PERIOD ** 2
    assert np.all(held[first + 1:last + 1, cols.index("v")] == 0.0)
    assert held[first, cols.index("v")] <= creep and at_stop[s_first, cols.index("v")] <= creep
    # and the rest of the motion is the stop's, shifted by the dwell
    np.testing.assert_array_equal(held[last:, cols.index("x")], at_stop[s_last:, cols.index("x")])


@pytest.mark.parametrize("options", PROFILES, ids=lambda o: " ".join(o) or "trapezoidal")
def test_m0_stops_the_tool_where_the_moves_do_not_turn(capsys, tmp_path, options):
    """The two moves are collinear: without the M0 they are one motion through x = 10; with it the tool comes to
    rest there (v = 0 on the point's tick)."""
    cols, through = stream(capsys, tmp_path, program(tmp_path, "", "plain"), *options)
    cols, stopped = stream(capsys, tmp_path, program(tmp_path, "M0\n", "m0"), *options)
    v = cols.index("v")
    on_point = np.abs(stopped[:, cols.index("x")] - 10.0) <= 1e-12
    assert stopped[on_point, v].min() == 0.0
    k = int(np.argmin(np.abs(through[:, cols.index("x")] - 10.0)))
    assert through[k, v] > 5.0  # the plain program passes the point moving
    assert stopped.shape[0] > through.shape[0]


def test_info_says_what_plan_writes(capsys, tmp_path):
    path = program(tmp_path, "G4 P2\n", "dwell")
    code, out, err = run_main(capsys, "info", path, "--json")
    assert code == 0, err
    doc = json.loads(out)
    _, data = stream(capsys, tmp_path, path)
    assert doc["ticks"] == data.shape[0]
    assert doc["motion_time"] == pytest.approx((data.shape[0] - 1) * PERIOD, abs=1e-12)


def test_a_yaml_blocks_dwell_is_held_too(capsys, tmp_path):
    job = tmp_path / "job.yaml"
    job.write_text("path:\n  start: [0, 0]\n  blocks:\n    - line: {to: [10, 0]}\n"
                   "    - line: {to: [20, 0], dwell: 0.5 s}\n"
                   "profile: {feedrate: 10 mm/s, accel_time: 0.5 s}\n")
    cols, data = stream(capsys, tmp_path, job)
    first, last = resting_at(cols, data, 10.0)
    assert last - first >= round(0.5 / PERIOD)


@pytest.mark.parametrize("options", PROFILES, ids=lambda o: " ".join(o) or "trapezoidal")
def test_every_profile_holds_a_yaml_paths_dwell_on_the_look_ahead(capsys, tmp_path, options):
    """A YAML path of several blocks is planned with look-ahead, as a program is: every profile, the adaptive
    one included, comes to rest at a block's dwell and holds it (2 s on 2 000 ticks)."""
    job = tmp_path / "job.yaml"
    job.write_text("path:\n  start: [0, 0]\n  blocks:\n    - line: {to: [10, 0]}\n"
                   "    - line: {to: [20, 0], dwell: 2 s}\n"
                   "profile: {feedrate: 10 mm/s, accel_time: 0.5 s}\n")
    cols, data = stream(capsys, tmp_path, job, *options)
    first, last = resting_at(cols, data, 10.0)
    assert last - first >= round(2.0 / PERIOD)
    assert np.all(data[first:last + 1, cols.index("v")] == 0.0)


def test_acc_dec_after_is_refused_for_a_program_not_ignored(capsys, tmp_path):
    """A program is planned with look-ahead, which plans the feedrate before interpolation: --accdec after is
    refused in one line naming it, never dropped (a YAML path takes it: the paper's planner)."""
    code, out, err = run_main(capsys, "plan", program(tmp_path, "G4 P2\n", "dwell"), "--accdec", "after")
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1 and "accdec = after" in err, err


def test_a_dwell_before_the_first_move_holds_the_start_and_a_stop_there_changes_nothing(capsys, tmp_path):
    """G4 before any motion holds the tool on the start point; an M6 there (the tool is at rest anyway) plans as the
    program without it, to the byte."""
    plain = tmp_path / "plain.ngc"
    plain.write_text("G21 G90\nG1 X10 F600\nM2\n")
    first = tmp_path / "first.ngc"
    first.write_text("G21 G90\nG4 P1\nG1 X10 F600\nM2\n")
    tool = tmp_path / "tool.ngc"
    tool.write_text("G21 G90\nM6 T1\nG1 X10 F600\nM2\n")
    # (the exact interpolator: each tick on its planned arc length, so the motions compare tick by tick)
    cols, moved = stream(capsys, tmp_path, plain, "--interpolator", "exact")
    _, held = stream(capsys, tmp_path, first, "--interpolator", "exact")
    _, changed = stream(capsys, tmp_path, tool, "--interpolator", "exact")
    x = cols.index("x")
    assert held.shape[0] - moved.shape[0] == round(1.0 / PERIOD)
    np.testing.assert_array_equal(held[:round(1.0 / PERIOD) + 1, x], 0.0)
    np.testing.assert_allclose(held[round(1.0 / PERIOD):, x], moved[:, x], rtol=0, atol=1e-9)
    np.testing.assert_array_equal(changed, moved)


@pytest.mark.parametrize("shape", ["trapezoidal", "exponential", "bell"])
def test_acc_dec_after_comes_to_rest_at_a_yaml_paths_dwell(capsys, tmp_path, shape):
    """Filters after interpolation hold the commands at a stop until the tool is at rest: the exponential lag
    needs many time constants, not one ramp time (it cut the corner by 19 um), so the commands never leave the
    programmed corner by more than the filter's settling tolerance (1e-6 mm)."""
    job = tmp_path / "job.yaml"
    job.write_text("path:\n  start: [0, 0]\n  blocks:\n    - line: {to: [10, 0]}\n"
                   "    - line: {to: [10, 10], dwell: 0.2 s}\n"
                   f"profile: {{type: {shape}, feedrate: 50, accel_time: 0.1 s, accdec: after}}\n")
    cols, data = stream(capsys, tmp_path, job)
    x, y = data[:, cols.index("x")], data[:, cols.index("y")]
    off = np.minimum(np.abs(y), np.abs(x - 10.0))  # the distance to the two legs, near the corner
    assert off.max() <= 1e-6 * (1 + 1e-9) + 1e-12, (off.max(), shape)


@pytest.mark.parametrize("profile", ["trapezoidal", "bell", "exponential"])
@pytest.mark.parametrize("length", [100.0, 7.0])
def test_a_profile_word_is_one_motion_on_a_curve_and_across_blocks(capsys, tmp_path, profile, length):
    """A profile means one motion (README, "One profile, one motion"): a straight move from rest to rest takes the
    same time as one curve (the paper's ramp, Ta of it from rest to F) and as two collinear blocks of a path (the
    look-ahead, whose ramp policy loses the time the paper's ramp loses), within a tick each side for landing on
    ticks; and neither exceeds the profile's peak acceleration.  A move too short to reach F (7 mm at 50 mm/s over
    Ta = 0.2 s needs 10 mm) is planned by each its own way: the look-ahead's never slower."""
    tau = ", time_constant: 0.05 s" if profile == "exponential" else ""
    head = f"profile: {{type: {profile}, feedrate: 50 mm/s, accel_time: 0.2 s{tau}}}\n"
    curve = tmp_path / "curve.yaml"
    curve.write_text(f"curve:\n  degree: 1\n  control_points: [[0, 0], [{length}, 0]]\n" + head)
    path = tmp_path / "path.yaml"
    path.write_text(f"path:\n  start: [0, 0]\n  blocks:\n    - line: {{to: [{length / 2}, 0]}}\n"
                    f"    - line: {{to: [{length}, 0]}}\n" + head)
    cols, one = stream(capsys, tmp_path, curve)
    cols2, two = stream(capsys, tmp_path, path)
    t1, t2 = one[-1, cols.index("t")], two[-1, cols2.index("t")]
    peak = {"trapezoidal": 50.0 / 0.2, "bell": 0.5 * math.pi * 50.0 / 0.2,
            "exponential": 4.0 / -math.expm1(-4.0) * 50.0 / 0.2}[profile]
    for c, data in ((cols, one), (cols2, two)):
        assert np.abs(data[:, c.index("a")]).max() <= peak * (1 + 1e-9)
    if length > 2 * 50.0 * 0.2:
        assert abs(t1 - t2) <= 2 * PERIOD + 1e-12, (t1, t2)
        assert abs(t1 - (length / 50.0 + 0.2)) <= PERIOD + 1e-12, t1  # the paper's ramps lose Ta a move
    else:
        assert t2 <= t1 + 2 * PERIOD + 1e-12, (t1, t2)
