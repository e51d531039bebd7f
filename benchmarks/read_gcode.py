"""How fast a plain CAM program reads: the fast path for plain lines against today's reader, in one run.

    .venv/bin/python benchmarks/read_gcode.py            # about half a minute
    .venv/bin/python benchmarks/read_gcode.py --json

The program is ``../shared/corpus/cam_Sienci-Labs_gsender/MB-3.1_test.nc`` (150 k lines of
``G1 X-88.0758 Z-2.2982``, a surface finish from gSender's users) when the corpus is beside the
checkout, otherwise a generated program of the same shape and length (say which in the output).
Each stage is measured in-process as CPU time (not wall: the machine's other work does not count),
the best of --runs after a warm call (the kernels compiled and loaded):

- ``scan``: the compiled scanner over the program's text (which lines are plain, their words' values);
- ``straight_run``: the moves of the plain lines from the table, as arrays (numpy over each run);
- the whole read by the fast path (``fast.read_machine``: the file read and decoded, scanned, plain
  runs as arrays, the other lines by the general reader), which must reach 200 000 blocks/s;
- today's ``read_gcode`` (every line by the general reader, a LineBlock per move), for the ratio.
"""
from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from nurbsinterp.config.gcode import _read_text, read_gcode
from nurbsinterp.config.gcode import fast
from nurbsinterp.config.gcode.fast import Moves, read_machine, scan, straight_run

ROOT = Path(__file__).resolve().parent.parent
MB31 = ROOT.parent / "shared" / "corpus" / "cam_Sienci-Labs_gsender" / "MB-3.1_test.nc"
LINES = 150_000
TARGET = 200_000  # blocks/s (issue 28, item 6)


def generated_program(path: Path, lines: int = LINES, seed: int = 0) -> Path:
    """A program of MB-3.1_test.nc's shape: G21 G90, a rapid, then G1 lines of X and Z (now and then Y)."""
    rng = np.random.default_rng(seed)
    out = ["G21", "G90", "G0 X-87.7758 Y-34.6641 Z2.0", "G1 Z-2.4609 F1200"]
    x, z = -87.7758, -2.4609
    for k in range(lines - 5):
        x -= 0.15
        z = float(np.clip(z + rng.normal(0, 0.1), -5, 0))
        out.append(f"G1 X{x:.4f} Z{z:.4f}" if k % 500 else f"G1 X{x:.4f} Y{rng.uniform(-40, 40):.4f} Z{z:.4f}")
    out.append("M30")
    path.write_text("\n".join(out) + "\n")
    return path


def best(call, runs: int) -> float:
    call()  # warm: compiled kernels loaded, the file in the page cache
    times = []
    for _ in range(runs):
        t0 = time.process_time()
        call()
        times.append(time.process_time() - t0)
    return min(times)


def measure(name: str, runs: int) -> dict:
    text = _read_text(name)
    table = scan(text)
    # the runs and the modes each starts from, as the reader's loop gives them (recorded once, outside the timing)
    given = []

    def recording(table, first, last, state):
        given.append((first, last, state))
        return straight_run(table, first, last, state)

    fast.straight_run = recording
    try:
        machine = read_machine(name, text)
    finally:
        fast.straight_run = straight_run
    blocks = sum(len(b) if isinstance(b, Moves) else 1 for b in machine.blocks)

    def all_runs():
        for first, last, state in given:
            straight_run(table, first, last, state)

    seconds = {
        "scan": best(lambda: scan(text), runs),
        "straight_run": best(all_runs, runs),
        "fast path (read_machine)": best(lambda: read_machine(name, _read_text(name)), runs),
        "read_gcode (today)": best(lambda: read_gcode(name), runs),
    }
    return {"program": name, "lines": len(table), "plain_lines": int(table.plain.sum()), "blocks": blocks,
            "plain_runs": len(given), "runs": runs, "cpu_s": seconds, "target_blocks_per_s": TARGET}


def markdown(result: dict) -> list[str]:
    seconds = result["cpu_s"]
    today = seconds["read_gcode (today)"]
    lines = [f"{result['program']}: {result['lines']} lines, {result['plain_lines']} plain, "
             f"{result['plain_runs']} calls of straight_run, {result['blocks']} blocks", "",
             f"| stage | CPU (s), best of {result['runs']} | µs a line | blocks/s | × faster than read_gcode |",
             "|---|---|---|---|---|"]
    for name, s in seconds.items():
        rate = result["blocks"] / s
        mark = ""
        if name.startswith("fast path"):
            mark = f" (target ≥ {result['target_blocks_per_s']:,}: {'✓' if rate >= TARGET else '✗'})"
        lines.append(f"| {name} | {s:.4f} | {s / result['lines'] * 1e6:.2f} | {rate:,.0f}{mark} | "
                     f"{today / s:.1f} |")
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        name = str(MB31) if MB31.is_file() else str(generated_program(Path(tmp) / "generated_mb31_shape.nc"))
        result = measure(name, args.runs)
    print(json.dumps(result, indent=2) if args.json else "\n".join(markdown(result)))


if __name__ == "__main__":
    main()
