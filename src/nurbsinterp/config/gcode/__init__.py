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
``part.ngc:12: G2.2 is not a G-code this reader knows``.  The whole program is
read before anything is returned.
"""
from __future__ import annotations

import math

from ...errors import SpecError
from ..curve import MAX_COORDINATE
from ..reading import read_bytes
from .codes import ARC_REL_TOL, ARC_TOL, MM_PER_INCH, R_TOL_MM  # noqa: F401  (the tolerances tests name)
from .fast import scan
from .machine import Machine, execute, execute_run, path_of
from .params import Parameters
from .program import Context, PlainRun, executed_lines


def read_gcode(name: str, start=None, homes: dict | None = None, *, fast: bool = True):
    """The path of a G-code program (see the module docstring).

    Parameters
    ----------
    name : the program's file
    start : (x, y, z) mm where the tool is when the program starts (default the origin, as ``rs274``)
    homes : ``{"G28": (x, y, z), "G30": (x, y, z)}`` mm, machine coordinates: the stored positions
        G28 and G30 go to until the program stores its own (G28.1, G30.1); default the machine origin
    fast : runs of plain lines (G0/G1 of numbers: :mod:`.fast`) read by the compiled scanner and made
        moves together; False reads every line by the general reader (the tests' reference)
    """
    text = _read_text(name)
    params = Parameters()  # one store: the program's lines read it, the machine keeps #5420.. and #5161.. in it
    stored = {}
    for label, code in (("G28", 280), ("G30", 300)):
        if (homes or {}).get(label) is not None:
            stored[code] = _start(name, homes[label], f"{label} position", 3)
    machine = Machine(name, (0.0, 0.0, 0.0) if start is None else _start(name, start), params, stored)
    for item in executed_lines(Context(name, params), text, scan(text) if fast else None):
        if isinstance(item, PlainRun):
            execute_run(machine, item)
        elif execute(machine, item):
            break
    if machine.nurbs is not None:
        nurbs = machine.nurbs
        what = "G5.3" if nurbs["kind"] == "G5.2" else f"{nurbs['order'] - nurbs['closing']} more knot-only blocks"
        raise machine.fail(nurbs["line"], f"{nurbs['kind']} is not closed: the program ends before {what}")
    return path_of(machine)


def _read_text(name: str) -> str:
    data = read_bytes(name, "program")
    if b"\0" in data:
        raise SpecError(f"{name}: is not a text file (it holds NUL bytes)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")  # comments in old programs; the words themselves are ASCII


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
