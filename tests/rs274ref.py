"""LinuxCNC's standalone interpreter ``rs274`` as a reference G-code reader, for tests only.

``rs274`` (Debian package ``linuxcnc-uspace``) runs the real RS274/NGC
interpreter against a dummy machine that prints every canonical call it
receives, one a line::

       12 N..... STRAIGHT_FEED(10.1235, 2.0000, 3.0000, 0.0000, 0.0000, 0.0000)
       13 N20    ARC_FEED(20.1235, 2.0000, 15.1235, 2.0000, -1, 3.0000, 0.0000, 0.0000, 0.0000)

(the output's own line number; the block's N word, or ``N.....``; the call).
This module runs it and turns that output into moves in mm, absolute, 3-D,
tracking the current position from the origin, so that a test can compare them
with :func:`nurbsinterp.config.gcode.read_gcode_job`'s blocks.  Nothing here is
shared with that reader.

Conventions of rs274's output (LinuxCNC 2.9, ``src/emc/sai/saicanon.cc``)
-------------------------------------------------------------------------
- Invocation: ``rs274 -g [-b] program.ngc < /dev/null``.  ``-g`` is batch mode
  (no menu on stdin); ``-b`` turns the block-delete switch ON, so that lines
  starting with ``/`` are skipped (rs274's default is OFF: they run).  No tool
  table, variable file or INI file is needed for G0–G3.  An error ends the run
  with exit status 1 and the message, and the offending line, on stderr.
  rs274 keeps its tool table in ``$HOME/.tool.mmap``, truncated and mapped
  shared at start: concurrent runs sharing a HOME die of SIGBUS, so each run
  here gets its own.
- Units: every length is printed in the *program's* units at the time of the
  call (after ``USE_LENGTH_UNITS(CANON_UNITS_INCHES)``, inches); the
  interpreter converts its current position when G20/G21 switch.  Feeds
  (``SET_FEED_RATE``) are in program units per minute.  A units switch prints
  no new ``SET_FEED_RATE`` (LinuxCNC keeps the speed in effect).  Within a line
  the F word is executed *before* G20/G21 (LinuxCNC's order of execution), so
  ``G20 G1 X1 F10`` after G21 sets 10 mm/min: ``SET_FEED_RATE`` comes before
  ``USE_LENGTH_UNITS`` and is read in the units in effect when it is printed.
- Digits: ``%.4f`` everywhere, so a printed length is within half a unit of
  the 4th decimal of the true value: 5e-5 mm in G21, 5e-5 in = 1.27e-3 mm in
  G20 (:data:`HALF_STEP`).
- ``STRAIGHT_TRAVERSE(x, y, z, a, b, c)`` (G0) and ``STRAIGHT_FEED(...)`` (G1):
  the end point.  A G1 or G0 without axis words prints a zero-length move.
- ``ARC_FEED(first_end, second_end, first_axis, second_axis, rotation,
  axis_end_point, a, b, c)``: the end in the plane, the centre in the plane,
  the turn, and the end along the plane's normal axis (a helix when it moves).
  The plane is the last ``SELECT_PLANE``: XY (G17) first = X, second = Y,
  axis = Z; XZ (G18) first = Z, second = X, axis = Y; YZ (G19) first = Y,
  second = Z, axis = X.  So first × second is always +axis, and *rotation* > 0
  (G3) turns counter-clockwise about +axis, < 0 (G2) clockwise; ``|rotation|``
  is the number of turns begun (P word, default 1): ``|rotation| - 1`` extra
  full circles.  An arc whose end equals its start in the plane is a full
  circle.
- ``NURBS_FEED(n, ...)`` (G5.2 ... G5.3) prints only the number of control
  points *n* (the start point included); no degree, weights, knots or end
  point, so the position after it is unknown here (``None``).  The installed
  build (2.9.0~pre1, 2023) knows G5.2 in the XY plane only: in G18/G19 it stops
  with "You must specify both X and Y coordinates for Control Points"; and it
  does not know G6.2 at all ("Unknown g code used").  LinuxCNC's master prints
  G6.2 as ``saicanon NURBS_G6_FEED_(n, ...)``, without the output's line
  number (read here too, as a NURBS move of *n* control points).
- Coordinates are the *program's* (the current work coordinate system,
  G5x + G92 offsets applied), as the interpreter hands them to the canon, which
  adds the offsets to reach the machine: so G53, G28 and G30 moves are printed
  as their machine target minus the offsets in effect.  ``SET_G5X_OFFSET(index,
  x, y, z, a, b, c)`` and ``SET_G92_OFFSET(x, y, z, a, b, c)`` are printed (in
  the units in effect, 4 decimals) whenever the offsets change: at start (all
  0 without a variable file), at G92/G92.1/G92.2/G92.3, G10 L2 and at M2/M30.
  A units switch prints no new offset (the interpreter converts its own).
  This module adds the two offsets, in mm as printed, to every point, so a
  move is in *machine* coordinates: the frame of the G-code reader, which
  applies G92 as LinuxCNC does and takes G54..G59.3 to be zero.  Tool-length
  offsets (``USE_TOOL_LENGTH_OFFSET``, G43) are zero: rs274 runs with a table of zero-length tools
  (its own gives T1 12.9794 mm), as the reader takes tool lengths. Otherwise they would not be added: a move is the
  controlled point, as the reader (which ignores G43) reads it.
  ``SET_XY_ROTATION`` other than 0 is refused.
- G28 / G30: two ``STRAIGHT_TRAVERSE`` calls, to the intermediate point (the
  axis words, in the distance mode in effect: ``G28 G91 Z0`` goes nowhere)
  and then to the stored position (#5161.. / #5181.., machine coordinates,
  0 without a variable file) for the axes named (all axes if none is).
  G28.1/G30.1 print nothing.  ``G53 G0 Z0`` prints one traverse.
- Path-control mode: ``SET_MOTION_CONTROL_MODE(CANON_EXACT_PATH)`` (G61),
  ``(CANON_EXACT_STOP)`` (G61.1), ``(CANON_CONTINUOUS, p)`` (G64, ``%f``: P in
  program units, 0.000000 for G64 without P), each followed for G64 by
  ``SET_NAIVECAM_TOLERANCE(q)`` (``%.4f``; Q, or P when Q is not given, or 0).
  Before any of them LinuxCNC is in G64 without P.  P 0 and no P are the
  same to LinuxCNC (no limit on the blend), and Q 0 turns the naive-CAM
  merging off: both are read here as None.  :class:`Mode` holds the mode
  in mm.
- Stops: ``PROGRAM_STOP()`` (M0), ``OPTIONAL_PROGRAM_STOP()`` (M1: printed
  whatever the switch), ``PALLET_SHUTTLE()`` then ``PROGRAM_STOP()`` (M60),
  ``SELECT_TOOL(t) START_CHANGE() STOP_SPINDLE_TURNING(0) CHANGE_TOOL(t)``
  (M6; LinuxCNC's master prints ``CHANGE_TOOL()``); ``PALLET_SHUTTLE()`` then
  ``PROGRAM_END()`` is M30.  ``DWELL(s)`` (G4 P, seconds, ``%.4f``): a stop "G4" in
  ``Move.stops`` (motion comes to rest before a dwell, even of 0 s) and its seconds in ``Move.dwell``.  Within a
  line LinuxCNC's order of execution holds: G4, M6 and the mode (G61, G64)
  come before the line's motion, M0 M1 M60 after it, so that a stop or dwell
  printed between two moves belongs to the joint before the second (``Move.stops``,
  ``Move.dwell``).
- Feed: ``SET_FEED_RATE(0.0000)`` is printed at start and by G94: no F yet
  (read here as None); rs274 refuses a feed move at zero feed ("Cannot do g1
  with zero feed rate"), as LinuxCNC does.
- A refused program still prints the calls before the refusal:
  :class:`Rs274Error` keeps the moves made (``moves``) and the offending line
  (``line``, as rs274 echoes it on stderr).
"""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

