"""Throughput, as issue 16 measures it: CPU time per extra tick and ratios measured in the same run.

    .venv/bin/python benchmarks/throughput.py            # a few minutes: idle, then with the other core busy
    .venv/bin/python benchmarks/throughput.py --quick    # smaller jobs, idle only (a smoke test)

Every end-to-end figure is the CPU time (user + system, the process and its
threads) of a long job minus that of a short one, divided by the ticks between
them, so that start-up cancels; the wall time of the long job, start-up
included, stands beside it.  The jobs are the paper's circle at 100 mm/s,
Ta = 0.5 s, at T = 1 µs (3.64 M ticks) and at T = 1 ms (3 643 ticks).  The
kernels are timed in-process, the fastest of three passes.  Each measure runs
twice: with the other core idle, and with a busy loop on it (a loaded 2-core
machine).  Ratios within a column are what to read; absolute times move with
the machine and its load.
"""
from __future__ import annotations

import argparse
import math
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import c_reference  # noqa: E402  (benchmarks/run.py)

ROOT = Path(__file__).resolve().parent.parent
EXE = Path(sys.executable).with_name("nurbsinterp")
CIRCLE_JOB = """curve:
  degree: 2
  control_points: [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]]
  weights: [1, 0.5, 0.5, 1, 0.5, 0.5, 1]
  knots: [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]
profile: {{type: trapezoidal, feedrate: 100, accel_time: 0.5}}
interpolator: {{method: taylor2, period: {period}}}
"""


def _cpu_children() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(cmd: str) -> tuple[float, float]:
    """(CPU s, wall s) of a shell command line, every process of it counted."""
    c0, t0 = _cpu_children(), time.perf_counter()
    proc = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    wall, cpu = time.perf_counter() - t0, _cpu_children() - c0
    if proc.returncode:
        raise RuntimeError(f"{cmd} failed: {proc.stderr.decode()[-400:]}")
    return cpu, wall


def per_tick(cmd: str, long_job: Path, short_job: Path, ticks: tuple[int, int], repeats: int = 2):
    """(CPU ns per extra tick, wall s of the long run): the fastest of *repeats*."""
    best_cpu, best_wall = math.inf, math.inf
    for _ in range(repeats):
        cl, wl = timed(cmd.format(job=long_job))
        cs, _ = timed(cmd.format(job=short_job))
        best_cpu = min(best_cpu, (cl - cs) / (ticks[0] - ticks[1]) * 1e9)
        best_wall = min(best_wall, wl)
    return best_cpu, best_wall


def kernels(job: Path) -> dict[str, float]:
    """ns per tick of the tick loop (interpolate_chunk) for taylor2 and exact, the fastest of three passes."""
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.interpolate import METHODS, Interpolation, interpolate_chunk

    out = {}
    for method in ("taylor2", "exact"):
        run = Interpolation(load_cli(str(job), overrides={"interpolator": method}))
        n = run.last_tick + 1
        best = math.inf
        for _ in range(3):
            state = run.new_state()
            us, pts, plan = np.empty(n), np.empty((n, run.curve.dim)), np.empty((n, 3))
            t0 = time.process_time()
            interpolate_chunk(METHODS[method], run.geometry, run.profile.params, run.period, run.sigma_min, 0,
                              run.last_tick, state, us, pts, plan, np.empty((0, 2, run.curve.dim)))
            best = min(best, time.process_time() - t0)
        out[method] = best / n * 1e9
    return out


NUMPY_WRITER = """import sys, numpy as np
head, _, body = open(sys.argv[1], "rb").read().partition(b"\\n")
data = np.frombuffer(body[:-64], "<f8").reshape(-1, len(head.split()[2].split(b",")))  # the end mark left out
out = sys.stdout.buffer
out.write(head + b"\\n")
for i in range(0, data.shape[0], 1 << 16):
    out.write(data[i:i + (1 << 16)].tobytes())
"""


