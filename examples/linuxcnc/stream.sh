#!/bin/sh
# Stream a plan into LinuxCNC's HAL and capture what comes back (docs/linuxcnc.md):
#
#   examples/linuxcnc/stream.sh HALFILE JOB [plan options] > capture.txt
#
# runs `nurbsinterp plan JOB --format hal --columns k,x,y [plan options]` into a temporary file, then
# `halrun -f HALFILE` on it, with the servo thread's period and the capture's length (the plan's
# lines) in the environment HALFILE reads (SERVO_PERIOD, TICKS); HALFILE's halsampler prints the
# capture on stdout.  HALFILE is
# loopback.hal (the commands straight back) or sim-machine.hal (a simulated X-Y machine).
#
# Plan options pass on: --precompensate MODEL.yaml, --resolution R, --hold-start "0.5 s" (the first command
# held before tick 0 while the loops are enabled; its lines count in TICKS, and the capture drops them).
#
# Run it as a normal user: HAL refuses root.  Environment:
#   SERVO_PERIOD  the servo thread's period in ns (default 1000000: 1 ms); the plan gets the same
#   NURBSINTERP   the nurbsinterp command (default: nurbsinterp)
#   HALRUN        the halrun command (default: halrun)
#   SENT          a file to keep the stream sent in (default: none)
set -eu
[ $# -ge 2 ] || { echo "usage: $0 HALFILE JOB [plan options]" >&2; exit 2; }
hal=$1
job=$2
shift 2
: "${SERVO_PERIOD:=1000000}" "${NURBSINTERP:=nurbsinterp}" "${SENT:=/dev/null}"
if [ -z "${HALRUN:-}" ]; then
    [ "$(id -u)" != 0 ] || { echo "$0: HAL refuses to run as root; run this as a normal user" >&2; exit 2; }
    HALRUN=halrun
fi
plan=$(mktemp)
trap 'rm -f "$plan"' EXIT
# planned once, into a file: its lines are the tick count halsampler stops after, and a plan that fails
# (sh has no pipefail) fails here, before HAL starts, with its message on stderr
"$NURBSINTERP" plan "$job" --period "$SERVO_PERIOD ns" --format hal --columns k,x,y -q "$@" > "$plan" \
    || { status=$?; echo "$0: nurbsinterp plan failed (exit $status)" >&2; exit 1; }
TICKS=$(wc -l < "$plan")
[ "$TICKS" -gt 0 ] || { echo "$0: the plan has no ticks" >&2; exit 1; }
export SERVO_PERIOD TICKS
echo "$0: streaming $TICKS ticks of $job through $hal at $SERVO_PERIOD ns ..." >&2
tee "$SENT" < "$plan" | $HALRUN -f "$hal"
