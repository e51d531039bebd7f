"""The DXF reader (issue 15, item 2): every entity type against closed forms, OCS, chaining, errors.

Drawings are made here with ezdxf in tmp_path; geometry is checked through the project's own
pipeline (``nurbsinterp.path.Path``: exact NURBS of every block, arc length) against closed
forms, and splines against the naive oracle evaluating the data as the drawing wrote it.
"""
from __future__ import annotations

import importlib.util
import math
from pathlib import Path

import ezdxf
import numpy as np
import pytest
from ezdxf import units

import oracle
from nurbsinterp.config import load_job
from nurbsinterp.config.dxf import DEFAULT_CHAIN_TOLERANCE, dxf_chains, read_dxf_job
from nurbsinterp.config.path import PathSpec
from nurbsinterp.errors import SpecError
from nurbsinterp.path import Path as ToolPath
from test_cli_contract import one_line_error, run_main

ROOT = Path(__file__).resolve().parents[1]
DRAWING = ROOT / "curves" / "drawing.dxf"


def drawing(tmp_path, build, name="t.dxf"):
    """A DXF file made by *build(msp)* (R2010, units mm); returns (its path as str, the entities build returned)."""
    doc = ezdxf.new("R2010")
    doc.units = units.MM
    made = build(doc.modelspace())
    path = tmp_path / name
    doc.saveas(path)
    return str(path), made


def length(spec) -> float:
    return float(ToolPath(spec).block_s[-1])


def joined_exactly(spec) -> bool:
    return all(np.array_equal(a.end, b.start) for a, b in zip(spec.blocks, spec.blocks[1:]))


def fails(call, *parts):
    with pytest.raises(SpecError) as info:
        call()
    text = str(info.value)
    assert "\n" not in text, text
    for part in parts:
        assert str(part) in text, f"{part!r} not in {text!r}"
    return text


# --------------------------------------------------------------------------- entities, against closed forms

def test_line_length(tmp_path):
    name, line = drawing(tmp_path, lambda m: m.add_line((1, 2), (4, 6)))
    spec, profile = read_dxf_job(name)
    assert profile == {}
    assert spec.dim == 2 and len(spec.blocks) == 1 and spec.notes == ()
    block = spec.blocks[0]
    assert block.kind == "line" and not block.rapid
    assert block.source == f"LINE #{line.dxf.handle} on layer 0"
    assert block.start.tolist() == [1.0, 2.0] and block.end.tolist() == [4.0, 6.0]
    assert length(spec) == pytest.approx(5.0, rel=1e-12)


def test_arc_length_is_r_theta(tmp_path):
    name, _ = drawing(tmp_path, lambda m: m.add_arc((3, 4), 7, 30, 250))
    spec, _ = read_dxf_job(name)
    (arc,) = spec.blocks
    sweep = math.radians(220)
    assert arc.kind == "arc" and arc.normal.tolist() == [0.0, 0.0, 1.0]
    assert arc.sweep == pytest.approx(sweep, rel=1e-15)
    assert arc.center.tolist() == [3.0, 4.0] and arc.radius == pytest.approx(7.0, rel=1e-15)
    a = math.radians(250)
    assert np.allclose(arc.end, [3 + 7 * math.cos(a), 4 + 7 * math.sin(a)], rtol=0, atol=1e-12)
    assert length(spec) == pytest.approx(7 * sweep, rel=1e-12)


def test_circle_is_2_pi_r_and_a_closed_chain(tmp_path):
    name, _ = drawing(tmp_path, lambda m: m.add_circle((-2, 5), 4.5))
    spec, _ = read_dxf_job(name)
    (arc,) = spec.blocks
    assert arc.sweep == 2 * math.pi and np.array_equal(arc.start, arc.end)
    assert length(spec) == pytest.approx(2 * math.pi * 4.5, rel=1e-12)
    (chain,) = dxf_chains(name)
    assert chain["closed"] and chain["entities"] == {"CIRCLE": 1}


