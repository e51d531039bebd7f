"""benchmarks/cam.py: the generated CAM programs (issue 29) and the measures of a plan stream.

The programs are checked against their definitions by brute force (the analytic spiral sampled densely
against each chord; the surface at every raster point), and read by LinuxCNC's rs274 where it is
installed.  The measures are held to naive references: point-to-segment distances by a plain Python
loop over every segment, finite differences of a cubic on a grid where every value is exact.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))
import cam  # noqa: E402  (benchmarks/cam.py)
import rs274ref  # noqa: E402  (tests/rs274ref.py)

from nurbsinterp.config.gcode import read_gcode  # noqa: E402

HALF_DIGIT = 0.5e-6  # mm: the programs' 6 decimals round each coordinate by at most this
G1_POINT = re.compile(r"^G1 X(-?\d+\.\d{6}) Y(-?\d+\.\d{6})(?: Z(-?\d+\.\d{6}))?(?: F\d+)?$")


def g1_points(text: str) -> np.ndarray:
    """The end points of the program's G1 lines that carry X and Y, as printed."""
    rows = []
    for line in text.splitlines():
        m = G1_POINT.match(line)
        if m:
            rows.append([float(v) for v in m.groups() if v is not None])
    return np.array(rows)


def spiral_xy(theta):
    r = cam.SPIRAL_R0 + cam.SPIRAL_PITCH * theta / (2 * math.pi)
    return np.stack([r * np.cos(theta), r * np.sin(theta)], axis=-1)


def chord_sagitta(a, b, theta0, theta1, samples=2001):
    """The largest distance from the spiral between theta0 and theta1 to the line through a, b (dense samples)."""
    p = spiral_xy(np.linspace(theta0, theta1, samples))
    d = b - a
    normal = np.array([-d[1], d[0]]) / np.hypot(*d)
    return np.abs((p - a) @ normal).max()


# --------------------------------------------------------------------------- the spiral

@pytest.mark.parametrize("first, count", [(0, 300), (9_700, 300)])
def test_spiral_chords_within_one_micrometre_of_the_spiral(first, count):
    """Each chord, as printed, within 1 µm of the analytic spiral between its end angles, and not needlessly
    short: at least 0.99 µm, the bound the step is taken from being that tight."""
    angles = cam.spiral_angles(first + count, cam.SAGITTA - cam.PRINTED)  # as spiral_program takes them
    exact = spiral_xy(np.array(angles))
    printed = np.round(exact * 1e6) / 1e6  # as the program prints them
    worst, least = 0.0, math.inf
    for i in range(first, first + count):
        # sampling misses the peak by ~(step/2000)² of the curvature: far below a nanometre here
        s = chord_sagitta(printed[i], printed[i + 1], angles[i], angles[i + 1])
        worst, least = max(worst, s), min(least, chord_sagitta(exact[i], exact[i + 1], angles[i], angles[i + 1]))
    assert worst <= cam.SAGITTA
    assert least >= 0.99 * cam.SAGITTA


def test_spiral_program_text_and_blocks():
    text = cam.spiral_program(1000)
    lines = text.splitlines()
    assert lines[1] == "G21 G90 G64"
    assert lines[2] == "G0 X5.000000 Y0.000000"
    assert lines[3].endswith(" F3000") and lines[-1] == "M2"
    assert sum(line.startswith("G1 ") for line in lines) == 1000
    assert not re.search(r"\d[eE][-+]?\d", text)  # no exponent
    points = g1_points(text)
    angles = np.array(cam.spiral_angles(1000, cam.SAGITTA - cam.PRINTED))
    assert np.abs(points - spiral_xy(angles[1:])).max() <= HALF_DIGIT
    r_end = cam.spiral_radius(angles[-1])
    assert 7.5 < r_end < 8.2  # 1 000 chords of ~0.2 mm: about 5.6 turns


