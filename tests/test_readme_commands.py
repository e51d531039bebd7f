"""Every command README and docs/*.md show runs (issue 49, item 2): an example can never again be refused.

The fenced ``sh`` blocks and the YAML blocks of README.md and docs/*.md are run in a scratch copy of the bundled
files (curves/, profiles/, servo/, examples/, sweeps/), cwd there, ``nurbsinterp`` on PATH from this venv: a
page's section (its ``##`` heading) runs its blocks in order in one directory, so that what one block writes the
next one reads.  A shell block runs under ``bash -e -o pipefail``: every command, and every stage of a pipeline,
must succeed.  A YAML block is a job file, written to a file and planned, unless its marker says what else it is.

A block that cannot run so says why on the line before its fence (docs/development.md lists the markers):
``<!-- run: no (REASON) -->``, ``<!-- run: slow -->`` (the slow set), ``<!-- run: needs halrun -->`` (skipped,
saying why, where HAL cannot run), ``<!-- run: exit 2 -->`` (a refusal shown on purpose), ... .  An unmarked
block runs, so no example is skipped silently; a marker this module does not know, a ``no`` without its
reason, a fence without a language or a command in an output block fails the structure test.
"""
from __future__ import annotations

import functools
import importlib.util
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
PAGES = [README, *sorted((ROOT / "docs").glob("*.md"))]
EXE = Path(sys.executable).parent / "nurbsinterp"
BUNDLED = ("curves", "profiles", "servo", "examples", "sweeps")
HANG_S = 900  # a hang catcher for one block, not a speed test
LANGUAGES = {"sh", "yaml", "text", "python"}  # every fence names one: shell, YAML, output, Python
FENCE = re.compile(r"^(?P<indent> *)```(?P<lang>\S*)\s*$")
MARKER = re.compile(r"^\s*<!--\s*run:\s*(?P<spec>.*?)\s*-->\s*$")
SETUP_STEPS = ("python3 -m venv ", ".venv/bin/pip install ", ". .venv/bin/activate", "source .venv/bin/activate")


@dataclass(frozen=True)
class Decision:
    """What a block's marker says: run it (how) or not (why)."""

    run: bool = True
    reason: str = ""
    slow: bool = False
    needs: tuple[str, ...] = ()
    exit: int = 0
    kind: str | None = None  # sh: "setup"; yaml: "job" (default), "servo", "profile", "sweep"
    save_as: str | None = None


@dataclass(frozen=True)
class Block:
    page: Path
    line: int  # of the opening fence, 1-based
    lang: str
    text: str
    marker: str | None
    section: str
    decision: Decision = field(default_factory=Decision)

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"


def decide(spec: str | None, lang: str) -> Decision:
    """A marker's spec, read; ValueError names what is wrong with it."""
    if spec is None:
        return Decision(kind="job" if lang == "yaml" else None)
    if spec.startswith("no"):
        reason = re.fullmatch(r"no \((.+)\)", spec)
        if reason is None:
            raise ValueError(f"'run: {spec}': a block not run says why: 'run: no (REASON)'")
        return Decision(run=False, reason=reason[1])
    slow, needs, status, kind, save_as = False, [], 0, None, None
    for item in (part.strip() for part in spec.split(",")):
        if item == "slow":
            slow = True
        elif item.startswith("needs "):
            needs.append(item[len("needs "):])
        elif re.fullmatch(r"exit \d+", item):
            status = int(item.split()[1])
        elif item in ("setup",) and lang == "sh":
            kind = item
        elif item in ("servo", "profile", "sweep") and lang == "yaml":
            kind = item
        elif item.startswith("as ") and lang == "yaml":
            save_as = item[len("as "):]
        else:
            raise ValueError(f"'run: {spec}': '{item}' is not a marker for a {lang} block")
    if lang == "yaml" and kind is None and save_as is None:
        kind = "job"
    return Decision(slow=slow, needs=tuple(needs), exit=status, kind=kind, save_as=save_as)