@pytest.mark.parametrize("bulge", [0.5, -0.5, 1.0, -2.0])
def test_a_bulge_is_an_arc_of_sweep_4_atan_bulge(tmp_path, bulge):
    name, _ = drawing(tmp_path, lambda m: m.add_lwpolyline([(0, 0, bulge), (10, 0, 0), (10, -3, 0)], format="xyb"))
    spec, _ = read_dxf_job(name)
    arc, line = spec.blocks
    sweep = 4 * math.atan(abs(bulge))
    h = 5.0
    r = h * (1 + bulge ** 2) / (2 * abs(bulge))
    assert arc.kind == "arc" and line.kind == "line"
    assert arc.sweep == pytest.approx(sweep, rel=1e-15)
    assert arc.normal.tolist() == [0.0, 0.0, math.copysign(1.0, bulge)]
    # the centre lies left of the chord for a counter-clockwise arc, at h (1 - b²) / (2 b)
    assert np.allclose(arc.center, [5.0, h * (1 - bulge ** 2) / (2 * bulge)], rtol=0, atol=1e-12)
    assert arc.radius == pytest.approx(r, rel=1e-14)
    # the arc's midpoint: the sagitta b·h to the right of the chord (below it, for b > 0)
    path = ToolPath(spec)
    mid = path.programmed.evaluate(path.programmed.parameter_at(np.array([r * sweep / 2])))[0]
    assert np.allclose(mid, [5.0, -bulge * h], rtol=0, atol=1e-9)
    assert length(spec) == pytest.approx(r * sweep + 3.0, rel=1e-12)


def test_spline_against_the_oracle(tmp_path):
    cps = [(0, 0, 0), (10, 20, 0), (30, 25, 0), (45, -5, 0), (60, 10, 0), (70, 0, 0)]
    weights = [1.0, 0.6, 2.0, 1.3, 0.8, 1.0]
    knots = [2.0, 2.0, 2.0, 2.0, 3.5, 6.0, 9.0, 9.0, 9.0, 9.0]

    def build(m):
        spline = m.add_spline()
        spline.dxf.degree = 3
        spline.control_points, spline.weights, spline.knots = cps, weights, knots
        return spline

    name, spline = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name)
    (block,) = spec.blocks
    assert block.kind == "nurbs" and block.curve.degree == 3
    assert block.source == f"SPLINE #{spline.dxf.handle} on layer 0"
    u = np.linspace(2.0, 9.0, 201)
    want = oracle.point(np.array(knots), 3, np.array(cps)[:, :2], np.array(weights), u)
    got = ToolPath(spec).programmed.evaluate(u)
    assert np.abs(got - want).max() <= 1e-12 * 70


def test_the_degree_comes_from_the_counts_not_the_degree_field(tmp_path):
    """ezdxf reports degree 3 for the SPLINEs of R12-style files: the counts are what hold."""

    def build(m):
        spline = m.add_spline()
        spline.dxf.degree = 3  # wrong: 4 control points and 7 knots are degree 2
        spline.control_points = [(0, 0, 0), (1, 2, 0), (3, 2, 0), (4, 0, 0)]
        spline.knots = [0, 0, 0, 0.5, 1, 1, 1]

    name, _ = drawing(tmp_path, build)
    (block,) = read_dxf_job(name)[0].blocks
    assert block.curve.degree == 2


def test_ellipse_is_exact(tmp_path):
    name, _ = drawing(tmp_path, lambda m: m.add_ellipse((1, 2), major_axis=(6, 8), ratio=0.4))
    spec, _ = read_dxf_job(name)
    (block,) = spec.blocks
    assert block.kind == "nurbs" and block.curve.degree == 2
    c = block.curve
    pts = oracle.point(c.knots, 2, c.control_points, c.weights, np.linspace(c.knots[0], c.knots[-1], 97))
    major = np.array([6.0, 8.0]) / 10
    minor = np.array([-8.0, 6.0]) / 10
    x = (pts - [1, 2]) @ major / 10
    y = (pts - [1, 2]) @ minor / 4
    assert np.abs(x ** 2 + y ** 2 - 1).max() <= 1e-12
    assert np.array_equal(block.start, block.end)


def test_polyline_2d_with_bulge_and_3d_polyline(tmp_path):
    def build(m):
        m.add_polyline2d([(0, 0), (10, 0), (10, 10)], format="xy", close=False)
        poly = m.add_polyline2d([(20, 0), (30, 0)], format="xy")
        poly.vertices[0].dxf.bulge = 1.0  # a half circle, r = 5
        m.add_polyline3d([(40, 0, 0), (40, 0, 5), (43, 4, 5)])

    name, _ = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name)
    assert spec.dim == 3
    kinds = [(b.kind, b.rapid) for b in spec.blocks]
    assert kinds == [("line", False), ("line", False), ("line", True), ("arc", False), ("line", True),
                     ("line", False), ("line", False)]
    assert spec.blocks[3].sweep == pytest.approx(math.pi, rel=1e-15)
    feed = sum(float(np.linalg.norm(b.end - b.start)) for b in spec.blocks if b.kind == "line" and not b.rapid)
    assert feed == pytest.approx(20 + 5 + 5, rel=1e-14)


