"""Regenerate the results tables of README and docs/*.md from the code that computes them.

    .venv/bin/python docs/readme_tables.py            # rewrite the deterministic tables where they are
    .venv/bin/python docs/readme_tables.py --check    # exit 1 if any of them is stale (what the test does)
    .venv/bin/python docs/readme_tables.py --timing   # also re-measure the timing tables (minutes; machine-dependent)
    .venv/bin/python docs/readme_tables.py --only NAME ...   # only these tables (timing ones too)

Each table sits between ``<!-- generated: NAME -->`` and ``<!-- end: NAME -->`` in one of the
pages (README.md or a docs/*.md page: whichever holds it; each name in exactly one page).  The
deterministic ones (the paper's experiments on the circle, the interpolators' fluctuation, the
adaptive planner on the butterfly) are the same on every run of the same code, so
tests/test_readme.py fails when a page no longer says what the code computes.  The timing tables
(``bench``, start-up, the peers and the limit; and LinuxCNC's loop, which needs halrun) depend on
the machine: the script refreshes them with --timing and no test compares them.
"""
from __future__ import annotations

import argparse
import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
CIRCLE = ROOT / "curves" / "circle.yaml"
BUTTERFLY = ROOT / "curves" / "butterfly.yaml"
ADAPTIVE = ROOT / "profiles" / "adaptive.yaml"
BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- end: (?P=name) -->)", re.S)


def compare_circle() -> list[str]:
    """`nurbsinterp compare curves/circle.yaml`: every variant through the paper's servo model."""
    from nurbsinterp.compare import compare
    from nurbsinterp.servo import PAPER_TABLE
    from nurbsinterp.config import load_job
    from nurbsinterp.cli.common import load_cli

    rows = compare(load_job(CIRCLE), PAPER_TABLE)
    out = ["| method | profile | acc/dec | max \\|FF\\| | contour max (µm) | contour RMS (µm) | "
           "feedrate error max (mm/s) | feedrate error RMS (mm/s) | motion time (s) |",
           "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.interpolator} | {r.profile} | {r.accdec} | {r.ff_max:.1e} | "
                   f"{r.contour_error_max * 1e3:.1f} | {r.contour_error_rms * 1e3:.1f} | "
                   f"{r.feedrate_error_max:.2f} | {r.feedrate_error_rms:.2f} | {r.motion_time:.3f} |")
    return out


def _measured_run(job):
    """Plan and interpolate *job* with the run summary's measures; also the largest |A| and |J| of the stream."""
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.metrics import RunStats

    run = Interpolation(job)
    stats = RunStats(run.curve, run.profile.peak, run.period, deviation=run.after)
    a_col = run.columns.index("a")
    accel = []
    for chunk in run.chunks(derivatives=True):
        stats.update(chunk, run.curve.dim)
        accel.append(chunk.data[:, a_col])
    a = np.concatenate(accel)
    return run, stats, float(np.abs(a).max()), float(np.abs(np.diff(a)).max() / run.period)


def interpolators_circle() -> list[str]:
    """`nurbsinterp plan curves/circle.yaml --interpolator M`: the run summary's fluctuation and end gap."""
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.names import METHODS

    out = ["| interpolator | max \\|FF\\| | RMS FF | end gap (mm) |", "|---|---|---|---|"]
    for method in METHODS:
        run, stats, _, _ = _measured_run(load_cli(CIRCLE, overrides={"interpolator": method}))
        gap = "0" if run.end_gap == 0 else "−" * (run.end_gap < 0) + "+" * (run.end_gap > 0) + f"{abs(run.end_gap):.1e}"
        out.append(f"| {method} | {abs(stats.ff_max):.1e} | {stats.ff_rms:.1e} | {gap} |")
    return out


