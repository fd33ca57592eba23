# SPDX-License-Identifier: MIT
# ctrlbus: every job starts with `setup`, which installs what a fresh Debian machine lacks.
SHELL := /bin/bash
VENV  := .venv
PY    := $(VENV)/bin/python
BUILD := build
JOBS  ?= 2
DEMO_ARGS ?=

.PHONY: all setup c-build firmware c-test c-test-asan lint py-test test demo size bench fuzz fuzz-smoke clean

all: test

setup:
	@scripts/setup.sh

# Host build of the C library, tests and examples (warnings are errors).
c-build: setup
	@cmake -S c -B $(BUILD)/c -G Ninja -DCMAKE_BUILD_TYPE=Debug >/dev/null
	@cmake --build $(BUILD)/c -j $(JOBS)

# Cortex-M3 firmware for QEMU's mps2-an385 board (arm-none-eabi-gcc).
firmware: setup
	@$(MAKE) --no-print-directory -C c/firmware O=$(CURDIR)/$(BUILD)/firmware

c-test: c-build
	@ctest --test-dir $(BUILD)/c --output-on-failure -j $(JOBS)

# The same tests under AddressSanitizer + UndefinedBehaviorSanitizer.
c-test-asan: setup
	@cmake -S c -B $(BUILD)/c-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCTRLBUS_SANITIZE=ON >/dev/null
	@cmake --build $(BUILD)/c-asan -j $(JOBS)
	@ctest --test-dir $(BUILD)/c-asan --output-on-failure -j $(JOBS)

lint: setup
	@cd python && ../$(VENV)/bin/ruff check src tests && ../$(VENV)/bin/ruff format --check src tests
	@cd python && ../$(VENV)/bin/mypy src tests
	@$(VENV)/bin/ruff check --config python/pyproject.toml bench && $(VENV)/bin/ruff format --config python/pyproject.toml --check bench
	@cd bench && MYPYPATH=../python/src ../$(VENV)/bin/mypy --config-file ../python/pyproject.toml --explicit-package-bases .

# Python tests run against the C builds too (host base, firmware), so build those first.
py-test: c-build firmware
	@cd python && ../$(VENV)/bin/pytest -q

test: c-test c-test-asan lint py-test fuzz-smoke
	@echo "make test: all suites passed"

demo: c-build firmware
	@$(PY) -m ctrlbus.demo $(DEMO_ARGS)

size: setup
	@scripts/size.sh

# Benchmarks build what they measure themselves, as Release (-O2 and -Os): not the Debug c-build.
bench: setup
	@$(PY) bench/run.py

# Each libFuzzer target until FUZZ_RUNS executions (default 10 M) or for FUZZ_SECONDS at most
# (default 3600), then the library's coverage by the corpora; records the run in
# bench/results/fuzz.json and docs/reliability.md.
FUZZ_RUNS ?= 10000000
FUZZ_SECONDS ?= 3600
fuzz: setup
	@FUZZ_COVERAGE=1 FUZZ_RECORD=1 FUZZ_RUNS=$(FUZZ_RUNS) \
	  FUZZ_COMMAND="make fuzz FUZZ_RUNS=$(FUZZ_RUNS) FUZZ_SECONDS=$(FUZZ_SECONDS)" scripts/fuzz.sh $(FUZZ_SECONDS)

# Each libFuzzer target for 30 s (part of `make test`).
fuzz-smoke: setup
	@scripts/fuzz.sh 30

clean:
	rm -rf $(BUILD)
