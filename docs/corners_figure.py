"""Draw docs/corners.png: the 40 mm square's corner (40, 0) under each corner treatment.

    .venv/bin/python docs/corners_figure.py

Left, the commanded ticks near the corner; right, the commanded feed over time.  The
variants are those of the "corners" table (docs/planning.md; docs/readme_tables.py: corner_variants).
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT))
from readme_tables import corner_variants, planned  # noqa: E402

SHOWN = (0, 2, 4, 5, 6)  # rows of the table (readme_tables.CORNER_ROWS): trapezoidal, after, the blends, rounded


def main(out=ROOT / "corners.png"):
    fig, (ax_xy, ax_v) = plt.subplots(1, 2, figsize=(11, 4.6))
    ax_xy.plot([38, 40, 40], [0, 0, 2], color="0.6", lw=4, alpha=0.4, label="the square's corner")
    for row, (label, path, args) in enumerate(corner_variants()):
        if row not in SHOWN:
            continue
        columns, data, _ = planned(path, args)
        x, y = data[:, columns.index("x")], data[:, columns.index("y")]
        near = (x > 37.5) & (y < 2.5)
        ax_xy.plot(x[near], y[near], ".-", ms=3, lw=0.8, label=label)
        ax_v.plot(data[:, columns.index("t")], data[:, columns.index("v")], lw=1, label=label)
    ax_xy.set_xlim(37.5, 40.6)
    ax_xy.set_ylim(-0.6, 2.5)
    ax_xy.set_aspect("equal")
    ax_xy.set_xlabel("x (mm)")
    ax_xy.set_ylabel("y (mm)")
    ax_xy.set_title("ticks near the corner (40, 0), T = 1 ms")
    ax_xy.legend(fontsize=7, loc="upper left")
    ax_v.set_xlabel("t (s)")
    ax_v.set_ylabel("commanded feed v (mm/s)")
    ax_v.set_title("feed over the whole square")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    print(f"wrote {out}", file=sys.stderr)


if __name__ == "__main__":
    main()
