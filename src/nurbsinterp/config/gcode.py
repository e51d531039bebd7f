"""The G-code reader: an RS274/NGC program, as LinuxCNC reads it, as a path.

What it reads
    Line numbers ``N``, comments ``( )`` and ``;``, block delete ``/`` (the line is
    skipped), letters in either case, spaces anywhere outside comments (LinuxCNC
    drops them before it reads a line, so ``X 1 0 . 5`` is X10.5), numbered and
    named parameters (``#10=290``, ``F#10``, ``#<feed>=300``; a line's assignments
    take effect after the line, as in LinuxCNC), ``%`` and ``M2``/``M30`` ends.
    Modes carried from block to block: ``G20``/``G21`` (inch or mm: everything
    read is converted to mm), ``G90``/``G91`` (absolute/incremental X Y Z),
    ``G90.1``/``G91.1`` (arc centres absolute/incremental, incremental by
    default), ``G17``/``G18``/``G19`` (arc and NURBS plane), ``G94`` (feed in
    units per minute), ``F`` and the motion mode.

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

Everything else
    G-codes that do not move the tool (``G40``, ``G49``, ``G54``..``G59.3``,
    ``G61``, ``G64``, ``G80``, ``G96``/``G97``, ``G4`` …) and every M-code but
    the ends are accepted and listed once in the path's notes; S, T, H, D words
    likewise.  Codes that would move the tool in ways this reader does not
    model (``G28``, ``G92``, cutter compensation ``G41``/``G42``, canned
    cycles, ``G93``/``G95`` feed modes, other axes A B C U V W) are refused
    with the line, as is any code it does not know.  Zero-length moves (a G1
    to where the tool already is) are dropped.

Every problem is one :class:`~nurbsinterp.errors.SpecError`:
``part.ngc:12: G2.2 is not a G-code this reader knows``.  The whole program is
read before anything is returned.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field

import numpy as np

from ..errors import SpecError
from .curve import MAX_COORDINATE, CurveSpec, validate_curve
from .path import MIN_BLOCK_LENGTH, ArcBlock, LineBlock, NurbsBlock, PathSpec
from .reading import read_bytes
from .rules import Where

MM_PER_INCH = 25.4
#: LinuxCNC's arc tolerances, which this reader accepts exactly as rs274 does (checked in tests/test_rs274.py).
#: I J K: the radii to start and end may differ by ARC_TOL (0.01·2·√2 in the program's units) when the
#: difference is also within ARC_REL_TOL of the radius, and never by more than 100·ARC_TOL.  Such an
#: arc LinuxCNC runs as a spiral; here its centre is moved onto the chord's perpendicular bisector so
#: that it is one circle through both ends, and refused if that moves it by more than the same
#: allowance.  R: |R| may fall short of half the chord by R_TOL (0.00005 in, in either unit system).
ARC_TOL = 0.01 * 2 * math.sqrt(2)
ARC_REL_TOL = 0.001
R_TOL_MM = 0.00005 * 25.4
DEFAULT_ORDER_G6 = 4
MAX_TURNS = 10_000

# plane -> (first axis, second axis, normal axis) as indices of X Y Z; a ccw arc turns from the
# first axis towards the second, about the normal (G18: Z towards X, about +Y)
PLANES = {170: (0, 1, 2), 180: (2, 0, 1), 190: (1, 2, 0)}
PLANE_NAMES = {170: "G17 (XY)", 180: "G18 (ZX)", 190: "G19 (YZ)"}
AXIS_LETTERS = "XYZ"
OFFSET_LETTERS = "IJK"

MOTION = {0, 10, 20, 30, 52, 53, 62}
#: modal groups: one code of each at most on a line (as rs274 checks)
GROUPS = ({200, 210}, {900, 910}, {901, 911}, {170, 180, 190}, {930, 940, 950}, {610, 611, 640},
          {540, 550, 560, 570, 580, 590, 591, 592, 593}, {400, 410, 420, 411, 421}, {430, 431, 490}, {980, 990})
MODAL = {200, 210, 900, 910, 901, 911, 170, 180, 190, 940}
#: G-codes that do not move the tool: accepted, listed in the notes
IGNORED_G = {40: "dwell", 400: "cutter compensation off", 430: "tool length offset",
             431: "dynamic tool length offset", 490: "tool length offset off", 540: "work offset",
             550: "work offset", 560: "work offset", 570: "work offset", 580: "work offset", 590: "work offset",
             591: "work offset", 592: "work offset", 593: "work offset", 610: "exact path", 611: "exact stop",
             640: "path blending", 800: "cancel canned cycle", 960: "constant surface speed",
             970: "spindle RPM mode", 980: "canned cycle return level", 990: "canned cycle return level"}
#: G-codes that move the tool, or change coordinates, in ways this reader does not model
REFUSED_G = {280: "G28 (go to a stored position)", 281: "G28.1 (store a position)",
             300: "G30 (go to a stored position)", 301: "G30.1 (store a position)", 530: "G53 (machine coordinates)", 920: "G92 (coordinate offset)", 921: "G92.1",
             922: "G92.2", 923: "G92.3", 100: "G10 (set offsets)", 410: "G41 (cutter compensation)",
             411: "G41.1 (cutter compensation)", 420: "G42 (cutter compensation)",
             421: "G42.1 (cutter compensation)", 930: "G93 (inverse-time feed)", 950: "G95 (feed per revolution)",
             50: "G5 (cubic spline)", 51: "G5.1 (quadratic spline)", 70: "G7 (lathe diameter mode)",
             80: "G8 (lathe radius mode)", 330: "G33 (spindle-synchronised motion)", 331: "G33.1 (rigid tapping)",
             381: "G38.x (probing)", 382: "G38.x (probing)", 383: "G38.x (probing)", 384: "G38.x (probing)",
             385: "G38.x (probing)", 730: "G73 (canned cycle)", 740: "G74 (canned cycle)",
             760: "G76 (threading cycle)", 810: "G81 (canned cycle)", 820: "G82 (canned cycle)",
             830: "G83 (canned cycle)", 840: "G84 (canned cycle)", 850: "G85 (canned cycle)",
             860: "G86 (canned cycle)", 870: "G87 (canned cycle)", 880: "G88 (canned cycle)",
             890: "G89 (canned cycle)", 171: "G17.1 (UV plane)", 181: "G18.1 (WU plane)",
             191: "G19.1 (VW plane)", 700: "G70", 710: "G71", 720: "G72"}
ENDS_M = {2, 30}
IGNORED_WORDS = {"S": "spindle speed", "T": "tool", "H": "tool length offset", "D": "tool radius"}
KNOWN_WORDS = set("GMXYZIJKRPQLFN") | set(IGNORED_WORDS)
OTHER_AXES = set("ABCUVW")

_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)")
_PARAM = re.compile(r"#(\d+|<[^>]*>)")


def _gname(code: int) -> str:
    """G-code name from its tenths: 52 -> 'G5.2', 200 -> 'G20'."""
    whole, tenth = divmod(code, 10)
    return f"G{whole}" if tenth == 0 else f"G{whole}.{tenth}"


@dataclass
class _Line:
    """One block of the program, its words read."""

    number: int  # line of the file, 1-based
    g: list = field(default_factory=list)  # G-codes in tenths
    m: list = field(default_factory=list)
    words: dict = field(default_factory=dict)  # letter -> float
    assignments: list = field(default_factory=list)  # (parameter, value)


class _Program:
    """The reader's state: modes, position, the blocks read so far."""

    def __init__(self, name: str, start):
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
        self.params = {}

    def fail(self, line: int, problem: str) -> SpecError:
        return SpecError(f"{self.name}:{line}: {problem}")

    def scale(self) -> float:
        return MM_PER_INCH if self.inch else 1.0

    def ignore(self, label: str, line: int) -> None:
        self.ignored.setdefault(label, line)


