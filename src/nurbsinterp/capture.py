"""Captures of a real run: LinuxCNC ``halsampler`` output, read and aligned to the plan's ticks.

A user streams a plan into HAL (``halstreamer`` → ``streamer``) and records with
``sampler`` / ``halsampler``, every servo period, the commanded and the feedback
(encoder) positions.  :class:`Capture` reads that recording a chunk at a time
(NumPy parses each chunk; memory does not grow with the capture) and hands the
simulation one row per tick of the plan, so that the machine's contour error is
measured as the model's is (:func:`nurbsinterp.simulation.simulate`, ``actual=``).

The file
    One line per sample, the values whitespace-separated in the order of the
    sampler's ``cfg=`` string: floats as C's ``%f`` (6 decimals), s32/u32 as
    integers, bits as 0/1; with ``halsampler -t`` the sample number first.  A
    line ``overrun`` says the sampler's FIFO overflowed there: samples are lost.

The column map (:func:`parse_columns`)
    One name per capture column, comma-separated: ``k`` the plan's tick number
    (streamed on a streamer pin and sampled back: it aligns the capture to the
    plan), ``sample`` halsampler ``-t``'s sample number, ``x_cmd,y_cmd[,z_cmd]``
    the commands as the machine received them, ``x,y[,z]`` the measured
    (feedback) positions, ``-`` a column to ignore.  The feedback of every axis
    of the job is required; the commands are optional, but all of the job's axes
    or none; a name may appear once (``-`` any number of times); an axis the job
    does not have (``z`` for a 2-D job) must be ``-``.  Default
    (:func:`default_columns`): ``k,x_cmd,y_cmd,x,y``, in 3-D
    ``k,x_cmd,y_cmd,z_cmd,x,y,z`` (examples/linuxcnc/sim-machine.hal).

Alignment
    With a ``k`` column: rows holding k's first value before it starts
    counting (the streamer holding its pins before the stream) are dropped
    but the last, which is tick k; counting must then start at tick 0 (a
    capture that starts at tick 5 missed commands and is refused).  When the
    held first value is not 0 and k then drops to 0 (the pins still holding an
    earlier stream's last tick), every held row is dropped and the row with
    k = 0 is tick 0.  While the stream runs k goes up by exactly 1 per row.
    Once k repeats, the stream has ended: the rows holding the last k are the
    hold (the command held while the table settles) -- if that k is the plan's
    last tick; if the plan goes on, the capture is refused (another plan, or
    the streamer ran dry).  k must not change again after that (one run per
    capture).  Without ``k``: row i is tick i (the capture started with the
    stream, as a sampler enabled only while the streamer has data); the rows
    after the plan's last tick are the hold.  The sample period is taken to be
    the plan's T (the sampler and the streamer in the same thread): with ``k``
    this is checked (one tick per row); without it, it cannot be.

Refusals (:class:`~nurbsinterp.errors.StreamError`, one line ``FILE:LINE: ...``
naming the value): an ``overrun`` line, a wrong count of columns, a non-number,
NaN or inf, an empty line before more samples (halsampler writes none; empty
lines at the end are ignored), ``k`` or ``sample`` not an integer, a gap in
``sample`` (it goes up by exactly 1), a gap or a repeat of ``k`` while the
stream runs, ``k`` changing after the stream ended, an empty capture, and a
capture that does not cover every command of the plan or goes on past its last
tick.  A bad map is a :class:`~nurbsinterp.errors.UsageError` naming the option.

Every row of the file is checked, including the hold rows past what the
simulation measures: a capture with lost samples anywhere is refused.

Writing one (:class:`CaptureWriter`)
    The model's own run as halsampler would record it from a machine that ran it, for trying ``identify`` and
    ``simulate --actual`` without HAL: the default columns, one line per tick of the run (the commands, then the
    hold, k holding the last command's tick), each value followed by one space as halsampler prints it (``%ld ``
    for k, ``%f `` for the rest).  The feedback may be made a real encoder's: Gaussian noise, then a count.
"""
from __future__ import annotations

import io
import re
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .errors import NurbsInterpError, StreamError, UsageError

