"""One case of a sweep, run where it lands (issue 31): plan, pre-compensate, simulate, measured into one row.

:func:`run_case` takes a :class:`~nurbsinterp.sweep.spec.Case` -- plain data, the program's and the servo
file's bytes included, so that a worker on another machine needs no shared filesystem -- and returns its row
(:data:`COLUMNS`).  It never raises: a case that fails is a row with ``status`` ``failed`` (the one line
`plan` or `simulate` would print for it, the program named as the sweep names it) or ``error`` (an internal
error).  It runs the pipeline the commands run: the planner `plan` would choose (``tolerance``: the look-ahead
within it; a G-code program that states G64 P: within its own; else the interpolator), pre-compensation as
`plan --precompensate` writes it, `simulate`'s measures, chunk by chunk -- no case holds its ticks.

Each row also gives the commands' own largest per-axis velocity, acceleration and jerk (finite differences of
the commands sent, pre-compensated where they are) against the machine's limits.  A machine's limits are
planned with where `plan` takes them (the adaptive profile: velocity and acceleration; the look-ahead:
jerk too) and only checked elsewhere.
"""
from __future__ import annotations

import os
import shutil
import tempfile
import time

import numpy as np

from ..errors import NurbsInterpError
from ..names import AXES
from .spec import SETTINGS, Case, reader_text

ORDERS = (("v", "max_velocity", "mm_s"), ("a", "max_accel", "mm_s2"), ("j", "max_jerk", "mm_s3"))
#: a setting's column: its name with the unit of its value
SETTING_COLUMNS = {"feedrate": "feedrate_mm_s", "rapid_feedrate": "rapid_feedrate_mm_s", "accel_time": "accel_time_s",
                   "period": "period_s", "max_accel": "max_accel_mm_s2", "max_jerk": "max_jerk_mm_s3",
                   "chord_tolerance": "chord_tolerance_mm", "corner_tolerance": "corner_tolerance_mm",
                   "tolerance": "tolerance_mm"}
COLUMNS = (
    "case", "case_fingerprint", "program", "program_sha256", "program_options", "machine", "servo",
    *(SETTING_COLUMNS.get(k, k) for k in SETTINGS),
    "planner", "status", "error", "ticks", "motion_time_s", "deviation_max_mm",
    *(f"{o}max_{a}_{unit}" for o, _, unit in ORDERS for a in AXES),
    *(f"{o}lim_{a}_{unit}" for o, _, unit in ORDERS for a in AXES),
    "limits_held", "worst_limit", "worst_limit_ratio",
    "contour_error_max_mm", "contour_error_rms_mm", "tracking_error_max_mm", "feedrate_error_max_mm_s",
    "settle_time_s", "plan_s", "simulate_s", "worker",
)
LIMIT_SLACK = 1e-9  # relative: a limit is held by a value within the rounding of its finite difference


class CaseTimeout(Exception):
    """A case ran longer than the sweep's timeout: stopped between two chunks."""


def labels(case: Case) -> dict:
    """The row of *case* as far as the sweep file says it: its labels, settings and limits, nothing measured."""
    row = dict.fromkeys(COLUMNS)
    row.update(case=case.index, case_fingerprint=case.fingerprint, program=case.program,
               program_sha256=case.program_sha256, program_options=reader_text(case.reader) or None,
               machine=case.machine, servo=case.servo_label)
    for key, value in case.settings.items():
        row[SETTING_COLUMNS.get(key, key)] = value
    return row


def run_case(case: Case) -> dict:
    """The case's row (module docstring): every column of COLUMNS, None where it has no value."""
    row = labels(case)
    for axis, limits in case.limits.items():
        for o, key, unit in ORDERS:
            row[f"{o}lim_{axis}_{unit}"] = limits.get(key)
    where = tempfile.mkdtemp(prefix="nurbsinterp-case-")
    started = time.perf_counter()
    clock = [0.0]  # s spent planning (and pre-compensating): inside the plan's generator
    try:
        program = os.path.join(where, "program", os.path.basename(case.program))
        os.makedirs(os.path.dirname(program))
        with open(program, "wb") as fh:
            fh.write(case.program_bytes)
        servo = None
        if case.servo_bytes is not None:
            servo = os.path.join(where, "servo.yaml")
            with open(servo, "wb") as fh:
                fh.write(case.servo_bytes)
        deadline = None if case.timeout is None else started + case.timeout
        _run(case, program, servo, row, clock, deadline)
        row["status"] = "ok"
    except CaseTimeout as exc:
        row["status"] = "timeout"
        row["error"] = str(exc)
    except NurbsInterpError as exc:
        row["status"] = "failed"
        row["error"] = _named(str(exc), where, case)
    except Exception as exc:  # noqa: BLE001 -- a case is a row, never the end of the sweep
        row["status"] = "error"
        row["error"] = _named(f"internal error: {type(exc).__name__}: {exc}", where, case)
    finally:
        shutil.rmtree(where, ignore_errors=True)
    row["plan_s"] = clock[0]
    row["simulate_s"] = max(0.0, time.perf_counter() - started - clock[0])
    return row


def _named(text: str, where: str, case: Case) -> str:
    """One line, the worker's temporary paths replaced by the names the sweep gives them."""
    text = text.replace(os.path.join(where, "program", os.path.basename(case.program)), case.program)
    if case.servo_label is not None:
        text = text.replace(os.path.join(where, "servo.yaml"), case.servo_label)
    return " ".join(text.split())


