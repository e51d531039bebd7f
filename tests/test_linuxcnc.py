"""The plan through LinuxCNC's HAL and back (issue 17, item 3): examples/linuxcnc/loopback.sh.

The script pipes ``nurbsinterp plan JOB --format hal --columns k,x,y`` into
``halstreamer``; LinuxCNC's ``streamer`` puts each line on its pins in a servo
thread of the plan's period, ``sampler`` records them (while the streamer has
fresh data) with the streamer's underrun count, and ``halsampler`` prints them.
The script then checks that every tick came back in order, within the 5e-7 mm
of halsampler's ``%f``, and that the underrun count never moved during the
stream.  Here the same files are read again and held to the same facts
independently, and to exact equality where the commands are quantised to
1 um or written in counts (their decimals fit in %f's six).

Opt-in: the HAL tests run where ``halrun`` is on PATH (Debian package
``linuxcnc-uspace``).  HAL refuses root; as root they run halrun as the user
``$NURBSINTERP_HAL_USER`` (default ``nobody``) through ``runuser``, with a
scratch HOME (rtapi_app keeps its socket there), or skip saying why.  A
realtime session already running (a machine's LinuxCNC) makes them skip too.

The script's own check is tested everywhere, LinuxCNC or not, against a fake
halrun that loses a tick, reorders, or reports an underrun: it must fail.
"""
from __future__ import annotations

import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "linuxcnc"
CIRCLE = ROOT / "curves" / "circle.yaml"
NURBSINTERP = str(Path(sys.executable).with_name("nurbsinterp"))
HALF_DIGIT = 5e-7 + 1e-12  # mm: %f's rounding to 6 decimals, and the double nearest to each printed value
RUN_LIMIT = 600  # s: only to catch a hang (a circle takes 3.6 s of servo thread)


def _tools() -> bool:
    return all(shutil.which(t) for t in ("sh", "awk", "paste", "tee", "wc"))


@pytest.fixture
def shared_dir():
    """A scratch directory any user can enter (pytest's own sit under a private /tmp/pytest-of-USER)."""
    path = Path(tempfile.mkdtemp(prefix="nurbsinterp-hal-"))
    path.chmod(0o777)
    yield path
    shutil.rmtree(path, ignore_errors=True)


def _staged(where: Path) -> Path:
    """The example's two files copied where any user can read them (a clone may sit in a private directory)."""
    stage = where / "linuxcnc"
    stage.mkdir()
    for name in ("stream.sh", "loopback.sh", "loopback.hal", "sim-machine.hal"):
        shutil.copy2(EXAMPLE / name, stage / name)
    for path in (stage, *stage.iterdir()):
        path.chmod(0o777 if path.is_dir() else 0o755)
    return stage


def _halrun(where: Path) -> str:
    """The halrun command for this user, or skip: HAL refuses root."""
    if shutil.which("halrun") is None:
        pytest.skip("halrun not on PATH (Debian package linuxcnc-uspace)")
    if os.geteuid() != 0:
        return "halrun"
    user = os.environ.get("NURBSINTERP_HAL_USER", "nobody")
    if shutil.which("runuser") is None:
        pytest.skip("running as root, which HAL refuses, and runuser (to run halrun as another user) is missing")
    try:
        pwd.getpwnam(user)
    except KeyError:
        pytest.skip(f"running as root, which HAL refuses, and there is no user {user!r} to run halrun as "
                    "(set NURBSINTERP_HAL_USER)")
    home = where / "hal-home"  # rtapi_app keeps its socket in $HOME
    home.mkdir()
    home.chmod(0o777)
    return f"runuser -u {user} -- env HOME={home} halrun"


def _loopback(where: Path, halrun: str, *plan_options: str) -> tuple[subprocess.CompletedProcess, Path]:
    stage = _staged(where)
    keep = where / "keep"
    keep.mkdir()
    env = dict(os.environ, NURBSINTERP=NURBSINTERP, HALRUN=halrun, KEEP=str(keep), SERVO_PERIOD="1000000")
    done = subprocess.run(["sh", str(stage / "loopback.sh"), str(CIRCLE), *plan_options], env=env,
                          capture_output=True, text=True, timeout=RUN_LIMIT)
    if "Realtime already running" in done.stderr:
        pytest.skip("a LinuxCNC realtime session is running on this machine (halrun -U stops it)")
    return done, keep