# --------------------------------------------------------------------------- reading a line


def _strip_comments(prog: _Program, text: str, number: int) -> str:
    out = []
    i = 0
    while i < len(text):
        c = text[i]
        if c == "(":
            j = text.find(")", i)
            if j < 0:
                raise prog.fail(number, "a comment '(' is not closed on its line")
            if "(" in text[i + 1:j]:
                raise prog.fail(number, "a comment holds another '(': comments do not nest")
            i = j + 1
            continue
        if c == ";":
            break
        out.append(c)
        i += 1
    return "".join(out)


def _value(prog: _Program, text: str, k: int, number: int, letter: str) -> tuple[float, int]:
    """The value after a word's letter at text[k:]: a number or a parameter; (value, next index)."""
    m = _NUMBER.match(text, k)
    if m:
        return float(m.group()), m.end()
    m = _PARAM.match(text, k)
    if m:
        key = m.group(1).lower()
        if key not in prog.params:
            raise prog.fail(number, f"{letter}#{m.group(1)}: parameter #{m.group(1)} is used before it is set")
        return prog.params[key], m.end()
    if text.startswith("[", k):
        raise prog.fail(number, f"{letter}[...]: expressions are not supported by this reader (give the number)")
    shown = text[k:k + 12] or "nothing"
    raise prog.fail(number, f"{letter} is followed by {shown!r}, not a number")


