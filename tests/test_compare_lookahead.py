"""`compare --tolerance` and `plan --tolerance --precompensate`: a program planned with look-ahead, once per profile
and pre-compensated, through the servo.

Every row of compare is checked against the same case run directly (`simulate --plan --tolerance --profile-type P`),
its commands' deviation against brute force over the program's blocks, and a pre-compensated stream of `plan` against
compare's study of the same method."""
from __future__ import annotations

import json

import numpy as np
import pytest

from test_cli_contract import one_line_error, run_main
from test_lookahead import program, random_program
from test_simulate_lookahead import ROOT, SERVO, brute_contour

PROFILES = ("trapezoidal", "exponential", "bell", "adaptive")
INI = """
[TRAJ]
LINEAR_UNITS = mm
MAX_LINEAR_VELOCITY = 100
[AXIS_X]
MAX_VELOCITY = 100
MAX_ACCELERATION = 1000
[AXIS_Y]
MAX_VELOCITY = 100
MAX_ACCELERATION = 1000
[AXIS_Z]
MAX_VELOCITY = 100
MAX_ACCELERATION = 1000
"""


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A program with real corners and arcs in 3-D, a LinuxCNC INI of its machine, and compare's rows for it."""
    d = tmp_path_factory.mktemp("compare")
    path = program(d, random_program(np.random.default_rng(21), "mixed", n=24))
    ini = d / "machine.ini"
    ini.write_text(INI)
    return {"path": path, "ini": str(ini), "dir": d}


def test_every_row_is_the_case_run_directly(capsys, case):
    code, out, err = run_main(capsys, "compare", case["path"], "--tolerance", "5um", "--servo", SERVO,
                              "--machine", case["ini"], "--json")
    assert code == 0, err
    rows = json.loads(out)
    assert [(r["interpolator"], r["profile"], r["accdec"]) for r in rows] == [
        ("look-ahead", p, "before") for p in PROFILES]
    for r in rows:
        assert r["ff_max"] is None and r["chord_error_max"] is None
        code, out, err = run_main(capsys, "simulate", "--plan", "--job", case["path"], "--tolerance", "5um",
                                  "--servo", SERVO, "--machine", case["ini"], "--profile-type", r["profile"], "--json")
        assert code == 0, err
        direct = json.loads(out)
        for key in ("contour_error_max", "contour_error_rms", "feedrate_error_max", "feedrate_error_rms"):
            assert r[key] == direct[key], (r["profile"], key)
        assert r["motion_time"] == pytest.approx((direct["command_ticks"] - 1) * direct["period"], rel=1e-12)
        assert 1e-4 < r["contour_error_max"]
        assert r["end_gap"] <= 1e-9
    # the exponential's ramps lose what F/Ta's do (README, "One profile, one motion"): across blocks it plans as
    # the trapezoidal; the bell's S-curve and the adaptive schedule plan otherwise
    times = {r["profile"]: r["motion_time"] for r in rows}
    assert times["exponential"] == times["trapezoidal"]
    assert len({times["trapezoidal"], times["bell"], times["adaptive"]}) == 3


@pytest.mark.parametrize("profile", ["trapezoidal", "adaptive"])
def test_the_deviation_is_brute_force_over_the_program(capsys, case, profile):
    """max dev: the commands' largest distance from the program's blocks within reach of each tick's block, as
    brute force over every block gives it; never beyond the tolerance."""
    code, out, err = run_main(capsys, "compare", case["path"], "--tolerance", "5um", "--servo", SERVO,
                              "--machine", case["ini"], "--json")
    assert code == 0, err
    row = next(r for r in json.loads(out) if r["profile"] == profile)
    stream = case["dir"] / f"{profile}.bin"
    code, _, err = run_main(capsys, "plan", case["path"], "--tolerance", "5um", "--machine", case["ini"],
                            "--profile-type", profile, "-q", "--format", "bin", "-o", str(stream))
    assert code == 0, err
    from nurbsinterp.streams import read_stream

    with open(stream, "rb") as fh:
        cols, chunks = read_stream(fh, str(stream))
        rows = np.concatenate(list(chunks))
    cmd = rows[:, [cols.index(a) for a in "xyz"]]
    seeds = rows[:, cols.index("n")] + rows[:, cols.index("u")]
    want = brute_contour(case["path"], cmd, seeds, np.full(cmd.shape[0], 2 * 0.005 + 1e-9))
    assert row["command_deviation_max"] == pytest.approx(want.max(), rel=1e-12, abs=1e-15)
    assert 1e-4 < row["command_deviation_max"] <= 0.005 + 1e-9


def test_precompensated_look_ahead(capsys, case):
    """compare's study with --tolerance, and plan --tolerance --precompensate's stream simulated: the same contour
    error, far below the stream's as planned, down to the tolerance the commands keep."""
    code, out, err = run_main(capsys, "compare", case["path"], "--tolerance", "5um", "--servo", SERVO,
                              "--machine", case["ini"], "--precompensate", "exact", "--json")
    assert code == 0, err
    study = {r["method"]: r for r in json.loads(out)["precompensation"]}
    # the table then follows the commands, which lie within the tolerance of the program: what is left is the
    # blends' own deviation
    assert study["exact"]["contour_error_max"] < 0.1 * study["none"]["contour_error_max"]
    assert study["exact"]["contour_error_max"] <= 0.005 + 1e-4
    stream = case["dir"] / "shaped.bin"
    code, _, err = run_main(capsys, "plan", case["path"], "--tolerance", "5um", "--machine", case["ini"],
                            "--precompensate", SERVO, "--format", "bin", "-o", str(stream))
    assert code == 0, err
    assert "precompensation  exact stable inverse" in err
    code, out, err = run_main(capsys, "simulate", str(stream), "--job", case["path"], "--tolerance", "5um",
                              "--servo", SERVO, "--json")
    assert code == 0, err
    report = json.loads(out)
    assert report["precompensated"] == "exact"
    assert report["contour_error_max"] == pytest.approx(study["exact"]["contour_error_max"], rel=1e-12, abs=1e-15)
    # the precompensated rows keep the plan's block and u: the stream is still measured against the program
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", case["path"], "--tolerance", "5um",
                              "--servo", SERVO, "--machine", case["ini"], "--json")
    assert json.loads(out)["contour_error_max"] == study["none"]["contour_error_max"]


def test_table_and_refusals(capsys, case):
    code, out, err = run_main(capsys, "compare", case["path"], "--tolerance", "5um", "--servo", SERVO,
                              "--machine", case["ini"], "--no-smooth")
    assert code == 0, err
    assert "look-ahead" in out and "max dev um" in out and all(p in out for p in PROFILES)
    # --smooth needs the look-ahead: a program always has it (on the exact path, nothing to smooth), a YAML path not
    assert run_main(capsys, "compare", case["path"], "--smooth", "--servo", SERVO)[0] == 0
    one_line_error(*run_main(capsys, "compare", ROOT / "curves" / "circle.yaml", "--smooth"), "--tolerance")
    one_line_error(*run_main(capsys, "compare", case["path"], "--tolerance", "-2um", "--servo", SERVO),
                   "--tolerance")
    one_line_error(*run_main(capsys, "compare", case["path"], "--tolerance", "5um"), "z")
