"""Start-up, the first run and interrupts (issue 12, item 4).

What is checked here is what a user sees, never how fast: which modules a command imports, what a
first run says while it compiles, that a compiled cache is used by every command after it, and that a
signal at any moment ends the run with its status and one line.  Speed is measured in benchmarks/.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
BUTTERFLY = ROOT / "curves" / "butterfly.yaml"
ADAPTIVE = ROOT / "profiles" / "adaptive.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")
HANG_S = 2400  # only a hang catcher: a first run compiles every kernel, 6 min on a quiet 2-core machine, more loaded

PACKAGE = str(Path(__import__("nurbsinterp").__file__).parent)  # a traceback through our code names this
HEAVY = ("numpy", "numba", "scipy", "yaml", "rich", "matplotlib")


def modules_after(*argv) -> set[str]:
    """The modules a fresh interpreter holds after running `nurbsinterp ARGV` through the CLI."""
    script = ("import sys\nfrom nurbsinterp.cli import main\n"
              "try:\n    main(sys.argv[1:])\nexcept SystemExit:\n    pass\n"
              "sys.stderr.write('\\nMODULES ' + ' '.join(sorted(sys.modules)) + '\\n')\n")
    res = subprocess.run([sys.executable, "-c", script, *map(str, argv)], capture_output=True, text=True,
                         timeout=HANG_S, stdin=subprocess.DEVNULL)
    return set(res.stderr.rsplit("MODULES ", 1)[1].split())


def top_level(modules) -> set[str]:
    return {m.split(".")[0] for m in modules}


@pytest.mark.parametrize("argv", [["--version"], ["--help"], ["plan", "--help"], ["simulate", "--help"],
                                  ["info", "--help"], ["compare", "--help"], ["bench", "--help"],
                                  ["warmup", "--help"]], ids=" ".join)
def test_version_and_help_import_neither_numpy_nor_numba(argv):
    assert not top_level(modules_after(*argv)) & set(HEAVY)


def test_each_subcommand_imports_only_what_it_uses(tmp_path):
    info = modules_after("info", CIRCLE, "--json")
    assert {"nurbsinterp.describe", "nurbsinterp.nurbs"} <= info
    assert not {"nurbsinterp.servo", "nurbsinterp.simulation", "nurbsinterp.plots", "nurbsinterp.interpolate",
                "nurbsinterp.metrics", "matplotlib"} & info
    plan = modules_after("plan", CIRCLE, "-q", "-o", tmp_path / "c.csv")
    assert "nurbsinterp.interpolate" in plan
    assert not {"nurbsinterp.servo", "nurbsinterp.simulation", "nurbsinterp.plots", "nurbsinterp.describe",
                "matplotlib", "rich"} & (top_level(plan) | plan)


@needs_exe
def test_a_first_run_says_it_compiles_then_no_command_compiles_again(tmp_path):
    """A fresh cache: the first command says so once, compiles what every command needs, and from then on
    plan, simulate, info, compare and warmup load the cache (the safety net would say 'compiling kernel')."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))

    def run(*argv, stdin=None):
        return subprocess.run([str(EXE), *map(str, argv)], capture_output=True, env=env, timeout=HANG_S,
                              input=stdin, stdin=None if stdin is not None else subprocess.DEVNULL)

    first = run("info", CIRCLE, "--json")
    assert first.returncode == 0, first.stderr
    lines = first.stderr.decode().splitlines()
    assert len(lines) == 2, lines
    assert lines[0].startswith("nurbsinterp: first run") and "compiling" in lines[0] and "minutes" in lines[0]
    assert lines[1].startswith("nurbsinterp: kernels compiled in")
    assert json.loads(first.stdout)["length"] == pytest.approx(100 * 3.141592653589793, rel=1e-12)

    stream = run("plan", BUTTERFLY, "--profile", ADAPTIVE, "--interpolator", "exact", "--format", "bin")
    csv = run("plan", CIRCLE, "--interpolator", "rk4", "--profile-type", "bell", "--accdec", "after", "-q")
    # per-axis limits (profile.axes) reach kernel signatures of their own: warmed up too
    axes_job = tmp_path / "axes.yaml"
    axes_job.write_text(BUTTERFLY.read_text().split("profile:")[0] + "profile:\n  type: adaptive\n  feedrate: 50\n"
                        "  max_accel: 2000\n  axes:\n    x: {max_velocity: 40, max_accel: 900}\n"
                        "    y: {max_velocity: 30, max_accel: 700}\n")
    later = [stream, csv, run("plan", axes_job, "-q", "--max-jerk", "20000"), run("info", axes_job),
             run("simulate", "-", "--job", BUTTERFLY, "--json", stdin=stream.stdout),
             run("simulate", "-", "--job", CIRCLE, "--json", stdin=csv.stdout),
             run("info", BUTTERFLY, "--profile", ADAPTIVE),
             run("compare", CIRCLE, "--json")]
    for res in later:
        assert res.returncode == 0, res.stderr
        assert b"compiling" not in res.stderr and b"first run" not in res.stderr, res.stderr
    warm = run("warmup", "--json")
    assert warm.returncode == 0 and json.loads(warm.stdout)["already_warm"] is True
    assert json.loads(warm.stdout)["kernels_compiled"] == 0


def interrupt(argv, after_s, sig=signal.SIGINT, env=None):
    proc = subprocess.Popen([str(EXE), *map(str, argv)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env=env)
    time.sleep(after_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=HANG_S)
    return proc.returncode, err.decode()


@needs_exe
@pytest.mark.parametrize("after_s", [0.02, 0.1, 0.25, 0.5, 0.8, 1.2])
def test_ctrl_c_at_any_moment_is_exit_130_and_one_line(tmp_path, after_s):
    """Wherever the signal lands — Python's start, click, numpy, numba's import, the kernel cache being
    loaded (llvmlite calls back into Python there), the run, the output file — the same end: 130, one line,
    no traceback and no file.  A run that finished before the signal came is fine too."""
    out = tmp_path / "c.csv"
    code, err = interrupt(["plan", CIRCLE, "--period", "10 us", "-o", out], after_s)
    if "KeyboardInterrupt" in err and PACKAGE not in err:
        return  # the interpreter's own start, before a line of ours runs: Python's message, as README says
    if code == -signal.SIGINT and err == "":
        return  # earlier still: before Python installs its handler the signal ends it as any program (README)
    assert "Traceback" not in err and "Exception ignored" not in err, err
    if code == 0:
        return
    assert code == 130, err
    assert err.splitlines()[-1] == "nurbsinterp: interrupted", err
    assert err.count("\n") == 1, err
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())


@needs_exe
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_a_signal_while_compiling_ends_the_run(tmp_path, sig, code, word):
    """Inside numba's compiler an interrupt can be swallowed or turned into an error of numba's own: the run
    still ends with the signal's status, after the first-run notice and one line."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    status, err = interrupt(["plan", CIRCLE, "-o", tmp_path / "c.csv"], 4.0, sig, env)
    lines = err.splitlines()
    assert status == code, err
    assert "Traceback" not in err and "internal error" not in err, err
    assert lines[0].startswith("nurbsinterp: first run") and lines[-1] == f"nurbsinterp: {word}", err
    assert len(lines) == 2, err
    assert not (tmp_path / "c.csv").exists()
