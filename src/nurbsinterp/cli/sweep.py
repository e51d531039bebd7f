"""`nurbsinterp sweep`: programs x machines x settings, every case planned and simulated on Dask."""
from __future__ import annotations

import sys

import click

from .common import check_outputs, compile_everything, echo_result, json_text


@click.command()
@click.argument("sweep_file", metavar="SWEEP.yaml", type=click.Path())
@click.option("-o", "--output", required=True, metavar="RESULTS.csv",
              help="The rows, one a case, in case order; written whole at the end (RESULTS.csv.partial while the "
                   "sweep runs, which a rerun resumes from).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary and every row as one JSON document on stdout.")
@click.option("--scheduler", metavar="tcp://HOST:PORT",
              help="Run on the Dask cluster of this scheduler (default: a local cluster, one worker per core).")
@click.option("--workers", type=click.IntRange(min=1), help="Worker processes of the local cluster (default: one "
                                                            "per usable core).")
@click.option("--fresh", is_flag=True, help="Compute every case, ignoring the rows of an earlier run.")
def sweep(sweep_file, output, as_json, scheduler, workers, fresh):
    """Plan, and where a machine names a servo simulate, every case of SWEEP.yaml on Dask; one row a case.

    A sweep file names programs (paths or globs, relative to it), machines (a servo model, per-axis
    limits) and a grid of settings; every program x machine x grid point is a case (docs/sweep.md).
    A case that fails is a row with its one-line error, never the end of the sweep.  Rows are appended
    to RESULTS.csv.partial as cases finish; an interrupted sweep run again with the same -o skips the
    cases already there.  The summary (what failed, the worst cases) goes to stdout.

    \b
    nurbsinterp sweep sweeps/bundled.yaml -o results.csv
    nurbsinterp sweep shop.yaml -o results.csv --scheduler tcp://10.0.0.5:8786
    """
    from ..errors import UsageError

    if workers is not None and scheduler is not None:
        raise UsageError("--workers sizes the local cluster; with --scheduler the cluster's workers are its own")
    if output == "-":
        raise UsageError("-o -: a sweep writes a file (a rerun resumes from it); its summary goes to stdout")
    try:
        import distributed  # noqa: F401  -- before any work: the one line that says what to install
    except ImportError:
        raise UsageError("sweep runs its cases on Dask, which is not installed: pip install 'nurbsinterp[dask]' "
                         "(or pip install 'dask[distributed]')") from None
    from ..sweep.spec import read_sweep

    spec = read_sweep(sweep_file)
    check_outputs(inputs=[sweep_file, *(p.path for p in spec.programs),
                          *(path for m in spec.machines for path in (m.servo_path, m.ini_path) if path)],
                  output=output)
    compile_everything()  # once here, both cores: the local workers load them from the cache
    from ..sweep.run import run_sweep
    from .report import progress, sweep_summary

    with progress(spec.size, unit="cases", minimum=1) as advance:
        result = run_sweep(spec, output, scheduler=scheduler, workers=workers, fresh=fresh, on_row=advance,
                           notice=lambda text: click.echo(f"nurbsinterp: {text}", err=True))
    if as_json:
        echo_result(json_text(result.document()))
    else:
        sweep_summary(result)
    if result.summary.counts.get("timeout"):
        click.echo(f"nurbsinterp: {result.summary.counts['timeout']} case(s) stopped at the sweep's timeout: raise it "
                   "and run the same sweep again to compute only those", err=True)
    if result.summary.counts.get("lost"):
        click.echo(f"nurbsinterp: {result.summary.counts['lost']} case(s) lost (their workers died): run the same "
                   "sweep again to compute them", err=True)
        sys.exit(1)