AXES = ("x", "y", "z")
NAMES = ("k", "sample", "x_cmd", "y_cmd", "z_cmd", "x", "y", "z", "-")
IGNORE = "-"
CHUNK_BYTES = 1 << 20  # about 15 k lines of 7 columns parsed at a time
_EXACT = 2.0 ** 53  # integers beyond this are not exact in float64
#: a capture's command may differ from the plan's by %f's rounding (5e-7 mm), the CSV stream's 9 decimals
#: (5e-10 mm) and the decimal-binary conversions (an ulp): RECEIVED_ABS is twice that, RECEIVED_REL a
#: margin for coordinates far from the origin; a capture of another plan or one tick off is far beyond it
RECEIVED_ABS = 1e-6  # mm
RECEIVED_REL = 1e-9
_NUMBER = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[+-]?(?:nan|inf|infinity)", re.IGNORECASE)


def default_columns(dim: int) -> str:
    """The default map for a *dim*-D job: the layout of examples/linuxcnc/sim-machine.hal."""
    axes = AXES[:dim]
    return ",".join(["k", *(f"{a}_cmd" for a in axes), *axes])


@dataclass(frozen=True)
class CaptureColumns:
    """A validated column map: the index of each named column in a capture row (-1: absent).

    names : the map as given, one name per capture column
    axes : the job's axes
    position : the columns of the measured positions, one per axis
    command : the columns of the received commands, one per axis, or None
    """

    names: tuple
    axes: tuple
    k: int
    sample: int
    position: tuple
    command: tuple | None

    @property
    def text(self) -> str:
        return ",".join(self.names)


def parse_columns(text: str, dim: int, option: str = "the column map") -> CaptureColumns:
    """Check a column map against the names and the job's *dim* axes; UsageError naming *option* (how the
    caller's user gave the map: the CLI passes its option) otherwise."""
    names = tuple(n.strip() for n in str(text).split(","))
    where = f"{option} {text!r}"
    for i, n in enumerate(names):
        if n not in NAMES:
            raise UsageError(f"{where}: column {i + 1} {n!r} is not a name of the map "
                             f"(use {', '.join(NAMES[:-1])} or - to ignore a column)")
    seen = {}
    for i, n in enumerate(names):
        if n != IGNORE and n in seen:
            raise UsageError(f"{where}: {n!r} names columns {seen[n] + 1} and {i + 1}; each name may appear once")
        seen.setdefault(n, i)
    axes = AXES[:dim]
    for extra in AXES[dim:]:
        for n in (extra, f"{extra}_cmd"):
            if n in seen:
                raise UsageError(f"{where}: the job is {dim}-D and has no {extra} axis: map column {seen[n] + 1} "
                                 "as - to ignore it")
    missing = [a for a in axes if a not in seen]
    if missing:
        raise UsageError(f"{where}: no feedback column for the job's {missing[0]} axis: the capture must "
                         f"hold the measured position of every axis ({','.join(axes)})")
    cmds = [f"{a}_cmd" for a in axes]
    given = [c for c in cmds if c in seen]
    if given and len(given) != len(cmds):
        absent = next(c for c in cmds if c not in seen)
        raise UsageError(f"{where}: {given[0]} without {absent}: give the received command of every axis "
                         "of the job, or of none")
    return CaptureColumns(names=names, axes=axes, k=seen.get("k", -1), sample=seen.get("sample", -1),
                          position=tuple(seen[a] for a in axes),
                          command=tuple(seen[c] for c in cmds) if given else None)


class Block(NamedTuple):
    """Capture rows aligned to ticks: measured positions (m, axes), received commands (m, axes) or None,
    and the line of the file each row came from (m,)."""

    position: np.ndarray
    command: np.ndarray | None
    line: np.ndarray


class NotThisPlan(StreamError):
    """The capture is not of the plan it is measured against: its received commands differ (*commands_differ*), or
    it covers other ticks -- which, where its commands matched every tick before, is a fault of the run (the
    streamer ran dry, the sampler stopped early), not another plan.  `compare --actual` tries the next plan on
    the first; every other fault of the capture is its own."""

    def __init__(self, message, commands_differ: bool = False):
        super().__init__(message)
        self.commands_differ = commands_differ


def received_deviation(name, tick, axes, cmd, block, check=True, hint="") -> np.ndarray:
    """The largest |received command - plan's command| per axis over the rows of *block* (ticks tick..);
    with *check*, a StreamError naming the line where one is beyond %f's rounding (RECEIVED_ABS): the capture
    is of another plan, or not aligned to it.  *hint* ends that message (how the caller's user goes on anyway)."""
    dev = np.abs(block.command - cmd)
    if check:
        over = dev > RECEIVED_ABS + RECEIVED_REL * np.abs(cmd)
        if over.any():
            r, c = (int(i) for i in np.argwhere(over)[0])
            a = axes[c]
            raise NotThisPlan(f"{name}:{int(block.line[r])}: tick {tick + r}: {a}_cmd = "
                              f"{float(block.command[r, c]):.6f} is {float(dev[r, c]):.3g} mm from the plan's "
                              f"{a} = {float(cmd[r, c]):.9f}, more than %f's rounding ({RECEIVED_ABS:g} mm): "
                              f"the capture is not of this plan, or not aligned to it{hint}", commands_differ=True)
    return dev.max(axis=0)


