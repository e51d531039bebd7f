"""`nurbsinterp identify`: each axis' plant fitted to a capture of the machine (issue 30).

The captures are made here, with known plants, written as halsampler writes them (C's %f):

- the paper's table with its 0.5 um encoder, run by the project's own closed loop: the fit must find
  the gains and poles within 0.5 % (the issue's target) and within 4 of its own standard deviations;
- the same plants run by an independent naive loop (scipy.signal.cont2discrete, a per-tick Python
  loop) with seeded measurement noise before the encoder, which the controller acts on;
- LinuxCNC's pid (error-previous-target: the P term acts on the previous command) driving a HAL
  ``scale`` + ``lowpass`` + ``integ`` drive in sim-machine.hal's thread order, re-implemented tick by
  tick from pid(9) and the components' one-line updates: the hal-lowpass family must be chosen and
  find the drive to the capture's 6 decimals.

A capture that cannot determine a model is refused in one line naming what is missing; the faults
``simulate --actual`` refuses are refused by identify with the same message.
"""
from __future__ import annotations

import io
import json
import math
import os
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from clirun import assert_one_line_error, run_main
from nurbsinterp.config import load_job
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.motion.pipeline import LookAhead
from nurbsinterp.path import job_path
from nurbsinterp.servo import AxisModel, ClosedLoop, ModelError, ServoModel, discretise, load_servo

ROOT = Path(__file__).resolve().parents[1]
EXCITATION = ROOT / "curves" / "excitation.yaml"
CIRCLE = ROOT / "curves" / "circle.yaml"
PAPER_ENCODER = ROOT / "servo" / "paper-xy-encoder.yaml"
PAPER = ROOT / "servo" / "paper-xy.yaml"
LEAD = 4  # rows of the streamer holding its pins (k = 0) before the stream
HOLD = 300  # rows of the capture after the last command
TARGET = 0.005  # the issue's: gains and poles within 0.5 %
SIGMAS = 4.0
PID = "x.Pgain=60,y.Pgain=90,FF1=0.95"
HAL_DRIVE = {"x": (0.97, 0.25), "y": (1.02, 0.4)}  # scale gain, lowpass gain: sim-machine.hal's


