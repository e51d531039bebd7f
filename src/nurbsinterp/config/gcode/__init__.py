"""The G-code reader: an RS274/NGC program, as LinuxCNC reads it, as a path.

What it reads
    Line numbers ``N``, comments ``( )`` and ``;``, block delete ``/`` (the line is
    skipped), letters in either case, spaces anywhere outside comments (LinuxCNC
    drops them before it reads a line, so ``X 1 0 . 5`` is X10.5), ``%`` and
    ``M2``/``M30`` ends.  Expressions ``[...]`` wherever a number stands, with
    LinuxCNC's operators, functions, precedence and degrees (:mod:`.expr`);
    numbered, indirect, named local and global parameters, a line's assignments
    taking effect after it (:mod:`.params`); O-word subroutines, conditions and
    loops, run with a stated limit on the lines a program may repeat
    (:mod:`.program`).  Runs of plain lines (G0/G1 of numbers) are read by a
    compiled scanner and made moves together (:mod:`.fast`), bit for bit as the
    general reader makes them.
    Modes carried from block to block: ``G20``/``G21`` (inch or mm: everything
    read is converted to mm), ``G90``/``G91`` (absolute/incremental X Y Z),
    ``G90.1``/``G91.1`` (arc centres absolute/incremental, incremental by
    default), ``G17``/``G18``/``G19`` (arc and NURBS plane), ``G94`` (feed in
    units per minute; setting it leaves no feed until the next F, as in
    LinuxCNC), ``F`` and the motion mode.

Motion
    ``G0`` (a rapid: a straight block with ``rapid=True``), ``G1``, ``G2``/``G3``
    with ``I J K`` or ``R`` (full circles with ``I J K``; the third axis moving
    makes a helix; ``P`` turns), and three NURBS blocks:

    - LinuxCNC ``G5.2``/``G5.3``: ``G5.2 [P-] [X- Y-] [L-]``, then ``X- Y- P-``
      per control point (the plane's two axes: X Y in G17, Z X in G18, Y Z in
      G19), closed by ``G5.3``.  The current position is the first control
      point, weight 1 (or the ``P`` of a ``G5.2`` line without coordinates);
      ``L`` is the order (3 unless L > 3, as LinuxCNC takes it); the knots are
      LinuxCNC's: clamped, uniform, integer interior knots 1, 2, ...
    - LinuxCNC ``G6.2`` and Fanuc ``G06.2`` (the same number to a G-code
      reader): ``G6.2 [P-] K- [X- Y- Z-] [R-] [Q-]`` (the first control point:
      P the order, R the weight, K its knot), then ``[X- Y- Z-] K- [R-]`` per
      control point, then ``P`` blocks of a knot alone (``G6.2 K-`` or ``K-``):
      control points + P knots in all.  Coordinates not given keep the
      previous control point's (the first: the current position, which is how
      Fanuc lets the first point be left out); weights default to 1.  The
      order defaults to 4 (a cubic: Fanuc's default rank, and what CAM writes
      for it).  The knots must be non-decreasing and clamped (P equal knots at
      each end: Fanuc's alarms 1007/1008).  ``Q`` (LinuxCNC's choice of its own
      interpolation method) is read and ignored with a note: nurbsinterp
      interpolates the NURBS itself.  A first control point away from the
      current position is reached by a straight feed move (said in a note).

Feed
    Each feed block carries the F in effect as its own feedrate (mm/s); rapids
    carry none (the profile's ``rapid_feedrate`` applies); feed moves before
    any F carry none (the profile's ``feedrate`` applies, said in a note).

Machine coordinates and stored positions
    Blocks are in machine coordinates (mm), with the work offsets ``G54``..``G59.3``
    taken as zero.  ``G92`` (the current point is given the coordinates named),
    ``G92.1``/``G92.2`` (cleared; .1 also zeroes #5211..), ``G92.3`` (restored from
    #5211..) and ``G52`` (a local offset) shift the program's coordinates as
    LinuxCNC shifts them.  ``G53`` moves (with G0 or G1, absolute only) in machine
    coordinates.  ``G28``/``G30`` rapid through their intermediate point (X Y Z in
    the current mode) and then to the stored position — the named axes only, or
    all when none is named; ``G28.1``/``G30.1`` store the current position.  The
    stored positions are the machine origin unless given (``homes``, the CLI's
    ``--g28``/``--g30``), as rs274 without a parameter file; a note says which
    was used.

Modes that shape motion, carried per block (``mode``, ``stop``, ``dwell``)
    ``G61`` (exact path), ``G61.1`` (exact stop), ``G64 [P-] [Q-]`` (blend, P the
    path tolerance, Q the naive-CAM tolerance, defaulting to P as in LinuxCNC;
    both become mm).  ``G4 P-`` (dwell, seconds) and ``M0 M1 M6 M60 M66`` and the
    user M-codes ``M100``..``M199`` bring the tool to rest before the next block,
    as LinuxCNC waits on them (M6 before its line's motion, the others after it);
    ``S``, ``T`` without ``M6``, ``M3 M4 M5 M7 M8 M9`` do not: they must not break
    the look-ahead (LinuxCNC issue #1813).

Everything else
    G-codes that neither move the tool nor shape its motion (``G40``, ``G43``,
    ``G49``, ``G54``..``G59.3``, ``G80``, ``G96``/``G97`` …) and the M-codes
    above that do not stop it are accepted and listed once in the path's notes;
    S, T, H, D words likewise.  Codes that would move the tool in ways this reader
    does not model (``G10``, cutter compensation ``G41``/``G42``, canned cycles,
    ``G93``/``G95`` feed modes, other axes A B C U V W) are refused with the line,
    as is any code it does not know.  Zero-length moves (a G1 to where the tool
    already is) are dropped.

Every problem is one :class:`~nurbsinterp.errors.SpecError`:
``part.ngc:12: G2.2 is not a G-code this reader knows``.

Reading piece by piece
    The file is read in pieces of about a megabyte, cut at line ends, each
    executed as it comes (:class:`~.program.Flow`): a program of millions of
    lines is never held whole.  :func:`read_gcode` gathers every block into a
    path; :class:`ProgramStream` hands them on as they are made (the look-ahead
    planner reads programs so).  A program whose flow can jump — one holding an
    O-word — is read whole from its first O-word's piece on, as LinuxCNC seeks
    through the file; the blocks it makes still flow out one at a time.  Each
    piece is decoded on its own (UTF-8, else Latin-1): a program mixing both
    reads the same but for the characters of its comments.
"""
from __future__ import annotations

