"""`nurbsinterp simulate`: the commands through the servo table, and the contour error they cause."""
from __future__ import annotations

import contextlib
import os
import sys

import click

from .common import (
    FORCE_HINT,
    MAX_TICKS_HINT,
    MAX_TICKS_OPTION,
    PROGRAM_TOLERANCE_HELP,
    PLOT_EXTENSIONS,
    SMOOTH_OPTION,
    LookAheadChoice,
    check_outputs,
    echo_result,
    ensure_kernels,
    job_options,
    json_text,
    load,
    open_capture,
    open_commands,
    option_flag,
    output_label,
    plot_format,
    plot_written,
)


@click.command()
@click.argument("commands", metavar="[COMMANDS|-]", required=False)
@click.option("--job", "job", required=True, metavar="JOB", type=click.Path(),
              help="The job the commands were planned from (its curve measures the contour error).")
@click.option("--plan", "plan_here", is_flag=True,
              help="Plan the job here and simulate that, instead of reading a stream (takes plan's options). "
                   "Without COMMANDS and with stdin a terminal simulate does the same, and says so.")
@click.option("--servo", "servo_file", metavar="SERVO.yaml", type=click.Path(),
              help="Servo model file (default: the paper's X-Y table, as in servo/paper-xy.yaml).")
@job_options
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object on stdout.")
@click.option("--plot", metavar="FILE.png",
              help="Write the path, contour error, feedrate and feedrate error (" + PLOT_EXTENSIONS + ").")
@click.option("-o", "--output", metavar="TRACE.csv",
              help="Write the per-tick trace: commanded and actual axes, contour error, feedrates.")
@click.option("--force", is_flag=True,
              help="Simulate a stream even if it does not look planned from this job (another curve's fingerprint, "
                   "a first point off the path's start), and measure a capture whose received commands are not "
                   "the plan's.")
@click.option("--actual", metavar="CAPTURE", type=click.Path(),
              help="A halsampler capture of the machine running these commands: its true contour error is "
                   "reported beside the model's (see below).")
@click.option("--actual-columns", metavar="MAP",
              help="The capture's columns, comma-separated: k, sample, x_cmd,y_cmd[,z_cmd], x,y[,z], - (ignored). "
                   "Default k,x_cmd,y_cmd,x,y (3-D: k,x_cmd,y_cmd,z_cmd,x,y,z).")
@click.option("--tolerance", metavar="D",
              help="The commands were planned with look-ahead (plan --tolerance D): measure them against the "
                   "program's blocks, read alongside the stream, never held whole (with --plan: plan so). "
                   + PROGRAM_TOLERANCE_HELP)
@click.option("--write-capture", "write_capture", metavar="CAPTURE.txt",
              help="Write the model's own run as a LinuxCNC halsampler capture (k, the commands, the feedback "
                   "positions; one line per tick, the hold included), which identify and simulate --actual read: a "
                   "capture made without HAL. Written atomically; - for stdout (the report then goes to stderr).")
@click.option("--noise", metavar="SIGMA",
              help="With --write-capture: Gaussian noise of this standard deviation added to the feedback positions "
                   "(a length: '0.1um').")
@click.option("--encoder", metavar="RES",
              help="With --write-capture: the feedback positions rounded to multiples of RES after the noise, as an "
                   "encoder reports them ('0.5um'; default: each axis' encoder_resolution in the servo file, if any).")
@click.option("--seed", type=click.IntRange(min=0), metavar="N",
              help="With --write-capture: the seed of the noise (default 0: the same capture every run).")
