"""The machine a program drives: modes, offsets, position, and the blocks each line's motion makes.

Frames: the blocks are in machine coordinates, mm.  The work offsets (``G54`` … ``G59.3``)
are taken as zero, so a program's coordinates are the machine's but for the ``G92``/``G52``
offset, which the reader applies as LinuxCNC does (``G92 X0`` makes the current point X0 of
the program; ``G92.1`` clears it).  ``G53`` moves to machine coordinates; ``G28``/``G30`` rapid
through their intermediate point to a stored machine position (the machine origin unless set
by ``G28.1``/``G30.1`` or the reader's options).
"""
from __future__ import annotations

import gc
from dataclasses import dataclass

import numpy as np

from ...errors import SpecError
from ..curve import MAX_COORDINATE, CurveSpec
from ..path import (DEFAULT_MODE, MIN_BLOCK_LENGTH, ArcBlock, BlockMode, LineBlock, NurbsBlock, PathSpec,
                    line_block_fast)
from .arcs import arc
from .codes import (AXIS_CODES, AXIS_LETTERS, CONTROL, ENDS_M, GROUPS, HOMES, IGNORED_G, IGNORED_WORDS, MAX_M,
                    MM_PER_INCH, MODAL, MODE_ORDER, MOTION, NON_MODAL, REFUSED_G, REFUSED_M, STOP_BEFORE_MOTION, STOP_M,
                    gname)
from .fast import StraightState, straight_run
from .nurbs import begin_g5, begin_g6, end_g5, g5_point, g6_point
from .words import Line

G92_PARAMS = (5211, 5212, 5213)  # the G92 offset, mm (LinuxCNC's user units)
SHOWN_LINES = 6  # lines a note lists (five, and '...' where there are more): all that is kept of them


class Machine:
    """The reader's state: modes, offsets, position, the blocks read so far.

    *homes*: the stored positions of G28 and G30, ``{280: (x, y, z), 300: (x, y, z)}`` mm in machine
    coordinates (default the machine origin, as rs274 without a parameter file)."""

    def __init__(self, name: str, start, params: dict | None = None, homes: dict | None = None):
        self.name = name
        self.pos = np.array(start, dtype=float)  # machine frame, mm
        self.start = self.pos.copy()
        self.offset = np.zeros(3)  # G92/G52: program = machine - offset, mm
        self.inch = False
        self.absolute = True
        self.center_absolute = False
        self.plane = 170
        self.motion = None  # the modal motion code
        self.feed = None  # mm/s, the F in effect
        self.mode = DEFAULT_MODE  # G61 / G61.1 / G64 P Q in effect
        self.stop = []  # why motion comes to rest before the next block (M0, M6, G4 ...)
        self.dwell = 0.0  # s, G4 before the next block
        self.blocks = []  # 3-D blocks
        self.ignored = {}  # label -> first line
        self.notes = []
        self.feedless = []  # lines of feed moves before any F (the first SHOWN_LINES)
        self.dropped = 0  # zero-length moves
        self.nurbs = None  # the NURBS block being collected: dict
        self.params = {} if params is None else params
        self.homes_used = {}  # 280/300 -> first line that went there
        self.homes_moved = {}  # 280/300 -> the lines whose G28/G30 moved the tool, and those that moved Z down
        self.homes_given = set(homes or ())
        for code, first in HOMES.items():
            for j, value in enumerate((homes or {}).get(code, (0.0, 0.0, 0.0))):
                self.params[first + j] = float(value)
        if hasattr(self.params, "position"):
            self.params.position = self.program_position  # #5420..#5422, computed when a line reads them

    def fail(self, line: int, problem: str) -> SpecError:
        return SpecError(f"{self.name}:{line}: {problem}")

    def scale(self) -> float:
        return MM_PER_INCH if self.inch else 1.0

    def ignore(self, label: str, line: int) -> None:
        self.ignored.setdefault(label, line)

    def coordinate(self, j: int, value: float) -> float:
        """An absolute coordinate of the program (its units, its frame) in machine mm."""
        return value * self.scale() + self.offset[j]

    def target(self, line: Line, machine: bool = False) -> np.ndarray:
        """The end point a block's X Y Z words name (absolute or incremental; *machine*: G53), in mm."""
        end = self.pos.copy()
        for j, letter in enumerate(AXIS_LETTERS):
            if letter in line.words:
                value = line.words[letter]
                if machine:
                    end[j] = value * self.scale()
                elif self.absolute:
                    end[j] = self.coordinate(j, value)
                else:
                    end[j] = end[j] + value * self.scale()
                if not abs(end[j]) <= MAX_COORDINATE:
                    raise self.fail(line.number, f"{letter}{value:g} is beyond the supported range of "
                                    f"+-{MAX_COORDINATE:g} mm")
        return end

    def joint(self) -> dict:
        """The mode, stop and dwell of the next block (the stop and dwell are then spent)."""
        out = {"mode": self.mode, "stop": "; ".join(self.stop) if self.stop else None, "dwell": self.dwell}
        self.stop = []
        self.dwell = 0.0
        return out

    def add_line(self, number: int, end, rapid: bool) -> None:
        if float(np.linalg.norm(end - self.pos)) <= MIN_BLOCK_LENGTH:
            self.dropped += 1
            return
        if not rapid and self.feed is None and len(self.feedless) < SHOWN_LINES:
            self.feedless.append(number)
        self.blocks.append(LineBlock(self.pos.copy(), end, None if rapid else self.feed, rapid, f"line {number}",
                                     **self.joint()))
        self.pos = end

    def program_position(self) -> np.ndarray:
        """LinuxCNC's #5420..#5422: where the tool is, in the program's units and frame."""
        return (self.pos - self.offset) / self.scale()


