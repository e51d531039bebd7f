"""A program's own G64 P: without --tolerance, a G-code program that states a blending tolerance is planned with
look-ahead within it, block by block (cli.common.LookAheadChoice, motion.limits: override_program False).

Checked: a program whose G64 P covers every move plans, to the byte, as --tolerance P does; where P changes, the
commands keep each part's own (brute force over every block, both ways); before any P the corners stop; a program
that states none (or reaches a NURBS block first) is planned as ever; simulate, info and compare follow plan."""
from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.streams import read_stream
from test_cli_contract import one_line_error, run_main
from test_lookahead import program
from test_simulate_lookahead import SERVO, brute_contour

AXES = ["--axis-max-velocity", "x=100,y=100,z=100", "--axis-max-accel", "x=1000,y=1000,z=1000"]


def zigzag(rng, n, heading_spread=0.5):
    """Moves of 0.5 to 3 mm, each heading within *heading_spread* rad of +x: a path that never comes back near
    itself (the window's distance is then the whole program's)."""
    p = np.zeros(3)
    out = []
    for _ in range(n):
        h = rng.uniform(-heading_spread, heading_spread)
        p = p + rng.uniform(0.5, 3.0) * np.array([math.cos(h), math.sin(h), 0.0])
        out.append(f"G1 X{p[0]:.6f} Y{p[1]:.6f}")
    return out


def stream(path, capsys, tmp_path, *args, name="run.bin", axes=True):
    """(columns, rows, stderr, the header's words, the bytes) of plan's binary stream."""
    out = tmp_path / name
    code, _, err = run_main(capsys, "plan", path, *(AXES if axes else ()), "--format", "bin", "-o", str(out), *args)
    assert code == 0, err
    with open(out, "rb") as fh:
        meta = {}
        cols, chunks = read_stream(fh, str(out), meta=meta)
        rows = np.concatenate(list(chunks))
    return cols, rows, err, meta, out.read_bytes()


def test_the_programs_own_p_is_the_tolerance_to_the_byte(capsys, tmp_path):
    lines = ["G21 G90 G64 P0.005 F3000", *zigzag(np.random.default_rng(1), 40), "M2"]
    path = program(tmp_path, "\n".join(lines) + "\n")
    _, own, err, meta, own_bytes = stream(path, capsys, tmp_path, name="own.bin")
    assert meta.get("planner") == "look-ahead"
    assert "within the program's own G64 P (up to 5 um" in err
    _, given, err, _, given_bytes = stream(path, capsys, tmp_path, "--tolerance", "0.005", name="given.bin")
    assert "within 5 um" in err
    # the same stream to the byte, but for the tolerance its header names
    assert own_bytes.replace(b" tolerance=program", b" tolerance=0.005", 1) == given_bytes
    # the tolerance is used: the commands leave the program's corners
    cols = list(read_stream(open(tmp_path / "own.bin", "rb"), "own")[0])
    cmd = own[:, [cols.index(a) for a in "xyz"]]
    assert brute_contour(path, cmd).max() > 1e-3


def test_each_part_keeps_its_own_p(capsys, tmp_path):
    """G64 P0.02 then G64 P0.002: every command within its part's P of the program, every vertex within it of the
    commands (brute force over every block and every tick)."""
    rng = np.random.default_rng(2)
    first, second = zigzag(rng, 20), zigzag(rng, 20)
    # the second part goes on from the first's end: shift it there
    end = [float(w[1:]) for w in first[-1].split()[1:]]
    shifted = []
    for line in second:
        x, y = (float(w[1:]) for w in line.split()[1:])
        shifted.append(f"G1 X{x + end[0]:.6f} Y{y + end[1]:.6f}")
    text = "\n".join(["G21 G90 G64 P0.02 F3000", *first, "G64 P0.002", *shifted, "M2"]) + "\n"
    path = program(tmp_path, text)
    cols, rows, err, _, _ = stream(path, capsys, tmp_path)
    assert "up to 20 um" in err
    cmd = rows[:, [cols.index(a) for a in "xyz"]]
    block = rows[:, cols.index("n")]
    dist = brute_contour(path, cmd)
    switch = len(first)  # the first block in P0.002 (block 0 is the first move)
    # a blend at the joint of the two parts keeps the smaller; beyond it, the second part's own
    late = block >= switch + 1
    assert dist[late].max() <= 0.002 + 1e-9, dist[late].max()
    assert dist[~late].max() <= 0.02 + 1e-9
    assert dist[block < switch - 1].max() > 0.002 + 1e-6  # the first part used its larger P
    # both ways: every vertex of the program within its part's P of the commands (the polyline through them)
    from nurbsinterp.config.gcode import read_gcode

    vertices = np.array([np.pad(b.end, (0, 3 - b.end.shape[0])) for b in read_gcode(path).blocks])
    seg_a, seg_b = cmd[:-1], cmd[1:]
    for i, v in enumerate(vertices):
        d = seg_b - seg_a
        t = np.clip(np.einsum("ij,ij->i", v - seg_a, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300), 0, 1)
        near = np.linalg.norm(seg_a + t[:, None] * d - v, axis=1).min()
        assert near <= (0.002 if i >= switch else 0.02) + 1e-9, (i, near)


