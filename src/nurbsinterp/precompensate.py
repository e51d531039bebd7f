"""Servo-lag pre-compensation: shape the axis commands so that the table, not the command, follows the path.

Each axis of the servo table (servo.py) maps its command c to its position x through
the sampled closed loop, a rational transfer function in the delay operator q⁻¹::

    x_k = H(q) c_k,   H = q^-d N(q^-1) / D(q^-1),   D(0) = 1,  d ≥ 1 (the relative degree)

from the plant's exact ZOH sample, the P position loop and the velocity feed-forward
(:func:`closed_loop`).  A pre-compensator is a filter C per axis so that H C is the
identity (or close to it): fed C r instead of the planned commands r, the table's
positions are r.

Methods (:data:`METHODS`)
    exact
        c = H⁻¹ r = D/N r_{k+d}.  N's zeros inside the unit circle become poles of a
        causal recursion; those outside it (every axis of the paper's table has one: the
        sampling zero near −3 that a ZOH puts on a plant of relative degree ≥ 2) cannot be
        inverted causally, so they become poles of an anticausal recursion, run over the
        preview: 1/(1 − u q⁻¹) = −Σ_{j≥1} u^-j q^j, the stable non-causal inverse (the
        discrete form of Devasia, Chen & Paden's).  Its taps decay as |u|^-j, so N of them
        and the rest summed in closed form on the last value read leave an error that the
        design bounds and reports (:attr:`AxisFilter.tail_abs`).
    zpetc
        Tomizuka's zero-phase-error tracking controller (1987): the zeros outside (or on)
        the unit circle are not inverted; their phase is cancelled instead,
        c = D/Ns · Nu(q)/Nu(1)² r_{k+d}, so that H C = Nu(q⁻¹)Nu(q)/Nu(1)², real, one at
        zero frequency, 1 − O(ω²) above.  A preview of d plus the number of those zeros.
    match
        No inverse: every axis is given the other axes' closed loops, c_i = Π_{j≠i} H_j r_i,
        so that all axes follow with the same dynamics Π H_j.  The path keeps its shape at
        a common lag (a circle stays round but is traced late: the lag still cuts a curve's
        tight turns), causal, nothing to preview.

Streaming
    Every method is one causal recursion followed by one anticausal FIR over a preview of
    L ticks (:class:`Design`): command k is final once reference k + L is read, so a
    stream of any length runs in memory O(L) (:class:`Precompensator`), and after the last
    reference the reference is held (the path ends at rest) for L ticks to flush: the tick
    count is preserved.  The filters work on r − r₀ from a zero state: the table is at rest
    at the path's start.  The first and the last commands are the path's own (r₀ and
    r_{K−1}), so the table starts where the path starts and settles where it ends: the ideal
    inverse would move before the stream begins and go on moving after it ends, which a
    stream of K commands cannot.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ._jit import njit
from .errors import SpecError, StreamError
from .names import PRECOMPENSATION as METHODS
from .servo import ServoModel, discretise, sample_axis

#: A zero this close to the unit circle has no bounded inverse (exact refuses it; zpetc cancels its phase).
UNIT_CIRCLE_MARGIN = 1e-6
#: The automatic preview keeps the anticausal taps beyond it below this share of their sum.
PREVIEW_TOL = 1e-16
#: the stream runs on past the plan's last tick, the path's end held, until every shaped command is within this of
#: it (mm): the inverse's own decay (a model's slow zeros become slow poles) is never cut off by a jump
SETTLED = 1e-9
MAX_SETTLE_TICKS = 10_000  # beyond it the last command is set to the end all the same (a pole all but on the circle)
SETTLE_CHUNK = 256
MAX_PREVIEW = 4096


@dataclass(frozen=True)
class AxisLoop:
    """One axis' closed loop, command to position: H = q^-delay num(q⁻¹)/den(q⁻¹), den[0] = 1."""

    name: str
    num: np.ndarray
    den: np.ndarray
    delay: int

    @property
    def zeros(self) -> np.ndarray:
        return np.roots(self.num) if self.num.size > 1 else np.empty(0)

    @property
    def poles(self) -> np.ndarray:
        return np.roots(self.den) if self.den.size > 1 else np.empty(0)

    def dc_gain(self) -> float:
        return float(self.num.sum() / self.den.sum())


