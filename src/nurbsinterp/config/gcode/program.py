"""A program's lines in the order LinuxCNC executes them: ``%`` ends, block delete, O-word control flow.

:func:`executed_lines` is the reader's source of blocks: it yields each executed line's words read
(:class:`~.words.Line`), and sets the line's parameter assignments once the consumer has carried the
line out — LinuxCNC's rule that ``#1=2 G1 X#1`` moves to the old ``#1``.  The consumer stops at the
program's end (``M2``/``M30``) by no longer asking for lines.

O-words (LinuxCNC 2.9, ``interp_o_word.cc``)
---------------------------------------------
``oN sub``/``endsub [v]``/``return [v]``/``call [a] [b]...`` (a label is a number, ``o0100`` being
``o100``, or a name ``o<name>``, case-insensitive); ``if [c]``/``elseif [c]``/``else``/``endif``;
``while [c]``/``endwhile``; ``do``/``while [c]``; ``repeat [n]``/``endrepeat``; ``break`` and
``continue`` of a ``while`` or ``do`` loop (LinuxCNC refuses them in a ``repeat``).  A call's
arguments are #1..#30 of the subroutine (see :mod:`.params`); a subroutine may be defined after its
call (LinuxCNC seeks forward through the file for it), not in another file.  A bare ``O1234`` is a
program number, read and ignored (LinuxCNC enters the "Fanuc-style program" and goes on).

The O-word lines are indexed once, before anything runs: each construct is matched with its end,
so that a jump is a table look-up and reading stays linear in the program's length.  That pass
refuses what cannot be run — an ``if`` without ``endif``, a ``while`` without ``endwhile``, a ``sub``
without ``endsub``, mismatched labels, a ``break`` outside its loop, a label opening two constructs
in one subroutine (LinuxCNC keeps one position per label: "duplicate O-word label").  Lines not
executed are not read at all (an ``if`` branch not taken may hold anything), as in LinuxCNC, which
reads only the O-words of the lines it skips.

LinuxCNC's own ways, kept because programs run on it rely on them (rs274 agrees, see
tests/test_rs274_language.py): a ``repeat`` keeps its count per label, not per call (a return from
inside it resumes the count at the next call); a ``break`` leaves LinuxCNC's doing_break flag set until
a ``do`` loop's closing ``while`` clears it (that loop then makes one pass), and a ``continue`` in a
``do`` loop leaves doing_continue set until the end of a ``while`` or ``repeat`` loop is skipped to
(which then loops back once more): see :class:`_LoopFlags`.  One difference: LinuxCNC evaluates a
subroutine's ``endsub [v]``/``return [v]`` values as it passes over the definition, changing
``#<_value>`` before any call; here only a return does.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Iterator

import numpy as np

from ...errors import SpecError
from .expr import ExprError, read_value
from .params import CALL_FRAMES, SUB_ARGS, Parameters
from .words import clean_line, program_lines, read_words, shown_word

#: The most lines a program may run beyond its own length (its loops and calls repeating lines): a
#: runaway loop stops here with an error instead of running for ever.  A million is ten times the
#: largest parametric program we know of (a few thousand passes of a pocket), yet is reached in a
#: few seconds; each executed line makes at most one block, so memory is bounded by it too.  A plain
#: program (no loop) runs each line once and never comes near it, whatever its length.
MAX_REPEATED_LINES = 1_000_000

_LABEL = re.compile(r"O(?:(<[^>]*>)|(\d+\.?\d*|\.\d+))")
#: LinuxCNC's order of matching (read_o): "else" after "elseif", "do" before "while"...
_KEYWORD = re.compile(r"SUB|ENDSUB|CALL|DO|WHILE|REPEAT|IF|ELSEIF|ELSE|ENDIF|BREAK|CONTINUE|ENDWHILE|ENDREPEAT|RETURN")
_OPENERS = ("if", "while", "do", "repeat")


class Context:
    """What reading a line needs beyond its text: the program's name (for messages) and its parameters.

    *params* is a :class:`~.params.Parameters` store shared with the machine, or a dict of initial
    values (``{10: 290.0, "feed": 300.0}``) from which one is made.
    """

    def __init__(self, name: str, params: Parameters | dict | None = None):
        self.name = name
        self.params = params if isinstance(params, Parameters) else Parameters(params)

    def fail(self, line: int, problem: str) -> SpecError:
        return SpecError(f"{self.name}:{line}: {problem}")


@dataclass(eq=False)
class OWord:
    """One O-word line: ``o<label> <kind> <rest>``, and the lines of its construct (indices into the file)."""

    index: int  # 0-based line of the file
    label: str  # "100" or "<name>" (canonical)
    kind: str  # sub endsub call do while repeat if elseif else endif break continue endwhile endrepeat return
    rest: str  # the cleaned text after the keyword: arguments, condition, value
    start: int  # where `rest` starts in `text`
    text: str  # the cleaned line
    opener: "OWord | None" = None  # the construct's first line (sub, if, while, do, repeat)
    end: "OWord | None" = None  # for an opener: its last line (endsub, endif, endwhile, do's while, endrepeat)
    next: "OWord | None" = None  # for if/elseif/else: the next branch (or the endif)
    branches: list = field(default_factory=list)  # for an if: its elseif/else lines
    breaks: list = field(default_factory=list)  # for a while or do loop: the lines of its breaks, in order

    @property
    def number(self) -> int:
        return self.index + 1

    @property
    def name(self) -> str:
        """The O-word as a message names it: ``o100 while``, ``o<pocket> call``."""
        return f"o{self.label} {self.kind}"


@dataclass
class _LoopFlags:
    """LinuxCNC's doing_break and doing_continue (interp_o_word.cc), global to the program as they are there.

    A break sets doing_break, which only a do loop's closing ``while`` clears: until then the next do loop
    ends after one pass.  A loop's own breaks set it too when LinuxCNC skips over them to the loop's end
    (its test failed, or a continue before them): it executes every line of the skipped loop's label on
    the way.  A continue sets doing_continue, which only the end of a while or repeat loop skipped to
    clears, by looping back: a continue in a do loop leaves it set, and the next such end loops back once
    more.  Programs run the same way here as in LinuxCNC (rs274 agrees, see tests/test_rs274_language.py).
    """

    doing_break: bool = False
    doing_continue: bool = False

    def skip_over(self, loop: OWord, index: int) -> None:
        """Skipping from line *index* to *loop*'s end passes over its breaks after that line."""
        if loop.breaks and loop.breaks[-1] > index:
            self.doing_break = True


