"""numba's ``njit`` for the package's kernels, with a cache that may fail to save without failing the run.

Every module that compiles a kernel imports ``njit`` from here, never from
numba: that names the kernel modules (``_cache.KERNEL_MODULES``, whose sources
key the cache directory, is checked against them by the tests), and it
installs, before the first compilation, the one change to numba's caching we
need.  numba saves a compiled kernel right after compiling it and lets an
``OSError`` of the save (a full disk, a read-only or vanished cache directory)
escape from the call that compiled it: the user's job would fail for want of
a cache that only saves time.  Here a failed save is said once on stderr and
the kernel runs from memory; the next run compiles it again.
"""
from __future__ import annotations

import sys

from numba import njit  # noqa: F401  (re-exported: the decorator of every kernel)
from numba.core import caching

_save = caching.Cache.save_overload
_told = []  # the first failed save's message, once said


def _save_or_say(self, sig, data):
    try:
        _save(self, sig, data)
    except OSError as exc:
        if not _told:
            # stderr directly: a process-wide condition of the install, like numba's own warnings, that the
            # command running (whichever it is) cannot word better; the run's result is unaffected
            _told.append(f"nurbsinterp: the compiled kernels cannot be saved in {self._cache_path} "
                         f"({exc.strerror or exc}): they are compiled again on every run until it can\n")
            sys.stderr.write(_told[0])


if getattr(caching.Cache.save_overload, "__name__", "") != "_save_or_say":
    caching.Cache.save_overload = _save_or_say
