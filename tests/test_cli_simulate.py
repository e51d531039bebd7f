"""`nurbsinterp simulate` and `nurbsinterp compare` on the command line.

In-process ``main([...])`` with capsys wherever no real pipe is needed; the installed
executable (a subprocess, ~1 s each) where stdin or a pipe is the point.  Streams are
planned once per module with ``plan -o``.
"""
from __future__ import annotations

import io
import json
import math
import os
import re
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import lfilter

from nurbsinterp.cli import main
from nurbsinterp.servo import PAPER_TABLE
from clirun import assert_one_line_error, plan_piped_into
from layout import one_curve

from test_servo import closed_loop_tf

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
TILTED = ROOT / "curves" / "tilted-circle-3d.yaml"
PAPER_FILE = ROOT / "servo" / "paper-xy.yaml"
XYZ_FILE = ROOT / "servo" / "example-xyz.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
REPORT_KEYS = {"contour_error_max", "contour_error_rms", "contour_error_max_t", "contour_error_max_u",
               "tracking_error_max", "tracking_error_rms", "feedrate_error_max", "feedrate_error_max_signed",
               "feedrate_error_max_t", "feedrate_error_rms", "axes", "period", "ticks", "command_ticks",
               "settle_time", "settled", "servo", "job", "cutting_ticks", "rapid_ticks"}
COMPARE_KEYS = {"interpolator", "profile", "accdec", "ff_max", "chord_error_max", "command_deviation_max",
                "contour_error_max", "contour_error_rms", "feedrate_error_max", "feedrate_error_rms",
                "motion_time", "end_gap"}
TRACE_HEADER = "k,t,u,x_cmd,y_cmd,x_act,y_act,contour_error,v_cmd,v_act"


def run_main(capsys, *args):
    """nurbsinterp.cli.main in-process: (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def run_exe(*args, stdin=subprocess.DEVNULL):
    return subprocess.run([str(EXE), *map(str, args)], stdin=stdin, capture_output=True, timeout=HANG_S)


def sim_json(capsys, *args) -> dict:
    code, out, err = run_main(capsys, "simulate", *args, "--json")
    assert code == 0, err
    return json.loads(out)



@pytest.fixture
def empty_stdin(monkeypatch):
    """stdin as `</dev/null` in a script: not a terminal, empty."""
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(b""))))


@pytest.fixture(scope="module")
def streams(tmp_path_factory):
    """The circle job planned once: a.csv, a.bin (circle), t3.csv (tilted 3-D circle)."""
    d = tmp_path_factory.mktemp("streams")
    for args, name in (([CIRCLE], "a.csv"), ([CIRCLE, "--format", "bin"], "a.bin"), ([TILTED], "t3.csv")):
        with pytest.raises(SystemExit) as info:
            main(["plan", *map(str, args), "-q", "-o", str(d / name)])
        assert info.value.code == 0
    return d


def bin_parts(path):
    """(header line, columns, records) of a binary stream; its 64-byte end mark left out."""
    head, _, body = path.read_bytes().partition(b"\n")
    cols = head.split()[2].decode().split(",")
    return head + b"\n", cols, np.frombuffer(body[:-64], "<f8").reshape(-1, len(cols)).copy()


def bin_mark(path, ticks=None):
    """The binary stream's end mark, saying *ticks* if given."""
    mark = path.read_bytes()[-64:]
    return mark if ticks is None else re.sub(rb"ticks=\d+ *", b"ticks=%d " % ticks, mark[:-1]).ljust(63) + b"\n"


def csv_lines(path):
    """The lines of a CSV stream, its end mark (`# nurbsinterp-end ...`) the last."""
    return path.read_text().splitlines(keepends=True)


def csv_mark(path, ticks):
    return re.sub(r"ticks=\d+", f"ticks={ticks}", csv_lines(path)[-1])


