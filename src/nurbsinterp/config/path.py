"""A toolpath: blocks (lines, arcs, NURBS) joined end to end — the `path:` section of a job.

Each block starts where the previous one ends; a block states only where it
goes (``to``) and how.  Validation here checks the blocks one by one and their
joints; the geometry (exact NURBS of every block, arc length, corners) is built
from the frozen :class:`PathSpec` by :mod:`nurbsinterp.path`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..names import BLOCK_KINDS
from .curve import MAX_COORDINATE, CurveSpec, fingerprint_bytes, validate_curve
from .rules import MAX_CONTROL_POINTS, Where, choice, finite, mapping, quantity

PATH_KEYS = ("start", "blocks")
JOINT_KEYS = ("mode", "stop", "dwell")  # what a program says of a block's joints (BlockMode, stop, dwell)
BLOCK_KEYS = {
    "line": ("to", "feedrate", "rapid", *JOINT_KEYS),
    "arc": ("to", "center", "radius", "direction", "plane", "normal", "feedrate", *JOINT_KEYS),
}
FEED_KEYS = ("feedrate", *JOINT_KEYS)  # what a nurbs block adds to a curve's keys
MODE_KEYS = ("control", "tolerance", "naive_tolerance")
JOINT_TOL = 1e-9  # mm: a block must start this close to the previous block's end (then it starts exactly there)
ARC_RADIUS_RTOL = 1e-9  # an arc's centre must be equidistant from its ends to max(ARC_RADIUS_ATOL, this · r)
ARC_RADIUS_ATOL = 1e-6  # mm
MIN_BLOCK_LENGTH = 1e-9  # mm: a line or arc shorter than this is a zero-length block
PLANES = {"xy": (0.0, 0.0, 1.0), "zx": (0.0, 1.0, 0.0), "yz": (1.0, 0.0, 0.0)}  # G17, G18, G19: ccw about +z, +y, +x
MAX_BLOCKS = MAX_CONTROL_POINTS


# Every block may carry its own feedrate (mm/s; None: the profile's), and where it was read
# from (``source``: "line 12" of a program, "SPLINE #2F on layer CUT" of a drawing), which
# messages and `info` name; neither is geometry, so neither enters the fingerprint.  Nor do
# the program's instructions for the joints: the path-control mode in effect for the block
# (``mode``: G61, G61.1, G64 P- Q-), and a stop before it (``stop``: why the program brings
# the tool to rest before this block, as M0 or M6 do; ``dwell``: seconds held there, G4).

CONTROL_MODES = ("blend", "exact_path", "exact_stop")  # G64, G61, G61.1


@dataclass(frozen=True)
class BlockMode:
    """How the program asks the controller to pass a block's joints (LinuxCNC's path-control mode).

    ``control``: "blend" (G64: corners may be rounded), "exact_path" (G61: the path is followed
    exactly, stopping at corners that are not tangent), "exact_stop" (G61.1: the tool stops at the
    end of every block).  ``tolerance`` (G64 P, mm): the most a blend may leave the programmed
    path (None: G64 without P, no limit stated).  ``naive_tolerance`` (G64 Q, mm): how far from a
    line short collinear-enough moves may be merged (None: not given)."""

    control: str = "blend"
    tolerance: float | None = None
    naive_tolerance: float | None = None


DEFAULT_MODE = BlockMode()


@dataclass(frozen=True)
class LineBlock:
    """A straight move; ``rapid`` marks a positioning move (G0), planned at the rapid feedrate."""

    start: np.ndarray
    end: np.ndarray
    feedrate: float | None = None
    rapid: bool = False
    source: str | None = field(default=None, compare=False)
    mode: BlockMode = field(default=DEFAULT_MODE, compare=False)
    stop: str | None = field(default=None, compare=False)  # why the tool comes to rest before this block
    dwell: float = field(default=0.0, compare=False)  # seconds held at rest before this block (G4)
    kind = "line"


def line_block_fast(start, end, feedrate, rapid, source, mode, stop, dwell) -> LineBlock:
    """A LineBlock from values already valid (a reader's hot loop), without the frozen dataclass's
    per-field ``object.__setattr__`` — as scipy's ``BSpline.construct_fast`` skips its checks."""
    block = object.__new__(LineBlock)
    block.__dict__.update(start=start, end=end, feedrate=feedrate, rapid=rapid, source=source, mode=mode, stop=stop,
                          dwell=dwell)
    return block


@dataclass(frozen=True)
class ArcBlock:
    """A circular arc: from start, counter-clockwise about *normal* (a unit vector) by *sweep* radians.

    A clockwise arc is stored as a counter-clockwise one about the opposite normal.
    In 2-D the normal is +z or -z (its first two components are zero).  A helical
    arc (3-D only) also rises by *rise* mm along the normal, uniformly with the
    angle; *center* is the centre of its start's circle."""

    start: np.ndarray
    end: np.ndarray
    center: np.ndarray
    normal: np.ndarray
    sweep: float  # radians, in (0, 2π]
    rise: float = 0.0
    feedrate: float | None = None
    source: str | None = field(default=None, compare=False)
    mode: BlockMode = field(default=DEFAULT_MODE, compare=False)
    stop: str | None = field(default=None, compare=False)  # why the tool comes to rest before this block
    dwell: float = field(default=0.0, compare=False)  # seconds held at rest before this block (G4)
    kind = "arc"
    rapid = False

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.start - self.center))


