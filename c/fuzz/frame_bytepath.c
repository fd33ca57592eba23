/* SPDX-License-Identifier: MIT */
/* frame.c without its bulk path, every public name prefixed bytepath_ (see frame_bytepath.h). */
#define CTRLBUS_DECODER_FAST 0
#define TWIN_PREFIX bytepath_
#include "frame_twin.h"