def test_spiral_program_read_as_blocks(tmp_path):
    path = tmp_path / "spiral_100.ngc"
    path.write_text(cam.spiral_program(100))
    blocks = read_gcode(str(path)).blocks
    assert len(blocks) == 101  # the G0 to the start, then the chords
    assert blocks[0].rapid and not any(b.rapid for b in blocks[1:])
    assert all(b.feedrate == pytest.approx(50.0) for b in blocks[1:])
    assert len(blocks[0].start) == 2  # flat: read as a 2-D path


# --------------------------------------------------------------------------- the raster

@pytest.mark.parametrize("blocks, rows", [(1000, 5), (10000, 50), (50, 1)])
def test_raster_points_on_the_surface_in_zigzag_rows(blocks, rows):
    text = cam.raster_program(blocks)
    lines = text.splitlines()
    assert lines[1:4] == ["G21 G90 G64", "G0 X0 Y0 Z5", "G1 Z0.000000 F2000"]
    assert lines[-2:] == ["G0 Z5", "M2"]
    assert cam.raster_surface(0.0, 0.0) == 0.0  # the plunge ends on the surface
    points = g1_points(text)
    assert len(points) == rows * 200 + (rows - 1)  # the moves of the rows and the step-overs
    z = 2 * np.sin(points[:, 0] / 7) * np.cos(points[:, 1] / 5)
    assert np.abs(points[:, 2] - z).max() <= HALF_DIGIT
    k = 0
    for row in range(rows):
        if row:  # the step-over: 0.5 mm in y at the row's end
            assert points[k, 0] == points[k - 1, 0] and points[k, 1] - points[k - 1, 1] == pytest.approx(0.5)
            k += 1
        run = points[k:k + 200]
        assert np.all(run[:, 1] == row * 0.5)
        steps = np.diff(np.concatenate([[points[k - 1, 0] if k else 0.0], run[:, 0]]))
        assert np.allclose(steps, 0.2 if row % 2 == 0 else -0.2, atol=2 * HALF_DIGIT)
        k += 200
    assert k == len(points)


def test_raster_program_read_as_blocks(tmp_path):
    path = tmp_path / "raster_1000.ngc"
    path.write_text(cam.raster_program(1000))
    blocks = read_gcode(str(path)).blocks
    assert len(blocks) == 1 + 1005 + 1  # G0 down to Z5, the 1 005 G1, the retract
    assert [b.rapid for b in (blocks[0], blocks[1], blocks[-1])] == [True, False, True]
    assert sum(not b.rapid for b in blocks) == 1005


@pytest.mark.skipif(rs274ref.RS274 is None, reason="LinuxCNC's rs274 is not installed")
@pytest.mark.parametrize("kind", ["spiral", "raster"])
def test_linuxcnc_reads_the_programs(tmp_path, kind):
    """LinuxCNC's interpreter runs the programs (no nested comment, no unknown word) to the same moves."""
    path = tmp_path / f"{kind}.ngc"
    path.write_text(cam.GENERATORS[kind](400))
    moves = rs274ref.without_zero_length(rs274ref.read_moves(path))
    blocks = read_gcode(str(path)).blocks
    assert len(moves) == len(blocks)
    for move, block in zip(moves, blocks):
        end = np.zeros(3)
        end[:len(block.end)] = block.end
        assert np.abs(np.array(move.end) - end).max() <= 1e-4  # rs274 prints 4 decimals


