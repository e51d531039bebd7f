"""`simulate --write-capture`: the model's own run written as a LinuxCNC halsampler capture (issue 49, defect 7),
so that `identify` and `simulate --actual` can be tried without HAL.

The capture is read back by the library's reader and by the two commands, unchanged.  Bounds come from the
roundings, not picked:

- %f prints 6 decimals: a printed value is within 5e-7 mm of the model's (plus an ulp parsing it back), the
  trace's 9 decimals within 5e-10 mm: POSITION per axis between the capture and the trace;
- the contour error is 1-Lipschitz in the position: the capture's differs from the model's by at most
  sqrt(dim) * %f's rounding, plus 1e-9 mm for each of the two certified window searches;
- identify's parameters: within SIGMAS of the standard deviation it reports, which the residual sets -- %f's
  floor (1e-6/sqrt(12) mm) without noise, the noise with it.
"""
from __future__ import annotations

import io
import json
import math
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from clirun import assert_one_line_error, in_process, read_trace, run_main
from nurbsinterp.capture import Capture, default_columns, parse_columns
from nurbsinterp.servo import load_servo

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
EXCITATION = ROOT / "curves" / "excitation.yaml"
PAPER = ROOT / "servo" / "paper-xy.yaml"
PAPER_ENCODER = ROOT / "servo" / "paper-xy-encoder.yaml"
PRINTED = 5e-7 + 1e-13  # mm: %f's rounding, and an ulp parsing it back (coordinates below 100 mm)
POSITION = PRINTED + 5e-10  # mm: the capture against the trace's 9 decimals
SEARCH = 1e-9  # mm: a certified window search of the contour error
FLOOR = 1e-6 / math.sqrt(12)  # mm: the residual of %f's rounding alone
SIGMAS = 4.0
LINE = re.compile(r"^\d+( -?\d+\.\d{6}){4} \n$")  # halsampler's: %ld, then %f, each value followed by a space


@pytest.fixture(autouse=True)
def empty_stdin(monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


def read_capture(path, dim=2):
    """The capture through the library's reader, as simulate --actual and identify read it: (commands' rows, the
    hold's rows), each a Block of positions and received commands."""
    columns = parse_columns(default_columns(dim), dim)
    with open(path, "rb") as fh:
        capture = Capture(fh, str(path), columns)
        ticks = int(np.loadtxt(path, usecols=0).max()) + 1
        commands = capture.commands(ticks)
        capture.end_commands()
        hold = capture.hold(1 << 20)
        capture.finish()
    return commands, hold, capture


@pytest.fixture(scope="module")
def circle(tmp_path_factory):
    """The circle through the paper's table: its report, its trace and its noiseless capture, from one run."""
    d = tmp_path_factory.mktemp("circle")
    code, out, err = in_process(["simulate", "--plan", "--job", CIRCLE, "--servo", PAPER, "--json",
                                  "-o", d / "trace.csv", "--write-capture", d / "capture.txt"])
    assert code == 0, err
    code, alone, err = in_process(["simulate", "--plan", "--job", CIRCLE, "--servo", PAPER, "--json"])
    assert code == 0, err
    cols, trace = read_trace(d / "trace.csv")
    return {"report": json.loads(out), "alone": json.loads(alone), "cols": cols, "trace": trace, "dir": d,
            "capture": d / "capture.txt"}


def test_the_capture_is_the_models_run_as_halsampler_prints_it(circle):
    """One line per tick of the run (the hold included, k held at the last command's tick), halsampler's layout;
    read back, the commands and the positions are the trace's to %f's rounding; the report is the run's without it."""
    rep, cols, trace = circle["report"], circle["cols"], circle["trace"]
    assert rep == circle["alone"]
    lines = circle["capture"].read_text().splitlines(keepends=True)
    assert len(lines) == rep["ticks"] == trace.shape[0]
    assert all(LINE.match(line) for line in lines), next(line for line in lines if not LINE.match(line))
    commands, hold, capture = read_capture(circle["capture"])
    assert capture.lead_rows == 0 and capture.hold_rows == rep["ticks"] - rep["command_ticks"] > 0
    k = np.loadtxt(circle["capture"], usecols=0)
    assert np.array_equal(k, np.minimum(trace[:, 0], rep["command_ticks"] - 1))
    n = rep["command_ticks"]
    for i, a in enumerate("xy"):
        cmd, act = trace[:, cols.index(f"{a}_cmd")], trace[:, cols.index(f"{a}_act")]
        assert np.abs(commands.command[:, i] - cmd[:n]).max() <= POSITION
        assert np.abs(commands.position[:, i] - act[:n]).max() <= POSITION
        assert np.abs(hold.command[:, i] - cmd[n - 1]).max() <= PRINTED
        assert np.abs(hold.position[:, i] - act[n:]).max() <= POSITION


def test_simulate_actual_measures_the_noiseless_capture_as_the_model(capsys, circle):
    """The capture as the machine's run: its contour error is the model's to %f's rounding, every tick measured."""
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--servo", PAPER, "--json",
                              "--actual", circle["capture"])
    assert code == 0, err
    report = json.loads(out)
    meas, rep = report["measured"], circle["report"]
    bound = math.sqrt(2) * PRINTED + 2 * SEARCH
    assert meas["contour_error_max"] == pytest.approx(rep["contour_error_max"], abs=bound, rel=0)
    assert meas["contour_error_rms"] == pytest.approx(rep["contour_error_rms"], abs=bound, rel=0)
    for a in "xy":
        assert meas["tracking_error_max"][a] == pytest.approx(rep["tracking_error_max"][a], abs=PRINTED, rel=0)
        assert meas["as_received_max"][a] <= PRINTED
    assert meas["ticks"] == rep["ticks"] and meas["hold_ticks"] == meas["capture_hold_rows"]


