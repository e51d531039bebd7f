"""Options and job fields that would do nothing are refused (issue 27, item 6).

On main `plan curves/circle.yaml --max-accel 5 --max-jerk 1 --chord-tolerance 1nm --corner-tolerance 1mm
--max-normal-accel 1` wrote the trapezoidal stream byte for byte and said nothing, and the same fields in a job
file were validated and then unused.  The rule (config.job.unused_fields, README "Job file"): a field the
planned profile ignores is refused -- one line naming it, its value and the profile, exit 2 -- when it is given
on the command line or in the same file as the profile type in effect; it is noted in one line on stderr when
its file's profile type was replaced, or it comes from a --profile file that states no type.
"""
from __future__ import annotations

from pathlib import Path as FilePath

import pytest
from clirun import assert_one_line_error
from test_cli_contract import run_main

from nurbsinterp.cli.common import load_cli
from nurbsinterp.config import load_job
from nurbsinterp.config.job import USED_BY
from nurbsinterp.errors import SpecError

ROOT = FilePath(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"  # states type: trapezoidal
SQUARE = ROOT / "curves" / "square.yaml"  # trapezoidal, accel_time 0.1 s
ADAPTIVE_FILE = ROOT / "profiles" / "adaptive.yaml"  # type adaptive, chord tolerance, max_accel, max_jerk

#: (option, value, job field) of every option only the adaptive profile reads
ADAPTIVE_ONLY = [("--chord-tolerance", "1nm", "chord_tolerance"), ("--max-accel", "5", "max_accel"),
                 ("--max-jerk", "1", "max_jerk"), ("--max-normal-accel", "1", "max_normal_accel"),
                 ("--corner-tolerance", "1mm", "corner_tolerance")]
COMMANDS = {"plan": ["plan"], "info": ["info"], "simulate": ["simulate", "--plan", "--job"]}


@pytest.fixture(autouse=True)
def empty_stdin(monkeypatch):
    import io
    import sys

    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


def refused(capsys, *args, parts=()):
    code, out, err = run_main(capsys, *args)
    return assert_one_line_error(code, out, err, *parts)


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("option, value, field", ADAPTIVE_ONLY, ids=[o for o, _, _ in ADAPTIVE_ONLY])
@pytest.mark.parametrize("shape", ["trapezoidal", "exponential", "bell"])
def test_an_adaptive_option_with_a_paper_profile_is_refused(capsys, command, option, value, field, shape):
    refused(capsys, *COMMANDS[command], CIRCLE, "--profile-type", shape, option, value,
            parts=(f"{option} {value}", f"the {shape} profile", "only the adaptive profile reads it"))


def test_the_issue_s_five_options_are_refused_in_one_line(capsys):
    options = [word for option, value, _ in ADAPTIVE_ONLY for word in (option, value)]
    err = refused(capsys, "plan", CIRCLE, *options, parts=[o for o, _, _ in ADAPTIVE_ONLY])
    assert "are refused: the trapezoidal profile of" in err and str(CIRCLE) in err


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("shape", ["trapezoidal", "bell", "adaptive"])
def test_a_time_constant_with_another_profile_than_the_exponential_is_refused(capsys, command, shape):
    refused(capsys, *COMMANDS[command], CIRCLE, "--profile-type", shape, "--time-constant", "10 ms",
            parts=("--time-constant 10 ms", f"the {shape} profile", "only the exponential profile"))


@pytest.mark.parametrize("command", COMMANDS)
def test_an_accel_time_with_the_adaptive_profile_and_its_max_accel_is_refused(capsys, command):
    """With max_accel the adaptive profile never reads accel_time (it only stands in for a missing max_accel)."""
    refused(capsys, *COMMANDS[command], CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000",
            "--accel-time", "0.2", parts=("--accel-time 0.2", "the adaptive profile"))


def job(tmp_path, profile: str, name="job.yaml") -> FilePath:
    path = tmp_path / name
    path.write_text("curve: {degree: 1, control_points: [[0, 0], [10, 0]]}\n" + profile)
    return path


@pytest.mark.parametrize("field, value", [("chord_tolerance", "1 um"), ("max_accel", "1000"), ("max_jerk", "30000"),
                                          ("max_normal_accel", "500"), ("corner_tolerance", "10 um"),
                                          ("axes", "{x: {max_accel: 800}}"), ("time_constant", "10 ms")])
@pytest.mark.parametrize("stated", ["", "  type: bell\n"])
def test_a_job_field_its_own_profile_ignores_is_refused(capsys, tmp_path, field, value, stated):
    path = job(tmp_path, f"profile:\n{stated}  {field}: {value}\n")
    shape = "bell" if stated else "trapezoidal"
    err = refused(capsys, "plan", path, parts=(str(path), f"profile.{field} = ", f"the {shape} profile"))
    assert ("(the default profile.type)" in err) == (not stated)


def test_a_profile_file_that_states_a_type_and_a_field_it_ignores_is_refused(tmp_path):
    profile = tmp_path / "p.yaml"
    profile.write_text("profile:\n  type: exponential\n  max_jerk: 1000\n")
    with pytest.raises(SpecError, match=r"p\.yaml: profile\.max_jerk = 1000 is refused: the exponential profile"):
        load_job(CIRCLE, profile_file=profile)


def test_a_job_file_whose_profile_the_command_line_replaced_is_noted_not_refused(capsys):
    """A curve written for one profile planned with another (circle.yaml's accel_time under --profile-type
    adaptive --max-accel) goes on, with one line naming the file and the fields unused."""
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000")
    assert code == 0, err
    notes = [line for line in err.splitlines() if "not used" in line]
    assert notes == [f"nurbsinterp: {CIRCLE}: profile.accel_time = '0.5 s' is not used: the adaptive profile "
                     "chosen by --profile-type ignores it"]


def test_a_path_planned_with_look_ahead_takes_the_adaptive_ramp_only_where_stated_with_it(capsys):
    """A path of several blocks is planned with look-ahead, which reads every field of the profile.  The job
    file's accel_time, written for its own trapezoidal profile, is not the ramp of the adaptive profile the command
    line chose (max_accel binds, as the paper's planner ignores it); --accel-time given with it is."""
    code, out, err = run_main(capsys, "info", SQUARE, "--profile-type", "adaptive", "--max-accel", "1000")
    assert code == 0, err
    assert "tangential accel 1000 mm/s^2 (max_accel)" in out
    assert f"note profile.accel_time of {SQUARE} is not used" in " ".join(out.split())  # said, not dropped
    code, out, err = run_main(capsys, "info", SQUARE, "--profile-type", "adaptive", "--max-accel", "1000",
                              "--accel-time", "0.2s")
    assert code == 0, err
    assert "tangential accel 250 mm/s^2 (the adaptive profile's ramp, F/Ta)" in out and "not used" not in out
    # the exponential's time constant shapes one curve's ramp only: across blocks, said so
    code, out, err = run_main(capsys, "info", SQUARE, "--profile-type", "exponential", "--time-constant", "0.02s")
    assert code == 0, err
    assert "note profile.time_constant shapes the exponential ramp of one curve only" in " ".join(out.split())


def test_a_profile_file_replaced_by_the_command_line_is_noted_in_one_line():
    spec = load_cli(str(CIRCLE), str(ADAPTIVE_FILE), {"profile_type": "bell"})
    assert spec.notes == (f"{ADAPTIVE_FILE}: profile.chord_tolerance = '1 um', profile.max_accel = '1000 mm/s^2', "
                          "profile.max_jerk = '30000 mm/s^3' are not used: the bell profile chosen by --profile-type "
                          "ignores them",)


def test_a_job_s_accel_time_under_a_shared_adaptive_profile_is_noted():
    """circle.yaml's trapezoidal accel_time, planned with profiles/adaptive.yaml (type adaptive, max_accel)."""
    assert load_job(CIRCLE, profile_file=ADAPTIVE_FILE).notes == (
        f"{CIRCLE}: profile.accel_time = '0.5 s' is not used: the adaptive profile of {ADAPTIVE_FILE} ignores it",)


def test_a_shared_profile_file_without_a_type_is_noted(tmp_path):
    """A machine's limits in one file used with every job: with a trapezoidal job they are noted, not refused."""
    machine = tmp_path / "machine.yaml"
    machine.write_text("profile:\n  max_accel: 2000\n  axes: {x: {max_velocity: 60}}\n")
    spec = load_job(CIRCLE, profile_file=machine)
    assert spec.notes == (f"{machine}: profile.max_accel = 2000, profile.axes = {{'x': {{'max_velocity': 60}}}} are "
                          f"not used: the trapezoidal profile of {CIRCLE} ignores them",)


def test_fields_a_profile_reads_are_taken_silently(tmp_path):
    """No false alarm: every field of USED_BY given with a profile that reads it."""
    adaptive = job(tmp_path, "profile: {type: adaptive, chord_tolerance: 1 um, max_accel: 1000, max_jerk: 30000, "
                             "max_normal_accel: 500, corner_tolerance: 10 um, axes: {x: {max_accel: 800}}}\n")
    assert load_job(adaptive).notes == ()
    assert load_job(job(tmp_path, "profile: {type: exponential, accel_time: 0.2, time_constant: 10 ms}\n")).notes == ()
    # the adaptive profile without max_accel reads accel_time as max_accel = feedrate / accel_time
    assert load_job(job(tmp_path, "profile: {type: adaptive, accel_time: 0.2, max_jerk: 30000}\n")).notes == ()
    assert load_job(ROOT / "curves" / "butterfly.yaml", profile_file=ADAPTIVE_FILE).notes == ()  # (no profile: of its own)
    assert set(USED_BY) == {"profile.chord_tolerance", "profile.max_accel", "profile.max_jerk",
                            "profile.max_normal_accel", "profile.corner_tolerance", "profile.axes",
                            "profile.time_constant", "profile.accel_time"}


def test_a_comparison_uses_every_field(capsys, tmp_path):
    """`compare` runs every profile (its adaptive rows read the limits, the exponential ones the time constant):
    nothing of the job is unused there, so nothing is refused or noted."""
    path = job(tmp_path, "profile: {feedrate: 200, accel_time: 0.02, max_accel: 20000, time_constant: 5 ms}\n"
                         "interpolator: {period: 5 ms}\n")
    with pytest.raises(SpecError):
        load_job(path)
    assert load_job(path, every_profile=True).notes == ()
    code, out, err = run_main(capsys, "compare", path, "--json")
    assert code == 0, err
    assert "not used" not in err and "ignored" not in err


def test_a_note_never_joins_a_refusal(capsys):
    """Found by test_robustness's fuzzer: the note on circle.yaml's accel_time, then the tick limit's refusal, made
    two lines on stderr.  The notes are said once the run has succeeded: a refusal stays the one line."""
    refused(capsys, "plan", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1", "--max-ticks", "20000", "-q",
            parts=("--max-ticks",))


def test_per_axis_options_with_a_paper_profile_are_refused_by_their_own_names(capsys):
    """--axis-max-velocity and --axis-max-accel set profile.axes, which only the adaptive profile reads."""
    err = refused(capsys, "plan", CIRCLE, "--axis-max-velocity", "x=60,y=50", "--axis-max-accel", "x=500",
                  parts=("--axis-max-velocity x=60", "--axis-max-velocity y=50", "--axis-max-accel x=500",
                         "the trapezoidal profile"))
    assert "profile.axes =" not in err
