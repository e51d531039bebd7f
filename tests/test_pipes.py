"""No silent data loss (issue 12): every write path writes all its bytes or fails.

The installed executable writes into real pipes whose readers stop after 0, 1, 65 535,
65 536 or 100 000 bytes, and into files that cannot grow (a file size limit, /dev/full,
a small tmpfs).  The contract (README): a reader that goes away gives exit 141 and
nothing on stderr (no run summary: the ticks were not delivered); a full disk gives
exit 1 and one line naming the output and the reason, and no partial or temporary file.

``PYTHONUNBUFFERED=1`` (common in containers and CI) is what made the loss silent: it
gives sys.stdout a raw FileIO, whose short write counts nobody checked.  The stdout
cases run both with and without it.

No test here depends on the clock: every subprocess is bounded only by a generous hang
catcher (HANG_S).  Each writer meets a reader that stops early in the quick set; the other
limits and environments of each (QUICK_READERS) run in the slow set.
"""
from __future__ import annotations

import fcntl
import os
import resource
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CIRCLE = str(ROOT / "curves" / "circle.yaml")
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one process, not a speed test

pytestmark = pytest.mark.skipif(not EXE.exists(), reason="console script not installed in this environment")

ENVS = {
    "buffered": {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"},
    "unbuffered": dict(os.environ, PYTHONUNBUFFERED="1"),
}
#: the reader reads at most argv[1] bytes (stopping early at end of stream), prints how many it got, and exits
READER = ("import os, sys\n"
          "left = int(sys.argv[1]); got = 0\n"
          "while left > 0:\n"
          "    b = os.read(0, min(left, 1 << 16))\n"
          "    if not b: break\n"
          "    got += len(b); left -= len(b)\n"
          "print(got)\n")
LIMITS = [0, 1, 65535, 65536, 100000]

#: name: (arguments, environments, reader limits, pipe size or None for the default).  Both environments run the
#: same code once main() has put stdout on whole writes; the second one is kept where it failed differently before.
STDOUT_WRITERS = {
    "plan-csv": (["plan", CIRCLE], ["buffered", "unbuffered"], LIMITS, None),  # with the run summary
    "plan-bin": (["plan", CIRCLE, "--format", "bin", "-q"], ["unbuffered"], LIMITS, None),
    "simulate-trace": (["simulate", "--plan", "--job", CIRCLE, "-o", "-"], ["unbuffered"], LIMITS, None),
    # 0.7 kB of JSON: a pipe takes it whole (atomic below PIPE_BUF) or not at all; a reader of 64 kB takes it all
    "info-json": (["info", CIRCLE, "--json"], ["unbuffered"], [0, 1], None),
    "simulate-json": (["simulate", "--plan", "--job", CIRCLE, "--json"], ["unbuffered"], [0, 1], None),
    # 7.9 kB of JSON through a one-page pipe: the text layer (click.echo) meets a short write
    "compare-json": (["compare", CIRCLE, "--json"], ["unbuffered"], [0, 1], 4096),
}


#: the quick set's readers: every writer and every environment once, the limits spread across them (nothing read,
#: one byte, one short of and at a pipe's capacity, beyond it); every other pair runs in the slow set
QUICK_READERS = {("plan-csv", "buffered", 0), ("plan-csv", "buffered", 65536), ("plan-csv", "unbuffered", 1),
                 ("plan-csv", "unbuffered", 100000), ("plan-bin", "unbuffered", 65535),
                 ("simulate-trace", "unbuffered", 0), ("info-json", "unbuffered", 1), ("simulate-json", "unbuffered", 0),
                 ("compare-json", "unbuffered", 1)}


def _cases():
    for name, (_, envs, limits, _) in STDOUT_WRITERS.items():
        for env in envs:
            for limit in limits:
                slow = () if (name, env, limit) in QUICK_READERS else pytest.mark.slow
                yield pytest.param(name, env, limit, id=f"{name}-{env}-{limit}", marks=slow)


@pytest.fixture(scope="module")
def full_outputs():
    """Each writer's whole stdout, from a run into a file (this also compiles and caches the kernels)."""
    outputs = {}
    for name, (args, *_) in STDOUT_WRITERS.items():
        proc = subprocess.run([str(EXE), *args], stdin=subprocess.DEVNULL, capture_output=True, timeout=HANG_S)
        assert proc.returncode == 0, proc.stderr
        outputs[name] = proc.stdout
    return outputs


def _into_reader(args, env, limit, pipe_size=None, preexec_fn=None):
    """Run nurbsinterp with stdout a pipe read by READER: (exit status, stderr, bytes the reader got, capacity)."""
    r, w = os.pipe()
    try:
        if pipe_size is not None:
            fcntl.fcntl(w, getattr(fcntl, "F_SETPIPE_SZ", 1031), pipe_size)
        capacity = fcntl.fcntl(w, getattr(fcntl, "F_GETPIPE_SZ", 1032))
        writer = subprocess.Popen([str(EXE), *args], stdin=subprocess.DEVNULL, stdout=w, stderr=subprocess.PIPE,
                                  env=ENVS[env], preexec_fn=preexec_fn)
        reader = subprocess.Popen([sys.executable, "-c", READER, str(limit)], stdin=r, stdout=subprocess.PIPE)
    finally:
        os.close(w)
        os.close(r)
    try:
        err = writer.communicate(timeout=HANG_S)[1].decode()
        got = int(reader.communicate(timeout=HANG_S)[0])
    finally:
        for proc in (writer, reader):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return writer.returncode, err, got, capacity


@pytest.mark.parametrize("name,env,limit", list(_cases()))
def test_reader_that_stops_early(full_outputs, name, env, limit):
    """Exit 141 and silence whenever the stream cannot all have been delivered; never a silent 0."""
    args, _, _, pipe_size = STDOUT_WRITERS[name]
    size = len(full_outputs[name])
    code, err, got, capacity = _into_reader(args, env, limit, pipe_size)
    assert got == min(limit, size)
    assert "Traceback" not in err and "Error" not in err, err
    if size > limit + capacity:  # the pipe cannot hold what the reader left: the writer met the closed pipe
        assert code == 141, (code, err)
    else:
        assert code in (0, 141), (code, err)
    if code == 141:
        assert err == "", f"a run that lost its reader must say nothing (no run summary): {err!r}"
    elif name == "plan-csv":
        assert "ticks" in err and "stdout" in err, err  # the run summary, once every byte was delivered


NONBLOCK_READER = ("import fcntl, os, select, sys, time\n"
                   "cap = fcntl.fcntl(0, getattr(fcntl, 'F_GETPIPE_SZ', 1032))\n"
                   "poll = select.poll(); poll.register(0, select.POLLIN)\n"
                   "def queued():\n"
                   "    import array, termios\n"
                   "    n = array.array('i', [0]); fcntl.ioctl(0, termios.FIONREAD, n, True); return n[0]\n"
                   "while queued() < cap - 4096:  # wait until the writer meets a full pipe (EAGAIN)\n"
                   "    if any(ev & select.POLLHUP for _, ev in poll.poll(0)): break  # or has finished\n"
                   "    time.sleep(0.01)\n"
                   "with open(sys.argv[1], 'wb') as fh:\n"
                   "    while True:\n"
                   "        b = os.read(0, 1 << 16)\n"
                   "        if not b: break\n"
                   "        fh.write(b)\n")


@pytest.mark.parametrize("env", list(ENVS))
def test_non_blocking_stdout_delivers_every_byte(tmp_path, full_outputs, env):
    """A parent may hand over a non-blocking pipe (O_NONBLOCK is shared): a full pipe is EAGAIN, not lost data."""
    args = STDOUT_WRITERS["plan-bin"][0]
    got = tmp_path / "got.bin"
    r, w = os.pipe()
    try:
        os.set_blocking(w, False)
        writer = subprocess.Popen([str(EXE), *args], stdin=subprocess.DEVNULL, stdout=w, stderr=subprocess.PIPE,
                                  env=ENVS[env])
        reader = subprocess.Popen([sys.executable, "-c", NONBLOCK_READER, str(got)], stdin=r)
    finally:
        os.close(w)
        os.close(r)
    try:
        err = writer.communicate(timeout=HANG_S)[1].decode()
        assert reader.wait(timeout=HANG_S) == 0
    finally:
        for proc in (writer, reader):
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    assert writer.returncode == 0 and err == "", (writer.returncode, err)
    assert got.read_bytes() == full_outputs["plan-bin"]


# --------------------------------------------------------------------------- full disks


def _file_size_limit(nbytes):
    """preexec_fn: cap the size of any file the child writes; SIGXFSZ at its default (which kills) as a shell leaves it."""
    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_DFL)
        resource.setrlimit(resource.RLIMIT_FSIZE, (nbytes, nbytes))
    return limit