class _Queue:
    """Parsed rows waiting for the simulation: pushed a chunk at a time, pulled any number at a time."""

    def __init__(self):
        self.parts = []  # (rows (n, ncols), lines (n,))
        self.size = 0

    def push(self, rows, lines):
        if rows.shape[0]:
            self.parts.append((rows, lines))
            self.size += rows.shape[0]

    def first_line(self) -> int:
        return int(self.parts[0][1][0])

    def pull(self, m):
        """(rows, lines) of the first m rows (m <= size)."""
        rows, lines, got = [], [], 0
        while got < m:
            r, ln = self.parts[0]
            take = min(m - got, r.shape[0])
            rows.append(r[:take])
            lines.append(ln[:take])
            if take == r.shape[0]:
                self.parts.pop(0)
            else:
                self.parts[0] = (r[take:], ln[take:])
            got += take
        self.size -= m
        if len(rows) == 1:
            return rows[0], lines[0]
        return (np.concatenate(rows) if rows else np.empty((0, 0))), (np.concatenate(lines) if lines
                                                                       else np.empty(0, np.int64))

    def clear(self):
        self.parts, self.size = [], 0


_LEAD, _RUN, _HELD = range(3)


class Capture:
    """A halsampler capture, read lazily and aligned to the plan's ticks (module docstring).

    The simulation asks for the rows of the commands (:meth:`commands`), says where the
    commands end (:meth:`end_commands`), takes hold rows (:meth:`hold`) and lets the rest be
    read and checked (:meth:`finish`).  Afterwards: ``lead_rows`` (leading rows dropped),
    ``hold_rows`` (rows of the capture after the plan's last tick), ``lines`` (lines read).

    Parameters
    ----------
    fh : binary file object
    name : how messages name the file
    columns : a :class:`CaptureColumns`
    chunk_bytes : about how much of the file is parsed at a time
    """

    def __init__(self, fh, name: str, columns: CaptureColumns, chunk_bytes: int = CHUNK_BYTES):
        self.fh, self.name, self.columns = fh, name, columns
        self.chunk_bytes = chunk_bytes
        self.ncols = len(columns.names)
        self._position = np.array(columns.position, dtype=np.int64)
        self._command = None if columns.command is None else np.array(columns.command, dtype=np.int64)
        self._run, self._hold = _Queue(), _Queue()
        self._next_line = 1  # the number of the next line to read
        self._blank = 0  # an empty line not yet followed by a sample (0: none)
        self._rows = 0  # samples read
        self._eof = False
        self._ended = False  # the plan's commands are over: new rows are the hold
        self._last_sample = None
        self._phase = _LEAD if columns.k >= 0 else _RUN
        self._k0 = None  # k's first value
        self._lead = None  # the last leading row so far: (row (1, ncols), line)
        self._k_last = -1.0  # the last tick given to the run
        self._held_line = 0  # where k started to hold
        self.ticks = 0  # rows given to the simulation as ticks of the commands
        self.lead_rows = 0
        self.hold_rows = 0

    # ------------------------------------------------------------------ what the simulation calls

    @property
    def has_commands(self) -> bool:
        return self._command is not None

    def commands(self, m: int) -> Block:
        """The rows of the next m ticks of the plan's commands; StreamError if the capture does not hold them."""
        while self._run.size < m and self._phase != _HELD and self._more():
            pass
        if self._run.size < m:
            have = self.ticks + self._run.size
            if self._phase == _HELD:
                raise NotThisPlan(f"{self.name}:{self._held_line}: k stays at {self._k_last:.0f} from this line on, "
                                  f"and the plan's commands go on to tick {have} and beyond: the capture must cover "
                                  "every command (is it of this plan? did the streamer run dry?)")
            last = self._next_line - 1
            what = "holds no tick" if have == 0 else f"ends at tick {have - 1}"
            raise NotThisPlan(f"{self.name}:{last}: the capture {what} (its last line), and the plan's commands go on "
                              f"to tick {have} and beyond: the capture must cover every command (start the sampler "
                              "before the stream, stop it after the last tick)")
        self.ticks += m
        return self._block(*self._run.pull(m))

    def end_commands(self) -> None:
        """The plan has no more ticks: the capture's stream must end here too; what follows is the hold."""
        self._ended = True
        if self.columns.k >= 0:
            while self._run.size == 0 and self._phase != _HELD and self._more():
                pass
            if self._run.size:
                line = self._run.first_line()
                raise NotThisPlan(f"{self.name}:{line}: k = {self.ticks} goes on past the plan's last tick "
                                  f"{self.ticks - 1}: is the capture of this plan?")
        else:
            self.hold_rows += self._run.size
            self._hold, self._run = self._run, _Queue()

    def hold(self, m: int) -> Block:
        """Up to m rows of the capture's hold (fewer, none, where it ends)."""
        while self._hold.size < m and self._more():
            pass
        return self._block(*self._hold.pull(min(m, self._hold.size)))

    def finish(self) -> None:
        """Read and check the rest of the capture (its hold rows are counted, not kept)."""
        self._hold.clear()
        while self._more():
            self._hold.clear()

    # ------------------------------------------------------------------ reading

    def _block(self, rows, lines) -> Block:
        if rows.shape[0] == 0:
            empty = np.empty((0, len(self._position)))
            return Block(empty, None if self._command is None else empty, np.empty(0, np.int64))
        cmd = None if self._command is None else np.ascontiguousarray(rows[:, self._command])
        return Block(np.ascontiguousarray(rows[:, self._position]), cmd, lines)

    def _more(self) -> bool:
        """Read, check and align the next chunk; False at the end of the file (checked there)."""
        while not self._eof:
            lines = self.fh.readlines(self.chunk_bytes)
            if not lines:
                self._eof = True
                self._at_end()
                return False
            first = self._next_line
            self._next_line += len(lines)
            data = self._parse(lines, first)
            if data.shape[0]:
                self._align(data, first + np.arange(data.shape[0], dtype=np.int64))
                return True
        return False

    def _at_end(self):
        if self._rows == 0:
            raise StreamError(f"{self.name}: the capture is empty: no samples (did halsampler run?)")
        if self._phase == _LEAD:
            raise StreamError(f"{self.name}: k holds {self._k0:.0f} on all {self._rows} lines: the capture never saw "
                              "the stream run")

    def _parse(self, lines, first) -> np.ndarray:
        """The chunk's samples (n, ncols): NumPy's parser; any fault is found and named line by line."""
        data = None
        text = b"".join(lines)
        if not self._blank and not text.isspace():
            try:
                data = np.loadtxt(io.StringIO(text.decode("ascii")), dtype=np.float64, comments=None, ndmin=2)
            except (ValueError, UnicodeDecodeError):
                data = None
        if data is None or data.shape != (len(lines), self.ncols):
            data = self._diagnose(lines, first)
        elif not np.isfinite(data).all():
            r, c = np.argwhere(~np.isfinite(data))[0]
            self._not_finite(first + int(r), int(c), float(data[r, c]))
        self._rows += data.shape[0]
        return data

    def _diagnose(self, lines, first) -> np.ndarray:
        """The slow path of :meth:`_parse`: the first fault, by line; the rows if there is none
        (a chunk that only ends in empty lines)."""
        rows = []
        for j, raw in enumerate(lines):
            no = first + j
            text = raw.strip()
            if not text:
                self._blank = self._blank or no
                continue
            if self._blank:
                raise StreamError(f"{self.name}:{self._blank}: an empty line among the samples (halsampler writes "
                                  "none): is this a halsampler capture?")
            if text == b"overrun":
                raise StreamError(f"{self.name}:{no}: halsampler lost samples here (overrun): enlarge the sampler's "
                                  "depth (loadrt sampler depth=...) or the priority of halsampler, and capture again")
            fields = text.split()
            if len(fields) != self.ncols:
                raise StreamError(f"{self.name}:{no}: {len(fields)} values, the column map "
                                  f"{self.columns.text!r} names {self.ncols}")
            for c, f in enumerate(fields):
                if not _NUMBER.fullmatch(f):
                    raise StreamError(f"{self.name}:{no}: column {c + 1} ({self.columns.names[c]}) = "
                                      f"{f[:40].decode('ascii', 'replace')!r} is not a number")
            values = [float(f) for f in fields]
            for c, v in enumerate(values):
                if not np.isfinite(v):
                    self._not_finite(no, c, v)
            rows.append(values)
        return np.array(rows, dtype=np.float64).reshape(len(rows), self.ncols)

    def _not_finite(self, line, c, value):
        raise StreamError(f"{self.name}:{line}: column {c + 1} ({self.columns.names[c]}) = {value} "
                          "is not a finite number")

    # ------------------------------------------------------------------ alignment

    def _align(self, data, lines):
        """Check sample and k, and hand the rows to the run or the hold (module docstring)."""
        m = data.shape[0]
        cut, fault = m, None  # the first row at fault in the checks that need no state but the last value
        for col in (self.columns.sample, self.columns.k):
            if col < 0:
                continue
            v = data[:, col]
            bad = np.flatnonzero((v != np.floor(v)) | (np.abs(v) >= _EXACT))
            if bad.size and bad[0] < cut:
                cut, fault = int(bad[0]), ("integer", col)
        if self.columns.sample >= 0 and cut:
            s = data[:cut, self.columns.sample]
            prev = s[0] - 1 if self._last_sample is None else self._last_sample
            gap = np.flatnonzero(np.diff(s, prepend=prev) != 1.0)
            if gap.size and gap[0] < cut:
                cut, fault = int(gap[0]), ("sample", prev if gap[0] == 0 else s[gap[0] - 1])
            if cut:
                self._last_sample = float(s[cut - 1])
        if self.columns.k >= 0:
            self._align_k(data[:cut], lines[:cut])
        else:
            (self._hold if self._ended else self._run).push(data[:cut], lines[:cut])
            if self._ended:
                self.hold_rows += cut
        if fault is None:
            return
        line = int(lines[cut])
        kind, arg = fault
        if kind == "integer":
            name = self.columns.names[arg]
            what = "a tick number" if name == "k" else "a sample number"
            raise StreamError(f"{self.name}:{line}: {name} = {float(data[cut, arg])!r} is not {what} (an integer)")
        now = data[cut, self.columns.sample]
        if now > arg:
            raise StreamError(f"{self.name}:{line}: sample = {now:.0f} follows sample = {arg:.0f}: halsampler lost "
                              f"{now - arg - 1:.0f} samples before this line")
        raise StreamError(f"{self.name}:{line}: sample = {now:.0f} follows sample = {arg:.0f}: the samples are out "
                          "of order (two captures in one file?)")

    def _align_k(self, data, lines):
        m = data.shape[0]
        if m == 0:
            return
        k = data[:, self.columns.k]
        i = 0
        if self._phase == _LEAD:
            if self._k0 is None:
                self._k0 = float(k[0])
            change = np.flatnonzero(k != self._k0)
            if change.size == 0:
                self._lead = (data[m - 1:m], lines[m - 1:m])
                self.lead_rows += m
                return
            j = int(change[0])
            if j > 0:
                self._lead = (data[j - 1:j], lines[j - 1:j])
            self.lead_rows += j
            first = float(k[j])
            k0 = self._k0
            if first == 0:  # the pins held an earlier stream's last tick: every leading row is dropped
                self._k_last = -1.0
            elif first == k0 + 1:
                if k0 != 0:
                    raise StreamError(f"{self.name}:{int(self._lead[1][0])}: the capture starts at tick k = {k0:.0f}: "
                                      "it must cover every command from tick 0 (start the sampler before the stream)")
                self.lead_rows -= 1  # the last leading row is tick 0
                self._run.push(*self._lead)
                self._k_last = 0.0
            else:
                raise StreamError(f"{self.name}:{int(lines[j])}: k = {first:.0f} follows k = {k0:.0f}, held from the "
                                  "first sample: the stream must start at tick 0 and count up by 1")
            self._lead = None
            self._phase = _RUN
            i = j
        if self._phase == _RUN:
            step = np.diff(k[i:], prepend=self._k_last)
            bad = np.flatnonzero(step != 1.0)
            stop = i + int(bad[0]) if bad.size else m
            self._run.push(data[i:stop], lines[i:stop])
            if stop > i:
                self._k_last = float(k[stop - 1])
            if stop == m:
                return
            now = float(k[stop])
            if now != self._k_last:
                lost = f"{now - self._k_last - 1:.0f} ticks lost" if now > self._k_last else "k went back"
                raise StreamError(f"{self.name}:{int(lines[stop])}: k = {now:.0f} follows k = {self._k_last:.0f} while "
                                  f"the stream runs ({lost}): is the capture of one run of this plan?")
            self._phase = _HELD
            self._held_line = int(lines[stop])
            i = stop
        rest = k[i:]
        bad = np.flatnonzero(rest != self._k_last)
        stop = i + int(bad[0]) if bad.size else m
        self._hold.push(data[i:stop], lines[i:stop])
        self.hold_rows += stop - i
        if stop == m:
            return
        now = float(k[stop])
        if now == self._k_last + 1:
            raise StreamError(f"{self.name}:{int(lines[stop])}: k = {now:.0f} resumes after holding "
                              f"{self._k_last:.0f} from line {self._held_line}: the streamer ran out of data there "
                              "(an underrun): enlarge the streamer's depth and capture again")
        raise StreamError(f"{self.name}:{int(lines[stop])}: k = {now:.0f} after the stream ended at tick "
                          f"{self._k_last:.0f} (held from line {self._held_line}): a capture holds one run of the "
                          "plan; cut it before this line")


