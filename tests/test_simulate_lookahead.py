"""`simulate --tolerance`: a look-ahead plan through the servo, its contour error measured against the program's
blocks read alongside the stream (motion.contour.ProgramWindow), never the program held whole.

The distances are checked against independent oracles (lines and arcs in closed form written here, helices by
dense sampling refined by scipy), the contour error of every tick against brute force over every block of the
program, and the command line's plan → simulate pipe against simulate planning itself."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from budgets import budgets
from scipy.optimize import minimize_scalar

from nurbsinterp.motion import segments as seg
from nurbsinterp.motion.contour import ProgramWindow, block_foot, item_arrays
from test_cli_contract import one_line_error, run_main
from test_lookahead import LIMITS, program, random_program

#: a program's look-ahead stream has x, y and z: a servo model with the three (the default is the paper's X-Y table)
ROOT = Path(__file__).resolve().parents[1]
SERVO = str(ROOT / "servo" / "example-xyz.yaml")


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def arc_point(P0, C, N, sweep, rise, th):
    N = unit(N)
    r = P0 - C
    h0 = r @ N
    r = r - h0 * N
    R = np.linalg.norm(r)
    e1 = r / R
    e2 = np.cross(N, e1)
    return C + h0 * N + R * (math.cos(th) * e1 + math.sin(th) * e2) + rise * th / sweep * N


def oracle_distance(kind, P0, P1, C, N, sweep, rise, p):
    """The distance of p from a block, by other means than the kernel's."""
    if kind == seg.LINE:
        d = P1 - P0
        t = np.clip((p - P0) @ d / (d @ d), 0.0, 1.0) if d @ d > 0 else 0.0
        return float(np.linalg.norm(P0 + t * d - p))
    f = lambda th: float(np.linalg.norm(arc_point(P0, C, N, sweep, rise, th) - p))  # noqa: E731
    grid = np.linspace(0.0, sweep, 4001)
    vals = np.array([f(th) for th in grid])
    k = int(vals.argmin())
    res = minimize_scalar(f, bounds=(grid[max(k - 1, 0)], grid[min(k + 1, 4000)]), method="bounded",
                          options={"xatol": 1e-13})
    return min(float(res.fun), float(vals.min()))


coords = st.floats(-50, 50, allow_nan=False)


@budgets(quick=50, full=200)
def test_line_distance_is_the_closed_form(budget):
    @settings(max_examples=budget, deadline=None)
    @given(p=st.tuples(coords, coords, coords), a=st.tuples(coords, coords, coords),
           b=st.tuples(coords, coords, coords))
    def check(p, a, b):
        P0, P1, p = np.array(a), np.array(b), np.array(p)
        kind, Q0, Q1, C, N, sweep, rise = item_arrays(type("L", (), {"kind": "line", "start": P0, "end": P1})())
        _, d = block_foot(kind, Q0, Q1, C, N, sweep, rise, 0, p)
        assert abs(d - oracle_distance(seg.LINE, P0, P1, None, None, 1, 0, p)) <= 1e-12 * (1 + np.abs(p).max() + 50)

    check()


@budgets(quick=30, full=120)
def test_arc_and_helix_distances_are_the_oracles(budget):
    @settings(max_examples=budget, deadline=None)
    @given(p=st.tuples(coords, coords, coords), radius=st.floats(0.5, 30), start=st.floats(0, 2 * math.pi),
           sweep=st.floats(0.05, 2 * math.pi), rise=st.sampled_from([0.0, 0.0, 3.0, -7.5]),
           tilt=st.floats(0, 1.2), off=st.floats(-5, 5))
    def check(p, radius, start, sweep, rise, tilt, off):
        N = unit([math.sin(tilt), 0.0, math.cos(tilt)])
        C = np.array([1.0, -2.0, off])
        e1 = unit(np.cross(N, [0.0, 1.0, 0.0]))
        e2 = np.cross(N, e1)
        P0 = C + radius * (math.cos(start) * e1 + math.sin(start) * e2)
        P1 = arc_point(P0, C, N, sweep, rise, sweep)
        item = type("A", (), {"kind": "arc", "start": P0, "end": P1, "center": C, "normal": N, "sweep": sweep,
                              "rise": rise})()
        arrays = item_arrays(item)
        p = np.array(p)
        _, d = block_foot(*arrays, 0, p)
        want = oracle_distance(seg.ARC, P0, P1, C, N, sweep, rise, p)
        # the oracle is a minimum found numerically (never below the true one); the closed form is exact to rounding
        assert d <= want + 1e-9
        assert d >= want - 1e-7 * (1 + want)

    check()


