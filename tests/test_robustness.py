"""Robustness battery (issue 6): the error contract, fuzzed inputs, resource bounds,
numerical edge cases, pipes, signals and files.

The contract (README): exit 0 success; 2 bad input or usage; 1 runtime failure; 130 SIGINT;
143 SIGTERM; 141 when stdout's reader went away.  An error is ONE line on stderr that names the
file (or option), the field or record and the value; no traceback without --debug; stdout
carries nothing but data, and nothing at all when the run fails.

How it is driven
    * Fuzzing runs IN-PROCESS through ``nurbsinterp.cli.main([...])`` (see :func:`invoke`), so
      hundreds of examples take seconds.  Python warnings are recorded and count as stderr lines
      (the real process prints them).  Two guards keep a bug from taking the suite down: the
      address space may grow by at most 4 GiB per call (MemoryError, not the OOM killer), and a
      ``faulthandler`` watchdog aborts a call that hangs for WATCHDOG_S, after writing what it ran
      to ``$TMPDIR/nurbsinterp-robustness-watchdog.log`` (and the stack to ``.trace``).
    * Pipes, signals and the shell pipe run the installed executable in subprocesses;
      inputs that hang or blow the memory up run there too, as many at once as the machine has
      cores, each capped at 1 GiB of address space and CAPPED_CPU_S of CPU time.
    * No test depends on the clock: the wall-clock limits (WATCHDOG_S, HANG_S) only catch a hang,
      and are generous enough for a cold kernel compile on a busy 2-core machine.
    * Each fuzzer runs a quarter of its examples in the quick set and all of them in the slow set
      (``pytest -m slow``, which CI runs too): see tests/budgets.py.
    * ``NURBSINTERP_FUZZ_SCALE=10`` multiplies the number of examples (both budgets) for a deeper hunt.

Fuzzed magnitudes are bounded (finite numbers with 1e-9 <= |x| <= 1e12, weights within 1e-3..1e3,
plan writing binary, at most FUZZ_MAX_TICKS ticks); beyond those bounds the scale rules of the job
file refuse the input, and the tests of section 3 and the extreme-geometry tests pin that.
"""
from __future__ import annotations

import copy
import contextlib
import dataclasses
import faulthandler
import io
import json
import math
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from nurbsinterp.cli import main
from nurbsinterp.errors import NurbsInterpError
from nurbsinterp.config import load_job
from budgets import budgets
from clirun import without_end_mark

ROOT = Path(__file__).resolve().parents[1]
CURVES = ROOT / "curves"
CIRCLE = CURVES / "circle.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")

WATCHDOG_S = 1800  # a hang catcher for one in-process call (the first one may compile the kernels), not a speed test
HANG_S = 900  # likewise for one subprocess
WATCHDOG_LOG = Path(tempfile.gettempdir()) / "nurbsinterp-robustness-watchdog.log"
FUZZ_MAX_TICKS = "20000"
SHOWN_WARNINGS = (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning)

#: NURBSINTERP_FUZZ_SCALE=10 runs ten times as many examples (a deeper hunt; the default keeps the file fast), in
#: the quick set's budgets and in the slow set's
FUZZ_SCALE = float(os.environ.get("NURBSINTERP_FUZZ_SCALE", "1"))


def examples(n: int) -> int:
    return max(1, int(n * FUZZ_SCALE))


FUZZ = settings(max_examples=examples(100), deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.filter_too_much, HealthCheck.large_base_example])


# =========================================================================== harness


@dataclasses.dataclass
class Result:
    code: int
    out: bytes
    err: str
    warnings: list

    def __str__(self):
        return f"exit {self.code}; stderr {self.err!r}; warnings {self.warnings}; stdout {self.out[:120]!r}"


def invoke(*args, stdin: bytes = b"", note: str = "") -> Result:
    """``main([...])`` in-process: stdout (bytes, text and binary), stderr, warnings, exit status.

    stdin is an in-memory stream (empty by default, as ``</dev/null`` in a script).
    """
    argv = [str(a) for a in args]
    WATCHDOG_LOG.write_text(f"nurbsinterp {argv}\n{note}\n")
    raw = io.BytesIO()
    out = io.TextIOWrapper(raw, encoding="utf-8", write_through=True)
    err = io.StringIO()
    saved = sys.stdout, sys.stderr, sys.stdin
    sys.stdout, sys.stderr = out, err
    sys.stdin = io.TextIOWrapper(io.BufferedReader(io.BytesIO(stdin)))
    code = None
    faulthandler.dump_traceback_later(WATCHDOG_S, exit=True, file=_watchdog_file())
    try:
        with _memory_guard(), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                main(argv)
            except SystemExit as exc:
                code = exc.code
    finally:
        faulthandler.cancel_dump_traceback_later()
        sys.stdout, sys.stderr, sys.stdin = saved
    assert code is not None, "main() returned instead of exiting"
    out.flush()
    shown = [f"{w.category.__name__}: {w.message}" for w in caught if not issubclass(w.category, SHOWN_WARNINGS)]
    return Result(code if isinstance(code, int) else (0 if code is None else 1), raw.getvalue(), err.getvalue(), shown)


GUARD_BYTES = 4 << 30  # address space an in-process call may add before it gets a MemoryError


@contextlib.contextmanager
def _memory_guard():
    """Cap this process's address space at its current size + GUARD_BYTES during one call, so that an
    unbounded allocation ends in MemoryError (exit 1: a failed property) instead of the OOM killer."""
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        with open("/proc/self/statm") as fh:
            size = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        cap = size + GUARD_BYTES
        if hard != resource.RLIM_INFINITY:
            cap = min(cap, hard)
        if soft != resource.RLIM_INFINITY and soft <= cap:
            raise ValueError("already capped")
        resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    except (ImportError, OSError, ValueError):
        yield  # not Linux, or capped already: run unguarded
        return
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


_WATCHDOG_FH = None


def _watchdog_file():
    """Where faulthandler writes the stack of a hung call (kept open: it writes from a C thread)."""
    global _WATCHDOG_FH
    if _WATCHDOG_FH is None:
        import atexit

        _WATCHDOG_FH = open(WATCHDOG_LOG.with_suffix(".trace"), "w")  # noqa: SIM115 - closed at exit
        atexit.register(_WATCHDOG_FH.close)
    return _WATCHDOG_FH


def assert_error(res: Result, *parts, status: int = 2, named=()) -> str:
    """The error contract: status, one line on stderr starting 'nurbsinterp', nothing on stdout."""
    assert res.code == status, str(res)
    assert res.out == b"", f"stdout is not empty on error: {res}"
    assert "Traceback" not in res.err, str(res)
    assert "internal error" not in res.err, str(res)
    assert res.err.endswith("\n") and res.err.count("\n") == 1, f"stderr is not one line: {res}"
    assert res.err.startswith("nurbsinterp"), str(res)
    assert not res.warnings, f"warnings would add lines to stderr: {res}"
    for part in parts:
        assert str(part) in res.err, f"{part!r} not in {res.err!r}"
    if named:
        assert any(str(n) in res.err for n in named), f"the message names none of {named}: {res.err!r}"
    return res.err


def assert_0_or_2(res: Result, named=()):
    """A fuzzed run: exit 2 under the error contract, or 0 (the caller checks the output).  True on 0."""
    with contextlib.suppress(Exception):  # outside a hypothesis test there is nothing to record
        event(f"exit {res.code}")
    assert res.code in (0, 2), f"bad input must be exit 2 (or 0 if valid): {res}"
    if res.code == 2:
        assert_error(res, named=named)
        return False
    return True


def parse_bin(out: bytes):
    head, nl, body = without_end_mark(out).partition(b"\n")
    assert nl, "no header line"
    parts = head.decode("ascii").split()
    assert parts[:2] == ["nurbsinterp-bin", "2"] and len(parts) >= 3, head
    assert all("=" in field for field in parts[3:]), head  # key=value fields (the curve's fingerprint)
    cols = parts[2].split(",")
    assert len(body) % (8 * len(cols)) == 0, "the body is not whole records"
    return cols, np.frombuffer(body, "<f8").reshape(-1, len(cols))


def parse_csv(out: bytes):
    lines = without_end_mark(out).decode("ascii").splitlines()
    cols = lines[0].split(",")
    data = np.array([[float(f) for f in line.split(",")] for line in lines[1:]], dtype=float).reshape(-1, len(cols))
    return cols, data


def check_plan_output(out: bytes, job_path, fmt: str = "bin"):
    """A successful plan's stream is sane: header, finite, k/t/u consistent, ends on the curve's ends."""
    cols, data = parse_bin(out) if fmt == "bin" else parse_csv(out)
    job = load_job(job_path)
    curve = job.curve
    dim = curve.control_points.shape[1]
    assert cols == ["k", "n", "t", "u", *"xyz"[:dim], "v", "a"]
    assert data.shape[0] >= 2
    assert (data[:, 1] == 0).all()  # one curve: one block
    data = np.delete(data, 1, axis=1)
    assert np.isfinite(data).all(), "non-finite value in the stream"
    k, t, u = data[:, 0], data[:, 1], data[:, 2]
    assert np.array_equal(k, np.arange(data.shape[0]))
    assert np.all(np.diff(t) > 0)
    period = t[1]
    assert np.allclose(t, k * period, rtol=1e-12, atol=1e-9 if fmt == "csv" else 0)
    p = curve.degree
    a, b = curve.knots[p], curve.knots[-p - 1]
    ulp = 1e-15 * max(1.0, abs(a), abs(b)) if fmt == "csv" else 0.0
    assert np.all(np.diff(u) >= -ulp), "u goes backwards"
    assert u[0] >= a - ulp and u[-1] <= b + ulp
    pts = data[:, 3:3 + dim]
    cps = curve.control_points
    scale = max(1.0, float(np.abs(cps).max()))
    tol = (5e-10 if fmt == "csv" else 1e-12) * scale
    assert np.allclose(pts[-1], cps[-1], rtol=0, atol=tol), (pts[-1], cps[-1])  # last row: the end point
    assert np.allclose(pts[0], cps[0], rtol=0, atol=tol), (pts[0], cps[0])
    # positive weights: the curve (and any average of its points) lies in the control points' hull
    lo, hi = cps.min(axis=0), cps.max(axis=0)
    slack = 1e-9 * scale + 1e-12 * (hi - lo)
    assert np.all(pts >= lo - slack) and np.all(pts <= hi + slack), "a command outside the control points' box"
    v = data[:, -2]
    assert np.all(v >= -1e-9 * max(1.0, float(np.abs(v).max())))
    return cols, data


def all_finite_json(obj, allow_null=()) -> None:
    def walk(x, key=""):
        if isinstance(x, dict):
            for k2, v in x.items():
                walk(v, k2)
        elif isinstance(x, list):
            for v in x:
                walk(v, key)
        elif x is None:
            assert key in allow_null, f"{key} is null (a non-finite number)"
        elif isinstance(x, float):
            assert math.isfinite(x), key
    walk(obj)


def check_info_json(out: bytes):
    facts = json.loads(out)
    all_finite_json(facts, allow_null=("min_radius", "accel_bound"))  # None: straight; no acceleration bound
    assert facts["length"] >= 0 and facts["ticks"] >= 2 and facts["motion_time"] >= 0
    lo, hi = np.array(facts["bounding_box"]["min"]), np.array(facts["bounding_box"]["max"])
    assert np.all(lo <= hi)
    return facts


def check_simulate_json(out: bytes):
    rep = json.loads(out)
    all_finite_json(rep)
    assert rep["contour_error_max"] >= 0 and rep["ticks"] >= 2
    return rep


# --------------------------------------------------------------------------- a YAML writer for fuzzing


class Raw(str):
    """A YAML token written verbatim: .nan, -.Inf, !!binary ..., &a, *a."""


class Pairs(list):
    """A mapping written as (key, value) pairs, so that a key may appear twice."""


