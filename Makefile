# SPDX-License-Identifier: MIT
# ctrlbus: the jobs that need the dev tools start with `setup`, which installs what a fresh Debian
# machine lacks. The C build (`c-build`, `c-test`) needs only a C compiler, CMake and make, and
# `arduino` only python3: neither runs the set-up.
SHELL := /bin/bash
VENV  := .venv
VENV310 := .venv310
# The venv's Python, for the jobs that run `setup` first; the scripts that `arduino` and
# `release-tag` run use nothing but the standard library, so they take the system's.
PY    := $(VENV)/bin/python
SYSTEM_PY := python3
# Ninja when it is installed (setup installs it), else CMake's default generator (make).
CMAKE_GENERATOR ?= $(if $(shell command -v ninja),Ninja,Unix Makefiles)
BUILD := build
JOBS  ?= 2
DEMO_ARGS ?=

.PHONY: all setup generate c-build c-build-only firmware firmware-only ports ports-only c-test c-test-config-off c-test-asan lint py-test test demo size bench fuzz fuzz-smoke clean

all: test

# Everything the test, bench and fuzz jobs use (apt groups, dev tools, the Python 3.10 venv).
setup:
	@scripts/setup.sh full

# Every table generated from the protocol description (protocol/ctrlbus.json): the C answer
# structs, layouts and decoders, ctrlbus.protocol_tables, the Wireshark and sigrok tables and the
# field tables of docs/protocol.md (scripts/generate_protocol.py: Python's standard library only).
# tests/test_generated.py (in py-test) fails when a committed file differs from what this writes.
generate:
	@python3 scripts/generate_protocol.py

# Host build of the C library, tests and examples (warnings are errors). A Debug build, for our
# tests: firmware links a Release one (docs/c-library.md). Needs a C compiler, CMake and make
# (python3 too for the tests, which are left out without it); no set-up
# (python/tests/test_c_build_alone.py runs it with nothing else on the PATH).
c-build: c-build-only
c-build-only:
	@cmake -S c -B $(BUILD)/c -G "$(CMAKE_GENERATOR)" -DCMAKE_BUILD_TYPE=Debug >/dev/null
	@cmake --build $(BUILD)/c -j $(JOBS)

# Every firmware image of c/ports/ (c/ports/README.md): the minimal base on the emulated MCUs
# (ATmega328P, nRF51, STM32F405, FE310, and its Cortex-M0+ build), the simulated base on the
# 32-bit boards, and QEMU's mps2-an385 (Cortex-M3) with its UART bring-up probe and its sdk2020
# image. `make -C c/ports sizes` prints their flash and RAM. `firmware` is the same job.
ports firmware: setup
	@$(MAKE) --no-print-directory ports-only
ports-only firmware-only:
	@$(MAKE) --no-print-directory -C c/ports O=$(CURDIR)/$(BUILD)/ports

c-test: c-build
	@cd $(BUILD)/c && ctest --output-on-failure -j $(JOBS)

# The C tests again with every feature switch of ctrlbus_config.h off (c/tests/config_all_off.h).
c-test-config-off: setup
	@cmake -S c -B $(BUILD)/c-config-off -G Ninja -DCMAKE_BUILD_TYPE=Debug \
	  -DCTRLBUS_CONFIG_HEADER=$(CURDIR)/c/tests/config_all_off.h >/dev/null
	@cmake --build $(BUILD)/c-config-off -j $(JOBS)
	@cd $(BUILD)/c-config-off && ctest --output-on-failure -j $(JOBS)

# The same tests under AddressSanitizer + UndefinedBehaviorSanitizer.
c-test-asan: setup
	@cmake -S c -B $(BUILD)/c-asan -G Ninja -DCMAKE_BUILD_TYPE=Debug -DCTRLBUS_SANITIZE=ON >/dev/null
	@cmake --build $(BUILD)/c-asan -j $(JOBS)
	@cd $(BUILD)/c-asan && ctest --output-on-failure -j $(JOBS)

