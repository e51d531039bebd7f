"""CAM programs as issue 29 measures them: generated spiral and raster programs, LinuxCNC's figures on them,
and the measures of a plan stream (motion time, two-sided deviation, per-axis v/a/j, RSS, first tick).

    python benchmarks/cam.py write DIR --blocks 1000,10000     # spiral_N.ngc, raster_N.ngc in DIR
    python benchmarks/cam.py measure PROGRAM [-- PLAN ARGS...] # one plan run's measures, as JSON

The programs (deterministic, no randomness):

spiral
    r = 5 + 0.5·θ/2π mm (0.5 mm a turn), as N G1 chords, each as long as the local curvature allows with
    its sagitta (its largest distance from the spiral) within 1 µm; F3000 (50 mm/s), ``G21 G90 G64``, a
    leading ``G0`` to the spiral's start (5, 0), ``M2``.  The chords are about 0.2 mm at r = 5 mm and grow
    as √r.
raster
    A finishing pass over z = 2 sin(x/7)·cos(y/5) mm: rows of 200 G1 moves of 0.2 mm in x (x from 0 to
    40 mm), rows 0.5 mm apart in y, zig-zag, each step-over one G1 in y with z on the surface; it starts
    ``G0 X0 Y0 Z5`` / ``G1 Z0 F2000`` (z(0, 0) = 0: the plunge ends on the surface) and ends ``G0 Z5``,
    ``M2``.  N blocks is N // 200 rows (1 000 → 5 rows: 1 000 row moves, 4 step-overs, the plunge).

Numbers are printed with 6 decimals (1 nm), never with an exponent.
"""
from __future__ import annotations

import math
from pathlib import Path

SAGITTA = 1.0e-3  # mm: a spiral chord's largest distance from the spiral
SPIRAL_R0 = 5.0  # mm: the spiral's radius at θ = 0
SPIRAL_PITCH = 0.5  # mm a turn
SPIRAL_FEED = 3000.0  # mm/min
RASTER_FEED = 2000.0  # mm/min
RASTER_STEP = 0.2  # mm: a move along a row
RASTER_ROW = 200  # moves a row
RASTER_STEPOVER = 0.5  # mm between rows
RASTER_SAFE_Z = 5.0  # mm


def _num(v: float) -> str:
    """v with 6 decimals, no exponent, no negative zero."""
    text = f"{v:.6f}"
    return "0.000000" if text == "-0.000000" else text


# --------------------------------------------------------------------------- spiral

def spiral_radius(theta):
    """r(θ) = 5 + 0.5·θ/2π mm."""
    return SPIRAL_R0 + SPIRAL_PITCH * theta / (2.0 * math.pi)


def spiral_point(theta):
    """(x, y) of the spiral at θ, mm."""
    r = spiral_radius(theta)
    return r * math.cos(theta), r * math.sin(theta)


def spiral_angles(chords: int, sagitta: float = SAGITTA) -> list[float]:
    """The chords' end angles θ_0 = 0 < θ_1 < … < θ_chords of the spiral, each chord's sagitta ≤ *sagitta*.

    Notes
    -----
    With b = 0.5/2π mm, the spiral r = 5 + bθ has speed |dP/dθ| = √(r² + b²) and curvature
    κ = (r² + 2b²)/(r² + b²)^(3/2), which decreases along it.  Over a chord from θ_i the curvature is at
    most κ(θ_i); an arc of length S whose curvature is at most 1/R lies within R(1 - cos(S/2R)) of its
    chord, the sagitta of the circle of radius R (the circle bends most), so S = 2R·acos(1 - s/R) keeps
    the chord within s.  The angle step is S over the largest speed on the chord (at its end, the speed
    grows with θ), so the arc is at most S long.  What the step gives up to this bound is < 0.1 %
    (the spiral is locally a circle to that order): tests/test_cam_programs.py measures it.
    """
    b = SPIRAL_PITCH / (2.0 * math.pi)
    angles = [0.0]
    theta = 0.0
    for _ in range(chords):
        r = spiral_radius(theta)
        radius = (r * r + b * b) ** 1.5 / (r * r + 2.0 * b * b)  # 1/κ at the chord's start: the least on it
        arc = 2.0 * radius * math.acos(1.0 - sagitta / radius)
        step = arc / math.hypot(r, b)
        for _ in range(2):  # the speed at the chord's end, the largest on it
            step = arc / math.hypot(spiral_radius(theta + step), b)
        theta += step
        angles.append(theta)
    return angles


