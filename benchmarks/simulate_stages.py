"""Where `simulate`'s time goes, stage by stage, in CPU time per tick (a benchmark, never a test).

    .venv/bin/python benchmarks/simulate_stages.py                  # the circle at 1 us: 3.8 M ticks, ~30 s
    .venv/bin/python benchmarks/simulate_stages.py --period "10 us"
    .venv/bin/python benchmarks/simulate_stages.py --cli            # and `nurbsinterp simulate` end to end

The paper's circle is planned into a binary stream (`plan --format bin -q`); then, in this process
and in CPU time (time.process_time: every thread of the process, so a thread pool spinning on the
other core is counted, and the other agents' load on the machine is not), each stage runs alone over
the whole stream, chunk by chunk as `simulate` runs it -- the best of --runs:

  read      streams.read_stream: the bytes into float64 rows, with the reader's checks
  check     simulation.check_chunk: period, blocks, domain and range, and the columns gathered
  servo     the closed loop (servo.ClosedLoop.run)
  contour   the contour error (contour.contour_errors: Newton, the convexity certificate, the
            window search where the certificate fails; the count of searched ticks is printed)
  measures  contour.chunk_measures: the maxima and sums of squares of every error, the feedrate
  simulate  simulation.simulate on the stream read from the file: all of the above and the glue, per
            extra tick over a short stream (the same circle at 1 ms): the fixed costs cancel

With --cli, `nurbsinterp simulate STREAM --job JOB --json` also runs as a subprocess on the long
stream and on a short one (the same circle at 1 ms), and the CPU time per extra tick is the
difference of the two runs' CPU times over the difference of their ticks: start-up cancels.  The
target of issue 16 is 3 M ticks/s, the contour error at most 150 ns/tick.
"""
from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
EXE = Path(sys.executable).with_name("nurbsinterp")
CIRCLE = ROOT / "curves" / "circle.yaml"


def plan(period: str, out: Path) -> None:
    subprocess.run([str(EXE), "plan", str(CIRCLE), "--period", period, "--format", "bin", "-q", "-o", str(out)],
                   check=True)


def cpu(fn, runs: int) -> float:
    """The least CPU time (s) of *runs* calls of fn."""
    best = float("inf")
    for _ in range(runs):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def stages(stream: Path, short: Path, runs: int) -> tuple[dict, int, int]:
    """{stage: CPU s} over the whole stream, its tick count, and the ticks the contour error searched.

    simulate's time is per extra tick over the *short* stream's, scaled to the stream's ticks.
    """
    from nurbsinterp.cli.common import load
    from nurbsinterp.contour import CARRY, PathWindow, chunk_measures, contour_errors
    from nurbsinterp.path import job_path
    from nurbsinterp.servo import PAPER_TABLE, ClosedLoop, discretise
    from nurbsinterp.simulation import _CHECKS, check_chunk, simulate
    from nurbsinterp.streams import read_stream

    spec = load(str(CIRCLE))
    path = job_path(spec)
    curve = path.programmed

    def read(keep=False):
        with open(stream, "rb") as fh:
            columns, chunks = read_stream(fh, str(stream))
            kept = [c for c in chunks if keep]  # dropped as read, as simulate drops them (no fresh pages)
        return columns, kept

    columns, chunks = read(keep=True)
    ticks = sum(c.shape[0] for c in chunks)
    axes = ["x", "y"]
    t_col, u_col, v_col, n_col = (columns.index(c) for c in ("t", "u", "v", "n"))
    ax_cols = np.array([columns.index(a) for a in axes])
    period = float(chunks[0][1, t_col] - chunks[0][0, t_col])
    a, b = curve.domain
    shifts = np.asarray(path.shifts, dtype=float)
    # every stage's inputs and outputs, allocated (and their pages touched) before any stage is timed:
    # each stage then times only its own work, as simulate's loop does with its reused buffers
    sizes = [c.shape[0] for c in chunks]
    gathered = [(c[:, t_col], np.zeros(m), np.zeros((m, 2)), np.zeros(m)) for c, m in zip(chunks, sizes)]
    servo_out = [tuple(np.zeros((m, 2)) for _ in range(3)) for m in sizes]
    contour_out = [(np.zeros(m), np.zeros(m)) for m in sizes]
    speeds = [np.zeros(m) for m in sizes]
    bad = np.empty(_CHECKS, dtype=np.int64)

    def check():
        tick = 0
        for data, (_t, u, cmd, v) in zip(chunks, gathered):
            check_chunk(data, t_col, u_col, n_col, v_col, ax_cols, chunks[0][0, t_col], period, tick, 1, shifts,
                        a, b, 1e6, u, cmd, v, bad)
            tick += data.shape[0]

    def servo():
        loop = ClosedLoop(discretise(PAPER_TABLE, period, axes))
        for (_t, _u, cmd, _v), out in zip(gathered, servo_out):
            loop.run(cmd, out=out)

    searched = 0

    def contour():
        nonlocal searched
        window = PathWindow(curve)
        carry = np.full(CARRY, np.nan)
        U, B, p, n = curve.kernel_args
        searched = 0
        for (_t, u, _cmd, _v), (act, _vel, _volt), (out_u, err) in zip(gathered, servo_out, contour_out):
            searched += contour_errors(U, B, p, n, *curve.panels, window._cert, act, u, carry, window.closed,
                                       out_u, err)

    def measures():
        at, sumsq = np.zeros(4, dtype=np.int64), np.zeros(4)
        for (_t, _u, cmd, v), (act, vel, _volt), (_out_u, err), speed in zip(gathered, servo_out, contour_out,
                                                                              speeds):
            chunk_measures(err, cmd, act, vel, v, speed, at, sumsq)

    def whole(which=stream):
        with open(which, "rb") as fh:
            columns, chunks = read_stream(fh, str(which))
            return simulate(path, PAPER_TABLE, columns, chunks, name=str(which))[0].ticks

    check()
    servo()
    times = {"read": cpu(read, runs), "check": cpu(check, runs), "servo": cpu(servo, runs),
             "contour": cpu(contour, runs), "measures": cpu(measures, runs)}
    # simulate per extra tick: the long stream less the short one (the same circle at 1 ms), whose
    # difference cancels the fixed costs (the servo's discretisation, the tables, the settle hold)
    simulated = whole(stream) - whole(short)
    times["simulate"] = (cpu(whole, runs) - cpu(lambda: whole(short), runs)) * ticks / simulated
    return times, ticks, searched


