"""The command line: parse, load, call the library, write.  No mathematics here.

One module per subcommand, imported only when that subcommand runs (or
``--help`` lists them): a subcommand module imports click alone at its top and
the library inside its function, so ``--version`` and ``--help`` start without
numpy or numba, and each subcommand loads only what it uses.  Errors reach the
user as one line on stderr; the exit status says what kind of failure it was:
0 success, 2 bad input or usage, 1 runtime failure, 130 interrupted (SIGINT),
143 terminated (SIGTERM), 141 (SIGPIPE) when the reader of stdout went away.
"""
from __future__ import annotations

import os
import signal
import sys

import click

from .._version import __version__
from ..errors import NurbsInterpError, OutputError, silence_asyncio
from ..output import install_stdout
from .common import say_notes

SUBCOMMANDS = ("info", "plan", "precompensate", "simulate", "identify", "compare", "sweep", "convert", "bench",
               "warmup")  # in the order --help lists them


class LazyGroup(click.Group):
    """A group whose subcommands are imported when they are asked for, not at start-up."""

    def list_commands(self, ctx):
        return list(SUBCOMMANDS)

    def get_command(self, ctx, name):
        if name not in SUBCOMMANDS:
            return None
        import importlib

        module = importlib.import_module(f"{__name__}.{name}")
        return getattr(module, name)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, "--version", prog_name="nurbsinterp")
@click.option("--debug", is_flag=True, help="Show the full traceback of any error.")
def cli(debug):
    """Real-time variable-feedrate NURBS interpolator for CNC motion.

    \b
    nurbsinterp info curves/circle.yaml
    nurbsinterp plan curves/circle.yaml | head
    """