def _read(path: Path, columns: int) -> np.ndarray:
    rows = np.loadtxt(path, ndmin=2)
    assert rows.shape[1] == columns, f"{path.name}: {rows.shape[1]} columns"
    return rows


def _check_came_back(done, keep, exact: bool) -> None:
    assert done.returncode == 0, done.stderr
    sent, back = _read(keep / "sent.txt", 3), _read(keep / "capture.txt", 4)
    ticks = sent.shape[0]
    assert ticks == 3643  # the circle at 1 ms: k = 0 .. 3642
    assert back.shape[0] == ticks, "a tick is missing or extra"
    assert np.array_equal(sent[:, 0], np.arange(ticks)) and np.array_equal(back[:, 0], sent[:, 0]), "order"
    if exact:
        assert np.array_equal(back[:, 1:3], sent[:, 1:3])
    else:
        assert np.abs(back[:, 1:3] - sent[:, 1:3]).max() <= HALF_DIGIT
    assert np.all(back[:, 3] == back[0, 3]), "the streamer ran dry during the stream"
    assert f"{ticks} ticks came back in order" in done.stderr


# --------------------------------------------------------------------------- with LinuxCNC


def test_the_circle_streams_through_hal_and_back(shared_dir):
    done, keep = _loopback(shared_dir, _halrun(shared_dir))
    _check_came_back(done, keep, exact=False)


def test_quantised_commands_come_back_exactly(shared_dir):
    """1 um has 3 decimals: halsampler's %f prints the very value sent."""
    done, keep = _loopback(shared_dir, _halrun(shared_dir), "--resolution", "1um")
    _check_came_back(done, keep, exact=True)
    micrometres = np.loadtxt(keep / "sent.txt")[:, 1:] * 1000
    assert np.abs(micrometres - np.round(micrometres)).max() < 1e-9  # whole micrometres


def test_counts_come_back_exactly(shared_dir):
    done, keep = _loopback(shared_dir, _halrun(shared_dir), "--resolution", "2000/mm", "--counts")
    _check_came_back(done, keep, exact=True)
    sent = np.loadtxt(keep / "sent.txt")
    assert np.array_equal(sent, np.round(sent)) and np.abs(sent[:, 1:]).max() == 200_000  # 100 mm at 0.5 um


def test_a_simulated_machine_in_hal_measured_by_simulate_actual(shared_dir):
    """sim-machine.hal: LinuxCNC's pid loops driving simulated drives, recorded by halsampler; then
    `simulate --actual` on the capture.  On the circle (centre (50, 0), R = 50) the contour error of a point p
    is ||p - c| - R| in closed form: the machine's measured contour error must be that, to rounding, on the
    captured feedback itself, and the commands must have arrived as sent."""
    halrun = _halrun(shared_dir)
    stage = _staged(shared_dir)
    capture = shared_dir / "capture.txt"
    env = dict(os.environ, NURBSINTERP=NURBSINTERP, HALRUN=halrun, SERVO_PERIOD="1000000")
    with capture.open("w") as out:
        done = subprocess.run(["sh", str(stage / "stream.sh"), str(stage / "sim-machine.hal"), str(CIRCLE)], env=env,
                              stdout=out, stderr=subprocess.PIPE, text=True, timeout=RUN_LIMIT)
    if "Realtime already running" in done.stderr:
        pytest.skip("a LinuxCNC realtime session is running on this machine (halrun -U stops it)")
    assert done.returncode == 0, done.stderr
    rows = _read(capture, 5)  # k, x_cmd, y_cmd, x, y
    assert np.array_equal(rows[:, 0], np.arange(3643))
    report = subprocess.run([NURBSINTERP, "simulate", "--plan", "--job", str(CIRCLE), "--actual", str(capture), "--json"],
                            capture_output=True, text=True, timeout=RUN_LIMIT)
    assert report.returncode == 0, report.stderr
    measured = json.loads(report.stdout)["measured"]
    feedback = rows[:, 3:5]
    radial = np.abs(np.hypot(feedback[:, 0] - 50.0, feedback[:, 1]) - 50.0)
    assert measured["ticks"] == 3643 and measured["hold_ticks"] == 0
    assert abs(measured["contour_error_max"] - radial.max()) <= 1e-9
    assert abs(measured["contour_error_rms"] - np.sqrt(np.mean(radial ** 2))) <= 1e-9
    for i, axis in enumerate("xy"):  # tracking error is against the plan's commands, the capture's are rounded
        assert abs(measured["tracking_error_max"][axis] - np.abs(rows[:, 1 + i] - rows[:, 3 + i]).max()) <= HALF_DIGIT
        assert measured["as_received_max"][axis] <= HALF_DIGIT
    # the pid loops lag: tens of um on the circle, as the paper's table does (181.5 um with its slower loops)
    assert 1e-3 < measured["contour_error_max"] < 0.1


