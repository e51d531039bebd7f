"""Writing a job back as YAML: what `nurbsinterp convert` shows of a program, a drawing or a job.

The YAML is the job's own format (:mod:`.path`, :mod:`.job`), every number written with
``repr`` in the base units (mm, s) so that reading it back gives the same floats: the same
blocks, the same profile and interpolator, the same plan.  Each block carries a comment
naming where it was read from (``# line 12``).
"""
from __future__ import annotations


from .job import AXIS_LIMITS, LIMIT_FIELDS, SECTION_KEYS, InterpolatorSpec, Job, ProfileSpec
from .path import DEFAULT_MODE, PathSpec


def _num(x) -> str:
    return repr(float(x))


def _point(p) -> str:
    return "[" + ", ".join(_num(c) for c in p) + "]"


def _quoted(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _list(values) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def path_yaml(spec: PathSpec, title: str = "") -> str:
    """The YAML text of a job holding *spec* as its ``path:`` (feedrates in mm/s)."""
    lines = [f"# {line}" for line in title.splitlines()]
    for note in spec.notes:
        lines.append(f"# read with a note: {note}")
    lines += ["path:", f"  start: {_point(spec.start)}", "  blocks:"]
    mode = DEFAULT_MODE
    for block in spec.blocks:
        comment = f"  # {block.source}" if block.source else ""
        feed = [] if block.feedrate is None else [f"feedrate: {_num(block.feedrate)}"]
        # the program's instructions for the joints: the mode where it changes (it holds until the next), a stop
        if block.mode != mode:
            mode = block.mode
            feed.append("mode: {" + ", ".join([f"control: {mode.control}"] + [
                f"{key}: {_num(getattr(mode, key))}" for key in ("tolerance", "naive_tolerance")
                if getattr(mode, key) is not None]) + "}")
        if block.stop is not None:
            feed.append(f"stop: {_quoted(block.stop)}")
        if block.dwell:
            feed.append(f"dwell: {_num(block.dwell)}")
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


def job_yaml(job: Job, title: str = "") -> str:
    """The YAML text of *job*: its path, and the profile and interpolator fields that differ from the defaults.

    A field left at its default is left out, so that it stays a default when the job is read
    back (the interpolator's method follows the profile type unless the job named it)."""
    profile = _section_lines(job.profile, ProfileSpec(), SECTION_KEYS["profile"])
    method_given = () if job.interpolator.method_default else ("method",)
    interpolator = _section_lines(job.interpolator, InterpolatorSpec(), ("period",), method_given)
    lines = [path_yaml(job.path, title).rstrip("\n")]
    for section, body in (("profile", profile), ("interpolator", interpolator)):
        if body:
            lines += [f"{section}:", *body]
    return "\n".join(lines) + "\n"


#: the base unit a bare number of each kind of field is read in (config.units), for a comment beside it
_UNITS = {"length": "mm", "accel": "mm/s^2", "jerk": "mm/s^3", "feedrate": "mm/s", "time": "s"}
_KINDS = {**LIMIT_FIELDS, "feedrate": "feedrate", "rapid_feedrate": "feedrate", "accel_time": "time",
          "time_constant": "time", "period": "time"}


def _section_lines(spec, default, keys, always=()) -> list[str]:
    """``  key: value`` of every field of *spec* (in *keys*' order) that differs from *default*'s, and *always*'s."""
    lines = []
    for key in (*always, *keys):
        value = getattr(spec, key)
        if key not in always and value == getattr(default, key):
            continue
        if key == "axes":  # ((axis, max_velocity or None, max_accel or None, max_jerk or None), ...)
            axes = ", ".join(f"{axis}: {{{', '.join(f'{limit}: {_num(v)}' for limit, v in zip(AXIS_LIMITS, limits) if v is not None)}}}"
                             for axis, *limits in value)
            lines.append(f"  axes: {{{axes}}}  # mm/s, mm/s^2, mm/s^3")
        elif isinstance(value, str):
            lines.append(f"  {key}: {value}")
        else:
            lines.append(f"  {key}: {_num(value)}  # {_UNITS[_KINDS[key]]}")
    return lines