@SMOOTH_OPTION
@MAX_TICKS_OPTION
def simulate(commands, job, plan_here, servo_file, as_json, plot, output, force, actual, actual_columns, max_ticks,
             tolerance, smooth, write_capture, noise, encoder, seed, **options):
    """Simulate the servo table following a command stream and report its errors.

    COMMANDS is a stream written by `plan` (CSV or binary, detected from its
    content), a file or '-' for stdin (the default).  A stream that is empty,
    or that ends without its end mark (its writer failed or was stopped), is
    refused: an upstream failure never turns into a report.  With --plan, or
    without COMMANDS and with stdin a terminal, simulate plans the job itself
    (saying so on stderr) and takes plan's options.  The report (a table, or JSON with --json) goes to stdout; with -o - the
    trace takes stdout and the table goes to stderr.

    \b
    nurbsinterp plan curves/circle.yaml | nurbsinterp simulate --job curves/circle.yaml
    nurbsinterp simulate --plan --job curves/circle.yaml --accdec after --plot after.png
    nurbsinterp simulate run.bin --job curves/circle.yaml --servo servo/paper-xy.yaml --json
    nurbsinterp simulate run.csv --job curves/circle.yaml --actual capture.txt
    nurbsinterp plan p.ngc --tolerance 5um | nurbsinterp simulate --job p.ngc --tolerance 5um --servo xyz.yaml
    nurbsinterp simulate --plan --job curves/circle.yaml --servo servo/paper-xy.yaml \\
        --write-capture capture.txt --noise 0.1um

    --actual CAPTURE measures the machine's real run of the same commands: a
    LinuxCNC halsampler capture, one line per servo period T of the plan (the
    sampler in the streamer's thread), the values in the order of the
    sampler's cfg (%f floats), its columns named by --actual-columns: k the
    plan's tick sampled back from the streamer, sample halsampler -t's number,
    *_cmd the commands as received, x,y[,z] the feedback positions, - ignored.
    With k: leading rows holding k's first value are dropped but the last,
    which is tick k and must be 0 (if k drops to 0 instead, the pins held an
    earlier stream's tick: all are dropped); k then counts up by 1, and the
    rows holding the last tick are the hold.  Without k: row i is tick i, the
    rows after the last command the hold.  Refused, naming the line: an
    'overrun' line, a gap in sample or k, a wrong count of values, a
    non-number, NaN or inf, a capture that does not cover every command.  The
    hold is measured over as many ticks as both the model and the capture
    have.  The measured feedrate is |p(k) - p(k-1)|/T (0 at the first tick).
    A received command more than 1e-6 mm + 1e-9 |x| from the plan's (%f rounds
    to 5e-7 mm) is refused: another plan or a misaligned capture (--force
    measures it anyway).  JSON gets "measured": {...}; -o adds the columns
    x_meas,y_meas[,z_meas],contour_error_meas,v_meas, one row per measured
    tick; --plot draws the machine beside the model.

    --write-capture CAPTURE writes what halsampler would record of a machine
    that is this model: the columns k,x_cmd,y_cmd[,z_cmd],x,y[,z] (%f), one
    line per tick of the run, the hold rows holding k at the last command's
    tick; --noise adds Gaussian noise to the feedback positions (never to the
    commands, nor to what the model's controller acted on), --encoder then
    rounds them to its count, --seed fixes the noise (default 0).
    """
    from ..errors import UsageError

    if plan_here and commands is not None:
        raise UsageError(f"--plan plans the job here: it reads no COMMANDS stream (got {commands!r})")
    # planning here only when asked plainly: an empty pipe is a failed upstream command, never a cue
    self_planned = plan_here or (commands is None and _stdin_is_terminal())
    from_stdin = not self_planned and commands in (None, "-")
    given = [option_flag(k) for k, v in options.items() if v is not None]
    if given and not self_planned:
        raise UsageError(f"{given[0]} applies only when simulate plans the job itself (--plan); "
                         "the stream was planned already")
    trace_on_stdout = output == "-" or write_capture == "-"
    if trace_on_stdout and as_json:
        raise UsageError(f"{'-o' if output == '-' else '--write-capture'} - and --json both want stdout; write the "
                         f"{'trace' if output == '-' else 'capture'} to a file")
    recording = _recording(write_capture, noise, encoder, seed, output, actual)
    if actual_columns is not None and actual is None:
        raise UsageError("--actual-columns applies only with --actual CAPTURE")
    if actual == "-":
        raise UsageError("--actual -: the capture is read from a file (stdin may carry the commands)")
    choice = LookAheadChoice(job, tolerance, options)
    choice.refuse_smooth(smooth, "--tolerance D and --plan")
    if smooth is not None and not self_planned:
        raise UsageError(f"--{'' if smooth else 'no-'}smooth applies only with --plan (a stream read is "
                         "smoothed as it was planned)")
    # a look-ahead plan: the job's program read as the stream advances, never whole
    spec = choice.load(job, **options) if choice.on else load(job, **options)
    from ..servo import load_servo

    model = load_servo(servo_file)
    if recording is not None:  # the feedback as --encoder counts it, else as each axis' own encoder does
        count = recording["encoder"]
        recording["encoder"] = {a: count or ax.encoder_resolution for a, ax in model.axes.items()}
    capture_map = None
    if actual is not None:
        from ..capture import default_columns, parse_columns

        dim = spec.path.dim
        capture_map = parse_columns(default_columns(dim) if actual_columns is None else actual_columns, dim,
                                    "--actual-columns")
    check_outputs(inputs=[job, servo_file, commands, options.get("profile_file"), options.get("machine"), actual],
                  output=output, plot=plot, write_capture=write_capture)
    if commands not in (None, "-") and os.path.isdir(commands):
        raise UsageError(f"{commands}: is a directory, not a command stream")
    with contextlib.ExitStack() as stack:
        capture = None
        if actual is not None:
            capture = stack.enter_context(open_capture(actual, capture_map))
        if choice.on:
            report, series = _simulate_look_ahead(spec, model, job, commands, from_stdin, self_planned, output,
                                                  plot, force, max_ticks, choice.tolerance, smooth is not False,
                                                  capture, recording)
            curve = None  # the program's path is drawn through the feet the series keeps
        else:
            report, series, curve = _simulate(spec, model, job, commands, from_stdin, self_planned, output, plot,
                                              force, max_ticks, capture, recording)
    if plot:
        from ..plots import plot_simulation

        plot_simulation(plot, series, report.axes, curve, report, _title(job, spec, model, report, self_planned, choice),
                        plot_format(plot), output_label("plot", plot))
        plot_written(plot)
    _say(report, job, as_json, trace_on_stdout, self_planned, plan_here)