def adaptive_butterfly() -> list[str]:
    """The butterfly at constant feed against the adaptive schedule, interpolated exactly, through the servo."""
    from nurbsinterp.compare import run_variant
    from nurbsinterp.nurbs import NurbsCurve
    from nurbsinterp.servo import PAPER_TABLE
    from nurbsinterp.cli.common import load_cli

    adaptive = load_cli(BUTTERFLY, profile_file=ADAPTIVE, overrides={"interpolator": "exact"})
    constant = load_cli(BUTTERFLY, overrides={"interpolator": "exact"})
    no_jerk = dataclasses.replace(adaptive, profile=dataclasses.replace(adaptive.profile, max_jerk=None))
    curve = NurbsCurve.from_spec(adaptive.curve)
    cols = []
    for job in (constant, adaptive):
        run, stats, a_max, j_max = _measured_run(job)
        servo = run_variant(job, curve, PAPER_TABLE)
        cols.append(dict(time=run.profile.duration, chord=stats.chord_max * 1e3, a=a_max, j=j_max,
                         contour=servo.contour_error_max * 1e3, feed=servo.feedrate_error_max))
    plan = _measured_run(adaptive)[0].profile.plan
    no_jerk_time = _measured_run(no_jerk)[0].profile.duration
    c, a = cols
    p = constant.profile
    low, slow = plan.slowest, plan.slowest_scheduled
    radius = 1.0 / float(curve.curvature(low.u))
    binding = ", ".join(f"{name} {frac:.1%}" for name, frac in plan.limit_fractions.items() if frac > 0)
    bound = ", ".join(f"{name} {frac:.1%}" for name, frac in plan.bound_fractions.items() if frac > 0)
    return [
        f"| measure | constant feed ({p.type}, {p.feedrate:g} mm/s, Ta = {p.accel_time:g} s) | adaptive "
        f"(`profiles/adaptive.yaml`) |",
        "|---|---|---|",
        f"| motion time (s) | {c['time']:.3f} | {a['time']:.3f} ({no_jerk_time:.3f} without the jerk limit) |",
        f"| max chord error (µm), tolerance 1 | {c['chord']:.3f} | {a['chord']:.3f} |",
        f"| max \\|A\\| of the stream (mm/s²), limit 1000 | {c['a']:.2f} | {a['a']:.2f} |",
        f"| max \\|J\\| of the stream (mm/s³), limit 30 000 | {c['j']:,.0f} (A steps in one tick) | {a['j']:,.0f} |",
        f"| servo model: contour error max (µm) | {c['contour']:.1f} | {a['contour']:.1f} |",
        f"| servo model: feedrate error max (mm/s) | {c['feed']:.1f} | {a['feed']:.1f} |",
        f"| what bounds the schedule | | {bound} of the motion time |",
        f"| where each limit sets the feed limit | | {binding} of the path |",
        f"| lowest feed limit | | {low.v:.3g} mm/s at s = {low.s:.2f} mm (radius {radius:.3f} mm), {low.limit} limit |",
        f"| slowest feed between the ramps | | {slow.v:.3g} mm/s at s = {slow.s:.2f} mm |",
    ]


