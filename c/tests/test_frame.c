/* SPDX-License-Identifier: MIT */
/* Unit tests of the frame layer: encoder sink, whole-frame encoding, and the stream decoder. */
#include <stdio.h>
#include <string.h>

#include "ctrlbus/frame.h"
#include "harness.h"
#include "rx_log.h"

/* ---- helpers -------------------------------------------------------------------------------- */

static rx_log_t log_a;
static rx_log_t log_b;
static uint8_t big_buffer[CTRLBUS_FRAME_MAX + 1000];
static uint8_t big_frame[CTRLBUS_FRAME_MAX];

/* A decoder over the first buffer_size bytes of a larger array; the rest holds a canary that the
 * decoder must never touch. */
#define CANARY 0xC5u

typedef struct {
    uint8_t buffer[1024];
    size_t buffer_size;
    ctrlbus_decoder_t decoder;
    ctrlbus_decoder_stats_t stats;
} fixture_t;

static void fixture_init(fixture_t *f, size_t buffer_size, uint16_t timeout_ms)
{
    memset(f->buffer, CANARY, sizeof f->buffer);
    f->buffer_size = buffer_size;
    CHECK_EQ(ctrlbus_decoder_init(&f->decoder, f->buffer, buffer_size, timeout_ms, &f->stats),
             CTRLBUS_OK);
}

static bool fixture_canary_intact(const fixture_t *f)
{
    for (size_t i = f->buffer_size; i < sizeof f->buffer; i++) {
        if (f->buffer[i] != CANARY) {
            return false;
        }
    }
    return true;
}

/* Feeds hex text at now_ms and appends the results to log_a. */
static void feed_hex(fixture_t *f, const char *hex, uint32_t now_ms)
{
    uint8_t data[512];
    size_t len = harness_unhex(data, sizeof data, hex);
    rx_log_feed(&log_a, &f->decoder, data, len, now_ms, 0);
    CHECK(!log_a.stalled);
}

/* Checks that log_a holds exactly the results described: "garbage", "frame:F8:30",
 * "frame-long:02:", ... separated by commas; "" for none. */
static void expect_results(const char *expected)
{
    char actual[2048] = "";
    size_t at = 0;
    for (size_t i = 0; i < log_a.count; i++) {
        const rx_entry_t *e = &log_a.entries[i];
        if (i > 0) {
            actual[at++] = ',';
        }
        if (e->rx == CTRLBUS_RX_FRAME) {
            at += (size_t)snprintf(actual + at, sizeof actual - at, "%s:%02X:",
                                   e->is_long ? "frame-long" : "frame", e->cmd);
            harness_hex(actual + at, rx_log_payload(&log_a, i), e->payload_len);
            at = strlen(actual);
        } else {
            at += (size_t)snprintf(actual + at, sizeof actual - at, "%s", ctrlbus_rx_name(e->rx));
        }
    }
    CHECK_STR(actual, expected);
}

/* Pushes len bytes one ctrlbus_decoder_push() each, stamped now_ms, taking every result after a
 * push with ctrlbus_decoder_next() (the header's loop); appends them to log. */
static void push_bytes(rx_log_t *log, ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                       uint32_t now_ms)
{
    for (size_t i = 0; i < len; i++) {
        ctrlbus_frame_t frame;
        for (ctrlbus_rx_t rx = ctrlbus_decoder_push(decoder, data[i], now_ms, &frame);
             rx != CTRLBUS_RX_NONE; rx = ctrlbus_decoder_next(decoder, &frame)) {
            if (!CHECK(rx != CTRLBUS_RX_BUSY)) {
                return;
            }
            rx_log_add(log, rx, &frame);
        }
    }
}

static void push_hex(fixture_t *f, const char *hex, uint32_t now_ms)
{
    uint8_t data[512];
    size_t len = harness_unhex(data, sizeof data, hex);
    push_bytes(&log_a, &f->decoder, data, len, now_ms);
}

/* Takes len bytes through ctrlbus_decoder_take() in pieces of `piece` bytes (0: whole), each
 * until it returns CTRLBUS_RX_NONE; appends the results to log. */
static void take_bytes(rx_log_t *log, ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                       uint32_t now_ms, size_t piece)
{
    while (len > 0) {
        size_t offered = piece == 0 || piece > len ? len : piece;
        const uint8_t *at = data;
        size_t left = offered;
        ctrlbus_frame_t frame;
        for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_take(decoder, &at, &left, now_ms, &frame)) !=
                              CTRLBUS_RX_NONE;) {
            rx_log_add(log, rx, &frame);
        }
        CHECK(left == 0 && at == data + offered);
        data += offered;
        len -= offered;
    }
}

/* Runs hex through a fresh decoder whole, byte by byte, in pieces of 2, 3 and 7, through
 * ctrlbus_decoder_push() one byte at a time, and through ctrlbus_decoder_take() whole and in pieces
 * of 1, 3 and 7, expecting the same results each time; leaves the whole-feed run in log_a and its
 * fixture in *f. */
static void run_all_splits(fixture_t *f, size_t buffer_size, uint16_t timeout_ms, const char *hex)
{
    static const size_t pieces[] = {1, 2, 3, 7};
    uint8_t data[512];
    size_t len = harness_unhex(data, sizeof data, hex);
    for (size_t i = 0; i < sizeof pieces / sizeof pieces[0]; i++) {
        fixture_t other;
        fixture_init(&other, buffer_size, timeout_ms);
        rx_log_clear(&log_b);
        rx_log_feed(&log_b, &other.decoder, data, len, 0, pieces[i]);
        fixture_init(f, buffer_size, timeout_ms);
        rx_log_clear(&log_a);
        rx_log_feed(&log_a, &f->decoder, data, len, 0, 0);
        if (!CHECK(rx_log_equal(&log_a, &log_b))) {
            rx_log_print("whole", &log_a);
            rx_log_print("split", &log_b);
        }
        CHECK(memcmp(&f->stats, &other.stats, sizeof f->stats) == 0);
        CHECK(fixture_canary_intact(f) && fixture_canary_intact(&other));
    }
    fixture_t pushed;
    fixture_init(&pushed, buffer_size, timeout_ms);
    rx_log_clear(&log_b);
    push_bytes(&log_b, &pushed.decoder, data, len, 0);
    if (!CHECK(rx_log_equal(&log_a, &log_b))) {
        rx_log_print("whole", &log_a);
        rx_log_print("pushed", &log_b);
    }
    CHECK(memcmp(&f->stats, &pushed.stats, sizeof f->stats) == 0);
    CHECK(fixture_canary_intact(&pushed));
    static const size_t take_pieces[] = {0, 1, 3, 7};
    for (size_t i = 0; i < sizeof take_pieces / sizeof take_pieces[0]; i++) {
        fixture_t taken;
        fixture_init(&taken, buffer_size, timeout_ms);
        rx_log_clear(&log_b);
        take_bytes(&log_b, &taken.decoder, data, len, 0, take_pieces[i]);
        if (!CHECK(rx_log_equal(&log_a, &log_b))) {
            rx_log_print("whole", &log_a);
            rx_log_print("taken", &log_b);
        }
        CHECK(memcmp(&f->stats, &taken.stats, sizeof f->stats) == 0);
        CHECK(fixture_canary_intact(&taken));
    }
}