def parse(page: Path) -> tuple[list[Block], list[str]]:
    """The fenced blocks of *page*, in order, and what is wrong with its fences and markers."""
    lines = page.read_text().split("\n")
    name = page.relative_to(ROOT)
    blocks, faults, section, i = [], [], "", 0
    while i < len(lines):
        line = lines[i]
        if re.match(r"#{1,2} ", line):
            section = line.lstrip("#").strip()
        fence = FENCE.match(line)
        if fence is None:
            if MARKER.match(line) and not (i + 1 < len(lines) and FENCE.match(lines[i + 1])):
                faults.append(f"{name}:{i + 1}: a marker not on the line before a fence")
            i += 1
            continue
        indent, lang = fence["indent"], fence["lang"]
        end = next((j for j in range(i + 1, len(lines)) if lines[j].strip() == "```"), None)
        if end is None:
            faults.append(f"{name}:{i + 1}: a fence never closed")
            break
        body = "\n".join(s[len(indent):] if s.startswith(indent) else s.lstrip() for s in lines[i + 1:end]) + "\n"
        marker = MARKER.match(lines[i - 1]) if i > 0 else None
        spec = marker["spec"] if marker else None
        if lang not in LANGUAGES:
            faults.append(f"{name}:{i + 1}: a fence of language {lang!r}; use one of {sorted(LANGUAGES)}")
        try:
            decision = decide(spec, lang)
        except ValueError as error:
            faults.append(f"{name}:{i + 1}: {error}")
            decision = Decision(run=False, reason="a bad marker")
        if lang == "text" and spec is not None:
            faults.append(f"{name}:{i + 1}: an output block needs no marker")
        if lang == "python" and decision.run:
            faults.append(f"{name}:{i + 1}: a Python block is not run here: mark it 'run: no (REASON)'")
        if lang == "text":
            commands = [s for s in body.splitlines() if s.startswith(("$ ", "nurbsinterp "))]
            if commands:
                faults.append(f"{name}:{i + 1}: a command in an output block (put it in an sh block): {commands[0]}")
        blocks.append(Block(page, i + 1, lang, body, spec, section, decision))
        i = end + 1
    return blocks, faults


def all_blocks() -> list[Block]:
    return [block for page in PAGES for block in parse(page)[0]]


def sections() -> dict[tuple[str, str], list[Block]]:
    """(page, section) -> its shell and YAML blocks, in order."""
    out: dict[tuple[str, str], list[Block]] = {}
    for block in all_blocks():
        if block.lang in ("sh", "yaml"):
            out.setdefault((str(block.page.relative_to(ROOT)), block.section), []).append(block)
    return out


def _slug(text: str) -> str:
    return re.sub(r"[^a-z0-9]+", "-", text.lower()).strip("-")


def _cases(slow: bool):
    cases = []
    for (page, section), blocks in sections().items():
        runnable = [b for b in blocks if b.decision.run]
        if slow and not any(b.decision.slow for b in runnable):
            continue
        if not slow and not any(not b.decision.slow for b in runnable):
            continue
        cases.append(pytest.param(page, section, id=f"{page}::{_slug(section)}"))
    return cases


# --------------------------------------------------------------------------- running a section


@functools.lru_cache(maxsize=None)
def _help(command: str) -> str:
    return subprocess.run([str(EXE), command, "--help"], capture_output=True, text=True, timeout=HANG_S).stdout


def _unmet(need: str, where: Path) -> tuple[str | None, dict]:
    """Why *need* cannot be met here (None: it is), and the environment it adds."""
    if need == "halrun":
        from test_linuxcnc import _halrun  # HAL refuses root: as root, halrun runs as another user, as there

        try:
            return None, {"HALRUN": _halrun(where)}
        except pytest.skip.Exception as skipped:
            return str(skipped), {}
    if need == "dask":
        return (None if importlib.util.find_spec("distributed") else "Dask is not installed (the test extra)"), {}
    option = re.fullmatch(r"(\w+) (--[\w-]+)", need)
    if option:
        command, flag = option.groups()
        return (None if re.search(rf"{flag}\b", _help(command)) else f"nurbsinterp {command} has no {flag} yet"), {}
    raise ValueError(f"unknown need {need!r}")


