/* SPDX-License-Identifier: MIT */
/* Runs every shared test vector (the JSON files in vectors/, through the generated
 * ctrlbus_vectors.h) against the C frame and message layers. Every file and list is required:
 * an empty one is a failure. */
#include <stddef.h>
#include <stdio.h>
#include <string.h>

#include "ctrlbus/frame.h"
#include "ctrlbus/messages.h"
#include "ctrlbus_vectors.h"
#include "harness.h"
#include "msg_fields.h"
#include "rx_log.h"

static uint8_t decoder_buffer[CTRLBUS_FRAME_MAX];
static rx_log_t log_whole;
static rx_log_t log_split;
static msg_fields_t fields;

/* Feeding modes: whole chunks, then pieces of these sizes (1 = byte by byte). */
static const size_t PIECES[] = {0, 1, 2, 3, 7};
#define PIECE_MODES (sizeof PIECES / sizeof PIECES[0])

static ctrlbus_req_kind_t request_kind_named(const char *name)
{
    for (int kind = 0; kind < CTRLBUS_REQ_COUNT; kind++) {
        const char *candidate = ctrlbus_request_name((ctrlbus_req_kind_t)kind);
        if (name != NULL && candidate != NULL && strcmp(candidate, name) == 0) {
            return (ctrlbus_req_kind_t)kind;
        }
    }
    return CTRLBUS_REQ_NONE;
}

static int32_t error_named(const char *name)
{
    if (strcmp(name, "format") == 0) {
        return CTRLBUS_ERR_FORMAT;
    }
    if (strcmp(name, "unsupported") == 0) {
        return CTRLBUS_ERR_UNSUPPORTED;
    }
    return 1; /* not an error code: never matches */
}

static const uint32_t *counter_named(const ctrlbus_decoder_stats_t *stats, const char *name)
{
    static const struct {
        const char *name;
        size_t offset;
    } COUNTERS[] = {
        {"frames", offsetof(ctrlbus_decoder_stats_t, frames)},
        {"bytes_discarded", offsetof(ctrlbus_decoder_stats_t, bytes_discarded)},
        {"checksum_errors", offsetof(ctrlbus_decoder_stats_t, checksum_errors)},
        {"oversize", offsetof(ctrlbus_decoder_stats_t, oversize)},
        {"timeouts", offsetof(ctrlbus_decoder_stats_t, timeouts)},
        {"empty_frames", offsetof(ctrlbus_decoder_stats_t, empty_frames)},
        {"resyncs", offsetof(ctrlbus_decoder_stats_t, resyncs)},
    };
    for (size_t i = 0; i < sizeof COUNTERS / sizeof COUNTERS[0]; i++) {
        if (strcmp(COUNTERS[i].name, name) == 0) {
            return (const uint32_t *)(const void *)((const char *)stats + COUNTERS[i].offset);
        }
    }
    return NULL;
}

/* Checks a decoder run (its results and counters) against a vector's expectations. */
static void check_expect(const vec_expect_t *expect, const rx_log_t *log,
                         const ctrlbus_decoder_stats_t *stats, const char *mode)
{
    CHECK(!log->overflow && !log->stalled);
    size_t frame_index = 0;
    size_t event_index = 0;
    bool ok = true;
    for (size_t i = 0; i < log->count; i++) {
        const rx_entry_t *entry = &log->entries[i];
        if (entry->rx == CTRLBUS_RX_FRAME) {
            if (frame_index < expect->frame_count) {
                const vec_expected_frame_t *want = &expect->frames[frame_index];
                ok &= CHECK_EQ(entry->cmd, want->cmd);
                ok &= CHECK_EQ(entry->is_long, want->is_long);
                ok &= CHECK_MEM(rx_log_payload(log, i), entry->payload_len, want->payload.data,
                                want->payload.len);
            }
            frame_index++;
        } else if (expect->events_given) {
            if (event_index < expect->event_count) {
                ok &= CHECK_STR(ctrlbus_rx_name(entry->rx), expect->events[event_index]);
            }
            event_index++;
        }
    }
    ok &= CHECK_EQ(frame_index, expect->frame_count);
    if (expect->events_given) {
        ok &= CHECK_EQ(event_index, expect->event_count);
    }
    for (size_t i = 0; i < expect->counter_count; i++) {
        const uint32_t *counter = counter_named(stats, expect->counters[i].name);
        if (counter == NULL) {
            harness_fail(__FILE__, __LINE__, "unknown counter \"%s\"", expect->counters[i].name);
            ok = false;
            continue;
        }
        if (!harness_check_int((long long)*counter, expect->counters[i].value, __FILE__, __LINE__,
                               expect->counters[i].name, "the vector's value")) {
            ok = false;
        }
    }
    if (!ok) {
        rx_log_print(mode, log);
    }
}

