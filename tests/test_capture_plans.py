"""What the HAL work left (issue 30, Deliver 5): the start guard, a pre-compensated stream's tracking error
against the plan, and `compare --actual`, each checked against what the stream and the capture hold.

Captures here are what examples/linuxcnc/loopback.hal records: the streamed commands straight back as the
positions (k, x_cmd, y_cmd, x, y, each float as C's %f), the last line held for the hold.  The machine is then
the commands themselves, so every measure of it has a closed form in the stream.
"""
from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.cli import main
from nurbsinterp.config import load_job
from nurbsinterp.path import job_path
from clirun import assert_one_line_error

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
PAPER = ROOT / "servo" / "paper-xy.yaml"
POSITION = 5e-7 + 5e-10 + 1e-13  # mm per axis: %f of a 9-decimal stream value, parsed back
TRACE_ROUNDING = 5e-10  # the trace's 9 decimals


def run_main(capsys, *args, stdin: bytes = b""):
    """nurbsinterp.cli.main in-process with *stdin*: (exit code, stdout, stderr)."""
    saved = sys.stdin
    sys.stdin = io.TextIOWrapper(io.BufferedReader(io.BytesIO(stdin)))
    try:
        with pytest.raises(SystemExit) as info:
            main([str(a) for a in args])
    finally:
        sys.stdin = saved
    out, err = capsys.readouterr()
    return info.value.code, out, err


def hal_lines(capsys, *options) -> list[list[str]]:
    """`plan CIRCLE --format hal --columns k,x,y OPTIONS` as lists of fields."""
    code, out, err = run_main(capsys, "plan", CIRCLE, "--format", "hal", "--columns", "k,x,y", "-q", *options)
    assert code == 0, err
    return [line.split() for line in out.splitlines()]


def loopback(lines, hold: int = 20) -> str:
    """The capture loopback.hal records of these HAL lines: k, the commands received, the same as positions."""
    rows = []
    for k, x, y in lines + [lines[-1]] * hold:
        xs, ys = "%f" % float(x), "%f" % float(y)
        rows.append(f"{k} {xs} {ys} {xs} {ys}\n")
    return "".join(rows)


# --------------------------------------------------------------------------- the start guard


def test_the_start_guard_holds_the_first_command_with_its_k(capsys):
    plain = hal_lines(capsys)
    held = hal_lines(capsys, "--hold-start", "5 ms")  # T = 1 ms: five more lines
    assert held[:6] == [plain[0]] * 6
    assert held[6:] == plain[1:]
    assert hal_lines(capsys, "--hold-start", "5 ticks") == held
    assert hal_lines(capsys, "--hold-start", "4.5 ms") == held  # rounded up to whole ticks
    assert hal_lines(capsys, "--hold-start", "0 s") == plain


def test_the_start_guard_is_said_in_the_summary(capsys):
    code, out, err = run_main(capsys, "plan", CIRCLE, "--format", "hal", "--columns", "k,x,y", "--hold-start", "0.25 s")
    assert code == 0
    assert "start guard      the first command written 250 more times (0.25 s) before tick 0" in err


def test_a_held_start_is_dropped_by_the_capture(capsys, tmp_path):
    lines = hal_lines(capsys, "--hold-start", "100 ms")
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(lines))
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--json", "--actual", cap)
    assert code == 0, err
    meas = json.loads(out)["measured"]
    assert meas["capture_lead_rows"] == 100
    assert meas["ticks"] - meas["hold_ticks"] == len(lines) - 100
    assert meas["contour_error_max"] <= np.sqrt(2) * POSITION  # the commands on the circle, through %f


@pytest.mark.parametrize("args, parts", [
    (("--hold-start", "1 s"), ("--hold-start '1 s'", "--format hal")),
    (("--format", "hal", "--columns", "k,x,y", "--hold-start", "soon"), ("--hold-start 'soon'", "ticks")),
    (("--format", "hal", "--columns", "k,x,y", "--hold-start", "-1 s"), ("--hold-start '-1 s'",
                                                                            "between 0 and 3600 s")),
    (("--format", "hal", "--columns", "k,x,y", "--hold-start", "2 h"), ("--hold-start '2 h'", "unknown unit")),
    (("--format", "hal", "--columns", "k,x,y", "--hold-start", "4000 s"), ("--hold-start '4000 s'", "3600 s")),
    (("--format", "hal", "--hold-start", "1 s"), ("--hold-start '1 s'", "needs the tick column k")),
    (("--format", "hal", "--columns", "k,x,y", "--hold-start", "99999999 ticks"),
     ("--hold-start '99999999 ticks'", "3600 s")),
    (("--rounding", "shaped"), ("--rounding shaped needs --resolution",)),
])
def test_bad_start_guards_and_roundings_are_refused(capsys, tmp_path, args, parts):
    out_file = tmp_path / "out.txt"
    code, out, err = run_main(capsys, "plan", CIRCLE, "-o", out_file, *args)
    assert_one_line_error(code, out, err, *parts)
    assert not out_file.exists()