def _run_limited(args, env, preexec_fn, stdout):
    proc = subprocess.run([str(EXE), *args], stdin=subprocess.DEVNULL, stdout=stdout, stderr=subprocess.PIPE,
                          env=ENVS[env], preexec_fn=preexec_fn, timeout=HANG_S)
    return proc.returncode, proc.stderr.decode()


def _assert_write_failure(code, err, output, reason):
    assert code == 1, (code, err)  # not killed by SIGXFSZ (-25), not a silent 0
    assert err == f"nurbsinterp: {output}: cannot write: {reason}\n", err


FILE_WRITERS = {
    "plan-csv": ["plan", CIRCLE, "-q"],
    "plan-bin": ["plan", CIRCLE, "--format", "bin"],  # with the summary, which must not be printed
    "simulate-trace": ["simulate", "--plan", "--job", CIRCLE],
}


@pytest.mark.parametrize("name", list(FILE_WRITERS))
def test_file_size_limit_on_output_file(tmp_path, full_outputs, name):
    """-o FILE hits RLIMIT_FSIZE: exit 1, one line naming -o FILE and the reason, no partial or temporary file."""
    out = tmp_path / "out" / "run.csv"
    out.parent.mkdir()
    code, err = _run_limited([*FILE_WRITERS[name], "-o", str(out)], "unbuffered", _file_size_limit(64 << 10),
                             subprocess.DEVNULL)
    _assert_write_failure(code, err, f"-o {out}", "File too large")
    assert os.listdir(out.parent) == [], "a partial or temporary file was left"


