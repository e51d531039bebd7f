"""The motions real posts start and end with, and the modes that shape motion (issue 28, items 3 and 4).

G28/G30 (two rapids: through the intermediate point in the current mode, then to the stored
position, only the named axes or all of them), G28.1/G30.1 (store), G53 (machine coordinates),
G92/G92.1/G92.2/G92.3 and G52 (the offset the reader applies), and per block: the path-control
mode (G61, G61.1, G64 P Q), the stops (M0 M1 M6 M60, G4 with its dwell) and what must not stop
(S, M3 M4 M5 M7 M8 M9, T without M6).  Expected positions are worked by hand from LinuxCNC's
rules (interp_convert.cc: convert_home, convert_axis_offsets, convert_control_mode); the same
programs are compared with rs274 itself in tests/test_rs274_machine.py where rs274 exists.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest

from test_cli_contract import one_line_error, run_main

from nurbsinterp.config import load_job
from nurbsinterp.config.gcode import read_gcode
from nurbsinterp.config.path import BlockMode
from nurbsinterp.errors import SpecError


def read(tmp_path, text, **kwargs):
    path = tmp_path / "p.ngc"
    path.write_text(textwrap.dedent(text))
    return read_gcode(str(path), **kwargs)


def ends(spec):
    """The blocks' end points as (x, y, z): a flat program reads as a 2-D path."""
    return [tuple(float(c) for c in b.end) + (0.0,) * (3 - len(b.end)) for b in spec.blocks]


# --------------------------------------------------------------------------- G28 / G30


def test_g28_alone_rapids_every_axis_to_the_machine_origin(tmp_path):
    spec = read(tmp_path, """
        G21 G90
        G1 X10 Y20 Z5 F600
        G28
        """)
    assert ends(spec) == [(10, 20, 5), (0, 0, 0)]
    assert spec.blocks[1].rapid
    assert any("G28 (line 4) goes to its stored position (0, 0, 0) mm" in n and "machine origin" in n
               for n in spec.notes)


def test_fusion_360s_g28_g91_z0_retracts_z_only(tmp_path):
    """The first motion of every Fusion 360 post: the intermediate point is where the tool is (G91 Z0),
    then only Z goes to its stored position."""
    spec = read(tmp_path, """
        G90 G21
        G1 X10 Y20 Z-3 F600
        G28 G91 Z0
        G90
        G1 X0
        """)
    assert ends(spec) == [(10, 20, -3), (10, 20, 0), (0, 20, 0)]


FUSION_RETRACTS = """
    G90 G21
    G28 G91 Z0
    G90
    G0 X10 Y20 Z5
    G1 Z-3 F600
    G0 Z5
    G28 G91 Z0
    G90
    M2
    """


def test_a_g28_that_moves_z_down_to_an_origin_nobody_gave_is_named(tmp_path, capsys):
    """A Fusion 360 post retracts with G28 G91 Z0: the first one moves nothing (the tool is at the origin), the
    second (line 8: the text's first line is empty) drives Z down from 5 to the machine origin's 0 when no G28 position was given.  The note names the
    line that moved and says Z goes down; the CLI names its option; given the position, no warning."""
    spec = read(tmp_path, FUSION_RETRACTS)
    (note,) = [n for n in spec.notes if n.startswith("G28")]
    assert note.startswith("G28 (line 8) goes to its stored position (0, 0, 0) mm"), note
    assert "Z moves down there (line 8)" in note, note
    code, _, err = run_main(capsys, "info", tmp_path / "p.ngc", "--json")
    assert code == 0, err
    assert "Z moves down there (line 8): if the machine homes elsewhere, give its G28 position with --g28 X,Y,Z" \
        in err, err
    spec = read(tmp_path, FUSION_RETRACTS, homes={"G28": (0, 0, 50)})
    (note,) = [n for n in spec.notes if n.startswith("G28")]
    assert "(0, 0, 50)" in note and "as stored or given" in note and "down" not in note, note


def test_every_g28_that_moves_is_named(tmp_path):
    spec = read(tmp_path, "G21 G90\nG0 X10 Y20 Z5\nG28\nG0 X5\nG28\nG28\nM2\n")
    (note,) = [n for n in spec.notes if n.startswith("G28")]
    assert note.startswith("G28 (lines 3, 5) goes to its stored position"), note  # line 6 moved nothing
    assert "Z moves down there (line 3)" in note, note


