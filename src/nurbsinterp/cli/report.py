"""What the commands tell people: results as tables (stdout), run summaries and progress bars (stderr).

A result table goes to stdout like any result: styled on a terminal, plain text
when piped or redirected (so `nurbsinterp compare job.yaml > table.txt` keeps
it).  Progress, summaries and messages go to stderr.
"""
from __future__ import annotations

import contextlib
import sys

PROGRESS_MIN_TICKS = 500_000


@contextlib.contextmanager
def progress(total: int, enabled: bool = True, unit: str = "ticks", minimum: int = PROGRESS_MIN_TICKS):
    """A rich progress bar on stderr for long jobs (at least *minimum* units) when stderr is a terminal; yields
    advance(n)."""
    if not (enabled and total >= minimum and sys.stderr.isatty()):
        yield lambda n: None
        return
    COMPILES.pause()  # one live display on the terminal at a time
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    with Progress(TextColumn(unit), BarColumn(), TextColumn("{task.completed:,}/{task.total:,}"),
                  TimeRemainingColumn(), console=Console(stderr=True), transient=True) as bar:
        task = bar.add_task("plan", total=total)
        yield lambda n: bar.advance(task, n)


def _ms(seconds: float) -> str:
    return f"{seconds * 1e3:g} ms" if seconds < 1 else f"{seconds:g} s"


def adaptive_lines(plan) -> list[str]:
    """What bounds the adaptive schedule, where its feed limit binds, and its slowest point."""
    from ..describe import adaptive_facts

    rows = adaptive_rows(adaptive_facts(plan))
    return [f"  peak feedrate    {plan.peak:.6g} mm/s (commanded {plan.feedrate:g})",
            *(f"  {label:<16} {text}" for label, text in rows),
            f"  planning         {plan.planning_time * 1e3:.1f} ms, {plan.sections} section(s), "
            f"time stretched by {plan.stretch - 1:.2e} to put the stops and the end on ticks"]


def _shares(fractions: dict) -> str:
    return ", ".join(f"{name} {frac:.1%}" for name, frac in fractions.items() if frac > 0)


def adaptive_rows(a: dict) -> list[tuple[str, str]]:
    """(label, text) of what bounds the schedule, where the feed limit binds and the slowest point, from
    :func:`~nurbsinterp.describe.adaptive_facts` (`plan`'s summary and `info` print the same rows)."""
    low, slow = a["lowest_feed_limit"], a["slowest"]
    return [
        ("bound by", f"{_shares(a['bound_fractions'])} of the motion time"),
        ("feed limit", f"set by {_shares(a['limit_fractions'])} of the path; lowest {low['feed_limit']:.6g} mm/s "
                       f"at s = {low['s']:.6g} mm (u = {low['u']:.9g}), {low['limit']} limit"),
        ("slowest", f"{slow['feedrate']:.6g} mm/s at s = {slow['s']:.6g} mm (t = {slow['t']:.6g} s), the "
                    "schedule's lowest between its first acceleration and its last deceleration"),
    ]


FEW_TICKS = 10  # a motion of fewer ticks than this gets a warning: the period is likely in the wrong unit


def given_lines(job, blocks=()) -> list[str]:
    """Feedrate, acceleration time and period as the user wrote them and as used, in SI: a unit slip shows.

    A setting the run does not use says so: the profile's feedrate where every feed block of *blocks* has its
    own (a program's F words), accel_time where the adaptive profile has max_accel."""
    from ..config.job import USED_BY

    given = {dotted: (value, origin) for dotted, value, origin in job.given}
    feeds = [b.feedrate for b in blocks if not getattr(b, "rapid", False)]
    unused = {"profile.feedrate": "not used: every feed block has its own feedrate (below)"
              if feeds and all(f is not None for f in feeds) else None,
              "profile.accel_time": None if USED_BY["profile.accel_time"][0](job.profile)
              else "not used: the adaptive profile has max_accel"}
    used = {"profile.feedrate": (job.profile.feedrate, f"{job.profile.feedrate:.9g} mm/s = {job.profile.feedrate / 1e3:.9g} m/s"),
            "profile.accel_time": (job.profile.accel_time, f"{job.profile.accel_time:.9g} s"),
            "interpolator.period": (job.interpolator.period, f"{job.interpolator.period:.9g} s")}
    lines = []
    for dotted, (_, si) in used.items():
        value, origin = given.get(dotted, (None, "default"))
        written = "" if value is None else f"{value} "
        lines.append(f"  {dotted.split('.')[1]:<16} {written}({origin}) = {si}"
                     + (f"; {unused[dotted]}" if unused.get(dotted) else ""))
    return lines


def _default_note(job) -> str:
    if job.interpolator.method_default and job.profile.type == "adaptive":
        return " (the adaptive profile's default: the stream keeps its limits)"
    return ""


def quantise_lines(quantiser) -> list[str]:
    """What --resolution did to the stream (a quantise.Quantiser): the scales, the largest rounding, the counts."""
    res = quantiser.resolution
    axes = quantiser.axes
    scales = ", ".join(f"{a} {res.describe(a)}" for a in axes)
    worst = ", ".join(f"{a} {quantiser.worst[a] * 1e3:.6g} um" for a in axes)
    largest = ", ".join(f"{a} {quantiser.largest[a]}" for a in axes)
    unit = "counts (columns " + ",".join(f"{a}_counts" for a in axes) + ")" if quantiser.counts else "mm"
    how = ("each command the rounding of the exact one" if quantiser.rounding == "nearest" else
           "noise-shaped: each moving tick's rounding error carried into the next (at most one count, never "
           "accumulating)")
    return [f"  resolution       {scales}: {how}, written in {unit}",
            f"  rounding         largest |rounded - exact| {worst}; largest |count| {largest}"]


