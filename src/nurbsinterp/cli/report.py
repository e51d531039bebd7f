"""What the commands tell people on stderr: run summaries and progress bars."""
from __future__ import annotations

import contextlib
import sys

PROGRESS_MIN_TICKS = 500_000


@contextlib.contextmanager
def progress(total: int, enabled: bool = True):
    """A rich progress bar on stderr for long jobs when stderr is a terminal; yields advance(n)."""
    if not (enabled and total >= PROGRESS_MIN_TICKS and sys.stderr.isatty()):
        yield lambda n: None
        return
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn("ticks"), BarColumn(), TextColumn("{task.completed:,}/{task.total:,}"),
                  TimeRemainingColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("plan", total=total)
        yield lambda n: bar.advance(task, n)


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:g} ms" if seconds < 1 else f"{seconds:g} s"


def summary_lines(run, stats, target: str) -> list[str]:
    """The run summary of `plan`: one fact per line, for people (stderr)."""
    job, prof = run.job, run.profile
    mode = "after interpolation (filtered)" if run.after else "before interpolation"
    lines = [
        f"{job.source}: {run.method}, {job.profile.type} acc/dec {mode}, T = {_ms(run.period)} -> {target}",
        f"  ticks            {stats.ticks} (k = 0..{stats.ticks - 1}), last command at t = {(stats.ticks - 1) * run.period:.9g} s",
        f"  motion time      {prof.duration + (0 if not run.after else job.profile.accel_time):.9g} s planned"
        + ("" if not run.after else " (constant feed, then the filter)"),
        f"  path length      {run.length:.9f} mm",
    ]
    if prof.lowered:
        lines.append(f"  peak feedrate    lowered to {prof.peak:.6g} mm/s: the path is shorter than feedrate x accel_time")
    if stats.ff_count:
        lines.append(f"  feedrate fluct.  max |FF| {abs(stats.ff_max):.3e} (k = {stats.ff_max_k}), RMS {stats.ff_rms:.3e}"
                     f" over {stats.ff_count} ticks")
    lines.append(f"  chord error      max {stats.chord_max * 1e3:.6g} um (step k = {stats.chord_max_k})")
    if run.after:
        lines.append(f"  path deviation   max {stats.deviation_max:.6g} mm (k = {stats.deviation_max_k}): "
                     "the filtered command leaves the curve")
    gap = run.end_gap
    side = "behind" if gap > 0 else "ahead of"
    lines.append(f"  end gap          {gap:+.3e} mm" + ("" if gap == 0 else
                 f" (the interpolator was {side} the plan where the command snapped to the end point)"))
    return lines
