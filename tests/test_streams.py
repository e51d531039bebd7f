"""Command streams: CSV and binary writers and readers, atomic output files.

The CSV formatter is checked against Python's own correctly rounded formatting
(``f"{x:.{d}f}"`` with trailing zeros stripped), and byte for byte against a
naive oracle of its rule in exact rational arithmetic; the binary stream must
carry the float64 values bit for bit.
"""
from __future__ import annotations

import io
import math
import os
import stat
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from budgets import budgets

from nurbsinterp import streams
from nurbsinterp.errors import NurbsInterpError, StreamError, UsageError
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.config import load_job
from nurbsinterp.cli.common import load_cli
from nurbsinterp.streams import (MAX_DECIMALS, StreamWriter, check_output_path, column_decimals, format_rows,
                                 open_output, read_stream)

CURVES = Path(__file__).resolve().parent.parent / "curves"
CIRCLE_YAML = CURVES / "circle.yaml"
COLUMNS = ["k", "t", "u", "x", "y", "v", "a"]
MAX_EXACT = 9.0e15


def run_data(path, **overrides):
    run = Interpolation(load_cli(path, overrides=overrides))
    return run.columns, np.vstack([c.data for c in run.chunks()])


@pytest.fixture(scope="module")
def circle_data():
    return run_data(CIRCLE_YAML)


@pytest.fixture(scope="module")
def tilted_data():
    return run_data(CURVES / "tilted-circle-3d.yaml")


def py_format(x: float, d: int) -> str:
    """The documented format: d decimals (fewer only where |x|·10^d would reach 9e15), trailing zeros
    dropped, correctly rounded as Python rounds; a zero is printed unsigned."""
    while d > 0 and abs(x) * 10.0 ** d >= MAX_EXACT:
        d -= 1
    s = f"{x:.{d}f}"
    if "." in s:
        s = s.rstrip("0").rstrip(".")
    return "0" if s == "-0" else s


def kernel_format(values, d):
    """format_rows of one column; with the largest limit, so that integers from 9e15 up print too."""
    data = np.ascontiguousarray(np.asarray(values, dtype=float).reshape(-1, 1))
    buf = np.empty(data.size * 32 + 16, dtype=np.uint8)
    n = format_rows(data, np.array([d], dtype=np.int64), buf, 2.0 ** 63)
    assert n >= 0, f"row {-1 - n} refused"
    return bytes(buf[:n]).decode().split("\n")[:-1]


def write(data, columns, fmt, finish=True):
    """The stream of *data* as plan writes it: in chunks, then (unless not *finish*) its end mark."""
    fh = io.BytesIO()
    w = StreamWriter(fh, columns, fmt)
    for i in range(0, data.shape[0], 1000):  # several writes, as plan does with chunks
        w.write(data[i:i + 1000])
    if finish:
        w.finish()
    return fh.getvalue()


def tolerance(columns, values):
    """Half a unit of the last printed decimal, plus the rounding of the value and of the reader."""
    d = column_decimals(columns).astype(float)
    return 0.5 * 10.0 ** -d + 4 * np.finfo(float).eps * np.abs(values)


# =========================================================================== writing


def test_binary_header_and_exact_records(circle_data):
    columns, data = circle_data
    raw = write(data, columns, "bin")
    head, _, body = raw.partition(b"\n")
    assert head == b"nurbsinterp-bin 2 k,n,t,u,x,y,v,a"
    assert len(body) == data.size * 8 + 64
    assert body[:-64] == data.astype("<f8").tobytes()
    assert body[-64:] == b"nurbsinterp-end ticks=%d" % data.shape[0] + b" " * (63 - 22 - len(str(data.shape[0]))) \
        + b"\n"


def test_binary_reader_one_liner_from_the_docstring(circle_data, tmp_path):
    columns, data = circle_data
    path = tmp_path / "run.bin"
    path.write_bytes(write(data, columns, "bin"))
    line = next(x.strip() for x in streams.__doc__.splitlines() if "np.frombuffer" in x)
    assert '"run.bin"' in line
    scope = {"np": np}
    exec(line.replace('"run.bin"', repr(str(path))), scope)  # noqa: S102 - the documented reader itself
    assert scope["data"].dtype == np.dtype("<f8")
    assert np.array_equal(scope["data"], data)


