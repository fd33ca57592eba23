/* SPDX-License-Identifier: MIT */
/* ctrlbus: the SLAMWARE Control Bus in portable C99.
 *
 * This header holds what every layer shares: the library version and the error codes. The layers
 * themselves are:
 *
 *   ctrlbus/frame.h     frames on the wire: the streaming encoder ("sink") and the stream decoder
 *   ctrlbus/messages.h  typed requests and answers, serialised field by field through a sink
 *   ctrlbus/base.h      the base stack: a robot base's whole side of the bus
 *
 * Build-time feature switches (all on by default) are in ctrlbus/ctrlbus_config.h.
 *
 * Conventions of the whole library (they are not repeated for every function):
 *
 * - No dynamic memory, no global or static mutable state, no standard I/O. Every piece of state
 *   lives in a caller-owned struct that is passed as the first argument; buffers are caller-owned.
 * - Functions that can fail return a negative CTRLBUS_ERR_* code; functions that produce a length
 *   return it as a non-negative int32_t and use the negative range for errors.
 * - "ISR-safe" means the function touches nothing but its arguments, so it may run in an interrupt
 *   as long as no other context uses the same instance at the same time. Nothing in the library
 *   blocks or takes locks.
 * - Costs are given in "byte visits": one read or write of one byte of the buffer concerned.
 */
#ifndef CTRLBUS_CTRLBUS_H
#define CTRLBUS_CTRLBUS_H

#include <stdint.h>

#include "ctrlbus/ctrlbus_config.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CTRLBUS_VERSION_MAJOR 0
#define CTRLBUS_VERSION_MINOR 1
#define CTRLBUS_VERSION_PATCH 0

/* Fixed point, as the protocol's fields carry it: Q8 (1/256: mm and degrees in GET_BASE_CONF) and
 * Q16 (1/65536: velocities, deadreckon deltas, distances). The arithmetic is int32_t whatever the
 * size of int, so CTRLBUS_Q8(170) cannot overflow where `170 << 8` would on a 16-bit int (AVR).
 * value: an integer (a constant or a variable) in the field's unit; its Q form must fit an int32_t.
 * The inverses give the integer part, rounded toward zero. Usable in constant initializers. */
#define CTRLBUS_Q8(value) ((int32_t)(value) * INT32_C(256))
#define CTRLBUS_Q16(value) ((int32_t)(value) * INT32_C(65536))
#define CTRLBUS_FROM_Q8(q8) ((int32_t)(q8) / INT32_C(256))
#define CTRLBUS_FROM_Q16(q16) ((int32_t)(q16) / INT32_C(65536))

/* Error codes. Every one is negative so that "length or error" can share one int32_t. */
#define CTRLBUS_OK 0
/* A NULL pointer, an impossible option, or a struct whose fields contradict each other (for
 * example a POLL_BASE_CMD answer with payload_size 0 and a pending command). A bug in the caller. */
#define CTRLBUS_ERR_ARGUMENT (-1)
/* Received bytes that do not form the message they claim to be: wrong payload length for the
 * command, or a value the layout does not allow. A base answers these with ERROR 0x8001. */
#define CTRLBUS_ERR_FORMAT (-2)
/* A command, control-bus request or sub-command that the protocol (or this library) does not
 * define. A base answers these with ERROR 0x8000, or 0x8002 for an unknown HEALTH sub-command. */
#define CTRLBUS_ERR_UNSUPPORTED (-3)
/* Something does not fit: a payload longer than a frame can carry, or a caller buffer that is too
 * small for what was asked to be written into it. */
#define CTRLBUS_ERR_TOO_BIG (-4)
/* The bytes written between ctrlbus_sink_begin() and ctrlbus_sink_end() differ in number from the
 * payload length announced to ctrlbus_sink_begin(), or a sink was used outside a frame. */
#define CTRLBUS_ERR_LENGTH (-5)
/* Suggested return value of a write callback that could not deliver its bytes; the sink reports
 * whatever negative value the callback returned. */
#define CTRLBUS_ERR_IO (-6)

/* A short, constant, English name of an error code ("format", "unsupported", ...), or "unknown".
 * Returns a pointer to a string constant. ISR-safe. Cost: O(1). */
const char *ctrlbus_error_name(int32_t error);

/* The function CTRLBUS_CONFIG_CHECK() calls (ctrlbus/ctrlbus_config.h): the library defines it
 * under the name of the switches it was compiled with. Returns 0. ISR-safe. Cost: O(1). */
int32_t CTRLBUS_CONFIG_SYMBOL(void);

#ifdef __cplusplus
}
#endif

#endif
