"""NURBS blocks in the look-ahead (motion.nurbs_blocks): G5.2/G6.2 blocks, YAML `nurbs` blocks and DXF splines
followed as cubic curve rows within the tolerance, between lines and arcs, planned through.

References are independent of the library's curve code: the NURBS evaluated by the naive Cox–de Boor recursion
(tests/oracle.py), at each command's own u and densely (20 001 samples a block, whose chords of about 1 µm on
radii of millimetres sag by some 4e-8 mm: measured and allowed); distances by brute force to every segment of a polyline; the
limits by the stream's finite differences (test_lookahead.check_limits); the stream planned whole and a block at
a time.
"""
from __future__ import annotations

import math

import numpy as np
import oracle
import pytest
from test_cli_contract import run_main
from test_lookahead import LIMITS, TIGHT, TOL, axes_of, check_limits, col, distance_to_polyline, planned, program

from nurbsinterp.cli.common import load
from nurbsinterp.config.curve import validate_curve
from nurbsinterp.config.gcode import read_gcode
from nurbsinterp.config.rules import Where
from nurbsinterp.motion import nurbs_blocks as nb
from nurbsinterp.motion import segments as seg
from nurbsinterp.motion.contour import ProgramWindow
from nurbsinterp.motion.limits import motion_limits
from nurbsinterp.motion.pipeline import path_items

# lines, then a rational quadratic G5.2 block (a quarter of an ellipse-like arc, weight 0.7 in the middle) meeting
# them along their directions, then a cubic G5.2 (L4) turning back, then lines again
PROGRAM = """
    G21 G90 G17 F1200
    G1 X10 Y0
    G5.2 X20 Y0 P1 L3
    X20 Y10 P0.7
    X10 Y10 P1
    G5.3
    G1 X5 Y10
    G5.2 X0 Y10 P1 L4
    X-5 Y15 P1
    X0 Y20 P1
    X5 Y20 P1
    G5.3
    G1 X15 Y20
    M2
    """


def spec_of(degree, points, weights, knots=None):
    raw = {"degree": degree, "control_points": np.asarray(points, float).tolist(),
           "weights": np.asarray(weights, float).tolist()}
    if knots is not None:
        raw["knots"] = list(knots)
    return validate_curve(raw, Where("test"))


def random_spec(rng, dim=3):
    degree = int(rng.integers(2, 6))
    n = degree + 1 + int(rng.integers(0, 5))
    points = np.cumsum(rng.uniform(-8.0, 8.0, (n, dim)), axis=0)
    weights = rng.uniform(0.4, 2.5, n)
    inner = np.sort(rng.uniform(0.0, 3.0, n - degree - 1))
    knots = np.concatenate([[0.0] * (degree + 1), inner, [3.0] * (degree + 1)])
    return spec_of(degree, points, weights, knots)


def curve_at(spec, u):
    """The naive rational curve at the block's own parameters u (the oracle's array form: the same recursion on
    every u at once, 10 000 at a time; it agrees with the oracle point by point to a few 1e-16 of the curve's
    size (test_the_oracles_array_form_is_its_point_by_point_form), far inside every bound checked with it)."""
    u = np.asarray(u, dtype=float)
    if u.size == 0:
        return np.empty((0, np.shape(spec.control_points)[1]))
    return np.concatenate([oracle.point(spec.knots, spec.degree, spec.control_points, spec.weights, u[lo:lo + 10_000])
                           for lo in range(0, u.size, 10_000)])


def test_the_oracles_array_form_is_its_point_by_point_form():
    """curve_at against oracle.point one parameter at a time, on the random blocks of the tests below: within
    1e-15 of the control net's size (the two forms multiply N·W·V in another order)."""
    for seed in range(6):
        spec = random_spec(np.random.default_rng(seed))
        a, z = spec.knots[spec.degree], spec.knots[-1]
        u = np.concatenate([np.linspace(a, z, 301), spec.knots])
        one_by_one = np.array([oracle.point(spec.knots, spec.degree, spec.control_points, spec.weights, x) for x in u])
        assert np.abs(curve_at(spec, u) - one_by_one).max() <= 1e-15 * np.abs(spec.control_points).max()


def lim_vector(path):
    return motion_limits(load(path, **LIMITS), TOL).vector()