def _recording(write_capture, noise, encoder, seed, output, actual):
    """--write-capture's settings (CaptureWriter's keywords and the path), None without it; the options that need it
    refused without it."""
    from ..errors import UsageError
    from .common import parse_length

    if write_capture is None:
        for option, value in (("--noise", noise), ("--encoder", encoder), ("--seed", seed)):
            if value is not None:
                raise UsageError(f"{option} applies only with --write-capture CAPTURE.txt (it shapes the capture's "
                                 "feedback positions)")
        return None
    if actual is not None:
        raise UsageError("--write-capture writes the model's own run as a capture: give it without --actual (then "
                         "measure the capture it wrote with simulate --actual)")
    if output == "-" and write_capture == "-":
        raise UsageError("-o - and --write-capture - both want stdout; write one of them to a file")
    return {"path": write_capture, "noise": 0.0 if noise is None else parse_length("--noise", noise),
            "encoder": None if encoder is None else parse_length("--encoder", encoder, zero=False),
            "seed": 0 if seed is None else seed}


def _say(report, job, as_json, trace_on_stdout, self_planned, plan_here):
    """The report on stdout (stderr when the trace takes stdout), then how the commands came about."""
    if as_json:
        echo_result(json_text({**report.as_dict(), "job": job}))
    else:
        from .report import servo_table

        servo_table(report, job, stderr=trace_on_stdout)
    if self_planned:  # said once the report is delivered, so that a refusal or a failed write stays one line
        why = "--plan" if plan_here else "no COMMANDS and stdin is a terminal"
        click.echo(f"nurbsinterp: simulate planned {job} itself ({why}): no stream was read", err=True)


def _simulate_look_ahead(spec, model, job, commands, from_stdin, self_planned, output, plot, force, max_ticks,
                         tolerance, smooth=True, capture=None, recording=None):
    """A look-ahead plan (planned here, or read) through the servo, measured against the program's blocks:
    (report, series)."""
    ensure_kernels("simulate --tolerance")
    from ..errors import SpecError, located
    from ..motion.pipeline import LookAhead, program_window

    def window():  # the model's and the capture's each read the program as far as their own positions need
        try:
            return program_window(spec, tolerance, job)
        except ValueError as exc:
            raise SpecError(f"{job}: {exc}") from None

    windows = {"window": window(), "measured_window": None if capture is None else window()}
    if self_planned:
        with located(job):
            run = LookAhead(spec, tolerance, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT, smooth=smooth)
        return _run(spec, None, model, run.columns, run.chunks(), f"{job} (planned)", output, plot, {}, True,
                    max_ticks, capture, force, recording=recording, **windows)
    with open_commands(None if from_stdin else commands) as fh:
        from ..simulation import check_look_ahead_stream
        from ..streams import read_stream

        name = "<stdin>" if from_stdin else commands
        meta = {}
        columns, chunks = read_stream(fh, name, meta=meta)
        if not force:
            chunks = check_look_ahead_stream(spec.path.fingerprint, chunks, meta, name, FORCE_HINT, tolerance)
        report, series = _run(spec, None, model, columns, chunks, name, output, plot, meta, True, max_ticks, capture,
                              force, recording=recording, **windows)
    return _precompensated(report, meta), series