@pytest.fixture(scope="module")
def reports(streams):
    """The JSON reports of a.csv and a.bin as files (in-process) and from stdin (subprocess)."""
    out = {}
    for name in ("a.csv", "a.bin"):
        with pytest.raises(SystemExit), _capture() as buf:
            main(["simulate", str(streams / name), "--job", str(CIRCLE), "--json"])
        out[name] = json.loads(buf.getvalue())
    with open(streams / "a.bin", "rb") as fh:  # no COMMANDS: stdin brings the stream
        r = run_exe("simulate", "--job", CIRCLE, "--json", stdin=fh)
    assert r.returncode == 0 and r.stderr == b"", r.stderr
    out["bin stdin"] = json.loads(r.stdout)
    with open(streams / "a.csv", "rb") as fh:  # '-': stdin, explicitly
        r = run_exe("simulate", "-", "--job", CIRCLE, "--json", stdin=fh)
    assert r.returncode == 0 and r.stderr == b"", r.stderr
    out["csv stdin"] = json.loads(r.stdout)
    return out


class _capture:
    """Capture sys.stdout text in a module-scoped fixture (capsys is function-scoped)."""

    def __enter__(self):
        self.saved, self.buf = sys.stdout, io.StringIO()
        sys.stdout = self.buf
        return self.buf

    def __exit__(self, *exc):
        sys.stdout = self.saved
        return False


# --------------------------------------------------------------------------- 8. CSV, binary, file and stdin


def test_binary_file_and_binary_stdin_identical(reports):
    assert reports["a.bin"] == reports["bin stdin"]
    assert reports["a.csv"] == reports["csv stdin"]
    assert set(reports["a.bin"]) == REPORT_KEYS  # no field names the stream: nothing to set aside


def rounding_bounds():
    """How far the CSV's 9-decimal rounding (|δ| ≤ 5e-10 in every command, in v) can move the
    report: the l1 norms of each axis' closed-loop impulse responses, command → position and
    command → velocity (``test_servo``'s transfer-function route)."""
    delta = 5e-10
    imp = np.zeros(4000)
    imp[0] = 1.0
    l1 = {o: max(np.abs(lfilter(*closed_loop_tf(PAPER_TABLE.axes[a], 1e-3, o), imp)).sum() for a in "xy")
          for o in ("position", "velocity")}
    position = l1["position"] * delta  # |Δ actual| per axis
    return {
        "tracking": position + delta,
        "contour": math.sqrt(2) * position,
        "feedrate": math.sqrt(2) * l1["velocity"] * delta + delta,
    }


def test_csv_and_binary_reports_agree_to_the_csv_rounding(reports):
    csv, bin_ = reports["a.csv"], reports["a.bin"]
    bound = rounding_bounds()
    assert bound["contour"] < 1e-9 and bound["feedrate"] < 2e-7
    assert set(csv) == set(bin_)
    for key in ("axes", "period", "ticks", "command_ticks", "settle_time", "settled", "servo", "job"):
        assert csv[key] == bin_[key], key
    for key in ("contour_error_max", "contour_error_rms"):
        assert csv[key] == pytest.approx(bin_[key], abs=bound["contour"], rel=0), key
    for key in ("tracking_error_max", "tracking_error_rms"):
        for a in ("x", "y"):
            assert csv[key][a] == pytest.approx(bin_[key][a], abs=bound["tracking"], rel=0), (key, a)
    for key in ("feedrate_error_max", "feedrate_error_max_signed", "feedrate_error_rms"):
        assert csv[key] == pytest.approx(bin_[key], abs=bound["feedrate"], rel=0), key
    # where: the same tick (t parsed from 9 decimals vs k·T differ by an ulp)
    for key in ("contour_error_max_t", "feedrate_error_max_t"):
        assert csv[key] == pytest.approx(bin_[key], abs=1e-12), key
    assert csv["contour_error_max_u"] == pytest.approx(bin_["contour_error_max_u"], abs=1e-9)


def test_binary_through_a_real_pipe(reports):
    """plan --format bin | simulate: the pipe delivers the records in pieces."""
    r = plan_piped_into(EXE, [CIRCLE, "--format", "bin", "-q"], ["simulate", "--job", CIRCLE, "--json"], HANG_S)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == reports["a.bin"]


# --------------------------------------------------------------------------- 7. the paper's finding, through the CLI


def test_paper_finding_through_the_cli(capsys, empty_stdin, reports):
    after = sim_json(capsys, "--plan", "--job", CIRCLE, "--accdec", "after")
    before = reports["a.bin"]
    assert 0.05 < before["contour_error_max"] < 0.5
    assert after["contour_error_max"] / before["contour_error_max"] > 3
    # planning it itself (--plan) gives what the planned stream gives
    assert sim_json(capsys, "--plan", "--job", CIRCLE) == before
    print(f"\nCLI: contour max before {before['contour_error_max'] * 1e3:.1f} um, "
          f"after {after['contour_error_max'] * 1e3:.1f} um")


