/* SPDX-License-Identifier: MIT */
/* The decoder of frame.c built once more without its bulk path (CTRLBUS_DECODER_FAST 0) and under
 * other names, so that a fuzz target can run both side by side and require the same results from
 * them. At level 0 frame.c has a core of its own (the smallest: a waiting candidate kept at the
 * buffer's front, a candidate's checksum taken once), written apart from the byte path that the
 * bulk path builds on (level 1): two implementations of the same rules that must not differ in a thing. Same
 * types and contracts as ctrlbus/frame.h.
 * The lean_ twin is frame.c at CTRLBUS_DECODER_FAST 2, the level size-optimised builds get: the
 * level-0 core with the fast steps of its own (push's header and last byte, feed's runs, take's
 * in-place frame), which fuzz_decoder.c compares with level 1 call by call. */
#ifndef CTRLBUS_FUZZ_FRAME_BYTEPATH_H
#define CTRLBUS_FUZZ_FRAME_BYTEPATH_H

#include "ctrlbus/frame.h"

int32_t bytepath_decoder_init(ctrlbus_decoder_t *decoder, uint8_t *buffer, size_t buffer_size,
                              uint16_t timeout_ms, ctrlbus_decoder_stats_t *stats);
size_t bytepath_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                             uint32_t now_ms);
void bytepath_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms);
ctrlbus_rx_t bytepath_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame);
ctrlbus_rx_t bytepath_decoder_push(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                   ctrlbus_frame_t *frame);
bool bytepath_decoder_busy(const ctrlbus_decoder_t *decoder);
ctrlbus_rx_t bytepath_decoder_take(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                                   uint32_t now_ms, ctrlbus_frame_t *frame);


int32_t lean_decoder_init(ctrlbus_decoder_t *decoder, uint8_t *buffer, size_t buffer_size,
                          uint16_t timeout_ms, ctrlbus_decoder_stats_t *stats);
size_t lean_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                         uint32_t now_ms);
void lean_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms);
ctrlbus_rx_t lean_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame);
bool lean_decoder_busy(const ctrlbus_decoder_t *decoder);
ctrlbus_rx_t lean_decoder_take(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                               uint32_t now_ms, ctrlbus_frame_t *frame);
ctrlbus_rx_t lean_decoder_push(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                               ctrlbus_frame_t *frame);

#endif
