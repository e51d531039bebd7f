"""`nurbsinterp sweep` (issue 31): the sweep file, one case against the commands run directly, and the cases on
a real Dask cluster -- a `dask scheduler` and two `dask worker` processes started here -- with a bad program, a
case breaking a limit, an interrupted sweep resumed, and a worker killed mid-sweep.

No assertion reads a clock: the waits are generous hang-catchers, and the timing columns are only checked to be
there.  Every row's measures are checked against running the same case with `plan` / `simulate` in-process.
"""
from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from nurbsinterp.errors import SpecError
from nurbsinterp.sweep.case import COLUMNS, run_case
from nurbsinterp.sweep.spec import cases, read_sweep
from clirun import assert_one_line_error, run_main

distributed = pytest.importorskip("distributed", reason="the test extra installs Dask: pip install -e '.[test]'")

ROOT = Path(__file__).resolve().parents[1]
EXE = Path(sys.executable).parent / "nurbsinterp"
HANG_S = 900  # a hang catcher for one process or one wait, not a speed test
TIMING = {"plan_s", "simulate_s", "worker"}  # the columns that differ from run to run

SWEEP = """\
programs: [circle.yaml, pocket.ngc, bad.ngc]
machines:
  - name: mill
    servo: example-xyz.yaml
    limits: {x: {max_velocity: 60, max_accel: 500 mm/s^2}, y: {max_velocity: 60 mm/s, max_accel: 500}}
  - name: table
    servo: paper-xy.yaml
grid:
  tolerance: [null, 5 um]
  precompensate: [none, exact]
"""


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory):
    """A sweep of the bundled circle and pocket, a bad program, on two machines: 24 cases."""
    where = tmp_path_factory.mktemp("sweep")
    for src in ("curves/circle.yaml", "curves/pocket.ngc", "servo/example-xyz.yaml", "servo/paper-xy.yaml"):
        (where / Path(src).name).write_bytes((ROOT / src).read_bytes())
    (where / "bad.ngc").write_text("G1 X1 Y\n")
    (where / "sweep.yaml").write_text(SWEEP)
    return where


# --------------------------------------------------------------------------- the sweep file


def test_cases_come_in_the_files_order(sweep_dir):
    spec = read_sweep(sweep_dir / "sweep.yaml")
    assert spec.size == 24
    got = [(c.index, c.program, c.machine, c.settings["tolerance"], c.settings["precompensate"]) for c in cases(spec)]
    assert got[:5] == [(0, "circle.yaml", "mill", None, "none"), (1, "circle.yaml", "mill", None, "exact"),
                       (2, "circle.yaml", "mill", 0.005, "none"), (3, "circle.yaml", "mill", 0.005, "exact"),
                       (4, "circle.yaml", "table", None, "none")]
    assert [g[1] for g in got[::8]] == ["circle.yaml", "pocket.ngc", "bad.ngc"]


def _fingerprints(where, text):
    (where / "s.yaml").write_text(text)
    return [c.fingerprint for c in cases(read_sweep(where / "s.yaml"))]


def test_the_fingerprint_is_what_decides_the_result(sweep_dir, tmp_path):
    for name in ("circle.yaml", "example-xyz.yaml"):
        (tmp_path / name).write_bytes((sweep_dir / name).read_bytes())
    base = "programs: [circle.yaml]\nmachines: [{name: m, servo: example-xyz.yaml}]\nsettings: {feedrate: %s}\n"
    one = _fingerprints(tmp_path, base % "100 mm/s")
    assert _fingerprints(tmp_path, base % "6000 mm/min") == one  # the same feedrate
    assert _fingerprints(tmp_path, base.replace("name: m", "name: renamed") % "100") == one  # a label
    assert _fingerprints(tmp_path, base % "99") != one
    (tmp_path / "circle.yaml").write_bytes((sweep_dir / "circle.yaml").read_bytes() + b"\n")
    assert _fingerprints(tmp_path, base % "100") != one  # one byte of the program
    (tmp_path / "circle.yaml").write_bytes((sweep_dir / "circle.yaml").read_bytes())
    (tmp_path / "example-xyz.yaml").write_bytes((sweep_dir / "example-xyz.yaml").read_bytes() + b"\n")
    assert _fingerprints(tmp_path, base % "100") != one  # one byte of the servo model