def closed_loop(model: ServoModel, period: float, names=None) -> list[AxisLoop]:
    """The closed loop of each axis (servo.py's controller around the sampled plant) as polynomials.

    Plant, voltage to position: P = q⁻¹ Pn/Pd with Pd the characteristic polynomial of the
    sampled matrix and Pn from its Markov parameters h_i = e·A^(i−1)·B (no cancellation of
    two characteristic polynomials).  Controller: u = F c − Kp x, F = Kp + Kv/T (1 − q⁻¹).
    Closed loop: H = q⁻¹ Pn F / (Pd + Kp q⁻¹ Pn).  Refuses an unstable closed loop (as
    :func:`~nurbsinterp.servo.discretise` does).
    """
    names = list(names or model.names)
    discretise(model, period, names)  # the checks: sampled without overflow, closed loop stable
    loops = []
    for name in names:
        ax = model.axes[name]
        Ad, Bd, _ = sample_axis(model.source, name, ax, period)
        n = Ad.shape[0]
        pd = np.real(np.poly(Ad))
        markov = np.empty(n)
        v = Bd.copy()
        for i in range(n):
            markov[i] = v[-1]
            v = Ad @ v
        pn = np.array([np.dot(pd[:j + 1][::-1], markov[:j + 1]) for j in range(n)])
        f = np.array([ax.kp + ax.kv / period, -ax.kv / period])
        num = np.convolve(pn, f)
        den = pd.copy()
        den[1:] += ax.kp * pn
        loops.append(_trimmed(name, num, den))
    return loops


def _trimmed(name, num, den) -> AxisLoop:
    """Exact zeros off both ends: leading ones of num are more delay, trailing ones of both no zero or pole."""
    delay = 1
    lead = np.flatnonzero(num)
    num = num[lead[0]:lead[-1] + 1]
    delay += int(lead[0])
    den = np.trim_zeros(den, "b")
    return AxisLoop(name, num / den[0], den / den[0], delay)


# --------------------------------------------------------------------------- design


@dataclass(frozen=True)
class AxisFilter:
    """One axis' pre-compensator: w = num/den r_{k+lead} (causal), c_k = Σ_j taps[j] w_{k+j} + tail·w_{k+N}.

    ``series`` is the anticausal part's whole impulse response when it is infinite (the
    exact inverse's outside zeros), from which a longer preview takes its taps; ``tail_abs``
    is Σ_{j>N} |g_j|: the held-value tail errs by at most that times the largest change of
    w beyond the preview.
    """

    name: str
    num: np.ndarray
    den: np.ndarray
    lead: int
    taps: np.ndarray
    tail: float
    tail_abs: float
    inverted: tuple  # the closed loop's zeros the filter inverts (causally or not)
    kept: tuple  # those it leaves (zpetc: phase cancelled; match: every one)
    series: np.ndarray | None = None

    @property
    def preview(self) -> int:
        return self.taps.size - 1

    def with_preview(self, taps: int) -> "AxisFilter":
        """The same filter with N = *taps* anticausal taps (more of the series, or zeros for a finite FIR)."""
        if self.series is not None:
            return _from_series(self, self.series, taps)
        if taps < self.preview:
            raise ValueError("a finite filter cannot be shortened")
        padded = np.concatenate([self.taps, np.zeros(taps - self.preview)])
        return replace(self, taps=padded)


def _from_series(f: AxisFilter, series: np.ndarray, n: int) -> AxisFilter:
    total = float(series.sum())
    head = series[:n + 1]
    if head.size < n + 1:
        head = np.concatenate([head, np.zeros(n + 1 - head.size)])
    return replace(f, taps=head, tail=total - float(head.sum()), tail_abs=float(np.abs(series[n + 1:]).sum()))


