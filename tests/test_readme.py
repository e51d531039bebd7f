"""README's results tables say what the current code computes (issue 12, item 7).

docs/readme_tables.py regenerates every marked table; the deterministic ones are recomputed here and
compared with README.md, so a change that moves a figure fails until README is regenerated
(`.venv/bin/python docs/readme_tables.py`).  Timing tables are refreshed by the script, never tested.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "docs"))

import readme_tables  # noqa: E402


#: tables that take longest to compute (the butterfly pre-compensated by every method: half a minute of CPU), checked
#: in the slow set; the quick set checks every other one
SLOW_TABLES = {"precompensation-butterfly"}


@pytest.mark.parametrize("name", [pytest.param(name, marks=pytest.mark.slow) if name in SLOW_TABLES else name
                                  for name in readme_tables.DETERMINISTIC])
def test_readme_table_is_current(name):
    fresh = readme_tables.render([name])
    found = readme_tables.blocks((ROOT / "README.md").read_text())
    assert name in found, f"README.md has no <!-- generated: {name} --> block"
    assert found[name] == fresh[name], (f"README.md's {name} table is stale; run .venv/bin/python "
                                        f"docs/readme_tables.py\n--- README\n{found[name]}--- now\n{fresh[name]}")


def test_every_timing_table_has_its_block():
    found = readme_tables.blocks((ROOT / "README.md").read_text())
    assert set(readme_tables.TIMING) <= set(found)


def test_a_stale_table_is_caught_and_rewritten():
    text = "a\n<!-- generated: t -->\n| old |\n<!-- end: t -->\nb\n"
    assert readme_tables.stale(text, {"t": "| new |\n"}) == ["t"]
    assert readme_tables.rewrite(text, {"t": "| new |\n"}) == "a\n<!-- generated: t -->\n| new |\n<!-- end: t -->\nb\n"
    assert readme_tables.stale(readme_tables.rewrite(text, {"t": "| new |\n"}), {"t": "| new |\n"}) == []


def test_the_job_files_own_example_plans(tmp_path, capsys):
    """README's reference job file (the first YAML block under "The job file"), as a user copies it: it plans.
    (It once set time_constant beside the trapezoidal profile, which refuses it.)"""
    from nurbsinterp.cli import main

    text = (ROOT / "README.md").read_text().split("\n## The job file\n", 1)[1]
    block = text.split("```yaml\n", 1)[1].split("```", 1)[0]
    job = tmp_path / "job.yaml"
    job.write_text(block)
    with pytest.raises(SystemExit) as info:
        main(["plan", str(job), "-q", "-o", str(tmp_path / "out.csv")])
    assert info.value.code == 0, capsys.readouterr().err
    assert (tmp_path / "out.csv").stat().st_size > 0