PRECOMPENSATION_NAMES = {"exact": "exact stable inverse", "zpetc": "zero-phase-error tracking (ZPETC)",
                          "match": "axis-lag matching"}


def precompensation_lines(pc, check) -> list[str]:
    """What pre-compensation did (a precompensate.Precompensator) and, with a ModelCheck, what it does to the model."""
    from ..precompensate import SETTLED, zero_text

    d = pc.design
    axes = d.axes

    def per_axis(values, fmt="{:.3g}", unit=" mm"):
        return ", ".join(f"{a} {fmt.format(v)}{unit}" for a, v in zip(axes, values))

    if pc.settle_ticks:
        ticks = (f"{pc.ticks} ticks in, {pc.ticks + pc.settle_ticks} out (the end held {pc.settle_ticks} ticks, "
                 f"{_ms(pc.settle_ticks * d.period)}, while the shaping settles on it)")
    else:
        ticks = f"{pc.ticks} ticks in and out"
    lines = [f"  precompensation  {PRECOMPENSATION_NAMES[d.method]} of {d.source}: a preview of {d.latency} ticks "
             f"({_ms(d.latency * d.period)}), {ticks}"]
    if pc.settle_jump > SETTLED:
        lines.append(f"  settling         not within {SETTLED:g} mm after {pc.settle_ticks} ticks: the last command "
                     f"was moved {pc.settle_jump:.3g} mm onto the end")
    for f in d.filters:
        inverted = " ".join(zero_text(z, 4) for z in f.inverted) or "none"
        kept = " ".join(zero_text(z, 4) for z in f.kept) or "none"
        outside = sum(abs(z) > 1 for z in f.inverted)
        how = f" ({outside} outside the unit circle, inverted backwards over the preview)" if outside else ""
        lines.append(f"  zeros {f.name:<10} inverted {inverted}{how}; left {kept}")
    if d.method == "exact":
        lines.append(f"  preview error    <= {per_axis(pc.truncation_bound)} (the taps beyond the preview, "
                     "summed on the last value read)")
    lines.append(f"  shaping          max |command - planned| {per_axis(pc.shaping_max)}")
    if check is None:
        return lines
    where = ", ".join(f"{a} {v:.3g} mm at tick {k}{_edge(k, check.ticks, d.latency)}"
                      for a, v, k in zip(axes, check.residual, check.residual_tick))
    lines += [f"  model's table    max |position - planned| {where} of 0 .. {check.ticks - 1} "
              f"(the planned commands as they are: {per_axis(check.lag)})",
              f"  voltage          peak {per_axis(check.voltage, unit=' V')} "
              f"(the planned commands: {per_axis(check.voltage_plain, unit=' V')})",
              f"  acceleration     peak command {per_axis(check.accel, unit=' mm/s^2')} "
              f"(planned: {per_axis(check.accel_plain, unit=' mm/s^2')})"]
    return lines


def _edge(tick: int, ticks: int, latency: int) -> str:
    """Where a tick lies if within a preview of the stream's first or last tick, whose commands are the plan's own."""
    if tick >= ticks - 1 - latency:
        return f" ({ticks - 1 - tick} before the last, whose command is the plan's own)"
    if tick <= latency:
        return f" ({tick} after the first, whose command is the plan's own)"
    return ""


def budget_warnings(check) -> list[str]:
    """One line per budget the pre-compensated commands exceed (a precompensate.ModelCheck)."""
    lines = []
    axes = check.axes
    if check.over_voltage:
        lines.append(f"nurbsinterp: warning: the commands need more than {check.voltage_budget:g} V on "
                     f"{check.over_voltage} ticks (the first k = {check.first_over_voltage}; peak "
                     + ", ".join(f"{a} {v:.4g} V" for a, v in zip(axes, check.voltage))
                     + "): saturated there, the model's table would leave the plan by up to "
                     + ", ".join(f"{a} {v:.3g} mm" for a, v in zip(axes, check.residual_saturated)))
    if check.over_accel:
        lines.append(f"nurbsinterp: warning: the commands accelerate faster than {check.accel_budget:g} mm/s^2 on "
                     f"{check.over_accel} ticks (the first k = {check.first_over_accel}; peak "
                     + ", ".join(f"{a} {v:.4g} mm/s^2" for a, v in zip(axes, check.accel)) + ")")
    return lines


