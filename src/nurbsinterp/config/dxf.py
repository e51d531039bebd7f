"""The DXF reader: a drawing's model space as a toolpath (lines, arcs and NURBS blocks).

Entities read (in world coordinates, ezdxf converting each entity's OCS):

- ``LINE``; ``ARC`` and ``CIRCLE`` (exact arcs, counter-clockwise about the entity's
  extrusion: an extrusion of (0, 0, -1) turns clockwise in the xy plane);
- ``LWPOLYLINE`` and 2-D/3-D ``POLYLINE``: one line or arc block per segment, a
  bulge b being an arc of sweep 4·atan|b| (counter-clockwise about the extrusion
  for b > 0); spline-fitted polylines are read as the vertices CAD shows (their
  frame control points are skipped); repeated vertices are skipped (a note);
- ``SPLINE``: control points, weights and knots as written, the degree taken from
  the counts (len(knots) - len(control points) - 1: ezdxf reports degree 3 for the
  SPLINEs of R12-style files).  An unclamped or periodic (closed) spline is made
  clamped exactly, by inserting its domain's end knots until they are p-fold
  (Boehm) and dropping what lies outside the domain [U_p, U_{n+1}].  A spline given
  only by fit points is fitted as AutoCAD and BricsCAD fit it (cubic, chord-length
  knots, natural ends or the end tangents given: ``ezdxf.math.fit_points_to_cad_cv``,
  as ezdxf's own ``Spline.construction_tool``); a note says so, since a CAD program
  may place it slightly differently.  A closed fit-point spline (a periodic fit) is
  refused;
- ``ELLIPSE``: its exact rational quadratic NURBS (``rational_bspline_from_ellipse``).

Everything else (TEXT, DIMENSION, INSERT, POINT, HATCH, meshes...) is no toolpath:
the path's notes list it once, counted by type.  Coordinates are read as mm, unscaled:
``$INSUNITS`` is the unit of block insertion, often wrong (ezdxf itself writes metres
into every new drawing), so a drawing that names another unit gets a note, not a scale.

Chains.  Entities are chained end to end: an entity whose start or end lies within
``chain_tolerance`` of a chain's free end extends it (reversed where needed: a
reversed spline has its control points and weights reversed and its knots mirrored),
the nearest end first, then drawing order.  A chain starts at the first entity, in
drawing order, not yet used, keeps that entity's direction, and grows forward then
backward; a closed entity (a circle, a closed polyline or spline) is a chain of its
own.  The default tolerance, DEFAULT_CHAIN_TOLERANCE = 0.01 mm, is ten times the
largest gaps CAD drawings commonly carry between entities that are meant to meet
(1e-6..1e-3 mm: coordinates rounded on export, arc ends computed from angles), and
small next to what a milling job resolves, so that chains do not break at those
gaps, while two contours drawn apart stay apart.  A gap closed within a chain moves
the end of a line or the end control point of a spline (the curve moves by at most
the gap, near that end) onto its neighbour's end; an arc's end moves only within the
arc radius tolerance; two arcs farther apart than that are joined by a short line
block.  The notes tell how many gaps were closed and the largest.

Several chains and no ``chain``: all are planned, in chain order (the drawing order of
their first entities), joined by straight ``rapid`` line blocks from one chain's end to
the next chain's start, as a CAM post moves between contours; a note says so.
``chain=N`` plans chain N alone; ``layer`` reads one layer's entities only (layer names
match as in CAD, case-insensitively).  :func:`dxf_chains` lists the chains (:func:`dxf_outline`
for `nurbsinterp info`).

Every error is one line: ``<file>: SPLINE #2F on layer CUT: <what is wrong>``, naming the
entity by its handle and layer, or ``<file>: <what is wrong>`` for the drawing.  The
whole drawing is read and checked before anything is returned.
"""
from __future__ import annotations

import logging
import math
import os
from collections import Counter
from dataclasses import dataclass, replace

import numpy as np

from ..errors import SpecError
from .curve import MAX_COORDINATE, CurveSpec, validate_curve
from .path import (ARC_RADIUS_ATOL, ARC_RADIUS_RTOL, JOINT_TOL, MAX_BLOCKS, MIN_BLOCK_LENGTH, ArcBlock, LineBlock,
                   NurbsBlock, PathSpec)
from .rules import Where, integer, quantity