def _simulate(spec, model, job, commands, from_stdin, self_planned, output, plot, force, max_ticks, capture,
              recording=None):
    """Plan or read the commands and run them: (report, series, curve)."""
    ensure_kernels("simulate")
    from ..errors import located
    from ..path import job_path

    with located(job):
        path = job_path(spec)  # the arc-length table: refused here, naming the job, if it cannot be built
    curve = path.programmed
    if self_planned:
        from ..interpolate import Interpolation

        run = Interpolation(spec, path, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
        columns, chunks, name = run.columns, (c.data for c in run.chunks()), f"{job} (planned)"
        report, series = _run(spec, path, model, columns, chunks, name, output, plot, {}, True, max_ticks, capture,
                              force, against_plan=False, recording=recording)
    elif from_stdin:
        with open_commands(None) as fh:
            report, series = _read_and_run(spec, path, model, fh, "<stdin>", output, plot, force, max_ticks, capture,
                                           recording)
    else:
        with open_commands(commands) as fh:
            report, series = _read_and_run(spec, path, model, fh, commands, output, plot, force, max_ticks, capture,
                                           recording)
    return report, series, curve


def _title(job, spec, model, report, self_planned, choice) -> str:
    if choice.on:
        what = (f"look-ahead within {choice.words()}, {spec.profile.type} profile, " if self_planned
                else f"a look-ahead stream (within {choice.words()}), ")
    elif self_planned:
        what = (f"{spec.interpolator.method}, {spec.profile.type} acc/dec {spec.profile.accdec} interpolation, "
                f"F = {spec.profile.feedrate:g} mm/s, ")
    else:
        what = "a planned stream, "
    return f"{job}: {what}T = {report.period * 1e3:g} ms, servo {model.source}"


def _stdin_is_terminal() -> bool:
    """Whether stdin is a terminal (a person at it, no stream piped in)."""
    return sys.stdin is not None and sys.stdin.isatty()


def _read_and_run(spec, path, model, fh, name, output, plot, force, max_ticks, capture=None, recording=None):
    from ..streams import read_stream

    meta = {}
    columns, chunks = read_stream(fh, name, meta=meta)
    report, series = _run(spec, path, model, columns, chunks, name, output, plot, meta, force, max_ticks, capture,
                          force, recording=recording)
    return _precompensated(report, meta), series


def _precompensated(report, meta):
    """The report naming the pre-compensation the stream's header names, if any."""
    if "precompensated" not in meta:
        return report
    import dataclasses

    return dataclasses.replace(report, precompensated=meta["precompensated"])


def _run(spec, path, model, columns, chunks, name, output, plot, meta, force, max_ticks, capture=None,
         force_received=False, window=None, measured_window=None, against_plan=None, recording=None):
    from ..simulation import check_stream_belongs, trace_columns
    from ..simulation import simulate as run_simulation
    from ..streams import StreamWriter, open_output

    if window is None and meta.get("planner") == "look-ahead":  # its header says so, before anything else
        from ..errors import StreamError

        raise StreamError(f"{name}: the stream was planned with look-ahead across the blocks (plan --tolerance): "
                          "simulate it with --tolerance as it was planned")
    if not force:
        chunks = check_stream_belongs(path.programmed, spec.path.fingerprint, columns, chunks, meta, name, FORCE_HINT)
    # a capture adds its keywords, a program's window its own; without them the call is what it always was
    extra = {} if capture is None else dict(actual=capture, check_received=not force_received,
                                            force_hint=FORCE_HINT.replace("simulates", "measures"))
    if window is not None:
        extra.update(window=window, measured_window=measured_window)
    elif against_plan is not False:
        # a pre-compensated stream's tracking error is against the plan, not its shaped commands; a binary
        # stream's header says up front whether it is one, a CSV stream's end mark only once it is read
        # (an acc/dec-after stream's u is the curve's before the filter: its C(u) is not the plan's command)
        if "precompensated" in meta or "curve" not in meta:
            extra["against_plan"] = lambda: "precompensated" in meta and meta.get("accdec") != "after"
    axes = [a for a in ("x", "y", "z") if a in columns]
    traces = []  # the trace's consumers, each fed every chunk as it is simulated
    with contextlib.ExitStack() as files:  # every file renamed into place only when the whole run succeeded
        if output is not None:
            fh = files.enter_context(open_output(output, output_label("output", output)))
            traces.append(StreamWriter(fh, trace_columns(axes, measured=capture is not None), "csv").write)
        if recording is not None:
            from ..capture import CaptureWriter

            target = recording["path"]
            fh = files.enter_context(open_output(target, output_label("write_capture", target)))
            recorder = CaptureWriter(fh, trace_columns(axes), recording["noise"], recording["encoder"],
                                     recording["seed"])
            chunks = recorder.through(chunks)  # where the commands end: the trace's rows past them are the hold
            traces.append(recorder.write)

        def trace(rows):
            for consume in traces:
                consume(rows)

        return run_simulation(path, model, columns, chunks, name=name, trace=trace if traces else None,
                              keep_series=bool(plot),
                              max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT, **extra)