def test_empty_stdin_is_refused_and_plan_plans_the_job_itself(capsys, empty_stdin):
    """`simulate --job circle.yaml </dev/null` is no stream, not a cue to plan (issue 27: a failed plan upstream
    gave a report of the job planned here); `--plan` asks for that plainly, and it is said on stderr."""
    r = run_exe("simulate", "--job", CIRCLE, "--json", stdin=subprocess.DEVNULL)
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>: no commands arrived")
    r = run_exe("simulate", "--plan", "--job", CIRCLE, "--accdec", "after", "--json", stdin=subprocess.DEVNULL)
    assert r.returncode == 0, r.stderr
    assert r.stderr.decode() == f"nurbsinterp: simulate planned {CIRCLE} itself (--plan): no stream was read\n"
    rep = json.loads(r.stdout)
    assert rep == sim_json(capsys, "--plan", "--job", CIRCLE, "--accdec", "after")
    assert rep["contour_error_max"] > 1.0


# --------------------------------------------------------------------------- 9. malformed streams


def _truncated(d):
    """Cut inside record 17, as a killed writer leaves it: no end mark."""
    head, cols, data = bin_parts(d / "a.bin")
    rec = 8 * len(cols)
    return head + data.astype("<f8").tobytes()[: 17 * rec + 16]


def _bin_with(d, row, col, value):
    head, cols, data = bin_parts(d / "a.bin")
    data[row, cols.index(col)] = value
    return head + data.astype("<f8").tobytes() + bin_mark(d / "a.bin")


def _csv_with(d, line, col, value):
    lines = csv_lines(d / "a.csv")
    cols = lines[0].strip().split(",")
    fields = lines[line - 1].rstrip("\n").split(",")
    fields[cols.index(col)] = value
    lines[line - 1] = ",".join(fields) + "\n"
    return "".join(lines)


def _csv_bump(d, line, col, delta):
    lines = csv_lines(d / "a.csv")
    cols = lines[0].strip().split(",")
    return _csv_with(d, line, col, repr(float(lines[line - 1].split(",")[cols.index(col)]) + delta))