def cli_rate(long: Path, short: Path, runs: int) -> tuple[float, float]:
    """(CPU ns per extra tick, wall s of the long run) of `nurbsinterp simulate`, the best of *runs*."""
    def run(stream: Path, period: str):
        job = Path(tempfile.gettempdir()) / f"simulate-stages-{period.replace(' ', '')}.yaml"
        job.write_text(CIRCLE.read_text().replace("period: 1 ms", f"period: {period}"))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t = time.perf_counter()
        done = subprocess.run([str(EXE), "simulate", str(stream), "--job", str(job), "--json"], check=True,
                              capture_output=True)
        wall = time.perf_counter() - t
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        used = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        return used, wall, json.loads(done.stdout)["ticks"]

    best = (float("inf"), 0.0)
    for _ in range(runs):
        cl, wl, nl = run(long, ARGS.period)
        cs, _ws, ns = run(short, "1 ms")
        best = min(best, ((cl - cs) / (nl - ns) * 1e9, wl))
    return best


def main() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        long, short = Path(tmp) / "long.bin", Path(tmp) / "short.bin"
        plan(ARGS.period, long)
        plan("1 ms", short)
        times, ticks, searched = stages(long, short, ARGS.runs)
        print(f"simulate stages, the circle at {ARGS.period}: {ticks} stream ticks, CPU time, best of {ARGS.runs}")
        parts = 0.0
        for name, seconds in times.items():
            per = seconds / ticks * 1e9
            if name != "simulate":
                parts += seconds
            note = f"   ({searched} ticks searched)" if name == "contour" else ""
            print(f"  {name:9s} {per:7.1f} ns/tick{note}")
        glue = times["simulate"] - parts
        print(f"  {'glue':9s} {glue / ticks * 1e9:7.1f} ns/tick   (simulate less the stages: Python per chunk, "
              "the hold)")
        print(f"  simulate in-process, per extra tick: {ticks / times['simulate'] / 1e6:.2f} M ticks/s")
        if ARGS.cli:
            per, wall = cli_rate(long, short, ARGS.runs)
            print(f"  nurbsinterp simulate, CPU per extra tick: {per:.1f} ns = {1e3 / per:.2f} M ticks/s "
                  f"(wall of the long run {wall:.2f} s)")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--period", default="1 us", help="the sampling period of the long stream (default 1 us)")
    parser.add_argument("--runs", type=int, default=3, help="the best of this many runs (default 3)")
    parser.add_argument("--cli", action="store_true", help="also time `nurbsinterp simulate` end to end")
    ARGS = parser.parse_args()
    main()
