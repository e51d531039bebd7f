"""The command-line contract across commands (issue 12, item 6): output paths, picture formats, a stream
that belongs to another job, results on stdout, the units a summary echoes, what docstrings cite."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from nurbsinterp.cli import main
from clirun import run_main

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
BUTTERFLY = ROOT / "curves" / "butterfly.yaml"
TILTED = ROOT / "curves" / "tilted-circle-3d.yaml"
ADAPTIVE = ROOT / "profiles" / "adaptive.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")


def one_line_error(code, out, err, *parts):
    assert code == 2, err
    assert out == "" and err.count("\n") == 1 and "Traceback" not in err, err
    for part in parts:
        assert str(part) in err, f"{part!r} not in {err!r}"


# --------------------------------------------------------------------------- output paths, before any work

@pytest.mark.parametrize("argv", [
    ["compare", CIRCLE, "--plot", "{d}/nodir/x.png"],
    ["simulate", "--plan", "--job", CIRCLE, "--plot", "{d}/nodir/y.png"],
    ["info", BUTTERFLY, "--profile", ADAPTIVE, "--plot", "{d}/nodir/a.png"],
], ids=lambda a: a[0])
def test_a_plot_path_is_checked_first_and_named_by_its_option(capsys, tmp_path, argv, monkeypatch):
    """compare once ran the whole comparison and then failed with an internal FileNotFoundError."""
    import importlib

    module = importlib.import_module(f"nurbsinterp.cli.{argv[0]}")
    monkeypatch.setattr(module, "ensure_kernels", lambda **_: pytest.fail("work started before the check"))
    code, out, err = run_main(capsys, *[str(a).format(d=tmp_path) for a in argv])
    one_line_error(code, out, err, "--plot", "nodir", "does not exist")
    assert "-o " not in err


def test_an_output_path_is_named_by_its_option(capsys, tmp_path):
    code, out, err = run_main(capsys, "plan", CIRCLE, "-o", tmp_path / "nodir" / "c.csv")
    one_line_error(code, out, err, "-o ", "does not exist")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "-o", tmp_path / "t.csv", "--plot", tmp_path / "t.csv")
    one_line_error(code, out, err, "-o and --plot name the same file")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "-o", "-", "--json")
    one_line_error(code, out, err, "-o -", "--json")


# --------------------------------------------------------------------------- picture formats

SIGNATURES = {".png": b"\x89PNG\r\n\x1a\n", ".jpg": b"\xff\xd8\xff", ".pdf": b"%PDF", ".svg": b"<?xml"}


@pytest.fixture(scope="module")
def circle_stream(tmp_path_factory):
    path = tmp_path_factory.mktemp("circle") / "c.bin"
    with pytest.raises(SystemExit):
        main(["plan", str(CIRCLE), "-q", "--period", "10 ms", "--format", "bin", "-o", str(path)])
    return path


@pytest.mark.parametrize("ext", list(SIGNATURES))
def test_plot_writes_the_format_its_extension_names(capsys, tmp_path, ext, circle_stream):
    """--plot y.jpg once wrote PNG bytes into a .jpg."""
    path = tmp_path / f"p{ext}"
    code, out, err = run_main(capsys, "simulate", circle_stream, "--job", CIRCLE, "--plot", path, "--json")
    assert code == 0, err
    assert path.read_bytes().startswith(SIGNATURES[ext])


@pytest.mark.parametrize("name", ["p.bmp", "p", "p.png.txt"])
def test_plot_refuses_an_extension_it_cannot_write(capsys, tmp_path, name):
    code, out, err = run_main(capsys, "compare", CIRCLE, "--plot", tmp_path / name)
    one_line_error(code, out, err, "--plot", "unknown picture format")
    assert not list(tmp_path.iterdir())


# --------------------------------------------------------------------------- a stream from another job

@pytest.fixture(scope="module")
def butterfly_streams(tmp_path_factory):
    d = tmp_path_factory.mktemp("other")
    for fmt in ("bin", "csv"):
        with pytest.raises(SystemExit):
            main(["plan", str(BUTTERFLY), "-q", "--format", fmt, "-o", str(d / f"b.{fmt}")])
    return d


@pytest.mark.parametrize("fmt, why", [("bin", "another curve"), ("csv", "from the start of the job's path")])
def test_a_stream_of_another_job_is_refused(capsys, butterfly_streams, fmt, why):
    """plan butterfly | simulate --job circle once reported a 33 mm contour error without a word."""
    code, out, err = run_main(capsys, "simulate", butterfly_streams / f"b.{fmt}", "--job", CIRCLE)
    one_line_error(code, out, err, why, "--force")
    code, out, err = run_main(capsys, "simulate", butterfly_streams / f"b.{fmt}", "--job", CIRCLE, "--force", "--json")
    assert code == 0, err
    assert json.loads(out)["contour_error_max"] > 1.0  # what --force asked for


def test_a_stream_of_its_own_job_passes(capsys, butterfly_streams):
    for fmt in ("bin", "csv"):
        code, out, err = run_main(capsys, "simulate", butterfly_streams / f"b.{fmt}", "--job", BUTTERFLY, "--json")
        assert code == 0, err


def test_the_fingerprint_names_the_curve_exactly():
    from nurbsinterp.config import load_job
    from nurbsinterp.cli.common import load_cli

    circle = load_job(CIRCLE).curve
    assert circle.fingerprint == load_cli(CIRCLE, overrides={"feedrate": "10"}).curve.fingerprint
    assert circle.fingerprint != load_job(TILTED).curve.fingerprint
    assert len(circle.fingerprint) == 16 and int(circle.fingerprint, 16) >= 0


# --------------------------------------------------------------------------- results on stdout

@needs_exe
@pytest.mark.parametrize("argv", [["compare", CIRCLE], ["info", CIRCLE], ["simulate", "--plan", "--job", CIRCLE],
                                  ["bench", CIRCLE, "--repeats", "1", "--period", "20 ms"]], ids=lambda a: a[0])
def test_a_commands_table_is_its_result_on_stdout(tmp_path, argv):
    """`compare > file` once gave an empty file: the table was on stderr while info's was on stdout."""
    res = subprocess.run([str(EXE), *map(str, argv)], capture_output=True, stdin=subprocess.DEVNULL, timeout=600)
    assert res.returncode == 0, res.stderr
    # simulate --plan says it planned the job itself (issue 27), and nothing else
    said = f"nurbsinterp: simulate planned {CIRCLE} itself (--plan): no stream was read\n" if argv[0] == "simulate" else ""
    assert res.stderr.decode() == said
    text = res.stdout.decode()
    assert len(text.splitlines()) >= 5 and "\x1b[" not in text  # plain text when piped
    assert max(len(line) for line in text.splitlines()) <= 160


