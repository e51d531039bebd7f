"""G2/G3: arcs and helices from I J K or R, within LinuxCNC's tolerances."""
from __future__ import annotations

import math

import numpy as np

from ..curve import MAX_COORDINATE
from ..path import MIN_BLOCK_LENGTH, ArcBlock, plane_angle
from .codes import ARC_REL_TOL, ARC_TOL, MAX_TURNS, OFFSET_LETTERS, PLANE_NAMES, PLANES, R_TOL_MM
from .words import Line


def arc(prog, line: Line, ccw: bool) -> None:
    number = line.number
    a0, a1, a2 = PLANES[prog.plane]
    scale = prog.scale()
    tol = ARC_TOL * scale  # in the program's units, as LinuxCNC applies it
    end = prog.target(line)
    start = prog.pos
    code = "G3" if ccw else "G2"
    has_r = "R" in line.words
    offsets = [letter for letter in OFFSET_LETTERS if letter in line.words]
    if has_r and offsets:
        raise prog.fail(number, f"{code} has both R and {''.join(offsets)}: give the radius or the centre")
    if not has_r and not offsets:
        raise prog.fail(number, f"{code} needs I J K (the centre) or R (the radius)")
    if OFFSET_LETTERS[a2] in offsets:
        raise prog.fail(number, f"{code}: {OFFSET_LETTERS[a2]} is not an offset in the {PLANE_NAMES[prog.plane]} plane")
    turns = 1
    if "P" in line.words:
        p = line.words["P"]
        if p != int(p) or not 1 <= p <= MAX_TURNS:
            raise prog.fail(number, f"{code} P{p:g}: the number of turns must be a whole number from 1 to {MAX_TURNS}")
        turns = int(p)
    u = np.array([start[a0], start[a1]])
    v = np.array([end[a0], end[a1]])
    chord = v - u
    half = float(np.linalg.norm(chord)) / 2
    if has_r:
        r = line.words["R"] * scale
        if half <= MIN_BLOCK_LENGTH:
            raise prog.fail(number, f"{code} R{line.words['R']:g}: an arc given by its radius cannot end where it "
                            "starts (give the centre with I J K for a full circle)")
        if abs(r) < half - R_TOL_MM:
            raise prog.fail(number, f"{code} R{line.words['R']:g}: the radius is smaller than half the distance to "
                            f"the end ({half:.6g} mm)")
        h = math.sqrt(max(r * r - half * half, 0.0))
        left = np.array([-chord[1], chord[0]]) / (2 * half)  # the chord turned +90°
        # the short arc's centre lies to the left of the chord for ccw motion, to the right for cw;
        # a negative R asks for the long arc
        side = (1.0 if ccw else -1.0) * (1.0 if r > 0 else -1.0)
        center = u + chord / 2 + side * h * left
        _centre_in_range(prog, number, code, center)
    else:
        center = u.copy()  # a missing offset is 0 (incremental centres)
        for j, a in enumerate((a0, a1)):
            letter = OFFSET_LETTERS[a]
            if letter in line.words:
                value = line.words[letter]
                center[j] = prog.coordinate(a, value) if prog.center_absolute else u[j] + value * scale
            elif prog.center_absolute:
                raise prog.fail(number, f"{code}: {letter} is missing (arc centres are absolute, G90.1)")
        _centre_in_range(prog, number, code, center)
        r0, r1 = float(np.linalg.norm(u - center)), float(np.linalg.norm(v - center))
        if r0 <= MIN_BLOCK_LENGTH:
            raise prog.fail(number, f"{code}: the centre is the arc's start (a zero radius)")
        err = abs(r1 - r0)
        if (err > tol and err > ARC_REL_TOL * max(r0, r1)) or err > 100 * tol:
            raise prog.fail(number, f"{code}: the radius to the end, {r1:.6g} mm, differs from the radius to the "
                            f"start, {r0:.6g} mm, by {err:.3g} mm (more than {tol:.3g} mm and "
                            f"{ARC_REL_TOL:g} of the radius)")
        if half > MIN_BLOCK_LENGTH and abs(r1 - r0) > 0:
            # onto the chord's bisector, so that the arc is one circle through both ends
            along = chord / (2 * half)
            shift = float((center - (u + v) / 2) @ along)
            if abs(shift) > max(tol, ARC_REL_TOL * r0):
                # LinuxCNC accepts it (the radius rule above) and runs it as a spiral about the centre as
                # written; moving the centre that far would turn the arc's ends: keep LinuxCNC's spiral
                if turns > 1:
                    raise prog.fail(number, f"{code} P{turns}: the radii {r0:.6g} and {r1:.6g} mm disagree and the "
                                    f"centre is {abs(shift):.3g} mm off the chord's bisector: a spiral of several "
                                    "turns is not read (give one turn, or the centre on the bisector)")
                _spiral(prog, line, code, ccw, start, end, center, r0, r1, abs(shift))
                return
            center = center - shift * along
    normal = np.zeros(3)
    normal[a2] = 1.0 if ccw else -1.0
    c3 = start.copy()
    c3[a0], c3[a1] = center
    # the sweep, in the direction of motion, in (0, 2π]; full turns before it for P > 1
    e1, e2 = u - center, v - center
    angle = plane_angle(e1, e2, ccw)
    if half <= MIN_BLOCK_LENGTH:  # a full circle: its end is its start (in the plane), exactly
        angle = 2 * math.pi
        end[a0], end[a1] = start[a0], start[a1]
    elif angle <= 0:
        angle += 2 * math.pi
    radius = float(np.linalg.norm(e1))
    rise = float(end[a2] - start[a2])
    total = angle + 2 * math.pi * (turns - 1)
    if total * radius <= MIN_BLOCK_LENGTH and abs(rise) <= MIN_BLOCK_LENGTH:
        prog.dropped += 1
        return
    if prog.feed is None:
        prog.feedless.append(number)
    here = start.copy()
    # P > 1: whole turns first, each a helix of its share of the rise
    for k in range(turns):
        sweep = 2 * math.pi if k < turns - 1 else angle
        stop = end.copy() if k == turns - 1 else here.copy()
        if k < turns - 1:
            stop[a2] = here[a2] + rise * sweep / total
        centre_k = c3.copy()
        centre_k[a2] = here[a2]
        piece_rise = float(stop[a2] - here[a2]) * normal[a2]  # along the normal, which points down for G2
        prog.blocks.append(ArcBlock(here.copy(), stop, centre_k, normal.copy(), sweep,
                                    0.0 if abs(piece_rise) <= MIN_BLOCK_LENGTH else piece_rise, prog.feed,
                                    f"line {number}", **prog.joint()))
        here = stop
    prog.pos = end.copy()