/* ---- encoder -------------------------------------------------------------------------------- */

static void check_encoded(uint8_t cmd, const char *payload_hex, ctrlbus_frame_type_t type,
                          const char *expected_hex)
{
    uint8_t payload[64];
    uint8_t expected[80];
    uint8_t out[80];
    size_t payload_len = harness_unhex(payload, sizeof payload, payload_hex);
    size_t expected_len = harness_unhex(expected, sizeof expected, expected_hex);
    int32_t len = ctrlbus_frame_encode(out, sizeof out, cmd, payload, payload_len, type);
    CHECK_EQ(len, (int32_t)expected_len);
    if (len > 0) {
        CHECK_MEM(out, (size_t)len, expected, expected_len);
    }
}

static void test_encode_reference_examples(void)
{
    check_encoded(0x00, "", CTRLBUS_FRAME_AUTO, "10 01 00 11");
    check_encoded(0x01, "AA 55", CTRLBUS_FRAME_AUTO, "10 03 01 AA 55 ED");
    check_encoded(0x01, "AA 55", CTRLBUS_FRAME_LONG, "50 03 00 01 AA 55 AD");
    check_encoded(0xF8, "10 01", CTRLBUS_FRAME_STANDARD, "10 03 F8 10 01 FA");
    check_encoded(0xF8, "30", CTRLBUS_FRAME_AUTO, "10 02 F8 30 DA");
    check_encoded(0xF8, "30", CTRLBUS_FRAME_LONG, "50 02 00 F8 30 9A");
    check_encoded(0x02, "", CTRLBUS_FRAME_LONG, "50 01 00 02 53");
    check_encoded(0x02, "50 03", CTRLBUS_FRAME_LONG, "50 03 00 02 50 03 02");
    check_encoded(0x03, "00 80", CTRLBUS_FRAME_LONG, "50 03 00 03 00 80 D0");
    check_encoded(0xF8, "41 33 33 00 00 00 00 00 00 00 80 00 00", CTRLBUS_FRAME_AUTO,
                  "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27");
}

static void test_frame_size_and_type_choice(void)
{
    CHECK_EQ(ctrlbus_frame_size(0, CTRLBUS_FRAME_AUTO), 4);
    CHECK_EQ(ctrlbus_frame_size(254, CTRLBUS_FRAME_AUTO), 258);
    CHECK_EQ(ctrlbus_frame_size(255, CTRLBUS_FRAME_AUTO), 260);
    CHECK_EQ(ctrlbus_frame_size(254, CTRLBUS_FRAME_STANDARD), 258);
    CHECK_EQ(ctrlbus_frame_size(255, CTRLBUS_FRAME_STANDARD), CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(ctrlbus_frame_size(0, CTRLBUS_FRAME_LONG), 5);
    CHECK_EQ(ctrlbus_frame_size(65534, CTRLBUS_FRAME_LONG), 65539);
    CHECK_EQ(ctrlbus_frame_size(65535, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(ctrlbus_frame_size(65535, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(ctrlbus_frame_size(1, (ctrlbus_frame_type_t)7), CTRLBUS_ERR_ARGUMENT);

    /* AUTO switches to a long frame exactly past 254 payload bytes. */
    static uint8_t payload[255];
    static uint8_t out[300];
    CHECK_EQ(ctrlbus_frame_encode(out, sizeof out, 0x01, payload, 254, CTRLBUS_FRAME_AUTO), 258);
    CHECK_EQ(out[0], 0x10);
    CHECK_EQ(out[1], 255);
    CHECK_EQ(ctrlbus_frame_encode(out, sizeof out, 0x01, payload, 255, CTRLBUS_FRAME_AUTO), 260);
    CHECK_EQ(out[0], 0x50);
    CHECK_EQ(out[1], 0x00); /* LEN 256, little-endian */
    CHECK_EQ(out[2], 0x01);
    CHECK_EQ(ctrlbus_frame_encode(out, sizeof out, 0x01, payload, 255, CTRLBUS_FRAME_STANDARD),
             CTRLBUS_ERR_TOO_BIG);
}

static void test_encode_buffer_too_small_leaves_it_untouched(void)
{
    uint8_t out[7];
    memset(out, 0xEE, sizeof out);
    uint8_t payload[3] = {1, 2, 3};
    CHECK_EQ(ctrlbus_frame_encode(out, 6, 0x01, payload, 3, CTRLBUS_FRAME_AUTO),
             CTRLBUS_ERR_TOO_BIG);
    for (size_t i = 0; i < sizeof out; i++) {
        CHECK_EQ(out[i], 0xEE);
    }
    CHECK_EQ(ctrlbus_frame_encode(out, 7, 0x01, payload, 3, CTRLBUS_FRAME_AUTO), 7);
}

/* A write callback that records every call, and can fail after a number of calls. */
typedef struct {
    uint8_t bytes[512];
    size_t len;
    int calls;
    int fail_at_call; /* 0 = never */
} recorder_t;

static int32_t record_write(void *context, const uint8_t *data, size_t len)
{
    recorder_t *r = context;
    r->calls++;
    if (r->fail_at_call != 0 && r->calls >= r->fail_at_call) {
        return CTRLBUS_ERR_IO;
    }
    memcpy(r->bytes + r->len, data, len);
    r->len += len;
    return CTRLBUS_OK;
}

static void test_sink_streams_fields_little_endian(void)
{
    recorder_t rec = {0};
    ctrlbus_sink_t sink;
    CHECK_EQ(ctrlbus_sink_init(&sink, record_write, &rec), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x02, 1 + 2 + 4 + 4 + 5 + 2, CTRLBUS_FRAME_AUTO),
             CTRLBUS_OK);
    ctrlbus_sink_put_u8(&sink, 0xAB);
    ctrlbus_sink_put_u16(&sink, 0x1234);
    ctrlbus_sink_put_u32(&sink, 0x89ABCDEFu);
    ctrlbus_sink_put_s32(&sink, -2);
    ctrlbus_sink_put_text(&sink, "ab", 5);
    ctrlbus_sink_put_text(&sink, "xyz", 2);
    CHECK_EQ(ctrlbus_sink_end(&sink), 4 + 18);
    uint8_t expected[32];
    size_t expected_len = harness_unhex(expected, sizeof expected,
                                        "10 13 02 AB 34 12 EF CD AB 89 FE FF FF FF 61 62 00 00 00 "
                                        "78 79 00");
    /* The checksum is whatever XOR gives: compute it independently. */
    uint8_t checksum = 0;
    for (size_t i = 0; i + 1 < expected_len; i++) {
        checksum ^= expected[i];
    }
    expected[expected_len - 1] = checksum;
    CHECK_MEM(rec.bytes, rec.len, expected, expected_len);
    CHECK(rec.calls > 1); /* streamed piece by piece, no frame buffer */

    /* The same frame through the whole-frame encoder gives the same bytes. */
    uint8_t out[32];
    CHECK_EQ(ctrlbus_frame_encode(out, sizeof out, 0x02, expected + 3, 18, CTRLBUS_FRAME_AUTO),
             22);
    CHECK_MEM(out, 22, expected, expected_len);
}

static void test_sink_text_edge_cases(void)
{
    uint8_t out[32];
    ctrlbus_buffer_t buffer;
    ctrlbus_sink_t sink;
    CHECK_EQ(ctrlbus_sink_init_buffer(&sink, &buffer, out, sizeof out), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 3 + 4, CTRLBUS_FRAME_STANDARD), CTRLBUS_OK);
    ctrlbus_sink_put_text(&sink, NULL, 3);
    ctrlbus_sink_put_text(&sink, "abcdefg", 4); /* cut to the field */
    CHECK_EQ(ctrlbus_sink_end(&sink), 11);
    uint8_t expected[11];
    harness_unhex(expected, sizeof expected, "10 08 01 00 00 00 61 62 63 64 00");
    expected[10] = 0x10 ^ 0x08 ^ 0x01 ^ 0x61 ^ 0x62 ^ 0x63 ^ 0x64;
    CHECK_MEM(out, buffer.len, expected, sizeof expected);
}

static void test_sink_length_mismatch_is_reported(void)
{
    recorder_t rec = {0};
    ctrlbus_sink_t sink;
    ctrlbus_sink_init(&sink, record_write, &rec);

    /* Too few bytes: no checksum is written. */
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 2, CTRLBUS_FRAME_AUTO), CTRLBUS_OK);
    ctrlbus_sink_put_u8(&sink, 1);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_LENGTH);
    CHECK_EQ(rec.len, 3 + 1);

    /* Too many bytes: the extra ones are not written. */
    rec.len = 0;
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 1, CTRLBUS_FRAME_AUTO), CTRLBUS_OK);
    ctrlbus_sink_put_u16(&sink, 0x0102);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_LENGTH);
    CHECK_EQ(rec.len, 3);

    /* Putting outside a frame. */
    ctrlbus_sink_put_u8(&sink, 1);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_LENGTH);

    /* An encoder's own error is sticky until the next begin. */
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 1, CTRLBUS_FRAME_AUTO), CTRLBUS_OK);
    ctrlbus_sink_fail(&sink, CTRLBUS_ERR_ARGUMENT);
    ctrlbus_sink_put_u8(&sink, 1);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 0, CTRLBUS_FRAME_AUTO), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_sink_end(&sink), 4);

    /* A second end after a whole frame: no frame is open, so LENGTH and nothing written. */
    rec.len = 0;
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_LENGTH);
    CHECK_EQ(rec.len, 0);
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 0, CTRLBUS_FRAME_LONG), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_sink_end(&sink), 5);
    CHECK_EQ(rec.len, 5);

    /* A payload too big for the type. */
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 255, CTRLBUS_FRAME_STANDARD), CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_TOO_BIG);

    CHECK_EQ(ctrlbus_sink_init(NULL, record_write, &rec), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_sink_init(&sink, NULL, &rec), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_sink_end(NULL), CTRLBUS_ERR_ARGUMENT);
}

