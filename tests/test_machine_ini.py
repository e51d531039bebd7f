"""A LinuxCNC INI file as the machine's limits (config.machine_ini, `--machine FILE.ini`).

The reference for the file's rules is LinuxCNC's own reader (src/emc/ini/inifile.cc; its tests
tests/inifile/duplicated_keys and comments): the first of a variable wins, a comment is a whole line,
[TRAJ] LINEAR_UNITS is machine units per mm.  Conversions are exact or one rounding (x 25.4), compared
at 4 ulp.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from test_cli_contract import one_line_error, run_main

from nurbsinterp.cli.common import load
from nurbsinterp.config.machine_ini import read_ini, read_machine
from nurbsinterp.errors import SpecError
from nurbsinterp.streams import read_stream

ROOT = Path(__file__).resolve().parents[1]
RASTER = ROOT / "curves" / "raster.ngc"
CIRCLE = ROOT / "curves" / "circle.yaml"
TP_SIM = ROOT.parent / "shared" / "tools" / "linuxcnc-tp" / "tp-sim.ini"

MILL = """
    # a 3-axis mill, mm
    [EMCMOT]
    SERVO_PERIOD = 1000000

    [TRAJ]
    COORDINATES = X Y Z
    LINEAR_UNITS = mm
    MAX_LINEAR_VELOCITY = 150

    [KINS]
    KINEMATICS = trivkins
    JOINTS = 3

    [AXIS_X]
    MAX_VELOCITY = 100
    MAX_ACCELERATION = 1000

    [AXIS_Y]
    MAX_VELOCITY = 90
    MAX_ACCELERATION = 800

    [AXIS_Z]
    MAX_VELOCITY = 50
    MAX_ACCELERATION = 500
"""


def ini(tmp_path, text, name="machine.ini"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text).lstrip("\n"))
    return str(path)


def limits_of(machine):
    return {a.axis: (a.max_velocity.value, a.max_accel.value) for a in machine.axes}


# --------------------------------------------------------------------------- the file's rules

def test_a_mill_reads_as_written(tmp_path):
    m = read_machine(ini(tmp_path, MILL))
    assert limits_of(m) == {"x": (100.0, 1000.0), "y": (90.0, 800.0), "z": (50.0, 500.0)}
    assert m.max_linear_velocity.value == 150.0
    assert m.servo_period.value == 1e-3
    assert m.axes[0].max_velocity.where.endswith("machine.ini:15: [AXIS_X] MAX_VELOCITY")
    assert all(a.max_jerk is None for a in m.axes)


def test_the_first_of_a_duplicated_variable_wins(tmp_path):
    """LinuxCNC's tests/inifile/duplicated_keys: key1=value1, key1=value2 reads value1."""
    m = read_machine(ini(tmp_path, MILL.replace("MAX_VELOCITY = 100\n", "MAX_VELOCITY = 100\n    MAX_VELOCITY = 7\n")))
    assert limits_of(m)["x"] == (100.0, 1000.0)


def test_a_repeated_section_is_merged_its_first_values_kept(tmp_path):
    text = MILL + """
    [AXIS_X]
    MAX_VELOCITY = 5
    MAX_JERK = 20000
    """
    m = read_machine(ini(tmp_path, text))
    assert limits_of(m)["x"] == (100.0, 1000.0)
    assert m.axes[0].max_jerk.value == 20000.0


def test_comments_blank_lines_continuations_and_crlf(tmp_path):
    text = MILL.replace("MAX_VELOCITY = 100",
                        "  ; the X axis\n    MAX_VELOCITY = \\\n       120   # a trailing comment")
    path = ini(tmp_path, text)
    Path(path).write_bytes(Path(path).read_bytes().replace(b"\n", b"\r\n"))
    m = read_machine(path)
    assert limits_of(m)["x"] == (120.0, 1000.0)
    assert m.axes[0].max_velocity.where.endswith(":16: [AXIS_X] MAX_VELOCITY")  # the joined line's first