@dataclass(frozen=True)
class Design:
    """The pre-compensator of every axis, with one common latency: command k leaves once reference k + latency is read."""

    method: str
    period: float
    axes: list
    filters: list
    loops: list
    source: str

    @property
    def latency(self) -> int:
        return max(f.lead + f.preview for f in self.filters)


def design(model: ServoModel, period: float, method: str = "exact", names=None, preview: int | None = None) -> Design:
    """Design the pre-compensator of *method* for the axes *names* of *model* at *period*.

    *preview* (exact only): the anticausal taps of every axis; None chooses the fewest that
    leave a tail below :data:`PREVIEW_TOL` of their sum.  Raises SpecError naming the
    axis and the zero when the method cannot invert this model.
    """
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}")
    missing = [a for a in (names or ()) if a not in model.axes]
    if missing:
        raise SpecError(f"{model.source}: the servo model has no {missing[0]} axis, the path has one; "
                        f"give a model with axes.{missing[0]}")
    loops = closed_loop(model, period, names)
    if method == "match":
        filters = [_match(loop, [other for other in loops if other is not loop]) for loop in loops]
    else:
        filters = [(_exact if method == "exact" else _zpetc)(model.source, loop, period, preview) for loop in loops]
    # at least one tick, so that the last command is known to be the last before it leaves
    latency = max(1, max(f.lead + f.preview for f in filters))
    # one latency for all axes, so that a row leaves whole: the axes with less to preview take
    # more taps of their series (more exact), or zeros (a delay)
    filters = [f.with_preview(latency - f.lead) for f in filters]
    return Design(method, period, [lp.name for lp in loops], filters, loops, model.source)


def _split(source, loop, period, refuse_unit_circle):
    zeros = loop.zeros
    near = np.abs(np.abs(zeros) - 1.0) < UNIT_CIRCLE_MARGIN
    if refuse_unit_circle and near.any():
        z = zeros[near][0]
        raise SpecError(f"{source}: axes.{loop.name}: the closed loop has a zero at z = {zero_text(z)} on the unit "
                        f"circle at T = {period:g} s: it has no bounded inverse (the zpetc method leaves it)")
    if (np.abs(zeros - 1.0) < UNIT_CIRCLE_MARGIN).any():
        raise SpecError(f"{source}: axes.{loop.name}: the closed loop has a zero at z = 1 at T = {period:g} s: "
                        "it passes no steady motion, nothing can pre-compensate it")
    outside = np.abs(zeros) >= 1.0 - (0.0 if refuse_unit_circle else UNIT_CIRCLE_MARGIN)
    return zeros[~outside], zeros[outside]


def _exact(source, loop, period, preview):
    inside, outside = _split(source, loop, period, refuse_unit_circle=True)
    den = loop.num[0] * np.real(np.poly(inside))
    f = AxisFilter(loop.name, loop.den.copy(), den, loop.delay, np.ones(1), 0.0, 0.0,
                   tuple(loop.zeros), ())
    if outside.size == 0:
        return f if preview is None else f.with_preview(preview)
    # 1/Π(1 − u q⁻¹) = Π(−1/u) q^m / Π(1 − q/u): a power series in q (the future), each factor a geometric one
    rho = float(np.max(1.0 / np.abs(outside)))
    length = MAX_PREVIEW + outside.size + 1
    if rho ** MAX_PREVIEW > PREVIEW_TOL:
        z = outside[np.argmax(1.0 / np.abs(outside))]
        raise SpecError(f"{source}: axes.{loop.name}: the closed loop's zero at z = {zero_text(z)} is so close to "
                        f"the unit circle that its inverse needs more than {MAX_PREVIEW} ticks of preview at "
                        f"T = {period:g} s (the zpetc method does not invert it)")
    h = np.zeros(length, dtype=complex)
    h[0] = 1.0
    for u in outside:
        # h ← h / (1 − q/u): the running sum h'_j = h_j + h'_{j−1}/u
        inv = 1.0 / u
        for j in range(1, length):
            h[j] += h[j - 1] * inv
    scale = np.prod(-1.0 / outside)
    series = np.zeros(length)
    m = outside.size
    series[m:] = np.real(scale * h[:length - m])
    f = replace(f, series=series)
    if preview is None:
        absolute = np.abs(series)
        # tail[n] = Σ_{j>n} |g_j|: the fewest taps whose tail is below the tolerance
        tails = np.concatenate([np.cumsum(absolute[::-1])[::-1][1:], [0.0]])
        preview = int(np.flatnonzero(tails <= PREVIEW_TOL * absolute.sum())[0])
    if preview > MAX_PREVIEW:
        raise ValueError(f"a preview of {preview} ticks is above the supported {MAX_PREVIEW}")
    return _from_series(f, series, preview)


