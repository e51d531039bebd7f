"""The G-code reader reads a file piece by piece (config.gcode: PIECE_BYTES, program.Flow): whatever the cut,
the path is the one the whole file gives — the same blocks bit for bit, the same notes, the same error on the
same line.  Programs are cut into pieces of 1 byte (every line a piece) up to the whole file, with '%' ends,
O-word flow (read whole from its piece on), M2 ends and errors falling in any piece."""
from __future__ import annotations

import re

import numpy as np
import pytest

from nurbsinterp.config.gcode import ProgramStream, read_gcode
from nurbsinterp.errors import SpecError
from test_gcode_fast import assert_same_path, bits, random_program

WHOLE = 1 << 30
CUTS = (1, 7, 64, 500)


def same_whatever_the_cut(path, cuts=CUTS) -> int:
    """read_gcode in pieces of every size in *cuts* equals read_gcode of the whole file (or fails alike)."""
    name = str(path)
    try:
        whole = read_gcode(name, piece_bytes=WHOLE)
    except SpecError as exc:
        for cut in cuts:
            with pytest.raises(SpecError) as info:
                read_gcode(name, piece_bytes=cut)
                raise AssertionError(f"pieces of {cut} bytes read what the whole file refuses")
            assert str(info.value) == str(exc), cut
        return 0
    for cut in cuts:
        assert_same_path(read_gcode(name, piece_bytes=cut), whole)
        assert_same_path(read_gcode(name, piece_bytes=cut, fast=False), whole)
    return len(whole.blocks)


@pytest.mark.parametrize("seed", range(40))
def test_random_cam_programs_read_alike_in_pieces(tmp_path, seed):
    path = tmp_path / "p.ngc"
    path.write_bytes(random_program(seed).encode())
    same_whatever_the_cut(path)


PLAIN = "".join(f"G1 X{k % 7}.5 Y{k % 5} F{600 + k}\n" for k in range(40))


@pytest.mark.parametrize("text", [
    "%\n" + PLAIN + "%\nG1 X99\n",  # '%' opens in the first piece, closes in a late one: nothing after it read
    "\n\n%\n" + PLAIN + "%\n",  # blanks before the opening '%'
    PLAIN + "%\nG1 X99\n",  # a '%' after lines: misplaced, refused when reached
    PLAIN + "M30\n%\nG1 X99\n",  # ... unless the program ended before it
    PLAIN + "M2\nG1 X99 Q\n",  # nothing after M2 is read, not even an error
    PLAIN + "o100 sub\nG1 X3\no100 endsub\no100 call\n" + PLAIN,  # an O-word after a long plain prefix
    PLAIN + "#1=3\no1 while [#1 GT 0]\nG91 G1 X1\n#1=[#1-1]\no1 endwhile\nG90\n" + PLAIN,
    PLAIN + "o<late> call\n" + PLAIN + "o<late> sub\nG1 Z-1\no<late> endsub\nM2\n",  # defined after its call
    PLAIN + "o1 if [1]\nG1 X1\n",  # an O-word refused (no endif): its line in the whole file
    PLAIN + "G1 X1 Y2 Z3 Q\n",  # an error in a late piece: the file's line
    PLAIN + "G2 X6.5 Y4 I1 J0\n" + PLAIN,
    PLAIN + "G5.2 X0 Y1 P1 L3\nX1 Y1 P1\nX2 Y0 P1\nG5.3\n" + PLAIN,
    PLAIN + "G1 X1\r\nG1 X2\r\n" + "G1 X3",  # CRLF and a last line without its end
    "G1 X1 F100\n" + "(é comment)\n" + PLAIN,
    "",
    "\n\n",
])
def test_programs_read_alike_in_pieces(tmp_path, text):
    path = tmp_path / "p.ngc"
    path.write_bytes(text.encode())
    same_whatever_the_cut(path, CUTS + (40, 41, 1000))


def test_an_error_in_a_late_piece_names_the_files_line(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text(PLAIN + "G1 X1 Y2 Z3 Q\n")
    with pytest.raises(SpecError, match=f"^{re.escape(str(path))}:41: "):
        read_gcode(str(path), piece_bytes=16)


def test_a_nul_byte_in_a_late_piece_is_refused(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_bytes(PLAIN.encode() * 10 + b"G1 X\0\n")
    with pytest.raises(SpecError, match="not a text file"):
        read_gcode(str(path), piece_bytes=64)


def test_a_program_stream_gives_the_paths_blocks_in_three_dimensions(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G21 G90\nG0 Z5\n" + PLAIN + "G1 Z-1\nG2 X6.5 Y4 I1 J0\nG4 P0.5\nM0\n" + PLAIN + "G1 X0\nX0\n")
    whole = read_gcode(str(path))
    assert whole.dim == 3
    stream = ProgramStream(str(path), piece_bytes=50)
    items = list(stream.items())
    blocks = []
    for item in items:
        if item.kind == "moves":
            blocks += item.blocks(3)
        else:
            blocks.append(item)
    assert len(blocks) == len(whole.blocks)
    for a, b in zip(blocks, whole.blocks):
        assert (a.kind, a.source, a.rapid, a.stop, a.dwell, a.mode) == (b.kind, b.source, b.rapid, b.stop, b.dwell,
                                                                         b.mode)
        assert bits(a.start) == bits(b.start) and bits(a.end) == bits(b.end)
    assert stream.notes == whole.notes and any("zero-length" in n for n in stream.notes)


def test_a_flat_program_streams_in_three_dimensions(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text(PLAIN)
    assert read_gcode(str(path)).dim == 2
    items = list(ProgramStream(str(path)).items())
    assert all(item.starts.shape[1] == 3 for item in items)
    assert np.all(np.concatenate([item.ends for item in items])[:, 2] == 0.0)


def test_the_streams_fingerprint_names_the_bytes_and_the_start(tmp_path):
    a = tmp_path / "a.ngc"
    b = tmp_path / "b.ngc"
    a.write_text(PLAIN)
    b.write_text(PLAIN + "\n")
    fa, fb = ProgramStream(str(a)).fingerprint, ProgramStream(str(b)).fingerprint
    assert re.fullmatch("[0-9a-f]{16}", fa) and fa != fb
    assert ProgramStream(str(a), start=(1, 0)).fingerprint != fa
    assert ProgramStream(str(a)).fingerprint == fa


def test_a_stream_of_a_program_that_moves_nowhere_is_refused(tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G21\nG90\n")
    with pytest.raises(SpecError, match="moves nowhere"):
        list(ProgramStream(str(path)).items())


def test_a_missing_program_is_one_line(tmp_path):
    with pytest.raises(SpecError, match="cannot read"):
        ProgramStream(str(tmp_path / "none.ngc"))
    with pytest.raises(SpecError, match="is a directory"):
        ProgramStream(str(tmp_path))
