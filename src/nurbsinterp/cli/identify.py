"""`nurbsinterp identify`: fit each axis' servo plant to a capture of the machine running a job."""
from __future__ import annotations

import os

import click

from .common import (
    FORCE_HINT,
    MAX_TICKS_HINT,
    MAX_TICKS_OPTION,
    LookAheadChoice,
    check_outputs,
    echo_result,
    ensure_kernels,
    job_options,
    json_text,
    load,
    open_capture,
    output_label,
)

FAMILY_CHOICES = ("lag1", "lag2", "ideal", "hal-lowpass")  # identify.FAMILIES (kept here: --help must not import it)


@click.command()
@click.argument("capture", metavar="CAPTURE", type=click.Path())
@click.option("--job", "job", required=True, metavar="JOB", type=click.Path(),
              help="The job the machine ran (planned here with the same options as the stream sent).")
@click.option("--servo", "servo_file", metavar="START.yaml", type=click.Path(),
              help="A servo file giving each axis' controller (kp, kv, voltage_limit) and a plant to start from.")
@click.option("--pid", "pid", metavar="TERMS",
              help="The controller as LinuxCNC's pid parameters: 'x.Pgain=60,x.FF1=0.95,y.Pgain=90,y.FF1=0.95' "
                   "(a term without an axis sets every axis; maxoutput is the voltage limit).")
@click.option("--capture-columns", "capture_columns", metavar="MAP",
              help="The capture's columns, as simulate --actual-columns: k, sample, x_cmd,y_cmd[,z_cmd], x,y[,z], "
                   "- (ignored). Default k,x_cmd,y_cmd,x,y (3-D: k,x_cmd,y_cmd,z_cmd,x,y,z).")
@click.option("--family", type=click.Choice(FAMILY_CHOICES),
              help="Fit this plant family only (default: every family, the least BIC kept).")
@click.option("--feedback-delay", type=click.Choice(["0", "1"]),
              help="The feedback is sampled before (0) or after (1) the drive's update in the servo period "
                   "(default: both fitted, the better kept). A loop whose controller sees the position later than "
                   "that is outside the servo model: identify says so.")
@job_options
@click.option("-o", "--output", metavar="SERVO.yaml",
              help="Write the fitted model here (a servo file simulate, compare and precompensate take); "
                   "- for stdout (the report then goes to stderr). Written atomically.")
@click.option("--json", "as_json", is_flag=True, help="Print the report as one JSON object on stdout.")
@click.option("--force", is_flag=True,
              help="Fit a capture whose received commands are not the plan's (another plan, or misaligned).")