RS274 = shutil.which("rs274")
MM_PER_UNIT = {"CANON_UNITS_MM": 1.0, "CANON_UNITS_INCHES": 25.4}
#: Half the step of rs274's %.4f, in program units: the largest rounding of a printed length.
HALF_STEP = 0.5e-4
#: (first, second, axis) coordinate indices of ARC_FEED in each plane, and the plane's +axis.
PLANES = {
    "CANON_PLANE_XY": ((0, 1, 2), np.array([0.0, 0.0, 1.0])),
    "CANON_PLANE_XZ": ((2, 0, 1), np.array([0.0, 1.0, 0.0])),
    "CANON_PLANE_YZ": ((1, 2, 0), np.array([1.0, 0.0, 0.0])),
}
PLANE_NAMES = {"CANON_PLANE_XY": "xy", "CANON_PLANE_XZ": "zx", "CANON_PLANE_YZ": "yz"}  # path.py's names
#: Canonical calls that move the tool; any other call with one of these words in its name is refused.
MOTIONS = ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED", "ARC_FEED", "NURBS_FEED")
MOTION_WORDS = ("TRAVERSE", "_FEED(", "PROBE", "TAP")
TIMEOUT = 600.0  # s: only to catch a hang; rs274 takes ~20 ms on a 20-move program, ~3 s on 150 000 lines
#: Half the step of SET_MOTION_CONTROL_MODE's %f (P) and SET_NAIVECAM_TOLERANCE's %.4f (Q), program units.
HALF_STEP_P, HALF_STEP_Q = 0.5e-6, 0.5e-4
CONTROL_MODES = {"CANON_CONTINUOUS": "blend", "CANON_EXACT_PATH": "exact_path", "CANON_EXACT_STOP": "exact_stop"}
#: The canonical call that stops motion between two moves -> the M word that asks for it.
STOPS = {"PROGRAM_STOP": "M0", "OPTIONAL_PROGRAM_STOP": "M1", "CHANGE_TOOL": "M6"}