def quantisation_circle() -> list[str]:
    """The paper's circle with quantised commands (`plan --resolution`) and quantised feedback (encoder_resolution)."""
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.quantise import Quantiser, parse_resolution
    from nurbsinterp.servo import PAPER_TABLE
    from nurbsinterp.simulation import simulate
    from nurbsinterp.config import load_job

    job = load_job(CIRCLE)

    def run(command: str | None, encoder: float | None):
        plan = Interpolation(job)
        quantiser = None if command is None else Quantiser(parse_resolution(command, ("x", "y")), plan.columns)
        model = PAPER_TABLE if encoder is None else dataclasses.replace(PAPER_TABLE, axes={
            a: dataclasses.replace(m, encoder_resolution=encoder) for a, m in PAPER_TABLE.axes.items()})
        chunks = (c.data if quantiser is None else quantiser.apply(c.data).copy() for c in plan.chunks())
        report, _ = simulate(plan.path, model, plan.columns, chunks, name=str(CIRCLE))
        return report

    cases = [(None, None, "exact (9 decimals)", "exact"),
             ("0.5um", None, "0.5 µm", "exact"),
             (None, 0.0005, "exact (9 decimals)", "0.5 µm (2500 lines × 4, 5 mm lead)"),
             ("0.5um", 0.0005, "0.5 µm", "0.5 µm"),
             ("1um", 0.001, "1 µm", "1 µm (2500 × 4, 10 mm lead)"),
             ("10um", 0.01, "10 µm", "10 µm")]
    out = ["| commands (`plan --resolution`) | feedback (`encoder_resolution`) | contour max (µm) | "
           "contour RMS (µm) | tracking max X / Y (µm) | feedrate error max (mm/s) |",
           "|---|---|---|---|---|---|"]
    base = None
    for command, encoder, said, fed in cases:
        r = run(command, encoder)
        base = base or r
        extra = "" if r is base else f" ({(r.contour_error_max - base.contour_error_max) * 1e3:+.2f})"
        out.append(f"| {said} | {fed} | {r.contour_error_max * 1e3:.2f}{extra} | {r.contour_error_rms * 1e3:.2f} | "
                   f"{r.tracking_error_max['x'] * 1e3:.1f} / {r.tracking_error_max['y'] * 1e3:.1f} | "
                   f"{r.feedrate_error_max:.2f} |")
    return out


#: the plants of the pre-compensation tables (docs/precompensation.md): (label, model error text; None the model itself)
PRECOMP_PLANTS = (("the model", None), ("gain +5 % (both axes)", "gain=+5%"), ("gain −5 % (both axes)", "gain=-5%"),
                  ("gain x +5 %, y −5 %", "x.gain=+5%,y.gain=-5%"), ("gain x −5 %, y +5 %", "x.gain=-5%,y.gain=+5%"),
                  ("gain +20 %", "gain=+20%"), ("gain −20 %", "gain=-20%"), ("poles ×1.1 (faster)", "poles=1.1"),
                  ("poles ×0.9 (slower)", "poles=0.9"))


def precompensation_run(job, method, error=None, resolution=None, rounding="nearest", encoder="same"):
    """The simulate report of *job* pre-compensated by *method* ('none': as planned) for the paper's model, run
    on the model changed by *error* (a `--model-error` text); *resolution* quantises the commands (after the
    pre-compensation, by *rounding*) and *encoder* the feedback to that many mm (None: exact; 'same': as the
    commands)."""
    from nurbsinterp.compare import run_shaped
    from nurbsinterp.interpolate import Interpolation
    from nurbsinterp.path import job_path
    from nurbsinterp.precompensate import design
    from nurbsinterp.quantise import Quantiser, parse_resolution
    from nurbsinterp.servo import PAPER_TABLE, parse_model_error

    plant = PAPER_TABLE if error is None else parse_model_error(error, ("x", "y")).apply(PAPER_TABLE)
    plan = None if method == "none" else design(PAPER_TABLE, job.interpolator.period, method, ("x", "y"))
    quantiser = None
    if resolution is not None:
        quantiser = Quantiser(parse_resolution(f"{resolution * 1e3:g}um", ("x", "y")), Interpolation(job).columns,
                              rounding=rounding)
    encoder = resolution if encoder == "same" else encoder
    if encoder is not None:
        plant = dataclasses.replace(plant, axes={a: dataclasses.replace(m, encoder_resolution=encoder)
                                                 for a, m in plant.axes.items()})
    return run_shaped(job, job_path(job).programmed, plant, plan, quantiser, keep_series=True)