@pytest.mark.parametrize("which", ["circle_data", "tilted_data"])
def test_csv_carries_the_binary_numbers_to_its_decimals(which, request):
    columns, data = request.getfixturevalue(which)
    text = write(data, columns, "csv", finish=False).decode("ascii")
    lines = text.splitlines()
    assert lines[0] == ",".join(columns)
    assert len(lines) == data.shape[0] + 1
    parsed = np.array([[float(f) for f in line.split(",")] for line in lines[1:]])
    assert parsed.shape == data.shape
    assert np.array_equal(parsed[:, 0], data[:, 0])  # k: integers
    assert (np.abs(parsed - data) <= tolerance(columns, data)).all()
    # the decimals really are 9 (t, positions, v, a) and 15 (u): no coarser
    frac = [len(f.partition(".")[2]) for line in lines[1:] for f in line.split(",")]
    assert max(frac) == 15
    assert max(len(line.split(",")[1].partition(".")[2]) for line in lines[1:]) <= 9


def test_writer_refuses_non_finite_values():
    for bad in (np.nan, np.inf, -np.inf):
        data = np.zeros((3, 7))
        data[:, 0] = [0, 1, 2]
        data[1, 4] = bad
        for fmt in ("csv", "bin"):
            with pytest.raises(NurbsInterpError, match="k = 1"):
                StreamWriter(io.BytesIO(), COLUMNS, fmt).write(data)


def test_writer_rejects_unknown_format():
    with pytest.raises(ValueError):
        StreamWriter(io.BytesIO(), COLUMNS, "xml")


# --------------------------------------------------------------------------- format_rows


EXPLICIT = [
    # (value, decimals, text)
    (0.0, 9, "0"), (-0.0, 9, "0"), (1.0, 9, "1"), (-1.0, 9, "-1"), (0.5, 9, "0.5"), (-0.25, 15, "-0.25"),
    (123.25, 9, "123.25"), (1e6, 9, "1000000"), (-1e6, 9, "-1000000"), (1e6 + 0.125, 9, "1000000.125"),
    (3.0, 0, "3"), (12345.0, 0, "12345"),
    (1e-10, 9, "0"), (-1e-10, 9, "0"), (-4e-10, 9, "0"), (6e-10, 9, "0.000000001"), (-6e-10, 9, "-0.000000001"),
    (1e-10, 15, "0.0000000001"), (-1e-16, 15, "0"), (1e-15, 15, "0.000000000000001"),
    (0.1, 9, "0.1"), (0.1, 15, "0.1"), (2.0 / 3.0, 15, "0.666666666666667"), (-2.0 / 3.0, 9, "-0.666666667"),
    (314.159265358979, 9, "314.159265359"), (3.641592653589793, 9, "3.641592654"),
    (9.0, 15, "9"), (12.3, 15, "12.3"),  # 12.3e15 >= 9e15: 14 decimals, as documented
    (123456789.123456789, 9, "123456789.1234568"),  # 7 decimals: |x|·10^d < 9e15
    (9.2e15, 9, "9200000000000000"), (-1.5e17, 9, "-150000000000000000"), (2.0 ** 62, 9, str(2 ** 62)),
]


@pytest.mark.parametrize("value,decimals,text", EXPLICIT, ids=[f"{v!r}@{d}" for v, d, _ in EXPLICIT])
def test_format_rows_explicit_values(value, decimals, text):
    assert kernel_format([value], decimals) == [text]
    assert py_format(value, decimals) == text  # the reference agrees


def _random_values(seed=0):
    rng = np.random.default_rng(seed)
    n = 4000
    return np.concatenate([
        rng.uniform(-1.0, 1.0, n),  # u-like, signed
        rng.uniform(-400.0, 400.0, n),  # positions, mm
        rng.uniform(-1.0, 1.0, n) * 10.0 ** rng.integers(-16, -6, n),  # tiny, both signs
        rng.uniform(-1e6, 1e6, n),  # large
        rng.integers(-10 ** 6, 10 ** 6, n) * 1e-3,  # exact-looking decimals (t = k·T)
        [0.0, -0.0, 1e6, -1e6, 5e-10, -5e-10],
    ])