# --------------------------------------------------------------------------- OCS

def test_an_extrusion_of_minus_z_mirrors_arcs(tmp_path):
    def build(m):
        return m.add_arc((10, 5), 3, 0, 90, dxfattribs={"extrusion": (0, 0, -1)})

    name, arc_entity = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name)
    (arc,) = spec.blocks
    assert spec.dim == 2
    assert arc.center.tolist() == [-10.0, 5.0]  # WCS x = -OCS x
    assert arc.normal.tolist() == [0.0, 0.0, -1.0]  # clockwise seen from +z
    assert np.allclose(arc.start, list(arc_entity.start_point)[:2], rtol=0, atol=1e-12)
    assert np.allclose(arc.end, list(arc_entity.end_point)[:2], rtol=0, atol=1e-12)
    assert np.allclose(arc.start, [-13, 5], rtol=0, atol=1e-12) and np.allclose(arc.end, [-10, 8], rtol=0, atol=1e-12)
    path = ToolPath(spec)
    mid = path.programmed.evaluate(path.programmed.parameter_at(np.array([3 * math.pi / 4])))[0]
    c = 3 / math.sqrt(2)
    assert np.allclose(mid, [-10 - c, 5 + c], rtol=0, atol=1e-9)
    assert length(spec) == pytest.approx(3 * math.pi / 2, rel=1e-12)


def test_an_extrusion_of_minus_z_mirrors_polyline_bulges(tmp_path):
    def build(m):
        return m.add_lwpolyline([(0, 0, 0.5), (10, 0, 0)], format="xyb", dxfattribs={"extrusion": (0, 0, -1)})

    name, poly = drawing(tmp_path, build)
    (arc,) = read_dxf_job(name)[0].blocks
    (virtual,) = list(poly.virtual_entities())  # ezdxf's own ARC for the segment, in the same OCS
    ocs = virtual.ocs()
    assert np.allclose(arc.center, list(ocs.to_wcs(virtual.dxf.center))[:2], rtol=0, atol=1e-12)
    assert arc.normal.tolist() == [0.0, 0.0, -1.0]
    assert arc.start.tolist() == [-0.0, 0.0] and arc.end.tolist() == [-10.0, 0.0]


def test_a_tilted_arc_is_3d(tmp_path):
    normal = np.array([0.0, 0.6, 0.8])
    name, arc_entity = drawing(tmp_path, lambda m: m.add_arc((1, 2, 3), 5, 10, 100, dxfattribs={"extrusion": normal}))
    spec, _ = read_dxf_job(name)
    (arc,) = spec.blocks
    assert spec.dim == 3
    assert np.allclose(arc.normal, normal, rtol=0, atol=1e-15)
    assert np.allclose(arc.start, list(arc_entity.start_point), rtol=0, atol=1e-12)
    assert np.allclose(arc.end, list(arc_entity.end_point), rtol=0, atol=1e-12)
    assert length(spec) == pytest.approx(5 * math.pi / 2, rel=1e-12)


# --------------------------------------------------------------------------- chaining

SPLINE_CPS = [(10, 10, 0), (6, 14, 0), (2, 12, 0), (0, 10, 0)]
SPLINE_W = [1.0, 0.5, 1.5, 1.0]
SPLINE_U = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0]


def _square_with_reversed_entities(m):
    """A closed outline, three of its four entities drawn against the path's direction.

    The path keeps the first entity's direction: (10,0) -> (0,0) -> (0,10) -> spline -> (10,10) -> (10,0)."""
    a = m.add_line((10, 0), (0, 0))
    b = m.add_line((0, 10), (0, 0))  # reversed in the path
    spline = m.add_spline()  # drawn (10,10) -> (0,10): reversed in the path
    spline.dxf.degree = 3
    spline.control_points, spline.weights, spline.knots = SPLINE_CPS, SPLINE_W, SPLINE_U
    c = m.add_line((10, 0), (10, 10))  # reversed in the path
    return a, b, spline, c


