"""The machine's limits as the look-ahead planner holds them, and how each profile's parameters map to them.

Per axis: max velocity v_i and max acceleration a_i (``profile.axes``, or
``--axis-max-velocity`` / ``--axis-max-accel``, or a LinuxCNC INI's
``[AXIS_X] MAX_VELOCITY / MAX_ACCELERATION``).  Along the path: the feedrate
(the blocks' own, F words, capped by the axes), the tangential acceleration A,
and for the adaptive profile its centripetal and chord limits.

The machine's limits (``profile.axes``, and ``max_accel``, ``max_jerk``,
``max_normal_accel``, ``chord_tolerance`` where given) are read with every
profile type.  A profile's own parameters add the tangential acceleration its
ramps reach (``accel_time`` Ta, the profile's feedrate F, ``profile.feedrate``),
and the lower of the two binds -- where the profile is chosen (its type or
accel_time given), or where the machine does not limit the acceleration of
every axis (nor max_accel along the path): the default profile's ramp never
binds a machine that has limits of its own:

====================  ====================================================
trapezoidal           F / Ta (its constant acceleration)
bell                  (π/2) F / Ta (the peak of its cosine ramp); jerk π² F / (2(π − 2) Ta²): F in Ta
exponential           F / Ta: its ramps' loss of time (Ta a move), below its peak c / (1 − e^(−c)) · F / Ta
adaptive              none of its own (F / Ta where accel_time is given, or nothing else limits): the machine's

(:func:`profile_ramp`: each ramp loses the time the paper's ramp of the same name loses from rest to F.)
====================  ====================================================

Without a jerk limit the ramps between junction speeds are planned at
constant acceleration (the trapezoidal shape: time-optimal under A and the
axes' limits).  With one -- the path's (``max_jerk``, ``--max-jerk``; the bell
profile's own, π² F / (2(π − 2) Ta²)) or the axes' (``profile.axes.X.max_jerk``,
``--axis-max-jerk``, an INI's ``[AXIS_X] MAX_JERK``) -- they are planned by the
jerk-limited pass (constant-jerk pieces, time-optimal under A and J: the
S-curve, of which the bell's cosine ramp is the smooth cousin), and the axes'
jerk is held as :mod:`.jerk` describes.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import SpecError
from ..names import AXES
from . import segments as seg

TANGENTIAL_SHARE = 0.4  # β: the share of each axis budget left to the tangential part on arcs (as adaptive)
#: β of a corner blend: a blend is short and passed at its cap, where the tangential part is idle; the
#: centripetal part may take 90 % (on the raster's 90° corners, 0.4 cost 2.8 ms a row change against LinuxCNC)
BLEND_TANGENTIAL_SHARE = 0.1
#: the shares of each axis' jerk budget (motion.jerk): the tangential jerk's, the V³ x_sss term's and the 3 V A x_ss
#: term's inside a segment (the last two also shared with the joints' jumps).  The spiral of benchmarks/cam.py
#: cruises at 50 mm/s on radii of 5 mm and more, whose |x_sss,i| (up to some 0.03/mm² on its fitted curve) takes a
#: fifth of 20 000 mm/s³ there
JERK_SHARES = (0.5, 0.25, 0.25)
#: what gives the look-ahead an acceleration limit, in the job's own fields (the CLI words them as its options)
ACCEL_LIMIT_REMEDY = "set profile.max_accel, accel_time > 0, or the axis' max_accel (profile.axes)"
JOINT_SHARE = 0.2  # γ: the share of each axis' acceleration an unblended joint's jump of direction may take


@dataclass(frozen=True)
class MotionLimits:
    """What the look-ahead planner holds.  mm, s; inf where there is no such limit."""

    period: float
    feedrate: float  # mm/s, the profile's (blocks without F)
    rapid_feedrate: float  # mm/s
    accel: float  # tangential, mm/s²
    jerk: float  # tangential, mm/s³
    normal_accel: float
    chord_tolerance: float
    axis_velocity: tuple  # (3,) mm/s
    axis_accel: tuple  # (3,) mm/s²
    tolerance: float  # mm: how far a blend may leave the programmed path (G64 P where the program sets none)
    override_program: bool = True  # the tolerance replaces the program's own G64 P
    source: str = ""  # where A came from, for the summary
    axis_jerk: tuple = (math.inf, math.inf, math.inf)  # (3,) mm/s³

    def unlimited_axes(self) -> tuple:
        """The axes whose moves nothing limits in acceleration (no max_accel of their own, no tangential A): a
        block moving along one is refused (motion.pipeline), an axis that never moves may go without."""
        if math.isfinite(self.accel):
            return ()
        return tuple(i for i, a in enumerate(self.axis_accel) if not math.isfinite(a))

    def tangential_jerk(self) -> float:
        """The jerk the windowed pass holds along the path (inf: none, constant-acceleration ramps): the path's
        own, and its share of the smallest axis' jerk (JERK_SHARES)."""
        return min(self.jerk, JERK_SHARES[0] * min(self.axis_jerk))

    def vector(self) -> np.ndarray:
        """The limits as the segment kernels take them (segments.L_* indices)."""
        out = np.empty(seg.NLIM)
        out[seg.L_PERIOD] = self.period
        out[seg.L_BETA] = TANGENTIAL_SHARE
        out[seg.L_GAMMA] = JOINT_SHARE
        out[seg.L_ACCEL] = self.accel
        out[seg.L_NORMAL] = self.normal_accel
        out[seg.L_CHORD] = self.chord_tolerance
        out[seg.L_VEL:seg.L_VEL + 3] = self.axis_velocity
        out[seg.L_ACC:seg.L_ACC + 3] = self.axis_accel
        out[seg.L_BLEND_BETA] = BLEND_TANGENTIAL_SHARE
        out[seg.L_JERK:seg.L_JERK + 3] = self.axis_jerk
        out[seg.L_RAMP_JERK] = self.tangential_jerk()
        out[seg.L_JUMP_SHARE] = 1.0 - JERK_SHARES[0]
        out[seg.L_SPEED_SHARE] = JERK_SHARES[1]
        return out


