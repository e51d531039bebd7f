"""Start-up, the first run and interrupts (issue 12, item 4).

What is checked here is what a user sees, never how fast: which modules a command imports, what a
first run says while it compiles, that a compiled cache is used by every command after it, and that a
signal at any moment ends the run with its status and one line.  Speed is measured in benchmarks/.
"""
from __future__ import annotations

import os
import re
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
RASTER = ROOT / "curves" / "raster.ngc"
POCKET = ROOT / "curves" / "pocket.ngc"
SERVO = ROOT / "servo" / "paper-xy.yaml"
SERVO_XYZ = ROOT / "servo" / "example-xyz.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")
HANG_S = 2400  # only a hang catcher: a first run compiles the command's kernels, about a minute on 2 cores

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


#: the kernel modules (cache subdirectory, module) that `plan` of a YAML curve never calls: the servo, the contour
#: error, the pre-compensator, the look-ahead, the G-code scanner, the jerk-limited pass
NOT_PLAN = {("nurbsinterp", "contour"), ("nurbsinterp", "servo"), ("nurbsinterp", "simulation"),
            ("nurbsinterp", "precompensate"), ("nurbsinterp", "quantise"), ("planner", "jerk"), ("gcode", "fast")}


def cached_kernels(cache: Path) -> set[tuple[str, str, str]]:
    """(package directory, module, kernel) of every kernel numba saved in *cache* (its index files are named
    DIR_HASH/MODULE.KERNEL-LINE.pyXY.nbi)."""
    found = set()
    for index in cache.rglob("*.nbi"):
        module, _, kernel = index.name.partition(".")
        found.add((index.parent.name.rsplit("_", 1)[0], module, kernel.rsplit("-", 1)[0]))
    return found


@needs_exe
@pytest.mark.slow  # two commands compiled from an empty cache: minutes of a core (the quick set's compile is shared)
def test_a_first_run_compiles_only_what_the_command_calls_and_says_so(tmp_path):
    """A fresh cache: `plan` of the circle says it compiles the kernels `plan` needs, compiles those and no
    other command's (no servo, contour error, look-ahead), says how many in how long after its result; a second
    run loads them and says nothing; `simulate` then compiles its own and says so, `plan` still nothing."""
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))

    def run(*argv):
        return subprocess.run([str(EXE), *map(str, argv)], capture_output=True, env=env, timeout=HANG_S,
                              stdin=subprocess.DEVNULL)

    first = run("plan", CIRCLE, "-q", "-o", tmp_path / "c.csv")
    assert first.returncode == 0, first.stderr
    lines = first.stderr.decode().splitlines()
    assert len(lines) == 2, lines
    assert lines[0].startswith("nurbsinterp: compiling the numeric kernels `plan` needs, once"), lines
    assert "nurbsinterp warmup" in lines[0] and "kept if the run stops" in lines[0], lines
    assert re.fullmatch(r"nurbsinterp: \d+ kernel\(s\) compiled in \d+ s; later runs load them", lines[1]), lines
    compiled = cached_kernels(cache)
    assert ("nurbsinterp", "interpolate", "interpolate_chunk") in compiled
    assert not {k for k in compiled if k[:2] in NOT_PLAN}, sorted(k for k in compiled if k[:2] in NOT_PLAN)
    assert int(lines[1].split()[1]) <= len(compiled)  # each counted once, those it compiles inside it not at all

    again = run("plan", CIRCLE, "-q", "-o", tmp_path / "c2.csv")
    assert again.returncode == 0 and again.stderr == b"", again.stderr
    assert (tmp_path / "c2.csv").read_bytes() == (tmp_path / "c.csv").read_bytes()

    sim = run("simulate", "--plan", "--job", CIRCLE, "--json")
    assert sim.returncode == 0, sim.stderr
    assert sim.stderr.decode().startswith("nurbsinterp: compiling the numeric kernels `simulate` needs"), sim.stderr
    assert ("nurbsinterp", "contour", "contour_errors") in cached_kernels(cache)
    assert run("plan", CIRCLE, "-q", "-o", tmp_path / "c3.csv").stderr == b""
    assert_one_specialisation_each(cache)