def test_reversed_entities_chain_into_one_closed_path(tmp_path):
    name, (a, b, spline, c) = drawing(tmp_path, _square_with_reversed_entities)
    spec, _ = read_dxf_job(name)
    assert joined_exactly(spec) and np.array_equal(spec.blocks[-1].end, spec.blocks[0].start)
    assert [blk.source.split(" ")[1] for blk in spec.blocks] == [f"#{e.dxf.handle}" for e in (a, b, spline, c)]
    assert [blk.start.tolist() for blk in spec.blocks] == [[10, 0], [0, 0], [0, 10], [10, 10]]
    curve = spec.blocks[2].curve
    assert curve.control_points.tolist() == [list(p[:2]) for p in SPLINE_CPS[::-1]]
    assert curve.weights.tolist() == SPLINE_W[::-1] and curve.knots.tolist() == SPLINE_U
    assert length(spec) == pytest.approx(30 + length(PathSpec((spec.blocks[2],), 2)), rel=1e-12)
    (chain,) = dxf_chains(name)
    assert chain["closed"] and chain["handles"] == [e.dxf.handle for e in (a, b, spline, c)]
    assert chain["entities"] == {"LINE": 3, "SPLINE": 1}


def test_a_reversed_spline_is_the_same_curve_backwards(tmp_path):
    def build(m):
        m.add_line((20, 10), (10, 10))  # drawn first: the chain runs (20,10) -> (10,10) -> spline -> (0,10)
        spline = m.add_spline()
        spline.dxf.degree = 3
        spline.control_points, spline.weights, spline.knots = SPLINE_CPS[::-1], SPLINE_W[::-1], [0, 0, 0, 0, 3, 3, 3, 3]

    name, _ = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name)
    line, curve = spec.blocks[0], spec.blocks[1].curve
    assert np.array_equal(line.end, curve.control_points[0])
    assert curve.knots.tolist() == [0, 0, 0, 0, 3, 3, 3, 3]
    u = np.linspace(0, 3, 51)
    forward = oracle.point(np.array([0, 0, 0, 0, 3, 3, 3, 3.0]), 3, np.array(SPLINE_CPS[::-1])[:, :2],
                           np.array(SPLINE_W[::-1]), u)
    backward = oracle.point(curve.knots, 3, curve.control_points, curve.weights, 3 - u)
    assert np.abs(forward - backward).max() <= 1e-12 * 10


def test_a_gap_within_the_tolerance_is_closed_and_noted(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_line((0, 0), (10, 0)), m.add_line((10 + 4e-4, 0), (20, 0)),
                                           m.add_arc((20, 5), 5, -90, 0)))
    spec, _ = read_dxf_job(name)
    assert len(spec.blocks) == 3 and joined_exactly(spec) and not spec.has_rapids
    assert spec.blocks[1].start.tolist() == [10.0, 0.0]  # the line's end moved onto its neighbour's
    assert any("closed 1 gap" in n and "0.0004 mm" in n for n in spec.notes), spec.notes


def test_a_gap_beyond_the_tolerance_splits_the_chains_joined_by_a_rapid(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_line((0, 0), (10, 0)), m.add_line((10 + 4e-4, 0), (20, 0))))
    spec, _ = read_dxf_job(name, chain_tolerance=1e-4)
    first, rapid, second = spec.blocks
    assert rapid.rapid and rapid.kind == "line" and joined_exactly(spec)
    assert rapid.start.tolist() == [10.0, 0.0] and rapid.end.tolist() == [10 + 4e-4, 0.0]
    assert any("2 chains" in n and "rapid" in n for n in spec.notes), spec.notes
    assert len(dxf_chains(name, chain_tolerance="0.1 um")) == 2
    assert len(dxf_chains(name)) == 1 and DEFAULT_CHAIN_TOLERANCE > 4e-4


def test_two_arcs_too_far_apart_to_move_get_a_short_line(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_arc((0, 0), 5, 0, 90), m.add_arc((0, 10.001), 5, 180, 270)))
    spec, _ = read_dxf_job(name)
    assert [b.kind for b in spec.blocks] == ["arc", "line", "arc"] and joined_exactly(spec)
    assert float(np.linalg.norm(spec.blocks[1].end - spec.blocks[1].start)) == pytest.approx(1e-3, rel=1e-9)
    assert any("short line" in n for n in spec.notes), spec.notes


