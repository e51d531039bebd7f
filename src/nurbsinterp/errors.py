"""The exception hierarchy.  The CLI maps each class to an exit status.

``SpecError`` and ``StreamError`` are bad input (exit 2); any other
``NurbsInterpError`` is a runtime failure that validation could not foresee
(exit 1), ``OutputError`` among them.
"""
import contextlib


class NurbsInterpError(Exception):
    """Base class of every error nurbsinterp raises on purpose."""

    exit_code = 1


class SpecError(NurbsInterpError, ValueError):
    """A job, profile or servo file (or a command-line override) breaks a rule."""

    exit_code = 2


class StreamError(NurbsInterpError, ValueError):
    """A command stream (CSV or binary) is malformed."""

    exit_code = 2


class UsageError(NurbsInterpError, ValueError):
    """A command-line option that cannot be honoured (an output path that must not be written)."""

    exit_code = 2


class OutputError(NurbsInterpError):
    """Writing the output failed: a full disk, a file size limit, an I/O error (exit 1).

    The message names the output (``stdout`` or ``-o FILE``) and the system's reason.
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