def test_write_programs_cli(tmp_path):
    assert cam.main(["write", str(tmp_path), "--blocks", "200,400"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["raster_200.ngc", "raster_400.ngc", "spiral_200.ngc",
                                                           "spiral_400.ngc"]
    assert (tmp_path / "spiral_400.ngc").read_text() == cam.spiral_program(400)


# --------------------------------------------------------------------------- the deviation

def naive_segment_distance(p, a, b):
    """Distance from point p to segment ab, one at a time in plain floats: the reference."""
    d = [bi - ai for ai, bi in zip(a, b)]
    length2 = sum(c * c for c in d)
    s = 0.0 if length2 == 0 else sum((pi - ai) * c for pi, ai, c in zip(p, a, d)) / length2
    s = min(1.0, max(0.0, s))
    return math.sqrt(sum((pi - ai - s * c) ** 2 for pi, ai, c in zip(p, a, d)))


def naive_deviation(points, pos):
    """(forward, backward) over every segment, by plain loops."""
    forward = max(min(naive_segment_distance(c, points[j], points[j + 1]) for j in range(len(points) - 1))
                  for c in pos)
    if len(pos) == 1:
        backward = max(math.dist(p, pos[0]) for p in points)
    else:
        backward = max(min(naive_segment_distance(p, pos[k], pos[k + 1]) for k in range(len(pos) - 1))
                       for p in points)
    return forward, backward


def random_case(seed, segments=12, dim=2, ticks_per_block=5, noise=0.05, repeat=False):
    """A random polyline and a stream that follows it with noise, ticks labelled by their block."""
    rng = np.random.default_rng(seed)
    points = np.cumsum(rng.normal(0.0, 1.0, (segments + 1, dim)), axis=0)
    if repeat:  # a zero-length block and a still tick
        points[3] = points[2]
    pos, block = [], []
    for j in range(segments):
        for s in np.linspace(0.0, 1.0, ticks_per_block, endpoint=False):
            pos.append(points[j] + s * (points[j + 1] - points[j]) + rng.normal(0.0, noise, dim))
            block.append(j)
    pos.append(points[-1])
    block.append(segments - 1)
    if repeat:
        pos.insert(4, pos[4])
        block.insert(4, block[4])
    return points, np.array(pos), np.array(block)


def rounding(points, pos):
    """How far two ways of computing a point-to-segment distance may differ by rounding alone: a few dozen
    operations on coordinates of size L, each off by at most half an ulp, ε·L each."""
    return 64 * np.finfo(float).eps * max(np.abs(points).max(), np.abs(pos).max(), 1.0)


def run_deviation(points, pos, block, window, chunk):
    dev = cam.Deviation(points, window)
    for i in range(0, len(pos), chunk):
        dev.add(pos[i:i + chunk], block[i:i + chunk])
    return dev


@given(seed=st.integers(0, 2 ** 32 - 1), dim=st.sampled_from([2, 3]), chunk=st.integers(1, 40),
       noise=st.sampled_from([0.0, 1e-3, 0.05, 0.5]), repeat=st.booleans())
def test_deviation_equals_brute_force_with_a_window_over_everything(seed, dim, chunk, noise, repeat):
    points, pos, block = random_case(seed, dim=dim, noise=noise, repeat=repeat)
    dev = run_deviation(points, pos, block, window=len(points), chunk=chunk)
    forward, backward = naive_deviation(points.tolist(), pos.tolist())
    slack = rounding(points, pos)
    assert dev.forward == pytest.approx(forward, rel=0, abs=slack)
    assert dev.backward == pytest.approx(backward, rel=0, abs=slack)
    assert cam.deviation_brute_force(points, pos) == pytest.approx((forward, backward), rel=0, abs=slack)


@given(seed=st.integers(0, 2 ** 32 - 1), window=st.integers(0, 3), chunk=st.integers(1, 40),
       noise=st.sampled_from([0.0, 1e-3, 0.05, 0.5]))
def test_windowed_deviation_bounds_the_exact_one_from_above(seed, window, chunk, noise):
    points, pos, block = random_case(seed, segments=20, dim=3, noise=noise)
    dev = run_deviation(points, pos, block, window, chunk)
    forward, backward = cam.deviation_brute_force(points, pos)
    slack = rounding(points, pos)
    assert dev.forward >= forward - slack
    assert dev.backward >= backward - slack
    # and the chunking changes nothing
    whole = run_deviation(points, pos, block, window, len(pos))
    assert (dev.forward, dev.backward) == (whole.forward, whole.backward)


def test_windowed_deviation_exact_on_a_rounded_corner():
    """A 90° corner cut by a quarter circle of radius r: the commands come within r(1 - 1/√2) of the corner's
    two lines (at the arc's middle), and the corner point is r(√2 - 1) from the arc: both found with window 1."""
    r = 0.01
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    phi = np.linspace(-np.pi / 2, 0.0, 201)  # φ = -π/4, the arc's middle, is sample 100
    arc = np.stack([1 - r + r * np.cos(phi), r + r * np.sin(phi)], axis=1)
    line_in = np.stack([np.linspace(0, 1 - r, 50, endpoint=False), np.zeros(50)], axis=1)
    line_out = np.stack([np.ones(50), np.linspace(r, 1, 51)[1:]], axis=1)
    pos = np.vstack([line_in, arc, line_out])
    block = np.array([0] * 50 + [0] * 101 + [1] * 100 + [1] * 50)
    dev = run_deviation(points, pos, block, window=1, chunk=17)
    # the chords between the arc's samples lie inside it: the corner, outside, is nearest the sample at φ = -π/4
    assert dev.backward == pytest.approx(r * (math.sqrt(2) - 1), rel=1e-12)
    assert dev.forward == pytest.approx(r * (1 - 1 / math.sqrt(2)), rel=1e-12)
    assert dev.backward_at == 1
    assert (dev.forward, dev.backward) == pytest.approx(cam.deviation_brute_force(points, pos), rel=1e-12)


# --------------------------------------------------------------------------- differences and motion time

def test_differences_of_a_cubic_exact_on_a_dyadic_grid():
    """x = 3t³, y = -5t³ at T = 2⁻¹⁰ s: every position and difference is exact in float64, so the maxima
    are exactly the differences' closed forms: jerk 6c, acceleration 6c·t_(K-2), velocity c T²(3k²+3k+1)."""
    period, ticks = 2.0 ** -10, 1000
    c = np.array([3.0, -5.0])
    t = np.arange(ticks) * period
    pos = c * t[:, None] ** 3
    for chunk in (1, 2, 3, 7, ticks):
        diff = cam.Differences(period, 2)
        for i in range(0, ticks, chunk):
            diff.add(pos[i:i + chunk])
        k = ticks - 2
        assert np.array_equal(diff.peak["jerk"], 6 * np.abs(c))
        assert np.array_equal(diff.peak["accel"], 6 * np.abs(c) * k * period)
        assert np.array_equal(diff.peak["velocity"], np.abs(c) * period ** 2 * (3 * k * k + 3 * k + 1))


def test_feed_differences_leave_the_rapid_ticks_out():
    period, ticks = 2.0 ** -10, 400
    t = np.arange(ticks) * period
    pos = np.stack([t ** 3, 0 * t], axis=1)
    feed = t < 200 * period  # the ticks from 200 on are rapid
    for chunk in (1, 5, ticks):
        diff = cam.Differences(period, 2)
        for i in range(0, ticks, chunk):
            diff.add(pos[i:i + chunk], feed[i:i + chunk])
        # the last difference of order m that is all feed ends at tick 199, starting at 199 - m
        assert diff.peak_feed["jerk"][0] == 6.0
        assert diff.peak_feed["accel"][0] == 6.0 * 198 * period
        assert diff.peak_feed["velocity"][0] == period ** 2 * (3 * 198 ** 2 + 3 * 198 + 1)
        assert diff.peak["accel"][0] == 6.0 * 398 * period


def test_motion_time_from_the_first_move_to_the_last():
    period = 1e-3
    x = np.concatenate([np.zeros(5), np.linspace(0.0, 1.0, 101)[1:], np.ones(7)])  # 100 moving steps
    t = np.arange(len(x)) * period
    pos = np.stack([x, np.zeros_like(x)], axis=1)
    for chunk in (1, 3, len(x)):
        motion = cam.MotionTime()
        for i in range(0, len(x), chunk):
            motion.add(t[i:i + chunk], pos[i:i + chunk])
        assert motion.seconds == pytest.approx(100 * period, abs=1e-12)
    assert cam.MotionTime().seconds == 0.0


def test_stream_measures_on_a_made_up_stream():
    """StreamMeasures over a stream with the plan's columns: the period from t, axes from x, y."""
    points = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])
    x = np.concatenate([np.linspace(0, 1, 11), np.ones(10)])
    y = np.concatenate([np.zeros(11), np.linspace(0.1, 1, 10)])
    n = np.concatenate([np.zeros(11), np.ones(10)])
    k = np.arange(21.0)
    columns = ["k", "n", "t", "u", "x", "y", "v", "a", "rapid"]
    data = np.stack([k, n, k * 0.001, 0 * k, x, y, 0 * k, 0 * k, 0 * k], axis=1)
    result = cam.measure_chunks(columns, [data[:4], data[4:13], data[13:]], points, window=1)
    assert result["ticks"] == 21 and result["period"] == pytest.approx(0.001)
    assert result["motion_time"] == pytest.approx(0.020)
    assert result["max_dev_um"] == pytest.approx(0.0, abs=1e-9)
    assert result["max_velocity"]["x"] == pytest.approx(100.0) and result["max_velocity"]["y"] == pytest.approx(100.0)