# --------------------------------------------------------------------------- the servo's contour error


def brute_contour(path, act, seeds=None, reach=None):
    """The distance of each position from every block of the program (read whole here, as an oracle); with
    seeds and reach, from the blocks whose arc length lies within reach of the seed's block (ProgramWindow's
    definition, written again here)."""
    from nurbsinterp.config.gcode import read_gcode

    blocks = read_gcode(path).blocks
    arrays = [item_arrays(b) for b in blocks]
    lengths = np.array([np.linalg.norm(a[2][0] - a[1][0]) if a[0][0] == seg.LINE
                        else math.hypot(np.linalg.norm(a[1][0] - a[3][0]) * a[5][0], a[6][0]) for a in arrays])
    S = np.concatenate([[0.0], np.cumsum(lengths)])
    pts = np.zeros((act.shape[0], 3))
    pts[:, :act.shape[1]] = act
    best = np.full(act.shape[0], np.inf)
    for i in range(act.shape[0]):
        if seeds is None:
            near = range(len(blocks))
        else:
            b = max(int(math.ceil(seeds[i])) - 1, 0)
            near = [j for j in range(len(blocks)) if S[j + 1] >= S[b] - reach[i] and S[j] <= S[b + 1] + reach[i]]
        for j in near:
            best[i] = min(best[i], block_foot(*arrays[j], 0, pts[i])[1])
    return best


def simulated(path, tolerance, **options):
    """(trace columns, every trace row at full precision) of the program planned with look-ahead and simulated
    through SERVO, through the library."""
    from nurbsinterp.cli.common import load
    from nurbsinterp.motion.pipeline import LookAhead, path_items
    from nurbsinterp.servo import load_servo
    from nurbsinterp.simulation import simulate, trace_columns

    job = load(path, stream=True, every_profile=True, **options)
    run = LookAhead(job, tolerance)
    window = ProgramWindow(path_items(job.path), tolerance, 3, path)
    rows = []
    simulate(None, load_servo(SERVO), run.columns, run.chunks(), trace=rows.append, window=window)
    return trace_columns(["x", "y", "z"]), np.concatenate(rows)


@pytest.mark.parametrize("kind", ["corners", "mixed", "noisy"])
def test_contour_error_is_brute_force_over_the_window(tmp_path, kind):
    """Every tick's contour error is the least distance from the blocks within reach of its block, as brute
    force over every block of the program, kept to those, gives it."""
    path = program(tmp_path, random_program(np.random.default_rng(3), kind, n=40))
    columns, rows = simulated(path, 0.005, **LIMITS)
    act = rows[:, [columns.index(a) for a in ("x_act", "y_act", "z_act")]]
    cmd = rows[:, [columns.index(a) for a in ("x_cmd", "y_cmd", "z_cmd")]]
    err = rows[:, columns.index("contour_error")]
    reach = 2.0 * (np.linalg.norm(act - cmd, axis=1) + 0.005) + 1e-9
    want = brute_contour(path, act, rows[:, columns.index("u")], reach)
    assert np.max(np.abs(err - want)) <= 1e-12 * (1 + np.abs(act).max()), np.max(np.abs(err - want))
    assert err.max() > 1e-4  # the servo leaves the path: the check is not of zeros


def test_contour_error_is_the_whole_programs_where_it_does_not_come_back(tmp_path):
    """A path that never turns back (its heading within 30 degrees of +x) has no other part near the one being
    cut: the window's contour error is brute force over every block of the program."""
    rng = np.random.default_rng(4)
    lines = ["G21 G90 G64 F3000"]
    p = np.zeros(3)
    for _ in range(60):
        heading = rng.uniform(-0.5, 0.5)
        p = p + rng.uniform(0.1, 3.0) * np.array([math.cos(heading), math.sin(heading), 0.0])
        lines.append(f"G1 X{p[0]:.6f} Y{p[1]:.6f} Z{rng.uniform(-0.2, 0.2):.6f}")
    path = program(tmp_path, "\n".join(lines + ["M2"]) + "\n")
    columns, rows = simulated(path, 0.005, **LIMITS)
    act = rows[:, [columns.index(a) for a in ("x_act", "y_act", "z_act")]]
    err = rows[:, columns.index("contour_error")]
    want = brute_contour(path, act)
    assert np.max(np.abs(err - want)) <= 1e-12 * (1 + np.abs(act).max()), np.max(np.abs(err - want))
    assert err.max() > 1e-4


