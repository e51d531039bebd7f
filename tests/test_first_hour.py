"""A new user's first hour (issue 27, item 8): what the README, --help and the messages say agrees, and says enough.

Each test here failed on the main of the issue.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from nurbsinterp.cli.common import PLOT_FORMATS
from test_cli_contract import run_main

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()




def test_quick_start_puts_nurbsinterp_on_path_before_using_it_bare():
    block = README.split("## Quick start", 1)[1].split("```sh", 1)[1].split("```", 1)[0].strip()
    steps = [s.strip() for s in block.split("&&")]
    bare = next(i for i, s in enumerate(steps) if s.startswith("nurbsinterp "))
    assert any(s in (". .venv/bin/activate", "source .venv/bin/activate") for s in steps[:bare]), steps


@pytest.mark.parametrize("command", ["info", "simulate", "compare"])
def test_every_plot_format_is_listed_alike_in_help_readme_and_errors(command, tmp_path, capsys):
    extensions = [ext[1:] for ext in PLOT_FORMATS]
    help_text = " ".join(run_main(capsys, command, "--help")[1].split())
    assert all(re.search(rf"\b{e}\b", help_text) for e in extensions), help_text
    row = next(line for line in README.splitlines() if line.startswith("| `--plot FILE`"))
    assert re.findall(r"`\.(\w+)`", row) == extensions, row
    job = ["--job", ROOT / "curves" / "circle.yaml"] if command == "simulate" else [ROOT / "curves" / "circle.yaml"]
    code, out, err = run_main(capsys, command, *job, "--plot", tmp_path / "x.gif")
    assert code == 2 and out == ""
    assert all(re.search(rf"\b{e}\b", err) for e in extensions), err


def test_a_written_plot_is_confirmed_on_stderr(tmp_path, capsys):
    picture = tmp_path / "a.svg"
    code, out, err = run_main(capsys, "info", ROOT / "curves" / "circle.yaml", "--profile-type", "adaptive",
                              "--plot", picture)
    assert code == 0, err
    assert picture.stat().st_size > 0
    assert f"plot written to {picture}" in err


def test_warm_up_names_the_stage_it_is_compiling_not_the_one_done():
    from nurbsinterp.warmup import STEPS, warm_up

    calls = []
    warm_up(lambda name, done, count: calls.append((name, done, count)))
    n = len(STEPS)
    assert calls == [(name, i, n) for i, (name, _) in enumerate(STEPS)] + [(None, n, n)]


def test_a_stray_o_after_words_is_named_as_such_not_as_an_o_word(tmp_path, capsys):
    prog = tmp_path / "typo.ngc"
    prog.write_text("G21 G90\nG1 X10 F60O\nM2\n")
    code, out, err = run_main(capsys, "info", prog)
    assert code == 2
    line = err.strip()
    assert "\n" not in line and "typo.ngc:2" in line and "F60O" in line and "typo" in line, line
    assert "not supported" not in line


def test_a_3d_job_on_the_2d_default_servo_names_a_model_with_z(capsys):
    code, out, err = run_main(capsys, "simulate", "--job", ROOT / "curves" / "pocket.ngc", "--plan")
    assert code == 2
    assert "servo/example-xyz.yaml" in err, err
    assert (ROOT / "servo" / "example-xyz.yaml").exists()
