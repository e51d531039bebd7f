"""`nurbsinterp precompensate`: shape a command stream so that the servo model's table follows the plan."""
from __future__ import annotations

import sys

import click

from ..names import PRECOMPENSATION
from .common import check_outputs, ensure_kernels, open_commands, output_label

METHOD_HELP = ("exact: the stable non-causal inverse of each axis' closed loop (the table follows the plan "
               "exactly on the model); zpetc: Tomizuka's zero-phase-error tracking (a few ticks of preview); "
               "match: give every axis the same dynamics (no inverse, a common lag).")


def budget_options(func):
    """--voltage-limit and --accel-limit: budgets the summary checks the commands against."""
    func = click.option("--accel-limit", metavar="A",
                        help="Warn where a command's acceleration |Δ²c|/T² passes A (mm/s², or with a unit).")(func)
    return click.option("--voltage-limit", metavar="V",
                        help="Warn where the model's drive voltage passes V, and say how far saturating there "
                             "would leave the table from the plan.")(func)


@click.command()
@click.argument("commands", metavar="[COMMANDS|-]", required=False)
@click.option("--servo", "servo_file", required=True, metavar="SERVO.yaml", type=click.Path(),
              help="The servo model to pre-compensate for (servo/paper-xy.yaml is the paper's table).")
@click.option("--method", type=click.Choice(list(PRECOMPENSATION)), default="exact", show_default=True,
              help=METHOD_HELP)
@click.option("--preview", type=click.IntRange(0, 4096), metavar="N",
              help="exact: the ticks of preview of the inverted zeros outside the unit circle (default: as many "
                   "as leave an error below 1e-16 of the signal; the summary bounds the error of a shorter one).")
@budget_options
@click.option("-o", "--output", metavar="FILE", default="-",
              help="Write here instead of stdout; written atomically (no partial file on failure).")
@click.option("-q", "--quiet", is_flag=True, help="No summary (and no check of the commands on the model).")
def precompensate(commands, servo_file, method, preview, voltage_limit, accel_limit, output, quiet):
    """Pre-compensate the servo's lag: rewrite a stream's axis commands so that the model's table follows the plan.

    COMMANDS is a stream written by `plan` (CSV or binary, a file or '-' for
    stdin; default stdin).  The output is the same stream, same format,
    columns, ticks and order, with x, y[, z] replaced by commands that, fed to
    the servo model, bring the table onto the planned ones; then, the path's
    end held (k and t running on), as many ticks as the shaping takes to settle
    within 1e-9 mm of it (the inverse's slow poles: 147 on the paper's
    circle).  An input that is empty or ends without its end mark is refused,
    and the output gets its own end mark only once the whole input has been
    read and shaped.  Memory stays bounded: a command leaves once the preview
    (a few dozen ticks) behind it is read.  The first command is the plan's
    own and the last the path's end: the table starts and settles where the
    path does.  A summary goes to stderr: the zeros
    inverted, the preview and the error it costs, and the model driven by the
    new commands (its distance from the plan, peak voltage and command
    acceleration) beside the planned commands.

    \b
    nurbsinterp plan curves/circle.yaml | nurbsinterp precompensate --servo servo/paper-xy.yaml \\
        | nurbsinterp simulate --job curves/circle.yaml
    nurbsinterp precompensate run.bin --servo servo/paper-xy.yaml --method zpetc -o shaped.bin
    """
    from ..errors import StreamError, UsageError
    from ..servo import load_servo

    if commands is None and sys.stdin.isatty():
        raise UsageError("no COMMANDS: give a stream from `plan` (a file, or - for stdin) or pipe one in")
    model = load_servo(servo_file)
    budgets = parse_budgets(voltage_limit, accel_limit)
    if preview is not None and method != "exact":
        raise UsageError(f"--preview applies to --method exact (the {method} method's preview is its own)")
    check_outputs(inputs=[servo_file, commands], output=output)
    ensure_kernels("precompensate")
    from ..names import AXES
    from ..precompensate import stream_period, uniform
    from ..streams import StreamWriter, open_output, read_stream

    name = "<stdin>" if commands in (None, "-") else commands
    with open_commands(commands) as fh:
        meta, detected = {}, {}
        columns, chunks = read_stream(fh, name, meta=meta, detected=detected)
        _refuse_precompensated(name, meta)  # a binary stream says so in its header
        chunks = iter(chunks)
        first = next(chunks, None)
        if first is None:
            raise StreamError(f"{name}: the stream has a header but no ticks")
        period = stream_period(first, columns, name)
        axes = [a for a in AXES if a in columns]
        missing = [a for a in axes if a not in model.axes]
        if missing:
            raise StreamError(f"{name}: the stream has a {missing[0]} axis, the servo model ({model.source}) has "
                              f"none; give a model with axes.{missing[0]}")
        pc, check = shaper(model, period, axes, columns, method, preview, budgets, quiet)
        with open_output(output, output_label("output", output)) as out:
            writer = StreamWriter(out, columns, detected["format"], fingerprint=meta.get("curve"),
                                  meta={**{k: v for k, v in meta.items() if k != "curve"}, "precompensated": method})
            for rows in shaped(uniform(_chained(first, chunks), columns, name, period), pc, check):
                writer.write(rows)
            # the input's end mark has been read and checked (read_stream): the input was whole, so is this
            _refuse_precompensated(name, meta)  # a CSV stream says so in its end mark
            writer.finish(fingerprint=meta.get("curve"))
    report(pc, check, quiet)


def shaper(model, period, axes, columns, method, preview, budgets, quiet):
    """(Precompensator, ModelCheck or None) for a stream of *columns* at *period*."""
    from ..precompensate import ModelCheck, Precompensator, design

    pc = Precompensator(design(model, period, method, axes, preview), columns)
    check = None
    if not quiet or any(b is not None for b in budgets):
        check = ModelCheck(model, period, axes, *budgets)
    return pc, check


def shaped(chunks, pc, check):
    """The rows pre-compensated (precompensate.Precompensator), each checked on the model if asked."""
    for rows, references in pc.run(chunks):
        if check is not None:
            check.update(rows[:, pc.axes], references)
        yield rows


def report(pc, check, quiet) -> None:
    """The summary (unless quiet) and the budget warnings, on stderr."""
    from .report import budget_warnings, precompensation_lines

    lines = [] if quiet else precompensation_lines(pc, check)
    if check is not None:
        lines += budget_warnings(check)
    for line in lines:
        click.echo(line, err=True)


def parse_budgets(voltage_limit, accel_limit):
    """(volts or None, mm/s² or None) from the options' text."""
    from ..config import parse_quantity
    from ..errors import UsageError

    budgets = []
    for option, text, kind in (("--voltage-limit", voltage_limit, None), ("--accel-limit", accel_limit, "accel")):
        if text is None:
            budgets.append(None)
            continue
        try:
            value = float(text) if kind is None else parse_quantity(text, kind)
        except ValueError as exc:
            reason = str(exc) if kind else "is not a number of volts"
            raise UsageError(f"{option} {text!r}: {reason}") from None
        if not (value > 0 and value < float("inf")):
            raise UsageError(f"{option} {text!r}: must be a finite number > 0")
        budgets.append(value)
    return tuple(budgets)


def _refuse_precompensated(name, meta) -> None:
    from ..errors import StreamError

    if "precompensated" in meta:
        raise StreamError(f"{name}: the stream is pre-compensated already (precompensated={meta['precompensated']}): "
                          "pre-compensate the planned stream")


def _chained(first, chunks):
    yield first
    yield from chunks
