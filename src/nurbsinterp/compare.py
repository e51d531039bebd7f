"""The paper's experiments in one call: every interpolator and profile, before and after, through the servo."""
from __future__ import annotations

import dataclasses

import numpy as np

from .interpolate import Interpolation
from .metrics import RunStats
from .nurbs import NurbsCurve
from .profiles import SHAPES
from .servo import ServoModel
from .simulation import simulate
from .config import Job
from .path import job_path
from .names import AXES, METHODS


def variants(job: Job):
    """(label, job) for every interpolator x profile before interpolation, every profile after it."""
    for method in METHODS:
        for shape in SHAPES:
            yield f"{method} {shape} before", _with(job, method, shape, "before")
    for shape in SHAPES:
        yield f"{job.interpolator.method} {shape} after", _with(job, job.interpolator.method, shape, "after")
    # the limit-aware schedule along the curve, with the job's limits (max_accel defaults to feedrate/accel_time)
    for method in ("taylor2", "exact"):
        yield f"{method} adaptive before", _with(job, method, "adaptive", "before")


def _with(job: Job, method: str, shape: str, accdec: str) -> Job:
    # each row names its profile: its ramp is what the row compares, on a machine with limits of its own too
    return dataclasses.replace(job, profile=dataclasses.replace(job.profile, type=shape, accdec=accdec),
                               interpolator=dataclasses.replace(job.interpolator, method=method), profile_chosen=True)


@dataclasses.dataclass(frozen=True)
class VariantResult:
    """One variant of `compare`: the interpolated commands' measures and the servo's (mm, mm/s, s)."""

    interpolator: str  # 'look-ahead': planned across the blocks of a program (look_ahead_compare)
    profile: str
    accdec: str
    ff_max: float | None  # the largest |feedrate fluctuation| (None: the look-ahead, which has no interpolator's)
    chord_error_max: float | None  # (None: the look-ahead, whose path is not the curve the chords are measured on)
    command_deviation_max: float  # how far the commands leave the curve (acc/dec after interpolation; the
    #                               look-ahead: the program, the blends' and the smoothing's deviation)
    contour_error_max: float
    contour_error_rms: float
    feedrate_error_max: float
    feedrate_error_rms: float
    motion_time: float  # from the first command to the last
    end_gap: float

    def as_dict(self) -> dict:
        """The fields by name, in order: the JSON form."""
        return dataclasses.asdict(self)


def run_variant(job: Job, curve: NurbsCurve, model: ServoModel) -> VariantResult:
    """Plan, interpolate and simulate one job; the measures of both stages."""
    run = Interpolation(job, curve)
    stats = RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)

    def chunks():
        for chunk in run.chunks(derivatives=True):
            stats.update(chunk, run.curve.dim)
            yield chunk.data

    report, _ = simulate(run.path, model, run.columns, chunks(), name=job.source)
    return VariantResult(
        interpolator=job.interpolator.method,
        profile=job.profile.type,
        accdec=job.profile.accdec,
        ff_max=abs(stats.ff_max),
        chord_error_max=stats.chord_max,
        command_deviation_max=stats.deviation_max,
        contour_error_max=report.contour_error_max,
        contour_error_rms=report.contour_error_rms,
        feedrate_error_max=report.feedrate_error_max,
        feedrate_error_rms=report.feedrate_error_rms,
        motion_time=report.command_ticks * run.period - run.period,
        end_gap=run.end_gap,
    )


def compare(job: Job, model: ServoModel, progress=None) -> list[VariantResult]:
    curve = job_path(job).programmed  # reused by every variant of a one-curve job
    rows = []
    for label, variant in variants(job):
        rows.append(run_variant(variant, curve, model))
        if progress is not None:
            progress(label)
    return rows