@dataclass(frozen=True)
class NurbsBlock:
    curve: CurveSpec
    feedrate: float | None = None
    source: str | None = field(default=None, compare=False)
    mode: BlockMode = field(default=DEFAULT_MODE, compare=False)
    stop: str | None = field(default=None, compare=False)  # why the tool comes to rest before this block
    dwell: float = field(default=0.0, compare=False)  # seconds held at rest before this block (G4)
    kind = "nurbs"
    rapid = False

    @property
    def start(self) -> np.ndarray:
        return self.curve.control_points[0]

    @property
    def end(self) -> np.ndarray:
        return self.curve.control_points[-1]


@dataclass(frozen=True)
class PathSpec:
    """A validated toolpath: blocks joined end to end, all 2-D or all 3-D.

    ``notes`` are what a reader has to tell about how it read the file (codes it
    ignored, moves it dropped): said once on stderr, never silently dropped."""

    blocks: tuple
    dim: int
    notes: tuple = ()
    dropped: int = 0  # the zero-length moves the reader left out (a note says so; the look-ahead's summary counts them)

    @property
    def has_rapids(self) -> bool:
        return any(b.rapid for b in self.blocks)

    @property
    def curve(self) -> CurveSpec:
        if len(self.blocks) != 1 or self.blocks[0].kind != "nurbs":
            raise ValueError("this path is not a single NURBS curve")
        return self.blocks[0].curve

    @property
    def start(self) -> np.ndarray:
        return self.blocks[0].start

    @property
    def fingerprint(self) -> str:
        """16 hex digits that name this path exactly, whatever form it was written in.

        A path of one NURBS block is named by its curve's fingerprint, so that a `curve:`
        job and the `path:` that `convert` writes of it are one path; nor does the sign of
        a zero enter (a clockwise arc's normal (-0, -0, -1) is (0, 0, -1))."""
        if len(self.blocks) == 1 and self.blocks[0].kind == "nurbs":
            return self.curve.fingerprint
        import hashlib

        digest = hashlib.sha1(b"path%d" % self.dim)
        for block in self.blocks:
            digest.update(block.kind.encode())
            if block.kind == "nurbs":
                digest.update(block.curve.fingerprint.encode())
                continue
            arrays = [block.start, block.end] + ([block.center, block.normal, np.array([block.sweep])]
                                                 if block.kind == "arc" else [])
            if block.kind == "arc" and block.rise != 0.0:  # (absent otherwise: planar paths keep their names)
                arrays.append(np.array([block.rise]))
            for arr in arrays:
                digest.update(fingerprint_bytes(arr))
        return digest.hexdigest()[:16]


def path_of_curve(curve: CurveSpec) -> PathSpec:
    return PathSpec((NurbsBlock(curve),), curve.control_points.shape[1])