def measure(tmp: Path, quick: bool) -> list[tuple[str, str]]:
    """[(measure, result)] for one machine state."""
    long_period = "10 us" if quick else "1 us"
    long_job, short_job = tmp / "long.yaml", tmp / "short.yaml"
    long_job.write_text(CIRCLE_JOB.format(period=long_period))
    short_job.write_text(CIRCLE_JOB.format(period="1 ms"))
    ticks = (int(round(3.641592653589793 / (1e-5 if quick else 1e-6))) + 1, 3643)
    exe = str(EXE)
    rows = []

    k = kernels(long_job)
    c_ns = c_reference(tmp)  # benchmarks/taylor2_ref.c, gcc -O2 (run.py's)
    rows.append(("taylor2 tick loop (in-process)", f"{k['taylor2']:.0f} ns"
                 + (f"; {k['taylor2'] / c_ns:.2f}x the C loop ({c_ns:.0f} ns)" if c_ns else "")))
    rows.append(("exact tick loop vs taylor2", f"{k['exact']:.0f} ns; {k['exact'] / k['taylor2']:.2f}x taylor2"))

    q_cpu, q_wall = per_tick(f"{exe} plan {{job}} --format bin -q -o /dev/null", long_job, short_job, ticks)
    rows.append((f"plan --format bin -q", f"{1e3 / q_cpu:.2f} M ticks/s CPU ({q_cpu:.0f} ns/tick); "
                 f"{ticks[0] / q_wall / 1e6:.2f} M ticks/s wall with start-up"))
    s_cpu, s_wall = per_tick(f"{exe} plan {{job}} --format bin -o /dev/null", long_job, short_job, ticks)
    rows.append((f"plan --format bin, with the summary", f"{1e3 / s_cpu:.2f} M ticks/s CPU, {s_cpu / q_cpu:.2f}x -q; "
                 f"wall {s_wall / q_wall:.2f}x -q (the measures on the second core)"))
    c_cpu, c_wall = per_tick(f"{exe} plan {{job}} --format csv -q -o /dev/null", long_job, short_job, ticks)
    rows.append((f"plan --format csv -q", f"{1e3 / c_cpu:.2f} M ticks/s CPU ({c_cpu:.0f} ns/tick); "
                 f"{ticks[0] / c_wall / 1e6:.2f} M ticks/s wall"))
    e_cpu, _ = per_tick(f"{exe} plan {{job}} --format bin -q --interpolator exact -o /dev/null", long_job,
                        short_job, ticks)
    rows.append((f"plan --format bin -q --interpolator exact", f"{1e3 / e_cpu:.2f} M ticks/s CPU, "
                 f"{e_cpu / q_cpu:.2f}x taylor2"))

    # into the same pipe: plan itself against numpy writing the same bytes from memory
    long_bin = tmp / "long.bin"
    timed(f"{exe} plan {long_job} --format bin -q -o {long_bin}")
    writer = tmp / "numpy_writer.py"
    writer.write_text(NUMPY_WRITER)
    _, plan_pipe = timed(f"{exe} plan {long_job} --format bin -q | cat > /dev/null")
    _, numpy_pipe = timed(f"{sys.executable} {writer} {long_bin} | cat > /dev/null")
    rows.append(("plan -q \\| cat, against numpy writing the same bytes into the same pipe",
                 f"{plan_pipe:.2f} s vs {numpy_pipe:.2f} s wall, both with start-up ({plan_pipe / numpy_pipe:.2f}x)"))

    short_bin = tmp / "short.bin"
    timed(f"{exe} plan {short_job} --format bin -q -o {short_bin}")
    sim_cpu = math.inf
    sim_wall = math.inf
    for _ in range(2):
        cl, wl = timed(f"{exe} simulate {long_bin} --job {long_job} --json")
        cs, _ = timed(f"{exe} simulate {short_bin} --job {short_job} --json")
        sim_cpu = min(sim_cpu, (cl - cs) / (ticks[0] - ticks[1]) * 1e9)
        sim_wall = min(sim_wall, wl)
    rows.append(("simulate (binary stream)", f"{1e3 / sim_cpu:.2f} M ticks/s CPU ({sim_cpu:.0f} ns/tick); "
                 f"{ticks[0] / sim_wall / 1e6:.2f} M ticks/s wall with start-up"))
    return rows


class BusyCore:
    """A busy loop on the other core while the block runs."""

    def __enter__(self):
        self.proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        return self

    def __exit__(self, *exc):
        self.proc.kill()
        self.proc.wait()


def markdown(idle: list, loaded: list | None) -> list[str]:
    if loaded is None:
        out = ["| measure | other core idle |", "|---|---|"]
        out += [f"| {name} | {value} |" for name, value in idle]
    else:
        out = ["| measure | other core idle | other core busy |", "|---|---|---|"]
        out += [f"| {name} | {value} | {busy} |" for (name, value), (_, busy) in zip(idle, loaded)]
    from nurbsinterp.bench import machine

    m = machine()
    out.append(f"\n{m.cpu}, {m.cores} cores, Python {m.python}; circle at T = 1 µs (3.64 M ticks) minus "
               "T = 1 ms, CPU time of every process and thread.")
    return out


def run(quick: bool = False, loaded: bool = True) -> list[str]:
    if not EXE.exists():
        raise SystemExit(f"{EXE} is missing: pip install -e . first")
    subprocess.run([str(EXE), "warmup"], check=True, stderr=subprocess.DEVNULL)
    with tempfile.TemporaryDirectory() as tmp:
        idle = measure(Path(tmp), quick)
        busy = None
        if loaded:
            with BusyCore():
                busy = measure(Path(tmp), quick)
    return markdown(idle, busy)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="T = 10 us instead of 1 us, idle only")
    args = parser.parse_args()
    print("\n".join(run(args.quick, loaded=not args.quick)))


if __name__ == "__main__":
    os.environ.setdefault("PYTHONHASHSEED", "0")
    main()
