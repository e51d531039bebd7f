"""Real CAM programs read as LinuxCNC reads them (issue 28, item 5): the corpus against ``rs274``.

Opt-in twice over: every test needs ``rs274`` on PATH (Debian package ``linuxcnc-uspace``), and
the corpus tests need ``../shared/corpus`` beside the checkout (other people's programs, under
their own licences: read from there, never copied into this tree).  The quirk tests at the end
need only rs274: each is a small program written here that holds one oddity found in the corpus.

Each corpus program (``cam_*/*.nc|ngc|gcode``, ``linuxcnc-nurbs/G5|G6/*.ngc`` but the invalid
``Curva_Stella_Q1_G5.ngc``) is read by :func:`~nurbsinterp.config.gcode.read_gcode` and by rs274
(``tests/rs274ref.py``, which documents rs274's output), and compared move by move:

- geometry and feed: kind, start and end, arc centre, normal (plane and direction), sweep, rise,
  feed, NURBS control-point count, with the bounds of ``test_rs274.py`` (rs274's printed digits,
  and the "CAM" allowance for arcs whose ends are not equidistant from their centre);
- the block count (rs274's moves without the zero-length ones, which the reader drops);
- the joints: path-control mode (G61, G61.1, G64 P Q) to the printed digits, the stops (M0 M1
  M60 M6) and the dwell (G4) since the previous move;
- ``nurbsinterp convert`` exits 0.

Every program of the corpus agrees, all aspects.

rs274's own gaps (this build, 2.9.0~pre1): it does not know G6.2, and reads G5.2 in the XY plane
only.  For those programs the moves it made before it stopped are compared, and the stop must be
one of these two.  It refuses a feed move before any F ("Cannot do g1 with zero feed rate", as
LinuxCNC does: SheepTile-v2.nc); such a program is run through rs274 from a temporary copy whose
first line is given a sentinel ``F`` (and each G94 without one: G94 sets the feed to none in
LinuxCNC), and the moves at that sentinel feed must carry no feed in
the reader (the profile's).
"""
from __future__ import annotations

import functools
import math
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import rs274ref

if rs274ref.RS274 is None:
    pytest.skip("rs274 not on PATH (Debian package linuxcnc-uspace)", allow_module_level=True)

from test_cli_contract import run_main  # noqa: E402
from test_rs274 import SLACK, compare_move, numbered  # noqa: E402

from nurbsinterp.config.gcode import read_gcode  # noqa: E402
from nurbsinterp.errors import SpecError  # noqa: E402

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus"
INVALID = "Curva_Stella_Q1_G5.ngc"
CAM = sorted(p for d in CORPUS.glob("cam_*") for p in d.iterdir() if p.suffix in (".nc", ".ngc", ".gcode"))
NURBS = sorted(p for p in (CORPUS / "linuxcnc-nurbs").glob("G[56]/*.ngc") if p.name != INVALID)
PROGRAMS = CAM + NURBS
#: rs274's own gaps (see the module's notes): its message, and a word of the line it stops at (a G5.2
#: control point's line holds none)
RS274_GAPS = {"Unknown g code used": "G6.2", "You must specify both X and Y coordinates for Control Points": ""}
ZERO_FEED = "Cannot do g1 with zero feed rate"
SENTINEL_FEED = 12345.0  # mm/min: the F given to a program rs274 refuses for moving before any F
DWELL_HALF_STEP = 0.5e-4  # s: DWELL is printed %.4f

def _cases(aspect: str):
    """Every program, each *aspect* of it a test (the aspect names what a failing case compared)."""
    return [pytest.param(program, id=f"{program.parent.name}/{program.name}") for program in PROGRAMS]


needs_corpus = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"the external corpus is absent ({CORPUS})")


# --------------------------------------------------------------------------- the two readings