def _zpetc(source, loop, period, preview):
    inside, outside = _split(source, loop, period, refuse_unit_circle=False)
    den = loop.num[0] * np.real(np.poly(inside))
    nu = np.real(np.poly(outside))  # Nu(q⁻¹) = Π(1 − u q⁻¹); Nu(q) has the same coefficients on q^j
    taps = nu / nu.sum() ** 2
    f = AxisFilter(loop.name, loop.den.copy(), den, loop.delay, taps, 0.0, 0.0, tuple(inside), tuple(outside))
    return f if preview is None or preview <= f.preview else f.with_preview(preview)


def _match(loop, others):
    num, den = np.ones(1), np.ones(1)
    for other in others:
        num = np.convolve(num, np.concatenate([np.zeros(other.delay), other.num]))
        den = np.convolve(den, other.den)
    return AxisFilter(loop.name, num, den, 0, np.ones(1), 0.0, 0.0, (), tuple(loop.zeros))


def zero_text(z, digits: int = 10) -> str:
    """A zero as text; 10 digits (the refusals') tell one 1e-6 off the unit circle from one on it."""
    z = complex(z)
    return f"{z.real:.{digits}g}" if abs(z.imag) < 1e-12 else f"{z.real:.{digits}g}{z.imag:+.{digits}g}j"


# --------------------------------------------------------------------------- the per-tick filter


@njit(cache=True)
def shape_chunk(s, out, num, den, taps, tail, preview, s_hist, w_hist, w_peak):
    """Pre-compensate the rows of s (m, axes), references minus r₀, one tick at a time.

    Per axis i, for each reference s_j read: w_m = (Σ_t num_t s_{j−t} − Σ_{t≥1} den_t w_{m−t}) / den_0
    (m = j − lead: the causal recursion), then command k = m − N: out[j] = Σ_t taps_t w_{k+t} +
    tail·w_m.  out[j] is command j − latency (garbage while that is negative: the caller drops it).
    s_hist (axes, len(num)) and w_hist (axes, ≥ max(N + 1, len(den) − 1)) carry the past from
    chunk to chunk, newest first; w_peak (axes) the largest |w| so far (for the tail's error bound).
    """
    for i in range(s.shape[1]):
        n_num = num.shape[1]
        n_den = den.shape[1]
        n_w = w_hist.shape[1]
        n = preview[i]
        for j in range(s.shape[0]):
            for t in range(n_num - 1, 0, -1):
                s_hist[i, t] = s_hist[i, t - 1]
            s_hist[i, 0] = s[j, i]
            acc = 0.0
            for t in range(n_num):
                acc += num[i, t] * s_hist[i, t]
            for t in range(1, n_den):
                acc -= den[i, t] * w_hist[i, t - 1]
            w = acc / den[i, 0]
            for t in range(n_w - 1, 0, -1):
                w_hist[i, t] = w_hist[i, t - 1]
            w_hist[i, 0] = w
            if abs(w) > w_peak[i]:
                w_peak[i] = abs(w)
            c = tail[i] * w
            for t in range(n + 1):
                c += taps[i, t] * w_hist[i, n - t]
            out[j, i] = c