def emit(value) -> str:
    """Flow-style YAML for *value*; Raw tokens verbatim; NaN and inf in YAML's own spelling."""
    if isinstance(value, Raw):
        return str(value)
    if isinstance(value, (dict, Pairs)):
        items = value.items() if isinstance(value, dict) else value
        return "{" + ", ".join(f"{emit(k)}: {emit(v)}" for k, v in items) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(emit(v) for v in value) + "]"
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return ".nan"
        if math.isinf(value):
            return ".inf" if value > 0 else "-.inf"
        return repr(value)
    return json.dumps(value)  # a double-quoted YAML string


def block(doc: dict) -> str:
    """Top-level sections in block style (as the bundled files are), each section a flow mapping."""
    return "".join(f"{emit(k)}: {emit(v)}\n" for k, v in doc.items())


# --------------------------------------------------------------------------- value strategies

NON_FINITE = [Raw(".nan"), Raw(".NaN"), Raw(".NAN"), Raw(".inf"), Raw(".Inf"), Raw("-.Inf"), Raw("+.INF"), Raw("-.inf"),
              "nan", "NaN", "inf", "-inf", "Infinity", Raw("1e999"), Raw("-1.0e+999"), "1e999", "1e999 mm/s",
              "nan ms", "inf s", 10 ** 400, -(10 ** 400)]
YAML_ODDITIES = [Raw("~"), Raw("null"), Raw("yes"), Raw("No"), Raw("on"), Raw("0x1F"), Raw("0o17"), Raw("017"),
                 Raw("0b101"), Raw("1_000"), Raw("1:30"), Raw("!!binary aGVsbG8="), Raw("2001-12-14"),
                 Raw("2001-12-14t21:59:43.10-05:00"), Raw("!!set {a, b}"), Raw("!!omap [a: 1]"), Raw("!!str 5"),
                 Raw("!!int '7'"), Raw("!!float '1e3'"), Raw("!!python/object/apply:os.system ['true']"),
                 Raw("!!python/name:os.system"), Raw("&anchor 5"), Raw("*anchor"), Raw("!!null ''"), Raw("!custom 1"),
                 Raw("'1e-3'"), Raw('""'), Raw("{}"), Raw("[]"), Raw("[[]]"), Raw("{? [1]: 2}"), Raw("!!float .nan"),
                 Raw("|\n  text"), Raw("'\u2028'"), Raw("\"\\ud83d\""), Raw("\"a\\nb\"")]
UNITS = ["", "s", "ms", "us", "µs", "μs", "ns", "min", "mm/s", "mm/min", "m/min", "in/min", "um/s", "nm/s", "cm/s",
         "m/s", "mm", "um", "mm/s^2", "mm/s2", "m/s²", "kg", "furlongs/fortnight", "mm/h", "s/mm", "m/s/s", "MM/S",
         "mm / s", "ms ms", "%", "1/s"]

SAFE_FLOATS = st.one_of(
    st.floats(min_value=1e-9, max_value=1e12),
    st.floats(min_value=-1e12, max_value=-1e-9),
    st.sampled_from([0.0, -0.0, 1.0, 0.5, 1e-6, 100.0, 1e6]),
)
SAFE_INTS = st.integers(min_value=-10 ** 12, max_value=10 ** 12)
QUANTITY = st.builds(lambda x, unit, sep: f"{x:g}{sep}{unit}", st.floats(min_value=1e-6, max_value=1e6) | st.floats(
    min_value=-1e6, max_value=-1e-6), st.sampled_from(UNITS), st.sampled_from([" ", "", "  "]))
TEXT = st.text(max_size=12) | st.sampled_from(["fast", "", " ", "abc", "1,5", "1.5.5", "--1", "0x10", "e5", "5e",
                                                "trapezoidal", "taylor2", "before", "curve"])
SCALAR = st.one_of(SAFE_FLOATS, SAFE_INTS, st.booleans(), st.none(), TEXT, QUANTITY,
                   st.sampled_from(NON_FINITE), st.sampled_from(YAML_ODDITIES))
ANY_VALUE = st.one_of(
    SCALAR, SCALAR,
    st.lists(SCALAR, max_size=4),
    st.lists(st.lists(SAFE_FLOATS | st.sampled_from(NON_FINITE), max_size=5), max_size=4),
    st.dictionaries(st.text(max_size=6) | st.sampled_from(["degree", "x", "num"]), SCALAR, max_size=3),
)
WEIGHT_VALUES = st.one_of(st.floats(min_value=1e-3, max_value=1e3), st.sampled_from([0, 0.0, -1, -1e-9, -0.0]),
                          st.sampled_from(NON_FINITE), TEXT, st.none(), st.booleans(), st.sampled_from(YAML_ODDITIES))


def value_for(path) -> st.SearchStrategy:
    """What to put at *path*; weights stay within 1e-3..1e3 when numeric (see the module docstring)."""
    if "weights" in path:
        return WEIGHT_VALUES if path[-1] != "weights" else st.one_of(SCALAR, st.lists(WEIGHT_VALUES, max_size=9))
    return ANY_VALUE


# --------------------------------------------------------------------------- structured mutations


def all_paths(node, prefix=()):
    """Every path into *node* in document order (a Pairs mapping counts as one leaf)."""
    out = [prefix] if prefix else []
    if isinstance(node, Pairs):
        return out
    if isinstance(node, dict):
        for key, value in node.items():
            out += all_paths(value, prefix + (key,))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            out += all_paths(value, prefix + (i,))
    return out


def get_at(doc, path):
    for p in path:
        doc = doc[p]
    return doc


def set_at(doc, path, value):
    get_at(doc, path[:-1])[path[-1]] = value


def del_at(doc, path):
    del get_at(doc, path[:-1])[path[-1]]


def _curve(doc):
    curve = doc.get("curve") if isinstance(doc, dict) else None
    return curve if isinstance(curve, dict) else None


def _is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)


def _degree(curve):
    """The curve's degree if it is a plain valid integer (from degree or order), else None."""
    p = curve.get("degree", curve["order"] - 1 if isinstance(curve.get("order"), int) else None)
    return p if isinstance(p, int) and not isinstance(p, bool) and 1 <= p <= 25 else None


def _knots(curve):
    """The curve's knots as a list of numbers (written out if the job left them to the default), or None."""
    p = _degree(curve)
    pts = curve.get("control_points")
    if p is None or not isinstance(pts, list) or not p < len(pts):
        return None
    if "knots" not in curve:
        n = len(pts)
        curve["knots"] = [0.0] * p + [float(x) for x in np.linspace(0.0, 1.0, n - p + 1)] + [1.0] * p
    knots = curve["knots"]
    if not isinstance(knots, list) or not all(_is_number(k) for k in knots) or len(knots) != len(pts) + p + 1:
        return None
    return knots


CURVE_DEFECTS = ("knot-count", "decreasing-knots", "interior-multiplicity", "unclamped-start", "unclamped-end",
                 "degree", "order-and-degree", "point-dimension", "one-point-dimension", "empty-list",
                 "weight-not-positive", "weight-count", "too-few-points", "null-section")