import hashlib
import math
import os

from ...errors import SpecError
from ..curve import MAX_COORDINATE
from ..reading import read_bytes
from .codes import ARC_REL_TOL, ARC_TOL, MM_PER_INCH, R_TOL_MM  # noqa: F401  (the tolerances tests name)
from .fast import scan
from .machine import Machine, execute, execute_run, path_of, program_notes
from .params import Parameters
from .program import Context, Flow, NotLinear, PlainRun, executed_lines


PIECE_BYTES = 1 << 20  # the file is read about this much at a time (cut at a line's end)


def read_gcode(name: str, start=None, homes: dict | None = None, *, fast: bool = True,
               piece_bytes: int = PIECE_BYTES):
    """The path of a G-code program (see the module docstring).

    Parameters
    ----------
    name : the program's file
    start : (x, y, z) mm where the tool is when the program starts (default the origin, as ``rs274``)
    homes : ``{"G28": (x, y, z), "G30": (x, y, z)}`` mm, machine coordinates: the stored positions
        G28 and G30 go to until the program stores its own (G28.1, G30.1); default the machine origin
    fast : runs of plain lines (G0/G1 of numbers: :mod:`.fast`) read by the compiled scanner and made
        moves together; False reads every line by the general reader (the tests' reference)
    piece_bytes : how much of the file is read at a time (the tests cut programs into tiny pieces)
    """
    machine = _machine(name, start, homes)
    for _ in _executed(machine, name, fast, piece_bytes):
        pass
    _closed(machine)
    return path_of(machine)


class ProgramStream:
    """A G-code program's blocks as they are made, 3-D, never the whole program held (the look-ahead's source).

    ``fingerprint`` names the input (the file's bytes and the reader's options), known before a block is read,
    so that a stream's header can carry it; ``notes`` (what :func:`read_gcode`'s path would note) are known
    once :meth:`items` is exhausted.  A program is 3-D here whatever its Z (its stream's columns are fixed
    before its last block is read), and may hold rapids."""

    dim = 3
    has_rapids = True

    def __init__(self, name: str, start=None, homes: dict | None = None, *, fast: bool = True,
                 piece_bytes: int = PIECE_BYTES):
        self.name = name
        self.start, self.homes, self.fast, self.piece_bytes = start, homes, fast, piece_bytes
        _machine(name, start, homes)  # its options refused before anything is read
        self.fingerprint = _file_fingerprint(name, (start, homes))
        self.notes: tuple = ()
        self.dropped = 0  # zero-length moves left out (known, as the notes, once the items are exhausted)

    def items(self):
        """The program's blocks in order: line and arc blocks, NURBS blocks, and runs of straight moves (items
        of kind ``"moves"``: arrays ``starts``, ``ends`` (n, 3), ``feeds`` (NaN: none), ``rapid``, ``lines``,
        with one ``mode``, and the ``stop``/``dwell`` of their first move)."""
        machine = _machine(self.name, self.start, self.homes)
        made = False
        for _ in _executed(machine, self.name, self.fast, self.piece_bytes):
            if machine.blocks:
                made = True
                yield from machine.blocks
                machine.blocks.clear()
        _closed(machine)
        if not made:
            path_of(machine)  # its refusal: the program moves nowhere
        self.notes = program_notes(machine)
        self.dropped = machine.dropped


