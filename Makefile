# libev3proto: the front door. Every target installs what is missing first (`make deps`).
#   make demo      a master and three agents on this machine: sync, behaviour, master lost, election (~30 s);
#                  SIGNED=1: in signed mode
#   make test      every test: C++ units, Python, black-box UDP, TLA+ small models, fuzz smoke, armel,
#                  the installed library and examples/robot (test-example)
#   make check     the edit loop (under 5 min): build, C++ units and transcripts, the Python tests
#                  without TLC, one small TLA+ model per module
#   make build     native build; programs land in build/bin/ (ev3-agent, ev3-master, ev3-codec, ev3-behaviour)
#   make fuzz      long libFuzzer run (FUZZ_SECONDS per target, default 1800)
#   make faults    the fault scenarios' full set, FAULT_SEEDS seeds of each of its 7 tests (default 15:
#                  105 seeded runs), and their summary
#   make bench     codec benchmark: ratios over BENCH_RUNS (9) runs of bench_codec (docs/benchmarks.md)
#   make bench-master  the master core per datagram at 100 and 10,000 agents, and a baseline's (MASTER_BASELINE)
#   make arm       static armel (EV3) build in build/arm/
#   make spec      SANY + TLC on the small models, broken variants refuted, diagram up to date
#   make spec-full the full models (minutes)
#   make conformance-full  every edge of the agent model replayed against the core (make test samples)
#   make spec-mutate  the spec mutations of spec/tla/mutations.toml, each killed by a make-spec
#                  model (docs/spec.md "Spec mutations"; minutes, not part of make test);
#                  MUTANTS="A0 L" runs a subset (id prefixes)
#   make diagrams  regenerate docs/lifecycle.svg from TLC's state graph, docs/behaviours/*.svg
SHELL := /bin/bash
.SHELLFLAGS := -eu -o pipefail -c
.DEFAULT_GOAL := help
.PHONY: help deps build demo test check faults conformance-agent-fleet conformance-master-system test-unit test-python test-python-quick spec-quick test-blackbox test-fuzz test-arm test-example fuzz fuzz-build \
        bench bench-master arm conformance conformance-full mutate \
        spec spec-full spec-mutate diagrams clean

PY := $(CURDIR)/.venv/bin/python
BIN := $(CURDIR)/build/bin
JOBS ?= $(shell nproc)
FUZZ_SECONDS ?= 1800
FAULT_SEEDS ?= 15
FUZZ_SMOKE_SECONDS ?= 30
BENCH_RUNS ?= 9
# The baseline of make bench-master: a commit whose master core finds its next deadline by walking
# the whole registry after each datagram (docs/benchmarks.md, "Master at scale").
MASTER_BASELINE ?= b1890d2
# -g1: line tables for backtraces and profilers, a third less compile time than -g. Unity builds
# (CMake compiles up to 8 sources of a target as one): the library is header-only, so a batch parses
# its headers once (docs/benchmarks.md "The time of make test").
CMAKE_NATIVE := cmake -S . -B build/native -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
                "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O2 -g1 -DNDEBUG" -DCMAKE_RUNTIME_OUTPUT_DIRECTORY=$(BIN) \
                -DCMAKE_UNITY_BUILD=ON

help:
	@sed -n '2,/^SHELL/{/^#/p}' Makefile | sed 's/^# \{0,1\}//'

deps:
	@bash tools/deps.sh

build: deps
	@$(CMAKE_NATIVE) >/dev/null
	@ninja -C build/native

# The parts of make test, and of make check, in order; tools/suite.py runs them one after another and
# prints each part's time at the end.
# deps and the builds (build: native, arm: static armel) are parts of their own, so that the table
# shows their time too.
TEST_PARTS := deps build test-unit test-python arm test-blackbox spec conformance test-fuzz test-arm test-example
CHECK_PARTS := deps build test-unit test-python-quick spec-quick

test:
	@python3 tools/suite.py "make test" $(TEST_PARTS)

# The edit loop: the native build, the C++ unit tests and transcripts, the Python tests that need no
# model checker, one small TLC model per spec module.
check:
	@python3 tools/suite.py "make check" $(CHECK_PARTS)

