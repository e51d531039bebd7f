"""Draw docs/precompensation.png: contour error over time with and without pre-compensation.

    .venv/bin/python docs/precompensation_figure.py

The paper's circle (left) and the butterfly with the adaptive profile (right), through the
paper's servo model: as planned, axis-lag matching and the exact inverse on the model itself,
and the exact inverse on plants 5 % off (README, "Pre-compensating the servo's lag"; the
runs are those of docs/readme_tables.py: precompensation_run).
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
from readme_tables import ADAPTIVE, BUTTERFLY, CIRCLE, precompensation_run  # noqa: E402

#: (label, method, model error, style)
CURVES = (("as planned, on the model", "none", None, dict(color="0.3", lw=1.2)),
          ("axis-lag matching, on the model", "match", None, dict(color="tab:orange", lw=1)),
          ("exact inverse, plant gain −5 %", "exact", "gain=-5%", dict(color="tab:blue", lw=1, ls="--")),
          ("exact inverse, gain x −5 %, y +5 %", "exact", "x.gain=-5%,y.gain=+5%", dict(color="tab:purple", lw=1,
                                                                                        ls=":")),
          ("exact inverse, on the model", "exact", None, dict(color="tab:green", lw=1)))
FLOOR = 1e-4  # µm: the plot's bottom (the exact inverse on the model reaches 1e-6 µm)


def main(out=ROOT / "precompensation.png"):
    from nurbsinterp.cli.common import load_cli
    from nurbsinterp.config import load_job

    jobs = (("the paper's circle, trapezoidal, 100 mm/s", load_job(CIRCLE)),
            ("the butterfly, adaptive profile", load_cli(BUTTERFLY, profile_file=ADAPTIVE)))
    fig, axes = plt.subplots(1, 2, figsize=(12, 6.0), sharey=True)
    for ax, (title, job) in zip(axes, jobs):
        for label, method, error, style in CURVES:
            report, series = precompensation_run(job, method, error)
            t, contour = series[:, 1], np.maximum(series[:, 7] * 1e3, FLOOR)
            ax.plot(t, contour, label=f"{label}: max {report.contour_error_max * 1e3:.3g} µm", **style)
        ax.set_yscale("log")
        ax.set_ylim(FLOOR, 2e3)
        ax.set_xlabel("t (s)")
        ax.set_title(title)
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    axes[0].set_ylabel("contour error (µm)")
    fig.suptitle("Contour error of the paper's X-Y table (T = 1 ms): commands pre-compensated for the model")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
