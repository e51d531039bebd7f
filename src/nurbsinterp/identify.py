"""Identifying a servo loop from what it did: each axis' plant fitted to a capture of the machine.

A user streams a job into the machine and records, every servo period, the commands and the
feedback (:mod:`capture`).  Given the controller's gains (a servo file's kp and kv, or LinuxCNC's
pid parameters, :func:`parse_pid`), :func:`identify` fits each axis' plant G(s) in the families
below so that the model's closed loop, fed the plan's commands, reproduces the captured positions,
and returns a model :func:`~nurbsinterp.servo.load_servo` reads back (:func:`servo_yaml`).

Why these choices
    - The model simulated is the one ``simulate``, ``compare`` and ``precompensate`` run
      (:func:`~nurbsinterp.servo.discretise`, :func:`~nurbsinterp.servo.servo_chunk`): the fit and its
      users cannot disagree.  One evaluation is an exact ZOH sample and one compiled pass over the
      capture (about 0.1 ms per 1 000 ticks).
    - The gains are given, never fitted: (G, kp, kv) and (αG, kp/α, kv/α) move the table alike, so
      positions alone cannot tell them apart.
    - The parameters are fitted as logarithms (relative steps; a positive K, pole or damping by
      construction) by ``scipy.optimize.least_squares`` (trust region), from a grid of starts and the
      given plant: the residual is smooth in them, the loop's response to a parameter is not linear.
      python-control is not a dependency and has no prediction-error fit; scipy is here already.
    - The encoder is left out of the fitted loop (its rounding makes the residual a staircase in the
      parameters, where a gradient method stops at once) and detected from the feedback instead.
    - The feedback may be sampled before the drive's update (a real encoder read at the start of
      the servo thread: delay 0) or after it (HAL's ``sampler`` after the simulated drive in the same
      thread: delay 1); both are fitted and the better kept.
    - What limited the fit is told from the residual itself: the noise in it is estimated from its
      tick-to-tick scatter (white noise of σ has differences of σ√2; a model's error moves as smoothly
      as the loop does, and adds little to them).  A residual above twice that noise is mostly the
      model's error, not noise: the family does not explain the capture.  identify then looks for what
      does -- another family, the other feedback delay, a loop whose controller sees the position 1 to
      MAX_LATE ticks late (a drive or fieldbus that reports it late, simulated as a delay line after the
      position in the same kernel) -- and says so.  The servo model holds no such delay: a loop that
      needs one is named, never written as if a servo file could hold it.

Families (θ the logarithms of the parameters; K the DC gain, mm/s per V)
    ``lag1``         K a / (s + a): a first-order drive lag
    ``lag2``         K ω² / (s² + 2ζω s + ω²): the paper's plants (ζ > 1: two real poles)
    ``ideal``        K: a velocity source (LinuxCNC's ``integ`` alone)
    ``hal-lowpass``  K (b s + a) / (s + a), b = 1 - aT(1 - g)/g, g = 1 - exp(-aT): exactly HAL's
                     ``lowpass`` of gain g before ``integ``, sampled at T

The family with the least BIC (n ln(RSS/n) + p ln n) is kept unless one is asked for.

Uncertainty
    cov(θ) = s² (JᵀJ)⁻¹ at the fit, s² = RSS/(n - p), inflated by n/n_eff, n_eff = n / (1 + 2 Σρ_j)
    over the residual's autocorrelation ρ up to lag 200 (the residual of a loop is not white).  θ
    being logarithms, its standard deviations are relative ones; a pole's comes by the delta method.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .errors import SpecError, StreamError
from .servo import AxisModel, ClosedLoop, ServoModel, axis_terms, discretise, servo_text

FAMILIES = ("lag1", "lag2", "ideal", "hal-lowpass")
PRINT_DIGIT = 1e-6  # mm: halsampler's %f
MIN_MOTION_TICKS = 60  # ticks on which an axis' command moves: 20 per parameter of the largest family
MIN_SPAN = 0.01  # mm an axis' commands must span (and 20 counts of its encoder)
MIN_SPAN_COUNTS = 20
HELD_SHARE = 0.25  # an axis moving on fewer ticks than this share of the busiest axis' is held, not refused
WARN_STD = 0.005  # relative standard deviation above which the excitation is said to limit the fit
REFUSE_STD = 0.02  # ... and above which the model is refused
START_OFF = 1e-3  # mm: the first feedback may be off the first command by this (or 2 counts) at most
MAX_LAG = 200  # ticks of the residual's autocorrelation counted in n_eff
#: a residual RMS above this many times the noise in it (or the floor, the larger) is the model's error, not noise:
#: at least 3/4 of its power something the family does not explain
NOISE_RATIO = 2.0
MAX_LATE = 4  # ticks: the longest feedback delay in the loop that identify tries, to say what explains a capture
PENALTY = 1e3  # mm: the residual of a trial plant that cannot be sampled or whose loop is unstable
PID_TERMS = ("Pgain", "FF1", "maxoutput")
PID_ZERO_ONLY = ("Igain", "Dgain", "FF0", "FF2", "FF3", "bias", "deadband", "maxerror", "maxerrorI",
                 "maxerrorD", "maxcmdD", "maxcmdDD", "maxcmdDDD")


# --------------------------------------------------------------------------- families


@dataclass(frozen=True)
class Family:
    """A plant family: its parameters (fitted as logarithms) and how they make num/den."""

    name: str
    parameters: tuple  # names, in θ's order

    def plant(self, theta, period):
        """(num, den) of G(s) for θ."""
        p = np.exp(theta)
        if self.name == "lag1":
            k, a = p
            return (k * a,), (1.0, a)
        if self.name == "lag2":
            k, w, z = p
            return (k * w * w,), (1.0, 2.0 * z * w, w * w)
        if self.name == "ideal":
            return (p[0],), (1.0,)
        k, a = p  # hal-lowpass
        g = -math.expm1(-a * period)
        b = 1.0 - a * period * (1.0 - g) / g
        return (k * b, k * a), (1.0, a)

    def values(self, theta, period) -> dict:
        """The parameters by name; hal-lowpass adds its HAL lowpass gain g."""
        out = dict(zip(self.parameters, (float(v) for v in np.exp(theta))))
        if self.name == "hal-lowpass":
            out["g"] = float(-math.expm1(-out["a"] * period))
        return out

    def poles(self, theta, period) -> np.ndarray:
        """The plant's poles (rad/s; the continuous equivalent's for hal-lowpass)."""
        den = self.plant(theta, period)[1]
        return np.roots(den) if len(den) > 1 else np.empty(0)

    def theta_of(self, num, den, period):
        """θ of a given plant of this family's form, or None (another form, or not positive)."""
        num, den = np.asarray(num, float) / den[0], np.asarray(den, float) / den[0]
        with np.errstate(all="ignore"):
            if self.name == "ideal" and den.size == 1 and num.size == 1:
                values = [num[0]]
            elif self.name == "lag1" and den.size == 2 and num.size == 1:
                values = [num[0] / den[1], den[1]]
            elif self.name == "hal-lowpass" and den.size == 2 and num.size == 2:
                values = [num[1] / den[1], den[1]]
            elif self.name == "lag2" and den.size == 3 and num.size == 1 and den[2] > 0:
                w = math.sqrt(den[2])
                values = [num[0] / den[2], w, den[1] / (2 * w)]
            else:
                return None
        values = np.array(values, dtype=float)
        return np.log(values) if np.all(np.isfinite(values) & (values > 0)) else None

    def grid(self, gain, period) -> list:
        """Starting points around a DC gain estimate."""
        k = math.log(gain)
        if self.name == "ideal":
            return [np.array([k])]
        if self.name == "lag1":
            return [np.array([k, math.log(a)]) for a in (30.0, 100.0, 300.0, 1e3, 3e3, 1e4)]
        if self.name == "hal-lowpass":
            return [np.array([k, math.log(-math.log1p(-g) / period)]) for g in (0.02, 0.1, 0.3, 0.6, 0.9)]
        return [np.array([k, math.log(w), math.log(z)]) for w in (50.0, 200.0, 800.0, 3200.0) for z in (0.5, 1.0, 2.0)]


