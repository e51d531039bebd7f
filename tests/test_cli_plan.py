"""`nurbsinterp plan`: streams on stdout, summaries on stderr, exit codes, pipes, memory.

A few cases run the installed console script in a subprocess (the real process:
pipes, signals, resident memory); the rest call ``nurbsinterp.cli.main([...])``
in-process, which always ends in ``sys.exit``.  No timing assertions.
"""
from __future__ import annotations

import io
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.interpolate import Interpolation
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli
from nurbsinterp.streams import read_stream
from clirun import assert_quiet_close, plan_into_head, run_plan as cli, without_end_mark

ROOT = Path(__file__).resolve().parent.parent
CURVES = ROOT / "curves"
CIRCLE = str(CURVES / "circle.yaml")
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test
HEADER = "k,n,t,u,x,y,v,a"
TICKS = 3643  # ceil(3.6416 s / 1 ms) + 1
EPS = np.finfo(float).eps

needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")



def parse_csv(text: bytes) -> np.ndarray:
    lines = without_end_mark(text).decode("ascii").splitlines()
    assert lines[0] == HEADER
    return np.array([[float(f) for f in line.split(",")] for line in lines[1:]])


def reference(**overrides):
    run = Interpolation(load_cli(CIRCLE, overrides=overrides))
    return np.vstack([c.data for c in run.chunks()])


def close_to_printed(parsed, data):
    dec = np.array([0, 0, 9, 15, 9, 9, 9, 9], dtype=float)
    return (np.abs(parsed - data) <= 0.5 * 10.0 ** -dec + 4 * EPS * np.abs(data)).all()


# =========================================================================== the real process


@needs_exe
def test_plan_to_stdout_subprocess():
    proc = subprocess.run([str(EXE), "plan", CIRCLE], capture_output=True, timeout=HANG_S)
    assert proc.returncode == 0, proc.stderr.decode()
    lines = without_end_mark(proc.stdout).decode("ascii").splitlines()
    assert lines[0] == HEADER
    assert len(lines) == TICKS + 1
    rows = np.array([[float(f) for f in line.split(",")] for line in lines[1:]])  # nothing but data
    assert rows.shape == (TICKS, 8)
    assert close_to_printed(rows, reference())
    err = proc.stderr.decode()
    assert "3643" in err and "3.64159265" in err and "314.159265359" in err and "end gap" in err
    assert HEADER not in err and "Traceback" not in err


@needs_exe
def test_plan_into_a_closed_pipe_is_quiet(tmp_path):
    """`plan ... | head -1`: the reader goes away; no traceback, no error message, exit 141 (or 0)."""
    # 36 k rows (~2 MB): far more than a pipe buffer, so the writer really meets the closed pipe
    code, out, err = plan_into_head(EXE, f'"{CIRCLE}" --period "100 us"', tmp_path / "plan.err", HANG_S)
    assert out == HEADER + "\n"
    assert_quiet_close(code, err)


@needs_exe
def test_memory_does_not_grow_with_the_job():
    """~11 million ticks (1 us, 30 mm/s) need no more resident memory than a tiny job (+50 MB)."""
    wrapper = ("import resource, subprocess, sys\n"
               "code = subprocess.run(sys.argv[1:]).returncode\n"
               "print(code, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)\n")

    def peak_kb(*args):
        proc = subprocess.run([sys.executable, "-c", wrapper, str(EXE), "plan", CIRCLE, "--format", "bin", "-q",
                               "-o", "/dev/null", *args], capture_output=True, text=True, timeout=HANG_S)
        code, kb = proc.stdout.split()
        assert code == "0", proc.stderr
        return int(kb)

    tiny = peak_kb("--period", "10 ms")
    big = peak_kb("--period", "1 us", "--feedrate", "30")
    assert big - tiny <= 50 * 1024, (tiny, big)


@needs_exe
def test_huge_acceleration_does_not_crash_the_process():
    proc = subprocess.run([str(EXE), "plan", CIRCLE, "--feedrate", "1e12", "--accel-time", "1 ns",
                           "--period", "1 ns", "-q"], capture_output=True, timeout=HANG_S)
    assert proc.returncode in (0, 2), proc.returncode
    if proc.returncode == 0:
        rows = parse_csv(proc.stdout)
        assert np.isfinite(rows).all()
    else:
        assert len(proc.stderr.decode().strip().splitlines()) == 1