def test_sections_and_names_are_case_sensitive(tmp_path):
    """[axis_x] is not [AXIS_X], max_velocity not MAX_VELOCITY (LinuxCNC's identifiers are case-sensitive)."""
    text = MILL.replace("[AXIS_Z]", "[axis_z]")
    m = read_machine(ini(tmp_path, text.replace("KINEMATICS = trivkins", "KINEMATICS = genserkins")))
    assert [a.axis for a in m.axes] == ["x", "y"]


@pytest.mark.parametrize("units, scale", [("mm", 1.0), ("metric", 1.0), ("inch", 25.4), ("in", 25.4),
                                          ("Imperial", 25.4), ("1", 1.0), ("0.1", 10.0)])
def test_linear_units_convert_to_mm(tmp_path, units, scale):
    m = read_machine(ini(tmp_path, MILL.replace("LINEAR_UNITS = mm", f"LINEAR_UNITS = {units}")))
    for (v, a), (v0, a0) in zip(limits_of(m).values(), [(100.0, 1000.0), (90.0, 800.0), (50.0, 500.0)]):
        assert v == pytest.approx(v0 * scale, rel=4e-16) and a == pytest.approx(a0 * scale, rel=4e-16)
    assert m.max_linear_velocity.value == pytest.approx(150.0 * scale, rel=4e-16)


def test_offset_av_ratio_leaves_the_planner_its_share(tmp_path):
    """iniaxis.cc: the planner gets (1 - OFFSET_AV_RATIO) of MAX_VELOCITY and MAX_ACCELERATION."""
    m = read_machine(ini(tmp_path, MILL.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = 1000\n"
                                                                           "    OFFSET_AV_RATIO = 0.25")))
    assert limits_of(m)["x"] == (75.0, 750.0)
    assert "OFFSET_AV_RATIO 0.25" in m.axes[0].max_velocity.where


def test_jerk_where_given_zero_is_none(tmp_path):
    text = MILL.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = 1000\n    MAX_JERK = 0")
    text = text.replace("MAX_ACCELERATION = 800", "MAX_ACCELERATION = 800\n    MAX_JERK = 2e4")
    m = read_machine(ini(tmp_path, text))
    assert [None if a.max_jerk is None else a.max_jerk.value for a in m.axes] == [None, 20000.0, None]


def test_trivkins_joints_stand_in_for_missing_axis_limits(tmp_path):
    """coordinates=XYYZ: joints 1 and 2 are Y (a gantry): the lower of theirs; joint 3 is Z."""
    text = """
        [TRAJ]
        LINEAR_UNITS = inch
        [KINS]
        KINEMATICS = trivkins coordinates=XYYZ kinstype=BOTH
        JOINTS = 4
        [AXIS_X]
        MAX_VELOCITY = 2
        [JOINT_0]
        MAX_VELOCITY = 9
        MAX_ACCELERATION = 20
        [JOINT_1]
        MAX_VELOCITY = 3
        MAX_ACCELERATION = 30
        [JOINT_2]
        MAX_VELOCITY = 4
        MAX_ACCELERATION = 25
        [JOINT_3]
        MAX_VELOCITY = 1
        MAX_ACCELERATION = 10
    """
    m = read_machine(ini(tmp_path, text))
    assert limits_of(m) == {"x": (2 * 25.4, 20 * 25.4), "y": (3 * 25.4, 25 * 25.4), "z": (1 * 25.4, 10 * 25.4)}
    assert m.axes[1].max_accel.where.endswith("[JOINT_2] MAX_ACCELERATION")
    assert m.max_linear_velocity is None and m.servo_period is None


def test_a_latin1_comment_is_harmless(tmp_path):
    path = ini(tmp_path, MILL)
    Path(path).write_bytes(b"# Fr\xe4se\n" + Path(path).read_bytes())
    assert limits_of(read_machine(path))["x"] == (100.0, 1000.0)