MALFORMED = {
    # name: (builder(streams dir) -> bytes or str, job, expected parts of the message)
    "truncated-record": (_truncated, CIRCLE, ["ends after 17 records and 16 bytes without its end mark",
                                              "incomplete"]),
    "truncated-record-before-the-mark": (lambda d: _truncated(d) + bin_mark(d / "a.bin", 17), CIRCLE,
                                         ["record 17 is truncated", "16 of 64 bytes"]),
    "csv-cut-at-a-line": (lambda d: "".join(csv_lines(d / "a.csv")[:1001]), CIRCLE,
                          ["ends after line 1001 without its end mark"]),
    "csv-cut-inside-a-line": (lambda d: "".join(csv_lines(d / "a.csv")[:1001])[:-7], CIRCLE,
                              ["inside line 1001", "without its end mark"]),
    "mark-miscounts": (lambda d: "".join(csv_lines(d / "a.csv")[:1001]) + csv_mark(d / "a.csv", 3643), CIRCLE,
                       ["end mark says ticks=3643 but the stream has 1000 rows"]),
    "wrong-header": (lambda d: "hello,world\n" + "".join(csv_lines(d / "a.csv")[1:]), CIRCLE,
                     ["no column 'k'"]),
    "binary-garbage-header": (lambda d: b"\xff\xfe\x00garbage\n" + b"\0" * 56, CIRCLE,
                              ["not a nurbsinterp command stream"]),
    "wrong-version": (lambda d: (d / "a.bin").read_bytes().replace(b"nurbsinterp-bin 2", b"nurbsinterp-bin 3", 1),
                      CIRCLE, ["nurbsinterp-bin 3", "is not 'nurbsinterp-bin 2"]),
    "missing-column": (lambda d: "".join(",".join(l.rstrip("\n").split(",")[:7]) + "\n"
                                         for l in csv_lines(d / "a.csv")), CIRCLE, ["no column 'a'"]),
    "nan-in-csv-row": (lambda d: _csv_with(d, 51, "x", "nan"), CIRCLE, ["line 51", "column x", "not a finite"]),
    "inf-in-csv-row": (lambda d: _csv_with(d, 7, "v", "inf"), CIRCLE, ["line 7", "column v", "not a finite"]),
    "nan-in-binary-record": (lambda d: _bin_with(d, 40, "y", np.nan), CIRCLE, ["record 40", "column y"]),
    "text-in-row": (lambda d: _csv_with(d, 12, "u", "abc"), CIRCLE, ["line 12", "'abc'", "not a number"]),
    "short-row": (lambda d: "".join(csv_lines(d / "a.csv")[:20]) + "20,0.02,0.1\n", CIRCLE,
                  ["line 21", "3 fields"]),
    "time-not-increasing": (lambda d: _csv_with(d, 30, "t", "0.027"), CIRCLE, ["line 30", "does not increase"]),
    "non-uniform-period": (lambda d: _csv_bump(d, 101, "t", 1e-6), CIRCLE, ["tick 99", "uniform period"]),
    "u-outside-domain": (lambda d: _csv_with(d, 101, "u", "1.5"), CIRCLE, ["tick 99", "outside the curve's domain"]),
    "u-outside-domain-binary": (lambda d: _bin_with(d, 2000, "u", -0.5), CIRCLE, ["tick 2000", "outside"]),
    "3d-stream-2d-job": (lambda d: (d / "t3.csv").read_bytes(), CIRCLE, ["3 axes (x,y,z)", "2-D"]),
    "3d-stream-2-axis-model": (lambda d: (d / "t3.csv").read_bytes(), TILTED,
                               ["z axis", "built-in paper X-Y table", "axes.z"]),
    "empty": (lambda d: b"", CIRCLE, ["no commands arrived", "upstream may have failed"]),
    "header-only": (lambda d: csv_lines(d / "a.csv")[0] + csv_mark(d / "a.csv", 0), CIRCLE,
                    ["header but no ticks"]),
    "binary-header-only": (lambda d: bin_parts(d / "a.bin")[0] + bin_mark(d / "a.bin", 0), CIRCLE,
                           ["header but no ticks"]),
    "one-tick": (lambda d: "".join(csv_lines(d / "a.csv")[:2]) + csv_mark(d / "a.csv", 1), CIRCLE,
                 ["at least two ticks"]),
}


@pytest.mark.parametrize("case", list(MALFORMED))
def test_malformed_stream(capsys, tmp_path, streams, case):
    build, job, parts = MALFORMED[case]
    content = build(streams)
    path = tmp_path / f"{case}.stream"
    path.write_bytes(content.encode() if isinstance(content, str) else content)
    trace = tmp_path / "trace.csv"
    code, out, err = run_main(capsys, "simulate", path, "--job", job, "--json", "-o", trace)
    assert_one_line_error(code, out, err, f"{path}:", *parts)
    assert not trace.exists() and os.listdir(tmp_path) == [path.name]  # no trace, no temporary left


@pytest.mark.parametrize("case", ["non-uniform-period", "u-outside-domain"])
def test_tick_errors_print_plain_numbers(capsys, tmp_path, streams, case):
    """Regression: the messages printed 't = np.float64(0.099001)' under numpy 2 (fixed in 1aa3bbb)."""
    build, job, _ = MALFORMED[case]
    path = tmp_path / "s.csv"
    path.write_text(build(streams))
    code, out, err = run_main(capsys, "simulate", path, "--job", job)
    assert code == 2
    assert "np.float64" not in err, err


def test_truncated_binary_on_stdin(streams, tmp_path):
    path = tmp_path / "trunc.bin"
    path.write_bytes(_truncated(streams))
    with open(path, "rb") as fh:
        r = run_exe("simulate", "--job", CIRCLE, "--json", stdin=fh)
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>: the stream ends after 17 records and 16 bytes")


def test_dash_with_empty_stdin_is_an_empty_stream():
    r = run_exe("simulate", "-", "--job", CIRCLE, stdin=subprocess.DEVNULL)
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>: no commands arrived")


@pytest.mark.parametrize("option", [["--accdec", "after"], ["--period", "0.5 ms"], ["--interpolator", "rk4"],
                                    ["--profile-type", "bell"], ["--feedrate", "50"]])