def curve_mutation(draw, doc):
    """One of the issue's named defects of a curve (each breaks a rule); returns its name."""
    curve = _curve(doc)
    if curve is None:
        return "no curve"
    kind = draw(st.sampled_from(CURVE_DEFECTS))
    p = _degree(curve)
    if kind == "degree":
        curve["degree"] = draw(st.sampled_from([0, -1, 26, 27, 100, 10 ** 6, 10 ** 30, 1.5, "two", None, True, []]))
    elif kind == "order-and-degree":
        curve["order"], curve["degree"] = (p + 1, p) if p is not None else (3, 2)
    elif kind == "point-dimension":
        dim = draw(st.sampled_from([0, 1, 4, 5]))
        pts = curve.get("control_points")
        if isinstance(pts, list):
            curve["control_points"] = [([c for c in q][:dim] + [1.0] * max(0, dim - len(q)))
                                       if isinstance(q, list) else q for q in pts]
    elif kind == "one-point-dimension":
        pts = curve.get("control_points")
        if isinstance(pts, list) and pts:
            i = draw(st.integers(0, len(pts) - 1))
            dim = len(pts[0]) if isinstance(pts[0], list) else 2
            pts[i] = draw(st.sampled_from([q for q in ([1.0], [1.0, 2.0, 3.0, 4.0], [], [1.0, 2.0, 3.0], [1.0, 2.0])
                                           if len(q) != dim]))
    elif kind == "empty-list":
        curve[draw(st.sampled_from(["control_points", "weights", "knots"]))] = []
    elif kind == "weight-not-positive":
        w = curve.get("weights")
        pts = curve.get("control_points")
        if not isinstance(w, list) and isinstance(pts, list):
            w = curve["weights"] = [1.0] * len(pts)
        if isinstance(w, list) and w:
            w[draw(st.integers(0, len(w) - 1))] = draw(st.sampled_from([0, 0.0, -0.0, -1, -1e-9, -1e6]))
    elif kind == "weight-count":
        pts = curve.get("control_points")
        if isinstance(pts, list):
            curve["weights"] = [1.0] * (len(pts) + draw(st.sampled_from([-1, 1, 5])))
    elif kind == "too-few-points":
        pts = curve.get("control_points")
        if isinstance(pts, list) and p is not None:
            curve["control_points"] = pts[:p]
            curve.pop("weights", None)
            curve.pop("knots", None)
    elif kind == "null-section":
        doc["curve"] = None
    else:
        knots = _knots(curve)
        if knots is None:
            return kind + " (skipped)"
        pts = curve["control_points"]
        if kind == "knot-count":
            if draw(st.booleans()):
                knots.insert(draw(st.integers(0, len(knots))), knots[len(knots) // 2])
            else:
                del knots[draw(st.integers(0, len(knots) - 1))]
        elif kind == "decreasing-knots":
            distinct = [i for i in range(len(knots) - 1) if knots[i] != knots[i + 1]]
            if distinct:
                i = draw(st.sampled_from(distinct))
                knots[i], knots[i + 1] = knots[i + 1], knots[i]
        elif kind == "interior-multiplicity":
            inner = sorted(set(knots[p + 1:len(knots) - p - 1]))
            if inner and len(pts) >= 2:
                value = draw(st.sampled_from(inner))
                have = knots.count(value)
                extra = p + 1 - have
                at = knots.index(value)
                knots[at:at] = [value] * extra
                pts[1:1] = [copy.deepcopy(pts[1])] * extra  # keep n_knots = n_ctrl + p + 1
                if isinstance(curve.get("weights"), list):
                    curve["weights"][1:1] = [1.0] * extra
                elif "weights" in curve:
                    del curve["weights"]
        elif kind == "unclamped-start":
            knots[p] = 0.5 * (knots[p] + knots[p + 1])
        elif kind == "unclamped-end":
            last = len(knots) - 1
            knots[last - p] = 0.5 * (knots[last - p] + knots[last - p - 1])
    return kind


@st.composite
def mutated_doc(draw, base: dict, max_mutations: int = 3):
    """*base* (valid) with 1..max_mutations mutations drawn by hypothesis, as (YAML bytes, labels)."""
    doc = copy.deepcopy(base)
    labels = []
    for _ in range(draw(st.integers(1, max_mutations))):
        op = draw(st.sampled_from(["set", "set", "set", "delete", "insert", "unknown-key", "curve", "curve",
                                   "duplicate-key", "alias"]))
        paths = all_paths(doc)
        if op == "curve":
            labels.append(curve_mutation(draw, doc))
            continue
        if not paths:
            op = "unknown-key"
        if op == "set":
            path = draw(st.sampled_from(paths))
            set_at(doc, path, draw(value_for(path)))
        elif op == "delete":
            path = draw(st.sampled_from(paths))
            del_at(doc, path)
        elif op == "insert":
            lists = [p for p in paths if isinstance(get_at(doc, p), list) and not isinstance(get_at(doc, p), Pairs)]
            if not lists:
                continue
            path = draw(st.sampled_from(lists))
            target = get_at(doc, path)
            target.insert(draw(st.integers(0, len(target))), draw(value_for(path + (0,))))
        elif op == "unknown-key":
            maps = [()] + [p for p in paths if isinstance(get_at(doc, p), dict)]
            path = draw(st.sampled_from(maps))
            key = draw(st.sampled_from(["curv", "Degree", "feed_rate", "x", "", "1", "extra", "axes", "z"]) | st.text(max_size=8))
            target = get_at(doc, path)
            if key in target:
                continue
            target[key] = draw(SCALAR)
        elif op == "duplicate-key":
            maps = [()] + [p for p in paths if isinstance(get_at(doc, p), dict) and get_at(doc, p)]
            path = draw(st.sampled_from(maps))
            target = get_at(doc, path)
            if not target:
                continue
            key = draw(st.sampled_from(sorted(target, key=str)))
            pairs = Pairs(target.items())
            pairs.insert(draw(st.integers(0, len(pairs))), (key, target[key]))
            if path:
                set_at(doc, path, pairs)
            else:
                labels.append(op)
                return block_pairs(pairs).encode(), labels
        elif op == "alias":
            leaves = [p for p in paths if not isinstance(get_at(doc, p), (dict, list, Pairs))]
            if len(leaves) < 2:
                continue
            i, j = sorted(draw(st.lists(st.integers(0, len(leaves) - 1), min_size=2, max_size=2, unique=True)))
            first, second = leaves[i], leaves[j]  # document order: the anchor comes first
            set_at(doc, first, Raw(f"&a {emit(get_at(doc, first))}"))
            set_at(doc, second, Raw("*a"))
        labels.append(op)
    text = block(doc).encode() if isinstance(doc, dict) else (emit(doc) + "\n").encode()
    if draw(st.integers(0, 9)) == 0:  # now and then, damage the text itself
        labels.append("bytes")
        at = draw(st.integers(0, len(text)))
        cut = draw(st.integers(0, 8))
        text = text[:at] + draw(st.binary(max_size=6) | st.sampled_from([b"\xff", b"\xc3", b"\xed\xa0\x80", b"\t",
                                                                          b"\x00", b": ", b"- ", b"\n  ", b"{", b"]"])) + text[at + cut:]
    return text, labels


def block_pairs(pairs) -> str:
    return "".join(f"{emit(k)}: {emit(v)}\n" for k, v in pairs)


# --------------------------------------------------------------------------- base documents

CIRCLE_JOB = {
    "curve": {"degree": 2, "control_points": [[0, 0], [0, 50], [100, 50], [100, 0], [100, -50], [0, -50], [0, 0]],
              "weights": [1, 0.5, 0.5, 1, 0.5, 0.5, 1], "knots": [0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1]},
    "profile": {"type": "trapezoidal", "feedrate": "100 mm/s", "accel_time": "0.5 s", "accdec": "before"},
    "interpolator": {"method": "taylor2", "period": "1 ms"},
}
CUBIC_3D_JOB = {
    "curve": {"order": 4, "control_points": [[0, 0, 0], [10, 20, 5], [30, -10, 10], [50, 15, 0], [70, 0, 20]],
              "knots": [2, 2, 2, 2, 4.5, 7, 7, 7, 7]},
    "profile": {"type": "bell", "feedrate": "3000 mm/min", "accel_time": 0.2, "accdec": "after"},
    "interpolator": {"method": "rk4", "period": 0.002},
}
POLYLINE_JOB = {
    "curve": {"degree": 1, "control_points": [[0, 0], [20, 0], [20, 0], [20, 10], [0, 10]]},
    "profile": {"type": "exponential", "feedrate": 50, "accel_time": "100 ms", "time_constant": 0.025},
    "interpolator": {"method": "exact", "period": "2 ms"},
}
BASE_JOBS = [CIRCLE_JOB, CUBIC_3D_JOB, POLYLINE_JOB]
BASE_PROFILE = {"profile": {"type": "exponential", "feedrate": "6 m/min", "accel_time": "250 ms",
                            "time_constant": "50 ms", "accdec": "before"},
                "interpolator": {"method": "exact", "period": "500 us"}}
ADAPTIVE_PROFILE = {"profile": {"type": "adaptive", "feedrate": "100 mm/s", "chord_tolerance": "1 um",
                                "max_accel": "1000 mm/s^2", "max_jerk": "30000 mm/s^3", "max_normal_accel": 2000,
                                "accdec": "before", "axes": {"x": {"max_velocity": 60, "max_accel": 800},
                                                             "y": {"max_velocity": "3.6 m/min", "max_accel": 800}}},
                    "interpolator": {"method": "exact", "period": "1 ms"}}
BASE_SERVO = {"axes": {
    "x": {"plant": {"num": [112570.543], "den": [1, 601.677, 113727.10]}, "kp": 40, "kv": 0.6,
          "encoder_resolution": 0.0005, "voltage_limit": 10},
    "y": {"plant": {"num": [319514.874], "den": [1, 1649.133, 342115.44]}, "kp": 70, "kv": 0.6},
}}


@pytest.fixture(scope="module")
def work(tmp_path_factory):
    """A scratch directory for the fuzzers (hypothesis and function-scoped tmp_path do not mix)."""
    return tmp_path_factory.mktemp("robust")


@pytest.fixture(scope="module")
def streams(work):
    """The circle planned at 4 ms (911 ticks, quick to simulate) as CSV and binary."""
    d = work / "streams"
    d.mkdir()
    for fmt in ("csv", "bin"):
        res = invoke("plan", CIRCLE, "--period", "4 ms", "-q", "--format", fmt, "-o", d / f"c4.{fmt}")
        assert res.code == 0, str(res)
    return d


def test_base_documents_are_valid(work, streams):
    for i, base in enumerate(BASE_JOBS):
        path = work / f"base{i}.yaml"
        path.write_text(block(base))
        res = invoke("plan", path, "-q", "--format", "bin")
        assert res.code == 0, str(res)
        check_plan_output(res.out, path)
    for base in (BASE_PROFILE, ADAPTIVE_PROFILE):
        (work / "p.yaml").write_text(block(base))
        res = invoke("info", CIRCLE, "--profile", work / "p.yaml", "--json")
        assert res.code == 0 and json.loads(res.out)["interpolator"] == "exact", str(res)
        assert json.loads(res.out)["profile"] == base["profile"]["type"]
    (work / "s.yaml").write_text(block(BASE_SERVO))
    res = invoke("simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", work / "s.yaml", "--json")
    assert res.code == 0, str(res)
    check_simulate_json(res.out)


# =========================================================================== 1. one error contract

DEFECTS = {
    "missing": None,
    "directory": "dir",
    "empty": b"",
    "whitespace": b"  \n\n# only a comment\n",
    "non-utf8": b"curve:\n  degree: 2\xff\n",
    "utf16": "curve: {degree: 1}\n".encode("utf-16"),
    "binary-junk": bytes(range(256)) * 4,
    "alias-bomb": b"a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\n"
                  b"c: &c [*b, *b, *b, *b, *b, *b, *b, *b, *b]\ncurve: [*c, *c, *c, *c, *c, *c, *c, *c, *c]\n",
    "duplicate-key": b"curve: {degree: 1}\ncurve: {degree: 2}\naxes: {}\naxes: {}\n",
    "a-list": b"- 1\n- 2\n",
    "a-scalar": b"42\n",
    "bad-yaml": b"curve: [1, 2\n",
    "tab-indent": b"curve:\n\tdegree: 2\n",
    "python-tag": b"!!python/object/apply:os.system ['echo hacked']\n",
}


def _defect_file(tmp_path, defect):
    path = tmp_path / "input.yaml"
    content = DEFECTS[defect]
    if content == "dir":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content)
    return path


@pytest.mark.parametrize("defect", list(DEFECTS))
@pytest.mark.parametrize("role", ["job", "profile", "servo", "stream", "simulate-job"])
def test_every_input_file_defect_is_one_line_exit_2(tmp_path, streams, role, defect):
    """Every file the tool reads, broken every way: exit 2, one line naming the file, stdout empty."""
    path = _defect_file(tmp_path, defect)
    args = {
        "job": ["plan", path],
        "profile": ["plan", CIRCLE, "--profile", path],
        "servo": ["simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", path],
        "stream": ["simulate", path, "--job", CIRCLE, "--json"],
        "simulate-job": ["simulate", streams / "c4.bin", "--job", path],
    }[role]
    res = invoke(*args)
    assert_error(res, named=[str(path)])
    assert sorted(os.listdir(tmp_path)) == ["input.yaml"] or defect == "missing"


@pytest.mark.parametrize("args,words", [
    (["plan"], "Missing argument"),
    (["plan", CIRCLE, "--format"], "requires an argument"),
    (["plan", CIRCLE, "--bogus"], "No such option"),
    (["plan", CIRCLE, "--interpolator", "taylor3"], "--interpolator"),
    (["info", CIRCLE, "extra"], "unexpected extra argument"),
    (["simulate", CIRCLE], "--job"),
    (["compare"], "Missing argument"),
    (["compare", CIRCLE, "--period", "fast"], "--period"),
    (["bench", CIRCLE, "--repeats", "0"], "--repeats"),
    (["nosuchcommand"], "No such command"),
    (["--bogus"], "No such option"),
])
def test_usage_errors_are_one_line_exit_2(args, words):
    res = invoke(*args)
    assert_error(res, words)


def test_runtime_failure_is_exit_1_one_line(monkeypatch):
    """A NurbsInterpError that is not bad input (exit 1), and an unexpected exception (exit 1, 'internal error')."""
    import nurbsinterp.interpolate as plan_cli  # the CLI imports Interpolation from here when plan runs

    class Boom:
        def __init__(self, *a, **k):
            raise NurbsInterpError("the sky fell\non two lines")

    monkeypatch.setattr(plan_cli, "Interpolation", Boom)
    res = invoke("plan", CIRCLE)
    assert res.code == 1 and res.out == b"" and res.err == "nurbsinterp: the sky fell on two lines\n"

    def crash(*a, **k):
        raise ZeroDivisionError("float division\nby zero")

    monkeypatch.setattr(plan_cli, "Interpolation", crash)
    res = invoke("plan", CIRCLE)
    assert res.code == 1 and res.out == b"" and res.err.count("\n") == 1
    assert "internal error: ZeroDivisionError" in res.err and "--debug" in res.err and "Traceback" not in res.err
    with pytest.raises(ZeroDivisionError):
        main(["--debug", "plan", str(CIRCLE)])


def test_messages_name_the_file_field_and_value(tmp_path):
    """The README's example, and a value-carrying message for each input kind."""
    job = tmp_path / "bad.yaml"
    job.write_text("curve:\n  degree: 2\n  control_points: [[0,0],[1,1],[2,0],[3,1],[4,0]]\n"
                   "  knots: [0, 0, 0, 0.5, 0.3, 1, 1, 1]\n")
    assert assert_error(invoke("info", job)) == \
        f"nurbsinterp: {job}: curve.knots[4] = 0.3 is smaller than curve.knots[3] = 0.5\n"
    servo = tmp_path / "servo.yaml"
    doc = copy.deepcopy(BASE_SERVO)
    doc["axes"]["y"]["kp"] = -70
    servo.write_text(block(doc))
    assert_error(invoke("simulate", "--plan", "--job", CIRCLE, "--servo", servo), str(servo), "axes.y.kp", "-70", "> 0")
    stream = tmp_path / "s.csv"
    stream.write_text("k,t,u,x,y,v,a\n0,0,0,0,0,0,0\n1,0.001,0.1,oops,0,0,0\n")
    assert_error(invoke("simulate", stream, "--job", CIRCLE), str(stream), "line 3", "'oops'")


# =========================================================================== 2. fuzzing

RANDOM_YAML = st.recursive(
    SCALAR,
    lambda children: st.lists(children, max_size=4) | st.dictionaries(
        st.sampled_from(["curve", "profile", "interpolator", "degree", "order", "control_points", "weights", "knots",
                         "type", "feedrate", "accel_time", "time_constant", "accdec", "method", "period", "axes", "x",
                         "y", "z", "plant", "num", "den", "kp", "kv"]) | st.text(max_size=5), children, max_size=5),
    max_leaves=25)


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_random_yaml_documents_as_a_job(work, budget):
    """Random YAML (as a whole document, or as one section of an otherwise valid job)."""
    @settings(FUZZ, max_examples=budget)
    @given(doc=RANDOM_YAML, section=st.sampled_from([None, "curve", "profile", "interpolator"]))
    def check(doc, section):
        if section is not None:
            full = copy.deepcopy(CIRCLE_JOB)
            full[section] = doc
            doc = full
        path = work / "random.yaml"
        path.write_text(block(doc) if isinstance(doc, dict) else emit(doc) + "\n")
        for command in (["info", path, "--json"],
                        ["plan", path, "-q", "--format", "bin", "--max-ticks", FUZZ_MAX_TICKS]):
            res = invoke(*command, note=path.read_text())
            if assert_0_or_2(res, named=[path]):
                check_info_json(res.out) if command[0] == "info" else check_plan_output(res.out, path)

    check()


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_random_bytes_as_every_input_file(work, streams, budget):
    @settings(FUZZ, max_examples=budget)
    @given(raw=st.binary(max_size=300) | st.text(max_size=200).map(str.encode))
    def check(raw):
        path = work / "bytes.yaml"
        path.write_bytes(raw)
        for args in (["info", path, "--json"], ["info", CIRCLE, "--profile", path, "--json"],
                     ["simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", path, "--json"],
                     ["simulate", path, "--job", CIRCLE, "--json"]):
            res = invoke(*args, note=repr(raw))
            if assert_0_or_2(res, named=[path]):  # only an empty mapping ('{}') is a valid (profile) file
                assert "--profile" in args, str(res)
                check_info_json(res.out)

    check()


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_job_mutations(work, budget):
    """Mutations of valid jobs (hypothesis chooses the field and the bad value): exit 2, or 0 and sane output."""
    @settings(FUZZ, max_examples=budget)
    @given(data=st.data(), which=st.integers(0, len(BASE_JOBS) - 1))
    def check(data, which):
        text, labels = data.draw(mutated_doc(BASE_JOBS[which]))
        path = work / "job.yaml"
        path.write_bytes(text)
        note = f"{labels}\n{text!r}"
        res = invoke("info", path, "--json", note=note)
        if assert_0_or_2(res, named=[path]):
            check_info_json(res.out)
        elif len(labels) == 1 and labels[0] in CURVE_DEFECTS:  # exactly one named defect: the message says where
            assert "curve" in res.err, res.err
        if len(labels) == 1 and labels[0] in CURVE_DEFECTS:
            assert res.code == 2, f"{labels[0]} was accepted: {text!r}"
        res = invoke("plan", path, "-q", "--format", "bin", "--max-ticks", FUZZ_MAX_TICKS, note=note)
        if assert_0_or_2(res, named=[path]):
            check_plan_output(res.out, path)

    check()


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_profile_file_mutations(work, budget):
    """--profile FILE mutated: the message names the profile file (or the job, for a job-level refusal).
    The adaptive base runs on the circle."""
    @settings(FUZZ, max_examples=budget)
    @given(data=st.data(), adaptive=st.booleans())
    def check(data, adaptive):
        text, labels = data.draw(mutated_doc(ADAPTIVE_PROFILE if adaptive else BASE_PROFILE))
        job = work / ("pjob-circle.yaml" if adaptive else "pjob.yaml")
        if not job.exists():
            job.write_text(block(CIRCLE_JOB if adaptive else POLYLINE_JOB))
        path = work / "profile.yaml"
        path.write_bytes(text)
        note = f"{labels}\n{text!r}"
        res = invoke("info", job, "--profile", path, "--json", note=note)
        if assert_0_or_2(res, named=[path, job]):
            check_info_json(res.out)
        out = work / "pout.bin"
        res = invoke("plan", job, "--profile", path, "-q", "--format", "bin", "--max-ticks", FUZZ_MAX_TICKS,
                     "-o", out, note=note)
        if assert_0_or_2(res, named=[path, job]):
            check_plan_output(out.read_bytes(), job)
            out.unlink()
        assert not out.exists() and not list(work.glob(".pout.bin.*")), "a partial output file was left"

    check()


SERVO_NUMBERS = st.one_of(st.floats(min_value=1e-3, max_value=1e7), st.floats(min_value=-1e7, max_value=-1e-3),
                          st.sampled_from([0, 0.0, 1, -1]))


def servo_value(path):
    numeric = path and (path[-1] in ("kp", "kv", "encoder_resolution", "voltage_limit") or isinstance(path[-1], int))
    return st.one_of(SERVO_NUMBERS, SERVO_NUMBERS, ANY_VALUE) if numeric else ANY_VALUE


@st.composite
def mutated_servo(draw):
    """Servo-file mutations (numbers stay within 1e-3..1e7 in magnitude; test_extreme_servo_plant_is_refused goes beyond)."""
    doc = copy.deepcopy(BASE_SERVO)
    labels = []
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["set", "set", "delete", "insert", "unknown-key", "z-axis", "drop-axis"]))
        paths = all_paths(doc)
        if op == "set" and paths:
            path = draw(st.sampled_from(paths))
            set_at(doc, path, draw(servo_value(path)))
        elif op == "delete" and paths:
            del_at(doc, draw(st.sampled_from(paths)))
        elif op == "insert":
            lists = [p for p in paths if isinstance(get_at(doc, p), list)]
            if lists:
                path = draw(st.sampled_from(lists))
                target = get_at(doc, path)
                target.insert(draw(st.integers(0, len(target))), draw(SERVO_NUMBERS | SCALAR))
        elif op == "unknown-key":
            maps = [()] + [p for p in paths if isinstance(get_at(doc, p), dict)]
            target = get_at(doc, draw(st.sampled_from(maps)))
            target.setdefault(draw(st.sampled_from(["w", "ki", "zeta", "plnt", "X", "Kp"])), draw(SCALAR))
        elif op == "z-axis" and isinstance(doc.get("axes"), dict):
            doc["axes"]["z"] = copy.deepcopy(BASE_SERVO["axes"]["y"])
        elif op == "drop-axis" and isinstance(doc.get("axes"), dict) and doc["axes"]:
            doc["axes"].pop(draw(st.sampled_from(sorted(doc["axes"], key=str))))
        labels.append(op)
    return (block(doc) if isinstance(doc, dict) else emit(doc) + "\n").encode(), labels


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_servo_file_mutations(work, streams, budget):
    @settings(FUZZ, max_examples=budget)
    @given(mutation=mutated_servo(), fmt=st.sampled_from(["csv", "bin"]))
    def check(mutation, fmt):
        text, labels = mutation
        path = work / "servo.yaml"
        path.write_bytes(text)
        stream = streams / f"c4.{fmt}"
        res = invoke("simulate", stream, "--job", CIRCLE, "--servo", path, "--json", note=f"{labels}\n{text!r}")
        if assert_0_or_2(res, named=[path, stream]):
            check_simulate_json(res.out)

    check()


