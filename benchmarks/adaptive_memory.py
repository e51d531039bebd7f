"""The adaptive planner's cost per control point: CPU time and peak memory of planning a long curve (issue 16, item 6).

    .venv/bin/python benchmarks/adaptive_memory.py                # 10³, 10⁴, 10⁵ control points: ~2 minutes
    .venv/bin/python benchmarks/adaptive_memory.py --sizes 1000 10000 --json

The curve: a clamped uniform cubic B-spline, control points 1 mm apart along x, y = 5 sin(2πx/40 mm)
± 0.2 mm (uniform, seeded) — a wavy line of realistic size, written to a job file in a temporary
directory and planned with profiles/adaptive.yaml (F = 100 mm/s, δ = 1 µm, 1000 mm/s², 30 000 mm/s³,
T = 1 ms).  tests/test_planner.py (wavy_cubic) builds the same curve.

Each size runs in processes of its own, so that their peaks do not mix:

* plan: the job's profile (profiles.planned_profile) in-process, after the curve and its arc-length
  table are built and the planner's kernels loaded (a plan of 300 control points first).  CPU time
  (getrusage, user + system: the 2-core machine is shared, wall time is not a measure), the RSS before
  and the peak RSS during planning (VmHWM, reset before), and the rise per control point;
* end to end: ``nurbsinterp plan job.yaml --profile profiles/adaptive.yaml --format bin -q -o /dev/null``,
  the child's CPU time and its maximum RSS (wait4), reading the job file and interpolating included.

A benchmark, never a test: tests/test_planner.py::test_planning_memory_per_control_point checks the bytes.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parent.parent
PROFILE = ROOT / "profiles" / "adaptive.yaml"
SIZES = (1_000, 10_000, 100_000)


def wavy_job_doc(n: int, seed: int = 0) -> dict:
    """The job of the wavy cubic of n control points (its profile is replaced by profiles/adaptive.yaml)."""
    rng = np.random.default_rng(seed)
    x = np.arange(n, dtype=float)
    y = 5.0 * np.sin(2.0 * np.pi * x / 40.0) + rng.uniform(-0.2, 0.2, n)
    knots = np.concatenate([np.zeros(4), np.arange(1, n - 3) / (n - 3), np.ones(4)])
    return {"curve": {"order": 4, "control_points": np.column_stack([x, y]).tolist(), "knots": knots.tolist()},
            "profile": {"type": "trapezoidal", "feedrate": 100, "accel_time": 0.1},
            "interpolator": {"method": "taylor2", "period": "1 ms"}}


def _status(field: str) -> int:
    """A field of /proc/self/status, bytes."""
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith(field + ":"))


def _cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def child(job_file: str) -> dict:
    """Plan the job's adaptive profile in this process and measure it (run by main in a process of its own)."""
    from nurbsinterp.config import load_job
    from nurbsinterp.path import job_path
    from nurbsinterp.profiles import planned_profile

    with tempfile.TemporaryDirectory() as tmp:  # the planner's kernels, loaded before the measure
        small = Path(tmp) / "small.yaml"
        small.write_text(yaml.dump(wavy_job_doc(300), Dumper=yaml.CSafeDumper))
        warm = load_job(small, profile_file=PROFILE)
        planned_profile(warm, job_path(warm))
    job = load_job(job_file, profile_file=PROFILE)
    path = job_path(job)
    length = path.curve.length
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")  # VmHWM := VmRSS
    before = _status("VmRSS")
    t0 = _cpu()
    profile, ticks = planned_profile(job, path)
    cpu = _cpu() - t0
    plan = profile.plan
    peak = _status("VmHWM")
    return {"control_points": int(path.curve.n + 1), "length_mm": length, "ticks": ticks,
            "pieces": int(plan.segments.shape[0]), "plan_cpu_s": cpu, "rss_before_mb": before / 2 ** 20,
            "peak_rss_mb": peak / 2 ** 20, "rise_mb": (peak - before) / 2 ** 20}


def run_child(args: list[str]) -> tuple[bytes, float, float]:
    """(stdout, CPU seconds, max RSS in MB) of a child process, from its own rusage."""
    proc = subprocess.Popen(args, stdout=subprocess.PIPE)
    out = proc.stdout.read()
    _pid, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode:
        raise SystemExit(f"{' '.join(args)} exited with {proc.returncode}")
    return out, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024


def measure(n: int, tmp: Path) -> dict:
    job_file = tmp / f"wave{n}.yaml"
    job_file.write_text(yaml.dump(wavy_job_doc(n), Dumper=yaml.CSafeDumper))
    out, _cpu_s, _rss = run_child([sys.executable, __file__, "--child", str(job_file)])
    row = json.loads(out)
    cli = str(Path(sys.executable).with_name("nurbsinterp"))
    _out, cpu, rss = run_child([cli, "plan", str(job_file), "--profile", str(PROFILE), "--format", "bin", "-q",
                                "-o", os.devnull])
    row.update(e2e_cpu_s=cpu, e2e_max_rss_mb=rss)
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=list(SIZES), help="control points")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child)))
        return
    with tempfile.TemporaryDirectory() as tmp:
        rows = [measure(n, Path(tmp)) for n in args.sizes]
    # the rise per control point over the previous size: what a control point costs, the constant part cancelled
    for prev, r in zip([None] + rows[:-1], rows):
        r["marginal_bytes_per_cp"] = None if prev is None else \
            (r["rise_mb"] - prev["rise_mb"]) * 2 ** 20 / (r["control_points"] - prev["control_points"])
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print("| control points | ticks | plan CPU (s) | RSS before (MB) | peak RSS (MB) | rise (MB) | bytes per control "
          "point over the previous size | end to end CPU (s) | end to end max RSS (MB) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        marginal = "" if r["marginal_bytes_per_cp"] is None else f"{r['marginal_bytes_per_cp']:.0f}"
        print(f"| {r['control_points']} | {r['ticks']} | {r['plan_cpu_s']:.2f} | {r['rss_before_mb']:.0f} | "
              f"{r['peak_rss_mb']:.0f} | {r['rise_mb']:.1f} | {marginal} | {r['e2e_cpu_s']:.2f} | "
              f"{r['e2e_max_rss_mb']:.0f} |")


if __name__ == "__main__":
    main()
