"""Writing output that never loses a byte: every write takes all its bytes or raises.

``write(2)`` may take fewer bytes than it was given: a pipe whose reader goes away
mid-write, a file that reaches its size limit (``RLIMIT_FSIZE``), a signal.  Python's
raw ``FileIO.write`` returns that short count and leaves the rest to the caller; a
``BufferedWriter`` loops, but Python gives ``sys.stdout`` no ``BufferedWriter`` under
``PYTHONUNBUFFERED=1`` or ``python -u`` (its ``buffer`` is then the raw ``FileIO``), and
its ``TextIOWrapper`` drops the count of every write it passes down.  Nobody checked it:
``plan ... | head -c 100000`` exited 0 with half its stream lost.

:func:`write_all` is the one place where output meets the operating system: it
writes again until every byte is taken, waits on a non-blocking descriptor, lets a
reader that went away raise ``BrokenPipeError`` (exit 141) and turns any other
failure (a full disk, a file too large, an I/O error) into an :class:`OutputError`
that names the output and the system's reason (exit 1).  :class:`OutputFile` is a raw
file that writes through it; :func:`install_stdout` puts ``sys.stdout`` (text and
binary) on one.  This module imports nothing heavy: the command line calls it first.
"""
from __future__ import annotations

import io
import os
import select
import sys

from .errors import OutputError


def write_all(fd: int, data, name: str) -> int:
    """Write every byte of *data* (any buffer) to the file descriptor *fd*; return the count.

    Raises BrokenPipeError when the reader went away and OutputError, naming *name*
    (``stdout`` or the file), for any other failure.
    """
    view = memoryview(data).cast("B")
    total = view.nbytes
    while view:
        try:
            n = os.write(fd, view)
        except BlockingIOError:  # a non-blocking descriptor (a parent may share one): wait until it takes more
            select.select([], [fd], [])
            continue
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise OutputError(f"{name}: cannot write: {exc.strerror or exc}") from None
        if n == 0:
            raise OutputError(f"{name}: cannot write: the output took no bytes")
        view = view[n:]
    return total


class OutputFile(io.FileIO):
    """A raw binary file whose ``write`` takes every byte or raises (see :func:`write_all`).

    *file* is a path or a file descriptor; *name* is how errors name it (``stdout``, the path).
    """

    def __init__(self, file, name: str, closefd: bool = True):
        super().__init__(file, "wb", closefd=closefd)
        self.label = name

    def write(self, data) -> int:
        return write_all(self.fileno(), data, self.label)

    def close(self) -> None:
        try:
            super().close()
        except BrokenPipeError:
            raise
        except OSError as exc:  # a network file system may report a failed write only here
            raise OutputError(f"{self.label}: cannot write: {exc.strerror or exc}") from None


def writes_whole(fh) -> bool:
    """Whether the binary file object *fh* ends in an OutputFile (directly or under a BufferedWriter)."""
    return isinstance(getattr(fh, "raw", fh), OutputFile)


def stdout_binary():
    """A binary file object for stdout whose writes take every byte or raise.

    sys.stdout.buffer itself when it already is one, or is not a real file (an
    in-memory stdout under test); otherwise a BufferedWriter over file descriptor 1,
    after flushing whatever sys.stdout holds.
    """
    buffer = sys.stdout.buffer
    try:
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        return buffer
    if writes_whole(buffer):
        return buffer
    sys.stdout.flush()
    return io.BufferedWriter(OutputFile(fd, "stdout", closefd=False))


def install_stdout() -> None:
    """Put sys.stdout, text and binary, on an OutputFile: every print, echo and stream write takes all its bytes.

    Keeps the encoding, error handler and line buffering Python chose.  Does
    nothing when stdout is not a real file or is installed already.
    """
    old = sys.stdout
    if old is None:
        return
    binary = stdout_binary()
    if binary is getattr(old, "buffer", None):
        return
    sys.stdout = io.TextIOWrapper(binary, encoding=old.encoding, errors=old.errors,
                                  line_buffering=old.line_buffering, write_through=getattr(old, "write_through", False))
