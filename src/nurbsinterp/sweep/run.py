"""A whole sweep: its cases on a Dask cluster, the rows to disk as they finish, then the ordered file and its
summary (the pipeline `nurbsinterp sweep` runs; docs/design/sweep.md)."""
from __future__ import annotations

import dataclasses

from .results import Partial, Summary, read_rows
from .spec import Sweep, cases


@dataclasses.dataclass
class SweepResult:
    source: str
    output: str
    cases: int
    resumed: int  # rows an earlier run had written, kept
    computed: int  # cases run by this one
    scheduler: str  # "local" or the address
    workers: int  # worker threads
    summary: Summary

    def document(self) -> dict:
        """The JSON form: the counts, the failed cases, the worst cases, and every row (streamed from the file)."""
        s = self.summary
        return {"sweep": self.source, "output": self.output, "cases": self.cases, "resumed": self.resumed,
                "computed": self.computed, **s.counts, "limits_broken": s.limits_broken,
                "scheduler": self.scheduler, "workers": self.workers,
                "failed_cases": [dict(zip(("case", "program", "machine", "settings", "error"), r))
                                 for r in s.failed_rows()],
                "worst": [{"machine": m, "measure": c, "value": v, "case": k, "program": p, "settings": st,
                           **({"limit": what} if what else {})}
                          for (m, c), (v, k, p, st, what) in sorted(s.worst.items())],
                "rows": list(read_rows(self.output))}


def settings_text(row: dict) -> str:
    """A row's settings for people: ``tolerance_mm=0.005 precompensate=exact`` (after the program's reader options,
    where it has some: ``layer=CUT``)."""
    from .case import COLUMNS

    start, stop = COLUMNS.index("servo") + 1, COLUMNS.index("planner")
    return " ".join([*([row["program_options"]] if row.get("program_options") else []),
                     *(f"{c}={row[c]}" for c in COLUMNS[start:stop] if row.get(c) is not None)])


def run_sweep(spec: Sweep, output: str, scheduler: str | None = None, workers: int | None = None,
              fresh: bool = False, on_row=None, cluster=None, notice=None) -> SweepResult:
    """Run every case of *spec* not already in *output*'s rows (results.Partial) on Dask (cluster.Cluster, or the
    open *cluster* given: a benchmark keeps its start-up off the clock), writing each row as it comes back; then
    *output* in case order and its summary.  *on_row*(n): n more cases have their row (the progress);
    *notice*(text): what a person should know while it runs (a worker compiling the kernels)."""
    import contextlib

    from .cluster import Cluster

    partial = Partial(output, fresh)
    computed, resumed = [0], [0]

    def todo():
        for case in cases(spec):  # every case noted, in order, on disk: what the final file is built from
            partial.case(case.fingerprint, {"program": case.program, "machine": case.machine,
                                            "servo": case.servo_label})
            if partial.done(case.fingerprint):
                resumed[0] += 1
                if on_row is not None:
                    on_row(1)
                continue
            yield case

    def arrived(row):
        partial.add(row)
        computed[0] += 1
        if on_row is not None:
            on_row(1)

    try:
        with (contextlib.nullcontext(cluster) if cluster is not None else Cluster(scheduler, workers)) as cluster:
            cluster.check_versions()
            cluster.prime(notice)
            threads = cluster.threads
            cluster.run(todo(), arrived)
    except BaseException:
        partial.discard()
        raise
    partial.finish()
    summary = Summary()
    for row in read_rows(output):
        summary.add(row, settings_text(row))
    return SweepResult(spec.source, output, partial.cases, resumed[0], computed[0],
                       "local" if scheduler is None else scheduler, threads, summary)