class Precompensator:
    """Run a :class:`Design` over a command stream in chunks: same rows, same order, then the settling rows.

    ``run(chunks)`` yields (rows, references): the stream's rows with the axis columns
    replaced by the pre-compensated commands, and the planned commands they replace
    ((m, axes), for a check against the table's positions).  Holds latency + one chunk of
    rows at a time.  After the last row the path's end is held (``settle_ticks`` more rows,
    copies of the last with k and t running on) until every command is within SETTLED of it:
    the shaping's own decay is sent whole, and the last command is the end itself.
    """

    def __init__(self, plan: Design, columns):
        self.design = plan
        missing = [a for a in plan.axes if a not in columns]
        if missing:
            raise ValueError(f"the stream has no column {missing[0]!r}")
        self.axes = [list(columns).index(a) for a in plan.axes]
        f = plan.filters
        n_ax = len(f)
        self.num = _padded([x.num for x in f])
        self.den = _padded([x.den for x in f])
        self.taps = _padded([x.taps for x in f])
        self.tail = np.array([x.tail for x in f])
        self.preview = np.array([x.preview for x in f], dtype=np.int64)
        self.s_hist = np.zeros((n_ax, self.num.shape[1]))
        self.w_hist = np.zeros((n_ax, max(int(self.preview.max()) + 1, self.den.shape[1] - 1, 1)))
        self.w_peak = np.zeros(n_ax)
        self.latency = plan.latency
        self.ticks = 0
        self.settle_ticks = 0  # rows after the stream's last, the end held while the shaping settles
        self.settle_jump = 0.0  # mm: what setting the last command to the end moved it (SETTLED, but past the limit)
        self.shaping_max = np.zeros(n_ax)  # max |c − r| per axis
        cols = list(columns)
        self._k = cols.index("k") if "k" in cols else -1
        self._t = cols.index("t") if "t" in cols else -1

    @property
    def truncation_bound(self) -> np.ndarray:
        """Per axis, mm: the most the finite preview can have moved a command (tail_abs × 2 max |w|)."""
        return np.array([f.tail_abs for f in self.design.filters]) * 2.0 * self.w_peak

    def run(self, chunks):
        latency = self.latency
        pending = None  # the rows read whose commands are not final yet (at most latency)
        r0 = None
        last = None
        for data in chunks:
            if data.shape[0] == 0:
                continue
            refs = data[:, self.axes]
            if r0 is None:
                r0 = refs[0].copy()
            last = data[-1:]
            shaped = self._shape(refs - r0)
            rows = data if pending is None else np.concatenate([pending, data])
            first = self.ticks - latency  # the tick of shaped[0]
            self.ticks += data.shape[0]
            skip = max(0, -first)
            ready = shaped.shape[0] - skip
            start = rows.shape[0] - data.shape[0] - latency + skip  # the row of that tick
            if ready > 0:
                yield self._emit(rows[start:start + ready], shaped[skip:], r0, first + skip == 0)
            keep = min(latency, self.ticks)
            pending = rows[rows.shape[0] - keep:].copy()
        if r0 is None:
            return
        # flush: the path ends at rest, its last reference held for latency ticks
        end = last[0, self.axes]
        held = np.repeat(last[:, self.axes] - r0, latency, axis=0)
        shaped = self._shape(held)
        first = self.ticks - latency
        skip = max(0, -first)
        rows, refs = self._emit(pending, shaped[skip:], r0, first + skip == 0)
        # then held on until the commands settle on it (the inverse's slow poles decay after the path has stopped)
        step = np.zeros(len(last[0]))
        if self._k >= 0:
            step[self._k] = 1.0
        if self._t >= 0:
            step[self._t] = self.design.period
        base = last[0]
        while np.abs(rows[-1, self.axes] - end).max() > SETTLED and self.settle_ticks < MAX_SETTLE_TICKS:
            yield rows, refs
            m = min(SETTLE_CHUNK, MAX_SETTLE_TICKS - self.settle_ticks)
            shaped = self._shape(np.repeat(end[None, :] - r0, m, axis=0))
            commands = r0 + shaped
            off = np.abs(commands - end).max(axis=1)
            within = np.flatnonzero(off[::-1] > SETTLED)  # the rows from the last one beyond SETTLED on are settled
            if within.size and within[0] == 0:
                keep = m  # not settled by this chunk's end: all of it, and more
            else:
                keep = m - (within[0] if within.size else m) + 1  # up to the first of the settled rows
            ticks = np.arange(self.settle_ticks + 1, self.settle_ticks + keep + 1, dtype=float)
            rows = base + ticks[:, None] * step
            refs = np.tile(end, (keep, 1))
            rows[:, self.axes] = commands[:keep]
            np.maximum(self.shaping_max, np.abs(commands[:keep] - end).max(axis=0), out=self.shaping_max)
            self.settle_ticks += keep
        self.settle_jump = float(np.abs(rows[-1, self.axes] - end).max())
        rows[-1, self.axes] = refs[-1]  # the last command is the path's end: the table settles there
        yield rows, refs

    def _shape(self, s):
        s = np.ascontiguousarray(s)  # one layout at the kernel's boundary (a transposed chunk compiled it twice)
        out = np.empty_like(s)
        shape_chunk(s, out, self.num, self.den, self.taps, self.tail, self.preview,
                    self.s_hist, self.w_hist, self.w_peak)
        return out

    def _emit(self, rows, shaped, r0, starts):
        rows = rows.copy()
        refs = rows[:, self.axes].copy()
        commands = r0 + shaped
        if starts:
            commands[0] = refs[0]  # the first command is the path's start, where the table rests
        np.maximum(self.shaping_max, np.abs(commands - refs).max(axis=0), out=self.shaping_max)
        rows[:, self.axes] = commands
        return rows, refs