@dataclass
class _Frame:
    """An active call: its subroutine and where to come back to."""

    sub: OWord | None  # None for the main program
    back: int  # the line after the call


#: the fewest plain lines taken as one run: below it the fixed cost of making a run's moves together (some
#: 0.2 ms of numpy) exceeds the general reader's (some 30 µs a line), as where plain lines come one at a time
#: between others (an S word on every other line, G1 and G3 alternating, a loop's body)
MIN_PLAIN_RUN = 16


@dataclass(eq=False)
class PlainRun:
    """Consecutive plain lines (``fast.scan``'s: G0/G1 moves of numbers, nothing to evaluate), taken whole.

    ``first``, ``last``: the run is lines [first, last) of the file, 0-based; ``table`` holds their words;
    ``read(k)`` is the general reading of line k (a :class:`~.words.Line`, or None for a blank one), for
    a line the fast path leaves to the general machine."""

    table: object
    first: int
    last: int
    read: object
    offset: int = 0  # lines of the file before the text the table was scanned from (a piece of the file)


class NotLinear(Exception):
    """A piece of a program holds an O-word: its flow may jump anywhere in the file, which must be read whole."""


@dataclass
class Flow:
    """What reading a program piece by piece (:func:`executed_lines` with *flow*) carries from piece to piece.

    A piece is executed line after line, as the whole file would be, as long as it holds no O-word (raised as
    :class:`NotLinear` before any of its lines is yielded: read the file whole from ``offset`` on, with
    *resume*).  The ``%`` rules need only the state before the piece: ``percent`` (the program opened with
    ``%``), ``seen`` (a line other than blanks came before), ``ended`` (the closing ``%`` was met: no line after
    it is read)."""

    offset: int = 0  # lines of the file before the piece
    percent: int = 0
    seen: bool = False
    ended: bool = False