def test_layer_selection(tmp_path):
    def build(m):
        m.add_line((0, 0), (1, 0), dxfattribs={"layer": "CUT"})
        m.add_circle((5, 5), 1, dxfattribs={"layer": "DRILL"})
        m.add_text("x", dxfattribs={"layer": "NOTES"})

    name, _ = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name, layer="DRILL")
    assert [b.kind for b in spec.blocks] == ["arc"] and spec.notes == ()
    assert read_dxf_job(name, layer="cut")[0].blocks[0].source.endswith("on layer CUT")  # as CAD: any case
    assert dxf_chains(name, layer="CUT")[0]["layers"] == ["CUT"]
    fails(lambda: read_dxf_job(name, layer="MILL"), f"{name}: layer 'MILL' has no entities",
          "CUT (1)", "DRILL (1)", "NOTES (1)")
    fails(lambda: read_dxf_job(name, layer="NOTES"), f"{name}: has no toolpath entities on layer NOTES", "1 TEXT")


def test_chain_selection(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_line((0, 0), (1, 0)), m.add_circle((5, 5), 1),
                                           m.add_line((9, 0), (9, 3))))
    chains = dxf_chains(name)
    assert [c["chain"] for c in chains] == [1, 2, 3] and [c["closed"] for c in chains] == [False, True, False]
    assert chains[2]["start"] == [9.0, 0.0] and chains[2]["end"] == [9.0, 3.0]
    spec, _ = read_dxf_job(name, chain=2)
    assert [b.kind for b in spec.blocks] == ["arc"]
    everything, _ = read_dxf_job(name)
    assert [b.rapid for b in everything.blocks] == [False, True, False, True, False]
    fails(lambda: read_dxf_job(name, chain=4), f"{name}: chain = 4 does not exist: the drawing has 3 chains")
    fails(lambda: read_dxf_job(name, chain=0), f"{name}: chain = 0 must be >= 1")


def test_load_job_passes_the_options_and_other_readers_options_are_ignored(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_line((0, 0), (1, 0)), m.add_circle((5, 5), 1)))
    job = load_job(name, reader_options={"chain": 2, "layer": None, "start": [1, 2]})
    assert [b.kind for b in job.path.blocks] == ["arc"]
    assert read_dxf_job(name, start=[1, 2], chain=1)[0].blocks[0].kind == "line"


# --------------------------------------------------------------------------- splines: periodic, fit points

@pytest.mark.parametrize("rational", [False, True])
def test_a_closed_periodic_spline_is_clamped_exactly(tmp_path, rational):
    rng = np.random.default_rng(15)
    ring = [(20 * math.cos(t) + rng.uniform(-3, 3), 20 * math.sin(t) + rng.uniform(-3, 3), 0.0)
            for t in np.linspace(0, 2 * math.pi, 9)[:-1]]
    weights = rng.uniform(0.5, 2.0, 8) if rational else None

    def build(m):
        spline = m.add_spline()
        spline.set_closed(ring, degree=3)  # wraps the first 3 points, unclamped uniform knots
        if rational:
            spline.weights = list(weights) + list(weights[:3])
        return spline

    name, spline = drawing(tmp_path, build)
    knots = np.array(spline.knots)
    assert knots[0] != knots[3]  # really unclamped
    spec, _ = read_dxf_job(name)
    (block,) = spec.blocks
    c = block.curve
    assert c.knots[0] == knots[3] and c.knots[-1] == knots[-4]
    assert np.array_equal(block.start, block.end)  # closed, exactly
    u = np.linspace(knots[3], knots[-4], 301)
    w = np.array(spline.weights) if rational else np.ones(len(ring) + 3)
    want = oracle.point(knots, 3, np.array(spline.control_points)[:, :2], w, u)
    got = oracle.point(c.knots, 3, c.control_points, c.weights, u)
    assert np.abs(got - want).max() <= 1e-12 * 25
    assert dxf_chains(name)[0]["closed"]


def test_a_fit_point_spline_is_fitted_through_its_points(tmp_path):
    fit = [(0, 0, 0), (10, 5, 0), (20, -3, 0), (32, 4, 0), (40, 0, 0)]
    name, spline = drawing(tmp_path, lambda m: m.add_spline(fit))
    assert spline.control_point_count() == 0
    spec, _ = read_dxf_job(name)
    (block,) = spec.blocks
    c = block.curve
    assert c.degree == 3
    # natural ends: the fit points sit at the interior knots (chord-length parameters)
    params = np.unique(c.knots)
    assert len(params) == len(fit)
    pts = oracle.point(c.knots, 3, c.control_points, c.weights, params)
    assert np.abs(pts - np.array(fit)[:, :2]).max() <= 1e-9
    assert any(f"SPLINE #{spline.dxf.handle} on layer 0: defined by 5 fit points only" in n for n in spec.notes)


