"""nurbsinterp against its peers and the limit, in one run on one machine.

    .venv/bin/python benchmarks/run.py            # about two minutes
    .venv/bin/python benchmarks/run.py --quick    # smaller jobs, for a smoke test

Measures (and prints as one table):
  1. one taylor2 tick on the paper's circle: nurbsinterp's compiled kernel (timed per tick,
     `nurbsinterp bench`) against the loop a user would otherwise write — per tick, a general
     NURBS library's derivative routine (geomdl) and Eq. 9 in Python — and against the same
     tick in plain C (benchmarks/taylor2_ref.c, compiled here with gcc -O2: the speed of light);
  2. end-to-end `nurbsinterp plan` throughput (process wall time, start-up included) with
     --format bin and csv on a long job, against numpy.savetxt writing the same rows;
  3. peak memory (max RSS) of a 10-million-tick `plan` beside a tiny one, and of `simulate`
     on a long stream;
  4. `simulate` throughput.
Needs the test extra (geomdl) and gcc; a missing one is reported and its rows skipped.
"""
from __future__ import annotations

import argparse
import dataclasses
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
EXE = Path(sys.executable).with_name("nurbsinterp")
CIRCLE = ROOT / "curves" / "circle.yaml"

LONG_JOB = """curve:
  degree: 2
  control_points: [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]]
  weights: [1, 0.5, 0.5, 1, 0.5, 0.5, 1]
  knots: [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]
profile: {{type: trapezoidal, feedrate: {feed}, accel_time: 0.5}}
interpolator: {{method: taylor2, period: {period}}}
"""


def run(cmd, stdout=subprocess.DEVNULL, stdin=None):
    """Wall time (s) and peak RSS (MB) of one process.

    The peak is the child's VmHWM, polled every 5 ms while it runs: unlike wait4's ru_maxrss
    it belongs to the image after exec, so it does not count this (large) parent's pages that
    the fork copied.
    """
    t0 = time.perf_counter()
    proc = subprocess.Popen([str(c) for c in cmd], stdout=stdout, stdin=stdin, stderr=subprocess.PIPE)
    peak = 0
    status_file = f"/proc/{proc.pid}/status"
    while proc.poll() is None:
        try:
            with open(status_file) as fh:
                for line in fh:
                    if line.startswith("VmHWM:"):
                        peak = max(peak, int(line.split()[1]))
        except OSError:
            pass
        time.sleep(0.005)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode()
    proc.stderr.close()
    if proc.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed: {err.strip()[-400:]}")
    return wall, peak / 1024.0


def geomdl_loop(ticks: int) -> float:
    """µs per tick of the naive loop: geomdl derivatives + Eq. 9, in Python."""
    from geomdl import NURBS

    curve = NURBS.Curve(normalize_kv=False)
    curve.degree = 2
    pts = [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]]
    w = [1, 0.5, 0.5, 1, 0.5, 0.5, 1]
    curve.ctrlptsw = [[x * wi, y * wi, wi] for (x, y), wi in zip(pts, w)]
    curve.knotvector = [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]
    T, Vp, Ta = 1e-3, 100.0, 0.5
    u = 0.0
    t0 = time.perf_counter()
    for k in range(ticks):
        t = k * T
        V, A = (Vp * t / Ta, Vp / Ta) if t < Ta else (Vp, 0.0)
        d = curve.derivatives(u, order=2)
        d1, d2 = np.asarray(d[1]), np.asarray(d[2])
        sigma = math.hypot(*d1)
        step = T * V / sigma
        u = min(1.0, u + step + 0.5 * T * T * A / sigma - 0.5 * step * step * float(d1 @ d2) / sigma ** 2)
    return (time.perf_counter() - t0) / ticks * 1e6