@pytest.mark.parametrize("text, parts", [
    ("programs: [nothing*.ngc]\nmachines: [{name: m}]\n", ("programs[0] = 'nothing*.ngc' matches no file",)),
    ("programs: [circle.yaml]\nmachines: []\n", ("machines = []", "non-empty list")),
    ("programs: [circle.yaml]\nmachines: [{name: m}, {name: m}]\n", ("machines[1].name = 'm'", "another machine")),
    ("programs: [circle.yaml]\nmachines: [{name: m}]\ngrid: {feedrate: [fast]}\n", ("grid.feedrate[0] = 'fast'",)),
    ("programs: [circle.yaml]\nmachines: [{name: m}]\ngrid: {precompensate: [exact]}\n",
     ("precompensate exact needs a servo model", "machine 'm' has none")),
    ("programs: [circle.yaml]\nmachines: [{name: m}]\nsettings: {speed: 3}\n", ("settings.speed", "not a known key")),
    ("programs: [circle.yaml]\nmachines: [{name: m, limits: {x: {max_velocity: -1}}}]\n",
     ("machines[0].limits.x.max_velocity = -1",)),
])
def test_a_bad_sweep_file_is_one_line(sweep_dir, capsys, text, parts):
    bad = sweep_dir / "bad-sweep.yaml"
    bad.write_text(text)
    with pytest.raises(SpecError) as info:
        read_sweep(bad)
    for part in parts:
        assert part in str(info.value)
    out = sweep_dir / "never.csv"
    code, stdout, err = run_main(capsys, "sweep", bad, "-o", out)
    assert_one_line_error(code, stdout, err, str(bad), *parts)
    assert not out.exists() and not Path(str(out) + ".partial").exists()


@pytest.mark.parametrize("text, parts", [
    ("programs: [{path: circle.yaml, layer: CUT}]\nmachines: [{name: m}]\n",
     ("programs[0].layer = 'CUT' applies to DXF drawings", "circle.yaml is one of the YAML jobs")),
    ("programs: [{path: pocket.ngc, start: [1]}]\nmachines: [{name: m}]\n", ("programs[0].start = [1]", "X,Y or X,Y,Z")),
    ("programs: [{path: pocket.ngc, chain: 1}]\nmachines: [{name: m}]\n", ("programs[0].chain = 1 applies to DXF",)),
    ("programs: [{path: pocket.ngc, speed: 1}]\nmachines: [{name: m}]\n", ("programs[0].speed", "not a known key")),
    ("programs: [{layer: CUT}]\nmachines: [{name: m}]\n", ("programs[0].path = null", "a path or a glob")),
    ("programs: [circle.yaml]\nmachines: [{name: m, ini: missing.ini}]\n", ("machines[0].ini = 'missing.ini'",
                                                                            "is not a file")),
    ("programs: [circle.yaml]\nmachines: [{name: m, ini: circle.yaml}]\n", ("machines[0].ini: ", "circle.yaml:5:")),
    ("programs: [circle.yaml]\nmachines: [{name: m}]\ntimeout: forever\n", ("timeout = 'forever'",)),
])
def test_a_bad_program_entry_ini_or_timeout_is_one_line(sweep_dir, capsys, text, parts):
    test_a_bad_sweep_file_is_one_line(sweep_dir, capsys, text, parts)


@pytest.fixture(scope="module")
def options_dir(tmp_path_factory):
    """Programs with the reader's options (a start point, a DXF layer, a missing layer) on a machine read from a
    LinuxCNC INI file, one of its limits given over it."""
    where = tmp_path_factory.mktemp("options")
    for src in ("curves/pocket.ngc", "curves/drawing.dxf", "servo/example-xyz.yaml", "examples/linuxcnc/mill.ini"):
        (where / Path(src).name).write_bytes((ROOT / src).read_bytes())
    (where / "sweep.yaml").write_text("""\
programs:
  - pocket.ngc
  - {path: pocket.ngc, start: [0, 0, 5]}
  - {path: drawing.dxf, layer: CUT}
  - {path: drawing.dxf, layer: NOPE}
machines:
  - {name: ini-mill, servo: example-xyz.yaml, ini: mill.ini, limits: {z: {max_accel: 400}}}
settings: {profile: adaptive}
""")
    return where