def test_plan_options_with_a_stream_are_a_usage_error(capsys, streams, option):
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, *option)
    assert_one_line_error(code, out, err, option[0], "plans the job itself")
    code, out, err = run_main(capsys, "simulate", "-", "--job", CIRCLE, *option)
    assert_one_line_error(code, out, err, option[0])


def test_plan_options_with_data_on_stdin_are_a_usage_error(capsys, streams, monkeypatch):
    data = (streams / "a.csv").read_bytes()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BufferedReader(io.BytesIO(data))))
    code, out, err = run_main(capsys, "simulate", "--job", CIRCLE, "--accdec", "after")
    assert_one_line_error(code, out, err, "--accdec")


def test_unreadable_commands(capsys, streams, tmp_path):
    code, out, err = run_main(capsys, "simulate", tmp_path / "none.csv", "--job", CIRCLE)
    assert_one_line_error(code, out, err, "none.csv", "cannot read")
    code, out, err = run_main(capsys, "simulate", tmp_path, "--job", CIRCLE)
    assert_one_line_error(code, out, err, "is a directory")
    before = (streams / "a.csv").read_bytes()
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, "-o", streams / "a.csv")
    assert_one_line_error(code, out, err, "refusing to overwrite")
    assert (streams / "a.csv").read_bytes() == before
    job = tmp_path / "job.png"  # a job file may have any name; a picture's extension makes --plot accept it
    job.write_bytes(CIRCLE.read_bytes())
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", job, "--plot", job)
    assert_one_line_error(code, out, err, "refusing to overwrite")
    assert job.read_bytes() == CIRCLE.read_bytes()
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, "--servo", tmp_path / "no.yaml")
    assert_one_line_error(code, out, err, "no.yaml", "cannot read")


def test_columns_in_another_order(capsys, streams, tmp_path, reports):
    """Columns are found by name: a CSV with y before x and a and v swapped reads the same."""
    lines = csv_lines(streams / "a.csv")
    order = [0, 1, 2, 3, 5, 4, 7, 6]
    swapped = tmp_path / "swapped.csv"
    swapped.write_text("".join(",".join(l.rstrip("\n").split(",")[i] for i in order) + "\n" for l in lines[:-1])
                       + lines[-1])  # the end mark as it was
    assert swapped.read_text().startswith("k,n,t,u,y,x,a,v\n")
    assert sim_json(capsys, swapped, "--job", CIRCLE) == reports["a.csv"]


# --------------------------------------------------------------------------- servo files on the command line


def test_servo_file_equal_to_builtin(capsys, streams, reports):
    rep = sim_json(capsys, streams / "a.bin", "--job", CIRCLE, "--servo", PAPER_FILE)
    assert rep.pop("servo") == str(PAPER_FILE)
    expected = dict(reports["a.bin"])
    assert expected.pop("servo") == "built-in paper X-Y table"
    assert rep == expected


def test_three_axis_stream_with_xyz_model(capsys, streams):
    rep = sim_json(capsys, streams / "t3.csv", "--job", TILTED, "--servo", XYZ_FILE)
    assert rep["axes"] == ["x", "y", "z"] and set(rep["tracking_error_max"]) == {"x", "y", "z"}
    assert rep["period"] == 5e-4 and rep["settled"]
    assert 0 < rep["contour_error_max"] < 1.0


def test_bad_servo_file(capsys, streams, tmp_path):
    text = PAPER_FILE.read_text().replace("kp: 40 ", "kp: -40 ", 1)
    assert "kp: -40" in text
    bad = tmp_path / "bad.yaml"
    bad.write_text(text)
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, "--servo", bad)
    assert_one_line_error(code, out, err, str(bad), "axes.x.kp", "> 0")


def test_unstable_servo_file(capsys, streams, tmp_path):
    text = PAPER_FILE.read_text().replace("kp: 70", "kp: 100000", 1)
    bad = tmp_path / "unstable.yaml"
    bad.write_text(text)
    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, "--servo", bad)
    assert_one_line_error(code, out, err, str(bad), "axes.y", "unstable", "T = 0.001 s")


# --------------------------------------------------------------------------- 10. report, trace, plot


