# libev3proto: the front door. Every target installs what is missing first (`make deps`).
#   make test      every test: C++ units, Python, TLA+ small models, fuzz smoke, armel under qemu-arm
#   make build     native build; programs land in build/bin/
#   make fuzz      long libFuzzer run (FUZZ_SECONDS, default 1800)
#   make bench     Google Benchmark figures (see docs/benchmarks.md)
#   make arm       static armel (EV3) build in build/arm/
#   make spec      SANY + TLC on the small models, broken variants refuted, diagram up to date
#   make spec-full the full models (minutes)
#   make diagrams  regenerate docs/lifecycle.svg from TLC's state graph
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help
.PHONY: help deps build test test-unit test-python test-fuzz test-arm fuzz fuzz-build bench arm \
        spec spec-full diagrams clean

PY := $(CURDIR)/.venv/bin/python
BIN := $(CURDIR)/build/bin
JOBS ?= $(shell nproc)
FUZZ_SECONDS ?= 1800
FUZZ_SMOKE_SECONDS ?= 60
CMAKE_NATIVE := cmake -S . -B build/native -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
                -DCMAKE_RUNTIME_OUTPUT_DIRECTORY=$(BIN)

help:
	@sed -n '2,10p' Makefile | sed 's/^# \{0,1\}//'

deps:
	@bash tools/deps.sh

build: deps
	@$(CMAKE_NATIVE) >/dev/null
	@ninja -C build/native

test: build
	@$(MAKE) --no-print-directory test-unit test-python spec test-fuzz test-arm
	@echo "make test: all suites passed"

test-unit: build
	@cd build/native && ctest --output-on-failure -j $(JOBS)

test-python: build
	@EV3_BIN=$(BIN) $(PY) -m pytest -q tests/python

fuzz-build: deps
	@cmake -S . -B build/fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	   -DCMAKE_CXX_COMPILER=clang++-14 -DEV3_FUZZ=ON -DEV3_TESTS=OFF -DEV3_TOOLS=OFF >/dev/null
	@ninja -C build/fuzz

# A short fuzz run with ASan+UBSan over the committed corpus: part of `make test`.
test-fuzz: fuzz-build
	@bash tools/fuzz.sh smoke $(FUZZ_SMOKE_SECONDS)

fuzz: fuzz-build
	@bash tools/fuzz.sh long $(FUZZ_SECONDS)

bench: deps
	@cmake -S . -B build/bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEV3_BENCH=ON -DEV3_TESTS=OFF \
	   -DEV3_TOOLS=OFF >/dev/null
	@ninja -C build/bench
	@build/bench/bin/bench_codec --benchmark_min_time=0.2

arm: deps
	@cmake -S . -B build/arm -G Ninja -DCMAKE_BUILD_TYPE=Release \
	   -DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/cmake/arm-linux-gnueabi.cmake >/dev/null
	@ninja -C build/arm

# The armel unit tests, run under qemu-arm (CMAKE_CROSSCOMPILING_EMULATOR).
test-arm: arm
	@cd build/arm && ctest --output-on-failure -j $(JOBS)

spec: deps
	@python3 tools/spec.py check --size small
	@python3 tools/spec.py refute
	@python3 tools/spec.py diagram --check

spec-full: deps
	@python3 tools/spec.py check --size full

diagrams: deps
	@python3 tools/spec.py diagram

clean:
	rm -rf build