def test_measure_runs_plan_and_reads_its_stream(tmp_path):
    """End to end on a 5-chord spiral with today's pipeline (no G64 P: the exact path, every tick on the program;
    the chord between the two ticks around a joint passed moving cuts its corner by at most (VT/2) sin(θ/2))."""
    path = tmp_path / "spiral_5.ngc"
    path.write_text(cam.spiral_program(5))
    result = cam.measure(path)
    assert result["exit_code"] == 0, result.get("stderr")
    assert result["blocks"] == 6
    assert result["ticks"] > 0 and result["motion_time"] > 0
    assert result["max_dev_forward_um"] < 1e-3
    points, rapid = cam.polyline_of(path)
    legs = np.diff(points, axis=0)[~rapid]  # the feed moves' (the rapid before them ends at rest)
    legs /= np.linalg.norm(legs, axis=1)[:, None]
    turn = np.arccos(np.clip(np.sum(legs[1:] * legs[:-1], axis=1), -1.0, 1.0)).max()
    feed = cam.SPIRAL_FEED / 60.0
    assert result["max_dev_um"] <= 0.5 * feed * result["period"] * math.sin(0.5 * turn) * 1e3 * (1 + 1e-9) + 1e-3
    assert 0 < result["first_bytes"] <= result["first_tick"] <= result["wall"]
    assert result["wall_alone"] > 0 and result["blocks_per_s_alone"] > 0
    assert result["peak_rss_mb"] > 10


