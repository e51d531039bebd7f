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
    """Write the path read from JOB as a YAML job (the blocks exactly as read, with their feedrates).

    Every number is written in full, so reading the YAML back gives the same path;
    each block's comment names the program line or drawing entity it came from.

    \b
    nurbsinterp convert curves/pocket.ngc -o pocket.yaml
    nurbsinterp convert curves/drawing.dxf --layer CUT
    """
    spec = load(job, **reading)
    check_outputs(inputs=[job], output=output)
    from ..config.writing import path_yaml
    from ..streams import open_output

    text = path_yaml(spec.path, f"converted by nurbsinterp from {job}")
    with open_output(output, output_label("output", output)) as fh:
        fh.write(text.encode())