class CaptureWriter:
    """The model's run of a plan written as a halsampler capture in the default columns (:func:`default_columns`).

    The simulation's trace (rows in *columns*: its ``k``, ``{a}_cmd`` and ``{a}_act``) goes in through
    :meth:`write` a chunk at a time, and the plan's chunks pass through :meth:`through` on their way to the
    simulation: a traced row past the plan's rows is the hold, written with k held at the last command's tick, as
    a streamer that has run dry holds its pins.  Nothing is kept but the count of the plan's rows.

    Parameters
    ----------
    fh : binary file object
    columns : the trace's column names (simulation.trace_columns)
    noise : float, mm
        standard deviation of the Gaussian noise added to the feedback positions (never to the commands, nor
        to what the simulated controller acted on: it is the recording's); 0 for none
    encoder : dict axis -> mm per count or None
        each axis' feedback rounded to the nearest multiple of its count after the noise, as an encoder reports
        it (the servo kernel's rounding, floor(p/q + 1/2) q); None or a missing axis: not rounded
    seed : int
        of the noise (numpy's default_rng): a run is reproducible
    """

    def __init__(self, fh, columns, noise: float = 0.0, encoder: dict | None = None, seed: int = 0):
        columns = list(columns)
        self.fh = fh
        self.axes = [a for a in AXES if f"{a}_act" in columns]
        self._k = columns.index("k")
        self._cmd = [columns.index(f"{a}_cmd") for a in self.axes]
        self._act = [columns.index(f"{a}_act") for a in self.axes]
        self.noise = float(noise)
        counts = encoder or {}
        self._count = np.array([counts.get(a) or 0.0 for a in self.axes], dtype=np.float64)
        self._rng = np.random.default_rng(seed)
        self._line = "%d " + "%f " * (2 * len(self.axes)) + "\n"  # halsampler's: a space after every value
        self.commands = 0  # the plan's rows passed through so far

    def through(self, chunks):
        """The plan's *chunks*, unchanged, counted on their way to the simulation."""
        for data in chunks:
            self.commands += data.shape[0]
            yield data

    def write(self, rows: np.ndarray) -> None:
        """Write the lines of the traced *rows* (m, columns)."""
        m = rows.shape[0]
        if m == 0:
            return
        if self.commands == 0:
            raise ValueError("the trace reached the capture before any of the plan's rows: pass the plan's chunks "
                             "through CaptureWriter.through")
        out = np.empty((m, 1 + 2 * len(self.axes)))
        # the hold: k stays at the last tick of the commands the streamer sent
        np.minimum(rows[:, self._k], self.commands - 1, out=out[:, 0])
        out[:, 1:1 + len(self.axes)] = rows[:, self._cmd]
        feedback = out[:, 1 + len(self.axes):]
        feedback[:] = rows[:, self._act]
        if self.noise > 0.0:
            feedback += self.noise * self._rng.standard_normal(feedback.shape)
        counted = self._count > 0.0
        if counted.any():
            q = self._count[counted]
            feedback[:, counted] = np.floor(feedback[:, counted] / q + 0.5) * q
        if not np.isfinite(out).all():  # %f would print nan or inf, which no capture holds
            r = int(np.flatnonzero(~np.isfinite(out).all(axis=1))[0])
            raise NurbsInterpError(f"refusing to write a non-finite value to the capture (tick k = "
                                   f"{rows[r, self._k]:.0f})")
        self.fh.write(((self._line * m) % tuple(out.ravel().tolist())).encode("ascii"))
