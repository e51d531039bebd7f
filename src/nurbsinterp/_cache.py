"""Where numba keeps the compiled kernels: a directory keyed by the kernels' sources.

numba's own cache checks only the source file of each compiled function, not
the files of the kernels it calls: after an edit of nurbs/kernels.py, a cached kernel
in contour.py would go on running the old geometry.  Keying the whole cache
directory by a hash of every module that compiles a kernel (KERNEL_MODULES:
the modules that import ``njit`` from ``_jit``) makes a change of any of them
compile every kernel afresh, and never mixes kernels of two versions.  An edit
of a reader, the CLI or a summary changes no kernel and compiles nothing: the
tests check that no kernel reads a name from a module outside the list (numba
freezes a global's value into the machine code).  A user's own
NUMBA_CACHE_DIR is respected.

Nothing here imports numba: ``nurbsinterp --version`` and ``--help`` must not
pay for it.  Before numba is imported the directory is handed over in
NUMBA_CACHE_DIR, which numba reads when it starts; if numba is loaded already
(a program that imported it first) its config is set directly.
"""
from __future__ import annotations

import hashlib
import os
import sys
from functools import lru_cache
from pathlib import Path

HERE = Path(__file__).parent
KEEP_OLD = 2  # caches of earlier versions kept beside the current one (another checkout may still run them)


#: the modules whose kernels numba compiles, the one that hands them numba's decorator, and those whose values
#: the kernels read (numba freezes them into the machine code): their sources key the cache
#: (tests/test_kernel_cache.py checks the list against the package)
KERNEL_MODULES = (
    "_jit.py", "bench.py", "contour.py", "interpolate.py", "metrics.py", "precompensate.py",
    "nurbs/__init__.py", "nurbs/kernels.py", "nurbs/arclength.py", "nurbs/projection.py", "nurbs/curve.py",
    "profiles.py", "quantise.py", "servo.py", "simulation.py", "streams.py",
    "planner/feed.py", "planner/jerk.py", "planner/plan.py", "planner/sections.py",
    "planner/limits.py",  # the limits' indices, read by planner/feed.py's kernels
    "config/gcode/fast.py",
    "motion/segments.py", "motion/lookahead.py", "motion/ticks.py", "motion/fit.py", "motion/contour.py",
    "motion/jerk.py", "motion/nurbs_blocks.py",
)


@lru_cache(maxsize=None)
def source_key() -> str:
    """This install's key (:func:`key_of` the package)."""
    return key_of(HERE)


def key_of(package: Path) -> str:
    """A hash of the kernel modules' paths, sizes and modification times: an edit of any of them changes it.

    stat() rather than the bytes: it costs well under a millisecond at every start; a checkout or a copy
    that changes the times only compiles once more.
    """
    digest = hashlib.sha1()
    for name in KERNEL_MODULES:
        try:
            st = (package / name).stat()
        except OSError:  # not installed (a broken install fails later, on import, with Python's own words)
            digest.update(f"{name} -\n".encode())
            continue
        digest.update(f"{name} {st.st_size} {st.st_mtime_ns}\n".encode())
    return digest.hexdigest()[:16]


@lru_cache(maxsize=None)
def _keyed_dir() -> Path:
    key = f"numba-{source_key()}"
    if os.access(HERE, os.W_OK):
        return HERE / "__pycache__" / key
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")  # an installed, read-only package
    return base / "nurbsinterp" / key


_USER_DIR = os.environ.get("NUMBA_CACHE_DIR")  # as the user started us, before we set it ourselves


def cache_dir() -> Path:
    """The directory the kernels are compiled into."""
    return Path(_USER_DIR) if _USER_DIR else _keyed_dir()


def use_source_keyed_cache() -> None:
    if _USER_DIR:
        return
    target = _keyed_dir()
    fresh = not target.exists()
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError:
        pass  # the kernels are compiled in memory (unusable() says why, _jit.njit acts on it)
    if "numba" in sys.modules:
        import numba.core.config as config

        config.CACHE_DIR = str(target)
    else:
        os.environ["NUMBA_CACHE_DIR"] = str(target)
    if fresh:
        _prune(target)


@lru_cache(maxsize=None)
def unusable() -> str | None:
    """Why the kernels cannot be saved in :func:`cache_dir` (it cannot be made, or written: a read-only file
    system, a file in its place), or None when they can -- numba's own test, made once, before any kernel is
    decorated: where it fails numba would save them beside the sources instead, keyed by no version."""
    import tempfile

    target = cache_dir()
    try:
        target.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=target).close()
    except OSError as exc:
        return exc.strerror or str(exc)
    return None


def _warm_marker() -> Path:
    return cache_dir() / f".warm-{source_key()}"


def kernels_warm() -> bool:
    """Whether `nurbsinterp warmup` (or a first run) has compiled every kernel of this version."""
    return _warm_marker().exists()


def mark_warm() -> None:
    try:
        _warm_marker().touch()
    except OSError:
        pass  # a read-only cache: every run compiles what it needs, as numba would anyway


def _prune(current: Path) -> None:
    """Remove caches of other versions (~5 MB each) but the newest KEEP_OLD and any touched in the last hour,
    which a process of that version may still be writing to."""
    import shutil
    import time

    try:
        old = [(d.stat().st_mtime, d) for d in current.parent.glob("numba-*") if d.is_dir() and d != current]
    except OSError:
        return
    old.sort(reverse=True)
    for mtime, d in old[KEEP_OLD:]:
        if mtime < time.time() - 3600:
            shutil.rmtree(d, ignore_errors=True)