@dataclasses.dataclass(frozen=True)
class CompensationResult:
    """The job's own variant, pre-compensated by *method* ('none': as planned) for the model, run on a plant
    that differs from it by *model_error* ('none': the model itself)."""

    method: str
    model_error: str
    contour_error_max: float
    contour_error_rms: float
    feedrate_error_max: float
    settle_time: float

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def precompensation_study(job: Job, model: ServoModel, methods, errors, progress=None, look_ahead=False,
                          tolerance=None, smooth=True) -> list[CompensationResult]:
    """Every method (and 'none') designed on *model*, every plant: the model, then each ModelError of *errors*.

    The job is planned afresh for each cell (flat memory, whatever its length); the contour error is the
    simulated table's, as `simulate` measures it.  *look_ahead*: planned with look-ahead across the program's
    blocks within *tolerance* (mm; None: the program's own G64 P), measured against them.
    """
    from .errors import SpecError
    from .precompensate import design

    curve = None if look_ahead else job_path(job).programmed
    axes = list(AXES[:job.path.dim if curve is None else curve.dim])
    rows = []
    for method in ("none", *methods):
        plan = None if method == "none" else design(model, job.interpolator.period, method, axes)
        for error in (None, *errors):
            label = "none" if error is None else error.label
            try:
                report, _ = run_shaped(job, curve, model if error is None else error.apply(model), plan,
                                       look_ahead=look_ahead, tolerance=tolerance, smooth=smooth)
            except SpecError as exc:
                raise SpecError(f"model error {label}: {exc}") from None
            rows.append(CompensationResult(method, label, report.contour_error_max, report.contour_error_rms,
                                           report.feedrate_error_max, report.settle_time))
            if progress is not None:
                progress(f"{method} on {label}")
    return rows


def run_shaped(job: Job, curve: NurbsCurve, plant: ServoModel, plan=None, quantiser=None, keep_series=False,
               look_ahead=False, tolerance=None, smooth=True, actual=None):
    """Plan *job*, pre-compensate it by *plan* (a precompensate.Design; None: as planned), round it by *quantiser*
    (a quantise.Quantiser, after the shaping) and simulate it on *plant*: simulate's (report, series).  With
    *look_ahead* the job is planned with look-ahead across its program's blocks within *tolerance* (mm; None: the
    program's own G64 P; *curve* unused) and measured against them.  *actual*: a capture.Capture of the machine
    running these commands, measured beside the model (``report.measured``)."""
    from .precompensate import Precompensator

    if not look_ahead:
        run = Interpolation(job, curve)
        chunks = (c.data for c in run.chunks())
        geometry, window = run.path, {}
    else:
        from .motion.pipeline import LookAhead, program_window

        run = LookAhead(job, tolerance, smooth=smooth)
        chunks = run.chunks()
        geometry = None
        window = {"window": program_window(job, tolerance)}
        if actual is not None:
            window["measured_window"] = program_window(job, tolerance)
    if actual is not None:
        window["actual"] = actual
    if plan is not None:
        chunks = (shaped for shaped, _ in Precompensator(plan, run.columns).run(chunks))
    if quantiser is not None:
        chunks = (quantiser.apply(rows).copy() for rows in chunks)
    # a pre-compensated stream's tracking error against C(u), which acc/dec after interpolation does not command
    return simulate(geometry, plant, run.columns, chunks, name=job.source, keep_series=keep_series,
                    against_plan=plan is not None and not getattr(run, "after", False), **window)


def look_ahead_variants(job: Job):
    """(label, job) for every profile the look-ahead plans with: the paper's ramps and the adaptive schedule.

    The adaptive schedule takes the job's limits; a job that gives no acceleration limit at all (no max_accel,
    no axis' max_accel) gets feedrate/accel_time, as compare's adaptive rows always have."""
    for shape in SHAPES:
        yield f"look-ahead {shape}", _with(job, job.interpolator.method, shape, "before")
    adaptive = _with(job, job.interpolator.method, "adaptive", "before")
    p = job.profile
    if p.max_accel is None and all(a is None for _, _, a, _ in p.axes) and p.accel_time > 0:
        adaptive = dataclasses.replace(adaptive, profile=dataclasses.replace(adaptive.profile,
                                                                             max_accel=p.feedrate / p.accel_time))
    yield "look-ahead adaptive", adaptive


