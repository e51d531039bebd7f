"""`nurbsinterp info`: what a job's curve is and how long its motion takes."""
from __future__ import annotations

import click

from .common import (JOB_ARGUMENT, MAX_TICKS_HINT, MAX_TICKS_OPTION, PLOT_EXTENSIONS, PROGRAM_TOLERANCE_HELP,
                     SMOOTH_OPTION, LookAheadChoice, check_outputs, echo_result, ensure_kernels, job_options,
                     json_text, load, output_label, plot_format, plot_written, say_path_notes)


@click.command()
@JOB_ARGUMENT
@job_options
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object on stdout instead of a table.")
@click.option("--plot", metavar="FILE.png",
              help="Adaptive profile: draw the feed limit, the schedule and the binding limits (" + PLOT_EXTENSIONS + ").")
@click.option("--tolerance", metavar="D",
              help="Plan with look-ahead across the blocks (as plan --tolerance D) and report what it did: "
                   "smoothing, blends, stops, the limits that bound the motion, the commands' extremes. "
                   + PROGRAM_TOLERANCE_HELP)
@SMOOTH_OPTION
@MAX_TICKS_OPTION
def info(job, as_json, plot, max_ticks, tolerance, smooth, **options):
    """Describe the path and the planned motion of JOB (a YAML job, a G-code program or a DXF drawing).

    \b
    nurbsinterp info curves/circle.yaml
    nurbsinterp info curves/butterfly.yaml --json | jq .length
    nurbsinterp info curves/raster.ngc --tolerance 5um
    """
    from ..errors import UsageError

    choice = LookAheadChoice(job, tolerance, options)
    choice.refuse_smooth(smooth)
    if choice.on:
        if plot:
            raise UsageError("--plot does not take a look-ahead plan (a program, a path of several blocks, or --tolerance) yet")
        return _look_ahead(job, choice, smooth is not False, as_json, max_ticks, options)
    spec = load(job, **options)
    check_outputs(inputs=[job, options.get("profile_file"), options.get("machine")], plot=plot)
    if plot and spec.profile.type != "adaptive":
        raise UsageError("--plot draws the adaptive planner; give --profile-type adaptive (and its limits)")
    ensure_kernels("info")
    from ..describe import describe_job

    facts, profile = describe_job(spec, with_profile=True, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT)
    outline = _outline(job, options)
    if plot:
        from ..plots import plot_adaptive

        plot_adaptive(plot, profile.plan, _title(job, spec), plot_format(plot), label=output_label("plot", plot))
        plot_written(plot)
    if as_json:
        echo_result(json_text({**facts.as_dict(), **outline}))
        return
    from rich.table import Table
    from rich.text import Text

    from .report import _console

    table = Table(title=Text(str(job)), show_header=False, box=None, pad_edge=False)
    table.add_column(style="bold")
    table.add_column()
    lo, hi = facts.bounding_box["min"], facts.bounding_box["max"]
    rows = [
        ("degree", f"{facts.degree} (order {facts.degree + 1})"),
        ("control points", f"{facts.n_control_points} in {facts.dimension}-D, {'rational' if facts.rational else 'polynomial'}"),
        ("domain", f"[{facts.domain[0]:g}, {facts.domain[1]:g}], {facts.knot_spans} knot spans"),
        ("length", f"{facts.length:.9f} mm"),
        ("min radius", "none (straight)" if facts.min_radius is None else
         f"{facts.min_radius:.6g} mm at u = {facts.min_radius_u:.9g}"),
        ("bounding box", " .. ".join("(" + ", ".join(f"{v:.6f}" for v in c) + ")" for c in (lo, hi))),
        ("profile", f"{facts.profile} at {_feedrates(facts)}"
         + ("" if facts.profile == "adaptive" else f", accel_time {facts.accel_time:g} s")),
        ("peak feedrate", f"{facts.peak_feedrate:g} mm/s" + (_lowered(facts)
                                                                 if facts.peak_lowered and facts.profile != "adaptive" else "")),
        ("motion time", f"{facts.motion_time:.6f} s"),
        ("interpolator", f"{facts.interpolator}, period {facts.period * 1e3:g} ms, {facts.ticks} ticks"),
    ]
    if facts.adaptive is not None:
        from .report import adaptive_rows

        rows += adaptive_rows(facts.adaptive)
    blocks = facts.blocks
    if len(blocks) > 1:
        corners = [j for j in facts.junctions if j["corner"]]
        kinds = ", ".join(f"{sum(b['kind'] == k for b in blocks)} {k}" for k in ("line", "arc", "nurbs")
                          if any(b["kind"] == k for b in blocks))
        rows.insert(0, ("path", f"{len(blocks)} blocks ({kinds}), {len(corners)} corners"
                        + f", {len(facts.junctions) - len(corners)} tangent joints"))
    for key, value in rows:
        table.add_row(key, value)
    _console().print(table)
    if len(blocks) > 1:
        _console().print(_block_table(facts))
    if outline.get("chains"):
        _console().print(_chain_table(outline["chains"]))


MAX_BLOCK_ROWS = 50  # the table lists this many blocks; --json lists them all