def _precompensation_table(job) -> list[str]:
    from nurbsinterp.names import PRECOMPENSATION

    methods = ("none", *PRECOMPENSATION)
    out = ["| plant the commands drive | none (as planned) | exact inverse | ZPETC | axis-lag matching |",
           "|---|---|---|---|---|"]
    cells = {}
    for label, error in PRECOMP_PLANTS:
        cells[label] = [precompensation_run(job, m, error)[0].contour_error_max * 1e3 for m in methods]
        out.append(f"| {label} | " + " | ".join(_um(v) for v in cells[label]) + " |")
    quantised = [precompensation_run(job, m, None, 0.0005)[0].contour_error_max * 1e3 for m in methods]
    out.append("| the model, 0.5 µm commands and encoder | " + " | ".join(_um(v) for v in quantised) + " |")
    five = [label for label, _ in PRECOMP_PLANTS[1:5]]
    for title, labels in (("**worst of the four ±5 % gain errors**", five),
                          ("**worst of the two common ±5 % gain errors**", five[:2])):
        worst = [max(cells[label][i] for label in labels) for i in range(len(methods))]
        out.append(f"| {title} | " + " | ".join(_um(v) for v in worst) + " |")
    return out


def _um(value: float) -> str:
    return f"{value:.3g}" if value < 10 else f"{value:.1f}"


def precompensation_circle() -> list[str]:
    """The paper's circle pre-compensated by every method, on the model and on wrong plants (max contour error)."""
    from nurbsinterp.config import load_job

    return _precompensation_table(load_job(CIRCLE))


def precompensation_butterfly() -> list[str]:
    """The butterfly with the adaptive profile, the same table."""
    from nurbsinterp.cli.common import load_cli

    return _precompensation_table(load_cli(BUTTERFLY, profile_file=ADAPTIVE))


RASTER = ROOT / "curves" / "raster.ngc"
CAM_MACHINE = ROOT / "profiles" / "cam-machine.yaml"
XYZ_SERVO = ROOT / "servo" / "example-xyz.yaml"


def compare_raster() -> list[str]:
    """`nurbsinterp compare curves/raster.ngc --tolerance 5um --profile profiles/cam-machine.yaml --servo
    servo/example-xyz.yaml --precompensate exact`: every profile with look-ahead, and the job's own pre-compensated."""
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.compare import look_ahead_compare, precompensation_study
    from nurbsinterp.servo import load_servo

    job = load_cli(str(RASTER), str(CAM_MACHINE), every_profile=True, stream=True)
    model = load_servo(str(XYZ_SERVO))
    rows = look_ahead_compare(job, 0.005, model)
    study = {r.method: r for r in precompensation_study(job, model, ["exact"], [], look_ahead=True, tolerance=0.005)}
    out = ["| profile | commands' max deviation (µm) | contour max (µm) | contour RMS (µm) | "
           "feedrate error max (mm/s) | motion time (s) |",
           "|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r.profile} | {r.command_deviation_max * 1e3:.3f} | {r.contour_error_max * 1e3:.2f} | "
                   f"{r.contour_error_rms * 1e3:.2f} | {r.feedrate_error_max:.3f} | {r.motion_time:.3f} |")
    p = study["exact"]
    # the job names no profile: its default one is planned to the machine's limits (motion.limits), as adaptive
    own = job.profile.type if job.profile_chosen else "the job's own (the machine's limits)"
    out.append(f"| {own}, pre-compensated (exact) | | {p.contour_error_max * 1e3:.2f} | "
               f"{p.contour_error_rms * 1e3:.2f} | {p.feedrate_error_max:.3f} | |")
    return out