def _parse(prog: _Program, raw: str, number: int) -> _Line | None:
    text = _strip_comments(prog, raw, number)
    text = "".join(text.split()).upper()  # LinuxCNC drops spaces and tabs outside comments
    if not text:
        return None
    line = _Line(number)
    k = 0
    if text[0] == "N":  # a line number
        m = re.compile(r"N\d+(\.\d*)?").match(text)
        if not m:
            raise prog.fail(number, f"N is followed by {text[1:13]!r}, not a line number")
        k = m.end()
    first = k  # where the words start: an O-word may only stand here
    while k < len(text):
        c = text[k]
        if c == "#":  # an assignment #n=value or #<name>=value
            m = _PARAM.match(text, k)
            if not m or not text.startswith("=", m.end()):
                raise prog.fail(number, f"{text[k:k + 12]!r} is not a parameter assignment #n=value")
            value, k = _value(prog, text, m.end() + 1, number, m.group() + "=")
            line.assignments.append((m.group(1).lower(), value))
            continue
        if c == "O" and k > first:  # LinuxCNC reads an O-word only at the start of a line: here it is a stray O
            raise prog.fail(number, f"{text[first:k + 1]!r}: an O after the words {text[first:k]!r} (an O-word "
                                    f"starts its line; a typo?)")
        if c == "O":
            raise prog.fail(number, "O-words (subroutines, loops, conditions) are not supported by this reader")
        if not c.isalpha():
            raise prog.fail(number, f"{text[k:k + 12]!r} is not a word (a letter and a number)")
        if c in OTHER_AXES:
            raise prog.fail(number, f"{c} is an axis this reader does not drive (only X, Y and Z)")
        if c not in KNOWN_WORDS:
            raise prog.fail(number, f"{c} is not a word this reader knows")
        value, k = _value(prog, text, k + 1, number, c)
        if c == "G":
            code = round(value * 10)
            if abs(value * 10 - code) > 1e-6 or code < 0:
                raise prog.fail(number, f"G{value:g} is not a G-code this reader knows")
            line.g.append(code)
        elif c == "M":
            if value != int(value) or value < 0:
                raise prog.fail(number, f"M{value:g} is not an M-code")
            line.m.append(int(value))
        elif c == "N":
            raise prog.fail(number, "N (a line number) must come first on its line")
        else:
            if c in line.words:
                raise prog.fail(number, f"{c} is given twice on one line")
            line.words[c] = value
    return line


# --------------------------------------------------------------------------- blocks


def _target(prog: _Program, line: _Line) -> np.ndarray:
    """The end point a block's X Y Z words name (absolute or incremental), in mm."""
    end = prog.pos.copy()
    for j, letter in enumerate(AXIS_LETTERS):
        if letter in line.words:
            value = line.words[letter] * prog.scale()
            end[j] = value if prog.absolute else end[j] + value
            if not abs(end[j]) <= MAX_COORDINATE:
                raise prog.fail(line.number, f"{letter}{line.words[letter]:g} is beyond the supported range of "
                                f"+-{MAX_COORDINATE:g} mm")
    return end


def _straight(prog: _Program, line: _Line, rapid: bool) -> None:
    end = _target(prog, line)
    _add_line(prog, line.number, end, rapid)