def _quiet_stdout() -> None:
    """After the reader of stdout went away: point stdout at /dev/null so exit flushes nothing."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


class Terminated(BaseException):
    """SIGTERM, raised like KeyboardInterrupt so that every `finally` and cleanup runs."""


_pending = None  # the exception of a signal that main() has not caught yet


def _on_signal(signum, frame):
    """SIGINT raises KeyboardInterrupt, SIGTERM Terminated, so that every `finally` and cleanup runs.

    numba loads and compiles kernels partly through C code that calls back into Python (llvmlite's
    object cache, the dispatcher's type checks); an exception raised there is printed as "Exception
    ignored" and dropped, and the interrupt would be lost.  So it is raised again every second until
    main() has caught it.
    """
    global _pending
    _pending = KeyboardInterrupt if signum == signal.SIGINT else Terminated
    signal.setitimer(signal.ITIMER_REAL, 1.0, 1.0)
    silence_asyncio()  # from the moment the run ends, not once it is reported: the loop's thread runs on
    raise _pending()


def _on_alarm(signum, frame):
    if _pending is not None:
        raise _pending()


_signalled = False  # the run ends because of a signal


def _caught() -> None:
    global _pending, _signalled
    _pending = None
    _signalled = True
    signal.setitimer(signal.ITIMER_REAL, 0)
    if "asyncio" in sys.modules:
        # what the signal cut short in an event loop (a Dask client and cluster starting) logs "Task exception
        # was never retrieved" and its traceback as it is collected: the run has ended, and says so in one line
        import logging

        logging.disable(logging.CRITICAL)


def _excepthook(exc_type, exc, tb, _default=sys.excepthook):
    """An extension module whose import an interrupt cuts short prints it with PyErr_Print (numpy's
    import_array does, then raises "failed to import"), which calls this hook: the run ends with its one
    line "interrupted" below, so say nothing here."""
    if _pending is not None and issubclass(exc_type, (KeyboardInterrupt, Terminated)):
        return
    _default(exc_type, exc, tb)


def take_signals() -> None:
    """The process's signal handling and last-resort hooks, installed before anything else runs."""
    # a shell starts background jobs with SIGINT ignored; Ctrl-C / kill -INT must still clean up
    signal.signal(signal.SIGINT, _on_signal)
    signal.signal(signal.SIGTERM, _on_signal)
    signal.signal(signal.SIGALRM, _on_alarm)
    sys.unraisablehook = _unraisable
    sys.excepthook = _excepthook
    # a file size limit (RLIMIT_FSIZE) must fail the write with EFBIG, reported as exit 1, not kill the process
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def _unraisable(args, _default=sys.unraisablehook):
    """A dropped interrupt is raised again by the alarm (above): say nothing of it here.  Nor, once a signal
    ends the run, of what the objects it cut short (llvmlite's, half built) raise as they are collected."""
    if _signalled or (args.exc_type is not None and issubclass(args.exc_type, (KeyboardInterrupt, Terminated))):
        return
    _default(args)


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else list(argv)
    if argv is None:  # the real process, not a test calling main() in-process
        take_signals()
        install_stdout()  # every write to stdout, text or binary, takes all its bytes or raises
    # --debug is an option of the group: it counts only before the subcommand
    first_word = next((i for i, a in enumerate(args) if not a.startswith("-")), len(args))
    debug = "--debug" in args[:first_word]
    try:
        # not cli.main(): click turns a broken pipe into exit 1 there; we want 141, quietly
        with cli.make_context("nurbsinterp", args) as ctx:
            cli.invoke(ctx)
        say_notes(ctx)
        code = 0
    except click.exceptions.Exit as exc:
        code = exc.exit_code
    except click.exceptions.NoArgsIsHelpError as exc:
        click.echo(exc.ctx.get_help(), err=True)
        code = exc.exit_code
    except click.ClickException as exc:
        if debug:
            raise
        where = f"nurbsinterp {exc.ctx.command.name}" if getattr(exc, "ctx", None) and exc.ctx.parent else "nurbsinterp"
        hint = " (see --help)" if isinstance(exc, click.UsageError) else ""
        click.echo(f"{where}: {' '.join(exc.format_message().split())}{hint}", err=True)
        code = exc.exit_code
    except NurbsInterpError as exc:
        if debug:
            raise
        click.echo(f"nurbsinterp: {' '.join(str(exc).split())}", err=True)
        code = exc.exit_code
    except BrokenPipeError:
        _quiet_stdout()
        code = 141
    except (KeyboardInterrupt, click.exceptions.Abort):
        _caught()
        click.echo("nurbsinterp: interrupted", err=True)
        code = 130
    except Terminated:
        _caught()
        click.echo("nurbsinterp: terminated", err=True)
        code = 143
    except Exception as exc:  # noqa: BLE001 - the last line of defence
        if _pending is not None:  # an interrupt that numba's compiler turned into an error of its own
            signal_name, code = ("interrupted", 130) if _pending is KeyboardInterrupt else ("terminated", 143)
            _caught()
            click.echo(f"nurbsinterp: {signal_name}", err=True)
            sys.exit(code)
        if debug:
            raise
        click.echo(f"nurbsinterp: internal error: {type(exc).__name__}: {' '.join(str(exc).split())} "
                   "(run with --debug for the traceback)", err=True)
        code = 1
    if "nurbsinterp.cli.report" in sys.modules:  # what the run compiled, said after its result (or not at all)
        sys.modules["nurbsinterp.cli.report"].COMPILES.finish(ok=code == 0)
    if argv is None:
        # the run has its result: a signal from now on can change nothing but the exit status, and
        # raised during the interpreter's exit it would end the process by the signal after all
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        signal.setitimer(signal.ITIMER_REAL, 0)
        if _pending is not None:  # a signal that numba swallowed, not yet raised again by the alarm
            signal_name, code = ("interrupted", 130) if _pending is KeyboardInterrupt else ("terminated", 143)
            _caught()
            click.echo(f"nurbsinterp: {signal_name}", err=True)
    try:
        sys.stdout.flush()
    except (BrokenPipeError, ValueError):
        _quiet_stdout()
        code = code or 141
    except OutputError as exc:  # the last bytes of stdout did not fit (a full disk, a size limit)
        if not code:
            click.echo(f"nurbsinterp: {exc}", err=True)
        _quiet_stdout()  # what is still buffered goes nowhere at exit, and says nothing more
        code = code or exc.exit_code
    sys.exit(code)
