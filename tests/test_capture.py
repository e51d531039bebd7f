"""`simulate --actual`: a LinuxCNC halsampler capture of the real run, measured as the model is.

The captures here are made from simulate's own trace (`-o`: per tick the commanded and the
model's positions), written as halsampler writes (C's %f, 6 decimals), so the machine's report
must be the model's to the printing's rounding; and from positions put at a known distance
from the curve, checked against closed forms and a naive brute force.  Bounds are derived
from the roundings, not picked:

- the trace prints positions with 9 decimals (|δ| <= 5e-10 mm), %f with 6 (<= 5e-7 mm), and
  parsing a decimal back costs an ulp (< 1e-13 mm below 100 mm): POSITION per axis;
- the contour error is a distance, 1-Lipschitz in the position: |Δ| <= |Δq| <= sqrt(2) POSITION,
  plus 1e-9 mm for each of the two certified window searches (nurbs.project_arc_window);
- a maximum or an RMS moves no more than the largest per-tick change.
"""
from __future__ import annotations

import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import oracle
from nurbsinterp.capture import Capture, default_columns, parse_columns
from nurbsinterp.cli import main
from nurbsinterp.config import load_job
from nurbsinterp.errors import StreamError, UsageError
from nurbsinterp.path import job_path
from nurbsinterp.servo import load_servo
from nurbsinterp.simulation import simulate
from clirun import assert_one_line_error, in_process, read_trace

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
WAVE = ROOT / "curves" / "quintic-wave.yaml"
TILTED = ROOT / "curves" / "tilted-circle-3d.yaml"
XYZ_FILE = ROOT / "servo" / "example-xyz.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test

POSITION = 5e-7 + 5e-10 + 1e-13  # mm per axis: %f of a 9-decimal trace value, parsed back
CONTOUR = math.sqrt(2) * POSITION + 2e-9  # mm (module docstring)
TRACE_ROUNDING = 5e-10  # the trace's 9 decimals
SEARCH = 1e-9  # the certified window search


# --------------------------------------------------------------------------- helpers


#: what simulate --plan says on stderr of the circle (issue 27: planning here is said)
PLANNED_HERE = f"nurbsinterp: simulate planned {CIRCLE} itself (--plan): no stream was read\n"


def run_main(capsys, *args):
    """nurbsinterp.cli.main in-process: (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err



@pytest.fixture(autouse=True)
def empty_stdin(monkeypatch):
    """stdin as `</dev/null` in a script, in every test here: simulate without COMMANDS plans the job itself."""
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


def fmt_f(v) -> str:
    """C's printf("%f"), as halsampler prints a float pin."""
    return "%f" % v


def capture_text(rows) -> str:
    """Lines of a halsampler capture: each row a list of already formatted values."""
    return "".join(" ".join(r) + "\n" for r in rows)


def tick_rows(trace, cols, last_tick, *, k=True, cmd=True, positions=None):
    """Capture rows of the trace: [k] x_cmd y_cmd x y (the default map), k held at the last tick in the hold."""
    axes = [a for a in "xyz" if f"{a}_cmd" in cols]
    rows = []
    for i, r in enumerate(trace):
        row = [str(min(int(r[0]), last_tick))] if k else []
        if cmd:
            row += [fmt_f(r[cols.index(f"{a}_cmd")]) for a in axes]
        p = positions[i] if positions is not None else [r[cols.index(f"{a}_act")] for a in axes]
        row += [fmt_f(v) for v in p]
        rows.append(row)
    return rows


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """The circle planned and simulated by simulate itself: its JSON report and its trace."""
    d = tmp_path_factory.mktemp("model")
    code, out, err = in_process(["simulate", "--plan", "--job", CIRCLE, "--json", "-o", d / "trace.csv"])
    assert code == 0, err
    cols, trace = read_trace(d / "trace.csv")
    report = json.loads(out)
    code, _, err = in_process(["plan", CIRCLE, "-q", "-o", d / "plan.csv"])
    assert code == 0, err
    return {"report": report, "cols": cols, "trace": trace, "dir": d, "last": report["command_ticks"] - 1}


# --------------------------------------------------------------------------- the model's run captured


def _layout_k(m):
    lead = [["0", fmt_f(0), fmt_f(0), fmt_f(0), fmt_f(0)]] * 4  # the streamer holding its pins before the stream
    return lead + tick_rows(m["trace"], m["cols"], m["last"]), None, 4