def summary_lines(run, stats, target: str) -> list[str]:
    """The run summary of `plan`: one fact per line, for people (stderr)."""
    job, prof = run.job, run.profile
    mode = "after interpolation (filtered)" if run.after else "before interpolation"
    lines = [
        f"{job.source}: {run.method}{_default_note(job)}, {job.profile.type} acc/dec {mode}, "
        f"T = {_ms(run.period)} -> {target}",
        f"  ticks            {stats.ticks} (k = 0..{stats.ticks - 1}), last command at t = {(stats.ticks - 1) * run.period:.9g} s",
        f"  motion time      {prof.duration + (0 if not run.after else job.profile.accel_time):.9g} s planned"
        + ("" if not run.after else " (constant feed, then the filter)"),
        f"  path length      {run.length:.9f} mm",
    ]
    lines.extend(given_lines(job, run.path.blocks if run.path.feedrates is not None else ()))
    feeds = run.path.feedrates
    if feeds is not None:
        rapids = [f for f, b in zip(feeds, run.path.blocks) if b.rapid]
        own = [f for f, b in zip(feeds, run.path.blocks) if not b.rapid]
        span = "" if not own else (f"{min(own):.6g}" if min(own) == max(own) else f"{min(own):.6g} to {max(own):.6g}")
        lines.append(f"  block feedrates  {span + ' mm/s' if own else 'none'}" + (f", rapids at {rapids[0]:.6g} mm/s"
                     if rapids else "") + " (each block's own: the paper's profiles stop where it changes)")
    if job.profile.type == "adaptive":
        lines.extend(adaptive_lines(prof.plan))
        if run.method != "exact":
            lines.append(f"  limits           kept by the plan; {run.method} follows it only to its truncation error (FF "
                         "below) and snaps to the end point, so this stream can exceed them: `--interpolator exact` "
                         "keeps them")
    elif prof.lowered:
        if len(run.path.section_ends()) > 1:
            lines.append(f"  peak feedrate    {prof.peak:.6g} mm/s; a section between stops that is shorter than its "
                         "feedrate x accel_time peaks below its feedrate")
        else:
            lines.append(f"  peak feedrate    lowered to {prof.peak:.6g} mm/s: the path is shorter than feedrate x "
                         "accel_time")
    if stats.ff_count:
        # (every tick's FF exactly 0 leaves no tick of a largest one to name)
        where = f"k = {stats.ff_max_k}" if stats.ff_max_k >= 0 else "at every tick"
        lines.append(f"  feedrate fluct.  max |FF| {abs(stats.ff_max):.3e} ({where}), RMS {stats.ff_rms:.3e}"
                     f" over {stats.ff_count} ticks")
    lines.append(f"  chord error      max {stats.chord_max * 1e3:.6g} um"
                 + (f" (step k = {stats.chord_max_k})" if stats.chord_max_k >= 0 else ""))
    if run.after:
        lines.append(f"  path deviation   max {stats.deviation_max:.6g} mm (k = {stats.deviation_max_k}): "
                     "the filtered command leaves the curve")
    if stats.ticks < FEW_TICKS:
        # a period of seconds (`--period 1`: a number is s) gives a polygon of a few chords, not a motion
        lines.append(f"  warning          the whole motion is {stats.ticks} ticks at T = {run.period:.9g} s: the chord "
                     "error above is that of a few long steps; is the period the one you meant (1 ms, 250 us)?")
    if job.profile.type == "adaptive":
        if run.path.program_stops():
            # the adaptive planner stops where the curve's geometry does, and knows nothing of M0 or G4 yet
            lines.append(f"  note             the program asks for {run.path.program_stops()} stop(s) or dwell(s) (M0, "
                         "M1, M6, G4), which the adaptive profile does not make: --tolerance (look-ahead) or another "
                         "profile plans them")
    gap = run.end_gap
    side = "behind" if gap > 0 else "ahead of"
    lines.append(f"  end gap          {gap:+.3e} mm" + ("" if gap == 0 else
                 f" (the interpolator was {side} the plan where the command snapped to the end point)"))
    return lines


def _console(stderr: bool = False):
    from rich.console import Console

    console = Console(stderr=stderr)
    if not console.is_terminal:
        console.width = max(console.width, 160)  # a file or a pipe is not a narrow terminal
    return console


class CompileDisplay:
    """What a run says while numba compiles the kernels it calls for the first time (nothing when they are all
    in the cache): a headline at the first compilation, then on a terminal a progress bar — the kernel compiling
    now, k of about N, the time left estimated from the count — and at the end of a successful run how many were
    compiled in how long.  After `nurbsinterp warmup` no command should compile: one that does all the same (a
    signature the warm-up did not reach) says so per kernel, so that a pause of seconds is never unexplained."""

    def __init__(self):
        self.command = None
        self.expected = None  # {"kernels": N, "seconds": S} measured for this command, or None
        self.warm = False
        self.count = 0
        self.t0 = None
        self.bar = None
        self.task = None
        self.paused = False

    def begin(self, command: str, expected, warm: bool) -> None:
        """The run is *command* (its estimate *expected*): the first call of a run starts the count, a later one
        (the command known better once its job is read) only names it."""
        if self.command is None:
            self.count, self.t0, self.paused = 0, None, False
        self.command, self.expected, self.warm = command, expected, warm

    def on_compile(self, name: str, _count: int) -> None:
        import time

        if self.warm:
            click_echo(f"nurbsinterp: compiling kernel {name} for first use (a few seconds, once)")
            return
        if self.count == 0:
            self.t0 = time.perf_counter()
            click_echo(self.headline())
        self.count += 1
        if self.paused or not sys.stderr.isatty():
            return
        if self.bar is None:
            from rich.console import Console
            from rich.progress import (BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn,
                                       TimeRemainingColumn)

            self.bar = Progress(TextColumn("compiling"), BarColumn(), MofNCompleteColumn(), TextColumn("kernels"),
                                TimeElapsedColumn(), TextColumn("left"), TimeRemainingColumn(),
                                TextColumn("{task.description}"), console=Console(stderr=True), transient=True)
            self.task = self.bar.add_task("", total=None)
        if not self.bar.live.is_started:
            self.bar.start()
        # k of about N: the estimate grows with the count where this run reaches more than the measured one
        total = max(self.expected["kernels"], self.count) if self.expected else None
        self.bar.update(self.task, completed=self.count - 1, total=total, description=name)

    def on_idle(self) -> None:
        """A compilation ended and the run goes on: the bar steps off the terminal (the run may write there) until
        the next one, keeping its count and clock."""
        if self.bar is not None and self.bar.live.is_started:
            self.bar.stop()

    def headline(self) -> str:
        about = ""
        if self.expected:
            about = (f"about {self.expected['kernels']} kernels, {_duration(self.expected['seconds'])} on a quiet "
                     "2-core machine; ")
        return (f"nurbsinterp: compiling the numeric kernels `{self.command}` needs, once for this version ({about}"
                "what is compiled is kept if the run stops; `nurbsinterp warmup` compiles every command's ahead of "
                "time)")

    def pause(self) -> None:
        """The run's own progress bar takes the terminal: the compile bar steps aside (kernels compiled from now
        on are still counted)."""
        self.paused = True
        self._stop_bar()

    def _stop_bar(self) -> None:
        if self.bar is not None:
            if self.bar.live.is_started:
                self.bar.stop()
            self.bar = None

    def finish(self, ok: bool) -> None:
        """The command ended: on success, how many kernels it compiled in how long (a failed or interrupted run
        says only its own one line)."""
        import time

        self._stop_bar()
        if ok and self.count and not self.warm:
            click_echo(f"nurbsinterp: {self.count} kernel(s) compiled in {time.perf_counter() - self.t0:.0f} s; "
                       "later runs load them")
        self.command, self.count = None, 0