# --------------------------------------------------------------------------- command streams

FIELD_VALUES = st.one_of(
    st.sampled_from([b"nan", b"NaN", b"inf", b"-inf", b"Infinity", b"1e999", b"", b" ", b"abc", b"0x10", b"1_0",
                     b"--1", b"1e", b"\xff", b"\x00", b"1,2", b"+5", b"-0", b"5\t", b"\r"]),
    st.floats(min_value=-1e12, max_value=1e12).map(lambda x: repr(x).encode()),
)
FLIP_BYTES = st.binary(min_size=1, max_size=3).filter(lambda b: b"e" not in b.lower())  # no new exponents


@st.composite
def mutated_csv(draw, base: bytes):
    """*base* (a whole stream) mutated; its end mark counts the rows left, as a writer's would, unless cut."""
    lines = base.split(b"\n")[:-2]  # the end mark is made anew below
    header, rows = lines[0], lines[1:]
    labels = []
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["truncate", "field", "drop-field", "add-field", "swap", "dup", "del", "header",
                                   "flip", "crlf", "blank"]))
        labels.append(op)
        if op == "field" and rows:
            i = draw(st.integers(0, len(rows) - 1))
            fields = rows[i].split(b",")
            fields[draw(st.integers(0, len(fields) - 1))] = draw(FIELD_VALUES)
            rows[i] = b",".join(fields)
        elif op == "drop-field" and rows:
            i = draw(st.integers(0, len(rows) - 1))
            rows[i] = b",".join(rows[i].split(b",")[:-1])
        elif op == "add-field" and rows:
            i = draw(st.integers(0, len(rows) - 1))
            rows[i] += b"," + draw(FIELD_VALUES)
        elif op == "swap" and len(rows) > 2:
            i = draw(st.integers(0, len(rows) - 2))
            rows[i], rows[i + 1] = rows[i + 1], rows[i]
        elif op == "dup" and rows:
            i = draw(st.integers(0, len(rows) - 1))
            rows.insert(i, rows[i])
        elif op == "del" and len(rows) > 1:
            del rows[draw(st.integers(0, len(rows) - 1))]
        elif op == "header":
            header = draw(st.sampled_from([b"", b"k,t,u,x,y,v", b"k,t,u,x,y,v,a,extra", b"k,t,u,y,x,v,a",
                                           b"k,t,u,x,y,z,v,a", b"K,T,U,X,Y,V,A", b"k,t,u,x,x,v,a", b"k t u x y v a",
                                           b"nurbsinterp-bin 1 k,t,u,x,y,v,a", b"nurbsinterp-bin 2 k,t,u,x,y,v,a",
                                           b"\xef\xbb\xbfk,t,u,x,y,v,a", b"k,t,u,x,y,v,a,"]) | st.binary(max_size=20))
        elif op == "flip":
            body = b"\n".join([header, *rows])
            at = draw(st.integers(0, max(0, len(body) - 1)))
            body = body[:at] + draw(FLIP_BYTES) + body[at + 1:]
            header, *rows = body.split(b"\n")
        elif op == "crlf":
            rows = [r + b"\r" for r in rows]
        elif op == "blank" and rows:
            rows.insert(draw(st.integers(0, len(rows))), b"")
    text = b"\n".join([header, *rows]) + b"\n" + b"# nurbsinterp-end ticks=%d\n" % len(rows)
    if "truncate" in labels:
        text = text[:draw(st.integers(0, len(text)))]
    return text, labels


@st.composite
def mutated_bin(draw, base: bytes):
    """*base* (a whole stream) mutated; its end mark counts the records left, as a writer's would, unless cut."""
    head, _, body = base.partition(b"\n")
    data = np.frombuffer(body[:-64], "<f8").reshape(-1, 8).copy()  # k, n, t, u, x, y, v, a
    labels = []
    cut = None
    for _ in range(draw(st.integers(1, 3))):
        op = draw(st.sampled_from(["truncate", "value", "swap", "header", "random-body", "drop-record"]))
        labels.append(op)
        if op == "truncate":
            cut = draw(st.integers(0, len(body)))
        elif op == "value":
            r = draw(st.integers(0, data.shape[0] - 1))
            c = draw(st.integers(0, 7))
            data[r, c] = draw(st.sampled_from([np.nan, np.inf, -np.inf, -0.0, 5e-324, 1e-300])
                              | st.floats(min_value=-1e12, max_value=1e12))
        elif op == "swap":
            r = draw(st.integers(0, data.shape[0] - 2))
            data[[r, r + 1]] = data[[r + 1, r]]
        elif op == "drop-record":
            data = np.delete(data, draw(st.integers(0, data.shape[0] - 1)), axis=0)
        elif op == "header":
            head = draw(st.sampled_from([b"nurbsinterp-bin 2 k,t,u,x,y,v,a", b"nurbsinterp-bin 1", b"nurbsinterp-bin",
                                         b"nurbsinterp-bin 1 k,t,u,x,y,v", b"nurbsinterp-bin 1 k,t,u,x,y,v,a,w",
                                         b"nurbsinterp-bin 1 k,t,u,x,y,v,a extra", b"nurbsinterp-bin  1  k,t,u,x,y,v,a",
                                         b"nurbsinterp-bin 1 a,v,y,x,u,t,k", b"nurbsinterp-bin 1 k,t,u,x,y,z,v,a",
                                         b"nurbsinterp-bin 1 k,t,u,x,y,v,a\r", b"nurbsinterp-bin\xff 1 k,t,u,x,y,v,a",
                                         b"nurbsinterp-bin 01 k,t,u,x,y,v,a", b"k,t,u,x,y,v,a"]) | st.binary(max_size=40))
        elif op == "random-body":
            data = np.frombuffer(draw(st.binary(min_size=0, max_size=8 * 8 * 6)).ljust(8 * 8 * 6, b"\0"), "<f8")
            data = data.reshape(-1, 8).copy()
    body = data.astype("<f8").tobytes() + (b"nurbsinterp-end ticks=%d" % data.shape[0]).ljust(63) + b"\n"
    if cut is not None:
        body = body[:cut]
    return head + b"\n" + body, labels


