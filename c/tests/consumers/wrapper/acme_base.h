/* SPDX-License-Identifier: MIT */
/* The wrapping library's one function (wrapper/CMakeLists.txt). */
#ifndef ACME_BASE_H
#define ACME_BASE_H

#include <stdint.h>

/* The robot's radius as GET_BASE_CONF carries it (mm Q8). */
int32_t acme_base_radius_mm_q8(void);

#endif