def _straight(prog, line: Line, rapid: bool, machine: bool = False) -> None:
    end = prog.target(line, machine)
    prog.add_line(line.number, end, rapid)


def execute(prog: Machine, line: Line) -> bool:
    """Carry out one line, in LinuxCNC's order of execution; True at the program's end."""
    number = line.number
    motions = [g for g in line.g if g in MOTION]
    if len(motions) > 1:
        raise prog.fail(number, f"{' and '.join(gname(g) for g in motions)} are two motions on one line")
    for group in GROUPS if len(line.g) > 1 else ():
        same = [g for g in line.g if g in group]
        if len(same) > 1:
            raise prog.fail(number, f"{' and '.join(gname(g) for g in same)} are two codes of one group on one line")
    for g in line.g:
        if g in MOTION or g in MODAL:
            continue
        if g in IGNORED_G:
            prog.ignore(f"{gname(g)} ({IGNORED_G[g]})", number)
        elif g in REFUSED_G:
            raise prog.fail(number, f"{REFUSED_G[g]} is not supported by this reader")
        else:
            raise prog.fail(number, f"{gname(g)} is not a G-code this reader knows")
    non_modal = next((g for g in line.g if g in NON_MODAL and g != 530), None)
    if 940 in line.g:  # setting the feed mode sets the feed to none, before the line's F (LinuxCNC's order)
        prog.feed = None
    if "F" in line.words:  # before the line's G20/G21, as LinuxCNC orders a line's actions
        f = line.words["F"]
        if not f > 0:
            raise prog.fail(number, f"F{f:g}: the feedrate must be > 0")
        prog.feed = f * prog.scale() / 60.0  # units per minute (G94) -> mm/s
    for letter, label in IGNORED_WORDS.items():
        if letter in line.words:
            prog.ignore(f"{letter} ({label})", number)
    for m in line.m:
        if m in REFUSED_M:
            raise prog.fail(number, f"{REFUSED_M[m]} is not supported by this reader")
        if m > MAX_M:
            raise prog.fail(number, f"M{m}: an M-code above M{MAX_M} (LinuxCNC has none)")
        if m in STOP_BEFORE_MOTION:
            prog.stop.append(f"{STOP_M[m].split(' (')[0]} at line {number}")
        elif m not in ENDS_M and m not in STOP_M:
            prog.ignore(f"M{m}", number)
    if non_modal == 40:  # G4 P: a dwell, before the line's motion
        _dwell(prog, line)
    # the modes, in LinuxCNC's order of execution whatever the line's order (convert_g: plane, units, path
    # control, distance modes): they apply to this line's motion, and G64's P is in the units just set
    for g in sorted((g for g in line.g if g in MODE_ORDER), key=MODE_ORDER.__getitem__):
        if g in (200, 210):
            prog.inch = g == 200
        elif g in (900, 910):
            prog.absolute = g == 900
        elif g in (901, 911):
            prog.center_absolute = g == 901
        elif g in (170, 180, 190):
            if prog.nurbs is not None:
                raise prog.fail(number, f"{gname(g)} changes the plane inside the {prog.nurbs['kind']} of line "
                                f"{prog.nurbs['line']}")
            prog.plane = g
        elif g in CONTROL:
            prog.mode = _control_mode(prog, line, g)
    motion = motions[0] if motions else None
    moving = any(c in line.words for c in "XYZ")
    if non_modal in AXIS_CODES or non_modal in (281, 301, 921, 922, 923):
        if motion is not None and moving:
            raise prog.fail(number, f"{gname(non_modal)} and {gname(motion)} both use the axis words of the line")
        if prog.nurbs is not None:
            raise prog.fail(number, f"{gname(non_modal)} inside the {prog.nurbs['kind']} of line {prog.nurbs['line']}")
        _check_words(prog, line, non_modal)
        if motion is not None:
            prog.motion = motion
        _non_modal(prog, line, non_modal)
    else:
        arc_words = any(c in line.words for c in "IJKR")
        if prog.nurbs is None and motion is None and prog.motion in (20, 30) and arc_words:
            moving = True  # I J K alone in G2/G3 mode: a full circle, as LinuxCNC runs it
        _check_words(prog, line, motion)
        if 530 in line.g:
            _machine_move(prog, line, motion)
        elif prog.nurbs is not None:
            _nurbs_line(prog, line, motion, moving)
        elif motion == 53:
            raise prog.fail(number, "G5.3 without G5.2: there is no NURBS block to close")
        elif motion == 52:
            prog.motion = 52
            begin_g5(prog, line)
        elif motion == 62:
            prog.motion = 62
            begin_g6(prog, line)
        else:
            if motion is not None:
                prog.motion = motion
            if motion is not None or moving:
                _move(prog, line)
    for m in line.m:  # M0 M1 M60 ... stop after the line's motion
        if m in STOP_M and m not in STOP_BEFORE_MOTION:
            prog.stop.append(f"{STOP_M[m].split(' (')[0]} at line {number}")
    return any(m in ENDS_M for m in line.m)