@pytest.fixture(scope="module")
def rs274_runs(tmp_path_factory):
    """rs274's moves of every corpus program (or its refusal), run as many at a time as there are cores."""
    results = dict(zip(PROGRAMS, rs274ref.read_many(PROGRAMS)))
    folder = tmp_path_factory.mktemp("sentinel-feed")
    for program, result in results.items():
        if isinstance(result, rs274ref.Rs274Error) and result.reason == ZERO_FEED:
            results[program] = _with_sentinel_feed(program, folder)
    return results


def _with_sentinel_feed(program: Path, folder: Path):
    """rs274's moves of *program* given F SENTINEL_FEED before its first line, and after each G94 that
    gives no F (G94 sets the feed to 0 in LinuxCNC: convert_feed_mode), the line numbers kept."""
    lines = program.read_bytes().decode("latin-1").split("\n")
    assert not lines[0].lstrip().startswith("%"), "a first line % cannot take a word"
    # F is executed before a G20 on its line: read in mm/min whatever the line says
    lines[0] = f"F{SENTINEL_FEED:g} " + lines[0]
    for k, line in enumerate(lines):
        words = re.sub(r"\(.*?\)|;.*", "", line).upper().replace(" ", "")
        if re.search(r"G0*94(?![\d.])", words) and "F" not in words:
            lines[k] = line.rstrip("\r") + f" F{SENTINEL_FEED:g}"  # F after the feed mode, on its line
    copy = folder / program.name
    copy.write_text("\n".join(lines))
    try:
        moves = rs274ref.read_moves(copy)
    except rs274ref.Rs274Error as refusal:
        return refusal
    return [m if m.feed != SENTINEL_FEED else _no_feed(m) for m in moves]


def _no_feed(move):
    return replace(move, feed=None)


@functools.lru_cache(maxsize=None)
def _read(program: Path):
    """The reader's path of *program*, or the SpecError it raised (read once for every test)."""
    try:
        return read_gcode(str(program))
    except SpecError as exc:
        return exc


def paired(blocks, moves) -> tuple[list, list]:
    """The reader's blocks paired with rs274's moves, and rs274's moves left over.

    rs274 prints zero-length moves, which the reader drops; but a move shorter than a printed
    step (vcarve.ngc's 6-decimal inches) also prints as zero-length while the reader keeps it.
    So a move printed as zero-length is paired with the reader's next block when that block is a
    straight move of the same kind from and to the printed point (within the roundings), and is
    otherwise left out, its stops and dwell passing to the next move.  Likewise a move after a NURBS
    (its start unknown) to where the reader's next block starts (see :func:`_dropped`)."""
    pairs, left, k = [], [], 0
    stops, dwell = (), 0.0
    for move in moves:
        block = blocks[k] if k < len(blocks) else None
        if _dropped(block, move):
            stops, dwell = stops + move.stops, dwell + move.dwell
            continue
        if stops or dwell:
            move = replace(move, stops=stops + move.stops, dwell=dwell + move.dwell)
            stops, dwell = (), 0.0
        if block is None:
            left.append(move)
        else:
            pairs.append((block, move))
            k += 1
    return pairs, left


def _dropped(block, move) -> bool:
    """*move* is one the reader dropped as zero-length: printed so (and not a sub-step block), or,
    right after a NURBS (whose end rs274 does not print), a straight move to where the reader's
    next block starts and not to where it ends."""
    if move.is_zero_length:
        return not _same_point_move(block, move)
    if move.start is None and move.kind in ("rapid", "line") and block is not None:
        start, end = _point3(block.start), _point3(block.end)
        return (float(np.max(np.abs(start - move.end))) <= move.end_tol + SLACK
                and float(np.max(np.abs(end - move.end))) > move.end_tol + SLACK)
    return False


def _same_point_move(block, move) -> bool:
    if block is None or block.kind != "line" or block.rapid != (move.kind == "rapid"):
        return False
    start, end = _point3(block.start), _point3(block.end)
    return (float(np.max(np.abs(start - move.start))) <= move.start_tol + SLACK
            and float(np.max(np.abs(end - move.end))) <= move.end_tol + SLACK)


