"""Conformance on programs nobody here wrote: LinuxCNC's own G5.2 and G6.2 samples (opt-in).

The samples live in ``../shared/corpus/linuxcnc-nurbs`` beside the checkout (their licence,
GPL-2, is not the project's: they are read from there, never copied).  Every program must
read, `info` and `plan` without error, except ``Curva_Stella_Q1_G5.ngc``, whose line 12
holds the invalid ``G2.2``.  The first NURBS of ``Curva_Stella_Q1.ngc`` is checked point by
point against an evaluation of the numbers as the file writes them, by the naive oracle.
"""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import oracle
from clirun import without_end_mark
from test_cli_contract import one_line_error, run_main

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus" / "linuxcnc-nurbs"
pytestmark = pytest.mark.skipif(not CORPUS.is_dir(), reason=f"the external corpus is absent ({CORPUS})")
INVALID = "Curva_Stella_Q1_G5.ngc"
PROGRAMS = sorted(CORPUS.glob("G[56]/*.ngc")) if CORPUS.is_dir() else []


def test_the_corpus_is_there():
    assert len([p for p in PROGRAMS if p.parent.name == "G6"]) == 40
    assert len([p for p in PROGRAMS if p.parent.name == "G5"]) == 15


def _variants_slow(programs):
    """The programs, each drawing's finer variants (_Q2, _Q3 beside its _Q1: the same shape in more control points)
    in the slow set: the quick set reads, describes and plans every drawing once."""
    names = {p.name for p in programs}
    return [pytest.param(p, marks=pytest.mark.slow)
            if re.search(r"_Q[23]", p.name) and re.sub(r"_Q[23]", "_Q1", p.name) in names else p for p in programs]


@pytest.mark.parametrize("program", _variants_slow([p for p in PROGRAMS if p.name != INVALID]), ids=lambda p: p.name)
def test_every_program_reads_describes_and_plans(capsys, tmp_path, program):
    from nurbsinterp.config import load_job

    job = load_job(program)
    kinds = {b.kind for b in job.path.blocks}
    assert "nurbs" in kinds  # each sample holds at least one NURBS block
    code, out, err = run_main(capsys, "info", program, "--json")
    assert code == 0, err
    out_file = tmp_path / "p.bin"
    code, out, err = run_main(capsys, "plan", program, "--format", "bin", "-q", "-o", out_file)
    assert code == 0, err
    assert out == ""
    head, _, body = without_end_mark(out_file.read_bytes()).partition(b"\n")
    columns = head.split()[2].split(b",")
    data = np.frombuffer(body, "<f8").reshape(-1, len(columns))
    assert np.isfinite(data).all()
    # the stream ends where the program ends (a program's stream has x, y and z whatever its moves)
    axes = [columns.index(a) for a in (b"x", b"y", b"z") if a in columns]
    end = np.zeros(len(axes))
    end[:len(job.path.blocks[-1].end)] = job.path.blocks[-1].end
    assert np.allclose(data[-1, axes], end, rtol=0, atol=1e-9)


def test_the_invalid_g2_2_is_refused_naming_line_12(capsys, tmp_path):
    program = CORPUS / "G5" / INVALID
    out_file = tmp_path / "p.csv"
    code, out, err = run_main(capsys, "plan", program, "-o", out_file)
    one_line_error(code, out, err, f"{program}:12:", "G2.2")
    assert not out_file.exists()


def _first_g6_block(text: str):
    """The first G6.2 block as the file writes it: control points, weights, knots and order (parsed here)."""
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip().startswith("G6.2"))
    order = int(re.search(r"P(\d+)", lines[start]).group(1))
    points, weights, knots, closing = [], [], [], 0
    for line in lines[start:]:
        words = dict(re.findall(r"([XYRK])([-+]?\d*\.?\d+)", line.split(";")[0]))
        if "X" in words:
            points.append([float(words["X"]), float(words["Y"])])
            weights.append(float(words["R"]))
            knots.append(float(words["K"]))
        elif "K" in words:
            knots.append(float(words["K"]))
            closing += 1
            if closing == order:
                break
    return order, np.array(points), np.array(weights), np.array(knots)


def test_curva_stella_first_block_point_by_point():
    from nurbsinterp.config import load_job
    from nurbsinterp.nurbs import NurbsCurve

    program = CORPUS / "G6" / "Curva_Stella_Q1.ngc"
    order, V, W, U = _first_g6_block(program.read_text())
    assert (order, len(V), len(U)) == (3, 16, 19)
    block = next(b for b in load_job(program).path.blocks if b.kind == "nurbs")
    c = block.curve
    assert c.degree == order - 1
    assert np.array_equal(c.weights, W) and np.array_equal(c.knots, U)
    assert np.array_equal(c.control_points[:, :2], V)  # x, y exactly as written; z the tool's height there
    assert np.all(c.control_points[:, 2] == -1.0)
    curve = NurbsCurve.from_spec(c)
    us = np.linspace(U[0], U[-1], 2001)
    ours = curve.evaluate(us)[:, :2]
    theirs = np.array([oracle.point(U, order - 1, V, W, u) for u in us])
    assert np.abs(ours - theirs).max() <= 1e-9


@pytest.mark.parametrize("program", [p for p in PROGRAMS if p.name != INVALID], ids=lambda p: p.name)
def test_every_program_plans_with_look_ahead(program):
    """Every sample planned with look-ahead within 5 um (its NURBS blocks as cubic rows: motion.nurbs_blocks), the
    per-axis limits held by the stream's finite differences, ending where the program ends."""
    from test_lookahead import check_limits, planned

    from nurbsinterp.config import load_job

    run, rows = planned(str(program), tol=0.005)
    assert run.facts.nurbs >= 1
    assert np.isfinite(rows).all()
    check_limits(run, rows)
    end = load_job(program).path.blocks[-1].end
    assert np.allclose(rows[-1, 4:4 + end.shape[0]], end, rtol=0, atol=1e-9)
