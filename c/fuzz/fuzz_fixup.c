/* SPDX-License-Identifier: MIT */
/* Fuzz target, "fix-up" mode: the input is a list of (cmd, payload) records that the target turns
 * into frames with the right length and checksum, so that nearly every input reaches the payload
 * handling that random bytes almost never reach past the 8-bit checksum: the message codecs
 * (ctrlbus/messages.h) and the base stack's dispatch.
 *
 * Input: the four setting bytes of base_harness.h, then records:
 *   ctl  bit 0: long frame (a payload over 254 bytes always is); bits 1-2: time before the next
 *        record: none, 1 ms, past the inter-byte timeout, past the watchdog; bit 3: spoil the
 *        checksum; bit 4: one byte of garbage before the frame (the byte after len); bit 5: 256
 *        more payload bytes; bit 6: poll after the frame; bit 7: the application queues an
 *        external command first (chosen by cmd).
 *   cmd  the CMD byte;  len  the payload length (with bit 5: len + 256), cut to what is left.
 *   the payload bytes.
 * For each record, before the base sees the frame:
 *   - as a request: ctrlbus_request_decode(); a request it accepts must encode again, to exactly
 *     the same payload, and decode to the same again;
 *   - as an answer to every request kind: ctrlbus_answer_decode(); an answer it accepts must
 *     encode, and its encoding must decode and encode to the same bytes (text fields keep only
 *     what precedes their NUL, so the first encoding may differ from the input). */
#include <string.h>

#include "base_harness.h"
#include "ctrlbus/messages.h"
#include "fuzz_common.h"

#define FRAME_CAP 2048u

static const uint8_t EXTERNAL_COMMANDS[] = {0x51, 0x52, 0x53, 0x80, 0x81, 0x82, 0x90,
                                            0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xAF, 0xB0};

/* The payload and CMD of an encoded frame (out[0..n)). */
static void split_frame(const uint8_t *out, int32_t n, uint8_t *cmd, const uint8_t **payload,
                        size_t *len)
{
    FUZZ_CHECK(n >= (int32_t)CTRLBUS_STANDARD_OVERHEAD);
    size_t header = out[0] == CTRLBUS_FLAG_LONG ? 3u : 2u;
    *cmd = out[header];
    *payload = out + header + 1u;
    *len = (size_t)n - header - 2u;
}

static void check_request_codec(uint8_t cmd, const uint8_t *payload, size_t len,
                                ctrlbus_frame_type_t type)
{
    ctrlbus_request_t request;
    if (ctrlbus_request_decode(&request, cmd, payload, len) != CTRLBUS_OK) {
        return;
    }
    FUZZ_CHECK(ctrlbus_request_payload_size(&request) == (int32_t)len);
    static uint8_t first[FRAME_CAP];
    static uint8_t second[FRAME_CAP];
    int32_t n = ctrlbus_request_encode(first, sizeof first, &request, type);
    uint8_t cmd2;
    const uint8_t *payload2;
    size_t len2;
    split_frame(first, n, &cmd2, &payload2, &len2);
    FUZZ_CHECK(cmd2 == cmd && len2 == len && (len == 0 || memcmp(payload2, payload, len) == 0));
    ctrlbus_request_t again;
    FUZZ_CHECK(ctrlbus_request_decode(&again, cmd2, payload2, len2) == CTRLBUS_OK);
    FUZZ_CHECK(again.kind == request.kind);
    int32_t n2 = ctrlbus_request_encode(second, sizeof second, &again, type);
    FUZZ_CHECK(n2 == n && memcmp(first, second, (size_t)n) == 0);
}

static void check_answer_codecs(uint8_t cmd, const uint8_t *payload, size_t len,
                                ctrlbus_frame_type_t type)
{
    static uint8_t first[FRAME_CAP];
    static uint8_t second[FRAME_CAP];
    for (int kind = CTRLBUS_REQ_NONE + 1; kind < CTRLBUS_REQ_COUNT; kind++) {
        ctrlbus_req_kind_t to = (ctrlbus_req_kind_t)kind;
        ctrlbus_answer_t answer;
        if (ctrlbus_answer_decode(&answer, to, cmd, payload, len) != CTRLBUS_OK) {
            continue;
        }
        FUZZ_CHECK(ctrlbus_answer_name(answer.kind) != NULL);
        int32_t n = ctrlbus_answer_encode(first, sizeof first, &answer, type);
        uint8_t cmd2;
        const uint8_t *payload2;
        size_t len2;
        split_frame(first, n, &cmd2, &payload2, &len2);
        FUZZ_CHECK(cmd2 == cmd && ctrlbus_answer_payload_size(&answer) == (int32_t)len2);
        ctrlbus_answer_t again;
        FUZZ_CHECK(ctrlbus_answer_decode(&again, to, cmd2, payload2, len2) == CTRLBUS_OK);
        FUZZ_CHECK(again.kind == answer.kind);
        int32_t n2 = ctrlbus_answer_encode(second, sizeof second, &again, type);
        FUZZ_CHECK(n2 == n && memcmp(first, second, (size_t)n) == 0);
    }
}

static uint32_t time_step(uint8_t ctl)
{
    switch ((ctl >> 1) & 3u) {
    case 1: return 1;
    case 2: return base_harness_timeout_ms() + 1u;
    case 3: return base_harness_watchdog_ms() + 1u;
    default: return 0;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input_t in = {data, size};
    uint32_t now = 0xFFFFF000u; /* the clock wraps around during the run */
    base_harness_start(&in, now);
    static uint8_t frame[FRAME_CAP];
    while (in.left > 0) {
        uint8_t ctl = fuzz_u8(&in);
        uint8_t cmd = fuzz_u8(&in);
        size_t len = fuzz_u8(&in) + ((ctl & 0x20u) ? 256u : 0u);
        uint8_t garbage = (ctl & 0x10u) ? fuzz_u8(&in) : 0u;
        if (len > in.left) {
            len = in.left;
        }
        const uint8_t *payload = in.data;
        in.data += len;
        in.left -= len;

        ctrlbus_frame_type_t type = (ctl & 1u) || len > CTRLBUS_STANDARD_PAYLOAD_MAX
                                        ? CTRLBUS_FRAME_LONG
                                        : CTRLBUS_FRAME_STANDARD;
        check_request_codec(cmd, payload, len, type);
        check_answer_codecs(cmd, payload, len, type);

        int32_t n = ctrlbus_frame_encode(frame, sizeof frame, cmd, payload, len, type);
        FUZZ_CHECK(n > 0);
        if (ctl & 0x08u) {
            frame[n - 1] ^= 0x01u;
        }
        if (ctl & 0x80u) {
            base_harness_queue_command(EXTERNAL_COMMANDS[cmd % sizeof EXTERNAL_COMMANDS]);
        }
        if (ctl & 0x10u) {
            base_harness_feed(&garbage, 1, now);
        }
        base_harness_feed(frame, (size_t)n, now);
        if (ctl & 0x40u) {
            base_harness_poll(now);
        }
        now += time_step(ctl);
    }
    base_harness_finish(now);
    return 0;
}
