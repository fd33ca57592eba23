/* SPDX-License-Identifier: MIT */
/* Fuzz target: the stream decoder (ctrlbus/frame.h) on arbitrary bytes, cut and timed at random.
 *
 * Input: three setting bytes, then the stream.
 *   byte 0  bits 0-2: the buffer, max_frame: 5, 6, 7, 16, 64, 255, 512 or 65539 bytes;
 *           bits 3-5: the inter-byte timeout: off, 1, 2, 5, 10, 20, 100 or 1000 ms;
 *           bits 6-7: how the stream is cut into feeds: 1-8, 1-64 or 1-600 bytes, or whole.
 *   bytes 1-2: the seed of the cuts, of the time between feeds (none, up to and past the timeout,
 *           rarely a jump the decoder takes for a clock that went backwards), of the ticks in
 *           between, and of the start time (anywhere: the clock wraps around).
 * Five decoders (the one decoder of frame.c, the one every build ships) take the same stream at
 * the same times and ticks, each through another entry point:
 *   A  fed in those cuts (ctrlbus_decoder_feed(), then next() until NONE). Every call is
 *      checked: guard regions around its buffer, every frame (inside the buffer, right checksum
 *      and length, at most max_frame), the feed/next contract (a feed stops early only with a
 *      result waiting), the counters, and that every byte taken is in a frame, discarded, or
 *      still buffered.
 *   C  fed one byte per call: the outcome must not depend on how the input is cut (§7.1).
 *   D  the byte path: ctrlbus_decoder_push() per byte, every result after it taken with next();
 *      a push while results wait must be refused (BUSY) and change nothing.
 *   G  the chunk path: ctrlbus_decoder_take() on each cut until it returns NONE; every frame
 *      checked where it lies (in the decoder's buffer, or in place in the cut), the cut used up
 *      exactly.
 *   L  mixed: each cut through feed, push or take, chosen by its position in the stream.
 * All must give A's results (frames and events, in order) and A's counters. */
#include <string.h>

#include "fuzz_common.h"

static const uint32_t BUFFER_SIZES[8] = {5, 6, 7, 16, 64, 255, 512, CTRLBUS_FRAME_MAX};
static const uint16_t TIMEOUTS[8] = {0, 1, 2, 5, 10, 20, 100, 1000};
static const uint32_t CUT_MAX[4] = {8, 64, 600, 0}; /* 0: the whole stream in one feed */

typedef struct {
    ctrlbus_decoder_t decoder;
    ctrlbus_decoder_stats_t stats;
    fuzz_guarded_t buffer;
    fuzz_log_t *log;
    uint64_t taken;       /* bytes the decoder took */
    uint64_t frame_bytes; /* bytes of the frames it handed out */
} run_t;

static fuzz_log_t log_a, log_c, log_d, log_g, log_l;
static uint32_t max_frame;

static uint64_t frame_size(const ctrlbus_frame_t *frame)
{
    return frame->payload_len + (frame->is_long ? CTRLBUS_LONG_OVERHEAD : CTRLBUS_STANDARD_OVERHEAD);
}

/* Every byte taken is in a handed-out frame, discarded, or still buffered (the partial candidate
 * between start and end: white-box, the decoder is ours). Only valid with nothing waiting. */
static void check_accounting(const run_t *r)
{
    fuzz_check_stats(&r->stats);
    FUZZ_CHECK(r->decoder.end >= r->decoder.start && r->decoder.end <= max_frame);
    FUZZ_CHECK(r->taken == r->frame_bytes + r->stats.bytes_discarded +
                               (r->decoder.end - r->decoder.start));
}

/* Takes every waiting result from A, checking each; returns how many. */
static size_t drain_checked(run_t *a)
{
    size_t results = 0;
    for (;;) {
        ctrlbus_frame_t frame;
        ctrlbus_rx_t rx = ctrlbus_decoder_next(&a->decoder, &frame);
        fuzz_guarded_check(&a->buffer);
        if (rx == CTRLBUS_RX_NONE) {
            break;
        }
        /* A result needs a byte, and a failed candidate leaves at most max_frame results. */
        FUZZ_CHECK(++results <= (size_t)max_frame + 2u);
        if (rx == CTRLBUS_RX_FRAME) {
            fuzz_check_frame(&frame, a->buffer.buffer, max_frame);
            a->frame_bytes += frame_size(&frame);
        } else {
            FUZZ_CHECK(rx >= CTRLBUS_RX_GARBAGE && rx <= CTRLBUS_RX_EMPTY_FRAME);
        }
        fuzz_log_add(a->log, rx, &frame);
    }
    check_accounting(a);
    return results;
}

