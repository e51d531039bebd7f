"""The look-ahead pipeline, assembled once: blocks → segments → windowed plan → ticks, in bounded windows.

:class:`LookAhead` takes a job (its path of lines, arcs and NURBS blocks, its profile, its
period) and a blend tolerance and yields the stream's rows in chunks.  Blocks
are taken a batch at a time (BATCH) and made segments by one kernel
(:mod:`.segments`); the window (:mod:`.lookahead`) commits what is final; the
committed pieces become ticks (:mod:`.ticks`).  What the run did — blocks,
segments, blends and their worst deviation, stops, the largest per-axis
velocity, acceleration and jerk of the commands themselves (finite
differences), the motion time — is gathered on the way for the summary.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..errors import SpecError
from ..names import AXES
from . import segments as seg
from .jerk import chain_start, jerk_caps
from .limits import ACCEL_LIMIT_REMEDY, JERK_SHARES, MotionLimits, motion_limits
from .lookahead import JerkWindow, Window
from .nurbs_blocks import end_tangents, nurbs_rows
from .smooth import NO_CURVES, Smoother, SmoothFacts, join, tail
from .ticks import (
    A_COL,
    K_COL,
    N_COL,
    NROW,
    RAPID_COL,
    T_COL,
    U_COL,
    V_COL,
    X_COL,
    axis_extremes,
    emit,
)

BATCH = 4096  # blocks made segments at a time
CHUNK_TICKS = 1 << 16  # rows of one chunk at most
CONTROL = {"blend": seg.BLEND, "exact_path": seg.EXACT_PATH, "exact_stop": seg.EXACT_STOP}


PROGRAM_STOPS_KEPT = 1000  # the program's stops the facts list (the count goes on): a program's stops are few


def _note_stop(facts, stop, dwell) -> None:
    """A program's stop before a block (its words, its dwell in s) into the facts."""
    facts.program_stop_count += 1
    if len(facts.program_stops) < PROGRAM_STOPS_KEPT:
        facts.program_stops.append((stop, float(dwell)))


@dataclass
class RunFacts:
    """What the look-ahead did, for the summary (filled as the run goes)."""

    blocks: int = 0
    segments: int = 0
    lines: int = 0
    arcs: int = 0
    blends: int = 0
    unblended: int = 0  # non-tangent joints passed without a blend, on the path, at their capped speed
    stops: int = 0  # where the plan comes to rest (program stops, exact stops, reversals, joints at cap 0), the end
    # excluded
    corners_at_rest: int = 0  # of those, corners taken at rest because crossing their blend would take longer (jerk)
    sharp_stops: int = 0  # of those, joints unblended (the exact path, or no blend fits) too sharp to pass moving
    worst_blend: float = 0.0  # mm: the largest two-sided deviation of a blend from its corner
    dropped: int = 0  # zero-length blocks
    ticks: int = 0
    motion_time: float = 0.0
    length: float = 0.0  # mm of the planned path (blends included)
    max_window: int = 0  # the most segments a window held
    axis_extremes: np.ndarray | None = None  # (3, dim): largest |v|, |a|, |jerk| per axis
    cruise_time: float = 0.0  # s at a segment's cap (or a joint's)
    ramp_time: float = 0.0  # s accelerating or braking at a cap
    rest_time: float = 0.0  # s at rest (stops on ticks, dwells)
    capped_feeds: int = 0  # blocks whose F the axes' velocity limits lowered
    wall_time: float = 0.0  # s from the first block read to the last tick handed on (reading included)
    first_tick: float = 0.0  # s from the first block read to the first ticks handed on
    tolerance_max: float = 0.0  # mm: the largest blend tolerance a block carried (the program's own G64 P)
    nurbs: int = 0  # NURBS blocks followed as curve rows (motion.nurbs_blocks)
    nurbs_rows: int = 0  # their rows
    nurbs_deviation: float = 0.0  # mm: the largest sampled distance of such a row from its block's curve
    curve_rows: int = 0  # rows of curves (refitted runs and NURBS blocks)
    feed_moves: int = 0  # cutting (feed) moves read, zero-length ones included
    feed_defaulted: int = 0  # of them, with no feedrate of their own (no F word before them): the profile's
    feed_low: float = math.inf  # mm/s: the lowest and the highest feedrate the program's own blocks set
    feed_high: float = 0.0
    rapid_moves: int = 0  # rapids (G0) read
    rapid_ticks: int = 0  # ticks whose command lies on a rapid
    # the program's stops before a block, in its own words ("M6 at line 4; G4 P2 at line 5") with their dwell (s):
    # the first PROGRAM_STOPS_KEPT of them, and how many in all
    program_stops: list = field(default_factory=list)
    program_stop_count: int = 0


