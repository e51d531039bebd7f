"""Opt-in: the DXF files of the shared corpus (/work/shared/corpus/dxf_*), read where they lie.

Skipped when the corpus is absent.  Every drawing reads (all chains, and each chain alone), and
`info` and `plan` succeed on it through the CLI; the rational quadratic circles and arc of
arcs-as-splines.dxf (an R12-style file: ezdxf reports degree 3, the counts say 2) come out with
the radii PROVENANCE.md records.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import oracle
from nurbsinterp.config.dxf import dxf_chains, read_dxf_job
from test_cli_contract import run_main

CORPUS = Path(__file__).resolve().parents[2] / "shared" / "corpus"
FILES = sorted(CORPUS.glob("dxf_*/**/*.dxf")) if CORPUS.is_dir() else []
needs_corpus = pytest.mark.skipif(not FILES, reason=f"no DXF corpus at {CORPUS}")


def _id(path: Path) -> str:
    return f"{path.parent.name}/{path.name}"


@needs_corpus
@pytest.mark.parametrize("path", FILES, ids=_id)
def test_every_drawing_and_every_chain_reads(path):
    spec, profile = read_dxf_job(str(path))
    assert profile == {} and spec.dim == 2
    assert all(np.array_equal(a.end, b.start) for a, b in zip(spec.blocks, spec.blocks[1:]))
    chains = dxf_chains(str(path))
    assert [c["chain"] for c in chains] == list(range(1, len(chains) + 1))
    assert sum(not b.rapid for b in spec.blocks) == sum(len(read_dxf_job(str(path), chain=c["chain"])[0].blocks)
                                                        for c in chains)


@needs_corpus
@pytest.mark.parametrize("path", FILES, ids=_id)
def test_info_and_plan_succeed(capsys, tmp_path, path):
    code, out, err = run_main(capsys, "info", path, "--json")
    assert code == 0, err
    assert '"chains"' in out
    code, out, err = run_main(capsys, "plan", path, "-q", "--period", "10 ms", "-o", tmp_path / "p.csv")
    assert code == 0, err
    assert (tmp_path / "p.csv").stat().st_size > 0


def _circle_fit(points):
    """Centre and radii of the points (least squares on |p|² = 2 c·p + k)."""
    A = np.column_stack([2 * points, np.ones(len(points))])
    centre = np.linalg.lstsq(A, (points ** 2).sum(axis=1), rcond=None)[0][:2]
    return centre, np.linalg.norm(points - centre, axis=1)


@needs_corpus
@pytest.mark.parametrize("chain, radius, closed", [(1, 32.320196, True), (2, 7.345499, True), (3, 146.909982, False)])
def test_rational_quadratic_circles_and_arc_keep_their_radii(chain, radius, closed):
    path = CORPUS / "dxf_gdsestimating_dxf-parser" / "arcs-as-splines.dxf"
    if not path.exists():
        pytest.skip(f"{path} is not in the corpus")
    spec, _ = read_dxf_job(str(path), chain=chain)
    (block,) = spec.blocks
    c = block.curve
    assert c.degree == 2 and not np.all(c.weights == 1.0)
    points = oracle.point(c.knots, 2, c.control_points, c.weights, np.linspace(c.knots[0], c.knots[-1], 401))
    _, radii = _circle_fit(points)
    assert np.abs(radii - radius).max() <= 1e-6
    assert np.array_equal(block.start, block.end) == closed
    assert dxf_chains(str(path))[chain - 1]["closed"] == closed