def test_a_planned_stream_simulates_as_simulate_plans_it(capsys, tmp_path):
    path = program(tmp_path, random_program(np.random.default_rng(8), "noisy", n=120))
    opts = ["--profile-type", "adaptive", "--axis-max-velocity", "x=100,y=100,z=100", "--axis-max-accel",
            "x=1000,y=1000,z=1000"]
    code, planned, err = run_main(capsys, "simulate", "--plan", "--job", path, "--tolerance", "5um", "--json",
                                  "--servo", SERVO, *opts)
    assert code == 0, err
    for fmt in ("bin", "csv"):
        stream = tmp_path / f"run.{fmt}"
        code, _, err = run_main(capsys, "plan", path, "--tolerance", "5um", "--format", fmt, "-q", "-o", str(stream),
                                *opts)
        assert code == 0, err
        code, read, err = run_main(capsys, "simulate", str(stream), "--job", path, "--tolerance", "5um", "--json",
                                   "--servo", SERVO)
        assert code == 0, err
        import json

        a, b = json.loads(planned), json.loads(read)
        for key in ("contour_error_max", "contour_error_rms", "ticks", "settle_time"):
            assert a[key] == pytest.approx(b[key], rel=1e-9, abs=1e-12 if fmt == "bin" else 1e-8), (fmt, key)


def test_refusals_are_one_line(capsys, tmp_path):
    path = program(tmp_path, random_program(np.random.default_rng(9), "corners", n=20))
    other = program(tmp_path, random_program(np.random.default_rng(10), "corners", n=20), "other.ngc")
    la = tmp_path / "la.bin"
    own = tmp_path / "own.csv"
    assert run_main(capsys, "plan", path, "--tolerance", "5um", "--format", "bin", "-q", "-o", la,
                    "--max-accel", "1000")[0] == 0
    assert run_main(capsys, "plan", path, "-q", "-o", own, "--max-accel", "1000")[0] == 0
    # a stream names the tolerance it was planned within (the binary header, the CSV end mark): the measures need
    # it, and another is refused
    one_line_error(*run_main(capsys, "simulate", str(la), "--job", path, "--servo", SERVO),
                   "planned within 5 um, not within the program's own G64 P")
    one_line_error(*run_main(capsys, "simulate", str(own), "--job", path, "--tolerance", "5um", "--servo", SERVO),
                   "planned within the program's own G64 P, not within 5 um")
    assert run_main(capsys, "simulate", str(own), "--job", path, "--servo", SERVO)[0] == 0
    # a curve is planned with look-ahead only when asked to: its stream then needs the same
    yaml = ROOT / "curves" / "circle.yaml"
    square = tmp_path / "circle.bin"
    assert run_main(capsys, "plan", yaml, "--tolerance", "5um", "--format", "bin", "-q", "-o", square)[0] == 0
    one_line_error(*run_main(capsys, "simulate", str(square), "--job", yaml, "--servo", SERVO),
                   "planned with look-ahead")
    one_line_error(*run_main(capsys, "simulate", str(la), "--job", other, "--tolerance", "5um", "--servo", SERVO),
                   "another program")
    one_line_error(*run_main(capsys, "simulate", str(la), "--job", path, "--tolerance", "-1"), "--tolerance")


def test_the_window_holds_a_bounded_part_of_the_program(tmp_path):
    """Read alongside a stream of 20 000 moves, the window never holds more than a few thousand blocks (what it
    reads at a time, and 10 mm of path behind the ticks)."""
    lines = ["G21 G90 G64 F3000", "G1 X0 Y0"]
    for r in range(100):
        xs = range(200) if r % 2 == 0 else range(199, -1, -1)
        lines += [f"G1 X{x * 0.2:.3f} Y{r * 0.5:.3f}" for x in xs]
    path = program(tmp_path, "\n".join(lines + ["M2"]) + "\n")
    from nurbsinterp.cli.common import load
    from nurbsinterp.motion.pipeline import LookAhead, path_items

    job = load(path, stream=True, **LIMITS)
    job.path.piece_bytes = 16 * 1024  # a run of moves is read a piece at a time: pieces far smaller than the program
    run = LookAhead(job, 0.005)
    window = ProgramWindow(path_items(job.path), 0.005, 3, path)
    held = 0
    for rows in run.chunks():
        x = rows[:, 4:7]
        window.nearest(x, rows[:, 1], x)
        held = max(held, window.arrays[0].shape[0])
    assert window.count > 19_000 and held < 10_000, (window.count, held)