def spiral_program(chords: int, sagitta: float = SAGITTA) -> str:
    """The spiral program of *chords* G1 moves (see the module's docstring)."""
    angles = spiral_angles(chords, sagitta)
    x0, y0 = spiral_point(angles[0])
    out = [f"(spiral r = 5 + 0.5*theta/2pi mm, {chords} G1 chords of sagitta <= {sagitta * 1000:g} um)",
           "G21 G90 G64", f"G0 X{_num(x0)} Y{_num(y0)}"]
    first = True
    for theta in angles[1:]:
        x, y = spiral_point(theta)
        out.append(f"G1 X{_num(x)} Y{_num(y)}" + (f" F{SPIRAL_FEED:g}" if first else ""))
        first = False
    out.append("M2")
    return "\n".join(out) + "\n"


# --------------------------------------------------------------------------- raster

def raster_surface(x, y):
    """z = 2 sin(x/7)·cos(y/5), mm."""
    return 2.0 * math.sin(x / 7.0) * math.cos(y / 5.0)


def raster_points(blocks: int) -> list[tuple[float, float, float]]:
    """The G1 end points of the raster of blocks // 200 rows (at least one), in order, plunge first."""
    rows = max(1, blocks // RASTER_ROW)
    points = [(0.0, 0.0, raster_surface(0.0, 0.0))]
    for row in range(rows):
        y = row * RASTER_STEPOVER
        if row:  # the step-over: one move in y at the row's end, z on the surface
            x = points[-1][0]
            points.append((x, y, raster_surface(x, y)))
        for i in range(1, RASTER_ROW + 1):
            j = i if row % 2 == 0 else RASTER_ROW - i
            x = j * RASTER_STEP
            points.append((x, y, raster_surface(x, y)))
    return points


def raster_program(blocks: int) -> str:
    """The raster program of about *blocks* G1 moves (see the module's docstring).

    Its comment has no parentheses inside it: LinuxCNC refuses a nested comment.
    """
    points = raster_points(blocks)
    rows = max(1, blocks // RASTER_ROW)
    out = [f"(raster over z = 2 sin[x/7] cos[y/5] mm, {rows} rows of {RASTER_ROW} G1 moves of "
           f"{RASTER_STEP:g} mm, {RASTER_STEPOVER:g} mm apart, zig-zag)",
           "G21 G90 G64", f"G0 X0 Y0 Z{RASTER_SAFE_Z:g}", f"G1 Z{_num(points[0][2])} F{RASTER_FEED:g}"]
    for x, y, z in points[1:]:
        out.append(f"G1 X{_num(x)} Y{_num(y)} Z{_num(z)}")
    out += [f"G0 Z{RASTER_SAFE_Z:g}", "M2"]
    return "\n".join(out) + "\n"


GENERATORS = {"spiral": spiral_program, "raster": raster_program}


def write_programs(directory, blocks=(1000, 10000), kinds=("spiral", "raster")) -> list[Path]:
    """Write ``<kind>_<N>.ngc`` into *directory* for each kind and N; return the paths."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    paths = []
    for n in blocks:
        for kind in kinds:
            path = directory / f"{kind}_{n}.ngc"
            path.write_text(GENERATORS[kind](n))
            paths.append(path)
    return paths


# --------------------------------------------------------------------------- LinuxCNC's figures
#
# Measured on 2026-11-26 on these generators' own programs (``write DIR --blocks 1000,10000``), with
# LinuxCNC 2.9.0~pre1 (Debian 12 package linuxcnc-uspace 2.9.0~pre1+git20230208.f1270d6ed7-1+deb12u2),
# its default trajectory planner (tpmod), by the harness in ../shared/tools/linuxcnc-tp (run_one.sh as
# a non-root user, analyze.py): a headless simulated trivkins XYZ machine, per-axis 100 mm/s and
# 1 000 mm/s², T = 1 ms, the commands sampled every servo period.  The spiral runs under G64, the raster
# under G64 P0.005 Q0.001 (inserted after the G21 line).  No sampler overruns, no errors; every run ended
# on the program's last point.
#   motion_time: s, from the last still sample before the joints move to the last that moves (the leading
#       G0 and the raster's final G0 Z5 included); feed_time: the G1 part of it.
#   max_dev_joint / max_dev_axis: µm, exact largest distance of joint.N.motor-pos-cmd (after motion's
#       cubic interpolator) / axis.L.pos-cmd (the planner's output) from the programmed polyline.
#   max_accel_feed: mm/s², per axis (x, y, z), |2nd difference|/T² of the joint commands on feed samples;
#       max_accel: over all samples (the G0 moves included); max_jerk: mm/s³, per axis, all samples.
#   max_feed_speed: mm/s, motion.current-vel over the G1 samples; dips: stretches below 0.1 F.
# Against ../shared/tools/linuxcnc-tp/README.md (the figures): spiral_1000 4.780 s (README 4.783),
# spiral_10000 69.775 s (69.791), raster_1000 6.991 s (6.989), raster_10000 64.873 s (64.872); deviation
# spiral 1.07 µm (1.09), raster 3.53 / 3.67 µm (3.63 / 3.63); spiral x/y accel 646/576 and 646/500 (640/577
# and 640/500).  The spiral's times are 3 ms and 16 ms (0.06 %, 0.02 %) shorter: its chords here come from
# the radius of curvature with a sagitta of 0.9995 µm at most (the README's programs are not kept, so
# their exact chords are unknown), which changes the spiral's length and its chords' angles slightly.
LINUXCNC = {
    "spiral_1000": {"mode": "G64", "g1_blocks": 1000, "motion_time": 4.780, "feed_time": 4.636,
                    "max_dev_joint": 1.074, "max_dev_axis": 0.999, "max_accel_feed": (646.0, 576.1, 0.0),
                    "max_accel": (1000.0, 576.1, 0.0), "max_jerk": (833335.0, 403551.0, 0.0),
                    "max_feed_speed": 50.0, "dips": 0},
    "raster_1000": {"mode": "G64 P0.005 Q0.001", "g1_blocks": 1005, "motion_time": 6.991, "feed_time": 6.628,
                    "max_dev_joint": 3.525, "max_dev_axis": 3.422, "max_accel_feed": (1000.0, 1000.0, 1000.0),
                    "max_accel": (1000.0, 1000.0, 1000.0), "max_jerk": (462698.0, 833333.0, 833335.0),
                    "max_feed_speed": 33.333, "dips": 9},
    "spiral_10000": {"mode": "G64", "g1_blocks": 10000, "motion_time": 69.775, "feed_time": 69.631,
                     "max_dev_joint": 1.074, "max_dev_axis": 1.000, "max_accel_feed": (646.0, 500.0, 0.0),
                     "max_accel": (1000.0, 500.0, 0.0), "max_jerk": (833335.0, 428080.0, 0.0),
                     "max_feed_speed": 50.0, "dips": 0},
    "raster_10000": {"mode": "G64 P0.005 Q0.001", "g1_blocks": 10050, "motion_time": 64.873, "feed_time": 64.529,
                     "max_dev_joint": 3.672, "max_dev_axis": 3.568, "max_accel_feed": (1000.0, 1000.0, 1000.0),
                     "max_accel": (1000.0, 1000.0, 1000.0), "max_jerk": (540678.0, 833336.0, 833335.0),
                     "max_feed_speed": 33.333, "dips": 99},
}


# --------------------------------------------------------------------------- command line

def main(argv=None) -> int:
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    write = sub.add_parser("write", help="write spiral_N.ngc and raster_N.ngc into DIR")
    write.add_argument("directory")
    write.add_argument("--blocks", default="1000,10000", help="comma-separated block counts (default 1000,10000)")
    write.add_argument("--kinds", default="spiral,raster")
    args = parser.parse_args(argv)
    if args.command == "write":
        blocks = [int(b) for b in args.blocks.split(",")]
        for path in write_programs(args.directory, blocks, args.kinds.split(",")):
            print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