COMPILES = CompileDisplay()


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.0f} minutes"


@contextlib.contextmanager
def warmup_progress(headline: str):
    """`nurbsinterp warmup`: say on stderr that every kernel is being compiled; a progress bar on a terminal
    naming the step compiling now. Yields warm_up's progress callback."""
    import time

    click_echo(headline)
    t0 = time.perf_counter()
    if not sys.stderr.isatty():
        yield lambda name, done, count: None
    else:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        with Progress(TextColumn("compiling"), TextColumn("{task.description}"), BarColumn(), TimeElapsedColumn(),
                      console=Console(stderr=True), transient=True) as bar:
            task = bar.add_task("", total=1)

            def progress(name, done, count):
                bar.update(task, completed=done, total=count,
                           description=f"{name} ({done + 1} of {count})" if name else "done")

            yield progress
    click_echo(f"nurbsinterp: kernels compiled in {time.perf_counter() - t0:.0f} s; later runs load them")


def click_echo(line: str) -> None:
    import click

    click.echo(line, err=True)


def servo_table(report, job: str, stderr: bool = False) -> None:
    """The simulate report (a SimulationReport) of *job* as a table (stdout; stderr when the trace takes stdout).

    With a capture (``report.measured``) the machine's errors stand beside the model's: model | machine.
    """
    from rich.table import Table

    from rich.text import Text

    title = f"servo simulation: {job} ({report.servo})"
    rows = [("ticks", f"{report.ticks} at T = {_ms(report.period)} "
             f"({report.command_ticks} commands, then {report.settle_time:.3g} s holding the last"
             + ("" if report.settled else ", NOT settled") + ")")]
    rows.extend(_error_rows(report))
    if report.rapid_ticks:
        rows.append(_rapid_row(report))
    if getattr(report, "precompensated", None):
        rows.append(("pre-compensated", f"{report.precompensated} (the stream's header): " + (
            "the tracking error is the plan's point (C(u) at the tick's u) - table, not the shaped command's"
            if report.tracking_against == "plan" else
            "the tracking error is command - table, the shaping itself (the plan's points are not in a "
            "look-ahead or acc/dec-after stream); the contour error is the measure")))
    meas = getattr(report, "measured", None)
    if meas is None:
        table = Table(title=Text(title), show_header=False, box=None)
        table.add_column(style="bold")
        table.add_column()
        for row in rows:
            table.add_row(*row)
    else:
        table = Table(title=Text(f"{title} beside the machine's capture {meas.capture}"), box=None)
        table.add_column("", style="bold")
        table.add_column("model")
        table.add_column("machine")
        machine = [f"{meas.ticks} measured: {report.command_ticks} commands + {meas.hold_ticks} hold (the capture: "
                   f"{meas.capture_lead_rows} rows before the stream, {meas.capture_hold_rows} after)"]
        machine.extend(text for _, text in _error_rows(meas, " (|dp|/T)"))
        if meas.rapid_ticks:
            machine.append(_rapid_row(meas)[1])
        for i, (label, model) in enumerate(rows):
            table.add_row(label, model, machine[i] if i < len(machine) else "")
        received = ("no *_cmd columns" if meas.as_received_max is None else "max |capture - plan| " + ", ".join(
            f"{a} {v:.3g} mm" for a, v in meas.as_received_max.items()))
        table.add_row("commands received", "", received)
    _console(stderr).print(table)


def _error_rows(r, feed_note: str = "") -> list[tuple[str, str]]:
    """(label, text) of a ServoReport's errors: contour, tracking per axis, feedrate (a program's cutting
    moves', when it has rapids)."""
    cutting = f" over the {r.cutting_ticks} ticks of cutting moves" if r.rapid_ticks else ""
    rows = [("contour error", f"max {r.contour_error_max * 1e3:.4g} um at t = {r.contour_error_max_t:.4f} s "
             f"(u = {r.contour_error_max_u:.6f}), RMS {r.contour_error_rms * 1e3:.4g} um{cutting}")]
    for axis, value in r.tracking_error_max.items():
        rows.append((f"tracking error {axis}", f"max {value * 1e3:.4g} um, RMS {r.tracking_error_rms[axis] * 1e3:.4g} um"))
    rows.append(("feedrate error", f"max |e| {r.feedrate_error_max:.4g} mm/s at t = {r.feedrate_error_max_t:.4f} s, "
                 f"RMS {r.feedrate_error_rms:.4g} mm/s{feed_note}"))
    return rows


def _rapid_row(r) -> tuple[str, str]:
    """The rapids' (G0) errors, apart from the cutting moves' (a traverse lags far more, and only where it ends
    counts): one row."""
    q = r.rapids
    tracking = ", ".join(f"{a} {v * 1e3:.4g}" for a, v in q.tracking_error_max.items())
    return ("rapids (G0)", f"{r.rapid_ticks} ticks, apart: contour error max {q.contour_error_max * 1e3:.4g} um at "
            f"t = {q.contour_error_max_t:.4f} s, tracking error max {tracking} um, feedrate error max "
            f"{q.feedrate_error_max:.4g} mm/s")


def _machine_errors(match) -> list[str]:
    """A capture's measured errors in compare's columns: contour max and RMS (um), feedrate error, motion time."""
    m = match.measured
    return [f"{m.contour_error_max * 1e3:.2f}", f"{m.contour_error_rms * 1e3:.2f}", f"{m.feedrate_error_max:.3f}",
            f"{match.motion_time:.4f}"]


