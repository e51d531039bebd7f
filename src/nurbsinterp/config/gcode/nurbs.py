"""NURBS blocks: LinuxCNC's G5.2/G5.3 and G6.2 (Fanuc's G06.2), collected line by line into one curve."""
from __future__ import annotations

import numpy as np

from ..curve import validate_curve
from ..path import MIN_BLOCK_LENGTH, NurbsBlock
from ..rules import Where
from .codes import AXIS_LETTERS, DEFAULT_ORDER_G6, PLANE_NAMES, PLANES
from .words import Line


def begin_g5(prog, line: Line) -> None:
    if prog.nurbs is not None:
        raise prog.fail(line.number, f"G5.2 starts a NURBS while the one of line {prog.nurbs['line']} is not closed")
    if not prog.absolute:
        raise prog.fail(line.number, "G5.2 in incremental mode (G91): control points must be absolute (G90)")
    order = 3
    if "L" in line.words:
        L = line.words["L"]
        if L != int(L) or L < 1:
            raise prog.fail(line.number, f"G5.2 L{L:g}: the order must be a whole number")
        if L > 3:
            order = int(L)
        elif L < 3:
            prog.notes.append(f"line {line.number}: G5.2 L{L:g} is read as order 3, as LinuxCNC reads any L <= 3")
    weight = 1.0
    a0, a1, _ = PLANES[prog.plane]
    has_point = AXIS_LETTERS[a0] in line.words or AXIS_LETTERS[a1] in line.words
    if "P" in line.words and not has_point:
        weight = _weight(prog, line, "P", "G5.2")
    prog.nurbs = {"kind": "G5.2", "line": line.number, "order": order, "points": [prog.pos.copy()],
                  "weights": [weight], "knots": None, "feed": prog.feed, "plane": prog.plane}
    if has_point:
        g5_point(prog, line)


def _weight(prog, line: Line, letter: str, code: str) -> float:
    w = line.words[letter]
    if not w > 0:
        raise prog.fail(line.number, f"{code} {letter}{w:g}: a control point's weight must be > 0")
    return float(w)


def g5_point(prog, line: Line) -> None:
    a0, a1, a2 = PLANES[prog.nurbs["plane"]]
    letters = AXIS_LETTERS[a0] + AXIS_LETTERS[a1]
    given = [c for c in letters if c in line.words]
    if len(given) != 2:
        raise prog.fail(line.number, f"G5.2: a control point needs both {letters[0]} and {letters[1]} "
                        f"(the {PLANE_NAMES[prog.nurbs['plane']]} plane)")
    if AXIS_LETTERS[a2] in line.words:
        raise prog.fail(line.number, f"G5.2: {AXIS_LETTERS[a2]} is not a coordinate of the "
                        f"{PLANE_NAMES[prog.nurbs['plane']]} plane")
    if "P" not in line.words:
        raise prog.fail(line.number, "G5.2: a control point needs its weight P")
    weight = _weight(prog, line, "P", "G5.2")
    point = prog.nurbs["points"][0].copy()
    for letter in letters:
        point["XYZ".index(letter)] = prog.coordinate("XYZ".index(letter), line.words[letter])
    prog.nurbs["points"].append(point)
    prog.nurbs["weights"].append(weight)


def end_g5(prog, line: Line) -> None:
    nurbs = prog.nurbs
    if nurbs is None or nurbs["kind"] != "G5.2":
        raise prog.fail(line.number, "G5.3 without G5.2: there is no NURBS block to close")
    n, k = len(nurbs["points"]), nurbs["order"]
    if n < k:
        raise prog.fail(line.number, f"G5.3 closes the G5.2 of line {nurbs['line']} with {n} control points; "
                        f"order {k} needs at least {k}")
    # LinuxCNC's knots: k zeros, 1 .. n-k, then n-k+1 k times
    nurbs["knots"] = [0.0] * k + [float(i) for i in range(1, n - k + 1)] + [float(n - k + 1)] * k
    _finish_nurbs(prog, line.number)


def begin_g6(prog, line: Line) -> None:
    if prog.nurbs is not None:
        raise prog.fail(line.number, f"G6.2 starts a NURBS while the one of line {prog.nurbs['line']} is not "
                        "closed (it needs order P knot-only blocks)")
    if not prog.absolute:
        raise prog.fail(line.number, "G6.2 in incremental mode (G91): control points must be absolute (G90)")
    order = DEFAULT_ORDER_G6
    if "P" in line.words:
        P = line.words["P"]
        if P != int(P) or not 2 <= P <= 26:
            raise prog.fail(line.number, f"G6.2 P{P:g}: the order must be a whole number from 2 to 26")
        order = int(P)
    if "Q" in line.words:
        prog.ignore("G6.2 Q (LinuxCNC's choice of interpolation method; nurbsinterp interpolates the NURBS "
                    "itself)", line.number)
    if "K" not in line.words:
        raise prog.fail(line.number, "G6.2 needs the first control point's knot K")
    prog.nurbs = {"kind": "G6.2", "line": line.number, "order": order, "points": [], "weights": [],
                  "knots": [], "knot_lines": [], "closing": 0, "feed": prog.feed, "plane": prog.plane}
    g6_point(prog, line)