#: after `nurbsinterp warmup`, every command and option family: none may compile a kernel
AFTER_WARMUP = {
    "info": ["info", CIRCLE, "--json"],
    "info adaptive": ["info", BUTTERFLY, "--profile", ADAPTIVE],
    "info adaptive, tight turns": ["info", CIRCLE, "--profile-type", "adaptive", "--chord-tolerance", "60"],
    "plan exact adaptive bin": ["plan", BUTTERFLY, "--profile", ADAPTIVE, "--interpolator", "exact", "--format", "bin",
                                "-o", "{tmp}/b.bin"],
    "plan rk4 bell after": ["plan", CIRCLE, "--interpolator", "rk4", "--profile-type", "bell", "--accdec", "after",
                            "-q", "-o", "{tmp}/c.csv"],
    "plan axes jerk": ["plan", "{tmp}/axes.yaml", "-q", "--max-jerk", "20000", "-o", "{tmp}/a.csv"],
    "plan hal resolution": ["plan", CIRCLE, "--format", "hal", "--resolution", "1um", "-q", "-o", "{tmp}/c.hal"],
    "plan G-code": ["plan", RASTER, "-q", "-o", "{tmp}/r.csv"],
    "plan --tolerance": ["plan", RASTER, "--tolerance", "5um", "-q", "-o", "{tmp}/r5.csv"],
    "plan --tolerance, one-segment windows": ["plan", RASTER, "--tolerance", "5mm", "-q", "-o", "{tmp}/r5mm.csv"],
    "plan --tolerance arcs": ["plan", POCKET, "--tolerance", "5um", "-q", "-o", "{tmp}/p5.csv"],
    "plan --tolerance jerk": ["plan", RASTER, "--tolerance", "5um", "--axis-max-jerk", "x=20000,y=20000,z=20000",
                              "-q", "-o", "{tmp}/rj.csv"],
    "plan --tolerance arcs jerk": ["plan", POCKET, "--tolerance", "5um", "--axis-max-jerk",
                                   "x=20000,y=20000,z=20000", "-q", "-o", "{tmp}/pj.csv"],
    "info --tolerance": ["info", RASTER, "--tolerance", "5um", "--json"],
    "simulate": ["simulate", "--plan", "--job", BUTTERFLY, "--json"],
    "simulate stream": ["simulate", "{tmp}/b.bin", "--job", BUTTERFLY, "--json"],
    "simulate --tolerance": ["simulate", "--plan", "--job", POCKET, "--tolerance", "5um", "--servo", SERVO_XYZ,
                             "--json"],
    "compare": ["compare", CIRCLE, "--json"],
    "compare --tolerance": ["compare", RASTER, "--tolerance", "5um", "--servo", SERVO_XYZ, "--json"],
    "precompensate": ["precompensate", "{tmp}/c.csv", "--servo", SERVO, "-o", "{tmp}/pre.csv"],
    "plan --precompensate": ["plan", CIRCLE, "--precompensate", SERVO, "-q", "-o", "{tmp}/cp.csv"],
}


def run_after_warmup(tmp_path: Path, case: str, env=None) -> None:
    """Run AFTER_WARMUP[case] (after the run that makes its input, where it reads one): it succeeds and says
    nothing of compiling."""
    axes = tmp_path / "axes.yaml"
    if not axes.exists():
        axes.write_text(BUTTERFLY.read_text().split("profile:")[0] + "profile:\n  type: adaptive\n  feedrate: 50\n"
                        "  max_accel: 2000\n  axes:\n    x: {max_velocity: 40, max_accel: 900}\n"
                        "    y: {max_velocity: 30, max_accel: 700}\n")
    needs = {"simulate stream": "plan exact adaptive bin", "precompensate": "plan rk4 bell after"}
    for step in ([needs[case]] if case in needs else []) + [case]:
        argv = [str(a).replace("{tmp}", str(tmp_path)) for a in AFTER_WARMUP[step]]
        res = subprocess.run([str(EXE), *argv], capture_output=True, timeout=HANG_S, stdin=subprocess.DEVNULL,
                             env=env)
        assert res.returncode == 0, (step, res.stderr)
        assert b"compiling" not in res.stderr, (step, res.stderr)