def _point3(p) -> np.ndarray:
    p = np.asarray(p, dtype=float)
    return np.append(p, 0.0) if p.shape[0] == 2 else p


def _both(program: Path, rs274_runs):
    """(the reader's path, rs274's moves, whether rs274 stopped at one of its gaps)."""
    spec = _read(program)
    if isinstance(spec, SpecError):
        pytest.fail(f"the reader refuses the program: {spec}")
    result = rs274_runs[program]
    partial = isinstance(result, rs274ref.Rs274Error)
    if partial:
        word = RS274_GAPS.get(result.reason)
        assert word is not None and word in result.line.upper(), f"rs274 refused the program: {result}"
        result = result.moves
    return spec, result, partial


# --------------------------------------------------------------------------- comparisons


def geometry_mismatches(spec, ref) -> list[str]:
    found = []
    for k, (block, move) in enumerate(paired(spec.blocks, ref)[0]):
        for problem in compare_move(block, move, 0.0, bisector=True):  # both start at the origin
            found.append(f"move {k} ({block.source}; rs274 output line {move.index} {move.n_word}): {problem}")
    return found


def joint_mismatches(block, move) -> list[str]:
    """What differs in how the program asks a joint to be passed: mode, stops, dwell."""
    problems = []
    mode, ref = block.mode, move.mode
    if mode.control != ref.control:
        problems.append(f"control {mode.control}, rs274 {ref.control}")
    for name, ours, theirs, tol in (("G64 P", mode.tolerance, ref.tolerance, ref.tolerance_tol),
                                    ("G64 Q", mode.naive_tolerance, ref.naive_tolerance, ref.naive_tol)):
        ours = ours or None  # 0 and None are the same to LinuxCNC (see rs274ref)
        if (ours is None) != (theirs is None) or (ours is not None and not abs(ours - theirs) <= tol + SLACK):
            problems.append(f"{name} {ours!r} mm, rs274 {theirs!r} mm")
    stops = move.stops  # what brought the tool to rest: M0 M1 M6 M60, G4 (a DWELL, even of 0 s)
    if (block.stop is None) != (not stops) or (
            block.stop is not None and not any(re.search(rf"\b{w}\b", block.stop) for w in stops)):
        problems.append(f"stop {block.stop!r}, rs274 {stops}")
    if not abs(block.dwell - move.dwell) <= DWELL_HALF_STEP * max(1, round(move.dwell)) + SLACK:
        problems.append(f"dwell {block.dwell!r} s, rs274 {move.dwell!r} s")
    return problems


def _fail(found: list[str], program: Path) -> None:
    assert not found, f"{program}: {len(found)} differences\n" + "\n".join(found[:8])


@needs_corpus
def test_the_corpus_is_there():
    assert len(CAM) == 9, [p.name for p in CAM]
    assert len(NURBS) == 54


@needs_corpus
@pytest.mark.parametrize("program", _cases("geometry"))
def test_moves_agree_with_rs274(program, rs274_runs):
    spec, ref, _partial = _both(program, rs274_runs)
    _fail(geometry_mismatches(spec, ref), program)


@needs_corpus
@pytest.mark.parametrize("program", _cases("count"))
def test_block_count_agrees_with_rs274(program, rs274_runs):
    """As many blocks as rs274's moves of any length; where rs274 stopped at its own gap, more."""
    spec, ref, partial = _both(program, rs274_runs)
    pairs, left = paired(spec.blocks, ref)
    assert not left, f"rs274 made {len(left)} moves more than the reader's {len(spec.blocks)} blocks"
    if partial:
        assert len(spec.blocks) > len(pairs)
        assert spec.blocks[len(pairs)].kind == "nurbs"  # where rs274 stopped, the reader goes on
    else:
        assert len(spec.blocks) == len(pairs), f"the reader made {len(spec.blocks)} blocks, rs274 {len(pairs)} moves"