def _block_arrays(items, first, limits: MotionLimits, override: bool, facts: RunFacts, pending, name=""):
    """The kernel's arrays of a batch of items (zero-length lines dropped, their stop passed on to the next block).

    An item is a block of the path, or a run of straight moves as the G-code reader makes them (arrays:
    config.gcode.ProgramStream.items), taken whole by numpy.  Blocks go attribute by attribute (list
    comprehensions, not a loop of numpy calls per block): a block costs well under a microsecond here.
    *pending*: [stop, dwell] of dropped blocks not yet passed on.  Returns (arrays, curves): the rows of the
    CURVE blocks that NURBS blocks became (motion.nurbs_blocks), each block's RISE its first row."""
    parts = []
    blocks = []
    curves = []
    rows = 0
    unlimited = limits.unlimited_axes()
    for item in items:
        if unlimited:
            _refuse_unlimited_moves(item, unlimited, name, first + len(blocks))
        if item.kind == "moves":
            if blocks:
                parts.append(_blocks_arrays(blocks, first, limits, override, name, facts, curves, rows))
                rows = sum(c.shape[0] for c in curves)
                first += len(blocks)
                blocks = []
            parts.append(_moves_arrays(item, first, limits, override, facts))
            first += item.starts.shape[0]
        else:
            blocks.append(item)
    if blocks:
        parts.append(_blocks_arrays(blocks, first, limits, override, name, facts, curves, rows))
    arrays = parts[0] if len(parts) == 1 else tuple(np.concatenate(a) for a in zip(*parts))
    return _drop_zero_length(arrays, facts, pending), (np.concatenate(curves) if curves else NO_CURVES)


def _refuse_unlimited_moves(item, unlimited, name, index):
    """SpecError where the *item* moves along an axis of *unlimited* (nothing limits its acceleration there),
    naming the block (its line, or its *index* among the path's blocks).  An axis moves where a block's ends differ in it, in an arc's plane, or where a NURBS block's
    control points differ in it."""
    if item.kind == "moves":
        moved = item.starts[:, unlimited] != item.ends[:, unlimited]
        rows = np.flatnonzero(moved.any(axis=1))
        if rows.shape[0] == 0:
            return
        r = int(rows[0])
        where = f"line {int(item.lines[r])}"
        axis = unlimited[int(np.flatnonzero(moved[r])[0])]
    else:
        d = item.start.shape[0]
        moving = [i for i in unlimited if i < d and item.start[i] != item.end[i]]
        if item.kind == "arc":
            moving += [i for i in unlimited if abs(item.normal[i]) < 1.0]
        elif item.kind == "nurbs":
            moving += [i for i in unlimited if i < d and np.ptp(item.curve.control_points[:, i]) > 0.0]
        if not moving:
            return
        where = item.source or f"block {index}"
        axis = min(moving)
    raise SpecError(f"{name}: {where} moves {AXES[axis]}, whose acceleration nothing limits: {ACCEL_LIMIT_REMEDY}")