def test_an_included_file_continues_the_section_in_effect(tmp_path):
    """LinuxCNC reads the lines of every file in order: an include's variables fall in the section open before
    it, and the section it opens runs on after it."""
    ini(tmp_path, "MAX_VELOCITY = 40\nMAX_ACCELERATION = 400\n[AXIS_Y]\n", name="z.inc")
    text = MILL.replace("[AXIS_Z]\n    MAX_VELOCITY = 50\n    MAX_ACCELERATION = 500\n", "[AXIS_Z]\n    #INCLUDE z.inc\n")
    text = text.replace("[AXIS_Y]\n    MAX_VELOCITY = 90\n    MAX_ACCELERATION = 800\n", "")
    m = read_machine(ini(tmp_path, text + "    MAX_VELOCITY = 30\n    MAX_ACCELERATION = 300\n"))
    assert limits_of(m) == {"x": (100.0, 1000.0), "y": (30.0, 300.0), "z": (40.0, 400.0)}


def test_an_include_is_read_in_place(tmp_path):
    ini(tmp_path, "[AXIS_Z]\nMAX_VELOCITY = 40\nMAX_ACCELERATION = 400\n", name="z.inc")
    m = read_machine(ini(tmp_path, MILL.replace("[AXIS_Z]", "#INCLUDE z.inc\n    [AXIS_Z]")))
    assert limits_of(m)["z"] == (40.0, 400.0)
    assert "z.inc:2: [AXIS_Z] MAX_VELOCITY" in m.axes[2].max_velocity.where


def test_read_ini_keeps_where_each_value_was(tmp_path):
    sections = read_ini(ini(tmp_path, MILL))
    entry = sections["TRAJ"]["LINEAR_UNITS"]
    assert (entry.value, entry.line) == ("mm", 7)


# --------------------------------------------------------------------------- refusals: one line each