@needs_corpus
@pytest.mark.parametrize("program", _cases("joints"))
def test_modes_stops_and_dwells_agree_with_rs274(program, rs274_runs):
    spec, ref, _partial = _both(program, rs274_runs)
    found = []
    for k, (block, move) in enumerate(paired(spec.blocks, ref)[0]):
        for problem in joint_mismatches(block, move):
            found.append(f"move {k} ({block.source}; rs274 output line {move.index}): {problem}")
    _fail(found, program)


@needs_corpus
@pytest.mark.parametrize("program", _cases("convert"))
def test_convert_writes_the_program(capsys, tmp_path, program):
    out_file = tmp_path / "job.yaml"
    code, out, err = run_main(capsys, "convert", program, "-o", out_file)
    assert code == 0, err
    assert out == "" and out_file.stat().st_size > 0


#: the programs whose description takes longest (the largest, 120-150 k blocks): in the slow set; the rest in the
#: quick one
INFO_SLOW = {"GrimReaper.gcode", "MB-3.1_test.nc", "DXF473.gcode"}


@needs_corpus
@pytest.mark.parametrize("program", [pytest.param(p, id=p.name, marks=[pytest.mark.slow] if p.name in INFO_SLOW else [])
                                     for p in CAM])
def test_info_plans_every_cam_program_with_look_ahead(capsys, program):
    """`info` reads, plans and describes each CAM program with look-ahead: within its own G64 P where it states one,
    on the exact path where not (the two that once stopped at every joint, 35 h of motion for MB-3.1's 150 k blocks
    and past --max-ticks, now plan in 1.5 and 2.3 h at the default profile's ramp), never a traceback."""
    code, out, err = run_main(capsys, "info", program, "--json")
    assert code == 0, err
    import json

    facts = json.loads(out)
    blocks = len(read_gcode(str(program)).blocks)
    assert facts["planner"] == "look-ahead" and facts["tolerance_source"] == "program"
    assert facts["blocks"] - facts["dropped"] == blocks, (facts["blocks"], facts["dropped"], blocks)
    assert facts["ticks"] > 1


# --------------------------------------------------------------------------- quirks (rs274 only)


def _pair(tmp_path, text: str, name: str = "quirk.ngc", *, newline: str = "\n"):
    path = tmp_path / name
    path.write_bytes(text.replace("\n", newline).encode())
    return path, rs274ref.read_moves(path)


def _agree(path, moves, *, joints: bool = False):
    spec = read_gcode(str(path))
    pairs, left = paired(spec.blocks, moves)
    found = geometry_mismatches(spec, moves)
    if len(spec.blocks) != len(pairs) or left:
        found.append(f"the reader made {len(spec.blocks)} blocks, rs274 {len(pairs) + len(left)} moves")
    if joints:
        found += [p for b, m in pairs for p in joint_mismatches(b, m)]
    assert not found, "\n".join(found) + "\n" + numbered(path.read_text())
    return spec


def test_quirk_mangled_f999_feeds(tmp_path):
    """LHchips4.ngc: a post replaced every "F" by "F999", feeds too: F999800.0 is 999 800 mm/min to rs274."""
    path, moves = _pair(tmp_path, "G21 G90\nG0 X1 Y2\n G1 Z-1.5 F999800.0\n X4.25 F9991300.0\nM2\n")
    assert [m.feed for m in moves] == [None, 999800.0, 9991300.0]
    _agree(path, moves)


def test_quirk_spaces_inside_numbers(tmp_path):
    """vcarve.ngc: ``G0Z  0.1000``, ``X  0.0238``, ``Z -0.0000``: spaces go before a line is read."""
    path, moves = _pair(tmp_path, "G20 G90\nG0Z  0.1000 \nG1 X  0.0238 Y 1 2 . 5 Z -0.0000 F 1 0\nM2\n")
    assert np.allclose(moves[-1].end, [0.0238 * 25.4, 12.5 * 25.4, 0.0], atol=moves[-1].end_tol)
    _agree(path, moves)