# Twice as many ctest jobs as cores: the ev3-sim suites mostly wait on simulated real time.
test-unit: build
	@cd build/native && ctest --output-on-failure -j $$(( $(JOBS) * 2 ))

# Three pytest processes (pytest-xdist, each taking the next test when done) on two cores: most of
# these tests wait on TLC or on ev3-codec's answers, and two leave a core idle a quarter of the time
# (docs/benchmarks.md, "make test").
PYTEST_PAR := -n 3 --dist worksteal
test-python: build
	@EV3_BIN=$(BIN) $(PY) -m pytest -q $(PYTEST_PAR) tests/python --ignore=tests/python/blackbox

# The Python tests that do not run TLC (marker `tlc`, tests/python/pytest.ini).
test-python-quick: build
	@EV3_BIN=$(BIN) $(PY) -m pytest -q $(PYTEST_PAR) tests/python --ignore=tests/python/blackbox -m "not tlc"

# ev3-agent and ev3-master over real UDP on loopback (tests/python/blackbox), including the static
# armel ev3-agent under qemu-arm against the native ev3-master (test_example.py is test-example's).
test-blackbox: build arm
	@EV3_BIN=$(BIN) EV3_ARM_BIN=$(CURDIR)/build/arm/bin $(PY) -m pytest -q tests/python/blackbox \
	   --ignore=tests/python/blackbox/test_example.py

# The library as a firmware project out of this tree gets it (docs/embedding.md): `cmake --install`
# into build/install (headers and package files: nothing is compiled), the installed headers checked
# against libev3proto/include, then against that prefix alone, natively and static for armel with
# the installed toolchain file: tests/package (find_package(ev3proto), ev3proto::ev3proto, one
# header; run, the armel one under qemu-arm), the same header through pkg-config, and
# examples/robot (minirobot), run against ev3-master (tests/python/blackbox/test_example.py: sync,
# wait, the master killed, PAUSED, PANIC, elected; the armel build syncs and runs wait under qemu-arm).
PREFIX_TEST := $(CURDIR)/build/install
test-example: build
	@rm -rf $(PREFIX_TEST)
	@cmake --install build/native --prefix $(PREFIX_TEST) >/dev/null
	@diff <(cd libev3proto/include && find . -name '*.hpp' | sort) \
	      <(cd $(PREFIX_TEST)/include && find . -name '*.hpp' ! -name builtins_text.hpp | sort)
	@test -f $(PREFIX_TEST)/include/ev3proto/behaviour/builtins_text.hpp
	@tools/example_builds.sh $(PREFIX_TEST)
	@build/package/package_check && qemu-arm build/package-arm/package_check
	@g++ -std=c++17 $$(PKG_CONFIG_PATH=$(PREFIX_TEST)/share/pkgconfig pkg-config --cflags ev3proto) \
	   tests/package/main.cpp -o build/package/pkgconfig_check && build/package/pkgconfig_check
	@EV3_BIN=$(BIN) EV3_EXAMPLE=$(CURDIR)/build/example/minirobot EV3_EXAMPLE_ARM=$(CURDIR)/build/example-arm/minirobot \
	   $(PY) -m pytest -q tests/python/blackbox/test_example.py
	@echo "test-example: installed package, out-of-tree projects (native, armel, pkg-config) and minirobot passed"

# A master and three agents on loopback, narrated (tools/demo.py): sync (the PC publishes its
# membership in epochs 2-4), a behaviour, the master killed, an election (epoch 5) with a relay, the
# new master's commands, the PC taking over again (epoch 6). The fleet's part takes about 30 s; then
# it validates the three agents' traces with TLC
# (AgentLogic composed with Election.tla's per-agent rules), the master's, and the whole run (every
# trace merged by send/receive: ev3-conformance merged) and fails if one does not conform.
# SIGNED=1: every node in signed mode with a fresh key (docs/protocol.md "Signed datagrams").
demo: build
	@$(PY) tools/demo.py --bin $(BIN) $(if $(filter 1,$(SIGNED)),--signed)

