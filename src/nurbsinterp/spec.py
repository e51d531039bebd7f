"""Job files: YAML in, validated and frozen objects out.

Everything a user can get wrong is checked here, at the boundary, so that the
geometry and the per-tick kernels never have to.  Each violated rule raises a
:class:`~nurbsinterp.errors.SpecError` whose message is one line naming the
source (file or option), the field, the index and the value::

    circle.yaml: curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5

YAML is read with a safe loader that also refuses duplicate keys and aliases
(an alias bomb expands to gigabytes from a few lines).
"""
from __future__ import annotations

import math
import os
import re
import sys
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import yaml

from .errors import SpecError

MAX_DEGREE = 25
MAX_COORDINATE = 1e12  # mm: squares and cross products of coordinates stay far from overflow
MAX_WEIGHT_RATIO = 1e6  # largest weight over smallest (see validate_curve)
# Each weight within [MIN_WEIGHT, MAX_WEIGHT] (see validate_curve).  The kernels multiply weights
# into homogeneous points w·P (|P| <= MAX_COORDINATE) and their u-derivative tables (factors up to
# ((degree / MIN_KNOT_SPAN)^3 ~ 1.6e94), and the contour search multiplies two of them together:
# w_i·w_j·d² and |w_i (P_i - q)|·|w_j (P_j - q)| with distances d down to its 1e-9 mm tolerance.
# Those products must stay normal doubles: w² · (1e-9 mm)² >= 2.2e-308 needs w >= 1.5e-145, and
# (w · 2e12 mm)² <= 1.8e308 (and 1.3e107·w finite for the third-derivative table) needs
# w <= 6e141.  [1e-100, 1e100] keeps forty orders of magnitude of margin for the sums, the
# dimension and the binomial factors; a subnormal weight (5e-324 makes every w·P of an ordinary
# coordinate vanish or lose all its digits) is far outside it.  Scaling every weight by one
# factor does not change the curve, so any curve can be brought inside.
MIN_WEIGHT = 1e-100
MAX_WEIGHT = 1e100
MAX_KNOT = 1e30  # |u| bound: with MIN_KNOT_SPAN it keeps the third derivative in u finite
MIN_KNOT_SPAN = 1e-30
MAX_U_RESOLUTION = 1e-6  # mm of curve between adjacent representable u values (see _check_resolution)
MAX_CONTROL_POINTS = 1_000_000
MAX_FILE_BYTES = 64 * 1024 * 1024

PROFILE_TYPES = ("trapezoidal", "exponential", "bell", "adaptive")
LIMIT_FIELDS = {  # the adaptive profile's limits: field -> kind of quantity
    "chord_tolerance": "length",
    "max_accel": "accel",
    "max_jerk": "jerk",
    "max_normal_accel": "accel",
}
AXIS_LIMITS = {"max_velocity": "feedrate", "max_accel": "accel"}
METHODS = ("taylor1", "taylor2", "rk4", "exact")
ACCDEC = ("before", "after")
SECTION_KEYS = {
    "curve": ("degree", "order", "control_points", "weights", "knots"),
    "profile": ("type", "feedrate", "accel_time", "time_constant", "accdec", *LIMIT_FIELDS, "axes"),
    "interpolator": ("method", "period"),
}


# --------------------------------------------------------------------------- values