REFUSALS = [
    (lambda t: t.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = abc"),
     "machine.ini:16: [AXIS_X] MAX_ACCELERATION = 'abc' is not a number"),
    (lambda t: t.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = 1000 mm/s^2"), "'1000 mm/s^2' is not a number"),
    (lambda t: t.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = nan"), "'nan' is not a number"),
    (lambda t: t.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = 1e999"), "'1e999' is too large"),
    (lambda t: t.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION ="), "MAX_ACCELERATION = '' is not a number"),
    (lambda t: t.replace("MAX_VELOCITY = 90", "MAX_VELOCITY = 0"),
     "machine.ini:19: [AXIS_Y] MAX_VELOCITY = '0' must be > 0"),
    (lambda t: t.replace("MAX_VELOCITY = 90", "MAX_VELOCITY = -90"), "[AXIS_Y] MAX_VELOCITY = '-90' must be > 0"),
    (lambda t: t.replace("MAX_ACCELERATION = 500", "MAX_ACCELERATION = 500\n    MAX_JERK = -1"),
     "[AXIS_Z] MAX_JERK = '-1' must be > 0"),
    (lambda t: t.replace("MAX_ACCELERATION = 500", "MAX_ACCELERATION = 500\n    OFFSET_AV_RATIO = 0.95"),
     "[AXIS_Z] OFFSET_AV_RATIO = '0.95' must be between 0 and 0.9"),
    (lambda t: t.replace("LINEAR_UNITS = mm", "LINEAR_UNITS = furlong"),
     "[TRAJ] LINEAR_UNITS = 'furlong' is not a unit"),
    (lambda t: t.replace("LINEAR_UNITS = mm", "LINEAR_UNITS = 0"), "[TRAJ] LINEAR_UNITS = '0' must be > 0"),
    (lambda t: t.replace("LINEAR_UNITS = mm", ""), "machine.ini: has no [TRAJ] LINEAR_UNITS"),
    (lambda t: t.replace("MAX_LINEAR_VELOCITY = 150", "MAX_LINEAR_VELOCITY = fast"),
     "[TRAJ] MAX_LINEAR_VELOCITY = 'fast' is not a number"),
    (lambda t: t.replace("SERVO_PERIOD = 1000000", "SERVO_PERIOD = -1"), "[EMCMOT] SERVO_PERIOD = '-1' must be > 0"),
    (lambda t: t.replace("[AXIS_X]", "[AXIS_X"), "machine.ini:14: section header '[AXIS_X' has no ']'"),
    (lambda t: t.replace("[AXIS_X]", "[ ]"), "section header '[ ]' names no section"),
    (lambda t: t.replace("MAX_VELOCITY = 100", "MAX_VELOCITY 100"),
     "machine.ini:15: 'MAX_VELOCITY 100' is not NAME = VALUE"),
    (lambda t: t.replace("MAX_VELOCITY = 100", "= 100"), "'= 100' has no name before '='"),
    (lambda t: "MACHINE = mill\n" + t, "machine.ini:1: MACHINE is given before any [SECTION]"),
    (lambda t: t + "    MAX_VELOCITY = \\", "the last line ends in a continuation"),
    (lambda t: t.replace("[AXIS_Z]", "#INCLUDE missing.inc\n    [AXIS_Z]"), "missing.inc: cannot read"),
    (lambda t: t.replace("[AXIS_Z]", "#INCLUDE machine.ini\n    [AXIS_Z]"), "includes itself"),
    (lambda t: t.replace("[AXIS_Z]", "#INCLUDE\n    [AXIS_Z]"), "#INCLUDE names no file"),
    # an axis without its limits, on kinematics whose joints are not its axes
    (lambda t: t.replace("MAX_VELOCITY = 50\n", "").replace("trivkins", "genserkins"),
     "[AXIS_Z] has no MAX_VELOCITY (LinuxCNC would use 1 unit/s), and"),
    # trivkins, but the joint lacks it too
    (lambda t: t.replace("MAX_VELOCITY = 50\n", ""),
     "neither [AXIS_Z] nor [JOINT_2] (trivkins' joint of Z) gives MAX_VELOCITY"),
    (lambda t: t.replace("JOINTS = 3", "JOINTS = 2.5"), "[KINS] JOINTS = '2.5' must be a whole number >= 1"),
]


@pytest.mark.parametrize("edit, message", REFUSALS, ids=[m for _, m in REFUSALS])
def test_every_malformed_thing_is_one_line(tmp_path, capsys, edit, message):
    path = ini(tmp_path, edit(textwrap.dedent(MILL).lstrip("\n")).replace("\n    ", "\n"))
    with pytest.raises(SpecError) as info:
        read_machine(path)
    assert message in str(info.value) and "\n" not in str(info.value)
    # the command line: exit 2, that one line, no traceback
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000",
                              "--machine", path)
    one_line_error(code, out, err, message)


@pytest.mark.parametrize("text, message", [
    ("[EMC]\nMACHINE = lathe\n", "machine.ini: has no [AXIS_X], [AXIS_Y] or [AXIS_Z] section"),
    ("[TRAJ]\nLINEAR_UNITS = mm\n[AXIS_0]\nMAX_VELOCITY = 1\n", "[AXIS_0] is LinuxCNC 2.7's joint section"),
    ("", "has no [AXIS_X]"),
])
def test_a_file_with_no_axis_limits_is_refused(tmp_path, capsys, text, message):
    path = tmp_path / "machine.ini"
    path.write_text(text.replace("[EMC]", "[TRAJ]\nLINEAR_UNITS = mm\n[EMC]"))
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000",
                              "--machine", path)
    one_line_error(code, out, err, message)


def test_a_missing_file_or_a_directory_is_one_line(tmp_path, capsys):
    for path, message in ((tmp_path / "nope.ini", "nope.ini: cannot read: No such file"),
                          (tmp_path, "is a directory, not a LinuxCNC INI file")):
        code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000",
                                  "--machine", path)
        one_line_error(code, out, err, message)


def test_binary_junk_is_one_line(tmp_path, capsys):
    path = tmp_path / "machine.ini"
    path.write_bytes(b"[TRAJ]\nLINEAR_UNITS = mm\n\xff\xfe\x00junk\n")
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--max-accel", "1000",
                              "--machine", path)
    one_line_error(code, out, err, "machine.ini:3: ", "is not NAME = VALUE")


