"""The results tables of README and docs/*.md say what the current code computes (issue 12, item 7).

docs/readme_tables.py regenerates every marked table, in whichever page (README.md or a docs/*.md page) holds
it; the deterministic ones are recomputed here and compared with that page, so a change that moves a figure
fails until the page is regenerated (`.venv/bin/python docs/readme_tables.py`).  Timing tables are refreshed by
the script, never tested; each table, deterministic or timing, has exactly one block across the pages.
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
    where = readme_tables.located()
    assert len(where.get(name, [])) == 1, f"{name}: blocks in {where.get(name, [])}, one page must hold it"
    page = where[name][0]
    held = readme_tables.blocks(page.read_text())[name]
    assert held == fresh[name], (f"{page.relative_to(ROOT)}'s {name} table is stale; run .venv/bin/python "
                                 f"docs/readme_tables.py\n--- {page.name}\n{held}--- now\n{fresh[name]}")


def test_every_table_has_exactly_one_block_across_the_pages():
    """README.md and docs/*.md together: each name of DETERMINISTIC and TIMING in one block of one page, and no
    block of a name the script does not know (it would never be regenerated)."""
    where = readme_tables.located()
    known = set(readme_tables.DETERMINISTIC) | set(readme_tables.TIMING)
    assert not known - set(where), f"tables without a block: {sorted(known - set(where))}"
    assert not set(where) - known, f"blocks no table regenerates: {sorted(set(where) - known)}"
    twice = {name: [p.name for p in pages] for name, pages in where.items() if len(pages) > 1}
    assert not twice, f"tables with more than one block: {twice}"


def test_the_pages_are_readme_and_the_docs():
    assert readme_tables.pages()[0] == ROOT / "README.md"
    assert {p.name for p in readme_tables.pages()[1:]} == {p.name for p in (ROOT / "docs").glob("*.md")}


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


def test_a_table_without_a_block_is_refused_before_any_computing():
    with pytest.raises(SystemExit, match="no page .* has a block for no-such-table"):
        readme_tables._page_of(["no-such-table"])
    assert readme_tables._page_of(["corners"]) == {ROOT / "docs" / "planning.md": ["corners"]}