def _machine(name: str, start, homes) -> Machine:
    params = Parameters()  # one store: the program's lines read it, the machine keeps #5420.. and #5161.. in it
    stored = {}
    for label, code in (("G28", 280), ("G30", 300)):
        if (homes or {}).get(label) is not None:
            stored[code] = _start(name, homes[label], f"{label} position", 3)
    return Machine(name, (0.0, 0.0, 0.0) if start is None else _start(name, start), params, stored)


def _executed(machine: Machine, name: str, fast: bool, piece_bytes: int):
    """Execute the program on *machine*, piece by piece (module docstring); yield after each item (a line, a
    run of plain lines), its blocks appended to ``machine.blocks``."""
    ctx = Context(name, machine.params)
    flow = Flow()
    for text in _pieces(name, piece_bytes):
        items = executed_lines(ctx, text, scan(text) if fast else None, flow=flow)
        try:
            item = next(items, None)
        except NotLinear:  # an O-word: the rest of the file is read whole, from this piece's first line
            whole = _read_text(name)
            items = executed_lines(ctx, whole, scan(whole) if fast else None, resume=flow.offset)
            item = next(items, None)
            flow.ended = True
        while item is not None:
            if _execute(machine, item):
                yield
                return
            yield
            item = next(items, None)
        if flow.ended:
            return
        flow.offset += text.count("\n") + (0 if text.endswith("\n") else 1)


def _execute(machine: Machine, item) -> bool:
    """Carry out one item of executed_lines; True at the program's end (M2, M30)."""
    if isinstance(item, PlainRun):
        execute_run(machine, item)
        return False
    return execute(machine, item)


def _closed(machine: Machine) -> None:
    if machine.nurbs is not None:
        nurbs = machine.nurbs
        what = "G5.3" if nurbs["kind"] == "G5.2" else f"{nurbs['order'] - nurbs['closing']} more knot-only blocks"
        raise machine.fail(nurbs["line"], f"{nurbs['kind']} is not closed: the program ends before {what}")


def _pieces(name: str, piece_bytes: int):
    """The program's text in pieces of about *piece_bytes*, each ending at a line's end (the last: the file's)."""
    with open_program(name) as fh:
        rest = b""
        while True:
            data = fh.read(piece_bytes)
            if not data:
                break
            data = rest + data
            cut = data.rfind(b"\n") + 1
            if cut == 0:  # no line end yet: a longer piece
                rest = data
                continue
            rest = data[cut:]
            yield _decoded(name, data[:cut])
        if rest or fh.tell() == 0:  # the last line without its line end; an empty file is one empty piece
            yield _decoded(name, rest)


def open_program(name: str):
    """The program's file open for reading in binary; a failure is one SpecError line."""
    try:
        if os.path.isdir(name):
            raise SpecError(f"{name}: is a directory, not a program")
        return open(name, "rb")
    except OSError as exc:
        raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None


def _file_fingerprint(name: str, options) -> str:
    """16 hex digits naming the program's bytes and the reader's options (its start point, stored homes)."""
    digest = hashlib.sha1(b"gcode" + repr(options).encode())
    with open_program(name) as fh:
        for data in iter(lambda: fh.read(1 << 20), b""):
            digest.update(data)
    return digest.hexdigest()[:16]


def _decoded(name: str, data: bytes) -> str:
    if b"\0" in data:
        raise SpecError(f"{name}: is not a text file (it holds NUL bytes)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")  # comments in old programs; the words themselves are ASCII


def _read_text(name: str) -> str:
    return _decoded(name, read_bytes(name, "program"))


def _start(name: str, start, what: str = "start position", sizes: int = 2) -> tuple:
    values = [float(v) for v in start]
    if len(values) == 2 and sizes == 2:
        values.append(0.0)
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in values):
        raise SpecError(f"{name}: the {what} {tuple(start)} must be {'2 or ' if sizes == 2 else ''}3 finite "
                        f"coordinates in mm (within +-{MAX_COORDINATE:g})")
    return tuple(values)


def read_gcode_job(name: str, *, start=None, g28=None, g30=None, **_options):
    """The G-code reader for :func:`~nurbsinterp.config.job.load_job`: (the path, no profile sections)."""
    return read_gcode(name, start, {"G28": g28, "G30": g30}), {}


def stream_gcode_job(name: str, *, start=None, g28=None, g30=None, **_options):
    """The streaming G-code reader for :func:`~nurbsinterp.config.job.load_job` (``stream=True``)."""
    return ProgramStream(name, start, {"G28": g28, "G30": g30}), {}
