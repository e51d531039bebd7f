"""The fast path for plain CAM lines (config/gcode/fast.py) against the general reader and Python's float().

The references are independent of the code under test: numbers against ``float()`` (correctly rounded by
CPython's own dtoa) and against the exact decimal value (``fractions.Fraction``) to decide which numbers the
exact fast path must take; lines against the general reader's ``parse_line``; whole programs against
``read_gcode``, bit for bit (every coordinate and feedrate compared as the bytes of its double, signed zeros
included), with the same notes and the same one-line error.
"""
from __future__ import annotations

import re
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from budgets import budgets

from nurbsinterp.config.gcode import _read_text, read_gcode
from nurbsinterp.config.gcode.fast import StraightState, scan, straight_run
from nurbsinterp.config.gcode.words import program_lines
from nurbsinterp.config.gcode.program import Context
from nurbsinterp.config.gcode.words import parse_line
from nurbsinterp.errors import SpecError

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus"
MB31 = CORPUS / "cam_Sienci-Labs_gsender" / "MB-3.1_test.nc"
EXACT = 2 ** 53


def bits(a) -> bytes:
    return np.asarray(a, dtype=float).tobytes()


# --- numbers ------------------------------------------------------------------------------------------------------

def fast_path_takes(s: str) -> bool:
    """Whether the exact fast path applies: the digits, trailing zeros dropped, M < 2**53, |exponent| <= 22."""
    sign, digits, exponent = Decimal(s.replace(" ", "")).as_tuple()
    digits = "".join(map(str, digits)).lstrip("0")
    if not digits:
        return True  # zero
    stripped = digits.rstrip("0")
    exponent += len(digits) - len(stripped)
    return int(stripped) < EXACT and abs(exponent) <= 22


def scanned_number(s: str):
    table = scan(f"X{s}")
    return bool(table.plain[0]), table.words[0, 0]


@st.composite
def decimals(draw):
    """Numbers as LinuxCNC writes them: [+-]digits[.[digits]] or [+-].digits, up to 25 digits on a side."""
    sign = draw(st.sampled_from(["", "+", "-"]))
    whole = draw(st.text("0123456789", max_size=25))
    point = draw(st.booleans())
    fraction = draw(st.text("0123456789", max_size=25)) if point else ""
    if not whole and not fraction:
        whole = draw(st.text("0123456789", min_size=1, max_size=3))
    return sign + whole + ("." if point else "") + fraction


@budgets(quick=300, full=3000)
def test_numbers_are_float_exactly_or_left_to_the_general_reader(budget):
    @settings(max_examples=budget)
    @given(s=decimals())
    @example("0.1")
    @example("-0")
    @example("-0.000")
    @example("9007199254740991")  # 2**53 - 1: the largest exact mantissa
    @example("9007199254740993")  # 2**53 + 1: 16 digits, must fall back
    @example("0.30000000000000004")  # 17 digits
    @example("1234567890123456.7")  # 17 digits
    @example("1e22".replace("1e22", "1" + "0" * 22))  # 10**22: exact by the power alone
    @example("1" + "0" * 23)
    @example("0." + "0" * 21 + "1")  # 1e-22
    @example("0." + "0" * 22 + "1")  # 1e-23: falls back
    @example("100.50000000000000000000")  # trailing zeros do not count
    @example("5.")
    @example(".5")
    def check(s):
        plain, value = scanned_number(s)
        assert plain == fast_path_takes(s), s
        if plain:
            assert bits(value) == bits(float(s)), (s, value, float(s))

    check()


@budgets(quick=100, full=500)
def test_spaces_and_tabs_inside_numbers_are_dropped(budget):
    @settings(max_examples=budget)
    @given(s=decimals(), data=st.data())
    def check(s, data):
        spaced = "".join(c + data.draw(st.sampled_from(["", "", " ", "\t", "  "])) for c in s)
        plain, value = scanned_number(" " + spaced)
        assert plain == fast_path_takes(s)
        if plain:
            assert bits(value) == bits(float(s))

    check()