def _layout_no_k(m):
    return tick_rows(m["trace"], m["cols"], m["last"], k=False), "x_cmd,y_cmd,x,y", 0


def _layout_sample(m):
    """halsampler -t: the sample number first; an ignored column (an underrun count); another order."""
    rows = [["0", "0", fmt_f(0), fmt_f(0), fmt_f(0), fmt_f(0)]] * 3 + tick_rows(m["trace"], m["cols"], m["last"])
    out = []
    for i, r in enumerate(rows):
        k, xc, yc, x, y = r[0], r[1], r[2], r[3], r[4]
        out.append([str(1000 + i), k, "0", x, y, xc, yc])
    return out, "sample,k,-,x,y,x_cmd,y_cmd", 3


def _layout_earlier_stream(m):
    """The pins still holding an earlier run's last tick before this one starts at k = 0: all dropped."""
    lead = [[str(m["last"]), fmt_f(0), fmt_f(0), fmt_f(0), fmt_f(0)]] * 6
    return lead + tick_rows(m["trace"], m["cols"], m["last"]), None, 6


LAYOUTS = {"k": _layout_k, "no-k": _layout_no_k, "sample": _layout_sample, "earlier-stream": _layout_earlier_stream}


def _measure(capsys, tmp_path, rows, columns, *extra):
    cap = tmp_path / "capture.txt"
    cap.write_text(capture_text(rows))
    args = ["simulate", "--plan", "--job", CIRCLE, "--json", "--actual", cap, *extra]
    if columns:
        args += ["--actual-columns", columns]
    code, out, err = run_main(capsys, *args)
    assert code == 0 and err == PLANNED_HERE, err
    return json.loads(out)


def assert_measured_is_model(meas, m, ticks):
    """The machine's report against the model's trace over its first *ticks* ticks (module docstring)."""
    cols, trace = m["cols"], m["trace"][:ticks]
    err = trace[:, cols.index("contour_error")]  # the model's, to 9 decimals
    assert meas["contour_error_max"] == pytest.approx(err.max(), abs=CONTOUR + TRACE_ROUNDING, rel=0)
    assert meas["contour_error_rms"] == pytest.approx(np.sqrt(np.mean(err ** 2)), abs=CONTOUR + TRACE_ROUNDING, rel=0)
    for a in "xy":
        track = trace[:, cols.index(f"{a}_cmd")] - trace[:, cols.index(f"{a}_act")]
        assert meas["tracking_error_max"][a] == pytest.approx(np.abs(track).max(), abs=POSITION + 2 * TRACE_ROUNDING)
        assert meas["tracking_error_rms"][a] == pytest.approx(np.sqrt(np.mean(track ** 2)),
                                                              abs=POSITION + 2 * TRACE_ROUNDING)
    assert meas["ticks"] == ticks
    for a in "xy":
        assert meas["as_received_max"][a] <= POSITION


def naive_feedrate_error(positions, v_cmd, period):
    """|p_k - p_(k-1)| / T (0 at the first tick) minus the commanded feedrate, tick by tick."""
    speed = np.zeros(len(positions))
    for k in range(1, len(positions)):
        speed[k] = math.hypot(*(positions[k] - positions[k - 1])) / period
    return speed - v_cmd


