"""A command stream tells its reader that it is whole (issue 27, item 2: no silent substitution).

`plan` and `precompensate` end a CSV or binary stream with an end mark (``nurbsinterp-end
ticks=N curve=...``) written only once every tick is; every reader refuses, in one line, a
stream that ends without it (cut anywhere: at a record or line boundary, inside one, inside
the header; a `plan` killed by SIGTERM) or whose mark disagrees with what was read.  An empty
stream is no stream: ``true | simulate --job J`` is an error, and `simulate` plans the job itself
only when asked plainly (--plan, or stdin a terminal), saying so.
"""
from __future__ import annotations

import io
import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from nurbsinterp.cli import main
from nurbsinterp.errors import StreamError
from nurbsinterp.streams import BIN_END_BYTES, StreamWriter, read_stream
from clirun import assert_one_line_error

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = ROOT / "curves" / "circle.yaml"
SQUARE = ROOT / "curves" / "square.yaml"
PAPER = ROOT / "servo" / "paper-xy.yaml"
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one subprocess, not a speed test
COLUMNS = ["k", "t", "u", "x", "y", "v", "a"]


def run_main(capsysbinary, *args):
    """nurbsinterp.cli.main in-process: (exit code, stdout bytes, stderr bytes)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsysbinary.readouterr()
    return (info.value.code or 0), out, err


def bash(script: str) -> subprocess.CompletedProcess:
    """*script* in bash, without pipefail (a pipeline's status is its last command's), nurbsinterp on PATH."""
    if shutil.which("bash") is None:
        pytest.skip("no bash")
    env = {**os.environ, "PATH": f"{EXE.parent}{os.pathsep}{os.environ.get('PATH', '')}"}
    return subprocess.run(["bash", "-c", script], capture_output=True, timeout=HANG_S, cwd=ROOT, env=env)


@pytest.fixture(scope="module")
def planned(tmp_path_factory):
    """The circle planned once, as `plan -o` writes it: c.csv, c.bin; and pre-compensated: p.csv, p.bin."""
    d = tmp_path_factory.mktemp("complete")
    for fmt in ("csv", "bin"):
        with pytest.raises(SystemExit) as info:
            main(["plan", str(CIRCLE), "--format", fmt, "-q", "-o", str(d / f"c.{fmt}")])
        assert info.value.code == 0
        with pytest.raises(SystemExit) as info:
            main(["precompensate", str(d / f"c.{fmt}"), "--servo", str(PAPER), "-q", "-o", str(d / f"p.{fmt}")])
        assert info.value.code == 0
    return d


def small_stream(fmt: str, rows: int = 12, fingerprint: str | None = "0123456789abcdef") -> bytes:
    """A whole stream of *rows* ticks, written in two pieces as plan writes chunks."""
    data = np.zeros((rows, len(COLUMNS)))
    data[:, 0] = np.arange(rows)
    data[:, 1] = np.arange(rows) * 1e-3
    data[:, 3] = np.linspace(0.0, 1.0, rows)
    fh = io.BytesIO()
    writer = StreamWriter(fh, COLUMNS, fmt, fingerprint=fingerprint)
    writer.write(data[:rows // 2])
    writer.write(data[rows // 2:])
    writer.finish()
    return fh.getvalue()


def read_all(raw: bytes, chunk_rows: int = 1 << 16, meta: dict | None = None) -> np.ndarray:
    columns, chunks = read_stream(io.BytesIO(raw), "s", chunk_rows=chunk_rows, meta=meta)
    pieces = list(chunks)
    return np.vstack(pieces) if pieces else np.empty((0, len(columns)))


# --------------------------------------------------------------------------- the mark and its readers


def test_the_marks_as_documented(planned):
    """CSV: the last line `# nurbsinterp-end ticks=N curve=F`; binary: its last 64 bytes, padded text."""
    csv = (planned / "c.csv").read_bytes()
    last = csv.splitlines()[-1].decode()
    assert last.startswith("# nurbsinterp-end ticks=3643 curve=") and len(last.split("curve=")[1]) == 16
    raw = (planned / "c.bin").read_bytes()
    head = raw.partition(b"\n")[0].split()
    assert head[:2] == [b"nurbsinterp-bin", b"2"]
    tail = raw[-BIN_END_BYTES:]
    assert tail.endswith(b"\n") and tail.split() == [b"nurbsinterp-end", b"ticks=3643", head[3]]
    assert last.split()[-1].encode() == head[3]  # the same fingerprint in both formats
    assert (planned / "p.csv").read_bytes().splitlines()[-1].endswith(b" precompensated=exact")


def test_ordinary_tools_read_the_streams(planned):
    """numpy.loadtxt (its comment character skips the CSV mark) and README's one line of NumPy for binary."""
    ours = read_all((planned / "c.bin").read_bytes())
    text = np.loadtxt(planned / "c.csv", delimiter=",", skiprows=1)
    assert text.shape == ours.shape
    assert np.abs(text - ours).max() <= 5e-10 * (1 + np.abs(ours).max())  # 9 decimals (u: 15)
    readme = (ROOT / "README.md").read_text()
    line = next(s for s in readme.splitlines() if s.startswith("import numpy as np; head, _, body"))
    scope = {}
    exec(line.replace('"run.bin"', repr(str(planned / "c.bin"))), scope)
    assert np.array_equal(scope["data"], ours)


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_every_cut_of_a_small_stream_is_refused(fmt):
    """Brute force: every proper prefix of a whole stream (at a line or record boundary, inside one,
    inside the header or the mark) is refused, in one line naming the stream."""
    raw = small_stream(fmt)
    assert read_all(raw).shape == (12, len(COLUMNS))
    for cut in range(len(raw)):
        with pytest.raises(StreamError) as info:
            read_all(raw[:cut], chunk_rows=5)
        message = str(info.value)
        assert message.startswith("s: ") and "\n" not in message, (cut, message)
        if cut:
            assert "incomplete" in message or "truncated" in message, (cut, message)
        else:
            assert "no commands arrived" in message and "upstream may have failed" in message


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 1.0, exclude_max=True), fmt=st.sampled_from(["csv", "bin"]),
       chunk_rows=st.sampled_from([7, 1000, 1 << 16]))