@pytest.mark.parametrize("text", ["X", "X.", "X+", "X-.", "X+-1", "X1.2.3", "X1e5", "X0x10", "X#1", "X[1]",
                                  "X1(c", "X1((c))", "X1(c(d)", "X(c)", "X١"])
def test_what_is_not_a_number_here_is_not_plain(text):
    assert not scan(text).plain[0]


# --- lines --------------------------------------------------------------------------------------------------------

WORDS = ["G0", "G00", "G1", "G01", "g1", "G1.0", "G-0", "G+1", "G2", "G1.5", "G90", "G20", "X1.5", "x-2", "Y.25",
         "y3.", "Z-0", "Z0.000", "F600", "f0", "F-5", "F12.5", "M3", "S1000", "T1", "(note)", ";end", "#1=2", "X#1",
         "N10", "n20.5", "/", "%", "O100", "X12345678901234567", "X1 0 . 5", "Y 2", "A1", "I1", "\x0c", "(a)",
         "(", ")", "(x(y)", "(1.5)", "(;)", "; (", "X1(c)2"]


@st.composite
def cam_lines(draw):
    parts = draw(st.lists(st.sampled_from(WORDS), max_size=5))
    separators = [draw(st.sampled_from(["", " ", "\t", "  "])) for _ in range(len(parts) + 1)]
    return separators[0] + "".join(p + s for p, s in zip(parts, separators[1:]))


@budgets(quick=200, full=2000)
def test_a_line_is_plain_exactly_when_the_general_reader_reads_it_as_plain(budget):
    """Plain: parse_line reads it (no error) as at most one G of 0 or 1 and only X Y Z F (F > 0), its numbers
    within the fast path; and then the values are parse_line's, bit for bit."""
    @settings(max_examples=budget)
    @given(raw=cam_lines())
    @example("G1 X1 X2")
    @example("N10 N20")
    @example("G0 G1 X1")
    @example("X1 N10")
    def check(raw):
        table = scan(raw)
        assert len(table) == max(1, len(program_lines(raw))) or raw == ""
        if raw == "" or len(program_lines(raw)) != 1:
            return
        try:
            line = parse_line(Context("p.ngc"), raw, 1)
        except SpecError:
            assert not table.plain[0], raw
            return
        stripped = raw.strip()
        uncommented = re.sub(r"\(.*?\)|;.*", "", raw)  # the comments dropped, as both readers drop them
        # the scanner's blanks are LinuxCNC's (space and tab); other whitespace the general reader drops it leaves to it
        other_space = {c for c in uncommented if c.isspace()} - {" ", "\t"}
        general_plain = (not stripped.startswith(("/", "%")) and not set("#[") & set(uncommented)
                         and not other_space and
                         (line is None or (len(line.g) <= 1 and set(line.g) <= {0, 10} and not line.m
                                           and not line.assignments and set(line.words) <= set("XYZF")
                                           and line.words.get("F", 1.0) > 0)))
        if general_plain and line is not None:
            numbers = re.findall(r"[+-]?(?:\d+\.?\d*|\.\d+)", "".join(uncommented.split()).upper())
            general_plain = all(fast_path_takes(n) for n in numbers)
        assert bool(table.plain[0]) == general_plain, raw
        if general_plain:
            assert bool(table.blank[0]) == (line is None), raw
            if line is not None:
                assert table.motion[0] == (line.g[0] if line.g else -1)
                for k, letter in enumerate("XYZF"):
                    if letter in line.words:
                        assert bits(table.words[0, k]) == bits(line.words[letter]), (raw, letter)
                    else:
                        assert np.isnan(table.words[0, k])

    check()


