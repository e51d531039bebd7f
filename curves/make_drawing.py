"""Write curves/drawing.dxf: the DXF reader's example, a small part outline (mm).

One closed chain on layer CUT, counter-clockwise from the origin: a LINE along the
bottom, an ARC (r = 15) round the right end, an LWPOLYLINE along the top with a
bulge of -1 (a semicircular notch, r = 10, turning clockwise into the part), and a
rational cubic SPLINE (weights != 1) back down to the origin, tangent to the bottom
line there.  A TEXT label on layer NOTES is no toolpath: the reader lists it as ignored.

    .venv/bin/python curves/make_drawing.py [OUT.dxf]

The output is deterministic for a given ezdxf version (fixed metadata, no timestamps).
"""
from __future__ import annotations

import sys
from pathlib import Path

import ezdxf
from ezdxf import units

SPLINE_POINTS = [(20, 30), (6, 30), (-10, 26), (-14, 8), (-8, 0), (0, 0)]
SPLINE_WEIGHTS = [1.0, 1.0, 1.6, 0.7, 1.0, 1.0]
SPLINE_KNOTS = [0, 0, 0, 0, 1 / 3, 2 / 3, 1, 1, 1, 1]


def make(out: Path) -> None:
    fixed = ezdxf.options.write_fixed_meta_data_for_testing
    ezdxf.options.write_fixed_meta_data_for_testing = True  # no timestamps or random GUIDs in the file
    try:
        _drawing().saveas(out)
    finally:
        ezdxf.options.write_fixed_meta_data_for_testing = fixed


def _drawing():
    doc = ezdxf.new("R2010", setup=False)
    doc.units = units.MM
    doc.header["$MEASUREMENT"] = 1  # metric
    doc.layers.add("CUT", color=1)
    doc.layers.add("NOTES", color=3)
    msp = doc.modelspace()
    cut = {"layer": "CUT"}
    msp.add_line((0, 0), (80, 0), dxfattribs=cut)
    msp.add_arc((80, 15), 15, -90, 90, dxfattribs=cut)  # (80, 0) to (80, 30), counter-clockwise
    msp.add_lwpolyline([(80, 30, 0), (55, 30, -1), (35, 30, 0), (20, 30, 0)], format="xyb", dxfattribs=cut)
    spline = msp.add_spline(dxfattribs=cut)
    spline.dxf.degree = 3
    spline.control_points = [(x, y, 0) for x, y in SPLINE_POINTS]
    spline.weights = SPLINE_WEIGHTS
    spline.knots = SPLINE_KNOTS
    msp.add_text("PART 1", height=4, dxfattribs={"layer": "NOTES", "insert": (30, 10)})
    return doc


if __name__ == "__main__":
    make(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).with_name("drawing.dxf"))