static void test_sink_write_failure_stops_the_frame(void)
{
    recorder_t rec = {0};
    rec.fail_at_call = 2; /* the header goes out, the first payload piece fails */
    ctrlbus_sink_t sink;
    ctrlbus_sink_init(&sink, record_write, &rec);
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 8, CTRLBUS_FRAME_AUTO), CTRLBUS_OK);
    ctrlbus_sink_put_u32(&sink, 1);
    ctrlbus_sink_put_u32(&sink, 2);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_IO);
    CHECK_EQ(rec.calls, 2); /* nothing more was tried after the failure */

    rec = (recorder_t){0};
    rec.fail_at_call = 1;
    CHECK_EQ(ctrlbus_frame_write(&sink, 0x01, NULL, 0, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_IO);

    /* The first error stays: a failed header, then too few payload bytes, is still IO. */
    rec = (recorder_t){0};
    rec.fail_at_call = 1;
    CHECK_EQ(ctrlbus_sink_begin(&sink, 0x01, 2, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_IO);
    ctrlbus_sink_put_u8(&sink, 1);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_IO);
    CHECK_EQ(rec.calls, 1);
}

static void test_buffer_sink_overflow(void)
{
    uint8_t out[6];
    ctrlbus_buffer_t buffer;
    ctrlbus_sink_t sink;
    ctrlbus_sink_init_buffer(&sink, &buffer, out, sizeof out);
    uint8_t payload[4] = {1, 2, 3, 4};
    CHECK_EQ(ctrlbus_frame_write(&sink, 0x01, payload, 4, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_TOO_BIG);
    CHECK(buffer.len <= sizeof out);
    CHECK_EQ(ctrlbus_sink_init_buffer(&sink, NULL, out, 1), CTRLBUS_ERR_ARGUMENT);
}

/* ---- decoder: rules one by one -------------------------------------------------------------- */

static void test_decoder_init_arguments(void)
{
    ctrlbus_decoder_t d;
    uint8_t buf[8];
    CHECK_EQ(ctrlbus_decoder_init(NULL, buf, sizeof buf, 0, NULL), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_decoder_init(&d, NULL, sizeof buf, 0, NULL), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_decoder_init(&d, buf, 4, 0, NULL), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_decoder_init(&d, buf, 5, 0, NULL), CTRLBUS_OK);
    /* Misuse never leaves the documented feed loop spinning. */
    CHECK_EQ(ctrlbus_decoder_feed(&d, NULL, 3, 0), 3);
    CHECK_EQ(ctrlbus_decoder_feed(NULL, buf, 3, 0), 3);
    CHECK_EQ(ctrlbus_decoder_next(NULL, NULL), CTRLBUS_RX_NONE);
    CHECK(!ctrlbus_decoder_busy(&d));
    /* The smallest buffer still takes a one-byte-payload frame, and works without stats. */
    rx_log_clear(&log_a);
    uint8_t frame[5] = {0x10, 0x02, 0x01, 0x7F, 0x10 ^ 0x02 ^ 0x01 ^ 0x7F};
    rx_log_feed(&log_a, &d, frame, sizeof frame, 0, 1);
    expect_results("frame:01:7F");
}

static void test_single_frames_whole_and_split(void)
{
    fixture_t f;
    run_all_splits(&f, 64, 0, "10 01 00 11");
    expect_results("frame:00:");
    run_all_splits(&f, 64, 0, "50 03 00 01 AA 55 AD");
    expect_results("frame-long:01:AA 55");
    CHECK_EQ(f.stats.frames, 1);
    CHECK_EQ(f.stats.bytes_discarded, 0);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));
    run_all_splits(&f, 64, 0, "10 01 00 11 10 02 F8 30 DA 50 02 00 F8 30 9A");
    expect_results("frame:00:,frame:F8:30,frame-long:F8:30");
}