FAMILY = {name: Family(name, params) for name, params in (
    ("lag1", ("K", "a")), ("lag2", ("K", "omega", "zeta")), ("ideal", ("K",)), ("hal-lowpass", ("K", "a")))}


# --------------------------------------------------------------------------- the controller


@dataclass(frozen=True)
class Controller:
    """One axis' controller as the servo file holds it, and the plant to start the fit from (or None)."""

    kp: float
    kv: float
    voltage_limit: float | None = None
    plant: tuple | None = None  # (num, den)
    encoder: float | None = None  # mm per count, where the capture does not show it


def controllers_of(model: ServoModel) -> dict:
    """Each axis' controller and plant from a servo model (a START file)."""
    return {a: Controller(ax.kp, ax.kv, ax.voltage_limit, (ax.num, ax.den), ax.encoder_resolution)
            for a, ax in model.axes.items()}


def parse_pid(text: str, axes, period: float) -> dict:
    """Each axis' controller from LinuxCNC pid parameters: ``x.Pgain=60,x.FF1=0.95,y.Pgain=90`` (a term without
    an axis applies to every axis).  pid with ``error-previous-target`` (its default) acts on the previous command,
    which is this controller with kp = Pgain, kv = FF1 - Pgain·T; ``maxoutput`` (> 0) is the voltage limit.  The
    terms the model has no place for (Igain, Dgain, FF0, FF2, bias, deadband, ...) are refused unless 0.  Raises
    ValueError saying what is wrong."""
    values = {a: {} for a in axes}
    for term, names, name, value in axis_terms(text, axes, PID_TERMS + PID_ZERO_ONLY, "x.Pgain=60,x.FF1=0.95",
                                               f"[axis.]NAME=V with NAME one of {', '.join(PID_TERMS)}", "the job"):
        try:
            number = float(value)
        except ValueError:
            raise ValueError(f"term {term!r}: {value!r} is not a number") from None
        if not math.isfinite(number):
            raise ValueError(f"term {term!r}: {value!r} is not a finite number")
        if name in PID_ZERO_ONLY and number != 0:
            raise ValueError(f"term {term!r}: the servo model has no {name} (it holds P and velocity feed-forward: "
                             "Pgain, FF1, maxoutput); identify a loop without it")
        for a in names:
            values[a][name] = number
    out = {}
    for a in axes:
        v = values[a]
        if v.get("Pgain", 0.0) <= 0:
            raise ValueError(f"axis {a} has no Pgain > 0 (give {a}.Pgain=... or Pgain=...)")
        limit = v.get("maxoutput", 0.0)
        if limit < 0:
            raise ValueError(f"{a}.maxoutput = {limit:g} must be >= 0 (0: no limit)")
        out[a] = Controller(v["Pgain"], v.get("FF1", 0.0) - v["Pgain"] * period, limit or None)
    return out