def test_quirk_zero_length_moves(tmp_path):
    """vcarve.ngc: a G1 to where the tool is, twice in a row: rs274 prints both, the reader drops them."""
    path, moves = _pair(tmp_path, "G21\nG1 X1 Y1 F100\nG1 X1 Y1\nG1\nG0 Z0\nG1 X2\nG1 X2.0001\nM2\n")
    assert len(moves) == 6 and len(rs274ref.without_zero_length(moves)) == 3  # one step (0.1 um) is a move
    _agree(path, moves)


def test_quirk_lines_beginning_with_spaces_and_crlf(tmp_path):
    """LHchips4.ngc, Cereal.ngc: CRLF endings; every line begins with a space; trailing spaces."""
    path, moves = _pair(tmp_path, " G21 G90 \n G0 X1 Y1\n  Z5.0 \n G1 Z-1 F200 \n X3 \n M2\n", newline="\r\n")
    assert len(moves) == 4
    _agree(path, moves)


def test_quirk_packed_words(tmp_path):
    """flower_mold.nc, 3D_Chips.ngc: words with no space between them, ``G90G20M03S2000``, ``G64P.1``."""
    path, moves = _pair(tmp_path, "G90G20M03S2000\nG64P.1\nG0X0.0000Y0.0000Z0.2000\nG1X0.0010Y0.0010Z0.0000F8.0\n"
                                  "N80G1X1.Y2.\nM2\n")
    assert moves[-1].feed == pytest.approx(8.0 * 25.4)
    _agree(path, moves)


def test_quirk_f_on_the_line_of_g20(tmp_path):
    """vcarve.ngc's first line ``G20 F6``: F is executed before G20, so the feed is 6 mm/min."""
    path, moves = _pair(tmp_path, "G20 F6\nG1 X1\nM2\n")
    assert moves[0].feed == 6.0
    _agree(path, moves)


def test_quirk_percent_after_the_end(tmp_path):
    """GrimReaper.gcode: N words on every line, ``Z2.``, and a ``%`` after M30 (nothing runs after M30)."""
    path, moves = _pair(tmp_path, "N1 G00 G17 G21 G40 G49 G80 G90\nN2 G00  X-47.5  Y-61.422 M03\n"
                                  "N3 G43H1  Z2. M8\nN4 G01 Z-1.688 F300\nN5 M30\n%\n", newline="\r\n")
    assert [m.n_word for m in moves] == ["N1", "N2", "N3", "N4"]  # G00 without axis words: a zero-length move
    _agree(path, moves)


def test_quirk_comments_that_look_like_words(tmp_path):
    """LHchips4.ngc: ``( G10 L2 P1 X0.0 Y0.0 Z0.0 Top)``, ``(M0)`` and ``(MSG, ...)`` are comments: no offset,
    no stop."""
    path, moves = _pair(tmp_path, "G21\n( G10 L2 P1 X5 Y5 Z0.0 Top)\n(M0)\n(MSG, INSERT BALLNOSE)\nG1 X1 F100\nM2\n")
    assert moves[0].stops == () and np.allclose(moves[0].end, [1, 0, 0])
    _agree(path, moves, joints=True)


def test_quirk_feed_move_before_any_f(tmp_path):
    """SheepTile-v2.nc: a G1 before any F.  rs274 (and LinuxCNC) refuse it; the reader moves it at the
    profile's feedrate and says so in a note."""
    path = tmp_path / "nofeed.ngc"
    path.write_text("G21 G90\nG1 X10 Y5\nG1 Z-1 F300\nM2\n")
    with pytest.raises(rs274ref.Rs274Error) as refusal:
        rs274ref.read_moves(path)
    assert refusal.value.reason == ZERO_FEED and refusal.value.line.strip() == "G1 X10 Y5"
    spec = read_gcode(str(path))
    assert [b.feedrate for b in spec.blocks] == [None, 5.0]
    assert any("F word (lines 2)" in note for note in spec.notes)


