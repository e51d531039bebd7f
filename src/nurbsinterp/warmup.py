"""Compile every kernel the command line uses, in one go, before the first real job needs them.

numba compiles a kernel the first time it is called with a given signature
and caches the machine code (see ``_cache.py``).  Left to itself, each
subcommand would compile its own kernels on its first use, silently: a new
user would wait half a minute on `info`, again on `plan`, again on
`simulate`.  :func:`warm_up` runs every stage of the pipeline once on the
bundled circle — geometry, every interpolator and profile, both streams
written and read back, the adaptive planner, the servo simulation and the
contour error — so that the user waits once, is told so, and every later run
loads the cache.  :func:`report_compiles` is the safety net: it calls back
when a kernel is compiled after all (a signature the warm-up did not reach).
"""
from __future__ import annotations

import dataclasses
import io
import time
from importlib.resources import files


def _circle():
    from .config import load_job

    return load_job(str(files("nurbsinterp").joinpath("data/circle.yaml")))


def _geometry(job):
    import numpy as np

    from .describe import describe_job
    from .metrics import chord_error
    from .nurbs import make_work
    from .path import job_path

    describe_job(job)
    curve = job_path(job).programmed
    U, B, p, n = curve.kernel_args  # the chord error of one step, the library's own measure of it
    a, b = curve.domain
    ends = curve.evaluate(np.array([a, a + 0.01 * (b - a)]))
    chord_error(U, B, p, n, a, a + 0.01 * (b - a), ends[0], ends[1], make_work(p, 2, B.shape[3]),
                np.empty((3, B.shape[3] - 1)))
    curve.closest_point(curve.evaluate(curve.domain[0] + 0.3 * (curve.domain[1] - curve.domain[0])))
    curve.arc_length_at(curve.domain[1])
    curve.parameter_at(curve.length / 3)


def _variant(job, method=None, shape=None, accdec=None, **profile):
    prof = dataclasses.replace(job.profile, **{k: v for k, v in
                                               dict(type=shape, accdec=accdec, **profile).items() if v is not None})
    interp = job.interpolator if method is None else dataclasses.replace(job.interpolator, method=method)
    return dataclasses.replace(job, profile=prof, interpolator=interp)


def _plan_and_read(job):
    """What `plan` runs: the run, its measures, both writers; and what `simulate` reads back."""
    from .interpolate import Interpolation
    from .metrics import RunStats
    from .names import AXES
    from .quantise import Quantiser, parse_resolution
    from .streams import StreamWriter, read_stream

    run = Interpolation(job)
    stats = RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
    for fmt in ("csv", "bin"):
        sink = io.BytesIO()
        writer = StreamWriter(sink, run.columns, fmt)
        for chunk in run.chunks(derivatives=True):
            writer.write(chunk.data)
            stats.update(chunk, run.curve.dim)
        writer.finish()
        sink.seek(0)
        _, chunks = read_stream(sink, "<warm-up>")
        for _ in chunks:
            pass
    # --resolution, --format hal (the same formatter, and the rounding of quantise.py)
    quantiser = Quantiser(parse_resolution("1um", AXES[:run.curve.dim]), run.columns)
    writer = StreamWriter(io.BytesIO(), run.columns, "hal", select=[0, 4, 5])
    for chunk in run.chunks():
        writer.write(quantiser.apply(chunk.data))


def _interpolators(job):
    from .profiles import SHAPES
    from .names import METHODS

    for method in METHODS:
        for shape in SHAPES:
            _plan_and_read(_variant(job, method, shape, "before"))
    for shape in SHAPES:
        _plan_and_read(_variant(job, shape=shape, accdec="after"))


def _adaptive(job):
    import numpy as np

    from .describe import describe_job

    # with and without a jerk limit, and with per-axis limits (profile.axes), whose caps are other arrays
    per_axis = (("x", 80.0, 800.0, None), ("y", 60.0, 600.0, None))
    for jerk, axes in ((None, None), (30000.0, None), (None, per_axis), (30000.0, per_axis)):
        variant = _variant(job, "exact", "adaptive", "before", chord_tolerance=1e-3, max_jerk=jerk, axes=axes)
        _, profile = describe_job(variant, with_profile=True)
        profile.plan.evaluate(np.linspace(0.0, profile.plan.duration, 11))  # what `info --plot` draws
        _plan_and_read(variant)