DEFAULT_CHAIN_TOLERANCE = 0.01  # mm (see the module's docstring)
MAX_DXF_BYTES = 256 * 1024 * 1024
TOOLPATH_TYPES = ("LINE", "ARC", "CIRCLE", "ELLIPSE", "LWPOLYLINE", "POLYLINE", "SPLINE")
#: $INSUNITS codes other than 0 (unitless) and 4 (mm), named in the note that says they are not applied
UNIT_NAMES = {1: "inches", 2: "feet", 3: "miles", 5: "centimetres", 6: "metres", 7: "kilometres", 8: "microinches",
              9: "mils", 10: "yards", 11: "angstroms", 12: "nanometres", 13: "microns", 14: "decimetres"}
SPLINE_FRAME_VERTEX = 16  # POLYLINE vertex flag: a spline-fit polyline's frame control point (not on the curve)


@dataclass(frozen=True)
class _Piece:
    """One oriented primitive (WCS, mm, 3-vectors): a line, an arc (ccw about *normal*) or a clamped NURBS."""

    kind: str
    label: str
    start: np.ndarray
    end: np.ndarray
    center: np.ndarray | None = None
    normal: np.ndarray | None = None
    sweep: float = 0.0
    degree: int = 0
    points: np.ndarray | None = None
    weights: np.ndarray | None = None
    knots: np.ndarray | None = None

    def reversed(self) -> _Piece:
        if self.kind == "nurbs":
            knots = self.knots[0] + self.knots[-1] - self.knots[::-1]
            return replace(self, start=self.end, end=self.start, points=self.points[::-1].copy(),
                           weights=self.weights[::-1].copy(), knots=knots)
        if self.kind == "arc":
            return replace(self, start=self.end, end=self.start, normal=-self.normal)
        return replace(self, start=self.end, end=self.start)

    @property
    def radius(self) -> float:
        return float(np.linalg.norm(self.start - self.center))


@dataclass(frozen=True)
class _Entity:
    """A toolpath entity of the drawing, as its pieces in drawing (or reversed) order."""

    dxftype: str
    handle: str
    layer: str
    pieces: tuple

    @property
    def start(self) -> np.ndarray:
        return self.pieces[0].start

    @property
    def end(self) -> np.ndarray:
        return self.pieces[-1].end

    def reversed(self) -> _Entity:
        return replace(self, pieces=tuple(p.reversed() for p in reversed(self.pieces)))


@dataclass(frozen=True)
class _Chain:
    entities: tuple
    closed: bool


# --------------------------------------------------------------------------- public API

def read_dxf_job(name: str, *, layer: str | None = None, chain: int | None = None,
                 chain_tolerance: float | str | None = None, **_other) -> tuple[PathSpec, dict]:
    """The DXF reader: (the path, ``{}``); a drawing carries no profile settings.

    Parameters
    ----------
    name : the DXF file.
    layer : read this layer only (case-insensitive); None: every layer.
    chain : plan chain N alone (1-based, as :func:`dxf_chains` numbers them); None:
        every chain, joined by rapid moves.
    chain_tolerance : float, mm (or a length with a unit, "5 um"): the largest gap
        between two entity ends that still chains them; None: DEFAULT_CHAIN_TOLERANCE.
    _other : options of the other readers, ignored.

    Raises
    ------
    SpecError : one line naming the file, and the entity (handle and layer) where one is at fault.
    """
    tol = _tolerance(name, chain_tolerance)
    number = _chain_number(name, chain)
    entities, notes = _entities(name, layer)
    chains, chain_notes = _chains(entities, tol)
    where = f" on layer {layer}" if layer is not None else ""
    if number is not None:
        if number > len(chains):
            raise SpecError(f"{name}: chain = {number} does not exist: the drawing{where} has {len(chains)} "
                            f"chain{'s' if len(chains) != 1 else ''}")
        picked = [chains[number - 1]]
        notes.append(f"chain {number} of {len(chains)} planned alone")
    else:
        picked = chains
        if len(chains) > 1:
            notes.append(f"the drawing{where} has {len(chains)} chains: all are planned, in drawing order, joined "
                         f"by {len(chains) - 1} rapid move{'s' if len(chains) > 2 else ''} (straight, at the rapid "
                         "feedrate); choose one by its number (the chain option) to plan it alone")
    notes.extend(note for k, note in chain_notes if number is None or k == number - 1)
    dim = _dimension([p for c in picked for e in c.entities for p in e.pieces])
    blocks = _blocks(name, picked, tol, dim, notes)
    if len(blocks) > MAX_BLOCKS:
        raise SpecError(f"{name}: has {len(blocks)} blocks, more than the limit of {MAX_BLOCKS}")
    return PathSpec(tuple(blocks), dim, notes=tuple(notes)), {}