def test_quirk_tool_word_without_m6(tmp_path):
    """Cereal.ngc: ``T1`` alone selects a tool and does not stop; ``T2 M6`` changes it, before the line's move."""
    path, moves = _pair(tmp_path, "G21\nG1 X1 F100\nT1\nG1 X2\nT2 M6 G1 X3\nG1 X4\nM2\n")
    assert [m.stops for m in moves] == [(), (), ("M6",), ()]
    _agree(path, moves)  # the stops themselves: test_quirk_stops_and_dwells


def test_quirk_g53_retract_with_g92(tmp_path):
    """Cereal.ngc's ``G0 G53 Z-10.0``: machine coordinates, whatever G92 says (rs274 prints them minus it)."""
    path, moves = _pair(tmp_path, "G21 G90\nG0 X10 Y5 Z2\nG92 X0 Y0 Z0\nG1 X1 F100\nG0 G53 Z-10.0\nG0 G53 X10 Y-10\n"
                                  "M2\n")
    assert np.allclose(moves[-2].end, [11, 5, -10]) and np.allclose(moves[-1].end, [10, -10, -10])
    _agree(path, moves)


def test_quirk_g28_incremental_zero(tmp_path):
    """SheepTile-v2.nc's ``G28 G91 Z0``: the intermediate point is where Z is, then Z goes to the stored
    position (the machine origin without a variable file); ``G28 G91 X0 Y0`` likewise in X and Y."""
    path, moves = _pair(tmp_path, "G21 G90\nG0 X10 Y5 Z2\nG28 G91 Z0\nG90\nG1 X12 F100\nG28 G91 X0 Y0\nG90\nM2\n")
    assert np.allclose(moves[2].end, [10, 5, 0]) and np.allclose(moves[-1].end, [0, 0, 0])
    _agree(path, moves)


def test_quirk_stops_and_dwells(tmp_path):
    """M0 after the line's move, M6 and G4 before it, M1 and M60 stop too; T alone does not."""
    path, moves = _pair(tmp_path, "G21\nG1 X1 F100\nT1\nG1 X2\nT2 M6 G1 X3\nM0 G1 X4\nG1 X5\nG4 P1.5 G1 X6\n"
                                  "M1\nG1 X7\nM60\nG1 X8\nM2\n")
    assert [m.stops for m in moves] == [(), (), ("M6",), (), ("M0",), ("G4",), ("M1",), ("M60",)]
    assert [m.dwell for m in moves] == [0, 0, 0, 0, 0, 1.5, 0, 0]
    _agree(path, moves, joints=True)


def test_quirk_g64_in_inches(tmp_path):
    """vcarve.ngc's ``G64 P0.001`` after G20: 0.0254 mm, and Q defaults to P; LHchips4's ``G64 P0.1 Q0.01``."""
    path, moves = _pair(tmp_path, "G20\nG64 P0.001\nG1 X1 F10\nG21 G64 P0.1 Q0.01\nG1 X1\nG61\nG1 X2\nG61.1\n"
                                  "G1 X3\nG64\nG1 X4\nM2\n")
    assert moves[0].mode.tolerance == pytest.approx(0.0254) and moves[0].mode.naive_tolerance == pytest.approx(0.0254)
    assert (moves[1].mode.tolerance, moves[1].mode.naive_tolerance) == (0.1, 0.01)
    assert [m.mode.control for m in moves] == ["blend", "blend", "exact_path", "exact_stop", "blend"]
    _agree(path, moves, joints=True)


# --------------------------------------------------------------------------- the tiny CamBam arc (issue 28)