def _scratch(hal: bool, tmp_path: Path) -> Path:
    """A copy of the bundled files; one any user can enter where HAL runs as another user."""
    where = Path(tempfile.mkdtemp(prefix="nurbsinterp-readme-")) if hal else tmp_path / "work"
    where.mkdir(exist_ok=True)
    if hal:
        where.chmod(0o777)
    for name in BUNDLED:
        shutil.copytree(ROOT / name, where / name)
    if hal:
        for path in where.rglob("*"):
            path.chmod(0o777 if path.is_dir() else path.stat().st_mode | 0o444)
    return where


def _setup_stripped(script: str) -> str:
    """The Quick start's first command without its set-up steps (this venv is set up and on PATH)."""
    steps = [s.strip() for s in script.strip().split("&&")]
    rest = [s for s in steps if not s.startswith(SETUP_STEPS)]
    assert rest and len(rest) < len(steps), f"no set-up step, or nothing after it: {script}"
    return " && ".join(rest)


def _run(block: Block, where: Path, env: dict) -> None:
    d = block.decision
    if block.lang == "sh":
        script = _setup_stripped(block.text) if d.kind == "setup" else block.text
        argv = ["bash", "-e", "-o", "pipefail", "-c", script]
    else:
        name = d.save_as or f"{block.page.stem}-{block.line}.yaml"
        path = (where / "sweeps" / name) if d.kind == "sweep" else where / name
        path.write_text(block.text)
        if d.kind is None:
            return  # `as NAME`: the blocks after it read it
        argv = {"job": [str(EXE), "plan", str(path), "-q", "-o", f"{path}.csv"],
                "servo": [str(EXE), "simulate", "--plan", "--job", "curves/circle.yaml", "--servo", str(path)],
                "profile": [str(EXE), "plan", "curves/circle.yaml", "--profile", str(path), "-q", "-o", f"{path}.csv"],
                "sweep": [str(EXE), "sweep", str(path), "-o", f"{path}.results.csv"]}[d.kind]
        script = " ".join(argv)
    done = subprocess.run(argv, cwd=where, env=env, capture_output=True, text=True, timeout=HANG_S)
    if "Realtime already running" in done.stderr:
        pytest.skip("a LinuxCNC realtime session is running on this machine (halrun -U stops it)")
    assert done.returncode == d.exit, (
        f"{block.where}: exit status {done.returncode}, expected {d.exit}\n{script}\n"
        f"--- stderr (the end)\n{done.stderr[-3000:]}\n--- stdout (the end)\n{done.stdout[-1500:]}")


def _run_section(page: str, section: str, slow: bool, tmp_path: Path) -> None:
    blocks = [b for b in sections()[(page, section)] if b.decision.run and (slow or not b.decision.slow)]
    hal = any("halrun" in b.decision.needs for b in blocks)
    where = _scratch(hal, tmp_path)
    env = {**os.environ, "PATH": f"{EXE.parent}{os.pathsep}{os.environ.get('PATH', '')}", "COLUMNS": "160"}
    not_run, met = [], {}
    try:
        for block in blocks:
            extra, why = {}, None
            for need in block.decision.needs:
                if need not in met:  # once a section: halrun's scratch HOME is made once
                    met[need] = _unmet(need, where)
                why, more = met[need]
                if why:
                    break
                extra.update(more)
            if why:
                not_run.append(f"{block.where} ({why})")
                continue
            _run(block, where, {**env, **extra})
    finally:
        if hal:
            shutil.rmtree(where, ignore_errors=True)
    if not_run:
        pytest.skip(f"{len(blocks) - len(not_run)} block(s) ran; not run: {'; '.join(not_run)}")