# --------------------------------------------------------------------------- tracking error against the plan


def _planned(u, n=None):
    path = job_path(load_job(CIRCLE))
    shifted = u if n is None else u + np.asarray(path.shifts)[n.astype(int)]
    return path.programmed.evaluate(shifted)


def _trace(path):
    with open(path) as fh:
        cols = fh.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return cols, data


@pytest.mark.parametrize("fmt", ["bin", "csv"])
def test_a_precompensated_streams_tracking_error_is_against_the_plan(capsys, tmp_path, fmt):
    stream_file = tmp_path / f"shaped.{fmt}"
    code, _, err = run_main(capsys, "plan", CIRCLE, "--precompensate", PAPER, "--format", fmt, "-q", "-o",
                            stream_file)
    assert code == 0, err
    trace_file = tmp_path / "trace.csv"
    code, out, err = run_main(capsys, "simulate", stream_file, "--job", CIRCLE, "--json", "-o", trace_file)
    assert code == 0, err
    report = json.loads(out)
    assert report["precompensated"] == "exact" and report["tracking_against"] == "plan"
    cols, trace = _trace(trace_file)
    plan = _planned(trace[:, cols.index("u")])
    for i, a in enumerate("xy"):
        act = trace[:, cols.index(f"{a}_act")]
        against_plan = np.abs(plan[:, i] - act)
        assert report["tracking_error_max"][a] == pytest.approx(against_plan.max(), abs=2 * TRACE_ROUNDING, rel=0)
        assert report["tracking_error_rms"][a] == pytest.approx(np.sqrt(np.mean(against_plan ** 2)),
                                                                abs=2 * TRACE_ROUNDING, rel=0)
        # the shaped commands are far from the plan: the old measure (command - table) would not pass
        against_commands = np.abs(trace[:, cols.index(f"{a}_cmd")] - act).max()
        assert against_commands > 100 * against_plan.max()
    # a perfect model follows the plan but for the start: the first command is the plan's own, so the table
    # leaves a tick late along the path (y, the circle's first tangent) and catches up over the inverse's slow
    # poles -- a third of a um, against the mm of lag the plain stream's tracking error is
    assert report["tracking_error_max"]["x"] < 1e-8
    assert 1e-4 < report["tracking_error_max"]["y"] < 1e-3
    y = np.abs(plan[:, 1] - trace[:, cols.index("y_act")])
    assert int(np.argmax(y)) < 10 and y[200:].max() < 1e-6


def test_a_plain_streams_report_is_what_it_always_was(capsys, tmp_path):
    stream_file = tmp_path / "plain.bin"
    code, _, err = run_main(capsys, "plan", CIRCLE, "--format", "bin", "-q", "-o", stream_file)
    assert code == 0, err
    code, out, err = run_main(capsys, "simulate", stream_file, "--job", CIRCLE, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert "tracking_against" not in report and "precompensated" not in report
    assert report["tracking_error_max"]["x"] > 1.0e-3 * 1000 * 0.5  # the lag: about a mm on the paper's table


def test_the_table_says_what_the_tracking_error_is_against(capsys, tmp_path):
    code, stream, err = run_main(capsys, "plan", CIRCLE, "--precompensate", PAPER, "-q")
    code, out, err = run_main(capsys, "simulate", "--job", CIRCLE, stdin=stream.encode())
    assert code == 0, err
    assert "the tracking error is the plan's point (C(u) at the tick's u) - table" in out


def test_a_precompensated_capture_is_tracked_against_the_plan(capsys, tmp_path):
    """The loopback machine is the shaped commands: its tracking error against the plan is how far the shaping
    moved them, max |command - C(u)|, through %f."""
    code, stream, err = run_main(capsys, "plan", CIRCLE, "--precompensate", PAPER, "--format", "csv", "-q")
    rows = np.loadtxt(io.StringIO(stream), delimiter=",", skiprows=1, comments="#")
    cols = stream.splitlines()[0].split(",")
    lines = hal_lines(capsys, "--precompensate", PAPER)
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(lines))
    code, out, err = run_main(capsys, "simulate", "--job", CIRCLE, "--json", "--actual", cap, stdin=stream.encode())
    assert code == 0, err
    meas = json.loads(out)["measured"]
    plan = _planned(rows[:, cols.index("u")], rows[:, cols.index("n")])
    for i, a in enumerate("xy"):
        shaping = np.abs(rows[:, cols.index(a)] - plan[:, i]).max()
        assert shaping > 0.1  # mm: the lag the shaping takes out
        assert meas["tracking_error_max"][a] == pytest.approx(shaping, abs=POSITION, rel=0)


