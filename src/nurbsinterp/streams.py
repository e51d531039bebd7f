"""Command streams: CSV and binary writers and readers, and atomic output files.

CSV
    One header line with the column names (``k,t,u,x,y[,z],v,a``), then one row
    per tick.  Numbers are fixed-point decimals with trailing zeros removed:
    9 decimals for t, positions, v and a (1e-9 s, 1e-9 mm), 15 for u (fewer
    only where a value is too large for them).

Binary (``nurbsinterp-bin`` version 1)
    One text header line ``nurbsinterp-bin 1 k,t,u,x,y,v,a`` then little-endian
    float64 records in that column order, one per tick.  The header may go on
    with space-separated ``key=value`` fields; `plan` writes
    ``curve=<16 hex digits>``, the fingerprint of the job's curve, which
    `simulate` checks against its job.  Read it with NumPy::

        head, _, body = open("run.bin", "rb").read().partition(b"\\n"); data = np.frombuffer(body, "<f8").reshape(-1, len(head.split()[2].split(b",")))

Rows are formatted by a compiled kernel a chunk at a time, so writing CSV costs
about as much as computing it.
"""
from __future__ import annotations

import contextlib
import io
import math
import os
import stat
import tempfile

import numpy as np
from numba import njit

from .errors import NurbsInterpError, OutputPathError, StreamError, UsageError
from .output import OutputFile, stdout_binary

BIN_MAGIC = b"nurbsinterp-bin"
BIN_VERSION = 1
FORMATS = ("csv", "bin")
DECIMALS = {"k": 0, "n": 0, "u": 15, "rapid": 0}
DEFAULT_DECIMALS = 9
_MAX_EXACT = 9.0e15  # below 2**53: integers up to here are exact in float64


def column_decimals(columns) -> np.ndarray:
    return np.array([DECIMALS.get(c, DEFAULT_DECIMALS) for c in columns], dtype=np.int64)


_POW10 = np.array([10.0 ** i for i in range(19)])


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


@njit(cache=True)
def _round_scaled(ax, scale):
    """ax·scale rounded to the nearest integer, ties to even, from its exact value."""
    p, e = _two_product(ax, scale)
    q = math.floor(p)
    below = (p - q) - 0.5  # exact: Sterbenz
    if below > -e or (below == -e and q % 2 == 1):
        q += 1.0
    return np.int64(q)


@njit(cache=True)
def format_rows(data, decimals, buf):
    """Write the rows of *data* as CSV text into *buf* (uint8); return the byte count.

    Each value is rounded to its column's decimals as an integer number of
    units (fewer decimals where a value is too large for 2**53 units), printed
    with its trailing zeros removed.  *buf* must hold at least 32 bytes per value.
    """
    pos = 0
    digits = np.empty(24, dtype=np.uint8)
    for r in range(data.shape[0]):
        for c in range(data.shape[1]):
            if c > 0:
                buf[pos] = 44  # ','
                pos += 1
            x = data[r, c]
            d = decimals[c]
            ax = abs(x)
            while d > 0 and ax * _POW10[d] >= _MAX_EXACT:
                d -= 1
            if ax * _POW10[d] < _MAX_EXACT:
                scaled = _round_scaled(ax, _POW10[d])
            else:  # beyond exact integers: the integer part only (the writer keeps |x| < 9e15)
                scaled = np.int64(ax)
            while d > 0 and scaled % 10 == 0:  # drop trailing zeros of the fraction
                scaled //= 10
                d -= 1
            if x < 0 and scaled != 0:
                buf[pos] = 45  # '-'
                pos += 1
            nd = 0
            v = scaled
            while True:
                digits[nd] = 48 + v % 10
                nd += 1
                v //= 10
                if v == 0:
                    break
            while nd <= d:  # at least one digit before the point
                digits[nd] = 48
                nd += 1
            for j in range(nd - 1, -1, -1):
                if j == d - 1:
                    buf[pos] = 46  # '.'
                    pos += 1
                buf[pos] = digits[j]
                pos += 1
        buf[pos] = 10  # '\n'
        pos += 1
    return pos