def test_a_real_stream_cut_at_a_random_byte_is_refused(planned, fraction, fmt, chunk_rows):
    raw = (planned / f"c.{fmt}").read_bytes()
    cut = int(fraction * len(raw))
    with pytest.raises(StreamError, match=r"^s: .*(incomplete|truncated|no commands arrived)"):
        read_all(raw[:cut], chunk_rows=chunk_rows)


def test_the_boundary_cuts_of_a_real_stream(planned):
    """The cuts the issue saw: 1000 of the circle's 3643 ticks, at a line and at a record boundary."""
    csv = (planned / "c.csv").read_bytes()
    lines = csv.splitlines(keepends=True)
    with pytest.raises(StreamError, match=r"ends after line 1001 without its end mark.*incomplete"):
        read_all(b"".join(lines[:1001]))
    raw = (planned / "c.bin").read_bytes()
    header = raw.index(b"\n") + 1
    record = 8 * len(raw[:header].split()[2].split(b","))
    with pytest.raises(StreamError, match=r"ends after 1000 records without its end mark"):
        read_all(raw[:header + 1000 * record])
    with pytest.raises(StreamError, match=r"ends after 1000 records and 3 bytes without"):
        read_all(raw[:header + 1000 * record + 3])
    with pytest.raises(StreamError, match=r"ends inside its header line"):
        read_all(raw[:header - 5])


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_a_mark_that_disagrees_is_refused(fmt):
    raw = small_stream(fmt)
    if fmt == "csv":
        lied = raw.replace(b"ticks=12", b"ticks=11")
        extra = raw + b"12,0.012,0,1,0,0,0\n"
        joined = raw + raw  # two whole streams one after the other
    else:
        lied = raw[:-BIN_END_BYTES] + raw[-BIN_END_BYTES:].replace(b"ticks=12", b"ticks=13")
        extra = raw[:-BIN_END_BYTES] + raw[-BIN_END_BYTES:].replace(b"0123456789abcdef", b"fedcba9876543210")
        joined = raw + raw
    with pytest.raises(StreamError, match=r"end mark says ticks=1[13] but the stream has 12"):
        read_all(lied)
    with pytest.raises(StreamError, match=r"followed by more lines|not the header's curve"):
        read_all(extra)
    with pytest.raises(StreamError):
        read_all(joined)


