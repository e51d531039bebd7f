"""`nurbsinterp info`: output on stdout, and every failure as exit 2 plus one line on stderr.

Successful runs go through ``click.testing.CliRunner`` on ``nurbsinterp.cli.cli``.  The one-line
error handling lives in ``nurbsinterp.cli.main`` (``cli.main(standalone_mode=False)`` plus a
mapping of exceptions to exit codes), so failures are run through ``main([...])`` in-process
with capsys, and a handful through the installed executable.
"""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import click
import pytest
import yaml
from click.testing import CliRunner

from nurbsinterp.cli import cli, main
from nurbsinterp.errors import SpecError

ROOT = Path(__file__).resolve().parents[1]
CURVES = sorted((ROOT / "curves").glob("*.yaml"))
CIRCLE = ROOT / "curves" / "circle.yaml"
CIRCLE_LENGTH = 314.159265358979
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test


def runner() -> CliRunner:
    try:  # click < 8.2 mixes stderr into stdout unless told not to
        return CliRunner(mix_stderr=False)
    except TypeError:  # click >= 8.2: stdout and stderr are always separate
        return CliRunner()


def invoke(*args):
    result = runner().invoke(cli, [str(a) for a in args], catch_exceptions=False)
    return result


def info_json(*args) -> dict:
    result = invoke("info", *args, "--json")
    assert result.exit_code == 0, result.stderr
    assert result.stderr == ""
    return json.loads(result.stdout)


