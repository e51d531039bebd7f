"""How fast a G-code program reads: plain CAM lines by the fast path, against the general reader, in one run.

    .venv/bin/python benchmarks/read_gcode.py            # about a minute
    .venv/bin/python benchmarks/read_gcode.py --json

The plain program is ``../shared/corpus/cam_Sienci-Labs_gsender/MB-3.1_test.nc`` (150 k lines of
``G1 X-88.0758 Z-2.2982``, a surface finish from gSender's users) when the corpus is beside the
checkout, otherwise a generated program of the same shape and length (the output says which).
Each stage is measured in-process as CPU time (not wall: the machine's other work does not count),
the best of --runs after a warm call (the kernels compiled and loaded):

- ``scan``: the compiled scanner over the program's text (which lines are plain, their words' values);
- ``straight_run``: the moves of the plain lines from the table, as arrays (numpy over each run);
- ``read_gcode``: the whole read, file to path — the text decoded, scanned, the O-word index built,
  plain runs made moves and then blocks, one LineBlock a move — which must reach 200 000 blocks/s
  (issue 28: the planner after it aims at 20 000 blocks/s end to end);
- ``read_gcode(fast=False)``: every line by the general reader, for the ratio.

Then programs of expressions and O-words (a parametric pocket: a ``while`` loop of passes, each line
an expression of named parameters) at 1×, 2× and 4× the passes: the CPU time per executed line
must stay flat (reading is linear in the lines run).
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
from nurbsinterp.config.gcode.fast import scan, straight_run

ROOT = Path(__file__).resolve().parent.parent
MB31 = ROOT.parent / "shared" / "corpus" / "cam_Sienci-Labs_gsender" / "MB-3.1_test.nc"
LINES = 150_000
TARGET = 200_000  # blocks/s (issue 28, item 6)
PASSES = (500, 1000, 2000)  # the parametric program's passes: 10 executed lines each


def generated_program(path: Path, lines: int = LINES, seed: int = 0, flat: bool = False) -> Path:
    """A program of MB-3.1_test.nc's shape: G21 G90, a rapid, then G1 lines of X and Z (now and then Y);
    *flat*: X and Y only, as a laser's or a drag knife's program (read as a 2-D path)."""
    rng = np.random.default_rng(seed)
    out = ["G21", "G90", "G0 X-87.7758 Y-34.6641" + ("" if flat else " Z2.0"), "G1 F1200" if flat else
           "G1 Z-2.4609 F1200"]
    x, z = -87.7758, -2.4609
    for k in range(lines - 5):
        x -= 0.15
        z = float(np.clip(z + rng.normal(0, 0.1), -5, 0))
        if flat:
            out.append(f"G1 X{x:.4f} Y{z * 10:.4f}")
            continue
        out.append(f"G1 X{x:.4f} Z{z:.4f}" if k % 500 else f"G1 X{x:.4f} Y{rng.uniform(-40, 40):.4f} Z{z:.4f}")
    out.append("M30")
    path.write_text("\n".join(out) + "\n")
    return path


def parametric_program(path: Path, passes: int) -> Path:
    """A hand-written LinuxCNC pocket: a while loop of *passes* passes, each a rectangle of expressions."""
    path.write_text(f"""G21 G90 G64 P0.01