# CamBam writes 4 decimals: a G3 whose ends are one step apart (chord 0.1 um = 1e-4 mm) about a
# centre 0.5 mm away, the radii to its ends 0.49999 and 0.500013 mm (issue 28).  LinuxCNC accepts
# it (|r_end - r_start| = 2.3e-5 mm is far inside its 0.0283 mm) and runs it as a spiral about the
# centre as written; moving that centre onto the chord's perpendicular bisector would move it by
# (r_end² - r_start²) / (2 chord) = 0.115 mm.
TINY_RADII = (0.49999, 0.500013)  # mm, to the start and to the end
TINY_CHORD = 1e-4  # mm


def tiny_arc_program() -> str:
    """The start S = (10, 10), the end S - (chord, 0), the centre S + (i, j) with |C - S| = r0, |C - E| = r1."""
    r0, r1 = TINY_RADII
    i = (r1 ** 2 - r0 ** 2 - TINY_CHORD ** 2) / (2 * TINY_CHORD)
    j = -math.sqrt(r0 ** 2 - i ** 2)
    return (f"G21 G90 G17\nG0 X10 Y10\nG1 Z-0.5 F300\nG3 X{10 - TINY_CHORD:.4f} Y10 I{i:.6f} J{j:.6f}\n"
            "G1 X12 F600\nM2\n")


def test_tiny_arc_is_what_rs274_prints(tmp_path):
    """rs274 emits the arc as written: ``ARC_FEED(9.9999, 10.0000, 10.1150, 9.5134, 1, -0.5000, ...)``."""
    path, moves = _pair(tmp_path, tiny_arc_program())
    arc = next(m for m in moves if m.kind == "arc")
    assert np.allclose(arc.end, [9.9999, 10, -0.5], rtol=0, atol=1e-12)
    assert np.allclose(arc.center, [10.1150, 9.5134, -0.5], rtol=0, atol=1e-12)
    assert arc.normal[2] == 1 and arc.turns == 1
    start, end = np.array([10, 10]), np.array([10 - TINY_CHORD, 10])
    center = start + [float(w[1:]) for w in tiny_arc_program().split("\n")[3].split()[3:5]]
    radii = np.linalg.norm(start - center), np.linalg.norm(end - center)
    assert np.allclose(radii, TINY_RADII, rtol=0, atol=2e-7)


def test_tiny_cambam_arc_reads_as_rs274_reads_it(tmp_path):
    """The reader accepts what rs274 accepts and keeps the arc as LinuxCNC runs it: a spiral about the
    centre rs274 prints, from its start to its end (a B-spline within 1e-9 mm of the spiral: see
    tests/test_gcode_machine.py); the other moves agree move by move."""
    path, moves = _pair(tmp_path, tiny_arc_program())
    spec = read_gcode(str(path))
    kinds = [b.kind for b in spec.blocks]
    assert kinds == ["line", "line", "nurbs", "line"] and [m.kind for m in moves][2] == "arc"
    arc, spiral = moves[2], spec.blocks[2]
    assert np.all(np.abs(spiral.start - arc.start) <= arc.start_tol + SLACK)
    assert np.all(np.abs(spiral.end - arc.end) <= arc.end_tol + SLACK)
    from nurbsinterp.nurbs import NurbsCurve

    curve = NurbsCurve.from_spec(spiral.curve)
    points = curve.evaluate(np.linspace(curve.knots[0], curve.knots[-1], 101))
    radii = np.linalg.norm(points[:, :2] - arc.center[:2], axis=1)
    # about the printed centre (each coordinate within its printed half step), between the two radii
    slack = math.sqrt(2) * (arc.end_tol + SLACK)
    assert np.all(radii >= min(TINY_RADII) - slack) and np.all(radii <= max(TINY_RADII) + slack)
    others = [k for k in range(len(moves)) if k != 2]
    for k in others:
        assert not compare_move(spec.blocks[k], moves[k], 0.0, bisector=False), k