def _machine_label(match) -> str:
    return "the machine" if match.matched_by == "commands" else "the machine (no commands: taken as the job's own)"


def _machine_title(match) -> str:
    return "" if match is None else f"\nthe machine: the capture {match.capture}, measured as the plan above it"


def compare_table(rows: list, title: str, match=None) -> None:
    """The compare rows (VariantResult) as one table on stdout; *match* (compare.CaptureMatch of the first table)
    the machine's row after its variant's."""
    from rich.table import Table

    from rich.text import Text

    look_ahead = bool(rows) and rows[0].interpolator == "look-ahead"
    if look_ahead:
        table = Table(title=Text(f"{title}: profiles planned with look-ahead, through the servo model"
                                 + _machine_title(match)))
        for name in ("profile", "max dev um", "contour max um", "contour RMS um", "feed err mm/s", "time s"):
            table.add_column(name, justify="left" if name == "profile" else "right")
    else:
        table = Table(title=Text(f"{title}: interpolators and acc/dec through the servo model"
                                 + _machine_title(match)))
        for name in ("method", "profile", "acc/dec", "max |FF|", "chord um", "contour max um",
                     "contour RMS um", "feed err mm/s", "time s"):
            table.add_column(name, justify="left" if name in ("method", "profile", "acc/dec") else "right")
    for i, r in enumerate(rows):
        if look_ahead:
            table.add_row(r.profile, f"{r.command_deviation_max * 1e3:.4f}", f"{r.contour_error_max * 1e3:.2f}",
                          f"{r.contour_error_rms * 1e3:.2f}", f"{r.feedrate_error_max:.3f}", f"{r.motion_time:.4f}")
        else:
            table.add_row(r.interpolator, r.profile, r.accdec, f"{r.ff_max:.2e}",
                          f"{r.chord_error_max * 1e3:.4f}", f"{r.contour_error_max * 1e3:.2f}",
                          f"{r.contour_error_rms * 1e3:.2f}", f"{r.feedrate_error_max:.3f}", f"{r.motion_time:.4f}")
        if match is not None and match.index == i:  # the plan's own measures (dev, FF, chord) are the row above's
            lead = [f"  {_machine_label(match)}"] + ([] if look_ahead else ["", ""]) + ["-"] * (1 if look_ahead else 2)
            table.add_row(*lead, *_machine_errors(match))
    _console().print(table)


def compensation_table(rows: list, title: str, match=None) -> None:
    """The pre-compensation study (compare.CompensationResult rows) on stdout: max contour error, plant x method;
    *match* (compare.CaptureMatch of a pre-compensated plan) the machine as a plant, in its method's column."""
    from rich.table import Table

    from rich.text import Text

    methods = list(dict.fromkeys(r.method for r in rows))
    plants = list(dict.fromkeys(r.model_error for r in rows))
    cell = {(r.method, r.model_error): r.contour_error_max for r in rows}
    table = Table(title=Text(f"{title}\nmax contour error, um: pre-compensated for the model, run on the model "
                             "or on a plant that differs from it" + ("" if match is None else
                                                                      f"\nthe machine: the capture {match.capture}")))
    table.add_column("plant", justify="left")
    for method in methods:
        table.add_column(method if method != "none" else "none (as planned)", justify="right")
    for plant in plants:
        table.add_row("the model" if plant == "none" else plant, *(f"{cell[m, plant] * 1e3:.4g}" for m in methods))
    wrong = [p for p in plants if p != "none"]
    if wrong:
        table.add_row("worst wrong plant", *(f"{max(cell[m, p] for p in wrong) * 1e3:.4g}" for m in methods))
    if match is not None:
        table.add_row(_machine_label(match), *(f"{match.measured.contour_error_max * 1e3:.4g}" if m == match.method
                                               else "-" for m in methods))
    _console().print(table)


def bench_table(result) -> None:
    """Table 1 of the paper beside this machine's numbers (a BenchResult), on stdout."""
    from rich.table import Table
    from rich.text import Text

    m = result.machine
    table = Table(title=Text(f"computation time per tick (us): {result.job}, T = {_ms(result.period)}, "
                             f"{m.cpu}, {m.cores} cores"))
    for name in ("interpolator", "profile", "paper DSP", "mean", "p99", "max", "speed-up"):
        table.add_column(name, justify="left" if name in ("interpolator", "profile") else "right")
    for r in result.rows:
        table.add_row(r.interpolator, r.profile, "-" if r.paper_us is None else f"{r.paper_us:g}",
                      f"{r.mean_us:.3f}", f"{r.p99_us:.3f}", f"{r.max_us:.2f}",
                      "-" if r.speedup is None else f"{r.speedup:,.0f}x")
    s = result.servo
    table.add_row("servo controller", f"{s.axes} axes", f"{s.paper_us:g}", f"{s.mean_us:.3f}",
                  f"{s.p99_us:.3f}", f"{s.max_us:.2f}", f"{s.speedup:,.0f}x")
    p = result.precompensation
    if p is not None:
        table.add_row("precompensate exact", f"{p.axes} axes, {p.preview_ticks}-tick preview", "-",
                      f"{p.mean_us:.3f}", f"{p.p99_us:.3f}", f"{p.max_us:.2f}", "-")
    console = _console()
    console.print(table)
    once = result.one_time
    console.print(f"one-time: planning (Bezier table, arc-length table, profile) {once.planning_ms:.2f} ms; "
                  f"kernel start-up (numba cache load, or compile on a first run) {once.kernel_startup_ms:.0f} ms; "
                  f"clock read {result.clock_overhead_ns:.0f} ns (subtracted)")