def _padded(arrays) -> np.ndarray:
    width = max(a.size for a in arrays)
    out = np.zeros((len(arrays), width))
    for i, a in enumerate(arrays):
        out[i, :a.size] = a
    return out


# --------------------------------------------------------------------------- what the commands do to the model


class ModelCheck:
    """The designed model driven by the pre-compensated commands and, beside it, by the planned ones.

    ``update(commands, references)`` per chunk (rows of ticks, (m, axes)) gathers, per axis:
    ``residual`` max |x − r| (the model's table against the planned commands: what the
    design leaves, with the model's own saturation if it has one) and ``residual_tick`` the
    tick (0-based, of the stream) where it is, ``lag`` the same for the
    planned commands fed as they are (the uncompensated following error), the peak voltages
    of both, and the peak command acceleration |Δ²c|/T² of both.  A voltage budget adds a
    third run with the voltage clipped there (``residual_saturated``: what saturating would
    do) and counts the ticks above it; an acceleration budget counts the ticks above it.
    """

    def __init__(self, model: ServoModel, period: float, axes, voltage_budget: float | None = None,
                 accel_budget: float | None = None):
        import dataclasses

        from .servo import ClosedLoop

        loop = discretise(model, period, axes)
        self.period = period
        self.axes = list(axes)
        self._shaped, self._plain = ClosedLoop(loop), ClosedLoop(loop)
        self._saturated = None
        if voltage_budget is not None:
            self._saturated = ClosedLoop(dataclasses.replace(loop, limit=np.minimum(loop.limit, voltage_budget)))
        self.voltage_budget, self.accel_budget = voltage_budget, accel_budget
        n = len(self.axes)
        self.residual, self.lag, self.residual_saturated = np.zeros(n), np.zeros(n), np.zeros(n)
        self.residual_tick = np.zeros(n, dtype=np.int64)
        self.voltage, self.voltage_plain = np.zeros(n), np.zeros(n)
        self.accel, self.accel_plain = np.zeros(n), np.zeros(n)
        self.over_voltage = self.over_accel = 0
        self.first_over_voltage = self.first_over_accel = None
        self.ticks = 0
        self._past = None  # the last two commands and references: the acceleration's carry

    def update(self, commands: np.ndarray, references: np.ndarray) -> None:
        pos, _, volt = self._shaped.run(commands)
        if commands.shape[0]:
            error = np.abs(pos - references)
            k = np.argmax(error, axis=0)
            worst = error[k, np.arange(error.shape[1])]
            larger = worst > self.residual  # the first tick of the largest: a later equal one does not move it
            self.residual_tick[larger] = self.ticks + k[larger]
            self.residual[larger] = worst[larger]
        np.maximum(self.voltage, np.abs(volt).max(axis=0), out=self.voltage)
        pos, _, volt_plain = self._plain.run(references)
        np.maximum(self.lag, np.abs(pos - references).max(axis=0), out=self.lag)
        np.maximum(self.voltage_plain, np.abs(volt_plain).max(axis=0), out=self.voltage_plain)
        if self._saturated is not None:
            pos, _, _ = self._saturated.run(commands)
            np.maximum(self.residual_saturated, np.abs(pos - references).max(axis=0), out=self.residual_saturated)
            over = (np.abs(volt) > self.voltage_budget).any(axis=1)
            self.first_over_voltage, self.over_voltage = self._count(over, self.first_over_voltage, self.over_voltage)
        if self._past is None:
            self._past = (np.repeat(commands[:1], 2, axis=0), np.repeat(references[:1], 2, axis=0))
        both = []
        for past, now in zip(self._past, (commands, references)):
            c = np.concatenate([past, now])
            both.append(np.abs(c[2:] - 2.0 * c[1:-1] + c[:-2]) / self.period ** 2)
        np.maximum(self.accel, both[0].max(axis=0), out=self.accel)
        np.maximum(self.accel_plain, both[1].max(axis=0), out=self.accel_plain)
        if self.accel_budget is not None:
            over = (both[0] > self.accel_budget).any(axis=1)
            self.first_over_accel, self.over_accel = self._count(over, self.first_over_accel, self.over_accel)
        self._past = tuple(np.concatenate([p, n])[-2:] for p, n in zip(self._past, (commands, references)))
        self.ticks += commands.shape[0]

    def _count(self, over, first, count):
        hits = np.flatnonzero(over)
        if hits.size and first is None:
            first = self.ticks + int(hits[0])
        return first, count + int(hits.size)


# --------------------------------------------------------------------------- a stream's period


def stream_period(first: np.ndarray, columns, name: str) -> float:
    """The period T of a stream from its first chunk's first two ticks (refused: fewer than two)."""
    if first.shape[0] < 2:
        raise StreamError(f"{name}: needs at least two ticks to know the period")
    t = columns.index("t")
    return float(first[1, t] - first[0, t])


def uniform(chunks, columns, name: str, period: float):
    """Yield the chunks, refusing the first tick whose t is off t₀ + k T (T the first two ticks')."""
    from .simulation import PERIOD_TOL

    t_col = columns.index("t")
    tick, t0 = 0, None
    for data in chunks:
        if data.shape[0]:
            t = data[:, t_col]
            if t0 is None:
                t0 = float(t[0])
            expect = t0 + period * np.arange(tick, tick + t.size, dtype=float)
            off = np.flatnonzero(np.abs(t - expect) > PERIOD_TOL + 1e-12 * np.abs(expect))
            if off.size:
                j = int(off[0])
                raise StreamError(f"{name}: tick {tick + j}: t = {float(t[j])!r} breaks the uniform period "
                                  f"T = {period!r} s of the first two ticks")
            tick += t.size
        yield data