def test_table_rows_and_plan_arguments_after_the_double_dash(tmp_path, monkeypatch, capsys):
    """`table` hands what follows -- to plan untouched and prints a row a program beside LinuxCNC's figures."""
    seen = []

    def fake_measure(path, plan_args, window):
        seen.append((Path(path).name, list(plan_args), window))
        axes = {"x": 1.0, "y": 2.0}
        return {"blocks": 1001, "motion_time": 4.5, "max_dev_forward_um": 3.0, "max_dev_backward_um": 4.0,
                "max_velocity": axes, "max_accel": axes, "max_jerk": axes, "blocks_per_s": 900.0,
                "blocks_per_s_alone": 1200.0,
                "peak_rss_mb": 150.0, "first_tick": 0.5, "exit_code": 0}

    monkeypatch.setattr(cam, "measure", fake_measure)
    assert cam.main(["table", str(tmp_path), "--blocks", "1000", "--", "--tolerance", "5um", "--window", "9"]) == 0
    assert seen == [("spiral_1000.ngc", ["--tolerance", "5um", "--window", "9"], 4),
                    ("raster_1000.ngc", ["--tolerance", "5um", "--window", "9"], 4)]
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("| program |") and len(out) == 4
    assert out[2] == ("| spiral_1000 | 1001 | 4.500 (4.778) | 3.00 / 4.00 (1.07 / 1.14) | 1/2 · 1/2 · 1/2 | 900 (1200) "
                      "| 150 | 0.50 |")