def test_g28_with_axes_goes_through_the_intermediate_point_then_homes_the_named_axes(tmp_path):
    spec = read(tmp_path, """
        G1 X10 Y20 Z5 F600
        G28 X3 Z7
        """, homes={"G28": (100, 200, 50)})
    # leg 1: X3 Z7 absolute (Y stays); leg 2: X and Z to the stored position, Y unmoved
    assert ends(spec) == [(10, 20, 5), (3, 20, 7), (100, 20, 50)]
    assert all(b.rapid for b in spec.blocks[1:])
    assert any("G28 (line 3)" in n and "(100, 200, 50)" in n and "as stored or given" in n for n in spec.notes)


def test_g28_1_stores_where_the_tool_is_and_g30_has_its_own_position(tmp_path):
    spec = read(tmp_path, """
        G1 X1 Y2 Z3 F600
        G28.1
        G1 X50 Y50 Z50
        G28
        G30
        """, homes={"G30": (-5, -6, -7)})
    assert ends(spec)[-2:] == [(1, 2, 3), (-5, -6, -7)]


def test_g28_in_inches_reads_the_intermediate_point_in_inches_and_the_stored_position_in_mm(tmp_path):
    spec = read(tmp_path, """
        G20 G1 X1 F10
        G28 X2
        """, homes={"G28": (5, 0, 0)})
    assert ends(spec) == [(25.4, 0, 0), (50.8, 0, 0), (5, 0, 0)]


