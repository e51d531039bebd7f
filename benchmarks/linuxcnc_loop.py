"""LinuxCNC's own loop identified and compensated (issue 30): the README's closed-loop table.

    python benchmarks/linuxcnc_loop.py [--keep DIR]     # the table's rows on stdout (about a minute)

On examples/linuxcnc/sim-machine.hal (LinuxCNC's pid driving `scale` + `lowpass` + `integ` drives whose
values the fit is not told), in a servo thread of 1 ms run by `halrun`:

1. stream curves/excitation.yaml through it (examples/linuxcnc/stream.sh) and capture;
2. `nurbsinterp identify` the capture with the pid's gains (`--pid`): fitted.yaml, and the same with the
   strictly proper family lag1 only (what the servo file could hold before proper plants);
3. stream the paper's circle through it as planned, and pre-compensated (`plan --precompensate`) for the
   fitted model, for the fitted model with its gain 5 % high and 5 % low, and for the lag1 fit;
4. measure each capture with `simulate --actual`: the machine's own contour error.

Needs `halrun` (Debian package linuxcnc-uspace).  HAL refuses root: as root, halrun runs as the user
$NURBSINTERP_HAL_USER (default nobody) through runuser, with the files staged where that user can read them.
"""
from __future__ import annotations

import argparse
import json
import os
import pwd
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "linuxcnc"
CIRCLE = ROOT / "curves" / "circle.yaml"
EXCITATION = ROOT / "curves" / "excitation.yaml"
NURBSINTERP = str(Path(sys.executable).with_name("nurbsinterp"))
PID = "x.Pgain=60,y.Pgain=90,FF1=0.95"  # sim-machine.hal's setp pid.*
RUN_LIMIT = 900  # s: only to catch a hang


class Unavailable(Exception):
    """LinuxCNC cannot run here: the reason."""


def halrun_command(work: Path) -> str:
    """The halrun command for this user (Unavailable: why not)."""
    if shutil.which("halrun") is None:
        raise Unavailable("halrun not on PATH (Debian package linuxcnc-uspace)")
    if os.geteuid() != 0:
        return "halrun"
    user = os.environ.get("NURBSINTERP_HAL_USER", "nobody")
    if shutil.which("runuser") is None:
        raise Unavailable("running as root, which HAL refuses, and runuser is missing")
    try:
        pwd.getpwnam(user)
    except KeyError:
        raise Unavailable(f"running as root, which HAL refuses, and there is no user {user!r} "
                          "(set NURBSINTERP_HAL_USER)") from None
    home = work / "hal-home"  # rtapi_app keeps its socket in $HOME
    home.mkdir(exist_ok=True)
    home.chmod(0o777)
    return f"runuser -u {user} -- env HOME={home} halrun"


def stage(work: Path) -> Path:
    """The example's files where any user can read them (a clone may sit in a private directory)."""
    where = work / "linuxcnc"
    where.mkdir(exist_ok=True)
    for name in ("stream.sh", "sim-machine.hal"):
        shutil.copy2(EXAMPLE / name, where / name)
    for path in (where, *where.iterdir()):
        path.chmod(0o777 if path.is_dir() else 0o755)
    return where


def nurbsinterp(*args) -> subprocess.CompletedProcess:
    done = subprocess.run([NURBSINTERP, *map(str, args)], capture_output=True, text=True, timeout=RUN_LIMIT)
    if done.returncode != 0:
        raise RuntimeError(f"nurbsinterp {' '.join(map(str, args))}: {done.stderr.strip()}")
    return done


def stream(work: Path, halrun: str, job: Path, capture: Path, *plan_options) -> None:
    """stream.sh sim-machine.hal JOB [plan options] > capture."""
    where = stage(work)
    env = dict(os.environ, NURBSINTERP=NURBSINTERP, HALRUN=halrun, SERVO_PERIOD="1000000")
    with capture.open("w") as out:
        done = subprocess.run(["sh", str(where / "stream.sh"), str(where / "sim-machine.hal"), str(job),
                               *map(str, plan_options)], env=env, stdout=out, stderr=subprocess.PIPE, text=True,
                              timeout=RUN_LIMIT)
    if "Realtime already running" in done.stderr:
        raise Unavailable("a LinuxCNC realtime session is running on this machine (halrun -U stops it)")
    if done.returncode != 0:
        raise RuntimeError(f"stream.sh {job.name}: {done.stderr.strip()}")


def shared(work: Path, path: Path) -> Path:
    """*path* copied where halrun's user can read it (a servo file given to the plan stream.sh runs)."""
    out = stage(work) / path.name
    shutil.copy2(path, out)
    out.chmod(0o644)
    return out