def _estimate(value: float, std: float, unit: str = "") -> str:
    return f"{value:.6g}{unit} ± {std * 100:.2g} %"


def _pole_text(pole, estimate) -> str:
    if abs(pole.imag) > 1e-9 * abs(pole):
        return f"{pole.real:.5g} ± {abs(pole.imag):.5g}j (|p| {_estimate(estimate.value, estimate.std)})"
    return _estimate(pole.real, estimate.std)


PARAMETER_LABELS = {"K": ("K (DC gain)", " mm/s/V"), "a": ("a (pole)", " rad/s"), "omega": ("omega", " rad/s"),
                    "zeta": ("zeta", ""), "g": ("HAL lowpass gain", "")}


def identify_table(result, output, stderr: bool = False) -> None:
    """identify's report (an identify.Identification): one column per axis (stdout; stderr with -o -)."""
    from rich.table import Table
    from rich.text import Text

    r = result.record
    title = (f"identified: {result.capture} of {result.job}, T = {_ms(result.period)}, {r.command.shape[0]} rows "
             f"({r.command_ticks} commands + {r.hold_rows} hold; {r.lead_rows} before the stream dropped)")
    table = Table(title=Text(title), box=None)
    table.add_column("", style="bold")
    fits = list(result.axes.values())
    for f in fits:
        table.add_column(f.axis)
    table.add_row("controller", *[f"kp {f.model.kp:.6g}, kv {f.model.kv:.6g}" for f in fits])
    table.add_row("plant family", *[f"{f.family}, feedback delay {f.delay}" for f in fits])
    names = []
    for f in fits:
        names.extend(k for k in f.parameters if k not in names)
    for name in names:
        label, unit = PARAMETER_LABELS.get(name, (name, ""))
        table.add_row(label, *[_estimate(f.parameters[name].value, f.parameters[name].std, unit)
                               if name in f.parameters else "" for f in fits])
    # a complex pair once, as re ± im j
    table.add_row("poles (rad/s)", *["; ".join(_pole_text(p, e) for p, e in zip(f.pole_values, f.poles)
                                               if p.imag >= 0) or "none" for f in fits])
    table.add_row("encoder", *[f"{f.encoder * 1e3:.4g} um (detected)" if f.encoder else "none (%f feedback)"
                               for f in fits])
    table.add_row("residual", *[f"RMS {f.rms * 1e3:.3g} um, max {f.max * 1e3:.3g} um" for f in fits])
    table.add_row("limited by", *[f"{', '.join(f.limited_by)} (floor {f.floor * 1e3:.3g} um, noise in the residual "
                                  f"{f.noise * 1e3:.3g} um)" for f in fits])
    table.add_row("families (RMS)", *[", ".join(f"{n} {rms * 1e3:.3g} um" for n, _, rms, _ in f.alternatives)
                                      for f in fits])
    if r.received_max is not None:
        table.add_row("commands received", *[f"max |capture - plan| {r.received_max[f.axis]:.3g} mm" for f in fits])
    console = _console(stderr)
    console.print(table)
    for a in result.held:
        console.print(Text(f"{a}: {result.held_text(a)}"))
    where = "not written (-o SERVO.yaml writes it)" if output is None else (
        "written to stdout" if output == "-" else f"written to {output}")
    console.print(Text(f"model {where}; it holds at T = {_ms(result.period)} only"))


def sweep_summary(result) -> None:
    """A sweep's summary on stdout: the headline, what failed, the worst case of each measure per machine."""
    from rich.table import Table
    from rich.text import Text

    from ..sweep.results import FAILED_SHOWN, WORST_MEASURES

    s = result.summary
    c = s.counts
    console = _console()
    console.print(Text(f"{result.cases} cases ({result.resumed} from an earlier run, {result.computed} computed on "
                       f"{result.scheduler}, {result.workers} worker(s)): {c['ok']} ok, {c['failed']} failed, "
                       f"{c['error']} internal errors, {c['lost']} lost"
                       + (f", {c['timeout']} timed out" if c.get("timeout") else "") +
                       f"; limits broken in {s.limits_broken}; "
                       f"rows in {result.output}"))
    failed = s.failed_rows()
    if failed:
        table = Table(title=Text("failed cases" + (f" (the first {FAILED_SHOWN}; {s.failed_more} more in the error "
                                                   "column)" if s.failed_more else "")))
        for name in ("case", "program", "machine", "settings", "error"):
            table.add_column(name, justify="right" if name == "case" else "left", overflow="fold")
        for case, program, machine, settings, error in failed:
            table.add_row(str(case), program, machine, settings, error)
        console.print(table)
    if s.worst:
        table = Table(title=Text("the worst case of each measure, per machine"))
        for name in ("machine", "measure", "value", "case", "program", "settings"):
            table.add_column(name, justify="right" if name in ("value", "case") else "left", overflow="fold")
        names = dict(WORST_MEASURES)
        for (machine, column), (value, case, program, settings, what) in sorted(s.worst.items()):
            table.add_row(machine, names[column], f"{value:.6g}" + (f" ({what})" if what else ""), str(case),
                          program, settings)
        console.print(table)


