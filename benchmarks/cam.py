"""CAM programs as issue 29 measures them: generated spiral and raster programs, LinuxCNC's figures on them,
and the measures of a plan stream (motion time, two-sided deviation, per-axis v/a/j, RSS, first tick).

    python benchmarks/cam.py write DIR --blocks 1000,10000     # spiral_N.ngc, raster_N.ngc in DIR
    python benchmarks/cam.py measure PROGRAM [-- PLAN ARGS...] # one plan run's measures, as JSON
    python benchmarks/cam.py table DIR --blocks 1000,10000 [-- PLAN ARGS...]   # the README's table rows

The measures (``measure``): motion time; the largest distance of a command from the programmed polyline
and of a programmed point from the commanded one (two-sided, exact segment distances over the blocks near
each tick, an upper bound of the exact figure); the largest per-axis |v|, |a|, |j| by finite differences;
the planner's peak RSS, wall time, time to the first tick, blocks per second.  They are taken as the
stream arrives on a pipe, a chunk at a time; the planner's own pace is then taken by a second run into
/dev/null (``blocks_per_s_alone``), since reading and measuring 10⁷ ticks costs this process more than
planning them costs the planner.  LINUXCNC holds LinuxCNC 2.9's figures on the same programs.

The programs (deterministic, no randomness):

spiral
    r = 5 + 0.5·θ/2π mm (0.5 mm a turn), as N G1 chords, each as long as the local curvature allows with
    its sagitta (its largest distance from the spiral) within 1 µm; F3000 (50 mm/s), ``G21 G90 G64``, a
    leading ``G0`` to the spiral's start (5, 0), ``M2``.  The chords are about 0.2 mm at r = 5 mm and grow
    as √r.
raster
    A finishing pass over z = 2 sin(x/7)·cos(y/5) mm: rows of 200 G1 moves of 0.2 mm in x (x from 0 to
    40 mm), rows 0.5 mm apart in y, zig-zag, each step-over one G1 in y with z on the surface; it starts
    ``G0 X0 Y0 Z5`` / ``G1 Z0 F2000`` (z(0, 0) = 0: the plunge ends on the surface) and ends ``G0 Z5``,
    ``M2``.  N blocks is N // 200 rows (1 000 → 5 rows: 1 000 row moves, 4 step-overs, the plunge).

Numbers are printed with 6 decimals (1 nm), never with an exponent.
"""
from __future__ import annotations

import contextlib
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

try:
    from numba import njit
except ImportError:  # the generators need no numba (LinuxCNC's harness runs them with the system Python)
    def njit(*_args, **_kwargs):
        return lambda function: function

SAGITTA = 1.0e-3  # mm: a spiral chord's largest distance from the spiral
DIGITS = 6  # decimals printed: a coordinate is off by at most half of 1e-6 mm
PRINTED = 0.5e-6 * math.sqrt(2)  # mm: how far rounding can move a printed x, y point, and so its chord
SPIRAL_R0 = 5.0  # mm: the spiral's radius at θ = 0
SPIRAL_PITCH = 0.5  # mm a turn
SPIRAL_FEED = 3000.0  # mm/min
RASTER_FEED = 2000.0  # mm/min
RASTER_STEP = 0.2  # mm: a move along a row
RASTER_ROW = 200  # moves a row
RASTER_STEPOVER = 0.5  # mm between rows
RASTER_SAFE_Z = 5.0  # mm


def _num(v: float) -> str:
    """v with 6 decimals, no exponent, no negative zero."""
    text = f"{v:.6f}"
    return "0.000000" if text == "-0.000000" else text


# --------------------------------------------------------------------------- spiral

def spiral_radius(theta):
    """r(θ) = 5 + 0.5·θ/2π mm."""
    return SPIRAL_R0 + SPIRAL_PITCH * theta / (2.0 * math.pi)


def spiral_point(theta):
    """(x, y) of the spiral at θ, mm."""
    r = spiral_radius(theta)
    return r * math.cos(theta), r * math.sin(theta)