@budgets(quick=100, full=1000)
def test_lines_are_split_as_linuxcnc_splits_them(budget):
    """At \\n only, a \\r before it left out (fgets), as the general reader's program_lines splits them."""
    @settings(max_examples=budget)
    @given(text=st.text(st.sampled_from(list("G1X2 \n\r\x0b\x0c\x1c\x1d\x1e\x1f\x85\u2028\u2029é;")), max_size=40))
    def check(text):
        lines = program_lines(text)
        assert lines == [line.removesuffix("\r") for line in text.split("\n")][:len(lines)]
        for source in (text, text.encode("utf-8")):
            table = scan(source)
            assert len(table) == len(lines)
            for k, raw in enumerate(lines):
                if table.plain[k]:
                    assert set(raw.split(";")[0]) <= set("G1X2 "), (raw, k)  # after a ';', a comment

    check()


def test_latin1_bytes_are_read_as_the_reader_decodes_them():
    data = b"G1 X1 (wait\x85 here)\n(caf\xe9)\r\nG1 X3\n"  # not UTF-8: Latin-1; 0x85 is no line break
    text = data.decode("latin-1")
    table = scan(data)
    assert len(table) == len(program_lines(text)) == 3
    assert table.plain.tolist() == [True, True, True]  # the comment line: plain, blank
    assert table.blank.tolist() == [False, True, False]
    assert table.words[:, 0].tolist()[::2] == [1.0, 3.0]


# --- runs ---------------------------------------------------------------------------------------------------------

def start_state(**kwargs):
    values = dict(position=np.zeros(3), absolute=True, scale=1.0, motion=None, feedrate=None)
    values.update(kwargs)
    return StraightState(**values)


def test_a_run_by_hand():
    table = scan("G0 X1 Y2 Z3\nG1 X4 F600\nF1200\nY6\nG1\nX4 Y6\nZ3.0\n")
    m = straight_run(table, 0, len(table), start_state())
    assert m.next == 7 and m.beyond == -1 and m.dropped == 3  # a G1 alone, X4 Y6 and Z3.0 go nowhere
    assert m.end.tolist() == [[1, 2, 3], [4, 2, 3], [4, 6, 3]]
    assert bits(m.feedrate) == bits([np.nan, 10.0, 20.0])
    assert m.rapid.tolist() == [True, False, False]
    assert m.line.tolist() == [1, 2, 4]
    assert m.state.motion == 10 and m.state.feedrate == 20.0 and m.state.position.tolist() == [4, 6, 3]


def test_incremental_inch_moves_add_in_the_general_readers_order():
    table = scan("G1 X0.1 F10\nX0.1\nX0.1 Y-0.2\n")
    m = straight_run(table, 0, 3, start_state(absolute=False, scale=25.4, motion=0))
    x = 0.0
    for k in range(3):
        x = x + 0.1 * 25.4
        assert bits(m.end[k, 0]) == bits(x)
    assert bits(m.feedrate) == bits([10 * 25.4 / 60.0] * 3)


@pytest.mark.parametrize("motion", [None, 20, 30, 52])
def test_coordinates_without_g0_or_g1_in_effect_end_the_run_there(motion):
    table = scan("F100\nG1 X1\n")
    m = straight_run(table, 0, 2, start_state(motion=motion))
    assert m.next == 2 and m.state.motion == 10
    table = scan("F100\nX1\nG1 X2\n")
    m = straight_run(table, 0, 3, start_state(motion=motion))
    assert m.next == 1 and len(m) == 0 and m.state.motion == motion and m.state.feedrate == 100 / 60


def test_a_move_near_min_block_length_and_a_coordinate_beyond_range_are_left_to_the_general_reader():
    table = scan("G1 X1 F60\nX1.0000000000005\nX2\n")
    m = straight_run(table, 0, 3, start_state())
    assert (m.next, m.beyond, len(m)) == (1, -1, 1)
    table = scan("G1 X1 F60\nX2000000000000\nX2\n")
    m = straight_run(table, 0, 3, start_state())
    assert (m.next, m.beyond, len(m)) == (1, 1, 1)


def test_a_run_must_be_plain_lines():
    table = scan("G1 X1\nM3\n")
    with pytest.raises(ValueError, match="not all plain"):
        straight_run(table, 0, 2, start_state())


# --- whole programs: read_gcode with the fast path against read_gcode without it ------------------------------

