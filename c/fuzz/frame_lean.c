/* SPDX-License-Identifier: MIT */
/* frame.c with the bulk path as size-optimised builds get it by default (CTRLBUS_DECODER_FAST 2:
 * take_bulk() in the general loop, without the shortcuts), every public name prefixed lean_ (see
 * frame_bytepath.h). */
#define CTRLBUS_DECODER_FAST 2
#define TWIN_PREFIX lean_
#include "frame_twin.h"
