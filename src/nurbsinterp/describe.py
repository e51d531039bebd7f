"""Facts about a job for `nurbsinterp info`: geometry and the planned motion."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from .errors import located
from .nurbs import NurbsCurve
from .profiles import MAX_TICKS, planned_profile
from .config import Job
from .config.path import DEFAULT_MODE
from .path import job_path


@dataclass(frozen=True)
class JobFacts:
    """What `info` reports: the path as one NURBS (the curve the tool follows, corner blends
    included), each block and joint, and the motion the job plans.  ``as_dict()`` is the JSON."""

    source: str
    degree: int
    dimension: int
    n_control_points: int
    rational: bool
    domain: list
    knot_spans: int
    length: float  # mm
    min_radius: float | None  # mm; None: straight
    min_radius_u: float
    min_radius_point: list
    bounding_box: dict  # {"min": [...], "max": [...]}
    profile: str
    accdec: str
    feedrate: float  # mm/s
    accel_time: float  # s
    time_constant: float  # s
    peak_feedrate: float  # mm/s
    peak_lowered: bool
    motion_time: float  # s
    interpolator: str
    period: float  # s
    ticks: int
    blocks: list  # block_facts
    junctions: list  # one dict per joint: after_block, s, angle_deg, corner
    adaptive: dict | None = None  # adaptive_facts, for the adaptive profile
    block_feedrates: list | None = None  # mm/s per block where blocks carry their own (F words, rapids)

    def as_dict(self) -> dict:
        """The fields by name, in order (``adaptive`` only for the adaptive profile): the JSON form."""
        out = dataclasses.asdict(self)
        for key in ("adaptive", "block_feedrates"):
            if out[key] is None:
                del out[key]
        return out


def describe_job(job: Job, curve: NurbsCurve | None = None, with_profile: bool = False,
                 max_ticks: int = MAX_TICKS, max_ticks_hint: str = ""):
    """:class:`JobFacts` of the job (and the planned profile, if asked)."""
    with located(job.source):
        path = job_path(job, curve)
        curve = path.curve
        if job.profile.accdec == "after":
            profile, last_tick = _filtered_run(job, path, max_ticks, max_ticks_hint)
        else:
            profile, last_tick = planned_profile(job, path, max_ticks=max_ticks, hint=max_ticks_hint)
    radius, radius_u = curve.min_radius()
    lo, hi = curve.bounding_box()
    facts = JobFacts(
        source=job.source,
        degree=curve.degree,
        dimension=curve.dim,
        n_control_points=curve.n + 1,
        rational=bool((curve.weights != curve.weights[0]).any()),
        domain=list(curve.domain),
        knot_spans=len(curve.span_ranges()),
        length=curve.length,
        min_radius=radius if math.isfinite(radius) else None,
        min_radius_u=radius_u,
        min_radius_point=curve.evaluate(radius_u).tolist(),
        bounding_box={"min": lo.tolist(), "max": hi.tolist()},
        profile=job.profile.type,
        accdec=job.profile.accdec,
        feedrate=job.profile.feedrate,
        accel_time=job.profile.accel_time,
        time_constant=job.profile.tau,
        peak_feedrate=profile.peak,
        peak_lowered=profile.lowered,
        motion_time=last_tick * job.interpolator.period if job.profile.accdec == "after" else profile.duration,
        interpolator=job.interpolator.method,
        period=job.interpolator.period,
        ticks=last_tick + 1,
        blocks=block_facts(path),
        junctions=[{"after_block": j.index, "s": j.s, "angle_deg": math.degrees(j.angle), "corner": j.corner}
                   for j in path.junctions],
        adaptive=adaptive_facts(profile.plan) if job.profile.type == "adaptive" else None,
        block_feedrates=None if path.feedrates is None else path.feedrates.tolist(),
    )
    return (facts, profile) if with_profile else facts


def _filtered_run(job, path, max_ticks, hint):
    """(profile, K) of an acc/dec-after job: the constant feed it interpolates at, and its stream's last tick.

    The filter ends the stream where it has brought the tool to rest on the end point (within SETTLE_TOL), which
    only running it says: the profile's duration is the interpolation's alone, and an estimate of the settling is
    a few ticks out (the exponential's most).  So the stream is run as `plan` runs it, its ticks counted and not
    kept: what info says is what plan writes."""
    from .interpolate import Interpolation

    run = Interpolation(job, path, max_ticks=max_ticks, max_ticks_hint=hint)
    ticks = sum(chunk.data.shape[0] for chunk in run.chunks())
    return run.profile, ticks - 1


def mode_words(mode) -> str:
    """A block's path-control mode as the G-code that sets it, tolerances in mm: 'G64 P0.01 Q0.005', 'G61.1'."""
    if mode.control != "blend":
        return "G61" if mode.control == "exact_path" else "G61.1"
    words = ["G64"] + [f"{letter}{value:g}" for letter, value in (("P", mode.tolerance), ("Q", mode.naive_tolerance))
                       if value is not None and not (letter == "Q" and value == mode.tolerance)]
    return " ".join(words)


def block_facts(path) -> list[dict]:
    """Per block: kind, length (mm), smallest radius of curvature (None: straight), start and end points.

    The radii come from one search of the whole path's curvature maxima (per knot span, refined),
    each span's maximum credited to the block it lies in."""
    kappa = np.zeros(len(path.blocks))
    values, us = np.array(path.programmed.curvature_maxima(), dtype=float).reshape(-1, 2).T
    np.maximum.at(kappa, path.locate(us)[0], values)
    out = []
    joints = any(b.mode != DEFAULT_MODE or b.stop is not None for b in path.blocks)  # a program that says how
    for i, block in enumerate(path.blocks):
        radius = None if block.kind == "line" or not kappa[i] > 0 else 1.0 / float(kappa[i])
        facts = {"kind": block.kind, "length": float(path.block_lengths[i]), "min_radius": radius,
                 "start": block.start.tolist(), "end": block.end.tolist()}
        # what a program or a drawing adds: each block's own feedrate, the rapids, where it was read
        if path.feedrates is not None:
            facts.update(feedrate=float(path.feedrates[i]), rapid=bool(block.rapid))
        if block.source is not None:
            facts["source"] = block.source
        if joints:  # the program's path-control mode for the block, and why the tool stops before it
            facts.update(mode=dataclasses.asdict(block.mode), mode_words=mode_words(block.mode), stop=block.stop,
                         dwell=block.dwell)
        out.append(facts)
    return out


def adaptive_facts(plan) -> dict:
    """What the adaptive planner found: what bounds the schedule (shares of the motion time), where each limit
    binds the feed limit (shares of the path) and its lowest point, the schedule's slowest point between its
    ramps, the cost of planning."""
    low, slow = plan.slowest, plan.slowest_scheduled
    return {
        "bound_fractions": {k: float(v) for k, v in plan.bound_fractions.items()},
        "limit_fractions": {k: float(v) for k, v in plan.limit_fractions.items()},
        "lowest_feed_limit": {"s": low.s, "u": low.u, "feed_limit": low.v, "limit": low.limit},
        "slowest": {"feedrate": slow.v, "s": slow.s, "t": slow.t},
        "peak_feedrate": plan.peak,
        "accel_bound": plan.accel_bound,
        "sections": plan.sections,
        "planning_time": plan.planning_time,
    }
