#!/usr/bin/env bash
# make test-example's builds: tests/package and examples/robot, each configured and built against the
# installed prefix (afresh) natively and for armel (the installed toolchain file), the four at the same time
# (each is one or two sources: one configure and compile per core is what keeps both busy). A build
# that fails prints its own log and the script exits 1 after the others end.
# Usage: tools/example_builds.sh PREFIX
set -u
prefix=${1:?usage: tools/example_builds.sh PREFIX}
toolchain=$prefix/share/cmake/ev3proto/arm-linux-gnueabi.cmake
mkdir -p build

one() {  # source dir, build dir, extra cmake arguments...
  local src=$1 dir=$2
  shift 2
  rm -rf "$dir"   # configured afresh: a cached ev3proto_DIR would hide a package that is not found
  { cmake -S "$src" -B "$dir" -G Ninja -DCMAKE_PREFIX_PATH="$prefix" "$@" && ninja -C "$dir"; } \
    >"$dir.log" 2>&1
}

pids=() names=()
for t in tests/package:build/package examples/robot:build/example; do
  src=${t%%:*} dir=${t#*:}
  one "$src" "$dir" & pids+=($!) names+=("$dir")
  one "$src" "$dir-arm" -DCMAKE_TOOLCHAIN_FILE="$toolchain" & pids+=($!) names+=("$dir-arm")
done
failed=0
for i in "${!pids[@]}"; do
  if ! wait "${pids[$i]}"; then
    echo "example_builds: ${names[$i]} failed (its log, ${names[$i]}.log):" >&2
    cat "${names[$i]}.log" >&2
    failed=1
  fi
done
exit $failed