class CommandDeviation:
    """The look-ahead commands' own largest distance from the program (``max``, mm), measured as they pass
    (:meth:`measured`): their window over the program's blocks, seeded by each tick's block (n + u); ``last`` the
    last command."""

    def __init__(self, job: Job, tolerance, columns):
        from .motion.pipeline import program_window

        self.window = program_window(job, tolerance)
        self.dim = job.path.dim
        self.n, self.u, self.x = (list(columns).index(c) for c in ("n", "u", "x"))
        self.max = 0.0
        self.last = None

    def measured(self, chunks):
        for rows in chunks:
            if rows.shape[0]:
                points = rows[:, self.x:self.x + self.dim]
                _, dist = self.window.nearest(points, rows[:, self.n] + rows[:, self.u], points)
                self.max = max(self.max, float(dist.max()))
                self.last = points[-1].copy()
            yield rows


def run_look_ahead_variant(job: Job, tolerance: float, model: ServoModel, smooth: bool = True) -> VariantResult:
    """Plan one profile with look-ahead across the program's blocks within *tolerance* (mm), simulate it on *model*
    and measure both against the program, read alongside the stream (motion.contour.ProgramWindow)."""
    from .motion.pipeline import LookAhead, program_window

    run = LookAhead(job, tolerance, smooth=smooth)
    deviation = CommandDeviation(job, tolerance, run.columns)
    report, _ = simulate(None, model, run.columns, deviation.measured(run.chunks()), name=job.source,
                         window=program_window(job, tolerance))
    return VariantResult(
        interpolator="look-ahead",
        profile=job.profile.type,
        accdec="before",
        ff_max=None,
        chord_error_max=None,
        command_deviation_max=deviation.max,
        contour_error_max=report.contour_error_max,
        contour_error_rms=report.contour_error_rms,
        feedrate_error_max=report.feedrate_error_max,
        feedrate_error_rms=report.feedrate_error_rms,
        motion_time=report.command_ticks * run.period - run.period,
        end_gap=float(np.linalg.norm(deviation.last - run.end_point[:deviation.dim])),
    )


def look_ahead_compare(job: Job, tolerance: float, model: ServoModel, smooth: bool = True,
                       progress=None) -> list[VariantResult]:
    """`compare --tolerance`: every profile planned with look-ahead across the program's blocks, through the
    servo, measured against the program (each planned afresh: flat memory, whatever the program's length)."""
    rows = []
    for label, variant in look_ahead_variants(job):
        rows.append(run_look_ahead_variant(variant, tolerance, model, smooth))
        if progress is not None:
            progress(label)
    return rows


@dataclasses.dataclass(frozen=True)
class CaptureMatch:
    """`compare --actual`: the capture's run measured as the variant it is of.

    table : "variants" (the first table's row *index*) or "precompensation" (the job's own variant,
        pre-compensated by *method* for the model)
    matched_by : "commands" (the capture's received commands are that plan's, to %f's rounding) or "ticks" (a
        capture without commands: taken to be of the job's own variant, whose tick count it has)
    motion_time : s from the first command to the last (a pre-compensated plan's settling commands included)
    measured : simulation.MeasuredReport, the machine's errors; its tracking error against the plan's points
        where the plan is pre-compensated (tracking_against)
    """

    capture: str
    table: str
    index: int | None
    method: str | None
    label: str
    matched_by: str
    motion_time: float
    measured: object
    tracking_against: str = "commands"

    def as_dict(self) -> dict:
        out = {k: getattr(self, k) for k in ("capture", "table", "index", "method", "label", "matched_by",
                                            "motion_time", "tracking_against")}
        out["measured"] = self.measured.as_dict()
        return out