@pytest.mark.parametrize("name,limit,env", [("plan-csv", 64 << 10, "buffered"), ("plan-csv", 64 << 10, "unbuffered"),
                                            ("plan-bin", 64 << 10, "unbuffered"),
                                            ("simulate-trace", 64 << 10, "unbuffered"),
                                            ("info-json", 100, "buffered"), ("info-json", 100, "unbuffered"),
                                            ("simulate-json", 100, "unbuffered")])
def test_file_size_limit_on_redirected_stdout(tmp_path, full_outputs, name, limit, env):
    """`nurbsinterp ... > FILE` hits RLIMIT_FSIZE: exit 1, one line naming stdout and the reason."""
    out = tmp_path / "stdout.file"
    with open(out, "wb") as fh:
        code, err = _run_limited(STDOUT_WRITERS[name][0], env, _file_size_limit(limit), fh)
    _assert_write_failure(code, err, "stdout", "File too large")
    assert os.listdir(tmp_path) == ["stdout.file"]
    assert out.stat().st_size <= limit


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="no /dev/full")
@pytest.mark.parametrize("name,how", [("plan-csv", "-o"), ("simulate-trace", "-o"), ("plan-bin", "stdout"),
                                      ("info-json", "stdout")])
def test_dev_full(full_outputs, name, how):
    """/dev/full takes nothing (ENOSPC), as `-o /dev/full` (a device, written in place) and as stdout."""
    args = STDOUT_WRITERS[name][0]
    if how == "-o":
        args = [a for a in args if a not in ("-o", "-")] + ["-o", "/dev/full"]
        with open(os.devnull, "wb") as sink:
            code, err = _run_limited(args, "unbuffered", None, sink)
        _assert_write_failure(code, err, "-o /dev/full", "No space left on device")
    else:
        with open("/dev/full", "wb") as full:
            code, err = _run_limited(args, "unbuffered", None, full)
        _assert_write_failure(code, err, "stdout", "No space left on device")


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 64 KiB tmpfs, where this process may mount one (root); skipped cleanly otherwise."""
    mount, umount = shutil.which("mount"), shutil.which("umount")
    if mount is None or umount is None or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root and mount(8)")
    where = tmp_path / "small"
    where.mkdir()
    proc = subprocess.run([mount, "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(where)], capture_output=True,
                          timeout=HANG_S)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {proc.stderr.decode().strip()}")
    try:
        yield where
    finally:
        subprocess.run([umount, str(where)], capture_output=True, timeout=HANG_S)


@pytest.mark.parametrize("name,how", [("plan-csv", "-o"), ("plan-bin", "-o"), ("simulate-trace", "-o"),
                                      ("plan-csv", "stdout")])
def test_full_filesystem(small_tmpfs, full_outputs, name, how):
    """A 64 KiB tmpfs fills up (ENOSPC): exit 1, one line, no partial or temporary file."""
    out = small_tmpfs / "run.csv"
    if how == "-o":
        code, err = _run_limited([*FILE_WRITERS[name], "-o", str(out)], "unbuffered", None, subprocess.DEVNULL)
        _assert_write_failure(code, err, f"-o {out}", "No space left on device")
        assert os.listdir(small_tmpfs) == [], "a partial or temporary file was left"
    else:
        args = [*FILE_WRITERS[name], "-o", "-"] if name == "simulate-trace" else FILE_WRITERS[name]
        with open(out, "wb") as fh:
            code, err = _run_limited(args, "unbuffered", None, fh)
        _assert_write_failure(code, err, "stdout", "No space left on device")
        assert os.listdir(small_tmpfs) == ["run.csv"]


# --------------------------------------------------------------------------- the layer itself, in-process


def test_write_all_loops_on_short_writes(monkeypatch):
    from nurbsinterp import output

    taken = []

    def short_write(fd, data):
        n = min(len(data), 7)
        taken.append(bytes(data[:n]))
        return n

    monkeypatch.setattr(output.os, "write", short_write)
    assert output.write_all(99, b"x" * 50 + b"end", "stdout") == 53
    assert b"".join(taken) == b"x" * 50 + b"end"


@pytest.mark.parametrize("errno_name,reason", [("ENOSPC", "No space left on device"), ("EFBIG", "File too large"),
                                               ("EIO", "Input/output error")])
def test_write_all_names_the_output(monkeypatch, errno_name, reason):
    import errno

    from nurbsinterp import output
    from nurbsinterp.errors import OutputError

    def failing(fd, data):
        raise OSError(getattr(errno, errno_name), os.strerror(getattr(errno, errno_name)))

    monkeypatch.setattr(output.os, "write", failing)
    with pytest.raises(OutputError, match=f"^-o run.csv: cannot write: {reason}$") as info:
        output.write_all(99, b"abc", "-o run.csv")
    assert info.value.exit_code == 1


def test_write_all_lets_a_broken_pipe_through(monkeypatch):
    from nurbsinterp import output

    def gone(fd, data):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(output.os, "write", gone)
    with pytest.raises(BrokenPipeError):
        output.write_all(99, b"abc", "stdout")


def test_output_file_under_a_buffered_writer(tmp_path):
    """BufferedWriter over OutputFile: small writes are gathered, large ones pass through, all arrive."""
    import io

    from nurbsinterp.output import OutputFile, writes_whole

    path = tmp_path / "f"
    with io.BufferedWriter(OutputFile(str(path), "-o f"), 16) as fh:
        assert writes_whole(fh)
        fh.write(b"head\n")
        fh.write(memoryview(b"y" * 1000))
    assert path.read_bytes() == b"head\n" + b"y" * 1000
