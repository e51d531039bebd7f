"""`nurbsinterp plan`: stream one axis command per tick as CSV or binary."""
from __future__ import annotations

import contextlib
import sys

import click

from ..names import PRECOMPENSATION, ROUNDINGS
from .common import (
    CSV_TOO_LARGE_HINT,
    JOB_ARGUMENT,
    MAX_TICKS_HINT,
    MAX_TICKS_OPTION,
    PROGRAM_TOLERANCE_HELP,
    SMOOTH_OPTION,
    LookAheadChoice,
    check_outputs,
    ensure_kernels,
    job_options,
    load,
    output_label,
    say_path_notes,
)
from .precompensate import (
    METHOD_HELP,
    budget_options,
    parse_budgets,
    report,
    shaped,
    shaper,
)


@click.command()
@JOB_ARGUMENT
@job_options
@click.option("--format", "fmt", type=click.Choice(["csv", "bin", "hal"]), default="csv", show_default=True,
              help="CSV text, the self-describing little-endian float64 stream, or HAL lines for LinuxCNC's "
                   "halstreamer (no header, space-separated; columns default to the axes).")
@click.option("--columns", metavar="NAMES",
              help="Write only these columns, in this order (for example x,y or k,x,y,v; default all, "
                   "--format hal the axes).")
@click.option("--resolution", metavar="R",
              help="Round every axis command to the drive's resolution, each tick from the exact one (no drift; "
                   "--rounding shaped: from the exact one and the error carried, within one count): "
                   "a length (1um, 0.0005) or counts per mm (2000/mm); per axis x=0.5um,y=1um.")
@click.option("--counts", is_flag=True, help="With --resolution: write the axes as integer counts (x_counts ...), not mm.")
@click.option("--rounding", type=click.Choice(list(ROUNDINGS)), default="nearest", show_default=True,
              help="With --resolution: nearest (every command within half a count of the exact one) or shaped "
                   "(first-order noise shaping: each moving tick's rounding error carried into the next, at most "
                   "one count, its power moved above the servo's band; for pre-compensated commands).")
@click.option("--hold-start", metavar="D",
              help="With --format hal: write the first command for D more ticks before tick 0 (a duration, "
                   "'0.5 s', '200 ms', or a tick count, '500 ticks'), so that the machine's loops can be enabled on "
                   "a steady command; the held lines keep tick 0's k, which `simulate --actual` and `identify` "
                   "drop.")