def test_the_csv_mark_carries_what_the_binary_header_does():
    """The curve (and precompensated=) reach *meta* from a CSV stream's mark once it is read."""
    fh = io.BytesIO()
    writer = StreamWriter(fh, COLUMNS, "csv", fingerprint="00000000000000aa", meta={"precompensated": "zpetc"})
    writer.write(np.zeros((1, len(COLUMNS))))
    writer.finish()
    meta = {}
    assert read_all(fh.getvalue(), meta=meta).shape == (1, len(COLUMNS))
    assert meta == {"curve": "00000000000000aa", "precompensated": "zpetc"}


def test_a_version_1_binary_stream_is_refused():
    raw = b"nurbsinterp-bin 1 k,t,u,x,y,v,a curve=0123456789abcdef\n" + np.zeros(7).tobytes()
    with pytest.raises(StreamError, match=r"version 1 binary stream has no end mark.*plan it again"):
        read_all(raw)


def test_hal_lines_have_no_mark(capsysbinary):
    """halstreamer takes every line for a tick: HAL output is numbers only (and nothing reads it back)."""
    code, out, err = run_main(capsysbinary, "plan", SQUARE, "--format", "hal", "-q")
    assert code == 0
    lines = out.decode().splitlines()
    assert all(len(line.split()) == 2 for line in lines) and "nurbsinterp-end" not in out.decode()


@pytest.mark.parametrize("extra", [["--columns", "x,y"], ["--columns", "k,x,y,v"], ["--resolution", "1um"],
                                   ["--resolution", "2000/mm", "--counts"]])
@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_subsets_and_resolutions_keep_the_mark(capsysbinary, fmt, extra):
    code, out, err = run_main(capsysbinary, "plan", SQUARE, "--format", fmt, "-q", *extra)
    assert code == 0, err
    head, _, body = out.partition(b"\n")
    if fmt == "csv":
        *rows, mark = body.splitlines()
        ncols = len(head.split(b","))
        assert all(len(r.split(b",")) == ncols for r in rows)
    else:
        ncols = len(head.split()[2].split(b","))
        mark = body[-BIN_END_BYTES:]
        rows = range((len(body) - BIN_END_BYTES) // (8 * ncols))
        assert (len(body) - BIN_END_BYTES) % (8 * ncols) == 0
    fields = mark.decode().lstrip("# ").split()
    assert fields[0] == "nurbsinterp-end" and fields[1] == f"ticks={len(rows)}" and fields[2].startswith("curve=")


# --------------------------------------------------------------------------- the command line


def test_an_empty_pipe_is_refused():
    """`true | nurbsinterp simulate --job curves/circle.yaml`: exit 2, one line; the same with `-` and a file."""
    r = bash("true | nurbsinterp simulate --job curves/circle.yaml")
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>", "no commands arrived",
                          "upstream may have failed")
    r = bash("true | nurbsinterp precompensate --servo servo/paper-xy.yaml")
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>", "no commands arrived")