# --------------------------------------------------------------------------- errors: one line, naming the entity

def _spline(m, cps, knots, weights=(), layer="CUT"):
    spline = m.add_spline(dxfattribs={"layer": layer})
    spline.dxf.degree = 3
    spline.control_points, spline.knots, spline.weights = cps, knots, list(weights)
    return spline


FOUR = [(0, 0, 0), (1, 1, 0), (2, 1, 0), (3, 0, 0)]


@pytest.mark.parametrize("case, knots, weights, expected", [
    ("weight", [0, 0, 0, 0, 1, 1, 1, 1], [1, 1, -2, 1], "weights[2] = -2.0 must be > 0"),
    ("knots", [0, 0, 0, 0, 1, 1, 0.5, 1], [], "knots[6] = 0.5 is smaller than knots[5] = 1.0"),
    ("periodic", [0, 1, 2, 3, 4], [], "degree = knots - control points - 1 = 0"),
    ("count", [0, 0, 0, 0, 1, 1, 1, 1], [1, 1], "has 2 weights for 4 control points"),
    ("empty", [0, 0, 0, 0, 0, 0, 0, 0], [], "its knot domain [knots[3], knots[4]] = [0.0, 0.0] is empty"),
], ids=lambda v: v if isinstance(v, str) and " " not in v else "")
def test_a_bad_spline_is_named_by_handle_and_layer(tmp_path, case, knots, weights, expected):
    name, spline = drawing(tmp_path, lambda m: _spline(m, FOUR, knots, weights))
    fails(lambda: read_dxf_job(name), f"{name}: SPLINE #{spline.dxf.handle} on layer CUT: ", expected)


def test_a_spline_the_curve_rules_refuse_is_named_too(tmp_path):
    cps = FOUR + [(4, 1, 0), (5, 1, 0), (6, 0, 0), (7, 1, 0)]
    name, spline = drawing(tmp_path, lambda m: _spline(m, cps, [0, 0, 0, 0, .5, .5, .5, .5, 1, 1, 1, 1]))
    fails(lambda: read_dxf_job(name), f"{name}: SPLINE #{spline.dxf.handle} on layer CUT: spline.knots[",
          "multiplicity 4")


def test_a_closed_fit_point_spline_is_refused(tmp_path):
    def build(m):
        spline = m.add_spline([(0, 0), (10, 5), (20, 0), (10, -5)], dxfattribs={"layer": "CUT"})
        spline.closed = True
        return spline

    name, spline = drawing(tmp_path, build)
    fails(lambda: read_dxf_job(name), f"{name}: SPLINE #{spline.dxf.handle} on layer CUT: is closed and defined by "
          "4 fit points only")


def test_a_zero_radius_arc_is_named(tmp_path):
    name, arc = drawing(tmp_path, lambda m: m.add_arc((0, 0), 0, 0, 90, dxfattribs={"layer": "CUT"}))
    fails(lambda: read_dxf_job(name), f"{name}: ARC #{arc.dxf.handle} on layer CUT: radius = 0.0 mm must be > 0")


def test_what_is_no_toolpath_is_listed_once(tmp_path):
    def build(m):
        m.doc.blocks.new("B").add_line((0, 0), (1, 1))
        m.add_line((0, 0), (5, 0))
        m.add_text("a")
        m.add_text("b")
        m.add_point((3, 3))
        m.add_blockref("B", (7, 7))

    name, _ = drawing(tmp_path, build)
    spec, _ = read_dxf_job(name)
    assert spec.notes == ("ignored (not toolpath geometry): 1 INSERT, 1 POINT, 2 TEXT",)
    assert len(spec.blocks) == 1


def test_zero_length_elements_are_skipped_with_a_note(tmp_path):
    name, _ = drawing(tmp_path, lambda m: (m.add_line((0, 0), (0, 0)),
                                           m.add_lwpolyline([(0, 0), (4, 0), (4, 0), (4, 4)])))
    spec, _ = read_dxf_job(name)
    assert [b.kind for b in spec.blocks] == ["line", "line"] and joined_exactly(spec)
    assert any(n.startswith("skipped 2 zero-length elements: LINE #") and "(segment 2)" in n for n in spec.notes)


