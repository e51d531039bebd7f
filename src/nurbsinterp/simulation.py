"""A command stream through the servo model, measured against the curve.

:func:`simulate` takes the rows `plan` writes (from a file, a pipe or an
in-memory run), drives the closed loop of :mod:`servo` with their axis
commands, holds the last command until the table settles, and accumulates
the contour, tracking and feedrate errors of :mod:`metrics`.  Everything runs
chunk by chunk; only a decimated copy is kept for plots.  Given the machine's
own run of the same commands (a capture, :mod:`capture`), the same loop
measures its positions beside the model's (``actual=``, ``report.measured``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._jit import njit
from .errors import SpecError, StreamError
from .interpolate import CHUNK_TICKS
from .profiles import MAX_TICKS
from .config import MAX_COORDINATE
from .path import Path
from .contour import ServoReport, ServoStats
from .servo import ClosedLoop, ServoModel, discretise
from .streams import refuse_counts
from .capture import received_deviation

SETTLE_TOL = 1e-6  # mm: the hold ends when every axis is this close to the last command
MAX_HOLD = 10.0  # s: give up waiting for the table to settle after this long
PERIOD_TOL = 2e-9  # s: CSV times carry 9 decimals
PLOT_POINTS = 200_000
HOLD_CHUNK = CHUNK_TICKS  # the most rows of the settle hold simulated at once (as plan's chunks)
TRACE_COLUMNS = ("k", "t", "u", "{a}_cmd", "{a}_act", "contour_error", "v_cmd", "v_act")
MEASURED_COLUMNS = ("{a}_meas", "contour_error_meas", "v_meas")  # the capture's, with actual=


@dataclass
class Series:
    """A decimated copy of a run for plots: keeps every `stride`-th tick, at most ~PLOT_POINTS."""

    stride: int = 1
    rows: list = field(default_factory=list)
    _next: int = 0

    def add(self, k0: int, block: np.ndarray, points=None) -> None:
        """Keep the rows of *block* (ticks k0..) on the stride; *points*: a callable giving the points (rows, axes)
        of the kept rows' last column, appended to them (a program's feet, evaluated while their blocks are read)."""
        kept = block[self.take(k0, block.shape[0])]
        if points is not None:
            kept = np.column_stack([kept, points(kept[:, -1])])
        self.append(kept)

    def take(self, k0: int, m: int) -> np.ndarray:
        """Which of the m rows of ticks k0.. the stride keeps (a mask)."""
        return (k0 + np.arange(m)) % self.stride == 0

    def append(self, kept: np.ndarray) -> None:
        """Rows already on the stride (:meth:`take`), their tick first."""
        self.rows.append(kept)
        if sum(r.shape[0] for r in self.rows) > 2 * PLOT_POINTS:
            self.stride *= 2
            merged = np.vstack(self.rows)
            self.rows = [merged[(merged[:, 0] % self.stride) == 0]]

    def array(self) -> np.ndarray:
        return np.vstack(self.rows) if self.rows else np.empty((0, 0))


@dataclass(frozen=True)
class MeasuredReport(ServoReport):
    """The errors of the machine's real run (a capture, :mod:`capture`), measured as the model's are.

    Contour error against the NURBS path, tracking error against the stream's commands (a pre-compensated
    stream's: against the plan's points, as the model's, SimulationReport.tracking_against); the feedrate
    error from the measured feedrate |p_k - p_(k-1)| / T (0 at the first tick).
    """

    capture: str  # the capture file
    ticks: int  # measured: the commands and as much of the hold as both the model and the capture have
    hold_ticks: int  # of them, after the last command
    capture_lead_rows: int  # rows before the stream, dropped (k holding its first value)
    capture_hold_rows: int  # rows of the capture after the plan's last tick
    as_received_max: dict[str, float] | None  # the largest |capture command - plan command| per axis, mm


@dataclass(frozen=True)
class SimulationReport(ServoReport):
    """What :func:`simulate` measured: the errors (:class:`ServoReport`) and the run they come from."""

    axes: list[str]
    period: float  # s
    ticks: int  # simulated: the commands and the settle hold
    command_ticks: int
    settle_time: float  # s of the hold after the last command
    settled: bool  # whether the table settled within MAX_HOLD
    servo: str  # the servo model's source
    measured: MeasuredReport | None = None  # the machine's run, when a capture was given
    precompensated: str | None = None  # the pre-compensation method the stream's header names
    tracking_against: str = "commands"  # "plan": the tracking errors are the plan's points - the table

    def as_dict(self) -> dict:
        """The fields by name, in order: the JSON form.  ``measured`` only when there is a capture,
        ``precompensated`` and ``tracking_against`` only for a pre-compensated stream (a report without them is
        what it always was)."""
        out = super().as_dict()
        for key in ("measured", "precompensated"):
            if out[key] is None:
                del out[key]
        if "measured" in out:  # the capture's own rapids as the model's: only when there were any
            out["measured"] = self.measured.as_dict()
        if out["tracking_against"] == "commands":
            del out["tracking_against"]
        return out


def series_columns(dim: int, program: bool = False, measured: bool = False) -> dict:
    """Where each quantity sits in a kept series (:func:`simulate`'s ``keep_series``): a column index or a slice.

    k, t, u, the commands, the model's positions, its contour error, the commanded and the model's feedrate, the
    contour error's foot (u, or for a *program* the block index plus the fraction of it, followed by the foot's
    point); then with a capture (*measured*) the machine's positions, contour error, feedrate (|dp|/T) and foot
    (and point), NaN on the ticks the capture does not have.
    """
    n = dim
    cols = {"k": 0, "t": 1, "u": 2, "cmd": slice(3, 3 + n), "act": slice(3 + n, 3 + 2 * n), "err": 3 + 2 * n,
            "v_cmd": 4 + 2 * n, "v_act": 5 + 2 * n, "foot": 6 + 2 * n}
    at = 7 + 2 * n
    if program:
        cols["foot_point"] = slice(at, at + n)
        at += n
    if measured:
        cols.update(meas=slice(at, at + n), err_meas=at + n, v_meas=at + n + 1, foot_meas=at + n + 2)
        at += n + 3
        if program:
            cols["foot_meas_point"] = slice(at, at + n)
            at += n
    cols["width"] = at
    return cols


def trace_columns(axes, measured: bool = False) -> list[str]:
    """The trace's columns; with *measured* the capture's beside them (MEASURED_COLUMNS)."""
    cols = []
    for c in TRACE_COLUMNS + (MEASURED_COLUMNS if measured else ()):
        cols.extend(c.format(a=a) for a in axes) if "{a}" in c else cols.append(c)
    return cols


# check_chunk's findings: the first row of each kind of fault (-1: none), in the order they are reported
_PERIOD, _BLOCK, _DOMAIN, _FAR, _FAR_AXIS = range(5)
_CHECKS = 5


@njit(cache=True)
def check_chunk(data, t_col, u_col, n_col, v_col, ax_cols, t0, period, tick, blocks, shifts, a, b, limit,
                u_out, cmd_out, v_out, bad):
    """One pass over a chunk of stream rows (m, columns): check them, and gather what the loop needs.

    Into *bad* (see _PERIOD ...): the first row whose time is off the uniform period t0 + k T,
    whose block n is not one of the path's *blocks*, whose path parameter is outside [a, b]
    (1e-12 relative slack), and the first command (row, axis) beyond +-limit mm.  Into u_out the
    path parameter (the block's u shifted by shifts[n]; with no shifts the column as it is),
    clipped to [a, b]; into cmd_out the axis columns *ax_cols*; into v_out the feedrate column.
    The same comparisons as NumPy's on whole columns, element by element, without the temporaries.
    """
    for j in range(bad.shape[0]):
        bad[j] = -1
    a_tol = a - 1e-12 * max(1.0, abs(a))
    b_tol = b + 1e-12 * max(1.0, abs(b))
    for r in range(data.shape[0]):
        expect = t0 + period * float(tick + r)
        if bad[_PERIOD] < 0 and abs(data[r, t_col] - expect) > PERIOD_TOL + 1e-12 * abs(expect):
            bad[_PERIOD] = r
        u = data[r, u_col]
        if n_col >= 0:
            block = data[r, n_col]
            if not (block == math.floor(block) and 0 <= block <= blocks - 1):
                if bad[_BLOCK] < 0:
                    bad[_BLOCK] = r
            elif shifts.shape[0] > 0:
                u = u + shifts[int(block)]
        if bad[_DOMAIN] < 0 and (u < a_tol or u > b_tol):
            bad[_DOMAIN] = r
        u_out[r] = min(max(u, a), b)
        for c in range(ax_cols.shape[0]):
            x = data[r, ax_cols[c]]
            cmd_out[r, c] = x
            if bad[_FAR] < 0 and abs(x) > limit:
                bad[_FAR] = r
                bad[_FAR_AXIS] = c
        v_out[r] = data[r, v_col]


class _Buffers:
    """Per-chunk arrays of the simulation loop, allocated once and reused (views of the first m rows)."""

    def __init__(self, axes: int):
        self.axes = axes
        self.rows = 0

    def _grow(self, m):
        if m > self.rows:
            self.rows = max(m, CHUNK_TICKS)
            self._u, self._v = np.empty(self.rows), np.empty(self.rows)
            self._cmd = np.empty((self.rows, self.axes))
            self._servo = tuple(np.empty((self.rows, self.axes)) for _ in range(3))

    def take(self, m):
        """(u, cmd, v) for a chunk of m rows."""
        self._grow(m)
        return self._u[:m], self._cmd[:m], self._v[:m]

    def servo(self, m):
        """(positions, velocities, voltages) for the closed loop's m rows."""
        self._grow(m)
        return tuple(x[:m] for x in self._servo)


def simulate(geometry, model: ServoModel, columns, chunks, *, name: str = "<stream>", trace=None,
             keep_series: bool = False, max_ticks: int = MAX_TICKS,
             max_ticks_hint: str = "", actual=None, check_received: bool = True,
             force_hint: str = "", window=None, measured_window=None,
             against_plan=False) -> tuple[dict, np.ndarray | None]:
    """Run a command stream through the servo model.

    Parameters
    ----------
    geometry : the job's :class:`~nurbsinterp.path.Path` (contour error is measured against
        its programmed blocks) or one NurbsCurve
    model : the servo model
    columns : the stream's column names (k, n, t, u, x, y[, z], v, a; a stream without n
        is on one curve, u its parameter)
    chunks : iterable of arrays (m, len(columns))
    trace : optional callable receiving arrays of rows with :func:`trace_columns`
    keep_series : keep a decimated trace for plots (the trace's columns and the contour error's foot u)
    max_ticks : the most ticks simulated, the commands and the settle hold together; a
        stream longer than that is refused when it passes the limit, a hold that would
        pass it before the hold is simulated (its length comes from a dry run of the
        servo loop alone, which costs a small part of a simulated tick); the refusal
        names the limit, followed by *max_ticks_hint* (how to raise it)
    actual : optional :class:`~nurbsinterp.capture.Capture`, the machine's real run of these
        commands.  Its measured positions go through a second :class:`ServoStats`, tick by tick
        with the same t, u (the seed of the foot search) and commands, and the measured feedrate
        |p_k - p_(k-1)| / T (the mean speed over the period ending at the tick; 0 at the first
        tick, where the plan starts at rest); the hold is measured over as many ticks as both
        the model's hold and the capture's have.  The capture must cover every command.  With a
        trace, the trace adds MEASURED_COLUMNS and has one row per measured tick.
    check_received : refuse a capture whose received commands (``*_cmd`` columns) differ from
        the plan's by more than capture.RECEIVED_ABS + RECEIVED_REL |x| (not of this plan, or
        misaligned); *force_hint* follows the refusal (how to measure it anyway)

    window : a look-ahead stream's measure (motion.contour.ProgramWindow): the contour error against the
        program's blocks around each tick's block, read as the stream advances; *geometry* is then None, the
        stream must have its ``n`` column, and the report's foot parameter is a block index plus the fraction of
        the block.  The kept series then adds the feet's points (one column per axis) after the foot.
    measured_window : with *window* and *actual*: the capture's own ProgramWindow over the same program (each
        window reads the program as far as its own positions need, and drops what lies behind them)
    against_plan : measure the tracking error (the model's and the capture's) against the plan's point of each
        tick, C(u) at the stream's u (a stream the interpolator wrote before acc/dec commands exactly that; the
        caller must not ask it of an acc/dec-after stream), not against the commands: for a pre-compensated
        stream, whose commands are shaped away from the plan.  True, False, or a
        callable asked once the stream is read (a CSV stream names its pre-compensation in its end mark).  A
        look-ahead stream (*window*) cannot: its commands lie on the blended path, not the program's; it is
        measured against its commands.

    Returns (report, decimated trace or None); ``report.measured`` the capture's errors.
    """
    path = geometry if isinstance(geometry, Path) else None
    curve = path.programmed if path is not None else geometry
    dim = curve.dim if window is None else window.dim
    if window is not None and actual is not None and measured_window is None:
        raise ValueError("a capture measured against a program's window needs its own window (measured_window)")
    refuse_counts(name, columns)
    axes = [a for a in ("x", "y", "z") if a in columns]
    if len(axes) != dim:
        raise StreamError(f"{name}: the stream has {len(axes)} axes ({','.join(axes)}), "
                          f"the job's curve is {dim}-D: is this stream from this job?")
    if window is not None and "n" not in columns:
        raise StreamError(f"{name}: the stream has no n column (the block of each tick), which measuring it against "
                          "the program's blocks needs: plan it with every column")
    missing = [a for a in axes if a not in model.axes]
    if missing:
        raise StreamError(f"{name}: the stream has a {missing[0]} axis, the servo model ({model.source}) has none; "
                          f"give a model with axes.{missing[0]} (the source tree's servo/example-xyz.yaml is an example "
                          f"of one with x, y and z)")
    ci = {c: columns.index(c) for c in ("k", "t", "u", "v")}
    ax_cols = np.array([columns.index(a) for a in axes], dtype=np.int64)
    n_col = columns.index("n") if "n" in columns else -1
    rapid_col = columns.index("rapid") if "rapid" in columns else -1  # a program's G0 ticks, measured apart
    blocks = 1 if path is None else len(path.blocks)
    shifts = np.zeros(0) if path is None else np.asarray(path.shifts, dtype=float)  # none: u is the curve's own
    if window is None:
        a, b = curve.domain
    else:  # each block's own u in [0, 1]; the block itself is checked against the program as it is read
        a, b = 0.0, 1.0
        blocks = 2 ** 53
    stats = ServoStats(curve, axes, window)
    plan_points = against_plan is not False and window is None
    measured = None if actual is None else _Measured(actual, curve, axes, check_received, force_hint, measured_window)
    series = Series() if keep_series else None
    closed = None
    period = None
    t0 = None
    last = last_planned = None
    last_rapid = False
    tick = 0
    bad = np.empty(_CHECKS, dtype=np.int64)
    buffers = _Buffers(len(axes))
    for data in chunks:
        m = data.shape[0]
        if m == 0:
            continue
        if period is None:
            if m < 2:
                raise StreamError(f"{name}: needs at least two ticks to know the period")
            t0 = data[0, ci["t"]]
            period = float(data[1, ci["t"]] - t0)
            closed = ClosedLoop(discretise(model, period, axes))
            if measured is not None:
                measured.period = period
        u, cmd, v_cmd = buffers.take(m)
        data = np.ascontiguousarray(data)  # one layout at the kernel's boundary (a transposed chunk compiled it twice)
        check_chunk(data, ci["t"], ci["u"], n_col, ci["v"], ax_cols, t0, period, tick, blocks, shifts, a, b,
                    MAX_COORDINATE, u, cmd, v_cmd, bad)
        t = data[:, ci["t"]]
        if bad[_PERIOD] >= 0:
            j = int(bad[_PERIOD])
            raise StreamError(f"{name}: tick {tick + j}: t = {float(t[j])!r} breaks the uniform period "
                              f"T = {period!r} s of the first two ticks")
        if bad[_BLOCK] >= 0:
            j = int(bad[_BLOCK])
            raise StreamError(f"{name}: tick {tick + j}: n = {float(data[j, n_col])!r} is not a block of the job's "
                              f"path (0 to {blocks - 1}): is this stream from this job?")
        if bad[_DOMAIN] >= 0:
            j = int(bad[_DOMAIN])
            where = ("the curve's domain" if path is None or len(path.blocks) == 1
                     else f"the domain of block {int(data[j, n_col])}")
            raise StreamError(f"{name}: tick {tick + j}: u = {float(data[j, ci['u']])!r} is outside {where}: "
                              "is this stream from this job?")
        if tick + m > max_ticks:
            raise SpecError(f"{name}: the stream has more ticks than the limit of {max_ticks:.3g}{max_ticks_hint}")
        if window is not None:  # the window's seed: the block, and the fraction of it
            u += data[:, n_col]
        if bad[_FAR] >= 0:
            j, c = int(bad[_FAR]), int(bad[_FAR_AXIS])
            raise StreamError(f"{name}: tick {tick + j}: {axes[c]} = {float(cmd[j, c])!r} mm is beyond the "
                              f"supported range of +-{MAX_COORDINATE:g} mm")
        block = None if measured is None else actual.commands(m)
        planned = curve.evaluate(u) if plan_points else None
        rapid = None if rapid_col < 0 else data[:, rapid_col] > 0.5
        _step(closed, stats, series, trace, tick, t, u, cmd, v_cmd, buffers, measured, block, planned, rapid)
        tick += m
        last, last_u = cmd[m - 1].copy(), float(u[m - 1])
        last_rapid = rapid is not None and bool(rapid[m - 1])
        last_planned = None if planned is None else planned[m - 1]
    if last is None:
        raise StreamError(f"{name}: the stream has a header but no ticks")
    if measured is not None:
        actual.end_commands()

    # hold the last command until the table settles: checked every `block` ticks (0.05 s), simulated
    # in chunks of at most HOLD_CHUNK rows, so that memory does not grow with block (1 ns: 5e7 ticks)
    block = max(1, int(round(0.05 / period)))
    tol = max(SETTLE_TOL, 2 * float(closed.loop.resolution.max()))
    held, settled = _settle_ticks(closed, last, block, period, tol, max_ticks - tick)
    if held is None:
        raise SpecError(f"{name}: the {tick} ticks of the stream and the hold until the table settles "
                        f"(checked every {block} ticks = 0.05 s at T = {period:g} s) need more than the limit of "
                        f"{max_ticks:.3g} ticks{max_ticks_hint}")
    done = 0
    while done < held:
        m = min(HOLD_CHUNK, held - done)
        t = t0 + period * np.arange(tick, tick + m)
        block = None
        if measured is not None:
            block = actual.hold(m) if measured.hold_ticks == done else actual.hold(0)  # a short hold ends it
            measured.hold_ticks += block.line.shape[0]
        _step(closed, stats, series, trace, tick, t, np.full(m, last_u), np.tile(last, (m, 1)), np.zeros(m), buffers,
              measured, block, None if last_planned is None else np.tile(last_planned, (m, 1)),
              np.full(m, last_rapid) if last_rapid else None)
        tick += m
        done += m
    plan = plan_points and (against_plan() if callable(against_plan) else bool(against_plan))
    result = None
    if measured is not None:
        actual.finish()
        result = measured.report(tick - held, plan)
    report = SimulationReport(**vars(stats.report(plan)), axes=axes, period=period, ticks=tick,
                              command_ticks=tick - held, settle_time=held * period, settled=settled,
                              servo=model.source, measured=result, tracking_against="plan" if plan else "commands")
    return report, (series.array() if series is not None else None)


def _settle_ticks(closed, cmd, block, period, tol, budget):
    """(ticks of the hold, whether it settled): the servo loop alone, on a copy of its state.

    The hold runs in blocks of *block* ticks until, over a whole block, every axis stays
    within *tol* of the held command *cmd*, or MAX_HOLD has passed (not settled).  None
    instead of the tick count when the hold would take more than *budget* ticks.  Chunks
    of at most HOLD_CHUNK rows: memory does not grow with the block or the hold.
    """
    loop = ClosedLoop(closed.loop)
    loop.state, loop.prev_cmd = closed.state.copy(), closed.prev_cmd.copy()
    rows = np.tile(cmd, (min(block, HOLD_CHUNK), 1))
    held = 0
    while held * period < MAX_HOLD:
        if held + block > budget:
            return None, False
        left = block
        off = 0.0  # the largest distance from the command over the block, every tick of it
        while left > 0:
            m = min(left, HOLD_CHUNK)
            off = max(off, float(np.abs(loop.run(rows[:m])[0] - cmd).max()))
            left -= m
        held += block
        if off <= tol:
            return held, True
    return held, False


def _step(closed, stats, series, trace, tick, t, u, cmd, v_cmd, buffers, measured=None, block=None, planned=None,
          rapid=None):
    act, vel, _ = closed.run(cmd, out=buffers.servo(cmd.shape[0]))
    err, speed = stats.update(t, u, cmd, act, v_cmd, vel, planned, rapid)
    n = 0
    if measured is not None:
        n = block.line.shape[0]
        err_m, speed_m = measured.update(tick, t[:n], u[:n], cmd[:n], v_cmd[:n], block,
                                         None if planned is None else planned[:n], None if rapid is None else rapid[:n])
    if trace is not None or series is not None:
        rows = np.column_stack([np.arange(tick, tick + t.shape[0]), t, u, cmd, act, err, v_cmd, speed])
        if trace is not None:
            if measured is None:
                trace(rows)
            elif n:
                trace(np.column_stack([rows[:n], block.position, err_m, speed_m]))
        if series is not None:
            # the feet: the plot's magnified path; a program's feet are block indices, their points taken now
            points = getattr(stats.window, "points", None)
            if measured is None:
                series.add(tick, np.column_stack([rows, stats.feet]), points)
            else:
                _keep_measured(series, tick, np.column_stack([rows, stats.feet]), points, measured, n, err_m, speed_m,
                               block)
    return act


def _keep_measured(series, tick, rows, points, measured, n, err_m, speed_m, block):
    """The kept rows with the capture's columns beside the model's (series_columns): NaN past the capture's n rows."""
    m = rows.shape[0]
    take = series.take(tick, m)
    kept = rows[take]
    parts = [kept]
    if points is not None:
        parts.append(points(kept[:, -1]))
    dim = block.position.shape[1]
    meas = np.full((m, dim + 3), np.nan)
    meas[:n, :dim] = block.position
    meas[:n, dim] = err_m
    meas[:n, dim + 1] = speed_m
    meas[:n, dim + 2] = measured.stats.feet[:n]
    meas = meas[take]
    parts.append(meas)
    if points is not None:
        feet = meas[:, -1]
        have = np.isfinite(feet)
        at = np.full((feet.shape[0], dim), np.nan)
        at[have] = measured.stats.window.points(feet[have])
        parts.append(at)
    series.append(np.column_stack(parts))


class _Measured:
    """The capture's side of :func:`simulate`: its positions through a second ServoStats."""

    def __init__(self, capture, curve, axes, check_received, force_hint, window=None):
        self.capture, self.axes = capture, list(axes)
        self.stats = ServoStats(curve, axes, window)
        self.check, self.force_hint = check_received, force_hint
        self.period = None
        self.prev = None  # the last measured position (the finite-difference feedrate)
        self.received = np.zeros(len(self.axes)) if capture.has_commands else None
        self.hold_ticks = 0

    def update(self, tick, t, u, cmd, v_cmd, block, planned=None, rapid=None):
        """Ticks tick.. of the plan (t, u, cmd, v_cmd; *planned* its points; *rapid* its ticks on rapids) with the
        capture's rows *block*: (contour error, feedrate)."""
        pos = block.position
        m = pos.shape[0]
        if m == 0:
            return np.empty(0), np.empty(0)
        if self.received is not None:
            self._check_received(tick, cmd, block)
        vel = np.empty_like(pos)
        vel[0] = 0.0 if self.prev is None else (pos[0] - self.prev) / self.period
        np.subtract(pos[1:], pos[:-1], out=vel[1:])
        vel[1:] /= self.period
        self.prev = pos[m - 1].copy()
        return self.stats.update(t, np.ascontiguousarray(u), cmd, pos, np.ascontiguousarray(v_cmd), vel, planned,
                                 None if rapid is None else rapid[:m])

    def _check_received(self, tick, cmd, block):
        dev = received_deviation(self.capture.name, tick, self.axes, cmd, block, self.check, self.force_hint)
        np.maximum(self.received, dev, out=self.received)

    def report(self, command_ticks, against_plan=False) -> MeasuredReport:
        cap = self.capture
        return MeasuredReport(**vars(self.stats.report(against_plan)), capture=cap.name, ticks=command_ticks + self.hold_ticks,
                              hold_ticks=self.hold_ticks, capture_lead_rows=cap.lead_rows,
                              capture_hold_rows=cap.hold_rows,
                              as_received_max=None if self.received is None else
                              {a: float(v) for a, v in zip(self.axes, self.received)})


def check_stream_belongs(curve, fingerprint: str, columns, chunks, meta: dict, name: str, hint: str = ""):
    """Refuse a stream that was not planned from this curve; yield its chunks unchanged otherwise.

    A stream from `plan` names its curve's fingerprint (binary: in its header; both: in its end
    mark, checked once the stream is read): it must be the job's.  A stream without one in its
    header (CSV) must also start where the path starts: its first commanded point within
    START_TOL (plus the CSV's 9-decimal rounding at large coordinates) of C(a).  A stream from
    another job that starts at the same point can only be caught by the fingerprint.  *hint*
    follows the question a refusal ends with (how the caller's user simulates the stream anyway).
    """
    question = f"is this stream from this job?{hint}"

    def check_fingerprint():
        theirs = meta.get("curve")
        if meta.get("planner") == "look-ahead":
            raise StreamError(f"{name}: the stream was planned with look-ahead across the blocks (plan --tolerance): "
                              "simulate it with --tolerance as it was planned")
        if theirs is not None and theirs != fingerprint:
            raise StreamError(f"{name}: the stream was planned from another curve (fingerprint {theirs}; "
                              f"the job's curve is {fingerprint}): {question}")
        return theirs

    theirs = check_fingerprint()
    axes = [columns.index(a) for a in ("x", "y", "z") if a in columns]
    first = True
    for data in chunks:
        if first and data.shape[0] and len(axes) == curve.dim:
            start = curve.evaluate(curve.domain[0])
            off = float(np.linalg.norm(data[0, axes] - start))
            if theirs is None and off > START_TOL * (1.0 + float(np.abs(start).max())):
                raise StreamError(f"{name}: the first command {_point(data[0, axes])} is {off:.6g} mm from the "
                                  f"start of the job's path {_point(start)}: {question}")
            first = False
        yield data
    check_fingerprint()  # a CSV stream names its curve in its end mark, read only now


def check_look_ahead_stream(fingerprint: str, chunks, meta: dict, name: str, hint: str = "",
                            tolerance: float | None = None):
    """Refuse a stream that was not planned with look-ahead from this program within *tolerance* (mm; None: the
    program's own); its chunks otherwise.

    Its header (binary) or end mark (CSV, checked once the stream is read) names the planner, the tolerance (a
    stream written before it was named is taken as it comes) and the program's fingerprint
    (config.gcode.ProgramStream's: the program's bytes and the reader's options).  The tolerance must be the
    plan's: the measures look for the nearest point of the path within the tolerance of each command."""
    question = f"is this stream from this job?{hint}"
    from .streams import tolerance_mark, tolerance_words

    ours = tolerance_mark(tolerance)

    def check(at_end):
        planner = meta.get("planner")
        if planner is None and not at_end and "curve" not in meta:
            return  # a CSV stream: its end mark says
        if planner != "look-ahead":
            raise StreamError(f"{name}: the stream was not planned with look-ahead (plan --tolerance): simulate it "
                              "without --tolerance")
        theirs = meta.get("curve")
        if theirs is not None and theirs != fingerprint:
            raise StreamError(f"{name}: the stream was planned from another program (fingerprint {theirs}; the job's "
                              f"is {fingerprint}): {question}")
        planned = meta.get("tolerance")
        if planned is not None and planned != ours:
            raise StreamError(f"{name}: the stream was planned within {tolerance_words(planned)}, not within "
                              f"{tolerance_words(ours)}: take it within the tolerance it was planned with")

    def checked():
        yield from chunks
        check(True)

    check(False)  # the header, before anything is simulated
    return checked()


START_TOL = 1e-6  # mm per mm of coordinate magnitude: far above CSV rounding (5e-10 mm), far below any real mismatch


def _point(p) -> str:
    return "(" + ", ".join(f"{v:.6g}" for v in p) + ")"