# --------------------------------------------------------------------------- the capture, aligned


@dataclass
class Record:
    """The plan's commands and the captured feedback, row by row: the commands' ticks, then the hold
    (the last command held while the capture goes on)."""

    axes: list
    period: float
    command: np.ndarray  # (n, axes)
    feedback: np.ndarray  # (n, axes)
    command_ticks: int
    lead_rows: int
    hold_rows: int
    received_max: dict | None  # the largest |received - plan| per axis, mm (None: no *_cmd columns)


def record(capture, columns, chunks, name: str, check_received: bool = True, hint: str = "",
           hold_chunk: int = 65536) -> Record:
    """Align *capture* (a :class:`~nurbsinterp.capture.Capture`) to the plan's rows (*chunks* of a stream with
    *columns*) as ``simulate --actual`` does, refusing it for the same faults; keep every row."""
    from .capture import received_deviation
    from .precompensate import stream_period

    axes = [a for a in ("x", "y", "z") if a in columns]
    cols = [columns.index(a) for a in axes]
    cmds, fbs = [], []
    received = np.zeros(len(axes)) if capture.has_commands else None
    tick, period, last = 0, None, None
    for data in chunks:
        m = data.shape[0]
        if m == 0:
            continue
        if period is None:
            period = stream_period(data, columns, name)
        cmd = np.ascontiguousarray(data[:, cols])
        block = capture.commands(m)
        if received is not None:
            np.maximum(received, received_deviation(capture.name, tick, axes, cmd, block, check_received, hint),
                       out=received)
        cmds.append(cmd)
        fbs.append(block.position)
        tick += m
        last = cmd[-1]
    if last is None:
        raise StreamError(f"{name}: the plan has no ticks")
    capture.end_commands()
    hold = 0
    while True:
        block = capture.hold(hold_chunk)
        n = block.line.shape[0]
        if n:
            fbs.append(block.position)
            cmds.append(np.tile(last, (n, 1)))
            hold += n
        if n < hold_chunk:
            break
    capture.finish()
    return Record(axes, period, np.vstack(cmds), np.vstack(fbs), tick, capture.lead_rows, hold,
                  None if received is None else {a: float(v) for a, v in zip(axes, received)})


# --------------------------------------------------------------------------- the fit


@dataclass(frozen=True)
class FamilyFit:
    """One family's best fit on one axis."""

    family: str
    delay: int  # ticks: 1 where the feedback is sampled after the drive's update
    theta: np.ndarray
    rss: float  # mm²
    n: int
    bic: float
    jac: np.ndarray = field(repr=False)
    residual: np.ndarray = field(repr=False)

    @property
    def rms(self) -> float:
        return math.sqrt(self.rss / self.n)