def true_values(ax):
    """K (DC gain) and the poles' magnitudes of a servo file's axis."""
    return ax.num[-1] / ax.den[-1], np.sort(np.abs(np.roots(ax.den)))


def assert_found(fit, ax):
    """identify's K and poles against the servo file's: within SIGMAS of the deviation it reports."""
    k_true, poles_true = true_values(ax)
    k = fit["parameters"]["K"]
    assert abs(k["value"] / k_true - 1) <= SIGMAS * k["std"], (k, k_true)
    poles = sorted(fit["poles"], key=lambda p: p["magnitude"])
    assert len(poles) == len(poles_true)
    for p, true in zip(poles, poles_true):
        assert abs(p["magnitude"] / true - 1) <= SIGMAS * p["std"], (p, true)


def test_identify_recovers_the_model_from_its_noiseless_capture(capsys, circle):
    """The README's walk without noise: identify finds the paper's plants on the circle, the residual %f's floor,
    and writes them back (the file's plant is the report's)."""
    fitted = circle["dir"] / "fitted.yaml"
    code, out, err = run_main(capsys, "identify", circle["capture"], "--job", CIRCLE, "--servo", PAPER, "--json",
                              "-o", fitted)
    assert code == 0, err
    report = json.loads(out)
    model, back = load_servo(PAPER), load_servo(fitted)
    assert report["rows"] == circle["report"]["ticks"] and report["capture_lead_rows"] == 0
    for a in "xy":
        fit = report["axes"][a]
        assert fit["family"] == "lag2" and fit["delay"] == 0 and fit["encoder_resolution"] is None
        assert fit["residual_rms"] <= 1.5 * FLOOR and fit["limited_by"] == ["the capture's 6 decimals"]
        assert fit["advice"] is None
        assert_found(fit, model.axes[a])  # the deviations %f's floor leaves: K's some 1e-8, the poles' 1e-5 - 1e-4
        k, poles = true_values(back.axes[a])
        assert k == pytest.approx(fit["parameters"]["K"]["value"], rel=1e-12)
        assert poles == pytest.approx(sorted(p["magnitude"] for p in fit["poles"]), rel=1e-9)