@pytest.mark.parametrize("layout", list(LAYOUTS))
def test_the_models_run_captured_is_measured_as_the_model(capsys, tmp_path, model, layout):
    rows, columns, lead = LAYOUTS[layout](model)
    report = _measure(capsys, tmp_path, rows, columns)
    meas, rep = report["measured"], model["report"]
    # the model's own part is what it is without a capture
    assert {k: v for k, v in report.items() if k != "measured"} == rep
    assert_measured_is_model(meas, model, rep["ticks"])
    for key in ("contour_error_max", "contour_error_rms"):
        assert meas[key] == pytest.approx(rep[key], abs=CONTOUR, rel=0), key
    assert meas["hold_ticks"] == rep["ticks"] - rep["command_ticks"] == meas["capture_hold_rows"]
    assert meas["capture_lead_rows"] == lead
    assert meas["capture"].endswith("capture.txt")
    assert set(meas) == {"contour_error_max", "contour_error_rms", "contour_error_max_t", "contour_error_max_u",
                         "tracking_error_max", "tracking_error_rms", "feedrate_error_max", "feedrate_error_max_signed",
                         "feedrate_error_max_t", "feedrate_error_rms", "capture", "ticks", "hold_ticks",
                         "capture_lead_rows", "capture_hold_rows", "as_received_max", "cutting_ticks", "rapid_ticks"}
    # the feedrate: a naive finite difference of the capture's positions as printed
    pos = np.array([[float(v) for v in r[-2:]] for r in tick_rows(model["trace"], model["cols"], model["last"])])
    e = naive_feedrate_error(pos, model["trace"][:, model["cols"].index("v_cmd")], rep["period"])
    assert meas["feedrate_error_max"] == pytest.approx(np.abs(e).max(), abs=2 * TRACE_ROUNDING, rel=1e-12)
    assert meas["feedrate_error_rms"] == pytest.approx(np.sqrt(np.mean(e ** 2)), abs=2 * TRACE_ROUNDING, rel=1e-12)


@pytest.mark.parametrize("hold", [0, 40, 500])
def test_the_hold_measured_is_what_both_have(capsys, tmp_path, model, hold):
    """A capture with fewer hold rows than the model's settle: only those are measured; more: the model's."""
    rep = model["report"]
    rows = tick_rows(model["trace"], model["cols"], model["last"])[:rep["command_ticks"]]
    last = rows[-1]
    held = tick_rows(model["trace"], model["cols"], model["last"])[rep["command_ticks"]:]
    rows += (held + [last] * hold)[:hold]
    meas = _measure(capsys, tmp_path, rows, None)["measured"]
    measured_hold = min(hold, rep["ticks"] - rep["command_ticks"])
    assert meas["hold_ticks"] == measured_hold and meas["capture_hold_rows"] == hold
    assert_measured_is_model(meas, model, rep["command_ticks"] + measured_hold)


def test_the_table_shows_model_and_machine(capsys, tmp_path, model):
    cap = tmp_path / "capture.txt"
    rows, _, _ = _layout_k(model)
    cap.write_text(capture_text(rows))
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap)
    assert code == 0 and err == PLANNED_HERE, err
    assert "model" in out and "machine" in out and "commands received" in out and "capture.txt" in out
    assert out.count("181.5 um") == 2  # the circle's contour error, model and machine (README)


def test_the_plot_draws_the_machine_beside_the_model(capsys, tmp_path, model):
    """With a capture, the kept series carries the machine's positions and their own feet on the circle
    (simulation.series_columns): each at exactly the measured contour error, ||p - c| - R| in closed form; and
    simulate --plot draws them."""
    from nurbsinterp.simulation import series_columns

    rows, _, _ = _layout_k(model)
    text = capture_text(rows)
    cap = tmp_path / "capture.txt"
    cap.write_text(text)
    job = load_job(str(CIRCLE))
    path = job_path(job)
    from nurbsinterp.interpolate import Interpolation

    run = Interpolation(job, path)
    capture = Capture(io.BytesIO(text.encode()), "capture", parse_columns(default_columns(2), 2))
    report, series = simulate(path, load_servo(None), run.columns, (c.data for c in run.chunks()), actual=capture,
                              keep_series=True)
    col = series_columns(2, measured=True)
    have = np.isfinite(series[:, col["err_meas"]])
    assert have.sum() > 1000
    meas, err_meas = series[have, col["meas"]], series[have, col["err_meas"]]
    radial = np.abs(np.hypot(meas[:, 0] - 50.0, meas[:, 1]) - 50.0)
    assert np.max(np.abs(err_meas - radial)) <= 1e-9
    on_foot = np.linalg.norm(meas - path.programmed.evaluate(series[have, col["foot_meas"]]), axis=1)
    assert np.max(np.abs(on_foot - err_meas)) <= 1e-9
    png = tmp_path / "machine.png"
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap, "--plot", png)
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_trace_adds_the_measured_columns(capsys, tmp_path, model):
    rows, _, _ = _layout_k(model)
    cap = tmp_path / "capture.txt"
    cap.write_text(capture_text(rows[:4 + model["report"]["command_ticks"] + 30]))  # a hold of 30 rows
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap, "-o", tmp_path / "t.csv", "--json")
    assert code == 0, err
    meas = json.loads(out)["measured"]
    cols, trace = read_trace(tmp_path / "t.csv")
    assert cols == model["cols"] + ["x_meas", "y_meas", "contour_error_meas", "v_meas"]
    assert trace.shape[0] == meas["ticks"] == model["report"]["command_ticks"] + 30  # one row per measured tick
    np.testing.assert_array_equal(trace[:, :len(model["cols"])], model["trace"][:trace.shape[0]])
    printed = np.array([[float(v) for v in r[-2:]] for r in rows[4:4 + trace.shape[0]]])
    np.testing.assert_allclose(trace[:, -4:-2], printed, atol=TRACE_ROUNDING, rtol=0)
    assert trace[:, -2].max() == pytest.approx(meas["contour_error_max"], abs=TRACE_ROUNDING)