def dxf_chains(name: str, *, layer: str | None = None, chain_tolerance: float | str | None = None,
               **_other) -> list[dict]:
    """The drawing's chains, as `nurbsinterp info` lists them: plain JSON-able values.

    Each is ``{"chain": N (1-based), "layers": [...], "entities": {"LINE": 3, ...},
    "start": [x, y(, z)], "end": [...], "closed": bool, "handles": [...]}``, the
    entities in path order; points in mm, 2-D when every z of the drawing is 0.
    """
    tol = _tolerance(name, chain_tolerance)
    entities, _notes = _entities(name, layer)
    chains, _chain_notes = _chains(entities, tol)
    dim = _dimension([p for e in entities for p in e.pieces])
    out = []
    for number, c in enumerate(chains, 1):
        out.append({
            "chain": number,
            "layers": sorted({e.layer for e in c.entities}),
            "entities": dict(Counter(e.dxftype for e in c.entities)),
            "start": [float(v) for v in c.entities[0].start[:dim]],
            "end": [float(v) for v in c.entities[-1].end[:dim]],
            "closed": c.closed,
            "handles": [e.handle for e in c.entities],
        })
    return out


def dxf_outline(name: str, *, layer: str | None = None, chain_tolerance: float | str | None = None,
                **_other) -> dict:
    """What `nurbsinterp info` lists of a drawing beyond its path (:func:`~.readers.outline_for`):
    ``{"chains": dxf_chains(...)}``; the other options (``chain``, a G-code ``start``) are ignored."""
    return {"chains": dxf_chains(name, layer=layer, chain_tolerance=chain_tolerance)}


# --------------------------------------------------------------------------- options

def _tolerance(name: str, value) -> float:
    if value is None:
        return DEFAULT_CHAIN_TOLERANCE
    where = Where(name)
    tol = quantity(where, "chain_tolerance", value, "length", zero_ok=True)
    if tol < JOINT_TOL:
        raise where.fail("chain_tolerance", value, f"mm is below {JOINT_TOL:g} mm (ends that close are one point)")
    return tol


def _chain_number(name: str, value) -> int | None:
    if value is None:
        return None
    where = Where(name)
    if isinstance(value, bool):
        raise where.fail("chain", value, "must be a chain number (1, 2, ...)")
    number = integer(where, "chain", value)
    if number < 1:
        raise where.fail("chain", value, "must be >= 1 (chains are numbered from 1)")
    return number


# --------------------------------------------------------------------------- reading the drawing

def _document(name: str):
    import ezdxf

    log = logging.getLogger("ezdxf")  # a library's warnings must not reach stderr through logging's last resort
    if not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())
    if os.path.isdir(name):
        raise SpecError(f"{name}: is a directory, not a DXF file")
    try:
        size = os.path.getsize(name)
    except OSError as exc:
        raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None
    if size > MAX_DXF_BYTES:
        raise SpecError(f"{name}: larger than {MAX_DXF_BYTES // 2**20} MiB; refusing to read it")
    if size == 0:
        raise SpecError(f"{name}: the file is empty")
    try:
        return ezdxf.readfile(name)
    except ezdxf.DXFStructureError as exc:
        raise SpecError(f"{name}: is not a readable DXF file: {_one_line(exc)}") from None
    except OSError as exc:
        if exc.errno is not None:
            raise SpecError(f"{name}: cannot read: {exc.strerror or exc}") from None
        raise SpecError(f"{name}: is not a DXF file") from None
    except Exception as exc:  # ezdxf raises StopIteration, ValueError... on truncated or corrupt files
        raise SpecError(f"{name}: is not a readable DXF file (truncated or corrupt: "
                        f"{type(exc).__name__}{': ' + _one_line(exc) if str(exc) else ''})") from None


