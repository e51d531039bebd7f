"""The machine's semantics against LinuxCNC's own interpreter (issue 28, items 3 and 4): seeded random
programs of offsets, stored positions, machine-coordinate moves, path-control modes, stops and dwells,
read by the reader and by ``rs274 -g``, compared move by move (opt-in: skipped without rs274).

Each program (written by :class:`MachineWriter` from its seed) mixes G0/G1 moves and G2/G3 arcs with
G20/G21, G90/G91, G17/G18/G19, G92 (some axes), G92.1, G92.2, G92.3, G52, G28 and G30 with and without
axis words in G90 and G91 (Fusion 360's ``G28 G91 Z0`` among them), G28.1/G30.1, G53 G0/G1 (absolute
mode only, as LinuxCNC requires), G61 / G61.1 / G64 [P] [Q] (program units), M0 M1 M60, ``T M6``,
``G4 P``, and the words that must not stop motion (S, M3 M4 M5, M7 M8 M9, T without M6).  Every feed
move has an F in effect before it (rs274 refuses a feed move without; G94 sets the feed to none in
LinuxCNC, so an F follows it before the next feed move).

The writer does not track where the tool is: it need not, since both readers work that out, and the
arcs are written in G91 from where the tool is (end and centre whole multiples of the radius, so that
they lie exactly on their circle whatever the offsets).  What it tracks is what LinuxCNC requires of
a program (units, distance mode, the motion mode in effect for G53, whether an F is in effect).
Numbers are written with 4 decimals in both units, the digits rs274 prints: a value at half a printed
step would make rs274 print a move that is none (see :func:`test_a_stored_position_at_half_a_step`).

The comparison is the corpus test's (``tests/test_corpus_cam.py``): geometry and feed move by move
with ``tests/test_rs274.py``'s bounds (rs274's printed digits: the offsets it prints are rounded like
the points), the block count (rs274's moves without the zero-length ones the reader drops: ``G28``
alone first goes to where the tool is), and the joints (path-control mode to the printed digits, the
stops M0 M1 M60 M6, and G4 with its dwell — a ``DWELL`` is a stop even of 0 s, as LinuxCNC's task
waits for motion to finish before any dwell: :func:`test_g4_p0_stops_without_dwelling`).
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import rs274ref

if rs274ref.RS274 is None:
    pytest.skip("rs274 not on PATH (Debian package linuxcnc-uspace)", allow_module_level=True)

from test_corpus_cam import geometry_mismatches, joint_mismatches, paired  # noqa: E402
from test_rs274 import numbered  # noqa: E402

from nurbsinterp.config.gcode import read_gcode  # noqa: E402

SEEDS = range(150)
#: plane -> (first axis, second axis, normal axis) letters and the centre-offset letters of the first two
PLANES = {"G17": ("XYZ", "IJ"), "G18": ("ZXY", "KI"), "G19": ("YZX", "JK")}
#: the unit vector at k quarter turns from the first axis, in (first, second)
QUARTERS = ((1, 0), (0, 1), (-1, 0), (0, -1))
SPINDLE = ("M3", "M4", "M5")
COOLANT = ("M7", "M8", "M9")
#: every feature a run of the random programs must hold (checked in test_the_programs_hold_every_feature)
FEATURES = {
    "G20": r"\bG20\b", "G21 after G20": None, "G91": r"\bG91\b", "G18": r"\bG18\b", "G19": r"\bG19\b",
    "G92": r"\bG92 [XYZ]", "G92.1": r"\bG92\.1\b", "G92.2": r"\bG92\.2\b", "G92.3": r"\bG92\.3\b",
    "G52": r"\bG52 [XYZ]", "G28 alone": r"^G28$", "G28 with axes": r"\bG28 [XYZ]",
    "G28 G91 Z0": r"\bG28 G91 Z0$", "G30 with axes": r"\bG30 (G91 )?[XYZ]", "G30 alone": r"^G30$",
    "G28.1": r"\bG28\.1\b", "G30.1": r"\bG30\.1\b", "G53 G0": r"\bG53 G0\b|\bG0 G53\b",
    "G53 G1": r"\bG53 G1\b", "G53 modal": r"^G53 [XYZ]", "G61": r"\bG61$", "G61.1": r"\bG61\.1\b",
    "G64": r"\bG64$", "G64 P": r"\bG64 P", "G64 P Q": r"\bG64 P\S+ Q", "G64 Q": r"\bG64 Q",
    "M0": r"\bM0\b", "M1": r"\bM1\b", "M60": r"\bM60\b", "T M6": r"\bT\d+ M6\b", "M6 alone": r"^M6$",
    "G4 P": r"\bG4 P", "S": r"\bS\d", "M3": r"\bM3\b", "M4": r"\bM4\b", "M5": r"\bM5\b", "M7": r"\bM7\b",
    "M8": r"\bM8\b", "M9": r"\bM9\b", "T alone": r"^T\d+$", "G94": r"\bG94\b", "arc": r"\bG[23] ",
}


# --------------------------------------------------------------------------- random programs


class MachineWriter:
    """Writes a random program that LinuxCNC accepts, tracking only what LinuxCNC requires of it."""

    def __init__(self, seed: int):
        self.rng = np.random.default_rng(seed)
        self.rows: list[str] = []
        self.inch = False
        self.absolute = True
        self.plane = "G17"
        self.motion: str | None = None  # the motion mode in effect (G53 moves only in G0 or G1)
        self.feed_ok = False  # an F in effect: rs274 refuses a feed move without
        self.tool_selected = False

    # ---- numbers

    #: 4 decimals in both units, as rs274 prints them: a written value is never half a printed step, where
    #: a stored position's round trip (G28.1 then G28: program units to mm and back, ~1e-16 off) would
    #: print one step away from where the tool is, a move of 0.1 um (2.5 um in inches) that is none
    decimals = 4

    def steps(self, mm: float) -> int:
        """*mm* in whole steps of the last written decimal, in program units."""
        return int(round(mm / (25.4 if self.inch else 1.0) * 10 ** self.decimals))

    def fixed(self, steps: int) -> str:
        """A whole number of steps as written: exact, so that 2·r is twice r to the last digit."""
        sign = "-" if steps < 0 else ""
        whole, part = divmod(abs(steps), 10 ** self.decimals)
        text = f"{whole}.{part:0{self.decimals}d}".rstrip("0").rstrip(".")
        return sign + text

    def length(self, low_mm: float, high_mm: float) -> str:
        return self.fixed(self.steps(self.rng.uniform(low_mm, high_mm)))

    def axes(self, letters: str = "XYZ", low: float = -100.0, high: float = 100.0) -> list[str]:
        """One to three axis words of random values (mm bounds, written in program units)."""
        chosen = [c for c in letters if self.rng.random() < 0.5] or [str(self.rng.choice(list(letters)))]
        return [c + self.length(low, high) if c != "Z" else c + self.length(low / 3, high / 3) for c in chosen]

    def feed(self) -> str:
        self.feed_ok = True
        return f"F{int(self.rng.integers(30, 3000)) if not self.inch else int(self.rng.integers(2, 120))}"

    # ---- lines

    def write(self, *words: str) -> None:
        self.rows.append(" ".join(w for w in words if w))

    def extras(self, dwell: bool = True) -> list[str]:
        """Words for a motion line that must not stop it, now and then a stop or a dwell (not on an arc's
        line: its P would be the arc's turns too)."""
        rng = self.rng
        words = []
        if rng.random() < 0.15:
            words.append(str(rng.choice(SPINDLE)))
        if rng.random() < 0.15:
            words.append(str(rng.choice(COOLANT)))
        if rng.random() < 0.1:
            words.append(f"S{int(rng.integers(100, 24000))}")
        roll = rng.random()
        if roll < 0.05:
            words.append(str(rng.choice(["M0", "M1", "M60"])))  # after the line's motion
        elif roll < 0.08:
            words += [f"T{int(rng.integers(1, 20))}", "M6"]  # before it
            self.tool_selected = True
        elif roll < 0.11 and dwell:
            words.insert(0, f"G4 P{rng.uniform(0.05, 3):.2f}")  # before it
        elif roll < 0.14:
            words.append(f"T{int(rng.integers(1, 20))}")
            self.tool_selected = True
        return words

    def line_modes(self) -> list[str]:
        """Now and then a units switch or a path-control mode on a motion's line: it applies to that motion
        (an F on the line is read in the units before the switch, as LinuxCNC orders a line's actions)."""
        rng = self.rng
        roll = rng.random()
        if roll < 0.05:
            self.inch = not self.inch
            return ["G20" if self.inch else "G21"]
        if roll < 0.1:
            return [str(rng.choice(["G61", "G61.1", "G64"]))]
        return []

    def straight(self) -> None:
        rng = self.rng
        motion = str(rng.choice(["G0", "G1"], p=[0.35, 0.65]))
        words = self.line_modes()
        words += [motion] if motion != self.motion or words or rng.random() < 0.6 else []
        self.motion = motion
        words += self.axes(low=-100 if self.absolute else -30, high=100 if self.absolute else 30)
        if motion == "G1" and (not self.feed_ok or rng.random() < 0.15):
            words.append(self.feed())
        self.write(*words, *self.extras())

    def arc(self) -> None:
        """A quarter, half, three-quarter or full circle (maybe a helix) from where the tool is, in G91."""
        rng = self.rng
        (first, second, normal), (i_first, i_second) = PLANES[self.plane]
        r = self.steps(rng.uniform(1.0, 40.0))
        k0 = int(rng.integers(4))
        quarters = int(rng.integers(1, 5))
        ccw = bool(rng.random() < 0.5)
        k1 = (k0 + quarters if ccw else k0 - quarters) % 4
        u0, u1 = QUARTERS[k0], QUARTERS[k1]
        motion = "G3" if ccw else "G2"
        words = ["G91"] if self.absolute else []
        words.append(motion)
        self.motion = motion
        d_first, d_second = (u1[0] - u0[0]) * r, (u1[1] - u0[1]) * r
        if quarters < 4 or rng.random() < 0.5:  # a full circle may leave out its (zero) end words
            words += [first + self.fixed(d_first), second + self.fixed(d_second)]
        if rng.random() < 0.25:
            words.append(normal + self.length(-5, 5))
        for letter, value in ((i_first, -u0[0] * r), (i_second, -u0[1] * r)):
            if value != 0 or rng.random() < 0.5:
                words.append(letter + self.fixed(value))
        if not self.feed_ok or rng.random() < 0.15:
            words.append(self.feed())
        self.write(*words, *self.extras(dwell=False))
        if self.absolute:
            self.write("G90")

    def home(self) -> None:
        """G28 or G30: alone, with axis words in the mode in effect, or Fusion 360's ``G28 G91 Z0``."""
        rng = self.rng
        code = str(rng.choice(["G28", "G30"]))
        form = rng.random()
        if form < 0.2:
            self.write(code, *self.extras(dwell=False))
        elif form < 0.45:  # Fusion's retract and its kin: incremental zero, the intermediate point is here
            self.absolute = False
            self.write(code, "G91", *[c + "0" for c in (["Z"] if rng.random() < 0.6 else ["X", "Y"])])
            if rng.random() < 0.7:
                self.absolute = True
                self.write("G90")
        else:
            low, high = (-100, 100) if self.absolute else (-20, 20)
            self.write(code, *self.axes(low=low, high=high), *self.extras(dwell=False))

    def store_home(self) -> None:
        self.write(str(self.rng.choice(["G28.1", "G30.1"])))

    def machine_move(self) -> None:
        """G53 with G0 or G1 (or the one in effect): absolute mode only."""
        rng = self.rng
        if not self.absolute:
            self.absolute = True
            self.write("G90")
        roll = rng.random()
        if roll < 0.25 and self.motion in ("G0", "G1"):
            words = ["G53"]
            motion = self.motion
        else:
            motion = str(rng.choice(["G0", "G1"], p=[0.7, 0.3]))
            words = ["G53", motion] if roll < 0.7 else [motion, "G53"]
        self.motion = motion
        words += self.axes(low=-100, high=100)
        if motion == "G1" and not self.feed_ok:
            words.append(self.feed())
        self.write(*words, *self.extras(dwell=False))

    def offset(self) -> None:
        rng = self.rng
        roll = rng.random()
        if roll < 0.4:
            self.write("G92", *self.axes(low=-50, high=50))
        elif roll < 0.55:
            self.write("G52", *self.axes(low=-30, high=30))
        elif roll < 0.7:  # suspended and restored around a move: the restore reads #5211.. (mm) back
            self.write("G92.2")
            self.straight()
            self.write("G92.3")
        else:
            self.write(str(rng.choice(["G92.1", "G92.2", "G92.3"])))

    def control_mode(self) -> None:
        rng = self.rng
        roll = rng.random()
        if roll < 0.15:
            self.write("G61")
        elif roll < 0.3:
            self.write("G61.1")
        elif roll < 0.4:
            self.write("G64")
        else:
            p = self.length(0.001, 0.5)
            q = self.length(0.001, 0.1)
            form = rng.random()
            if form < 0.4:
                self.write("G64", "P" + p)
            elif form < 0.7:
                self.write("G64", "P" + p, "Q" + q)
            elif form < 0.9:
                self.write("G64", "Q" + q)
            else:
                self.write("G64", "P0")

    def standalone(self) -> None:
        """A line of its own: a stop, a dwell, a tool change, or words that must not stop."""
        rng = self.rng
        roll = rng.random()
        if roll < 0.12:
            self.write("M0")
        elif roll < 0.24:
            self.write("M1")
        elif roll < 0.34:
            self.write("M60")
        elif roll < 0.46:
            self.tool_selected = True
            self.write(f"T{int(rng.integers(1, 20))}", "M6")
        elif roll < 0.52 and self.tool_selected:
            self.write("M6")
        elif roll < 0.64:
            self.write(f"G4 P{rng.uniform(0.05, 3):.3f}")
        elif roll < 0.76:
            self.tool_selected = True
            self.write(f"T{int(rng.integers(1, 20))}")
        elif roll < 0.88:
            self.write(f"S{int(rng.integers(100, 24000))}", str(rng.choice(SPINDLE)))
        else:
            self.write(str(rng.choice(COOLANT)))

    def modes(self) -> None:
        rng = self.rng
        roll = rng.random()
        if roll < 0.35:
            self.inch = not self.inch
            self.write("G20" if self.inch else "G21")
        elif roll < 0.6:
            self.absolute = not self.absolute
            self.write("G90" if self.absolute else "G91")
        elif roll < 0.85:
            self.plane = str(rng.choice([p for p in PLANES if p != self.plane]))
            self.write(self.plane)
        else:  # LinuxCNC's G94 sets the feed to none: an F with it, or before the next feed move
            self.feed_ok = False
            self.write("G94", self.feed() if rng.random() < 0.5 else "")

    def program(self) -> str:
        rng = self.rng
        if rng.random() < 0.7:
            self.inch = bool(rng.random() < 0.35)
            self.write("G20" if self.inch else "G21", "G90", "G17")
        if rng.random() < 0.3:  # a Fusion 360 post's start
            self.write("G28", "G91", "Z0")
            self.write("G90")
        actions = [self.straight, self.arc, self.home, self.store_home, self.machine_move, self.offset,
                   self.control_mode, self.standalone, self.modes]
        weights = np.array([0.3, 0.15, 0.09, 0.04, 0.07, 0.09, 0.07, 0.1, 0.09])
        for _ in range(int(rng.integers(25, 45))):
            actions[int(rng.choice(len(actions), p=weights / weights.sum()))]()
        self.write(str(rng.choice(["M2", "M30"])))
        return "\n".join(self.rows) + "\n"


def random_machine_program(seed: int) -> str:
    """Seeded: the same seed writes the same program."""
    return MachineWriter(seed).program()


# --------------------------------------------------------------------------- comparison


def differences(path: Path, moves) -> list[str]:
    """Every difference between the reader's blocks and rs274's moves: geometry and feed, count, joints."""
    spec = read_gcode(str(path))
    pairs, left = paired(spec.blocks, moves)
    found = geometry_mismatches(spec, moves)
    if len(spec.blocks) != len(pairs) or left:
        found.append(f"the reader made {len(spec.blocks)} blocks, rs274 {len(pairs) + len(left)} moves "
                     "(zero-length ones left out)")
    for k, (block, move) in enumerate(pairs):
        for problem in joint_mismatches(block, move):
            found.append(f"move {k} ({block.source}; rs274 output line {move.index}): {problem}")
    return found


def check(path: Path, moves) -> None:
    if isinstance(moves, Exception):
        pytest.fail(f"rs274 refused the program (the test's own writer is wrong):\n{moves}\n"
                    f"{numbered(path.read_text())}")
    found = differences(path, moves)
    assert not found, "\n".join(found[:8]) + f"\n{path}:\n{numbered(path.read_text())}"


@pytest.fixture(scope="module")
def machine_runs(tmp_path_factory):
    """Every random program written and run through rs274 once, as many at a time as there are cores."""
    return rs274ref.read_seeded(tmp_path_factory.mktemp("rs274-machine"), "machine", SEEDS, random_machine_program)


@pytest.mark.parametrize("seed", SEEDS)
def test_random_machine_program(seed, machine_runs):
    path, moves = machine_runs[seed]
    check(path, moves)


def test_the_programs_hold_every_feature(machine_runs):
    """The writer's mix: each feature in several programs, and rs274 printing each kind of joint."""
    texts = [path.read_text() for path, _moves in machine_runs.values()]
    missing = []
    for feature, pattern in FEATURES.items():
        if pattern is None:  # G21 after a G20: a switch back
            count = sum(bool(re.search(r"\bG20\b[\s\S]*\bG21\b", text)) for text in texts)
        else:
            count = sum(bool(re.search(pattern, text, re.MULTILINE)) for text in texts)
        if count < 5:
            missing.append(f"{feature}: in {count} programs")
    assert not missing, missing
    moves = [m for _path, result in machine_runs.values() if isinstance(result, list) for m in result]
    assert {s for m in moves for s in m.stops} == {"M0", "M1", "M60", "M6", "G4"}
    assert sum(m.dwell > 0 for m in moves) > 20
    assert {m.mode.control for m in moves} == {"blend", "exact_path", "exact_stop"}
    assert any(m.mode.tolerance is None and m.mode.naive_tolerance is not None for m in moves)  # G64 Q alone
    assert sum(m.is_zero_length for m in moves) > 20  # G28 alone, G28 G91 Z0: first legs that go nowhere


def test_the_writer_is_seeded():
    assert random_machine_program(7) == random_machine_program(7)
    assert random_machine_program(7) != random_machine_program(8)


# --------------------------------------------------------------------------- hand-written edges


def _agree(tmp_path, text: str) -> tuple:
    """rs274's moves of *text* and the reader's path, which must agree in every aspect."""
    path = tmp_path / "edge.ngc"
    path.write_text(text)
    moves = rs274ref.read_moves(path)
    check(path, moves)
    return moves, read_gcode(str(path))


def test_g28_in_inches_with_a_g92_offset(tmp_path):
    """The intermediate point is in the program's frame (inches, G92 applied); the stored position is machine mm."""
    moves, _spec = _agree(tmp_path, "G21 G90\nG0 X10 Y5 Z2\nG92 X1 Y1\nG20\nG28 X0.5 Z1\nG1 X1 F10\nG28\nM2\n")
    via, home = moves[1], moves[2]
    assert np.allclose(via.end, [9 + 12.7, 5, 25.4], atol=via.end_tol)  # G92 X: 10 mm - 1 in
    assert np.allclose(home.end, [0, 5, 0], atol=home.end_tol)  # only X and Z go home
    assert np.allclose(moves[-1].end, [0, 0, 0], atol=moves[-1].end_tol)


def test_g30_after_g30_1_in_g91(tmp_path):
    """G30.1 stores where the tool is; ``G30 X1 Z0`` in G91 goes 1 along X, then X and Z to the stored point."""
    moves, _spec = _agree(tmp_path, "G21\nG0 X10 Y20 Z5\nG30.1\nG0 X0 Y0 Z0\nG91\nG30 X1 Z0\nG90\nG0 Y3\nG30\n"
                                    "M2\n")
    assert np.allclose(moves[2].end, [1, 0, 0]) and np.allclose(moves[3].end, [10, 0, 5])
    assert np.allclose(moves[-1].end, [10, 20, 5])


def test_g53_right_after_g92(tmp_path):
    """G53 is machine coordinates whatever the G92 offset just set (rs274 prints them minus the offset)."""
    moves, _spec = _agree(tmp_path, "G21 G90\nG0 X10 Y5 Z3\nG92 X0 Y0\nG53 G0 X5\nG1 X1 F100\nG53 G1 Z-1\n"
                                    "G92 Z7\nG53 X1 Y1 Z1\nG1 Z0\nM2\n")
    # G92 Z7 at machine Z-1 makes the offset -8: the program's Z0 is machine Z-8
    assert np.allclose([m.end for m in moves[1:]], [[5, 5, 3], [11, 5, 3], [11, 5, -1], [1, 1, 1], [1, 1, -8]])


def test_g92_3_after_g92_2(tmp_path):
    """G92.2 clears the offset but keeps its parameters; G92.3 brings it back, also across a units switch."""
    moves, _spec = _agree(tmp_path, "G21 G90\nG0 X10 Y4\nG92 X0 Y0\nG92.2\nG0 X5\nG92.3\nG0 X1\nG20\nG92.2\n"
                                    "G0 X1\nG92.3\nG0 X1\nG21\nG92.1\nG92.3\nG0 X1\nM2\n")
    assert np.allclose([m.end[0] for m in moves[1:]], [5, 11, 25.4, 35.4, 1], atol=2e-3)


def test_g64_q_alone(tmp_path):
    """``G64 Q`` without P: no blend tolerance, the naive-CAM tolerance as given (in inches too)."""
    moves, spec = _agree(tmp_path, "G21\nG64 Q0.02\nG1 X1 F100\nG20\nG64 Q0.001\nG1 X1\nG64 P0.002\nG1 X2\nM2\n")
    assert [(b.mode.tolerance, b.mode.naive_tolerance) for b in spec.blocks] == [
        (None, pytest.approx(0.02)), (None, pytest.approx(0.0254)), (pytest.approx(0.0508), pytest.approx(0.0508))]
    assert moves[0].mode.tolerance is None and moves[0].mode.naive_tolerance == pytest.approx(0.02)


def test_g4_p0_stops_without_dwelling(tmp_path):
    """rs274 prints ``DWELL(0.0000)`` for G4 P0: motion comes to rest (LinuxCNC's task waits for it before a
    dwell) for no time.  The reader marks the joint a G4 stop of 0 s, and the joint comparison agrees."""
    path = tmp_path / "g4p0.ngc"
    path.write_text("G21\nG1 X1 F100\nG4 P0\nG1 X2\nM2\n")
    output = rs274ref.run_rs274(path)
    calls = [line.split(maxsplit=2)[2] for line in output.splitlines() if "(" in line]
    at = calls.index("DWELL(0.0000)")
    assert calls[at - 1].startswith("STRAIGHT_FEED(1.0000") and calls[at + 1].startswith("STRAIGHT_FEED(2.0000")
    spec = read_gcode(str(path))
    assert spec.blocks[1].dwell == 0 and spec.blocks[1].stop == "G4 P0 at line 3"
    _agree(tmp_path, "G21\nG1 X1 F100\nG4 P0\nG1 X2\nM2\n")


def test_the_first_leg_after_an_offset_change_goes_nowhere(tmp_path):
    """``G28`` alone in G91 first goes to where the tool is: rs274 prints that point in the new G92 frame,
    whose sum with the printed offset may differ from the previous point in the last bit.  It is still a
    move of no length (rs274ref compares such points within their roundings), and the reader drops it."""
    moves, spec = _agree(tmp_path, "G91 G2 X0 Y0 Z0.1643 I0 J0.9384 F115\nG1 Y0.3394\nG92.2\n"
                                   "G91 G3 X0 Y0 I0 J1.4181\nG92 X-0.8863 Y1.5119\nG28\nM2\n")
    assert moves[3].is_zero_length and not moves[3].same_frame
    assert len(spec.blocks) == len(moves) - 1


def test_a_stored_position_at_half_a_step(tmp_path):
    """rs274 prints a move of one step where the tool goes nowhere: G30.1 stores the point in mm and G30
    converts it back, ~1e-16 off, and Z 0.60755 (half a printed step) then prints 0.6075, not 0.6076.
    Not a difference of the reader (whose G30 goes nowhere, and is dropped); the random programs write 4
    decimals, so that none of their values lies at half a step."""
    path = tmp_path / "half.ngc"
    path.write_text("G1 X2.35171 F36\nG92 Y-0.88677 Z-0.57058\nG1 Y0.82904 Z0.60755\nG30.1\nG30 G91 Z0\nM2\n")
    moves = rs274ref.read_moves(path)
    assert [m.is_zero_length for m in moves] == [False, False, True, False]
    assert abs(moves[3].end[2] - moves[3].start[2]) == pytest.approx(1e-4)
    spec = read_gcode(str(path))
    # G92 Y-0.88677 at Y0 is an offset of +0.88677: the program's Y0.82904 is machine Y1.71581
    assert len(spec.blocks) == 2 and np.allclose(spec.blocks[-1].end, [2.35171, 1.71581, 1.17813])