def test_json_report_keys(reports):
    rep = reports["a.bin"]
    assert set(rep) == REPORT_KEYS
    assert set(rep["tracking_error_max"]) == {"x", "y"} and set(rep["tracking_error_rms"]) == {"x", "y"}
    for key in ("contour_error_max", "contour_error_rms", "feedrate_error_max", "feedrate_error_rms"):
        assert isinstance(rep[key], float) and rep[key] > 0, key
    assert rep["contour_error_rms"] < rep["contour_error_max"]
    assert rep["job"] == str(CIRCLE) and rep["axes"] == ["x", "y"] and rep["settled"] is True


def test_table_is_the_result_on_stdout(capsys, streams):
    """The report is simulate's result: stdout, like info's table and every --json (issue 12)."""
    code, out, err = run_main(capsys, "simulate", streams / "a.bin", "--job", CIRCLE)
    assert code == 0 and err == ""
    assert "contour error" in out and "tracking error x" in out and "feedrate error" in out


def test_table_goes_to_stderr_when_the_trace_takes_stdout(capsys, streams):
    code, out, err = run_main(capsys, "simulate", streams / "a.bin", "--job", CIRCLE, "-o", "-")
    assert code == 0
    assert out.startswith("k,t,u,x_cmd,y_cmd,x_act,y_act,contour_error,v_cmd,v_act\n")
    assert "contour error" in err and "contour error" not in out


def test_trace_file(capsys, streams, tmp_path, reports):
    trace = tmp_path / "trace.csv"
    code, out, err = run_main(capsys, "simulate", streams / "a.bin", "--job", CIRCLE, "--json", "-o", trace)
    assert code == 0, err
    assert json.loads(out) == reports["a.bin"]
    lines = trace.read_text().splitlines()
    assert lines[0] == TRACE_HEADER
    data = np.loadtxt(lines[1:], delimiter=",")
    rep = reports["a.bin"]
    assert data.shape == (rep["ticks"], 10)
    assert np.array_equal(data[:, 0], np.arange(rep["ticks"]))
    np.testing.assert_allclose(data[:, 1], data[:, 0] * 1e-3, rtol=0, atol=5e-10)
    _, cols, stream = bin_parts(streams / "a.bin")
    n = rep["command_ticks"]
    for a, c in (("x", 3), ("y", 4)):
        np.testing.assert_allclose(data[:n, c], stream[:, cols.index(a)], rtol=0, atol=5e-10)
        np.testing.assert_allclose(data[n:, c], stream[-1, cols.index(a)], rtol=0, atol=5e-10)
        e = data[:, c] - data[:, c + 2]
        assert np.abs(e).max() == pytest.approx(rep["tracking_error_max"][a], abs=1e-9)
    assert data[:, 7].max() == pytest.approx(rep["contour_error_max"], abs=5e-10)
    # the trace's actual path is on the circle to within its reported contour error
    r = np.hypot(data[:, 5] - 50.0, data[:, 6])
    assert np.abs(r - 50.0).max() == pytest.approx(rep["contour_error_max"], abs=1e-9)
    assert np.abs(data[:, 9] - data[:, 8]).max() == pytest.approx(rep["feedrate_error_max"], abs=1e-8)


def test_plot_file(capsys, streams, tmp_path, reports):
    png = tmp_path / "out.png"
    code, out, err = run_main(capsys, "simulate", streams / "a.bin", "--job", CIRCLE, "--json", "--plot", png)
    assert code == 0, err
    assert json.loads(out) == reports["a.bin"]
    raw = png.read_bytes()
    assert raw[:8] == PNG_SIGNATURE
    assert raw[12:16] == b"IHDR"
    width, height = struct.unpack(">II", raw[16:24])
    assert 400 <= width <= 6000 and 300 <= height <= 6000, (width, height)
    assert 20_000 < len(raw) < 20_000_000
    assert [p.name for p in tmp_path.iterdir()] == ["out.png"]


# --------------------------------------------------------------------------- 11. compare


@pytest.fixture(scope="module")
def compare_rows():
    with pytest.raises(SystemExit) as info, _capture() as buf:
        main(["compare", str(CIRCLE), "--json"])
    assert info.value.code == 0
    return json.loads(buf.getvalue())


