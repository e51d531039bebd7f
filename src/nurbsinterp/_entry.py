"""The console script's entry point: as little as possible between Python's start and our signal handling.

A Ctrl-C while click, numpy or numba are still being imported must end with
exit 130 and one line, never a traceback from inside somebody's import.
"""
import sys


def main() -> None:
    try:
        from .cli import main as run
    except (KeyboardInterrupt, RuntimeError) as exc:
        # inside a class body the interrupt may come wrapped: "Error calling __set_name__"
        if not (isinstance(exc, KeyboardInterrupt) or isinstance(exc.__cause__, KeyboardInterrupt)):
            raise
        sys.stderr.write("nurbsinterp: interrupted\n")
        sys.exit(130)
    run()
