"""Reading plain CAM lines fast: a compiled scanner, and their straight moves as arrays.

Most of a CAM program is lines like ``G1 X-88.0758 Z-2.2982``: numbers, G0/G1, no
expression.  The general reader (:mod:`.words`, :mod:`.machine`) spends
some 50 µs on each, and one :class:`~nurbsinterp.config.path.LineBlock` alone costs
8 µs to build; reading at 200 000 blocks/s leaves 5 µs a line for everything.  So
the plain lines are read here in two steps, neither of which runs Python per line:

- :func:`scan` reads every line of the program's bytes in one compiled loop and
  says which lines are *plain* (below), with their words' values;
- :func:`straight_run` makes the moves of a run of consecutive plain lines with
  numpy, as arrays (end points, feedrates, rapid flags, line numbers).

Everything else (parameters, other codes, M/S/T words, a number whose
value this module cannot convert exactly, a second G) makes a line not plain,
and the general reader takes it: this module never refuses anything.

A line is plain when, its comments (``( )`` closed on the line and holding no ``(``,
``;`` to its end) and its spaces and tabs dropped (LinuxCNC drops them anywhere outside
comments, even inside numbers: ``X 1 0 . 5`` and ``X1(c)0.5`` are X10.5), it is empty or
an optional line number ``N`` followed only by the words G0/G1 (at most one G,
written ``G0``, ``G00``, ``G1``, ``G01``, ``g1.0``, … : any number equal to 0 or 1)
and X Y Z F (each at most once, F > 0), letters in either case, numbers as
LinuxCNC writes them: ``[+-]digits[.[digits]]`` or ``[+-].digits``.

Numbers are converted exactly as Python's ``float()`` converts them (correctly
rounded) by the classic exact fast path (Clinger 1990): the number's digits,
trailing zeros dropped, are an integer M < 2**53 and its power of ten 10**e has
|e| <= 22, so that M and 10**|e| are both exact doubles and one IEEE
multiplication or division of them is the correctly rounded value.  A number
outside that (17 significant digits, say) makes its line not plain.

Lines are split as LinuxCNC splits them (fgets: at ``\\n`` only, a ``\\r`` before it
left out), as :func:`~.words.program_lines` splits them for the general reader, so that
line i of the table is ``program_lines(text)[i]`` and line numbers agree.

How the reader uses it: :func:`scan` once per program; ``program.executed_lines``
gives each run of plain lines met in the program's flow as one ``PlainRun``, which
``machine.execute_run`` makes moves of with :func:`straight_run` (any line it leaves
going to the general machine) and blocks of in one loop.  ``read_gcode(...,
fast=False)``, every line by the general reader, is the tests' reference.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..._jit import njit
from ..curve import MAX_COORDINATE
from ..path import MIN_BLOCK_LENGTH

#: 10**0 .. 10**22: every one an exact double (5**22 < 2**53), made from exact integers
_POW10 = np.array([float(10 ** k) for k in range(23)])
_EXACT_MANTISSA = 2 ** 53  # integers below it are exact doubles
_MAX_EXP10 = 22
#: a line's word columns in PlainTable.words
WORD_COLUMNS = "XYZF"
#: a move this close above MIN_BLOCK_LENGTH (relative) may fall either side of it in the general reader's
#: np.linalg.norm, whose sum of squares may be ordered otherwise than ours: such a move is left to it
_NORM_MARGIN = 1e-9


@dataclass(frozen=True)
class PlainTable:
    """The program's lines, scanned: line i is ``program_lines(text)[i]``, the file's line i + 1.

    plain : (lines,) bool — the line is plain (module docstring): :func:`straight_run` can make its moves
    blank : (lines,) bool — plain and holding no word (nothing but spaces, tabs and comments)
    motion : (lines,) int16 — the line's G0 or G1 in tenths as the reader counts codes (0 or 10), -1 without
    words : (lines, 4) float64 — the values of X Y Z F in the program's units, NaN where the line has no such word
    """

    plain: np.ndarray
    blank: np.ndarray
    motion: np.ndarray
    words: np.ndarray

    def __len__(self) -> int:
        return len(self.plain)


class StraightState(NamedTuple):
    """The modes a run of plain lines starts from, as the reader's ``Machine`` holds them.

    position : (3,) mm — where the tool is
    absolute : bool — G90 (True) or G91
    scale : float — mm per program unit: 1.0 (G21) or 25.4 (G20)
    motion : the modal motion in tenths (0 G0, 10 G1; 20, 30, 52, 62 or None: a line that would need it
             ends the run)
    feedrate : mm/s, the F in effect, or None (NaN is taken as None) before any F
    offset : (3,) mm — the G92/G52 offset the program's absolute coordinates are shifted by (machine =
             program × scale + offset, as ``Machine.coordinate`` adds it: -0 + 0 is +0 there too)
    """

    position: np.ndarray
    absolute: bool
    scale: float
    motion: int | None
    feedrate: float | None
    offset: np.ndarray = np.zeros(3)


@dataclass(frozen=True)
class Moves:
    """The straight moves a run of plain lines makes, in order.

    start : (3,) mm — where the first move starts (the position the run started from)
    end : (n, 3) mm — each move's end point (move k starts at end[k - 1])
    feedrate : (n,) mm/s — NaN for rapids, and for feed moves before any F
    rapid : (n,) bool — G0
    line : (n,) int — the file's line (1-based) of each move
    dropped : zero-length moves (length <= MIN_BLOCK_LENGTH) left out
    next : index of the first table line not consumed: the run's ``last``, or a line the general reader must
           execute (a motion other than G0/G1, a move within rounding of MIN_BLOCK_LENGTH, a coordinate beyond
           MAX_COORDINATE, which the general reader refuses with its usual message)
    beyond : index of the table line whose coordinate is beyond MAX_COORDINATE (== next), or -1
    state : the modes after the lines consumed
    """

    start: np.ndarray
    end: np.ndarray
    feedrate: np.ndarray
    rapid: np.ndarray
    line: np.ndarray
    dropped: int
    next: int
    beyond: int
    state: StraightState

    def __len__(self) -> int:
        return len(self.line)


# --- the scanner -------------------------------------------------------------------------------------------------

@njit(cache=True)
def _line_bounds(data):
    """Each line's [start, end) in data, as :func:`~.words.program_lines` splits: at ``\n`` only (LinuxCNC reads
    a program with fgets), a ``\r`` before it left out, no line after a final break."""
    n = len(data)
    count = 0
    for i in range(n):
        if data[i] == 10:
            count += 1
    starts = np.empty(count + 1, np.int64)
    ends = np.empty(count + 1, np.int64)
    line = 0
    start = 0
    for i in range(n):
        if data[i] == 10:
            starts[line] = start
            ends[line] = i - 1 if i > start and data[i - 1] == 13 else i
            line += 1
            start = i + 1
    if start < n:  # a last line without a break
        starts[line] = start
        ends[line] = n - 1 if data[n - 1] == 13 else n
        line += 1
    return starts[:line], ends[:line]


@njit(cache=True, inline="always")
def _skip_blanks(data, i, end):
    """Past spaces, tabs and comments — ``( )`` closed on the line and holding no ``(``, and ``;`` to the
    line's end — as LinuxCNC drops them before it reads a line; -1 at a comment it refuses (left to the
    general reader, which says why)."""
    while i < end:
        b = data[i]
        if b == 32 or b == 9:
            i += 1
        elif b == 40:  # (
            j = i + 1
            while j < end and data[j] != 41:
                if data[j] == 40:
                    return -1
                j += 1
            if j == end:
                return -1
            i = j + 1
        elif b == 59:  # ;
            return end
        else:
            break
    return i


@njit(cache=True)
def _number(data, i, end, pow10):
    """The number at data[i:end] (spaces and tabs inside it skipped): (ok, value, next index).

    ok is False when there is no number there or when its value is not exact by the fast path.
    """
    i = _skip_blanks(data, i, end)
    if i < 0:
        return False, 0.0, 0
    negative = False
    if i < end and (data[i] == 43 or data[i] == 45):  # + -
        negative = data[i] == 45
        i += 1
    mantissa = 0  # the digits read, trailing zeros held back in `zeros`
    zeros = 0
    fraction = 0  # digits after the point
    digits = 0
    point = False
    while i < end:
        b = data[i]
        if b == 32 or b == 9 or b == 40 or b == 59:  # a blank or a comment inside the number: X1(c)2 is X12
            i = _skip_blanks(data, i, end)
            if i < 0:
                return False, 0.0, 0
            continue
        if 48 <= b <= 57:
            digits += 1
            if point:
                fraction += 1
            if b == 48:
                zeros += 1
            else:
                if mantissa == 0:
                    mantissa = b - 48
                else:
                    for _ in range(zeros + 1):
                        mantissa *= 10
                        if mantissa >= 9007199254740992:  # 2**53: not exact
                            return False, 0.0, i
                    mantissa += b - 48
                    if mantissa >= 9007199254740992:
                        return False, 0.0, i
                zeros = 0
        elif b == 46 and not point:  # .
            point = True
        else:
            break
        i += 1
    if digits == 0:
        return False, 0.0, i
    if mantissa == 0:
        value = 0.0
    else:
        e = zeros - fraction
        if e > 22 or e < -22:
            return False, 0.0, i
        value = float(mantissa) * pow10[e] if e >= 0 else float(mantissa) / pow10[-e]
    return True, -value if negative else value, i


@njit(cache=True)
def _scan_line(data, start, end, pow10, words, row):
    """Read one line: (plain, blank, motion) with the X Y Z F values put in words[row]."""
    i = _skip_blanks(data, start, end)
    if i < 0:
        return False, False, -1
    if i == end:
        return True, True, -1
    motion = -1
    b = data[i] | 32  # lower case
    if b == 110:  # n: a line number, digits with an optional fraction
        i = _skip_blanks(data, i + 1, end)
        if i == end or not 48 <= data[i] <= 57:
            return False, False, -1
        point = False
        while i < end:
            b = data[i]
            if 48 <= b <= 57 or b == 32 or b == 9:
                i += 1
            elif b == 46 and not point:
                point = True
                i += 1
            else:
                break
    while True:
        i = _skip_blanks(data, i, end)
        if i < 0:
            return False, False, -1
        if i == end:
            return True, False, motion
        b = data[i] | 32
        if b == 103:  # g
            column = -1
        elif b == 120:  # x
            column = 0
        elif b == 121:
            column = 1
        elif b == 122:
            column = 2
        elif b == 102:  # f
            column = 3
        else:
            return False, False, -1
        ok, value, i = _number(data, i + 1, end, pow10)
        if not ok:
            return False, False, -1
        if column < 0:
            if motion >= 0 or not (value == 0.0 or value == 1.0):
                return False, False, -1
            motion = 0 if value == 0.0 else 10
        else:
            if not np.isnan(words[row, column]):  # a word given twice: the general reader refuses it
                return False, False, -1
            if column == 3 and not value > 0.0:
                return False, False, -1
            words[row, column] = value


@njit(cache=True)
def _scan(data, starts, ends, pow10):
    lines = len(starts)
    plain = np.zeros(lines, np.bool_)
    blank = np.zeros(lines, np.bool_)
    motion = np.full(lines, -1, np.int16)
    words = np.full((lines, 4), np.nan)
    for row in range(lines):
        p, e, m = _scan_line(data, starts[row], ends[row], pow10, words, row)
        if p:
            plain[row] = True
            blank[row] = e
            motion[row] = m
        else:
            words[row, :] = np.nan  # a line not plain holds no values here
    return plain, blank, motion, words


def program_bytes(text: str | bytes) -> bytes:
    """The program as UTF-8 bytes, decoded first as the reader decodes a file (UTF-8, else Latin-1)."""
    if isinstance(text, str):
        return text.encode("utf-8", "surrogatepass")
    try:
        text.decode("utf-8")
        return bytes(text)
    except UnicodeDecodeError:
        return text.decode("latin-1").encode("utf-8")  # as the reader reads it


def scan(text: str | bytes) -> PlainTable:
    """Scan a program: which lines are plain, and their words' values (see the module docstring).

    Parameters
    ----------
    text : the program, as ``str`` or as the file's bytes (decoded as the reader decodes them)

    Returns
    -------
    PlainTable, one row a line of ``words.program_lines(text)``

    Examples
    --------
    >>> t = scan("G21\\nG1 X 1 0 . 5 f600\\n")
    >>> t.plain.tolist(), t.words[1].tolist()
    ([False, True], [10.5, nan, nan, 600.0])
    """
    data = np.frombuffer(program_bytes(text), np.uint8)
    starts, ends = _line_bounds(data)
    plain, blank, motion, words = _scan(data, starts, ends, _POW10)
    for a in (plain, blank, motion, words):
        a.setflags(write=False)
    return PlainTable(plain, blank, motion, words)


# --- the moves of a run ------------------------------------------------------------------------------------------

def _filled(present: np.ndarray) -> np.ndarray:
    """For each row, the index of the last row at or before it where *present* holds, -1 before any
    (along axis 0)."""
    index = np.arange(len(present)).reshape((-1,) + (1,) * (present.ndim - 1))
    last = np.where(present, index, -1)
    np.maximum.accumulate(last, axis=0, out=last)
    return last


def _targets(scaled: np.ndarray, given: np.ndarray, start: np.ndarray, absolute: bool, offset) -> np.ndarray:
    """The position after each line: (lines, 3) mm, from the words given (scaled to mm)."""
    if absolute:
        last_axis = _filled(given)
        placed = np.take_along_axis(scaled, np.maximum(last_axis, 0), axis=0) + offset  # as Machine.coordinate
        return np.where(last_axis >= 0, placed, start)
    # G91: end = position + word, the sums in the general reader's order; -0.0 for an axis not given
    # (x + -0.0 is x for every x, -0.0 included)
    steps = np.concatenate([start[None, :], np.where(given, scaled, -0.0)])
    return np.add.accumulate(steps, axis=0)[1:]


def straight_run(table: PlainTable, first: int, last: int, state: StraightState) -> Moves:
    """The straight moves of the plain lines table[first:last], from the modes *state*.

    Exactly what the general reader's ``execute`` makes of each line, in order: F first (F × scale / 60 mm/s),
    then the line's G0/G1 as the modal motion, then a move to the X Y Z given (absolute, or added to the
    position under G91; axes not given stay), a G0/G1 without coordinates moving nowhere.  Moves of length
    <= MIN_BLOCK_LENGTH are dropped, the position staying where it was.

    The run stops early (``Moves.next`` < last) at the first line the general reader must execute itself:
    coordinates under a modal motion other than G0/G1 (or none), a nonzero move not clearly longer than
    MIN_BLOCK_LENGTH (it is dropped there, and then the position does not follow the words), a coordinate
    beyond MAX_COORDINATE (``Moves.beyond``: the general reader refuses it with its usual message).
    Call it again from the line after.  The caller gives plain lines only, and none while a NURBS block
    (G5.2, G6.2) is being collected.

    No Python runs per line: numpy over the run (forward fills of the words, a cumulative sum under G91,
    which adds in the order the general reader adds, so the end points are the same doubles).
    """
    with np.errstate(over="ignore", invalid="ignore"):  # huge numbers: found below, refused by the general reader
        return _straight_run(table, first, last, state)


def _straight_run(table: PlainTable, first: int, last: int, state: StraightState) -> Moves:
    if not 0 <= first <= last <= len(table):
        raise ValueError(f"lines [{first}, {last}) are not within the table's {len(table)} lines")
    if not table.plain[first:last].all():
        raise ValueError(f"lines [{first}, {last}) are not all plain")
    start = np.array(state.position, dtype=float).reshape(3)
    offset = np.array(state.offset, dtype=float).reshape(3)
    scale = float(state.scale)
    feed0 = np.nan if state.feedrate is None else float(state.feedrate)
    motion0 = -1 if state.motion is None else int(state.motion)

    g = table.motion[first:last]
    words = table.words[first:last]
    given = ~np.isnan(words[:, :3])
    has_axes = given.any(axis=1)
    # the modal motion on each line (a line's own G applies to it)
    last_g = _filled(g >= 0)
    mode = np.where(last_g >= 0, g[np.maximum(last_g, 0)], motion0)
    # coordinates without G0/G1 in effect: an arc, a NURBS, or no motion at all — the general reader's
    not_straight = np.flatnonzero(has_axes & (mode != 0) & (mode != 10))
    stop = int(not_straight[0]) if len(not_straight) else last - first

    # end points of every line (those of lines that do not move are the position carried)
    scaled = words[:stop, :3] * scale
    given = given[:stop]
    moving = np.flatnonzero(has_axes[:stop] | (g[:stop] >= 0))
    ends = _targets(scaled, given, start, state.absolute, offset)[moving]
    delta = np.diff(np.concatenate([start[None, :], ends]), axis=0)
    zero = (delta == 0).all(axis=1)
    if (zero & has_axes[moving]).any():
        # a dropped move leaves the position as it was: the same numbers, but X-0 from 0.0 must leave +0.0
        # (not -0.0) for the axes the next lines do not give
        given = given.copy()
        given[moving[zero]] = False
        ends = _targets(scaled, given, start, state.absolute, offset)[moving]
    length = np.sqrt((delta * delta).sum(axis=1))
    tiny = ~zero & (length <= MIN_BLOCK_LENGTH * (1 + _NORM_MARGIN))
    beyond_rows = ~(np.abs(ends) <= MAX_COORDINATE).all(axis=1)
    beyond = -1
    odd = np.flatnonzero(tiny | beyond_rows)
    if len(odd):
        k = int(odd[0])
        stop = int(moving[k])
        if beyond_rows[k]:
            beyond = first + stop
        moving, ends, zero = moving[:k], ends[:k], zero[:k]

    # the F in effect on each line (a line's own F applies to it)
    feeds = words[:stop, 3] * scale / 60.0  # as the general reader: F * scale / 60, left to right
    last_f = _filled(~np.isnan(feeds))
    feed_on = np.where(last_f >= 0, feeds[np.maximum(last_f, 0)], feed0)

    kept = moving[~zero]
    rapid = mode[kept] == 0
    feedrate = np.where(rapid, np.nan, feed_on[kept])
    end = ends[~zero]
    position = end[-1].copy() if len(end) else start
    after = StraightState(position, state.absolute, state.scale,
                          state.motion if stop == 0 or mode[stop - 1] < 0 else int(mode[stop - 1]),
                          state.feedrate if stop == 0 or np.isnan(feed_on[stop - 1]) else float(feed_on[stop - 1]),
                          offset)
    return Moves(start, end, feedrate, rapid, kept + first + 1, int(zero.sum()), first + stop, beyond, after)