static void test_garbage_raises_one_event_per_gap(void)
{
    fixture_t f;
    run_all_splits(&f, 64, 0, "AA BB 10 01 00 11");
    expect_results("garbage,frame:00:");
    CHECK_EQ(f.stats.bytes_discarded, 2);
    /* Garbage after a frame is a new gap; more garbage in the same gap stays quiet. */
    run_all_splits(&f, 64, 0, "AA 10 01 00 11 BB CC DD");
    expect_results("garbage,frame:00:,garbage");
    /* After any event (here a checksum error), garbage stays quiet until the next frame. */
    run_all_splits(&f, 64, 0, "AA 10 02 F8 30 DB CC 10 01 00 11 EE");
    expect_results("garbage,checksum_error,frame:00:,garbage");
    CHECK_EQ(f.stats.bytes_discarded, 1 + 5 + 1 + 1);
    CHECK_EQ(f.stats.checksum_errors, 1);
    CHECK_EQ(f.stats.resyncs, 1);
}

static void test_checksum_failure_backtracks_to_a_swallowed_frame(void)
{
    fixture_t f;
    /* A false flag 10 06 claims the next 7 bytes; the real frame hides inside them. */
    run_all_splits(&f, 64, 0, "10 06 10 02 F8 30 DA 00 77");
    expect_results("checksum_error,frame:F8:30");
    CHECK_EQ(f.stats.checksum_errors, 1);
    CHECK_EQ(f.stats.resyncs, 1);
    CHECK_EQ(f.stats.frames, 1);
    CHECK_EQ(f.stats.bytes_discarded, 4); /* the flag, 06, and the tail 00 77 (silent) */
}

static void test_nested_failures_are_silent(void)
{
    fixture_t f;
    /* The outer candidate fails; inside its span a second candidate (10 01 99 00) fails too. */
    run_all_splits(&f, 64, 0, "10 04 10 01 99 00 55");
    expect_results("checksum_error");
    CHECK_EQ(f.stats.checksum_errors, 2);
    CHECK_EQ(f.stats.resyncs, 2);
    CHECK_EQ(f.stats.bytes_discarded, 7);
}

static void test_oversize_with_a_small_buffer(void)
{
    fixture_t f;
    /* max_frame 16: a long LEN of 0x01FF fails as soon as the header is in. */
    run_all_splits(&f, 16, 0, "50 FF 01 10 02 F8 30 DA");
    expect_results("oversize,frame:F8:30");
    CHECK_EQ(f.stats.oversize, 1);
    CHECK_EQ(f.stats.bytes_discarded, 3);
    /* A frame of exactly max_frame bytes fits, one byte more does not. */
    run_all_splits(&f, 8, 0, "10 05 01 0A 0B 0C 0D 14");
    expect_results("frame:01:0A 0B 0C 0D");
    run_all_splits(&f, 8, 0, "10 06 01 0A 0B 0C 0D 0E 04");
    CHECK_EQ(f.stats.oversize, 1);
    CHECK_EQ(f.stats.frames, 0);
    CHECK_EQ(log_a.count >= 1 ? log_a.entries[0].rx : CTRLBUS_RX_NONE, CTRLBUS_RX_OVERSIZE);
}

static void test_empty_frames(void)
{
    fixture_t f;
    run_all_splits(&f, 64, 0, "10 00 10");
    expect_results("empty_frame");
    CHECK_EQ(f.stats.empty_frames, 1);
    CHECK_EQ(f.stats.bytes_discarded, 3);
    CHECK_EQ(f.stats.resyncs, 0);
    run_all_splits(&f, 64, 0, "50 00 00 50 AA 10 01 00 11");
    expect_results("empty_frame,frame:00:"); /* the garbage after an event stays quiet */
    CHECK_EQ(f.stats.bytes_discarded, 5);
    /* LEN 0 with a wrong checksum is a checksum failure like any other. */
    run_all_splits(&f, 64, 0, "10 00 11");
    expect_results("checksum_error");
    CHECK_EQ(f.stats.empty_frames, 0);
    CHECK_EQ(f.stats.checksum_errors, 1);
    CHECK_EQ(f.stats.bytes_discarded, 3);
}

static void test_backtracking_yields_several_buffered_frames(void)
{
    fixture_t f;
    fixture_init(&f, 64, 0);
    rx_log_clear(&log_a);
    uint8_t data[16];
    size_t len = harness_unhex(data, sizeof data, "10 0A 10 01 00 11 10 01 00 11 10 01 00");
    /* Byte by byte, nothing comes out until the 13th byte completes the false candidate. */
    for (size_t i = 0; i + 1 < len; i++) {
        CHECK_EQ(ctrlbus_decoder_feed(&f.decoder, data + i, 1, 0), 1);
        CHECK_EQ(ctrlbus_decoder_next(&f.decoder, NULL), CTRLBUS_RX_NONE);
    }
    /* The last byte makes three results, handed out one at a time from buffered bytes. */
    CHECK_EQ(ctrlbus_decoder_feed(&f.decoder, data + len - 1, 1, 0), 1);
    ctrlbus_frame_t frame;
    CHECK_EQ(ctrlbus_decoder_feed(&f.decoder, data, 1, 0), 0); /* a result waits: nothing taken */
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_CHECKSUM_ERROR);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(frame.cmd, 0x00);
    CHECK_EQ(frame.payload_len, 0);
    CHECK(frame.payload >= f.buffer && frame.payload <= f.buffer + sizeof f.buffer);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_NONE);
    CHECK(ctrlbus_decoder_busy(&f.decoder)); /* 10 01 00 is waiting for its checksum */
    uint8_t last = 0x11;
    CHECK_EQ(ctrlbus_decoder_feed(&f.decoder, &last, 1, 0), 1);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(f.stats.frames, 3);
    CHECK_EQ(f.stats.bytes_discarded, 2);
}

static void test_payload_points_into_the_buffer(void)
{
    fixture_t f;
    fixture_init(&f, 64, 0);
    uint8_t data[8];
    size_t len = harness_unhex(data, sizeof data, "10 03 01 AA 55 ED");
    CHECK_EQ(ctrlbus_decoder_feed(&f.decoder, data, len, 0), len);
    ctrlbus_frame_t frame;
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK(frame.payload == f.buffer + 3);
    CHECK_EQ(frame.payload_len, 2);
    CHECK(!frame.is_long);
}

