#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Footprint of the ctrlbus C library on Cortex-M (called by `make size`).
#
# For cortex-m0plus, cortex-m3 and cortex-m4 it compiles every c/src/*.c with arm-none-eabi-gcc
# -Os -ffunction-sections -fdata-sections and prints .text/.data/.bss:
#   - per layer, linked with --gc-sections from the functions its public header declares (so only
#     what a firmware using that layer pays for; libgcc included, libc's memcpy/memset not);
#   - for every object file as compiled (an upper bound: nothing dropped yet).
# Then the sizes of the state structs on a 32-bit target, read from a compiled probe.
# Then the base stack per target (cortex-m0plus/m3/m4, ATmega328P with avr-gcc, RV32 rv32imac with
# riscv64-unknown-elf-gcc), in the default configuration and the minimal one (every switch of
# c/include/ctrlbus/ctrlbus_config.h off), at -Os and -O2, each compiled warning-free with
# -Wconversion and linked with --gc-sections, with the worst-case stack of ctrlbus_base_poll()
# (-fstack-usage along the call graph: scripts/stack_usage.py).
#
#   scripts/size.sh            all three CPUs, all five targets
#   CPUS="cortex-m3" TARGETS="cortex-m3 atmega328p" scripts/size.sh
#   EXTRA_CFLAGS="-DNAME=1" scripts/size.sh   every build compiled with these flags too (a measured
#                                             variant, e.g. bench/experiments/footprint-limits/)
set -euo pipefail
cd "$(dirname "$0")/.."

CROSS=${CROSS:-arm-none-eabi-}
CC="${CROSS}gcc"
SIZE="${CROSS}size"
NM="${CROSS}nm"
CPUS=${CPUS:-"cortex-m0plus cortex-m3 cortex-m4"}
read -r -a EXTRA <<<"${EXTRA_CFLAGS:-}"
CFLAGS=(-std=c99 -Os -ffunction-sections -fdata-sections -Wall -Wextra -Werror -Ic/include "${EXTRA[@]}")

if ! command -v "$CC" >/dev/null; then
  echo "size.sh: $CC not found; scripts/setup.sh installs it (apt package gcc-arm-none-eabi)" >&2
  exit 2
