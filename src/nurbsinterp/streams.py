"""Command streams: CSV and binary writers and readers, and atomic output files.

CSV
    One header line with the column names (``k,t,u,x,y[,z],v,a``), then one row
    per tick.  Numbers are fixed-point decimals with trailing zeros removed:
    9 decimals for t, positions, v and a (1e-9 s, 1e-9 mm), 15 for u (fewer
    only where a value is too large for them).

HAL (``--format hal``)
    What LinuxCNC's ``halstreamer`` reads onto the pins of its ``streamer``: no
    header, the values of a tick separated by one space, integers (the tick,
    the block, counts) without a decimal point, for s32 pins.

Binary (``nurbsinterp-bin`` version 1)
    One text header line ``nurbsinterp-bin 1 k,t,u,x,y,v,a`` then little-endian
    float64 records in that column order, one per tick.  The header may go on
    with space-separated ``key=value`` fields; `plan` writes
    ``curve=<16 hex digits>``, the fingerprint of the job's curve, which
    `simulate` checks against its job.  Read it with NumPy::

        head, _, body = open("run.bin", "rb").read().partition(b"\\n"); data = np.frombuffer(body, "<f8").reshape(-1, len(head.split()[2].split(b",")))

Rows are formatted by a compiled kernel a chunk at a time, under 100 ns for a
tick of 8 columns: writing CSV costs less than computing it.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import stat
import sys
import tempfile

import numpy as np
from llvmlite import ir
from numba import types
from numba.cpython.unsafe.numbers import leading_zeros, trailing_zeros  # LLVM's ctlz, cttz
from numba.extending import intrinsic

from ._jit import njit
from .errors import NurbsInterpError, OutputPathError, StreamError, UsageError
from .output import OutputFile, stdout_binary

BIN_MAGIC = b"nurbsinterp-bin"
BIN_VERSION = 1
FORMATS = ("csv", "bin", "hal")
DECIMALS = {"k": 0, "n": 0, "u": 15, "rapid": 0}
DEFAULT_DECIMALS = 9
COUNTS_SUFFIX = "_counts"  # an axis in drive counts (quantise.py): x_counts
_MAX_EXACT = 9.0e15  # below 2**53: integers up to here are exact in float64
S32_MAX = 2 ** 31 - 1  # the range of a HAL s32 pin
S32_MIN = -2 ** 31


def is_integer_column(name: str) -> bool:
    """Whether a column holds integers: the tick, the block, the rapid flag, an axis in counts."""
    return DECIMALS.get(name, DEFAULT_DECIMALS) == 0 or name.endswith(COUNTS_SUFFIX)


def column_decimals(columns) -> np.ndarray:
    return np.array([0 if is_integer_column(c) else DECIMALS.get(c, DEFAULT_DECIMALS) for c in columns],
                    dtype=np.int64)


def hal_pin_types(columns) -> str:
    """The ``cfg=`` string of LinuxCNC's streamer for these columns: a pin type letter per column.

    ``b`` (bit) for the rapid flag, ``s`` (s32) for the other integer columns (tick, block,
    counts), ``f`` (float) for the rest.
    """
    return "".join("b" if c == "rapid" else "s" if is_integer_column(c) else "f" for c in columns)


# --------------------------------------------------------------------------- CSV formatting
#
# format_rows prints a tick of 8 columns (about 70 bytes) in under 100 ns (issue 16), so that CSV costs
# little beside computing the tick.  Its text is, byte for byte, that of the digit-by-digit kernel it
# replaced (tests/test_streams.py holds it to a naive oracle with exact rational arithmetic); the speed
# comes from doing the same work differently:
#
# - the rounding takes the plain float64 product, and the exact one (Dekker's) only where the
#   product's own rounding could decide a tie: about one value in a hundred in a plan (u near 1,
#   whose product with 10^15 has only a few bits of fraction);
# - the digits come four at a time from a table, eight of them assembled in a 64-bit word, and go
#   into the buffer with one unaligned 8-byte store (bytes past the value are overwritten by the next);
# - the trailing zeros of the fraction and the leading zeros of the whole part are counted with one
#   instruction (lzcnt, tzcnt) on those words, not a loop of divisions;
# - the refusals of the writer (a value not finite, or too large for exact units) are found in the
#   same pass: the kernel returns where, and the Python side names it.

_POW10 = np.array([10.0 ** i for i in range(17)])  # exact: 5**16 < 2**53
_POW10_INT = np.array([10 ** i for i in range(17)], dtype=np.int64)
MAX_DECIMALS = 16  # the fraction is laid out as 16 digits
_ZEROS = 0x3030303030303030  # eight ASCII '0'
# "0000" … "9999": entry i holds the 4 ASCII digits of i, the first in the lowest byte, so that on
# this little-endian layout a store puts them in reading order
_DIGITS4 = np.array([int.from_bytes(b"%04d" % i, "little") for i in range(10_000)], dtype=np.uint32)


@intrinsic
def _store8(typingctx, buf, pos, word):
    """buf[pos:pos + 8] = the 8 bytes of the int64 *word*, lowest first: one unaligned store.

    No bounds check (format_rows checks the buffer's size once).  Indexing byte by byte would
    cost eight stores, each with numba's test for a negative index.
    """
    if buf != types.Array(types.uint8, 1, "C") or not isinstance(pos, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        array = context.make_array(signature.args[0])(context, builder, args[0])
        word = context.cast(builder, args[2], signature.args[2], types.int64)
        address = builder.bitcast(builder.gep(array.data, [args[1]]), ir.IntType(64).as_pointer())
        builder.store(word, address, align=1)
        return context.get_dummy_value()

    return types.void(buf, pos, word), codegen


@njit(cache=True)
def _two_product(a, b):
    """p, e with p = fl(a b) and a b = p + e exactly (Dekker's product with Veltkamp's split)."""
    p = a * b
    c = 134217729.0 * a
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


@njit(cache=True, inline="always")
def round_scaled(x, scale):
    """x·scale rounded to the nearest integer, ties to even, from its exact value (|x·scale| < 2**52, scale > 0).

    The magnitude is rounded and the sign put back (ties to even are symmetric): |x|·scale = p + e
    exactly (two-product, p ≥ 0); with q = floor(p), the exact product lies above q + 1/2 when
    (p - q) - 1/2 > -e, and p - q - 1/2 is exact from p - q = 1/4 up (Sterbenz; below it, e, at
    most half an ulp of p, cannot make up for it).  (On a negative p, p - floor(p) = p + 1 is not
    exact: -0.49999999999999994 + 1 rounds to 0.5.)  Returns a float64 integer, never -0.
    """
    p, e = _two_product(abs(x), scale)
    q = math.floor(p)
    below = (p - q) - 0.5
    if below > -e or (below == -e and q % 2.0 != 0.0):
        q += 1.0
    return -q if x < 0.0 and q != 0.0 else q


@njit(cache=True)
def _round_scaled(ax, scale):
    """ax·scale (ax ≥ 0) rounded to the nearest integer, ties to even, from its exact value."""
    return np.int64(round_scaled(ax, scale))


@njit(cache=True)
def _units_exactly(ax, d):
    """(d', units): ax in units of 10^-d', d' ≤ d the most decimals that keep ax·10^d' < 9e15.

    The careful path of format_rows, for the values its fast rounding leaves: near a tie, and too
    large for d decimals.  Where no decimal is left, ax ≥ 9e15 is an integer and is its own units.
    """
    while d > 0 and ax * _POW10[d] >= _MAX_EXACT:
        d -= 1
    if ax * _POW10[d] < _MAX_EXACT:
        return d, _round_scaled(ax, _POW10[d])
    return d, np.int64(ax)


@njit(cache=True)
def _digits8(v):
    """The 8 ASCII digits of 0 ≤ v < 10^8, zero-padded, the first in the lowest byte."""
    high = (v * 109951163) >> 40  # v // 10^4 for v < 10^8: 109951163 = ceil(2^40 / 10^4)
    # unsigned indices: numba tests a signed one for being negative (Python's wrap-around) on every load
    return np.int64(_DIGITS4[np.uint64(high)]) | (np.int64(_DIGITS4[np.uint64(v - high * 10_000)]) << 32)


@njit(cache=True)
def _put_digits(buf, pos, v):
    """Write the digits of v ≥ 0 at buf[pos:], one at a time; return the position after them."""
    n = 1
    while n < 19 and v >= 10 ** n:
        n += 1
    for j in range(pos + n - 1, pos - 1, -1):
        buf[j] = 48 + v % 10
        v //= 10
    return pos + n


@njit(cache=True, nogil=True)  # nogil: the run's measures go on beside it (metrics.Alongside)
def format_rows(data, decimals, buf, limit, sep=44):
    """Write the rows of *data* as text into *buf*; return the byte count, or -1 - r to refuse row r.

    Each value is rounded to its column's *decimals* (0 … 16) as an integer number of units, ties to
    even from its exact value, with fewer decimals where a value is too large for 9e15 units; it is
    printed with the trailing zeros of its fraction removed, and a '-' only if it did not round to
    zero.  The first row holding a value that is not finite or not below *limit* (9e15, the writer's,
    up to 2**63: from 9e15 up, values are integers and printed whole) is refused.

    data : (m, n) float64.  decimals : (n,) int64.  buf : uint8, C-contiguous, at least 32 bytes per
    value and 16 more; the bytes past the returned count are scratch.  sep: the byte between values
    (',' for CSV, ' ' for HAL); each row ends in '\n'.
    """
    if decimals.shape[0] != data.shape[1] or buf.shape[0] < 32 * data.size + 16:
        raise ValueError("format_rows: decimals must have one entry per column, buf 32 bytes per value + 16")
    for c in range(decimals.shape[0]):
        if not 0 <= decimals[c] <= MAX_DECIMALS:
            raise ValueError("format_rows: decimals must be between 0 and 16")
    # the fast rounding takes values below 9e15 without comparing them with limit; whole parts are int64
    if not _MAX_EXACT <= limit <= 2.0 ** 63:
        raise ValueError("format_rows: limit must be between 9e15 and 2**63")
    pos = 0
    for r in range(data.shape[0]):
        for c in range(data.shape[1]):
            x = data[r, c]
            d = decimals[c]
            ax = abs(x)
            # units = ax·10^d rounded, ties to even.  The float product p is off the exact one by
            # at most half its ulp, ≤ p·2^-53: where p's fraction f is farther than that from one
            # half, the exact product lies on the same side of q + 1/2 as p, and rounds as p does.
            # (f - 0.5 is exact from f = 1/4 up, and stays ≤ -1/4 below; a subnormal p, whose half
            # ulp is larger, has f far from one half; from p = 2^52 up, where p is an integer and
            # half an ulp is a half, every f fails the test.)
            p = ax * _POW10[d]
            q = np.floor(p)
            f = p - q
            if p < _MAX_EXACT and abs(f - 0.5) > p * 2.0 ** -53:
                units = np.int64(q) + (f > 0.5)
            else:  # a near tie, a value too large for d decimals, or one refused (this also catches NaN)
                if not ax < limit:
                    return -1 - r
                d, units = _units_exactly(ax, d)
            unit = _POW10_INT[d]
            whole = np.int64(ax)
            fraction = units - whole * unit
            if fraction >= unit:  # rounded up into the next whole number
                whole += 1
                fraction -= unit

            _store8(buf, pos, 45)  # '-', kept only where the value did not round to zero
            pos += (x < 0) & (units != 0)
            if whole < 10_000:
                digits = np.int64(_DIGITS4[np.uint64(whole)])
                # drop leading '0's, all but the last: count zero bytes from the low end, at most 3
                skip = trailing_zeros((digits ^ _ZEROS) | (1 << 24)) >> 3
                _store8(buf, pos, digits >> (8 * skip))
                pos += 4 - skip
            elif whole < 100_000_000:
                digits = _digits8(whole)
                skip = trailing_zeros((digits ^ _ZEROS) | (1 << 56)) >> 3
                _store8(buf, pos, digits >> (8 * skip))
                pos += 8 - skip
            else:  # a tick number or a position of 9 digits or more: rare
                pos = _put_digits(buf, pos, whole)
            if fraction != 0:
                # the fraction as 16 digits, left-aligned (0.25 at 9 decimals: 2500000000000000),
                # in two words; its trailing zeros are the high zero bytes of the second, or of both
                aligned = np.uint64(fraction * _POW10_INT[MAX_DECIMALS - d])
                high = np.int64(aligned // np.uint64(100_000_000))
                first = _digits8(high)
                second = _digits8(np.int64(aligned) - high * 100_000_000)
                _store8(buf, pos, 46)  # '.'
                _store8(buf, pos + 1, first)
                _store8(buf, pos + 9, second)
                zeros = (leading_zeros(second ^ _ZEROS) >> 3 if second != _ZEROS
                         else 8 + (leading_zeros(first ^ _ZEROS) >> 3))
                pos += 1 + 16 - zeros
            _store8(buf, pos, sep)
            pos += 1
        buf[pos - 1] = 10  # the row's last separator becomes its '\n'
    return pos


@njit(cache=True, nogil=True)
def first_not_finite(data):
    """The first row of *data* (m, n) holding NaN or ±inf, or −1: one pass, no temporaries."""
    for r in range(data.shape[0]):
        for c in range(data.shape[1]):
            x = data[r, c]
            if not (x - x == 0.0):  # false for NaN and ±inf only
                return r
    return -1


class StreamWriter:
    """Writes chunks of rows as CSV, binary or HAL lines to a binary file object.

    *columns* name the rows' columns; *select* (indices into them, default all) the
    columns written, in that order.  ``hal`` is what LinuxCNC's halstreamer reads: no
    header, values separated by one space, integer columns (:func:`is_integer_column`)
    as integers, which must fit the s32 pins :func:`hal_pin_types` gives them.
    *too_large_hint* follows the refusal of a value too large for the text formats
    (how the caller's user asks for the binary format instead).  Refusals name the
    tick by the rows' ``k`` column, written or not.  *meta* adds ``key=value`` fields
    to the binary header after ``curve=`` (``precompensated=exact``).
    """

    def __init__(self, fh, columns, fmt: str = "csv", fingerprint: str | None = None, too_large_hint: str = "",
                 select=None, meta: dict | None = None):
        if fmt not in FORMATS:
            raise ValueError(f"unknown format {fmt!r}")
        self.fh = fh
        self.all_columns = list(columns)
        self._k = self.all_columns.index("k") if "k" in self.all_columns else None
        self._select = None if select is None else np.asarray(select, dtype=np.int64)
        self.columns = self.all_columns if select is None else [self.all_columns[i] for i in select]
        self.fmt = fmt
        self.too_large_hint = too_large_hint
        self.decimals = column_decimals(self.columns)
        self._sep = ord(" ") if fmt == "hal" else ord(",")
        # the integer columns of a HAL line go to s32 pins (the rapid flag to a bit, 0 or 1)
        self._s32 = np.array([i for i, c in enumerate(self.columns) if fmt == "hal" and is_integer_column(c)
                              and c != "rapid"], dtype=np.int64)
        self._buf = np.empty(0, dtype=np.uint8)
        self._rows = np.empty((0, len(self.columns)))
        names = ",".join(self.columns)
        # the header waits for the first rows that pass the checks below: a run refused
        # on its first chunk leaves nothing on stdout that a consumer could take for an empty stream
        if fmt == "hal":
            self._header = b""
        elif fmt == "csv":
            self._header = names.encode() + b"\n"
        else:
            extra = b"" if fingerprint is None else b" curve=" + fingerprint.encode("ascii")
            extra += b"".join(b" %s=%s" % (k.encode("ascii"), v.encode("ascii")) for k, v in (meta or {}).items())
            self._header = b"%s %d %s%s\n" % (BIN_MAGIC, BIN_VERSION, names.encode(), extra)

    def write(self, data: np.ndarray) -> None:
        full = data
        if self._select is not None:
            if self._rows.shape[0] < data.shape[0]:
                self._rows = np.empty((data.shape[0], len(self.columns)))
            data = np.take(data, self._select, axis=1, out=self._rows[:data.shape[0]])
        if self.fmt == "bin":
            data = np.ascontiguousarray(data, dtype="<f8")  # no copy of the float64 rows a run makes
            if first_not_finite(data) >= 0:
                self._check(data, full)
            self._write_header()
            self.fh.write(data)  # the rows' own bytes, not a copy of them (write_all takes any buffer)
            return
        data = np.ascontiguousarray(data, dtype=np.float64)
        need = data.size * 32 + data.shape[0] + 16
        if self._buf.shape[0] < need:
            self._buf = np.empty(need, dtype=np.uint8)
        # the kernel refuses what _check names, in the same pass as it formats; only then is the
        # chunk scanned again, for the message
        nbytes = format_rows(data, self.decimals, self._buf, _MAX_EXACT, self._sep)
        if nbytes < 0:
            self._check(data, full)
            raise RuntimeError(f"format_rows refused row {-1 - nbytes}, which the writer's checks pass")
        if self._s32.shape[0] and data.shape[0]:
            ints = data[:, self._s32]
            if ints.max() > S32_MAX or ints.min() < S32_MIN:
                r, c = np.argwhere((ints > S32_MAX) | (ints < S32_MIN))[0]
                raise UsageError(f"{self._tick(full, r)}{self.columns[self._s32[c]]} = {ints[r, c]:.0f} is beyond "
                                 f"the range of a HAL s32 pin ({S32_MIN} to {S32_MAX})")
        self._write_header()
        self.fh.write(memoryview(self._buf)[:nbytes])

    def _tick(self, full, row) -> str:
        return "" if self._k is None else f"tick k = {full[row, self._k]:.0f}: "

    def _check(self, data: np.ndarray, full: np.ndarray) -> None:
        """Raise for a value the stream cannot carry: one not finite, or for text one of 9e15 or more."""
        if not np.isfinite(data).all():
            row = int(np.flatnonzero(~np.isfinite(data).all(axis=1))[0])
            where = self._tick(full, row)
            raise NurbsInterpError(f"refusing to write a non-finite value ({where[:-2] or f'row {row}'})")
        if self.fmt != "bin" and (np.abs(data) >= _MAX_EXACT).any():
            r, c = np.argwhere(np.abs(data) >= _MAX_EXACT)[0]
            raise UsageError(f"{self._tick(full, r)}{self.columns[c]} = {data[r, c]:.6g} is too large "
                             f"for the {self.fmt.upper()} writer (|value| < 9e15){self.too_large_hint}")

    def _write_header(self) -> None:
        if self._header:
            self.fh.write(self._header)
            self._header = b""


# --------------------------------------------------------------------------- readers


def read_stream(fh, name: str = "<stdin>", chunk_rows: int = 1 << 16, meta: dict | None = None,
                detected: dict | None = None):
    """Read a CSV or binary command stream (detected from its first bytes).

    Returns (columns, iterator of float64 arrays of shape (m, len(columns))).
    The binary header's key=value fields (``curve``) are put in *meta* if given,
    the format found (``csv`` or ``bin``) in ``detected["format"]`` if *detected* is given.
    Raises StreamError naming the stream and the line or record for anything
    malformed: a wrong header, a short binary record, a row with the wrong
    number of fields, a non-number, NaN or inf, a time that does not increase.
    """
    head = fh.readline(4096)
    if not head:
        raise StreamError(f"{name}: the stream is empty")
    if not head.endswith(b"\n"):
        raise StreamError(f"{name}: the header line is missing or longer than 4096 bytes")
    if head.startswith(BIN_MAGIC):
        parts = head.decode("ascii", "replace").split()
        fields = [p.partition("=") for p in parts[3:]]
        if len(parts) < 3 or parts[1] != str(BIN_VERSION) or any(not (k and sep) for k, sep, _ in fields):
            raise StreamError(f"{name}: header {head[:80].decode('ascii', 'replace').strip()!r} is not "
                              f"'{BIN_MAGIC.decode()} {BIN_VERSION} <columns> [key=value ...]'")
        if meta is not None:
            meta.update({k: v for k, _, v in fields})
        columns = _check_columns(name, parts[2].split(","))
        if detected is not None:
            detected["format"] = "bin"
        return columns, _checked(name, columns, _read_bin(fh, name, len(columns), chunk_rows), "record")
    try:
        text = head.decode("ascii").strip()
    except UnicodeDecodeError:
        raise StreamError(f"{name}: not a nurbsinterp command stream (no CSV or binary header)") from None
    columns = _check_columns(name, text.split(","))
    if detected is not None:
        detected["format"] = "csv"
    return columns, _checked(name, columns, _read_csv(fh, name, len(columns), chunk_rows), "line")


def refuse_counts(name, columns) -> None:
    """Refuse a stream whose axes are drive counts (x_counts ...): its readers need positions in mm."""
    counts = [c for c in columns if c.endswith(COUNTS_SUFFIX)]
    if counts:
        raise StreamError(f"{name}: the stream is in drive counts ({','.join(counts)}): it needs positions in mm "
                          "(plan it with a resolution but not in counts)")


def _check_columns(name, columns):
    columns = [c.strip() for c in columns]
    refuse_counts(name, columns)
    for need in ("k", "t", "u", "x", "y", "v", "a"):
        if need not in columns:
            raise StreamError(f"{name}: the header has no column {need!r} (found {','.join(columns)[:80]!r})")
    return columns


def _read_bin(fh, name, ncols, chunk_rows):
    record = 8 * ncols
    index = 0
    direct = hasattr(fh, "readinto") and sys.byteorder == "little"
    while True:
        if direct:
            # the records straight into the chunk's own float64 rows: no bytes object, no copy of it
            data = np.empty((chunk_rows, ncols))
            got = _fill(fh, memoryview(data).cast("B"))
            if got % record:  # the buffer is filled to the end of the stream: a partial record ends it
                raise StreamError(f"{name}: record {index + got // record} is truncated "
                                  f"({got % record} of {record} bytes)")
            if got < data.nbytes:
                data = data[:got // record]
        else:
            raw = fh.read(record * chunk_rows)
            got = len(raw)
            if len(raw) % record:
                # a pipe may deliver a short read: top it up before calling it truncated
                while len(raw) % record:
                    more = fh.read(record - len(raw) % record)
                    if not more:
                        raise StreamError(f"{name}: record {index + len(raw) // record} is truncated "
                                          f"({len(raw) % record} of {record} bytes)")
                    raw += more
            data = np.frombuffer(raw, dtype="<f8").reshape(-1, ncols).astype(np.float64)
        if not got:
            return
        yield index, data
        index += data.shape[0]


def _fill(fh, view) -> int:
    """Read into *view* until it is full or the stream ends (a pipe delivers what it has); the byte count."""
    got = 0
    while got < view.nbytes:
        n = fh.readinto(view[got:])
        if not n:
            break
        got += n
    return got


def _read_csv(fh, name, ncols, chunk_rows):
    line_no = 1
    while True:
        lines = fh.readlines(chunk_rows * 16 * ncols)
        if not lines:
            return
        rows = np.empty((len(lines), ncols))
        for j, line in enumerate(lines):
            fields = line.split(b",")
            if len(fields) != ncols:
                raise StreamError(f"{name}: line {line_no + j + 1} has {len(fields)} fields, the header has {ncols}")
            try:
                rows[j] = [float(f) for f in fields]
            except ValueError:
                bad = next(f for f in fields if not _is_float(f))
                raise StreamError(f"{name}: line {line_no + j + 1}: {bad.strip()[:40].decode('ascii', 'replace')!r} "
                                  "is not a number") from None
        yield line_no, rows
        line_no += len(lines)


def _is_float(text) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def _checked(name, columns, pieces, unit):
    """Check every chunk: finite values, time increasing; yield the arrays."""
    t_col = columns.index("t")
    last_t = -np.inf
    for first, data in pieces:
        kind, r, c = _check_rows(data, t_col, last_t)
        if kind:
            where = f"{unit} {first + r + (1 if unit == 'line' else 0)}"
            if kind == _NOT_FINITE:
                raise StreamError(f"{name}: {where}: column {columns[c]} = {float(data[r, c])} is not a finite number")
            raise StreamError(f"{name}: {where}: time t = {float(data[r, t_col])!r} does not increase")
        last_t = data[-1, t_col]
        yield data


_NOT_FINITE, _NOT_INCREASING = 1, 2


@njit(cache=True, nogil=True)
def _check_rows(data, t_col, last_t):
    """(0, 0, 0), or (_NOT_FINITE, row, column) of the first value that is NaN or ±inf, else
    (_NOT_INCREASING, row, t column) of the first time not above the one before: two passes, no temporaries."""
    for r in range(data.shape[0]):
        for c in range(data.shape[1]):
            x = data[r, c]
            if not (x - x == 0.0):  # false for NaN and ±inf only
                return _NOT_FINITE, r, c
    for r in range(data.shape[0]):
        if not data[r, t_col] > last_t:
            return _NOT_INCREASING, r, t_col
        last_t = data[r, t_col]
    return 0, 0, 0


# --------------------------------------------------------------------------- output files


def is_stdout(path) -> bool:
    return path is None or os.fspath(path) == "-"


def check_output_path(path, inputs=()) -> None:
    """Refuse, before any work is done, an output path that cannot or must not be written.

    Raises OutputPathError, naming the path and what is wrong with it.
    """
    if is_stdout(path):
        return
    name = os.fspath(path)
    if name == "":
        raise OutputPathError("''", "the path is empty; give a file name, or - for stdout", "empty")
    for src in inputs:
        with contextlib.suppress(OSError):
            if src and os.path.exists(name) and os.path.samefile(name, src):
                raise OutputPathError(name, f"refusing to overwrite the input file {src}", "input")
    if os.path.isdir(name):
        raise OutputPathError(name, "is a directory", "directory")
    directory = os.path.dirname(os.path.abspath(name))
    if not os.path.isdir(directory):
        raise OutputPathError(name, f"directory {directory} does not exist", "no-directory")
    if os.path.exists(name) and not stat.S_ISREG(os.stat(name).st_mode):
        return  # a device or FIFO is written in place
    if not os.access(directory, os.W_OK):
        raise OutputPathError(name, f"directory {directory} is not writable", "not-writable")
    # the file is written beside its target and renamed into place (open_output): try that
    # creation now, so that a place that takes no new file (/proc, a read-only file system,
    # which root's access() does not see) is refused before any work, not after it
    try:
        fd, probe = tempfile.mkstemp(dir=directory, prefix=f".{os.path.basename(name)}.", suffix=".part")
    except OSError as exc:
        raise OutputPathError(name, f"cannot create a file in {directory}: {exc.strerror or exc}",
                              "cannot-create") from None
    os.close(fd)
    try:
        os.replace(probe, probe + ".x")  # a rename within the directory, as the real output's
        probe += ".x"
    except OSError as exc:
        raise OutputPathError(name, f"cannot replace files in {directory}: {exc.strerror or exc}",
                              "cannot-replace") from None
    finally:
        with contextlib.suppress(OSError):
            os.unlink(probe)


@contextlib.contextmanager
def open_output(path, label: str | None = None):
    """A binary file object for *path*; stdout when path is None or '-'.

    *label* is how an error names the file (default: its path).

    Every write takes all its bytes or raises (:mod:`nurbsinterp.output`): a reader
    that went away is BrokenPipeError, a full disk or a size limit an OutputError
    naming ``stdout`` or the file.  The block's end flushes, so a caller that
    reports success after it reports only what was delivered.

    A regular file is written to a temporary file beside it and renamed into
    place only when the block finishes without an exception, so a failed or
    interrupted run never leaves a partial file.  A path that exists and is not
    a regular file (/dev/null, a FIFO, a terminal) is written directly.
    """
    if is_stdout(path):
        out = stdout_binary()
        yield out
        out.flush()
        return
    name = os.fspath(path)
    label = name if label is None else label
    if os.path.exists(name) and not stat.S_ISREG(os.stat(name).st_mode):
        with io.BufferedWriter(OutputFile(name, label)) as fh:
            yield fh
        return
    directory = os.path.dirname(os.path.abspath(name))
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{os.path.basename(name)}.", suffix=".part")
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the mode open() would
        with io.BufferedWriter(OutputFile(fd, label), 1 << 20) as fh:
            yield fh
        os.replace(tmp, name)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