# --------------------------------------------------------------------------- compare --actual


def _compare(capsys, cap, *extra):
    code, out, err = run_main(capsys, "compare", CIRCLE, "--json", "--actual", cap, *extra)
    assert code == 0, err
    return json.loads(out)


def test_compare_finds_the_jobs_own_variant(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys)))
    doc = _compare(capsys, cap)
    actual = doc["actual"]
    own = doc["variants"][actual["index"]]
    job = load_job(CIRCLE)
    assert (own["interpolator"], own["profile"], own["accdec"]) == (job.interpolator.method, job.profile.type,
                                                                   job.profile.accdec)
    assert actual["table"] == "variants" and actual["matched_by"] == "commands" and actual["method"] is None
    assert actual["motion_time"] == own["motion_time"]
    # the loopback machine is the commands: on the circle to %f
    assert actual["measured"]["contour_error_max"] <= np.sqrt(2) * POSITION
    assert "precompensation" not in doc


def test_compare_finds_another_variant(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys, "--interpolator", "exact", "--profile-type", "bell")))
    doc = _compare(capsys, cap)
    row = doc["variants"][doc["actual"]["index"]]
    assert (row["interpolator"], row["profile"], row["accdec"]) == ("exact", "bell", "before")
    assert doc["actual"]["label"] == "exact bell before"


def test_compare_finds_a_precompensated_plan_and_adds_its_column(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys, "--precompensate", PAPER, "--precompensate-method", "zpetc")))
    doc = _compare(capsys, cap)
    assert doc["actual"]["table"] == "precompensation" and doc["actual"]["method"] == "zpetc"
    assert [r["method"] for r in doc["precompensation"]] == ["none", "zpetc"]
    # the loopback machine is the shaped commands: as far off the circle as ZPETC's commands, which the model
    # runs back onto it
    assert doc["actual"]["measured"]["contour_error_max"] > 0.01


def test_compare_prints_the_machine_beside_its_plan(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys)))
    code, out, err = run_main(capsys, "compare", CIRCLE, "--actual", cap)
    assert code == 0, err
    lines = out.splitlines()
    at = next(i for i, line in enumerate(lines) if line.startswith("│") and "the machine" in line)
    assert lines[at - 1].replace("│", " ").split()[:3] == ["taylor2", "trapezoidal", "before"]
    assert f"the machine: the capture {cap}" in " ".join(out.split())


def test_compare_without_received_commands_takes_the_jobs_own(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(" ".join(line.split()[:1] + line.split()[3:]) + "\n"
                           for line in loopback(hal_lines(capsys)).splitlines()))
    doc = _compare(capsys, cap, "--actual-columns", "k,x,y")
    assert doc["actual"]["matched_by"] == "ticks"
    assert doc["actual"]["measured"]["contour_error_max"] <= np.sqrt(2) * POSITION


def test_a_capture_of_no_compared_plan_is_refused(capsys, tmp_path):
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys, "--feedrate", "60")))
    code, out, err = run_main(capsys, "compare", CIRCLE, "--actual", cap)
    assert_one_line_error(code, out, err, "the capture is of none of the 17 variant(s)",
                          "the job's own pre-compensated by exact, zpetc, match",
                          "against taylor2 trapezoidal before:", f"{cap}:", "measure it with simulate --actual")


def test_compare_refuses_a_broken_capture_as_simulate_does(capsys, tmp_path):
    lines = loopback(hal_lines(capsys)).splitlines(keepends=True)
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(lines[:100] + ["overrun\n"] + lines[100:]))
    code, out, err = run_main(capsys, "compare", CIRCLE, "--actual", cap)
    assert_one_line_error(code, out, err, f"{cap}:101", "overrun")
    code, out, err = run_main(capsys, "compare", CIRCLE, "--actual-columns", "k,x,y")
    assert_one_line_error(code, out, err, "--actual-columns applies only with --actual")


def test_compare_finds_a_look_ahead_plan(capsys, tmp_path):
    """A program planned with look-ahead: the loopback machine is the commands, so its contour error against
    the program is the commands' own largest deviation, the plan's "max dev", through %f."""
    pocket = ROOT / "curves" / "pocket.ngc"
    code, out, err = run_main(capsys, "plan", pocket, "--tolerance", "5um", "--format", "hal", "--columns",
                              "k,x,y,z", "-q")
    assert code == 0, err
    lines = [line.split() for line in out.splitlines()]
    rows = []
    for k, *values in lines + [lines[-1]] * 20:
        formatted = ["%f" % float(v) for v in values]
        rows.append(" ".join([k, *formatted, *formatted]) + "\n")
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(rows))
    code, out, err = run_main(capsys, "compare", pocket, "--tolerance", "5um", "--servo",
                              ROOT / "servo" / "example-xyz.yaml", "--json", "--actual", cap)
    assert code == 0, err
    doc = json.loads(out)
    row = doc["variants"][doc["actual"]["index"]]
    assert row["interpolator"] == "look-ahead" and doc["actual"]["matched_by"] == "commands"
    assert doc["actual"]["measured"]["contour_error_max"] == pytest.approx(row["command_deviation_max"],
                                                                           abs=np.sqrt(3) * POSITION + 1e-9)


