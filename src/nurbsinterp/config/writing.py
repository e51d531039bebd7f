"""Writing a path back as a YAML job: what `nurbsinterp convert` shows of a program or a drawing.

The YAML is the job's own format (:mod:`.path`), every number written with ``repr`` so
that reading it back gives the same floats: the same blocks, the same path.  Each
block carries a comment naming where it was read from (``# line 12``).
"""
from __future__ import annotations

import numpy as np

from .path import PathSpec


def _num(x) -> str:
    return repr(float(x))


def _point(p) -> str:
    return "[" + ", ".join(_num(c) for c in p) + "]"


def _list(values) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def path_yaml(spec: PathSpec, title: str = "") -> str:
    """The YAML text of a job holding *spec* as its ``path:`` (feedrates in mm/s)."""
    lines = [f"# {line}" for line in title.splitlines()]
    for note in spec.notes:
        lines.append(f"# read with a note: {note}")
    lines += ["path:", f"  start: {_point(spec.start)}", "  blocks:"]
    for block in spec.blocks:
        comment = f"  # {block.source}" if block.source else ""
        feed = [] if block.feedrate is None else [f"feedrate: {_num(block.feedrate)}"]
        if block.kind == "line":
            fields = [f"to: {_point(block.end)}", *feed] + (["rapid: true"] if block.rapid else [])
            lines.append(f"    - line: {{{', '.join(fields)}}}{comment}")
        elif block.kind == "arc":
            if spec.dim == 2:
                turn = [f"direction: {'ccw' if block.normal[2] > 0 else 'cw'}"]
            else:
                turn = [f"normal: {_point(block.normal)}"]  # counter-clockwise about it
            # the end: the circle's end, raised by the helix's rise along the normal
            fields = [f"to: {_point(block.end)}", f"center: {_point(block.center)}", *turn, *feed]
            lines.append(f"    - arc: {{{', '.join(fields)}}}{comment}")
        else:
            c = block.curve
            lines.append(f"    - nurbs:{comment}")
            lines.append(f"        degree: {c.degree}")
            lines.append("        control_points:")
            lines += [f"          - {_point(p)}" for p in c.control_points]
            lines.append(f"        weights: {_list(c.weights)}")
            lines.append(f"        knots: {_list(c.knots)}")
            lines += [f"        {f}" for f in feed]
    return "\n".join(lines) + "\n"
