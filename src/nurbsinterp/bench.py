"""The paper's Table 1 on this machine: computation time per tick of each interpolator and the servo.

Each tick is timed on its own inside compiled code, with the monotonic clock
read through ``clock_gettime`` around one call of the same
:func:`~nurbsinterp.interpolate.interpolate_tick` the `plan` command runs (or
:func:`~nurbsinterp.servo.servo_tick`), so the numbers are the per-tick
latency a real-time loop would see — mean, 99th percentile and maximum over the
whole motion, after one untimed warm-up pass — not a throughput divided by a
count.  The cost of reading the clock itself (about 20 ns) is measured the
same way and subtracted.

The timing kernels call a C function through ctypes, which numba cannot
cache, so they are compiled when a benchmark starts (a second or so).
"""
from __future__ import annotations

import ctypes
import ctypes.util
import dataclasses
import platform
import time

import numpy as np

from ._jit import njit
from .interpolate import METHODS, Interpolation, interpolate_tick
from .nurbs import make_work
from .profiles import SHAPES
from .precompensate import Precompensator, design, shape_chunk
from .servo import PAPER_TABLE, ServoModel, discretise, servo_tick
from .config import Job
from .path import job_path

#: Table 1 of the paper (TMS320C32 DSP, µs per tick): interpolator -> profile -> time
PAPER_TABLE1 = {
    "taylor1": {"trapezoidal": 540.0, "exponential": 580.0, "bell": 600.0},
    "taylor2": {"trapezoidal": 1020.0, "exponential": 1040.0, "bell": 1140.0},
}
PAPER_SERVO_US = 45.0
CLOCK_MONOTONIC = 1

_libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
_clock_gettime = _libc.clock_gettime
_clock_gettime.argtypes = [ctypes.c_int, ctypes.c_void_p]
_clock_gettime.restype = ctypes.c_int


@njit
def _now(buf):
    _clock_gettime(CLOCK_MONOTONIC, buf.ctypes.data)
    return buf[0] * 1_000_000_000 + buf[1]


@njit
def _clock_cost(n):
    buf = np.zeros(2, dtype=np.int64)
    out = np.empty(n, dtype=np.int64)
    for i in range(n):
        a = _now(buf)
        b = _now(buf)
        out[i] = b - a
    return out


@njit
def _time_ticks(method, geom, prof, T, sigma_min, K, state, dim):
    """ns spent in interpolate_tick for each tick 0..K."""
    buf = np.zeros(2, dtype=np.int64)
    dimh = geom[1].shape[3]
    work = make_work(geom[2], 2, dimh)
    CK = np.empty((3, dimh - 1))
    point = np.empty(dim)
    plan = np.empty(3)
    ders = np.empty((2, dim))
    out = np.empty(K + 1, dtype=np.int64)
    for k in range(K + 1):
        a = _now(buf)
        interpolate_tick(method, geom, prof, T, sigma_min, k, K, state, work, CK, point, plan, ders)
        b = _now(buf)
        out[k] = b - a
    return out


@njit
def _time_servo(cmd, A, B, Cv, kp, kv, resolution, limit, period, state, prev_cmd):
    buf = np.zeros(2, dtype=np.int64)
    n_ax = cmd.shape[1]
    pos = np.empty(n_ax)
    vel = np.empty(n_ax)
    volt = np.empty(n_ax)
    tmp = np.empty(state.shape[1])
    out = np.empty(cmd.shape[0], dtype=np.int64)
    for k in range(cmd.shape[0]):
        a = _now(buf)
        servo_tick(cmd[k], A, B, Cv, kp, kv, resolution, limit, period, state, prev_cmd, pos, vel, volt, tmp)
        b = _now(buf)
        out[k] = b - a
    return out


@njit
def _time_shaping(s, out, num, den, taps, tail, preview, s_hist, w_hist, w_peak):
    """precompensate.shape_chunk one tick at a time, timed: what `precompensate` adds to a tick."""
    buf = np.zeros(2, dtype=np.int64)
    times = np.empty(s.shape[0], dtype=np.int64)
    for k in range(s.shape[0]):
        a = _now(buf)
        shape_chunk(s[k:k + 1], out[k:k + 1], num, den, taps, tail, preview, s_hist, w_hist, w_peak)
        b = _now(buf)
        times[k] = b - a
    return times


@dataclasses.dataclass(frozen=True)
class TickTiming:
    """Time per tick over a whole motion, clock cost subtracted, µs."""

    mean_us: float
    p99_us: float
    max_us: float
    ticks: int


@dataclasses.dataclass(frozen=True)
class VariantTiming:
    """One interpolator x profile: its time per tick, its planning time and the paper's DSP beside it."""

    interpolator: str
    profile: str
    mean_us: float
    p99_us: float
    max_us: float
    ticks: int
    plan_ms: float
    paper_us: float | None  # Table 1 of the paper (None: not in it)
    speedup: float | None  # paper_us / mean_us


@dataclasses.dataclass(frozen=True)
class ServoTiming(TickTiming):
    """The servo controller's time per tick, beside the paper's."""

    axes: int
    paper_us: float
    speedup: float | None


@dataclasses.dataclass(frozen=True)
class ShapingTiming(TickTiming):
    """The exact pre-compensator's time per tick (all axes): its causal recursion and its preview's taps."""

    axes: int
    preview_ticks: int


@dataclasses.dataclass(frozen=True)
class OneTimeCosts:
    planning_ms: float  # the Bezier and arc-length tables and the profile
    kernel_startup_ms: float  # the numba cache load (or compile, on a first run)
    timer_compile_ms: float  # the timing kernels, compiled on every run


