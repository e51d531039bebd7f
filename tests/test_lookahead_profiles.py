"""The look-ahead holds the machine's limits with every profile, on random programs (issue 29's acceptance:
"limits by finite differences on random programs with every profile").

Hypothesis writes G-code programs -- noisy short moves, real corners, near-reversals and reversals, arcs (G2/G3 in
G17) and helices, 1 um moves, rapids, G61 / G61.1 / G64 P, G4 dwells, M0 -- and random machines: per-axis max
velocity and acceleration, the profile's feedrate, accel_time, time constant and max_accel, the period
(0.25 .. 2 ms) and the blend tolerance (0, or 0.1 .. 50 um log-uniformly); 2-D where no Z changes, 3-D
else.  Each is planned with each profile type, and every tick of the stream is checked against references
independent of the planner:

* per axis, |Δx/T| <= v_i and |Δ²x/T²| <= a_i by finite differences of the emitted positions
  (test_lookahead.check_limits: the caps' rounding, 1e-12 relative, plus 2ε/T and 4ε/T² for the positions'
  own rounding ε, a few ulps of |x|, of the arc length and of V·t -- at |x| ~ 100 mm and T = 0.25 ms some
  1e-13 mm, 1e-5 mm/s², far below any limit drawn here);
* the column a within the tangential acceleration the profile maps to (limits.motion_limits(job, tol).accel:
  F/Ta, the bell's and the exponential's peaks, max_accel), exactly: a is one of the segments' acceleration caps,
  each a min() with that limit; with the bell, whose ramps are jerk-limited, a changing by at most J·T a tick;
* the column v within the feedrate of the block the tick is on (its F word as the reader resolved it, the
  profile's where the block has none or the command line overrides it, the rapid feedrate on G0), to a few ulps
  (a cruise's speed is sqrt(cap²));
* k consecutive from 0 and t = k·T to the bit; the last tick at the program's end point exactly, at rest.

What they found (the regressions below, fixed in segments.py): a blend whose radius was out of step with the
lines' trim when its sag loop ran out of iterations (the commands jumped up to 10 um where it ended: 12x an axis'
acceleration, on 8 of 600 random noisy programs at 0.1 .. 0.5 um), and a ZeroDivisionError at tolerances below
~6.5e-163 mm (a blend's radius squared underflowing: blends below segments.MIN_BLEND are now none).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from test_lookahead import axes_of, check_limits, col, program

from nurbsinterp.cli.common import load
from nurbsinterp.errors import SpecError
from nurbsinterp.motion import segments as seg
from nurbsinterp.motion.pipeline import LookAhead

PROFILES = ("trapezoidal", "bell", "exponential", "adaptive")
MAX_BLOCKS = 60
FEED_ROUNDING = 4 * np.finfo(float).eps  # v of a cruise is sqrt(cap²): within an ulp or two of the cap


# --------------------------------------------------------------------------- random programs


def _xyz(p):
    return f"X{p[0]:.6f} Y{p[1]:.6f} Z{p[2]:.6f}"


def _read(p):
    """The point as the program states it (6 decimals): where the reader will put the tool."""
    return np.array([float(f"{c:.6f}") for c in p])


def _heading(angle, climb=0.0):
    return np.array([math.cos(angle), math.sin(angle), climb])


@st.composite
def programs(draw):
    """G-code text of a random 3-D program of at most MAX_BLOCKS + 1 motion blocks."""
    lines = ["G21 G90 G17 " + draw(st.sampled_from(["G64", "G64 P0.01", "G61", "G61.1"])),
             f"F{draw(st.floats(300, 6000)):.3f}"]
    p = np.zeros(3)
    heading = 0.0
    moves = 0
    pieces = draw(st.lists(st.sampled_from(["noisy", "corner", "reversal", "arc", "micro", "rapid", "mode", "dwell",
                                            "stop", "feed", "plunge"]), min_size=1, max_size=14))
    for piece in pieces:
        if moves >= MAX_BLOCKS:
            break
        room = MAX_BLOCKS - moves
        if piece == "noisy":  # short moves along a slowly turning heading, rounded to 0.1 um, with 0.3 um noise
            # (a run's moves from a seed: drawn one by one they would overrun hypothesis's buffer on long programs)
            rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
            for _ in range(min(room, draw(st.integers(2, 30)))):
                heading += rng.uniform(-0.15, 0.15)
                q = p + rng.uniform(0.05, 0.5) * _heading(heading)
                q[:2] += rng.uniform(-3e-4, 3e-4, 2)
                p = _read(np.round(q, 4))
                lines.append(f"G1 {_xyz(p)}")
                moves += 1
        elif piece == "corner":  # a real corner, in the plane or climbing
            heading += draw(st.one_of(st.sampled_from([0.3, math.pi / 2, -2.0, 2.8]), st.floats(-3.1, 3.1)))
            p = _read(p + draw(st.floats(0.2, 3.0)) * _heading(heading, draw(st.sampled_from([0.0, 0.0, 0.4, -1.0]))))
            lines.append(f"G1 {_xyz(p)}")
            moves += 1
        elif piece == "reversal":  # a reversal, or nearly one (a turn just short of 180 degrees)
            heading += math.pi - draw(st.sampled_from([0.0, 1e-3, 0.02, 0.05, -0.02]))
            p = _read(p + draw(st.floats(0.1, 3.0)) * _heading(heading))
            lines.append(f"G1 {_xyz(p)}")
            moves += 1
        elif piece == "arc":  # G2/G3 in G17, tangent to the move before or not, a helix where Z changes
            cw = draw(st.booleans())
            r = draw(st.floats(0.05, 3.0))
            side = -1.0 if cw else 1.0
            to_centre = heading + side * math.pi / 2 + (0.0 if draw(st.booleans()) else draw(st.floats(-1.5, 1.5)))
            centre = p + r * _heading(to_centre)
            a0 = math.atan2(p[1] - centre[1], p[0] - centre[0])
            sweep = draw(st.floats(0.05, 2 * math.pi - 0.05))
            a1 = a0 - sweep if cw else a0 + sweep
            dz = draw(st.sampled_from([0.0, 0.0, 0.5, -1.0, 2.0]))
            end = _read([centre[0] + r * math.cos(a1), centre[1] + r * math.sin(a1), p[2] + dz])
            lines.append(f"{'G2' if cw else 'G3'} {_xyz(end)} I{centre[0] - p[0]:.6f} J{centre[1] - p[1]:.6f}")
            p = end
            heading = a1 - math.pi / 2 if cw else a1 + math.pi / 2
            moves += 1
        elif piece == "micro":  # 1 um moves
            rng = np.random.default_rng(draw(st.integers(0, 2 ** 32 - 1)))
            for _ in range(min(room, draw(st.integers(3, 20)))):
                heading += rng.uniform(-0.05, 0.05)
                p = _read(p + 1e-3 * _heading(heading))
                lines.append(f"G1 {_xyz(p)}")
                moves += 1
        elif piece == "rapid":
            p = _read(p + [draw(st.floats(-5, 5)), draw(st.floats(-5, 5)), draw(st.floats(-2, 2))])
            lines.append(f"G0 {_xyz(p)}")
            moves += 1
        elif piece == "plunge":  # straight down and on (the raster's retract then plunge, when after a rapid up)
            p = _read(p + [0.0, 0.0, -draw(st.floats(0.1, 2.0))])
            lines.append(f"G1 {_xyz(p)}")
            moves += 1
        elif piece == "mode":
            lines.append(draw(st.sampled_from(["G64", "G61", "G61.1"])) if draw(st.booleans())
                         else f"G64 P{draw(st.floats(0.001, 0.05)):.4f}")
        elif piece == "dwell":
            lines.append(f"G4 P{draw(st.floats(0.001, 0.05)):.4f}")
        elif piece == "stop":
            lines.append("M0")
        else:
            lines.append(f"F{draw(st.floats(300, 6000)):.3f}")
    # a last move, so that no program moves nowhere (its blocks may all be of zero length)
    lines.append(f"G1 {_xyz(_read(p + [0.5, 0.3, 0.0]))}")
    lines.append("M2")
    return "\n".join(lines) + "\n"


@st.composite
def machines(draw, profile):
    """(command-line options of a random machine and profile, the blend tolerance in mm)."""
    number = st.floats
    options = {
        "profile_type": profile,
        "axis_max_velocity": ",".join(f"{a}={draw(number(5, 300)):.6g}" for a in "xyz"),
        "axis_max_accel": ",".join(f"{a}={draw(number(50, 5000)):.6g}" for a in "xyz"),
        "period": f"{draw(number(0.25e-3, 2e-3)):.6g}",
    }
    if draw(st.booleans()):  # the profile's feedrate overrides the program's F words (rapids too)
        options["feedrate"] = f"{draw(number(5, 200)):.6g}"
    if profile != "adaptive" or draw(st.booleans()):
        options["accel_time"] = f"{draw(number(0.005, 1.0)):.6g}"
    if draw(st.booleans()):
        options["max_accel"] = f"{draw(number(50, 5000)):.6g}"
    if profile == "exponential" and "accel_time" in options and draw(st.booleans()):
        options["time_constant"] = f"{float(options['accel_time']) * draw(number(0.1, 1.0)):.6g}"
    # 0 (no blends), or 0.1 .. 50 um: far below 0.1 um an arc's chord cap 2/T·sqrt(2ρδ) and an unblended
    # joint's 2δ/(T sin(θ/2)) make the motion legitimately take more than --max-ticks (a clean refusal), and
    # below ~1e-155 mm the blend's radius underflows (test_tiny_tolerance_is_planned_or_refused)
    # (log-uniform: the sub-micrometre tolerances, where a blend's chord sag nearly fills it, are as likely as the
    # coarse ones)
    tolerance = draw(st.one_of(st.just(0.0), number(-4.0, math.log10(0.05)).map(lambda e: 10.0 ** e)))
    return options, tolerance


# --------------------------------------------------------------------------- the checks


def axis_limits(job):
    """(max velocity (dim,), max acceleration (dim,)) of the job's axes, inf where none is given."""
    vel = np.full(job.path.dim, math.inf)
    acc = np.full(job.path.dim, math.inf)
    for name, v, a, _ in job.profile.axes:
        i = "xyz".index(name)
        if i < job.path.dim:
            vel[i] = math.inf if v is None else v
            acc[i] = math.inf if a is None else a
    return vel, acc