def look_ahead_lines(run, target: str) -> list[str]:
    """The look-ahead run summary (a motion.pipeline.LookAhead run to its end), in a machinist's terms: the motion
    time, cutting apart from rapids; the feeds the program set; the tolerance as taken; what blending did; which
    limits bound the motion; what the commands measured; and, when the plan is slow or rough, what to do."""
    import math

    from ..motion.limits import JERK_SHARES
    from ..motion.nurbs_blocks import APPROX_SHARE, SAMPLES
    from ..motion.pipeline import rapid_time
    from ..names import AXES

    f = run.facts
    sm = run.smoothing
    lim = run.limits
    axes = AXES[:run.dim]
    moving = f.motion_time or 1.0
    vel = ", ".join(f"{a} {f.axis_extremes[0, i]:.6g}" for i, a in enumerate(axes))
    acc = ", ".join(f"{a} {f.axis_extremes[1, i]:.6g}" for i, a in enumerate(axes))
    jerk = ", ".join(f"{a} {f.axis_extremes[2, i]:.3g}" for i, a in enumerate(axes))

    def limits_of(values, unit):
        given = ", ".join(f"{a} {values[i]:g}" for i, a in enumerate(axes) if math.isfinite(values[i]))
        return f"{given} {unit}" if given else "none"

    rapids = rapid_time(run)
    own = _own_words(run)
    exact = lim.tolerance == 0.0 and f.tolerance_max == 0.0  # no tolerance anywhere: nothing smoothed or blended
    lines = [
        f"nurbsinterp: {f.ticks} ticks to {target}, look-ahead across {f.blocks} blocks "
        f"({f.dropped} of zero length dropped)",
        f"  motion time      {f.motion_time:.6g} s at T = {run.period * 1e3:g} ms"
        + (f": cutting {f.motion_time - rapids:.6g} s, rapids (G0) {rapids:.6g} s" if f.rapid_moves else ""),
        _feeds_line(run),
        "  tolerance        " + (f"{lim.tolerance * 1e3:g} um = {lim.tolerance:g} mm (--tolerance"
                                 + ("; over any G64 P the program states)" if hasattr(run.job.path, "items") else ")")
                                 if lim.override_program else
                                 (f"{own['own']}, block by block: up to {f.tolerance_max * 1e3:g} um "
                                  f"({own['rest']}" + (": the exact path)" if own["rest"].startswith("none") else ")")
                                  if f.tolerance_max > 0.0 else
                                  f"none: the exact path ({own['none']})")),
        f"  segments         {f.segments}: {f.lines} lines, {f.arcs} arcs, {f.curve_rows} curve rows, {f.blends} corner "
        f"blends (two halves each: {2 * f.blends} arcs)",
        *([f"  NURBS            {f.nurbs} blocks followed by {f.nurbs_rows} cubic rows (Hermite, on the curve's own "
           f"points and tangents); worst deviation {f.nurbs_deviation * 1e3:.3g} um from the curve at the same "
           f"parameter ({SAMPLES} samples a row; each within {0.5 * APPROX_SHARE:.0%} of the tolerance, 1e-9 mm "
           "with none)"] if f.nurbs else []),
        *([] if exact else [
            f"  smoothing        {sm.moves} moves in {sm.runs} runs refitted as {sm.curves} cubic B-splines "
            f"({sm.rows} Bezier rows); worst deviation {sm.worst * 1e3:.4g} um (verified bound, two-sided)"
            + (f"; {sm.kept} runs left to blends (no smooth curve within the tolerance)" if sm.kept else "")
            if run.smooth else "  smoothing        off (--no-smooth): every joint blended or passed",
            f"  blends           {f.blends} corners rounded within "
            + (f"{lim.tolerance * 1e3:g} um" if lim.override_program else
               f"{own['own']} (up to {f.tolerance_max * 1e3:g} um; {own['rest']})")
            + "; worst deviation "
            f"{f.worst_blend * 1e3:.4g} um (two-sided, exact: d tan(theta/4))"]),
        f"  joints           {f.unblended} passed unblended on the path at a capped speed; {max(f.stops, 0)} stops "
        f"(program stops, G61.1 corners, reversals; {max(f.sharp_stops, 0)} joints too sharp to pass unblended "
        "moving"
        + (f"; {f.corners_at_rest} corners at rest where crossing the blend under the jerk limit takes longer"
           if f.corners_at_rest else "") + ")",
        *([f"  program stops    {f.program_stop_count}: " + "; ".join(
            words + (f" (dwell {dwell:g} s)" if dwell > 0.0 else "") for words, dwell in f.program_stops[:3])
           + ("; ..." if f.program_stop_count > 3 else "")] if f.program_stop_count else []),
        f"  bound by         the feed cap {f.cruise_time / moving:.1%}, an acceleration cap "
        f"{f.ramp_time / moving:.1%}, at rest {f.rest_time / moving:.1%} of the motion time",
        "  limits           tangential accel " + (f"{lim.accel:g} mm/s^2 ({lim.source})" if math.isfinite(lim.accel)
                                                    else "none of its own (the axes' bound)") + "; axes max velocity "
        f"{limits_of(lim.axis_velocity, 'mm/s')}, max accel {limits_of(lim.axis_accel, 'mm/s^2')}"
        + (f", max jerk {limits_of(lim.axis_jerk, 'mm/s^3')}" if any(math.isfinite(j) for j in lim.axis_jerk) else ""),
        *([f"  jerk             ramps jerk-limited at {lim.tangential_jerk():g} mm/s^3 along the path"
           + ("" if not any(math.isfinite(j) for j in lim.axis_jerk) else
              f", or at a segment's own cap where its axes allow more ({JERK_SHARES[0]:g} of the smallest axis' jerk; "
              "the rest for the path's turns and joints)")]
          if math.isfinite(lim.tangential_jerk()) else []),
        f"  commands         largest |v| {vel} mm/s; |a| {acc} mm/s^2; |jerk| {jerk} mm/s^3 "
        "(finite differences of the stream)",
        f"  planning         {f.wall_time:.3g} s end to end, read to written ({f.blocks / max(f.wall_time, 1e-9):,.0f} "
        f"blocks/s); the first ticks after {f.first_tick:.3g} s; the largest window held {f.max_window} segments",
    ]
    ip = run.job.interpolator
    if not ip.method_default and ip.method != "exact":  # asked for, and not what the look-ahead does: say so
        lines.append(f"  note             interpolator.method {ip.method} is not used: the look-ahead places each tick "
                     "at its planned arc length along the segments (exact)")
    prof = run.job.profile
    if prof.type == "exponential" and "exponential" in lim.source:  # its ramp binds, τ aside: say so
        lines.append("  note             profile.time_constant shapes the exponential ramp of one curve only: across "
                     "blocks its ramp is F/Ta, which loses the same Ta a move (README, \"One profile, one motion\")")
    accel_given = {dotted: origin for dotted, _, origin in run.job.given}.get("profile.accel_time")
    if prof.type == "adaptive" and accel_given is not None and not run.job.accel_time_stated:
        lines.append(f"  note             profile.accel_time of {accel_given} is not used: it was written for that "
                     "file's own profile, and the adaptive profile chosen elsewhere plans to its limits")
    if f.capped_feeds:
        lines.append(f"  note             {f.capped_feeds} line(s) programmed faster than their axes allow: their "
                     "feedrate is capped by the axes' max velocity")
    hint = look_ahead_hint(run)
    if hint:
        lines.append(f"  what to do       {hint}")
    return lines