def _stream(stage, halrun, job, capture, *plan_options):
    env = dict(os.environ, NURBSINTERP=NURBSINTERP, HALRUN=halrun, SERVO_PERIOD="1000000")
    with capture.open("w") as out:
        done = subprocess.run(["sh", str(stage / "stream.sh"), str(stage / "sim-machine.hal"), str(job),
                               *map(str, plan_options)], env=env, stdout=out, stderr=subprocess.PIPE, text=True,
                              timeout=RUN_LIMIT)
    if "Realtime already running" in done.stderr:
        pytest.skip("a LinuxCNC realtime session is running on this machine (halrun -U stops it)")
    assert done.returncode == 0, done.stderr


def test_the_machine_identified_and_its_lag_compensated(shared_dir):
    """Issue 30 on LinuxCNC's own loop: the excitation job through sim-machine.hal, `identify` with the pid's
    gains, and the circle pre-compensated for the fitted model streamed through the same machine.  The fit must
    find the drives' setp values (scale 0.97/1.02, lowpass 0.25/0.4) and predict the capture within 1 um RMS; the
    machine's own contour error on the compensated circle must be at most 1 um (54.9 um as planned)."""
    halrun = _halrun(shared_dir)
    stage = _staged(shared_dir)
    excite = shared_dir / "excite.txt"
    _stream(stage, halrun, ROOT / "curves" / "excitation.yaml", excite)
    fitted = shared_dir / "fitted.yaml"
    done = subprocess.run([NURBSINTERP, "identify", str(excite), "--job", str(ROOT / "curves" / "excitation.yaml"),
                           "--pid", "x.Pgain=60,y.Pgain=90,FF1=0.95", "-o", str(fitted), "--json"],
                          capture_output=True, text=True, timeout=RUN_LIMIT)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout)
    for axis, (scale, gain) in {"x": (0.97, 0.25), "y": (1.02, 0.4)}.items():
        fit = report["axes"][axis]
        assert fit["family"] == "hal-lowpass" and fit["delay"] == 1  # the sampler runs after the drive
        assert fit["parameters"]["K"]["value"] == pytest.approx(scale, rel=1e-3)
        assert fit["parameters"]["g"]["value"] == pytest.approx(gain, rel=1e-3)
        assert fit["residual_rms"] <= 1e-3
    fitted.chmod(0o644)
    compensated = shared_dir / "compensated.txt"
    # with the start guard: the first command held 20 ticks before tick 0, which the capture's alignment drops
    _stream(stage, halrun, CIRCLE, compensated, "--precompensate", fitted, "--hold-start", "20 ms")
    plan = subprocess.run([NURBSINTERP, "plan", str(CIRCLE), "--precompensate", str(fitted), "-q", "--format", "bin"],
                          capture_output=True, timeout=RUN_LIMIT)
    assert plan.returncode == 0, plan.stderr
    measured = subprocess.run([NURBSINTERP, "simulate", "--job", str(CIRCLE), "--servo", str(fitted), "--actual",
                               str(compensated), "--json"], input=plan.stdout, capture_output=True, timeout=RUN_LIMIT)
    assert measured.returncode == 0, measured.stderr
    machine = json.loads(measured.stdout)["measured"]
    rows = _read(compensated, 5)
    radial = np.abs(np.hypot(rows[:, 3] - 50.0, rows[:, 4]) - 50.0)  # the circle's closed form, on the feedback
    assert abs(machine["contour_error_max"] - radial.max()) <= 1e-9
    assert machine["contour_error_max"] <= 1e-3
    assert machine["capture_lead_rows"] == 20 and np.all(rows[:21, 0] == 0)


# --------------------------------------------------------------------------- the script's check, without LinuxCNC