def quantisation_precompensated() -> list[str]:
    """The paper's circle pre-compensated for its own model, commands rounded to 0.5 um plainly or noise-shaped
    (`plan --precompensate --resolution 0.5um --rounding`), the encoder exact or 0.5 um."""
    from nurbsinterp.config import load_job

    job = load_job(CIRCLE)
    methods = ("exact", "zpetc")
    out = ["| commands | encoder | " + " | ".join(f"{m}: contour max (µm)" for m in methods) + " | "
           + " | ".join(f"{m}: RMS (µm)" for m in methods) + " |",
           "|---|---|" + "---|" * (2 * len(methods))]
    for encoder in (None, 0.0005):
        for said, resolution, rounding in (("exact (9 decimals)", None, "nearest"),
                                           ("0.5 µm, `--rounding nearest`", 0.0005, "nearest"),
                                           ("0.5 µm, `--rounding shaped`", 0.0005, "shaped")):
            reports = [precompensation_run(job, m, None, resolution, rounding, encoder)[0] for m in methods]
            fed = "exact" if encoder is None else "0.5 µm"
            # rounded commands: which way a command near a half count rounds is decided by the last bits of the
            # pre-compensator's roots (LAPACK's, which differ between CPUs): 2 significant digits hold on every
            # machine (0.00949 here, 0.00951 there), 3 did not
            um = _um if resolution is None else (lambda value: f"{value:.2g}")
            out.append(f"| {said} | {fed} | " + " | ".join(um(r.contour_error_max * 1e3) for r in reports)
                       + " | " + " | ".join(um(r.contour_error_rms * 1e3) for r in reports) + " |")
    return out


DETERMINISTIC = {
    "compare-circle": compare_circle,
    "compare-raster": compare_raster,
    "interpolators-circle": interpolators_circle,
    "adaptive-butterfly": adaptive_butterfly,
    "quantisation-circle": quantisation_circle,
    "precompensation-circle": precompensation_circle,
    "precompensation-butterfly": precompensation_butterfly,
    "quantisation-precompensated": quantisation_precompensated,
}


def bench_tick() -> list[str]:
    """`nurbsinterp bench --json`: the paper's Table 1 beside this machine."""
    import json

    result = json.loads(subprocess.run([sys.executable, "-m", "nurbsinterp", "bench", str(CIRCLE), "--json"],
                                       capture_output=True, check=True, text=True).stdout)
    m = result["machine"]
    out = ["| interpolator | profile | paper DSP (µs) | mean (µs) | p99 (µs) | speed-up |", "|---|---|---|---|---|---|"]
    for r in result["rows"]:
        paper = "—" if r["paper_us"] is None else f"{r['paper_us']:g}"
        speedup = "—" if r["speedup"] is None else f"{r['speedup']:,.0f}×"
        out.append(f"| {r['interpolator']} | {r['profile']} | {paper} | {r['mean_us']:.3f} | {r['p99_us']:.3f} | {speedup} |")
    s = result["servo"]
    out.append(f"| servo controller | {s['axes']} axes | {s['paper_us']:g} | {s['mean_us']:.3f} | {s['p99_us']:.3f} | "
               f"{s['speedup']:,.0f}× |")
    p = result["precompensation"]
    out.append(f"| `precompensate` (exact inverse) | {p['axes']} axes, {p['preview_ticks']}-tick preview | — | "
               f"{p['mean_us']:.3f} | {p['p99_us']:.3f} | — |")
    out.append(f"\n{m['cpu']}, {m['cores']} cores, Python {m['python']}.")
    return out


def startup() -> list[str]:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import startup as bench_startup

    return bench_startup.markdown(bench_startup.measure(runs=7))


SQUARE = ROOT / "curves" / "square.yaml"
ROUNDED = ROOT / "curves" / "rounded-square.yaml"
#: each row's options, as `nurbsinterp plan curves/square.yaml OPTIONS` (or rounded-square.yaml) takes them
CORNER_ROWS = (
    (SQUARE, ()), (SQUARE, ("--profile-type", "bell")), (SQUARE, ("--accdec", "after")),
    (SQUARE, ("--profile-type", "adaptive", "--max-accel", "1000")),
    (SQUARE, ("--profile-type", "adaptive", "--max-accel", "1000", "--corner-tolerance", "10 um")),
    (SQUARE, ("--profile-type", "adaptive", "--max-accel", "1000", "--corner-tolerance", "100 um")),
    (ROUNDED, ()), (ROUNDED, ("--profile-type", "adaptive", "--max-accel", "1000")),
)


