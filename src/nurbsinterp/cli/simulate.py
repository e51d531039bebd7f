"""`nurbsinterp simulate`: the commands through the servo table, and the contour error they cause."""
from __future__ import annotations

import os
import sys

import click

from ..errors import UsageError, located
from ..interpolate import Interpolation
from ..nurbs import NurbsCurve
from ..servo import load_servo
from ..simulation import simulate as run_simulation
from ..simulation import trace_columns
from ..streams import StreamWriter, check_output_path, open_output, read_stream
from . import cli
from .common import MAX_TICKS_HINT, MAX_TICKS_OPTION, job_options, json_text, load
from .report import servo_table


@cli.command()
@click.argument("commands", metavar="[COMMANDS|-]", required=False)
@click.option("--job", "job", required=True, metavar="JOB.yaml", type=click.Path(),
              help="The job the commands were planned from (its curve measures the contour error).")
@click.option("--servo", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Servo model file (default: the paper's X-Y table, as in servo/paper-xy.yaml).")
@job_options
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object on stdout.")
@click.option("--plot", metavar="FILE.png", help="Write the path, contour error, feedrate and feedrate error.")
@click.option("-o", "--output", metavar="TRACE.csv",
              help="Write the per-tick trace: commanded and actual axes, contour error, feedrates.")
@MAX_TICKS_OPTION
def simulate(commands, job, servo_file, as_json, plot, output, max_ticks, **options):
    """Simulate the servo table following a command stream and report its errors.

    COMMANDS is a stream written by `plan` (CSV or binary, detected from its
    content), a file or '-' for stdin.  Without COMMANDS, and with stdin a
    terminal or empty, simulate plans the job itself and takes plan's options.

    \b
    nurbsinterp plan curves/circle.yaml | nurbsinterp simulate --job curves/circle.yaml
    nurbsinterp simulate --job curves/circle.yaml --accdec after --plot after.png
    nurbsinterp simulate run.bin --job curves/circle.yaml --servo servo/paper-xy.yaml --json
    """
    from_stdin = commands == "-" or (commands is None and _stdin_has_data())
    self_planned = commands is None and not from_stdin
    given = [f"--{k.replace('_', '-')}" for k, v in options.items() if v is not None]
    if given and not self_planned:
        raise UsageError(f"{given[0]} applies only when simulate plans the job itself "
                         "(no COMMANDS, stdin a terminal or empty); the stream was planned already")
    spec = load(job, **options)
    model = load_servo(servo_file)
    for path in (output, plot):
        check_output_path(path, inputs=[job, servo_file, commands])
    curve = NurbsCurve.from_spec(spec.curve)
    with located(job):
        curve.panels  # noqa: B018 - the arc-length table: refused here, naming the job, if it cannot be built
    if self_planned:
        run = Interpolation(spec, curve, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
        columns, chunks, name = run.columns, (c.data for c in run.chunks()), f"{job} (planned)"
        report, series = _run(curve, model, columns, chunks, name, output, plot)
    elif from_stdin:
        columns, chunks = read_stream(sys.stdin.buffer, "<stdin>")
        report, series = _run(curve, model, columns, chunks, "<stdin>", output, plot)
    else:
        if os.path.isdir(commands):
            raise UsageError(f"{commands}: is a directory, not a command stream")
        try:
            fh = open(commands, "rb")
        except OSError as exc:
            raise UsageError(f"{commands}: cannot read: {exc.strerror or exc}") from None
        with fh:
            columns, chunks = read_stream(fh, commands)
            report, series = _run(curve, model, columns, chunks, commands, output, plot)
    report["job"] = job
    if plot:
        from ..plots import plot_simulation

        plot_simulation(plot, series, report["axes"], curve, report,
                        f"{job}: {model.source}, T = {report['period'] * 1e3:g} ms")
    if as_json:
        click.echo(json_text(report))
    else:
        servo_table(report)


def _stdin_has_data() -> bool:
    """Whether stdin brings a stream: not a terminal, and not empty (as </dev/null is in scripts)."""
    if sys.stdin is None or sys.stdin.isatty():
        return False
    try:
        return bool(sys.stdin.buffer.peek(1))
    except (AttributeError, OSError, ValueError):
        return True


def _run(curve, model, columns, chunks, name, output, plot):
    if output is None:
        return run_simulation(curve, model, columns, chunks, name=name, keep_series=bool(plot))
    axes = [a for a in ("x", "y", "z") if a in columns]
    with open_output(output) as fh:
        writer = StreamWriter(fh, trace_columns(axes), "csv")
        return run_simulation(curve, model, columns, chunks, name=name, trace=writer.write, keep_series=bool(plot))