class StreamWriter:
    """Writes chunks of rows as CSV or binary to a binary file object.

    *too_large_hint* follows the refusal of a value too large for CSV (how the
    caller's user asks for the binary format instead).
    """

    def __init__(self, fh, columns, fmt: str = "csv", fingerprint: str | None = None, too_large_hint: str = ""):
        if fmt not in FORMATS:
            raise ValueError(f"unknown format {fmt!r}")
        self.fh = fh
        self.columns = list(columns)
        self.fmt = fmt
        self.too_large_hint = too_large_hint
        self.decimals = column_decimals(self.columns)
        self._buf = np.empty(0, dtype=np.uint8)
        names = ",".join(self.columns)
        # the header waits for the first rows that pass the checks below: a run refused
        # on its first chunk leaves nothing on stdout that a consumer could take for an empty stream
        if fmt == "csv":
            self._header = names.encode() + b"\n"
        else:
            extra = b"" if fingerprint is None else b" curve=" + fingerprint.encode("ascii")
            self._header = b"%s %d %s%s\n" % (BIN_MAGIC, BIN_VERSION, names.encode(), extra)

    def write(self, data: np.ndarray) -> None:
        if not np.isfinite(data).all():
            row = int(np.flatnonzero(~np.isfinite(data).all(axis=1))[0])
            raise NurbsInterpError(f"refusing to write a non-finite value (tick k = {data[row, 0]:.0f})")
        if self.fmt == "csv" and (np.abs(data) >= _MAX_EXACT).any():
            r, c = np.argwhere(np.abs(data) >= _MAX_EXACT)[0]
            raise UsageError(f"tick k = {data[r, 0]:.0f}: {self.columns[c]} = {data[r, c]:.6g} is too large "
                             f"for the CSV writer (|value| < 9e15){self.too_large_hint}")
        if self._header:
            self.fh.write(self._header)
            self._header = b""
        if self.fmt == "bin":
            self.fh.write(np.ascontiguousarray(data, dtype="<f8").tobytes())
            return
        need = data.size * 32 + data.shape[0] + 16
        if self._buf.shape[0] < need:
            self._buf = np.empty(need, dtype=np.uint8)
        nbytes = format_rows(np.ascontiguousarray(data, dtype=np.float64), self.decimals, self._buf)
        self.fh.write(memoryview(self._buf)[:nbytes])


# --------------------------------------------------------------------------- readers


def read_stream(fh, name: str = "<stdin>", chunk_rows: int = 1 << 16, meta: dict | None = None):
    """Read a CSV or binary command stream (detected from its first bytes).

    Returns (columns, iterator of float64 arrays of shape (m, len(columns))).
    The binary header's key=value fields (``curve``) are put in *meta* if given.
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
        return columns, _checked(name, columns, _read_bin(fh, name, len(columns), chunk_rows), "record")
    try:
        text = head.decode("ascii").strip()
    except UnicodeDecodeError:
        raise StreamError(f"{name}: not a nurbsinterp command stream (no CSV or binary header)") from None
    columns = _check_columns(name, text.split(","))
    return columns, _checked(name, columns, _read_csv(fh, name, len(columns), chunk_rows), "line")


def _check_columns(name, columns):
    columns = [c.strip() for c in columns]
    for need in ("k", "t", "u", "x", "y", "v", "a"):
        if need not in columns:
            raise StreamError(f"{name}: the header has no column {need!r} (found {','.join(columns)[:80]!r})")
    return columns


def _read_bin(fh, name, ncols, chunk_rows):
    record = 8 * ncols
    index = 0
    while True:
        raw = fh.read(record * chunk_rows)
        if not raw:
            return
        if len(raw) % record:
            # a pipe may deliver a short read: top it up before calling it truncated
            while len(raw) % record:
                more = fh.read(record - len(raw) % record)
                if not more:
                    raise StreamError(f"{name}: record {index + len(raw) // record} is truncated "
                                      f"({len(raw) % record} of {record} bytes)")
                raw += more
        data = np.frombuffer(raw, dtype="<f8").reshape(-1, ncols).astype(np.float64)
        yield index, data
        index += data.shape[0]


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
        bad = ~np.isfinite(data)
        if bad.any():
            r, c = np.argwhere(bad)[0]
            where = f"{unit} {first + r + (1 if unit == 'line' else 0)}"
            raise StreamError(f"{name}: {where}: column {columns[c]} = {float(data[r, c])} is not a finite number")
        t = np.concatenate([[last_t], data[:, t_col]])
        step = np.diff(t)
        if (step <= 0).any():
            r = int(np.flatnonzero(step <= 0)[0])
            where = f"{unit} {first + r + (1 if unit == 'line' else 0)}"
            raise StreamError(f"{name}: {where}: time t = {float(data[r, t_col])!r} does not increase")
        last_t = data[-1, t_col]
        yield data


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