def _one_line(exc) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _entities(name: str, layer: str | None) -> tuple[list[_Entity], list[str]]:
    """The toolpath entities of the model space (of *layer*), in drawing order, and the reader's notes."""
    doc = _document(name)
    notes = []
    units = doc.header.get("$INSUNITS", 0) if doc.dxfversion >= "AC1015" else 0  # (R12 has no $INSUNITS)
    if units not in (0, 4):
        notes.append(f"the drawing's $INSUNITS = {units} says {UNIT_NAMES.get(units, 'another unit than mm')}; "
                     "its coordinates are read as mm, unscaled")
    every = list(doc.modelspace())
    if not every:
        raise SpecError(f"{name}: the drawing's model space is empty")
    chosen = every
    if layer is not None:
        chosen = [e for e in every if e.dxf.layer == layer] or [e for e in every
                                                                if e.dxf.layer.casefold() == str(layer).casefold()]
        if not chosen:
            present = Counter(e.dxf.layer for e in every)
            listed = ", ".join(f"{lay} ({n})" for lay, n in sorted(present.items()))
            raise SpecError(f"{name}: layer {layer!r} has no entities (layers with entities: {listed})")
    ignored: Counter = Counter()
    skipped: list[str] = []
    entities = []
    for e in chosen:
        kind = e.dxftype()
        if kind not in TOOLPATH_TYPES or (kind == "POLYLINE" and not (e.is_2d_polyline or e.is_3d_polyline)):
            ignored[kind if kind != "POLYLINE" else "POLYLINE (mesh)"] += 1
            continue
        label = f"{kind} #{e.dxf.handle} on layer {e.dxf.layer}"
        at = f"{name}: {label}"
        pieces = _READ[kind](e, at, label, notes, skipped)
        if pieces:
            for piece in pieces:
                _check_range(at, piece)
            entities.append(_Entity(kind, str(e.dxf.handle), str(e.dxf.layer), tuple(pieces)))
    if ignored:
        notes.insert(0, "ignored (not toolpath geometry): " + ", ".join(f"{n} {kind}" for kind, n in
                                                                       sorted(ignored.items())))
    if skipped:
        shown = ", ".join(skipped[:5]) + (f" and {len(skipped) - 5} more" if len(skipped) > 5 else "")
        notes.append(f"skipped {len(skipped)} zero-length element{'s' if len(skipped) > 1 else ''}: {shown}")
    if not entities:
        where = f" on layer {layer}" if layer is not None else ""
        found = ("; it has only " + ", ".join(f"{n} {kind}" for kind, n in sorted(ignored.items()))) if ignored else ""
        raise SpecError(f"{name}: has no toolpath entities{where} ({', '.join(TOOLPATH_TYPES)}){found}")
    return entities, notes


def _check_range(at: str, piece: _Piece) -> None:
    for arr in (piece.start, piece.end, piece.center, piece.points):
        if arr is None:
            continue
        if not np.isfinite(arr).all():
            raise SpecError(f"{at}: has a coordinate that is not a finite number")
        if np.abs(arr).max() > MAX_COORDINATE:
            raise SpecError(f"{at}: has a coordinate of {np.abs(arr).max():.6g} mm, beyond the supported "
                            f"range of +-{MAX_COORDINATE:g} mm")


def _vec(v) -> np.ndarray:
    return np.array([float(v[0]), float(v[1]), float(v[2]) if len(v) > 2 else 0.0])


def _line(e, at, label, notes, skipped):
    start, end = _vec(e.dxf.start), _vec(e.dxf.end)
    if not np.isfinite(start).all() or not np.isfinite(end).all():
        raise SpecError(f"{at}: has a coordinate that is not a finite number")
    if float(np.linalg.norm(end - start)) <= MIN_BLOCK_LENGTH:
        skipped.append(label)
        return []
    return [_Piece("line", label, start, end)]


def _arc(e, at, label, notes, skipped):
    ocs = e.ocs()
    c = e.dxf.center
    r = float(e.dxf.radius)
    if not (math.isfinite(r) and r > 0):
        raise SpecError(f"{at}: radius = {r!r} mm must be > 0")
    if e.dxftype() == "CIRCLE":
        a0, span = 0.0, 360.0
    else:
        from ezdxf.math import arc_angle_span_deg

        a0, span = float(e.dxf.start_angle), arc_angle_span_deg(float(e.dxf.start_angle), float(e.dxf.end_angle))
    sweep = math.radians(span)
    if sweep * r <= MIN_BLOCK_LENGTH:
        skipped.append(label)
        return []

    def at_angle(deg):
        a = math.radians(deg)
        return _vec(ocs.to_wcs((c[0] + r * math.cos(a), c[1] + r * math.sin(a), c[2])))

    start = at_angle(a0)
    end = start if span == 360.0 else at_angle(a0 + span)
    normal = _unit(_vec(e.dxf.extrusion), at)
    return [_Piece("arc", label, start, end, center=_vec(ocs.to_wcs(c)), normal=normal, sweep=sweep)]


