"""Options and helpers shared by the subcommands.

Only click is imported here: the library (numpy, numba) loads inside the
functions that need it, so that --help and --version stay fast.
"""
from __future__ import annotations

import contextlib
import os
import sys

import click

from ..names import ACCDEC, METHODS, PROFILE_TYPES

JOB_ARGUMENT = click.argument("job", metavar="JOB", type=click.Path(dir_okay=True))
INPUT_FORMATS = ("yaml", "gcode", "dxf")  # the readers of config.readers (kept here: --help must not import them)


def job_options(func):
    """The options that override fields of the job file (every field of profile and interpolator)."""
    options = [
        click.option("--profile", "profile_file", metavar="FILE", type=click.Path(),
                     help="YAML file with 'profile' and/or 'interpolator' sections overriding the job's."),
        click.option("--profile-type", type=click.Choice(list(PROFILE_TYPES)),
                     help="Feedrate profile (profile.type); 'adaptive' schedules it along the curve from the limits."),
        click.option("--feedrate", metavar="F",
                     help="Peak feedrate: mm/s, or with a unit ('6000 mm/min'); overrides a program's F words too."),
        click.option("--rapid-feedrate", metavar="F", help="Feedrate of rapid (G0) moves (default 10000 mm/min)."),
        click.option("--accel-time", metavar="TA", help="Acc/dec time: s, or with a unit ('500 ms')."),
        click.option("--time-constant", metavar="TAU", help="Exponential time constant (default accel_time/4)."),
        click.option("--accdec", type=click.Choice(list(ACCDEC)),
                     help="Acc/dec before interpolation (default) or after it (the conventional filter)."),
        click.option("--interpolator", type=click.Choice(list(METHODS)),
                     help="Interpolator (interpolator.method)."),
        click.option("--period", metavar="T", help="Sampling period: s, or with a unit ('1 ms', '250 us')."),
        click.option("--chord-tolerance", metavar="D", help="Adaptive: largest chord error, mm or '1 um'."),
        click.option("--max-accel", metavar="A",
                     help="Adaptive: acceleration limit, mm/s^2: tangential, and centripetal unless --max-normal-accel."),
        click.option("--max-jerk", metavar="J", help="Adaptive: tangential jerk limit, mm/s^3."),
        click.option("--max-normal-accel", metavar="AN",
                     help="Adaptive: centripetal acceleration limit, mm/s^2 (default: the --max-accel limit)."),
        click.option("--axis-max-velocity", metavar="X=V,...",
                     help="Adaptive: per-axis velocity limits (profile.axes), mm/s or with a unit: 'x=60,y=60'."),
        click.option("--axis-max-accel", metavar="X=A,...",
                     help="Adaptive: per-axis acceleration limits (profile.axes), mm/s^2 or with a unit: 'x=800,y=800'."),
        click.option("--axis-max-jerk", metavar="X=J,...",
                     help="Look-ahead (a path of several blocks, or --tolerance): per-axis jerk limits "
                          "(profile.axes), mm/s^3 or with a unit: "
                          "'x=20000,y=20000'."),
        click.option("--corner-tolerance", metavar="D",
                     help="How far a corner blend may leave the path where a block states no tolerance (a path of "
                          "several blocks: every profile), mm or '10 um' (none: the exact path)."),
        click.option("--machine", metavar="FILE.ini", type=click.Path(),
                     help="A LinuxCNC INI file: per-axis limits from [AXIS_X] MAX_VELOCITY/MAX_ACCELERATION "
                          "(and MAX_JERK on the look-ahead), "
                          "G0 speed from [TRAJ] MAX_LINEAR_VELOCITY (--axis-max-* and --rapid-feedrate win)."),
    ]
    for option in reversed(options):
        func = option(func)
    return reader_options(func)