def assert_same_path(fast, general):
    assert fast.dim == general.dim and fast.notes == general.notes
    assert len(fast.blocks) == len(general.blocks)
    for a, b in zip(fast.blocks, general.blocks):
        assert (a.kind, a.source, a.rapid) == (b.kind, b.source, b.rapid)
        assert bits(a.start) == bits(b.start) and bits(a.end) == bits(b.end), a.source
        assert (a.feedrate is None) == (b.feedrate is None), a.source
        if a.feedrate is not None:
            assert bits(a.feedrate) == bits(b.feedrate), a.source


def same_as_read_gcode(path: Path) -> int:
    """read_gcode with the fast path equals read_gcode without it (every line by the general reader): the
    same blocks bit for bit, the same notes, or the same error."""
    name = str(path)
    try:
        general = read_gcode(name, fast=False)
    except SpecError as exc:
        with pytest.raises(SpecError) as info:
            read_gcode(name)
            raise AssertionError("the fast path read what the general reader refuses")
        assert str(info.value) == str(exc)
        return 0
    assert_same_path(read_gcode(name), general)
    return len(general.blocks)


def number(rng, small=False) -> str:
    """A number as CAM writes it, now and then with spaces inside, a sign of zero or 17 digits."""
    kind = rng.integers(6)
    if small:
        s = f"{rng.uniform(-0.5, 0.5):.5f}"
    elif kind == 0:
        s = str(rng.integers(-200, 200)) + ("." if rng.random() < 0.2 else "")
    elif kind == 1:
        s = f"{rng.uniform(-150, 150):.{rng.integers(1, 7)}f}"
    elif kind == 2:
        s = f"{rng.uniform(-1, 1):.4f}".replace("0.", ".")
    elif kind == 3:
        s = str(rng.choice(["0", "-0", "0.0", "-0.000", "+0", "0."]))
    elif kind == 4:
        s = f"{rng.uniform(-150, 150):.15f}"  # beyond the fast path (17+ digits): the general reader's
    else:
        s = f"{rng.uniform(-5, 5):.4f}"
    if rng.random() < 0.05:
        k = int(rng.integers(len(s) + 1))
        s = s[:k] + rng.choice([" ", "\t"]) + s[k:]
    return s


#: general lines between the runs: modes, ignored words, comments, an arc (G2 stays the modal motion after it)
GENERAL = ["G20", "G21", "G90", "G91", "M3 S1000", "(comment)", "G0 X1 Y1 (go)", "/G1 X50", "G2 I1 J0", "G17",
           "#1=5", "G1 X#1", "G4 P0.5", "G61", "G64 P0.01", "N5 G1 X1 M8", "S2000"]


def random_program(seed: int) -> str:
    """A seeded CAM-like program: runs of plain lines between general lines that change the modes."""
    rng = np.random.default_rng(seed)
    lines = ["%"] if rng.random() < 0.3 else []
    lines += [str(rng.choice(["G21", "G20", "g21 g90", "(a program)"])), str(rng.choice(["G90", "G91", "G90 G94"])),
              "#1=2.5"]
    incremental = "G91" in lines[-2]
    for run in range(rng.integers(3, 12)):
        for k in range(rng.integers(1, 40)):  # a run of plain lines
            words = []
            if rng.random() < 0.1:
                words.append(f"N{rng.integers(1, 9999)}")
            if (run == 0 and k == 0) or rng.random() < 0.5:
                words.append(str(rng.choice(["G0", "G1", "G00", "G01", "g1", "g0"])))
            for axis in "XYZ":
                if rng.random() < 0.5:
                    words.append(axis + number(rng, small=incremental))
            if rng.random() < 0.15:
                words.append(f"F{rng.integers(1, 3000)}" + str(rng.choice(["", ".5", "."])))
            if k > 0 and rng.random() < 0.1:
                lines.append(lines[-1])  # a zero-length move when it repeats absolute coordinates
            if rng.random() < 0.05:
                words = []  # a blank line
            text = str(rng.choice(["", " ", "\t"])).join(words)
            lines.append(text.lower() if rng.random() < 0.2 else text)
        general = str(rng.choice(GENERAL))
        incremental = (general == "G91") or (incremental and general != "G90")
        lines.append(general)
        if general == "G2 I1 J0":  # arc mode: a plain F line, then back to straight moves
            lines += ["F200", "G1"]
    if rng.random() < 0.2:
        lines.append("%" if lines[0] == "%" else "M30")
        lines.append("G1 X999")  # after the end: never read
    elif lines[0] == "%":
        lines.append("%")
    eol = str(rng.choice(["\n", "\r\n"]))
    return eol.join(lines) + (eol if rng.random() < 0.8 else "")


