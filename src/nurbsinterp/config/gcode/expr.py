"""Values as LinuxCNC reads them: numbers, parameters, ``[...]`` expressions and unary functions.

The rules are those of LinuxCNC 2.9's interpreter (``interp_read.cc``, ``interp_execute.cc``):

- A value is a number, ``#`` and a parameter, ``[`` an expression ``]``, a unary function
  (``SIN[30]``, ``ATAN[1]/[2]``, ``EXISTS[#<name>]``) or a sign before a value: ``-#1``,
  ``-[1+2]``, ``--1``.  The sign binds to the value alone: ``[-2**2]`` is 4.
- Binary operators, by precedence: ``**``; ``* / MOD``; ``+ -``; ``EQ NE GT GE LT LE``;
  ``AND OR XOR``.  Operators of equal precedence are applied left to right, ``**`` included:
  ``[2**3**2]`` is 64.  LinuxCNC evaluates with an operator stack as it reads, so errors come in
  reading order; :func:`_expression` keeps that stack.
- Angles are degrees (``SIN COS TAN`` take them, ``ASIN ACOS ATAN`` return them, ATAN in
  (-180, 180]).  ``FIX`` is floor, ``FUP`` ceiling, ``ROUND`` rounds half away from zero.
  ``a MOD b`` is C's ``fmod`` made non-negative by adding ``|b|``.  Logic yields 1 or 0, any
  non-zero being true.  ``EQ``/``NE`` compare within :data:`EQUAL_TOLERANCE`, and so do
  ``LE``/``GE`` on their equal side; ``LT``/``GT`` are exact.
- Every value read (a number, a parameter, a bracket, a function) must be finite: LinuxCNC checks
  each one ("Calculation resulted in 'not a number'"), not the steps inside a bracket, so
  ``[10**400 GT 1]`` is 1 while ``X[10**400]`` is an error.

The text read is a line already cleaned (comments removed, no spaces, upper case); problems are
raised as :class:`ExprError` and given their file, line and word by the line's reader.
"""
from __future__ import annotations

import math
import re

from .params import NUMBERED, canonical_name

#: Two values are EQ when closer than this: LinuxCNC 2.9.0's TOLERANCE_EQUAL (interp_internal.hh), which
#: also makes LE and GE true within it (commit 014777a "fix GE/LE operators", in every 2.9 release).
#: The Debian 2.9.0~pre1 rs274 predates that commit: it compares EQ/NE within 0.0001 and LE/GE exactly.
EQUAL_TOLERANCE = 1e-6
#: read_integer_value's rule: a parameter number or label must be within this of an integer.
INTEGER_TOLERANCE = 0.0001
_DEGREE = math.pi / 180.0

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_OPERATOR = re.compile(r"\*\*|[-+*/\]]|MOD|AND|XOR|OR|EQ|NE|GT|GE|LT|LE")
_FUNCTION = re.compile(r"ABS|ACOS|ASIN|ATAN|COS|EXISTS|EXP|FIX|FUP|LN|ROUND|SIN|SQRT|TAN")
_LETTERS = re.compile(r"[A-Z]*")
#: LinuxCNC's precedence() (interp_internal.cc); "]" ends an expression, so it is lowest.
PRECEDENCE = {"]": 1, "AND": 2, "OR": 2, "XOR": 2, "EQ": 3, "NE": 3, "GT": 3, "GE": 3, "LT": 3, "LE": 3,
              "+": 4, "-": 4, "*": 5, "/": 5, "MOD": 5, "**": 6}


class ExprError(Exception):
    """A value that cannot be read; *problem* says why (the caller adds file, line and word)."""

    def __init__(self, problem: str):
        super().__init__(problem)
        self.problem = problem


def read_value(text: str, k: int, params) -> tuple[float, int]:
    """The value at ``text[k:]`` and the index after it (LinuxCNC's read_real_value)."""
    m = _NUMBER.match(text, k)  # the common case first: a plain number
    if m:
        value = float(m.group())
        if value - value != 0.0:  # inf: a number too long for a double
            raise ExprError(f"{m.group()[:20]}... is too large a number")
        return value, m.end()
    try:
        return _value(text, k, params)
    except RecursionError:  # brackets, signs or #s nested hundreds deep: no program means it
        raise ExprError("the value is nested too deeply (brackets, signs or #s hundreds of levels deep)") from None


