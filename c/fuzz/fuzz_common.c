/* SPDX-License-Identifier: MIT */
/* Shared support of the ctrlbus fuzz targets (see fuzz_common.h). */
#include "fuzz_common.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define FUZZ_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define FUZZ_ASAN 1
#endif
#ifdef FUZZ_ASAN
#include <sanitizer/asan_interface.h>
#define POISON(addr, size) ASAN_POISON_MEMORY_REGION((addr), (size))
#define UNPOISON(addr, size) ASAN_UNPOISON_MEMORY_REGION((addr), (size))
#else
#define POISON(addr, size) ((void)(addr), (void)(size))
#define UNPOISON(addr, size) ((void)(addr), (void)(size))
#endif

#define GUARD_PATTERN 0xA5u

void fuzz_fail(const char *file, int line, const char *what)
{
    fprintf(stderr, "%s:%d: fuzz invariant broken: %s\n", file, line, what);
    abort();
}

uint8_t fuzz_u8(fuzz_input_t *in)
{
    if (in->left == 0) {
        return 0;
    }
    in->left--;
    return *in->data++;
}

uint16_t fuzz_u16(fuzz_input_t *in)
{
    uint16_t low = fuzz_u8(in);
    return (uint16_t)(low | (uint16_t)(fuzz_u8(in) << 8));
}

void fuzz_rng_seed(fuzz_rng_t *rng, uint32_t seed)
{
    rng->state = seed * 2654435761u + 0x9E3779B9u;
    if (rng->state == 0) {
        rng->state = 1;
    }
}

uint32_t fuzz_rng(fuzz_rng_t *rng)
{
    uint32_t x = rng->state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    rng->state = x;
    return x;
}

uint32_t fuzz_rng_below(fuzz_rng_t *rng, uint32_t n)
{
    return fuzz_rng(rng) % n;
}

void fuzz_guarded_init(fuzz_guarded_t *g, size_t size)
{
    FUZZ_CHECK(size <= CTRLBUS_FRAME_MAX);
    UNPOISON(g->block, sizeof g->block); /* the guards of the previous run */
    g->buffer = g->block + FUZZ_GUARD;
    g->size = size;
    memset(g->block, GUARD_PATTERN, FUZZ_GUARD);
    memset(g->buffer + size, GUARD_PATTERN, FUZZ_GUARD);
    POISON(g->block, FUZZ_GUARD);
    POISON(g->buffer + size, FUZZ_GUARD);
}

void fuzz_guarded_check(const fuzz_guarded_t *g)
{
#ifdef FUZZ_ASAN
    (void)g; /* poisoned: AddressSanitizer has already reported any access to the guards */
#else
    for (size_t i = 0; i < FUZZ_GUARD; i++) {
        FUZZ_CHECK(g->block[i] == GUARD_PATTERN);
        FUZZ_CHECK(g->buffer[g->size + i] == GUARD_PATTERN);
    }
#endif
}

void fuzz_check_frame(const ctrlbus_frame_t *frame, const uint8_t *buffer, size_t max_frame)
{
    size_t header = frame->is_long ? 3u : 2u;
    size_t size = header + 1u + frame->payload_len + 1u;
    FUZZ_CHECK(frame->payload_len <= CTRLBUS_LONG_PAYLOAD_MAX);
    FUZZ_CHECK(frame->is_long || frame->payload_len <= CTRLBUS_STANDARD_PAYLOAD_MAX);
    FUZZ_CHECK(size <= max_frame);
    /* Compared as addresses, so that a payload pointer outside the buffer is reported rather
     * than compared (undefined behaviour). */
    uintptr_t start = (uintptr_t)buffer;
    uintptr_t payload = (uintptr_t)frame->payload;
    FUZZ_CHECK(payload >= start + header + 1u);
    size_t first = (size_t)(payload - start) - header - 1u;
    FUZZ_CHECK(first + size <= max_frame);
    const uint8_t *bytes = buffer + first;
    FUZZ_CHECK(bytes[0] == (frame->is_long ? CTRLBUS_FLAG_LONG : CTRLBUS_FLAG_STANDARD));
    size_t len_field = bytes[1];
    if (frame->is_long) {
        len_field |= (size_t)bytes[2] << 8;
    }
    FUZZ_CHECK(len_field == frame->payload_len + 1u);
    FUZZ_CHECK(bytes[header] == frame->cmd);
    uint8_t x = 0;
    for (size_t i = 0; i < size; i++) {
        x ^= bytes[i];
    }
    FUZZ_CHECK(x == 0);
}

void fuzz_check_stats(const ctrlbus_decoder_stats_t *stats)
{
    FUZZ_CHECK(stats->resyncs == stats->checksum_errors + stats->oversize + stats->timeouts);
    /* Every failed candidate discards at least its flag byte, every empty frame 3 bytes. */
    FUZZ_CHECK(stats->bytes_discarded >= stats->resyncs + 3u * stats->empty_frames);
}

void fuzz_log_clear(fuzz_log_t *log)
{
    log->count = 0;
    log->overflow = false;
}

void fuzz_log_add(fuzz_log_t *log, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame)
{
    if (log->count + 2u > FUZZ_LOG_MAX) {
        log->overflow = true;
        return;
    }
    uint32_t kind = (uint32_t)rx;
    uint32_t hash = 2166136261u; /* FNV-1a over the payload */
    if (rx == CTRLBUS_RX_FRAME) {
        kind |= (frame->is_long ? 1u : 0u) << 4 | (uint32_t)frame->cmd << 8 |
                (uint32_t)frame->payload_len << 16;
        for (size_t i = 0; i < frame->payload_len; i++) {
            hash = (hash ^ frame->payload[i]) * 16777619u;
        }
    }
    log->entries[log->count++] = kind;
    log->entries[log->count++] = hash;
}

bool fuzz_log_equal(const fuzz_log_t *a, const fuzz_log_t *b)
{
    return a->overflow == b->overflow && a->count == b->count &&
           memcmp(a->entries, b->entries, a->count * sizeof a->entries[0]) == 0;
}
