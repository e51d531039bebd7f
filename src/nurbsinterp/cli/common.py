"""Options and helpers shared by the subcommands."""
from __future__ import annotations

import click

from ..spec import load_job

JOB_ARGUMENT = click.argument("job", metavar="JOB.yaml", type=click.Path(dir_okay=True))


def job_options(func):
    """The options that override fields of the job file (every field of profile and interpolator)."""
    options = [
        click.option("--profile", "profile_file", metavar="FILE", type=click.Path(),
                     help="YAML file with 'profile' and/or 'interpolator' sections overriding the job's."),
        click.option("--profile-type", type=click.Choice(["trapezoidal", "exponential", "bell", "adaptive"]),
                     help="Feedrate profile (profile.type); 'adaptive' schedules it along the curve from the limits."),
        click.option("--feedrate", metavar="F", help="Peak feedrate: mm/s, or with a unit ('6000 mm/min')."),
        click.option("--accel-time", metavar="TA", help="Acc/dec time: s, or with a unit ('500 ms')."),
        click.option("--time-constant", metavar="TAU", help="Exponential time constant (default accel_time/4)."),
        click.option("--accdec", type=click.Choice(["before", "after"]),
                     help="Acc/dec before interpolation (default) or after it (the conventional filter)."),
        click.option("--interpolator", type=click.Choice(["taylor1", "taylor2", "rk4", "exact"]),
                     help="Interpolator (interpolator.method)."),
        click.option("--period", metavar="T", help="Sampling period: s, or with a unit ('1 ms', '250 us')."),
        click.option("--chord-tolerance", metavar="D", help="Adaptive: largest chord error, mm or '1 um'."),
        click.option("--max-accel", metavar="A", help="Adaptive: tangential acceleration limit, mm/s^2."),
        click.option("--max-jerk", metavar="J", help="Adaptive: tangential jerk limit, mm/s^3."),
        click.option("--max-normal-accel", metavar="AN", help="Adaptive: centripetal acceleration limit, mm/s^2."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


MAX_TICKS_OPTION = click.option(
    "--max-ticks", type=click.IntRange(min=1), default=100_000_000, show_default=True, metavar="N",
    help="Refuse a job that would take more ticks than this.")
MAX_TICKS_HINT = " (--max-ticks)"  # how a refusal tells the user to raise the limit


def load(job, profile_file=None, **overrides):
    """Load the job with the command-line overrides applied."""
    return load_job(job, profile_file=profile_file, overrides=overrides)


def json_text(obj) -> str:
    """Strict JSON (RFC 8259): a non-finite number becomes null, never 'Infinity' or 'NaN'."""
    import json
    import math

    def clean(value):
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if isinstance(value, dict):
            return {k: clean(v) for k, v in value.items()}
        if isinstance(value, (list, tuple)):
            return [clean(v) for v in value]
        return value

    return json.dumps(clean(obj), indent=2, allow_nan=False)