def read_integer(text: str, k: int, params) -> tuple[int, int]:
    """An integer value (a parameter's number, a label): LinuxCNC's read_integer_value, within 0.0001."""
    value, k = read_value(text, k, params)
    whole = math.floor(value)
    if value - whole > 1 - INTEGER_TOLERANCE:
        whole += 1
    elif value - whole > INTEGER_TOLERANCE:
        raise ExprError(f"{value:g} is not an integer")
    return int(whole), k


def _value(text: str, k: int, params) -> tuple[float, int]:
    if k >= len(text):
        raise ExprError("a value is missing at the end of the line")
    c = text[k]
    if c == "[":
        value, k = _expression(text, k, params)
    elif c == "#":
        value, k = read_parameter(text, k, params)
    elif c in "+-":  # a sign before a parameter, a bracket or a function (before digits it is the number's)
        value, k = _value(text, k + 1, params)
        if c == "-":
            value = -value
    elif c.isalpha():
        value, k = _function(text, k, params)
    else:
        m = _NUMBER.match(text, k)
        if not m and c in "]=":
            raise ExprError(f"a value is missing before '{c}'")
        if not m:
            raise ExprError(f"{text[k:k + 10]!r} is not a number")
        value, k = float(m.group()), m.end()
    if value != value:
        raise ExprError("the result is not a number (NaN)")
    if value - value != 0.0:
        raise ExprError("the result is infinite")
    return value, k


def read_parameter(text: str, k: int, params) -> tuple[float, int]:
    """The value of the parameter ``#...`` at ``text[k]``: ``#12``, ``##1``, ``#[#2+1]``, ``#<name>``."""
    if text.startswith("<", k + 1):
        name, k = read_name(text, k + 1)
        value = params.named(name)
        if value is None:
            raise ExprError(f"#<{name}> is read before it is set")
        return value, k
    index, k = read_integer(text, k + 1, params)
    if not 1 <= index < NUMBERED:
        raise ExprError(f"#{index}: numbered parameters run from #1 to #{NUMBERED - 1}")
    return params.read_numbered(index), k


def read_name(text: str, k: int) -> tuple[str, int]:
    """The name ``<...>`` at ``text[k]`` (canonical: lower case) and the index after ``>``."""
    end = text.find(">", k + 1)
    if end < 0:
        raise ExprError(f"{text[k:k + 20]!r}: the name is not closed by '>'")
    name = canonical_name(text[k + 1:end])
    if not name:
        raise ExprError("'<>' is an empty name")
    return name, end + 1


def _expression(text: str, k: int, params) -> tuple[float, int]:
    """``[...]`` at ``text[k]``: LinuxCNC's read_real_expression, an operator stack applied as it reads."""
    values = [0.0]
    operators = [""]
    values[0], k = _value(text, k + 1, params)
    operators[0], k = _operator(text, k)
    top = 1
    while operators[0] != "]":
        value, k = _value(text, k, params)
        operator, k = _operator(text, k)
        del values[top:], operators[top:]
        values.append(value)
        operators.append(operator)
        if PRECEDENCE[operator] > PRECEDENCE[operators[top - 1]]:
            top += 1
            continue
        while PRECEDENCE[operators[top]] <= PRECEDENCE[operators[top - 1]]:
            values[top - 1] = binary(values[top - 1], operators[top - 1], values[top])
            operators[top - 1] = operators[top]
            if top > 1 and PRECEDENCE[operators[top - 1]] <= PRECEDENCE[operators[top - 2]]:
                top -= 1
            else:
                break
    return values[0], k


def _operator(text: str, k: int) -> tuple[str, int]:
    m = _OPERATOR.match(text, k)
    if m:
        return m.group(), m.end()
    if k >= len(text):
        raise ExprError("'[' is not closed by ']'")
    raise ExprError(f"{text[k:k + 8]!r} is not an operator (+ - * / ** MOD AND OR XOR EQ NE GT GE LT LE or ])")