def show(value: Any) -> str:
    """Render a value for an error message: short, unambiguous, one line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        text = str(int(value))
        return text if len(text) <= 24 else f"{text[:12]}...{text[-6:]} ({len(text.lstrip('-'))} digits)"
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if value is None:
        return "null"
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


_NUMBER = re.compile(r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?\s*$")


def _as_float(value: Any) -> float | None:
    """A number, or a string that is one (YAML 1.1 reads ``1e-3`` as a string)."""
    if isinstance(value, bool):
        return None
    try:
        if isinstance(value, (int, float, np.integer, np.floating)):
            return float(value)
        if isinstance(value, str) and _NUMBER.match(value):
            return float(value)
    except OverflowError:  # an integer with hundreds of digits
        return math.inf if value > 0 else -math.inf
    return None


# --------------------------------------------------------------------------- units

_LENGTH_UNITS = {"nm": 1e-6, "um": 1e-3, "µm": 1e-3, "μm": 1e-3, "mm": 1.0, "cm": 10.0, "m": 1e3, "in": 25.4}
_TIME_UNITS = {"ns": 1e-9, "us": 1e-6, "µs": 1e-6, "μs": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0}
_POWERS = {"": 1, "^2": 2, "2": 2, "²": 2, "^3": 3, "3": 3, "³": 3}

#: kind -> (power of length, power of time, units to suggest)
QUANTITIES = {
    "length": (1, 0, "mm, um, nm"),
    "time": (0, 1, "s, ms, us"),
    "feedrate": (1, -1, "mm/s, mm/min, m/min"),
    "accel": (1, -2, "mm/s^2, m/s^2"),
    "jerk": (1, -3, "mm/s^3, m/s^3"),
}
_QUANTITY = re.compile(r"^\s*([+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?)\s*(.*?)\s*$")


def _unit_scale(unit: str) -> tuple[int, int, float] | None:
    """``'mm/min'`` -> (1, -1, 1/60): powers of length and time and the factor to mm, s."""
    num, _, den = unit.partition("/")
    num, den = num.strip(), den.strip()
    if num in _LENGTH_UNITS:
        lpow, scale = 1, _LENGTH_UNITS[num]
    elif num in _TIME_UNITS and not den:
        return 0, 1, _TIME_UNITS[num]
    else:
        return None
    if not den:
        return lpow, 0, scale
    m = re.match(r"^(ns|us|µs|μs|ms|s|min)(\^2|\^3|2|3|²|³)?$", den)
    if m is None:
        return None
    tpow = _POWERS[m.group(2) or ""]
    return lpow, -tpow, scale / _TIME_UNITS[m.group(1)] ** tpow


def parse_quantity(value: Any, kind: str) -> float:
    """Read a number in base units (mm, s) or a string with a unit.

    Raises ``ValueError`` with the reason (no location: the caller adds it).

    >>> parse_quantity("6000 mm/min", "feedrate")
    100.0
    >>> parse_quantity("250 us", "time")
    0.00025
    """
    lpow, tpow, suggest = QUANTITIES[kind]
    number = _as_float(value)
    if number is not None:
        return number
    if not isinstance(value, str):
        raise ValueError(f"is not a number or a quantity with a unit ({suggest})")
    m = _QUANTITY.match(value)
    if m is None:
        raise ValueError(f"is not a number or a quantity with a unit ({suggest})")
    unit = m.group(2)
    scaled = _unit_scale(unit)
    if scaled is None:
        raise ValueError(f"has an unknown unit {unit!r} (use {suggest})")
    if scaled[:2] != (lpow, tpow):
        noun = kind.replace("accel", "acceleration")
        raise ValueError(f"is not {'an' if noun[0] in 'aeiou' else 'a'} {noun} (use {suggest})")
    return float(m.group(1)) * scaled[2]


# --------------------------------------------------------------------------- YAML


class _Loader(yaml.SafeLoader):
    """Safe loading that also refuses aliases and duplicate keys."""

    def compose_node(self, parent, index):  # noqa: D401 - PyYAML hook
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.MarkedYAMLError(problem="YAML aliases (*name) are not allowed in job files",
                                       problem_mark=event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, Any] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                hash(key)
            except TypeError:
                raise yaml.MarkedYAMLError(problem="a mapping key must be a plain value",
                                           problem_mark=key_node.start_mark) from None
            if key in seen:
                raise yaml.MarkedYAMLError(problem=f"duplicate key {show(key)} (first at line {seen[key] + 1})",
                                           problem_mark=key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        # Python refuses int() of more than 4300 digits (a ValueError PyYAML lets through)
        try:
            return super().construct_yaml_int(node)
        except ValueError:
            raise yaml.MarkedYAMLError(problem=f"the integer {show(node.value)} has too many digits",
                                       problem_mark=node.start_mark) from None


_Loader.add_constructor("tag:yaml.org,2002:int", _Loader.construct_yaml_int)


FAST_YAML_BYTES = 1 << 16  # files above this size try the event reader first
_MAX_DEPTH = 64
_PLAIN_INT = re.compile(r"[-+]?(?:0|[1-9][0-9]*)")
_PLAIN_FLOAT = re.compile(r"[-+]?[0-9]+\.[0-9]*(?:[eE][-+][0-9]+)?")
_NO_KEY = object()


class _Unusual(Exception):
    """Something only the full loader reads (or refuses with its message)."""


def _plain_value(value: str, resolver, constructor):
    """A plain scalar as SafeLoader reads it; decimal numbers without the regex resolver."""
    if _PLAIN_INT.fullmatch(value):
        return int(value)  # ValueError past 4300 digits: the full loader words that
    if _PLAIN_FLOAT.fullmatch(value):
        return float(value)
    return constructor.construct_object(yaml.ScalarNode(resolver.resolve(yaml.ScalarNode, value, (True, False)),
                                                        value))


def _fast_yaml(text: str):
    """The document of a plain YAML file, built from libyaml's events.

    A large control net read by the pure-Python loader costs about 0.3 ms a point
    (a minute for 200,000 points); libyaml's events and this builder take a
    hundredth of that.  Only mappings, sequences and untagged scalars are read
    here: an alias, anchor, tag, merge key, duplicate key, second document, deep
    nesting or syntax error raises _Unusual, and the caller reads the file again
    with the full loader, which gives the same result or the usual message.
    """
    from yaml.constructor import SafeConstructor
    from yaml.resolver import Resolver

    resolver, constructor = Resolver(), SafeConstructor()
    stack: list = []  # [container, pending key] of each open collection
    root = None
    documents = 0

    def add(value):
        nonlocal root
        if not stack:
            root = value
            return
        top = stack[-1]
        if isinstance(top[0], list):
            top[0].append(value)
        elif top[1] is _NO_KEY:
            try:
                if value in top[0] or value == "<<":  # a duplicate or a merge key
                    raise _Unusual
            except TypeError:  # an unhashable key
                raise _Unusual from None
            top[1] = value
        else:
            top[0][top[1]] = value
            top[1] = _NO_KEY

    try:
        for event in yaml.parse(text, Loader=yaml.CSafeLoader):
            kind = type(event)
            if kind is yaml.ScalarEvent:
                if event.anchor is not None or event.tag is not None:
                    raise _Unusual
                add(_plain_value(event.value, resolver, constructor) if event.implicit[0] else event.value)
            elif kind is yaml.MappingStartEvent or kind is yaml.SequenceStartEvent:
                if event.anchor is not None or event.tag is not None or len(stack) >= _MAX_DEPTH:
                    raise _Unusual
                stack.append([{} if kind is yaml.MappingStartEvent else [], _NO_KEY])
            elif kind is yaml.MappingEndEvent or kind is yaml.SequenceEndEvent:
                add(stack.pop()[0])
            elif kind is yaml.DocumentStartEvent:
                documents += 1
                if documents > 1:
                    raise _Unusual
            elif kind is yaml.AliasEvent:
                raise _Unusual
    except _Unusual:
        raise
    except Exception:  # noqa: BLE001 - any error: the full loader reads it again and words it
        raise _Unusual from None
    return root


def read_yaml(path: str | os.PathLike) -> dict:
    """Read one YAML mapping from *path*; every failure is a one-line SpecError."""
    name = os.fspath(path)
    try:
        if os.path.isdir(name):
            raise SpecError(f"{name}: is a directory, not a YAML file")
        with open(name, "rb") as fh:
            raw = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None
    if len(raw) > MAX_FILE_BYTES:
        raise SpecError(f"{name}: larger than {MAX_FILE_BYTES // 2**20} MiB; refusing to read it")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(f"{name}: is not UTF-8 text (byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None
    doc = _Unusual
    if len(raw) > FAST_YAML_BYTES and getattr(yaml, "__with_libyaml__", False):
        try:
            doc = _fast_yaml(text)
        except _Unusual:
            pass
    try:
        if doc is _Unusual:
            doc = yaml.load(text, Loader=_Loader)  # noqa: S506 - _Loader is a SafeLoader
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" line {mark.line + 1}, column {mark.column + 1}:" if mark is not None else ""
        problem = " ".join(str(exc.problem or exc.context or "invalid YAML").split())
        raise SpecError(f"{name}:{where} {problem}") from None
    except yaml.YAMLError as exc:
        raise SpecError(f"{name}: invalid YAML: {' '.join(str(exc).split())}") from None
    except RecursionError:
        raise SpecError(f"{name}: YAML nested too deeply") from None
    if doc is None:
        raise SpecError(f"{name}: the file is empty")
    if not isinstance(doc, dict):
        raise SpecError(f"{name}: the document must be a mapping with a 'curve' key, not a {type(doc).__name__}")
    return doc


# --------------------------------------------------------------------------- frozen objects


@dataclass(frozen=True)
class CurveSpec:
    """A validated NURBS: degree p, control points (n+1, dim), weights (n+1,), knots (n+p+2,)."""

    degree: int
    control_points: np.ndarray
    weights: np.ndarray
    knots: np.ndarray

    def __post_init__(self):
        for arr in (self.control_points, self.weights, self.knots):
            arr.setflags(write=False)

    @property
    def fingerprint(self) -> str:
        """16 hex digits that name this curve exactly (degree, control points, weights, knots).

        A binary stream carries it, so that `simulate` can tell a stream planned from another job.
        """
        import hashlib

        digest = hashlib.sha1(b"%d" % self.degree)
        for arr in (self.control_points, self.weights, self.knots):
            digest.update(b"%d," % arr.shape[-1] if arr.ndim > 1 else b"1,")
            digest.update(np.ascontiguousarray(arr, dtype="<f8").tobytes())
        return digest.hexdigest()[:16]


@dataclass(frozen=True)
class ProfileSpec:
    """Feedrate planning.  feedrate in mm/s, accel_time and time_constant in s."""

    type: str = "trapezoidal"
    feedrate: float = 100.0
    accel_time: float = 0.5
    time_constant: float | None = None  # exponential only; None means accel_time / 4
    accdec: str = "before"
    # the adaptive type's limits (None: no such limit); the other types ignore them
    chord_tolerance: float | None = None  # mm
    max_accel: float | None = None  # mm/s², tangential
    max_jerk: float | None = None  # mm/s³, tangential
    max_normal_accel: float | None = None  # mm/s², centripetal
    axes: tuple = ()  # ((axis, max_velocity or None, max_accel or None), ...)

    @property
    def tau(self) -> float:
        """Time constant of the exponential shape and of the after-interpolation lag."""
        return self.time_constant if self.time_constant is not None else self.accel_time / 4.0


@dataclass(frozen=True)
class InterpolatorSpec:
    """The real-time interpolator: method and sampling period T in s.

    ``method_default`` is True where the job left the method to the default: ``taylor2``
    (the paper's Eq. 9), or ``exact`` with the adaptive profile, whose limits only an
    interpolator that follows the plan exactly keeps in the emitted stream (the Taylor
    and RK methods drift from the plan by their truncation error and snap at the end).
    """

    method: str = "taylor2"
    period: float = 0.001
    method_default: bool = field(default=False, compare=False)  # provenance, not part of the value


@dataclass(frozen=True)
class Job:
    curve: CurveSpec
    profile: ProfileSpec = field(default_factory=ProfileSpec)
    interpolator: InterpolatorSpec = field(default_factory=InterpolatorSpec)
    source: str = "<job>"
    # how the user wrote the fields a summary echoes: ((dotted field, value as written, where from), ...)
    given: tuple = ()

    def with_overrides(self, **changes) -> "Job":
        return replace(self, **changes)


# --------------------------------------------------------------------------- validation


class _Where:
    """Where a field came from, so that each message names it."""

    def __init__(self, default: str, origins: dict[str, str] | None = None):
        self.default = default
        self.origins = origins or {}

    def fail(self, fieldname: str, value: Any, problem: str, *, shown: bool = True) -> SpecError:
        top = fieldname.split("[")[0]
        source = self.origins.get(top, self.default)
        text = f"{fieldname} = {show(value)} {problem}" if shown else f"{fieldname} {problem}"
        return SpecError(f"{source}: {text}")


def _mapping(where: _Where, name: str, value: Any, allowed: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise where.fail(name, value, f"must be a mapping with keys {', '.join(allowed)}")
    for key in value:
        if key not in allowed:
            label = key if isinstance(key, str) and key.isidentifier() else show(key)
            raise where.fail(f"{name}.{label}" if name else label, value[key],
                             f"is not a known key (known: {', '.join(allowed)})", shown=False)
    return value


def _finite(where: _Where, name: str, value: Any) -> float:
    number = _as_float(value)
    if number is None:
        raise where.fail(name, value, "is not a number")
    if not math.isfinite(number):
        raise where.fail(name, value, "must be a finite number")
    return number


def _integer(where: _Where, name: str, value: Any) -> int:
    number = _as_float(value)
    if number is None or not math.isfinite(number) or number != int(number):
        raise where.fail(name, value, "must be an integer")
    return int(number)


def _quantity(where: _Where, name: str, value: Any, kind: str, *, positive: bool = True,
              zero_ok: bool = False) -> float:
    try:
        number = parse_quantity(value, kind)
    except ValueError as exc:
        raise where.fail(name, value, str(exc)) from None
    if not math.isfinite(number):
        raise where.fail(name, value, "must be a finite number")
    if positive and (number < 0 or (number == 0 and not zero_ok)):
        raise where.fail(name, value, "must be >= 0" if zero_ok else "must be > 0")
    return number


def _choice(where: _Where, name: str, value: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise where.fail(name, value, f"is not one of {', '.join(choices)}")
    return value


def _number_list(where: _Where, name: str, value: Any, *, limit: int = MAX_CONTROL_POINTS * 2) -> np.ndarray:
    if not isinstance(value, list):
        raise where.fail(name, value, "must be a list of numbers")
    if not value:
        raise where.fail(name, value, "must not be empty")
    if len(value) > limit:
        raise where.fail(name, f"<{len(value)} values>", f"is longer than the limit of {limit}")
    out = np.empty(len(value))
    for i, item in enumerate(value):
        out[i] = _finite(where, f"{name}[{i}]", item)
    return out


def validate_curve(raw: Any, where: _Where) -> CurveSpec:
    raw = _mapping(where, "curve", raw, SECTION_KEYS["curve"])
    if "degree" in raw and "order" in raw:
        raise where.fail("curve.order", raw["order"], "is given together with curve.degree; give one (order = degree + 1)")
    if "degree" in raw:
        degree = _integer(where, "curve.degree", raw["degree"])
        if degree < 1:
            raise where.fail("curve.degree", raw["degree"], "must be >= 1")
        if degree > MAX_DEGREE:
            raise where.fail("curve.degree", raw["degree"], f"is above the supported maximum of {MAX_DEGREE}")
    elif "order" in raw:
        order = _integer(where, "curve.order", raw["order"])
        if order < 2:
            raise where.fail("curve.order", raw["order"], "must be >= 2 (order = degree + 1)")
        if order > MAX_DEGREE + 1:
            raise where.fail("curve.order", raw["order"], f"is above the supported maximum of {MAX_DEGREE + 1}")
        degree = order - 1
    else:
        raise where.fail("curve", "", "needs a degree (or order = degree + 1)", shown=False)

    if "control_points" not in raw:
        raise where.fail("curve", "", "needs control_points", shown=False)
    cps = raw["control_points"]
    if not isinstance(cps, list) or not cps:
        raise where.fail("curve.control_points", cps, "must be a non-empty list of [x, y] or [x, y, z] points")
    if len(cps) > MAX_CONTROL_POINTS:
        raise where.fail("curve.control_points", f"<{len(cps)} points>", f"has more than the limit of {MAX_CONTROL_POINTS} points")
    dim = None
    points = []
    for i, cp in enumerate(cps):
        name = f"curve.control_points[{i}]"
        if not isinstance(cp, list) or len(cp) not in (2, 3):
            raise where.fail(name, cp, "must be a point [x, y] or [x, y, z]")
        if dim is None:
            dim = len(cp)
        elif len(cp) != dim:
            raise where.fail(name, cp, f"has {len(cp)} coordinates; curve.control_points[0] has {dim}")
        coords = [_finite(where, f"{name}[{j}]", c) for j, c in enumerate(cp)]
        for j, c in enumerate(coords):
            if abs(c) > MAX_COORDINATE:
                raise where.fail(f"{name}[{j}]", cp[j], f"mm is beyond the supported range of +-{MAX_COORDINATE:g} mm")
        points.append(coords)
    control_points = np.array(points, dtype=float)
    n_ctrl = len(points)
    if n_ctrl < degree + 1:
        raise where.fail("curve.control_points", f"<{n_ctrl} points>",
                         f"are too few for degree {degree} (need at least degree + 1 = {degree + 1})")

    if "weights" in raw:
        weights = _number_list(where, "curve.weights", raw["weights"])
        if len(weights) != n_ctrl:
            raise where.fail("curve.weights", f"<{len(weights)} values>", f"must have one weight per control point ({n_ctrl})")
        for i, w in enumerate(weights):
            if not w > 0:
                raise where.fail(f"curve.weights[{i}]", raw["weights"][i], "must be > 0")
            if not MIN_WEIGHT <= w <= MAX_WEIGHT:
                kind = "subnormal, " if w < sys.float_info.min else ""
                raise where.fail(f"curve.weights[{i}]", raw["weights"][i],
                                 f"is {kind}outside the supported range [{MIN_WEIGHT:g}, {MAX_WEIGHT:g}] (products of "
                                 "weights and coordinates would underflow or overflow); scale all the weights by one "
                                 "factor (the curve does not change)")
        lo, hi = int(np.argmin(weights)), int(np.argmax(weights))
        if weights[hi] / weights[lo] > MAX_WEIGHT_RATIO:
            raise where.fail(f"curve.weights[{hi}]", raw["weights"][hi],
                             f"is {weights[hi] / weights[lo]:.3g} times curve.weights[{lo}] = {show(raw['weights'][lo])}; "
                             f"the supported ratio is at most {MAX_WEIGHT_RATIO:g} (beyond it part of the curve is "
                             "squeezed into a sliver of u that double precision cannot step through evenly)")
    else:
        weights = np.ones(n_ctrl)

    n_knots = n_ctrl + degree + 1
    if "knots" in raw:
        knots = _number_list(where, "curve.knots", raw["knots"])
        _check_knots(where, knots, degree, n_ctrl, raw["knots"])
    else:  # clamped, uniform on [0, 1]
        inner = np.linspace(0.0, 1.0, n_ctrl - degree + 1)
        knots = np.concatenate([np.zeros(degree), inner, np.ones(degree)])
    assert len(knots) == n_knots
    _check_resolution(where, control_points, weights, knots, degree)
    return CurveSpec(degree, control_points, weights, knots)


def _check_resolution(where: _Where, points: np.ndarray, weights: np.ndarray, knots: np.ndarray, p: int) -> None:
    """The knot domain must keep u resolvable and the derivatives in u finite.

    Scaling the knots does not change the curve, but u is what the interpolator
    steps: a domain too narrow for its magnitude ([1, 1 + 1e-15]) has a handful of
    representable u values, and a span of 1e-300 makes |P'|² overflow.  Adjacent
    doubles u and u + ulp(u) lie about |C'(u)|·ulp(u) apart on the curve; the rule is

        max over the domain of |C'(u)|·ulp(u)  <=  max(1e-6 mm, 1e-12 · control polygon length)

    with the maximum taken over samples of every span (a polynomial span whose
    hodograph bounds it within the limit is cleared unsampled) (:func:`_max_step_per_ulp`: both span ends and
    17 points per span, refined wherever the chord between two samples shows the
    speed peaking between them).  Not the polygon's average
    speed: a rational curve with a large weight moves through most of its length in
    a sliver of u, where |C'| is many times the average.
    """
    a, b = float(knots[p]), float(knots[-p - 1])
    name = "curve.knots"
    if abs(a) > MAX_KNOT or abs(b) > MAX_KNOT:
        raise where.fail(name, "", f"domain [{a:g}, {b:g}] is beyond +-{MAX_KNOT:g}; rescale the knots "
                         "(the curve does not change)", shown=False)
    spans = np.diff(knots)
    narrow = spans[(spans > 0) & (spans < MIN_KNOT_SPAN)]
    if narrow.size:
        raise where.fail(name, "", f"domain [{a:g}, {b:g}] has a knot span of {narrow[0]:g}, narrower than "
                         f"{MIN_KNOT_SPAN:g}; merge those knots or rescale them", shown=False)
    polygon = float(np.linalg.norm(np.diff(points, axis=0), axis=1).sum())
    # 1 nm, or 1e-12 of the path on paths over a kilometre (whose coordinates themselves are
    # not finer than that); a domain [0, 1] always passes
    allowed = max(MAX_U_RESOLUTION, 1e-12 * polygon)
    step, at = _max_step_per_ulp(points, weights, knots, p, allowed)
    if not step <= allowed:
        raise where.fail(name, "", f"domain [{a!r}, {b!r}] is too narrow for its magnitude: adjacent values of u "
                         f"lie up to {step:.3g} mm apart on the curve (max |C'(u)|·ulp(u), near u = {at!r}; at most "
                         f"{allowed:.3g} mm is supported); shift or rescale the knots (the curve does not change)",
                         shown=False)


RESOLUTION_SAMPLES = 17  # per knot span, both ends included (see _max_step_per_ulp)
RESOLUTION_ROUNDS = 12  # refinements of the intervals where the speed may peak between samples
_RESOLUTION_CHUNK = 1 << 16  # samples evaluated at once (memory: tens of MB at degree 25)


def _speeds(points, weights, knots, p, span, u):
    """|C'(u)| at parameters u, each on its knot span (the span's polynomial: u may be its right end).

    Plain numpy (validation runs before the compiled kernels load): Cox–de Boor
    for the basis of degree p - 1 and p, the derivative from the former, then the
    quotient rule on the homogeneous sums.
    """
    m = u.shape[0]
    low = cur = np.ones((m, 1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        for d in range(1, p + 1):
            prev = low = cur
            cur = np.zeros((m, d + 1))
            for r in range(d + 1):
                i = span - d + r
                if r >= 1:
                    den = knots[i + d] - knots[i]
                    cur[:, r] += np.where(den > 0, (u - knots[i]) / np.where(den > 0, den, 1.0), 0.0) * prev[:, r - 1]
                if r <= d - 1:
                    den = knots[i + d + 1] - knots[i + 1]
                    cur[:, r] += np.where(den > 0, (knots[i + d + 1] - u) / np.where(den > 0, den, 1.0), 0.0) * prev[:, r]
        N = cur  # degree p; low is degree p - 1
        dN = np.zeros((m, p + 1))
        for r in range(p + 1):
            i = span - p + r
            if r >= 1:
                den = knots[i + p] - knots[i]
                dN[:, r] += np.where(den > 0, p / np.where(den > 0, den, 1.0), 0.0) * low[:, r - 1]
            if r <= p - 1:
                den = knots[i + p + 1] - knots[i + 1]
                dN[:, r] -= np.where(den > 0, p / np.where(den > 0, den, 1.0), 0.0) * low[:, r]
        idx = span[:, None] - p + np.arange(p + 1)[None, :]
        w = weights[idx]
        P = points[idx]
        W = (N * w).sum(axis=1)
        dW = (dN * w).sum(axis=1)
        A = np.einsum("mr,mrc->mc", N * w, P)
        dA = np.einsum("mr,mrc->mc", dN * w, P)
        C = A / W[:, None]
        D = (dA - dW[:, None] * C) / W[:, None]
        return np.sqrt((D * D).sum(axis=1)), C


def _max_step_per_ulp(points, weights, knots, p, allowed: float = 0.0) -> tuple[float, float]:
    """(max of |C'(u)|·ulp(u) over samples of the domain, the u where it is), mm.

    A polynomial span (equal weights) whose hodograph's control points bound the
    product by *allowed* is cleared without samples.  Every other non-empty knot span is sampled at RESOLUTION_SAMPLES points, both ends
    included (the speed of a rational piece peaks at an end or near the control
    point of a large weight).  Between two samples the mean value theorem gives
    max |C'| >= chord / Δu; where that exceeds both samples' speeds by a quarter
    the speed peaks in between, and the interval is sampled again, up to
    RESOLUTION_ROUNDS times (each round narrows the peak 16-fold).  The chords
    count as well as the speeds, so the result is a lower bound of the true
    maximum that the refinement makes tight.
    """
    n = points.shape[0] - 1
    idx = np.flatnonzero(knots[p:n + 1] < knots[p + 1:n + 2]) + p  # non-empty spans
    best, best_u = 0.0, float(knots[p])
    # a span whose p + 1 weights are equal is a polynomial piece: its hodograph's control points
    # p (P_{j+1} - P_j) / (U_{j+p+1} - U_{j+1}) bound |C'| exactly (convex hull), no sampling needed
    changes = np.concatenate([[0], np.cumsum(weights[1:] != weights[:-1])])  # O(n) memory, any degree
    plain = changes[idx] == changes[idx - p]  # weights span - p .. span all equal
    if plain.any():
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            jj = np.arange(n)
            hodo = p * np.linalg.norm(points[1:] - points[:-1], axis=1) / (knots[jj + p + 1] - knots[jj + 1])
            hodo = np.nan_to_num(hodo, nan=np.inf)
            sp = idx[plain]
            top = hodo[sp - p]
            for r in range(1, p):  # j = span - p .. span - 1
                top = np.maximum(top, hodo[sp - p + r])
            step = top * np.spacing(np.maximum(np.abs(knots[sp]), np.abs(knots[sp + 1])))
        clear = step <= allowed  # the bound clears these; the others are sampled like rational spans
        if clear.any():
            k = int(np.argmax(np.where(clear, step, -1.0)))
            best, best_u = float(step[k]), float(knots[sp[k]])
        cleared = np.zeros(idx.shape[0], dtype=bool)
        cleared[np.flatnonzero(plain)[clear]] = True
        idx = idx[~cleared]
    t = np.linspace(0.0, 1.0, RESOLUTION_SAMPLES)
    lo, hi = knots[idx], knots[idx + 1]
    spans = idx
    for _ in range(RESOLUTION_ROUNDS + 1):
        next_lo, next_hi, next_spans = [], [], []
        for c0 in range(0, spans.shape[0], max(1, _RESOLUTION_CHUNK // RESOLUTION_SAMPLES)):
            c1 = c0 + max(1, _RESOLUTION_CHUNK // RESOLUTION_SAMPLES)
            l, h, s = lo[c0:c1], hi[c0:c1], spans[c0:c1]
            u = (l[:, None] + (h - l)[:, None] * t[None, :])
            u[:, -1] = h
            flat_s = np.repeat(s, RESOLUTION_SAMPLES)
            speed, C = _speeds(points, weights, knots, p, flat_s, u.reshape(-1))
            speed = speed.reshape(u.shape)
            C = C.reshape(u.shape + (points.shape[1],))
            du = np.diff(u, axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                chord = np.sqrt(((C[:, 1:] - C[:, :-1]) ** 2).sum(axis=2)) / du
            chord = np.where(du > 0, chord, 0.0)
            ulp = np.spacing(np.abs(u))
            ulp_mid = np.maximum(ulp[:, 1:], ulp[:, :-1])
            for values, where_u, scale in ((speed, u, ulp), (chord, u[:, :-1], ulp_mid)):
                prod = values * scale
                if not np.isfinite(prod).all():
                    k = np.unravel_index(int(np.argmax(~np.isfinite(prod))), prod.shape)
                    return math.inf, float(where_u[k])
                k = np.unravel_index(int(np.argmax(prod)), prod.shape)
                if prod[k] > best:
                    best, best_u = float(prod[k]), float(where_u[k])
            peak = (chord > 1.25 * np.maximum(speed[:, 1:], speed[:, :-1])) & (du > np.spacing(np.abs(u[:, 1:])) * 4)
            if peak.any():
                r, j = np.nonzero(peak)
                next_lo.append(u[r, j])
                next_hi.append(u[r, j + 1])
                next_spans.append(s[r])
        if not next_lo:
            break
        lo, hi, spans = np.concatenate(next_lo), np.concatenate(next_hi), np.concatenate(next_spans)
        if lo.shape[0] > 1 << 16:  # bounded work: at most 65 536 intervals a round
            lo, hi, spans = lo[: 1 << 16], hi[: 1 << 16], spans[: 1 << 16]
    return best, best_u


def _check_knots(where: _Where, knots: np.ndarray, p: int, n_ctrl: int, raw: list) -> None:
    need = n_ctrl + p + 1
    if len(knots) != need:
        raise where.fail("curve.knots", f"<{len(knots)} values>",
                         f"has the wrong length: {n_ctrl} control points of degree {p} need {need} knots (n_ctrl + degree + 1)")
    for i in range(1, len(knots)):
        if knots[i] < knots[i - 1]:
            raise where.fail(f"curve.knots[{i}]", raw[i], f"is smaller than curve.knots[{i - 1}] = {show(raw[i - 1])}")
    for i in range(1, p + 1):
        if knots[i] != knots[0]:
            raise where.fail(f"curve.knots[{i}]", raw[i],
                             f"differs from curve.knots[0] = {show(raw[0])}: the curve must be clamped (the first degree + 1 = {p + 1} knots equal)")
    last = len(knots) - 1
    for i in range(last - p, last):
        if knots[i] != knots[last]:
            raise where.fail(f"curve.knots[{i}]", raw[i],
                             f"differs from curve.knots[{last}] = {show(raw[last])}: the curve must be clamped (the last degree + 1 = {p + 1} knots equal)")
    if knots[p + 1] == knots[0]:
        raise where.fail(f"curve.knots[{p + 1}]", raw[p + 1],
                         f"repeats the start knot: its multiplicity may be at most degree + 1 = {p + 1}")
    if knots[last - p - 1] == knots[last]:
        raise where.fail(f"curve.knots[{last - p - 1}]", raw[last - p - 1],
                         f"repeats the end knot: its multiplicity may be at most degree + 1 = {p + 1}")
    run = 1
    for i in range(p + 2, last - p):
        run = run + 1 if knots[i] == knots[i - 1] else 1
        if run > p:
            raise where.fail(f"curve.knots[{i}]", raw[i],
                             f"makes an interior knot of multiplicity {run}, more than the degree {p} (the curve would break apart)")


def validate_profile(raw: dict, where: _Where) -> ProfileSpec:
    raw = _mapping(where, "profile", raw, SECTION_KEYS["profile"])
    kwargs: dict[str, Any] = {}
    if "type" in raw:
        kwargs["type"] = _choice(where, "profile.type", raw["type"], PROFILE_TYPES)
    if "feedrate" in raw:
        kwargs["feedrate"] = _quantity(where, "profile.feedrate", raw["feedrate"], "feedrate")
    if "accel_time" in raw:
        kwargs["accel_time"] = _quantity(where, "profile.accel_time", raw["accel_time"], "time", zero_ok=True)
    if "time_constant" in raw and raw["time_constant"] is not None:
        kwargs["time_constant"] = _quantity(where, "profile.time_constant", raw["time_constant"], "time")
    if "accdec" in raw:
        kwargs["accdec"] = _choice(where, "profile.accdec", raw["accdec"], ACCDEC)
    for key, kind in LIMIT_FIELDS.items():
        if raw.get(key) is not None:
            kwargs[key] = _quantity(where, f"profile.{key}", raw[key], kind)
    if raw.get("axes") is not None:
        axes_raw = _mapping(where, "profile.axes", raw["axes"], ("x", "y", "z"))
        axes = []
        for axis in ("x", "y", "z"):
            if axis not in axes_raw:
                continue
            limits = _mapping(where, f"profile.axes.{axis}", axes_raw[axis], tuple(AXIS_LIMITS))
            axes.append((axis, *(None if limits.get(key) is None else
                                 _quantity(where, f"profile.axes.{axis}.{key}", limits[key], kind)
                                 for key, kind in AXIS_LIMITS.items())))
        kwargs["axes"] = tuple(axes)
    spec = ProfileSpec(**kwargs)
    if spec.type == "adaptive" and spec.accdec == "after":
        raise where.fail("profile.accdec", "after", "cannot be used with profile.type = 'adaptive', "
                         "which plans the feedrate along the curve before interpolation")
    _check_ramp(spec, where)
    return spec


def _check_ramp(spec: ProfileSpec, where: _Where) -> None:
    """The ramp's acceleration must be a number: a subnormal accel_time or time constant makes it inf.

    The bound is the largest acceleration any shape reaches before the peak is
    lowered: F/Ta·π/2 (bell), F/τ (exponential, whose ratio Ta/τ must also be finite).
    """
    if spec.accel_time == 0:
        return
    F, Ta, tau = spec.feedrate, spec.accel_time, spec.tau
    problem = (f"s is too short: profile.feedrate = {F:g} mm/s would be reached with an infinite acceleration "
               "(accel_time 0 gives an instant start)")
    if not math.isfinite(F / Ta * math.pi / 2):
        raise where.fail("profile.accel_time", Ta, problem)
    if spec.type == "exponential":
        fieldname, value = (("profile.time_constant", spec.time_constant) if spec.time_constant is not None
                            else ("profile.accel_time", Ta))
        if not (tau > 0 and math.isfinite(F / tau) and math.isfinite(Ta / tau)):
            raise where.fail(fieldname, value, problem)


def validate_interpolator(raw: dict, where: _Where) -> InterpolatorSpec:
    raw = _mapping(where, "interpolator", raw, SECTION_KEYS["interpolator"])
    kwargs: dict[str, Any] = {}
    if "method" in raw:
        kwargs["method"] = _choice(where, "interpolator.method", raw["method"], METHODS)
    if "period" in raw:
        kwargs["period"] = _quantity(where, "interpolator.period", raw["period"], "time")
    return InterpolatorSpec(**kwargs)


#: command-line option -> dotted job field it overrides
OVERRIDE_FIELDS = {
    "profile_type": "profile.type",
    "feedrate": "profile.feedrate",
    "accel_time": "profile.accel_time",
    "time_constant": "profile.time_constant",
    "accdec": "profile.accdec",
    "interpolator": "interpolator.method",
    "period": "interpolator.period",
    "chord_tolerance": "profile.chord_tolerance",
    "max_accel": "profile.max_accel",
    "max_jerk": "profile.max_jerk",
    "max_normal_accel": "profile.max_normal_accel",
}


def load_job(path: str | os.PathLike, *, profile_file: str | os.PathLike | None = None,
             overrides: dict[str, Any] | None = None) -> Job:
    """Read and validate a job file.

    Parameters
    ----------
    path : job YAML with ``curve`` and optional ``profile`` and ``interpolator``.
    profile_file : optional YAML with ``profile`` and/or ``interpolator`` sections; its
        fields override the job file's, field by field.
    overrides : ``{option name: value}`` from the command line (keys of
        :data:`OVERRIDE_FIELDS`, e.g. ``{"feedrate": "6000 mm/min"}``); ``None`` values
        are ignored.  They win over both files.
    """
    name = os.fspath(path)
    doc = read_yaml(name)
    where = _Where(name)
    _mapping(where, "", doc, tuple(SECTION_KEYS))
    if "curve" not in doc:
        raise SpecError(f"{name}: has no 'curve' section")
    sections = {s: dict(_mapping(where, s, {} if doc.get(s) is None else doc[s], SECTION_KEYS[s]))
                for s in ("profile", "interpolator")}
    origins: dict[str, str] = {}
    if profile_file is not None:
        pname = os.fspath(profile_file)
        pdoc = read_yaml(pname)
        pwhere = _Where(pname)
        _mapping(pwhere, "", pdoc, ("profile", "interpolator"))
        for section in ("profile", "interpolator"):
            if section in pdoc:
                for key, value in _mapping(pwhere, section, pdoc[section], SECTION_KEYS[section]).items():
                    sections[section][key] = value
                    origins[f"{section}.{key}"] = pname
    for option, value in (overrides or {}).items():
        if value is None:
            continue
        dotted = OVERRIDE_FIELDS[option]
        section, key = dotted.split(".")
        sections[section][key] = value
        origins[dotted] = "--" + option.replace("_", "-")
    where = _Where(name, origins)
    given = tuple((dotted, sections[dotted.split(".")[0]][dotted.split(".")[1]], origins.get(dotted, name))
                  for dotted in ECHOED_FIELDS if dotted.split(".")[1] in sections[dotted.split(".")[0]])
    curve = validate_curve(doc["curve"], where)
    profile = validate_profile(sections["profile"], where)
    interpolator = validate_interpolator(sections["interpolator"], where)
    if "method" not in sections["interpolator"]:
        interpolator = replace(interpolator, method="exact" if profile.type == "adaptive" else "taylor2",
                               method_default=True)
    return Job(curve=curve, profile=profile, interpolator=interpolator,
               source=name, given=given)


#: the fields whose units a run summary echoes, so that a user can confirm a conversion
ECHOED_FIELDS = ("profile.feedrate", "profile.accel_time", "interpolator.period")

