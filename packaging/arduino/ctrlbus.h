/* SPDX-License-Identifier: MIT */
/* The Arduino entry point of the ctrlbus library: `#include <ctrlbus.h>` in a sketch brings in the
 * base stack (ctrlbus/base.h, which is its manual) and the differential-drive helpers
 * (ctrlbus/diffdrive.h). The Arduino IDE finds a library by a header at the top of its src/, so
 * this one sits there; the library's own headers keep their ctrlbus/ prefix. */
#ifndef CTRLBUS_ARDUINO_H
#define CTRLBUS_ARDUINO_H

#include "ctrlbus/base.h"
#include "ctrlbus/diffdrive.h"

#endif