def run_main(capsys, *args):
    """nurbsinterp.cli.main in-process: (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def assert_one_line_error(code, out, err, *parts):
    assert code == 2, (code, err)
    assert out == "", f"stdout is not empty: {out!r}"
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, f"stderr is not one line: {err!r}"
    assert err.startswith("nurbsinterp"), err
    for part in parts:
        assert str(part) in err, f"{part!r} not in {err!r}"


def write_job(tmp_path, mutate=None, name="job.yaml"):
    doc = yaml.safe_load(CIRCLE.read_text())
    if mutate is not None:
        mutate(doc)
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True), encoding="utf-8")
    return path


# --------------------------------------------------------------------------- success


def test_json_circle():
    facts = info_json(CIRCLE)
    for key in ("length", "degree", "dimension", "n_control_points", "domain", "min_radius", "motion_time"):
        assert key in facts
    assert facts["length"] == pytest.approx(CIRCLE_LENGTH, rel=0, abs=1e-9)
    assert facts["degree"] == 2
    assert facts["dimension"] == 2
    assert facts["n_control_points"] == 7
    assert facts["domain"] == [0.0, 1.0]
    assert facts["min_radius"] == pytest.approx(50.0, rel=1e-9)
    assert facts["motion_time"] == pytest.approx(3.6416, rel=0, abs=1e-4)
    assert facts["motion_time"] == pytest.approx(CIRCLE_LENGTH / 100.0 + 0.5, rel=1e-12)
    assert (facts["profile"], facts["feedrate"], facts["accel_time"]) == ("trapezoidal", 100.0, 0.5)
    assert (facts["interpolator"], facts["period"]) == ("taylor2", 0.001)


@pytest.mark.parametrize("path", CURVES, ids=[p.name for p in CURVES])
def test_info_works_on_every_example(path):
    raw = yaml.safe_load(path.read_text())
    result = invoke("info", path)
    assert result.exit_code == 0, result.stderr
    assert result.stderr == ""
    assert "length" in result.stdout
    facts = info_json(path)
    if "curve" in raw:
        assert facts["n_control_points"] == len(raw["curve"]["control_points"])
        assert facts["dimension"] == len(raw["curve"]["control_points"][0])
    else:  # a path of several blocks: the look-ahead's plan of it, every block counted
        assert facts["planner"] == "look-ahead"
        assert facts["blocks"] == len(raw["path"]["blocks"])
        assert "look-ahead plan" in result.stdout
    for key in ("length", "motion_time") + (("min_radius",) if facts.get("min_radius") is not None else ()):
        assert math.isfinite(facts[key]) and facts[key] > 0, (key, facts[key])


@pytest.mark.parametrize("name, length, abs_tol", [
    ("circle.yaml", CIRCLE_LENGTH, 1e-9),
    ("tilted-circle-3d.yaml", CIRCLE_LENGTH, 1e-9),
    ("butterfly.yaml", 382.860, 1e-3),
    # The file's comment says "about 190 mm"; an independent quadrature (Cox-de Boor + scipy.quad)
    # gives 172.374788 mm, so the comment is off, not the kernel.
    ("quintic-wave.yaml", 172.374788, 1e-5),
])
def test_example_lengths(name, length, abs_tol):
    assert info_json(ROOT / "curves" / name)["length"] == pytest.approx(length, rel=0, abs=abs_tol)


def test_example_jobs_are_read_with_their_units():
    wave = info_json(ROOT / "curves" / "quintic-wave.yaml")
    assert (wave["degree"], wave["domain"], wave["feedrate"], wave["period"]) == (5, [2.0, 7.0], 50.0, 0.0005)
    assert (wave["profile"], wave["interpolator"], wave["time_constant"]) == ("exponential", "rk4", 0.05)
    tilted = info_json(ROOT / "curves" / "tilted-circle-3d.yaml")
    assert (tilted["dimension"], tilted["feedrate"], tilted["accel_time"], tilted["period"]) == (3, 100.0, 0.2, 0.0005)
    assert tilted["min_radius"] == pytest.approx(50.0, rel=1e-9)


def test_table_goes_to_stdout():
    result = invoke("info", CIRCLE)
    assert result.exit_code == 0
    assert result.stderr == ""
    for text in ("length", "314.159265", "degree", "motion time", "3.641593", "interpolator"):
        assert text in result.stdout, text


def test_table_through_main(capsys):
    code, out, err = run_main(capsys, "info", CIRCLE)
    assert (code, err) == (0, "")
    assert "length" in out and "314.159265" in out


def test_json_through_main(capsys):
    code, out, err = run_main(capsys, "info", CIRCLE, "--json")
    assert (code, err) == (0, "")
    assert json.loads(out)["length"] == pytest.approx(CIRCLE_LENGTH, rel=0, abs=1e-9)


def test_version(capsys):
    result = invoke("--version")
    assert result.exit_code == 0
    assert result.stdout.strip() == f"nurbsinterp, version {version('nurbsinterp')}"
    code, out, err = run_main(capsys, "--version")
    assert (code, err) == (0, "")
    assert version("nurbsinterp") in out


def test_info_help_lists_every_override():
    result = invoke("info", "--help")
    assert result.exit_code == 0
    for option in ("--profile", "--profile-type", "--feedrate", "--accel-time", "--time-constant", "--accdec",
                   "--interpolator", "--period", "--json"):
        assert option in result.stdout


# --------------------------------------------------------------------------- overrides on the command line


def test_feedrate_and_accel_time_overrides():
    facts = info_json(CIRCLE, "--feedrate", "6000 mm/min", "--accel-time", "0")
    assert facts["feedrate"] == 100.0 and facts["accel_time"] == 0.0
    assert facts["motion_time"] == pytest.approx(CIRCLE_LENGTH / 100.0, rel=1e-12)
    facts = info_json(CIRCLE, "--feedrate", "50")
    assert facts["motion_time"] == pytest.approx(CIRCLE_LENGTH / 50.0 + 0.5, rel=1e-12)
    facts = info_json(CIRCLE, "--accel-time", "250 ms")
    assert facts["motion_time"] == pytest.approx(CIRCLE_LENGTH / 100.0 + 0.25, rel=1e-12)


def test_choice_and_period_overrides():
    facts = info_json(CIRCLE, "--profile-type", "exponential", "--time-constant", "50 ms", "--accdec", "after",
                      "--interpolator", "rk4", "--period", "250 us")
    assert facts["profile"] == "exponential"
    assert facts["time_constant"] == 0.05
    assert facts["accdec"] == "after"
    assert facts["interpolator"] == "rk4"
    assert facts["period"] == 0.00025


def test_profile_file_then_command_line(tmp_path):
    pfile = tmp_path / "machine.yaml"
    pfile.write_text("profile:\n  feedrate: 50 mm/s\n  type: bell\ninterpolator:\n  period: 2 ms\n")
    facts = info_json(CIRCLE, "--profile", pfile)
    assert (facts["feedrate"], facts["profile"], facts["period"]) == (50.0, "bell", 0.002)
    assert (facts["accel_time"], facts["interpolator"]) == (0.5, "taylor2")  # from the job
    facts = info_json(CIRCLE, "--profile", pfile, "--feedrate", "1200 mm/min", "--period", "1 ms")
    assert (facts["feedrate"], facts["profile"], facts["period"]) == (20.0, "bell", 0.001)


# --------------------------------------------------------------------------- failures: exit 2, one line


def _set(dotted, value):
    def apply(doc):
        *path, last = dotted.split(".")
        box = doc
        for step in path:
            box = box[int(step)] if isinstance(box, list) else box[step]
        if isinstance(box, list):
            box[int(last)] = value
        else:
            box[last] = value
    return apply


BAD_JOBS = [
    ("weight-negative", _set("curve.weights.2", -0.5), "curve.weights[2] = -0.5 must be > 0"),
    ("knots-decreasing", _set("curve.knots", [0, 0, 0, 0.5, 0.3, 0.5, 0.75, 1, 1, 1]),
     "curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5"),
    ("degree-zero", _set("curve.degree", 0), "curve.degree = 0 must be >= 1"),
    ("cp-3d", _set("curve.control_points.2", [100, 50, 0]), "curve.control_points[2] = [100, 50, 0] has 3 coordinates"),
    ("cp-nan", _set("curve.control_points.1.1", float("nan")), "curve.control_points[1][1] = nan must be a finite number"),
    ("unknown-key", _set("curve.colour", "red"), "curve.colour is not a known key"),
    ("profile-type", _set("profile.type", "scurve"), "profile.type = 'scurve' is not one of"),
    ("feedrate-unit", _set("profile.feedrate", "100 furlongs"), "profile.feedrate = '100 furlongs' has an unknown unit"),
    ("accel-time-dimension", _set("profile.accel_time", "5 mm"), "profile.accel_time = '5 mm' is not a time"),
    ("period-zero", _set("interpolator.period", 0), "interpolator.period = 0 must be > 0"),
    ("method", _set("interpolator.method", "euler"), "interpolator.method = 'euler' is not one of"),
]


@pytest.mark.parametrize("mutate, expected", [pytest.param(m, e, id=i) for i, m, e in BAD_JOBS])
@pytest.mark.parametrize("as_json", [False, True], ids=["table", "json"])
def test_malformed_job(tmp_path, capsys, mutate, expected, as_json):
    path = write_job(tmp_path, mutate)
    code, out, err = run_main(capsys, "info", path, *(["--json"] if as_json else []))
    assert_one_line_error(code, out, err, f"{path}: {expected}")


def test_malformed_job_exact_line(tmp_path, capsys):
    path = write_job(tmp_path, _set("curve.weights.2", -0.5))
    code, out, err = run_main(capsys, "info", path)
    assert (code, out) == (2, "")
    assert err == f"nurbsinterp: {path}: curve.weights[2] = -0.5 must be > 0\n"


@pytest.mark.parametrize("text, expected", [
    pytest.param("", "the file is empty", id="empty"),
    pytest.param("- 1\n- 2\n", "not a list", id="list"),
    pytest.param("curve: [1, 2\n", "line 2, column 1", id="invalid-yaml"),
    pytest.param("curve:\n  degree: 2\n  degree: 3\n", "duplicate key 'degree' (first at line 2)", id="duplicate"),
    pytest.param("curve: {degree: &d 2, order: *d}\n", "aliases", id="alias"),
])
def test_yaml_failures(tmp_path, capsys, text, expected):
    path = tmp_path / "job.yaml"
    path.write_text(text)
    code, out, err = run_main(capsys, "info", path)
    assert_one_line_error(code, out, err, str(path), expected)


def test_non_utf8(tmp_path, capsys):
    path = tmp_path / "job.yaml"
    path.write_bytes(b"curve:\n  degree: \xff\n")
    assert_one_line_error(*run_main(capsys, "info", path), str(path), "not UTF-8")


def test_missing_file(tmp_path, capsys):
    path = tmp_path / "missing.yaml"
    assert_one_line_error(*run_main(capsys, "info", path), str(path), "cannot read")


def test_directory(tmp_path, capsys):
    assert_one_line_error(*run_main(capsys, "info", tmp_path), str(tmp_path), "is a directory")


@pytest.mark.parametrize("args, expected", [
    (["--feedrate=-5"], "--feedrate: profile.feedrate = '-5' must be > 0"),
    (["--feedrate", "-5"], "--feedrate: profile.feedrate = '-5' must be > 0"),
    (["--feedrate", "100 furlongs"], "--feedrate: profile.feedrate = '100 furlongs' has an unknown unit"),
    (["--feedrate", "fast"], "--feedrate: profile.feedrate = 'fast' is not a number"),
    (["--accel-time", "5 mm"], "--accel-time: profile.accel_time = '5 mm' is not a time"),
    (["--accel-time", "-1"], "--accel-time: profile.accel_time = '-1' must be >= 0"),
    (["--time-constant", "0"], "--time-constant: profile.time_constant = '0' must be > 0"),
    (["--period", "0"], "--period: interpolator.period = '0' must be > 0"),
    (["--period", "1 fortnight"], "--period: interpolator.period = '1 fortnight' has an unknown unit"),
])
def test_override_error_names_the_option(capsys, args, expected):
    code, out, err = run_main(capsys, "info", CIRCLE, *args)
    assert_one_line_error(code, out, err, f"nurbsinterp: {expected}")


@pytest.mark.parametrize("text, expected", [
    ("profile:\n  feedrate: -1\n", "profile.feedrate = -1 must be > 0"),
    ("profile:\n  speed: 1\n", "profile.speed is not a known key"),
    ("curve:\n  degree: 2\n", "curve is not a known key"),
    ("", "the file is empty"),
])
def test_profile_file_error_names_the_file(tmp_path, capsys, text, expected):
    pfile = tmp_path / "machine.yaml"
    pfile.write_text(text)
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile", pfile)
    assert_one_line_error(code, out, err, f"nurbsinterp: {pfile}: {expected}")


def test_missing_profile_file(tmp_path, capsys):
    pfile = tmp_path / "missing.yaml"
    assert_one_line_error(*run_main(capsys, "info", CIRCLE, "--profile", pfile), f"{pfile}: cannot read")


@pytest.mark.parametrize("args, expected", [
    (["info", CIRCLE, "--bogus"], "--bogus"),
    (["--bogus", "info", CIRCLE], "--bogus"),
    (["info", CIRCLE, "--profile-type", "scurve"], "--profile-type"),
    (["info", CIRCLE, "--interpolator", "euler"], "--interpolator"),
    (["info", CIRCLE, "--accdec", "during"], "--accdec"),
    (["info", CIRCLE, "--feedrate"], "--feedrate"),
    (["info"], "JOB"),
    (["info", CIRCLE, CIRCLE], "unexpected extra argument"),
    (["infoo", CIRCLE], "infoo"),
])
def test_usage_errors(capsys, args, expected):
    code, out, err = run_main(capsys, *args)
    assert_one_line_error(code, out, err, expected)


def test_debug_shows_the_exception(tmp_path):
    path = write_job(tmp_path, _set("curve.degree", 0))
    with pytest.raises(SpecError, match=r"curve\.degree = 0 must be >= 1"):
        main(["--debug", "info", str(path)])


# --------------------------------------------------------------------------- bugs


def test_path_with_closing_markup_tag(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a short relative path: the table title is not wrapped
    Path("a[").mkdir()
    shutil.copy(CIRCLE, "a[/x].yaml")
    code, out, err = run_main(capsys, "info", "a[/x].yaml")
    assert (code, err) == (0, "")
    assert "a[/x].yaml" in out and "length" in out


def test_plain_relative_path_is_the_table_title(tmp_path, capsys, monkeypatch):
    """Control for the two markup tests below: without brackets the title is the path."""
    monkeypatch.chdir(tmp_path)
    shutil.copy(CIRCLE, "cd.yaml")
    code, out, err = run_main(capsys, "info", "cd.yaml")
    assert (code, err) == (0, "")
    assert "cd.yaml" in out


def test_path_with_markup_is_shown_verbatim(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a short relative path: the table title is not wrapped
    shutil.copy(CIRCLE, "c[bold]d.yaml")
    code, out, err = run_main(capsys, "info", "c[bold]d.yaml")
    assert (code, err) == (0, "")
    assert "c[bold]d.yaml" in out


def test_json_of_a_straight_line_is_strict_json(tmp_path):
    path = tmp_path / "line.yaml"
    path.write_text("curve:\n  degree: 1\n  control_points: [[0, 0], [10, 0]]\n")
    result = invoke("info", path, "--json")
    assert result.exit_code == 0

    def refuse(name):
        raise ValueError(f"not JSON: {name}")

    facts = json.loads(result.stdout, parse_constant=refuse)
    assert facts["length"] == pytest.approx(10.0)


def test_huge_integer_is_bad_input(tmp_path, capsys):
    path = tmp_path / "job.yaml"
    path.write_text("curve:\n  degree: 1" + "0" * 400 + "\n  control_points: [[0, 0], [10, 0]]\n")
    assert_one_line_error(*run_main(capsys, "info", path), "curve.degree")


def test_debug_after_the_subcommand(capsys):
    code, out, err = run_main(capsys, "info", CIRCLE, "--debug")
    assert code in (0, 2)
    if code == 2:
        assert_one_line_error(code, out, err, "--debug")


def test_bare_command_shows_readable_help(capsys):
    """No command: the help keeps its lines (it used to be squashed into one long stderr line)."""
    with pytest.raises(SystemExit) as info:
        main([])
    out, err = capsys.readouterr()
    assert info.value.code in (0, 2)
    assert "Commands:\n" in out + err or (err.count("\n") == 1 and "Commands:" not in err)


# --------------------------------------------------------------------------- the installed executable

needs_exe = pytest.mark.skipif(not EXE.exists(), reason=f"{EXE} is not installed")


def run_exe(*args):
    return subprocess.run([str(EXE), *map(str, args)], capture_output=True, text=True, timeout=HANG_S)


@needs_exe
def test_exe_json():
    proc = run_exe("info", CIRCLE, "--json")
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    facts = json.loads(proc.stdout)
    assert facts["length"] == pytest.approx(CIRCLE_LENGTH, rel=0, abs=1e-9)
    assert facts["motion_time"] == pytest.approx(3.6416, rel=0, abs=1e-4)


@needs_exe
def test_exe_malformed_job(tmp_path):
    path = write_job(tmp_path, _set("curve.weights.2", -0.5))
    proc = run_exe("info", path)
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr == f"nurbsinterp: {path}: curve.weights[2] = -0.5 must be > 0\n"


@needs_exe
def test_exe_unknown_option():
    proc = run_exe("info", CIRCLE, "--bogus")
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "--bogus" in proc.stderr and "Traceback" not in proc.stderr


@needs_exe
def test_exe_version():
    proc = run_exe("--version")
    assert proc.returncode == 0
    assert proc.stdout.strip() == f"nurbsinterp, version {version('nurbsinterp')}"


@needs_exe
def test_exe_debug_shows_traceback(tmp_path):
    path = write_job(tmp_path, _set("curve.knots", [0, 0, 0, 0.5, 0.3, 0.5, 0.75, 1, 1, 1]))
    proc = run_exe("--debug", "info", path)
    assert proc.returncode != 0
    assert "Traceback" in proc.stderr
    assert "SpecError" in proc.stderr and "curve.knots[4] = 0.3" in proc.stderr
    plain = run_exe("info", path)
    assert plain.returncode == 2 and "Traceback" not in plain.stderr
