"""The plan summary of a G-code program in a machinist's terms (issue 49, Deliver 4): the program's own feeds,
the tolerance as taken, the motion time of cutting apart from rapids, and one line of what to do when the plan is
slow or rough.  Each figure is checked against the program or the stream itself, never against a printed one.
"""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from clirun import in_process, read_trace, run_main

ROOT = Path(__file__).resolve().parents[1]
POCKET = ROOT / "curves" / "pocket.ngc"
RASTER = ROOT / "curves" / "raster.ngc"
SQUARE = ROOT / "curves" / "square.yaml"
MILL = ROOT / "examples" / "linuxcnc" / "mill.ini"


def line(err: str, label: str) -> str:
    found = [s for s in err.splitlines() if s.startswith(f"  {label} ")]
    assert len(found) == 1, err
    return " ".join(found[0].split()[len(label.split()):])


def program_feeds(path: Path) -> list[float]:
    """The F words of a program (mm/min): what a machinist wrote."""
    text = re.sub(r"\(.*?\)|;.*", "", path.read_text())
    return [float(f) for f in re.findall(r"F\s*([0-9.]+)", text, flags=re.I)]


@pytest.fixture(scope="module")
def pocket(tmp_path_factory):
    """pocket.ngc for the bundled LinuxCNC machine, blended within 10 um: (stderr, the stream, its columns)."""
    where = tmp_path_factory.mktemp("pocket")
    code, _, err = in_process(["plan", POCKET, "--machine", MILL, "--tolerance", "10um", "-o", where / "p.csv"])
    assert code == 0, err
    header, stream = read_trace(where / "p.csv")
    return err, stream, header


def test_the_feeds_are_the_programs_own(pocket):
    err, _, _ = pocket
    feeds = program_feeds(POCKET)
    assert line(err, "feeds").startswith(f"{min(feeds):g} to {max(feeds):g} mm/min (the program's own, on 9 of 9 "
                                         "feed moves); 4 rapids (G0)")
    assert "feedrate (default)" not in err  # a default the program did not use is not shown as if it were


def test_the_motion_time_of_cutting_and_of_rapids_come_from_the_stream(pocket):
    err, stream, header = pocket
    T = 1e-3
    rapid = stream[:, header.index("rapid")] > 0.5
    text = line(err, "motion time")
    total, cutting, rapids = (float(x) for x in re.match(r"([0-9.]+) s at T = 1 ms: cutting ([0-9.]+) s, rapids "
                                                         r"\(G0\) ([0-9.]+) s$", text).groups())
    assert rapids == pytest.approx(rapid.sum() * T, abs=5e-7 * max(1.0, rapids))  # (6 significant digits)
    assert cutting + rapids == pytest.approx(total, abs=1e-5)
    assert total == pytest.approx((stream.shape[0] - 1) * T, abs=1e-5)


def test_the_tolerance_as_taken_with_its_unit_and_source(pocket):
    err, _, _ = pocket
    assert line(err, "tolerance") == "10 um = 0.01 mm (--tolerance; over any G64 P the program states)"


def test_what_to_do_names_the_ramp_that_holds_the_machine_back(pocket, capsys, tmp_path):
    """A machine with limits of its own is planned to them: a profile's ramp (F/Ta, 200 mm/s^2 here) binds only
    where the profile is chosen (its type or accel_time given) -- and then the summary says it holds the machine
    back, and how to lift it."""
    err, _, _ = pocket
    assert "profile's ramp" not in line(err, "what to do") and "profile's ramp" not in line(err, "limits")
    code, _, ramped = run_main(capsys, "plan", POCKET, "--machine", MILL, "--tolerance", "10um", "--accel-time",
                               "0.5", "-o", tmp_path / "a.csv")
    assert code == 0, ramped
    assert line(ramped, "what to do") == (
        "the acceleration along the path is the trapezoidal profile's ramp, 200 mm/s^2, below the axes' 500 mm/s^2: "
        "--profile-type adaptive, or the default profile (no profile type, no accel_time), plans to the machine's "
        "own limits; a shorter accel_time raises the ramp")
    # and the advice holds: the machine's own limits plan it faster
    before = float(line(ramped, "motion time").split()[0])
    after = float(line(err, "motion time").split()[0])
    assert after < 0.95 * before


