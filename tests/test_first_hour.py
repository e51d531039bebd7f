"""A new user's first hour (issue 27, item 8): what the README, --help and the messages say agrees, and says enough.

Each test here failed on the main of the issue.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from click.testing import CliRunner

from nurbsinterp.cli import main
from nurbsinterp.cli.common import PLOT_FORMATS

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def run(*argv, input=None):
    return CliRunner().invoke(main, [str(a) for a in argv], input=input)


def test_quick_start_puts_nurbsinterp_on_path_before_using_it_bare():
    block = README.split("## Quick start", 1)[1].split("```sh", 1)[1].split("```", 1)[0].strip()
    steps = [s.strip() for s in block.split("&&")]
    bare = next(i for i, s in enumerate(steps) if s.startswith("nurbsinterp "))
    assert any(s in (". .venv/bin/activate", "source .venv/bin/activate") for s in steps[:bare]), steps


@pytest.mark.parametrize("command", ["info", "simulate", "compare"])
def test_every_plot_format_is_listed_alike_in_help_readme_and_errors(command, tmp_path):
    extensions = [ext[1:] for ext in PLOT_FORMATS]
    help_text = " ".join(run(command, "--help").output.split())
    assert all(re.search(rf"\b{e}\b", help_text) for e in extensions), help_text
    row = next(line for line in README.splitlines() if line.startswith("| `--plot FILE`"))
    assert re.findall(r"`\.(\w+)`", row) == extensions, row
    res = run(command, ROOT / "curves" / "circle.yaml", "--plot", tmp_path / "x.gif",
              *(["--job", ROOT / "curves" / "circle.yaml"] if command == "simulate" else []))
    assert res.exit_code == 2
    assert all(re.search(rf"\b{e}\b", res.output) for e in extensions), res.output


def test_a_written_plot_is_confirmed_on_stderr(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "a.svg"
    res = CliRunner().invoke(main, ["info", str(ROOT / "curves" / "circle.yaml"), "--profile-type", "adaptive",
                                    "--plot", str(out)])
    assert res.exit_code == 0, res.output
    assert out.stat().st_size > 0
    assert f"plot written to {out}" in res.stderr


def test_warm_up_names_the_stage_it_is_compiling_not_the_one_done():
    from nurbsinterp.warmup import STEPS, warm_up

    calls = []
    warm_up(lambda name, done, count: calls.append((name, done, count)))
    n = len(STEPS)
    assert calls == [(name, i, n) for i, (name, _) in enumerate(STEPS)] + [(None, n, n)]


def test_a_stray_o_after_words_is_named_as_such_not_as_an_o_word(tmp_path):
    prog = tmp_path / "typo.ngc"
    prog.write_text("G21 G90\nG1 X10 F60O\nM2\n")
    res = run("info", prog)
    assert res.exit_code == 2
    line = res.stderr.strip()
    assert "\n" not in line and "typo.ngc:2" in line and "F60O" in line and "typo" in line, line
    assert "not supported" not in line


def test_a_3d_job_on_the_2d_default_servo_names_a_model_with_z():
    res = run("simulate", "--job", ROOT / "curves" / "pocket.ngc", "--self-plan") \
        if "--self-plan" in run("simulate", "--help").output else run("simulate", "--job", ROOT / "curves" / "pocket.ngc")
    assert res.exit_code == 2
    assert "servo/example-xyz.yaml" in res.stderr, res.stderr
    assert (ROOT / "servo" / "example-xyz.yaml").exists()
