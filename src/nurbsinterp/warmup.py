"""The kernels' first compilation: each command's as it calls them, or every command's ahead of time.

numba compiles a kernel the first time it is called with a given signature
and caches the machine code (see ``_cache.py``).  A command compiles only the
kernels it calls -- `plan` of a YAML curve some forty, not the servo's, the
contour error's or the look-ahead's -- and :class:`CompileWatch` tells the
command line as each one starts, so that it can say so while it lasts (with an
estimate from the count measured for that command: :func:`first_run_estimate`).
:func:`warm_up` (``nurbsinterp warmup``) runs every stage of the pipeline once
on the bundled circle and a small program -- geometry, every interpolator and
profile, both streams written and read back, the adaptive planner, the
look-ahead with and without a jerk limit, the servo simulation and the contour
error -- on every core, so that no later command compiles.
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
    # a variant names its profile as compare's rows do: its ramp binds the look-ahead (motion.limits)
    return dataclasses.replace(job, profile=prof, interpolator=interp,
                               profile_chosen=job.profile_chosen or shape is not None or "accel_time" in profile)


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
    from .names import METHODS
    from .profiles import SHAPES

    for method in METHODS:
        for shape in SHAPES:
            _plan_and_read(_variant(job, method, shape, "before"))


def _after(job):
    """Acc/dec after interpolation: its filter, and the contour error the filter makes (the run's deviation)."""
    from .profiles import SHAPES

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
    # a chord tolerance above the radius: every point a tight turn, the feed floored near it (planner.sections)
    describe_job(_variant(job, "exact", "adaptive", "before", chord_tolerance=60.0), with_profile=True)


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
    blends, an arc, a stop, a NURBS block, the windowed planner (with and without a jerk limit), the ticks, and the
    contour error against the blocks."""
    import os
    import tempfile

    import numpy as np

    from .config import load_job
    from .motion.contour import ProgramWindow
    from .motion.pipeline import BATCH, LookAhead, path_items
    from .servo import ServoModel, load_servo
    from .simulation import simulate

    lines = ["G21 G90 G64 P0.005 F3000", "G0 X0 Y0 Z1", "G1 Z0"]
    lines += [f"G1 X{5 * np.cos(a):.4f} Y{5 * np.sin(a):.4f}" for a in np.linspace(0.04, 3.0, 75)]
    lines += ["G1 X-6 Y1", "G2 X-4 Y3 R2", "G4 P0.01", "G1 Y5"]
    # a NURBS block (motion.nurbs_blocks) restating the current point, as G5.2 programs do: its first piece starts
    # at rest, the rest move
    lines += ["G5.2 X-4 Y5 P1 L3", "X-2 Y7 P1", "X0 Y5 P1", "G5.3", "G0 Z1", "M2"]
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
        # a program longer than a batch of blocks (pipeline.BATCH) with no stop: the jerk-limited pass commits
        # inside a section and hands its state to the next window (the Handover, an argument type of its own)
        long = os.path.join(tmp, "long.ngc")
        angles = np.linspace(0.0, 6.0, BATCH + 500)
        with open(long, "w") as fh:
            fh.write("G21 G90 G64 P0.005 F3000\nG1 X0 Y0 Z0\n")
            fh.write("".join(f"G1 X{20 * np.cos(a):.4f} Y{20 * np.sin(a):.4f}\n" for a in angles))
            fh.write("M2\n")
        for _ in LookAhead(load_job(long, stream=True, every_profile=True, overrides=jerk), 0.005).chunks():
            pass


#: the warm-up's steps, in the order a parallel warm-up hands them out, each to the first worker free: the
#: curve's own kernels (every other step calls them, and finds them in the cache once this step has saved them)
#: beside the interpolators, then the look-ahead (its own kernels) beside the contour error (the longest), then
#: the rest -- about 35, 20, 50, 70, 10 and 2 s of CPU
STEPS = (
    ("geometry", _geometry),
    ("interpolators and streams", _interpolators),
    ("look-ahead planner", _look_ahead),
    ("acc/dec after, contour error", _after),
    ("adaptive planner", _adaptive),
    ("servo", _servo),
)


def warm_up(progress=None, jobs: int = 1) -> dict:
    """Run every stage once on the bundled circle (and a small program), compiling (or loading) every kernel.

    jobs > 1 runs the steps in that many processes at once (numba compiles under a global lock, so threads
    would not help; its cache is written by renaming a finished file, so two processes may save the same kernel
    and a reader sees one whole or none).  progress(name, done, count) is called as each step starts (*name* the
    step, *done* the steps finished) and once at the end with name None.  Returns {"seconds": wall time,
    "compiled": the package's kernels compiled}.
    """
    t0 = time.perf_counter()
    if jobs > 1:
        compiled = _in_processes(progress, min(jobs, len(STEPS)))
    else:
        counter = CompileWatch()
        job = _circle()
        with counter:
            for i, (name, step) in enumerate(STEPS):
                if progress is not None:
                    progress(name, i, len(STEPS))
                step(job)
        compiled = counter.count
    if progress is not None:
        progress(None, len(STEPS), len(STEPS))
    return {"seconds": time.perf_counter() - t0, "compiled": compiled}


def _in_processes(progress, jobs: int) -> int:
    """The steps handed out to *jobs* worker processes (``python -m nurbsinterp.warmup``), each taking the next
    when it has finished one: the sum of the kernels they compiled."""
    import os
    import subprocess
    import sys
    import tempfile
    from selectors import EVENT_READ, DefaultSelector

    env = dict(os.environ, NUMBA_CACHE_DIR=_numba_cache_dir())
    errors = [tempfile.TemporaryFile("w+") for _ in range(jobs)]  # a file, not a pipe: never full, never a hang
    workers = [subprocess.Popen([sys.executable, "-m", "nurbsinterp.warmup"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=err, env=env, text=True, bufsize=1)
               for err in errors]
    pending = list(range(len(STEPS)))
    done = compiled = 0
    selector = DefaultSelector()
    try:
        for worker, err in zip(workers, errors):
            selector.register(worker.stdout, EVENT_READ, (worker, err))
            _hand_out(worker, pending, progress, done)
        busy = len(workers)
        while busy:
            for key, _ in selector.select():
                worker, err = key.data
                line = worker.stdout.readline()
                if not line:  # the worker died: its error, whole
                    worker.wait()
                    err.seek(0)
                    raise RuntimeError(f"the warm-up's worker process failed (exit {worker.returncode}): "
                                       f"{err.read().strip()}")
                compiled += int(line.split()[1])
                done += 1
                if pending:
                    _hand_out(worker, pending, progress, done)
                else:
                    selector.unregister(worker.stdout)
                    worker.stdin.close()
                    busy -= 1
        for worker in workers:
            worker.wait()
    finally:
        for worker in workers:
            if worker.poll() is None:
                worker.kill()
                worker.wait()
            for fh in (worker.stdin, worker.stdout):
                try:
                    fh.close()
                except OSError:
                    pass
        for err in errors:
            err.close()
    return compiled


def _hand_out(worker, pending, progress, done) -> None:
    i = pending.pop(0)
    if progress is not None:
        progress(STEPS[i][0], done, len(STEPS))
    worker.stdin.write(f"{i}\n")
    worker.stdin.flush()


def _numba_cache_dir() -> str:
    """The directory numba saves this process's kernels in (the workers must save theirs there too)."""
    from ._cache import cache_dir

    try:
        import numba.core.config as config

        return str(config.CACHE_DIR or cache_dir())
    except ImportError:  # pragma: no cover - numba is a dependency
        return str(cache_dir())


def _worker() -> None:
    """A warm-up worker: runs the step whose index each line of stdin names, answering 'done COMPILED'."""
    import sys

    answers, sys.stdout = sys.stdout, sys.stderr  # stdout carries the answers alone, whatever a step may print
    job = _circle()
    for line in sys.stdin:
        with CompileWatch() as counter:
            STEPS[int(line)][1](job)
        answers.write(f"done {counter.count}\n")
        answers.flush()


def first_run_estimate(command: str):
    """What a command's first run of a version compiled when measured (benchmarks/first_run.py writes
    data/first_run.json): {"kernels": N, "seconds": S} or None where it was not measured."""
    import json
    from importlib.resources import files

    try:
        table = json.loads(files("nurbsinterp").joinpath("data/first_run.json").read_text())
    except (OSError, ValueError):
        return None
    return table.get("commands", {}).get(command)


class CompileWatch:
    """Calls back on numba's compilations of the package's kernels while registered: on_start(name, count) as
    each starts (*count* the kernels so far) -- a kernel calling others compiles them inside its own compilation,
    each counted (numba's own implementations of numpy functions, compiled alongside, are not) -- and on_idle()
    when the outermost compilation ends."""

    def __init__(self, on_start=None, on_idle=None):
        from numba.core import event

        watch = self

        class Listener(event.Listener):
            def on_start(self, ev):
                watch.depth += 1
                # (a kernel kept out of the cache by design -- bench's, which call the C clock -- compiles on
                # every run: not a first-run cost, never counted)
                if _ours(ev.data["dispatcher"]):
                    watch.count += 1
                    if watch.on_start is not None:
                        watch.on_start(ev.data["dispatcher"].py_func.__qualname__, watch.count)

            def on_end(self, ev):
                watch.depth -= 1
                if watch.depth == 0 and watch.on_idle is not None:
                    watch.on_idle()  # the run goes on (and may write): a display steps aside until the next

        self.count = 0
        self.depth = 0
        self.on_start = on_start
        self.on_idle = on_idle
        self._listener = Listener()
        self._event = event

    def __enter__(self):
        self._event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc):
        self._event.unregister("numba:compile", self._listener)


#: the modules whose kernels are compiled on every run by design (bench's call the C clock, which numba cannot cache)
UNCACHED = ("nurbsinterp.bench",)


def _ours(dispatcher) -> bool:
    module = getattr(dispatcher.py_func, "__module__", "") or ""
    return module.startswith("nurbsinterp.") and module not in UNCACHED


_WATCHING = []  # the watch watch_compiles registered (one a process: a command run in-process again adds none)


def watch_compiles(on_start, on_idle=None) -> CompileWatch:
    """For the rest of the process, call on_start(kernel name, count) as each kernel of the package starts
    compiling, and on_idle() as the outermost compilation ends; a second call (a command run in-process again)
    replaces the callbacks."""
    if not _WATCHING:
        _WATCHING.append(CompileWatch().__enter__())
    _WATCHING[0].on_start, _WATCHING[0].on_idle = on_start, on_idle
    return _WATCHING[0]


if __name__ == "__main__":
    _worker()