def _unit(v: np.ndarray, at: str) -> np.ndarray:
    size = float(np.linalg.norm(v))
    if not (size > 0 and math.isfinite(size)):
        raise SpecError(f"{at}: extrusion = {v.tolist()} is not a direction")
    return v / size


def _ellipse(e, at, label, notes, skipped):
    from ezdxf.math import rational_bspline_from_ellipse

    ratio = float(e.dxf.ratio)
    if not (math.isfinite(ratio) and 0 < ratio <= 1):
        raise SpecError(f"{at}: ratio = {ratio!r} must be in (0, 1]")
    tool = e.construction_tool()
    if tool.param_span * float(np.linalg.norm(_vec(e.dxf.major_axis))) * ratio <= MIN_BLOCK_LENGTH:
        skipped.append(label)
        return []
    spline = rational_bspline_from_ellipse(tool)
    points = np.array([_vec(p) for p in spline.control_points])
    return [_nurbs_piece(at, label, spline.degree, points, np.array(spline.weights(), dtype=float),
                         np.array(spline.knots(), dtype=float))]


def _lwpolyline(e, at, label, notes, skipped):
    z = float(e.dxf.elevation)
    vertices = [((float(x), float(y), z), float(b)) for x, y, b in e.get_points("xyb")]
    return _polyline_pieces(e, vertices, bool(e.closed), e.ocs(), at, label, skipped)


def _polyline(e, at, label, notes, skipped):
    if e.is_3d_polyline:
        from ezdxf.math import OCS

        vertices = [(tuple(v.dxf.location), 0.0) for v in e.vertices if not v.dxf.flags & SPLINE_FRAME_VERTEX]
        ocs = OCS()
    else:
        z = float(e.dxf.elevation[2])
        vertices = [((float(v.dxf.location[0]), float(v.dxf.location[1]), z), float(v.dxf.bulge))
                    for v in e.vertices if not v.dxf.flags & SPLINE_FRAME_VERTEX]
        ocs = e.ocs()
    return _polyline_pieces(e, vertices, bool(e.is_closed), ocs, at, label, skipped)


def _polyline_pieces(e, vertices, closed, ocs, at, label, skipped):
    """Each segment of a polyline (vertices in its OCS, each with the bulge of the segment it starts)."""
    if len(vertices) < 2:
        raise SpecError(f"{at}: has {len(vertices)} vertex{'es' if len(vertices) != 1 else ''}; a polyline needs two")
    extrusion = _unit(_vec(e.dxf.extrusion), at)
    count = len(vertices) if closed else len(vertices) - 1
    pieces = []
    for i in range(count):
        (p0, bulge), (p1, _) = vertices[i], vertices[(i + 1) % len(vertices)]
        seg = f"{label.split(' on layer ')[0]} (segment {i + 1}) on layer {label.split(' on layer ')[1]}"
        a, b = np.array(p0, dtype=float), np.array(p1, dtype=float)
        if not (np.isfinite(a).all() and np.isfinite(b).all() and math.isfinite(bulge)):
            raise SpecError(f"{at}: vertex {i + 1} is not a finite point")
        chord = b[:2] - a[:2]
        half = float(np.linalg.norm(chord)) / 2
        if float(np.linalg.norm(b - a)) <= MIN_BLOCK_LENGTH:
            skipped.append(seg)
            continue
        start, end = _vec(ocs.to_wcs(p0)), _vec(ocs.to_wcs(p1))
        if bulge == 0:
            pieces.append(_Piece("line", seg, start, end))
            continue
        left = np.array([-chord[1], chord[0]]) / (2 * half)
        mid = (a[:2] + b[:2]) / 2
        c2 = mid + left * half * (1 - bulge * bulge) / (2 * bulge)
        center = _vec(ocs.to_wcs((c2[0], c2[1], a[2])))
        pieces.append(_Piece("arc", seg, start, end, center=center, normal=math.copysign(1.0, bulge) * extrusion,
                             sweep=4 * math.atan(abs(bulge))))
    return pieces


