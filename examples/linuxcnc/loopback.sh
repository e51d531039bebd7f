#!/bin/sh
# A plan through LinuxCNC's HAL and back (docs/linuxcnc.md):
#
#   nurbsinterp plan JOB --format hal | halstreamer -> streamer -> sampler -> halsampler
#
# in a servo thread of the plan's period (stream.sh with loopback.hal), then a check that every
# tick came back in order, unchanged to the 6 decimals halsampler prints, and that the streamer
# never ran dry once the stream had started.
#
#   examples/linuxcnc/loopback.sh curves/circle.yaml [plan options, e.g. --resolution 1um]
#
# Run it as a normal user: HAL refuses root.  Environment: as stream.sh, and
#   KEEP  a directory to keep the stream sent (sent.txt) and the capture (capture.txt) in
set -eu
[ $# -ge 1 ] || { echo "usage: $0 JOB [plan options]" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
work=${KEEP:-$(mktemp -d)}
[ -n "${KEEP:-}" ] || trap 'rm -rf "$work"' EXIT
SENT="$work/sent.txt" sh "$here/stream.sh" "$here/loopback.hal" "$@" > "$work/capture.txt"
ticks=$(wc -l < "$work/sent.txt")

# sent: k x y; captured: k x y underruns.  %f prints 6 decimals: a value comes back within 5e-7.
paste -d ' ' "$work/sent.txt" "$work/capture.txt" | awk -v ticks="$ticks" '
    function abs(v) { return v < 0 ? -v : v }
    NF != 7 { print "line " NR ": a tick is missing from the capture"; bad = 1; exit 1 }
    $1 != NR - 1 || $4 != $1 { print "line " NR ": tick " $4 " came back where tick " $1 " was sent"; bad = 1; exit 1 }
    { d = abs($2 - $5); if (abs($3 - $6) > d) d = abs($3 - $6); if (d > worst) worst = d }
    d > 5.000001e-7 { print "tick " $1 ": sent " $2 " " $3 ", came back " $5 " " $6; bad = 1; exit 1 }
    NR == 1 { runs = $7 }
    $7 != runs { print "tick " $1 ": the streamer ran dry " $7 - runs " time(s) during the stream"; bad = 1; exit 1 }
    END { if (bad) exit 1
          if (NR != ticks || NR == 0) { print NR " of " ticks " ticks came back"; exit 1 }
          printf "%d ticks came back in order, each within %.1e mm of the command sent, no underrun\n", NR, worst }
' >&2