def test_the_plots_feet_are_on_the_program_at_the_contour_error(tmp_path):
    """The kept series of a program's run adds each foot's point: on the foot's block at its fraction (a line's
    point and arc_point written here), and as far from the actual position as the contour error says."""
    from nurbsinterp.cli.common import load
    from nurbsinterp.config.gcode import read_gcode
    from nurbsinterp.motion.pipeline import LookAhead, path_items
    from nurbsinterp.servo import load_servo
    from nurbsinterp.simulation import simulate

    path = program(tmp_path, """
        G21 G90 G64 F3000
        G1 X10 Y0 Z0
        G3 X20 Y0 I5 J0
        G2 X30 Y0 Z-1 I5 J0
        G1 X30 Y-10
        G17 G3 X30 Y-10 I-5 J0 Z2
        G1 X0 Y-10 Z0
        M2
        """)
    job = load(path, stream=True, every_profile=True, **LIMITS)
    run = LookAhead(job, 0.005)
    window = ProgramWindow(path_items(job.path), 0.005, 3, path)
    _, series = simulate(None, load_servo(SERVO), run.columns, run.chunks(), window=window, keep_series=True)
    n = 3
    act, err, foot = series[:, 6:9], series[:, 9], series[:, 12]
    points = series[:, 13:16]
    assert series.shape[1] == 16
    assert np.max(np.abs(np.linalg.norm(act - points, axis=1) - err)) <= 1e-12 * (1 + np.abs(act).max())
    blocks = [item_arrays(b) for b in read_gcode(path).blocks]
    arcs = 0
    for f, p in zip(foot, points):
        j = min(int(math.floor(f)), len(blocks) - 1)
        t = f - j
        kind, P0, P1, C, N, sweep, rise = (a[0] for a in blocks[j])
        if kind == seg.LINE:
            want = P0 + t * (P1 - P0)
        else:
            arcs += 1
            want = arc_point(P0, C, N, sweep, rise, t * sweep)
        assert np.max(np.abs(want[:n] - p)) <= 1e-9, (f, want, p)
    assert arcs > 0 and err.max() > 1e-4


def test_plot_of_a_program(capsys, tmp_path):
    path = program(tmp_path, random_program(np.random.default_rng(12), "corners", n=20))
    png = tmp_path / "run.png"
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", path, "--tolerance", "5um", "--servo", SERVO,
                              "--plot", str(png), "--max-accel", "1000")
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert str(png) in err


def model_trace(capsys, tmp_path, path):
    """The program planned with look-ahead (5 um, 1000 mm/s^2) through the xyz servo: (command ticks, the trace's
    columns, its rows)."""
    trace = tmp_path / "trace.csv"
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", path, "--tolerance", "5um", "--servo", SERVO,
                              "--max-accel", "1000", "-o", str(trace), "--json")
    assert code == 0, err
    with open(trace) as fh:
        cols = fh.readline().strip().split(",")
    return json.loads(out)["command_ticks"], cols, np.loadtxt(trace, delimiter=",", skiprows=1, ndmin=2)


def test_a_capture_is_measured_against_the_program(capsys, tmp_path):
    """A capture of a look-ahead plan: its received commands checked against the plan, its positions' contour
    error the least distance from the program's blocks within reach (brute force here), tick by tick."""
    path = program(tmp_path, random_program(np.random.default_rng(13), "corners", n=30))
    commands, cols, rows = model_trace(capsys, tmp_path, path)
    cmd = rows[:, [cols.index(f"{a}_cmd") for a in "xyz"]]
    # the machine: the model's positions, off by a few micrometres that vary from tick to tick
    rng = np.random.default_rng(14)
    pos = rows[:, [cols.index(f"{a}_act") for a in "xyz"]] + rng.uniform(-3e-3, 3e-3, (rows.shape[0], 3))
    k = np.minimum(rows[:, 0], commands - 1).astype(int)  # the capture's k stays at the last command's in the hold
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(f"{int(kk)} " + " ".join("%f" % v for v in (*c, *p)) + "\n"
                           for kk, c, p in zip(k, cmd, pos)))
    measured = tmp_path / "measured.csv"
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", path, "--tolerance", "5um", "--servo", SERVO,
                              "--max-accel", "1000", "--actual", str(cap), "-o", str(measured), "--json")
    assert code == 0, err
    report = json.loads(out)
    with open(measured) as fh:
        mcols = fh.readline().strip().split(",")
    mrows = np.loadtxt(measured, delimiter=",", skiprows=1, ndmin=2)
    got = np.array([[float("%f" % v) for v in p] for p in pos[:mrows.shape[0]]])
    meas = mrows[:, [mcols.index(f"{a}_meas") for a in "xyz"]]
    assert np.max(np.abs(meas - got)) <= 5e-10
    err_meas = mrows[:, mcols.index("contour_error_meas")]
    cmd_m = mrows[:, [mcols.index(f"{a}_cmd") for a in "xyz"]]
    reach = 2.0 * (np.linalg.norm(meas - cmd_m, axis=1) + 0.005) + 1e-9
    want = brute_contour(path, meas, mrows[:, mcols.index("u")], reach)
    # the trace's 9 decimals of the positions and of u (a seed only: the reach has 1e-9 to spare)
    assert np.max(np.abs(err_meas - want)) <= 2e-9, np.max(np.abs(err_meas - want))
    assert report["measured"]["contour_error_max"] == pytest.approx(err_meas.max(), abs=2e-9)
    assert report["measured"]["contour_error_max"] > report["contour_error_max"] - 6e-3