def test_before_any_p_corners_stop(capsys, tmp_path):
    """Moves under G64 without P, then G64 P0.01: the corner before the P is passed at rest, on its vertex."""
    path = program(tmp_path, "G21 G90 G64 F3000\nG1 X10\nG1 X10 Y10\nG64 P0.01\nG1 X20 Y10\nG1 X20 Y20\nM2\n")
    cols, rows, _, _, _ = stream(path, capsys, tmp_path)
    cmd = rows[:, [cols.index(a) for a in "xyz"]]
    v = rows[:, cols.index("v")]
    at_corner = np.linalg.norm(cmd - [10.0, 0.0, 0.0], axis=1) <= 1e-9
    assert at_corner.any() and v[at_corner].min() == 0.0
    # the corner in P0.01 is blended: the commands miss its vertex by its blend, within 10 um
    dist = np.linalg.norm(cmd - [20.0, 10.0, 0.0], axis=1).min()
    assert 1e-4 < dist <= 0.01 / math.tan(math.pi / 8) * math.sqrt(2)


def test_a_program_that_states_no_p_is_planned_on_the_exact_path(capsys, tmp_path):
    """No P (and no --tolerance): the look-ahead all the same, every command on the programmed path (brute force),
    the corners passed unblended -- moving where the axes allow it -- and the stream says it was planned so."""
    lines = ["G21 G90 G64 F3000", *zigzag(np.random.default_rng(4), 40, heading_spread=0.05), "G1 Y5", "M2"]
    path = program(tmp_path, "\n".join(lines) + "\n")
    cols, rows, err, meta, _ = stream(path, capsys, tmp_path)
    assert meta.get("planner") == "look-ahead" and meta.get("tolerance") == "program"
    assert "tolerance        none: the exact path" in err and "corners passed on the exact path" in err
    cmd = rows[:, [cols.index(a) for a in "xyz"]]
    assert brute_contour(path, cmd).max() <= 1e-9
    # the shallow kinks are passed moving (the right angle at the end rests)
    assert re.search(r"joints +([1-9]\d*) passed unblended", err) and "1 joints too sharp" in err


def test_a_nurbs_block_before_the_p_is_planned_with_look_ahead(capsys, tmp_path):
    """A P anywhere before the end, NURBS blocks before it: the look-ahead follows them (motion.nurbs_blocks)."""
    path = program(tmp_path, "G21 G90 G64 F3000\nG1 X10\nG5.2 X10 Y0 P1 L3\nX11 Y2 P1\nX13 Y2 P1\nX14 Y0 P1\n"
                   "G5.3\nG64 P0.01\nG1 X20 Y0\nM2\n")
    _, _, err, meta, _ = stream(path, capsys, tmp_path, axes=False)
    assert meta.get("planner") == "look-ahead" and "NURBS            1 blocks followed by" in err