def _add_line(prog: _Program, number: int, end, rapid: bool) -> None:
    if float(np.linalg.norm(end - prog.pos)) <= MIN_BLOCK_LENGTH:
        prog.dropped += 1
        return
    if not rapid and prog.feed is None:
        prog.feedless.append(number)
    prog.blocks.append(LineBlock(prog.pos.copy(), end, None if rapid else prog.feed, rapid, f"line {number}"))
    prog.pos = end


def _arc(prog: _Program, line: _Line, ccw: bool) -> None:
    number = line.number
    a0, a1, a2 = PLANES[prog.plane]
    scale = prog.scale()
    tol = ARC_TOL * scale  # in the program's units, as LinuxCNC applies it
    end = _target(prog, line)
    start = prog.pos
    code = "G3" if ccw else "G2"
    has_r = "R" in line.words
    offsets = [letter for letter in OFFSET_LETTERS if letter in line.words]
    if has_r and offsets:
        raise prog.fail(number, f"{code} has both R and {''.join(offsets)}: give the radius or the centre")
    if not has_r and not offsets:
        raise prog.fail(number, f"{code} needs I J K (the centre) or R (the radius)")
    if OFFSET_LETTERS[a2] in offsets:
        raise prog.fail(number, f"{code}: {OFFSET_LETTERS[a2]} is not an offset in the {PLANE_NAMES[prog.plane]} plane")
    turns = 1
    if "P" in line.words:
        p = line.words["P"]
        if p != int(p) or not 1 <= p <= MAX_TURNS:
            raise prog.fail(number, f"{code} P{p:g}: the number of turns must be a whole number from 1 to {MAX_TURNS}")
        turns = int(p)
    u = np.array([start[a0], start[a1]])
    v = np.array([end[a0], end[a1]])
    chord = v - u
    half = float(np.linalg.norm(chord)) / 2
    if has_r:
        r = line.words["R"] * scale
        if half <= MIN_BLOCK_LENGTH:
            raise prog.fail(number, f"{code} R{line.words['R']:g}: an arc given by its radius cannot end where it "
                            "starts (give the centre with I J K for a full circle)")
        if abs(r) < half - R_TOL_MM:
            raise prog.fail(number, f"{code} R{line.words['R']:g}: the radius is smaller than half the distance to "
                            f"the end ({half:.6g} mm)")
        h = math.sqrt(max(r * r - half * half, 0.0))
        left = np.array([-chord[1], chord[0]]) / (2 * half)  # the chord turned +90°
        # the short arc's centre lies to the left of the chord for ccw motion, to the right for cw;
        # a negative R asks for the long arc
        side = (1.0 if ccw else -1.0) * (1.0 if r > 0 else -1.0)
        center = u + chord / 2 + side * h * left
    else:
        center = u.copy()  # a missing offset is 0 (incremental centres)
        for j, a in enumerate((a0, a1)):
            letter = OFFSET_LETTERS[a]
            if letter in line.words:
                value = line.words[letter] * scale
                center[j] = value if prog.center_absolute else u[j] + value
            elif prog.center_absolute:
                raise prog.fail(number, f"{code}: {letter} is missing (arc centres are absolute, G90.1)")
        r0, r1 = float(np.linalg.norm(u - center)), float(np.linalg.norm(v - center))
        if r0 <= MIN_BLOCK_LENGTH:
            raise prog.fail(number, f"{code}: the centre is the arc's start (a zero radius)")
        err = abs(r1 - r0)
        if (err > tol and err > ARC_REL_TOL * max(r0, r1)) or err > 100 * tol:
            raise prog.fail(number, f"{code}: the radius to the end, {r1:.6g} mm, differs from the radius to the "
                            f"start, {r0:.6g} mm, by {err:.3g} mm (more than {tol:.3g} mm and "
                            f"{ARC_REL_TOL:g} of the radius)")
        if half > MIN_BLOCK_LENGTH and abs(r1 - r0) > 0:
            # onto the chord's bisector, so that the arc is one circle through both ends
            along = chord / (2 * half)
            shift = float((center - (u + v) / 2) @ along)
            if abs(shift) > max(tol, ARC_REL_TOL * r0):
                raise prog.fail(number, f"{code}: the centre is {abs(shift):.3g} mm off the perpendicular bisector of "
                                f"the arc's chord (more than {max(tol, ARC_REL_TOL * r0):.3g} mm): the radii {r0:.6g} "
                                f"and {r1:.6g} mm disagree, and this reader makes every arc a true circle")
            center = center - shift * along
    normal = np.zeros(3)
    normal[a2] = 1.0 if ccw else -1.0
    c3 = start.copy()
    c3[a0], c3[a1] = center
    # the sweep, in the direction of motion, in (0, 2π]; full turns before it for P > 1
    e1, e2 = u - center, v - center
    angle = math.atan2(e1[0] * e2[1] - e1[1] * e2[0], float(e1 @ e2))
    if not ccw:
        angle = -angle
    if half <= MIN_BLOCK_LENGTH:  # a full circle: its end is its start (in the plane), exactly
        angle = 2 * math.pi
        end[a0], end[a1] = start[a0], start[a1]
    elif angle <= 0:
        angle += 2 * math.pi
    radius = float(np.linalg.norm(e1))
    rise = float(end[a2] - start[a2])
    total = angle + 2 * math.pi * (turns - 1)
    if total * radius <= MIN_BLOCK_LENGTH and abs(rise) <= MIN_BLOCK_LENGTH:
        prog.dropped += 1
        return
    if prog.feed is None:
        prog.feedless.append(number)
    here = start.copy()
    # P > 1: whole turns first, each a helix of its share of the rise
    for k in range(turns):
        sweep = 2 * math.pi if k < turns - 1 else angle
        stop = end.copy() if k == turns - 1 else here.copy()
        if k < turns - 1:
            stop[a2] = here[a2] + rise * sweep / total
        centre_k = c3.copy()
        centre_k[a2] = here[a2]
        piece_rise = float(stop[a2] - here[a2]) * normal[a2]  # along the normal, which points down for G2
        prog.blocks.append(ArcBlock(here.copy(), stop, centre_k, normal.copy(), sweep,
                                    0.0 if abs(piece_rise) <= MIN_BLOCK_LENGTH else piece_rise, prog.feed,
                                    f"line {number}"))
        here = stop
    prog.pos = end.copy()