def _spline(e, at, label, notes, skipped):
    points = np.array([_vec(p) for p in e.control_points]).reshape(-1, 3)
    if points.shape[0] == 0:
        return [_fitted_spline(e, at, label, notes)]
    n = points.shape[0]
    knots = np.array(list(e.knots), dtype=float)
    weights = np.array(list(e.weights), dtype=float)
    if knots.size == 0:
        raise SpecError(f"{at}: has {n} control points and no knots")
    degree = knots.size - n - 1
    if degree < 1:
        raise SpecError(f"{at}: has {knots.size} knots for {n} control points: degree = knots - control points - 1 "
                        f"= {degree}; a spline needs control points + degree + 1 knots (the periodic form with "
                        "control points + 1 knots is not read: save it with its control points wrapped)")
    if weights.size and weights.size != n:
        raise SpecError(f"{at}: has {weights.size} weights for {n} control points (one each, or none)")
    if not np.isfinite(knots).all():
        raise SpecError(f"{at}: knots[{int(np.argmin(np.isfinite(knots)))}] is not a finite number")
    for i in range(1, knots.size):
        if knots[i] < knots[i - 1]:
            raise SpecError(f"{at}: knots[{i}] = {float(knots[i])!r} is smaller than knots[{i - 1}] = "
                            f"{float(knots[i - 1])!r}")
    if weights.size == 0:
        weights = np.ones(n)
    for i, w in enumerate(weights):
        if not (math.isfinite(w) and w > 0):
            raise SpecError(f"{at}: weights[{i}] = {float(w)!r} must be > 0")
    if not knots[degree] < knots[n]:
        raise SpecError(f"{at}: its knot domain [knots[{degree}], knots[{n}]] = "
                        f"[{float(knots[degree])!r}, {float(knots[n])!r}] is empty")
    points, weights, knots = _clamped(degree, points, weights, knots)
    return [_nurbs_piece(at, label, degree, points, weights, knots)]


def _fitted_spline(e, at, label, notes):
    fit = [_vec(p) for p in e.fit_points]
    if len(fit) < 2:
        raise SpecError(f"{at}: has no control points and {len(fit)} fit point{'s' if len(fit) != 1 else ''}; "
                        "a spline needs control points or two fit points or more")
    if e.closed:
        raise SpecError(f"{at}: is closed and defined by {len(fit)} fit points only (a periodic fit, which is not "
                        "read); save the drawing with the spline's control points")
    from ezdxf.math import fit_points_to_cad_cv

    tangents = None
    if e.dxf.hasattr("start_tangent") and e.dxf.hasattr("end_tangent"):
        tangents = [e.dxf.start_tangent, e.dxf.end_tangent]
    try:
        spline = fit_points_to_cad_cv(fit, tangents=tangents)
    except Exception as exc:  # a singular system: repeated fit points
        raise SpecError(f"{at}: its {len(fit)} fit points cannot be fitted ({_one_line(exc)})") from None
    ends = "the end tangents given" if tangents else "natural ends"
    notes.append(f"{label}: defined by {len(fit)} fit points only; fitted as a cubic through them as AutoCAD and "
                 f"BricsCAD do (chord-length knots, {ends}), which a CAD program may place slightly differently")
    points = np.array([_vec(p) for p in spline.control_points])
    return _nurbs_piece(at, label, spline.degree, points, np.ones(points.shape[0]),
                        np.array(spline.knots(), dtype=float))


def _nurbs_piece(at, label, degree, points, weights, knots) -> _Piece:
    """A clamped NURBS, checked as a YAML ``nurbs:`` block is (:func:`validate_curve`)."""
    raw = {"degree": int(degree), "control_points": points.tolist(), "weights": weights.tolist(),
           "knots": knots.tolist()}
    curve = validate_curve(raw, Where(at), "spline")
    pts = np.array(curve.control_points)
    return _Piece("nurbs", label, pts[0].copy(), pts[-1].copy(), degree=curve.degree, points=pts,
                  weights=np.array(curve.weights), knots=np.array(curve.knots))


