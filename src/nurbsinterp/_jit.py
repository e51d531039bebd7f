"""numba's ``njit`` for the package's kernels, with a cache that may fail to save without failing the run.

Every module that compiles a kernel imports ``njit`` from here, never from
numba: that names the kernel modules (``_cache.KERNEL_MODULES``, whose sources
key the cache directory, is checked against them by the tests), and it
installs, before the first compilation, the one change to numba's caching we
need.  numba saves a compiled kernel right after compiling it and lets an
``OSError`` of the save (a full disk, a read-only or vanished cache directory)
escape from the call that compiled it: the user's job would fail for want of
a cache that only saves time.  Here a failed save is said once on stderr and
the kernel runs from memory; the next run compiles it again.  A cache directory
that cannot be written at all (a read-only file system, a file in its place)
is found before the first kernel is decorated: the kernels are then compiled
in memory, said once, rather than saved beside the sources, where numba would
fall back to and where no version keys them.

And one change to how a kernel is typed where another kernel calls it.  numba
types a constant argument as a literal (``norm_row(CK, 1)`` is typed
``Literal[int](1)``, not ``int64``) and compiles the callee once for each
constant it meets: a fifth of the first run's compilations were such copies
(``_put_arc`` four times for its kinds, ``_window_end`` four times for two
flags).  Our kernels never ask for a literal (no ``numba.literally``), so a
kernel of the package is typed on its arguments' plain types: one
specialisation serves every constant, and the machine code computes the same
numbers (a constant folded or passed gives the same IEEE result).
"""
from __future__ import annotations

import sys

from numba import njit as _numba_njit
from numba.core import caching, dispatcher, types

from ._cache import cache_dir, unusable

_told = []  # the first message of a cache that cannot be used, once said


def njit(*args, **options):
    """numba's ``njit``, the decorator of every kernel; ``cache=True`` where the cache directory can be written,
    else compiled in memory on every run, said once (a read-only or full file system never fails a run)."""
    if options.get("cache") and unusable() is not None:
        options["cache"] = False
        _say(f"nurbsinterp: the compiled kernels cannot be saved in {cache_dir()} ({unusable()}): each run "
             "compiles the kernels it calls in memory (set NUMBA_CACHE_DIR to a writable directory)\n")
    return _numba_njit(*args, **options)


def _say(message: str) -> None:
    if not _told:
        # stderr directly: a process-wide condition of the install, like numba's own warnings, that the
        # command running (whichever it is) cannot word better; the run's result is unaffected
        _told.append(message)
        sys.stderr.write(message)


_save = caching.Cache.save_overload


def _save_or_say(self, sig, data):
    try:
        _save(self, sig, data)
    except OSError as exc:
        _say(f"nurbsinterp: the compiled kernels cannot be saved in {self._cache_path} "
             f"({exc.strerror or exc}): they are compiled again on every run until it can\n")


if getattr(caching.Cache.save_overload, "__name__", "") != "_save_or_say":
    caching.Cache.save_overload = _save_or_say


_call_template = dispatcher.Dispatcher.get_call_template


def _plain_call_template(self, args, kws):
    """A call from a kernel to a kernel of this package typed on its arguments' plain (non-literal) types."""
    if getattr(self.py_func, "__module__", "").startswith("nurbsinterp."):
        args = tuple(types.unliteral(a) for a in args)
        kws = {k: types.unliteral(v) for k, v in kws.items()}
    return _call_template(self, args, kws)


if getattr(dispatcher.Dispatcher.get_call_template, "__name__", "") != "_plain_call_template":
    dispatcher.Dispatcher.get_call_template = _plain_call_template