# --------------------------------------------------------------------------- NURBS blocks


def _begin_g5(prog: _Program, line: _Line) -> None:
    if prog.nurbs is not None:
        raise prog.fail(line.number, f"G5.2 starts a NURBS while the one of line {prog.nurbs['line']} is not closed")
    if not prog.absolute:
        raise prog.fail(line.number, "G5.2 in incremental mode (G91): control points must be absolute (G90)")
    order = 3
    if "L" in line.words:
        L = line.words["L"]
        if L != int(L) or L < 1:
            raise prog.fail(line.number, f"G5.2 L{L:g}: the order must be a whole number")
        if L > 3:
            order = int(L)
        elif L < 3:
            prog.notes.append(f"line {line.number}: G5.2 L{L:g} is read as order 3, as LinuxCNC reads any L <= 3")
    weight = 1.0
    a0, a1, _ = PLANES[prog.plane]
    has_point = AXIS_LETTERS[a0] in line.words or AXIS_LETTERS[a1] in line.words
    if "P" in line.words and not has_point:
        weight = _weight(prog, line, "P", "G5.2")
    prog.nurbs = {"kind": "G5.2", "line": line.number, "order": order, "points": [prog.pos.copy()],
                  "weights": [weight], "knots": None, "feed": prog.feed, "plane": prog.plane}
    if has_point:
        _g5_point(prog, line)


def _weight(prog: _Program, line: _Line, letter: str, code: str) -> float:
    w = line.words[letter]
    if not w > 0:
        raise prog.fail(line.number, f"{code} {letter}{w:g}: a control point's weight must be > 0")
    return float(w)