def own_variant(job: Job, labelled) -> int | None:
    """The index, in *labelled* ((label, job) pairs as variants() gives them), of the job's own settings; None
    where compare has no such variant (taylor1 with the adaptive profile)."""
    want = (job.interpolator.method, job.profile.type, job.profile.accdec)
    for i, (_, v) in enumerate(labelled):
        if (v.interpolator.method, v.profile.type, v.profile.accdec) == want:
            return i
    return None


def match_capture(job: Job, model: ServoModel, open_capture, has_commands: bool, methods, look_ahead=False,
                  tolerance=None, smooth=True, progress=None, capture_name: str = "the capture") -> CaptureMatch:
    """Which of compare's plans the capture is of, and the machine's errors measured against it.

    *open_capture*: a callable giving a context manager of a fresh capture.Capture of the file (each try reads
    it from its start); *has_commands*: whether its column map has the received commands.
    The job's own variant is tried first, then the same pre-compensated by each of *methods*, then the other
    variants; a try ends at the first received command that is not the plan's (capture.NotThisPlan), so a
    wrong plan costs a few ticks.  A capture without received commands can only be told by its ticks: it is
    measured as the job's own variant.  No plan matching: StreamError naming the capture and the own variant's
    mismatch.  Any other fault of the capture is refused as `simulate --actual` refuses it.
    """
    from .capture import NotThisPlan
    from .errors import StreamError
    from .precompensate import design

    labelled = list(look_ahead_variants(job) if look_ahead else variants(job))
    if look_ahead:
        own = next(i for i, (_, v) in enumerate(labelled) if v.profile.type == job.profile.type)
    else:
        own = own_variant(job, labelled)
    if own is None and not has_commands:
        raise StreamError(f"{capture_name}: the job's own settings ({job.interpolator.method} {job.profile.type} "
                          f"{job.profile.accdec}) are not among compare's variants, and a capture without received "
                          "commands can only be taken as them: measure it with simulate --actual")
    curve = None if look_ahead else job_path(job).programmed
    axes = list(AXES[:job.path.dim if curve is None else curve.dim])
    tries = [] if own is None else [("variants", own, None)]
    tries += [] if own is None else [("precompensation", own, m) for m in methods]
    tries += [("variants", i, None) for i in range(len(labelled)) if i != own]
    if not has_commands:  # nothing tells the other plans apart from the own variant's
        tries = tries[:1]
    first_miss = None
    for table, index, method in tries:
        label, variant = labelled[index]
        plan = None if method is None else design(model, variant.interpolator.period, method, axes)
        if progress is not None:
            progress(f"the capture against {label}" + ("" if method is None else f" + {method}"))
        with open_capture() as capture:
            try:
                report, _ = run_shaped(variant, curve, model, plan, look_ahead=look_ahead, tolerance=tolerance,
                                       smooth=smooth, actual=capture)
            except NotThisPlan as exc:
                if has_commands and not exc.commands_differ:  # every command matched: the run's own fault
                    raise StreamError(str(exc)) from None
                if first_miss is None:
                    first_miss = (label, str(exc))
                continue
        period = variant.interpolator.period
        return CaptureMatch(capture=capture.name, table=table, index=index if method is None else None,
                            method=method, label=label, matched_by="commands" if has_commands else "ticks",
                            motion_time=report.command_ticks * period - period, measured=report.measured,
                            tracking_against=report.tracking_against)
    plain = sum(1 for t in tries if t[2] is None)
    shaped = [t[2] for t in tries if t[2] is not None]
    what = (f"{plain} variant(s)" if plain > 1 else f"the job's own variant ({labelled[own][0]})") + \
        (f" and the job's own pre-compensated by {', '.join(shaped)}" if shaped else "")
    label, miss = first_miss
    raise StreamError(f"the capture is of none of the {what} compared; against {label}: {miss} (a stream planned "
                      "with --resolution or other options: measure it with simulate --actual)")