@pytest.mark.parametrize("seed", range(60))
def test_random_cam_programs_read_as_the_general_reader_reads_them(tmp_path, seed):
    path = tmp_path / "p.ngc"
    path.write_bytes(random_program(seed).encode())
    same_as_read_gcode(path)


@pytest.mark.parametrize("text, line", [
    ("G21\nG1 X1 F100\nX2000000000000\n", 3),  # beyond MAX_COORDINATE
    ("G21\nG1 X1 F100\nX2\nG91\nG1 X900000000000\nX200000000000\n", 6),  # there by G91 sums
    ("G21\nX1\n", 2),  # no motion mode
    ("G21\nG1 X1 F0\n", 2),  # F0: not plain, refused by the general reader
    ("G21\nG1 X1 X2\n", 2),
])
def test_errors_are_the_general_readers(tmp_path, text, line):
    path = tmp_path / "p.ngc"
    path.write_text(text)
    with pytest.raises(SpecError, match=f"^{re.escape(str(path))}:{line}: "):
        read_gcode(str(path))
    same_as_read_gcode(path)


def test_tiny_moves_are_dropped_as_the_general_reader_drops_them(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G21 G91\nG1 X1 F100\nX0.0000000001\nY1\nX0.000000001\nX0.0000000010000001\nG90\nX1\nX-0\nY0\n"
                    "X1.0000000000001\nZ0\n")
    assert same_as_read_gcode(path) > 0
    path.write_text("G21\nG1 X-0 F100\nY-0\nY1\nY1.0000000000001\nX1\n")
    assert same_as_read_gcode(path) > 0


def test_feed_moves_before_any_f_are_noted_as_the_general_reader_notes_them(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G21\nG1 X1\nY1\nG0 Z1\nG1 X2 F300\nX3\n")
    assert same_as_read_gcode(path) == 5


# --- the corpus (opt-in) ------------------------------------------------------------------------------------------

@pytest.mark.skipif(not MB31.is_file(), reason=f"the external corpus is absent ({MB31})")
def test_every_number_of_mb31_is_float_exactly():
    text = _read_text(str(MB31))
    table = scan(text)
    ctx = Context(str(MB31))
    checked = 0
    for k, raw in enumerate(program_lines(text)):
        line = parse_line(ctx, raw, k + 1)
        if not table.plain[k]:
            continue
        for j, letter in enumerate("XYZF"):
            if letter in line.words:
                assert bits(table.words[k, j]) == bits(line.words[letter]), (k + 1, raw)
                checked += 1
            else:
                assert np.isnan(table.words[k, j])
    assert table.plain.sum() == len(table) - 3  # G21, G90, M30
    assert checked > 300_000


CAM_PROGRAMS = sorted(p for d in CORPUS.glob("cam_*") for p in d.iterdir()
                      if p.suffix.lower() in {".nc", ".ngc", ".gcode", ".tap", ".cnc"}) if CORPUS.is_dir() else []


@pytest.mark.skipif(not CAM_PROGRAMS, reason=f"the external corpus is absent ({CORPUS})")
@pytest.mark.parametrize("path", CAM_PROGRAMS, ids=lambda p: p.name)
def test_the_corpus_reads_as_the_general_reader_reads_it(path):
    same_as_read_gcode(path)
