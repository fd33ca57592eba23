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
 * Three decoders take the same stream:
 *   A  frame.c's decoder, fed in those cuts. Every call is checked: guard regions around its
 *      buffer, every frame (inside the buffer, right checksum and length, at most max_frame), the
 *      feed/next contract (a feed stops early only with a result waiting), the counters, and that
 *      every byte taken is in a frame, discarded, or still buffered.
 *   B  the byte-path twin (frame_bytepath.h), fed the same cuts: every call must give what A's
 *      gave (bytes taken, results, frames, counters, busy).
 *   C  frame.c's decoder fed one byte per call at the same times: the same results and counters
 *      as A in the end, since the outcome must not depend on how the input is cut (§7.1).
 *   D  frame.c's decoder through the byte API, ctrlbus_decoder_push() per byte at the same times
 *      (its inline path and push_slow()), every result after it taken with next(): the same
 *      results and counters as A; and a push while results wait must be refused (BUSY) and change
 *      nothing (D runs in lockstep with K, below).
 *   E  the byte-path twin through its push, as D: the same again.
 *   F  the lean twin (frame_lean.c: level 2, the level size-optimised builds get), fed the same
 *      cuts as A: the same results and counters (in lockstep with J, below).
 *   G  frame.c's decoder through ctrlbus_decoder_take(), the same cuts, each taken until it returns
 *      NONE: the same results and counters as A; every frame checked where it lies (in the
 *      decoder's buffer, or in place in the cut), the cut used up exactly.
 *   H  the lean twin through its take, as G.
 *   I  the byte-path twin through its take (the general loop alone), as G.
 * And call by call, level 1 (frame.c as built here) against level 2 (the lean twin, its own
 * compact core), each pair taking the same cuts at the same times and ticks: every call must
 * return the same (result, frame; for feed, the bytes taken), with the same counters and busy after
 * it:
 *   F/J  feed and next;  D/K  push and next (K: the lean push);  G/H  take;
 *   L/M  mixed: each cut goes through feed, push or take, chosen by its position. */
#include <string.h>

#include "frame_bytepath.h"
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

static fuzz_log_t log_a, log_c, log_d, log_e, log_f, log_g, log_h, log_i, log_j, log_k, log_l,
    log_m;
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

static void check_same_frame(const ctrlbus_frame_t *a, const ctrlbus_frame_t *b)
{
    FUZZ_CHECK(a->is_long == b->is_long && a->cmd == b->cmd && a->payload_len == b->payload_len);
    FUZZ_CHECK(a->payload_len == 0 || memcmp(a->payload, b->payload, a->payload_len) == 0);
}

/* Takes every waiting result from A and B, which must agree; returns how many. */
static size_t drain_both(run_t *a, run_t *b)
{
    size_t results = 0;
    for (;;) {
        ctrlbus_frame_t fa;
        ctrlbus_frame_t fb;
        ctrlbus_rx_t ra = ctrlbus_decoder_next(&a->decoder, &fa);
        ctrlbus_rx_t rb = bytepath_decoder_next(&b->decoder, &fb);
        fuzz_guarded_check(&a->buffer);
        fuzz_guarded_check(&b->buffer);
        FUZZ_CHECK(ra == rb);
        if (ra == CTRLBUS_RX_NONE) {
            break;
        }
        /* A result needs a byte, and a failed candidate leaves at most max_frame results. */
        FUZZ_CHECK(++results <= (size_t)max_frame + 2u);
        if (ra == CTRLBUS_RX_FRAME) {
            fuzz_check_frame(&fa, a->buffer.buffer, max_frame);
            fuzz_check_frame(&fb, b->buffer.buffer, max_frame);
            check_same_frame(&fa, &fb);
            a->frame_bytes += frame_size(&fa);
            b->frame_bytes += frame_size(&fb);
        } else {
            FUZZ_CHECK(ra >= CTRLBUS_RX_GARBAGE && ra <= CTRLBUS_RX_EMPTY_FRAME);
        }
        fuzz_log_add(a->log, ra, &fa);
    }
    FUZZ_CHECK(memcmp(&a->stats, &b->stats, sizeof a->stats) == 0);
    FUZZ_CHECK(ctrlbus_decoder_busy(&a->decoder) == bytepath_decoder_busy(&b->decoder));
    check_accounting(a);
    return results;
}

static void feed_both(run_t *a, run_t *b, const uint8_t *data, size_t len, uint32_t now)
{
    while (len > 0) {
        size_t used_a = ctrlbus_decoder_feed(&a->decoder, data, len, now);
        size_t used_b = bytepath_decoder_feed(&b->decoder, data, len, now);
        FUZZ_CHECK(used_a == used_b && used_a <= len);
        a->taken += used_a;
        b->taken += used_b;
        size_t results = drain_both(a, b);
        /* A feed stops early only when a result is waiting (and never spins). */
        FUZZ_CHECK(used_a == len || results > 0);
        data += used_a;
        len -= used_a;
    }
}

static void tick_both(run_t *a, run_t *b, uint32_t now)
{
    ctrlbus_decoder_tick(&a->decoder, now);
    bytepath_decoder_tick(&b->decoder, now);
    (void)drain_both(a, b);
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

/* Decoders D and E: the same bytes through the byte API. White-box: frame.c's STATE_WAITING bits
 * (a result pending, a rescan due, a held byte). */
#define FRAME_C_STATE_WAITING 0x97u

typedef ctrlbus_rx_t (*push_fn)(ctrlbus_decoder_t *, uint8_t, uint32_t, ctrlbus_frame_t *);
typedef ctrlbus_rx_t (*next_fn)(ctrlbus_decoder_t *, ctrlbus_frame_t *);

static void drain_with(run_t *r, next_fn next)
{
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = next(&r->decoder, &frame)) != CTRLBUS_RX_NONE;) {
        if (rx == CTRLBUS_RX_FRAME) {
            fuzz_check_frame(&frame, r->buffer.buffer, max_frame);
            r->frame_bytes += frame_size(&frame);
        }
        fuzz_log_add(r->log, rx, &frame);
    }
    fuzz_guarded_check(&r->buffer);
}