def executed_lines(ctx: Context, text: str, table=None, *, flow: Flow | None = None, resume: int = 0) -> Iterator:
    """The program's lines, read, in execution order; a line's assignments take effect after it.

    With *table* (``fast.scan(text)``), each run of plain lines met in the flow comes as one
    :class:`PlainRun` instead of its lines (plain lines assign nothing and hold no O-word).
    With *flow*, *text* is a piece of the file after ``flow.offset`` lines (see :class:`Flow`); the flow is
    updated.  *resume*: the whole file is given, and execution starts at its line *resume* (0-based): the
    lines before it were executed piece by piece, and held no O-word."""
    lines = program_lines(text)
    offset = 0 if flow is None else flow.offset
    plain = run_end = None
    if table is not None:  # per line: plain or not, and where its run of plain lines ends (Python lists: looked up
        plain = table.plain.tolist()  # once a line, a numpy scalar each time would cost more than the line)
        general = np.append(np.flatnonzero(~table.plain), len(plain))
        run_end = general[np.searchsorted(general, np.arange(len(plain)))].tolist()

    def read(k: int):
        cleaned = clean_line(ctx, lines[k], k + 1 + offset)
        return read_words(ctx, cleaned, k + 1 + offset) if cleaned else None

    end, owords, subs, percents = _index(ctx, lines, flow)
    params = ctx.params
    frames = [_Frame(None, end)]
    budget = end + MAX_REPEATED_LINES - resume  # the lines before *resume* ran once each
    pc = resume
    seeking = False  # jumping to an if's next branch: an elseif there is tested, an else entered
    flags = _LoopFlags()
    repeats: dict = {}  # repeat O-word -> iterations left: one count per label, across calls, as LinuxCNC keeps it

    def skipped_to_end(loop: OWord) -> int:
        """Where a while or repeat loop goes on when its end is skipped to (its test failed, a break, a
        continue): LinuxCNC loops back if a continue is pending (its doing_continue flag), else leaves."""
        if flags.doing_continue:
            flags.doing_continue = False
            return loop.index
        return loop.end.index + 1

    last_jump = None  # the O-word that last sent execution back: the culprit of a runaway
    while pc < end:
        budget -= 1
        if budget < 0:
            culprit = last_jump or owords.get(pc) or OWord(pc, "?", "line", "", 0, "")  # the first: always set
            raise ctx.fail(culprit.number, f"{culprit.name}: the program runs more than {MAX_REPEATED_LINES:,} "
                                           f"lines beyond its own {end:,} (its loops and calls repeat them): a "
                                           f"loop that never ends?")
        ow = owords.get(pc)
        if ow is None:
            if plain is not None and plain[pc]:
                last = min(run_end[pc], end)
                if last - pc >= MIN_PLAIN_RUN:
                    budget -= last - pc - 1
                    yield PlainRun(table, pc, last, read, offset)
                    pc = last
                    continue
            if pc in percents:
                if percents[pc]:
                    raise ctx.fail(pc + 1 + offset, "'%' is only a program's first line and, after it, its end")
                pc += 1  # the opening '%'
                continue
            raw = lines[pc]
            pc += 1
            if raw.lstrip().startswith("/"):  # block delete: skipped, as with the switch on
                continue
            cleaned = clean_line(ctx, raw, pc + offset)
            if not cleaned:
                continue
            line = read_words(ctx, cleaned, pc + offset)
            yield line
            for key, value in line.assignments:  # after the line, as LinuxCNC sets parameters
                params[key] = value
            continue
        kind = ow.kind
        frame = frames[-1]
        was_seeking, seeking = seeking, False
        if kind == "program":  # a bare O-number: Fanuc's program number
            pc += 1
        elif kind == "sub":  # a definition met in the flow of the program: skipped
            pc = ow.end.index + 1
        elif kind in ("endsub", "return"):
            if frame.sub is None:
                raise ctx.fail(ow.number, f"{ow.name} outside a call")
            value = _value(ctx, ow, optional=True)
            params.leave(value)
            frames.pop()
            pc = frame.back
        elif kind == "call":
            sub = subs.get(ow.label)
            if sub is None:
                raise ctx.fail(ow.number, f"{ow.name}: no subroutine o{ow.label} in this file (o{ow.label} sub "
                                          f"... o{ow.label} endsub; other files are not read)")
            if len(frames) >= CALL_FRAMES:
                raise ctx.fail(ow.number, f"{ow.name}: more than {CALL_FRAMES - 1} nested calls (LinuxCNC's "
                                          f"limit)")
            args = _arguments(ctx, ow)
            params.enter(args)
            frames.append(_Frame(sub, pc + 1))
            last_jump = ow
            pc = sub.index + 1
        elif kind == "if" or kind == "elseif" and was_seeking:
            if _value(ctx, ow) != 0.0:
                pc += 1
            else:
                pc, seeking = ow.next.index, True
        elif kind in ("elseif", "else"):
            pc = ow.index + 1 if was_seeking else ow.opener.end.index + 1
        elif kind == "endif" or kind == "do":
            pc += 1
        elif kind == "while" and ow.opener is None:  # a while loop's head
            if _value(ctx, ow) != 0.0:
                pc += 1
            else:
                flags.skip_over(ow, pc)
                pc = skipped_to_end(ow)
        elif kind == "while":  # a do loop's end, reached or skipped to (break, continue): tested either way
            if _value(ctx, ow) != 0.0 and not flags.doing_break:
                last_jump = ow
                pc = ow.opener.index + 1
            else:
                flags.doing_break = False
                pc += 1
        elif kind == "endwhile" or kind == "endrepeat":
            last_jump = ow
            pc = ow.opener.index
        elif kind == "repeat":
            left = repeats.get(ow)
            if left is None:  # entering the loop: the count, rounded to nearest-even as C's nearbyint
                left = round(_value(ctx, ow))
            if left > 0:
                repeats[ow] = left - 1
                pc += 1
            else:
                repeats.pop(ow, None)
                pc = skipped_to_end(ow)
        elif kind == "break":
            flags.doing_break = True
            pc = skipped_to_end(ow.opener) if ow.opener.kind == "while" else ow.opener.end.index
        elif kind == "continue":
            flags.doing_continue = True
            flags.skip_over(ow.opener, pc)
            last_jump = ow
            pc = skipped_to_end(ow.opener) if ow.opener.kind == "while" else ow.opener.end.index
        else:  # not reached: _index knows only these kinds
            raise ctx.fail(ow.number, f"{ow.name}: not understood")