@pytest.mark.parametrize("page, section", _cases(slow=False))
def test_the_sections_commands_run(page, section, tmp_path, compiled_kernels):
    _run_section(page, section, slow=False, tmp_path=tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("page, section", _cases(slow=True))
def test_the_sections_commands_run_with_the_slow_ones(page, section, tmp_path, compiled_kernels):
    _run_section(page, section, slow=True, tmp_path=tmp_path)


# --------------------------------------------------------------------------- the pages' structure


def test_every_block_carries_a_decision():
    """Every fence names its language, every marker is one this module reads (a 'no' with its reason), no
    command hides in an output block, no marker strays from its fence."""
    faults = [fault for page in PAGES for fault in parse(page)[1]]
    assert not faults, "\n".join(faults)


def test_a_marker_is_read_as_written():
    assert decide(None, "sh") == Decision()
    assert decide(None, "yaml").kind == "job"
    assert decide("no (placeholder: your program)", "sh") == Decision(run=False, reason="placeholder: your program")
    assert decide("slow, needs halrun", "sh") == Decision(slow=True, needs=("halrun",))
    assert decide("exit 2", "sh").exit == 2
    assert decide("as bad.yaml", "yaml") == Decision(save_as="bad.yaml")
    assert decide("slow, needs dask, sweep", "yaml") == Decision(slow=True, needs=("dask",), kind="sweep")
    for bad, lang in (("no", "sh"), ("no reason", "sh"), ("later", "sh"), ("servo", "sh"), ("setup", "yaml")):
        with pytest.raises(ValueError):
            decide(bad, lang)


def test_a_broken_command_fails_its_section(tmp_path):
    """The runner can fail: a command refused (a misspelt option) fails the section, naming the block."""
    page = tmp_path / "page.md"
    block = Block(page=ROOT / "README.md", line=1, lang="sh", marker=None, section="s",
                  text="nurbsinterp info curves/circle.yaml --tolerence 5um\n")
    where = _scratch(False, tmp_path)
    env = {**os.environ, "PATH": f"{EXE.parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    with pytest.raises(AssertionError, match=r"README.md:1: exit status 2, expected 0"):
        _run(block, where, env)
    piped = Block(page=ROOT / "README.md", line=2, lang="sh", marker=None, section="s",
                  text="nurbsinterp plan curves/no-such-job.yaml | cat\n")  # pipefail: the first stage counts
    with pytest.raises(AssertionError, match=r"exit status 2"):
        _run(piped, where, env)


def test_readme_is_a_guide_that_links_every_page():
    text = README.read_text()
    lines = text.count("\n")
    assert lines <= 600, f"README.md has {lines} lines: move the depth to a docs/ page"
    assert "## Contents" in text
    linked = set(re.findall(r"\]\((docs/[\w.-]+\.md)(?:#[\w-]*)?\)", text))
    pages = {f"docs/{p.name}" for p in PAGES[1:]}
    assert pages - linked == set(), f"docs pages README does not link: {sorted(pages - linked)}"
    assert linked - pages == set(), f"README links pages that do not exist: {sorted(linked - pages)}"


def test_readme_sends_no_one_to_the_developers_files():
    """../shared (the corpus, LinuxCNC's planner harness) is beside the developers' clones, not in a user's."""
    assert "../shared" not in README.read_text()
    assert not [b.where for b in all_blocks() if "../shared" in b.text], "a block uses the developers' files"


def test_readmes_test_command_is_what_ci_runs():
    block = README.read_text().split("## Quick start", 1)[1].split("```sh\n")[2].split("```", 1)[0].strip()
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    setup = next(line for line in ci if line.startswith("python3 -m venv "))
    assert block == f"{setup} && .venv/bin/python -m pytest", (block, setup)
    assert any(line.startswith(".venv/bin/python -m pytest ||") for line in ci)


def test_the_acceptance_walk_is_in_readme_and_run():
    """Issue 49's acceptance: plan the pocket for the bundled INI with blending, read what bound it, simulate its
    contour error on cutting moves, stream it into HAL: each one command of a README block that runs."""
    runnable = [b.text for b in parse(README)[0] if b.lang == "sh" and b.decision.run]
    steps = ["nurbsinterp plan curves/pocket.ngc --machine examples/linuxcnc/mill.ini --tolerance 10um",
             "nurbsinterp simulate --plan --job curves/pocket.ngc --machine examples/linuxcnc/mill.ini --tolerance 10um"
             " --servo servo/example-xyz.yaml",
             "examples/linuxcnc/stream.sh examples/linuxcnc/sim-machine.hal curves/pocket.ngc"
             " --machine examples/linuxcnc/mill.ini --tolerance 10um"]
    for step in steps:
        assert any(step in text for text in runnable), f"no README block that runs has: {step}"
    assert "**bound by**" in README.read_text()
