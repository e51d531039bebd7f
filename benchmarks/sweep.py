"""`nurbsinterp sweep` on 1 and 2 local Dask workers: the speed-up, and the overhead per case beyond its own work.

    python benchmarks/sweep.py            # about 4 minutes on 2 cores; prints README's table (generated: sweep)

A 40-case sweep of the bundled jobs and programs (5 programs x 2 profiles x tolerance none / 5 um x
pre-compensation none / exact, on one machine with a servo).  Each worker count runs on its own local cluster,
started and primed off the clock (every worker has run the pipeline once: its kernels loaded), best of
ROUNDS runs alternating between the two clusters; W(n) is the wall time from the first case submitted to the ordered file written, own the sum of the
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


ROUNDS = 4


def run_once(cluster, spec, out: Path):
    """One sweep of *spec* on the open, primed *cluster*: (wall s, the cases' own work s, the result)."""
    from nurbsinterp.sweep.results import read_rows
    from nurbsinterp.sweep.run import run_sweep

    t0 = time.perf_counter()
    result = run_sweep(spec, str(out), cluster=cluster, fresh=True)
    wall = time.perf_counter() - t0
    return wall, sum(r["plan_s"] + r["simulate_s"] for r in read_rows(str(out))), result


def main() -> None:
    import contextlib

    from nurbsinterp.cli.common import ensure_kernels
    from nurbsinterp.sweep.cluster import Cluster
    from nurbsinterp.sweep.spec import read_sweep

    ensure_kernels(safety_net=False)
    with tempfile.TemporaryDirectory() as tmp, contextlib.ExitStack() as stack:
        where = Path(tmp)
        (where / "bench.yaml").write_text(SWEEP.format(root=ROOT))
        spec = read_sweep(where / "bench.yaml")
        # both clusters up and primed before the first clock; the rounds alternate 1, 2, 1, 2, ... so that a
        # machine whose speed drifts over minutes (a shared host) drifts under both alike
        clusters = {n: stack.enter_context(Cluster(workers=n)) for n in (1, 2)}
        for cluster in clusters.values():
            cluster.prime()
        load = os.getloadavg()[0]
        best = {}
        for _ in range(ROUNDS):
            for n, cluster in clusters.items():
                wall, own, result = run_once(cluster, spec, where / f"w{n}.csv")
                if n not in best or wall < best[n][0]:
                    best[n] = (wall, own, result)
        lines = ["| workers | wall (s) | cases' own work (s) | overhead per case (ms) | speed-up |", "|---|---|---|---|---|"]
        for n, (wall, own, result) in best.items():
            overhead = (n * wall - own) / result.cases * 1e3
            lines.append(f"| {n} | {wall:.1f} | {own:.1f} | {overhead:.0f} | {best[1][0] / wall:.2f}x |")
        lines.append("")
        lines.append(f"40 cases, best of {ROUNDS} alternating runs each; load average before: {load:.2f} on "
                     f"{os.cpu_count()} cores.")
        print("\n".join(lines))


if __name__ == "__main__":
    main()
