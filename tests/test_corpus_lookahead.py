"""Real CAM programs planned with look-ahead (issue 29's acceptance): every corpus program (``cam_*``) plans
within --max-ticks, with its motion time where its own F words, capped by the machine's axes, put it, and
every axis within its limits on every tick.

Opt-in: the corpus is ``../shared/corpus`` beside the checkout (other people's programs, under their own
licences: read from there, never copied into this tree); without it the tests skip.  The machine is the one
README's CAM table uses (LinuxCNC's harness machine: 100 mm/s and 1 000 mm/s² per axis, rapids 6 000 mm/min,
T = 1 ms) with a 5 µm tolerance.

The nominal time is Σ L / F over the blocks, F the block's feed (rapids: the rapid feedrate; none: the
profile's) capped on a line by the axes (v_i / |τ_i|): no plan of the programmed path can be faster.  A blend
shortens the path: it replaces 2d of its corner's legs by an arc at least as long as its chord, 2d cos(θ/2),
so by at most 4d sin²(θ/4) = 2e sin(θ/2) ≤ 2e, e = d tan(θ/4) ≤ the tolerance; passed at most at the lowest
feed F_min of the program, that is at most 2·tol/F_min a blend: the motion time must not be below the
nominal less that (GrimReaper: 75 416 blends at F300 cut 11.4 s of its 9 799 s).  Above it by the corners,
ramps and stops, but never above the time of stopping at every joint: each block from rest to rest, a line at
min(F, v_i/|τ_i|) and min a_i/|τ_i|, an arc at its feed capped as the planner caps it (the centripetal part
at most 60 % of the smallest axis acceleration, the tangential 40 %) — look-ahead only removes stops.
Measured (smoothing on, the default): 1.01–1.04 × the nominal on the three longest (MB-3.1 1 266.6 s against
1 228.5 s, DXF473 7 043.9 s against 6 805 s, vcarve 570.1 s against 563 s); 3.1 × on LHchips4 (236.1 s
against 75.2 s: short moves and sharp corners at F capped to 100 mm/s, where 1 000 mm/s² binds), still well
below stopping at every joint.  A refitted curve can be shorter than its moves by more than a blend's
allowance (it straightens their rounding noise): the lower bound does not allow for that, and holds on these
programs by a margin of 0.2 % and more, which this test watches.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.cli.common import load
from nurbsinterp.motion.pipeline import LookAhead

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus"
PROGRAMS = sorted(p for d in CORPUS.glob("cam_*") for p in d.iterdir() if p.suffix in (".nc", ".ngc", ".gcode"))
MACHINE = dict(profile_type="adaptive", axis_max_velocity="x=100,y=100,z=100", axis_max_accel="x=1000,y=1000,z=1000",
               rapid_feedrate="6000mm/min")
VMAX, AMAX = 100.0, 1000.0
MAX_TICKS = 100_000_000

pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"the corpus is not at {CORPUS} (opt-in)")


def rest_to_rest(length, feed, accel):
    """The time of a move of *length* from rest to rest at most at *feed* and *accel* (a trapezoid)."""
    return np.where(length >= feed * feed / accel, length / feed + feed / accel, 2 * np.sqrt(length / accel))


def nominal_time(job) -> tuple[float, float, float]:
    """Σ L / F over the program's blocks, the lowest F, and the time of stopping at every joint (see the
    module's docstring)."""
    lim_v = np.full(3, VMAX)
    profile = job.profile
    total = 0.0
    lowest = math.inf
    stopping = 0.0
    for item in job.path.items():
        if item.kind == "moves":
            delta = item.ends - item.starts
            length = np.sqrt((delta * delta).sum(axis=1))
            feed = np.where(item.rapid, profile.rapid_feedrate, np.where(np.isnan(item.feeds), profile.feedrate,
                                                                         item.feeds))
            with np.errstate(divide="ignore"):
                cap = (lim_v / np.abs(delta / length[:, None])).min(axis=1)
                accel = (AMAX / np.abs(delta / length[:, None])).min(axis=1)
            total += float((length / np.minimum(feed, cap)).sum())
            lowest = min(lowest, float(np.minimum(feed, cap).min()))
            stopping += float(rest_to_rest(length, np.minimum(feed, cap), accel).sum())
        elif item.kind == "line":
            delta = item.end - item.start
            length = float(np.linalg.norm(delta))
            feed = profile.rapid_feedrate if item.rapid else (item.feedrate or profile.feedrate)
            with np.errstate(divide="ignore"):
                cap = float((lim_v / np.abs(delta / length)).min())
                accel = float((AMAX / np.abs(delta / length)).min())
            total += length / min(feed, cap)
            lowest = min(lowest, feed, cap)
            stopping += float(rest_to_rest(length, min(feed, cap), accel))
        else:  # an arc (a helix): its length at its feed (a lower bound of its time: its caps are below F)
            radius = float(np.linalg.norm(item.start - item.center))
            length = math.hypot(radius * item.sweep, item.rise)
            feed = item.feedrate or profile.feedrate
            total += length / feed
            lowest = min(lowest, feed)
            v = min(feed, VMAX, math.sqrt(0.6 * AMAX * radius))
            stopping += float(rest_to_rest(length, v, 0.4 * AMAX))
    return total, lowest, stopping


