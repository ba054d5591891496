#!/usr/bin/env bash
# Runs the libFuzzer targets built by `make fuzz-build` (build/fuzz/bin, ASan + UBSan).
#   tools/fuzz.sh smoke SECONDS   fuzz each target for SECONDS from the committed corpus (read-only);
#                                 new inputs go to a temporary directory that is thrown away.
#   tools/fuzz.sh long SECONDS    the same, then merge the new interesting inputs into the committed
#                                 corpus (fuzz/corpus/<target>) with -merge=1.
# Fails on any crash, leak or sanitizer report and prints how to reproduce it. Prints exec counts.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

usage() { echo "usage: $0 smoke|long SECONDS" >&2; exit 2; }
[ $# -eq 2 ] || usage
mode=$1; seconds=$2
case "$mode" in smoke|long) ;; *) usage ;; esac
[[ "$seconds" =~ ^[0-9]+$ ]] || usage

bindir="$root/build/fuzz/bin"
targets=(fuzz_decode fuzz_behaviour fuzz_signed fuzz_agent fuzz_master fuzz_node fuzz_robot fuzz_console)
export ASAN_OPTIONS="${ASAN_OPTIONS:-abort_on_error=1:detect_leaks=1:symbolize=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-halt_on_error=1:print_stacktrace=1}"

# One target: fuzz, report, keep a finding (and merge new inputs when long). Exit status 1 on a finding.
fuzz_one() {
  local t=$1 bin corpus dict work artifacts log dict_arg rc execs rate cov crashes c keep before
  bin="$bindir/$t"
  corpus="$root/fuzz/corpus/$t"
  dict="$root/fuzz/$t.dict"
  [ -x "$bin" ] || { echo "fuzz: $bin missing: run 'make fuzz-build' first" >&2; exit 1; }
  [ -d "$corpus" ] || { echo "fuzz: corpus $corpus missing" >&2; exit 1; }
  work=$(mktemp -d "${TMPDIR:-/tmp}/ev3fuzz.$t.XXXXXX")
  artifacts="$work/artifacts"; mkdir -p "$artifacts" "$work/new"
  log="$work/fuzz.log"
  dict_arg=(); [ -f "$dict" ] && dict_arg=("-dict=$dict")
  echo "fuzz: $t for ${seconds}s ($mode), seeds from ${corpus#"$root"/}"
  # New inputs land in $work/new (first directory); the committed corpus is only read.
  set +e
  "$bin" "$work/new" "$corpus" "${dict_arg[@]}" -max_total_time="$seconds" -max_len=5000 \
         -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts/" >"$log" 2>&1
  rc=$?
  set -e
  execs=$(awk '/^stat::number_of_executed_units/ {n=$2} END {print n}' "$log")
  rate=$(awk '/^stat::average_exec_per_sec/ {n=$2} END {print n}' "$log")
  cov=$(awk '/DONE/ {for (i = 1; i < NF; i++) if ($i == "cov:") c = "cov: " $(i + 1)} END {print c}' "$log")
  echo "fuzz: $t: ${execs:-?} execs, ${rate:-?} exec/s, ${cov:-cov: ?}, $(ls "$work/new" | wc -l) new inputs"
  crashes=$(find "$artifacts" -type f | sort)
  if [ $rc -ne 0 ] || [ -n "$crashes" ]; then
    status=1
    echo "fuzz: $t FAILED (exit $rc). Last lines of the log ($log):" >&2
    tail -40 "$log" >&2
    for c in $crashes; do
      keep="$root/build/fuzz/findings/$t"; mkdir -p "$keep"; cp "$c" "$keep/"
      echo "fuzz: finding kept as build/fuzz/findings/$t/$(basename "$c")" >&2
      echo "fuzz: reproduce:  $bin build/fuzz/findings/$t/$(basename "$c")" >&2
      echo "fuzz: then add it as a regression seed: cp build/fuzz/findings/$t/$(basename "$c") fuzz/corpus/$t/regression_<what>" >&2
    done
    return 1  # keep $work for inspection
  fi
  if [ "$mode" = long ] && [ -n "$(ls -A "$work/new")" ]; then
    before=$(ls "$corpus" | wc -l)
    "$bin" -merge=1 "$corpus" "$work/new" "${dict_arg[@]}" -max_len=5000 >"$work/merge.log" 2>&1 \
      || { echo "fuzz: merge failed, see $work/merge.log" >&2; return 1; }
    echo "fuzz: $t: merged $(( $(ls "$corpus" | wc -l) - before )) new inputs into ${corpus#"$root"/}"
  fi
  rm -rf "$work"
}

# The targets fuzz at the same time, one process each (the machine's cores are used, the wall time
# is SECONDS, not SECONDS per target).
pids=()
for t in "${targets[@]}"; do
  fuzz_one "$t" &
  pids+=($!)
done
status=0
for p in "${pids[@]}"; do
  wait "$p" || status=1
done
exit $status