def bezier(rows, w):
    """Points (len(rows), len(w), 3) of curve rows at their Bézier parameters w."""
    a = (1.0 - w)[None, :, None]
    b = w[None, :, None]
    c = [rows[:, None, col:col + 3] for col in (seg.B0, seg.B1, seg.B2, seg.B3)]
    return a ** 3 * c[0] + 3 * a * a * b * c[1] + 3 * a * b * b * c[2] + b ** 3 * c[3]


# --------------------------------------------------------------------------- the rows against the curve


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("tolerance", [0.005, 0.0])
def test_rows_within_budget_at_the_same_parameter(tmp_path, seed, tolerance):
    """Every row point H(w) within the budget of the curve's point C(u(w)) at the same parameter, checked at 400
    points a row (the library checks 32): that distance bounds both sides (each row point from the curve, each
    curve point from the rows), and the rows cover the block's domain end to end, meeting with its tangent."""
    rng = np.random.default_rng(seed)
    spec = random_spec(rng)
    path = program(tmp_path, "G21 G90 F600\nG1 X1\nM2\n")
    rows, deviation = nb.nurbs_rows(spec, tolerance, 7, 20.0, lim_vector(path), "test")
    budget = nb.APPROX_SHARE * tolerance if tolerance > 0 else nb.FLOOR
    assert deviation <= 0.5 * budget
    a, z = spec.knots[spec.degree], spec.knots[-1]
    # the domain covered, in order, without gaps
    assert rows[0, seg.U0] == 0.0
    assert np.allclose(rows[1:, seg.U0], rows[:-1, seg.U0] + rows[:-1, seg.DU], rtol=0, atol=1e-15)
    assert rows[-1, seg.U0] + rows[-1, seg.DU] == pytest.approx(1.0, abs=1e-15)
    w = np.linspace(0.0, 1.0, 401)
    H = bezier(rows, w)
    u = a + (rows[:, seg.U0, None] + w[None, :] * rows[:, seg.DU, None]) * (z - a)
    C = curve_at(spec, u.ravel()).reshape(H.shape)
    scale = float(np.abs(spec.control_points).max())
    assert np.sqrt(((H - C) ** 2).sum(axis=2)).max() <= budget + 1e-13 * scale
    # the ends exactly as programmed; consecutive rows meet, along one tangent
    assert np.array_equal(rows[0, seg.B0:seg.B0 + 3], spec.control_points[0])
    assert np.array_equal(rows[-1, seg.B3:seg.B3 + 3], spec.control_points[-1])
    assert np.array_equal(rows[1:, seg.B0:seg.B0 + 3], rows[:-1, seg.B3:seg.B3 + 3])
    t_out = rows[:-1, seg.B3:seg.B3 + 3] - rows[:-1, seg.B2:seg.B2 + 3]
    t_in = rows[1:, seg.B1:seg.B1 + 3] - rows[1:, seg.B0:seg.B0 + 3]
    cosine = (t_out * t_in).sum(axis=1) / np.linalg.norm(t_out, axis=1) / np.linalg.norm(t_in, axis=1)
    # (rows meet C1 inside a span, and at a knot of multiplicity below the degree)
    multiplicity = {k: int(np.count_nonzero(spec.knots == k)) for k in np.unique(spec.knots)}
    joints_u = a + (rows[1:, seg.U0]) * (z - a)
    smooth_joint = np.array([multiplicity.get(float(x), 0) < spec.degree for x in joints_u])
    assert np.all(cosine[smooth_joint] >= 1.0 - 1e-12)
    # each row's length as the interpolator takes it (8-point Gauss-Legendre) against a fine composite rule
    for r in rows[:: max(1, rows.shape[0] // 6)]:
        ww = np.linspace(0.0, 1.0, 4001)
        pts = bezier(r[None, :], ww)[0]
        chord = float(np.sqrt(((pts[1:] - pts[:-1]) ** 2).sum(axis=1)).sum())
        assert r[seg.LEN] == pytest.approx(chord, rel=1e-6)  # the polyline's length converges as 1/N²


def test_polynomial_cubic_is_reproduced_exactly(tmp_path):
    """A non-rational NURBS of degree 3 (or 2) is a cubic on each knot span: its rows on it to rounding (a span
    may still be cut where its speed varies too much for the rows' 8-point length rule)."""
    path = program(tmp_path, "G21 G90 F600\nG1 X1\nM2\n")
    for degree in (2, 3):
        rng = np.random.default_rng(degree)
        n = 7
        spec = spec_of(degree, np.cumsum(rng.uniform(-5, 5, (n, 3)), axis=0), np.ones(n),
                       [0.0] * (degree + 1) + list(np.linspace(0, 1, n - degree + 1)[1:-1]) + [1.0] * (degree + 1))
        rows, deviation = nb.nurbs_rows(spec, 0.005, 0, 20.0, lim_vector(path), "test")
        assert rows.shape[0] >= n - degree  # one a span at least
        assert deviation <= 1e-13
        w = np.linspace(0, 1, 101)
        H = bezier(rows, w)
        C = curve_at(spec, (rows[:, seg.U0, None] + w[None, :] * rows[:, seg.DU, None]).ravel()).reshape(H.shape)
        assert np.abs(H - C).max() <= 1e-12


@pytest.mark.parametrize("tol", [TOL, 0.0, None], ids=["5 um", "exact path", "own"])
def test_a_corner_inside_a_block_is_passed_at_rest_on_it(tmp_path, tol):
    """A block whose pieces meet at an angle (a control point repeated to the degree: a 90-degree corner at
    u = 1 of 0 .. 2) is followed to its corner, where the plan comes to rest on a tick exactly on it (no blend
    inside a block, whatever the tolerance), and on from there; the summary counts it among the sharp stops."""
    path = program(tmp_path, "G21 G90 F600\nG5.2 X5 Y5 P1 L3\nX5 Y5 P1\nX10 Y0 P1\nG5.3\nM2\n")
    run, rows = planned(path, tol)
    xy = rows[:, [col(run, "x"), col(run, "y")]]
    on_corner = np.flatnonzero(np.abs(xy - [5.0, 5.0]).max(axis=1) <= 1e-12)
    assert on_corner.size and rows[on_corner, col(run, "v")].min() == 0.0
    assert np.abs(xy[-1] - [10.0, 0.0]).max() <= 1e-12  # and on to the block's end
    assert run.facts.sharp_stops == 1 and run.facts.stops == 1
    check_limits(run, rows)


# --------------------------------------------------------------------------- a program with NURBS blocks


def program_path(path, with_sag=False):
    """The programmed path densely: lines by their ends, NURBS blocks by the oracle at 20 001 parameters each;
    with *with_sag* also a bound on how far its chords stray from the curve: the largest distance of a sample
    from the chord of its two neighbours (four times a chord's own sag, on a curve whose curvature varies
    little over three samples)."""
    pts = []
    sag = 0.0
    for b in read_gcode(path).blocks:
        if b.kind == "nurbs":
            c = b.curve
            u = np.linspace(c.knots[c.degree], c.knots[-1], 20001)
            q = curve_at(c, u)
            pts.append(q)
            sag = max(sag, float(distance_pairs(q[1:-1], q[:-2], q[2:]).max()))
        else:
            pts.append(np.array([b.start, b.end]))
    out = np.concatenate(pts)
    out = np.column_stack([out, np.zeros((out.shape[0], 3 - out.shape[1]))]) if out.shape[1] < 3 else out
    return (out, sag) if with_sag else out


def distance_pairs(p, a, b):
    """Distance of each p from the segment a -> b of its own row."""
    ab = b - a
    t = np.clip(((p - a) * ab).sum(axis=1) / (ab * ab).sum(axis=1), 0.0, 1.0)
    return np.sqrt(((a + t[:, None] * ab - p) ** 2).sum(axis=1))


@pytest.mark.parametrize("tolerance", [TOL, 0.0])
def test_program_two_sided_and_limits(tmp_path, tolerance):
    """Every command within the tolerance of the programmed path, every point of the path within it of the
    commands' polyline, the per-axis limits by finite differences, the end exactly; with no tolerance, the
    commands on the path (its NURBS within 1e-9 mm) and the chord sag free, as on an arc."""
    path = program(tmp_path, PROGRAM)
    run, rows = planned(path, tol=tolerance)
    assert run.facts.nurbs == 2 and run.facts.nurbs_rows >= 2
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    dense, sag = program_path(path, with_sag=True)
    assert sag < 1e-6
    assert distance_to_polyline(x, dense).max() <= max(tolerance, 1e-9) + sag + TIGHT
    if tolerance:
        assert distance_to_polyline(dense, x).max() <= tolerance + TIGHT
    # the commands on a NURBS block against the curve at their own u: within the rows' budget
    n, u = rows[:, col(run, "n")], rows[:, col(run, "u")]
    budget = nb.APPROX_SHARE * tolerance if tolerance else nb.FLOOR
    for k, b in enumerate(read_gcode(path).blocks):
        if b.kind == "nurbs":
            c = b.curve
            on = n == k
            a, z = c.knots[c.degree], c.knots[-1]
            exact = curve_at(c, a + u[on] * (z - a))
            assert np.sqrt(((exact - x[on, :2]) ** 2).sum(axis=1)).max() <= budget + TIGHT
    check_limits(run, rows)
    assert np.all(np.isfinite(rows))
    assert np.array_equal(x[-1, :2], [15.0, 20.0])
    # the feed reaches F on the first NURBS block (a radius near 5 mm: the axes allow ~ sqrt(0.6*1000*5))
    n = rows[:, col(run, "n")]
    assert rows[n == 1, col(run, "v")].max() > 0.5 * 20.0


def test_u_is_the_fraction_of_the_blocks_domain(tmp_path):
    """On a NURBS block, u is the fraction of its knot domain (every block's u runs 0 .. 1 in a look-ahead stream):
    the curve there lies within the budget of the command."""
    path = program(tmp_path, PROGRAM)
    run, rows = planned(path)
    blocks = read_gcode(path).blocks
    for k in (1, 3):
        c = blocks[k].curve
        on = rows[rows[:, col(run, "n")] == k]
        assert on.shape[0] > 10
        a, z = c.knots[c.degree], c.knots[-1]
        u = on[:, col(run, "u")]
        assert u.min() >= 0.0 and u.max() <= 1.0
        pts = curve_at(c, a + u * (z - a))
        assert np.sqrt(((pts - axes_of(run, on)) ** 2).sum(axis=1)).max() <= nb.APPROX_SHARE * TOL


def test_windows_equal_whole(tmp_path):
    """A program of short moves, arcs and NURBS blocks planned whole and a block at a time: the same stream."""
    lines = ["G21 G90 G17 F1500", "G1 X0 Y0"]
    for i in range(1, 40):
        lines.append(f"G1 X{i * 0.2:.4f} Y{0.3 * math.sin(i * 0.2):.5f}")
    lines += ["G5.2 X9 Y1 P1 L4", "X10 Y3 P0.8", "X12 Y3 P1", "G5.3", "G2 X14 Y3 I1 J0"]
    for i in range(1, 40):
        lines.append(f"G1 X{14 + i * 0.2:.4f} Y{3 + 0.3 * math.sin(i * 0.2):.5f}")
    path = program(tmp_path, "\n".join(lines + ["M2"]) + "\n")
    run, whole = planned(path, batch=10_000)
    _, windowed = planned(path, batch=1)
    assert run.facts.nurbs == 1 and run.smoothing.curves > 0
    assert np.array_equal(whole, windowed)


@pytest.mark.parametrize("tolerance", [TOL, 0.0])
def test_a_block_that_starts_and_ends_at_rest(tmp_path, tolerance):
    """G5.2 blocks that restate the current position (and end on a repeated point) start and end at rest (C' = 0
    there), as LinuxCNC's own samples do: followed from the limit tangent, two-sided within the tolerance by the
    oracle's dense samples, the limits held."""
    path = program(tmp_path, """
        G21 G90 G17 F600
        G1 X10 Y0
        G5.2 P1 L4
        X10 Y0 P1
        X20 Y20 P1
        X12 Y8 P0.5
        X10 Y20 P1
        X10 Y20 P1
        G5.3
        G1 X10 Y30
        M2
        """)
    run, rows = planned(path, tol=tolerance)
    assert run.facts.nurbs == 1
    x = np.zeros((rows.shape[0], 3))
    x[:, :run.dim] = axes_of(run, rows)
    dense, sag = program_path(path, with_sag=True)
    assert distance_to_polyline(x, dense).max() <= max(tolerance, 1e-9) + sag + TIGHT
    if tolerance:
        assert distance_to_polyline(dense, x).max() <= tolerance + TIGHT
    check_limits(run, rows)
    assert np.array_equal(x[-1, :2], [10.0, 30.0])


def test_repeated_points_with_weights_are_rest_not_corners(tmp_path):
    """A G5.2 block restating the current position with decimal weights, its last point repeated: knot insertion
    and the weights leave the repeated points a few ulps apart, which is rounding, not a direction (it once
    read as a corner inside the block); and a degree-1 block with a point repeated has a span that does not move
    (no row), the path going on from it."""
    path = program(tmp_path, """
        G21 G90 G17 F600
        G1 X-0.8 Y17.6
        G5.2 P1.8 L4
        X-0.8 Y17.6 P1.1
        X19.3 Y27.1 P1.6
        X-30.9 Y-4.0 P0.6
        X-27.9 Y46.3 P1.9
        X-27.9 Y46.3 P1.3
        G5.3
        M2
        """)
    for tolerance in (TOL, 0.0):
        run, rows = planned(path, tol=tolerance)
        x = np.zeros((rows.shape[0], 3))
        x[:, :run.dim] = axes_of(run, rows)
        dense, sag = program_path(path, with_sag=True)
        assert distance_to_polyline(x, dense).max() <= max(tolerance, 1e-9) + sag + TIGHT
        check_limits(run, rows)
    spec = spec_of(1, [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]], [1.0, 1.0, 1.0, 1.0])
    rows, _ = nb.nurbs_rows(spec, TOL, 0, 20.0, lim_vector(path), "test")
    assert rows[0, seg.B0] == 0.0 and rows[-1, seg.B3] == 2.0 and np.all(rows[:, seg.LEN] > 0)
    assert rows[:, seg.LEN].sum() == pytest.approx(2.0, rel=1e-12)


# --------------------------------------------------------------------------- the programmed path's window


def test_program_window_measures_nurbs_blocks(tmp_path):
    """ProgramWindow's distance of points near a NURBS block against brute force (the oracle's dense samples):
    the same to their sag, and its feet on the curve at that distance."""
    path = program(tmp_path, PROGRAM)
    run, rows = planned(path)
    job = load(path, **LIMITS)
    window = ProgramWindow(path_items(job.path), TOL, run.dim, "p.ngc")
    rng = np.random.default_rng(3)
    cmd = axes_of(run, rows)
    pos = cmd + rng.normal(0.0, 0.01, cmd.shape)  # a servo's lag and noise
    seeds = rows[:, col(run, "n")] + rows[:, col(run, "u")]
    feet, dist = window.nearest(pos, seeds, cmd)
    dense, sag = program_path(path, with_sag=True)
    p3 = np.column_stack([pos, np.zeros((pos.shape[0], 3 - run.dim))])
    brute = distance_to_polyline(p3, dense)
    # the samples' chords stray from the curve by at most their sag, to either side
    assert np.abs(brute - dist).max() <= sag + TIGHT
    on = window.points(feet)
    assert np.abs(np.sqrt(((on - pos) ** 2).sum(axis=1)) - dist).max() <= TIGHT
    # a foot on a NURBS block is the oracle's curve point at that fraction of its domain, at that distance
    blocks = read_gcode(path).blocks
    for k in (1, 3):
        c = blocks[k].curve
        a, z = c.knots[c.degree], c.knots[-1]
        at = (feet >= k) & (feet < k + 1)
        assert np.count_nonzero(at) > 10
        exact = curve_at(c, a + (feet[at] - k) * (z - a))
        assert np.abs(np.sqrt(((exact - pos[at]) ** 2).sum(axis=1)) - dist[at]).max() <= TIGHT


def test_contour_error_against_nurbs_blocks_is_brute_force(tmp_path):
    """Every tick's contour error through the servo, against the program's blocks read alongside the stream: the
    oracle's dense samples of the whole program give it, to their sag (the program never comes back near itself)."""
    from test_simulate_lookahead import simulated

    path = program(tmp_path, PROGRAM)
    columns, rows = simulated(path, TOL, **LIMITS)
    act = rows[:, [columns.index(a) for a in ("x_act", "y_act", "z_act")]]
    err = rows[:, columns.index("contour_error")]
    dense, sag = program_path(path, with_sag=True)
    want = distance_to_polyline(act, dense)
    assert np.abs(err - want).max() <= sag + TIGHT
    assert err.max() > 1e-4  # the servo leaves the path: the check is not of zeros


def test_cli_plan_and_simulate(tmp_path, capsys):
    """plan --tolerance says what it did with the NURBS blocks; simulate --job PROGRAM measures its stream."""
    path = program(tmp_path, PROGRAM)
    out = tmp_path / "run.bin"
    limits = ["--profile-type", "adaptive", "--axis-max-velocity", "x=100,y=100,z=100",
              "--axis-max-accel", "x=1000,y=1000,z=1000"]
    code, _, err = run_main(capsys, "plan", path, "--tolerance", "5um", *limits, "--format", "bin", "-o", out)
    assert code == 0, err
    assert "NURBS            2 blocks followed by" in err
    from test_simulate_lookahead import SERVO

    code, stdout, err = run_main(capsys, "simulate", str(out), "--job", path, "--tolerance", "5um", "--servo", SERVO,
                                 "--json")
    assert code == 0, err
    import json

    assert json.loads(stdout)["contour_error_max"] > 1e-4


# --------------------------------------------------------------------------- the commands


def test_program_own_tolerance_with_nurbs(tmp_path, capsys):
    """A program stating G64 P before its NURBS blocks is planned with look-ahead within it (no --tolerance)."""
    path = program(tmp_path, PROGRAM.replace("G21 G90 G17 F1200", "G21 G90 G17 G64 P0.01 F1200"))
    code, stdout, err = run_main(capsys, "info", path, "--json", "--profile-type", "adaptive",
                                 "--axis-max-accel", "x=1000,y=1000,z=1000")
    assert code == 0, err
    import json

    facts = json.loads(stdout)
    assert facts["planner"] == "look-ahead" and facts["tolerance_source"] == "program"
    assert facts["nurbs"]["blocks"] == 2 and 0 < facts["nurbs"]["worst_deviation"] <= 0.05 * 0.01


def test_curve_job_with_tolerance(tmp_path, capsys):
    """A YAML curve job (one NURBS) with --tolerance: planned by the look-ahead, on the circle within it."""
    out = tmp_path / "c.csv"
    code, _, err = run_main(capsys, "plan", "curves/circle.yaml", "--tolerance", "5um", "-o", out)
    assert code == 0, err
    from nurbsinterp.streams import read_stream

    with open(out, "rb") as f:
        columns, chunks = read_stream(f, str(out))
        data = np.concatenate(list(chunks))
    xy = data[:, [columns.index("x"), columns.index("y")]]
    job = load("curves/circle.yaml")
    c = job.path.blocks[0].curve
    # the paper's circle: its centre and radius from three of its points (the oracle)
    p = curve_at(c, np.array([0.0, 0.25, 0.5]) * (c.knots[-1] - c.knots[0]) + c.knots[0])
    centre = 0.5 * (p[0] + p[2])
    radius = float(np.linalg.norm(p[0] - centre))
    assert np.abs(np.sqrt(((xy - centre) ** 2).sum(axis=1)) - radius).max() <= TOL + TIGHT
    assert np.array_equal(xy[-1], c.control_points[-1])


def test_dxf_spline(tmp_path, capsys):
    """A DXF drawing's spline between lines, planned with --tolerance."""
    ezdxf = pytest.importorskip("ezdxf")
    doc = ezdxf.new()
    msp = doc.modelspace()
    msp.add_line((0, 0), (10, 0))
    msp.add_spline(fit_points=[(10, 0), (15, 2), (20, 0), (25, -2)])
    path = tmp_path / "d.dxf"
    doc.saveas(path)
    out = tmp_path / "d.bin"
    code, _, err = run_main(capsys, "plan", str(path), "--tolerance", "5um", "--format", "bin", "-o", out)
    assert code == 0, err
    assert "NURBS            1 blocks followed by" in err