typedef size_t (*feed_fn)(ctrlbus_decoder_t *, const uint8_t *, size_t, uint32_t);

static ctrlbus_rx_t push_ours(ctrlbus_decoder_t *d, uint8_t byte, uint32_t now, ctrlbus_frame_t *f)
{
    return ctrlbus_decoder_push(d, byte, now, f);
}

static void push_bytewise(run_t *r, push_fn push, next_fn next, const uint8_t *data, size_t len,
                          uint32_t now)
{
    for (size_t i = 0; i < len; i++) {
        ctrlbus_frame_t frame;
        size_t results = 0;
        for (ctrlbus_rx_t rx = push(&r->decoder, data[i], now, &frame); rx != CTRLBUS_RX_NONE;
             rx = next(&r->decoder, &frame)) {
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
                FUZZ_CHECK(push(&r->decoder, data[i + 1u], now + 1u, NULL) == CTRLBUS_RX_BUSY);
                FUZZ_CHECK(memcmp(&before, &r->decoder, sizeof before) == 0);
                FUZZ_CHECK(memcmp(&stats_before, &r->stats, sizeof stats_before) == 0);
            }
        }
        r->taken++;
        fuzz_guarded_check(&r->buffer);
    }
    check_accounting(r);
}

typedef ctrlbus_rx_t (*take_fn)(ctrlbus_decoder_t *, const uint8_t **, size_t *, uint32_t,
                                ctrlbus_frame_t *);

static ctrlbus_rx_t take_ours(ctrlbus_decoder_t *d, const uint8_t **data, size_t *len, uint32_t now,
                              ctrlbus_frame_t *f)
{
    return ctrlbus_decoder_take(d, data, len, now, f);
}

