"""The X–Y(–Z) servo table: model file, exact discretisation, closed-loop simulation.

Per axis (the paper's Section 4.2 and Fig. 5; docs/servo.md)::

    voltage  u_k = Kp (xc_k − xm_k) + Kv (xc_k − xc_{k−1}) / T     (clipped to ±voltage_limit)
    velocity V(s) = G(s) U(s),   G = num(s) / den(s)  (mm/s per V, proper: a drive may pass
                                                      part of u straight to velocity)
    position x = ∫ velocity

The controller runs at the command period T and holds its output for one
period (zero-order hold); xm is the measured position (the true one, or
quantised to the encoder resolution).  The continuous plant, with the
position integrator appended, is discretised exactly for a ZOH input
(``scipy.signal.cont2discrete``), so the simulated positions and velocities
are the continuous system's, sampled at the ticks — no integration error.

The closed loop runs as one compiled recurrence per tick (:func:`servo_chunk`),
linear or not (quantisation and saturation are just two more lines), chunk by
chunk with its state carried over, so a stream of any length runs in flat
memory.
"""
from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass

import numpy as np

from ._jit import njit
from .errors import SpecError
from .config import Where, finite, mapping, quantity, read_yaml

from .names import AXES  # noqa: E402
PERIOD_MATCH = 1e-9  # relative: a stream's period read from CSV times carries 9 decimals
AXIS_KEYS = ("plant", "kp", "kv", "encoder_resolution", "voltage_limit")


@dataclass(frozen=True)
class AxisModel:
    """One axis: plant G(s) = num/den (mm/s per V), gains, optional encoder and saturation."""

    num: tuple
    den: tuple
    kp: float
    kv: float
    encoder_resolution: float | None = None  # mm per count
    voltage_limit: float | None = None  # V

    @property
    def dc_gain(self) -> float:
        """G(0), mm/s per V."""
        return self.num[-1] / self.den[-1]

    def following_error(self, velocity: float) -> float:
        """Steady following error at constant axis velocity: (1 − Kv G(0)) v / (Kp G(0)), mm."""
        g0 = self.dc_gain
        return (1.0 - self.kv * g0) * velocity / (self.kp * g0)


@dataclass(frozen=True)
class ServoModel:
    axes: dict
    source: str = "built-in paper X-Y table"
    #: the one period the model holds at (s), None for any: a model fitted to a LinuxCNC loop is exact only at
    #: the period it was captured at (its kv folds in the pid's Pgain·T, a HAL lowpass' drive its gain per period)
    period: float | None = None

    @property
    def names(self):
        return [a for a in AXES if a in self.axes]


#: The paper's table (Section 4.2): plants measured with an HP3563A, gains for 100 mm/s.
PAPER_TABLE = ServoModel({
    "x": AxisModel((112570.543,), (1.0, 601.677, 113727.10), kp=40.0, kv=0.6),
    "y": AxisModel((319514.874,), (1.0, 1649.133, 342115.44), kp=70.0, kv=0.6),
})


# --------------------------------------------------------------------------- model files


def load_servo(path: str | os.PathLike | None) -> ServoModel:
    """Read and validate a servo model file; None gives the paper's table."""
    if path is None:
        return PAPER_TABLE
    name = os.fspath(path)
    doc = read_yaml(name)
    where = Where(name)
    mapping(where, "", doc, ("axes", "period"))
    if "axes" not in doc:
        raise SpecError(f"{name}: has no 'axes' section")
    axes_raw = mapping(where, "axes", doc["axes"], AXES)
    if not axes_raw:
        raise SpecError(f"{name}: axes is empty; give at least x and y")
    for needed in ("x", "y"):
        if needed not in axes_raw:
            raise SpecError(f"{name}: axes has no '{needed}' axis")
    period = quantity(where, "period", doc["period"], "time") if doc.get("period") is not None else None
    return ServoModel({a: _axis(where, f"axes.{a}", axes_raw[a]) for a in AXES if a in axes_raw}, name, period)


def _coefficients(where, name, value):
    if not isinstance(value, list) or not value:
        raise where.fail(name, value, "must be a non-empty list of polynomial coefficients, highest power first")
    return tuple(finite(where, f"{name}[{i}]", c) for i, c in enumerate(value))


def _positive(where, name, value):
    number = finite(where, name, value)
    if not number > 0:
        raise where.fail(name, value, "must be > 0")
    return number