def reader_options(func):
    """The options of the readers of G-code and DXF (and --input-format)."""
    options = [
        click.option("--input-format", type=click.Choice(list(INPUT_FORMATS)),
                     help="Read JOB as this format whatever its suffix (.yaml/.yml, .ngc/.nc/.gcode/.tap/.cnc, .dxf)."),
        click.option("--start", metavar="X,Y[,Z]",
                     help="G-code: where the tool is when the program starts, mm (default the origin, as rs274)."),
        click.option("--g28", metavar="X,Y,Z",
                     help="G-code: the stored position G28 goes to, mm in machine coordinates (default the origin)."),
        click.option("--g30", metavar="X,Y,Z",
                     help="G-code: the stored position G30 goes to, mm in machine coordinates (default the origin)."),
        click.option("--layer", metavar="NAME", help="DXF: read only the entities of this layer."),
        click.option("--chain", metavar="N", type=click.IntRange(min=1),
                     help="DXF: plan only chain N (as `info` numbers them; default every chain, joined by rapids)."),
        click.option("--chain-tolerance", metavar="D",
                     help="DXF: largest gap between entities that still chain, mm or '1 um'."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


MAX_TICKS_OPTION = click.option(
    "--max-ticks", type=click.IntRange(min=1), default=100_000_000, show_default=True, metavar="N",
    help="Refuse a job that would take more ticks than this (simulate: the commands and the settle hold together).")
SMOOTH_OPTION = click.option(
    "--smooth/--no-smooth", default=None,
    help="With --tolerance: refit runs of short moves as cubic B-splines within the tolerance (the default), or "
         "blend every corner by an arc only.")
MAX_TICKS_HINT = " (--max-ticks)"  # how a refusal tells the user to raise the limit
FORCE_HINT = " (--force simulates it anyway)"  # after simulate's refusal of a stream from another job
CSV_TOO_LARGE_HINT = "; use --format bin"  # after plan's refusal of a value too large for CSV
#: the output path problems whose message spells the -o option out in full (the path alone reads badly)
SPELLED_OUT = ("empty", "cannot-create", "cannot-replace")


#: command-line option (its Python name) -> the job field it overrides
OVERRIDE_FIELDS = {
    "profile_type": "profile.type",
    "feedrate": "profile.feedrate",
    "accel_time": "profile.accel_time",
    "time_constant": "profile.time_constant",
    "accdec": "profile.accdec",
    "interpolator": "interpolator.method",
    "period": "interpolator.period",
    "chord_tolerance": "profile.chord_tolerance",
    "max_accel": "profile.max_accel",
    "max_jerk": "profile.max_jerk",
    "max_normal_accel": "profile.max_normal_accel",
    "corner_tolerance": "profile.corner_tolerance",
    "rapid_feedrate": "profile.rapid_feedrate",
}
#: command-line options that set one limit of several axes ('x=800,y=800'): option -> key of profile.axes.AXIS
AXIS_OPTIONS = {"axis_max_velocity": "max_velocity", "axis_max_accel": "max_accel", "axis_max_jerk": "max_jerk"}
#: command-line options that are a reader's own settings (config.readers), not job fields
READER_OPTIONS = ("start", "g28", "g30", "layer", "chain", "chain_tolerance")


def load_cli(job, profile_file=None, overrides=None, input_format=None, reader_options=None, every_profile=False,
             stream=False):
    """Load the job with the command-line overrides ``{option name: value}`` applied; messages name the option.

    An option the job's profile ignores is refused (config.job.unused_fields), unless the command plans
    every profile (*every_profile*: compare, bench).  What the reader has to say of the file (codes it
    ignored, moves it dropped) goes to stderr, once; the fields of a file that go unused are said once the
    run has succeeded (:func:`say_notes`), so that a later refusal stays the one line on stderr."""
    from ..config import load_job

    watch_kernels()
    overrides = dict(overrides or {})
    machine = overrides.pop("machine", None)
    per_axis = {option: overrides.pop(option) for option in AXIS_OPTIONS if option in overrides}
    fields = {OVERRIDE_FIELDS[option]: (value, "--" + option.replace("_", "-")) for option, value in overrides.items()}
    for option, text in per_axis.items():
        if text is not None:
            for axis, value in _axis_values("--" + option.replace("_", "-"), text).items():
                fields[f"profile.axes.{axis}.{AXIS_OPTIONS[option]}"] = (value, "--" + option.replace("_", "-"))
    limits = None
    if machine is not None:
        from ..config.machine_ini import read_machine

        limits = read_machine(machine)
        # below the options (a field an option gives keeps the option's value), above the job's files
        for dotted, value in _machine_fields(limits, stream).items():
            if fields.get(dotted, (None,))[0] is None:
                fields[dotted] = value
    spec = load_job(job, profile_file=profile_file, overrides=fields, input_format=input_format,
                    reader_options=_reader_options(reader_options or {}), every_profile=every_profile,
                    stream=stream)
    say_path_notes(job, spec.path)
    ctx = click.get_current_context(silent=True)
    if ctx is not None:
        notes = ctx.find_root().meta.setdefault(NOTES, [])
        notes.extend(spec.notes)
        if limits is not None:
            notes.extend(_machine_notes(limits, spec, stream))
    return spec


def _machine_fields(limits, stream=False) -> dict:
    """The job fields a LinuxCNC INI file's limits set: {dotted field: (value in mm and s, where it was read)}.
    MAX_JERK counts where the look-ahead plans (*stream*): the adaptive profile holds no per-axis jerk."""
    fields = {}
    for axis in limits.axes:
        fields[f"profile.axes.{axis.axis}.max_velocity"] = (axis.max_velocity.value, axis.max_velocity.where)
        fields[f"profile.axes.{axis.axis}.max_accel"] = (axis.max_accel.value, axis.max_accel.where)
        if stream and axis.max_jerk is not None:
            fields[f"profile.axes.{axis.axis}.max_jerk"] = (axis.max_jerk.value, axis.max_jerk.where)
    if limits.max_linear_velocity is not None:  # LinuxCNC runs G0 at it (the axes capping it)
        fields["profile.rapid_feedrate"] = (limits.max_linear_velocity.value, limits.max_linear_velocity.where)
    return fields


def _machine_notes(limits, spec, stream=False) -> list:
    """What the INI file gives that this run does not apply, said once it has succeeded."""
    notes = [f"{axis.max_jerk.where} = {axis.max_jerk.value:g} mm/s^3 is not applied: a per-axis jerk limit is "
             "held by the look-ahead planner only (--tolerance)" for axis in limits.axes
             if axis.max_jerk is not None and not stream]
    period = limits.servo_period
    if period is not None and abs(period.value - spec.interpolator.period) > 1e-12 * spec.interpolator.period:
        notes.append(f"{period.where} = {period.value * 1e3:g} ms is not applied: the stream's period is "
                     f"{spec.interpolator.period * 1e3:g} ms (interpolator.period, --period)")
    return notes


def _axis_values(option: str, text: str) -> dict:
    """'x=800, y=1 m/s^2' -> {'x': '800', 'y': '1 m/s^2'}: the values as written (the job's rules read them)."""
    from ..errors import UsageError
    from ..names import AXES

    out = {}
    for item in str(text).split(","):
        axis, sep, value = (part.strip() for part in item.partition("="))
        if not sep or not value:
            raise UsageError(f"{option} {text!r}: {item.strip()!r} is not AXIS=VALUE (for example {option} x=800,y=800)")
        if axis not in AXES:
            raise UsageError(f"{option} {text!r}: {axis!r} is not an axis (one of {', '.join(AXES)})")
        if axis in out:
            raise UsageError(f"{option} {text!r}: axis {axis} is given twice")
        out[axis] = value
    return out


NOTES = "nurbsinterp.notes"  # the click context's meta key of the notes said after a successful run


def say_path_notes(job, path) -> None:
    """What the reader noted of the job's path, one line each on stderr, where the reader asks for a value
    the CLI takes as an option, naming that option."""
    from ..config.gcode.machine import HOME_HINT

    hints = {HOME_HINT.format(code=code): f"its {code} position with --{code.lower()} X,Y,Z" for code in ("G28", "G30")}
    for note in path.notes:
        for hint, option in hints.items():
            note = note.replace(hint, option)
        click.echo(f"nurbsinterp: {job}: {note}", err=True)


def say_notes(ctx) -> None:
    """The notes the command gathered (load_cli), one line each on stderr: after the run, which succeeded."""
    for note in ctx.meta.get(NOTES, ()):
        click.echo(f"nurbsinterp: {note}", err=True)


def _reader_options(options: dict) -> dict:
    """The reader options in the library's terms: --start as numbers, --chain-tolerance in mm."""
    from ..config import parse_quantity
    from ..config.readers import reader_point
    from ..errors import UsageError

    out = dict(options)
    for key, sizes, shape, example in (("start", (2, 3), "X,Y or X,Y,Z", "0,0,5"), ("g28", (3,), "X,Y,Z", "0,0,50"),
                                       ("g30", (3,), "X,Y,Z", "0,0,50")):
        if out.get(key) is None:
            continue
        values = reader_point(out[key], sizes)
        if values is None:
            raise UsageError(f"--{key} {out[key]!r}: give {shape} in mm (for example --{key} {example})")
        out[key] = values
    if out.get("chain_tolerance") is not None:
        try:
            out["chain_tolerance"] = parse_quantity(out["chain_tolerance"], "length")
        except ValueError as exc:
            raise UsageError(f"--chain-tolerance {out['chain_tolerance']!r}: {exc}") from None
        if not out["chain_tolerance"] >= 0:
            raise UsageError(f"--chain-tolerance {options['chain_tolerance']!r}: must be >= 0")
    return out


def load(job, profile_file=None, input_format=None, every_profile=False, stream=False, **overrides):
    """Load the job with the command-line overrides (job fields and reader options) applied."""
    reader = {key: overrides.pop(key) for key in READER_OPTIONS if key in overrides}
    return load_cli(job, profile_file, overrides, input_format, reader, every_profile, stream)


def parse_tolerance(text):
    """--tolerance D in mm (a length >= 0; a bare number is mm, and said so after the run)."""
    return parse_length("--tolerance", text)


def parse_length(option: str, text, zero: bool = True) -> float:
    """A length option's value in mm ('0.1um', '0.0005 mm'): refused in one line naming *option* and the value where
    it is not a finite length >= 0 (> 0 unless *zero*).  A bare number is mm, and said so after the run, as
    --tolerance's."""
    from ..config.units import is_bare_number, parse_quantity
    from ..errors import UsageError

    try:
        value = parse_quantity(text, "length")
    except ValueError as exc:
        raise UsageError(f"{option} {text!r}: {exc}") from None
    if not (value >= 0.0 if zero else value > 0.0) or value == float("inf"):
        raise UsageError(f"{option} {text!r}: must be a finite length {'>=' if zero else '>'} 0 (for example "
                         f"{option} 0.5um)")
    ctx = click.get_current_context(silent=True)
    if ctx is not None and value > 0.0 and is_bare_number(text):
        ctx.find_root().meta.setdefault(NOTES, []).append(
            f"{option} {text} has no unit: taken as {value:g} mm = {value * 1000.0:g} um (write the unit you mean: "
            f"{text}mm, {text}um)")
    return value


#: what every command's --tolerance help says of a program without it (motion.pipeline.plans_with_look_ahead)
PROGRAM_TOLERANCE_HELP = ("Without it, a G-code program, a drawing or a YAML path of several blocks is planned "
                          "with look-ahead all the same: within its own tolerance (G64 P, a block's mode, "
                          "profile.corner_tolerance), block by block, and on the exact path where it states none "
                          "(its corners passed unblended at the speed the axes allow).")


class LookAheadChoice:
    """How a command plans its job: with look-ahead across the blocks or not, within what tolerance.

    ``--tolerance D``: the look-ahead within D, overriding the program's own.  Without it, a job of several blocks
    (a G-code program, a drawing, a YAML path) is planned with look-ahead within its own tolerance, block by block,
    on the exact path where it states none: the motion the program asks a controller for
    (motion.pipeline.plans_with_look_ahead).  A curve (one block) is the paper's motion from rest to rest.  ``tolerance`` is the library's (mm; None: the
    program's own); ``spec`` the job loaded as a stream when the choice read it (a second load saved), else
    None."""

    def __init__(self, job, text, options):
        self.spec = None
        self.tolerance = None
        self.on = text is not None
        if self.on:
            self.tolerance = parse_tolerance(text)
            return
        from ..config.readers import format_of
        from ..errors import located
        from ..motion.pipeline import plans_with_look_ahead

        fmt = format_of(str(job), options.get("input_format"))
        # loaded outside located(job): an error of another file (--machine's INI) names that file alone
        spec = load(job, every_profile=True, stream=True, **options)
        with located(job):
            self.on, _ = plans_with_look_ahead(None, fmt, lambda: spec)
        self.spec = spec if self.on else None

    def refuse_smooth(self, smooth, needs="--tolerance D (the look-ahead)"):
        """--smooth/--no-smooth given where nothing is planned with look-ahead: refused, saying what it needs."""
        from ..errors import UsageError

        if smooth is not None and not self.on:
            raise UsageError(f"--{'' if smooth else 'no-'}smooth applies only with {needs}")

    def load(self, job, **options):
        """The job as the look-ahead reads it (a stream, every profile's fields)."""
        return self.spec if self.spec is not None else load(job, every_profile=True, stream=True, **options)

    def words(self) -> str:
        """The tolerance as a title says it."""
        return "the program's own G64 P" if self.tolerance is None else f"{self.tolerance * 1e3:g} um"


#: the picture formats --plot writes, by file extension (matplotlib's Agg, SVG, PDF and PS back ends)
PLOT_FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf", ".jpg": "jpeg", ".jpeg": "jpeg", ".eps": "eps",
                ".ps": "ps", ".tif": "tiff", ".tiff": "tiff", ".webp": "webp"}
PLOT_EXTENSIONS = ", ".join(ext[1:] for ext in PLOT_FORMATS)  # the one list --help, README and errors give


def plot_written(path) -> None:
    """Say on stderr where the picture went (stdout may be carrying the result)."""
    click.echo(f"nurbsinterp: plot written to {path}", err=True)


def check_outputs(inputs=(), **paths) -> None:
    """Refuse, before any work, every output path that cannot be written; each message names its option.

    paths maps an option's name without dashes ('output' is -o, 'plot' is --plot) to the path given.
    """
    from ..errors import OutputPathError, UsageError
    from ..streams import check_output_path

    files = [(key, os.path.abspath(p)) for key, p in paths.items() if p is not None and p != "-"]
    for i, (key, full) in enumerate(files):
        for other, full2 in files[i + 1:]:
            if full == full2:
                raise UsageError(f"{_option(key)} and {_option(other)} name the same file {paths[key]}")
    for key, path in paths.items():
        if path is None:
            continue
        option = _option(key)
        if key == "plot":
            if path == "-":
                raise UsageError("--plot -: a picture is written to a file, not to stdout")
            ext = os.path.splitext(path)[1].lower()
            if ext not in PLOT_FORMATS:
                raise UsageError(f"--plot {path}: unknown picture format {ext or '(no extension)'!r}; "
                                 f"use one of {PLOT_EXTENSIONS}")
        try:
            check_output_path(path, inputs=[i for i in inputs if i])
        except OutputPathError as exc:
            long = " (--output)" if key == "output" and exc.kind in SPELLED_OUT else ""
            raise UsageError(f"{option} {exc.name}{long}: {exc.problem}") from None


def _option(key: str) -> str:
    return "-o" if key == "output" else f"--{key.replace('_', '-')}"


def option_flag(name: str) -> str:
    """The option a user types for the running command's parameter *name* (``profile_file`` is ``--profile``):
    its longest flag, from click's own declaration, so that a message never names an option that does not
    exist."""
    ctx = click.get_current_context(silent=True)
    for param in ctx.command.params if ctx is not None else ():
        if param.name == name and getattr(param, "opts", None):
            return max(param.opts, key=len)
    return f"--{name.replace('_', '-')}"


def output_label(key: str, path) -> str:
    """How an error while writing names the output *path* given to option *key* (as check_outputs' keys)."""
    return f"{_option(key)} {path}"


def plot_format(path) -> str:
    return PLOT_FORMATS[os.path.splitext(path)[1].lower()]


def open_commands(commands):
    """A context manager on the command stream COMMANDS: stdin's bytes for None or '-', else the file, opened
    (a directory or an unreadable file is refused in one line)."""
    import contextlib
    import io

    from ..errors import UsageError

    if commands in (None, "-"):
        if sys.stdin is None:  # fd 0 closed: as an empty stream
            return contextlib.nullcontext(io.BytesIO())
        return contextlib.nullcontext(sys.stdin.buffer)
    if os.path.isdir(commands):
        raise UsageError(f"{commands}: is a directory, not a command stream")
    try:
        return open(commands, "rb")
    except OSError as exc:
        raise UsageError(f"{commands}: cannot read: {exc.strerror or exc}") from None


def watch_kernels(command: str | None = None) -> None:
    """Say on stderr what the run compiles, from now on (report.COMPILES): called before the job is read (a
    reader builds curves with kernels too) and again by :func:`ensure_kernels`, which names the command's
    estimate.  *command* defaults to the subcommand's name."""
    from .._cache import kernels_warm
    from ..warmup import first_run_estimate, watch_compiles
    from .report import COMPILES

    if command is None:
        ctx = click.get_current_context(silent=True)
        command = ctx.info_name if ctx is not None else "nurbsinterp"
    COMPILES.begin(command, first_run_estimate(command), kernels_warm())
    watch_compiles(COMPILES.on_compile, COMPILES.on_idle)


def ensure_kernels(command: str) -> None:
    """The kernels *command* calls load from the cache as the run reaches them; those not yet compiled for this
    version are compiled then, and only they (never another command's), said on stderr while it lasts
    (:func:`watch_kernels`; *command* names the estimate of the count: warmup.first_run_estimate)."""
    watch_kernels(command)
    # numba's own initialisation on the first call of any kernel (its typing registries: some 0.5 s) is start-up,
    # paid here once, not inside the run whose time a summary reports (the look-ahead's "first ticks after")
    try:  # (numba's own internals: a cost moved earlier, never a failure; calling a kernel here would compile a
        # signature of its own, which the first-run test catches)
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()
    except Exception:  # noqa: BLE001
        pass


def compile_everything(force: bool = False, check: bool = False) -> dict:
    """Compile the kernels of every command (warmup.warm_up, on every core) where they are not all compiled yet,
    saying so on stderr; marks the cache warm.  *check*: where they are, run the warm-up all the same in this
    process (it loads them, and counts what it compiled: none, unless the cache lost some).  Returns warm_up's
    result and "already_warm"."""
    from .._cache import kernels_warm, mark_warm
    from ..warmup import warm_up
    from .report import warmup_progress

    if kernels_warm() and not force:
        return {**(warm_up() if check else {"seconds": 0.0, "compiled": 0}), "already_warm": True}
    with warmup_progress("nurbsinterp: compiling the numeric kernels of every command, once for this version "
                         "(about 2 minutes on 2 cores)") as progress:
        result = warm_up(progress, jobs=os.cpu_count() or 1)
    mark_warm()
    return {**result, "already_warm": False}


def echo_result(text: str) -> None:
    """The command's result on stdout (a table or JSON), written whole or failing loudly."""
    click.echo(text)
    sys.stdout.flush()


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


@contextlib.contextmanager
def open_capture(actual, columns, option="--actual"):
    """The capture file *actual* as a :class:`~nurbsinterp.capture.Capture` read by the column map *columns*,
    closed on leaving; refused in one line naming *option* (None: an argument) when it is a directory or cannot
    be read."""
    from ..capture import Capture
    from ..errors import UsageError

    where = actual if option is None else f"{option} {actual}"
    if os.path.isdir(actual):
        raise UsageError(f"{where}: is a directory, not a capture")
    try:
        fh = open(actual, "rb")
    except OSError as exc:
        raise UsageError(f"{where}: cannot read: {exc.strerror or exc}") from None
    with fh:
        yield Capture(fh, actual, columns)