# =========================================================================== in-process


def test_plan_csv_in_process(capsysbinary):
    code, out, err = cli(capsysbinary, CIRCLE)
    assert code == 0
    rows = parse_csv(out)
    assert rows.shape == (TICKS, 8)
    data = reference()
    assert close_to_printed(rows, data)
    assert np.array_equal(rows[:, 0], np.arange(TICKS))
    assert err.startswith(CIRCLE + ": taylor2, trapezoidal acc/dec before interpolation, T = 1 ms -> stdout")
    assert "ticks            3643 (k = 0..3642)" in err


def test_plan_binary_round_trips_to_the_csv_numbers(capsysbinary):
    code, out_bin, _ = cli(capsysbinary, CIRCLE, "--format", "bin")
    assert code == 0
    head, _, body = without_end_mark(out_bin).partition(b"\n")
    assert head.startswith(b"nurbsinterp-bin 2 k,n,t,u,x,y,v,a curve=")  # the curve's fingerprint follows
    data = np.frombuffer(body, "<f8").reshape(-1, 8)
    assert np.array_equal(data, reference())  # bit for bit
    cols, pieces = read_stream(io.BytesIO(out_bin), "bin")
    assert np.array_equal(np.vstack(list(pieces)), data)
    code, out_csv, _ = cli(capsysbinary, CIRCLE)
    assert code == 0
    assert close_to_printed(parse_csv(out_csv), data)


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_plan_output_file(capsysbinary, tmp_path, fmt):
    path = tmp_path / f"run.{fmt}"
    code, out, err = cli(capsysbinary, CIRCLE, "-o", path, "--format", fmt)
    assert code == 0
    assert out == b""  # nothing on stdout
    assert f"-> {path}" in err
    assert sorted(os.listdir(tmp_path)) == [path.name]  # no temporary file left
    with open(path, "rb") as fh:
        cols, pieces = read_stream(fh, str(path))
        data = np.vstack(list(pieces))
    assert data.shape == (TICKS, 8)
    assert close_to_printed(data, reference())


def test_plan_quiet(capsysbinary):
    code, out, err = cli(capsysbinary, CIRCLE, "--quiet")
    assert code == 0 and err == ""
    assert parse_csv(out).shape == (TICKS, 8)
    code, out, err = cli(capsysbinary, CIRCLE, "-q", "-o", "/dev/null")
    assert code == 0 and err == "" and out == b""


def test_period_override(capsysbinary):
    code, out, err = cli(capsysbinary, CIRCLE, "--period", "250 us", "-q")
    assert code == 0
    rows = parse_csv(out)
    assert rows.shape[0] == math.ceil(3.641592653589793 / 250e-6) + 1 == 14568
    assert np.max(np.abs(rows[:, 2] - np.arange(rows.shape[0]) * 250e-6)) <= 5e-10
    assert close_to_printed(rows, reference(period="250 us"))


def test_feedrate_override_with_units(capsysbinary):
    code, out, _ = cli(capsysbinary, CIRCLE, "--feedrate", "6000 mm/min", "-q")
    assert code == 0
    assert close_to_printed(parse_csv(out), reference())  # 6000 mm/min is the job's own 100 mm/s
    code, out, _ = cli(capsysbinary, CIRCLE, "--feedrate", "3000 mm/min", "-q")
    assert code == 0
    rows = parse_csv(out)
    assert rows[:, 6].max() == 50.0
    assert rows.shape[0] == math.ceil((100 * math.pi / 50 + 0.5) / 1e-3) + 1


def test_other_overrides_take_effect(capsysbinary):
    args = ["--interpolator", "exact", "--profile-type", "bell", "--accel-time", "200 ms", "-q"]
    code, out, _ = cli(capsysbinary, CIRCLE, *args)
    assert code == 0
    ref = reference(interpolator="exact", profile_type="bell", accel_time="200 ms")
    assert close_to_printed(parse_csv(out), ref)
    assert ref.shape[0] == math.ceil((math.pi + 0.2) / 1e-3) + 1
    code, out, _ = cli(capsysbinary, CIRCLE, "--accdec", "after", "--profile-type", "exponential",
                       "--time-constant", "50 ms", "-q")
    assert code == 0
    assert close_to_printed(parse_csv(out), reference(accdec="after", profile_type="exponential",
                                                      time_constant="50 ms"))