lint: setup
	@cd python && ../$(VENV)/bin/ruff check src tests && ../$(VENV)/bin/ruff format --check src tests
	@cd python && ../$(VENV)/bin/mypy src tests
	@$(VENV)/bin/ruff check --config python/pyproject.toml bench && $(VENV)/bin/ruff format --config python/pyproject.toml --check bench
	@cd bench && MYPYPATH=../python/src ../$(VENV)/bin/mypy --config-file ../python/pyproject.toml --explicit-package-bases .
	@$(VENV)/bin/ruff check --config python/pyproject.toml scripts/generate_protocol.py && \
	  $(VENV)/bin/ruff format --config python/pyproject.toml --check scripts/generate_protocol.py && \
	  $(VENV)/bin/mypy --config-file python/pyproject.toml scripts/generate_protocol.py

# Python tests run against the C builds too (host base, firmware), so build those first. The suite
# runs on both cores (pytest-xdist) with the CI Hypothesis profile, then again on Python 3.10, the
# oldest supported, but only the tests marked py310 (python/tests/conftest.py: imports, packaging,
# the CLI, the typed core; README.md says why that covers 3.10). PY310_PYTEST_ARGS adds options.
PYTEST_JOBS ?= auto
PY310_PYTEST_ARGS ?=
py-test: setup c-build ports
	@cd python && HYPOTHESIS_PROFILE=ci ../$(VENV)/bin/pytest -q -n $(PYTEST_JOBS)
	@echo "py-test: the py310 tests again on $$($(VENV310)/bin/python --version)"
	@cd python && HYPOTHESIS_PROFILE=ci ../$(VENV310)/bin/pytest -q -n $(PYTEST_JOBS) -p no:cacheprovider \
	  -m py310 $(PY310_PYTEST_ARGS)

# The contributor's inner loop: lint, then every test not marked slow or external, on both cores
# with the dev Hypothesis profile (few examples). Needs only `scripts/setup.sh full` once.
.PHONY: check test-stress
check: setup
	@$(MAKE) --no-print-directory lint
	@cd python && HYPOTHESIS_PROFILE=dev ../$(VENV)/bin/pytest -q -n $(PYTEST_JOBS) -m "not slow and not external"

# The proof that no test depends on the host's scheduling: the emulator, checker, firmware, CLI
# and ROS 2 bridge (DDS) tests STRESS_RUNS times in a row while stress-ng keeps both cores busy; prints the count of
# failed runs and the time. 0 failed runs is the bar.
STRESS_RUNS ?= 20
STRESS_TESTS ?= tests/test_mcu_ports.py tests/test_firmware.py tests/test_minimal_base.py \
  tests/test_served_bases.py tests/test_hostile_link.py tests/test_posix_base.py tests/test_checker.py \
  tests/test_quirks.py tests/test_vtime.py tests/test_cli.py tests/test_cli_face.py tests/test_core_cli.py \
  tests/test_sim_cli.py tests/test_ros2_bridge.py tests/test_ros2_cli.py tests/test_ros2_loopback.py \
  tests/test_ros2_record.py
test-stress: setup c-build ports
	@command -v stress-ng >/dev/null || { echo "test-stress: stress-ng is missing (scripts/setup.sh full)"; exit 1; }
	@mkdir -p $(BUILD)/stress; stress-ng --cpu 2 --quiet & stress=$$!; \
	  trap 'kill $$stress 2>/dev/null' EXIT; started=$$(date +%s); failed=0; \
	  for run in $$(seq 1 $(STRESS_RUNS)); do \
	    log=$(BUILD)/stress/run-$$run.log; \
	    if (cd python && HYPOTHESIS_PROFILE=ci ../$(VENV)/bin/pytest -q -n $(PYTEST_JOBS) -p no:cacheprovider \
	        $(STRESS_TESTS)) >$$log 2>&1; then result=passed; else result=FAILED; failed=$$((failed + 1)); fi; \
	    echo "test-stress: run $$run of $(STRESS_RUNS) $$result ($$(tail -1 $$log)) after $$(( $$(date +%s) - started )) s"; \
	  done; \
	  echo "test-stress: $$failed of $(STRESS_RUNS) runs failed under stress-ng --cpu 2 in $$(( $$(date +%s) - started )) s (logs: $(BUILD)/stress)"; \
	  test $$failed = 0

test: c-test c-test-config-off c-test-asan lint py-test fuzz-smoke pictures
	@echo "make test: all suites passed"

