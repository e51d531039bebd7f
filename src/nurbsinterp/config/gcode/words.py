"""Reading one line of a program: comments, words, numbers, parameters — as LinuxCNC reads a line."""
from __future__ import annotations

import re
from dataclasses import dataclass, field

from .codes import KNOWN_WORDS, OTHER_AXES
from .expr import ExprError, read_integer, read_name, read_value
from .params import NUMBERED, READ_ONLY

_LINE_NUMBER = re.compile(r"N\d+(\.\d*)?")
_NAME = re.compile(r"<[^>]*>")
#: A line of words with plain numbers, and one such word (letter, number).
_PLAIN = re.compile(r"(?:[A-Z][+-]?(?:\d+\.?\d*|\.\d+))+")
_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
#: The letters whose value is kept as it is (not G, M, N, O, nor an axis this reader does not drive).
_VALUE_WORDS = frozenset(KNOWN_WORDS - set("GMN"))


def program_lines(text: str) -> list[str]:
    """A program's lines as LinuxCNC reads them (fgets): split at ``\\n`` only — a form feed, a vertical tab or a
    Windows-1252 "…" (0x85) read as Latin-1 is a character of its line, not a break — a ``\\r`` before the
    ``\\n`` (CRLF) left out, no line after a final break."""
    lines = text.split("\n")
    if lines[-1] == "":
        lines.pop()
    return [line[:-1] if line.endswith("\r") else line for line in lines]


@dataclass
class Line:
    """One block of the program, its words read (values in the program's units)."""

    number: int  # line of the file, 1-based
    g: list = field(default_factory=list)  # G-codes in tenths
    m: list = field(default_factory=list)
    words: dict = field(default_factory=dict)  # letter -> float
    assignments: list = field(default_factory=list)  # (parameter, value): set after the line; an int key is #n


def strip_comments(ctx, text: str, number: int) -> str:
    """The line without its comments: ``(...)`` (not nested, closed on the line) and ``;`` to the end."""
    out = []
    i = 0
    while True:
        opening = text.find("(", i)
        semicolon = text.find(";", i)
        if semicolon >= 0 and (opening < 0 or semicolon < opening):
            out.append(text[i:semicolon])
            break
        if opening < 0:
            out.append(text[i:])
            break
        out.append(text[i:opening])
        closing = text.find(")", opening)
        if closing < 0:
            raise ctx.fail(number, "a comment '(' is not closed on its line")
        if "(" in text[opening + 1:closing]:
            raise ctx.fail(number, "a comment holds another '(': comments do not nest")
        i = closing + 1
    return "".join(out)


def clean_line(ctx, raw: str, number: int) -> str:
    """The line as LinuxCNC reads it: no comments, no spaces or tabs (dropped anywhere outside comments,
    so ``X 1 0 . 5`` is X10.5), upper case here (LinuxCNC lower-cases; names are case-insensitive)."""
    text = strip_comments(ctx, raw, number) if ("(" in raw or ";" in raw) else raw
    return "".join(text.split()).upper()


def parse_line(ctx, raw: str, number: int) -> Line | None:
    """One line of the program read (None if it holds nothing), its values evaluated with ``ctx.params``."""
    text = clean_line(ctx, raw, number)
    return read_words(ctx, text, number) if text else None


def read_words(ctx, text: str, number: int) -> Line:
    """The words of a cleaned line (see :func:`clean_line`), values read left to right as LinuxCNC reads them."""
    if _PLAIN.fullmatch(text):  # letters and numbers only, as CAM writes nearly every line: the quick way
        line = _plain_words(ctx, text, number)
        if line is not None:
            return line
    return _read_words(ctx, text, number)


def _plain_words(ctx, text: str, number: int) -> Line | None:
    """A line of letters and plain numbers read in one pass; None if it needs :func:`_read_words` (an error)."""
    line = Line(number)
    words = line.words
    pairs = _WORD.findall(text)
    if pairs[0][0] == "N":
        if not pairs[0][1][0].isdigit():  # N-5, N.5: not a line number
            return None
        pairs = pairs[1:]
    for letter, digits in pairs:
        value = float(digits)
        if letter in _VALUE_WORDS:
            if letter in words or value - value != 0.0:
                return None
            words[letter] = value
        elif letter == "G":
            line.g.append(_g_code(ctx, number, value))
        elif letter == "M":
            line.m.append(_m_code(ctx, number, value))
        else:
            return None
    return line