def block_feedrates(job, limits):
    """The feedrate each block asks for (mm/s), as the reader resolved its F words: the profile's where the block
    has none or the command line overrides them, the rapid feedrate on G0."""
    out = []
    for b in job.path.blocks:
        if job.feedrate_override:
            out.append(limits.feedrate)
        elif b.rapid:
            out.append(limits.rapid_feedrate)
        else:
            out.append(limits.feedrate if b.feedrate is None else b.feedrate)
    return np.array(out)


def check_stream(run, rows):
    """Every check of the module's docstring on one planned run; returns what it measured."""
    job, lim = run.job, run.limits
    T = run.period
    assert rows.shape[1] == len(run.columns) and np.all(np.isfinite(rows))
    k = rows[:, col(run, "k")]
    assert np.array_equal(k, np.arange(rows.shape[0], dtype=float))
    assert np.array_equal(rows[:, col(run, "t")], k * T)
    vel, acc = axis_limits(job)
    v_max, a_max = check_limits(run, rows, vel, acc)
    # the tangential acceleration the profile maps to
    a = rows[:, col(run, "a")]
    assert np.abs(a).max() <= lim.accel, (np.abs(a).max(), lim.accel, lim.source)
    # the bell's jerk (its ramps jerk-limited): the acceleration column changes by at most J·T a tick
    J = lim.tangential_jerk()
    if math.isfinite(J):
        assert np.abs(np.diff(a)).max() <= J * T * (1 + 1e-9), (np.abs(np.diff(a)).max(), J * T)
    # the feed within the block's F
    v = rows[:, col(run, "v")]
    assert v.min() >= 0.0
    feed = block_feedrates(job, lim)[rows[:, col(run, "n")].astype(int)]
    over = v / feed
    assert over.max() <= 1 + FEED_ROUNDING, (over.max(), int(over.argmax()))
    # the end: the program's end point exactly, at rest
    end = np.asarray(job.path.blocks[-1].end, dtype=float)
    assert np.array_equal(axes_of(run, rows)[-1], end)
    assert v[-1] == 0.0 and a[-1] == 0.0
    return v_max / vel, a_max / acc