def test_the_corpus_is_there():
    assert len(PROGRAMS) >= 9, PROGRAMS


@pytest.mark.parametrize("program", PROGRAMS, ids=lambda p: p.name)
def test_every_cam_program_plans_in_its_nominal_time_within_the_limits(program):
    job = load(str(program), stream=True, **MACHINE)
    run = LookAhead(job, 0.005, max_ticks=MAX_TICKS)
    for _ in run.chunks():
        pass
    facts = run.facts
    nominal, lowest, stopping = nominal_time(load(str(program), stream=True, **MACHINE))
    assert facts.ticks <= MAX_TICKS
    shortened = facts.blends * 2 * 0.005 / lowest
    assert facts.motion_time >= (nominal - shortened) * (1 - 1e-9), (facts.motion_time, nominal, shortened)
    # the stops' own rests on ticks and dwells: a tick each, and whatever the program's G4 asks
    assert facts.motion_time <= stopping + facts.rest_time + run.period, (facts.motion_time, nominal, stopping)
    v, a = facts.axis_extremes[0], facts.axis_extremes[1]
    # a tick's point is found from its arc length S since the program's start, at t = kT since it: each carries
    # its rounding, ulp(S) + v ulp(t), into the commands (some 1e-11 mm at S ~ 1e5 mm), which a second
    # difference takes 4 times over T²: 1000.0000366 mm/s² was measured on flower_mold.nc (S 7.5e4 mm)
    T = run.period
    rounding = 4 * (np.spacing(facts.length) + VMAX * np.spacing(facts.motion_time))
    assert v.max() <= VMAX * (1 + 1e-9) + rounding / T, v
    assert a.max() <= AMAX * (1 + 1e-9) + rounding / T ** 2, (a, rounding / T ** 2)
    assert facts.worst_blend <= 0.005 * (1 + 1e-9)


JERK = 20000.0  # mm/s³ per axis
#: LHchips4 (a minute: 6 000 blocks of a jerk-limited plan) only in the slow set; the others in both
JERK_PROGRAMS = [pytest.param(p, id=p.name, marks=[pytest.mark.slow] if p.name == "LHchips4.ngc" else [])
                 for p in PROGRAMS if p.name in ("Cereal.ngc", "LHchips4.ngc", "vcarve.ngc")]


@pytest.mark.parametrize("program", JERK_PROGRAMS)
def test_cam_programs_hold_a_jerk_limit(program):
    """With a per-axis jerk limit: every axis' velocity, acceleration and jerk within its limit on every tick, by
    the stream's own differences.  LHchips4.ngc found two joint bounds short (blends turning opposite ways across
    lines of 0.1 µm; a kink turning the tangential acceleration: 20 432 mm/s³), vcarve.ngc a dropped row (a
    1.4 µm jump, 1 367 mm/s²)."""
    job = load(str(program), stream=True, axis_max_jerk=f"x={JERK:g},y={JERK:g},z={JERK:g}", **MACHINE)
    run = LookAhead(job, 0.005, max_ticks=MAX_TICKS)
    for _ in run.chunks():
        pass
    facts = run.facts
    T = run.period
    rounding = 8 * (np.spacing(facts.length) + VMAX * np.spacing(facts.motion_time))
    v, a, j = facts.axis_extremes
    assert v.max() <= VMAX * (1 + 1e-9) + rounding / T, v
    assert a.max() <= AMAX * (1 + 1e-9) + rounding / T ** 2, a
    assert j.max() <= JERK * (1 + 1e-9) + rounding / T ** 3, (j, rounding / T ** 3)
    assert facts.worst_blend <= 0.005 * (1 + 1e-9)
