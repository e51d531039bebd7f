"""The command line run in-process, into a closed pipe, and the shape every refusal must have: shared by the
CLI tests."""
import shutil
import subprocess

import pytest

from nurbsinterp.cli import main


def run_plan(capsysbinary, *args):
    """`nurbsinterp plan ...` in-process: (exit code, stdout bytes, stderr text)."""
    with pytest.raises(SystemExit) as info:
        main(["plan", *map(str, args)])
    out, err = capsysbinary.readouterr()
    code = info.value.code
    return (0 if code is None else code), out, err.decode()


def assert_one_line_error(code, out, err, *parts, status=2):
    """Exit *status*, nothing on stdout, one line on stderr naming every one of *parts*, no traceback."""
    if isinstance(out, bytes):
        out, err = out.decode(), err.decode()
    assert code == status, (code, err)
    assert out == "", f"stdout is not empty: {out[:200]!r}"
    assert "Traceback" not in err
    assert err.endswith("\n") and err.count("\n") == 1, f"stderr is not one line: {err!r}"
    assert err.startswith("nurbsinterp"), err
    for part in parts:
        assert str(part) in err, f"{part!r} not in {err!r}"
    return err


def plan_into_head(exe, args: str, errfile, timeout):
    """`EXE plan ARGS | head -1` in bash: (plan's exit status, head's output, plan's stderr).

    *args* is shell text; the caller picks a job long enough (far more than a pipe buffer) for the
    writer really to meet the closed pipe.  Skips without bash.
    """
    bash = shutil.which("bash")
    if bash is None:
        pytest.skip("no bash")
    script = f'"{exe}" plan {args} 2>"{errfile}" | head -1; exit "${{PIPESTATUS[0]}}"'
    proc = subprocess.run([bash, "-c", script], capture_output=True, timeout=timeout)
    return proc.returncode, proc.stdout.decode(), errfile.read_text()


def assert_quiet_close(code, err):
    """A reader that went away: exit 141 (or 0), and nothing said about it."""
    assert code in (141, 0), (code, err)
    assert "Traceback" not in err and "Error" not in err and "error" not in err, err


def plan_piped_into(exe, plan_args, consumer_args, timeout):
    """`EXE plan PLAN_ARGS | EXE CONSUMER_ARGS` through a real pipe: the consumer's CompletedProcess.

    The plan must succeed; the pipe delivers its records in pieces, as a shell's does.
    """
    plan = subprocess.Popen([str(exe), "plan", *map(str, plan_args)], stdout=subprocess.PIPE)
    try:
        done = subprocess.run([str(exe), *map(str, consumer_args)], stdin=plan.stdout, capture_output=True,
                              timeout=timeout)
    finally:
        plan.stdout.close()
        assert plan.wait(timeout=timeout) == 0
    return done


def without_end_mark(raw):
    """A whole CSV or binary stream (bytes or text) without its end mark, checked to be there and to count its
    rows, so that a test may parse the rows as plain numbers."""
    text = isinstance(raw, str)
    data = raw.encode() if text else raw
    head, _, body = data.partition(b"\n")
    if head.startswith(b"nurbsinterp-bin "):
        mark = body[-64:]
        rows = body[:-64]
        ncols = len(head.split()[2].split(b","))
        assert len(rows) % (8 * ncols) == 0, "a truncated record before the end mark"
        count = len(rows) // (8 * ncols)
        fields = mark.split()
    else:
        rows, _, mark = body[:-1].rpartition(b"\n")
        rows = rows + b"\n" if rows else b""
        assert mark.startswith(b"# "), f"no end mark: the last line is {mark[:80]!r}"
        count = rows.count(b"\n")
        fields = mark[2:].split()
    assert fields[0] == b"nurbsinterp-end" and fields[1] == b"ticks=%d" % count, (mark, count)
    out = head + b"\n" + rows
    return out.decode() if text else out


def in_process(args) -> tuple[int, str, str]:
    """main() where capsys cannot serve (a module-scoped fixture: capsys is per test), stdin empty: (exit code,
    stdout, stderr)."""
    import contextlib
    import io
    import sys

    out, err = io.StringIO(), io.StringIO()
    saved = sys.stdin
    sys.stdin = io.TextIOWrapper(io.BufferedReader(io.BytesIO(b"")))
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                main([str(a) for a in args])
                code = 0
            except SystemExit as stop:
                code = stop.code
    finally:
        sys.stdin = saved
    return code, out.getvalue(), err.getvalue()


def read_trace(path):
    """A CSV trace or stream: (its columns, its rows (m, columns))."""
    import numpy as np

    with open(path) as fh:
        cols = fh.readline().strip().split(",")
    return cols, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def run_main(capsys, *args):
    """nurbsinterp.cli.main in-process: (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err