def _point(where: Where, name: str, value: Any, dim: int | None) -> np.ndarray:
    if not isinstance(value, list) or len(value) not in (2, 3):
        raise where.fail(name, value, "must be a point [x, y] or [x, y, z]")
    if dim is not None and len(value) != dim:
        raise where.fail(name, value, f"has {len(value)} coordinates; the path is {dim}-D")
    coords = np.array([finite(where, f"{name}[{j}]", c) for j, c in enumerate(value)])
    for j, c in enumerate(coords):
        if abs(c) > MAX_COORDINATE:
            raise where.fail(f"{name}[{j}]", value[j], f"mm is beyond the supported range of +-{MAX_COORDINATE:g} mm")
    return coords


def validate_path(raw: Any, where: Where) -> PathSpec:
    raw = mapping(where, "path", raw, PATH_KEYS)
    blocks_raw = raw.get("blocks")
    if not isinstance(blocks_raw, list) or not blocks_raw:
        raise where.fail("path.blocks", blocks_raw, "must be a non-empty list of blocks (line:, arc:, nurbs:)")
    if len(blocks_raw) > MAX_BLOCKS:
        raise where.fail("path.blocks", f"<{len(blocks_raw)} blocks>", f"has more than the limit of {MAX_BLOCKS} blocks")
    dim = None
    here = None
    if raw.get("start") is not None:
        here = _point(where, "path.start", raw["start"], None)
        dim = here.shape[0]
    blocks = []
    mode = DEFAULT_MODE  # modal, as in a program: a block's mode holds until another block gives one
    for i, item in enumerate(blocks_raw):
        name = f"path.blocks[{i}]"
        if not isinstance(item, dict) or len(item) != 1:
            raise where.fail(name, item, f"must be a mapping with one key, the block's kind ({', '.join(BLOCK_KINDS)})")
        kind, body = next(iter(item.items()))
        if kind not in BLOCK_KINDS:
            raise where.fail(f"{name}", kind, f"is not a known block kind (known: {', '.join(BLOCK_KINDS)})")
        name = f"{name}.{kind}"
        feedrate = None
        if isinstance(body, dict) and body.get("feedrate") is not None:
            feedrate = quantity(where, f"{name}.feedrate", body["feedrate"], "feedrate")
        if isinstance(body, dict) and "mode" in body:
            mode = _mode(where, f"{name}.mode", body["mode"])
        joint = _joint(where, name, body, mode)
        if kind == "nurbs":
            body = {key: value for key, value in body.items() if key not in FEED_KEYS} if isinstance(body, dict) else body
            curve = validate_curve(body, where, name)
            cdim = curve.control_points.shape[1]
            if dim is not None and cdim != dim:
                raise where.fail(f"{name}.control_points[0]", curve.control_points[0].tolist(),
                                 f"has {cdim} coordinates; the path is {dim}-D")
            dim = cdim
            if here is not None:
                gap = float(np.linalg.norm(curve.control_points[0] - here))
                if gap > JOINT_TOL:
                    raise where.fail(f"{name}.control_points[0]", curve.control_points[0].tolist(),
                                     f"is {gap:.3g} mm from the end of the previous block {_shown(here)}; a block "
                                     f"starts where the previous one ends (to {JOINT_TOL:g} mm)")
                if gap > 0:  # start exactly at the previous end
                    cps = curve.control_points.copy()
                    cps[0] = here
                    curve = CurveSpec(curve.degree, cps, curve.weights.copy(), curve.knots.copy())
            block = NurbsBlock(curve, feedrate, **joint)
        else:
            if here is None:
                raise where.fail("path.start", None, f"is needed: {name} has no start of its own (only a nurbs "
                                 "block starts at its first control point)", shown=False)
            body = mapping(where, name, body, BLOCK_KEYS[kind])
            if "to" not in body:
                raise where.fail(name, "", "needs to: [x, y] or [x, y, z]", shown=False)
            end = _point(where, f"{name}.to", body["to"], dim)
            if kind == "line":
                rapid = body.get("rapid", False)
                if not isinstance(rapid, bool):
                    raise where.fail(f"{name}.rapid", rapid, "must be true or false")
                block = _line(where, name, here, end, body["to"], feedrate, rapid, joint=joint)
            else:
                block = _arc(where, name, body, here, end, dim, feedrate, joint=joint)
        blocks.append(block)
        here = block.end
    return PathSpec(tuple(blocks), dim)