@needs_exe
@pytest.mark.parametrize("case", list(AFTER_WARMUP))
def test_after_warmup_no_command_compiles(tmp_path, case):
    """The suite's cache is warm (conftest runs the warm-up, as `nurbsinterp warmup` does): every command and
    option family loads its kernels; the safety net would say 'compiling kernel NAME for first use'."""
    run_after_warmup(tmp_path, case)


#: the kernel modules whose kernels may hold more than one specialisation, how many, and why
SEVERAL = {
    # the jerk-limited pass of the adaptive planner takes a constant cap as a broadcast view (read-only,
    # strided: materialised, it cost 250 bytes of peak memory per control point, tests/test_planner.py), the
    # look-ahead its own arrays, with per-interval jerk caps and a handover between windows: the two planners'
    # code paths, until issue 47 leaves one planner
    "planner/jerk": 4,
}


def specialisations(cache: Path) -> dict[str, list[str]]:
    """Every kernel numba saved in *cache*, with the signatures its index holds (one a compiled
    specialisation): read from the index files as numba reads them (a pickled version, then (stamp, overloads))."""
    import pickle

    found = {}
    for index in cache.rglob("*.nbi"):
        with open(index, "rb") as fh:
            pickle.load(fh)
            _stamp, overloads = pickle.loads(fh.read())
        module, _, kernel = index.name.partition(".")
        found[f"{index.parent.name.rsplit('_', 1)[0]}/{module}.{kernel.rsplit('-', 1)[0]}"] = \
            [str(key[0]) for key in overloads]
    return found


def assert_one_specialisation_each(cache: Path) -> None:
    """No copy of a kernel per constant argument (a literal), per omitted optional argument, per array layout or
    writability at a kernel's boundary: each would be a compilation of its own on a first run."""
    found = specialisations(cache)
    assert found, f"no kernels saved in {cache}"
    for kernel, sigs in found.items():
        assert not [s for s in sigs if "Literal" in s or "omitted" in s], (kernel, sigs)
        module = kernel.split(".", 1)[0]
        assert len(sigs) <= SEVERAL.get(module, 1), (kernel, sigs)


@needs_exe
@pytest.mark.slow
def test_warmup_in_an_empty_cache_compiles_one_specialisation_per_kernel_and_then_every_command_loads(tmp_path):
    """`nurbsinterp warmup` from an empty cache, as after `pip install`: every kernel of every command compiled
    once (one specialisation each), and every command and option family then compiles nothing."""
    cache = tmp_path / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    warm = subprocess.run([str(EXE), "warmup", "--json"], capture_output=True, env=env, timeout=HANG_S,
                          stdin=subprocess.DEVNULL)
    assert warm.returncode == 0, warm.stderr
    assert_one_specialisation_each(cache)
    for case in AFTER_WARMUP:
        run_after_warmup(tmp_path, case, env)


def interrupt(argv, after_s, sig=signal.SIGINT, env=None):
    proc = subprocess.Popen([str(EXE), *map(str, argv)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env=env)
    time.sleep(after_s)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=HANG_S)
    return proc.returncode, err.decode()