def test_reader_options_and_a_machine_from_its_ini_file(options_dir, capsys):
    import hashlib

    spec = read_sweep(options_dir / "sweep.yaml")
    assert [(p.label, p.reader) for p in spec.programs] == [
        ("pocket.ngc", {}), ("pocket.ngc", {"start": (0.0, 0.0, 5.0)}), ("drawing.dxf", {"layer": "CUT"}),
        ("drawing.dxf", {"layer": "NOPE"})]
    mill = spec.machines[0]
    assert mill.limits == {"x": {"max_velocity": 100.0, "max_accel": 1000.0},
                           "y": {"max_velocity": 100.0, "max_accel": 1000.0},
                           "z": {"max_velocity": 50.0, "max_accel": 400.0}}  # the sweep's z over the INI's 500
    assert mill.settings == {"rapid_feedrate": 100.0}  # [TRAJ] MAX_LINEAR_VELOCITY, as plan --machine reads it
    all_cases = list(cases(spec))
    for case in all_cases:
        assert case.program_sha256 == hashlib.sha256((options_dir / case.program).read_bytes()).hexdigest()
    assert len({c.fingerprint for c in all_cases}) == 4  # the reader's options decide the result
    got = [run_case(c) for c in all_cases]
    assert [r["status"] for r in got] == ["ok", "ok", "ok", "failed"]
    assert [r["program_options"] for r in got] == [None, "start=0,0,5", "layer=CUT", "layer=NOPE"]
    assert got[0]["program_sha256"] == all_cases[0].program_sha256 and got[0]["rapid_feedrate_mm_s"] == 100.0
    # each against plan --machine with the same options
    machine = ["--machine", "mill.ini", "--axis-max-accel", "z=400", "--profile-type", "adaptive"]
    for case, row, extra in zip(all_cases, got, ([], ["--start", "0,0,5"], ["--layer", "CUT"])):
        columns, data = _stream(capsys, options_dir, case.program, case, *machine, *extra)
        assert row["ticks"] == data.shape[0], extra
        period = data[1, columns.index("t")] - data[0, columns.index("t")]
        for axis in (a for a in "xyz" if a in columns):
            naive = np.abs(np.diff(data[:, columns.index(axis)])).max() / period
            assert row[f"vmax_{axis}_mm_s"] == pytest.approx(naive, rel=1e-9, abs=1e-6)
    assert got[0]["ticks"] != got[1]["ticks"]  # from (0, 0, 5) the program's first move is another
    code, out, err = _direct(capsys, options_dir, "plan", "drawing.dxf", "--layer", "NOPE", "-q", "-o",
                             options_dir / "never.csv")
    assert code == 2 and got[3]["error"] == err.strip().removeprefix("nurbsinterp: ")
    assert "layer 'NOPE' has no entities" in got[3]["error"]


def test_no_input_of_the_sweep_is_its_output(options_dir, capsys):
    """-o naming the machine's INI file (or any input) is refused before any work, the file untouched."""
    before = (options_dir / "mill.ini").read_bytes()
    for name in ("mill.ini", "example-xyz.yaml", "pocket.ngc", "sweep.yaml"):
        code, out, err = run_main(capsys, "sweep", options_dir / "sweep.yaml", "-o", options_dir / name, "--fresh")
        assert_one_line_error(code, out, err, name)
    assert (options_dir / "mill.ini").read_bytes() == before


def test_a_case_past_the_timeout_is_a_timeout_row_a_rerun_computes(sweep_dir, rows, shared_cluster, capsys,
                                                                    tmp_path):
    """A timeout of 1 us stops every case after its first chunk: `timeout` rows (exit 0, said on stderr); the same
    sweep without it resumes from them and computes each again (the timeout is not in the fingerprint)."""
    import dataclasses

    spec = read_sweep(sweep_dir / "sweep.yaml")
    first = dataclasses.replace(next(cases(spec)), timeout=1e-6)
    row = run_case(first)
    assert row["status"] == "timeout" and row["error"].startswith("stopped after 1e-06 s (the sweep's timeout)")
    address = shared_cluster[0]
    (tmp_path / "sweep.yaml").write_text((sweep_dir / "sweep.yaml").read_text().replace(
        "programs: [circle.yaml, pocket.ngc, bad.ngc]", "programs: [circle.yaml]") + "timeout: 1 us\n")
    for name in ("circle.yaml", "example-xyz.yaml", "paper-xy.yaml"):
        (tmp_path / name).write_bytes((sweep_dir / name).read_bytes())
    out = tmp_path / "results.csv"
    code, stdout, err = run_main(capsys, "sweep", tmp_path / "sweep.yaml", "-o", out, "--scheduler", address)
    assert code in (None, 0), err
    assert "8 timed out" in stdout and "8 case(s) stopped at the sweep's timeout" in err
    assert [r["status"] for r in _read(out)] == ["timeout"] * 8
    (tmp_path / "sweep.yaml").write_text((tmp_path / "sweep.yaml").read_text().replace("timeout: 1 us\n", ""))
    code, stdout, err = run_main(capsys, "sweep", tmp_path / "sweep.yaml", "-o", out, "--scheduler", address,
                                 "--json")
    doc = json.loads(stdout)
    assert (doc["resumed"], doc["computed"], doc["ok"]) == (0, 8, 8)
    for got, expected in zip(_read(out), rows[:8]):
        _same(got, expected)