def test_compare_rows_and_keys(compare_rows):
    rows = compare_rows
    assert len(rows) == 17
    for row in rows:
        assert set(row) == COMPARE_KEYS
    variants = [(r["interpolator"], r["profile"], r["accdec"]) for r in rows]
    shapes = ("trapezoidal", "exponential", "bell")
    expected = [(m, s, "before") for m in ("taylor1", "taylor2", "rk4", "exact") for s in shapes]
    expected += [("taylor2", s, "after") for s in shapes]
    expected += [("taylor2", "adaptive", "before"), ("exact", "adaptive", "before")]  # issue 7's rows
    assert variants == expected


def test_compare_after_always_worse_than_before(compare_rows):
    before = [r["contour_error_max"] for r in compare_rows if r["accdec"] == "before"]
    after = [r["contour_error_max"] for r in compare_rows if r["accdec"] == "after"]
    assert len(before) == 14 and len(after) == 3
    assert min(after) > max(before)
    print(f"\ncompare: before {min(before) * 1e3:.1f}..{max(before) * 1e3:.1f} um, "
          f"after {min(after) * 1e3:.1f}..{max(after) * 1e3:.1f} um")
    # before interpolation the command is on the circle; after it the filter pulls it inside
    for r in compare_rows:
        if r["accdec"] == "before":
            assert r["command_deviation_max"] == 0.0
        else:
            assert r["command_deviation_max"] > 0.5


def test_compare_command_deviation_is_the_distance_from_the_circle(compare_rows):
    """After interpolation the filtered command leaves the circle; its largest distance from it, by
    the closed form | |p − (50, 0)| − 50 | over the planned stream, and near REFERENCE §5's
    moving-average formula r(1 − sin(x)/x), x = ωT1/2 = 0.5, for the trapezoid.
    Regression: 02c88c0 reported 24.27 mm (trapezoidal) and 24.41 mm (bell) (fixed in 1aa3bbb)."""
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.config import load_job
    from nurbsinterp.cli.common import load_cli

    rows = {r["profile"]: r for r in compare_rows if r["accdec"] == "after"}
    for shape, row in rows.items():
        job = load_cli(CIRCLE, overrides={"accdec": "after", "profile_type": shape})
        data = one_curve(np.vstack([c.data for c in Interpolation(job).chunks()]))
        dev = np.abs(np.hypot(data[:, 3] - 50.0, data[:, 4]) - 50.0).max()
        assert row["command_deviation_max"] == pytest.approx(dev, abs=1e-9), shape
    assert rows["trapezoidal"]["command_deviation_max"] == pytest.approx(50 * (1 - math.sin(0.5) / 0.5), abs=1e-4)


def test_compare_agrees_with_simulate(compare_rows, reports, capsys, empty_stdin):
    row = compare_rows[3]  # taylor2 trapezoidal before: the job as it is
    rep = reports["a.bin"]
    assert (row["interpolator"], row["profile"], row["accdec"]) == ("taylor2", "trapezoidal", "before")
    for key in ("contour_error_max", "contour_error_rms", "feedrate_error_max", "feedrate_error_rms"):
        assert row[key] == rep[key], key
    assert row["motion_time"] == pytest.approx(3.642, abs=1e-12)  # L/V + Ta = 3.6416 s, to the next tick
    after = sim_json(capsys, "--plan", "--job", CIRCLE, "--accdec", "after")
    assert compare_rows[12]["contour_error_max"] == after["contour_error_max"]


def test_compare_exponential_has_the_largest_feedrate_error(compare_rows):
    """The paper's Fig. 7 finding (exponential worst), reproduced per interpolator."""
    for method in ("taylor1", "taylor2", "rk4", "exact"):
        fe = {r["profile"]: r["feedrate_error_max"] for r in compare_rows
              if r["interpolator"] == method and r["accdec"] == "before"}
        assert fe["exponential"] > max(fe["trapezoidal"], fe["bell"]), (method, fe)


@pytest.mark.parametrize("option, value", [("--profile", str(CIRCLE)), ("--feedrate", "10"), ("--period", "2ms"),
                                           ("--machine", str(ROOT / "examples" / "linuxcnc" / "mill.ini"))])
def test_a_planning_option_beside_a_stream_is_named_as_typed(capsys, streams, option, value):
    """A planning option given with a stream already planned is refused naming that option as the user typed it
    (the refusal once named `--profile` `--profile-file`, an option no command has)."""
    import click

    from nurbsinterp.cli import cli

    code, out, err = run_main(capsys, "simulate", streams / "a.csv", "--job", CIRCLE, option, value)
    assert_one_line_error(code, out, err, f"{option} applies only when simulate plans the job itself (--plan)")
    command = cli.get_command(click.Context(cli), "simulate")
    flags = {flag for param in command.params for flag in getattr(param, "opts", ())}
    assert option in flags