@pytest.mark.parametrize("decimals", [9, 15])
def test_format_rows_round_trips_within_half_a_unit(decimals):
    values = _random_values(1)
    out = kernel_format(values, decimals)
    back = np.array([float(s) for s in out])
    d = np.array([len(py_format(x, decimals).partition(".")[2]) if abs(x) * 10.0 ** decimals >= MAX_EXACT
                  else decimals for x in values])
    assert (np.abs(back - values) <= 0.5 * 10.0 ** -d + 4 * np.finfo(float).eps * np.abs(values)).all()
    assert not any(s.startswith("-0") and float(s) == 0 for s in out)  # no "-0"
    assert all(s == s.strip() and s and not s.endswith(".") and (("." not in s) or not s.endswith("0"))
               for s in out)


@pytest.mark.parametrize("decimals", [9, 15])
def test_format_rows_matches_python_formatting(decimals):
    values = _random_values(0)
    out = kernel_format(values, decimals)
    bad = [(x, s, py_format(x, decimals)) for x, s in zip(values, out) if s != py_format(x, decimals)]
    assert not bad, f"{len(bad)} of {len(values)} differ, e.g. {bad[:3]}"


@pytest.mark.parametrize("value", [9e15, 1e19, -1e21])
def test_csv_writer_refuses_values_beyond_exact_integers(value):
    """format_rows needs |x| < 9e15 (exact integers of units); the writer refuses larger values, naming them."""
    import io

    from nurbsinterp.errors import UsageError
    from nurbsinterp.streams import StreamWriter

    writer = StreamWriter(io.BytesIO(), ["k", "t", "u", "x", "y", "v", "a"], "csv")
    with pytest.raises(UsageError, match=r"k = 3: a = .* too large for the CSV writer"):
        writer.write(np.array([[3, 0.003, 0.5, 1.0, 2.0, 3.0, value]]))
    StreamWriter(io.BytesIO(), ["k", "t", "u", "x", "y", "v", "a"], "bin").write(
        np.array([[3, 0.003, 0.5, 1.0, 2.0, 3.0, value]]))  # binary carries any finite value


# --------------------------------------------------------------------------- format_rows against a naive oracle
#
# format_rows is written for speed (issue 16: at most 100 ns for a tick of 8 columns).  Its rule is
# restated here as plainly as it can be said, with exact rational arithmetic one value at a time, and
# the kernel must print what this oracle prints, byte for byte, where printing is hardest: exact ties,
# one ulp either side of them, the edges where a value loses decimals, zeros and values that round to
# zero, integers near 2**53.  The oracle was checked against the kernel before its rewrite, so it
# holds the output as it was.

# every count of decimals format_rows takes; the columns have 0 (k, n), 9 (t, x, y, v, a) and 15 (u)
ALL_DECIMALS = list(range(MAX_DECIMALS + 1))


def oracle_format(x: float, d: int) -> str:
    """*x* as the CSV writer prints it with *d* decimals: the rule spelt out, one value at a time.

    The decimals are d, fewer while |x|·10^d, the float64 product as the kernel computes it, is
    at least 9e15.  The exact value of |x|·10^d is rounded to an integer number of units, ties to
    even (where no decimal is left, |x| ≥ 9e15 is an integer and stays as it is).  The units are
    printed with the point d digits from the right and at least one digit before it, trailing
    zeros of the fraction and a bare point dropped, and a '-' only where the units are not zero:
    -0.0, and -4e-10 at 9 decimals, print "0".
    """
    ax = abs(x)
    while d > 0 and ax * float(10 ** d) >= MAX_EXACT:
        d -= 1
    units = round(Fraction(ax) * 10 ** d)  # Fraction(ax) is ax exactly; round() of a Fraction: half to even
    digits = str(units).rjust(d + 1, "0")
    whole, fraction = (digits[:-d], digits[-d:].rstrip("0")) if d else (digits, "")
    return ("-" if x < 0 and units else "") + whole + ("." + fraction if fraction else "")


def assert_kernel_matches_oracle(values, d):
    values = np.asarray(values, dtype=float)
    got = kernel_format(values, d)
    want = [oracle_format(float(x), d) for x in values]
    bad = [(float(x).hex(), g, w) for x, g, w in zip(values, got, want) if g != w]
    assert not bad, f"{len(bad)} of {len(values)} values differ at {d} decimals, e.g. (x, kernel, oracle) {bad[:3]}"