static void test_timeout_drops_a_partial_frame(void)
{
    fixture_t f;
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 09 10 02 F8 30 DA", 100);
    expect_results("");
    rx_log_tick(&log_a, &f.decoder, 110); /* exactly the timeout: not yet */
    expect_results("");
    CHECK(ctrlbus_decoder_busy(&f.decoder));
    rx_log_tick(&log_a, &f.decoder, 111);
    /* The stale bytes are rescanned: the complete frame inside them still comes out. */
    expect_results("timeout,frame:F8:30");
    CHECK_EQ(f.stats.timeouts, 1);
    CHECK_EQ(f.stats.resyncs, 1);
    CHECK_EQ(f.stats.bytes_discarded, 2);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));

    /* Incomplete candidates found in the stale bytes time out at once, silently. */
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 09 10 05 F8", 0);
    rx_log_tick(&log_a, &f.decoder, 11);
    expect_results("timeout");
    CHECK_EQ(f.stats.timeouts, 2);
    CHECK_EQ(f.stats.bytes_discarded, 5);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));
}

static void test_timeout_is_applied_before_new_bytes(void)
{
    fixture_t f;
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 05 F8", 0);
    feed_hex(&f, "10 02 F8 30 DA", 50);
    expect_results("timeout,frame:F8:30");

    /* Bytes that keep arriving within the timeout keep the frame alive. */
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 03", 0);
    feed_hex(&f, "01 AA", 10);
    feed_hex(&f, "55 ED", 20);
    expect_results("frame:01:AA 55");

    /* Without a timeout the same bytes are one false candidate that swallows the frame, and
     * backtracking finds it. */
    fixture_init(&f, 64, 0);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 05 F8", 0);
    feed_hex(&f, "10 02 F8 30 DA", 50);
    expect_results("checksum_error,frame:F8:30");
    rx_log_tick(&log_a, &f.decoder, 1000000);
    expect_results("checksum_error,frame:F8:30");
}

static void test_timeout_across_clock_wraparound(void)
{
    fixture_t f;
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 03 01", 0xFFFFFFF8u);
    rx_log_tick(&log_a, &f.decoder, 0x00000002u); /* 10 ms later */
    expect_results("");
    rx_log_tick(&log_a, &f.decoder, 0x00000003u); /* 11 ms later */
    expect_results("timeout");
    CHECK_EQ(f.stats.timeouts, 1);

    /* A frame whose bytes straddle the wrap is fine. */
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 03 01", 0xFFFFFFFEu);
    feed_hex(&f, "AA 55 ED", 0x00000005u);
    expect_results("frame:01:AA 55");

    /* A clock that steps backwards is not a timeout. */
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    feed_hex(&f, "10 03 01", 1000);
    rx_log_tick(&log_a, &f.decoder, 990);
    expect_results("");
    CHECK(ctrlbus_decoder_busy(&f.decoder));
}

static void test_push_takes_a_frame_byte_by_byte(void)
{
    static const uint8_t request[] = {0x10, 0x03, 0x01, 0xAA, 0x55, 0xED};
    fixture_t f;
    fixture_init(&f, 64, 10);
    ctrlbus_frame_t frame;
    for (size_t i = 0; i + 1u < sizeof request; i++) {
        CHECK_EQ(ctrlbus_decoder_push(&f.decoder, request[i], 7, &frame), CTRLBUS_RX_NONE);
    }
    CHECK_EQ(ctrlbus_decoder_push(&f.decoder, request[5], 7, &frame), CTRLBUS_RX_FRAME);
    CHECK(!frame.is_long && frame.cmd == 0x01 && frame.payload_len == 2);
    CHECK(frame.payload[0] == 0xAA && frame.payload[1] == 0x55);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_NONE);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));
    CHECK_EQ(f.stats.frames, 1);

    /* A long frame, each byte at a new millisecond (none takes push's same-millisecond path). */
    rx_log_clear(&log_a);
    static const char *const bytes[] = {"50", "03", "00", "02", "11", "22", "62"};
    for (uint32_t i = 0; i < sizeof bytes / sizeof bytes[0]; i++) {
        push_hex(&f, bytes[i], 8u + i);
    }
    expect_results("frame-long:02:11 22");

    /* A NULL decoder takes nothing. */
    CHECK_EQ(ctrlbus_decoder_push(NULL, 0x10, 0, &frame), CTRLBUS_RX_NONE);
}

static void test_push_own_cases_match_feed(void)
{
    /* The bytes push settles itself (flags, length bytes, a frame's last byte) next to those it
     * leaves to the scan: garbage before and after its gap's event, LEN 0 (standard and long), a checksum error at the last byte, oversize lengths of
     * both kinds in a 32-byte buffer. run_all_splits() compares results and counters with feed. */
    static const char *const stream =
        "10 03 01 AA 55 ED 33 44 40 99 50 04 00 02 01 02 03 56 10 00 10 10 02 03 07 16 50 00 00 50 "
        "10 03 04 09 09 16 10 01 05 14 10 F0 10 02 06 01 15 50 40 00 50 02 00 07 02 57 55 10";
    fixture_t f;
    run_all_splits(&f, 32, 10, stream);
    expect_results("frame:01:AA 55,garbage,frame-long:02:01 02 03,empty_frame,frame:03:07,"
                   "empty_frame,checksum_error,frame:05:,oversize,frame:06:01,oversize,"
                   "frame-long:07:02,garbage");
    CHECK_EQ(f.stats.bytes_discarded, 4u + 3u + 4u + 6u + 2u + 3u + 1u);

    /* The last byte with no frame to fill in: still counted, nothing left waiting. */
    fixture_init(&f, 32, 10);
    static const uint8_t request[] = {0x50, 0x02, 0x00, 0x09, 0x33, 0x68};
    for (size_t i = 0; i + 1u < sizeof request; i++) {
        CHECK_EQ(ctrlbus_decoder_push(&f.decoder, request[i], 3, NULL), CTRLBUS_RX_NONE);
    }
    CHECK_EQ(ctrlbus_decoder_push(&f.decoder, request[5], 3, NULL), CTRLBUS_RX_FRAME);
    CHECK_EQ(f.stats.frames, 1u);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));
}