def test_the_readme_walk_with_noise_lands_within_its_standard_errors(capsys, tmp_path):
    """simulate --write-capture --noise 0.1um, then identify: on the excitation job the paper's plants are found
    within SIGMAS of the reported deviations, the residual is the noise and is said to be."""
    capture = tmp_path / "capture.txt"
    code, _, err = run_main(capsys, "simulate", "--plan", "--job", EXCITATION, "--servo", PAPER,
                            "--write-capture", capture, "--noise", "0.1um")
    assert code == 0, err
    code, out, err = run_main(capsys, "identify", capture, "--job", EXCITATION, "--servo", PAPER, "--json",
                              "-o", tmp_path / "fitted.yaml")
    assert code == 0, err
    report = json.loads(out)
    model = load_servo(PAPER)
    rows = report["rows"]
    for a in "xy":
        fit = report["axes"][a]
        assert fit["family"] == "lag2" and fit["limited_by"] == ["noise"] and fit["advice"] is None
        assert_found(fit, model.axes[a])
        # the residual is the noise: its RMS and the noise identify sees in it, each within SIGMAS of the sample
        # deviation's own scatter (1/sqrt(2 n)) of 0.1 um, and %f's rounding beside it
        sigma = math.hypot(1e-4, FLOOR)
        for value in (fit["residual_rms"], fit["noise"]):
            assert value == pytest.approx(sigma, rel=SIGMAS / math.sqrt(2 * rows)), (a, value)


def test_noise_encoder_and_seed(capsys, tmp_path, circle):
    """--noise on the feedback only, reproducible by its seed; --encoder rounds after the noise; a model with its
    own encoder is captured as that encoder counts."""
    def capture(name, *args, servo=PAPER):
        path = tmp_path / name
        code, _, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--servo", servo,
                                "--write-capture", path, *args)
        assert code == 0, err
        return path

    clean = np.loadtxt(circle["capture"])
    noisy = capture("noisy.txt", "--noise", "0.1um")
    assert noisy.read_bytes() == capture("seed0.txt", "--noise", "0.1um", "--seed", "0").read_bytes()
    assert noisy.read_bytes() != capture("seed1.txt", "--noise", "0.1um", "--seed", "1").read_bytes()
    rows = np.loadtxt(noisy)
    assert np.array_equal(rows[:, :3], clean[:, :3])  # k and the commands, to the printed digit
    noise = rows[:, 3:] - clean[:, 3:]
    n = noise.size
    assert abs(noise.mean()) <= SIGMAS * 1e-4 / math.sqrt(n) + PRINTED
    assert noise.std() == pytest.approx(1e-4, rel=SIGMAS / math.sqrt(2 * n) + PRINTED / 1e-4)
    counted = np.loadtxt(capture("encoder.txt", "--noise", "0.1um", "--encoder", "0.5um"))
    assert np.array_equal(counted[:, :3], clean[:, :3])
    counts = counted[:, 3:] / 5e-4
    assert np.abs(counts - np.round(counts)).max() <= 1e-9  # whole counts, as %f prints a multiple of 0.5 um
    assert np.abs(counted[:, 3:] - rows[:, 3:]).max() <= 2.5e-4 + 2 * PRINTED  # the noisy position, rounded
    own = np.loadtxt(capture("own.txt", servo=PAPER_ENCODER))[:, 3:] / 5e-4
    assert np.abs(own - np.round(own)).max() <= 1e-9


def test_the_capture_on_stdout(capsys, circle):
    """--write-capture -: the capture on stdout, byte for byte the file's; the report on stderr."""
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--servo", PAPER, "--write-capture", "-")
    assert code == 0, err
    assert out == circle["capture"].read_text()
    assert "contour error" in err


def test_a_failed_run_leaves_no_capture(capsys, tmp_path):
    """Written atomically: a run refused after its commands (the hold passes --max-ticks) leaves no file, not even
    a temporary one, though every command's line had been written."""
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--servo", PAPER, "--max-ticks", "3700",
                              "--write-capture", tmp_path / "capture.txt", "-o", tmp_path / "trace.csv")
    assert_one_line_error(code, out, err, "the hold until the table settles", "--max-ticks")
    assert os.listdir(tmp_path) == []