def _check_stream_result(res, path):
    if assert_0_or_2(res, named=[path, "built-in paper X-Y table"]):
        check_simulate_json(res.out)


@pytest.mark.parametrize("fmt", ["csv", "bin"])
@budgets(quick=examples(25), full=examples(100))
def test_fuzz_stream_mutations(work, streams, fmt, budget):
    @settings(FUZZ, max_examples=budget)
    @given(data=st.data())
    def check(data):
        mutated = {"csv": mutated_csv, "bin": mutated_bin}[fmt]
        raw, labels = data.draw(mutated((streams / f"c4.{fmt}").read_bytes()))
        path = work / f"stream.{fmt}"
        path.write_bytes(raw)
        _check_stream_result(invoke("simulate", path, "--job", CIRCLE, "--json", note=str(labels)), path)

    check()


@budgets(quick=examples(15), full=examples(60))
def test_fuzz_streams_on_stdin(streams, budget):
    """The same mutations through stdin ('-'): the message names <stdin>."""
    @settings(FUZZ, max_examples=budget)
    @given(data=st.data())
    def check(data):
        if data.draw(st.booleans()):
            raw, labels = data.draw(mutated_csv((streams / "c4.csv").read_bytes()))
        else:
            raw, labels = data.draw(mutated_bin((streams / "c4.bin").read_bytes()))
        _check_stream_result(invoke("simulate", "-", "--job", CIRCLE, "--json", stdin=raw, note=str(labels)),
                             "<stdin>")

    check()


OPTION_VALUES = st.one_of(QUANTITY, TEXT, SAFE_FLOATS.map(repr), st.sampled_from(
    ["nan", "inf", "-inf", "1e999", "1e999 s", "0", "-0", "0 ms", "  1 ms ", "1e-3", "1E-3", "1 MS", "1ms", "1 ms ms"]))


@budgets(quick=examples(25), full=examples(100))
def test_fuzz_command_line_quantities(budget):
    @settings(FUZZ, max_examples=budget)
    @given(option=st.sampled_from(["--period", "--feedrate", "--accel-time", "--time-constant", "--chord-tolerance",
                                   "--max-accel", "--max-jerk", "--max-normal-accel"]), value=OPTION_VALUES,
           extra=st.sampled_from([[], ["--profile-type", "exponential"], ["--accdec", "after"],
                                  ["--profile-type", "adaptive"],
                                  ["--profile-type", "adaptive", "--max-jerk", "30000"]]))
    def check(option, value, extra):
        res = invoke("plan", CIRCLE, option, value, *extra, "-q", "--format", "bin", "--max-ticks", FUZZ_MAX_TICKS,
                     note=value)
        if assert_0_or_2(res, named=[option, CIRCLE]):
            check_plan_output(res.out, CIRCLE)

    check()


@settings(FUZZ, max_examples=examples(30))
@given(levels=st.integers(1, 12), width=st.integers(1, 12), where=st.sampled_from(["job", "profile", "servo"]))
def test_fuzz_alias_bombs_are_refused_at_the_first_alias(work, streams, levels, width, where):
    lines = ["l0: &l0 [" + ", ".join(["lol"] * width) + "]"]
    for i in range(1, levels + 1):
        lines.append(f"l{i}: &l{i} [" + ", ".join([f"*l{i - 1}"] * width) + "]")
    path = work / "bomb.yaml"
    path.write_text("\n".join(lines) + "\n")
    args = {"job": ["info", path], "profile": ["info", CIRCLE, "--profile", path],
            "servo": ["simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", path]}[where]
    assert_error(invoke(*args), "aliases", "line 2", named=[path])


@st.composite
def valid_jobs(draw):
    """Random VALID jobs: degree 1-5, 2-D or 3-D, repeated points, weights 1e-2..1e2, interior knots of
    multiplicity up to p, any domain, every profile, method and acc/dec mode."""
    p = draw(st.integers(1, 5))
    dim = draw(st.sampled_from([2, 3]))
    n_inner = draw(st.integers(0, 6))
    inner = sorted(draw(st.lists(st.floats(0.01, 0.99), min_size=n_inner, max_size=n_inner)))
    mults = [draw(st.integers(1, p)) for _ in inner]
    a = draw(st.floats(-100, 100))
    width = draw(st.sampled_from([1.0, 1e-3, 7.5, 1e3]))
    b = a + width
    interior = {}  # value -> multiplicity (at most p: two draws may land on one float)
    for x, m in zip(inner, mults):
        value = a + width * x
        if a < value < b:
            interior[value] = min(p, interior.get(value, 0) + m)
    knots = [a] * (p + 1) + [v for v in sorted(interior) for _ in range(interior[v])] + [b] * (p + 1)
    n = len(knots) - p - 1
    coord = st.floats(-200, 200, allow_subnormal=False)
    pts = [draw(st.lists(coord, min_size=dim, max_size=dim)) for _ in range(n)]
    for i in range(1, n):  # now and then a repeated control point (zero speed)
        if draw(st.integers(0, 4)) == 0:
            pts[i] = list(pts[i - 1])
    curve = {"degree": p, "control_points": pts, "knots": knots}
    if draw(st.booleans()):
        curve["weights"] = draw(st.lists(st.floats(1e-2, 1e2), min_size=n, max_size=n))
    profile = {"type": draw(st.sampled_from(["trapezoidal", "exponential", "bell", "adaptive"])),
               "feedrate": draw(st.floats(10.0, 2e3)), "accel_time": draw(st.sampled_from([0, 0.01, 0.2, 1.0])),
               "accdec": draw(st.sampled_from(["before", "after"]))}
    if profile["type"] == "exponential" and draw(st.booleans()):  # the only profile that reads it (issue 27)
        profile["time_constant"] = draw(st.floats(1e-3, 0.5))
    if profile["type"] == "adaptive":
        profile["accdec"] = "before"
        # a span where the speed vanishes blows the planner's memory up (test_adaptive_plan_stops_at_a_zero_speed_span)
        assume(all(pts[i] != pts[i + 1] for i in range(n - 1)))
        for key, lo, hi in (("chord_tolerance", 1e-4, 0.1), ("max_accel", 100.0, 1e4), ("max_jerk", 1e3, 1e6),
                            ("max_normal_accel", 100.0, 1e4)):
            if draw(st.booleans()):
                profile[key] = draw(st.floats(lo, hi))
        if draw(st.booleans()):
            profile["axes"] = {a: {"max_velocity": draw(st.floats(10.0, 1e3)), "max_accel": draw(st.floats(100.0, 1e4))}
                               for a in "xyz"[:dim]}
        if "max_accel" in profile:
            del profile["accel_time"]  # which the adaptive profile reads only without max_accel
    interpolator = {"method": draw(st.sampled_from(["taylor1", "taylor2", "rk4", "exact"])),
                    "period": draw(st.sampled_from([2.5e-4, 1e-3, 4e-3, 0.02]))}
    return {"curve": curve, "profile": profile, "interpolator": interpolator}


@budgets(quick=examples(20), full=examples(80))
def test_fuzz_valid_random_jobs_give_sane_output(work, budget):
    """The other side of the mutations: valid jobs (which the knot rules must accept) give sane streams."""
    @settings(FUZZ, max_examples=budget)
    @given(doc=valid_jobs(), fmt=st.sampled_from(["bin", "csv"]))
    def check(doc, fmt):
        path = work / "valid.yaml"
        path.write_text(block(doc))
        for command in (["info", path, "--json"], ["plan", path, "-q", "--format", fmt, "--max-ticks", "100000"]):
            res = invoke(*command, note=block(doc))
            ok = assert_0_or_2(res, named=[path])
            if ok:
                check_info_json(res.out) if command[0] == "info" else check_plan_output(res.out, path, fmt)
            elif ok is False:  # the only refusals a valid job may get: README, "Edge cases"
                # "too narrow for its magnitude": issue 13 item 8 bounds the speed's peak times ulp(u), no longer
                # the average; a domain of width 1e-3 at |u| ~ 100 with weights up to 1e4 apart (or knot spans of
                # 1e-9) puts adjacent doubles of u microns apart on the curve, which the rule refuses
                assert any(text in res.err for text in ("zero length", "ticks", "max_accel is not set",
                                                        "insert a knot", "too narrow for its magnitude")), res.err

    check()


# =========================================================================== 3. resource bounds


def test_max_ticks_refused_up_front_with_the_estimate(tmp_path, monkeypatch):
    """3.6e9 ticks (T = 1 ns): refused before any tick is computed or any byte is written."""
    import nurbsinterp.interpolate as interp

    def no_ticks(self):
        raise AssertionError("a tick was computed")

    monkeypatch.setattr(interp.Interpolation, "chunks", no_ticks)
    out = tmp_path / "run.csv"
    for args in (["plan", CIRCLE, "--period", "1 ns", "-o", out],
                 ["plan", CIRCLE, "--period", "1 ns"],
                 ["plan", CIRCLE, "--max-ticks", "3000"],  # the circle needs 3643
                 ["plan", CIRCLE, "--accdec", "after", "--profile-type", "exponential", "--time-constant", "1e6"],
                 ["simulate", "--plan", "--job", CIRCLE, "--period", "1 ns", "-o", out],
                 ["simulate", "--plan", "--job", CIRCLE, "--max-ticks", "3000", "--json"]):
        res = invoke(*args)
        err = assert_error(res, "ticks", "--max-ticks", named=[CIRCLE])
        assert "about " in err
        assert os.listdir(tmp_path) == [], "something was written"
    assert "about 3.64e+09 ticks" in assert_error(invoke("plan", CIRCLE, "--period", "1 ns"))


def test_max_ticks_boundary():
    """--max-ticks N accepts a job of exactly N ticks (3643 for the circle) and refuses N - 1."""
    res = invoke("plan", CIRCLE, "--max-ticks", "3643", "-q", "--format", "bin")
    assert res.code == 0
    assert check_plan_output(res.out, CIRCLE)[1].shape[0] == 3643
    assert_error(invoke("plan", CIRCLE, "--max-ticks", "3642", "-q"), "3.64e+03")


def _net_job(path, n, degree=3):
    t = np.linspace(0.0, 2 * np.pi * n / 4000, n)
    pts = np.column_stack([t * 10.0, 100.0 * np.sin(t)])
    path.write_text(f"curve:\n  degree: {degree}\n  control_points: ["
                    + ",".join(f"[{x:.6f},{y:.6f}]" for x, y in pts) + "]\n")
    return pts


def test_large_control_net(tmp_path):
    """A net of 2,000 points (the 200k one is slow: see test_very_large_control_net_200k)."""
    job = tmp_path / "net.yaml"
    pts = _net_job(job, 2000)
    res = invoke("info", job, "--json")
    assert res.code == 0, str(res)
    facts = check_info_json(res.out)
    assert facts["n_control_points"] == 2000 and facts["knot_spans"] == 1997
    polygon = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
    assert 0.5 * polygon < facts["length"] <= polygon * (1 + 1e-12)  # a B-spline is no longer than its polygon
    out = tmp_path / "net.bin"
    res = invoke("plan", job, "-q", "--format", "bin", "-o", out, "--feedrate", "2000")
    assert res.code == 0, str(res)
    check_plan_output(out.read_bytes(), job)


@pytest.mark.skipif(not os.environ.get("NURBSINTERP_SLOW_TESTS"),
                    reason="about 20 s (info ~10 s, of it YAML ~1 s, min radius ~4 s): set NURBSINTERP_SLOW_TESTS=1")
