"""The G-code reader against LinuxCNC's own interpreter, ``rs274`` (issue 15, item 5).

Opt-in: these tests run only where ``rs274`` is on PATH (Debian package
``linuxcnc-uspace``).  Each program is read twice, by
:func:`~nurbsinterp.config.gcode.read_gcode_job` and by rs274 (through
``tests/rs274ref.py``, which documents rs274's output), and the two must agree
move by move: kind, start and end, arc centre, normal (plane and direction),
sweep, helical rise and feed.  rs274 prints zero-length moves (a G1 without
axis words, ``G91 X0``); the reader drops them, so they are left out here too.

Programs: ``curves/pocket.ngc`` when it exists, and seeded random programs of
G0/G1/G2/G3 over G20/G21, G90/G91, G90.1/G91.1, G17/G18/G19, I J K and R arcs
(negative R: the long arc), full circles, helices, F words, comments ``( )``
and ``;``, N words, lower case, block delete ``/`` (rs274 runs with its switch
on, ``-b``, as the reader skips those lines) and M2.  Every random arc ends
exactly on its circle before its numbers are printed; the "exact" programs
print 8 decimals in mm and 9 in inches, so that their rounding (at most
1.4e-8 mm, 3.6e-8 mm on a radius) stays far inside every tolerance; the "CAM"
programs print 4 and 5, as CAM post-processors do.

Tolerances
----------
rs274 prints lengths with 4 decimals in the program's units, so each printed
coordinate is within ``HALF_STEP`` = 5e-5 units of the interpreter's value:
5e-5 mm in G21, 1.27e-3 mm in G20 (``Move.start_tol``, ``Move.end_tol``:
the start's bound is that of the units it was printed in).  Points are
compared coordinate by coordinate to that bound plus ``SLACK`` = 1e-9 mm for
floating point in both readers (coordinates stay below 400 mm, where a few
roundings cost ~1e-13 mm).  A radius vector whose two ends are each off by
at most t_a and t_b per coordinate turns by at most √2·(t_a + t_b)/r, so a
sweep from the rounded start, end and centre is within
√2·(t_s + 2·t_c + t_e)/r.  The rise is within t_s + t_e.  Normals are exact
(± a coordinate axis).  Feeds are whole numbers of units per minute here, so
they must agree to 1e-9 relative.

Where the program's centre is not equidistant from the arc's ends (CAM
rounding), LinuxCNC keeps the centre and the reader moves it onto the chord's
perpendicular bisector; the centre may then differ by that move,
|r_end² - r_start²| / (2·chord), which the "CAM" comparison allows.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest

import rs274ref

if rs274ref.RS274 is None:
    pytest.skip("rs274 not on PATH (Debian package linuxcnc-uspace)", allow_module_level=True)

from nurbsinterp.config.gcode import read_gcode_job  # noqa: E402
from nurbsinterp.errors import SpecError  # noqa: E402

POCKET = Path(__file__).resolve().parent.parent / "curves" / "pocket.ngc"
SLACK = 1e-9  # mm: floating point in both readers, far below rs274's printed digits
EXACT_SEEDS = range(200)
CAM_SEEDS = range(1000, 1050)
PLANE_AXES = {"xy": (0, 1, 2), "zx": (2, 0, 1), "yz": (1, 2, 0)}  # (first, second, normal axis), as G17 G18 G19
PLANE_CODES = {"xy": "G17", "zx": "G18", "yz": "G19"}
AXIS_LETTERS, OFFSET_LETTERS = "XYZ", "IJK"
COMMENTS = ("rough", "finish pass", "pocket 2", "contour", "tool 3, 6 mm", "side wall", "op 10")


# --------------------------------------------------------------------------- random programs


@dataclass
class Program:
    """A generated program: its text, and the file line of each move that is not zero-length."""

    text: str
    move_lines: list[int] = field(default_factory=list)


class ProgramWriter:
    """Writes a random program that LinuxCNC accepts, tracking the interpreter's state as it goes.

    Positions are kept in mm as the interpreter reads the printed numbers (what
    rs274 and the reader both see), not as drawn: the drawn values only choose
    the words."""

    def __init__(self, seed: int, *, decimals_mm: int, decimals_inch: int):
        self.rng = np.random.default_rng(seed)
        self.decimals = {False: decimals_mm, True: decimals_inch}
        self.rows: list[str] = []
        self.move_lines: list[int] = []
        self.inch = False
        self.absolute = True
        self.center_absolute = False  # LinuxCNC's default, G91.1
        self.plane = "xy"
        self.pos = np.zeros(3)  # mm
        self.feed_ok = False  # an F given in the current units
        self.motion: str | None = None
        self.n_word = 0
        self.planar = bool(self.rng.random() < 0.3)  # never moves Z: the reader's 2-D case

    @property
    def factor(self) -> float:
        return 25.4 if self.inch else 1.0

    # ---- words and lines

    def number(self, value: float) -> tuple[str, float]:
        """*value* (program units) as written, in one of the forms G-code allows, and as read back."""
        rng = self.rng
        text = f"{value:.{self.decimals[self.inch]}f}".rstrip("0")
        if text in ("-0.", "0."):
            text = "0."
        if text.endswith(".") and rng.random() < 0.6:
            text = text[:-1]
        roll = rng.random()
        if roll < 0.1 and text.startswith(("0.", "-0.")):  # .5, -.25
            text = text.replace("0.", ".", 1)
        elif roll > 0.95 and not text.startswith("-"):
            text = "+" + text
        return text, float(text)

    def code(self, g: str) -> str:
        """G1 as G1 or G01."""
        if len(g) == 2 and self.rng.random() < 0.3:
            return g[0] + "0" + g[1]
        return g

    def write(self, words: list[str], *, move: bool = False, zero: bool = False) -> int:
        rng = self.rng
        sep = str(rng.choice(["", " ", "  "], p=[0.15, 0.75, 0.1]))
        text = sep.join(words)
        if rng.random() < 0.15:
            text = f"({rng.choice(COMMENTS)}) " + text
        if rng.random() < 0.3:
            self.n_word += int(rng.integers(1, 10))
            text = f"N{self.n_word} " + text
        roll = rng.random()
        if roll < 0.1:
            text += f" ({rng.choice(COMMENTS)})"
        elif roll < 0.2:
            text += f" ; {rng.choice(COMMENTS)}"
        if rng.random() < 0.2:
            text = text.lower()
        self.rows.append(text)
        line = len(self.rows)
        if move and not zero:
            self.move_lines.append(line)
        return line

    def modal_changes(self) -> list[str]:
        """Mode codes to change before a move: written on their own line or in front of the move."""
        rng = self.rng
        codes = []
        if rng.random() < 0.08:
            self.inch = not self.inch
            self.feed_ok = False  # F is restated after a units switch (see test_unit_switch_feed)
            codes.append("G20" if self.inch else "G21")
        if rng.random() < 0.1:
            self.absolute = not self.absolute
            codes.append("G90" if self.absolute else "G91")
        if rng.random() < 0.08:
            self.center_absolute = not self.center_absolute
            codes.append("G90.1" if self.center_absolute else "G91.1")
        if not self.planar and rng.random() < 0.15:
            self.plane = str(rng.choice([p for p in PLANE_AXES if p != self.plane]))
            codes.append(PLANE_CODES[self.plane])
        # an F on the line of a units switch is read in the old units (LinuxCNC's order of
        # execution, see test_feed_on_units_switch_line): a switch gets a line of its own
        if codes and (rng.random() < 0.4 or {"G20", "G21"} & set(codes)):
            self.write(codes)
            return []
        return codes

    def feed_words(self, motion: str) -> list[str]:
        if motion == "G0":
            return []
        if not self.feed_ok or self.rng.random() < 0.2:
            self.feed_ok = True
            return [f"F{int(self.rng.integers(30, 3000))}"]
        return []

    def motion_word(self, motion: str, codes: list[str]) -> list[str]:
        """The motion code, left out (modal) now and then when it is the one in effect."""
        keep = codes or motion != self.motion or self.rng.random() < 0.7
        self.motion = motion
        return [self.code(motion)] if keep else []

    def axis_word(self, axis: int, target_mm: float) -> str:
        """The word moving *axis* to *target_mm*; updates the position as the interpreter reads it."""
        f = self.factor
        value = target_mm / f if self.absolute else (target_mm - self.pos[axis]) / f
        text, read = self.number(value)
        self.pos[axis] = read * f if self.absolute else self.pos[axis] + read * f
        return AXIS_LETTERS[axis] + text

    # ---- moves

    def straight(self, motion: str) -> None:
        rng = self.rng
        codes = self.modal_changes()
        while True:
            target = self.pos.copy()
            moving = [a for a in (0, 1) if rng.random() < 0.7] or [int(rng.integers(2))]
            if not self.planar and rng.random() < 0.35:
                moving.append(2)
            for a in moving:
                target[a] = rng.uniform(-20, 20) if a == 2 else rng.uniform(-100, 100)
            if np.max(np.abs(target - self.pos)) > 0.01:
                break
        words = codes + self.motion_word(motion, codes) + [self.axis_word(a, target[a]) for a in moving]
        self.write(words + self.feed_words(motion), move=True)

    def zero_length(self) -> None:
        """A move to where the tool is: rs274 prints it, the reader drops it."""
        motion = str(self.rng.choice(["G0", "G1"]))
        self.motion = motion
        words = [self.code(motion)] + (["X0"] if not self.absolute and self.rng.random() < 0.5 else [])
        self.write(words + self.feed_words(motion), move=True, zero=True)

    def arc(self) -> None:
        rng = self.rng
        codes = self.modal_changes()
        a0, a1, a2 = PLANE_AXES[self.plane]
        f = self.factor
        start = self.pos.copy()
        radius = rng.uniform(1.0, 40.0)
        phi = rng.uniform(0, 2 * math.pi)  # the start's angle about the centre, in (first, second)
        center = start.copy()
        center[a0] -= radius * math.cos(phi)
        center[a1] -= radius * math.sin(phi)
        ccw = bool(rng.random() < 0.5)
        kind = str(rng.choice(["full", "ijk", "r"], p=[0.15, 0.55, 0.3]))
        if kind == "full":
            sweep = 2 * math.pi
        elif kind == "r":  # away from the half circle, where R fixes the centre badly
            short = rng.random() < 0.6
            sweep = rng.uniform(0.1, math.pi - 0.3) if short else rng.uniform(math.pi + 0.3, 2 * math.pi - 0.1)
        else:
            sweep = rng.uniform(0.1, 2 * math.pi - 0.1)
        theta = phi + (sweep if ccw else -sweep)
        target = start.copy()
        target[a0] = center[a0] + radius * math.cos(theta)
        target[a1] = center[a1] + radius * math.sin(theta)
        helix = not self.planar and rng.random() < 0.3
        if helix:
            target[a2] = start[a2] + rng.uniform(-5, 5)
        motion = "G3" if ccw else "G2"
        # a full circle in the motion mode in effect may be a line of I J K alone: LinuxCNC runs it
        words = codes + self.motion_word(motion, codes)
        for a in (a0, a1):
            if kind != "full":
                words.append(self.axis_word(a, target[a]))
            elif not self.absolute and rng.random() < 0.5:
                words.append(AXIS_LETTERS[a] + "0")  # a full circle: ends where it starts
            elif self.absolute and rng.random() < 0.5 and float(self.number(self.pos[a] / f)[0]) * f == self.pos[a]:
                words.append(AXIS_LETTERS[a] + self.number(self.pos[a] / f)[0])
        if helix:
            words.append(self.axis_word(a2, target[a2]))
        if kind == "r":
            text, _ = self.number((radius if sweep < math.pi else -radius) / f)
            words.append("R" + text)
        else:
            for a in (a0, a1):
                value = center[a] / f if self.center_absolute else (center[a] - start[a]) / f
                text, read = self.number(value)
                if not self.center_absolute and read == 0.0 and rng.random() < 0.5:
                    continue  # an offset of 0 may be left out
                words.append(OFFSET_LETTERS[a] + text)
        self.write(words + self.feed_words(motion), move=True)

    def block_deleted(self) -> None:
        """A line the block-delete switch skips: it would move the tool if it ran."""
        x, y = (self.number(v / self.factor)[0] for v in self.rng.uniform(-100, 100, 2))
        self.rows.append(str(self.rng.choice(["/", " /", "/ "])) + f"G0 X{x} Y{y}")

    def program(self) -> Program:
        rng = self.rng
        if rng.random() < 0.3:
            self.rows.append(f"({rng.choice(COMMENTS)})")
        if rng.random() < 0.7:  # a header; LinuxCNC's defaults (G21 G90 G17 G91.1) otherwise
            self.inch = bool(rng.random() < 0.4)
            header = ["G20" if self.inch else "G21", "G90", "G17"]
            if rng.random() < 0.3:
                self.center_absolute = True
                header.append("G90.1")
            self.write(header)
        actions = ["rapid", "line", "arc", "zero", "deleted", "comment", "feed"]
        for _ in range(int(rng.integers(12, 28))):
            action = rng.choice(actions, p=[0.15, 0.3, 0.4, 0.04, 0.04, 0.04, 0.03])
            if action == "rapid":
                self.straight("G0")
            elif action == "line":
                self.straight("G1")
            elif action == "arc":
                self.arc()
            elif action == "zero":
                self.zero_length()
            elif action == "deleted":
                self.block_deleted()
            elif action == "comment":
                self.rows.append(str(rng.choice(["", f"({rng.choice(COMMENTS)})", f"; {rng.choice(COMMENTS)}"])))
            else:
                self.feed_ok = True
                self.write([f"F{int(rng.integers(30, 3000))}"])
        self.write([str(rng.choice(["M2", "M02", "m2"]))])
        return Program("\n".join(self.rows) + "\n", self.move_lines)


def random_program(seed: int, *, cam: bool = False) -> Program:
    """Seeded: the same seed writes the same program."""
    return ProgramWriter(seed, decimals_mm=4 if cam else 8, decimals_inch=5 if cam else 9).program()


# --------------------------------------------------------------------------- comparison


def _point3(p, z0: float) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    return np.append(p, z0) if p.shape[0] == 2 else p


def _shown(p) -> str:
    return "[" + ", ".join(f"{float(c):.6f}" for c in p) + "]"


def _far(name: str, ours, ref, tol: float) -> list[str]:
    gap = float(np.max(np.abs(ours - ref)))
    if not gap <= tol:
        return [f"{name} {_shown(ours)}, rs274 {_shown(ref)}: {gap:.3g} mm apart (> {tol:.3g} mm)"]
    return []


def compare_move(block, move: rs274ref.Move, z0: float, *, bisector: bool = False) -> list[str]:
    """What differs between one of the reader's blocks and one of rs274's moves (empty: they agree)."""
    kind = "rapid" if block.kind == "line" and block.rapid else block.kind
    if kind != move.kind:
        return [f"kind {kind}, rs274 {move.kind}"]
    problems: list[str] = []
    start, end = _point3(block.start, z0), _point3(block.end, z0)
    t_s, t_e = move.start_tol + SLACK, move.end_tol + SLACK
    if move.start is not None:
        problems += _far("start", start, move.start, t_s)
    if move.end is not None:
        problems += _far("end", end, move.end, t_e)
    if kind == "arc":
        t_c = max(move.start_tol, move.end_tol) + SLACK
        chord_slack = 0.0
        if bisector and not move.is_full_circle:
            u = move.start - move.center
            v = (move.end - move.rise * move.normal) - move.center
            chord = float(np.linalg.norm(v - u))
            chord_slack = (abs(v @ v - u @ u) + 4 * math.sqrt(2) * move.radius * t_c) / (2 * chord)
        problems += _far("centre", _point3(block.center, start[2]), move.center, t_c + chord_slack)
        normal = np.asarray(block.normal, dtype=float)
        if not np.allclose(normal, move.normal, rtol=0, atol=1e-12):
            problems.append(f"normal {_shown(normal)}, rs274 {_shown(move.normal)} (plane {move.plane}, "
                            f"{'ccw' if move.normal.sum() > 0 else 'cw'})")
        t_sweep = math.sqrt(2) * (t_s + 2 * t_c + t_e + 2 * chord_slack) / move.radius + SLACK
        if not abs(block.sweep - move.sweep) <= t_sweep:
            problems.append(f"sweep {block.sweep!r} rad, rs274 {move.sweep!r} rad (> {t_sweep:.3g} rad apart)")
        if not abs(block.rise - move.rise) <= t_s + t_e:
            problems.append(f"rise {block.rise!r} mm, rs274 {move.rise!r} mm")
    if kind == "nurbs" and len(block.curve.control_points) != move.count:
        problems.append(f"{len(block.curve.control_points)} control points, rs274 {move.count}")
    if kind != "rapid":
        expected = None if move.feed is None else move.feed / 60.0
        if (block.feedrate is None) != (expected is None) or (
                expected is not None and not abs(block.feedrate - expected) <= 1e-9 * expected):
            problems.append(f"feedrate {block.feedrate!r} mm/s, rs274 {expected!r} mm/s")
    return problems


def mismatches(spec, moves: list[rs274ref.Move], *, z0: float = 0.0, bisector: bool = False) -> list[str]:
    """Every difference between the reader's path and rs274's moves, move by move (zero-length ones left out)."""
    ref = [m for m in moves if not m.is_zero_length]
    found = []
    for k, (block, move) in enumerate(zip(spec.blocks, ref)):
        for problem in compare_move(block, move, z0, bisector=bisector):
            found.append(f"move {k} ({block.source}; rs274 output line {move.index}): {problem}")
    if len(spec.blocks) != len(ref):
        found.append(f"the reader made {len(spec.blocks)} blocks, rs274 {len(ref)} moves (zero-length ones left out)")
    return found


def numbered(text: str) -> str:
    return "\n".join(f"{k:4d}  {row}" for k, row in enumerate(text.splitlines(), 1))


def check_program(path: Path, moves, *, expected_lines: list[int] | None = None, bisector: bool = False):
    if isinstance(moves, Exception):
        pytest.fail(f"rs274 refused the program (the test's own generator is wrong):\n{moves}\n"
                    f"{numbered(path.read_text())}")
    if expected_lines is not None:  # the generator's own model of the program, checked against rs274
        count = sum(not m.is_zero_length for m in moves)
        assert count == len(expected_lines), f"generator expected {len(expected_lines)} moves, rs274 made {count}"
    spec, _sections = read_gcode_job(str(path))
    found = mismatches(spec, moves, bisector=bisector)
    if expected_lines is not None and not found:
        sources = [b.source for b in spec.blocks]
        if sources != [f"line {n}" for n in expected_lines]:
            found.append(f"sources {sources}, the program's move lines {expected_lines}")
    assert not found, "\n".join(found[:8]) + f"\n{path}:\n{numbered(path.read_text())}"


# --------------------------------------------------------------------------- the reference itself


def test_reference_reads_rs274_conventions(tmp_path):
    """rs274ref on a program of known geometry: the planes' axes, the turn's sign, units, helices."""
    path = tmp_path / "known.ngc"
    path.write_text("G21 G90 G17\nG0 X10 Y0 Z1\nG3 X0 Y10 I-10 F600\nG18 G2 X-10 Z-9 K-10\n"
                    "G19 G3 Y0 Z1 J-10 K0\nG20 G1 X1\nG17 G2 X1 Y0 I1 Z-1\nM2\n")
    moves = rs274ref.read_moves(path)
    assert [m.kind for m in moves] == ["rapid", "arc", "arc", "arc", "line", "arc"]
    quarter, zx, yz, line, full = moves[1:]
    assert np.allclose(quarter.center, [0, 0, 1]) and np.allclose(quarter.normal, [0, 0, 1])
    assert quarter.sweep == pytest.approx(math.pi / 2) and quarter.feed == 600
    # G18: (first, second) = (Z, X); G2 turns clockwise about +Y: from (0, 10, 1) about (0, 10, -9)
    assert np.allclose(zx.end, [-10, 10, -9]) and np.allclose(zx.center, [0, 10, -9])
    assert np.allclose(zx.normal, [0, -1, 0]) and zx.sweep == pytest.approx(math.pi / 2)
    # G19: (first, second) = (Y, Z); G3 turns counter-clockwise about +X: from (-10, 10, -9) about (-10, 0, -9)
    assert np.allclose(yz.end, [-10, 0, 1]) and np.allclose(yz.center, [-10, 0, -9])
    assert np.allclose(yz.normal, [1, 0, 0]) and yz.sweep == pytest.approx(math.pi / 2)
    # G20: printed in inches (4 decimals: Z 1 mm is printed 0.0394 in), read in mm; the feed keeps its mm/min
    assert np.allclose(line.end, [25.4, 0, 1], rtol=0, atol=line.end_tol) and line.end_tol == pytest.approx(1.27e-3)
    assert line.feed == 600
    # a helical full circle, clockwise, of 1 in about (2 in, 0), down to Z-1 in
    assert full.is_full_circle and full.sweep == pytest.approx(2 * math.pi) and np.allclose(full.normal, [0, 0, -1])
    assert np.allclose(full.center, [50.8, 0, 1], rtol=0, atol=full.end_tol)
    assert full.rise == pytest.approx(25.4 + 1, abs=2 * full.end_tol)


# --------------------------------------------------------------------------- the comparisons


@pytest.fixture(scope="module")
def random_runs(tmp_path_factory):
    """Every random program written and run through rs274 once, as many at a time as there are cores."""
    folder = tmp_path_factory.mktemp("rs274")
    programs = {}
    for seed in EXACT_SEEDS:
        programs[("exact", seed)] = random_program(seed)
    for seed in CAM_SEEDS:
        programs[("cam", seed)] = random_program(seed, cam=True)
    paths = {}
    for (kind, seed), program in programs.items():
        paths[(kind, seed)] = folder / f"{kind}-{seed}.ngc"
        paths[(kind, seed)].write_text(program.text)
    keys = list(programs)
    results = rs274ref.read_many([paths[k] for k in keys])
    return {k: (paths[k], programs[k], r) for k, r in zip(keys, results)}


@pytest.mark.parametrize("seed", EXACT_SEEDS)
def test_random_program(seed, random_runs):
    path, program, moves = random_runs[("exact", seed)]
    check_program(path, moves, expected_lines=program.move_lines)


@pytest.mark.parametrize("seed", CAM_SEEDS)
def test_cam_precision_program(seed, random_runs):
    """4 decimals in mm, 5 in inches: arc ends off their circle by the rounding, as from CAM."""
    path, program, moves = random_runs[("cam", seed)]
    check_program(path, moves, expected_lines=program.move_lines, bisector=True)


def test_pocket_example():
    if not POCKET.exists():
        pytest.skip(f"{POCKET.name} is not written yet")
    check_program(POCKET, rs274ref.read_moves(POCKET))


def test_unit_switch_feed(tmp_path):
    """An F given in mm/min keeps its speed across G20 in LinuxCNC (the random programs restate F instead).

    rs274's dummy machine prints no new SET_FEED_RATE at a units switch; LinuxCNC converts the feed
    in effect ("feed rate ... converted by rereading [it] from the canon level"), so the physical speed
    stays.  Compared here without rs274's feed: the reader's must not change."""
    path = tmp_path / "feed.ngc"
    path.write_text("G21 G90\nG1 X10 F600\nG20\nG1 X1\nM2\n")
    moves = rs274ref.read_moves(path)
    spec, _ = read_gcode_job(str(path))
    assert [b.feedrate for b in spec.blocks] == [pytest.approx(10.0)] * 2, "feed changed at G20"
    assert not mismatches(spec, moves)


def test_feed_on_units_switch_line(tmp_path):
    """F is executed before G20/G21 on the same line: ``G20 G1 X1 F10`` after G21 feeds at 10 mm/min.

    rs274 prints SET_FEED_RATE(10) before USE_LENGTH_UNITS(CANON_UNITS_INCHES); LinuxCNC's canon
    converts a feed with the units in effect when it is set (emccanon's FROM_PROG_LEN)."""
    path = tmp_path / "feed-units.ngc"
    path.write_text("G21 G90\nG1 X10 F600\nG20 G1 X1 F10\nG21 G1 X10 F10\nM2\n")
    moves = rs274ref.read_moves(path)
    assert [m.feed for m in moves] == [600, 10, 254]  # mm/min: F10 read in mm, then F10 read in inches
    spec, _ = read_gcode_job(str(path))
    found = mismatches(spec, moves)
    assert not found, "\n".join(found)


# LinuxCNC's arc tolerances (interp_internal.hh): an I J K arc may end off its circle by up to
# 2·0.01·√2 mm (2·0.001·√2 in), or by more if within 0.1 % of the radius (up to 100 times that);
# an R arc may have |R| short of half the chord by up to 0.00127 mm (0.00005 in).  rs274 decides:
# the reader should accept exactly what it accepts.


@pytest.mark.parametrize("units, excess", [
    ("G21", 0.001), ("G21", 0.004), ("G21", 0.008), ("G21", 0.02), ("G21", 0.04),
    ("G20", 0.0001), ("G20", 0.0004), ("G20", 0.001), ("G20", 0.002), ("G20", 0.004),
])
def test_ijk_radius_tolerance(tmp_path, units, excess):
    """A quarter arc of radius 10 whose end is *excess* (program units) beyond its circle."""
    path = tmp_path / "ijk.ngc"
    path.write_text(f"{units} G90\nG0 X10 Y0\nG3 X0 Y{10 + excess:.6f} I-10 J0 F100\nM2\n")
    _agree_on_acceptance(path, bisector=True)


@pytest.mark.parametrize("units, short", [
    ("G21", 0.0005), ("G21", 0.001), ("G21", 0.002), ("G21", 0.004),
    ("G20", 0.00002), ("G20", 0.00004), ("G20", 0.0001), ("G20", 0.0004),
])
def test_r_radius_tolerance(tmp_path, units, short):
    """A half circle from (0, 0) to (10, 0) whose R is *short* (program units) of half the chord."""
    path = tmp_path / "r.ngc"
    path.write_text(f"{units} G90\nG2 X10 Y0 R{5 - short:.6f} F100\nM2\n")
    _agree_on_acceptance(path, bisector=True)


def _agree_on_acceptance(path: Path, *, bisector: bool) -> None:
    try:
        moves = rs274ref.read_moves(path)
    except rs274ref.Rs274Error as refusal:
        with pytest.raises(SpecError):
            read_gcode_job(str(path))
        assert refusal.message  # both refuse
        return
    try:
        spec, _ = read_gcode_job(str(path))
    except SpecError as exc:
        pytest.fail(f"rs274 accepts the program, the reader refuses it: {exc}\n{numbered(path.read_text())}")
    found = mismatches(spec, moves, bisector=bisector)
    assert not found, "\n".join(found) + "\n" + numbered(path.read_text())


def test_g5_2_nurbs(tmp_path):
    """G5.2 through rs274: it prints only NURBS_FEED(n, ...), the number of control points.

    So only that count, and where the curve ends (revealed by an incremental move after it), can be
    compared; degree, weights and knots do not reach rs274's output."""
    path = tmp_path / "nurbs.ngc"
    path.write_text("G21 G90 G17\nG0 X0 Y0\nG1 X5 F600\nG5.2 X5 Y10 P1 L4\nX15 Y10 P2\nX15 Y0 P0.5\n"
                    "X25 Y5 P1\nG5.3\nG91 G1 X1\nM2\n")
    moves = [m for m in rs274ref.read_moves(path) if not m.is_zero_length]
    assert [m.kind for m in moves] == ["line", "nurbs", "line"]
    spec, _ = read_gcode_job(str(path))
    assert [b.kind for b in spec.blocks] == ["line", "nurbs", "line"]
    nurbs = spec.blocks[1]
    assert len(nurbs.curve.control_points) == moves[1].count == 5
    after = moves[2].end - np.array([1.0, 0.0, 0.0])  # G91 X1 from where the curve ended
    assert not _far("NURBS end", _point3(nurbs.end, 0.0), after, moves[2].end_tol + SLACK)
    assert not _far("NURBS start", _point3(nurbs.start, 0.0), moves[0].end, moves[0].end_tol + SLACK)
    assert nurbs.curve.degree == 3
    assert list(nurbs.curve.weights) == [1, 1, 2, 0.5, 1]
    assert not mismatches(spec, moves)
