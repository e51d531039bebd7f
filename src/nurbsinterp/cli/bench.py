"""`nurbsinterp bench`: the paper's Table 1 on this machine."""
from __future__ import annotations

import click

from .common import echo_result, ensure_kernels, json_text, load

DEFAULT_JOB = "curves/circle.yaml"


@click.command()
@click.argument("job", metavar="[JOB.yaml]", required=False, type=click.Path())
@click.option("--period", metavar="T", help="Sampling period (default: the job's; the paper's circle uses 1 ms).")
@click.option("--repeats", type=click.IntRange(1, 50), default=3, show_default=True,
              help="Timed passes over the motion per variant; the fastest pass is reported.")
@click.option("--json", "as_json", is_flag=True, help="Print the results as one JSON object on stdout.")
def bench(job, period, repeats, as_json):
    """Time one interpolator tick and one servo tick, per tick, beside the paper's DSP (Table 1).

    Without JOB, the paper's circle (curves/circle.yaml: 100 mm/s, Ta 0.5 s, T 1 ms)
    or, outside a checkout, the same circle built in.  The result goes to stdout.

    \b
    nurbsinterp bench
    nurbsinterp bench curves/butterfly.yaml --json
    """
    spec = load(job or _default_job(), period=period, every_profile=True)
    ensure_kernels("bench")  # (its timing kernels call the C clock: compiled on every run, never announced)
    from ..bench import run_bench

    result = run_bench(spec, repeats=repeats)
    if as_json:
        echo_result(json_text(result.as_dict()))
    else:
        from .report import bench_table

        bench_table(result)


def _default_job() -> str:
    import os

    if os.path.exists(DEFAULT_JOB):
        return DEFAULT_JOB
    from importlib.resources import files

    return str(files("nurbsinterp").joinpath("data/circle.yaml"))
