"""`nurbsinterp plan`: stream one axis command per tick as CSV or binary."""
from __future__ import annotations

import contextlib
import sys

import click

from .common import (CSV_TOO_LARGE_HINT, JOB_ARGUMENT, MAX_TICKS_HINT, MAX_TICKS_OPTION, check_outputs, ensure_kernels,
                     job_options, load, output_label)


@click.command()
@JOB_ARGUMENT
@job_options
@click.option("--format", "fmt", type=click.Choice(["csv", "bin"]), default="csv", show_default=True,
              help="CSV text or the self-describing little-endian float64 stream.")
@click.option("-o", "--output", metavar="FILE", default="-",
              help="Write here instead of stdout; written atomically (no partial file on failure).")
@click.option("-q", "--quiet", is_flag=True, help="No run summary (also skips computing its measures).")
@MAX_TICKS_OPTION
def plan(job, fmt, output, quiet, max_ticks, **options):
    """Plan the feedrate, interpolate JOB (a YAML job, a G-code program or a DXF drawing) and write one command per tick.

    Columns: k,n,t,u,x,y[,z],v,a (tick, block, s, the block's parameter, mm, mm/s, mm/s²).
    The run summary goes to stderr.

    \b
    nurbsinterp plan curves/circle.yaml > circle.csv
    nurbsinterp plan curves/circle.yaml --interpolator exact --period "250 us" --format bin -o run.bin
    nurbsinterp plan curves/circle.yaml --accdec after | other-tool
    """
    spec = load(job, **options)
    check_outputs(inputs=[job, options.get("profile_file")], output=output)
    ensure_kernels()
    from ..interpolate import Interpolation
    from ..metrics import Alongside, RunStats
    from ..streams import StreamWriter, is_stdout, open_output
    from .report import progress, summary_lines

    run = Interpolation(spec, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
    stats = None if quiet else RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
    dim = run.curve.dim
    with open_output(output, output_label("output", output)) as fh, \
            progress(run.ticks_estimate, enabled=not quiet) as advance, \
            contextlib.ExitStack() as measures:
        writer = StreamWriter(fh, run.columns, fmt, fingerprint=spec.path.fingerprint,
                              too_large_hint=CSV_TOO_LARGE_HINT)
        # the summary's measures on the second core while this one interpolates and writes
        alongside = None if stats is None else measures.enter_context(Alongside(stats.update))
        for chunk in run.chunks(derivatives=stats is not None):
            writer.write(chunk.data)
            if alongside is not None:
                alongside.submit(chunk, dim)
            advance(chunk.data.shape[0])
    if is_stdout(output):
        sys.stdout.flush()  # every byte delivered (or the error raised) before the summary claims it
    if stats is not None:
        target = "stdout" if is_stdout(output) else output
        for line in summary_lines(run, stats, target):
            click.echo(line, err=True)