static void test_take_hands_out_frames_in_place(void)
{
    /* garbage, a whole frame, then a frame split between two calls */
    static const uint8_t first[] = {0x33, 0x10, 0x03, 0x01, 0xAA, 0x55, 0xED, 0x50, 0x03};
    static const uint8_t second[] = {0x00, 0x02, 0x11, 0x22, 0x62, 0x10};
    fixture_t f;
    fixture_init(&f, 64, 10);
    const uint8_t *at = first;
    size_t left = sizeof first;
    ctrlbus_frame_t frame;
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 5, &frame), CTRLBUS_RX_GARBAGE);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 5, &frame), CTRLBUS_RX_FRAME);
    CHECK(frame.cmd == 0x01 && frame.payload_len == 2);
    CHECK(frame.payload[0] == 0xAA && frame.payload[1] == 0x55);
    CHECK(frame.payload == first + 4); /* in place: not copied */
    CHECK(at == first + 7 && left == 2);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 5, &frame), CTRLBUS_RX_NONE);
    CHECK(left == 0 && ctrlbus_decoder_busy(&f.decoder));
    at = second;
    left = sizeof second;
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 6, &frame), CTRLBUS_RX_FRAME);
    CHECK(frame.is_long && frame.cmd == 0x02 && frame.payload_len == 2);
    CHECK(frame.payload[0] == 0x11 && frame.payload[1] == 0x22);
    CHECK(frame.payload >= f.buffer && frame.payload < f.buffer + f.buffer_size);
    CHECK(left == 1);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 6, &frame), CTRLBUS_RX_NONE);
    CHECK(left == 0);
    CHECK_EQ(f.stats.frames, 2u);
    CHECK_EQ(f.stats.bytes_discarded, 1u);
    /* The flag left buffered times out at the next call's time, before its bytes. */
    static const uint8_t later[] = {0x10, 0x01, 0x05, 0x14};
    at = later;
    left = sizeof later;
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 20, &frame), CTRLBUS_RX_TIMEOUT);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 20, &frame), CTRLBUS_RX_FRAME);
    CHECK(frame.cmd == 0x05 && frame.payload_len == 0);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 20, &frame), CTRLBUS_RX_NONE);

    /* Bad arguments take nothing and never crash. */
    at = later;
    left = sizeof later;
    CHECK_EQ(ctrlbus_decoder_take(NULL, &at, &left, 0, &frame), CTRLBUS_RX_NONE);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, NULL, &left, 0, &frame), CTRLBUS_RX_NONE);
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, NULL, 0, &frame), CTRLBUS_RX_NONE);
    at = NULL;
    CHECK_EQ(ctrlbus_decoder_take(&f.decoder, &at, &left, 0, &frame), CTRLBUS_RX_NONE);
    CHECK(left == 0);
}

static void test_push_applies_the_timeout_before_the_byte(void)
{
    /* The stale partial frame fails first; the byte that arrived late starts the next frame. */
    fixture_t f;
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    push_hex(&f, "10 05 F8", 0);
    push_hex(&f, "10 02 F8 30 DA", 50);
    expect_results("timeout,frame:F8:30");

    /* The stale bytes hold a whole frame: it comes out after the timeout, then what the late
     * byte starts (garbage here), exactly as feeding gives. */
    static const char *const stale = "10 07 10 02 F8 30 DA";
    fixture_init(&f, 64, 10);
    rx_log_clear(&log_a);
    push_hex(&f, stale, 0);
    push_hex(&f, "AA", 50);
    expect_results("timeout,frame:F8:30,garbage");
    fixture_t fed;
    fixture_init(&fed, 64, 10);
    rx_log_clear(&log_b);
    uint8_t data[16];
    size_t len = harness_unhex(data, sizeof data, stale);
    rx_log_feed(&log_b, &fed.decoder, data, len, 0, 0);
    rx_log_feed(&log_b, &fed.decoder, (const uint8_t *)"\xAA", 1, 50, 0);
    CHECK(rx_log_equal(&log_a, &log_b));
    CHECK(memcmp(&f.stats, &fed.stats, sizeof f.stats) == 0);

    /* The held byte is counted as buffered until the timeout's results are taken. */
    fixture_init(&f, 64, 10);
    ctrlbus_frame_t frame;
    push_hex(&f, "10 07 10 02 F8 30 DA", 0);
    CHECK_EQ(ctrlbus_decoder_push(&f.decoder, 0x10, 50, &frame), CTRLBUS_RX_TIMEOUT);
    CHECK(ctrlbus_decoder_busy(&f.decoder));
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_NONE);
    CHECK(ctrlbus_decoder_busy(&f.decoder)); /* the 0x10 now starts a candidate */
    CHECK_EQ(f.decoder.end - f.decoder.start, 1);
}

static void test_push_refuses_a_byte_while_results_wait(void)
{
    /* A checksum failure whose span holds a frame: two results from one byte. */
    uint8_t data[32];
    size_t len = harness_unhex(data, sizeof data, "10 08 10 02 F8 30 DA 10 02 F8 31 DB 00 00");
    fixture_t f;
    fixture_init(&f, 64, 0);
    ctrlbus_frame_t frame;
    size_t i = 0;
    ctrlbus_rx_t rx = CTRLBUS_RX_NONE;
    while (i < len && (rx = ctrlbus_decoder_push(&f.decoder, data[i], 0, &frame)) == CTRLBUS_RX_NONE) {
        i++;
    }
    CHECK_EQ(rx, CTRLBUS_RX_CHECKSUM_ERROR);
    ctrlbus_decoder_t before = f.decoder;
    ctrlbus_decoder_stats_t stats = f.stats;
    CHECK_EQ(ctrlbus_decoder_push(&f.decoder, 0x10, 0, &frame), CTRLBUS_RX_BUSY);
    CHECK(memcmp(&before, &f.decoder, sizeof before) == 0);
    CHECK(memcmp(&stats, &f.stats, sizeof stats) == 0);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(frame.payload[0], 0x30);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_NONE);
    /* The rescan left 10 02 F8 31 waiting for its checksum: the next byte completes it. */
    CHECK_EQ(ctrlbus_decoder_push(&f.decoder, data[i + 1u], 0, &frame), CTRLBUS_RX_FRAME);
    CHECK_EQ(frame.payload[0], 0x31);
    CHECK_EQ(ctrlbus_decoder_next(&f.decoder, &frame), CTRLBUS_RX_NONE);
    CHECK_STR(ctrlbus_rx_name(CTRLBUS_RX_BUSY), "busy");
}

static void test_push_and_feed_mix(void)
{
    /* The same stream fed whole, and alternately pushed and fed in pieces: the same results. */
    uint8_t data[64];
    size_t len = harness_unhex(data, sizeof data,
                               "10 03 01 AA 55 ED 77 50 03 00 02 11 22 20 10 00 10 10 02 F8 30 DA "
                               "50 FF FF 10 02 F8 30 DA");
    fixture_t whole;
    fixture_init(&whole, 16, 10);
    rx_log_clear(&log_a);
    rx_log_feed(&log_a, &whole.decoder, data, len, 0, 0);
    fixture_t mixed;
    fixture_init(&mixed, 16, 10);
    rx_log_clear(&log_b);
    for (size_t i = 0; i < len;) {
        size_t piece = i % 3u == 0 ? 1u : 4u;
        if (piece > len - i) {
            piece = len - i;
        }
        if (i % 2u == 0) {
            push_bytes(&log_b, &mixed.decoder, data + i, piece, 0);
        } else {
            rx_log_feed(&log_b, &mixed.decoder, data + i, piece, 0, 0);
        }
        i += piece;
    }
    if (!CHECK(rx_log_equal(&log_a, &log_b))) {
        rx_log_print("whole", &log_a);
        rx_log_print("mixed", &log_b);
    }
    CHECK(memcmp(&whole.stats, &mixed.stats, sizeof whole.stats) == 0);
}