# --------------------------------------------------------------------------- off the path: exact answers


def _normal(U, p, V, W, u):
    d = oracle.curve_derivatives(U, p, V, W, u, 1)
    tangent = d[:, 1, :] / np.linalg.norm(d[:, 1, :], axis=1)[:, None]
    return d[:, 0, :], np.column_stack([tangent[:, 1], -tangent[:, 0]])


def _off_path(job, trace, cols, lag, amplitude):
    """Positions lagging *lag* ticks behind the command and moved along the normal by δ_k (both signs)."""
    c = job.curve
    U, p, V, W = (np.asarray(c.knots, float), c.degree, np.asarray(c.control_points, float),
                  np.asarray(c.weights, float))
    u = trace[:, cols.index("u")]
    w = np.concatenate([np.full(lag, u[0]), u[:-lag]])
    base, normal = _normal(U, p, V, W, w)
    t = trace[:, cols.index("t")]
    delta = amplitude * np.sin(2 * np.pi * t / 0.7)
    return base + delta[:, None] * normal, (U, p, V, W)


def _run_off_path(capsys, tmp_path, job_file, lag, amplitude):
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", job_file, "-o", tmp_path / "model.csv", "--json")
    assert code == 0, err
    cols, trace = read_trace(tmp_path / "model.csv")
    q, nurbs = _off_path(load_job(job_file), trace, cols, lag, amplitude)
    rows = tick_rows(trace, cols, json.loads(out)["command_ticks"] - 1, positions=q)
    cap = tmp_path / "off.txt"
    cap.write_text(capture_text(rows))
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", job_file, "--actual", cap, "-o", tmp_path / "t.csv",
                              "--json")
    assert code == 0, err
    tcols, t = read_trace(tmp_path / "t.csv")
    printed = np.array([[float(v) for v in r[-2:]] for r in rows])[:t.shape[0]]
    return json.loads(out)["measured"], t[:, tcols.index("contour_error_meas")], printed, nurbs


def test_off_path_on_the_circle_is_the_offset(capsys, tmp_path):
    """Normal offsets on the circle: the contour error is | |q - c| - 50 | of the printed q, exactly."""
    meas, err, q, _ = _run_off_path(capsys, tmp_path, CIRCLE, lag=3, amplitude=0.02)
    exact = np.abs(np.hypot(q[:, 0] - 50.0, q[:, 1]) - 50.0)
    np.testing.assert_allclose(err, exact, atol=SEARCH + TRACE_ROUNDING, rtol=0)
    assert meas["contour_error_max"] == pytest.approx(exact.max(), abs=SEARCH, rel=0)
    assert meas["contour_error_max"] == pytest.approx(0.02, abs=POSITION * 2)


def brute_force_distance(nurbs, q, samples=20001, iterations=90):
    """The distance from each point q (N, 2) to the curve: dense samples, then golden section on the
    bracket of the nearest sample -- naive, with the naive oracle's evaluation."""
    U, p, V, W = nurbs
    a, b = U[p], U[-p - 1]
    us = np.linspace(a, b, samples)
    pts = oracle.point(U, p, V, W, us)
    best = np.empty(len(q), dtype=np.int64)
    for s in range(0, len(q), 64):
        d2 = ((q[s:s + 64, None, :] - pts[None, :, :]) ** 2).sum(axis=2)
        best[s:s + 64] = d2.argmin(axis=1)
    lo, hi = us[np.maximum(best - 1, 0)], us[np.minimum(best + 1, samples - 1)]
    g = (math.sqrt(5) - 1) / 2

    def dist(u):
        return np.linalg.norm(oracle.point(U, p, V, W, u) - q, axis=1)

    for _ in range(iterations):
        m1, m2 = hi - g * (hi - lo), lo + g * (hi - lo)
        left = dist(m1) < dist(m2)
        hi = np.where(left, m2, hi)
        lo = np.where(left, lo, m1)
    return dist(0.5 * (lo + hi))


