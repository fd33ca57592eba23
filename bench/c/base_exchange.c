/* SPDX-License-Identifier: MIT */
/*
 * Benchmark harness for Core<->base exchanges through the ctrlbus C base stack (base.h), as a
 * firmware runs them (exchange_timeline.h): each request byte handed to ctrlbus_base_feed() from
 * the receive "interrupt", the clock advancing 1 ms every 11 byte slots, ctrlbus_base_poll() once
 * per millisecond, the answer streamed out through a write callback that only counts (or, in dump
 * mode, writes it to a file). callgrind counts the instructions.
 *
 *   base_exchange MODE REQUESTS ANSWER_BYTES [ANSWERS]
 *
 * REQUESTS is a file of request frames back to back; ANSWER_BYTES the size of one answer (the
 * idle slots after each request). MODE
 *   baseline  the same timeline with neither feed nor poll (the cost subtracted: start-up, file
 *             reading, the loop)
 *   firmware  feed and poll as above
 *   dump      as firmware, the answers written to the file ANSWERS (to check them; not measured)
 *
 * The handlers do the least a base must: set_velocity reports the motion the velocity gives over
 * 50 ms in integer arithmetic; status reports a fixed battery level.
 *
 * Prints "bytes=N exchanges=E answer_bytes=A writes=W max_write=M" so the caller can check that
 * every request was answered (max_write: the largest piece the stack handed to write at once).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exchange_timeline.h"
#include "read_file.h"

#include "ctrlbus/base.h"

#define RX_RING 256u
#define FRAME_BUFFER CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED

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

static int32_t status(void *context, ctrlbus_get_base_status_answer_t *out)
{
    (void)context;
    out->battery_percent = 87u;
    out->power_status = 0u;
    return CTRLBUS_OK;
}

static TIMELINE_ENTRY void isr_byte(void *base, uint8_t byte)
{
    (void)ctrlbus_base_feed_byte(base, byte);
}

static TIMELINE_ENTRY void main_poll(void *base, uint32_t now_ms)
{
    ctrlbus_base_poll(base, now_ms);
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
    static uint8_t rx_ring[RX_RING];
    static uint8_t frame_buffer[FRAME_BUFFER];
    ctrlbus_base_config_t config;
    memset(&config, 0, sizeof config);
    config.rx_ring = rx_ring;
    config.rx_ring_size = RX_RING;
    config.frame_buffer = frame_buffer;
    config.frame_buffer_size = FRAME_BUFFER;
    config.write = discard;
    config.write_context = &out;
    config.set_velocity = set_velocity;
    config.status = status;
    ctrlbus_base_t base;
    if (ctrlbus_base_init(&base, &config, 0) != CTRLBUS_OK) {
        fprintf(stderr, "ctrlbus_base_init failed\n");
        return 2;
    }
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