def _square_distance(points):
    """Exact distance of each point from the 40 mm square (its four sides)."""
    corners = np.array([[0, 0], [40, 0], [40, 40], [0, 40], [0, 0]], float)
    best = np.full(points.shape[0], np.inf)
    for a, b in zip(corners[:-1], corners[1:]):
        t = np.clip(((points - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
        best = np.minimum(best, np.linalg.norm(a + t[:, None] * (b - a) - points, axis=1))
    return best


def corner_variants():
    """(label, path, options) of the square and the rounded square under each corner treatment, labelled with the
    options `nurbsinterp plan` takes."""
    out = []
    for path, args in CORNER_ROWS:
        shown = " ".join(f'"{a}"' if " " in a else a for a in args)
        label = f"{path.stem}, `{shown}`" if args else f"{path.stem}, as the job file says (trapezoidal)"
        out.append((label, path, args))
    return out


def planned(path, args):
    """`nurbsinterp plan PATH ARGS` run in-process, its binary stream read back: (columns, rows, period)."""
    import tempfile

    from nurbsinterp.cli import main
    from nurbsinterp.streams import read_stream

    with tempfile.TemporaryDirectory() as where:
        out = Path(where) / "stream.bin"
        try:
            main(["plan", str(path), *args, "--format", "bin", "-q", "-o", str(out)])
        except SystemExit as exc:
            if exc.code not in (0, None):
                raise RuntimeError(f"plan {path} {' '.join(args)}: exit {exc.code}") from None
        with open(out, "rb") as fh:
            columns, chunks = read_stream(fh, str(out))
            data = np.vstack(list(chunks))
    return columns, data, float(data[1, columns.index("t")] - data[0, columns.index("t")])


def corners() -> list[str]:
    """The square's corners: stops, the conventional filter and blends (docs/planning.md, "Paths and corners")."""
    corner_pts = np.array([[40, 0], [40, 40], [0, 40]], float)  # the three inside the motion (it starts at 0, 0)
    out = ["| path and treatment | motion time (s) | feed at the tick nearest a corner, slowest (mm/s) | "
           "max distance from the square (µm) |", "|---|---|---|---|"]
    for label, path, args in corner_variants():
        columns, data, period = planned(path, args)
        xy = data[:, [columns.index("x"), columns.index("y")]]
        v = data[:, columns.index("v")]
        rounded = label.startswith("rounded")
        feed = "–" if rounded else f"{min_feed_near(xy, v, corner_pts):.2f}"
        dev = "–" if rounded else f"{_square_distance(xy).max() * 1e3:.2f}"
        out.append(f"| {label} | {(data.shape[0] - 1) * period:.3f} | {feed} | {dev} |")
    return out


def min_feed_near(xy, v, corner_pts):
    """The slowest of the commanded feeds at the ticks nearest each corner."""
    return min(float(v[int(np.argmin(np.linalg.norm(xy - c, axis=1)))]) for c in corner_pts)


def peers() -> list[str]:
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import run as bench_run

    rows, m = bench_run.measure(quick=False)
    out = ["| measure | result | note |", "|---|---|---|"]
    out += [f"| {name} | {value} | {note} |" for name, value, note in rows]
    out.append(f"\n{m['cpu']}, {m['cores']} cores, Python {m['python']}.")
    return out


DETERMINISTIC["corners"] = corners
def paths_bench() -> list[str]:
    """benchmarks/paths.py: planning cost against the number of blocks (CPU time, machine-dependent)."""
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "paths.py")], check=True, capture_output=True,
                         text=True).stdout
    return out.rstrip("\n").splitlines()