@dataclass(frozen=True)
class Estimate:
    value: float
    std: float  # relative (a fraction of value)


@dataclass(frozen=True)
class AxisFit:
    """What :func:`identify` found for one axis."""

    axis: str
    family: str
    delay: int
    rows: int
    parameters: dict  # name -> Estimate
    poles: list  # Estimate of each pole's magnitude (rad/s), with its complex value in `pole_values`
    pole_values: list
    rms: float  # mm
    max: float  # mm
    encoder: float | None  # mm per count, detected from the feedback
    floor: float  # mm: the residual's floor set by the feedback's rounding (q/√12 or %f's)
    limited_by: list  # words: what limited the fit
    n_eff_ratio: float  # n_eff / n
    model: AxisModel
    alternatives: list  # (family, delay, rms mm, bic) of every family tried, best BIC first
    noise: float = 0.0  # mm: the noise in the residual, from its tick-to-tick scatter (white_noise)
    advice: str = ""  # where the family does not explain the capture: what does, or what to try


@dataclass(frozen=True)
class Identification:
    capture: str
    job: str
    period: float
    controller: str  # where the gains came from
    record: Record = field(repr=False)
    axes: dict  # axis -> AxisFit
    #: axes the capture cannot identify while it identifies the others (a 2.5-D program's z, which only plunges
    #: and retracts); axis -> (why, in words; START's model of it, kept, or None without one: --pid)
    held: dict = field(default_factory=dict)

    def model(self) -> ServoModel:
        axes = {a: f.model for a, f in self.axes.items()}
        axes.update((a, kept) for a, (_, kept) in self.held.items() if kept is not None)
        return ServoModel({a: axes[a] for a in self.record.axes if a in axes}, f"fitted to {self.capture}",
                          self.period)

    def held_text(self, a: str) -> str:
        """Why axis *a* was not fitted, and what the model holds for it."""
        why, kept = self.held[a]
        return f"not identified ({why})" + ("; START's model of it kept" if kept is not None else "")

    def as_dict(self) -> dict:
        r = self.record
        out = {"capture": self.capture, "job": self.job, "period": self.period, "controller": self.controller,
               "rows": int(r.command.shape[0]), "command_ticks": r.command_ticks, "hold_rows": r.hold_rows,
               "capture_lead_rows": r.lead_rows, "as_received_max": r.received_max, "axes": {}}
        for a, f in self.axes.items():
            out["axes"][a] = {
                "family": f.family, "delay": f.delay, "rows": f.rows,
                "parameters": {k: {"value": e.value, "std": e.std} for k, e in f.parameters.items()},
                "poles": [{"re": float(p.real), "im": float(p.imag), "magnitude": e.value, "std": e.std}
                          for p, e in zip(f.pole_values, f.poles)],
                "plant": {"num": list(f.model.num), "den": list(f.model.den)},
                "kp": f.model.kp, "kv": f.model.kv, "encoder_resolution": f.encoder,
                "residual_rms": f.rms, "residual_max": f.max, "floor": f.floor, "noise": f.noise,
                "limited_by": f.limited_by, "advice": f.advice or None, "n_eff_ratio": f.n_eff_ratio,
                "families": [{"family": n, "delay": d, "residual_rms": rms, "bic": bic}
                             for n, d, rms, bic in f.alternatives],
            }
        out["held"] = {a: {"reason": why, "kept": kept is not None} for a, (why, kept) in self.held.items()}
        return out


def detect_encoder(feedback: np.ndarray) -> float | None:
    """The encoder's count (mm) if every captured position is a whole number of one, else None.

    The count is the smallest non-zero step between samples; one of %f's last digit (1e-6 mm) or less is
    the capture's printing, not an encoder.  A count that %f cannot print exactly (1/1024 mm) leaves the
    positions off its multiples by up to half a digit, and is not detected."""
    steps = np.abs(np.diff(feedback))
    steps = steps[steps > 0.5 * PRINT_DIGIT]
    if steps.size == 0:
        return None
    q = float(steps.min())
    if q <= 1.5 * PRINT_DIGIT:
        return None
    counts = np.round(feedback / q)
    if np.abs(feedback - counts * q).max() > 0.5 * PRINT_DIGIT + 1e-12 * float(np.abs(feedback).max()):
        return None
    digits = q / PRINT_DIGIT
    # a whole number of digits, as the decimal it is (20 / 1e6 is 2e-05; 20 * 1e-6 is not)
    return round(digits) / 1e6 if abs(digits - round(digits)) < 1e-3 else q