def test_off_path_against_a_brute_force(capsys, tmp_path):
    """A tight degree-5 curve, positions lagging and off the path: every tick against the brute force."""
    meas, err, q, nurbs = _run_off_path(capsys, tmp_path, WAVE, lag=5, amplitude=0.01)
    ref = brute_force_distance(nurbs, q)
    np.testing.assert_allclose(err, ref, atol=SEARCH + TRACE_ROUNDING + 1e-11, rtol=0)
    assert meas["contour_error_max"] == pytest.approx(ref.max(), abs=SEARCH + 1e-11, rel=0)
    assert meas["contour_error_rms"] == pytest.approx(np.sqrt(np.mean(ref ** 2)), abs=SEARCH + 1e-11, rel=0)


# --------------------------------------------------------------------------- the commands from a stream


def test_a_stream_from_a_file_and_from_a_pipe(capsys, tmp_path, model):
    rows, _, _ = _layout_k(model)
    cap = tmp_path / "capture.txt"
    cap.write_text(capture_text(rows))
    plan = model["dir"] / "plan.csv"
    code, out, err = run_main(capsys, "simulate", plan, "--job", CIRCLE, "--actual", cap, "--json")
    assert code == 0 and err == "", err
    from_file = json.loads(out)
    r = subprocess.run(f"'{EXE}' plan '{CIRCLE}' -q | '{EXE}' simulate --job '{CIRCLE}' --actual '{cap}' --json",
                       shell=True, capture_output=True, timeout=HANG_S)
    assert r.returncode == 0 and r.stderr == b"", r.stderr
    from_pipe = json.loads(r.stdout)
    assert from_pipe == from_file
    self_planned = model["report"]
    meas = from_file["measured"]
    assert meas["ticks"] == self_planned["ticks"]
    # the CSV's commands are the plan's to 9 decimals: the capture's commands within %f's rounding of them
    assert max(meas["as_received_max"].values()) <= 5e-7 + 2 * TRACE_ROUNDING
    assert meas["contour_error_max"] == pytest.approx(self_planned["contour_error_max"], abs=CONTOUR, rel=0)


def test_3d_default_columns(capsys, tmp_path):
    """A 3-D job: the default map k,x_cmd,y_cmd,z_cmd,x,y,z."""
    args = ["--plan", "--job", TILTED, "--servo", XYZ_FILE, "--interpolator", "taylor2"]
    code, out, err = run_main(capsys, "simulate", *args, "-o", tmp_path / "t.csv", "--json")
    assert code == 0, err
    rep = json.loads(out)
    cols, trace = read_trace(tmp_path / "t.csv")
    rows = tick_rows(trace, cols, rep["command_ticks"] - 1)
    assert len(rows[0]) == 7
    (tmp_path / "c.txt").write_text(capture_text(rows))
    code, out, err = run_main(capsys, "simulate", *args, "--actual", tmp_path / "c.txt", "--json")
    assert code == 0, err
    meas = json.loads(out)["measured"]
    assert set(meas["as_received_max"]) == {"x", "y", "z"}
    bound = math.sqrt(3) * POSITION + 2 * SEARCH
    assert meas["contour_error_max"] == pytest.approx(rep["contour_error_max"], abs=bound, rel=0)
    assert meas["ticks"] == rep["ticks"]


# --------------------------------------------------------------------------- bad captures


def _lines(m):
    rows, _, _ = _layout_k(m)
    return capture_text(rows).splitlines(keepends=True)  # line 5 is tick 0


def _with_line(m, line, text):
    lines = _lines(m)
    lines[line - 1] = text
    return "".join(lines)


def _insert(m, line, text):
    lines = _lines(m)
    lines.insert(line - 1, text)
    return "".join(lines)


def _drop(m, line):
    lines = _lines(m)
    del lines[line - 1]
    return "".join(lines)


