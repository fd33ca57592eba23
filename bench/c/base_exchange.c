/* SPDX-License-Identifier: MIT */
/*
 * Benchmark harness for a full base exchange through the ctrlbus C base stack (base.h): feed one
 * SET_V_AND_GET_DEADRECKON request, poll, and let the stack stream its answer out through a write
 * callback that discards it. callgrind counts the instructions.
 *
 *   base_exchange MODE REQUESTS [ANSWERS]
 *
 * REQUESTS is a file of request frames back to back (each frame's size comes from its header).
 * MODE
 *   baseline  start the base and walk the requests' bytes, one request at a time, without feeding
 *             or polling (the cost subtracted: start-up, file reading, the loop)
 *   frames    ctrlbus_base_feed() each whole request, then ctrlbus_base_poll(): a DMA or
 *             ring-buffer receiver
 *   bytes     ctrlbus_base_feed() each request one byte at a time (a UART receive interrupt per
 *             byte), then ctrlbus_base_poll()
 *   polled    ctrlbus_base_feed() one byte, then ctrlbus_base_poll(), for every byte (a main loop
 *             that polls faster than bytes arrive: the poll finds one byte in the ring each time)
 *   dump      as frames, but the answers go to the file ANSWERS (to check them; not measured)
 *
 * The clock advances 50 ms per request (the Core's 20 Hz), so the watchdog stays fed and no
 * request times out. The set_velocity handler does the least a base must: it reports the motion
 * the velocity gives over 50 ms, in integer arithmetic.
 *
 * Prints "bytes=N exchanges=E answer_bytes=A writes=W max_write=M" so the caller can check that
 * every request was answered (max_write: the largest piece the stack handed to write at once).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "read_file.h"

#include "ctrlbus/base.h"

#define RX_RING 256u
#define FRAME_BUFFER CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED
#define PERIOD_MS 50u

/* Size of the frame starting at data[0], from its header; 0 if it is not a whole frame. */
static size_t frame_size(const unsigned char *data, size_t left)
{
    size_t size = 0;
    if (left >= 2 && data[0] == 0x10u) {
        size = (size_t)data[1] + 3u; /* flag, LEN, then LEN bytes (CMD and payload), checksum */
    } else if (left >= 3 && data[0] == 0x50u) {
        size = ((size_t)data[1] | (size_t)data[2] << 8) + 4u; /* flag, LEN (2), LEN bytes, checksum */
    }
    return size <= left ? size : 0u;
}

typedef struct {
    FILE *dump; /* NULL: discard */
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
        return CTRLBUS_ERR_IO;
    }
    return CTRLBUS_OK;
}

/* The motion over one 50 ms period: vx m/s -> mm is x 50; omega rad/s -> degrees is x 2.8648. */
static int32_t set_velocity(void *context, const ctrlbus_set_v_and_get_deadreckon_request_t *velocity,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    (void)context;
    out->dx_mm_q16 = (int32_t)((int64_t)velocity->vx_mps_q16 * 50);
    out->dy_mm_q16 = 0;
    out->dtheta_deg_q16 = (int32_t)((int64_t)velocity->omega_radps_q16 * 2865 / 1000);
    out->status = 0u;
    return CTRLBUS_OK;
}

typedef enum { MODE_BASELINE, MODE_FRAMES, MODE_BYTES, MODE_POLLED } harness_mode_t;

static int run(const unsigned char *data, size_t size, harness_mode_t mode, output_t *out, unsigned long *exchanges)
{
    static uint8_t rx_ring[RX_RING];
    static uint8_t frame_buffer[FRAME_BUFFER];
    ctrlbus_base_config_t config;
    memset(&config, 0, sizeof config);
    config.rx_ring = rx_ring;
    config.rx_ring_size = RX_RING;
    config.frame_buffer = frame_buffer;
    config.frame_buffer_size = FRAME_BUFFER;
    config.write = discard;
    config.write_context = out;
    config.set_velocity = set_velocity;
    ctrlbus_base_t base;
    uint32_t now_ms = 0;
    if (ctrlbus_base_init(&base, &config, now_ms) != CTRLBUS_OK) {
        fprintf(stderr, "ctrlbus_base_init failed\n");
        return 2;
    }
    volatile unsigned char sink = 0;
    size_t pos = 0;
    while (pos < size) {
        size_t len = frame_size(data + pos, size - pos);
        if (len == 0) {
            fprintf(stderr, "not a whole frame at offset %lu\n", (unsigned long)pos);
            return 2;
        }
        now_ms += PERIOD_MS;
        if (mode == MODE_BASELINE) {
            for (size_t i = 0; i < len; i++) {
                sink = data[pos + i];
            }
        } else if (mode == MODE_FRAMES) {
            if (ctrlbus_base_feed(&base, data + pos, len) != len) {
                fprintf(stderr, "the ring refused bytes\n");
                return 2;
            }
            ctrlbus_base_poll(&base, now_ms);
        } else if (mode == MODE_BYTES) {
            for (size_t i = 0; i < len; i++) {
                (void)ctrlbus_base_feed(&base, data + pos + i, 1u);
            }
            ctrlbus_base_poll(&base, now_ms);
        } else {
            for (size_t i = 0; i < len; i++) {
                (void)ctrlbus_base_feed(&base, data + pos + i, 1u);
                ctrlbus_base_poll(&base, now_ms);
            }
        }
        pos += len;
        (*exchanges)++;
    }
    (void)sink;
    return 0;
}

int main(int argc, char **argv)
{
    if (argc < 3 || (strcmp(argv[1], "dump") == 0 && argc != 4)) {
        fprintf(stderr, "usage: %s baseline|frames|bytes|polled REQUESTS | dump REQUESTS ANSWERS\n", argv[0]);
        return 2;
    }
    harness_mode_t mode;
    output_t out;
    memset(&out, 0, sizeof out);
    if (strcmp(argv[1], "baseline") == 0) {
        mode = MODE_BASELINE;
    } else if (strcmp(argv[1], "frames") == 0) {
        mode = MODE_FRAMES;
    } else if (strcmp(argv[1], "bytes") == 0) {
        mode = MODE_BYTES;
    } else if (strcmp(argv[1], "polled") == 0) {
        mode = MODE_POLLED;
    } else if (strcmp(argv[1], "dump") == 0) {
        mode = MODE_FRAMES;
        out.dump = fopen(argv[3], "wb");
        if (out.dump == NULL) {
            perror(argv[3]);
            return 2;
        }
    } else {
        fprintf(stderr, "unknown mode %s\n", argv[1]);
        return 2;
    }
    size_t size = 0;
    unsigned char *data = read_file(argv[2], &size);
    if (data == NULL) {
        return 2;
    }
    unsigned long exchanges = 0;
    int status = run(data, size, mode, &out, &exchanges);
    free(data);
    if (out.dump != NULL && fclose(out.dump) != 0) {
        perror(argv[3]);
        status = 2;
    }
    if (status == 0) {
        printf("bytes=%lu exchanges=%lu answer_bytes=%lu writes=%lu max_write=%lu\n",
               (unsigned long)size, exchanges, out.bytes, out.writes, out.max_write);
    }
    return status;
}