def _modes(blocks, limits):
    """Each block's control (segments.BLEND ...) and blend tolerance (mm), from its mode (a few distinct ones)."""
    modes = {}
    ctrl = [modes.get(id(b.mode)) or modes.setdefault(id(b.mode), (CONTROL[b.mode.control], b.mode.tolerance))
            for b in blocks]
    tol = np.array([limits.tolerance if (limits.override_program or m[1] is None) else m[1] for m in ctrl])
    return np.array([m[0] for m in ctrl], dtype=np.int64), tol


def _blocks_arrays(blocks, first, limits, override, name, facts, curves, rows):
    """The arrays of a list of blocks; a NURBS block's rows appended to *curves* (*rows* of them before it)."""
    K = len(blocks)
    kinds = [b.kind for b in blocks]
    d = blocks[0].start.shape[0]
    P0 = np.zeros((K, 3))
    P1 = np.zeros((K, 3))
    P0[:, :d] = [b.start for b in blocks]
    P1[:, :d] = [b.end for b in blocks]
    kind = np.zeros(K, np.int64)
    C = np.zeros((K, 3))
    N = np.zeros((K, 3))
    sweep = np.ones(K)
    rise = np.zeros(K)
    upieces = np.ones(K)
    for i in [i for i, k in enumerate(kinds) if k == "arc"]:
        b = blocks[i]
        kind[i] = seg.ARC
        C[i, :d] = b.center
        N[i] = b.normal
        sweep[i] = b.sweep
        rise[i] = b.rise
        upieces[i] = _arc_pieces(b)
    rapid = np.array([b.rapid for b in blocks], dtype=float)
    own = np.array([math.nan if b.feedrate is None else b.feedrate for b in blocks], dtype=float)
    _count_feeds(facts, rapid > 0.0, own)
    if override:
        feed = np.full(K, limits.feedrate)
    else:
        feed = np.array([limits.rapid_feedrate if b.rapid else (limits.feedrate if b.feedrate is None else b.feedrate)
                         for b in blocks], dtype=float)
    ctrl, tol = _modes(blocks, limits)
    for i in [i for i, k in enumerate(kinds) if k == "nurbs"]:
        b = blocks[i]
        where = f"{name}: {b.source or f'block {first + i}'}"
        piece, deviation = nurbs_rows(b.curve, float(tol[i]), first + i, float(feed[i]), limits.vector(), where)
        kind[i] = seg.CURVE
        C[i], N[i] = end_tangents(piece)
        sweep[i] = float(piece[:, seg.LEN].sum())
        rise[i] = float(rows)
        upieces[i] = float(piece.shape[0])
        curves.append(piece)
        rows += piece.shape[0]
        facts.nurbs += 1
        facts.nurbs_rows += piece.shape[0]
        facts.nurbs_deviation = max(facts.nurbs_deviation, deviation)
    stop = np.array([b.stop is not None for b in blocks], dtype=float)
    dwell = np.array([b.dwell for b in blocks], dtype=float)
    for b in blocks:
        if b.stop is not None:
            _note_stop(facts, b.stop, b.dwell)
    index = np.arange(first, first + K, dtype=float)
    return kind, P0, P1, C, N, sweep, rise, feed, rapid, ctrl, tol, stop, dwell, index, upieces


def _count_feeds(facts, rapid, own):
    """The summary's count of a batch's moves: rapids and feed moves, the feedrates the feed moves set (*own*,
    NaN where a move has none)."""
    facts.rapid_moves += int(np.count_nonzero(rapid))
    cut = own[~rapid]
    facts.feed_moves += cut.shape[0]
    given = cut[~np.isnan(cut)]
    facts.feed_defaulted += cut.shape[0] - given.shape[0]
    if given.shape[0]:
        facts.feed_low = min(facts.feed_low, float(given.min()))
        facts.feed_high = max(facts.feed_high, float(given.max()))