def blend_gap(run):
    """The largest distance (mm) between a corner blend's end and the start of the segment after it: 0 to rounding
    when the blend's radius R and the lines' trim d agree (d = R tan(θ/2)).  See test_blend_meets_the_next_line."""
    segs = np.concatenate(list(LookAhead(run.job, run.limits.tolerance)._segments()))
    end, start = np.empty(3), np.empty(3)
    gap = 0.0
    for i in np.flatnonzero(segs[:-1, seg.UKIND] == seg.U_BLEND_OUT):
        seg.segment_point(segs[i], segs[i, seg.LEN], end)
        seg.segment_point(segs[i + 1], 0.0, start)
        gap = max(gap, float(np.abs(end - start).max()))
    return gap


#: a blend's end and the next line's start, as far apart as rounding allows: a few ulps of the coordinates
#: (<= 100 mm here: 1.4e-14 mm each) -- 1e-9 mm is the known defect's threshold, not a tolerance of the checks
STALE_BLEND = 1e-9


def plan(path, options, tolerance):
    job = load(path, every_profile=True, **options)
    run = LookAhead(job, tolerance)
    return run, np.concatenate(list(run.chunks()))


# --------------------------------------------------------------------------- random programs, every profile


@pytest.mark.parametrize("profile", PROFILES)
@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_random_programs_hold_the_limits(tmp_path_factory, profile, data):
    text = data.draw(programs(), label="program")
    options, tolerance = data.draw(machines(profile), label="machine")
    path = program(tmp_path_factory.mktemp("p"), text)
    run, rows = plan(path, options, tolerance)
    assert blend_gap(run) <= STALE_BLEND
    check_stream(run, rows)