def _g5_point(prog: _Program, line: _Line) -> None:
    a0, a1, a2 = PLANES[prog.nurbs["plane"]]
    letters = AXIS_LETTERS[a0] + AXIS_LETTERS[a1]
    given = [c for c in letters if c in line.words]
    if len(given) != 2:
        raise prog.fail(line.number, f"G5.2: a control point needs both {letters[0]} and {letters[1]} "
                        f"(the {PLANE_NAMES[prog.nurbs['plane']]} plane)")
    if AXIS_LETTERS[a2] in line.words:
        raise prog.fail(line.number, f"G5.2: {AXIS_LETTERS[a2]} is not a coordinate of the "
                        f"{PLANE_NAMES[prog.nurbs['plane']]} plane")
    if "P" not in line.words:
        raise prog.fail(line.number, "G5.2: a control point needs its weight P")
    weight = _weight(prog, line, "P", "G5.2")
    point = prog.nurbs["points"][0].copy()
    for letter in letters:
        point["XYZ".index(letter)] = line.words[letter] * prog.scale()
    prog.nurbs["points"].append(point)
    prog.nurbs["weights"].append(weight)


def _end_g5(prog: _Program, line: _Line) -> None:
    nurbs = prog.nurbs
    if nurbs is None or nurbs["kind"] != "G5.2":
        raise prog.fail(line.number, "G5.3 without G5.2: there is no NURBS block to close")
    n, k = len(nurbs["points"]), nurbs["order"]
    if n < k:
        raise prog.fail(line.number, f"G5.3 closes the G5.2 of line {nurbs['line']} with {n} control points; "
                        f"order {k} needs at least {k}")
    # LinuxCNC's knots: k zeros, 1 .. n-k, then n-k+1 k times
    nurbs["knots"] = [0.0] * k + [float(i) for i in range(1, n - k + 1)] + [float(n - k + 1)] * k
    _finish_nurbs(prog, line.number)


def _begin_g6(prog: _Program, line: _Line) -> None:
    if prog.nurbs is not None:
        raise prog.fail(line.number, f"G6.2 starts a NURBS while the one of line {prog.nurbs['line']} is not "
                        "closed (it needs order P knot-only blocks)")
    if not prog.absolute:
        raise prog.fail(line.number, "G6.2 in incremental mode (G91): control points must be absolute (G90)")
    order = DEFAULT_ORDER_G6
    if "P" in line.words:
        P = line.words["P"]
        if P != int(P) or not 2 <= P <= 26:
            raise prog.fail(line.number, f"G6.2 P{P:g}: the order must be a whole number from 2 to 26")
        order = int(P)
    if "Q" in line.words:
        prog.ignore(f"G6.2 Q (LinuxCNC's choice of interpolation method; nurbsinterp interpolates the NURBS "
                    "itself)", line.number)
    if "K" not in line.words:
        raise prog.fail(line.number, "G6.2 needs the first control point's knot K")
    prog.nurbs = {"kind": "G6.2", "line": line.number, "order": order, "points": [], "weights": [],
                  "knots": [], "knot_lines": [], "closing": 0, "feed": prog.feed, "plane": prog.plane}
    _g6_point(prog, line)


def _g6_point(prog: _Program, line: _Line) -> None:
    nurbs = prog.nurbs
    point = nurbs["points"][-1].copy() if nurbs["points"] else prog.pos.copy()
    moved = False
    for j, letter in enumerate(AXIS_LETTERS):
        if letter in line.words:
            point[j] = line.words[letter] * prog.scale()
            moved = True
    if "K" not in line.words:
        raise prog.fail(line.number, "G6.2: a control point needs its knot K")
    if not moved and nurbs["points"]:  # K alone (and perhaps R): a closing knot
        if "R" in line.words:
            raise prog.fail(line.number, "G6.2: a knot-only block takes no weight R")
        _g6_knot(prog, line)
        return
    if nurbs["closing"]:
        raise prog.fail(line.number, "G6.2: a control point after the closing knots began")
    weight = _weight(prog, line, "R", "G6.2") if "R" in line.words else 1.0
    nurbs["points"].append(point)
    nurbs["weights"].append(weight)
    _g6_knot(prog, line, closing=False)


def _g6_knot(prog: _Program, line: _Line, closing: bool = True) -> None:
    nurbs = prog.nurbs
    knot = float(line.words["K"])
    if nurbs["knots"] and knot < nurbs["knots"][-1]:
        raise prog.fail(line.number, f"G6.2: knot K{knot:g} is smaller than the previous knot "
                        f"K{nurbs['knots'][-1]:g} (line {nurbs['knot_lines'][-1]}); knots must not decrease")
    nurbs["knots"].append(knot)
    nurbs["knot_lines"].append(line.number)
    if closing:
        nurbs["closing"] += 1
        if nurbs["closing"] == nurbs["order"]:
            _finish_g6(prog, line.number)