def test_simulate_info_and_compare_follow_plan(capsys, tmp_path):
    lines = ["G21 G90 G64 P0.01 F3000", *zigzag(np.random.default_rng(3), 30), "M2"]
    path = program(tmp_path, "\n".join(lines) + "\n")
    _, _, _, _, _ = stream(path, capsys, tmp_path)
    code, read, err = run_main(capsys, "simulate", str(tmp_path / "run.bin"), "--job", path, "--servo", SERVO,
                               "--json")
    assert code == 0, err
    code, planned, err = run_main(capsys, "simulate", "--plan", "--job", path, "--servo", SERVO, "--json", *AXES)
    assert code == 0, err
    a, b = json.loads(read), json.loads(planned)
    assert a["contour_error_max"] == b["contour_error_max"] and a["ticks"] == b["ticks"]
    # the RMS sums the chunks as they come: a stream read back comes in other chunks
    assert a["contour_error_rms"] == pytest.approx(b["contour_error_rms"], rel=1e-12)
    code, out, err = run_main(capsys, "info", path, "--json", *AXES)
    assert code == 0, err
    facts = json.loads(out)
    assert facts["planner"] == "look-ahead" and facts["tolerance"] is None
    assert facts["tolerance_source"] == "program" and facts["tolerance_max"] == 0.01
    assert facts["ticks"] == b["command_ticks"]
    code, out, err = run_main(capsys, "compare", path, "--servo", SERVO, "--json")
    assert code == 0, err
    assert {r["interpolator"] for r in json.loads(out)} == {"look-ahead"}
    # --tolerance overrides the program's own
    code, out, err = run_main(capsys, "info", path, "--json", "--tolerance", "1um", *AXES)
    assert json.loads(out)["tolerance"] == 0.001 and json.loads(out)["tolerance_source"] == "option"
    # --smooth needs a look-ahead: a program (a path of several blocks) always has one; a curve only with --tolerance
    assert run_main(capsys, "info", path, "--no-smooth", *AXES)[0] == 0
    assert run_main(capsys, "info", program(tmp_path, "G1 X1 F60\nG1 Y1\n", "q.ngc"), "--no-smooth")[0] == 0
    one_line_error(*run_main(capsys, "info", Path(__file__).resolve().parents[1] / "curves" / "circle.yaml",
                             "--no-smooth"), "--tolerance")


def test_acc_dec_after_is_refused_not_ignored(capsys, tmp_path):
    """A program under G64 P is planned with look-ahead, which has no filters after interpolation: --accdec after
    is refused in one line, never dropped."""
    path = program(tmp_path, "G21 G90 G64 P0.01 F3000\nG1 X10\nG1 X10 Y10\nM2\n")
    one_line_error(*run_main(capsys, "plan", path, "--accdec", "after"), "accdec", "after", "look-ahead")
    one_line_error(*run_main(capsys, "plan", path, "--tolerance", "5um", "--accdec", "after"), "accdec")


def test_an_interpolator_asked_for_is_said_unused(capsys, tmp_path):
    path = program(tmp_path, "G21 G90 G64 P0.01 F3000\nG1 X10\nG1 X10 Y10\nM2\n")
    code, _, err = run_main(capsys, "plan", path, "--interpolator", "taylor1", "-o", str(tmp_path / "a.csv"))
    assert code == 0 and "interpolator.method taylor1 is not used" in err, err
    code, _, err = run_main(capsys, "plan", path, "-o", str(tmp_path / "b.csv"))
    assert code == 0 and "is not used" not in err, err
    assert (tmp_path / "a.csv").read_bytes() == (tmp_path / "b.csv").read_bytes()


RASTER = Path(__file__).resolve().parents[1] / "curves" / "raster.ngc"


@pytest.mark.parametrize("text, says", [("5", "taken as 5 mm = 5000 um"), ("0.005", "taken as 0.005 mm = 5 um"),
                                        ("5um", None), ("0.005 mm", None), ("0", None)])
def test_a_tolerance_without_a_unit_is_said_as_taken(capsysbinary, tmp_path, text, says):
    """`--tolerance 5` (the unit forgotten) rounds the corners by up to 5 mm: it is taken as mm, as every length,
    and a line after the run says so with both readings, even under -q; a tolerance with its unit says nothing."""
    from clirun import run_plan

    code, _, err = run_plan(capsysbinary, RASTER, "--tolerance", text, "-q",
                            "-o", tmp_path / "r.csv")
    assert code == 0, err
    if says is None:
        assert err == "", err
    else:
        assert err == f"nurbsinterp: --tolerance {text} has no unit: {says} (write the unit you mean: {text}mm, " \
                      f"{text}um)\n", err
