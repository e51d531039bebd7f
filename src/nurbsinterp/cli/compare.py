"""`nurbsinterp compare`: the paper's experiments in one table."""
from __future__ import annotations

import click

from .common import (JOB_ARGUMENT, PLOT_EXTENSIONS, PROGRAM_TOLERANCE_HELP, SMOOTH_OPTION, LookAheadChoice,
                     check_outputs, echo_result, ensure_kernels, json_text, load, open_capture, output_label,
                     plot_format, plot_written, reader_options)


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
@click.option("--plot", metavar="FILE.png", help="Contour and feedrate error per variant (" + PLOT_EXTENSIONS + ").")
@click.option("--precompensate", "methods", is_flag=False, flag_value="all", metavar="[METHODS]",
              help="Add the job's own variant pre-compensated for the model: exact, zpetc, match, comma-separated "
                   "(alone: all), beside 'none', in a second table.")
@click.option("--model-error", "model_errors", multiple=True, metavar="ERR",
              help="Also run every pre-compensation on a plant that differs from the model: gain=+5%, "
                   "x.gain=1.05,y.gain=0.95, poles=1.1 (s-plane poles scaled, DC gain kept); repeatable; "
                   "'standard': gain +-5 %, +-20 %, opposite +-5 % on x and y, poles x1.1, x0.9.")
@click.option("--machine", metavar="FILE.ini", type=click.Path(),
              help="A LinuxCNC INI file: per-axis limits from [AXIS_X] MAX_VELOCITY/MAX_ACCELERATION (and "
                   "MAX_JERK with --tolerance), G0 speed from [TRAJ] MAX_LINEAR_VELOCITY.")
@click.option("--tolerance", metavar="D",
              help="A program planned with look-ahead across its blocks within D (as plan --tolerance D): one row "
                   "per profile, measured against the program's blocks. " + PROGRAM_TOLERANCE_HELP)
@click.option("--actual", metavar="CAPTURE", type=click.Path(),
              help="A halsampler capture of the machine running one of the compared plans (as simulate --actual "
                   "reads it): measured as that plan, its row beside the plan's (see below).")
@click.option("--actual-columns", metavar="MAP",
              help="The capture's columns, as simulate's --actual-columns (default k,x_cmd,y_cmd,x,y).")