def _moves_arrays(moves, first, limits, override, facts):
    """The arrays of a run of straight moves (the G-code reader's, 3-D), as _blocks_arrays makes them of its
    blocks one by one."""
    K = moves.starts.shape[0]
    rapid = moves.rapid.astype(float)
    _count_feeds(facts, moves.rapid.astype(bool), np.asarray(moves.feeds, dtype=float))
    if override:
        feed = np.full(K, limits.feedrate)
    else:
        feed = np.where(moves.rapid, limits.rapid_feedrate, np.where(np.isnan(moves.feeds), limits.feedrate,
                                                                     moves.feeds))
    ctrl, tol = _modes([moves], limits)
    stop = np.zeros(K)
    stop[0] = moves.stop is not None
    if moves.stop is not None:
        _note_stop(facts, moves.stop, moves.dwell)
    dwell = np.zeros(K)
    dwell[0] = moves.dwell
    return (np.zeros(K, np.int64), np.ascontiguousarray(moves.starts, dtype=float),
            np.ascontiguousarray(moves.ends, dtype=float), np.zeros((K, 3)), np.zeros((K, 3)), np.ones(K),
            np.zeros(K), feed, rapid, np.full(K, ctrl[0]), np.full(K, tol[0]), stop, dwell,
            np.arange(first, first + K, dtype=float), np.ones(K))


def _drop_zero_length(arrays, facts, pending):
    kind, P0, P1, stop, dwell = arrays[0], arrays[1], arrays[2], arrays[11], arrays[12]
    K = kind.shape[0]
    delta = P1 - P0
    keep = (kind != seg.LINE) | (np.einsum("ij,ij->i", delta, delta) >= seg.MIN_LENGTH * seg.MIN_LENGTH)
    # the stop and dwell of a dropped block go to the next block kept (in this batch or the next)
    stop[0] = max(stop[0], pending[0])
    dwell[0] += pending[1]
    pending[0] = pending[1] = 0.0
    for i in np.flatnonzero(~keep):
        facts.dropped += 1
        if i + 1 < K:
            stop[i + 1] = max(stop[i + 1], stop[i])
            dwell[i + 1] += dwell[i]
        else:
            pending[0], pending[1] = stop[i], dwell[i]
    return arrays if keep.all() else tuple(np.ascontiguousarray(a[keep]) for a in arrays)


def plans_with_look_ahead(tolerance: float | None, program_format: str, load_stream):
    """Whether a job is planned with look-ahead across its blocks -- the one rule `plan`, `simulate`, `compare`,
    `info`, `identify` and `sweep` follow: with a *tolerance* given, within it; a job of several blocks (a G-code
    program, a drawing, a YAML path) always, within a program's own G64 P block by block and on the exact path
    where none is stated (its corners passed at the speed their jump of direction allows, as a controller's
    exact-path mode passes them: never a stop at every joint); a job of one block (a curve) is one motion from
    rest to rest along its own parameter: the paper's interpolation.  A YAML path or a drawing under acc/dec after
    interpolation (profile.accdec = after) is still the paper's too, one motion between its joints, filtered: the
    look-ahead plans the feedrate before interpolation and has no filter stage yet (a program refuses it).
    *load_stream*() loads the job as the look-ahead reads it (a program as a stream: read once, as it is planned).
    Returns (look-ahead or not, the job it loaded or None): the caller plans that one rather than reading the job
    again."""
    if tolerance is not None:
        return True, None
    job = load_stream()
    if program_format == "gcode":
        return True, job
    return len(job.path.blocks) > 1 and job.profile.accdec != "after", job


def program_window(job, tolerance: float | None, name: str | None = None):
    """The job's programmed blocks read alongside a stream of it (motion.contour.ProgramWindow): the contour error's
    and the commands' distance from the program, within *tolerance* (None: the program's own G64 P)."""
    from .contour import ProgramWindow

    corner = job.profile.corner_tolerance
    return ProgramWindow(path_items(job.path), tolerance, job.path.dim, job.source if name is None else name,
                         0.0 if corner is None else corner)


def path_items(path):
    """The path's items in order: a path held whole (YAML, DXF) gives its blocks; a program read as it runs
    (config.gcode.ProgramStream) its items afresh, runs of straight moves among them."""
    return path.items() if hasattr(path, "items") else iter(path.blocks)