#<_w> = 40
#<_h> = 25
#<step> = [0.5 / {passes}]
#<depth> = 0
o100 sub
  G1 X[#1] Y[#2] F[600 + #3 * 0]
  G1 X[#1 + #<_w>] Y[#2]
  G1 X[#1 + #<_w>] Y[#2 + #<_h>]
  G1 X[#1] Y[#2 + #<_h>]
o100 endsub
G0 X0 Y0 Z1
#<pass> = 0
o200 while [#<pass> LT {passes}]
  #<depth> = [#<depth> - #<step>]
  G1 Z[#<depth>] F300
  o100 call [COS[#<pass>] * 0.5] [SIN[#<pass>] * 0.5] [#<pass>]
  #<pass> = [#<pass> + 1]
o200 endwhile
G0 Z5
M2
""")
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

    def recording(piece, first, last, state):
        given.append((piece, first, last, state))  # the table of the piece of the file the run was read from
        return straight_run(piece, first, last, state)

    from nurbsinterp.config.gcode import machine

    machine.straight_run = recording
    try:
        blocks = len(read_gcode(name).blocks)
    finally:
        machine.straight_run = straight_run

    def all_runs():
        for piece, first, last, state in given:
            fast.straight_run(piece, first, last, state)

    seconds = {
        "scan": best(lambda: scan(text), runs),
        "straight_run": best(all_runs, runs),
        "read_gcode": best(lambda: read_gcode(name), runs),
        "read_gcode(fast=False)": best(lambda: read_gcode(name, fast=False), runs),
    }
    return {"program": name, "lines": len(table), "plain_lines": int(table.plain.sum()), "blocks": blocks,
            "plain_runs": len(given), "runs": runs, "cpu_s": seconds, "target_blocks_per_s": TARGET}


def measure_parametric(folder: Path, runs: int) -> list[dict]:
    out = []
    for passes in PASSES:
        path = parametric_program(folder / f"pocket_{passes}.ngc", passes)
        # a pass: the while, 2 assignments, G1 Z, the call, the sub's 4 lines and its endsub, the endwhile
        executed = 11 * passes
        seconds = best(lambda: read_gcode(str(path)), runs)
        out.append({"passes": passes, "executed_lines": executed, "blocks": len(read_gcode(str(path)).blocks),
                    "cpu_s": seconds, "us_per_executed_line": seconds / executed * 1e6})
    return out


def markdown(result: dict, parametric: list[dict]) -> list[str]:
    seconds = result["cpu_s"]
    general = seconds["read_gcode(fast=False)"]
    lines = [f"| stage | CPU (s), best of {result['runs']} | µs a line | blocks/s | × the general reader |",
             "|---|---|---|---|---|"]
    for name, s in seconds.items():
        rate = result["blocks"] / s
        mark = f" (target ≥ {TARGET:,}: {'met' if rate >= TARGET else 'NOT met'})" if name == "read_gcode" else ""
        lines.append(f"| `{name}` | {s:.4f} | {s / result['lines'] * 1e6:.2f} | {rate:,.0f}{mark} | "
                     f"{general / s:.1f} |")
    lines += ["", "| parametric pocket (expressions, a sub, a while loop) | executed lines | blocks | CPU (s) | "
                  "µs an executed line |", "|---|---|---|---|---|"]
    for row in parametric:
        lines.append(f"| {row['passes']} passes | {row['executed_lines']:,} | {row['blocks']:,} | "
                     f"{row['cpu_s']:.3f} | {row['us_per_executed_line']:.1f} |")
    program = Path(result["program"]).name
    lines += ["", f"{program}: {result['lines']:,} lines, {result['plain_lines']:,} plain (read in "
                  f"{result['plain_runs']} runs), {result['blocks']:,} blocks."]
    if "flat" in result:
        flat = result["flat"]
        lines += [f"A flat program of the same length (X Y only, read as a 2-D path): "
                  f"`read_gcode` {flat['cpu_s']:.3f} s, {flat['blocks'] / flat['cpu_s']:,.0f} blocks/s."]
    return lines


def table(runs: int = 3) -> list[str]:
    """The README's table (docs/readme_tables.py --timing)."""
    import platform

    result = run(runs)
    return markdown(result, result["parametric"]) + ["", f"{platform.python_implementation()} "
                                                         f"{platform.python_version()}, CPU time of this process."]


def run(runs: int = 3) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        name = str(MB31) if MB31.is_file() else str(generated_program(Path(tmp) / "generated_mb31_shape.nc"))
        result = measure(name, runs)
        flat = str(generated_program(Path(tmp) / "flat.nc", flat=True))
        result["flat"] = {"lines": LINES, "blocks": len(read_gcode(flat).blocks),
                          "cpu_s": best(lambda: read_gcode(flat), runs)}
        result["parametric"] = measure_parametric(Path(tmp), runs)
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    result = run(args.runs)
    print(json.dumps(result, indent=2) if args.json else "\n".join(markdown(result, result["parametric"])))


if __name__ == "__main__":
    main()