fi
shopt -s nullglob
sources=(c/src/*.c)
if ((${#sources[@]} == 0)); then
  echo "size.sh: no C library sources in c/src yet" >&2
  exit 2
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The functions a public header declares: `name(` at the start of a declaration.
declared_functions() {
  # (static inline functions are defined in the header itself: no object implements them)
  grep -hoE '^[a-z_][a-z0-9_ *]*[ *](ctrlbus_[a-z0-9_]+)\(' "$1" | grep -v '^static ' |
    grep -oE 'ctrlbus_[a-z0-9_]+\($' | tr -d '('
}

# .text .data .bss of a linked or object file, as three numbers.
sections() {
  "$SIZE" -B "$1" | awk 'NR == 2 { print $1, $2, $3 }'
}

# Layers: label, header. A layer whose header is missing is reported as pending.
layers=(
  "frame layer (frame.h)|c/include/ctrlbus/frame.h"
  "messages (messages.h)|c/include/ctrlbus/messages.h"
  "base stack (base.h)|c/include/ctrlbus/base.h"
)

echo "ctrlbus footprint: $("$CC" --version | head -1)"
echo "flags: -Os -ffunction-sections -fdata-sections, linked with --gc-sections (libgcc in, libc out)"
echo "a layer counts every function its header declares plus what they use from the layers below"
echo

for cpu in $CPUS; do
  objdir="$work/$cpu"
  mkdir -p "$objdir"
  objects=()
  for src in "${sources[@]}"; do
    obj="$objdir/$(basename "${src%.c}").o"
    "$CC" -mcpu="$cpu" -mthumb "${CFLAGS[@]}" -c "$src" -o "$obj"
    objects+=("$obj")
  done

  # Every function the objects define: a layer is measured from the declared ones among them.
  defined=$("$NM" --defined-only "${objects[@]}" | awk '$2 == "T" { print $3 }' | sort -u)
  printf '%-14s %-34s %7s %6s %6s\n' "$cpu" "what" ".text" ".data" ".bss"
  for layer in "${layers[@]}"; do
    label=${layer%%|*}
    header=${layer#*|}
    if [ ! -f "$header" ]; then
      printf '%-14s %-34s %s\n' "" "$label" "pending: $header not written yet"
      continue
    fi
    declared=$(declared_functions "$header" | sort -u)
    roots=$(comm -12 <(echo "$declared") <(echo "$defined"))
    missing=$(comm -23 <(echo "$declared") <(echo "$defined") | grep -c . || true)
    if [ -z "$roots" ]; then
      printf '%-14s %-34s %s\n' "" "$label" "pending: nothing that $header declares is implemented yet"
      continue
    fi
    keep=()
    for fn in $roots; do keep+=("-Wl,--undefined=$fn"); done
    first=$(echo "$roots" | head -1)
    out="$objdir/$(basename "$header" .h).elf"
    "$CC" -mcpu="$cpu" -mthumb -nostdlib -Wl,--gc-sections -Wl,--entry="$first" \
      -Wl,--unresolved-symbols=ignore-all "${keep[@]}" -o "$out" "${objects[@]}" -lgcc
    read -r text data bss < <(sections "$out")
    note=""
    if ((missing > 0)); then note="  ($missing declared functions not implemented yet)"; fi
    printf '%-14s %-34s %7s %6s %6s%s\n' "" "$label" "$text" "$data" "$bss" "$note"
  done
  total_text=0 total_data=0 total_bss=0
  for obj in "${objects[@]}"; do
    read -r text data bss < <(sections "$obj")
    printf '%-14s %-34s %7s %6s %6s\n' "" "  object $(basename "${obj%.o}").c (unlinked)" "$text" "$data" "$bss"
    total_text=$((total_text + text)) total_data=$((total_data + data)) total_bss=$((total_bss + bss))
  done
  printf '%-14s %-34s %7s %6s %6s\n' "" "  all objects (unlinked)" "$total_text" "$total_data" "$total_bss"
  echo
done

# Struct sizes: each probe is a const array as long as the struct; nm reports its size.
probe_struct() { # header type
  local header=$1 type=$2 name
  name="sizeof_${type}"
  printf '#include "%s"\nconst unsigned char %s[sizeof(%s)] = {0};\n' "$header" "$name" "$type" >"$work/probe.c"
  if ! "$CC" -mcpu=cortex-m3 -mthumb "${CFLAGS[@]}" -Ic/include -c "$work/probe.c" -o "$work/probe.o" 2>"$work/probe.err"; then
    echo "error: $(head -1 "$work/probe.err")"
    return
  fi
  echo $((16#$("$NM" -S "$work/probe.o" | awk -v n="$name" '$4 == n { print $2 }')))
}

echo "state structs on a 32-bit target (bytes; caller-owned buffers not included):"
printf '  %-24s %s\n' "ctrlbus_decoder_t" "$(probe_struct ctrlbus/frame.h ctrlbus_decoder_t) (+ the receive buffer)"
printf '  %-24s %s\n' "ctrlbus_sink_t" "$(probe_struct ctrlbus/frame.h ctrlbus_sink_t)"
BASE_STRUCT=${BASE_STRUCT:-ctrlbus_base_t}
if [ -f c/include/ctrlbus/base.h ]; then
  printf '  %-24s %s\n' "$BASE_STRUCT" "$(probe_struct ctrlbus/base.h "$BASE_STRUCT") (goal: <= 64 besides the receive buffer)"
else
  printf '  %-24s %s\n' "$BASE_STRUCT" "pending: c/include/ctrlbus/base.h not written yet"
fi
echo

# ---- the base stack on every target, default and minimal configuration, with its worst stack ----
# Targets: label|compiler|flags|objdump. A target whose compiler is missing fails the run.
targets=(
  "cortex-m0plus|arm-none-eabi-gcc|-mcpu=cortex-m0plus -mthumb|arm-none-eabi-objdump"
  "cortex-m3|arm-none-eabi-gcc|-mcpu=cortex-m3 -mthumb|arm-none-eabi-objdump"
  "cortex-m4|arm-none-eabi-gcc|-mcpu=cortex-m4 -mthumb|arm-none-eabi-objdump"
  "atmega328p|avr-gcc|-mmcu=atmega328p|avr-objdump"
  "rv32imac|riscv64-unknown-elf-gcc|-march=rv32imac -mabi=ilp32 --specs=picolibc.specs|riscv64-unknown-elf-objdump"
)
TARGETS=${TARGETS:-"cortex-m0plus cortex-m3 cortex-m4 atmega328p rv32imac"}
# The minimal configuration: every switch of ctrlbus/ctrlbus_config.h off (what remains: the 13
# mandatory requests, SYNC/ECHO, REBOOT/DFU, the error answers, the watchdog, the timeout).
MINIMAL=(-DCTRLBUS_CONFIG_HEALTH=0 -DCTRLBUS_CONFIG_COMMAND_QUEUE=0 -DCTRLBUS_CONFIG_LIMITS=0
  -DCTRLBUS_CONFIG_PROFILE_SDK2020=0 -DCTRLBUS_CONFIG_CONF_ADV=0 -DCTRLBUS_CONFIG_MASTER_CODECS=0)
WARNINGS=(-Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Werror)
base_roots=$(declared_functions c/include/ctrlbus/base.h | sort -u)

# build_base DIR CC "TARGET FLAGS" OPT [DEFINES...]: objects with .su files, the base stack linked
# with --gc-sections (libgcc in, libc out) as DIR/base.elf, and with libc as DIR/stack.elf.
build_base() {
  local dir=$1 cc=$2 flags=$3 opt=$4
  shift 4
  mkdir -p "$dir"
  local objs=() keep=()
  for src in "${sources[@]}"; do
    local obj="$dir/$(basename "${src%.c}").o"
    # shellcheck disable=SC2086
    (cd "$dir" && "$cc" $flags -std=c99 "$opt" -ffunction-sections -fdata-sections -fstack-usage \
      "${WARNINGS[@]}" -I"$OLDPWD/c/include" "${EXTRA[@]}" "$@" -c "$OLDPWD/$src" -o "$obj")
    objs+=("$obj")
  done
  for fn in $base_roots; do keep+=("-Wl,--undefined=$fn"); done
  # shellcheck disable=SC2086
  "$cc" ${flags//--specs=picolibc.specs/} -nostdlib -Wl,--gc-sections -Wl,--entry=ctrlbus_base_poll \
    -Wl,--unresolved-symbols=ignore-all "${keep[@]}" -o "$dir/base.elf" "${objs[@]}" -lgcc
  # shellcheck disable=SC2086
  "$cc" $flags -nostdlib -Wl,--gc-sections -Wl,--entry=ctrlbus_base_poll "${keep[@]}" \
    -o "$dir/stack.elf" "${objs[@]}" -Wl,--start-group -lc -lgcc -Wl,--end-group
}

echo "base stack per target: everything base.h declares, linked with --gc-sections (libgcc in, libc out);"
echo "minimal = every switch of ctrlbus_config.h off; stack = worst case of ctrlbus_base_poll() along its"
echo "call graph (-fstack-usage frames, scripts/stack_usage.py), plus the application's callbacks' own"
printf '%-14s %-8s %-4s %7s %6s %6s %7s\n' "target" "config" "opt" ".text" ".data" ".bss" "stack"
for target in "${targets[@]}"; do
  IFS='|' read -r label cc flags objdump <<<"$target"
  [[ " $TARGETS " == *" $label "* ]] || continue
  if ! command -v "$cc" >/dev/null; then
    echo "size.sh: $cc not found; scripts/setup.sh installs it" >&2
    exit 2
  fi
  for config in default minimal; do
    defines=()
    if [ "$config" = minimal ]; then defines=("${MINIMAL[@]}"); fi
    for opt in -Os -O2; do
      dir="$work/targets/$label-$config$opt"
      build_base "$dir" "$cc" "$flags" "$opt" "${defines[@]}"
      SIZE_TOOL=${objdump%objdump}size
      read -r text data bss < <("$SIZE_TOOL" -B "$dir/base.elf" | awk 'NR == 2 { print $1, $2, $3 }')
      stack=$(python3 scripts/stack_usage.py "$objdump" "$dir/stack.elf" ctrlbus_base_poll "$dir"/*.su)
      printf '%-14s %-8s %-4s %7s %6s %6s %7s\n' "$label" "$config" "$opt" "$text" "$data" "$bss" "${stack%% *}"
      if [ "$label $config $opt" = "cortex-m0plus default -Os" ]; then
        worst_path=${stack#* }
        default_m0_text=$text
      fi
    done
  done
done
if [ -n "${worst_path:-}" ]; then
  echo "worst stack path (cortex-m0plus, default, -Os): $worst_path"
fi

# What each switch of ctrlbus_config.h saves, turned off alone from the default configuration
# (cortex-m0plus -Os, the goal's target): the figures ctrlbus_config.h points at.
if [[ " $TARGETS " == *" cortex-m0plus "* ]]; then
  echo
  echo "switches off one at a time (cortex-m0plus -Os, base stack .text; default: $default_m0_text B):"
  for switch in "${MINIMAL[@]}"; do
    name=${switch#-D}
    dir="$work/switch-${name%%=*}"
    build_base "$dir" arm-none-eabi-gcc "-mcpu=cortex-m0plus -mthumb" -Os "$switch"
    read -r text _ < <(arm-none-eabi-size -B "$dir/base.elf" | awk 'NR == 2 { print $1 }')
    printf '  switch %-36s %6s B .text, saves %5s B\n' "$name" "$text" "$((default_m0_text - text))"
  done
fi
echo
echo "goals (issue 27): cortex-m0plus -Os base stack <= 2560 B .text minimal, <= 4096 B default;"
echo "ctrlbus_base_poll() stack <= 256 B (cortex-m0plus, default); ctrlbus_base_t <= 64 B; no transmit buffer"
