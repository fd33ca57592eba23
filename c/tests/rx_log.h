/* SPDX-License-Identifier: MIT */
/* Test support: feeds a ctrlbus decoder the way an application would and records every result
 * (frames with a copy of their payload, events) in stream order, so runs can be compared. */
#ifndef CTRLBUS_TEST_RX_LOG_H
#define CTRLBUS_TEST_RX_LOG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/frame.h"

#define RX_LOG_ENTRIES 2048u
#define RX_LOG_POOL (1u << 18) /* room for several maximal long-frame payloads */

typedef struct {
    ctrlbus_rx_t rx;
    bool is_long;
    uint8_t cmd;
    size_t payload_offset; /* into the log's pool */
    size_t payload_len;
} rx_entry_t;

typedef struct {
    rx_entry_t entries[RX_LOG_ENTRIES];
    size_t count;
    uint8_t pool[RX_LOG_POOL];
    size_t pool_used;
    bool overflow; /* more results than fit: the log is incomplete */
    bool stalled;  /* the decoder took no byte and had no result: an API contract breach */
} rx_log_t;

void rx_log_clear(rx_log_t *log);

/* Appends one result (frame may be NULL for events). */
void rx_log_add(rx_log_t *log, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame);

/* Takes every waiting result from the decoder into the log. */
void rx_log_drain(rx_log_t *log, ctrlbus_decoder_t *decoder);

/* Feeds data at time now_ms in pieces of at most `piece` bytes (0 = all at once), draining after
 * every feed call as the documented loop does. */
void rx_log_feed(rx_log_t *log, ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                 uint32_t now_ms, size_t piece);

/* Ticks the decoder at now_ms and drains it. */
void rx_log_tick(rx_log_t *log, ctrlbus_decoder_t *decoder, uint32_t now_ms);

/* The payload bytes of entry i. */
const uint8_t *rx_log_payload(const rx_log_t *log, size_t i);

/* Whether two logs hold the same results in the same order. */
bool rx_log_equal(const rx_log_t *a, const rx_log_t *b);

/* Prints the log to stderr (for failure messages). */
void rx_log_print(const char *title, const rx_log_t *log);

#endif