class _FakeFuture:
    def release(self):
        pass


class _FakeClient:
    """What Cluster.prime asks of a Dask client: run(function) on every worker, submit(function, workers=[one])."""

    def __init__(self, hosts):
        self.hosts = hosts  # address -> (host, warm)
        self.calls = []

    def run(self, function):
        self.calls.append((function.__name__, None))
        return dict(self.hosts)

    def submit(self, function, key, workers, allow_other_workers, pure):
        assert allow_other_workers and not pure and key.startswith("nurbsinterp-prime-")
        self.calls.append((function.__name__, workers))
        return _FakeFuture()

    def gather(self, futures):
        return [0] * len(futures)


def test_a_cold_worker_host_is_said_and_compiles_once():
    """One worker of each host whose install has not compiled the kernels compiles them (said first), as a task
    (not in the worker's event loop: minutes there would stop its heartbeats); then every worker is primed, once
    a cluster."""
    from nurbsinterp.sweep.cluster import Cluster

    cluster = Cluster.__new__(Cluster)
    cluster.primed = False
    cluster.client = _FakeClient({"tcp://a:1": ("hostA", False), "tcp://a:2": ("hostA", False),
                                  "tcp://b:1": ("hostB", True), "tcp://c:1": ("hostC", False)})
    said = []
    cluster.prime(said.append)
    assert len(said) == 2
    assert "worker tcp://a:1 on hostA: compiling the numeric kernels once" in said[0] and "hostC" in said[1]
    assert cluster.client.calls == [("_kernels_warm", None), ("_prime", ["tcp://a:1"]), ("_prime", ["tcp://c:1"]),
                                    *(("_prime", [a]) for a in ("tcp://a:1", "tcp://a:2", "tcp://b:1", "tcp://c:1"))]
    cluster.prime(said.append)
    assert len(cluster.client.calls) == 7 and len(said) == 2


# --------------------------------------------------------------------------- one case against the commands


def _direct(capsys, where, *args):
    """A command run in-process from the sweep's directory: (exit code, stdout, stderr)."""
    here = os.getcwd()
    os.chdir(where)
    try:
        return run_main(capsys, *args)
    finally:
        os.chdir(here)


def _stream(capsys, where, program, case, *plan_args):
    """The case's commands as `plan` writes them (binary): (columns, rows)."""
    path = where / f"direct-{case.index}.bin"
    code, out, err = _direct(capsys, where, "plan", program, "--format", "bin", "-q", "-o", path, *plan_args)
    assert code == 0, err
    head, _, body = path.read_bytes().partition(b"\n")
    columns = head.split()[2].decode().split(",")
    return columns, np.frombuffer(body[:-64], "<f8").reshape(-1, len(columns))


@pytest.fixture(scope="module")
def rows(sweep_dir):
    """Every case of the sweep run in-process by run_case, as a worker runs it."""
    return [run_case(c) for c in cases(read_sweep(sweep_dir / "sweep.yaml"))]