@SMOOTH_OPTION
@reader_options
def compare(job, servo_file, profile_file, period, feedrate, accel_time, as_json, plot, methods, model_errors,
            machine, tolerance, actual, actual_columns, smooth, **reading):
    """Every interpolator x profile before interpolation and every profile after it, through the servo.

    The result (a table, or JSON with --json) goes to stdout.  The last rows
    are the adaptive schedule with the job's limits (max_accel defaults to
    feedrate / accel_time).

    \b
    nurbsinterp compare curves/circle.yaml
    nurbsinterp compare curves/butterfly.yaml --profile profiles/adaptive.yaml --json > butterfly.json
    nurbsinterp compare curves/circle.yaml --precompensate --model-error standard
    nurbsinterp compare curves/raster.ngc --tolerance 5um --servo servo/example-xyz.yaml --machine m.ini

    With --tolerance D the job's program (G-code, DXF or a YAML path) is
    planned with look-ahead across its blocks, once per profile (the paper's
    three ramps and the adaptive schedule), each run through the servo: its
    rows give the commands' largest distance from the program (max dev),
    the contour error measured against the program's blocks, and the motion
    time; FF and chord error are an interpolator's and have no look-ahead
    value (JSON null).

    With --precompensate or --model-error a second table follows: the job's
    own variant as planned ('none') and pre-compensated by each method for
    the model, run on the model and on each plant of --model-error; its
    maximum contour error, and the worst over the wrong plants.  --json then
    prints {"variants": [...], "precompensation": [...]}.

    With --actual CAPTURE the machine's run is measured as the plan it is of:
    the job's own variant, then the same pre-compensated for the model by
    each method, then every other variant, the first whose commands the
    capture received (to %f's rounding).  Its row follows that plan's in the
    first table ("the machine"), or for a pre-compensated plan is the plant
    "the machine" in the second (which then has that method).  A capture
    without received commands is measured as the job's own variant.  --json
    then adds "actual": the plan matched and the machine's errors.
    """
    from ..errors import UsageError
    from ..names import PRECOMPENSATION
    from ..servo import STANDARD_MODEL_ERRORS, load_servo, parse_model_error

    if actual_columns is not None and actual is None:
        raise UsageError("--actual-columns applies only with --actual CAPTURE")
    given = dict(profile_file=profile_file, period=period, feedrate=feedrate, accel_time=accel_time, machine=machine,
                 **reading)
    choice = LookAheadChoice(job, tolerance, given)
    choice.refuse_smooth(smooth)
    spec = choice.load(job, **given) if choice.on else load(job, every_profile=True, **given)
    blend = choice.tolerance
    model = load_servo(servo_file)
    chosen = []
    if methods is not None:
        chosen = list(PRECOMPENSATION) if methods.strip() == "all" else [m.strip() for m in methods.split(",")]
        for m in chosen:
            if m not in PRECOMPENSATION:
                raise UsageError(f"--precompensate {methods!r}: {m!r} is not one of {', '.join(PRECOMPENSATION)}")
    errors = []
    for text in model_errors:
        for item in (STANDARD_MODEL_ERRORS if text.strip() == "standard" else (text,)):
            try:
                errors.append(parse_model_error(item, model.names))
            except ValueError as exc:
                raise UsageError(f"--model-error {text!r}: {exc}") from None
    capture_map = None
    if actual is not None:
        from ..capture import default_columns, parse_columns

        dim = spec.path.dim
        capture_map = parse_columns(default_columns(dim) if actual_columns is None else actual_columns, dim,
                                    "--actual-columns")
    check_outputs(inputs=[job, profile_file, servo_file, machine, actual], plot=plot)
    if actual is not None:
        with open_capture(actual, capture_map):
            pass  # an unreadable capture refused before any compiling
    ensure_kernels("compare")
    from ..errors import located

    with located(job):
        match = None
        if actual is not None:  # first: a capture of no compared plan is refused before the variants are run
            from ..compare import match_capture

            # every method is tried, asked for or not: a capture of shaped commands is recognised all the same
            match = match_capture(spec, model, lambda: open_capture(actual, capture_map),
                                  capture_map.command is not None, list(PRECOMPENSATION), look_ahead=choice.on,
                                  tolerance=blend, smooth=smooth is not False, capture_name=actual)
            if match.method is not None and match.method not in chosen:
                chosen.append(match.method)  # the machine's row needs its method's column
        if not choice.on:
            from ..compare import compare as run_compare

            rows = run_compare(spec, model)
        else:
            from ..compare import look_ahead_compare

            rows = look_ahead_compare(spec, blend, model, smooth is not False)
        study = None
        if methods is not None or errors or (match is not None and match.method is not None):
            from ..compare import precompensation_study

            study = precompensation_study(spec, model, list(dict.fromkeys(chosen)), errors, look_ahead=choice.on,
                                          tolerance=blend, smooth=smooth is not False)
    if plot:
        from ..plots import plot_compare

        p = spec.profile
        plot_compare(plot, rows, f"{job}: every variant through {model.source}\n"
                                 f"F = {p.feedrate:g} mm/s, Ta = {p.accel_time:g} s, "
                                 f"T = {spec.interpolator.period * 1e3:g} ms", plot_format(plot),
                     output_label("plot", plot))
        plot_written(plot)
    if as_json:
        variants = [row.as_dict() for row in rows]
        if study is None and match is None:
            echo_result(json_text(variants))
        else:
            doc = {"variants": variants}
            if study is not None:
                doc["precompensation"] = [r.as_dict() for r in study]
            if match is not None:
                doc["actual"] = match.as_dict()
            echo_result(json_text(doc))
    else:
        from .report import compare_table, compensation_table

        compare_table(rows, job, match if match is not None and match.method is None else None)
        if study is not None:
            p = spec.profile
            how = (f"look-ahead within {choice.words()}, {p.type}" if choice.on else
                   f"{spec.interpolator.method} {p.type} {p.accdec}")
            compensation_table(study, f"{job}: {how}, designed for {model.source}",
                               match if match is not None and match.method is not None else None)
