"""`nurbsinterp sweep` on 1 and 2 local Dask workers: the speed-up, and the overhead per case beyond its own work.

    python benchmarks/sweep.py            # about 3 minutes on 2 cores; prints README's table (generated: sweep)

A 40-case sweep of the bundled jobs and programs (5 programs x 2 profiles x tolerance none / 5 um x
pre-compensation none / exact, on one machine with a servo).  Each worker count runs on its own local cluster,
started and primed off the clock (every worker has run the pipeline once: its kernels loaded), best of
ROUNDS; W(n) is the wall time from the first case submitted to the ordered file written, own the sum of the
rows' plan_s + simulate_s, and the overhead per case (n W(n) - own) / 40: what the sweep costs beyond the cases
themselves (scheduling, transfers, the client's bookkeeping, the workers' waits).  The load average is printed
beside: on a busy machine two workers cannot be twice one, and the ratio says so, not the sweep.
"""
from __future__ import annotations

import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

SWEEP = """\
programs: [{root}/curves/circle.yaml, {root}/curves/butterfly.yaml, {root}/curves/square.yaml,
           {root}/curves/rounded-square.yaml, {root}/curves/pocket.ngc]
machines:
  - name: mill
    servo: {root}/servo/example-xyz.yaml
grid:
  profile: [trapezoidal, bell]
  tolerance: [null, 5 um]
  precompensate: [none, exact]
"""


ROUNDS = 3


def run(workers: int, spec, where: Path):
    from nurbsinterp.sweep.cluster import Cluster
    from nurbsinterp.sweep.results import read_rows
    from nurbsinterp.sweep.run import run_sweep

    out = where / f"w{workers}.csv"
    best = None
    with Cluster(workers=workers) as cluster:
        cluster.prime()
        for _ in range(ROUNDS):
            t0 = time.perf_counter()
            result = run_sweep(spec, str(out), cluster=cluster, fresh=True)
            wall = time.perf_counter() - t0
            own = sum(r["plan_s"] + r["simulate_s"] for r in read_rows(str(out)))
            if best is None or wall < best[0]:
                best = (wall, own, result)
    return best


def main() -> None:
    from nurbsinterp.cli.common import ensure_kernels
    from nurbsinterp.sweep.spec import read_sweep

    ensure_kernels(safety_net=False)
    with tempfile.TemporaryDirectory() as tmp:
        where = Path(tmp)
        (where / "bench.yaml").write_text(SWEEP.format(root=ROOT))
        spec = read_sweep(where / "bench.yaml")
        load = os.getloadavg()[0]
        walls = {}
        lines = ["| workers | wall (s) | cases' own work (s) | overhead per case (ms) | speed-up |", "|---|---|---|---|---|"]
        for n in (1, 2):
            wall, own, result = run(n, spec, where)
            walls[n] = wall
            overhead = (n * wall - own) / result.cases * 1e3
            lines.append(f"| {n} | {wall:.1f} | {own:.1f} | {overhead:.0f} | {walls[1] / wall:.2f}x |")
        lines.append("")
        lines.append(f"40 cases, best of {ROUNDS} runs each; load average before: {load:.2f} on {os.cpu_count()} cores.")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
