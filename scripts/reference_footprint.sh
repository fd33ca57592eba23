#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# The vendor reference base's framer + dispatcher compiled with the flags of scripts/size.sh, so
# that docs/performance.md can set ctrlbus's footprint beside it. Nothing of the reference is
# copied into this repository: the script reads the user's own checkout of the public sources
# (ROM-robotics/slamware_kit_v6, the base_ref and infra_pub trees) and leaves no object behind.
#
#   scripts/reference_footprint.sh CHECKOUT [DEVICE_INCLUDE]
#
# CHECKOUT is the directory holding base_ref/ and infra_pub/. The sources include the STM32F10x
# CMSIS device header stm32f10x.h, which the repository does not carry: DEVICE_INCLUDE is a
# directory holding one (ST's STM32F10x standard peripheral library has it, under
# Libraries/CMSIS/CM3/DeviceSupport/ST/STM32F10x); without it the script looks for one inside
# CHECKOUT. Only declarations are used from it; no peripheral code is compiled.
#
# Compiled: infra_pub/arch/infra_stm32/net/interchip.c (framing, checksum, error codes),
# base_ref/src/drv/drv_ctrlbus.c (the control-bus driver), base_ref/src/request_handler.c (the
# dispatch and the answers) and base_ref/src/binary_config.c (GET_BASE_CONF's blob), with the
# IAR project's Release_Rev6 defines (-D__ICCARM__ selects the sources' IAR branches, as the
# original toolchain did), arm-none-eabi-gcc -mcpu=$CPU -mthumb -std=gnu99 -Os -ffunction-sections
# -fdata-sections. Printed: .text/.data/.bss per file and in total, unlinked (every function of
# those files: what a firmware links of them, the motor and sensor drivers they call excluded).
#   CPUS="cortex-m0plus cortex-m3" OPTS="-Os -O2" scripts/reference_footprint.sh ~/slamware_kit_v6
set -euo pipefail

if [ $# -lt 1 ] || [ $# -gt 2 ]; then
  echo "usage: $0 CHECKOUT [DEVICE_INCLUDE]" >&2
  exit 2
fi
checkout=$(cd "$1" && pwd)
CC=${CC:-arm-none-eabi-gcc}
SIZE=${SIZE:-arm-none-eabi-size}
CPUS=${CPUS:-cortex-m0plus}
OPTS=${OPTS:--Os}
files=(infra_pub/arch/infra_stm32/net/interchip.c base_ref/src/drv/drv_ctrlbus.c
  base_ref/src/request_handler.c base_ref/src/binary_config.c)
for f in "${files[@]}"; do
  if [ ! -f "$checkout/$f" ]; then
    echo "reference_footprint.sh: $checkout/$f not found (CHECKOUT must hold base_ref/ and infra_pub/)" >&2
    exit 2
  fi
done
if [ $# -eq 2 ]; then
  device_include=$(cd "$2" && pwd)
else
  header=$(find "$checkout" -name stm32f10x.h -print -quit)
  if [ -z "$header" ]; then
    echo "reference_footprint.sh: no stm32f10x.h in $checkout; give its directory as DEVICE_INCLUDE" >&2
    exit 2
  fi
  device_include=$(dirname "$header")
fi
if [ ! -f "$device_include/stm32f10x.h" ]; then
  echo "reference_footprint.sh: no stm32f10x.h in $device_include" >&2
  exit 2
fi
if ! command -v "$CC" >/dev/null; then
  echo "reference_footprint.sh: $CC not found; scripts/setup.sh installs it" >&2
  exit 2
fi

defines=(-D__ICCARM__ -DUSE_STDPERIPH_DRIVER -DSTM32F10X_HD -DUSART_ENABLE_USART3
  -DCONFIG_BREAKOUT_REV=6 -DUSE_FRONT_IR_SENSORS -DFEATURE_SET_V)
includes=(-I"$device_include" -I"$checkout/base_ref/src" -I"$checkout/infra_pub/arch/infra_stm32"
  -I"$checkout/infra_pub" -I"$checkout/infra_pub/arch/infra_stm32/32f10x")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

echo "reference framer + dispatcher: $("$CC" --version | head -1)"
printf '%-14s %-4s %-20s %7s %6s %6s\n' "cpu" "opt" "file" ".text" ".data" ".bss"
for cpu in $CPUS; do
  for opt in $OPTS; do
    total_text=0 total_data=0 total_bss=0
    for f in "${files[@]}"; do
      obj="$work/$(basename "${f%.c}").o"
      # (-w: the vendor's code, compiled as it is; its warnings are not ours to fix)
      "$CC" -mcpu="$cpu" -mthumb -std=gnu99 "$opt" -ffunction-sections -fdata-sections -w \
        "${defines[@]}" "${includes[@]}" -c "$checkout/$f" -o "$obj"
      read -r text data bss < <("$SIZE" -B "$obj" | awk 'NR == 2 { print $1, $2, $3 }')
      printf '%-14s %-4s %-20s %7s %6s %6s\n' "$cpu" "$opt" "$(basename "$f")" "$text" "$data" "$bss"
      total_text=$((total_text + text)) total_data=$((total_data + data)) total_bss=$((total_bss + bss))
    done
    printf '%-14s %-4s %-20s %7s %6s %6s\n' "$cpu" "$opt" "total" "$total_text" "$total_data" "$total_bss"
  done
done
