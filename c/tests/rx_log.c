/* SPDX-License-Identifier: MIT */
/* Test support: decoder result recorder (see rx_log.h). */
#include "rx_log.h"

#include <stdio.h>
#include <string.h>

void rx_log_clear(rx_log_t *log)
{
    log->count = 0;
    log->pool_used = 0;
    log->overflow = false;
    log->stalled = false;
}

void rx_log_add(rx_log_t *log, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame)
{
    if (log->count == RX_LOG_ENTRIES) {
        log->overflow = true;
        return;
    }
    rx_entry_t *entry = &log->entries[log->count++];
    memset(entry, 0, sizeof *entry);
    entry->rx = rx;
    if (rx != CTRLBUS_RX_FRAME) {
        return;
    }
    entry->is_long = frame->is_long;
    entry->cmd = frame->cmd;
    entry->payload_offset = log->pool_used;
    entry->payload_len = frame->payload_len;
    if (frame->payload_len > RX_LOG_POOL - log->pool_used) {
        log->overflow = true;
        entry->payload_len = 0;
        return;
    }
    memcpy(log->pool + log->pool_used, frame->payload, frame->payload_len);
    log->pool_used += frame->payload_len;
}

void rx_log_drain(rx_log_t *log, ctrlbus_decoder_t *decoder)
{
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(decoder, &frame)) != CTRLBUS_RX_NONE;) {
        rx_log_add(log, rx, &frame);
    }
}

void rx_log_feed(rx_log_t *log, ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                 uint32_t now_ms, size_t piece)
{
    while (len > 0) {
        size_t offered = piece == 0 || piece > len ? len : piece;
        size_t used = ctrlbus_decoder_feed(decoder, data, offered, now_ms);
        size_t before = log->count;
        bool overflow_before = log->overflow;
        if (used > offered) {
            log->stalled = true;
            return;
        }
        data += used;
        len -= used;
        rx_log_drain(log, decoder);
        /* Taking nothing is allowed only when it stopped for a result (which was drained). */
        if (used == 0 && log->count == before && log->overflow == overflow_before) {
            log->stalled = true;
            return;
        }
    }
}

void rx_log_tick(rx_log_t *log, ctrlbus_decoder_t *decoder, uint32_t now_ms)
{
    ctrlbus_decoder_tick(decoder, now_ms);
    rx_log_drain(log, decoder);
}

const uint8_t *rx_log_payload(const rx_log_t *log, size_t i)
{
    return log->pool + log->entries[i].payload_offset;
}

bool rx_log_equal(const rx_log_t *a, const rx_log_t *b)
{
    if (a->count != b->count || a->overflow || b->overflow) {
        return false;
    }
    for (size_t i = 0; i < a->count; i++) {
        const rx_entry_t *x = &a->entries[i];
        const rx_entry_t *y = &b->entries[i];
        if (x->rx != y->rx || x->is_long != y->is_long || x->cmd != y->cmd ||
            x->payload_len != y->payload_len ||
            memcmp(rx_log_payload(a, i), rx_log_payload(b, i), x->payload_len) != 0) {
            return false;
        }
    }
    return true;
}

void rx_log_print(const char *title, const rx_log_t *log)
{
    fprintf(stderr, "  %s (%zu results%s%s):\n", title, log->count,
            log->overflow ? ", OVERFLOW" : "", log->stalled ? ", STALLED" : "");
    for (size_t i = 0; i < log->count && i < 40; i++) {
        const rx_entry_t *e = &log->entries[i];
        if (e->rx == CTRLBUS_RX_FRAME) {
            fprintf(stderr, "    frame %s cmd=0x%02X payload=", e->is_long ? "long" : "std",
                    e->cmd);
            const uint8_t *p = rx_log_payload(log, i);
            for (size_t k = 0; k < e->payload_len && k < 24; k++) {
                fprintf(stderr, "%02X ", p[k]);
            }
            if (e->payload_len > 24) {
                fprintf(stderr, "... (%zu)", e->payload_len);
            }
            fputc('\n', stderr);
        } else {
            fprintf(stderr, "    %s\n", ctrlbus_rx_name(e->rx));
        }
    }
}