def _mode(where: Where, name: str, raw: Any) -> BlockMode:
    """A block's ``mode:`` mapping: control (blend, exact_path, exact_stop) and the blend's tolerances."""
    raw = mapping(where, name, raw, MODE_KEYS)
    control = choice(where, f"{name}.control", raw.get("control", "blend"), CONTROL_MODES)
    values = {}
    for key in ("tolerance", "naive_tolerance"):
        if raw.get(key) is not None:
            if control != "blend":
                raise where.fail(f"{name}.{key}", raw[key], f"is a blend's tolerance; control is {control}")
            values[key] = quantity(where, f"{name}.{key}", raw[key], "length", zero_ok=True)
    return BlockMode(control, values.get("tolerance"), values.get("naive_tolerance"))


def _joint(where: Where, name: str, body: Any, mode: BlockMode) -> dict:
    """The mode in effect for a block, and its own stop (a reason) and dwell (s) before it."""
    out = {"mode": mode, "stop": None, "dwell": 0.0}
    if not isinstance(body, dict):
        return out
    stop = body.get("stop")
    if stop is not None:
        if not isinstance(stop, str) or not stop.strip():
            raise where.fail(f"{name}.stop", stop, "must be the reason the tool stops before this block (text)")
        out["stop"] = stop.strip()
    if body.get("dwell") is not None:
        out["dwell"] = quantity(where, f"{name}.dwell", body["dwell"], "time", zero_ok=True)
        if out["stop"] is None and out["dwell"] > 0:
            out["stop"] = "dwell"
    return out


def _shown(point) -> str:
    return "[" + ", ".join(repr(float(c)) for c in point) + "]"


def _line(where: Where, name: str, start, end, raw, feedrate=None, rapid=False, source=None, joint=None) -> LineBlock:
    length = float(np.linalg.norm(end - start))
    if length <= MIN_BLOCK_LENGTH:
        raise where.fail(f"{name}.to", raw, f"is {length:.3g} mm from the block's start: a zero-length block "
                         f"(lines must be longer than {MIN_BLOCK_LENGTH:g} mm)")
    return LineBlock(start, end, feedrate, rapid, source, **(joint or {}))


#: the coordinate plane (first, second in-plane axis) of an arc about each coordinate axis, in G17/G18/G19's order
#: (about z: x, y; about y: z, x; about x: y, z): config/gcode reads its arcs' angles in these coordinates
AXIS_PLANES = {2: (0, 1), 1: (2, 0), 0: (1, 2)}


def plane_angle(e1, e2, ccw: bool) -> float:
    """The angle from e1 to e2, two in-plane vectors (first, second axis), in the arc's direction, in (-π, π].

    One expression for both readers of arcs: an arc `convert` writes from a G-code program is read back with
    the same bits (a dot product of three coordinates rounds otherwise than one of two where the machine's BLAS
    fuses a multiply-add: the sweeps differed by an ulp and the paths' fingerprints with them)."""
    angle = math.atan2(e1[0] * e2[1] - e1[1] * e2[0], float(e1 @ e2))
    return angle if ccw else -angle