@needs_exe
def test_very_large_control_net_200k(tmp_path):
    job = tmp_path / "net.yaml"
    _net_job(job, 200_000)
    proc = subprocess.run([str(EXE), "info", str(job), "--json"], capture_output=True, timeout=HANG_S)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["n_control_points"] == 200_000
    proc = subprocess.run([str(EXE), "plan", str(job), "-q", "--format", "bin", "-o", "/dev/null",
                           "--feedrate", "20000"], capture_output=True, timeout=HANG_S)
    assert proc.returncode == 0, proc.stderr


def test_file_over_the_size_limit_is_refused_unread(tmp_path):
    from nurbsinterp.config import MAX_FILE_BYTES

    job = tmp_path / "huge.yaml"
    with open(job, "wb") as fh:
        fh.write(b"curve: {degree: 1, control_points: [[0, 0], [1, 0]]}\n")
        fh.write(b"#" * (MAX_FILE_BYTES - 80) + b"\n")
        fh.write(b"# " + b"x" * 100 + b"\n")
    assert job.stat().st_size > MAX_FILE_BYTES
    for args in (["info", job], ["info", CIRCLE, "--profile", job], ["simulate", "--plan", "--job", CIRCLE, "--servo", job]):
        assert_error(invoke(*args), "larger than 64 MiB", named=[job])


def test_too_many_control_points_is_refused_naming_the_limit(tmp_path, monkeypatch):
    """The 10^6 limit (lowered here to 1,000: `info` on a real 10^6-point job takes about a minute)."""
    import nurbsinterp.config.curve as curve_rules

    monkeypatch.setattr(curve_rules, "MAX_CONTROL_POINTS", 1000)
    job = tmp_path / "many.yaml"
    job.write_text("curve:\n  degree: 1\n  control_points: [" + ",".join(["[0,0]"] * 1001) + "]\n")
    assert_error(invoke("info", job), "<1001 points>", "more than the limit of 1000", named=[job])
    job.write_text("curve:\n  degree: 1\n  control_points: [" + ",".join(f"[{i},0]" for i in range(1000)) + "]\n")
    res = invoke("plan", job, "-q", "--format", "bin", "--feedrate", "1000")
    assert res.code == 0, str(res)
    check_plan_output(res.out, job)
    # info samples every span's curvature and coordinates (once ~30 s here: a straight line is one plateau)
    facts = check_info_json(invoke("info", job, "--json").out)
    assert facts["length"] == 999.0 and facts["min_radius"] is None
    assert facts["bounding_box"] == {"min": [0.0, 0.0], "max": [999.0, 0.0]}


@pytest.mark.parametrize("value", [
    pytest.param('"' + "9" * 100_000 + '"', id="long-string"),
    pytest.param("9" * 4000, id="4000-digit-integer"),
])
def test_a_long_value_is_shortened_in_the_message(tmp_path, value):
    job = tmp_path / "long.yaml"
    job.write_text(f"curve: {{degree: 1, control_points: [[0, 0], [1, 0]], weights: {value}}}\n")
    err = assert_error(invoke("info", job), "curve.weights", named=[job])
    assert len(err) < 400, f"the message repeats the whole value ({len(err)} characters)"


# =========================================================================== 4. numerical edge cases


def _job(tmp_path, name, text):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text)
    return path


def _plan_bin(path, *args):
    res = invoke("plan", path, "--format", "bin", *args)
    assert res.code == 0, str(res)
    return res, check_plan_output(res.out, path)[1]


def test_zero_length_curve(tmp_path):
    job = _job(tmp_path, "point", "curve:\n  degree: 2\n  control_points: [[5, 5], [5, 5], [5, 5]]\n")
    assert_error(invoke("plan", job), "zero length", named=[job])
    assert_error(invoke("simulate", "--plan", "--job", job), "zero length", named=[job])
    res = invoke("info", job, "--json")
    assert res.code == 0, str(res)
    facts = check_info_json(res.out)
    assert facts["length"] == 0 and facts["motion_time"] == 0
    assert facts["bounding_box"]["min"] == pytest.approx([5.0, 5.0], abs=1e-12)
    assert facts["bounding_box"]["max"] == pytest.approx([5.0, 5.0], abs=1e-12)


EDGE_JOBS = {
    "repeated-start": "curve:\n  degree: 3\n  control_points: [[0,0],[0,0],[0,0],[10,0],[10,10],[10,10],[20,10]]\n",
    "repeated-middle": "curve:\n  degree: 2\n  control_points: [[0,0],[5,0],[5,0],[5,0],[5,5]]\n",
    "polyline-zero-segments": "curve:\n  degree: 1\n  control_points: [[0,0],[10,0],[10,0],[10,0],[10,10],[0,10],[0,10]]\n",
    "coordinates-1e6": "curve:\n  degree: 2\n  control_points: [[1e6,1e6],[1.00001e6,1.00002e6],[1.00003e6,1e6]]\n",
    "span-2e6": "curve:\n  degree: 2\n  control_points: [[0,0],[1e6,1e6],[2e6,0]]\nprofile: {feedrate: 1e6}\n",
    # the largest weight ratio accepted (1e6); 1e-6 .. 1e6 is refused (test_weight_ratio_beyond_1e6_is_refused)
    "weights-1e-3-to-1e3": "curve:\n  degree: 2\n  control_points: [[0,0],[50,50],[100,0],[150,-50],[200,0]]\n"
                           "  weights: [1e-3, 1e3, 1, 1e3, 1e-3]\n",
    "weights-1e3-to-1e-3": "curve:\n  degree: 3\n  control_points: [[0,0],[50,50],[100,0],[150,-50],[200,0]]\n"
                           "  weights: [1e3, 1e-3, 1, 1e-3, 1e3]\n",
    "knots-1e-15-apart": "curve:\n  degree: 2\n  control_points: [[0,0],[10,10],[20,0],[30,10],[40,0]]\n"
                         "  knots: [0,0,0,0.5,0.500000000000001,1,1,1]\n",
    "domain-3e-15-wide": "curve:\n  degree: 2\n  control_points: [[0,0],[10,10],[20,0],[30,10],[40,0]]\n"
                         "  knots: [0,0,0,1e-15,2e-15,3e-15,3e-15,3e-15]\n",
}


@pytest.mark.parametrize("accdec", ["before", "after"])
@pytest.mark.parametrize("method", ["taylor1", "taylor2", "rk4", "exact"])
@pytest.mark.parametrize("name", list(EDGE_JOBS))
def test_numerical_edge_cases_stay_sane(tmp_path, name, method, accdec):
    """No NaN/inf, u monotone, first/last row on the curve's ends, commands inside the hull (check_plan_output)."""
    job = _job(tmp_path, name, EDGE_JOBS[name])
    res, data = _plan_bin(job, "--interpolator", method, "--accdec", accdec)
    assert len(res.err.splitlines()) >= 5 and "Traceback" not in res.err and not res.warnings
    assert np.isfinite(data).all()
    res = invoke("info", job, "--json")
    assert res.code == 0, str(res)
    check_info_json(res.out)


@pytest.mark.parametrize("weights", ["[1e-6, 1e6, 1, 1e6, 1e-6]", "[1e6, 1e-6, 1, 1e-6, 1e6]", "[1, 1, 1.0000001e6, 1, 1]"])
def test_weight_ratio_beyond_1e6_is_refused(tmp_path, weights):
    """Weights spanning more than 1e6 squeeze part of the path into a sliver of u: refused, naming a weight."""
    job = _job(tmp_path, "w", f"curve:\n  degree: 2\n  control_points: [[0,0],[50,50],[100,0],[150,-50],[200,0]]\n"
                              f"  weights: {weights}\n")
    for command in ("info", "plan"):
        assert_error(invoke(command, job), "curve.weights[", "ratio", named=[job])


def _step_ratios(data):
    """|chord| of each tick over its planned step max(v_k, v_k+1) T (chord <= arc <= planned for an exact run)."""
    step = np.linalg.norm(np.diff(data[:, 3:-2], axis=0), axis=1)  # k, t, u, axes, v, a (check_plan_output's)
    planned = np.maximum(data[:-1, -2], data[1:, -2]) * data[1, 1]
    return step / np.maximum(planned, 1e-300), step, planned


@pytest.mark.parametrize("method", ["taylor2", "rk4", "exact"])
def test_zero_speed_points_take_safe_steps(tmp_path, method):
    """Three equal control points (a whole knot span where P' = 0): the run crosses it without a leap.
    The last tick is left out: a run short of the end snaps to it there (documented; the end gap says how far)."""
    job = _job(tmp_path, "rep", EDGE_JOBS["repeated-middle"])
    _, data = _plan_bin(job, "--interpolator", method, "-q")
    _, step, planned = _step_ratios(data)
    assert np.all(step[:-1] <= planned[:-1] * 1.05 + 1e-9)


def test_taylor1_safe_step_does_not_catch_up_in_one_tick(tmp_path):
    job = _job(tmp_path, "rep", EDGE_JOBS["repeated-middle"])
    _, data = _plan_bin(job, "--interpolator", "taylor1", "-q")
    _, step, planned = _step_ratios(data)
    assert np.all(step[:-1] <= planned[:-1] * 1.05 + 1e-9), f"tick {np.argmax(step[:-1] / planned[:-1])}"


def test_path_shorter_than_the_ramps(tmp_path):
    job = _job(tmp_path, "short", "curve:\n  degree: 1\n  control_points: [[0, 0], [3, 4]]\n"
                                  "profile: {type: bell, feedrate: 100, accel_time: 0.5}\n")
    res = invoke("info", job, "--json")
    facts = check_info_json(res.out)
    assert facts["peak_lowered"] and facts["peak_feedrate"] == pytest.approx(10.0)
    assert facts["motion_time"] == pytest.approx(1.0)
    res, data = _plan_bin(job, "--interpolator", "exact")
    assert "lowered to 10 mm/s" in res.err
    assert data[:, -2].max() == pytest.approx(10.0, abs=1e-9) and data.shape[0] == 1001


@pytest.mark.parametrize("period,ticks", [("5", 2), ("3.641592653589793", 2), ("3.6", 3), ("1e6", 2)])
def test_period_at_least_the_motion_time(period, ticks):
    res, data = _plan_bin(CIRCLE, "--period", period)
    assert data.shape[0] == ticks
    assert np.array_equal(data[-1, 2:7], [1.0, 0.0, 0.0, 0.0, 0.0])  # u = 1, the end point, at rest
    assert data[-1, 1] == float(period) * (ticks - 1)


@needs_exe
def test_one_microsecond_period_on_the_circle(tmp_path):
    """3,641,594 ticks through a real pipe: only the tail is kept (the CSV is ~200 MB)."""
    proc = subprocess.run(f'"{EXE}" plan "{CIRCLE}" --period "1 us" -q | tail -n 3', shell=True,
                          capture_output=True, timeout=HANG_S)
    assert proc.returncode == 0 and proc.stderr == b"", proc.stderr
    *rows, mark = proc.stdout.decode().splitlines()
    assert mark.startswith("# nurbsinterp-end ticks=3641594 curve=")
    before, last = (np.array([float(f) for f in line.split(",")]) for line in rows)
    assert last[0] == 3641593 and last[1] == 0 and last[2] == pytest.approx(3.641593)  # k, n, t
    assert np.array_equal(last[3:], [1, 0, 0, 0, 0])
    assert before[0] == 3641592 and before[3] < 1.0
    res = invoke("plan", CIRCLE, "--period", "1 us", "-q", "--format", "bin", "-o", os.devnull)
    assert res.code == 0 and res.out == b"" and res.err == ""


# =========================================================================== 5. pipes, signals and files


def _bash():
    bash = shutil.which("bash")
    if bash is None:
        pytest.skip("no bash")
    return bash


