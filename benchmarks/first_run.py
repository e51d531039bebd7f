"""What a command's first run of a version costs: the kernels it compiles, and how long it takes (a benchmark).

    .venv/bin/python benchmarks/first_run.py              # about 10 minutes on 2 cores
    .venv/bin/python benchmarks/first_run.py --json
    .venv/bin/python benchmarks/first_run.py --write      # also src/nurbsinterp/data/first_run.json

Each command runs in a cache of its own, empty, as on the first run after `pip install` (NUMBA_CACHE_DIR set to
a fresh directory; the package's modules are loaded from the install, not compiled): its wall time, its CPU time
(this process and the warm-up's workers), and from numba's compile events in that process the package's kernels
compiled (the count a user is shown; each a specialisation: one per kernel, tests/test_startup.py) and numba's
own implementations of numpy functions compiled alongside.  Last, `nurbsinterp warmup` from an empty cache, every kernel
of every command on every core.

--write stores each command's count and wall time where the CLI reads them (warmup.first_run_estimate): the
estimate a first run shows while it compiles ("about N kernels, S s on a quiet 2-core machine").  README's table
"First run" is this script's output (docs/readme_tables.py --only first-run).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
CURVES = ROOT / "curves"
JSON_OUT = ROOT / "src" / "nurbsinterp" / "data" / "first_run.json"
JERK = "x=20000,y=20000,z=20000"

#: (the estimate's key, as ensure_kernels names the command; the command as README shows it; its arguments)
COMMANDS = (
    ("plan", "plan curves/circle.yaml -o circle.csv", ["plan", CURVES / "circle.yaml", "-o", "{tmp}/out.csv"]),
    ("info", "info curves/circle.yaml", ["info", CURVES / "circle.yaml"]),
    ("plan --tolerance", "plan curves/raster.ngc -o raster.csv",  # a program, on the exact path: the look-ahead
     ["plan", CURVES / "raster.ngc", "-o", "{tmp}/out.csv"]),
    ("plan --tolerance", "plan curves/raster.ngc --tolerance 5um",
     ["plan", CURVES / "raster.ngc", "--tolerance", "5um", "-o", "{tmp}/out.csv"]),
    ("plan --tolerance", f"plan curves/pocket.ngc --tolerance 5um --axis-max-jerk {JERK}",
     ["plan", CURVES / "pocket.ngc", "--tolerance", "5um", "--axis-max-jerk", JERK, "-o", "{tmp}/out.csv"]),
    ("info --tolerance", "info curves/raster.ngc --tolerance 5um",
     ["info", CURVES / "raster.ngc", "--tolerance", "5um"]),
    ("simulate", "simulate --plan --job curves/circle.yaml", ["simulate", "--plan", "--job", CURVES / "circle.yaml"]),
    ("simulate --tolerance", "simulate --plan --job curves/raster.ngc --tolerance 5um --servo servo/example-xyz.yaml",
     ["simulate", "--plan", "--job", CURVES / "raster.ngc", "--tolerance", "5um", "--servo",
      ROOT / "servo" / "example-xyz.yaml"]),
    ("compare", "compare curves/circle.yaml", ["compare", CURVES / "circle.yaml"]),
)

#: run in the measured process: numba's compile events counted, the CLI then run as the console script runs it
PROBE = """
import json, sys, time
from numba.core import event
counts = {"ours": 0, "numba": 0}
class Listener(event.Listener):
    def on_start(self, ev):
        mod = getattr(ev.data["dispatcher"].py_func, "__module__", "") or ""
        counts["ours" if mod.startswith("nurbsinterp") else "numba"] += 1
    def on_end(self, ev):
        pass
event.register("numba:compile", Listener())
from nurbsinterp.cli import main
try:
    main(sys.argv[2:])
except SystemExit as exc:
    code = exc.code
with open(sys.argv[1], "w") as fh:
    json.dump(counts, fh)
sys.exit(code)
"""


def _cpu_children() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def first_run(argv, tmp: Path) -> dict:
    """One command in an empty cache: its wall and CPU time and its compile counts."""
    cache = tmp / "cache"
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    counts = tmp / "counts.json"
    args = [str(a).replace("{tmp}", str(tmp)) for a in argv]
    cpu0, t0 = _cpu_children(), time.perf_counter()
    subprocess.run([sys.executable, "-c", PROBE, str(counts), *args], env=env, check=True, stdin=subprocess.DEVNULL,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    found = json.loads(counts.read_text())
    return {"wall_s": wall, "cpu_s": _cpu_children() - cpu0, "kernels": found["ours"],
            "numba_overloads": found["numba"]}


def warmup_run(tmp: Path) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp / "cache"))
    exe = Path(sys.executable).with_name("nurbsinterp")
    cpu0, t0 = _cpu_children(), time.perf_counter()
    out = subprocess.run([str(exe), "warmup", "--json"], env=env, check=True, capture_output=True,
                         stdin=subprocess.DEVNULL).stdout
    return {"wall_s": time.perf_counter() - t0, "cpu_s": _cpu_children() - cpu0,
            "kernels": json.loads(out)["kernels_compiled"]}


def measure() -> dict:
    rows = []
    for key, shown, argv in COMMANDS:
        with tempfile.TemporaryDirectory() as tmp:
            rows.append({"key": key, "command": shown, **first_run(argv, Path(tmp))})
        print(f"{shown}: {rows[-1]['wall_s']:.0f} s", file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp:
        warm = warmup_run(Path(tmp))
    return {"date": time.strftime("%Y-%m-%d"), "cores": os.cpu_count(), "commands": rows, "warmup": warm}


def markdown(result: dict) -> list[str]:
    out = ["| first run, empty cache | wall (s) | CPU (s) | kernels compiled | and numba's own |",
           "|---|---|---|---|---|"]
    for r in result["commands"]:
        out.append(f"| `nurbsinterp {r['command']}` | {r['wall_s']:.0f} | {r['cpu_s']:.0f} | {r['kernels']} | "
                   f"{r['numba_overloads']} |")
    w = result["warmup"]
    out.append(f"| `nurbsinterp warmup` (every command's, {result['cores']} processes) | {w['wall_s']:.0f} | "
               f"{w['cpu_s']:.0f} | {w['kernels']} | |")
    out.append("")
    out.append(f"Measured {result['date']} on {result['cores']} cores (`benchmarks/first_run.py`).")
    return out


def estimates(result: dict) -> dict:
    """The CLI's table: each command's kernels and wall time (the larger where two rows share a key)."""
    table = {}
    for r in result["commands"]:
        old = table.get(r["key"], {"kernels": 0, "seconds": 0.0})
        table[r["key"]] = {"kernels": max(old["kernels"], r["kernels"]),
                           "seconds": round(max(old["seconds"], r["wall_s"]))}
    return {"measured": result["date"], "commands": table}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--write", action="store_true", help="write the CLI's estimates (data/first_run.json)")
    args = parser.parse_args()
    result = measure()
    if args.write:
        JSON_OUT.write_text(json.dumps(estimates(result), indent=1) + "\n")
    print(json.dumps(result, indent=1) if args.json else "\n".join(markdown(result)))


if __name__ == "__main__":
    main()