# --------------------------------------------------------------------------- the job fields, precedence

def axes_of(spec):
    return {axis: (v, a) for axis, v, a, _ in spec.profile.axes}


def test_the_ini_sets_the_axes_and_the_rapid_feedrate(tmp_path):
    spec = load(str(CIRCLE), profile_type="adaptive", machine=ini(tmp_path, MILL))
    assert axes_of(spec) == {"x": (100.0, 1000.0), "y": (90.0, 800.0), "z": (50.0, 500.0)}
    assert spec.profile.rapid_feedrate == 150.0


def test_options_win_over_the_ini_which_wins_over_the_job_file(tmp_path):
    job = tmp_path / "job.yaml"
    job.write_text(CIRCLE.read_text().split("profile:")[0] + textwrap.dedent("""
        profile:
          type: adaptive
          max_accel: 1000
          rapid_feedrate: 50
          axes:
            x: {max_velocity: 10, max_accel: 11}
    """))
    path = ini(tmp_path, """
        [TRAJ]
        LINEAR_UNITS = mm
        MAX_LINEAR_VELOCITY = 150
        [AXIS_Z]
        MAX_VELOCITY = 50
        MAX_ACCELERATION = 500
    """)
    spec = load(str(job), machine=path)
    assert axes_of(spec) == {"x": (10.0, 11.0), "z": (50.0, 500.0)}  # the file's x: the INI has no [AXIS_X]
    assert spec.profile.rapid_feedrate == 150.0  # the INI over the file
    spec = load(str(job), machine=ini(tmp_path, MILL), axis_max_velocity="x=60", rapid_feedrate="70")
    assert axes_of(spec) == {"x": (60.0, 1000.0), "y": (90.0, 800.0), "z": (50.0, 500.0)}
    assert spec.profile.rapid_feedrate == 70.0


def test_a_refusal_names_the_ini_line_a_value_came_from(tmp_path, capsys):
    """The trapezoidal profile ignores per-axis limits (as with --axis-max-*): the INI's lines are named."""
    code, out, err = run_main(capsys, "info", CIRCLE, "--machine", ini(tmp_path, MILL))
    one_line_error(code, out, err, "machine.ini:15: [AXIS_X] MAX_VELOCITY x=100.0", "refused: the trapezoidal")


def test_unapplied_jerk_and_servo_period_are_said(tmp_path, capsys):
    text = MILL.replace("MAX_ACCELERATION = 1000", "MAX_ACCELERATION = 1000\n    MAX_JERK = 20000")
    path = ini(tmp_path, text.replace("SERVO_PERIOD = 1000000", "SERVO_PERIOD = 500000"))
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--machine", path)
    assert code == 0, err
    assert "machine.ini:17: [AXIS_X] MAX_JERK = 20000 mm/s^3 is not applied" in err
    assert "machine.ini:3: [EMCMOT] SERVO_PERIOD = 0.5 ms is not applied: the stream's period is 1 ms" in err
    code, out, err = run_main(capsys, "info", CIRCLE, "--profile-type", "adaptive", "--machine", path,
                              "--period", "0.5ms")
    assert code == 0 and "SERVO_PERIOD" not in err, err


# --------------------------------------------------------------------------- the bundled and shared files