def _field(m, line, col, value):
    lines = _lines(m)
    f = lines[line - 1].split()
    f[col] = value
    lines[line - 1] = " ".join(f) + "\n"
    return "".join(lines)


def _sampled(m, skip=None):
    lines = _lines(m)
    return "".join(f"{7 + i + (1 if skip is not None and i >= skip else 0)} {l}" for i, l in enumerate(lines))


def _last_line(m):
    return len(_lines(m))


BAD = {
    # name: (builder(model) -> text, --actual-columns or None, expected parts of the message with the line)
    "overrun": (lambda m: _insert(m, 100, "overrun\n"), None, [":100:", "overrun", "depth"]),
    "too-many-values": (lambda m: _with_line(m, 50, "45 1.0 2.0 3.0 4.0 5.0\n"), None, [":50:", "6 values", "5"]),
    "too-few-values": (lambda m: _with_line(m, 51, "46 1.0 2.0\n"), None, [":51:", "3 values"]),
    "not-a-number": (lambda m: _field(m, 60, 3, "abc"), None, [":60:", "column 4 (x)", "'abc'", "not a number"]),
    "nan": (lambda m: _field(m, 70, 4, "nan"), None, [":70:", "column 5 (y)", "not a finite number"]),
    "inf": (lambda m: _field(m, 71, 1, "-inf"), None, [":71:", "column 2 (x_cmd)", "not a finite number"]),
    "sample-gap": (lambda m: _sampled(m, skip=80), "sample,k,x_cmd,y_cmd,x,y", [":81:", "lost 1 samples"]),
    "k-gap": (lambda m: _drop(m, 90), None, [":90:", "k = 86 follows k = 84", "1 ticks lost"]),
    "k-underrun": (lambda m: _insert(m, 91, _lines(m)[89]), None, [":92:", "resumes", "underrun"]),
    "k-not-integer": (lambda m: _field(m, 40, 0, "35.5"), None, [":40:", "k = 35.5", "integer"]),
    "empty-line": (lambda m: _insert(m, 30, "\n"), None, [":30:", "empty line"]),
    "empty": (lambda m: "", None, ["the capture is empty"]),
    "only-empty-lines": (lambda m: "\n\n", None, ["the capture is empty"]),
    "shorter-than-the-plan": (lambda m: "".join(_lines(m)[:1000]), None,
                              [":1000:", "ends at tick 995", "must cover every command"]),
    "stops-early-holding": (lambda m: "".join(_lines(m)[:1000] + [_lines(m)[999]] * 5), None,
                            [":1001:", "k stays at 995", "must cover every command"]),
    "starts-late": (lambda m: "".join(_lines(m)[9:]), None, [":1:", "starts at tick k = 5", "from tick 0"]),
    "never-runs": (lambda m: "".join(_lines(m)[:4]), None, ["k holds 0 on all 4 lines"]),
    "past-the-last-tick": (lambda m: "".join(_lines(m)[:4 + m["last"] + 1])
                           + f"{m['last'] + 1} 0.000000 0.000000 0.000000 0.000000\n", None,
                           lambda m: [f":{4 + m['last'] + 2}:", "goes on past the plan's last tick"]),
    "k-changes-after-the-end": (lambda m: "".join(_lines(m)) + "0 0.000000 0.000000 0.000000 0.000000\n", None,
                                lambda m: [f":{_last_line(m) + 1}:", "after the stream ended", "cut it"]),
    "received-differs": (lambda m: _field(m, 500, 1, "%f" % (float(_lines(m)[499].split()[1]) + 2e-6)), None,
                         [":500:", "tick 495", "x_cmd", "not of this plan", "--force"]),
    "misaligned-without-k": (lambda m: "".join(l.split(" ", 1)[1] for l in _lines(m)[5:]), "x_cmd,y_cmd,x,y",
                             [":1:", "tick 0", "y_cmd"]),
    "held-command-differs": (lambda m: _field(m, _last_line(m) - 3, 2, "1.000000"), None,
                             lambda m: [f":{_last_line(m) - 3}:", "y_cmd", "not of this plan"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_capture(capsys, tmp_path, model, empty_stdin, case):
    build, columns, parts = BAD[case]
    parts = parts(model) if callable(parts) else parts
    cap = tmp_path / "capture.txt"
    cap.write_text(build(model))
    trace = tmp_path / "trace.csv"
    args = ["simulate", "--plan", "--job", CIRCLE, "--actual", cap, "--json", "-o", trace]
    if columns:
        args += ["--actual-columns", columns]
    code, out, err = run_main(capsys, *args)
    where = parts[0] if parts[0].startswith(":") else ""
    assert_one_line_error(code, out, err, f"{cap}{where}", *parts[1 if where else 0:])
    assert not trace.exists() and os.listdir(tmp_path) == [cap.name]  # no trace, no temporary left


def test_force_measures_a_capture_of_other_commands(capsys, tmp_path, model, empty_stdin):
    build, _, _ = BAD["received-differs"]
    cap = tmp_path / "capture.txt"
    cap.write_text(build(model))
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap, "--json", "--force")
    assert code == 0, err
    assert json.loads(out)["measured"]["as_received_max"]["x"] == pytest.approx(2e-6, abs=POSITION)


@pytest.mark.parametrize("columns, parts", [
    ("k,x_cmd,y_cmd,x,q", ["column 5 'q'", "not a name"]),
    ("k,x,y,x,y", ["'x' names columns 2 and 4"]),
    ("k,x_cmd,y_cmd,x,-", ["no feedback column", "y axis"]),
    ("k,x_cmd,x,y", ["x_cmd without y_cmd"]),
    ("k,x,y,z", ["2-D", "no z axis", "column 4"]),
])
def test_bad_column_map(capsys, tmp_path, model, empty_stdin, columns, parts):
    cap = tmp_path / "capture.txt"
    cap.write_text("".join(_lines(model)))
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap, "--actual-columns", columns,
                              "-o", tmp_path / "t.csv")
    assert_one_line_error(code, out, err, "--actual-columns", *parts)
    assert os.listdir(tmp_path) == [cap.name]


def test_capture_usage_errors(capsys, tmp_path, empty_stdin):
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual-columns", "k,x,y")
    assert_one_line_error(code, out, err, "--actual-columns applies only with --actual")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", "-")
    assert_one_line_error(code, out, err, "--actual -")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", tmp_path / "none.txt")
    assert_one_line_error(code, out, err, "none.txt", "cannot read")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", tmp_path)
    assert_one_line_error(code, out, err, "is a directory")
    cap = tmp_path / "c.txt"
    cap.write_text("0 0 0 0 0\n")
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--actual", cap, "-o", cap)
    assert_one_line_error(code, out, err, "refusing to overwrite")
    assert cap.read_text() == "0 0 0 0 0\n"


def test_help_documents_the_capture(capsys):
    code, out, _ = run_main(capsys, "simulate", "--help")
    assert code == 0
    text = " ".join(out.split())
    for part in ("--actual CAPTURE", "--actual-columns", "k,x_cmd,y_cmd,x,y", "halsampler", "overrun", "hold",
                 "|p(k) - p(k-1)|/T", "1e-6 mm + 1e-9 |x|"):
        assert part in text, part


# --------------------------------------------------------------------------- the library


def _capture(text, columns="k,x_cmd,y_cmd,x,y", chunk_bytes=1 << 22, name="cap"):
    return Capture(io.BytesIO(text.encode()), name, parse_columns(columns, 2), chunk_bytes=chunk_bytes)


def _synthetic(ticks=50, lead=3, hold=7):
    rows = [f"0 0.000000 0.000000 {0.5 * i:f} 0.000000" for i in range(lead)]
    rows += [f"{k} {k:f} {2 * k:f} {k + 0.25:f} {2 * k - 0.25:f}" for k in range(ticks)]
    rows += [f"{ticks - 1} {ticks - 1:f} {2 * ticks - 2:f} {ticks - 1:f} {2 * ticks - 2:f}"] * hold
    return "\n".join(rows) + "\n"


def _drain(cap, sizes, hold_sizes):
    blocks = [cap.commands(m) for m in sizes]
    cap.end_commands()
    holds = [cap.hold(m) for m in hold_sizes]
    cap.finish()
    return blocks, holds


@pytest.mark.parametrize("chunk_bytes", [1, 37, 200, 1 << 22])
def test_capture_alignment_is_the_same_in_any_chunks(chunk_bytes):
    cap = _capture(_synthetic(), chunk_bytes=chunk_bytes)
    blocks, holds = _drain(cap, [1, 20, 29], [4, 10])
    pos = np.vstack([b.position for b in blocks])
    k = np.arange(50)
    np.testing.assert_array_equal(pos, np.column_stack([k + 0.25, 2 * k - 0.25]))
    np.testing.assert_array_equal(np.vstack([b.command for b in blocks]), np.column_stack([k, 2.0 * k]))
    np.testing.assert_array_equal(np.concatenate([b.line for b in blocks]), np.arange(4, 54))
    assert [h.position.shape[0] for h in holds] == [4, 3]
    np.testing.assert_array_equal(holds[0].line, [54, 55, 56, 57])
    assert (cap.lead_rows, cap.hold_rows, cap.ticks) == (3, 7, 50)
    for b in blocks + holds:
        assert b.position.flags.c_contiguous and b.position.dtype == np.float64


def test_capture_without_k_counts_rows_as_ticks():
    text = "".join(f"{i:f} {i:f}\n" for i in range(10))
    cap = Capture(io.BytesIO(text.encode()), "cap", parse_columns("x,y", 2), chunk_bytes=5)
    blocks, holds = _drain(cap, [6], [10])
    assert blocks[0].command is None
    np.testing.assert_array_equal(blocks[0].position[:, 0], np.arange(6.0))
    np.testing.assert_array_equal(holds[0].position[:, 0], np.arange(6.0, 10.0))
    assert (cap.lead_rows, cap.hold_rows) == (0, 4)


def test_trailing_empty_lines_are_ignored():
    cap = _capture(_synthetic() + "\n  \n")
    _drain(cap, [50], [100])
    assert cap.hold_rows == 7


def test_the_capture_is_checked_to_its_end():
    """A fault in the hold rows past what the simulation measures is refused all the same."""
    text = _synthetic(hold=20).splitlines(keepends=True)
    text.insert(len(text) - 2, "overrun\n")
    cap = _capture("".join(text), chunk_bytes=64)
    cap.commands(50)
    cap.end_commands()
    cap.hold(3)
    with pytest.raises(StreamError, match=f"cap:{len(text) - 2}: halsampler lost samples here"):
        cap.finish()


def test_default_columns():
    assert default_columns(2) == "k,x_cmd,y_cmd,x,y"
    assert default_columns(3) == "k,x_cmd,y_cmd,z_cmd,x,y,z"
    cols = parse_columns("sample,-,y,x,-,k", 2)
    assert (cols.sample, cols.k, cols.position, cols.command) == (0, 5, (3, 2), None)
    with pytest.raises(UsageError, match="^the column map 'k,x': "):  # the library words no option
        parse_columns("k,x", 2)
    with pytest.raises(UsageError, match="^--actual-columns 'k,x': "):
        parse_columns("k,x", 2, "--actual-columns")


def test_a_stream_in_encoder_counts_is_refused():
    """plan --counts writes x_counts, y_counts: simulate needs millimetres."""
    job = load_job(CIRCLE)
    columns = ["k", "n", "t", "u", "x_counts", "y_counts", "v", "a"]
    chunk = np.zeros((4, len(columns)))
    chunk[:, 2] = np.arange(4) * 1e-3
    with pytest.raises(StreamError, match=r"^run.csv: the stream is in drive counts \(x_counts,y_counts\): "
                                          r"it needs positions in mm \(plan it with a resolution but not in counts\)$"):
        simulate(job_path(job), load_servo(None), columns, iter([chunk]), name="run.csv")


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_simulate_refuses_a_counts_stream_in_one_line(tmp_path, fmt):
    """The CLI: plan --counts, then simulate on it."""
    stream = tmp_path / f"run.{fmt}"
    exe = str(Path(sys.executable).with_name("nurbsinterp"))
    done = subprocess.run([exe, "plan", str(CIRCLE), "-q", "--format", fmt, "--resolution", "0.5um", "--counts",
                           "-o", str(stream)], capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    done = subprocess.run([exe, "simulate", str(stream), "--job", str(CIRCLE)], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.splitlines() == [f"nurbsinterp: {stream}: the stream is in drive counts (x_counts,y_counts): "
                                        "it needs positions in mm (plan it with a resolution but not in counts)"]