# --------------------------------------------------------------------------- one program with every feature


EVERY_FEATURE = """
G21 G90 G17 G64 P0.01
F2400
G0 X0 Y0 Z5
G1 Z0 F600
G1 X10 F3000
G1 X10.2 Y0.05
G1 X10.4 Y0.1003
G1 X10.6 Y0.1498
G3 X12.7914 Y3.7827 I-0.7208 J2.9121
G2 X16.6742 Y4.7437 Z-1 I1.9414 J0.4805
G1 X16.6744 Y4.7427
G1 X16.6747 Y4.7417
G1 X16.6749 Y4.7407
G61
G1 X20 Y8
G1 X16 Y8.001
G61.1
G1 X12 Y9
G64
G4 P0.02
G1 X8 Y9
M0
G1 X2 Y3 Z2
G0 X0 Y0 Z5
M2
"""


@pytest.mark.parametrize("profile", PROFILES)
@pytest.mark.parametrize("period, tolerance", [(0.25e-3, 0.05), (2e-3, 0.0), (1e-3, 0.005)])
def test_every_feature_with_every_profile(tmp_path, profile, period, tolerance):
    """A program with a retract and plunge, noisy short moves, an arc and a helix, 1 um moves, G61, G61.1, a
    dwell, M0 and rapids, on a machine whose axes differ, planned with each profile: every check holds."""
    options = {"profile_type": profile, "axis_max_velocity": "x=120,y=60,z=20", "axis_max_accel": "x=2000,y=800,z=300",
               "period": str(period), "accel_time": "0.05"}
    run, rows = plan(program(tmp_path, EVERY_FEATURE), options, tolerance)
    v_share, a_share = check_stream(run, rows)
    assert run.facts.arcs >= 2 and run.facts.stops >= 4
    assert a_share.max() > 0.5  # the axes' limits bind somewhere: the check is not vacuous


# --------------------------------------------------------------------------- regressions


@pytest.mark.parametrize("tolerance", [1e-300, 6e-163])
def test_tiny_tolerance_is_planned_or_refused(tmp_path, tolerance):
    """A tolerance far below any machine's resolution is planned (the corner passed at rest, in effect) or refused
    in one line (SpecError), never a traceback (it was a ZeroDivisionError below 6.5e-163 mm: a blend's radius
    squared underflowed in segments._arc_caps)."""
    path = program(tmp_path, "G21 G90 F3000\nG1 X10\nG1 Y10\nM2\n")
    options = {"profile_type": "adaptive", "axis_max_accel": "x=1000,y=1000"}
    try:
        run, rows = plan(path, options, tolerance)
    except SpecError:
        return
    check_stream(run, rows)


def test_blend_meets_the_next_line(tmp_path):
    """Two lines turning by 3.3 degrees, a blend within 0.44 um at a feed whose chord sag nearly fills it.

    The blend's loop used to leave after 8 iterations with d lowered but R = d / tan(theta/2) of the previous d:
    the lines trimmed by 11.009 um, the arc's R tan(theta/2) 12.775 um, ending 3.53 um from the next line's start;
    the commands jumped there (x axis 1963 mm/s^2 by second differences, 12.4x its 157.824)."""
    path = program(tmp_path, "G21 G90 G64\nF5816.2\nG1 X0.265100 Y0.009900\nG1 X0.374500 Y0.020400\nM2\n")
    options = {"profile_type": "adaptive", "axis_max_velocity": "x=23.1425,y=278.005",
               "axis_max_accel": "x=157.824,y=1856.31", "period": "0.00135849"}
    run, rows = plan(path, options, 0.00044328844036623145)
    assert blend_gap(run) <= STALE_BLEND
    check_stream(run, rows)