# Spec -> implementation: MCAgent's state graph replayed against `ev3-agent --driver` (every edge,
# except that of the edges where the agent ignores a datagram or answers a duplicate, 78 % of them,
# one of each class and one in 8 of the rest: --sample 8; conformance-full replays them all),
# every edge of MCMaster's against `ev3-master --driver`, every edge of MCReportsReplay's (Reports.tla)
# against `ev3-reports-driver` (the library's report buffer, records and record file; two graphs,
# ~1.5 min), and
# 40 seeded TLC -simulate traces of the
# fleet (MCFleetSim: 3 agents, losses, duplicates, crashes) against one master and three agent
# drivers talking to each other, then 40 of the whole system (MCSystemSim: the PC lost and back,
# relay, pre-vote, elections, HANDOVER; --election-num, --election-depth) against the PC's, the
# agents' and the elected agents' Master cores' drivers (docs/driver.md, docs/spec.md
# "Conformance"; the fleet ~25-60 s, the election ~25-30 s more).
# Two halves at once, each keeping about one core busy: the agent's replay, the reports' and then
# the fleet's; the master's replay and then the system's.
AGENT_SAMPLE := 8
conformance: build
	@python3 tools/suite.py --together "make conformance" conformance-agent-fleet conformance-master-system

# (its two halves, of about equal time, run by conformance after the build)
conformance-agent-fleet:
	@EV3_BIN=$(BIN) $(CURDIR)/.venv/bin/ev3-conformance replay --model agent --sample $(AGENT_SAMPLE)
	@EV3_BIN=$(BIN) $(CURDIR)/.venv/bin/ev3-conformance replay --model reports
	@EV3_BIN=$(BIN) $(CURDIR)/.venv/bin/ev3-conformance replay --model fleet --seed 1 --num 40 --depth 300 \
		--election-num 0

conformance-master-system:
	@EV3_BIN=$(BIN) $(CURDIR)/.venv/bin/ev3-conformance replay --model master
	@EV3_BIN=$(BIN) $(CURDIR)/.venv/bin/ev3-conformance replay --model fleet --seed 1 --num 0 \
		--election-num 40 --election-depth 150

# The same with every edge of MCAgent's graph replayed (not part of make test; ~3 min more).
conformance-full:
	@$(MAKE) --no-print-directory conformance AGENT_SAMPLE=1

# Mutation score of the conformance checks (not part of make test; ~20-40 min on 2 loaded cores):
# seeded faults in a copy of the core, each rebuilt in build/mutate and checked (docs/spec.md
# "Conformance"). Fails below 95 %. MUTANTS="A01 M" runs a subset (name prefixes).
mutate: build
	@EV3_BIN=$(BIN) PYTHONUNBUFFERED=1 $(CURDIR)/.venv/bin/ev3-conformance mutate $(if $(MUTANTS),--only $(MUTANTS))

fuzz-build: deps
	@cmake -S . -B build/fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
	   -DCMAKE_CXX_COMPILER=clang++-14 -DEV3_FUZZ=ON -DEV3_TESTS=OFF -DEV3_TOOLS=OFF >/dev/null
	@ninja -C build/fuzz

# A short fuzz run with ASan+UBSan over the committed corpus: part of `make test`. FUZZ_SMOKE_SECONDS
# is per target; fuzz_decode and fuzz_behaviour fuzz at the same time, one core each (30 s of wall
# time, 60 s of fuzzing in all).
test-fuzz: fuzz-build
	@bash tools/fuzz.sh smoke $(FUZZ_SMOKE_SECONDS)

fuzz: fuzz-build
	@bash tools/fuzz.sh long $(FUZZ_SECONDS)

# The seeded fault scenarios (tests/python/blackbox/test_fault_scenarios.py; make test runs one seed
# of each), FAULT_SEEDS seeds each: every run's figures in build/faults/results.jsonl, then the
# summary table of docs/faults.md. Fails when a run failed a check.
faults: build
	@mkdir -p build/faults && rm -f build/faults/results.jsonl
	@set -o pipefail; rc=0; EV3_BIN=$(BIN) EV3_FAULT_SEEDS=$(FAULT_SEEDS) \
	   EV3_FAULT_RESULTS=$(CURDIR)/build/faults/results.jsonl $(PY) -m pytest -q -rfE \
	   tests/python/blackbox/test_fault_scenarios.py 2>&1 | tee build/faults/pytest.log || rc=$$?; \
	 $(PY) tools/faults_summary.py build/faults/results.jsonl --pytest-log build/faults/pytest.log; exit $$rc