def throughput() -> list[str]:
    """benchmarks/throughput.py: issue 16's measures, idle and with the other core busy."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import throughput as bench_throughput

    return bench_throughput.run()


def read_gcode_bench() -> list[str]:
    """benchmarks/read_gcode.py: reading plain CAM lines and parametric programs (CPU time, machine-dependent)."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import read_gcode as bench_read

    return bench_read.table()


#: the look-ahead's settings the CAM table runs with: LinuxCNC's harness machine (tools/linuxcnc-tp/tp-sim.ini)
CAM_ARGS = ["--tolerance", "5um", "--profile-type", "adaptive", "--axis-max-velocity", "x=100,y=100,z=100",
            "--axis-max-accel", "x=1000,y=1000,z=1000", "--rapid-feedrate", "6000mm/min"]


def cam_bench() -> list[str]:
    """benchmarks/cam.py: the generated spiral and raster programs at 10³..10⁶ blocks, planned with look-ahead,
    measured from their streams, beside LinuxCNC 2.9's figures on the same programs (minutes)."""
    import tempfile

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import cam

    lines = [cam.TABLE_HEAD] if "\n" not in cam.TABLE_HEAD else cam.TABLE_HEAD.splitlines()
    with tempfile.TemporaryDirectory() as tmp:
        for path in cam.write_programs(tmp, [1000, 10_000, 100_000, 1_000_000]):
            lines.append(cam.table_row(path.stem, cam.measure(path, CAM_ARGS)))
    return lines


#: and with the issue's jerk limit added, 20 000 mm/s³ per axis
CAM_JERK_ARGS = [*CAM_ARGS, "--axis-max-jerk", "x=20000,y=20000,z=20000"]


def cam_jerk_bench() -> list[str]:
    """The CAM table's programs of 10³ and 10⁴ blocks with a per-axis jerk limit, beside LinuxCNC's (which has
    none)."""
    import tempfile

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import cam

    lines = cam.TABLE_HEAD.splitlines()
    with tempfile.TemporaryDirectory() as tmp:
        for path in cam.write_programs(tmp, [1000, 10_000]):
            lines.append(cam.table_row(path.stem, cam.measure(path, CAM_JERK_ARGS)))
    return lines


#: the exact path: the CAM table's machine with no tolerance (no --tolerance; the programs state no G64 P)
CAM_EXACT_ARGS = [a for a in CAM_ARGS if a not in ("--tolerance", "5um")]


def cam_exact() -> list[str]:
    """The CAM table's programs of 10³ blocks on the exact path, beside LinuxCNC's G61 (deterministic: motion
    time, deviations and the axes' peaks from the stream)."""
    import tempfile

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import cam

    lines = cam.EXACT_HEAD.splitlines()
    with tempfile.TemporaryDirectory() as tmp:
        for path in cam.write_programs(tmp, [1000]):
            lines.append(cam.exact_row(path.stem, cam.measure(path, CAM_EXACT_ARGS, alone=False)))
    return lines


DETERMINISTIC["cam-exact"] = cam_exact


def linuxcnc_loop() -> list[str]:
    """benchmarks/linuxcnc_loop.py: sim-machine.hal identified and its circle compensated, in LinuxCNC's HAL (needs
    halrun; about a minute)."""
    import shutil
    import tempfile

    sys.path.insert(0, str(ROOT / "benchmarks"))
    import linuxcnc_loop

    work = Path(tempfile.mkdtemp(prefix="nurbsinterp-loop-"))
    work.chmod(0o777)
    try:
        result = linuxcnc_loop.run(work)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return linuxcnc_loop.identified_rows(result) + [""] + linuxcnc_loop.table_rows(result)


def sweep_bench() -> list[str]:
    """benchmarks/sweep.py: a 40-case sweep on 1 and 2 local Dask workers (about 4 minutes; needs Dask)."""
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "sweep.py")], check=True, capture_output=True,
                         text=True).stdout
    return out.rstrip("\n").splitlines()


