/* SPDX-License-Identifier: MIT */
/* The consumer's own ctrlbus configuration (CTRLBUS_CONFIG_HEADER), set the way a firmware team
 * sets it: a normal CMake variable before the library is added (CMakeLists.txt,
 * CONSUMER_CONFIG_HEADER). One switch off, which shows at run time in the library's objects. */
#define CTRLBUS_CONFIG_HEALTH 0
