"""Write curves/excitation.yaml: a job whose motion excites a servo loop well enough to identify it.

`nurbsinterp identify` (docs/identify.md) fits each axis' closed loop to what the
machine did.  A circle alone moves both axes at one frequency and one speed, which leaves a
plant's poles poorly determined (±1–3 % on the paper's table).  This job gives the fit what it needs,
within an acceleration budget the machine can take:

- **legs** along x, y and the diagonal at three feeds, each a stop to a stop (the paper's profiles
  stop where the feed changes): velocity steps, and long stretches at constant feed whose following
  error fixes the loop's gain at low frequency;
- **runs of full circles** at FREQUENCIES (Hz), each about RUN_TIME s: both axes driven by a sine and
  a cosine at that frequency, from well below to near the bandwidth of a stiff loop.  The radius of
  a run at f is r = (A/2) / (2 pi f)^2, so that its centripetal acceleration is half the budget A
  (the ramps into and out of the run take the other half); its feed is 2 pi f r.

It starts at [0, 0] (a streamer's pins and a simulated machine's drives hold 0 before the stream,
so the loops start at rest on the first command) and ends there.

    .venv/bin/python curves/make_excitation.py [--max-accel A] [--max-feed F] [OUT.yaml]

Defaults: A = 4000 mm/s^2, F = 100 mm/s.  The output is deterministic.
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

FREQUENCIES = (5.0, 10.0, 20.0, 40.0, 70.0)  # Hz
RUN_TIME = 0.3  # s of each run of circles
LEG_FEEDS = (0.2, 0.5, 1.0)  # of --max-feed
LEG_DIRECTIONS = ((1.0, 0.0), (0.0, 1.0), (math.sqrt(0.5), math.sqrt(0.5)))


def blocks(max_accel: float, max_feed: float) -> tuple[list, float]:
    """The path's blocks (YAML mappings) and the job's accel_time (s)."""
    accel_time = max_feed / (max_accel / 2)  # the fastest leg ramps at half the budget
    out = []
    for direction in LEG_DIRECTIONS:
        for share in LEG_FEEDS:
            feed = share * max_feed
            # a leg long enough to cruise for about as long as it ramps: ramps of accel_time at every feed
            length = feed * 2 * accel_time
            there = [round(length * c, 6) for c in direction]
            out.append({"line": {"to": there, "feedrate": _feed(feed)}})
            out.append({"line": {"to": [0.0, 0.0], "feedrate": _feed(feed)}})
    for f in FREQUENCIES:
        omega = 2 * math.pi * f
        r = (max_accel / 2) / omega ** 2
        feed = omega * r
        if feed > max_feed:  # a slow run's feed caps its radius instead
            feed, r = max_feed, max_feed / omega
        turns = max(2, round(RUN_TIME * f))
        centre = [round(r, 9), 0.0]
        # the first half-turn of a run starts along +y: the stop at the origin lets it turn there
        for _ in range(turns):
            out.append({"arc": {"to": [0.0, 0.0], "center": centre, "feedrate": _feed(feed)}})
    return out, accel_time


def _feed(value: float) -> str:
    return f"{value:.6g} mm/s"


def write(out: Path, max_accel: float, max_feed: float) -> None:
    body, accel_time = blocks(max_accel, max_feed)
    lines = [
        "# Written by curves/make_excitation.py (--max-accel %g --max-feed %g): do not edit by hand." % (max_accel,
                                                                                                      max_feed),
        "# A job to identify a servo loop from (docs/identify.md): legs along x, y and the",
        "# diagonal at three feeds, then runs of full circles at %s Hz, each circle's"
        % ", ".join(f"{f:g}" for f in FREQUENCIES),
        "# centripetal acceleration half the budget of %g mm/s^2.  Stream it through the machine, capture," % max_accel,
        "# and fit: nurbsinterp identify capture.txt --job curves/excitation.yaml --pid ... -o fitted.yaml",
        "path:",
        "  start: [0, 0]",
        "  blocks:",
    ]
    for block in body:
        (kind, fields), = block.items()
        items = ", ".join(f"{k}: {_yaml(v)}" for k, v in fields.items())
        lines.append(f"    - {kind}: {{{items}}}")
    lines += [
        "profile:",
        "  type: trapezoidal",
        f"  feedrate: {max_feed:g} mm/s",
        f"  accel_time: {accel_time:.6g} s",
        "interpolator:",
        "  method: taylor2",
        "  period: 1 ms",
        "",
    ]
    out.write_text("\n".join(lines))


def _yaml(value) -> str:
    if isinstance(value, list):
        return "[" + ", ".join(f"{v:.9g}" for v in value) + "]"
    return str(value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", default=str(Path(__file__).with_name("excitation.yaml")))
    parser.add_argument("--max-accel", type=float, default=4000.0, help="mm/s^2 (default 4000)")
    parser.add_argument("--max-feed", type=float, default=100.0, help="mm/s (default 100)")
    args = parser.parse_args()
    write(Path(args.out), args.max_accel, args.max_feed)


if __name__ == "__main__":
    main()