class _Axis:
    """One axis' data and the residual of a trial plant."""

    def __init__(self, name, command, feedback, period, controller: Controller):
        self.name, self.period, self.controller = name, period, controller
        self.n = feedback.shape[0]
        # more rows than the capture, holding the last command: delay d compares sim[k + d] with row k (a loop
        # whose controller sees the position MAX_LATE ticks late, sampled as the table is after the update: d up to
        # MAX_LATE + 1)
        self.command = np.ascontiguousarray(np.append(command, np.full(MAX_LATE + 1, command[-1]))[:, None])
        self.feedback = feedback

    def positions(self, num, den, encoder=None, late=0) -> np.ndarray | None:
        """The model's positions at the n + MAX_LATE + 1 ticks, or None where the trial plant cannot run; with *late*,
        the positions its controller sees, that many ticks late (:func:`late_loop`)."""
        c = self.controller
        ax = AxisModel(tuple(float(v) for v in num), tuple(float(v) for v in den), c.kp, c.kv, encoder, c.voltage_limit)
        try:
            loop = discretise(ServoModel({self.name: ax}, "a trial plant"), self.period)
        except SpecError:
            return None
        closed = ClosedLoop(late_loop(loop, late) if late else loop)
        if late:  # at rest on the first command: the position and every tick of the delay line hold it
            closed.state = np.zeros((1, closed.loop.A.shape[1]))
            closed.state[0, -1 - late:] = self.command[0, 0]
            closed.prev_cmd = self.command[0].copy()
        with np.errstate(all="ignore"):
            pos = closed.run(self.command)[0][:, 0]
        return pos if np.all(np.isfinite(pos)) and np.abs(pos).max() < 1e9 else None

    def residual(self, family: Family, theta, delay, late=0) -> np.ndarray:
        num, den = family.plant(theta, self.period)
        pos = self.positions(num, den, late=late)
        if pos is None:
            return np.full(self.n, PENALTY)
        return pos[delay:delay + self.n] - self.feedback


def late_loop(loop, ticks: int):
    """*loop* (a one-axis servo.DiscreteLoop) whose controller sees the position *ticks* late: a delay line of that
    many states after the position, the last of which the kernel measures and returns as the position (the kernel
    takes the last state for it).  What a drive or fieldbus that reports the position late does to a loop; the
    servo model has no place for it (load_servo, simulate): identify uses it only to say what explains a capture."""
    from dataclasses import replace

    axes, ns, _ = loop.A.shape
    size = ns + ticks
    A = np.zeros((axes, size, size))
    A[:, :ns, :ns] = loop.A
    for j in range(ticks):  # each tick of the line takes the one before it: the first, the position
        A[:, ns + j, ns + j - 1] = 1.0
    B = np.zeros((axes, size))
    B[:, :ns] = loop.B
    Cv = np.zeros((axes, size))
    Cv[:, :ns] = loop.Cv
    return replace(loop, A=A, B=B, Cv=Cv)


def white_noise(residual) -> float:
    """The noise in a residual (mm): sqrt(mean(Δr²) / 2), its tick-to-tick scatter.  White noise of standard
    deviation σ gives σ; an error of the model, as smooth as the loop's motion, adds little to it."""
    if residual.size < 2:
        return 0.0
    step = np.diff(residual)
    return math.sqrt(float(np.dot(step, step)) / (2.0 * step.size))


def _explained(fit, floor) -> bool:
    """Whether *fit*'s residual is the noise in it (or the floor): at most NOISE_RATIO times the larger."""
    return fit.rms <= NOISE_RATIO * max(white_noise(fit.residual), floor)


def _gain_estimate(cmd, fb, period, c: Controller) -> float:
    """The plant's DC gain from the following error where the command moves at a steady speed:
    e = (1 - kv K) v / (kp K), so K = v / (kp e + kv v)."""
    v = np.diff(cmd) / period
    steady = np.zeros(v.size, dtype=bool)
    steady[1:] = np.abs(np.diff(v)) <= 1e-3 * (np.abs(v[1:]) + 1e-9)
    fast = np.abs(v) > 0.2 * float(np.abs(v).max()) if v.size else steady
    take = steady & fast
    if take.sum() >= 5:
        e = cmd[1:][take] - fb[1:][take]
        k = v[take] / (c.kp * e + c.kv * v[take])
        k = k[np.isfinite(k) & (k > 0)]
        if k.size:
            return float(np.median(k))
    return 1.0 / max(c.kp * period, abs(c.kv), 1e-6)