static void feed_cut(run_t *a, const uint8_t *data, size_t len, uint32_t now)
{
    while (len > 0) {
        size_t used = ctrlbus_decoder_feed(&a->decoder, data, len, now);
        FUZZ_CHECK(used <= len);
        a->taken += used;
        size_t results = drain_checked(a);
        /* A feed stops early only when a result is waiting (and never spins). */
        FUZZ_CHECK(used == len || results > 0);
        data += used;
        len -= used;
    }
}

static void tick_checked(run_t *a, uint32_t now)
{
    ctrlbus_decoder_tick(&a->decoder, now);
    (void)drain_checked(a);
}

/* Decoder C: the same bytes one per call. */
static void drain_one(run_t *c)
{
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(&c->decoder, &frame)) != CTRLBUS_RX_NONE;) {
        if (rx == CTRLBUS_RX_FRAME) {
            fuzz_check_frame(&frame, c->buffer.buffer, max_frame);
            c->frame_bytes += frame_size(&frame);
        }
        fuzz_log_add(c->log, rx, &frame);
    }
    fuzz_guarded_check(&c->buffer);
}

static void feed_bytewise(run_t *c, const uint8_t *data, size_t len, uint32_t now)
{
    for (size_t i = 0; i < len;) {
        size_t used = ctrlbus_decoder_feed(&c->decoder, data + i, 1, now);
        FUZZ_CHECK(used <= 1);
        c->taken += used;
        i += used;
        drain_one(c);
    }
    check_accounting(c);
}

/* Decoder D: the same bytes through the byte API. White-box: frame.c's STATE_WAITING bits (a
 * result pending, a rescan due, a held byte). */
#define FRAME_C_STATE_WAITING 0x97u

static void push_bytewise(run_t *r, const uint8_t *data, size_t len, uint32_t now)
{
    for (size_t i = 0; i < len; i++) {
        ctrlbus_frame_t frame;
        size_t results = 0;
        for (ctrlbus_rx_t rx = ctrlbus_decoder_push(&r->decoder, data[i], now, &frame);
             rx != CTRLBUS_RX_NONE; rx = ctrlbus_decoder_next(&r->decoder, &frame)) {
            FUZZ_CHECK(rx >= CTRLBUS_RX_FRAME && rx <= CTRLBUS_RX_EMPTY_FRAME);
            FUZZ_CHECK(++results <= (size_t)max_frame + 2u);
            if (rx == CTRLBUS_RX_FRAME) {
                fuzz_check_frame(&frame, r->buffer.buffer, max_frame);
                r->frame_bytes += frame_size(&frame);
            }
            fuzz_log_add(r->log, rx, &frame);
            if (i + 1u < len && (r->decoder.state & FRAME_C_STATE_WAITING) && (data[i] & 1u)) {
                /* Pushing while results wait is refused and changes nothing. */
                ctrlbus_decoder_t before = r->decoder;
                ctrlbus_decoder_stats_t stats_before = r->stats;
                FUZZ_CHECK(ctrlbus_decoder_push(&r->decoder, data[i + 1u], now + 1u, NULL) ==
                           CTRLBUS_RX_BUSY);
                FUZZ_CHECK(memcmp(&before, &r->decoder, sizeof before) == 0);
                FUZZ_CHECK(memcmp(&stats_before, &r->stats, sizeof stats_before) == 0);
            }
        }
        r->taken++;
        fuzz_guarded_check(&r->buffer);
    }
    check_accounting(r);
}

/* Decoder G: one cut through take, until it returns NONE. */
static void take_cut(run_t *r, const uint8_t *data, size_t len, uint32_t now)
{
    const uint8_t *at = data;
    size_t left = len;
    size_t results = 0;
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_take(&r->decoder, &at, &left, now, &frame)) != CTRLBUS_RX_NONE;) {
        FUZZ_CHECK(rx >= CTRLBUS_RX_FRAME && rx <= CTRLBUS_RX_EMPTY_FRAME);
        FUZZ_CHECK(left <= len && at == data + (len - left));
        FUZZ_CHECK(++results <= len + (size_t)max_frame + 2u);
        if (rx == CTRLBUS_RX_FRAME) {
            uintptr_t payload = (uintptr_t)frame.payload;
            if (payload >= (uintptr_t)data && payload < (uintptr_t)data + len) {
                /* handed out in place: the whole frame lies in the cut */
                fuzz_check_frame(&frame, data, len);
                FUZZ_CHECK(frame_size(&frame) <= max_frame);
            } else {
                fuzz_check_frame(&frame, r->buffer.buffer, max_frame);
            }
            r->frame_bytes += frame_size(&frame);
        }
        fuzz_log_add(r->log, rx, &frame);
    }
    FUZZ_CHECK(left == 0 && at == data + len);
    r->taken += len;
    fuzz_guarded_check(&r->buffer);
    check_accounting(r);
}