def test_the_stored_positions_are_reader_options_on_the_command_line(capsys, tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G1 X10 F600\nG28\nG30\n")
    code, out, err = run_main(capsys, "convert", path, "--g28", "1,2,3", "--g30", "4,5,6", "-o", "-")
    assert code == 0, err
    assert "to: [1.0, 2.0, 3.0]" in out and "to: [4.0, 5.0, 6.0]" in out
    code, out, err = run_main(capsys, "convert", path, "--g28", "1,2", "-o", tmp_path / "x.yaml")
    one_line_error(code, out, err, "--g28", "X,Y,Z")
    assert not (tmp_path / "x.yaml").exists()


# --------------------------------------------------------------------------- G53, G92, G52


def test_g53_moves_in_machine_coordinates_past_a_g92_offset(tmp_path):
    spec = read(tmp_path, """
        G1 X10 Y10 Z0 F600
        G92 X0 Y0 Z0
        G1 X5
        G53 G0 Z20
        G1 X1
        """)
    # after G92 at (10, 10, 0) the program's X5 is machine X15; G53 Z20 is machine Z20; G53 is not modal
    assert ends(spec) == [(10, 10, 0), (15, 10, 0), (15, 10, 20), (11, 10, 20)]
    assert spec.blocks[2].rapid and not spec.blocks[3].rapid


def test_g53_takes_the_motion_mode_in_effect(tmp_path):
    spec = read(tmp_path, """
        G0 X1
        G53 Z-2
        """)
    assert ends(spec) == [(1, 0, 0), (1, 0, -2)] and spec.blocks[1].rapid


def test_g92_clear_restore_and_g52(tmp_path):
    spec = read(tmp_path, """
        G1 X10 F600
        G92 X0
        G1 X1
        G92.2
        G1 X1
        G92.3
        G1 X2
        G92.1
        G1 X3
        G52 X100
        G1 X-90
        """)
    assert [e[0] for e in ends(spec)] == [10, 11, 1, 12, 3, 10]


def test_g92_in_inches_is_an_offset_in_mm(tmp_path):
    spec = read(tmp_path, """
        G20 G1 X1 F10
        G92 X0
        G1 X1
        """)
    assert ends(spec)[-1] == pytest.approx((50.8, 0, 0), abs=1e-12)


def test_absolute_arc_centres_and_nurbs_points_are_offset_too(tmp_path):
    spec = read(tmp_path, """
        G1 X10 F600
        G92 X0
        G90.1 G3 X-5 Y5 I-5 J0
        G5.2 X-4 Y7 P1 L3
        X-3 Y9 P1
        G5.3
        """)
    arc, nurbs = spec.blocks[1], spec.blocks[2]
    assert tuple(arc.center[:2]) == (5, 0) and tuple(arc.end[:2]) == (5, 5)  # the program's (-5, 0), (-5, 5)
    assert nurbs.curve.control_points[:, :2].tolist() == [[5, 5], [6, 7], [7, 9]]


# --------------------------------------------------------------------------- modes and stops


def test_the_path_control_mode_is_carried_per_block_in_mm(tmp_path):
    spec = read(tmp_path, """
        G1 X1 F600
        G64 P0.01 Q0.005
        G1 X2
        G61
        G1 X3
        G61.1 G1 X4
        G20 G64 P0.001
        G1 X1
        G64
        G1 X2
        """)
    modes = [b.mode for b in spec.blocks]
    assert modes[0] == BlockMode("blend")
    assert modes[1] == BlockMode("blend", 0.01, 0.005)
    assert modes[2] == BlockMode("exact_path")
    assert modes[3] == BlockMode("exact_stop")  # the mode is set before the line's motion
    assert modes[4].control == "blend" and modes[4].tolerance == pytest.approx(0.0254, abs=1e-15)
    assert modes[4].naive_tolerance == modes[4].tolerance  # Q defaults to P, as LinuxCNC takes it
    assert modes[5] == BlockMode("blend")


def test_a_line_s_modes_take_effect_in_linuxcnc_s_order_not_the_text_s(tmp_path):
    """``G64 P0.01 G20``: units before path control (convert_g), so P is 0.01 in = 0.254 mm, as rs274 prints;
    a negative P is LinuxCNC's "not given" (the default tolerance), not an error."""
    spec = read(tmp_path, """
        G21 G90 G1 X1 F100
        G64 P0.01 G20
        G1 X2
        G21 G64 P-1 Q-1
        G1 X3
        """)
    assert spec.blocks[1].mode.tolerance == pytest.approx(0.254, abs=1e-15)
    assert spec.blocks[2].mode == BlockMode("blend")


def test_m66_and_user_m_codes_stop_before_their_line_s_motion(tmp_path):
    """LinuxCNC carries out M66 and M100..M199 in convert_m, before the line's motion (convert_g)."""
    spec = read(tmp_path, """
        G1 X1 F100
        G1 X2 M66 P0 L0
        G1 X3 M101
        M66 E0 L3 Q2.5
        G1 X4
        """)
    assert [b.stop for b in spec.blocks] == [None, "M66 at line 3", "M101 at line 4", "M66 at line 5"]


def test_stops_and_dwells_fall_before_the_next_block(tmp_path):
    spec = read(tmp_path, """
        G1 X1 F600
        G1 X2 M0
        G1 X3
        T2 M6 G1 X4
        G4 P0.5
        G4 P1
        G1 X5
        M1
        M60
        G1 X6
        G1 X7
        G1 X8 M100
        """)
    stops = [(b.stop, b.dwell) for b in spec.blocks]
    assert stops[0] == (None, 0) and stops[1] == (None, 0)  # M0 after the motion of its own line
    assert stops[2] == ("M0 at line 3", 0)
    assert stops[3] == ("M6 at line 5", 0)  # M6 before its line's motion, as LinuxCNC orders them
    assert stops[4] == ("G4 P0.5 at line 6; G4 P1 at line 7", 1.5)
    assert stops[5] == ("M1 at line 9; M60 at line 10", 0)
    assert stops[6] == (None, 0) and stops[7] == ("M100 at line 13", 0)  # before its own line's motion


def test_spindle_coolant_and_tool_words_never_stop_the_motion(tmp_path):
    """LinuxCNC issue #1813: a planner flushed by an S on every line.  They stop nothing here."""
    spec = read(tmp_path, """
        G1 X1 F600 S1000 M3
        G1 X2 S1200
        G1 X3 M8 T4
        G1 X4 M4 M9
        G1 X5 M5 M7
        """)
    assert all(b.stop is None and b.dwell == 0 for b in spec.blocks)


def test_modes_and_stops_survive_convert_and_reading_the_yaml_back(capsys, tmp_path):
    path = tmp_path / "p.ngc"
    path.write_text("G1 X1 F600\nG64 P0.02\nG1 X2\nM6 T1\nG4 P2\nG61.1\nG1 X3 Y1\nG1 X4\n")
    out_file = tmp_path / "p.yaml"
    code, out, err = run_main(capsys, "convert", path, "-o", out_file)
    assert code == 0, err
    again = load_job(str(out_file)).path.blocks
    first = read_gcode(str(path)).blocks
    assert [(b.mode, b.stop, b.dwell) for b in again] == [(b.mode, b.stop, b.dwell) for b in first]
    text = out_file.read_text()
    assert text.count("mode:") == 2  # written where it changes: the mode holds until the next


def test_info_lists_the_programs_stops_in_its_own_words(capsys, tmp_path):
    """A program is planned with look-ahead, read as it runs: info lists its stops (the words that stop it, where,
    and the dwell), not every block."""
    path = tmp_path / "p.ngc"
    path.write_text("G1 X1 F600\nG61\nG1 X2\nM6 T1\nG4 P2\nG61.1\nG1 X3 Y1\nM0\nG1 X4\n")
    code, out, err = run_main(capsys, "info", path, "--json")
    assert code == 0, err
    import json

    stops = json.loads(out)["program_stops"]
    assert stops == {"count": 2, "first": [{"stop": "M6 at line 4; G4 P2 at line 5", "dwell": 2.0},
                                           {"stop": "M0 at line 8", "dwell": 0.0}]}
    code, out, err = run_main(capsys, "info", path)
    assert "program stops    2: M6 at line 4; G4 P2 at line 5 (dwell 2 s); M0 at line 8" in out, out


@pytest.mark.parametrize("text, line, parts", [
    ("G1 X1 F60\nG91 G53 G0 X1\n", 2, ["G53", "incremental"]),
    ("G1 X1 F60\nG2 X2 Y1 R1\nG53 X3\n", 3, ["G53", "G0 or G1"]),
    ("G1 X1 F60\nG28 G1 X2\n", 2, ["G28", "G1", "axis words"]),
    ("G1 X1 F60\nG92\n", 2, ["G92", "X Y Z"]),
    ("G1 X1 F60\nG28 G92 X1\n", 2, ["G28", "G92", "one group"]),
    ("G1 X1 F60\nG4 P-1\n", 2, ["G4 P-1", ">= 0"]),
    ("G1 X1 F60\nM70\n", 2, ["M70", "modal state", "not supported"]),
    ("G1 X1 F60\nG2 X0 Y0 I1" + "0" * 300 + "\n", 2, ["G2", "centre", "beyond the supported range"]),
    ("G1 X1 F60\n#5161=1" + "0" * 300 + "\nG28\n", 3, ["G28", "stored position", "#5161", "beyond"]),
])
def test_misused_codes_are_one_line_naming_the_line(tmp_path, text, line, parts):
    path = tmp_path / "p.ngc"
    path.write_text(text)
    with pytest.raises(SpecError) as info:
        read_gcode(str(path))
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: ") and "\n" not in message
    for part in parts:
        assert part in message


# --------------------------------------------------------------------------- an arc LinuxCNC keeps as a spiral


def test_a_tiny_cam_arc_with_unequal_radii_reads_as_linuxcncs_spiral(tmp_path):
    """CamBam's G3 of chord 0.1 um, radius 0.5 mm, radii to its ends 0.49999 and 0.500013 mm: rs274
    accepts it (the radii differ by 2.3e-5 mm, within 0.028 mm); moving the centre onto the chord's
    bisector would move it 0.115 mm.  It is kept about its written centre, the radius going linearly
    from one to the other, as a B-spline within 1e-9 mm of that spiral, ending exactly at the end."""
    import math

    spec = read(tmp_path, """
        G21 G90 G17
        G0 X0.5 Y0
        G1 X0.49999 Y0 F600
        G3 X0.500012990529 Y0.000097321301 I-0.49999 J0.0
        G1 X0 Y0
        """)
    block = spec.blocks[2]
    assert block.kind == "nurbs"
    assert tuple(block.end) == (0.500012990529, 0.000097321301)
    from nurbsinterp.nurbs import NurbsCurve

    curve = NurbsCurve.from_spec(block.curve)
    u = np.linspace(curve.knots[0], curve.knots[-1], 2001)
    points = curve.evaluate(u)
    r = np.hypot(points[:, 0], points[:, 1])
    theta = np.unwrap(np.arctan2(points[:, 1], points[:, 0]))
    sweep = math.atan2(0.000097321301, 0.500012990529)
    r1 = math.hypot(0.500012990529, 0.000097321301)
    spiral_r = 0.49999 + (r1 - 0.49999) * theta / sweep
    assert np.max(np.abs(r - spiral_r)) <= 1e-9  # on LinuxCNC's spiral (radius linear in the angle)
    assert np.all(np.diff(theta) > 0)  # counter-clockwise throughout
    assert any("spiral" in n and "line 5" in n for n in spec.notes)  # (line 1 is the text's blank)
