/* SPDX-License-Identifier: MIT */
/*
 * The floor of a Core<->base exchange: what a minimal hand-written base costs, driven by the same
 * firmware timeline as the ctrlbus base stack (exchange_timeline.h). The receive interrupt puts
 * each byte in a ring; the main loop, once per millisecond, runs the ring's bytes through a plain
 * state machine (hunt for 0x10/0x50, length, body, XOR check), dispatches a complete frame with a
 * switch, and writes the answer as one frame straight from its fields. No watchdog, no velocity
 * limits, no health registry, no backtracking, no timeout, no error answers: not a base anyone
 * should ship, only the least work an exchange can take. It answers SET_V_AND_GET_DEADRECKON and
 * GET_BASE_STATUS as base_exchange.c's handlers do, in the same long OK frames.
 *
 *   floor_exchange MODE REQUESTS ANSWER_BYTES [ANSWERS]   (as base_exchange.c)
 *
 * Prints "bytes=N exchanges=E answer_bytes=A writes=W max_write=M".
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exchange_timeline.h"
#include "read_file.h"

#define RX_RING 256u
#define FRAME_MAX 512u

typedef int32_t (*write_fn)(void *context, const uint8_t *data, size_t len);

enum { HUNT, LEN_LO, LEN_HI, BODY };

typedef struct {
    uint8_t ring[RX_RING];
    volatile uint16_t head;
    volatile uint16_t tail;
    uint8_t frame[FRAME_MAX];
    uint16_t have;
    uint16_t need;
    uint8_t phase;
    uint8_t checksum;
    write_fn write;
    void *write_context;
} floor_base_t;

typedef struct {
    FILE *dump;
    unsigned long bytes;
    unsigned long writes;
    unsigned long max_write;
} output_t;

static int32_t discard(void *context, const uint8_t *data, size_t len)
{
    output_t *out = context;
    out->bytes += len;
    out->writes++;
    if (len > out->max_write) {
        out->max_write = len;
    }
    if (out->dump != NULL && fwrite(data, 1, len, out->dump) != len) {
        return -1;
    }
    return 0;
}

static int32_t get_s32(const uint8_t *p)
{
    return (int32_t)((uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24);
}

static uint8_t *put_s32(uint8_t *p, int32_t value)
{
    uint32_t v = (uint32_t)value;
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
    return p + 4;
}

/* An OK answer in a long frame: header, the payload already at tx + 4, checksum; one write. */
static void send_ok(floor_base_t *b, uint8_t *tx, uint16_t payload_len)
{
    uint16_t len = (uint16_t)(payload_len + 1u);
    tx[0] = 0x50u;
    tx[1] = (uint8_t)len;
    tx[2] = (uint8_t)(len >> 8);
    tx[3] = 0x02u;
    uint8_t checksum = 0;
    for (uint16_t i = 0; i < payload_len + 4u; i++) {
        checksum ^= tx[i];
    }
    tx[payload_len + 4u] = checksum;
    (void)b->write(b->write_context, tx, payload_len + 5u);
}

/* A complete frame whose checksum matched: frame[0..have). */
static void dispatch(floor_base_t *b)
{
    uint8_t header = b->frame[0] == 0x10u ? 2u : 3u;
    const uint8_t *payload = b->frame + header + 1u;
    if (b->frame[header] != 0xF8u) {
        return;
    }
    uint8_t tx[32];
    switch (payload[0]) {
    case 0x41: { /* SET_V_AND_GET_DEADRECKON */
        int32_t vx = get_s32(payload + 1);
        int32_t omega = get_s32(payload + 9);
        uint8_t *p = put_s32(tx + 4, (int32_t)((int64_t)vx * 50));
        p = put_s32(p, 0);
        p = put_s32(p, (int32_t)((int64_t)omega * 2865 / 1000));
        *p = 0u;
        send_ok(b, tx, 13u);
        break;
    }
    case 0x30: /* GET_BASE_STATUS */
        tx[4] = 87u;
        tx[5] = 0u;
        send_ok(b, tx, 2u);
        break;
    default: break;
    }
}

static void step(floor_base_t *b, uint8_t byte)
{
    switch (b->phase) {
    case HUNT:
        if (byte == 0x10u || byte == 0x50u) {
            b->frame[0] = byte;
            b->checksum = byte;
            b->have = 1u;
            b->phase = LEN_LO;
        }
        return;
    case LEN_LO:
        b->need = (uint16_t)(byte + (b->frame[0] == 0x10u ? 3u : 4u));
        b->phase = b->frame[0] == 0x10u ? BODY : LEN_HI;
        break;
    case LEN_HI:
        b->need = (uint16_t)(b->need + ((uint16_t)byte << 8));
        b->phase = BODY;
        break;
    default:
        if (b->have + 1u == b->need) {
            b->phase = HUNT;
            if (b->checksum == byte) {
                dispatch(b);
            }
            return;
        }
        break;
    }
    if (b->need > FRAME_MAX) {
        b->phase = HUNT;
        return;
    }
    b->frame[b->have++] = byte;
    b->checksum ^= byte;
}

static TIMELINE_ENTRY void isr_byte(void *base, uint8_t byte)
{
    floor_base_t *b = base;
    uint16_t head = b->head;
    uint16_t next = (uint16_t)((head + 1u) % RX_RING);
    if (next != b->tail) {
        b->ring[head] = byte;
        b->head = next;
    }
}

static TIMELINE_ENTRY void main_poll(void *base, uint32_t now_ms)
{
    floor_base_t *b = base;
    (void)now_ms;
    uint16_t head = b->head;
    uint16_t tail = b->tail;
    while (tail != head) {
        step(b, b->ring[tail]);
        tail = (uint16_t)((tail + 1u) % RX_RING);
    }
    b->tail = tail;
}

int main(int argc, char **argv)
{
    int dump = argc == 5 && strcmp(argv[1], "dump") == 0;
    int baseline = argc == 4 && strcmp(argv[1], "baseline") == 0;
    if (!dump && !baseline && !(argc == 4 && strcmp(argv[1], "firmware") == 0)) {
        fprintf(stderr, "usage: %s baseline|firmware REQUESTS ANSWER_BYTES | dump REQUESTS ANSWER_BYTES ANSWERS\n",
                argv[0]);
        return 2;
    }
    output_t out;
    memset(&out, 0, sizeof out);
    if (dump) {
        out.dump = fopen(argv[4], "wb");
        if (out.dump == NULL) {
            perror(argv[4]);
            return 2;
        }
    }
    size_t size = 0;
    unsigned char *data = read_file(argv[2], &size);
    if (data == NULL) {
        return 2;
    }
    static floor_base_t base;
    base.write = discard;
    base.write_context = &out;
    long exchanges = run_timeline(&base, data, size, (size_t)strtoul(argv[3], NULL, 10), baseline);
    free(data);
    if (out.dump != NULL && fclose(out.dump) != 0) {
        perror(argv[4]);
        return 2;
    }
    if (exchanges < 0) {
        fprintf(stderr, "the requests file is not whole frames\n");
        return 2;
    }
    printf("bytes=%lu exchanges=%ld answer_bytes=%lu writes=%lu max_write=%lu\n", (unsigned long)size,
           exchanges, out.bytes, out.writes, out.max_write);
    return 0;
}