/* L: each cut through feed, push or take, chosen by its position in the stream. */
static void mixed_cut(run_t *r, size_t pos, const uint8_t *data, size_t len, uint32_t now)
{
    switch ((uint32_t)(pos * 2654435761u) >> 30) {
    case 0: feed_cut(r, data, len, now); break;
    case 1: push_bytewise(r, data, len, now); break;
    default: take_cut(r, data, len, now); break;
    }
}

static void run_init(run_t *r, fuzz_log_t *log, uint16_t timeout)
{
    memset(&r->stats, 0, sizeof r->stats);
    fuzz_guarded_init(&r->buffer, max_frame);
    int32_t result = ctrlbus_decoder_init(&r->decoder, r->buffer.buffer, max_frame, timeout, &r->stats);
    FUZZ_CHECK(result == CTRLBUS_OK);
    r->log = log;
    r->taken = r->frame_bytes = 0;
    if (log != NULL) {
        fuzz_log_clear(log);
    }
}

/* A time step between feeds: mostly none or short, sometimes just at or past the timeout. */
static uint32_t time_step(fuzz_rng_t *rng, uint16_t timeout)
{
    switch (fuzz_rng_below(rng, 16)) {
    case 0: return 1;
    case 1: return timeout;
    case 2: return timeout + 1u;
    case 3: return 2u * timeout + 7u;
    case 4: return fuzz_rng_below(rng, 3u * timeout + 3u);
    case 5: return fuzz_rng_below(rng, 64) == 0 ? 0x80000000u + fuzz_rng_below(rng, 1000) : 0;
    default: return 0;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input_t in = {data, size};
    uint8_t settings = fuzz_u8(&in);
    fuzz_rng_t rng;
    fuzz_rng_seed(&rng, fuzz_u16(&in));
    max_frame = BUFFER_SIZES[settings & 7u];
    uint16_t timeout = TIMEOUTS[(settings >> 3) & 7u];
    uint32_t cut_max = CUT_MAX[settings >> 6];
    const uint8_t *stream = in.data;
    size_t stream_len = in.left;

    static run_t a, c, d, g, l;
    run_init(&a, &log_a, timeout);
    run_init(&c, &log_c, timeout);
    run_init(&d, &log_d, timeout);
    run_init(&g, &log_g, timeout);
    run_init(&l, &log_l, timeout);
    run_t *const others[] = {&c, &d, &g, &l};

    uint32_t now = fuzz_rng(&rng);
    for (size_t pos = 0; pos < stream_len;) {
        if (fuzz_rng_below(&rng, 4) == 0) {
            uint32_t tick_at = now + time_step(&rng, timeout);
            tick_checked(&a, tick_at);
            for (size_t k = 0; k < sizeof others / sizeof others[0]; k++) {
                ctrlbus_decoder_tick(&others[k]->decoder, tick_at);
                drain_one(others[k]);
            }
            now = tick_at;
        }
        now += time_step(&rng, timeout);
        size_t cut = stream_len - pos;
        if (cut_max != 0 && cut > 1) {
            size_t most = cut < cut_max ? cut : cut_max;
            cut = 1u + fuzz_rng_below(&rng, (uint32_t)most);
        }
        feed_cut(&a, stream + pos, cut, now);
        feed_bytewise(&c, stream + pos, cut, now);
        push_bytewise(&d, stream + pos, cut, now);
        take_cut(&g, stream + pos, cut, now);
        mixed_cut(&l, pos, stream + pos, cut, now);
        check_accounting(&l);
        pos += cut;
    }
    /* The line goes quiet: a partial frame left over times out. */
    uint32_t end = now + timeout + 1u;
    tick_checked(&a, end);
    FUZZ_CHECK(a.taken == stream_len);
    for (size_t k = 0; k < sizeof others / sizeof others[0]; k++) {
        run_t *r = others[k];
        ctrlbus_decoder_tick(&r->decoder, end);
        drain_one(r);
        FUZZ_CHECK(r->taken == stream_len);
        FUZZ_CHECK(fuzz_log_equal(&log_a, r->log));
        FUZZ_CHECK(memcmp(&a.stats, &r->stats, sizeof a.stats) == 0);
        /* After the final timeout nothing is left: every byte is in a frame or discarded. */
        FUZZ_CHECK(timeout == 0 || !ctrlbus_decoder_busy(&r->decoder));
    }
    if (timeout != 0) {
        FUZZ_CHECK(!ctrlbus_decoder_busy(&a.decoder));
        FUZZ_CHECK(a.taken == a.frame_bytes + a.stats.bytes_discarded);
    }
    return 0;
}