def _finish_g6(prog: _Program, number: int) -> None:
    nurbs = prog.nurbs
    k, n = nurbs["order"], len(nurbs["points"])
    knots = nurbs["knots"]
    if n < k:
        raise prog.fail(number, f"G6.2 of line {nurbs['line']} has {n} control points; order P{k} needs at least {k}")
    lines = nurbs["knot_lines"]
    for side, idx in (("first", range(k)), ("last", range(len(knots) - k, len(knots)))):
        idx = list(idx)
        if any(knots[i] != knots[idx[0]] for i in idx):
            bad = next(i for i in idx if knots[i] != knots[idx[0]])
            raise prog.fail(lines[bad], f"G6.2: knot K{knots[bad]:g} breaks the clamped knot vector: the {side} "
                            f"P{k} knots must be equal (K{knots[idx[0]]:g}, line {lines[idx[0]]}) (Fanuc alarm "
                            f"{1007 if side == 'first' else 1008})")
    if knots[-1] == knots[0]:
        raise prog.fail(number, f"G6.2 of line {nurbs['line']}: every knot is K{knots[0]:g}; the curve has no domain")
    _finish_nurbs(prog, number)


def _finish_nurbs(prog: _Program, number: int) -> None:
    nurbs = prog.nurbs
    prog.nurbs = None
    points = np.array(nurbs["points"])
    first = nurbs["line"]
    if float(np.linalg.norm(points[0] - prog.pos)) > MIN_BLOCK_LENGTH:
        prog.notes.append(f"line {first}: the {nurbs['kind']} curve starts "
                          f"{float(np.linalg.norm(points[0] - prog.pos)):.6g} mm from the tool's position; a straight "
                          "feed move goes there first")
        _add_line(prog, first, points[0].copy(), rapid=False)
    points[0] = prog.pos
    raw = {"degree": nurbs["order"] - 1, "control_points": points.tolist(), "weights": nurbs["weights"],
           "knots": nurbs["knots"]}
    curve = validate_curve(raw, Where(f"{prog.name}:{first}"), nurbs["kind"])
    if nurbs["feed"] is None and prog.feed is None:
        prog.feedless.append(first)
    feed = prog.feed if prog.feed is not None else nurbs["feed"]
    prog.blocks.append(NurbsBlock(curve, feed, f"line {first}"))
    prog.pos = curve.control_points[-1].copy()


# --------------------------------------------------------------------------- the program


def read_gcode(name: str, start=None) -> PathSpec:
    """The path of a G-code program (see the module docstring).

    Parameters
    ----------
    name : the program's file
    start : (x, y, z) mm where the tool is when the program starts (default the origin, as ``rs274``)
    """
    text = _read_text(name)
    prog = _Program(name, (0.0, 0.0, 0.0) if start is None else _start(name, start))
    percent = 0
    seen = False  # a line other than blanks before it
    for number, raw in enumerate(text.splitlines(), 1):
        stripped = raw.strip()
        if stripped.startswith("/"):  # block delete: skipped, as with the switch on
            continue
        if stripped == "%":
            if percent == 0 and not seen:
                percent = 1  # the program's first line: it ends at the next '%'
                continue
            if percent:
                break
            raise prog.fail(number, "'%' is only a program's first line and, after it, its end")
        seen = seen or bool(stripped)
        line = _parse(prog, raw, number)
        if line is None:
            continue
        if _execute(prog, line):
            break
    if prog.nurbs is not None:
        nurbs = prog.nurbs
        what = "G5.3" if nurbs["kind"] == "G5.2" else f"{nurbs['order'] - nurbs['closing']} more knot-only blocks"
        raise prog.fail(nurbs["line"], f"{nurbs['kind']} is not closed: the program ends before {what}")
    return _path(prog)