_LINE = re.compile(r"^\s*(\d+) (N\S*)\s+([A-Z_0-9]+)\((.*)\)\s*$")
#: LinuxCNC master's G6.2 line, printed without the output's line number.
_G6_LINE = re.compile(r"^\s*(N\S*)\s+saicanon NURBS_G6_FEED_\((\d+), \.\.\.\)\s*$")


class Rs274Error(RuntimeError):
    """rs274 refused a program: *message* is its stderr, *line* the offending line it echoes.

    *moves* are the moves it made before the refusal (None when not parsed)."""

    def __init__(self, path: str, status: int, message: str, output: str = ""):
        super().__init__(f"rs274 refused {path} (exit status {status}): {message.strip()}")
        self.message = message
        lines = [row for row in message.strip().splitlines() if row.strip()]
        self.reason = lines[0] if lines else ""
        self.line = lines[1] if len(lines) > 1 else ""
        self.output = output
        self.moves: list | None = None


@dataclass(frozen=True)
class Mode:
    """LinuxCNC's path-control mode (see the module's notes): *control* "blend" (G64), "exact_path"
    (G61) or "exact_stop" (G61.1); *tolerance* (G64 P) and *naive_tolerance* (G64 Q), mm, None for
    0 or not given; *tolerance_tol*, *naive_tol* (mm) bound their rounding in rs274's output."""

    control: str = "blend"
    tolerance: float | None = None
    naive_tolerance: float | None = None
    tolerance_tol: float = 0.0
    naive_tol: float = 0.0


DEFAULT_MODE = Mode()