def profile_ramp(kind: str, F: float, Ta: float) -> tuple[float, float]:
    """(acceleration, jerk) of a profile's ramp as the look-ahead's policy (mm/s², mm/s³; inf: none): the motion
    whose ramp from rest to F loses the time the paper's own ramp loses, so that a move of length L from rest to
    rest takes L/F + that loss either way (README, "One profile, one motion").

    trapezoidal (and adaptive, given accel_time): F/Ta, the paper's ramp itself (the loss Ta).
    bell: its cosine's peak acceleration (π/2)F/Ta, and the jerk π²F/(2(π − 2)Ta²) ≈ 4.32 F/Ta² with which the
        S-curve reaches F in Ta, as the cosine does (the loss Ta); the cosine's own peak jerk, (π²/2)F/Ta², is
        higher (it took F in 0.955 Ta).
    exponential: F/Ta, the constant acceleration that loses what its ramps lose: its rise, fast at first, covers
        more than F·Ta/2 and its fall, fast at first too, as much less, so that a move from rest to rest loses Ta
        as the trapezoid's does; its own peak, c/(1 − e^(−c)) · F/Ta (c = Ta/τ) at the start of each ramp, is
        higher.
    """
    if kind == "bell":
        return 0.5 * math.pi * F / Ta, math.pi ** 2 * F / (2.0 * (math.pi - 2.0) * Ta ** 2)
    return F / Ta, math.inf


def motion_limits(job, tolerance: float | None) -> MotionLimits:
    """The look-ahead's limits from a job (its profile and interpolator) and the blend tolerance (mm; None: each
    block's own, G64 P, and none where the program states none)."""
    prof = job.profile
    dim = job.path.dim
    vel = [math.inf] * 3
    acc = [math.inf] * 3
    jerks = [math.inf] * 3
    for name, v, a, j in prof.axes:
        i = AXES.index(name)
        if i < dim:
            vel[i] = math.inf if v is None else float(v)
            acc[i] = math.inf if a is None else float(a)
            jerks[i] = math.inf if j is None else float(j)
    F, Ta = prof.feedrate, prof.accel_time
    # the machine's own limits, read with every profile
    A = math.inf if prof.max_accel is None else prof.max_accel
    jerk = math.inf if prof.max_jerk is None else prof.max_jerk
    chord = math.inf if prof.chord_tolerance is None else prof.chord_tolerance
    source = "max_accel" if prof.max_accel is not None else "the axes"
    # the profile's own ramp: where the profile is chosen (its type or its accel_time given: the job, the command
    # line), or where the machine does not limit every axis.  The default profile on a machine with limits of its
    # own (a LinuxCNC INI, profile.axes for every axis, max_accel) is planned to the machine's limits: that is what
    # the user means there, not the default ramp from the default feedrate (200 mm/s² bound the raster under a
    # 1 000 mm/s² machine); a machine that limits x and y alone keeps the ramp for the rest.  The adaptive
    # profile has no ramp of its own: its accel_time counts only where it is stated with it (the same file, or
    # --accel-time), not a job file's under --profile-type adaptive -- unless nothing else limits the acceleration
    # at all: then, as on one curve (profiles.profile_for), its max_accel is F/Ta of the default accel_time.
    machine = prof.max_accel is not None or all(math.isfinite(acc[i]) for i in range(dim))
    unlimited = prof.max_accel is None and not any(math.isfinite(acc[i]) for i in range(dim))
    chosen = (job.accel_time_stated or unlimited) if prof.type == "adaptive" else job.profile_chosen
    ramp = math.inf
    if Ta > 0.0 and (chosen or (prof.type != "adaptive" and not machine)):
        ramp, ramp_jerk = profile_ramp(prof.type, F, Ta)
        jerk = min(jerk, ramp_jerk)
    if ramp < A:
        A = ramp
        source = f"the {prof.type} profile's ramp, " + {"bell": "its peak", "exponential": "F/Ta, its ramps' loss of "
                                                        "time"}.get(prof.type, "F/Ta")
    An = prof.max_normal_accel if prof.max_normal_accel is not None else A
    if not math.isfinite(A) and not any(math.isfinite(acc[i]) for i in range(dim)):
        raise SpecError(f"the look-ahead planner needs an acceleration limit: {ACCEL_LIMIT_REMEDY}")
    if prof.accdec == "after":  # never ignored silently: a G-code program comes here without asking
        raise SpecError("profile.accdec = after (acc/dec filters after interpolation): the look-ahead plans the "
                        "feedrate before interpolation, across the blocks; plan it with accdec before")
    own = tolerance is None  # the job's own, block by block: G64 P, a block's mode.tolerance
    if not own and not tolerance >= 0.0:
        raise SpecError(f"tolerance = {tolerance!r} must be >= 0")
    # where a block states none: the profile's corner_tolerance (how far a corner blend may leave the path), else
    # none (the exact path)
    default = 0.0 if prof.corner_tolerance is None else float(prof.corner_tolerance)
    return MotionLimits(job.interpolator.period, F, prof.rapid_feedrate, A, jerk, An, chord, tuple(vel), tuple(acc),
                        default if own else float(tolerance), not own, source, tuple(jerks))
