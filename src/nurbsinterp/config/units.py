"""Values as users write them: numbers, and quantities with units ("6000 mm/min", "1 us")."""
from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

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


def is_bare_number(value: Any) -> bool:
    """Whether *value* is a number with no unit written (read in base units: mm, s)."""
    return _as_float(value) is not None


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