def _value(ctx: Context, ow: OWord, optional: bool = False) -> float | None:
    """The bracketed value after an O-word (a condition, a count, a return value); None if optional and absent."""
    if not ow.rest:
        if optional:
            return None
        raise ctx.fail(ow.number, f"{ow.name} needs a value in brackets: o{ow.label} {ow.kind} [...]")
    if not ow.rest.startswith("["):
        raise ctx.fail(ow.number, f"{ow.name} {ow.rest[:20]}: the value must be in brackets [...]")
    try:
        value, k = read_value(ow.text, ow.start, ctx.params)
    except ExprError as exc:
        raise ctx.fail(ow.number, f"{ow.name} {shown_word(ow.text, ow.start)}: {exc.problem}") from None
    if k != len(ow.text):
        raise ctx.fail(ow.number, f"{ow.name}: {ow.text[k:k + 20]!r} after its value")
    return value


def _arguments(ctx: Context, ow: OWord) -> list:
    """A call's arguments: ``[a] [b] ...``, at most #1..#30."""
    args = []
    k = ow.start
    text = ow.text
    while k < len(text):
        if text[k] != "[":
            raise ctx.fail(ow.number, f"{ow.name}: {text[k:k + 20]!r}: each argument is in brackets [...]")
        if len(args) == SUB_ARGS:
            raise ctx.fail(ow.number, f"{ow.name}: more than {SUB_ARGS} arguments")
        try:
            value, k = read_value(text, k, ctx.params)
        except ExprError as exc:
            raise ctx.fail(ow.number, f"{ow.name} {shown_word(text, k)}: {exc.problem}") from None
        args.append(value)
    return args