static void test_reset_forgets_buffered_bytes(void)
{
    fixture_t f;
    fixture_init(&f, 64, 0);
    rx_log_clear(&log_a);
    feed_hex(&f, "AA 10 05 F8", 0);
    ctrlbus_decoder_reset(&f.decoder);
    CHECK(!ctrlbus_decoder_busy(&f.decoder));
    feed_hex(&f, "10 01 00 11", 0);
    expect_results("garbage,frame:00:");
    CHECK_EQ(f.stats.bytes_discarded, 1); /* counters survive a reset */
}

static void test_largest_long_frame(void)
{
    size_t payload_len = CTRLBUS_LONG_PAYLOAD_MAX;
    static uint8_t payload[CTRLBUS_LONG_PAYLOAD_MAX];
    for (size_t i = 0; i < payload_len; i++) {
        payload[i] = (uint8_t)(i * 7u + 3u);
    }
    int32_t len = ctrlbus_frame_encode(big_frame, sizeof big_frame, 0x01, payload, payload_len,
                                       CTRLBUS_FRAME_AUTO);
    CHECK_EQ(len, (int32_t)CTRLBUS_FRAME_MAX);
    ctrlbus_decoder_t d;
    ctrlbus_decoder_stats_t stats;
    /* A buffer larger than the largest frame is fine (the extra is not used). */
    CHECK_EQ(ctrlbus_decoder_init(&d, big_buffer, sizeof big_buffer, 0, &stats), CTRLBUS_OK);
    for (size_t piece = 1; piece <= 4096; piece *= 64) {
        rx_log_clear(&log_a);
        /* Some garbage first so the frame does not start at offset 0 of the buffer. */
        uint8_t junk[3] = {0x01, 0x02, 0x03};
        rx_log_feed(&log_a, &d, junk, sizeof junk, 0, piece);
        rx_log_feed(&log_a, &d, big_frame, (size_t)len, 0, piece);
        CHECK_EQ(log_a.count, 2);
        if (log_a.count == 2) {
            CHECK_EQ(log_a.entries[1].rx, CTRLBUS_RX_FRAME);
            CHECK(log_a.entries[1].is_long);
            CHECK_MEM(rx_log_payload(&log_a, 1), log_a.entries[1].payload_len, payload,
                      payload_len);
        }
    }
    /* One byte less of buffer and the same frame is oversize. */
    CHECK_EQ(ctrlbus_decoder_init(&d, big_buffer, CTRLBUS_FRAME_MAX - 1, 0, &stats), CTRLBUS_OK);
    rx_log_clear(&log_a);
    rx_log_feed(&log_a, &d, big_frame, (size_t)len, 0, 0);
    CHECK_EQ(stats.oversize, 1);
    CHECK_EQ(stats.frames, 0);
}

/* ---- decoder against a literal model of the contract ---------------------------------------- */

/* A slow, literal reading of the contract's rules (vectors/README.md), written independently of
 * frame.c: it keeps the buffered bytes at the front of an array, re-examines from the front after
 * every byte, recomputes every checksum from scratch, and counts the span as "how many leading
 * bytes are silent". Random streams must give the same results and counters as the decoder. */
#define MODEL_CAP 1024u

typedef struct {
    uint8_t buf[MODEL_CAP];
    size_t len;
    size_t silent;
    bool event_since_frame;
    size_t max_frame;
    uint32_t timeout_ms;
    uint32_t last_ms;
    ctrlbus_decoder_stats_t stats;
    rx_log_t *log;
} model_t;

static void model_pop(model_t *m, size_t n)
{
    memmove(m->buf, m->buf + n, m->len - n);
    m->len -= n;
    m->silent = m->silent > n ? m->silent - n : 0;
}

static void model_event(model_t *m, ctrlbus_rx_t rx)
{
    m->event_since_frame = true;
    rx_log_add(m->log, rx, NULL);
}

static void model_fail(model_t *m, ctrlbus_rx_t kind)
{
    bool outermost = m->silent == 0;
    if (kind == CTRLBUS_RX_CHECKSUM_ERROR) {
        m->stats.checksum_errors++;
    } else if (kind == CTRLBUS_RX_OVERSIZE) {
        m->stats.oversize++;
    } else {
        m->stats.timeouts++;
    }
    m->stats.resyncs++;
    m->stats.bytes_discarded++;
    model_pop(m, 1);
    m->silent = m->len;
    if (outermost) {
        model_event(m, kind);
    }
}

static void model_settle(model_t *m, bool flushing)
{
    while (m->len > 0) {
        uint8_t flag = m->buf[0];
        if (flag != 0x10 && flag != 0x50) {
            bool quiet = m->silent > 0 || m->event_since_frame;
            model_pop(m, 1);
            m->stats.bytes_discarded++;
            if (!quiet) {
                model_event(m, CTRLBUS_RX_GARBAGE);
            }
            continue;
        }
        size_t header = flag == 0x10 ? 2 : 3;
        if (m->len < header) {
            if (!flushing) {
                return;
            }
            model_fail(m, CTRLBUS_RX_TIMEOUT);
            continue;
        }
        size_t len_field = m->buf[1] + (header == 3 ? (size_t)m->buf[2] * 256u : 0u);
        size_t size = header + len_field + 1;
        if (size > m->max_frame) {
            model_fail(m, CTRLBUS_RX_OVERSIZE);
            continue;
        }
        if (m->len < size) {
            if (!flushing) {
                return;
            }
            model_fail(m, CTRLBUS_RX_TIMEOUT);
            continue;
        }
        uint8_t checksum = 0;
        for (size_t i = 0; i + 1 < size; i++) {
            checksum ^= m->buf[i];
        }
        if (checksum != m->buf[size - 1]) {
            model_fail(m, CTRLBUS_RX_CHECKSUM_ERROR);
            continue;
        }
        if (len_field == 0) {
            bool quiet = m->silent > 0;
            m->stats.empty_frames++;
            m->stats.bytes_discarded += (uint32_t)size;
            model_pop(m, size);
            if (!quiet) {
                model_event(m, CTRLBUS_RX_EMPTY_FRAME);
            }
            continue;
        }
        ctrlbus_frame_t frame = {m->buf + header + 1, len_field - 1, m->buf[header], header == 3};
        m->stats.frames++;
        m->event_since_frame = false;
        rx_log_add(m->log, CTRLBUS_RX_FRAME, &frame);
        model_pop(m, size);
    }
}

static void model_time(model_t *m, uint32_t now_ms)
{
    uint32_t elapsed = now_ms - m->last_ms;
    if (m->timeout_ms != 0 && m->len > 0 && elapsed > m->timeout_ms && elapsed < 0x80000000u) {
        model_fail(m, CTRLBUS_RX_TIMEOUT);
        model_settle(m, true);
    }
}

static void model_feed(model_t *m, const uint8_t *data, size_t len, uint32_t now_ms)
{
    model_time(m, now_ms);
    for (size_t i = 0; i < len; i++) {
        m->buf[m->len++] = data[i];
        m->last_ms = now_ms;
        model_settle(m, false);
    }
}

