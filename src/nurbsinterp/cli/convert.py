"""`nurbsinterp convert`: a G-code program or a DXF drawing written as the equivalent YAML job."""
from __future__ import annotations

import click

from .common import JOB_ARGUMENT, check_outputs, load, output_label, reader_options


@click.command()
@JOB_ARGUMENT
@click.option("-o", "--output", metavar="FILE.yaml", default="-",
              help="Write here instead of stdout; written atomically (no partial file on failure).")
@reader_options
def convert(job, output, **reading):
    """Write JOB as a YAML job: the blocks exactly as read, with their feedrates, and the job's profile and interpolator.

    Every number is written in full (mm, s), so the YAML plans exactly like JOB: the same
    ticks at the same positions, under the same fingerprint; each block's comment names
    the program line or drawing entity it came from.

    \b
    nurbsinterp convert curves/pocket.ngc -o pocket.yaml
    nurbsinterp convert curves/drawing.dxf --layer CUT
    """
    spec = load(job, **reading)
    check_outputs(inputs=[job], output=output)
    from ..config.writing import job_yaml
    from ..streams import open_output

    text = job_yaml(spec, f"converted by nurbsinterp from {job}")
    with open_output(output, output_label("output", output)) as fh:
        fh.write(text.encode())