def _run(case: Case, program: str, servo_file: str | None, row: dict, clock: list, deadline) -> None:
    from ..config import load_job
    from ..errors import located
    from ..motion.pipeline import plans_with_look_ahead

    settings = case.settings
    tolerance = settings.get("tolerance")
    fields = {field: (settings[key], f"sweep: {key}") for key, (_, field) in SETTINGS.items()
              if field is not None and settings.get(key) is not None}
    with located(program):  # as plan decides (a program's own G64 P): before the limits, which hang on it
        look_ahead, _ = plans_with_look_ahead(tolerance, case.program_format, lambda: load_job(
            program, overrides=fields, reader_options=case.reader, every_profile=True, stream=True))
    profile = settings.get("profile")
    planned = ("max_velocity", "max_accel", "max_jerk") if look_ahead else \
        ("max_velocity", "max_accel") if profile == "adaptive" else ()
    for axis, limits in case.limits.items():
        for key in planned:
            if limits.get(key) is not None:
                fields[f"profile.axes.{axis}.{key}"] = (limits[key], f"sweep: machine {case.machine}")
    with located(program):
        job = load_job(program, overrides=fields, reader_options=case.reader, every_profile=True, stream=look_ahead)
    row["planner"] = "look-ahead" if look_ahead else "interpolator"
    model = None
    if servo_file is not None:
        from ..servo import load_servo

        model = load_servo(servo_file)
    if look_ahead:
        from ..motion.pipeline import LookAhead, program_window

        from ..compare import CommandDeviation

        with located(program):
            run = LookAhead(job, tolerance, smooth=True)
        dim = job.path.dim
        geometry, window = None, {"window": program_window(job, tolerance)}
        deviation = CommandDeviation(job, tolerance, run.columns)

        def planned_rows():
            yield from deviation.measured(run.chunks())
    else:
        from ..interpolate import Interpolation
        from ..metrics import RunStats

        run = Interpolation(job)
        dim = run.curve.dim
        geometry, window = run.path, {}
        stats = RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
        deviation = None

        def planned_rows():
            for chunk in run.chunks(derivatives=True):
                stats.update(chunk, dim)
                yield chunk.data
    period = run.period
    rows = planned_rows()
    method = settings.get("precompensate") or "none"
    if method != "none":
        from ..precompensate import Precompensator, design

        shaper = Precompensator(design(model, period, method, list(AXES[:dim])), run.columns)
        rows = (shaped for shaped, _ in shaper.run(rows))
    axes = [run.columns.index(a) for a in AXES[:dim]]
    extremes = _Extremes(dim, period)

    def sent():
        it = iter(rows)
        while True:
            t0 = time.perf_counter()
            chunk = next(it, None)
            clock[0] += time.perf_counter() - t0
            if chunk is None:
                return
            extremes.update(chunk[:, axes])
            if deadline is not None and time.perf_counter() > deadline:
                raise CaseTimeout(f"stopped after {case.timeout:g} s (the sweep's timeout), {extremes.ticks} ticks "
                                  f"({extremes.ticks * period:g} s of motion) in")
            yield chunk

    if model is not None:
        from ..simulation import simulate

        report, _ = simulate(geometry, model, run.columns, sent(), name=f"{case.program} (planned)",
                             against_plan=method != "none", **window)
        row.update(contour_error_max_mm=report.contour_error_max, contour_error_rms_mm=report.contour_error_rms,
                   tracking_error_max_mm=max(report.tracking_error_max.values()),
                   feedrate_error_max_mm_s=report.feedrate_error_max, settle_time_s=report.settle_time)
    else:
        for _ in sent():
            pass
    row["ticks"] = extremes.ticks
    row["motion_time_s"] = (extremes.ticks - 1) * period
    row["deviation_max_mm"] = deviation.max if deviation is not None else stats.deviation_max
    _limits(row, case.limits, extremes, dim)


class _Extremes:
    """The commands' largest |velocity|, |acceleration| and |jerk| per axis: finite differences over the whole
    stream, its last three commands carried from chunk to chunk (motion.ticks.axis_extremes)."""

    def __init__(self, dim, period):
        self.period = period
        self.prev = np.zeros((3, dim))
        self.count = 0
        self.out = np.zeros((3, dim))
        self.ticks = 0
        self.largest = 0.0  # the largest |coordinate|: the finite differences' rounding

    def update(self, x):
        from ..motion.ticks import axis_extremes

        if x.shape[0]:
            self.count = axis_extremes(np.ascontiguousarray(x), self.prev, self.count, self.period, self.out)
            self.ticks += x.shape[0]
            self.largest = max(self.largest, float(np.abs(x).max()))


def _limits(row, limits, extremes, dim):
    """The commands' extremes into the row, and each against its limit: held, the worst ratio and where."""
    worst, ratio, held, any_limit = None, 0.0, True, False
    for i, axis in enumerate(AXES[:dim]):
        for order, (o, key, unit) in enumerate(ORDERS):
            value = float(extremes.out[order, i])
            row[f"{o}max_{axis}_{unit}"] = value
            limit = limits.get(axis, {}).get(key)
            if limit is None:
                continue
            any_limit = True
            # the finite difference of rounded coordinates: 2**order roundings of an ulp, over T**(order+1)
            slack = LIMIT_SLACK * limit + 2 ** order * float(np.spacing(extremes.largest)) \
                / extremes.period ** (order + 1)
            if value > limit + slack:
                held = False
            if value / limit > ratio:
                worst, ratio = f"{o}_{axis}", value / limit
    if any_limit:
        row.update(limits_held="yes" if held else "no", worst_limit=worst, worst_limit_ratio=ratio)