@MAX_TICKS_OPTION
def identify(capture, job, servo_file, pid, capture_columns, family, feedback_delay, output, as_json, force,
             max_ticks, **options):
    """Identify the servo: fit each axis' plant to what the machine did.

    CAPTURE is a halsampler capture of the machine running JOB's plan, as
    `simulate --actual` reads it (its alignment and refusals: see simulate
    --help), commands and feedback per servo period.  JOB is planned here
    with the given options (they must be the ones the stream was planned
    with); every row of the capture is kept (the commands, then the hold).
    The controller is given, never fitted (positions alone cannot tell a gain
    of the plant from one of the controller): --servo START.yaml (its kp, kv,
    voltage_limit, and its plant to start from) or --pid, LinuxCNC's pid terms
    (with its default error-previous-target: kp = Pgain, kv = FF1 - Pgain*T).

    Each axis' plant is fitted in the families lag1 K a/(s+a), lag2
    K w^2/(s^2+2 z w s+w^2) (the paper's), ideal K (a velocity source), and
    hal-lowpass (HAL's lowpass before integ, exactly), the least BIC kept;
    the encoder's count is detected from the feedback.  The report gives per
    axis the parameters and poles with their standard deviation, the
    residual (RMS, max) and what limited the fit: quantisation (or the
    capture's 6 decimals), noise, the model family (a residual above twice
    the noise in it, estimated from its tick-to-tick scatter: then what
    explains the capture is said on stderr -- another family, the other
    feedback delay, or a controller that sees the position 1 to 4 ticks late,
    which the servo model cannot hold), excitation (a deviation above 0.5 %).
    A capture that cannot determine a model is refused in one line: too
    short, an axis that does not move, a deviation above 2 % (too little
    excitation: capture curves/excitation.yaml), a loop not at rest on the
    first command.  The model (-o) holds at the capture's period only.

    \b
    examples/linuxcnc/stream.sh examples/linuxcnc/sim-machine.hal curves/excitation.yaml > excite.txt
    nurbsinterp identify excite.txt --job curves/excitation.yaml \\
        --pid x.Pgain=60,y.Pgain=90,FF1=0.95 -o fitted.yaml
    nurbsinterp identify run.txt --job curves/excitation.yaml --servo servo/paper-xy.yaml --json
    """
    from ..errors import UsageError

    if (servo_file is None) == (pid is None):
        raise UsageError("identify needs the controller's gains: give --servo START.yaml or --pid TERMS (one of them)"
                         if servo_file is None else "--servo and --pid both give the controller: give one of them")
    if output == "-" and as_json:
        raise UsageError("-o - and --json both want stdout; write the model to a file")
    if os.path.isdir(capture):
        raise UsageError(f"{capture}: is a directory, not a capture")
    # planned as `plan` plans it (the stream a capture of `plan`'s output recorded): a program with look-ahead,
    # within its own G64 P or on the exact path, any other job as one motion
    choice = LookAheadChoice(job, None, options)
    spec = choice.load(job, **options) if choice.on else load(job, **options)
    from ..capture import default_columns, parse_columns

    dim = spec.path.dim
    columns = parse_columns(default_columns(dim) if capture_columns is None else capture_columns, dim,
                            "--capture-columns")
    check_outputs(inputs=[job, servo_file, capture, options.get("profile_file"), options.get("machine")],
                  output=output)
    with open_capture(capture, columns, option=None) as captured:  # refused unreadable before any compiling
        ensure_kernels("identify")
        from .. import identify as fit
        from ..errors import located
        from ..interpolate import Interpolation
        from ..path import job_path

        with located(job):
            if choice.on:
                from ..motion.pipeline import LookAhead

                run = LookAhead(spec, choice.tolerance, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
                chunks = run.chunks()
            else:
                run = Interpolation(spec, job_path(spec), max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
                chunks = (c.data for c in run.chunks())
        record = fit.record(captured, run.columns, chunks, f"{job} (planned)", check_received=not force,
                            hint=FORCE_HINT.replace("simulates", "fits"))
    axes = record.axes
    if servo_file is not None:
        from ..servo import load_servo

        model = load_servo(servo_file)
        missing = [a for a in axes if a not in model.axes]
        if missing:
            raise UsageError(f"--servo {servo_file}: has no axis {missing[0]} (the job has {', '.join(axes)})")
        controllers, source = fit.controllers_of(model), servo_file
    else:
        try:
            controllers = fit.parse_pid(pid, axes, record.period)
        except ValueError as exc:
            raise UsageError(f"--pid {pid!r}: {exc}") from None
        source = f"LinuxCNC pid {pid}"
    result = fit.identify(record, controllers, capture=capture, job=job, controller=source,
                          families=(family,) if family else fit.FAMILIES,
                          delays=(int(feedback_delay),) if feedback_delay else (0, 1))
    lost = [a for a, (_, kept) in result.held.items() if kept is None]
    if output is not None and lost:
        # a servo file drives every axis of the job; one without a plant for a held axis would be refused by
        # every command that reads it
        raise UsageError(f"-o {output}: not written: axis {lost[0]} is {result.held_text(lost[0])}: give --servo "
                         "START.yaml (its model of that axis is kept), or leave out -o to see the fit")
    if output is not None:
        from ..streams import open_output

        with open_output(output, output_label("output", output)) as out:
            out.write(fit.servo_yaml(result).encode())
    if as_json:
        echo_result(json_text({**result.as_dict(), "output": output}))
    else:
        from .report import identify_table

        identify_table(result, output, stderr=output == "-")
    for a, f in result.axes.items():  # a family that does not explain the capture: what does, said after the report
        if f.advice:
            click.echo(f"nurbsinterp: {capture}: axis {a}: {f.advice}", err=True)