def execute_run(prog: Machine, run) -> None:
    """Carry out a run of plain lines (``program.PlainRun``): their straight moves made by ``fast.straight_run``
    over the whole run at once, and any line it leaves (an arc's mode in effect, a move within rounding of
    the shortest block, a coordinate out of range) by :func:`execute`, exactly as line by line."""
    k, last = run.first, run.last
    while k < last:
        if prog.nurbs is not None:  # inside G5.2/G6.2: each line is the curve's, read line by line
            line = run.read(k)
            if line is not None:
                execute(prog, line)
            k += 1
            continue
        moves = straight_run(run.table, k, last, StraightState(prog.pos, prog.absolute, prog.scale(), prog.motion,
                                                               prog.feed, prog.offset.copy()))
        _add_moves(prog, moves, run.offset)
        k = moves.next
        if k < last:  # a line the general machine carries out
            line = run.read(k)
            if line is not None:
                execute(prog, line)
            k += 1


@dataclass(eq=False)
class _Moves:
    """A run's straight moves, held as arrays until :func:`path_of` makes them blocks of the path's dimension."""

    starts: np.ndarray  # (n, 3) mm
    ends: np.ndarray  # (n, 3) mm
    feeds: np.ndarray  # (n,) mm/s, NaN: none (a rapid, or no F yet)
    rapid: np.ndarray  # (n,) bool
    lines: np.ndarray  # (n,) the program's line of each move
    mode: BlockMode
    stop: str | None  # before the first move
    dwell: float
    kind = "moves"

    def flat(self, z0: float) -> bool:
        return bool(np.all(self.starts[:, 2] == z0) and np.all(self.ends[:, 2] == z0))

    def part(self, lo: int, hi: int) -> "_Moves":
        """Moves lo .. hi−1 (the stop and dwell stay with the first move)."""
        first = lo == 0
        return _Moves(self.starts[lo:hi], self.ends[lo:hi], self.feeds[lo:hi], self.rapid[lo:hi], self.lines[lo:hi],
                      self.mode, self.stop if first else None, self.dwell if first else 0.0)

    def blocks(self, dim: int) -> list:
        feeds = [None if f != f else f for f in self.feeds.tolist()]  # NaN: the block has none
        stop, dwell, mode = self.stop, self.dwell, self.mode
        out = []
        # one block a line and no cycles: the cyclic collector, which would walk every new block over and over
        # as they pile up, is held off while they are made (a third of the time otherwise)
        collecting = gc.isenabled()
        gc.disable()
        try:
            for start, end, feed, rapid, number in zip(self.starts[:, :dim], self.ends[:, :dim], feeds,
                                                       self.rapid.tolist(), self.lines.tolist()):
                out.append(line_block_fast(start, end, feed, rapid, f"line {number}", mode, stop, dwell))
                stop, dwell = None, 0.0
        finally:
            if collecting:
                gc.enable()
        return out