def _index(ctx: Context, lines: list, flow: Flow | None = None) -> tuple[int, dict, dict, dict]:
    """One pass over the program: where it ends (``%``), its O-words matched, its subroutines by label.

    Returns (end, owords by line index, subroutines by label, '%' lines: True where misplaced).  With *flow*,
    *lines* are a piece of the file (see :class:`Flow`): its '%' state is taken and updated, and an O-word
    raises :class:`NotLinear` before it is read.
    """
    percent = 0 if flow is None else flow.percent
    seen = False if flow is None else flow.seen  # a line other than blanks before it
    end = len(lines)
    owords: dict = {}
    subs: dict = {}
    percents: dict = {}
    stack: list = []  # open constructs, innermost last
    openers: dict = {}  # (subroutine label or "", label) -> the opener that holds the label
    for index, raw in enumerate(lines):
        stripped = raw.strip()
        if stripped.startswith("/"):
            continue
        if stripped == "%":
            if percent == 0 and not seen:
                percent = 1  # the program's first line: it ends at the next '%'
                percents[index] = False
                continue
            if percent:
                end = index
                break
            percents[index] = True  # an error if the program gets there (it may end before)
            continue
        seen = seen or bool(stripped)
        if "O" not in raw and "o" not in raw:  # the quick test: most lines hold no O at all
            continue
        try:
            text = clean_line(ctx, raw, index + 1)
        except SpecError:  # an unclosed comment: refused if the line is ever executed, not before
            continue
        k = 0
        if text.startswith("N"):
            m = re.match(r"N\d+(\.\d*)?", text)
            k = m.end() if m else 0
        if not text.startswith("O", k):
            continue
        if flow is not None:
            raise NotLinear
        ow = _oword(ctx, index, text, k)
        owords[index] = ow
        _match(ctx, ow, stack, openers, subs)
    if stack:
        ow = stack[-1]
        closing = {"sub": "endsub", "if": "endif", "while": "endwhile", "do": "while", "repeat": "endrepeat"}
        raise ctx.fail(ow.number, f"{ow.name} has no o{ow.label} {closing[ow.kind]}")
    if flow is not None:
        flow.percent, flow.seen, flow.ended = percent, seen, end < len(lines)
    return end, owords, subs, percents


def _oword(ctx: Context, index: int, text: str, k: int) -> OWord:
    m = _LABEL.match(text, k)
    if not m:
        raise ctx.fail(index + 1, f"{text[k:k + 20]!r}: an O-word's label is a number or <name> (computed "
                                  f"labels are not supported)")
    if m.group(1) is not None:
        label = "<" + "".join(m.group(1)[1:-1].split()).lower() + ">"
    else:
        number = float(m.group(2))
        if abs(number - round(number)) > 0.0001:
            raise ctx.fail(index + 1, f"O{m.group(2)}: an O-word's number is an integer")
        label = str(round(number))
    word = _KEYWORD.match(text, m.end())
    if word is None:
        if m.end() == len(text):
            return OWord(index, label, "program", "", m.end(), text)
        raise ctx.fail(index + 1, f"o{label} {text[m.end():m.end() + 12].lower()}: not an O-word command (sub, "
                                  f"endsub, call, do, while, repeat, if, elseif, else, endif, break, continue, "
                                  f"endwhile, endrepeat, return)")
    kind = word.group().lower()
    rest = text[word.end():]
    if rest and kind not in ("call", "if", "elseif", "while", "repeat", "return", "endsub"):
        raise ctx.fail(index + 1, f"o{label} {kind}: {rest[:20]!r} after it (nothing may follow but a comment)")
    return OWord(index, label, kind, rest, word.end(), text)


