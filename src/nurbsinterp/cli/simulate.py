"""`nurbsinterp simulate`: the commands through the servo table, and the contour error they cause."""
from __future__ import annotations

import os
import sys

import click

from .common import (FORCE_HINT, MAX_TICKS_HINT, MAX_TICKS_OPTION, check_outputs, echo_result, ensure_kernels,
                     job_options, json_text, load, output_label, plot_format)


@click.command()
@click.argument("commands", metavar="[COMMANDS|-]", required=False)
@click.option("--job", "job", required=True, metavar="JOB", type=click.Path(),
              help="The job the commands were planned from (its curve measures the contour error).")
@click.option("--servo", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Servo model file (default: the paper's X-Y table, as in servo/paper-xy.yaml).")
@job_options
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object on stdout.")
@click.option("--plot", metavar="FILE.png",
              help="Write the path, contour error, feedrate and feedrate error (png, svg, pdf, jpg).")
@click.option("-o", "--output", metavar="TRACE.csv",
              help="Write the per-tick trace: commanded and actual axes, contour error, feedrates.")
@click.option("--force", is_flag=True,
              help="Simulate a stream even if it does not look planned from this job (another curve's fingerprint, "
                   "a first point off the path's start).")
@MAX_TICKS_OPTION
def simulate(commands, job, servo_file, as_json, plot, output, force, max_ticks, **options):
    """Simulate the servo table following a command stream and report its errors.

    COMMANDS is a stream written by `plan` (CSV or binary, detected from its
    content), a file or '-' for stdin.  Without COMMANDS, and with stdin a
    terminal or empty, simulate plans the job itself and takes plan's options.
    The report (a table, or JSON with --json) goes to stdout; with -o - the
    trace takes stdout and the table goes to stderr.

    \b
    nurbsinterp plan curves/circle.yaml | nurbsinterp simulate --job curves/circle.yaml
    nurbsinterp simulate --job curves/circle.yaml --accdec after --plot after.png
    nurbsinterp simulate run.bin --job curves/circle.yaml --servo servo/paper-xy.yaml --json
    """
    from ..errors import UsageError

    from_stdin = commands == "-" or (commands is None and _stdin_has_data())
    self_planned = commands is None and not from_stdin
    given = [f"--{k.replace('_', '-')}" for k, v in options.items() if v is not None]
    if given and not self_planned:
        raise UsageError(f"{given[0]} applies only when simulate plans the job itself "
                         "(no COMMANDS, stdin a terminal or empty); the stream was planned already")
    trace_on_stdout = output == "-"
    if trace_on_stdout and as_json:
        raise UsageError("-o - and --json both want stdout; write the trace to a file")
    spec = load(job, **options)
    from ..servo import load_servo

    model = load_servo(servo_file)
    check_outputs(inputs=[job, servo_file, commands, options.get("profile_file")], output=output, plot=plot)
    if commands not in (None, "-") and os.path.isdir(commands):
        raise UsageError(f"{commands}: is a directory, not a command stream")
    ensure_kernels()
    from ..errors import located
    from ..path import job_path

    with located(job):
        path = job_path(spec)  # the arc-length table: refused here, naming the job, if it cannot be built
    curve = path.programmed
    if self_planned:
        from ..interpolate import Interpolation

        run = Interpolation(spec, path, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
        columns, chunks, name = run.columns, (c.data for c in run.chunks()), f"{job} (planned)"
        report, series = _run(spec, path, model, columns, chunks, name, output, plot, {}, True, max_ticks)
    elif from_stdin:
        report, series = _read_and_run(spec, path, model, sys.stdin.buffer, "<stdin>", output, plot, force,
                                        max_ticks)
    else:
        try:
            fh = open(commands, "rb")
        except OSError as exc:
            raise UsageError(f"{commands}: cannot read: {exc.strerror or exc}") from None
        with fh:
            report, series = _read_and_run(spec, path, model, fh, commands, output, plot, force, max_ticks)
    if plot:
        from ..plots import plot_simulation

        plot_simulation(plot, series, report.axes, curve, report, _title(job, spec, model, report, self_planned),
                        plot_format(plot), output_label("plot", plot))
    if as_json:
        echo_result(json_text({**report.as_dict(), "job": job}))
    else:
        from .report import servo_table

        servo_table(report, job, stderr=trace_on_stdout)


def _title(job, spec, model, report, self_planned) -> str:
    what = (f"{spec.interpolator.method}, {spec.profile.type} acc/dec {spec.profile.accdec} interpolation, "
            f"F = {spec.profile.feedrate:g} mm/s, " if self_planned else "a planned stream, ")
    return f"{job}: {what}T = {report.period * 1e3:g} ms, servo {model.source}"


def _stdin_has_data() -> bool:
    """Whether stdin brings a stream: not a terminal, and not empty (as </dev/null is in scripts)."""
    if sys.stdin is None or sys.stdin.isatty():
        return False
    try:
        return bool(sys.stdin.buffer.peek(1))
    except (AttributeError, OSError, ValueError):
        return True


def _read_and_run(spec, path, model, fh, name, output, plot, force, max_ticks):
    from ..streams import read_stream

    meta = {}
    columns, chunks = read_stream(fh, name, meta=meta)
    return _run(spec, path, model, columns, chunks, name, output, plot, meta, force, max_ticks)


def _run(spec, path, model, columns, chunks, name, output, plot, meta, force, max_ticks):
    from ..simulation import check_stream_belongs, trace_columns
    from ..simulation import simulate as run_simulation
    from ..streams import StreamWriter, open_output

    if not force:
        chunks = check_stream_belongs(path.programmed, spec.path.fingerprint, columns, chunks, meta, name, FORCE_HINT)
    if output is None:
        return run_simulation(path, model, columns, chunks, name=name, keep_series=bool(plot), max_ticks=max_ticks,
                              max_ticks_hint=MAX_TICKS_HINT)
    axes = [a for a in ("x", "y", "z") if a in columns]
    with open_output(output, output_label("output", output)) as fh:
        writer = StreamWriter(fh, trace_columns(axes), "csv")
        return run_simulation(path, model, columns, chunks, name=name, trace=writer.write, keep_series=bool(plot),
                              max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
