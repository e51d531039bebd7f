"""Command streams: CSV and binary writers and readers, and atomic output files.

CSV
    One header line with the column names (``k,t,u,x,y[,z],v,a``), then one row
    per tick, then the end mark ``# nurbsinterp-end ticks=<rows> curve=<16 hex
    digits>`` (and ``precompensated=<method>`` on a pre-compensated stream, ``accdec=after`` on one filtered
    after interpolation).
    Numbers are fixed-point decimals with trailing zeros removed: 9 decimals for
    t, positions, v and a (1e-9 s, 1e-9 mm), 15 for u (fewer only where a value
    is too large for them).  ``numpy.loadtxt(f, delimiter=",", skiprows=1)``
    skips the end mark as a comment; pandas wants ``comment="#"``.

HAL (``--format hal``)
    What LinuxCNC's ``halstreamer`` reads onto the pins of its ``streamer``: no
    header, the values of a tick separated by one space, integers (the tick,
    the block, counts) without a decimal point, for s32 pins.  No end mark:
    halstreamer takes every line for a tick, and nothing reads HAL lines back.

Binary (``nurbsinterp-bin`` version 2)
    One text header line ``nurbsinterp-bin 2 k,t,u,x,y,v,a`` then little-endian
    float64 records in that column order, one per tick, then the end mark: 64
    bytes of text, ``nurbsinterp-end ticks=<records> curve=<16 hex digits>``
    padded with spaces and ended by a newline.  The header may go on with
    space-separated ``key=value`` fields; `plan` writes ``curve=<16 hex
    digits>``, the fingerprint of the job's curve, which `simulate` checks
    against its job.  Version 1 (no end mark) is refused: a cut one cannot be
    told from a whole one.  Read it with NumPy::

        import numpy as np; head, _, body = open("run.bin", "rb").read().partition(b"\\n"); data = np.frombuffer(body[:-64], "<f8").reshape(-1, len(head.split()[2].split(b",")))

The end mark is what tells a reader that the stream is whole: a writer puts it
last, only once every tick is written (:meth:`StreamWriter.finish`), so a run
that fails, is killed or is cut in a pipe leaves a stream without it, and
:func:`read_stream` refuses that stream, as it refuses a mark whose tick count
is not the rows it read.

Rows are formatted by a compiled kernel a chunk at a time, under 100 ns for a
tick of 8 columns: writing CSV costs less than computing it.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import stat
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
BIN_VERSION = 2  # 2: the end mark after the records (1 had none)
END_MARK = b"nurbsinterp-end"
BIN_END_BYTES = 64  # the binary end mark's fixed size: a whole number of float64 words, room for 10^16 ticks
CSV_END_PREFIX = b"# "  # the CSV end mark is a comment line for ordinary readers (numpy.loadtxt, pandas)
#: how a refusal of an incomplete or empty stream says why it may be so
UPSTREAM = "the command that wrote it may have failed or been stopped"
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
    to the binary header after ``curve=`` (``precompensated=exact``), and to the CSV
    end mark.  :meth:`finish` writes the end mark: call it once every row is written,
    and never after a failure, so that the stream's readers can tell it is whole.
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
        self.fingerprint = fingerprint
        self.meta = dict(meta or {})
        self.ticks = 0  # rows written, for the end mark
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
            self.ticks += data.shape[0]
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
        self.ticks += data.shape[0]

    def finish(self, fingerprint: str | None = None) -> None:
        """Write the end mark: the stream is whole, *ticks* rows of the curve *fingerprint* (default the writer's).

        HAL lines get none (halstreamer would take it for a tick).  A stream of no rows still gets its header.
        """
        self._write_header()
        if self.fmt == "hal":
            return
        fingerprint = self.fingerprint if fingerprint is None else fingerprint
        fields = {"ticks": str(self.ticks), **({} if fingerprint is None else {"curve": fingerprint})}
        if self.fmt == "csv":
            fields.update(self.meta)  # the CSV header line is the column names only: the rest goes here
        mark = END_MARK + b"".join(b" %s=%s" % (k.encode("ascii"), v.encode("ascii")) for k, v in fields.items())
        if self.fmt == "csv":
            self.fh.write(CSV_END_PREFIX + mark + b"\n")
            return
        if len(mark) >= BIN_END_BYTES:
            raise ValueError(f"the end mark {mark!r} does not fit in {BIN_END_BYTES} bytes")
        self.fh.write(mark.ljust(BIN_END_BYTES - 1) + b"\n")

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
    and the end mark's (``curve``, and a CSV stream's ``precompensated``) once the
    iterator is exhausted; the format found (``csv`` or ``bin``) goes in
    ``detected["format"]`` if *detected* is given.
    Raises StreamError naming the stream and the line or record for anything
    malformed: an empty stream, a wrong header, a short binary record, a row with
    the wrong number of fields, a non-number, NaN or inf, a time that does not
    increase; and, at the end, a stream that stops without its end mark (cut
    short: its writer failed or was stopped) or whose end mark disagrees with it
    (tick count, curve).
    """
    meta = {} if meta is None else meta
    head = fh.readline(4096)
    if not head:
        raise StreamError(f"{name}: no commands arrived (the stream is empty): the command upstream may have failed")
    if not head.endswith(b"\n"):
        if len(head) < 4096:
            raise StreamError(f"{name}: the stream ends inside its header line: it is incomplete; {UPSTREAM}")
        raise StreamError(f"{name}: the header line is missing or longer than 4096 bytes")
    if head.startswith(BIN_MAGIC):
        parts = head.decode("ascii", "replace").split()
        fields = [p.partition("=") for p in parts[3:]]
        if len(parts) >= 3 and parts[1] == "1":
            raise StreamError(f"{name}: a version 1 binary stream has no end mark, so a cut one cannot be told "
                              f"from a whole one: plan it again (this version writes version {BIN_VERSION})")
        if len(parts) < 3 or parts[1] != str(BIN_VERSION) or any(not (k and sep) for k, sep, _ in fields):
            raise StreamError(f"{name}: header {head[:80].decode('ascii', 'replace').strip()!r} is not "
                              f"'{BIN_MAGIC.decode()} {BIN_VERSION} <columns> [key=value ...]'")
        meta.update({k: v for k, _, v in fields})
        columns = _check_columns(name, parts[2].split(","))
        if detected is not None:
            detected["format"] = "bin"
        return columns, _checked(name, columns, _read_bin(fh, name, len(columns), chunk_rows, meta), "record")
    try:
        text = head.decode("ascii").strip()
    except UnicodeDecodeError:
        raise StreamError(f"{name}: not a nurbsinterp command stream (no CSV or binary header)") from None
    columns = _check_columns(name, text.split(","))
    if detected is not None:
        detected["format"] = "csv"
    return columns, _checked(name, columns, _read_csv(fh, name, len(columns), chunk_rows, meta), "line")


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


def _end_fields(text: bytes) -> dict | None:
    """The key=value fields of an end mark ``nurbsinterp-end ticks=N ...`` (spaces and newline ended), or None."""
    if not (text.startswith(END_MARK + b" ") and text.endswith(b"\n")):
        return None
    try:
        parts = text[len(END_MARK):].decode("ascii").split()
    except UnicodeDecodeError:
        return None
    fields = dict(p.partition("=")[::2] for p in parts)
    if len(fields) != len(parts) or not all(k and v for k, v in fields.items()) or \
            not fields.get("ticks", "").isdigit():
        return None
    return fields


def _ended(name, fields, rows, unit, meta) -> None:
    """Check an end mark against the stream read (its tick count, its header's curve); put its fields in *meta*."""
    if int(fields["ticks"]) != rows:
        raise StreamError(f"{name}: the end mark says ticks={fields['ticks']} but the stream has {rows} {unit}s: "
                          f"it is not the stream its writer wrote")
    curve = fields.get("curve")
    if curve is not None and meta.get("curve", curve) != curve:
        raise StreamError(f"{name}: the end mark's curve={curve} is not the header's curve={meta['curve']}: "
                          "the stream is two streams joined")
    meta.update({k: v for k, v in fields.items() if k != "ticks"})


def _incomplete(name, where) -> StreamError:
    return StreamError(f"{name}: the stream ends {where} without its end mark ('{END_MARK.decode()} ticks=...'): "
                       f"it is incomplete; {UPSTREAM}")


def _read_bin(fh, name, ncols, chunk_rows, meta):
    """(first record, records) chunks of the binary records after the header; checks the end mark at the end.

    The last BIN_END_BYTES bytes read so far may be the end mark: they are held back (carried into the
    next chunk's buffer) until the stream goes on past them.
    """
    record = 8 * ncols
    words = chunk_rows * ncols
    tail = BIN_END_BYTES // 8
    carry = np.empty(0, dtype="<f8")
    index = 0
    while True:
        buf = np.empty(words + tail, dtype="<f8")  # records straight into float64 rows: no bytes object, no copy
        buf[:carry.size] = carry
        raw = memoryview(buf).cast("B")
        got = carry.nbytes + _fill(fh, raw[carry.nbytes:])
        if got == buf.nbytes:  # more may follow: the held-back bytes are records, or the end mark
            carry = buf[words:]
            yield index, buf[:words].reshape(chunk_rows, ncols).astype(np.float64, copy=False)
            index += chunk_rows
            continue
        body = got - BIN_END_BYTES
        fields = _end_fields(bytes(raw[body:got])) if body >= 0 else None
        if fields is None:
            part = f" and {got % record} bytes" if got % record else ""
            raise _incomplete(name, f"after {index + got // record} records{part}")
        if body % record:
            raise StreamError(f"{name}: record {index + body // record} is truncated ({body % record} of "
                              f"{record} bytes) before the end mark")
        rows = body // record
        if rows:
            yield index, buf[:rows * ncols].reshape(rows, ncols).astype(np.float64, copy=False)
        _ended(name, fields, index + rows, "record", meta)
        return


def _fill(fh, view) -> int:
    """Read into *view* until it is full or the stream ends (a pipe delivers what it has); the byte count."""
    got = 0
    into = getattr(fh, "readinto", None)
    while got < view.nbytes:
        if into is not None:
            n = into(view[got:])
        else:
            more = fh.read(view.nbytes - got)
            n = len(more)
            view[got:got + n] = more
        if not n:
            break
        got += n
    return got


def _read_csv(fh, name, ncols, chunk_rows, meta):
    """(first line number, rows) chunks of the CSV rows after the header; checks the end mark at the end."""
    line_no = 1
    while True:
        lines = fh.readlines(chunk_rows * 16 * ncols)
        if not lines:
            raise _incomplete(name, f"after line {line_no}")
        if not lines[-1].endswith(b"\n"):
            raise _incomplete(name, f"inside line {line_no + len(lines)}")
        rows = np.empty((len(lines), ncols))
        for j, line in enumerate(lines):
            fields = line.split(b",")
            try:
                if len(fields) != ncols:
                    raise ValueError
                rows[j] = [float(f) for f in fields]
            except ValueError:
                if line.startswith(CSV_END_PREFIX + END_MARK):
                    # the end mark: the last line of the stream, after every row
                    if j + 1 < len(lines) or fh.read(1):
                        raise StreamError(f"{name}: line {line_no + j + 1}: the end mark is followed by more "
                                          "lines") from None
                    if j:
                        yield line_no, rows[:j]
                    fields = _end_fields(line[len(CSV_END_PREFIX):])
                    if fields is None:
                        raise StreamError(f"{name}: line {line_no + j + 1}: {line.strip()[:80].decode('ascii', 'replace')!r} "
                                          f"is not an end mark '{END_MARK.decode()} ticks=N [key=value ...]'") from None
                    _ended(name, fields, line_no + j - 1, "row", meta)
                    return
                if len(fields) != ncols:
                    raise StreamError(f"{name}: line {line_no + j + 1} has {len(fields)} fields, "
                                      f"the header has {ncols}") from None
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


def tolerance_mark(tolerance: float | None) -> str:
    """The blend tolerance a look-ahead stream's header or end mark names: mm, or "program" (each block's own)."""
    return "program" if tolerance is None else repr(float(tolerance))


def tolerance_words(mark: str) -> str:
    return "the program's own G64 P" if mark == "program" else f"{float(mark) * 1e3:g} um"