@pytest.mark.skipif(not TP_SIM.exists(), reason="../shared/tools/linuxcnc-tp/tp-sim.ini is not here")
def test_the_linuxcnc_measuring_machine():
    """The INI LinuxCNC's planner was measured with (issue 29's table): 100 mm/s and 1 000 mm/s² per axis."""
    m = read_machine(TP_SIM)
    assert limits_of(m) == {axis: (100.0, 1000.0) for axis in "xyz"}
    assert m.max_linear_velocity.value == 100.0 and m.servo_period.value == 1e-3
    assert m.mm_per_unit == 1.0


def stream(capsys, tmp_path, name, *options):
    out = tmp_path / name
    code, _, err = run_main(capsys, "plan", RASTER, "--tolerance", "5um", "--profile-type", "adaptive", "-q",
                            "--format", "bin", "-o", out, *options)
    assert code == 0, err
    return out.read_bytes()


def test_the_plan_with_an_ini_is_the_plan_with_the_options(capsys, tmp_path):
    """Byte for byte: the INI's limits are the --axis-max-* options' (and MAX_LINEAR_VELOCITY --rapid-feedrate's)."""
    text = MILL.replace("MAX_VELOCITY = 90", "MAX_VELOCITY = 100").replace("MAX_ACCELERATION = 800",
                                                                           "MAX_ACCELERATION = 1000")
    options = ["--axis-max-velocity", "x=100,y=100,z=50", "--axis-max-accel", "x=1000,y=1000,z=500"]
    with_ini = stream(capsys, tmp_path, "ini.bin", "--machine",
                      ini(tmp_path, text.replace("MAX_LINEAR_VELOCITY = 150", "")))
    assert with_ini == stream(capsys, tmp_path, "options.bin", *options)
    # G0 at 30 mm/s, below every axis' limit: a stream of its own
    slow = text.replace("MAX_LINEAR_VELOCITY = 150", "MAX_LINEAR_VELOCITY = 30")
    with_rapid = stream(capsys, tmp_path, "ini2.bin", "--machine", ini(tmp_path, slow, name="m2.ini"))
    assert with_rapid == stream(capsys, tmp_path, "options2.bin", *options, "--rapid-feedrate", "30")
    assert with_rapid != with_ini
    with open(tmp_path / "ini2.bin", "rb") as fh:
        columns, chunks = read_stream(fh)
        assert sum(len(c) for c in chunks) > 1000  # a real plan, not two empty streams


@pytest.mark.skipif(not TP_SIM.exists(), reason="../shared/tools/linuxcnc-tp/tp-sim.ini is not here")
def test_the_measuring_machine_plans_as_the_benchmark_options(capsys, tmp_path):
    """README's benchmark options (the harness machine's limits spelled out) and its INI give one stream."""
    options = ["--axis-max-velocity", "x=100,y=100,z=100", "--axis-max-accel", "x=1000,y=1000,z=1000",
               "--rapid-feedrate", "6000mm/min"]
    assert stream(capsys, tmp_path, "ini.bin", "--machine", TP_SIM) == stream(capsys, tmp_path, "opt.bin", *options)


def test_a_bad_ini_beside_a_g_code_program_names_the_ini_alone(tmp_path, capsys):
    """A G-code program is read once to look for its own G64 P; an INI file's fault found while loading it is
    the INI file's line, not prefixed with the program's name."""
    path = ini(tmp_path, textwrap.dedent(MILL).lstrip("\n").replace("MAX_VELOCITY = 90", "MAX_VELOCITY = fast"))
    for command in ("info", "plan"):
        code, out, err = run_main(capsys, command, ROOT / "curves" / "pocket.ngc", "--machine", path,
                                  *(["-o", tmp_path / "never.csv"] if command == "plan" else []))
        one_line_error(code, out, err, "[AXIS_Y] MAX_VELOCITY = 'fast' is not a number")
        assert err.startswith(f"nurbsinterp: {path}:"), err
    assert not (tmp_path / "never.csv").exists()