def _clamped(p: int, points: np.ndarray, weights: np.ndarray, knots: np.ndarray):
    """The same curve on its domain [U_p, U_{n+1}] with clamped knots: the domain's ends inserted until p-fold."""
    from ..path import insert_knot  # the exact NURBS operations of the geometry stage

    Pw = np.column_stack([points * weights[:, None], weights])
    U = knots
    a, b = float(U[p]), float(U[-p - 1])
    if not (U[: p + 1] == a).all():
        Pw, U = insert_knot(p, Pw, U, a, max(0, p - int(np.count_nonzero(U == a))))
        k = int(np.flatnonzero(U == a)[-1])  # the last a: C(a) = P[k - p]
        Pw, U = Pw[k - p:], np.concatenate([np.full(p + 1, a), U[k + 1:]])
    if not (U[-p - 1:] == b).all():
        Pw, U = insert_knot(p, Pw, U, b, max(0, p - int(np.count_nonzero(U == b))))
        f = int(np.flatnonzero(U == b)[0])  # the first b: C(b) = P[f - 1]
        Pw, U = Pw[:f], np.concatenate([U[:f], np.full(p + 1, b)])
    return Pw[:, :-1] / Pw[:, -1:], Pw[:, -1].copy(), U


_READ = {"LINE": _line, "ARC": _arc, "CIRCLE": _arc, "ELLIPSE": _ellipse, "LWPOLYLINE": _lwpolyline,
         "POLYLINE": _polyline, "SPLINE": _spline}


# --------------------------------------------------------------------------- chaining

def _chains(entities: list[_Entity], tol: float) -> tuple[list[_Chain], list[tuple[int, str]]]:
    """The entities chained end to end (see the module's docstring); notes (chain index, text) on
    the points where more than two ends meet."""
    from scipy.spatial import cKDTree

    n = len(entities)
    ends = np.array([e.start for e in entities] + [e.end for e in entities])  # j < n: a start; j >= n: an end
    tree = cKDTree(ends)
    closed = [float(np.linalg.norm(e.end - e.start)) <= tol for e in entities]
    used = np.zeros(n, dtype=bool)
    chains, notes = [], []
    for first in range(n):
        if used[first]:
            continue
        used[first] = True
        chain = [entities[first]]
        for forward in (True, False):
            while not closed[first] and float(np.linalg.norm(chain[-1].end - chain[0].start)) > tol:
                here = chain[-1].end if forward else chain[0].start
                hits = [j for j in tree.query_ball_point(here, tol) if not used[j % n] and not closed[j % n]]
                if not hits:
                    break
                j = min(hits, key=lambda j: (float(np.linalg.norm(ends[j] - here)), j % n))
                if len({h % n for h in hits}) > 1:
                    names = ", ".join(f"#{entities[h].handle}" for h in sorted({h % n for h in hits}))
                    notes.append((len(chains), f"at {_shown(here)} the ends of {names} meet; followed "
                                               f"#{entities[j % n].handle} (the nearest, then drawing order)"))
                used[j % n] = True
                entity = entities[j % n]
                if forward:
                    chain.append(entity if j < n else entity.reversed())
                else:
                    chain.insert(0, entity if j >= n else entity.reversed())
        chains.append(_Chain(tuple(chain), float(np.linalg.norm(chain[-1].end - chain[0].start)) <= tol))
    return chains, notes


def _shown(point) -> str:
    """A point for a note: [x, y], or [x, y, z] off the xy plane."""
    coords = point[:2] if len(point) == 3 and point[2] == 0 else point
    return "[" + ", ".join(f"{float(c):.6g}" for c in coords) + "]"


# --------------------------------------------------------------------------- blocks

def _dimension(pieces: list[_Piece]) -> int:
    """2 when every z (points, centres, control points) is 0 (to JOINT_TOL) and every arc turns about ±z."""
    for piece in pieces:
        for arr in (piece.start, piece.end, piece.center, piece.points):
            if arr is not None and np.abs(np.asarray(arr)[..., 2]).max() > JOINT_TOL:
                return 3
        if piece.kind == "arc" and np.abs(piece.normal[:2]).max() > 1e-12:
            return 3
    return 2


def _arc_tol(piece: _Piece) -> float:
    """How far an arc's end may move off its circle (validate_path's radius consistency); 0 for other pieces."""
    return max(ARC_RADIUS_ATOL, ARC_RADIUS_RTOL * piece.radius) if piece.kind == "arc" else 0.0


def _join(a: _Piece, b: _Piece, gaps: list) -> list[_Piece]:
    """[a, b] with b starting exactly where a ends: the end of a line or spline moves onto its
    neighbour's (an arc's only within its radius tolerance), or a short line bridges two arcs."""
    gap = float(np.linalg.norm(b.start - a.end))
    if gap == 0.0:
        return [a, b]
    if gap > JOINT_TOL:
        gaps.append((gap, a, b))
    if b.kind != "arc" or gap <= _arc_tol(b):
        return [a, replace(b, start=a.end.copy())]
    if a.kind != "arc" or gap <= _arc_tol(a):
        return [replace(a, end=b.start.copy()), b]
    return [a, _Piece("bridge", f"a line from {a.label} to {b.label}", a.end, b.start), b]