def spiral_angles(chords: int, sagitta: float = SAGITTA) -> list[float]:
    """The chords' end angles θ_0 = 0 < θ_1 < … < θ_chords of the spiral, each chord's sagitta ≤ *sagitta*.

    Notes
    -----
    With b = 0.5/2π mm, the spiral r = 5 + bθ has speed |dP/dθ| = √(r² + b²) and curvature
    κ = (r² + 2b²)/(r² + b²)^(3/2), which decreases along it.  Over a chord from θ_i the curvature is at
    most κ(θ_i); an arc of length S whose curvature is at most 1/R lies within R(1 - cos(S/2R)) of its
    chord, the sagitta of the circle of radius R (the circle bends most), so S = 2R·acos(1 - s/R) keeps
    the chord within s.  The angle step is S over the largest speed on the chord (at its end, the speed
    grows with θ), so the arc is at most S long.  What the step gives up to this bound is < 0.1 %
    (the spiral is locally a circle to that order): tests/test_cam_programs.py measures it.
    """
    b = SPIRAL_PITCH / (2.0 * math.pi)
    angles = [0.0]
    theta = 0.0
    for _ in range(chords):
        r = spiral_radius(theta)
        radius = (r * r + b * b) ** 1.5 / (r * r + 2.0 * b * b)  # 1/κ at the chord's start: the least on it
        arc = 2.0 * radius * math.acos(1.0 - sagitta / radius)
        step = arc / math.hypot(r, b)
        for _ in range(2):  # the speed at the chord's end, the largest on it
            step = arc / math.hypot(spiral_radius(theta + step), b)
        theta += step
        angles.append(theta)
    return angles


def spiral_program(chords: int, sagitta: float = SAGITTA) -> str:
    """The spiral program of *chords* G1 moves (see the module's docstring).

    The chords are taken for a sagitta smaller by what printing their end points with 6 decimals may move
    them, so that the printed chords are within *sagitta* of the spiral.
    """
    angles = spiral_angles(chords, sagitta - PRINTED)
    x0, y0 = spiral_point(angles[0])
    out = [f"(spiral r = 5 + 0.5*theta/2pi mm, {chords} G1 chords of sagitta <= {sagitta * 1000:g} um)",
           "G21 G90 G64", f"G0 X{_num(x0)} Y{_num(y0)}"]
    first = True
    for theta in angles[1:]:
        x, y = spiral_point(theta)
        out.append(f"G1 X{_num(x)} Y{_num(y)}" + (f" F{SPIRAL_FEED:g}" if first else ""))
        first = False
    out.append("M2")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- raster

def raster_surface(x, y):
    """z = 2 sin(x/7)·cos(y/5), mm."""
    return 2.0 * math.sin(x / 7.0) * math.cos(y / 5.0)