static uint32_t rng_state;

static uint32_t rng(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 17;
    rng_state ^= rng_state << 5;
    return rng_state;
}

static uint32_t rng_below(uint32_t n)
{
    return rng() % n;
}

/* Appends one random piece of a noisy link to data: frames, broken frames, false flags, garbage. */
static size_t random_piece(uint8_t *data, size_t max_frame)
{
    uint8_t payload[40];
    size_t payload_len = rng_below(max_frame < 24 ? 12 : 30);
    for (size_t i = 0; i < payload_len; i++) {
        payload[i] = (uint8_t)rng();
    }
    ctrlbus_frame_type_t type = rng_below(2) ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD;
    int32_t len = ctrlbus_frame_encode(data, 64, (uint8_t)rng(), payload, payload_len, type);
    size_t n = (size_t)len;
    switch (rng_below(9)) {
    case 0: /* a valid frame */
    case 1: return n;
    case 2: /* a wrong checksum */
        data[n - 1] ^= (uint8_t)(1u + rng_below(255));
        return n;
    case 3: /* a truncated frame */
        return 1 + rng_below((uint32_t)n - 1);
    case 4: /* a false flag with a random length */
        data[0] = rng_below(2) ? 0x10 : 0x50;
        data[1] = (uint8_t)rng();
        data[2] = (uint8_t)(rng_below(4) == 0 ? rng() : 0);
        return 1 + rng_below(3);
    case 5: /* an empty frame, right or wrong */
        if (rng_below(2)) {
            data[0] = 0x10;
            data[1] = 0;
            data[2] = (uint8_t)(rng_below(3) ? 0x10u : rng());
            return 3;
        }
        data[0] = 0x50;
        data[1] = 0;
        data[2] = 0;
        data[3] = (uint8_t)(rng_below(3) ? 0x50u : rng());
        return 4;
    default: /* garbage, flags included */
        n = 1 + rng_below(6);
        for (size_t i = 0; i < n; i++) {
            data[i] = (uint8_t)(rng_below(4) == 0 ? (rng_below(2) ? 0x10u : 0x50u) : rng());
        }
        return n;
    }
}

static void test_decoder_matches_the_model_on_random_streams(void)
{
    static uint8_t stream[4096];
    static uint32_t times[4096]; /* time of each byte */
    static model_t model;
    rng_state = 0x12345678u;
    for (int round = 0; round < 1500; round++) {
        size_t max_frame = 5 + rng_below(60);
        uint16_t timeout = rng_below(3) == 0 ? 0 : (uint16_t)(1 + rng_below(20));
        size_t len = 0;
        uint32_t now = rng(); /* anywhere, wraparound included */
        while (len < 1500) {
            if (rng_below(6) == 0) {
                now += rng_below(2u * timeout + 3u); /* a pause, maybe past the timeout */
            }
            size_t n = random_piece(stream + len, max_frame);
            for (size_t i = 0; i < n; i++) {
                times[len + i] = now;
            }
            len += n;
        }
        uint32_t end_time = now + (uint32_t)timeout + 1u;

        memset(&model, 0, sizeof model);
        model.max_frame = max_frame;
        model.timeout_ms = timeout;
        model.log = &log_b;
        rx_log_clear(&log_b);
        for (size_t i = 0; i < len; i++) {
            model_feed(&model, stream + i, 1, times[i]);
        }
        model_time(&model, end_time);

        size_t piece = rng_below(4) == 0 ? 1 : 1 + rng_below(40);
        fixture_t f;
        fixture_init(&f, max_frame, timeout);
        rx_log_clear(&log_a);
        for (size_t i = 0; i < len;) {
            size_t run = 1;
            while (i + run < len && times[i + run] == times[i]) {
                run++; /* bytes with one time stamp form one chunk */
            }
            rx_log_feed(&log_a, &f.decoder, stream + i, run, times[i], piece);
            i += run;
        }
        rx_log_tick(&log_a, &f.decoder, end_time);

        harness_context("round %d max_frame %zu timeout %u piece %zu", round, max_frame,
                        (unsigned)timeout, piece);
        CHECK(!log_a.stalled);
        CHECK(fixture_canary_intact(&f));
        if (!CHECK(rx_log_equal(&log_a, &log_b))) {
            rx_log_print("decoder", &log_a);
            rx_log_print("model", &log_b);
            return;
        }
        if (!CHECK(memcmp(&f.stats, &model.stats, sizeof f.stats) == 0)) {
            return;
        }
        /* Once the final tick has flushed the buffer, every byte is either in a yielded frame or
         * counted as discarded. */
        if (timeout == 0) {
            continue;
        }
        CHECK(!ctrlbus_decoder_busy(&f.decoder));
        size_t in_frames = 0;
        for (size_t k = 0; k < log_a.count; k++) {
            if (log_a.entries[k].rx == CTRLBUS_RX_FRAME) {
                in_frames += log_a.entries[k].payload_len +
                             (log_a.entries[k].is_long ? CTRLBUS_LONG_OVERHEAD
                                                       : CTRLBUS_STANDARD_OVERHEAD);
            }
        }
        CHECK_EQ(in_frames + f.stats.bytes_discarded, len);
    }
    harness_context(NULL);
}

int main(void)
{
    RUN(test_encode_reference_examples);
    RUN(test_frame_size_and_type_choice);
    RUN(test_encode_buffer_too_small_leaves_it_untouched);
    RUN(test_sink_streams_fields_little_endian);
    RUN(test_sink_text_edge_cases);
    RUN(test_sink_length_mismatch_is_reported);
    RUN(test_sink_write_failure_stops_the_frame);
    RUN(test_buffer_sink_overflow);
    RUN(test_decoder_init_arguments);
    RUN(test_single_frames_whole_and_split);
    RUN(test_garbage_raises_one_event_per_gap);
    RUN(test_checksum_failure_backtracks_to_a_swallowed_frame);
    RUN(test_nested_failures_are_silent);
    RUN(test_oversize_with_a_small_buffer);
    RUN(test_empty_frames);
    RUN(test_backtracking_yields_several_buffered_frames);
    RUN(test_payload_points_into_the_buffer);
    RUN(test_timeout_drops_a_partial_frame);
    RUN(test_timeout_is_applied_before_new_bytes);
    RUN(test_timeout_across_clock_wraparound);
    RUN(test_push_takes_a_frame_byte_by_byte);
    RUN(test_push_own_cases_match_feed);
    RUN(test_take_hands_out_frames_in_place);
    RUN(test_push_applies_the_timeout_before_the_byte);
    RUN(test_push_refuses_a_byte_while_results_wait);
    RUN(test_push_and_feed_mix);
    RUN(test_reset_forgets_buffered_bytes);
    RUN(test_largest_long_frame);
    RUN(test_decoder_matches_the_model_on_random_streams);
    return harness_finish();
}
