"""How planning grows with the number of blocks: random paths of 1 k and 10 k blocks, one run.

    .venv/bin/python benchmarks/paths.py            # about a minute
    .venv/bin/python benchmarks/paths.py --json

Each path mixes lines, arcs and cubic NURBS, half of the joints corners, half tangent
(:func:`random_path_doc`, seeded).  Measured in-process as CPU time (not wall: the machine's
other work does not count), the best of --runs: reading and validating the job, building the
path (every block as exact NURBS, joined; arc-length table; junctions), planning the paper's
trapezoid rest to rest between corners, and the whole run (every tick interpolated, with
`plan -q`'s work).  The last column is the cost per block, which stays flat when the growth
is linear.
"""
from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

SIZES = (1_000, 10_000)


def random_path_doc(count: int, seed: int = 0) -> dict:
    """A job of *count* random blocks: lines 0.5-5 mm, arcs of 0.5-5 mm radius, cubic NURBS; half the joints turn."""
    rng = np.random.default_rng(seed)
    here, heading, blocks = np.zeros(2), 0.0, []
    for _ in range(count):
        kind = rng.choice(["line", "arc", "nurbs"])
        if rng.random() < 0.5:
            heading += rng.uniform(-2.5, 2.5)
        d = np.array([math.cos(heading), math.sin(heading)])
        if kind == "line":
            here = here + rng.uniform(0.5, 5) * d
            blocks.append({"line": {"to": here.tolist()}})
        elif kind == "arc":
            r, sweep, ccw = rng.uniform(0.5, 5), rng.uniform(0.2, 3), rng.random() < 0.5
            c = here + r * np.array([-d[1], d[0]]) * (1 if ccw else -1)
            ang = sweep if ccw else -sweep
            rot = np.array([[math.cos(ang), -math.sin(ang)], [math.sin(ang), math.cos(ang)]])
            here = c + rot @ (here - c)
            blocks.append({"arc": {"to": here.tolist(), "center": c.tolist(), "direction": "ccw" if ccw else "cw"}})
            t = rot @ d
            heading = math.atan2(t[1], t[0])
        else:
            pts, h = [here.tolist()], heading
            for _ in range(3):
                here = here + rng.uniform(0.5, 3) * np.array([math.cos(h), math.sin(h)])
                pts.append(here.tolist())
                h += rng.uniform(-1, 1)
            heading = math.atan2(pts[-1][1] - pts[-2][1], pts[-1][0] - pts[-2][0])
            blocks.append({"nurbs": {"degree": 3, "control_points": pts}})
    return {"path": {"start": [0.0, 0.0], "blocks": blocks},
            "profile": {"type": "trapezoidal", "feedrate": 50, "accel_time": 0.02}}


def measure(count: int, runs: int) -> dict:
    from nurbsinterp.config import load_job
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.path import job_path

    with tempfile.TemporaryDirectory() as tmp:
        job_file = Path(tmp) / "path.yaml"
        job_file.write_text(yaml.safe_dump(random_path_doc(count)))
        best = {}
        for _ in range(runs):
            t0 = time.process_time()
            job = load_job(job_file)
            t1 = time.process_time()
            path = job_path(job)
            t2 = time.process_time()
            run = Interpolation(job, path)
            t3 = time.process_time()
            ticks = sum(c.data.shape[0] for c in run.chunks())
            t4 = time.process_time()
            for key, value in (("read", t1 - t0), ("path", t2 - t1), ("plan", t3 - t2), ("run", t4 - t3)):
                best[key] = min(best.get(key, math.inf), value)
        return {"blocks": count, "ticks": ticks, **best}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args()
    measure(100, 1)  # load the kernels
    rows = [measure(n, args.runs) for n in SIZES]
    if args.json:
        print(json.dumps(rows, indent=2))
        return
    print("| blocks | ticks | read (s) | path (s) | plan (s) | run (s) | read+path+plan per block (ms) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        per = (r["read"] + r["path"] + r["plan"]) / r["blocks"] * 1e3
        print(f"| {r['blocks']} | {r['ticks']} | {r['read']:.2f} | {r['path']:.2f} | {r['plan']:.2f} | "
              f"{r['run']:.2f} | {per:.3f} |")


if __name__ == "__main__":
    main()