@click.option("--precompensate", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Pre-compensate the commands for this servo model (as `precompensate` does, before --resolution).")
@click.option("--precompensate-method", type=click.Choice(list(PRECOMPENSATION)), default="exact",
              show_default=True, help="With --precompensate: " + METHOD_HELP)
@budget_options
@click.option("-o", "--output", metavar="FILE", default="-",
              help="Write here instead of stdout; written atomically (no partial file on failure).")
@click.option("--tolerance", metavar="D",
              help="Plan with look-ahead across the blocks of a program (lines, arcs, NURBS blocks): corners rounded "
                   "by arcs within D (mm or '5 um'; 0: none), per-axis limits held, stops only where the program "
                   "asks. "
                   "A G-code program is read as it is planned, never held whole: its stream has the columns "
                   "x, y, z and rapid whatever its moves. Runs of short moves are refitted as smooth curves "
                   "within D (--no-smooth: not). " + PROGRAM_TOLERANCE_HELP)
@SMOOTH_OPTION
@click.option("-q", "--quiet", is_flag=True, help="No run summary (also skips computing its measures).")
@MAX_TICKS_OPTION
def plan(job, fmt, columns, resolution, counts, rounding, hold_start, servo_file, precompensate_method, voltage_limit,
         accel_limit, output, quiet, max_ticks, tolerance, smooth, **options):
    """Plan the feedrate, interpolate JOB (a YAML job, a G-code program or a DXF drawing) and write one command per tick.

    Columns: k,n,t,u,x,y[,z],v,a (tick, block, s, the block's parameter, mm, mm/s, mm/s²).
    A CSV or binary stream ends with its end mark (nurbsinterp-end ticks=N curve=...),
    written only once every tick is: its readers refuse a stream without it.
    The run summary goes to stderr.

    \b
    nurbsinterp plan curves/circle.yaml > circle.csv
    nurbsinterp plan curves/circle.yaml --interpolator exact --period "250 us" --format bin -o run.bin
    nurbsinterp plan curves/circle.yaml --accdec after | other-tool
    nurbsinterp plan curves/circle.yaml --format hal --resolution 0.5um | halstreamer
    nurbsinterp plan curves/circle.yaml --format hal --columns k,x,y --hold-start "0.5 s" | halstreamer
    nurbsinterp plan curves/circle.yaml --format hal --columns k,x,y --resolution 2000/mm --counts
    nurbsinterp plan curves/circle.yaml --precompensate servo/paper-xy.yaml --format bin -o shaped.bin
    nurbsinterp plan curves/circle.yaml --precompensate servo/paper-xy.yaml --resolution 0.5um --rounding shaped
    """
    from ..errors import UsageError

    if counts and resolution is None:
        raise UsageError("--counts needs --resolution: the size of one count (for example --resolution 0.5um)")
    if rounding != "nearest" and resolution is None:
        raise UsageError(f"--rounding {rounding} needs --resolution: the size of one count (for example "
                         "--resolution 0.5um)")
    if hold_start is not None and fmt != "hal":
        raise UsageError(f"--hold-start {hold_start!r} applies only with --format hal: a CSV or binary stream has one "
                         "row per tick of the plan, which its readers check")
    if hold_start is not None and "k" not in [c.strip() for c in (columns or "").split(",")]:
        raise UsageError(f"--hold-start {hold_start!r} needs the tick column k among --columns (for example "
                         "--columns k,x,y): a capture tells the held lines from the stream by their k")
    if servo_file is None:
        given = [f"--{k.replace('_', '-')}" for k, v in (("voltage_limit", voltage_limit), ("accel_limit", accel_limit))
                 if v is not None]
        if precompensate_method != "exact":
            given.insert(0, "--precompensate-method")
        if given:
            raise UsageError(f"{given[0]} applies only with --precompensate SERVO.yaml")
    choice = LookAheadChoice(job, tolerance, options)
    choice.refuse_smooth(smooth)
    # the look-ahead reads the machine's limits (profile.axes, max_accel ...) whatever the profile type
    # and a program (G-code) as it reads it, block by block, never held whole
    spec = choice.load(job, **options) if choice.on else load(job, **options)
    model = budgets = None
    if servo_file is not None:
        from ..servo import load_servo

        model = load_servo(servo_file)
        budgets = parse_budgets(voltage_limit, accel_limit)
    if choice.on:
        precompensation = None if model is None else (model, precompensate_method, budgets)
        return _look_ahead(spec, job, choice.tolerance, fmt, columns, resolution, counts, output, quiet, max_ticks,
                           [job, options.get("profile_file"), options.get("machine"), servo_file],
                           smooth is not False, precompensation, rounding, hold_start)
    check_outputs(inputs=[job, options.get("profile_file"), options.get("machine"), servo_file], output=output)
    ensure_kernels("plan")
    from ..interpolate import Interpolation
    from ..metrics import Alongside, RunStats
    from ..streams import StreamWriter, is_stdout, open_output
    from .report import progress, summary_lines

    run = Interpolation(spec, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
    hold = _hold_ticks(hold_start, run.period)
    quantiser = None if resolution is None else _quantiser(resolution, run.columns, run.curve.dim, counts, rounding)
    names = run.columns if quantiser is None else quantiser.columns
    select = _select(columns, names, run.columns, fmt, run.curve.dim)
    stats = None if quiet else RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
    dim = run.curve.dim
    shaping = None
    if model is not None:
        from ..names import AXES

        shaping = shaper(model, run.period, AXES[:dim], run.columns, precompensate_method, None, budgets, quiet)
    with open_output(output, output_label("output", output)) as fh, \
            progress(run.ticks_estimate, enabled=not quiet) as advance, \
            contextlib.ExitStack() as measures:
        meta = {}
        if shaping is not None:
            meta["precompensated"] = precompensate_method
        if run.after:  # the stream's u is not its commands' parameter: simulate must not take C(u) for the plan
            meta["accdec"] = "after"
        writer = StreamWriter(fh, names, fmt, fingerprint=spec.path.fingerprint,
                              too_large_hint=CSV_TOO_LARGE_HINT, select=select, meta=meta or None)
        # the summary's measures on the second core while this one interpolates and writes
        alongside = None if stats is None else measures.enter_context(Alongside(stats.update))

        def planned():
            for chunk in run.chunks(derivatives=stats is not None):
                if alongside is not None:
                    alongside.submit(chunk, dim)
                advance(chunk.data.shape[0])
                yield chunk.data

        # the measures take the exact commands; the stream their rounding
        _write(writer, planned() if shaping is None else shaped(planned(), *shaping), quantiser, hold)
        writer.finish()  # only now: a run that fails or is killed leaves a stream its readers refuse
    if is_stdout(output):
        sys.stdout.flush()  # every byte delivered (or the error raised) before the summary claims it
    if stats is not None:
        target = "stdout" if is_stdout(output) else output
        for line in summary_lines(run, stats, target) + _stream_lines(quantiser, hold, run.period, fmt, writer):
            click.echo(line, err=True)
    if shaping is not None:
        report(*shaping, quiet)


def _stream_lines(quantiser, hold, period, fmt, writer) -> list[str]:
    """The summary's lines on the stream as written, whichever planner made it: its rounding to counts, the held
    start, and for HAL the streamer that reads it."""
    lines = []
    if quantiser is not None:
        from .report import quantise_lines

        lines += quantise_lines(quantiser)
    lines += _hold_lines(hold, period)
    if fmt == "hal":
        from ..streams import hal_pin_types

        lines.append(f"  HAL              {' '.join(writer.columns)}: loadrt streamer depth=N "
                     f"cfg={hal_pin_types(writer.columns)} (one pin a column), addf streamer.0 in a thread of "
                     f"period {period * 1e9:.0f} ns")
    return lines


def _quantiser(resolution, stream_columns, dim, counts, rounding):
    from ..errors import UsageError
    from ..names import AXES
    from ..quantise import Quantiser, parse_resolution

    try:
        parsed = parse_resolution(resolution, AXES[:dim])
    except ValueError as exc:
        raise UsageError(f"--resolution {resolution!r}: {exc}") from None
    return Quantiser(parsed, stream_columns, counts, rounding)


MAX_HOLD_START = 3600.0  # s: a start guard longer than an hour is a mistake in the option


def _hold_ticks(text, period) -> int:
    """--hold-start: the ticks the first command is held before tick 0 (a duration rounded up to ticks, or
    'N ticks'); 0 without it."""
    if text is None:
        return 0
    import math
    import re

    from ..config.units import parse_quantity
    from ..errors import UsageError

    m = re.fullmatch(r"\s*(\d+)\s*ticks?\s*", text)
    if m is not None:
        ticks = int(m.group(1))
    else:
        try:
            seconds = parse_quantity(text, "time")
        except ValueError as exc:
            raise UsageError(f"--hold-start {text!r}: {exc} (or a tick count: '500 ticks')") from None
        if not 0 <= seconds <= MAX_HOLD_START:
            raise UsageError(f"--hold-start {text!r}: the hold must be between 0 and {MAX_HOLD_START:g} s")
        ticks = math.ceil(seconds / period - 1e-9)  # a whole number of periods stays itself
    if ticks * period > MAX_HOLD_START:
        raise UsageError(f"--hold-start {text!r}: {ticks} ticks of {period:g} s is more than {MAX_HOLD_START:g} s")
    return ticks


def _hold_lines(hold, period) -> list[str]:
    if not hold:
        return []
    return [f"  start guard      the first command written {hold} more times ({hold * period:.6g} s) before "
            "tick 0, with its k"]


def _write(writer, chunks, quantiser, hold):
    """The chunks of rows to *writer*, rounded by *quantiser* (None: as they are); the first row written *hold*
    more times before them (--hold-start: the command the machine rests on while its loops are enabled), a chunk
    at a time (an hour at 100 us is 3.6e7 lines)."""
    import numpy as np

    from ..interpolate import CHUNK_TICKS

    for rows in chunks:
        out = rows if quantiser is None else quantiser.apply(rows)
        if hold and out.shape[0]:
            held = np.repeat(out[:1], min(hold, CHUNK_TICKS), axis=0)
            while hold:
                m = min(hold, held.shape[0])
                writer.write(held[:m])
                hold -= m
        writer.write(out)


def _select(columns, names, plain, fmt, dim):
    """The indices of the columns to write (None: all), from --columns; names may be given as in *plain* too."""
    from ..errors import UsageError
    from ..names import AXES

    if columns is None:
        if fmt != "hal":
            return None
        return [plain.index(a) for a in AXES[:dim]]
    chosen = []
    for name in columns.split(","):
        name = name.strip()
        if name in names:
            i = names.index(name)
        elif name in plain:
            i = plain.index(name)
        else:
            raise UsageError(f"--columns {columns!r}: {name!r} is not a column of this stream "
                             f"({','.join(names)})")
        if i in chosen:
            raise UsageError(f"--columns {columns!r}: {name!r} is given twice")
        chosen.append(i)
    return chosen


def _look_ahead(spec, job, tolerance, fmt, columns, resolution, counts, output, quiet, max_ticks, inputs, smooth,
                precompensation=None, rounding="nearest", hold_start=None):
    """`plan --tolerance`: the look-ahead pipeline (nurbsinterp.motion) from the job to the stream; with
    *precompensation* (model, method, budgets) its commands pre-compensated as plan's are."""
    check_outputs(inputs=inputs, output=output)
    ensure_kernels("plan --tolerance")
    from ..motion.pipeline import LookAhead
    from ..names import AXES
    from ..streams import StreamWriter, is_stdout, open_output, tolerance_mark

    from ..errors import located

    with located(job):
        run = LookAhead(spec, tolerance, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT, smooth=smooth)
    quantiser = None if resolution is None else _quantiser(resolution, run.columns, run.dim, counts, rounding)
    hold = _hold_ticks(hold_start, run.period)
    names = run.columns if quantiser is None else quantiser.columns
    select = _select(columns, names, run.columns, fmt, run.dim)
    shaping = None
    meta = {"planner": "look-ahead", "tolerance": tolerance_mark(tolerance)}
    if precompensation is not None:
        model, method, budgets = precompensation
        shaping = shaper(model, run.period, AXES[:run.dim], run.columns, method, None, budgets, quiet)
        meta["precompensated"] = method
    with open_output(output, output_label("output", output)) as fh:
        writer = StreamWriter(fh, names, fmt, fingerprint=spec.path.fingerprint, too_large_hint=CSV_TOO_LARGE_HINT,
                              select=select, meta=meta)
        _write(writer, run.chunks() if shaping is None else shaped(run.chunks(), *shaping), quantiser, hold)
        writer.finish()
    if is_stdout(output):
        sys.stdout.flush()
    if hasattr(spec.path, "items"):  # a program read as it ran: what its reader noted is known only now
        say_path_notes(job, spec.path)
    if not quiet:
        from .report import look_ahead_lines

        lines = look_ahead_lines(run, "stdout" if is_stdout(output) else output)
        for line in lines + _stream_lines(quantiser, hold, run.period, fmt, writer):
            click.echo(line, err=True)
    if shaping is not None:
        report(*shaping, quiet)