def _centre_in_range(prog, number: int, code: str, center) -> None:
    if not np.all(np.abs(center) <= MAX_COORDINATE):
        shown = ", ".join(f"{c:.6g}" for c in center)
        raise prog.fail(number, f"{code}: the centre ({shown}) mm is beyond the supported range of "
                                f"+-{MAX_COORDINATE:g} mm")


SPIRAL_TOLERANCE = 1e-9  # mm: the B-spline of a spiral arc stays this close to LinuxCNC's spiral
MAX_SPIRAL_POINTS = 4097


def _spiral(prog, line: Line, code: str, ccw: bool, start, end, center, r0: float, r1: float, shift: float) -> None:
    """An arc whose radii to its ends differ, read as LinuxCNC runs it: about the centre as written, the radius
    going linearly with the angle from r0 to r1 (and a helix's rise linearly too), made exact as a cubic
    B-spline through points of that spiral, refined until it stays within SPIRAL_TOLERANCE of it."""
    from scipy.interpolate import make_interp_spline

    from ..curve import validate_curve
    from ..rules import Where

    a0, a1, a2 = PLANES[prog.plane]
    e1 = np.array([start[a0], start[a1]]) - center
    e2 = np.array([end[a0], end[a1]]) - center
    phi0 = math.atan2(e1[1], e1[0])
    sweep = math.atan2(e1[0] * e2[1] - e1[1] * e2[0], float(e1 @ e2))
    sweep = sweep if ccw else -sweep
    if sweep <= 0:
        sweep += 2 * math.pi
    turn = 1.0 if ccw else -1.0

    def spiral(theta):
        r = r0 + (r1 - r0) * theta / sweep
        points = np.empty((theta.size, 3))
        points[:, a0] = center[0] + r * np.cos(phi0 + turn * theta)
        points[:, a1] = center[1] + r * np.sin(phi0 + turn * theta)
        points[:, a2] = start[a2] + (end[a2] - start[a2]) * theta / sweep
        return points

    n = 5
    while True:
        theta = np.linspace(0.0, sweep, n)
        points = spiral(theta)
        points[0], points[-1] = start, end  # the ends exactly where the program's blocks meet
        fit = make_interp_spline(theta, points, k=3)
        check = np.linspace(0.0, sweep, 8 * (n - 1) + 1)
        deviation = float(np.max(np.linalg.norm(fit(check) - spiral(check), axis=1)))
        if deviation <= SPIRAL_TOLERANCE:
            break
        if n >= MAX_SPIRAL_POINTS:
            raise prog.fail(line.number, f"{code}: a spiral arc (radii {r0:.6g} and {r1:.6g} mm) that {n} points do "
                            f"not fit within {SPIRAL_TOLERANCE:g} mm")
        n = 2 * n - 1
    control = np.array(fit.c, dtype=float)
    control[0], control[-1] = start, end
    curve = validate_curve({"degree": 3, "control_points": control.tolist(), "weights": [1.0] * len(control),
                            "knots": [float(k) for k in fit.t]}, Where(f"{prog.name}:{line.number}"), code)
    if prog.feed is None:
        prog.feedless.append(line.number)
    prog.notes.append(f"line {line.number}: {code}'s centre is {shift:.3g} mm off its chord's perpendicular bisector "
                      f"(radii {r0:.6g} and {r1:.6g} mm): read as LinuxCNC runs it, a spiral about the centre as "
                      f"written, made a cubic B-spline of {len(control)} control points within "
                      f"{SPIRAL_TOLERANCE:g} mm of it")
    from ..path import NurbsBlock

    prog.blocks.append(NurbsBlock(curve, prog.feed, f"line {line.number}", **prog.joint()))
    prog.pos = end.copy()