def test_the_drawing_level_errors(tmp_path):
    empty_doc, _ = drawing(tmp_path, lambda m: None, "empty.dxf")
    fails(lambda: read_dxf_job(empty_doc), f"{empty_doc}: the drawing's model space is empty")
    text_only, _ = drawing(tmp_path, lambda m: m.add_text("hello"), "text.dxf")
    fails(lambda: read_dxf_job(text_only), f"{text_only}: has no toolpath entities", "it has only 1 TEXT")
    (tmp_path / "zero.dxf").write_bytes(b"")
    fails(lambda: read_dxf_job(str(tmp_path / "zero.dxf")), "zero.dxf: the file is empty")
    (tmp_path / "yaml.dxf").write_text("curve: {degree: 2}\n")
    fails(lambda: read_dxf_job(str(tmp_path / "yaml.dxf")), "yaml.dxf: is not a DXF file")
    good = Path(drawing(tmp_path, lambda m: m.add_line((0, 0), (1, 0)), "good.dxf")[0]).read_bytes()
    (tmp_path / "cut.dxf").write_bytes(good[: len(good) // 3])
    fails(lambda: read_dxf_job(str(tmp_path / "cut.dxf")), "cut.dxf: is not a readable DXF file")
    fails(lambda: read_dxf_job(str(tmp_path / "missing.dxf")), "missing.dxf: cannot read: No such file")
    fails(lambda: read_dxf_job(str(tmp_path)), "is a directory")
    fails(lambda: read_dxf_job(text_only, chain_tolerance=0), "chain_tolerance = 0", "below 1e-09 mm")
    fails(lambda: read_dxf_job(text_only, chain_tolerance="wide"), "chain_tolerance = 'wide' is not a number")


# --------------------------------------------------------------------------- the example drawing and the CLI

def test_make_drawing_reproduces_the_stored_drawing(tmp_path):
    spec_ = importlib.util.spec_from_file_location("make_drawing", ROOT / "curves" / "make_drawing.py")
    module = importlib.util.module_from_spec(spec_)
    spec_.loader.exec_module(module)
    module.make(tmp_path / "d.dxf")
    made, stored = read_dxf_job(str(tmp_path / "d.dxf"))[0], read_dxf_job(str(DRAWING))[0]
    assert made.fingerprint == stored.fingerprint and made.notes == stored.notes
    assert [b.source for b in made.blocks] == [b.source for b in stored.blocks]


def test_the_example_drawing(tmp_path):
    spec, _ = read_dxf_job(str(DRAWING))
    assert [b.kind for b in spec.blocks] == ["line", "arc", "line", "arc", "line", "nurbs"]
    assert joined_exactly(spec) and np.array_equal(spec.blocks[-1].end, spec.blocks[0].start)
    assert spec.notes == ("ignored (not toolpath geometry): 1 TEXT",)
    assert not np.all(spec.blocks[-1].curve.weights == 1.0)
    s = ToolPath(spec).block_s
    assert np.allclose(np.diff(s)[:5], [80, 15 * math.pi, 25, 10 * math.pi, 15], rtol=1e-12, atol=0)
    (chain,) = dxf_chains(str(DRAWING), layer="CUT")
    assert chain["closed"] and chain["entities"] == {"LINE": 1, "ARC": 1, "LWPOLYLINE": 1, "SPLINE": 1}


def test_cli_info_and_plan_end_to_end(capsys, tmp_path):
    code, out, err = run_main(capsys, "info", DRAWING, "--layer", "CUT")
    assert code == 0 and "6 blocks" in out, err
    code, out, err = run_main(capsys, "plan", DRAWING, "-q", "-o", tmp_path / "p.csv")
    assert code == 0, err
    rows = (tmp_path / "p.csv").read_text().splitlines()
    assert len(rows) > 100
    code, out, err = run_main(capsys, "info", DRAWING, "--chain", "2")
    one_line_error(code, out, err, f"{DRAWING}: chain = 2 does not exist")
    (tmp_path / "bad.dxf").write_text("not a drawing\n")
    code, out, err = run_main(capsys, "plan", tmp_path / "bad.dxf", "-o", tmp_path / "q.csv")
    one_line_error(code, out, err, "bad.dxf: is not a DXF file")
    assert not (tmp_path / "q.csv").exists()
