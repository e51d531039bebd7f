"""`plan --format hal` and `--columns`: the lines LinuxCNC's halstreamer reads.

A HAL line is the CSV row's values (the same formatter, the same text) separated by one space, with
no header; the columns default to the axes.  Integer columns (k, n, rapid, *_counts) are printed as
integers for s32 pins (the rapid flag for a bit), within the s32 range.  No timing assertions.
"""
from __future__ import annotations

import io
import os
import re
import sys
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.errors import UsageError
from nurbsinterp.streams import StreamWriter, hal_pin_types, read_stream
from clirun import assert_quiet_close, plan_into_head, run_plan as cli, without_end_mark

ROOT = Path(__file__).resolve().parent.parent
CURVES = ROOT / "curves"
CIRCLE = str(CURVES / "circle.yaml")
TILTED = str(CURVES / "tilted-circle-3d.yaml")
PATH3D = str(CURVES / "path-3d.yaml")
POCKET = str(CURVES / "pocket.ngc")
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test
S32_MAX = 2 ** 31 - 1
INTEGER = re.compile(r"^(0|-?[1-9][0-9]*)$")  # no '.', no leading zero, no '-0'
DECIMAL = re.compile(r"^-?(0|[1-9][0-9]*)(\.[0-9]*[1-9])?$")  # what strtod reads whole; no exponent, no '-0'

needs_exe = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")



def ok(capsysbinary, *args):
    code, out, err = cli(capsysbinary, *args)
    assert code == 0, err
    return out, err


def hal_rows(out: bytes) -> list[list[str]]:
    """The lines of a HAL stream, split on single spaces, after checking the layout."""
    text = out.decode("ascii")
    assert text.endswith("\n") and "\r" not in text and "\t" not in text
    lines = text[:-1].split("\n")
    for line in lines:
        assert line and not line.startswith(" ") and not line.endswith(" ") and "  " not in line, repr(line)
    return [line.split(" ") for line in lines]


def csv_table(out: bytes) -> tuple[list[str], list[list[str]]]:
    lines = without_end_mark(out).decode("ascii").splitlines()
    return lines[0].split(","), [line.split(",") for line in lines[1:]]