def _axis(where: Where, name: str, raw) -> AxisModel:
    raw = mapping(where, name, raw, AXIS_KEYS)
    for key in ("plant", "kp", "kv"):
        if key not in raw:
            raise where.fail(name, "", f"needs '{key}'", shown=False)
    plant = mapping(where, f"{name}.plant", raw["plant"], ("num", "den"))
    for key in ("num", "den"):
        if key not in plant:
            raise where.fail(f"{name}.plant", "", f"needs '{key}' (coefficients, highest power of s first)", shown=False)
    num = _coefficients(where, f"{name}.plant.num", plant["num"])
    den = _coefficients(where, f"{name}.plant.den", plant["den"])
    if den[0] == 0:
        raise where.fail(f"{name}.plant.den[0]", plant["den"][0], "must not be 0 (the leading coefficient)")
    while len(num) > 1 and num[0] == 0:
        num = num[1:]
    if len(num) > len(den):
        raise where.fail(f"{name}.plant", f"{len(num) - 1}/{len(den) - 1}",
                         "must be proper (numerator degree at most the denominator's): it maps volts to velocity")
    if len(den) > 9:
        raise where.fail(f"{name}.plant.den", f"<{len(den)} coefficients>", "is above the supported order of 8")
    if num[-1] == 0 or den[-1] == 0:
        raise where.fail(f"{name}.plant", "", "needs a finite, non-zero DC gain num(0)/den(0)", shown=False)
    kp = _positive(where, f"{name}.kp", raw["kp"])
    kv = finite(where, f"{name}.kv", raw["kv"])
    enc = _positive(where, f"{name}.encoder_resolution", raw["encoder_resolution"]) \
        if raw.get("encoder_resolution") is not None else None
    vmax = _positive(where, f"{name}.voltage_limit", raw["voltage_limit"]) \
        if raw.get("voltage_limit") is not None else None
    return AxisModel(num, den, kp, kv, enc, vmax)