def _batches(items, batch):
    """The path's items in lists of about *batch* blocks (a run of moves counts its moves, cut where it is
    longer), and whether each list is the last."""
    group, count = [], 0
    for item in items:
        if item.kind == "moves":
            n = item.starts.shape[0]
            for lo in range(0, n, batch) if n > batch else (0,):
                part = item if n <= batch else item.part(lo, min(n, lo + batch))
                group.append(part)
                count += part.starts.shape[0]
                if count >= batch:
                    yield group
                    group, count = [], 0
        else:
            group.append(item)
            count += 1
            if count >= batch:
                yield group
                group, count = [], 0
    if group:
        yield group


def _arc_pieces(block) -> float:
    """The number of Bézier pieces of the arc block's NURBS (path.block_nurbs), which its parameter u counts."""
    if block.rise == 0.0:
        return float(max(1, math.ceil(block.sweep / (math.pi / 2) - 1e-12)))
    from ..path import block_nurbs

    p, _, U = block_nurbs(block)
    return float(len(np.unique(U)) - 1)


class LookAhead:
    """A program planned with look-ahead across its blocks; its ticks in chunks (see the module's docstring).

    Parameters
    ----------
    job : a validated Job (its path of lines, arcs and NURBS blocks, the last followed as cubic rows:
        motion.nurbs_blocks)
    tolerance : float, mm — how far a corner blend or a refitted curve may leave the programmed path (0: none);
        None: each block's own (the program's G64 P), none where the program states none
    smooth : refit runs of short moves as smooth curves (motion.smooth); False: blend corners only
    max_ticks : refuse (SpecError) a run longer than this many ticks, as soon as it is known
    """

    def __init__(self, job, tolerance: float | None, *, max_ticks: int = 100_000_000, max_ticks_hint: str = "",
                 batch: int = BATCH, smooth: bool = True):
        self.job = job
        self.limits = motion_limits(job, tolerance)
        self.period = self.limits.period
        path = job.path
        self.dim = path.dim
        self.rapid = path.has_rapids
        self.columns = ["k", "n", "t", "u", *AXES[:self.dim], "v", "a", *(["rapid"] if self.rapid else [])]
        self.max_ticks = max_ticks
        self.max_ticks_hint = max_ticks_hint
        self.batch = batch
        self.facts = RunFacts()
        self.smooth = smooth
        self.smoothing = SmoothFacts()
        self._select = [K_COL, N_COL, T_COL, U_COL, *range(X_COL, X_COL + self.dim), V_COL, A_COL,
                        *([RAPID_COL] if self.rapid else [])]
        self._path = path
        self.end_point = np.zeros(3)  # the last block's end (known once it is read)

    def _segments(self):
        """Segment rows, batch by batch."""
        lim = self.limits.vector()
        override = bool(self.job.feedrate_override)
        d_in = np.array([0.0, 0.0, 1.0, 0.0, 0.0])  # the program starts at rest
        started = False
        carry = (None, None)  # the last block of the previous batch (its end joint not yet known), its curve rows
        smoother = Smoother(lim, self.smooth, self.smoothing)
        pending = [0.0, 0.0]  # stop and dwell of dropped zero-length blocks, passed on
        facts = self.facts
        first = 0
        batches = _batches(path_items(self._path), self.batch)
        group = next(batches, None)
        while group is not None:
            following = next(batches, None)  # one batch ahead: is this one the program's last?
            last = following is None
            arrays, curves_in = _block_arrays(group, first, self.limits, override, facts, pending, self.job.source)
            K0 = sum(item.starts.shape[0] if item.kind == "moves" else 1 for item in group)
            first += K0
            facts.blocks = first
            group = following
            if arrays[0].shape[0]:
                self.end_point = arrays[2][-1, :self.dim].copy()
                facts.tolerance_max = max(facts.tolerance_max, float(arrays[10].max()))
            arrays, curves = join(carry, smoother.push(arrays, curves_in, last))
            K = arrays[0].shape[0]
            if K == 0:
                continue
            if not last and K < 2:
                carry = (arrays, curves)
                continue
            if not started:  # a dwell before the first move holds the tool on the start, where it is at rest
                d_in[3] += arrays[12][0]
                started = True
            out = np.empty((3 * K + 3 + curves.shape[0], seg.NCOL))
            m, d_in = seg.build_segments(*arrays, curves, lim, d_in, last, out)
            carry = (None, None) if last else tail(arrays, curves, K - 1)
            rows = out[:m]
            self._count(rows, arrays)
            yield rows
        if carry[0] is not None:  # the program's last batch dropped everything after the carried block
            arrays, curves = carry
            out = np.empty((6 + curves.shape[0], seg.NCOL))
            m, d_in = seg.build_segments(*arrays, curves, lim, d_in, True, out)
            self._count(out[:m], arrays)
            yield out[:m]
        # the moves the reader left out as zero-length (its note says so) count with the look-ahead's own: of the
        # program's blocks, so many dropped
        left_out = getattr(self._path, "dropped", 0)
        facts.dropped += left_out
        facts.blocks += left_out

    def _count(self, rows, arrays):
        f = self.facts
        f.segments += rows.shape[0]
        kinds = rows[:, seg.UKIND]
        f.lines += int(np.count_nonzero(kinds == seg.U_LINEAR))
        f.arcs += int(np.count_nonzero(kinds == seg.U_ARC))
        f.curve_rows += int(np.count_nonzero(kinds == seg.U_CURVE))
        blends = rows[kinds == seg.U_BLEND_IN]
        f.blends += blends.shape[0]
        if blends.shape[0]:
            # e = d tan(θ/4) = R tan(θ/2) tan(θ/4), θ twice the half's sweep
            half = blends[:, seg.SWEEP]
            dev = blends[:, seg.RADIUS] * np.tan(half) * np.tan(0.5 * half)
            f.worst_blend = max(f.worst_blend, float(dev.max()))
        nodes = rows[:, seg.NODECAP]
        # joints passed unblended whose cap is below the segments' beside them (a tangent joint -- a curve meeting
        # the line it leaves along, to rounding -- has a cap of some 1e13 mm/s: not counted)
        beside = np.minimum(np.concatenate(([math.inf], rows[:-1, seg.VCAP])), rows[:, seg.VCAP])
        f.unblended += int(np.count_nonzero(np.isfinite(nodes) & (nodes > 0) & (rows[:, seg.STOP] == 0)
                                            & (nodes < beside)))
        # at rest: the program's stops, and joints too sharp to pass unblended moving (their jump cap 0)
        f.stops += int(np.count_nonzero((rows[:, seg.STOP] != 0) | (nodes == 0)))
        f.corners_at_rest += int(np.count_nonzero(rows[:, seg.STOP] == seg.CORNER_REST))
        f.sharp_stops += int(np.count_nonzero((nodes == 0) & (rows[:, seg.STOP] == 0)))
        # the lines whose F the axes' velocity limits lower
        lines = rows[kinds == seg.U_LINEAR]
        feed = arrays[7][np.searchsorted(arrays[13], lines[:, seg.BLOCK])]
        with np.errstate(divide="ignore"):
            axis_cap = (np.array(self.limits.axis_velocity) / np.abs(lines[:, seg.D:seg.D + 3])).min(axis=1)
        f.capped_feeds += int(np.count_nonzero(axis_cap < feed))

    def chunks(self):
        """The stream's rows, (m, len(columns)) a chunk, until the last tick (the program's end, at rest)."""
        t0 = time.perf_counter()
        lim = self.limits
        jerk = lim.tangential_jerk()
        axis_jerk = np.array(lim.axis_jerk, dtype=float)
        per_axis = bool(np.isfinite(axis_jerk).any())
        # a segment's own jerk cap (motion.jerk) is at most √3 times the largest axis' (a diagonal line's)
        top = min(lim.jerk, math.sqrt(3.0) * float(axis_jerk[np.isfinite(axis_jerk)].max())) if per_axis else jerk
        window = Window(self.period) if not math.isfinite(jerk) else JerkWindow(self.period, jerk, top)
        joint = np.full(13, math.nan)  # where the last batch's rows end (motion.jerk.jerk_caps)
        shares = np.array(JERK_SHARES)
        held = np.empty((0, seg.NCOL))  # the last rows made: the last's JCAP waits for its end joint, and the joints
        # within three ticks before that one add theirs to it (motion.jerk.chain_start)
        t_start = 0.0  # where the last committed table ended
        facts = self.facts
        k_next = 0
        prev = np.zeros((3, self.dim))
        facts.axis_extremes = np.zeros((3, self.dim))
        count = 0
        source = self._segments()
        finished = False
        first_stop_skipped = False
        start_rest = 0.0
        while not finished:
            rows = next(source, None)
            if rows is None:
                finished = True
                if held.shape[0]:
                    window.add(held)
            else:
                if not first_stop_skipped and rows.shape[0]:
                    facts.stops -= 1  # the program's start is a node at rest, not a stop
                    facts.sharp_stops -= int(rows[0, seg.NODECAP] == 0 and rows[0, seg.STOP] == 0)
                    first_stop_skipped = True
                    # a dwell before the first move: the tool rests on the start for it (whole ticks), then moves
                    start_rest = math.ceil(float(rows[0, seg.DWELL]) / self.period - 1e-9) * self.period
                    if start_rest > 0.0:
                        window.start_at(start_rest)
                if per_axis and rows.shape[0]:
                    rows = np.concatenate([held, rows])
                    jerk_caps(rows, axis_jerk, self.period, shares, joint, held.shape[0], top)
                    keep = chain_start(rows, self.period)
                    held = rows[keep:]
                    rows = rows[:keep]
                window.add(rows)
                facts.max_window = max(facts.max_window, window.rows.shape[0])
            table, committed, t_end = window.plan(finished)
            if table.shape[0] == 0:
                continue
            if start_rest > 0.0:  # the rest before the first piece
                table = np.concatenate([np.zeros((1, table.shape[1])), table])
                start_rest = 0.0
            self._time_shares(table, t_start, t_end)
            t_start = t_end
            # ticks whose time lies in the committed part: k·T < t_end (the last: k·T >= t_end, at the end)
            k_end = math.ceil(t_end / self.period - 1e-9) if finished else math.ceil(t_end / self.period - 1e-9) - 1
            k_end = max(k_end, k_next - 1)
            if k_end + 1 > self.max_ticks:
                raise SpecError(f"the motion takes more than {self.max_ticks} ticks{self.max_ticks_hint}")
            for lo in range(k_next, k_end + 1, CHUNK_TICKS):
                hi = min(lo + CHUNK_TICKS, k_end + 1)
                out = np.empty((hi - lo, NROW))
                emit(table, committed, lo, hi, self.period, out)
                if finished and hi == k_end + 1:
                    out[-1, X_COL:X_COL + self.dim] = self.end_point  # the end, exactly
                    out[-1, V_COL] = 0.0
                    out[-1, A_COL] = 0.0
                data = out[:, self._select]
                count = axis_extremes(data[:, 4:4 + self.dim], prev, count, self.period, facts.axis_extremes)
                if self.rapid:
                    facts.rapid_ticks += int(np.count_nonzero(data[:, -1]))
                if facts.ticks == 0:
                    facts.first_tick = time.perf_counter() - t0
                facts.ticks += hi - lo
                yield data
            k_next = k_end + 1
        facts.motion_time = (k_next - 1) * self.period
        facts.length = window.s_end
        facts.wall_time = time.perf_counter() - t0

    def _time_shares(self, table, t_start, t_end):
        # a table may begin with the piece the last one ended in (lookahead.JerkWindow): from t_start only
        dur = np.diff(np.append(np.maximum(table[:, 0], t_start), t_end))
        v, a, j = table[:, 2], table[:, 3], table[:, 4]
        moving = (a != 0) | (j != 0)  # a constant-jerk piece starting at A = 0 is a ramp too
        self.facts.rest_time += float(dur[(v == 0) & ~moving].sum())
        self.facts.cruise_time += float(dur[(v > 0) & ~moving].sum())
        self.facts.ramp_time += float(dur[moving].sum())


