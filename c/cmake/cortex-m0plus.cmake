# SPDX-License-Identifier: MIT
# CMake toolchain file: Arm Cortex-M0+ (ARMv6-M, Thumb) with the GNU Arm Embedded toolchain
# (arm-none-eabi-gcc on the PATH, newlib).
#   cmake -S c -B build/m0plus -DCMAKE_TOOLCHAIN_FILE=c/cmake/cortex-m0plus.cmake -DCMAKE_BUILD_TYPE=MinSizeRel
# builds the library alone (tests and POSIX examples are host-only). In your firmware project,
# pass your own linker script and start-up code; this file only selects the compiler and the CPU.
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
set(CMAKE_AR arm-none-eabi-ar CACHE FILEPATH "Archiver")
set(CMAKE_RANLIB arm-none-eabi-ranlib CACHE FILEPATH "Archive indexer")

# One section per function and object, so --gc-sections drops what the firmware does not call.
set(ctrlbus_cpu_flags "-mcpu=cortex-m0plus -mthumb -mfloat-abi=soft")
set(CMAKE_C_FLAGS_INIT "${ctrlbus_cpu_flags} -ffunction-sections -fdata-sections")
set(CMAKE_CXX_FLAGS_INIT "${ctrlbus_cpu_flags} -ffunction-sections -fdata-sections")
set(CMAKE_ASM_FLAGS_INIT "${ctrlbus_cpu_flags}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,--gc-sections")

# Without a linker script no test program links, so CMake's compiler checks build a library.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

# Programs (code generators) come from the host; libraries, headers and packages from the target.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
