"""Reading one line of a program: comments, words, numbers, parameters — as LinuxCNC reads a line."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from .codes import KNOWN_WORDS, OTHER_AXES

_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_PARAM = re.compile(r"#(\d+|<[^>]*>)")
_LINE_NUMBER = re.compile(r"N\d+(\.\d*)?")


@dataclass
class Line:
    """One block of the program, its words read (values in the program's units)."""

    number: int  # line of the file, 1-based
    g: list = field(default_factory=list)  # G-codes in tenths
    m: list = field(default_factory=list)
    words: dict = field(default_factory=dict)  # letter -> float
    assignments: list = field(default_factory=list)  # (parameter, value): set after the line


def strip_comments(ctx, text: str, number: int) -> str:
    out = []
    i = 0
    while i < len(text):
        c = text[i]
        if c == "(":
            j = text.find(")", i)
            if j < 0:
                raise ctx.fail(number, "a comment '(' is not closed on its line")
            if "(" in text[i + 1:j]:
                raise ctx.fail(number, "a comment holds another '(': comments do not nest")
            i = j + 1
            continue
        if c == ";":
            break
        out.append(c)
        i += 1
    return "".join(out)


def _value(ctx, text: str, k: int, number: int, letter: str) -> tuple[float, int]:
    """The value after a word's letter at text[k:]: a number or a parameter; (value, next index)."""
    m = _NUMBER.match(text, k)
    if m:
        return float(m.group()), m.end()
    m = _PARAM.match(text, k)
    if m:
        key = m.group(1).lower()
        if key not in ctx.params:
            raise ctx.fail(number, f"{letter}#{m.group(1)}: parameter #{m.group(1)} is used before it is set")
        return ctx.params[key], m.end()
    if text.startswith("[", k):
        raise ctx.fail(number, f"{letter}[...]: expressions are not supported by this reader (give the number)")
    shown = text[k:k + 12] or "nothing"
    raise ctx.fail(number, f"{letter} is followed by {shown!r}, not a number")


def parse_line(ctx, raw: str, number: int) -> Line | None:
    text = strip_comments(ctx, raw, number)
    text = "".join(text.split()).upper()  # LinuxCNC drops spaces and tabs outside comments
    if not text:
        return None
    line = Line(number)
    k = 0
    if text[0] == "N":  # a line number
        m = _LINE_NUMBER.match(text)
        if not m:
            raise ctx.fail(number, f"N is followed by {text[1:13]!r}, not a line number")
        k = m.end()
    first = k  # where the words start: an O-word may only stand here
    while k < len(text):
        c = text[k]
        if c == "#":  # an assignment #n=value or #<name>=value
            m = _PARAM.match(text, k)
            if not m or not text.startswith("=", m.end()):
                raise ctx.fail(number, f"{text[k:k + 12]!r} is not a parameter assignment #n=value")
            value, k = _value(ctx, text, m.end() + 1, number, m.group() + "=")
            line.assignments.append((m.group(1).lower(), value))
            continue
        if c == "O" and k > first:  # LinuxCNC reads an O-word only at the start of a line: here it is a stray O
            raise ctx.fail(number, f"{text[first:k + 1]!r}: an O after the words {text[first:k]!r} (an O-word "
                                    f"starts its line; a typo?)")
        if c == "O":
            raise ctx.fail(number, "O-words (subroutines, loops, conditions) are not supported by this reader")
        if not c.isalpha():
            raise ctx.fail(number, f"{text[k:k + 12]!r} is not a word (a letter and a number)")
        if c in OTHER_AXES:
            raise ctx.fail(number, f"{c} is an axis this reader does not drive (only X, Y and Z)")
        if c not in KNOWN_WORDS:
            raise ctx.fail(number, f"{c} is not a word this reader knows")
        value, k = _value(ctx, text, k + 1, number, c)
        if c == "G":
            code = round(value * 10)
            if abs(value * 10 - code) > 1e-6 or code < 0:
                raise ctx.fail(number, f"G{value:g} is not a G-code this reader knows")
            line.g.append(code)
        elif c == "M":
            if value != int(value) or value < 0:
                raise ctx.fail(number, f"M{value:g} is not an M-code")
            line.m.append(int(value))
        elif c == "N":
            raise ctx.fail(number, "N (a line number) must come first on its line")
        else:
            if c in line.words:
                raise ctx.fail(number, f"{c} is given twice on one line")
            line.words[c] = value
    return line