@pytest.mark.parametrize("options", [[], ["--tolerance", "0"]], ids=["no option", "--tolerance 0"])
def test_what_to_do_on_the_exact_path(capsys, tmp_path, options):
    """No tolerance (none given, no G64 P in the program): the corners are passed on the exact path, moving where
    the axes allow it, and the summary says that a tolerance would blend them."""
    code, _, err = run_main(capsys, "plan", RASTER, *options, "-o", tmp_path / "r.csv")
    assert code == 0, err
    joints = re.search(r"joints +(\d+) passed unblended .*; (\d+) stops .*; (\d+) joints too sharp", err)
    passed, stops, sharp = (int(g) for g in joints.groups())
    assert passed > 500 and 0 < sharp <= stops < 20  # the row ends' right angles rest; the rows' kinks do not
    assert line(err, "what to do").startswith(f"{passed + sharp} corners passed on the exact path ({sharp} of them "
                                              "at rest, too sharp to pass moving): --tolerance (e.g. 10um")
    assert line(err, "tolerance").startswith("0 um" if options else "none: the exact path")
    code, _, err = run_main(capsys, "plan", SQUARE, "-o", tmp_path / "s.csv")
    assert code == 0, err
    # a YAML path is planned with look-ahead too: on the exact path, its own tolerance named in its own words
    assert line(err, "what to do") == ("3 corners passed on the exact path (3 of them at rest, too sharp to pass "
                                       "moving): --tolerance (e.g. 10um; or profile.corner_tolerance in the job) "
                                       "would blend them within it")
    assert line(err, "tolerance") == "none: the exact path (the job states no tolerance)"
    code, _, err = run_main(capsys, "plan", ROOT / "curves" / "circle.yaml", "-o", tmp_path / "c.csv")
    assert code == 0 and "what to do" not in err  # one motion from rest to rest: nothing to say


def test_info_json_carries_the_same_figures(capsys):
    code, out, err = run_main(capsys, "info", POCKET, "--machine", MILL, "--tolerance", "10um", "--json")
    assert code == 0, err
    doc = json.loads(out)
    feeds = program_feeds(POCKET)
    assert doc["feeds"]["lowest"] * 60 == pytest.approx(min(feeds), rel=1e-12)
    assert doc["feeds"]["highest"] * 60 == pytest.approx(max(feeds), rel=1e-12)
    assert (doc["feeds"]["moves"], doc["feeds"]["defaulted"], doc["feeds"]["rapid_moves"]) == (9, 0, 4)
    assert doc["cutting_time"] + doc["rapid_time"] == pytest.approx(doc["motion_time"], rel=1e-12)
    assert 0 < doc["rapid_time"] < doc["cutting_time"]


def test_what_to_do_says_nothing_wrong(capsys, tmp_path):
    """Under acc/dec after the filter goes through the corners (nothing stops: no "stops at N joints"); an adaptive
    profile whose accel_time was given a ramp of its own is told to drop it, not to use the adaptive profile."""
    code, _, err = run_main(capsys, "plan", SQUARE, "--accdec", "after", "-o", tmp_path / "s.csv")
    assert code == 0 and "stops at" not in err, err
    code, _, err = run_main(capsys, "plan", POCKET, "--machine", MILL, "--tolerance", "10um", "--profile-type",
                            "adaptive", "--accel-time", "1s", "-o", tmp_path / "p.csv")
    assert code == 0, err
    hint = line(err, "what to do")
    assert "without accel_time (the job's or --accel-time) it plans to the machine's own limits" in hint, hint
    assert "--profile-type adaptive" not in hint, hint


def test_what_to_do_about_one_corner_is_worded_for_one(capsys, tmp_path):
    """One right angle on the exact path: "1 corner passed on the exact path (at rest, ...) ... blend it", not
    "1 corners ... 1 of them ... them"."""
    path = tmp_path / "one.ngc"
    path.write_text("G21 G90\nG1 X10 F600\nG1 X10 Y10\nM2\n")
    code, _, err = run_main(capsys, "plan", path, "-o", tmp_path / "one.csv")
    assert code == 0, err
    assert line(err, "what to do") == ("1 corner passed on the exact path (at rest, too sharp to pass moving): "
                                       "--tolerance (e.g. 10um; or G64 P in the program) would blend it within it")


def test_a_profiles_corner_tolerance_blends_the_blocks_that_state_none(capsys, tmp_path):
    """profile.corner_tolerance is the tolerance of the blocks whose program states no G64 P (a YAML path's, whose
    blocks state no mode.tolerance): their corners are blended within it, and the summary says where it came from;
    a block's own G64 P still wins."""
    plain = tmp_path / "plain.ngc"
    plain.write_text("G21 G90\nG1 X10 F600\nG1 Y10\nG1 X0\nM2\n")
    code, _, err = run_main(capsys, "plan", plain, "--corner-tolerance", "10um", "-o", tmp_path / "p.csv")
    assert code == 0, err
    assert line(err, "tolerance") == ("the program's own G64 P, block by block: up to 10 um "
                                      "(profile.corner_tolerance, 10 um, where it states none)")
    assert line(err, "segments").endswith("2 corner blends (two halves each: 4 arcs)")
    own = tmp_path / "own.ngc"
    own.write_text("G21 G90 G64 P0.002\nG1 X10 F600\nG1 Y10\nG1 X0\nM2\n")
    code, _, err = run_main(capsys, "plan", own, "--corner-tolerance", "10um", "-o", tmp_path / "o.csv")
    assert code == 0, err
    assert line(err, "tolerance").startswith("the program's own G64 P, block by block: up to 2 um ")