@dataclasses.dataclass(frozen=True)
class Machine:
    cpu: str
    cores: int | None
    python: str


@dataclasses.dataclass(frozen=True)
class BenchResult:
    """What :func:`run_bench` measured."""

    job: str
    period: float  # s
    rows: list[VariantTiming]
    servo: ServoTiming
    one_time: OneTimeCosts
    clock_overhead_ns: float  # the cost of one clock read, subtracted from every tick
    machine: Machine
    precompensation: ShapingTiming | None = None  # the exact inverse of the servo model, per tick

    def as_dict(self) -> dict:
        """Nested dicts of the fields by name, in order: the JSON form."""
        return dataclasses.asdict(self)


def _stats(ns: np.ndarray, overhead: float) -> TickTiming:
    us = np.maximum(ns - overhead, 0.0) / 1e3
    return TickTiming(mean_us=float(us.mean()), p99_us=float(np.percentile(us, 99)), max_us=float(us.max()),
                      ticks=int(us.size))


def machine() -> Machine:
    cpu = platform.processor() or platform.machine()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import os

    return Machine(cpu=cpu, cores=os.cpu_count(), python=platform.python_version())


def run_bench(job: Job, model: ServoModel = PAPER_TABLE, repeats: int = 3) -> BenchResult:
    """Time every interpolator x profile per tick on *job*, and the servo controller.

    Returns the rows (per variant: mean/p99/max µs, paper µs, speed-up), the
    servo, the one-time costs (planning, kernel start-up) and the machine.
    """
    def prepare():
        t0 = time.perf_counter()
        curve = job_path(job).programmed
        first = Interpolation(job, curve)  # the arc-length table and the profile
        t_plan = time.perf_counter() - t0
        for _chunk in first.chunks():
            pass
        return curve, t_plan, time.perf_counter() - t0

    # the first time in a process loads (or compiles) the kernels; the second is the planning itself
    _, _, cold = prepare()
    curve, t_plan, warm = prepare()
    t0 = time.perf_counter()
    _clock_cost(10)
    t_timer_compile = time.perf_counter() - t0
    overhead = float(np.median(_clock_cost(200_000)))

    rows = []
    for method in METHODS:
        for shape in SHAPES:
            variant = dataclasses.replace(job, profile=dataclasses.replace(job.profile, type=shape, accdec="before"),
                                          interpolator=dataclasses.replace(job.interpolator, method=method))
            t0 = time.perf_counter()
            run = Interpolation(variant, curve)
            t_plan = time.perf_counter() - t0
            best = _fastest(repeats, lambda: _time_ticks(METHODS[method], run.geometry, run.profile.params,
                                                         run.period, run.sigma_min, run.last_tick, run.new_state(),
                                                         curve.dim), overhead)
            paper = PAPER_TABLE1.get(method, {}).get(shape)
            rows.append(VariantTiming(interpolator=method, profile=shape, **vars(best), plan_ms=t_plan * 1e3,
                                      paper_us=paper, speedup=_speedup(paper, best)))

    # the servo controller, on the commands of the job itself
    run = Interpolation(job, curve)
    cmd = np.vstack([c.points for c in run.chunks()])
    axes = ["x", "y", "z"][: curve.dim]
    loop = discretise(model, run.period, axes)

    def servo_pass():
        state = np.zeros((len(axes), loop.A.shape[1]))
        state[:, -1] = cmd[0]
        return _time_servo(np.ascontiguousarray(cmd), loop.A, loop.B, loop.Cv, loop.kp, loop.kv, loop.resolution,
                           loop.limit, loop.period, state, cmd[0].copy())

    best = _fastest(repeats, servo_pass, overhead)
    servo = ServoTiming(**vars(best), axes=len(axes), paper_us=PAPER_SERVO_US, speedup=_speedup(PAPER_SERVO_US, best))

    # the exact pre-compensator of that model, on the same commands
    shaper = Precompensator(design(model, run.period, "exact", axes), ["x", "y", "z"][: curve.dim])
    s = np.ascontiguousarray(cmd - cmd[0])

    def shaping_pass():
        return _time_shaping(s, np.empty_like(s), shaper.num, shaper.den, shaper.taps, shaper.tail, shaper.preview,
                             np.zeros_like(shaper.s_hist), np.zeros_like(shaper.w_hist), np.zeros_like(shaper.w_peak))

    best = _fastest(repeats, shaping_pass, overhead)
    shaping = ShapingTiming(**vars(best), axes=len(axes), preview_ticks=shaper.latency)
    return BenchResult(
        job=job.source,
        period=job.interpolator.period,
        rows=rows,
        servo=servo,
        one_time=OneTimeCosts(planning_ms=t_plan * 1e3, kernel_startup_ms=(cold - warm) * 1e3,
                              timer_compile_ms=t_timer_compile * 1e3),
        clock_overhead_ns=overhead,
        machine=machine(),
        precompensation=shaping,
    )


def _fastest(repeats: int, timed_pass, overhead: float) -> TickTiming:
    """The pass of lowest mean time per tick among repeats + 1 (the first warms up caches and compiles)."""
    best = None
    for _ in range(repeats + 1):
        stats = _stats(timed_pass(), overhead)
        if best is None or stats.mean_us < best.mean_us:
            best = stats
    return best


def _speedup(paper_us: float | None, timing: TickTiming) -> float | None:
    return paper_us / timing.mean_us if paper_us and timing.mean_us > 0 else None