def interrupt_once_it_says(argv, prefix, sig, env=None, then_s=1.0):
    """Signal the run *then_s* after it has printed a line starting with *prefix* on stderr (not after a fixed time
    from its start: on a loaded machine its start may take longer than any such time); (status, stderr)."""
    proc = subprocess.Popen([str(EXE), *map(str, argv)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            stdin=subprocess.DEVNULL, env=env)
    seen = []
    for line in proc.stderr:  # blocks until the line comes (or the run ends: the assertions then say why)
        seen.append(line)
        if line.decode().startswith(prefix):
            time.sleep(then_s)
            proc.send_signal(sig)
            break
    rest = proc.stderr.read()
    proc.wait(timeout=HANG_S)
    return proc.returncode, (b"".join(seen) + rest).decode()


@needs_exe
@pytest.mark.parametrize("after_s", [0.02, 0.1, 0.25, 0.5, 0.8, 1.2])
def test_ctrl_c_at_any_moment_is_exit_130_and_one_line(tmp_path, after_s):
    """Wherever the signal lands — Python's start, click, numpy, numba's import, the kernel cache being
    loaded (llvmlite calls back into Python there), the run, the output file — the same end: 130, one line,
    no traceback and no file.  A run that finished before the signal came is fine too."""
    out = tmp_path / "c.csv"
    code, err = interrupt(["plan", CIRCLE, "--period", "10 us", "-o", out], after_s)
    if "KeyboardInterrupt" in err and PACKAGE not in err:
        return  # the interpreter's own start, before a line of ours runs: Python's message, as docs/job-file.md says
    if code == -signal.SIGINT and err == "":
        return  # earlier still: before Python installs its handler the signal ends it as any program (README)
    assert "Traceback" not in err and "Exception ignored" not in err, err
    if code == 0:
        return
    assert code == 130, err
    assert err.splitlines()[-1] == "nurbsinterp: interrupted", err
    assert err.count("\n") == 1, err
    assert not list(tmp_path.iterdir()), list(tmp_path.iterdir())


PYERR_PRINT = """\
import ctypes, signal
from nurbsinterp.cli import take_signals
take_signals()
# C code that runs Python and prints what it raises with PyErr_Print, as numpy's import_array does when the
# import it makes fails (it then raises "failed to import" of its own)
ctypes.pythonapi.PyRun_SimpleString(b"raise ValueError('not a signal')")
ctypes.pythonapi.PyRun_SimpleString(b"import os, signal; os.kill(os.getpid(), signal.SIGINT); signal.pause()")
signal.setitimer(signal.ITIMER_REAL, 0)
print("went on")
"""


def test_an_interrupt_that_an_extension_module_prints_says_nothing():
    """A SIGINT inside an extension module's import (numpy's import_array calls PyErr_Print on the way, then
    raises "failed to import", which main() reports as "interrupted"): no traceback of it on stderr.  Any other
    exception printed that way still shows, with its traceback."""
    res = subprocess.run([sys.executable, "-c", PYERR_PRINT], capture_output=True, text=True, timeout=HANG_S,
                         stdin=subprocess.DEVNULL)
    # (the status is not ours to check: PyRun_SimpleString marks the interrupt unhandled, and the interpreter
    # then ends by SIGINT at exit, as it does for an interrupt no code caught)
    assert res.stdout == "went on\n", res.stderr
    assert "ValueError: not a signal" in res.stderr
    assert "KeyboardInterrupt" not in res.stderr, res.stderr


@needs_exe
@pytest.mark.parametrize("sig, code, word", [
    # SIGINT's case also resumes the compile (a minute of a core): the slow set runs it, the quick set SIGTERM's
    pytest.param(signal.SIGINT, 130, "interrupted", marks=pytest.mark.slow),
    (signal.SIGTERM, 143, "terminated")])
def test_a_signal_while_compiling_ends_the_run(tmp_path, sig, code, word):
    """Inside numba's compiler an interrupt can be swallowed or turned into an error of numba's own: the run
    still ends with the signal's status, after the first-run notice (which says what was compiled is kept) and
    one line; and what it saved is whole: the next run loads it and compiles only the rest."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    status, err = interrupt_once_it_says(["plan", CIRCLE, "-o", tmp_path / "c.csv"],
                                         "nurbsinterp: compiling the numeric kernels", sig, env)
    lines = err.splitlines()
    assert status == code, err
    assert "Traceback" not in err and "internal error" not in err, err
    assert lines[0].startswith("nurbsinterp: compiling the numeric kernels `plan` needs"), err
    assert lines[-1] == f"nurbsinterp: {word}", err
    assert len(lines) == 2, err
    assert not (tmp_path / "c.csv").exists()
    if sig == signal.SIGINT:  # (once is enough: the resumed run compiles the rest, a minute on a loaded machine)
        saved = cached_kernels(tmp_path / "cache")
        again = subprocess.run([str(EXE), "plan", CIRCLE, "-q", "-o", tmp_path / "c.csv"], capture_output=True,
                               env=env, timeout=HANG_S, stdin=subprocess.DEVNULL)
        assert again.returncode == 0, again.stderr
        assert saved <= cached_kernels(tmp_path / "cache")
        warm = subprocess.run([str(EXE), "plan", CIRCLE, "-q", "-o", tmp_path / "warm.csv"], capture_output=True,
                              timeout=HANG_S, stdin=subprocess.DEVNULL)  # the suite's own (warm) cache
        assert warm.returncode == 0, warm.stderr
        assert (tmp_path / "c.csv").read_bytes() == (tmp_path / "warm.csv").read_bytes()