/* Decoders G and H: one cut through take, until it returns NONE. */
static void take_cut(run_t *r, take_fn take, const uint8_t *data, size_t len, uint32_t now)
{
    const uint8_t *at = data;
    size_t left = len;
    size_t results = 0;
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = take(&r->decoder, &at, &left, now, &frame)) != CTRLBUS_RX_NONE;) {
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

typedef int32_t (*init_fn)(ctrlbus_decoder_t *, uint8_t *, size_t, uint16_t,
                          ctrlbus_decoder_stats_t *);
typedef void (*tick_fn)(ctrlbus_decoder_t *, uint32_t);
typedef bool (*busy_fn)(const ctrlbus_decoder_t *);

/* One level's API, for the lockstep pairs. */
typedef struct {
    feed_fn feed;
    next_fn next;
    push_fn push;
    take_fn take;
    tick_fn tick;
    busy_fn busy;
} api_t;

static const api_t LEVEL_1 = {ctrlbus_decoder_feed, ctrlbus_decoder_next, push_ours,
                              take_ours,            ctrlbus_decoder_tick, ctrlbus_decoder_busy};
static const api_t LEVEL_2 = {lean_decoder_feed, lean_decoder_next, lean_decoder_push,
                              lean_decoder_take, lean_decoder_tick, lean_decoder_busy};

/* One result of each of a lockstep pair (x at level 1, y at level 2): they must be the same. A
 * frame lies in its decoder's buffer or, from take, in place in the cut data[0..len). */
static void pair_result(run_t *x, run_t *y, ctrlbus_rx_t rx, ctrlbus_rx_t ry,
                        const ctrlbus_frame_t *fx, const ctrlbus_frame_t *fy, const uint8_t *data,
                        size_t len)
{
    FUZZ_CHECK(rx == ry);
    FUZZ_CHECK(rx >= CTRLBUS_RX_FRAME && rx <= CTRLBUS_RX_EMPTY_FRAME);
    if (rx == CTRLBUS_RX_FRAME) {
        const ctrlbus_frame_t *frames[2] = {fx, fy};
        run_t *runs[2] = {x, y};
        for (unsigned k = 0; k < 2u; k++) {
            uintptr_t payload = (uintptr_t)frames[k]->payload;
            if (data != NULL && payload >= (uintptr_t)data && payload < (uintptr_t)data + len) {
                fuzz_check_frame(frames[k], data, len);
                FUZZ_CHECK(frame_size(frames[k]) <= max_frame);
            } else {
                fuzz_check_frame(frames[k], runs[k]->buffer.buffer, max_frame);
            }
            runs[k]->frame_bytes += frame_size(frames[k]);
        }
        check_same_frame(fx, fy);
    }
    fuzz_log_add(x->log, rx, fx);
    fuzz_log_add(y->log, ry, fy);
}

/* After every call of a pair: the same counters and busy, and the buffers' guards intact. */
static void pair_state(const run_t *x, const run_t *y)
{
    fuzz_guarded_check(&x->buffer);
    fuzz_guarded_check(&y->buffer);
    FUZZ_CHECK(memcmp(&x->stats, &y->stats, sizeof x->stats) == 0);
    FUZZ_CHECK(LEVEL_1.busy(&x->decoder) == LEVEL_2.busy(&y->decoder));
}

/* next() on both until NONE, call by call. */
static void pair_drain(run_t *x, run_t *y, const uint8_t *data, size_t len)
{
    for (size_t results = 0;; results++) {
        ctrlbus_frame_t fx;
        ctrlbus_frame_t fy;
        ctrlbus_rx_t rx = LEVEL_1.next(&x->decoder, &fx);
        ctrlbus_rx_t ry = LEVEL_2.next(&y->decoder, &fy);
        FUZZ_CHECK(rx == ry);
        pair_state(x, y);
        if (rx == CTRLBUS_RX_NONE) {
            break;
        }
        FUZZ_CHECK(results <= len + (size_t)max_frame + 2u);
        pair_result(x, y, rx, ry, &fx, &fy, data, len);
    }
}

static void pair_feed(run_t *x, run_t *y, const uint8_t *data, size_t len, uint32_t now)
{
    while (len > 0) {
        size_t ux = LEVEL_1.feed(&x->decoder, data, len, now);
        size_t uy = LEVEL_2.feed(&y->decoder, data, len, now);
        FUZZ_CHECK(ux == uy && ux <= len);
        pair_state(x, y);
        x->taken += ux;
        y->taken += uy;
        data += ux;
        len -= ux;
        pair_drain(x, y, NULL, 0);
    }
}

static void pair_push(run_t *x, run_t *y, const uint8_t *data, size_t len, uint32_t now)
{
    for (size_t i = 0; i < len; i++) {
        ctrlbus_frame_t fx;
        ctrlbus_frame_t fy;
        ctrlbus_rx_t rx = LEVEL_1.push(&x->decoder, data[i], now, &fx);
        ctrlbus_rx_t ry = LEVEL_2.push(&y->decoder, data[i], now, &fy);
        FUZZ_CHECK(rx == ry);
        pair_state(x, y);
        if (rx != CTRLBUS_RX_NONE) {
            pair_result(x, y, rx, ry, &fx, &fy, NULL, 0);
            if (i + 1u < len && (data[i] & 1u) && (x->decoder.state & FRAME_C_STATE_WAITING) &&
                (y->decoder.state & FRAME_C_STATE_WAITING)) {
                /* both refuse a byte while results wait, changing nothing (whether more results
                 * may wait before next() says NONE is each core's own business) */
                ctrlbus_decoder_t before_x = x->decoder;
                ctrlbus_decoder_t before_y = y->decoder;
                FUZZ_CHECK(LEVEL_1.push(&x->decoder, data[i + 1u], now + 1u, NULL) ==
                           CTRLBUS_RX_BUSY);
                FUZZ_CHECK(LEVEL_2.push(&y->decoder, data[i + 1u], now + 1u, NULL) ==
                           CTRLBUS_RX_BUSY);
                FUZZ_CHECK(memcmp(&before_x, &x->decoder, sizeof before_x) == 0);
                FUZZ_CHECK(memcmp(&before_y, &y->decoder, sizeof before_y) == 0);
                pair_state(x, y);
            }
            pair_drain(x, y, NULL, 0);
        }
        x->taken++;
        y->taken++;
    }
}

static void pair_take(run_t *x, run_t *y, const uint8_t *data, size_t len, uint32_t now)
{
    const uint8_t *at_x = data;
    const uint8_t *at_y = data;
    size_t left_x = len;
    size_t left_y = len;
    for (size_t results = 0;; results++) {
        ctrlbus_frame_t fx;
        ctrlbus_frame_t fy;
        ctrlbus_rx_t rx = LEVEL_1.take(&x->decoder, &at_x, &left_x, now, &fx);
        ctrlbus_rx_t ry = LEVEL_2.take(&y->decoder, &at_y, &left_y, now, &fy);
        /* The same result; how many bytes a call takes before it returns one may differ (level 1
         * steps over a whole garbage run with its event, level 2 over the event's byte only), and
         * with them the counters, until the input is used up. */
        FUZZ_CHECK(rx == ry);
        FUZZ_CHECK(left_x <= len && at_x == data + (len - left_x));
        FUZZ_CHECK(left_y <= len && at_y == data + (len - left_y));
        fuzz_guarded_check(&x->buffer);
        fuzz_guarded_check(&y->buffer);
        if (rx == CTRLBUS_RX_NONE) {
            pair_state(x, y);
            break;
        }
        FUZZ_CHECK(results <= len + (size_t)max_frame + 2u);
        pair_result(x, y, rx, ry, &fx, &fy, data, len);
    }
    FUZZ_CHECK(left_x == 0 && left_y == 0);
    x->taken += len;
    y->taken += len;
}

static void pair_tick(run_t *x, run_t *y, uint32_t now)
{
    LEVEL_1.tick(&x->decoder, now);
    LEVEL_2.tick(&y->decoder, now);
    pair_state(x, y);
    pair_drain(x, y, NULL, 0);
}

/* The end of a cut: every byte accounted for in both. */
static void pair_done(const run_t *x, const run_t *y)
{
    check_accounting(x);
    check_accounting(y);
}

/* L/M: each cut through feed, push or take, chosen by its position in the stream. */
static void pair_mixed(run_t *x, run_t *y, size_t pos, const uint8_t *data, size_t len,
                       uint32_t now)
{
    switch ((uint32_t)(pos * 2654435761u) >> 30) {
    case 0: pair_feed(x, y, data, len, now); break;
    case 1: pair_push(x, y, data, len, now); break;
    default: pair_take(x, y, data, len, now); break;
    }
}

static void run_init(run_t *r, fuzz_log_t *log, uint16_t timeout, init_fn init)
{
    memset(&r->stats, 0, sizeof r->stats);
    fuzz_guarded_init(&r->buffer, max_frame);
    int32_t result = init(&r->decoder, r->buffer.buffer, max_frame, timeout, &r->stats);
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

    static run_t a, b, c, d, e, f, g, h, i, j, k, l, m;
    run_init(&a, &log_a, timeout, ctrlbus_decoder_init);
    run_init(&b, NULL, timeout, bytepath_decoder_init); /* compared with A call by call */
    run_init(&c, &log_c, timeout, ctrlbus_decoder_init);
    run_init(&d, &log_d, timeout, ctrlbus_decoder_init);
    run_init(&e, &log_e, timeout, bytepath_decoder_init);
    run_init(&f, &log_f, timeout, lean_decoder_init);
    run_init(&g, &log_g, timeout, ctrlbus_decoder_init);
    run_init(&h, &log_h, timeout, lean_decoder_init);
    run_init(&i, &log_i, timeout, bytepath_decoder_init);
    run_init(&j, &log_j, timeout, ctrlbus_decoder_init);
    run_init(&k, &log_k, timeout, lean_decoder_init);
    run_init(&l, &log_l, timeout, ctrlbus_decoder_init);
    run_init(&m, &log_m, timeout, lean_decoder_init);

    uint32_t now = fuzz_rng(&rng);
    for (size_t pos = 0; pos < stream_len;) {
        if (fuzz_rng_below(&rng, 4) == 0) {
            uint32_t tick_at = now + time_step(&rng, timeout);
            tick_both(&a, &b, tick_at);
            ctrlbus_decoder_tick(&c.decoder, tick_at);
            drain_one(&c);
            pair_tick(&d, &k, tick_at);
            bytepath_decoder_tick(&e.decoder, tick_at);
            drain_with(&e, bytepath_decoder_next);
            pair_tick(&j, &f, tick_at);
            pair_tick(&g, &h, tick_at);
            pair_tick(&l, &m, tick_at);
            bytepath_decoder_tick(&i.decoder, tick_at);
            drain_with(&i, bytepath_decoder_next);
            now = tick_at;
        }
        now += time_step(&rng, timeout);
        size_t cut = stream_len - pos;
        if (cut_max != 0 && cut > 1) {
            size_t most = cut < cut_max ? cut : cut_max;
            cut = 1u + fuzz_rng_below(&rng, (uint32_t)most);
        }
        feed_both(&a, &b, stream + pos, cut, now);
        feed_bytewise(&c, stream + pos, cut, now);
        pair_push(&d, &k, stream + pos, cut, now);
        pair_done(&d, &k);
        push_bytewise(&e, bytepath_decoder_push, bytepath_decoder_next, stream + pos, cut, now);
        pair_feed(&j, &f, stream + pos, cut, now);
        pair_done(&j, &f);
        pair_take(&g, &h, stream + pos, cut, now);
        pair_done(&g, &h);
        pair_mixed(&l, &m, pos, stream + pos, cut, now);
        pair_done(&l, &m);
        take_cut(&i, bytepath_decoder_take, stream + pos, cut, now);
        pos += cut;
    }
    /* The line goes quiet: a partial frame left over times out. */
    uint32_t end = now + timeout + 1u;
    tick_both(&a, &b, end);
    ctrlbus_decoder_tick(&c.decoder, end);
    drain_one(&c);
    pair_tick(&d, &k, end);
    bytepath_decoder_tick(&e.decoder, end);
    drain_with(&e, bytepath_decoder_next);
    pair_tick(&j, &f, end);
    pair_tick(&g, &h, end);
    pair_tick(&l, &m, end);
    bytepath_decoder_tick(&i.decoder, end);
    drain_with(&i, bytepath_decoder_next);

    FUZZ_CHECK(a.taken == stream_len && c.taken == stream_len);
    FUZZ_CHECK(d.taken == stream_len && e.taken == stream_len && f.taken == stream_len);
    FUZZ_CHECK(g.taken == stream_len && h.taken == stream_len && i.taken == stream_len);
    FUZZ_CHECK(j.taken == stream_len && k.taken == stream_len && l.taken == stream_len &&
               m.taken == stream_len);
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_c));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_d));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_e));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_f));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_g));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_h));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_i));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_j) && fuzz_log_equal(&log_a, &log_k));
    FUZZ_CHECK(fuzz_log_equal(&log_a, &log_l) && fuzz_log_equal(&log_a, &log_m));
    FUZZ_CHECK(memcmp(&a.stats, &c.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &d.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &e.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &f.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &g.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &h.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &i.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &j.stats, sizeof a.stats) == 0);
    FUZZ_CHECK(memcmp(&a.stats, &l.stats, sizeof a.stats) == 0);
    if (timeout != 0) {
        /* After the final timeout nothing is left: every byte is in a frame or discarded. */
        FUZZ_CHECK(!ctrlbus_decoder_busy(&a.decoder) && !ctrlbus_decoder_busy(&c.decoder));
        FUZZ_CHECK(!ctrlbus_decoder_busy(&d.decoder) && !bytepath_decoder_busy(&e.decoder));
        FUZZ_CHECK(!lean_decoder_busy(&f.decoder) && !ctrlbus_decoder_busy(&g.decoder));
        FUZZ_CHECK(!lean_decoder_busy(&h.decoder) && !bytepath_decoder_busy(&i.decoder));
        FUZZ_CHECK(!ctrlbus_decoder_busy(&j.decoder) && !lean_decoder_busy(&k.decoder));
        FUZZ_CHECK(!ctrlbus_decoder_busy(&l.decoder) && !lean_decoder_busy(&m.decoder));
        FUZZ_CHECK(a.taken == a.frame_bytes + a.stats.bytes_discarded);
    }
    return 0;
}