def _fit_family(axis: _Axis, family: Family, starts, delays, late=0) -> FamilyFit:
    from scipy.optimize import least_squares

    best = None
    for delay in delays:
        scored = sorted(((float(np.dot(r, r)), i, t) for i, t in enumerate(starts)
                         for r in [axis.residual(family, t, delay, late)]), key=lambda s: s[0])
        for _, _, theta0 in scored[:2]:
            result = least_squares(lambda t: axis.residual(family, t, delay, late), theta0, method="trf",
                                   x_scale=1.0, max_nfev=100 * theta0.size)
            rss = float(np.dot(result.fun, result.fun))
            if best is None or rss < best[0]:
                best = (rss, delay, result)
    rss, delay, result = best
    n, p = axis.n, result.x.size
    bic = n * math.log(max(rss, 1e-300) / n) + p * math.log(n)
    return FamilyFit(family.name, delay, result.x, rss, n, bic, result.jac, result.fun)


def _n_eff_ratio(residual) -> float:
    """n_eff / n of the residual: 1 / (1 + 2 Σρ_j), ρ its autocorrelation up to MAX_LAG (at most 1)."""
    r = residual - residual.mean()
    energy = float(np.dot(r, r))
    if energy == 0.0 or r.size < 4 * MAX_LAG:
        return 1.0
    spectrum = np.fft.rfft(r, 2 * r.size)
    acf = np.fft.irfft(spectrum * np.conj(spectrum))[1:MAX_LAG + 1] / energy
    return min(1.0, 1.0 / max(1.0 + 2.0 * float(acf.sum()), 1e-12))


def _uncertainty(fit: FamilyFit):
    """Covariance of θ (relative variances: θ are logarithms), inflated for the residual's correlation."""
    n, p = fit.n, fit.theta.size
    ratio = _n_eff_ratio(fit.residual)
    s2 = fit.rss / max(n - p, 1)
    jtj = fit.jac.T @ fit.jac
    try:
        cov = np.linalg.inv(jtj) * s2 / ratio
    except np.linalg.LinAlgError:
        cov = np.full((p, p), np.inf)
    if not np.all(np.isfinite(cov)):
        cov = np.full((p, p), np.inf)
    return cov, ratio


def _pole_estimates(family: Family, theta, cov, period):
    """Each pole and the relative std of its magnitude (delta method, central differences in θ)."""
    poles = family.poles(theta, period)
    if poles.size == 0:
        return [], []
    order = np.argsort(np.abs(poles))
    poles = poles[order]
    grads = np.zeros((poles.size, theta.size))
    h = 1e-6
    for j in range(theta.size):
        step = np.zeros(theta.size)
        step[j] = h
        up = np.sort(np.abs(family.poles(theta + step, period)))
        down = np.sort(np.abs(family.poles(theta - step, period)))
        grads[:, j] = (np.log(up) - np.log(down)) / (2 * h)
    with np.errstate(all="ignore"):
        stds = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", grads, cov, grads), 0.0))
    return list(poles), [Estimate(float(abs(p)), float(s)) for p, s in zip(poles, stds)]


def identify(rec: Record, controllers: dict, *, capture: str, job: str, controller: str,
             families=FAMILIES, delays=(0, 1)) -> Identification:
    """Fit every axis of *rec* (see the module docstring); SpecError/StreamError naming *capture* where the capture
    cannot determine a model (too short, an axis not moving, too little excitation, not at rest at the start)."""
    fits, held = {}, {}
    moving = np.count_nonzero(np.diff(rec.command[:rec.command_ticks], axis=0) != 0, axis=0)
    for i, a in enumerate(rec.axes):
        try:
            fits[a] = _identify_axis(a, rec.command[:, i], rec.feedback[:, i], rec, controllers[a], capture,
                                     families, delays, int(moving[i]))
        except Unidentifiable as exc:
            # an axis the job hardly moves (a 2.5-D program's z: a plunge, a retract; y of a job that moves x
            # alone) tells too little of its loop, and is no fault of the capture: the others are fitted, and it
            # is said so.  One that moves as much as the others and still cannot be fitted is refused: the job
            # does not excite the machine enough (every axis unidentifiable: refused too)
            if moving[i] >= HELD_SHARE * moving.max():  # (the busiest axis always: no fit, no run)
                raise
            c = controllers[a]
            held[a] = (exc.why, None if c.plant is None else
                       AxisModel(tuple(c.plant[0]), tuple(c.plant[1]), c.kp, c.kv, c.encoder, c.voltage_limit))
    return Identification(capture, job, rec.period, controller, rec, fits, held)


