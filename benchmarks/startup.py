"""How long a command takes to start, against Python itself and numpy, in one run on one machine.

    .venv/bin/python benchmarks/startup.py            # about half a minute
    .venv/bin/python benchmarks/startup.py --json

A user runs nurbsinterp in shell loops, so start-up counts.  Each command is run
--runs times (warm: the kernels are compiled and cached first) and the fastest
wall time is kept (the others measure the machine's other work, not ours); the
result is given as a ratio to `python -c pass` and to `python -c "import numpy"`
measured in the same run.  The numba rows split the floor that numba sets for
every command that computes: importing it, and the first call of a cached
kernel (numba builds its typing and target registries then, importing
numba.np and scipy.linalg, before it can load the cached machine code).
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXE = Path(sys.executable).with_name("nurbsinterp")
CIRCLE = ROOT / "curves" / "circle.yaml"
PY = sys.executable

FIRST_KERNEL_CALL = ("import time, numpy as np; from nurbsinterp.nurbs import find_span; "
                     "U = np.array([0., 0, 1, 1]); t = time.perf_counter(); find_span(U, 1, 1, 0.5); "
                     "print(time.perf_counter() - t)")

#: name -> (command, target in s or None)
COMMANDS = {
    "python -c pass": ([PY, "-c", "pass"], None),
    'python -c "import numpy"': ([PY, "-c", "import numpy"], None),
    'python -c "import numba"': ([PY, "-c", "import numba"], None),
    "nurbsinterp --version": ([EXE, "--version"], 0.15),
    "nurbsinterp --help": ([EXE, "--help"], None),
    "nurbsinterp info curves/circle.yaml": ([EXE, "info", CIRCLE], 0.6),
    "nurbsinterp plan curves/circle.yaml -o /dev/null": ([EXE, "plan", CIRCLE, "-o", os.devnull], 0.7),
}


def wall(cmd) -> float:
    t0 = time.perf_counter()
    subprocess.run([str(c) for c in cmd], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
    return time.perf_counter() - t0


def measure(runs: int) -> dict:
    subprocess.run([str(EXE), "warmup"], stdout=subprocess.DEVNULL, check=True)  # the cached case a user sees
    best = {name: min(wall(cmd) for _ in range(runs)) for name, (cmd, _) in COMMANDS.items()}
    first_call = min(float(subprocess.run([PY, "-c", FIRST_KERNEL_CALL], capture_output=True, text=True,
                                          check=True).stdout) for _ in range(runs))
    return {"runs": runs, "best_s": best, "first_cached_kernel_call_s": first_call,
            "targets_s": {name: target for name, (_, target) in COMMANDS.items() if target is not None}}


def markdown(result: dict) -> list[str]:
    best = result["best_s"]
    base, numpy = best["python -c pass"], best['python -c "import numpy"']
    lines = ["| command | wall (s), best of %d | × `python -c pass` | × `import numpy` | target |" % result["runs"],
             "|---|---|---|---|---|"]
    for name, seconds in best.items():
        target = result["targets_s"].get(name)
        lines.append(f"| `{name}` | {seconds:.3f} | {seconds / base:.1f} | {seconds / numpy:.2f} | "
                     + ("" if target is None else f"≤ {target:g} s" + (" ✓" if seconds <= target else " ✗")) + " |")
    lines.append(f"| first call of a cached kernel (numba's registries) | {result['first_cached_kernel_call_s']:.3f} "
                 "| | | |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = measure(args.runs)
    print(json.dumps(result, indent=2) if args.json else "\n".join(markdown(result)))


if __name__ == "__main__":
    main()