def one_line_error(code, out, err, *parts):
    assert code == 2 and out == b"", (code, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("nurbsinterp") and "Traceback" not in err, err
    for part in parts:
        assert part in lines[0], (part, err)


# =========================================================================== default columns: the axes

@pytest.mark.parametrize("job,axes", [(CIRCLE, ["x", "y"]), (TILTED, ["x", "y", "z"]), (PATH3D, ["x", "y", "z"])],
                         ids=["circle", "tilted-3d", "path-3d"])
@pytest.mark.parametrize("resolution", [None, "0.5um"])
def test_hal_default_columns_are_the_axes_text_for_text(capsysbinary, job, axes, resolution):
    extra = [] if resolution is None else ["--resolution", resolution]
    hal, err = ok(capsysbinary, job, "--format", "hal", *extra)
    csv, _ = ok(capsysbinary, job, "-q", *extra)
    names, table = csv_table(csv)
    rows = hal_rows(hal)
    assert len(rows) == len(table)
    assert not any(t in names for t in rows[0]) and hal.split(b"\n", 1)[0].decode() != ",".join(names)
    cols = [names.index(a) for a in axes]
    for hal_row, csv_row in zip(rows, table):
        assert hal_row == [csv_row[j] for j in cols]  # the CSV's own text, 9 decimals
        for token in hal_row:
            assert DECIMAL.match(token), token
            float(token)  # strtod reads it
    # the values are the stream's to the printed 9 decimals
    data = np.array([[float(t) for t in r] for r in rows])
    full = np.array([[float(t) for t in r] for r in table])
    assert np.array_equal(data, full[:, cols])
    line = next(x for x in err.splitlines() if x.strip().startswith("HAL"))
    assert f"{' '.join(axes)}:" in line and f"cfg={'f' * len(axes)} " in line


# =========================================================================== --columns

def test_hal_columns_order_and_integer_columns(capsysbinary):
    hal, err = ok(capsysbinary, CIRCLE, "--format", "hal", "--columns", "k,n,x,y,v", "--period", "0.1 ms")
    csv, _ = ok(capsysbinary, CIRCLE, "-q", "--period", "0.1 ms")
    names, table = csv_table(csv)
    rows = hal_rows(hal)
    want = ["k", "n", "x", "y", "v"]
    assert [r for r in rows] == [[row[names.index(c)] for c in want] for row in table]
    for r, row in enumerate(rows):
        assert row[0] == str(r) and INTEGER.match(row[1]), row
    assert "cfg=ssfff " in err and "k n x y v:" in err
    # the period of the thread it names: 0.1 ms
    assert "period 100000 ns" in err


def test_hal_counts_are_integers_without_minus_zero(capsysbinary):
    """Counts (the circle ends slightly below y = 0: negative counts and zeros on both sides)."""
    hal, err = ok(capsysbinary, CIRCLE, "--format", "hal", "--resolution", "0.5um", "--counts",
                  "--columns", "k,x,y_counts,n")  # an axis by either name
    rows = hal_rows(hal)
    assert all(len(r) == 4 for r in rows)
    ys = [r[2] for r in rows]
    assert any(y.startswith("-") for y in ys) and "0" in ys
    for row in rows:
        for token in (row[0], row[1], row[2], row[3]):
            assert INTEGER.match(token), row
    assert "cfg=ssss " in err and "k x_counts y_counts n:" in err


def test_minus_zero_and_integer_formatting_in_the_writer():
    fh = io.BytesIO()
    w = StreamWriter(fh, ["k", "n", "x_counts", "x", "rapid"], "hal")
    w.write(np.array([[0.0, 0.0, -0.0, -0.0, 0.0],
                      [1.0, 10.0, -10.0, -1e-10, 1.0],
                      [S32_MAX, 7.0, -S32_MAX, 0.1 + 0.2, 0.0]]))
    assert fh.getvalue() == (b"0 0 0 0 0\n"
                             b"1 10 -10 0 1\n"
                             b"2147483647 7 -2147483647 0.3 0\n")


def test_hal_pin_types():
    assert hal_pin_types(["k", "n", "t", "u", "x", "y", "v", "a", "rapid"]) == "ssffffffb"
    assert hal_pin_types(["x_counts", "y_counts", "z", "rapid", "k"]) == "ssfbs"
    assert hal_pin_types(["x", "y"]) == "ff"


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_columns_for_csv_and_bin(capsysbinary, tmp_path, fmt):
    full_path, part_path = tmp_path / f"full.{fmt}", tmp_path / f"part.{fmt}"
    ok(capsysbinary, CIRCLE, "-q", "--format", fmt, "-o", full_path)
    ok(capsysbinary, CIRCLE, "-q", "--format", fmt, "--columns", "y,k,v", "-o", part_path)
    if fmt == "csv":
        names, table = csv_table(full_path.read_bytes())
        part_names, part = csv_table(part_path.read_bytes())
        assert part_names == ["y", "k", "v"]
        assert part == [[row[names.index(c)] for c in part_names] for row in table]
    else:
        head = part_path.read_bytes().split(b"\n", 1)[0].split()
        assert head[:3] == [b"nurbsinterp-bin", b"2", b"y,k,v"] and head[3].startswith(b"curve=")
        with open(full_path, "rb") as fh:
            names, chunks = read_stream(fh, str(full_path))
            full = np.vstack(list(chunks))
        body = without_end_mark(part_path.read_bytes()).partition(b"\n")[2]
        part = np.frombuffer(body, "<f8").reshape(-1, 3)
        assert np.array_equal(part, full[:, [names.index(c) for c in ("y", "k", "v")]])  # bit for bit


def test_columns_with_counts_in_csv(capsysbinary):
    out, _ = ok(capsysbinary, CIRCLE, "-q", "--resolution", "1um", "--counts", "--columns", "k,x,y_counts")
    names, table = csv_table(out)
    assert names == ["k", "x_counts", "y_counts"]
    assert all(INTEGER.match(v) for row in table for v in row)


@pytest.mark.parametrize("fmt", ["csv", "bin", "hal"])
@pytest.mark.parametrize("columns,words", [
    ("k,q", ["'q'", "is not a column"]),
    ("k,x,k", ["'k'", "twice"]),
    ("z", ["'z'"]),  # a 2-D job
    ("x,,y", ["''"]),
    ("rapid", ["'rapid'"]),  # the circle has no rapids
])
def test_bad_columns_exit_2_with_one_line(capsysbinary, fmt, columns, words):
    code, out, err = cli(capsysbinary, CIRCLE, "--format", fmt, "--columns", columns)
    one_line_error(code, out, err, "--columns", *words)


def test_counts_and_plain_name_of_one_axis_twice(capsysbinary):
    code, out, err = cli(capsysbinary, CIRCLE, "--format", "hal", "--resolution", "1um", "--counts",
                         "--columns", "x,x_counts")
    one_line_error(code, out, err, "--columns", "twice")
    code, out, err = cli(capsysbinary, CIRCLE, "--columns", "x_counts")  # no --counts: no such column
    one_line_error(code, out, err, "--columns", "'x_counts'")


def test_gcode_rapids_as_bits(capsysbinary):
    hal, err = ok(capsysbinary, POCKET, "--format", "hal", "--columns", "k,rapid,x,y")
    csv, _ = ok(capsysbinary, POCKET, "-q")
    names, table = csv_table(csv)
    rows = hal_rows(hal)
    assert rows == [[row[names.index(c)] for c in ("k", "rapid", "x", "y")] for row in table]
    flags = [r[1] for r in rows]
    assert set(flags) == {"0", "1"}
    line = next(x for x in err.splitlines() if x.strip().startswith("HAL"))
    assert "k rapid x y:" in line and "cfg=sbff " in line


# =========================================================================== the s32 range

@pytest.mark.parametrize("column", ["x_counts", "k", "n"])
@pytest.mark.parametrize("value", [2 ** 31, -(2 ** 31) - 1, 2 ** 40])
def test_s32_range_is_refused_naming_tick_and_column(column, value):
    names = ["k", "n", "x_counts", "v"]
    data = np.array([[5.0, 0.0, 1.0, 2.0], [6.0, 0.0, 1.0, 2.0], [7.0, 0.0, 1.0, 2.0]])
    j = names.index(column)
    data[1, j] = value
    fh = io.BytesIO()
    w = StreamWriter(fh, names, "hal")
    with pytest.raises(UsageError) as info:
        w.write(data)
    msg = str(info.value)
    tick = value if column == "k" else 6
    assert f"tick k = {tick}" in msg and f"{column} = {value}" in msg and "s32" in msg, msg
    assert fh.getvalue() == b""  # nothing of the refused chunk


def test_s32_limits_pass_and_the_tick_is_named_when_k_is_not_written():
    fh = io.BytesIO()
    w = StreamWriter(fh, ["k", "x_counts", "y"], "hal", select=[1, 2])
    w.write(np.array([[0.0, S32_MAX, 3e9], [1.0, -S32_MAX - 1, -3e9]]))  # a float column may go beyond
    assert fh.getvalue() == b"2147483647 3000000000\n-2147483648 -3000000000\n"
    with pytest.raises(UsageError, match=r"tick k = 2: x_counts = 2147483648 "):
        w.write(np.array([[2.0, S32_MAX + 1, 0.0]]))
    assert fh.getvalue().count(b"\n") == 2
    # the same counts in CSV and bin carry no s32 limit
    for fmt in ("csv", "bin"):
        StreamWriter(io.BytesIO(), ["k", "x_counts"], fmt).write(np.array([[0.0, 2.0 ** 40]]))


# =========================================================================== -o and pipes

def big_line_job(tmp_path) -> Path:
    """A 3 m line at 1 m/s, T = 10 us: 300 k ticks; at 1 nm, x passes 2**31 counts after ~215 k ticks (chunk 4)."""
    job = tmp_path / "long-line.yaml"
    job.write_text("path:\n  start: [0, 0]\n  blocks:\n    - line: {to: [3000, 0]}\n"
                   "profile:\n  type: trapezoidal\n  feedrate: 1000 mm/s\n  accel_time: 0.1 s\n"
                   "interpolator:\n  period: 10 us\n")
    return job


def test_hal_output_file_is_atomic_when_refused(capsysbinary, tmp_path):
    job = big_line_job(tmp_path)
    target = tmp_path / "run.hal"
    target.write_bytes(b"old\n")
    code, out, err = cli(capsysbinary, job, "--format", "hal", "--resolution", "1nm", "--counts", "-o", target)
    one_line_error(code, out, err, "x_counts", "tick k = ", "s32")
    k = int(re.search(r"tick k = (\d+)", err).group(1))
    assert k > 3 * 65536  # chunks were written before the refusal: the file must still not have them
    assert target.read_bytes() == b"old\n"
    assert sorted(os.listdir(tmp_path)) == ["long-line.yaml", "run.hal"]
    # a coarser count fits: the file is written whole
    code, out, err = cli(capsysbinary, job, "-q", "--format", "hal", "--resolution", "1um", "--counts", "-o", target)
    assert code == 0 and out == b"", err
    rows = hal_rows(target.read_bytes())
    assert rows[0] == ["0", "0"] and rows[-1] == ["3000000", "0"]
    assert sorted(os.listdir(tmp_path)) == ["long-line.yaml", "run.hal"]


@needs_exe
def test_hal_into_a_closed_pipe_is_quiet(tmp_path):
    """`plan --format hal ... | head -1`: no traceback, no error message, exit 141 (or 0)."""
    # 36 k lines (~0.7 MB): far more than a pipe buffer, so the writer really meets the closed pipe
    code, out, err = plan_into_head(EXE, f'"{CIRCLE}" --period "100 us" --format hal --resolution 0.5um '
                                         '--columns k,x,y', tmp_path / "plan.err", HANG_S)
    assert out == "0 0 0\n"
    assert_quiet_close(code, err)