@needs_exe
@pytest.mark.parametrize("command,reader", [
    (["plan", str(CIRCLE), "--period", "100 us"], "head -1"),
    (["plan", str(CIRCLE), "--format", "bin", "--period", "100 us"], "head -c 100"),
    (["plan", str(CIRCLE), "--accdec", "after", "--period", "100 us", "-q"], "head -1"),
    (["simulate", "--plan", "--job", str(CIRCLE), "--json"], "head -1"),
    (["simulate", "--plan", "--job", str(CIRCLE), "--json"], "true"),  # the reader never reads at all
    (["info", str(CIRCLE)], "head -1"),
])
def test_closed_stdout_exits_quietly(tmp_path, command, reader):
    errfile = tmp_path / "err"
    quoted = " ".join(f"'{a}'" for a in [str(EXE), *command])
    script = f"{quoted} 2>'{errfile}' </dev/null | {reader}; exit \"${{PIPESTATUS[0]}}\""
    proc = subprocess.run([_bash(), "-c", script], capture_output=True, timeout=HANG_S)
    err = errfile.read_text()
    assert proc.returncode in (0, 141), (proc.returncode, err)
    for word in ("Traceback", "BrokenPipe", "Error", "Exception"):
        assert word not in err, err


def _wait_for(predicate, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.05)
    return False


@needs_exe
@pytest.mark.parametrize("sig,status,word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
@pytest.mark.parametrize("existing", [False, True], ids=["new-file", "old-file-kept"])
def test_signal_leaves_no_partial_file(tmp_path, sig, status, word, existing):
    out = tmp_path / "run.csv"
    if existing:
        out.write_text("old contents\n")
    proc = subprocess.Popen([str(EXE), "plan", str(CIRCLE), "--period", "1 us", "--feedrate", "5", "-o", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    try:
        def writing():
            if proc.poll() is not None:  # the run ended on its own: say why (a fresh-clone CI saw its .part vanish)
                raise AssertionError(f"the run ended before the signal, status {proc.returncode}: "
                                     f"{proc.stderr.read().decode(errors='replace')[-2000:]}")
            parts = list(tmp_path.glob(".run.csv.*.part"))
            try:
                return bool(parts) and parts[0].stat().st_size > 0
            except FileNotFoundError:  # removed between the glob and the stat: the next look says why
                return False

        assert _wait_for(writing, HANG_S), "the run never started writing"
        time.sleep(0.3)
        assert proc.poll() is None, "the run ended before the signal"
        proc.send_signal(sig)
        stdout, stderr = proc.communicate(timeout=HANG_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == status, stderr
    assert stdout == b""
    assert stderr.decode() == f"nurbsinterp: {word}\n"
    assert sorted(os.listdir(tmp_path)) == (["run.csv"] if existing else []), "a partial or temporary file was left"
    if existing:
        assert out.read_text() == "old contents\n"


@pytest.mark.parametrize("spelling", ["same", "dot-slash", "symlink", "hardlink", "profile", "servo", "stream"])
def test_output_naming_an_input_is_refused(tmp_path, streams, spelling):
    job = tmp_path / "job.yaml"
    job.write_bytes(CIRCLE.read_bytes())
    profile = tmp_path / "profile.yaml"
    profile.write_text(block(BASE_PROFILE))
    servo = tmp_path / "servo.yaml"
    servo.write_text(block(BASE_SERVO))
    stream = tmp_path / "s.bin"
    stream.write_bytes((streams / "c4.bin").read_bytes())
    if spelling == "symlink":
        (tmp_path / "link.yaml").symlink_to(job)
    elif spelling == "hardlink":
        os.link(job, tmp_path / "link.yaml")
    target = {"same": job, "dot-slash": tmp_path / "." / "job.yaml", "symlink": tmp_path / "link.yaml",
              "hardlink": tmp_path / "link.yaml", "profile": profile, "servo": servo, "stream": stream}[spelling]
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}
    if spelling in ("servo", "stream"):
        res = invoke("simulate", stream, "--job", job, "--servo", servo, "-o", target)
    else:
        res = invoke("plan", job, "--profile", profile, "-o", target)
    assert_error(res, "refusing to overwrite the input file")
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before


@pytest.mark.parametrize("command", ["plan", "simulate-trace", "simulate-plot"])
def test_output_into_a_missing_directory_is_refused_before_any_work(tmp_path, monkeypatch, command):
    import nurbsinterp.interpolate as interpolate  # the CLI imports Interpolation from here when it runs

    def no_work(*a, **k):
        raise AssertionError("work started before the output path was checked")

    monkeypatch.setattr(interpolate, "Interpolation", no_work)
    target = tmp_path / "missing" / ("out.png" if command == "simulate-plot" else "out.file")
    args = {"plan": ["plan", CIRCLE, "-o", target],
            "simulate-trace": ["simulate", "--plan", "--job", CIRCLE, "-o", target],
            "simulate-plot": ["simulate", "--plan", "--job", CIRCLE, "--plot", target]}[command]
    assert_error(invoke(*args), "does not exist", named=[target])
    assert os.listdir(tmp_path) == []


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0, reason="root writes into a mode-500 directory")
def test_output_into_an_unwritable_directory_is_refused(tmp_path):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(stat.S_IRUSR | stat.S_IXUSR)
    try:
        assert_error(invoke("plan", CIRCLE, "-o", locked / "run.csv"), "not writable", named=[locked / "run.csv"])
        assert os.listdir(locked) == []
    finally:
        locked.chmod(stat.S_IRWXU)


@needs_exe
@pytest.mark.parametrize("cut", [100, 1000, 33 + 56 * 17 + 5])
def test_truncated_binary_stream_through_a_real_pipe(streams, cut):
    """`head -c N run.bin | nurbsinterp simulate`: a stream cut short (here inside a record) is exit 2, one line."""
    script = f"head -c {cut} '{streams / 'c4.bin'}' | '{EXE}' simulate --job '{CIRCLE}' --json"
    proc = subprocess.run([_bash(), "-c", script], capture_output=True, timeout=HANG_S)
    assert proc.returncode == 2 and proc.stdout == b"", proc.stderr
    err = proc.stderr.decode()
    assert err.count("\n") == 1 and err.startswith("nurbsinterp: <stdin>: the stream ends after ") \
        and "without its end mark" in err, err


# =========================================================================== 6. the real shell pipe


@needs_exe
def test_plan_piped_into_simulate_in_a_real_shell(tmp_path):
    env = dict(os.environ, PATH=f"{EXE.parent}{os.pathsep}{os.environ.get('PATH', '')}")
    plan_errfile = tmp_path / "plan.err"
    proc = subprocess.run(f"nurbsinterp plan curves/circle.yaml 2>'{plan_errfile}' "
                          "| nurbsinterp simulate --job curves/circle.yaml --json",
                          shell=True, cwd=ROOT, env=env, capture_output=True, timeout=HANG_S)
    # no pipefail: each side is checked by what it wrote
    plan_err = plan_errfile.read_text()
    assert proc.returncode == 0 and proc.stderr == b"", proc.stderr
    assert "ticks            3643" in plan_err and "Traceback" not in plan_err
    report = check_simulate_json(proc.stdout)
    assert report["command_ticks"] == 3643 and report["period"] == pytest.approx(1e-3, abs=1e-12)
    assert 0.17 < report["contour_error_max"] < 0.19  # README: 181.5 um on the paper's circle
    assert report["axes"] == ["x", "y"] and report["settled"] is True


# =========================================================================== regressions found by this battery


@pytest.mark.parametrize("args", [["--period", "1e-320"], ["--feedrate", "1e-320"],
                                  ["--feedrate", "1e308", "--accel-time", "1e308"]], ids=" ".join)
@pytest.mark.parametrize("command", ["info", "plan"])
def test_overflowing_tick_count_is_refused(command, args):
    assert_error(invoke(command, CIRCLE, *args), named=[CIRCLE, args[0]])


@pytest.mark.parametrize("command", ["info", "plan"])
def test_subnormal_accel_time_is_refused(command):
    res = invoke(command, CIRCLE, "--accel-time", "5e-324", "--feedrate", "1e10", "-q" if command == "plan" else "--json")
    assert res.code in (0, 2) and "internal error" not in res.err, str(res)


@pytest.mark.parametrize("args", [["--accel-time", "1e-320"],
                                  ["--profile-type", "exponential", "--time-constant", "1e-320"]], ids=" ".join)
def test_infinite_acceleration_is_refused_before_output(args):
    assert_error(invoke("plan", CIRCLE, *args, "-q"), named=[args[-2]])


@pytest.mark.parametrize("args", [["--feedrate", "1e16", "--accel-time", "0"], ["--period", "1e300"]], ids=" ".join)
def test_csv_too_large_leaves_stdout_empty(args):
    assert_error(invoke("plan", CIRCLE, *args, "-q"), "use --format bin")


HANG_JOBS = {
    "coordinates-1e300": "curve: {degree: 1, control_points: [[0, 0], [1e300, 0]]}\n",
    "weights-1e20": "curve: {degree: 2, control_points: [[0, 0], [10, 10], [20, 0]], weights: [1, 1e20, 1]}\n",
    "weights-1e-300-ends": "curve: {degree: 2, control_points: [[0,0],[10,10],[20,0]], weights: [1e-300, 1, 1e-300]}\n",
    "knot-5e-324": "curve: {degree: 2, control_points: [[0,0],[10,10],[20,0],[30,10]], knots: [0,0,0,5e-324,1,1,1]}\n",
    # found by test_fuzz_valid_random_jobs_give_sane_output: a point with unequal weights
    "zero-length-rational": "curve: {degree: 2, control_points: [[5, 5], [5, 5], [5, 5]], weights: [1, 0.5, 1]}\n",
}
#: adaptive profile + chord tolerance (or normal acceleration) on a curve whose speed vanishes on a span or at
#: its start: these once refined the planner's grid without end (20 GB); now they are stops, and plan
MEMORY_JOBS = {
    "polyline-zero-segment": ("curve: {degree: 1, control_points: [[0, 0], [20, 0], [20, 0], [20, 10], [0, 10]]}\n",
                              ["--chord-tolerance", "1 um"]),
    "repeated-points-normal-accel": ("curve: {degree: 2, control_points: [[0,0],[5,0],[5,0],[5,0],[5,5]]}\n",
                                     ["--max-normal-accel", "500"]),
    "zero-speed-at-the-start": ("curve: {degree: 3, control_points: [[0,0],[0,0],[0,0],[10,0],[10,10],[10,10],[20,10]]}"
                                "\n", ["--max-normal-accel", "500"]),
}
#: adaptive + max_jerk on the circle, with a slow feed or a tiny period: 3e8 ticks, or 3.6e9
SLOW_ADAPTIVE = {"feedrate-1e-3": ["--feedrate", "1e-3"], "period-1ns": ["--period", "1 ns"]}
CAPPED_CPU_S = 120  # CPU seconds per run (each takes ~1 s when it works): a loop without end is killed by SIGXCPU
CAPPED_MEMORY = 1 << 30  # bytes of address space per run (a plain run needs ~0.5 GiB)


def _cap_resources():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (CAPPED_MEMORY, CAPPED_MEMORY))
    resource.setrlimit(resource.RLIMIT_CPU, (CAPPED_CPU_S, CAPPED_CPU_S + 10))


def _run_capped(args):
    """One capped run: (exit status, stdout, stderr); 'cpu limit' if it spent CAPPED_CPU_S, 'hang' if it hung."""
    try:
        proc = subprocess.run([str(EXE), *args], capture_output=True, stdin=subprocess.DEVNULL,
                              preexec_fn=_cap_resources, timeout=HANG_S)
    except subprocess.TimeoutExpired:  # blocked without using CPU: only the wall clock can tell
        return "hang", b"", ""
    if proc.returncode in (-signal.SIGXCPU, -signal.SIGKILL):
        return "cpu limit", proc.stdout, proc.stderr.decode()
    return proc.returncode, proc.stdout, proc.stderr.decode()


@pytest.fixture(scope="module")
def capped_runs(tmp_path_factory):
    """The HANG_JOBS (info) and MEMORY_JOBS (plan) in subprocesses, each with its address space capped (an
    unbounded run would be killed by the OOM killer, or take the machine with it) and its CPU time: a run that
    does not return promptly is one that computes without end, whatever the machine's load.  As many run at once
    as the machine has cores, after one plain run has compiled the kernels.
    {name: (exit status or 'cpu limit' or 'hang', stdout, stderr)}."""
    if not EXE.exists():
        pytest.skip("console script not installed")
    d = tmp_path_factory.mktemp("capped")
    commands = {}
    for name, text in HANG_JOBS.items():
        (d / f"{name}.yaml").write_text(text)
        commands[name] = ["info", str(d / f"{name}.yaml"), "--json"]
    for name, (text, options) in MEMORY_JOBS.items():
        (d / f"{name}.yaml").write_text(text)
        commands[name] = ["plan", str(d / f"{name}.yaml"), "--profile-type", "adaptive", *options, "-q",
                          "--format", "bin", "-o", os.devnull]
    for name, options in SLOW_ADAPTIVE.items():
        commands[name] = ["plan", str(CIRCLE), "--profile-type", "adaptive", "--max-jerk", "30000", *options, "-q",
                          "--format", "bin", "-o", os.devnull]
    # a cold kernel cache is compiled once here, not against the CPU limit of every capped run
    warm = subprocess.run([str(EXE), "plan", str(CIRCLE), "--profile-type", "adaptive", "-o", os.devnull],
                          capture_output=True, stdin=subprocess.DEVNULL, timeout=HANG_S)
    assert warm.returncode == 0, warm.stderr
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=min(len(commands), os.cpu_count() or 1)) as pool:
        results = dict(zip(commands, pool.map(_run_capped, commands.values())))
    return results


