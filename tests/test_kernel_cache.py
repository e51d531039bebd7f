"""The compiled-kernel cache (issue 27, item 9): keyed on what the kernels are compiled from, and never a reason
for a run to fail.

Editing a reader, a summary or the CLI must not recompile the 200 kernels (minutes on 2 cores); editing
any module a kernel is compiled from must.  numba freezes a global's value into a kernel's machine code, so
the key is only sound if no kernel reads a name from a module outside it: checked here on the sources.
"""
from __future__ import annotations

import ast
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from nurbsinterp import _cache

PACKAGE = Path(_cache.__file__).parent
HANG_S = 900  # only a hang catcher: the subprocess compiles a kernel


def _modules():
    return sorted(p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py") if "__pycache__" not in p.parts)


def _imports(rel: str):
    """(module, imported names) of every relative import of package module *rel*, resolved to paths."""
    tree = ast.parse((PACKAGE / rel).read_text())
    here = Path(rel).parent
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.level:
            base = here
            for _ in range(node.level - 1):
                base = base.parent
            target = base.joinpath(*node.module.split(".")) if node.module else base
            for alias in node.names:
                yield target, alias


def _as_module(target: Path, name: str | None = None) -> str | None:
    for cand in ([target / name] if name else []) + [target]:
        if (PACKAGE / f"{cand.as_posix()}.py").exists():
            return f"{cand.as_posix()}.py"
        if (PACKAGE / cand / "__init__.py").exists():
            return f"{cand.as_posix()}/__init__.py"
    return None


def _takers() -> set[str]:
    """The modules that compile kernels: those taking njit from _jit."""
    return {rel for rel in _modules() for target, alias in _imports(rel)
            if alias.name == "njit" and _as_module(target) == "_jit.py"}


def test_the_kernel_modules_are_those_that_take_njit_from_jit():
    takers = _takers()
    assert takers | {"_jit.py"} <= set(_cache.KERNEL_MODULES)
    # the rest hold values the kernels read (test_no_kernel_reads_a_name_from_outside_the_key): none stale
    read = {_as_module(target) for rel in takers for target, _ in _imports(rel)}
    assert set(_cache.KERNEL_MODULES) - takers - {"_jit.py"} <= read
    # and nobody compiles behind the list's back with numba's own decorator
    for rel in _modules():
        if rel == "_jit.py":
            continue
        for node in ast.walk(ast.parse((PACKAGE / rel).read_text())):
            if isinstance(node, ast.ImportFrom) and node.module == "numba":
                assert not {a.name for a in node.names} & {"njit", "jit", "vectorize", "guvectorize", "cfunc"}, rel


def _code_names(code) -> set[str]:
    names = set(code.co_names)
    for const in code.co_consts:
        if hasattr(const, "co_names"):
            names |= _code_names(const)
    return names


@pytest.mark.parametrize("rel", sorted(_takers()))
def test_no_kernel_reads_a_name_from_outside_the_key(rel):
    """Every global a kernel's code names, imported from a module of the package, comes from a kernel module."""
    import importlib

    from numba.core.registry import CPUDispatcher

    outside = {}
    for target, alias in _imports(rel):
        module = _as_module(target, alias.name) if alias.name != "*" else _as_module(target)
        source = _as_module(target)
        # `from . import names` binds a module; `from .config import X` a name of config's
        origin = module if module and module != source else source
        if origin not in _cache.KERNEL_MODULES:
            outside[alias.asname or alias.name] = origin
    mod = importlib.import_module("nurbsinterp." + rel[:-3].replace("/", "."))
    kernels = [v for v in vars(mod).values() if isinstance(v, CPUDispatcher) and v.py_func.__module__ == mod.__name__]
    assert kernels, rel
    def from_outside(name):
        value = getattr(mod, name, None)
        if isinstance(value, CPUDispatcher):  # a kernel, perhaps re-exported by a package's __init__: its own file
            return value.py_func.__module__.replace(".", "/").split("/", 1)[1] + ".py" not in _cache.KERNEL_MODULES
        return True  # a value (frozen into the machine code) or a module from outside the key

    for kernel in kernels:
        read = sorted(n for n in _code_names(kernel.py_func.__code__) & set(outside) if from_outside(n))
        assert not read, f"{rel}: {kernel.py_func.__name__} reads {read} from {[outside[n] for n in read]}"


def test_the_key_changes_with_a_kernel_module_only(tmp_path):
    copy = tmp_path / "nurbsinterp"
    shutil.copytree(PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    key = _cache.key_of(copy)
    for rel in ("cli/plan.py", "config/gcode/machine.py", "describe.py", "errors.py"):
        (copy / rel).write_text((copy / rel).read_text() + "\n# an edit\n")
        assert _cache.key_of(copy) == key, rel
    for rel in ("nurbs/kernels.py", "nurbs/curve.py", "planner/jerk.py", "_jit.py"):
        (copy / rel).write_text((copy / rel).read_text() + "\n# an edit\n")
        assert _cache.key_of(copy) != key, rel
        key = _cache.key_of(copy)


def test_a_cache_that_cannot_be_saved_does_not_fail_the_run(tmp_path):
    """A full disk under a cold cache: numba's save raises ENOSPC; the kernel runs and one line says why
    the next run compiles again."""
    script = textwrap.dedent("""
        import errno, numpy as np
        from numba.core import caching

        def full(self, *args, **kwargs):
            raise OSError(errno.ENOSPC, "No space left on device")

        caching.IndexDataCacheFile.save = full
        from nurbsinterp.nurbs import find_span
        U = np.array([0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0])
        print(find_span(U, 3, 2, 0.7), find_span(U, 3, 2, 0.2))
    """)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=HANG_S,
                         stdin=subprocess.DEVNULL)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["3", "2"]
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and "cannot be saved" in lines[0] and "No space left on device" in lines[0], lines


@pytest.mark.parametrize("where", ["a file", "under a file"])
def test_a_cache_directory_that_cannot_be_written_compiles_in_memory(tmp_path, where):
    """A cache directory that cannot be made or written (here a file stands where it would be: the same
    refusal as a read-only file system, for root too): the kernels run, compiled in memory, one line says so
    once, and nothing is saved beside the sources (where numba falls back to, keyed by no version)."""
    blocker = tmp_path / "blocker"
    blocker.write_text("not a directory\n")
    target = blocker if where == "a file" else blocker / "cache"
    script = textwrap.dedent("""
        import numpy as np
        from nurbsinterp.nurbs import find_span, make_work
        U = np.array([0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0])
        print(find_span(U, 3, 2, 0.7), find_span(U, 3, 2, 0.2), make_work(2, 1, 3)[0].shape[0] > 0)
        print(find_span._cache.__class__.__name__)
    """)
    def beside_sources():  # numba's in-tree fallback (not our keyed cache, numba-KEY, which other tests may fill)
        return {p for p in PACKAGE.rglob("*.nbi") if not any(part.startswith("numba-") for part in p.parts)}

    before = beside_sources()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(target))
    res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, timeout=HANG_S,
                         stdin=subprocess.DEVNULL)
    assert res.returncode == 0, res.stderr
    assert res.stdout.split() == ["3", "2", "True", "NullCache"]
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and "cannot be saved in" in lines[0] and str(target) in lines[0], lines
    assert "in memory" in lines[0] and "NUMBA_CACHE_DIR" in lines[0], lines
    assert beside_sources() == before