def g6_point(prog, line: Line) -> None:
    nurbs = prog.nurbs
    point = nurbs["points"][-1].copy() if nurbs["points"] else prog.pos.copy()
    moved = False
    for j, letter in enumerate(AXIS_LETTERS):
        if letter in line.words:
            point[j] = prog.coordinate(j, line.words[letter])
            moved = True
    if "K" not in line.words:
        raise prog.fail(line.number, "G6.2: a control point needs its knot K")
    if not moved and nurbs["points"]:  # K alone (and perhaps R): a closing knot
        if "R" in line.words:
            raise prog.fail(line.number, "G6.2: a knot-only block takes no weight R")
        _g6_knot(prog, line)
        return
    if nurbs["closing"]:
        raise prog.fail(line.number, "G6.2: a control point after the closing knots began")
    weight = _weight(prog, line, "R", "G6.2") if "R" in line.words else 1.0
    nurbs["points"].append(point)
    nurbs["weights"].append(weight)
    _g6_knot(prog, line, closing=False)


def _g6_knot(prog, line: Line, closing: bool = True) -> None:
    nurbs = prog.nurbs
    knot = float(line.words["K"])
    if nurbs["knots"] and knot < nurbs["knots"][-1]:
        raise prog.fail(line.number, f"G6.2: knot K{knot:g} is smaller than the previous knot "
                        f"K{nurbs['knots'][-1]:g} (line {nurbs['knot_lines'][-1]}); knots must not decrease")
    nurbs["knots"].append(knot)
    nurbs["knot_lines"].append(line.number)
    if closing:
        nurbs["closing"] += 1
        if nurbs["closing"] == nurbs["order"]:
            _finish_g6(prog, line.number)


def _finish_g6(prog, number: int) -> None:
    nurbs = prog.nurbs
    k, n = nurbs["order"], len(nurbs["points"])
    knots = nurbs["knots"]
    if n < k:
        raise prog.fail(number, f"G6.2 of line {nurbs['line']} has {n} control points; order P{k} needs at least {k}")
    lines = nurbs["knot_lines"]
    for side, idx in (("first", range(k)), ("last", range(len(knots) - k, len(knots)))):
        idx = list(idx)
        if any(knots[i] != knots[idx[0]] for i in idx):
            bad = next(i for i in idx if knots[i] != knots[idx[0]])
            raise prog.fail(lines[bad], f"G6.2: knot K{knots[bad]:g} breaks the clamped knot vector: the {side} "
                            f"P{k} knots must be equal (K{knots[idx[0]]:g}, line {lines[idx[0]]}) (Fanuc alarm "
                            f"{1007 if side == 'first' else 1008})")
    if knots[-1] == knots[0]:
        raise prog.fail(number, f"G6.2 of line {nurbs['line']}: every knot is K{knots[0]:g}; the curve has no domain")
    _finish_nurbs(prog, number)


def _finish_nurbs(prog, number: int) -> None:
    nurbs = prog.nurbs
    prog.nurbs = None
    points = np.array(nurbs["points"])
    first = nurbs["line"]
    if float(np.linalg.norm(points[0] - prog.pos)) > MIN_BLOCK_LENGTH:
        prog.notes.append(f"line {first}: the {nurbs['kind']} curve starts "
                          f"{float(np.linalg.norm(points[0] - prog.pos)):.6g} mm from the tool's position; a straight "
                          "feed move goes there first")
        prog.add_line(first, points[0].copy(), rapid=False)
    points[0] = prog.pos
    raw = {"degree": nurbs["order"] - 1, "control_points": points.tolist(), "weights": nurbs["weights"],
           "knots": nurbs["knots"]}
    curve = validate_curve(raw, Where(f"{prog.name}:{first}"), nurbs["kind"])
    if nurbs["feed"] is None and prog.feed is None:
        prog.feedless.append(first)
    feed = prog.feed if prog.feed is not None else nurbs["feed"]
    prog.blocks.append(NurbsBlock(curve, feed, f"line {first}", **prog.joint()))
    prog.pos = curve.control_points[-1].copy()
