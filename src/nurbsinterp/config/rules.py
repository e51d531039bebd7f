"""Field rules shared by every reader: each failure is one line naming the source, the field and the value."""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import SpecError
from .units import _as_float, parse_quantity, show

MAX_CONTROL_POINTS = 1_000_000


class Where:
    """Where a field came from, so that each message names it."""

    def __init__(self, default: str, origins: dict[str, str] | None = None):
        self.default = default
        self.origins = origins or {}

    def fail(self, fieldname: str, value: Any, problem: str, *, shown: bool = True) -> SpecError:
        top = fieldname.split("[")[0]
        source = self.origins.get(top, self.default)
        text = f"{fieldname} = {show(value)} {problem}" if shown else f"{fieldname} {problem}"
        return SpecError(f"{source}: {text}")


def mapping(where: Where, name: str, value: Any, allowed: tuple[str, ...]) -> dict:
    if not isinstance(value, dict):
        raise where.fail(name, value, f"must be a mapping with keys {', '.join(allowed)}")
    for key in value:
        if key not in allowed:
            label = key if isinstance(key, str) and key.isidentifier() else show(key)
            raise where.fail(f"{name}.{label}" if name else label, value[key],
                             f"is not a known key (known: {', '.join(allowed)})", shown=False)
    return value


def finite(where: Where, name: str, value: Any) -> float:
    number = _as_float(value)
    if number is None:
        raise where.fail(name, value, "is not a number")
    if not math.isfinite(number):
        raise where.fail(name, value, "must be a finite number")
    return number


def integer(where: Where, name: str, value: Any) -> int:
    number = _as_float(value)
    if number is None or not math.isfinite(number) or number != int(number):
        raise where.fail(name, value, "must be an integer")
    return int(number)


def quantity(where: Where, name: str, value: Any, kind: str, *, positive: bool = True,
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


def choice(where: Where, name: str, value: Any, choices: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in choices:
        raise where.fail(name, value, f"is not one of {', '.join(choices)}")
    return value


def number_list(where: Where, name: str, value: Any, *, limit: int = MAX_CONTROL_POINTS * 2) -> np.ndarray:
    if not isinstance(value, list):
        raise where.fail(name, value, "must be a list of numbers")
    if not value:
        raise where.fail(name, value, "must not be empty")
    if len(value) > limit:
        raise where.fail(name, f"<{len(value)} values>", f"is longer than the limit of {limit}")
    out = np.empty(len(value))
    for i, item in enumerate(value):
        out[i] = finite(where, f"{name}[{i}]", item)
    return out
