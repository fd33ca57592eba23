#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Idempotent set-up for a fresh Debian machine: apt packages, then the Python venv in .venv.
# Fast when everything is already there, so `make test` and `make demo` can always call it.
set -euo pipefail
cd "$(dirname "$0")/.."

APT_PACKAGES=(
  cmake ninja-build gcc make python3-venv
  qemu-system-arm gcc-arm-none-eabi libnewlib-arm-none-eabi   # Cortex-M3 firmware under QEMU
  gcc-avr avr-libc gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf  # make size: AVR, RV32
  clang libclang-rt-14-dev                                     # libFuzzer + sanitizers
  valgrind                                                     # callgrind benchmarks
  tshark                                                       # Wireshark dissector test
  chromium                                                     # dashboard browser test
  socat
)

missing=()
for pkg in "${APT_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  echo "setup: installing apt packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi
stamp=.venv/.ctrlbus-installed
if [ ! -f "$stamp" ] || [ python/pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing the ctrlbus Python package and its test tools into .venv"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e "python[dev,web,bench]"
  touch "$stamp"
fi