# --------------------------------------------------------------------------- cutting moves and rapids apart

RAPIDS_PROGRAM = """\
G21 G90 G17
G0 Z5
G0 X40 Y30
G0 Z0.5
G1 Z-1 F300
G1 X60 F900
G2 X70 Y40 I0 J10
G1 Y55
G0 Z5
G0 X0 Y0
M2
"""


@pytest.mark.parametrize("tolerance", [None, "10um"])
def test_the_headline_errors_are_the_cutting_moves_and_the_rapids_are_apart(tmp_path, capsys, tolerance):
    """Issue 49, defect 6: a program's rapids (here long G0 traverses) lag far more than its cuts; the report's
    headline is the cutting ticks' and the rapids' stand apart.  Brute force over the trace: every tick whose
    command is on a G0 block (the stream's rapid column; the hold takes the last command's kind) counts for the
    rapids, every other one for the cutting moves, and each maximum, RMS and tick count is theirs."""
    prog = tmp_path / "p.ngc"
    prog.write_text(RAPIDS_PROGRAM)
    look = [] if tolerance is None else ["--tolerance", tolerance]
    code, _, err = run_main(capsys, "plan", prog, "-q", "-o", tmp_path / "s.csv", *look)
    assert code == 0, err
    code, out, err = run_main(capsys, "simulate", tmp_path / "s.csv", "--job", prog, "--servo", XYZ_FILE, "--json",
                              "-o", tmp_path / "trace.csv", *look)
    assert code == 0, err
    doc = json.loads(out)
    stream = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)
    header = (tmp_path / "s.csv").read_text().splitlines()[0].split(",")
    rapid = stream[:, header.index("rapid")] > 0.5
    trace = np.loadtxt(tmp_path / "trace.csv", delimiter=",", skiprows=1)
    cols = (tmp_path / "trace.csv").read_text().splitlines()[0].split(",")
    kinds = np.concatenate([rapid, np.full(trace.shape[0] - rapid.shape[0], rapid[-1])])  # the hold: the last's
    ce = trace[:, cols.index("contour_error")]
    fe = trace[:, cols.index("v_act")] - trace[:, cols.index("v_cmd")]
    assert 0 < kinds.sum() < kinds.shape[0]
    assert (doc["cutting_ticks"], doc["rapid_ticks"]) == (int((~kinds).sum()), int(kinds.sum()))
    for report, mask in ((doc, ~kinds), (doc["rapids"], kinds)):
        # (the trace's CSV carries 9 decimals: 5e-10 mm of rounding)
        assert report["contour_error_max"] == pytest.approx(ce[mask].max(), abs=1e-9, rel=0)
        assert report["contour_error_rms"] == pytest.approx(math.sqrt(np.mean(ce[mask] ** 2)), abs=1e-9, rel=0)
        assert report["feedrate_error_max"] == pytest.approx(np.abs(fe[mask]).max(), abs=1e-8, rel=0)
        for a in ("x", "y", "z"):
            e = trace[:, cols.index(f"{a}_cmd")] - trace[:, cols.index(f"{a}_act")]
            assert report["tracking_error_max"][a] == pytest.approx(np.abs(e[mask]).max(), abs=1e-9, rel=0)
    assert doc["rapids"]["tracking_error_max"]["x"] > 3 * doc["tracking_error_max"]["x"]  # the case is a real one
    code, out, err = run_main(capsys, "simulate", tmp_path / "s.csv", "--job", prog, "--servo", XYZ_FILE, *look)
    assert code == 0, err
    assert f"over the {doc['cutting_ticks']} ticks of cutting moves" in " ".join(out.split())
    assert f"rapids (G0) {doc['rapid_ticks']} ticks, apart: contour error max" in " ".join(out.split())


def test_a_job_without_rapids_reports_as_before(capsys):
    code, out, err = run_main(capsys, "simulate", "--plan", "--job", CIRCLE, "--json")
    assert code == 0, err
    doc = json.loads(out)
    assert "rapids" not in doc and doc["rapid_ticks"] == 0 and doc["cutting_ticks"] == doc["ticks"]
