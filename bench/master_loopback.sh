#!/bin/bash
# One loopback measurement of docs/benchmarks.md, "Master at scale": an ev3-master on 127.0.0.1 and
# ev3-loadgen with N simulated agents (one UDP socket each) against it. Prints the load average
# before and after, ev3-loadgen's summary (JSON: cpu_master is the master's share of a core in the
# measurement window), and the master's CPU seconds over the whole run.
#
#   bench/master_loopback.sh [--master-bin PATH] [--port P] [--db] [--reports MS] AGENTS HEARTBEAT_MS [DURATION_S]
#
# --db: the master keeps its record in SQLite too (--db, with the --state-file it needs; docs/record.md).
# --reports MS: the master's --script sends `behaviour all wait` and `start all` once the agents have
# synced (after 15 s), and each agent then makes a SENSOR_VALUE report every MS ms (ev3-loadgen
# --report-ms); the window begins when all are WORKING.
# --master-bin: the ev3-master to measure (default build/bin/ev3-master; for "before", one built
# from an earlier commit). ev3-loadgen is build/bin/ev3-loadgen. Files go to build/loopback/.
set -euo pipefail
cd "$(dirname "$0")/.."
MASTER=build/bin/ev3-master
PORT=24555
DB=0
REPORTS=0
while [[ $# -gt 0 && $1 == --* ]]; do
  case $1 in
    --master-bin) MASTER=$2; shift 2 ;;
    --port) PORT=$2; shift 2 ;;
    --db) DB=1; shift ;;
    --reports) REPORTS=$2; shift 2 ;;
    *) echo "master_loopback.sh: unknown option $1" >&2; exit 2 ;;
  esac
done
if [[ $# -lt 2 ]]; then
  echo "usage: bench/master_loopback.sh [--master-bin PATH] [--port P] [--db] [--reports MS] AGENTS HEARTBEAT_MS [DURATION_S]" >&2
  exit 2
fi
AGENTS=$1 HB=$2 DURATION=${3:-30}
OUT=build/loopback
mkdir -p "$OUT"
TAG="$AGENTS-$HB-$(date +%s)"
STATUS=$OUT/status-$TAG.json
rm -f "$STATUS"
EXTRA=()
if [[ $DB == 1 ]]; then EXTRA=(--db "$OUT/record-$TAG.db" --state-file "$OUT/state-$TAG"); fi
LOADGEN_EXTRA=()
if [[ $REPORTS != 0 ]]; then
  printf 'wait 15\nbehaviour all wait seconds=100000\nstart all\n' >"$OUT/script-$TAG.txt"
  EXTRA+=(--script "$OUT/script-$TAG.txt")
  LOADGEN_EXTRA=(--report-ms "$REPORTS")
fi
"$MASTER" --port "$PORT" --bind 127.0.0.1 --status-json "$STATUS" "${EXTRA[@]}" >"$OUT/master-$TAG.out" 2>&1 &
MPID=$!
trap 'kill $MPID 2>/dev/null || true; wait $MPID 2>/dev/null || true' EXIT  # the port is free again at exit
sleep 0.5
cpu() { awk '{print ($14 + $15) / 100}' "/proc/$MPID/stat"; }  # utime + stime, in clock ticks of 10 ms
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
build/bin/ev3-loadgen --master "127.0.0.1:$PORT" --agents "$AGENTS" --heartbeat-ms "$HB" --ramp-s 10 \
  --settle-s 30 --duration-s "$DURATION" --master-status "$STATUS" --master-pid "$MPID" --json "${LOADGEN_EXTRA[@]}" \
  2>"$OUT/loadgen-$TAG.log"
echo "master CPU: $(cpu) s over the whole run (ramp, settle, window)"
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