def _match(ctx: Context, ow: OWord, stack: list, openers: dict, subs: dict) -> None:
    """Match one O-word with the open constructs (*stack*); LinuxCNC's structural errors, found before running."""
    kind, fail = ow.kind, ctx.fail
    top = stack[-1] if stack else None
    scope = stack[0].label if stack and stack[0].kind == "sub" else ""
    if kind == "sub":
        if top is not None:
            raise fail(ow.number, f"{ow.name} inside the {top.name} of line {top.number} (subroutines are "
                                  f"defined at the top level and do not nest)")
        if ow.label in subs:
            raise fail(ow.number, f"{ow.name}: o{ow.label} is already defined on line {subs[ow.label].number}")
        subs[ow.label] = ow
        stack.append(ow)
        return
    if kind == "program":
        if top is not None:
            raise fail(ow.number, f"o{ow.label} alone inside the {top.name} of line {top.number} (a program "
                                  f"number, or a command missing?)")
        return
    if kind == "call":
        return
    if kind == "while" and top is not None and top.kind == "do" and top.label == ow.label:
        ow.opener, top.end = top, ow  # the end of a do loop
        stack.pop()
        return
    if kind in _OPENERS:
        key = (scope, ow.label)
        if key in openers:
            first = openers[key]
            raise fail(ow.number, f"{ow.name}: the label o{ow.label} already opens the {first.kind} of line "
                                  f"{first.number} (LinuxCNC keeps one position per label: \"duplicate O-word "
                                  f"label\")")
        openers[key] = ow
        stack.append(ow)
        return
    if kind in ("return", "endsub"):
        sub = stack[0] if stack and stack[0].kind == "sub" else None
        if sub is None:
            raise fail(ow.number, f"{ow.name} outside a subroutine definition")
        if sub.label != ow.label:
            raise fail(ow.number, f"{ow.name} inside the {sub.name} of line {sub.number}")
        if kind == "return":
            ow.opener = sub
            return
        if top is not sub:
            raise fail(top.number, f"{top.name} is not closed before the {ow.name} of line {ow.number}")
        sub.end, ow.opener = ow, sub
        stack.pop()
        return
    if kind in ("break", "continue"):
        for loop in reversed(stack):
            if loop.label == ow.label and loop.kind in ("while", "do"):
                ow.opener = loop
                if kind == "break":
                    loop.breaks.append(ow.index)
                return
            if loop.label == ow.label and loop.kind == "repeat":
                raise fail(ow.number, f"{ow.name}: LinuxCNC's {kind} leaves only while and do loops, not the "
                                      f"repeat of line {loop.number}")
        raise fail(ow.number, f"{ow.name} is not inside a while or do loop o{ow.label}")
    # the ends and middles of constructs: the innermost open one must be theirs
    wanted = {"elseif": "if", "else": "if", "endif": "if", "endwhile": "while", "endrepeat": "repeat"}[kind]
    if top is None or top.label != ow.label or top.kind != wanted:
        if top is None or top.kind == "sub":
            raise fail(ow.number, f"{ow.name} without o{ow.label} {wanted}")
        raise fail(ow.number, f"{ow.name} where the {top.name} of line {top.number} is still open")
    if kind in ("elseif", "else"):
        last = top.branches[-1] if top.branches else top
        if last.kind == "else":
            raise fail(ow.number, f"{ow.name} after the o{ow.label} else of line {last.number}")
        last.next = ow
        ow.opener = top
        top.branches.append(ow)
        return
    if kind == "endif":
        last = top.branches[-1] if top.branches else top
        last.next = ow
    ow.opener, top.end = top, ow
    stack.pop()