def run_facts(run: LookAhead) -> dict:
    """What the run did, as plain values (info --tolerance --json): the summary's figures, by name."""
    f = run.facts
    sm = run.smoothing
    lim = run.limits
    axes = AXES[:run.dim]
    moving = f.motion_time or 1.0

    def per_axis(values):
        return {a: (float(values[i]) if math.isfinite(values[i]) else None) for i, a in enumerate(axes)}

    return {
        "planner": "look-ahead", "tolerance": lim.tolerance if lim.override_program else None,
        "tolerance_source": "option" if lim.override_program else "program", "tolerance_max": f.tolerance_max,
        "period": run.period, "ticks": f.ticks,
        "motion_time": f.motion_time, "length": f.length, "blocks": f.blocks, "dropped": f.dropped,
        "segments": {"total": f.segments, "lines": f.lines, "arcs": f.arcs, "curve_rows": f.curve_rows,
                     "blends": f.blends},
        "nurbs": {"blocks": f.nurbs, "rows": f.nurbs_rows, "worst_deviation": f.nurbs_deviation},
        "smoothing": {"enabled": run.smooth, "runs": sm.runs, "moves": sm.moves, "curves": sm.curves,
                      "rows": sm.rows, "worst_deviation": sm.worst, "runs_left_to_blends": sm.kept},
        "blends": {"count": f.blends, "worst_deviation": f.worst_blend},
        "joints": {"unblended": f.unblended, "stops": max(f.stops, 0), "corners_at_rest": f.corners_at_rest,
                   "sharp_stops": max(f.sharp_stops, 0)},
        "program_stops": {"count": f.program_stop_count,
                          "first": [{"stop": words, "dwell": dwell} for words, dwell in f.program_stops]},
        "bound_by": {"feed_cap": f.cruise_time / moving, "acceleration_cap": f.ramp_time / moving,
                     "at_rest": f.rest_time / moving},
        "limits": {"tangential_accel": lim.accel if math.isfinite(lim.accel) else None, "source": lim.source,
                   "axis_max_velocity": per_axis(lim.axis_velocity), "axis_max_accel": per_axis(lim.axis_accel),
                   "axis_max_jerk": per_axis(lim.axis_jerk),
                   "tangential_jerk": lim.tangential_jerk() if math.isfinite(lim.tangential_jerk()) else None},
        "commands": {name: {a: float(f.axis_extremes[k, i]) for i, a in enumerate(axes)}
                     for k, name in enumerate(("max_velocity", "max_accel", "max_jerk"))},
        "capped_feeds": f.capped_feeds, "planning_seconds": f.wall_time, "largest_window": f.max_window,
        "feeds": {"moves": f.feed_moves, "defaulted": f.feed_defaulted,
                  "lowest": f.feed_low if f.feed_moves > f.feed_defaulted else None,
                  "highest": f.feed_high if f.feed_moves > f.feed_defaulted else None,
                  "default": lim.feedrate, "override": bool(run.job.feedrate_override), "rapid_moves": f.rapid_moves,
                  "rapid_feedrate": lim.rapid_feedrate},
        "rapid_time": rapid_time(run), "cutting_time": f.motion_time - rapid_time(run),
    }


def rapid_time(run: LookAhead) -> float:
    """s of the motion whose commands lie on rapids (G0): the ticks' count, each a period."""
    return min(run.facts.rapid_ticks * run.period, run.facts.motion_time)
