"""identify on a loop whose controller sees the position late (issue 49, defect 9).

A drive or fieldbus that reports the position 2 ticks late makes a loop the servo model cannot hold.  Its capture
used to leave a residual far above the noise while the report said "limited by noise".  Now the residual is
weighed against the noise in it (its tick-to-tick scatter): the report says the model family, and what explains
the capture -- a controller that sees the position 2 ticks late -- on stderr, in the JSON and in the file written.

The capture is made here by an independent loop (scipy.signal.cont2discrete's ZOH sample of the paper's plants,
a per-tick Python loop with a delay line), printed as halsampler prints it.
"""
from __future__ import annotations

import io
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.config import load_job
from nurbsinterp.interpolate import Interpolation
from nurbsinterp.path import job_path
from nurbsinterp.servo import load_servo
from clirun import run_main

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
PAPER = ROOT / "servo" / "paper-xy.yaml"
HOLD = 300  # rows of the capture after the last command
LATE = 2  # ticks the controller sees the position late
NOISE_RATIO = 2.0  # identify's: a residual above twice the noise in it is the model's error


@pytest.fixture(autouse=True)
def empty_stdin(monkeypatch):
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


def late_loop(commands, ax, period, late):
    """The closed loop tick by tick, its controller acting on the position *late* ticks old: u = kp (c - m) +
    kv Δc / T with m = p[k - late]; returns m per tick, the feedback the controller (and a sampler on its pin) saw."""
    from scipy.signal import cont2discrete, tf2ss

    A, B, C, _, _ = cont2discrete(tf2ss(np.asarray(ax.num, float), np.append(np.asarray(ax.den, float), 0.0)),
                                  period, method="zoh")
    C, B = C[0], B[:, 0]
    # at rest at the first command: the state whose output is c0 and which A keeps
    x = np.linalg.lstsq(np.vstack([C, A - np.eye(A.shape[0])]), np.concatenate([[commands[0]], np.zeros(A.shape[0])]),
                        rcond=None)[0]
    seen = [commands[0]] * late
    prev = commands[0]
    out = np.empty(commands.size)
    for k, c in enumerate(commands):
        seen.append(float(C @ x))
        m = seen.pop(0)
        out[k] = m
        u = ax.kp * (c - m) + ax.kv * (c - prev) / period
        prev = c
        x = A @ x + B * u
    return out


@pytest.fixture(scope="module")
def late_capture(tmp_path_factory):
    spec = load_job(str(CIRCLE))
    run = Interpolation(spec, job_path(spec))
    data = np.vstack([c.data for c in run.chunks()])
    commands = np.ascontiguousarray(data[:, [run.columns.index("x"), run.columns.index("y")]])
    held = np.vstack([commands, np.tile(commands[-1], (HOLD, 1))])
    model = load_servo(PAPER)
    feedback = np.column_stack([late_loop(held[:, i], model.axes[a], 1e-3, LATE) for i, a in enumerate("xy")])
    ticks = np.minimum(np.arange(held.shape[0]), commands.shape[0] - 1)
    path = tmp_path_factory.mktemp("late") / "capture.txt"
    path.write_text("".join(f"{k} {c[0]:f} {c[1]:f} {f[0]:f} {f[1]:f} \n" for k, c, f in zip(ticks, held, feedback)))
    return path


def test_a_loop_two_ticks_late_is_the_model_familys_limit_and_named(capsys, late_capture):
    out_file = late_capture.parent / "fitted.yaml"
    code, out, err = run_main(capsys, "identify", late_capture, "--job", CIRCLE, "--servo", PAPER, "--family", "lag2",
                              "--json", "-o", out_file)
    assert code == 0, err
    report = json.loads(out)
    for a in "xy":
        fit = report["axes"][a]
        # not noise (the capture has none but %f's) but the family, the residual far above the noise in it
        assert fit["limited_by"][0] == "the model family" and "noise" not in fit["limited_by"], (a, fit["limited_by"])
        assert fit["residual_rms"] > NOISE_RATIO * max(fit["noise"], fit["floor"]), fit
        advice = fit["advice"]
        assert advice.startswith("the lag2 plant does not explain the capture")
        assert f"sees the position {LATE} ticks late" in advice and "no place for such a delay" in advice
        assert f"nurbsinterp: {late_capture}: axis {a}: {advice}\n" in err
        assert advice in out_file.read_text()  # the file written says it too