def test_after_mode_summary_reports_the_path_deviation(capsysbinary):
    code, _, err = cli(capsysbinary, CIRCLE, "--accdec", "after", "--interpolator", "exact", "-o", "/dev/null")
    assert code == 0
    line = next(x for x in err.splitlines() if "path deviation" in x)
    value = float(line.split("max")[1].split("mm")[0])
    # REFERENCE §5: r(1 - |sin(N ω T/2) / (N sin(ω T/2))|), N = 500, ω = 2 rad/s, T = 1 ms
    assert value == pytest.approx(50 * (1 - math.sin(0.5) / (500 * math.sin(0.001))), rel=5e-6)  # printed %.6g


def test_short_path_summary_says_the_peak_was_lowered(capsysbinary, tmp_path):
    job = tmp_path / "line.yaml"
    job.write_text("curve:\n  degree: 1\n  control_points: [[0, 0], [30, 0]]\n")
    code, out, err = cli(capsysbinary, job)
    assert code == 0
    assert "lowered to 60 mm/s" in err
    rows = parse_csv(out)
    assert rows.shape[0] == 1001 and rows[:, 6].max() == pytest.approx(60.0, abs=1e-9)


BAD_OPTIONS = [
    (["--period", "abc"], "--period"),
    (["--period", "-1 ms"], "--period"),
    (["--period", "0"], "--period"),
    (["--period", "1 kg"], "--period"),
    (["--period", "5 mm/s"], "--period"),
    (["--feedrate", "fast"], "--feedrate"),
    (["--feedrate", "0"], "--feedrate"),
    (["--feedrate", "5 mm"], "--feedrate"),
    (["--feedrate", "nan"], "--feedrate"),
    (["--feedrate", "inf mm/s"], "--feedrate"),
    (["--accel-time", "-0.5"], "--accel-time"),
    (["--accel-time", "500 mm"], "--accel-time"),
    (["--time-constant", "0"], "--time-constant"),
    (["--interpolator", "taylor3"], "--interpolator"),
    (["--profile-type", "parabolic"], "--profile-type"),
    (["--accdec", "during"], "--accdec"),
    (["--format", "xml"], "--format"),
    (["--max-ticks", "0"], "--max-ticks"),
    (["--max-ticks", "100"], "--max-ticks"),  # the circle needs 3643
]


@pytest.mark.parametrize("args,option", BAD_OPTIONS, ids=[" ".join(a) for a, _ in BAD_OPTIONS])
def test_bad_option_values_exit_2_with_one_line(capsysbinary, args, option):
    code, out, err = cli(capsysbinary, CIRCLE, *args)
    assert code == 2
    assert out == b""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert option in lines[0]
    assert lines[0].startswith("nurbsinterp")
    assert "Traceback" not in err


@pytest.mark.parametrize("target,words", [("input", "input file"), ("dir", "is a directory"),
                                          ("missing", "does not exist")])
def test_output_path_refusals(capsysbinary, tmp_path, target, words):
    job = tmp_path / "circle.yaml"
    job.write_bytes(Path(CIRCLE).read_bytes())
    out_path = {"input": job, "dir": tmp_path, "missing": tmp_path / "nowhere" / "run.csv"}[target]
    code, out, err = cli(capsysbinary, job, "-o", out_path)
    assert code == 2 and out == b""
    assert len(err.strip().splitlines()) == 1 and words in err
    assert job.read_bytes() == Path(CIRCLE).read_bytes()
    assert sorted(os.listdir(tmp_path)) == ["circle.yaml"]


def test_missing_job_file(capsysbinary, tmp_path):
    code, out, err = cli(capsysbinary, tmp_path / "nope.yaml")
    assert code == 2 and out == b""
    assert len(err.strip().splitlines()) == 1 and "nope.yaml" in err


def test_after_mode_zero_accel_time_exponential(capsysbinary):
    code, out, err = cli(capsysbinary, CIRCLE, "--accdec", "after", "--profile-type", "exponential",
                         "--accel-time", "0", "-q")
    assert code in (0, 2), err
    if code == 0:
        assert parse_csv(out).shape[0] >= math.ceil(math.pi / 1e-3) + 1
    else:
        assert out == b"" and "internal error" not in err