/* ---- frames.json ---------------------------------------------------------------------------- */

static void check_request_message(const vec_frame_t *v, const ctrlbus_frame_t *frame)
{
    static uint8_t wire[CTRLBUS_FRAME_MAX];
    ctrlbus_request_t request;
    int32_t result = ctrlbus_request_decode(&request, frame->cmd, frame->payload, frame->payload_len);
    if (!CHECK_STR(ctrlbus_error_name(result), "ok")) {
        return;
    }
    CHECK_STR(ctrlbus_request_name(request.kind), v->message_name);
    msg_fields_of_request(&fields, &request);
    msg_fields_check(&fields, v->fields, v->field_count, __FILE__, __LINE__);
    int32_t len = ctrlbus_request_encode(wire, sizeof wire, &request,
                                         v->is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
    CHECK_EQ(len, (int32_t)v->wire.len);
    CHECK_MEM(wire, len > 0 ? (size_t)len : 0, v->wire.data, v->wire.len);
}

static void check_answer_message(const vec_frame_t *v, const ctrlbus_frame_t *frame)
{
    static uint8_t wire[CTRLBUS_FRAME_MAX];
    static ctrlbus_answer_t answer;
    ctrlbus_req_kind_t to = request_kind_named(v->to);
    if (!CHECK(to != CTRLBUS_REQ_NONE)) {
        harness_fail(__FILE__, __LINE__, "unknown request name \"%s\" in 'to'", v->to);
        return;
    }
    int32_t result =
        ctrlbus_answer_decode(&answer, to, frame->cmd, frame->payload, frame->payload_len);
    if (!CHECK_STR(ctrlbus_error_name(result), "ok")) {
        return;
    }
    CHECK_STR(ctrlbus_answer_name(answer.kind), v->message_name);
    msg_fields_of_answer(&fields, &answer);
    msg_fields_check(&fields, v->fields, v->field_count, __FILE__, __LINE__);
    int32_t len = ctrlbus_answer_encode(wire, sizeof wire, &answer,
                                        v->is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
    CHECK_EQ(len, (int32_t)v->wire.len);
    CHECK_MEM(wire, len > 0 ? (size_t)len : 0, v->wire.data, v->wire.len);
}

static void test_frames_json(void)
{
    for (size_t i = 0; i < VEC_FRAMES_COUNT; i++) {
        const vec_frame_t *v = &VEC_FRAMES[i];
        harness_context("frames.json %s", v->name);
        /* The frame layer: exactly this one frame, however the bytes are split. */
        ctrlbus_decoder_t decoder;
        ctrlbus_decoder_stats_t stats;
        for (size_t mode = 0; mode < PIECE_MODES; mode++) {
            ctrlbus_decoder_init(&decoder, decoder_buffer, sizeof decoder_buffer, 0, &stats);
            rx_log_clear(&log_split);
            rx_log_feed(&log_split, &decoder, v->wire.data, v->wire.len, 0, PIECES[mode]);
            bool one_frame = log_split.count == 1 && log_split.entries[0].rx == CTRLBUS_RX_FRAME &&
                             !ctrlbus_decoder_busy(&decoder);
            if (!CHECK(one_frame)) {
                rx_log_print("decoded", &log_split);
                continue;
            }
            CHECK_EQ(log_split.entries[0].is_long, v->is_long);
            CHECK_EQ(log_split.entries[0].cmd, v->cmd);
            CHECK_MEM(rx_log_payload(&log_split, 0), log_split.entries[0].payload_len,
                      v->payload.data, v->payload.len);
        }
        /* Encoding the frame gives the same bytes. */
        static uint8_t wire[CTRLBUS_FRAME_MAX];
        int32_t len = ctrlbus_frame_encode(wire, sizeof wire, v->cmd, v->payload.data,
                                           v->payload.len,
                                           v->is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
        CHECK_MEM(wire, len > 0 ? (size_t)len : 0, v->wire.data, v->wire.len);
        if (v->kind == NULL) {
            continue;
        }
        /* The message layer, on the frame as the decoder hands it out. */
        ctrlbus_decoder_init(&decoder, decoder_buffer, sizeof decoder_buffer, 0, NULL);
        ctrlbus_frame_t frame;
        if (ctrlbus_decoder_feed(&decoder, v->wire.data, v->wire.len, 0) != v->wire.len ||
            ctrlbus_decoder_next(&decoder, &frame) != CTRLBUS_RX_FRAME) {
            continue; /* already reported above */
        }
        if (strcmp(v->kind, "request") == 0) {
            check_request_message(v, &frame);
        } else if (strcmp(v->kind, "answer") == 0) {
            check_answer_message(v, &frame);
        } else {
            harness_fail(__FILE__, __LINE__, "unknown message kind \"%s\"", v->kind);
        }
    }
    harness_context(NULL);
    if (VEC_FRAMES_COUNT == 0) {
        harness_fail(__FILE__, __LINE__, "frames.json: no cases (the shared vectors are required)");
    }
}

/* ---- invalid.json --------------------------------------------------------------------------- */

static void test_invalid_json_frame_level(void)
{
    for (size_t i = 0; i < VEC_FRAME_LEVEL_COUNT; i++) {
        const vec_frame_level_t *v = &VEC_FRAME_LEVEL[i];
        for (size_t mode = 0; mode < PIECE_MODES; mode++) {
            harness_context("invalid.json frame_level %s (pieces of %zu)", v->name, PIECES[mode]);
            ctrlbus_decoder_t decoder;
            ctrlbus_decoder_stats_t stats;
            if (!CHECK_EQ(ctrlbus_decoder_init(&decoder, decoder_buffer, v->max_frame,
                                               (uint16_t)v->timeout_ms, &stats),
                          CTRLBUS_OK)) {
                break;
            }
            CHECK(v->timeout_ms <= 0xFFFFu);
            rx_log_t *log = mode == 0 ? &log_whole : &log_split;
            rx_log_clear(log);
            rx_log_feed(log, &decoder, v->input.data, v->input.len, 0, PIECES[mode]);
            if (v->timeout_ms != 0) {
                rx_log_tick(log, &decoder, v->timeout_ms + 1u); /* an idle gap past the timeout */
            }
            check_expect(&v->expect, log, &stats, "decoded");
        }
    }
    harness_context(NULL);
    if (VEC_FRAME_LEVEL_COUNT == 0) {
        harness_fail(__FILE__, __LINE__, "invalid.json frame_level: no cases (the shared vectors are required)");
    } else {
        harness_note("invalid.json frame_level: base_answer is the base stack's to check");
    }
}

static void test_invalid_json_message_level(void)
{
    for (size_t i = 0; i < VEC_MESSAGE_LEVEL_COUNT; i++) {
        const vec_message_level_t *v = &VEC_MESSAGE_LEVEL[i];
        harness_context("invalid.json message_level %s", v->name);
        int32_t expected = error_named(v->expect_error);
        if (!CHECK(expected < 0)) {
            harness_fail(__FILE__, __LINE__, "unknown expect_error \"%s\"", v->expect_error);
            continue;
        }
        if (strcmp(v->direction, "request") == 0) {
            ctrlbus_request_t request;
            int32_t result = ctrlbus_request_decode(&request, v->cmd, v->payload.data,
                                                    v->payload.len);
            CHECK_STR(ctrlbus_error_name(result), v->expect_error);
            if (v->has_base_answer && result < 0) {
                /* The ERROR frame a base sends for this failure (long, as by default). */
                uint8_t answer[16];
                ctrlbus_sink_t sink;
                ctrlbus_buffer_t buffer;
                ctrlbus_sink_init_buffer(&sink, &buffer, answer, sizeof answer);
                ctrlbus_error_answer_write(&sink, ctrlbus_request_error_code(&request, result),
                                           CTRLBUS_FRAME_LONG);
                CHECK_MEM(answer, buffer.len, v->base_answer.data, v->base_answer.len);
            }
        } else if (strcmp(v->direction, "answer") == 0) {
            ctrlbus_req_kind_t to = request_kind_named(v->to);
            if (!CHECK(to != CTRLBUS_REQ_NONE)) {
                harness_fail(__FILE__, __LINE__, "unknown request name \"%s\" in 'to'", v->to);
                continue;
            }
            static ctrlbus_answer_t answer;
            int32_t result = ctrlbus_answer_decode(&answer, to, v->cmd, v->payload.data,
                                                   v->payload.len);
            CHECK_STR(ctrlbus_error_name(result), v->expect_error);
        } else {
            harness_fail(__FILE__, __LINE__, "unknown direction \"%s\"", v->direction);
        }
    }
    harness_context(NULL);
    if (VEC_MESSAGE_LEVEL_COUNT == 0) {
        harness_fail(__FILE__, __LINE__, "invalid.json message_level: no cases (the shared vectors are required)");
    }
}

/* ---- streams.json --------------------------------------------------------------------------- */

static void test_streams_json(void)
{
    for (size_t i = 0; i < VEC_STREAMS_COUNT; i++) {
        const vec_stream_t *v = &VEC_STREAMS[i];
        for (size_t mode = 0; mode < PIECE_MODES; mode++) {
            harness_context("streams.json %s (pieces of %zu)", v->name, PIECES[mode]);
            ctrlbus_decoder_t decoder;
            ctrlbus_decoder_stats_t stats;
            if (!CHECK_EQ(ctrlbus_decoder_init(&decoder, decoder_buffer, v->max_frame,
                                               (uint16_t)v->timeout_ms, &stats),
                          CTRLBUS_OK)) {
                break;
            }
            CHECK(v->timeout_ms <= 0xFFFFu);
            rx_log_t *log = mode == 0 ? &log_whole : &log_split;
            rx_log_clear(log);
            uint32_t last_ms = 0;
            for (size_t c = 0; c < v->chunk_count; c++) {
                const vec_chunk_t *chunk = &v->chunks[c];
                /* A chunk with no bytes still moves time on. */
                rx_log_tick(log, &decoder, chunk->t_ms);
                rx_log_feed(log, &decoder, chunk->data.data, chunk->data.len, chunk->t_ms,
                            PIECES[mode]);
                last_ms = chunk->t_ms;
            }
            if (v->has_final_idle) {
                rx_log_tick(log, &decoder, last_ms + v->final_idle_ms);
            }
            check_expect(&v->expect, log, &stats, "decoded");
            if (mode > 0 && !CHECK(rx_log_equal(&log_whole, log))) {
                rx_log_print("whole chunks", &log_whole);
                rx_log_print("split", log);
            }
        }
    }
    harness_context(NULL);
    if (VEC_STREAMS_COUNT == 0) {
        harness_fail(__FILE__, __LINE__, "streams.json: no cases (the shared vectors are required)");
    }
}

int main(void)
{
    RUN(test_frames_json);
    RUN(test_invalid_json_frame_level);
    RUN(test_invalid_json_message_level);
    RUN(test_streams_json);
    printf("vectors: %zu frames, %zu frame_level, %zu message_level, %zu streams\n",
           VEC_FRAMES_COUNT, VEC_FRAME_LEVEL_COUNT, VEC_MESSAGE_LEVEL_COUNT, VEC_STREAMS_COUNT);
    return harness_finish();
}