class Unidentifiable(StreamError):
    """An axis whose commands in the capture cannot determine its loop (too little motion or excitation)."""

    def __init__(self, capture: str, axis: str, why: str, remedy: str = ""):
        super().__init__(f"{capture}: axis {axis}: {why}{remedy}")
        self.why = why  # the reason, without the remedy (an axis held says why, the remedy is another capture's)


def _identify_axis(a, cmd, fb, rec: Record, c: Controller, capture, families, delays, moving: int) -> AxisFit:
    """Axis *a*'s fit; *moving*: the ticks its commands move on."""
    period = rec.period
    # a count that is not a whole number of %f's digits cannot be told from the printing: START's then
    encoder = detect_encoder(fb) or c.encoder
    count = encoder or PRINT_DIGIT
    span = float(cmd.max() - cmd.min())
    if span < max(MIN_SPAN, MIN_SPAN_COUNTS * count):
        raise Unidentifiable(capture, a, f"it does not move enough to identify: its commands span {span * 1e3:.4g} "
                             f"um, at least {max(MIN_SPAN, MIN_SPAN_COUNTS * count) * 1e3:.4g} um needed",
                             " (capture a job that moves every axis: curves/excitation.yaml)")
    if moving < MIN_MOTION_TICKS:
        raise Unidentifiable(capture, a, f"the commands move it on {moving} ticks, too short to identify: at "
                             f"least {MIN_MOTION_TICKS} needed", " (capture a longer job: curves/excitation.yaml)")
    off = abs(float(fb[0] - cmd[0]))
    if off > max(START_OFF, 2 * count):
        raise StreamError(f"{capture}: axis {a}: the first feedback {fb[0]:.6f} is {off * 1e3:.4g} um from the first "
                          f"command {cmd[0]:.6f}: the loop was not at rest on it when the capture began (hold the "
                          "first command until it settles, then stream)")
    axis = _Axis(a, cmd, fb, period, c)
    gain = _gain_estimate(cmd[:rec.command_ticks], fb[:rec.command_ticks], period, c)

    def starts(family):
        grid = family.grid(gain, period)
        theta = None if c.plant is None else family.theta_of(*c.plant, period)
        return grid if theta is None else [theta, *grid]

    tried = [_fit_family(axis, FAMILY[name], starts(FAMILY[name]), delays) for name in families]
    tried.sort(key=lambda f: f.bic)
    best = tried[0]
    family = FAMILY[best.family]
    cov, ratio = _uncertainty(best)
    stds = np.sqrt(np.maximum(np.diag(cov), 0.0))
    values = family.values(best.theta, period)
    params = {k: Estimate(values[k], float(s)) for k, s in zip(family.parameters, stds)}
    if "g" in values:  # g = 1 - exp(-aT): dg/g = (aT (1 - g)/g) da/a
        a_std = params["a"].std
        g = values["g"]
        params["g"] = Estimate(g, float(a_std * values["a"] * period * (1 - g) / g))
    pole_values, poles = _pole_estimates(family, best.theta, cov, period)
    num, den = family.plant(best.theta, period)
    model = AxisModel(tuple(float(v) for v in num), tuple(float(v) for v in den), c.kp, c.kv, encoder, c.voltage_limit)
    floor = (encoder if encoder else PRINT_DIGIT) / math.sqrt(12)
    noise = white_noise(best.residual)
    limited, advice = [], ""
    if best.rms <= 1.5 * floor:
        limited.append("quantisation" if encoder else "the capture's 6 decimals")
    elif _explained(best, floor):
        limited.append("noise")
    else:
        limited.append("the model family")
        remedy = _what_explains(axis, best, starts, floor, families, delays)
        advice = (f"the {best.family} plant does not explain the capture: its residual RMS {best.rms * 1e3:.3g} um is "
                  f"{best.rms / max(noise, floor):.3g} times the noise in it; {remedy}")
    worst = max([e.std for e in params.values()] + [e.std for e in poles])
    if worst > WARN_STD:
        limited.append("excitation")
    if not worst <= REFUSE_STD:
        spread = ", ".join([f"{k} ±{e.std * 100:.2g} %" for k, e in params.items()]
                           + [f"pole {e.value:.4g} rad/s ±{e.std * 100:.2g} %" for p, e in zip(pole_values, poles)
                              if p.imag >= 0 and e.std > REFUSE_STD])  # a pair once, as the report shows it
        if limited[0] == "the model family":  # a family that does not fit can leave a parameter free (lag2 → lag1)
            # (an axis the job hardly moves is held, as any it cannot identify: identify_capture decides)
            raise Unidentifiable(capture, a, f"the {best.family} plant is not determined by the capture: {spread}, "
                                 f"and its residual RMS {best.rms * 1e3:.3g} um is {best.rms / max(noise, floor):.3g} "
                                 "times the noise in it: the family does not fit this loop", f"; {remedy}")
        raise Unidentifiable(capture, a, f"too little excitation to fit its {best.family} plant: {spread} (at "
                             f"most {REFUSE_STD * 100:g} % needed)", ": capture a richer job (curves/excitation.yaml)")
    return AxisFit(a, best.family, best.delay, best.n, params, poles, pole_values, best.rms,
                   float(np.abs(best.residual).max()), encoder, floor, limited, ratio, model,
                   [(f.family, f.delay, f.rms, f.bic) for f in tried], noise, advice)


