"""The look-ahead reads a G-code program as it plans it (config.gcode.ProgramStream): the same stream as the
program read whole, to the bit, whatever the pieces the file is read in and the batches the planner takes;
its memory does not grow with the program's length."""
from __future__ import annotations

import gc
import tracemalloc

import numpy as np
import pytest
from test_lookahead import LIMITS, TOL, planned, program, random_program

from nurbsinterp.cli.common import load
from nurbsinterp.motion import smooth
from nurbsinterp.motion.pipeline import LookAhead


def streamed(path, tol=TOL, batch=4096, piece_bytes=None, **options):
    """(the run, every row of its stream), the program read as it is planned."""
    job = load(path, stream=True, **{**LIMITS, **options})
    if piece_bytes is not None:
        job.path.piece_bytes = piece_bytes
    run = LookAhead(job, tol, batch=batch)
    return run, np.concatenate(list(run.chunks()))


def three_d(run, rows):
    """A whole path's rows with z (0 where the path is flat) and the rapid column, as a stream has them."""
    if run.dim == 3 and run.rapid:
        return rows
    k = 4 + run.dim
    z = rows[:, k:k] if run.dim == 3 else np.zeros((rows.shape[0], 1))
    rapid = rows[:, -1:] if run.rapid else np.zeros((rows.shape[0], 1))
    body = rows[:, :-1] if run.rapid else rows
    return np.hstack([body[:, :k], z if run.dim == 2 else np.empty((rows.shape[0], 0)), body[:, k:], rapid])


@pytest.mark.parametrize("kind", ["noisy", "corners", "reversals", "micro", "mixed"])
@pytest.mark.parametrize("batch, piece", [(4096, None), (3, 40), (17, 1)])
def test_a_streamed_program_plans_as_the_whole_path(tmp_path, kind, batch, piece):
    path = program(tmp_path, random_program(np.random.default_rng(7), kind, n=150))
    whole_run, whole = planned(path)
    run, rows = streamed(path, batch=batch, piece_bytes=piece)
    assert run.columns[4:7] == ["x", "y", "z"] and run.columns[-1] == "rapid"
    assert np.array_equal(three_d(whole_run, whole), rows)
    assert run.facts.blocks == whole_run.facts.blocks and run.facts.segments == whole_run.facts.segments


def test_stops_dwells_and_dropped_moves_in_runs_cut_by_batches(tmp_path):
    """M0 and G4 inside long runs of plain lines, zero-length moves, batches cutting the runs (their stop stays
    with their first move)."""
    moves = "".join(f"G1 X{k % 9 * 0.7:.3f} Y{k // 9 * 0.4:.3f}\n" for k in range(60))
    again = "".join(f"G1 X{k % 5 * 0.9:.3f} Y{3 + k // 5 * 0.3:.3f} Z-0.5\n" for k in range(60))
    path = program(tmp_path, "G21 G90 G64 F1200\n" + moves + "M0\n" + again + "G4 P0.25\nG1 X0 Y0\nG1 X0 Y0\n"
                   + moves + "M2\n")
    whole_run, whole = planned(path)
    for batch in (4, 7, 4096):
        run, rows = streamed(path, batch=batch, piece_bytes=64)
        assert np.array_equal(three_d(whole_run, whole), rows), batch
    assert run.facts.stops == whole_run.facts.stops >= 2


PIECE = 16 * 1024


def _peak(path, **options):
    gc.collect()
    tracemalloc.start()
    try:
        job = load(path, stream=True, **{**LIMITS, **options})
        job.path.piece_bytes = PIECE
        run = LookAhead(job, TOL)
        for _ in run.chunks():
            pass
        return tracemalloc.get_traced_memory()[1], run
    finally:
        tracemalloc.stop()


def test_memory_does_not_grow_with_the_program(tmp_path):
    """Planning 80 000 moves holds no more than planning 12 000 (the Python and numpy allocations traced): the
    program is read a piece at a time (16 kB here, so that both programs span many: a piece of the default
    megabyte holds some 10 MB of lines read), smoothed and planned a window at a time, its ticks handed on a
    chunk at a time.  Held whole, the 68 000 moves more would cost some 70 MB (a block ~ 1 kB)."""
    def raster(rows):
        lines = ["G21 G90 G64 F3000", "G0 X0 Y0 Z1", "G1 Z0"]
        for r in range(rows):
            xs = range(200) if r % 2 == 0 else range(199, -1, -1)
            lines += [f"G1 X{x * 0.2:.3f} Y{r * 0.5:.3f}" for x in xs]
        return "\n".join(lines + ["M2"]) + "\n"

    small = program(tmp_path, raster(60), "small.ngc")
    large = program(tmp_path, raster(400), "large.ngc")
    _peak(small)  # the first run's one-off allocations (imports, kernels loaded) out of the way
    peak_small, run_small = _peak(small)
    peak_large, run_large = _peak(large)
    assert run_large.facts.blocks > 6 * run_small.facts.blocks
    assert run_small.smoothing.moves > smooth.WINDOW  # both beyond the smoothing stage's window
    assert peak_large - peak_small < 8 * 2 ** 20, (peak_small, peak_large)