def raster_points(blocks: int) -> list[tuple[float, float, float]]:
    """The G1 end points of the raster of blocks // 200 rows (at least one), in order, plunge first."""
    rows = max(1, blocks // RASTER_ROW)
    points = [(0.0, 0.0, raster_surface(0.0, 0.0))]
    for row in range(rows):
        y = row * RASTER_STEPOVER
        if row:  # the step-over: one move in y at the row's end, z on the surface
            x = points[-1][0]
            points.append((x, y, raster_surface(x, y)))
        for i in range(1, RASTER_ROW + 1):
            j = i if row % 2 == 0 else RASTER_ROW - i
            x = j * RASTER_STEP
            points.append((x, y, raster_surface(x, y)))
    return points


def raster_program(blocks: int) -> str:
    """The raster program of about *blocks* G1 moves (see the module's docstring).

    Its comment has no parentheses inside it: LinuxCNC refuses a nested comment.
    """
    points = raster_points(blocks)
    rows = max(1, blocks // RASTER_ROW)
    out = [f"(raster over z = 2 sin[x/7] cos[y/5] mm, {rows} rows of {RASTER_ROW} G1 moves of "
           f"{RASTER_STEP:g} mm, {RASTER_STEPOVER:g} mm apart, zig-zag)",
           "G21 G90 G64", f"G0 X0 Y0 Z{RASTER_SAFE_Z:g}", f"G1 Z{_num(points[0][2])} F{RASTER_FEED:g}"]
    for x, y, z in points[1:]:
        out.append(f"G1 X{_num(x)} Y{_num(y)} Z{_num(z)}")
    out += [f"G0 Z{RASTER_SAFE_Z:g}", "M2"]
    return "\n".join(out) + "\n"


GENERATORS = {"spiral": spiral_program, "raster": raster_program}


def write_programs(directory, blocks=(1000, 10000), kinds=("spiral", "raster")) -> list[Path]:
    """Write ``<kind>_<N>.ngc`` into *directory* for each kind and N; return the paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for n in blocks:
        for kind in kinds:
            path = directory / f"{kind}_{n}.ngc"
            path.write_text(GENERATORS[kind](n))
            paths.append(path)
    return paths


# --------------------------------------------------------------------------- the measures of a plan stream
#
# Every measure takes the stream a chunk at a time (any chunking gives the same figures, bit for bit) and
# keeps only what the next chunk needs: the last three ticks for the differences, the last tick for the
# command segments, and one float per programmed point for the two-sided deviation.

def polyline_of(program, start=None):
    """The programmed polyline of a G-code program: (points (M + 1, dim) mm, rapid (M,) bool).

    Point 0 is where the tool starts (block 0's start), point i + 1 the end of block i, as the plan
    stream's ``n`` column numbers blocks.  Only programs of straight moves (G0, G1): an arc is refused.
    """
    from nurbsinterp.config.gcode import read_gcode
    from nurbsinterp.config.path import LineBlock
    blocks = read_gcode(str(program), start).blocks
    points = np.empty((len(blocks) + 1, len(blocks[0].start)))
    rapid = np.empty(len(blocks), dtype=bool)
    points[0] = blocks[0].start
    for i, block in enumerate(blocks):
        if not isinstance(block, LineBlock):
            raise ValueError(f"{program}: block {i} ({block.source}) is a {type(block).__name__}: the measures "
                             "take programs of straight moves only")
        points[i + 1] = block.end
        rapid[i] = block.rapid
    return points, rapid


def segment_distance(p, a, b):
    """Distances from points p to segments a-b, elementwise over the leading axes (..., dim) -> (...)."""
    ab = b - a
    ap = p - a
    length2 = np.einsum("...i,...i->...", ab, ab)
    along = np.einsum("...i,...i->...", ap, ab)
    s = np.clip(np.divide(along, length2, out=np.zeros_like(along), where=length2 > 0.0), 0.0, 1.0)
    gap = ap - s[..., None] * ab
    return np.sqrt(np.einsum("...i,...i->...", gap, gap))


@njit(cache=True, nogil=True, inline="always")
def _distance(p, i, q, j, k):
    """Distance from point p[i] to segment q[j]-q[k] (rows of (m, dim) arrays: no views made)."""
    length2 = 0.0
    along = 0.0
    for c in range(p.shape[1]):
        length2 += (q[k, c] - q[j, c]) ** 2
        along += (p[i, c] - q[j, c]) * (q[k, c] - q[j, c])
    s = 0.0 if length2 == 0.0 else min(1.0, max(0.0, along / length2))
    gap2 = 0.0
    for c in range(p.shape[1]):
        gap2 += (p[i, c] - q[j, c] - s * (q[k, c] - q[j, c])) ** 2
    return math.sqrt(gap2)


@njit(cache=True, nogil=True)
def _deviation_chunk(points, pos, block, window, nearest, start):
    """One chunk of :class:`Deviation`: (largest forward distance, its row); lowers *nearest* in place.

    Rows from *start* on are this chunk's ticks (row start - 1, if there, the previous chunk's last):
    each against the programmed segments of blocks n - window … n + window; each command segment (row
    r - 1 to r, r ≥ 1) against the programmed points n - window … n + window + 1 of its first tick's block.
    """
    last = points.shape[0] - 1  # the last programmed point; segments 0 … last - 1
    worst, where = -1.0, -1
    for r in range(start, pos.shape[0]):
        n = block[r]
        best = math.inf
        for j in range(max(0, n - window), min(last - 1, n + window) + 1):
            best = min(best, _distance(pos, r, points, j, j + 1))
        if best > worst:
            worst, where = best, r
    for r in range(1, pos.shape[0]):
        n = block[r - 1]
        for i in range(max(0, n - window), min(last, n + window + 1) + 1):
            d = _distance(points, i, pos, r - 1, r)
            if d < nearest[i]:
                nearest[i] = d
    return worst, where


class Deviation:
    """The two-sided distance between the commands and the programmed polyline, a chunk at a time.

    ``forward``: the largest distance of a command (a tick's position) from the programmed polyline.
    ``backward``: the largest distance of a programmed point (the polyline's vertices, where a blend is
    farthest from the path) from the commanded polyline (the ticks joined by straight segments).
    Both are exact distances to segments, taken over the segments near the tick's block only: a tick of
    block n against blocks n - window … n + window, a command segment from a tick of block n against
    points n - window … n + window + 1.  A minimum over fewer segments is never smaller, so both figures
    are upper bounds of the exact ones, equal to them when the nearest segment lies within the window
    (tests/test_cam_programs.py holds them to brute force).  A programmed point no command segment came
    near stays at infinity.  (The backward figure takes the vertices only: between two vertices, a
    command path that leaves a straight programmed segment farther than it leaves the vertices is not
    seen; blends and fitted curves are farthest from the path at its vertices.)
    """

    def __init__(self, points, window: int = 4):
        self.points = np.ascontiguousarray(points, dtype=float)
        self.window = int(window)
        self.nearest = np.full(len(self.points), np.inf)  # each programmed point's distance to the commands
        self.forward = 0.0
        self.forward_at = None  # (tick index, block) of the largest
        self.ticks = 0
        self._last = None  # the previous chunk's last (position, block)

    def add(self, pos, block):
        """Take a chunk: pos (m, dim) mm, block (m,) the ticks' block indices."""
        pos = np.asarray(pos, dtype=float)
        block = np.asarray(block).astype(np.int64)
        if not len(pos):
            return
        start = 0
        if self._last is not None:  # the command segment across the chunks' boundary
            pos = np.vstack([self._last[0][None], pos])
            block = np.concatenate([[self._last[1]], block])
            start = 1
        elif len(pos) == 1:  # a single tick so far: its distance to the points near it
            i = np.arange(max(0, block[0] - self.window), min(len(self.points) - 1, block[0] + self.window + 1) + 1)
            np.minimum.at(self.nearest, i, np.linalg.norm(self.points[i] - pos[0], axis=1))
        worst, r = _deviation_chunk(self.points, np.ascontiguousarray(pos), block, self.window, self.nearest, start)
        if worst > self.forward:
            self.forward, self.forward_at = float(worst), (self.ticks + r - start, int(block[r]))
        self.ticks += len(pos) - start
        self._last = (pos[-1].copy(), int(block[-1]))

    @property
    def backward(self) -> float:
        return float(self.nearest.max())

    @property
    def backward_at(self) -> int:
        """The programmed point farthest from the commands."""
        return int(np.argmax(self.nearest))


def deviation_brute_force(points, pos):
    """(forward, backward) as :class:`Deviation` defines them, over every segment: the tests' reference."""
    points = np.asarray(points, dtype=float)
    pos = np.asarray(pos, dtype=float)
    forward = segment_distance(pos[:, None, :], points[None, :-1], points[None, 1:]).min(axis=1).max()
    if len(pos) == 1:
        backward = np.linalg.norm(points - pos[0], axis=1).max()
    else:
        backward = segment_distance(points[:, None, :], pos[None, :-1], pos[None, 1:]).min(axis=1).max()
    return float(forward), float(backward)


class Differences:
    """The largest per-axis |velocity|, |acceleration|, |jerk| of the commands, a chunk at a time.

    The 1st, 2nd and 3rd differences of each axis over T, T² and T³.  With a ``feed`` flag per tick,
    ``*_feed`` takes only the differences all of whose ticks are feed ticks (not rapid), as LinuxCNC's
    figures on feed moves do.
    """

    ORDERS = ("velocity", "accel", "jerk")

    def __init__(self, period: float, dim: int):
        self.period = float(period)
        self.peak = {name: np.zeros(dim) for name in self.ORDERS}
        self.peak_feed = {name: np.zeros(dim) for name in self.ORDERS}
        self._tail = np.empty((0, dim))
        self._tail_feed = np.empty(0, dtype=bool)

    def add(self, pos, feed=None):
        pos = np.asarray(pos, dtype=float)
        feed = np.ones(len(pos), dtype=bool) if feed is None else np.asarray(feed, dtype=bool)
        x = np.vstack([self._tail, pos])
        f = np.concatenate([self._tail_feed, feed])
        carried = len(self._tail)
        d = x
        for order, name in enumerate(self.ORDERS, start=1):
            d = np.diff(d, axis=0)
            # the differences not taken before: those that end at a tick of this chunk
            fresh = d[max(0, carried - order):]
            if len(fresh):
                scaled = np.abs(fresh) / self.period ** order
                self.peak[name] = np.maximum(self.peak[name], scaled.max(axis=0))
                window = np.lib.stride_tricks.sliding_window_view(f, order + 1)[max(0, carried - order):]
                on_feed = window.all(axis=1)
                if on_feed.any():
                    self.peak_feed[name] = np.maximum(self.peak_feed[name], scaled[on_feed].max(axis=0))
        self._tail = x[-3:]
        self._tail_feed = f[-3:]


class MotionTime:
    """Motion time: from the last still tick before the first move to the last tick a move reaches (×T).

    A step of less than *still* mm on every axis is no move (as the LinuxCNC harness counts it).
    """

    def __init__(self, still: float = 1e-9):
        self.still = still
        self.first = None  # the time of the tick before the first move
        self.last = None  # the time of the tick the last move reaches
        self._prev = None  # (t, position) of the previous chunk's last tick

    def add(self, t, pos):
        t = np.asarray(t, dtype=float)
        pos = np.asarray(pos, dtype=float)
        if self._prev is not None:
            t = np.concatenate([[self._prev[0]], t])
            pos = np.vstack([self._prev[1][None], pos])
        if len(t) > 1:
            moves = np.flatnonzero((np.abs(np.diff(pos, axis=0)) > self.still).any(axis=1))
            if len(moves):
                if self.first is None:
                    self.first = float(t[moves[0]])
                self.last = float(t[moves[-1] + 1])
        self._prev = (float(t[-1]), pos[-1].copy())

    @property
    def seconds(self) -> float:
        return 0.0 if self.first is None else self.last - self.first


class StreamMeasures:
    """All the measures of one plan stream against its programmed polyline, a chunk at a time."""

    def __init__(self, columns, points, window: int = 4, period: float | None = None):
        self.columns = list(columns)
        self.axes = [self.columns.index(a) for a in ("x", "y", "z") if a in self.columns]
        if len(self.axes) == 3 and np.shape(points)[1] == 2:
            # a flat program's look-ahead stream has z too (its columns are fixed before its end is read): the
            # program's z is its start's, 0 here (no --start)
            points = np.column_stack([points, np.zeros(len(points))])
        if len(self.axes) != np.shape(points)[1]:
            raise ValueError(f"the stream has {len(self.axes)} axes, the program {np.shape(points)[1]}")
        self.deviation = Deviation(points, window)
        self.time = MotionTime()
        self.period = period
        self.differences = None
        self._first_t = None
        self.ticks = 0

    def add(self, chunk):
        chunk = np.asarray(chunk, dtype=float)
        if not len(chunk):
            return
        c = self.columns.index
        pos = chunk[:, self.axes]
        t = chunk[:, c("t")]
        if self.differences is None:
            if self.period is None:  # from the stream's own times
                if self._first_t is None and len(t) < 2:
                    raise ValueError("the first chunk needs two ticks to give the period")
                self.period = float(t[1] - t[0])
            self.differences = Differences(self.period, len(self.axes))
        feed = chunk[:, c("rapid")] == 0 if "rapid" in self.columns else None
        self.differences.add(pos, feed)
        self.deviation.add(pos, chunk[:, c("n")])
        self.time.add(t, pos)
        self.ticks += len(chunk)

    def result(self) -> dict:
        axes = "xyz"[:len(self.axes)]
        out = {"ticks": self.ticks, "period": self.period, "motion_time": self.time.seconds,
               "max_dev_forward_um": 1e3 * self.deviation.forward,
               "max_dev_backward_um": 1e3 * self.deviation.backward,
               "max_dev_um": 1e3 * max(self.deviation.forward, self.deviation.backward),
               "max_dev_forward_at": self.deviation.forward_at,
               "max_dev_backward_point": self.deviation.backward_at}
        for name in Differences.ORDERS:
            out[f"max_{name}"] = dict(zip(axes, map(float, self.differences.peak[name])))
            out[f"max_{name}_feed"] = dict(zip(axes, map(float, self.differences.peak_feed[name])))
        return out


def measure_chunks(columns, chunks, points, window: int = 4) -> dict:
    """The measures of a stream given as (columns, iterable of chunks) against *points* (see polyline_of)."""
    measures = StreamMeasures(columns, points, window)
    for chunk in chunks:
        measures.add(chunk)
    return measures.result()


class _Timed:
    """A binary pipe that notes when the first byte after the header line arrives (the first tick)."""

    def __init__(self, raw, t0):
        self.raw = raw
        self.t0 = t0
        self.header_at = None
        self.first_tick_at = None

    def readline(self, size=-1):
        line = self.raw.readline(size)
        if self.header_at is None:
            self.header_at = time.perf_counter() - self.t0
        return line

    def readinto(self, view):
        n = self.raw.readinto(view)
        if n and self.first_tick_at is None:
            self.first_tick_at = time.perf_counter() - self.t0
        return n


def plan_command(program, extra_args=()) -> list[str]:
    """The plan run the measures take: this Python's nurbsinterp, binary stream to stdout, no summary."""
    return [sys.executable, "-m", "nurbsinterp", "plan", str(program), "--format", "bin", "-q", *extra_args]


def measure(program_path, extra_args=(), window: int = 4, chunk_rows: int = 1 << 14, alone: bool = True) -> dict:
    """Plan *program_path* in a subprocess into a pipe and measure its stream as it arrives.

    Returns the stream's measures (:class:`StreamMeasures`) and the run's: ``wall`` s (start to exit),
    ``first_bytes`` s (the header line) and ``first_tick`` s (the first record) after the start,
    ``peak_rss_mb`` (the planner process's own ru_maxrss, by wait4), ``blocks`` and ``blocks_per_s``
    (blocks over wall time, start-up included), ``reader_cpu`` s (this process's CPU time reading and
    measuring the stream: near ``wall``, the measures, not the planner, set the pace), ``exit_code`` and,
    on failure, ``error`` and ``stderr``; with *alone*, ``wall_alone`` and ``blocks_per_s_alone`` of a second run
    into /dev/null (the planner's own pace).
    The stream is read in chunks of *chunk_rows* ticks and never held whole.
    """
    from nurbsinterp.streams import read_stream
    program_path = Path(program_path)
    points, _rapid = polyline_of(program_path)
    # the planner's peak RSS from GNU time, a small process that forks it: a child forked from this one would
    # report this process's own size (ru_maxrss counts the pages a child starts with, before its exec)
    gnu_time = "/usr/bin/time" if os.path.exists("/usr/bin/time") else None
    rss_file = tempfile.NamedTemporaryFile(suffix=".rss", delete=False)
    rss_file.close()
    command = plan_command(program_path, extra_args)
    if gnu_time:
        command = [gnu_time, "-f", "%M", "-o", rss_file.name, *command]
    with tempfile.TemporaryFile() as err:
        cpu0 = time.process_time()
        t0 = time.perf_counter()
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=err)
        timed = _Timed(proc.stdout, t0)
        result, failure = {}, None
        try:
            columns, chunks = read_stream(timed, str(program_path), chunk_rows=chunk_rows)
            result = measure_chunks(columns, chunks, points, window)
        except Exception as exc:  # the run failed: its exit code and stderr say why
            failure = f"{type(exc).__name__}: {exc}"
            proc.stdout.read()
        finally:
            proc.stdout.close()
            _pid, status, usage = os.wait4(proc.pid, 0)
            wall = time.perf_counter() - t0
            reader_cpu = time.process_time() - cpu0
            proc.returncode = os.waitstatus_to_exitcode(status)
        err.seek(0)
        stderr = err.read().decode("utf-8", "replace")
    result.update({"program": str(program_path), "args": list(extra_args), "blocks": len(points) - 1,
                   "wall": wall, "first_bytes": timed.header_at, "first_tick": timed.first_tick_at,
                   "peak_rss_mb": _peak_rss_mb(rss_file.name, usage), "blocks_per_s": (len(points) - 1) / wall,
                   "reader_cpu": reader_cpu, "exit_code": proc.returncode})
    if failure or proc.returncode:
        result["error"] = failure
        result["stderr"] = stderr[-2000:]
    elif alone:
        # the planner alone: the same run into /dev/null, so that the measures above (this process reading and
        # measuring every tick, which on 29.6 million ticks takes longer than planning them) do not set its pace
        t0 = time.perf_counter()
        alone = subprocess.run(plan_command(program_path, extra_args), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
        result["wall_alone"] = time.perf_counter() - t0
        result["blocks_per_s_alone"] = (len(points) - 1) / result["wall_alone"] if alone.returncode == 0 else None
    return result


# --------------------------------------------------------------------------- LinuxCNC's figures
#
# Measured on 2026-11-26 on these generators' own programs (``write DIR --blocks 1000,10000``), with
# LinuxCNC 2.9.0~pre1 (Debian 12 package linuxcnc-uspace 2.9.0~pre1+git20230208.f1270d6ed7-1+deb12u2),
# its default trajectory planner (tpmod), by the harness in ../shared/tools/linuxcnc-tp (run_one.sh as
# a non-root user, analyze.py): a headless simulated trivkins XYZ machine, per-axis 100 mm/s and
# 1 000 mm/s², T = 1 ms, the commands sampled every servo period.  The spiral runs under G64, the raster
# under G64 P0.005 Q0.001 (inserted after the G21 line).  No sampler overruns, no errors; every run ended
# on the program's last point.
#   motion_time: s, from the last still sample before the joints move to the last that moves (the leading
#       G0 and the raster's final G0 Z5 included); feed_time: the G1 part of it.
#   max_dev_joint / max_dev_axis: µm, exact largest distance of joint.N.motor-pos-cmd (after motion's
#       cubic interpolator) / axis.L.pos-cmd (the planner's output) from the programmed polyline.
#   max_accel_feed: mm/s², per axis (x, y, z), |2nd difference|/T² of the joint commands on feed samples;
#       max_accel: over all samples (the G0 moves included); max_jerk: mm/s³, per axis, all samples.
#   max_feed_speed: mm/s, motion.current-vel over the G1 samples; dips: stretches below 0.1 F.
#   max_dev_backward: µm, the largest distance of a programmed point from the joint commands joined by
#       segments (the other side, which analyze.py does not take), by this module's Deviation on the same
#       captures (the block from motion.program-line; window 8 blocks on the spiral, 80 on the raster, whose
#       Q0.001 merges moves so that the line reported runs up to ~15 blocks ahead; the 1 000-block figures
#       checked with window 300).  The same code gives analyze.py's motion time, forward deviation, per-axis
#       acceleration and jerk to the last digit on these captures.  On the raster it is 5.25 µm at the
#       row-to-step-over corners, over the 5 µm of G64 P0.005.
# Against ../shared/tools/linuxcnc-tp/README.md (the figures): raster_1000 6.991 s (README 6.989),
# raster_10000 64.873 s (64.872); spiral_1000 4.778 s (4.783), spiral_10000 69.745 s (69.791); deviation
# spiral 1.075 µm (1.09), raster 3.53 / 3.67 µm (3.63 / 3.63); spiral x/y accel 647/577 and 647/500 (640/577
# and 640/500).  The spiral runs at F all the way, so its time is its length over F, and the length goes
# as the chords' √sagitta: these chords are within 1 µm as printed (≤ 0.9988 µm before rounding, the
# rounding's 0.7 nm kept in hand), and an earlier version of them at ≤ 0.9995 µm gave 4.780 s and 69.775 s:
# the README's 69.791 s is what chords of a sagitta of 1.000 µm (at or a hair over the 1 µm) would take,
# 0.07 % more.  The README's programs are not kept, so this is inferred, not checked.  The raster runs
# gave the same figures twice.
LINUXCNC = {
    "spiral_1000": {"mode": "G64", "g1_blocks": 1000, "motion_time": 4.778, "feed_time": 4.634,
                    "max_dev_joint": 1.075, "max_dev_backward": 1.141, "max_dev_axis": 0.998,
                    "max_accel_feed": (647.1, 576.9, 0.0),
                    "max_accel": (1000.0, 576.9, 0.0), "max_jerk": (833335.0, 409340.0, 0.0),
                    "max_feed_speed": 50.0, "dips": 0},
    "raster_1000": {"mode": "G64 P0.005 Q0.001", "g1_blocks": 1005, "motion_time": 6.991, "feed_time": 6.628,
                    "max_dev_joint": 3.525, "max_dev_backward": 5.249, "max_dev_axis": 3.422,
                    "max_accel_feed": (1000.0, 1000.0, 1000.0),
                    "max_accel": (1000.0, 1000.0, 1000.0), "max_jerk": (462698.0, 833333.0, 833335.0),
                    "max_feed_speed": 33.333, "dips": 9},
    "spiral_10000": {"mode": "G64", "g1_blocks": 10000, "motion_time": 69.745, "feed_time": 69.601,
                     "max_dev_joint": 1.075, "max_dev_backward": 1.141, "max_dev_axis": 0.999,
                     "max_accel_feed": (647.1, 500.0, 0.0),
                     "max_accel": (1000.0, 500.0, 0.0), "max_jerk": (833335.0, 505831.0, 0.0),
                     "max_feed_speed": 50.0, "dips": 0},
    "raster_10000": {"mode": "G64 P0.005 Q0.001", "g1_blocks": 10050, "motion_time": 64.873, "feed_time": 64.529,
                     "max_dev_joint": 3.672, "max_dev_backward": 5.252, "max_dev_axis": 3.568,
                     "max_accel_feed": (1000.0, 1000.0, 1000.0),
                     "max_accel": (1000.0, 1000.0, 1000.0), "max_jerk": (540678.0, 833336.0, 833335.0),
                     "max_feed_speed": 33.333, "dips": 99},
}


# The exact path: LinuxCNC's G61 (exact path: it stops where consecutive moves are not tangent, slows at the
# rest) on the same programs, machine and harness, from ../shared/tools/linuxcnc-tp/README.md's results table
# (motion time s; max_dev_joint / max_dev_axis µm as above).  nurbsinterp's counterpart is the program planned
# without a tolerance (the spiral states a plain G64, no P; no --tolerance): every tick on the programmed path.
LINUXCNC_EXACT = {
    "spiral_1000": {"mode": "G61", "motion_time": 30.717, "max_dev_joint": 0.01, "max_dev_axis": 0.00},
    "raster_1000": {"mode": "G61", "motion_time": 25.636, "max_dev_joint": 0.05, "max_dev_axis": 0.00},
}

EXACT_HEAD = ("| program | blocks | motion time s (LinuxCNC 2.9, G61) | max deviation µm: commands from path / path from "
              "commands (LinuxCNC: joints / axes from path) | max per-axis v mm/s · a mm/s² · j mm/s³ |\n"
              "|---|---|---|---|---|")


def exact_row(name: str, result: dict) -> str:
    """One Markdown row of the exact-path table (deterministic columns only) from :func:`measure`'s result."""
    ref = LINUXCNC_EXACT.get(name)
    return _row(name, result, ref and (ref["max_dev_joint"], ref["max_dev_axis"]), ref, 3, 2) + " |"


def _row(name: str, result: dict, ref_dev, ref, decimals: int, empty: int) -> str:
    """The columns both tables share: program, blocks, motion time, deviations, the axes' peaks (LinuxCNC's
    figures in brackets where *ref*); a failed run's exit status and *empty* empty columns after it."""
    if result.get("exit_code"):
        return f"| {name} | {result['blocks']} | exit {result['exit_code']}: {result.get('error')}" + " |" * empty
    axes = lambda key: "/".join(f"{v:.0f}" for v in result[key].values())  # noqa: E731
    time_ = f"{result['motion_time']:.3f}" + (f" ({ref['motion_time']:.3f})" if ref else "")
    dev = (f"{result['max_dev_forward_um']:.{decimals}f} / {result['max_dev_backward_um']:.{decimals}f}"
           + (f" ({ref_dev[0]:.2f} / {ref_dev[1]:.2f})" if ref else ""))
    return f"| {name} | {result['blocks']} | {time_} | {dev} | {axes('max_velocity')} · {axes('max_accel')} · " \
           f"{axes('max_jerk')}"


# --------------------------------------------------------------------------- the table

TABLE_HEAD = ("| program | blocks | motion time s (LinuxCNC 2.9) | max deviation µm: commands from path / path from "
              "commands (LinuxCNC) "
              "| max per-axis v mm/s · a mm/s² · j mm/s³ | blocks/s end to end: measured (plan alone, `-q > /dev/null`) "
              "| peak RSS MB | first tick s |\n"
              "|---|---|---|---|---|---|---|---|")


def _peak_rss_mb(rss_path, usage) -> float:
    """MB: GNU time's %M (KB) where it ran, else wait4's ru_maxrss (an overestimate: see measure)."""
    try:
        text = Path(rss_path).read_text().strip().splitlines()
        return int(text[-1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return usage.ru_maxrss / 1024.0
    finally:
        with contextlib.suppress(OSError):
            os.unlink(rss_path)


def table_row(name: str, result: dict) -> str:
    """One Markdown row of the README's table from :func:`measure`'s result for program *name* (e.g. spiral_1000)."""
    ref = LINUXCNC.get(name)
    row = _row(name, result, ref and (ref["max_dev_joint"], ref["max_dev_backward"]), ref, 2, 5)
    if result.get("exit_code"):
        return row + " |"
    return (row + f" | {result['blocks_per_s']:.0f}"
            + (f" ({result['blocks_per_s_alone']:.0f})" if result.get("blocks_per_s_alone") else "")
            + f" | {result['peak_rss_mb']:.0f} | {result['first_tick']:.2f} |")


# --------------------------------------------------------------------------- command line

def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    write = sub.add_parser("write", help="write spiral_N.ngc and raster_N.ngc into DIR")
    write.add_argument("directory")
    write.add_argument("--blocks", default="1000,10000", help="comma-separated block counts (default 1000,10000)")
    write.add_argument("--kinds", default="spiral,raster")
    run = sub.add_parser("measure", help="plan PROGRAM and print its stream's measures as JSON",
                         epilog="python benchmarks/cam.py measure spiral_200.ngc -- --tolerance 5um")
    run.add_argument("program")
    run.add_argument("--window", type=int, default=4, help="blocks either side searched for the deviation")
    table = sub.add_parser("table", help="write the programs into DIR, plan and measure each, print the table",
                           epilog="python benchmarks/cam.py table /tmp/cam --blocks 1000,10000 -- --tolerance 5um "
                                  "--profile-type adaptive --axis-max-velocity x=100,y=100,z=100 "
                                  "--axis-max-accel x=1000,y=1000,z=1000")
    table.add_argument("directory")
    table.add_argument("--blocks", default="1000,10000")
    table.add_argument("--window", type=int, default=4)
    argv = sys.argv[1:] if argv is None else list(argv)
    plan_args = argv[argv.index("--") + 1:] if "--" in argv else []  # what follows -- goes to plan untouched
    args = parser.parse_args(argv[:len(argv) - len(plan_args) - ("--" in argv)])
    args.plan_args = plan_args
    if args.command == "table":
        print(TABLE_HEAD)
        for path in write_programs(args.directory, [int(b) for b in args.blocks.split(",")]):
            print(table_row(path.stem, measure(path, args.plan_args, args.window)), flush=True)
        return 0
    if args.command == "measure":
        import json
        print(json.dumps(measure(args.program, args.plan_args, args.window), indent=1))
        return 0
    if args.command == "write":
        blocks = [int(b) for b in args.blocks.split(",")]
        for path in write_programs(args.directory, blocks, args.kinds.split(",")):
            print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