def scaled(fitted: Path, factor: float, out: Path) -> Path:
    """The fitted model with every axis' gain times *factor*: a model that is that wrong."""
    sys.path.insert(0, str(ROOT / "src"))
    from nurbsinterp.servo import ModelError, load_servo, servo_text

    model = load_servo(fitted)
    wrong = ModelError(f"gain x{factor:g}", {a: factor for a in model.axes}, {}).apply(model)
    out.write_text(servo_text(wrong, [f"{fitted.name} with every gain x{factor:g}"]))
    return out


def measure(capture: Path, servo: Path, precompensate: Path | None) -> dict:
    """The machine's contour error on the circle from its capture, and the model's (simulate --actual)."""
    if precompensate is None:
        done = nurbsinterp("simulate", "--plan", "--job", CIRCLE, "--servo", servo, "--actual", capture, "--json")
    else:
        plan = subprocess.run([NURBSINTERP, "plan", str(CIRCLE), "--precompensate", str(precompensate), "-q",
                               "--format", "bin"], capture_output=True, timeout=RUN_LIMIT, check=True)
        done = subprocess.run([NURBSINTERP, "simulate", "--job", str(CIRCLE), "--servo", str(servo), "--actual",
                               str(capture), "--json"], input=plan.stdout, capture_output=True, timeout=RUN_LIMIT)
        if done.returncode != 0:
            raise RuntimeError(f"simulate --actual {capture.name}: {done.stderr.decode().strip()}")
    report = json.loads(done.stdout)
    return {"model_max": report["contour_error_max"], "machine_max": report["measured"]["contour_error_max"],
            "machine_rms": report["measured"]["contour_error_rms"]}


def run(work: Path) -> dict:
    """The whole experiment in *work*: the identification reports and the measured rows."""
    halrun = halrun_command(work)
    excite = work / "excite.txt"
    stream(work, halrun, EXCITATION, excite)
    fits = {}
    for name, extra in (("fitted", []), ("lag1", ["--family", "lag1"])):
        path = work / f"{name}.yaml"
        report = nurbsinterp("identify", excite, "--job", EXCITATION, "--pid", PID, "-o", path, "--json", *extra)
        fits[name] = (path, json.loads(report.stdout))
    fitted = fits["fitted"][0]
    cases = [("as planned", None),
             ("pre-compensated: the fitted model (hal-lowpass)", fitted),
             ("pre-compensated: the fitted model, its gains 5 % high", scaled(fitted, 1.05, work / "plus5.yaml")),
             ("pre-compensated: the fitted model, its gains 5 % low", scaled(fitted, 0.95, work / "minus5.yaml")),
             ("pre-compensated: the fit in lag1 (strictly proper)", fits["lag1"][0])]
    rows = []
    for label, model in cases:
        capture = work / f"circle-{len(rows)}.txt"
        options = [] if model is None else ["--precompensate", shared(work, model)]
        stream(work, halrun, CIRCLE, capture, *options)
        rows.append((label, measure(capture, fitted, model)))
    return {"identified": {k: v[1] for k, v in fits.items()}, "rows": rows}


TABLE_HEAD = ("| commands streamed (the circle) | machine's contour error max (µm) | RMS (µm) |\n"
              "|---|---|---|")


def table_rows(result: dict) -> list[str]:
    lines = TABLE_HEAD.splitlines()
    for label, m in result["rows"]:
        lines.append(f"| {label} | {_um(m['machine_max'])} | {_um(m['machine_rms'])} |")
    return lines


def identified_rows(result: dict) -> list[str]:
    """The fit against sim-machine.hal's own values (its setp lines)."""
    truth = {"x": (0.97, 0.25), "y": (1.02, 0.4)}
    lines = ["| axis | K found (HAL: scale) | lowpass gain found (HAL) | residual RMS (µm) | lag1's residual RMS (µm) |",
             "|---|---|---|---|---|"]
    fitted, lag1 = result["identified"]["fitted"], result["identified"]["lag1"]
    for a, (k, g) in truth.items():
        r = fitted["axes"][a]
        p = r["parameters"]
        lines.append(f"| {a} | {p['K']['value']:.6f} ± {p['K']['std'] * 100:.1g} % ({k:g}) | "
                     f"{p['g']['value']:.6f} ± {p['g']['std'] * 100:.1g} % ({g:g}) | {_um(r['residual_rms'])} | "
                     f"{_um(lag1['axes'][a]['residual_rms'])} |")
    return lines


def _um(mm: float) -> str:
    um = mm * 1e3
    return f"{um:.2f}" if um >= 0.1 else f"{um:.4f}" if um >= 1e-4 else f"{um:.1e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--keep", metavar="DIR", help="run in DIR and keep the captures and models")
    args = parser.parse_args()
    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="nurbsinterp-loop-"))
    work.mkdir(parents=True, exist_ok=True)
    work.chmod(0o777)
    try:
        result = run(work)
    except Unavailable as exc:
        raise SystemExit(f"{sys.argv[0]}: {exc}") from None
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print("\n".join(identified_rows(result) + [""] + table_rows(result)))


if __name__ == "__main__":
    main()