def _servo(job):
    from .compare import compare, precompensation_study
    from .servo import load_servo, parse_model_error

    model = load_servo(None)
    compare(job, model)
    # every pre-compensator (the shaping kernel) on the model and on a wrong plant
    quick = dataclasses.replace(job, profile=dataclasses.replace(job.profile, feedrate=400.0, accel_time=0.05))
    precompensation_study(quick, model, ("exact", "zpetc", "match"), [parse_model_error("gain=+5%", model.names)])


def _look_ahead(job):
    """What `plan --tolerance` and `simulate --tolerance` run on a program: the G-code reader, smoothing, corner
    blends, an arc, a stop, the windowed planner (with and without a jerk limit), the ticks, and the contour error
    against the blocks."""
    import os
    import tempfile

    import numpy as np

    from .config import load_job
    from .motion.contour import ProgramWindow
    from .motion.pipeline import LookAhead, path_items
    from .servo import ServoModel, load_servo
    from .simulation import simulate

    lines = ["G21 G90 G64 P0.005 F3000", "G0 X0 Y0 Z1", "G1 Z0"]
    lines += [f"G1 X{5 * np.cos(a):.4f} Y{5 * np.sin(a):.4f}" for a in np.linspace(0.04, 3.0, 75)]
    lines += ["G1 X-6 Y1", "G2 X-4 Y3 R2", "G4 P0.01", "G1 Y5", "G0 Z1", "M2"]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "warmup.ngc")
        with open(path, "w") as fh:
            fh.write("\n".join(lines) + "\n")
        per_axis = {f"profile.axes.{a}.max_accel": ("1000", "warm-up") for a in "xyz"}
        jerk = {**per_axis, **{f"profile.axes.{a}.max_jerk": ("20000", "warm-up") for a in "xyz"}}
        tangential = {**per_axis, "profile.max_jerk": ("30000", "warm-up")}
        # without and with per-axis limits, with per-axis jerk (the jerk-limited pass and its caps), and with a
        # tangential jerk only (the pass without caps: the bell profile's ramps)
        for options in ({}, per_axis, jerk, tangential):
            spec = load_job(path, stream=True, every_profile=True, overrides=options)
            run = LookAhead(spec, 0.005)
            window = ProgramWindow(path_items(load_job(path, stream=True, every_profile=True).path), 0.005, 3, path)
            paper = load_servo(None).axes  # a third axis for the 3-D stream (the paper's table has two)
            model = ServoModel({**paper, "z": paper["y"]}, "warm-up")
            # the kept series (--plot) takes the feet's points on the blocks, an arc's among them
            simulate(spec, model, run.columns, run.chunks(), window=window, keep_series=options is per_axis)


STEPS = (
    ("geometry", _geometry),
    ("interpolators and streams", _interpolators),
    ("adaptive planner", _adaptive),
    ("servo and contour error", _servo),
    ("look-ahead planner", _look_ahead),
)


def warm_up(progress=None) -> dict:
    """Run every stage once on the bundled circle, compiling (or loading) every kernel.

    progress(name, done, count) is called as each step starts (*name* the step now compiling, *done* the
    steps finished) and once at the end with name None.  Returns
    {"seconds": wall time, "compiled": number of kernel signatures compiled}.
    """
    counter = _CompileCounter()
    job = _circle()
    t0 = time.perf_counter()
    with counter:
        for i, (name, step) in enumerate(STEPS):
            if progress is not None:
                progress(name, i, len(STEPS))
            step(job)
        if progress is not None:
            progress(None, len(STEPS), len(STEPS))
    return {"seconds": time.perf_counter() - t0, "compiled": counter.count}


class _CompileCounter:
    """Counts numba compilations while active."""

    def __init__(self, on_first=None):
        from numba.core import event

        class Listener(event.Listener):
            def on_start(inner, ev):  # noqa: N805 - the listener's own self is unused
                self.count += 1
                if self.count == 1 and self.on_first is not None:
                    self.on_first(ev.data["dispatcher"].py_func.__qualname__)

            def on_end(inner, ev):  # noqa: N805
                pass

        self.count = 0
        self.on_first = on_first
        self._listener = Listener()
        self._event = event

    def __enter__(self):
        self._event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc):
        self._event.unregister("numba:compile", self._listener)


_REPORTING = []  # the listener report_compiles registered (one a process: a command run in-process again adds none)


def report_compiles(on_first) -> None:
    """For the rest of the process, call on_first(kernel name) when the first kernel is compiled."""
    if not _REPORTING:
        _REPORTING.append(_CompileCounter(on_first).__enter__())
