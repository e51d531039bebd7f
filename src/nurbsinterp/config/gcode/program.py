"""A program's lines in the order LinuxCNC executes them: ``%`` ends, block delete, parameters.

:func:`executed_lines` is the reader's source of blocks: it yields each line's words read
(:class:`~.words.Line`), and sets the line's parameter assignments once the consumer has
carried the line out — LinuxCNC's rule that ``#1=2 G1 X#1`` moves to the old ``#1``.
"""
from __future__ import annotations

from typing import Iterator

from ...errors import SpecError
from .words import Line, parse_line


class Context:
    """What reading a line needs beyond its text: the program's name (for messages) and its parameters."""

    def __init__(self, name: str, params: dict | None = None):
        self.name = name
        self.params = {} if params is None else params

    def fail(self, line: int, problem: str) -> SpecError:
        return SpecError(f"{self.name}:{line}: {problem}")


def executed_lines(ctx: Context, text: str) -> Iterator[Line]:
    """The program's lines, read, in execution order; a line's assignments take effect after it."""
    percent = 0
    seen = False  # a line other than blanks before it
    for number, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        if stripped.startswith("/"):  # block delete: skipped, as with the switch on
            continue
        if stripped == "%":
            if percent == 0 and not seen:
                percent = 1  # the program's first line: it ends at the next '%'
                continue
            if percent:
                return
            raise ctx.fail(number, "'%' is only a program's first line and, after it, its end")
        seen = seen or bool(stripped)
        line = parse_line(ctx, raw, number)
        if line is None:
            continue
        yield line
        for key, value in line.assignments:  # after the line, as LinuxCNC sets parameters
            ctx.params[key] = value