def _what_explains(axis: _Axis, best: FamilyFit, starts, floor, families, delays) -> str:
    """What explains a capture *best* (the fit kept) does not: the first of another family or feedback delay than
    the ones asked for, or a loop whose controller sees the position 1 .. MAX_LATE ticks late (in the families
    asked for), whose residual is its noise; or that none does.  One clause, naming the settings that explain it
    and the residual they leave (the CLI's options of those names set them)."""
    def rms(fit):
        return f"residual RMS {fit.rms * 1e3:.3g} um"

    def ticks(n):
        return f"{n} tick{'' if n == 1 else 's'}"

    others = [f for f in FAMILIES if f not in families]
    other_delays = tuple(d for d in (0, 1) if d not in delays)
    relaxed = [_fit_family(axis, FAMILY[name], starts(FAMILY[name]), (0, 1) if name in others else other_delays)
               for name in FAMILIES if name in others or other_delays]
    found = [f for f in relaxed if _explained(f, floor)]
    if found:
        fit = min(found, key=lambda f: f.bic)
        settings = ([f"the {fit.family} family"] if fit.family != best.family else []) + \
                   ([f"feedback delay {fit.delay}"] if fit.delay not in delays else [])
        return f"{', '.join(settings)} explains it ({rms(fit)}, at its noise)"
    tried = []  # (fit, ticks late)
    for late in range(1, MAX_LATE + 1):
        # the capture's feedback as the controller sees it, the tick after that, or the table's own position
        # after the update (a sampler beside the drive in the thread: late + 1 ticks after the controller's)
        fits = [_fit_family(axis, FAMILY[name], starts(FAMILY[name]), (0, 1, late + 1), late) for name in families]
        found = [f for f in fits if _explained(f, floor)]
        if found:
            fit = min(found, key=lambda f: f.bic)
            return (f"a loop whose controller sees the position {ticks(late)} late (a drive or fieldbus that reports "
                    f"it late) explains it ({fit.family}, feedback delay {fit.delay}, {rms(fit)}, at its noise), and "
                    "the servo model has no place for such a delay: a model written from this capture does not hold "
                    "it")
        tried.extend((f, late) for f in fits)
    fit, late = min(tried, key=lambda pair: pair[0].rms)
    return (f"neither another family nor a controller seeing the position up to {MAX_LATE} ticks late explains it "
            f"(the closest, {fit.family} {ticks(late)} late: {rms(fit)}): the loop holds what the servo model has no "
            "place for (friction, saturation, a pid's I or D term)")


# --------------------------------------------------------------------------- the servo file


def servo_yaml(ident: Identification) -> str:
    """The fitted model as a servo file (load_servo reads it); where it came from in comments."""
    header = [f"Fitted by nurbsinterp identify to the capture {ident.capture} of the job {ident.job},",
              f"controller {ident.controller}, T = {ident.period * 1e3:g} ms.  The model holds at that period only."]
    notes = {}
    for a, (_, kept) in ident.held.items():
        if kept is None:  # a model missing an axis would drive it by nothing
            raise ValueError(f"axis {a} is held and START gave no plant of it to keep: no servo file can be written")
        notes[a] = [f"{a}: {ident.held_text(a)}"]
    for a, f in ident.axes.items():
        values = ", ".join(f"{k} = {e.value:.6g} ± {e.std * 100:.2g} %" for k, e in f.parameters.items())
        notes[a] = [f"{a}: {f.family}, {values}; feedback delay {f.delay} tick(s); residual RMS {f.rms * 1e3:.3g} um, "
                    f"max {f.max * 1e3:.3g} um over {f.rows} rows ({', '.join(f.limited_by)})"]
        if f.advice:
            notes[a].append(f.advice)
        if f.family == "hal-lowpass":
            notes[a].append(f"(HAL: lowpass.gain {f.parameters['g'].value:.6g} before integ, output gain "
                            f"{f.parameters['K'].value:.6g})")
    return servo_text(ident.model(), header, notes)
