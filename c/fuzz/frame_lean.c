/* SPDX-License-Identifier: MIT */
/* frame.c at the level size-optimised builds get by default (CTRLBUS_DECODER_FAST 2: the compact
 * core with its fast steps), every public name prefixed lean_ (see frame_bytepath.h). */
#define CTRLBUS_DECODER_FAST 2
#define TWIN_PREFIX lean_
#include "frame_twin.h"