def test_the_plot_draws_the_machine_on_its_own_feet(capsys, tmp_path):
    """simulate --plot with a capture: the kept series carries the machine's positions, contour error and feet
    (simulation.series_columns), each foot's point at exactly that contour error from its position; and the PNG."""
    import io

    from nurbsinterp.capture import Capture, parse_columns
    from nurbsinterp.cli.common import load
    from nurbsinterp.motion.pipeline import LookAhead, program_window
    from nurbsinterp.servo import load_servo
    from nurbsinterp.simulation import series_columns, simulate

    path = program(tmp_path, random_program(np.random.default_rng(21), "corners", n=20))
    commands, cols, rows = model_trace(capsys, tmp_path, path)
    rows = rows[:commands + 40]  # the capture stops 40 ticks into the hold: the series has NaN after it
    cmd = rows[:, [cols.index(f"{a}_cmd") for a in "xyz"]]
    pos = rows[:, [cols.index(f"{a}_act") for a in "xyz"]] + np.random.default_rng(22).uniform(-3e-3, 3e-3,
                                                                                                 (rows.shape[0], 3))
    k = np.minimum(rows[:, 0], commands - 1).astype(int)
    text = "".join(f"{int(kk)} " + " ".join("%f" % v for v in (*c, *p)) + "\n" for kk, c, p in zip(k, cmd, pos))
    cap = tmp_path / "capture.txt"
    cap.write_text(text)

    job = load(str(path), stream=True, every_profile=True, max_accel="1000")
    run = LookAhead(job, 0.005)
    windows = [program_window(job, 0.005, str(path)) for _ in range(2)]  # as simulate's CLI makes them
    capture = Capture(io.BytesIO(text.encode()), "capture", parse_columns("k,x_cmd,y_cmd,z_cmd,x,y,z", 3))
    report, series = simulate(None, load_servo(SERVO), run.columns, run.chunks(), window=windows[0],
                              measured_window=windows[1], actual=capture, keep_series=True)
    col = series_columns(3, program=True, measured=True)
    assert series.shape[1] == col["width"]
    have = np.isfinite(series[:, col["err_meas"]])
    kept_k = series[:, col["k"]].astype(int)
    assert np.array_equal(have, kept_k < rows.shape[0])
    meas, err_meas = series[have, col["meas"]], series[have, col["err_meas"]]
    printed = np.array([[float("%f" % v) for v in p] for p in pos[kept_k[have]]])
    assert np.array_equal(meas, printed)
    on_foot = np.linalg.norm(meas - series[have, col["foot_meas_point"]], axis=1)
    assert np.max(np.abs(on_foot - err_meas)) <= 1e-12 * (1 + np.abs(meas).max())
    assert np.nanmax(series[:, col["err_meas"]]) <= report.measured.contour_error_max
    # the model's columns where they always were
    act, foot_point = series[:, col["act"]], series[:, col["foot_point"]]
    assert np.max(np.abs(np.linalg.norm(act - foot_point, axis=1) - series[:, col["err"]])) <= 1e-12 * (
        1 + np.abs(act).max())

    png = tmp_path / "machine.png"
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", path, "--tolerance", "5um", "--servo", SERVO,
                              "--max-accel", "1000", "--actual", str(cap), "--plot", str(png))
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
