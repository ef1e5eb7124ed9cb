# Two commands set up a fresh Debian machine and do the work:
#   make run    the main job (installs what is missing first)
#   make test   every test: ctest (GoogleTest) and pytest, with the
#               Cortex-M7 firmware built and its self-test run under QEMU,
#               clang-tidy and cppcheck; with CI=true also sanitized and
#               with line and branch coverage against its floors
# and one builds the flight processor image (docs/FIRMWARE.md):
#   make firmware   cross toolchain installed if missing, image, size and stack report
# and, outside CI (tens of minutes of compiling), the flight core's
# GoogleTest suite built for aarch64 Linux and run under qemu-aarch64:
#   make test-aarch64
# Both are idempotent: stamps under build/ skip the set-up when nothing changed.

SHELL      := /bin/bash
PYTHON     ?= python3
VENV       := .venv
VPY        := $(VENV)/bin/python
STAMPS     := build/.stamps
CPP_BUILD  := build/cpp
APT_PKGS   := libeigen3-dev libgtest-dev libbenchmark-dev libopencv-dev clang libclang-rt-14-dev clang-format
SUDO       := $(shell [ "$$(id -u)" = 0 ] || echo sudo)
CMAKE_SRC  := CMakeLists.txt $(wildcard fsw/CMakeLists.txt bindings/CMakeLists.txt cmake/*.cmake cmake/*.in)
NATIVE_SRC := $(shell find fsw bindings -type f \( -name '*.hpp' -o -name '*.cpp' \) 2>/dev/null) $(CMAKE_SRC) pyproject.toml
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1
export MPLBACKEND ?= Agg

FW_BUILD   := build/firmware
FW_ELF     := $(FW_BUILD)/firmware/proxops_fw.elf
FW_APT_PKGS := gcc-arm-none-eabi libstdc++-arm-none-eabi-newlib qemu-system-arm
FW_SRC     := $(shell find fsw/include fsw/src firmware cmake -type f 2>/dev/null) CMakeLists.txt CMakePresets.json
# The harness's indirect calls (output sink, instruction counter), for the stack report.
FW_INDIRECT := --indirect "(anonymous namespace)::SemihostingOutput::write" --indirect "(anonymous namespace)::instructions"

AARCH64_BUILD := build/aarch64
AARCH64_APT_PKGS := g++-aarch64-linux-gnu qemu-user

# Assurance (docs/ASSURANCE.md): with TEST_SANITIZE=address,undefined the
# ctest suite is built with AddressSanitizer + UndefinedBehaviorSanitizer
# (its checked core and test programs) and test-asan runs the link tests
# against the sanitized fsw_node_checked; clang-tidy and cppcheck on fsw/;
# line and branch coverage (make coverage).
ASSURANCE_APT_PKGS := clang-tidy cppcheck ccache
# CI (CI=true) runs the ctest suite and the link tests sanitized: 424 tests
# in about 4 min instead of 1 (docs/ASSURANCE.md); elsewhere off unless set.
COMMA := ,
TEST_SANITIZE ?= $(if $(CI),address$(COMMA)undefined)
TIDY_BUILD := build/tidy
# The coverage tree is built at a fixed path outside the checkout, from its
# sources reached through a fixed symbolic link to the checkout: gcc writes
# each object's absolute counter path into it, so only a tree at one path
# lets ccache hand another clone (CI's) the objects of the last run
# (docs/ASSURANCE.md, "Coverage"). One run at a time (a lock).
COV_ROOT   ?= $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/proxops/coverage
COV_SRC    := $(COV_ROOT)/src
COV_BUILD  := $(COV_ROOT)/build
# CI (CI=true) ends `make test` with the coverage target, which fails under
# the core's floors; TEST_COVERAGE=1 does the same elsewhere.
TEST_COVERAGE ?= $(CI)
# The two soak tests (a simulated day of the navigation filter, ten million
# BLR add/remove pairs) took over half of the suite's time at -O0 and
# reach no line or branch the rest does not (checked 2026-11-27): the
# coverage run leaves them out (the main suite runs them).
COV_CTEST_EXCLUDE := CovarianceStaysPositiveDefiniteOver24Hours|ExactAfterTenMillionAddRemovePairs
# ccache, when installed (paths relative to here, so another clone of the
# repository shares the cache).
CCACHE     := $(shell command -v ccache 2>/dev/null)
CCACHE_LAUNCHER := $(if $(CCACHE),-DCMAKE_CXX_COMPILER_LAUNCHER=$(CCACHE))
export CCACHE_BASEDIR := $(CURDIR)
# Every sanitizer report fatal and written to a file, which the run then
# looks for (fsw_node's standard error is the bench's to read).
SAN_REPORTS := $(abspath $(CPP_BUILD))/sanitizer-reports
SAN_ENV := ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:strict_string_checks=1:log_path=$(SAN_REPORTS)/asan \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1:log_path=$(SAN_REPORTS)/ubsan
SAN_CHECK := if [ -n "$$(ls -A $(SAN_REPORTS) 2>/dev/null)" ]; then echo "sanitizer reports:"; cat $(SAN_REPORTS)/*; exit 1; fi
# The Python tests that run fsw_node over the link, run again against the
# sanitized fsw_node_checked (and, for coverage, against build/cov's fsw_node).
LINK_PY_TESTS := tests/py/test_fsw_node_link.py tests/py/test_fsw_node_args.py tests/py/test_hil_loop.py \
  tests/py/test_hil_modal.py tests/py/test_hil_device.py

.PHONY: run test test-cpp test-py setup bench bench-modal clean firmware firmware-selftest test-aarch64 \
  test-asan check-static check-cppcheck coverage coverage-locked

run: $(STAMPS)/install
	$(VENV)/bin/proxops run --report report

test: test-cpp test-py test-asan check-static $(if $(TEST_COVERAGE),coverage)

setup: $(STAMPS)/install $(STAMPS)/cpp-configure

$(STAMPS)/apt:
	@mkdir -p $(STAMPS)
	@dpkg -s $(APT_PKGS) >/dev/null 2>&1 || { \
	  echo "installing Debian packages: $(APT_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(APT_PKGS); }
	@touch $@

# The firmware's cross toolchain and emulator (make firmware, make test).
$(STAMPS)/apt-firmware:
	@mkdir -p $(STAMPS)
	@dpkg -s $(FW_APT_PKGS) >/dev/null 2>&1 || { \
	  echo "installing Debian packages: $(FW_APT_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(FW_APT_PKGS); }
	@touch $@

$(STAMPS)/apt-aarch64:
	@mkdir -p $(STAMPS)
	@dpkg -s $(AARCH64_APT_PKGS) >/dev/null 2>&1 || { \
	  echo "installing Debian packages: $(AARCH64_APT_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(AARCH64_APT_PKGS); }
	@touch $@

$(STAMPS)/apt-assurance:
	@mkdir -p $(STAMPS)
	@dpkg -s $(ASSURANCE_APT_PKGS) >/dev/null 2>&1 || { \
	  echo "installing Debian packages: $(ASSURANCE_APT_PKGS)"; \
	  $(SUDO) apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive $(SUDO) apt-get install -y -qq --no-install-recommends $(ASSURANCE_APT_PKGS); }
	@touch $@

$(STAMPS)/venv: $(STAMPS)/apt
	@test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install -q --disable-pip-version-check "scikit-build-core>=0.10" "pybind11>=2.12" cmake ninja setuptools wheel
	@touch $@

# Editable install: Python sources are used in place (with the dev tools and
# the optional Basilisk engine, whose cross-check runs with the tests); the native module is
# rebuilt incrementally (build/<wheel tag>) when a native source changes. It
# links the flight libraries built in $(CPP_BUILD) rather than compiling the
# flight templates a second time.
$(STAMPS)/install: $(STAMPS)/venv $(STAMPS)/cpp-configure $(NATIVE_SRC)
	$(VENV)/bin/cmake --build $(CPP_BUILD) --target fsw_libraries
	$(VPY) -m pip install -q --disable-pip-version-check --no-build-isolation \
	  -C cmake.define.PROXOPS_PREBUILT_FSW=$(abspath $(CPP_BUILD)) -e ".[dev,basilisk]"
	@touch $@

# CI (CI=true) builds what the tests need; the Google Benchmark targets
# (several minutes of compiling on 2 cores) are built by `make bench`.
BENCHMARKS ?= $(if $(CI),OFF,ON)

# CI compiles the flight core once, with assertions on, and every test and
# the bindings link it; elsewhere the core is a release build and the C++
# tests link a second, checked copy (docs/ARCHITECTURE.md).
CORE_ASSERTS ?= $(if $(CI),ON,OFF)

# Warnings are errors here (PROXOPS_WERROR), as in CI.
$(STAMPS)/cpp-configure: $(STAMPS)/venv $(STAMPS)/apt-assurance $(CMAKE_SRC) Makefile
	$(VENV)/bin/cmake -S . -B $(CPP_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DPROXOPS_BUILD_TESTS=ON -DPROXOPS_BUILD_BENCHMARKS=$(BENCHMARKS) -DPROXOPS_BUILD_PYTHON=OFF \
	  -DPROXOPS_WERROR=ON -DPROXOPS_CORE_ASSERTS=$(CORE_ASSERTS) -DPROXOPS_TEST_SANITIZE=$(TEST_SANITIZE) \
	  $(CCACHE_LAUNCHER) >/dev/null
	@touch $@

test-cpp: $(STAMPS)/cpp-configure
	$(VENV)/bin/cmake --build $(CPP_BUILD)
	@rm -rf $(SAN_REPORTS) && mkdir -p $(SAN_REPORTS)
	cd $(CPP_BUILD) && $(SAN_ENV) $(abspath $(VENV))/bin/ctest --output-on-failure -j2 || { $(SAN_CHECK); exit 1; }
	@$(SAN_CHECK)

# pytest on this many processes (pytest-xdist); each test is independent.
PYTEST_WORKERS ?= 2

test-py: $(STAMPS)/install $(STAMPS)/cpp-configure $(FW_ELF)
	$(VENV)/bin/cmake --build $(CPP_BUILD)
	PROXOPS_CPP_BUILD=$(abspath $(CPP_BUILD)) PROXOPS_FIRMWARE_BUILD=$(abspath $(FW_BUILD)) $(VPY) -m pytest -q -n $(PYTEST_WORKERS)

# The link tests against the sanitized flight executable (built by test-cpp).
test-asan: test-cpp $(STAMPS)/install
	@if [ -n "$(TEST_SANITIZE)" ]; then \
	  mkdir -p $(SAN_REPORTS) && \
	  $(SAN_ENV) PROXOPS_FSW_NODE=$(abspath $(CPP_BUILD))/fsw_node_checked \
	    $(VPY) -m pytest -q -n $(PYTEST_WORKERS) $(LINK_PY_TESTS) && { $(SAN_CHECK); } && \
	  echo "test-asan: no sanitizer report"; \
	else echo "test-asan: TEST_SANITIZE is empty, nothing to run"; fi

# cppcheck alone (seconds; in make test until clang-tidy's first full run
# is clean, docs/ASSURANCE.md).
check-cppcheck: $(STAMPS)/apt-assurance $(STAMPS)/venv
	$(VPY) tests/static/check_static.py --build $(TIDY_BUILD) --tool cppcheck

# clang-tidy (fsw/.clang-tidy) and cppcheck (tests/static/) on fsw/: any
# finding not suppressed in place fails. clang-tidy reads the compile
# commands of a configure-only tree.
check-static: $(STAMPS)/apt $(STAMPS)/apt-assurance $(STAMPS)/venv
	$(VENV)/bin/cmake -S . -B $(TIDY_BUILD) -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) \
	  -DCMAKE_EXPORT_COMPILE_COMMANDS=ON -DPROXOPS_BUILD_TESTS=OFF -DPROXOPS_BUILD_PYTHON=OFF -DPROXOPS_INSTALL=OFF >/dev/null
	$(VPY) tests/static/check_static.py --build $(TIDY_BUILD) --jobs 2

# Line and branch coverage of fsw/ (CMakePresets.json "coverage", -O0 with
# gcov counters): the ctest suite (without the soaks), then the link tests
# against its fsw_node; gcovr reports the core, vision and platform apart
# and fails when the core is under its floors or an exclusion is stale
# (tests/static/coverage.py, tests/static/coverage_exclusions.txt).
$(STAMPS)/gcovr: $(STAMPS)/venv
	$(VPY) -m pip install -q --disable-pip-version-check "gcovr>=7"
	@touch $@

coverage: $(STAMPS)/apt $(STAMPS)/apt-assurance $(STAMPS)/install $(STAMPS)/gcovr
	@mkdir -p $(COV_ROOT)
	flock $(COV_ROOT)/.lock $(MAKE) --no-print-directory coverage-locked

# Configured every run (seconds when the tree exists): the tree is shared by
# every checkout on the machine, the link points at this one. Its objects
# are deleted first: one built from another checkout's headers can look
# newer than this checkout's, so Ninja's times cannot be trusted here;
# ccache (which hashes the contents) gives back each object that did not
# change, in well under a minute for the whole tree. The counters go too:
# the build runs each test program to list its tests, and a counter file
# left by another build of an object would be refused with a warning.
coverage-locked:
	@mkdir -p $(COV_ROOT)
	ln -sfn $(CURDIR) $(COV_SRC)
	cd $(COV_SRC) && $(abspath $(VENV))/bin/cmake --preset coverage -B $(COV_BUILD) \
	  -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) $(CCACHE_LAUNCHER) >/dev/null
	find $(COV_BUILD) \( -name '*.o' -o -name '*.gcda' \) -delete
	CCACHE_BASEDIR=$(COV_ROOT) $(VENV)/bin/cmake --build $(COV_BUILD) -j2
	find $(COV_BUILD) -name '*.gcda' -delete
	cd $(COV_BUILD) && $(abspath $(VENV))/bin/ctest --output-on-failure -j2 -E '$(COV_CTEST_EXCLUDE)'
	PROXOPS_FSW_NODE=$(COV_BUILD)/fsw_node $(VPY) -m pytest -q -n $(PYTEST_WORKERS) $(LINK_PY_TESTS)
	$(VPY) tests/static/coverage.py --build $(COV_BUILD) --root $(COV_SRC) --gcovr $(VENV)/bin/gcovr \
	  --json $(COV_BUILD)/coverage.json

# The Cortex-M7 self-test firmware (CMakePresets.json "firmware"; -j2: the
# machine is shared).
$(STAMPS)/fw-configure: $(STAMPS)/apt-firmware $(STAMPS)/venv $(CMAKE_SRC) CMakePresets.json firmware/CMakeLists.txt \
    cmake/toolchains/arm-none-eabi-cortex-m7.cmake
	$(VENV)/bin/cmake --preset firmware -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) >/dev/null
	@touch $@

$(FW_ELF): $(STAMPS)/fw-configure $(FW_SRC)
	$(VENV)/bin/cmake --build --preset firmware

firmware: $(FW_ELF)
	$(VPY) firmware/report.py $(FW_ELF) $(FW_INDIRECT) --json $(FW_BUILD)/report.json

# The GoogleTest suite for aarch64 under qemu-aarch64 (CMakePresets.json
# "aarch64"; ctest runs each test program through the emulator).
test-aarch64: $(STAMPS)/apt $(STAMPS)/apt-aarch64 $(STAMPS)/venv
	$(VENV)/bin/cmake --preset aarch64 -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) >/dev/null
	$(VENV)/bin/cmake --build --preset aarch64
	$(VENV)/bin/ctest --preset aarch64

# The QEMU self-test against the host float build, and instructions per step.
firmware-selftest: $(FW_ELF) $(STAMPS)/install $(STAMPS)/cpp-configure
	$(VENV)/bin/cmake --build $(CPP_BUILD) --target fw_selftest_host
	$(VPY) -m hil_sim.firmware --elf $(FW_ELF) --host-exe $(CPP_BUILD)/fw_selftest_host

# C++ benchmarks (Google Benchmark); results go to docs/PERFORMANCE.md by hand.
bench: $(STAMPS)/cpp-configure
	$(VENV)/bin/cmake -S . -B $(CPP_BUILD) -DPROXOPS_BUILD_BENCHMARKS=ON >/dev/null
	$(VENV)/bin/cmake --build $(CPP_BUILD)
	for b in $(CPP_BUILD)/bench_*; do $$b --benchmark_repetitions=9 --benchmark_report_aggregates_only=true; done

# Table I grid of the modal estimator (docs/perf/modal.md, about 15 minutes on
# 2 cores once built): the portable and the x86-64-v3 build beside numpy and
# the seed's figures, in one run. Needs nothing else running.
MODAL_TIMING_JSON ?= docs/perf/data/modal_timing_grid.json
bench-modal: $(STAMPS)/install
	$(VENV)/bin/cmake -S . -B build/bench-rel -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) -DCMAKE_BUILD_TYPE=Release \
	  -DPROXOPS_BUILD_TESTS=OFF -DPROXOPS_BUILD_BENCHMARKS=ON -DPROXOPS_BUILD_PYTHON=OFF -DPROXOPS_MARCH= >/dev/null
	$(VENV)/bin/cmake -S . -B build/bench-v3 -G Ninja -DCMAKE_MAKE_PROGRAM=$(abspath $(VENV)/bin/ninja) -DCMAKE_BUILD_TYPE=Release \
	  -DPROXOPS_BUILD_TESTS=OFF -DPROXOPS_BUILD_BENCHMARKS=ON -DPROXOPS_BUILD_PYTHON=OFF -DPROXOPS_MARCH=x86-64-v3 >/dev/null
	$(VENV)/bin/cmake --build build/bench-rel --target bench_modal
	$(VENV)/bin/cmake --build build/bench-v3 --target bench_modal
	$(VENV)/bin/proxops modal-timing --bench-exe portable=build/bench-rel/bench_modal \
	  --bench-exe v3=build/bench-v3/bench_modal --repeats 5 --json $(MODAL_TIMING_JSON)

clean:
	rm -rf build report