@dataclass(frozen=True)
class Move:
    """One motion of rs274's output, in mm, absolute, 3-D.

    *start_tol* and *end_tol* (mm) bound the rounding of each coordinate of
    *start* and *end* (and *end_tol* that of *center*): half the last printed
    digit in the units they were printed in; 0 for the program's start, the
    origin.  *start* is None after a NURBS_FEED, whose end rs274 does not
    print.  Arcs also carry *center* (on the start's plane, the axis coordinate
    being the start's), *normal* (the unit vector they turn counter-clockwise
    about: ±the plane's axis), *turns* (``|rotation|``) and *plane*
    (``"xy"``, ``"zx"``, ``"yz"``); a NURBS_FEED has *count* control points and
    no *end*.  *feed* is the feed rate in effect, mm/min (None for rapids).
    *index* is rs274's output line, *n_word* the block's N word (``N.....`` if none).
    *mode* is the path-control mode in effect; *stops* the M words (M0, M1, M60, M6) that
    stopped motion since the previous move, in order; *dwell* the seconds of G4 since then.
    Points are in machine coordinates (the printed ones plus the G5x and G92 offsets).
    """

    kind: str  # "rapid" | "line" | "arc" | "nurbs"
    start: np.ndarray | None
    end: np.ndarray | None
    start_tol: float
    end_tol: float
    feed: float | None
    index: int
    n_word: str
    center: np.ndarray | None = None
    normal: np.ndarray | None = None
    turns: int = 0
    plane: str | None = None
    count: int = 0
    mode: Mode = DEFAULT_MODE
    stops: tuple = ()
    dwell: float = 0.0
    same_frame: bool = True  # start and end printed in the same units and offsets

    @property
    def is_zero_length(self) -> bool:
        """A line whose printed end is its printed start: readers may drop it.

        Printed in the same units and offsets, the two must be equal: a move of one printed step
        (CAM programs of 4 decimals hold many) is a move.  Across a units switch or an offset
        change (G92, G52, G92.x: equal tolerances do not mean one frame), equal up to their
        roundings: the same point printed in two frames, each summed with its own rounded offsets,
        may differ in the last bit or the last printed digit.  A move shorter than a printed step
        may print as zero-length while a reader keeps it: a comparison pairs such a block with it
        (see ``tests/test_corpus_cam.py``)."""
        if self.kind not in ("rapid", "line") or self.start is None:
            return False
        if self.same_frame:
            return bool(np.array_equal(self.end, self.start))
        return float(np.max(np.abs(self.end - self.start))) <= self.start_tol + self.end_tol + 1e-12

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.start - self.center))

    @property
    def rise(self) -> float:
        """Helical displacement along *normal*, mm (0 for a planar arc)."""
        return float((self.end - self.start) @ self.normal)

    @property
    def is_full_circle(self) -> bool:
        """The end is the start in the plane (up to the roundings): a whole turn."""
        chord = (self.end - self.start) - self.rise * self.normal
        return float(np.max(np.abs(chord))) <= self.start_tol + self.end_tol + 1e-12

    @property
    def sweep(self) -> float:
        """Angle turned counter-clockwise about *normal*, radians, in (0, 2π·turns]."""
        u = self.start - self.center
        v = (self.end - self.rise * self.normal) - self.center
        if self.is_full_circle:
            last = 2 * math.pi
        else:
            last = math.atan2(float(np.cross(u, v) @ self.normal), float(u @ v))
            if last <= 0:
                last += 2 * math.pi
        return last + 2 * math.pi * (self.turns - 1)


def _numbers(args: str) -> list[float]:
    return [float(a) for a in args.split(",")]