def _look_ahead(job, choice, smooth, as_json, max_ticks, options):
    """`info --tolerance`: the look-ahead run through to its last tick (nothing written), its facts on stdout."""
    spec = choice.load(job, **options)
    tolerance = choice.tolerance
    check_outputs(inputs=[job, options.get("profile_file"), options.get("machine")])
    ensure_kernels("info --tolerance")
    from ..errors import located
    from ..motion.pipeline import LookAhead, run_facts

    with located(job):
        run = LookAhead(spec, tolerance, max_ticks=max_ticks, max_ticks_hint=MAX_TICKS_HINT, smooth=smooth)
        for _ in run.chunks():
            pass
    if hasattr(spec.path, "items"):  # a program read as it ran: what its reader noted is known only now
        say_path_notes(job, spec.path)
    outline = _outline(job, options)  # a drawing's chains, as the one-curve info lists them
    if as_json:
        echo_result(json_text({"job": str(job), **run_facts(run), **outline}))
        return
    from .report import _console, look_ahead_lines

    lines = look_ahead_lines(run, "nowhere (info)")
    echo_result("\n".join([f"{job}: look-ahead plan, {lines[0].split(', look-ahead across ', 1)[1]}"] + lines[1:]))
    if outline.get("chains"):
        _console().print(_chain_table(outline["chains"]))


def _outline(job, options) -> dict:
    """What the reader lists of the file beyond its path: a drawing's chains ({} for other formats)."""
    from ..config.readers import outline_for
    from .common import READER_OPTIONS, _reader_options

    outline = outline_for(job, options.get("input_format"))
    if outline is None:
        return {}
    reading = _reader_options({key: options.get(key) for key in READER_OPTIONS})
    return outline(job, **{key: value for key, value in reading.items() if value is not None})


def _chain_table(chains):
    from rich.table import Table

    table = Table(title="chains (--chain N plans one)", box=None, pad_edge=False)
    for name in ("chain", "entities", "layers", "start", "end", "closed"):
        table.add_column(name, justify="right" if name == "chain" else "left")
    for c in chains:
        point = lambda p: "(" + ", ".join(f"{v:.6g}" for v in p) + ")"  # noqa: E731
        table.add_row(str(c["chain"]), ", ".join(f"{n} {kind}" for kind, n in c["entities"].items()),
                      ", ".join(c["layers"]), point(c["start"]), point(c["end"]), "yes" if c["closed"] else "no")
    return table


def _feedrates(facts) -> str:
    feeds = facts.block_feedrates
    if feeds is None:
        return f"{facts.feedrate:g} mm/s"
    lo, hi = min(feeds), max(feeds)
    return f"the blocks' feedrates, {lo:g} mm/s" if lo == hi else f"the blocks' feedrates, {lo:g} to {hi:g} mm/s"


def _lowered(facts) -> str:
    if facts.block_feedrates is not None or any(j["corner"] for j in facts.junctions):
        return " (lowered: a section between stops is shorter than its feedrate x accel_time)"
    return " (lowered: the path is shorter than feedrate x accel_time)"


def _block_table(facts):
    from rich.table import Table

    table = Table(title="blocks", box=None, pad_edge=False)
    feeds = facts.block_feedrates is not None
    sources = any(block.get("source") for block in facts.blocks)  # read from a program or a drawing
    joints = any("mode" in block for block in facts.blocks)  # a program that sets G61/G64 or stops the tool
    names = ("n", "kind", "length mm", "min radius mm", "corner after") + (("feed mm/s",) if feeds else ()) \
        + (("mode", "stop before") if joints else ()) + (("from",) if sources else ())
    for name in names:
        table.add_column(name, justify="left" if name in ("kind", "from", "mode", "stop before") else "right")
    after = {j["after_block"]: j for j in facts.junctions}
    for i, block in enumerate(facts.blocks[:MAX_BLOCK_ROWS]):
        j = after.get(i)
        corner = "" if j is None else (f"{j['angle_deg']:.3f}°" if j["corner"] else "tangent")
        radius = "-" if block["min_radius"] is None else f"{block['min_radius']:.6g}"
        extra = ((f"{block['feedrate']:.6g}" + (" rapid" if block["rapid"] else ""),) if feeds else ()) \
            + ((block["mode_words"], _stop(block)) if joints else ()) + ((block.get("source", ""),) if sources else ())
        table.add_row(str(i), block["kind"], f"{block['length']:.6f}", radius, corner, *extra)
    if len(facts.blocks) > MAX_BLOCK_ROWS:
        table.add_row("...", f"{len(facts.blocks) - MAX_BLOCK_ROWS} more (--json lists every block)",
                      *[""] * (len(names) - 2))
    return table


def _stop(block) -> str:
    return "" if block["stop"] is None else block["stop"] + (f" (dwell {block['dwell']:g} s)" if block["dwell"] else "")


def _title(job, spec) -> str:
    p = spec.profile
    # the centripetal limit is max_accel's unless the job gives its own (profiles.profile_for)
    normal = p.max_normal_accel if p.max_normal_accel is not None else p.max_accel
    limits = ", ".join(f"{name} {value:g}" for name, value in (
        ("chord", None if p.chord_tolerance is None else p.chord_tolerance * 1e3),
        ("A", p.max_accel), ("J", p.max_jerk), ("An", normal),
        *((f"{axis} v", v) for axis, v, _, _ in p.axes), *((f"{axis} a", a) for axis, _, a, _ in p.axes))
        if value is not None)
    return (f"{job}: adaptive feedrate, F = {p.feedrate:g} mm/s, T = {spec.interpolator.period * 1e3:g} ms"
            + (f"\nlimits: {limits} (chord in µm, v in mm/s, A, An, a in mm/s², J in mm/s³)" if limits else ""))