def servo_text(model: ServoModel, header=(), notes=None) -> str:
    """*model* as a servo file :func:`load_servo` reads back to the bit (coefficients as Python's shortest
    round-trip repr); *header*: comment lines on top, *notes*: per axis, comment lines above it."""
    lines = [f"# {line}" for line in header]
    if model.period is not None:
        lines.append(f"period: {model.period!r}")
    lines.append("axes:")
    for a, ax in model.axes.items():
        lines += [f"  # {line}" for line in (notes or {}).get(a, ())]
        lines += [f"  {a}:", "    plant:",
                  f"      num: [{', '.join(repr(float(v)) for v in ax.num)}]",
                  f"      den: [{', '.join(repr(float(v)) for v in ax.den)}]",
                  f"    kp: {float(ax.kp)!r}", f"    kv: {float(ax.kv)!r}"]
        if ax.encoder_resolution is not None:
            lines.append(f"    encoder_resolution: {float(ax.encoder_resolution)!r}")
        if ax.voltage_limit is not None:
            lines.append(f"    voltage_limit: {float(ax.voltage_limit)!r}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------- discretisation


@dataclass
class DiscreteLoop:
    """The per-axis matrices of the sampled plant, padded to one state size for the kernel.

    State per axis: the plant's states (controllable canonical form) then position, and first the
    voltage held over the last period where the plant passes part of it straight to velocity (a
    proper G: num and den of one degree, as a HAL ``lowpass`` before ``integ``, or G = K, an ideal
    velocity drive).  x_{k+1} = A x_k + B u_k; velocity = Cv · x (the plant's output c·x plus d·u held
    up to t_k: the velocity just before the tick); position = x[-1].
    """

    names: list
    period: float
    A: np.ndarray  # (axes, ns, ns)
    B: np.ndarray  # (axes, ns)
    Cv: np.ndarray  # (axes, ns)
    kp: np.ndarray
    kv: np.ndarray
    resolution: np.ndarray  # 0: exact feedback
    limit: np.ndarray  # inf: no saturation


def discretise(model: ServoModel, period: float, names=None) -> DiscreteLoop:
    """Sample *model* at *period* with a zero-order hold; refuse an unstable closed loop, or a period other than
    the one the model holds at (its ``period``)."""
    names = list(names or model.names)
    if model.period is not None and abs(period - model.period) > PERIOD_MATCH * model.period:
        raise SpecError(f"{model.source}: period = {model.period * 1e3:g} ms: the model holds at that period only "
                        f"(it was fitted there), and the commands' is {period * 1e3:g} ms")
    # plant order + 1 for position, + 1 for the held voltage where the plant passes it on
    ns = max(len(model.axes[a].den) + (_feedthrough(model.axes[a]) != 0.0) for a in names)
    n_ax = len(names)
    A = np.zeros((n_ax, ns, ns))
    B = np.zeros((n_ax, ns))
    Cv = np.zeros((n_ax, ns))
    for i, name in enumerate(names):
        ax = model.axes[name]
        Ad, Bd, c = sample_axis(model.source, name, ax, period)
        order = c.size
        # pad at the front so that position is always the last state
        off = ns - (order + 1)
        A[i, off:, off:] = Ad
        B[i, off:] = Bd
        Cv[i, off:off + order] = c
        d = _feedthrough(ax)
        if d != 0.0:
            # the voltage just applied, kept as a state (its row of A zero, of B one) so that the kernel's
            # velocity Cv · x adds d·u without knowing of it
            B[i, off - 1] = 1.0
            Cv[i, off - 1] = d
        _check_stable(model.source, name, ax, Ad, Bd, period)
    return DiscreteLoop(
        names, period, A, B, Cv,
        np.array([model.axes[a].kp for a in names]),
        np.array([model.axes[a].kv for a in names]),
        np.array([model.axes[a].encoder_resolution or 0.0 for a in names]),
        np.array([model.axes[a].voltage_limit or np.inf for a in names]),
    )


def sample_axis(source: str, name: str, ax: AxisModel, period: float):
    """(Ad, Bd, Cv) of one axis' plant with position appended, sampled exactly for a ZOH input.

    State: the plant's (controllable canonical form), then position, the last; x+ = Ad x + Bd u,
    velocity = Cv · x[:-1].  Raises SpecError, naming the axis, when the sample overflows.
    """
    # scipy.linalg, not scipy.signal: the latter's import (it pulls in scipy.stats) costs 0.6 s of
    # every simulate's start-up, for two formulas
    from scipy.linalg import expm

    # extreme coefficients (a pole with Re(p) T beyond ~709, 1e300 gains) overflow exp(A T):
    # scipy then warns or raises; either way the plant cannot be sampled at this period
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")
        try:
            a, b, c, d = _canonical(ax.num, ax.den)
            order = a.shape[0]
            # the plant with position' = velocity = c·x + d·u appended, and the input as a state held
            # constant over the period: exp of that block matrix times T is the exact ZOH sample
            M = np.zeros((order + 2, order + 2))
            M[:order, :order] = a
            M[order, :order] = c
            M[order, order + 1] = d
            M[:order, order + 1] = b
            E = expm(M * period)
            Ad, Bd = E[:order + 1, :order + 1], E[:order + 1, order + 1]
            sampled = bool(np.isfinite(Ad).all() and np.isfinite(Bd).all() and np.isfinite(c).all())
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            sampled = False
    if not sampled:
        raise SpecError(f"{source}: axes.{name}.plant = {_plant_text(ax)} overflows when sampled at "
                        f"T = {period:g} s (its coefficients or a fast pole are too extreme)")
    return Ad, Bd, c


def _canonical(num, den):
    """(A, b, c, d) of the proper num/den in controllable canonical form (as scipy's tf2ss): d the direct
    feedthrough num₀/den₀ where the degrees are equal (else 0), c from what remains, num − d·den."""
    den = np.asarray(den, dtype=float)
    num = np.asarray(num, dtype=float)
    order = den.size - 1
    d = 0.0
    if num.size == den.size:
        d = num[0] / den[0]
        num = (num - d * den)[1:]
    A = np.eye(order, k=-1)
    b = np.zeros(order)
    c = np.zeros(order)
    if order:  # (an order-0 plant, G = K, has no state: a velocity source)
        A[0] = -den[1:] / den[0]
        b[0] = 1.0
        c[order - len(num):] = num / den[0]
    return A, b, c, d


def _feedthrough(ax) -> float:
    """The part of the voltage an axis' plant passes straight to velocity (mm/s per V): 0 if strictly proper."""
    return ax.num[0] / ax.den[0] if len(ax.num) == len(ax.den) else 0.0


def _plant_text(ax) -> str:
    return f"num {list(ax.num)!r}, den {list(ax.den)!r}"


def _check_stable(source, name, ax, Ad, Bd, period):
    """The sampled closed loop x+ = (A − B Kp e_pos^T) x must have all poles inside the unit circle."""
    with np.errstate(all="ignore"):
        closed = Ad - ax.kp * np.outer(Bd, np.eye(Ad.shape[0])[-1])
        radius = float(np.max(np.abs(np.linalg.eigvals(closed)))) if np.isfinite(closed).all() else math.inf
    if not radius < 1.0:
        raise SpecError(f"{source}: axes.{name}: the closed loop is unstable at T = {period:g} s "
                        f"(largest pole magnitude {radius:.6g}); lower kp or the period")


# --------------------------------------------------------------------------- simulation


@njit(cache=True, inline="always")
def servo_tick(cmd, A, B, Cv, kp, kv, resolution, limit, period, state, prev_cmd, pos, vel, volt, tmp):
    """One controller period for every axis: what a real-time servo task computes per tick.

    Reads the table's position and velocity at t_k (into pos, vel), computes the
    voltage from the command cmd and the measured position, holds it until
    t_{k+1} (into volt) and advances ``state`` (axes, ns); ``prev_cmd`` carries
    the previous command for the velocity feed-forward; tmp (ns,) is scratch.
    """
    ns = state.shape[1]
    for i in range(cmd.shape[0]):
        p = state[i, ns - 1]
        v = 0.0
        for j in range(ns):
            v += Cv[i, j] * state[i, j]
        pos[i] = p
        vel[i] = v
        measured = p
        if resolution[i] > 0.0:
            measured = math.floor(p / resolution[i] + 0.5) * resolution[i]
        u = kp[i] * (cmd[i] - measured) + kv[i] * (cmd[i] - prev_cmd[i]) / period
        if u > limit[i]:
            u = limit[i]
        elif u < -limit[i]:
            u = -limit[i]
        volt[i] = u
        prev_cmd[i] = cmd[i]
        for r in range(ns):
            acc = B[i, r] * u
            for j in range(ns):
                acc += A[i, r, j] * state[i, j]
            tmp[r] = acc
        for r in range(ns):
            state[i, r] = tmp[r]


@njit(cache=True)
def servo_chunk(cmd, A, B, Cv, kp, kv, resolution, limit, period, state, prev_cmd, out_pos, out_vel, out_volt):
    """Run the sampled closed loop over the rows of cmd (m, axes): :func:`servo_tick` per row.

    The axes do not interact, so each runs through the whole chunk on its own, its state in a
    small local array: the same operations in the same order as servo_tick per row (the same
    numbers to the bit, tests/test_servo.py), without re-reading every axis' matrices and state
    through the (axes, ns, ns) arrays at every tick.
    """
    ns = state.shape[1]
    x = np.empty(ns)
    nxt = np.empty(ns)
    for i in range(cmd.shape[1]):
        Ai = A[i]
        Bi = B[i]
        Ci = Cv[i]
        gain_p, gain_v, res, lim = kp[i], kv[i], resolution[i], limit[i]
        for j in range(ns):
            x[j] = state[i, j]
        prev = prev_cmd[i]
        for k in range(cmd.shape[0]):
            c = cmd[k, i]
            p = x[ns - 1]
            v = 0.0
            for j in range(ns):
                v += Ci[j] * x[j]
            out_pos[k, i] = p
            out_vel[k, i] = v
            measured = p
            if res > 0.0:
                measured = math.floor(p / res + 0.5) * res
            u = gain_p * (c - measured) + gain_v * (c - prev) / period
            if u > lim:
                u = lim
            elif u < -lim:
                u = -lim
            out_volt[k, i] = u
            prev = c
            for r in range(ns):
                acc = Bi[r] * u
                for j in range(ns):
                    acc += Ai[r, j] * x[j]
                nxt[r] = acc
            for r in range(ns):
                x[r] = nxt[r]
        for j in range(ns):
            state[i, j] = x[j]
        prev_cmd[i] = prev


class ClosedLoop:
    """The table under simulation: feed it command rows, get actual positions and velocities.

    Starts at rest at the first command it is given.
    """

    def __init__(self, loop: DiscreteLoop):
        self.loop = loop
        self.state = None
        self.prev_cmd = None

    def run(self, cmd: np.ndarray, out=None):
        """(positions, velocities, voltages), each (m, axes), for command rows cmd (m, axes).

        *out*: three (m, axes) arrays to write them into (a caller running chunk after chunk
        reuses its own), else new ones.
        """
        cmd = np.ascontiguousarray(cmd, dtype=float)
        if self.state is None:
            ns = self.loop.A.shape[1]
            self.state = np.zeros((cmd.shape[1], ns))
            self.state[:, ns - 1] = cmd[0]
            self.prev_cmd = cmd[0].copy()
        pos, vel, volt = out if out is not None else (np.empty_like(cmd), np.empty_like(cmd), np.empty_like(cmd))
        lp = self.loop
        servo_chunk(cmd, lp.A, lp.B, lp.Cv, lp.kp, lp.kv, lp.resolution, lp.limit, lp.period,
                    self.state, self.prev_cmd, pos, vel, volt)
        return pos, vel, volt


# --------------------------------------------------------------------------- model error


@dataclass(frozen=True)
class ModelError:
    """A plant that differs from the model: per axis, its gain and its poles scaled.

    ``gain[a]`` multiplies axis a's G(s) (its DC gain with it); ``poles[a]`` scales the roots
    of its denominator (s-plane: 1.1 is a 10 % faster plant), its DC gain kept.  The
    controller (kp, kv), the encoder and the saturation stay the model's: only the table
    the commands were designed for is not the one they drive.
    """

    label: str
    gain: dict
    poles: dict

    def apply(self, model: ServoModel) -> ServoModel:
        axes = {}
        for name, ax in model.axes.items():
            num, den = np.asarray(ax.num, float), np.asarray(ax.den, float)
            factor = self.poles.get(name, 1.0)
            if factor != 1.0:
                scaled = np.real(np.poly(np.roots(den) * factor)) * den[0]
                num = num * (scaled[-1] / den[-1])  # the same DC gain with the moved poles
                den = scaled
            num = num * self.gain.get(name, 1.0)
            axes[name] = AxisModel(tuple(float(c) for c in num), tuple(float(c) for c in den), ax.kp, ax.kv,
                                   ax.encoder_resolution, ax.voltage_limit)
        return ServoModel(axes, f"{model.source} with {self.label}", model.period)


#: The model errors of `compare --model-error standard`: common and opposite gain errors, pole shifts.
STANDARD_MODEL_ERRORS = ("gain=+5%", "gain=-5%", "x.gain=+5%,y.gain=-5%", "x.gain=-5%,y.gain=+5%",
                         "gain=+20%", "gain=-20%", "poles=1.1", "poles=0.9")


def parse_model_error(text: str, axes) -> ModelError:
    """A model error from ``gain=+5%``, ``poles=0.9``, ``x.gain=1.05,y.gain=0.95`` (comma-joined terms).

    A term is ``[axis.]gain`` or ``[axis.]poles`` = a factor (1.05) or a signed percentage
    (+5%, -20%); without an axis it applies to every axis.  Raises ValueError saying what is wrong.
    """
    gain, poles = {}, {}
    for term, names, what, value in axis_terms(text, axes, ("gain", "poles"), "gain=+5%, x.gain=0.95, poles=1.1",
                                               "[axis.]gain=F or [axis.]poles=F", "the model"):
        try:
            factor = 1.0 + float(value[:-1]) / 100.0 if value.endswith("%") else float(value)
        except ValueError:
            raise ValueError(f"term {term!r}: {value!r} is not a factor (1.05) or a percentage (+5%)") from None
        if not (math.isfinite(factor) and 0.0 < factor <= 100.0):
            raise ValueError(f"term {term!r}: the factor {factor:g} is outside (0, 100]")
        target = gain if what == "gain" else poles
        for name in names:
            target[name] = target.get(name, 1.0) * factor
    return ModelError(text.strip(), gain, poles)


def axis_terms(text: str, axes, names, example: str, shape: str, owner: str) -> list:
    """The comma-joined terms ``[axis.]NAME=VALUE`` of *text*: (term, the axes it sets, NAME, VALUE's text) each, a
    term without an axis setting every one of *axes*.  ValueError saying what is wrong: an empty term (*example*:
    what to give), a term not of *shape* (NAME not in *names*), an axis *owner* does not have."""
    terms = [t.strip() for t in text.split(",")]
    if not text.strip() or any(not t for t in terms):
        raise ValueError(f"is empty or has an empty term; give terms like {example}")
    out = []
    for term in terms:
        key, sep, value = term.partition("=")
        axis, _, name = key.strip().rpartition(".")
        if not sep or name not in names:
            raise ValueError(f"term {term!r} is not {shape}")
        if axis and axis not in axes:
            raise ValueError(f"term {term!r}: {owner} has no axis {axis!r} (it has {', '.join(axes)})")
        out.append((term, [axis] if axis else list(axes), name, value.strip()))
    return out