def test_an_axis_without_an_acceleration_limit_is_refused_only_where_it_moves(tmp_path):
    """Per-axis limits for x and y only, no tangential one: a program that never moves z is planned (it was
    refused: "needs an acceleration limit for every axis that moves"), and the first block that moves z -- a line,
    or an arc in the XZ plane whose ends share their z -- is refused in one line naming its line."""
    options = {"profile_type": "adaptive", "axis_max_accel": "x=1000,y=1000", "axis_max_velocity": "x=100,y=100"}
    flat = program(tmp_path, "G21 G90 F600\nG1 X10 Z0\nG1 Y10\nG2 X20 Y10 I5 J0\nM2\n", "flat.ngc")
    run, rows = plan(flat, options, None)
    check_stream(run, rows)
    for text, line in (("G21 G90 F600\nG1 X10\nG1 Z-1\nM2\n", 3), ("G21 G90 G18 F600\nG1 X1\nG2 X1 Z0 I5\nM2\n", 3)):
        path = program(tmp_path, text, f"moves_z_{line}.ngc")
        with pytest.raises(SpecError, match=rf": line {line} moves z, whose acceleration nothing limits: set "
                                            r"profile\.max_accel"):
            plan(path, options, None)
    # a YAML path's NURBS block rising in z between ends at z = 0: named by its index among the blocks
    rising = program(tmp_path, """
        path:
          start: [0, 0, 0]
          blocks:
            - line: {to: [10, 0, 0]}
            - nurbs: {degree: 2, control_points: [[10, 0, 0], [20, 0, 5], [30, 0, 0]]}
        """, "rising.yaml")
    with pytest.raises(SpecError, match=r"rising\.yaml: block 1 moves z, whose acceleration nothing limits"):
        plan(rising, options, 0.005)


def test_the_default_profile_s_ramp_never_holds_back_a_machine_with_limits(tmp_path):
    """The tangential acceleration the look-ahead holds (motion.limits.motion_limits): the default profile on a
    machine with limits of its own is planned to the machine's (it was F/Ta = 100/0.5 = 200 mm/s^2 under a
    1 000 mm/s^2 machine); a profile the user chose -- its type, or its accel_time -- keeps its ramp; with no
    machine limit the default ramp is what there is."""
    from nurbsinterp.motion.limits import motion_limits

    path = program(tmp_path, "G21 G90 F600\nG1 X10\nG1 Y10\nM2\n")
    machine = {"axis_max_accel": "x=1000,y=1000,z=1000", "axis_max_velocity": "x=100,y=100,z=100"}

    def accel(**options):
        return motion_limits(load(path, every_profile=True, **options), None).accel

    assert accel(**machine) == math.inf  # the axes bind, each its own
    assert accel(**machine, profile_type="trapezoidal") == pytest.approx(100 / 0.5, rel=1e-15)
    assert accel(**machine, accel_time="0.25") == pytest.approx(100 / 0.25, rel=1e-15)
    assert accel(**machine, profile_type="bell") == pytest.approx(0.5 * math.pi * 100 / 0.5, rel=1e-15)
    assert accel(**machine, profile_type="adaptive") == math.inf  # no ramp of its own
    assert accel(**machine, profile_type="adaptive", accel_time="0.25") == pytest.approx(400, rel=1e-15)
    assert accel() == pytest.approx(100 / 0.5, rel=1e-15)  # no machine: the default ramp
    # a machine that limits x and y alone, on a program that moves z: the ramp stays, for z (a flat program's
    # path is 2-D, and x and y are every axis it has)
    assert accel(axis_max_accel="x=1000,y=1000") == math.inf
    path = program(tmp_path, "G21 G90 F600\nG1 X10\nG1 Z-1\nM2\n", "plunge.ngc")
    assert accel(axis_max_accel="x=1000,y=1000") == pytest.approx(100 / 0.5, rel=1e-15)
    assert accel(max_accel="300") == 300  # a path limit is a machine's limit too