def parse_canon(text: str) -> list[Move]:
    """rs274's standard output → its moves (see the module's notes for the conventions)."""
    factor = 1.0
    plane = "CANON_PLANE_XY"
    here: np.ndarray | None = np.zeros(3)  # machine coordinates, mm
    here_tol = 0.0
    here_frame = frame = (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # units and offsets the position was printed in
    feed: float | None = None
    g5x, g92 = np.zeros(3), np.zeros(3)  # mm
    g5x_tol = g92_tol = 0.0  # 0 until an offset other than the start's exact zero is printed
    mode = DEFAULT_MODE
    stops: list[str] = []
    dwell = 0.0
    last = ""  # the previous call's name: PALLET_SHUTTLE then PROGRAM_STOP is M60
    moves: list[Move] = []

    def add(move: Move) -> None:
        nonlocal dwell
        moves.append(replace(move, mode=mode, stops=tuple(stops), dwell=dwell))
        stops.clear()
        dwell = 0.0

    for line in text.splitlines():
        match = _LINE.match(line)
        if match is None:
            g6 = _G6_LINE.match(line)
            if g6 is not None:
                add(Move("nurbs", here, None, here_tol, 0.0, feed, -1, g6[1], count=int(g6[2])))
                here, here_tol = None, 0.0
            continue
        index, n_word, name, args = int(match[1]), match[2], match[3], match[4]
        offset = g5x + g92
        point_tol = HALF_STEP * factor + g5x_tol + g92_tol
        frame = (factor, *g5x, *g92)
        if name == "USE_LENGTH_UNITS":
            if args not in MM_PER_UNIT:
                raise ValueError(f"rs274 output line {index}: unknown units {args!r}")
            factor = MM_PER_UNIT[args]
        elif name == "SELECT_PLANE":
            if args not in PLANES:
                raise ValueError(f"rs274 output line {index}: unknown plane {args!r}")
            plane = args
        elif name == "SET_FEED_RATE":
            feed = float(args) * factor or None  # 0: no F yet
        elif name == "SET_G5X_OFFSET":
            g5x = np.array(_numbers(args)[1:4]) * factor
            g5x_tol = 0.0 if index <= 6 else HALF_STEP * factor  # the start's: exactly 0, no variable file
        elif name == "SET_G92_OFFSET":
            g92 = np.array(_numbers(args)[:3]) * factor
            g92_tol = 0.0 if index <= 6 else HALF_STEP * factor
        elif name == "SET_XY_ROTATION":
            if float(args) != 0.0:
                raise NotImplementedError(f"rs274 output line {index}: {name}({args}): rotation is not supported here")
        elif name == "SET_MOTION_CONTROL_MODE":
            control, _, tolerance = args.partition(",")
            if control not in CONTROL_MODES:
                raise ValueError(f"rs274 output line {index}: unknown motion control mode {args!r}")
            p = float(tolerance) * factor if tolerance else 0.0
            mode = Mode(CONTROL_MODES[control], p or None, None, HALF_STEP_P * factor if p else 0.0)
        elif name == "SET_NAIVECAM_TOLERANCE":
            q = float(args) * factor
            mode = replace(mode, naive_tolerance=q or None, naive_tol=HALF_STEP_Q * factor if q else 0.0)
        elif name == "DWELL":  # a dwell brings motion to rest first, even G4 P0: a stop of its own
            dwell += float(args)
            stops.append("G4")
        elif name == "PROGRAM_STOP" and last == "PALLET_SHUTTLE":
            stops.append("M60")
        elif name in STOPS:
            stops.append(STOPS[name])
        elif name in ("STRAIGHT_TRAVERSE", "STRAIGHT_FEED"):
            end = np.array(_numbers(args)[:3]) * factor + offset
            kind = "rapid" if name == "STRAIGHT_TRAVERSE" else "line"
            add(Move(kind, here, end, here_tol, point_tol, None if kind == "rapid" else feed, index, n_word,
                     same_frame=frame == here_frame))
            here, here_tol, here_frame = end, point_tol, frame
        elif name == "ARC_FEED":
            values = args.split(",")
            first_end, second_end, first_c, second_c = (float(v) * factor for v in values[:4])
            rotation = int(values[4])
            axis_end = float(values[5]) * factor
            (i1, i2, ia), axis = PLANES[plane]
            if here is None:
                raise ValueError(f"rs274 output line {index}: an arc right after a NURBS_FEED (unknown start)")
            end = np.empty(3)
            end[i1], end[i2], end[ia] = first_end, second_end, axis_end
            end += offset
            center = np.empty(3)
            center[i1], center[i2] = first_c + offset[i1], second_c + offset[i2]
            center[ia] = here[ia]
            add(Move("arc", here, end, here_tol, point_tol, feed, index, n_word, center=center,
                     normal=axis * math.copysign(1.0, rotation), turns=abs(rotation), plane=PLANE_NAMES[plane]))
            here, here_tol, here_frame = end, point_tol, frame
        elif name == "NURBS_FEED":
            count = int(args.split(",")[0])
            add(Move("nurbs", here, None, here_tol, 0.0, feed, index, n_word, count=count))
            here, here_tol = None, 0.0
        elif any(word in name + "(" for word in MOTION_WORDS) and not name.startswith("SET_"):
            raise NotImplementedError(f"rs274 output line {index}: canonical call {name}({args}) is not supported here")
        last = name
    return moves


def without_zero_length(moves: list[Move]) -> list[Move]:
    """*moves* without the zero-length lines (which readers drop): their stops and dwell pass to the next move."""
    kept: list[Move] = []
    stops: tuple = ()
    dwell = 0.0
    for move in moves:
        if move.is_zero_length:
            stops, dwell = stops + move.stops, dwell + move.dwell
            continue
        if stops or dwell:
            move = replace(move, stops=stops + move.stops, dwell=dwell + move.dwell)
            stops, dwell = (), 0.0
        kept.append(move)
    return kept


ZERO_LENGTH_TOOLS = 999  # tools T1..T999 of length 0 in the table rs274 runs with


def run_rs274(path: str | os.PathLike, *, block_delete: bool = True, timeout: float = TIMEOUT) -> str:
    """rs274's standard output for the program at *path*; :class:`Rs274Error` if it refuses it.

    *block_delete* (the switch, ``-b``): skip lines starting with ``/``."""
    if RS274 is None:
        raise FileNotFoundError("rs274 is not on PATH (Debian package linuxcnc-uspace)")
    # rs274 creates $HOME/.tool.mmap (truncating it) and maps it shared: two runs with one HOME
    # crash each other with SIGBUS, so each run gets a HOME of its own
    with tempfile.TemporaryDirectory(prefix="rs274-home-") as home:
        # the reader takes tool lengths as zero (as it takes the work offsets): so must rs274, whose
        # built-in table gives tool 1 a length of 12.9794 mm (G43 H1 would shift every Z by it)
        table = os.path.join(home, "zero.tbl")
        with open(table, "w") as out:
            out.writelines(f"T{t} P{t} Z0 D0 ;\n" for t in range(1, ZERO_LENGTH_TOOLS + 1))
        args = [RS274, "-g", "-t", table] + (["-b"] if block_delete else []) + [os.fspath(path)]
        env = dict(os.environ, HOME=home)
        done = subprocess.run(args, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=timeout,
                              env=env, cwd=home)
    # rs274 says "executing" on stderr even when all goes well; an error is the exit status
    if done.returncode != 0:
        raise Rs274Error(os.fspath(path), done.returncode, done.stderr.replace("executing", "", 1), done.stdout)
    return done.stdout


def read_moves(path: str | os.PathLike, *, block_delete: bool = True) -> list[Move]:
    """The moves rs274 makes of the program at *path* (mm, machine coordinates, from the origin).

    On a refusal the :class:`Rs274Error` raised carries the moves made before it (``moves``)."""
    try:
        return parse_canon(run_rs274(path, block_delete=block_delete))
    except Rs274Error as refusal:
        refusal.moves = parse_canon(refusal.output)
        raise


def read_many(paths, *, block_delete: bool = True, jobs: int | None = None) -> list:
    """:func:`read_moves` of each path, run *jobs* at a time (default: the cores this process may use).

    Each result is a list of moves, or the :class:`Rs274Error` the program raised."""

    def one(path):
        try:
            return read_moves(path, block_delete=block_delete)
        except Rs274Error as exc:
            return exc

    jobs = jobs or len(os.sched_getaffinity(0))
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        return list(pool.map(one, paths))


def read_seeded(folder, prefix: str, seeds, write) -> dict:
    """Seeded programs written into *folder* (``write(seed) -> text``) and run through rs274 together:
    ``{seed: (path, moves or the Rs274Error)}``, as many at a time as there are cores."""
    paths = []
    for seed in seeds:
        path = Path(folder) / f"{prefix}-{seed}.ngc"
        path.write_text(write(seed))
        paths.append(path)
    return dict(zip(seeds, zip(paths, read_many(paths))))
