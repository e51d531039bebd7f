"""Pictures of a simulated run (the paper's Figs. 7 and 8), of `compare` and of the adaptive planner.

Written with matplotlib in the format the file's extension names (png, svg, pdf, jpg, ...: the CLI checks
the extension before any work and passes the format here).
"""
from __future__ import annotations

import numpy as np


def _figure(rows, cols, size):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(rows, cols, figsize=size, constrained_layout=True)
    return plt, fig, axs


def _save(plt, fig, path, fmt, label=None) -> None:
    """Write the picture atomically: a failed run leaves no partial file.  *label* names it in errors (the path)."""
    from .streams import open_output

    with open_output(path, label=label) as fh:
        fig.savefig(fh, format=fmt, dpi=110)
    plt.close(fig)


def plot_simulation(path, series: np.ndarray, axes, curve, report, title: str, fmt: str = "png",
                    label: str | None = None) -> None:
    """Four panels: path (actual with its error magnified), contour error, feedrate, feedrate error.

    *series* holds per row k, t, u, the commanded and the actual position per axis, the contour error, the
    commanded and the actual feedrate, and the contour error's foot point u (simulation.Series); *curve* None: a
    program's run, whose rows add the feet's points (the path is drawn through them).  *report* is
    simulate's SimulationReport (or a ServoReport); *label* names the file in errors (see _save).  With a
    capture (``report.measured``) the machine's run is drawn beside the model's in every panel, its path
    magnified by the same gain on its own feet (simulation.series_columns).
    """
    from .simulation import series_columns

    n = len(axes)
    machine = getattr(report, "measured", None)
    col = series_columns(n, program=curve is None, measured=machine is not None)
    t = series[:, col["t"]]
    cmd = series[:, col["cmd"]]
    act = series[:, col["act"]]
    err = series[:, col["err"]]
    v_cmd, v_act = series[:, col["v_cmd"]], series[:, col["v_act"]]
    plt, fig, axs = _figure(2, 2, (12, 8.5))
    fig.suptitle(title)

    ax = axs[0, 0]
    if curve is not None:
        on_curve = curve.evaluate(np.linspace(*curve.domain, 4000))
        # the contour error's own foot points (contour.PathWindow)
        foot = curve.evaluate(series[:, col["foot"]])
        drawn = "curve"
    else:  # a program, never held whole: its path drawn through the kept ticks' feet (motion.contour.ProgramWindow)
        foot = series[:, col["foot_point"]]
        on_curve = foot
        drawn = "program (at the feet)"
    meas = None
    if machine is not None:  # the capture's positions on their own feet, NaN where the capture has no tick
        meas = series[:, col["meas"]]
        have = np.isfinite(series[:, col["foot_meas"]])
        meas_foot = np.full_like(meas, np.nan)
        if curve is not None:
            meas_foot[have] = curve.evaluate(series[have, col["foot_meas"]])
        else:
            meas_foot = series[:, col["foot_meas_point"]]
    ax.plot(on_curve[:, 0], on_curve[:, 1], color="0.75", lw=3, label=drawn)
    # magnify the contour error, the deviation from the curve (not the lag behind the command,
    # which runs along the path and would bend the picture): foot point + gain x (actual - foot); the model's and the
    # machine's by the same gain, so that they compare
    peak = max(float(np.abs(act - foot).max()), 1e-12)
    if meas is not None and np.isfinite(meas).any():
        peak = max(peak, float(np.nanmax(np.abs(meas - meas_foot))))
    gain = 10 ** np.floor(np.log10(max(0.05 * np.ptp(on_curve[:, :2], axis=0).max() / peak, 1.0)))
    shown = foot[:, :2] + gain * (act[:, :2] - foot[:, :2])
    ax.plot(cmd[:, 0], cmd[:, 1], color="C0", lw=1, label="commanded")
    ax.plot(shown[:, 0], shown[:, 1], color="C3", lw=1, label=f"model, error x{gain:g}" if meas is not None
            else f"actual, error x{gain:g}")
    if meas is not None:
        on_machine = meas_foot[:, :2] + gain * (meas[:, :2] - meas_foot[:, :2])
        ax.plot(on_machine[:, 0], on_machine[:, 1], color="C1", lw=1, label=f"machine, error x{gain:g}")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("path")
    ax.legend(loc="best", fontsize=8)

    ax = axs[0, 1]
    ax.plot(t, err * 1e3, color="C3", lw=1, label="model" if meas is not None else None)
    title_err = (f"contour error: max {report.contour_error_max * 1e3:.4g} µm, "
                 f"RMS {report.contour_error_rms * 1e3:.4g} µm")
    if meas is not None:
        ax.plot(t, series[:, col["err_meas"]] * 1e3, color="C1", lw=1, label="machine")
        ax.legend(loc="best", fontsize=8)
        title_err = (f"contour error max: model {report.contour_error_max * 1e3:.4g} µm, "
                     f"machine {machine.contour_error_max * 1e3:.4g} µm")
    if report.rapid_ticks:  # the maxima are the cutting moves'; the curve shows the rapids' too
        title_err = title_err.replace("contour error", "contour error (cutting moves)", 1)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("contour error (µm)")
    ax.set_title(title_err)

    ax = axs[1, 0]
    ax.plot(t, v_cmd, color="C0", lw=1, label="commanded")
    ax.plot(t, v_act, color="C3", lw=1, ls="--", label="model" if meas is not None else "actual")
    if meas is not None:
        ax.plot(t, series[:, col["v_meas"]], color="C1", lw=1, ls=":", label="machine (|dp|/T)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("feedrate (mm/s)")
    ax.set_title("feedrate")
    ax.legend(loc="best", fontsize=8)

    ax = axs[1, 1]
    ax.plot(t, v_act - v_cmd, color="C2", lw=1, label="model" if meas is not None else None)
    if meas is not None:
        ax.plot(t, series[:, col["v_meas"]] - v_cmd, color="C1", lw=1, label="machine")
        ax.legend(loc="best", fontsize=8)
    ax.set_xlabel("t (s)")
    ax.set_ylabel("feedrate error (mm/s)")
    ax.set_title(f"feedrate error: max |e| {report.feedrate_error_max:.4g} mm/s, "
                 f"RMS {report.feedrate_error_rms:.4g} mm/s" if meas is None else
                 f"feedrate error max |e|: model {report.feedrate_error_max:.4g} mm/s, "
                 f"machine {machine.feedrate_error_max:.4g} mm/s")
    for a in axs.flat:
        a.grid(True, alpha=0.3)
    _save(plt, fig, path, fmt, label)


def plot_compare(path, rows: list, title: str, fmt: str = "png", label: str | None = None) -> None:
    """Contour error and feedrate error of every variant (compare's VariantResult rows), side by side."""
    labels = [f"{r.interpolator}\n{r.profile}\n{r.accdec}" for r in rows]
    x = np.arange(len(rows))
    plt, fig, axs = _figure(2, 1, (max(10, 0.75 * len(rows)), 8))
    fig.suptitle(title)
    axs[0].bar(x - 0.2, [r.contour_error_max * 1e3 for r in rows], 0.4, label="max")
    axs[0].bar(x + 0.2, [r.contour_error_rms * 1e3 for r in rows], 0.4, label="RMS")
    axs[0].set_ylabel("contour error (µm, linear scale)")
    axs[0].legend()
    axs[1].bar(x, [r.feedrate_error_max for r in rows], 0.6, color="C2")
    axs[1].set_ylabel("max feedrate error (mm/s)")
    for ax in axs:
        ax.set_xticks(x, labels, fontsize=7)
        ax.grid(True, axis="y", alpha=0.3)
    _save(plt, fig, path, fmt, label)


def plot_adaptive(path, plan, title: str, fmt: str = "png", label: str | None = None) -> None:
    """The adaptive planner in one figure: feed limit, scheduled feedrate, and where each limit binds."""
    from .planner import LIMITS

    plt, fig, axs = _figure(2, 1, (12, 7.5))
    fig.suptitle(title)
    ax = axs[0]
    s, vl, binding = plan.s_grid, plan.v_limit, plan.binding
    for i, name in enumerate(LIMITS):
        mask = binding == i
        if mask.any() and name != "feedrate":
            ax.scatter(s[mask], vl[mask], s=4, alpha=0.5, label=f"{name} binds", zorder=2)
    # the limit line above the markers, so that it is never hidden under them
    ax.plot(s, vl, color="0.35", lw=1, label="feed limit V_lim(s)", zorder=3)
    t = np.linspace(0.0, plan.duration, 20001)
    S, V, A = plan.evaluate(t)
    ax.plot(S, V, color="C3", lw=1.2, label="scheduled feedrate V(s)")
    ax.set_ylim(0, 1.15 * plan.feedrate)
    ax.set_xlabel("arc length s (mm)")
    ax.set_ylabel("feedrate (mm/s)")
    ax.legend(loc="lower right", fontsize=8)
    ax = axs[1]
    line_v, = ax.plot(t, V, color="C3", lw=1, label="feedrate V (mm/s, left)")
    ax2 = ax.twinx()
    line_a, = ax2.plot(t, A, color="C0", lw=0.8, label="tangential acceleration A (mm/s², right)")
    ax.set_xlabel("t (s)")
    ax.set_ylabel("feedrate (mm/s)", color="C3")
    ax2.set_ylabel("tangential acceleration (mm/s²)", color="C0")
    ax.legend(handles=[line_v, line_a], loc="lower right", fontsize=8)
    slow = plan.slowest_scheduled
    ax.set_title(f"motion time {plan.duration:.4g} s; slowest between the ramps {slow.v:.3g} mm/s "
                 f"at s = {slow.s:.4g} mm")
    for a in axs:
        a.grid(True, alpha=0.3)
    _save(plt, fig, path, fmt, label)
