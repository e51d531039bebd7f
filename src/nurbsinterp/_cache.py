"""Where numba keeps the compiled kernels: a directory keyed by the package's source.

numba's own cache checks only the source file of each compiled function, not
the files of the kernels it calls: after an edit of nurbs.py, a cached kernel
in metrics.py would go on running the old geometry.  Keying the whole cache
directory by a hash of every module of the package makes any change compile
everything afresh, and never mixes kernels of two versions.  A user's own
NUMBA_CACHE_DIR is respected.
"""
from __future__ import annotations

import hashlib
import os
from pathlib import Path


def source_key() -> str:
    digest = hashlib.sha1()
    for path in sorted(Path(__file__).parent.rglob("*.py")):
        digest.update(path.name.encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def use_source_keyed_cache() -> None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return
    import numba.core.config as config

    here = Path(__file__).parent
    key = f"numba-{source_key()}"
    if os.access(here, os.W_OK):
        target = here / "__pycache__" / key
    else:  # an installed, read-only package: the user's cache directory
        base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
        target = base / "nurbsinterp" / key
    fresh = not target.exists()
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError:
        return  # numba falls back to its own default
    config.CACHE_DIR = str(target)
    if fresh:
        _prune(target)


KEEP_OLD = 2  # caches of earlier versions kept beside the current one (another checkout may still run them)


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
