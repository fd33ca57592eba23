#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Idempotent set-up for a fresh Debian machine: apt packages by group, then the Python venv(s).
# Fast when everything is already there, so every make target can call it.
#
#   scripts/setup.sh          the light default (= `demo`): the venv with the package and the
#                             dashboard's Python packages; what `make demo` needs, nothing more
#   scripts/setup.sh c        + the C host toolchain (make demo DEMO_ARGS="--base c")
#   scripts/setup.sh qemu     + the firmware toolchain and QEMU (make demo DEMO_ARGS="--base qemu")
#   scripts/setup.sh full     everything `make test`, `make bench` and `make fuzz` use, including
#                             the contributors' Python tools and a second venv on Python 3.10
set -euo pipefail
cd "$(dirname "$0")/.."

# apt packages, one group per line: GROUP="packages"   # what needs them
declare -A APT_GROUP
APT_GROUP[venv]="python3-venv"                                          # the Python venv
APT_GROUP[c]="cmake ninja-build gcc make"                               # C host build
APT_GROUP[firmware]="qemu-system-arm gcc-arm-none-eabi libnewlib-arm-none-eabi"  # Cortex-M3 firmware under QEMU
APT_GROUP[fuzz]="clang libclang-rt-14-dev"                              # libFuzzer + sanitizers
APT_GROUP[bench]="valgrind"                                             # callgrind benchmarks
APT_GROUP[tshark]="tshark"                                              # Wireshark dissector test
APT_GROUP[browser]="chromium"                                           # dashboard browser test
APT_GROUP[tools]="socat zsh iproute2"                                   # link tests; zsh completion test; test_web's network namespace (ip)
APT_GROUP[ports]="qemu-system-misc gcc-avr avr-libc binutils-avr gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf libsimavr-dev libelf-dev pkg-config"  # c/ports: ATmega328P (QEMU, and simavr for the chip image), RV32 (and make size)
APT_GROUP[sigrok]="sigrok-cli"                                          # sigrok decoder test (tools/sigrok)
APT_GROUP[pictures]="graphviz mscgen fonts-dejavu-core fonts-dejavu-extra"  # make pictures (docs/diagrams); without -extra, dot draws wiring.png otherwise
APT_GROUP[packaging]="git pkg-config"                                   # release and consumer tests
APT_GROUP[stress]="stress-ng"                                           # make test-stress (loads both cores)

# which apt groups and Python set-up each choice needs
case "${1:-demo}" in
  demo | sim | light) groups=(venv); python=light ;;
  c) groups=(venv c); python=light ;;
  qemu) groups=(venv c firmware); python=light ;;
  full) groups=("${!APT_GROUP[@]}"); python=full ;;
  *) echo "setup: unknown choice '$1' (demo, c, qemu or full)" >&2; exit 2 ;;
esac

missing=()
for group in "${groups[@]}"; do
  for pkg in ${APT_GROUP[$group]}; do
    dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
  done
done
if ((${#missing[@]})); then
  echo "setup: installing apt packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" = 0 ] || SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# A venv with the package (editable) and, for `full`, the contributors' dependency groups
# (python/pyproject.toml [dependency-groups]; pip >= 25.1 reads them).
# install_venv VENV PYTHON STAMP-NAME PIP-ARGS...
install_venv() {
  local venv=$1 py=$2 stamp=$1/.ctrlbus-$3 kind=$3 extras=web
  shift 3
  if [ ! -x "$venv/bin/python" ]; then
    echo "setup: creating $venv ($("$py" --version 2>&1))"
    "$py" -m venv "$venv"
  fi
  local full_stamp=$venv/.ctrlbus-full  # a full install holds everything a light one does
  if [ "$kind" = light ] && [ -f "$full_stamp" ] && [ "$full_stamp" -nt python/pyproject.toml ] \
    && [ "$full_stamp" -nt scripts/setup.sh ]; then
    return 0
  fi
  # The stamp holds the version installed: the package's version is read from the C header when it
  # is installed (python/setup.py), so a new version there means installing again.
  if [ ! -f "$stamp" ] || [ python/pyproject.toml -nt "$stamp" ] || [ scripts/setup.sh -nt "$stamp" ] \
    || [ scripts/requirements-packaging.txt -nt "$stamp" ] || [ "$(cat "$stamp")" != "$version" ]; then
    echo "setup: installing the ctrlbus Python package ($kind) into $venv"
    "$venv/bin/python" -m pip install -q --upgrade pip
    [ "$kind" = full ] && extras=web,ros2  # the ROS 2 bridge's tests (docs/ros2.md)
    "$venv/bin/python" -m pip install -q -e "python[$extras]" "$@"
    echo "$version" > "$stamp"
  fi
}

# Python 3.10, the oldest supported: on PATH, else an interpreter pyenv installed.
find_python310() {
  local candidate
  for candidate in "$(command -v python3.10 || true)" "${PYENV_ROOT:-${HOME:-/root}/.pyenv}"/versions/3.10*/bin/python3.10; do
    if [ -n "$candidate" ] && [ -x "$candidate" ] && "$candidate" -c 'import sys, venv; assert sys.version_info[:2] == (3, 10)' 2>/dev/null; then
      echo "$candidate"
      return 0
    fi
  done
  return 1
}

PY=${PYTHON:-python3}
version=$("$PY" scripts/ctrlbus_version.py)
if [ "$python" = light ]; then
  install_venv .venv "$PY" light
else
  install_venv .venv "$PY" full --group python/pyproject.toml:dev --group python/pyproject.toml:bench \
    -r scripts/requirements-packaging.txt
  if ! py310=$(find_python310); then
    echo "setup: no Python 3.10 found (not on PATH, not in \$PYENV_ROOT/versions): make test runs the" \
      "Python suite on 3.10 too; install one (e.g. pyenv install 3.10) or put python3.10 on PATH" >&2
    exit 1
  fi
  install_venv .venv310 "$py310" full --group python/pyproject.toml:dev --group python/pyproject.toml:bench \
    -r scripts/requirements-packaging.txt
fi
