"""The machine a program drives: modes, position, and the blocks each line's motion makes."""
from __future__ import annotations

import numpy as np

from ...errors import SpecError
from ..curve import MAX_COORDINATE, CurveSpec
from ..path import MIN_BLOCK_LENGTH, ArcBlock, LineBlock, NurbsBlock, PathSpec
from .arcs import arc
from .codes import (AXIS_LETTERS, ENDS_M, GROUPS, IGNORED_G, IGNORED_WORDS, MM_PER_INCH, MODAL, MOTION, REFUSED_G,
                    gname)
from .nurbs import begin_g5, begin_g6, end_g5, g5_point, g6_point
from .words import Line


class Machine:
    """The reader's state: modes, position, the blocks read so far."""

    def __init__(self, name: str, start, params: dict | None = None):
        self.name = name
        self.pos = np.array(start, dtype=float)
        self.start = self.pos.copy()
        self.inch = False
        self.absolute = True
        self.center_absolute = False
        self.plane = 170
        self.motion = None  # the modal motion code
        self.feed = None  # mm/s, the F in effect
        self.blocks = []  # 3-D blocks
        self.ignored = {}  # label -> first line
        self.notes = []
        self.feedless = []  # lines of feed moves before any F
        self.dropped = 0  # zero-length moves
        self.nurbs = None  # the NURBS block being collected: dict
        self.params = {} if params is None else params

    def fail(self, line: int, problem: str) -> SpecError:
        return SpecError(f"{self.name}:{line}: {problem}")

    def scale(self) -> float:
        return MM_PER_INCH if self.inch else 1.0

    def ignore(self, label: str, line: int) -> None:
        self.ignored.setdefault(label, line)

    def target(self, line: Line) -> np.ndarray:
        """The end point a block's X Y Z words name (absolute or incremental), in mm."""
        end = self.pos.copy()
        for j, letter in enumerate(AXIS_LETTERS):
            if letter in line.words:
                value = line.words[letter] * self.scale()
                end[j] = value if self.absolute else end[j] + value
                if not abs(end[j]) <= MAX_COORDINATE:
                    raise self.fail(line.number, f"{letter}{line.words[letter]:g} is beyond the supported range of "
                                    f"+-{MAX_COORDINATE:g} mm")
        return end

    def add_line(self, number: int, end, rapid: bool) -> None:
        if float(np.linalg.norm(end - self.pos)) <= MIN_BLOCK_LENGTH:
            self.dropped += 1
            return
        if not rapid and self.feed is None:
            self.feedless.append(number)
        self.blocks.append(LineBlock(self.pos.copy(), end, None if rapid else self.feed, rapid, f"line {number}"))
        self.pos = end


def _straight(prog, line: Line, rapid: bool) -> None:
    end = prog.target(line)
    prog.add_line(line.number, end, rapid)


def execute(prog: Machine, line: Line) -> bool:
    """Carry out one line; True at the program's end."""
    number = line.number
    motions = [g for g in line.g if g in MOTION]
    if len(motions) > 1:
        raise prog.fail(number, f"{' and '.join(gname(g) for g in motions)} are two motions on one line")
    for group in GROUPS:
        same = [g for g in line.g if g in group]
        if len(same) > 1:
            raise prog.fail(number, f"{' and '.join(gname(g) for g in same)} are two modes of one group on one line")
    for g in line.g:
        if g in MOTION or g in MODAL:
            continue
        if g in IGNORED_G:
            prog.ignore(f"{gname(g)} ({IGNORED_G[g]})", number)
        elif g in REFUSED_G:
            raise prog.fail(number, f"{REFUSED_G[g]} is not supported by this reader")
        else:
            raise prog.fail(number, f"{gname(g)} is not a G-code this reader knows")
    if "F" in line.words:  # before the line's G20/G21, as LinuxCNC orders a line's actions
        f = line.words["F"]
        if not f > 0:
            raise prog.fail(number, f"F{f:g}: the feedrate must be > 0")
        prog.feed = f * prog.scale() / 60.0  # units per minute (G94) -> mm/s
    for g in line.g:  # the modes first: they apply to this line's motion
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
    for letter, label in IGNORED_WORDS.items():
        if letter in line.words:
            prog.ignore(f"{letter} ({label})", number)
    for m in line.m:
        if m not in ENDS_M:
            prog.ignore(f"M{m}", number)
    motion = motions[0] if motions else None
    moving = any(c in line.words for c in "XYZ")
    arc_words = any(c in line.words for c in "IJKR")
    if prog.nurbs is None and motion is None and prog.motion in (20, 30) and arc_words:
        moving = True  # I J K alone in G2/G3 mode: a full circle, as LinuxCNC runs it
    _check_words(prog, line, motion)
    if prog.nurbs is not None:
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
    return any(m in ENDS_M for m in line.m)


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
    flat = all(_flat(b, z0) for b in prog.blocks)
    blocks = [_to_2d(b) for b in prog.blocks] if flat else prog.blocks
    notes = list(prog.notes)
    if prog.feedless:
        shown = ", ".join(str(n) for n in prog.feedless[:5]) + (" ..." if len(prog.feedless) > 5 else "")
        notes.append(f"feed moves before any F word (lines {shown}) move at the profile's feedrate")
    if prog.dropped:
        notes.append(f"{prog.dropped} zero-length move{'s' if prog.dropped > 1 else ''} dropped")
    if prog.ignored:
        notes.append("ignored (they do not move the tool): " + ", ".join(
            f"{label} (line {line})" for label, line in sorted(prog.ignored.items(), key=lambda item: item[1])))
    return PathSpec(tuple(blocks), 2 if flat else 3, notes=tuple(notes))


def _flat(block, z0: float) -> bool:
    if block.kind == "nurbs":
        return bool(np.all(block.curve.control_points[:, 2] == z0))
    if block.kind == "arc" and (block.normal[2] == 0 or block.rise != 0):
        return False
    return block.start[2] == z0 and block.end[2] == z0


def _to_2d(block):
    if block.kind == "line":
        return LineBlock(block.start[:2].copy(), block.end[:2].copy(), block.feedrate, block.rapid, block.source)
    if block.kind == "arc":
        return ArcBlock(block.start[:2].copy(), block.end[:2].copy(), block.center[:2].copy(), block.normal,
                        block.sweep, 0.0, block.feedrate, block.source)
    c = block.curve
    return NurbsBlock(CurveSpec(c.degree, np.ascontiguousarray(c.control_points[:, :2]), c.weights.copy(),
                                c.knots.copy()), block.feedrate, block.source)