def _execute(prog: _Program, line: _Line) -> bool:
    """Carry out one line; True at the program's end."""
    number = line.number
    motions = [g for g in line.g if g in MOTION]
    if len(motions) > 1:
        raise prog.fail(number, f"{' and '.join(_gname(g) for g in motions)} are two motions on one line")
    for group in GROUPS:
        same = [g for g in line.g if g in group]
        if len(same) > 1:
            raise prog.fail(number, f"{' and '.join(_gname(g) for g in same)} are two modes of one group on one line")
    for g in line.g:
        if g in MOTION or g in MODAL:
            continue
        if g in IGNORED_G:
            prog.ignore(f"{_gname(g)} ({IGNORED_G[g]})", number)
        elif g in REFUSED_G:
            raise prog.fail(number, f"{REFUSED_G[g]} is not supported by this reader")
        else:
            raise prog.fail(number, f"{_gname(g)} is not a G-code this reader knows")
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
                raise prog.fail(number, f"{_gname(g)} changes the plane inside the {prog.nurbs['kind']} of line "
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
        _begin_g5(prog, line)
    elif motion == 62:
        prog.motion = 62
        _begin_g6(prog, line)
    else:
        if motion is not None:
            prog.motion = motion
        if motion is not None or moving:
            _move(prog, line)
    for key, value in line.assignments:  # after the line, as LinuxCNC sets parameters
        prog.params[key] = value
    return any(m in ENDS_M for m in line.m)


def _check_words(prog: _Program, line: _Line, motion) -> None:
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


def _nurbs_line(prog: _Program, line: _Line, motion, moving: bool) -> None:
    nurbs = prog.nurbs
    kind = nurbs["kind"]
    if kind == "G5.2":
        if motion == 53:
            if moving:
                raise prog.fail(line.number, "G5.3 takes no coordinates")
            _end_g5(prog, line)
            prog.motion = None
        elif motion in (None, 52):
            if motion == 52:
                raise prog.fail(line.number, f"G5.2 starts a NURBS while the one of line {nurbs['line']} is not "
                                "closed by G5.3")
            if moving or "P" in line.words:
                _g5_point(prog, line)
        else:
            raise prog.fail(nurbs["line"], f"G5.2 is not closed by G5.3 before the {_gname(motion)} of line "
                            f"{line.number}")
        return
    if motion not in (None, 62):
        raise prog.fail(nurbs["line"], f"G6.2 is not closed: {nurbs['order'] - nurbs['closing']} more knot-only "
                        f"blocks were expected before the {_gname(motion)} of line {line.number}")
    if motion == 62 and moving:
        raise prog.fail(nurbs["line"], f"G6.2 is not closed: {nurbs['order'] - nurbs['closing']} more knot-only "
                        f"blocks were expected before the new G6.2 of line {line.number}")
    if moving or "K" in line.words or "R" in line.words:
        _g6_point(prog, line)
        if prog.nurbs is None:
            prog.motion = None


def _move(prog: _Program, line: _Line) -> None:
    motion = prog.motion
    if motion is None:
        raise prog.fail(line.number, "coordinates without a motion mode (G0, G1, G2, G3) in effect")
    if motion in (0, 10):
        _straight(prog, line, rapid=motion == 0)
    elif motion in (20, 30):
        _arc(prog, line, ccw=motion == 30)
    elif motion in (52, 62, 53):
        raise prog.fail(line.number, "coordinates after a closed NURBS block: give a motion (G0, G1, G2, G3)")


def _path(prog: _Program) -> PathSpec:
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


def _read_text(name: str) -> str:
    data = read_bytes(name, "program")
    if b"\0" in data:
        raise SpecError(f"{name}: is not a text file (it holds NUL bytes)")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")  # comments in old programs; the words themselves are ASCII


def _start(name: str, start) -> tuple:
    values = [float(v) for v in start]
    if len(values) == 2:
        values.append(0.0)
    if len(values) != 3 or not all(math.isfinite(v) and abs(v) <= MAX_COORDINATE for v in values):
        raise SpecError(f"{name}: the start position {tuple(start)} must be 2 or 3 finite coordinates in mm")
    return tuple(values)


def read_gcode_job(name: str, *, start=None, **_options):
    """The G-code reader for :func:`~nurbsinterp.config.job.load_job`: (the path, no profile sections)."""
    return read_gcode(name, start), {}