def _add_moves(prog: Machine, moves, offset: int = 0) -> None:
    """The run's moves as one item of the program's blocks; *offset*: the file's lines before the run's table."""
    prog.dropped += moves.dropped
    prog.motion, prog.feed = moves.state.motion, moves.state.feedrate
    n = len(moves)
    if n == 0:
        return
    ends = moves.end
    starts = np.concatenate([prog.pos[None, :], ends[:-1]])
    feeds = moves.feedrate
    lines = moves.line + offset if offset else moves.line
    feedless = ~moves.rapid & np.isnan(feeds)
    if feedless.any():
        prog.feedless.extend(lines[feedless][:SHOWN_LINES - len(prog.feedless)].tolist())
    joint = prog.joint()  # the first move takes a pending stop; the mode holds for the whole run
    # the blocks are made once the program is read, in 2-D or 3-D as the whole program turns out (path_of)
    prog.blocks.append(_Moves(starts, ends, feeds, moves.rapid, lines, joint["mode"], joint["stop"],
                              joint["dwell"]))
    prog.pos = ends[-1].copy()


def _dwell(prog: Machine, line: Line) -> None:
    if "P" not in line.words:
        raise prog.fail(line.number, "G4 needs P, the dwell's seconds")
    seconds = line.words["P"]
    if not seconds >= 0:
        raise prog.fail(line.number, f"G4 P{seconds:g}: a dwell's seconds must be >= 0")
    prog.dwell += float(seconds)
    prog.stop.append(f"G4 P{seconds:g} at line {line.number}")


def _control_mode(prog: Machine, line: Line, g: int) -> BlockMode:
    """G61, G61.1, or G64 with its tolerances (P, and Q which defaults to P, as LinuxCNC takes them), mm."""
    if g != 640:
        return BlockMode(CONTROL[g])
    values = {}
    for letter in "PQ":
        # a negative P or Q is LinuxCNC's "not given": the default tolerance (convert_control_mode)
        if letter in line.words and line.words[letter] >= 0:
            values[letter] = float(line.words[letter]) * prog.scale()
    p = values.get("P")
    return BlockMode("blend", p, values.get("Q", p))


def _non_modal(prog: Machine, line: Line, g: int) -> None:
    """G28/G30 (and .1), G92 (.1 .2 .3), G52."""
    number = line.number
    if g in HOMES:  # a rapid to the intermediate point (in the current mode), then to the stored position
        first = HOMES[g]
        via = prog.target(line)
        prog.add_line(number, via, rapid=True)
        home = np.array([prog.params.get(first + j, 0.0) for j in range(3)], dtype=float)
        if not np.all(np.abs(home) <= MAX_COORDINATE):  # #5161.. may be set by the program
            raise prog.fail(number, f"{gname(g)}: the stored position ({', '.join(f'{c:.6g}' for c in home)}) mm "
                                    f"(#{first}..#{first + 2}) is beyond the supported range of "
                                    f"+-{MAX_COORDINATE:g} mm")
        end = via.copy()
        named = [j for j, letter in enumerate(AXIS_LETTERS) if letter in line.words]
        for j in named or range(3):  # only the named axes go home; all of them when none is named
            end[j] = home[j]
        before = np.array(prog.pos, dtype=float)
        prog.add_line(number, end, rapid=True)
        prog.homes_used.setdefault(g, number)
        if not (np.array_equal(via, before) and np.array_equal(end, via)):
            # a home that moves the tool is worth a word each time: the first G28 of a program often moves
            # nothing (the tool is there), a later one plunges Z to a position nobody gave
            moved, down = prog.homes_moved.setdefault(g, ([], []))
            moved.append(number)
            if min(via[2], end[2]) < before[2]:
                down.append(number)
    elif g in (281, 301):  # store where the tool is, machine mm
        first = HOMES[g - 1]
        for j in range(3):
            prog.params[first + j] = float(prog.pos[j])
        prog.homes_given.add(g - 1)
    elif g in (920, 520):
        named = [j for j, letter in enumerate(AXIS_LETTERS) if letter in line.words]
        if not named:
            raise prog.fail(number, f"{gname(g)} needs at least one of X Y Z")
        for j in named:
            value = line.words[AXIS_LETTERS[j]] * prog.scale()
            # G92: the current point is given these coordinates; G52: the offset is given
            prog.offset[j] = prog.pos[j] - value if g == 920 else value
        for key, value in zip(G92_PARAMS, prog.offset):
            prog.params[key] = float(value)
    elif g in (921, 922):  # clear the offset (G92.1 also its parameters)
        prog.offset[:] = 0.0
        if g == 921:
            for key in G92_PARAMS:
                prog.params[key] = 0.0
    elif g == 923:  # restore the offset from its parameters
        prog.offset[:] = [prog.params.get(key, 0.0) for key in G92_PARAMS]