def test_a_look_ahead_program_planned_here_or_read(capsys, tmp_path):
    """A G-code program with --tolerance: the capture of simulate planning it is the capture of simulate reading
    plan's stream, byte for byte, and simulate --actual measures it as the model, against the program's blocks."""
    from test_lookahead import program, random_program

    path = program(tmp_path, random_program(np.random.default_rng(13), "corners", n=30))
    servo = tmp_path / "xyz.yaml"  # the paper's axes, z a copy of x: no encoder, no drive limit
    paper = yaml.safe_load(PAPER.read_text())["axes"]
    servo.write_text(yaml.safe_dump({"axes": {**paper, "z": json.loads(json.dumps(paper["x"]))}}))
    common = ["--job", path, "--tolerance", "5um", "--servo", servo]
    code, out, err = run_main(capsys, "simulate", "--plan", *common, "--max-accel", "1000", "--json",
                              "--write-capture", tmp_path / "planned.txt")
    assert code == 0, err
    model = json.loads(out)
    code, _, err = run_main(capsys, "plan", path, "--tolerance", "5um", "--max-accel", "1000", "--format", "bin",
                            "-q", "-o", tmp_path / "run.bin")
    assert code == 0, err
    code, _, err = run_main(capsys, "simulate", tmp_path / "run.bin", *common, "--write-capture", tmp_path / "read.txt")
    assert code == 0, err
    planned = (tmp_path / "planned.txt").read_text()
    assert planned == (tmp_path / "read.txt").read_text()
    assert len(planned.splitlines()) == model["ticks"] and "nan" not in planned
    code, out, err = run_main(capsys, "simulate", tmp_path / "run.bin", *common, "--json",
                              "--actual", tmp_path / "planned.txt")
    assert code == 0, err
    meas = json.loads(out)["measured"]
    bound = math.sqrt(3) * PRINTED + 2 * SEARCH
    assert meas["contour_error_max"] == pytest.approx(model["contour_error_max"], abs=bound, rel=0)
    assert meas["ticks"] == model["ticks"]


@pytest.mark.parametrize("args, parts", [
    (["--noise", "0.1um"], ["--noise applies only with --write-capture"]),
    (["--encoder", "0.5um"], ["--encoder applies only with --write-capture"]),
    (["--seed", "3"], ["--seed applies only with --write-capture"]),
    (["--write-capture", "{d}/c.txt", "--noise", "-0.1um"], ["--noise '-0.1um'", "must be a finite length >= 0"]),
    (["--write-capture", "{d}/c.txt", "--noise", "abc"], ["--noise 'abc'", "is not a number"]),
    (["--write-capture", "{d}/c.txt", "--noise", "1e400"], ["--noise '1e400'", "finite length"]),
    (["--write-capture", "{d}/c.txt", "--encoder", "0"], ["--encoder '0'", "must be a finite length > 0"]),
    (["--write-capture", "{d}/c.txt", "--encoder", "1 s"], ["--encoder '1 s'", "is not a length"]),
    (["--write-capture", "{d}/c.txt", "--seed", "-1"], ["--seed", "-1"]),
    (["--write-capture", "-", "-o", "-"], ["-o - and --write-capture -", "both want stdout"]),
    (["--write-capture", "-", "--json"], ["--write-capture - and --json", "both want stdout"]),
    (["--write-capture", "{d}/c.txt", "-o", "{d}/c.txt"], ["-o and --write-capture name the same file"]),
    (["--write-capture", str(CIRCLE)], ["--write-capture", "refusing to overwrite the input file"]),
    (["--write-capture", "{d}/nodir/c.txt"], ["--write-capture", "does not exist"]),
    (["--write-capture", "{d}/c.txt", "--actual", str(CIRCLE)], ["--write-capture", "without --actual"]),
])
def test_refusals(capsys, tmp_path, args, parts):
    args = [a.replace("{d}", str(tmp_path)) for a in args]
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, *args)
    assert_one_line_error(code, out, err, *parts)
    assert os.listdir(tmp_path) == []


def test_the_writer_refuses_a_value_it_cannot_print():
    """No NaN or inf ever reaches a capture (%f would print them, and no reader takes them): refused, naming the
    tick, and nothing of the chunk written."""
    from nurbsinterp.capture import CaptureWriter
    from nurbsinterp.errors import NurbsInterpError
    from nurbsinterp.simulation import trace_columns

    columns = trace_columns(["x", "y"])
    rows = np.zeros((3, len(columns)))
    rows[:, 0] = [0, 1, 2]
    rows[1, columns.index("y_act")] = np.nan
    fh = io.BytesIO()
    writer = CaptureWriter(fh, columns)
    list(writer.through([np.zeros((3, 1))]))
    with pytest.raises(NurbsInterpError, match=r"non-finite value .*\(tick k = 1\)"):
        writer.write(rows)
    assert fh.getvalue() == b""