def _close(pieces: list[_Piece], gaps: list) -> list[_Piece]:
    """A closed chain's last piece ending exactly where its first starts."""
    if len(pieces) > 1:
        last, *bridge, first = _join(pieces[-1], pieces[0], gaps)
        return [first] + pieces[1:-1] + [last] + bridge
    piece = pieces[0]
    gap = float(np.linalg.norm(piece.end - piece.start))
    if gap == 0.0:
        return pieces
    if gap > JOINT_TOL:
        gaps.append((gap, piece, piece))
    if piece.kind != "arc" or gap <= _arc_tol(piece):
        return [replace(piece, end=piece.start.copy())]
    return [piece, _Piece("bridge", f"a line closing {piece.label}", piece.end, piece.start)]


def _blocks(name: str, chains: list[_Chain], tol: float, dim: int, notes: list[str]) -> list:
    """The chains' pieces as blocks, every joint exact, the chains joined by rapid moves."""
    gaps: list = []
    sequence: list = []
    for k, c in enumerate(chains):
        pieces = [p for e in c.entities for p in e.pieces]
        out = [pieces[0]]
        for piece in pieces[1:]:
            out.extend(_join(out.pop(), piece, gaps))
        if c.closed:
            out = _close(out, gaps)
        if sequence:
            gap = float(np.linalg.norm(out[0].start - sequence[-1].end))
            if gap > MIN_BLOCK_LENGTH:
                sequence.append(_Piece("rapid", f"rapid move to chain {k + 1}", sequence[-1].end, out[0].start))
            else:
                out[0] = replace(out[0], start=sequence[-1].end.copy())
        sequence.extend(out)
    if gaps:
        gap, a, b = max(gaps, key=lambda g: g[0])
        notes.append(f"closed {len(gaps)} gap{'s' if len(gaps) > 1 else ''} between entities by moving an end "
                     f"onto its neighbour's (the largest {gap:.3g} mm, from {a.label} to {b.label} at "
                     f"{_shown(a.end[:dim])})")
    bridges = [p for p in sequence if p.kind == "bridge"]
    if bridges:
        notes.append(f"added {len(bridges)} short line{'s' if len(bridges) > 1 else ''} between arcs whose ends "
                     f"are too far apart to move ({bridges[0].label})")
    return [_block(name, piece, dim) for piece in sequence]


def _cut(point: np.ndarray, dim: int) -> np.ndarray:
    return np.array(point[:dim], dtype=float)


def _block(name: str, piece: _Piece, dim: int):
    start, end = _cut(piece.start, dim), _cut(piece.end, dim)
    if piece.kind == "rapid":
        return LineBlock(start, end, rapid=True, source=piece.label)
    if piece.kind in ("line", "bridge"):
        length = float(np.linalg.norm(end - start))
        if length <= MIN_BLOCK_LENGTH:
            raise SpecError(f"{name}: {piece.label}: is {length:.3g} mm long once its end is moved onto its "
                            f"neighbour's: a zero-length block (lines must be longer than {MIN_BLOCK_LENGTH:g} mm)")
        return LineBlock(start, end, source=piece.label)
    if piece.kind == "arc":
        center = _cut(piece.center, dim)
        r0, r1 = float(np.linalg.norm(start - center)), float(np.linalg.norm(end - center))
        allowed = max(ARC_RADIUS_ATOL, ARC_RADIUS_RTOL * r0)
        if abs(r1 - r0) > allowed:  # not reached: the ends are computed from the centre, and moved only within this
            raise SpecError(f"{name}: {piece.label}: its ends are {r0!r} mm and {r1!r} mm from its centre: they "
                            f"differ by more than the {allowed:.3g} mm allowed")
        normal = np.array([0.0, 0.0, math.copysign(1.0, piece.normal[2])]) if dim == 2 else piece.normal.copy()
        return ArcBlock(start, end, center, normal, piece.sweep, source=piece.label)
    points = piece.points.copy()
    points[0], points[-1] = piece.start, piece.end
    curve = CurveSpec(piece.degree, np.ascontiguousarray(points[:, :dim]), piece.weights.copy(), piece.knots.copy())
    return NurbsBlock(curve, source=piece.label)