def _machine_move(prog: Machine, line: Line, motion) -> None:
    """G53: a straight move to machine coordinates, with G0 or G1 (LinuxCNC's rules)."""
    active = motion if motion is not None else prog.motion
    if active not in (0, 10):
        raise prog.fail(line.number, "G53 moves only with G0 or G1 in effect")
    if not prog.absolute:
        raise prog.fail(line.number, "G53 in incremental mode (G91): machine coordinates are absolute")
    if prog.nurbs is not None:
        raise prog.fail(line.number, f"G53 inside the {prog.nurbs['kind']} of line {prog.nurbs['line']}")
    prog.motion = active
    _straight(prog, line, rapid=active == 0, machine=True)


def _check_words(prog: Machine, line: Line, motion) -> None:
    """Refuse a word that no code of the line uses (``G1 X10 R5``: a G2 meant?), as rs274 does."""
    if prog.nurbs is not None:
        active = 52 if prog.nurbs["kind"] == "G5.2" else 62
    else:
        active = motion if motion is not None else prog.motion
    users = set("XYZF") | set(IGNORED_WORDS)
    if active in (20, 30):
        users |= set("IJKRP")
    elif active == 52 or motion == 53:
        users |= set("PL")
    elif active == 62:
        users |= set("KRPQ")
    if 40 in line.g:  # G4 P (the dwell's seconds)
        users.add("P")
    if 66 in line.m:  # M66 P- | E- L- [Q-]: which input, how to wait, how long
        users |= set("PELQ")
    if 640 in line.g:  # G64 P Q (blending tolerances)
        users |= set("PQ")
    for letter, value in line.words.items():
        if letter not in users:
            raise prog.fail(line.number, f"{letter}{value:g} is given with no G-code on or before this line that "
                            "uses it")


def _nurbs_line(prog: Machine, line: Line, motion, moving: bool) -> None:
    nurbs = prog.nurbs
    kind = nurbs["kind"]
    if kind == "G5.2":
        if motion == 53:
            if moving:
                raise prog.fail(line.number, "G5.3 takes no coordinates")
            end_g5(prog, line)
            prog.motion = None
        elif motion in (None, 52):
            if motion == 52:
                raise prog.fail(line.number, f"G5.2 starts a NURBS while the one of line {nurbs['line']} is not "
                                "closed by G5.3")
            if moving or "P" in line.words:
                g5_point(prog, line)
        else:
            raise prog.fail(nurbs["line"], f"G5.2 is not closed by G5.3 before the {gname(motion)} of line "
                            f"{line.number}")
        return
    if motion not in (None, 62):
        raise prog.fail(nurbs["line"], f"G6.2 is not closed: {nurbs['order'] - nurbs['closing']} more knot-only "
                        f"blocks were expected before the {gname(motion)} of line {line.number}")
    if motion == 62 and moving:
        raise prog.fail(nurbs["line"], f"G6.2 is not closed: {nurbs['order'] - nurbs['closing']} more knot-only "
                        f"blocks were expected before the new G6.2 of line {line.number}")
    if moving or "K" in line.words or "R" in line.words:
        g6_point(prog, line)
        if prog.nurbs is None:
            prog.motion = None