def _check_capped(result):
    code, out, err = result
    assert code not in ("hang", "cpu limit"), f"{code}: did not return within {CAPPED_CPU_S} s of CPU time"
    assert code in (0, 2), (code, err)
    assert "Traceback" not in err and "MemoryError" not in err and err.count("\n") <= 1, (code, err)


@pytest.mark.parametrize("name", list(HANG_JOBS))
def test_extreme_geometry_returns_promptly(capped_runs, name):
    _check_capped(capped_runs[name])


@pytest.mark.parametrize("name", list(MEMORY_JOBS))
def test_adaptive_plan_stops_at_a_zero_speed_span(capped_runs, name):
    _check_capped(capped_runs[name])
    assert capped_runs[name][0] == 0, capped_runs[name][2]


@pytest.mark.parametrize("name", list(SLOW_ADAPTIVE))
def test_adaptive_job_is_refused_before_planning(capped_runs, name):
    code, out, err = capped_runs[name]
    _check_capped(capped_runs[name])
    assert code == 2 and "ticks" in err, err


@pytest.mark.parametrize("args", [["--chord-tolerance", "1e-9"], ["--max-normal-accel", "1e-6"]], ids=" ".join)
def test_adaptive_job_over_the_limit_is_refused_before_the_jerk_pass(args):
    """The feed limit, not F, makes these long (~500 s and ~44 000 s on the circle): the refusal comes from the
    acceleration-limited optimum, before the jerk-limited pass would step through the whole motion."""
    err = assert_error(invoke("plan", CIRCLE, "--profile-type", "adaptive", "--max-jerk", "30000", *args,
                              "--max-ticks", "20000", "-q"), "s of motion or more", "--max-ticks", named=[CIRCLE])
    assert "the limit of 2e+04" in err


OVERFLOW_JOBS = {
    "coordinates-1e155": "curve: {degree: 2, control_points: [[0,0],[1e155,1e155],[2e155,0]]}\n",
    "coordinates-pm1e308": "curve: {degree: 1, control_points: [[-1e308, 0], [1e308, 0]]}\n",
    "domain-1e-300": "curve: {degree: 2, control_points: [[0,0],[1,1],[2,0]], knots: [0,0,0,1e-300,1e-300,1e-300]}\n",
    "domain-pm1e308": "curve: {degree: 2, control_points: [[0,0],[1,1],[2,0]], "
                      "knots: [-1e308,-1e308,-1e308,1e308,1e308,1e308]}\n",
    "domain-5e-324": "curve: {degree: 2, control_points: [[0,0],[10,10],[20,0]], knots: [0,0,0,5e-324,5e-324,5e-324]}\n",
    "domain-1e200": "curve: {degree: 2, control_points: [[0,0],[10,10],[20,0]], knots: [0,0,0,1e200,1e200,1e200]}\n",
}


@pytest.mark.parametrize("name", list(OVERFLOW_JOBS))
def test_extreme_geometry_is_refused_without_overflow(tmp_path, name):
    job = _job(tmp_path, name, OVERFLOW_JOBS[name])
    res = invoke("info", job, "--json")
    if assert_0_or_2(res, named=[job]):
        check_info_json(res.out)
        assert not res.warnings, str(res)


@pytest.mark.parametrize("method", ["taylor2", "exact"])
@pytest.mark.parametrize("name", ["domain-ulps", "weights-1e-6-to-1e6"])
def test_unresolvable_parametrisation_is_refused(tmp_path, name, method):
    text = {"domain-ulps": "curve:\n  degree: 2\n  control_points: [[0,0],[10,10],[20,0]]\n"
                           "  knots: [1,1,1,1.000000000000001,1.000000000000001,1.000000000000001]\n",
            "weights-1e-6-to-1e6": "curve:\n  degree: 2\n  control_points: [[0,0],[50,50],[100,0],[150,-50],[200,0]]\n"
                                   "  weights: [1e-6, 1e6, 1, 1e6, 1e-6]\n"}[name]
    job = _job(tmp_path, name, text)
    res = invoke("plan", job, "--interpolator", method, "--format", "bin", "-q")
    if res.code == 2:
        assert_error(res, named=[job])
        return
    _, data = parse_bin(res.out)
    ratio, _, _ = _step_ratios(data)
    assert np.all(ratio <= 1.5), f"tick {np.argmax(ratio)} moves {ratio.max():.3g}x its planned step"


SERVO_OVERFLOWS = {
    "fast-unstable-pole": ("319514.874", "1, -177282.0, 1649.133, 342115.44"),  # found by the servo fuzzer
    "num-1e300": ("1e300", "1, 601.677, 113727.10"),
    "den0-1e-300": ("112570.543", "1e-300, 601.677, 113727.10"),
    "den-badly-conditioned": ("1", "1e300, 1e-300, 1e-300"),
}


@pytest.mark.parametrize("name", list(SERVO_OVERFLOWS))
def test_extreme_servo_plant_is_refused(tmp_path, streams, name):
    num, den = SERVO_OVERFLOWS[name]
    servo = tmp_path / "servo.yaml"
    servo.write_text(f"axes:\n  x: {{plant: {{num: [{num}], den: [{den}]}}, kp: 40, kv: 0.6}}\n"
                     "  y: {plant: {num: [319514.874], den: [1, 1649.133, 342115.44]}, kp: 70, kv: 0.6}\n")
    res = invoke("simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", servo, "--json")
    assert_error(res, named=[servo])


def test_huge_command_in_a_stream_is_refused(tmp_path, streams):
    head, _, body = (streams / "c4.bin").read_bytes().partition(b"\n")
    data = np.frombuffer(body[:-64], "<f8").reshape(-1, 8).copy()
    data[300, 4] = 1e300  # x
    path = tmp_path / "huge.bin"
    path.write_bytes(head + b"\n" + data.tobytes() + body[-64:])  # whole: its end mark as plan wrote it
    res = invoke("simulate", path, "--job", CIRCLE, "--json")
    if assert_0_or_2(res, named=[path]):
        check_simulate_json(res.out)
        assert not res.warnings, str(res)


@pytest.mark.parametrize("command", ["compare", "bench"])
def test_compare_and_bench_name_no_option_they_lack(command):
    err = assert_error(invoke(command, CIRCLE, "--period", "1 ns"), "ticks")
    assert "--max-ticks" not in err


@pytest.mark.parametrize("where", ["degree", "coordinate", "servo-kp"])
def test_integer_literal_over_4300_digits(tmp_path, streams, where):
    big = "9" * 5000
    path = tmp_path / "big.yaml"
    if where == "servo-kp":
        path.write_text(f"axes:\n  x: {{plant: {{num: [1], den: [1, 1]}}, kp: {big}, kv: 0}}\n"
                        "  y: {plant: {num: [1], den: [1, 1]}, kp: 1, kv: 0}\n")
        res = invoke("simulate", streams / "c4.bin", "--job", CIRCLE, "--servo", path)
    else:
        path.write_text(f"curve: {{degree: {big}}}\n" if where == "degree" else
                        f"curve: {{degree: 1, control_points: [[0, {big}], [1, 1]]}}\n")
        res = invoke("info", path)
    assert_error(res, named=[path])


JERK_PASS_FAILURES = {
    # a valid 35 s motion: the step budget 4 L / min(feed cap) / dt + 1e5 ignores the acceleration limit
    "circle-accel-1-jerk-1e5": (None, ["--max-accel", "1", "--max-jerk", "1e5"]),
    "circle-jerk-1e-3": (None, ["--max-jerk", "1e-3"]),
    # found by test_fuzz_valid_random_jobs_give_sane_output: a 1 mm line at a coarse period
    "1mm-line-T-20ms": ("curve: {degree: 1, control_points: [[0, 0], [1, 0]]}\n",
                        ["--feedrate", "10", "--accel-time", "0", "--max-jerk", "2474", "--period", "20 ms"]),
    "1mm-line-T-20ms-J-30000": ("curve: {degree: 1, control_points: [[0, 0], [1, 0]]}\n",
                                ["--feedrate", "10", "--accel-time", "0", "--max-jerk", "30000", "--period", "20 ms"]),
}


@pytest.mark.parametrize("name", list(JERK_PASS_FAILURES))
def test_adaptive_jerk_pass_finishes_every_section(tmp_path, name):
    text, options = JERK_PASS_FAILURES[name]
    job = CIRCLE if text is None else _job(tmp_path, "line", text)
    res = invoke("plan", job, "--profile-type", "adaptive", *options, "-q", "--format", "bin")
    assert "jerk-limited pass" not in res.err, str(res)
    if assert_0_or_2(res, named=[job]):
        check_plan_output(res.out, job)


ADAPTIVE_REFUSALS = {
    "no-acceleration-limit": ("curve: {degree: 2, control_points: [[0, 0], [10, 10], [20, 0]]}\n",
                              ["--profile-type", "adaptive", "--accel-time", "0"]),
    "cusp-inside-a-span": ("curve: {degree: 2, control_points: [[0, 0], [10, 0], [0, 0]]}\n",
                           ["--profile-type", "adaptive", "--chord-tolerance", "1 um"]),
}


@pytest.mark.parametrize("name", list(ADAPTIVE_REFUSALS))
def test_adaptive_refusals_name_the_file(tmp_path, name):
    text, options = ADAPTIVE_REFUSALS[name]
    job = _job(tmp_path, name, text)
    assert_error(invoke("plan", job, *options, "-q"), named=[job])


def test_a_jerk_limited_motion_of_millennia_is_refused_in_one_line(tmp_path):
    """The fuzz's find (test_fuzz_profile_file_mutations): an adaptive job with a jerk limit and a period of
    3.09e9 s, whose 1 um chord tolerance caps the feed at some 1e-10 mm/s -- a motion of 4.9e14 s.  The
    jerk-limited pass stalled on it (exit 1, "did not reach the end of the section"); it is refused, naming the
    motion time and the period (the same job at T = 1 ms plans)."""
    profile = tmp_path / "profile.yaml"
    profile.write_text(
        'profile: {"type": "adaptive", "feedrate": "100 mm/s", "chord_tolerance": "1 um", "max_accel": "1000 mm/s^2",'
        ' "max_jerk": "30000 mm/s^3", "max_normal_accel": 2000, "accdec": "before"}\n'
        'interpolator: {"method": "exact", "period": 3093763880.0}\n')
    out = tmp_path / "c.csv"
    err = assert_error(invoke("plan", CIRCLE, "--profile", profile, "-o", out), "the motion would take 4.86e+14 s",
                       "interpolator.period (3.09376e+09 s)")
    assert not out.exists(), err
    assert invoke("info", CIRCLE, "--profile", profile, "--period", "1ms").code == 0