def binary(left: float, operator: str, right: float) -> float:
    """``left operator right`` as LinuxCNC's execute_binary1/2 compute it (C's fmod, pow, IEEE overflow)."""
    if operator == "+":
        return left + right
    if operator == "-":
        return left - right
    if operator == "*":
        return left * right
    if operator == "/":
        if right == 0.0:
            raise ExprError(f"division by zero ({left:g} / 0)")
        return left / right
    if operator == "MOD":
        try:
            result = math.fmod(left, right)
        except ValueError:  # fmod(x, 0), fmod(inf, y): C's NaN, refused when the value is used
            return math.nan
        return result + abs(right) if result < 0.0 else result
    if operator == "**":
        if left < 0.0 and math.floor(right) != right:
            raise ExprError(f"{left:g} ** {right:g}: a negative number to a non-integer power")
        try:
            return math.pow(left, right)
        except OverflowError:
            return -math.inf if left < 0.0 and right % 2 == 1 else math.inf
        except ValueError:  # 0 ** negative: C's pow gives inf
            return math.inf
    if operator == "EQ":
        return 1.0 if abs(left - right) < EQUAL_TOLERANCE else 0.0
    if operator == "NE":
        return 1.0 if not abs(left - right) < EQUAL_TOLERANCE else 0.0
    if operator == "LT":
        return 1.0 if left < right else 0.0
    if operator == "GT":
        return 1.0 if left > right else 0.0
    if operator == "LE":
        return 1.0 if abs(left - right) < EQUAL_TOLERANCE or left <= right else 0.0
    if operator == "GE":
        return 1.0 if abs(left - right) < EQUAL_TOLERANCE or left >= right else 0.0
    if operator == "AND":
        return 0.0 if left == 0.0 or right == 0.0 else 1.0
    if operator == "OR":
        return 1.0 if left != 0.0 or right != 0.0 else 0.0
    if operator == "XOR":
        return 1.0 if (left == 0.0) != (right == 0.0) else 0.0
    raise ExprError(f"{operator!r} is not an operator")  # not reached: _OPERATOR reads only these


def _function(text: str, k: int, params) -> tuple[float, int]:
    m = _FUNCTION.match(text, k)
    if not m or not text.startswith("[", m.end()):
        word = _LETTERS.match(text, k).group()
        if m and word == m.group():
            raise ExprError(f"{word} is not followed by '[' (write {word}[...])")
        raise ExprError(f"{word!r} is not a function (ABS ACOS ASIN ATAN COS EXISTS EXP FIX FUP LN ROUND SIN "
                        f"SQRT TAN)")
    name, k = m.group(), m.end()
    if name == "EXISTS":
        return _exists(text, k, params)
    value, k = _expression(text, k, params)
    if name == "ATAN":
        if not text.startswith("/[", k):
            raise ExprError("ATAN takes two values: ATAN[y]/[x]")
        x, k = _expression(text, k + 1, params)
        return math.atan2(value, x) / _DEGREE, k
    return unary(name, value), k


def unary(name: str, value: float) -> float:
    """A unary function of LinuxCNC's execute_unary (degrees for angles)."""
    if name in ("ASIN", "ACOS") and not -1.0 <= value <= 1.0:
        raise ExprError(f"{name}[{value:g}]: the argument is outside [-1, 1]")
    if name == "LN" and value <= 0.0:
        raise ExprError(f"LN[{value:g}]: the argument must be positive")
    if name == "SQRT" and value < 0.0:
        raise ExprError(f"SQRT[{value:g}]: the argument is negative")
    if not math.isfinite(value):  # inside a bracket an overflow may reach here: C gives inf or NaN
        return value if name in ("ABS", "FIX", "FUP", "ROUND", "EXP", "SQRT", "LN") else math.nan
    if name == "ABS":
        return abs(value)
    if name == "ACOS":
        return math.acos(value) / _DEGREE
    if name == "ASIN":
        return math.asin(value) / _DEGREE
    if name == "COS":
        return math.cos(value * _DEGREE)
    if name == "SIN":
        return math.sin(value * _DEGREE)
    if name == "TAN":
        return math.tan(value * _DEGREE)
    if name == "EXP":
        try:
            return math.exp(value)
        except OverflowError:
            return math.inf
    if name == "LN":
        return math.log(value)
    if name == "SQRT":
        return math.sqrt(value)
    if name == "FIX":
        return float(math.floor(value))
    if name == "FUP":
        return float(math.ceil(value))
    if name == "ROUND":  # (int)(x ± 0.5): half away from zero
        return float(math.trunc(value + (-0.5 if value < 0.0 else 0.5)))
    raise ExprError(f"{name} is not a function")  # not reached


def _exists(text: str, k: int, params) -> tuple[float, int]:
    """``EXISTS[#<name>]``: 1 if the parameter is set (a numbered one: if its number is in range)."""
    if not text.startswith("[#", k):
        raise ExprError("EXISTS takes a parameter: EXISTS[#<name>]")
    if text.startswith("<", k + 2):
        name, k = read_name(text, k + 2)
        value = 0.0 if params.named(name) is None else 1.0
    else:
        index, k = read_integer(text, k + 2, params)
        value = 1.0 if 1 <= index < NUMBERED else 0.0
    if not text.startswith("]", k):
        raise ExprError("EXISTS[#...] is not closed by ']'")
    return value, k + 1
