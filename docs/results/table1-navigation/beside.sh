#!/usr/bin/env bash
# Run one job of queue.sh beside another study's queue (issue 65's football) on the idle CPU only: in its own session
# (setsid), whose autogroup gets nice 19. Plain `nice` does not do it: the kernel's autogroup shares the CPU between
# sessions first and applies nice only inside one (measured 2026-12-07: football fell from ~490 to 67 agent-steps/s
# beside a `nice 19` lane, and kept ~450 beside a lane whose session had autogroup nice 19; scheduling.log).
#
#   bash docs/results/table1-navigation/beside.sh saeir-n4-s1     # appends to $OUT/lane-beside.log
#
# Stop it as the lanes: SIGTERM to the queue script, then to the benchmark driver (it stops at its checkpoint).
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
OUT="$HOME/saeir-results/table1-navigation"
[ $# -eq 1 ] || { echo "usage: bash docs/results/table1-navigation/beside.sh JOB (a job of queue.sh)" >&2; exit 2; }
setsid nohup bash "$HERE/queue.sh" "$1" >> "$OUT/lane-beside.log" 2>&1 < /dev/null &
pid=$!
sleep 1
echo 19 > "/proc/$pid/autogroup"
echo "$(date -u +%FT%TZ) $1 started beside the football queue (own session, autogroup nice 19: $(cat "/proc/$pid/autogroup"))" \
    | tee -a "$OUT/scheduling.log"