def _arc(where: Where, name: str, body: dict, start, end, dim: int, feedrate=None, source=None,
         joint=None) -> ArcBlock:
    """An arc from its fields: *body* holds ``to``, ``center`` or ``radius``, ``direction``, and in 3-D
    ``plane`` or ``normal``.  In 3-D an end off the arc's plane makes a helix: the rise along the normal
    is spread evenly over the turn (G2/G3 with the third axis moving)."""
    direction = choice(where, f"{name}.direction", body.get("direction", "ccw"), ("ccw", "cw"))
    if dim == 2:
        for key in ("plane", "normal"):
            if key in body:
                raise where.fail(f"{name}.{key}", body[key], "is for 3-D paths; a 2-D arc turns in the xy plane")
        axis = np.array([0.0, 0.0, 1.0])
    elif "plane" in body and "normal" in body:
        raise where.fail(f"{name}.normal", body["normal"], f"is given together with {name}.plane; give one")
    elif "normal" in body:
        axis = _point(where, f"{name}.normal", body["normal"], 3)
        size = float(np.linalg.norm(axis))
        if not size > 0 or not math.isfinite(size):
            raise where.fail(f"{name}.normal", body["normal"], "must be a non-zero vector")
        axis = axis / size
    else:
        axis = np.array(PLANES[choice(where, f"{name}.plane", body.get("plane", "xy"), tuple(PLANES))])
    if direction == "cw":
        axis = -axis
    s3, e3 = np.append(start, 0.0)[:3], np.append(end, 0.0)[:3]
    rise = float((e3 - s3) @ axis)
    if abs(rise) <= JOINT_TOL:
        rise = 0.0
    e3 = e3 - rise * axis  # the end's projection on the start's plane: the circle's own end
    chord = e3 - s3
    if ("center" in body) == ("radius" in body):
        raise where.fail(name, "", "needs center: [x, y(, z)] or radius: r (one of them)", shown=False)
    if "center" in body:
        c3 = np.append(_point(where, f"{name}.center", body["center"], dim), 0.0)[:3]
        r0, r1 = float(np.linalg.norm(s3 - c3)), float(np.linalg.norm(e3 - c3))
        if abs(float((c3 - s3) @ axis)) > JOINT_TOL:
            raise where.fail(f"{name}.center", body["center"], "is not in the plane of the arc's start and normal")
        tol = max(ARC_RADIUS_ATOL, ARC_RADIUS_RTOL * r0)
        if abs(r1 - r0) > tol:
            raise where.fail(f"{name}.center", body["center"], f"is {r0!r} mm from the arc's start and {r1!r} mm from "
                             f"its end: they differ by {abs(r1 - r0):.3g} mm, more than the {tol:.3g} mm allowed")
        if r0 <= MIN_BLOCK_LENGTH:
            raise where.fail(f"{name}.center", body["center"], "is the arc's start: a zero-radius arc")
    else:
        r = quantity(where, f"{name}.radius", body["radius"], "length", positive=False)
        half = float(np.linalg.norm(chord)) / 2
        if half <= MIN_BLOCK_LENGTH:
            raise where.fail(f"{name}.radius", body["radius"], "cannot place a full circle: give its center")
        if abs(r) < half - max(ARC_RADIUS_ATOL, ARC_RADIUS_RTOL * abs(r)):
            raise where.fail(f"{name}.radius", body["radius"], f"is smaller than half the chord to the end ({half!r} mm)")
        h = math.sqrt(max(r * r - half * half, 0.0))
        side = np.cross(axis, chord / (2 * half))  # towards the centre of the short ccw arc
        c3 = s3 + chord / 2 + (h if r > 0 else -h) * side
    # the sweep, ccw about axis, in (0, 2π]: a closed arc (to = start) is a full circle
    u, v = s3 - c3, e3 - c3
    along = np.flatnonzero(axis)
    if along.shape[0] == 1:  # about a coordinate axis: in that plane's coordinates, as the G-code reader reads it
        a0, a1 = AXIS_PLANES[int(along[0])]
        sweep = plane_angle(u[[a0, a1]], v[[a0, a1]], bool(axis[along[0]] > 0))
    else:
        sweep = math.atan2(float(np.cross(u, v) @ axis), float(u @ v))
    if float(np.linalg.norm(chord)) <= JOINT_TOL:
        sweep = 2 * math.pi
    elif sweep <= 0:
        sweep += 2 * math.pi
    center = c3[:dim]
    normal = axis + 0.0  # -(0, 0, 1) of a clockwise arc is (-0, -0, -1): the same normal, written with plain zeros
    if sweep * float(np.linalg.norm(u)) <= MIN_BLOCK_LENGTH:
        raise where.fail(f"{name}.to", body["to"], "makes a zero-length arc")
    return ArcBlock(start, end, center, normal, sweep, rise, feedrate, source, **(joint or {}))