def _g_code(ctx, number: int, value: float) -> int:
    code = round(value * 10)
    if abs(value * 10 - code) > 1e-6 or code < 0:
        raise ctx.fail(number, f"G{value:g} is not a G-code this reader knows")
    return code


def _m_code(ctx, number: int, value: float) -> int:
    if value != int(value) or value < 0:
        raise ctx.fail(number, f"M{value:g} is not an M-code")
    if value in (98, 99):
        raise ctx.fail(number, f"M{value:g} (a Fanuc-style subprogram call or return) is not "
                               f"supported: use O-word subroutines (o100 sub ... o100 call)")
    return int(value)


def _read_words(ctx, text: str, number: int) -> Line:
    line = Line(number)
    params = ctx.params
    k = 0
    if text[0] == "N":  # a line number
        m = _LINE_NUMBER.match(text)
        if not m:
            raise ctx.fail(number, f"N is followed by {text[1:13]!r}, not a line number")
        k = m.end()
    first = k  # where the words start: an O-word may only stand here
    start = k
    try:
        while k < len(text):
            start = k
            c = text[k]
            if c == "#":  # an assignment #n=value or #<name>=value
                k = _assignment(text, k, params, line)
                continue
            if c == "O" and k > first:  # LinuxCNC reads an O-word only at the start of a line: a stray O
                raise ctx.fail(number, f"{text[first:k + 1]!r}: an O after the words {text[first:k]!r} (an "
                                       f"O-word starts its line; a typo?)")
            if c == "O":
                raise ctx.fail(number, f"{text[:24]!r}: an O-word where none is expected")
            if not c.isalpha():
                raise ctx.fail(number, f"{text[k:k + 12]!r} is not a word (a letter and a number)")
            if c in OTHER_AXES:
                raise ctx.fail(number, f"{c} is an axis this reader does not drive (only X, Y and Z)")
            if c not in KNOWN_WORDS:
                raise ctx.fail(number, f"{c} is not a word this reader knows")
            value, k = read_value(text, k + 1, params)
            if c == "G":
                line.g.append(_g_code(ctx, number, value))
            elif c == "M":
                line.m.append(_m_code(ctx, number, value))
            elif c == "N":
                raise ctx.fail(number, "N (a line number) must come first on its line")
            else:
                if c in line.words:
                    raise ctx.fail(number, f"{c} is given twice on one line")
                line.words[c] = value
    except ExprError as exc:
        raise ctx.fail(number, f"{shown_word(text, start)}: {exc.problem}") from None
    return line


def _assignment(text: str, k: int, params, line: Line) -> int:
    """``#n=value`` or ``#<name>=value`` at ``text[k]``: kept in *line* (set after the line); the next index."""
    if text.startswith("<", k + 1):
        key, k = read_name(text, k + 1)
        if params.is_read_only(key):
            raise ExprError(f"#<{key}> is read-only")
        params.declare(key)  # as LinuxCNC: the name exists (at 0) from here on, even on this line
    else:
        key, k = read_integer(text, k + 1, params)
        if not 1 <= key < NUMBERED:
            raise ExprError(f"#{key}: numbered parameters run from #1 to #{NUMBERED - 1}")
        if key in READ_ONLY:
            raise ExprError(f"#{key} is read-only (the machine keeps it)")
    if not text.startswith("=", k):
        raise ExprError("a parameter is given without '=' and a value (#n=value)")
    value, k = read_value(text, k + 1, params)
    line.assignments.append((key, value))
    return k


def shown_word(text: str, start: int, limit: int = 40) -> str:
    """The word at ``text[start]`` as written, for a message: up to the next word (a letter after a value's
    last character, outside brackets): ``X[1/0]`` of ``G1X[1/0]Y2``."""
    depth = 0
    i = start + 1
    while i < len(text):
        c = text[i]
        if c == "[":
            depth += 1
        elif c == "]":
            depth -= 1
        elif c == "<":
            close = text.find(">", i)
            i = len(text) - 1 if close < 0 else close
        elif (c.isalpha() or c == "#") and depth <= 0 and text[i - 1] in "0123456789.]>":
            break
        i += 1
    shown = _NAME.sub(lambda m: m.group().lower(), text[start:i])  # names as they are keyed: lower case
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."