# --------------------------------------------------------------------------- the summary echoes units

def test_the_plan_summary_echoes_feedrate_accel_time_and_period_as_given_and_in_si(capsys, tmp_path):
    code, out, err = run_main(capsys, "plan", CIRCLE, "--feedrate", "6000 mm/min", "--accel-time", "500 ms",
                              "--period", "250 us", "-o", tmp_path / "c.bin", "--format", "bin")
    assert code == 0, err
    assert "feedrate         6000 mm/min (--feedrate) = 100 mm/s = 0.1 m/s" in err
    assert "accel_time       500 ms (--accel-time) = 0.5 s" in err
    assert "period           250 us (--period) = 0.00025 s" in err
    code, out, err = run_main(capsys, "plan", CIRCLE, "-o", tmp_path / "c.csv")
    assert f"period           1 ms ({CIRCLE}) = 0.001 s" in err


def test_a_setting_the_run_does_not_use_says_so(capsys, tmp_path):
    """A program whose F words set every feed block does not move at the profile's feedrate, nor the adaptive
    profile given max_accel at accel_time's ramp: their lines say "not used" (they once read as if they bound
    the run), or name what was used instead; where they are used, no such word."""
    code, _, err = run_main(capsys, "plan", ROOT / "curves" / "raster.ngc", "-o", tmp_path / "r.csv")
    assert code == 0, err
    assert "feeds            2000 mm/min (the program's own, on 1005 of 1005 feed moves)" in err
    assert "tangential accel 200 mm/s^2 (the trapezoidal profile's ramp, F/Ta)" in err
    code, _, err = run_main(capsys, "plan", BUTTERFLY, "--profile-type", "adaptive", "--max-accel", "1000",
                            "-o", tmp_path / "b.csv")
    assert code == 0, err
    assert "accel_time       (default) = 0.5 s; not used: the adaptive profile has max_accel\n" in err
    assert "feedrate         (default) = 100 mm/s = 0.1 m/s\n" in err
    code, _, err = run_main(capsys, "plan", CIRCLE, "-o", tmp_path / "c.csv")
    assert "not used" not in err, err


def test_a_period_of_seconds_is_warned_of_and_names_no_tick_minus_one(capsys, tmp_path):
    """`--period 1` (a number is s) makes the circle five ticks: the summary warns, and a fluctuation that is 0
    at every tick names no tick "-1"; a period in ms warns of nothing."""
    code, _, err = run_main(capsys, "plan", CIRCLE, "--period", "1", "-o", tmp_path / "c.csv")
    assert code == 0, err
    assert "the whole motion is 5 ticks at T = 1 s" in err, err
    assert "k = -1" not in err, err
    code, _, err = run_main(capsys, "plan", CIRCLE, "--period", "0.1", "-o", tmp_path / "c.csv")
    assert code == 0 and "warning" not in err, err


# --------------------------------------------------------------------------- citations a reader can open

def test_no_docstring_cites_a_file_that_is_not_in_the_repository():
    for path in (ROOT / "src").rglob("*.py"):
        assert "REFERENCE" not in path.read_text(), path