@pytest.fixture(autouse=True)
def empty_stdin(monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


def planned(job) -> np.ndarray:
    """The job's axis commands (ticks, 2) as plan makes them: a path of several blocks with look-ahead, on the
    exact path (no tolerance stated), a curve by the paper's interpolation."""
    spec = load_job(str(job), every_profile=True, stream=True)
    if len(spec.path.blocks) > 1:
        run = LookAhead(spec, None)
        chunks = list(run.chunks())
    else:
        spec = load_job(str(job))
        run = Interpolation(spec, job_path(spec))
        chunks = [c.data for c in run.chunks()]
    cols = run.columns
    data = np.vstack(chunks)
    return np.ascontiguousarray(data[:, [cols.index("x"), cols.index("y")]])


def capture_file(path, commands, feedback, lead=LEAD):
    """A halsampler capture k, x_cmd, y_cmd, x, y (%f): *lead* rows holding tick 0, then one row per tick, the hold
    rows (beyond the commands) holding the last tick."""
    last = commands.shape[0] - 1
    ticks = np.minimum(np.arange(feedback.shape[0]), last)
    cmd = np.vstack([commands, np.tile(commands[-1], (feedback.shape[0] - commands.shape[0], 1))])
    rows = [(0, cmd[0], feedback[0])] * lead + list(zip(ticks, cmd, feedback))
    path.write_text("".join(f"{k} {c[0]:f} {c[1]:f} {f[0]:f} {f[1]:f}\n" for k, c, f in rows))
    return path


def held(commands, extra=HOLD):
    return np.vstack([commands, np.tile(commands[-1], (extra, 1))])


def true_values(ax):
    """K (DC gain) and the poles of a servo file's axis."""
    return ax.num[-1] / ax.den[-1], np.sort(np.abs(np.roots(ax.den)))


def identified(capsys, tmp_path, capture, *args, job=EXCITATION):
    out_file = tmp_path / "fitted.yaml"
    code, out, err = run_main(capsys, "identify", capture, "--job", job, "--json", "-o", out_file, *args)
    assert code == 0, err
    return json.loads(out), out_file


def assert_found(report_axis, ax, target=TARGET):
    """The fitted K and poles against the truth: within *target* and within SIGMAS of the reported deviation."""
    k_true, poles_true = true_values(ax)
    k = report_axis["parameters"]["K"]
    assert abs(k["value"] / k_true - 1) <= min(target, SIGMAS * k["std"] + 1e-12), (k, k_true)
    poles = sorted(report_axis["poles"], key=lambda p: p["magnitude"])
    assert len(poles) == len(poles_true)
    for p, true in zip(poles, poles_true):
        assert abs(p["magnitude"] / true - 1) <= min(target, SIGMAS * p["std"]), (p, true)


# --------------------------------------------------------------------------- the paper's table


@pytest.fixture(scope="module")
def excitation():
    return planned(EXCITATION)


def test_the_paper_table_is_found_within_half_a_percent(capsys, tmp_path, excitation):
    """The paper's plants behind a 0.5 um encoder, started from a model 30 % off in gain and 30 % off in its poles:
    K and the poles within 0.5 % and 4 sigma, the residual at the encoder's floor, the model written back."""
    model = load_servo(PAPER_ENCODER)
    period = 1e-3
    pos = ClosedLoop(discretise(model, period)).run(held(excitation))[0]
    capture = capture_file(tmp_path / "capture.txt", excitation, np.round(pos / 5e-4) * 5e-4)
    start = tmp_path / "start.yaml"
    wrong = ModelError("", {"x": 1.3, "y": 1.3}, {"x": 0.7, "y": 0.7}).apply(model)
    start.write_text(yaml.safe_dump({"axes": {a: {"plant": {"num": list(ax.num), "den": list(ax.den)}, "kp": ax.kp,
                                                  "kv": ax.kv} for a, ax in wrong.axes.items()}}))
    report, fitted = identified(capsys, tmp_path, capture, "--servo", start)
    assert report["rows"] == excitation.shape[0] + HOLD and report["capture_lead_rows"] == LEAD
    for a in "xy":
        r = report["axes"][a]
        assert r["family"] == "lag2" and r["delay"] == 0
        assert_found(r, model.axes[a])
        assert r["encoder_resolution"] == 5e-4
        floor = 5e-4 / math.sqrt(12)
        assert r["residual_rms"] <= 1.5 * floor and r["limited_by"] == ["quantisation"]
        assert (r["kp"], r["kv"]) == (model.axes[a].kp, model.axes[a].kv)
    # the written model: the paper's encoder, this period, and the residual it reports when run again
    back = load_servo(fitted)
    assert back.period == period
    pos_back = ClosedLoop(discretise(back, period)).run(held(excitation))[0]
    feedback = np.round(pos / 5e-4) * 5e-4
    for i, a in enumerate("xy"):
        ax = back.axes[a]
        assert ax.encoder_resolution == 5e-4
        # the fit runs the loop unquantised (the file's model quantises as the encoder does): its residual again
        bare = ServoModel({a: AxisModel(ax.num, ax.den, ax.kp, ax.kv)}, "bare", period)
        unquantised = ClosedLoop(discretise(bare, period)).run(held(excitation)[:, i:i + 1])[0][:, 0]
        rms = math.sqrt(np.mean((unquantised - feedback[:, i]) ** 2))
        assert rms == pytest.approx(report["axes"][a]["residual_rms"], rel=1e-6)
        assert np.abs(pos_back[:, i] - pos[:, i]).max() < 5e-3  # the quantised loop: close, not the same ticks


def naive_loop(commands, ax, period, resolution, noise, rng):
    """The closed loop tick by tick from scipy.signal's ZOH sample of the plant: u = kp (c - m) + kv Δc / T, m the
    position plus N(0, noise) rounded to the encoder, the drive's position integrated exactly."""
    from scipy.signal import cont2discrete

    den = np.asarray(ax.den, float)
    num = np.asarray(ax.num, float)
    # the plant with position appended: position = velocity / s, so P(s) = num / (den s)
    A, B, C, _, _ = cont2discrete(_tf2ss(num, np.append(den, 0.0)), period, method="zoh")
    C, B = C[0], B[:, 0]
    # at rest at the first command: the fixed point x = A x whose output is c0 (the integrator's state)
    x = np.linalg.lstsq(np.vstack([C, A - np.eye(A.shape[0])]), np.concatenate([[commands[0]], np.zeros(A.shape[0])]),
                        rcond=None)[0]
    prev = commands[0]
    out = np.empty(commands.size)
    for k, c in enumerate(commands):
        p = float(C @ x)
        out[k] = p
        m = round((p + noise * rng.standard_normal()) / resolution) * resolution
        u = ax.kp * (c - m) + ax.kv * (c - prev) / period
        prev = c
        x = A @ x + B * u
    return out


def _tf2ss(num, den):
    from scipy.signal import tf2ss

    return tf2ss(num, den)


def test_noise_in_the_loop(capsys, tmp_path, excitation):
    """0.2 um of measurement noise before the 0.5 um encoder, which the controller acts on, in a loop the project's
    code does not run: still within 0.5 % and 4 sigma; the residual is said to be noise or quantisation."""
    model = load_servo(PAPER_ENCODER)
    rng = np.random.default_rng(30)
    cmd = held(excitation)
    feedback = np.column_stack([naive_loop(cmd[:, i], model.axes[a], 1e-3, 5e-4, 2e-4, rng) for i, a in enumerate("xy")])
    feedback = np.round(feedback / 5e-4) * 5e-4  # what the encoder reports of the true position
    capture = capture_file(tmp_path / "capture.txt", excitation, feedback)
    report, _ = identified(capsys, tmp_path, capture, "--servo", PAPER)
    for a in "xy":
        r = report["axes"][a]
        assert r["family"] == "lag2"
        assert_found(r, model.axes[a])
        assert r["limited_by"][0] in ("quantisation", "noise")


def test_the_circle_alone_is_too_little_excitation(capsys, tmp_path):
    """The paper's circle moves both axes at one frequency: y's poles come out ±2.6 % (x's ±1.3 %), refused."""
    model = load_servo(PAPER_ENCODER)
    commands = planned(CIRCLE)
    pos = ClosedLoop(discretise(model, 1e-3)).run(held(commands))[0]
    capture = capture_file(tmp_path / "capture.txt", commands, np.round(pos / 5e-4) * 5e-4)
    code, out, err = run_main(capsys, "identify", capture, "--job", CIRCLE, "--servo", PAPER, "-o",
                              tmp_path / "fitted.yaml")
    assert_one_line_error(code, out, err, str(capture), "axis y", "too little excitation", "omega ±", "zeta ±",
                          "at most 2 %", "curves/excitation.yaml")
    assert sorted(os.listdir(tmp_path)) == ["capture.txt"]


def test_a_program_with_its_own_g64_p_is_planned_as_plan_plans_it(capsys, tmp_path):
    """identify --job PROGRAM plans the program as `plan` does: with look-ahead within the G64 P it states.  A
    capture of the stream `plan` wrote is fitted (it was refused as going on past the plan's last tick: the job
    planned without look-ahead, stopping at every corner, is another stream)."""
    rng = np.random.default_rng(7)
    moves = [f"G1 X{x:.3f} Y{y:.3f} Z{z:.3f} F{f:.0f}" for x, y, z, f in
             zip(rng.uniform(-20, 20, 40), rng.uniform(-20, 20, 40), rng.uniform(-20, 20, 40),
                 rng.uniform(600, 6000, 40))]
    program = tmp_path / "p.ngc"
    program.write_text("\n".join(["G21 G90 G64 P0.01", "G0 X0 Y0 Z0", *moves, "M2"]) + "\n")
    code, _, err = run_main(capsys, "plan", program, "-q", "-o", tmp_path / "p.csv")
    assert code == 0, err
    header, *rows = (tmp_path / "p.csv").read_text().splitlines()
    cols = header.split(",")
    data = np.array([[float(v) for v in r.split(",")] for r in rows if not r.startswith("#")])
    commands = np.ascontiguousarray(data[:, [cols.index(a) for a in "xyz"]])
    servo = tmp_path / "xyz.yaml"  # the paper's axes, z a copy of x (no drive limit: a linear loop to fit)
    paper = yaml.safe_load(PAPER.read_text())["axes"]
    servo.write_text(yaml.safe_dump({"axes": {**paper, "z": json.loads(json.dumps(paper["x"]))}}))
    model = load_servo(servo)
    pos = ClosedLoop(discretise(model, 1e-3)).run(held(commands))[0]
    cmd = held(commands)
    ticks = np.minimum(np.arange(pos.shape[0]), commands.shape[0] - 1)
    capture = tmp_path / "capture.txt"
    capture.write_text("".join(f"{k} {' '.join(f'{v:f}' for v in (*c, *f))}\n"
                               for k, c, f in [(0, cmd[0], pos[0])] * LEAD + list(zip(ticks, cmd, pos))))
    code, out, err = run_main(capsys, "identify", capture, "--job", program, "--servo", servo, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["rows"] == commands.shape[0] + HOLD
    for a in "xyz":
        k_true, _ = true_values(model.axes[a])
        assert report["axes"][a]["parameters"]["K"]["value"] == pytest.approx(k_true, rel=1e-3)


# --------------------------------------------------------------------------- LinuxCNC's pid and a HAL drive


def hal_machine(commands, period, drive):
    """sim-machine.hal tick by tick: pid (error-previous-target: P on the previous command; FF1 on the command's
    velocity), then scale, lowpass (out += (in - out) g) and integ (out += in T); the sampler after them."""
    gains = {"x": (60.0, 0.95), "y": (90.0, 0.95)}
    out = np.empty_like(commands)
    for i, a in enumerate("xy"):
        pgain, ff1 = gains[a]
        scale, g = drive[a]
        prev, lag, pos = commands[0, i], 0.0, commands[0, i]
        for k, c in enumerate(commands[:, i]):
            u = pgain * (prev - pos) + ff1 * (c - prev) / period
            prev = c
            lag += (scale * u - lag) * g
            pos += lag * period
            out[k, i] = pos
    return out


def test_a_hal_lowpass_drive_is_found_to_the_capture_digits(capsys, tmp_path, excitation):
    capture = capture_file(tmp_path / "capture.txt", excitation, hal_machine(excitation, 1e-3, HAL_DRIVE), lead=4)
    report, fitted = identified(capsys, tmp_path, capture, "--pid", PID)
    for a in "xy":
        r = report["axes"][a]
        scale, g = HAL_DRIVE[a]
        assert r["family"] == "hal-lowpass" and r["delay"] == 1, r["families"]
        assert r["parameters"]["K"]["value"] == pytest.approx(scale, rel=1e-3)
        assert r["parameters"]["g"]["value"] == pytest.approx(g, rel=1e-3)
        assert r["residual_rms"] <= 1e-6 and r["limited_by"] == ["the capture's 6 decimals"]
        assert r["kp"] == {"x": 60.0, "y": 90.0}[a] and r["kv"] == pytest.approx(0.95 - r["kp"] * 1e-3, abs=1e-15)
        # the strictly proper families cannot follow a drive that passes its input on within the period
        others = {f["family"]: f["residual_rms"] for f in r["families"]}
        assert min(others["lag1"], others["lag2"]) > 100 * r["residual_rms"]
    # the file runs in simulate: the model's contour error on the capture's own commands
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", EXCITATION, "--servo", fitted, "--json")
    assert code == 0, err


# --------------------------------------------------------------------------- refusals


def line_job(path, points, accel_time):
    """A job of lines from the origin through *points* at 50 mm/s."""
    lines = "".join(f"    - line: {{to: [{x}, {y}]}}\n" for x, y in points)
    path.write_text(f"path:\n  start: [0, 0]\n  blocks:\n{lines}"
                    f"profile: {{type: trapezoidal, feedrate: 50 mm/s, accel_time: {accel_time} s}}\n"
                    "interpolator: {period: 1 ms}\n")
    return path


def test_a_short_capture_is_refused(capsys, tmp_path):
    job = line_job(tmp_path / "short.yaml", [(0.5, 0.5)], 0.01)
    commands = planned(job)
    assert commands.shape[0] < 60
    capture = capture_file(tmp_path / "capture.txt", commands, held(commands, 10))
    code, out, err = run_main(capsys, "identify", capture, "--job", job, "--pid", PID)
    assert_one_line_error(code, out, err, str(capture), "axis x", "too short", f"{commands.shape[0] - 1} ticks")


@pytest.fixture(scope="module")
def x_only(tmp_path_factory):
    """A job that moves x alone (one axis identified at a time, as a machine is often tuned), steps of several
    lengths, and its capture from sim-machine.hal's loops."""
    where = tmp_path_factory.mktemp("x-only")
    steps = [(20, 0), (0, 0), (5, 0), (0, 0), (1, 0), (0, 0), (10, 0), (0, 0), (0.3, 0), (0, 0)]
    job = line_job(where / "x-only.yaml", steps, 0.01)
    commands = planned(job)
    return job, capture_file(where / "capture.txt", commands, hal_machine(held(commands), 1e-3, HAL_DRIVE))


def test_an_axis_the_job_does_not_move_is_held_and_the_others_are_fitted(capsys, tmp_path, x_only):
    """y never moves: nothing of its loop is in the capture, and that is no fault of it.  x is fitted (the drive to
    the capture's 6 decimals) and y said not identified; with --pid there is no plant to keep for it."""
    job, capture = x_only
    code, out, err = run_main(capsys, "identify", capture, "--job", job, "--pid", PID, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert list(report["axes"]) == ["x"] and report["held"]["y"]["kept"] is False
    assert report["held"]["y"]["reason"].startswith("it does not move enough to identify: its commands span 0 um")
    x = report["axes"]["x"]
    assert x["family"] == "hal-lowpass"
    assert x["parameters"]["g"]["value"] == pytest.approx(HAL_DRIVE["x"][1], rel=1e-4)
    # a servo file must drive every axis of the job: without a plant for y, -o is refused, and nothing written
    code, out, err = run_main(capsys, "identify", capture, "--job", job, "--pid", PID, "-o", tmp_path / "f.yaml")
    assert_one_line_error(code, out, err, "-o", "not written: axis y is not identified", "--servo START.yaml")
    assert not (tmp_path / "f.yaml").exists()
    code, out, err = run_main(capsys, "identify", capture, "--job", job, "--pid", PID)
    assert code == 0, err
    assert "y: not identified (it does not move enough to identify" in " ".join(out.split())


def test_a_held_axis_keeps_the_start_models(capsys, tmp_path, x_only):
    """With --servo START.yaml the held axis keeps START's model, to the bit, so the fitted file drives every axis
    of the job."""
    job, capture = x_only
    report, fitted = identified(capsys, tmp_path, capture, "--servo", PAPER, job=job)
    assert report["held"]["y"]["kept"] is True
    model, start = load_servo(fitted), load_servo(PAPER)
    assert list(model.axes) == ["x", "y"]
    assert model.axes["y"] == start.axes["y"]
    assert model.axes["x"] != start.axes["x"]  # x is the capture's, not START's


def test_an_axis_that_moves_as_much_as_the_others_is_refused_not_held(capsys, tmp_path):
    """Holding is for an axis the job hardly moves: one as busy as the others that still cannot be fitted is the
    job's too little excitation, refused (the circle: y moves on as many ticks as x)."""
    # (test_the_circle_alone_is_too_little_excitation holds the message; here the count that decides)
    from nurbsinterp import identify

    assert 0.0 < identify.HELD_SHARE < 1.0
    commands = planned(CIRCLE)
    moving = np.count_nonzero(np.diff(commands, axis=0) != 0, axis=0)
    assert moving.min() >= identify.HELD_SHARE * moving.max()


def test_a_loop_not_at_rest_on_the_first_command_is_refused(capsys, tmp_path, excitation):
    feedback = hal_machine(held(excitation), 1e-3, HAL_DRIVE)
    feedback[:, 1] += 0.01  # y 10 um off from the start
    capture = capture_file(tmp_path / "capture.txt", excitation, feedback)
    code, out, err = run_main(capsys, "identify", capture, "--job", EXCITATION, "--pid", PID)
    assert_one_line_error(code, out, err, str(capture), "axis y", "10 um from the first command", "not at rest")


@pytest.mark.parametrize("pid, parts", [
    ("x.Pgain=60,y.Pgain=90,Igain=1", ["Igain", "has no Igain"]),
    ("x.Pgain=60,FF1=0.95", ["axis y has no Pgain"]),
    ("x.Pgain=60,y.Pgain=abc", ["'abc' is not a number"]),
    ("x.Pgain=60,y.Pgain=90,q.FF1=1", ["no axis 'q'"]),
    ("x.Pgain=60,y.Pgain=90,x.Kp=1", ["x.Kp=1", "Pgain, FF1, maxoutput"]),
    ("", ["is empty"]),
])
def test_bad_pid_terms(capsys, tmp_path, excitation, pid, parts):
    capture = capture_file(tmp_path / "capture.txt", excitation, hal_machine(held(excitation), 1e-3, HAL_DRIVE))
    code, out, err = run_main(capsys, "identify", capture, "--job", EXCITATION, "--pid", pid)
    assert_one_line_error(code, out, err, "--pid", *parts)


@pytest.mark.parametrize("args, parts", [
    ([], ["--servo START.yaml or --pid TERMS"]),
    (["--pid", PID, "--servo", PAPER], ["give one of them"]),
    (["--pid", PID, "--json", "-o", "-"], ["both want stdout"]),
])
def test_usage(capsys, tmp_path, args, parts):
    capture = tmp_path / "capture.txt"
    capture.write_text("0 0 0 0 0\n")
    code, out, err = run_main(capsys, "identify", capture, "--job", EXCITATION, *args)
    assert_one_line_error(code, out, err, *parts)


FAULTS = {
    # name: (edit of the capture's lines, parts of the message)
    "overrun": (lambda lines: lines[:99] + ["overrun\n"] + lines[99:], [":100:", "overrun"]),
    "k-gap": (lambda lines: lines[:89] + lines[90:], [":90:", "ticks lost"]),
    "underrun": (lambda lines: lines[:90] + [lines[89]] + lines[90:], [":92:", "resumes", "underrun"]),
    "shorter-than-the-plan": (lambda lines: lines[:1000], [":1000:", "must cover every command"]),
    "another-plan": (lambda lines: lines[:499] + [_bump(lines[499])] + lines[500:], [":500:", "not of this plan"]),
}


def _bump(line):
    f = line.split()
    f[1] = "%f" % (float(f[1]) + 2e-6)
    return " ".join(f) + "\n"


@pytest.mark.parametrize("fault", list(FAULTS))
def test_faults_are_refused_as_simulate_refuses_them(capsys, tmp_path, excitation, fault):
    """The capture's alignment is simulate --actual's: the same faults, the same one-line message."""
    edit, parts = FAULTS[fault]
    good = capture_file(tmp_path / "good.txt", excitation, hal_machine(held(excitation), 1e-3, HAL_DRIVE))
    capture = tmp_path / "capture.txt"
    capture.write_text("".join(edit(good.read_text().splitlines(keepends=True))))
    code, out, err_identify = run_main(capsys, "identify", capture, "--job", EXCITATION, "--pid", PID)
    assert_one_line_error(code, out, err_identify, f"{capture}{parts[0]}", *parts[1:])
    code, out, err_simulate = run_main(capsys, "simulate", "--plan", "--job", EXCITATION, "--actual", capture)
    assert_one_line_error(code, out, err_simulate, f"{capture}{parts[0]}", *parts[1:])
    hint = ("(--force fits it anyway)", "(--force measures it anyway)")
    assert err_identify.replace(*hint) == err_simulate
    assert sorted(os.listdir(tmp_path)) == ["capture.txt", "good.txt"]  # no model file, no temporary


def test_a_model_fitted_at_one_period_is_refused_at_another(capsys, tmp_path, excitation):
    capture = capture_file(tmp_path / "capture.txt", excitation, hal_machine(held(excitation), 1e-3, HAL_DRIVE))
    _, fitted = identified(capsys, tmp_path, capture, "--pid", PID)
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--servo", fitted, "--period", "0.5 ms")
    assert_one_line_error(code, out, err, str(fitted), "period = 1 ms", "fitted there", "0.5 ms")


@pytest.mark.parametrize("count, found", [(5e-4, 5e-4), (1e-3, 1e-3), (2e-5, 2e-5), (1e-6, None), (1 / 1024, None),
                                          (0.0, None)])
def test_the_encoder_is_detected_from_the_feedback(count, found):
    """A sine through 0 .. 12 mm as a capture prints it (%f): whole counts where the count has six decimals."""
    from nurbsinterp.identify import detect_encoder

    true = 6 + 6 * np.sin(np.linspace(0, 20, 5000))
    feedback = np.round(true / count) * count if count else true
    printed = np.array([float("%f" % v) for v in feedback])
    assert detect_encoder(printed) == found


def test_the_reported_deviations_are_the_scatter_over_noise(excitation):
    """Twelve captures of the paper's table with 0.2 um of white noise on the feedback (seeds 0-11): the scatter of
    K, omega and zeta over them is what the fit reports as their standard deviation (a ratio of 0.9-1.14 measured;
    the sample deviation of twelve has some 20 % of its own)."""
    from nurbsinterp.identify import Controller, Record, identify

    model = load_servo(PAPER)
    commands = held(excitation)
    pos = ClosedLoop(discretise(model, 1e-3)).run(commands)[0]
    controllers = {a: Controller(model.axes[a].kp, model.axes[a].kv) for a in "xy"}
    found = {a: [] for a in "xy"}
    reported = {a: [] for a in "xy"}
    for seed in range(12):
        feedback = np.round((pos + 2e-4 * np.random.default_rng(seed).standard_normal(pos.shape)) * 1e6) / 1e6
        rec = Record(["x", "y"], 1e-3, commands, feedback, excitation.shape[0], 0, HOLD, None)
        fit = identify(rec, controllers, capture="noise", job="excitation", controller="paper", families=("lag2",),
                       delays=(0,))
        for a in "xy":
            found[a].append([fit.axes[a].parameters[k].value for k in ("K", "omega", "zeta")])
            reported[a].append([fit.axes[a].parameters[k].std for k in ("K", "omega", "zeta")])
    for a in "xy":
        values = np.array(found[a])
        scatter = values.std(axis=0, ddof=1) / values.mean(axis=0)
        ratio = scatter / np.array(reported[a]).mean(axis=0)
        assert np.all((ratio > 0.5) & (ratio < 2.0)), (a, ratio)
