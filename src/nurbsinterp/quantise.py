"""Drive resolution: every axis command rounded to the counts of a real drive, without drift.

A drive takes positions in counts: encoder counts of a servo's position loop, steps
of a step generator.  :class:`Resolution` holds, per axis, the *scale* in counts per
mm (LinuxCNC's ``SCALE``) as an exact rational: ``1um`` is 1000/mm, ``0.5um``
2000/mm, ``2000/mm`` itself, ``1.5625um`` 640/mm (200 steps x 16 microsteps on a
5 mm lead).

Each command is the rounding of the exact one, never of a sum of increments:
``n_k = round(x_k * scale)``, ties to even, so the error of every tick is at most
half a count and it never accumulates, however long the stream.  Where the scale
is an integer (every example above) the rounding is exact: the product
``x * scale`` is carried with its rounding error (Dekker's two-product) and a tie
is decided from the exact value, not from the rounded product.  A command in mm
is then ``n / scale``, the double nearest to n counts (one correctly rounded
division), so reading it back, ``round(x * scale)`` gives n again; written with
9 decimals (CSV, HAL) it still does for every scale up to 10^6 per mm (1 nm).
With a scale that is not an integer (``0.3um``) the product uses the double
nearest to the scale: a tie may go the other way, a rounding off by 1e-16 of the
count.

Noise shaping (``shaped``, first-order error feedback): each moving tick's
rounding error is carried into the next tick's, ``n_k = round(x_k * scale +
r_(k-1))``, ``r_k`` what that rounding left.  The command's error ``r_(k-1) -
r_k`` is then the first difference of a sequence bounded by half a count: at most
one count on any tick, still never accumulating (the errors telescope), and with
its power moved from the servo's band to the Nyquist frequency, where the loop does
not follow it -- on the paper's circle, pre-compensated, the 0.5 um rounding's
contour error falls from 0.135 um to 0.035 um (docs/resolution.md).  Where an axis' exact
command holds (the same value as the tick before: at rest, or an axis the move
does not use) it is rounded plainly and the carried error dropped, so that a
resting axis sits on the nearest count instead of dithering between two.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from ._jit import njit
from .errors import UsageError
from .names import ROUNDINGS
from .streams import round_scaled

#: length units as exact fractions of a mm (the rounding works on exact scales)
LENGTH_UNITS = {"nm": Fraction(1, 10 ** 6), "um": Fraction(1, 1000), "µm": Fraction(1, 1000),
                "μm": Fraction(1, 1000), "mm": Fraction(1), "cm": Fraction(10), "m": Fraction(1000),
                "in": Fraction(254, 10)}
FINEST = Fraction(1, 10 ** 6)  # mm: 1 nm; finer counts would not survive the streams' 9 decimals
COARSEST = Fraction(1000)  # mm
MAX_COUNTS = 2.0 ** 52  # |x * scale| below this: a count is an exact integer, its rounding exact

_NUMBER = r"[+]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?"
_LENGTH = re.compile(rf"^\s*({_NUMBER})\s*([a-zµμ]*)\s*$")
_SCALE = re.compile(rf"^\s*({_NUMBER})\s*/\s*([a-zµμ]+)\s*$")


@dataclass(frozen=True)
class Resolution:
    """Counts per mm of each axis (exact fractions), and the text each came from."""

    scales: dict  # axis -> Fraction, counts per mm
    given: dict  # axis -> the text the user gave

    def step(self, axis) -> Fraction:
        """The size of one count of *axis*, mm."""
        return 1 / self.scales[axis]

    def describe(self, axis) -> str:
        """``0.5 um (2000 counts/mm)``: one count of *axis* for people."""
        step = self.step(axis)
        size = f"{float(step * 1000):.6g} um" if step < 1 else f"{float(step):.6g} mm"
        scale = self.scales[axis]
        per_mm = str(scale.numerator) if scale.denominator == 1 else f"{float(scale):.9g}"
        return f"{size} ({per_mm} counts/mm)"


def parse_resolution(text: str, axes) -> Resolution:
    """Read a resolution for the job's *axes*: one for all (``1um``, ``0.0005``, ``2000/mm``) or one
    per axis (``x=0.5um,y=1um``, every axis of the job named once).

    A bare number is mm; a length takes nm, um, mm, cm, m, in; a scale is counts per length
    (``2000/mm``, ``50800/in``).  Raises ValueError with the reason (the caller names the option).
    """
    axes = list(axes)
    text = str(text).strip()
    if "=" not in text:
        scale = _scale(text)
        return Resolution({a: scale for a in axes}, {a: text for a in axes})
    scales, given = {}, {}
    for item in text.split(","):
        axis, sep, value = item.partition("=")
        axis = axis.strip()
        if not sep:
            raise ValueError(f"{item.strip()!r}: give every axis as AXIS=VALUE (for example x=0.5um,y=1um)")
        if axis not in axes:
            raise ValueError(f"{axis!r} is not an axis of the job ({','.join(axes)})")
        if axis in scales:
            raise ValueError(f"axis {axis} is given twice")
        scales[axis] = _scale(value, f"{axis}=")
        given[axis] = value.strip()
    missing = [a for a in axes if a not in scales]
    if missing:
        raise ValueError(f"no resolution for axis {missing[0]} (give every axis of the job: {','.join(axes)})")
    return Resolution(scales, given)


def _scale(text: str, prefix: str = "") -> Fraction:
    """Counts per mm, exactly, from a length (one count) or a scale (counts per length)."""
    what = f"{prefix}{text.strip()!r}"
    m = _SCALE.match(text)
    if m is not None:
        if m.group(2) not in LENGTH_UNITS:
            raise ValueError(f"{what} has an unknown unit {m.group(2)!r} (counts per mm or per in, e.g. 2000/mm)")
        per = Fraction(m.group(1))
        if per == 0:
            raise ValueError(f"{what}: the scale must be > 0")
        step = LENGTH_UNITS[m.group(2)] / per
    else:
        m = _LENGTH.match(text)
        if m is None:
            raise ValueError(f"{what} is not a length (0.5um, 0.0005 mm) or a scale (2000/mm)")
        unit = m.group(2) or "mm"
        if unit not in LENGTH_UNITS:
            raise ValueError(f"{what} has an unknown unit {unit!r} (use nm, um, mm, in; or a scale, 2000/mm)")
        step = Fraction(m.group(1)) * LENGTH_UNITS[unit]
    if not FINEST <= step <= COARSEST:
        raise ValueError(f"{what}: one count must be between 1 nm and 1000 mm")
    return 1 / step


@njit(cache=True, nogil=True)
def quantise_rows(data, cols, scales, steps, counts, out, worst, carry, previous, shaped):
    """*out* = *data* with its axis columns *cols* rounded to counts (per column, *scales* counts per mm).

    counts: write the counts themselves; otherwise mm, ``n / scale`` (``n * step`` where the scale
    is not an integer: steps[c] > 0 only there).  worst[c] gathers the largest |rounded - exact| in mm,
    worst[len(cols) + c] the largest |count|; a value whose count would reach 2**52 returns its row
    (the caller refuses it), otherwise -1.  *shaped*: noise shaping (the module's docstring), carry[c]
    the rounding error carried to the next tick (counts), previous[c] the exact command of the tick
    before (NaN before the first); both updated for the next chunk.
    """
    out[:, :] = data
    m = cols.shape[0]
    for r in range(data.shape[0]):
        for c in range(m):
            j = cols[c]
            x = data[r, j]
            if not abs(x * scales[c]) < MAX_COUNTS:
                return r
            if shaped and x != previous[c] and previous[c] == previous[c]:  # NaN: the first tick, plain
                v = x * scales[c] + carry[c]
                n = np.rint(v)  # ties to even
                carry[c] = v - n
            else:  # plain, or the command holds: the nearest count, nothing carried on
                n = round_scaled(x, scales[c])  # ties to even, from the exact product
                carry[c] = 0.0
            previous[c] = x
            mm = n * steps[c] if steps[c] > 0.0 else n / scales[c]
            worst[c] = max(worst[c], abs(mm - x))
            worst[m + c] = max(worst[m + c], abs(n))
            out[r, j] = n if counts else mm
    return -1


class Quantiser:
    """Rounds the axis columns of a stream's chunks to a :class:`Resolution`, in mm or in counts.

    ``columns`` are the stream's (``x``, ``y``...); :attr:`columns` the ones written (``x_counts``
    ... with *counts*).  :attr:`worst` and :attr:`largest` hold, per axis, the largest rounding
    (mm) and the largest count so far.
    """

    def __init__(self, resolution: Resolution, columns, counts: bool = False, rounding: str = "nearest"):
        if rounding not in ROUNDINGS:
            raise ValueError(f"rounding {rounding!r}: use one of {', '.join(ROUNDINGS)}")
        self.resolution = resolution
        self.counts = counts
        self.rounding = rounding
        self.axes = [a for a in resolution.scales]
        self.cols = np.array([list(columns).index(a) for a in self.axes], dtype=np.int64)
        self.columns = [f"{c}_counts" if counts and c in resolution.scales else c for c in columns]
        fr = [resolution.scales[a] for a in self.axes]
        self.scales = np.array([float(s) for s in fr])
        self.steps = np.array([0.0 if s.denominator == 1 else float(1 / s) for s in fr])
        self._worst = np.zeros(2 * len(self.axes))
        self._carry = np.zeros(len(self.axes))  # shaped: the rounding error carried to the next tick, counts
        self._previous = np.full(len(self.axes), np.nan)  # the exact command of the tick before
        self._out = np.empty((0, len(columns)))

    def apply(self, data: np.ndarray) -> np.ndarray:
        """The chunk *data* rounded (a buffer reused by the next call: write it before calling again)."""
        if self._out.shape[0] < data.shape[0]:
            self._out = np.empty((data.shape[0], data.shape[1]))
        out = self._out[:data.shape[0]]
        bad = quantise_rows(data, self.cols, self.scales, self.steps, self.counts, out, self._worst, self._carry,
                            self._previous, self.rounding == "shaped")
        if bad >= 0:
            c = int(np.argmax(np.abs(data[bad, self.cols]) * self.scales))
            a = self.axes[c]
            raise UsageError(f"tick k = {data[bad, 0]:.0f}: {a} = {data[bad, self.cols[c]]:.6g} mm is "
                             f"{abs(data[bad, self.cols[c]]) * self.scales[c]:.3g} counts of "
                             f"{self.resolution.describe(a)}, beyond the 2**52 a count can be exactly")
        return out

    @property
    def worst(self) -> dict:
        return {a: float(self._worst[i]) for i, a in enumerate(self.axes)}

    @property
    def largest(self) -> dict:
        return {a: int(self._worst[len(self.axes) + i]) for i, a in enumerate(self.axes)}