def _move(prog: Machine, line: Line) -> None:
    motion = prog.motion
    if motion is None:
        raise prog.fail(line.number, "coordinates without a motion mode (G0, G1, G2, G3) in effect")
    if motion in (0, 10):
        _straight(prog, line, rapid=motion == 0)
    elif motion in (20, 30):
        arc(prog, line, ccw=motion == 30)
    elif motion in (52, 62, 53):
        raise prog.fail(line.number, "coordinates after a closed NURBS block: give a motion (G0, G1, G2, G3)")


def path_of(prog: Machine) -> PathSpec:
    if not prog.blocks:
        raise SpecError(f"{prog.name}: the program moves nowhere (no G0, G1, G2, G3, G5.2 or G6.2 move of any "
                        "length)")
    z0 = prog.start[2]
    flat = all(b.flat(z0) if b.kind == "moves" else _flat(b, z0) for b in prog.blocks)
    blocks = []
    for b in prog.blocks:
        if b.kind == "moves":  # a run's moves, made blocks once, in the path's dimension
            blocks.extend(b.blocks(2 if flat else 3))
        else:
            blocks.append(_to_2d(b) if flat else b)
    return PathSpec(tuple(blocks), 2 if flat else 3, notes=program_notes(prog), dropped=prog.dropped)


def program_notes(prog: Machine) -> tuple:
    """What the reader has to say of the program once it is read: moves without F, dropped moves, homes, codes
    ignored."""
    notes = list(prog.notes)
    if prog.feedless:
        shown = ", ".join(str(n) for n in prog.feedless[:5]) + (" ..." if len(prog.feedless) > 5 else "")
        notes.append(f"feed moves before any F word (lines {shown}) move at the profile's feedrate")
    if prog.dropped:
        notes.append(f"{prog.dropped} zero-length move{'s' if prog.dropped > 1 else ''} dropped")
    for code, first in sorted(prog.homes_used.items()):
        home = ", ".join(f"{prog.params.get(HOMES[code] + j, 0.0):g}" for j in range(3))
        given = code in prog.homes_given
        source = "as stored or given" if given else "the machine origin: no position was given"
        moved, down = prog.homes_moved.get(code, ([], []))
        # the lines where it moved the tool (the first, where none did)
        where = f"line{'s' if len(moved) > 1 else ''} {_lines(moved or [first])}"
        notes.append(f"{gname(code)} ({where}) goes to its stored position ({home}) mm, machine coordinates "
                     f"({source})" + ("" if given or not down else
                                      f"; Z moves down there (line{'s' if len(down) > 1 else ''} {_lines(down)}): "
                                      f"if the machine homes elsewhere, give {HOME_HINT.format(code=gname(code))}"))
    if prog.ignored:
        notes.append("ignored (they do not move the tool): " + ", ".join(
            f"{label} (line {line})" for label, line in sorted(prog.ignored.items(), key=lambda item: item[1])))
    return tuple(notes)


#: how a note asks for a stored position the program did not give (the CLI names its option here)
HOME_HINT = "its {code} position to the reader"


def _lines(numbers: list) -> str:
    """Line numbers for a note: the first five, then how many more."""
    shown = ", ".join(str(n) for n in numbers[:5])
    return shown + (f" and {len(numbers) - 5} more" if len(numbers) > 5 else "")


def _flat(block, z0: float) -> bool:
    if block.kind == "nurbs":
        return bool(np.all(block.curve.control_points[:, 2] == z0))
    if block.kind == "arc" and (block.normal[2] == 0 or block.rise != 0):
        return False
    return block.start[2] == z0 and block.end[2] == z0


def _to_2d(block):
    if block.kind == "line":
        return LineBlock(block.start[:2].copy(), block.end[:2].copy(), block.feedrate, block.rapid, block.source,
                         **_joint_of(block))
    if block.kind == "arc":
        return ArcBlock(block.start[:2].copy(), block.end[:2].copy(), block.center[:2].copy(), block.normal,
                        block.sweep, 0.0, block.feedrate, block.source, **_joint_of(block))
    c = block.curve
    return NurbsBlock(CurveSpec(c.degree, np.ascontiguousarray(c.control_points[:, :2]), c.weights.copy(),
                                c.knots.copy()), block.feedrate, block.source, **_joint_of(block))


def _joint_of(block) -> dict:
    return {"mode": block.mode, "stop": block.stop, "dwell": block.dwell}