def _own_words(run) -> dict:
    """How the summary names the job's own feedrates and tolerance: a G-code program's F words and G64 P, a YAML
    path's or a drawing's blocks, and the profile's corner_tolerance where a block states none."""
    corner = run.job.profile.corner_tolerance
    if hasattr(run.job.path, "items"):  # a program, read as it runs (config.gcode.ProgramStream)
        words = {"whose": "program's", "own": "the program's own G64 P", "none": "the program states no G64 P",
                 "set": "G64 P in the program"}
    else:
        words = {"whose": "job's", "own": "the job's own tolerance (a block's mode.tolerance)",
                 "none": "the job states no tolerance", "set": "profile.corner_tolerance in the job"}
    words["rest"] = ("none where it states none" if corner is None else
                     f"profile.corner_tolerance, {corner * 1e3:g} um, where it states none")
    return words


def _mm_min(v: float) -> str:
    return f"{v * 60.0:.6g} mm/min"


def _feeds_line(run) -> str:
    """The feeds as the program set them (its F words, in mm/min as a programmer writes them) and what the
    moves without one took; an overriding --feedrate says that the program's are not used."""
    f, lim = run.facts, run.limits
    if run.job.feedrate_override:
        return (f"  feeds            every move at {lim.feedrate:.6g} mm/s = {_mm_min(lim.feedrate)} (--feedrate: the "
                "program's own feedrates are not used)")
    own = f.feed_moves - f.feed_defaulted
    if own:
        span = (_mm_min(f.feed_low) if f.feed_low == f.feed_high else
                f"{f.feed_low * 60.0:.6g} to {_mm_min(f.feed_high)}")
        text = f"{span} (the {_own_words(run)['whose']} own, on {own} of {f.feed_moves} feed moves)"
    else:
        text = f"the profile's {lim.feedrate:.6g} mm/s = {_mm_min(lim.feedrate)} on every feed move ({f.feed_moves})"
    if f.feed_defaulted and own:
        text += (f"; {f.feed_defaulted} feed moves with no feedrate of their own take the profile's "
                 f"{lim.feedrate:.6g} mm/s = {_mm_min(lim.feedrate)}")
    if f.rapid_moves:
        text += f"; {f.rapid_moves} rapids (G0) at {lim.rapid_feedrate:.6g} mm/s, capped by the axes"
    return f"  feeds            {text}"


def look_ahead_hint(run) -> str:
    """One line of what to do when the plan is slow (corners that stop, an acceleration below the machine's) or
    rough (no jerk limit); empty when there is nothing to say.  The first that applies, slowest cause first."""
    import math

    f, lim = run.facts, run.limits
    dim = run.dim
    corners = f.unblended + max(f.sharp_stops, 0)
    if corners > 0 and lim.tolerance == 0.0 and f.tolerance_max == 0.0:  # the exact path everywhere
        at_rest = max(f.sharp_stops, 0)
        if corners == 1:
            which = "1 corner passed on the exact path" + (" (at rest, too sharp to pass moving)" if at_rest else "")
        else:
            which = f"{corners} corners passed on the exact path ({at_rest} of them at rest, too sharp to pass moving)"
        return (f"{which}: --tolerance (e.g. 10um; or {_own_words(run)['set']}) would blend "
                f"{'them' if corners != 1 else 'it'} within it")
    axis_acc = [a for a in lim.axis_accel[:dim] if math.isfinite(a)]
    if "ramp" in lim.source and axis_acc and lim.accel < min(axis_acc):
        ramp = (f"the acceleration along the path is the {run.job.profile.type} profile's ramp, {lim.accel:g} mm/s^2, "
                f"below the axes' {min(axis_acc):g} mm/s^2: ")
        # the ramp binds a machine with limits of its own only where the profile is chosen (motion.limits)
        if run.job.profile.type == "adaptive":  # its accel_time given: a ramp of its own
            return ramp + "without accel_time (the job's or --accel-time) it plans to the machine's own limits"
        return ramp + ("--profile-type adaptive, or the default profile (no profile type, no accel_time), plans to "
                       "the machine's own limits; a shorter accel_time raises the ramp")
    if f.corners_at_rest:
        return (f"{f.corners_at_rest} corners are taken at rest under the jerk limit: a larger --tolerance rounds "
                "them wider, a higher --axis-max-jerk lets the plan cross them")
    if not any(math.isfinite(j) for j in lim.axis_jerk[:dim]) and not math.isfinite(lim.jerk):
        worst = max(float(f.axis_extremes[2, i]) for i in range(dim))
        return (f"rough: no jerk limit, the commands' jerk reaches {worst:.3g} mm/s^3; --axis-max-jerk "
                + ",".join(f"{a}=J" for a in "xyz"[:dim]) + " (the machine's tuning) holds one on every tick")
    return ""