def test_each_row_is_what_plan_and_simulate_say(sweep_dir, rows, capsys):
    spec = read_sweep(sweep_dir / "sweep.yaml")
    checked = 0
    for case, row in zip(cases(spec), rows):
        tol = case.settings["tolerance"]
        pre = case.settings["precompensate"]
        look = ["--tolerance", f"{tol}"] if tol is not None else []
        servo = {"mill": "example-xyz.yaml", "table": "paper-xy.yaml"}[case.machine]
        if case.program == "bad.ngc" or (case.machine == "table" and case.program == "pocket.ngc"):
            continue  # the failed rows: below
        limits = ["--axis-max-velocity", "x=60,y=60", "--axis-max-accel", "x=500,y=500"] \
            if tol is not None and case.machine == "mill" else []  # the look-ahead plans with the machine's limits
        planned = look + limits + (["--precompensate", servo] if pre != "none" else [])
        columns, data = _stream(capsys, sweep_dir, case.program, case, *planned)
        assert row["status"] == "ok", row["error"]
        assert row["ticks"] == data.shape[0]
        period = data[1, columns.index("t")] - data[0, columns.index("t")]
        assert row["motion_time_s"] == pytest.approx((data.shape[0] - 1) * period, rel=1e-12)
        for i, axis in enumerate(a for a in "xyz" if a in columns):
            x = data[:, columns.index(axis)]
            for order, name in enumerate(("v", "a", "j"), start=1):
                naive = np.abs(np.diff(x, order)).max() / period ** order
                unit = {"v": "mm_s", "a": "mm_s2", "j": "mm_s3"}[name]
                assert row[f"{name}max_{axis}_{unit}"] == pytest.approx(naive, rel=1e-9, abs=1e-6)
        # the servo's measures: simulate on the same stream
        code, out, err = _direct(capsys, sweep_dir, "simulate", sweep_dir / f"direct-{case.index}.bin", "--job",
                                 case.program, "--servo", servo, "--json", *look)
        assert code == 0, err
        report = json.loads(out)
        assert row["contour_error_max_mm"] == pytest.approx(report["contour_error_max"], rel=1e-12, abs=1e-15)
        assert row["contour_error_rms_mm"] == pytest.approx(report["contour_error_rms"], rel=1e-12, abs=1e-15)
        assert row["tracking_error_max_mm"] == pytest.approx(max(report["tracking_error_max"].values()), rel=1e-12)
        assert row["feedrate_error_max_mm_s"] == pytest.approx(report["feedrate_error_max"], rel=1e-12)
        assert row["settle_time_s"] == pytest.approx(report["settle_time"], rel=1e-12)
        assert row["plan_s"] >= 0 and row["simulate_s"] >= 0
        checked += 1
    assert checked == 12


def test_a_failed_case_is_a_row_with_the_commands_own_line(sweep_dir, rows, capsys):
    bad = [r for r in rows if r["program"] == "bad.ngc"]
    assert len(bad) == 8 and all(r["status"] == "failed" for r in bad)
    code, out, err = _direct(capsys, sweep_dir, "plan", "bad.ngc", "-q", "-o", sweep_dir / "never.csv")
    assert code == 2
    line = err.strip().removeprefix("nurbsinterp: ")
    assert [r["error"] for r in bad if r["machine"] == "mill" and r["tolerance_mm"] is None] == [line, line]
    z = [r for r in rows if r["program"] == "pocket.ngc" and r["machine"] == "table"]
    assert all(r["status"] == "failed" and "z axis" in r["error"] for r in z)


def test_a_case_breaking_a_limit_says_which(rows):
    """The circle at 100 mm/s on a 60 mm/s machine without look-ahead (the trapezoid does not plan with limits):
    y reaches 100 mm/s, 5/3 of its limit; with look-ahead the limits are planned with, and held."""
    plain = rows[0]
    assert plain["limits_held"] == "no" and plain["worst_limit"] == "v_y"
    assert plain["worst_limit_ratio"] == pytest.approx(plain["vmax_y_mm_s"] / 60.0, rel=1e-12)
    assert plain["worst_limit_ratio"] > 1.6
    look = rows[2]
    assert look["planner"] == "look-ahead" and look["limits_held"] == "yes"
    assert look["vmax_x_mm_s"] <= 60.0 * (1 + 1e-9) and look["amax_y_mm_s2"] <= 500.0 * (1 + 1e-9)


# --------------------------------------------------------------------------- on a real Dask cluster


def _start(args, log):
    return subprocess.Popen([sys.executable, "-m", "dask", *args], stdout=log, stderr=subprocess.STDOUT,
                            start_new_session=True)


def _stop(proc):
    if proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(60)