def test_an_empty_file_is_refused(capsysbinary, tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_bytes(b"")
    code, out, err = run_main(capsysbinary, "simulate", empty, "--job", CIRCLE)
    assert_one_line_error(code, out, err, "empty.csv", "no commands arrived")
    code, out, err = run_main(capsysbinary, "precompensate", empty, "--servo", PAPER, "-o", tmp_path / "o.csv")
    assert_one_line_error(code, out, err, "empty.csv", "no commands arrived")
    assert not (tmp_path / "o.csv").exists()


def test_a_failed_plan_fails_the_pipeline():
    """The issue's typo: plan exits 2, and simulate must not plan the job itself in its place."""
    r = bash("nurbsinterp plan curves/circle.yaml --interpolatr exact | nurbsinterp simulate --job curves/circle.yaml")
    assert r.returncode == 2, r.stderr
    assert r.stdout == b""
    assert "no commands arrived" in r.stderr.decode()


def test_a_failed_precompensate_fails_the_readme_pipeline(tmp_path):
    """README's pre-compensation pipeline with precompensate failing (a servo file that does not exist)."""
    r = bash("nurbsinterp plan curves/circle.yaml -q | nurbsinterp precompensate --servo servo/no-such.yaml "
             "| nurbsinterp simulate --job curves/circle.yaml")
    assert r.returncode == 2 and r.stdout == b"", r.stderr


def test_a_precompensate_killed_midway_fails_the_pipeline(planned, tmp_path):
    """precompensate's output stops without its mark when its input does: simulate refuses it."""
    cut = tmp_path / "cut.bin"
    raw = (planned / "c.bin").read_bytes()
    cut.write_bytes(raw[:len(raw) // 2])
    r = bash(f"nurbsinterp precompensate '{cut}' --servo servo/paper-xy.yaml -q "
             "| nurbsinterp simulate --job curves/circle.yaml")
    assert r.returncode == 2 and r.stdout == b"", r.stderr
    said = r.stderr.decode().splitlines()
    assert "cut.bin: the stream ends after 1821 records" in said[0] and "without its end mark" in said[0]
    assert "<stdin>:" in said[1]  # simulate refuses what precompensate left it (here nothing: one chunk)


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_precompensate_refuses_a_cut_input_and_leaves_no_file(capsysbinary, planned, tmp_path, fmt):
    raw = (planned / f"c.{fmt}").read_bytes()
    lines = raw.splitlines(keepends=True)
    cut = tmp_path / f"cut.{fmt}"
    cut.write_bytes(b"".join(lines[:-1]) if fmt == "csv" else raw[:-BIN_END_BYTES])  # only the mark missing
    out_path = tmp_path / f"o.{fmt}"
    code, out, err = run_main(capsysbinary, "precompensate", cut, "--servo", PAPER, "-q", "-o", out_path)
    assert_one_line_error(code, out, err, f"cut.{fmt}", "without its end mark")
    assert not out_path.exists()


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_precompensate_passes_a_whole_stream_on_whole(planned, fmt):
    """Every tick, then the settle rows (the end held while the shaping settles), the same curve in the mark;
    simulate takes it and names it pre-compensated."""
    meta_in, meta_out = {}, {}
    planned_rows = read_all((planned / f"c.{fmt}").read_bytes(), meta=meta_in)
    shaped_rows = read_all((planned / f"p.{fmt}").read_bytes(), meta=meta_out)
    assert shaped_rows.shape[0] > planned_rows.shape[0] and shaped_rows.shape[1] == planned_rows.shape[1]
    assert meta_out == {**meta_in, "precompensated": "exact"}


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_simulate_refuses_a_stream_cut_at_a_boundary(capsysbinary, planned, tmp_path, fmt):
    raw = (planned / f"c.{fmt}").read_bytes()
    if fmt == "csv":
        cut = b"".join(raw.splitlines(keepends=True)[:1001])  # header and 1000 ticks, the last at full speed
    else:
        header = raw.index(b"\n") + 1
        cut = raw[:header + 1000 * 8 * len(raw[:header].split()[2].split(b","))]
    path = tmp_path / f"cut.{fmt}"
    path.write_bytes(cut)
    trace = tmp_path / "trace.csv"
    code, out, err = run_main(capsysbinary, "simulate", path, "--job", CIRCLE, "-o", trace)
    assert_one_line_error(code, out, err, f"cut.{fmt}", "without its end mark", "incomplete")
    assert not trace.exists()


def test_simulate_refuses_a_csv_stream_whose_mark_names_another_curve(capsysbinary, planned, tmp_path):
    raw = (planned / "c.csv").read_bytes()
    body, mark = raw[:raw.rindex(b"curve=") + 6], raw[raw.rindex(b"curve=") + 6:]
    other = tmp_path / "other.csv"
    other.write_bytes(body + b"f" * 16 + mark[16:])
    code, out, err = run_main(capsysbinary, "simulate", other, "--job", CIRCLE)
    assert_one_line_error(code, out, err, "other.csv", "planned from another curve", "ffffffffffffffff")
    code, out, err = run_main(capsysbinary, "simulate", other, "--job", CIRCLE, "--force", "--json")
    assert code == 0, err


@pytest.mark.parametrize("fmt", ["csv", "bin"])
def test_a_plan_killed_by_sigterm_is_refused(tmp_path, fmt):
    """A real `plan` of 3.64 M ticks (the circle at T = 1 us) killed by SIGTERM once it has written 1 MB."""
    plan = subprocess.Popen([str(EXE), "plan", str(CIRCLE), "--period", "1us", "--format", fmt, "-q"],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    try:
        got = plan.stdout.read(1 << 20)
        plan.send_signal(signal.SIGTERM)
        got += plan.stdout.read()
    finally:
        plan.stdout.close()
        status = plan.wait(timeout=HANG_S)
    assert status in (-signal.SIGTERM, 128 + signal.SIGTERM) and len(got) >= 1 << 20
    with pytest.raises(StreamError, match=r"without its end mark.*incomplete|truncated"):
        read_all(got)
    path = tmp_path / f"killed.{fmt}"
    path.write_bytes(got)
    r = subprocess.run([str(EXE), "simulate", "--job", str(CIRCLE)], stdin=open(path, "rb"), capture_output=True,
                       timeout=HANG_S)
    assert_one_line_error(r.returncode, r.stdout, r.stderr, "<stdin>", "end mark")


def test_simulate_plans_the_job_itself_only_when_asked(capsysbinary, planned):
    """--plan: planned here, said on stderr, the same report as the planned stream's."""
    code, out, err = run_main(capsysbinary, "simulate", "--plan", "--job", CIRCLE, "--json")
    assert code == 0, err
    assert err.decode() == f"nurbsinterp: simulate planned {CIRCLE} itself (--plan): no stream was read\n"
    here = json.loads(out)
    code, out, err = run_main(capsysbinary, "simulate", planned / "c.bin", "--job", CIRCLE, "--json")
    assert code == 0 and err == b""
    assert json.loads(out) == here
    code, out, err = run_main(capsysbinary, "simulate", planned / "c.bin", "--plan", "--job", CIRCLE)
    assert_one_line_error(code, out, err, "--plan", "no COMMANDS")


def test_a_terminal_on_stdin_plans_the_job_itself():
    """No COMMANDS and stdin a terminal (a pseudo-terminal here): planned here, and said so."""
    pty = pytest.importorskip("pty")
    leader, follower = pty.openpty()
    try:
        r = subprocess.run([str(EXE), "simulate", "--job", str(CIRCLE), "--json"], stdin=follower,
                           capture_output=True, timeout=HANG_S)
    finally:
        os.close(follower)
        os.close(leader)
    assert r.returncode == 0, r.stderr
    assert "stdin is a terminal" in r.stderr.decode()
    assert json.loads(r.stdout)["command_ticks"] == 3643
