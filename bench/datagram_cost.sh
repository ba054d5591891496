#!/usr/bin/env bash
# Instructions per datagram on the robot (docs/benchmarks.md, "Per datagram on the robot"): builds
# bench/datagram_cost (build/bench, -O2) and runs it under callgrind, counting only inside its
# measured() (the node's work: the harness's formatting and checks left out), N rounds; prints the
# instructions per round.
#   bench/datagram_cost.sh [N]      (default N = 1000)
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-1000}
[[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [N]  (N rounds, a positive number)" >&2; exit 2; }
command -v valgrind >/dev/null || { echo "datagram_cost: valgrind is missing (make deps installs it)" >&2; exit 1; }
cmake -S . -B build/bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEV3_BENCH=ON -DEV3_TESTS=OFF -DEV3_TOOLS=OFF >/dev/null
ninja -C build/bench datagram_cost >/dev/null
bin=build/bench/bin/datagram_cost
out=$(mktemp -d "${TMPDIR:-/tmp}/datagram_cost.XXXXXX")
trap 'rm -rf "$out"' EXIT
instructions() {  # mode rounds -> instructions (Ir) counted inside measured()
  valgrind --tool=callgrind --toggle-collect='*measured*' --callgrind-out-file="$out/cg.$1.$2" \
    "$bin" "$1" "$2" 2>"$out/log.$1.$2" ||
    { echo "datagram_cost: '$bin $1 $2' failed:" >&2; cat "$out/log.$1.$2" >&2; exit 1; }
  awk '/^summary:/ {print $2}' "$out/cg.$1.$2"
}
echo "| round | instructions per round (callgrind, -O2, x86-64) |"
echo "|---|---:|"
for mode in heartbeat master; do
  a=$(instructions "$mode" "$n")
  what=$([ "$mode" = heartbeat ] && echo "an agent node's heartbeat: PING sent, PONG received" ||
         echo "an elected node: a PING received, the PONG sent")
  echo "| $what | $(( a / n )) |"
done
