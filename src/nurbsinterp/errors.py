"""The exception hierarchy.  The CLI maps each class to an exit status.

``SpecError`` and ``StreamError`` are bad input (exit 2); any other
``NurbsInterpError`` is a runtime failure that validation could not foresee
(exit 1), ``OutputError`` among them.
"""
import contextlib
import sys


class NurbsInterpError(Exception):
    """Base class of every error nurbsinterp raises on purpose."""

    exit_code = 1


class SpecError(NurbsInterpError, ValueError):
    """A job, profile or servo file (or a command-line override) breaks a rule."""

    exit_code = 2


class CuspError(SpecError):
    """The curve's parametric speed vanishes inside a knot span where it turns back (a cusp).

    *u* and *point* say where, *angle* (degrees) how far the tangent turns there: a caller
    that knows the curve as blocks of a path names the block and its own parameter instead."""

    def __init__(self, message: str, u: float, point, angle: float):
        super().__init__(message)
        self.u, self.point, self.angle = u, point, angle


class StreamError(NurbsInterpError, ValueError):
    """A command stream (CSV or binary) is malformed."""

    exit_code = 2


class UsageError(NurbsInterpError, ValueError):
    """A request that cannot be honoured (an output path that must not be written)."""

    exit_code = 2


class OutputPathError(UsageError):
    """An output path that cannot or must not be written, refused before any work.

    The message is ``<path>: <problem>``.  The parts are kept for a caller that
    names the path its own way (the command line, by its option): *name* is the
    path as the message shows it, *problem* what is wrong with it and *kind* a
    tag for it (``empty``, ``input``, ``directory``, ``no-directory``,
    ``not-writable``, ``cannot-create``, ``cannot-replace``).
    """

    def __init__(self, name: str, problem: str, kind: str):
        super().__init__(f"{name}: {problem}")
        self.name, self.problem, self.kind = name, problem, kind


class OutputError(NurbsInterpError):
    """Writing the output failed: a full disk, a file size limit, an I/O error (exit 1).

    The message names the output (``stdout``, its path or the caller's label for it) and the system's reason.
    A reader that went away is not one: that is BrokenPipeError, exit 141.
    """

    exit_code = 1


@contextlib.contextmanager
def located(source: str):
    """Prefix *source* (the job file) to a SpecError raised inside that does not name it yet.

    The deeper layers (arc length, the adaptive planner) know the field, not the file.
    """
    try:
        yield
    except SpecError as exc:
        if str(exc).startswith(f"{source}:"):
            raise
        raise SpecError(f"{source}: {exc}") from None


def silence_asyncio() -> None:
    """asyncio's logger silent for the rest of the run, once an interrupt or a termination has cut an event loop
    short (a Dask client's, which runs in a thread of its own): what the signal cut short there (a gather's wait,
    AllExit) is collected -- while the client closes, or later, as the interrupt's traceback lets go of its frames
    -- and would be logged as "Task exception was never retrieved" with its traceback.  The run ends and its
    caller says so in its own words.  (Called from a signal handler too: it imports nothing.)"""
    if "asyncio" in sys.modules:
        logging = sys.modules["logging"]
        logging.getLogger("asyncio").setLevel(logging.CRITICAL + 1)