def c_reference(workdir: Path) -> float | None:
    """ns per tick of the plain C taylor2 loop, or None without gcc."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        return None
    exe = workdir / "taylor2_ref"
    subprocess.run([gcc, "-O2", "-o", str(exe), str(ROOT / "benchmarks" / "taylor2_ref.c"), "-lm"], check=True)
    best = math.inf
    for _ in range(5):
        out = subprocess.run([str(exe), "1e-3", "300"], check=True, capture_output=True, text=True).stdout
        best = min(best, float(out.split()[0]))
    return best


def measure(quick: bool = False):
    """Run every measure: ([(name, value, note), ...], the machine)."""
    from nurbsinterp.bench import machine, run_bench
    from nurbsinterp.config import load_job

    long_ticks = 1_000_000 if quick else 10_000_000
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        # warm the numba cache (every path used below) so that start-up is the cached case a user sees
        warm = tmp / "warm.bin"
        run([EXE, "plan", CIRCLE, "--format", "bin", "-o", warm])
        run([EXE, "plan", CIRCLE, "-o", os.devnull])
        run([EXE, "simulate", warm, "--job", CIRCLE, "--json"])

        # 1. one tick
        result = run_bench(load_job(CIRCLE), repeats=5).as_dict()
        ours = next(r for r in result["rows"] if r["interpolator"] == "taylor2" and r["profile"] == "trapezoidal")
        ours_ns = ours["mean_us"] * 1e3
        naive_us = None
        try:
            naive_us = geomdl_loop(2000 if quick else 3643)
        except ImportError:
            print("geomdl is not installed (pip install -e '.[test]'): skipping the naive loop", file=sys.stderr)
        c_ns = c_reference(tmp)
        rows.append(("taylor2 tick, nurbsinterp (compiled, timed per tick)", f"{ours_ns:.0f} ns", "mean; p99 "
                     f"{ours['p99_us'] * 1e3:.0f} ns"))
        if naive_us is not None:
            rows.append(("taylor2 tick, Python loop over geomdl.derivatives", f"{naive_us:.1f} us",
                         f"nurbsinterp is {naive_us * 1e3 / ours_ns:.0f}x faster (target >= 50x)"))
        if c_ns is not None:
            rows.append(("taylor2 tick, plain C (gcc -O2)", f"{c_ns:.0f} ns",
                         f"nurbsinterp is {ours_ns / c_ns:.2f}x the C loop (target <= 3x)"))
        rows.append(("servo controller tick (2 axes)", f"{result['servo']['mean_us'] * 1e3:.0f} ns", "paper: 45 us"))

        # 2. end-to-end plan
        feed = 100.0 * math.pi / (long_ticks * 1e-6 - 0.5)  # so that the job has about long_ticks ticks at 1 us
        long_job = tmp / "long.yaml"
        long_job.write_text(LONG_JOB.format(feed=feed, period="1 us"))
        tiny_job = tmp / "tiny.yaml"
        tiny_job.write_text(LONG_JOB.format(feed=100, period="1 ms"))
        wall, rss_long = run([EXE, "plan", long_job, "--format", "bin", "-o", os.devnull])
        rows.append((f"plan --format bin, {long_ticks / 1e6:g}M ticks, with summary", f"{long_ticks / wall / 1e6:.2f} M ticks/s",
                     f"{wall:.2f} s wall incl. start-up (target >= 1 M/s)"))
        wall_q, _ = run([EXE, "plan", long_job, "--format", "bin", "-q", "-o", os.devnull])
        rows.append((f"plan --format bin -q, {long_ticks / 1e6:g}M ticks", f"{long_ticks / wall_q / 1e6:.2f} M ticks/s",
                     f"{wall_q:.2f} s wall"))
        _, rss_tiny = run([EXE, "plan", tiny_job, "--format", "bin", "-o", os.devnull])
        rows.append(("peak RSS: plan of 10k ticks vs " + f"{long_ticks / 1e6:g}M ticks",
                     f"{rss_tiny:.0f} MB vs {rss_long:.0f} MB", f"+{rss_long - rss_tiny:.0f} MB (target <= 50 MB)"))

        # CSV against numpy.savetxt, on one million rows
        mid_ticks = 1_000_000
        mid_job = tmp / "mid.yaml"
        mid_job.write_text(LONG_JOB.format(feed=100.0 * math.pi / (mid_ticks * 1e-6 - 0.5), period="1 us"))
        mid_bin = tmp / "mid.bin"
        run([EXE, "plan", mid_job, "--format", "bin", "-q", "-o", mid_bin])
        wall_csv, _ = run([EXE, "plan", mid_job, "--format", "csv", "-q", "-o", tmp / "mid.csv"])
        head, _, body = mid_bin.read_bytes().partition(b"\n")
        columns = head.split()[2].decode().split(",")
        data = np.frombuffer(body[:-64], "<f8").reshape(-1, len(columns))  # the 64-byte end mark left out
        t0 = time.perf_counter()
        np.savetxt(tmp / "savetxt.csv", data, fmt="%.9f", delimiter=",")
        wall_np = time.perf_counter() - t0
        from nurbsinterp.streams import StreamWriter

        wall_writer = math.inf
        for _ in range(3):
            with open(tmp / "writer.csv", "wb") as fh:
                writer = StreamWriter(fh, columns, "csv")
                t0 = time.perf_counter()
                for i in range(0, data.shape[0], 1 << 16):
                    writer.write(data[i:i + (1 << 16)])
                wall_writer = min(wall_writer, time.perf_counter() - t0)
        rows.append((f"CSV writer, {data.shape[0] / 1e6:.1f}M rows x {len(columns)} columns", f"{wall_writer:.2f} s",
                     f"numpy.savetxt of the same rows: {wall_np:.2f} s, {wall_np / wall_writer:.1f}x slower (target >= 3x)"))
        rows.append((f"plan --format csv -q, {data.shape[0] / 1e6:.1f}M rows (whole process)", f"{wall_csv:.2f} s",
                     "start-up, interpolation and writing"))

        # 4. simulate on the long stream
        long_bin = tmp / "long.bin"
        run([EXE, "plan", long_job, "--format", "bin", "-q", "-o", long_bin])
        wall_sim, rss_sim = run([EXE, "simulate", long_bin, "--job", long_job, "--json"])
        rows.append((f"simulate, {long_ticks / 1e6:g}M-tick binary stream", f"{long_ticks / wall_sim / 1e6:.2f} M ticks/s",
                     f"{wall_sim:.2f} s wall incl. start-up (target >= 1 M/s)"))
        wall_short, rss_short = run([EXE, "simulate", warm, "--job", CIRCLE, "--json"])
        rows.append((f"peak RSS: simulate of 3.6k ticks vs {long_ticks / 1e6:g}M ticks",
                     f"{rss_short:.0f} MB vs {rss_sim:.0f} MB", f"+{rss_sim - rss_short:.0f} MB; the short run takes "
                     f"{wall_short:.2f} s (start-up)"))

    return rows, dataclasses.asdict(machine())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller jobs (a smoke test, not the numbers)")
    args = parser.parse_args()
    rows, m = measure(args.quick)
    print(f"nurbsinterp benchmarks on {m['cpu']} ({m['cores']} cores), Python {m['python']}")
    width = max(len(r[0]) for r in rows)
    for name, value, note in rows:
        print(f"  {name:<{width}}  {value:>22}  {note}")


if __name__ == "__main__":
    main()