# The pictures in docs/img drawn from their text sources in docs/diagrams (Graphviz .dot, mscgen
# .msc). Always drawn (so `make test` checks that they build); a picture is copied into docs/img
# only when it changed. The dashboard screenshot comes from tests/test_dashboard_browser.py.
.PHONY: pictures
pictures: setup
	@mkdir -p $(BUILD)/pictures
	@for source in docs/diagrams/*.dot docs/diagrams/*.msc; do \
	  name=$$(basename "$${source%.*}"); out=$(BUILD)/pictures/$$name.png; \
	  case "$$source" in \
	    *.dot) dot -Tpng -o "$$out" "$$source" ;; \
	    *.msc) mscgen -T png -F "DejaVu Sans:size=10" -o "$$out" "$$source" ;; \
	  esac || exit 1; \
	  cmp -s "$$out" docs/img/$$name.png || { cp "$$out" docs/img/$$name.png; echo "pictures: docs/img/$$name.png updated"; }; \
	done

# The default demo (the simulated base) needs only the venv; `--base c` adds the C host build and
# `--base qemu` the firmware and QEMU, each set up and built only when asked for.
DEMO_BASE = $(shell printf '%s\n' $(DEMO_ARGS) | sed -n '/^--base=/{s/^--base=//p;q;};/^--base$$/{n;p;q;}')
demo:
	@case "$(DEMO_BASE)" in \
	  ""|sim) scripts/setup.sh demo ;; \
	  c) scripts/setup.sh c && $(MAKE) --no-print-directory c-build-only ;; \
	  qemu) scripts/setup.sh qemu && $(MAKE) --no-print-directory -C c/ports O=$(CURDIR)/$(BUILD)/ports mps2_an385 ;; \
	  *) scripts/setup.sh demo ;; \
	esac
	@$(PY) -m ctrlbus demo $(DEMO_ARGS)

# The library per target and configuration (scripts/size.sh), then every firmware image's flash and RAM.
size: setup
	@scripts/size.sh
	@$(MAKE) --no-print-directory -s -C c/ports O=$(CURDIR)/$(BUILD)/ports sizes

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

.PHONY: consumers arduino release release-tag

# The C library as other projects consume it: CMake add_subdirectory, FetchContent, find_package,
# pkg-config, and a Cortex-M0+ cross build (python/tests/test_c_consumers.py, also run by py-test).
consumers: setup
	@cd python && ../$(VENV)/bin/pytest -q tests/test_c_consumers.py

# Release artefacts in $(DIST): the Arduino library zip, the PlatformIO package, the Python wheel
# and sdist, and a source tarball of what is committed at HEAD (git archive). The version is the
# one in c/include/ctrlbus/ctrlbus.h; python/tests/test_release.py checks every artefact.
DIST ?= dist
arduino:
	@$(SYSTEM_PY) scripts/arduino_zip.py $(DIST)

release: setup
	@version=$$($(PY) scripts/ctrlbus_version.py) && mkdir -p $(DIST) && \
	  rm -f $(DIST)/ctrlbus-*$$version[.-]* && mkdir -p $(BUILD) && \
	  $(PY) scripts/arduino_zip.py $(DIST) >/dev/null && \
	  PLATFORMIO_CORE_DIR=$(CURDIR)/$(BUILD)/platformio PLATFORMIO_SETTING_ENABLE_TELEMETRY=No \
	    $(PY) scripts/pio_pack.py -o $(DIST)/ctrlbus-platformio-$$version.tar.gz . >/dev/null && \
	  { $(PY) -m build --outdir $(DIST) python >$(BUILD)/python-build.log 2>&1 || \
	    { cat $(BUILD)/python-build.log; exit 1; }; } && \
	  git archive --format=tar.gz --prefix=ctrlbus-$$version/ -o $(DIST)/ctrlbus-$$version-source.tar.gz HEAD && \
	  ls -1 $(DIST)/ctrlbus-*$$version[.-]*

clean:
	rm -rf $(BUILD)

# The last step of a release (docs/c-library.md, "Releases"): the annotated tag v<version> on
# HEAD, the tag the README's FetchContent recipe names. Refuses a tree with uncommitted changes.
release-tag:
	@git diff --quiet HEAD || { echo "release-tag: commit your changes first" >&2; exit 2; }
	@version=$$($(SYSTEM_PY) scripts/ctrlbus_version.py) && git tag -a "v$$version" -m "ctrlbus $$version" && \
	  echo "tagged v$$version: git push origin v$$version"