def first_run() -> list[str]:
    """benchmarks/first_run.py: each command's first run in an empty cache, and the warm-up (about 10 minutes)."""
    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "first_run.py")], check=True, capture_output=True,
                         text=True).stdout
    return out.rstrip("\n").splitlines()


TIMING = {"bench-tick": bench_tick, "first-run": first_run, "startup": startup, "peers": peers, "paths": paths_bench,
          "throughput": throughput, "read-gcode": read_gcode_bench, "cam": cam_bench, "cam-jerk": cam_jerk_bench,
          "linuxcnc-loop": linuxcnc_loop, "sweep": sweep_bench}


def render(names) -> dict[str, str]:
    tables = {**DETERMINISTIC, **TIMING}
    return {name: "\n".join(tables[name]()) + "\n" for name in names}


def blocks(text: str) -> dict[str, str]:
    return {m["name"]: m["body"] for m in BLOCK.finditer(text)}


def pages() -> list[Path]:
    """The markdown pages that may hold a table: README.md and docs/*.md."""
    return [README, *sorted((ROOT / "docs").glob("*.md"))]


def located() -> dict[str, list[Path]]:
    """Each table's name -> the pages holding a block of it (one page each, when the pages are sound)."""
    where: dict[str, list[Path]] = {}
    for page in pages():
        for match in BLOCK.finditer(page.read_text()):
            where.setdefault(match["name"], []).append(page)
    return where


def found() -> dict[str, str]:
    """Each table's name -> its block's body, from whichever page holds it."""
    bodies: dict[str, str] = {}
    for page in pages():
        for name, body in blocks(page.read_text()).items():
            bodies.setdefault(name, body)
    return bodies


def _page_of(names) -> dict[Path, list[str]]:
    """The pages holding *names*, each with its names; refuses a name held by no page or by several."""
    where = located()
    missing = sorted(name for name in names if name not in where)
    if missing:
        raise SystemExit(f"no page (README.md, docs/*.md) has a block for {', '.join(missing)}")
    twice = sorted(name for name in names if len(where[name]) > 1)
    if twice:
        raise SystemExit("more than one block for " + "; ".join(
            f"{name} ({', '.join(str(p.relative_to(ROOT)) for p in where[name])})" for name in twice))
    by_page: dict[Path, list[str]] = {}
    for name in names:
        by_page.setdefault(where[name][0], []).append(name)
    return by_page


def stale(text: str, fresh: dict[str, str]) -> list[str]:
    found = blocks(text)
    return [name for name, body in fresh.items() if found.get(name) != body]


def rewrite(text: str, fresh: dict[str, str]) -> str:
    missing = set(fresh) - set(blocks(text))
    if missing:
        raise SystemExit(f"the page has no block for {', '.join(sorted(missing))}")
    return BLOCK.sub(lambda m: m.group(1) + fresh.get(m["name"], m["body"]) + m.group(4), text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 if a deterministic table is stale")
    parser.add_argument("--timing", action="store_true", help="also re-measure the timing tables")
    parser.add_argument("--only", nargs="*", help="only these tables")
    args = parser.parse_args()
    names = args.only or list(DETERMINISTIC) + (list(TIMING) if args.timing else [])
    by_page = _page_of(names)  # before the minutes of computing: a table with no block, or two, is refused
    fresh = render(names)
    if args.check:
        bad = [f"{page.relative_to(ROOT)}: {name}" for page, held in by_page.items()
               for name in stale(page.read_text(), {name: fresh[name] for name in held})]
        if bad:
            print(f"stale: {', '.join(bad)} (run docs/readme_tables.py)", file=sys.stderr)
            raise SystemExit(1)
        return
    for page, held in by_page.items():
        page.write_text(rewrite(page.read_text(), {name: fresh[name] for name in held}))
        print(f"rewrote {', '.join(held)} in {page.relative_to(ROOT)}", file=sys.stderr)


if __name__ == "__main__":
    main()
