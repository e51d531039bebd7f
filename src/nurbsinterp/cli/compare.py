"""`nurbsinterp compare`: the paper's experiments in one table."""
from __future__ import annotations

import click

from .common import (JOB_ARGUMENT, check_outputs, echo_result, ensure_kernels, json_text, load, output_label,
                     plot_format, reader_options)


@click.command()
@JOB_ARGUMENT
@click.option("--servo", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Servo model file (default: the paper's X-Y table).")
@click.option("--profile", "profile_file", metavar="FILE", type=click.Path(),
              help="YAML with 'profile'/'interpolator' sections (e.g. the adaptive limits) overriding the job's.")
@click.option("--period", metavar="T", help="Sampling period (overrides the job's).")
@click.option("--feedrate", metavar="F", help="Peak feedrate (overrides the job's).")
@click.option("--accel-time", metavar="TA", help="Acc/dec time (overrides the job's).")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as a JSON list on stdout.")
@click.option("--plot", metavar="FILE.png", help="Contour and feedrate error per variant (png, svg, pdf, jpg).")
@reader_options
def compare(job, servo_file, profile_file, period, feedrate, accel_time, as_json, plot, **reading):
    """Every interpolator x profile before interpolation and every profile after it, through the servo.

    The result (a table, or JSON with --json) goes to stdout.  The last rows
    are the adaptive schedule with the job's limits (max_accel defaults to
    feedrate / accel_time).

    \b
    nurbsinterp compare curves/circle.yaml
    nurbsinterp compare curves/butterfly.yaml --profile profiles/adaptive.yaml --json > butterfly.json
    """
    from ..servo import load_servo

    spec = load(job, profile_file=profile_file, period=period, feedrate=feedrate, accel_time=accel_time, **reading)
    model = load_servo(servo_file)
    check_outputs(inputs=[job, profile_file, servo_file], plot=plot)
    ensure_kernels()
    from ..compare import compare as run_compare

    rows = run_compare(spec, model)
    if plot:
        from ..plots import plot_compare

        p = spec.profile
        plot_compare(plot, rows, f"{job}: every variant through {model.source}\n"
                                 f"F = {p.feedrate:g} mm/s, Ta = {p.accel_time:g} s, "
                                 f"T = {spec.interpolator.period * 1e3:g} ms", plot_format(plot),
                     output_label("plot", plot))
    if as_json:
        echo_result(json_text([row.as_dict() for row in rows]))
    else:
        from .report import compare_table

        compare_table(rows, job)