@contextlib.contextmanager
def _cluster(tmp_path):
    """A `dask scheduler` and two `dask worker` processes (no nanny: a killed worker stays dead) on localhost."""
    logs = tmp_path / "logs"
    logs.mkdir()
    file = tmp_path / "scheduler.json"
    procs = {"scheduler": _start(["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                  "--scheduler-file", str(file)], open(logs / "scheduler.log", "w"))}
    deadline = time.monotonic() + HANG_S
    while not file.exists():
        assert procs["scheduler"].poll() is None, (logs / "scheduler.log").read_text()
        assert time.monotonic() < deadline, "the scheduler did not start"
        time.sleep(0.2)
    address = json.loads(file.read_text())["address"]
    for name in ("w0", "w1"):
        procs[name] = _start(["worker", address, "--nworkers", "1", "--nthreads", "1", "--no-nanny",
                              "--no-dashboard", "--name", name, "--local-directory", str(tmp_path / name)],
                             open(logs / f"{name}.log", "w"))
    client = distributed.Client(address, timeout="60s")
    try:
        client.wait_for_workers(2, timeout=HANG_S)
        yield address, procs, client
    finally:
        client.close()
        for name in ("w0", "w1", "scheduler"):
            _stop(procs[name])


@pytest.fixture(scope="module")
def shared_cluster(tmp_path_factory):
    """One cluster for the tests that leave its workers alive (each sweep writes its own results file, and a
    client's sweep leaves no task behind): three processes started once, not once a test."""
    with _cluster(tmp_path_factory.mktemp("cluster")) as started:
        yield started


@pytest.fixture()
def cluster(tmp_path):
    """A cluster of its own, for a test that kills one of its workers."""
    with _cluster(tmp_path) as started:
        yield started


def _read(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _same(row, expected):
    """A row read back from the CSV against run_case's: every column but the timings, as the CSV writes them."""
    from nurbsinterp.sweep.results import cell

    for c in COLUMNS:
        if c not in TIMING:
            assert row[c] == cell(expected[c]), (c, row[c], expected[c])


def test_the_sweep_on_a_scheduler_and_two_workers(sweep_dir, rows, shared_cluster, capsys, tmp_path):
    address, _, client = shared_cluster
    out = tmp_path / "results.csv"
    code, stdout, err = run_main(capsys, "sweep", sweep_dir / "sweep.yaml", "-o", out, "--scheduler", address,
                                 "--json")
    assert code is None or code == 0, err
    doc = json.loads(stdout)
    assert (doc["cases"], doc["computed"], doc["resumed"], doc["ok"], doc["failed"]) == (24, 24, 0, 12, 12)
    assert doc["limits_broken"] >= 1 and doc["scheduler"] == address
    written = _read(out)
    assert [int(r["case"]) for r in written] == list(range(24))
    for row, expected in zip(written, rows):
        _same(row, expected)
    assert {r["worker"] for r in written} <= set(client.scheduler_info()["workers"])
    assert not Path(str(out) + ".partial").exists()
    # the table form: the headline, the failed cases, the worst ones
    code, stdout, err = run_main(capsys, "sweep", sweep_dir / "sweep.yaml", "-o", out, "--scheduler", address)
    assert stdout.startswith("24 cases (24 from an earlier run, 0 computed")
    assert "failed cases" in stdout and "the worst case of each measure" in stdout


def test_a_sweep_resumes_what_an_earlier_run_wrote(sweep_dir, rows, shared_cluster, capsys, tmp_path):
    """The partial file of a run that was stopped: its rows are kept (their timings too), a torn last line is
    dropped, and only the other cases are computed."""
    address = shared_cluster[0]
    out = tmp_path / "results.csv"
    from nurbsinterp.sweep.results import HEADER, row_line

    kept = rows[:7]
    marked = [dict(r, plan_s=123.0, worker="an earlier run") for r in kept]
    Path(str(out) + ".partial").write_text(HEADER + "".join(row_line(r) for r in marked)
                                           + row_line(rows[7])[:40])
    code, stdout, err = run_main(capsys, "sweep", sweep_dir / "sweep.yaml", "-o", out, "--scheduler", address,
                                 "--json")
    doc = json.loads(stdout)
    assert (doc["resumed"], doc["computed"]) == (7, 17)
    written = _read(out)
    assert [r["worker"] for r in written[:7]] == ["an earlier run"] * 7
    assert all(r["worker"] != "an earlier run" for r in written[7:])
    for row, expected in zip(written, rows):
        _same(row, expected)


def test_an_interrupted_sweep_keeps_its_rows_and_resumes(sweep_dir, rows, capsys, tmp_path):
    """SIGINT once the first row is written: exit 130 and the partial file (or, had it finished first, the
    results); the rerun computes only what is not there."""
    out = tmp_path / "results.csv"
    partial = Path(str(out) + ".partial")
    proc = subprocess.Popen([str(EXE), "sweep", str(sweep_dir / "sweep.yaml"), "-o", str(out), "--workers", "1"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + HANG_S
    while proc.poll() is None and not (partial.exists() and partial.read_text().count("\n") >= 2):
        assert time.monotonic() < deadline, "no row was written"
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=HANG_S)
    if proc.returncode == 130:
        assert not out.exists() and partial.exists()
        before = partial.read_text().count("\n") - 1
    else:  # it finished before the signal arrived
        assert proc.returncode == 0, stderr
        before = 24
    assert before >= 1
    done = subprocess.run([str(EXE), "sweep", str(sweep_dir / "sweep.yaml"), "-o", str(out), "--workers", "1",
                           "--json"], capture_output=True, text=True, timeout=HANG_S)
    assert done.returncode == 0, done.stderr
    doc = json.loads(done.stdout)
    assert doc["resumed"] >= before and doc["resumed"] + doc["computed"] == 24
    for row, expected in zip(_read(out), rows):
        _same(row, expected)


# the quick set interrupts once, mid-start; the slow set earlier and later too (the same contract at other moments)
@pytest.mark.parametrize("after_s", [pytest.param(0.5, marks=pytest.mark.slow), 1.5,
                                     pytest.param(3.0, marks=pytest.mark.slow)])
def test_ctrl_c_while_the_sweep_starts_is_one_line(sweep_dir, tmp_path, after_s):
    """SIGINT while the local cluster and its client are starting (Dask's event loop mid-way): exit 130 and the
    one line "interrupted" -- never asyncio's "Task exception was never retrieved" and its tracebacks (a run that
    got further, or finished, is fine too; its stderr still holds no traceback)."""
    out = tmp_path / "results.csv"
    proc = subprocess.Popen([str(EXE), "sweep", str(sweep_dir / "sweep.yaml"), "-o", str(out), "--workers", "2"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    time.sleep(after_s)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=HANG_S)
    package = str(Path(__import__("nurbsinterp").__file__).parent)
    if "KeyboardInterrupt" in stderr and package not in stderr and "nurbsinterp._entry" in stderr:
        return  # on a loaded machine, still in the interpreter's own start: Python's message (tests/test_startup.py)
    assert "Traceback" not in stderr and "never retrieved" not in stderr and "Exception" not in stderr, stderr
    if proc.returncode == 0:
        return
    assert proc.returncode == 130, stderr
    assert stderr.splitlines()[-1] == "nurbsinterp: interrupted", stderr
    assert not out.exists()


def test_a_second_cluster_on_the_machine_draws_no_port_warning(sweep_dir, tmp_path):
    """Port 8787 (Dask's default HTTP port) held by someone else: the local cluster takes a free loopback port
    without a word -- stderr holds the sweep's own lines only, no "already in use" warning."""
    import socket

    holder = socket.socket()
    try:
        holder.bind(("0.0.0.0", 8787))
        holder.listen()
    except OSError:
        pass  # taken already: the condition under test holds anyway
    try:
        done = subprocess.run([str(EXE), "sweep", str(sweep_dir / "sweep.yaml"), "-o", str(tmp_path / "r.csv"),
                               "--workers", "1", "--json"], capture_output=True, text=True, timeout=HANG_S)
    finally:
        holder.close()
    assert done.returncode == 0, done.stderr
    assert "already in use" not in done.stderr and "Warning" not in done.stderr, done.stderr


def test_a_worker_killed_mid_sweep_costs_only_its_cases(sweep_dir, rows, cluster, capsys, tmp_path):
    address, procs, client = cluster
    out = tmp_path / "results.csv"
    proc = subprocess.Popen([str(EXE), "sweep", str(sweep_dir / "sweep.yaml"), "-o", str(out), "--scheduler",
                             address, "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    w0 = next(a for a, w in client.scheduler_info()["workers"].items() if w["name"] == "w0")
    deadline = time.monotonic() + HANG_S
    while not any(str(k).startswith("nurbsinterp-case-") for k in client.processing().get(w0, ())):
        assert proc.poll() is None, proc.communicate()[1]
        assert time.monotonic() < deadline, "no case reached w0"
        time.sleep(0.05)
    procs["w0"].kill()
    stdout, stderr = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 0, stderr
    doc = json.loads(stdout)
    assert doc["lost"] == 0 and doc["ok"] + doc["failed"] == 24
    written = _read(out)
    for row, expected in zip(written, rows):
        _same(row, expected)
    assert any(r["worker"] != w0 for r in written)


def test_without_dask_sweep_says_what_to_install(sweep_dir, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    code, out, err = run_main(capsys, "sweep", sweep_dir / "sweep.yaml", "-o", sweep_dir / "x.csv")
    assert_one_line_error(code, out, err, "pip install 'nurbsinterp[dask]'")
    assert not (sweep_dir / "x.csv").exists()


# the bundled sweep's 88 cases on a local cluster, a minute of CPU: in the slow set; the quick set runs a sweep on a
# local cluster in test_an_interrupted_sweep_keeps_its_rows_and_resumes
@pytest.mark.slow
def test_the_readme_sweep_runs_for_a_new_user(tmp_path):
    out = tmp_path / "results.csv"
    done = subprocess.run([str(EXE), "sweep", "sweeps/bundled.yaml", "-o", str(out)], cwd=ROOT, capture_output=True,
                          text=True, timeout=HANG_S)
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("88 cases (0 from an earlier run, 88 computed on local")
    assert "failed cases" in done.stdout
    rows = _read(out)
    assert len(rows) == 88 and all(r["status"] in ("ok", "failed") for r in rows)
    assert all("z axis" in r["error"] for r in rows if r["status"] == "failed")


def test_the_clients_index_of_cases_and_rows_does_not_grow_in_memory(tmp_path):
    """Ten times the cases, not ten times the client's Python memory: the order of the cases and where each row
    is live on disk (results.Partial's index); the final file is still every row, in case order."""
    import tracemalloc

    from nurbsinterp.sweep.results import Partial, read_rows

    def run(n):
        partial = Partial(str(tmp_path / f"r{n}.csv"), fresh=True)
        tracemalloc.start()
        for i in range(n):
            fp = f"{i * 7919 % n:032x}"  # the rows arrive in another order than the cases'
            partial.case(fp, {"program": f"p{i % 13}.ngc", "machine": "m", "servo": None})
            if not partial.done(fp):
                partial.add({**dict.fromkeys(COLUMNS), "case": i, "case_fingerprint": fp, "program": "old name",
                             "machine": "m", "status": "ok", "ticks": i})
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        partial.finish()
        return peak

    small, large = run(2_000), run(20_000)
    assert large < small + 512 * 1024, (small, large)
    got = list(read_rows(str(tmp_path / "r20000.csv")))
    assert [r["case"] for r in got] == list(range(20_000))
    assert [r["program"] for r in got[:14]] == [f"p{i % 13}.ngc" for i in range(14)]  # this run's labels
    assert [r["ticks"] for r in got[:3]] == [0, 1, 2]
    assert not (tmp_path / "r20000.csv.partial").exists()


def test_a_task_collected_after_an_interrupt_logs_nothing(caplog):
    """What the interrupted client leaves behind (a task whose AllExit nobody retrieved) may be collected after the
    cluster has closed, as the interrupt's traceback lets go of its frames: asyncio's "Task exception was never
    retrieved" must not be logged then either (it was, between the cluster's close and main's report)."""
    import asyncio
    import gc
    import logging

    from nurbsinterp.sweep.cluster import Cluster

    class Closed:
        def close(self):
            pass

    async def fails():
        raise RuntimeError("AllExit stand-in")

    log = logging.getLogger("asyncio")
    level = log.level
    loop = asyncio.new_event_loop()
    try:
        task = loop.create_task(fails())
        loop.run_until_complete(asyncio.sleep(0.01))
        assert task.done()
        Cluster.__exit__(Closed(), KeyboardInterrupt, KeyboardInterrupt(), None)
        del task
        gc.collect()
        assert "never retrieved" not in caplog.text
    finally:
        loop.close()
        log.setLevel(level)


def test_the_interrupt_silences_asyncio_at_once():
    """The client's event loop runs in a thread of its own, which may collect (and log) the task the interrupt cut
    short before the main thread has unwound to the cluster's exit: the signal handler itself silences asyncio."""
    import logging

    from nurbsinterp import cli

    log = logging.getLogger("asyncio")
    level = log.level
    try:
        with pytest.raises(KeyboardInterrupt):
            cli._on_signal(signal.SIGINT, None)
        assert log.level > logging.CRITICAL
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)  # (the handler arms the alarm that raises it again)
        cli._pending = None
        log.setLevel(level)


def test_the_local_cluster_s_workers_log_nothing_below_critical():
    """A worker process of the local cluster logs nothing the sweep has not said: its `distributed` loggers are
    at CRITICAL from its start (a worker's INFO "Received 'close-stream'" line followed "interrupted" after a
    Ctrl-C once).  The level is read in the worker itself."""
    import logging

    from nurbsinterp.sweep.cluster import Cluster

    def levels():
        import logging as worker_logging

        return [worker_logging.getLogger(name).getEffectiveLevel()
                for name in ("distributed.core", "distributed.worker", "distributed.nanny", "distributed.comm")]

    with Cluster(workers=1) as local:
        found = local.client.run(levels)
    assert found and all(level >= logging.CRITICAL for worker in found.values() for level in worker), found
