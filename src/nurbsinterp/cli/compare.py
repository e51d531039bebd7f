"""`nurbsinterp compare`: the paper's experiments in one table."""
from __future__ import annotations


import click

from ..compare import compare as run_compare
from ..servo import load_servo
from . import cli
from .common import JOB_ARGUMENT, json_text, load
from .report import compare_table


@cli.command()
@JOB_ARGUMENT
@click.option("--servo", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Servo model file (default: the paper's X-Y table).")
@click.option("--profile", "profile_file", metavar="FILE", type=click.Path(),
              help="YAML with 'profile'/'interpolator' sections (e.g. the adaptive limits) overriding the job's.")
@click.option("--period", metavar="T", help="Sampling period (overrides the job's).")
@click.option("--feedrate", metavar="F", help="Peak feedrate (overrides the job's).")
@click.option("--accel-time", metavar="TA", help="Acc/dec time (overrides the job's).")
@click.option("--json", "as_json", is_flag=True, help="Print the rows as a JSON list on stdout.")
@click.option("--plot", metavar="FILE.png", help="Bar chart of contour and feedrate error per variant.")
def compare(job, servo_file, profile_file, period, feedrate, accel_time, as_json, plot):
    """Every interpolator x profile before interpolation and every profile after it, through the servo.

    The last rows are the adaptive schedule with the job's limits (max_accel
    defaults to feedrate / accel_time).

    \b
    nurbsinterp compare curves/circle.yaml
    nurbsinterp compare curves/butterfly.yaml --profile profiles/adaptive.yaml --json > butterfly.json
    """
    spec = load(job, profile_file=profile_file, period=period, feedrate=feedrate, accel_time=accel_time)
    rows = run_compare(spec, load_servo(servo_file))
    if plot:
        from ..plots import plot_compare

        plot_compare(plot, rows, f"{job}: contour and feedrate error by variant")
    if as_json:
        click.echo(json_text(rows))
    else:
        compare_table(rows, job)