FAKE = """\
#!/bin/sh
# a fake halrun: prints what halstreamer -> streamer -> sampler -> halsampler would, with a fault
awk '{ %s }'
"""


@pytest.mark.skipif(not _tools(), reason="needs sh, awk, paste, tee, wc")
@pytest.mark.parametrize("fault,message", [
    ('printf "%d %f %f 7\\n", $1, $2, $3', None),  # faithful: %f and a steady underrun count
    ('if (NR != 100) printf "%d %f %f 7\\n", $1, $2, $3', "came back where tick"),  # a tick lost
    # (each fault a run of the script: the quick set tries the faithful echo and two faults, the slow set all)
    pytest.param('if (NR == 10) { hold = $0; next } printf "%d %f %f 7\\n", $1, $2, $3; if (NR == 11) print hold, 7',
                 "came back where tick", marks=pytest.mark.slow),  # two ticks swapped
    pytest.param('printf "%d %f %f %d\\n", $1, $2, $3, (NR > 50 ? 8 : 7)', "ran dry 1 time(s)",
                 marks=pytest.mark.slow),  # an underrun
    ('printf "%d %f %f 7\\n", $1, $2 + (NR == 30 ? 1e-5 : 0), $3', "tick 29: sent"),  # a value changed
    pytest.param('if (NR < 3643) printf "%d %f %f 7\\n", $1, $2, $3', "a tick is missing",
                 marks=pytest.mark.slow),  # the last tick lost
])
def test_the_loopback_check_fails_on_every_fault(tmp_path, fault, message):
    stage = _staged(tmp_path)
    fake = stage / "fake-halrun"
    fake.write_text(FAKE % fault)
    fake.chmod(0o755)
    env = dict(os.environ, NURBSINTERP=NURBSINTERP, HALRUN=str(fake), SERVO_PERIOD="1000000")
    done = subprocess.run(["sh", str(stage / "loopback.sh"), str(CIRCLE)], env=env, capture_output=True, text=True,
                          timeout=RUN_LIMIT)
    if message is None:
        assert done.returncode == 0, done.stderr
        assert "3643 ticks came back in order, each within 5.0e-07 mm" in done.stderr
    else:
        assert done.returncode == 1, done.stderr
        assert message in done.stderr


FLAKY_PLAN = """\
#!/bin/sh
# a fake nurbsinterp: a plan that dies mid-stream, its first 100 ticks written
"%(real)s" "$@" | head -n 100
exit 3
"""


@pytest.mark.skipif(not _tools(), reason="needs sh, awk, paste, tee, wc")
@pytest.mark.parametrize("case", ["bad job", "dies mid-stream"])
def test_the_scripts_fail_when_the_plan_fails(tmp_path, case):
    """sh has no pipefail: a failed plan must still fail the script, not pass as a short (or empty) stream."""
    stage = _staged(tmp_path)
    halrun = stage / "fake-halrun"
    halrun.write_text(FAKE % 'printf "%d %f %f 7\\n", $1, $2, $3')
    halrun.chmod(0o755)
    plan, job = NURBSINTERP, str(CIRCLE)
    if case == "bad job":
        job = str(tmp_path / "missing.yaml")
    else:
        fake = tmp_path / "fake-nurbsinterp"
        fake.write_text(FLAKY_PLAN % {"real": NURBSINTERP})
        fake.chmod(0o755)
        plan = str(fake)
    env = dict(os.environ, NURBSINTERP=plan, HALRUN=str(halrun), SERVO_PERIOD="1000000")
    done = subprocess.run(["sh", str(stage / "loopback.sh"), job], env=env, capture_output=True, text=True,
                          timeout=RUN_LIMIT)
    assert done.returncode == 1, done.stderr
    assert "nurbsinterp plan failed" in done.stderr and "came back in order" not in done.stderr


def test_the_loopback_refuses_root_without_halrun_given(tmp_path):
    if os.geteuid() != 0:
        pytest.skip("the refusal is of root")
    stage = _staged(tmp_path)
    env = {k: v for k, v in os.environ.items() if k != "HALRUN"}
    done = subprocess.run(["sh", str(stage / "loopback.sh"), str(CIRCLE)], env=dict(env, NURBSINTERP=NURBSINTERP),
                          capture_output=True, text=True, timeout=RUN_LIMIT)
    assert done.returncode == 2 and "HAL refuses to run as root" in done.stderr