def around(values, ulps=1):
    """*values* and their neighbours up to *ulps* floats away on either side."""
    values = np.asarray(values, dtype=float)
    out = [values]
    up = down = values
    for _ in range(ulps):
        up, down = np.nextafter(up, np.inf), np.nextafter(down, -np.inf)
        out += [up, down]
    return np.concatenate(out)


def exact_ties(rng, d, count=200):
    """Floats x with x·10^d exactly k + 1/2: x = m / 2^(d+1) with m odd (x·10^d = m·5^d / 2).

    Small m, and random odd m up to where x·10^d would reach 9e15.
    """
    largest = min(2 ** 53, int(2 * MAX_EXACT) // 5 ** d)
    m = np.concatenate([np.arange(1, 2 * count, 2), 2 * rng.integers(0, largest // 2, count) + 1])
    return m.astype(float) / 2.0 ** (d + 1)


def decimal_ties(rng, d, count=200):
    """The floats nearest to decimal ties k.5·10^-d (not exact: each lies a little above or below)."""
    k = np.concatenate([np.arange(count), rng.integers(0, 10 ** 15, count)])
    return np.array([float(f"{kk}5e-{d + 1}") for kk in k])


def test_oracle_explicit_values():
    """The oracle is right where the answer is known by hand."""
    for value, decimals, text in EXPLICIT:
        assert oracle_format(value, decimals) == text, (value, decimals)


@pytest.mark.parametrize("decimals", ALL_DECIMALS)
def test_format_rows_oracle_magnitudes(decimals):
    """Seeded values of both signs, log-uniform over 1e-12 … 8e15 (and a tenth of them whole numbers)."""
    rng = np.random.default_rng(100 + decimals)
    values = rng.choice([-1.0, 1.0], 4000) * 10.0 ** rng.uniform(-12.0, math.log10(8e15), 4000)
    assert_kernel_matches_oracle(np.concatenate([values, np.round(values[:400])]), decimals)


@pytest.mark.parametrize("decimals", ALL_DECIMALS)
def test_format_rows_oracle_ties(decimals):
    """Exact ties and the floats one ulp either side, for every count of decimals (so also ties at the
    decimals a large value is cut to), and the floats nearest to decimal ties."""
    rng = np.random.default_rng(200 + decimals)
    ties = np.concatenate([exact_ties(rng, d, 50) for d in ALL_DECIMALS] + [exact_ties(rng, decimals)])
    near = decimal_ties(rng, decimals)
    values = around(np.concatenate([ties, near]))
    assert_kernel_matches_oracle(np.concatenate([values, -values]), decimals)


@pytest.mark.parametrize("decimals", ALL_DECIMALS)
def test_format_rows_oracle_where_decimals_are_dropped(decimals):
    """Around 9e15 / 10^e, where a value loses its e-th decimal, three ulps either side; and the
    integers near 2**53 and 9e15, which keep no decimal at all."""
    edges = around([MAX_EXACT / 10.0 ** e for e in range(17)], ulps=3)
    integers = np.concatenate([MAX_EXACT - np.arange(1, 6), 2.0 ** 53 - np.arange(0, 6), 2.0 ** 53 + 2 * np.arange(3),
                               2.0 ** 52 + np.arange(-3, 4), [MAX_EXACT, 9.2e15, 1e16, 2.0 ** 62, 2.0 ** 63 - 1024]])
    values = np.concatenate([edges, integers])
    assert_kernel_matches_oracle(np.concatenate([values, -values]), decimals)


@pytest.mark.parametrize("decimals", ALL_DECIMALS)
def test_format_rows_oracle_zeros(decimals):
    """0.0 and -0.0, values that round to zero (no "-0"), the smallest that do not, subnormals."""
    rng = np.random.default_rng(300 + decimals)
    unit = 10.0 ** -decimals
    values = np.concatenate([
        [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, -1e-300, 0.5 * unit, -0.5 * unit],
        around([0.5 * unit, -0.5 * unit, unit, -unit], ulps=2),
        -rng.uniform(0.0, 0.5, 500) * unit,
        -rng.uniform(0.5, 1.5, 500) * unit,
    ])
    assert_kernel_matches_oracle(values, decimals)


@budgets(quick=100, full=400)
def test_format_rows_oracle_property(budget):
    """Any float the writer accepts, at any count of decimals."""
    @settings(max_examples=budget)
    @given(x=st.floats(min_value=-MAX_EXACT, max_value=MAX_EXACT, exclude_min=True, exclude_max=True),
           decimals=st.integers(0, MAX_DECIMALS))
    def check(x, decimals):
        assert kernel_format([x], decimals) == [oracle_format(x, decimals)]

    check()


def plan_like_rows(rng, m):
    """m rows shaped like a plan chunk: k, n, t, u, x, y, v, a (k counting, t = k·1 µs, u in [0, 1])."""
    k = np.arange(m, dtype=float) + rng.integers(0, 10 ** 7)
    return np.column_stack([k, rng.integers(0, 40, m).astype(float), k * 1e-6, rng.uniform(0.0, 1.0, m),
                            rng.uniform(-400.0, 400.0, (m, 2)), rng.uniform(0.0, 200.0, m),
                            rng.uniform(-2e3, 2e3, m)])


def test_format_rows_oracle_rows():
    """Whole rows: the columns' own decimals, commas between values, a newline after each row, across
    the chunks of a writer that reuses its buffer."""
    rng = np.random.default_rng(400)
    columns = ["k", "n", "t", "u", "x", "y", "v", "a"]
    data = plan_like_rows(rng, 3000)
    data[::7, 2:] *= rng.choice([-1.0, 1.0], (len(data[::7]), 6)) * 10.0 ** rng.integers(-12, 6, (len(data[::7]), 6))
    data[5, 4:] = [-0.0, 0.0, -1e-10, 4.5e-10]
    decimals = column_decimals(columns)
    want = "".join(",".join(oracle_format(float(x), int(d)) for x, d in zip(row, decimals)) + "\n" for row in data)
    fh = io.BytesIO()
    writer = StreamWriter(fh, columns, "csv")
    for lo, hi in [(0, 1), (1, 1000), (1000, 1001), (1001, 3000)]:  # chunks of changing size
        writer.write(data[lo:hi])
    assert fh.getvalue().decode("ascii") == ",".join(columns) + "\n" + want


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, MAX_EXACT, -MAX_EXACT, 1e300])
def test_format_rows_refuses_the_first_row_it_cannot_print(bad):
    """Not finite, or not below the limit: format_rows returns -1 - r for the first such row r."""
    data = np.ones((5, 3))
    data[3, 1] = bad
    data[4, 0] = np.nan
    decimals = np.array([0, 9, 15], dtype=np.int64)
    buf = np.empty(32 * data.size + 16, dtype=np.uint8)
    assert format_rows(data, decimals, buf, MAX_EXACT) == -1 - 3
    if math.isfinite(bad) and abs(bad) < 2.0 ** 63:  # the largest limit: integers from 9e15 up print
        assert format_rows(data[:4], decimals, buf, 2.0 ** 63) > 0
    below = np.array([[np.nextafter(MAX_EXACT, 0.0), -np.nextafter(MAX_EXACT, 0.0), 0.0]])
    n = format_rows(below, decimals, buf, MAX_EXACT)
    assert bytes(buf[:n]) == b"8999999999999999,-8999999999999999,0\n"


def test_format_rows_refuses_bad_arguments():
    data = np.ones((2, 3))
    decimals = np.array([0, 9, 15], dtype=np.int64)
    buf = np.empty(32 * data.size + 16, dtype=np.uint8)
    for bad_decimals in (np.array([0, 9], dtype=np.int64), np.array([0, 9, 17], dtype=np.int64),
                         np.array([0, -1, 9], dtype=np.int64)):
        with pytest.raises(ValueError, match="decimals"):
            format_rows(data, bad_decimals, buf, MAX_EXACT)
    with pytest.raises(ValueError, match="buf"):
        format_rows(data, decimals, buf[:-1], MAX_EXACT)
    for limit in (1e3, 2.0 ** 64):
        with pytest.raises(ValueError, match="limit"):
            format_rows(data, decimals, buf, limit)


def test_csv_writer_refusals_as_before():
    """The kernel finds what the writer refuses in its formatting pass; the messages, which refusal
    wins (a value not finite anywhere in the chunk, before a large one), and an output untouched by
    the refused chunk (not even the header, if it is the first) are as they were before it did."""
    columns = ["k", "n", "t", "u", "x", "y", "v", "a"]
    data = plan_like_rows(np.random.default_rng(500), 40)
    bad = data[20:].copy()
    bad[3, 6] = 1.5e16  # v too large, first in the chunk ...
    bad[10, 4] = np.nan  # ... and x not a number, later in it
    fh = io.BytesIO()
    writer = StreamWriter(fh, columns, "csv", too_large_hint="; write --format bin")
    with pytest.raises(NurbsInterpError) as info:
        writer.write(bad)
    assert type(info.value) is NurbsInterpError
    assert str(info.value) == f"refusing to write a non-finite value (tick k = {bad[10, 0]:.0f})"
    assert fh.getvalue() == b""
    writer.write(data[:20])
    before = fh.getvalue()
    bad[10, 4] = 1.0
    with pytest.raises(UsageError) as info:
        writer.write(bad)
    assert str(info.value) == (f"tick k = {bad[3, 0]:.0f}: v = 1.5e+16 is too large for the CSV writer "
                               "(|value| < 9e15); write --format bin")
    assert fh.getvalue() == before
    bad[3, 6] = -MAX_EXACT  # the bound itself, negative
    with pytest.raises(UsageError, match=r"v = -9e\+15 is too large"):
        writer.write(bad)
    assert fh.getvalue() == before


# =========================================================================== reading


@pytest.mark.parametrize("chunk_rows", [5, 1 << 16])
@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_read_stream_round_trip(circle_data, fmt, chunk_rows):
    columns, data = circle_data
    raw = write(data, columns, fmt)
    cols, pieces = read_stream(io.BytesIO(raw), "run", chunk_rows=chunk_rows)
    assert cols == columns
    back = np.vstack(list(pieces))
    assert back.dtype == np.float64 and back.shape == data.shape
    if fmt == "bin":
        assert np.array_equal(back, data)
    else:
        assert (np.abs(back - data) <= tolerance(columns, data)).all()


def test_read_stream_3d(tilted_data):
    columns, data = tilted_data
    for fmt in ("csv", "bin"):
        cols, pieces = read_stream(io.BytesIO(write(data, columns, fmt)), "run")
        assert cols == ["k", "n", "t", "u", "x", "y", "z", "v", "a"]
        assert np.vstack(list(pieces)).shape == data.shape


class Trickle(io.RawIOBase):
    """A pipe that delivers at most a few bytes per read."""

    def __init__(self, data, size=5):
        self.data, self.pos, self.size = data, 0, size

    def readable(self):
        return True

    def readinto(self, b):
        n = min(len(b), self.size, len(self.data) - self.pos)
        b[:n] = self.data[self.pos:self.pos + n]
        self.pos += n
        return n


def test_binary_reader_tops_up_short_reads(circle_data):
    columns, data = circle_data
    raw = write(data[:200], columns, "bin")
    cols, pieces = read_stream(Trickle(raw, 13), "pipe", chunk_rows=7)
    assert np.array_equal(np.vstack(list(pieces)), data[:200])
    with pytest.raises(StreamError, match=r"without its end mark"):
        list(read_stream(Trickle(raw[:-3], 13), "pipe", chunk_rows=7)[1])
    with pytest.raises(StreamError, match=r"record 199 is truncated \(61 of 64 bytes\) before the end mark"):
        list(read_stream(Trickle(raw[:-67] + raw[-64:], 13), "pipe", chunk_rows=7)[1])


HEADER = b"k,t,u,x,y,v,a\n"
ROW0 = b"0,0,0,0,0,0,0\n"
BIN_HEADER = b"nurbsinterp-bin 2 k,t,u,x,y,v,a\n"


def rec(*rows):
    """Binary records of *rows*, then the end mark for as many ticks."""
    return np.array(rows, dtype="<f8").tobytes() + end_mark(len(rows))


def end_mark(ticks):
    return (b"nurbsinterp-end ticks=%d" % ticks).ljust(63) + b"\n"


BAD_STREAMS = {
    "empty": (b"", r"no commands arrived \(the stream is empty\): the command upstream may have failed"),
    "truncated-binary": (BIN_HEADER + rec([0, 0, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, 0, 0])[:-64] + b"\0" * 20
                         + end_mark(2), r"record 2 is truncated \(20 of 56 bytes\)"),
    "binary-version": (b"nurbsinterp-bin 3 k,t,u,x,y,v,a\n" + rec([0, 0, 0, 0, 0, 0, 0]), r"nurbsinterp-bin 3"),
    "binary-version-1": (b"nurbsinterp-bin 1 k,t,u,x,y,v,a\n" + rec([0, 0, 0, 0, 0, 0, 0])[:-64],
                         r"version 1 binary stream has no end mark"),
    "binary-no-columns": (b"nurbsinterp-bin 2\n", r"header"),
    "binary-missing-column": (b"nurbsinterp-bin 2 k,t,u,x,y,v\n" + rec([0, 0, 0, 0, 0, 0]), r"no column 'a'"),
    "binary-nan": (BIN_HEADER + rec([0, 0, 0, 0, 0, 0, 0], [1, 1, 0, np.nan, 0, 0, 0]), r"record 1: column x"),
    "binary-inf": (BIN_HEADER + rec([0, 0, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, np.inf, 0]), r"record 1: column v"),
    "binary-time": (BIN_HEADER + rec([0, 0, 0, 0, 0, 0, 0], [1, 1, 0, 0, 0, 0, 0], [2, 1, 0, 0, 0, 0, 0]),
                    r"record 2: time"),
    "csv-missing-column": (b"k,t,u,x,y,a\n0,0,0,0,0,0\n", r"no column 'v'"),
    "csv-wrong-names": (b"time,x,y\n0,0,0\n", r"no column 'k'"),
    "csv-extra-field": (HEADER + ROW0 + b"1,0.001,0.1,1,2,3,4,5\n", r"line 3 has 8 fields, the header has 7"),
    "csv-missing-field": (HEADER + ROW0 + b"1,0.001,0.1,1,2,3\n", r"line 3 has 6 fields, the header has 7"),
    "csv-non-numeric": (HEADER + ROW0 + b"1,0.001,zero,1,2,3,4\n", r"line 3: .*zero.* is not a number"),
    "csv-empty-field": (HEADER + ROW0 + b"1,0.001,,1,2,3,4\n", r"line 3"),
    "csv-nan": (HEADER + ROW0 + b"1,0.001,nan,1,2,3,4\n", r"line 3: column u = nan is not a finite number"),
    "csv-inf": (HEADER + ROW0 + b"1,0.001,0.1,-inf,2,3,4\n", r"line 3: column x"),
    "csv-time-equal": (HEADER + ROW0 + b"1,0.001,0,0,0,0,0\n2,0.001,0,0,0,0,0\n", r"line 4: time"),
    "csv-time-back": (HEADER + ROW0 + b"1,0.002,0,0,0,0,0\n2,0.001,0,0,0,0,0\n", r"line 4: time"),
    "not-a-stream": (b"\x89PNG\r\n\x1a\n\0\0", r"not a nurbsinterp command stream"),
    "no-newline-header": (b"k,t,u,x,y,v,a", r"header"),
}


@pytest.mark.parametrize("name", list(BAD_STREAMS))
def test_read_stream_rejects(name):
    raw, pattern = BAD_STREAMS[name]
    with pytest.raises(StreamError, match=pattern) as info:
        cols, pieces = read_stream(io.BytesIO(raw), "cmd.stream")
        list(pieces)
    assert str(info.value).startswith("cmd.stream: ")
    assert "\n" not in str(info.value)


def test_read_stream_error_line_numbers_across_chunks():
    rows = b"".join(b"%d,%g,0,0,0,0,0\n" % (k, k * 1e-3) for k in range(50))
    raw = HEADER + rows + b"50,0.05,0,0,0,0\n"  # line 52 is short
    with pytest.raises(StreamError, match=r"line 52 has 6 fields"):
        list(read_stream(io.BytesIO(raw), "s", chunk_rows=3)[1])
    raw = HEADER + rows + b"50,0.049,0,0,0,0,0\n"  # t back at line 52, in a later chunk
    with pytest.raises(StreamError, match=r"line 52: time"):
        list(read_stream(io.BytesIO(raw), "s", chunk_rows=3)[1])
    data = np.zeros((50, 7))
    data[:, 0] = data[:, 1] = np.arange(50)
    data[37, 1] = 36  # record 37 (0-based, = tick k) does not increase
    with pytest.raises(StreamError, match=r"record 37: time"):
        list(read_stream(io.BytesIO(BIN_HEADER + data.astype("<f8").tobytes() + end_mark(50)), "s",
                         chunk_rows=4)[1])


@pytest.mark.parametrize("raw,forbidden", [
    pytest.param(HEADER + ROW0 + b"1,0.001,0.1,1,2,3,4\n2,0.001,0.2,1,2,3,4\n", "np.float64", id="time"),
    pytest.param(HEADER + ROW0 + b"1,0.001,zero,1,2,3,4\n", "b'zero'", id="non-numeric"),
    pytest.param(HEADER + ROW0 + b"1,0.001,nan,1,2,3,4\n", "np.float64", id="nan"),
])
def test_read_stream_messages_show_values_as_written(raw, forbidden):
    with pytest.raises(StreamError) as info:
        list(read_stream(io.BytesIO(raw), "s")[1])
    assert forbidden not in str(info.value), str(info.value)


# =========================================================================== output files


def test_open_output_writes_atomically(tmp_path):
    path = tmp_path / "out.csv"
    with open_output(path) as fh:
        fh.write(b"hello\n")
        assert not path.exists()  # still in the temporary file
    assert path.read_bytes() == b"hello\n"
    assert os.listdir(tmp_path) == ["out.csv"]
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~umask


@pytest.mark.parametrize("exc", [RuntimeError, KeyboardInterrupt])
def test_open_output_leaves_nothing_when_the_block_fails(tmp_path, exc):
    path = tmp_path / "out.csv"
    with pytest.raises(exc):
        with open_output(path) as fh:
            fh.write(b"partial" * 100000)
            raise exc()
    assert os.listdir(tmp_path) == []


def test_open_output_failure_keeps_the_old_file(tmp_path):
    path = tmp_path / "out.csv"
    path.write_bytes(b"old\n")
    with pytest.raises(RuntimeError):
        with open_output(path) as fh:
            fh.write(b"new\n")
            raise RuntimeError
    assert path.read_bytes() == b"old\n"
    assert os.listdir(tmp_path) == ["out.csv"]


def test_open_output_writes_devices_in_place():
    with open_output("/dev/null") as fh:
        fh.write(b"x" * 100000)
    assert stat.S_ISCHR(os.stat("/dev/null").st_mode)


def test_open_output_stdout(capsysbinary):
    for target in (None, "-"):
        with open_output(target) as fh:
            fh.write(b"to stdout\n")
    assert capsysbinary.readouterr().out == b"to stdout\nto stdout\n"


def test_check_output_path_refusals(tmp_path):
    job = tmp_path / "job.yaml"
    job.write_text("curve: {}\n")
    with pytest.raises(UsageError, match="input file"):
        check_output_path(job, inputs=[job])
    with pytest.raises(UsageError, match="input file"):
        check_output_path(tmp_path / "." / "job.yaml", inputs=[str(job)])  # another spelling, same file
    with pytest.raises(UsageError, match="is a directory"):
        check_output_path(tmp_path, inputs=[job])
    with pytest.raises(UsageError, match="does not exist"):
        check_output_path(tmp_path / "missing" / "out.csv", inputs=[job])
    # accepted: stdout, a device, a new file, an existing output, an unset optional input
    for ok in (None, "-", "/dev/null", tmp_path / "new.csv"):
        check_output_path(ok, inputs=[job, None])
    (tmp_path / "old.csv").write_text("x")
    check_output_path(tmp_path / "old.csv", inputs=[job])
    assert sorted(os.listdir(tmp_path)) == ["job.yaml", "old.csv"]


def test_column_decimals():
    assert column_decimals(["k", "t", "u", "x", "y", "z", "v", "a"]).tolist() == [0, 9, 15, 9, 9, 9, 9, 9]
    assert math.isclose(0.5 * 10.0 ** -15, 5e-16)


def test_check_output_path_names_the_path_not_an_option(tmp_path):
    """The library says what is wrong with the path; the command line names its option (cli/common.py)."""
    from nurbsinterp.errors import OutputPathError

    with pytest.raises(OutputPathError) as info:
        check_output_path(tmp_path)
    assert str(info.value) == f"{tmp_path}: is a directory"
    assert (info.value.name, info.value.problem, info.value.kind) == (str(tmp_path), "is a directory", "directory")
    with pytest.raises(OutputPathError, match=r"^'': the path is empty"):
        check_output_path("")
