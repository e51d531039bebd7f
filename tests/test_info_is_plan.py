"""`info` is `plan` without the ticks (issue 47, item 5): for random jobs and options, the tick count and the motion
time `info --json` states are those of the stream `plan` writes -- acc/dec after interpolation included, whose
filter ends the stream where it has settled (info said the interpolation's own time before: 3.600 s for the square
whose stream ends at 3.299 s, 3.6416 s for the circle's exponential filter whose stream runs to 5.18 s).  A job both
refuse is refused by both in the same words.

The reference is the stream itself, read back from the file `plan` wrote: its rows and its last t."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from budgets import budgets
from clirun import in_process, read_trace

ROOT = Path(__file__).resolve().parent.parent
JOBS = ["circle.yaml", "square.yaml", "rounded-square.yaml", "butterfly.yaml", "quintic-wave.yaml", "path-3d.yaml",
        "tilted-circle-3d.yaml", "pocket.yaml", "pocket.ngc", "drawing.dxf"]


@st.composite
def runs(draw):
    job = draw(st.sampled_from(JOBS))
    options = ["--profile-type", draw(st.sampled_from(["trapezoidal", "bell", "exponential", "adaptive"])),
               "--interpolator", draw(st.sampled_from(["taylor1", "taylor2", "rk4", "exact"])),
               "--period", draw(st.sampled_from(["0.5ms", "1ms", "2ms"]))]
    if draw(st.booleans()):
        options += ["--accdec", "after"]
    if draw(st.booleans()):
        options += ["--tolerance", draw(st.sampled_from(["0", "5um", "50um"]))]
    if draw(st.booleans()):
        options += ["--accel-time", draw(st.sampled_from(["0.05", "0.2"]))]
    if draw(st.booleans()):
        options += ["--max-accel", "800"]
    return job, options


@budgets(quick=12, full=120)
def test_info_states_the_stream_plan_writes(budget, tmp_path):
    @settings(max_examples=budget, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(run=runs())
    def check(run):
        job, options = run
        path = ROOT / "curves" / job
        out = tmp_path / "stream.csv"
        out.unlink(missing_ok=True)
        planned, _, plan_err = in_process(["plan", path, *options, "-o", out])
        told, info_out, info_err = in_process(["info", path, *options, "--json"])
        if planned != 0:  # refused (an option the job cannot take): info refuses it in the same words
            assert told == planned == 2, (plan_err, info_err)
            assert plan_err.strip().splitlines()[-1] == info_err.strip().splitlines()[-1], (plan_err, info_err)
            return
        assert told == 0, info_err
        facts = json.loads(info_out)
        columns, stream = read_trace(out)
        period = float(facts["period"])
        last_t = float(stream[-1, columns.index("t")])
        assert facts["ticks"] == stream.shape[0], (run, facts["ticks"], stream.shape[0])
        # the last tick is the first at or after the motion's end (a plan's duration need not be whole periods)
        assert last_t - period < facts["motion_time"] <= last_t + 1e-9 * max(1.0, last_t), \
            (run, facts["motion_time"], last_t)
        assert np.all(np.isfinite(stream))

    check()