def test_a_precompensated_look_ahead_stream_is_tracked_against_its_commands(capsys, tmp_path):
    """Its commands lie on the blended path, which the stream does not carry: the report says so."""
    pocket, xyz = ROOT / "curves" / "pocket.ngc", ROOT / "servo" / "example-xyz.yaml"
    stream_file = tmp_path / "shaped.bin"
    code, _, err = run_main(capsys, "plan", pocket, "--tolerance", "5um", "--precompensate", xyz, "--format", "bin",
                            "-q", "-o", stream_file)
    assert code == 0, err
    code, out, err = run_main(capsys, "simulate", stream_file, "--job", pocket, "--tolerance", "5um", "--servo", xyz,
                              "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["precompensated"] == "exact" and "tracking_against" not in report
    code, out, err = run_main(capsys, "simulate", stream_file, "--job", pocket, "--tolerance", "5um", "--servo", xyz)
    assert code == 0, err
    assert "the plan's points are not in a look-ahead or acc/dec-after stream" in " ".join(out.split())


def test_the_start_guard_holds_the_rounded_or_shaped_first_command(capsys):
    counted = hal_lines(capsys, "--resolution", "0.5um", "--counts", "--hold-start", "3 ticks")
    plain = hal_lines(capsys, "--resolution", "0.5um", "--counts")
    assert counted[:4] == [plain[0]] * 4 and counted[4:] == plain[1:]
    shaped = hal_lines(capsys, "--precompensate", PAPER, "--hold-start", "5 ticks")
    unheld = hal_lines(capsys, "--precompensate", PAPER)
    assert shaped[:6] == [unheld[0]] * 6 and shaped[6:] == unheld[1:]


def test_a_precompensated_accdec_after_stream_is_tracked_against_its_commands(capsys, tmp_path):
    """After interpolation the stream's u is the curve's before the filter, so C(u) is not the plan's command:
    the stream says accdec=after, and simulate measures it against its commands, saying so."""
    stream_file = tmp_path / "after.bin"
    code, _, err = run_main(capsys, "plan", CIRCLE, "--accdec", "after", "--precompensate", PAPER, "--format", "bin",
                            "-q", "-o", stream_file)
    assert code == 0, err
    assert b"accdec=after" in stream_file.read_bytes().split(b"\n", 1)[0]
    code, out, err = run_main(capsys, "simulate", stream_file, "--job", CIRCLE, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["precompensated"] == "exact" and "tracking_against" not in report
    code, out, err = run_main(capsys, "simulate", "--job", CIRCLE, stdin=run_main(
        capsys, "plan", CIRCLE, "--accdec", "after", "--precompensate", PAPER, "-q")[1].encode())
    assert code == 0, err
    assert "the plan's points are not in a look-ahead or acc/dec-after stream" in " ".join(out.split())


def test_a_run_that_stops_short_is_its_own_fault_not_another_plan(capsys, tmp_path):
    """Every received command matched the job's own plan, then the capture ends: the fault is said as it is."""
    lines = loopback(hal_lines(capsys), hold=0).splitlines(keepends=True)
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(lines[:-100]))
    code, out, err = run_main(capsys, "compare", CIRCLE, "--actual", cap)
    assert_one_line_error(code, out, err, f"{cap}:", "the capture must cover every command")
    assert "none of the" not in err


def test_a_job_whose_own_settings_compare_lacks_is_not_matched_to_another(capsys, tmp_path):
    profile = tmp_path / "own.yaml"
    profile.write_text("profile: {type: adaptive}\ninterpolator: {method: taylor1}\n")
    cap = tmp_path / "capture.txt"
    cap.write_text(loopback(hal_lines(capsys, "--profile", profile)))
    code, out, err = run_main(capsys, "compare", CIRCLE, "--profile", profile, "--actual", cap)
    assert_one_line_error(code, out, err, "the capture is of none of the 17 variant(s)")
    code, out, err = run_main(capsys, "compare", CIRCLE, "--profile", profile, "--actual", cap, "--actual-columns",
                              "k,-,-,x,y")
    assert_one_line_error(code, out, err, "taylor1 adaptive before", "are not among compare's variants")