bench: deps
	@cmake -S . -B build/bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEV3_BENCH=ON -DEV3_TESTS=OFF \
	   -DEV3_TOOLS=OFF >/dev/null
	@ninja -C build/bench
	@python3 bench/ratios.py --runs $(BENCH_RUNS)

# The master core's CPU per datagram with 100 and with 10,000 agents (bench/bench_master.cpp), and
# the same benchmark built against MASTER_BASELINE's headers (docs/benchmarks.md, "Master at scale").
bench-master: deps
	@cmake -S . -B build/bench -G Ninja -DCMAKE_BUILD_TYPE=Release -DEV3_BENCH=ON -DEV3_TESTS=OFF \
	   -DEV3_TOOLS=OFF -DEV3_MASTER_BASELINE=$(MASTER_BASELINE) >/dev/null
	@ninja -C build/bench bench_master bench_master_baseline
	@python3 bench/master_scale.py --bin build/bench/bin

# -O2, not Release's -O3: on the EV3's ARM926 (16 KB instruction cache) the smaller code is the
# better trade, and it keeps the static ev3-agent under its 1.5 MB limit (docs/benchmarks.md).
arm: deps
	@cmake -S . -B build/arm -G Ninja -DCMAKE_BUILD_TYPE=Release "-DCMAKE_CXX_FLAGS_RELEASE=-O2 -DNDEBUG" \
	   "-DCMAKE_C_FLAGS_RELEASE=-O2 -DNDEBUG" -DCMAKE_TOOLCHAIN_FILE=$(CURDIR)/cmake/arm-linux-gnueabi.cmake \
	   -DCMAKE_UNITY_BUILD=ON >/dev/null
	@ninja -C build/arm

# The armel unit tests, run under qemu-arm (CMAKE_CROSSCOMPILING_EMULATOR).
test-arm: arm
	@cd build/arm && ctest --output-on-failure -j $(JOBS)

spec: deps
	@python3 tools/spec.py check --size small
	@python3 tools/spec.py refute
	@python3 tools/spec.py diagram --check
	@python3 tools/spec.py distributed reports_three

# One small model per spec module (manifest.json "quick"): make check's share of make spec.
spec-quick: deps
	@python3 tools/spec.py check --size quick

spec-full: deps
	@python3 tools/spec.py check --size full

spec-mutate: deps
	@PYTHONUNBUFFERED=1 python3 tools/spec.py mutate $(if $(MUTANTS),--only $(MUTANTS))

diagrams: build
	@python3 tools/spec.py diagram
	@bash tools/behaviour/diagrams.sh

clean:
	rm -rf build

# Line coverage of the library headers (libev3proto/include) by the native tests; fails below 95%.
.PHONY: coverage
COVERAGE_MIN ?= 95
coverage: deps
	@cmake -S . -B build/coverage -G Ninja -DCMAKE_BUILD_TYPE=Debug -DEV3_COVERAGE=ON -DEV3_TOOLS=OFF >/dev/null
	@ninja -C build/coverage
	@find build/coverage -name '*.gcda' -delete
	@cd build/coverage && ctest --output-on-failure -j $(JOBS) >/dev/null
	@lcov --quiet --capture --directory build/coverage --output-file build/coverage/all.info \
	   --ignore-errors mismatch >/dev/null 2>&1 || lcov --quiet --capture --directory build/coverage \
	   --output-file build/coverage/all.info >/dev/null
	@lcov --quiet --extract build/coverage/all.info '$(CURDIR)/libev3proto/include/*' \
	   --output-file build/coverage/lib.info >/dev/null
	@lcov --list build/coverage/lib.info
	@pct=$$(lcov --summary build/coverage/lib.info 2>&1 | sed -n 's/.*lines\.*: *\([0-9.]*\)%.*/\1/p'); \
	  echo "line coverage of libev3proto/include: $$pct% (minimum $(COVERAGE_MIN)%)"; \
	  awk -v p="$$pct" -v m="$(COVERAGE_MIN)" 'BEGIN { exit !(p >= m) }'
